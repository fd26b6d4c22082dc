#include "sim/synthetic_world.h"

#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "sim/raycaster.h"
#include "sim/scene_builder.h"
#include "sim/texture.h"
#include "slam/common/error.h"

namespace pcr::sim {

struct SyntheticWorld::Impl {
  SynthOptions options;
  Scene scene;
  InstanceTable table;
  std::vector<int> index_of_id;  // instance id -> position in scene.instances
  SE3 world_from_map = SE3::Identity();

  SE3 MapFromCam(double t_s) const;
  SE3 MapFromObject(const SceneInstance& inst, double t_s) const;
  double TimeOf(int frame) const { return frame / options.rate_hz; }
};

SE3 SyntheticWorld::Impl::MapFromCam(double t_s) const {
  const PathPoint p = scene.ego_path.At(scene.ego_s0_m + options.speed_mps * t_s);
  const double k = options.bounce_scale;
  const uint32_t ph = scene.bounce_phase_seed;
  const double two_pi = 2 * std::numbers::pi;
  const double phase1 = two_pi * tex::Unit(tex::Hash1(1, ph));
  const double phase2 = two_pi * tex::Unit(tex::Hash1(2, ph));
  const double phase3 = two_pi * tex::Unit(tex::Hash1(3, ph));
  const double dh_m = k * 0.01 * std::sin(two_pi * 1.1 * t_s + phase1);
  const double pitch = k * 0.0035 * std::sin(two_pi * 0.7 * t_s + phase2);
  const double roll = k * 0.0025 * std::sin(two_pi * 0.5 * t_s + phase3);
  SE3 pose = SE3::Identity();
  pose.linear() = (Eigen::AngleAxisd(p.heading_rad, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
                   Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                      .toRotationMatrix();
  pose.translation() = Eigen::Vector3d(p.xz.x(), -(options.camera_height_m + dh_m), p.xz.y());
  return pose;
}

SE3 SyntheticWorld::Impl::MapFromObject(const SceneInstance& inst, double t_s) const {
  Eigen::Vector2d xz;
  double heading;
  inst.motion.At(t_s, &xz, &heading);
  return GroundPose(xz, heading);
}

SyntheticWorld::SyntheticWorld(const SynthOptions& options) : impl_(std::make_unique<Impl>()) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("synthetic world options: " + why);
  impl_->options = options;
  impl_->scene = BuildScene(options);
  std::vector<InstanceInfo> infos;
  impl_->index_of_id.assign(65536, -1);
  for (size_t i = 0; i < impl_->scene.instances.size(); ++i) {
    infos.push_back(impl_->scene.instances[i].info);
    impl_->index_of_id[impl_->scene.instances[i].info.id] = static_cast<int>(i);
  }
  impl_->table = InstanceTable(std::move(infos));
  impl_->world_from_map = impl_->MapFromCam(0.0).inverse();
}

SyntheticWorld::~SyntheticWorld() = default;
SyntheticWorld::SyntheticWorld(SyntheticWorld&&) noexcept = default;
SyntheticWorld& SyntheticWorld::operator=(SyntheticWorld&&) noexcept = default;

const SynthOptions& SyntheticWorld::options() const { return impl_->options; }

int64_t SyntheticWorld::FrameTimeNs(int frame) const { return SecondsToNs(impl_->TimeOf(frame)); }

SE3 SyntheticWorld::WorldFromCam(int frame) const {
  return impl_->world_from_map * impl_->MapFromCam(impl_->TimeOf(frame));
}

Trajectory SyntheticWorld::GroundTruth() const {
  Trajectory out;
  for (int i = 0; i < NumFrames(); ++i) out.push_back({FrameTimeNs(i), i, WorldFromCam(i)});
  return out;
}

const InstanceTable& SyntheticWorld::Instances() const { return impl_->table; }

SE3 SyntheticWorld::WorldFromObject(uint16_t id, int frame) const {
  const int index = impl_->index_of_id[id];
  if (index < 0) throw std::out_of_range("unknown instance id " + std::to_string(id));
  return impl_->world_from_map *
         impl_->MapFromObject(impl_->scene.instances[static_cast<size_t>(index)],
                              impl_->TimeOf(frame));
}

namespace {

// Optics blur, sensor noise (Irwin-Hall approximation of a Gaussian, hashed per pixel) and
// 8-bit quantisation.
cv::Mat Develop(const cv::Mat& radiance, double noise_sigma, uint32_t noise_seed) {
  cv::Mat blurred;
  cv::GaussianBlur(radiance, blurred, cv::Size(3, 3), 0.4, 0.4, cv::BORDER_REPLICATE);
  cv::Mat out(radiance.size(), CV_8UC1);
  const double scale = noise_sigma * std::sqrt(3.0) / 2.0;  // sum of 4 U(-1,1): variance 4/3
  cv::parallel_for_(cv::Range(0, radiance.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* in = blurred.ptr<float>(y);
      uint8_t* o = out.ptr<uint8_t>(y);
      for (int x = 0; x < radiance.cols; ++x) {
        double value = in[x];
        if (noise_sigma > 0) {
          const uint32_t h1 = tex::Hash2(x, y, noise_seed);
          const uint32_t h2 = tex::Mix32(h1 ^ 0x68e31da4U);
          const double n =
              tex::Signed(h1) + tex::Signed(h1 << 12) + tex::Signed(h2) + tex::Signed(h2 << 12);
          value += scale * n;
        }
        o[x] = cv::saturate_cast<uint8_t>(value);
      }
    }
  });
  return out;
}

}  // namespace

RenderedFrame SyntheticWorld::RenderFrame(int frame) const {
  if (frame < 0 || frame >= NumFrames())
    throw std::out_of_range("frame " + std::to_string(frame) + " outside [0, " +
                            std::to_string(NumFrames()) + ")");
  const Impl& im = *impl_;
  const double t_s = im.TimeOf(frame);
  std::vector<BoxPrim> boxes = im.scene.static_boxes;
  for (const SceneInstance& inst : im.scene.instances) {
    const SE3 map_from_object = im.MapFromObject(inst, t_s);
    const double yaw = std::atan2(map_from_object.linear()(0, 2), map_from_object.linear()(2, 2));
    for (const BoxPrim& part : inst.parts) {
      BoxPrim b = part;
      b.center = map_from_object * part.center;
      b.yaw_rad = part.yaw_rad + yaw;
      boxes.push_back(b);
    }
  }
  const SE3 map_from_left = im.MapFromCam(t_s);
  ViewInput view;
  view.boxes = &boxes;
  view.ground = &im.scene.ground;
  view.camera = im.options.Rig().left;
  view.map_from_cam_rotation = map_from_left.linear();
  view.cam_in_map = map_from_left.translation();
  ViewOutput left, right;
  RenderView(view, &left);
  view.cam_in_map = map_from_left * Eigen::Vector3d(im.options.baseline_m, 0, 0);
  RenderView(view, &right);

  RenderedFrame out;
  out.index = frame;
  out.t_ns = FrameTimeNs(frame);
  out.world_from_cam = im.world_from_map * map_from_left;
  const uint32_t seed32 = static_cast<uint32_t>(im.options.seed ^ (im.options.seed >> 32));
  const uint32_t frame_seed = tex::Hash2(frame, 0x5eed, seed32);
  out.left = Develop(left.radiance, im.options.noise_sigma, tex::Hash1(0, frame_seed));
  out.right = Develop(right.radiance, im.options.noise_sigma, tex::Hash1(1, frame_seed));
  out.instance_left = left.instance;
  out.instance_right = right.instance;
  out.depth_left = left.depth;
  out.depth_right = right.depth;
  return out;
}

}  // namespace pcr::sim
