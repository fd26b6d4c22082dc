#include "io/kitti_calib.h"

#include <algorithm>

#include "io/text_parse.h"
#include "slam/common/error.h"

namespace pcr {

CalibFile CalibFile::Parse(std::istream& in, const std::string& name) {
  CalibFile calib;
  calib.name_ = name;
  io::LineReader reader(in, name);
  std::string line;
  while (reader.Next(&line)) {
    if (io::IsBlank(line)) continue;
    const size_t colon = line.find(':');
    const std::vector<std::string_view> key_tokens =
        io::SplitWhitespace(std::string_view(line).substr(0, colon));
    if (colon == std::string::npos || key_tokens.size() != 1)
      throw InputError(name, reader.line_no(), "expected 'KEY: values'");
    const std::string key(key_tokens[0]);
    if (std::any_of(key.begin(), key.end(), [](char c) {
          return static_cast<unsigned char>(c) < 0x21 || static_cast<unsigned char>(c) > 0x7e;
        }))
      throw InputError(name, reader.line_no(),
                       "key " + io::Quote(key) + " has a byte that is not printable ASCII");
    if (calib.entries_.count(key))
      throw InputError(name, reader.line_no(), "key '" + key + "' appears twice");
    calib.entries_[key] = Entry{line.substr(colon + 1), reader.line_no()};
  }
  return calib;
}

int CalibFile::Line(const std::string& key) const {
  const auto it = entries_.find(key);
  return it == entries_.end() ? 0 : it->second.line;
}

CalibFile CalibFile::Read(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  return Parse(in, path);
}

std::vector<double> CalibFile::Numbers(const std::string& key, size_t count) const {
  const auto it = entries_.find(key);
  if (it == entries_.end()) throw InputError(name_, 0, "missing calibration entry '" + key + "'");
  try {
    return io::ParseExactly(it->second.value, count, name_, it->second.line);
  } catch (const InputError& e) {
    std::string message = e.what();
    const std::string prefix = name_ + ":" + std::to_string(it->second.line) + ": ";
    if (message.rfind(prefix, 0) == 0) message.erase(0, prefix.size());
    throw InputError(name_, it->second.line, "entry '" + key + "': " + message);
  }
}

Eigen::Matrix<double, 3, 4> CalibFile::Matrix3x4(const std::string& key) const {
  const std::vector<double> v = Numbers(key, 12);
  Eigen::Matrix<double, 3, 4> m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[r * 4 + c];
  return m;
}

Eigen::Matrix3d CalibFile::Matrix3(const std::string& key) const {
  const std::vector<double> v = Numbers(key, 9);
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = v[r * 3 + c];
  return m;
}

Eigen::Vector3d CalibFile::Vector3(const std::string& key) const {
  const std::vector<double> v = Numbers(key, 3);
  return {v[0], v[1], v[2]};
}

Eigen::Matrix3d CalibFile::Rotation(const std::string& key) const {
  return io::NearestRotation(Matrix3(key), name_, entries_.at(key).line);
}

}  // namespace pcr
