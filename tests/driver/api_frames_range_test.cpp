// A frame number beyond what a run can address (--frames, api::Source::Dataset) is an
// out-of-range error naming the value, not a "negative frame number".
#include <gtest/gtest.h>

#include <string>

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

}  // namespace
}  // namespace pcr::api
