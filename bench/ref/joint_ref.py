#!/usr/bin/python3
"""NumPy/SciPy reference for bench/joint_bench.cc (CONTRACT.md "Benchmarks").

Run with Debian's /usr/bin/python3 (python3-numpy, python3-scipy).

  joint_ref.py mixed --n N
      Mixed-lubrication friction of paper 002 at N joint states (speed,
      load, temperature drawn as in the C++ benchmark): Vogel viscosity,
      Sommerfeld number S = eta V / p, film d = d_ref (S/S_ref)^n, solid
      LOAD fraction alpha = min(1, K F_3/2((d - Alt)/SAlt) / W) (paper 002
      eqs. 6-7, issue 19), F_3/2 by the same 128-node Gauss-Legendre rule as
      frictiond's CalcSummitIntegrals and, for loads above the summits'
      Hertz capacity at the mean line, the film counted from the dry
      separation (Newton on ln F_3/2), f = alpha f_s + (1 - alpha) f_l,
      vectorised over all N states in chunks (NumPy's best case). Prints
      {"ns": median wall time per state, "checksum": sum f}.

  joint_ref.py grid --n N
      Repeatability ellipsoids of the 3R arm of bench/joint_bench.cc over an
      N x N grid of a 400 x 400 mm plane: damped-least-squares position IK
      warm-started along a serpentine path (same rule as frictiond's
      SolvePositionIk), position Jacobian, P_x = J P_q J^T, eigenvalues
      (numpy.linalg.eigh), semi-axes sqrt(chi2_3(0.95) lambda)
      (scipy.stats.chi2.ppf). Prints {"ms": median wall time per grid,
      "reachable": count, "max_axis_um": largest semi-axis}.
"""
import argparse
import json
import math
import time

import numpy as np
from scipy.stats import chi2

# Model constants shared with bench/joint_bench.cc.
F_S, F_L, D_REF, N_FILM = 0.1, 0.004, 0.5, 0.6
ALT, SALT, S_REF = 0.5, 0.15, 0.01
VOGEL_A, VOGEL_B, VOGEL_C = 7.39e-5, 902.5, 95.0
AREA_MM2 = 50.0
# Hertz summits (frictiond AsperitySurface defaults): N, E* [N/mm^2],
# SRAD [mm], radius log-sd a and log-mean b; K = N 4/3 E* E[sqrt R] SAlt^3/2.
N_SUMMITS, E_STAR_MPA, SRAD_MM, RAD_A, RAD_B = 400.0, 115.4e3, 0.02, 0.8, 0.0
K_N = (N_SUMMITS * 4.0 / 3.0 * E_STAR_MPA * math.sqrt(SRAD_MM) *
       math.exp(0.5 * RAD_B + 0.125 * RAD_A ** 2) * (SALT * 1e-3) ** 1.5)
GL_X, GL_W = np.polynomial.legendre.leggauss(8)
PANELS = 16
OFFS = (np.arange(PANELS)[:, None] + 0.5 + 0.5 * GL_X[None, :]).ravel()
WTS = np.tile(GL_W, PANELS)
CHUNK = 20000


def states(n):
    i = np.arange(n, dtype=float)
    # Deterministic states (same formula as the C++ side).
    v = 5.0 * 400.0 ** ((i * 0.6180339887) % 1.0)
    load = 20.0 + 180.0 * ((i * 0.7548776662) % 1.0)
    temp = 20.0 + 60.0 * ((i * 0.5698402910) % 1.0)
    return v, load, temp


def summit_integrals(lam):
    """F_1/2 and F_3/2 at each lambda: int 2 u^(2 nu + 1) phi(lam + u^2) du."""
    u2_lo = np.maximum(0.0, -lam - 9.5)
    u2_hi = np.where(lam <= 0, 9.5 - lam, -lam + np.sqrt(lam * lam + 90.0))
    u_lo = np.sqrt(u2_lo)
    h = (np.sqrt(u2_hi) - u_lo) / PANELS
    u = u_lo[:, None] + h[:, None] * OFFS[None, :]
    u2 = u * u
    s = lam[:, None] + u2
    w = WTS[None, :] * h[:, None] * (1.0 / math.sqrt(2.0 * math.pi)) * \
        np.exp(-0.5 * s * s)
    wu2 = w * u2
    return wu2.sum(axis=1), (wu2 * u2).sum(axis=1)


def alpha_chunk(d, load):
    cap = K_N * summit_integrals(np.array([-ALT / SALT]))[1][0]
    heavy = load > cap
    if np.any(heavy):
        target = load[heavy] / K_N
        lam = -target ** (2.0 / 3.0)
        for _ in range(40):  # Newton on the log-concave F_3/2
            f12, f32 = summit_integrals(lam)
            step = (np.log(f32) - np.log(target)) * f32 / (1.5 * f12)
            lam = lam + step
            if np.max(np.abs(step)) < 1e-13 * (1.0 + np.max(np.abs(lam))):
                break
        d = d.copy()
        d[heavy] += np.minimum(0.0, ALT + lam * SALT)
    f32 = summit_integrals((d - ALT) / SALT)[1]
    return np.minimum(1.0, K_N * f32 / load)


def mixed(v, load, temp):
    eta = VOGEL_A * np.exp(VOGEL_B / (temp + VOGEL_C))
    s_um = eta * (v * 1e-3) / (load / (AREA_MM2 * 1e-6)) * 1e6
    d = D_REF * (s_um / S_REF) ** N_FILM
    alpha = np.empty_like(d)
    for i in range(0, len(d), CHUNK):
        alpha[i:i + CHUNK] = alpha_chunk(d[i:i + CHUNK], load[i:i + CHUNK])
    return alpha * F_S + (1.0 - alpha) * F_L


def dh(theta, d, a, alpha):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


ARM = [(0.0, 300.0, 0.0, math.pi / 2), (0.0, 0.0, 400.0, 0.0), (0.0, 0.0, 350.0, 0.0)]
SD_Q = np.array([5.0 / 2e4] * 3)  # sigma_tau / stiffness [rad]


def fk_jac(q):
    t = np.eye(4)
    origins, axes = [], []
    for (th0, d, a, al), qi in zip(ARM, q):
        origins.append(t[:3, 3].copy())
        axes.append(t[:3, 2].copy())
        t = t @ dh(th0 + qi, d, a, al)
    tip = t[:3, 3]
    j = np.column_stack([np.cross(z, tip - o) for z, o in zip(axes, origins)])
    return tip, j


def ik(target, q0, tol=1e-6, iters=200):
    q = q0.copy()
    x, _ = fk_jac(q)
    err = target - x
    lam2 = 1e-4
    for _ in range(iters):
        if np.linalg.norm(err) <= tol:
            break
        _, j = fk_jac(q)
        jjt = j @ j.T
        scale = max(np.trace(jjt) / 3.0, 1e-12)
        qn = q + j.T @ np.linalg.solve(jjt + lam2 * scale * np.eye(3), err)
        xn, _ = fk_jac(qn)
        en = target - xn
        if np.linalg.norm(en) < np.linalg.norm(err):
            q, err = qn, en
            lam2 = max(lam2 / 10, 1e-12)
        else:
            lam2 *= 10
            if lam2 > 1e6:
                break
    return q, np.linalg.norm(err) <= tol


def grid(n):
    c2 = chi2.ppf(0.95, 3)
    q_start = np.array([0.0, 0.3, -1.0])
    q = q_start.copy()
    reach, biggest = 0, 0.0
    step = 400.0 / (n - 1)
    for iy in range(n):
        for k in range(n):
            ix = k if iy % 2 == 0 else n - 1 - k
            target = np.array([200.0 + step * ix, -200.0 + step * iy, 0.0])
            qs, ok = ik(target, q)
            if not ok:
                qs, ok = ik(target, q_start)
            if not ok:
                continue
            q = qs
            _, j = fk_jac(q)
            p = (j * SD_Q ** 2) @ j.T
            lam = np.linalg.eigh(p)[0]
            axes = np.sqrt(c2 * np.clip(lam, 0, None))
            reach += 1
            biggest = max(biggest, axes[-1] * 1e3)
    return reach, biggest


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["mixed", "grid"])
    ap.add_argument("--n", type=int, required=True)
    args = ap.parse_args()
    if args.what == "mixed":
        v, load, temp = states(args.n)
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            f = mixed(v, load, temp)
            times.append(time.perf_counter() - t0)
        print(json.dumps({"ns": float(np.median(times)) / args.n * 1e9,
                          "checksum": float(np.sum(f))}))
    else:
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            reach, biggest = grid(args.n)
            times.append(time.perf_counter() - t0)
        print(json.dumps({"ms": float(np.median(times)) * 1e3,
                          "reachable": reach, "max_axis_um": biggest}))


if __name__ == "__main__":
    main()
