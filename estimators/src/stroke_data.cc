#include "frictiond/estimators/stroke_data.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace frictiond {

std::optional<SampleViolation> CheckSample(
    double t_s, double fn_n, double ft_n, double v_mm_s, double previous_t_s) {
  if (!std::isfinite(t_s))
    return SampleViolation{"t_s", t_s, "must be finite", ""};
  if (t_s < previous_t_s) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", previous_t_s);
    return SampleViolation{
        "t_s", t_s, std::string("time goes backwards from ") + buf, ""};
  }
  auto broken = [](const char* field, double x, const char* bound) {
    return SampleViolation{field,
                           x,
                           std::string("must be finite and ") + bound,
                           std::isfinite(x) ? bound : ""};
  };
  if (!(fn_n > 0) || !std::isfinite(fn_n)) return broken("fn_n", fn_n, "> 0");
  if (!(ft_n >= 0) || !std::isfinite(ft_n)) return broken("ft_n", ft_n, ">= 0");
  if (!(v_mm_s >= 0) || !std::isfinite(v_mm_s))
    return broken("v_mm_s", v_mm_s, ">= 0");
  return std::nullopt;
}

std::optional<std::size_t> StrokeData::FindCovariate(
    std::string_view name) const {
  for (std::size_t k = 0; k < covariate_names.size(); ++k) {
    if (covariate_names[k] == name) return k;
  }
  return std::nullopt;
}

const std::vector<double>* StrokeData::Column(std::string_view name) const {
  if (name == "t_s") return &t_s;
  if (name == "fn_n") return &fn_n;
  if (name == "ft_n") return &ft_n;
  if (name == "v_mm_s") return &v_mm_s;
  if (auto k = FindCovariate(name)) return &covariates[*k];
  return nullptr;
}

void StrokeData::Reserve(std::size_t n) {
  t_s.reserve(n);
  fn_n.reserve(n);
  ft_n.reserve(n);
  v_mm_s.reserve(n);
}

void StrokeData::Append(const StrokeData& other) {
  const std::size_t n0 = size();
  const std::size_t n1 = other.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // Covariates: union by name.
  for (std::size_t k = 0; k < other.covariate_names.size(); ++k) {
    if (!FindCovariate(other.covariate_names[k])) {
      covariate_names.push_back(other.covariate_names[k]);
      covariates.emplace_back(n0, nan);
    }
  }
  for (std::size_t k = 0; k < covariate_names.size(); ++k) {
    auto& col = covariates[k];
    if (auto j = other.FindCovariate(covariate_names[k])) {
      col.insert(
          col.end(), other.covariates[*j].begin(), other.covariates[*j].end());
    } else {
      col.insert(col.end(), n1, nan);
    }
  }
  // Slip and stroke labels: keep them only if both sides have them (or this is
  // empty).
  if (n0 == 0) {
    slip = other.slip;
    stroke = other.stroke;
  } else {
    if (!slip.empty() && other.slip.size() == n1) {
      slip.insert(slip.end(), other.slip.begin(), other.slip.end());
    } else {
      slip.clear();
    }
    if (!stroke.empty() && other.stroke.size() == n1) {
      const int offset =
          *std::max_element(stroke.begin(), stroke.end()) + 1 -
          (n1 ? *std::min_element(other.stroke.begin(), other.stroke.end())
              : 0);
      for (int s : other.stroke) stroke.push_back(s + offset);
    } else {
      stroke.clear();
    }
  }
  t_s.insert(t_s.end(), other.t_s.begin(), other.t_s.end());
  fn_n.insert(fn_n.end(), other.fn_n.begin(), other.fn_n.end());
  ft_n.insert(ft_n.end(), other.ft_n.begin(), other.ft_n.end());
  v_mm_s.insert(v_mm_s.end(), other.v_mm_s.begin(), other.v_mm_s.end());
}

StrokeData StrokeData::Select(const std::vector<std::size_t>& rows) const {
  StrokeData out;
  out.Reserve(rows.size());
  out.covariate_names = covariate_names;
  out.covariates.resize(covariates.size());
  for (auto& c : out.covariates) c.reserve(rows.size());
  for (std::size_t r : rows) {
    out.t_s.push_back(t_s[r]);
    out.fn_n.push_back(fn_n[r]);
    out.ft_n.push_back(ft_n[r]);
    out.v_mm_s.push_back(v_mm_s[r]);
    if (!slip.empty()) out.slip.push_back(slip[r]);
    if (!stroke.empty()) out.stroke.push_back(stroke[r]);
    for (std::size_t k = 0; k < covariates.size(); ++k)
      out.covariates[k].push_back(covariates[k][r]);
  }
  return out;
}

}  // namespace frictiond
