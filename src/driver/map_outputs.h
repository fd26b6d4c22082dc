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

namespace pcr::driver {

// Writes the four files into out_dir (created if needed); returns their summary for stats.json
// ("points", "removed_points", "removed_by_reason", "removed_by_truth": moving / parked / static
// against the dataset's ground truth where it has one, "keyframes", "loops": [query, match]
// pairs of keyframe indices, i.e. of keyframes.txt's pose lines). Throws InputError naming the
// file when one cannot be written.
nlohmann::json WriteMapOutputs(const std::string& out_dir, const graph::MapSnapshot& map,
                               const RunSummary& summary);

}  // namespace pcr::driver
