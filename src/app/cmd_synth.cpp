#include "app/commands.h"

namespace pcr::app {
void AddSynthCommand(CLI::App& app) { (void)app; }
}  // namespace pcr::app
