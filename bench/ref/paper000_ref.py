#!/usr/bin/python3
"""NumPy/SciPy reference for bench/paper000_bench.cc (CONTRACT.md
"Benchmarks"). Run with Debian's /usr/bin/python3 (python3-numpy,
python3-scipy).

  paper000_ref.py ols --n N [--repeats R]
      Paper 000 eq. (1) by least squares on N simulated samples (same
      distribution as the C++ side: v ~ U(5, 80) mm/s, Fn ~ U(0.5, 4.5) N,
      mu = 0.9 + 0.004 v - 0.06 Fn + N(0, 0.05)): numpy.linalg.lstsq, the
      residual sigma, R^2, F and its p-value (scipy.stats.f.sf), the
      coefficient covariance and standard errors -- what frictiond's FitOls
      returns. Timed from the arrays in memory to the results.
      Prints {"ms": median wall time, "beta": [...]}.

  paper000_ref.py likelihood --n N
      Sigmoid slip likelihood L = 1/(1+exp(-c1 (Ft/Fn - c2))) (paper 000,
      III-A) at N (Fn, Ft) points: vectorised with scipy.special.expit
      ("ns_vector", per point), and one Python call per point with math.exp
      ("ns_scalar", on N/100 points).
      Prints {"ns_vector": ..., "ns_scalar": ...}.
"""
import argparse
import json
import math
import time

import numpy as np
from scipy import stats
from scipy.special import expit


def ols(n, repeats):
    rng = np.random.default_rng(1)
    v = rng.uniform(5.0, 80.0, n)
    fn = rng.uniform(0.5, 4.5, n)
    mu = 0.9 + 0.004 * v - 0.06 * fn + rng.normal(0.0, 0.05, n)
    X = np.column_stack([np.ones(n), v, fn])
    times = []
    beta = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        beta, _, rank, _ = np.linalg.lstsq(X, mu, rcond=None)
        resid = mu - X @ beta
        k = X.shape[1]
        dof = n - rank
        sse = float(resid @ resid)
        sst = float(((mu - mu.mean()) ** 2).sum())
        r2 = 1.0 - sse / sst
        sigma2 = sse / dof
        cov = sigma2 * np.linalg.inv(X.T @ X)
        se = np.sqrt(np.diag(cov))
        f = ((sst - sse) / (k - 1)) / sigma2
        p = stats.f.sf(f, k - 1, dof)
        times.append(time.perf_counter() - t0)
        _ = (r2, se, p)
    print(json.dumps({"ms": 1e3 * float(np.median(times)),
                      "beta": [float(b) for b in beta]}))


def likelihood(n):
    rng = np.random.default_rng(2)
    fn = rng.uniform(0.5, 4.5, n)
    ft = fn * rng.uniform(0.2, 1.6, n)
    c1, c2 = 12.0, 0.85
    best = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        p = expit(c1 * (ft / fn - c2))
        best = min(best, time.perf_counter() - t0)
    _ = p.sum()
    m = max(1, n // 100)
    fl, tl = fn[:m].tolist(), ft[:m].tolist()
    t0 = time.perf_counter()
    s = 0.0
    for a, b in zip(fl, tl):
        s += 1.0 / (1.0 + math.exp(-c1 * (b / a - c2)))
    scalar = time.perf_counter() - t0
    print(json.dumps({"ns_vector": 1e9 * best / n, "ns_scalar": 1e9 * scalar / m}))


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("ols")
    a.add_argument("--n", type=int, required=True)
    a.add_argument("--repeats", type=int, default=5)
    b = sub.add_parser("likelihood")
    b.add_argument("--n", type=int, required=True)
    args = ap.parse_args()
    if args.cmd == "ols":
        ols(args.n, args.repeats)
    else:
        likelihood(args.n)


if __name__ == "__main__":
    main()
