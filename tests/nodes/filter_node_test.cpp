// Mask carry-forward, the mask scorer and the filter stage, with hand-made messages.
#include "nodes/filter_node.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "nodes/segment_node.h"
#include "slam/common/error.h"

namespace pcr::nodes {
namespace {

FrameTicket Ticket(int64_t seq) {
  FrameTicket t;
  t.seq = seq;
  t.frame_index = 10 + seq;
  t.t_ns = seq * 100'000'000;
  return t;
}

std::shared_ptr<const Segmentation> MaskWithValue(float value) {
  auto s = std::make_shared<Segmentation>();
  s->dynamic_confidence = cv::Mat(4, 6, CV_32FC1, cv::Scalar(value));
  return s;
}

SegmentationMsg Fresh(int64_t seq, std::shared_ptr<const Segmentation> s) {
  SegmentationMsg m;
  m.ticket = Ticket(seq);
  m.outcome = SegmentationOutcome::kFresh;
  m.segmentation = std::move(s);
  return m;
}

SegmentationMsg NotRun(int64_t seq, SegmentationOutcome outcome) {
  return *SegmentNode::NotRun(Ticket(seq), outcome);
}

// A stale mask is m as it was (the same maps), marked stale.
bool IsStaleCopyOf(const MaskMsg& r, const std::shared_ptr<const Segmentation>& m) {
  return r.status == MaskStatus::kStale && r.segmentation && r.segmentation->stale &&
         r.segmentation->dynamic_confidence.data == m->dynamic_confidence.data;
}

MaskCarryOptions CarryOptions(bool use_stale, int max_age_frames) {
  MaskCarryOptions o;
  o.use_stale = use_stale;
  o.max_age_frames = max_age_frames;
  return o;
}

TEST(MaskCarryTest, FreshMasksAreUsedAndCarriedForwardAsStale) {
  MaskCarry carry;
  const auto m0 = MaskWithValue(0.1f);
  MaskMsg r = carry.Resolve(Fresh(0, m0));
  EXPECT_EQ(r.status, MaskStatus::kFresh);
  EXPECT_EQ(r.segmentation, m0);
  EXPECT_EQ(r.source_seq, 0);
  r = carry.Resolve(NotRun(1, SegmentationOutcome::kNotScheduled));
  EXPECT_TRUE(IsStaleCopyOf(r, m0));
  EXPECT_FALSE(m0->stale);
  EXPECT_EQ(r.source_seq, 0);
  r = carry.Resolve(NotRun(2, SegmentationOutcome::kBusy));
  EXPECT_EQ(r.status, MaskStatus::kStale);
  EXPECT_EQ(r.source_seq, 0);
}

TEST(MaskCarryTest, PrefersTheNewerFallbackButNeverAFutureOne) {
  MaskCarry carry;
  const auto m0 = MaskWithValue(0.1f), m3 = MaskWithValue(0.3f), m9 = MaskWithValue(0.9f);
  carry.Resolve(Fresh(0, m0));
  SegmentationMsg late = NotRun(4, SegmentationOutcome::kLate);
  late.fallback = m3;  // a result that finished after its own frame went on
  late.fallback_seq = 3;
  MaskMsg r = carry.Resolve(late);
  EXPECT_TRUE(IsStaleCopyOf(r, m3));
  EXPECT_EQ(r.source_seq, 3);
  SegmentationMsg future = NotRun(5, SegmentationOutcome::kLate);
  future.fallback = m9;
  future.fallback_seq = 9;
  r = carry.Resolve(future);
  EXPECT_EQ(r.status, MaskStatus::kStale);
  EXPECT_EQ(r.source_seq, 0);  // the carried fallback is not remembered; the last fresh one is
}

TEST(MaskCarryTest, SkipsWithoutSegmenterTooOldOrDisabled) {
  MaskCarry carry(CarryOptions(true, 2));
  carry.Resolve(Fresh(0, MaskWithValue(0.5f)));
  EXPECT_EQ(carry.Resolve(NotRun(1, SegmentationOutcome::kNoSegmenter)).status,
            MaskStatus::kSkipped);
  EXPECT_EQ(carry.Resolve(NotRun(2, SegmentationOutcome::kLate)).status, MaskStatus::kStale);
  EXPECT_EQ(carry.Resolve(NotRun(3, SegmentationOutcome::kLate)).status, MaskStatus::kSkipped);
  MaskCarry no_stale(CarryOptions(false, 5));
  no_stale.Resolve(Fresh(0, MaskWithValue(0.5f)));
  EXPECT_EQ(no_stale.Resolve(NotRun(1, SegmentationOutcome::kNotScheduled)).status,
            MaskStatus::kSkipped);
  MaskCarry empty;
  EXPECT_EQ(empty.Resolve(NotRun(0, SegmentationOutcome::kNotScheduled)).status,
            MaskStatus::kSkipped);
  EXPECT_THROW(MaskCarry(CarryOptions(true, 0)), ConfigError);
}

// Masks that kept their image are carried by their objects' motion: a textured square moving
// 3 px right per frame, segmented on frame 0 only (and a late result of frame 2 arriving at 4).
TEST(MaskCarryTest, MasksWithTheirImageFollowTheirObject) {
  cv::Mat texture(40, 40, CV_8U);
  cv::randu(texture, 0, 255);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 1.0);
  const auto frame = [&](int seq) {
    cv::Mat image(120, 160, CV_8U, cv::Scalar(100));
    texture.copyTo(image(cv::Rect(30 + 3 * seq, 40, 40, 40)));
    return image;
  };
  const auto segmentation_of = [&](int seq) {
    auto s = std::make_shared<Segmentation>();
    Instance inst;
    inst.class_name = "car";
    inst.confidence = 0.9f;
    inst.box_px = cv::Rect2f(30.0f + 3 * seq, 40, 40, 40);
    inst.instance_id = 0;
    s->instances.push_back(inst);
    s->instance_map = cv::Mat(120, 160, CV_16U, cv::Scalar(0));
    s->instance_map(cv::Rect(30 + 3 * seq, 40, 40, 40)).setTo(1);
    s->dynamic_confidence = cv::Mat(120, 160, CV_32F, cv::Scalar(0));
    s->dynamic_confidence.setTo(0.9f, s->instance_map > 0);
    s->source_grey = frame(seq);
    return std::shared_ptr<const Segmentation>(s);
  };
  MaskCarry carry;
  carry.Resolve(Fresh(0, segmentation_of(0)), frame(0));
  for (int seq = 1; seq <= 3; ++seq) {
    const MaskMsg r = carry.Resolve(NotRun(seq, SegmentationOutcome::kNotScheduled), frame(seq));
    ASSERT_EQ(r.status, MaskStatus::kPropagated);
    EXPECT_EQ(r.source_seq, 0);
    EXPECT_EQ(r.propagation_steps, seq);
    EXPECT_NEAR(r.segmentation->instances[0].box_px.x, 30 + 3 * seq, 0.6);
    EXPECT_EQ(cv::countNonZero(r.segmentation->instance_map(cv::Rect(30 + 3 * seq, 40, 40, 40))),
              1600);
  }
  // A late result of frame 2 is newer than frame 0's: it is carried from frame 2 (two steps).
  SegmentationMsg late = NotRun(4, SegmentationOutcome::kLate);
  late.fallback = segmentation_of(2);
  late.fallback_seq = 2;
  MaskMsg r = carry.Resolve(late, frame(4));
  EXPECT_EQ(r.status, MaskStatus::kPropagated);
  EXPECT_EQ(r.source_seq, 2);
  EXPECT_EQ(r.propagation_steps, 1);
  EXPECT_NEAR(r.segmentation->instances[0].box_px.x, 42, 0.6);
  // A level without propagation, or no image of the frame: the mask as it was, stale.
  SegmentationMsg off = NotRun(5, SegmentationOutcome::kNotScheduled);
  off.ticket.settings.propagate_masks = false;
  r = carry.Resolve(off, frame(5));
  EXPECT_EQ(r.status, MaskStatus::kStale);
  EXPECT_TRUE(r.segmentation->stale);
  EXPECT_EQ(carry.Resolve(NotRun(6, SegmentationOutcome::kBusy)).status, MaskStatus::kStale);
  // Too old (max_age_frames 5 from frame 2).
  EXPECT_EQ(carry.Resolve(NotRun(8, SegmentationOutcome::kBusy), frame(8)).status,
            MaskStatus::kSkipped);
}

// A stereo message with keypoints at given pixels (no descriptors needed by the filter) over the
// given left image (a blank 6 x 4 one when empty).
StereoPtr StereoWithKeypoints(int64_t seq, const std::vector<cv::Point2f>& points,
                              const cv::Mat& left_image = cv::Mat()) {
  auto images = std::make_shared<ImagesMsg>();
  images->ticket = Ticket(seq);
  images->left = left_image.empty() ? cv::Mat::zeros(4, 6, CV_8UC1) : left_image;
  images->right = images->left.clone();
  auto left = std::make_shared<FeaturesMsg>();
  left->ticket = images->ticket;
  left->images = images;
  for (const cv::Point2f& p : points) left->features.keypoints.emplace_back(p, 31.0f);
  auto stereo = std::make_shared<StereoMsg>();
  stereo->ticket = images->ticket;
  stereo->images = images;
  stereo->left = left;
  stereo->stereo.u_right_px.assign(points.size(), -1.0f);
  stereo->stereo.depth_m.assign(points.size(), -1.0f);
  return stereo;
}

TEST(MaskScorerTest, ExcludesConfidentPixelsAndWeightsTheRest) {
  auto s = std::make_shared<Segmentation>();
  s->dynamic_confidence = cv::Mat::zeros(4, 6, CV_32FC1);
  s->dynamic_confidence.at<float>(1, 2) = 0.9f;  // row 1, column 2
  s->dynamic_confidence.at<float>(3, 5) = 0.3f;
  const StereoPtr stereo =
      StereoWithKeypoints(0, {{2.2f, 0.8f}, {5.0f, 3.0f}, {0.0f, 0.0f}, {9.0f, -2.0f}});
  MaskMsg mask;
  mask.status = MaskStatus::kFresh;
  mask.segmentation = s;
  MaskScorer scorer;
  const ScoringInput input{stereo->ticket, *stereo->images, stereo->left->features, stereo->stereo,
                           mask};
  const KeypointFilter f = scorer.Score(input).filter;
  ASSERT_EQ(f.excluded.size(), 4u);
  ASSERT_EQ(f.weight.size(), 4u);
  EXPECT_EQ(f.excluded, (std::vector<uint8_t>{1, 0, 0, 0}));
  EXPECT_NEAR(f.weight[1], 0.7f, 1e-6);
  EXPECT_NEAR(f.weight[2], 1.0f, 1e-6);
  EXPECT_NEAR(f.weight[3], 1.0f, 1e-6);  // clamped to the image: pixel (5, 0)
  mask.status = MaskStatus::kSkipped;
  mask.segmentation = nullptr;
  const KeypointFilter none = scorer.Score(input).filter;
  EXPECT_TRUE(none.excluded.empty());
  EXPECT_TRUE(none.weight.empty());
}

// The pipeline's quality level reaches the dynamic filter: a frame whose settings switch the
// optical flow off is scored without LK (the low level), the same frame with it on tracks.
TEST(DynamicFilterScorerTest, TheTicketsOpticalFlowSettingSwitchesLkOff) {
  cv::Mat texture(400, 700, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 1.5);
  std::vector<cv::Point2f> points;
  for (int v = 40; v < 330; v += 25)
    for (int u = 40; u < 600; u += 25) points.emplace_back(static_cast<float>(u), v);
  StereoRig rig;
  rig.left = {500, 500, 320, 180, 640, 360};
  rig.baseline_m = 0.5;
  MaskMsg no_mask;
  for (const bool flow : {true, false}) {
    DynamicFilterScorer scorer(rig, 1.2);
    for (int64_t seq = 0; seq < 2; ++seq) {
      const int shift_px = 3 * static_cast<int>(seq);
      const StereoPtr s =
          StereoWithKeypoints(seq, points, texture(cv::Rect(20 + shift_px, 20, 640, 360)).clone());
      FrameTicket ticket = s->ticket;
      ticket.settings.optical_flow = flow || seq == 0;
      scorer.Score(ScoringInput{ticket, *s->images, s->left->features, s->stereo, no_mask});
    }
    if (flow)
      EXPECT_GT(scorer.last_tracked(), static_cast<int>(0.8 * points.size()));
    else
      EXPECT_EQ(scorer.last_tracked(), 0);
  }
}

class FixedScorer final : public FrameScorer {
 public:
  explicit FixedScorer(std::vector<uint8_t> excluded) : excluded_(std::move(excluded)) {}
  ScoredFrame Score(const ScoringInput& input) override {
    last_mask = input.mask.status;
    ScoredFrame f;
    f.filter.excluded = excluded_;
    return f;
  }
  std::string Name() const override { return "fixed"; }
  MaskStatus last_mask = MaskStatus::kSkipped;

 private:
  std::vector<uint8_t> excluded_;
};

TEST(FilterNodeTest, JoinsStereoAndMaskAndCountsExclusions) {
  FixedScorer scorer({1, 0, 1});
  FilterNode node(&scorer, MaskCarryOptions{});
  const auto seg = std::make_shared<const SegmentationMsg>(Fresh(0, MaskWithValue(0.2f)));
  const FilteredPtr out = node(StereoWithKeypoints(0, {{1, 1}, {2, 2}, {3, 3}}), seg);
  EXPECT_EQ(out->ticket.seq, 0);
  EXPECT_EQ(out->num_excluded, 2);
  EXPECT_EQ(out->mask.status, MaskStatus::kFresh);
  EXPECT_EQ(out->segmentation, SegmentationOutcome::kFresh);
  EXPECT_EQ(scorer.last_mask, MaskStatus::kFresh);
  const FilteredPtr next = node(StereoWithKeypoints(1, {{1, 1}, {2, 2}, {3, 3}}),
                                SegmentNode::NotRun(Ticket(1), SegmentationOutcome::kLate));
  EXPECT_EQ(next->mask.status, MaskStatus::kStale);
  EXPECT_EQ(next->mask.source_seq, 0);
}

TEST(FilterNodeTest, RejectsMismatchedInputs) {
  FixedScorer wrong_size({1, 0});
  FilterNode node(&wrong_size, MaskCarryOptions{});
  const auto seg = SegmentNode::NotRun(Ticket(0), SegmentationOutcome::kNoSegmenter);
  EXPECT_THROW(node(StereoWithKeypoints(0, {{1, 1}, {2, 2}, {3, 3}}), seg), std::invalid_argument);
  FilterNode plain(nullptr, MaskCarryOptions{});
  EXPECT_THROW(plain(StereoWithKeypoints(1, {{1, 1}}), seg), std::invalid_argument);
  const FilteredPtr out = plain(StereoWithKeypoints(0, {{1, 1}}), seg);
  EXPECT_TRUE(out->filter.excluded.empty());
  EXPECT_EQ(out->mask.status, MaskStatus::kSkipped);
}

// A segmenter answering with its name, counting calls.
class NamedSegmenter final : public Segmenter {
 public:
  explicit NamedSegmenter(std::string name) : name_(std::move(name)) {}
  Segmentation Segment(const cv::Mat& image) override {
    ++calls;
    Segmentation s;
    s.dynamic_confidence = cv::Mat::zeros(image.size(), CV_32FC1);
    s.instance_map = cv::Mat::zeros(image.size(), CV_16UC1);
    Instance car;
    car.class_name = "car";
    car.box_px = cv::Rect2f(1, 1, 2, 2);
    car.mask = cv::Mat::zeros(image.size(), CV_8UC1);
    car.mask(cv::Rect(1, 1, 2, 2)).setTo(255);
    s.instance_map(cv::Rect(1, 1, 2, 2)).setTo(1);
    s.instances.push_back(car);
    s.backend = name_;
    return s;
  }
  std::string Name() const override { return name_; }
  int calls = 0;

 private:
  std::string name_;
};

TEST(SegmentNodeTest, RunsTheSlotOfTheTicketOrSaysWhyNot) {
  NamedSegmenter accurate("accurate"), fast("fast");
  auto images = std::make_shared<ImagesMsg>();
  images->ticket = Ticket(0);
  images->left = cv::Mat::zeros(4, 6, CV_8UC1);

  SegmentNode none(SegmenterSet{});
  EXPECT_FALSE(none.WillRun(images->ticket));
  EXPECT_EQ(none(images)->outcome, SegmentationOutcome::kNoSegmenter);

  SegmentNode both(SegmenterSet{&accurate, &fast});
  images->ticket.settings.segmenter = SegmenterSlot::kAccurate;
  SegmentationPtr out = both(images);
  EXPECT_EQ(out->outcome, SegmentationOutcome::kFresh);
  EXPECT_EQ(out->model, "accurate");
  EXPECT_EQ(out->segmentation->dynamic_confidence.size(), images->left.size());
  // The instances travel without their full-image masks; the instance map still has them.
  ASSERT_EQ(out->segmentation->instances.size(), 1u);
  EXPECT_EQ(out->segmentation->instances[0].class_name, "car");
  EXPECT_TRUE(out->segmentation->instances[0].mask.empty());
  EXPECT_EQ(cv::countNonZero(out->segmentation->instance_map == 1), 4);
  images->ticket.settings.segmenter = SegmenterSlot::kFast;
  EXPECT_EQ(both(images)->model, "fast");
  images->ticket.run_inference = false;
  EXPECT_FALSE(both.WillRun(images->ticket));
  EXPECT_EQ(both(images)->outcome, SegmentationOutcome::kNotScheduled);
  EXPECT_EQ(accurate.calls + fast.calls, 2);

  SegmentNode fast_only(SegmenterSet{nullptr, &fast});
  images->ticket.run_inference = true;
  images->ticket.settings.segmenter = SegmenterSlot::kAccurate;  // falls back to the other slot
  EXPECT_EQ(fast_only(images)->model, "fast");
  // The fresh segmentation keeps the image it describes (for carrying it to later frames).
  EXPECT_EQ(fast_only(images)->segmentation->source_grey.data, images->left.data);
}

TEST(SegmentNodeTest, TheLightSlotFallsBackToTheNextCheaperNetworkFirst) {
  NamedSegmenter accurate("accurate"), fast("fast"), light("light");
  const auto model = [](const SegmenterSet& set, SegmenterSlot slot) {
    Segmenter* s = set.For(slot);
    return s ? s->Name() : std::string("none");
  };
  const SegmenterSet all{&accurate, &fast, &light};
  EXPECT_EQ(model(all, SegmenterSlot::kLight), "light");
  EXPECT_EQ(model(all, SegmenterSlot::kFast), "fast");
  EXPECT_EQ(model(all, SegmenterSlot::kAccurate), "accurate");
  const SegmenterSet no_light{&accurate, &fast, nullptr};
  EXPECT_EQ(model(no_light, SegmenterSlot::kLight), "fast");
  const SegmenterSet light_only{nullptr, nullptr, &light};
  EXPECT_FALSE(light_only.empty());
  EXPECT_EQ(model(light_only, SegmenterSlot::kAccurate), "light");
  const SegmenterSet accurate_and_light{&accurate, nullptr, &light};
  EXPECT_EQ(model(accurate_and_light, SegmenterSlot::kFast), "light");  // cheaper first
  EXPECT_EQ(model(SegmenterSet{}, SegmenterSlot::kLight), "none");
}

}  // namespace
}  // namespace pcr::nodes
