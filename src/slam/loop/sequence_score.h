#pragma once
// Place recognition over sequences: a query frame is compared with a database frame together with
// the frames that led up to each, in the manner of SeqSLAM, on bag-of-words scores. One frame's
// best-scoring database frame is often a look-alike elsewhere (a street of the same kind in
// another drive); a run of frames that scores well frame after frame, at some constant ratio of
// speeds, is far more often the same road driven again.
//
// Pure functions, no state; deterministic (speeds are tried in the order given, the first best
// wins).
#include <cmath>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace pcr {

struct SequenceScoreOptions {
  // Frames compared: the query and up to length - 1 frames before it.
  int length = 12;
  // Fewer comparable frames at every speed (a history too short at either end): no score.
  int min_length = 3;
  // Database frames stepped per query frame: the database drive may have been slower (< 1) or
  // faster (> 1) than the query's over the sequence.
  std::vector<double> speeds{0.5, 0.67, 0.8, 1.0, 1.25, 1.5, 2.0};

  bool IsValid(std::string* why) const;
};

// The sequence score of a query against a database frame: the best over options.speeds v of the
// mean of score(query_history[Q - 1 - k], database_history[D - 1 - round(k v)]) over k = 0, 1, ...
// while k < options.length and both frames exist (Q, D: the histories' sizes). Both histories list
// positions in time order, the query and the database frame last; score(a, b) is the bag-of-words
// score of query-side position a against database-side position b. None when every speed has
// fewer than options.min_length terms. Throws ConfigError when options are invalid.
template <typename ScoreFn>
std::optional<double> SequenceScore(std::span<const size_t> query_history,
                                    std::span<const size_t> database_history, const ScoreFn& score,
                                    const SequenceScoreOptions& options);

// Throws ConfigError when options are invalid (SequenceScore calls it).
void CheckSequenceScoreOptions(const SequenceScoreOptions& options);

template <typename ScoreFn>
std::optional<double> SequenceScore(std::span<const size_t> query_history,
                                    std::span<const size_t> database_history, const ScoreFn& score,
                                    const SequenceScoreOptions& options) {
  CheckSequenceScoreOptions(options);
  const long q_size = static_cast<long>(query_history.size());
  const long d_size = static_cast<long>(database_history.size());
  std::optional<double> best;
  for (const double speed : options.speeds) {
    double sum = 0;
    int terms = 0;
    for (long k = 0; k < options.length && k < q_size; ++k) {
      const long back = std::lround(static_cast<double>(k) * speed);
      if (back >= d_size) break;
      sum += score(query_history[static_cast<size_t>(q_size - 1 - k)],
                   database_history[static_cast<size_t>(d_size - 1 - back)]);
      ++terms;
    }
    if (terms < options.min_length) continue;
    const double mean = sum / terms;
    if (!best || mean > *best) best = mean;
  }
  return best;
}

}  // namespace pcr
