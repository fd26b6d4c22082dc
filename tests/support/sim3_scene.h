#pragma once
// Two cameras related by a known similarity and point matches between them (header-only), for
// the Sim(3) RANSAC and Sim(3) optimiser tests.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/lie.h"
#include "slam/geometry/sim3.h"
#include "support/test_helpers.h"

namespace pcr::test {

struct MatchScene {
  Sim3 cam1_from_cam2;
  std::vector<Sim3Correspondence> matches;
  std::vector<bool> is_outlier;
};

// A point seen by both cameras: in camera 1 at a pixel inside the image and a depth in [4, 30] m,
// and in front of camera 2 (z > 1 m) inside its image.
inline bool SampleSharedPoint(const PinholeCamera& camera, const Sim3& cam1_from_cam2,
                              std::mt19937_64& rng, Eigen::Vector3d* p_in_cam1,
                              Eigen::Vector3d* p_in_cam2) {
  std::uniform_real_distribution<double> u(0.0, camera.width_px - 1.0);
  std::uniform_real_distribution<double> v(0.0, camera.height_px - 1.0);
  std::uniform_real_distribution<double> depth(4.0, 30.0);
  for (int attempt = 0; attempt < 100; ++attempt) {
    *p_in_cam1 = camera.Unproject({u(rng), v(rng)}, depth(rng));
    *p_in_cam2 = cam1_from_cam2.Inverse().Map(*p_in_cam1);
    if (p_in_cam2->z() > 1.0 && camera.InImage(camera.Project(*p_in_cam2))) return true;
  }
  return false;
}

// count matches in the KITTI camera between camera 1 and camera 2 = cam1_from_cam2^-1, where
// cam1_from_cam2 = [scale, ExpSO3(rotation_log), translation]; keypoints at random octaves 0-3
// with Gaussian pixel noise noise_px times the octave's scale; an outlier (probability
// outlier_fraction) pairs a point with another point's position and keypoint in camera 2.
inline MatchScene MakeMatchScene(const Eigen::Vector3d& rotation_log,
                                 const Eigen::Vector3d& translation, double scale, uint64_t seed,
                                 int count, double outlier_fraction, double noise_px) {
  const PinholeCamera camera = KittiCamera();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::uniform_int_distribution<int> octave(0, 3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  MatchScene scene;
  scene.cam1_from_cam2.scale = scale;
  scene.cam1_from_cam2.rotation = ExpSO3(rotation_log);
  scene.cam1_from_cam2.translation = translation;
  for (int i = 0; i < count; ++i) {
    Sim3Correspondence m;
    EXPECT_TRUE(SampleSharedPoint(camera, scene.cam1_from_cam2, rng, &m.p_in_cam1, &m.p_in_cam2));
    const double level1 = std::pow(1.2, octave(rng)), level2 = std::pow(1.2, octave(rng));
    m.sigma2_1 = level1 * level1;
    m.sigma2_2 = level2 * level2;
    m.uv1_px = camera.Project(m.p_in_cam1) + level1 * Eigen::Vector2d(noise(rng), noise(rng));
    const bool outlier = unit(rng) < outlier_fraction;
    if (outlier) {
      Eigen::Vector3d other_in_cam1;
      EXPECT_TRUE(
          SampleSharedPoint(camera, scene.cam1_from_cam2, rng, &other_in_cam1, &m.p_in_cam2));
    }
    m.uv2_px = camera.Project(m.p_in_cam2) + level2 * Eigen::Vector2d(noise(rng), noise(rng));
    scene.matches.push_back(m);
    scene.is_outlier.push_back(outlier);
  }
  return scene;
}

inline double RotationErrorDeg(const Sim3& a, const Sim3& b) {
  return RotationDistanceRad(a.rotation, b.rotation) / kDegToRad;
}

}  // namespace pcr::test
