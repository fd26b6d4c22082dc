// The command line's own pieces: progress reporting (src/app/progress.h) and the heap options
// (`pcr_orb --mmap-threshold`, graph/heap.h).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "graph/heap.h"
#include "pcr_orb_command.h"

// pcr_app (src/app) is not linked into this binary: its progress reporting is compiled in here.
#include "app/progress.cpp"  // NOLINT(bugprone-suspicious-include)

namespace pcr::app {
namespace {

TEST(Progress, WorkThatStoppedEarlyIsNotShownAsComplete) {
  testing::internal::CaptureStdout();
  {
    Progress progress("run", 6);
    progress.Update(2);
  }  // not finished: as when an exception unwinds through the run
  std::string out = testing::internal::GetCapturedStdout();
  EXPECT_NE(out.find("run: 2/6"), std::string::npos) << out;
  EXPECT_EQ(out.find("6/6"), std::string::npos) << out;
  EXPECT_EQ(out.find("100%"), std::string::npos) << out;

  testing::internal::CaptureStdout();
  {
    Progress progress("run", 6);
    progress.Update(6);
    progress.Finish();
  }
  out = testing::internal::GetCapturedStdout();
  EXPECT_NE(out.find("run: 6/6 (100%)"), std::string::npos) << out;
}

TEST(HeapPolicy, AnMmapThresholdBeyondMalloptsIntIsRefusedNotWrapped) {
  if (graph::ProcessAllocator() != graph::Allocator::kGlibc) GTEST_SKIP() << "not glibc malloc";
  graph::HeapPolicy policy;
  policy.mmap_threshold_bytes = (size_t{1} << 32) + 131072;  // as an int: 131072
  policy.max_arenas = 0;
  EXPECT_FALSE(graph::ConfigureHeap(policy));
}

// The command line refuses an --mmap-threshold glibc cannot take, naming the option.
TEST(CommandLine, MmapThresholdOutOfRangeIsRefused) {
  for (const char* value : {"4295098368", "33554433", "-1", "1e6"}) {
    const test::CommandOutput r = test::RunPcrOrb(std::string("--log-level off --mmap-threshold ") +
                                                  value + " info --model /nonexistent/model.onnx");
    const std::string out = r.out + r.err;
    EXPECT_NE(r.status, 0) << value;
    EXPECT_NE(out.find("--mmap-threshold"), std::string::npos) << value << ": " << out;
    EXPECT_EQ(out.find("cannot open the model"), std::string::npos) << value << ": " << out;
  }
}

// --log-level applies to the library's lines as to the command line's own: the library logs
// through a logger of its own, which hands its lines on to the command line's default logger.
TEST(CommandLine, LogLevelAppliesToTheLibrarysLines) {
  const std::string dir = test::MakeTempDir("pcr_cli_log_level");
  const std::string run = " run --sequence " + test::SharedPath("data/kitti/sequences/06") +
                          " --frames 0:2 --loop off --out " + dir;
  test::CommandOutput r = test::RunPcrOrb("--log-level debug" + run + "/debug");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("] [info] sequential stereo"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("] [debug] effective configuration:"), std::string::npos) << r.out;
  r = test::RunPcrOrb("--log-level info" + run + "/info");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("] [info] sequential stereo"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("[debug]"), std::string::npos) << r.out;
  r = test::RunPcrOrb("--log-level warn" + run + "/warn");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out.find("[info]"), std::string::npos) << r.out;
}

// The driver's set-up errors name the command line's options, not api::Config's fields (which
// api::Run's own users get).
TEST(CommandLine, SetupErrorsNameTheOptions) {
  const std::string run = "--log-level off run --sequence " +
                          test::SharedPath("data/kitti/sequences/06") + " --frames 0:2 --out " +
                          test::MakeTempDir("pcr_cli_setup_errors") + " --loop off";
  test::CommandOutput r = test::RunPcrOrb(run + " --segmenter yolo");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("error: --segmenter yolo needs --model FILE (a YOLOv8-seg ONNX export)"),
            std::string::npos)
      << r.err;
  r = test::RunPcrOrb(run + " --segmenter truth --truth-miss-rate 1.5");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("error: --truth-miss-rate must be in [0, 1] (truth_miss_rate), not 1.5"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("Config::"), std::string::npos) << r.err;
  r = test::RunPcrOrb(run + " --set orb.bogus=1");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("error: --set: unknown key 'orb.bogus'"), std::string::npos) << r.err;
  // Truth labels on a raw drive without ground truth (drive 0005 without its oxts folder).
  const std::string drive = test::RawDriveWithoutGroundTruth("pcr_cli_raw_no_truth");
  const std::string date = std::filesystem::path(drive).parent_path().string();
  r = test::RunPcrOrb("--log-level off run --sequence " + drive + " --frames 0:2 --out " + date +
                      "/out --loop off --filter on --truth-labels " +
                      test::SharedPath("data/kitti_tracking/training/label_02/0000.txt"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("error: --truth-labels needs ground-truth poses for the sequence ("),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("Config::"), std::string::npos) << r.err;
  std::filesystem::remove_all(std::filesystem::path(date).parent_path());
}

}  // namespace
}  // namespace pcr::app
