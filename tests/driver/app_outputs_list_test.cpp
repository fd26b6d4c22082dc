// The outputs line of `pcr_orb run` lists exactly the files the run wrote, and a run in which no
// frame was tracked says so on stderr (exit status 0: its outputs were written).
#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <sstream>
#include <string>

#include "pcr_orb_command.h"
#include "support/data_paths.h"

namespace pcr::test {
namespace {

namespace fs = std::filesystem;

// The names inside the braces of "outputs: DIR/{a,b,c}...".
std::set<std::string> ListedNames(const std::string& line) {
  std::set<std::string> names;
  const size_t open = line.find('{'), close = line.find('}');
  if (open == std::string::npos || close == std::string::npos) return names;
  std::istringstream in(line.substr(open + 1, close - open - 1));
  for (std::string name; std::getline(in, name, ',');) names.insert(name);
  return names;
}

std::set<std::string> FilesIn(const std::string& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

TEST(AppOutputs, TheOutputsLineListsExactlyTheFilesWritten) {
  const std::string dir = MakeTempDir("pcr_outputs_list");
  const std::string kitti06 = SharedPath("data/kitti/sequences/06");
  // Monocular, one frame: nothing is initialised, no evaluation, but ground_truth.txt is written.
  const std::string mono = dir + "/mono";
  CommandOutput r = RunPcrOrb("--log-level warn run --mode mono --frames 0:1 --loop off --out " +
                              mono + " --sequence " + kitti06);
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_EQ(ListedNames(LineStartingWith(r.out, "outputs:")), FilesIn(mono)) << r.out;
  EXPECT_TRUE(fs::is_regular_file(mono + "/ground_truth.txt"));
  EXPECT_NE(r.err.find("no frame was tracked"), std::string::npos) << r.err;
  // Stereo, five frames: tracked and evaluated.
  const std::string stereo = dir + "/stereo";
  r = RunPcrOrb("--log-level warn run --frames 0:5 --loop off --out " + stereo + " --sequence " +
                kitti06);
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_EQ(ListedNames(LineStartingWith(r.out, "outputs:")), FilesIn(stereo)) << r.out;
  EXPECT_TRUE(fs::is_regular_file(stereo + "/evaluation.json"));
  EXPECT_EQ(r.err.find("no frame was tracked"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace pcr::test
