#include "io/kitti_odometry.h"

#include <filesystem>

#include "io/kitti_calib.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"
#include "slam/common/log.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;

}  // namespace

Dataset OpenKittiOdometry(const std::string& sequence_dir, KittiCameras cams) {
  std::error_code ec;
  if (!fs::is_directory(sequence_dir, ec))
    throw InputError(sequence_dir, 0,
                     fs::exists(sequence_dir, ec) ? "not a directory (a sequence is a directory)"
                                                  : "sequence directory not found");
  const fs::path dir = NormalDirectoryPath(sequence_dir);

  Dataset dataset;
  dataset.root = dir.string();
  dataset.name = dir.filename().string();

  const bool color = cams == KittiCameras::kColor;
  const std::string left_dir_name = color ? "image_2" : "image_0";
  const std::string right_dir_name = color ? "image_3" : "image_1";
  const fs::path left_dir = dir / left_dir_name;
  if (!fs::is_directory(left_dir, ec))
    throw InputError(left_dir.string(), 0, "image directory not found");
  std::vector<int64_t> numbers;
  dataset.left_paths = ListFrameFiles(left_dir.string(), ".png", &numbers);
  if (dataset.left_paths.empty()) throw InputError(left_dir.string(), 0, "no PNG images");
  AddOtherCameras(&dataset, numbers, left_dir_name, (dir / right_dir_name).string(),
                  (dir / "image_2").string(), color);

  if (fs::exists(dir / kSynthOptionsName, ec) && !fs::exists(dir / kSynthCompleteName, ec))
    Logger().warn(
        "{}: a synthetic sequence whose render did not finish ({} without {}): its images, "
        "poses and options may come from two renders; render it again (pcr_orb synth)",
        dataset.root, kSynthOptionsName, kSynthCompleteName);
  const std::string times_path = (dir / "times.txt").string();
  const std::vector<int64_t> times = ReadKittiTimes(times_path);
  RequireLines(times.size(), numbers, dataset.left_paths, times_path, "timestamps",
               std::to_string(dataset.size()) + " images in " + left_dir_name);
  for (const int64_t number : numbers) dataset.t_ns.push_back(times[number]);
  dataset.frame_numbers = numbers;

  const CalibFile calib = CalibFile::Read((dir / "calib.txt").string());
  SetRigFromCalib(calib, color ? "P2" : "P0", color ? "P3" : "P1", &dataset);

  // poses/NN.txt beside sequences/ (of the link's target where the sequence is a link)
  const auto poses_of = [&](const fs::path& d) {
    return d.parent_path().parent_path() / "poses" / (d.filename().string() + ".txt");
  };
  const fs::path poses_path = poses_of(FirstDirectoryWhere(dir.string(), [&](const std::string& d) {
    std::error_code e;
    return fs::exists(poses_of(d), e);
  }));
  if (fs::exists(poses_path, ec)) {
    if (!fs::is_regular_file(poses_path, ec))
      throw InputError(poses_path.string(), 0, "the ground-truth poses are not a regular file");
    const Trajectory poses = ReadKittiTrajectory(poses_path.string());
    RequireLines(poses.size(), numbers, dataset.left_paths, poses_path.string(), "poses",
                 std::to_string(dataset.size()) + " frames");
    Trajectory truth;
    for (size_t i = 0; i < numbers.size(); ++i) {
      StampedPose pose = poses[numbers[i]];
      pose.t_ns = dataset.t_ns[i];
      pose.frame_index = static_cast<int64_t>(i);
      truth.push_back(pose);
    }
    dataset.ground_truth = std::move(truth);
    dataset.ground_truth_source = poses_path.string();
  }
  return dataset;
}

}  // namespace pcr
