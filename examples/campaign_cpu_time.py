#!/usr/bin/env python3
"""python3 examples/campaign_cpu_time.py OLD NEW VARIANTS REPEATS (repo root): the blade campaign
(omega 20..40, 2 threads, CPU stage) through OLD and NEW alternately: wall and CPU (user+sys) seconds per run.
CPU time is the throughput measure on a shared machine: it does not count the time the
sweep's threads wait for other processes' cores."""
import os, resource, subprocess, sys, tempfile, time
old, new, variants, reps = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
res = {"old": [], "new": []}
for r in range(reps):
    for tag, exe in (("old", old), ("new", new)):
        cmd = [exe, "sweep", "models/flapping_blade.toml", "--vary", f"omega=20:40:{variants}", "--set", "dt=0.005",
               "--threads", "2", "--backend", "cpu", "-o", os.path.join(tempfile.gettempdir(), f"campaign_cpu_{tag}.h5")]
        u0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        u1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (u1.ru_utime - u0.ru_utime) + (u1.ru_stime - u0.ru_stime)
        res[tag].append((wall, cpu))
        print(f"repeat {r}: {tag} wall {wall:.2f} s cpu {cpu:.2f} s", flush=True)
for tag in res:
    w = min(x[0] for x in res[tag]); c = min(x[1] for x in res[tag])
    print(f"{tag}: best wall {w:.2f} s ({variants / w:.2f} variants/s), best CPU {c:.2f} s ({c / variants * 1e3:.0f} ms CPU per variant)")
bo = min(x[1] for x in res["old"]); bn = min(x[1] for x in res["new"])
print(f"new/old throughput by CPU time: {bo / bn:.3f}; by wall: {min(x[0] for x in res['old']) / min(x[0] for x in res['new']):.3f}")
