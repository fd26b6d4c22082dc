#pragma once
// Ego-motion-compensated motion evidence per keypoint (the M_motion term of the static score):
// pyramidal Lucas-Kanade tracking of the current keypoints back into the previous left image,
// the camera motion between the two frames (given by the caller, or estimated here by PnP RANSAC
// on static-looking points), and per keypoint the residual between where the keypoint was seen in
// the previous image and where a static scene point would have been, normalised by the predicted
// uncertainty of that prediction. Raw flow magnitude is not motion: a near static point flows
// fast and is predicted to.
//
// Frames and units: cur_from_prev maps previous-camera coordinates to current-camera coordinates
// (p_in_cur = cur_from_prev * p_in_prev); prev_from_cur is its inverse. Pixels follow
// slam/common/camera.h. Depths are the CURRENT frame's stereo depths along z in metres (<= 0:
// none): a current keypoint is back-projected at its current depth and mapped into the previous
// camera, which is the same test as predicting forwards from the previous depth, but uses the
// depth the frame already carries.
//
// Pure functions; thread-compatible.
#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/dynamic/flow_engine.h"

namespace pcr {

struct LkOptions {
  // Side of the square LK window (odd, >= 5). 11 px tracks as well as 21 for the filter (drive
  // 0005: precision/recall 0.963/0.627 against 0.969/0.625, ATE 0.563 against 0.570 m) at about
  // a third of the cost (bench_filter BM_FilterFlow/11 vs /21: 29 vs 79 ms for 2000 keypoints).
  int window_px = 11;
  int max_level = 3;         // pyramid levels above the base: displacements up to ~80 px
  int max_iterations = 20;   // per level
  double epsilon_px = 0.01;  // iteration stop
  double min_eigen_threshold = 1e-4;
  bool forward_backward_check = true;    // track back again and compare with the start
  double max_forward_backward_px = 1.0;  // larger round-trip errors invalidate the track
  // With an initial guess (TrackIntoPrevious), a search starts there on levels
  // 0..refine_max_level. Its match stands alone when its mean absolute patch difference is within
  // guess_accept_error_factor x the frame's median (0: always search from zero flow too);
  // otherwise the zero-flow search runs and replaces it when the guess's difference exceeds
  // guess_error_ratio x the other's + guess_error_slack (grey levels).
  int refine_max_level = 1;
  double guess_accept_error_factor = 1.5;
  bool round_trip_accepted_guesses = true;  // forward-backward check on accepted guesses too
  double guess_error_ratio = 1.15;
  double guess_error_slack = 0.5;
  bool IsValid(std::string* why) const;
};

// LK pyramid (cv::buildOpticalFlowPyramid with derivatives) of a CV_8UC1 image. Throws
// std::invalid_argument on an empty or non-grey image.
std::vector<cv::Mat> BuildLkPyramid(const cv::Mat& gray, const LkOptions& options);

struct FlowTracks {
  std::vector<cv::Point2f> prev_uv_px;  // per current keypoint: its position in the previous image
  std::vector<uint8_t> valid;           // non-zero: tracked (and passed the round trip)
  std::vector<float> forward_backward_px;  // round-trip error, -1 when not checked or failed
  std::vector<uint8_t> from_guess;         // non-zero: the search from the initial guess won
  int num_valid = 0;
};

// Tracks cur_uv_px from the current image back into the previous one (both pyramids from
// BuildLkPyramid with the same options, images of the same size): a search from zero flow over
// the whole pyramid and, when initial_prev_uv_px is not empty, one from that guess per point
// (a guess outside the image, e.g. (-1, -1), means none for that point) on the fine levels (see
// LkOptions::guess_*; the zero-flow search is skipped where the guess matches well). With the
// static prediction of a motion prior as the guess, a static point is found where it should be even
// when it flows fast, or sits on an edge or a repeated texture where the zero-flow search slides to
// a wrong but self-consistent match; a moving point's guess is off and its true match (found from
// zero flow) fits better. Tracks that leave the image are invalid. The LK passes run on `engine`
// (nullptr: OpenCV on this thread). Throws ConfigError for invalid options,
// std::invalid_argument for a guess vector of another size.
FlowTracks TrackIntoPrevious(const std::vector<cv::Mat>& prev_pyramid,
                             const std::vector<cv::Mat>& cur_pyramid,
                             const std::vector<cv::Point2f>& cur_uv_px, const LkOptions& options,
                             const std::vector<cv::Point2f>& initial_prev_uv_px = {},
                             FlowEngine* engine = nullptr);

struct EgoMotionOptions {
  double ransac_reprojection_px = 2.0;  // inlier bound on the previous-image reprojection error
  int ransac_iterations = 300;
  double ransac_confidence = 0.999;
  int min_inliers = 15;
  double min_inlier_ratio = 0.25;  // inliers / candidates
  double min_depth_m = 0.5;        // candidates: stereo depth in [min, max]
  double max_depth_m = 40.0;       // far points constrain translation too weakly
  bool IsValid(std::string* why) const;
};

struct EgoMotionEstimate {
  bool success = false;
  SE3 cur_from_prev = SE3::Identity();
  int num_candidates = 0;
  int num_inliers = 0;
  std::vector<uint8_t> inliers;  // per input point (non-zero: RANSAC inlier)
  std::string failure_reason;
};

// cur_from_prev by PnP RANSAC (cv::solvePnPRansac, then Levenberg-Marquardt on the inliers): the
// current keypoints back-projected at their stereo depths are the 3-D points, their tracked
// previous positions the 2-D observations. usable[i] != 0 selects candidates (the caller leaves
// out failed tracks and points inside dynamic masks); the depth window is applied here.
// initial_cur_from_prev (may be null) seeds the solver. All spans have the same size, else
// std::invalid_argument; throws ConfigError for invalid options.
EgoMotionEstimate EstimateCurFromPrev(const PinholeCamera& camera,
                                      std::span<const cv::Point2f> cur_uv_px,
                                      std::span<const float> depth_m,
                                      std::span<const cv::Point2f> prev_uv_px,
                                      std::span<const uint8_t> usable,
                                      const SE3* initial_cur_from_prev,
                                      const EgoMotionOptions& options);

// Standard deviations of the camera-motion estimate (per axis), used to widen the prediction.
struct PoseSigma {
  double rotation_rad = 0.002;
  double translation_m = 0.03;
};

struct MotionScoreOptions {
  double disparity_sigma_px = 0.5;  // stereo disparity noise at level 0 (scaled by the octave)
  // Camera-motion uncertainty by source: a caller's prior (e.g. a constant-velocity model) is
  // trusted less than PnP on this frame's own correspondences. A caller whose prior is exact
  // (ground truth, the tracker's result) may lower prior_pose.
  PoseSigma prior_pose{0.003, 0.05};
  PoseSigma pnp_pose{0.0015, 0.008};
  // P(static) = 1 / (1 + exp((chi2 - mid) / width)): 0.5 at the chi-square 99% quantile.
  double chi2_mid_2dof = 9.21;   // depth or rotation-only test (2 dof)
  double chi2_mid_1dof = 14.0;   // epipolar test (1 dof): LK slides along edges and stripes
  double chi2_mid_3dof = 11.34;  // depth test with the previous disparity (3 dof)
  double chi2_width = 2.0;
  // Observability: how far (pixels) a point of an object moving at reference_speed_mps along
  // the camera's direction of travel (the usual direction of traffic, and the direction hardest
  // to see) would be from the static prediction, in units of observability_sigmas standard
  // deviations of the prediction. 1 = a static verdict is confirmed; 0 = the test could not have
  // seen such a motion (far points ahead, points without depth).
  double reference_speed_mps = 5.0;
  double observability_sigmas = 2.0;
  double min_translation_m = 1e-3;  // below this the epipolar test degenerates (rotation only)
  bool IsValid(std::string* why) const;
};

enum class MotionTest : uint8_t {
  kNone,      // no observation in the previous frame (or no camera motion)
  kDepth,     // point with stereo depth: full 2-D prediction (+ the previous disparity: 3 dof)
  kEpipolar,  // no depth: Sampson distance to the epipolar line (1 dof)
  kRotation,  // no depth and no translation: infinite-homography prediction (2 dof)
};

struct PointMotion {
  MotionTest test = MotionTest::kNone;
  double residual_px = -1.0;   // |observed - predicted| (kDepth, kRotation); Sampson distance
  double chi2 = -1.0;          // squared Mahalanobis distance of the residual
  double static_prob = 0.5;    // P(static | residual) in [0, 1]
  double observability = 0.0;  // in [0, 1], see MotionScoreOptions
  Eigen::Vector2d predicted_prev_uv_px = Eigen::Vector2d::Constant(-1.0);  // kDepth, kRotation
  bool with_disparity = false;  // kDepth: the previous disparity entered the test (3 dof)
  bool valid() const { return test != MotionTest::kNone; }
};

// Per-point noise inputs of ScorePointMotion (pixels at level 0, already scaled by the octave).
struct PointNoise {
  double cur_sigma_px = 0.0;   // current position (0 when LK tracked from this exact position)
  double prev_sigma_px = 0.5;  // previous position (LK or matched keypoint)
  double disparity_sigma_px = 0.5;
  // Stereo disparity measured at the previous position (the same point's keypoint in the
  // previous frame); <= 0: none (the depth test is then 2-D).
  double prev_disparity_px = -1.0;
};

// Motion test of one keypoint. bf: rig baseline * fx (0: mono), depth_m <= 0: no depth.
// object_displacement_m: the displacement the observability refers to (reference speed * dt);
// travel_dir_in_cur: unit direction of travel in the current camera (the object displacement
// direction). Returns kNone when the prediction falls behind the previous camera.
PointMotion ScorePointMotion(const PinholeCamera& camera, double bf,
                             const Eigen::Vector2d& cur_uv_px, double depth_m,
                             const Eigen::Vector2d& prev_uv_px, const SE3& prev_from_cur,
                             const PoseSigma& pose_sigma, const PointNoise& noise,
                             double object_displacement_m, const Eigen::Vector3d& travel_dir_in_cur,
                             const MotionScoreOptions& options);

// The logistic map from a squared Mahalanobis distance to P(static).
double StaticProbabilityFromChi2(double chi2, int dof, const MotionScoreOptions& options);

// Static probability limited by observability: motion evidence (p < 0.5) is always kept; a static
// verdict only counts as far as the test could have seen motion: 0.5 + (p - 0.5) * observability.
double GateByObservability(double static_prob, double observability);

}  // namespace pcr
