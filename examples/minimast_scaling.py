#!/usr/bin/env python3
"""Cost of the whole Mini-Mast (models/minimast.toml) against its size.

Runs `latdyn run models/minimast.toml --set bays=N --json` for N = 1, 2, 4, 8, 18 (all bays
deploying together over T, the model's default) and prints a markdown table of free dofs,
nonzeros of the Jacobian and of its LU factor, steps, Newton iterations, wall time per
step and per step per dof, the same per Newton iteration, and the shares of the factorisation (LU + solves)
and of the assembly (element arrays, chains, scatter) in the time.

    cargo build --release
    python3 examples/minimast_scaling.py [--bin target/release/latdyn] [--set t_end=0.6] \
        [--bays 1,2,4,8,18]

Times are wall clock on whatever else the machine is doing: say so where you quote them.
"""
import argparse
import json
import subprocess
import sys


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/release/latdyn")
    ap.add_argument("--bays", default="1,2,4,8,18")
    ap.add_argument("--set", action="append", default=[], help="extra NAME=VALUE")
    a = ap.parse_args()
    rows = []
    for n in [int(x) for x in a.bays.split(",")]:
        # the run's own cost: no mesh twin beside it (since session 49 `run` runs one)
        cmd = [a.bin, "run", "models/minimast.toml", "--json", "--mesh-check", "never", "--set", f"bays={n}"]
        for s in a.set:
            cmd += ["--set", s]
        out = subprocess.run(cmd, capture_output=True, text=True)
        if not out.stdout.strip():
            sys.exit(f"{' '.join(cmd)}: no result ({out.stderr.strip()})")
        r = json.loads(out.stdout)
        st = r["stage_times_s"]
        per_step = r["wall_s"] / r["steps"]
        rows.append(
            (
                n,
                r["free_dofs"],
                r["matrix_nnz"],
                r["factor_nnz"],
                r["steps"],
                r["newton_iterations"],
                r["wall_s"],
                per_step,
                per_step / r["free_dofs"],
                st["factorization"] / max(r["wall_s"], 1e-300),
                st["assembly"] / max(r["wall_s"], 1e-300),
                r["wall_s"] / r["newton_iterations"] / r["free_dofs"],
                r["status"],
            )
        )
        print(f"bays={n}: {r['status']} {r['steps']} steps in {r['wall_s']:.1f} s", file=sys.stderr)
    print(
        "| bays | free dofs | nnz(K) | nnz(L+U) | nnz(L+U)/dof | steps | Newton it. | wall [s] "
        "| per step [ms] | per step per dof [µs] | per iteration per dof [µs] | LU share "
        "| assembly share | status |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (n, d, nk, nf, s, it, w, ps, psd, fs, asm, pid, status) in rows:
        print(
            f"| {n} | {d} | {nk} | {nf} | {nf / d:.1f} | {s} | {it} | {w:.2f} | {1e3 * ps:.2f} "
            f"| {1e6 * psd:.2f} | {1e6 * pid:.2f} | {100 * fs:.0f} % | {100 * asm:.0f} % | {status} |"
        )


if __name__ == "__main__":
    main()
