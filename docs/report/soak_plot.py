#!/usr/bin/env python3
"""Plots RSS over time from a `neural-cloth soak` CSV: soak_plot.py soak.csv out.svg"""
import csv, sys

rows = [r for r in csv.DictReader(open(sys.argv[1]))]
t = [float(r["elapsed_min"]) for r in rows]
m = [float(r["rss_mb"]) for r in rows]
W, H, L, R, T, B = 640, 300, 60, 20, 20, 40
tmax = max(t[-1], 1.0)
ymax = max(m) * 1.1
x = lambda v: L + v / tmax * (W - L - R)
y = lambda v: H - B - v / ymax * (H - T - B)
out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="11">',
       f'<rect width="{W}" height="{H}" fill="white"/>']
step = 10 if tmax <= 150 else 20
for k in range(0, int(tmax) + 1, step):
    out.append(f'<line x1="{x(k):.1f}" y1="{T}" x2="{x(k):.1f}" y2="{H-B}" stroke="#ddd"/>'
               f'<text x="{x(k):.1f}" y="{H-B+14}" text-anchor="middle">{k}</text>')
for k in range(0, int(ymax) + 1, 200):
    out.append(f'<line x1="{L}" y1="{y(k):.1f}" x2="{W-R}" y2="{y(k):.1f}" stroke="#ddd"/>'
               f'<text x="{L-4}" y="{y(k)+4:.1f}" text-anchor="end">{k}</text>')
warm = [v for s, v in zip(t, m) if s >= 10.0]
if warm:
    for f, dash in ((1.0, ""), (1.05, ' stroke-dasharray="4 3"')):
        out.append(f'<line x1="{x(10):.1f}" y1="{y(warm[0]*f):.1f}" x2="{W-R}" y2="{y(warm[0]*f):.1f}" stroke="#c33"{dash}/>')
    out.append(f'<text x="{W-R}" y="{y(warm[0]*1.05)-4:.1f}" text-anchor="end" fill="#c33">+5 % of RSS at 10 min</text>')
pts = " ".join(f"{x(a):.1f},{y(b):.1f}" for a, b in zip(t, m))
out.append(f'<polyline points="{pts}" fill="none" stroke="#236" stroke-width="1.5"/>')
out.append(f'<text x="{(L+W-R)/2}" y="{H-6}" text-anchor="middle">minutes</text>')
out.append(f'<text x="14" y="{(T+H-B)/2}" text-anchor="middle" transform="rotate(-90 14 {(T+H-B)/2})">resident memory, MiB</text>')
out.append("</svg>")
open(sys.argv[2], "w").write("\n".join(out) + "\n")
