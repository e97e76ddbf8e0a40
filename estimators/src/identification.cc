#include "frictiond/estimators/identification.h"

#include <atomic>
#include <exception>
#include <future>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/estimators/preprocessing.h"

namespace frictiond {

namespace {

// The slipping samples' (Fn, v) and stroke ids: the inputs of the span
// coverage and the hull.
struct SlipPoints {
  std::vector<double> fn, v;
  std::vector<int> stroke;
};

SlipPoints CollectSlipPoints(const StrokeData& data) {
  const std::size_t n = data.size();
  SlipPoints p;
  p.fn.reserve(n);
  p.v.reserve(n);
  const bool has_stroke = data.stroke.size() == n;
  for (std::size_t i = 0; i < n; ++i) {
    if (data.slip[i]) {
      p.fn.push_back(data.fn_n[i]);
      p.v.push_back(data.v_mm_s[i]);
      if (has_stroke) p.stroke.push_back(data.stroke[i]);
    }
  }
  return p;
}

// Eq. (2) on every sample, the span coverage and the LuGre family: the
// steps that do not need the regressions (a second thread's share).
void FitConditionalCoverageAndLuGre(
    const StrokeData& data,
    const SlipPoints& slip,
    const MaterialIdentificationOptions& options,
    MaterialIdentification* out) {
  const std::size_t n = data.size();
  std::vector<double> ratio(n);
  for (std::size_t i = 0; i < n; ++i) ratio[i] = data.ft_n[i] / data.fn_n[i];
  // A family that cannot be identified is a status, never an exception.
  try {
    out->conditional = FitConditionalSlipLikelihood(data.fn_n,
                                                    ratio,
                                                    data.slip,
                                                    options.conditional,
                                                    options.conditional_start);
  } catch (const std::exception& e) {
    out->conditional = ConditionalSlipLikelihood{};
    out->conditional.why = std::string("identification failed: ") + e.what();
  }
  out->coverage = CalcSpanCoverage(
      slip.fn, slip.v, options.reference, slip.stroke, options.memo);
  if (options.lugre) {
    // Likewise (the other families stand).
    try {
      out->lugre = IdentifyLuGreFromStrokes(data, options.memo);
    } catch (const std::exception& e) {
      out->lugre = LuGreIdentification{};
      out->lugre.why = std::string("identification failed: ") + e.what();
    }
  } else {
    out->lugre.why = "not requested";
  }
}

// A task run exactly once, by whichever thread claims it first: the worker
// it was posted to, or the caller once its own share is done.
class ClaimedTask {
 public:
  explicit ClaimedTask(std::function<void()> f) : f_(std::move(f)) {}
  // Runs the task if nobody has; true when this call ran it.
  bool TryRun() {
    if (claimed_.exchange(true)) return false;
    try {
      f_();
      done_.set_value();
    } catch (...) {
      done_.set_exception(std::current_exception());
    }
    return true;
  }
  // Claims the task without running it; true when it had not started.
  bool Cancel() { return !claimed_.exchange(true); }
  std::future<void> Future() { return done_.get_future(); }

 private:
  std::function<void()> f_;
  std::atomic<bool> claimed_{false};
  std::promise<void> done_;
};

}  // namespace

MaterialIdentification IdentifyMaterial(
    StrokeData data, const MaterialIdentificationOptions& options) {
  std::string why;
  if (!options.fit.IsValid(&why)) throw std::invalid_argument(why);
  if (!options.conditional.IsValid(&why))
    throw std::invalid_argument("conditional: " + why);
  if (!options.reference.IsValid())
    throw std::invalid_argument(
        "reference: fn and v ranges must be finite and non-empty");
  if (options.threads < 1)
    throw std::invalid_argument("threads = " + std::to_string(options.threads) +
                                " (must be >= 1)");
  EnsureLabels(&data, options.fit.labelling);
  MaterialIdentification out;
  const SlipPoints slip = CollectSlipPoints(data);
  if (options.threads == 1) {
    out.fit = FitStochasticModel(data, options.fit);
    out.hull = CalcMaterialHullCoverage(
        slip.fn, slip.v, slip.stroke, kDefaultMaxHullStrokes, options.memo);
    FitConditionalCoverageAndLuGre(data, slip, options, &out);
    if (options.memo) options.memo->Sweep();
    return out;
  }
  // Two shares of about equal cost (profiled on the bundled 42k-sample
  // set: the regressions and the hull; eq. (2), the span and the LuGre
  // stroke recognition). Both read `data` and `slip` only and write
  // disjoint members of `out`.
  auto side_task = std::make_shared<ClaimedTask>(
      [&] { FitConditionalCoverageAndLuGre(data, slip, options, &out); });
  std::future<void> side_done = side_task->Future();
  std::future<void> thread;  // std::async's: joined when it goes
  if (options.post) {
    try {
      options.post([side_task] { side_task->TryRun(); });
    } catch (...) {
      // Not posted: this thread runs it below.
    }
  } else {
    thread =
        std::async(std::launch::async, [side_task] { side_task->TryRun(); });
  }
  try {
    out.fit = FitStochasticModel(data, options.fit);
    out.hull = CalcMaterialHullCoverage(
        slip.fn, slip.v, slip.stroke, kDefaultMaxHullStrokes, options.memo);
  } catch (...) {
    // Not started: nobody runs it now; started: it uses `out`, wait.
    if (!side_task->Cancel()) side_done.wait();
    throw;
  }
  side_task->TryRun();  // not started yet: run it here
  side_done.get();      // rethrows the side's exception, if any
  if (options.memo) options.memo->Sweep();
  return out;
}

}  // namespace frictiond
