#!/usr/bin/env python3
"""Time-error estimate against the true error under step refinement (README "Not built yet").

    python3 examples/time_error_ladder.py LATDYN MODEL DT1,DT2,... DT_REF [NAME=VALUE ...]

Runs `latdyn run models/MODEL.toml --set dt=DT` for each step and once at DT_REF (the
reference), and prints per sensor: the run's `time_error_by_sensor` (est), the largest
pointwise difference from the reference on the output grid relative to the reference's
range (true), and the difference of the extremes relative to the range (ext).
Example: python3 examples/time_error_ladder.py target/release/latdyn fourbar 0.02,0.002 1.25e-4
"""
import json
import os
import subprocess
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(exe, model, sets):
    # time error only: no mesh twin (since session 49 `run` runs one by default)
    cmd = [exe, "run", os.path.join(REPO, "models", f"{model}.toml"), "--json", "--mesh-check", "never"]
    for s in sets:
        cmd += ["--set", s]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode not in (0, 3):
        sys.exit(f"{' '.join(cmd)}: exit {p.returncode}\n{p.stderr}")
    return json.loads(p.stdout)


def history(r, name):
    s = r["sensors"][name]
    v = np.array(s["values"], dtype=float)
    return np.array(s["t"], dtype=float), (v[:, None] if v.ndim == 1 else v)


def main():
    exe, model, dts, dt_ref = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
    extra = sys.argv[5:]
    ref = run(exe, model, [f"dt={dt_ref}"] + extra)
    for dt in dts.split(","):
        r = run(exe, model, [f"dt={dt}"] + extra)
        row = []
        for name, est in r["time_error_by_sensor"].items():
            if est is None:
                continue
            t, v = history(r, name)
            tr, vr = history(ref, name)
            # both runs sample the same output grid; match the times to the nearest sample
            vr_on_t = vr[np.searchsorted(tr, t - 1e-12).clip(0, len(tr) - 1)]
            rng = vr.max(0) - vr.min(0)
            rng[rng == 0] = 1.0
            true = (np.abs(v - vr_on_t) / rng).max()
            ext = max(abs(v.max() - vr.max()), abs(v.min() - vr.min())) / rng.max()
            row.append(f"{name}: est {est:.3g} true {true:.3g} ext {ext:.3g}")
        print(f"dt {dt}: steps {r['steps']}, warnings {len(r['warnings'])} | " + " | ".join(row),
              flush=True)


if __name__ == "__main__":
    main()
