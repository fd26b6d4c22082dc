// Stereo matching of KITTI seq 06 frame 0 (image_0 + image_1, 1226 x 370) with the default
// OrbExtractor and StereoMatchOptions: MatchStereo alone on precomputed features, and the whole
// frame (left and right extraction + matching) for scale. Single-threaded OpenCV.
// Counters: left keypoints and the matched fraction.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>

#include "bench_args.h"
#include "bench_main.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"

namespace {

cv::Mat LoadGrey(const char* camera_dir) {
  const std::string path =
      pcr::bench::SharedDir() + "/data/kitti/sequences/06/" + camera_dir + "/000000.png";
  cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw std::runtime_error("cannot read " + path);
  return img;
}

pcr::StereoRig KittiSeq06Rig() {
  pcr::StereoRig rig;
  rig.left = {707.0912, 707.0912, 601.8873, 183.1104, 1226, 370};
  rig.baseline_m = 379.8145 / 707.0912;  // calib.txt P1(0,3) = -fx * baseline
  return rig;
}

struct Frame {
  cv::Mat left_img, right_img;
  pcr::OrbExtractor extractor{pcr::OrbOptions{}};
  pcr::OrbFeatures left, right;
};

const Frame& KittiFrame() {
  static const Frame frame = [] {
    Frame f;
    f.left_img = LoadGrey("image_0");
    f.right_img = LoadGrey("image_1");
    f.left = f.extractor.Extract(f.left_img);
    f.right = f.extractor.Extract(f.right_img);
    return f;
  }();
  return frame;
}

void SetCounters(benchmark::State& state, const pcr::StereoMatches& m, size_t n_left) {
  state.counters["left_keypoints"] = static_cast<double>(n_left);
  state.counters["matched_fraction"] = static_cast<double>(m.num_matched) / n_left;
}

void BM_MatchStereo(benchmark::State& state) {
  cv::setNumThreads(1);
  const Frame& f = KittiFrame();
  const pcr::StereoRig rig = KittiSeq06Rig();
  pcr::StereoMatches m;
  for (auto _ : state) {
    m = pcr::MatchStereo(rig, f.left, f.right, f.extractor.scale_factors());
    benchmark::DoNotOptimize(m.depth_m.data());
  }
  SetCounters(state, m, f.left.keypoints.size());
}

void BM_StereoFrame(benchmark::State& state) {
  cv::setNumThreads(1);
  const Frame& f = KittiFrame();
  const pcr::StereoRig rig = KittiSeq06Rig();
  pcr::StereoMatches m;
  size_t n_left = 0;
  for (auto _ : state) {
    const pcr::OrbFeatures left = f.extractor.Extract(f.left_img);
    const pcr::OrbFeatures right = f.extractor.Extract(f.right_img);
    m = pcr::MatchStereo(rig, left, right, f.extractor.scale_factors());
    n_left = left.keypoints.size();
    benchmark::DoNotOptimize(m.depth_m.data());
  }
  SetCounters(state, m, n_left);
}

BENCHMARK(BM_MatchStereo)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StereoFrame)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) { return pcr::bench::RunBenchmarks("bench_stereo", argc, argv); }
