#pragma once
// Ray caster of the synthetic world (src/sim internal): one ray per pixel centre against the road
// plane (map y = 0) and oriented boxes, nearest hit wins. Boxes are culled per 32x32 tile by their
// projected rectangle (near-plane clipped) and sorted by their nearest depth, so a ray stops
// testing once the remaining boxes are all farther than its hit. Rows are shaded in parallel;
// every pixel depends only on the inputs, so the result does not depend on the thread count.
#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "sim/scene.h"
#include "slam/common/camera.h"

namespace pcr::sim {

struct ViewInput {
  const std::vector<BoxPrim>* boxes = nullptr;  // map frame
  const Ground* ground = nullptr;
  PinholeCamera camera;
  Eigen::Matrix3d map_from_cam_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d cam_in_map = Eigen::Vector3d::Zero();
};

struct ViewOutput {
  cv::Mat radiance;  // CV_32FC1, 0..255 (noise-free, not yet blurred)
  cv::Mat instance;  // CV_16UC1, BoxPrim::instance_id, 0 for the road, kSkyInstanceId for sky
  cv::Mat depth;     // CV_32FC1, metres along the optical axis; +infinity for sky
};

void RenderView(const ViewInput& input, ViewOutput* output);

}  // namespace pcr::sim
