#pragma once
// OpenCV's poses as SE3: the rotation and translation that cv::recoverPose,
// cv::decomposeHomographyMat and cv::solvePnP* give (CV_64F), converted once here.
#include <opencv2/core.hpp>

#include "slam/common/pose.h"

namespace pcr {

// [R | t] from a 3x3 rotation matrix and a 3-vector translation.
SE3 PoseFromCvRotation(const cv::Mat& rotation, const cv::Mat& translation);
// [R | t] from a Rodrigues rotation vector (cv::solvePnP's rvec) and a 3-vector translation.
SE3 PoseFromCvRodrigues(const cv::Mat& rvec, const cv::Mat& tvec);

}  // namespace pcr
