#pragma once
// The refined map as files: OUT/map.ply (every map point when the run ended: world position,
// grey level, observation count), OUT/map_removed.ply (keypoints the dynamic filter kept out of
// the map, placed by their stereo depth and their frame's pose, with the reason), OUT/keyframes.txt
// (keyframe poses, TUM format) and OUT/map.png (top view: kept points grey, removed ones red, the
// keyframe trajectory blue, loops green with a ring on the query keyframe). PLY files are
// binary little-endian with the standard header, so CloudCompare, MeshLab or Open3D open them.
#include <nlohmann/json.hpp>
#include <string>

#include "driver/run_slam.h"
#include "graph/pipeline.h"
#include "slam/geometry/ground_height.h"

namespace pcr::driver {

// KITTI's camera height above the road (the synthetic sequences' default too).
inline constexpr double kRoadCameraHeightM = 1.65;

// The road under the map's keyframes (slam/geometry/ground_height.h) at kRoadCameraHeightM.
MapGroundScale RoadScale(const graph::MapSnapshot& map);

// The map's scale from the road under its keyframes (slam/geometry/ground_height.h): "keyframes",
// "estimated" (those with a road), and where any has one "median_height" (map units),
// "metres_per_unit" (kRoadCameraHeightM over it: ~1 on a stereo map, the monocular map's scale
// otherwise) with the keyframes' 10th-90th percentiles; with an evaluation also the alignment's
// scale ("truth_metres_per_unit"; 1 for SE(3)) and "ratio_to_truth", and for a monocular run
// "ate_m_road_scale_se3": the ATE RMSE of its trajectory in the road's metres, aligned by SE(3)
// (stats.json's "ate_m" is the Sim(3)-aligned one).
nlohmann::json GroundScaleJson(const graph::MapSnapshot& map, const RunSummary& summary);

// The map's summary for stats.json ("points", "removed_points", "removed_by_reason",
// "removed_by_truth": moving / parked / static against the dataset's ground truth where it has
// one, "keyframes", "loops": [query, match] pairs of keyframe indices, i.e. of keyframes.txt's
// pose lines, "ground": GroundScaleJson). Writes nothing.
nlohmann::json MapOutputsJson(const graph::MapSnapshot& map, const RunSummary& summary);

// Writes the four files into out_dir (created if needed). A file that cannot be written does not
// keep the others from being written: the first failure (InputError naming the file) is thrown
// at the end.
void WriteMapFiles(const std::string& out_dir, const graph::MapSnapshot& map,
                   const RunSummary& summary);

// Both: the files, then their summary.
nlohmann::json WriteMapOutputs(const std::string& out_dir, const graph::MapSnapshot& map,
                               const RunSummary& summary);

}  // namespace pcr::driver
