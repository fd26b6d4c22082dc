#include "driver/map_floor.h"

#include <chrono>
#include <map>
#include <stdexcept>

#include "eval/association.h"
#include "eval/evaluation.h"
#include "slam/common/error.h"
#include "slam/common/log.h"
#include "slam/optim/bundle_adjustment.h"

namespace pcr::driver {
namespace {

using KeyframePoses = std::map<KeyframeId, Sim3>;  // cam_from_world

KeyframePoses PosesOf(const Map& map) {
  KeyframePoses poses;
  for (const auto& [id, kf] : map.keyframes()) poses[id] = Sim3::FromSE3(kf.cam_from_world);
  return poses;
}

double AteOf(const KeyframePoses& poses, const Trajectory& truth) {
  Trajectory t;
  for (const auto& [id, cam_from_world] : poses)
    t.push_back({0, id.value, cam_from_world.Inverse().ToSE3()});
  eval::EvalOptions eval;
  eval.alignment.mode = eval::AlignMode::kSe3;
  try {
    return eval::Evaluate(eval::AssociateByFrameIndex(truth, t), eval).ape.trans_m.rmse;
  } catch (const std::exception& e) {
    Logger().warn("keyframe ATE: {}", e.what());
    return MapFloor::kNaN;
  }
}

// The map's keyframes at their true poses, in the map's world (the first keyframe stays where
// the map has it).
KeyframePoses TruePoses(const Map& map, const Trajectory& truth) {
  auto gt = [&](KeyframeId id) -> const SE3& {
    return truth.at(static_cast<size_t>(id.value)).world_from_cam;
  };
  const KeyframeId first = map.first_keyframe();
  const SE3 map_from_truth = map.keyframe(first)->cam_from_world.inverse() * gt(first).inverse();
  KeyframePoses poses;
  for (const auto& [id, kf] : map.keyframes())
    poses[id] = Sim3::FromSE3((map_from_truth * gt(id)).inverse());
  return poses;
}

// The global BA of map, its keyframes first moved to `start` (none: from the map as it is).
MapCorrection Converge(const Map& map, LoopClosingOptions loop_options,
                       const MapFloorOptions& options, const KeyframePoses* start) {
  loop_options.global_ba_iterations = options.iterations;
  loop_options.global_ba_function_tolerance = options.function_tolerance;
  MapCorrection moved;
  if (start) {
    moved.before = PosesOf(map);
    moved.after = *start;
  }
  return LoopCloser::GlobalBundleAdjustmentOfMap(map, loop_options, moved).correction;
}

struct ResidualSums {
  int observations = 0, stereo = 0;
  double radial_u = 0, radial_v = 0, disparity = 0;
};

}  // namespace

double KeyframeAte(const Map& map, const Trajectory& truth) { return AteOf(PosesOf(map), truth); }

std::vector<LevelResidual> ResidualsByLevel(const Map& map) {
  const BundleAdjustmentOptions gates;  // BA's chi-square thresholds
  std::map<int, ResidualSums> sums;
  for (const auto& [pid, mp] : map.points()) {
    for (const auto& [kid, kp] : mp.observations) {
      const Keyframe* kf = map.keyframe(kid);
      if (!kf || !kf->frame) continue;
      const Frame& f = *kf->frame;
      if (kp < 0 || kp >= f.size() || f.excluded(kp)) continue;
      const Eigen::Vector3d pc = kf->cam_from_world * mp.p_in_world;
      if (!(pc.z() > 0)) continue;
      const StereoRig& rig = f.rig();
      const PinholeCamera& cam = rig.left;
      const Eigen::Vector2d projected = cam.Project(pc);
      const double u = projected.x(), v = projected.y();
      const Eigen::Vector2d uv = f.uv(kp);
      const double du = uv.x() - u, dv = uv.y() - v;
      const int level = f.octave(kp);
      const double information = f.scale().inv_level_sigma2[level];
      const bool stereo = f.has_stereo(kp) && rig.IsStereo();
      const double dr = stereo ? f.u_right_px(kp) - rig.ProjectRightX(pc) : 0.0;
      const double chi2 = (du * du + dv * dv + dr * dr) * information;
      if (chi2 > (stereo ? gates.chi2_stereo : gates.chi2_mono)) continue;
      ResidualSums& s = sums[level];
      ++s.observations;
      s.radial_u += u >= cam.cx ? du : -du;
      s.radial_v += v >= cam.cy ? dv : -dv;
      if (stereo) {
        ++s.stereo;
        s.disparity += du - dr;  // (u - u_right) observed minus predicted
      }
    }
  }
  std::vector<LevelResidual> out;
  for (const auto& [level, s] : sums) {
    LevelResidual r;
    r.level = level;
    r.observations = s.observations;
    r.stereo = s.stereo;
    r.radial_u_px = s.radial_u / s.observations;
    r.radial_v_px = s.radial_v / s.observations;
    r.disparity_px = s.stereo > 0 ? s.disparity / s.stereo : 0.0;
    out.push_back(r);
  }
  return out;
}

MapFloor MapEstimateFloor(const Map& map, const Trajectory& truth,
                          const LoopClosingOptions& loop_options, const MapFloorOptions& options) {
  if (options.iterations < 1 || !(options.function_tolerance > 0))
    throw ConfigError("map floor: iterations must be >= 1 and function_tolerance > 0");
  MapFloor f;
  f.keyframes = static_cast<int>(map.keyframes().size());
  f.map_m = KeyframeAte(map, truth);
  if (f.keyframes < 3) return f;
  const auto start = std::chrono::steady_clock::now();
  const MapCorrection converged = Converge(map, loop_options, options, nullptr);
  f.converged_m = AteOf(converged.after, truth);
  Map solved = map;
  solved.Apply(LoopCloser::CorrectionDelta(solved, converged));
  f.converged_residuals = ResidualsByLevel(solved);
  const KeyframePoses at_truth = TruePoses(map, truth);
  f.start_m = AteOf(at_truth, truth);
  f.from_truth_m = AteOf(Converge(map, loop_options, options, &at_truth).after, truth);
  f.solve_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

}  // namespace pcr::driver
