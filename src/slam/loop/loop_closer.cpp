#include "slam/loop/loop_closer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "slam/common/disjoint_sets.h"
#include "slam/common/error.h"
#include "slam/common/lie.h"
#include "slam/common/timing.h"
#include "slam/features/orb_extractor.h"
#include "slam/geometry/se3.h"
#include "slam/loop/sequence_score.h"
#include "slam/loop/sim3_ransac.h"
#include "slam/loop/vocabulary_io.h"
#include "slam/map/matcher.h"
#include "slam/optim/bundle_adjustment.h"
#include "slam/optim/pose_graph.h"
#include "slam/optim/sim3_optimizer.h"

namespace pcr {
namespace {

std::vector<uint8_t> ExcludedFlags(const Frame& frame) {
  std::vector<uint8_t> skip(static_cast<size_t>(frame.size()), 0);
  for (int i = 0; i < frame.size(); ++i) skip[static_cast<size_t>(i)] = frame.excluded(i) ? 1 : 0;
  return skip;
}

// A live map point observed at keypoint i of kf that the dynamic filter did not exclude.
const MapPoint* PointAt(const Map& map, const Keyframe& kf, int i) {
  if (i < 0 || i >= static_cast<int>(kf.points.size()) || !kf.points[i].valid()) return nullptr;
  if (kf.frame->excluded(i)) return nullptr;
  return map.point(kf.points[i]);
}

FuseCandidate FuseCandidateOf(const MapPoint& mp) {
  return {mp.p_in_world, mp.normal, mp.min_distance_m, mp.max_distance_m, mp.descriptor};
}

// The keyframe and every keyframe it shares a point with.
std::vector<KeyframeId> ConnectedGroup(const Keyframe& kf, const Map& map) {
  std::vector<KeyframeId> group{kf.id};
  for (const auto& [id, w] : kf.connections)
    if (id != kf.id && map.keyframe(id)) group.push_back(id);
  return group;
}

// The word-matched keypoint pairs (query, candidate) as Sim(3) correspondences: each pair's map
// points in its keyframe's camera, its pixels and its octaves' variances.
std::vector<Sim3Correspondence> Correspondences(const Map& map, const Keyframe& query,
                                                const Keyframe& candidate,
                                                const std::vector<std::pair<int, int>>& pairs) {
  const Frame& fqf = *query.frame;
  const Frame& fcf = *candidate.frame;
  std::vector<Sim3Correspondence> corr;
  corr.reserve(pairs.size());
  for (const auto& [i, j] : pairs) {
    const MapPoint* pq = PointAt(map, query, i);
    const MapPoint* pc = PointAt(map, candidate, j);
    Sim3Correspondence c;
    c.p_in_cam1 = query.cam_from_world * pq->p_in_world;
    c.p_in_cam2 = candidate.cam_from_world * pc->p_in_world;
    c.uv1_px = fqf.uv(i);
    c.uv2_px = fcf.uv(j);
    c.sigma2_1 = fqf.scale().level_sigma2[fqf.octave(i)];
    c.sigma2_2 = fcf.scale().level_sigma2[fcf.octave(j)];
    corr.push_back(c);
  }
  return corr;
}

// The RANSAC of job `job_id` on `candidate`: its seed depends on both only, so that the owner's
// precheck (LoopCloser::Detect) and the lane's verification of the same job agree.
Sim3RansacOptions RansacOptionsOf(const LoopClosingOptions& o, bool fix_scale, int64_t job_id,
                                  KeyframeId candidate) {
  Sim3RansacOptions ro;
  ro.min_inliers = o.min_ransac_inliers;
  ro.max_iterations = o.ransac_iterations;
  ro.fix_scale = fix_scale;
  ro.seed = static_cast<uint64_t>(job_id) * 1000003u + static_cast<uint64_t>(candidate.value);
  return ro;
}

double TranslationDistance(const SE3& a, const SE3& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

}  // namespace

const char* ToString(LoopOutcomeKind kind) {
  switch (kind) {
    case LoopOutcomeKind::kRejected:
      return "rejected";
    case LoopOutcomeKind::kCorrected:
      return "corrected";
    case LoopOutcomeKind::kGlobalBundleAdjustment:
      return "global-ba";
  }
  return "?";
}

bool LoopClosingOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* what) {
    if (why) *why = what;
    return false;
  };
  if (direct_index_levels_up < 0) return fail("direct_index_levels_up must be >= 0");
  if (min_keyframes < 2) return fail("min_keyframes must be >= 2");
  if (exclude_recent_keyframes < 0) return fail("exclude_recent_keyframes must be >= 0");
  if (consistency < 0 || sequence_consistency < 0)
    return fail("consistency and sequence_consistency must be >= 0");
  if (min_bow_matches < 3 || min_ransac_inliers < 3 || min_sim3_inliers < 3)
    return fail("min_bow_matches, min_ransac_inliers and min_sim3_inliers must be >= 3");
  if (min_loop_matches < min_sim3_inliers)
    return fail("min_loop_matches must be >= min_sim3_inliers");
  if (bow_max_distance < 0 || bow_max_distance > 256) return fail("bow_max_distance in [0, 256]");
  if (!(bow_ratio > 0 && bow_ratio <= 1)) return fail("bow_ratio must be in (0, 1]");
  if (ransac_iterations < 1) return fail("ransac_iterations must be >= 1");
  if (!(projection_radius_factor > 0) || !(fuse_radius_factor > 0))
    return fail("projection_radius_factor and fuse_radius_factor must be > 0");
  if (!(max_correction_m > 0)) return fail("max_correction_m must be > 0");
  if (!(join_evidence_factor >= 1) || join_evidence_factor > 100)
    return fail("join_evidence_factor must be in [1, 100]");
  if (covisibility_edge_weight < 1) return fail("covisibility_edge_weight must be >= 1");
  if (pose_graph_iterations < 1) return fail("pose_graph_iterations must be >= 1");
  if (global_ba_iterations < 1) return fail("global_ba_iterations must be >= 1");
  if (final_global_ba_min_keyframes < 1) return fail("final_global_ba_min_keyframes must be >= 1");
  if (skip_keyframes_after_loop < 0) return fail("skip_keyframes_after_loop must be >= 0");
  if (max_snapshot_edits < 0) return fail("max_snapshot_edits must be >= 0");
  if (sequence_length < 0) return fail("sequence_length must be >= 0");
  if (sequence_length > 0 && (sequence_min_length < 1 || sequence_min_length > sequence_length))
    return fail("sequence_min_length must be in [1, sequence_length]");
  if (!(sequence_uniqueness >= 1) || !std::isfinite(sequence_uniqueness))
    return fail("sequence_uniqueness must be finite and >= 1");
  if (sequence_window < 0 || sequence_neighbours < 0)
    return fail("sequence_window and sequence_neighbours must be >= 0");
  return true;
}

SE3 PoseOfSim3(const Sim3& cam_from_world) { return cam_from_world.ToSE3(); }

std::vector<std::pair<int, int>> MatchFeaturesByWords(
    const std::vector<cv::KeyPoint>& keypoints_a, const cv::Mat& descriptors_a,
    const FeatureVector& features_a, const std::vector<uint8_t>* usable_a,
    const std::vector<cv::KeyPoint>& keypoints_b, const cv::Mat& descriptors_b,
    const FeatureVector& features_b, const std::vector<uint8_t>* usable_b, int max_distance,
    double ratio) {
  auto usable = [](const std::vector<uint8_t>* u, int i) {
    return u == nullptr || (*u)[static_cast<size_t>(i)] != 0;
  };
  const size_t nb = keypoints_b.size();
  std::vector<int> b_to_a(nb, -1);
  std::vector<int> b_best(nb, max_distance + 1);
  auto ia = features_a.nodes.begin();
  auto ib = features_b.nodes.begin();
  while (ia != features_a.nodes.end() && ib != features_b.nodes.end()) {
    if (ia->first < ib->first) {
      ++ia;
      continue;
    }
    if (ib->first < ia->first) {
      ++ib;
      continue;
    }
    for (int i : ia->second) {
      if (!usable(usable_a, i)) continue;
      const uint8_t* da = descriptors_a.ptr<uint8_t>(i);
      NearestTwo near(257);
      for (int j : ib->second)
        if (usable(usable_b, j)) near.Add(DescriptorDistance(da, descriptors_b.ptr<uint8_t>(j)), j);
      const int best = near.nearest, best_j = near.nearest_index;
      if (best_j < 0 || best > max_distance || best >= ratio * near.second) continue;
      if (best < b_best[static_cast<size_t>(best_j)]) {
        b_best[static_cast<size_t>(best_j)] = best;
        b_to_a[static_cast<size_t>(best_j)] = i;
      }
    }
    ++ia;
    ++ib;
  }
  std::vector<std::pair<int, int>> pairs;
  for (size_t j = 0; j < nb; ++j)
    if (b_to_a[j] >= 0) pairs.emplace_back(b_to_a[j], static_cast<int>(j));
  std::sort(pairs.begin(), pairs.end());
  RotationConsistency rotation;
  for (size_t k = 0; k < pairs.size(); ++k)
    rotation.Add(keypoints_a[static_cast<size_t>(pairs[k].first)].angle,
                 keypoints_b[static_cast<size_t>(pairs[k].second)].angle, static_cast<int>(k));
  std::vector<int> rejected = rotation.Rejected();
  std::sort(rejected.begin(), rejected.end());
  std::vector<std::pair<int, int>> kept;
  for (size_t k = 0; k < pairs.size(); ++k)
    if (!std::binary_search(rejected.begin(), rejected.end(), static_cast<int>(k)))
      kept.push_back(pairs[k]);
  return kept;
}

namespace {

// Which keypoints of kf hold a live map point the dynamic filter did not exclude (PointAt).
std::vector<uint8_t> KeypointsWithPoints(const Map& map, const Keyframe& kf) {
  std::vector<uint8_t> usable(static_cast<size_t>(kf.frame->size()), 0);
  for (int i = 0; i < kf.frame->size(); ++i)
    usable[static_cast<size_t>(i)] = PointAt(map, kf, i) != nullptr;
  return usable;
}

// MatchByWords with a's flags already computed (the loop query's, once for all its candidates).
std::vector<std::pair<int, int>> MatchByWordsFrom(const Map& map, const Keyframe& a,
                                                  const FeatureVector& features_a,
                                                  const std::vector<uint8_t>& usable_a,
                                                  const Keyframe& b,
                                                  const FeatureVector& features_b, int max_distance,
                                                  double ratio) {
  const std::vector<uint8_t> usable_b = KeypointsWithPoints(map, b);
  return MatchFeaturesByWords(a.frame->keypoints(), a.frame->descriptors(), features_a, &usable_a,
                              b.frame->keypoints(), b.frame->descriptors(), features_b, &usable_b,
                              max_distance, ratio);
}

}  // namespace

std::vector<std::pair<int, int>> MatchByWords(const Map& map, const Keyframe& a,
                                              const FeatureVector& features_a, const Keyframe& b,
                                              const FeatureVector& features_b, int max_distance,
                                              double ratio) {
  return MatchByWordsFrom(map, a, features_a, KeypointsWithPoints(map, a), b, features_b,
                          max_distance, ratio);
}

LoopCloser::LoopCloser(const LoopClosingOptions& options,
                       std::shared_ptr<const Vocabulary> vocabulary, bool fix_scale)
    : options_(options), vocabulary_(std::move(vocabulary)), fix_scale_(fix_scale) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("LoopClosingOptions: " + why);
  if (vocabulary_ && vocabulary_->empty()) vocabulary_.reset();
  edit_log_->max_edits = static_cast<size_t>(options_.max_snapshot_edits);
}

void LoopCloser::OnKeyframe(KeyframeId id, const Map& map) {
  if (!HasPlaceRecognition()) return;
  const auto start = std::chrono::steady_clock::now();
  if (!AddToDatabase(id, map)) return;
  ++stats_.keyframes_seen;
  stats_.add_ms.push_back(MsSince(start));
}

bool LoopCloser::AddToDatabase(KeyframeId id, const Map& map) {
  // Forget keyframes the map culled or forgot.
  for (auto it = bow_.begin(); it != bow_.end();) {
    if (map.keyframe(it->first)) {
      ++it;
      continue;
    }
    database_.Erase(it->first);
    features_.erase(it->first);
    sequence_rows_.erase(it->first);
    it = bow_.erase(it);
  }
  const Keyframe* kf = map.keyframe(id);
  if (!kf || bow_.count(id)) return false;
  const std::vector<uint8_t> skip = ExcludedFlags(*kf->frame);
  BowVector bow;
  FeatureVector features;
  vocabulary_->Transform(kf->frame->descriptors(), &skip, options_.direct_index_levels_up, &bow,
                         &features);
  if (options_.sequence_length > 0) {
    // Only the last keyframes' rows are read (SequenceCandidates computes a missing one); a few
    // lengths are kept for keyframes culled among them.
    const int64_t keep = 3 * static_cast<int64_t>(options_.sequence_length);
    for (auto it = sequence_rows_.begin(); it != sequence_rows_.end();) {
      const Keyframe* row_kf = map.keyframe(it->first);
      it = row_kf && row_kf->index + keep >= kf->index ? std::next(it) : sequence_rows_.erase(it);
    }
    sequence_rows_[id] = database_.Scores(bow);
  }
  database_.Add(id, bow);
  bow_[id] = std::move(bow);
  features_[id] = std::move(features);
  return true;
}

std::vector<PlaceCandidate> LoopCloser::SequenceCandidates(KeyframeId query_id, const Map& map) {
  const Keyframe* query_keyframe = map.keyframe(query_id);
  if (!IsActive() || !query_keyframe || options_.sequence_length == 0) return {};
  const Keyframe& query = *query_keyframe;
  // The keyframes the database holds, in insertion order: the sequences run along it.
  std::vector<std::pair<int64_t, KeyframeId>> order;
  for (const auto& [kid, k] : map.keyframes())
    if (bow_.count(kid)) order.emplace_back(k.index, kid);
  std::sort(order.begin(), order.end());
  std::unordered_map<KeyframeId, size_t> position;
  for (size_t p = 0; p < order.size(); ++p) position.emplace(order[p].second, p);
  const auto found = position.find(query.id);
  if (found == position.end()) return {};
  const size_t q = found->second;
  // score[k][p]: the (q - k)-th keyframe's score against the p-th (those it came after).
  const size_t length = std::min(static_cast<size_t>(options_.sequence_length), q + 1);
  std::vector<std::vector<double>> score(length, std::vector<double>(order.size(), 0.0));
  for (size_t k = 0; k < length; ++k) {
    const KeyframeId h = order[q - k].second;
    auto row = sequence_rows_.find(h);
    if (row == sequence_rows_.end())  // a loaded map, or rows culled meanwhile
      row = sequence_rows_.emplace(h, database_.Scores(bow_.at(h))).first;
    // Against the keyframes before it only, as when it came: a row computed again now also
    // holds the keyframe itself (1) and those added after it.
    for (const auto& [other, s] : row->second) {
      const auto p = position.find(other);
      if (p != position.end() && p->second < q - k) score[k][p->second] = s;
    }
  }
  // Left out as by KeyframeDatabase::DetectLoopCandidates.
  auto excluded = [&](size_t p) {
    return ExcludedFromLoopQuery(query, order[p].second, order[p].first,
                                 options_.exclude_recent_keyframes);
  };
  std::vector<size_t> positions(q + 1);
  for (size_t p = 0; p <= q; ++p) positions[p] = p;
  SequenceScoreOptions sequence;
  sequence.length = options_.sequence_length;
  sequence.min_length = options_.sequence_min_length;
  const auto pair_score = [&](size_t a, size_t b) { return score[q - a][b]; };
  std::vector<double> by_position(order.size(), -1.0);  // -1: excluded or no score
  std::optional<size_t> best;
  for (size_t p = 0; p < q; ++p) {
    if (excluded(p)) continue;
    const std::optional<double> s =
        SequenceScore(std::span<const size_t>(positions),
                      std::span<const size_t>(positions.data(), p + 1), pair_score, sequence);
    if (!s) continue;
    by_position[p] = *s;
    if (!best || *s > by_position[*best]) best = p;
  }
  if (!best || !(by_position[*best] > 0)) return {};
  // Unique: the best further than sequence_window keyframes from it scores clearly less.
  double elsewhere = 0;
  for (size_t p = 0; p < by_position.size(); ++p) {
    const size_t apart = p > *best ? p - *best : *best - p;
    if (apart > static_cast<size_t>(options_.sequence_window))
      elsewhere = std::max(elsewhere, by_position[p]);
  }
  if (by_position[*best] < options_.sequence_uniqueness * elsewhere) {
    ++stats_.sequence_gated;
    return {};
  }
  // The answer, then its neighbours in insertion order by their own score: the lane keeps the
  // one that verifies with the most loop matches (the best sequence need not be the best view).
  std::vector<PlaceCandidate> candidates{
      PlaceCandidate{order[*best].second, score[0][*best], score[0][*best], 0}};
  const size_t reach = static_cast<size_t>(options_.sequence_neighbours);
  for (size_t p = *best > reach ? *best - reach : 0; p <= *best + reach && p < q; ++p)
    if (p != *best && !excluded(p))
      candidates.push_back({order[p].second, score[0][p], score[0][p], 0});
  std::stable_sort(
      candidates.begin() + 1, candidates.end(),
      [](const PlaceCandidate& a, const PlaceCandidate& b) { return a.score > b.score; });
  return candidates;
}

uint64_t LoopCloser::VocabularyFingerprint() const {
  if (!vocabulary_) return 0;
  if (vocabulary_fingerprint_ == 0)
    vocabulary_fingerprint_ = pcr::VocabularyFingerprint(*vocabulary_);
  return vocabulary_fingerprint_;
}

std::vector<std::pair<KeyframeId, KeyframeId>> LiveLoopEdges(
    const std::vector<std::pair<KeyframeId, KeyframeId>>& edges, const Map& map) {
  std::vector<std::pair<KeyframeId, KeyframeId>> live;
  std::set<std::pair<KeyframeId, KeyframeId>> have;
  for (const auto& [i, j] : edges) {
    const KeyframeId a = map.ResolveKeyframe(i), b = map.ResolveKeyframe(j);
    if (!a.valid() || !b.valid() || a == b) continue;
    if (!have.insert(std::minmax(a, b)).second) continue;
    live.emplace_back(a, b);
  }
  return live;
}

std::optional<PlaceArchive> LoopCloser::Archive(const Map& map) const {
  if (!HasPlaceRecognition()) {
    if (!restored_place_) return std::nullopt;
    PlaceArchive archive = *restored_place_;
    std::erase_if(archive.bows, [&](const auto& e) { return !map.keyframe(e.first); });
    std::erase_if(archive.features, [&](const auto& e) { return !map.keyframe(e.first); });
    archive.loop_edges = LiveLoopEdges(loop_edges_, map);
    return archive;
  }
  PlaceArchive archive;
  archive.vocabulary_fingerprint = VocabularyFingerprint();
  archive.direct_index_levels_up = options_.direct_index_levels_up;
  for (const auto& [id, bow] : bow_) {
    if (!map.keyframe(id)) continue;
    archive.bows.emplace(id, bow);
    const auto it = features_.find(id);
    if (it != features_.end()) archive.features.emplace(id, it->second);
  }
  archive.loop_edges = LiveLoopEdges(loop_edges_, map);
  return archive;
}

int LoopCloser::Restore(const std::optional<PlaceArchive>& archive, const Map& map) {
  if (archive) loop_edges_ = archive->loop_edges;
  if (!HasPlaceRecognition()) {
    restored_place_ = archive;
    return 0;
  }
  const bool same = archive && archive->vocabulary_fingerprint == VocabularyFingerprint() &&
                    archive->direct_index_levels_up == options_.direct_index_levels_up;
  // A stored vector is used only when it fits this vocabulary and the keyframe's keypoints, in
  // the order Transform makes (words, nodes and rows increasing: scoring and matching by words
  // are merge joins, which an unsorted vector would silently get wrong).
  auto fits = [this](const BowVector& bow, const FeatureVector& features, const Frame& frame) {
    for (size_t i = 0; i < bow.words.size(); ++i) {
      const auto& [word, weight] = bow.words[i];
      if (word >= vocabulary_->num_words() || !std::isfinite(weight) || weight < 0) return false;
      if (i > 0 && !(bow.words[i - 1].first < word)) return false;
    }
    for (size_t i = 0; i < features.nodes.size(); ++i) {
      const auto& [node, rows] = features.nodes[i];
      if (node >= vocabulary_->num_nodes()) return false;
      if (i > 0 && !(features.nodes[i - 1].first < node)) return false;
      for (size_t r = 0; r < rows.size(); ++r)
        if (rows[r] < 0 || rows[r] >= frame.size() || (r > 0 && !(rows[r - 1] < rows[r])))
          return false;
    }
    return true;
  };
  int computed = 0;
  for (const auto& [id, kf] : map.keyframes()) {
    if (same) {
      const auto bit = archive->bows.find(id);
      const auto fit = archive->features.find(id);
      if (bit != archive->bows.end() && fit != archive->features.end() &&
          fits(bit->second, fit->second, *kf.frame)) {
        database_.Add(id, bit->second);
        bow_[id] = bit->second;
        features_[id] = fit->second;
        continue;
      }
    }
    if (AddToDatabase(id, map)) ++computed;
  }
  return computed;
}

std::shared_ptr<const LoopJob> LoopCloser::Detect(KeyframeId id, const Map& map, bool busy) {
  if (!IsActive()) return nullptr;
  const auto start = std::chrono::steady_clock::now();
  auto done = [&](std::shared_ptr<const LoopJob> job) {
    stats_.detect_ms.push_back(MsSince(start));
    return job;
  };
  const Keyframe* kf = map.keyframe(id);
  const auto own = bow_.find(id);
  if (!kf || own == bow_.end()) return nullptr;
  if (static_cast<int>(map.num_keyframes()) < options_.min_keyframes) return nullptr;
  if (last_loop_index_ >= 0 && kf->index < last_loop_index_ + options_.skip_keyframes_after_loop)
    return nullptr;
  ++stats_.detections;
  std::vector<PlaceCandidate> candidates;
  if (options_.sequence_length > 0) {
    candidates = SequenceCandidates(id, map);
  } else {
    // The lowest similarity to the keyframe's covisible neighbours: a loop candidate must look
    // at least as much like the query as the keyframes it was just seen with.
    double min_score = 1.0;
    bool any = false;
    for (const auto& [n, w] : kf->covisible) {
      const auto it = bow_.find(n);
      if (it == bow_.end()) continue;
      min_score = std::min(min_score, Vocabulary::Score(own->second, it->second));
      any = true;
    }
    if (!any) return done(nullptr);
    LoopQueryOptions query;
    query.exclude_recent = options_.exclude_recent_keyframes;
    candidates = database_.DetectLoopCandidates(id, own->second, map, min_score, query);
  }
  stats_.candidates += static_cast<int>(candidates.size());
  if (candidates.empty()) {
    groups_.clear();
    return done(nullptr);
  }

  // Consistency: a candidate's group (itself and its connected keyframes) must share a keyframe
  // with a group that was a candidate of the previous queries, `consistency` times in a row
  // (sequence_consistency over sequences, whose scores already span several keyframes).
  const int needed =
      options_.sequence_length > 0 ? options_.sequence_consistency : options_.consistency;
  std::vector<ConsistentGroup> current;
  std::vector<KeyframeId> consistent;
  std::vector<bool> previous_extended(groups_.size(), false);
  for (const PlaceCandidate& c : candidates) {
    const Keyframe* ck = map.keyframe(c.keyframe);
    if (!ck) continue;
    std::vector<KeyframeId> group = ConnectedGroup(*ck, map);
    std::sort(group.begin(), group.end());
    bool enough = false, extended_any = false;
    for (size_t g = 0; g < groups_.size(); ++g) {
      const std::vector<KeyframeId>& previous = groups_[g].keyframes;
      std::vector<KeyframeId> common;
      std::set_intersection(group.begin(), group.end(), previous.begin(), previous.end(),
                            std::back_inserter(common));
      if (common.empty()) continue;
      extended_any = true;
      const int consistency = groups_[g].consistency + 1;
      if (!previous_extended[g]) {
        current.push_back({group, consistency});
        previous_extended[g] = true;
      }
      if (consistency >= needed) enough = true;
    }
    if (!extended_any) current.push_back({group, 0});
    if (enough || needed == 0)
      if (std::find(consistent.begin(), consistent.end(), c.keyframe) == consistent.end())
        consistent.push_back(c.keyframe);
  }
  groups_ = std::move(current);
  if (consistent.empty() || busy) return done(nullptr);
  // The cheap part of the verification here, on the owner: candidates sharing too few
  // descriptor matches with the query (most look-alike places) never cost a snapshot.
  std::vector<KeyframeId> plausible;
  std::map<KeyframeId, std::vector<std::pair<int, int>>> word_matches;
  const std::vector<uint8_t> query_usable = KeypointsWithPoints(map, *kf);
  const FeatureVector& query_features = features_.at(id);
  for (KeyframeId c : consistent) {
    const Keyframe* ck = map.keyframe(c);
    const auto fc = features_.find(c);
    if (!ck || fc == features_.end()) continue;
    auto pairs = MatchByWordsFrom(map, *kf, query_features, query_usable, *ck, fc->second,
                                  options_.bow_max_distance, options_.bow_ratio);
    if (static_cast<int>(pairs.size()) < options_.min_bow_matches) {
      ++stats_.candidates_rejected;
      ++stats_.candidates_prechecked;
      continue;
    }
    // The Sim(3) RANSAC too (well under a millisecond when it fails): the lane would run the
    // same one on the same map with the same seed (the job this would become), so a candidate
    // it rejects here would be rejected there, after a snapshot brought up to date for it.
    if (options_.ransac_precheck &&
        !EstimateSim3Ransac(kf->frame->rig().left, Correspondences(map, *kf, *ck, pairs),
                            RansacOptionsOf(options_, fix_scale_, next_job_, c))
             .success) {
      ++stats_.candidates_rejected;
      ++stats_.candidates_ransac_prechecked;
      continue;
    }
    plausible.push_back(c);
    word_matches[c] = std::move(pairs);
  }
  if (plausible.empty()) return done(nullptr);
  consistent = std::move(plausible);

  ++stats_.consistent;
  auto job = std::make_shared<LoopJob>();
  job->id = next_job_++;
  job->query = id;
  job->candidates = consistent;
  // The map as it stands: the edits since the previous job when they were all recorded, else a
  // copy; the recording starts again for the next job.
  if (edit_log_->recording && options_.incremental_snapshots) {
    job->edits = std::make_shared<const std::vector<MapDelta>>(std::exchange(edit_log_->edits, {}));
    ++stats_.map_edit_jobs;
    stats_.map_edits += static_cast<int64_t>(job->edits->size());
  } else {
    job->map = std::make_shared<const Map>(map);
    ++stats_.map_copies;
  }
  ResetEditLog();
  edit_log_->recording = options_.incremental_snapshots;
  job->word_matches = std::move(word_matches);  // the lane does not match them again
  // Earlier loops' edges at the keyframes that hold them now: one culled since would leave its
  // loop out of this loop's essential graph.
  loop_edges_ = LiveLoopEdges(loop_edges_, map);
  job->loop_edges = loop_edges_;
  job->fix_scale = fix_scale_;
  job->options = options_;
  ++stats_.jobs;
  return done(job);
}

namespace {

// A threshold times LoopClosingOptions::join_evidence_factor, rounded up.
int JoinThreshold(int threshold, double factor) {
  return static_cast<int>(std::ceil(factor * threshold - 1e-9));
}

// Geometric verification of one candidate; fills *match and returns true when it passes,
// otherwise sets *why. A candidate in another part of the map than the query must pass the
// thresholds times LoopClosingOptions::join_evidence_factor.
// parts: Map::Parts() of the job's map.
bool VerifyCandidate(const LoopJob& job, const std::map<KeyframeId, int>& parts,
                     const Keyframe& query, const Keyframe& candidate, LoopMatch* match,
                     std::string* why) {
  const Map& map = *job.map;
  const LoopClosingOptions& o = job.options;
  const auto found = job.word_matches.find(candidate.id);
  if (found == job.word_matches.end()) {
    *why = "no word matches";
    return false;
  }
  // The owner's precheck (LoopCloser::Detect) passed only candidates with at least
  // min_bow_matches of them.
  const std::vector<std::pair<int, int>>& pairs = found->second;
  match->bow_matches = static_cast<int>(pairs.size());
  const Frame& fqf = *query.frame;
  const std::vector<Sim3Correspondence> corr = Correspondences(map, query, candidate, pairs);
  const PinholeCamera& camera = fqf.rig().left;
  const Sim3RansacResult ransac =
      EstimateSim3Ransac(camera, corr, RansacOptionsOf(o, job.fix_scale, job.id, candidate.id));
  match->ransac_inliers = ransac.num_inliers;
  if (!ransac.success) {
    *why = "Sim3 RANSAC found " + std::to_string(ransac.num_inliers) + " inliers";
    return false;
  }
  Sim3OptimizerOptions so;
  so.fix_scale = job.fix_scale;
  const Sim3OptimizerResult refined = OptimizeSim3(camera, corr, ransac.cam1_from_cam2, so);
  match->sim3_inliers = refined.num_inliers;
  match->joins_parts = parts.at(query.id) != parts.at(candidate.id);
  const double factor = match->joins_parts ? o.join_evidence_factor : 1.0;
  const std::string joining = match->joins_parts ? " (joining two parts of the map)" : "";
  if (!refined.success || refined.num_inliers < JoinThreshold(o.min_sim3_inliers, factor)) {
    *why = "Sim3 refinement kept " + std::to_string(refined.num_inliers) + " inliers" + joining;
    return false;
  }
  match->query = query.id;
  match->matched = candidate.id;
  match->query_from_matched = refined.cam1_from_cam2;
  match->corrected_query_from_world =
      refined.cam1_from_cam2 * Sim3::FromSE3(candidate.cam_from_world);
  match->matches.clear();
  std::vector<uint8_t> taken(static_cast<size_t>(fqf.size()), 0);
  std::set<MapPointId> used;
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!refined.inliers[k]) continue;
    const int i = pairs[k].first;
    const MapPointId p = candidate.points[pairs[k].second];
    if (!used.insert(p).second) continue;
    match->matches.emplace_back(i, p);
    taken[static_cast<size_t>(i)] = 1;
  }
  // The loop's map points (the matched keyframe and its covisible keyframes) projected into the
  // query at its corrected pose.
  std::vector<KeyframeId> loop_group{candidate.id};
  for (const auto& [n, w] : candidate.covisible) loop_group.push_back(n);
  std::vector<FuseCandidate> fuse;
  std::vector<MapPointId> fuse_id;
  for (KeyframeId k : loop_group) {
    const Keyframe* kf = map.keyframe(k);
    if (!kf) continue;
    for (int j = 0; j < kf->frame->size(); ++j) {
      const MapPoint* mp = PointAt(map, *kf, j);
      if (!mp || !used.insert(mp->id).second) continue;
      fuse.push_back(FuseCandidateOf(*mp));
      fuse_id.push_back(mp->id);
    }
  }
  const auto projected = FuseByProjection(fqf, PoseOfSim3(match->corrected_query_from_world), fuse,
                                          o.projection_radius_factor);
  int added = 0;
  for (const auto& [c, kp] : projected) {
    if (taken[static_cast<size_t>(kp)] || fqf.excluded(kp)) continue;
    taken[static_cast<size_t>(kp)] = 1;
    match->matches.emplace_back(kp, fuse_id[static_cast<size_t>(c)]);
    ++added;
  }
  match->projection_matches = added;
  if (static_cast<int>(match->matches.size()) < JoinThreshold(o.min_loop_matches, factor)) {
    *why = "projection found " + std::to_string(match->matches.size()) + " loop matches" + joining;
    return false;
  }
  const double jump_m =
      TranslationDistance(query.cam_from_world, PoseOfSim3(match->corrected_query_from_world));
  if (jump_m > o.max_correction_m) {
    *why = "correction of " + std::to_string(jump_m) + " m";
    return false;
  }
  return true;
}

}  // namespace

void LoopCloser::ResetEditLog() {
  edit_log_->recording = false;
  edit_log_->edits = {};
}

std::shared_ptr<const LoopJob> LoopMapReplica::Resolve(const std::shared_ptr<const LoopJob>& job) {
  if (job->map) {
    base_ = job->map;
    map_.reset();
    last_job_ = job->id;
    return job;
  }
  if ((!base_ && !map_) || job->id != last_job_ + 1) {
    base_.reset();
    map_.reset();
    throw std::invalid_argument("LoopMapReplica: loop job " + std::to_string(job->id) +
                                " carries the map edits since job " + std::to_string(job->id - 1) +
                                ", which this replica has not seen");
  }
  if (!map_) {
    map_ = std::make_shared<Map>(*base_);  // the first edits after a job with a copy
    base_.reset();
  } else if (map_.use_count() > 1) {
    map_ = std::make_shared<Map>(*map_);  // a job still reads it
  }
  try {
    if (job->edits)
      for (const MapDelta& edit : *job->edits) map_->Apply(edit);
  } catch (...) {
    map_.reset();  // no longer the owner's map
    throw;
  }
  last_job_ = job->id;
  auto resolved = std::make_shared<LoopJob>(*job);
  resolved->edits.reset();
  resolved->map = map_;
  return resolved;
}

LoopOutcome LoopCloser::CloseLoop(const LoopJob& job) {
  if (!job.map)
    throw std::invalid_argument("LoopCloser::CloseLoop: job " + std::to_string(job.id) +
                                " carries map edits; resolve it with the lane's LoopMapReplica");
  LoopOutcome outcome;
  outcome.job = job.id;
  outcome.query = job.query;
  outcome.metric = job.fix_scale;
  const auto verify_start = std::chrono::steady_clock::now();
  const Map& snapshot = *job.map;
  const Keyframe* query = snapshot.keyframe(job.query);
  if (!query) {
    outcome.rejection = "query keyframe gone";
    return outcome;
  }
  // Every candidate is verified and the one with the most loop matches is kept: a facade
  // repeated down the street can pass the checks too, with fewer matches than the place itself,
  // and it may score higher in the bag of words.
  LoopMatch match;
  bool found = false;
  const std::map<KeyframeId, int> map_parts = snapshot.Parts();  // the same for every candidate
  for (KeyframeId c : job.candidates) {
    const Keyframe* candidate = snapshot.keyframe(c);
    if (!candidate) continue;
    ++outcome.candidates_tried;
    LoopMatch m;
    std::string why;
    if (!VerifyCandidate(job, map_parts, *query, *candidate, &m, &why)) {
      if (!found) outcome.rejection = why;
      continue;
    }
    ++outcome.candidates_verified;
    if (!found || m.matches.size() > match.matches.size()) match = std::move(m);
    found = true;
  }
  outcome.verify_ms = MsSince(verify_start);
  if (!found) return outcome;
  outcome.rejection.clear();

  const auto correct_start = std::chrono::steady_clock::now();
  Map work = snapshot;
  std::map<KeyframeId, Sim3> before;
  for (const auto& [id, kf] : work.keyframes()) before[id] = Sim3::FromSE3(kf.cam_from_world);
  // 1. The query's connected group (every keyframe sharing a point with it) moves with the
  //    query's corrected pose; their points with the first group keyframe that sees them.
  //    (ORB-SLAM moves the covisible group, weight >= 15, alone, and fuses the whole loop
  //    group's points: both tried, 2026-12-07, in docs/loop-closing.md; not kept.)
  const std::vector<KeyframeId> group = ConnectedGroup(*query, work);
  const std::set<KeyframeId> in_group(group.begin(), group.end());
  std::map<KeyframeId, Sim3> initial = before;
  const Sim3 query_before = before.at(job.query);
  for (KeyframeId k : group)
    initial[k] = before.at(k) * query_before.Inverse() * match.corrected_query_from_world;
  std::map<MapPointId, KeyframeId> corrected_by;
  MapDelta moved;
  for (KeyframeId k : group) {
    const Keyframe* kf = work.keyframe(k);
    moved.keyframe_poses.emplace_back(k, PoseOfSim3(initial.at(k)));
    for (MapPointId p : kf->points) {
      const MapPoint* mp = p.valid() ? work.point(p) : nullptr;
      if (!mp || corrected_by.count(p)) continue;
      corrected_by[p] = k;
      moved.point_positions.emplace_back(
          p, initial.at(k).Inverse().Map(before.at(k).Map(mp->p_in_world)));
    }
  }
  work.Apply(moved);
  outcome.correction_m =
      TranslationDistance(query->cam_from_world, PoseOfSim3(match.corrected_query_from_world));
  outcome.correction_deg = RadToDeg(RotationDistanceRad(query->cam_from_world.linear(),
                                                        match.corrected_query_from_world.rotation));

  // 2. Fusion: the loop's points replace the duplicates the group made of them.
  std::map<KeyframeId, std::set<KeyframeId>> previous_connections;
  for (KeyframeId k : group) {
    std::set<KeyframeId>& prev = previous_connections[k];
    for (const auto& [n, w] : work.keyframe(k)->connections) prev.insert(n);
  }
  MapDelta fusion;
  std::map<std::pair<KeyframeId, int>, MapPointId> claimed;
  auto fuse_slot = [&](const Keyframe& kf, int kp, MapPointId loop_point) {
    if (kf.frame->excluded(kp)) return;
    const auto key = std::make_pair(kf.id, kp);
    if (claimed.count(key)) return;
    claimed[key] = loop_point;
    const MapPointId existing = kf.points[kp];
    if (existing.valid() && work.point(existing)) {
      if (existing != loop_point) fusion.merges.push_back({existing, loop_point});
    } else {
      fusion.added_observations.push_back({loop_point, kf.id, kp});
    }
  };
  std::vector<FuseCandidate> loop_points;
  std::vector<MapPointId> loop_point_id;
  std::set<MapPointId> seen;
  for (const auto& [kp, p] : match.matches) {
    fuse_slot(*work.keyframe(job.query), kp, p);
    if (seen.insert(p).second) {
      loop_points.push_back(FuseCandidateOf(*work.point(p)));
      loop_point_id.push_back(p);
    }
  }
  for (KeyframeId k : group) {
    const Keyframe* kf = work.keyframe(k);
    const auto fused = FuseByProjection(*kf->frame, kf->cam_from_world, loop_points,
                                        job.options.fuse_radius_factor);
    for (const auto& [c, kp] : fused) fuse_slot(*kf, kp, loop_point_id[static_cast<size_t>(c)]);
  }
  outcome.fused_points = static_cast<int>(fusion.merges.size() + fusion.added_observations.size());
  work.Apply(fusion);

  // 3. The loop edges: connections the fusion made between the group and the rest.
  std::vector<std::pair<KeyframeId, KeyframeId>> new_edges;
  for (KeyframeId k : group) {
    const Keyframe* kf = work.keyframe(k);
    if (!kf) continue;
    for (const auto& [n, w] : kf->connections)
      if (!in_group.count(n) && !previous_connections[k].count(n)) new_edges.emplace_back(k, n);
  }
  if (std::find(new_edges.begin(), new_edges.end(), std::make_pair(job.query, match.matched)) ==
      new_edges.end())
    new_edges.emplace_back(job.query, match.matched);
  outcome.correct_ms = MsSince(correct_start);

  // 4. The essential graph.
  const auto graph_start = std::chrono::steady_clock::now();
  std::vector<PoseGraphVertex> vertices;
  std::map<KeyframeId, int> vertex_of;
  for (const auto& [id, kf] : work.keyframes()) {
    vertex_of[id] = static_cast<int>(vertices.size());
    PoseGraphVertex v;
    v.id = id.value;
    v.cam_from_world = initial.at(id);
    v.fixed = id == match.matched;
    vertices.push_back(v);
  }
  std::vector<PoseGraphEdge> edges;
  std::set<std::pair<KeyframeId, KeyframeId>> have;
  auto add_edge = [&](KeyframeId i, KeyframeId j, const Sim3& i_from_j) {
    if (i == j || !vertex_of.count(i) || !vertex_of.count(j)) return;
    const auto key = std::minmax(i, j);
    if (!have.insert({key.first, key.second}).second) return;
    PoseGraphEdge e;
    e.i = vertex_of.at(i);
    e.j = vertex_of.at(j);
    e.i_from_j = i_from_j;
    edges.push_back(e);
  };
  // Loop edges measured at the corrected poses; the rest at the poses before the correction.
  auto loop_edge = [&](KeyframeId i, KeyframeId j) {
    if (initial.count(i) && initial.count(j))
      add_edge(i, j, initial.at(i) * initial.at(j).Inverse());
  };
  for (const auto& [i, j] : new_edges) loop_edge(i, j);
  for (const auto& [i, j] : job.loop_edges) loop_edge(i, j);
  // Parts of the map: keyframes joined by shared points before this loop's fusion. A part that
  // tracking started after a loss (TrackerOptions::reinitialise_after_lost_frames) hangs in the
  // spanning tree below the keyframe before the loss, at a guessed pose: that link is no
  // measurement, so it is left out, and the loop that joins the part moves it as a whole.
  const std::set<std::pair<KeyframeId, KeyframeId>> fusion_links(new_edges.begin(),
                                                                 new_edges.end());
  DisjointSets parts(vertices.size());
  for (const auto& [id, kf] : work.keyframes())
    for (const auto& [n, w] : kf.connections)
      if (w > 0 && vertex_of.count(n) && !fusion_links.count({id, n}) &&
          !fusion_links.count({n, id}))
        parts.Join(vertex_of.at(id), vertex_of.at(n));
  for (const auto& [id, kf] : work.keyframes()) {
    if (kf.parent.valid() && before.count(kf.parent) && vertex_of.count(kf.parent)) {
      if (parts.Joined(vertex_of.at(id), vertex_of.at(kf.parent)))
        add_edge(id, kf.parent, before.at(id) * before.at(kf.parent).Inverse());
      else
        ++outcome.pose_graph_part_links;
    }
    for (const auto& [n, w] : kf.connections)
      if (w >= job.options.covisibility_edge_weight && n < id && before.count(n))
        add_edge(id, n, before.at(id) * before.at(n).Inverse());
  }
  PoseGraphOptions pgo;
  pgo.max_iterations = job.options.pose_graph_iterations;
  pgo.fix_scale = job.fix_scale;
  const PoseGraphResult graph = OptimizePoseGraph(vertices, edges, pgo);
  outcome.pose_graph_edges = static_cast<int>(edges.size());
  outcome.pose_graph_iterations = graph.iterations;
  outcome.pose_graph_initial_cost = graph.initial_cost;
  outcome.pose_graph_final_cost = graph.final_cost;

  // 5. Points follow the keyframe that corrected them, or their reference keyframe.
  MapCorrection& out = outcome.correction;
  out.before = before;
  for (const auto& [id, v] : vertex_of)
    out.after[id] = graph.cam_from_world[static_cast<size_t>(v)];
  for (const auto& [pid, mp] : work.points()) {
    KeyframeId ref = mp.reference_keyframe;
    if (const auto it = corrected_by.find(pid); it != corrected_by.end()) ref = it->second;
    if (!out.after.count(ref)) {
      ref = KeyframeId();
      for (const auto& [k, kp] : mp.observations)
        if (out.after.count(k)) {
          ref = k;
          break;
        }
    }
    if (!ref.valid()) continue;
    out.point_positions.emplace_back(
        pid, out.after.at(ref).Inverse().Map(initial.at(ref).Map(mp.p_in_world)));
  }
  out.merges = fusion.merges;
  out.added_observations = fusion.added_observations;
  outcome.new_loop_edges = new_edges;
  outcome.pose_graph_ms = MsSince(graph_start);
  outcome.kind = LoopOutcomeKind::kCorrected;
  outcome.match = std::move(match);
  return outcome;
}

LoopOutcome LoopCloser::GlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& corrected,
                                               const std::atomic<bool>* abort) {
  if (!job.map)
    throw std::invalid_argument("LoopCloser::GlobalBundleAdjustment: job " +
                                std::to_string(job.id) + " carries map edits; resolve it first");
  const auto start = std::chrono::steady_clock::now();
  LoopOutcome outcome;
  outcome.job = job.id;
  outcome.query = job.query;
  outcome.kind = LoopOutcomeKind::kGlobalBundleAdjustment;
  outcome.match = corrected.match;
  outcome.metric = corrected.metric;
  Map work = *job.map;
  work.Apply(CorrectionDelta(work, corrected.correction));

  std::vector<BaKeyframe> keyframes;
  std::map<KeyframeId, int> kf_index;
  std::vector<KeyframeId> kf_ids;
  for (const auto& [id, kf] : work.keyframes()) {
    kf_index[id] = static_cast<int>(keyframes.size());
    kf_ids.push_back(id);
    keyframes.push_back({id.value, kf.cam_from_world, id == work.first_keyframe()});
  }
  std::vector<BaPoint> points;
  std::vector<MapPointId> point_ids;
  std::vector<BaObservation> observations;
  for (const auto& [pid, mp] : work.points()) {
    const int j = static_cast<int>(points.size());
    bool any = false;
    for (const auto& [k, kp] : mp.observations) {
      const auto it = kf_index.find(k);
      if (it == kf_index.end()) continue;
      const Frame& f = *work.keyframe(k)->frame;
      if (f.excluded(kp)) continue;
      BaObservation o;
      o.keyframe = it->second;
      o.point = j;
      o.uv_px = f.uv(kp);
      o.u_right_px = f.has_stereo(kp) ? f.u_right_px(kp) : -1.0;
      o.information = f.scale().inv_level_sigma2[f.octave(kp)];
      o.weight = f.weight(kp);
      observations.push_back(o);
      any = true;
    }
    if (!any) continue;
    points.push_back({pid.value, mp.p_in_world});
    point_ids.push_back(pid);
  }
  outcome.ba_keyframes = static_cast<int>(keyframes.size());
  outcome.ba_points = static_cast<int>(points.size());
  if (points.empty() || keyframes.empty()) {
    outcome.ba_ms = MsSince(start);
    return outcome;
  }
  BundleAdjustmentOptions options;
  options.max_iterations = job.options.global_ba_iterations;
  options.optimise_twice = job.options.global_ba_optimise_twice;
  options.function_tolerance = job.options.global_ba_function_tolerance;
  options.abort = abort;
  const StereoRig& rig = work.keyframe(work.first_keyframe())->frame->rig();
  const BundleAdjustmentResult r =
      RunBundleAdjustment(rig, keyframes, points, observations, options);
  outcome.ba_iterations = r.iterations;
  outcome.ba_aborted = r.aborted;
  outcome.ba_ms = MsSince(start);
  if (r.aborted) return outcome;
  MapCorrection& out = outcome.correction;
  for (size_t k = 0; k < kf_ids.size(); ++k) {
    out.before[kf_ids[k]] = Sim3::FromSE3(keyframes[k].cam_from_world);
    out.after[kf_ids[k]] = Sim3::FromSE3(r.cam_from_world[k]);
  }
  for (size_t j = 0; j < point_ids.size(); ++j)
    out.point_positions.emplace_back(point_ids[j], r.p_in_world[j]);
  return outcome;
}

LoopOutcome LoopCloser::GlobalBundleAdjustmentOfMap(const Map& map,
                                                    const LoopClosingOptions& options,
                                                    const MapCorrection& start) {
  LoopJob job;
  job.id = -1;
  job.map = std::shared_ptr<const Map>(std::shared_ptr<const Map>(), &map);  // not owned
  job.options = options;
  LoopOutcome moved;
  moved.correction = start;
  return GlobalBundleAdjustment(job, moved, nullptr);
}

MapDelta LoopCloser::CorrectionDelta(const Map& map, const MapCorrection& correction) {
  MapDelta delta;
  if (correction.after.empty()) return delta;
  // Per live keyframe: the world correction (old world -> new world) of itself or of its nearest
  // spanning-tree ancestor in the snapshot.
  std::map<KeyframeId, Sim3> world_correction;
  auto correction_of = [&](KeyframeId id) -> const Sim3* {
    std::vector<KeyframeId> chain;
    KeyframeId a = id;
    const Sim3* found = nullptr;
    while (a.valid()) {
      if (const auto it = world_correction.find(a); it != world_correction.end()) {
        found = &it->second;
        break;
      }
      const auto b = correction.before.find(a);
      const auto c = correction.after.find(a);
      if (b != correction.before.end() && c != correction.after.end()) {
        found = &(world_correction[a] = c->second.Inverse() * b->second);
        break;
      }
      chain.push_back(a);
      const Keyframe* kf = map.keyframe(a);
      if (!kf) break;
      a = kf->parent;
    }
    if (!found) return nullptr;
    const Sim3 w = *found;
    for (KeyframeId k : chain) world_correction[k] = w;
    return &world_correction.at(id);
  };
  for (const auto& [id, kf] : map.keyframes()) {
    const Sim3* w = correction_of(id);
    if (!w) continue;
    const Sim3 corrected = Sim3::FromSE3(kf.cam_from_world) * w->Inverse();
    delta.keyframe_poses.emplace_back(id, PoseOfSim3(corrected));
  }
  std::unordered_map<MapPointId, Eigen::Vector3d> snapshot_position;
  for (const auto& [pid, p] : correction.point_positions) snapshot_position[pid] = p;
  // A point that this delta merges away takes no position of its own: Map::Apply resolves ids
  // through the merges, so its entry would land on the point it merges into and overwrite the
  // position the correction gave that one. (Where the point it merges into is gone, the merge
  // will not happen, and the point moves like any other.)
  // The merges as Map::Apply will make them.
  std::unordered_set<MapPointId> merged_away;
  for (const auto& [from, into] : map.PlanMerges(correction.merges)) merged_away.insert(from);
  for (const auto& [pid, mp] : map.points()) {
    if (merged_away.count(pid)) continue;
    if (const auto it = snapshot_position.find(pid); it != snapshot_position.end()) {
      delta.point_positions.emplace_back(pid, it->second);
      continue;
    }
    const Sim3* w = nullptr;
    if (map.keyframe(mp.reference_keyframe)) w = correction_of(mp.reference_keyframe);
    for (auto it = mp.observations.begin(); !w && it != mp.observations.end(); ++it)
      w = correction_of(it->first);
    if (w) delta.point_positions.emplace_back(pid, w->Map(mp.p_in_world));
  }
  delta.merges = correction.merges;
  delta.added_observations = correction.added_observations;
  return delta;
}

void LoopCloser::OnOutcome(const LoopOutcome& outcome, const Map& map) {
  switch (outcome.kind) {
    case LoopOutcomeKind::kRejected:
      ++stats_.rejected;
      stats_.candidates_rejected += outcome.candidates_tried;
      return;
    case LoopOutcomeKind::kCorrected:
      ++stats_.corrections;
      stats_.candidates_rejected += outcome.candidates_tried - outcome.candidates_verified;
      loop_edges_.insert(loop_edges_.end(), outcome.new_loop_edges.begin(),
                         outcome.new_loop_edges.end());
      groups_.clear();
      for (const auto& [id, kf] : map.keyframes())
        last_loop_index_ = std::max(last_loop_index_, kf.index);
      return;
    case LoopOutcomeKind::kGlobalBundleAdjustment:
      if (outcome.ba_aborted)
        ++stats_.global_bas_aborted;
      else
        ++stats_.global_bas;
      return;
  }
}

std::vector<KeyframeId> LoopCloser::PlaceCandidates(const Frame& frame, const Map& map,
                                                    int max_candidates) const {
  if (!HasPlaceRecognition()) return {};
  const std::vector<uint8_t> skip = ExcludedFlags(frame);
  BowVector bow;
  vocabulary_->Transform(frame.descriptors(), &skip, options_.direct_index_levels_up, &bow,
                         nullptr);
  std::vector<KeyframeId> ids;
  for (const PlaceCandidate& c : database_.DetectRelocalisationCandidates(bow, map, max_candidates))
    ids.push_back(c.keyframe);
  return ids;
}

}  // namespace pcr
