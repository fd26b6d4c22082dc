#pragma once
// The map store: keyframes, map points, the covisibility graph and the spanning tree.
//
// Ownership and threading: one serial owner holds the Map and is the only caller of Apply();
// tracking and local mapping read it through `const Map&` and return their edits as a MapDelta.
// Thread-compatible, not thread-safe (a flow graph serialises access around it).
//
// Frames: keyframe poses are cam_from_world; point positions are in the world frame, metres.
#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <unordered_map>
#include <utility>
#include <vector>

#include "slam/common/pose.h"
#include "slam/map/frame.h"
#include "slam/map/ids.h"

namespace pcr {

struct Keyframe {
  KeyframeId id;
  int64_t index = -1;  // insertion order in this map: 0 for the first keyframe
  FramePtr frame;
  SE3 cam_from_world = SE3::Identity();
  std::vector<MapPointId> points;  // per keypoint of frame; invalid id: not associated
  // Covisibility: number of shared map points with every keyframe sharing at least one
  // (symmetric), and the covisible neighbours: weight >= Map::kCovisibilityMinWeight (or the
  // best one when none reaches it), by decreasing weight then increasing id.
  std::map<KeyframeId, int> connections;
  std::vector<std::pair<KeyframeId, int>> covisible;
  // Spanning tree: parent is invalid only for the root (the first keyframe).
  KeyframeId parent;
  std::set<KeyframeId> children;

  Eigen::Vector3d CameraCentre() const { return cam_from_world.inverse().translation(); }
  // Up to n covisible neighbours, best first.
  std::vector<KeyframeId> BestCovisible(size_t n) const;
  int Weight(KeyframeId other) const;
  int NumPoints() const;
};

struct MapPoint {
  MapPointId id;
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  cv::Mat descriptor;  // 1 x 32 CV_8U: the observation descriptor with the least median distance
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // mean unit ray camera -> point, world
  double min_distance_m = 0, max_distance_m = 0;      // scale-invariance range of distances
  std::map<KeyframeId, int> observations;             // keyframe -> keypoint index
  KeyframeId reference_keyframe;
  int64_t first_keyframe_index = -1;  // Keyframe::index of the keyframe that created it
  int visible_count = 1;              // frames in whose frustum it was predicted
  int found_count = 1;                // frames in which it was matched as an inlier

  double FoundRatio() const { return static_cast<double>(found_count) / visible_count; }
  // Predicted pyramid level at distance_m from a camera.
  int PredictLevel(double distance_m, const ScalePyramid& scale) const {
    return scale.PredictLevel(distance_m, max_distance_m);
  }
};

// The map's points in id order (iteration is deterministic), found by id in constant time.
// A std::map lookup walks ~15 nodes of 20-50 thousand points, and the map looks a point up for
// every keypoint it touches (4% of a loop route's run time went to those lookups). The table
// keeps the ordered map and an index of pointers into it, slot id - base: ids are handed out in
// increasing order, so the index grows at its end, and its front is dropped once more than half
// of it lies before the first live id, so it follows the live ids, not the length of the run.
// A copy indexes its own nodes; a move keeps the nodes and with them the pointers.
class PointTable {
 public:
  using Points = std::map<MapPointId, MapPoint>;

  PointTable() = default;
  explicit PointTable(Points points);
  PointTable(const PointTable& other);
  PointTable(PointTable&&) noexcept = default;
  PointTable& operator=(const PointTable& other);
  PointTable& operator=(PointTable&&) noexcept = default;
  ~PointTable() = default;

  const Points& all() const { return points_; }
  size_t size() const { return points_.size(); }
  // Slots of the index (live and erased ids from the first live one on, and at most as many
  // erased ones again before it).
  size_t index_slots() const { return index_.size(); }
  // Null when id is not live.
  const MapPoint* find(MapPointId id) const {
    const int64_t slot = id.value - base_;
    return slot >= 0 && slot < static_cast<int64_t>(index_.size()) ? index_[slot] : nullptr;
  }
  MapPoint* find(MapPointId id) {
    return const_cast<MapPoint*>(static_cast<const PointTable&>(*this).find(id));
  }
  // Throws std::out_of_range when id is not live, as std::map::at does.
  MapPoint& at(MapPointId id);
  // Adds point under id; false, and nothing changes, when id is invalid or live already.
  bool emplace(MapPointId id, MapPoint point);
  void erase(MapPointId id);

 private:
  void Reindex();

  Points points_;
  std::vector<MapPoint*> index_;  // index_[id - base_]: the live point, or null
  int64_t base_ = 0;
};

struct KeyframeObservation {
  KeyframeId keyframe;
  int keypoint = -1;
};

// Edits to apply. Ids that no longer exist when the delta is applied are skipped; point ids are
// first resolved through earlier merges (Map::Resolve).
struct NewKeyframe {
  FramePtr frame;  // its id becomes the keyframe id
  SE3 cam_from_world = SE3::Identity();
  std::vector<std::pair<int, MapPointId>> associations;  // keypoint index -> existing point
  KeyframeId parent_hint;  // spanning-tree parent when the keyframe shares no point
};

struct NewMapPoint {
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  std::vector<KeyframeObservation> observations;  // the first one is the reference keyframe
};

struct ObservationEdit {
  MapPointId point;
  KeyframeId keyframe;
  int keypoint = -1;
};

struct PointMerge {
  MapPointId from;  // erased; its observations move to `into` where the keyframe has none
  MapPointId into;
  // A point merges once per delta: a later merge whose `from` stands for the same point (the
  // same id, or an id merged into it before the delta) is skipped (resolved, it would merge the
  // first `into` with the second, two points nothing compared). A merge whose `from` an earlier
  // merge of the delta moved into its `into` (A->B then B->A) is none.
};

struct MapDelta {
  std::optional<NewKeyframe> new_keyframe;
  std::vector<NewMapPoint> new_points;
  std::vector<PointMerge> merges;
  std::vector<ObservationEdit> added_observations;
  std::vector<ObservationEdit> removed_observations;
  std::vector<std::pair<KeyframeId, SE3>> keyframe_poses;  // new cam_from_world
  std::vector<std::pair<MapPointId, Eigen::Vector3d>> point_positions;
  std::vector<MapPointId> removed_points;
  std::vector<KeyframeId> removed_keyframes;  // the first keyframe is never removed
  std::vector<MapPointId> visible_increments;
  std::vector<MapPointId> found_increments;

  bool empty() const;
  // Appends other's edits after this delta's (applied in Apply's fixed order, not interleaved).
  void Append(const MapDelta& other);
};

struct MapApplyResult {
  std::vector<MapPointId> new_point_ids;  // per delta.new_points; invalid when it was dropped
  int num_merged = 0;
  int num_points_removed = 0;  // explicit removals and points left with too few observations
  int num_keyframes_removed = 0;
};

// Edits a map records as Apply makes them (Map::set_edit_log), for a copy elsewhere that replays
// them in order instead of copying the whole map again (the loop lane's replica, LoopMapReplica).
struct MapEditLog {
  bool recording = false;
  size_t max_edits = 0;  // one more stops the recording and drops the edits; 0: no limit
  std::vector<MapDelta> edits;
};

class Map {
 public:
  static constexpr int kCovisibilityMinWeight = 15;

  // What the map keeps besides its keyframes and points (a saved map stores it too).
  struct ErasedKeyframe {
    KeyframeId parent;
    SE3 cam_from_parent = SE3::Identity();
  };
  struct Bookkeeping {
    std::vector<std::pair<MapPointId, MapPointId>> replaced_by;  // merged id -> into, by id
    std::map<KeyframeId, ErasedKeyframe> erased_keyframes;
    int64_t next_point_id = 0;
    int64_t next_keyframe_index = 0;
    KeyframeId first_keyframe, last_keyframe;
  };
  Bookkeeping bookkeeping() const;
  // A map from stored parts (a saved map), as it was: Restore(keyframes(), points(),
  // bookkeeping()) is equal to the original. Throws std::invalid_argument naming the first
  // inconsistency (a keypoint association and a point's observation that disagree, a keyframe
  // or point id that does not exist, a spanning tree that is not one, ids beyond the counters).
  static Map Restore(std::map<KeyframeId, Keyframe> keyframes,
                     std::map<MapPointId, MapPoint> points, Bookkeeping bookkeeping);

  // Applies the edits in this order: new keyframe (with its associations), new points, merges,
  // added observations, removed observations (a point whose stereo-weighted observation count
  // drops to <= 2 by a removal is erased), keyframe poses, point positions, removed points,
  // removed keyframes, counters; then refreshes the descriptors, normals and distance ranges of
  // touched points and the covisibility of touched keyframes. Throws std::invalid_argument when
  // the new keyframe's id already exists or its frame is null.
  MapApplyResult Apply(const MapDelta& delta);
  // From now on Apply appends each delta it applied to log while log->recording (null: none).
  // The log belongs to this object: a copy of the map records nothing, and assigning another map
  // to this one keeps this one's log.
  void set_edit_log(std::shared_ptr<MapEditLog> log) { edit_log_.log = std::move(log); }

  const Keyframe* keyframe(KeyframeId id) const;
  const MapPoint* point(MapPointId id) const;
  const std::map<KeyframeId, Keyframe>& keyframes() const { return keyframes_; }
  const std::map<MapPointId, MapPoint>& points() const { return points_.all(); }
  bool empty() const { return keyframes_.empty(); }
  size_t num_keyframes() const { return keyframes_.size(); }
  size_t num_points() const { return points_.size(); }
  KeyframeId first_keyframe() const { return first_keyframe_; }
  KeyframeId last_keyframe() const { return last_keyframe_; }

  // The live point that id was merged into (id itself when live); invalid when erased.
  MapPointId Resolve(MapPointId id) const;
  // The merges Apply makes of these, in order, as (live point merged away, live point it merges
  // into): each source resolved before any merge and merged once (PointMerge), each merge on the
  // points the earlier ones left; merges of a gone point, or of a point into itself, are none.
  std::vector<std::pair<MapPointId, MapPointId>> PlanMerges(
      const std::vector<PointMerge>& merges) const;
  // Merged point ids the map remembers for Resolve. Apply forgets those whose point is gone (they
  // resolve to invalid either way) and points the rest straight at their live point whenever the
  // count has doubled since the last time, so the memory follows the live map, not the length of
  // the run (bench_memory, map bounded to 60 keyframes: 54751 entries after 800 frames before).
  size_t num_replacements() const { return replaced_by_.size(); }
  // The live keyframe nearest to id along the spanning tree (id itself when live), or invalid.
  KeyframeId ResolveKeyframe(KeyframeId id) const;
  // Pose of a live or erased keyframe (erased ones keep their pose relative to their parent).
  std::optional<SE3> CamFromWorld(KeyframeId id) const;
  // Points of the keyframe observed by at least min_observations keyframes.
  int TrackedPoints(KeyframeId id, int min_observations) const;
  // Parts of the map: live keyframes joined through shared points (a path of connections), as a
  // part number per keyframe. Part 0 holds the oldest keyframe (the smallest index), the others
  // are numbered by their oldest keyframe's index. A map is one part unless tracking started a
  // new part after a loss, or beside a loaded map, that no loop has joined to the rest.
  std::map<KeyframeId, int> Parts() const;

 private:
  void AddObservation(MapPointId point, KeyframeId keyframe, int keypoint);
  // Returns true when the observation existed and was removed.
  bool RemoveObservation(MapPointId point, KeyframeId keyframe);
  int WeightedObservations(const MapPoint& point) const;
  void ErasePoint(MapPointId id);
  void MergePoint(MapPointId from, MapPointId into);
  void EraseKeyframe(KeyframeId id);
  void CompactReplacements();
  void RefreshPoint(MapPoint& point) const;
  void UpdateConnections(KeyframeId id);
  static void SortCovisible(Keyframe& keyframe);

  std::map<KeyframeId, Keyframe> keyframes_;
  PointTable points_;
  std::unordered_map<MapPointId, MapPointId> replaced_by_;
  size_t replacements_after_compaction_ = 0;
  std::map<KeyframeId, ErasedKeyframe> erased_keyframes_;
  int64_t next_point_id_ = 0;
  int64_t next_keyframe_index_ = 0;
  KeyframeId first_keyframe_, last_keyframe_;
  struct EditLogSlot {
    EditLogSlot() = default;
    EditLogSlot(const EditLogSlot&) {}
    EditLogSlot(EditLogSlot&&) noexcept = default;
    EditLogSlot& operator=(const EditLogSlot&) { return *this; }
    EditLogSlot& operator=(EditLogSlot&&) noexcept { return *this; }
    ~EditLogSlot() = default;
    std::shared_ptr<MapEditLog> log;
  };
  EditLogSlot edit_log_;
  // Scratch sets filled during Apply.
  std::set<MapPointId> touched_points_;
  std::set<KeyframeId> touched_keyframes_;
};

}  // namespace pcr
