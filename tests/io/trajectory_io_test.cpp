#include "io/trajectory_io.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>

#include "io/text_parse.h"
#include "io_test_util.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;
using test::ExpectInputError;
using test::WriteText;

Trajectory RandomTrajectory(int n, std::mt19937* rng, bool stamped) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Trajectory trajectory;
  int64_t t_ns = 1317384506'123456789;
  for (int i = 0; i < n; ++i) {
    StampedPose pose;
    pose.frame_index = stamped ? -1 : i;
    pose.t_ns = stamped ? t_ns : 0;
    t_ns += 100'000'000 + static_cast<int64_t>((*rng)() % 1000);
    const Eigen::Quaterniond q(Eigen::Vector4d(u(*rng), u(*rng), u(*rng), u(*rng)).normalized());
    pose.world_from_cam.linear() = q.toRotationMatrix();
    pose.world_from_cam.translation() = 100.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
    trajectory.push_back(pose);
  }
  return trajectory;
}

double RotationError(const SE3& pose) {
  const Eigen::Matrix3d r = pose.linear();
  return std::max((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(),
                  std::abs(r.determinant() - 1.0));
}

class TrajectoryIoTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::MakeTempDir("pcr_traj_io"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return dir_ + "/" + name; }
  std::string dir_;
};

TEST_F(TrajectoryIoTest, KittiRoundTripIsExact) {
  std::mt19937 rng(7);
  const Trajectory written = RandomTrajectory(50, &rng, false);
  WriteKittiTrajectory(Path("poses.txt"), written);
  const Trajectory read = ReadKittiTrajectory(Path("poses.txt"));
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].frame_index, static_cast<int64_t>(i));
    EXPECT_EQ(read[i].t_ns, 0);
    EXPECT_LT((read[i].world_from_cam.matrix() - written[i].world_from_cam.matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-13);
    EXPECT_LT(RotationError(read[i].world_from_cam), 1e-14);
  }
  // No temporary file left behind.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1);
}

TEST_F(TrajectoryIoTest, TumRoundTripKeepsNanosecondsAndPoses) {
  std::mt19937 rng(11);
  const Trajectory written = RandomTrajectory(40, &rng, true);
  WriteTumTrajectory(Path("traj.tum"), written);
  const Trajectory read = ReadTumTrajectory(Path("traj.tum"));
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].t_ns, written[i].t_ns);  // exact: epoch seconds with 9 decimals
    EXPECT_EQ(read[i].frame_index, -1);
    EXPECT_LT((read[i].world_from_cam.matrix() - written[i].world_from_cam.matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-12);
  }
}

TEST_F(TrajectoryIoTest, WriteReplacesExistingFileAndFailsCleanlyOnBadDirectory) {
  WriteText(Path("poses.txt"), "old\n");
  std::mt19937 rng(3);
  WriteKittiTrajectory(Path("poses.txt"), RandomTrajectory(3, &rng, false));
  EXPECT_EQ(ReadKittiTrajectory(Path("poses.txt")).size(), 3u);
  ExpectInputError([&] { WriteKittiTrajectory(Path("missing_dir/poses.txt"), {}); },
                   "missing_dir/poses.txt", 0, "cannot open");
}

TEST_F(TrajectoryIoTest, WriterExceptionLeavesTheOldFileIntact) {
  WriteText(Path("good.txt"), "precious\n");
  EXPECT_THROW(io::WriteFileAtomically(Path("good.txt"),
                                       [](std::ostream& out) {
                                         out << "half";
                                         throw std::runtime_error("boom");
                                       }),
               std::runtime_error);
  EXPECT_EQ(test::ReadFileText(Path("good.txt")), "precious\n");
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1);
}

// A link is followed (the file it names gets the text, the link stays a link); a FIFO is
// written in place, not replaced by a regular file (eval --json /dev/stdout renamed over it).
TEST_F(TrajectoryIoTest, WritingThroughALinkOrIntoAFifoKeepsThem) {
  WriteText(Path("real.txt"), "old\n");
  fs::create_symlink(Path("real.txt"), Path("link.txt"));
  io::WriteFileAtomically(Path("link.txt"), [](std::ostream& out) { out << "new\n"; });
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(Path("link.txt"))));
  EXPECT_EQ(test::ReadFileText(Path("real.txt")), "new\n");

  const std::string fifo = Path("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);  // so opening to write works
  ASSERT_GE(reader, 0);
  io::WriteFileAtomically(fifo, [](std::ostream& out) { out << "through\n"; });
  EXPECT_TRUE(fs::is_fifo(fs::status(fifo)));
  char buffer[16] = {};
  const ssize_t n = ::read(reader, buffer, sizeof(buffer));
  ::close(reader);
  EXPECT_EQ(std::string(buffer, n > 0 ? static_cast<size_t>(n) : 0), "through\n");
}

// /dev/stdout redirected to a file (>> out.txt) is a link into /proc/self/fd: the file is
// appended to, not replaced by a renamed temporary file (which lost what stood in it).
TEST_F(TrajectoryIoTest, WritingToAnOpenDescriptorsLinkAppendsToItsFile) {
  const std::string file = Path("redirected.txt");
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::write(fd, "PREFIX\n", 7), 7);
  const std::string link = Path("stdout_link");
  fs::create_symlink("/proc/self/fd/" + std::to_string(fd), link);
  io::WriteFileAtomically(link, [](std::ostream& out) { out << "json\n"; });
  ::close(fd);
  EXPECT_EQ(test::ReadFileText(file), "PREFIX\njson\n");
}

TEST_F(TrajectoryIoTest, KittiRotationIsReOrthonormalised) {
  // A rotation about z by 0.3 rad written with 4 significant digits.
  WriteText(Path("p.txt"),
            "0.9553 -0.2955 0 1\n0.2955 0.9553 0 2\n0 0 1 3\n"
            "1 0 0 0 0 1 0 0 0 0 1 0\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("p.txt")); }, "p.txt", 1, "expected 12 numbers");
  WriteText(Path("p.txt"), "0.9553 -0.2955 0 1 0.2955 0.9553 0 2 0 0 1 3\n");
  const Trajectory t = ReadKittiTrajectory(Path("p.txt"));
  ASSERT_EQ(t.size(), 1u);
  EXPECT_LT(RotationError(t[0].world_from_cam), 1e-15);
  EXPECT_NEAR(Eigen::AngleAxisd(t[0].world_from_cam.rotation()).angle(), 0.3, 1e-3);
  EXPECT_EQ(t[0].world_from_cam.translation(), Eigen::Vector3d(1, 2, 3));
  // Not a rotation at all (a scaled matrix, a reflection).
  WriteText(Path("p.txt"), "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 2 0 0 0 0 2 0\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("p.txt")); }, "p.txt", 2, "not a rotation");
  WriteText(Path("p.txt"), "-1 0 0 0 0 1 0 0 0 0 1 0\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("p.txt")); }, "p.txt", 1, "not a rotation");
}

TEST_F(TrajectoryIoTest, KittiBadInputNamesFileAndLine) {
  const std::string good = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  ExpectInputError([&] { ReadKittiTrajectory(Path("nope.txt")); }, "nope.txt", 0, "not found");
  WriteText(Path("a.txt"), good + good + "1 0 0 0 0 1 0 0 0 0 1\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("a.txt")); }, "a.txt", 3,
                   "expected 12 numbers, found 11");
  WriteText(Path("a.txt"), good + "1 0 0 nan 0 1 0 0 0 0 1 0\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("a.txt")); }, "a.txt", 2, "NaN");
  WriteText(Path("a.txt"), "1 0 0 inf 0 1 0 0 0 0 1 0\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("a.txt")); }, "a.txt", 1, "infinite");
  WriteText(Path("a.txt"), good + good + good + "1 0 0 0 0 1 0 0 0 0 1 0x\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("a.txt")); }, "a.txt", 4, "not a number: '0x'");
  WriteText(Path("a.txt"), "1 0 0 1e999 0 1 0 0 0 0 1 0\n");
  ExpectInputError([&] { ReadKittiTrajectory(Path("a.txt")); }, "a.txt", 1, "out of double range");
  WriteText(Path("a.txt"), good + "\n" + good);
  ExpectInputError([&] { ReadKittiTrajectory(Path("a.txt")); }, "a.txt", 2, "blank line");
  // Trailing blank lines and CRLF line ends are fine.
  WriteText(Path("a.txt"), "1 0 0 0 0 1 0 0 0 0 1 0\r\n" + good + "\n\n");
  EXPECT_EQ(ReadKittiTrajectory(Path("a.txt")).size(), 2u);
}

TEST_F(TrajectoryIoTest, TumSkipsCommentsAndRejectsBadLines) {
  WriteText(Path("t.txt"),
            "# header\n\n1.5 1 2 3 0 0 0 1\n  # indented comment\n2.000000001 4 5 6 0 0 0.7071068 "
            "0.7071068\n");
  const Trajectory t = ReadTumTrajectory(Path("t.txt"));
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].t_ns, 1'500'000'000);
  EXPECT_EQ(t[1].t_ns, 2'000'000'001);
  EXPECT_EQ(t[1].world_from_cam.translation(), Eigen::Vector3d(4, 5, 6));
  EXPECT_NEAR(Eigen::AngleAxisd(t[1].world_from_cam.rotation()).angle(), M_PI / 2, 1e-6);
  EXPECT_LT(RotationError(t[1].world_from_cam), 1e-15);

  WriteText(Path("t.txt"), "# c\n1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n");
  ExpectInputError([&] { ReadTumTrajectory(Path("t.txt")); }, "t.txt", 3, "increase");
  WriteText(Path("t.txt"), "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n");
  ExpectInputError([&] { ReadTumTrajectory(Path("t.txt")); }, "t.txt", 2, "increase");
  WriteText(Path("t.txt"), "1 0 0 0 0 0 1\n");
  ExpectInputError([&] { ReadTumTrajectory(Path("t.txt")); }, "t.txt", 1, "expected 8 numbers");
  WriteText(Path("t.txt"), "1 0 0 0 0 0 0 1\n2 0 NaN 0 0 0 0 1\n");
  ExpectInputError([&] { ReadTumTrajectory(Path("t.txt")); }, "t.txt", 2, "NaN");
  WriteText(Path("t.txt"), "abc 0 0 0 0 0 0 1\n");
  ExpectInputError([&] { ReadTumTrajectory(Path("t.txt")); }, "t.txt", 1, "not a time");
  WriteText(Path("t.txt"), "1 0 0 0 0 0 0 0\n");
  ExpectInputError([&] { ReadTumTrajectory(Path("t.txt")); }, "t.txt", 1, "unit length");
  ExpectInputError([&] { ReadTumTrajectory(Path("missing.tum")); }, "missing.tum", 0, "not found");
}

TEST_F(TrajectoryIoTest, KittiTimes) {
  WriteText(Path("times.txt"), "0.000000e+00\n1.044989e-01\n2.077935e-01\n");
  const std::vector<int64_t> t = ReadKittiTimes(Path("times.txt"));
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[0], 0);
  EXPECT_EQ(t[1], 104'498'900);
  EXPECT_EQ(t[2], 207'793'500);
  WriteText(Path("times.txt"), "0\n0.1\n0.1\n");
  ExpectInputError([&] { ReadKittiTimes(Path("times.txt")); }, "times.txt", 3, "increase");
  WriteText(Path("times.txt"), "0\n0.1 0.2\n");
  ExpectInputError([&] { ReadKittiTimes(Path("times.txt")); }, "times.txt", 2, "found 2");
  WriteText(Path("times.txt"), "0\ninf\n");
  ExpectInputError([&] { ReadKittiTimes(Path("times.txt")); }, "times.txt", 2, "infinite");
  WriteText(Path("times.txt"), "0\n-nan\n");
  ExpectInputError([&] { ReadKittiTimes(Path("times.txt")); }, "times.txt", 2, "NaN");
}

TEST(TextParse, SecondsToNsIsExactForDecimals) {
  EXPECT_EQ(io::ParseSecondsToNs("1317384506.123456789", "x", 1), 1317384506'123456789);
  EXPECT_EQ(io::ParseSecondsToNs("0.0000000015", "x", 1), 2);  // rounds half up
  EXPECT_EQ(io::ParseSecondsToNs("-1.5", "x", 1), -1'500'000'000);
  EXPECT_EQ(io::ParseSecondsToNs("7", "x", 1), 7'000'000'000);
  EXPECT_EQ(io::ParseSecondsToNs(".25", "x", 1), 250'000'000);
  EXPECT_THROW(io::ParseSecondsToNs(".", "x", 1), InputError);
  EXPECT_THROW(io::ParseSecondsToNs("1.2.3", "x", 1), InputError);
  EXPECT_THROW(io::ParseSecondsToNs("99999999999", "x", 1), InputError);
}

TEST(TextParse, PlusSignIsNotFollowedByASecondSign) {
  EXPECT_EQ(io::ParseFiniteDouble("+5", "x", 1), 5.0);
  EXPECT_EQ(io::ParseInt("+5", "x", 1), 5);
  ExpectInputError([] { io::ParseFiniteDouble("+-5", "x", 3); }, "x", 3, "not a number: '+-5'");
  ExpectInputError([] { io::ParseInt("+-5", "x", 3); }, "x", 3, "not an integer: '+-5'");
  ExpectInputError([] { io::ParseFiniteDouble("+-inf", "x", 3); }, "x", 3, "not a number");
}

TEST(TextParse, UnderflowIsZeroButOverflowIsAnError) {
  // As strtod: a magnitude below the smallest subnormal rounds to (signed) zero.
  EXPECT_EQ(io::ParseFiniteDouble("1e-400", "x", 1), 0.0);
  EXPECT_TRUE(std::signbit(io::ParseFiniteDouble("-1e-400", "x", 1)));
  EXPECT_EQ(io::ParseFiniteDouble("+0.00001e-99999999999999999999", "x", 1), 0.0);
  EXPECT_EQ(io::ParseFiniteDouble("1e-310", "x", 1), 1e-310);  // subnormal, as it was
  ExpectInputError([] { io::ParseFiniteDouble("1e400", "x", 2); }, "x", 2, "out of double range");
  ExpectInputError([] { io::ParseFiniteDouble("-1e400", "x", 2); }, "x", 2, "out of double range");
  ExpectInputError([] { io::ParseFiniteDouble("0.000001e316", "x", 2); }, "x", 2,
                   "out of double range");  // 1e310
  ExpectInputError([] { io::ParseFiniteDouble("123456e99999999999999999999", "x", 2); }, "x", 2,
                   "out of double range");
}

TEST(TextParse, IstreamOverloadsUseTheGivenName) {
  std::istringstream in("1 0 0 0 0 1 0 0 0 0 1 0\n1 2 3\n");
  ExpectInputError([&] { ReadKittiTrajectory(in, "memory"); }, "memory", 2, "found 3");
}

TEST(RealData, GroundTruthAndTimesLineCounts) {
  const std::pair<const char*, size_t> sequences[] = {{"00", 100}, {"06", 51}, {"07", 160}};
  for (const auto& [name, count] : sequences) {
    const Trajectory gt =
        ReadKittiTrajectory(test::SharedPath("data/kitti/poses/") + name + ".txt");
    ASSERT_EQ(gt.size(), count) << name;
    EXPECT_EQ(gt.back().frame_index, static_cast<int64_t>(count - 1));
    EXPECT_LT(gt.front().world_from_cam.translation().norm(), 1e-9) << name;  // starts at origin
    for (const StampedPose& pose : gt) EXPECT_LT(RotationError(pose.world_from_cam), 1e-14);
    const std::vector<int64_t> times =
        ReadKittiTimes(test::SharedPath("data/kitti/sequences/") + name + "/times.txt");
    EXPECT_EQ(times.size(), count) << name;
  }
  // Seq 06 line 2 (frame 1), read at full precision: t = (-0.01401751, -0.02820321, 1.198998).
  const Trajectory gt06 = ReadKittiTrajectory(test::SharedPath("data/kitti/poses/06.txt"));
  EXPECT_NEAR(gt06[1].world_from_cam.translation().z(), 1.198998, 1e-12);
  EXPECT_NEAR(gt06[1].world_from_cam.translation().x(), -0.01401751, 1e-12);
}

}  // namespace
}  // namespace pcr
