#!/usr/bin/env python3
"""Lee frame: latdyn's path (`statics --path`, 20 and 80 elements) against the independent
80-element solution of examples/lee_frame_reference.py (tests/data/lee_frame_reference_80el.csv);
writes docs/figures/lee_frame_path.{png,svg}. Usage: examples/lee_frame_figure.py LATDYN"""
import json
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

B = sys.argv[1]
ref = np.loadtxt("tests/data/lee_frame_reference_80el.csv", delimiter=",", skiprows=1)
fig, ax = plt.subplots(1, 2, figsize=(10, 4))
for j, (col, name) in enumerate(((1, "vertical"), (0, "horizontal"))):
    ax[j].plot(-ref[:, col] if col == 1 else ref[:, col], ref[:, 2], "k-", lw=2.5, alpha=0.35,
               label="independent 2D solution, 80 elements")
for n, c, mk in ((2, "tab:red", "o"), (8, "tab:blue", ".")):
    d = json.loads(subprocess.run([B, "statics", "models/lee_frame.toml", "--path", "--set", f"elements={n}",
                                   "--until", "load_point.y=-80", "--json"],
                                  capture_output=True, text=True, check=True).stdout)
    v = np.array(d["sensors"]["load_point"]["values"])
    lam = np.array(d["lambda"]) * 1e4
    for j, col in enumerate((1, 0)):
        ax[j].plot(-v[:, col] if col == 1 else v[:, col], lam, color=c, marker=mk, ms=3, lw=0.8,
                   label=f"latdyn --path, {10 * n} elements")
for j, name in enumerate(("vertical deflection −v", "horizontal displacement u")):
    ax[j].set_xlabel(f"load point {name}")
    ax[j].set_ylabel("load P")
    ax[j].grid(alpha=0.3)
    ax[j].axhline(0, color="0.5", lw=0.5)
ax[0].legend(fontsize=8)
fig.suptitle("Lee frame: path through the limit point and the snap-back")
fig.tight_layout()
for ext in ("png", "svg"):
    fig.savefig(f"docs/figures/lee_frame_path.{ext}", dpi=110)
