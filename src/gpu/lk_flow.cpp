#include "gpu/lk_flow.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "gpu/executor.h"

namespace pcr::gpu {
namespace {

[[noreturn]] void RejectLkInput(const std::string& why) {
  throw std::invalid_argument("FlowEngine::Track (lk): " + why);
}

// Checks one pyramid's layout: interleaved CV_8UC1 images and CV_16SC2 derivatives of the same
// size, at least `levels` levels.
void CheckLkPyramid(const std::vector<cv::Mat>& pyramid, const char* name, int levels) {
  if (pyramid.empty() || pyramid.size() % 2 != 0) {
    RejectLkInput(std::string("the ") + name +
                  " pyramid is not images interleaved with their derivatives (BuildLkPyramid)");
  }
  const int have = static_cast<int>(pyramid.size() / 2);
  if (have < levels) {
    RejectLkInput(std::string("the ") + name + " pyramid has " + std::to_string(have) +
                  " levels, the pass uses " + std::to_string(levels));
  }
  for (int l = 0; l < have; ++l) {
    const cv::Mat& image = pyramid[2 * l];
    const cv::Mat& deriv = pyramid[2 * l + 1];
    if (image.empty() || image.type() != CV_8UC1 || image.dims != 2) {
      RejectLkInput(std::string("level ") + std::to_string(l) + " of the " + name +
                    " pyramid is not a CV_8UC1 image");
    }
    if (deriv.type() != CV_16SC2 || deriv.size() != image.size() || deriv.dims != 2) {
      RejectLkInput(std::string("level ") + std::to_string(l) + " of the " + name +
                    " pyramid has no CV_16SC2 derivatives of its size (BuildLkPyramid makes them)");
    }
  }
}

// The level's stored border is at least `window`, and offsets into it fit an int.
void CheckLkLevelBorder(const cv::Mat& level, int window, const char* what, int l) {
  const lk_detail::StoredLevel stored = lk_detail::LocateStoredLevel(level);
  if (stored.border < window) {
    RejectLkInput(std::string("level ") + std::to_string(l) + " of the " + what +
                  " has a border of " + std::to_string(stored.border) + " px, narrower than the " +
                  std::to_string(window) +
                  " px window (build the pyramids with a window at least as large)");
  }
  if (static_cast<double>(level.step[0]) * stored.rows > static_cast<double>(INT_MAX)) {
    RejectLkInput(std::string("level ") + std::to_string(l) + " of the " + what + " is too large");
  }
}

// The CPU twin: LkTrackPoint per point, points spread over OpenCV's threads. With a DeviceWait
// it computes the pass inside the wait's launch and calls done() as the launch's last act, as the
// network executor's twin does: the scheduler's device path runs with a real engine on the CPU.
class TwinLkFlowEngine final : public FlowEngine {
 public:
  void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
             const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
             std::vector<uint8_t>& status, std::vector<float>& error, const LkPass& pass) override {
    const LkSettings settings =
        lk_detail::CheckTrackInputs(from, to, from_pts.size(), to_pts.size(), pass);
    const LkPyramidViews views = lk_detail::HostViews(from, to, pass.max_level);
    to_pts.resize(from_pts.size());  // with use_initial_flow the size is already right
    status.resize(from_pts.size());
    error.resize(from_pts.size());
    if (from_pts.empty()) return;
    auto compute = [&] { Compute(views, settings, from_pts, to_pts, status, error); };
    if (!wait_) {
      compute();
      return;
    }
    wait_([&compute](const DeviceDone& done) {
      compute();  // a throw here has not called done(), as DeviceWait requires
      done();
    });
  }

  std::string Name() const override { return "cpu-twin"; }
  void SetDeviceWait(DeviceWait wait) override { wait_ = std::move(wait); }

 private:
  static void Compute(const LkPyramidViews& views, const LkSettings& settings,
                      const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
                      std::vector<uint8_t>& status, std::vector<float>& error) {
    const int n = static_cast<int>(from_pts.size());
    const int area = settings.window * settings.window;
    cv::parallel_for_(cv::Range(0, n), [&](const cv::Range& range) {
      std::vector<int16_t> buffer(3 * static_cast<size_t>(area));
      LkSerialLanes lanes;
      lanes.image_window = buffer.data();
      lanes.deriv_window = buffer.data() + area;
      for (int i = range.start; i < range.end; ++i) {
        const cv::Point2f p = from_pts[i];
        const cv::Point2f guess = settings.use_initial_flow ? to_pts[i] : p;
        const LkPointResult r = LkTrackPoint(lanes, views, settings, p.x, p.y, guess.x, guess.y);
        to_pts[i] = cv::Point2f(r.x, r.y);
        status[i] = r.status;
        error[i] = r.error;
      }
    });
  }

  DeviceWait wait_;  // empty: compute on the calling thread
};

}  // namespace

namespace lk_detail {

StoredLevel LocateStoredLevel(const cv::Mat& level) {
  StoredLevel stored;
  if (level.empty()) return stored;
  cv::Size whole;
  cv::Point offset;
  level.locateROI(whole, offset);
  const int right = whole.width - offset.x - level.cols;
  const int bottom = whole.height - offset.y - level.rows;
  stored.border = std::min({offset.x, offset.y, right, bottom, StoredLevel::kMaxBorder});
  stored.border = std::max(stored.border, 0);
  const size_t pixel = level.elemSize();
  stored.first = level.ptr<uint8_t>(0) - static_cast<size_t>(stored.border) * level.step[0] -
                 static_cast<size_t>(stored.border) * pixel;
  stored.row_bytes = static_cast<size_t>(level.cols + 2 * stored.border) * pixel;
  stored.rows = level.rows + 2 * stored.border;
  return stored;
}

LkSettings CheckTrackInputs(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                            size_t from_count, size_t to_count, const LkPass& pass) {
  if (pass.window_px < 5 || pass.window_px % 2 == 0) {
    RejectLkInput("the window must be odd and at least 5 px, not " +
                  std::to_string(pass.window_px));
  }
  if (pass.max_level < 0 || pass.max_level >= kLkMaxLevels) {
    RejectLkInput("max_level must be in 0.." + std::to_string(kLkMaxLevels - 1) + ", not " +
                  std::to_string(pass.max_level));
  }
  if (!std::isfinite(pass.epsilon_px) || !std::isfinite(pass.min_eigen_threshold)) {
    RejectLkInput("epsilon_px and min_eigen_threshold must be finite");
  }
  if (pass.use_initial_flow && to_count != from_count) {
    RejectLkInput("use_initial_flow needs one initial position per point (" +
                  std::to_string(from_count) + " points, " + std::to_string(to_count) +
                  " positions)");
  }
  if (from_count > static_cast<size_t>(INT_MAX)) RejectLkInput("too many points");
  const int levels = pass.max_level + 1;
  CheckLkPyramid(from, "from", levels);
  CheckLkPyramid(to, "to", levels);
  for (int l = 0; l < levels; ++l) {
    if (from[2 * l].size() != to[2 * l].size()) {
      RejectLkInput("pyramids of different sizes (level " + std::to_string(l) + ": " +
                    std::to_string(from[2 * l].cols) + "x" + std::to_string(from[2 * l].rows) +
                    " and " + std::to_string(to[2 * l].cols) + "x" +
                    std::to_string(to[2 * l].rows) + ")");
    }
    CheckLkLevelBorder(from[2 * l], pass.window_px, "from pyramid", l);
    CheckLkLevelBorder(from[2 * l + 1], pass.window_px, "from pyramid's derivatives", l);
    CheckLkLevelBorder(to[2 * l], pass.window_px, "to pyramid", l);
  }
  LkSettings settings;
  settings.window = pass.window_px;
  settings.max_iterations = std::clamp(pass.max_iterations, 0, 100);
  const double epsilon = std::clamp(pass.epsilon_px, 0.0, 10.0);
  settings.epsilon_sq = epsilon * epsilon;
  settings.min_eigen = static_cast<float>(pass.min_eigen_threshold);
  settings.use_initial_flow = pass.use_initial_flow;
  return settings;
}

LkPyramidViews HostViews(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                         int max_level) {
  auto image_view = [](const cv::Mat& m) {
    LkImageView v;
    v.origin = m.ptr<uint8_t>(0);
    v.step = static_cast<int>(m.step[0]);
    v.cols = m.cols;
    v.rows = m.rows;
    v.border = LocateStoredLevel(m).border;
    return v;
  };
  LkPyramidViews views;
  views.max_level = max_level;
  for (int l = 0; l <= max_level; ++l) {
    LkLevelViews& level = views.level[l];
    level.from_image = image_view(from[2 * l]);
    level.to_image = image_view(to[2 * l]);
    const cv::Mat& deriv = from[2 * l + 1];
    level.from_deriv.origin = deriv.ptr<int16_t>(0);
    level.from_deriv.step = static_cast<int>(deriv.step[0] / sizeof(int16_t));
    level.from_deriv.cols = deriv.cols;
    level.from_deriv.rows = deriv.rows;
    level.from_deriv.border = LocateStoredLevel(deriv).border;
  }
  return views;
}

}  // namespace lk_detail

bool IsLkFlowDevice(const std::string& device) { return IsEngineDevice(device); }

std::unique_ptr<FlowEngine> MakeLkFlowEngine(const std::string& device) {
  const int index = EngineDeviceIndex(device, "flow");
  if (index < 0) return std::make_unique<TwinLkFlowEngine>();
  return lk_detail::MakeCudaLkFlowEngine(index);
}

FlowEngineFactory LkFlowFactory(const std::string& device) {
  EngineDeviceIndex(device, "flow");  // reject a bad name now, not at the first engine
  return [device]() { return MakeLkFlowEngine(device); };
}

}  // namespace pcr::gpu
