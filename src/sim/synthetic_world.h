#pragma once
// A synthetic street world rendered as a rectified KITTI-like stereo pair with exact ground truth:
// camera poses, per-pixel depth and per-pixel object instance ids (see instances.h). The world
// frame is camera 0 at frame 0 (as in KITTI pose files), so it carries that frame's small bounce
// pitch/roll (bounce_scale = 0 gives a level world); camera frame x right, y down, z forward.
//
// Rendering: one ray per pixel against the road plane and oriented boxes; procedural textures
// fixed to each surface (prefiltered by the pixel footprint), Lambertian shading (overcast light
// from above), distance haze, a 3x3 Gaussian optics blur and seeded sensor noise. RenderFrame is
// const and may run concurrently with itself; it also parallelises internally
// (cv::parallel_for_), and its output depends only on the options and the frame index.
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "sim/instances.h"
#include "sim/synth_options.h"
#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr::sim {

struct RenderedFrame {
  int index = 0;
  int64_t t_ns = 0;
  cv::Mat left, right;                    // CV_8UC1
  cv::Mat instance_left, instance_right;  // CV_16UC1
  cv::Mat depth_left, depth_right;        // CV_32FC1, metres along z; +infinity for sky
  SE3 world_from_cam = SE3::Identity();   // left camera
};

class SyntheticWorld {
 public:
  // Throws pcr::ConfigError when !options.IsValid().
  explicit SyntheticWorld(const SynthOptions& options);
  ~SyntheticWorld();
  SyntheticWorld(SyntheticWorld&&) noexcept;
  SyntheticWorld& operator=(SyntheticWorld&&) noexcept;

  const SynthOptions& options() const;
  StereoRig Rig() const { return options().Rig(); }
  int NumFrames() const { return options().frames; }
  int64_t FrameTimeNs(int frame) const;

  // Left camera (camera 0) pose; frame may be any index (the motion is defined for all times).
  SE3 WorldFromCam(int frame) const;
  // All frames' poses, t_ns and frame_index set.
  Trajectory GroundTruth() const;

  const InstanceTable& Instances() const;
  // world_from_object of an instance at a frame. Throws std::out_of_range for an unknown id.
  SE3 WorldFromObject(uint16_t id, int frame) const;

  // Throws std::out_of_range when frame is not in [0, NumFrames()).
  RenderedFrame RenderFrame(int frame) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pcr::sim
