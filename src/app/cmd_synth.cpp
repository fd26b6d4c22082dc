// pcr_orb synth: writes a synthetic KITTI-format stereo sequence with exact ground truth
// (poses, per-pixel instance ids, object poses); see src/sim/sequence_writer.h for the layout.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "app/commands.h"
#include "app/progress.h"
#include "sim/sequence_writer.h"
#include "slam/common/error.h"
#include "slam/common/validation.h"

namespace pcr::app {
namespace {

namespace fs = std::filesystem;

// Creates dir (and its parents) as WriteSequence would, but says why it cannot: a part of the path
// that is a file, or the system's reason. (WriteSequence says only "cannot create directory".)
void CreateOutputFolder(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (!ec && fs::is_directory(dir, ec)) return;
  for (fs::path p = dir; !p.empty(); p = p.parent_path()) {
    std::error_code status_ec;
    const fs::file_status status = fs::status(p, status_ec);
    if (fs::exists(status)) {
      if (!fs::is_directory(status))
        throw InputError(dir.string(), 0,
                         "cannot create directory: " + p.string() +
                             (fs::is_regular_file(status) ? " is a file" : " exists") +
                             ", not a directory (give --out a folder)");
      break;
    }
    if (p == p.parent_path()) break;
  }
  throw InputError(dir.string(), 0,
                   "cannot create directory: " + (ec ? ec.message() : std::string("not created")));
}

}  // namespace

void AddSynthCommand(CLI::App& app) {
  struct Args {
    std::string out_dir;
    std::string route = "straight";
    sim::SynthOptions options;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a synthetic KITTI-format stereo sequence with ground-truth poses and "
      "per-pixel instance ids of moving objects");
  cmd->add_option("--out", args->out_dir,
                  "Output root: writes OUT/sequences/NN and OUT/poses/NN.txt")
      ->required();
  cmd->add_option("--frames", args->options.frames, "Number of stereo frames")
      ->capture_default_str();
  cmd->add_option("--seed", args->options.seed, "Random seed of the world")
      ->capture_default_str()
      ->check(UnsignedWhole64());  // CLI11 reads "-1" into an unsigned option as 2^64-1
  cmd->add_option("--movers", args->options.num_movers,
                  "Moving objects (cars, pedestrians, cyclists)")
      ->capture_default_str();
  cmd->add_option("--parked", args->options.num_parked, "Parked cars")->capture_default_str();
  cmd->add_option("--speed", args->options.speed_mps, "Ego speed, m/s")->capture_default_str();
  cmd->add_option(
         "--lead-gap", args->options.lead_gap_m,
         "Heavy traffic: a lead car this many metres ahead at about the ego speed (0: off)")
      ->capture_default_str();
  cmd->add_option("--route", args->route, "straight or loop")
      ->check(CLI::IsMember({"straight", "loop"}))
      ->capture_default_str();
  cmd->add_option(
         "--laps", args->options.laps,
         "loop route: times round the loop's streets (their length is the travel over laps; the "
         "ego's lane is 6.6 m shorter, so it drives a little more)")
      ->capture_default_str();
  cmd->add_option("--sequence", args->options.sequence, "Two-digit sequence name")
      ->capture_default_str();
  cmd->callback([args, cmd] {
    sim::SynthOptions options = args->options;
    options.route = sim::ParseRoute(args->route);
    if (args->out_dir.empty()) throw ConfigError("synth: --out needs a folder, not ''");
    if (cmd->count("--laps") > 0 && options.route != sim::RouteKind::kLoop)
      throw ConfigError("synth: --laps applies to --route loop only, not to --route " +
                        args->route);
    // On the loop route, the ego car drives --laps times round the streets at --speed; standing
    // still, it drives no loop. (On the straight route, --speed 0 is a parked ego car.)
    if (options.route == sim::RouteKind::kLoop && options.speed_mps == 0)
      throw ConfigError(
          "synth: --speed 0 with --route loop: the ego car would stand still and never drive the "
          "loop (--laps); give --speed above 0, or --route straight for a parked ego car");
    std::string why;
    // SynthOptions::IsValid names its fields: the command line's options instead.
    if (!options.IsValid(&why))
      throw ConfigError("synth: " + NamedAsOption(why, {{"frames", "--frames"},
                                                        {"num_movers", "--movers"},
                                                        {"num_parked", "--parked"},
                                                        {"speed_mps", "--speed"},
                                                        {"lead_gap_m", "--lead-gap"},
                                                        {"laps", "--laps"},
                                                        {"sequence", "--sequence"},
                                                        {"seed", "--seed"}}));
    // (WriteSequence refuses too; this names the option.)
    sim::RefuseForeignData(options, args->out_dir,
                           "give another --out (or --sequence) or remove it");
    CreateOutputFolder(fs::path(args->out_dir) / "sequences" / options.sequence);
    CreateOutputFolder(fs::path(args->out_dir) / "poses");
    Progress progress("synth", options.frames);
    const sim::WriteSummary summary =
        sim::WriteSequence(options, args->out_dir, [&progress](int done, int total) {
          if (done < total) progress.Update(done);
        });
    progress.Finish();
    if (summary.parked_instances < options.num_parked)
      spdlog::warn(
          "synth: --parked {}: only {} parked cars fit beside the route (synth_options.txt "
          "records num_parked_placed: {})",
          options.num_parked, summary.parked_instances, summary.parked_instances);
    std::printf(
        "wrote %d stereo frames (%dx%d, %s route, seed %llu) to %s and poses to %s: %d instances "
        "(%d moving, %d parked), %.1f s (%.1f frames/s)\n",
        summary.frames, options.width_px, options.height_px, sim::RouteName(options.route),
        static_cast<unsigned long long>(options.seed), summary.sequence_dir.c_str(),
        summary.poses_path.c_str(), summary.instances, summary.moving_instances,
        summary.parked_instances, summary.seconds,
        summary.seconds > 0 ? summary.frames / summary.seconds : 0.0);
  });
}

}  // namespace pcr::app
