#include "driver/map_floor.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <map>
#include <stdexcept>

#include "eval/association.h"
#include "eval/evaluation.h"
#include "slam/common/error.h"

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
    spdlog::warn("keyframe ATE: {}", e.what());
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

// The keyframe poses after the global BA of map, its keyframes first moved to `start` (none:
// from the map as it is).
KeyframePoses Converge(const Map& map, LoopClosingOptions loop_options,
                       const MapFloorOptions& options, const KeyframePoses* start) {
  loop_options.global_ba_iterations = options.iterations;
  loop_options.global_ba_function_tolerance = options.function_tolerance;
  MapCorrection moved;
  if (start) {
    moved.before = PosesOf(map);
    moved.after = *start;
  }
  return LoopCloser::GlobalBundleAdjustmentOfMap(map, loop_options, moved).correction.after;
}

}  // namespace

double KeyframeAte(const Map& map, const Trajectory& truth) { return AteOf(PosesOf(map), truth); }

MapFloor MapEstimateFloor(const Map& map, const Trajectory& truth,
                          const LoopClosingOptions& loop_options, const MapFloorOptions& options) {
  if (options.iterations < 1 || !(options.function_tolerance > 0))
    throw ConfigError("map floor: iterations must be >= 1 and function_tolerance > 0");
  MapFloor f;
  f.keyframes = static_cast<int>(map.keyframes().size());
  f.map_m = KeyframeAte(map, truth);
  if (f.keyframes < 3) return f;
  const auto start = std::chrono::steady_clock::now();
  f.converged_m = AteOf(Converge(map, loop_options, options, nullptr), truth);
  const KeyframePoses at_truth = TruePoses(map, truth);
  f.start_m = AteOf(at_truth, truth);
  f.from_truth_m = AteOf(Converge(map, loop_options, options, &at_truth), truth);
  f.solve_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

}  // namespace pcr::driver
