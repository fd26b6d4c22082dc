// The mask board: exactly one segmentation message per frame, fresh when it is in time, "late"
// with the newest earlier result after the deadline; and the queue-depth sweep of the profiler.
#include "graph/mask_board.h"

#include <gtest/gtest.h>

#include <vector>

#include "graph/profiler.h"
#include "nodes/segment_node.h"

namespace pcr::graph {
namespace {

using nodes::SegmentationOutcome;

nodes::FrameTicket Ticket(int64_t seq) {
  nodes::FrameTicket t;
  t.seq = seq;
  t.frame_index = seq;
  return t;
}

nodes::SegmentationPtr Fresh(int64_t seq) {
  auto m = std::make_shared<nodes::SegmentationMsg>();
  m->ticket = Ticket(seq);
  m->outcome = SegmentationOutcome::kFresh;
  m->segmentation = std::make_shared<const Segmentation>();
  return m;
}

struct Recorder {
  std::vector<nodes::SegmentationPtr> emitted;
  int wakes = 0;
  MaskBoard Board(double deadline_ms, bool wait_for_first = false) {
    return MaskBoard(
        deadline_ms, [this](const nodes::SegmentationPtr& m) { emitted.push_back(m); },
        [this] { ++wakes; }, wait_for_first);
  }
};

TEST(MaskBoardTest, WithoutDeadlineEveryResultPassesAsIs) {
  Recorder r;
  MaskBoard board = r.Board(-1);
  board.OnFeaturesReady(Ticket(0), 0);
  EXPECT_TRUE(r.emitted.empty());  // waits for the result, however long
  EXPECT_FALSE(board.NextDeadlineNs().has_value());
  board.OnSegmentation(Fresh(0));
  board.OnSegmentation(Fresh(1));  // before its features: emitted at once, the join keeps it
  board.OnFeaturesReady(Ticket(1), 5);
  ASSERT_EQ(r.emitted.size(), 2u);
  EXPECT_EQ(r.emitted[0]->outcome, SegmentationOutcome::kFresh);
  EXPECT_EQ(r.emitted[1]->ticket.seq, 1);
  EXPECT_EQ(board.late(), 0u);
  EXPECT_EQ(r.wakes, 0);
}

TEST(MaskBoardTest, DeadlineEmitsLateWithTheNewestEarlierResult) {
  Recorder r;
  MaskBoard board = r.Board(10);
  board.OnSegmentation(Fresh(0));
  board.OnFeaturesReady(Ticket(0), 0);
  board.OnFeaturesReady(Ticket(2), 1'000'000);  // deadline at 11 ms
  EXPECT_EQ(r.wakes, 1);
  EXPECT_EQ(board.NextDeadlineNs(), 11'000'000);
  board.ExpireDue(10'999'999);
  EXPECT_EQ(r.emitted.size(), 1u);
  board.OnSegmentation(Fresh(1));  // frame 1's result, in time for frame 1 (not for frame 2)
  board.ExpireDue(11'000'000);
  ASSERT_EQ(r.emitted.size(), 3u);
  const nodes::SegmentationPtr& late = r.emitted[2];
  EXPECT_EQ(late->ticket.seq, 2);
  EXPECT_EQ(late->outcome, SegmentationOutcome::kLate);
  EXPECT_EQ(late->fallback_seq, 1);
  EXPECT_TRUE(late->fallback != nullptr);
  EXPECT_FALSE(board.NextDeadlineNs().has_value());
  // Frame 2's own result arrives after its deadline: no second message, counted as late result.
  board.OnSegmentation(Fresh(2));
  EXPECT_EQ(r.emitted.size(), 3u);
  EXPECT_EQ(board.late(), 1u);
  EXPECT_EQ(board.late_results(), 1u);
}

TEST(MaskBoardTest, AFramesQualitySettingsCanWaitLongerForItsMask) {
  Recorder r;
  MaskBoard board = r.Board(10);
  nodes::FrameTicket patient = Ticket(0);
  patient.settings.mask_wait_ms = 120;
  board.OnFeaturesReady(patient, 0);
  EXPECT_EQ(board.NextDeadlineNs(), 120'000'000);
  board.ExpireDue(100'000'000);
  EXPECT_TRUE(r.emitted.empty());
  board.OnSegmentation(Fresh(0));  // in time for the longer wait
  ASSERT_EQ(r.emitted.size(), 1u);
  EXPECT_EQ(r.emitted[0]->outcome, SegmentationOutcome::kFresh);
  // Without a deadline (not realtime) the frame's setting changes nothing: it always waits.
  Recorder r2;
  MaskBoard no_deadline = r2.Board(-1);
  no_deadline.OnFeaturesReady(patient, 0);
  EXPECT_FALSE(no_deadline.NextDeadlineNs().has_value());
}

TEST(MaskBoardTest, ZeroDeadlineAndNotRunResultsCarryTheFallbackAtOnce) {
  Recorder r;
  MaskBoard board = r.Board(0);
  board.OnSegmentation(Fresh(3));
  board.OnFeaturesReady(Ticket(3), 0);
  board.OnFeaturesReady(Ticket(4), 0);  // no result yet: late immediately
  board.OnSegmentation(nodes::SegmentNode::NotRun(Ticket(5), SegmentationOutcome::kBusy));
  ASSERT_EQ(r.emitted.size(), 3u);
  EXPECT_EQ(r.emitted[1]->outcome, SegmentationOutcome::kLate);
  EXPECT_EQ(r.emitted[1]->fallback_seq, 3);
  EXPECT_EQ(r.emitted[2]->outcome, SegmentationOutcome::kBusy);
  EXPECT_EQ(r.emitted[2]->fallback_seq, 3);
  board.OnSegmentation(nodes::SegmentNode::NotRun(Ticket(4), SegmentationOutcome::kBusy));
  board.OnFeaturesReady(Ticket(5), 0);
  EXPECT_EQ(r.emitted.size(), 3u);  // one message per frame, never two
}

// Before any fresh result there is nothing to carry: frames wait for their own result, and get
// their deadlines (from when their features were ready) once the first one arrives.
TEST(MaskBoardTest, FramesBeforeTheFirstMaskWaitForTheirOwn) {
  Recorder r;
  MaskBoard board = r.Board(10, /*wait_for_first=*/true);
  board.OnFeaturesReady(Ticket(0), 0);
  board.OnFeaturesReady(Ticket(1), 1'000'000);
  EXPECT_FALSE(board.NextDeadlineNs().has_value());
  board.ExpireDue(500'000'000);  // far past a 10 ms deadline: still waiting
  EXPECT_TRUE(r.emitted.empty());
  board.OnSegmentation(Fresh(0));  // the first mask, 500 ms late
  ASSERT_EQ(r.emitted.size(), 1u);
  EXPECT_EQ(r.emitted[0]->outcome, SegmentationOutcome::kFresh);
  EXPECT_EQ(board.NextDeadlineNs(), 11'000'000);  // frame 1: its features at 1 ms + 10 ms
  EXPECT_EQ(r.wakes, 1);
  board.ExpireDue(500'000'001);
  ASSERT_EQ(r.emitted.size(), 2u);
  EXPECT_EQ(r.emitted[1]->ticket.seq, 1);
  EXPECT_EQ(r.emitted[1]->outcome, SegmentationOutcome::kLate);
  EXPECT_EQ(r.emitted[1]->fallback_seq, 0);
  // From then on the deadline applies as before.
  board.OnFeaturesReady(Ticket(2), 600'000'000);
  EXPECT_EQ(board.NextDeadlineNs(), 610'000'000);
  EXPECT_EQ(board.late(), 1u);

  // A zero deadline: the frames that waited go on with the first mask as soon as it exists.
  Recorder z;
  MaskBoard zero = z.Board(0, /*wait_for_first=*/true);
  zero.OnFeaturesReady(Ticket(0), 0);
  zero.OnFeaturesReady(Ticket(1), 0);
  EXPECT_TRUE(z.emitted.empty());
  zero.OnSegmentation(Fresh(0));
  ASSERT_EQ(z.emitted.size(), 2u);
  EXPECT_EQ(z.emitted[1]->outcome, SegmentationOutcome::kLate);
  EXPECT_EQ(z.emitted[1]->fallback_seq, 0);
  zero.OnFeaturesReady(Ticket(2), 0);  // after the first mask: emitted at once
  EXPECT_EQ(z.emitted.size(), 3u);
}

TEST(ProfilerTest, MaxQueueDepthCountsOverlappingWaits) {
  EXPECT_EQ(MaxQueueDepth({}), 0u);
  EXPECT_EQ(MaxQueueDepth({{0, 0}, {5, 5}}), 0u);            // nobody waited
  EXPECT_EQ(MaxQueueDepth({{0, 10}, {10, 20}}), 1u);         // back to back
  EXPECT_EQ(MaxQueueDepth({{0, 10}, {2, 12}, {4, 6}}), 3u);  // three at t = 5
  EXPECT_EQ(MaxQueueDepth({{0, 3}, {4, 8}, {5, 6}, {9, 10}}), 2u);
  Profiler profiler;
  profiler.Record("tracking", 1, 7, 30, 40);
  profiler.Record("tracking", 0, 6, 10, 20);
  const std::vector<StageEvent> events = profiler.Events();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].seq, 0);  // by start time
  EXPECT_EQ(events[1].frame_index, 7);
  EXPECT_EQ(profiler.num_threads(), 1);
}

}  // namespace
}  // namespace pcr::graph
