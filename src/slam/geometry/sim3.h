#pragma once
// Similarity transforms Sim(3) and their closed-form estimation from 3-D/3-D correspondences,
// the geometry of loop closing (ORB-SLAM's Sim3: a monocular map drifts in scale).
//
// A similarity named a_from_b maps coordinates in frame b to frame a:
//   p_in_a = a_from_b.Map(p_in_b) = scale * rotation * p_in_b + translation.
// A keyframe pose as a similarity is cam_from_world (ORB-SLAM's Scw); with scale 1 it is the SE3
// pose. The struct and its operations are header-only (inline), so layers that do not link
// pcr_slam_geometry (slam/optim) can use the type; AlignPoints lives in sim3.cpp.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "slam/common/pose.h"

namespace pcr {

struct Sim3 {
  double scale = 1.0;  // > 0, dimensionless
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // in units of frame a

  static Sim3 Identity() { return Sim3{}; }
  // The rigid motion a_from_b as a similarity of scale 1.
  static Sim3 FromSE3(const SE3& a_from_b) {
    return Sim3{1.0, a_from_b.linear(), a_from_b.translation()};
  }

  // p_in_a of p_in_b.
  Eigen::Vector3d Map(const Eigen::Vector3d& p_in_b) const {
    return scale * (rotation * p_in_b) + translation;
  }
  // (a_from_b * b_from_c).Map(p) == a_from_b.Map(b_from_c.Map(p)).
  Sim3 operator*(const Sim3& b_from_c) const {
    return Sim3{scale * b_from_c.scale, rotation * b_from_c.rotation,
                scale * (rotation * b_from_c.translation) + translation};
  }
  // b_from_a: scale 1/s, rotation R^T, translation -(1/s) R^T t.
  Sim3 Inverse() const {
    const Eigen::Matrix3d rotation_t = rotation.transpose();
    return Sim3{1.0 / scale, rotation_t, -(rotation_t * translation) / scale};
  }
  // Drops the scale as ORB-SLAM does for a corrected keyframe pose Scw = [sR, t]: returns
  // [R, t / s]. For cam_from_world this is the rigid pose with the same orientation and the same
  // camera centre in the world (-R^T t / s); points keep their world-frame metric. Equivalently,
  // ToSE3() == (1/s) * S as a map, so ToSE3().Map(p) == Map(p) / scale.
  SE3 ToSE3() const {
    SE3 pose = SE3::Identity();
    pose.linear() = rotation;
    pose.translation() = translation / scale;
    return pose;
  }
  // Homogeneous 4x4 matrix [sR, t; 0, 1].
  Eigen::Matrix4d ToMatrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = scale * rotation;
    m.topRightCorner<3, 1>() = translation;
    return m;
  }
};

// The similarity a_from_b that minimises sum_i |p_a[i] - a_from_b.Map(p_b[i])|^2 in closed form
// (Horn 1987 / Umeyama 1991, proper rotation guaranteed). fix_scale: scale is 1 (a rigid motion,
// stereo/RGB-D); else the scale is Umeyama's, sum of the singular values over the spread of p_b.
// Returns nullopt when the sizes differ, there are fewer than 3 pairs, a value is not finite, or
// the points are degenerate (all coincident or collinear: the cross-covariance has rank < 2).
std::optional<Sim3> AlignPoints(const std::vector<Eigen::Vector3d>& p_a,
                                const std::vector<Eigen::Vector3d>& p_b, bool fix_scale);

// The one 3-D/3-D correspondence between two keyframes that Sim3 estimation and refinement use
// (slam/loop/sim3_ransac.h, slam/optim/sim3_optimizer.h): the same map point seen by both.
struct Sim3Correspondence {
  Eigen::Vector3d p_in_cam1 = Eigen::Vector3d::Zero();  // metres (keyframe 1's map), camera 1
  Eigen::Vector3d p_in_cam2 = Eigen::Vector3d::Zero();  // metres (keyframe 2's map), camera 2
  Eigen::Vector2d uv1_px = Eigen::Vector2d::Zero();     // its keypoint in image 1
  Eigen::Vector2d uv2_px = Eigen::Vector2d::Zero();     // its keypoint in image 2
  // Pixel noise variance of each keypoint: the pyramid level's scale factor squared
  // (1.2^(2 octave)); information is 1 / sigma2.
  double sigma2_1 = 1.0;
  double sigma2_2 = 1.0;
};

}  // namespace pcr
