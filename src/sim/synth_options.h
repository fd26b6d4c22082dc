#pragma once
// Options of the synthetic KITTI-format stereo world (src/sim). Defaults give KITTI odometry
// geometry: 1241x376 grey images, fx = fy = 718.856 px, baseline 0.537 m, 10 Hz, camera 1.65 m
// above a straight street.
#include <cstdint>
#include <string>

#include "slam/common/camera.h"

namespace pcr::sim {

enum class RouteKind {
  kStraight,  // one straight street, driven forward
  kLoop,      // a rounded rectangle of streets (left turns), driven past its start
};

// "straight" / "loop"; ParseRoute throws pcr::ConfigError for another name.
const char* RouteName(RouteKind route);
RouteKind ParseRoute(const std::string& name);

struct SynthOptions {
  int frames = 300;
  uint64_t seed = 1;
  int num_movers = 6;      // moving objects (a cyclist is two instances: bicycle + person)
  int num_parked = 8;      // parked cars (instances with moving = 0)
  double speed_mps = 8.0;  // ego speed along its lane
  RouteKind route = RouteKind::kStraight;
  // Heavy traffic: > 0 puts the first car ahead lead_gap_m (+0..2 m) in front of the ego at
  // nearly the ego's speed (a close lead car, as in a queue); 0 keeps the default drifting one.
  double lead_gap_m = 0.0;
  // Loop route: times round the loop's streets in `frames` (the streets' centre lines measure the
  // travel over laps round, 208 m at least, so a short travel drives fewer laps). The ego's lane
  // runs 1.75 m outside them with corners of 12 m radius, which makes it 6.6 m shorter than
  // the streets, so the ego drives a little more: 1.15 drives 1.17 laps of its lane at 600 frames
  // and 8 m/s (68 m past the start), 2.15 at 1122 frames drives 2.18.
  double laps = 1.15;

  int width_px = 1241;
  int height_px = 376;
  double fx = 718.856, fy = 718.856, cx = 607.1928, cy = 185.2157;  // pixels
  double baseline_m = 0.537;
  double rate_hz = 10.0;              // frames per second
  double camera_height_m = 1.65;      // optical centre above the road
  double bounce_scale = 1.0;          // 0: perfectly planar motion; 1: ~1 cm / 0.2 deg oscillations
  double noise_sigma = 1.5;           // sensor noise, grey levels (8-bit)
  std::string sequence = "00";        // two digits: OUT/sequences/NN, OUT/poses/NN.txt
  bool write_right_instances = true;  // instance_1/ beside instance_0/

  bool IsValid(std::string* why) const;
  StereoRig Rig() const;
  // Scales the image size and intrinsics (for small, fast test renders).
  SynthOptions Scaled(double factor) const;
};

}  // namespace pcr::sim
