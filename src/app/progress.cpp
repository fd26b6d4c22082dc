#include "app/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <mutex>

namespace pcr::app {
namespace {

// The terminal's current line: whether a bar is drawn on it (not ended by a newline). Draw and
// WriteLogLine take the mutex.
std::mutex g_line_mutex;
bool g_bar_on_line = false;

}  // namespace

void WriteLogLine(const std::function<void()>& write) {
  const std::lock_guard<std::mutex> lock(g_line_mutex);
  if (g_bar_on_line) {
    std::printf("\r\033[K");
    std::fflush(stdout);
    g_bar_on_line = false;
  }
  write();
}

Progress::Progress(std::string label, int64_t total)
    : label_(std::move(label)),
      total_(std::max<int64_t>(total, 1)),
      tty_(isatty(STDOUT_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

Progress::~Progress() {
  if (!finished_ && done_ > 0) Stop();
}

void Progress::Update(int64_t done, const std::string& detail, int64_t skipped) {
  done_ = std::clamp<int64_t>(done, 0, total_);
  skipped_ = std::clamp<int64_t>(skipped, 0, total_ - done_);
  const int64_t reached = done_ + skipped_;
  const auto now = std::chrono::steady_clock::now();
  if (tty_) {
    if (now - last_draw_ < std::chrono::milliseconds(100) && reached < total_) return;
    last_draw_ = now;
    Draw(false, detail);
    return;
  }
  const int decile = static_cast<int>(10 * reached / total_);
  if (decile != last_decile_) {
    last_decile_ = decile;
    Draw(false, detail);
  }
}

void Progress::Finish(const std::string& detail, int64_t skipped) {
  if (finished_) return;
  finished_ = true;
  skipped_ = std::clamp<int64_t>(skipped, 0, total_);
  done_ = total_ - skipped_;
  // Plain lines: the last Update may have printed this very line.
  if (!tty_ && detail.empty() && done_ == drawn_done_ && skipped_ == drawn_skipped_) return;
  Draw(true, detail);
}

void Progress::Stop(const std::string& detail) {
  if (finished_) return;
  finished_ = true;
  Draw(true, detail.empty() ? "stopped" : detail);
}

void Progress::Draw(bool final, const std::string& detail) {
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double frac = static_cast<double>(done_ + skipped_) / static_cast<double>(total_);
  const double eta_s = frac > 0 ? elapsed_s * (1.0 - frac) / frac : 0.0;
  const std::string skipped =
      skipped_ > 0 ? " (" + std::to_string(skipped_) + " dropped)" : std::string();
  const std::lock_guard<std::mutex> lock(g_line_mutex);
  if (tty_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(frac * kWidth);
    std::string bar(filled, '#');
    bar.resize(kWidth, '-');
    std::printf("\r%s [%s] %lld/%lld%s %5.1fs eta %5.1fs %s\033[K", label_.c_str(), bar.c_str(),
                static_cast<long long>(done_), static_cast<long long>(total_), skipped.c_str(),
                elapsed_s, eta_s, detail.c_str());
    if (final) std::printf("\n");
    g_bar_on_line = !final;
  } else {
    std::printf("%s: %lld/%lld%s (%3.0f%%) %.1fs %s\n", label_.c_str(),
                static_cast<long long>(done_), static_cast<long long>(total_), skipped.c_str(),
                100.0 * frac, elapsed_s, detail.c_str());
    drawn_done_ = done_;
    drawn_skipped_ = skipped_;
  }
  std::fflush(stdout);
}

}  // namespace pcr::app
