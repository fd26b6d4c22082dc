#include "slam/common/error.h"

namespace pcr {
namespace {
std::string Compose(const std::string& file, int line, const std::string& what) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + what;
  return file + ": " + what;
}
}  // namespace

InputError::InputError(const std::string& file, int line, const std::string& what)
    : std::runtime_error(Compose(file, line, what)), file_(file), line_(line) {}

}  // namespace pcr
