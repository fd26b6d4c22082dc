// The report's "N keyframes in the database" is the place-recognition database's size at the end
// of the run: the keyframes of a loaded map included, not only those added in this run.
#include <gtest/gtest.h>

#include <regex>
#include <string>

#include "driver/map_file.h"
#include "pcr/api.h"
#include "support/data_paths.h"
#include "support/shipped_vocabulary.h"

namespace pcr::api {
namespace {

// N of "N keyframes in the database" in the report; -1 when the report has no such line.
int DatabaseKeyframes(const std::string& report) {
  std::smatch m;
  if (!std::regex_search(report, m, std::regex("(\\d+) keyframes in the database"))) return -1;
  return std::stoi(m[1]);
}

TEST(LoopDatabaseReport, ALoadedMapsKeyframesAreCountedInTheDatabase) {
  const std::string dir = test::MakeTempDir("pcr_loop_database");
  const std::string kitti06 = test::SharedPath("data/kitti/sequences/06");
  Config c;
  c.vocabulary = test::ShippedVocabularyPath();
  c.save_map = dir + "/first.map";
  const Result first = api::Run(c, Source::Dataset(kitti06, 0, 20));
  ASSERT_TRUE(first.error.empty()) << first.error;
  const size_t saved = driver::LoadMap(c.save_map).map.num_keyframes();
  ASSERT_GE(saved, 3u);
  EXPECT_EQ(DatabaseKeyframes(first.report), static_cast<int>(saved)) << first.report;

  // Localisation only: no keyframe is added, the database holds the loaded map's.
  Config l = c;
  l.load_map = c.save_map;
  l.save_map.clear();
  l.localize_only = true;
  const Result located = api::Run(l, Source::Dataset(kitti06, 20, 23));
  ASSERT_TRUE(located.error.empty()) << located.error;
  EXPECT_EQ(DatabaseKeyframes(located.report), static_cast<int>(saved)) << located.report;

  // Mapping on from the loaded map: the loaded keyframes and the new ones.
  l.localize_only = false;
  l.save_map = dir + "/second.map";
  const Result more = api::Run(l, Source::Dataset(kitti06, 20, 30));
  ASSERT_TRUE(more.error.empty()) << more.error;
  EXPECT_EQ(DatabaseKeyframes(more.report),
            static_cast<int>(driver::LoadMap(l.save_map).map.num_keyframes()))
      << more.report;
}

}  // namespace
}  // namespace pcr::api
