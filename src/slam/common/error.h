#pragma once
// Errors for bad input. Expected failures are values (see TrackingStatus); these are thrown at the
// edge when a file or configuration cannot be used, and always name the file and, where known, the
// 1-based line.
#include <stdexcept>
#include <string>

namespace pcr {

class InputError : public std::runtime_error {
 public:
  // line <= 0 means "whole file" (no line number in the message).
  InputError(const std::string& file, int line, const std::string& what);
  const std::string& file() const { return file_; }
  int line() const { return line_; }

 private:
  std::string file_;
  int line_;
};

// Configuration that fails its IsValid() check.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pcr
