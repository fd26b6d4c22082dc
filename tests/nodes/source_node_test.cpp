// The source stage: release schedule, waiting room with drop-oldest, tickets and the inference
// cadence of a quality level.
#include "nodes/source_node.h"

#include <gtest/gtest.h>

#include "slam/common/error.h"

namespace pcr::nodes {
namespace {

FrameSource TenFrames() {
  FrameSource s;
  s.name = "synthetic";
  for (int i = 0; i < 10; ++i) {
    s.frame_indices.push_back(100 + i);
    s.t_ns.push_back(5'000'000'000LL + i * 100'000'000LL);  // 10 Hz, not starting at 0
  }
  return s;
}

TEST(SourceNodeTest, UnpacedReleasesEverythingAtOnceAndNeverDrops) {
  SourceNode source(TenFrames(), SourceOptions{});
  EXPECT_EQ(source.NextReleaseNs(), 0);
  EXPECT_TRUE(source.ReleaseDue(0).empty());
  EXPECT_TRUE(source.AllReleased());
  EXPECT_EQ(source.num_waiting(), 10u);
  EXPECT_FALSE(source.NextReleaseNs().has_value());
}

TEST(SourceNodeTest, PacedReleaseFollowsTimestampsTimesRate) {
  SourceOptions o;
  o.paced = true;
  o.rate = 0.5;
  SourceNode source(TenFrames(), o);
  EXPECT_EQ(source.ReleaseTimeNs(0), 0);
  EXPECT_EQ(source.ReleaseTimeNs(1), 50'000'000);
  EXPECT_EQ(source.ReleaseTimeNs(9), 450'000'000);
  EXPECT_EQ(source.ReleaseDue(120'000'000).size(), 0u);
  EXPECT_EQ(source.num_waiting(), 3u);  // released at 0, 50 and 100 ms
  EXPECT_EQ(source.NextReleaseNs(), 150'000'000);
  // At most max_frames at a time: of the frames due at 300 ms (150, 200, 250, 300), one.
  EXPECT_TRUE(source.ReleaseDue(300'000'000, 1).empty());
  EXPECT_EQ(source.num_waiting(), 4u);
  EXPECT_EQ(source.NextReleaseNs(), 200'000'000);
}

TEST(SourceNodeTest, FullWaitingRoomDropsTheOldestFrame) {
  SourceOptions o;
  o.paced = true;
  o.waiting_capacity = 2;
  SourceNode source(TenFrames(), o);
  const std::vector<WaitingFrame> dropped = source.ReleaseDue(350'000'000);  // frames 0..3
  ASSERT_EQ(dropped.size(), 2u);
  EXPECT_EQ(dropped[0].entry, 0u);
  EXPECT_EQ(dropped[1].entry, 1u);
  EXPECT_EQ(dropped[1].release_ns, 100'000'000);
  EXPECT_EQ(source.dropped(), 2u);
  // The two newest wait; admitting one makes room.
  const FrameTicket t = source.PeekTicket(QualityLevel::kHigh, QualitySettings{});
  EXPECT_EQ(t.frame_index, 102);
  EXPECT_EQ(t.seq, 0);
  EXPECT_EQ(t.t_ns, 5'200'000'000LL);
  EXPECT_EQ(source.Admit(t).entry, 2u);
  EXPECT_TRUE(source.ReleaseDue(400'000'000).empty());  // frame 4 joins frame 3
  EXPECT_EQ(source.num_waiting(), 2u);
}

TEST(SourceNodeTest, SeqIsContiguousAcrossDrops) {
  SourceOptions o;
  o.paced = true;
  o.waiting_capacity = 1;
  SourceNode source(TenFrames(), o);
  source.ReleaseDue(250'000'000);  // 0, 1, 2 released; 0 and 1 dropped
  FrameTicket a = source.PeekTicket(QualityLevel::kHigh, {});
  source.Admit(a);
  source.ReleaseDue(900'000'000);  // 3..9 released; only 9 remains
  FrameTicket b = source.PeekTicket(QualityLevel::kHigh, {});
  source.Admit(b);
  EXPECT_EQ(a.frame_index, 102);
  EXPECT_EQ(b.frame_index, 109);
  EXPECT_EQ(b.seq, a.seq + 1);
  EXPECT_EQ(source.dropped(), 8u);
  EXPECT_EQ(source.admitted(), 2);
}

TEST(SourceNodeTest, InferenceCadenceRestartsAtEveryLevelChange) {
  SourceNode source(TenFrames(), SourceOptions{});
  source.ReleaseDue(0);
  QualitySettings every_second;
  every_second.inference_every = 2;
  const QualitySettings every_frame;
  std::vector<bool> ran;
  const std::vector<QualityLevel> levels = {
      QualityLevel::kLow, QualityLevel::kLow, QualityLevel::kLow,  QualityLevel::kHigh,
      QualityLevel::kLow, QualityLevel::kLow, QualityLevel::kHigh, QualityLevel::kHigh};
  for (QualityLevel l : levels) {
    const QualitySettings& s = l == QualityLevel::kLow ? every_second : every_frame;
    const FrameTicket t = source.PeekTicket(l, s);
    EXPECT_EQ(t.quality, l);
    EXPECT_EQ(t.settings, s);
    ran.push_back(t.run_inference);
    source.Admit(t);
  }
  EXPECT_EQ(ran, (std::vector<bool>{true, false, true, true, true, false, true, true}));
}

TEST(SourceNodeTest, RejectsBadInput) {
  SourceOptions o;
  o.rate = -1;
  EXPECT_THROW(SourceNode(TenFrames(), o), ConfigError);
  FrameSource s = TenFrames();
  s.t_ns.pop_back();
  EXPECT_THROW(SourceNode(s, SourceOptions{}), ConfigError);
  std::string why;
  EXPECT_FALSE(s.IsValid(&why));
  s = TenFrames();
  EXPECT_FALSE(s.IsValid(&why));  // no loaders, no rig
  EXPECT_NEAR(s.NominalPeriodMs(), 100.0, 1e-9);
}

}  // namespace
}  // namespace pcr::nodes
