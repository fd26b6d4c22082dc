#include "slam/geometry/two_view.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/geometry/cv_pose.h"
#include "slam/geometry/se3.h"
#include "slam/geometry/triangulation.h"

namespace pcr {
namespace {

using Points = std::vector<Eigen::Vector2d>;

constexpr int kHomographySample = 4;
constexpr int kFundamentalSample = 8;
// A minimal system whose second-smallest singular value falls below this fraction of the largest
// has a null space of dimension > 1 (collinear or otherwise degenerate sample).
constexpr double kDegenerateSvRatio = 1e-10;

// Similarity moving the centroid to the origin and the mean distance to it to sqrt(2).
Eigen::Matrix3d NormalizingTransform(const Points& pts) {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& p : pts) centroid += p;
  centroid /= static_cast<double>(pts.size());
  double mean_dist = 0.0;
  for (const auto& p : pts) mean_dist += (p - centroid).norm();
  mean_dist /= static_cast<double>(pts.size());
  const double s = mean_dist > 0.0 ? std::sqrt(2.0) / mean_dist : 1.0;
  Eigen::Matrix3d T;
  T << s, 0.0, -s * centroid.x(), 0.0, s, -s * centroid.y(), 0.0, 0.0, 1.0;
  return T;
}

Points Transform(const Eigen::Matrix3d& T, const Points& pts) {
  Points out(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) out[i] = (T * pts[i].homogeneous()).hnormalized();
  return out;
}

// Null vector of A (rows >= 8, 9 columns) reshaped row-major into 3x3; nullopt when the null space
// is not one-dimensional.
std::optional<Eigen::Matrix3d> NullVector3x3(const Eigen::Matrix<double, Eigen::Dynamic, 9>& A) {
  const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 9>> svd(A, Eigen::ComputeFullV);
  const auto& sv = svd.singularValues();
  if (!(sv(0) > 0.0) || sv(7) < kDegenerateSvRatio * sv(0)) return std::nullopt;
  const Eigen::Matrix<double, 9, 1> h = svd.matrixV().col(8);
  Eigen::Matrix3d M;
  M << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  if (!M.allFinite()) return std::nullopt;
  return M;
}

// DLT for to ~ H from on the (normalised) points idx.
std::optional<Eigen::Matrix3d> SolveHomography(const Points& from, const Points& to,
                                               const std::vector<int>& idx) {
  Eigen::Matrix<double, Eigen::Dynamic, 9> A(2 * idx.size(), 9);
  for (size_t k = 0; k < idx.size(); ++k) {
    const double x = from[idx[k]].x(), y = from[idx[k]].y();
    const double u = to[idx[k]].x(), v = to[idx[k]].y();
    A.row(2 * k) << x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u;
    A.row(2 * k + 1) << 0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v;
  }
  return NullVector3x3(A);
}

// 8-point system for cur^T F ref = 0 on the (normalised) points idx, rank 2 enforced.
std::optional<Eigen::Matrix3d> SolveFundamental(const Points& ref, const Points& cur,
                                                const std::vector<int>& idx) {
  Eigen::Matrix<double, Eigen::Dynamic, 9> A(idx.size(), 9);
  for (size_t k = 0; k < idx.size(); ++k) {
    const double x = ref[idx[k]].x(), y = ref[idx[k]].y();
    const double u = cur[idx[k]].x(), v = cur[idx[k]].y();
    A.row(k) << u * x, u * y, u, v * x, v * y, v, x, y, 1.0;
  }
  const auto F = NullVector3x3(A);
  if (!F) return std::nullopt;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(*F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sv = svd.singularValues();
  sv(2) = 0.0;
  return Eigen::Matrix3d(svd.matrixU() * sv.asDiagonal() * svd.matrixV().transpose());
}

// Pixel-space model from a model estimated on normalised points.
Eigen::Matrix3d DenormaliseHomography(const Eigen::Matrix3d& Hn, const Eigen::Matrix3d& T_from,
                                      const Eigen::Matrix3d& T_to) {
  const Eigen::Matrix3d H = T_to.inverse() * Hn * T_from;
  return H / H.norm();
}

Eigen::Matrix3d DenormaliseFundamental(const Eigen::Matrix3d& Fn, const Eigen::Matrix3d& T_ref,
                                       const Eigen::Matrix3d& T_cur) {
  const Eigen::Matrix3d F = T_cur.transpose() * Fn * T_ref;
  return F / F.norm();
}

// Symmetric transfer score of H (cur ~ H ref). Fills inliers; returns the score (0 when H is
// singular).
double ScoreHomography(const Eigen::Matrix3d& H, const Points& ref, const Points& cur,
                       const TwoViewOptions& opt, std::vector<bool>* inliers) {
  inliers->assign(ref.size(), false);
  Eigen::FullPivLU<Eigen::Matrix3d> lu(H);
  if (!lu.isInvertible()) return 0.0;
  const Eigen::Matrix3d H_inv = lu.inverse();
  const double inv_sigma2 = 1.0 / (opt.sigma_px * opt.sigma_px);
  double score = 0.0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const Eigen::Vector3d in_cur = H * ref[i].homogeneous();
    const Eigen::Vector3d in_ref = H_inv * cur[i].homogeneous();
    if (in_cur.z() == 0.0 || in_ref.z() == 0.0) continue;
    const double chi2_cur = (in_cur.hnormalized() - cur[i]).squaredNorm() * inv_sigma2;
    if (!(chi2_cur <= opt.homography_chi2)) continue;
    const double chi2_ref = (in_ref.hnormalized() - ref[i]).squaredNorm() * inv_sigma2;
    if (!(chi2_ref <= opt.homography_chi2)) continue;
    (*inliers)[i] = true;
    score += (opt.score_chi2 - chi2_cur) + (opt.score_chi2 - chi2_ref);
  }
  return score;
}

// Symmetric point-to-epipolar-line score of F (cur^T F ref = 0).
double ScoreFundamental(const Eigen::Matrix3d& F, const Points& ref, const Points& cur,
                        const TwoViewOptions& opt, std::vector<bool>* inliers) {
  inliers->assign(ref.size(), false);
  const double inv_sigma2 = 1.0 / (opt.sigma_px * opt.sigma_px);
  double score = 0.0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const Eigen::Vector3d x_ref = ref[i].homogeneous();
    const Eigen::Vector3d x_cur = cur[i].homogeneous();
    const Eigen::Vector3d line_cur = F * x_ref;  // epipolar line of x_ref in the current image
    const Eigen::Vector3d line_ref = F.transpose() * x_cur;
    const double n_cur = line_cur.head<2>().squaredNorm();
    const double n_ref = line_ref.head<2>().squaredNorm();
    if (!(n_cur > 0.0) || !(n_ref > 0.0)) continue;
    const double residual = x_cur.dot(line_cur);  // equals x_ref.dot(line_ref)
    const double chi2_cur = residual * residual / n_cur * inv_sigma2;
    if (!(chi2_cur <= opt.fundamental_chi2)) continue;
    const double chi2_ref = residual * residual / n_ref * inv_sigma2;
    if (!(chi2_ref <= opt.fundamental_chi2)) continue;
    (*inliers)[i] = true;
    score += (opt.score_chi2 - chi2_cur) + (opt.score_chi2 - chi2_ref);
  }
  return score;
}

struct ModelFit {
  bool valid = false;
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();  // pixel-space model
  double score = 0.0;
  std::vector<bool> inliers;
};

std::vector<int> InlierIndices(const std::vector<bool>& inliers) {
  std::vector<int> idx;
  for (size_t i = 0; i < inliers.size(); ++i) {
    if (inliers[i]) idx.push_back(static_cast<int>(i));
  }
  return idx;
}

// Motion hypothesis evaluated by triangulating the inliers of the chosen model.
struct Candidate {
  SE3 cur_from_ref = SE3::Identity();
  // Correspondences the motion explains: reprojection within bounds and either in front of both
  // cameras or with a parallax too small for the depth sign to mean anything.
  int support = 0;
  // Of those, the ones in front of both cameras with parallax (the triangulated points).
  int num_good = 0;
  std::vector<bool> explained;  // per correspondence, the ones counted in support
  std::vector<std::optional<Eigen::Vector3d>> points;
  std::vector<double> parallax_deg;  // of the good points
};

Candidate EvaluateMotion(const PinholeCamera& camera, const SE3& cur_from_ref, const Points& ref,
                         const Points& cur, const std::vector<bool>& inliers,
                         const TwoViewOptions& opt) {
  Candidate c;
  c.cur_from_ref = cur_from_ref;
  c.points.assign(ref.size(), std::nullopt);
  c.explained.assign(ref.size(), false);
  const Matrix34d P_ref = ProjectionMatrix(camera, SE3::Identity());
  const Matrix34d P_cur = ProjectionMatrix(camera, cur_from_ref);
  const double max_err2 = opt.reprojection_chi2 * opt.sigma_px * opt.sigma_px;
  const Eigen::Vector3d centre_cur =
      -cur_from_ref.linear().transpose() * cur_from_ref.translation();
  for (size_t i = 0; i < ref.size(); ++i) {
    if (!inliers[i]) continue;
    Eigen::Vector3d p;
    if (!TriangulateDlt(P_ref, P_cur, ref[i], cur[i], &p)) {
      ++c.support;  // parallel rays: consistent with the rotation, no depth information
      c.explained[i] = true;
      continue;
    }
    // Reprojection through the homogeneous projection is valid for points behind a camera too.
    const Eigen::Vector3d h_ref = P_ref * p.homogeneous();
    const Eigen::Vector3d h_cur = P_cur * p.homogeneous();
    if ((h_ref.hnormalized() - ref[i]).squaredNorm() > max_err2 ||
        (h_cur.hnormalized() - cur[i]).squaredNorm() > max_err2) {
      continue;
    }
    const Eigen::Vector3d ray_cur = p - centre_cur;
    const double cos_parallax = std::clamp(p.dot(ray_cur) / (p.norm() * ray_cur.norm()), -1.0, 1.0);
    const bool low_parallax = !(cos_parallax < opt.point_max_cos_parallax);
    const bool in_front = h_ref.z() > 0.0 && h_cur.z() > 0.0;
    if (!in_front && !low_parallax) continue;
    ++c.support;
    c.explained[i] = true;
    if (in_front && !low_parallax) {
      c.parallax_deg.push_back(RadToDeg(std::acos(cos_parallax)));
      c.points[i] = p;
      ++c.num_good;
    }
  }
  return c;
}

// Sampson distances (pixels) of the correspondences idx to the epipolar geometry of motion
// cur_from_ref.
Eigen::VectorXd SampsonResiduals(const Eigen::Matrix3d& K_inv, const Eigen::Matrix3d& R,
                                 const Eigen::Vector3d& t, const Points& ref, const Points& cur,
                                 const std::vector<int>& idx) {
  const Eigen::Matrix3d F = K_inv.transpose() * Skew(t) * R * K_inv;
  Eigen::VectorXd r(idx.size());
  for (size_t k = 0; k < idx.size(); ++k) {
    const Eigen::Vector3d x_ref = ref[idx[k]].homogeneous();
    const Eigen::Vector3d x_cur = cur[idx[k]].homogeneous();
    const Eigen::Vector3d l_cur = F * x_ref;
    const Eigen::Vector3d l_ref = F.transpose() * x_cur;
    const double den = l_cur.head<2>().squaredNorm() + l_ref.head<2>().squaredNorm();
    r(k) = den > 0.0 ? x_cur.dot(l_cur) / std::sqrt(den) : 0.0;
  }
  return r;
}

// Levenberg-Marquardt on the 5-dof relative motion (rotation, unit translation direction),
// minimising the squared Sampson distances of the correspondences idx.
SE3 RefineMotionSampson(const PinholeCamera& camera, const SE3& cur_from_ref, const Points& ref,
                        const Points& cur, const std::vector<int>& idx, int max_iterations) {
  const Eigen::Matrix3d K_inv = IntrinsicMatrix(camera).inverse();
  Eigen::Matrix3d R = cur_from_ref.linear();
  Eigen::Vector3d t = cur_from_ref.translation().normalized();
  using Vector5d = Eigen::Matrix<double, 5, 1>;
  auto apply = [](const Eigen::Matrix3d& R0, const Eigen::Vector3d& t0, const Vector5d& delta,
                  Eigen::Matrix3d* R1, Eigen::Vector3d* t1) {
    // Tangent basis of the unit sphere at t0.
    const Eigen::Vector3d helper =
        std::abs(t0.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d b1 = t0.cross(helper).normalized();
    const Eigen::Vector3d b2 = t0.cross(b1);
    *R1 = ExpSO3(delta.head<3>()) * R0;
    *t1 = (t0 + delta(3) * b1 + delta(4) * b2).normalized();
  };
  Eigen::VectorXd r = SampsonResiduals(K_inv, R, t, ref, cur, idx);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  constexpr double kStep = 1e-7;
  for (int it = 0; it < max_iterations; ++it) {
    Eigen::MatrixXd J(r.size(), 5);
    for (int j = 0; j < 5; ++j) {
      Vector5d d = Vector5d::Zero();
      Eigen::Matrix3d Rp, Rm;
      Eigen::Vector3d tp, tm;
      d(j) = kStep;
      apply(R, t, d, &Rp, &tp);
      d(j) = -kStep;
      apply(R, t, d, &Rm, &tm);
      J.col(j) = (SampsonResiduals(K_inv, Rp, tp, ref, cur, idx) -
                  SampsonResiduals(K_inv, Rm, tm, ref, cur, idx)) /
                 (2.0 * kStep);
    }
    const Eigen::Matrix<double, 5, 5> JtJ = J.transpose() * J;
    const Vector5d g = J.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::Matrix<double, 5, 5> A = JtJ;
      A.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
      const Vector5d delta = A.ldlt().solve(-g);
      Eigen::Matrix3d R_new;
      Eigen::Vector3d t_new;
      apply(R, t, delta, &R_new, &t_new);
      const Eigen::VectorXd r_new = SampsonResiduals(K_inv, R_new, t_new, ref, cur, idx);
      const double cost_new = r_new.squaredNorm();
      if (std::isfinite(cost_new) && cost_new < cost) {
        improved = true;
        const bool converged = cost - cost_new < 1e-10 * cost;
        R = R_new;
        t = t_new;
        r = r_new;
        cost = cost_new;
        lambda = std::max(1e-9, lambda * 0.1);
        if (converged) it = max_iterations;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  // Re-orthonormalise the rotation against accumulated round-off.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  SE3 out = SE3::Identity();
  out.linear() = svd.matrixU() * svd.matrixV().transpose();
  out.translation() = t;
  return out;
}

// Parallax (degrees) reached by the k-th most parallax good point (k = min_triangulated, or the
// last one when there are fewer).
double ParallaxStatisticDeg(std::vector<double> parallax_deg, int min_triangulated) {
  if (parallax_deg.empty()) return 0.0;
  const size_t k = std::min<size_t>(min_triangulated, parallax_deg.size()) - 1;
  std::nth_element(parallax_deg.begin(), parallax_deg.begin() + k, parallax_deg.end(),
                   std::greater<double>());
  return parallax_deg[k];
}

std::vector<SE3> HomographyMotions(const Eigen::Matrix3d& H, const PinholeCamera& camera) {
  cv::Matx33d H_cv, K_cv;
  const Eigen::Matrix3d K = IntrinsicMatrix(camera);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      H_cv(r, c) = H(r, c);
      K_cv(r, c) = K(r, c);
    }
  }
  std::vector<cv::Mat> rotations, translations, normals;
  cv::decomposeHomographyMat(H_cv, K_cv, rotations, translations, normals);
  std::vector<SE3> motions;
  for (size_t s = 0; s < rotations.size(); ++s) {
    SE3 motion = PoseFromCvRotation(rotations[s], translations[s]);
    // t is the translation over the plane distance; zero for a pure rotation, which leaves no
    // baseline to triangulate with.
    const double t_norm = motion.translation().norm();
    if (!(t_norm > 1e-12) || !motion.linear().allFinite()) continue;
    motion.translation() /= t_norm;
    // When the translation is parallel to the plane normal the two decompositions coincide;
    // keep one copy so that a duplicate does not pass for an ambiguity.
    const bool duplicate = std::any_of(motions.begin(), motions.end(), [&](const SE3& m) {
      return RotationDistanceRad(m.linear(), motion.linear()) < 1e-6 &&
             (m.translation() - motion.translation()).norm() < 1e-6;
    });
    if (!duplicate) motions.push_back(motion);
  }
  return motions;
}

std::string Format(const char* prefix, double value, const char* suffix) {
  std::ostringstream os;
  os.precision(3);
  os << prefix << value << suffix;
  return os.str();
}

}  // namespace

bool TwoViewOptions::IsValid(std::string* why) const {
  auto fail = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (ransac_iterations < 1) return fail("ransac_iterations must be >= 1");
  if (!(sigma_px > 0.0)) return fail("sigma_px must be > 0");
  if (!(homography_chi2 > 0.0) || !(fundamental_chi2 > 0.0) || !(score_chi2 > 0.0)) {
    return fail("chi2 thresholds must be > 0");
  }
  if (score_chi2 < homography_chi2 || score_chi2 < fundamental_chi2) {
    return fail("score_chi2 must be >= the inlier thresholds (scores must stay positive)");
  }
  if (!(homography_ratio_threshold >= 0.0 && homography_ratio_threshold <= 1.0)) {
    return fail("homography_ratio_threshold must be in [0, 1]");
  }
  if (refine_iterations < 0) return fail("refine_iterations must be >= 0");
  if (!(reprojection_chi2 > 0.0)) return fail("reprojection_chi2 must be > 0");
  if (!(point_max_cos_parallax > 0.0 && point_max_cos_parallax <= 1.0)) {
    return fail("point_max_cos_parallax must be in (0, 1]");
  }
  if (min_triangulated < 1) return fail("min_triangulated must be >= 1");
  if (!(min_parallax_deg >= 0.0 && min_parallax_deg < 90.0)) {
    return fail("min_parallax_deg must be in [0, 90)");
  }
  if (!(max_second_best_ratio > 0.0 && max_second_best_ratio <= 1.0)) {
    return fail("max_second_best_ratio must be in (0, 1]");
  }
  return true;
}

std::optional<Eigen::Matrix3d> EstimateHomography(const Points& from, const Points& to) {
  if (from.size() != to.size() || from.size() < kHomographySample) return std::nullopt;
  const Eigen::Matrix3d T_from = NormalizingTransform(from);
  const Eigen::Matrix3d T_to = NormalizingTransform(to);
  std::vector<int> idx(from.size());
  std::iota(idx.begin(), idx.end(), 0);
  const auto Hn = SolveHomography(Transform(T_from, from), Transform(T_to, to), idx);
  if (!Hn) return std::nullopt;
  return DenormaliseHomography(*Hn, T_from, T_to);
}

std::optional<Eigen::Matrix3d> EstimateFundamental(const Points& ref, const Points& cur) {
  if (ref.size() != cur.size() || ref.size() < kFundamentalSample) return std::nullopt;
  const Eigen::Matrix3d T_ref = NormalizingTransform(ref);
  const Eigen::Matrix3d T_cur = NormalizingTransform(cur);
  std::vector<int> idx(ref.size());
  std::iota(idx.begin(), idx.end(), 0);
  const auto Fn = SolveFundamental(Transform(T_ref, ref), Transform(T_cur, cur), idx);
  if (!Fn) return std::nullopt;
  return DenormaliseFundamental(*Fn, T_ref, T_cur);
}

std::vector<SE3> DecomposeEssential(const Eigen::Matrix3d& E) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  Eigen::Matrix3d V = svd.matrixV();
  // E is defined up to sign, so U and V may be flipped to make both proper rotations.
  if (U.determinant() < 0.0) U = -U;
  if (V.determinant() < 0.0) V = -V;
  Eigen::Matrix3d W;
  W << 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  const Eigen::Matrix3d R_a = U * W * V.transpose();
  const Eigen::Matrix3d R_b = U * W.transpose() * V.transpose();
  const Eigen::Vector3d t = U.col(2).normalized();
  std::vector<SE3> motions;
  for (const Eigen::Matrix3d* R : {&R_a, &R_b}) {
    for (double sign : {1.0, -1.0}) {
      SE3 m = SE3::Identity();
      m.linear() = *R;
      m.translation() = sign * t;
      motions.push_back(m);
    }
  }
  return motions;
}

TwoViewResult InitializeTwoView(const PinholeCamera& camera, const Points& uv_ref,
                                const Points& uv_cur, const TwoViewOptions& options) {
  std::string why;
  if (uv_ref.size() != uv_cur.size()) {
    throw std::invalid_argument("InitializeTwoView: uv_ref and uv_cur differ in size");
  }
  if (!camera.IsValid(&why)) throw std::invalid_argument("InitializeTwoView: camera: " + why);
  if (!options.IsValid(&why)) throw ConfigError("TwoViewOptions: " + why);
  // One non-finite point would make the shared normalising transforms NaN and fail every model
  // with a misleading reason; the extractor never gives one, so it is a caller's error.
  for (size_t i = 0; i < uv_ref.size(); ++i) {
    if (!uv_ref[i].allFinite() || !uv_cur[i].allFinite()) {
      throw std::invalid_argument("InitializeTwoView: correspondence " + std::to_string(i) +
                                  " is not finite");
    }
  }

  const size_t n = uv_ref.size();
  TwoViewResult result;
  result.points_in_ref.assign(n, std::nullopt);
  result.inliers.assign(n, false);
  if (n < static_cast<size_t>(std::max(kFundamentalSample, options.min_triangulated))) {
    result.failure_reason = "too few correspondences (" + std::to_string(n) + ")";
    return result;
  }

  // RANSAC on shared minimal samples; models are solved in normalised coordinates.
  const Eigen::Matrix3d T_ref = NormalizingTransform(uv_ref);
  const Eigen::Matrix3d T_cur = NormalizingTransform(uv_cur);
  const Points n_ref = Transform(T_ref, uv_ref);
  const Points n_cur = Transform(T_cur, uv_cur);

  std::mt19937_64 rng(options.seed);
  std::vector<int> pool(n);
  std::iota(pool.begin(), pool.end(), 0);
  std::vector<int> sample_h(kHomographySample), sample_f(kFundamentalSample);
  ModelFit best_h, best_f;
  std::vector<bool> mask;
  for (int it = 0; it < options.ransac_iterations; ++it) {
    // Partial Fisher-Yates: the first 8 entries of pool become a fresh sample without repeats.
    for (int k = 0; k < kFundamentalSample; ++k) {
      const size_t j = k + static_cast<size_t>(rng() % (n - k));
      std::swap(pool[k], pool[j]);
      sample_f[k] = pool[k];
    }
    std::copy_n(sample_f.begin(), kHomographySample, sample_h.begin());
    if (const auto Hn = SolveHomography(n_ref, n_cur, sample_h)) {
      const Eigen::Matrix3d H = DenormaliseHomography(*Hn, T_ref, T_cur);
      const double score = ScoreHomography(H, uv_ref, uv_cur, options, &mask);
      if (!best_h.valid || score > best_h.score) best_h = {true, H, score, mask};
    }
    if (const auto Fn = SolveFundamental(n_ref, n_cur, sample_f)) {
      const Eigen::Matrix3d F = DenormaliseFundamental(*Fn, T_ref, T_cur);
      const double score = ScoreFundamental(F, uv_ref, uv_cur, options, &mask);
      if (!best_f.valid || score > best_f.score) best_f = {true, F, score, mask};
    }
  }

  // Least-squares refits on the inliers, kept while they raise the score.
  for (int r = 0; r < options.refine_iterations && best_h.valid; ++r) {
    const std::vector<int> idx = InlierIndices(best_h.inliers);
    if (idx.size() < kHomographySample) break;
    const auto Hn = SolveHomography(n_ref, n_cur, idx);
    if (!Hn) break;
    const Eigen::Matrix3d H = DenormaliseHomography(*Hn, T_ref, T_cur);
    const double score = ScoreHomography(H, uv_ref, uv_cur, options, &mask);
    if (score <= best_h.score) break;
    best_h = {true, H, score, mask};
  }
  for (int r = 0; r < options.refine_iterations && best_f.valid; ++r) {
    const std::vector<int> idx = InlierIndices(best_f.inliers);
    if (idx.size() < kFundamentalSample) break;
    const auto Fn = SolveFundamental(n_ref, n_cur, idx);
    if (!Fn) break;
    const Eigen::Matrix3d F = DenormaliseFundamental(*Fn, T_ref, T_cur);
    const double score = ScoreFundamental(F, uv_ref, uv_cur, options, &mask);
    if (score <= best_f.score) break;
    best_f = {true, F, score, mask};
  }

  result.score_homography = best_h.valid ? best_h.score : 0.0;
  result.score_fundamental = best_f.valid ? best_f.score : 0.0;
  const double total = result.score_homography + result.score_fundamental;
  if (!(total > 0.0)) {
    result.failure_reason = "neither a homography nor a fundamental matrix fits the matches";
    return result;
  }
  result.homography_ratio = result.score_homography / total;
  result.used_homography = result.homography_ratio > options.homography_ratio_threshold;
  const ModelFit& model = result.used_homography ? best_h : best_f;
  result.inliers = model.inliers;
  result.num_inliers =
      static_cast<int>(std::count(model.inliers.begin(), model.inliers.end(), true));

  std::vector<SE3> motions;
  if (result.used_homography) {
    motions = HomographyMotions(model.M, camera);
  } else {
    const Eigen::Matrix3d K = IntrinsicMatrix(camera);
    motions = DecomposeEssential(K.transpose() * model.M * K);
  }
  if (motions.empty()) {
    result.failure_reason = "no parallax: the homography is a pure rotation";
    return result;
  }

  std::vector<Candidate> candidates;
  for (const SE3& m : motions) {
    candidates.push_back(EvaluateMotion(camera, m, uv_ref, uv_cur, model.inliers, options));
  }
  // The best motion explains the most correspondences; ties go to the one with more parallax
  // points.
  std::stable_sort(
      candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
        return a.support != b.support ? a.support > b.support : a.num_good > b.num_good;
      });
  Candidate& best = candidates.front();
  // A runner-up is a real alternative when it explains nearly as many correspondences: the
  // points it loses must amount to at least (1 - max_second_best_ratio) of the best motion's
  // triangulated points. With no low-parallax points this is "second < ratio * best".
  int runner_up_support = 0;
  for (size_t c = 1; c < candidates.size(); ++c) {
    runner_up_support = std::max(runner_up_support, candidates[c].support);
  }
  result.num_triangulated = best.num_good;
  result.best_support = best.support;
  result.runner_up_support = runner_up_support;
  const double point_min_parallax_deg =
      RadToDeg(std::acos(std::clamp(options.point_max_cos_parallax, -1.0, 1.0)));

  if (best.num_good == 0) {
    result.failure_reason =
        Format("no parallax: no point triangulated with parallax above ", point_min_parallax_deg,
               " deg (pure rotation or too short a baseline)");
    return result;
  }
  result.parallax_deg = ParallaxStatisticDeg(best.parallax_deg, options.min_triangulated);
  if (best.num_good < options.min_triangulated) {
    result.failure_reason = "only " + std::to_string(best.num_good) +
                            " points triangulated with parallax (need " +
                            std::to_string(options.min_triangulated) + ")";
    return result;
  }
  if (result.parallax_deg < options.min_parallax_deg) {
    result.failure_reason = Format("insufficient parallax: ", result.parallax_deg, " deg < ") +
                            Format("", options.min_parallax_deg, " deg");
    return result;
  }
  if (static_cast<double>(best.support - runner_up_support) <
      (1.0 - options.max_second_best_ratio) * best.num_good) {
    result.failure_reason = "ambiguous motion: runner-up explains " +
                            std::to_string(runner_up_support) + " correspondences against " +
                            std::to_string(best.support) + " (" + std::to_string(best.num_good) +
                            " triangulated)";
    return result;
  }

  if (options.refine_motion && !result.used_homography) {
    // Polish the essential-matrix motion on the correspondences it explains, re-select the
    // inliers against the polished epipolar geometry (recovering those a rough RANSAC model
    // missed) and repeat until the inlier set settles.
    const Eigen::Matrix3d K_inv = IntrinsicMatrix(camera).inverse();
    Candidate current = best;
    std::vector<bool> current_inliers = model.inliers;
    for (int round = 0; round < 4; ++round) {
      std::vector<int> idx = InlierIndices(current.explained);
      if (idx.size() < kFundamentalSample) break;
      const SE3 refined =
          RefineMotionSampson(camera, current.cur_from_ref, uv_ref, uv_cur, idx, 20);
      const Eigen::Matrix3d F =
          K_inv.transpose() * Skew(refined.translation()) * refined.linear() * K_inv;
      ScoreFundamental(F, uv_ref, uv_cur, options, &mask);
      Candidate next = EvaluateMotion(camera, refined, uv_ref, uv_cur, mask, options);
      if (next.num_good < options.min_triangulated ||
          ParallaxStatisticDeg(next.parallax_deg, options.min_triangulated) <
              options.min_parallax_deg) {
        break;  // keep the last motion that passed the checks
      }
      const bool settled = mask == current_inliers;
      current = std::move(next);
      current_inliers = mask;
      if (settled) break;
    }
    best = std::move(current);
    result.inliers = current_inliers;
    result.num_inliers =
        static_cast<int>(std::count(result.inliers.begin(), result.inliers.end(), true));
    result.num_triangulated = best.num_good;
    result.best_support = best.support;
    result.parallax_deg = ParallaxStatisticDeg(best.parallax_deg, options.min_triangulated);
  }

  result.success = true;
  result.cur_from_ref = best.cur_from_ref;
  result.points_in_ref = std::move(best.points);
  return result;
}

}  // namespace pcr
