// Saved maps and localisation in them (`--save-map`, `--load-map`, `--localize-only`).
//
// Real clips (--sequence DIR...): every frame is mapped and the map saved; the map is loaded and
// saved again (the bytes must be equal); then every frame is localised in the loaded map.
// Synthetic loop routes (--seeds, `pcr_orb synth --route loop`, written under --work): the first
// lap is mapped and saved (up to --lap-extra frames past the revisit of its start, where loop
// closing can close it), and the frames that drive on past the start are localised in it.
//
// Printed per run: the map's size on disk, save and load times, whether a loaded map saves to the
// same bytes, frames localised, map points before/after localisation and whether the map's bytes
// are unchanged by it, and the mapping run's ATE over its own frames (SE(3)-aligned; context
// only). The localised frames are then compared with a mapping run on the same frames: on a real
// clip the mapping run itself (it mapped every frame); on a loop a second mapping run over the
// whole route (mapping goes on past the start instead of localising), both scored on the frames
// that both runs tracked among the localised ones: the SE(3) ATE with each run's own alignment
// fitted on those frames only, and the error against the truth without alignment (in the map's
// frame: the world is the first frame's camera in all runs; it includes the map's own drift),
// each with the ratio localised / mapping. (Scoring the localisation's few frames past the start
// against the whole lap's ATE would compare a short, well-mapped stretch, whose own alignment
// absorbs most of its error, with a whole lap.)
//
// --outside (loops only): a drive that starts outside a loaded map (ORB-SLAM3's atlas case). The
// route's first quarter up to its revisit is mapped and saved, and a run on that map (mapping on)
// drives from a third of the way to the end: it is not in the map until the revisit. Three runs
// of those frames: on the map as configured (a part of its own after
// tracking.reinitialise_after_lost_frames frames not found, joined to the map by the revisit's
// loop), on the map with that option at 0 (waiting to be found), and without the map (its own
// frame). Printed: frames tracked, parts started, loops closed, the error against the truth
// without alignment (the map's frame; for the run without the map it is not in that frame, so
// only its ATE), its largest value, and the SE(3)-aligned ATE.
//
//   build/bench/bench_map --sequence ../shared/data/kitti/sequences/06 --seeds 7,8,9
//   build/bench/bench_map --outside --seeds 1,2,3
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "bench_args.h"
#include "bench_cli.h"
#include "driver/binary_file.h"
#include "driver/map_file.h"
#include "driver/slam_config.h"
#include "eval/alignment.h"
#include "io/dataset.h"
#include "pcr/api.h"
#include "sim/sequence_writer.h"

namespace fs = std::filesystem;

namespace {

struct Args {
  std::vector<std::string> sequences;
  std::string seeds = "7,8,9";
  int frames = 200;
  double speed_mps = 12;
  double scale = 0.5;
  int movers = 4;
  int lap_extra = 10;
  std::string work = "/tmp/pcr_bench_map";
  std::vector<std::string> overrides;
  bool outside = false;
};

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// The frame indices in [first, end) that both trajectories hold, ascending.
std::vector<int64_t> CommonFrames(const std::vector<pcr::api::Pose>& a,
                                  const std::vector<pcr::api::Pose>& b, size_t first, size_t end) {
  std::set<int64_t> in_a;
  for (const pcr::api::Pose& p : a)
    if (p.frame_index >= static_cast<int64_t>(first) && p.frame_index < static_cast<int64_t>(end))
      in_a.insert(p.frame_index);
  std::set<int64_t> both;
  for (const pcr::api::Pose& p : b)
    if (in_a.contains(p.frame_index)) both.insert(p.frame_index);
  return {both.begin(), both.end()};
}

struct Errors {
  double ate_m = NAN;        // SE(3)-aligned on the scored frames (as the runs' own ATE)
  double unaligned_m = NAN;  // without alignment
};

// RMSE of the positions of `poses` on `frames` (all of which it holds) against the truth.
Errors ErrorsOn(const std::vector<pcr::api::Pose>& poses, const pcr::Trajectory& truth,
                const std::vector<int64_t>& frames) {
  std::map<int64_t, Eigen::Vector3d> by_frame;
  for (const pcr::api::Pose& p : poses)
    by_frame[p.frame_index] = p.world_from_cam.block<3, 1>(0, 3);
  std::vector<Eigen::Vector3d> estimate, reference;
  for (int64_t f : frames) {
    estimate.push_back(by_frame.at(f));
    reference.push_back(truth[static_cast<size_t>(f)].world_from_cam.translation());
  }
  Errors e;
  if (frames.empty()) return e;
  const double n = static_cast<double>(frames.size());
  double sum2 = 0;
  for (size_t i = 0; i < frames.size(); ++i) sum2 += (estimate[i] - reference[i]).squaredNorm();
  e.unaligned_m = std::sqrt(sum2 / n);
  if (const auto s = pcr::eval::UmeyamaAlignment(estimate, reference, /*with_scale=*/false)) {
    sum2 = 0;
    for (size_t i = 0; i < frames.size(); ++i)
      sum2 += (s->Apply(estimate[i]) - reference[i]).squaredNorm();
    e.ate_m = std::sqrt(sum2 / n);
  }
  return e;
}

// The first frame back within 8 m of the start after having been 30 m away (a loop's revisit).
size_t RevisitFrame(const pcr::Trajectory& truth) {
  const Eigen::Vector3d start = truth.front().world_from_cam.translation();
  bool away = false;
  for (size_t i = 0; i < truth.size(); ++i) {
    const double d = (truth[i].world_from_cam.translation() - start).norm();
    away = away || d > 30;
    if (away && d < 8) return i;
  }
  return truth.size();
}

// Maps [0, lap_end), saves, reloads, localises [loc_first, loc_end) and compares the localised
// frames with a mapping run over [0, loc_end) (the first one when it covered them); prints one row.
bool MapAndLocalise(const Args& a, const std::string& name, const std::string& sequence,
                    size_t lap_end, size_t loc_first, size_t loc_end) {
  const pcr::Dataset dataset = pcr::OpenDataset(sequence);
  const std::string map_path = fmt::format("{}/{}.map", a.work, name);
  pcr::api::Config c;
  c.threads = 2;
  c.overrides = a.overrides;
  c.save_map = map_path;
  const pcr::api::Result mapped =
      pcr::api::Run(c, pcr::api::Source::Dataset(sequence, 0, static_cast<int64_t>(lap_end)));
  auto t = std::chrono::steady_clock::now();
  const pcr::MapArchive archive = pcr::driver::LoadMap(map_path);
  const double load_ms = 1e3 * Seconds(t);
  const std::string again = map_path + ".again";
  t = std::chrono::steady_clock::now();
  const size_t bytes = pcr::driver::SaveMap(again, archive);
  const double save_ms = 1e3 * Seconds(t);
  const bool same_bytes =
      pcr::driver::ReadFileBytes(again, "map") == pcr::driver::ReadFileBytes(map_path, "map");

  pcr::api::Config l = c;
  l.load_map = map_path;
  l.save_map = map_path + ".after";
  l.localize_only = true;
  t = std::chrono::steady_clock::now();
  const pcr::api::Result loc =
      pcr::api::Run(l, pcr::api::Source::Dataset(sequence, static_cast<int64_t>(loc_first),
                                                 static_cast<int64_t>(loc_end)));
  const double loc_s = Seconds(t);
  const bool unchanged =
      pcr::driver::ReadFileBytes(l.save_map, "map") == pcr::driver::ReadFileBytes(map_path, "map");

  // The mapping run to compare with: one that mapped the localised frames too.
  const bool mapped_covers = loc_end <= lap_end;
  pcr::api::Result mapping_on;
  if (!mapped_covers) {
    pcr::api::Config r = c;
    r.save_map.clear();
    mapping_on =
        pcr::api::Run(r, pcr::api::Source::Dataset(sequence, 0, static_cast<int64_t>(loc_end)));
  }
  const pcr::api::Result& reference = mapped_covers ? mapped : mapping_on;
  const std::vector<int64_t> frames =
      CommonFrames(reference.trajectory, loc.trajectory, loc_first, loc_end);
  const Errors e_map = ErrorsOn(reference.trajectory, *dataset.ground_truth, frames);
  const Errors e_loc = ErrorsOn(loc.trajectory, *dataset.ground_truth, frames);
  const std::string compared =
      mapped_covers ? std::string("the mapping run")
                    : fmt::format("0:{} ({} tracked)", loc_end, reference.stats.frames_tracked);
  std::printf(
      "| %s | %zu:%zu | %zu/%zu | %zu | %.1f | %.0f | %.0f | %s | %zu:%zu | %zu/%zu | %.1f | %zu "
      "-> %zu | %s | %.4f | %s | %zu/%zu | %.4f | %.4f (%.2fx) | %.4f | %.4f (%.2fx) |\n",
      name.c_str(), size_t{0}, lap_end, mapped.stats.frames_tracked, lap_end,
      mapped.stats.keyframes, bytes / 1e6, save_ms, load_ms, same_bytes ? "yes" : "NO", loc_first,
      loc_end, loc.stats.frames_tracked, loc_end - loc_first, loc_s, mapped.stats.map_points,
      loc.stats.map_points, unchanged ? "yes" : "NO", mapped.stats.ate_rmse_m.value_or(NAN),
      compared.c_str(), frames.size(), loc_end - loc_first, e_map.ate_m, e_loc.ate_m,
      e_loc.ate_m / e_map.ate_m, e_map.unaligned_m, e_loc.unaligned_m,
      e_loc.unaligned_m / e_map.unaligned_m);
  std::fflush(stdout);
  bool failed = false;
  for (const pcr::api::Result* r : {&mapped, &loc, &reference})
    if (!r->error.empty()) {
      std::fprintf(stderr, "bench_map: %s: %s\n", name.c_str(), r->error.c_str());
      failed = true;
    }
  return !failed && same_bytes && unchanged && loc.stats.frames_tracked == loc_end - loc_first &&
         frames.size() == loc_end - loc_first;
}

// Maps [0, map_end) and saves it; then drives [first, end) on the loaded map as configured, with
// tracking.reinitialise_after_lost_frames=0, and without the map; prints one row.
bool DriveOutsideTheMap(const Args& a, const std::string& name, const std::string& sequence,
                        size_t map_end, size_t first, size_t end) {
  const pcr::Dataset dataset = pcr::OpenDataset(sequence);
  const pcr::Trajectory& truth = *dataset.ground_truth;
  pcr::api::Config c;
  c.threads = 2;
  c.overrides = a.overrides;
  c.save_map = fmt::format("{}/{}_first_{}.map", a.work, name, map_end);
  const pcr::api::Result mapped =
      pcr::api::Run(c, pcr::api::Source::Dataset(sequence, 0, static_cast<int64_t>(map_end)));
  const auto drive = [&](bool load, bool own_part) {
    pcr::api::Config d = c;
    d.save_map.clear();
    if (load) d.load_map = c.save_map;
    if (!own_part) d.overrides.push_back("tracking.reinitialise_after_lost_frames=0");
    return pcr::api::Run(d, pcr::api::Source::Dataset(sequence, static_cast<int64_t>(first),
                                                      static_cast<int64_t>(end)));
  };
  const pcr::api::Result own = drive(true, true), waiting = drive(true, false),
                         alone = drive(false, true);
  // Errors over each run's own tracked frames, and the largest unaligned one.
  const auto scored = [&](const pcr::api::Result& r, double* max_m) {
    std::vector<int64_t> frames;
    *max_m = 0;
    for (const pcr::api::Pose& p : r.trajectory) {
      frames.push_back(p.frame_index);
      *max_m =
          std::max(*max_m, (p.world_from_cam.block<3, 1>(0, 3) -
                            truth[static_cast<size_t>(p.frame_index)].world_from_cam.translation())
                               .norm());
    }
    return ErrorsOn(r.trajectory, truth, frames);
  };
  double own_max = 0, waiting_max = 0, alone_max = 0;
  const Errors e_own = scored(own, &own_max), e_waiting = scored(waiting, &waiting_max),
               e_alone = scored(alone, &alone_max);
  const auto from = [](const pcr::api::Result& r) {
    return r.trajectory.empty() ? std::string("-")
                                : std::to_string(r.trajectory.front().frame_index);
  };
  std::printf(
      "| %s | %zu:%zu (%zu kf) | %zu:%zu | %zu from %s, %d part(s), %d loop(s) | %.4f (max %.3f) | "
      "%.4f | %zu from %s | %.4f | %zu, %d loop(s) | %.4f |\n",
      name.c_str(), size_t{0}, map_end, mapped.stats.keyframes, first, end,
      own.stats.frames_tracked, from(own).c_str(), own.stats.reinitialisations,
      own.stats.loops_closed, e_own.unaligned_m, own_max, e_own.ate_m, waiting.stats.frames_tracked,
      from(waiting).c_str(), e_waiting.unaligned_m, alone.stats.frames_tracked,
      alone.stats.loops_closed, e_alone.ate_m);
  std::fflush(stdout);
  bool failed = false;
  for (const pcr::api::Result* r : {&mapped, &own, &waiting, &alone})
    if (!r->error.empty()) {
      std::fprintf(stderr, "bench_map: %s: %s\n", name.c_str(), r->error.c_str());
      failed = true;
    }
  return !failed;
}

// The loop route of `seed`.
pcr::sim::SynthOptions LoopOptions(const Args& a, uint64_t seed) {
  pcr::sim::SynthOptions o;
  o.route = pcr::sim::RouteKind::kLoop;
  o.frames = a.frames;
  o.speed_mps = a.speed_mps;
  o.num_movers = a.movers;
  o.seed = seed;
  return o.Scaled(a.scale);
}

}  // namespace

int main(int argc, char** argv) {
  using pcr::bench::AddInt;
  using pcr::bench::AddNumber;
  CLI::App app{"Saved maps: size, save/load times, the byte round trip, localisation"};
  Args a;
  app.add_option("--sequence", a.sequences, "real clips: map every frame, localise every frame");
  app.add_option("--seeds", a.seeds, "synthetic loop routes' seeds (empty: none)")
      ->capture_default_str();
  AddInt(app, "--frames", &a.frames, 1, 1000000, "N", "frames of each loop route");
  AddNumber(
      app, "--speed", &a.speed_mps, "in [0, 40]", [](double v) { return v >= 0 && v <= 40; }, "M/S",
      "ego speed of the loop routes, m/s");
  AddNumber(
      app, "--scale", &a.scale, "in (0, 4]", [](double v) { return v > 0 && v <= 4; }, "X",
      "image scale of the loop routes (1: KITTI's 1241x376)");
  AddInt(app, "--movers", &a.movers, 0, 500, "N", "moving objects per route");
  AddInt(app, "--lap-extra", &a.lap_extra, 0, 1000000, "FRAMES",
         "loops: frames past the revisit that the first lap's mapping still holds (its loop can "
         "close there)");
  app.add_option("--work", a.work, "where routes and maps are written")->capture_default_str();
  app.add_option("--set", a.overrides, "configuration override section.key=value (repeatable)");
  app.add_flag("--outside", a.outside,
               "loops: map the route's first quarter up to its revisit, then drive from a third "
               "of the way on that map (a drive that starts outside a loaded map)");
  spdlog::set_level(spdlog::level::warn);
  try {
    if (const int status = pcr::bench::Parse(app, argc, argv); status >= 0) return status;
    const std::vector<uint64_t> seeds = pcr::bench::ParseSeeds(a.seeds, "--seeds");
    if (seeds.empty() && a.sequences.empty())
      throw std::invalid_argument("nothing to measure: no --sequence and no seed in --seeds '" +
                                  a.seeds + "'");
    pcr::driver::LoadRunConfig("", a.overrides, nullptr);  // --set: names the option and the key
    for (const std::string& seq : a.sequences)
      if (!fs::is_directory(seq)) throw std::invalid_argument("--sequence: no folder " + seq);
    // The routes' options, checked before any work (the ranges above keep this from failing).
    std::string why;
    if (!LoopOptions(a, seeds.empty() ? 1 : seeds.front()).IsValid(&why))
      throw std::invalid_argument("the loop routes (--frames, --speed, --movers, --scale): " + why);
    fs::create_directories(a.work);
    if (a.outside && !a.sequences.empty())
      throw std::invalid_argument("--outside takes loop routes (--seeds), not --sequence");
    if (a.outside) {
      std::printf(
          "| run | mapped (keyframes) | driven | on the map: tracked, parts, loops | error in the "
          "map's frame, m (largest) | ATE | option 0: tracked | error in the map's frame | "
          "without the map: tracked, loops | ATE |\n|");
      for (int i = 0; i < 10; ++i) std::printf("---|");
    } else {
      std::printf(
          "| run | mapped | tracked | keyframes | MB | save ms | load ms | same bytes | localised "
          "frames | localised | s | map points | map unchanged | ATE mapping, its frames | mapping "
          "run compared | frames compared | ATE mapping | ATE localised | error mapping "
          "(unaligned) | error localised (unaligned) |\n|");
      for (int i = 0; i < 20; ++i) std::printf("---|");
    }
    std::printf("\n");
    bool ok = true;
    for (const std::string& seq : a.sequences) {
      const size_t n = pcr::OpenDataset(seq).size();
      ok = MapAndLocalise(a, fs::path(seq).filename().string(), seq, n, 0, n) && ok;
    }
    for (uint64_t seed : seeds) {
      const pcr::sim::SynthOptions o = LoopOptions(a, seed);
      const fs::path dir = fmt::format("{}/loop_s{}_f{}_v{}_m{}_x{}", a.work, o.seed, o.frames,
                                       o.speed_mps, o.num_movers, a.scale);
      const std::string sequence = pcr::sim::RenderOnce(o, dir.string());
      const pcr::Dataset d = pcr::OpenDataset(sequence);
      const size_t revisit = RevisitFrame(*d.ground_truth);
      if (revisit >= d.size()) {
        std::printf("| loop seed %llu | the route does not come back to its start |\n",
                    static_cast<unsigned long long>(seed));
        ok = false;
        continue;
      }
      if (a.outside) {
        ok = DriveOutsideTheMap(a, fmt::format("loop_s{}", o.seed), sequence, revisit / 4,
                                revisit / 3, d.size()) &&
             ok;
        continue;
      }
      const size_t lap_end = std::min(d.size() - 1, revisit + static_cast<size_t>(a.lap_extra));
      ok = MapAndLocalise(a, fmt::format("loop_s{}", o.seed), sequence, lap_end, lap_end,
                          d.size()) &&
           ok;
    }
    return ok ? 0 : 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_map: %s\n", e.what());
    return 1;
  }
}
