#pragma once
/// @file
/// Stroke samples as the contract's CSV defines them (CONTRACT.md, "Stroke
/// data"): time, normal force, tangential force, sliding speed, optional slip
/// label and stroke id, and any number of extra numeric covariate columns.
/// Column-major so that a million-sample upload is a handful of allocations.

#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace frictiond {

/// Samples of one or more strokes, column-major. All required columns have
/// size() entries; `slip` and `stroke` are either empty (absent in the input,
/// derive them with LabelSlip / SegmentStrokes) or size() long.
///
/// Copyable and movable (plain value type).
struct StrokeData {
  std::vector<double> t_s;     ///< sample time [s], non-decreasing
  std::vector<double> fn_n;    ///< normal force [N], > 0
  std::vector<double> ft_n;    ///< tangential force magnitude [N], >= 0
  std::vector<double> v_mm_s;  ///< sliding speed [mm/s], >= 0
  std::vector<int> slip;       ///< 0/1 slip label, empty when not given
  std::vector<int> stroke;     ///< stroke id, empty when not given

  /// Extra numeric columns (covariates), by name, in input order.
  std::vector<std::string> covariate_names;
  /// covariates[k][i] is covariate k at sample i.
  std::vector<std::vector<double>> covariates;

  /// Number of samples.
  std::size_t size() const { return t_s.size(); }
  bool empty() const { return t_s.empty(); }

  /// mu = Ft/Fn at sample i (dimensionless).
  double mu(std::size_t i) const { return ft_n[i] / fn_n[i]; }

  /// Index of covariate `name`, or nullopt.
  std::optional<std::size_t> FindCovariate(std::string_view name) const;

  /// Column by name: one of the required columns, `slip`/`stroke` (as
  /// doubles, if present), a covariate, or nullptr when unknown. The pointer
  /// is valid until the data is modified. `slip` and `stroke` are not
  /// returned (they are int columns); use the members.
  const std::vector<double>* Column(std::string_view name) const;

  /// Appends all samples of `other`. Covariates are matched by name; a
  /// covariate missing on one side is filled with NaN. Stroke ids of `other`
  /// are offset so they stay distinct.
  void Append(const StrokeData& other);

  /// Returns the samples whose index is in `rows` (ascending or not).
  StrokeData Select(const std::vector<std::size_t>& rows) const;

  /// Reserves capacity for n samples in every column.
  void Reserve(std::size_t n);
};

/// A broken per-sample rule (CheckSample): the field, its value and the
/// rule, so a caller can write "fn_n = -1 (must be finite and > 0)" with
/// its own location (CSV line, LCM sample index).
struct SampleViolation {
  std::string field;  ///< "t_s", "fn_n", "ft_n" or "v_mm_s"
  double value = 0.0;
  /// "must be finite", "must be finite and > 0", "must be finite and >= 0",
  /// or "time goes backwards from <previous t_s>".
  std::string rule;
  /// The bound alone ("> 0", ">= 0") when a finite value broke it, else
  /// empty: for callers that reject non-finite text before (the CSV
  /// parser words it "fn_n = 0 (must be > 0)").
  std::string bound;
};

/// The one per-sample validity rule of the contract (CONTRACT.md, "Stroke
/// data"), used by the CSV parser and the LCM stroke reassembler: t_s
/// finite and not below previous_t_s; fn_n finite and > 0; ft_n and v_mm_s
/// finite and >= 0. Checked in that order; the first broken rule is
/// returned, nullopt when the sample is valid. previous_t_s is the time of
/// the sample before (-inf for the first).
std::optional<SampleViolation> CheckSample(
    double t_s,
    double fn_n,
    double ft_n,
    double v_mm_s,
    double previous_t_s = -std::numeric_limits<double>::infinity());

}  // namespace frictiond
