// pcr_orb vocab: trains the place-recognition vocabulary (slam/loop/vocabulary.h) on the ORB
// descriptors (default OrbOptions) of PNG images and, optionally, of frames of a synthetic street
// rendered in memory, and writes it (driver/vocabulary_file.h); --check FILE reads one back.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "app/commands.h"
#include "app/progress.h"
#include "driver/run_slam.h"
#include "driver/vocabulary_file.h"
#include "io/dataset.h"
#include "sim/synthetic_world.h"
#include "slam/common/error.h"
#include "slam/common/validation.h"
#include "slam/features/orb_extractor.h"
#include "slam/loop/vocabulary.h"
#include "slam/loop/vocabulary_io.h"

namespace pcr::app {
namespace {

namespace fs = std::filesystem;

bool IsPng(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".png";
}

// The PNG files of dir and of its direct subdirectories (e.g. a raw drive's image_00/data),
// sorted by path; every stride-th one, at most max_images (0: all).
std::vector<std::string> ImagesOf(const std::string& dir, int stride, int max_images) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir, 0, "not a directory");
  std::vector<std::string> all;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && IsPng(e.path())) {
      all.push_back(e.path().string());
    } else if (e.is_directory()) {
      for (const fs::directory_entry& f : fs::directory_iterator(e.path()))
        if (f.is_regular_file() && IsPng(f.path())) all.push_back(f.path().string());
    }
  }
  std::sort(all.begin(), all.end());
  std::vector<std::string> picked;
  for (size_t i = 0; i < all.size(); i += static_cast<size_t>(stride)) {
    if (max_images > 0 && static_cast<int>(picked.size()) >= max_images) break;
    picked.push_back(all[i]);
  }
  if (picked.empty()) throw InputError(dir, 0, "no PNG image in it or its subdirectories");
  return picked;
}

// The images of all --images folders, each file once: a folder given twice, a folder and its
// subfolder, or links (symbolic or hard) to one file would otherwise train on the same image twice.
// The first of each is kept, in the order picked (the folders in the order given, each folder's
// images sorted by path): that order is the training's, which scripts/train_vocabulary.sh relies
// on to reproduce vocabulary/pcr_orb_voc.bin byte for byte. *dropped: how many were left out.
std::vector<std::string> WithoutDuplicates(const std::vector<std::string>& paths, size_t* dropped) {
  std::set<std::string> resolved;           // symbolic links followed
  std::set<std::pair<dev_t, ino_t>> files;  // hard links: one file under two names
  std::vector<std::string> kept;
  for (const std::string& path : paths) {
    std::error_code ec;
    fs::path key = fs::canonical(path, ec);
    if (ec) key = fs::absolute(path, ec).lexically_normal();
    if (!resolved.insert(key.string()).second) continue;
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && !files.insert({st.st_dev, st.st_ino}).second) continue;
    kept.push_back(path);
  }
  *dropped = paths.size() - kept.size();
  return kept;
}

}  // namespace

void AddVocabCommand(CLI::App& app) {
  struct Args {
    std::vector<std::string> image_dirs;
    std::string out;
    std::string check;
    VocabularyOptions options;
    int stride = 1;
    int max_images = 0;
    int synth_frames = 0;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "vocab", "Train the place-recognition vocabulary (bag of binary words) on ORB descriptors");
  cmd->add_option("--images", args->image_dirs,
                  "Directories of PNG images (their direct subdirectories too), read in the order "
                  "given, each one's images sorted by path; each file once");
  cmd->add_option("--out", args->out, "Vocabulary file to write");
  CLI::Option* check =
      cmd->add_option("--check", args->check,
                      "Only read this vocabulary file and describe it (nothing is trained)");
  cmd->add_option("--branching", args->options.branching, "Children per node (k)")
      ->capture_default_str();
  cmd->add_option("--depth", args->options.depth, "Levels below the root (L)")
      ->capture_default_str();
  cmd->add_option("--iterations", args->options.max_iterations, "k-medians iterations per node")
      ->capture_default_str();
  cmd->add_option("--seed", args->options.seed, "Seed of the k-means++ sampling")
      ->capture_default_str()
      ->check(UnsignedWhole64());
  cmd->add_option("--stride", args->stride, "Every stride-th image of each directory")
      ->check(WholeFrom(1))
      ->capture_default_str();
  cmd->add_option("--max-images", args->max_images,
                  "At most this many images per directory (0: all)")
      ->check(WholeFrom(0))
      ->capture_default_str();
  cmd->add_option("--synth-frames", args->synth_frames,
                  "Also this many left frames of the default synthetic street, rendered in memory")
      ->check(WholeFrom(0))
      ->capture_default_str();
  // --check trains nothing: a training option beside it is an error, not ignored.
  for (const char* name : {"--images", "--out", "--branching", "--depth", "--iterations", "--seed",
                           "--stride", "--max-images", "--synth-frames"})
    check->excludes(cmd->get_option(name));
  cmd->callback([args] {
    if (!args->check.empty()) {
      const Vocabulary v = driver::LoadVocabulary(args->check);
      fmt::print("{}: k={} L={} (seed {}), {} words, {} nodes, {} bytes\n", args->check,
                 v.branching(), v.depth(), v.options().seed, v.num_words(), v.num_nodes(),
                 fs::file_size(args->check));
      return;
    }
    if (args->out.empty()) throw ConfigError("vocab: --out FILE is required to train");
    std::string why;
    // VocabularyOptions::IsValid names its fields: the command line's options instead.
    if (!args->options.IsValid(&why))
      throw ConfigError("vocab: " + NamedAsOption(why, {{"branching^depth", "--branching^--depth"},
                                                        {"branching", "--branching"},
                                                        {"depth", "--depth"},
                                                        {"max_iterations", "--iterations"}}));
    // Before any image is read: the file is written after the extraction and the training.
    driver::CheckOutputFile(args->out, "--out", "", kVocabularyMagic);
    std::vector<std::string> paths;
    for (const std::string& dir : args->image_dirs) {
      const std::vector<std::string> images = ImagesOf(dir, args->stride, args->max_images);
      fmt::print("{}: {} images\n", dir, images.size());
      paths.insert(paths.end(), images.begin(), images.end());
    }
    size_t dropped = 0;
    paths = WithoutDuplicates(paths, &dropped);
    if (dropped > 0)
      spdlog::warn(
          "vocab: --images: {} {} the same file as another one picked (a folder given twice, a "
          "folder and its subfolder, or links to one file): each file is read once, {} images "
          "in all",
          dropped, dropped == 1 ? "image is" : "images are", paths.size());
    if (paths.empty() && args->synth_frames == 0)
      throw ConfigError("vocab: no images (give --images DIR... or --synth-frames N)");

    const OrbExtractor extractor{OrbOptions()};
    std::vector<cv::Mat> descriptors;
    size_t num_descriptors = 0;
    std::string first_image;  // the first real image and its size, for an error
    const auto t0 = std::chrono::steady_clock::now();
    {
      Progress progress("orb", static_cast<int64_t>(paths.size()) + args->synth_frames);
      for (const std::string& path : paths) {
        const cv::Mat image = LoadGreyImage(path);
        if (first_image.empty())
          first_image = fmt::format("{}, {}x{} px", path, image.cols, image.rows);
        descriptors.push_back(extractor.Extract(image).descriptors);
        num_descriptors += descriptors.back().rows;
        progress.Update(static_cast<int64_t>(descriptors.size()));
      }
      if (args->synth_frames > 0) {
        sim::SynthOptions synth;
        synth.frames = args->synth_frames;
        const sim::SyntheticWorld world(synth);
        for (int f = 0; f < args->synth_frames; ++f) {
          descriptors.push_back(extractor.Extract(world.RenderFrame(f).left).descriptors);
          num_descriptors += descriptors.back().rows;
          progress.Update(static_cast<int64_t>(descriptors.size()));
        }
      }
      progress.Finish();
    }
    const auto t1 = std::chrono::steady_clock::now();
    fmt::print("read {} images ({} real, {} synthetic): {} descriptors, {:.1f} s\n",
               descriptors.size(), paths.size(), args->synth_frames, num_descriptors,
               std::chrono::duration<double>(t1 - t0).count());
    // (Vocabulary::Train would say only "no descriptors".)
    if (num_descriptors == 0) {
      std::string read;
      if (!paths.empty())
        read = fmt::format("{} images from --images {} (the first: {})", paths.size(),
                           fmt::join(args->image_dirs, ", "), first_image);
      if (args->synth_frames > 0)
        read +=
            fmt::format("{}{} synthetic frames", read.empty() ? "" : " and ", args->synth_frames);
      throw ConfigError(
          "vocab: no ORB descriptors in the " + read +
          ": the images are too small or featureless (ORB finds no corners in them); give "
          "--images folders of textured camera frames (e.g. KITTI's image_0), or --synth-frames N");
    }
    const Vocabulary vocabulary = Vocabulary::Train(descriptors, args->options);
    const auto t2 = std::chrono::steady_clock::now();
    fmt::print("trained k={} L={} seed {}: {} words, {} nodes, {:.1f} s\n", vocabulary.branching(),
               vocabulary.depth(), args->options.seed, vocabulary.num_words(),
               vocabulary.num_nodes(), std::chrono::duration<double>(t2 - t1).count());
    driver::SaveVocabulary(args->out, vocabulary);
    if (SerializeVocabulary(driver::LoadVocabulary(args->out)) != SerializeVocabulary(vocabulary))
      throw InputError(args->out, 0, "reads back differently from what was written");
    fmt::print("wrote {} ({} bytes, read back)\n", args->out, fs::file_size(args->out));
  });
}

}  // namespace pcr::app
