// LCM messages from the service's types (lcm_messages.h).
#include "lcm_messages.h"

#ifdef FRICTIOND_HAVE_LCM

#include <cmath>
#include <exception>

#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lugre_json.h"

namespace frictiond {
namespace internal {

friction_model_v1 ModelToLcm(const CachedModel& m) {
  friction_model_v1 out;
  out.material = m.set.material;
  out.fingertip = m.set.fingertip;
  out.version = m.set.version;
  out.created_at = m.set.created_at;
  out.n_terms = 0;
  out.sigma_eps = out.r2 = out.mu_coulomb = std::nan("");
  out.likelihood_c1 = out.likelihood_c2 = std::nan("");
  out.samples = 0;
  out.n_quantiles = 0;
  if (m.set.stochastic) {
    const StochasticFrictionModel& s = *m.set.stochastic;
    out.n_terms = static_cast<int32_t>(s.mu.terms.size());
    for (std::size_t i = 0; i < s.mu.terms.size(); ++i) {
      out.term_names.push_back(s.mu.terms[i].Name());
      out.coefficients.push_back(static_cast<Eigen::Index>(i) < s.mu.beta.size()
                                     ? s.mu.beta[i]
                                     : std::nan(""));
      out.std_errors.push_back(
          static_cast<Eigen::Index>(i) < s.mu.std_err.size() ? s.mu.std_err[i]
                                                             : std::nan(""));
    }
    out.sigma_eps = s.mu.sigma_eps;
    out.r2 = s.mu.r2;
    out.samples = s.mu.samples;
    const std::vector<double>& levels = EpsQuantileLevels();
    if (s.mu.eps_quantiles.size() == levels.size()) {
      out.n_quantiles = static_cast<int32_t>(levels.size());
      out.eps_levels = levels;
      out.eps_quantiles = s.mu.eps_quantiles;
    }
    out.mu_coulomb = s.mu_coulomb;
    if (s.likelihood.valid) {
      out.likelihood_c1 = s.likelihood.c1;
      out.likelihood_c2 = s.likelihood.c2;
    }
  }
  out.has_lugre = false;
  for (double& x : out.lugre_theta) x = std::nan("");
  if (auto it = m.set.other.find(kLuGreFamilyKey); it != m.set.other.end()) {
    try {
      const LuGreFamily f = LuGreFromJson(*it);
      for (int i = 0; i < 6; ++i) out.lugre_theta[i] = f.theta[i];
      out.has_lugre = true;
    } catch (const std::exception&) {
      // A family this build cannot read is left out of the LCM message.
    }
  }
  return out;
}

IdentificationRequestMessages IdentificationRequestToLcm(
    std::int64_t utime,
    std::int64_t job_id,
    const std::string& request_id,
    const std::string& robot,
    const std::string& material,
    const std::string& fingertip,
    const StrokePlan& plan,
    int stroke,
    const std::optional<SpanRect>& missing) {
  identification_request_v1 r;
  r.utime = utime;
  r.job_id = job_id;
  r.stroke = stroke;
  r.request_id = request_id.substr(0, kLcmMaxTextField);
  r.robot = robot.substr(0, kLcmMaxTextField);
  r.material = material;
  r.fingertip = fingertip;
  const SpanRect span = missing ? *missing : plan.span();
  r.fn_min_n = span.fn_min_n;
  r.fn_max_n = span.fn_max_n;
  r.v_min_mm_s = span.v_min_mm_s;
  r.v_max_mm_s = span.v_max_mm_s;
  r.max_duration_s = plan.max_duration_s;
  r.min_span_pct = plan.min_span_pct;
  r.follow_up = missing.has_value();
  r.instructions =
      std::string(missing ? "follow-up: the strokes so far covered too "
                            "little of the Fn-v span; "
                          : "") +
      "slide the fingertip in repeated strokes with rests between them, "
      "sweeping normal force over [fn_min_n, fn_max_n] and peak speed over "
      "[v_min_mm_s, v_max_mm_s]; stream the samples as stroke_chunk_v1 on " +
      kLcmStrokeChannel + " with job_id " + std::to_string(job_id) +
      " and stroke " + std::to_string(stroke);
  // v2: the same plus the LuGre pair (a plan stored before the pair
  // existed asks for none).
  identification_request_v2 r2;
  r2.utime = r.utime;
  r2.job_id = r.job_id;
  r2.stroke = r.stroke;
  r2.request_id = r.request_id;
  r2.robot = r.robot;
  r2.material = r.material;
  r2.fingertip = r.fingertip;
  r2.fn_min_n = r.fn_min_n;
  r2.fn_max_n = r.fn_max_n;
  r2.v_min_mm_s = r.v_min_mm_s;
  r2.v_max_mm_s = r.v_max_mm_s;
  r2.max_duration_s = r.max_duration_s;
  r2.min_span_pct = r.min_span_pct;
  r2.follow_up = r.follow_up;
  r2.instructions = r.instructions;
  const std::optional<LuGrePairPlan>& lugre = plan.lugre;
  r2.lugre_pair = lugre.has_value();
  const double nan = std::nan("");
  r2.lugre_fn_n = lugre ? lugre->fn_n : nan;
  r2.lugre_slow_accel_mm_s2 = lugre ? lugre->slow_accel_mm_s2 : nan;
  r2.lugre_slow_peak_mm_s = lugre ? lugre->slow_peak_mm_s : nan;
  r2.lugre_fast_strokes = lugre ? lugre->fast_strokes : 0;
  r2.lugre_fast_accel_mm_s2 = lugre ? lugre->fast_accel_mm_s2 : nan;
  r2.lugre_fast_peak_mm_s = lugre ? lugre->fast_peak_mm_s : nan;
  r2.lugre_rest_s = lugre ? lugre->rest_s : nan;
  if (lugre)
    r2.instructions +=
        "; then, at normal force lugre_fn_n, the LuGre pair: a slow "
        "triangle to lugre_slow_peak_mm_s at lugre_slow_accel_mm_s2 and "
        "lugre_fast_strokes fast triangles to lugre_fast_peak_mm_s at "
        "lugre_fast_accel_mm_s2, lugre_rest_s apart, in the same stroke";
  return {r, r2};
}

}  // namespace internal
}  // namespace frictiond

#endif  // FRICTIOND_HAVE_LCM
