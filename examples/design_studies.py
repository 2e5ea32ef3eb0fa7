#!/usr/bin/env python3
"""Tables of the two design studies from their campaign files (h5py + numpy).

  design_studies.py minimast MINIMAST.h5 OUT.md
  design_studies.py blade BLADE.h5 MODES.json OUT.md

Written by examples/design_studies.sh; see that script for the runs.
"""
import json
import math
import sys

import h5py
import numpy as np

TURN_RIGID_DEG = 100.49  # turn of B that puts the longerons vertical (models/README.md)


def params(f):
    names = list(f["parameters/names"].asstr()[:])
    return names, f["parameters/values"][:]


def minimast(path, out):
    f = h5py.File(path, "r")
    names, vals = params(f)
    ang = vals[:, names.index("longeron_axis_angle")]
    T = vals[0, names.index("T")]
    t = f["time"][:]
    state = f["status/state"][:]
    msg = f["status/message"].asstr()[:] if "message" in f["status"] else [""] * len(state)
    lm = f["sensors/longeron_mid"][:]      # (V, T, 6): N Vy Vz T My Mz
    lt = f["sensors/longeron_top"][:]
    da = f["sensors/diagonal_a_mid"][:]
    db = f["sensors/diagonal_b_mid"][:]
    drive = f["sensors/drive_force"][:, :, 0]
    up = f["sensors/upper_z"][:]
    mid = f["sensors/diagonal_mid_hinge"][:, :, 0]
    lax = f["sensors/longeron_axial"][:, :, 0]
    iT = int(np.argmin(abs(t - T)))
    after = t > T + 0.05
    rows = []
    for v in range(len(ang)):
        if state[v] != 2:
            rows.append(dict(v=v, a=ang[v], ok=False, why="run failed: " + msg[v]))
            continue
        bend = lambda s: np.nanmax(np.hypot(s[v, :, 4], s[v, :, 5]))
        turn = math.degrees(up[v, iT, 5])
        locked = abs(mid[v, iT] - math.pi) < 1e-6
        post_n = float(np.nanmean(lax[v, after])) if after.any() else float("nan")
        ok = locked and abs(turn - TURN_RIGID_DEG) < 1.0
        clean = ok and abs(post_n) < 1000.0
        why = []
        if not locked:
            why.append("mid-hinges not locked at T")
        if abs(turn - TURN_RIGID_DEG) >= 1.0:
            why.append(f"turn {turn:.2f} deg")
        if abs(post_n) >= 1000.0:
            why.append(f"longerons left pre-stressed {post_n/1e3:+.1f} kN")
        rows.append(dict(v=v, a=ang[v], ok=ok, clean=clean, why="; ".join(why),
                         lmid=bend(lm), ltop=bend(lt), twist=np.nanmax(abs(lm[v, :, 3])),
                         dia=max(bend(da), bend(db)), drive=np.nanmax(abs(drive[v])),
                         turn=turn, post_n=post_n))
    good = [r for r in rows if r.get("clean")]
    deployed = [r for r in rows if r["ok"]]
    L = []
    L.append("# Mini-Mast bay: longeron hinge-orientation sweep\n")
    L.append(f"Campaign file: `{path}` ({len(rows)} designs, one `latdyn sweep`). Both longeron "
             "hinge axes (A and B ends) of every longeron are turned by `longeron_axis_angle` about "
             "the packaged longeron (0 = Table 3 as printed). Peaks over the whole run "
             f"(0 to {t[-1]:.2f} s, deployment time T = {T:g} s). Bending = resultant "
             "√(My²+Mz²) at the section; diagonal = larger of the two halves' mid-spans.\n")
    L.append("A design **deploys** when at t = T the mid-hinges are locked straight and triangle B has "
             f"turned within 1° of the rigid-member value {TURN_RIGID_DEG}°; otherwise (or if the run "
             "fails) it is listed as **failed** with the reason. A deployed design is **clean** when "
             "the longerons are not left pre-stressed beyond 1 kN (mean axial force after T), "
             "**forced** otherwise: the hinge axes then cannot carry the members rigidly to the "
             "deployed lines, so the driver stretches the longerons into place. None is dropped.\n")
    if good:
        b = min(good, key=lambda r: r["lmid"])
        bd = min(good, key=lambda r: r["drive"])
        L.append(f"**Best design** (least peak longeron mid-span bending among the clean designs): "
                 f"`longeron_axis_angle` = {b['a']:+.4f} rad ({math.degrees(b['a']):+.2f}°): longeron "
                 f"{b['lmid']:.1f} N·m, diagonal {b['dia']:.1f} N·m, drive force {b['drive']/1e3:.2f} kN. "
                 f"Least peak drive force: {bd['a']:+.4f} rad ({bd['drive']/1e3:.2f} kN). "
                 f"{len(deployed)} of {len(rows)} designs deploy, {len(good)} of them clean.\n")
    else:
        L.append("**No design deploys cleanly** by the criteria above.\n")
    L.append("| # | angle [rad] | angle [°] | outcome | longeron mid bending [N·m] | longeron top bending [N·m] | longeron twist [N·m] | diagonal bending [N·m] | drive force [kN] | turn at T [°] | longeron N after T [N] | remarks |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "lmid" not in r:
            L.append(f"| {r['v']} | {r['a']:+.4f} | {math.degrees(r['a']):+.2f} | **failed** | | | | | | | | {r['why']} |")
            continue
        L.append(f"| {r['v']} | {r['a']:+.4f} | {math.degrees(r['a']):+.2f} | {('clean' if r['clean'] else '**forced**') if r['ok'] else '**failed**'} | "
                 f"{r['lmid']:.1f} | {r['ltop']:.1f} | {r['twist']:.1f} | {r['dia']:.1f} | {r['drive']/1e3:.2f} | "
                 f"{r['turn']:.2f} | {r['post_n']:.0f} | {r['why']} |")
    # the quasi-static screening section (examples/minimast_quasistatic.py --study) stays
    keep = ""
    try:
        old = open(out).read()
        mark = "## Quasi-static screening"
        if mark in old:
            keep = "\n" + old[old.index(mark):]
    except FileNotFoundError:
        pass
    open(out, "w").write("\n".join(L) + "\n" + keep)
    print(f"wrote {out}; {len(deployed)} of {len(rows)} deploy, {len(good)} clean")


def blade(path, modes_path, out):
    f = h5py.File(path, "r")
    names, vals = params(f)
    om = vals[:, names.index("omega")]
    EI, rhoA, Lb = (vals[0, names.index(n)] for n in ("EI", "rhoA", "L"))
    w0 = 3.926602312 ** 2 * math.sqrt(EI / (rhoA * Lb ** 4))
    K = 6.4
    fft = 2 * math.pi * f["derived/first_bending_hz"][:]
    state = f["status/state"][:]
    md = json.load(open(modes_path))
    mom = np.array(md["omega_rad_s"])
    # the elastic flap branch: the tracked branch nearest Southwell at the first speed
    brs = [np.array([np.nan if x is None else x for x in b["frequencies_hz"]]) * 2 * math.pi
           for b in md["branches"]]
    sw0 = math.sqrt(w0 ** 2 + K * mom[0] ** 2)
    eb = min(brs, key=lambda b: abs(b[0] - sw0))
    eig = np.interp(om, mom, eb)
    sw = np.sqrt(w0 ** 2 + K * om ** 2)

    def crossings(x, y, n):
        out = []
        g = y - n * x
        for i in range(len(x) - 1):
            if np.isfinite(g[i]) and np.isfinite(g[i + 1]) and g[i] * g[i + 1] < 0:
                out.append(x[i] + g[i] / (g[i] - g[i + 1]) * (x[i + 1] - x[i]))
        return out

    L = ["# Flapping blade: rotor-speed campaign\n"]
    L.append(f"Campaign file: `{path}` ({len(om)} speeds, one `latdyn sweep --frequency mid_moment`); "
             f"eigenvalues from `{modes_path}` (`latdyn modes --vary`, branches tracked by MAC). "
             f"Southwell: ω₁² = ω₀² + K Ω² with ω₀ = 3.9266²·√(EI/(ρA L⁴)) = {w0:.4f} rad/s (pinned-free "
             f"closed form) and K = {K}. FFT = dominant frequency of the simulated mid-span moment "
             "(Hann-windowed FFT with peak refinement) over the 10 s record.\n")
    L.append("## Resonance speeds (interpolated crossings ω₁(Ω) = nΩ)\n")
    L.append("| harmonic | FFT points | eigenvalue branch | Southwell |")
    L.append("|---|---|---|---|")
    fine = np.linspace(om.min(), om.max(), 4001)
    for n in (3, 4, 5):
        a = crossings(om, fft, n)
        b = crossings(mom, eb, n)
        c = crossings(fine, np.sqrt(w0 ** 2 + K * fine ** 2), n)
        fmt = lambda xs: ", ".join(f"{x:.3f}" for x in xs) or "none"
        L.append(f"| {n}Ω | {fmt(a)} rad/s | {fmt(b)} rad/s | {fmt(c)} rad/s |")
    L.append("\n## First bending frequency against Southwell\n")
    L.append("| Ω [rad/s] | FFT [rad/s] | eigenvalue [rad/s] | Southwell [rad/s] | FFT − Southwell | eigenvalue − Southwell | FFT − eigenvalue |")
    L.append("|---|---|---|---|---|---|---|")
    worst = (0, 0)
    for i in range(len(om)):
        if state[i] != 2:
            L.append(f"| {om[i]:.3f} | failed | {eig[i]:.4f} | {sw[i]:.4f} | | | |")
            continue
        e1, e2, e3 = (fft[i] - sw[i]) / sw[i], (eig[i] - sw[i]) / sw[i], (fft[i] - eig[i]) / eig[i]
        worst = (max(worst[0], abs(e1)), max(worst[1], abs(e2)))
        L.append(f"| {om[i]:.3f} | {fft[i]:.4f} | {eig[i]:.4f} | {sw[i]:.4f} | {100*e1:+.2f} % | {100*e2:+.2f} % | {100*e3:+.2f} % |")
    L.append(f"\nLargest |FFT − Southwell| {100*worst[0]:.2f} %, largest |eigenvalue − Southwell| {100*worst[1]:.2f} %.\n")
    open(out, "w").write("\n".join(L) + "\n")
    print(f"wrote {out}; worst FFT {100*worst[0]:.2f} %, eigen {100*worst[1]:.2f} %")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "minimast":
        minimast(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 5 and sys.argv[1] == "blade":
        blade(sys.argv[2], sys.argv[3], sys.argv[4])
    else:
        sys.exit(__doc__)
