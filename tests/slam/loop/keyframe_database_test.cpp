#include "slam/loop/keyframe_database.h"

#include <gtest/gtest.h>

#include <vector>

#include "slam/common/error.h"
#include "slam/features/stereo_matcher.h"
#include "slam/loop/vocabulary.h"
#include "slam/map/map.h"
#include "slam/map/scale_pyramid.h"
#include "slam/map/synthetic_scene.h"

namespace pcr {
namespace {

constexpr int kKeypoints = 40;

// A stereo frame with kKeypoints keypoints (positions and descriptors do not matter here).
FramePtr TinyFrame(int64_t id) {
  OrbFeatures f;
  f.descriptors = cv::Mat::zeros(kKeypoints, 32, CV_8U);
  StereoMatches s;
  const StereoRig rig = test::KittiLikeRig();
  for (int i = 0; i < kKeypoints; ++i) {
    f.keypoints.emplace_back(50.f + 10.f * i, 40.f + 3.f * i, 31.f, 0.f, 0.f, 0);
    s.depth_m.push_back(10.f);
    s.u_right_px.push_back(f.keypoints[i].pt.x - static_cast<float>(rig.Bf() / 10.0));
  }
  return Frame::Create(id, id * 1000, rig, ScalePyramid::Make(1.2, 8), f, s);
}

// Words first..first+count-1 with equal weights (L1-normalised).
BowVector Words(WordId first, int count) {
  BowVector bow;
  for (int i = 0; i < count; ++i) bow.words.emplace_back(first + i, 1.0 / count);
  return bow;
}

// Eight keyframes K0..K7 along a path: each shares 20 map points with the next one (keypoints
// 20..39 of K_i are keypoints 0..19 of K_i+1), so K_i is connected to K_i-1 and K_i+1 only.
// Bags of words: K0 sees place A (words 0..9), K1 most of it (words 2..11), K2..K4 places of
// their own, K5 and K6 place A again; K7, the query, is at place A and is not in the database.
class KeyframeDatabaseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::vector<MapPointId> previous;
    for (int k = 0; k < 8; ++k) {
      MapDelta d;
      NewKeyframe kf;
      kf.frame = TinyFrame(k);
      for (int i = 0; i < static_cast<int>(previous.size()); ++i)
        kf.associations.emplace_back(i, previous[i]);
      d.new_keyframe = kf;
      for (int i = 20; i < kKeypoints; ++i) {
        NewMapPoint p;
        p.p_in_world = Eigen::Vector3d(0.1 * i, 0.0, 10.0 + k);
        p.observations = {{KeyframeId(k), i}};
        d.new_points.push_back(p);
      }
      previous = map.Apply(d).new_point_ids;
    }
    bows = {Words(0, 10),   Words(2, 10), Words(100, 10), Words(200, 10),
            Words(300, 10), Words(0, 10), Words(0, 10)};
    for (int k = 0; k < 7; ++k) database.Add(KeyframeId(k), bows[k]);
  }

  std::vector<KeyframeId> Ids(const std::vector<PlaceCandidate>& candidates) {
    std::vector<KeyframeId> ids;
    for (const PlaceCandidate& c : candidates) ids.push_back(c.keyframe);
    return ids;
  }

  Map map;
  KeyframeDatabase database;
  std::vector<BowVector> bows;
  const KeyframeId query{7};
};

TEST_F(KeyframeDatabaseTest, MapIsAChain) {
  ASSERT_EQ(map.num_keyframes(), 8u);
  EXPECT_EQ(map.keyframe(KeyframeId(0))->Weight(KeyframeId(1)), 20);
  EXPECT_EQ(map.keyframe(KeyframeId(7))->Weight(KeyframeId(6)), 20);
  EXPECT_EQ(map.keyframe(KeyframeId(7))->connections.size(), 1u);
  EXPECT_EQ(map.keyframe(KeyframeId(3))->BestCovisible(10).size(), 2u);
  EXPECT_EQ(map.keyframe(KeyframeId(7))->index, 7);
}

TEST_F(KeyframeDatabaseTest, InvertedIndex) {
  EXPECT_EQ(database.size(), 7u);
  ASSERT_NE(database.Find(KeyframeId(1)), nullptr);
  EXPECT_EQ(database.Find(KeyframeId(1))->words, bows[1].words);
  EXPECT_EQ(database.Find(query), nullptr);
  const auto& with_word_5 = database.KeyframesWithWord(5);
  ASSERT_EQ(with_word_5.size(), 4u);
  EXPECT_EQ(with_word_5[0].first, KeyframeId(0));
  EXPECT_EQ(with_word_5[3].first, KeyframeId(6));
  EXPECT_DOUBLE_EQ(with_word_5[0].second, 0.1);
  EXPECT_TRUE(database.KeyframesWithWord(99999).empty());
}

TEST_F(KeyframeDatabaseTest, ScoresThroughTheInvertedIndexAreVocabularyScores) {
  // Uneven weights, so that |a - b| differs from term to term.
  BowVector query;
  for (WordId w = 0; w < 12; ++w) query.words.emplace_back(w, 0.02 + 0.01 * w);
  query.words.emplace_back(205, 0.1);
  const std::vector<std::pair<KeyframeId, double>> scores = database.Scores(query);
  // K0, K1, K5, K6 share words 0..11; K3 word 205; K2 and K4 nothing (left out).
  std::vector<KeyframeId> ids;
  for (const auto& [id, score] : scores) ids.push_back(id);
  EXPECT_EQ(ids, (std::vector<KeyframeId>{KeyframeId(0), KeyframeId(1), KeyframeId(3),
                                          KeyframeId(5), KeyframeId(6)}));
  for (const auto& [id, score] : scores) {
    EXPECT_EQ(score, Vocabulary::Score(query, bows[static_cast<size_t>(id.value)])) << id.value;
    EXPECT_GT(score, 0.0);
  }
  EXPECT_EQ(Vocabulary::Score(query, bows[2]), 0.0);
  // The place queries score in the same pass: their candidates' scores are the same numbers.
  const std::vector<PlaceCandidate> candidates =
      database.DetectRelocalisationCandidates(query, map, 0);
  ASSERT_FALSE(candidates.empty());
  for (const PlaceCandidate& c : candidates)
    EXPECT_EQ(c.score, Vocabulary::Score(query, bows[static_cast<size_t>(c.keyframe.value)]))
        << c.keyframe.value;
  EXPECT_TRUE(database.Scores(Words(5000, 3)).empty());
  EXPECT_TRUE(database.Scores(BowVector{}).empty());
  database.Erase(KeyframeId(3));
  EXPECT_EQ(database.Scores(query).size(), 4u);
}

TEST_F(KeyframeDatabaseTest, LoopQueryFindsThePlaceAndExcludesConnectedAndRecent) {
  LoopQueryOptions options;
  options.exclude_recent = 2;  // K5 (index 5) is recent; K6 is connected to K7
  const std::vector<PlaceCandidate> candidates =
      database.DetectLoopCandidates(query, Words(0, 10), map, 0.5, options);
  ASSERT_EQ(candidates.size(), 1u);
  // K0's group (K0, K1) and K1's group (K1, K0) both have K0 as their best keyframe.
  EXPECT_EQ(candidates[0].keyframe, KeyframeId(0));
  EXPECT_DOUBLE_EQ(candidates[0].score, 1.0);
  EXPECT_DOUBLE_EQ(candidates[0].accumulated_score, 1.8);
  EXPECT_EQ(candidates[0].common_words, 10);

  // Without the recency exclusion, K5 (not connected to K7) comes back when weaker groups count.
  options.exclude_recent = 0;
  options.min_accumulated_ratio = 0.5;
  const std::vector<PlaceCandidate> with_recent =
      database.DetectLoopCandidates(query, Words(0, 10), map, 0.5, options);
  EXPECT_EQ(Ids(with_recent), (std::vector<KeyframeId>{KeyframeId(0), KeyframeId(5)}));
  EXPECT_DOUBLE_EQ(with_recent[1].accumulated_score, 1.0);  // K6 (its neighbour) is excluded

  // A minimum score above K1's keeps K1 out as a candidate, not as K0's neighbour.
  options = LoopQueryOptions();
  options.exclude_recent = 2;
  const std::vector<PlaceCandidate> strict =
      database.DetectLoopCandidates(query, Words(0, 10), map, 0.9, options);
  ASSERT_EQ(strict.size(), 1u);
  EXPECT_DOUBLE_EQ(strict[0].accumulated_score, 1.8);
  // Nothing above a perfect score.
  EXPECT_TRUE(database.DetectLoopCandidates(query, Words(0, 10), map, 1.01, options).empty());
  // A place nobody saw.
  EXPECT_TRUE(database.DetectLoopCandidates(query, Words(5000, 10), map, 0.0, options).empty());
  options.min_common_words_ratio = 2;
  EXPECT_THROW(database.DetectLoopCandidates(query, Words(0, 10), map, 0.0, options), ConfigError);
}

TEST_F(KeyframeDatabaseTest, TheLoopQueryExclusionRule) {
  const Keyframe& k7 = *map.keyframe(query);                       // index 7, connected to K6 only
  EXPECT_TRUE(ExcludedFromLoopQuery(k7, query, 7, 0));             // itself
  EXPECT_TRUE(ExcludedFromLoopQuery(k7, KeyframeId(6), 6, 0));     // connected
  EXPECT_TRUE(ExcludedFromLoopQuery(k7, KeyframeId(6), -100, 0));  // connected, whatever index
  EXPECT_FALSE(ExcludedFromLoopQuery(k7, KeyframeId(5), 5, 1));    // 2 apart
  EXPECT_TRUE(ExcludedFromLoopQuery(k7, KeyframeId(5), 5, 2));     // recent
  EXPECT_TRUE(ExcludedFromLoopQuery(k7, KeyframeId(42), 9, 2));    // recent, later
  EXPECT_FALSE(ExcludedFromLoopQuery(k7, KeyframeId(0), 0, 6));
  EXPECT_TRUE(ExcludedFromLoopQuery(k7, KeyframeId(0), 0, 7));
}

TEST_F(KeyframeDatabaseTest, RelocalisationExcludesNothing) {
  const std::vector<PlaceCandidate> candidates =
      database.DetectRelocalisationCandidates(Words(0, 10), map, 10);
  // K5's group (K5, K6) scores 2.0, K6's the same with K5 best (tie: lower id); K0's 1.8.
  EXPECT_EQ(Ids(candidates), (std::vector<KeyframeId>{KeyframeId(5), KeyframeId(0)}));
  EXPECT_DOUBLE_EQ(candidates[0].accumulated_score, 2.0);
  EXPECT_EQ(database.DetectRelocalisationCandidates(Words(0, 10), map, 1).size(), 1u);
  EXPECT_EQ(Ids(database.DetectRelocalisationCandidates(Words(100, 10), map, 0)),
            std::vector<KeyframeId>{KeyframeId(2)});
}

TEST_F(KeyframeDatabaseTest, EraseAndKeyframesGoneFromTheMap) {
  LoopQueryOptions options;
  options.exclude_recent = 2;
  database.Erase(KeyframeId(0));
  database.Erase(KeyframeId(0));  // twice: nothing
  EXPECT_EQ(database.size(), 6u);
  EXPECT_EQ(database.Find(KeyframeId(0)), nullptr);
  EXPECT_EQ(database.KeyframesWithWord(0).size(), 2u);  // K5, K6
  std::vector<PlaceCandidate> candidates =
      database.DetectLoopCandidates(query, Words(0, 10), map, 0.5, options);
  ASSERT_EQ(candidates.size(), 1u);
  EXPECT_EQ(candidates[0].keyframe, KeyframeId(1));
  EXPECT_DOUBLE_EQ(candidates[0].score, 0.8);
  EXPECT_EQ(candidates[0].common_words, 8);

  // K1 removed from the map but still in the database: skipped.
  MapDelta remove;
  remove.removed_keyframes.push_back(KeyframeId(1));
  map.Apply(remove);
  ASSERT_EQ(map.keyframe(KeyframeId(1)), nullptr);
  EXPECT_TRUE(database.DetectLoopCandidates(query, Words(0, 10), map, 0.5, options).empty());

  // Add again replaces; Clear empties.
  database.Add(KeyframeId(2), Words(0, 10));
  EXPECT_EQ(database.KeyframesWithWord(100).size(), 0u);
  EXPECT_EQ(Ids(database.DetectLoopCandidates(query, Words(0, 10), map, 0.5, options)),
            std::vector<KeyframeId>{KeyframeId(2)});
  database.Clear();
  EXPECT_EQ(database.size(), 0u);
  EXPECT_TRUE(database.DetectRelocalisationCandidates(Words(0, 10), map, 5).empty());
}

}  // namespace
}  // namespace pcr
