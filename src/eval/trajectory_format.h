#pragma once
// Telling KITTI from TUM trajectory files by their first data line ('#' comments and blank lines
// skipped): 12 numbers = KITTI (3x4 pose), 8 = TUM (t tx ty tz qx qy qz qw). Only the tokens are
// counted; reading the poses is src/io's job.
#include <istream>
#include <string>
#include <string_view>

namespace pcr::eval {

enum class TrajectoryFormat { kKitti, kTum };

std::string_view ToString(TrajectoryFormat format);  // "kitti", "tum"

// Throws pcr::InputError naming the file (and the line) when the file is unreadable, has no data
// line, or its first data line holds neither 12 nor 8 tokens.
TrajectoryFormat DetectTrajectoryFormat(const std::string& path);
TrajectoryFormat DetectTrajectoryFormat(std::istream& in, const std::string& name);

}  // namespace pcr::eval
