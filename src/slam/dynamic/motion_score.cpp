#include "slam/dynamic/motion_score.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/video/tracking.hpp>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/validation.h"
#include "slam/geometry/cv_pose.h"
#include "slam/geometry/se3.h"

namespace pcr {
namespace {

// d(pixel)/d(point) of the pinhole projection at p (p.z() > 0).
Eigen::Matrix<double, 2, 3> ProjectionJacobian(const PinholeCamera& camera,
                                               const Eigen::Vector3d& p) {
  const double inv_z = 1.0 / p.z();
  Eigen::Matrix<double, 2, 3> j;
  j << camera.fx * inv_z, 0.0, -camera.fx * p.x() * inv_z * inv_z,  //
      0.0, camera.fy * inv_z, -camera.fy * p.y() * inv_z * inv_z;
  return j;
}

// Pixel covariance of the projection of p under the camera-motion uncertainty (small rotation
// and translation perturbations of prev_from_cur, applied on the left).
template <int kRows>
Eigen::Matrix<double, kRows, kRows> PoseCovariance(const Eigen::Matrix<double, kRows, 3>& j,
                                                   const Eigen::Vector3d& p,
                                                   const PoseSigma& sigma) {
  const Eigen::Matrix3d skew = Skew(p);
  const Eigen::Matrix3d cov3 =
      sigma.translation_m * sigma.translation_m * Eigen::Matrix3d::Identity() +
      sigma.rotation_rad * sigma.rotation_rad * skew * skew.transpose();
  return j * cov3 * j.transpose();
}

template <int kRows>
double Mahalanobis2(const Eigen::Matrix<double, kRows, 1>& r,
                    const Eigen::Matrix<double, kRows, kRows>& cov) {
  const double det = cov.determinant();
  if (!(det > 1e-18)) return r.squaredNorm() / std::max(cov.trace() / kRows, 1e-9);
  return r.dot(cov.inverse() * r);
}

// Observability of a displacement whose effect on the measurement is `shift`, against the
// prediction covariance: |shift| in units of observability_sigmas standard deviations along it.
template <int kRows>
double Observability(const Eigen::Matrix<double, kRows, 1>& shift,
                     const Eigen::Matrix<double, kRows, kRows>& cov,
                     const MotionScoreOptions& options) {
  const double norm = shift.norm();
  if (!(norm > 1e-9)) return 0.0;
  const Eigen::Matrix<double, kRows, 1> dir = shift / norm;
  const double sigma_dir = std::sqrt(std::max(dir.dot(cov * dir), 1e-12));
  return std::clamp(norm / (options.observability_sigmas * sigma_dir), 0.0, 1.0);
}

// Covariance of the depth test's measurement about its static prediction (kRows = 2: the
// previous pixel; 3: and the previous disparity). j: projection (and disparity) Jacobian at
// p_prev = r p_cur + t; the previous measurement's own noise, the current pixel and depth noise
// carried through the prediction, and the pose uncertainty.
template <int kRows>
Eigen::Matrix<double, kRows, kRows> DepthTestCovariance(
    const Eigen::Matrix<double, kRows, 3>& j, const Eigen::Matrix3d& r,
    const Eigen::Matrix<double, 3, 2>& d_point_d_uv, const Eigen::Vector3d& ray, double sigma_z,
    const Eigen::Vector3d& p_prev, const PoseSigma& pose_sigma, const PointNoise& noise) {
  const Eigen::Matrix<double, kRows, 3> jr = j * r;
  const Eigen::Matrix<double, kRows, 2> j_uv = jr * d_point_d_uv;
  const Eigen::Matrix<double, kRows, 1> j_z = jr * ray;
  Eigen::Matrix<double, kRows, kRows> measured = Eigen::Matrix<double, kRows, kRows>::Zero();
  measured(0, 0) = measured(1, 1) = noise.prev_sigma_px * noise.prev_sigma_px;
  if constexpr (kRows == 3) measured(2, 2) = noise.disparity_sigma_px * noise.disparity_sigma_px;
  return measured + noise.cur_sigma_px * noise.cur_sigma_px * j_uv * j_uv.transpose() +
         sigma_z * sigma_z * j_z * j_z.transpose() + PoseCovariance<kRows>(j, p_prev, pose_sigma);
}

}  // namespace

bool LkOptions::IsValid(std::string* why) const {
  if (window_px < 5 || window_px % 2 == 0) return Fail(why, "window_px must be odd and >= 5");
  if (max_level < 0 || max_level > 8) return Fail(why, "max_level must be in [0, 8]");
  if (max_iterations < 1) return Fail(why, "max_iterations must be >= 1");
  if (!(epsilon_px > 0.0)) return Fail(why, "epsilon_px must be > 0");
  if (!(min_eigen_threshold >= 0.0)) return Fail(why, "min_eigen_threshold must be >= 0");
  if (!(max_forward_backward_px > 0.0)) return Fail(why, "max_forward_backward_px must be > 0");
  if (refine_max_level < 0) return Fail(why, "refine_max_level must be >= 0");
  if (!(guess_accept_error_factor >= 0.0)) return Fail(why, "guess_accept_error_factor >= 0");
  if (!(guess_error_ratio >= 1.0 && guess_error_slack >= 0.0)) {
    return Fail(why, "guess_error_ratio must be >= 1 and guess_error_slack >= 0");
  }
  return true;
}

bool EgoMotionOptions::IsValid(std::string* why) const {
  if (!(ransac_reprojection_px > 0.0)) return Fail(why, "ransac_reprojection_px must be > 0");
  if (ransac_iterations < 1) return Fail(why, "ransac_iterations must be >= 1");
  if (!(ransac_confidence > 0.0 && ransac_confidence < 1.0)) {
    return Fail(why, "ransac_confidence must be in (0, 1)");
  }
  if (min_inliers < 6) return Fail(why, "min_inliers must be >= 6");
  if (!(min_inlier_ratio >= 0.0 && min_inlier_ratio <= 1.0)) {
    return Fail(why, "min_inlier_ratio must be in [0, 1]");
  }
  if (!(min_depth_m > 0.0 && max_depth_m > min_depth_m)) {
    return Fail(why, "depth window must satisfy 0 < min_depth_m < max_depth_m");
  }
  return true;
}

bool MotionScoreOptions::IsValid(std::string* why) const {
  if (!(disparity_sigma_px > 0.0)) return Fail(why, "disparity_sigma_px must be > 0");
  for (const PoseSigma* s : {&prior_pose, &pnp_pose}) {
    if (!(s->rotation_rad >= 0.0 && s->translation_m >= 0.0)) {
      return Fail(why, "pose sigmas must be >= 0");
    }
  }
  if (!(chi2_mid_2dof > 0.0 && chi2_mid_1dof > 0.0 && chi2_mid_3dof > 0.0))
    return Fail(why, "chi2 mids must be > 0");
  if (!(chi2_width > 0.0)) return Fail(why, "chi2_width must be > 0");
  if (!(reference_speed_mps > 0.0)) return Fail(why, "reference_speed_mps must be > 0");
  if (!(observability_sigmas > 0.0)) return Fail(why, "observability_sigmas must be > 0");
  if (!(min_translation_m >= 0.0)) return Fail(why, "min_translation_m must be >= 0");
  return true;
}

std::vector<cv::Mat> BuildLkPyramid(const cv::Mat& gray, const LkOptions& options) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw std::invalid_argument("BuildLkPyramid: image must be a non-empty CV_8UC1");
  }
  std::vector<cv::Mat> pyramid;
  cv::buildOpticalFlowPyramid(gray, pyramid, cv::Size(options.window_px, options.window_px),
                              options.max_level, /*withDerivatives=*/true);
  return pyramid;
}

FlowTracks TrackIntoPrevious(const std::vector<cv::Mat>& prev_pyramid,
                             const std::vector<cv::Mat>& cur_pyramid,
                             const std::vector<cv::Point2f>& cur_uv_px, const LkOptions& options,
                             const std::vector<cv::Point2f>& initial_prev_uv_px,
                             FlowEngine* engine) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("LkOptions: " + why);
  FlowTracks tracks;
  const size_t n = cur_uv_px.size();
  tracks.prev_uv_px.assign(n, cv::Point2f(-1.0f, -1.0f));
  tracks.valid.assign(n, 0);
  tracks.forward_backward_px.assign(n, -1.0f);
  if (n == 0 || prev_pyramid.empty() || cur_pyramid.empty()) return tracks;
  if (prev_pyramid[0].size() != cur_pyramid[0].size()) {
    throw std::invalid_argument("TrackIntoPrevious: pyramids of different image sizes");
  }
  std::unique_ptr<FlowEngine> opencv;
  if (!engine) {
    opencv = MakeOpenCvFlowEngine();
    engine = opencv.get();
  }
  // cv::buildOpticalFlowPyramid stops early once a level would be no larger than the window,
  // so a pyramid can hold fewer levels than options.max_level asks for; cv::calcOpticalFlowPyrLK
  // quietly uses what there is, and every engine is given no more (the pyramids hold each level
  // with its derivatives).
  const int top_level =
      std::min(options.max_level,
               static_cast<int>(std::min(prev_pyramid.size(), cur_pyramid.size()) / 2) - 1);
  if (top_level < 0) throw std::invalid_argument("TrackIntoPrevious: a pyramid without levels");
  LkPass pass;
  pass.window_px = options.window_px;
  pass.max_iterations = options.max_iterations;
  pass.epsilon_px = options.epsilon_px;
  pass.min_eigen_threshold = options.min_eigen_threshold;
  if (!initial_prev_uv_px.empty() && initial_prev_uv_px.size() != n) {
    throw std::invalid_argument("TrackIntoPrevious: one initial guess per point");
  }
  const cv::Size size = prev_pyramid[0].size();
  auto inside = [&size](const cv::Point2f& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && p.x >= 0.0f && p.y >= 0.0f &&
           p.x <= size.width - 1.0f && p.y <= size.height - 1.0f;
  };
  std::vector<cv::Point2f> prev_uv(n, cv::Point2f(-1.0f, -1.0f));
  std::vector<uint8_t> status(n, 0);
  std::vector<float> error;
  std::vector<uint8_t> search_zero(n, 1);
  std::vector<float> guess_error;
  tracks.from_guess.assign(n, 0);
  if (!initial_prev_uv_px.empty()) {
    // Search from the guess on the fine levels. Where its match is as good as most matches of
    // the frame (error within guess_accept_error_factor x the median), it stands without the
    // zero-flow search; elsewhere it wins unless that search's match is clearly better.
    std::vector<cv::Point2f> guess_start, guess_uv;
    std::vector<size_t> guess_index;
    for (size_t i = 0; i < n; ++i) {
      if (!inside(initial_prev_uv_px[i])) continue;  // (-1, -1): no guess for this point
      guess_start.push_back(cur_uv_px[i]);
      guess_uv.push_back(initial_prev_uv_px[i]);
      guess_index.push_back(i);
    }
    guess_error.assign(n, 0.0f);
    std::vector<float> good_errors;
    if (!guess_start.empty()) {
      std::vector<uint8_t> guess_status;
      std::vector<float> errors;
      pass.max_level = std::min(options.refine_max_level, top_level);
      pass.use_initial_flow = true;
      engine->Track(cur_pyramid, prev_pyramid, guess_start, guess_uv, guess_status, errors, pass);
      for (size_t k = 0; k < guess_index.size(); ++k) {
        if (!guess_status[k] || !inside(guess_uv[k])) continue;
        const size_t i = guess_index[k];
        prev_uv[i] = guess_uv[k];
        status[i] = 1;
        guess_error[i] = errors[k];
        tracks.from_guess[i] = 1;
        good_errors.push_back(errors[k]);
      }
    }
    if (options.guess_accept_error_factor > 0.0 && !good_errors.empty()) {
      const size_t mid = good_errors.size() / 2;
      std::nth_element(good_errors.begin(), good_errors.begin() + mid, good_errors.end());
      const double accept = options.guess_accept_error_factor * good_errors[mid];
      for (size_t i = 0; i < n; ++i) {
        if (tracks.from_guess[i] && guess_error[i] <= accept) search_zero[i] = 0;
      }
    }
  }
  // Search from zero flow over the whole pyramid (for the points the guess did not settle).
  std::vector<cv::Point2f> zero_start;
  std::vector<size_t> zero_index;
  for (size_t i = 0; i < n; ++i) {
    if (!search_zero[i]) continue;
    zero_start.push_back(cur_uv_px[i]);
    zero_index.push_back(i);
  }
  if (!zero_start.empty()) {
    std::vector<cv::Point2f> zero_uv;
    std::vector<uint8_t> zero_status;
    pass.max_level = top_level;
    pass.use_initial_flow = false;
    engine->Track(cur_pyramid, prev_pyramid, zero_start, zero_uv, zero_status, error, pass);
    for (size_t k = 0; k < zero_index.size(); ++k) {
      const size_t i = zero_index[k];
      if (!zero_status[k] || !inside(zero_uv[k])) continue;
      if (tracks.from_guess[i] &&
          guess_error[i] <= options.guess_error_ratio * error[k] + options.guess_error_slack) {
        continue;  // the guess stands
      }
      prev_uv[i] = zero_uv[k];
      status[i] = 1;
      tracks.from_guess[i] = 0;
    }
  }
  // Forward-backward check: the round trip over the whole pyramid, started at the start (on the
  // fine levels only it would let an edge point that slid along its edge come straight back).
  // Guesses accepted on their match error alone skip it unless round_trip_accepted_guesses.
  std::vector<cv::Point2f> back_start, back_uv;
  std::vector<size_t> back_index;
  for (size_t i = 0; i < n; ++i) {
    if (!status[i] || !inside(prev_uv[i])) continue;
    tracks.prev_uv_px[i] = prev_uv[i];
    const bool accepted = tracks.from_guess[i] && !search_zero[i];
    if (options.forward_backward_check && (!accepted || options.round_trip_accepted_guesses)) {
      back_start.push_back(prev_uv[i]);
      back_uv.push_back(cur_uv_px[i]);
      back_index.push_back(i);
      continue;
    }
    tracks.valid[i] = 1;
  }
  if (!back_start.empty()) {
    std::vector<uint8_t> back_status;
    pass.max_level = top_level;
    pass.use_initial_flow = true;
    engine->Track(prev_pyramid, cur_pyramid, back_start, back_uv, back_status, error, pass);
    for (size_t k = 0; k < back_index.size(); ++k) {
      if (!back_status[k]) continue;
      const size_t i = back_index[k];
      const float fb = static_cast<float>(cv::norm(back_uv[k] - cur_uv_px[i]));
      tracks.forward_backward_px[i] = fb;
      if (fb <= options.max_forward_backward_px) tracks.valid[i] = 1;
    }
  }
  tracks.num_valid = static_cast<int>(std::count(tracks.valid.begin(), tracks.valid.end(), 1));
  return tracks;
}

EgoMotionEstimate EstimateCurFromPrev(const PinholeCamera& camera,
                                      std::span<const cv::Point2f> cur_uv_px,
                                      std::span<const float> depth_m,
                                      std::span<const cv::Point2f> prev_uv_px,
                                      std::span<const uint8_t> usable,
                                      const SE3* initial_cur_from_prev,
                                      const EgoMotionOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("EgoMotionOptions: " + why);
  const size_t n = cur_uv_px.size();
  if (depth_m.size() != n || prev_uv_px.size() != n || usable.size() != n) {
    throw std::invalid_argument("EstimateCurFromPrev: inputs of different sizes");
  }
  EgoMotionEstimate result;
  result.inliers.assign(n, 0);
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  std::vector<int> index;
  for (size_t i = 0; i < n; ++i) {
    const float z = depth_m[i];
    if (!usable[i] || !(z >= options.min_depth_m && z <= options.max_depth_m)) continue;
    const Eigen::Vector3d p =
        camera.Unproject(Eigen::Vector2d(cur_uv_px[i].x, cur_uv_px[i].y), static_cast<double>(z));
    object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                        static_cast<float>(p.z()));
    image.push_back(prev_uv_px[i]);
    index.push_back(static_cast<int>(i));
  }
  result.num_candidates = static_cast<int>(object.size());
  if (result.num_candidates < options.min_inliers) {
    result.failure_reason = "too few candidates (" + std::to_string(result.num_candidates) + ")";
    return result;
  }
  const cv::Matx33d k(camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0);
  cv::Mat rvec, tvec;
  bool use_guess = false;
  if (initial_cur_from_prev) {
    const SE3 prev_from_cur = initial_cur_from_prev->inverse();
    cv::Matx33d r;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) r(a, b) = prev_from_cur.linear()(a, b);
    }
    cv::Rodrigues(r, rvec);
    const Eigen::Vector3d t = prev_from_cur.translation();
    tvec = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
    use_guess = true;
  }
  std::vector<int> inliers;
  bool ok = false;
  try {
    ok = cv::solvePnPRansac(object, image, k, cv::noArray(), rvec, tvec, use_guess,
                            options.ransac_iterations,
                            static_cast<float>(options.ransac_reprojection_px),
                            options.ransac_confidence, inliers, cv::SOLVEPNP_ITERATIVE);
  } catch (const cv::Exception& e) {
    result.failure_reason = std::string("solvePnPRansac: ") + e.what();
    return result;
  }
  if (!ok || static_cast<int>(inliers.size()) < options.min_inliers) {
    result.failure_reason = "PnP RANSAC found " + std::to_string(inliers.size()) + " inliers";
    return result;
  }
  std::vector<cv::Point3f> object_in;
  std::vector<cv::Point2f> image_in;
  for (int i : inliers) {
    object_in.push_back(object[i]);
    image_in.push_back(image[i]);
  }
  cv::solvePnPRefineLM(object_in, image_in, k, cv::noArray(), rvec, tvec);
  const SE3 prev_from_cur = PoseFromCvRodrigues(rvec, tvec);
  // Inliers of the refined motion.
  int count = 0;
  for (size_t c = 0; c < object.size(); ++c) {
    const Eigen::Vector3d p_prev =
        prev_from_cur * Eigen::Vector3d(object[c].x, object[c].y, object[c].z);
    if (!(p_prev.z() > 1e-6)) continue;
    const Eigen::Vector2d uv = camera.Project(p_prev);
    if ((uv - Eigen::Vector2d(image[c].x, image[c].y)).norm() <= options.ransac_reprojection_px) {
      result.inliers[index[c]] = 1;
      ++count;
    }
  }
  result.num_inliers = count;
  if (count < options.min_inliers ||
      count < options.min_inlier_ratio * static_cast<double>(result.num_candidates)) {
    result.failure_reason = "too few inliers after refinement (" + std::to_string(count) + " of " +
                            std::to_string(result.num_candidates) + ")";
    return result;
  }
  result.success = true;
  result.cur_from_prev = prev_from_cur.inverse();
  return result;
}

double StaticProbabilityFromChi2(double chi2, int dof, const MotionScoreOptions& options) {
  const double mid = dof == 1   ? options.chi2_mid_1dof
                     : dof == 3 ? options.chi2_mid_3dof
                                : options.chi2_mid_2dof;
  const double x = (chi2 - mid) / options.chi2_width;
  if (x > 50.0) return 0.0;
  return 1.0 / (1.0 + std::exp(x));
}

double GateByObservability(double static_prob, double observability) {
  if (static_prob < 0.5) return static_prob;
  return 0.5 + (static_prob - 0.5) * std::clamp(observability, 0.0, 1.0);
}

PointMotion ScorePointMotion(const PinholeCamera& camera, double bf,
                             const Eigen::Vector2d& cur_uv_px, double depth_m,
                             const Eigen::Vector2d& prev_uv_px, const SE3& prev_from_cur,
                             const PoseSigma& pose_sigma, const PointNoise& noise,
                             double object_displacement_m, const Eigen::Vector3d& travel_dir_in_cur,
                             const MotionScoreOptions& options) {
  PointMotion out;
  const Eigen::Matrix3d r = prev_from_cur.linear();
  const Eigen::Vector3d t = prev_from_cur.translation();
  const Eigen::Vector3d ray((cur_uv_px.x() - camera.cx) / camera.fx,
                            (cur_uv_px.y() - camera.cy) / camera.fy, 1.0);
  const double cur_var = noise.cur_sigma_px * noise.cur_sigma_px;
  const double prev_var = noise.prev_sigma_px * noise.prev_sigma_px;

  if (depth_m > 0.0 && bf > 0.0 && std::isfinite(depth_m)) {
    const Eigen::Vector3d p_cur = depth_m * ray;
    const Eigen::Vector3d p_prev = r * p_cur + t;
    if (!(p_prev.z() > 0.05)) return out;
    const Eigen::Matrix<double, 2, 3> j = ProjectionJacobian(camera, p_prev);
    // Current pixel noise at fixed depth: d p_cur / d uv = depth * diag(1/fx, 1/fy) (top rows).
    Eigen::Matrix<double, 3, 2> d_point_d_uv = Eigen::Matrix<double, 3, 2>::Zero();
    d_point_d_uv(0, 0) = depth_m / camera.fx;
    d_point_d_uv(1, 1) = depth_m / camera.fy;
    // Depth noise from disparity noise: sigma_z = z^2 / bf * sigma_d, along the ray.
    const double sigma_z = depth_m * depth_m / bf * noise.disparity_sigma_px;
    out.predicted_prev_uv_px = camera.Project(p_prev);
    const Eigen::Vector2d residual = prev_uv_px - out.predicted_prev_uv_px;
    out.test = MotionTest::kDepth;
    out.residual_px = residual.norm();
    // Observability: an object displaced by delta (current frame) between the frames was at
    // p_cur - delta in the previous one, so its previous measurement moves by -J R delta.
    const Eigen::Vector3d delta = object_displacement_m * travel_dir_in_cur;
    if (noise.prev_disparity_px > 0.0 && std::isfinite(noise.prev_disparity_px)) {
      // The previous frame's own disparity is a third measurement: a car ahead that keeps its
      // distance keeps its disparity, where a static point at the same place would have come
      // closer (the 2-D test alone hardly sees this near the focus of expansion).
      const double inv_z = 1.0 / p_prev.z();
      Eigen::Matrix3d j3;
      j3.topRows<2>() = j;
      j3.row(2) << 0.0, 0.0, -bf * inv_z * inv_z;
      const Eigen::Matrix3d cov3 =
          DepthTestCovariance<3>(j3, r, d_point_d_uv, ray, sigma_z, p_prev, pose_sigma, noise);
      const Eigen::Vector3d residual3(residual.x(), residual.y(),
                                      noise.prev_disparity_px - bf * inv_z);
      out.with_disparity = true;
      out.chi2 = Mahalanobis2<3>(residual3, cov3);
      out.static_prob = StaticProbabilityFromChi2(out.chi2, 3, options);
      out.observability = Observability<3>(j3 * r * delta, cov3, options);
      return out;
    }
    const Eigen::Matrix2d cov =
        DepthTestCovariance<2>(j, r, d_point_d_uv, ray, sigma_z, p_prev, pose_sigma, noise);
    out.chi2 = Mahalanobis2<2>(residual, cov);
    out.static_prob = StaticProbabilityFromChi2(out.chi2, 2, options);
    out.observability = Observability<2>(j * r * delta, cov, options);
    return out;
  }

  if (t.norm() < options.min_translation_m) {
    // No translation: a static point at any depth maps through the infinite homography K R K^-1.
    const Eigen::Vector3d p_prev = r * ray;
    if (!(p_prev.z() > 1e-6)) return out;
    const Eigen::Matrix<double, 2, 3> j = ProjectionJacobian(camera, p_prev);
    const Eigen::Matrix2d cov =
        (prev_var + cur_var) * Eigen::Matrix2d::Identity() +
        PoseCovariance<2>(j, p_prev, PoseSigma{pose_sigma.rotation_rad, 0.0});
    out.predicted_prev_uv_px = camera.Project(p_prev);
    const Eigen::Vector2d residual = prev_uv_px - out.predicted_prev_uv_px;
    out.test = MotionTest::kRotation;
    out.residual_px = residual.norm();
    out.chi2 = Mahalanobis2<2>(residual, cov);
    out.static_prob = StaticProbabilityFromChi2(out.chi2, 2, options);
    out.observability = 0.0;  // motion along the travel direction at unknown depth is invisible
    return out;
  }

  // Epipolar test: x_prev^T [t]x R x_cur = 0 in normalised coordinates; F = K^-T E K^-1.
  const Eigen::Matrix3d k_inv = IntrinsicMatrix(camera).inverse();
  const Eigen::Matrix3d f = k_inv.transpose() * Skew(t) * r * k_inv;
  const Eigen::Vector3d x_cur(cur_uv_px.x(), cur_uv_px.y(), 1.0);
  const Eigen::Vector3d x_prev(prev_uv_px.x(), prev_uv_px.y(), 1.0);
  const Eigen::Vector3d line_prev = f * x_cur;              // epipolar line in the previous image
  const Eigen::Vector3d line_cur = f.transpose() * x_prev;  // and in the current one
  const double e = x_prev.dot(line_prev);
  const double g_prev = line_prev.head<2>().squaredNorm();
  const double g_cur = line_cur.head<2>().squaredNorm();
  if (!(g_prev + g_cur > 1e-18)) return out;
  // First-order variance of e: previous position (plus the rotation uncertainty, which moves the
  // previous point by about f * sigma_rot) and current position noise.
  const double rot_px = camera.fx * pose_sigma.rotation_rad;
  const double var_e = (prev_var + rot_px * rot_px) * g_prev + cur_var * g_cur;
  out.test = MotionTest::kEpipolar;
  out.residual_px = std::abs(e) / std::sqrt(g_prev + g_cur);  // Sampson distance
  out.chi2 = e * e / std::max(var_e, 1e-18);
  out.static_prob = StaticProbabilityFromChi2(out.chi2, 1, options);
  out.observability = 0.0;  // motion along the epipolar line is invisible without depth
  return out;
}

}  // namespace pcr
