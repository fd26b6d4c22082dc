// A frame number beyond what a run can address (--frames, api::Source::Dataset) is an
// out-of-range error naming the value, not a "negative frame number".
#include <gtest/gtest.h>

#include <string>
#include <tuple>

#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

// The error of Source::Dataset(path, frames) and then Run; "" when neither failed.
std::string FramesError(const std::string& frames) {
  try {
    Config c;
    c.loop_closing = false;
    (void)api::Run(c, Source::Dataset(test::SharedPath("data/kitti/sequences/06"), frames));
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(FramesRange, AFrameNumberOutOfRangeIsNamed) {
  for (const char* number :
       {"18446744073709551615", "9223372036854775808", "99999999999999999999999"}) {
    const std::string value = number;
    for (const std::string& frames : {value + ":3", "0:" + value, value + ":"}) {
      const std::string e = FramesError(frames);
      EXPECT_NE(e.find("out of range"), std::string::npos) << frames << ": " << e;
      EXPECT_NE(e.find("'" + value + "'"), std::string::npos) << frames << ": " << e;
      EXPECT_EQ(e.find("negative"), std::string::npos) << frames << ": " << e;
    }
  }
}

// A range that selects no frame (B <= A) is refused by Source::Dataset itself, as its
// documentation says, not by a later Run; the errors name the argument and the command line's
// option.
TEST(FramesRange, SourceDatasetRefusesARangeThatSelectsNoFrame) {
  for (const std::string frames : {"5:2", "5:5"}) {
    try {
      const Source s = Source::Dataset("kitti/sequences/06", frames);
      ADD_FAILURE() << frames << " gave " << s.first << ":" << s.end;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind(
                    "Source::Dataset frames (--frames) '" + frames + "' selects no frame: B (", 0),
                0u)
          << e.what();
    }
  }
  try {
    (void)Source::Dataset("kitti/sequences/06", "abc");
    ADD_FAILURE() << "accepted abc";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "Source::Dataset frames (--frames) 'abc' is not A:B");
  }
  for (const auto& [frames, first, end] : {std::tuple{"2:5", 2, 5}, std::tuple{"5:", 5, 0},
                                           std::tuple{":5", 0, 5}, std::tuple{"", 0, 0}}) {
    const Source s = Source::Dataset("kitti/sequences/06", frames);
    EXPECT_EQ(s.first, first) << frames;
    EXPECT_EQ(s.end, end) << frames;
  }
}

}  // namespace
}  // namespace pcr::api
