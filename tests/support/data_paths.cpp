#include "support/data_paths.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <random>
#include <sstream>
#include <system_error>
#include <vector>

namespace pcr::test {

std::string SharedDir() {
  if (const char* env = std::getenv("PCR_SHARED_DIR"); env && *env) return env;
  return PCR_SHARED_DIR;
}

std::string SharedPath(const std::string& relative) { return SharedDir() + "/" + relative; }

std::string ReadFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::vector<double> CalibRow(const std::string& path, const std::string& key) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) != 0) continue;
    std::istringstream ss(line.substr(key.size()));
    std::vector<double> p(12);
    for (double& v : p) ss >> v;
    if (ss) return p;
  }
  ADD_FAILURE() << "no " << key << " line in " << path;
  return std::vector<double>(12, 0.0);
}

SE3 KittiPose(const std::string& path, int frame) {
  std::ifstream in(path);
  std::string line;
  for (int i = 0; std::getline(in, line); ++i) {
    if (i != frame) continue;
    std::istringstream ss(line);
    Eigen::Matrix<double, 3, 4, Eigen::RowMajor> m;
    for (int k = 0; k < 12; ++k) ss >> m.data()[k];
    SE3 pose = SE3::Identity();
    pose.linear() = m.leftCols<3>();
    pose.translation() = m.col(3);
    return pose;
  }
  ADD_FAILURE() << "no line " << frame + 1 << " in " << path;
  return SE3::Identity();
}

namespace {

// The directories MakeTempDir created in this process, removed at exit (each CI run used to
// leave about 25 MB of sequences and outputs under /tmp).
class TempDirs {
 public:
  ~TempDirs() {
    if (const char* keep = std::getenv("PCR_KEEP_TEST_DIRS"); keep && *keep && *keep != '0') return;
    for (const auto& dir : dirs_) {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  }
  void Add(const std::filesystem::path& dir) {
    std::lock_guard<std::mutex> lock(mutex_);
    dirs_.push_back(dir);
  }

 private:
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

TempDirs& CreatedDirs() {
  static TempDirs dirs;
  return dirs;
}

}  // namespace

std::string RawDriveWithoutGroundTruth(const std::string& prefix) {
  namespace fs = std::filesystem;
  const std::string date = MakeTempDir(prefix) + "/2011_09_26";
  const std::string drive = date + "/2011_09_26_drive_0005_sync";
  fs::create_directories(drive);
  fs::create_symlink(SharedPath("data/kitti_raw/2011_09_26/calib_cam_to_cam.txt"),
                     date + "/calib_cam_to_cam.txt");
  for (const char* camera : {"image_00", "image_01"})
    fs::create_directory_symlink(
        SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync/") + camera,
        drive + "/" + camera);
  return drive;
}

std::string MakeTempDir(const std::string& prefix) {
  namespace fs = std::filesystem;
  TempDirs& created = CreatedDirs();  // constructed before any directory exists
  std::random_device rd;
  for (int attempt = 0; attempt < 100; ++attempt) {
    fs::path p = fs::temp_directory_path() / (prefix + "_" + std::to_string(rd()));
    if (fs::create_directories(p)) {
      created.Add(p);
      return p.string();
    }
  }
  throw std::runtime_error("cannot create a temporary directory for " + prefix);
}

}  // namespace pcr::test
