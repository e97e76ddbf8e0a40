#include "frictiond/server/stroke_reassembler.h"

#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

// A chunk of `n` samples starting at time seq * n * 0.01 s, with values that
// identify the chunk (fn_n = 1 + seq).
StrokeChunk MakeChunk(int seq, int total, bool last = false, int n = 5) {
  StrokeChunk c;
  c.job_id = 7;
  c.stroke = 0;
  c.seq = seq;
  c.total_chunks = total;
  c.last = last;
  for (int i = 0; i < n; ++i) {
    c.t_s.push_back((seq * n + i) * 0.01);
    c.fn_n.push_back(1.0 + seq);
    c.ft_n.push_back(0.5);
    c.v_mm_s.push_back(10.0);
  }
  return c;
}

std::string RejectMessage(const StrokeChunk& c) {
  try {
    ValidateStrokeChunk(c, ReassemblerOptions{});
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(StrokeReassembler, OutOfOrderAndDuplicatesReassembleInSeqOrder) {
  StrokeReassembler r;
  EXPECT_EQ(r.Add(MakeChunk(2, 4), 0.0), ChunkOutcome::kAccepted);
  EXPECT_EQ(r.Add(MakeChunk(0, 4), 0.1), ChunkOutcome::kAccepted);
  EXPECT_EQ(r.Add(MakeChunk(2, 4), 0.2), ChunkOutcome::kDuplicate);
  EXPECT_EQ(r.Add(MakeChunk(3, 0, /*last=*/true), 0.3),
            ChunkOutcome::kAccepted);
  const auto p = r.Progress({7, 0});
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->chunks_received, 3);
  EXPECT_EQ(p->chunks_expected, 4);
  ASSERT_EQ(p->missing.size(), 1u);
  EXPECT_EQ(p->missing[0], 1);
  EXPECT_EQ(r.Add(MakeChunk(1, 0), 0.4), ChunkOutcome::kComplete);
  const StrokeData d = r.Take({7, 0});
  ASSERT_EQ(d.size(), 20u);
  for (std::size_t i = 0; i < d.size(); ++i) {
    EXPECT_DOUBLE_EQ(d.t_s[i], i * 0.01) << i;
    EXPECT_DOUBLE_EQ(d.fn_n[i], 1.0 + static_cast<double>(i / 5)) << i;
  }
  EXPECT_EQ(r.open_strokes(), 0u);
}

TEST(StrokeReassembler, ConflictingResendAndTotalsAreRejected) {
  StrokeReassembler r;
  r.Add(MakeChunk(0, 3), 0.0);
  StrokeChunk changed = MakeChunk(0, 3);
  changed.ft_n[2] = 0.7;
  EXPECT_THROW(
      {
        try {
          r.Add(changed, 0.1);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("seq = 0"), std::string::npos)
              << e.what();
          throw;
        }
      },
      std::invalid_argument);
  EXPECT_THROW(r.Add(MakeChunk(1, 5), 0.1), std::invalid_argument);
  EXPECT_THROW(r.Add(MakeChunk(1, 0, /*last=*/true), 0.1),
               std::invalid_argument);  // says total 2, earlier 3
  // Nothing of the rejected chunks was kept.
  EXPECT_EQ(r.Progress({7, 0})->chunks_received, 1);
}

TEST(StrokeReassembler, AsksAgainThenGivesUp) {
  ReassemblerOptions o;
  o.resend_after_s = 0.5;
  o.give_up_after_s = 2.0;
  StrokeReassembler r(o);
  r.Add(MakeChunk(0, 3), 0.0);
  r.Add(MakeChunk(2, 3), 0.0);
  EXPECT_TRUE(r.Poll(0.2).empty());
  auto events = r.Poll(0.6);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, ReassemblyEvent::Kind::kResend);
  ASSERT_EQ(events[0].progress.missing.size(), 1u);
  EXPECT_EQ(events[0].progress.missing[0], 1);
  EXPECT_TRUE(r.Poll(0.8).empty());   // not again before resend_after_s
  EXPECT_EQ(r.Poll(1.2).size(), 1u);  // asked again
  events = r.Poll(2.5);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, ReassemblyEvent::Kind::kExpired);
  EXPECT_NE(events[0].reason.find("dropped"), std::string::npos);
  EXPECT_EQ(r.open_strokes(), 0u);
}

// The samples held over all open strokes are bounded: a chunk beyond the
// total is rejected (nothing kept), and Take, Drop and expiry give the room
// back.
TEST(StrokeReassembler, TotalSamplesAreBoundedAcrossStrokes) {
  ReassemblerOptions o;
  o.max_total_samples = 12;
  o.give_up_after_s = 2.0;
  StrokeReassembler r(o);
  auto chunk = [](int stroke, int seq, int total, bool last = false) {
    StrokeChunk c = MakeChunk(seq, total, last, /*n=*/5);
    c.stroke = stroke;
    return c;
  };
  r.Add(chunk(0, 0, 2), 0.0);
  r.Add(chunk(1, 0, 2), 0.0);
  EXPECT_EQ(r.total_samples(), 10u);
  try {
    r.Add(chunk(2, 0, 2), 0.0);
    ADD_FAILURE() << "accepted beyond the total";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("n_samples"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(r.open_strokes(), 2u);
  EXPECT_EQ(r.total_samples(), 10u);
  EXPECT_TRUE(r.Drop({7, 1}));
  EXPECT_EQ(r.total_samples(), 5u);
  EXPECT_EQ(r.Add(chunk(0, 1, 2, /*last=*/true), 0.1), ChunkOutcome::kComplete);
  EXPECT_EQ(r.total_samples(), 10u);
  EXPECT_EQ(r.Take({7, 0}).size(), 10u);
  EXPECT_EQ(r.total_samples(), 0u);
  r.Add(chunk(3, 0, 2), 1.0);
  r.Poll(5.0);  // expired
  EXPECT_EQ(r.open_strokes(), 0u);
  EXPECT_EQ(r.total_samples(), 0u);
}

TEST(StrokeReassembler, UnknownEndIsReportedAsMissing) {
  StrokeReassembler r;
  r.Add(MakeChunk(0, 0), 0.0);
  r.Add(MakeChunk(3, 0), 0.0);
  const auto p = r.Progress({7, 0});
  EXPECT_EQ(p->chunks_expected, 0);
  // The gaps, and the chunk after the highest seq (the end is unknown).
  EXPECT_EQ(p->missing, (std::vector<int>{1, 2, 4}));
  EXPECT_THROW(r.Take({7, 0}), std::logic_error);
}

TEST(StrokeReassembler, TimeGoingBackwardsAcrossChunksIsRejected) {
  StrokeReassembler r;
  StrokeChunk a = MakeChunk(0, 2);
  StrokeChunk b = MakeChunk(1, 2);
  for (double& t : b.t_s) t -= 0.03;  // overlaps chunk 0
  r.Add(a, 0);
  ASSERT_EQ(r.Add(b, 0), ChunkOutcome::kComplete);
  EXPECT_THROW(r.Take({7, 0}), std::invalid_argument);
}

// Every rejection carries its field as data (what the LCM endpoint sends in
// error_v1), equal to the start of its message.
TEST(StrokeReassembler, RejectionsCarryTheirField) {
  auto field_of = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const RequestError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(e.field(), 0), 0u) << e.what();
      EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
      return e.field();
    }
    return "(no error)";
  };
  StrokeChunk bad = MakeChunk(0, 2);
  bad.fn_n[3] = -1;
  EXPECT_EQ(field_of([&] { ValidateStrokeChunk(bad, ReassemblerOptions{}); }),
            "fn_n[3]");
  StrokeReassembler r;
  r.Add(MakeChunk(0, 3), 0.0);
  StrokeChunk changed = MakeChunk(0, 3);
  changed.ft_n[2] = 0.7;
  EXPECT_EQ(field_of([&] { r.Add(changed, 0.1); }), "seq");
  EXPECT_EQ(field_of([&] { r.Add(MakeChunk(1, 0, /*last=*/true), 0.1); }),
            "total_chunks");
  ReassemblerOptions small;
  small.max_samples = 12;
  StrokeReassembler s(small);
  s.Add(MakeChunk(0, 3), 0.0);
  s.Add(MakeChunk(1, 3), 0.0);
  EXPECT_EQ(field_of([&] { s.Add(MakeChunk(2, 3), 0.0); }), "n_samples");
  StrokeReassembler t;
  StrokeChunk b = MakeChunk(1, 2);
  for (double& x : b.t_s) x -= 0.03;
  t.Add(MakeChunk(0, 2), 0);
  t.Add(b, 0);
  EXPECT_EQ(field_of([&] { t.Take({7, 0}); }), "t_s");
}

TEST(ValidateStrokeChunk, NamesTheBadField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  StrokeChunk c = MakeChunk(0, 2);
  EXPECT_EQ(RejectMessage(c), "");
  c.fn_n[3] = -1;
  EXPECT_EQ(RejectMessage(c), "fn_n[3] = -1 (must be finite and > 0)");
  c = MakeChunk(0, 2);
  c.fn_n[1] = nan;
  EXPECT_EQ(RejectMessage(c).rfind("fn_n[1] = nan", 0), 0u) << RejectMessage(c);
  c = MakeChunk(0, 2);
  c.v_mm_s[0] = -3;
  EXPECT_EQ(RejectMessage(c).rfind("v_mm_s[0]", 0), 0u);
  c = MakeChunk(0, 2);
  c.ft_n[4] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(RejectMessage(c).rfind("ft_n[4]", 0), 0u);
  c = MakeChunk(0, 2);
  c.t_s[2] = 0.0;
  EXPECT_EQ(RejectMessage(c).rfind("t_s[2]", 0), 0u);
  c = MakeChunk(0, 2);
  c.ft_n.pop_back();
  EXPECT_EQ(RejectMessage(c).rfind("ft_n: 4 samples", 0), 0u);
  c = MakeChunk(2, 2);
  EXPECT_EQ(RejectMessage(c).rfind("seq = 2", 0), 0u);
  c = MakeChunk(0, 2);
  c.job_id = 0;
  EXPECT_EQ(RejectMessage(c).rfind("job_id", 0), 0u);
  c = MakeChunk(0, 2, false, 0);
  EXPECT_EQ(RejectMessage(c).rfind("n_samples = 0", 0), 0u);
  c = MakeChunk(1, 3, /*last=*/true);
  EXPECT_EQ(RejectMessage(c).rfind("total_chunks = 3", 0), 0u);
}

}  // namespace
}  // namespace frictiond
