#pragma once
// Rectified pinhole camera and stereo rig. Pixel coordinates have (0,0) at the centre of the
// top-left pixel, x to the right, y down; the camera frame has z forward, x right, y down.
#include <Eigen/Core>
#include <string>

namespace pcr {

struct PinholeCamera {
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  int width_px = 0, height_px = 0;

  // p_in_cam must have z > 0.
  Eigen::Vector2d Project(const Eigen::Vector3d& p_in_cam) const {
    return {fx * p_in_cam.x() / p_in_cam.z() + cx, fy * p_in_cam.y() / p_in_cam.z() + cy};
  }
  // Back-projects a pixel at depth z (metres along the optical axis).
  Eigen::Vector3d Unproject(const Eigen::Vector2d& uv_px, double depth_m) const {
    return {(uv_px.x() - cx) / fx * depth_m, (uv_px.y() - cy) / fy * depth_m, depth_m};
  }
  bool InImage(const Eigen::Vector2d& uv_px, double border_px = 0.0) const {
    return uv_px.x() >= border_px && uv_px.y() >= border_px &&
           uv_px.x() <= width_px - 1 - border_px && uv_px.y() <= height_px - 1 - border_px;
  }
  bool IsValid(std::string* why) const;
};

// Rectified stereo pair: the right camera has the same intrinsics and sits baseline_m along +x of
// the left camera (right_from_left = translation(-baseline_m, 0, 0)).
struct StereoRig {
  PinholeCamera left;
  double baseline_m = 0;  // 0 for a monocular rig

  bool IsStereo() const { return baseline_m > 0; }
  double Bf() const { return baseline_m * left.fx; }  // disparity_px = Bf / depth_m
  // x coordinate in the right image of a point given in the left camera frame.
  double ProjectRightX(const Eigen::Vector3d& p_in_left) const {
    return left.fx * (p_in_left.x() - baseline_m) / p_in_left.z() + left.cx;
  }
  bool IsValid(std::string* why) const;
};

}  // namespace pcr
