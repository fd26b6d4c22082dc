#include "io/text_parse.h"

#include <unistd.h>

#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>
#include <system_error>

#include "slam/common/error.h"
#include "slam/common/pose.h"

namespace pcr::io {
namespace {

bool IsSpace(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

// Strips one leading '+' (from_chars accepts only '-'); false when a second sign follows it.
bool StripPlus(std::string_view* digits) {
  if (digits->empty() || digits->front() != '+') return true;
  digits->remove_prefix(1);
  return digits->empty() || (digits->front() != '-' && digits->front() != '+');
}

// For a decimal number that from_chars parsed whole but found out of double range: true when its
// magnitude is below 1, i.e. it underflowed rather than overflowed.
bool IsUnderflow(std::string_view digits) {
  if (!digits.empty() && digits.front() == '-') digits.remove_prefix(1);
  const size_t e = digits.find_first_of("eE");
  const std::string_view mantissa = digits.substr(0, e);
  constexpr int64_t kMaxExponent = 1'000'000'000'000;  // saturates; the sign is what counts
  int64_t exponent = 0;
  if (e != std::string_view::npos) {
    std::string_view text = digits.substr(e + 1);
    const bool negative = !text.empty() && text.front() == '-';
    if (!text.empty() && (text.front() == '-' || text.front() == '+')) text.remove_prefix(1);
    for (char c : text) exponent = std::min(exponent * 10 + (c - '0'), kMaxExponent);
    if (negative) exponent = -exponent;
  }
  // Decimal order of the mantissa's first non-zero digit: 0 for "1.5", -3 for "0.0012".
  const size_t dot = mantissa.find('.');
  const std::string_view whole = mantissa.substr(0, dot);
  const std::string_view frac =
      dot == std::string_view::npos ? std::string_view() : mantissa.substr(dot + 1);
  int64_t order = 0;
  const size_t first_whole = whole.find_first_not_of('0');
  if (first_whole != std::string_view::npos) {
    order = static_cast<int64_t>(whole.size() - first_whole) - 1;
  } else {
    const size_t first_frac = frac.find_first_not_of('0');
    if (first_frac == std::string_view::npos) return true;  // zero (not out of range anyway)
    order = -static_cast<int64_t>(first_frac) - 1;
  }
  return order + exponent < 0;
}

}  // namespace

std::string Quote(std::string_view token) {
  constexpr size_t kMaxShown = 40;
  std::string out = "'";
  for (size_t i = 0; i < token.size() && i < kMaxShown; ++i) {
    const unsigned char c = static_cast<unsigned char>(token[i]);
    if (c < 0x20 || c >= 0x7f) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xf];
    } else {
      out += static_cast<char>(c);
    }
  }
  if (token.size() > kMaxShown) out += "...";
  return out + "'";
}

std::vector<std::string_view> SplitWhitespace(std::string_view text) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && IsSpace(text[i])) ++i;
    const size_t begin = i;
    while (i < text.size() && !IsSpace(text[i])) ++i;
    if (i > begin) tokens.push_back(text.substr(begin, i - begin));
  }
  return tokens;
}

bool IsBlank(std::string_view line) {
  for (char c : line)
    if (!IsSpace(c)) return false;
  return true;
}

double ParseFiniteDouble(std::string_view token, const std::string& name, int line) {
  std::string_view digits = token;
  if (!StripPlus(&digits)) throw InputError(name, line, "not a number: " + Quote(token));
  double value = 0;
  const char* end = digits.data() + digits.size();
  const auto [ptr, ec] = std::from_chars(digits.data(), end, value);
  if (digits.empty() || ptr != end || (ec != std::errc() && ec != std::errc::result_out_of_range))
    throw InputError(name, line, "not a number: " + Quote(token));
  if (ec == std::errc::result_out_of_range) {
    // from_chars reports underflow too (and leaves value alone); strtod's answer there is a zero.
    if (!IsUnderflow(digits))
      throw InputError(name, line, "number out of double range: " + Quote(token));
    value = digits.front() == '-' ? -0.0 : 0.0;
  }
  if (std::isnan(value)) throw InputError(name, line, "NaN is not allowed: " + Quote(token));
  if (!std::isfinite(value))
    throw InputError(name, line, "infinite value is not allowed: " + Quote(token));
  return value;
}

int64_t ParseInt(std::string_view token, const std::string& name, int line) {
  std::string_view digits = token;
  if (!StripPlus(&digits)) throw InputError(name, line, "not an integer: " + Quote(token));
  int64_t value = 0;
  const char* end = digits.data() + digits.size();
  const auto [ptr, ec] = std::from_chars(digits.data(), end, value);
  if (digits.empty() || ptr != end || ec != std::errc())
    throw InputError(name, line, "not an integer: " + Quote(token));
  return value;
}

int64_t ParseSecondsToNs(std::string_view token, const std::string& name, int line) {
  if (token.find_first_of("eEnNiI") != std::string_view::npos) {
    const double t_s = ParseFiniteDouble(token, name, line);
    if (std::abs(t_s) > 9.0e9) throw InputError(name, line, "time out of range: " + Quote(token));
    return SecondsToNs(t_s);
  }
  std::string_view s = token;
  bool negative = false;
  if (!s.empty() && (s.front() == '+' || s.front() == '-')) {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  const size_t dot = s.find('.');
  const std::string_view whole = s.substr(0, dot);
  const std::string_view frac =
      dot == std::string_view::npos ? std::string_view() : s.substr(dot + 1);
  const auto all_digits = [](std::string_view d) {
    for (char c : d)
      if (c < '0' || c > '9') return false;
    return true;
  };
  if ((whole.empty() && frac.empty()) || !all_digits(whole) || !all_digits(frac))
    throw InputError(name, line, "not a time in seconds: " + Quote(token));
  constexpr int64_t kMaxWholeSeconds = 9'000'000'000;
  int64_t whole_s = 0;
  for (char c : whole) {
    whole_s = whole_s * 10 + (c - '0');
    if (whole_s > kMaxWholeSeconds)
      throw InputError(name, line, "time out of range: " + Quote(token));
  }
  int64_t frac_ns = 0;
  for (size_t i = 0; i < 9; ++i) frac_ns = frac_ns * 10 + (i < frac.size() ? frac[i] - '0' : 0);
  if (frac.size() > 9 && frac[9] >= '5') ++frac_ns;  // round half up on the 10th digit
  const int64_t t_ns = whole_s * 1'000'000'000 + frac_ns;
  return negative ? -t_ns : t_ns;
}

std::vector<double> ParseNumbers(std::string_view line, const std::string& name, int line_no) {
  std::vector<double> values;
  for (std::string_view token : SplitWhitespace(line))
    values.push_back(ParseFiniteDouble(token, name, line_no));
  return values;
}

std::vector<double> ParseExactly(std::string_view line, size_t count, const std::string& name,
                                 int line_no) {
  const std::vector<std::string_view> tokens = SplitWhitespace(line);
  if (tokens.size() != count)
    throw InputError(
        name, line_no,
        "expected " + std::to_string(count) + " numbers, found " + std::to_string(tokens.size()));
  std::vector<double> values;
  values.reserve(count);
  for (std::string_view token : tokens) values.push_back(ParseFiniteDouble(token, name, line_no));
  return values;
}

Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m, const std::string& name, int line) {
  constexpr double kTolerance = 1e-2;
  const double deviation = (m.transpose() * m - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(deviation <= kTolerance) || !(m.determinant() > 0))
    throw InputError(
        name, line,
        "rotation block is not a rotation (max |R^T R - I| = " + std::to_string(deviation) +
            ", det = " + std::to_string(m.determinant()) + ")");
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) = -u.col(2);
    r = u * svd.matrixV().transpose();
  }
  return r;
}

bool LineReader::Next(std::string* line) {
  if (!std::getline(in_, *line)) return false;
  ++line_no_;
  if (!line->empty() && line->back() == '\r') line->pop_back();
  if (line_no_ == 1 && line->rfind("\xEF\xBB\xBF", 0) == 0) line->erase(0, 3);
  return true;
}

std::ifstream OpenInputFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(path, 0, "file not found");
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path, 0, "is a directory, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open file for reading");
  return in;
}

void WriteFileAtomically(const std::string& given_path,
                         const std::function<void(std::ostream&)>& write) {
  namespace fs = std::filesystem;
  std::error_code status_ec;
  const fs::file_status target = fs::status(given_path, status_ec);  // follows links
  const bool link = fs::is_symlink(fs::symlink_status(given_path, status_ec));
  // /dev/stdout and the like: a link into /proc/<pid>/fd names an open descriptor, whose file
  // (a pipe, a terminal, or the file the shell redirected to, perhaps with >>) is appended to,
  // never replaced.
  const bool descriptor =
      given_path.starts_with("/dev/") || given_path.starts_with("/proc/") ||
      (link && fs::read_symlink(given_path, status_ec).string().starts_with("/proc/"));
  if (fs::is_directory(target)) throw InputError(given_path, 0, "is a directory");
  if (descriptor || (fs::exists(target) && !fs::is_regular_file(target))) {
    // A FIFO or a device: written in place; renaming over it would replace it.
    std::ofstream out(given_path, std::ios::binary | std::ios::app);
    if (!out) throw InputError(given_path, 0, "cannot open for writing");
    write(out);
    out.flush();
    if (!out) throw InputError(given_path, 0, "write failed");
    return;
  }
  // Through a symbolic link: the file it names is replaced, not the link.
  std::string path = given_path;
  if (link) {
    const fs::path resolved = fs::weakly_canonical(given_path, status_ec);
    if (!status_ec) path = resolved.string();
  }
  const std::string tmp_path = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp_path, std::ios::binary | std::ios::trunc);
    if (!out)
      throw InputError(given_path, 0, "cannot open a temporary file for writing: " + tmp_path);
    try {
      write(out);
    } catch (...) {
      out.close();
      std::error_code ignored;
      fs::remove(tmp_path, ignored);
      throw;
    }
    out.flush();
    if (!out) {
      out.close();
      std::error_code ignored;
      fs::remove(tmp_path, ignored);
      throw InputError(given_path, 0, "write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp_path, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp_path, ignored);
    throw InputError(given_path, 0, "cannot replace file: " + ec.message());
  }
}

}  // namespace pcr::io
