#include "slam/map/matcher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <utility>
#include <vector>

#include "slam/map/stereo_points.h"
#include "slam/map/synthetic_scene.h"

namespace pcr {
namespace {

struct FramePair {
  FramePtr a, b;
  std::vector<int> point_a, point_b;  // scene point per keypoint (-1: clutter)
  SE3 pose_a, pose_b;
};

FramePair MakePair(test::SyntheticScene& scene, const SE3& pose_a, const SE3& pose_b) {
  FramePair p;
  p.pose_a = pose_a;
  p.pose_b = pose_b;
  p.a = scene.MakeFrame(0, pose_a, &p.point_a);
  p.b = scene.MakeFrame(1, pose_b, &p.point_b);
  return p;
}

TEST(RotationConsistency, KeepsTheDominantRotations) {
  RotationConsistency r;
  for (int i = 0; i < 50; ++i) r.Add(10.f, 8.f, i);     // rotation 2 degrees
  for (int i = 50; i < 60; ++i) r.Add(10.f, 11.f, i);   // -1 degree: 359, other bin
  for (int i = 60; i < 63; ++i) r.Add(100.f, 10.f, i);  // 90 degrees: small bin, < 10%
  for (int i = 63; i < 70; ++i) r.Add(200.f, 10.f, i);  // 190 degrees: third bin
  const std::vector<int> rejected = r.Rejected();
  EXPECT_EQ(rejected, (std::vector<int>{60, 61, 62}));
}

TEST(Matcher, FrameToFrameProjectionFindsTheRightKeypoints) {
  test::SyntheticScene scene(11);
  const SE3 pose_a = test::CamFromWorld({0, 0, 0}, 0.0);
  const SE3 pose_b = test::CamFromWorld({0.1, 0, 1.0}, 0.02);
  FramePair p = MakePair(scene, pose_a, pose_b);
  // Candidates: every keypoint of a that belongs to a scene point, at its true position.
  std::vector<FramePointCandidate> candidates;
  std::vector<int> candidate_point;
  for (int i = 0; i < p.a->size(); ++i) {
    if (p.point_a[i] < 0) continue;
    candidates.push_back(
        {scene.point(p.point_a[i]), p.a->descriptor(i), p.a->octave(i), p.a->keypoint(i).angle});
    candidate_point.push_back(p.point_a[i]);
  }
  // A slightly wrong pose guess (as from a motion model).
  const SE3 guess = test::CamFromWorld({0.12, 0.01, 0.97}, 0.021);
  std::vector<int> assigned(p.b->size(), -1);
  const int n = SearchByProjection(*p.b, guess, pose_a, candidates, 7.0, true, &assigned);
  int correct = 0, wrong = 0;
  for (int i = 0; i < p.b->size(); ++i) {
    if (assigned[i] < 0) continue;
    (candidate_point[assigned[i]] == p.point_b[i] ? correct : wrong)++;
  }
  EXPECT_EQ(correct + wrong, n);
  EXPECT_GT(correct, 0.6 * p.b->size());
  EXPECT_LT(wrong, 0.01 * correct);
  // Taken keypoints are never reassigned.
  std::vector<int> all_taken(p.b->size(), -3);
  EXPECT_EQ(SearchByProjection(*p.b, guess, pose_a, candidates, 7.0, true, &all_taken), 0);
}

TEST(Matcher, LocalPointSearchUsesPredictedLevelAndRatio) {
  test::SyntheticScene scene(12);
  const SE3 pose = test::CamFromWorld({0.3, 0, 2.0}, -0.01);
  std::vector<int> point_of;
  const FramePtr frame = scene.MakeFrame(3, pose, &point_of);
  // Candidates: the points with their base descriptor, predicted level = the rendered level.
  std::vector<int> kp_of_point(scene.num_points(), -1);
  for (int i = 0; i < frame->size(); ++i)
    if (point_of[i] >= 0) kp_of_point[point_of[i]] = i;
  std::vector<ProjectedPoint> candidates;
  std::vector<int> cand_point;
  for (int j = 0; j < scene.num_points(); ++j) {
    if (kp_of_point[j] < 0) continue;
    const Eigen::Vector3d pc = pose * scene.point(j);
    ProjectedPoint pp;
    pp.uv_px = scene.rig().left.Project(pc);
    pp.u_right_px = scene.rig().ProjectRightX(pc);
    pp.predicted_level = frame->octave(kp_of_point[j]);
    pp.descriptor = frame->descriptor(kp_of_point[j]).clone();
    candidates.push_back(pp);
    cand_point.push_back(j);
  }
  std::vector<int> assigned(frame->size(), -1);
  const int n = SearchLocalPoints(*frame, candidates, 1.0, &assigned);
  int correct = 0;
  for (int i = 0; i < frame->size(); ++i)
    if (assigned[i] >= 0 && cand_point[assigned[i]] == point_of[i]) ++correct;
  EXPECT_GT(correct, 0.9 * candidates.size());
  EXPECT_GE(correct, n - 5);
  // Predicted two levels too high: the default window [pred - 1, pred] misses them, a wider
  // window finds them again.
  for (ProjectedPoint& pp : candidates) pp.predicted_level += 2;
  std::vector<int> a1(frame->size(), -1), a2(frame->size(), -1);
  const int narrow = SearchLocalPoints(*frame, candidates, 1.0, &a1);
  const int wide = SearchLocalPoints(*frame, candidates, 1.0, &a2, 2, 0);
  EXPECT_LT(narrow, 0.3 * correct);
  EXPECT_GT(wide, 0.8 * correct);
}

TEST(Matcher, DescriptorMatchingRatioTest) {
  test::SyntheticScene scene(13);
  FramePair p =
      MakePair(scene, test::CamFromWorld({0, 0, 0}, 0), test::CamFromWorld({0, 0, 1.5}, 0.03));
  std::vector<int> a_idx, b_idx;
  for (int i = 0; i < p.a->size(); ++i) a_idx.push_back(i);
  for (int j = 0; j < p.b->size(); ++j) b_idx.push_back(j);
  const auto pairs = MatchDescriptors(*p.a, a_idx, *p.b, b_idx, 50, 0.75, true);
  int correct = 0;
  std::set<int> used_b;
  for (const auto& [i, j] : pairs) {
    EXPECT_TRUE(used_b.insert(j).second);
    if (p.point_a[i] >= 0 && p.point_a[i] == p.point_b[j]) ++correct;
  }
  EXPECT_GT(pairs.size(), 500u);
  EXPECT_GE(correct, static_cast<int>(pairs.size()) - 2);
  // Two identical descriptors in b make their match ambiguous: the ratio test drops it.
  const int target = pairs.front().second, copy = pairs.back().second;
  ASSERT_NE(target, copy);
  cv::Mat desc = p.b->descriptors().clone();
  desc.row(target).copyTo(desc.row(copy));
  OrbFeatures f;
  f.keypoints = p.b->keypoints();
  f.descriptors = desc;
  StereoMatches none;
  const FramePtr b2 = Frame::Create(5, 0, p.b->rig(), p.b->scale(), f, none);
  const auto pairs2 = MatchDescriptors(*p.a, a_idx, *b2, b_idx, 50, 0.75, true);
  // Everything else still matches as before; neither of the two tied keypoints matches.
  std::vector<std::pair<int, int>> others;
  for (const auto& [i, j] : pairs)
    if (j != target && j != copy) others.emplace_back(i, j);
  std::vector<std::pair<int, int>> sorted2(pairs2.begin(), pairs2.end());
  std::sort(others.begin(), others.end());
  std::sort(sorted2.begin(), sorted2.end());
  EXPECT_EQ(sorted2, others);
  for (const auto& [i, j] : pairs2) {
    EXPECT_NE(j, target);
    EXPECT_NE(j, copy);
  }
}

TEST(Matcher, EpipolarSearchForTriangulation) {
  test::SyntheticScene scene(14);
  FramePair p =
      MakePair(scene, test::CamFromWorld({0, 0, 0}, 0), test::CamFromWorld({0.5, 0, 3.0}, 0.05));
  std::vector<uint8_t> free_a(p.a->size(), 1), free_b(p.b->size(), 1);
  free_a[0] = 0;
  const auto pairs = SearchForTriangulation(*p.a, p.pose_a, free_a, *p.b, p.pose_b, free_b);
  int correct = 0;
  for (const auto& [i, j] : pairs) {
    EXPECT_NE(i, 0);
    if (p.point_a[i] >= 0 && p.point_a[i] == p.point_b[j]) ++correct;
  }
  EXPECT_GT(pairs.size(), 300u);
  EXPECT_GT(correct, 0.97 * pairs.size());
}

TEST(Matcher, FuseByProjectionChecksReprojection) {
  test::SyntheticScene scene(15);
  const SE3 pose = test::CamFromWorld({0, 0, 1}, 0.01);
  std::vector<int> point_of;
  const FramePtr frame = scene.MakeFrame(0, pose, &point_of);
  std::vector<FuseCandidate> good, shifted;
  std::vector<int> good_kp;
  for (int i = 0; i < frame->size() && good.size() < 200; ++i) {
    if (point_of[i] < 0) continue;
    const Eigen::Vector3d x = scene.point(point_of[i]);
    const double d = (x - pose.inverse().translation()).norm();
    FuseCandidate c;
    c.p_in_world = x;
    c.normal = (x - pose.inverse().translation()).normalized();
    c.max_distance_m = d * frame->scale().scale_factors[frame->octave(i)];
    c.min_distance_m = c.max_distance_m / frame->scale().scale_factors.back();
    c.descriptor = frame->descriptor(i);
    good.push_back(c);
    good_kp.push_back(i);
    // 8 level-0 pixels sideways at the point's depth: outside the chi-square gate.
    FuseCandidate s = c;
    const Eigen::Vector3d pc = pose * x;
    s.p_in_world =
        pose.inverse() *
        (pc + Eigen::Vector3d(
                  8.0 * pc.z() / 718.856 * frame->scale().scale_factors[frame->octave(i)], 0, 0));
    shifted.push_back(s);
  }
  const auto found = FuseByProjection(*frame, pose, good, 3.0);
  int same = 0;
  for (const auto& [c, kp] : found) same += (kp == good_kp[c]);
  EXPECT_GT(same, 180);
  EXPECT_LT(FuseByProjection(*frame, pose, shifted, 3.0).size(), 10u);
}

TEST(StereoPoints, SelectionCountsAndInitialisation) {
  test::SyntheticScene scene(16);
  std::vector<int> point_of;
  const FramePtr frame = scene.MakeFrame(0, SE3::Identity(), &point_of);
  const double close = 40 * frame->rig().baseline_m;
  std::vector<MapPointId> none(frame->size());
  const std::vector<int> selected = SelectStereoPointsToCreate(*frame, none, close, 100);
  int close_count = 0;
  for (int i = 0; i < frame->size(); ++i)
    if (frame->has_stereo(i) && frame->depth_m(i) <= close) ++close_count;
  ASSERT_GT(close_count, 100);
  EXPECT_EQ(static_cast<int>(selected.size()), close_count);
  for (int i : selected) EXPECT_LE(frame->depth_m(i), close);
  // With few close points, far ones fill up to min_points.
  const std::vector<int> selected_small = SelectStereoPointsToCreate(*frame, none, 5.0, 300);
  EXPECT_EQ(selected_small.size(), 300u);
  // Keypoints with a point are skipped but counted.
  std::vector<MapPointId> some(frame->size());
  for (int i : selected) some[i] = MapPointId(i);
  EXPECT_TRUE(SelectStereoPointsToCreate(*frame, some, close, 100).empty());
  const ClosePointCounts counts = CountClosePoints(*frame, some, close);
  EXPECT_EQ(counts.tracked, close_count);
  EXPECT_EQ(counts.untracked, 0);
  EXPECT_EQ(CountClosePoints(*frame, none, close).untracked, close_count);

  const auto init = StereoInitialisation(frame, SE3::Identity(), 500);
  ASSERT_TRUE(init.has_value());
  EXPECT_EQ(static_cast<int>(init->new_points.size()), frame->num_stereo());
  for (size_t k = 0; k < 50; ++k) {
    const KeyframeObservation& o = init->new_points[k].observations[0];
    const Eigen::Vector3d truth = scene.point(point_of[o.keypoint]);
    EXPECT_LT((init->new_points[k].p_in_world - truth).norm(), 0.02 * truth.z() * truth.z());
  }
  EXPECT_FALSE(StereoInitialisation(frame, SE3::Identity(), frame->num_stereo() + 1));
}

}  // namespace
}  // namespace pcr
