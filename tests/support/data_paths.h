#pragma once
// Paths of the shared KITTI data and models (../shared beside the checkout).
#include <string>
#include <vector>

#include "slam/common/pose.h"

namespace pcr::test {

// Root of ../shared (PCR_SHARED_DIR in the environment overrides the build-time default).
std::string SharedDir();
// SharedDir() + "/" + relative.
std::string SharedPath(const std::string& relative);
// A fresh empty directory under the system temp dir. It is removed, with everything in it, when
// the test process exits normally; PCR_KEEP_TEST_DIRS=1 in the environment keeps it for a look.
std::string MakeTempDir(const std::string& prefix);

// Raw drive 0005 (image_00, image_01 and the calibration, linked) without its oxts folder, in a
// fresh MakeTempDir(prefix): a raw drive without ground-truth poses. Returns the drive's folder;
// its date folder (the drive's parent) may take other files.
std::string RawDriveWithoutGroundTruth(const std::string& prefix);

// A file's whole contents, byte for byte; empty when it cannot be read.
std::string ReadFileText(const std::string& path);

// The 12 numbers after `key` (e.g. "P0:" or "P_rect_02:") on its line of a KITTI calibration
// file; a test failure and zeros when the file or the line is missing.
std::vector<double> CalibRow(const std::string& path, const std::string& key);

// world_from_cam of the given frame (0-based line) of a KITTI poses file (3x4 row-major per
// line); a test failure and the identity when the file has no such line.
SE3 KittiPose(const std::string& path, int frame);

}  // namespace pcr::test
