// The whole DynamicFilter on the synthetic street (filter_test_scene.h): moving points out,
// parked / static / near points in, ground plane and horizon, sky and border points, a frame
// whose segmentation misses the moving box, the filter without segmentation, and with the
// camera motion estimated by PnP instead of given.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <map>

#include "filter_test_scene.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/geometry/se3.h"

namespace pcr {
namespace {

using test::PointKind;

constexpr int kNumKinds = 7;

// Fractions of a kind that has no points are NaN: every comparison with them fails.
struct KindStats {
  std::array<int, kNumKinds> total{}, excluded{}, moving{};
  double Excluded(PointKind k) const {
    const int t = total[static_cast<int>(k)];
    return t > 0 ? static_cast<double>(excluded[static_cast<int>(k)]) / t
                 : std::numeric_limits<double>::quiet_NaN();
  }
  double Kept(PointKind k) const { return 1.0 - Excluded(k); }
  int Total(PointKind k) const { return total[static_cast<int>(k)]; }
};

struct RunOptions {
  bool with_segmentation = true;
  bool with_prior = true;
  bool matched_positions = true;
  SE3 prior_error = SE3::Identity();  // applied to the true motion: a rough motion model
};

struct RunResult {
  std::vector<FilterOutput> outputs;
  KindStats stats;  // frames >= 1
};

RunResult RunScene(const std::vector<test::FilterSceneFrame>& frames, const RunOptions& run,
                   const DynamicFilterOptions& options = {}) {
  // With a prior, these runs exercise the prior path (it is exact here); PnP is tested apart.
  DynamicFilterOptions opts = options;
  if (run.with_prior) opts.motion_source = MotionSourcePolicy::kPriorElsePnp;
  DynamicFilter filter(opts);
  RunResult result;
  for (const test::FilterSceneFrame& f : frames) {
    FilterInput in = test::SceneFilterInput(f);
    if (!run.matched_positions) in.previous_uv_px = {};
    if (!run.with_segmentation) in.segmentation = nullptr;
    in.cur_from_prev.reset();
    if (run.with_prior && f.index > 0) in.cur_from_prev = run.prior_error * f.cur_from_prev;
    FilterOutput out = filter.Process(in);
    EXPECT_EQ(out.filter.weight.size(), f.keypoints.size());
    EXPECT_EQ(out.filter.excluded.size(), f.keypoints.size());
    for (size_t i = 0; i < f.keypoints.size(); ++i) {
      EXPECT_GT(out.filter.weight[i], 0.0f);
      EXPECT_LE(out.filter.weight[i], 1.0f);
      if (f.index == 0) continue;
      const int k = static_cast<int>(f.kinds[i]);
      ++result.stats.total[k];
      if (out.filter.excluded[i]) ++result.stats.excluded[k];
      if (IsMovingReason(out.points[i].reason)) ++result.stats.moving[k];
    }
    result.outputs.push_back(std::move(out));
  }
  return result;
}

void ExpectGoodSeparation(const KindStats& s, const std::string& label) {
  SCOPED_TRACE(label);
  // Every kind is there in numbers (frames 1-5 of the scene: 500 moving, 500 parked, 2430 static,
  // 1824 ground, 64 near, 100 sky and 40 border points), so no fraction below is of nothing.
  EXPECT_GT(s.Total(PointKind::kMoving), 200);
  EXPECT_GT(s.Total(PointKind::kParked), 200);
  EXPECT_GT(s.Total(PointKind::kStatic), 1000);
  EXPECT_GT(s.Total(PointKind::kGround), 1000);
  EXPECT_GT(s.Total(PointKind::kNearStatic), 40);
  EXPECT_GT(s.Total(PointKind::kSky), 50);
  EXPECT_GT(s.Total(PointKind::kBorder), 20);
  EXPECT_GE(s.Excluded(PointKind::kMoving), 0.95);
  EXPECT_GE(s.Kept(PointKind::kParked), 0.95);
  EXPECT_GE(s.Kept(PointKind::kStatic), 0.95);
  EXPECT_GE(s.Kept(PointKind::kGround), 0.95);
  EXPECT_GE(s.Kept(PointKind::kNearStatic), 0.95);
  EXPECT_EQ(s.Excluded(PointKind::kSky), 1.0);
  EXPECT_EQ(s.Excluded(PointKind::kBorder), 1.0);
}

TEST(FilterScene, SeparatesMovingFromParkedAndStaticWithMotionPrior) {
  const auto frames = test::BuildFilterScene({});
  const RunResult r = RunScene(frames, {});
  ExpectGoodSeparation(r.stats, "prior + segmentation");
  for (size_t k = 1; k < r.outputs.size(); ++k) {
    const FilterOutput& out = r.outputs[k];
    EXPECT_EQ(out.motion_source, MotionSource::kPrior);
    // Every sky and border keypoint carries its reason; moving points their motion reasons.
    for (size_t i = 0; i < frames[k].kinds.size(); ++i) {
      const PointKind kind = frames[k].kinds[i];
      const FilterReason reason = out.points[i].reason;
      if (kind == PointKind::kSky) {
        EXPECT_EQ(reason, FilterReason::kSky);
      }
      if (kind == PointKind::kBorder) {
        EXPECT_EQ(reason, FilterReason::kEdge);
      }
      // The box's lowest points, at road level and in the margin below its mask, cannot be told
      // from the road: unreliable motion (kGroundMotion) there, a moving object elsewhere.
      const bool road_level = frames[k].p_in_cam[i].y() > 1.65 - 0.15;
      if (kind == PointKind::kMoving && out.filter.excluded[i] &&
          !(road_level && reason == FilterReason::kGroundMotion)) {
        EXPECT_TRUE(IsMovingReason(reason)) << FilterReasonName(reason);
      }
    }
  }
}

TEST(FilterScene, NearStaticPointWithLargeFlowIsNotFlagged) {
  const auto frames = test::BuildFilterScene({});
  const RunResult r = RunScene(frames, {});
  double max_flow_px = 0.0;
  int checked = 0;
  for (size_t k = 1; k < frames.size(); ++k) {
    for (size_t i = 0; i < frames[k].kinds.size(); ++i) {
      if (frames[k].kinds[i] != PointKind::kNearStatic || frames[k].prev_uv_px[i].x < 0) continue;
      const double flow = cv::norm(frames[k].keypoints[i].pt - frames[k].prev_uv_px[i]);
      max_flow_px = std::max(max_flow_px, flow);
      EXPECT_FALSE(r.outputs[k].filter.excluded[i]) << "flow " << flow << " px";
      EXPECT_GT(r.outputs[k].points[i].frame_static_prob, 0.5f);
      ++checked;
    }
  }
  EXPECT_GT(checked, 40);
  // The pole flows far faster than the crossing box does (which is ~50 px per frame).
  EXPECT_GT(max_flow_px, 100.0);
}

TEST(FilterScene, RecoversGroundPlaneAndHorizon) {
  const auto frames = test::BuildFilterScene({});
  const RunResult r = RunScene(frames, {});
  for (size_t k = 0; k < r.outputs.size(); ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const FilterOutput& out = r.outputs[k];
    ASSERT_TRUE(out.ground.success) << out.ground.failure_reason;
    ASSERT_TRUE(out.ground_plane.has_value());
    // The camera only yaws: the ground normal is (0, -1, 0) and the height 1.65 m in every frame.
    EXPECT_LT(RadToDeg(AngleBetweenRad(out.ground_plane->normal, Eigen::Vector3d(0, -1, 0))), 1.0);
    EXPECT_NEAR(out.ground_plane->d, 1.65, 0.03);
    ASSERT_TRUE(out.horizon.valid);
    EXPECT_FALSE(out.horizon.from_prior);
    // Horizon of a level camera: the principal row, across the image.
    const double cy = test::KittiRig().left.cy;
    EXPECT_NEAR(out.horizon.RowAt(0.0), cy, 8.0);
    EXPECT_NEAR(out.horizon.RowAt(1240.0), cy, 8.0);
    // Ground points are down-weighted, not removed.
    int ground = 0, marked = 0;
    for (size_t i = 0; i < frames[k].kinds.size(); ++i) {
      if (frames[k].kinds[i] != PointKind::kGround || frames[k].depth_m[i] <= 0) continue;
      ++ground;
      if (out.points[i].ground) {
        ++marked;
        EXPECT_FLOAT_EQ(out.points[i].g_ground, 0.7f);
      }
    }
    ASSERT_GT(ground, 200);  // 259-472 ground points with a depth per frame
    EXPECT_GE(marked, 0.95 * ground);
  }
}

TEST(FilterScene, MovingBoxStaysExcludedWhenItsMaskIsMissing) {
  test::FilterSceneOptions scene;
  scene.omit_moving_mask_frame = 3;
  const auto frames = test::BuildFilterScene(scene);
  const RunResult r = RunScene(frames, {});
  ExpectGoodSeparation(r.stats, "mask missing in frame 3");
  int moving = 0, excluded = 0;
  for (size_t i = 0; i < frames[3].kinds.size(); ++i) {
    if (frames[3].kinds[i] != PointKind::kMoving) continue;
    EXPECT_EQ(r.outputs[3].points[i].s_mask, 1.0f);  // really no mask
    ++moving;
    excluded += r.outputs[3].filter.excluded[i] ? 1 : 0;
  }
  EXPECT_GT(moving, 40);
  EXPECT_GE(excluded, 0.95 * moving);
}

TEST(FilterScene, TemporalVoteCarriesThroughAFrameWithoutMaskAndWithoutTracks) {
  // Frame 3: no mask for the moving box and none of its previous positions: no evidence at all
  // in that frame, only what the tracks remember.
  test::FilterSceneOptions scene;
  scene.omit_moving_mask_frame = 3;
  scene.drop_moving_tracks_frame = 3;
  const auto frames = test::BuildFilterScene(scene);
  const RunResult r = RunScene(frames, {});
  int moving = 0, excluded = 0, voted = 0;
  for (size_t i = 0; i < frames[3].kinds.size(); ++i) {
    if (frames[3].kinds[i] != PointKind::kMoving) continue;
    const KeypointDiagnostics& d = r.outputs[3].points[i];
    EXPECT_EQ(d.test, MotionTest::kNone);
    ++moving;
    excluded += r.outputs[3].filter.excluded[i] ? 1 : 0;
    voted += d.vote_log_odds >= DynamicFilterOptions{}.voting.dynamic_threshold ? 1 : 0;
  }
  EXPECT_GT(moving, 40);
  EXPECT_GE(excluded, 0.95 * moving);
  EXPECT_GE(voted, 0.9 * moving);

  // Without temporal memory (window 1, a vote that cannot reach its threshold) the same frame
  // loses the moving box: the carry is what keeps it out.
  DynamicFilterOptions forgetful;
  forgetful.voting.window_frames = 1;
  forgetful.voting.max_evidence = 0.1;
  forgetful.voting.decay = 0.01;
  const RunResult f = RunScene(frames, {}, forgetful);
  int forgetful_excluded = 0;
  for (size_t i = 0; i < frames[3].kinds.size(); ++i) {
    if (frames[3].kinds[i] == PointKind::kMoving && f.outputs[3].filter.excluded[i]) {
      ++forgetful_excluded;
    }
  }
  EXPECT_LT(forgetful_excluded, 0.5 * moving);
}

TEST(FilterScene, PointsWithoutOwnMotionEvidenceOnAMovingInstanceSayTheMotionIsTheInstances) {
  // Frame 3: every other point of the crossing box has lost its previous position, and without
  // temporal memory (window 1, a vote that cannot reach its threshold) it has no motion evidence
  // of its own; the other half see the box move. The unobserved half take the moving instance's
  // verdict and stay excluded, but for the instance's motion (kCluster), not for a motion of
  // their own that nothing observed (kMaskMotion).
  auto frames = test::BuildFilterScene({});
  test::FilterSceneFrame& f3 = frames[3];
  std::vector<uint8_t> unobserved(f3.kinds.size(), 0);
  int n = 0;
  for (size_t i = 0; i < f3.kinds.size(); ++i) {
    if (f3.kinds[i] != PointKind::kMoving || f3.prev_uv_px[i].x < 0.0f) continue;
    if (n++ % 2 == 0) {
      unobserved[i] = 1;
      f3.prev_uv_px[i] = cv::Point2f(-1.0f, -1.0f);
    }
  }
  DynamicFilterOptions forgetful;
  forgetful.voting.window_frames = 1;
  forgetful.voting.max_evidence = 0.1;
  forgetful.voting.decay = 0.01;
  const RunResult r = RunScene(frames, {}, forgetful);
  const FilterOutput& out = r.outputs[3];
  int num_unobserved = 0, unobserved_cluster = 0, num_observed = 0, observed_mask_motion = 0;
  for (size_t i = 0; i < f3.kinds.size(); ++i) {
    if (f3.kinds[i] != PointKind::kMoving || out.points[i].s_mask >= 0.5f) continue;
    const KeypointDiagnostics& d = out.points[i];
    if (unobserved[i]) {
      ++num_unobserved;
      EXPECT_EQ(d.test, MotionTest::kNone);
      EXPECT_TRUE(out.filter.excluded[i]);
      EXPECT_NE(d.reason, FilterReason::kMaskMotion)
          << "keypoint " << i << ": " << FilterReasonName(d.reason);
      unobserved_cluster += d.reason == FilterReason::kCluster ? 1 : 0;
    } else if (d.test != MotionTest::kNone && d.frame_static_prob < 0.5f) {
      ++num_observed;
      observed_mask_motion += d.reason == FilterReason::kMaskMotion ? 1 : 0;
    }
  }
  ASSERT_GT(num_unobserved, 20);
  ASSERT_GT(num_observed, 20);
  EXPECT_EQ(unobserved_cluster, num_unobserved);
  EXPECT_GE(observed_mask_motion, 0.9 * num_observed);  // their own motion: mask+motion
}

TEST(FilterScene, MovingShadowOnTheRoadIsUnreliableNotAMovingObject) {
  // A cyclist's shadow slides 40 px per frame (0.5 m at 9 m) across a patch of road: the keypoints
  // there keep the road's stereo depth (the shadow lies on it) but move in the image, and no mask
  // covers them. Counted: those with a stereo depth (without one, the epipolar test alone does not
  // call an unmasked point moving when a segmenter runs).
  auto frames = test::BuildFilterScene({});
  std::vector<std::vector<uint8_t>> shadow(frames.size());
  int num_shadow = 0;
  for (size_t k = 0; k < frames.size(); ++k) {
    shadow[k].assign(frames[k].kinds.size(), 0);
    for (size_t i = 0; i < frames[k].kinds.size(); ++i) {
      const Eigen::Vector3d& p = frames[k].p_in_cam[i];
      // Road well below the crossing box (rows under its dilated mask) and left of the centre.
      if (frames[k].kinds[i] != PointKind::kGround || p.x() < -4.0 || p.x() > 0.0 || p.z() > 10.0)
        continue;
      shadow[k][i] = 1;
      frames[k].keypoints[i].pt.x += 40.0f * static_cast<float>(k);
      if (k > 0 && frames[k].prev_uv_px[i].x >= 0.0f)
        frames[k].prev_uv_px[i].x += 40.0f * static_cast<float>(k - 1);
      num_shadow += k >= 3 && frames[k].depth_m[i] > 0.0f ? 1 : 0;
    }
  }
  ASSERT_GT(num_shadow, 40);
  const auto count = [&](const RunResult& r, bool want_moving) {
    int excluded = 0, moving = 0;
    for (size_t k = 3; k < frames.size(); ++k) {  // two frames of evidence first
      for (size_t i = 0; i < shadow[k].size(); ++i) {
        if (!shadow[k][i] || !(frames[k].depth_m[i] > 0.0f)) continue;
        excluded += r.outputs[k].filter.excluded[i] ? 1 : 0;
        moving += IsMovingReason(r.outputs[k].points[i].reason) ? 1 : 0;
        if (!want_moving && r.outputs[k].filter.excluded[i]) {
          EXPECT_EQ(r.outputs[k].points[i].reason, FilterReason::kGroundMotion);
        }
      }
    }
    return std::pair<int, int>{excluded, moving};
  };
  const RunResult r = RunScene(frames, {});
  const auto [excluded, moving] = count(r, false);
  EXPECT_GE(excluded, 0.6 * num_shadow);  // out of the pose estimate ...
  EXPECT_EQ(moving, 0);                   // ... but not called a moving object
  EXPECT_GT(r.stats.Total(PointKind::kMoving), 200);
  EXPECT_GT(r.stats.Total(PointKind::kStatic), 1000);
  EXPECT_GE(r.stats.Excluded(PointKind::kMoving), 0.95);  // the crossing box still is
  EXPECT_GE(r.stats.Kept(PointKind::kStatic), 0.95);

  DynamicFilterOptions off;
  off.scoring.ground_motion_unreliable = false;
  const RunResult o = RunScene(frames, {}, off);
  const auto [off_excluded, off_moving] = count(o, true);
  EXPECT_GE(off_excluded, 0.6 * num_shadow);
  EXPECT_EQ(off_moving, off_excluded);  // all of them called moving
}

TEST(FilterScene, VoteEarnedUnderAPassingMaskDoesNotExcludeAnUnresolvedMarginPoint) {
  // Far background points without depth (z = 80 m) that the crossing box's mask covers in frames
  // 0-2 and that sit just left of it in frame 3, in the dilated margin: under the mask they take
  // the moving instance's verdict and its vote; in frame 3 nothing can tell them from the box's
  // edge (no depth), and the vote earned under the mask must not exclude them.
  auto frames = test::BuildFilterScene({});
  const PinholeCamera cam = test::KittiRig().left;
  auto moving_box = [](const test::FilterSceneFrame& f) {  // the leftmost box: the crossing car
    cv::Rect2f best;
    for (const Instance& inst : f.segmentation.instances) {
      if (best.width == 0 || inst.box_px.x < best.x) best = inst.box_px;
    }
    return best;
  };
  const cv::Rect2f box3 = moving_box(frames[3]);
  ASSERT_GT(box3.width, 50.0f);
  std::vector<Eigen::Vector3d> world;
  for (int j = 0; j < 6; ++j) {
    const Eigen::Vector2d uv(box3.x - 3.0, box3.y + 8.0 + 7.0 * j);
    world.push_back(frames[3].world_from_cam * cam.Unproject(uv, 80.0));
  }
  std::vector<size_t> first(frames.size());
  for (size_t k = 0; k < 4; ++k) {
    test::FilterSceneFrame& f = frames[k];
    first[k] = f.keypoints.size();
    for (size_t j = 0; j < world.size(); ++j) {
      const Eigen::Vector3d p = f.world_from_cam.inverse() * world[j];
      const Eigen::Vector2d uv = cam.Project(p);
      f.keypoints.emplace_back(static_cast<float>(uv.x()), static_cast<float>(uv.y()), 7.0f);
      f.keypoints.back().octave = 0;
      f.depth_m.push_back(-1.0f);
      f.ids.push_back(1'000'000 + static_cast<int64_t>(j));
      cv::Point2f prev(-1.0f, -1.0f);
      if (k > 0) {
        const Eigen::Vector2d before =
            cam.Project(frames[k - 1].world_from_cam.inverse() * world[j]);
        prev = cv::Point2f(static_cast<float>(before.x()), static_cast<float>(before.y()));
      }
      f.prev_uv_px.push_back(prev);
      f.kinds.push_back(PointKind::kStatic);
      f.p_in_cam.push_back(p);
      if (k < 3) {
        EXPECT_TRUE(moving_box(f).contains(f.keypoints.back().pt)) << "frame " << k;
      }
    }
  }
  frames.resize(4);
  const RunResult r = RunScene(frames, {});
  const float threshold = static_cast<float>(DynamicFilterOptions{}.voting.dynamic_threshold);
  int unresolved = 0;
  for (size_t j = 0; j < world.size(); ++j) {
    const size_t i = first[3] + j;
    const KeypointDiagnostics& d = r.outputs[3].points[i];
    if (d.instance != 0 || d.s_mask >= 1.0f) continue;  // not a margin point after all
    ++unresolved;
    EXPECT_GE(d.vote_log_odds, threshold) << j;  // the vote from under the mask is there ...
    EXPECT_FALSE(r.outputs[3].filter.excluded[i]) << j << " " << FilterReasonName(d.reason);
  }
  EXPECT_GE(unresolved, 4);
}

TEST(FilterScene, WorksWithoutSegmentation) {
  const auto frames = test::BuildFilterScene({});
  RunOptions run;
  run.with_segmentation = false;
  const RunResult r = RunScene(frames, run);
  ExpectGoodSeparation(r.stats, "no segmentation");
}

TEST(FilterScene, EstimatesCameraMotionByPnpWhenNoPriorIsGiven) {
  const auto frames = test::BuildFilterScene({});
  RunOptions run;
  run.with_prior = false;
  const RunResult r = RunScene(frames, run);
  ExpectGoodSeparation(r.stats, "PnP motion");
  EXPECT_EQ(r.outputs[0].motion_source, MotionSource::kNone);
  for (size_t k = 1; k < frames.size(); ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const FilterOutput& out = r.outputs[k];
    ASSERT_EQ(out.motion_source, MotionSource::kPnp) << out.motion_note;
    const SE3 error = frames[k].cur_from_prev.inverse() * out.cur_from_prev;
    EXPECT_LT(RadToDeg(RotationAngleRad(error.linear())), 0.05);
    EXPECT_LT(error.translation().norm(), 0.02);
  }
}

TEST(FilterScene, DefaultPolicyRefinesARoughPriorByPnp) {
  // A motion-model prior 8 cm and 0.4 deg off: the default policy (PnP, seeded by the prior)
  // recovers the motion and the separation; a prior far off makes PnP look wrong and is used.
  const auto frames = test::BuildFilterScene({});
  SE3 error = SE3::Identity();
  error.linear() = ExpSO3(Eigen::Vector3d(0.0, DegToRad(0.4), 0.0));
  error.translation() = Eigen::Vector3d(0.05, 0.0, 0.06);
  DynamicFilter filter;  // default options
  KindStats stats;
  for (const auto& f : frames) {
    FilterInput in = test::SceneFilterInput(f);
    if (f.index > 0) in.cur_from_prev = error * f.cur_from_prev;
    const FilterOutput out = filter.Process(in);
    if (f.index == 0) continue;
    EXPECT_EQ(out.motion_source, MotionSource::kPnp) << out.motion_note;
    const SE3 e = f.cur_from_prev.inverse() * out.cur_from_prev;
    // Both parts of the prior's error are gone (0.4 deg -> under 0.03 deg now).
    EXPECT_LT(RadToDeg(RotationAngleRad(e.linear())), 0.05);
    EXPECT_LT(e.translation().norm(), 0.02);
    for (size_t i = 0; i < f.kinds.size(); ++i) {
      const int k = static_cast<int>(f.kinds[i]);
      ++stats.total[k];
      stats.excluded[k] += out.filter.excluded[i] ? 1 : 0;
    }
  }
  ExpectGoodSeparation(stats, "rough prior, PnP");

  SE3 far = SE3::Identity();
  far.translation() = Eigen::Vector3d(0.0, 0.0, 0.6);
  DynamicFilter gated;
  FilterInput in;
  for (int k = 0; k < 2; ++k) {
    const auto& f = frames[k];
    in.frame_index = f.index;
    in.left_image = f.image;
    in.keypoints = f.keypoints;
    in.depth_m = f.depth_m;
    in.previous_uv_px = f.prev_uv_px;
    in.rig = test::KittiRig();
    if (k > 0) in.cur_from_prev = far * f.cur_from_prev;
    const FilterOutput out = gated.Process(in);
    if (k == 0) continue;
    EXPECT_EQ(out.motion_source, MotionSource::kPrior);
    EXPECT_NE(out.motion_note.find("PnP rejected"), std::string::npos) << out.motion_note;
  }
}

FilterOutput RunFirstFrame(const std::vector<test::FilterSceneFrame>& frames,
                           const DynamicFilterOptions& options) {
  DynamicFilter filter(options);
  return filter.Process(test::SceneFilterInput(frames[0]));
}

TEST(FilterScene, FirstFrameHasNoMotionEvidenceAndKeepsMaskedPointsAtReducedWeight) {
  const auto frames = test::BuildFilterScene({});
  const FilterOutput out = RunFirstFrame(frames, {});
  DynamicFilterOptions strict;
  strict.keep_first_frame_masks = false;
  const FilterOutput strict_out = RunFirstFrame(frames, strict);
  int static_kept = 0, statics = 0, masked = 0;
  for (size_t i = 0; i < frames[0].kinds.size(); ++i) {
    const PointKind kind = frames[0].kinds[i];
    EXPECT_FALSE(out.points[i].has_motion);
    if (kind == PointKind::kStatic || kind == PointKind::kGround) {
      ++statics;
      static_kept += out.filter.excluded[i] ? 0 : 1;
    }
    if ((kind == PointKind::kMoving || kind == PointKind::kParked) && out.points[i].s_mask < 0.2f) {
      ++masked;
      // Kept (the next frames decide), but weighted down by the mask ...
      EXPECT_EQ(out.points[i].reason, FilterReason::kKept);
      EXPECT_LT(out.filter.weight[i], 0.9f);
      // ... and excluded for their mask when the first frame is not special.
      EXPECT_EQ(strict_out.points[i].reason, FilterReason::kMask);
    }
  }
  EXPECT_GT(masked, 20);
  EXPECT_GE(static_kept, 0.95 * statics);
}

}  // namespace
}  // namespace pcr
