// Evaluations on the real KITTI 07 ground truth (160 poses, 90.6 m) against copies with known
// changes, written to and read back from files with src/io.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "eval/evaluation.h"
#include "eval/pose_math.h"
#include "eval/report.h"
#include "eval_test_util.h"
#include "io/trajectory_io.h"
#include "support/data_paths.h"

namespace pcr::eval {
namespace {

using test::MakePose;

Trajectory Seq07() { return ReadKittiTrajectory(pcr::test::SharedPath("data/kitti/poses/07.txt")); }

// Writes `t` as a KITTI file into a fresh temp dir and reads it back.
Trajectory RoundTripKitti(const Trajectory& t) {
  const test::ScopedTempDir dir("pcr_eval_rt");
  const std::string path = dir.path + "/est.txt";
  WriteKittiTrajectory(path, t);
  return ReadKittiTrajectory(path);
}

// pose -> s * R * p + t with rotation R * R_i.
Trajectory Mapped(const Trajectory& t, double scale, const Eigen::Matrix3d& rotation,
                  const Eigen::Vector3d& translation) {
  Trajectory out = t;
  for (StampedPose& p : out)
    p.world_from_cam = MakePose(rotation * p.world_from_cam.linear(),
                                scale * (rotation * p.world_from_cam.translation()) + translation);
  return out;
}

const Eigen::Matrix3d kRotation =
    Eigen::AngleAxisd(0.6, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
const Eigen::Vector3d kTranslation(5.0, -2.0, 10.0);

TEST(RealDataTest, Seq07RigidCopyAlignsToZero) {
  const Trajectory gt = Seq07();
  ASSERT_EQ(gt.size(), 160u);
  const Trajectory est = RoundTripKitti(Mapped(gt, 1.0, kRotation, kTranslation));

  const AssociatedTrajectories associated = AssociateByFrameIndex(gt, est);
  ASSERT_EQ(associated.matched(), 160u);
  EvalOptions options;  // se3, RPE delta 1 frame
  options.kitti.lengths_m = {10, 20, 40, 80};
  const EvalResult r = Evaluate(associated, options);
  EXPECT_LT(r.ape.trans_m.max, 1e-6);
  EXPECT_LT(r.ape.rot_deg.max, 1e-5);
  EXPECT_LT(r.rpe.trans_m.max, 1e-6);
  EXPECT_EQ(r.rpe.trans_m.count, 159u);
  // The alignment is the inverse of the applied motion.
  EXPECT_LT((r.alignment.rotation - kRotation.transpose()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((r.alignment.translation + kRotation.transpose() * kTranslation).norm(), 1e-8);
  EXPECT_TRUE(r.kitti.HasSegments());
  EXPECT_LT(r.kitti.t_rel_percent, 1e-6);
  const std::string kitti_text = FormatKittiMetrics(r, options.kitti);
  EXPECT_NE(kitti_text.find("KITTI devkit metrics (every 10 frames"), std::string::npos);
  EXPECT_NE(kitti_text.find("all"), std::string::npos);
  // 90.6 m of path: 80 m segments can only start in the first few frames.
  EXPECT_GT(r.kitti.per_length[3].count, 0u);
  EXPECT_LT(r.kitti.per_length[3].count, r.kitti.per_length[0].count);

  // Without alignment APE_i = ||(R p_i + t) - p_i||.
  options.alignment.mode = AlignMode::kNone;
  const EvalResult raw = Evaluate(associated, options);
  for (size_t i = 0; i < gt.size(); ++i) {
    const Eigen::Vector3d p = gt[i].world_from_cam.translation();
    EXPECT_NEAR(raw.ape.trans_error_m[i], (kRotation * p + kTranslation - p).norm(), 1e-9);
    EXPECT_NEAR(raw.ape.rot_error_deg[i], 0.6 * kDegPerRad, 1e-6);
  }
  // RPE does not depend on a rigid motion of the estimate.
  EXPECT_LT(raw.rpe.trans_m.max, 1e-6);
}

// Known noise: even poses moved 0.1 m along x, odd poses 0.2 m along y (no alignment).
// APE: 80 errors of 0.1 and 80 of 0.2: mean 0.15, median 0.15, rmse sqrt(0.025), std 0.05,
// sse 80 * 0.01 + 80 * 0.04 = 4. RPE (delta 1): E_i,i+1 = [I | A^T R_i^T (o_j - o_i)], so
// every pair has ||t|| = ||(0.1, -0.2, 0)|| = sqrt(0.05) and angle 0.
TEST(RealDataTest, Seq07KnownNoise) {
  const Trajectory gt = Seq07();
  Trajectory noisy = gt;
  for (size_t i = 0; i < noisy.size(); ++i)
    noisy[i].world_from_cam.translation() +=
        (i % 2 == 0) ? Eigen::Vector3d(0.1, 0, 0) : Eigen::Vector3d(0, 0.2, 0);
  const Trajectory est = RoundTripKitti(noisy);
  EvalOptions options;
  options.alignment.mode = AlignMode::kNone;
  const EvalResult r = Evaluate(AssociateByFrameIndex(gt, est), options);
  EXPECT_EQ(r.ape.trans_m.count, 160u);
  EXPECT_NEAR(r.ape.trans_m.mean, 0.15, 1e-9);
  EXPECT_NEAR(r.ape.trans_m.median, 0.15, 1e-9);
  EXPECT_NEAR(r.ape.trans_m.max, 0.2, 1e-9);
  EXPECT_NEAR(r.ape.trans_m.min, 0.1, 1e-9);
  EXPECT_NEAR(r.ape.trans_m.rmse, std::sqrt(0.025), 1e-9);
  EXPECT_NEAR(r.ape.trans_m.std, 0.05, 1e-9);
  EXPECT_NEAR(r.ape.trans_m.sse, 4.0, 1e-8);
  EXPECT_NEAR(r.rpe.trans_m.min, std::sqrt(0.05), 1e-9);
  EXPECT_NEAR(r.rpe.trans_m.max, std::sqrt(0.05), 1e-9);
  EXPECT_NEAR(r.rpe.rot_deg.max, 0.0, 1e-6);

  const std::string report = FormatReport(r, options);
  EXPECT_NE(report.find("matched 160 of 160 estimate poses to 160 ground-truth poses"),
            std::string::npos);
  EXPECT_NE(report.find("0.1500"), std::string::npos);  // the median / mean cells
  // 90.6 m is too short for the default 100 m segments.
  EXPECT_NE(report.find("no segment fits"), std::string::npos);

  const nlohmann::json j = ToJson(r, options);
  EXPECT_EQ(j.at("association").at("matched"), 160);
  EXPECT_NEAR(j.at("ape").at("trans_m").at("rmse").get<double>(), std::sqrt(0.025), 1e-9);
  EXPECT_EQ(j.at("ape").at("trans_error_m").size(), 160u);
  EXPECT_EQ(j.at("rpe").at("pairs").size(), 159u);
  EXPECT_EQ(j.at("alignment").at("mode"), "none");
  EXPECT_TRUE(j.at("kitti").at("t_rel_percent").is_null());
}

// KITTI 06's first 51 frames drive straight: the truth spreads 4.4 cm across the road, less than
// the 5 cm noise added here, so the alignment's roll about the road is the noise's. A path that
// turns (07 bent into an arc here) fixes it. The estimates carry the truth's orientations.
TEST(RealDataTest, AStraightDriveLeavesTheAlignmentsRotationAboutItUndetermined) {
  auto noisy = [](Trajectory t) {
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 0.05);
    for (StampedPose& p : t)
      p.world_from_cam.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    return t;
  };
  EvalOptions options;  // SE(3)
  Trajectory straight = ReadKittiTrajectory(pcr::test::SharedPath("data/kitti/poses/06.txt"));
  straight.resize(51);
  const EvalResult s = Evaluate(AssociateByFrameIndex(straight, noisy(straight)), options);
  EXPECT_NEAR(s.cross_spread_m, 0.0444, 5e-4);
  EXPECT_FALSE(s.RotationDetermined());
  EXPECT_NE(FormatReport(s, options).find("note: the ground truth's positions spread 0.0444 m"),
            std::string::npos);
  EXPECT_FALSE(ToJson(s, options).at("alignment").at("rotation_determined").get<bool>());

  Trajectory arc = Seq07();  // positions on a 40 m arc, the same count
  for (size_t i = 0; i < arc.size(); ++i) {
    const double a = static_cast<double>(i) / static_cast<double>(arc.size()) * 1.5;
    arc[i].world_from_cam.translation() = Eigen::Vector3d(40 * std::sin(a), 0, 40 * std::cos(a));
  }
  const EvalResult t = Evaluate(AssociateByFrameIndex(arc, noisy(arc)), options);
  EXPECT_GT(t.cross_spread_m, 2.0);
  EXPECT_TRUE(t.RotationDetermined());
  EXPECT_EQ(FormatReport(t, options).find("note:"), std::string::npos);
  options.alignment.mode = AlignMode::kNone;  // nothing rotated: nothing to say
  EXPECT_TRUE(
      Evaluate(AssociateByFrameIndex(straight, noisy(straight)), options).RotationDetermined());
}

TEST(RealDataTest, Seq07MonocularScaleNeedsSim3) {
  const Trajectory gt = Seq07();
  const Trajectory est = RoundTripKitti(Mapped(gt, 0.37, kRotation, kTranslation));
  const AssociatedTrajectories associated = AssociateByFrameIndex(gt, est);
  EvalOptions options;
  options.alignment.mode = AlignMode::kSim3;
  options.kitti.lengths_m = {10, 20, 40};
  const EvalResult r = Evaluate(associated, options);
  EXPECT_NEAR(r.alignment.scale, 1.0 / 0.37, 1e-9);
  EXPECT_LT(r.ape.trans_m.max, 1e-6);
  EXPECT_LT(r.rpe.trans_m.max, 1e-6);
  EXPECT_LT(r.kitti.t_rel_percent, 1e-6);

  // se3 keeps the wrong scale: RPE per step = (1 - 0.37) * step length.
  options.alignment.mode = AlignMode::kSe3;
  const EvalResult rigid = Evaluate(associated, options);
  EXPECT_NEAR(rigid.kitti.t_rel_percent, 63.0, 2.0);  // chord / nominal length ~ 1
  for (size_t k = 0; k < rigid.rpe.pairs.size(); ++k) {
    const auto [i, j] = rigid.rpe.pairs[k];
    const double step_m =
        (gt[j].world_from_cam.translation() - gt[i].world_from_cam.translation()).norm();
    EXPECT_NEAR(rigid.rpe.trans_error_m[k], 0.63 * step_m, 1e-6);
  }
}

// The same data as TUM files stamped with the sequence's times.txt; the estimate misses every
// 16th pose and its stamps jitter by +-3 ms: 150 of 160 poses match, all with zero error.
TEST(RealDataTest, Seq07TumFilesAssociateByTime) {
  const Trajectory gt_kitti = Seq07();
  const std::vector<int64_t> times_ns =
      ReadKittiTimes(pcr::test::SharedPath("data/kitti/sequences/07/times.txt"));
  ASSERT_EQ(times_ns.size(), gt_kitti.size());
  Trajectory gt = gt_kitti, est;
  for (size_t i = 0; i < gt.size(); ++i) {
    gt[i].t_ns = times_ns[i];
    if (i % 16 == 5) continue;
    StampedPose p = gt[i];
    p.t_ns += (i % 2 == 0 ? 3'000'000 : -3'000'000);
    est.push_back(p);
  }
  const test::ScopedTempDir dir("pcr_eval_tum");
  WriteTumTrajectory(dir.path + "/gt.tum", gt);
  WriteTumTrajectory(dir.path + "/est.tum", est);
  const Trajectory gt_read = ReadTumTrajectory(dir.path + "/gt.tum");
  const Trajectory est_read = ReadTumTrajectory(dir.path + "/est.tum");
  const AssociatedTrajectories associated = AssociateByTimestamp(gt_read, est_read, {});
  EXPECT_EQ(associated.matched(), 150u);
  EXPECT_EQ(associated.estimate_count, 150u);
  EXPECT_EQ(associated.reference_count, 160u);
  const EvalResult r = Evaluate(associated, {});
  EXPECT_LT(r.ape.trans_m.max, 1e-6);
  EXPECT_NE(FormatMatchLine(r).find(
                "matched 150 of 150 estimate poses to 160 ground-truth poses (by timestamp)"),
            std::string::npos);
  // 2 ms of tolerance is too tight for 3 ms of jitter.
  EXPECT_EQ(AssociateByTimestamp(gt_read, est_read, {0.002, 0}).matched(), 0u);
}

TEST(RealDataTest, TwoRunTableLayout) {
  ErrorStatistics a, b;
  a.max = 3.3476, a.median = 1.0061, a.min = 0.1079, a.rmse = 1.1863, a.count = 10;
  b.max = 3.2745, b.median = 0.9618, b.min = 0.0387, b.rmse = 1.1617, b.count = 10;
  const std::string table = FormatApeRpeTable({{"Original", a, b}, {"PCR-ORB", b, a}}, "m");
  // Header groups and run names in Table 1's order.
  EXPECT_LT(table.find("APE [m]"), table.find("RPE [m]"));
  const size_t names = table.find("Original");
  ASSERT_NE(names, std::string::npos);
  EXPECT_LT(names, table.find("PCR-ORB"));
  // Row "Max": APE Original, APE PCR-ORB, RPE Original, RPE PCR-ORB.
  const size_t row = table.find("Max");
  const std::string line = table.substr(row, table.find('\n', row) - row);
  EXPECT_LT(line.find("3.3476"), line.find("3.2745"));
  EXPECT_NE(line.find("3.2745", line.find("3.3476") + 1), std::string::npos);
  EXPECT_LT(table.find("Max"), table.find("Median"));
  EXPECT_LT(table.find("Median"), table.find("Min"));
  EXPECT_LT(table.find("Min"), table.find("RMSE"));
  EXPECT_NE(table.find(" - "), std::string::npos);  // unset mean / std print as "-"
}

}  // namespace
}  // namespace pcr::eval
