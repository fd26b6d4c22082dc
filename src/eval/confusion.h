#pragma once
// Confusion matrix of the dynamic-point filter (the paper's Fig. 2). Positive = "dynamic":
// a keypoint the filter removed (predicted) / a keypoint on a moving object (actual).
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace pcr::eval {

struct ConfusionMatrix {
  int64_t true_positive = 0;   // predicted dynamic, actually dynamic
  int64_t false_positive = 0;  // predicted dynamic, actually static
  int64_t true_negative = 0;   // predicted static, actually static
  int64_t false_negative = 0;  // predicted static, actually dynamic

  void Add(bool predicted_dynamic, bool actually_dynamic);
  ConfusionMatrix& operator+=(const ConfusionMatrix& other);

  int64_t Total() const { return true_positive + false_positive + true_negative + false_negative; }
  // Ratios in [0, 1]; 0 when the denominator is 0.
  double Accuracy() const;   // (TP + TN) / total
  double Precision() const;  // TP / (TP + FP)
  double Recall() const;     // TP / (TP + FN)
  double F1() const;         // 2 TP / (2 TP + FP + FN) = harmonic mean of precision and recall
};

// Counts per-keypoint decisions; the two vectors must have equal sizes (else
// std::invalid_argument).
ConfusionMatrix CountConfusion(const std::vector<bool>& predicted_dynamic,
                               const std::vector<bool>& actually_dynamic);

// A 2x2 table (rows actual, columns predicted; counts and share of all) and the four ratios.
std::string FormatConfusionMatrix(const ConfusionMatrix& matrix, std::string_view title = "");

nlohmann::json ToJson(const ConfusionMatrix& matrix);

}  // namespace pcr::eval
