#pragma once
// Writes a synthetic world as a KITTI odometry sequence:
//   OUT/sequences/NN/image_0/%06d.png, image_1/%06d.png   8-bit grey left / right
//   OUT/sequences/NN/instance_0/%06d.png (instance_1/)     16-bit instance ids (instances.h)
//   OUT/sequences/NN/calib.txt (P0..P3), times.txt (%e seconds)
//   OUT/sequences/NN/instances.txt                         id class moving speed size
//   OUT/sequences/NN/objects.txt                           frame id visible_px + 12 numbers
//                                                          (world_from_object, 3x4 row-major)
//   OUT/sequences/NN/synth_options.txt                     the options used (written first),
//                                                          then num_parked_placed: the parked
//                                                          cars that fit (at most num_parked)
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
  int parked_instances = 0;  // parked cars placed: fewer than num_parked where no more fit
  double seconds = 0;        // wall time
};

// Called after each written frame with (frames done, total frames), from the calling thread.
using ProgressCallback = std::function<void(int, int)>;

// Throws pcr::ConfigError for invalid options and pcr::InputError naming the file that cannot be
// written, or as RefuseForeignData does (nothing is written then).
WriteSummary WriteSequence(const SynthOptions& options, const std::string& out_dir,
                           const ProgressCallback& progress = {});

// Throws pcr::InputError naming what WriteSequence(options, out_dir) would replace although no
// synthetic render wrote it (a real KITTI sequence, say), `advice` (how to proceed) ending the
// message: the sequence folder OUT/sequences/NN when it holds files but no synth_options.txt or
// render_complete.txt, else OUT/poses/NN.txt when that is there, not empty and its sequence
// folder has neither file. Returns where there is nothing such (an absent or empty folder, or an
// earlier synthetic render, finished or not). WriteSequence and RenderOnce call it first.
void RefuseForeignData(
    const SynthOptions& options, const std::string& out_dir,
    const std::string& advice = "write the synthetic sequence elsewhere or remove it");

// Whether out_dir holds the whole sequence that WriteSequence(options, out_dir) writes: its
// render_complete.txt, written after every other file of a render that finished, names exactly
// these options (every one, defaults included). It does not see a change of the renderer's code.
bool HoldsSequence(const SynthOptions& options, const std::string& out_dir);

// The sequence folder of WriteSequence(options, out_dir), rendered only where HoldsSequence is
// false (then the folder's older sequence NN and poses/NN.txt are removed first, unless
// RefuseForeignData finds them not synth's). For benchmarks and tests that reuse a render;
// throws as WriteSequence does.
std::string RenderOnce(const SynthOptions& options, const std::string& out_dir,
                       const ProgressCallback& progress = {});

// The four calib.txt lines (P0..P3) for a rig, KITTI format.
std::string KittiCalibText(const SynthOptions& options);

}  // namespace pcr::sim
