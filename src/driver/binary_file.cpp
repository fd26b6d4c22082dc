#include "driver/binary_file.h"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <system_error>

#include "io/text_parse.h"
#include "slam/common/error.h"

namespace pcr::driver {

void WriteFileAtomically(const std::string& path, const std::vector<uint8_t>& bytes) {
  io::WriteFileAtomically(path, [&bytes](std::ostream& out) {
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
  });
}

std::vector<uint8_t> ReadFileBytes(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path, 0, "is a directory, not a " + what + " file");
  // A device or a FIFO (/dev/zero) would be read until memory runs out.
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw InputError(path, 0, "is not a regular file, not a " + what + " file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open the " + what + " file");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, "cannot read the " + what + " file");
  return bytes;
}

}  // namespace pcr::driver
