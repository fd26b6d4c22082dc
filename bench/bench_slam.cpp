// End-to-end SLAM accuracy and speed on the target inputs, one table:
//   kitti06   real stereo, KITTI odometry 06 frames 0-50 (target ATE RMSE <= 0.08 m)
//   raw0005   real stereo, raw drive 0005 (91 frames, OXTS ground truth)
//   synth     synthetic static street, 300 stereo frames (target ATE RMSE <= 0.05 m)
//   mono07    real monocular, KITTI 07 (160 frames, Sim(3) ATE target <= 1% of the path)
//   mono00    real monocular, KITTI 00 (100 frames, likewise)
// Each input runs twice to check that trajectories repeat exactly. Usage:
//   bench_slam [case ...] [--synth-frames N] [--shared DIR]   (--shared: default $PCR_SHARED_DIR,
//                                                             else the build's)
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "bench_args.h"
#include "driver/driver.h"
#include "io/dataset.h"
#include "sim/sequence_writer.h"

namespace {

struct Case {
  std::string name, path;
  pcr::SlamMode mode = pcr::SlamMode::kStereo;
};

// Bit-identical poses.
bool SameTrajectory(const pcr::Trajectory& a, const pcr::Trajectory& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].world_from_cam.matrix() != b[i].world_from_cam.matrix()) return false;
  return true;
}

// Runs the cases named in `wanted` (CLI-checked names) and prints the table.
int Run(const std::vector<std::string>& wanted, const std::string& shared, int synth_frames) {
  std::vector<Case> cases;
  for (const std::string& w : wanted) {
    if (w == "kitti06") {
      cases.push_back({w, shared + "/data/kitti/sequences/06"});
    } else if (w == "raw0005") {
      cases.push_back({w, shared + "/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"});
    } else if (w == "mono07" || w == "mono00") {
      cases.push_back(
          {w, shared + "/data/kitti/sequences/" + w.substr(4), pcr::SlamMode::kMonocular});
    } else if (w == "synth") {
      pcr::sim::SynthOptions o;
      o.frames = synth_frames;
      o.num_movers = 0;
      o.seed = 1;
      const std::string out = std::filesystem::temp_directory_path() / "pcr_bench_synth_static";
      std::printf("writing %d synthetic static frames to %s ...\n", o.frames, out.c_str());
      const auto summary = pcr::sim::WriteSequence(o, out);
      std::printf("  %.1f s\n", summary.seconds);
      cases.push_back({w, summary.sequence_dir});
    }
  }

  std::printf("\n%-9s %6s %7s %5s %4s %9s %9s %9s %8s %8s %7s %6s\n", "input", "frames", "tracked",
              "lost", "kf", "ATE rmse", "ATE max", "RPE rmse", "path m", "ATE %", "fps", "repeat");
  std::vector<std::pair<std::string, pcr::driver::RunSummary>> runs;
  for (const Case& c : cases) {
    const pcr::Dataset dataset = pcr::OpenDataset(c.path);
    pcr::driver::RunConfig config;
    const pcr::driver::FrameRange all{0, dataset.size()};
    pcr::driver::DriverOptions run;
    run.mode = c.mode;
    run.pipeline.policy = pcr::graph::Policy::kSequential;
    const pcr::driver::RunSummary a = pcr::driver::RunDataset(dataset, config, all, run).summary;
    const pcr::driver::RunSummary b = pcr::driver::RunDataset(dataset, config, all, run).summary;
    const bool repeat = SameTrajectory(a.per_frame, b.per_frame);
    double rmse = -1, mx = -1, rpe = -1, path = 0;
    if (a.evaluation) {
      rmse = a.evaluation->ape.trans_m.rmse;
      mx = a.evaluation->ape.trans_m.max;
      rpe = a.evaluation->rpe.trans_m.rmse;
      path = a.evaluation->reference_path_m;
    }
    std::printf("%-9s %6zu %7zu %5zu %4zu %9.4f %9.4f %9.4f %8.1f %8.3f %7.2f %6s\n",
                c.name.c_str(), a.frames_in, a.frames_tracked, a.frames_lost, a.keyframes, rmse, mx,
                rpe, path, path > 0 ? 100.0 * rmse / path : -1.0,
                a.wall_s > 0 ? a.frames_in / a.wall_s : 0.0, repeat ? "yes" : "NO");
    std::fflush(stdout);
    runs.emplace_back(c.name, a);
  }
  for (const auto& [name, s] : runs) {
    std::printf("\n== %s: per-stage times on this machine\n", name.c_str());
    const std::string text = pcr::driver::FormatRunSummary(s);
    // Only the frames line and the stage table (the evaluation table is summarised above).
    const auto cut = text.find("matched ");
    std::printf("%s", text.substr(0, cut).c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"End-to-end SLAM accuracy and speed: ATE/RPE, losses, repeatability, stage times"};
  std::string shared = pcr::bench::SharedDir();
  int synth_frames = 300;
  std::vector<std::string> wanted;
  app.add_option("cases", wanted, "inputs to run (default: all)")
      ->check(CLI::IsMember({"kitti06", "raw0005", "synth", "mono07", "mono00"}));
  app.add_option("--synth-frames", synth_frames, "frames of the synthetic static street")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--shared", shared,
                 "the shared data folder (default: $PCR_SHARED_DIR, else "
                 "the build's)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (wanted.empty()) wanted = {"kitti06", "raw0005", "synth", "mono07", "mono00"};
  spdlog::set_level(spdlog::level::warn);
  try {
    return Run(wanted, shared, synth_frames);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_slam: %s\n", e.what());
    return 1;
  }
}
