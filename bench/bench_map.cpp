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
// are unchanged by it, the mapping run's ATE (SE(3)-aligned) against the localised frames' ATE,
// and the error against the truth without alignment (in the map's frame: the world is the first
// frame's camera in both runs; it includes the map's own drift) of the mapping run's frames and
// of the localised frames.
//
//   build/bench/bench_map --sequence ../shared/data/kitti/sequences/06 --seeds 7,8,9
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "bench_args.h"
#include "driver/binary_file.h"
#include "driver/map_file.h"
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
};

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// RMSE of the localised positions against the truth without alignment.
double UnalignedRmse(const std::vector<pcr::api::Pose>& poses, const pcr::Trajectory& truth) {
  double sum2 = 0;
  for (const pcr::api::Pose& p : poses) {
    const Eigen::Vector3d t =
        truth[static_cast<size_t>(p.frame_index)].world_from_cam.translation();
    sum2 += (p.world_from_cam.block<3, 1>(0, 3) - t).squaredNorm();
  }
  return poses.empty() ? NAN : std::sqrt(sum2 / static_cast<double>(poses.size()));
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

// Maps [0, lap_end), saves, reloads, localises [loc_first, loc_end); prints one row.
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
  const double unaligned = UnalignedRmse(loc.trajectory, *dataset.ground_truth);
  const double unaligned_map = UnalignedRmse(mapped.trajectory, *dataset.ground_truth);
  const double ate_map = mapped.stats.ate_rmse_m.value_or(NAN);
  const double ate_loc = loc.stats.ate_rmse_m.value_or(NAN);
  std::printf(
      "| %s | %zu:%zu | %zu/%zu | %zu | %.1f | %.0f | %.0f | %s | %zu:%zu | %zu/%zu | %.1f | %zu "
      "-> %zu | %s | %.4f | %.4f (%.2fx) | %.4f | %.4f (%.2fx) |\n",
      name.c_str(), size_t{0}, lap_end, mapped.stats.frames_tracked, lap_end,
      mapped.stats.keyframes, bytes / 1e6, save_ms, load_ms, same_bytes ? "yes" : "NO", loc_first,
      loc_end, loc.stats.frames_tracked, loc_end - loc_first, loc_s, mapped.stats.map_points,
      loc.stats.map_points, unchanged ? "yes" : "NO", ate_map, ate_loc, ate_loc / ate_map,
      unaligned_map, unaligned, unaligned / unaligned_map);
  std::fflush(stdout);
  return same_bytes && unchanged && loc.stats.frames_tracked == loc_end - loc_first;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Saved maps: size, save/load times, the byte round trip, localisation"};
  Args a;
  app.add_option("--sequence", a.sequences, "real clips: map every frame, localise every frame");
  app.add_option("--seeds", a.seeds, "synthetic loop routes' seeds (empty: none)")
      ->capture_default_str();
  app.add_option("--frames", a.frames, "frames of each loop route")->capture_default_str();
  app.add_option("--speed", a.speed_mps, "ego speed, m/s")->capture_default_str();
  app.add_option("--scale", a.scale, "image scale of the loop routes")->capture_default_str();
  app.add_option("--movers", a.movers, "moving objects per route")->capture_default_str();
  app.add_option("--lap-extra", a.lap_extra,
                 "loops: frames past the revisit that the first lap's mapping still holds (its "
                 "loop can close there)")
      ->capture_default_str();
  app.add_option("--work", a.work, "where routes and maps are written")->capture_default_str();
  app.add_option("--set", a.overrides, "configuration override section.key=value (repeatable)");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);
  try {
    fs::create_directories(a.work);
    std::printf(
        "| run | mapped | tracked | keyframes | MB | save ms | load ms | same bytes | localised "
        "frames | localised | s | map points | map unchanged | ATE mapping | ATE localised "
        "(aligned) | error mapping (unaligned) | error localised (unaligned) |\n|");
    for (int i = 0; i < 17; ++i) std::printf("---|");
    std::printf("\n");
    bool ok = true;
    for (const std::string& seq : a.sequences) {
      const size_t n = pcr::OpenDataset(seq).size();
      ok = MapAndLocalise(a, fs::path(seq).filename().string(), seq, n, 0, n) && ok;
    }
    for (double seed : pcr::bench::ParseList(a.seeds)) {
      pcr::sim::SynthOptions o;
      o.route = pcr::sim::RouteKind::kLoop;
      o.frames = a.frames;
      o.speed_mps = a.speed_mps;
      o.num_movers = a.movers;
      o.seed = static_cast<uint64_t>(seed);
      o = o.Scaled(a.scale);
      const fs::path dir =
          fmt::format("{}/loop_s{}_f{}_v{}_x{}", a.work, o.seed, o.frames, o.speed_mps, a.scale);
      std::string sequence = (dir / "sequences" / o.sequence).string();
      if (!fs::exists(dir / "complete")) {
        sequence = pcr::sim::WriteSequence(o, dir.string()).sequence_dir;
        std::ofstream(dir / "complete") << "ok\n";
      }
      const pcr::Dataset d = pcr::OpenDataset(sequence);
      const size_t revisit = RevisitFrame(*d.ground_truth);
      if (revisit >= d.size()) {
        std::printf("| loop seed %g | the route does not come back to its start |\n", seed);
        ok = false;
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
