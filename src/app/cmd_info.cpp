#include <fmt/format.h>

#include <string>

#include "app/commands.h"
#include "io/dataset.h"

namespace pcr::app {
namespace {

void PrintInfo(const std::string& path, bool color) {
  const Dataset dataset = OpenDataset(path, color ? KittiCameras::kColor : KittiCameras::kGray);
  const PinholeCamera& cam = dataset.rig.left;
  const double duration_s = dataset.DurationSeconds();
  fmt::print("name:          {}\n", dataset.name);
  fmt::print("root:          {}\n", dataset.root);
  fmt::print("frames:        {}\n", dataset.size());
  fmt::print("image size:    {} x {} px\n", cam.width_px, cam.height_px);
  fmt::print("intrinsics:    fx {:.4f} fy {:.4f} cx {:.4f} cy {:.4f} px\n", cam.fx, cam.fy, cam.cx,
             cam.cy);
  if (dataset.has_right())
    fmt::print("stereo:        yes, baseline {:.4f} m\n", dataset.rig.baseline_m);
  else
    fmt::print("stereo:        no (monocular)\n");
  fmt::print("colour left:   {}\n", dataset.has_color() ? "yes" : "no");
  fmt::print("duration:      {:.3f} s\n", duration_s);
  if (dataset.size() > 1 && duration_s > 0)
    fmt::print("frame rate:    {:.3f} Hz (mean)\n", (dataset.size() - 1) / duration_s);
  if (dataset.ground_truth) {
    fmt::print("ground truth:  yes ({})\n", dataset.ground_truth_source);
    fmt::print("path length:   {:.3f} m\n", PathLength(*dataset.ground_truth));
  } else {
    fmt::print("ground truth:  no\n");
  }
}

}  // namespace

void AddInfoCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "info",
      "Describe a KITTI odometry sequence or raw drive (calibration, frames, ground truth)");
  auto path = std::make_shared<std::string>();
  auto color = std::make_shared<bool>(false);
  cmd->add_option(
         "--sequence,-s", *path,
         "Odometry sequence dir (sequences/NN) or raw drive dir (DATE/DATE_drive_NNNN_sync)")
      ->required();
  cmd->add_flag("--color", *color, "Use the colour cameras (2/3) instead of the grey ones (0/1)");
  cmd->callback([path, color] { PrintInfo(*path, *color); });
}

}  // namespace pcr::app
