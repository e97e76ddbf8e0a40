#!/usr/bin/env python3
"""Plot of docs/mujoco.md "Drop rates end to end": drop frequency vs the
requested risk, from the CSV that drop_rate_e2e_test writes with
FRICTIOND_DROP_RATE_CSV=path (committed as docs/mujoco_drop_rate.csv).
Writes the SVG directly (no matplotlib):

    python3 docs/mujoco_drop_rate.py docs/mujoco_drop_rate.csv \
        docs/mujoco_drop_rate.svg
"""
import csv
import math
import sys

W, H = 760, 460
L, R, T, B = 80, 270, 30, 60  # margins
X0, X1 = 0.008, 0.4  # risk axis (log)
Y0, Y1 = 0.003, 1.0  # drop frequency axis (log); 0 drawn at the bottom


def px(r):
    return L + (math.log(r) - math.log(X0)) / (math.log(X1) - math.log(X0)) * (W - L - R)


def py(f):
    f = max(f, Y0)
    return H - B - (math.log(f) - math.log(Y0)) / (math.log(Y1) - math.log(Y0)) * (H - T - B)


def main(src, dst):
    rows = list(csv.DictReader(open(src)))
    risk = [float(r["risk"]) for r in rows]
    series = [
        ("truth's model (its own grip force)", "#1f77b4", "circle",
         [int(r["drops_truth"]) / int(r["episodes_truth"]) for r in rows]),
    ]
    if "crossings_truth" in rows[0]:
        series.append(
            ("truth: eps below the slip level", "#1f77b4", "ring",
             [int(r["crossings_truth"]) / int(r["episodes_truth"]) for r in rows]))
    series += [
        ("identified by the daemon (end to end)", "#d62728", "square",
         [int(r["drops_served"]) / int(r["episodes"]) for r in rows]),
        ("Coulomb, served mean mu", "#2ca02c", "triangle",
         [int(r["drops_coulomb"]) / int(r["coulomb_episodes"]) for r in rows]),
        ("MuJoCo default friction (1)", "#7f7f7f", "diamond",
         [int(r["drops_default"]) / int(r["coulomb_episodes"]) for r in rows]),
    ]
    o = []
    o.append(f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
             f'font-family="sans-serif" font-size="12">')
    o.append(f'<rect width="{W}" height="{H}" fill="white"/>')
    # factor-1.5 band and the identity
    band = [(X0, X0 / 1.5), (X1, X1 / 1.5), (X1, min(X1 * 1.5, Y1)), (Y1 / 1.5, Y1), (X0, X0 * 1.5)]
    o.append('<polygon fill="#f4e4c8" points="' +
             " ".join(f"{px(x):.1f},{py(y):.1f}" for x, y in band) + '"/>')
    o.append(f'<line x1="{px(X0):.1f}" y1="{py(X0):.1f}" x2="{px(X1):.1f}" y2="{py(X1):.1f}" '
             'stroke="black" stroke-dasharray="4,3"/>')
    # axes and ticks
    o.append(f'<rect x="{L}" y="{T}" width="{W - L - R}" height="{H - T - B}" '
             'fill="none" stroke="black"/>')
    for r in (0.01, 0.02, 0.05, 0.1, 0.2, 0.3):
        o.append(f'<line x1="{px(r):.1f}" y1="{H - B}" x2="{px(r):.1f}" y2="{H - B + 5}" stroke="black"/>')
        o.append(f'<text x="{px(r):.1f}" y="{H - B + 18}" text-anchor="middle">{r:g}</text>')
    for f in (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0):
        o.append(f'<line x1="{L - 5}" y1="{py(f):.1f}" x2="{L}" y2="{py(f):.1f}" stroke="black"/>')
        o.append(f'<text x="{L - 8}" y="{py(f) + 4:.1f}" text-anchor="end">{f:g}</text>')
    o.append(f'<text x="{L - 8}" y="{py(Y0) + 4:.1f}" text-anchor="end">0</text>')
    o.append(f'<text x="{(L + W - R) / 2:.0f}" y="{H - 18}" text-anchor="middle">'
             'requested risk r (two-contact pinch, 0.5 s hold)</text>')
    o.append(f'<text transform="translate(20,{(T + H - B) / 2:.0f}) rotate(-90)" '
             'text-anchor="middle">frequency per hold (log; 0 at the bottom)</text>')

    def marker(kind, x, y, c):
        if kind == "ring":
            return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="5" fill="none" stroke="{c}" stroke-width="1.5"/>'
        if kind == "circle":
            return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{c}"/>'
        if kind == "square":
            return f'<rect x="{x - 4:.1f}" y="{y - 4:.1f}" width="8" height="8" fill="{c}"/>'
        if kind == "triangle":
            return f'<polygon points="{x:.1f},{y - 5:.1f} {x - 5:.1f},{y + 4:.1f} {x + 5:.1f},{y + 4:.1f}" fill="{c}"/>'
        return f'<polygon points="{x:.1f},{y - 5:.1f} {x + 5:.1f},{y:.1f} {x:.1f},{y + 5:.1f} {x - 5:.1f},{y:.1f}" fill="{c}"/>'

    for i, (name, c, kind, freq) in enumerate(series):
        dy = {"triangle": -3, "diamond": 3}.get(kind, 0)  # separate overlaps at 0
        pts = " ".join(f"{px(r):.1f},{py(f) + dy:.1f}" for r, f in zip(risk, freq))
        dash = ' stroke-dasharray="2,2"' if kind == "ring" else ""
        o.append(f'<polyline fill="none" stroke="{c}" stroke-width="1.5"{dash} points="{pts}"/>')
        for r, f in zip(risk, freq):
            o.append(marker(kind, px(r), py(f) + dy, c))
        ly = T + 20 + 22 * i
        o.append(marker(kind, W - R + 15, ly, c))
        o.append(f'<text x="{W - R + 25}" y="{ly + 4}" font-size="11">{name}</text>')
    ly = T + 20 + 22 * len(series)
    o.append(f'<line x1="{W - R + 8}" y1="{ly}" x2="{W - R + 22}" y2="{ly}" stroke="black" stroke-dasharray="4,3"/>')
    o.append(f'<text x="{W - R + 25}" y="{ly + 4}" font-size="11">drops = r</text>')
    o.append(f'<rect x="{W - R + 8}" y="{ly + 14}" width="14" height="10" fill="#f4e4c8"/>')
    o.append(f'<text x="{W - R + 25}" y="{ly + 23}" font-size="11">within a factor 1.5</text>')
    o.append("</svg>")
    open(dst, "w").write("\n".join(o) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
