#pragma once
// Trajectory files: KITTI odometry poses (12 numbers per line, 3x4 row-major world_from_cam),
// TUM (t tx ty tz qx qy qz qw, t in seconds) and KITTI times.txt. Rotations read from text are
// projected to the nearest exact rotation. Bad input throws pcr::InputError naming the file and
// 1-based line; writers go through a temporary file and a rename, so a failed write never
// replaces a good file.
#include <cstdint>
#include <istream>
#include <string>
#include <vector>

#include "slam/common/pose.h"

namespace pcr {

// frame_index = 0-based pose index (the index among the data lines), t_ns = 0. '#' comment lines
// are skipped (as evo does); blank lines are allowed only at the end of the file (a blank line in
// between would shift the frame indices).
Trajectory ReadKittiTrajectory(const std::string& path);
Trajectory ReadKittiTrajectory(std::istream& in, const std::string& name);

// '#' comments and blank lines are skipped; frame_index = -1; timestamps strictly increasing.
Trajectory ReadTumTrajectory(const std::string& path);
Trajectory ReadTumTrajectory(std::istream& in, const std::string& name);

// %.17g numbers (exact double round trip).
void WriteKittiTrajectory(const std::string& path, const Trajectory& trajectory);
// Time written exactly from t_ns with 9 decimals, then tx ty tz qx qy qz qw in %.17g.
void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory);
// One of WriteTumTrajectory's lines, without its newline.
std::string TumLine(const StampedPose& pose);

// KITTI odometry times.txt: one time in seconds per line -> nanoseconds, strictly increasing.
std::vector<int64_t> ReadKittiTimes(const std::string& path);
std::vector<int64_t> ReadKittiTimes(std::istream& in, const std::string& name);

}  // namespace pcr
