#include "sim/sequence_writer.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "io/kitti_odometry.h"
#include "io/trajectory_io.h"
#include "sim/instances.h"
#include "sim/synthetic_world.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::sim {
namespace {
namespace fs = std::filesystem;

std::vector<std::string> Lines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<double> Numbers(const std::string& text) {
  std::istringstream in(text);
  std::vector<double> out;
  for (double x; in >> x;) out.push_back(x);
  return out;
}

size_t CountFiles(const fs::path& dir) {
  return static_cast<size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}));
}

TEST(SequenceWriterTest, WritesALoadableKittiSequence) {
  const std::string out = test::MakeTempDir("sim_writer");
  SynthOptions options;
  options.frames = 4;
  options.sequence = "07";
  std::vector<std::pair<int, int>> calls;
  const WriteSummary summary =
      WriteSequence(options, out, [&](int done, int total) { calls.emplace_back(done, total); });
  const fs::path seq = fs::path(out) / "sequences" / "07";
  EXPECT_EQ(summary.sequence_dir, seq.string());
  EXPECT_EQ(summary.frames, 4);
  ASSERT_FALSE(calls.empty());
  EXPECT_EQ(calls.back(), std::make_pair(4, 4));
  for (size_t i = 1; i < calls.size(); ++i) EXPECT_GT(calls[i].first, calls[i - 1].first);

  for (const char* dir : {"image_0", "image_1", "instance_0", "instance_1"})
    EXPECT_EQ(CountFiles(seq / dir), 4u) << dir;
  EXPECT_TRUE(fs::exists(seq / "image_0" / "000003.png"));

  const std::vector<std::string> calib = Lines(seq / "calib.txt");
  ASSERT_EQ(calib.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(calib[i].rfind("P" + std::to_string(i) + ": ", 0), 0u);
    const std::vector<double> p = Numbers(calib[i].substr(4));
    ASSERT_EQ(p.size(), 12u);
    EXPECT_DOUBLE_EQ(p[0], 718.856);
    EXPECT_NEAR(p[3], i % 2 == 1 ? -718.856 * 0.537 : 0.0, 1e-9);
  }
  const std::vector<std::string> times = Lines(seq / "times.txt");
  ASSERT_EQ(times.size(), 4u);
  EXPECT_EQ(times[0], "0.000000e+00");
  for (size_t i = 1; i < times.size(); ++i) EXPECT_GT(std::stod(times[i]), std::stod(times[i - 1]));
  const std::vector<std::string> poses = Lines(fs::path(out) / "poses" / "07.txt");
  ASSERT_EQ(poses.size(), 4u);
  for (const std::string& line : poses) EXPECT_EQ(Numbers(line).size(), 12u);

  const InstanceTable table = InstanceTable::Read((seq / "instances.txt").string());
  EXPECT_EQ(static_cast<int>(table.size()), summary.instances);
  EXPECT_EQ(table.size(), 15u);
  size_t object_lines = 0;
  for (const std::string& line : Lines(seq / "objects.txt")) {
    if (line.empty() || line[0] == '#') continue;
    EXPECT_EQ(Numbers(line).size(), 15u);
    ++object_lines;
  }
  EXPECT_EQ(object_lines, 4 * table.size());

  // The written images are the rendered ones; instance images are 16-bit.
  const SyntheticWorld world(options);
  const RenderedFrame frame = world.RenderFrame(2);
  const cv::Mat left = cv::imread((seq / "image_0" / "000002.png").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat ids =
      cv::imread((seq / "instance_0" / "000002.png").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat ids_right =
      cv::imread((seq / "instance_1" / "000002.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(left.type(), CV_8UC1);
  ASSERT_EQ(ids.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(left, frame.left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(ids, frame.instance_left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(ids_right, frame.instance_right, cv::NORM_INF), 0.0);

  // The project's own readers load it.
  const Trajectory gt = ReadKittiTrajectory((fs::path(out) / "poses" / "07.txt").string());
  ASSERT_EQ(gt.size(), 4u);
  EXPECT_TRUE(gt[3].world_from_cam.isApprox(world.WorldFromCam(3), 1e-7));
  const Dataset dataset = OpenKittiOdometry(seq.string());
  EXPECT_EQ(dataset.size(), 4u);
  EXPECT_TRUE(dataset.has_right());
  EXPECT_NEAR(dataset.rig.left.fx, 718.856, 1e-6);
  EXPECT_NEAR(dataset.rig.left.cx, 607.1928, 1e-6);
  EXPECT_NEAR(dataset.rig.baseline_m, 0.537, 1e-9);
  EXPECT_EQ(dataset.rig.left.width_px, 1241);
  EXPECT_EQ(dataset.rig.left.height_px, 376);
  ASSERT_TRUE(dataset.ground_truth.has_value());
  EXPECT_EQ(dataset.ground_truth->size(), 4u);
  EXPECT_EQ(dataset.t_ns.size(), 4u);
  EXPECT_EQ(cv::norm(dataset.LoadRight(2), frame.right, cv::NORM_INF), 0.0);
  fs::remove_all(out);
}

TEST(SequenceWriterTest, SameSeedWritesIdenticalFiles) {
  SynthOptions options = SynthOptions{}.Scaled(0.25);
  options.frames = 3;
  const std::string a = test::MakeTempDir("sim_writer_a"), b = test::MakeTempDir("sim_writer_b");
  const std::string c = test::MakeTempDir("sim_writer_c");
  WriteSequence(options, a);
  WriteSequence(options, b);
  options.seed = 5;
  WriteSequence(options, c);
  for (const std::string rel :
       {"sequences/00/image_0/000002.png", "sequences/00/image_1/000001.png",
        "sequences/00/instance_0/000002.png", "sequences/00/objects.txt",
        "sequences/00/instances.txt", "poses/00.txt"}) {
    // FileBytes reads a missing file as empty: two missing files must not pass as identical.
    const std::string in_a = test::ReadFileText(fs::path(a) / rel);
    EXPECT_FALSE(in_a.empty()) << rel;
    EXPECT_EQ(in_a, test::ReadFileText(fs::path(b) / rel)) << rel;
  }
  const std::string image_c = test::ReadFileText(fs::path(c) / "sequences/00/image_0/000002.png");
  EXPECT_FALSE(image_c.empty());
  EXPECT_NE(test::ReadFileText(fs::path(a) / "sequences/00/image_0/000002.png"), image_c);
  for (const auto& dir : {a, b, c}) fs::remove_all(dir);
}

TEST(SequenceWriterTest, RenderOnceReusesOnlyAFinishedRenderOfTheSameOptions) {
  SynthOptions options = SynthOptions{}.Scaled(0.25);
  options.frames = 3;
  const std::string out = test::MakeTempDir("sim_render_once");
  const fs::path seq = fs::path(out) / "sequences" / "00";
  EXPECT_FALSE(HoldsSequence(options, out));
  EXPECT_EQ(RenderOnce(options, out), seq.string());
  EXPECT_TRUE(HoldsSequence(options, out));
  EXPECT_EQ(CountFiles(seq / "image_0"), 3u);

  // Reused: a file put beside the render survives a second call.
  const fs::path sentinel = seq / "sentinel";
  std::ofstream(sentinel) << "x";
  EXPECT_EQ(RenderOnce(options, out), seq.string());
  EXPECT_TRUE(fs::exists(sentinel));

  // Any option counts, to the last digit, and so does whether instance_1/ is written.
  SynthOptions other = options;
  other.noise_sigma += 1e-12;
  EXPECT_FALSE(HoldsSequence(other, out));
  other = options;
  other.write_right_instances = false;
  EXPECT_FALSE(HoldsSequence(other, out));
  other = options;
  other.frames = 2;
  EXPECT_FALSE(HoldsSequence(other, out));

  // Other options render afresh: the older frames and files go, the new render is held.
  EXPECT_EQ(RenderOnce(other, out), seq.string());
  EXPECT_FALSE(fs::exists(sentinel));
  EXPECT_EQ(CountFiles(seq / "image_0"), 2u);
  EXPECT_EQ(Lines(fs::path(out) / "poses" / "00.txt").size(), 2u);
  EXPECT_TRUE(HoldsSequence(other, out));
  EXPECT_FALSE(HoldsSequence(options, out));

  // A render that did not finish has no marker; WriteSequence removes an older one first.
  fs::remove(seq / "render_complete.txt");
  EXPECT_FALSE(HoldsSequence(other, out));
  EXPECT_EQ(RenderOnce(other, out), seq.string());
  EXPECT_TRUE(HoldsSequence(other, out));
  const fs::path blocked = seq / "image_1";  // a file where a folder goes: the render fails
  fs::remove_all(blocked);
  std::ofstream(blocked) << "x";
  EXPECT_THROW(WriteSequence(other, out), InputError);
  EXPECT_FALSE(HoldsSequence(other, out));
  fs::remove_all(out);
}

// Written over an older, longer render (pcr_orb synth --out DIR twice): the older frames beyond
// this render's go, and the folder loads as this render (before, 5 timestamps and 30 images).
TEST(SequenceWriterTest, AShorterRenderOverALongerOneLeavesNoOlderFrames) {
  SynthOptions options = SynthOptions{}.Scaled(0.25);
  options.frames = 4;
  const std::string out = test::MakeTempDir("sim_writer_over");
  const fs::path seq = fs::path(out) / "sequences" / "00";
  WriteSequence(options, out);
  std::ofstream(seq / "image_0" / "notes.png") << "x";  // not a frame: kept
  options.frames = 2;
  options.write_right_instances = false;
  WriteSequence(options, out);
  for (const char* dir : {"image_0", "image_1", "instance_0"})
    EXPECT_TRUE(fs::exists(seq / dir / "000001.png") && !fs::exists(seq / dir / "000002.png") &&
                !fs::exists(seq / dir / "000003.png"))
        << dir;
  EXPECT_EQ(CountFiles(seq / "instance_1"), 0u);  // not written this time: none left
  EXPECT_TRUE(fs::exists(seq / "image_0" / "notes.png"));
  fs::remove(seq / "image_0" / "notes.png");
  EXPECT_EQ(OpenKittiOdometry(seq.string()).size(), 2u);
  fs::remove_all(out);
}

TEST(SequenceWriterTest, UnwritableOutputThrowsInputError) {
  const std::string dir = test::MakeTempDir("sim_writer_bad");
  const std::string file = dir + "/not_a_dir";
  std::ofstream(file) << "x";
  SynthOptions options = SynthOptions{}.Scaled(0.25);
  options.frames = 1;
  EXPECT_THROW(WriteSequence(options, file), InputError);
  options.frames = 0;
  EXPECT_THROW(WriteSequence(options, dir), ConfigError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pcr::sim
