#include "slam/tracking/mono_initializer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "slam/common/error.h"
#include "slam/map/synthetic_scene.h"
#include "slam/tracking/tracker.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using test::TruePose;

StereoRig MonoRig() {
  StereoRig rig = test::KittiLikeRig();
  rig.baseline_m = 0;
  return rig;
}

// A monocular frame of the synthetic scene (no stereo), with the scene point of each keypoint.
FramePtr MonoFrame(test::SyntheticScene& scene, int64_t id, const SE3& cam_from_world,
                   std::vector<int>* point_of) {
  test::RenderedFrame r = scene.Render(cam_from_world);
  if (point_of) *point_of = r.point_of_keypoint;
  return Frame::Create(id, id * 100'000'000, MonoRig(), scene.scale(), r.features, StereoMatches{});
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

using test::RotationErrorDeg;

TEST(MonoInitializerOptions, DefaultsAreValidAndBadValuesRejected) {
  std::string why;
  EXPECT_TRUE(MonoInitializerOptions{}.IsValid(&why)) << why;
  MonoInitializerOptions bad;
  bad.match_ratio = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  bad = {};
  bad.min_matches = 3;
  EXPECT_FALSE(bad.IsValid(&why));
  bad = {};
  bad.two_view.ransac_iterations = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_THROW(MonoInitializer{bad}, ConfigError);
  TrackerOptions tracker;
  tracker.mono_init.search_window_px = -1;
  EXPECT_FALSE(tracker.IsValid(&why));
}

TEST(SearchForInitialization, MatchesTheSameScenePointsAndFollowsThem) {
  test::SyntheticScene scene(31);
  std::vector<int> point_of_ref, point_of_cur;
  const FramePtr ref = MonoFrame(scene, 0, TruePose(0), &point_of_ref);
  const FramePtr cur = MonoFrame(scene, 2, TruePose(2), &point_of_cur);
  const MonoInitializerOptions options;  // every octave
  std::vector<Eigen::Vector2d> last(ref->size());
  for (int i = 0; i < ref->size(); ++i) last[i] = ref->uv(i);
  const std::vector<Eigen::Vector2d> before = last;
  const std::vector<int> m = SearchForInitialization(*ref, *cur, &last, options);
  ASSERT_EQ(static_cast<int>(m.size()), ref->size());
  int matched = 0, wrong = 0;
  std::vector<int> used(cur->size(), 0);
  for (int i = 0; i < ref->size(); ++i) {
    if (m[i] < 0) {
      EXPECT_EQ(last[i], before[i]);
      continue;
    }
    ++matched;
    EXPECT_EQ(used[m[i]]++, 0) << "current keypoint used twice";
    EXPECT_EQ(ref->octave(i), cur->octave(m[i]));
    EXPECT_LE((cur->uv(m[i]) - ref->uv(i)).cwiseAbs().maxCoeff(), options.search_window_px);
    EXPECT_EQ(last[i], cur->uv(m[i]));
    if (point_of_ref[i] < 0 || point_of_ref[i] != point_of_cur[m[i]]) ++wrong;
  }
  EXPECT_GT(matched, 500);
  EXPECT_LE(wrong, matched / 50);

  // Only level-0 reference keypoints (ORB-SLAM's choice) when max_octave is 0.
  MonoInitializerOptions level0 = options;
  level0.max_octave = 0;
  std::vector<Eigen::Vector2d> last0(ref->size());
  for (int i = 0; i < ref->size(); ++i) last0[i] = ref->uv(i);
  const std::vector<int> m0 = SearchForInitialization(*ref, *cur, &last0, level0);
  int matched0 = 0;
  for (int i = 0; i < ref->size(); ++i)
    if (m0[i] >= 0) {
      EXPECT_EQ(ref->octave(i), 0);
      ++matched0;
    }
  EXPECT_GT(matched0, 0);
  EXPECT_LT(matched0, matched);
  std::vector<Eigen::Vector2d> wrong_size(3);
  EXPECT_THROW(SearchForInitialization(*ref, *cur, &wrong_size, options), std::invalid_argument);
}

TEST(MonoInitializer, InitialisesFromTwoFramesUpToScale) {
  test::SyntheticScene scene(32);
  const MonoInitializerOptions options;
  MonoInitializer init(options);
  std::optional<MonoInitialisation> result;
  int frame = 0;
  std::map<int, std::vector<int>> point_of;
  for (; frame < 8 && !result; ++frame) {
    result = init.Add(MonoFrame(scene, frame, TruePose(frame), &point_of[frame]));
    if (frame == 0) {
      EXPECT_FALSE(result.has_value());
      EXPECT_EQ(init.last_step().reference_frame_id, 0);
      EXPECT_TRUE(init.last_step().reference_replaced);
    }
  }
  ASSERT_TRUE(result.has_value()) << init.last_step().failure_reason;
  const int cur = frame - 1;
  EXPECT_GE(cur, 1);
  ASSERT_TRUE(result->reference_frame);
  const int ref = static_cast<int>(result->reference_frame->id());
  EXPECT_EQ(ref, 0);
  EXPECT_EQ(init.last_step().reference_frame_id, -1);  // forgotten after success

  // Deltas: the reference keyframe at the identity, then the current one with the points.
  ASSERT_TRUE(result->first_keyframe.new_keyframe.has_value());
  EXPECT_EQ(result->first_keyframe.new_keyframe->frame->id(), ref);
  EXPECT_TRUE(result->first_keyframe.new_keyframe->cam_from_world.isApprox(SE3::Identity()));
  EXPECT_TRUE(result->first_keyframe.new_points.empty());
  ASSERT_TRUE(result->second_keyframe.new_keyframe.has_value());
  EXPECT_EQ(result->second_keyframe.new_keyframe->frame->id(), cur);
  EXPECT_GE(result->num_points, options.min_points);
  EXPECT_EQ(static_cast<int>(result->second_keyframe.new_points.size()), result->num_points);

  // Motion up to scale against the truth (world = the reference camera = TruePose(0)).
  const SE3 truth = TruePose(cur) * TruePose(ref).inverse();
  EXPECT_LT(RotationErrorDeg(result->cam_from_world, truth), 0.2);
  EXPECT_LT(AngleDeg(result->cam_from_world.inverse().translation(), truth.inverse().translation()),
            2.0);

  // Scale: median depth 1 in the first keyframe; with it, points agree with the truth.
  std::vector<double> depths;
  for (const NewMapPoint& p : result->second_keyframe.new_points)
    depths.push_back(p.p_in_world.z());
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  EXPECT_NEAR(depths[depths.size() / 2], 1.0, 1e-9);
  const double scale =
      result->cam_from_world.inverse().translation().norm() / truth.inverse().translation().norm();
  int wrong = 0;
  std::vector<double> errors;
  for (const NewMapPoint& p : result->second_keyframe.new_points) {
    ASSERT_EQ(p.observations.size(), 2u);
    EXPECT_EQ(p.observations[0].keyframe, KeyframeId(ref));
    EXPECT_EQ(p.observations[1].keyframe, KeyframeId(cur));
    const int scene_point = point_of[ref][p.observations[0].keypoint];
    if (scene_point < 0 || scene_point != point_of[cur][p.observations[1].keypoint]) {
      ++wrong;
      continue;
    }
    const Eigen::Vector3d truth_p = TruePose(ref) * scene.point(scene_point);
    errors.push_back((p.p_in_world / scale - truth_p).norm() / truth_p.norm());
  }
  EXPECT_LE(wrong, result->num_points / 50);
  // Relative position errors (far points have little parallax over one metre).
  std::sort(errors.begin(), errors.end());
  ASSERT_FALSE(errors.empty());
  std::printf("relative point errors: p50 %.3f p75 %.3f p90 %.3f\n", errors[errors.size() / 2],
              errors[errors.size() * 3 / 4], errors[errors.size() * 9 / 10]);
  EXPECT_LT(errors[errors.size() / 2], 0.08);
  EXPECT_LT(errors[errors.size() * 3 / 4], 0.2);

  // The deltas build a valid two-keyframe map.
  Map map;
  map.Apply(result->first_keyframe);
  map.Apply(result->second_keyframe);
  EXPECT_EQ(map.num_keyframes(), 2u);
  EXPECT_EQ(static_cast<int>(map.num_points()), result->num_points);
  EXPECT_EQ(map.keyframe(KeyframeId(cur))->parent, KeyframeId(ref));
  EXPECT_EQ(map.keyframe(KeyframeId(ref))->Weight(KeyframeId(cur)), result->num_points);
}

TEST(MonoInitializer, ReplacesTheReferenceWhenMatchesDropOrItAges) {
  test::SyntheticScene scene(33);
  test::SyntheticScene::Options junk_options;
  junk_options.num_points = 0;
  junk_options.num_clutter = 1500;
  test::SyntheticScene junk(99, junk_options);
  MonoInitializerOptions options;
  options.max_reference_age_frames = 2;
  MonoInitializer init(options);
  EXPECT_FALSE(init.Add(MonoFrame(scene, 0, TruePose(0), nullptr)));
  EXPECT_EQ(init.last_step().reference_frame_id, 0);
  // Unrelated keypoints: too few matches, the junk frame becomes the reference.
  EXPECT_FALSE(init.Add(MonoFrame(junk, 1, SE3::Identity(), nullptr)));
  EXPECT_LT(init.last_step().num_matches, options.min_matches);
  EXPECT_TRUE(init.last_step().reference_replaced);
  EXPECT_EQ(init.last_step().reference_frame_id, 1);
  // A frame with too few keypoints is never a reference.
  test::SyntheticScene::Options sparse_options = junk_options;
  sparse_options.num_clutter = 50;
  test::SyntheticScene sparse(98, sparse_options);
  EXPECT_FALSE(init.Add(MonoFrame(sparse, 2, SE3::Identity(), nullptr)));
  EXPECT_EQ(init.last_step().reference_frame_id, -1);
  // No parallax (the same pose again): two-view fails; the reference is replaced once it is
  // max_reference_age_frames old.
  EXPECT_FALSE(init.Add(MonoFrame(scene, 3, TruePose(3), nullptr)));
  EXPECT_EQ(init.last_step().reference_frame_id, 3);
  EXPECT_FALSE(init.Add(MonoFrame(scene, 4, TruePose(3), nullptr)));
  EXPECT_TRUE(init.last_step().tried_two_view);
  EXPECT_FALSE(init.last_step().failure_reason.empty());
  EXPECT_EQ(init.last_step().reference_frame_id, 3);
  EXPECT_FALSE(init.Add(MonoFrame(scene, 5, TruePose(3), nullptr)));
  EXPECT_EQ(init.last_step().reference_frame_id, 5);
  // Moving again: initialises against frame 5.
  std::optional<MonoInitialisation> result;
  for (int f = 6; f < 10 && !result; ++f)
    result = init.Add(MonoFrame(scene, f, TruePose(f - 2), nullptr));
  ASSERT_TRUE(result.has_value()) << init.last_step().failure_reason;
  EXPECT_EQ(result->reference_frame->id(), 5);
}

TEST(MonoInitializer, IsDeterministic) {
  auto run = [] {
    test::SyntheticScene scene(34);
    MonoInitializer init(MonoInitializerOptions{});
    std::optional<MonoInitialisation> r;
    for (int f = 0; f < 8 && !r; ++f) r = init.Add(MonoFrame(scene, f, TruePose(f), nullptr));
    return r;
  };
  const auto a = run(), b = run();
  ASSERT_TRUE(a && b);
  EXPECT_TRUE((a->cam_from_world.matrix().array() == b->cam_from_world.matrix().array()).all());
  ASSERT_EQ(a->num_points, b->num_points);
  for (int i = 0; i < a->num_points; ++i)
    EXPECT_EQ(a->second_keyframe.new_points[i].p_in_world,
              b->second_keyframe.new_points[i].p_in_world);
}

// The tracker initialises a monocular rig from two frames and then tracks the following frames
// against that map (reference keyframe, then motion model), at the map's scale.
TEST(Tracker, MonocularInitialisationThenTracking) {
  test::SyntheticScene scene(35);
  Tracker tracker(TrackerOptions{});
  Map map;
  int init_frame = -1;
  double scale = 0;
  for (int i = 0; i < 10; ++i) {
    const FramePtr frame = MonoFrame(scene, i, TruePose(i), nullptr);
    TrackingResult r = tracker.Track(frame, map);
    if (init_frame < 0) {
      if (r.method != TrackingMethod::kInitialisation) {
        EXPECT_EQ(r.status, TrackingStatus::kNotInitialized);
        EXPECT_FALSE(r.first_keyframe_delta.has_value());
        continue;
      }
      init_frame = i;
      ASSERT_TRUE(r.first_keyframe_delta.has_value());
      map.Apply(*r.first_keyframe_delta);
      map.Apply(r.map_delta);
      tracker.OnKeyframeInserted(KeyframeId(frame->id()), map);
      EXPECT_EQ(map.num_keyframes(), 2u);
      const KeyframeId first = map.first_keyframe();
      const SE3 truth = TruePose(i) * TruePose(static_cast<int>(first.value)).inverse();
      scale =
          r.cam_from_world.inverse().translation().norm() / truth.inverse().translation().norm();
      continue;
    }
    ASSERT_EQ(r.status, TrackingStatus::kOk) << "frame " << i;
    EXPECT_EQ(r.method, i == init_frame + 1 ? TrackingMethod::kReferenceKeyframe
                                            : TrackingMethod::kMotionModel);
    map.Apply(r.map_delta);
    const int first = static_cast<int>(map.first_keyframe().value);
    const SE3 truth = TruePose(i) * TruePose(first).inverse();
    EXPECT_LT(RotationErrorDeg(r.cam_from_world, truth), 0.2) << "frame " << i;
    const Eigen::Vector3d c = r.cam_from_world.inverse().translation() / scale;
    EXPECT_LT((c - truth.inverse().translation()).norm(), 0.05 * (i - first)) << "frame " << i;
    EXPECT_FALSE(r.keyframe_input.stereo);
    EXPECT_GT(r.num_tracked, 100);
  }
  EXPECT_GE(init_frame, 1);
  EXPECT_LE(init_frame, 4);
}

}  // namespace
}  // namespace pcr
