#pragma once
// Runs the build's pcr_orb (PCR_ORB_BINARY, which test_driver depends on: tests/CMakeLists.txt)
// with arguments and returns its exit status, standard output and standard error.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "support/data_paths.h"

namespace pcr::test {

struct CommandOutput {
  int status = -1;  // the exit status (-1: did not exit normally)
  std::string out, err;
};

inline CommandOutput RunPcrOrb(const std::string& arguments) {
  const std::filesystem::path pcr_orb = PCR_ORB_BINARY;
  EXPECT_TRUE(std::filesystem::is_regular_file(pcr_orb)) << "no " << pcr_orb << " built";
  const std::string err_file = MakeTempDir("pcr_orb_command") + "/stderr.txt";
  const std::string command = pcr_orb.string() + " " + arguments + " 2>" + err_file;
  CommandOutput r;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) {
    ADD_FAILURE() << "cannot run " << command;
    return r;
  }
  char buffer[512];
  while (std::fgets(buffer, sizeof(buffer), pipe)) r.out += buffer;
  const int status = pclose(pipe);
  if (WIFEXITED(status)) r.status = WEXITSTATUS(status);
  std::ifstream err(err_file);
  std::ostringstream text;
  text << err.rdbuf();
  r.err = text.str();
  return r;
}

// The line of `text` that starts with `prefix` ("" when none).
inline std::string LineStartingWith(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(prefix, 0) == 0) return line;
  return "";
}

}  // namespace pcr::test
