#pragma once
// How far apart two cameras are, in metres, from their images alone: two-view geometry gives
// their relative pose up to scale (rotation and the direction of the baseline), and the road
// gives the scale. A plane a known height below the front camera (KITTI: 1.65 m) induces a
// homography between the images that depends on the baseline's length; the length (and the
// road's pitch against the camera) whose homography best maps the front camera's road onto the
// rear camera's image, by normalised cross-correlation of band-passed intensities, is the
// estimate. No map, stereo or ground truth goes into it: place recognition uses it to tell a
// place 8 m back from one 15 m back on a straight street, which look alike.
#include <opencv2/core.hpp>
#include <string>

#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

struct RoadDistanceOptions {
  double camera_height_m = 1.65;  // the front camera's height above the road
  // The front camera's road: the pixels whose rays meet a level road this far ahead (metres
  // along the optical axis) and within max_lateral_m sideways, every pixel_step-th pixel.
  double min_depth_m = 5.0;
  double max_depth_m = 25.0;
  double max_lateral_m = 3.5;
  int pixel_step = 2;
  // Search: the baseline's length in (0, max_distance_m] at coarse_step_m, the road's pitch in
  // [-max_pitch_deg, max_pitch_deg] at coarse_pitch_step_deg, then around the best at the fine
  // steps (+-1 coarse step).
  double max_distance_m = 40.0;
  double coarse_step_m = 0.5;
  double fine_step_m = 0.05;
  double max_pitch_deg = 3.0;
  double coarse_pitch_step_deg = 0.5;
  double fine_pitch_step_deg = 0.1;
  // Band-pass of the intensities: smoothed at smooth_sigma_px, minus the background at
  // background_sigma_px (shading and exposure do not count, the road's marks do).
  double smooth_sigma_px = 1.5;
  double background_sigma_px = 8.0;
  // Acceptance: at least this fraction of the road's pixels lands in the other image, the best
  // correlation reaches min_ncc, and neither the pitch nor the length is at its search's limit.
  double min_overlap = 0.5;
  double min_ncc = 0.2;
  // ... and it beats the best correlation at lengths further than ambiguity_band of it (and two
  // coarse steps) from it by min_ncc_margin: a repeated texture matches at several lengths. (On
  // the synthetic loops' tiled streets, pairs of different places that pass the bag of words and
  // the two-view check reach 0.08 at most.)
  double min_ncc_margin = 0.1;
  double ambiguity_band = 0.3;

  bool IsValid(std::string* why) const;
};

// Why a distance could not be measured.
enum class RoadFailure {
  kNone,             // success
  kNoBaseline,       // the relative pose has no translation, or is not finite
  kTooLittleRoad,    // fewer than 100 pixels of the front camera's road
  kNotInRearImage,   // the front camera's road lands in the rear image at no distance searched
  kPitchAtLimit,     // the best pitch is at the search's limit
  kDistanceAtLimit,  // the best length is at the search's limit
  kNoMatch,          // the best correlation is under min_ncc
  kAmbiguous,        // another length correlates within min_ncc_margin
};
// A short description of `failure` ("" for kNone), the first words of failure_reason.
const char* RoadFailureName(RoadFailure failure);

struct RoadDistance {
  bool success = false;
  RoadFailure failure = RoadFailure::kNone;
  double distance_m = 0.0;      // the baseline's length (metres); the best fit even on failure
  double ncc = -1.0;            // its correlation
  double runner_up_ncc = -1.0;  // the best correlation away from it (RoadDistanceOptions)
  double pitch_deg = 0.0;       // the road's normal against the front camera's y axis, about x
  bool a_in_front = true;       // whether camera a is the front one (its road was used)
  int road_pixels = 0;          // pixels of the front camera's road
  std::string failure_reason;   // RoadFailureName(failure) and its figures; empty on success
};

// image_a and image_b: 8-bit grey images of the two cameras; b_from_a: the relative pose from
// two-view geometry (x_b = R x_a + t), its translation of any length (only its direction is
// used). The camera in front is the one the other sees the road ahead of. Throws ConfigError for
// invalid options and std::invalid_argument for images that are not 8-bit grey or do not match
// their camera's size (when the camera gives one). Deterministic.
RoadDistance EstimateRoadDistance(const cv::Mat& image_a, const PinholeCamera& camera_a,
                                  const cv::Mat& image_b, const PinholeCamera& camera_b,
                                  const SE3& b_from_a, const RoadDistanceOptions& options);

}  // namespace pcr
