#include "driver/vocabulary_file.h"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <system_error>
#include <vector>

#include "slam/common/error.h"
#include "slam/loop/vocabulary_io.h"

namespace pcr::driver {

void SaveVocabulary(const std::string& path, const Vocabulary& vocabulary) {
  const std::vector<uint8_t> bytes = SerializeVocabulary(vocabulary);
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path, 0, "cannot open " + tmp + " for writing");
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw InputError(path, 0, "cannot write " + tmp);
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError(path, 0, "cannot rename " + tmp + " to it: " + ec.message());
}

Vocabulary LoadVocabulary(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open the vocabulary file");
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, "cannot read the vocabulary file");
  return DeserializeVocabulary(bytes.data(), bytes.size(), path);
}

}  // namespace pcr::driver
