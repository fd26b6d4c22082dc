#include "io/trajectory_io.h"

#include <cinttypes>
#include <cmath>
#include <cstdio>

#include "io/text_parse.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

// Whether the line's first non-blank character is '#'.
bool IsComment(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t\v\f");
  return first != std::string::npos && line[first] == '#';
}

// Reads the non-blank lines of a positional file (one record per line, blank lines only at the
// end); calls on_line(text, line_no, index). With `comments`, '#' lines are skipped and take no
// index.
template <typename OnLine>
void ForEachPositionalLine(std::istream& in, const std::string& name, bool comments,
                           OnLine on_line) {
  io::LineReader reader(in, name);
  std::string line;
  int first_blank_line = 0;
  int64_t index = 0;
  while (reader.Next(&line)) {
    if (comments && IsComment(line)) continue;
    if (io::IsBlank(line)) {
      if (first_blank_line == 0) first_blank_line = reader.line_no();
      continue;
    }
    if (first_blank_line != 0)
      throw InputError(name, first_blank_line,
                       "blank line before the end of the file (it would shift frame indices)");
    on_line(line, reader.line_no(), index++);
  }
}

std::string FormatTime(int64_t t_ns) {
  const bool negative = t_ns < 0;
  const uint64_t abs_ns = negative ? 0 - static_cast<uint64_t>(t_ns) : static_cast<uint64_t>(t_ns);
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "",
                abs_ns / 1'000'000'000u, abs_ns % 1'000'000'000u);
  return buffer;
}

}  // namespace

Trajectory ReadKittiTrajectory(std::istream& in, const std::string& name) {
  Trajectory trajectory;
  ForEachPositionalLine(
      in, name, /*comments=*/true, [&](const std::string& line, int line_no, int64_t index) {
        const std::vector<double> v = io::ParseExactly(line, 12, name, line_no);
        Eigen::Matrix3d rotation;
        rotation << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
        StampedPose pose;
        pose.t_ns = 0;
        pose.frame_index = index;
        pose.world_from_cam.linear() = io::NearestRotation(rotation, name, line_no);
        pose.world_from_cam.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
        trajectory.push_back(pose);
      });
  return trajectory;
}

Trajectory ReadKittiTrajectory(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  return ReadKittiTrajectory(in, path);
}

Trajectory ReadTumTrajectory(std::istream& in, const std::string& name) {
  Trajectory trajectory;
  io::LineReader reader(in, name);
  std::string line;
  while (reader.Next(&line)) {
    if (io::IsBlank(line) || IsComment(line)) continue;
    const int line_no = reader.line_no();
    const std::vector<std::string_view> tokens = io::SplitWhitespace(line);
    if (tokens.size() != 8)
      throw InputError(
          name, line_no,
          "expected 8 numbers (t tx ty tz qx qy qz qw), found " + std::to_string(tokens.size()));
    StampedPose pose;
    pose.t_ns = io::ParseSecondsToNs(tokens[0], name, line_no);
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = io::ParseFiniteDouble(tokens[i + 1], name, line_no);
    if (!trajectory.empty() && pose.t_ns <= trajectory.back().t_ns)
      throw InputError(name, line_no, "timestamps must increase strictly");
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);  // (w, x, y, z)
    const double norm = q.norm();
    if (!(std::abs(norm - 1.0) <= 1e-2))
      throw InputError(name, line_no,
                       "quaternion is not unit length (|q| = " + std::to_string(norm) + ")");
    q.normalize();
    pose.frame_index = -1;
    pose.world_from_cam.linear() = q.toRotationMatrix();
    pose.world_from_cam.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    trajectory.push_back(pose);
  }
  return trajectory;
}

Trajectory ReadTumTrajectory(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  return ReadTumTrajectory(in, path);
}

void WriteKittiTrajectory(const std::string& path, const Trajectory& trajectory) {
  io::WriteFileAtomically(path, [&](std::ostream& out) {
    char buffer[32];
    for (const StampedPose& pose : trajectory) {
      const Eigen::Matrix<double, 3, 4> m = pose.world_from_cam.matrix().topRows<3>();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
          std::snprintf(buffer, sizeof(buffer), "%.17g", m(r, c));
          if (r != 0 || c != 0) out << ' ';
          out << buffer;
        }
      }
      out << '\n';
    }
  });
}

std::string TumLine(const StampedPose& pose) {
  const Eigen::Quaterniond q(pose.world_from_cam.rotation());
  const Eigen::Vector3d t = pose.world_from_cam.translation();
  std::string line = FormatTime(pose.t_ns);
  char buffer[32];
  for (double value : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
    std::snprintf(buffer, sizeof(buffer), " %.17g", value);
    line += buffer;
  }
  return line;
}

void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  io::WriteFileAtomically(path, [&](std::ostream& out) {
    out << "# timestamp tx ty tz qx qy qz qw\n";
    for (const StampedPose& pose : trajectory) out << TumLine(pose) << '\n';
  });
}

std::vector<int64_t> ReadKittiTimes(std::istream& in, const std::string& name) {
  std::vector<int64_t> times_ns;
  ForEachPositionalLine(
      in, name, /*comments=*/false, [&](const std::string& line, int line_no, int64_t) {
        const std::vector<std::string_view> tokens = io::SplitWhitespace(line);
        if (tokens.size() != 1)
          throw InputError(
              name, line_no,
              "expected 1 number (time in seconds), found " + std::to_string(tokens.size()));
        const int64_t t_ns = io::ParseSecondsToNs(tokens[0], name, line_no);
        if (!times_ns.empty() && t_ns <= times_ns.back())
          throw InputError(name, line_no, "timestamps must increase strictly");
        times_ns.push_back(t_ns);
      });
  return times_ns;
}

std::vector<int64_t> ReadKittiTimes(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  return ReadKittiTimes(in, path);
}

}  // namespace pcr
