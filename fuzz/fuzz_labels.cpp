// libFuzzer target: KITTI tracking labels, then box projection and track motion on whatever
// parsed (all values finite by contract).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>

#include "io/kitti_tracking.h"
#include "slam/common/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    std::istringstream in(text);
    const pcr::TrackingLabels labels = pcr::ReadTrackingLabels(in, "fuzz.labels", size % 2 == 0);
    Eigen::Matrix<double, 3, 4> p;
    p << 721.5, 0, 609.6, 44.9, 0, 721.5, 172.9, 0.2, 0, 0, 1, 0.003;
    pcr::Trajectory ego;
    for (size_t f = 0; f < labels.frames.size() && f < 200; ++f) {
      pcr::StampedPose pose;
      pose.frame_index = static_cast<int64_t>(f);
      pose.t_ns = static_cast<int64_t>(f) * 100'000'000;
      pose.world_from_cam.translation() = Eigen::Vector3d(0, 0, static_cast<double>(f));
      ego.push_back(pose);
      for (const pcr::TrackedObject& object : labels.frames[f]) {
        const pcr::ProjectedBox box = pcr::ProjectBox(object, p, 1242, 375);
        for (const Eigen::Vector2d& q : box.polygon)
          if (!(q.x() >= -1e-6 && q.x() <= 1242 + 1e-6 && q.y() >= -1e-6 && q.y() <= 375 + 1e-6))
            std::abort();
      }
    }
    (void)pcr::ComputeTrackMotion(labels, ego);
  } catch (const pcr::InputError&) {
  }
  return 0;
}
