#!/usr/bin/env python3
"""A new user's audit of the time-error warnings (issue 14): every shipped scene at several
steps (and spectral radii, and some parameter changes), each run compared with the same
run at a fine step. A run whose worst sensor is more than 1 % of its range off the fine
run and carries no warning is printed as SILENT: the one outcome latdyn must not have.

    cargo build --release && python3 benches/audit/new_user.py [FILTER]

Needs h5py. About 12 min on 2 cores (the rotating cantilever's references dominate).
FILTER runs only the cases whose model path contains it. Rotation-vector components whose
range is round-off (below 1e-9 of their sensor's largest) are left out, as latdyn does.
"""
import json, os, subprocess, sys, tempfile

import h5py
import numpy as np
BIN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "target", "release", "latdyn")
TMP = tempfile.mkdtemp(prefix="latdyn-audit-")


def run(model, sets, tag):
    """`latdyn run` with the HDF5 output: (its JSON, times, sensors) or (None, stderr)."""
    out = os.path.join(TMP, f"{tag}.h5")
    args = [BIN, "run", model, "--json", "-o", out] + sum([["--set", s] for s in sets], [])
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode != 0:
        return None, p.stderr[-400:]
    with h5py.File(out, "r") as f:
        t = f["time"][()]
        s = {k: f["sensors"][k][0] for k in f["sensors"]}
    return (json.loads(p.stdout), t, s), None


def err(run_, ref):
    """Per sensor: the largest |y - y_ref| on the common samples over the reference's range,
    the largest over the components (the measure latdyn's estimate reports)."""
    _, t, s = run_
    _, tr, sr = ref
    res = {}
    for k in s:
        if k == "energy" or k not in sr:
            continue
        idx = np.searchsorted(tr, t - 1e-9)
        ok = (idx < len(tr)) & (np.abs(tr[np.minimum(idx, len(tr) - 1)] - t) < 1e-7)
        a, b = s[k][ok], sr[k][idx[ok]]
        rng = b.max(0) - b.min(0)
        keep = rng > 1e-9 * rng.max()
        if keep.any():
            res[k] = float((np.abs(a - b).max(0)[keep] / rng[keep]).max())
    return res


# (model, --set, steps, rho_inf values (None: the model's), reference step)
CASES = [
    ("models/pendulum.toml", [], [1e-3, 0.01, 0.03, 0.1], [None, 0.6, 0.0], 1.25e-4),
    ("models/spinup_beam.toml", [], [0.005, 0.01, 0.02, 0.05], [None, 1.0, 0.0], 6.25e-4),
    ("models/fourbar.toml", [], [2e-3, 5e-3, 0.01, 0.02], [None], 2.5e-4),
    ("models/flapping_blade.toml", [], [1e-3, 2e-3, 5e-3, 0.01], [None, 0.9], 1.25e-4),
    ("models/bend45.toml", [], [2e-4, 5e-4, 1e-3, 2e-3], [None], 2.5e-5),
    ("models/lee_frame.toml", [], [1e-4, 3e-4, 1e-3], [None], 1.25e-5),
    ("models/minimast_bay.toml", [], [1e-3, 2e-3, 5e-3], [None], 1.25e-4),
    ("models/rotating_cantilever.toml", [], [1e-4, 1e-3, 1e-2], [None], 2.5e-5),
    ("models/fourbar.toml", ["EI=2e3", "mc=20"], [2e-3, 5e-3], [None], 2.5e-4),
    ("models/flapping_blade.toml", ["omega=30", "t_end=4"], [1e-3, 2e-3], [None], 1.25e-4),
    ("models/flapping_blade.toml", ["omega=15", "tilt=0.3", "t_end=4"], [1e-3, 2e-3], [None], 1.25e-4),
    ("models/flapping_blade.toml", ["omega=10", "L=1", "EI=1", "rhoA=1", "GJ=1", "EA=1e6", "t_end=4"], [1e-3, 1e-2], [None], 1.25e-4),
    ("models/spinup_beam.toml", ["ws=4", "Ts=5", "t_end=10"], [0.005, 0.01], [None], 6.25e-4),
    ("models/spinup_beam.toml", ["ws=10", "EI=5e3", "GJ=5e3"], [0.005, 0.01], [None], 6.25e-4),
    ("models/rotating_cantilever.toml", ["omega=20", "t_end=3"], [1e-4, 3e-4], [None], 2.5e-5),
    ("models/rotating_cantilever.toml", ["omega=50", "t_end=3"], [1e-4, 3e-4], [None], 2.5e-5),
    ("models/rotating_cantilever.toml", ["omega=2", "t_end=3", "elements=4"], [1e-4, 1e-3], [None], 2.5e-5),
    # session 38: rotors whose band caps now bind (the window in the hub's frame)
    ("models/rotating_cantilever.toml", ["t_end=3"], [1e-4, 4e-4, 1e-3], [0.9, 1.0], 1.25e-5),
    ("models/flapping_blade.toml", ["t_end=4"], [1e-3, 2e-3, 4e-3], [1.0], 1.25e-4),
    ("models/flapping_blade.toml", ["omega=20", "t_end=4"], [1e-3, 2e-3], [None], 1.25e-4),
    ("models/spinup_beam.toml", [], [0.005, 0.01, 0.02], [0.9], 6.25e-4),
    ("models/spinup_beam.toml", ["ws=12", "Ts=6", "t_end=10"], [0.0025, 0.005, 0.01], [None], 3.125e-4),
]


def audit(model, base_sets, dts, rhos, refdt):
    name = os.path.basename(model)[:-5] + "".join("_" + s for s in base_sets)
    for rho in rhos:
        rs = [] if rho is None else [f"rho_inf={rho}"]
        ref, e = run(model, base_sets + rs + [f"dt={refdt}"], f"{name}_ref_{rho}")
        if ref is None:
            print(name, rho, "ref failed", e)
            continue
        for dt in dts:
            r, e = run(model, base_sets + rs + [f"dt={dt}"], f"{name}_{dt}_{rho}")
            if r is None:
                print(f"{name} rho={rho} dt={dt}: FAILED {e.strip()[-200:]}", flush=True)
                continue
            ers = err(r, ref)
            worst = max(ers.values(), default=0.0)
            w = r[0]["warnings"]
            flag = "ok" if worst <= 0.01 else ("warned" if w else "SILENT")
            est = r[0]["time_error_estimate"]
            print(
                f"{name} rho={rho} dt={dt}: worst {worst:.3g} estimate {est:.3g} {flag}"
                f" {ers} warnings: {[x[:80] for x in w]}",
                flush=True,
            )

if __name__ == "__main__":
    only = sys.argv[1] if len(sys.argv) > 1 else ""
    for case in CASES:
        if only in case[0]:
            audit(*case)
