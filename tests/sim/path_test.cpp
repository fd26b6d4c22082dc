#include "sim/path.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace pcr::sim {
namespace {

constexpr double kPi = std::numbers::pi;

Path RoundedRectangle(double side_x, double side_z, double radius) {
  Path path({0.0, 0.0}, 0.0);
  for (int i = 0; i < 2; ++i) {
    path.AddLine(side_z);
    path.AddArc(radius, -0.5 * kPi);
    path.AddLine(side_x);
    path.AddArc(radius, -0.5 * kPi);
  }
  path.Close();
  return path;
}

TEST(PathTest, StraightLineAndExtrapolation) {
  Path path({1.0, 2.0}, 0.5 * kPi);  // heading +x
  path.AddLine(10.0);
  EXPECT_DOUBLE_EQ(path.Length(), 10.0);
  const PathPoint mid = path.At(4.0);
  EXPECT_NEAR(mid.xz.x(), 5.0, 1e-12);
  EXPECT_NEAR(mid.xz.y(), 2.0, 1e-12);
  EXPECT_NEAR(mid.Right().y(), -1.0, 1e-12);  // right of +x is -z (y down, seen from above)
  EXPECT_NEAR(path.At(-3.0).xz.x(), -2.0, 1e-12);
  EXPECT_NEAR(path.At(15.0).xz.x(), 16.0, 1e-12);
}

TEST(PathTest, ArcTurnsAndKeepsUnitSpeed) {
  Path path({0.0, 0.0}, 0.0);
  path.AddArc(10.0, 0.5 * kPi);  // right turn: heading 0 -> pi/2, ends at (10, 10)
  const PathPoint end = path.At(path.Length());
  EXPECT_NEAR(end.xz.x(), 10.0, 1e-9);
  EXPECT_NEAR(end.xz.y(), 10.0, 1e-9);
  EXPECT_NEAR(end.heading_rad, 0.5 * kPi, 1e-12);
  // Finite differences of position have unit length per metre of arc.
  for (double s = 0.5; s < path.Length(); s += 2.0)
    EXPECT_NEAR((path.At(s + 1e-4).xz - path.At(s).xz).norm(), 1e-4, 1e-9);
}

TEST(PathTest, ClosedLoopWrapsAndClosingErrorIsRejected) {
  const Path loop = RoundedRectangle(30, 50, 12);
  EXPECT_TRUE(loop.closed());
  EXPECT_NEAR((loop.At(loop.Length() + 3.0).xz - loop.At(3.0).xz).norm(), 0.0, 1e-9);
  EXPECT_NEAR((loop.At(-2.0).xz - loop.At(loop.Length() - 2.0).xz).norm(), 0.0, 1e-9);
  Path open({0.0, 0.0}, 0.0);
  open.AddLine(5);
  open.AddArc(3, 0.5 * kPi);
  EXPECT_THROW(open.Close(), std::invalid_argument);
}

TEST(PathTest, OffsetKeepsDistanceAndReversedRetraces) {
  const Path loop = RoundedRectangle(30, 50, 12);
  const Path outer = loop.Offset(2.0);  // left turns: right is outside
  EXPECT_GT(outer.Length(), loop.Length());
  EXPECT_NEAR(outer.Length() - loop.Length(), 4 * 0.5 * kPi * 2.0, 1e-9);
  for (double s = 0; s < loop.Length(); s += 7.3) {
    const PathPoint p = loop.At(s);
    const Eigen::Vector2d q = p.xz + 2.0 * p.Right();
    const double s_outer = outer.Closest(q);
    EXPECT_NEAR((outer.At(s_outer).xz - q).norm(), 0.0, 1e-3) << "s = " << s;
  }
  const Path back = loop.Reversed();
  EXPECT_NEAR(back.Length(), loop.Length(), 1e-9);
  for (double s = 1; s < loop.Length(); s += 9.1) {
    const PathPoint a = loop.At(s), b = back.At(loop.Length() - s);
    EXPECT_NEAR((a.xz - b.xz).norm(), 0.0, 1e-9);
    EXPECT_NEAR(std::remainder(a.heading_rad + kPi - b.heading_rad, 2 * kPi), 0.0, 1e-9);
  }
  EXPECT_THROW(loop.Offset(-13.0), std::invalid_argument);  // inner arcs would collapse
}

}  // namespace
}  // namespace pcr::sim
