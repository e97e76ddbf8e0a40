#include "frictiond/estimators/eps_scale.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "frictiond/estimators/stats.h"

namespace frictiond {

double EpsScaleModel::Sigma(double x) const {
  const double xc = std::min(std::max(x, x_min), x_max);
  return std::exp(log_sigma_intercept + log_sigma_slope * xc);
}

double EpsScaleModel::ScaleFactor(double x) const {
  return sigma_ref > 0 ? Sigma(x) / sigma_ref : 1.0;
}

bool EpsScaleModel::IsValid(std::string* why) const {
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (input.empty() || input.size() > 128)
    return fail("eps_scale.input: must be 1 to 128 characters");
  for (char c : input) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '*'))
      return fail("eps_scale.input = '" + input + "' (not a column name)");
  }
  // exp() of the log scale over the clamp range must stay finite.
  auto bounded = [](double v) {
    return std::isfinite(v) && std::fabs(v) < 1e6;
  };
  if (!bounded(log_sigma_intercept) || !bounded(log_sigma_slope))
    return fail(
        "eps_scale: log_sigma_intercept and log_sigma_slope must be "
        "finite and below 1e6 in magnitude");
  if (!(std::isfinite(x_min) && std::isfinite(x_max) && x_min <= x_max))
    return fail("eps_scale: x_min = " + std::to_string(x_min) +
                ", x_max = " + std::to_string(x_max) +
                " (must be finite with x_min <= x_max)");
  if (!(sigma_ref > 0) || !std::isfinite(sigma_ref))
    return fail("eps_scale.sigma_ref = " + std::to_string(sigma_ref) +
                " (must be finite and > 0)");
  for (double x : {x_min, x_max}) {
    const double s = Sigma(x);
    if (!(s > 0) || !std::isfinite(s) || !std::isfinite(s / sigma_ref))
      return fail("eps_scale: sigma_eps at x = " + std::to_string(x) +
                  " is not a finite positive number");
  }
  return true;
}

bool FitEpsScaleModel(const std::vector<double>& r,
                      const std::vector<double>& z,
                      const std::string& input,
                      EpsScaleModel* out) {
  const std::size_t n = std::min(r.size(), z.size());
  if (n < 10) return false;
  double ss = 0.0;
  for (std::size_t i = 0; i < n; ++i) ss += r[i] * r[i];
  const double sigma0 = std::sqrt(ss / n);
  if (!(sigma0 > 0)) return false;
  EpsScaleModel f;
  f.input = input;
  f.sigma_ref = sigma0;
  const double floor = 1e-3 * sigma0;
  std::vector<double> zs(z.begin(), z.begin() + n);
  std::sort(zs.begin(), zs.end());
  f.x_min = SortedQuantile(zs, 0.01);
  f.x_max = SortedQuantile(zs, 0.99);
  if (!(f.x_max > f.x_min)) return false;
  auto clamp = [&f](double x) {
    return std::min(std::max(x, f.x_min), f.x_max);
  };
  double mz = 0, ml = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mz += clamp(z[i]);
    ml += std::log(std::max(std::fabs(r[i]), floor));
  }
  mz /= n, ml /= n;
  double szz = 0, szl = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dz = clamp(z[i]) - mz;
    szz += dz * dz;
    szl += dz * (std::log(std::max(std::fabs(r[i]), floor)) - ml);
  }
  if (!(szz > 0)) return false;
  f.log_sigma_slope = szl / szz;
  f.log_sigma_intercept = ml - f.log_sigma_slope * mz;
  double c = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = f.Sigma(z[i]);
    c += r[i] * r[i] / (s * s);
  }
  f.log_sigma_intercept += 0.5 * std::log(std::max(1e-300, c / n));
  if (!std::isfinite(f.log_sigma_intercept) ||
      !std::isfinite(f.log_sigma_slope))
    return false;
  *out = std::move(f);
  return true;
}

bool SplitProductName(std::string_view name, std::string* x, std::string* y) {
  const std::size_t star = name.find('*');
  if (star == std::string_view::npos || star == 0 || star + 1 >= name.size() ||
      name.find('*', star + 1) != std::string_view::npos)
    return false;
  if (x) *x = std::string(name.substr(0, star));
  if (y) *y = std::string(name.substr(star + 1));
  return true;
}

bool CanComputeColumn(const StrokeData& data, std::string_view name) {
  if (data.Column(name)) return true;
  std::string x, y;
  return SplitProductName(name, &x, &y) && data.Column(x) && data.Column(y);
}

bool AddComputedColumn(StrokeData* data, const std::string& name) {
  if (data->Column(name)) return true;
  std::string x, y;
  if (!SplitProductName(name, &x, &y)) return false;
  const std::vector<double>* cx = data->Column(x);
  const std::vector<double>* cy = data->Column(y);
  if (!cx || !cy) return false;
  std::vector<double> p(data->size());
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = (*cx)[i] * (*cy)[i];
  data->covariate_names.push_back(name);
  data->covariates.push_back(std::move(p));
  return true;
}

}  // namespace frictiond
