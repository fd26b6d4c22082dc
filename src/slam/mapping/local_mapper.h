#pragma once
// Local mapping for one new keyframe, as a sequence of pure steps that read the map and return
// a MapDelta: stereo points from the keyframe's close unmatched keypoints, culling of recently
// created points, triangulation against covisible keyframes, fusion of duplicates with the
// neighbours, local bundle adjustment, and culling of redundant keyframes.
//
// ProcessKeyframe() runs the steps in order and applies each delta to the map before the next
// step reads it; the caller hands it the map for that call (it is the map's serial owner then).
// Thread-compatible: the mapper keeps the list of recently created points between keyframes.
#include <string>
#include <vector>

#include "slam/map/map.h"
#include "slam/optim/bundle_adjustment.h"

namespace pcr {

struct LocalMapperOptions {
  double close_depth_baselines = 40;  // close stereo depth: < this * baseline
  int min_stereo_points = 100;        // per keyframe: every close one, far ones up to this count
  int triangulation_neighbours = 10;  // covisible keyframes to triangulate with
  double min_found_ratio = 0.25;      // recent points found/visible below this are culled
  int min_weighted_observations = 3;  // recent points with this many or fewer (stereo counts 2)
  int cull_after_keyframes = 2;       // ... are culled this many keyframes after creation
  int recent_keyframes = 3;           // points stop being "recent" after this many keyframes
  int fuse_neighbours = 10;           // first-order neighbours for fusion
  int fuse_second_neighbours = 5;     // neighbours of each of them
  double fuse_radius_factor = 3.0;    // search window (times the level scale)
  bool local_bundle_adjustment = true;
  // Keyframes the local BA optimises besides the new one: its best covisible neighbours (by
  // shared points), at most this many; 0: all of them. On a long straight street every keyframe
  // shares its far points with all the earlier ones, and after a loop closure with the first
  // pass's too, so an unbounded window grows to the whole street.
  int ba_local_keyframes = 20;
  BundleAdjustmentOptions bundle_adjustment;
  bool cull_keyframes = true;
  // Bounded map (long replays, odometry without loop closing): above this many keyframes the
  // oldest ones (never the first, never the newest) are forgotten with the points only they
  // observe; the trajectory keeps their poses (chained to their spanning-tree parents).
  // 0: unbounded.
  int max_keyframes = 0;
  double redundant_fraction = 0.9;  // keyframe culled when this fraction of its close points ...
  int redundant_observers = 3;      // ... is seen by this many other keyframes at the same or
                                    // a finer scale
  bool IsValid(std::string* why) const;
};

struct MappingResult {
  KeyframeId keyframe;
  int stereo_points_created = 0;
  int points_triangulated = 0;
  int recent_points_culled = 0;
  int points_fused = 0;  // observations added plus points merged
  int ba_outlier_observations = 0;
  int ba_keyframes = 0, ba_fixed_keyframes = 0, ba_points = 0;
  int keyframes_culled = 0;
  int keyframes_forgotten = 0;  // by max_keyframes
  double ba_initial_cost = 0, ba_final_cost = 0;
  int ba_iterations = 0;  // solver iterations of the local BA (both solves)
  // Step times in milliseconds: stereo, culling, triangulation, fusion, ba, keyframe_culling.
  double stereo_ms = 0, culling_ms = 0, triangulation_ms = 0, fusion_ms = 0, ba_ms = 0,
         keyframe_culling_ms = 0;
};

class LocalMapper {
 public:
  // Throws ConfigError when options are invalid.
  explicit LocalMapper(const LocalMapperOptions& options);

  // Runs all steps for keyframe id (already in the map), applying each step's delta.
  // ba_max_iterations > 0 caps this keyframe's local BA below the options' (a scheduler's
  // low-quality level); 0: the options'.
  MappingResult ProcessKeyframe(KeyframeId id, Map* map, int ba_max_iterations = 0);

  // The steps, each a pure function of the map (and, for culling, the recent-point list).
  MapDelta CreateStereoPoints(KeyframeId id, const Map& map) const;
  MapDelta CullRecentPoints(KeyframeId id, const Map& map,
                            const std::vector<MapPointId>& recent_points,
                            std::vector<MapPointId>* still_recent) const;
  MapDelta TriangulatePoints(KeyframeId id, const Map& map) const;
  // into_neighbours: the keyframe's points into its neighbours; else the neighbours' points
  // into the keyframe.
  MapDelta FusePoints(KeyframeId id, const Map& map, bool into_neighbours) const;
  MapDelta LocalBundleAdjustment(KeyframeId id, const Map& map, MappingResult* stats,
                                 int ba_max_iterations = 0) const;
  MapDelta CullKeyframes(KeyframeId id, const Map& map) const;

  const std::vector<MapPointId>& recent_points() const { return recent_points_; }
  const LocalMapperOptions& options() const { return options_; }

 private:
  std::vector<KeyframeId> FuseTargets(const Keyframe& kf, const Map& map) const;

  LocalMapperOptions options_;
  std::vector<MapPointId> recent_points_;
};

}  // namespace pcr
