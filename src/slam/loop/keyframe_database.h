#pragma once
// The keyframe database for place recognition: an inverted index from each word to the
// keyframes whose bag of words holds it, queried for loop-closing and relocalisation candidates
// in the manner of ORB-SLAM2's KeyFrameDatabase (candidates share many words with the query,
// and their covisibility group scores well as a whole).
//
// Ownership and threading: a value type, thread-compatible (queries are const). It keeps its own
// copy of each keyframe's bag of words; the Map is only read during a query. Keyframes that the
// database holds but the map no longer has are skipped by the queries (Erase them when the map
// removes them). Results are deterministic: ordered containers only, ties broken by keyframe id.
#include <cstddef>
#include <map>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "slam/loop/vocabulary.h"
#include "slam/map/ids.h"
#include "slam/map/map.h"

namespace pcr {

struct PlaceCandidate {
  KeyframeId keyframe;
  double score = 0;              // Vocabulary::Score against the query
  double accumulated_score = 0;  // summed score of its covisibility group (see below)
  int common_words = 0;          // words shared with the query
};

struct LoopQueryOptions {
  // Keyframes whose Keyframe::index differs from the query's by at most this are left out
  // (besides the query's covisibility connections and the query itself). 0: only those.
  int exclude_recent = 0;
  // A candidate must share at least this fraction of the most words any keyframe shares.
  double min_common_words_ratio = 0.8;
  // Covisible neighbours (best first) whose scores add to a candidate's group score.
  int covisible_neighbours = 10;
  // Groups are kept when their accumulated score is at least this fraction of the best group's.
  double min_accumulated_ratio = 0.75;

  bool IsValid(std::string* why) const;
};

// Whether a loop query by `query` leaves out the keyframe `id` whose Keyframe::index is `index`:
// the query itself, its covisibility connections and the keyframes within exclude_recent of its
// index. The one rule of KeyframeDatabase::DetectLoopCandidates and of the loop closer's
// candidates over sequences (LoopCloser::SequenceCandidates).
bool ExcludedFromLoopQuery(const Keyframe& query, KeyframeId id, int64_t index, int exclude_recent);

class KeyframeDatabase {
 public:
  // Adds the keyframe's bag of words (replacing the one it had).
  void Add(KeyframeId keyframe, const BowVector& bow);
  // Removes the keyframe; nothing when it is not there.
  void Erase(KeyframeId keyframe);
  void Clear();
  size_t size() const { return bows_.size(); }
  bool empty() const { return bows_.empty(); }
  // The keyframe's bag of words, or null.
  const BowVector* Find(KeyframeId keyframe) const;
  // Keyframes (increasing id) with their weight holding the word; empty for an unknown word.
  const std::vector<std::pair<KeyframeId, double>>& KeyframesWithWord(WordId word) const;
  // Vocabulary::Score of `bow` against every keyframe of the database that shares a word with it
  // (the others score 0), increasing id; through the inverted index, so only the shared words
  // are visited. Bit-identical to Vocabulary::Score (the same terms added in the same order).
  std::vector<std::pair<KeyframeId, double>> Scores(const BowVector& bow) const;

  // Loop candidates of keyframe `query` with bag of words `bow`, ORB-SLAM2's DetectLoopCandidates:
  // 1. keyframes of the database that are in the map and share a word with the query, except the
  //    query, its covisibility connections (map.keyframe(query)->connections) and those within
  //    options.exclude_recent of its Keyframe::index (when the query is not in the map, only the
  //    query itself is excluded);
  // 2. of those, the ones sharing >= min_common_words_ratio * (most shared words) words ("similar"
  //    keyframes), scored against the query (Vocabulary::Score); candidates: score >= min_score;
  // 3. each candidate's group: itself and its best `covisible_neighbours` covisible neighbours
  //    that are similar keyframes; the group's accumulated score is the sum of their scores and
  //    its representative the member with the highest score (ties: lower id);
  // 4. the representatives of groups with accumulated score >= min_accumulated_ratio * best,
  //    each once (with its best group), by decreasing accumulated score, then increasing id.
  // Throws ConfigError when options are invalid.
  std::vector<PlaceCandidate> DetectLoopCandidates(KeyframeId query, const BowVector& bow,
                                                   const Map& map, double min_score,
                                                   const LoopQueryOptions& options) const;

  // Relocalisation candidates for a frame with bag of words `bow` (ORB-SLAM2's
  // DetectRelocalizationCandidates): as DetectLoopCandidates with nothing excluded and no minimum
  // score, the default options, best first, at most max_candidates (all when <= 0).
  std::vector<PlaceCandidate> DetectRelocalisationCandidates(const BowVector& bow, const Map& map,
                                                             int max_candidates) const;

 private:
  // Per keyframe sharing a word with `bow`: how many words it shares and the sum of their
  // L1ScoreTerm, added in the order of bow's words (Vocabulary::Score's order), through the
  // inverted index. Scores and Detect both score from it.
  struct SharedWords {
    int words = 0;
    double sum = 0;
  };
  std::unordered_map<KeyframeId, SharedWords> Shared(const BowVector& bow) const;
  // Steps 1-4 above; `excluded(id)` tells which keyframes step 1 leaves out.
  template <typename Excluded>
  std::vector<PlaceCandidate> Detect(const BowVector& bow, const Map& map, double min_score,
                                     const LoopQueryOptions& options,
                                     const Excluded& excluded) const;

  std::map<KeyframeId, BowVector> bows_;
  // word id -> (keyframe, weight), increasing keyframe id.
  std::vector<std::vector<std::pair<KeyframeId, double>>> inverted_;
};

}  // namespace pcr
