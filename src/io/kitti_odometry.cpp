#include "io/kitti_odometry.h"

#include <filesystem>

#include "io/kitti_calib.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;

// Images of one camera folder, or an empty list when the folder does not exist.
std::vector<std::string> CameraImages(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return {};
  return ListFiles(dir.string(), ".png");
}

}  // namespace

Dataset OpenKittiOdometry(const std::string& sequence_dir, KittiCameras cams) {
  std::error_code ec;
  if (!fs::is_directory(sequence_dir, ec))
    throw InputError(sequence_dir, 0, "sequence directory not found");
  fs::path dir = fs::path(sequence_dir);
  if (dir.filename().empty()) dir = dir.parent_path();  // trailing '/'

  Dataset dataset;
  dataset.root = dir.string();
  dataset.name = dir.filename().string();

  const bool color = cams == KittiCameras::kColor;
  const std::string left_dir_name = color ? "image_2" : "image_0";
  const std::string right_dir_name = color ? "image_3" : "image_1";
  const fs::path left_dir = dir / left_dir_name;
  if (!fs::is_directory(left_dir, ec))
    throw InputError(left_dir.string(), 0, "image directory not found");
  dataset.left_paths = ListFiles(left_dir.string(), ".png");
  if (dataset.left_paths.empty()) throw InputError(left_dir.string(), 0, "no PNG images");
  dataset.right_paths = CameraImages(dir / right_dir_name);
  if (!dataset.right_paths.empty() && dataset.right_paths.size() != dataset.left_paths.size())
    throw InputError((dir / right_dir_name).string(), 0,
                     std::to_string(dataset.right_paths.size()) + " images but " + left_dir_name +
                         " has " + std::to_string(dataset.left_paths.size()));
  dataset.left_color_paths = color ? dataset.left_paths : CameraImages(dir / "image_2");
  if (dataset.left_color_paths.size() != dataset.left_paths.size())
    dataset.left_color_paths.clear();  // a partial colour folder is not used

  const std::string times_path = (dir / "times.txt").string();
  dataset.t_ns = ReadKittiTimes(times_path);
  if (dataset.t_ns.size() != dataset.left_paths.size())
    throw InputError(times_path, 0,
                     std::to_string(dataset.t_ns.size()) + " timestamps but " +
                         std::to_string(dataset.left_paths.size()) + " images in " + left_dir_name);

  const CalibFile calib = CalibFile::Read((dir / "calib.txt").string());
  SetRigFromProjections(calib.Matrix3x4(color ? "P2" : "P0"), calib.Matrix3x4(color ? "P3" : "P1"),
                        calib.name(), &dataset);

  const fs::path poses_path = dir.parent_path().parent_path() / "poses" / (dataset.name + ".txt");
  if (fs::is_regular_file(poses_path, ec)) {
    Trajectory poses = ReadKittiTrajectory(poses_path.string());
    if (poses.size() < dataset.size())
      throw InputError(poses_path.string(), 0,
                       std::to_string(poses.size()) + " poses but " +
                           std::to_string(dataset.size()) + " frames");
    poses.resize(dataset.size());
    for (size_t i = 0; i < poses.size(); ++i) poses[i].t_ns = dataset.t_ns[i];
    dataset.ground_truth = std::move(poses);
    dataset.ground_truth_source = poses_path.string();
  }
  return dataset;
}

}  // namespace pcr
