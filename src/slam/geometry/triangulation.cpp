#include "slam/geometry/triangulation.h"

#include <Eigen/SVD>
#include <cmath>

namespace pcr {

bool TriangulateDlt(const Matrix34d& P1, const Matrix34d& P2, const Eigen::Vector2d& x1,
                    const Eigen::Vector2d& x2, Eigen::Vector3d* X) {
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  for (int r = 0; r < 4; ++r) {
    const double n = A.row(r).norm();
    if (!(n > 0.0) || !std::isfinite(n)) return false;
    A.row(r) /= n;
  }
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  // h is a unit vector; a tiny homogeneous weight means a point at (or beyond) infinity.
  if (!(std::abs(h(3)) > 1e-12)) return false;
  const Eigen::Vector3d p = h.head<3>() / h(3);
  if (!p.allFinite()) return false;
  *X = p;
  return true;
}

bool TriangulationChecks::IsValid(std::string* why) const {
  auto fail = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (!(chi2_threshold > 0.0)) return fail("chi2_threshold must be > 0");
  if (!(sigma2_first > 0.0) || !(sigma2_second > 0.0)) return fail("sigma2 must be > 0");
  if (!(max_cos_parallax > -1.0 && max_cos_parallax <= 1.0)) {
    return fail("max_cos_parallax must be in (-1, 1]");
  }
  if (!(min_depth_m >= 0.0)) return fail("min_depth_m must be >= 0");
  return true;
}

const char* ToString(TriangulationRejection rejection) {
  switch (rejection) {
    case TriangulationRejection::kNone:
      return "none";
    case TriangulationRejection::kDegenerate:
      return "degenerate";
    case TriangulationRejection::kLowParallax:
      return "low parallax";
    case TriangulationRejection::kBehindCamera:
      return "behind camera";
    case TriangulationRejection::kReprojectionError:
      return "reprojection error";
  }
  return "unknown";
}

double ParallaxCos(const Eigen::Vector3d& p_in_world, const SE3& cam1_from_world,
                   const SE3& cam2_from_world) {
  // Camera centre in world: -R^T t.
  const Eigen::Vector3d c1 = -cam1_from_world.linear().transpose() * cam1_from_world.translation();
  const Eigen::Vector3d c2 = -cam2_from_world.linear().transpose() * cam2_from_world.translation();
  const Eigen::Vector3d r1 = p_in_world - c1;
  const Eigen::Vector3d r2 = p_in_world - c2;
  const double n = r1.norm() * r2.norm();
  if (!(n > 0.0)) return 1.0;
  return r1.dot(r2) / n;
}

std::optional<Eigen::Vector3d> TriangulateChecked(
    const PinholeCamera& camera, const SE3& cam1_from_world, const SE3& cam2_from_world,
    const Eigen::Vector2d& uv1_px, const Eigen::Vector2d& uv2_px, const TriangulationChecks& checks,
    TriangulationRejection* rejection) {
  auto reject = [rejection](TriangulationRejection r) -> std::optional<Eigen::Vector3d> {
    if (rejection) *rejection = r;
    return std::nullopt;
  };
  // Triangulate in normalised image coordinates for conditioning.
  auto normalised = [&camera](const Eigen::Vector2d& uv) {
    return Eigen::Vector2d((uv.x() - camera.cx) / camera.fx, (uv.y() - camera.cy) / camera.fy);
  };
  Matrix34d P1, P2;
  P1 << cam1_from_world.linear(), cam1_from_world.translation();
  P2 << cam2_from_world.linear(), cam2_from_world.translation();
  Eigen::Vector3d p_in_world;
  if (!TriangulateDlt(P1, P2, normalised(uv1_px), normalised(uv2_px), &p_in_world)) {
    return reject(TriangulationRejection::kDegenerate);
  }
  if (ParallaxCos(p_in_world, cam1_from_world, cam2_from_world) >= checks.max_cos_parallax) {
    return reject(TriangulationRejection::kLowParallax);
  }
  const Eigen::Vector3d p_in_cam1 = cam1_from_world * p_in_world;
  const Eigen::Vector3d p_in_cam2 = cam2_from_world * p_in_world;
  if (!(p_in_cam1.z() > checks.min_depth_m) || !(p_in_cam2.z() > checks.min_depth_m)) {
    return reject(TriangulationRejection::kBehindCamera);
  }
  const double e1 = (camera.Project(p_in_cam1) - uv1_px).squaredNorm();
  const double e2 = (camera.Project(p_in_cam2) - uv2_px).squaredNorm();
  if (e1 > checks.chi2_threshold * checks.sigma2_first ||
      e2 > checks.chi2_threshold * checks.sigma2_second) {
    return reject(TriangulationRejection::kReprojectionError);
  }
  if (rejection) *rejection = TriangulationRejection::kNone;
  return p_in_world;
}

}  // namespace pcr
