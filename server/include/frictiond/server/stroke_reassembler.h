#pragma once
/// @file
/// Reassembly of test strokes streamed in chunks (the LCM stroke_chunk_v1
/// message, docs/lcm.md), independent of the transport so that it is tested
/// without a network. Chunks may arrive out of order or more than once; a
/// stroke is complete when every seq 0..total-1 is there. Strokes with
/// missing chunks are asked again (resend requests) and dropped with a
/// reason after a deadline. Every chunk is validated field by field before
/// anything of it is kept.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "frictiond/estimators/stroke_data.h"
#include "frictiond/server/request_error.h"

namespace frictiond {

/// One chunk of a stroke, as decoded from the wire (units as in the stroke
/// CSV of CONTRACT.md).
struct StrokeChunk {
  std::int64_t job_id = 0;
  int stroke = 0;        ///< stroke number within the job
  int seq = 0;           ///< 0 .. total_chunks-1
  int total_chunks = 0;  ///< 0: not known yet
  bool last = false;     ///< final chunk (then total = seq + 1)
  std::vector<double> t_s, fn_n, ft_n, v_mm_s;
};

/// Limits of the reassembler.
struct ReassemblerOptions {
  int max_chunks = 4096;                ///< chunks per stroke
  int max_samples_per_chunk = 10000;    ///< samples per chunk
  std::size_t max_samples = 2'000'000;  ///< samples per stroke
  int max_open_strokes = 64;            ///< strokes reassembled at once
  /// Samples held over all open strokes (8e6: 256 MB of samples). The
  /// per-stroke limits alone allowed 64 x 2e6 samples (4 GB); an outside
  /// attack run (unsigned LCM, 70 never-finished strokes) grew the daemon
  /// to 800 MB and rising.
  std::size_t max_total_samples = 8'000'000;
  /// A stroke with chunks missing and no chunk for this long gets a resend
  /// request [s] (and again every resend_after_s).
  double resend_after_s = 0.5;
  /// A stroke still incomplete this long after its newest chunk is dropped
  /// with a reason [s].
  double give_up_after_s = 10.0;

  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// Checks one chunk's fields against the CSV rules (finite numbers,
/// fn_n > 0, ft_n >= 0, v_mm_s >= 0, t_s not decreasing within the chunk)
/// and the limits. @throws RequestError (kInvalidArgument, a
/// std::invalid_argument) whose field() is the field and whose message
/// starts with it ("fn_n[12] = -1 (must be > 0)").
void ValidateStrokeChunk(const StrokeChunk& chunk,
                         const ReassemblerOptions& options);

/// Identifies a stroke under reassembly.
struct StrokeKey {
  std::int64_t job_id = 0;
  int stroke = 0;
  bool operator<(const StrokeKey& o) const {
    return job_id != o.job_id ? job_id < o.job_id : stroke < o.stroke;
  }
};

/// What Add() did with a chunk.
enum class ChunkOutcome {
  kAccepted,   ///< stored; the stroke is still incomplete
  kDuplicate,  ///< identical to a chunk already held: ignored
  kComplete,   ///< stored and the stroke is now complete (call Take())
};

/// Status of a stroke under reassembly.
struct StrokeProgress {
  StrokeKey key;
  int chunks_received = 0;
  int chunks_expected = 0;  ///< 0 while unknown
  std::size_t samples = 0;
  /// Seqs to ask for: the gaps below the total when it is known; else the
  /// gaps below the highest seq received plus the seq after it.
  std::vector<int> missing;
};

/// Something the owner must act on (from Poll()).
struct ReassemblyEvent {
  enum class Kind {
    kResend,  ///< ask the sender again for progress.missing
    kExpired  ///< dropped: `reason` says why
  };
  Kind kind = Kind::kResend;
  StrokeProgress progress;
  std::string reason;
};

/// Reassembles strokes. Time is passed in (seconds on any monotonic clock)
/// so that tests control it. Not thread-safe; copyable and movable.
class StrokeReassembler {
 public:
  explicit StrokeReassembler(ReassemblerOptions options = {});

  /// Validates and stores a chunk.
  /// @throws RequestError naming the field (see
  /// ValidateStrokeChunk; also: total_chunks changed, seq beyond the total,
  /// a resent seq with different samples, too many open strokes or samples,
  /// t_s going backwards across chunks); nothing of the chunk is kept then.
  ChunkOutcome Add(const StrokeChunk& chunk, double now_s);

  /// Progress of a stroke (nullopt when not held).
  std::optional<StrokeProgress> Progress(const StrokeKey& key) const;

  /// Removes a complete stroke and returns its samples in seq order.
  /// @throws std::logic_error when the stroke is not complete;
  /// RequestError naming t_s when a chunk starts before the previous one
  /// ends.
  StrokeData Take(const StrokeKey& key);

  /// Drops a stroke (e.g. its job failed). @return false when not held.
  bool Drop(const StrokeKey& key);

  /// Resend requests and expiries due at `now_s`; expired strokes are
  /// removed.
  std::vector<ReassemblyEvent> Poll(double now_s);

  std::size_t open_strokes() const { return strokes_.size(); }
  /// Samples held over all open strokes.
  std::size_t total_samples() const { return total_samples_; }
  const ReassemblerOptions& options() const { return options_; }

 private:
  struct Partial {
    int total = 0;  // 0: unknown
    std::map<int, StrokeChunk> chunks;
    std::size_t samples = 0;
    double last_chunk_s = 0;
    double last_resend_s = -1;
  };
  static bool IsComplete(const Partial& p);
  static StrokeProgress MakeProgress(const StrokeKey& key, const Partial& p);

  ReassemblerOptions options_;
  std::map<StrokeKey, Partial> strokes_;
  std::size_t total_samples_ = 0;
};

}  // namespace frictiond
