#include "slam/map/map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_set>

#include "slam/common/disjoint_sets.h"

namespace pcr {

PointTable::PointTable(Points points) : points_(std::move(points)) { Reindex(); }

PointTable::PointTable(const PointTable& other) : points_(other.points_) { Reindex(); }

PointTable& PointTable::operator=(const PointTable& other) {
  if (this != &other) {
    points_ = other.points_;
    Reindex();
  }
  return *this;
}

MapPoint& PointTable::at(MapPointId id) {
  MapPoint* p = find(id);
  if (!p) throw std::out_of_range("map point " + std::to_string(id.value) + " is not live");
  return *p;
}

bool PointTable::emplace(MapPointId id, MapPoint point) {
  if (!id.valid() || find(id)) return false;
  MapPoint& stored = points_.emplace(id, std::move(point)).first->second;
  if (id.value < base_ || index_.empty()) {
    Reindex();
    return true;
  }
  const auto slot = static_cast<size_t>(id.value - base_);
  if (slot >= index_.size()) index_.resize(slot + 1, nullptr);
  index_[slot] = &stored;
  return true;
}

void PointTable::erase(MapPointId id) {
  if (!find(id)) return;
  index_[static_cast<size_t>(id.value - base_)] = nullptr;
  points_.erase(id);
  if (points_.empty()) {
    index_.clear();
    base_ = 0;
    return;
  }
  // Amortised: the slots dropped were all erased since the last drop or rebuild.
  const int64_t first = points_.begin()->first.value - base_;
  if (first > static_cast<int64_t>(index_.size() / 2)) {
    index_.erase(index_.begin(), index_.begin() + first);
    base_ += first;
  }
}

void PointTable::Reindex() {
  index_.clear();
  base_ = 0;
  if (points_.empty()) return;
  base_ = points_.begin()->first.value;
  index_.assign(static_cast<size_t>(points_.rbegin()->first.value - base_ + 1), nullptr);
  for (auto& [id, point] : points_) index_[static_cast<size_t>(id.value - base_)] = &point;
}

std::vector<KeyframeId> Keyframe::BestCovisible(size_t n) const {
  std::vector<KeyframeId> ids;
  for (size_t i = 0; i < covisible.size() && i < n; ++i) ids.push_back(covisible[i].first);
  return ids;
}

int Keyframe::Weight(KeyframeId other) const {
  const auto it = connections.find(other);
  return it == connections.end() ? 0 : it->second;
}

int Keyframe::NumPoints() const {
  return static_cast<int>(
      std::count_if(points.begin(), points.end(), [](MapPointId id) { return id.valid(); }));
}

bool MapDelta::empty() const {
  return !new_keyframe && new_points.empty() && merges.empty() && added_observations.empty() &&
         removed_observations.empty() && keyframe_poses.empty() && point_positions.empty() &&
         removed_points.empty() && removed_keyframes.empty() && visible_increments.empty() &&
         found_increments.empty();
}

void MapDelta::Append(const MapDelta& other) {
  if (other.new_keyframe) {
    if (new_keyframe) throw std::invalid_argument("MapDelta::Append: two new keyframes");
    new_keyframe = other.new_keyframe;
  }
  auto add = [](auto& into, const auto& from) {
    into.insert(into.end(), from.begin(), from.end());
  };
  add(new_points, other.new_points);
  add(merges, other.merges);
  add(added_observations, other.added_observations);
  add(removed_observations, other.removed_observations);
  add(keyframe_poses, other.keyframe_poses);
  add(point_positions, other.point_positions);
  add(removed_points, other.removed_points);
  add(removed_keyframes, other.removed_keyframes);
  add(visible_increments, other.visible_increments);
  add(found_increments, other.found_increments);
}

const Keyframe* Map::keyframe(KeyframeId id) const {
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}

const MapPoint* Map::point(MapPointId id) const { return points_.find(id); }

MapPointId Map::Resolve(MapPointId id) const {
  // Chains are acyclic and shorter than the number of replacements (compaction shortens them).
  for (size_t hops = 0; id.valid() && hops <= replaced_by_.size(); ++hops) {
    if (points_.find(id)) return id;
    const auto it = replaced_by_.find(id);
    if (it == replaced_by_.end()) return MapPointId();
    id = it->second;
  }
  return MapPointId();
}

std::vector<std::pair<MapPointId, MapPointId>> Map::PlanMerges(
    const std::vector<PointMerge>& merges) const {
  // A point merges once per delta: the sources are resolved before any merge is made, so two
  // ids that stood for one point (merged by an earlier delta) merge it once, not into two points
  // nothing compared; a merge back onto a point merged away in this delta is none.
  std::unordered_map<MapPointId, MapPointId> into_of;  // the merges planned so far
  auto resolve = [&](MapPointId id) {
    MapPointId r = Resolve(id);
    for (auto it = into_of.find(r); it != into_of.end(); it = into_of.find(r)) r = it->second;
    return r;
  };
  std::vector<std::pair<MapPointId, MapPointId>> plan;
  std::unordered_set<MapPointId> sources;
  for (const PointMerge& merge : merges) {
    if (!sources.insert(Resolve(merge.from)).second) continue;
    const MapPointId from = resolve(merge.from), into = resolve(merge.into);
    if (!from.valid() || !into.valid() || from == into) continue;
    into_of[from] = into;
    plan.emplace_back(from, into);
  }
  return plan;
}

KeyframeId Map::ResolveKeyframe(KeyframeId id) const {
  for (int hops = 0; id.valid() && hops < 100000; ++hops) {
    if (keyframes_.count(id)) return id;
    const auto it = erased_keyframes_.find(id);
    if (it == erased_keyframes_.end()) return KeyframeId();
    id = it->second.parent;
  }
  return KeyframeId();
}

std::map<KeyframeId, int> Map::Parts() const {
  std::vector<const Keyframe*> by_index;
  for (const auto& [id, kf] : keyframes_) by_index.push_back(&kf);
  std::sort(by_index.begin(), by_index.end(),
            [](const Keyframe* a, const Keyframe* b) { return a->index < b->index; });
  std::map<KeyframeId, size_t> position;
  for (size_t i = 0; i < by_index.size(); ++i) position.emplace(by_index[i]->id, i);
  DisjointSets sets(by_index.size());
  for (size_t i = 0; i < by_index.size(); ++i)
    for (const auto& [n, w] : by_index[i]->connections)
      if (const auto it = position.find(n); w > 0 && it != position.end()) sets.Join(i, it->second);
  // Numbered in the order of their oldest keyframes.
  std::map<size_t, int> number;
  std::map<KeyframeId, int> parts;
  for (size_t i = 0; i < by_index.size(); ++i) {
    const auto [it, added] = number.emplace(sets.Find(i), static_cast<int>(number.size()));
    parts.emplace(by_index[i]->id, it->second);
  }
  return parts;
}

std::optional<SE3> Map::CamFromWorld(KeyframeId id) const {
  SE3 cam_from_live = SE3::Identity();
  for (int hops = 0; id.valid() && hops < 100000; ++hops) {
    if (const Keyframe* kf = keyframe(id)) return cam_from_live * kf->cam_from_world;
    const auto it = erased_keyframes_.find(id);
    if (it == erased_keyframes_.end()) return std::nullopt;
    cam_from_live = cam_from_live * it->second.cam_from_parent;
    id = it->second.parent;
  }
  return std::nullopt;
}

int Map::TrackedPoints(KeyframeId id, int min_observations) const {
  const Keyframe* kf = keyframe(id);
  if (!kf) return 0;
  int count = 0;
  for (MapPointId p : kf->points) {
    if (!p.valid()) continue;
    const MapPoint* mp = point(p);
    if (mp && static_cast<int>(mp->observations.size()) >= min_observations) ++count;
  }
  return count;
}

Map::Bookkeeping Map::bookkeeping() const {
  Bookkeeping b;
  b.replaced_by.assign(replaced_by_.begin(), replaced_by_.end());
  std::sort(b.replaced_by.begin(), b.replaced_by.end());
  b.erased_keyframes = erased_keyframes_;
  b.next_point_id = next_point_id_;
  b.next_keyframe_index = next_keyframe_index_;
  b.first_keyframe = first_keyframe_;
  b.last_keyframe = last_keyframe_;
  return b;
}

namespace {

// Restore's limits on a stored map: ids and counters (incremented as the map grows) and the span
// of the live point ids, which the point index holds one slot each (2^26 slots: 512 MiB).
constexpr int64_t kMaxMapId = int64_t{1} << 62;
constexpr int64_t kMaxPointIdSpan = int64_t{1} << 26;

[[noreturn]] void Inconsistent(const std::string& what) {
  throw std::invalid_argument("inconsistent map: " + what);
}

std::string Kf(KeyframeId id) { return "keyframe " + std::to_string(id.value); }
std::string Pt(MapPointId id) { return "map point " + std::to_string(id.value); }

bool Finite(const SE3& pose) { return pose.matrix().allFinite(); }

}  // namespace

Map Map::Restore(std::map<KeyframeId, Keyframe> keyframes, std::map<MapPointId, MapPoint> points,
                 Bookkeeping bookkeeping) {
  const Bookkeeping& b = bookkeeping;
  if (keyframes.empty()) {
    if (!points.empty()) Inconsistent("map points without keyframes");
    if (b.first_keyframe.valid() || b.last_keyframe.valid())
      Inconsistent("first or last keyframe set in an empty map");
  } else if (!keyframes.count(b.first_keyframe) || !keyframes.count(b.last_keyframe)) {
    Inconsistent("the first or last keyframe is not in the map");
  }
  // Ids and counters far below int64's end (they are incremented), and live point ids within a
  // span the point index can hold (one slot per id between the lowest and the highest).
  if (b.next_point_id < 0 || b.next_point_id > kMaxMapId || b.next_keyframe_index < 0 ||
      b.next_keyframe_index > kMaxMapId)
    Inconsistent("an id counter is negative or beyond " + std::to_string(kMaxMapId));
  if (!points.empty() &&
      points.rbegin()->first.value - points.begin()->first.value >= kMaxPointIdSpan)
    Inconsistent("the live point ids span " +
                 std::to_string(points.rbegin()->first.value - points.begin()->first.value) +
                 " ids, more than " + std::to_string(kMaxPointIdSpan));
  std::set<int64_t> indices;
  for (const auto& [id, kf] : keyframes) {
    if (!id.valid() || kf.id != id || id.value > kMaxMapId)
      Inconsistent(Kf(id) + " stored under another id, or beyond " + std::to_string(kMaxMapId));
    if (!kf.frame || kf.frame->id() != id.value) Inconsistent(Kf(id) + " has no frame of its id");
    if (kf.index < 0 || kf.index >= b.next_keyframe_index || !indices.insert(kf.index).second)
      Inconsistent(Kf(id) + " has an index beyond the counter or used twice");
    if (!Finite(kf.cam_from_world)) Inconsistent(Kf(id) + " has a pose that is not finite");
    if (kf.points.size() != static_cast<size_t>(kf.frame->size()))
      Inconsistent(Kf(id) + " has associations of another size than its keypoints");
    for (size_t i = 0; i < kf.points.size(); ++i) {
      const MapPointId p = kf.points[i];
      if (!p.valid()) continue;
      const auto pit = points.find(p);
      if (pit == points.end()) Inconsistent(Kf(id) + " associates a missing " + Pt(p));
      const auto oit = pit->second.observations.find(id);
      if (oit == pit->second.observations.end() || oit->second != static_cast<int>(i))
        Inconsistent(Kf(id) + " and " + Pt(p) + " disagree on the observation");
    }
    for (const auto& [other, weight] : kf.connections) {
      const auto oit = keyframes.find(other);
      if (other == id || oit == keyframes.end() || weight <= 0 || oit->second.Weight(id) != weight)
        Inconsistent(Kf(id) + " has a connection that is not symmetric");
    }
    for (const auto& [other, weight] : kf.covisible)
      if (kf.Weight(other) != weight || weight <= 0)
        Inconsistent(Kf(id) + " has a covisible keyframe that is not a connection");
    if (id == b.first_keyframe ? kf.parent.valid() : !keyframes.count(kf.parent))
      Inconsistent(Kf(id) + " has a missing spanning-tree parent");
    if (kf.parent.valid() && !keyframes.at(kf.parent).children.count(id))
      Inconsistent(Kf(id) + " is not a child of its parent");
    for (KeyframeId c : kf.children) {
      const auto cit = keyframes.find(c);
      if (cit == keyframes.end() || cit->second.parent != id)
        Inconsistent(Kf(id) + " has a child whose parent it is not");
    }
  }
  // The spanning tree reaches the first keyframe from everywhere (no cycle).
  for (const auto& [id, kf] : keyframes) {
    KeyframeId at = id;
    for (size_t hops = 0; at != b.first_keyframe; ++hops) {
      if (hops > keyframes.size()) Inconsistent(Kf(id) + " is on a spanning-tree cycle");
      at = keyframes.at(at).parent;
    }
  }
  for (const auto& [id, mp] : points) {
    if (!id.valid() || mp.id != id || id.value >= b.next_point_id)
      Inconsistent(Pt(id) + " stored under another id or beyond the counter");
    if (mp.observations.empty()) Inconsistent(Pt(id) + " has no observation");
    for (const auto& [kf_id, kp] : mp.observations) {
      const auto kit = keyframes.find(kf_id);
      if (kit == keyframes.end() || kp < 0 || kp >= static_cast<int>(kit->second.points.size()) ||
          kit->second.points[kp] != id)
        Inconsistent(Pt(id) + " and " + Kf(kf_id) + " disagree on the observation");
    }
    if (!keyframes.count(mp.reference_keyframe))
      Inconsistent(Pt(id) + " has a missing reference keyframe");
    if (mp.descriptor.rows != 1 || mp.descriptor.cols != 32 || mp.descriptor.type() != CV_8U)
      Inconsistent(Pt(id) + " has no 1 x 32 descriptor");
    if (!mp.p_in_world.allFinite() || !mp.normal.allFinite() || !std::isfinite(mp.min_distance_m) ||
        !std::isfinite(mp.max_distance_m))
      Inconsistent(Pt(id) + " is not finite");
    if (mp.visible_count < 1 || mp.found_count < 0)
      Inconsistent(Pt(id) + " has invalid visible/found counters");
  }
  for (const auto& [from, into] : b.replaced_by)
    if (!from.valid() || points.count(from)) Inconsistent(Pt(from) + " is merged and live");
  for (const auto& [id, erased] : b.erased_keyframes)
    if (!id.valid() || id.value > kMaxMapId || keyframes.count(id) ||
        !Finite(erased.cam_from_parent))
      Inconsistent(Kf(id) + " is erased and live, or has a pose that is not finite");

  Map map;
  map.keyframes_ = std::move(keyframes);
  map.points_ = PointTable(std::move(points));
  map.replaced_by_.insert(b.replaced_by.begin(), b.replaced_by.end());
  map.replacements_after_compaction_ = map.replaced_by_.size();
  map.erased_keyframes_ = std::move(bookkeeping.erased_keyframes);
  map.next_point_id_ = b.next_point_id;
  map.next_keyframe_index_ = b.next_keyframe_index;
  map.first_keyframe_ = b.first_keyframe;
  map.last_keyframe_ = b.last_keyframe;
  return map;
}

void Map::AddObservation(MapPointId point_id, KeyframeId keyframe_id, int keypoint) {
  MapPoint* point = points_.find(point_id);
  auto kit = keyframes_.find(keyframe_id);
  if (!point || kit == keyframes_.end()) return;
  Keyframe& kf = kit->second;
  if (keypoint < 0 || keypoint >= static_cast<int>(kf.points.size())) return;
  if (kf.points[keypoint].valid() || point->observations.count(keyframe_id)) return;
  kf.points[keypoint] = point_id;
  point->observations[keyframe_id] = keypoint;
  touched_points_.insert(point_id);
  touched_keyframes_.insert(keyframe_id);
}

bool Map::RemoveObservation(MapPointId point_id, KeyframeId keyframe_id) {
  MapPoint* point = points_.find(point_id);
  if (!point) return false;
  auto oit = point->observations.find(keyframe_id);
  if (oit == point->observations.end()) return false;
  auto kit = keyframes_.find(keyframe_id);
  if (kit != keyframes_.end() && oit->second >= 0 &&
      oit->second < static_cast<int>(kit->second.points.size()) &&
      kit->second.points[oit->second] == point_id)
    kit->second.points[oit->second] = MapPointId();
  point->observations.erase(oit);
  touched_points_.insert(point_id);
  touched_keyframes_.insert(keyframe_id);
  return true;
}

int Map::WeightedObservations(const MapPoint& point) const {
  int count = 0;
  for (const auto& [kf_id, kp] : point.observations) {
    const Keyframe* kf = keyframe(kf_id);
    count += (kf && kf->frame->has_stereo(kp)) ? 2 : 1;
  }
  return count;
}

void Map::ErasePoint(MapPointId id) {
  const MapPoint* point = points_.find(id);
  if (!point) return;
  for (const auto& [kf_id, kp] : point->observations) {
    auto kit = keyframes_.find(kf_id);
    if (kit == keyframes_.end()) continue;
    if (kit->second.points[kp] == id) kit->second.points[kp] = MapPointId();
    touched_keyframes_.insert(kf_id);
  }
  points_.erase(id);
  touched_points_.erase(id);
}

void Map::CompactReplacements() {
  std::unordered_map<MapPointId, MapPointId> compact;
  for (const auto& [from, into] : replaced_by_) {
    const MapPointId live = Resolve(into);
    if (live.valid()) compact.emplace(from, live);
  }
  replaced_by_ = std::move(compact);
  replacements_after_compaction_ = replaced_by_.size();
}

void Map::MergePoint(MapPointId from, MapPointId into) {
  from = Resolve(from);
  into = Resolve(into);
  if (!from.valid() || !into.valid() || from == into) return;
  MapPoint& src = points_.at(from);
  const std::map<KeyframeId, int> observations = src.observations;
  const int visible = src.visible_count, found = src.found_count;
  for (const auto& [kf_id, kp] : observations) {
    RemoveObservation(from, kf_id);
    AddObservation(into, kf_id, kp);
  }
  MapPoint& dst = points_.at(into);
  dst.visible_count += visible;
  dst.found_count += found;
  touched_points_.insert(into);
  ErasePoint(from);
  replaced_by_[from] = into;
}

void Map::EraseKeyframe(KeyframeId id) {
  auto kit = keyframes_.find(id);
  if (kit == keyframes_.end() || id == first_keyframe_) return;
  // Observations: a point left with too few observations goes with the keyframe.
  const std::vector<MapPointId> points = kit->second.points;
  for (MapPointId p : points) {
    if (!p.valid() || !RemoveObservation(p, id)) continue;
    const MapPoint* mp = point(p);
    if (mp && (mp->observations.empty() || WeightedObservations(*mp) <= 2)) ErasePoint(p);
  }
  Keyframe& kf = keyframes_.at(id);
  // Covisibility.
  for (const auto& [other, weight] : kf.connections) {
    auto oit = keyframes_.find(other);
    if (oit == keyframes_.end()) continue;
    oit->second.connections.erase(id);
    SortCovisible(oit->second);
  }
  // Spanning tree: children pick, greedily by covisibility weight, a parent among the erased
  // keyframe's parent and the children already re-attached; the rest go to the parent.
  const KeyframeId parent = kf.parent;
  std::set<KeyframeId> candidates;
  if (parent.valid() && keyframes_.count(parent)) candidates.insert(parent);
  std::set<KeyframeId> remaining;
  for (KeyframeId c : kf.children)
    if (keyframes_.count(c)) remaining.insert(c);
  while (!remaining.empty() && !candidates.empty()) {
    KeyframeId best_child, best_parent;
    int best_weight = 0;
    for (KeyframeId c : remaining) {
      const Keyframe& child = keyframes_.at(c);
      for (KeyframeId cand : candidates) {
        const int w = child.Weight(cand);
        if (w > best_weight) {
          best_weight = w;
          best_child = c;
          best_parent = cand;
        }
      }
    }
    if (!best_child.valid()) break;
    keyframes_.at(best_child).parent = best_parent;
    keyframes_.at(best_parent).children.insert(best_child);
    candidates.insert(best_child);
    remaining.erase(best_child);
  }
  for (KeyframeId c : remaining) {
    keyframes_.at(c).parent = parent;
    if (parent.valid() && keyframes_.count(parent)) keyframes_.at(parent).children.insert(c);
  }
  if (parent.valid() && keyframes_.count(parent)) keyframes_.at(parent).children.erase(id);
  ErasedKeyframe erased;
  erased.parent = parent;
  if (parent.valid() && keyframes_.count(parent))
    erased.cam_from_parent = kf.cam_from_world * keyframes_.at(parent).cam_from_world.inverse();
  erased_keyframes_[id] = erased;
  keyframes_.erase(id);
  touched_keyframes_.erase(id);
  if (last_keyframe_ == id) {  // the newest keyframe left
    last_keyframe_ = KeyframeId();
    int64_t newest = -1;
    for (const auto& [other_id, other] : keyframes_)
      if (other.index > newest) {
        newest = other.index;
        last_keyframe_ = other_id;
      }
  }
}

void Map::RefreshPoint(MapPoint& point) const {
  // Representative descriptor: least median Hamming distance to the other observations.
  std::vector<cv::Mat> descriptors;
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  for (const auto& [kf_id, kp] : point.observations) {
    const Keyframe* kf = keyframe(kf_id);
    if (!kf) continue;
    descriptors.push_back(kf->frame->descriptor(kp));
    const Eigen::Vector3d ray = point.p_in_world - kf->CameraCentre();
    if (ray.norm() > 0) normal_sum += ray.normalized();
  }
  if (descriptors.empty()) return;
  const size_t n = descriptors.size();
  if (n <= 2) {
    point.descriptor = descriptors[0];
  } else {
    std::vector<std::vector<int>> dist(n, std::vector<int>(n, 0));
    for (size_t i = 0; i < n; ++i)
      for (size_t j = i + 1; j < n; ++j)
        dist[i][j] = dist[j][i] = DescriptorDistance(descriptors[i], descriptors[j]);
    // Least median distance to the other observations (lower median), ties broken by the sum.
    std::pair<int, int> best_key{std::numeric_limits<int>::max(), 0};
    size_t best = 0;
    for (size_t i = 0; i < n; ++i) {
      std::vector<int> row;
      int sum = 0;
      for (size_t j = 0; j < n; ++j)
        if (j != i) {
          row.push_back(dist[i][j]);
          sum += dist[i][j];
        }
      std::nth_element(row.begin(), row.begin() + (row.size() - 1) / 2, row.end());
      const std::pair<int, int> key{row[(row.size() - 1) / 2], sum};
      if (key < best_key) {
        best_key = key;
        best = i;
      }
    }
    point.descriptor = descriptors[best];
  }
  if (normal_sum.norm() > 0) point.normal = normal_sum.normalized();
  // Scale-invariance distances from the reference keyframe.
  if (!point.observations.count(point.reference_keyframe))
    point.reference_keyframe = point.observations.begin()->first;
  const Keyframe* ref = keyframe(point.reference_keyframe);
  if (!ref) return;
  const int kp = point.observations.at(point.reference_keyframe);
  const ScalePyramid& scale = ref->frame->scale();
  const double distance = (point.p_in_world - ref->CameraCentre()).norm();
  const int level = ref->frame->octave(kp);
  point.max_distance_m = distance * scale.scale_factors[level];
  point.min_distance_m = point.max_distance_m / scale.scale_factors.back();
}

void Map::SortCovisible(Keyframe& keyframe) {
  keyframe.covisible.clear();
  std::pair<KeyframeId, int> best{KeyframeId(), 0};
  for (const auto& [other, weight] : keyframe.connections) {
    if (weight >= kCovisibilityMinWeight) keyframe.covisible.emplace_back(other, weight);
    if (weight > best.second) best = {other, weight};
  }
  if (keyframe.covisible.empty() && best.first.valid()) keyframe.covisible.push_back(best);
  std::sort(keyframe.covisible.begin(), keyframe.covisible.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first < b.first;
  });
}

void Map::UpdateConnections(KeyframeId id) {
  auto kit = keyframes_.find(id);
  if (kit == keyframes_.end()) return;
  Keyframe& kf = kit->second;
  std::map<KeyframeId, int> counts;
  for (MapPointId p : kf.points) {
    if (!p.valid()) continue;
    const MapPoint* mp = point(p);
    if (!mp) continue;
    for (const auto& obs : mp->observations)
      if (obs.first != id) ++counts[obs.first];
  }
  for (const auto& [other, weight] : kf.connections) {
    if (counts.count(other)) continue;
    auto oit = keyframes_.find(other);
    if (oit == keyframes_.end()) continue;
    oit->second.connections.erase(id);
    SortCovisible(oit->second);
  }
  for (const auto& [other, weight] : counts) {
    Keyframe& o = keyframes_.at(other);
    auto cit = o.connections.find(id);
    if (cit != o.connections.end() && cit->second == weight) continue;
    o.connections[id] = weight;
    SortCovisible(o);
  }
  kf.connections = std::move(counts);
  SortCovisible(kf);
}

MapApplyResult Map::Apply(const MapDelta& delta) {
  MapApplyResult result;
  touched_points_.clear();
  touched_keyframes_.clear();
  KeyframeId new_keyframe_id;

  if (delta.new_keyframe) {
    const NewKeyframe& nk = *delta.new_keyframe;
    if (!nk.frame) throw std::invalid_argument("Map::Apply: new keyframe without a frame");
    const KeyframeId id(nk.frame->id());
    if (keyframes_.count(id) || erased_keyframes_.count(id))
      throw std::invalid_argument("Map::Apply: keyframe id already used");
    Keyframe kf;
    kf.id = id;
    kf.index = next_keyframe_index_++;
    kf.frame = nk.frame;
    kf.cam_from_world = nk.cam_from_world;
    kf.points.assign(nk.frame->size(), MapPointId());
    keyframes_.emplace(id, std::move(kf));
    if (!first_keyframe_.valid()) first_keyframe_ = id;
    last_keyframe_ = id;
    new_keyframe_id = id;
    touched_keyframes_.insert(id);
    for (const auto& [kp, p] : nk.associations) AddObservation(Resolve(p), id, kp);
  }

  for (const NewMapPoint& np : delta.new_points) {
    MapPoint mp;
    mp.id = MapPointId(next_point_id_);
    mp.p_in_world = np.p_in_world;
    for (const KeyframeObservation& obs : np.observations) {
      if (!keyframes_.count(obs.keyframe)) continue;
      mp.reference_keyframe = obs.keyframe;
      mp.first_keyframe_index = keyframes_.at(obs.keyframe).index;
      break;
    }
    if (!mp.reference_keyframe.valid()) {
      result.new_point_ids.push_back(MapPointId());
      continue;
    }
    ++next_point_id_;
    const MapPointId id = mp.id;
    points_.emplace(id, std::move(mp));
    for (const KeyframeObservation& obs : np.observations)
      AddObservation(id, obs.keyframe, obs.keypoint);
    if (points_.at(id).observations.empty()) {
      points_.erase(id);
      result.new_point_ids.push_back(MapPointId());
      continue;
    }
    touched_points_.insert(id);
    result.new_point_ids.push_back(id);
  }

  for (const auto& [from, into] : PlanMerges(delta.merges)) {
    MergePoint(from, into);
    ++result.num_merged;
  }

  for (const ObservationEdit& edit : delta.added_observations)
    AddObservation(Resolve(edit.point), edit.keyframe, edit.keypoint);

  for (const ObservationEdit& edit : delta.removed_observations) {
    const MapPointId p = Resolve(edit.point);
    if (!p.valid()) continue;
    const MapPoint& mp = points_.at(p);
    const auto oit = mp.observations.find(edit.keyframe);
    if (oit == mp.observations.end() || (edit.keypoint >= 0 && oit->second != edit.keypoint))
      continue;
    RemoveObservation(p, edit.keyframe);
    const MapPoint& after = points_.at(p);
    if (after.observations.empty() || WeightedObservations(after) <= 2) {
      ErasePoint(p);
      ++result.num_points_removed;
    }
  }

  for (const auto& [id, pose] : delta.keyframe_poses) {
    auto kit = keyframes_.find(id);
    if (kit != keyframes_.end()) kit->second.cam_from_world = pose;
  }
  for (const auto& [id, position] : delta.point_positions) {
    const MapPointId p = Resolve(id);
    if (!p.valid()) continue;
    points_.at(p).p_in_world = position;
    touched_points_.insert(p);
  }
  for (MapPointId id : delta.removed_points) {
    const MapPointId p = Resolve(id);
    if (!p.valid()) continue;
    ErasePoint(p);
    ++result.num_points_removed;
  }
  for (KeyframeId id : delta.removed_keyframes) {
    if (!keyframes_.count(id) || id == first_keyframe_) continue;
    EraseKeyframe(id);
    ++result.num_keyframes_removed;
  }
  for (MapPointId id : delta.visible_increments) {
    const MapPointId p = Resolve(id);
    if (p.valid()) ++points_.at(p).visible_count;
  }
  for (MapPointId id : delta.found_increments) {
    const MapPointId p = Resolve(id);
    if (p.valid()) ++points_.at(p).found_count;
  }

  for (MapPointId id : touched_points_) {
    if (MapPoint* point = points_.find(id)) RefreshPoint(*point);
  }
  for (KeyframeId id : touched_keyframes_) UpdateConnections(id);
  // Spanning tree: a new keyframe hangs from its strongest connection.
  if (new_keyframe_id.valid() && keyframes_.count(new_keyframe_id) &&
      new_keyframe_id != first_keyframe_) {
    Keyframe& kf = keyframes_.at(new_keyframe_id);
    KeyframeId parent = kf.covisible.empty() ? KeyframeId() : kf.covisible.front().first;
    if (!parent.valid()) parent = ResolveKeyframe(delta.new_keyframe->parent_hint);
    if (!parent.valid() || parent == new_keyframe_id) {
      // Fall back to the most recently inserted other keyframe.
      int64_t best_index = -1;
      for (const auto& [id, other] : keyframes_)
        if (id != new_keyframe_id && other.index > best_index) {
          best_index = other.index;
          parent = id;
        }
    }
    if (parent.valid() && parent != new_keyframe_id) {
      kf.parent = parent;
      keyframes_.at(parent).children.insert(new_keyframe_id);
    }
  }
  // At most doubling since the last compaction (1024 entries at least): amortised O(1) per merge.
  if (replaced_by_.size() > 2 * replacements_after_compaction_ + 1024) CompactReplacements();
  touched_points_.clear();
  touched_keyframes_.clear();
  if (MapEditLog* log = edit_log_.log.get(); log && log->recording) {
    if (log->max_edits > 0 && log->edits.size() >= log->max_edits) {
      log->recording = false;
      log->edits = {};
    } else {
      log->edits.push_back(delta);
    }
  }
  return result;
}

}  // namespace pcr
