#!/usr/bin/python3
"""NumPy/SciPy reference for bench/paper000_bench.cc (CONTRACT.md
"Benchmarks"). Run with Debian's /usr/bin/python3 (python3-numpy,
python3-scipy).

  paper000_ref.py ols --n N [--repeats R]
      Paper 000 eq. (1) by least squares on N simulated samples (same
      distribution as the C++ side: v ~ U(5, 80) mm/s, Fn ~ U(0.5, 4.5) N,
      mu = 0.9 + 0.004 v - 0.06 Fn + N(0, 0.05)): numpy.linalg.lstsq (its
      residual sum of squares, no residual vector), the residual sigma, R^2, F and its p-value (scipy.stats.f.sf), the
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
from scipy.ndimage import median_filter
from scipy.spatial import ConvexHull
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
        beta, ssr, rank, _ = np.linalg.lstsq(X, mu, rcond=None)
        k = X.shape[1]
        dof = n - rank
        # lstsq returns the residual sum of squares at full rank; the
        # residuals themselves are not formed (as FitOls without them).
        sse = float(ssr[0]) if ssr.size else float(((mu - X @ beta) ** 2).sum())
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


def _irls(ratio, slip, ridge=1e-6, iters=50):
    """Logistic MLE of L = 1/(1+exp(-c1 (r - c2))) by Newton/IRLS."""
    A = np.column_stack([np.ones_like(ratio), ratio])
    b = np.zeros(2)
    for _ in range(iters):
        p = expit(A @ b)
        w = p * (1.0 - p)
        H = A.T @ (A * w[:, None]) + ridge * np.eye(2)
        step = np.linalg.solve(H, A.T @ (slip - p))
        b += step
        if np.max(np.abs(step)) < 1e-10:
            break
    return b[1], -b[0] / b[1] if b[1] != 0 else math.nan


def _ols_stats(X, y):
    beta, _, rank, _ = np.linalg.lstsq(X, y, rcond=None)
    resid = y - X @ beta
    dof = len(y) - rank
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.pinv(X.T @ X)
    return beta, resid, np.sqrt(np.clip(np.diag(cov), 0, None))


def _hull_area(pts):
    if len(pts) < 3:
        return 0.0
    try:
        return ConvexHull(pts).volume
    except Exception:  # degenerate (collinear) hull
        return 0.0


def _eps_time(resid, episode, dt):
    """eps's AR(1) time model by lag-1/lag-2 moments within episodes
    (estimators/src/eps_time.cc)."""
    z = (resid - resid.mean()) / resid.std()
    same1 = episode[1:] == episode[:-1]
    same2 = same1[1:] & same1[:-1]
    g0 = np.mean(z * z)
    g1 = np.mean((z[:-1] * z[1:])[same1])
    g2 = np.mean((z[:-2] * z[2:])[same2])
    phi = np.clip((g1 - g2) / (g0 - g1), 0.0, 0.98) if g0 - g1 > 1e-9 else 0.0
    return phi, -dt / math.log(phi) if phi > 0 else 0.0


def _lugre_strokes(t, v, ft, fn, dt):
    """The LuGre stroke recognition (lugre_stroke_identification.cc): speed
    median-filtered over 0.05 s, rests at 5 % of the peak split strokes,
    each stroke's 95th percentile of |dv/dt| (least-squares slope over
    +-0.05 s) classifies it; mu signed by the motion."""
    k = int(np.clip(round(0.05 / dt), 1, 51)) | 1
    vf = median_filter(v, size=k, mode="nearest")
    moving = vf > 0.05 * vf.max()
    mu = ft / fn
    edges = np.diff(np.concatenate(([0], moving.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    h = max(2, int(round(0.05 / dt)))
    kinds = []
    for s, e in zip(starts, ends):
        if e - s < 20:
            continue
        tt, vv = t[s:e] - t[s], v[s:e]
        w = np.ones(2 * h + 1)
        m = np.convolve(np.ones_like(tt), w, "same")
        st, sv = np.convolve(tt, w, "same"), np.convolve(vv, w, "same")
        stt, stv = np.convolve(tt * tt, w, "same"), np.convolve(tt * vv, w, "same")
        den = m * stt - st * st
        slope = np.where(den > 0, (m * stv - st * sv) / np.where(den > 0, den, 1), 0)
        a = np.quantile(np.abs(slope), 0.95)
        kinds.append(0 if a <= 3.0 else (2 if a >= 5.0 else 1))
        _ = np.sign(vv) * mu[s:e]
    return kinds


def identify(csv, peak, floor, window_s, repeats):
    """Full identification of one material as frictiond does it: median
    filter + episode rule (II-C), stroke segmentation, eq. (1) and the
    Fn-only model with SEs and eps quantiles, the sigmoid likelihood and the
    conditional one of eq. (2) (0.2 N steps, 0.6 N windows), and the convex
    hull of the slipping (Fn, v) samples against the plan's reference span;
    then eps's AR(1) time model, the material hull with each stroke's share
    and the LuGre stroke recognition, as IdentifyMaterial does since."""
    d = np.genfromtxt(csv, delimiter=",", names=True)
    t, fn, ft, v = d["t_s"], d["fn_n"], d["ft_n"], d["v_mm_s"]
    # frictiond's EpsQuantileLevels(): the stored eps distribution.
    levels = np.array([0.001, 0.0025, 0.005, 0.0075] +
                      [k / 100.0 for k in range(1, 100)] +
                      [0.9925, 0.995, 0.9975, 0.999])
    times = []
    out = {}
    for _ in range(repeats):
        t0 = time.perf_counter()
        dt = np.median(np.diff(t)[np.diff(t) > 0])
        k = max(1, int(round(window_s / dt)))
        k += 1 - k % 2
        vf = median_filter(np.abs(v), size=k, mode="nearest")
        above = vf > floor
        edges = np.diff(np.concatenate(([0], above.astype(np.int8), [0])))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        slip = np.zeros(len(v), dtype=np.int8)
        if len(starts):
            peaks = np.maximum.reduceat(vf, starts)
            for s, e, pk in zip(starts, ends, peaks):
                if pk > peak:
                    slip[s:e] = 1
        stroke = np.cumsum(np.diff(slip, prepend=0) == -1)
        mask = slip == 1
        mu = ft / fn
        X = np.column_stack([np.ones(mask.sum()), v[mask], fn[mask]])
        beta, resid, se = _ols_stats(X, mu[mask])
        q = np.quantile(resid, levels)
        beta_fn, resid_fn, _ = _ols_stats(X[:, [0, 2]], mu[mask])
        q_fn = np.quantile(resid_fn, levels)
        ok = np.isfinite(mu)
        c1, c2 = _irls(mu[ok], slip[ok].astype(float))
        windows = []
        lo, hi = np.min(fn[ok]), np.max(fn[ok])
        for c in np.arange(np.floor(lo / 0.2) * 0.2, hi + 1e-9, 0.2):
            w = ok & (np.abs(fn - c) <= 0.3)
            n_slip = int(slip[w].sum())
            if w.sum() >= 40 and n_slip >= 5 and w.sum() - n_slip >= 5:
                c1_w, c2_w = _irls(mu[w], slip[w].astype(float))
                if c1_w > 0:  # a knot only where L rises with Ft/Fn
                    windows.append((c, c1_w, c2_w))
        pts = np.column_stack([np.clip(fn[mask], 0.5, 4.5),
                               np.clip(v[mask], 15.0, 80.0)])
        try:
            area = ConvexHull(pts).volume if len(pts) >= 3 else 0.0
        except Exception:  # degenerate (collinear) hull
            area = 0.0
        span_pct = 100.0 * area / ((4.5 - 0.5) * (80.0 - 15.0))
        # Steps the daemon's identification gained since this reference was
        # written (issues 18, 19, 17): eps's AR(1) time model, the hull of
        # the material's slipping samples with each stroke's share of it
        # (paper 000 III-C-2), and the LuGre stroke recognition.
        sl_idx = np.flatnonzero(mask)
        episode = np.cumsum(np.concatenate(([0], np.diff(sl_idx) != 1)))
        phi, corr_s = _eps_time(resid, episode, dt)
        raw = np.column_stack([fn[mask], v[mask]])
        material_area = _hull_area(raw)
        st = stroke[mask]
        bounds = np.flatnonzero(np.diff(st)) + 1
        shares = [100.0 * _hull_area(p) / material_area if material_area > 0 else 0.0
                  for p in np.split(raw, bounds)]
        kinds = _lugre_strokes(t, v, ft, fn, dt)
        times.append(time.perf_counter() - t0)
        out = {"beta": [float(b) for b in beta], "strokes": int(stroke[-1]) + 1,
               "slip": int(mask.sum()), "c1": float(c1), "c2": float(c2),
               "windows": len(windows), "span_pct": span_pct,
               "eps_q50": float(q[53]), "eps_fn_q50": float(q_fn[53]), "se": [float(x) for x in se],
               "beta_fn": [float(b) for b in beta_fn], "eps_phi": float(phi),
               "stroke_hulls": len(shares), "lugre_strokes": len(kinds)}
    out["ms"] = 1e3 * float(np.median(times))
    print(json.dumps(out))


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("ols")
    a.add_argument("--n", type=int, required=True)
    a.add_argument("--repeats", type=int, default=5)
    b = sub.add_parser("likelihood")
    b.add_argument("--n", type=int, required=True)
    c = sub.add_parser("identify")
    c.add_argument("--csv", required=True)
    c.add_argument("--peak", type=float, required=True)
    c.add_argument("--floor", type=float, required=True)
    c.add_argument("--window-s", type=float, required=True)
    c.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    if args.cmd == "ols":
        ols(args.n, args.repeats)
    elif args.cmd == "identify":
        identify(args.csv, args.peak, args.floor, args.window_s, args.repeats)
    else:
        likelihood(args.n)


if __name__ == "__main__":
    main()
