#include "kitti_clip.h"

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/pose.h"
#include "support/data_paths.h"

namespace pcr::test {
namespace {

std::string ImagePath(const std::string& dir, int camera, int64_t index) {
  char name[32];
  std::snprintf(name, sizeof(name), "/image_%d/%06lld.png", camera, static_cast<long long>(index));
  return dir + name;
}

cv::Mat LoadGrey(const std::string& path) {
  cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty()) throw InputError(path, 0, "cannot decode the image");
  return image;
}

}  // namespace

nodes::FrameSource KittiOdometryClip(const std::string& dir, int first, int end) {
  nodes::FrameSource source;
  source.name = std::filesystem::path(dir).filename().string();
  std::ifstream calib(dir + "/calib.txt");
  std::string line;
  double p0[12] = {}, p1[12] = {};
  while (std::getline(calib, line)) {
    std::istringstream in(line);
    std::string key;
    in >> key;
    double* p = key == "P0:" ? p0 : key == "P1:" ? p1 : nullptr;
    for (int i = 0; p && i < 12; ++i) in >> p[i];
  }
  source.rig.left.fx = p0[0];
  source.rig.left.cx = p0[2];
  source.rig.left.fy = p0[5];
  source.rig.left.cy = p0[6];
  source.rig.baseline_m = -p1[3] / p1[0];
  const cv::Mat first_image = LoadGrey(ImagePath(dir, 0, first));
  source.rig.left.width_px = first_image.cols;
  source.rig.left.height_px = first_image.rows;
  std::ifstream times(dir + "/times.txt");
  double t_s = 0;
  for (int i = 0; i < end && times >> t_s; ++i) {
    if (i < first) continue;
    source.frame_indices.push_back(i);
    source.t_ns.push_back(SecondsToNs(t_s));
  }
  if (static_cast<int>(source.frame_indices.size()) != end - first)
    throw std::runtime_error(dir + ": times.txt has fewer frames than asked for");
  source.load_left = [dir](int64_t i) { return LoadGrey(ImagePath(dir, 0, i)); };
  source.load_right = [dir](int64_t i) { return LoadGrey(ImagePath(dir, 1, i)); };
  return source;
}

std::string CopyClip(const std::string& dir, int end) {
  namespace fs = std::filesystem;
  const std::string out = MakeTempDir("pcr_graph_clip");
  fs::copy_file(dir + "/calib.txt", out + "/calib.txt");
  fs::copy_file(dir + "/times.txt", out + "/times.txt");
  for (int camera : {0, 1}) {
    fs::create_directories(out + "/image_" + std::to_string(camera));
    for (int i = 0; i < end; ++i)
      fs::copy_file(ImagePath(dir, camera, i), ImagePath(out, camera, i));
  }
  return out;
}

}  // namespace pcr::test
