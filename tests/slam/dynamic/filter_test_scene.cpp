#include "filter_test_scene.h"

#include <Eigen/Geometry>
#include <map>
#include <opencv2/imgproc.hpp>
#include <random>

#include "slam/dynamic/mask_utils.h"

namespace pcr::test {
namespace {

constexpr double kHeightM = 1.65;  // camera above the ground (ground at y = +1.65)

struct Box {
  Eigen::Vector3d min_corner, max_corner;  // at frame 0, world
  Eigen::Vector3d velocity;                // world, per frame
  Eigen::Vector3d Min(int k) const { return min_corner + k * velocity; }
  Eigen::Vector3d Max(int k) const { return max_corner + k * velocity; }
};

struct ScenePoint {
  int64_t id = 0;
  PointKind kind = PointKind::kStatic;
  Eigen::Vector3d p_world;  // frame 0
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  int box = -1;  // the box it lies on
  int octave = 0;
  bool stereo = true;
};

SE3 Pose(const FilterSceneOptions& o, int k) {
  SE3 pose = SE3::Identity();
  pose.translation() = Eigen::Vector3d(0.0, 0.0, k * o.camera_speed_m);
  pose.linear() =
      Eigen::AngleAxisd(k * o.yaw_deg_per_frame * M_PI / 180.0, Eigen::Vector3d::UnitY())
          .toRotationMatrix();
  return pose;
}

// Convex hull of the projected corners of a box (CV_8U 0/255), empty when behind the camera.
cv::Mat BoxMask(const PinholeCamera& cam, const SE3& cam_from_world, const Eigen::Vector3d& lo,
                const Eigen::Vector3d& hi, double* min_depth) {
  std::vector<cv::Point> corners;
  *min_depth = 1e9;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p(c & 1 ? hi.x() : lo.x(), c & 2 ? hi.y() : lo.y(),
                            c & 4 ? hi.z() : lo.z());
    const Eigen::Vector3d q = cam_from_world * p;
    if (q.z() < 0.5) return {};
    *min_depth = std::min(*min_depth, q.z());
    const Eigen::Vector2d uv = cam.Project(q);
    corners.emplace_back(static_cast<int>(std::lround(uv.x())),
                         static_cast<int>(std::lround(uv.y())));
  }
  std::vector<cv::Point> hull;
  cv::convexHull(corners, hull);
  cv::Mat mask(cam.height_px, cam.width_px, CV_8U, cv::Scalar(0));
  cv::fillConvexPoly(mask, hull, cv::Scalar(255));
  return mask;
}

}  // namespace

StereoRig KittiRig() {
  StereoRig rig;
  rig.left = PinholeCamera{718.856, 718.856, 607.1928, 185.2157, 1241, 376};
  rig.baseline_m = 0.537;
  return rig;
}

cv::Rect SkyPatch() { return cv::Rect(500, 5, 240, 95); }

std::vector<FilterSceneFrame> BuildFilterScene(const FilterSceneOptions& o) {
  const StereoRig rig = KittiRig();
  const PinholeCamera& cam = rig.left;
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  auto u = [&](double a, double b) { return a + (b - a) * uni(rng); };

  const std::vector<Box> boxes = {
      // Parked car at the right kerb.
      {{3.5, 0.15, 14.0}, {5.3, kHeightM, 18.2}, Eigen::Vector3d::Zero()},
      // Car crossing the road from the left, 1.5 m per frame.
      {{-8.0, 0.15, 20.0}, {-3.8, kHeightM, 21.8}, Eigen::Vector3d(o.moving_speed_m, 0, 0)},
  };
  std::vector<ScenePoint> points;
  int64_t next_id = 0;
  auto add = [&](PointKind kind, const Eigen::Vector3d& p, int box = -1) {
    ScenePoint sp;
    sp.id = next_id++;
    sp.kind = kind;
    sp.p_world = p;
    sp.box = box;
    if (box >= 0) sp.velocity = boxes[box].velocity;
    sp.octave = static_cast<int>(uni(rng) * 3.0);
    sp.stereo = kind == PointKind::kSky ? false : uni(rng) < o.stereo_fraction;
    points.push_back(sp);
  };
  for (int i = 0; i < 700; ++i) add(PointKind::kGround, {u(-7, 7), kHeightM, u(3, 45)});
  for (int side = -1; side <= 1; side += 2) {
    for (int i = 0; i < 250; ++i) add(PointKind::kStatic, {side * 9.0, u(-3, 1.6), u(2, 60)});
  }
  for (int i = 0; i < 150; ++i) add(PointKind::kStatic, {u(-30, 30), u(-3, 1.6), 80.0});
  for (int i = 0; i < 30; ++i)
    add(PointKind::kNearStatic, {u(2.4, 2.6), u(-1.0, 1.6), u(6.0, 6.4)});
  for (int b = 0; b < 2; ++b) {
    const Box& box = boxes[b];
    const PointKind kind = b == 0 ? PointKind::kParked : PointKind::kMoving;
    for (int i = 0; i < 100; ++i) {
      const double face = uni(rng);
      Eigen::Vector3d p(u(box.min_corner.x(), box.max_corner.x()),
                        u(box.min_corner.y(), box.max_corner.y()),
                        u(box.min_corner.z(), box.max_corner.z()));
      if (face < 0.6) {
        p.z() = box.min_corner.z();  // the face towards the camera
      } else if (face < 0.8) {
        p.y() = box.min_corner.y();  // top
      } else if (b == 0) {
        p.x() = box.min_corner.x();  // the parked car's side towards the road
      } else {
        p.z() = box.min_corner.z();
      }
      add(kind, p, b);
    }
  }
  // Sky: directions through the sky patch of frame 0, at 100 km.
  const cv::Rect sky = SkyPatch();
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector2d uv(u(sky.x + 30, sky.x + sky.width - 30),
                             u(sky.y + 15, sky.y + sky.height - 15));
    add(PointKind::kSky, cam.Unproject(uv, 1.0).normalized() * 1e5);
  }

  // Per-point noisy observation of the previous frame.
  std::map<int64_t, cv::Point2f> previous_obs;
  std::vector<FilterSceneFrame> frames;
  for (int k = 0; k < o.num_frames; ++k) {
    FilterSceneFrame f;
    f.index = k;
    f.world_from_cam = Pose(o, k);
    const SE3 cam_from_world = f.world_from_cam.inverse();
    if (k > 0) f.cur_from_prev = cam_from_world * Pose(o, k - 1);

    // Box masks (instance 1: parked, 2: moving) for occlusion and segmentation.
    std::vector<cv::Mat> masks(2);
    std::vector<double> box_depth(2, 1e9);
    for (int b = 0; b < 2; ++b) {
      masks[b] = BoxMask(cam, cam_from_world, boxes[b].Min(k), boxes[b].Max(k), &box_depth[b]);
    }
    std::map<int64_t, cv::Point2f> obs;
    for (const ScenePoint& sp : points) {
      const Eigen::Vector3d p_world = sp.p_world + k * sp.velocity;
      const Eigen::Vector3d p = cam_from_world * p_world;
      if (p.z() < 1.0) continue;
      const Eigen::Vector2d uv_true = cam.Project(p);
      if (!cam.InImage(uv_true, 20.0)) continue;
      const cv::Point iuv(static_cast<int>(std::lround(uv_true.x())),
                          static_cast<int>(std::lround(uv_true.y())));
      bool hidden = false;
      for (int b = 0; b < 2; ++b) {
        if (b == sp.box || masks[b].empty()) continue;
        if (masks[b].at<uint8_t>(iuv) && p.z() > box_depth[b]) hidden = true;
      }
      if (hidden) continue;
      if (sp.kind != PointKind::kSky && sky.contains(iuv)) continue;  // keep the sky patch clean
      const cv::Point2f uv(static_cast<float>(uv_true.x() + o.pixel_noise_px * gauss(rng)),
                           static_cast<float>(uv_true.y() + o.pixel_noise_px * gauss(rng)));
      obs[sp.id] = uv;
      cv::KeyPoint kp(uv, 31.0f * static_cast<float>(std::pow(1.2, sp.octave)));
      kp.octave = sp.octave;
      f.keypoints.push_back(kp);
      float depth = -1.0f;
      if (sp.stereo) {
        const double disparity = rig.Bf() / p.z() + o.disparity_noise_px * gauss(rng);
        if (disparity > 0.5) depth = static_cast<float>(rig.Bf() / disparity);
      }
      f.depth_m.push_back(depth);
      f.ids.push_back(sp.id);
      const auto prev = previous_obs.find(sp.id);
      const bool dropped = k == o.drop_moving_tracks_frame && sp.kind == PointKind::kMoving;
      f.prev_uv_px.push_back(prev != previous_obs.end() && !dropped ? prev->second
                                                                    : cv::Point2f(-1, -1));
      f.kinds.push_back(sp.kind);
      f.p_in_cam.push_back(p);
    }
    // Border keypoints: static points 15 m away seen within 2 px of the border.
    if (k > 0) {
      const SE3 prev_from_cur = f.cur_from_prev.inverse();
      const Eigen::Vector2d border_uv[] = {{1.0, 150.0},    {1.5, 250.0},  {1239.0, 120.0},
                                           {1238.5, 300.0}, {300.0, 1.0},  {900.0, 1.5},
                                           {450.0, 374.0},  {800.0, 373.5}};
      for (const Eigen::Vector2d& uv : border_uv) {
        const Eigen::Vector3d p = cam.Unproject(uv, 15.0);
        const Eigen::Vector2d prev = cam.Project(prev_from_cur * p);
        cv::KeyPoint kp(cv::Point2f(static_cast<float>(uv.x()), static_cast<float>(uv.y())), 31.0f);
        kp.octave = 0;
        f.keypoints.push_back(kp);
        f.depth_m.push_back(15.0f);
        f.ids.push_back(next_id++);
        f.prev_uv_px.push_back(cam.InImage(prev) ? cv::Point2f(static_cast<float>(prev.x()),
                                                               static_cast<float>(prev.y()))
                                                 : cv::Point2f(-1, -1));
        f.kinds.push_back(PointKind::kBorder);
        f.p_in_cam.push_back(p);
      }
    }
    previous_obs = std::move(obs);

    // Image: blurred noise texture, the sky patch flat and bright.
    f.image = cv::Mat(cam.height_px, cam.width_px, CV_8U);
    cv::RNG cv_rng(static_cast<uint64_t>(o.seed + 1000 * k));
    cv_rng.fill(f.image, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(f.image, f.image, cv::Size(3, 3), 0.8);
    cv::Mat sky_noise(sky.size(), CV_8U);
    cv_rng.fill(sky_noise, cv::RNG::NORMAL, 225, 1.0);
    sky_noise.copyTo(f.image(sky));

    // Segmentation: both boxes as "car" instances (the moving one possibly missing).
    for (int b = 0; b < 2; ++b) {
      if (masks[b].empty()) continue;
      if (b == 1 && k == o.omit_moving_mask_frame) continue;
      Instance inst;
      inst.class_id = 2;
      inst.class_name = "car";
      inst.confidence = o.mask_confidence;
      const cv::Rect r = cv::boundingRect(masks[b]);
      inst.box_px = cv::Rect2f(static_cast<float>(r.x), static_cast<float>(r.y),
                               static_cast<float>(r.width), static_cast<float>(r.height));
      inst.mask = masks[b];
      inst.instance_id = static_cast<int>(f.segmentation.instances.size());
      f.segmentation.instances.push_back(inst);
    }
    const cv::Size size(cam.width_px, cam.height_px);
    f.segmentation.instance_map = BuildInstanceMap(f.segmentation.instances, size);
    f.segmentation.dynamic_confidence =
        DynamicConfidenceMap(f.segmentation.instances, size, DynamicClassPolicy{}, 5, 2.0);
    f.segmentation.backend = "synthetic";
    frames.push_back(std::move(f));
  }
  return frames;
}

FilterInput SceneFilterInput(const FilterSceneFrame& f) {
  FilterInput in;
  in.frame_index = f.index;
  in.t_ns = f.index * 100'000'000LL;
  in.left_image = f.image;
  in.keypoints = f.keypoints;
  in.depth_m = f.depth_m;
  in.point_ids = f.ids;
  in.previous_uv_px = f.prev_uv_px;
  in.rig = KittiRig();
  in.segmentation = &f.segmentation;
  if (f.index > 0) in.cur_from_prev = f.cur_from_prev;
  return in;
}

}  // namespace pcr::test
