#include "frictiond/client/mu_sampler.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Core>

#include "frictiond/estimators/stats.h"

namespace frictiond {

namespace {

// Buckets of the O(1) quantile-segment lookup over p in [0, 1).
constexpr int kBuckets = 4096;
// Terms evaluated on the stack; larger models fall back to PredictMu.
constexpr int kMaxStackTerms = 32;

// Phi^-1(u) for u in [0, 1); u = 0 (a draw of 2^-53 odds) is moved to the
// smallest positive double so the AR(1) state never becomes -inf.
double NormalScore(double u) {
  return NormalQuantile(std::max(u, std::numeric_limits<double>::min()));
}

}  // namespace

MuSampler::MuSampler(const StochasticFrictionModel& model) : model_(model) {
  const RegressionModel& m = model_.mu;
  if (m.beta.size() != static_cast<Eigen::Index>(m.terms.size()))
    throw std::invalid_argument(
        "model: mu has " + std::to_string(m.terms.size()) + " terms but " +
        std::to_string(m.beta.size()) + " coefficients");
  // The x of PredictMu: intercept 1, fn_n and v_mm_s given, any other input
  // at its fitted mean (0 when unknown).
  for (const Term& t : m.terms) {
    if (t.kind == TermKind::kIntercept) {
      source_.push_back(Source::kConstant);
      constant_.push_back(1.0);
    } else if (t.input == "fn_n") {
      source_.push_back(t.kind == TermKind::kLinear ? Source::kFnLinear
                                                    : Source::kFn);
      constant_.push_back(0.0);
    } else if (t.input == "v_mm_s") {
      source_.push_back(t.kind == TermKind::kLinear ? Source::kVLinear
                                                    : Source::kV);
      constant_.push_back(0.0);
    } else if (std::string a, b;
               SplitProductName(t.input, &a, &b) &&
               (a == "fn_n" || a == "v_mm_s" || b == "fn_n" || b == "v_mm_s")) {
      // A product column (eps_scale.h) of fn_n or v_mm_s: PredictMu's
      // ResolveInputValue, the other factor at its mean when not fn/v.
      const bool has_fn = a == "fn_n" || b == "fn_n";
      const bool has_v = a == "v_mm_s" || b == "v_mm_s";
      if (has_fn && has_v) {
        source_.push_back(Source::kFnV);
        constant_.push_back(0.0);
      } else {
        const std::string& other = (a == "fn_n" || a == "v_mm_s") ? b : a;
        source_.push_back(has_fn ? Source::kFnTimes : Source::kVTimes);
        constant_.push_back(ResolveInputValue(model_, {}, other));
      }
    } else {
      // Any other input at its fitted mean (a product of two other
      // columns: the product of their means), as PredictMu.
      source_.push_back(Source::kConstant);
      constant_.push_back(t.Eval(ResolveInputValue(model_, {}, t.input)));
    }
  }
  if (model_.eps_scale) {
    const std::string& in = model_.eps_scale->input;
    scale_source_ = in == "fn_n"           ? ScaleSource::kFn
                    : in == "v_mm_s"       ? ScaleSource::kV
                    : SplitProductName(in) ? ScaleSource::kGeneral
                                           : ScaleSource::kConstant;
    scale_constant_ = CalcEpsScaleFactor(model_, {});
  }
  q_lo95_ = frictiond::CalcEpsQuantile(m, 0.025);
  q_hi95_ = frictiond::CalcEpsQuantile(m, 0.975);
  if (const auto it = model_.inputs.find("fn_n"); it != model_.inputs.end()) {
    has_fn_range_ = true;
    fn_min_ = it->second.min;
    fn_max_ = it->second.max;
  }
  if (const auto it = model_.inputs.find("v_mm_s"); it != model_.inputs.end()) {
    has_v_range_ = true;
    v_min_ = it->second.min;
    v_max_ = it->second.max;
  }
  // segment_[b] = index of the first level > b / kBuckets (upper_bound), the
  // starting point of the search for any p in bucket b.
  const auto& levels = EpsQuantileLevels();
  levels_ = levels;
  table_ = m.eps_quantiles.size() == levels.size() && levels.size() < 65535;
  if (table_) {
    segment_.resize(kBuckets);
    for (int b = 0; b < kBuckets; ++b) {
      const double p = static_cast<double>(b) / kBuckets;
      segment_[b] = static_cast<std::uint16_t>(
          std::upper_bound(levels.begin(), levels.end(), p) - levels.begin());
    }
  }
}

bool MuSampler::FillRegressors(double fn_n, double v_mm_s, double* x) const {
  const RegressionModel& m = model_.mu;
  const std::size_t n = m.terms.size();
  if (n > static_cast<std::size_t>(kMaxStackTerms)) return false;
  for (std::size_t k = 0; k < n; ++k) {
    switch (source_[k]) {
      case Source::kFn:
        x[k] = m.terms[k].Eval(fn_n);
        break;
      case Source::kV:
        x[k] = m.terms[k].Eval(v_mm_s);
        break;
      case Source::kFnLinear:  // Term::Eval of kLinear is x itself
        x[k] = fn_n;
        break;
      case Source::kVLinear:
        x[k] = v_mm_s;
        break;
      case Source::kConstant:
        x[k] = constant_[k];
        break;
      case Source::kFnV:
        x[k] = m.terms[k].Eval(fn_n * v_mm_s);
        break;
      case Source::kFnTimes:
        x[k] = m.terms[k].Eval(fn_n * constant_[k]);
        break;
      case Source::kVTimes:
        x[k] = m.terms[k].Eval(v_mm_s * constant_[k]);
        break;
    }
  }
  return true;
}

double MuSampler::CalcMean(double fn_n, double v_mm_s) const {
  const RegressionModel& m = model_.mu;
  // Same arithmetic as PredictMu: beta.dot(x) over an aligned vector, so the
  // result is the same bit for bit.
  alignas(EIGEN_MAX_ALIGN_BYTES) double x[kMaxStackTerms];
  if (!FillRegressors(fn_n, v_mm_s, x))
    return PredictMu(model_, fn_n, v_mm_s).mu;
  const std::size_t n = m.terms.size();
  // Up to 3 terms Eigen's dot adds left to right (one SSE2 packet holds two
  // products, summed, then the third is added; AVX packets of 4 are not
  // used below 4 terms), so the plain sum is the same number, faster.
  if (n <= 3) {
    double sum = n ? m.beta(0) * x[0] : 0.0;
    for (std::size_t k = 1; k < n; ++k) sum += m.beta(k) * x[k];
    return sum;
  }
  const Eigen::Map<const Eigen::VectorXd, Eigen::AlignedMax> xv(
      x, static_cast<Eigen::Index>(n));
  return m.beta.dot(xv);
}

MuPoint MuSampler::CalcPrediction(double fn_n, double v_mm_s) const {
  const RegressionModel& m = model_.mu;
  alignas(EIGEN_MAX_ALIGN_BYTES) double x[kMaxStackTerms];
  alignas(EIGEN_MAX_ALIGN_BYTES) double px[kMaxStackTerms];
  MuPoint out;
  if (!FillRegressors(fn_n, v_mm_s, x)) {
    const MuPrediction p = PredictMu(model_, fn_n, v_mm_s);
    out.mu = p.mu;
    out.sigma = p.sigma;
    out.lo95 = p.lo95;
    out.hi95 = p.hi95;
    out.extrapolated = p.extrapolated;
    return out;
  }
  // PredictMu's arithmetic, step for step (see stochastic_model.cc).
  const auto n = static_cast<Eigen::Index>(m.terms.size());
  const Eigen::Map<const Eigen::VectorXd, Eigen::AlignedMax> xv(x, n);
  out.extrapolated = (has_fn_range_ && (fn_n < fn_min_ || fn_n > fn_max_)) ||
                     (has_v_range_ && (v_mm_s < v_min_ || v_mm_s > v_max_));
  out.mu = m.beta.dot(xv);
  double var_param = 0.0;
  if (m.P_beta.rows() == n && m.P_beta.cols() == n && n <= 3) {
    // Up to 3 terms Eigen's matrix-vector product and dot add left to
    // right (see CalcMean), so plain loops give the same bits, faster.
    double quad = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      double row = m.P_beta(i, 0) * x[0];
      for (Eigen::Index j = 1; j < n; ++j) row += m.P_beta(i, j) * x[j];
      quad = i == 0 ? x[0] * row : quad + x[i] * row;
    }
    var_param = std::max(0.0, quad);
  } else if (m.P_beta.rows() == n) {
    Eigen::Map<Eigen::VectorXd, Eigen::AlignedMax> pxv(px, n);
    pxv.noalias() = m.P_beta * xv;
    var_param = std::max(0.0, xv.dot(pxv));
  }
  if (scale_source_ == ScaleSource::kNone) {
    out.sigma = std::sqrt(m.sigma_eps * m.sigma_eps + var_param);
    const double widen = m.sigma_eps > 0 ? out.sigma / m.sigma_eps : 1.0;
    out.lo95 = out.mu + widen * q_lo95_;
    out.hi95 = out.mu + widen * q_hi95_;
    return out;
  }
  // Heteroscedastic eps: PredictMu's arithmetic with the scale s.
  const double s = CalcEpsScale(fn_n, v_mm_s);
  const double sigma_x = s * m.sigma_eps;
  out.sigma = std::sqrt(sigma_x * sigma_x + var_param);
  const double widen = sigma_x > 0 ? out.sigma / sigma_x : 1.0;
  out.lo95 = out.mu + widen * s * q_lo95_;
  out.hi95 = out.mu + widen * s * q_hi95_;
  return out;
}

double MuSampler::CalcEpsScale(double fn_n, double v_mm_s) const {
  switch (scale_source_) {
    case ScaleSource::kNone:
      return 1.0;
    case ScaleSource::kFn:
      return model_.eps_scale->ScaleFactor(fn_n);
    case ScaleSource::kV:
      return model_.eps_scale->ScaleFactor(v_mm_s);
    case ScaleSource::kConstant:
      return scale_constant_;
    case ScaleSource::kGeneral:
      return CalcEpsScaleFactor(model_, {{"fn_n", fn_n}, {"v_mm_s", v_mm_s}});
  }
  return 1.0;
}

double MuSampler::CalcEpsQuantile(double p) const {
  if (!table_) return frictiond::CalcEpsQuantile(model_.mu, p);
  // The arithmetic of CalcEpsQuantile; only the search is a table lookup.
  const double* levels = levels_.data();
  const double* q = model_.mu.eps_quantiles.data();
  if (!(p > levels[0])) return std::isnan(p) ? p : q[0];
  if (p >= levels_.back()) return q[levels_.size() - 1];
  std::size_t k = segment_[static_cast<int>(p * kBuckets)];
  while (levels[k] <= p) ++k;  // levels.back() > p ends the walk
  const double w = (p - levels[k - 1]) / (levels[k] - levels[k - 1]);
  return q[k - 1] + w * (q[k] - q[k - 1]);
}

bool EpisodeSampleOptions::IsValid(std::string* why) const {
  std::string w;
  if (!(envs > 0)) {
    w = "envs = " + std::to_string(envs) + " (must be > 0)";
  } else if (!(steps > 0)) {
    w = "steps = " + std::to_string(steps) + " (must be > 0)";
  } else if (!(ar1 >= 0 && ar1 <= 1)) {
    w = "ar1 = " + std::to_string(ar1) + " (must be in [0, 1])";
  } else if (!(offset_fraction >= 0 && offset_fraction <= 1)) {
    w = "offset_fraction = " + std::to_string(offset_fraction) +
        " (must be in [0, 1])";
  }
  if (why) *why = w;
  return w.empty();
}

void SampleMuEpisodes(const MuSampler& sampler,
                      StridedInput fn_n,
                      StridedInput v_mm_s,
                      const EpisodeSampleOptions& options,
                      UniformSource uniform,
                      double* out) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  if (!uniform.next || !out || !fn_n.data || !v_mm_s.data)
    throw std::invalid_argument("SampleMuEpisodes: null input or output");
  const int n = options.envs;
  const int t_max = options.steps;
  const double phi = options.ar1;
  const double f = options.offset_fraction;
  const double innovation = std::sqrt(std::max(0.0, 1.0 - phi * phi));
  const double offset_scale = std::sqrt(f);
  const double ar_scale = std::sqrt(std::max(0.0, 1.0 - f));
  for (int env = 0; env < n; ++env) {
    double* row = out + static_cast<std::ptrdiff_t>(env) * t_max;
    if (phi == 0.0 && f == 0.0) {
      for (int t = 0; t < t_max; ++t) {
        row[t] = sampler.Draw(fn_n.at(env, t), v_mm_s.at(env, t), uniform());
      }
      continue;
    }
    // The stationary start (w_0 ~ N(0, 1)) makes every step's marginal the
    // model's eps distribution.
    const double offset = f > 0.0 ? offset_scale * NormalScore(uniform()) : 0.0;
    double w = 0.0;
    for (int t = 0; t < t_max; ++t) {
      if (f < 1.0) {
        if (t == 0) {
          w = NormalScore(uniform());
        } else if (phi < 1.0) {
          w = phi * w + innovation * NormalScore(uniform());
        }
      }
      const double p = NormalCdf(offset + ar_scale * w);
      const double fn = fn_n.at(env, t), v = v_mm_s.at(env, t);
      row[t] = sampler.CalcMean(fn, v) +
               sampler.CalcEpsScale(fn, v) * sampler.CalcEpsQuantile(p);
    }
  }
}

}  // namespace frictiond
