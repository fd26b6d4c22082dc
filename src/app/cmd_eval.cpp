#include "app/commands.h"

namespace pcr::app {
void AddEvalCommand(CLI::App& app) { (void)app; }
}  // namespace pcr::app
