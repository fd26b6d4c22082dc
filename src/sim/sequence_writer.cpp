#include "sim/sequence_writer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <thread>

#include "io/kitti_odometry.h"
#include "sim/synthetic_world.h"
#include "slam/common/error.h"

namespace pcr::sim {
namespace fs = std::filesystem;

namespace {

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << text;
  out.flush();
  if (!out) throw InputError(path, 0, "write failed");
}

void MakeDir(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw InputError(dir.string(), 0, "cannot create directory");
}

void WritePng(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(
        path, image,
        {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY, cv::IMWRITE_PNG_STRATEGY_RLE});
  } catch (const cv::Exception& e) {
    throw InputError(path, 0, std::string("cannot write image: ") + e.what());
  }
  if (!ok) throw InputError(path, 0, "cannot write image");
}

void AppendPose(std::string* out, const SE3& pose) {
  char line[512];
  const Eigen::Matrix<double, 3, 4> m = pose.matrix().topRows<3>();
  std::snprintf(line, sizeof(line), "%.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e",
                m(0, 0), m(0, 1), m(0, 2), m(0, 3), m(1, 0), m(1, 1), m(1, 2), m(1, 3), m(2, 0),
                m(2, 1), m(2, 2), m(2, 3));
  *out += line;
}

// precision: significant digits of the real-valued options.
std::string OptionsText(const SynthOptions& o, int precision = 10) {
  std::ostringstream s;
  s.precision(precision);
  s << "frames: " << o.frames << "\nseed: " << o.seed << "\nnum_movers: " << o.num_movers
    << "\nnum_parked: " << o.num_parked << "\nlead_gap_m: " << o.lead_gap_m
    << "\nspeed_mps: " << o.speed_mps << "\nroute: " << RouteName(o.route) << "\nlaps: " << o.laps
    << "\nwidth_px: " << o.width_px << "\nheight_px: " << o.height_px << "\nfx: " << o.fx
    << "\nfy: " << o.fy << "\ncx: " << o.cx << "\ncy: " << o.cy << "\nbaseline_m: " << o.baseline_m
    << "\nrate_hz: " << o.rate_hz << "\ncamera_height_m: " << o.camera_height_m
    << "\nbounce_scale: " << o.bounce_scale << "\nnoise_sigma: " << o.noise_sigma
    << "\nsequence: " << o.sequence << "\nwrite_right_instances: " << o.write_right_instances
    << "\n";
  return s.str();
}

constexpr const char* kCompleteName = kSynthCompleteName;
constexpr const char* kOptionsName = kSynthOptionsName;

// Whether `dir` or a folder in it holds anything but folders.
bool HoldsFiles(const fs::path& dir) {
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it);
       it.increment(ec))
    if (!it->is_directory(ec)) return true;
  return static_cast<bool>(ec);  // unreadable: not known to be empty
}

// What WriteSequence(options, out_dir) would replace although no synthetic render wrote it (see
// RefuseForeignData), "" when nothing.
std::string ForeignSequenceData(const fs::path& seq, const fs::path& poses) {
  std::error_code ec;
  if (fs::exists(seq / kOptionsName, ec) || fs::exists(seq / kCompleteName, ec)) return "";
  if (fs::is_directory(seq, ec) && HoldsFiles(seq)) return seq.string();
  const fs::file_status poses_status = fs::symlink_status(poses, ec);
  if (!fs::exists(poses_status)) return "";
  if (fs::is_regular_file(poses_status) && fs::file_size(poses, ec) == 0 && !ec) return "";
  return poses.string();
}

// Removes the frame images (NNNNNN.png) numbered `first` or higher from dir: an older render into
// the same folder may have held more frames, which a loader would pair with this one's lines.
void RemoveFramesFrom(const fs::path& dir, int first) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  std::vector<fs::path> stale;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.size() != 10 || name.compare(6, 4, ".png") != 0) continue;
    if (!std::all_of(name.begin(), name.begin() + 6, [](char c) { return c >= '0' && c <= '9'; }))
      continue;
    if (std::stoi(name.substr(0, 6)) >= first) stale.push_back(e.path());
  }
  for (const fs::path& p : stale) {
    fs::remove(p, ec);
    if (ec)
      throw InputError(p.string(), 0, "cannot remove an older render's frame: " + ec.message());
  }
}

}  // namespace

std::string KittiCalibText(const SynthOptions& o) {
  std::string text;
  for (int cam = 0; cam < 4; ++cam) {
    const double tx = (cam % 2 == 1) ? -o.fx * o.baseline_m : 0.0;
    char line[512];
    std::snprintf(line, sizeof(line),
                  "P%d: %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e\n",
                  cam, o.fx, 0.0, o.cx, tx, 0.0, o.fy, o.cy, 0.0, 0.0, 0.0, 1.0, 0.0);
    text += line;
  }
  return text;
}

WriteSummary WriteSequence(const SynthOptions& options, const std::string& out_dir,
                           const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  const SyntheticWorld world(options);
  const InstanceTable& table = world.Instances();
  int parked = 0;
  for (const InstanceInfo& info : table.all()) parked += info.moving ? 0 : 1;
  const fs::path seq = fs::path(out_dir) / "sequences" / options.sequence;
  const fs::path poses_dir = fs::path(out_dir) / "poses";
  RefuseForeignData(options, out_dir);
  // A marker of an earlier render here no longer vouches for these files.
  std::error_code ec;
  // (A path through a file is reported by MakeDir below.)
  if (!fs::remove(seq / kCompleteName, ec) && ec && ec != std::errc::not_a_directory)
    throw InputError((seq / kCompleteName).string(), 0, "cannot remove: " + ec.message());
  // synth_options.txt first: it marks the folder as synth's, for a later render's check
  // (RefuseForeignData) even where this one stops early.
  MakeDir(seq);
  WriteText((seq / kOptionsName).string(),
            OptionsText(options) + "num_parked_placed: " + std::to_string(parked) + "\n");
  const char* image_dirs[] = {"image_0", "image_1", "instance_0", "instance_1"};
  const int num_dirs = options.write_right_instances ? 4 : 3;
  for (int i = 0; i < num_dirs; ++i) MakeDir(seq / image_dirs[i]);
  for (int i = 0; i < 4; ++i)
    RemoveFramesFrom(seq / image_dirs[i], i < num_dirs ? options.frames : 0);
  MakeDir(poses_dir);

  WriteText((seq / "calib.txt").string(), KittiCalibText(options));
  {
    std::ostringstream s;
    table.Write(s);
    WriteText((seq / "instances.txt").string(), s.str());
  }
  // Text lines per frame, written at the end (or, after a failure, for the frames whose images
  // were all written, so that a partial sequence stays consistent).
  const int n = options.frames;
  std::vector<std::string> times(n), poses(n), objects(n);
  const std::string poses_path = (poses_dir / (options.sequence + ".txt")).string();
  auto write_text = [&](int frames_done) {
    std::string t, p,
        o = "# frame id visible_px_left r00 r01 r02 tx r10 r11 r12 ty r20 r21 r22 tz "
            "(world_from_object)\n";
    for (int i = 0; i < frames_done; ++i) {
      t += times[i];
      p += poses[i];
      o += objects[i];
    }
    WriteText((seq / "times.txt").string(), t);
    WriteText((seq / "objects.txt").string(), o);
    WriteText(poses_path, p);
  };
  // Frame k+1 renders while frame k's PNGs are encoded on a helper thread.
  std::thread writer;
  std::exception_ptr writer_error;
  int images_done = 0;
  auto join_writer = [&] {
    if (writer.joinable()) writer.join();
    if (writer_error) std::rethrow_exception(writer_error);
  };
  try {
    std::vector<int> visible(65536);
    for (int i = 0; i < n; ++i) {
      RenderedFrame frame = world.RenderFrame(i);
      char line[64];
      std::snprintf(line, sizeof(line), "%e\n", static_cast<double>(frame.t_ns) * 1e-9);
      times[i] = line;
      AppendPose(&poses[i], frame.world_from_cam);
      poses[i] += "\n";
      std::fill(visible.begin(), visible.end(), 0);
      for (int y = 0; y < frame.instance_left.rows; ++y) {
        const uint16_t* row = frame.instance_left.ptr<uint16_t>(y);
        for (int x = 0; x < frame.instance_left.cols; ++x) ++visible[row[x]];
      }
      for (const InstanceInfo& info : table.all()) {
        std::snprintf(line, sizeof(line), "%d %u %d ", i, static_cast<unsigned>(info.id),
                      visible[info.id]);
        objects[i] += line;
        AppendPose(&objects[i], world.WorldFromObject(info.id, i));
        objects[i] += "\n";
      }
      join_writer();
      images_done = i;
      if (progress && i > 0) progress(i, n);
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.png", i);
      writer = std::thread([&, frame = std::move(frame), file = std::string(name)] {
        try {
          WritePng((seq / "image_0" / file).string(), frame.left);
          WritePng((seq / "image_1" / file).string(), frame.right);
          WritePng((seq / "instance_0" / file).string(), frame.instance_left);
          if (num_dirs == 4) WritePng((seq / "instance_1" / file).string(), frame.instance_right);
        } catch (...) {
          writer_error = std::current_exception();
        }
      });
    }
    join_writer();
    images_done = n;
  } catch (...) {
    if (writer.joinable()) writer.join();
    try {
      write_text(images_done);
    } catch (...) {
      // The first error is the one to report.
    }
    throw;
  }
  write_text(n);
  WriteText((seq / kCompleteName).string(), OptionsText(options, 17));  // last of all
  if (progress) progress(n, n);

  WriteSummary summary;
  summary.sequence_dir = seq.string();
  summary.poses_path = poses_path;
  summary.frames = n;
  summary.instances = static_cast<int>(table.size());
  summary.parked_instances = parked;
  summary.moving_instances = summary.instances - parked;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

void RefuseForeignData(const SynthOptions& options, const std::string& out_dir,
                       const std::string& advice) {
  const fs::path seq = fs::path(out_dir) / "sequences" / options.sequence;
  const std::string foreign =
      ForeignSequenceData(seq, fs::path(out_dir) / "poses" / (options.sequence + ".txt"));
  if (!foreign.empty())
    throw InputError(foreign, 0,
                     "not written by pcr_orb synth (" + seq.string() +
                         " has no synth_options.txt): refusing to replace it; " + advice);
}

bool HoldsSequence(const SynthOptions& options, const std::string& out_dir) {
  const fs::path seq = fs::path(out_dir) / "sequences" / options.sequence;
  std::ifstream in(seq / kCompleteName, std::ios::binary);
  if (!in) return false;
  std::ostringstream text;
  text << in.rdbuf();
  return text.str() == OptionsText(options, 17);
}

std::string RenderOnce(const SynthOptions& options, const std::string& out_dir,
                       const ProgressCallback& progress) {
  const fs::path seq = fs::path(out_dir) / "sequences" / options.sequence;
  if (HoldsSequence(options, out_dir)) return seq.string();
  RefuseForeignData(options, out_dir);
  // A render of other options (or an unfinished one) may hold more frames than this one writes.
  std::error_code ec;
  fs::remove_all(seq, ec);
  if (ec) throw InputError(seq.string(), 0, "cannot remove the older render: " + ec.message());
  const fs::path poses = fs::path(out_dir) / "poses" / (options.sequence + ".txt");
  fs::remove(poses, ec);
  if (ec) throw InputError(poses.string(), 0, "cannot remove the older render: " + ec.message());
  return WriteSequence(options, out_dir, progress).sequence_dir;
}

}  // namespace pcr::sim
