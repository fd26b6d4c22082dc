#include "eval/trajectory_format.h"

#include <fstream>
#include <sstream>

#include "slam/common/error.h"

namespace pcr::eval {

std::string_view ToString(TrajectoryFormat format) {
  return format == TrajectoryFormat::kKitti ? "kitti" : "tum";
}

TrajectoryFormat DetectTrajectoryFormat(std::istream& in, const std::string& name) {
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const size_t first = line.find_first_not_of(" \t\r\v\f");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream tokens(line);
    std::string token;
    int count = 0;
    while (tokens >> token) ++count;
    if (count == 12) return TrajectoryFormat::kKitti;
    if (count == 8) return TrajectoryFormat::kTum;
    throw InputError(name, line_no,
                     "cannot tell the trajectory format: " + std::to_string(count) +
                         " values on the first data line (KITTI has 12, TUM 8)");
  }
  throw InputError(name, 0, "no trajectory data in the file");
}

TrajectoryFormat DetectTrajectoryFormat(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open the file");
  return DetectTrajectoryFormat(in, path);
}

}  // namespace pcr::eval
