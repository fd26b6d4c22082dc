// ORB extraction on KITTI seq 06 frame 0 (1226 x 370): pcr::OrbExtractor against cv::ORB with
// the same pyramid (2000 features, scale 1.2, 8 levels). The argument is the number of OpenCV
// threads (1: everything single-threaded, the fair comparison; 0: OpenCV's default pool).
// Counters: keypoints per image, occupied cells of a 24 x 8 grid over the image and the
// coefficient of variation of the per-cell counts (lower = more even).
#include <benchmark/benchmark.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_args.h"
#include "bench_main.h"
#include "slam/features/orb_extractor.h"

namespace {

const cv::Mat& KittiImage() {
  static const cv::Mat image = [] {
    const std::string path =
        pcr::bench::SharedDir() + "/data/kitti/sequences/06/image_0/000000.png";
    cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (img.empty()) throw std::runtime_error("cannot read " + path);
    return img;
  }();
  return image;
}

struct Spread {
  int occupied_cells = 0;
  double count_cv = 0;
};

Spread MeasureSpread(const std::vector<cv::KeyPoint>& keypoints, cv::Size size) {
  constexpr int kCols = 24, kRows = 8;
  std::vector<int> counts(kCols * kRows, 0);
  for (const cv::KeyPoint& kp : keypoints) {
    const int c = std::min(kCols - 1, static_cast<int>(kp.pt.x * kCols / size.width));
    const int r = std::min(kRows - 1, static_cast<int>(kp.pt.y * kRows / size.height));
    ++counts[r * kCols + c];
  }
  Spread s;
  double sum = 0, sum2 = 0;
  for (int n : counts) {
    s.occupied_cells += n > 0 ? 1 : 0;
    sum += n;
    sum2 += static_cast<double>(n) * n;
  }
  const double mean = sum / counts.size();
  s.count_cv = mean > 0 ? std::sqrt(std::max(0.0, sum2 / counts.size() - mean * mean)) / mean : 0;
  return s;
}

void SetCounters(benchmark::State& state, const std::vector<cv::KeyPoint>& keypoints) {
  const Spread s = MeasureSpread(keypoints, KittiImage().size());
  state.counters["keypoints"] = static_cast<double>(keypoints.size());
  state.counters["occupied_24x8"] = s.occupied_cells;
  state.counters["cell_count_cv"] = s.count_cv;
}

void SetThreads(const benchmark::State& state) {
  cv::setNumThreads(state.range(0) == 0 ? -1 : static_cast<int>(state.range(0)));
}

void BM_PcrOrbExtractor(benchmark::State& state) {
  SetThreads(state);
  const cv::Mat& image = KittiImage();
  const pcr::OrbExtractor extractor(pcr::OrbOptions{});  // 2000, 1.2, 8 levels, FAST 20 / 7
  pcr::OrbFeatures features;
  for (auto _ : state) {
    features = extractor.Extract(image);
    benchmark::DoNotOptimize(features.descriptors.data);
  }
  SetCounters(state, features.keypoints);
}

void RunCvOrb(benchmark::State& state, cv::ORB::ScoreType score) {
  SetThreads(state);
  const cv::Mat& image = KittiImage();
  cv::Ptr<cv::ORB> orb = cv::ORB::create(2000, 1.2f, 8, 31, 0, 2, score, 31, 20);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (auto _ : state) {
    orb->detectAndCompute(image, cv::noArray(), keypoints, descriptors);
    benchmark::DoNotOptimize(descriptors.data);
  }
  SetCounters(state, keypoints);
}

void BM_CvOrbHarris(benchmark::State& state) { RunCvOrb(state, cv::ORB::HARRIS_SCORE); }
void BM_CvOrbFast(benchmark::State& state) { RunCvOrb(state, cv::ORB::FAST_SCORE); }

BENCHMARK(BM_PcrOrbExtractor)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CvOrbHarris)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CvOrbFast)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) { return pcr::bench::RunBenchmarks("bench_orb", argc, argv); }
