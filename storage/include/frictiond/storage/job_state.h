#pragma once
/// @file
/// The life cycle of an identification job (IdentificationJob::state) as an
/// enum, with the one spelling of each state that the store keeps and the
/// transports show (CONTRACT.md, docs/lcm.md: "requested", "stroking",
/// "enough_coverage", "fitted", "failed"). Every other file converts through
/// JobStateName / ParseJobState; no state is written out as a literal.
///
///   requested -> stroking -> (stroking: follow-up)* -> enough_coverage
///             -> fitted | failed
/// and any open state -> fitted when an upload of the pair commits
/// (Store::CommitUpload), or -> failed.
/// The server's IdentificationJobs (server/identification_jobs.h) is the
/// only class that changes a job's state.

#include <optional>
#include <string>
#include <string_view>

namespace frictiond {

/// State of an identification job.
enum class JobState {
  kRequested,       ///< recorded; waiting for a test stroke
  kStroking,        ///< strokes are arriving (or a follow-up was asked for)
  kEnoughCoverage,  ///< the strokes cover the span; the fit is running
  kFitted,          ///< closed: a model version was made
  kFailed,          ///< closed: `detail` says why
};

/// The stored text of a state ("requested", ...).
const char* JobStateName(JobState state);

/// The state a stored text names; nullopt for any other text.
std::optional<JobState> ParseJobState(std::string_view text);

/// True for requested, stroking and enough_coverage (the job still takes
/// strokes or is being fitted); false for fitted and failed.
constexpr bool IsOpenJobState(JobState state) {
  return state != JobState::kFitted && state != JobState::kFailed;
}

/// True when `text` names an open state (unknown texts are not open).
bool IsOpenJobState(std::string_view text);

/// The open states as an SQL list: ('requested','stroking','enough_coverage').
const std::string& OpenJobStatesSql();

}  // namespace frictiond
