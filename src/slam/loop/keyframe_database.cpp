#include "slam/loop/keyframe_database.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <set>
#include <unordered_map>

#include "slam/common/error.h"

namespace pcr {
namespace {

bool ById(const std::pair<KeyframeId, double>& entry, KeyframeId id) { return entry.first < id; }

}  // namespace

bool LoopQueryOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (exclude_recent < 0) return fail("exclude_recent must be >= 0");
  if (!(min_common_words_ratio >= 0 && min_common_words_ratio <= 1))
    return fail("min_common_words_ratio must be in [0, 1]");
  if (covisible_neighbours < 0) return fail("covisible_neighbours must be >= 0");
  if (!(min_accumulated_ratio >= 0 && min_accumulated_ratio <= 1))
    return fail("min_accumulated_ratio must be in [0, 1]");
  return true;
}

void KeyframeDatabase::Add(KeyframeId keyframe, const BowVector& bow) {
  Erase(keyframe);
  for (const auto& [word, weight] : bow.words) {
    if (word >= inverted_.size()) inverted_.resize(static_cast<size_t>(word) + 1);
    auto& list = inverted_[word];
    list.insert(std::lower_bound(list.begin(), list.end(), keyframe, ById), {keyframe, weight});
  }
  bows_[keyframe] = bow;
}

void KeyframeDatabase::Erase(KeyframeId keyframe) {
  const auto it = bows_.find(keyframe);
  if (it == bows_.end()) return;
  for (const auto& [word, weight] : it->second.words) {
    auto& list = inverted_[word];
    const auto entry = std::lower_bound(list.begin(), list.end(), keyframe, ById);
    if (entry != list.end() && entry->first == keyframe) list.erase(entry);
  }
  bows_.erase(it);
}

void KeyframeDatabase::Clear() {
  bows_.clear();
  inverted_.clear();
}

const BowVector* KeyframeDatabase::Find(KeyframeId keyframe) const {
  const auto it = bows_.find(keyframe);
  return it == bows_.end() ? nullptr : &it->second;
}

const std::vector<std::pair<KeyframeId, double>>& KeyframeDatabase::KeyframesWithWord(
    WordId word) const {
  static const std::vector<std::pair<KeyframeId, double>> kNone;
  return word < inverted_.size() ? inverted_[word] : kNone;
}

std::unordered_map<KeyframeId, KeyframeDatabase::SharedWords> KeyframeDatabase::Shared(
    const BowVector& bow) const {
  // Vocabulary::Score sums L1ScoreTerm over the shared words in increasing word order; so does
  // this, one keyframe's terms at a time in the order of the query's words.
  std::unordered_map<KeyframeId, SharedWords> shared;
  shared.reserve(bows_.size());
  for (const auto& [word, weight] : bow.words) {
    if (word >= inverted_.size()) continue;
    for (const auto& [keyframe, keyframe_weight] : inverted_[word]) {
      SharedWords& s = shared[keyframe];
      ++s.words;
      s.sum += L1ScoreTerm(weight, keyframe_weight);
    }
  }
  return shared;
}

std::vector<std::pair<KeyframeId, double>> KeyframeDatabase::Scores(const BowVector& bow) const {
  const std::unordered_map<KeyframeId, SharedWords> shared = Shared(bow);
  std::vector<std::pair<KeyframeId, double>> scores;
  scores.reserve(shared.size());
  for (const auto& [keyframe, s] : shared) scores.emplace_back(keyframe, L1ScoreOfSum(s.sum));
  std::sort(scores.begin(), scores.end());
  return scores;
}

bool ExcludedFromLoopQuery(const Keyframe& query, KeyframeId id, int64_t index,
                           int exclude_recent) {
  return id == query.id || query.connections.count(id) != 0 ||
         std::llabs(index - query.index) <= static_cast<long long>(exclude_recent);
}

template <typename Excluded>
std::vector<PlaceCandidate> KeyframeDatabase::Detect(const BowVector& bow, const Map& map,
                                                     double min_score,
                                                     const LoopQueryOptions& options,
                                                     const Excluded& excluded) const {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("LoopQueryOptions: " + why);
  // 1. Keyframes sharing words with the query, with their score's sum (Scores()' numbers).
  std::unordered_map<KeyframeId, SharedWords> shared = Shared(bow);
  int max_common = 0;
  for (auto it = shared.begin(); it != shared.end();) {
    if (excluded(it->first) || map.keyframe(it->first) == nullptr) {
      it = shared.erase(it);
    } else {
      max_common = std::max(max_common, it->second.words);
      ++it;
    }
  }
  if (shared.empty()) return {};
  // 2. Similar keyframes (in increasing id, as below) and their scores.
  struct Similar {
    double score;
    int common_words;
  };
  const double min_common = options.min_common_words_ratio * max_common;
  std::map<KeyframeId, Similar> similar;
  for (const auto& [keyframe, s] : shared) {
    if (s.words < min_common) continue;
    similar[keyframe] = {L1ScoreOfSum(s.sum), s.words};
  }
  // 3. Covisibility groups of the candidates.
  std::map<KeyframeId, PlaceCandidate> best_of_groups;
  double best_accumulated = 0;
  for (const auto& [keyframe, s] : similar) {
    if (s.score < min_score) continue;
    PlaceCandidate group{keyframe, s.score, s.score, s.common_words};
    for (KeyframeId neighbour :
         map.keyframe(keyframe)->BestCovisible(static_cast<size_t>(options.covisible_neighbours))) {
      const auto n = similar.find(neighbour);
      if (n == similar.end()) continue;
      group.accumulated_score += n->second.score;
      if (n->second.score > group.score ||
          (n->second.score == group.score && neighbour < group.keyframe)) {
        group.keyframe = neighbour;
        group.score = n->second.score;
        group.common_words = n->second.common_words;
      }
    }
    best_accumulated = std::max(best_accumulated, group.accumulated_score);
    const auto [it, inserted] = best_of_groups.try_emplace(group.keyframe, group);
    if (!inserted && group.accumulated_score > it->second.accumulated_score) it->second = group;
  }
  // 4. Groups near the best.
  std::vector<PlaceCandidate> candidates;
  for (const auto& [keyframe, group] : best_of_groups) {
    if (group.accumulated_score >= options.min_accumulated_ratio * best_accumulated)
      candidates.push_back(group);
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const PlaceCandidate& a, const PlaceCandidate& b) {
              if (a.accumulated_score != b.accumulated_score)
                return a.accumulated_score > b.accumulated_score;
              return a.keyframe < b.keyframe;
            });
  return candidates;
}

std::vector<PlaceCandidate> KeyframeDatabase::DetectLoopCandidates(
    KeyframeId query, const BowVector& bow, const Map& map, double min_score,
    const LoopQueryOptions& options) const {
  const Keyframe* query_keyframe = map.keyframe(query);
  return Detect(bow, map, min_score, options, [&](KeyframeId id) {
    if (id == query) return true;
    if (query_keyframe == nullptr) return false;
    const Keyframe* other = map.keyframe(id);
    if (other == nullptr) return query_keyframe->connections.count(id) != 0;  // Detect skips it
    return ExcludedFromLoopQuery(*query_keyframe, id, other->index, options.exclude_recent);
  });
}

std::vector<PlaceCandidate> KeyframeDatabase::DetectRelocalisationCandidates(
    const BowVector& bow, const Map& map, int max_candidates) const {
  std::vector<PlaceCandidate> candidates =
      Detect(bow, map, 0.0, LoopQueryOptions(), [](KeyframeId) { return false; });
  if (max_candidates > 0 && candidates.size() > static_cast<size_t>(max_candidates))
    candidates.resize(static_cast<size_t>(max_candidates));
  return candidates;
}

}  // namespace pcr
