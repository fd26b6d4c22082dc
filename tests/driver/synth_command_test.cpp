// `pcr_orb synth` on the command line: options that wrap, do nothing or name no folder are
// refused before anything is written; a real sequence under --out is not replaced; parked cars
// that do not fit are reported.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "pcr_orb_command.h"
#include "support/data_paths.h"

// (A namespace of its own: the unity build may share another test file's anonymous one.)
namespace pcr::app::synth_command_test {
namespace {
namespace fs = std::filesystem;

// Before, --seed -1 rendered with seed 18446744073709551615.
TEST(SynthCommand, ANegativeSeedIsRefused) {
  const fs::path out = test::MakeTempDir("synth_cmd_seed");
  const test::CommandOutput r =
      test::RunPcrOrb("--log-level warn synth --frames 1 --seed -1 --out " + out.string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("--seed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("-1 is not a whole number from 0 to 18446744073709551615"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(out / "sequences"));
}

// Before, --out "" wrote sequences/ and poses/ into the current folder.
TEST(SynthCommand, AnEmptyOutIsRefused) {
  const fs::path dir = test::MakeTempDir("synth_cmd_out");
  const fs::path cwd = fs::current_path();
  fs::current_path(dir);  // where pcr_orb runs
  const test::CommandOutput r = test::RunPcrOrb("--log-level warn synth --frames 1 --out ''");
  fs::current_path(cwd);
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("synth: --out needs a folder"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "sequences"));
  EXPECT_FALSE(fs::exists(dir / "poses"));
}

// Before, --laps on the straight route was accepted and did nothing.
TEST(SynthCommand, LapsOnTheStraightRouteAreRefused) {
  const fs::path out = test::MakeTempDir("synth_cmd_laps");
  test::CommandOutput r =
      test::RunPcrOrb("--log-level warn synth --frames 1 --laps 2 --out " + out.string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("synth: --laps applies to --route loop only, not to --route straight"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(out / "sequences"));
  r = test::RunPcrOrb("--log-level warn synth --frames 1 --route loop --laps 2 --out " +
                      out.string());
  EXPECT_EQ(r.status, 0) << r.err;
}

// Before, synth --out ROOT --sequence 06 replaced ROOT's real sequence 06 and poses/06.txt.
TEST(SynthCommand, ARealSequenceUnderOutIsNotReplaced) {
  const fs::path out = test::MakeTempDir("synth_cmd_real");
  const fs::path seq = out / "sequences" / "06";
  fs::create_directories(seq / "image_0");
  fs::copy_file(test::SharedPath("data/kitti/sequences/06/image_0/000000.png"),
                seq / "image_0" / "000000.png");
  fs::copy_file(test::SharedPath("data/kitti/sequences/06/calib.txt"), seq / "calib.txt");
  const std::string calib = test::ReadFileText(seq / "calib.txt");
  const test::CommandOutput r =
      test::RunPcrOrb("--log-level warn synth --frames 1 --sequence 06 --out " + out.string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find(seq.string() + ": not written by pcr_orb synth"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("give another --out (or --sequence) or remove it"), std::string::npos)
      << r.err;
  EXPECT_EQ(test::ReadFileText(seq / "calib.txt"), calib);
  EXPECT_FALSE(fs::exists(seq / "synth_options.txt"));
  EXPECT_FALSE(fs::exists(out / "poses"));
}

// Before, --parked 50 placed 17 cars on this short street without a word.
TEST(SynthCommand, ParkedCarsThatDoNotFitAreReported) {
  const fs::path out = test::MakeTempDir("synth_cmd_parked");
  const test::CommandOutput r = test::RunPcrOrb(
      "--log-level warn synth --frames 3 --movers 0 --parked 50 --out " + out.string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("synth: --parked 50: only 17 parked cars fit beside the route"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.out.find("17 instances (0 moving, 17 parked)"), std::string::npos) << r.out;
  const std::string options = test::ReadFileText(out / "sequences" / "00" / "synth_options.txt");
  EXPECT_NE(options.find("\nnum_parked: 50\n"), std::string::npos) << options;
  EXPECT_NE(options.find("\nnum_parked_placed: 17\n"), std::string::npos) << options;
}

}  // namespace
}  // namespace pcr::app::synth_command_test
