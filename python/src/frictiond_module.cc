/// @file
/// The `frictiond._core` extension module: pybind11 bindings of the C++
/// client library (FrictionClient, the fetched ModelSet and its evaluation
/// by PredictMu / CalcSlipLikelihood / CalcGripForce / MuSampler). No
/// formula is written here: every value comes from the client library or
/// the estimators; this file only broadcasts NumPy arrays over them, with
/// the GIL released. The Python package (python/frictiond/__init__.py)
/// adds the user-facing Client (uploads of files and data frames) and the
/// docs; python/frictiond/_core.pyi holds the type hints.

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "frictiond/client/client.h"
#include "frictiond/client/mu_sampler.h"
#include "frictiond/estimators/grip_force.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/proto/model_json.h"

namespace py = pybind11;

namespace frictiond {
namespace {

// ---------------------------------------------------------------------------
// JSON <-> Python (through the json module: bodies are small)

py::object ToPython(const nlohmann::json& j) {
  if (j.is_null()) return py::none();
  return py::module_::import("json").attr("loads")(j.dump());
}

nlohmann::json FromPython(const py::handle& o) {
  if (py::isinstance<py::str>(o))
    return nlohmann::json::parse(o.cast<std::string>());
  const std::string text =
      py::module_::import("json").attr("dumps")(o).cast<std::string>();
  return nlohmann::json::parse(text);
}

// ---------------------------------------------------------------------------
// Errors: ClientError -> frictiond.DaemonError (or its subclasses), with the
// daemon's status, error, field, detail and whole body.

void RaiseDaemonError(const ClientError& e) {
  const py::module_ errors = py::module_::import("frictiond._errors");
  const char* cls_name = e.status() == 0     ? "UnreachableError"
                         : e.status() == 404 ? "NotFoundError"
                                             : "DaemonError";
  const py::object cls = errors.attr(cls_name);
  const nlohmann::json& b = e.body();
  auto field = [&](const char* key) -> py::object {
    if (b.is_object() && b.contains(key) && b[key].is_string())
      return py::str(b[key].get<std::string>());
    return py::none();
  };
  const py::object inst = cls(py::str(e.what()),
                              py::int_(e.status()),
                              field("error"),
                              field("field"),
                              field("detail"),
                              ToPython(b));
  PyErr_SetObject(cls.ptr(), inst.ptr());
}

// ---------------------------------------------------------------------------
// Broadcasting NumPy operands over a scalar function.

using DArray = py::array_t<double, py::array::forcecast>;

// One operand: its data and byte strides aligned to the output's dims (0
// where it is broadcast).
struct Operand {
  const char* data = nullptr;
  std::vector<py::ssize_t> strides;
};

struct Broadcast {
  std::vector<py::ssize_t> shape;
  py::ssize_t size = 1;
  std::vector<Operand> operands;
  std::vector<DArray> keep;  // the (possibly converted) arrays read
  // True when every operand is one value (all strides 0).
  bool AllScalar() const {
    for (const Operand& o : operands)
      for (py::ssize_t s : o.strides)
        if (s != 0) return false;
    return true;
  }
};

std::string ShapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k)
    s += (k ? ", " : "") + std::to_string(a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// An aligned double array of any shape from any array-like.
DArray AsArray(const py::handle& x, const char* name) {
  DArray a;
  try {
    a = DArray::ensure(x);
  } catch (const py::error_already_set&) {
    throw py::type_error(std::string(name) + ": not a number or an array");
  }
  if (!a) {
    PyErr_Clear();
    throw py::type_error(std::string(name) + ": not a number or an array");
  }
  if (!(a.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_)) {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
        a);
  }
  return a;
}

// numpy's broadcasting rules over `arrays` and an optional extra shape (a
// `size` argument). @throws ValueError naming the operands' shapes.
Broadcast MakeBroadcast(const std::vector<std::pair<const char*, DArray>>& ops,
                        const std::vector<py::ssize_t>& extra_shape = {}) {
  std::size_t nd = extra_shape.size();
  for (const auto& [name, a] : ops)
    nd = std::max(nd, static_cast<std::size_t>(a.ndim()));
  Broadcast bc;
  bc.shape.assign(nd, 1);
  auto merge = [&](std::size_t dim, py::ssize_t n) -> bool {
    if (n == 1) return true;
    if (bc.shape[dim] == 1) {
      bc.shape[dim] = n;
      return true;
    }
    return bc.shape[dim] == n;
  };
  auto fail = [&]() {
    std::string msg = "operands could not be broadcast together with shapes";
    for (const auto& [name, a] : ops)
      msg += " " + std::string(name) + ShapeText(a);
    if (!extra_shape.empty()) {
      msg += " size(";
      for (std::size_t k = 0; k < extra_shape.size(); ++k)
        msg += (k ? ", " : "") + std::to_string(extra_shape[k]);
      msg += ")";
    }
    throw py::value_error(msg);
  };
  for (std::size_t k = 0; k < extra_shape.size(); ++k)
    if (!merge(nd - extra_shape.size() + k, extra_shape[k])) fail();
  for (const auto& [name, a] : ops) {
    for (py::ssize_t k = 0; k < a.ndim(); ++k)
      if (!merge(nd - a.ndim() + k, a.shape(k))) fail();
  }
  // A `size` must be the result's shape (as numpy's Generator methods).
  if (!extra_shape.empty()) {
    for (std::size_t k = 0; k < nd; ++k) {
      const std::size_t off = nd - extra_shape.size();
      if (k < off || bc.shape[k] != extra_shape[k - off]) fail();
    }
  }
  for (py::ssize_t n : bc.shape) bc.size *= n;
  for (const auto& [name, a] : ops) {
    Operand o;
    o.data = reinterpret_cast<const char*>(a.data());
    o.strides.assign(nd, 0);
    for (py::ssize_t k = 0; k < a.ndim(); ++k) {
      const std::size_t dim = nd - a.ndim() + k;
      o.strides[dim] = a.shape(k) == 1 ? 0 : a.strides(k);
    }
    bc.operands.push_back(std::move(o));
    bc.keep.push_back(a);
  }
  return bc;
}

// Calls f(i, x0, x1, ...) for every output element i (C order) with the
// operands' values. Runs without the GIL.
template <std::size_t N, class F>
void ForEach(const Broadcast& bc, F&& f) {
  if (bc.size == 0) return;
  const std::size_t nd = bc.shape.size();
  std::vector<py::ssize_t> index(nd, 0);
  std::vector<const char*> base(N);
  for (std::size_t j = 0; j < N; ++j) base[j] = bc.operands[j].data;
  const py::ssize_t inner = nd ? bc.shape[nd - 1] : 1;
  py::ssize_t out = 0;
  double x[N];
  py::ssize_t inner_stride[N];
  for (std::size_t j = 0; j < N; ++j)
    inner_stride[j] = nd ? bc.operands[j].strides[nd - 1] : 0;
  while (true) {
    for (py::ssize_t i = 0; i < inner; ++i) {
      for (std::size_t j = 0; j < N; ++j)
        std::memcpy(&x[j], base[j] + i * inner_stride[j], sizeof(double));
      f(out++, x);
    }
    // Advance the odometer over the outer dimensions.
    std::size_t k = nd >= 1 ? nd - 1 : 0;
    bool done = true;
    while (k > 0) {
      --k;
      ++index[k];
      for (std::size_t j = 0; j < N; ++j) base[j] += bc.operands[j].strides[k];
      if (index[k] < bc.shape[k]) {
        done = false;
        break;
      }
      for (std::size_t j = 0; j < N; ++j)
        base[j] -= bc.operands[j].strides[k] * bc.shape[k];
      index[k] = 0;
    }
    if (done) return;
  }
}

template <class T>
py::array_t<T> NewArray(const std::vector<py::ssize_t>& shape) {
  return py::array_t<T>(shape);
}

// "at index (i, j): " for a failing element of a non-scalar result.
std::string IndexText(const Broadcast& bc, py::ssize_t flat) {
  if (bc.shape.empty()) return "";
  std::vector<py::ssize_t> idx(bc.shape.size());
  for (std::size_t k = bc.shape.size(); k-- > 0;) {
    idx[k] = flat % bc.shape[k];
    flat /= bc.shape[k];
  }
  std::string s = "at index (";
  for (std::size_t k = 0; k < idx.size(); ++k)
    s += (k ? ", " : "") + std::to_string(idx[k]);
  return s + (idx.size() == 1 ? ",): " : "): ");
}

// ForEach without the GIL for calls that reject an element with
// std::invalid_argument: the first rejection becomes a ValueError naming
// the element's index (IndexText) and the estimator's reason.
template <std::size_t N, class F>
void ForEachChecked(const Broadcast& bc, F&& f) {
  std::string error;
  {
    py::gil_scoped_release nogil;
    try {
      ForEach<N>(bc, [&](py::ssize_t i, const double* x) {
        try {
          f(i, x);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(IndexText(bc, i) + e.what());
        }
      });
    } catch (const std::invalid_argument& e) {
      error = e.what();
    }
  }
  if (!error.empty()) throw py::value_error(error);
}

// ---------------------------------------------------------------------------
// NumPy random generators: draw uniforms through the BitGenerator's C
// interface (numpy/random/bitgen.h), under its lock, so the C++ draws are
// the numbers Generator.random() would give and the generator advances.

struct NumpyBitgen {  // numpy's bitgen_t
  void* state;
  std::uint64_t (*next_uint64)(void* st);
  std::uint32_t (*next_uint32)(void* st);
  double (*next_double)(void* st);
  std::uint64_t (*next_raw)(void* st);
};

// Holds a numpy BitGenerator's lock for the lifetime of the object.
class GeneratorLease {
 public:
  explicit GeneratorLease(py::object rng) {
    py::module_ np_random = py::module_::import("numpy.random");
    if (rng.is_none() || py::isinstance<py::int_>(rng))
      rng = np_random.attr("default_rng")(rng);
    if (py::hasattr(rng, "bit_generator")) rng = rng.attr("bit_generator");
    if (!py::hasattr(rng, "capsule") || !py::hasattr(rng, "lock"))
      throw py::type_error(
          "rng: expected a numpy.random.Generator, a BitGenerator, an int "
          "seed or None");
    bitgen_ = rng;
    const py::capsule cap = rng.attr("capsule");
    auto* bg = static_cast<NumpyBitgen*>(
        PyCapsule_GetPointer(cap.ptr(), "BitGenerator"));
    if (!bg) throw py::error_already_set();
    source_.next = bg->next_double;
    source_.state = bg->state;
    lock_ = rng.attr("lock");
    lock_.attr("acquire")();
  }
  ~GeneratorLease() {
    try {
      lock_.attr("release")();
    } catch (...) {
    }
  }
  GeneratorLease(const GeneratorLease&) = delete;
  GeneratorLease& operator=(const GeneratorLease&) = delete;
  UniformSource source() const { return source_; }

 private:
  py::object bitgen_;
  py::object lock_;
  UniformSource source_;
};

// ---------------------------------------------------------------------------
// Model

class Model {
 public:
  Model(ModelSet set, FetchInfo info)
      : set_(std::move(set)), info_(std::move(info)) {
    if (set_.stochastic)
      sampler_ = std::make_shared<MuSampler>(*set_.stochastic);
  }

  const ModelSet& set() const { return set_; }
  const FetchInfo& info() const { return info_; }

  const StochasticFrictionModel& stochastic() const {
    if (!set_.stochastic)
      throw py::value_error("model of " + set_.material + " (fingertip " +
                            set_.fingertip + ", version " +
                            std::to_string(set_.version) +
                            ") has no stochastic family");
    return *set_.stochastic;
  }
  const MuSampler& sampler() const {
    stochastic();
    return *sampler_;
  }

  // The model's identified eps time structure, when it has one: the AR(1)
  // coefficient phi per sample of dt_s seconds and the per-episode offset
  // share (EpsTimeModel, eps_time.h).
  struct EpsTime {
    double dt_s = 0.0;
    double phi = 0.0;
    double offset_fraction = 0.0;
  };
  std::optional<EpsTime> eps_time() const {
    if (!set_.stochastic || !set_.stochastic->eps_time.valid)
      return std::nullopt;
    const EpsTimeModel& t = set_.stochastic->eps_time;
    return EpsTime{t.dt_s, t.phi, t.offset_fraction};
  }
  std::optional<double> eps_ar1() const {
    if (const auto t = eps_time()) return t->phi;
    return std::nullopt;
  }

 private:
  ModelSet set_;
  FetchInfo info_;
  std::shared_ptr<const MuSampler> sampler_;
};

py::object Predict(const Model& model, py::handle fn_n, py::handle v_mm_s) {
  const MuSampler& s = model.sampler();
  const Broadcast bc = MakeBroadcast(
      {{"fn_n", AsArray(fn_n, "fn_n")}, {"v_mm_s", AsArray(v_mm_s, "v_mm_s")}});
  auto mu = NewArray<double>(bc.shape), sigma = NewArray<double>(bc.shape),
       lo = NewArray<double>(bc.shape), hi = NewArray<double>(bc.shape);
  auto extra = NewArray<bool>(bc.shape);
  double* pm = mu.mutable_data();
  double* ps = sigma.mutable_data();
  double* pl = lo.mutable_data();
  double* ph = hi.mutable_data();
  bool* pe = extra.mutable_data();
  {
    py::gil_scoped_release nogil;
    ForEach<2>(bc, [&](py::ssize_t i, const double* x) {
      const MuPoint p = s.CalcPrediction(x[0], x[1]);
      pm[i] = p.mu;
      ps[i] = p.sigma;
      pl[i] = p.lo95;
      ph[i] = p.hi95;
      pe[i] = p.extrapolated;
    });
  }
  return py::module_::import("frictiond._types")
      .attr("Prediction")(mu, sigma, lo, hi, extra);
}

py::array_t<double> SlipLikelihood(const Model& model,
                                   py::handle fn_n,
                                   py::handle ft_n) {
  const StochasticFrictionModel& m = model.stochastic();
  const Broadcast bc = MakeBroadcast(
      {{"fn_n", AsArray(fn_n, "fn_n")}, {"ft_n", AsArray(ft_n, "ft_n")}});
  auto out = NewArray<double>(bc.shape);
  double* po = out.mutable_data();
  {
    py::gil_scoped_release nogil;
    ForEach<2>(bc, [&](py::ssize_t i, const double* x) {
      po[i] = CalcSlipLikelihood(m, x[0], x[1]);
    });
  }
  return out;
}

py::object GripForces(const Model& model,
                      py::handle load_n,
                      py::handle risk,
                      py::handle hold_s,
                      py::handle v_mm_s) {
  const StochasticFrictionModel& m = model.stochastic();
  const Broadcast bc = MakeBroadcast({{"load_n", AsArray(load_n, "load_n")},
                                      {"risk", AsArray(risk, "risk")},
                                      {"hold_s", AsArray(hold_s, "hold_s")},
                                      {"v_mm_s", AsArray(v_mm_s, "v_mm_s")}});
  auto fn = NewArray<double>(bc.shape), mu = NewArray<double>(bc.shape),
       sd = NewArray<double>(bc.shape), instant = NewArray<double>(bc.shape),
       min_risk = NewArray<double>(bc.shape);
  auto ok = NewArray<bool>(bc.shape), extra = NewArray<bool>(bc.shape);
  auto status = NewArray<std::int8_t>(bc.shape);
  double* pf = fn.mutable_data();
  double* pm = mu.mutable_data();
  double* psd = sd.mutable_data();
  double* pi = instant.mutable_data();
  double* pr = min_risk.mutable_data();
  bool* pok = ok.mutable_data();
  bool* pe = extra.mutable_data();
  std::int8_t* ps = status.mutable_data();
  ForEachChecked<4>(bc, [&](py::ssize_t i, const double* x) {
    GripForceOptions o;
    o.hold_s = x[2];
    o.v_mm_s = x[3];
    const GripForce g = CalcGripForce(m, x[0], x[1], o);
    const double nan = std::nan("");
    pf[i] = g.attainable ? g.fn_n : nan;
    pm[i] = g.attainable ? g.mu_used : nan;
    psd[i] = g.attainable ? g.fn_n_sd : nan;
    pi[i] = g.attainable ? g.instant_risk : nan;
    pr[i] = g.min_supported_risk;
    pok[i] = g.attainable;
    pe[i] = g.extrapolated;
    ps[i] = static_cast<std::int8_t>(g.status);
  });
  return py::module_::import("frictiond._types")
      .attr("GripForce")(fn, mu, ok, extra, sd, instant, min_risk, status);
}

py::array_t<double> HoldSlipProbabilities(const Model& model,
                                          py::handle fn_n,
                                          py::handle load_n,
                                          py::handle hold_s,
                                          py::handle v_mm_s) {
  const StochasticFrictionModel& m = model.stochastic();
  const Broadcast bc = MakeBroadcast({{"fn_n", AsArray(fn_n, "fn_n")},
                                      {"load_n", AsArray(load_n, "load_n")},
                                      {"hold_s", AsArray(hold_s, "hold_s")},
                                      {"v_mm_s", AsArray(v_mm_s, "v_mm_s")}});
  auto out = NewArray<double>(bc.shape);
  double* po = out.mutable_data();
  ForEachChecked<4>(bc, [&](py::ssize_t i, const double* x) {
    GripForceOptions o;
    o.hold_s = x[2];
    o.v_mm_s = x[3];
    po[i] = CalcHoldSlipProbability(m, x[0], x[1], o);
  });
  return out;
}

std::vector<py::ssize_t> SizeShape(const py::object& size) {
  std::vector<py::ssize_t> shape;
  if (size.is_none()) return shape;
  if (py::isinstance<py::int_>(size)) {
    shape.push_back(size.cast<py::ssize_t>());
  } else {
    for (const py::handle& n : size) shape.push_back(n.cast<py::ssize_t>());
  }
  for (py::ssize_t n : shape)
    if (n < 0)
      throw py::value_error("size: negative dimension " + std::to_string(n));
  return shape;
}

py::array_t<double> SampleMu(const Model& model,
                             py::handle fn_n,
                             py::handle v_mm_s,
                             py::object rng,
                             py::object size) {
  const MuSampler& s = model.sampler();
  const Broadcast bc = MakeBroadcast(
      {{"fn_n", AsArray(fn_n, "fn_n")}, {"v_mm_s", AsArray(v_mm_s, "v_mm_s")}},
      SizeShape(size));
  auto out = NewArray<double>(bc.shape);
  double* po = out.mutable_data();
  GeneratorLease lease(std::move(rng));
  const UniformSource u = lease.source();
  {
    py::gil_scoped_release nogil;
    if (bc.AllScalar()) {
      double x[2];
      std::memcpy(&x[0], bc.operands[0].data, sizeof(double));
      std::memcpy(&x[1], bc.operands[1].data, sizeof(double));
      const double mean = s.CalcMean(x[0], x[1]);
      const double scale = s.CalcEpsScale(x[0], x[1]);  // 1: no eps scale
      for (py::ssize_t i = 0; i < bc.size; ++i)
        po[i] = mean + scale * s.CalcEpsQuantile(u());
    } else {
      ForEach<2>(bc, [&](py::ssize_t i, const double* x) {
        po[i] = s.Draw(x[0], x[1], u());
      });
    }
  }
  return out;
}

// A correlation argument: "model" (the model's value, or 0 without one),
// None (0) or a number.
double CorrelationArg(const py::object& arg,
                      const char* name,
                      std::optional<double> from_model) {
  if (arg.is_none()) return 0.0;
  if (py::isinstance<py::str>(arg)) {
    if (arg.cast<std::string>() != "model")
      throw py::value_error(std::string(name) + ": '" +
                            arg.cast<std::string>() +
                            "' (must be 'model', None or a number in [0, 1])");
    return from_model.value_or(0.0);
  }
  try {
    return arg.cast<double>();
  } catch (const py::cast_error&) {
    throw py::type_error(std::string(name) +
                         ": expected 'model', None or a number in [0, 1]");
  }
}

py::array_t<double> SampleMuEpisodesPy(const Model& model,
                                       int n_envs,
                                       int n_steps,
                                       py::handle fn_n,
                                       py::handle v_mm_s,
                                       py::object rng,
                                       py::object ar1,
                                       py::object offset_fraction,
                                       std::optional<double> dt_s) {
  const MuSampler& s = model.sampler();
  if (dt_s && !(*dt_s > 0 && std::isfinite(*dt_s)))
    throw py::value_error("dt_s = " + std::to_string(*dt_s) +
                          " (must be finite and > 0, or None)");
  const auto time = model.eps_time();
  // The model's phi is per sample of its data (time->dt_s); for a
  // simulation step dt_s the same continuous-time correlation gives
  // phi^(dt_s / data dt_s).
  std::optional<double> phi_model, f_model;
  if (time) {
    phi_model = dt_s && time->dt_s > 0 ? std::pow(time->phi, *dt_s / time->dt_s)
                                       : time->phi;
    f_model = time->offset_fraction;
  }
  EpisodeSampleOptions o;
  o.envs = n_envs;
  o.steps = n_steps;
  o.ar1 = CorrelationArg(ar1, "ar1", phi_model);
  o.offset_fraction =
      CorrelationArg(offset_fraction, "offset_fraction", f_model);
  std::string why;
  if (!o.IsValid(&why)) throw py::value_error(why);
  const Broadcast bc = MakeBroadcast(
      {{"fn_n", AsArray(fn_n, "fn_n")}, {"v_mm_s", AsArray(v_mm_s, "v_mm_s")}},
      {n_envs, n_steps});
  auto out = NewArray<double>(bc.shape);
  double* po = out.mutable_data();
  const StridedInput f{
      reinterpret_cast<const double*>(bc.operands[0].data),
      bc.operands[0].strides[0] / static_cast<py::ssize_t>(sizeof(double)),
      bc.operands[0].strides[1] / static_cast<py::ssize_t>(sizeof(double))};
  const StridedInput v{
      reinterpret_cast<const double*>(bc.operands[1].data),
      bc.operands[1].strides[0] / static_cast<py::ssize_t>(sizeof(double)),
      bc.operands[1].strides[1] / static_cast<py::ssize_t>(sizeof(double))};
  if (f.env_stride * 8 != bc.operands[0].strides[0] ||
      f.step_stride * 8 != bc.operands[0].strides[1] ||
      v.env_stride * 8 != bc.operands[1].strides[0] ||
      v.step_stride * 8 != bc.operands[1].strides[1])
    throw py::value_error("fn_n, v_mm_s: strides not a multiple of 8 bytes");
  GeneratorLease lease(std::move(rng));
  {
    py::gil_scoped_release nogil;
    SampleMuEpisodes(s, f, v, o, lease.source(), po);
  }
  return out;
}

// ---------------------------------------------------------------------------
// Client: one FrictionClient behind a mutex (it is thread-compatible, and
// calls run without the GIL).

class Client {
 public:
  Client(const std::string& url,
         const std::optional<std::string>& token,
         const std::optional<std::string>& cache_dir,
         const std::string& fingertip,
         const std::string& robot,
         double timeout_s) {
    ClientOptions o;
    o.base_url = url;
    o.token = token.value_or("");
    o.cache_dir = cache_dir.value_or("");
    o.fingertip = fingertip;
    o.robot = robot;
    o.timeout_s = timeout_s;
    if (!(timeout_s > 0))
      throw py::value_error("timeout_s = " + std::to_string(timeout_s) +
                            " (must be > 0)");
    client_ = std::make_unique<FrictionClient>(std::move(o));
  }

  py::list Materials() {
    std::vector<MaterialInfo> list =
        CallWithoutGil([&](FrictionClient& c) { return c.ListMaterials(); });
    py::list out;
    for (const MaterialInfo& m : list) {
      py::dict d;
      d["id"] = m.id;
      d["name"] = m.name;
      d["description"] = m.description;
      d["tags"] = m.tags;
      d["latest_version"] = m.latest_version
                                ? py::object(py::int_(*m.latest_version))
                                : py::object(py::none());
      out.append(d);
    }
    return out;
  }

  Model FetchModel(const std::string& material,
                   const std::string& fingertip,
                   std::optional<int> version) {
    if (version && !(*version > 0))
      throw py::value_error("version = " + std::to_string(*version) +
                            " (must be > 0, or None for the newest)");
    FetchResult r = CallWithoutGil([&](FrictionClient& c) {
      return c.FetchModelWithInfo(material, version.value_or(0), fingertip);
    });
    return Model(std::move(r.model), std::move(r.info));
  }

  py::object UploadCsv(
      const std::string& material,
      const std::string& csv,
      const std::vector<std::pair<std::string, std::string>>& params) {
    UploadReply r = CallWithoutGil([&](FrictionClient& c) {
      return c.UploadStrokes(material, csv, params);
    });
    return ToPython(r.body);
  }

  py::list Resync() {
    std::vector<ResyncEntry> list =
        CallWithoutGil([&](FrictionClient& c) { return c.Resync(); });
    py::list out;
    for (const ResyncEntry& e : list) {
      py::dict d;
      d["material"] = e.material;
      d["fingertip"] = e.fingertip;
      d["cached_version"] = e.cached_version;
      d["version"] = e.version;
      d["error"] = e.error;
      out.append(d);
    }
    return out;
  }

  py::object GetJson(const std::string& path) {
    nlohmann::json j =
        CallWithoutGil([&](FrictionClient& c) { return c.GetJson(path); });
    return ToPython(j);
  }

  const ClientOptions& options() const { return client_->options(); }

 private:
  // Runs f(client) without the GIL, one call at a time: FrictionClient is
  // not thread-safe, and other Python threads run while it waits on I/O.
  template <class F>
  std::invoke_result_t<F&, FrictionClient&> CallWithoutGil(F&& f) {
    py::gil_scoped_release nogil;
    std::lock_guard<std::mutex> lock(mu_);
    return f(*client_);
  }

  std::mutex mu_;
  std::unique_ptr<FrictionClient> client_;
};

Model ModelFromJson(const py::object& obj) {
  nlohmann::json j;
  try {
    j = FromPython(obj);
  } catch (const nlohmann::json::exception& e) {
    throw py::value_error(std::string("model JSON: ") + e.what());
  }
  FetchInfo info;
  info.source = "json";
  ModelSet set = ModelSetFromJson(j);  // invalid_argument -> ValueError
  info.version = set.version;
  return Model(std::move(set), std::move(info));
}

// ---------------------------------------------------------------------------
// Docstrings (units in brackets; shown by help() and IDEs).

constexpr const char* kPredictDoc =
    R"(Predicted friction coefficient at (fn_n, v_mm_s).

Paper 000 eq. (1): mu = b0 + b1*v + b2*Fn (+ the terms of an extended
model, whose other inputs take their fitted mean), with eps from its
empirical distribution. Evaluated by the C++ client library for every
element (MuSampler::CalcPrediction, equal bit for bit to PredictMu).

Args:
    fn_n: normal force [N]; a number or an array.
    v_mm_s: sliding speed [mm/s]; a number or an array broadcastable with
        fn_n.

Returns:
    Prediction(mu, sigma, lo95, hi95, extrapolated): arrays of the
    broadcast shape. mu is the mean coefficient [-], sigma its standard
    deviation including coefficient uncertainty [-], lo95/hi95 the 2.5 % and
    97.5 % quantiles [-], extrapolated True where an input lies outside the
    fitted range.

Raises:
    ValueError: the model has no stochastic family, or shapes do not
        broadcast.
)";

constexpr const char* kSlipDoc =
    R"(Likelihood of slip at normal force fn_n and tangential force ft_n.

The sigmoid L(Ft/Fn) = 1/(1 + exp(-c1 (Ft/Fn - c2))) of paper 000
section III-A when fitted, otherwise P(mu <= Ft/Fn) under the Fn-only
model's empirical eps. Evaluated by the C++ CalcSlipLikelihood.

Args:
    fn_n: normal force [N], > 0; a number or an array.
    ft_n: tangential force [N]; broadcastable with fn_n.

Returns:
    Array of probabilities in [0, 1] of the broadcast shape.
)";

constexpr const char* kHoldSlipDoc =
    R"(P(any slip during the hold) of a grasp at fn_n holding load_n.

The forward model of grip_force (C++ CalcHoldSlipProbability, element by
element): at fn_n = grip_force(load_n, risk, hold_s, v_mm_s).fn_n it
answers risk. Eq. (1) at v_mm_s with eps's identified time correlation;
the daemon's slip-likelihood route answers it when given v_mm_s or hold_s
(docs/grip_force.md). load_n = 0 answers 0.

Args:
    fn_n: normal force [N], finite and > 0.
    load_n: tangential load held [N], finite and >= 0.
    hold_s: duration of the hold [s], in [0, 3600]; > 0 needs the model's
        eps time model.
    v_mm_s: sliding speed of the grasp [mm/s], >= 0 (default 0: at rest).

Returns:
    Array of probabilities in [0, 1] of the broadcast shape.

Raises:
    ValueError: naming the element's index and the input.
)";

constexpr const char* kGripDoc =
    R"(Smallest normal force holding load_n with slip risk at most `risk`.

Paper 000 section IV-A, for a grasp held hold_s seconds at sliding speed
v_mm_s (C++ CalcGripForce with GripForceOptions, element by element): the
smallest Fn with P(slip at any time during the hold) <= risk under eq. (1)
with eps's identified time correlation (docs/grip_force.md). hold_s = 0 is
the risk at one instant.

Args:
    load_n: tangential load to hold [N], finite and > 0.
    risk: slip probability in (0, 1).
    hold_s: duration of the hold [s], in [0, 3600]; > 0 needs the model's
        eps time model (model.eps_time), else status "no_time_model".
    v_mm_s: sliding speed of the grasp [mm/s], >= 0 (0 = at rest).
    All four broadcast together.

Returns:
    GripForce(fn_n, mu_used, attainable, extrapolated, fn_n_sd,
    instant_risk, min_supported_risk, status): arrays of the broadcast
    shape. fn_n [N], its sd fn_n_sd [N] (coefficient covariance), mu_used
    [-] and instant_risk [-] are NaN where not attainable; status codes
    index GRIP_STATUS ("ok", "unattainable", "unsupported_risk": risk below
    min_supported_risk, the smallest the data support, "no_time_model");
    extrapolated is True where fn_n or v_mm_s lies outside the fitted range.

Raises:
    ValueError: a load_n, risk, hold_s or v_mm_s out of range (naming the
        element).
)";

constexpr const char* kSampleDoc =
    R"(Random draws of mu from the model's stochastic part.

mu = b0 + b1*v + b2*Fn + eps with eps drawn from its empirical
distribution (inverse CDF of the stored quantiles, C++ MuSampler; the
coefficients are not resampled).

Args:
    fn_n: normal force [N]; a number or an array.
    v_mm_s: sliding speed [mm/s]; broadcastable with fn_n.
    rng: a numpy.random.Generator (or BitGenerator), an int seed, or None
        for fresh entropy. A Generator is advanced exactly as
        rng.random(n) would be (one double per draw), so a seeded
        generator gives reproducible samples.
    size: output shape (int or tuple), as numpy's size=; fn_n and v_mm_s
        must broadcast to it. None: the broadcast shape of the inputs.

Returns:
    Array of mu [-] (float64).
)";

constexpr const char* kEpisodesDoc =
    R"(Domain randomisation: mu for n_envs parallel environments over n_steps.

Returns an (n_envs, n_steps) array; row i is one episode of environment i.
eps keeps the model's empirical distribution at every step; its time
structure is a Gaussian copula (C++ SampleMuEpisodes): with f =
offset_fraction and phi = ar1,
    z_t = sqrt(f) A + sqrt(1 - f) w_t,   A ~ N(0, 1) once per episode,
    w_t = phi w_(t-1) + sqrt(1 - phi^2) e_t,   w_0 ~ N(0, 1),
    eps_t = Q_eps(Phi(z_t)),
so the normal scores correlate as f + (1 - f) phi^k at lag k.

Args:
    n_envs: number of environments N, > 0.
    n_steps: steps per episode T, > 0.
    fn_n: normal force [N], broadcastable to (N, T) (a number, an (N, 1)
        column per environment, or a full array).
    v_mm_s: sliding speed [mm/s], broadcastable to (N, T).
    rng: numpy.random.Generator, BitGenerator, int seed or None (see
        sample_mu). The same seed gives the same array.
    ar1: step-to-step AR(1) coefficient in [0, 1]. "model" (default): the
        model's identified eps time correlation (eps_time) when it has one,
        converted to the step dt_s, else 0. None or 0: independent steps
        (then the result equals sample_mu(..., size=(N, T)) with the same
        seed); 1: w held for the whole episode.
    offset_fraction: f in [0, 1]. "model" (default): the model's
        per-episode offset share when it has one, else 0. 1 holds one draw
        per episode (per-episode randomisation).
    dt_s: simulation step [s], > 0. With "model" values the model's phi
        (per sample of its data, eps_time["dt_s"]) becomes
        phi ** (dt_s / eps_time["dt_s"]). None: one step per data sample.

Returns:
    float64 array of shape (n_envs, n_steps).
)";

}  // namespace
}  // namespace frictiond

PYBIND11_MODULE(_core, m) {
  using namespace frictiond;
  m.doc() =
      "Native part of the frictiond package (pybind11 over the C++ client "
      "library). Use the `frictiond` package, not this module.";

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ClientError& e) {
      RaiseDaemonError(e);
    }
  });

  py::class_<Model>(m, "Model")
      .def_static("from_json", &ModelFromJson, py::arg("model_json"))
      .def_property_readonly("material",
                             [](const Model& s) { return s.set().material; })
      .def_property_readonly("fingertip",
                             [](const Model& s) { return s.set().fingertip; })
      .def_property_readonly("version",
                             [](const Model& s) { return s.set().version; })
      .def_property_readonly("created_at",
                             [](const Model& s) { return s.set().created_at; })
      .def_property_readonly("source",
                             [](const Model& s) { return s.info().source; })
      .def_property_readonly("stale",
                             [](const Model& s) { return s.info().stale; })
      .def_property_readonly("fetched_at",
                             [](const Model& s) { return s.info().fetched_at; })
      .def_property_readonly(
          "daemon_error", [](const Model& s) { return s.info().daemon_error; })
      .def_property_readonly(
          "has_stochastic",
          [](const Model& s) { return s.set().stochastic.has_value(); })
      .def_property_readonly("eps_ar1", &Model::eps_ar1)
      .def_property_readonly("eps_time",
                             [](const Model& s) -> py::object {
                               const auto t = s.eps_time();
                               if (!t) return py::none();
                               py::dict d;
                               d["dt_s"] = t->dt_s;
                               d["phi"] = t->phi;
                               d["offset_fraction"] = t->offset_fraction;
                               return d;
                             })
      .def_property_readonly(
          "sigma_eps",
          [](const Model& s) { return s.stochastic().mu.sigma_eps; })
      .def_property_readonly(
          "coefficients",
          [](const Model& s) {
            const RegressionModel& r = s.stochastic().mu;
            py::dict d;
            for (std::size_t k = 0; k < r.terms.size(); ++k)
              d[py::str(r.terms[k].Name())] =
                  k < static_cast<std::size_t>(r.beta.size()) ? r.beta(k) : 0.0;
            return d;
          })
      .def_property_readonly("eps_levels",
                             [](const Model&) {
                               const auto& l = EpsQuantileLevels();
                               return py::array_t<double>(l.size(), l.data());
                             })
      .def_property_readonly("eps_quantiles",
                             [](const Model& s) {
                               const auto& q = s.stochastic().mu.eps_quantiles;
                               return py::array_t<double>(q.size(), q.data());
                             })
      .def("__repr__",
           [](const Model& s) {
             return "<frictiond.Model " + s.set().material +
                    " fingertip=" + s.set().fingertip +
                    " version=" + std::to_string(s.set().version) +
                    " source=" + s.info().source +
                    (s.info().stale ? " stale" : "") + ">";
           })
      .def("to_json",
           [](const Model& s) { return ToPython(ModelSetToJson(s.set())); })
      .def("predict", &Predict, py::arg("fn_n"), py::arg("v_mm_s"), kPredictDoc)
      .def("slip_likelihood",
           &SlipLikelihood,
           py::arg("fn_n"),
           py::arg("ft_n"),
           kSlipDoc)
      .def("hold_slip_probability",
           &HoldSlipProbabilities,
           py::arg("fn_n"),
           py::arg("load_n"),
           py::arg("hold_s") = 0.0,
           py::arg("v_mm_s") = 0.0,
           kHoldSlipDoc)
      .def("grip_force",
           &GripForces,
           py::arg("load_n"),
           py::arg("risk"),
           py::arg("hold_s") = 0.0,
           py::arg("v_mm_s") = 0.0,
           kGripDoc)
      .def("sample_mu",
           &SampleMu,
           py::arg("fn_n"),
           py::arg("v_mm_s"),
           py::arg("rng") = py::none(),
           py::arg("size") = py::none(),
           kSampleDoc)
      .def("sample_mu_episodes",
           &SampleMuEpisodesPy,
           py::arg("n_envs"),
           py::arg("n_steps"),
           py::arg("fn_n"),
           py::arg("v_mm_s"),
           py::arg("rng") = py::none(),
           py::arg("ar1") = py::str("model"),
           py::arg("offset_fraction") = py::str("model"),
           py::arg("dt_s") = py::none(),
           kEpisodesDoc)
      // Scalar references: the estimators' functions called once, for
      // tests that the vectorised calls equal them element-wise.
      .def("_predict_scalar",
           [](const Model& s, double fn_n, double v_mm_s) {
             const MuPrediction p = PredictMu(s.stochastic(), fn_n, v_mm_s);
             return py::make_tuple(
                 p.mu, p.sigma, p.lo95, p.hi95, p.extrapolated);
           })
      .def("_slip_likelihood_scalar",
           [](const Model& s, double fn_n, double ft_n) {
             return CalcSlipLikelihood(s.stochastic(), fn_n, ft_n);
           })
      .def(
          "_grip_force_scalar",
          [](const Model& s,
             double load_n,
             double risk,
             double hold_s,
             double v_mm_s) {
            GripForceOptions o;
            o.hold_s = hold_s;
            o.v_mm_s = v_mm_s;
            const GripForce g = CalcGripForce(s.stochastic(), load_n, risk, o);
            return py::make_tuple(g.attainable,
                                  g.fn_n,
                                  g.mu_used,
                                  g.extrapolated,
                                  g.why,
                                  g.fn_n_sd,
                                  g.instant_risk,
                                  g.min_supported_risk,
                                  static_cast<int>(g.status));
          },
          py::arg("load_n"),
          py::arg("risk"),
          py::arg("hold_s") = 0.0,
          py::arg("v_mm_s") = 0.0)
      .def("_eps_quantile_scalar", [](const Model& s, double p) {
        return CalcEpsQuantile(s.stochastic().mu, p);
      });

  py::class_<Client>(m, "_Client")
      .def(py::init<const std::string&,
                    const std::optional<std::string>&,
                    const std::optional<std::string>&,
                    const std::string&,
                    const std::string&,
                    double>(),
           py::arg("url"),
           py::arg("token") = py::none(),
           py::arg("cache_dir") = py::none(),
           py::arg("fingertip") = "default",
           py::arg("robot") = "",
           py::arg("timeout_s") = 5.0)
      .def_property_readonly(
          "url", [](const Client& c) { return c.options().base_url; })
      .def("__repr__",
           [](const Client& c) {
             return "<frictiond.Client " + c.options().base_url + ">";
           })
      .def("materials", &Client::Materials)
      .def("model",
           &Client::FetchModel,
           py::arg("id"),
           py::arg("fingertip") = "default",
           py::arg("version") = py::none())
      .def("_upload_csv",
           &Client::UploadCsv,
           py::arg("id"),
           py::arg("csv"),
           py::arg("params"))
      .def("resync", &Client::Resync)
      .def("get_json", &Client::GetJson, py::arg("path"));
}
