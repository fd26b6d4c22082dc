#pragma once
// The refined map as files: OUT/map.ply (every map point when the run ended: world position,
// grey level, observation count), OUT/map_removed.ply (keypoints the dynamic filter kept out of
// the map, placed by their stereo depth and their frame's pose, with the reason; none in a
// monocular run, which has no depth, as its header says), OUT/keyframes.txt
// (the map's keyframes when the run ended, TUM format: a loaded map's first, then this run's, each
// part under a comment saying what it holds) and OUT/map.png (top view: kept points grey, removed
// ones red, the keyframe trajectory blue, loops green with a ring on the query keyframe). PLY
// files are binary little-endian with the standard header, so CloudCompare, MeshLab or Open3D
// open them.
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

// How many of the map's keyframes (map.keyframes, in the order they were made) came with a loaded
// map (--load-map) and are still in it: those the snapshot marks as no frame of this run
// (frame_index -1), which come before this run's. 0 without a loaded map.
size_t LoadedKeyframes(const graph::MapSnapshot& map);

// Why none of the excluded keypoints is placed (map_removed.ply, stats.json, map.png and the
// run's summary say so), null where they are: a monocular run with the filter on (no depth), or
// a run with the filter off whose segmenter's masks alone excluded keypoints (only the filter's
// decisions, with its depths, are placed).
const char* RemovedPointsUnplacedWhy(const RunSummary& summary);
bool RemovedPointsUnplaced(const RunSummary& summary);

inline constexpr const char* kRemovedPointsUnplaced =
    "monocular: the keypoints the filter excluded have no depth to place them by (stereo depth "
    "places them), so map_removed.ply holds none";
inline constexpr const char* kMaskExclusionsUnplaced =
    "the filter is off: the segmenter's masks alone excluded these keypoints, and map_removed.ply "
    "places only the filter's decisions (--filter on), so it holds none";

// The keypoints kept out of tracking and the map over the frames that ran: with the filter on,
// summary.filter_reasons' counts other than "kept" (the stereo ones with depth in tracked frames
// are summary.removed_points); with it off, those a segmenter's masks excluded
// (summary.keypoints_excluded).
size_t ExcludedKeypoints(const RunSummary& summary);

// map.png's title line: the counts of what it draws.
std::string MapPictureTitle(const graph::MapSnapshot& map, const RunSummary& summary);

// The map's summary for stats.json ("points", "removed_points" (map_removed.ply's points),
// "removed_by_reason", "removed_by_truth": moving / parked / static against the dataset's ground
// truth where it has one; a monocular run with the filter on places none: "removed_points" null
// and "removed_points_unplaced" says why; with the filter on, "excluded_keypoints":
// ExcludedKeypoints; "keyframes", "keyframes_loaded": LoadedKeyframes, the first pose lines of
// keyframes.txt,
// "loops": [query, match] pairs of keyframe indices, i.e. of keyframes.txt's pose lines, "ground":
// GroundScaleJson). Writes nothing.
nlohmann::json MapOutputsJson(const graph::MapSnapshot& map, const RunSummary& summary);

// Writes OUT/keyframes.txt: TUM lines (t in s with 9 decimals, then tx ty tz qx qy qz qw of
// world_from_cam in %.17g, as trajectory_tum.txt), one per keyframe of `map` in its order, so that
// stats.json's loop indices count its pose lines. Comment lines say what they hold: the world
// frame and units, that the poses are the map's when the run ended (after this run's bundle
// adjustments and loop corrections: a loaded keyframe's pose need not be the saved one), and
// before each part its keyframe indices and what they are: the loaded ones (made by the runs that
// built the map, stamped with their frames' times; where this run has a frame of the same image,
// its pose in the trajectory is this run's own estimate and differs by the two estimates' error)
// and those made in this run (each exactly its frame's pose in trajectory_tum.txt). With a loaded
// map the timestamps go back or repeat where this run's part starts: the whole file is then no one
// trajectory, this run's part is. Throws InputError naming the file when it cannot be written.
void WriteKeyframesFile(const std::string& path, const graph::MapSnapshot& map,
                        const RunSummary& summary);

// Writes the four files into out_dir (created if needed). A file that cannot be written does not
// keep the others from being written: the first failure (InputError naming the file) is thrown
// at the end.
void WriteMapFiles(const std::string& out_dir, const graph::MapSnapshot& map,
                   const RunSummary& summary);

// Both: the files, then their summary.
nlohmann::json WriteMapOutputs(const std::string& out_dir, const graph::MapSnapshot& map,
                               const RunSummary& summary);

}  // namespace pcr::driver
