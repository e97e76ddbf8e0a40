#!/usr/bin/env python3
"""Benchmarks of the frictiond Python module (bench/run python_sample_mu
python_predict), each beside the same computation written in plain NumPy
from the model JSON, measured in the same run (CONTRACT.md "Benchmarks").

The model is the stochastic model of the bundled measured trace
(data/microtribo_recip), fitted offline by `friction fit --json`.

    python_sample_mu  draws of mu for N = 1e6 environments, each at its own
                      (Fn, v): the module's Model.sample_mu vs
                      mean(eq. 1) + np.interp(rng.random(N), levels, eps
                      quantiles); samples/s, ratio = module / NumPy.
    python_predict    Model.predict over N = 1e6 (Fn, v) pairs (mu, sigma,
                      95 % interval, extrapolation flags) vs the same
                      outputs in NumPy; ns per element, ratio = NumPy /
                      module.

Run by bench/run through the wrapper build/bench/python_module, which sets
PYTHONPATH to build/python and uses the interpreter the module was built
for.
"""

import json
import os
import subprocess
import sys
import time

import numpy as np

import frictiond

N = 1_000_000
REPEATS = 7


def best_time(fn):
    """Smallest CPU time of this thread over REPEATS calls [s] (after one
    warm-up call). Both sides run single-threaded on the calling thread (the
    module releases the GIL but starts no threads), so CPU time is their
    cost, and other processes on a shared machine do not skew the ratio."""
    fn()
    best = float("inf")
    for _ in range(REPEATS):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def line(name, value, unit, baseline, baseline_name, ratio, goal):
    print(json.dumps({"bench": name, "value": value, "unit": unit,
                      "baseline": baseline, "baseline_name": baseline_name,
                      "ratio": round(ratio, 3), "goal": goal}), flush=True)


def fit_model(root, bin_dir):
    csv = os.path.join(root, "data", "microtribo_recip", "test_data_2.strokes.csv")
    out = subprocess.run(
        [os.path.join(bin_dir, "friction"), "fit", csv, "--slip-peak-mm-s", "0.1",
         "--slip-floor-mm-s", "0.02", "--json"],
        check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def numpy_sample(j, fn, v, rng):
    """Plain NumPy from the model JSON: eq. (1) mean plus the empirical eps
    quantile at a uniform draw (linear between the stored quantiles)."""
    c = j["coefficients"]
    q = j["eps_quantiles"]
    mean = c["intercept"] + c["v_mm_s"] * v + c["fn_n"] * fn
    return mean + np.interp(rng.random(fn.shape), q["levels"], q["values"])


class NumpyPredict:
    """PredictMu in plain NumPy from the model JSON (eq. 1 terms intercept,
    v_mm_s, fn_n): mean, sigma with coefficient covariance, interval from
    the eps quantiles widened by sigma/sigma_eps, extrapolation flags."""

    def __init__(self, set_json):
        j = set_json["stochastic"]
        self.terms = j["covariance"]["terms"]
        self.beta = np.array([j["coefficients"][t] for t in self.terms])
        self.P = np.array(j["covariance"]["matrix"])
        self.s2 = j["sigma_eps"] ** 2
        q = j["eps_quantiles"]
        self.q_lo = np.interp(0.025, q["levels"], q["values"])
        self.q_hi = np.interp(0.975, q["levels"], q["values"])
        self.ranges = {k: (r["min"], r["max"]) for k, r in j["inputs"].items()} \
            if isinstance(j.get("inputs"), dict) else {}

    def __call__(self, fn, v):
        cols = {"intercept": np.ones_like(fn), "fn_n": fn, "v_mm_s": v}
        X = np.stack([cols[t] for t in self.terms], axis=-1)
        mu = X @ self.beta
        var = np.einsum("ij,jk,ik->i", X, self.P, X)
        sigma = np.sqrt(self.s2 + np.maximum(var, 0))
        widen = sigma / np.sqrt(self.s2)
        extra = np.zeros(fn.shape, dtype=bool)
        for name, x in (("fn_n", fn), ("v_mm_s", v)):
            if name in self.ranges:
                lo, hi = self.ranges[name]
                extra |= (x < lo) | (x > hi)
        return mu, sigma, mu + widen * self.q_lo, mu + widen * self.q_hi, extra


def main():
    root = os.environ.get("FRICTIOND_SOURCE_DIR",
                          os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
    bin_dir = os.environ.get("FRICTIOND_BIN_DIR", os.path.join(root, "build", "bin"))
    wanted = set(sys.argv[1:]) or {"python_sample_mu", "python_predict"}
    set_json = fit_model(root, bin_dir)
    model = frictiond.Model.from_json(set_json)
    j = set_json["stochastic"]

    inputs = np.random.default_rng(1)
    fn = inputs.uniform(4.9, 5.1, N)   # the trace's load: 5 N
    v = inputs.uniform(0.05, 0.5, N)   # its sliding speeds [mm/s]

    if "python_sample_mu" in wanted:
        # Same generator type and seed for both, so both draw the same u.
        np.testing.assert_allclose(
            model.sample_mu(fn[:1000], v[:1000], rng=np.random.default_rng(5)),
            numpy_sample(j, fn[:1000], v[:1000], np.random.default_rng(5)),
            rtol=1e-12, atol=1e-14)
        g1, g2 = np.random.default_rng(2), np.random.default_rng(2)
        t_mod = best_time(lambda: model.sample_mu(fn, v, rng=g1))
        t_np = best_time(lambda: numpy_sample(j, fn, v, g2))
        line("python_sample_mu", round(N / t_mod), "samples/s", round(N / t_np),
             "plain NumPy from the model JSON (eq. 1 + np.interp of rng.random)",
             t_np / t_mod, ">= 3x plain NumPy")

    if "python_predict" in wanted:
        ref = NumpyPredict(set_json)
        p = model.predict(fn[:1000], v[:1000])
        r = ref(fn[:1000], v[:1000])
        for a, b in zip(p, r):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
        t_mod = best_time(lambda: model.predict(fn, v))
        t_np = best_time(lambda: ref(fn, v))
        line("python_predict", round(t_mod / N * 1e9, 2), "ns/element",
             round(t_np / N * 1e9, 2),
             "plain NumPy PredictMu from the model JSON (mu, sigma, 95 % interval, flags)",
             t_np / t_mod, "report (per element)")


if __name__ == "__main__":
    main()
