#include "eval/confusion.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

namespace pcr::eval {
namespace {

// 10 keypoints, positive = dynamic:
//   predicted: 1 1 1 1 0 0 0 0 0 0
//   actual:    1 1 1 0 1 1 0 0 0 0
// TP 3, FP 1, FN 2, TN 4 -> accuracy 7/10, precision 3/4, recall 3/5,
// F1 = 2 * 0.75 * 0.6 / 1.35 = 2/3.
TEST(ConfusionTest, CountsAndRatios) {
  const std::vector<bool> predicted = {1, 1, 1, 1, 0, 0, 0, 0, 0, 0};
  const std::vector<bool> actual = {1, 1, 1, 0, 1, 1, 0, 0, 0, 0};
  const ConfusionMatrix m = CountConfusion(predicted, actual);
  EXPECT_EQ(m.true_positive, 3);
  EXPECT_EQ(m.false_positive, 1);
  EXPECT_EQ(m.false_negative, 2);
  EXPECT_EQ(m.true_negative, 4);
  EXPECT_EQ(m.Total(), 10);
  EXPECT_DOUBLE_EQ(m.Accuracy(), 0.7);
  EXPECT_DOUBLE_EQ(m.Precision(), 0.75);
  EXPECT_DOUBLE_EQ(m.Recall(), 0.6);
  EXPECT_NEAR(m.F1(), 2.0 / 3.0, 1e-15);

  const std::string text = FormatConfusionMatrix(m, "seq 00");
  EXPECT_NE(text.find("seq 00"), std::string::npos);
  EXPECT_NE(text.find("Predicted static"), std::string::npos);
  EXPECT_NE(text.find("Actual dynamic"), std::string::npos);
  EXPECT_NE(text.find("4 (40.00%)"), std::string::npos);  // TN cell
  EXPECT_NE(text.find("Accuracy 70.00%"), std::string::npos);
  EXPECT_NE(text.find("Precision 75.00%"), std::string::npos);
  EXPECT_NE(text.find("Recall 60.00%"), std::string::npos);
  EXPECT_NE(text.find("F1 66.67%"), std::string::npos);
  // Row "Actual static" holds TN then FP.
  const size_t row = text.find("Actual static");
  ASSERT_NE(row, std::string::npos);
  const std::string line = text.substr(row, text.find('\n', row) - row);
  EXPECT_LT(line.find("4 (40.00%)"), line.find("1 (10.00%)"));

  const nlohmann::json j = ToJson(m);
  EXPECT_EQ(j.at("tp"), 3);
  EXPECT_EQ(j.at("fn"), 2);
  EXPECT_DOUBLE_EQ(j.at("precision").get<double>(), 0.75);
}

TEST(ConfusionTest, ZeroDenominatorsAreSafe) {
  ConfusionMatrix empty;
  EXPECT_EQ(empty.Accuracy(), 0.0);
  EXPECT_EQ(empty.Precision(), 0.0);
  EXPECT_EQ(empty.Recall(), 0.0);
  EXPECT_EQ(empty.F1(), 0.0);
  EXPECT_NO_THROW(FormatConfusionMatrix(empty));

  // Nothing predicted dynamic, nothing dynamic: precision / recall / F1 have no positives.
  const ConfusionMatrix all_static = CountConfusion({0, 0, 0}, {0, 0, 0});
  EXPECT_EQ(all_static.true_negative, 3);
  EXPECT_EQ(all_static.Accuracy(), 1.0);
  EXPECT_EQ(all_static.Precision(), 0.0);
  EXPECT_EQ(all_static.F1(), 0.0);

  EXPECT_THROW(CountConfusion({1}, {1, 0}), std::invalid_argument);
}

TEST(ConfusionTest, AddAndAccumulate) {
  ConfusionMatrix a, b;
  a.Add(true, true);
  a.Add(false, true);
  b.Add(true, false);
  b.Add(false, false);
  a += b;
  EXPECT_EQ(a.true_positive, 1);
  EXPECT_EQ(a.false_negative, 1);
  EXPECT_EQ(a.false_positive, 1);
  EXPECT_EQ(a.true_negative, 1);
}

}  // namespace
}  // namespace pcr::eval
