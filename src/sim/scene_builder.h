#pragma once
// Builds the synthetic world from SynthOptions (src/sim internal): streets, the ego lane path,
// static boxes (buildings, sidewalks, poles, signs) and object instances with their motions.
// Everything is drawn from counter-based random streams of options.seed, so a scene is a pure
// function of the options.
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "sim/instances.h"
#include "sim/path.h"
#include "sim/scene.h"
#include "sim/synth_options.h"

namespace pcr::sim {

// SplitMix64 stream: the same numbers on every platform.
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t Next();
  double Uniform(double lo, double hi);  // [lo, hi)
  bool Chance(double p) { return Uniform(0, 1) < p; }
  uint32_t U32() { return static_cast<uint32_t>(Next() >> 32); }

 private:
  uint64_t state_;
};

// How an object moves on the ground. Headings as in path.h.
struct Motion {
  enum class Kind { kStatic, kFollowPath, kCrossing };
  Kind kind = Kind::kStatic;
  // kStatic
  Eigen::Vector2d xz = Eigen::Vector2d::Zero();
  double heading_rad = 0;
  // kFollowPath: arc length s0_m + speed_mps * t on `path`.
  Path path;
  double s0_m = 0;
  double speed_mps = 0;
  // kCrossing: back and forth across the street through xz (heading_rad = street direction),
  // lateral offset (to the right) between lat_lo_m and lat_hi_m; u0_m is the distance walked at
  // t = 0 measured from lat_lo_m along the back-and-forth cycle.
  double lat_lo_m = 0, lat_hi_m = 0, u0_m = 0;

  // Position on the ground and heading (the object's forward) at time t_s.
  void At(double t_s, Eigen::Vector2d* xz_out, double* heading_out) const;
  double LateralAt(double t_s) const;  // kCrossing only
};

struct SceneInstance {
  InstanceInfo info;
  Motion motion;
  std::vector<BoxPrim> parts;  // in the object frame (origin on the ground, x right, y down)
};

struct Scene {
  Ground ground;                      // streets and road paint
  std::vector<BoxPrim> static_boxes;  // map frame
  std::vector<SceneInstance> instances;
  Path ego_path;  // the ego's lane
  double ego_s0_m = 0;
  uint32_t bounce_phase_seed = 0;
};

Scene BuildScene(const SynthOptions& options);

// map_from_object for a ground pose: rotation about y by heading, origin on the road.
Eigen::Isometry3d GroundPose(const Eigen::Vector2d& xz, double heading_rad);

}  // namespace pcr::sim
