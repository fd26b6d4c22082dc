#include "driver/config_schema.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "io/io_test_util.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

struct Opts {
  int count = 5;
  double scale = 1.2;
  bool flag = false;
  std::string name = "x";
};

ConfigSchema MakeSchema(Opts& o) {
  ConfigSchema s;
  s.Add("orb", "count", &o.count);
  s.Add("orb", "scale", &o.scale);
  s.Add("misc", "flag", &o.flag);
  s.Add("misc", "name", &o.name);
  return s;
}

TEST(ConfigSchema, OverridesOnlyGivenKeys) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  s.LoadString("orb:\n  count: 9\nmisc:\n  flag: true\n", "t.yaml");
  EXPECT_EQ(o.count, 9);
  EXPECT_DOUBLE_EQ(o.scale, 1.2);
  EXPECT_TRUE(o.flag);
  EXPECT_EQ(o.name, "x");
}

TEST(ConfigSchema, UnknownKeyNamesFileAndLine) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  test::ExpectInputError([&] { s.LoadString("orb:\n  count: 9\n  cuont: 3\n", "cfg.yaml"); },
                         "cfg.yaml", 3, "cfg.yaml:3: unknown key 'orb.cuont'");
  EXPECT_THROW(s.LoadString("nosuch:\n  a: 1\n", "cfg.yaml"), InputError);
}

TEST(ConfigSchema, WrongTypeAndMalformedYamlRejected) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  test::ExpectInputError([&] { s.LoadString("orb:\n  count: many\n", "cfg.yaml"); }, "cfg.yaml", 2,
                         "not a valid integer");
  EXPECT_THROW(s.LoadString("orb: [1, 2\n", "bad.yaml"), InputError);
  EXPECT_THROW(s.LoadString("orb:\n  scale: .nan\n", "nan.yaml"), InputError);
  EXPECT_EQ(o.count, 5);  // nothing applied by the failed loads above
  EXPECT_THROW(s.LoadString("orb:\n  count: 8\n  scale: big\n", "half.yaml"), InputError);
  EXPECT_EQ(o.count, 5);  // the valid first key of a failing file is rolled back
}

TEST(ConfigSchema, DumpRoundTrips) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  // Every field off its default, so that each one must come back from the dump.
  o.count = 17;
  o.scale = 1.7;
  o.flag = true;
  o.name = "kitti";
  const std::string dumped = s.Dump();
  Opts o2;
  ConfigSchema s2 = MakeSchema(o2);
  s2.LoadString(dumped, "dump");
  EXPECT_EQ(o2.count, 17);
  EXPECT_DOUBLE_EQ(o2.scale, 1.7);
  EXPECT_TRUE(o2.flag);
  EXPECT_EQ(o2.name, "kitti");
}

TEST(ConfigSchema, CommandLineOverride) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  s.Set("orb.scale=1.5", "--set");
  EXPECT_DOUBLE_EQ(o.scale, 1.5);
  EXPECT_THROW(s.Set("orb.scale", "--set"), InputError);
  EXPECT_THROW(s.Set("orb.nokey=1", "--set"), InputError);
}

TEST(ConfigSchema, MissingFileNamed) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  test::ExpectInputError([&] { s.LoadFile("/nonexistent/cfg.yaml"); }, "/nonexistent/cfg.yaml", 0,
                         "/nonexistent/cfg.yaml");
}

TEST(ConfigSchema, ADirectoryOrADeviceIsNotAConfigurationFile) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  const std::string dir = test::MakeTempDir("pcr_schema");
  try {
    s.LoadFile(dir);  // an ifstream opens it and reads nothing: all defaults, silently
    FAIL() << "loaded a directory";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), dir);
    EXPECT_NE(std::string(e.what()).find("directory"), std::string::npos) << e.what();
  }
  EXPECT_THROW(s.LoadFile("/dev/zero"), InputError);  // read until memory runs out
  std::ofstream(dir + "/empty.yaml").close();
  EXPECT_NO_THROW(s.LoadFile(dir + "/empty.yaml"));  // an empty file: all defaults
}

TEST(ConfigSchema, MalformedOverridesAndNonScalarKeysNameTheirSource) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  test::ExpectInputError([&] { s.Set("orb.count=[", "--set"); }, "--set", 0,
                         "--set: orb.count: malformed value '['");
  test::ExpectInputError([&] { s.LoadString("orb:\n  [a, b]: 3\n", "cfg.yaml"); }, "cfg.yaml", 2,
                         "key names must be plain words");
  test::ExpectInputError([&] { s.LoadString("[a, b]:\n  count: 3\n", "cfg.yaml"); }, "cfg.yaml", 1,
                         "section names must be plain words");
  EXPECT_EQ(o.count, 5);
}

TEST(ConfigSchema, AKeyWithNoValueIsReportedAtItsOwnLine) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  test::ExpectInputError(
      [&] { s.LoadString("orb:\n  scale: 1.5\n  count:\nmisc:\n  flag: true\n", "cfg.yaml"); },
      "cfg.yaml", 3, "orb.count");
}

// yaml-cpp keeps both pairs of a repeated key, so the second silently won: a repeated key or
// section is an error at the second one's line, naming it and the first one's line.
TEST(ConfigSchema, ARepeatedKeyOrSectionIsAnErrorAtItsSecondLine) {
  Opts o;
  ConfigSchema s = MakeSchema(o);
  test::ExpectInputError([&] { s.LoadString("orb:\n  count: 9\n  count: 3\n", "cfg.yaml"); },
                         "cfg.yaml", 3,
                         "cfg.yaml:3: key 'orb.count' given twice (first at line 2)");
  test::ExpectInputError([&] { s.LoadString("orb: {count: 9, scale: 1.5, count: 3}\n", "f.yaml"); },
                         "f.yaml", 1, "key 'orb.count' given twice");
  test::ExpectInputError(
      [&] {
        s.LoadString("orb:\n  count: 9\nmisc:\n  flag: true\norb:\n  scale: 1.5\n", "cfg.yaml");
      },
      "cfg.yaml", 5, "cfg.yaml:5: section 'orb' given twice (first at line 1)");
  EXPECT_EQ(o.count, 5);  // nothing applied
  EXPECT_DOUBLE_EQ(o.scale, 1.2);
  // The same key in two sections is two keys.
  ConfigSchema t;
  int a = 0, b = 0;
  t.Add("one", "n", &a);
  t.Add("two", "n", &b);
  t.LoadString("one:\n  n: 1\ntwo:\n  n: 2\n", "ok.yaml");
  EXPECT_EQ(a, 1);
  EXPECT_EQ(b, 2);
}

}  // namespace
}  // namespace pcr::driver
