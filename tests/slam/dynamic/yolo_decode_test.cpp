// YOLOv8 output decoding on synthetic tensors: layout checks, NMS, prototype masks, the
// detection-only fallback, instance and dynamic-confidence maps, the ONNX input-shape reader.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "slam/common/error.h"
#include "slam/dynamic/mask_utils.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "support/onnx_writer.h"

namespace pcr {
namespace {

float Sigmoid(float z) { return 1.0f / (1.0f + std::exp(-z)); }

int CountNonZero(const cv::Mat& m, const cv::Rect& r) { return cv::countNonZero(m(r)); }

// ---- Layout ----

TEST(YoloLayout, AcceptsSegmentationAndDetectionOnlyShapes) {
  const YoloOutputLayout seg =
      InspectYoloOutputs({{1, 32, 96, 320}, {1, 116, 10080}}, 80, "model.onnx");
  EXPECT_EQ(seg.detection_output, 1);
  EXPECT_EQ(seg.prototype_output, 0);
  EXPECT_EQ(seg.num_classes, 80);
  EXPECT_EQ(seg.num_mask_coeffs, 32);
  EXPECT_EQ(seg.num_anchors, 10080);
  EXPECT_EQ(seg.proto_size, cv::Size(320, 96));
  EXPECT_TRUE(seg.has_prototypes());

  const YoloOutputLayout det = InspectYoloOutputs({{1, 84, 2100}}, 80, "det.onnx");
  EXPECT_FALSE(det.has_prototypes());
  EXPECT_EQ(det.num_classes, 80);
  EXPECT_EQ(det.prototype_output, -1);
}

void ExpectLayoutError(const std::vector<std::vector<int>>& shapes, const std::string& shape_text) {
  try {
    InspectYoloOutputs(shapes, 80, "/models/bad.onnx");
    ADD_FAILURE() << "no error for " << shape_text;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), "/models/bad.onnx");
    EXPECT_NE(what.find("/models/bad.onnx"), std::string::npos) << what;
    EXPECT_NE(what.find(shape_text), std::string::npos) << what;
  }
}

TEST(YoloLayout, OtherLayoutsAreInputErrorsNamingTheShape) {
  ExpectLayoutError({{1, 100, 8400}, {1, 32, 160, 160}}, "1x100x8400");  // wrong channel count
  ExpectLayoutError({{1, 116, 8400}}, "1x116x8400");  // seg channels but no prototypes
  ExpectLayoutError({{1, 8400, 116}, {1, 32, 160, 160}}, "1x8400x116");  // transposed
  ExpectLayoutError({{2, 116, 8400}, {1, 32, 160, 160}}, "2x116x8400");  // batch
  ExpectLayoutError({{1, 32, 160, 160}}, "1x32x160x160");                // no detections
  ExpectLayoutError({{1, 116, 8400}, {1, 32, 160, 160}, {1, 3}}, "1x3");
  ExpectLayoutError({{1, 116, 8400, 1}, {1, 32, 160, 160}}, "1x116x8400x1");
}

// ---- NMS ----

TEST(YoloNms, IouOfHandMadeBoxes) {
  EXPECT_FLOAT_EQ(BoxIou({0, 0, 10, 10}, {0, 0, 10, 10}), 1.0f);
  EXPECT_FLOAT_EQ(BoxIou({0, 0, 10, 10}, {5, 0, 10, 10}), 50.0f / 150.0f);
  EXPECT_FLOAT_EQ(BoxIou({0, 0, 10, 10}, {1, 1, 10, 10}), 81.0f / 119.0f);
  EXPECT_FLOAT_EQ(BoxIou({0, 0, 10, 10}, {10, 0, 10, 10}), 0.0f);  // touching
  EXPECT_FLOAT_EQ(BoxIou({0, 0, 0, 0}, {0, 0, 0, 0}), 0.0f);
}

TEST(YoloNms, ClassAwareAndAgnosticOnHandMadeBoxes) {
  const std::vector<cv::Rect2f> boxes = {
      {0, 0, 10, 10},    // 0: best
      {1, 1, 10, 10},    // 1: IoU 0.68 with 0, same class -> dropped
      {1, 1, 10, 10},    // 2: same place, other class -> kept unless agnostic
      {20, 20, 5, 5},    // 3: apart -> kept
      {5, 0, 10, 10},    // 4: IoU 0.33 with 0 -> kept
      {20.5, 20, 5, 5},  // 5: IoU 0.82 with 3 -> dropped
  };
  const std::vector<float> scores = {0.9f, 0.8f, 0.7f, 0.6f, 0.5f, 0.4f};
  const std::vector<int> classes = {0, 0, 1, 0, 0, 0};
  EXPECT_EQ(NonMaxSuppression(boxes, scores, classes, 0.45f, false, 100),
            (std::vector<int>{0, 2, 3, 4}));
  EXPECT_EQ(NonMaxSuppression(boxes, scores, classes, 0.45f, true, 100),
            (std::vector<int>{0, 3, 4}));
  EXPECT_EQ(NonMaxSuppression(boxes, scores, classes, 0.45f, false, 2), (std::vector<int>{0, 2}));
  // A looser threshold keeps box 1 (0.68 < 0.7) and a tighter one drops box 4 (0.33 > 0.3).
  EXPECT_EQ(NonMaxSuppression(boxes, scores, classes, 0.7f, false, 100),
            (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(NonMaxSuppression(boxes, scores, classes, 0.3f, false, 100),
            (std::vector<int>{0, 2, 3}));
  // Order follows the score, not the input order: with reversed scores box 3 falls to box 5,
  // box 1 survives box 4 (IoU 54/146 = 0.37) and box 0 falls to box 1.
  const std::vector<float> reversed = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f};
  EXPECT_EQ(NonMaxSuppression(boxes, reversed, classes, 0.45f, false, 100),
            (std::vector<int>{5, 4, 2, 1}));
  EXPECT_THROW(NonMaxSuppression(boxes, scores, {0}, 0.45f, false, 100), std::invalid_argument);
}

// ---- Prototype masks ----

TEST(YoloMasks, ProbabilitiesAreTheSigmoidOfTheCoefficientDotProduct) {
  const cv::Size proto_size(5, 4);
  cv::Mat protos(2, proto_size.area(), CV_32F);
  for (int i = 0; i < proto_size.area(); ++i) {
    protos.at<float>(0, i) = 0.1f * i - 1.0f;
    protos.at<float>(1, i) = std::sin(0.7f * i);
  }
  const float coeffs[2] = {1.5f, -2.0f};
  const cv::Rect roi(1, 1, 3, 2);
  const cv::Mat prob = MaskProbabilities(coeffs, protos, proto_size, roi);
  ASSERT_EQ(prob.size(), roi.size());
  for (int y = 0; y < roi.height; ++y) {
    for (int x = 0; x < roi.width; ++x) {
      const int i = (roi.y + y) * proto_size.width + roi.x + x;
      const float z = 1.5f * protos.at<float>(0, i) - 2.0f * protos.at<float>(1, i);
      EXPECT_NEAR(prob.at<float>(y, x), Sigmoid(z), 1e-6f);
    }
  }
  EXPECT_THROW(MaskProbabilities(coeffs, protos, proto_size, {3, 0, 3, 1}), std::invalid_argument);
}

// A 128x64 image letterboxed into a 64x64 input (gain 0.5, 16 rows of padding on top), a 16x16
// prototype grid (4 input px per cell), classes {car, person, tree}, 2 mask coefficients.
struct SyntheticOutputs {
  static constexpr int kClasses = 3;
  static constexpr int kCoeffs = 2;
  static constexpr int kAnchors = 5;
  cv::Mat detections;  // 1 x 9 x 5
  cv::Mat prototypes;  // 1 x 2 x 16 x 16
  std::vector<std::string> names = {"car", "person", "tree"};
  LetterboxInfo letterbox = ComputeLetterbox({128, 64}, {64, 64});

  explicit SyntheticOutputs(bool with_prototypes) {
    const int channels = 4 + kClasses + (with_prototypes ? kCoeffs : 0);
    const int det_shape[] = {1, channels, kAnchors};
    detections = cv::Mat(3, det_shape, CV_32F, cv::Scalar(0));
    // anchor: cx, cy, w, h (input px), class, score, coefficients
    Set(0, {24, 32, 32, 16}, 0, 0.9f, {1, 0});  // car, left half of its box (see protos)
    Set(1, {25, 32, 32, 16}, 0, 0.5f, {1, 0});  // duplicate car, suppressed
    Set(2, {52, 28, 8, 8}, 1, 0.6f, {0, 1});    // person, full box
    Set(3, {40, 40, 8, 8}, 2, 0.1f, {0, 1});    // tree below the threshold
    Set(4, {32, 6, 16, 8}, 2, 0.95f, {0, 1});   // tree entirely in the top padding
    const int proto_shape[] = {1, kCoeffs, 16, 16};
    prototypes = cv::Mat(4, proto_shape, CV_32F, cv::Scalar(0));
    for (int y = 0; y < 16; ++y) {
      for (int x = 0; x < 16; ++x) {
        // Plane 0: positive left of input x = 24 (cells 0..5), negative right of it.
        prototypes.ptr<float>(0, 0)[y * 16 + x] = x < 6 ? 8.0f : -8.0f;
        prototypes.ptr<float>(0, 1)[y * 16 + x] = 8.0f;
      }
    }
    (void)with_prototypes;
  }

  void Set(int anchor, cv::Vec4f box, int cls, float score, cv::Vec2f coeffs) {
    const int channels = detections.size[1];
    const int n = detections.size[2];
    float* d = detections.ptr<float>();
    for (int k = 0; k < 4; ++k) d[k * n + anchor] = box[k];
    for (int c = 0; c < kClasses; ++c) d[(4 + c) * n + anchor] = c == cls ? score : 0.01f;
    if (channels == 4 + kClasses + kCoeffs) {
      for (int m = 0; m < kCoeffs; ++m) d[(4 + kClasses + m) * n + anchor] = coeffs[m];
    }
  }
};

TEST(YoloDecode, SyntheticSegmentationOutputsGiveKnownInstancesAndMasks) {
  const SyntheticOutputs s(true);
  ASSERT_EQ(s.letterbox.pad_top_px, 16);
  const YoloOutputLayout layout =
      InspectYoloOutputs({ShapeOf(s.detections), ShapeOf(s.prototypes)}, 3, "synthetic.onnx");
  ASSERT_TRUE(layout.has_prototypes());

  const std::vector<YoloCandidate> candidates = DecodeYoloCandidates(s.detections, layout, 0.25f);
  ASSERT_EQ(candidates.size(), 4u);  // all but the tree below the threshold
  EXPECT_EQ(candidates[0].anchor, 0);
  EXPECT_FLOAT_EQ(candidates[0].box_input_px.x, 8.0f);
  EXPECT_FLOAT_EQ(candidates[0].box_input_px.y, 24.0f);
  EXPECT_FLOAT_EQ(candidates[0].box_input_px.width, 32.0f);

  YoloDecodeParams params;
  const std::vector<Instance> instances =
      DecodeYoloOutputs(s.detections, s.prototypes, layout, s.letterbox, s.names, params);
  ASSERT_EQ(instances.size(), 2u);
  const Instance& car = instances[0];
  const Instance& person = instances[1];
  EXPECT_EQ(car.class_name, "car");
  EXPECT_EQ(car.class_id, 0);
  EXPECT_EQ(car.instance_id, 0);
  EXPECT_FLOAT_EQ(car.confidence, 0.9f);
  // Input [8, 40] x [24, 40] -> image [16, 80] x [16, 48].
  EXPECT_NEAR(car.box_px.x, 16.0f, 1e-4f);
  EXPECT_NEAR(car.box_px.y, 16.0f, 1e-4f);
  EXPECT_NEAR(car.box_px.width, 64.0f, 1e-4f);
  EXPECT_NEAR(car.box_px.height, 32.0f, 1e-4f);
  // Mask: the part of the box left of input x = 24, i.e. image x = 48.
  ASSERT_EQ(car.mask.size(), cv::Size(128, 64));
  ASSERT_EQ(car.mask.type(), CV_8U);
  EXPECT_EQ(cv::countNonZero(car.mask), 32 * 32);
  EXPECT_EQ(CountNonZero(car.mask, cv::Rect(16, 16, 32, 32)), 32 * 32);
  double max_value = 0;
  cv::minMaxLoc(car.mask, nullptr, &max_value);
  EXPECT_EQ(max_value, 255.0);

  EXPECT_EQ(person.class_name, "person");
  EXPECT_EQ(person.instance_id, 1);
  // Input [48, 56] x [24, 32] -> image [96, 112] x [16, 32], mask = whole box.
  EXPECT_NEAR(person.box_px.x, 96.0f, 1e-4f);
  EXPECT_NEAR(person.box_px.y, 16.0f, 1e-4f);
  EXPECT_EQ(cv::countNonZero(person.mask), 16 * 16);
  EXPECT_EQ(CountNonZero(person.mask, cv::Rect(96, 16, 16, 16)), 16 * 16);

  // A box in the padding takes no slot of max_detections (the tree scores highest).
  YoloDecodeParams two = params;
  two.max_detections = 2;
  const std::vector<Instance> capped =
      DecodeYoloOutputs(s.detections, s.prototypes, layout, s.letterbox, s.names, two);
  ASSERT_EQ(capped.size(), 2u);
  EXPECT_EQ(capped[0].class_name, "car");
  EXPECT_EQ(capped[1].class_name, "person");

  // A higher threshold changes what survives: only the car (0.9) passes 0.7.
  YoloDecodeParams high = params;
  high.conf_threshold = 0.7f;
  const std::vector<Instance> confident =
      DecodeYoloOutputs(s.detections, s.prototypes, layout, s.letterbox, s.names, high);
  ASSERT_EQ(confident.size(), 1u);
  EXPECT_EQ(confident[0].class_name, "car");

  // So does class-agnostic NMS: the duplicate of the car's box, made a person, survives the
  // class-aware NMS (other class) and falls to the car under the class-agnostic one.
  SyntheticOutputs other(true);
  other.Set(1, {25, 32, 32, 16}, 1, 0.5f, {0, 1});
  const std::vector<Instance> aware = DecodeYoloOutputs(other.detections, other.prototypes, layout,
                                                        other.letterbox, other.names, params);
  ASSERT_EQ(aware.size(), 3u);
  EXPECT_EQ(aware[0].class_name, "car");
  EXPECT_EQ(aware[1].class_name, "person");
  EXPECT_FLOAT_EQ(aware[1].confidence, 0.6f);  // the real person first ...
  EXPECT_EQ(aware[2].class_name, "person");
  EXPECT_FLOAT_EQ(aware[2].confidence, 0.5f);  // ... then the duplicate
  EXPECT_NEAR(aware[2].box_px.x, 18.0f, 1e-4f);
  YoloDecodeParams agnostic = params;
  agnostic.class_agnostic_nms = true;
  const std::vector<Instance> merged = DecodeYoloOutputs(other.detections, other.prototypes, layout,
                                                         other.letterbox, other.names, agnostic);
  ASSERT_EQ(merged.size(), 2u);
  EXPECT_EQ(merged[0].class_name, "car");
  EXPECT_EQ(merged[1].class_name, "person");
  EXPECT_FLOAT_EQ(merged[1].confidence, 0.6f);
}

// The same outputs with the frame cut at the top to fill the input's width: a 128x192 frame into
// the 64x64 input at gain 0.5 keeps its lowest 128 rows (64 cut), so input y maps to image
// 2 y + 64 and nothing lands in the cut rows.
TEST(YoloDecode, CroppedTopShiftsBoxesAndMasksBelowTheCut) {
  SyntheticOutputs s(true);
  s.letterbox = ComputeLetterbox({128, 192}, {64, 64}, /*crop_top_to_fill_width=*/true);
  ASSERT_EQ(s.letterbox.crop_top_px, 64);
  ASSERT_EQ(s.letterbox.pad_top_px, 0);
  const YoloOutputLayout layout =
      InspectYoloOutputs({ShapeOf(s.detections), ShapeOf(s.prototypes)}, 3, "synthetic.onnx");
  const std::vector<Instance> instances =
      DecodeYoloOutputs(s.detections, s.prototypes, layout, s.letterbox, s.names, {});
  // No padding now: the tree at input y 2..10 is in the frame (image rows 68..84).
  ASSERT_EQ(instances.size(), 3u);
  const Instance& tree = instances[0];
  const Instance& car = instances[1];
  const Instance& person = instances[2];
  EXPECT_EQ(tree.class_name, "tree");
  EXPECT_NEAR(tree.box_px.y, 68.0f, 1e-4f);
  // Car: input [8, 40] x [24, 40] -> image [16, 80] x [112, 144]; mask left of image x = 48.
  EXPECT_EQ(car.class_name, "car");
  EXPECT_NEAR(car.box_px.x, 16.0f, 1e-4f);
  EXPECT_NEAR(car.box_px.y, 112.0f, 1e-4f);
  EXPECT_NEAR(car.box_px.height, 32.0f, 1e-4f);
  ASSERT_EQ(car.mask.size(), cv::Size(128, 192));
  EXPECT_EQ(cv::countNonZero(car.mask), 32 * 32);
  EXPECT_EQ(CountNonZero(car.mask, cv::Rect(16, 112, 32, 32)), 32 * 32);
  // Person: input [48, 56] x [24, 32] -> image [96, 112] x [112, 128], the whole box.
  EXPECT_EQ(CountNonZero(person.mask, cv::Rect(96, 112, 16, 16)), 16 * 16);
  EXPECT_EQ(cv::countNonZero(person.mask), 16 * 16);
  for (const Instance& inst : instances) EXPECT_EQ(CountNonZero(inst.mask, {0, 0, 128, 64}), 0);
}

TEST(YoloDecode, DetectionOnlyOutputsFallBackToBoxMasks) {
  const SyntheticOutputs s(false);
  const YoloOutputLayout layout =
      InspectYoloOutputs({ShapeOf(s.detections)}, 3, "detection_only.onnx");
  ASSERT_FALSE(layout.has_prototypes());
  const std::vector<Instance> instances =
      DecodeYoloOutputs(s.detections, cv::Mat(), layout, s.letterbox, s.names, {});
  ASSERT_EQ(instances.size(), 2u);
  EXPECT_EQ(instances[0].class_name, "car");
  EXPECT_EQ(cv::countNonZero(instances[0].mask), 64 * 32);  // the whole box
  EXPECT_EQ(CountNonZero(instances[0].mask, cv::Rect(16, 16, 64, 32)), 64 * 32);
  EXPECT_EQ(cv::countNonZero(instances[1].mask), 16 * 16);
}

TEST(YoloDecode, TensorsThatDoNotMatchTheLayoutAreRejected) {
  const SyntheticOutputs s(true);
  const YoloOutputLayout layout =
      InspectYoloOutputs({ShapeOf(s.detections), ShapeOf(s.prototypes)}, 3, "synthetic.onnx");
  const int other_shape[] = {1, 2, 8, 8};
  const cv::Mat other_protos(4, other_shape, CV_32F, cv::Scalar(0));
  EXPECT_THROW(DecodeYoloOutputs(s.detections, other_protos, layout, s.letterbox, s.names, {}),
               std::invalid_argument);
  EXPECT_THROW(DecodeYoloOutputs(s.detections, cv::Mat(), layout, s.letterbox, s.names, {}),
               std::invalid_argument);
  const SyntheticOutputs no_coeffs(false);
  EXPECT_THROW(
      DecodeYoloOutputs(no_coeffs.detections, s.prototypes, layout, s.letterbox, s.names, {}),
      std::invalid_argument);
  EXPECT_THROW(DecodeYoloOutputs(s.detections, s.prototypes, layout, s.letterbox, {"car"}, {}),
               std::invalid_argument);
}

// ---- Maps ----

Instance SquareInstance(const std::string& name, float confidence, cv::Rect square, cv::Size size) {
  Instance inst;
  inst.class_name = name;
  inst.confidence = confidence;
  inst.box_px = cv::Rect2f(square);
  inst.mask = BoxMask(size, inst.box_px);
  return inst;
}

TEST(YoloMaps, InstanceMapGivesOverlapsToTheMoreConfident) {
  const cv::Size size(50, 40);
  std::vector<Instance> instances = {SquareInstance("car", 0.5f, {0, 0, 20, 20}, size),
                                     SquareInstance("car", 0.9f, {10, 10, 20, 20}, size)};
  const cv::Mat map = BuildInstanceMap(instances, size);
  ASSERT_EQ(map.type(), CV_16U);
  EXPECT_EQ(map.at<uint16_t>(5, 5), 1);
  EXPECT_EQ(map.at<uint16_t>(15, 15), 2);  // overlap: the 0.9 instance
  EXPECT_EQ(map.at<uint16_t>(25, 25), 2);
  EXPECT_EQ(map.at<uint16_t>(35, 45), 0);
}

TEST(YoloMaps, DynamicConfidenceFollowsThePolicies) {
  const cv::Size size(200, 100);
  DynamicClassPolicy policy;  // car aggressive (x1.4, x1.0), person conservative (x0.6, x0.8)
  const std::vector<Instance> instances = {
      SquareInstance("car", 0.9f, {40, 40, 20, 20}, size),
      SquareInstance("person", 0.9f, {140, 40, 20, 20}, size),
      SquareInstance("traffic light", 0.99f, {100, 5, 10, 10}, size)};  // static class

  const cv::Mat sharp = DynamicConfidenceMap(instances, size, policy, 5, 0.0);
  ASSERT_EQ(sharp.type(), CV_32F);
  ASSERT_EQ(sharp.size(), size);
  EXPECT_FLOAT_EQ(sharp.at<float>(50, 50), 0.9f);
  EXPECT_FLOAT_EQ(sharp.at<float>(50, 40 - 7), 0.9f);  // car dilated by round(5 * 1.4) = 7
  EXPECT_FLOAT_EQ(sharp.at<float>(50, 40 - 8), 0.0f);
  EXPECT_FLOAT_EQ(sharp.at<float>(50, 150), 0.72f);      // person scaled by 0.8
  EXPECT_FLOAT_EQ(sharp.at<float>(50, 140 - 3), 0.72f);  // dilated by 3
  EXPECT_FLOAT_EQ(sharp.at<float>(50, 140 - 4), 0.0f);
  EXPECT_FLOAT_EQ(sharp.at<float>(10, 105), 0.0f);  // static class ignored

  const cv::Mat smooth = DynamicConfidenceMap(instances, size, policy, 5, 2.0);
  double lo = 0, hi = 0;
  cv::minMaxLoc(smooth, &lo, &hi);
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 1.0);
  EXPECT_NEAR(smooth.at<float>(50, 50), 0.9f, 1e-4f);
  EXPECT_LT(smooth.at<float>(50, 40 - 8), 0.9f * 0.5f);  // blurred edge
  EXPECT_GT(smooth.at<float>(50, 40 - 8), 0.0f);
  EXPECT_EQ(smooth.at<float>(50, 10), 0.0f);  // far away
  EXPECT_EQ(smooth.at<float>(90, 100), 0.0f);
  for (int x = 20; x < 40; ++x) {  // rises monotonically towards the car
    EXPECT_LE(smooth.at<float>(50, x), smooth.at<float>(50, x + 1) + 1e-6f);
  }

  // A custom policy: cars no longer dynamic.
  DynamicClassPolicy people_only;
  people_only.classes = {{"person", DynamicPolicy::kConservative}};
  const cv::Mat people = DynamicConfidenceMap(instances, size, people_only, 5, 0.0);
  EXPECT_EQ(people.at<float>(50, 50), 0.0f);
  EXPECT_FLOAT_EQ(people.at<float>(50, 150), 0.72f);
}

TEST(YoloMaps, ImageBorderKeepsConfidenceUnderSmoothing) {
  const cv::Size size(60, 40);
  const std::vector<Instance> instances = {SquareInstance("car", 1.0f, {0, 0, 30, 40}, size)};
  const cv::Mat map = DynamicConfidenceMap(instances, size, DynamicClassPolicy(), 5, 2.0);
  EXPECT_NEAR(map.at<float>(20, 0), 1.0f, 1e-5f);
  EXPECT_NEAR(map.at<float>(0, 0), 1.0f, 1e-5f);
}

// ---- Options ----

TEST(YoloOptions, ValidationCatchesBadValues) {
  YoloOptions options;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));  // no model
  EXPECT_NE(why.find("model_path"), std::string::npos);
  options.model_path = "m.onnx";
  EXPECT_TRUE(options.IsValid(&why)) << why;
  YoloOptions bad = options;
  bad.conf_threshold = 1.5f;
  EXPECT_FALSE(bad.IsValid(&why));
  bad = options;
  bad.dynamic_input_size = {100, 64};
  EXPECT_FALSE(bad.IsValid(&why));
  bad = options;
  bad.classes.classes.push_back({"car", DynamicPolicy::kConservative});
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("duplicate"), std::string::npos) << why;
  bad = options;
  bad.classes.conservative.confidence_scale = 0.0f;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_THROW(YoloSegmenter{bad}, ConfigError);

  const DynamicClassPolicy policy;
  ASSERT_NE(policy.Find("person"), nullptr);
  EXPECT_EQ(policy.Find("person")->policy, DynamicPolicy::kConservative);
  EXPECT_EQ(policy.Find("truck")->policy, DynamicPolicy::kAggressive);
  EXPECT_NE(policy.Find("giraffe"), nullptr);
  EXPECT_EQ(policy.Find("traffic light"), nullptr);
  EXPECT_EQ(policy.classes.size(), 17u);
  EXPECT_EQ(CocoClassNames().size(), 80u);
  EXPECT_EQ(CocoClassNames()[2], "car");
  EXPECT_EQ(CocoClassNames()[23], "giraffe");
}

// ---- ONNX input shape reader ----

using test::BytesField;
using test::Cat;
using test::Str;
using test::ValueInfo;
using test::VarintField;

TEST(YoloOnnx, InputShapeSkipsInitializersAndMarksSymbolicDims) {
  const auto initializer = Cat({VarintField(1, 3), BytesField(8, Str("w")), BytesField(9, {1, 2})});
  const auto graph = Cat({BytesField(1, Str("node-bytes")), BytesField(5, initializer),
                          BytesField(11, ValueInfo("w", {3})),
                          BytesField(11, ValueInfo("images", {1, 3, -1, 640}))});
  const auto model = Cat({VarintField(1, 8), BytesField(2, Str("pytorch")), BytesField(7, graph)});
  EXPECT_EQ(OnnxGraphInputShape(model), (std::vector<int64_t>{1, 3, -1, 640}));
}

TEST(YoloOnnx, NonOnnxBytesAreRejected) {
  const std::string text = "# a markdown file\nnot a model\n";
  EXPECT_THROW(OnnxGraphInputShape(Str(text)), std::invalid_argument);
  EXPECT_THROW(OnnxGraphInputShape(VarintField(1, 8)), std::invalid_argument);  // no graph
  const auto model = Cat({VarintField(1, 8), BytesField(7, BytesField(1, Str("n")))});
  EXPECT_THROW(OnnxGraphInputShape(model), std::invalid_argument);  // graph without input
  std::vector<uint8_t> truncated = Cat({VarintField(1, 8), BytesField(7, Str("0123456789"))});
  truncated.resize(truncated.size() - 3);
  EXPECT_THROW(OnnxGraphInputShape(truncated), std::invalid_argument);
}

}  // namespace
}  // namespace pcr
