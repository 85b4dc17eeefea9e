#!/usr/bin/env python3
"""Where a trained garment is strained more than the simulator's, frame by frame.

Reads three PC2 caches of the same motion and garment: the network's frames
(`neural-cloth bake RUN --motion M --out net.pc2`), the simulator's and its quasi-static
drape (the reference cache `compare` writes into RUN/reference/, `NAME.pc2` and
`NAME.static.pc2`), and one OBJ frame of the garment for its edges (`bake --format obj
--end 1`). Prints, over the moving frames (from `--from`, default 30), each cache's edge
strain against the first quasi-static frame: mean, mean absolute value, mean square; the
mean square split into the part that persists over the frames (a held shape) and the part
that varies; by height band and sleeves against torso; and the mean rotation of the best
rigid fit of each frame onto the quasi-static drape. Needs numpy (not a project dependency:
an analysis aid for docs/TRAINING.md round 29).

usage: edge_strain.py NET.pc2 REFERENCE_BASE OBJ [--from N]
"""
import struct
import sys

import numpy as np


def read_pc2(path):
    raw = open(path, "rb").read()
    vertices = struct.unpack("<i", raw[16:20])[0]
    samples = struct.unpack("<i", raw[28:32])[0]
    data = np.frombuffer(raw[32 : 32 + samples * vertices * 12], dtype="<f4")
    return data.reshape(samples, vertices, 3).astype(np.float64)


def edges_of(obj_path):
    faces = [
        [int(t.split("/")[0]) - 1 for t in line.split()[1:4]]
        for line in open(obj_path)
        if line.startswith("f ")
    ]
    f = np.array(faces)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def rotation_deg(a, b):
    a = a - a.mean(0)
    b = b - b.mean(0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)))


def main():
    args = sys.argv[1:]
    start = 30
    if "--from" in args:
        i = args.index("--from")
        start = int(args[i + 1])
        del args[i : i + 2]
    net_path, base, obj = args
    net = read_pc2(net_path)
    sim = read_pc2(base + ".pc2")
    still = read_pc2(base + ".static.pc2")
    e = edges_of(obj)

    def lengths(x):
        return np.linalg.norm(x[:, e[:, 0]] - x[:, e[:, 1]], axis=2)

    rest = lengths(still)[0]
    moving = slice(start, net.shape[0])
    mid = (still[0][e[:, 0]] + still[0][e[:, 1]]) / 2.0
    bands = np.percentile(mid[:, 1], [0, 20, 40, 60, 80, 100])
    sleeves = np.abs(mid[:, 0]) > 0.25
    for name, x in (("quasi-static", still), ("simulator", sim), ("network", net)):
        r = (lengths(x) / rest - 1.0)[moving]
        held = r.mean(0)
        print(
            f"{name:>12}: strain mean {r.mean():+.4f}, mean |.| {np.abs(r).mean():.4f}, "
            f"mean square {np.mean(r**2):.6f} (held {np.mean(held**2):.6f}, "
            f"varying {np.mean((r - held) ** 2):.6f}), sleeves {np.mean(r[:, sleeves]**2):.6f}, "
            f"torso {np.mean(r[:, ~sleeves]**2):.6f}, rigid turn "
            f"{np.mean([rotation_deg(still[f], x[f]) for f in range(start, x.shape[0])]):.2f} deg"
        )
        bands_ms = [
            np.mean(r[:, (mid[:, 1] >= bands[i]) & (mid[:, 1] <= bands[i + 1])] ** 2)
            for i in range(5)
        ]
        print(" " * 14 + "mean square by height band, low to high: "
              + ", ".join(f"{v:.6f}" for v in bands_ms))


if __name__ == "__main__":
    main()
