// libFuzzer harness of the stroke CSV parser (ParseStrokeCsv), docs/fuzzing.md.
// Any input must either parse or throw StrokeCsvError; what parses must
// satisfy the documented rules and round-trip through FormatStrokeCsv.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "frictiond/estimators/stroke_csv.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  frictiond::StrokeCsvOptions options;
  options.max_samples = 20000;  // bounded memory per input
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  frictiond::StrokeData parsed;
  try {
    parsed = frictiond::ParseStrokeCsv(text, options);
  } catch (const frictiond::StrokeCsvError&) {
    return 0;  // rejected with a message: fine
  }
  if (parsed.size() > options.max_samples) std::abort();
  for (std::size_t i = 0; i < parsed.size(); ++i) {
    if (!(parsed.fn_n[i] > 0) || !(parsed.ft_n[i] >= 0) ||
        !(parsed.v_mm_s[i] >= 0))
      std::abort();
    if (i > 0 && parsed.t_s[i] < parsed.t_s[i - 1]) std::abort();
  }
  // What parsed is written back and parses again to the same samples.
  const frictiond::StrokeData again =
      frictiond::ParseStrokeCsv(frictiond::FormatStrokeCsv(parsed), options);
  if (again.size() != parsed.size()) std::abort();
  for (std::size_t i = 0; i < parsed.size(); ++i)
    if (again.t_s[i] != parsed.t_s[i] || again.fn_n[i] != parsed.fn_n[i])
      std::abort();
  return 0;
}
