// `pcr_orb eval` as a user runs it: inputs read once (a pipe too), outputs that never overwrite
// an input, options that would do nothing refused, out-of-range values naming the option, and
// trajectory files with comments or a byte order mark.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "pcr_orb_command.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

const std::string kGt = test::SharedPath("data/kitti/poses/06.txt");  // 51 poses
const std::string kTimes = test::SharedPath("data/kitti/sequences/06/times.txt");

std::string ReadFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void WriteFileText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// The ground truth as TUM lines (time, position, quaternion of the rotation block).
std::string GroundTruthAsTum() {
  std::ifstream poses(kGt), times(kTimes);
  std::string out = "# t tx ty tz qx qy qz qw\n";
  std::string line;
  double t = 0;
  while (std::getline(poses, line) && times >> t) {
    std::istringstream in(line);
    double m[12];
    for (double& v : m) in >> v;
    Eigen::Matrix3d r;
    r << m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10];
    const Eigen::Quaterniond q(r);
    char buffer[256];
    std::snprintf(buffer, sizeof(buffer), "%.6f %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", t,
                  m[3], m[7], m[11], q.x(), q.y(), q.z(), q.w());
    out += buffer;
  }
  return out;
}

// test::RunPcrOrb with `input` in a pipe as its standard input (the pipe's 64 KiB buffer holds
// it all: nothing has to read it while it is written).
test::CommandOutput RunPcrOrbOnPipedInput(const std::string& input, const std::string& arguments) {
  int fds[2];
  if (pipe(fds) != 0) {
    ADD_FAILURE() << "no pipe";
    return {};
  }
  EXPECT_EQ(write(fds[1], input.data(), input.size()), static_cast<ssize_t>(input.size()));
  close(fds[1]);
  const int saved_stdin = dup(0);
  dup2(fds[0], 0);  // the command's shell and pcr_orb inherit it
  close(fds[0]);
  const test::CommandOutput r = test::RunPcrOrb(arguments);
  dup2(saved_stdin, 0);
  close(saved_stdin);
  return r;
}

TEST(EvalCommand, APipedEstimateIsReadOnce) {
  // The ground truth with long lines (14 KB): the format detection used to read the first 8 KiB
  // of the pipe and the parser the rest, matching 21 poses to frames 0-20 (APE 0.06 m, exit 0).
  std::ifstream poses(kGt);
  std::string text, line;
  while (std::getline(poses, line)) {
    std::istringstream in(line);
    std::string padded;
    double v = 0;
    while (in >> v) {
      char number[64];
      std::snprintf(number, sizeof(number), "%.15f ", v);
      padded += number;
    }
    padded.resize(272, ' ');
    text += padded + "\n";
  }
  ASSERT_GT(text.size(), 8192u);
  ASSERT_LT(text.size(), 65536u);
  const test::CommandOutput r =
      RunPcrOrbOnPipedInput(text, "eval --gt " + kGt + " --est /dev/stdin");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("matched 51 of 51 estimate poses to 51 ground-truth poses"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(test::LineStartingWith(r.out, "RMSE"), "RMSE      |     0.0000  |     0.0000  ")
      << r.out;
}

TEST(EvalCommand, AnOutputThatNamesAnInputIsRefusedBeforeAnythingIsWritten) {
  const std::string dir = test::MakeTempDir("eval_outputs");
  const std::string gt = dir + "/gt.txt", est = dir + "/est.txt", times = dir + "/times.txt";
  std::filesystem::copy_file(kGt, gt);
  std::filesystem::copy_file(kGt, est);
  std::filesystem::copy_file(kTimes, times);
  const std::string poses = ReadFileText(gt), stamps = ReadFileText(times);
  const std::string inputs =
      " --gt " + gt + " --est " + est + " --gt-times " + times + " --est-times " + times;
  const std::string est_by_another_path =
      dir + "/../" + std::filesystem::path(dir).filename().string() + "/est.txt";
  for (const std::string& clash : {"--json " + gt, "--json " + est_by_another_path,
                                   "--plot " + dir + "/p.svg --json " + times}) {
    const test::CommandOutput r = test::RunPcrOrb("eval" + inputs + " " + clash);
    EXPECT_NE(r.status, 0) << clash;
    EXPECT_NE(r.err.find("would overwrite the input"), std::string::npos) << r.err;
  }
  EXPECT_EQ(ReadFileText(gt), poses);
  EXPECT_EQ(ReadFileText(est), poses);
  EXPECT_EQ(ReadFileText(times), stamps);
  EXPECT_FALSE(std::filesystem::exists(dir + "/p.svg"));

  // The two outputs on one file: refused, and nothing written.
  const test::CommandOutput same =
      test::RunPcrOrb("eval" + inputs + " --json " + dir + "/x.svg --plot " + dir + "/./x.svg");
  EXPECT_NE(same.status, 0);
  EXPECT_NE(same.err.find("--json and --plot name the same file"), std::string::npos) << same.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.svg"));
}

// An output whose folder is missing is refused before either output is written (nothing of the
// other is left half done); a write that fails later still leaves the other (OutputErrors).
TEST(EvalCommand, AnOutputThatCannotBeWrittenIsRefusedBeforeEither) {
  const std::string dir = test::MakeTempDir("eval_outputs_fail");
  for (const auto& [json, plot] :
       {std::pair<std::string, std::string>{"/nodir/x.json", "/ok.svg"},
        std::pair<std::string, std::string>{"/ok.json", "/nodir/x.svg"}}) {
    const test::CommandOutput r = test::RunPcrOrb(
        "eval --gt " + kGt + " --est " + kGt + " --json " + dir + json + " --plot " + dir + plot);
    EXPECT_NE(r.status, 0);
    EXPECT_FALSE(std::filesystem::exists(dir + "/ok.svg"));
    EXPECT_FALSE(std::filesystem::exists(dir + "/ok.json"));
    EXPECT_NE(r.err.find(dir + "/nodir/x."), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
  }
}

// Runs each case and expects a non-zero exit status and its error on stderr.
void ExpectEvalErrors(const std::vector<std::pair<std::string, std::string>>& cases) {
  for (const auto& [arguments, error] : cases) {
    const test::CommandOutput r = test::RunPcrOrb("eval --gt " + kGt + " --est " + kGt + arguments);
    EXPECT_NE(r.status, 0) << arguments;
    EXPECT_NE(r.err.find(error), std::string::npos) << arguments << ": " << r.err;
  }
}

TEST(EvalCommand, RepeatedSegmentLengthsAreRefused) {
  // Each occurrence was evaluated and counted: "10 segments" for the 5 of --segments 10.
  ExpectEvalErrors(
      {{" --segments 10,20,10", "--segments must be distinct, got 10 more than once"}});
}

TEST(EvalCommand, OptionsThatWouldDoNothingAreRefused) {
  ExpectEvalErrors({{" --align none --align-first 10", "--align-first needs --align se3 or sim3"},
                    {" --max-diff 5", "--max-diff applies only when poses match by time"},
                    {" --t-offset 3", "--t-offset applies only when poses match by time"}});
}

TEST(EvalCommand, BaselineAndLabelOptionsThatWouldDoNothingAreRefused) {
  const std::string dir = test::MakeTempDir("eval_options");
  ExpectEvalErrors({{" --names a,b", "--names needs --baseline"},
                    {" --baseline-times " + kTimes, "--baseline-times needs --baseline"},
                    {" --baseline " + kGt + " --label L --plot " + dir + "/x.svg",
                     "--label is not used with --baseline"},
                    {" --label L", "--label needs --plot"}});
}

TEST(EvalCommand, OutOfRangeValuesNameTheOption) {
  ExpectEvalErrors(
      {{" --delta 1e300", "--delta must be at most 1000000000, got 1e+300 (delta)"},
       {" --align-first 2", "--align-first must be -1 (all) or at least 3, got 2 (first_n)"},
       {" --max-diff -1 --gt-times " + kTimes + " --est-times " + kTimes,
        "--max-diff must be in [0, 1000000000] s, got -1 (max_diff_s)"}});
}

TEST(EvalCommand, CommentsAndAByteOrderMarkAreAccepted) {
  const std::string dir = test::MakeTempDir("eval_comments");
  WriteFileText(dir + "/kitti.txt", "# KITTI poses\n" + ReadFileText(kGt));
  WriteFileText(dir + "/tum.txt", "\xEF\xBB\xBF" + GroundTruthAsTum());
  const test::CommandOutput kitti =
      test::RunPcrOrb("eval --gt " + kGt + " --est " + dir + "/kitti.txt");
  EXPECT_EQ(kitti.status, 0) << kitti.err;
  EXPECT_NE(kitti.out.find("matched 51 of 51"), std::string::npos) << kitti.out;
  const test::CommandOutput tum =
      test::RunPcrOrb("eval --gt " + kGt + " --gt-times " + kTimes + " --est " + dir + "/tum.txt");
  EXPECT_EQ(tum.status, 0) << tum.err;
  EXPECT_NE(tum.out.find("estimate: " + dir + "/tum.txt (tum)"), std::string::npos) << tum.out;
  EXPECT_NE(tum.out.find("matched 51 of 51 estimate poses to 51 ground-truth poses (by timestamp)"),
            std::string::npos)
      << tum.out;
}

TEST(EvalCommand, TheBaselineIsNamedAsTheBaseline) {
  const std::string dir = test::MakeTempDir("eval_baseline");
  WriteFileText(dir + "/tum.txt", GroundTruthAsTum());
  // A TUM baseline beside KITTI ground truth and estimate.
  const test::CommandOutput r =
      test::RunPcrOrb("eval --gt " + kGt + " --est " + kGt + " --baseline " + dir + "/tum.txt");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("the baseline (" + dir + "/tum.txt) has timestamps"), std::string::npos)
      << r.err;
  // Its times file is in the JSON inputs.
  const test::CommandOutput ok = test::RunPcrOrb(
      "eval --gt " + kGt + " --gt-times " + kTimes + " --est " + dir + "/tum.txt --baseline " +
      kGt + " --baseline-times " + kTimes + " --json " + dir + "/e.json");
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_NE(ReadFileText(dir + "/e.json").find("\"baseline_times\": \"" + kTimes + "\""),
            std::string::npos);
}

}  // namespace
}  // namespace pcr
