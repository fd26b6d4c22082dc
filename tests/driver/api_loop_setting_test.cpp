// Loop closing is on when api::Config::loop_closing (--loop) and the configuration's
// loop.enabled (file or --set) both are; config.yaml records that effective setting, so that a
// rerun with --config OUT/config.yaml runs as this run did, and the log says which setting won.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "driver/loop_vocabulary.h"
#include "pcr/api.h"
#include "support/data_paths.h"
#include "support/log_capture.h"
#include "support/shipped_vocabulary.h"

namespace pcr::api {
namespace {

// "enabled: ..." of the loop section of a configuration's text.
std::string LoopEnabledLineIn(const std::string& yaml) {
  std::istringstream in(yaml);
  bool in_loop = false;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != ' ') in_loop = line.rfind("loop:", 0) == 0;
    if (!in_loop || line.rfind("  enabled:", 0) != 0) continue;
    line = line.substr(2, line.find('#') - 2);  // without the comment
    return line.substr(0, line.find_last_not_of(' ') + 1);
  }
  return "";
}

// "enabled: ..." of config.yaml's loop section.
std::string LoopEnabledLine(const std::string& config_yaml) {
  return LoopEnabledLineIn(test::ReadFileText(config_yaml));
}

TEST(LoopSetting, ConfigYamlRecordsTheEffectiveSettingAndTheLogSaysWhichWon) {
  const std::string dir = test::MakeTempDir("pcr_loop_setting");
  const Source source = Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 2);
  Config c;
  c.vocabulary = test::ShippedVocabularyPath();
  // --loop off --set loop.enabled=true: off.
  c.loop_closing = false;
  c.overrides = {"loop.enabled=true"};
  c.out_dir = dir + "/off_over_set";
  {
    test::LogCapture log;
    const Result r = api::Run(c, source);
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_EQ(r.report.find("loop closing:"), std::string::npos) << r.report;
    EXPECT_NE(log.Text().find("loop closing off"), std::string::npos) << log.Text();
  }
  EXPECT_EQ(LoopEnabledLine(c.out_dir + "/config.yaml"), "enabled: false");
  // A rerun with that config.yaml and the default --loop on runs as this one did.
  Config again;
  again.vocabulary = c.vocabulary;
  again.config_file = c.out_dir + "/config.yaml";
  again.out_dir = dir + "/rerun";
  const Result rerun = api::Run(again, source);
  ASSERT_TRUE(rerun.error.empty()) << rerun.error;
  EXPECT_EQ(rerun.report.find("loop closing:"), std::string::npos) << rerun.report;
  EXPECT_EQ(LoopEnabledLine(again.out_dir + "/config.yaml"), "enabled: false");

  // --loop on --set loop.enabled=false: off, and the log names the configuration's setting.
  c.loop_closing = true;
  c.overrides = {"loop.enabled=false"};
  c.out_dir = dir + "/set_over_on";
  {
    test::LogCapture log;
    const Result r = api::Run(c, source);
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_NE(log.Text().find("loop closing off"), std::string::npos) << log.Text();
    EXPECT_NE(log.Text().find("loop.enabled"), std::string::npos) << log.Text();
  }
  EXPECT_EQ(LoopEnabledLine(c.out_dir + "/config.yaml"), "enabled: false");

  // Both on.
  c.overrides.clear();
  c.out_dir = dir + "/on";
  ASSERT_TRUE(api::Run(c, source).error.empty());
  EXPECT_EQ(LoopEnabledLine(c.out_dir + "/config.yaml"), "enabled: true");
}

// No vocabulary to be found: loop closing is off, and config.yaml says so (a rerun with it, once a
// vocabulary is installed, runs as this run did); the warning names where it looked.
TEST(LoopSetting, MissingVocabularyTurnsLoopClosingOffInConfigYaml) {
  const std::string dir = test::MakeTempDir("pcr_loop_no_vocabulary");
  const std::vector<std::string> nowhere = {dir + "/absent_voc.bin"};
  driver::RunConfig run_config = driver::LoadRunConfig("", {"loop.enabled=true"}, nullptr);
  std::string yaml;
  {
    test::LogCapture log;
    const auto vocabulary = driver::ChooseLoopClosing(true, false, "", "", {"loop.enabled=true"},
                                                      &run_config, &yaml, nowhere);
    EXPECT_EQ(vocabulary, nullptr);
    EXPECT_NE(log.Text().find("no vocabulary at " + nowhere[0]), std::string::npos) << log.Text();
  }
  EXPECT_FALSE(run_config.slam.loop.enabled);
  EXPECT_EQ(LoopEnabledLineIn(yaml), "enabled: false") << yaml;

  // A vocabulary among the candidates: on, and the configuration untouched.
  run_config = driver::LoadRunConfig("", {}, &yaml);
  const auto found = driver::ChooseLoopClosing(true, false, "", "", {}, &run_config, &yaml,
                                               {nowhere[0], test::ShippedVocabularyPath()});
  EXPECT_NE(found, nullptr);
  EXPECT_TRUE(run_config.slam.loop.enabled);
  EXPECT_EQ(driver::FindVocabulary("", nowhere), "");
  EXPECT_EQ(driver::FindVocabulary("given.bin", nowhere), "given.bin");
}

}  // namespace
}  // namespace pcr::api
