#include "slam/geometry/sim3.h"

#include <Eigen/SVD>
#include <cmath>

namespace pcr {

std::optional<Sim3> AlignPoints(const std::vector<Eigen::Vector3d>& p_a,
                                const std::vector<Eigen::Vector3d>& p_b, bool fix_scale) {
  const size_t n = p_a.size();
  if (n < 3 || p_b.size() != n) return std::nullopt;
  Eigen::Vector3d centroid_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid_b = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    if (!p_a[i].allFinite() || !p_b[i].allFinite()) return std::nullopt;
    centroid_a += p_a[i];
    centroid_b += p_b[i];
  }
  const double inv_n = 1.0 / static_cast<double>(n);
  centroid_a *= inv_n;
  centroid_b *= inv_n;

  // Cross-covariance sum (a - ca)(b - cb)^T and the spread of b.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double spread_b = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = p_a[i] - centroid_a;
    const Eigen::Vector3d b = p_b[i] - centroid_b;
    covariance += a * b.transpose();
    spread_b += b.squaredNorm();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d singular = svd.singularValues();  // descending
  // Rank < 2 (coincident or collinear points): the rotation about the line is undetermined.
  if (!(spread_b > 0) || !(singular(0) > 0) || !(singular(1) > 1e-10 * singular(0)))
    return std::nullopt;

  Eigen::Vector3d signs(1.0, 1.0, 1.0);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) signs(2) = -1.0;
  Sim3 a_from_b;
  a_from_b.rotation = svd.matrixU() * signs.asDiagonal() * svd.matrixV().transpose();
  if (!fix_scale) {
    a_from_b.scale = singular.dot(signs) / spread_b;
    if (!(a_from_b.scale > 0) || !std::isfinite(a_from_b.scale)) return std::nullopt;
  }
  a_from_b.translation = centroid_a - a_from_b.scale * (a_from_b.rotation * centroid_b);
  return a_from_b;
}

}  // namespace pcr
