#pragma once
// Strict text parsing shared by the dataset readers in src/io. Every failure throws
// pcr::InputError naming the file (the `name` given by the caller) and the 1-based line.
#include <Eigen/Core>
#include <cstdint>
#include <fstream>
#include <functional>
#include <istream>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

namespace pcr::io {

// Splits on ASCII whitespace (space, tab, CR, LF, VT, FF); empty tokens are dropped.
std::vector<std::string_view> SplitWhitespace(std::string_view text);

// A token as an error message shows it: quoted, cut to 40 characters, bytes below 0x20 or above
// 0x7e as \xHH.
std::string Quote(std::string_view token);

// True when the line holds only whitespace.
bool IsBlank(std::string_view line);

// Parses a whole token as a finite double (one leading '+' or '-' allowed). Throws InputError on
// a non-numeric token, trailing characters, NaN, infinity or a value beyond the double range; a
// value too small for a subnormal is a (signed) zero, as strtod gives.
double ParseFiniteDouble(std::string_view token, const std::string& name, int line);

// Parses a whole token as a base-10 integer (one leading '+' or '-' allowed).
int64_t ParseInt(std::string_view token, const std::string& name, int line);

// Parses a decimal time in seconds ("1317384506.123456789", "1.044989e-01") to nanoseconds.
// Plain decimals are converted exactly (digits beyond 1 ns are rounded), so epoch times keep
// full nanosecond precision; exponent notation goes through double.
int64_t ParseSecondsToNs(std::string_view token, const std::string& name, int line);

// Every token of the line parsed with ParseFiniteDouble.
std::vector<double> ParseNumbers(std::string_view line, const std::string& name, int line_no);

// Exactly `count` numbers, else InputError "expected N numbers, found M".
std::vector<double> ParseExactly(std::string_view line, size_t count, const std::string& name,
                                 int line_no);

// The rotation nearest to m in the Frobenius norm (SVD). Throws InputError when m is not
// close to a rotation (max |m^T m - I| > 1e-2, or det(m) <= 0): such a matrix is not a pose.
Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m, const std::string& name, int line);

// Reads lines one at a time and counts them (1-based), stripping a trailing '\r' and a UTF-8
// byte order mark before the first line (as `pcr_orb eval` does: a file saved by an editor that
// writes one reads the same).
class LineReader {
 public:
  LineReader(std::istream& in, std::string name) : in_(in), name_(std::move(name)) {}
  // False at end of input.
  bool Next(std::string* line);
  int line_no() const { return line_no_; }
  const std::string& name() const { return name_; }

 private:
  std::istream& in_;
  std::string name_;
  int line_no_ = 0;
};

// Opens a file for reading; throws InputError(path, 0, ...) when it is missing or unreadable.
std::ifstream OpenInputFile(const std::string& path);

// Writes a file through `write` into a temporary file beside `path`, then renames it over
// `path`, so a failure never leaves a half-written file in place of a good one. A symbolic link
// is followed (the file it names is replaced, the link stays); an existing target that is not a
// regular file (a FIFO, /dev/stdout) is written in place. Throws InputError(path, 0, ...) when
// the file cannot be written.
void WriteFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write);

}  // namespace pcr::io
