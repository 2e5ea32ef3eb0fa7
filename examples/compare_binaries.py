#!/usr/bin/env python3
"""Shipped scenes through two latdyn binaries: the largest sensor (or frequency) difference
relative to the run's largest value, and Newton iterations, per scene. Used to show that a change
moves no number: python3 examples/compare_binaries.py OLD_BINARY NEW_BINARY (from the repo root).
A binary older than session 18 refuses models/rotating_cantilever.toml (`[initial] steady`):
that line then reads "EXIT 2 0"; compare it on the file as it was (git show a454aa1:PATH)."""
import json, subprocess, sys, math
old, new = sys.argv[1], sys.argv[2]
cases = [("run","models/pendulum.toml",[]),("run","models/fourbar.toml",[]),("run","models/rotating_cantilever.toml",[]),
         ("run","models/spinup_beam.toml",[]),("run","models/flapping_blade.toml",[]),("run","models/minimast_bay.toml",[]),
         ("statics","models/cantilever.toml",[]),("statics","models/bend45.toml",[]),("modes","models/cantilever.toml",[]),
         ("modes","models/flapping_blade.toml",["--set","omega=8"])]
def flat(x):
    if isinstance(x,(int,float)): return [float(x)]
    if isinstance(x,list): return [v for e in x for v in flat(e)]
    if isinstance(x,dict): return [v for k in sorted(x) for v in flat(x[k])]
    return []
worst=0
for verb,m,extra in cases:
    r=[]
    for b in (old,new):
        p=subprocess.run([b,verb,m,"--json"]+extra,capture_output=True,text=True)
        r.append((p.returncode,json.loads(p.stdout) if p.returncode==0 else p.stderr[-300:]))
    if r[0][0]!=0 or r[1][0]!=0:
        print(verb,m,"EXIT",r[0][0],r[1][0],r[1][1] if r[1][0] else ""); continue
    a,b=r[0][1],r[1][1]
    key = "sensors" if verb!="modes" else "frequencies_hz"
    fa,fb=flat(a[key]),flat(b[key])
    if len(fa)!=len(fb): print(verb,m,"LEN",len(fa),len(fb)); continue
    scale=max(1e-300,max(abs(v) for v in fa))
    d=max((abs(x-y) for x,y in zip(fa,fb)),default=0)/scale
    it=(a.get("newton_iterations"),b.get("newton_iterations"))
    print(f"{verb:8s} {m:35s} maxdiff/scale={d:.2e} iters={it}")
