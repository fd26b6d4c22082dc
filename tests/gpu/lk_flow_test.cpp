// The LK flow engines (gpu/lk_flow.h) on real KITTI frames: the CPU twin against
// cv::calcOpticalFlowPyrLK on the same pyramids, the engines reused over a sequence as the dynamic
// filter reuses them, bad input, and (on a machine with a CUDA device) the CUDA engine against
// the twin.
#include "gpu/lk_flow.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <barrier>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <future>
#include <limits>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "gpu/executor.h"
#include "slam/dynamic/flow_engine.h"
#include "slam/dynamic/motion_score.h"
#include "support/data_paths.h"
#include "support/device_wait.h"
#include "support/texture_images.h"

namespace pcr::gpu::lk_test {
namespace {

cv::Mat LoadGray(const std::string& relative) {
  const cv::Mat image = cv::imread(test::SharedPath(relative), cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(image.empty()) << test::SharedPath(relative);
  return image;
}

std::string Odometry06(int frame) {
  char name[64];
  std::snprintf(name, sizeof name, "data/kitti/sequences/06/image_0/%06d.png", frame);
  return name;
}

std::string Raw0005(int frame) {
  char name[96];
  std::snprintf(name, sizeof name,
                "data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync/image_00/data/%010d.png",
                frame);
  return name;
}

LkOptions PyramidOptions(int window = 21, int max_level = 3) {
  LkOptions options;
  options.window_px = window;
  options.max_level = max_level;
  return options;
}

LkPass Pass(int max_level, bool use_initial_flow) {
  LkPass pass;
  pass.window_px = 21;
  pass.max_level = max_level;
  pass.max_iterations = 20;
  pass.epsilon_px = 0.01;
  pass.min_eigen_threshold = 1e-4;
  pass.use_initial_flow = use_initial_flow;
  return pass;
}

// ~2000 corners of the image, plus points on and beyond its edges (border handling) and one
// that is not a number.
std::vector<cv::Point2f> TrackedPoints(const cv::Mat& image) {
  std::vector<cv::Point2f> points;
  cv::goodFeaturesToTrack(image, points, 2000, 0.001, 5.0);
  const float w = static_cast<float>(image.cols), h = static_cast<float>(image.rows);
  for (float t = 0.0f; t <= 1.0f; t += 0.125f) {
    points.emplace_back(t * (w - 1), 0.0f);
    points.emplace_back(t * (w - 1), h - 1);
    points.emplace_back(0.3f, t * (h - 1));
    points.emplace_back(w - 1.5f, t * (h - 1));
  }
  points.emplace_back(-25.0f, 40.0f);
  points.emplace_back(w + 30.0f, 100.0f);
  points.emplace_back(200.0f, -8.0f);
  points.emplace_back(300.0f, h + 3.0f);
  points.emplace_back(std::numeric_limits<float>::quiet_NaN(), 50.0f);
  return points;
}

struct PassResult {
  std::vector<cv::Point2f> to;
  std::vector<uint8_t> status;
  std::vector<float> error;
  double ms = 0.0;
};

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

PassResult RunOpenCv(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                     const std::vector<cv::Point2f>& from_pts,
                     const std::vector<cv::Point2f>& initial, const LkPass& pass) {
  PassResult r;
  r.to = initial;
  const auto start = std::chrono::steady_clock::now();
  cv::calcOpticalFlowPyrLK(from, to, from_pts, r.to, r.status, r.error,
                           cv::Size(pass.window_px, pass.window_px), pass.max_level,
                           cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                            pass.max_iterations, pass.epsilon_px),
                           pass.use_initial_flow ? cv::OPTFLOW_USE_INITIAL_FLOW : 0,
                           pass.min_eigen_threshold);
  r.ms = MsSince(start);
  return r;
}

PassResult RunEngine(FlowEngine& engine, const std::vector<cv::Mat>& from,
                     const std::vector<cv::Mat>& to, const std::vector<cv::Point2f>& from_pts,
                     const std::vector<cv::Point2f>& initial, const LkPass& pass) {
  PassResult r;
  r.to = initial;
  const auto start = std::chrono::steady_clock::now();
  engine.Track(from, to, from_pts, r.to, r.status, r.error, pass);
  r.ms = MsSince(start);
  return r;
}

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[static_cast<size_t>(q * static_cast<double>(values.size() - 1))];
}

// How closely `got` follows `want` (same points).
struct Agreement {
  double status_agreement = 0.0;  // fraction of points with the same status
  size_t both_found = 0;
  // Position differences of the points both found (px), and the fraction beyond 0.05 px.
  double median_px = 0.0, p95_px = 0.0, max_px = 0.0, apart = 0.0;
  double error_p95 = 0.0, error_p99 = 0.0, error_max = 0.0;  // |error difference|, grey levels
  std::string Text() const {
    char text[256];
    std::snprintf(text, sizeof text,
                  "status agree %.4f, %zu both found: |dpos| median %.1e p95 %.1e max %.1e px, "
                  "%.4f beyond 0.05 px, |derr| p95 %.1e p99 %.1e max %.1e",
                  status_agreement, both_found, median_px, p95_px, max_px, apart, error_p95,
                  error_p99, error_max);
    return text;
  }
};

Agreement Compare(const PassResult& got, const PassResult& want) {
  Agreement a;
  EXPECT_EQ(got.to.size(), want.to.size());
  EXPECT_EQ(got.status.size(), want.status.size());
  EXPECT_EQ(got.error.size(), want.error.size());
  const size_t n = std::min({got.to.size(), want.to.size(), got.status.size(), want.status.size(),
                             got.error.size(), want.error.size()});
  size_t same = 0;
  std::vector<double> position, error;
  for (size_t i = 0; i < n; ++i) {
    if ((got.status[i] != 0) == (want.status[i] != 0)) ++same;
    if (!got.status[i] || !want.status[i]) continue;
    position.push_back(cv::norm(got.to[i] - want.to[i]));
    error.push_back(std::abs(got.error[i] - want.error[i]));
  }
  a.status_agreement = n ? static_cast<double>(same) / static_cast<double>(n) : 1.0;
  a.both_found = position.size();
  a.median_px = Percentile(position, 0.5);
  a.p95_px = Percentile(position, 0.95);
  a.max_px = Percentile(position, 1.0);
  a.apart = position.empty()
                ? 0.0
                : static_cast<double>(std::count_if(position.begin(), position.end(),
                                                    [](double d) { return d > 0.05; })) /
                      static_cast<double>(position.size());
  a.error_p95 = Percentile(error, 0.95);
  a.error_p99 = Percentile(error, 0.99);
  a.error_max = Percentile(error, 1.0);
  return a;
}

// The twin's agreement with OpenCV, measured (window 21, 3 levels, 20 iterations, eps 0.01) on
// three frame pairs and four pass kinds, ~2000 points each: status agrees on every point;
// position differences have a median of 0 and a p95 <= 1.2e-4 px, at most 1 point in 2000 is
// beyond 0.05 px (a borderline stop decision that went the other way); error differences have a
// p99 <= 1e-3 grey levels. The window sums are exact here and float in OpenCV, which is the
// whole difference. The limits below leave a margin of 10-20x and fail with a twin that stops
// after 2 iterations instead of 20 (checked by hand).
void ExpectAgreesWithOpenCv(const Agreement& a) {
  EXPECT_GE(a.status_agreement, 0.998) << a.Text();
  EXPECT_GT(a.both_found, 1000u) << a.Text();
  EXPECT_LT(a.median_px, 0.001) << a.Text();
  EXPECT_LT(a.p95_px, 0.002) << a.Text();
  EXPECT_LE(a.apart, 0.002) << a.Text();
  EXPECT_LT(a.error_p95, 0.005) << a.Text();
  EXPECT_LT(a.error_p99, 0.01) << a.Text();
}

TEST(LkTwin, MatchesOpenCvOnKittiFrames) {
  struct FramePair {
    std::string prev, cur;
  };
  const std::vector<FramePair> pairs = {{Odometry06(10), Odometry06(11)},
                                        {Odometry06(30), Odometry06(32)},
                                        {Raw0005(20), Raw0005(21)}};
  std::unique_ptr<FlowEngine> twin = MakeLkFlowEngine("twin");
  EXPECT_EQ(twin->Name(), "cpu-twin");
  double twin_ms = 0.0, opencv_ms = 0.0;
  int passes = 0;
  for (const FramePair& pair : pairs) {
    const cv::Mat prev = LoadGray(pair.prev), cur = LoadGray(pair.cur);
    ASSERT_FALSE(prev.empty() || cur.empty());
    const std::vector<cv::Mat> prev_pyr = BuildLkPyramid(prev, PyramidOptions());
    const std::vector<cv::Mat> cur_pyr = BuildLkPyramid(cur, PyramidOptions());
    const std::vector<cv::Point2f> cur_pts = TrackedPoints(cur);
    ASSERT_GT(cur_pts.size(), 1500u);
    std::vector<cv::Point2f> shifted = cur_pts;
    for (cv::Point2f& p : shifted) p += cv::Point2f(2.5f, -1.5f);

    auto check = [&](const char* what, const std::vector<cv::Mat>& from,
                     const std::vector<cv::Mat>& to, const std::vector<cv::Point2f>& from_pts,
                     const std::vector<cv::Point2f>& initial, const LkPass& pass) {
      const PassResult want = RunOpenCv(from, to, from_pts, initial, pass);
      const PassResult got = RunEngine(*twin, from, to, from_pts, initial, pass);
      const Agreement a = Compare(got, want);
      std::printf("%s, %s: %s (twin %.1f ms, opencv %.1f ms)\n", pair.cur.c_str(), what,
                  a.Text().c_str(), got.ms, want.ms);
      SCOPED_TRACE(pair.cur + ", " + what);
      ExpectAgreesWithOpenCv(a);
      twin_ms += got.ms;
      opencv_ms += want.ms;
      ++passes;
      return want;
    };
    // Into the previous image from zero flow, then from a shifted guess (on all levels, and on
    // the two finest as the filter's guided search), then back (started at the forward matches,
    // from the original points as the guess), as the filter's round trip.
    const PassResult forward = check("forward", cur_pyr, prev_pyr, cur_pts, {}, Pass(3, false));
    check("guess, 3 levels", cur_pyr, prev_pyr, cur_pts, shifted, Pass(3, true));
    check("guess, 1 level", cur_pyr, prev_pyr, cur_pts, shifted, Pass(1, true));
    std::vector<cv::Point2f> back_start, back_guess;
    for (size_t i = 0; i < cur_pts.size(); ++i) {
      if (!forward.status[i]) continue;
      back_start.push_back(forward.to[i]);
      back_guess.push_back(cur_pts[i]);
    }
    check("backward", prev_pyr, cur_pyr, back_start, back_guess, Pass(3, true));
  }
  std::printf("mean per pass over %d passes (~2000 points): twin %.1f ms, opencv %.1f ms\n", passes,
              twin_ms / passes, opencv_ms / passes);
}

// A synthetic check independent of OpenCV's tracker: an image shifted by whole pixels is found
// at the shift, with a match error near zero.
TEST(LkTwin, FindsAWholePixelShift) {
  const cv::Mat image = LoadGray(Odometry06(5));
  ASSERT_FALSE(image.empty());
  const int dx = 7, dy = -3;
  cv::Mat shifted(image.size(), image.type(), cv::Scalar(0));
  const cv::Rect src(std::max(0, -dx), std::max(0, -dy), image.cols - std::abs(dx),
                     image.rows - std::abs(dy));
  image(src).copyTo(shifted(src + cv::Point(dx, dy)));
  const std::vector<cv::Mat> from = BuildLkPyramid(image, PyramidOptions());
  const std::vector<cv::Mat> to = BuildLkPyramid(shifted, PyramidOptions());
  std::vector<cv::Point2f> points;
  cv::goodFeaturesToTrack(image(cv::Rect(40, 40, image.cols - 80, image.rows - 80)), points, 500,
                          0.01, 8.0);
  for (cv::Point2f& p : points) p += cv::Point2f(40.0f, 40.0f);
  ASSERT_GT(points.size(), 200u);
  std::unique_ptr<FlowEngine> twin = MakeLkFlowEngine("twin");
  const PassResult r = RunEngine(*twin, from, to, points, {}, Pass(3, false));
  int found = 0, on_target = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!r.status[i]) continue;
    ++found;
    const double miss = cv::norm(r.to[i] - (points[i] + cv::Point2f(dx, dy)));
    if (miss < 0.02 && r.error[i] < 0.5f) ++on_target;
  }
  EXPECT_GT(found, static_cast<int>(points.size() * 0.95));
  EXPECT_GT(on_target, static_cast<int>(found * 0.95)) << found;
}

// Bitwise equal fields.
bool SameResult(const LkPointResult& a, const LkPointResult& b) {
  auto bits = [](float v) {
    uint32_t u = 0;
    std::memcpy(&u, &v, sizeof u);
    return u;
  };
  return bits(a.x) == bits(b.x) && bits(a.y) == bits(b.y) && bits(a.error) == bits(b.error) &&
         a.status == b.status;
}

// LkTrackPoint run by a group of 32 lanes as the CUDA kernel's warp runs it (lane i visits
// window pixels i, i + 32, ...), here one thread per lane with a barrier for Sum(), on the CPU.
class ThreadWarp {
 public:
  static constexpr int kLanes = 32;

  struct Lanes {
    ThreadWarp* warp = nullptr;
    int16_t* image_window = nullptr;
    int16_t* deriv_window = nullptr;
    int first = 0;
    int stride = kLanes;
    int64_t Sum(int64_t v) const { return warp->AllReduce(first, v); }
  };

  LkPointResult Track(const LkPyramidViews& views, const LkSettings& settings, cv::Point2f from,
                      cv::Point2f guess) {
    const int area = settings.window * settings.window;
    std::vector<int16_t> shared(3 * static_cast<size_t>(area));  // the warp's shared memory
    std::vector<LkPointResult> results(kLanes);
    std::vector<std::thread> threads;
    for (int lane = 0; lane < kLanes; ++lane) {
      threads.emplace_back([&, lane] {
        Lanes lanes;
        lanes.warp = this;
        lanes.image_window = shared.data();
        lanes.deriv_window = shared.data() + area;
        lanes.first = lane;
        results[lane] = LkTrackPoint(lanes, views, settings, from.x, from.y, guess.x, guess.y);
      });
    }
    for (std::thread& t : threads) t.join();
    for (const LkPointResult& r : results) {  // every lane ends with the same result
      EXPECT_TRUE(SameResult(r, results[0]));
    }
    return results[0];
  }

 private:
  int64_t AllReduce(int lane, int64_t v) {
    values_[lane] = v;
    barrier_.arrive_and_wait();
    int64_t total = 0;
    for (int64_t x : values_) total += x;
    barrier_.arrive_and_wait();  // all have read before the next Sum writes
    return total;
  }

  int64_t values_[kLanes] = {};
  std::barrier<> barrier_{kLanes};
};

// Needs no GPU: the CUDA kernel's way through a window (32 lanes, strided pixels, sums over
// lanes) gives bitwise the twin's results, for windows smaller and larger than a warp.
TEST(LkMath, AWarpOfLanesMatchesOneLane) {
  const cv::Mat prev = LoadGray(Odometry06(20)), cur = LoadGray(Odometry06(21));
  ASSERT_FALSE(prev.empty() || cur.empty());
  const std::vector<cv::Mat> prev_pyr = BuildLkPyramid(prev, PyramidOptions(31, 3));
  const std::vector<cv::Mat> cur_pyr = BuildLkPyramid(cur, PyramidOptions(31, 3));
  std::vector<cv::Point2f> pts = TrackedPoints(cur);
  std::vector<cv::Point2f> sample;  // corners and edge points
  for (size_t i = 0; i < pts.size(); i += pts.size() / 24) sample.push_back(pts[i]);
  sample.insert(sample.end(), pts.end() - 12, pts.end());
  ThreadWarp warp;
  for (int window : {5, 21, 31}) {
    LkPass pass = Pass(3, true);
    pass.window_px = window;
    const LkSettings settings =
        lk_detail::CheckTrackInputs(cur_pyr, prev_pyr, sample.size(), sample.size(), pass);
    const LkPyramidViews views = lk_detail::HostViews(cur_pyr, prev_pyr, pass.max_level);
    std::vector<int16_t> buffer(3 * static_cast<size_t>(window * window));
    LkSerialLanes serial;
    serial.image_window = buffer.data();
    serial.deriv_window = buffer.data() + window * window;
    int found = 0;
    for (const cv::Point2f& p : sample) {
      const cv::Point2f guess = p + cv::Point2f(1.5f, -0.75f);
      const LkPointResult want = LkTrackPoint(serial, views, settings, p.x, p.y, guess.x, guess.y);
      const LkPointResult got = warp.Track(views, settings, p, guess);
      EXPECT_TRUE(SameResult(got, want))
          << "window " << window << ", point " << p << ": " << got.x << " " << got.y << " "
          << int{got.status} << " " << got.error << " vs " << want.x << " " << want.y << " "
          << int{want.status} << " " << want.error;
      found += want.status;
    }
    EXPECT_GT(found, static_cast<int>(sample.size()) / 2) << window;
  }
}

std::vector<std::string> Devices() {
  std::vector<std::string> devices = {"twin"};
  if (CudaDeviceCount() > 0) devices.push_back("cuda");
  return devices;
}

bool SameResults(const PassResult& a, const PassResult& b) {
  if (a.to.size() != b.to.size() || a.status != b.status || a.error.size() != b.error.size()) {
    return false;
  }
  return std::memcmp(a.to.data(), b.to.data(), a.to.size() * sizeof(cv::Point2f)) == 0 &&
         std::memcmp(a.error.data(), b.error.data(), a.error.size() * sizeof(float)) == 0;
}

// The passes of a filter over frames first..last: per frame, into the previous image from zero
// flow and back from the matches; the current pyramid becomes the previous one of the next frame
// (the same vector, as the filter keeps it). `engine` null: a new engine for every pass.
std::vector<PassResult> FilterPasses(const std::string& device, FlowEngine* engine, int first,
                                     int last) {
  std::vector<PassResult> results;
  std::vector<cv::Mat> prev_pyr = BuildLkPyramid(LoadGray(Odometry06(first)), PyramidOptions());
  for (int frame = first + 1; frame <= last; ++frame) {
    const cv::Mat cur = LoadGray(Odometry06(frame));
    std::vector<cv::Mat> cur_pyr = BuildLkPyramid(cur, PyramidOptions());
    const std::vector<cv::Point2f> pts = TrackedPoints(cur);
    std::unique_ptr<FlowEngine> fresh;
    auto pass_engine = [&]() -> FlowEngine& {
      if (engine) return *engine;
      fresh = MakeLkFlowEngine(device);
      return *fresh;
    };
    const PassResult forward = RunEngine(pass_engine(), cur_pyr, prev_pyr, pts, {}, Pass(3, false));
    results.push_back(forward);
    results.push_back(RunEngine(pass_engine(), prev_pyr, cur_pyr, forward.to, pts, Pass(3, true)));
    prev_pyr = std::move(cur_pyr);
  }
  return results;
}

// On a machine without CUDA only the twin runs, which keeps no state between passes: there this is
// a determinism check (and that the passes track something); the cached pyramids a reused engine
// must not confuse are the CUDA engine's.
TEST(LkFlow, AnEngineOverASequenceMatchesFreshEngines) {
  for (const std::string& device : Devices()) {
    SCOPED_TRACE(device);
    std::unique_ptr<FlowEngine> engine = MakeLkFlowEngine(device);
    // Five frames: more pyramids than a CUDA engine caches, so entries are replaced.
    const std::vector<PassResult> reused = FilterPasses(device, engine.get(), 0, 5);
    const std::vector<PassResult> fresh = FilterPasses(device, nullptr, 0, 5);
    ASSERT_EQ(reused.size(), 10u);  // two passes for each of frames 1-5
    ASSERT_EQ(reused.size(), fresh.size());
    for (size_t i = 0; i < reused.size(); ++i) {
      EXPECT_TRUE(SameResults(reused[i], fresh[i])) << i;
      // Agreeing on nothing found would be no check: most points are found in every pass
      // (measured on the twin: 1879-2029 of 2041).
      const size_t found = static_cast<size_t>(std::count_if(
          reused[i].status.begin(), reused[i].status.end(), [](uint8_t s) { return s != 0; }));
      EXPECT_GT(found, reused[i].status.size() * 3 / 4)
          << "pass " << i << ": " << found << " of " << reused[i].status.size() << " found";
    }
  }
}

// cv::buildOpticalFlowPyramid stops below max_level once a level would be no larger than the
// window; the filter's passes then use the levels there are, on every engine, as OpenCV does.
TEST(LkFlow, PyramidsShorterThanMaxLevelTrackAsOnOpenCv) {
  LkOptions options;
  options.max_level = 6;
  const cv::Mat prev = test::RandomTexture({120, 80}, 4, 1.5, /*stretch=*/false);
  const cv::Mat cur = test::Shifted(prev, 2, 1);
  const std::vector<cv::Mat> prev_pyr = BuildLkPyramid(prev, options);
  const std::vector<cv::Mat> cur_pyr = BuildLkPyramid(cur, options);
  ASSERT_LT(prev_pyr.size() / 2, static_cast<size_t>(options.max_level + 1));
  std::vector<cv::Point2f> pts;
  for (int v = 20; v <= 60; v += 10) {
    for (int u = 20; u <= 100; u += 10) pts.emplace_back(static_cast<float>(u), v * 1.0f);
  }
  const FlowTracks on_opencv = TrackIntoPrevious(prev_pyr, cur_pyr, pts, options);
  EXPECT_GT(on_opencv.num_valid, static_cast<int>(pts.size()) / 2);
  for (const std::string& device : Devices()) {
    SCOPED_TRACE(device);
    std::unique_ptr<FlowEngine> engine = MakeLkFlowEngine(device);
    FlowTracks on_engine;
    ASSERT_NO_THROW(on_engine =
                        TrackIntoPrevious(prev_pyr, cur_pyr, pts, options, {}, engine.get()));
    EXPECT_EQ(on_engine.num_valid, on_opencv.num_valid);
    EXPECT_EQ(on_engine.valid, on_opencv.valid);
  }
}

TEST(LkFlow, NoPointsGiveEmptyOutputs) {
  const std::vector<cv::Mat> pyr = BuildLkPyramid(LoadGray(Odometry06(0)), PyramidOptions());
  for (const std::string& device : Devices()) {
    std::unique_ptr<FlowEngine> engine = MakeLkFlowEngine(device);
    std::vector<cv::Point2f> to = {{1.0f, 2.0f}};
    std::vector<uint8_t> status = {1};
    std::vector<float> error = {3.0f};
    engine->Track(pyr, pyr, {}, to, status, error, Pass(3, false));
    EXPECT_TRUE(to.empty() && status.empty() && error.empty()) << device;
  }
}

TEST(LkFlow, BadInputIsRejected) {
  const cv::Mat image = LoadGray(Odometry06(0));
  ASSERT_FALSE(image.empty());
  const std::vector<cv::Mat> pyr = BuildLkPyramid(image, PyramidOptions());
  cv::Mat smaller;
  cv::resize(image, smaller, cv::Size(image.cols - 16, image.rows));
  const std::vector<cv::Mat> smaller_pyr = BuildLkPyramid(smaller, PyramidOptions());
  const std::vector<cv::Mat> two_levels = BuildLkPyramid(image, PyramidOptions(21, 1));
  const std::vector<cv::Mat> narrow_border = BuildLkPyramid(image, PyramidOptions(11, 3));
  std::vector<cv::Mat> no_derivatives;
  cv::buildOpticalFlowPyramid(image, no_derivatives, cv::Size(21, 21), 3, false);
  const std::vector<cv::Point2f> pts = {{100.0f, 100.0f}, {500.0f, 200.0f}};
  for (const std::string& device : Devices()) {
    SCOPED_TRACE(device);
    std::unique_ptr<FlowEngine> engine = MakeLkFlowEngine(device);
    std::vector<cv::Point2f> to;
    std::vector<uint8_t> status;
    std::vector<float> error;
    auto track = [&](const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& into,
                     const LkPass& pass) {
      engine->Track(from, into, pts, to, status, error, pass);
    };
    EXPECT_THROW(track(pyr, smaller_pyr, Pass(3, false)), std::invalid_argument);
    EXPECT_THROW(track(smaller_pyr, pyr, Pass(0, false)), std::invalid_argument);
    EXPECT_THROW(track(pyr, two_levels, Pass(3, false)), std::invalid_argument);
    EXPECT_THROW(track(two_levels, pyr, Pass(2, false)), std::invalid_argument);
    EXPECT_NO_THROW(track(two_levels, pyr, Pass(1, false)));  // levels 0..1 are there
    EXPECT_THROW(track(narrow_border, pyr, Pass(3, false)), std::invalid_argument);
    EXPECT_THROW(track(pyr, no_derivatives, Pass(3, false)), std::invalid_argument);
    EXPECT_THROW(track({}, pyr, Pass(3, false)), std::invalid_argument);
    LkPass pass = Pass(3, false);
    pass.window_px = 20;
    EXPECT_THROW(track(pyr, pyr, pass), std::invalid_argument);
    pass.window_px = 3;
    EXPECT_THROW(track(pyr, pyr, pass), std::invalid_argument);
    pass = Pass(3, false);
    pass.epsilon_px = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(track(pyr, pyr, pass), std::invalid_argument);
    to.assign(1, cv::Point2f(0.0f, 0.0f));  // one guess for two points
    EXPECT_THROW(track(pyr, pyr, Pass(3, true)), std::invalid_argument);
    // A smaller window than the pyramids were built with is fine.
    pass = Pass(3, false);
    pass.window_px = 15;
    EXPECT_NO_THROW(track(pyr, pyr, pass));
    EXPECT_EQ(status.size(), pts.size());
  }
}

TEST(LkFlow, DeviceNames) {
  EXPECT_TRUE(IsLkFlowDevice("twin"));
  EXPECT_TRUE(IsLkFlowDevice("cuda"));
  EXPECT_TRUE(IsLkFlowDevice("cuda:1"));
  for (const char* bad : {"", "gpu", "cuda:", "cuda:x", "cuda:-1", "opencv", "Twin"}) {
    EXPECT_FALSE(IsLkFlowDevice(bad)) << bad;
    EXPECT_THROW(MakeLkFlowEngine(bad), std::invalid_argument) << bad;
    EXPECT_THROW(LkFlowFactory(bad), std::invalid_argument) << bad;
  }
  FlowEngineFactory factory = LkFlowFactory("twin");
  ASSERT_TRUE(factory);
  EXPECT_EQ(factory()->Name(), "cpu-twin");
}

// Needs no GPU: without CUDA in the build, or without a device, "cuda" is a runtime error that
// says why; a device number beyond those present is one everywhere.
TEST(LkFlow, CudaWithoutADeviceIsARuntimeError) {
  std::string why;
  const int count = CudaDeviceCount(&why);
  EXPECT_THROW(MakeLkFlowEngine("cuda:" + std::to_string(count + 3)), std::runtime_error);
  if (count > 0) GTEST_SKIP() << "this machine has a CUDA device";
  try {
    MakeLkFlowEngine("cuda");
    FAIL() << "a CUDA engine was made without a device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
  }
  FlowEngineFactory factory = LkFlowFactory("cuda");  // the name is fine
  EXPECT_THROW(factory(), std::runtime_error);
}

using test::BlockingWait;

// The twin through a DeviceWait (as the flow graph installs one): the pass runs inside the
// launch, done() once per pass, bitwise the tracks of the twin without one.
TEST(LkFlow, TheTwinThroughADeviceWaitGivesTheSameTracks) {
  const cv::Mat prev = LoadGray(Odometry06(20)), cur = LoadGray(Odometry06(21));
  const std::vector<cv::Mat> prev_pyr = BuildLkPyramid(prev, PyramidOptions());
  const std::vector<cv::Mat> cur_pyr = BuildLkPyramid(cur, PyramidOptions());
  const std::vector<cv::Point2f> pts = TrackedPoints(cur);
  ASSERT_GT(pts.size(), 500u);
  std::unique_ptr<FlowEngine> plain = MakeLkFlowEngine("twin");
  std::unique_ptr<FlowEngine> waited = MakeLkFlowEngine("twin");
  BlockingWait wait;
  waited->SetDeviceWait(wait.Get());
  LkPass pass;
  std::vector<cv::Point2f> to_a, to_b;
  std::vector<uint8_t> status_a, status_b;
  std::vector<float> error_a, error_b;
  plain->Track(cur_pyr, prev_pyr, pts, to_a, status_a, error_a, pass);
  waited->Track(cur_pyr, prev_pyr, pts, to_b, status_b, error_b, pass);
  EXPECT_TRUE(SameResults({to_a, status_a, error_a}, {to_b, status_b, error_b}));
  EXPECT_GT(std::count(status_b.begin(), status_b.end(), 1), static_cast<long>(pts.size() / 2));
  EXPECT_EQ(wait.waits, 1);
  EXPECT_EQ(wait.dones, 1);
  // No points: nothing to launch.
  std::vector<cv::Point2f> none, to_none;
  waited->Track(cur_pyr, prev_pyr, none, to_none, status_b, error_b, pass);
  EXPECT_EQ(wait.waits, 1);
  // Bad input throws before the launch.
  LkPass even = pass;
  even.window_px = 20;
  EXPECT_THROW(waited->Track(cur_pyr, prev_pyr, pts, to_b, status_b, error_b, even),
               std::invalid_argument);
  EXPECT_EQ(wait.waits, 1);
  waited->SetDeviceWait({});
  waited->Track(cur_pyr, prev_pyr, pts, to_b, status_b, error_b, pass);
  EXPECT_EQ(wait.waits, 1);
  EXPECT_TRUE(SameResults({to_a, status_a, error_a}, {to_b, status_b, error_b}));
}

// On a machine with a CUDA device: the CUDA engine against its twin, which runs the same
// per-point code; skipped, saying why, elsewhere.
TEST(LkCuda, MatchesTheTwin) {
  std::string why;
  if (CudaDeviceCount(&why) == 0) GTEST_SKIP() << "no CUDA device: " << why;
  std::unique_ptr<FlowEngine> twin = MakeLkFlowEngine("twin");
  std::unique_ptr<FlowEngine> cuda = MakeLkFlowEngine("cuda");
  EXPECT_EQ(cuda->Name().rfind("cuda:0 (", 0), 0u) << cuda->Name();
  BlockingWait wait;
  int waited_passes = 0;
  for (int frame : {10, 30}) {
    SCOPED_TRACE(frame);
    const cv::Mat prev = LoadGray(Odometry06(frame)), cur = LoadGray(Odometry06(frame + 1));
    const std::vector<cv::Mat> prev_pyr = BuildLkPyramid(prev, PyramidOptions());
    const std::vector<cv::Mat> cur_pyr = BuildLkPyramid(cur, PyramidOptions());
    const std::vector<cv::Point2f> pts = TrackedPoints(cur);
    std::vector<cv::Point2f> shifted = pts;
    for (cv::Point2f& p : shifted) p += cv::Point2f(-3.5f, 1.25f);
    struct Case {
      const std::vector<cv::Mat>* from;
      const std::vector<cv::Mat>* to;
      const std::vector<cv::Point2f>* initial;
      LkPass pass;
    };
    const std::vector<cv::Point2f> none;
    const std::vector<Case> cases = {{&cur_pyr, &prev_pyr, &none, Pass(3, false)},
                                     {&cur_pyr, &prev_pyr, &shifted, Pass(1, true)},
                                     {&prev_pyr, &cur_pyr, &shifted, Pass(3, true)}};
    // Blocking, then through the wait; the same pyramids every time (the cache's hits).
    for (int through_wait = 0; through_wait < 2; ++through_wait) {
      cuda->SetDeviceWait(through_wait ? wait.Get() : DeviceWait());
      for (const Case& c : cases) {
        const PassResult want = RunEngine(*twin, *c.from, *c.to, pts, *c.initial, c.pass);
        const PassResult got = RunEngine(*cuda, *c.from, *c.to, pts, *c.initial, c.pass);
        const Agreement a = Compare(got, want);
        std::printf("cuda vs twin, frame %d: %s (cuda %.2f ms, twin %.1f ms)\n", frame + 1,
                    a.Text().c_str(), got.ms, want.ms);
        EXPECT_TRUE(SameResults(got, want)) << a.Text();
        EXPECT_EQ(a.status_agreement, 1.0);
        EXPECT_LT(a.max_px, 1e-4) << a.Text();
        EXPECT_LT(a.error_max, 1e-4) << a.Text();
        waited_passes += through_wait;
      }
    }
  }
  EXPECT_EQ(wait.waits, waited_passes);
  EXPECT_EQ(wait.dones, waited_passes);
  EXPECT_NE(wait.done_thread, std::this_thread::get_id());
}

}  // namespace
}  // namespace pcr::gpu::lk_test
