#include "slam/loop/sequence_score.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "slam/common/error.h"

namespace pcr {
namespace {

std::vector<size_t> Positions(size_t first, size_t count) {
  std::vector<size_t> out(count);
  std::iota(out.begin(), out.end(), first);
  return out;
}

// Query frames 0..11 drove past database frames 1000..1030 twice as fast as the database drive:
// query frame i is the place of database frame 1000 + 2 i + 7. A pair of the same place scores 1,
// any other pair 0.1.
double TwiceAsFast(size_t query, size_t database) {
  return database == 1000 + 2 * query + 7 ? 1.0 : 0.1;
}

TEST(SequenceScore, FindsTheSpeedAtWhichTheDrivesAgree) {
  const std::vector<size_t> query = Positions(0, 12);
  const std::vector<size_t> database = Positions(1000, 30);  // ends at 1029, query 11's place
  const std::optional<double> s =
      SequenceScore(std::span(query), std::span(database), TwiceAsFast, SequenceScoreOptions{});
  ASSERT_TRUE(s.has_value());
  EXPECT_DOUBLE_EQ(*s, 1.0);

  // At the same speed only the newest pair is the same place: (1 + 11 x 0.1) / 12.
  SequenceScoreOptions same_speed;
  same_speed.speeds = {1.0};
  const std::optional<double> slow =
      SequenceScore(std::span(query), std::span(database), TwiceAsFast, same_speed);
  ASSERT_TRUE(slow.has_value());
  EXPECT_NEAR(*slow, (1.0 + 11 * 0.1) / 12, 1e-12);
}

TEST(SequenceScore, AnotherPlaceScoresLowerThanTheSamePlace) {
  const std::vector<size_t> query = Positions(0, 12);
  const std::vector<size_t> right = Positions(1000, 30);
  const std::vector<size_t> elsewhere = Positions(1000, 26);  // ends 4 frames before the place
  const SequenceScoreOptions options;
  const double at_place = *SequenceScore(std::span(query), std::span(right), TwiceAsFast, options);
  const double off_place =
      *SequenceScore(std::span(query), std::span(elsewhere), TwiceAsFast, options);
  EXPECT_GT(at_place, off_place);
  // Off the place by 4 database frames, a speed line crosses the true one at one pair at most
  // (speed 1.5, k = 8: back 12 -> 1013, query 3's place), never all of them.
  EXPECT_LT(off_place, 0.5);
}

TEST(SequenceScore, ShortHistoriesUseTheFramesThereAre) {
  // A database history of 5 frames at speed 2: k = 0, 1, 2 (back 0, 2, 4), 3 terms.
  const std::vector<size_t> query = Positions(0, 12);
  const std::vector<size_t> database = Positions(1025, 5);  // 1025..1029
  SequenceScoreOptions options;
  options.speeds = {2.0};
  const std::optional<double> s =
      SequenceScore(std::span(query), std::span(database), TwiceAsFast, options);
  ASSERT_TRUE(s.has_value());
  EXPECT_DOUBLE_EQ(*s, 1.0);
  options.min_length = 4;  // 3 terms are too few
  EXPECT_FALSE(
      SequenceScore(std::span(query), std::span(database), TwiceAsFast, options).has_value());

  // A query history of 2 frames: none at the default min_length (3), a score at 2.
  const std::vector<size_t> young = Positions(9, 2);     // 9, 10
  const std::vector<size_t> full = Positions(1000, 28);  // ends at 1027, query 10's place
  SequenceScoreOptions two;
  EXPECT_FALSE(SequenceScore(std::span(young), std::span(full), TwiceAsFast, two).has_value());
  two.min_length = 2;
  const std::optional<double> s2 =
      SequenceScore(std::span(young), std::span(full), TwiceAsFast, two);
  ASSERT_TRUE(s2.has_value());
  EXPECT_DOUBLE_EQ(*s2, 1.0);  // speed 2: 1027 <-> 10, 1025 <-> 9
}

TEST(SequenceScore, CountsEveryTermOfTheLongestSequence) {
  // score = the database position: the mean of the positions visited shows which pairs counted.
  const std::vector<size_t> query = Positions(0, 20);
  const std::vector<size_t> database = Positions(0, 100);
  SequenceScoreOptions options;
  options.length = 4;
  options.min_length = 1;
  options.speeds = {1.0};
  const auto position = [](size_t, size_t d) { return static_cast<double>(d); };
  // k = 0..3: database 99, 98, 97, 96.
  EXPECT_DOUBLE_EQ(*SequenceScore(std::span(query), std::span(database), position, options), 97.5);
  // At 0.5 the best speed is chosen: rounding half away from zero, backs 0, 1, 1, 2 -> 99, 98, 98,
  // 97 (mean 98) beats speed 1's 97.5.
  options.speeds = {1.0, 0.5};
  EXPECT_DOUBLE_EQ(*SequenceScore(std::span(query), std::span(database), position, options), 98.0);
}

TEST(SequenceScore, BadOptionsAreConfigErrors) {
  const std::vector<size_t> h = Positions(0, 5);
  const auto one = [](size_t, size_t) { return 1.0; };
  auto run = [&](const SequenceScoreOptions& o) {
    return SequenceScore(std::span(h), std::span(h), one, o);
  };
  SequenceScoreOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why));
  o.length = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("length"), std::string::npos);
  EXPECT_THROW(run(o), ConfigError);
  o = {};
  o.min_length = o.length + 1;
  EXPECT_THROW(run(o), ConfigError);
  o = {};
  o.min_length = 0;
  EXPECT_THROW(run(o), ConfigError);
  o = {};
  o.speeds.clear();
  EXPECT_THROW(run(o), ConfigError);
  o.speeds = {1.0, 0.0};
  EXPECT_THROW(run(o), ConfigError);
  o.speeds = {std::numeric_limits<double>::quiet_NaN()};
  EXPECT_THROW(run(o), ConfigError);
  o.speeds = {std::numeric_limits<double>::infinity()};
  EXPECT_THROW(run(o), ConfigError);
}

}  // namespace
}  // namespace pcr
