#!/usr/bin/python3
"""NumPy reference for bench/actuator_bench.cc (CONTRACT.md "Benchmarks").

Run with Debian's /usr/bin/python3 (python3-numpy).

  actuator_ref.py rollout --log LOG.json --params PARAMS.json [--reps N]
      Closed-loop rollout of the servo + pendulum of docs/actuator.md with a
      Coulomb-viscous friction budget (BAM M1 parameter file): controller
      duty = clip(kp g_e (goal - q), -1, 1), DC motor with back-EMF, gravity,
      stopping torque clipped to the budget, semi-implicit Euler; the same
      arithmetic as frictiond's SimulateActuatorLog. The loop is sequential
      (each step needs the previous state), so it runs step by step over
      NumPy arrays. Prints {"ms": median wall time per rollout, "mae_rad":
      mean |q_sim - q|}.
"""
import argparse
import json
import math
import time

import numpy as np

ERROR_GAIN = (4096 / (2 * np.pi)) / (256 * 885)
G = 9.81


def rollout(log, p):
    e = log["entries"]
    t = np.array([x["timestamp"] for x in e])
    q_meas = np.array([x["position"] for x in e])
    goal = np.array([x["goal_position"] for x in e])
    enable = np.array([bool(x["torque_enable"]) for x in e])
    speed = np.array([x.get("speed", 0.0) for x in e])
    dt = log.get("dt", float(np.median(np.diff(t))))
    m, l, kp, vin = log["mass"], log["length"], log["kp"], log["vin"]
    kt, r, arm = p["kt"], p["R"], p["armature"]
    q_off = p.get("q_offset", 0.0)
    fc, fv = p.get("friction_base", 0.0), p.get("friction_viscous", 0.0)
    inertia = m * l * l + arm
    mgl = m * G * l
    gain = kp * ERROR_GAIN
    q, dq = float(q_meas[0]), float(speed[0])
    q_sim = np.empty(len(e))
    for k in range(len(e)):
        q_sim[k] = q
        duty = np.clip(gain * (goal[k] - q), -1.0, 1.0)
        tau_m = kt * (vin * duty - kt * dq) / r if enable[k] else 0.0
        tau_e = -mgl * np.sin(q + q_off)
        net = tau_m + tau_e
        tau_stop = inertia / dt * dq + net
        limit = fc + fv * abs(dq)
        tau_f = -np.sign(tau_stop) * min(abs(tau_stop), limit)
        dq += (net + tau_f) / inertia * dt
        q += dq * dt
    return float(np.mean(np.abs(q_sim - q_meas)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["rollout"])
    ap.add_argument("--log", required=True)
    ap.add_argument("--params", required=True)
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    with open(a.log) as f:
        log = json.load(f)
    with open(a.params) as f:
        p = json.load(f)
    times = []
    mae = 0.0
    for _ in range(a.reps):
        t0 = time.perf_counter()
        mae = rollout(log, p)
        times.append((time.perf_counter() - t0) * 1e3)
    print(json.dumps({"ms": float(np.median(times)), "mae_rad": mae}))


if __name__ == "__main__":
    main()
