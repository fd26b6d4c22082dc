#pragma once
// Helpers for the io tests: writing small files into temporary directories.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "slam/common/error.h"

namespace pcr::test {

inline void WriteText(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

// Runs `fn`, expects an InputError whose file ends with `file_suffix`, whose line is `line`
// (0 = whole file) and whose message contains `needle`.
inline void ExpectInputError(const std::function<void()>& fn, const std::string& file_suffix,
                             int line, const std::string& needle) {
  try {
    fn();
    ADD_FAILURE() << "expected InputError (" << needle << ")";
  } catch (const InputError& e) {
    const std::string file = e.file();
    EXPECT_TRUE(file.size() >= file_suffix.size() &&
                file.compare(file.size() - file_suffix.size(), file_suffix.size(), file_suffix) ==
                    0)
        << "file '" << file << "' does not end with '" << file_suffix << "'";
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

// Makes `dir` the working directory for its lifetime (tests of relative paths).
class WorkingDirectory {
 public:
  explicit WorkingDirectory(const std::string& dir) : previous_(std::filesystem::current_path()) {
    std::filesystem::current_path(dir);
  }
  ~WorkingDirectory() { std::filesystem::current_path(previous_); }
  WorkingDirectory(const WorkingDirectory&) = delete;
  WorkingDirectory& operator=(const WorkingDirectory&) = delete;

 private:
  std::filesystem::path previous_;
};

}  // namespace pcr::test
