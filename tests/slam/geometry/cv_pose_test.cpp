#include "slam/geometry/cv_pose.h"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>

#include "slam/common/lie.h"
#include "slam/geometry/se3.h"

namespace pcr {
namespace {

TEST(CvPose, RodriguesVectorAndTranslationMapPointsAsOpenCvDoes) {
  // A quarter turn about z, then (1, 2, 3): x goes to y.
  const cv::Mat rvec = (cv::Mat_<double>(3, 1) << 0.0, 0.0, DegToRad(90.0));
  const cv::Mat tvec = (cv::Mat_<double>(3, 1) << 1.0, 2.0, 3.0);
  const SE3 pose = PoseFromCvRodrigues(rvec, tvec);
  EXPECT_LT((pose * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(1, 3, 3)).norm(), 1e-12);
  EXPECT_LT((pose * Eigen::Vector3d(0, 1, 0) - Eigen::Vector3d(0, 2, 3)).norm(), 1e-12);
  EXPECT_LT((pose.linear() * pose.linear().transpose() - Eigen::Matrix3d::Identity()).norm(),
            1e-12);
}

TEST(CvPose, RotationMatrixIsCopiedRowByRow) {
  const SE3 truth = ExpSE3((Vector6d() << 0.5, -0.2, 1.0, 0.02, -0.1, 0.05).finished());
  cv::Mat rotation(3, 3, CV_64F), translation(3, 1, CV_64F);
  for (int r = 0; r < 3; ++r) {
    translation.at<double>(r) = truth.translation()(r);
    for (int c = 0; c < 3; ++c) rotation.at<double>(r, c) = truth.linear()(r, c);
  }
  const SE3 pose = PoseFromCvRotation(rotation, translation);
  EXPECT_TRUE(pose.matrix() == truth.matrix());  // copied, not recomputed
  // The same rotation as a Rodrigues vector gives the same pose.
  cv::Mat rvec;
  cv::Rodrigues(rotation, rvec);
  EXPECT_LT((PoseFromCvRodrigues(rvec, translation).matrix() - truth.matrix()).norm(), 1e-12);
}

}  // namespace
}  // namespace pcr
