#include "slam/tracking/tracker.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

#include "slam/common/error.h"
#include "slam/map/stereo_points.h"
#include "slam/map/synthetic_scene.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

double TranslationError(const SE3& a, const SE3& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

using test::RotationErrorDeg;

using test::TruePose;

// Inserts the tracked frame as a keyframe with its associations and new stereo points (what
// the system and the local mapper do, without triangulation or bundle adjustment).
void InsertKeyframe(const FramePtr& frame, const TrackingResult& r, Map* map, Tracker* tracker) {
  MapDelta d;
  NewKeyframe kf;
  kf.frame = frame;
  kf.cam_from_world = r.cam_from_world;
  kf.parent_hint = r.reference_keyframe;
  for (int i = 0; i < frame->size(); ++i)
    if (r.points[i].valid()) kf.associations.emplace_back(i, r.points[i]);
  d.new_keyframe = kf;
  const SE3 world_from_cam = r.cam_from_world.inverse();
  for (int i : SelectStereoPointsToCreate(*frame, r.points, 40 * frame->rig().baseline_m, 100)) {
    NewMapPoint p;
    p.p_in_world = world_from_cam * frame->UnprojectStereo(i);
    p.observations.push_back({KeyframeId(frame->id()), i});
    d.new_points.push_back(p);
  }
  map->Apply(d);
  tracker->OnKeyframeInserted(KeyframeId(frame->id()), *map);
}

// Map, tracker and the results of the frames tracked so far.
struct TrackerRun {
  Map map;
  Tracker tracker{TrackerOptions{}};
  std::vector<TrackingResult> results;
  std::map<int64_t, std::vector<int>> point_of_frame;  // scene point per keypoint, per frame id
};

void TrackFrames(test::SyntheticScene& scene, int first, int last, TrackerRun* run,
                 std::vector<FramePtr>* frames = nullptr) {
  for (int i = first; i < last; ++i) {
    std::vector<int> point_of;
    const FramePtr frame = scene.MakeFrame(i, TruePose(i), &point_of);
    run->point_of_frame[i] = point_of;
    if (frames) frames->push_back(frame);
    TrackingResult r = run->tracker.Track(frame, run->map);
    run->map.Apply(r.map_delta);
    if (r.method == TrackingMethod::kInitialisation)
      run->tracker.OnKeyframeInserted(KeyframeId(frame->id()), run->map);
    else if (r.status == TrackingStatus::kOk && ShouldInsertKeyframe(r.keyframe_input).insert)
      InsertKeyframe(frame, r, &run->map, &run->tracker);
    run->results.push_back(std::move(r));
  }
}

// Tracks a frame of unrelated keypoints (a scene of clutter only, of this seed): lost.
TrackingResult TrackJunk(TrackerRun* run, uint32_t seed, int64_t frame_id) {
  test::SyntheticScene::Options junk_options;
  junk_options.num_points = 0;
  junk_options.num_clutter = 1500;
  test::SyntheticScene junk(seed, junk_options);
  return run->tracker.Track(junk.MakeFrame(frame_id, SE3::Identity(), nullptr), run->map);
}

TEST(Tracker, TracksASyntheticStereoTrajectory) {
  test::SyntheticScene scene(21);
  TrackerRun run;
  TrackFrames(scene, 0, 25, &run);
  ASSERT_EQ(run.results.size(), 25u);
  EXPECT_EQ(run.results[0].method, TrackingMethod::kInitialisation);
  EXPECT_EQ(run.results[1].method, TrackingMethod::kReferenceKeyframe);  // no velocity yet
  for (int i = 0; i < 25; ++i) {
    const TrackingResult& r = run.results[i];
    ASSERT_EQ(r.status, TrackingStatus::kOk) << "frame " << i;
    if (i >= 2) {
      EXPECT_EQ(r.method, TrackingMethod::kMotionModel) << "frame " << i;
    }
    // World = first camera, which is the identity of the true trajectory too. Without bundle
    // adjustment the stereo depth noise makes the position drift slowly (1 m per frame).
    EXPECT_LT(TranslationError(r.cam_from_world, TruePose(i)), 0.03 + 0.01 * i) << "frame " << i;
    EXPECT_LT(RotationErrorDeg(r.cam_from_world, TruePose(i)), 0.1) << "frame " << i;
    if (i > 0) {
      EXPECT_GT(r.num_tracked, 150) << "frame " << i;
      EXPECT_EQ(static_cast<int>(std::count_if(r.points.begin(), r.points.end(),
                                               [](MapPointId p) { return p.valid(); })),
                r.num_tracked);
      // Counters: every tracked point was found and visible.
      EXPECT_EQ(static_cast<int>(r.map_delta.found_increments.size()), r.num_tracked);
      EXPECT_GE(r.map_delta.visible_increments.size(), r.map_delta.found_increments.size());
      EXPECT_TRUE(r.reference_keyframe.valid());
    }
  }
  EXPECT_GE(run.map.num_keyframes(), 3u);
  EXPECT_EQ(run.tracker.status(), TrackingStatus::kOk);
}

TEST(Tracker, TrackedPointsAreTheRightOnes) {
  test::SyntheticScene scene(22);
  TrackerRun run;
  TrackFrames(scene, 0, 6, &run);
  std::vector<int> point_of;
  const FramePtr frame = scene.MakeFrame(6, TruePose(6), &point_of);
  const TrackingResult r = run.tracker.Track(frame, run.map);
  ASSERT_EQ(r.status, TrackingStatus::kOk);
  int checked = 0, wrong = 0;
  for (int i = 0; i < frame->size(); ++i) {
    if (!r.points[i].valid()) continue;
    const MapPoint* mp = run.map.point(r.points[i]);
    ASSERT_NE(mp, nullptr);
    ++checked;
    // The map point was made from a keyframe keypoint of the same scene point.
    const int kp = mp->observations.at(mp->reference_keyframe);
    if (point_of[i] < 0 || run.point_of_frame.at(mp->reference_keyframe.value)[kp] != point_of[i])
      ++wrong;
  }
  EXPECT_GT(checked, 200);
  EXPECT_LE(wrong, checked / 100);
}

TEST(Tracker, LosesTrackOnGarbageAndRelocalises) {
  test::SyntheticScene scene(23);
  TrackerRun run;
  TrackFrames(scene, 0, 8, &run);
  ASSERT_EQ(run.tracker.status(), TrackingStatus::kOk);
  // A frame of unrelated keypoints: tracking is lost.
  const TrackingResult lost = TrackJunk(&run, 99, 8);
  EXPECT_EQ(lost.status, TrackingStatus::kLost);
  EXPECT_EQ(run.tracker.status(), TrackingStatus::kLost);
  EXPECT_TRUE(lost.map_delta.found_increments.empty());
  // Back near the map (at frame 5's place): relocalised by descriptor matching and PnP.
  const FramePtr back = scene.MakeFrame(9, TruePose(5), nullptr);
  const TrackingResult r = run.tracker.Track(back, run.map);
  ASSERT_EQ(r.status, TrackingStatus::kOk);
  EXPECT_EQ(r.method, TrackingMethod::kRelocalisation);
  EXPECT_LT(TranslationError(r.cam_from_world, TruePose(5)), 0.05);
  EXPECT_LT(RotationErrorDeg(r.cam_from_world, TruePose(5)), 0.1);
  EXPECT_TRUE(r.keyframe_input.recently_relocalised);
}

// A frame at `pose` that also shows, as a repeated structure would, `repeats` keypoints looking
// exactly like what the map shows at `lookalike` (their descriptors, where they would be seen).
FramePtr FrameWithRepeats(test::SyntheticScene& scene, int64_t id, const SE3& pose,
                          const SE3& lookalike, int repeats) {
  test::RenderedFrame r = scene.Render(pose);
  const test::RenderedFrame fake = scene.Render(lookalike);
  std::vector<cv::Mat> rows{r.features.descriptors};
  for (int k = 0, added = 0; k < static_cast<int>(fake.point_of_keypoint.size()) && added < repeats;
       k += 7) {
    if (fake.point_of_keypoint[k] < 0 || fake.stereo.depth_m[k] <= 0) continue;
    r.features.keypoints.push_back(fake.features.keypoints[k]);
    rows.push_back(fake.features.descriptors.row(k));
    r.stereo.u_right_px.push_back(fake.stereo.u_right_px[k]);
    r.stereo.depth_m.push_back(fake.stereo.depth_m[k]);
    ++r.stereo.num_matched;
    ++added;
  }
  cv::vconcat(rows, r.features.descriptors);
  return Frame::Create(id, id * 100'000'000, scene.rig(), scene.scale(), r.features, r.stereo, {});
}

// A turn the constant-velocity model does not foresee: frame 9 yaws 6 degrees away from where
// frames 0-8 were heading, and a repeated structure makes 60 keypoints look exactly like what the
// map shows at the predicted pose. The motion model's window finds those and its optimisation
// agrees with them: a wrong pose with a few, consistent inliers. The consistency check compares
// it with reference-keyframe tracking and keeps the true pose; the next frames go on from there.
// Keypoints per map point in a result (more than one: a point tracked twice).
int DuplicateAssociations(const TrackingResult& r) {
  std::map<MapPointId, int> uses;
  for (MapPointId p : r.points)
    if (p.valid()) ++uses[p];
  int duplicates = 0;
  for (const auto& [id, count] : uses) duplicates += count - 1;
  return duplicates;
}

TEST(Tracker, RelocalisationMatchesAMapPointToOneKeypointOnly) {
  test::SyntheticScene scene(23);
  TrackerRun run;
  TrackFrames(scene, 0, 8, &run);
  ASSERT_EQ(TrackJunk(&run, 99, 8).status, TrackingStatus::kLost);
  // Back at frame 5's place, with most descriptors 72 bits off (beyond the descriptor matching's
  // distance, within the projection search's), so that PnP finds few matches and the search by
  // projection runs; and every keypoint found again one level up (one corner, two keypoints).
  test::RenderedFrame rendered = scene.Render(TruePose(5));
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> bit(0, 255);
  const int n = static_cast<int>(rendered.features.keypoints.size());
  for (int i = 0; i < n; ++i) {
    if (i % 40 == 0) continue;
    std::set<int> bits;
    while (bits.size() < 72) bits.insert(bit(rng));
    for (int b : bits)
      rendered.features.descriptors.at<uint8_t>(i, b / 8) ^= static_cast<uint8_t>(1u << (b % 8));
  }
  OrbFeatures features = rendered.features;
  StereoMatches stereo = rendered.stereo;
  std::vector<cv::Mat> rows{rendered.features.descriptors};
  for (int i = 0; i < n; ++i) {
    cv::KeyPoint kp = rendered.features.keypoints[i];
    if (kp.octave >= 7) continue;
    kp.octave += 1;
    kp.pt += cv::Point2f(0.4f, -0.3f);
    features.keypoints.push_back(kp);
    rows.push_back(rendered.features.descriptors.row(i).clone());
    stereo.u_right_px.push_back(rendered.stereo.u_right_px[i]);
    stereo.depth_m.push_back(rendered.stereo.depth_m[i]);
  }
  cv::vconcat(rows, features.descriptors);
  const FramePtr back =
      Frame::Create(9, 9 * 100'000'000, scene.rig(), scene.scale(), features, stereo);
  const TrackingResult r = run.tracker.Track(back, run.map);
  ASSERT_EQ(r.status, TrackingStatus::kOk);
  EXPECT_EQ(r.method, TrackingMethod::kRelocalisation);
  EXPECT_EQ(DuplicateAssociations(r), 0);
}

TEST(Tracker, RotationSinceTheLastKeyframeIsAgainstItsPoseInTheMapNow) {
  test::SyntheticScene scene(21);
  TrackerRun run;
  TrackFrames(scene, 0, 8, &run);
  {  // a keyframe at frame 8
    const FramePtr f = scene.MakeFrame(8, TruePose(8), nullptr);
    TrackingResult r = run.tracker.Track(f, run.map);
    run.map.Apply(r.map_delta);
    InsertKeyframe(f, r, &run.map, &run.tracker);
  }
  // A correction turns the whole map 12 degrees (every keyframe and point, as a loop correction
  // does to its part of the map): the next frame has turned only as the camera did since.
  SE3 turn = SE3::Identity();
  turn.linear() = Eigen::AngleAxisd(12.0 * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
  MapDelta correction;
  for (const auto& [id, kf] : run.map.keyframes())
    correction.keyframe_poses.emplace_back(id, SE3(kf.cam_from_world * turn.inverse()));
  for (const auto& [id, mp] : run.map.points())
    correction.point_positions.emplace_back(id, turn * mp.p_in_world);
  run.map.Apply(correction);
  const TrackingResult r = run.tracker.Track(scene.MakeFrame(9, TruePose(9), nullptr), run.map);
  ASSERT_EQ(r.status, TrackingStatus::kOk);
  const SE3 keyframe_now = run.map.keyframe(run.map.last_keyframe())->cam_from_world;
  const double turned =
      RotationAngleRad(r.cam_from_world.linear() * keyframe_now.linear().transpose());
  EXPECT_LT(turned * 180 / M_PI, 2.0);
  EXPECT_NEAR(r.keyframe_input.rotation_since_keyframe_rad, turned, 1e-9);
}

// Localisation mode on a map that holds one place twice: keyframe 100 (copy A, at the place's
// true pose) and keyframe 200 (copy B, the same place 3 m to the side in the map), each with its
// points; one copy dense, the other with every `sparse`-th stereo point only.
struct TwoCopies {
  explicit TwoCopies(bool dense_b) : scene(31) {
    AddCopy(100, Eigen::Vector3d::Zero(), dense_b ? 4 : 1);
    AddCopy(200, Eigen::Vector3d(3, 0, 0), dense_b ? 1 : 3);
  }
  static SE3 Pose(double s) { return test::CamFromWorld({0.05 * s, 0.0, 1.0 * s}, 0.01 * s); }
  void AddCopy(int64_t id, const Eigen::Vector3d& offset, int every) {
    const FramePtr f = scene.MakeFrame(id, Pose(5), nullptr);
    SE3 true_from_copy = SE3::Identity();
    true_from_copy.translation() = -offset;
    const SE3 cam_from_copy = Pose(5) * true_from_copy;
    MapDelta delta;
    NewKeyframe kf;
    kf.frame = f;
    kf.cam_from_world = cam_from_copy;
    delta.new_keyframe = kf;
    int k = 0;
    for (int i = 0; i < f->size(); ++i) {
      if (!f->has_stereo(i) || (k++ % every)) continue;
      NewMapPoint p;
      p.p_in_world = cam_from_copy.inverse() * f->UnprojectStereo(i);
      p.observations.push_back({KeyframeId(id), i});
      delta.new_points.push_back(p);
    }
    map.Apply(delta);
  }
  // Frames 1..5 along the route; the place query answers copy A first, then copy B.
  std::vector<TrackingResult> Drive() {
    TrackerOptions o;
    o.localisation_recheck_frames = 2;
    o.min_relocalisation_confirmations = 0;  // the toy map has no covisible keyframes
    Tracker tracker(o);
    tracker.SetLocalisationMode(true);
    int call = 0;
    const PlaceQuery place = [&](const Frame&) {
      return std::vector<KeyframeId>{KeyframeId(++call == 1 ? 100 : 200)};
    };
    std::vector<TrackingResult> results;
    for (int k = 0; k < 5; ++k)
      results.push_back(
          tracker.Track(scene.MakeFrame(k + 1, Pose(5 + 0.3 * k), nullptr), map, place));
    return results;
  }
  test::SyntheticScene scene;
  Map map;
};

TEST(Tracker, LocalisationModeSwitchingPlacesStartsTheMotionModelAfresh) {
  // Copy B is denser: the check at frame 2 moves tracking onto it. The velocity across that
  // switch would hold the 3 m between the copies; frame 3 has none and is not mispredicted.
  TwoCopies copies(/*dense_b=*/true);
  const std::vector<TrackingResult> r = copies.Drive();
  ASSERT_EQ(r[1].status, TrackingStatus::kOk);
  ASSERT_EQ(r[1].reference_keyframe, KeyframeId(200));
  for (size_t k = 2; k < r.size(); ++k) {
    ASSERT_EQ(r[k].status, TrackingStatus::kOk) << k;
    EXPECT_EQ(r[k].motion_model_rejected, 0) << k;
    EXPECT_EQ(r[k].reference_keyframe, KeyframeId(200)) << k;
  }
}

TEST(Tracker, LocalisationModeKeepsItsReferenceWhenTheOtherPlaceIsNotBetter) {
  // Copy B is sparser: each check finds it and keeps copy A, and with it copy A's keyframe.
  TwoCopies copies(/*dense_b=*/false);
  const std::vector<TrackingResult> r = copies.Drive();
  for (size_t k = 0; k < r.size(); ++k) {
    ASSERT_EQ(r[k].status, TrackingStatus::kOk) << k;
    EXPECT_EQ(r[k].reference_keyframe, KeyframeId(100)) << k;
    EXPECT_LT(r[k].cam_from_world.inverse().translation().x(), 1.0) << k;  // on copy A
  }
}

TEST(Tracker, AWrongMotionPredictionIsCaughtAndRecoveredFrom) {
  for (const bool check : {true, false}) {
    test::SyntheticScene scene(25);
    TrackerRun run;
    TrackerOptions options;
    if (!check) options.min_motion_inlier_ratio = options.min_motion_inliers_of_last = 0;
    run.tracker = Tracker(options);
    TrackFrames(scene, 0, 9, &run);
    ASSERT_EQ(run.results.back().method, TrackingMethod::kMotionModel);
    const auto turned = [](int i) {
      return test::CamFromWorld({0.05 * i, 0.0, 1.0 * i}, 0.01 * i + (i >= 9 ? 0.105 : 0.0));
    };
    int rejected = 0;
    double turn_error_deg = 0, worst_deg = 0;
    for (int i = 9; i < 13; ++i) {
      const FramePtr frame = i == 9 ? FrameWithRepeats(scene, i, turned(i), TruePose(i), 60)
                                    : scene.MakeFrame(i, turned(i), nullptr);
      const TrackingResult r = run.tracker.Track(frame, run.map);
      run.map.Apply(r.map_delta);
      rejected += r.motion_model_rejected;
      const double error =
          r.status == TrackingStatus::kOk ? RotationErrorDeg(r.cam_from_world, turned(i)) : 180.0;
      if (i == 9) turn_error_deg = error;
      worst_deg = std::max(worst_deg, error);
      if (r.status == TrackingStatus::kOk && ShouldInsertKeyframe(r.keyframe_input).insert)
        InsertKeyframe(frame, r, &run.map, &run.tracker);
    }
    if (check) {
      EXPECT_EQ(rejected, 1) << "the turn's frame: its motion-model pose replaced";
      EXPECT_LT(worst_deg, 0.1);
    } else {
      // Without the check the wrong pose is accepted (so this test can fail).
      EXPECT_EQ(rejected, 0);
      EXPECT_GT(turn_error_deg, 1.0);
    }
  }
}

// A lost frame elsewhere that shows a look-alike of a mapped place in a small part of the image
// (a poster, a repeated facade): 150 keypoints exactly as the map saw them from frame 5, the rest
// an unrelated scene. Descriptor matching and PnP support frame 5's pose with 150 inliers, but the
// local map around that pose finds nothing else in the frame: the candidate is rejected and the
// frame stays lost. Without the verification it would be accepted.
TEST(Tracker, ARelocalisationCandidateTheLocalMapDoesNotConfirmIsRejected) {
  for (const bool verify : {true, false}) {
    test::SyntheticScene scene(26);
    TrackerRun run;
    TrackerOptions options;
    if (!verify) options.min_relocalisation_confirmations = 0;
    run.tracker = Tracker(options);
    TrackFrames(scene, 0, 8, &run);
    ASSERT_EQ(TrackJunk(&run, 98, 8).status, TrackingStatus::kLost);

    test::SyntheticScene::Options other_options;
    other_options.num_clutter = 0;
    test::SyntheticScene other(97, other_options);
    test::RenderedFrame r = other.Render(TruePose(3));
    const test::RenderedFrame place = scene.Render(TruePose(5));
    std::vector<cv::Mat> rows{r.features.descriptors};
    for (int k = 0, added = 0; k < static_cast<int>(place.point_of_keypoint.size()) && added < 150;
         ++k) {
      if (place.point_of_keypoint[k] < 0) continue;
      r.features.keypoints.push_back(place.features.keypoints[k]);
      rows.push_back(place.features.descriptors.row(k));
      r.stereo.u_right_px.push_back(place.stereo.u_right_px[k]);
      r.stereo.depth_m.push_back(place.stereo.depth_m[k]);
      ++added;
    }
    cv::vconcat(rows, r.features.descriptors);
    const FramePtr poster =
        Frame::Create(9, 9 * 100'000'000, scene.rig(), scene.scale(), r.features, r.stereo, {});
    const RelocalisationStats before = run.tracker.relocalisation_stats();
    const TrackingResult result = run.tracker.Track(poster, run.map);
    const RelocalisationStats& after = run.tracker.relocalisation_stats();
    EXPECT_EQ(after.calls, before.calls + 1);
    const int passed = after.passed - before.passed, rejected = after.rejected - before.rejected;
    EXPECT_GE(passed, 1) << "PnP supported a candidate";
    EXPECT_GE(after.matched - before.matched, passed);
    EXPECT_GE(after.keyframes_tried - before.keyframes_tried, after.matched - before.matched);
    if (verify) {
      EXPECT_EQ(result.status, TrackingStatus::kLost);
      EXPECT_EQ(rejected, passed);
      EXPECT_EQ(after.accepted, before.accepted);
    } else {
      EXPECT_EQ(result.status, TrackingStatus::kOk);
      EXPECT_EQ(result.method, TrackingMethod::kRelocalisation);
      EXPECT_EQ(after.accepted, before.accepted + 1);
      EXPECT_EQ(passed, rejected + 1);
    }
  }
}

TEST(Tracker, ExcludedKeypointsNeverEnterTracking) {
  test::SyntheticScene scene(24);
  Map map;
  Tracker tracker{TrackerOptions{}};
  // Exclude every other keypoint from the first frame on.
  KeypointFilter filter;
  filter.excluded.assign(3000, 0);
  for (size_t i = 0; i < filter.excluded.size(); i += 2) filter.excluded[i] = 1;
  for (int i = 0; i < 5; ++i) {
    const FramePtr frame = scene.MakeFrame(i, TruePose(i), nullptr, filter);
    ASSERT_GT(frame->num_excluded(), 500);
    TrackingResult r = tracker.Track(frame, map);
    ASSERT_EQ(r.status, TrackingStatus::kOk) << "frame " << i;
    if (i == 0) {
      for (const NewMapPoint& p : r.map_delta.new_points) {
        EXPECT_FALSE(frame->excluded(p.observations[0].keypoint));
      }
    }
    for (int k = 0; k < frame->size(); ++k) {
      if (frame->excluded(k)) {
        EXPECT_FALSE(r.points[k].valid()) << "frame " << i;
      }
    }
    if (i > 0) {
      EXPECT_EQ(r.keyframe_input.filtered_points, frame->num_excluded());
    }
    EXPECT_LT(TranslationError(r.cam_from_world, TruePose(i)), 0.05);
    map.Apply(r.map_delta);
    if (i == 0) tracker.OnKeyframeInserted(KeyframeId(frame->id()), map);
  }
}

TEST(Tracker, NeedsEnoughStereoPointsToInitialise) {
  test::SyntheticScene::Options sparse;
  sparse.num_points = 300;
  test::SyntheticScene scene(25, sparse);
  Map map;
  Tracker tracker{TrackerOptions{}};
  const TrackingResult r = tracker.Track(scene.MakeFrame(0, SE3::Identity(), nullptr), map);
  EXPECT_EQ(r.status, TrackingStatus::kNotInitialized);
  EXPECT_TRUE(r.map_delta.empty());
  EXPECT_THROW(tracker.Track(nullptr, map), std::invalid_argument);
}

TEST(Tracker, OptionsValidation) {
  TrackerOptions bad;
  bad.min_relocalisation_matches = 3;
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_THROW(Tracker{bad}, ConfigError);
  bad = {};
  bad.pose.rounds = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_TRUE(TrackerOptions{}.IsValid(&why)) << why;
}

TEST(LocalMap, CollectsObserversNeighboursAndReference) {
  test::SyntheticScene scene(26);
  TrackerRun run;
  TrackFrames(scene, 0, 20, &run);
  ASSERT_GE(run.map.num_keyframes(), 3u);
  const TrackingResult& last = run.results.back();
  std::vector<MapPointId> matched;
  for (MapPointId p : last.points)
    if (p.valid()) matched.push_back(p);
  const LocalMap local = CollectLocalKeyframes(run.map, matched, 80, 10);
  ASSERT_FALSE(local.keyframes.empty());
  EXPECT_EQ(local.keyframes.front(), local.reference);
  // The reference shares the most points with the frame.
  std::map<KeyframeId, int> counts;
  for (MapPointId p : matched)
    for (const auto& obs : run.map.point(p)->observations) ++counts[obs.first];
  for (const auto& [id, c] : counts) EXPECT_LE(c, counts[local.reference]);
  EXPECT_GE(local.keyframes.size(), 2u);
  const LocalMap capped = CollectLocalKeyframes(run.map, matched, 1, 10);
  EXPECT_EQ(capped.keyframes.size(), 1u);
  EXPECT_TRUE(CollectLocalKeyframes(run.map, {}, 80, 10).keyframes.empty());
}

}  // namespace
}  // namespace pcr
