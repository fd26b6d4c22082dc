#include "eval/confusion.h"

#include <fmt/format.h>

#include <nlohmann/json.hpp>
#include <stdexcept>

namespace pcr::eval {
namespace {
double Ratio(int64_t numerator, int64_t denominator) {
  return denominator == 0 ? 0.0 : static_cast<double>(numerator) / static_cast<double>(denominator);
}
}  // namespace

void ConfusionMatrix::Add(bool predicted_dynamic, bool actually_dynamic) {
  if (predicted_dynamic)
    ++(actually_dynamic ? true_positive : false_positive);
  else
    ++(actually_dynamic ? false_negative : true_negative);
}

ConfusionMatrix& ConfusionMatrix::operator+=(const ConfusionMatrix& o) {
  true_positive += o.true_positive;
  false_positive += o.false_positive;
  true_negative += o.true_negative;
  false_negative += o.false_negative;
  return *this;
}

double ConfusionMatrix::Accuracy() const { return Ratio(true_positive + true_negative, Total()); }
double ConfusionMatrix::Precision() const {
  return Ratio(true_positive, true_positive + false_positive);
}
double ConfusionMatrix::Recall() const {
  return Ratio(true_positive, true_positive + false_negative);
}
double ConfusionMatrix::F1() const {
  return Ratio(2 * true_positive, 2 * true_positive + false_positive + false_negative);
}

ConfusionMatrix CountConfusion(const std::vector<bool>& predicted_dynamic,
                               const std::vector<bool>& actually_dynamic) {
  if (predicted_dynamic.size() != actually_dynamic.size())
    throw std::invalid_argument("CountConfusion: " + std::to_string(predicted_dynamic.size()) +
                                " decisions but " + std::to_string(actually_dynamic.size()) +
                                " labels");
  ConfusionMatrix m;
  for (size_t i = 0; i < predicted_dynamic.size(); ++i)
    m.Add(predicted_dynamic[i], actually_dynamic[i]);
  return m;
}

std::string FormatConfusionMatrix(const ConfusionMatrix& m, std::string_view title) {
  const int64_t total = m.Total();
  auto cell = [&](int64_t count) {
    return fmt::format("{} ({:.2f}%)", count, 100.0 * Ratio(count, total));
  };
  std::string out;
  if (!title.empty()) out += fmt::format("{}\n", title);
  out += fmt::format("{:<18}{:>22}{:>22}\n", "", "Predicted static", "Predicted dynamic");
  out += fmt::format("{:<18}{:>22}{:>22}\n", "Actual static", cell(m.true_negative),
                     cell(m.false_positive));
  out += fmt::format("{:<18}{:>22}{:>22}\n", "Actual dynamic", cell(m.false_negative),
                     cell(m.true_positive));
  out += fmt::format("Total {}  Accuracy {:.2f}%  Precision {:.2f}%  Recall {:.2f}%  F1 {:.2f}%\n",
                     total, 100.0 * m.Accuracy(), 100.0 * m.Precision(), 100.0 * m.Recall(),
                     100.0 * m.F1());
  return out;
}

nlohmann::json ToJson(const ConfusionMatrix& m) {
  return nlohmann::json{
      {"tp", m.true_positive},      {"fp", m.false_positive}, {"tn", m.true_negative},
      {"fn", m.false_negative},     {"total", m.Total()},     {"accuracy", m.Accuracy()},
      {"precision", m.Precision()}, {"recall", m.Recall()},   {"f1", m.F1()}};
}

}  // namespace pcr::eval
