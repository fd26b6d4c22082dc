// What WriteSequence and RenderOnce may replace in their output folder (pcr_orb synth --out):
// an earlier synthetic render, finished or not, but never a sequence that synth did not write
// (a real KITTI sequence and its poses file), and what the summary and synth_options.txt say
// about parked cars that do not fit.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "io/kitti_odometry.h"
#include "sim/instances.h"
#include "sim/sequence_writer.h"
#include "slam/common/error.h"
#include "support/data_paths.h"
#include "support/log_capture.h"

// (A namespace of its own: the unity build shares sequence_writer_test.cpp's anonymous one.)
namespace pcr::sim::guard_test {
namespace {
namespace fs = std::filesystem;

size_t CountFiles(const fs::path& dir) {
  return static_cast<size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}));
}

SynthOptions Small(const std::string& sequence) {
  SynthOptions options = SynthOptions{}.Scaled(0.25);
  options.frames = 2;
  options.sequence = sequence;
  return options;
}

// A copy of real KITTI 06 (calib, times, frames 0-4 of both cameras) and poses/06.txt in out.
void CopyKitti06(const fs::path& out) {
  const fs::path from = test::SharedPath("data/kitti/sequences/06");
  const fs::path seq = out / "sequences" / "06";
  for (const char* dir : {"image_0", "image_1"}) {
    fs::create_directories(seq / dir);
    for (int i = 0; i < 5; ++i) {
      const std::string name = "00000" + std::to_string(i) + ".png";
      fs::copy_file(from / dir / name, seq / dir / name);
    }
  }
  fs::copy_file(from / "calib.txt", seq / "calib.txt");
  fs::copy_file(from / "times.txt", seq / "times.txt");
  fs::create_directories(out / "poses");
  fs::copy_file(test::SharedPath("data/kitti/poses/06.txt"), out / "poses" / "06.txt");
}

// The message of the InputError that f throws ("" and a failure when it throws none).
template <typename F>
std::string InputErrorOf(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

// Before, `pcr_orb synth --out ROOT --sequence 06` replaced ROOT's real sequence 06: frames 2-4
// deleted, frames 0-1, calib.txt, times.txt and poses/06.txt overwritten.
TEST(SequenceWriterGuardTest, ARealKittiSequenceIsNotReplaced) {
  const fs::path out = test::MakeTempDir("sim_guard_kitti");
  CopyKitti06(out);
  const fs::path seq = out / "sequences" / "06";
  const std::string frame0 = test::ReadFileText(seq / "image_0" / "000000.png");
  const std::string calib = test::ReadFileText(seq / "calib.txt");
  const std::string poses = test::ReadFileText(out / "poses" / "06.txt");
  const SynthOptions options = Small("06");

  const std::string error = InputErrorOf([&] { WriteSequence(options, out.string()); });
  EXPECT_EQ(error.rfind(seq.string() + ": not written by pcr_orb synth", 0), 0u) << error;
  EXPECT_NE(error.find("remove it"), std::string::npos) << error;
  EXPECT_THROW(RenderOnce(options, out.string()), InputError);
  const std::string advice =
      InputErrorOf([&] { RefuseForeignData(options, out.string(), "give another --out"); });
  EXPECT_NE(advice.find("give another --out"), std::string::npos) << advice;

  EXPECT_EQ(CountFiles(seq / "image_0"), 5u);
  EXPECT_EQ(CountFiles(seq / "image_1"), 5u);
  EXPECT_FALSE(fs::exists(seq / "instance_0"));
  EXPECT_FALSE(fs::exists(seq / "synth_options.txt"));
  EXPECT_EQ(test::ReadFileText(seq / "image_0" / "000000.png"), frame0);
  EXPECT_EQ(test::ReadFileText(seq / "calib.txt"), calib);
  EXPECT_EQ(test::ReadFileText(out / "poses" / "06.txt"), poses);

  // Another sequence of the same root is written.
  EXPECT_NO_THROW(WriteSequence(Small("07"), out.string()));
  EXPECT_TRUE(HoldsSequence(Small("07"), out.string()));
}

// A poses file with no sequence folder beside it (the KITTI poses download alone) is real
// ground truth too; an empty one is not.
TEST(SequenceWriterGuardTest, APosesFileThatSynthDidNotWriteIsNotReplaced) {
  const fs::path out = test::MakeTempDir("sim_guard_poses");
  fs::create_directories(out / "poses");
  const std::string poses = test::ReadFileText(test::SharedPath("data/kitti/poses/06.txt"));
  std::ofstream(out / "poses" / "00.txt", std::ios::binary) << poses;
  const SynthOptions options = Small("00");
  const std::string error = InputErrorOf([&] { WriteSequence(options, out.string()); });
  EXPECT_EQ(error.rfind((out / "poses" / "00.txt").string() + ": not written", 0), 0u) << error;
  EXPECT_EQ(test::ReadFileText(out / "poses" / "00.txt"), poses);
  EXPECT_FALSE(fs::exists(out / "sequences" / "00" / "synth_options.txt"));

  std::ofstream(out / "poses" / "00.txt", std::ios::trunc);  // empty: nothing to lose
  EXPECT_NO_THROW(WriteSequence(options, out.string()));
  EXPECT_TRUE(HoldsSequence(options, out.string()));
}

// An empty sequence folder (empty folders in it too) is written into; so is an earlier render
// that stopped before its last file, and the earlier render's poses file is replaced with it.
TEST(SequenceWriterGuardTest, EmptyFoldersAndEarlierRendersAreWritten) {
  const fs::path out = test::MakeTempDir("sim_guard_empty");
  const fs::path seq = out / "sequences" / "00";
  fs::create_directories(seq / "image_0");
  SynthOptions options = Small("00");
  EXPECT_NO_THROW(WriteSequence(options, out.string()));

  // An unfinished render: synth_options.txt is its first file, render_complete.txt its last.
  fs::remove(seq / "render_complete.txt");
  fs::remove_all(seq / "instance_1");
  options.frames = 3;
  EXPECT_NO_THROW(WriteSequence(options, out.string()));
  EXPECT_EQ(CountFiles(seq / "image_0"), 3u);
  // Re-rendered by RenderOnce with other options, as the benchmarks do.
  options.frames = 1;
  EXPECT_EQ(RenderOnce(options, out.string()), seq.string());
  EXPECT_EQ(CountFiles(seq / "image_0"), 1u);
  EXPECT_TRUE(HoldsSequence(options, out.string()));
}

// Opening a render that stopped (options without render_complete.txt) warns; a finished one does
// not.
TEST(SequenceWriterGuardTest, OpeningAnUnfinishedRenderWarns) {
  const fs::path out = test::MakeTempDir("sim_guard_unfinished");
  const fs::path seq = out / "sequences" / "00";
  WriteSequence(Small("00"), out.string());
  {
    test::LogCapture log;
    (void)OpenKittiOdometry(seq.string());
    EXPECT_EQ(log.Text().find("did not finish"), std::string::npos) << log.Text();
  }
  fs::remove(seq / "render_complete.txt");
  test::LogCapture log;
  (void)OpenKittiOdometry(seq.string());
  EXPECT_NE(log.Text().find("a synthetic sequence whose render did not finish"), std::string::npos)
      << log.Text();
  fs::remove_all(out);
}

// Before, --parked 50 on a short street placed 17 cars without a word and synth_options.txt said
// 50 alone. Now the summary counts the cars placed and synth_options.txt records both; the
// options themselves (render_complete.txt, compared by HoldsSequence) are as asked, so a second
// RenderOnce with --parked 50 reuses the render.
TEST(SequenceWriterGuardTest, ParkedCarsThatDoNotFitAreCounted) {
  const fs::path out = test::MakeTempDir("sim_guard_parked");
  SynthOptions options = Small("00");
  options.frames = 3;
  options.num_movers = 0;
  options.num_parked = 50;
  const WriteSummary summary = WriteSequence(options, out.string());
  EXPECT_GT(summary.parked_instances, 0);
  EXPECT_LT(summary.parked_instances, 50);
  EXPECT_EQ(summary.moving_instances, 0);
  EXPECT_EQ(summary.instances, summary.parked_instances);
  const fs::path seq = out / "sequences" / "00";
  const InstanceTable table = InstanceTable::Read((seq / "instances.txt").string());
  EXPECT_EQ(static_cast<int>(table.size()), summary.parked_instances);
  const std::string text = test::ReadFileText(seq / "synth_options.txt");
  EXPECT_NE(text.find("\nnum_parked: 50\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nnum_parked_placed: " + std::to_string(summary.parked_instances) + "\n"),
            std::string::npos)
      << text;
  EXPECT_TRUE(HoldsSequence(options, out.string()));

  // All of them placed: the same count twice.
  options.num_parked = 2;
  const WriteSummary two = WriteSequence(options, out.string());
  EXPECT_EQ(two.parked_instances, 2);
  EXPECT_NE(test::ReadFileText(seq / "synth_options.txt").find("\nnum_parked_placed: 2\n"),
            std::string::npos);
}

}  // namespace
}  // namespace pcr::sim::guard_test
