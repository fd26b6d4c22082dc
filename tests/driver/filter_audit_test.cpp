#include "driver/filter_audit.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "driver/driver.h"
#include "driver/traffic_street.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

DriverOptions Sequential() {
  DriverOptions o;
  o.pipeline.policy = graph::Policy::kSequential;
  return o;
}

// The filter's per-frame reports travel with the frames' records to the audit, in every policy.
TEST(FilterAudit, FilterExcludesMovingObjectPointsFarMoreThanStaticOnes) {
  const Dataset dataset = OpenDataset(test_street::TrafficStreet());
  RunConfig config;
  config.dynamic.segmenter = "truth";
  config.dynamic.filter = true;
  config.dynamic.dump = true;
  const RunSummary s =
      RunDataset(dataset, config, FrameRange{0, dataset.size()}, Sequential()).summary;
  EXPECT_EQ(s.frames_lost, 0u);
  EXPECT_EQ(s.frames_tracked, dataset.size());
  ASSERT_TRUE(s.filtered);
  ASSERT_TRUE(s.filter_confusion.has_value());
  const eval::ConfusionMatrix& c = *s.filter_confusion;
  const double moving_flag_rate = static_cast<double>(c.true_positive) /
                                  std::max<int64_t>(1, c.true_positive + c.false_negative);
  const double static_flag_rate = static_cast<double>(c.false_positive) /
                                  std::max<int64_t>(1, c.false_positive + c.true_negative);
  EXPECT_GT(c.true_positive + c.false_negative, 100) << "scene has too few moving-object points";
  // Measured: 84% of moving-object points flagged against 8.7% of the others (parked cars
  // included). The targets (precision 0.97, recall 0.90) are checked by benchmarks.
  EXPECT_GT(moving_flag_rate, 0.6);
  EXPECT_GT(moving_flag_rate, 5.0 * static_flag_rate)
      << "moving " << moving_flag_rate << " static " << static_flag_rate;
  EXPECT_GT(s.parked_points, 0);
  EXPECT_GT(s.stages.count("filter"), 0u);
  EXPECT_EQ(s.filter_dump.size(), static_cast<size_t>(c.Total()));
  // Sequential: every frame waits for its own mask, so every decision is under a fresh one.
  ASSERT_EQ(s.filter_confusion_by_mask.size(), 1u);
  EXPECT_EQ(s.filter_confusion_by_mask.at("fresh").Total(), c.Total());
  EXPECT_EQ(s.filter_confusion_by_mask.at("fresh").true_positive, c.true_positive);

  const std::string out = test::MakeTempDir("pcr_dynrun_out");
  WriteRunOutputs(out, s, "");
  std::ifstream stats(out + "/stats.json");
  const nlohmann::json j = nlohmann::json::parse(stats);
  EXPECT_TRUE(j["filter"].contains("confusion"));
  EXPECT_EQ(j["filter"]["confusion_by_mask"]["fresh"], j["filter"]["confusion"]);
  EXPECT_TRUE(std::filesystem::exists(out + "/filter_decisions.txt"));
}

TEST(FilterAudit, BadSegmenterSetupsAreClearErrorsBeforeAnyFrameRuns) {
  const Dataset dataset = OpenDataset(test_street::TrafficStreet());
  const FrameRange range{0, 3};
  RunConfig config;
  DynamicRunOptions& o = config.dynamic;
  o.filter = true;
  o.segmenter = "yolo";  // no --model
  EXPECT_THROW(RunDataset(dataset, config, range, Sequential()), ConfigError);
  o.model_path = "/nonexistent/model.onnx";
  EXPECT_THROW(RunDataset(dataset, config, range, Sequential()), InputError);
  o.segmenter = "magic";
  EXPECT_THROW(RunDataset(dataset, config, range, Sequential()), ConfigError);
  o.segmenter = "none";
  o.filter = false;
  o.truth_labels = test::SharedPath("data/kitti_tracking/training/label_02/0000.txt");
  EXPECT_THROW(RunDataset(dataset, config, range, Sequential()), ConfigError);
  // The truth segmenter needs a synthetic sequence.
  const Dataset kitti = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  o.truth_labels.clear();
  o.filter = true;
  o.segmenter = "truth";
  EXPECT_THROW(RunDataset(kitti, config, range, Sequential()), InputError);
}

}  // namespace
}  // namespace pcr::driver
