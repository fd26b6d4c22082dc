// Masks carried from the image they describe to later images by their objects' motion: a
// synthetic scene with known motions (an object with texture of its own, a textureless one that
// moves with its surroundings, one that grows as it approaches), and real KITTI frames of drive
// 0005 where a YOLO mask carried three frames is compared with the network's own mask there.
#include "slam/dynamic/mask_propagation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "slam/dynamic/mask_utils.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

// Pixels of a map (or a dynamic-confidence map) that are set, as a CV_8U mask.
cv::Mat Set(const cv::Mat& map, double at_least) {
  cv::Mat out;
  cv::compare(map, at_least, out, cv::CMP_GE);
  return out;
}

double Iou(const cv::Mat& a, const cv::Mat& b) {
  const int inter = cv::countNonZero(a & b);
  const int uni = cv::countNonZero(a | b);
  return uni == 0 ? 1.0 : static_cast<double>(inter) / uni;
}

// Texture at several scales (as real images have: LK's coarse levels need some too).
cv::Mat Noise(cv::Size size, int seed) {
  cv::RNG rng(seed);
  cv::Mat sum(size, CV_32F, cv::Scalar(0));
  for (int cell : {4, 12, 32}) {
    cv::Mat small(size.height / cell + 2, size.width / cell + 2, CV_32F);
    rng.fill(small, cv::RNG::UNIFORM, 0, 85);
    cv::Mat up;
    cv::resize(small, up, cv::Size(), cell, cell, cv::INTER_LINEAR);
    sum += up(cv::Rect(cv::Point(), size));
  }
  cv::Mat out;
  sum.convertTo(out, CV_8U);
  cv::GaussianBlur(out, out, cv::Size(0, 0), 1.0);
  return out;
}

// A scene: textured background shifted by `ego`, a textured object at `car` (its own texture),
// a flat grey object at `flat` (no texture of its own).
cv::Mat Render(cv::Point ego, const cv::Rect& car, double car_scale, const cv::Rect& flat) {
  const cv::Size size(480, 240);
  static const cv::Mat background = Noise(cv::Size(600, 360), 1);
  static const cv::Mat car_texture = Noise(cv::Size(200, 200), 2);
  cv::Mat image = background(cv::Rect(cv::Point(60, 60) - ego, size)).clone();
  cv::Mat scaled;
  cv::resize(car_texture, scaled, cv::Size(), car_scale, car_scale, cv::INTER_LINEAR);
  scaled(cv::Rect(0, 0, car.width, car.height)).copyTo(image(car));
  image(flat).setTo(128);
  return image;
}

Segmentation TwoInstances(const cv::Rect& car, const cv::Rect& flat, cv::Size size) {
  Segmentation seg;
  for (const auto& [rect, name] : {std::pair{car, "car"}, std::pair{flat, "truck"}}) {
    Instance inst;
    inst.class_name = name;
    inst.confidence = 0.9f;
    inst.box_px = cv::Rect2f(rect);
    inst.mask = BoxMask(size, inst.box_px);
    inst.instance_id = static_cast<int>(seg.instances.size());
    seg.instances.push_back(inst);
  }
  seg.instance_map = BuildInstanceMap(seg.instances, size);
  seg.dynamic_confidence = cv::Mat(size, CV_32F, cv::Scalar(0));
  seg.dynamic_confidence.setTo(0.9f, seg.instance_map > 0);
  return seg;
}

TEST(MaskPropagation, EachObjectFollowsItsOwnMotionOrItsSurroundings) {
  const cv::Rect car0(100, 80, 80, 60), flat0(300, 90, 50, 40);
  const cv::Point ego(-4, 1);                     // the background moves by this
  const cv::Rect car1 = car0 + cv::Point(12, 3);  // the car by this
  const cv::Rect flat1 = flat0 + ego;             // the flat object with the background
  const cv::Mat prev = Render({0, 0}, car0, 1.0, flat0);
  const cv::Mat cur = Render(ego, car1, 1.0, flat1);
  const Segmentation seg = TwoInstances(car0, flat0, prev.size());

  PropagationReport report;
  const Segmentation moved = PropagateSegmentation(seg, prev, cur, {}, &report);
  ASSERT_EQ(report.moves.size(), 2u);
  for (const InstanceMove& m : report.moves)
    std::printf("move %s: %d tracks, (%.2f, %.2f) -> (%.2f, %.2f) x %.3f\n", ToString(m.source),
                m.tracks, m.centre_from.x, m.centre_from.y, m.centre_to.x, m.centre_to.y, m.scale);
  std::printf("box %.2f %.2f %.2f %.2f\n", moved.instances[0].box_px.x, moved.instances[0].box_px.y,
              moved.instances[0].box_px.width, moved.instances[0].box_px.height);
  EXPECT_EQ(report.moves[0].source, InstanceMoveSource::kOwnTracks);
  EXPECT_EQ(report.moves[1].source, InstanceMoveSource::kSurroundings);
  EXPECT_EQ(report.own, 1);
  EXPECT_EQ(report.surroundings, 1);
  EXPECT_NEAR(report.moves[0].scale, 1.0, 0.03);

  cv::Mat truth_car(prev.size(), CV_8U, cv::Scalar(0)), truth_flat = truth_car.clone();
  truth_car(car1).setTo(255);
  truth_flat(flat1).setTo(255);
  const double car_iou = Iou(moved.instance_map == 1, truth_car);
  const double flat_iou = Iou(moved.instance_map == 2, truth_flat);
  const double car_unmoved = Iou(seg.instance_map == 1, truth_car);
  std::printf("car IoU %.3f (unmoved %.3f), flat object IoU %.3f\n", car_iou, car_unmoved,
              flat_iou);
  EXPECT_GT(car_iou, 0.95);
  EXPECT_GT(flat_iou, 0.95);
  EXPECT_LT(car_unmoved, 0.75);
  // Boxes, ids and the confidence map moved too; the confidence is decayed once.
  EXPECT_NEAR(moved.instances[0].box_px.x, car1.x, 1.0);
  EXPECT_NEAR(moved.instances[0].box_px.y, car1.y, 1.0);
  EXPECT_EQ(moved.instances[1].instance_id, 1);
  EXPECT_TRUE(moved.instances[0].mask.empty());
  EXPECT_GT(Iou(Set(moved.dynamic_confidence, 0.5), truth_car | truth_flat), 0.9);
  double max_conf = 0;
  cv::minMaxLoc(moved.dynamic_confidence, nullptr, &max_conf);
  EXPECT_NEAR(max_conf, 0.9 * 0.9, 1e-5);
  EXPECT_FALSE(moved.stale);
  EXPECT_EQ(moved.source_grey.data, cur.data);
}

TEST(MaskPropagation, AnApproachingObjectGrowsAndAnUntrackableOneStays) {
  const cv::Rect car0(150, 70, 80, 60);
  const cv::Rect car1(146, 67, 88, 66);  // 1.1x about its centre
  const cv::Mat prev = Render({0, 0}, car0, 1.0, cv::Rect(400, 10, 10, 10));
  const cv::Mat cur = Render({0, 0}, car1, 1.1, cv::Rect(400, 10, 10, 10));
  const Segmentation seg = TwoInstances(car0, cv::Rect(400, 10, 10, 10), prev.size());
  PropagationReport report;
  const Segmentation moved = PropagateSegmentation(seg, prev, cur, {}, &report);
  ASSERT_EQ(report.moves.size(), 2u);
  EXPECT_EQ(report.moves[0].source, InstanceMoveSource::kOwnTracks);
  EXPECT_NEAR(report.moves[0].scale, 1.1, 0.03);
  EXPECT_EQ(report.moves[1].source, InstanceMoveSource::kSurroundings);
  cv::Mat truth(prev.size(), CV_8U, cv::Scalar(0));
  truth(car1).setTo(255);
  EXPECT_GT(Iou(moved.instance_map == 1, truth), 0.9);
  // The flat 10x10 patch in a flat corner... its ring has the background's texture: it stays put
  // (the background did not move), on exactly the pixels it had.
  EXPECT_EQ(cv::countNonZero(moved.instance_map == 2), 100);
  EXPECT_EQ(cv::countNonZero((moved.instance_map == 2) ^ (seg.instance_map == 2)), 0);

  // Nothing to track anywhere: every instance stays where it was.
  const cv::Mat flat_image(prev.size(), CV_8U, cv::Scalar(90));
  const Segmentation same = PropagateSegmentation(seg, flat_image, flat_image, {}, &report);
  EXPECT_EQ(report.unmoved, 2);
  EXPECT_EQ(cv::countNonZero(same.instance_map != seg.instance_map), 0);
}

TEST(MaskPropagation, BadInputIsRefused) {
  const cv::Mat a(100, 100, CV_8U, cv::Scalar(0)), b(100, 90, CV_8U, cv::Scalar(0));
  Segmentation seg;
  EXPECT_THROW(PropagateSegmentation(seg, a, b, {}), std::invalid_argument);
  EXPECT_THROW(PropagateSegmentation(seg, a, cv::Mat(100, 100, CV_8UC3), {}),
               std::invalid_argument);
  MaskPropagationOptions bad;
  bad.confidence_decay = 0;
  EXPECT_THROW(PropagateSegmentation(seg, a, a, bad), std::invalid_argument);
  // No instances: an empty segmentation of the new image.
  const Segmentation none = PropagateSegmentation(seg, a, a, {});
  EXPECT_TRUE(none.instances.empty());
  EXPECT_EQ(cv::countNonZero(none.instance_map), 0);
}

// Real frames: YOLO on frame f and on f + 3 of drive 0005 (the ego car turning, cars driving by,
// a cyclist); each instance of f carried frame by frame to f + 3 matches the network's own mask
// of that object there (same class, best overlap) much better than the mask of f left where it
// was. (Per object: the network itself misses or adds objects between frames.)
TEST(MaskPropagation, YoloMasksCarriedThreeFramesMatchTheFreshOnes) {
  YoloOptions options;
  options.model_path = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  YoloSegmenter yolo(options);
  const auto image = [](int index) {
    char name[64];
    std::snprintf(name, sizeof(name), "%010d.png", index);
    const std::string path =
        test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync/image_00/data/") +
        name;
    cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
    EXPECT_FALSE(grey.empty()) << path;
    return grey;
  };
  double sum_moved = 0, sum_stale = 0;
  int objects = 0;
  for (int first : {20, 50, 75}) {
    const cv::Mat f0 = image(first);
    const Segmentation start = yolo.Segment(f0);
    Segmentation carried = start;
    cv::Mat prev = f0;
    for (int step = 1; step <= 3; ++step) {
      const cv::Mat cur = image(first + step);
      carried = PropagateSegmentation(carried, prev, cur, {});
      prev = cur;
    }
    const Segmentation fresh = yolo.Segment(prev);
    for (size_t k = 0; k < start.instances.size(); ++k) {
      const cv::Mat was = start.instance_map == static_cast<int>(k + 1);
      const cv::Mat now = carried.instance_map == static_cast<int>(k + 1);
      double best_moved = 0, best_stale = 0;
      for (size_t j = 0; j < fresh.instances.size(); ++j) {
        if (fresh.instances[j].class_name != start.instances[k].class_name) continue;
        const cv::Mat truth = fresh.instance_map == static_cast<int>(j + 1);
        const double moved = Iou(now, truth), stale = Iou(was, truth);
        if (std::max(moved, stale) > std::max(best_moved, best_stale)) {
          best_moved = moved;
          best_stale = stale;
        }
      }
      if (std::max(best_moved, best_stale) < 0.2) continue;  // not found again
      std::printf("frames %d -> %d, %s: mask IoU with the fresh one %.3f carried, %.3f in place\n",
                  first, first + 3, start.instances[k].class_name.c_str(), best_moved, best_stale);
      sum_moved += best_moved;
      sum_stale += best_stale;
      ++objects;
    }
  }
  ASSERT_GE(objects, 6);
  std::printf("%d objects: mean IoU %.3f carried, %.3f in place\n", objects, sum_moved / objects,
              sum_stale / objects);
  EXPECT_GT(sum_moved / objects, sum_stale / objects + 0.1);
  EXPECT_GT(sum_moved / objects, 0.55);  // measured 0.639 against 0.348
}

}  // namespace
}  // namespace pcr
