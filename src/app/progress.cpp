#include "app/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace pcr::app {

Progress::Progress(std::string label, int64_t total)
    : label_(std::move(label)),
      total_(std::max<int64_t>(total, 1)),
      tty_(isatty(STDOUT_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

Progress::~Progress() {
  if (!finished_ && done_ > 0) Stop();
}

void Progress::Update(int64_t done, const std::string& detail) {
  done_ = std::clamp<int64_t>(done, 0, total_);
  const auto now = std::chrono::steady_clock::now();
  if (tty_) {
    if (now - last_draw_ < std::chrono::milliseconds(100) && done_ < total_) return;
    last_draw_ = now;
    Draw(false, detail);
    return;
  }
  const int decile = static_cast<int>(10 * done_ / total_);
  if (decile != last_decile_) {
    last_decile_ = decile;
    Draw(false, detail);
  }
}

void Progress::Finish(const std::string& detail) {
  if (finished_) return;
  finished_ = true;
  done_ = total_;
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
  const double frac = static_cast<double>(done_) / static_cast<double>(total_);
  const double eta_s = done_ > 0 ? elapsed_s * (1.0 - frac) / frac : 0.0;
  if (tty_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(frac * kWidth);
    std::string bar(filled, '#');
    bar.resize(kWidth, '-');
    std::printf("\r%s [%s] %lld/%lld %5.1fs eta %5.1fs %s\033[K", label_.c_str(), bar.c_str(),
                static_cast<long long>(done_), static_cast<long long>(total_), elapsed_s, eta_s,
                detail.c_str());
    if (final) std::printf("\n");
  } else {
    std::printf("%s: %lld/%lld (%3.0f%%) %.1fs %s\n", label_.c_str(), static_cast<long long>(done_),
                static_cast<long long>(total_), 100.0 * frac, elapsed_s, detail.c_str());
  }
  std::fflush(stdout);
}

}  // namespace pcr::app
