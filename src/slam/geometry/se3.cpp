#include "slam/geometry/se3.h"

#include <cmath>

namespace pcr {

double AngleBetweenRad(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

Eigen::Matrix3d IntrinsicMatrix(const PinholeCamera& camera) {
  Eigen::Matrix3d K;
  K << camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0;
  return K;
}

Matrix34d ProjectionMatrix(const PinholeCamera& camera, const SE3& cam_from_world) {
  Matrix34d Rt;
  Rt.leftCols<3>() = cam_from_world.linear();
  Rt.col(3) = cam_from_world.translation();
  return IntrinsicMatrix(camera) * Rt;
}

}  // namespace pcr
