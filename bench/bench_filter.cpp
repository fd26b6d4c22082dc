// Dynamic-point filter stages on a real KITTI frame pair (seq 06 frames 10 -> 11, 1226 x 370,
// default OrbExtractor: 2000 keypoints, stereo depths from MatchStereo), single-threaded OpenCV:
//   BM_FilterLkPyramid      LK pyramid of one image (built once per frame, kept for the next);
//   BM_FilterFlow           LK back into the previous image: zero-flow and predicted-flow searches
//                           plus the forward-backward check (as Process runs it);
//   BM_FilterFlowNoGuess    the zero-flow search and the check only (lk_predict_initial_flow off);
//                           both per LK window side (11, 15, 21 px);
//   BM_FilterPnp            PnP RANSAC ego-motion on the tracked stereo points;
//   BM_FilterGroundRansac   ground plane RANSAC + least squares on the stereo points;
//   BM_FilterProcess*       the whole DynamicFilter::Process of frame 11 (frame 10 processed
//                           before, untimed), default options: with the ground-truth motion as the
//                           prior (the default policy still runs PnP, seeded by it), without a
//                           prior, and with a YOLOv8-seg segmentation (computed once, not timed).
// Process counters: the per-stage times of the last run (ms) and the keypoint counts.
// Note: benchmark::DoNotOptimize is only given ints and pointers here; with this Google
// Benchmark and GCC, handing it a double member corrupted the value.
#include <benchmark/benchmark.h>

#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "bench_args.h"
#include "bench_main.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"

namespace {

const std::string kSequence = pcr::bench::SharedDir() + "/data/kitti/sequences/06/";

cv::Mat LoadGrey(const std::string& camera_dir, int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "/%06d.png", frame);
  const std::string path = kSequence + camera_dir + name;
  cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw std::runtime_error("cannot read " + path);
  return img;
}

pcr::SE3 GroundTruthPose(int frame) {
  const std::string path = pcr::bench::SharedDir() + "/data/kitti/poses/06.txt";
  std::ifstream in(path);
  std::string line;
  for (int i = 0; std::getline(in, line); ++i) {
    if (i != frame) continue;
    std::istringstream ss(line);
    pcr::SE3 pose = pcr::SE3::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        double v = 0;
        ss >> v;
        if (c < 3) {
          pose.linear()(r, c) = v;
        } else {
          pose.translation()(r) = v;
        }
      }
    }
    return pose;
  }
  throw std::runtime_error("no pose for frame " + std::to_string(frame) + " in " + path);
}

pcr::StereoRig KittiSeq06Rig() {
  pcr::StereoRig rig;
  rig.left = {707.0912, 707.0912, 601.8873, 183.1104, 1226, 370};
  rig.baseline_m = 379.8145 / 707.0912;  // calib.txt P1(0,3) = -fx * baseline
  return rig;
}

struct PairData {
  cv::Mat image[2];
  std::vector<cv::KeyPoint> keypoints[2];
  std::vector<float> depth[2];
  pcr::SE3 cur_from_prev;
  pcr::Segmentation segmentation[2];
};

const PairData& Pair() {
  static const PairData data = [] {
    cv::setNumThreads(1);
    PairData d;
    const pcr::OrbExtractor extractor{pcr::OrbOptions{}};
    const pcr::StereoRig rig = KittiSeq06Rig();
    for (int k = 0; k < 2; ++k) {
      d.image[k] = LoadGrey("image_0", 10 + k);
      const pcr::OrbFeatures left = extractor.Extract(d.image[k]);
      const pcr::OrbFeatures right = extractor.Extract(LoadGrey("image_1", 10 + k));
      d.keypoints[k] = left.keypoints;
      d.depth[k] = pcr::MatchStereo(rig, left, right, extractor.scale_factors()).depth_m;
    }
    d.cur_from_prev = GroundTruthPose(11).inverse() * GroundTruthPose(10);
    return d;
  }();
  return data;
}

const PairData& PairWithSegmentation() {
  static const PairData data = [] {
    PairData d = Pair();
    pcr::YoloOptions options;
    options.model_path = pcr::bench::SharedDir() + "/models/yolov8n-seg_coco_384x1280.onnx";
    pcr::YoloSegmenter segmenter(options);
    for (int k = 0; k < 2; ++k) d.segmentation[k] = segmenter.Segment(d.image[k]);
    return d;
  }();
  return data;
}

pcr::FilterInput Input(const PairData& d, int k, bool prior, bool segmentation) {
  pcr::FilterInput in;
  in.frame_index = 10 + k;
  in.t_ns = (10 + k) * 103'000'000LL;
  in.left_image = d.image[k];
  in.keypoints = d.keypoints[k];
  in.depth_m = d.depth[k];
  in.rig = KittiSeq06Rig();
  if (segmentation) in.segmentation = &d.segmentation[k];
  if (prior && k == 1) in.cur_from_prev = d.cur_from_prev;
  return in;
}

// Predicted previous positions under the ground-truth motion of the keypoints with a stereo
// depth, (-1, -1) for the others (the LK guesses Process builds).
std::vector<cv::Point2f> Guess(const PairData& d) {
  const pcr::StereoRig rig = KittiSeq06Rig();
  const pcr::SE3 prev_from_cur = d.cur_from_prev.inverse();
  std::vector<cv::Point2f> guess(d.keypoints[1].size(), cv::Point2f(-1.0f, -1.0f));
  for (size_t i = 0; i < d.keypoints[1].size(); ++i) {
    if (!(d.depth[1][i] > 0)) continue;
    const cv::Point2f uv = d.keypoints[1][i].pt;
    const Eigen::Vector3d p = prev_from_cur * rig.left.Unproject({uv.x, uv.y}, d.depth[1][i]);
    const Eigen::Vector2d q = rig.left.Project(p);
    if (p.z() > 0.05 && rig.left.InImage(q)) {
      guess[i] = cv::Point2f(static_cast<float>(q.x()), static_cast<float>(q.y()));
    }
  }
  return guess;
}

std::vector<cv::Point2f> Points(const std::vector<cv::KeyPoint>& keypoints) {
  std::vector<cv::Point2f> pts;
  for (const cv::KeyPoint& kp : keypoints) pts.push_back(kp.pt);
  return pts;
}

void BM_FilterLkPyramid(benchmark::State& state) {
  cv::setNumThreads(1);
  const PairData& d = Pair();
  for (auto _ : state) {
    const auto pyramid = pcr::BuildLkPyramid(d.image[1], pcr::LkOptions{});
    benchmark::DoNotOptimize(pyramid.data());
  }
}

void RunFlow(benchmark::State& state, bool with_guess) {
  cv::setNumThreads(1);
  const PairData& d = Pair();
  pcr::LkOptions options;
  options.window_px = static_cast<int>(state.range(0));
  const auto prev = pcr::BuildLkPyramid(d.image[0], options);
  const auto cur = pcr::BuildLkPyramid(d.image[1], options);
  const std::vector<cv::Point2f> pts = Points(d.keypoints[1]);
  const std::vector<cv::Point2f> guess = with_guess ? Guess(d) : std::vector<cv::Point2f>{};
  pcr::FlowTracks tracks;
  for (auto _ : state) {
    tracks = pcr::TrackIntoPrevious(prev, cur, pts, options, guess);
    benchmark::DoNotOptimize(tracks.prev_uv_px.data());
  }
  state.counters["keypoints"] = static_cast<double>(pts.size());
  state.counters["tracked"] = tracks.num_valid;
  state.counters["window"] = options.window_px;
}
void BM_FilterFlow(benchmark::State& state) { RunFlow(state, true); }
void BM_FilterFlowNoGuess(benchmark::State& state) { RunFlow(state, false); }

void BM_FilterPnp(benchmark::State& state) {
  cv::setNumThreads(1);
  const PairData& d = Pair();
  const pcr::LkOptions options;
  const std::vector<cv::Point2f> pts = Points(d.keypoints[1]);
  const pcr::FlowTracks tracks =
      pcr::TrackIntoPrevious(pcr::BuildLkPyramid(d.image[0], options),
                             pcr::BuildLkPyramid(d.image[1], options), pts, options, Guess(d));
  pcr::EgoMotionEstimate est;
  for (auto _ : state) {
    est = pcr::EstimateCurFromPrev(KittiSeq06Rig().left, pts, d.depth[1], tracks.prev_uv_px,
                                   tracks.valid, nullptr, pcr::EgoMotionOptions{});
    benchmark::DoNotOptimize(est.num_inliers);
  }
  state.counters["candidates"] = est.num_candidates;
  state.counters["inliers"] = est.num_inliers;
}

void BM_FilterGroundRansac(benchmark::State& state) {
  const PairData& d = Pair();
  const pcr::StereoRig rig = KittiSeq06Rig();
  std::vector<Eigen::Vector3d> points;
  std::vector<uint8_t> usable;
  for (size_t i = 0; i < d.keypoints[1].size(); ++i) {
    const cv::Point2f uv = d.keypoints[1][i].pt;
    const float z = d.depth[1][i];
    points.push_back(z > 0 ? rig.left.Unproject({uv.x, uv.y}, z) : Eigen::Vector3d::Zero());
    usable.push_back(z > 0);
  }
  pcr::GroundEstimate est;
  for (auto _ : state) {
    est = pcr::EstimateGroundPlane(points, usable, 0.0, pcr::GroundOptions{});
    benchmark::DoNotOptimize(est.num_inliers);  // (not a double: see the note below)
  }
  state.counters["candidates"] = est.num_candidates;
  state.counters["inliers"] = est.num_inliers;
  state.counters["height_m"] = est.height_m();
  state.counters["success"] = est.success;
  state.counters["tilt"] = pcr::GroundTiltDeg(est.plane);
}

void RunProcess(benchmark::State& state, bool prior, bool segmentation) {
  cv::setNumThreads(1);
  const PairData& d = segmentation ? PairWithSegmentation() : Pair();
  // Only Process(frame 11) is timed: the filter, its input and the previous output live outside
  // the loop and are torn down (LK pyramids, copies, the output's vectors) while timing is paused.
  std::optional<pcr::DynamicFilter> filter;
  std::optional<pcr::FilterInput> in;
  pcr::FilterOutput out;
  for (auto _ : state) {
    state.PauseTiming();
    filter.reset();
    in.reset();
    out = pcr::FilterOutput{};
    filter.emplace();
    filter->Process(Input(d, 0, prior, segmentation));
    in.emplace(Input(d, 1, prior, segmentation));
    state.ResumeTiming();
    out = filter->Process(*in);  // out is empty: the assignment frees nothing
    benchmark::DoNotOptimize(out.filter.weight.data());
  }
  state.counters["keypoints"] = static_cast<double>(out.points.size());
  state.counters["excluded"] = out.num_excluded;
  state.counters["moving"] = out.num_moving;
  state.counters["mask_ms"] = out.timing.mask_ms;
  state.counters["flow_ms"] = out.timing.flow_ms;
  state.counters["pose_ms"] = out.timing.pose_ms;
  state.counters["ransac_ms"] = out.timing.ransac_ms;
  state.counters["scoring_ms"] = out.timing.scoring_ms;
  state.counters["total_ms"] = out.timing.total_ms;
}
void BM_FilterProcessWithPrior(benchmark::State& state) { RunProcess(state, true, false); }
void BM_FilterProcessNoPrior(benchmark::State& state) { RunProcess(state, false, false); }
void BM_FilterProcessWithPriorYolo(benchmark::State& state) { RunProcess(state, true, true); }

}  // namespace

BENCHMARK(BM_FilterLkPyramid)->Unit(benchmark::kMillisecond);
// The argument is the LK window side (LkOptions::window_px; the default is 11).
BENCHMARK(BM_FilterFlow)->Arg(11)->Arg(15)->Arg(21)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterFlowNoGuess)->Arg(11)->Arg(15)->Arg(21)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterPnp)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterGroundRansac)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterProcessWithPrior)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterProcessNoPrior)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FilterProcessWithPriorYolo)->Unit(benchmark::kMillisecond);
int main(int argc, char** argv) { return pcr::bench::RunBenchmarks("bench_filter", argc, argv); }
