#pragma once
// Writes a synthetic world as a KITTI odometry sequence:
//   OUT/sequences/NN/image_0/%06d.png, image_1/%06d.png   8-bit grey left / right
//   OUT/sequences/NN/instance_0/%06d.png (instance_1/)     16-bit instance ids (instances.h)
//   OUT/sequences/NN/calib.txt (P0..P3), times.txt (%e seconds)
//   OUT/sequences/NN/instances.txt                         id class moving speed size
//   OUT/sequences/NN/objects.txt                           frame id visible_px + 12 numbers
//                                                          (world_from_object, 3x4 row-major)
//   OUT/sequences/NN/synth_options.txt                     the options used
//   OUT/sequences/NN/render_complete.txt                   the options again, written last of all
//   OUT/poses/NN.txt                                       world_from_cam0, 12 numbers a line
#include <functional>
#include <string>

#include "sim/synth_options.h"

namespace pcr::sim {

struct WriteSummary {
  std::string sequence_dir;
  std::string poses_path;
  int frames = 0;
  int instances = 0;
  int moving_instances = 0;
  double seconds = 0;  // wall time
};

// Called after each written frame with (frames done, total frames), from the calling thread.
using ProgressCallback = std::function<void(int, int)>;

// Throws pcr::ConfigError for invalid options and pcr::InputError naming the file that cannot be
// written.
WriteSummary WriteSequence(const SynthOptions& options, const std::string& out_dir,
                           const ProgressCallback& progress = {});

// Whether out_dir holds the whole sequence that WriteSequence(options, out_dir) writes: its
// render_complete.txt, written after every other file of a render that finished, names exactly
// these options (every one, defaults included). It does not see a change of the renderer's code.
bool HoldsSequence(const SynthOptions& options, const std::string& out_dir);

// The sequence folder of WriteSequence(options, out_dir), rendered only where HoldsSequence is
// false (then the folder's older sequence NN and poses/NN.txt are removed first). For benchmarks
// and tests that reuse a render; throws as WriteSequence does.
std::string RenderOnce(const SynthOptions& options, const std::string& out_dir,
                       const ProgressCallback& progress = {});

// The four calib.txt lines (P0..P3) for a rig, KITTI format.
std::string KittiCalibText(const SynthOptions& options);

}  // namespace pcr::sim
