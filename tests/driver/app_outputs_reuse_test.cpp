// After a run, --out describes that run only: the files an earlier run wrote there that this one
// did not (the run's known output names; nothing else) are removed, and the outputs line says so.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "pcr_orb_command.h"
#include "support/data_paths.h"

namespace pcr::test {
namespace {

namespace fs = std::filesystem;

TEST(AppOutputs, AReusedOutputDirectoryHoldsOnlyTheLatestRunsFiles) {
  const std::string dir = MakeTempDir("pcr_outputs_reuse");
  const std::string kitti06 = SharedPath("data/kitti/sequences/06");
  // KITTI 06 without its poses file: no ground truth.
  const std::string bare = dir + "/kitti/sequences/06";
  fs::create_directories(bare);
  for (const char* name : {"image_0", "image_1", "calib.txt", "times.txt"})
    fs::create_symlink(kitti06 + "/" + name, bare + "/" + name);
  const std::string out = dir + "/o_reuse";
  const std::string common = "--log-level warn run --frames 0:5 --loop off --out " + out;

  CommandOutput r = RunPcrOrb(common + " --sequence " + kitti06);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  for (const char* name : {"ground_truth.txt", "evaluation.json", "trajectory.png"})
    ASSERT_TRUE(fs::is_regular_file(out + "/" + name)) << name;
  std::ofstream(out + "/notes.txt") << "mine\n";  // not a name the run writes

  r = RunPcrOrb(common + " --sequence " + bare);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_TRUE(fs::is_regular_file(out + "/trajectory.txt"));
  EXPECT_TRUE(fs::is_regular_file(out + "/stats.json"));
  EXPECT_TRUE(fs::is_regular_file(out + "/notes.txt"));
  const std::string line = LineStartingWith(r.out, "outputs:");
  const size_t removed = line.find("removed");
  EXPECT_NE(removed, std::string::npos) << line;
  for (const char* name : {"ground_truth.txt", "evaluation.json", "trajectory.png"}) {
    EXPECT_FALSE(fs::exists(out + "/" + name)) << name;
    // Named after "removed", not among the files written.
    EXPECT_GT(line.find(name), removed) << name << ": " << line;
  }
}

}  // namespace
}  // namespace pcr::test
