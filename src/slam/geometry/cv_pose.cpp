#include "slam/geometry/cv_pose.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace pcr {

SE3 PoseFromCvRotation(const cv::Mat& rotation, const cv::Mat& translation) {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, r);
  cv::cv2eigen(translation, t);
  SE3 pose = SE3::Identity();
  pose.linear() = r;
  pose.translation() = t;
  return pose;
}

SE3 PoseFromCvRodrigues(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat rotation;
  cv::Rodrigues(rvec, rotation);
  return PoseFromCvRotation(rotation, tvec);
}

}  // namespace pcr
