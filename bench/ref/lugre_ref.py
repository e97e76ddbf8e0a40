#!/usr/bin/python3
"""SciPy reference for bench/lugre_bench.cc (CONTRACT.md "Benchmarks").

Run with Debian's /usr/bin/python3 (python3-numpy, python3-scipy).

  lugre_ref.py identify CSV [--repeats N]
      Two-step LuGre identification (paper 001) of the two-stroke dataset in
      CSV (columns stroke,t_s,v_mm_s,mu; stroke 0 = low-acceleration,
      1 = high-acceleration) with scipy.optimize.least_squares, on the same
      residual models as frictiond's FitLuGreQuasiStatic (binned eq. 4) and
      FitLuGreDynamic LM-2 (exact-exponential bristle step, eq. 9 at the
      samples), from the same starts and within the same bounds.
      Prints {"ms": median wall time per identification, "theta": [...],
      "nfev": [...]}.

  lugre_ref.py breakaway --theta a,b,c,d,e,f --fn-n F --mass-kg M --rates r,..
      Force-driven LuGre ODE (paper 001 eqs. 16-20) from rest with
      scipy.integrate.solve_ivp (LSODA, analytic Jacobian, rtol 1e-3,
      atol 1e-6 as Table II) until v > 2 v0 (terminal event); BF-ratio = the
      largest friction ratio at the accepted steps, as frictiond does.
      Prints {"us": mean wall time per prediction, "bf": [...]}.
"""
import argparse
import json
import math
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares


# ------------------------------------------------------------- model pieces

def stribeck(p, v):
    mu_s, mu_c, v0 = p[0], p[1], p[2]
    return mu_c + (mu_s - mu_c) * math.exp(-(v / v0) ** 2)


def bin_quasi_static(v, mu, min_speed_fraction=0.03, bins=50):
    """Fold onto |v|, drop the slowest samples, average in speed bins."""
    speed = np.abs(v)
    v_max = speed.max()
    v_min = min_speed_fraction * v_max
    keep = speed > v_min
    speed, ratio = speed[keep], np.where(v[keep] > 0, mu[keep], -mu[keep])
    width = (v_max - v_min) / bins
    b = np.clip(((speed - v_min) / width).astype(int), 0, bins - 1)
    count = np.bincount(b, minlength=bins).astype(float)
    sum_v = np.bincount(b, weights=speed, minlength=bins)
    sum_mu = np.bincount(b, weights=ratio, minlength=bins)
    filled = count > 0
    return (sum_v[filled] / count[filled], sum_mu[filled] / count[filled],
            np.sqrt(count[filled]))


def fit_quasi_static(v, mu, start):
    speed, ratio, weight = bin_quasi_static(v, mu)

    def residual(p):
        mu_s, mu_c, v0, s2 = p
        e = np.exp(-(speed / v0) ** 2)
        return weight * (mu_c + (mu_s - mu_c) * e + s2 * speed - ratio)

    def jacobian(p):
        mu_s, mu_c, v0, s2 = p
        e = np.exp(-(speed / v0) ** 2)
        d_v0 = (mu_s - mu_c) * e * 2.0 * speed ** 2 / v0 ** 3
        return weight[:, None] * np.column_stack((e, 1.0 - e, d_v0, speed))

    return least_squares(residual, start, jac=jacobian,
                         bounds=([1e-4, 1e-4, 1e-4, -1.0],
                                 [10.0, 10.0, 1e4, 1.0]),
                         method="trf", x_scale="jac", ftol=1e-10, xtol=1e-10)


def discrete_response(p_qs, s0, s1, z0, t, v):
    """mu at the samples: z by the exact step for the midpoint velocity."""
    mu_s, mu_c, v0, s2 = p_qs
    out = [0.0] * len(t)
    z = z0
    for k in range(len(t)):
        if k > 0:
            vm = 0.5 * (v[k - 1] + v[k])
            if vm != 0.0:
                g = mu_c + (mu_s - mu_c) * math.exp(-(vm / v0) ** 2)
                a = s0 * abs(vm) / g
                zss = math.copysign(g / s0, vm)
                z = zss + (z - zss) * math.exp(-a * (t[k] - t[k - 1]))
        vk = v[k]
        g = mu_c + (mu_s - mu_c) * math.exp(-(vk / v0) ** 2)
        zdot = vk - s0 * abs(vk) * z / g
        out[k] = s0 * z + s1 * zdot + s2 * vk
    return out


def fit_dynamic(p_qs, t, v, mu, start):
    t_list, v_list = list(t), list(v)

    def residual(x):
        return np.asarray(discrete_response(p_qs, x[0], x[1], x[2], t_list,
                                            v_list)) - mu

    return least_squares(residual, start, jac="2-point",
                         bounds=([1e-3, 0.0, -10.0], [1e6, 1e3, 10.0]),
                         method="trf", x_scale="jac", ftol=1e-10, xtol=1e-10)


def identify(path, repeats):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    slow, fast = data[data[:, 0] == 0], data[data[:, 0] == 1]
    times, theta, nfev = [], None, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        qs = fit_quasi_static(slow[:, 2], slow[:, 3],
                              np.array([0.3, 0.2, 1.0, 0.0]))
        dyn = fit_dynamic(qs.x, fast[:, 1], fast[:, 2], fast[:, 3],
                          np.array([10.0, 0.01, 0.0]))
        times.append(1e3 * (time.perf_counter() - t0))
        theta = list(qs.x) + list(dyn.x[:2])
        nfev = [int(qs.nfev), int(dyn.nfev)]
    times.sort()
    return {"ms": times[len(times) // 2], "theta": theta, "nfev": nfev}


# ------------------------------------------------------------- break-away

def predict_breakaway(theta, rho, fn_n, mass_kg):
    mu_s, mu_c, v0, s2, s0, s1 = theta
    k_acc = 1000.0 * fn_n / mass_kg

    def parts(v, z):
        e = math.exp(-(v / v0) ** 2)
        g = mu_c + (mu_s - mu_c) * e
        zdot = v - s0 * abs(v) * z / g
        return e, g, zdot, s0 * z + s1 * zdot + s2 * v

    def rhs(t, y):
        _, _, zdot, mu_f = parts(y[0], y[1])
        return [k_acc * (rho * t - mu_f), zdot]

    def jac(t, y):
        v, z = y
        e, g, _, _ = parts(v, z)
        sv = math.copysign(1.0, v) if v != 0 else 0.0
        dg_dv = (mu_s - mu_c) * e * (-2.0 * v / v0 ** 2)
        dzdot_dv = 1.0 - s0 * z * (sv * g - abs(v) * dg_dv) / g ** 2
        dzdot_dz = -s0 * abs(v) / g
        dmu_dv = s1 * dzdot_dv + s2
        dmu_dz = s0 + s1 * dzdot_dz
        return [[-k_acc * dmu_dv, -k_acc * dmu_dz], [dzdot_dv, dzdot_dz]]

    def breakaway(t, y):
        return y[0] - 2.0 * v0
    breakaway.terminal = True
    breakaway.direction = 1

    sol = solve_ivp(rhs, (0.0, 50.0), [0.0, 0.0], method="LSODA", jac=jac,
                    rtol=1e-3, atol=1e-6, events=breakaway)
    if sol.status != 1:
        return float("nan")
    return max(parts(v, z)[3] for v, z in zip(sol.y[0], sol.y[1]))


def breakaway_bench(theta, fn_n, mass_kg, rates):
    bf = []
    t0 = time.perf_counter()
    for rho in rates:
        bf.append(predict_breakaway(theta, rho, fn_n, mass_kg))
    us = 1e6 * (time.perf_counter() - t0) / len(rates)
    return {"us": us, "bf": bf}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p_id = sub.add_parser("identify")
    p_id.add_argument("csv")
    p_id.add_argument("--repeats", type=int, default=3)
    p_bf = sub.add_parser("breakaway")
    p_bf.add_argument("--theta", required=True)
    p_bf.add_argument("--fn-n", type=float, required=True)
    p_bf.add_argument("--mass-kg", type=float, default=0.2)
    p_bf.add_argument("--rates", required=True)
    args = parser.parse_args()
    if args.cmd == "identify":
        out = identify(args.csv, args.repeats)
    else:
        theta = [float(x) for x in args.theta.split(",")]
        rates = [float(x) for x in args.rates.split(",")]
        out = breakaway_bench(theta, args.fn_n, args.mass_kg, rates)
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
