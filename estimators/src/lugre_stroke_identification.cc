// LuGre identification from a material's recorded strokes (paper 001,
// Section III; docs/lugre.md, "Service"): the stroke recognition rule and
// the two-step fit the daemon runs on every upload. The rule is documented
// at RecognizeLuGreStrokes and IdentifyLuGreFromStrokes
// (lugre_identification.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>

#include "frictiond/estimators/identification_memo.h"
#include "frictiond/estimators/lugre_identification.h"
#include "frictiond/estimators/number_text.h"
#include "frictiond/estimators/preprocessing.h"

namespace frictiond {

namespace {

constexpr double kQuasiStaticMaxAccel = 3.0;  // [mm/s^2], paper 001 Step 1
constexpr double kDynamicMinAccel = 5.0;      // [mm/s^2], paper 001 Step 2
constexpr double kAccelPercentile = 0.95;     // of |dv/dt| over moving samples
constexpr double kAccelHalfWindowS = 0.05;    // slope window half width [s]
constexpr double kSpeedFilterS = 0.05;        // median filter for rest [s]
constexpr double kRestFraction = 0.05;        // rest: speed <= this * peak
constexpr double kMinRestS = 0.25;            // a rest this long splits
constexpr double kPadS = 0.1;                 // rest kept around a stroke [s]
constexpr double kGapFactor = 10.0;           // time gap in median steps
constexpr double kFlipBeforeS = 0.2;          // force-reversal search window
constexpr double kFlipAfterS = 1.0;
constexpr int kMinMovingSamples = 20;
constexpr int kMaxDynamicStrokes = 4;    // accepted Step-2 fits combined
constexpr int kMaxDynamicAttempts = 12;  // newest dynamic strokes tried
constexpr double kMaxRmsRatio = 3.0;     // Step-2 RMS <= this * Step-1 RMS
constexpr Eigen::Index kMaxDynamicSamples = 5000;  // per Step-2 stroke
constexpr std::size_t kMaxStep2Samples = 40000;    // over all tried strokes
constexpr std::size_t kMaxQuasiStaticSamples = 1000000;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Step 1's premise (paper 001 eq. 4: dz/dt ~ 0 on the low-acceleration
// stroke) holds when the quasi-static fit explains that stroke to the noise:
// residual RMS <= this * the noise estimated from second differences.
constexpr double kQuasiStaticNoiseRatio = 2.0;
// LM-6 fallback (eq. 15 substituted into eqs. 11-12) accepted when its RMS
// is <= this * noise and the Stribeck parameters it frees are pinned down:
// std(mu_s)/mu_s, std(mu_c)/mu_c <= kMaxLm6RelStd, std(v0)/v0 and
// std(sigma1)/sigma1 <= 2x that (sigma1 damps the stick-phase oscillation
// at break-away: an LM-6 sigma1 near 0 doubled the predicted BF-ratio).
constexpr double kLm6NoiseRatio = 2.0;
constexpr double kMaxLm6RelStd = 0.1;
constexpr double kMinNoiseMu = 1e-4;  // floor of the noise estimate

double Sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

// Least-squares slope of v over t within +-half_window (at least +-2
// samples) at every sample, by prefix sums (O(n)).
std::vector<double> CalcSlopes(const std::vector<double>& t,
                               const std::vector<double>& v,
                               double half_window) {
  const std::size_t n = t.size();
  std::vector<double> st(n + 1, 0.0), sv(n + 1, 0.0), stt(n + 1, 0.0),
      stv(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = t[i] - t[0];
    st[i + 1] = st[i] + x;
    sv[i + 1] = sv[i] + v[i];
    stt[i + 1] = stt[i] + x * x;
    stv[i + 1] = stv[i] + x * v[i];
  }
  std::vector<double> slope(n, 0.0);
  std::size_t lo = 0, hi = 0;
  for (std::size_t i = 0; i < n; ++i) {
    while (lo < i && t[i] - t[lo] > half_window) ++lo;
    if (hi < i) hi = i;
    while (hi + 1 < n && t[hi + 1] - t[i] <= half_window) ++hi;
    const std::size_t a = std::min(lo, i >= 2 ? i - 2 : 0);
    const std::size_t b = std::max(hi, std::min(n - 1, i + 2));
    const double m = static_cast<double>(b - a + 1);
    const double s_t = st[b + 1] - st[a], s_v = sv[b + 1] - sv[a];
    const double s_tt = stt[b + 1] - stt[a], s_tv = stv[b + 1] - stv[a];
    const double den = m * s_tt - s_t * s_t;
    slope[i] = den > 0 ? (m * s_tv - s_t * s_v) / den : 0.0;
  }
  return slope;
}

// Signed v and mu of samples [b, e) (rule step 1). `dir` is the dir_sign
// column or null; `moving` flags samples above the rest threshold.
void SignRun(const StrokeData& d,
             std::size_t b,
             std::size_t e,
             const std::vector<double>* dir,
             const std::vector<bool>& moving,
             std::vector<double>* v,
             std::vector<double>* mu) {
  const std::size_t n = e - b;
  v->resize(n);
  mu->resize(n);
  bool use_dir = dir != nullptr;
  if (use_dir) {
    bool any = false;
    for (std::size_t i = b; i < e; ++i) {
      if (!std::isfinite((*dir)[i])) use_dir = false;
      if ((*dir)[i] != 0) any = true;
    }
    use_dir = use_dir && any;
  }
  if (!use_dir) {
    for (std::size_t i = 0; i < n; ++i) {
      (*v)[i] = d.v_mm_s[b + i];
      (*mu)[i] = d.mu(b + i);
    }
    return;
  }
  // Motion direction changes -> force flips at the |mu| minimum nearby.
  std::vector<double> mu_run(n);  // each sample's Ft/Fn, divided once
  for (std::size_t i = 0; i < n; ++i) mu_run[i] = d.mu(b + i);
  std::vector<std::pair<std::size_t, double>> flips;  // (index, new sign)
  double motion = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = Sign((*dir)[b + i]);
    (*v)[i] = s * d.v_mm_s[b + i];
    if (!moving[i] || s == 0 || s == motion) continue;
    if (motion == 0) {
      flips.emplace_back(0, s);
    } else {
      // The reversal began where the run of the new sign ending at i began
      // (the speed may take a while to leave the rest band).
      std::size_t r = i;
      while (r > 0 && Sign((*dir)[b + r - 1]) == s) --r;
      std::size_t lo = r, hi = i, best = i;
      while (lo > 0 && d.t_s[b + r] - d.t_s[b + lo - 1] <= kFlipBeforeS) --lo;
      while (hi + 1 < n && d.t_s[b + hi + 1] - d.t_s[b + i] <= kFlipAfterS)
        ++hi;
      for (std::size_t j = lo; j <= hi; ++j)
        if (mu_run[j] < mu_run[best]) best = j;
      flips.emplace_back(best, s);
    }
    motion = s;
  }
  std::size_t f = 0;
  double force = flips.empty() ? 1.0 : flips[0].second;
  for (std::size_t i = 0; i < n; ++i) {
    while (f < flips.size() && flips[f].first <= i) force = flips[f++].second;
    (*mu)[i] = force * mu_run[i];
  }
}

// Rule steps 3-5 on one run [b, e) (step 2's cut), appended to `out`.
void RecognizeRun(const StrokeData& d,
                  std::size_t b,
                  std::size_t e,
                  double dt_med,
                  const std::vector<double>* dir,
                  std::vector<RecognizedStroke>* out_strokes) {
  std::vector<RecognizedStroke>& out = *out_strokes;
  const std::size_t m = e - b;
  if (m >= static_cast<std::size_t>(kMinMovingSamples)) {
    const std::vector<double> t(d.t_s.begin() + b, d.t_s.begin() + e);
    const std::vector<double> speed(d.v_mm_s.begin() + b, d.v_mm_s.begin() + e);
    int kernel = static_cast<int>(std::lround(kSpeedFilterS / dt_med));
    kernel = std::clamp(kernel | 1, 1, 51);
    const std::vector<double> filtered = MedianFilter(speed, kernel);
    const double peak = *std::max_element(filtered.begin(), filtered.end());
    if (peak > 0) {
      const double threshold = kRestFraction * peak;
      std::vector<bool> moving(m);
      for (std::size_t i = 0; i < m; ++i) moving[i] = filtered[i] > threshold;
      std::vector<double> v, mu;
      SignRun(d, b, e, dir, moving, &v, &mu);
      // Long rests split strokes: mark samples inside them.
      std::vector<bool> long_rest(m, false);
      for (std::size_t i = 0; i < m;) {
        if (moving[i]) {
          ++i;
          continue;
        }
        std::size_t j = i;
        while (j + 1 < m && !moving[j + 1]) ++j;
        if (t[j] - t[i] >= kMinRestS || i == 0 || j + 1 == m)
          std::fill(long_rest.begin() + i, long_rest.begin() + j + 1, true);
        i = j + 1;
      }
      for (std::size_t i = 0; i < m;) {
        if (long_rest[i]) {
          ++i;
          continue;
        }
        std::size_t j = i;
        while (j + 1 < m && !long_rest[j + 1]) ++j;
        // Stroke: moving samples [i, j] plus kPadS of rest either side.
        std::size_t lo = i, hi = j;
        while (lo > 0 && t[i] - t[lo - 1] <= kPadS) --lo;
        while (hi + 1 < m && t[hi + 1] - t[j] <= kPadS) ++hi;
        RecognizedStroke s;
        s.t_s.assign(t.begin() + lo, t.begin() + hi + 1);
        s.v_mm_s.assign(v.begin() + lo, v.begin() + hi + 1);
        s.mu.assign(mu.begin() + lo, mu.begin() + hi + 1);
        double fn_sum = 0;
        for (std::size_t k = lo; k <= hi; ++k) fn_sum += d.fn_n[b + k];
        s.fn_mean_n = fn_sum / static_cast<double>(hi - lo + 1);
        const std::vector<double> slope =
            CalcSlopes(s.t_s, s.v_mm_s, kAccelHalfWindowS);
        std::vector<double> accel;
        for (std::size_t k = i; k <= j; ++k)
          if (moving[k]) accel.push_back(std::abs(slope[k - lo]));
        s.moving = static_cast<int>(accel.size());
        if (s.moving >= kMinMovingSamples) {
          const auto q = static_cast<std::size_t>(
              kAccelPercentile * static_cast<double>(accel.size() - 1));
          std::nth_element(accel.begin(), accel.begin() + q, accel.end());
          s.accel_mm_s2 = accel[q];
          s.kind = s.accel_mm_s2 <= kQuasiStaticMaxAccel
                       ? LuGreStrokeKind::kQuasiStatic
                       : (s.accel_mm_s2 >= kDynamicMinAccel
                              ? LuGreStrokeKind::kDynamic
                              : LuGreStrokeKind::kIntermediate);
        }
        out.push_back(std::move(s));
        i = j + 1;
      }
    }
  }
}

// Rule steps 2-5: the recognised strokes of the pair, oldest first. With a
// memo, a run seen by the previous call (same samples, same median step)
// is looked up (identification_memo.h); `keep` holds the runs' strokes.
std::vector<const RecognizedStroke*> Recognize(
    const StrokeData& d,
    IdentificationMemo* memo,
    std::vector<std::shared_ptr<const std::vector<RecognizedStroke>>>* keep) {
  std::vector<const RecognizedStroke*> out;
  const std::size_t n = d.size();
  if (n < 2) return out;
  const double dt_med = CalcMedianDt(d.t_s);
  if (!(dt_med > 0)) return out;
  const std::vector<double>* dir = nullptr;
  if (auto k = d.FindCovariate("dir_sign")) dir = &d.covariates[*k];
  std::size_t b = 0;
  while (b < n) {
    std::size_t e = b + 1;
    while (e < n && d.t_s[e] >= d.t_s[e - 1] &&
           d.t_s[e] - d.t_s[e - 1] <= kGapFactor * dt_med)
      ++e;
    std::shared_ptr<const std::vector<RecognizedStroke>> run = Memoized(
        memo ? &memo->lugre_runs : nullptr,
        e - b,
        [&] {
          // Everything RecognizeRun reads: the run's columns, the median
          // step and whether the direction column exists.
          MemoKeyBuilder h(0x4c7547726552756eULL);  // "LuGreRun"
          h.Add(dt_med).Add(static_cast<std::uint64_t>(dir != nullptr));
          h.Add(d.t_s, b, e).Add(d.v_mm_s, b, e).Add(d.fn_n, b, e);
          h.Add(d.ft_n, b, e);
          if (dir) h.Add(*dir, b, e);
          return h.Key();
        },
        [&] {
          std::vector<RecognizedStroke> strokes;
          RecognizeRun(d, b, e, dt_med, dir, &strokes);
          return strokes;
        });
    for (const RecognizedStroke& s : *run) out.push_back(&s);
    keep->push_back(std::move(run));
    b = e;
  }
  return out;
}

// Appends a segment to a LuGreStroke-to-be, dropping repeated times and
// shifting time so it follows the previous content (for Step 1, where only
// the speed-ratio pairs matter).
void AppendRecognizedStroke(const RecognizedStroke& s,
                            std::vector<double>* t,
                            std::vector<double>* v,
                            std::vector<double>* mu,
                            std::size_t max_samples) {
  const double offset = t->empty() ? 0.0 : t->back() + 1.0 - s.t_s.front();
  for (std::size_t k = 0; k < s.t_s.size() && t->size() < max_samples; ++k) {
    const double tk = s.t_s[k] + offset;
    if (!t->empty() && !(tk > t->back())) continue;
    t->push_back(tk);
    v->push_back(s.v_mm_s[k]);
    mu->push_back(s.mu[k]);
  }
}

LuGreStroke ToStroke(const std::vector<double>& t,
                     const std::vector<double>& v,
                     const std::vector<double>& mu) {
  LuGreStroke s;
  const auto n = static_cast<Eigen::Index>(t.size());
  s.t_s = Eigen::Map<const Eigen::VectorXd>(t.data(), n);
  s.v_mm_s = Eigen::Map<const Eigen::VectorXd>(v.data(), n);
  s.mu = Eigen::Map<const Eigen::VectorXd>(mu.data(), n);
  return s;
}

double Median(std::vector<double> x) {
  if (x.empty()) return kNaN;
  const std::size_t h = x.size() / 2;
  std::nth_element(x.begin(), x.begin() + h, x.end());
  return x[h];
}

std::string Summary(const std::vector<const RecognizedStroke*>& segments) {
  int qs = 0, dyn = 0, mid = 0, short_ = 0;
  for (const RecognizedStroke* p : segments) {
    const RecognizedStroke& s = *p;
    qs += s.kind == LuGreStrokeKind::kQuasiStatic;
    dyn += s.kind == LuGreStrokeKind::kDynamic;
    mid += s.kind == LuGreStrokeKind::kIntermediate;
    short_ += s.kind == LuGreStrokeKind::kTooShort;
  }
  return std::to_string(segments.size()) +
         " stroke(s) recognised: " + std::to_string(qs) +
         " low-acceleration, " + std::to_string(dyn) + " high-acceleration, " +
         std::to_string(mid) + " between 3 and 5 mm/s^2, " +
         std::to_string(short_) + " too short";
}

// Step 1 on the quasi-static strokes: LM from three starts, best converged.
LuGreFitResult FitStep1(const LuGreStroke& stroke) {
  const Eigen::Index n = stroke.size();
  const double v_max = stroke.v_mm_s.cwiseAbs().maxCoeff();
  std::vector<double> low, high;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double s = std::abs(stroke.v_mm_s[k]);
    const double r = stroke.v_mm_s[k] >= 0 ? stroke.mu[k] : -stroke.mu[k];
    if (s > 0.03 * v_max && s <= 0.1 * v_max) low.push_back(r);
    if (s >= 0.7 * v_max) high.push_back(r);
  }
  const QuasiStaticFitOptions options;
  auto inside = [&](double x, int i) {
    const double lo = options.lower_bounds[i], hi = options.upper_bounds[i];
    if (!std::isfinite(x)) x = 0.5 * (lo + hi);
    return std::clamp(x, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo));
  };
  const double mu_c = inside(Median(high), 1);
  const double mu_s = inside(low.empty() ? 1.2 * mu_c : Median(low), 0);
  const Eigen::Vector4d starts[3] = {
      Eigen::Vector4d(mu_s, mu_c, inside(0.1 * v_max, 2), 0.0),
      Eigen::Vector4d(mu_s, mu_c, inside(0.3 * v_max, 2), 0.0),
      Eigen::Vector4d(
          inside(0.3, 0), inside(0.2, 1), inside(0.05 * v_max, 2), 0.0)};
  LuGreFitResult best;
  bool have = false;
  for (const Eigen::Vector4d& start : starts) {
    LuGreFitResult r = FitLuGreQuasiStatic(stroke, start, options);
    const bool better = !have || (r.status == LuGreFitStatus::kConverged &&
                                  (best.status != LuGreFitStatus::kConverged ||
                                   r.residual_rms < best.residual_rms));
    if (better) {
      best = std::move(r);
      have = true;
    }
  }
  return best;
}

// Noise of mu on the quasi-static strokes: RMS of second differences
// mu[k+1] - 2 mu[k] + mu[k-1] over sqrt(6) (white noise of std s gives
// variance 6 s^2; a slow stroke's smooth part adds almost nothing at the
// sampling rates used), over triples whose samples all move faster than 3 %
// of the stroke's peak speed (the samples Step 1 fits).
double EstimateNoise(const std::vector<const RecognizedStroke*>& strokes) {
  double sum = 0;
  std::size_t count = 0;
  for (const RecognizedStroke* s : strokes) {
    double v_max = 0;
    for (double v : s->v_mm_s) v_max = std::max(v_max, std::abs(v));
    const double floor = 0.03 * v_max;
    for (std::size_t k = 1; k + 1 < s->mu.size(); ++k) {
      if (!(std::abs(s->v_mm_s[k - 1]) > floor &&
            std::abs(s->v_mm_s[k]) > floor &&
            std::abs(s->v_mm_s[k + 1]) > floor))
        continue;
      const double d2 = s->mu[k + 1] - 2.0 * s->mu[k] + s->mu[k - 1];
      sum += d2 * d2;
      ++count;
    }
  }
  return count > 0 ? std::sqrt(sum / (6.0 * static_cast<double>(count))) : kNaN;
}

// Step 2 on one dynamic stroke: LM-2 from sigma0 = 10 and 100 /mm, else LM-1.
struct Step2Fit {
  const RecognizedStroke* stroke = nullptr;
  LuGreFitResult fit;
  DynamicFitVariant variant = DynamicFitVariant::kLm2;
  Eigen::Index samples = 0;
  double damping_gain = 0.0;  // LM-1's tie gain for this stroke
};

// Mass behind the LM-1 tie (paper 001 after eq. 10: sigma1 = sqrt(sigma0)
// in N/m, Ns/m, i.e. m = 1 kg and zeta = 0.5); the gain is computed from
// the stroke's own mean normal force (CalcDampingGain), not the 5 N
// constant of DynamicFitOptions.
constexpr double kTieMassKg = 1.0;
constexpr double kTieDampingRatio = 0.5;

double TieGain(double fn_mean_n) {
  if (!(fn_mean_n > 0) || !std::isfinite(fn_mean_n))
    return DynamicFitOptions().damping_gain;
  return CalcDampingGain(kTieMassKg, fn_mean_n, kTieDampingRatio);
}

Step2Fit FitStep2(const LuGreStroke& stroke,
                  const LuGreTheta& qs,
                  double fn_mean_n) {
  Step2Fit last;
  last.samples = stroke.size();
  last.damping_gain = TieGain(fn_mean_n);
  for (DynamicFitVariant variant :
       {DynamicFitVariant::kLm2, DynamicFitVariant::kLm1}) {
    for (double sigma0 : {10.0, 100.0}) {
      LuGreTheta guess = qs;
      guess[LuGreIndex::kStiffness] = sigma0;
      guess[LuGreIndex::kDamping] = 0.01 * std::sqrt(sigma0 / 10.0);
      DynamicFitOptions options;
      options.variant = variant;
      options.damping_gain = last.damping_gain;
      last.fit = FitLuGreDynamic(stroke, guess, 0.0, options);
      last.variant = variant;
      if (last.fit.status == LuGreFitStatus::kConverged) return last;
    }
  }
  return last;
}

const char* VariantName(DynamicFitVariant v) {
  switch (v) {
    case DynamicFitVariant::kLm1:
      return "lm1";
    case DynamicFitVariant::kLm2:
      return "lm2";
    case DynamicFitVariant::kLm6:
      return "lm6";
  }
  return "?";
}

// The family fitter: recognise strokes, run the two steps, encode.
LuGreIdentification Identify(const StrokeData& all, IdentificationMemo* memo) {
  LuGreIdentification out;
  std::string* note = &out.why;
  std::vector<std::shared_ptr<const std::vector<RecognizedStroke>>> runs;
  const std::vector<const RecognizedStroke*> segments =
      Recognize(all, memo, &runs);
  for (const RecognizedStroke* s : segments) {
    out.strokes_quasi_static += s->kind == LuGreStrokeKind::kQuasiStatic;
    out.strokes_dynamic += s->kind == LuGreStrokeKind::kDynamic;
    out.strokes_intermediate += s->kind == LuGreStrokeKind::kIntermediate;
    out.strokes_too_short += s->kind == LuGreStrokeKind::kTooShort;
  }
  std::vector<const RecognizedStroke*> qs, dyn;
  for (const RecognizedStroke* s : segments) {
    if (s->kind == LuGreStrokeKind::kQuasiStatic) qs.push_back(s);
    if (s->kind == LuGreStrokeKind::kDynamic) dyn.push_back(s);
  }
  if (qs.empty()) {
    *note =
        "no low-acceleration stroke (<= 3 mm/s^2) for the quasi-static "
        "step; " +
        Summary(segments);
    return out;
  }
  if (dyn.empty()) {
    *note = "no high-acceleration stroke (>= 5 mm/s^2) for the dynamic step; " +
            Summary(segments);
    return out;
  }
  // Step 1: all quasi-static strokes, newest first up to the sample cap.
  std::vector<double> t, v, mu;
  int used_qs = 0;
  for (auto it = qs.rbegin(); it != qs.rend(); ++it) {
    if (t.size() >= kMaxQuasiStaticSamples) break;
    AppendRecognizedStroke(**it, &t, &v, &mu, kMaxQuasiStaticSamples);
    ++used_qs;
  }
  if (t.size() < static_cast<std::size_t>(kMinMovingSamples)) {
    *note = "too few quasi-static samples (" + std::to_string(t.size()) + ")";
    return out;
  }
  const LuGreFitResult step1 = FitStep1(ToStroke(t, v, mu));
  if (step1.status != LuGreFitStatus::kConverged) {
    *note = std::string("quasi-static fit: ") + ToString(step1.status) + ": " +
            step1.why;
    return out;
  }
  // Step 2: newest dynamic strokes, one fit each.
  std::vector<Step2Fit> fits;
  std::string last_why;
  const double rms_limit = kMaxRmsRatio * std::max(step1.residual_rms, 1e-6);
  const DynamicFitOptions bounds;
  const double z0_span = bounds.upper_bounds[6] - bounds.lower_bounds[6];
  int tried = 0;
  std::size_t tried_samples = 0;
  for (auto it = dyn.rbegin();
       it != dyn.rend() && static_cast<int>(fits.size()) < kMaxDynamicStrokes &&
       tried < kMaxDynamicAttempts && tried_samples < kMaxStep2Samples;
       ++it, ++tried) {
    std::vector<double> td, vd, mud;
    AppendRecognizedStroke(
        **it, &td, &vd, &mud, static_cast<std::size_t>(kMaxDynamicSamples));
    tried_samples += td.size();
    Step2Fit r = FitStep2(ToStroke(td, vd, mud), step1.theta, (*it)->fn_mean_n);
    r.stroke = *it;
    if (r.fit.status != LuGreFitStatus::kConverged) {
      last_why = std::string(ToString(r.fit.status)) + ": " + r.fit.why;
    } else if (!(r.fit.residual_rms <= rms_limit)) {
      last_why = "residual RMS " + NumberText(r.fit.residual_rms) + " > " +
                 NumberText(kMaxRmsRatio) + " x quasi-static RMS " +
                 NumberText(step1.residual_rms);
    } else if (!(std::abs(r.fit.z0_mm - bounds.lower_bounds[6]) >
                     1e-6 * z0_span &&
                 std::abs(r.fit.z0_mm - bounds.upper_bounds[6]) >
                     1e-6 * z0_span)) {
      last_why = "z0 = " + NumberText(r.fit.z0_mm) + " mm at its bound";
    } else {
      fits.push_back(std::move(r));
    }
  }
  if (fits.empty()) {
    *note = "no LuGre fit accepted on the newest " + std::to_string(tried) +
            " high-acceleration stroke(s) (LM-2, LM-1); last: " + last_why;
    return out;
  }
  // Prefer LM-2 results; combine them by information (sigma0, sigma1).
  const bool any_lm2 =
      std::any_of(fits.begin(), fits.end(), [](const Step2Fit& f) {
        return f.variant == DynamicFitVariant::kLm2;
      });
  LuGreFamily family;
  family.theta = step1.theta;
  family.P_theta.topLeftCorner<4, 4>() = step1.P_theta.topLeftCorner<4, 4>();
  family.quasi_static_residual_rms = step1.residual_rms;
  family.iterations = step1.iterations;
  family.strokes_quasi_static = used_qs;
  family.variant =
      VariantName(any_lm2 ? DynamicFitVariant::kLm2 : DynamicFitVariant::kLm1);
  Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
  Eigen::Vector2d info_x = Eigen::Vector2d::Zero();
  double sse = 0;
  Eigen::Index samples = 0;
  int used_dyn = 0;
  const LuGreFitResult* newest = nullptr;
  for (std::size_t k = 0; k < fits.size(); ++k) {
    const LuGreFitResult& f = fits[k].fit;
    const bool is_lm2 = fits[k].variant == DynamicFitVariant::kLm2;
    if (is_lm2 != any_lm2) continue;
    const Eigen::Vector2d x = f.theta.segment<2>(LuGreIndex::kStiffness);
    if (any_lm2) {
      const Eigen::Matrix2d P =
          f.P_theta.block<2, 2>(LuGreIndex::kStiffness, LuGreIndex::kStiffness);
      const Eigen::LDLT<Eigen::Matrix2d> ldlt(P);
      if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0))
        continue;
      const Eigen::Matrix2d I = ldlt.solve(Eigen::Matrix2d::Identity());
      info += I;
      info_x += I * x;
    } else {
      const double var =
          f.P_theta(LuGreIndex::kStiffness, LuGreIndex::kStiffness);
      if (!(var > 0)) continue;
      info(0, 0) += 1.0 / var;
      info_x[0] += x[0] / var;
    }
    if (!newest) newest = &f;
    family.iterations += f.iterations;
    family.excited_samples += f.excited_samples;
    sse +=
        f.residual_rms * f.residual_rms * static_cast<double>(fits[k].samples);
    samples += fits[k].samples;
    ++used_dyn;
  }
  if (!newest) {
    // No usable covariance: keep the newest converged fit as it is.
    newest = &fits.front().fit;
    family.variant = VariantName(fits.front().variant);
    family.theta.segment<2>(LuGreIndex::kStiffness) =
        newest->theta.segment<2>(LuGreIndex::kStiffness);
    family.iterations += newest->iterations;
    family.excited_samples = newest->excited_samples;
    sse = newest->residual_rms * newest->residual_rms;
    samples = 1;
    used_dyn = 1;
  } else if (any_lm2) {
    const Eigen::Matrix2d P = info.ldlt().solve(Eigen::Matrix2d::Identity());
    family.theta.segment<2>(LuGreIndex::kStiffness) = P * info_x;
    family.P_theta.block<2, 2>(LuGreIndex::kStiffness, LuGreIndex::kStiffness) =
        P;
  } else {
    // LM-1: sigma1 = c sqrt(sigma0) with the newest used fit's gain (its
    // stroke's normal force).
    const double var = 1.0 / info(0, 0);
    const double s0 = info_x[0] * var;
    double c = DynamicFitOptions().damping_gain;
    for (const Step2Fit& f : fits)
      if (&f.fit == newest) c = f.damping_gain;
    const double ds1 = c / (2.0 * std::sqrt(s0));
    family.theta[LuGreIndex::kStiffness] = s0;
    family.theta[LuGreIndex::kDamping] = c * std::sqrt(s0);
    family.P_theta(4, 4) = var;
    family.P_theta(4, 5) = family.P_theta(5, 4) = ds1 * var;
    family.P_theta(5, 5) = ds1 * ds1 * var;
  }
  family.z0_mm = newest->z0_mm;
  family.residual_rms =
      samples > 0 ? std::sqrt(sse / static_cast<double>(samples)) : kNaN;
  family.strokes_dynamic = used_dyn;
  family.status = ToString(LuGreFitStatus::kConverged);
  // Step 1's premise (eq. 4: dz/dt ~ 0 on the slow stroke). With compliant
  // bristles (paper 001 Tables I, III: sigma0 ~ 0.4 /mm in ratio form) the
  // bristles relax over g / sigma0 ~ 1 mm, as long as the 2 mm/s^2 stroke
  // takes to cross the Stribeck region, so the slow stroke keeps a
  // hysteresis that eq. 4 cannot fit and Step 1 returns a flattened Stribeck
  // curve (mu_s 0.1 for a truth of 0.3; docs/lugre.md "Paper regime").
  // Then Step 1's numbers are not kept: LM-6 (all six and z0, eqs. 11-15)
  // is run on the newest accepted dynamic stroke from the two-step result,
  // and kept only if it explains that stroke to the noise and pins down
  // mu_s, mu_c and v0; otherwise nothing is identified and `why` says so.
  // Floor 1e-4 (below any force sensor's resolution in Ft/Fn) so that
  // noise-free data compare against a model error, not against rounding.
  const double noise = std::max(EstimateNoise(qs), kMinNoiseMu);
  const std::string two_step =
      std::string("GNR+") + (family.variant == "lm2" ? "LM-2" : "LM-1");
  if (std::isfinite(noise) && noise > 0 &&
      !(step1.residual_rms <= kQuasiStaticNoiseRatio * noise)) {
    std::string premise =
        "the low-acceleration stroke is not quasi-static (paper 001 eq. 4): "
        "Step-1 residual RMS " +
        NumberText(step1.residual_rms) + " is " +
        NumberText(step1.residual_rms / noise) + " x the noise " +
        NumberText(noise) +
        " (second differences); the bristles relax over g/sigma0 ~ " +
        NumberText(std::max(step1.theta[LuGreIndex::kMuStatic],
                            step1.theta[LuGreIndex::kMuCoulomb]) /
                   family.theta[LuGreIndex::kStiffness]) +
        " mm, so the slow stroke still shows hysteresis and " + two_step +
        "'s Stribeck parameters are biased";
    const Step2Fit* source = nullptr;
    for (const Step2Fit& f : fits)
      if (&f.fit == newest) source = &f;
    LuGreFitResult lm6;
    if (source && source->stroke) {
      std::vector<double> td, vd, mud;
      AppendRecognizedStroke(*source->stroke,
                             &td,
                             &vd,
                             &mud,
                             static_cast<std::size_t>(kMaxDynamicSamples));
      DynamicFitOptions options;
      options.variant = DynamicFitVariant::kLm6;
      LuGreTheta start = family.theta;
      const double z0 = std::clamp(newest->z0_mm,
                                   0.99 * bounds.lower_bounds[6],
                                   0.99 * bounds.upper_bounds[6]);
      lm6 = FitLuGreDynamic(ToStroke(td, vd, mud), start, z0, options);
    }
    const auto rel_std = [&lm6](int i) {
      return std::sqrt(std::max(lm6.P_theta(i, i), 0.0)) /
             std::abs(lm6.theta[i]);
    };
    const bool lm6_ok =
        lm6.status == LuGreFitStatus::kConverged &&
        lm6.residual_rms <= kLm6NoiseRatio * noise &&
        rel_std(LuGreIndex::kMuStatic) <= kMaxLm6RelStd &&
        rel_std(LuGreIndex::kMuCoulomb) <= kMaxLm6RelStd &&
        rel_std(LuGreIndex::kStribeckVelocity) <= 2 * kMaxLm6RelStd &&
        rel_std(LuGreIndex::kDamping) <= 2 * kMaxLm6RelStd &&
        IsValidLuGreTheta(lm6.theta, nullptr);
    if (!lm6_ok) {
      *note =
          "cannot identify LuGre from these strokes: " + premise +
          "; LM-6 on the newest high-acceleration stroke: " +
          (lm6.status == LuGreFitStatus::kConverged
               ? "RMS " + NumberText(lm6.residual_rms) + ", std/value mu_s " +
                     NumberText(rel_std(LuGreIndex::kMuStatic)) + ", mu_c " +
                     NumberText(rel_std(LuGreIndex::kMuCoulomb)) + ", v0 " +
                     NumberText(rel_std(LuGreIndex::kStribeckVelocity)) +
                     ", sigma1 " + NumberText(rel_std(LuGreIndex::kDamping)) +
                     " (limits RMS " + NumberText(kLm6NoiseRatio) +
                     " x noise, " + NumberText(kMaxLm6RelStd) + ", " +
                     NumberText(kMaxLm6RelStd) + ", " +
                     NumberText(2 * kMaxLm6RelStd) + ", " +
                     NumberText(2 * kMaxLm6RelStd) + ")"
               : std::string(ToString(lm6.status)) + ": " + lm6.why) +
          "; record a slower low-acceleration stroke (its travel below 2 v0 "
          "must be many times g/sigma0)";
      return out;
    }
    family.theta = lm6.theta;
    family.P_theta = lm6.P_theta;
    family.variant = VariantName(DynamicFitVariant::kLm6);
    family.iterations += lm6.iterations;
    family.residual_rms = lm6.residual_rms;
    family.z0_mm = lm6.z0_mm;
    family.excited_samples = lm6.excited_samples;
    family.strokes_dynamic = 1;
    *note = premise +
            "; kept LM-6 on the newest high-acceleration stroke "
            "(RMS " +
            NumberText(lm6.residual_rms) + ", std/value mu_s " +
            NumberText(rel_std(LuGreIndex::kMuStatic)) + ", sigma1 " +
            NumberText(rel_std(LuGreIndex::kDamping)) + ")";
  } else {
    *note = "two-step " + two_step + ": Step-1 RMS " +
            NumberText(step1.residual_rms) + " (noise " + NumberText(noise) +
            ")" +
            (family.variant == "lm2"
                 ? ", sigma1 free"
                 : ", sigma1 tied to sigma0 (LM-2 did not converge)");
  }
  std::string why;
  if (!IsValidLuGreTheta(family.theta, &why)) {
    *note = "identified parameters are not usable: " + why;
    return out;
  }
  out.identified = true;
  out.family = std::move(family);
  return out;
}

}  // namespace

std::vector<RecognizedStroke> RecognizeLuGreStrokes(const StrokeData& data) {
  std::vector<std::shared_ptr<const std::vector<RecognizedStroke>>> runs;
  std::vector<RecognizedStroke> out;
  for (const RecognizedStroke* s : Recognize(data, nullptr, &runs))
    out.push_back(*s);
  return out;
}

LuGreIdentification IdentifyLuGreFromStrokes(const StrokeData& data,
                                             IdentificationMemo* memo) {
  return Identify(data, memo);
}

}  // namespace frictiond
