// libFuzzer harness of the stroke reassembler (StrokeReassembler), driven
// by a sequence of operations read from the input: add a chunk (small job,
// stroke and seq numbers so that inputs collide), poll at a later time,
// take a complete stroke. docs/fuzzing.md. Invariants: Add either stores or
// throws std::invalid_argument; open strokes and held samples stay within
// the limits; Take succeeds exactly when Add reported the stroke complete.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

#include <fuzzer/FuzzedDataProvider.h>

#include "frictiond/server/stroke_reassembler.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  FuzzedDataProvider in(data, size);
  frictiond::ReassemblerOptions options;
  options.max_chunks = 16;
  options.max_samples_per_chunk = 32;
  options.max_samples = 256;
  options.max_open_strokes = 4;
  options.resend_after_s = 0.5;
  options.give_up_after_s = 2.0;
  frictiond::StrokeReassembler r(options);
  double now_s = 0;
  for (int op = 0; op < 256 && in.remaining_bytes() > 0; ++op) {
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
      case 0:
      case 1: {
        frictiond::StrokeChunk c;
        c.job_id = in.ConsumeIntegralInRange<std::int64_t>(-1, 3);
        c.stroke = in.ConsumeIntegralInRange<int>(-1, 3);
        c.seq = in.ConsumeIntegralInRange<int>(-2, 20);
        c.total_chunks = in.ConsumeIntegralInRange<int>(-1, 20);
        c.last = in.ConsumeBool();
        const int n = in.ConsumeIntegralInRange<int>(0, 40);
        for (int i = 0; i < n; ++i) {
          c.t_s.push_back(in.ConsumeFloatingPoint<double>());
          c.fn_n.push_back(in.ConsumeFloatingPoint<double>());
          c.ft_n.push_back(in.ConsumeFloatingPoint<double>());
          c.v_mm_s.push_back(in.ConsumeFloatingPoint<double>());
        }
        // Arrays of unequal length, now and then.
        if (in.ConsumeBool() && !c.ft_n.empty()) c.ft_n.pop_back();
        try {
          const frictiond::ChunkOutcome o = r.Add(c, now_s);
          if (o == frictiond::ChunkOutcome::kComplete) {
            const frictiond::StrokeData s = r.Take({c.job_id, c.stroke});
            if (s.size() > options.max_samples || s.empty()) std::abort();
            for (std::size_t i = 1; i < s.size(); ++i)
              if (!(s.t_s[i] >= s.t_s[i - 1])) std::abort();
          }
        } catch (const std::invalid_argument&) {
          // rejected with a reason: nothing kept
        }
        break;
      }
      case 2:
        now_s += in.ConsumeIntegralInRange<int>(0, 3000) / 1000.0;
        for (const frictiond::ReassemblyEvent& e : r.Poll(now_s))
          if (e.kind == frictiond::ReassemblyEvent::Kind::kExpired &&
              e.reason.empty())
            std::abort();
        break;
      default:
        r.Drop({in.ConsumeIntegralInRange<std::int64_t>(-1, 3),
                in.ConsumeIntegralInRange<int>(-1, 3)});
        break;
    }
    if (r.open_strokes() > static_cast<std::size_t>(options.max_open_strokes))
      std::abort();
  }
  return 0;
}
