#include "frictiond/storage/job_state.h"

namespace frictiond {

namespace {

constexpr JobState kAllStates[] = {JobState::kRequested,
                                   JobState::kStroking,
                                   JobState::kEnoughCoverage,
                                   JobState::kFitted,
                                   JobState::kFailed};

}  // namespace

const char* JobStateName(JobState state) {
  switch (state) {
    case JobState::kRequested:
      return "requested";
    case JobState::kStroking:
      return "stroking";
    case JobState::kEnoughCoverage:
      return "enough_coverage";
    case JobState::kFitted:
      return "fitted";
    case JobState::kFailed:
      return "failed";
  }
  return "failed";  // not reached: every enumerator is named above
}

std::optional<JobState> ParseJobState(std::string_view text) {
  for (JobState s : kAllStates)
    if (text == JobStateName(s)) return s;
  return std::nullopt;
}

bool IsOpenJobState(std::string_view text) {
  const std::optional<JobState> s = ParseJobState(text);
  return s && IsOpenJobState(*s);
}

const std::string& OpenJobStatesSql() {
  static const std::string sql = [] {
    std::string out = "(";
    for (JobState s : kAllStates) {
      if (!IsOpenJobState(s)) continue;
      if (out.size() > 1) out += ',';
      out += std::string("'") + JobStateName(s) + "'";
    }
    return out + ")";
  }();
  return sql;
}

}  // namespace frictiond
