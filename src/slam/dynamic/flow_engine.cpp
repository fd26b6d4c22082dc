#include "slam/dynamic/flow_engine.h"

#include <opencv2/video/tracking.hpp>
#include <stdexcept>

namespace pcr {
namespace {

class OpenCvFlowEngine final : public FlowEngine {
 public:
  void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
             const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
             std::vector<uint8_t>& status, std::vector<float>& error, const LkPass& pass) override {
    if (from.empty() || to.empty() || from[0].size() != to[0].size()) {
      throw std::invalid_argument("FlowEngine::Track: pyramids of different image sizes");
    }
    if (pass.use_initial_flow && to_pts.size() != from_pts.size()) {
      throw std::invalid_argument("FlowEngine::Track: one initial position per point");
    }
    const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                    pass.max_iterations, pass.epsilon_px);
    cv::calcOpticalFlowPyrLK(from, to, from_pts, to_pts, status, error,
                             cv::Size(pass.window_px, pass.window_px), pass.max_level, criteria,
                             pass.use_initial_flow ? cv::OPTFLOW_USE_INITIAL_FLOW : 0,
                             pass.min_eigen_threshold);
  }
  std::string Name() const override { return "opencv"; }
};

}  // namespace

std::unique_ptr<FlowEngine> MakeOpenCvFlowEngine() { return std::make_unique<OpenCvFlowEngine>(); }

}  // namespace pcr
