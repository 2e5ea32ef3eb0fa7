#!/usr/bin/env python3
"""Per step-element cost of the blade and the spin-up beam (10 elements each) through OLD and NEW
binaries alternately, the minimum of R runs of each: python3 examples/step_element_cost.py OLD NEW R
(from the repo root; stage times from `run --json`)."""
import json, subprocess, sys
old, new, reps = sys.argv[1], sys.argv[2], int(sys.argv[3])
scenes = ["models/flapping_blade.toml", "models/spinup_beam.toml"]
best = {}
for r in range(reps):
    for tag, exe in (("old", old), ("new", new)):
        for m in scenes:
            # the blade at dt 5 ms, the step of issue 17's measure (it ships at 1 ms since session 23)
            sets = ["--set", "dt=0.005"] if "blade" in m else []
            j = json.loads(subprocess.run([exe, "run", m, "--json", *sets], capture_output=True, text=True).stdout)
            st = j["stage_times_s"]
            key = (m, tag)
            cur = best.get(key)
            rec = dict(wall=j["wall_s"], elem=st["element"], asm=st["assembly"], lu=st["factorization"],
                       steps=j["steps"], it=j["newton_iterations"])
            if cur is None:
                best[key] = rec
            else:
                for k in ("wall", "elem", "asm", "lu"):
                    cur[k] = min(cur[k], rec[k])
for m in scenes:
    for tag in ("old", "new"):
        b = best[(m, tag)]
        n = b["steps"] * 10  # both scenes: 10 elements
        print(f"{m:30s} {tag}: wall {b['wall']*1e6/n:6.2f} us/step-elem, element stage {b['elem']*1e6/n:6.2f}, "
              f"assembly {b['asm']*1e6/n:5.2f}, LU {b['lu']*1e6/n:5.2f}; steps {b['steps']}, "
              f"Newton it/step {b['it']/b['steps']:.3f}")
