// Tracking through turns: PCR-ORB (stereo, sequential policy, no loop closing) against a naive
// frame-to-frame stereo VO (OpenCV ORB, left-right matching on the rectified rows, PnP RANSAC
// between consecutive frames, poses chained), both on the same turn-rich synthetic loops
// (`pcr_orb synth --route loop`: four 90-degree corners), in one run, so the ratio of their
// SE(3) ATEs is measured on the same machine state. Prints per case: frames tracked, the largest
// per-frame rotation error (degrees, against the rendered poses; both start at the identity),
// the SE(3) ATE and the ratio to the naive VO's.
//
//   bench_turns [--frames 600] [--seeds 1,2,3] [--speeds 5,8,12] [--movers 0,6] [--work DIR]
//               [--sequence DIR ...]   (a KITTI sequence with ground truth instead of loops)
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <string>
#include <vector>

#include "bench_args.h"
#include "driver/driver.h"
#include "eval/association.h"
#include "eval/evaluation.h"
#include "io/dataset.h"
#include "sim/sequence_writer.h"
#include "slam/common/error.h"
#include "slam/common/lie.h"
#include "slam/common/validation.h"
#include "slam/geometry/cv_pose.h"
#include "slam/geometry/se3.h"

namespace {

// The naive baseline: frame-to-frame stereo VO with OpenCV's own ORB and PnP RANSAC.
pcr::Trajectory NaiveStereoVo(const pcr::Dataset& d) {
  cv::Ptr<cv::ORB> orb = cv::ORB::create(2000);
  cv::BFMatcher matcher(cv::NORM_HAMMING, true);
  const pcr::PinholeCamera& c = d.rig.left;
  const cv::Mat K = (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  pcr::Trajectory out;
  pcr::SE3 world_from_cam = pcr::SE3::Identity();
  std::vector<cv::KeyPoint> prev_kp;
  cv::Mat prev_desc;
  std::vector<cv::Point3f> prev_xyz;  // per previous keypoint; z <= 0: no depth
  for (size_t i = 0; i < d.size(); ++i) {
    const cv::Mat left = d.LoadLeft(i), right = d.LoadRight(i);
    std::vector<cv::KeyPoint> kl, kr;
    cv::Mat dl, dr;
    orb->detectAndCompute(left, cv::noArray(), kl, dl);
    orb->detectAndCompute(right, cv::noArray(), kr, dr);
    // Stereo depth: mutual best matches on (nearly) the same row with positive disparity.
    std::vector<cv::Point3f> xyz(kl.size(), cv::Point3f(0, 0, -1));
    std::vector<cv::DMatch> lr;
    if (!dl.empty() && !dr.empty()) matcher.match(dl, dr, lr);
    for (const cv::DMatch& m : lr) {
      const cv::Point2f& a = kl[m.queryIdx].pt;
      const cv::Point2f& b = kr[m.trainIdx].pt;
      const float disparity = a.x - b.x;
      if (m.distance > 50 || std::abs(a.y - b.y) > 2 || disparity < 0.5f) continue;
      const double z = c.fx * d.rig.baseline_m / disparity;
      if (z > 80 * d.rig.baseline_m) continue;
      xyz[m.queryIdx] =
          cv::Point3f(static_cast<float>((a.x - c.cx) * z / c.fx),
                      static_cast<float>((a.y - c.cy) * z / c.fy), static_cast<float>(z));
    }
    if (i > 0 && !prev_desc.empty() && !dl.empty()) {
      std::vector<cv::DMatch> ff;
      matcher.match(prev_desc, dl, ff);
      std::vector<cv::Point3f> object;
      std::vector<cv::Point2f> image;
      for (const cv::DMatch& m : ff) {
        if (m.distance > 64 || prev_xyz[m.queryIdx].z <= 0) continue;
        object.push_back(prev_xyz[m.queryIdx]);
        image.push_back(kl[m.trainIdx].pt);
      }
      cv::Mat rvec, tvec;
      std::vector<int> inliers;
      if (object.size() >= 6 &&
          cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 300, 2.0f, 0.999,
                             inliers, cv::SOLVEPNP_EPNP) &&
          inliers.size() >= 10) {
        world_from_cam = world_from_cam * pcr::PoseFromCvRodrigues(rvec, tvec).inverse();
      }  // else: hold the pose (counted as tracked: the naive VO has no failure state)
    }
    out.push_back({d.t_ns[i], static_cast<int64_t>(i), world_from_cam});
    prev_kp = std::move(kl);
    prev_desc = dl;
    prev_xyz = std::move(xyz);
  }
  return out;
}

struct Score {
  size_t tracked = 0;
  double max_rotation_deg = -1;
  int worst_frame = -1;
  double ate_m = -1;
  std::string ate_error;  // why there is no ATE (e.g. a standing ego: nothing to align)
};

Score Evaluate(const pcr::Dataset& d, const pcr::Trajectory& tracked) {
  Score s;
  s.tracked = tracked.size();
  if (!d.ground_truth) return s;
  for (const pcr::StampedPose& p : tracked) {
    const pcr::SE3& gt = (*d.ground_truth)[static_cast<size_t>(p.frame_index)].world_from_cam;
    const double deg =
        pcr::RadToDeg(pcr::RotationAngleRad(gt.linear().transpose() * p.world_from_cam.linear()));
    if (deg > s.max_rotation_deg) {
      s.max_rotation_deg = deg;
      s.worst_frame = static_cast<int>(p.frame_index);
    }
  }
  pcr::eval::EvalOptions options;
  options.alignment.mode = pcr::eval::AlignMode::kSe3;
  try {
    s.ate_m =
        pcr::eval::Evaluate(pcr::eval::AssociateByFrameIndex(*d.ground_truth, tracked), options)
            .ape.trans_m.rmse;
  } catch (const std::exception& e) {
    s.ate_error = e.what();
  }
  return s;
}

// An ATE column: "-" where there is none.
std::string Ate(const Score& s) {
  return s.ate_m >= 0 ? fmt::format("{:9.3f}", s.ate_m) : "        -";
}

struct Case {
  std::string name, path;
};

// The synthetic loops of the command line's lists, rendered under `work` where not there yet.
std::vector<Case> Loops(int frames, const std::string& seeds, const std::string& speeds,
                        const std::string& movers, const std::string& work) {
  std::vector<Case> cases;
  for (uint64_t seed : pcr::bench::ParseSeeds(seeds, "--seeds"))
    for (double speed : pcr::bench::ParseList(speeds, "--speeds"))
      for (const std::string& m : pcr::bench::SplitList(movers)) {
        pcr::sim::SynthOptions o;
        o.frames = frames;
        o.seed = seed;
        o.speed_mps = speed;
        o.num_movers = pcr::bench::ParseInt(m, "--movers", 0);
        o.route = pcr::sim::RouteKind::kLoop;
        std::string why;
        if (!o.IsValid(&why))
          throw std::invalid_argument(pcr::NamedAsOption(
              why,
              {{"frames", "--frames"}, {"num_movers", "--movers"}, {"speed_mps", "--speeds"}}));
        const std::string name = fmt::format("loop s{} {}m/s {}mv", o.seed, speed, o.num_movers);
        const std::string dir =
            fmt::format("{}/loop_s{}_v{}_m{}_f{}", work, o.seed, speed, o.num_movers, frames);
        if (!pcr::sim::HoldsSequence(o, dir)) {
          std::printf("writing %s ...\n", name.c_str());
          std::fflush(stdout);
        }
        cases.push_back({name, pcr::sim::RenderOnce(o, dir)});
      }
  if (cases.empty())
    throw std::invalid_argument("--seeds, --speeds and --movers need a value each");
  return cases;
}

int Run(const std::vector<Case>& cases) {
  std::printf("\n%-22s %6s | %7s %8s %9s | %7s %8s %9s | %9s\n", "sequence", "frames", "tracked",
              "max rot", "ATE m", "naive", "max rot", "ATE m", "ATE ratio");
  int worse = 0;
  for (const Case& c : cases) {
    const pcr::Dataset d = pcr::OpenDataset(c.path);
    if (!d.has_right())
      throw pcr::InputError(c.path, 0, "no right images: bench_turns compares stereo trackers");
    pcr::driver::DriverOptions options;
    options.pipeline.policy = pcr::graph::Policy::kSequential;
    const pcr::driver::DriverResult run =
        pcr::driver::RunDataset(d, pcr::driver::RunConfig{}, {0, d.size()}, options);
    const Score ours = Evaluate(d, run.summary.tracked);
    const Score naive = Evaluate(d, NaiveStereoVo(d));
    const bool has_ratio = ours.ate_m >= 0 && naive.ate_m > 0;
    const double ratio = has_ratio ? ours.ate_m / naive.ate_m : -1;
    if (ours.tracked < d.size() || ours.max_rotation_deg >= 1.0 || ratio > 0.5) ++worse;
    std::printf("%-22s %6zu | %7zu %7.3f° %s | %7zu %7.3f° %s | %9s\n", c.name.c_str(), d.size(),
                ours.tracked, ours.max_rotation_deg, Ate(ours).c_str(), naive.tracked,
                naive.max_rotation_deg, Ate(naive).c_str(),
                has_ratio ? fmt::format("{:.3f}", ratio).c_str() : "-");
    for (const Score* s : {&ours, &naive})
      if (!s->ate_error.empty())
        std::printf("  no ATE (%s): %s\n", s == &ours ? "PCR-ORB" : "naive", s->ate_error.c_str());
    std::fflush(stdout);
  }
  std::printf(
      "\n%d of %zu cases miss a target (every frame tracked, rotation error < 1 degree, ATE <= "
      "0.5x the naive VO's)\n",
      worse, cases.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Tracking through turns: PCR-ORB against a naive frame-to-frame stereo VO"};
  int frames = 600;
  std::string seeds = "1,2,3", speeds = "8", movers = "6", work = "/tmp/pcr_bench_turns";
  std::vector<std::string> sequences;
  app.add_option("--frames", frames, "frames of each synthetic loop")->capture_default_str();
  app.add_option("--seeds", seeds, "synthetic loops' seeds")->capture_default_str();
  app.add_option("--speeds", speeds, "ego speeds, m/s")->capture_default_str();
  app.add_option("--movers", movers, "moving objects per loop")->capture_default_str();
  app.add_option("--work", work, "where the loops are written")->capture_default_str();
  app.add_option("--sequence", sequences, "KITTI sequences with ground truth (instead of loops)");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);
  try {
    std::vector<Case> cases;
    for (const std::string& s : sequences)
      cases.push_back({std::filesystem::path(s).filename().string(), s});
    if (sequences.empty()) cases = Loops(frames, seeds, speeds, movers, work);
    return Run(cases);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_turns: %s\n", e.what());
    return 1;
  }
}
