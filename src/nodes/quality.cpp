#include "nodes/quality.h"

#include <cmath>

#include "slam/common/error.h"
#include "slam/common/validation.h"

namespace pcr::nodes {
const char* ToString(QualityLevel level) {
  switch (level) {
    case QualityLevel::kLow:
      return "low";
    case QualityLevel::kMedium:
      return "medium";
    case QualityLevel::kHigh:
      return "high";
  }
  return "?";
}

bool ParseQualityLevel(const std::string& text, QualityLevel* level) {
  for (QualityLevel l : {QualityLevel::kLow, QualityLevel::kMedium, QualityLevel::kHigh}) {
    if (text == ToString(l)) {
      *level = l;
      return true;
    }
  }
  return false;
}

bool QualitySettings::IsValid(std::string* why) const {
  if (orb_features < 100 || orb_features > 100000)
    return Fail(why, "orb_features must be in [100, 100000]");
  if (inference_every < 1 || inference_every > 1000)
    return Fail(why, "inference_every must be in [1, 1000]");
  if (ba_max_iterations < 1 || ba_max_iterations > 1000)
    return Fail(why, "ba_max_iterations must be in [1, 1000]");
  if (!(min_keyframe_interval_s >= 0 && min_keyframe_interval_s <= 60))
    return Fail(why, "min_keyframe_interval_s must be in [0, 60]");
  if (!(mask_wait_ms <= 10000)) return Fail(why, "mask_wait_ms must be <= 10000 (< 0: default)");
  return true;
}

const QualitySettings& QualityLevels::At(QualityLevel level) const {
  switch (level) {
    case QualityLevel::kLow:
      return low;
    case QualityLevel::kMedium:
      return medium;
    case QualityLevel::kHigh:
      break;
  }
  return high;
}

bool QualityLevels::IsValid(std::string* why) const {
  std::string inner;
  for (QualityLevel l : {QualityLevel::kLow, QualityLevel::kMedium, QualityLevel::kHigh}) {
    if (!At(l).IsValid(&inner)) return Fail(why, std::string(ToString(l)) + ": " + inner);
  }
  return true;
}

bool QualityControllerOptions::IsValid(std::string* why) const {
  if (!(threshold_fraction > 0 && threshold_fraction <= 1))
    return Fail(why, "threshold_fraction must be in (0, 1]");
  if (!(hysteresis_fraction >= 0 && hysteresis_fraction < 0.5))
    return Fail(why, "hysteresis_fraction must be in [0, 0.5)");
  if (min_dwell_frames < 0) return Fail(why, "min_dwell_frames must be >= 0");
  if (!(smoothing > 0 && smoothing <= 1)) return Fail(why, "smoothing must be in (0, 1]");
  return true;
}

QualityController::QualityController(const QualityControllerOptions& options)
    : options_(options), level_(options.initial) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("QualityControllerOptions: " + why);
}

QualityLevel QualityController::Classify(double available_ms, double threshold_ms) {
  if (available_ms > threshold_ms) return QualityLevel::kHigh;
  if (available_ms > 0.5 * threshold_ms) return QualityLevel::kMedium;
  return QualityLevel::kLow;
}

QualityLevel QualityController::Update(double period_ms, double busy_ms) {
  if (!std::isfinite(period_ms) || !std::isfinite(busy_ms) || period_ms <= 0) return level_;
  if (!has_average_) {
    busy_average_ms_ = busy_ms;
    has_average_ = true;
  } else {
    busy_average_ms_ += options_.smoothing * (busy_ms - busy_average_ms_);
  }
  threshold_ms_ = options_.threshold_fraction * period_ms;
  available_ms_ = period_ms - busy_average_ms_;
  ++frames_at_level_;

  const double band_ms = options_.hysteresis_fraction * threshold_ms_;
  const QualityLevel down = Classify(available_ms_ + band_ms, threshold_ms_);
  const QualityLevel up = Classify(available_ms_ - band_ms, threshold_ms_);
  QualityLevel next = level_;
  if (static_cast<int>(down) < static_cast<int>(level_)) {
    next = down;
  } else if (static_cast<int>(up) > static_cast<int>(level_) &&
             frames_at_level_ >= options_.min_dwell_frames) {
    next = static_cast<QualityLevel>(static_cast<int>(level_) + 1);  // one step at a time
  }
  if (next != level_) {
    level_ = next;
    ++changes_;
    frames_at_level_ = 0;
  }
  return level_;
}

}  // namespace pcr::nodes
