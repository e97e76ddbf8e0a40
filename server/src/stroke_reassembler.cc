#include "frictiond/server/stroke_reassembler.h"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "frictiond/server/request_error.h"

namespace frictiond {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string Num(double x) {
  std::ostringstream s;
  s.precision(10);
  s << x;
  return s.str();
}

// Every rejection of a chunk: the message starts with the field, and the
// error carries it (a transport reads e.field(), not the text).
[[noreturn]] void Reject(const std::string& field, const std::string& why) {
  throw RequestError(StatusCode::kInvalidArgument, field, field + why);
}

}  // namespace

bool ReassemblerOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (max_chunks < 1)
    return fail("max_chunks = " + std::to_string(max_chunks) +
                " (must be >= 1)");
  if (max_samples_per_chunk < 1)
    return fail("max_samples_per_chunk = " +
                std::to_string(max_samples_per_chunk) + " (must be >= 1)");
  if (max_samples < 1) return fail("max_samples = 0 (must be >= 1)");
  if (max_open_strokes < 1)
    return fail("max_open_strokes = " + std::to_string(max_open_strokes) +
                " (must be >= 1)");
  if (max_total_samples < 1)
    return fail("max_total_samples = 0 (must be >= 1)");
  if (!(resend_after_s > 0))
    return fail("resend_after_s = " + Num(resend_after_s) + " (must be > 0)");
  if (!(give_up_after_s > resend_after_s))
    return fail("give_up_after_s = " + Num(give_up_after_s) +
                " (must be > resend_after_s)");
  return true;
}

void ValidateStrokeChunk(const StrokeChunk& c,
                         const ReassemblerOptions& options) {
  if (!(c.job_id > 0))
    Reject("job_id", " = " + std::to_string(c.job_id) + " (must be > 0)");
  if (c.stroke < 0)
    Reject("stroke", " = " + std::to_string(c.stroke) + " (must be >= 0)");
  if (c.total_chunks < 0 || c.total_chunks > options.max_chunks)
    Reject("total_chunks",
           " = " + std::to_string(c.total_chunks) + " (must be in 0.." +
               std::to_string(options.max_chunks) + ")");
  if (c.seq < 0 || c.seq >= options.max_chunks)
    Reject("seq",
           " = " + std::to_string(c.seq) + " (must be in 0.." +
               std::to_string(options.max_chunks - 1) + ")");
  if (c.total_chunks > 0 && c.seq >= c.total_chunks)
    Reject("seq",
           " = " + std::to_string(c.seq) + " (must be below total_chunks = " +
               std::to_string(c.total_chunks) + ")");
  if (c.last && c.total_chunks > 0 && c.total_chunks != c.seq + 1)
    Reject("total_chunks",
           " = " + std::to_string(c.total_chunks) +
               " (the last chunk has seq " + std::to_string(c.seq) +
               ", so it must be " + std::to_string(c.seq + 1) + ")");
  const std::size_t n = c.t_s.size();
  if (n == 0) Reject("n_samples", " = 0 (must be >= 1)");
  if (n > static_cast<std::size_t>(options.max_samples_per_chunk))
    Reject("n_samples",
           " = " + std::to_string(n) + " (at most " +
               std::to_string(options.max_samples_per_chunk) + " per chunk)");
  auto same_size = [&](const std::vector<double>& x, const char* name) {
    if (x.size() != n)
      Reject(name,
             ": " + std::to_string(x.size()) + " samples (t_s has " +
                 std::to_string(n) + "; all columns must have n_samples)");
  };
  same_size(c.fn_n, "fn_n");
  same_size(c.ft_n, "ft_n");
  same_size(c.v_mm_s, "v_mm_s");
  for (std::size_t i = 0; i < n; ++i) {
    // The one per-sample rule (estimators/stroke_data.h), as the CSV parser.
    if (auto bad = CheckSample(c.t_s[i],
                               c.fn_n[i],
                               c.ft_n[i],
                               c.v_mm_s[i],
                               i > 0 ? c.t_s[i - 1] : -kInf)) {
      Reject(bad->field + "[" + std::to_string(i) + "]",
             " = " + Num(bad->value) + " (" + bad->rule + ")");
    }
  }
}

StrokeReassembler::StrokeReassembler(ReassemblerOptions options)
    : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument(why);
}

bool StrokeReassembler::IsComplete(const Partial& p) {
  return p.total > 0 && static_cast<int>(p.chunks.size()) == p.total;
}

StrokeProgress StrokeReassembler::MakeProgress(const StrokeKey& key,
                                               const Partial& p) {
  StrokeProgress out;
  out.key = key;
  out.chunks_received = static_cast<int>(p.chunks.size());
  out.chunks_expected = p.total;
  out.samples = p.samples;
  // Without a known total, the gaps below the highest seq seen are missing,
  // and so is the chunk after it (the end may have been lost; asking for it
  // one at a time converges on the last chunk).
  const int upto = p.total > 0        ? p.total
                   : p.chunks.empty() ? 0
                                      : p.chunks.rbegin()->first + 2;
  for (int s = 0; s < upto; ++s) {
    if (!p.chunks.count(s)) out.missing.push_back(s);
  }
  return out;
}

ChunkOutcome StrokeReassembler::Add(const StrokeChunk& chunk, double now_s) {
  ValidateStrokeChunk(chunk, options_);
  const StrokeKey key{chunk.job_id, chunk.stroke};
  auto it = strokes_.find(key);
  const int chunk_total = chunk.last ? chunk.seq + 1 : chunk.total_chunks;
  if (it == strokes_.end()) {
    if (static_cast<int>(strokes_.size()) >= options_.max_open_strokes)
      Reject("stroke",
             ": " + std::to_string(strokes_.size()) +
                 " strokes are already being reassembled (at most " +
                 std::to_string(options_.max_open_strokes) + ")");
  } else {
    const Partial& p = it->second;
    if (auto dup = p.chunks.find(chunk.seq); dup != p.chunks.end()) {
      const StrokeChunk& old = dup->second;
      if (old.t_s == chunk.t_s && old.fn_n == chunk.fn_n &&
          old.ft_n == chunk.ft_n && old.v_mm_s == chunk.v_mm_s)
        return ChunkOutcome::kDuplicate;
      Reject("seq",
             " = " + std::to_string(chunk.seq) +
                 " (resent with different samples than the first copy)");
    }
    if (p.total > 0 && chunk_total > 0 && chunk_total != p.total)
      Reject("total_chunks",
             " = " + std::to_string(chunk_total) +
                 " (earlier chunks of this stroke said " +
                 std::to_string(p.total) + ")");
    if (p.total > 0 && chunk.seq >= p.total)
      Reject("seq",
             " = " + std::to_string(chunk.seq) + " (the stroke has " +
                 std::to_string(p.total) + " chunks)");
    if (chunk_total > 0 && !p.chunks.empty() &&
        p.chunks.rbegin()->first >= chunk_total)
      Reject("total_chunks",
             " = " + std::to_string(chunk_total) + " (a chunk with seq " +
                 std::to_string(p.chunks.rbegin()->first) +
                 " was already received)");
    if (p.samples + chunk.t_s.size() > options_.max_samples)
      Reject("n_samples",
             ": the stroke would exceed " +
                 std::to_string(options_.max_samples) + " samples");
  }
  if (total_samples_ + chunk.t_s.size() > options_.max_total_samples)
    Reject("n_samples",
           ": the strokes being reassembled would exceed " +
               std::to_string(options_.max_total_samples) +
               " samples in all (retry when they are complete)");
  Partial& p = strokes_[key];
  if (chunk_total > 0) p.total = chunk_total;
  p.samples += chunk.t_s.size();
  total_samples_ += chunk.t_s.size();
  p.last_chunk_s = now_s;
  p.last_resend_s = -1;
  p.chunks.emplace(chunk.seq, chunk);
  return IsComplete(p) ? ChunkOutcome::kComplete : ChunkOutcome::kAccepted;
}

std::optional<StrokeProgress> StrokeReassembler::Progress(
    const StrokeKey& key) const {
  auto it = strokes_.find(key);
  if (it == strokes_.end()) return std::nullopt;
  return MakeProgress(key, it->second);
}

StrokeData StrokeReassembler::Take(const StrokeKey& key) {
  auto it = strokes_.find(key);
  if (it == strokes_.end() || !IsComplete(it->second))
    throw std::logic_error("StrokeReassembler::Take: stroke not complete");
  Partial p = std::move(it->second);
  strokes_.erase(it);
  total_samples_ -= p.samples;
  StrokeData d;
  d.Reserve(p.samples);
  double last_t = -INFINITY;
  for (const auto& [seq, c] : p.chunks) {
    if (c.t_s.front() < last_t)
      Reject("t_s",
             ": chunk " + std::to_string(seq) + " starts at " +
                 Num(c.t_s.front()) + " s, before the previous chunk ends (" +
                 Num(last_t) + " s)");
    last_t = c.t_s.back();
    d.t_s.insert(d.t_s.end(), c.t_s.begin(), c.t_s.end());
    d.fn_n.insert(d.fn_n.end(), c.fn_n.begin(), c.fn_n.end());
    d.ft_n.insert(d.ft_n.end(), c.ft_n.begin(), c.ft_n.end());
    d.v_mm_s.insert(d.v_mm_s.end(), c.v_mm_s.begin(), c.v_mm_s.end());
  }
  return d;
}

bool StrokeReassembler::Drop(const StrokeKey& key) {
  auto it = strokes_.find(key);
  if (it == strokes_.end()) return false;
  total_samples_ -= it->second.samples;
  strokes_.erase(it);
  return true;
}

std::vector<ReassemblyEvent> StrokeReassembler::Poll(double now_s) {
  std::vector<ReassemblyEvent> events;
  for (auto it = strokes_.begin(); it != strokes_.end();) {
    Partial& p = it->second;
    const double idle_s = now_s - p.last_chunk_s;
    if (idle_s >= options_.give_up_after_s) {
      ReassemblyEvent e;
      e.kind = ReassemblyEvent::Kind::kExpired;
      e.progress = MakeProgress(it->first, p);
      e.reason =
          "stroke incomplete: " + std::to_string(e.progress.chunks_received) +
          " chunk(s) of " +
          (p.total > 0 ? std::to_string(p.total) : "an unknown number") +
          " received, none for " + Num(idle_s) + " s (limit " +
          Num(options_.give_up_after_s) +
          " s); the stroke was dropped, stream it again";
      events.push_back(std::move(e));
      total_samples_ -= p.samples;
      it = strokes_.erase(it);
      continue;
    }
    const bool due = idle_s >= options_.resend_after_s &&
                     (p.last_resend_s < 0 ||
                      now_s - p.last_resend_s >= options_.resend_after_s);
    if (due) {
      ReassemblyEvent e;
      e.kind = ReassemblyEvent::Kind::kResend;
      e.progress = MakeProgress(it->first, p);
      if (p.total == 0) {
        // The end is unknown: ask for what lies after the highest seq too.
        e.reason =
            "missing chunks; the last chunk (last = true) was not "
            "received";
      } else {
        e.reason =
            std::to_string(e.progress.missing.size()) + " chunk(s) missing";
      }
      p.last_resend_s = now_s;
      events.push_back(std::move(e));
    }
    ++it;
  }
  return events;
}

}  // namespace frictiond
