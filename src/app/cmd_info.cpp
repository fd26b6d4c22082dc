#include "app/commands.h"

namespace pcr::app {
void AddInfoCommand(CLI::App& app) { (void)app; }
}  // namespace pcr::app
