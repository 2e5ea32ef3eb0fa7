#!/usr/bin/env python3
"""Compare two latdyn campaign files with h5py, the reference reader.

Usage: python3 tests/compare_campaigns.py A.h5 B.h5

Every dataset and attribute must be equal, floats bit for bit (NaN where NaN), except
what says how and when the files were made: the root attributes `command_line` and
`threads`, and `/status/wall_s`; dimension scales are compared by the names of the
datasets they point to (object references are file addresses). Also checks that both files have the same sensor chunk
layout. Prints OK, or one line per difference and exits 1. (tests/campaign.rs,
tests/slurm.rs: a merged or resumed campaign against a single-process sweep.)
"""
import sys

import h5py
import numpy as np

IGNORED_ATTRS = {"command_line", "threads"}
IGNORED_DATASETS = {"status/wall_s"}
# object references differ between files: the dimension scales are compared by the
# names they point to instead
REFERENCE_ATTRS = {"DIMENSION_LIST", "REFERENCE_LIST"}


def walk(g, out, pre=""):
    for k in g:
        x = g[k]
        if isinstance(x, h5py.Group):
            out[pre + k + "/"] = x
            walk(x, out, pre + k + "/")
        else:
            out[pre + k] = x


def scales(ds):
    return [[s.name for s in ds.dims[i].values()] for i in range(ds.ndim)]


def same(x, y):
    x, y = np.asarray(x), np.asarray(y)
    if x.shape != y.shape or x.dtype.kind != y.dtype.kind:
        return False
    if x.dtype.kind == "f":
        return np.array_equal(
            x.astype(np.float64).view(np.uint64), y.astype(np.float64).view(np.uint64)
        )
    return np.array_equal(x, y)


def main(a_path, b_path):
    diffs = []
    with h5py.File(a_path, "r") as a, h5py.File(b_path, "r") as b:
        oa, ob = {}, {}
        walk(a, oa)
        walk(b, ob)
        for k in sorted(set(oa) ^ set(ob)):
            diffs.append(f"{k}: only in {'A' if k in oa else 'B'}")
        for k in [""] + sorted(set(oa) & set(ob)):
            xa, xb = (a, b) if k == "" else (oa[k], ob[k])
            for n in sorted(set(xa.attrs) | set(xb.attrs)):
                if (k == "" and n in IGNORED_ATTRS) or n in REFERENCE_ATTRS:
                    continue
                if n not in xa.attrs or n not in xb.attrs:
                    diffs.append(f"/{k} attr {n}: only in one file")
                elif not same(xa.attrs[n], xb.attrs[n]):
                    diffs.append(f"/{k} attr {n}: {xa.attrs[n]!r} vs {xb.attrs[n]!r}")
            if isinstance(xa, h5py.Dataset) and scales(xa) != scales(xb):
                diffs.append(f"/{k}: dimension scales {scales(xa)} vs {scales(xb)}")
            if isinstance(xa, h5py.Dataset) and k not in IGNORED_DATASETS:
                if not same(xa[()], xb[()]):
                    diffs.append(f"/{k}: values differ")
                if k.startswith("sensors/") and xa.chunks != xb.chunks:
                    diffs.append(f"/{k}: chunks {xa.chunks} vs {xb.chunks}")
    for d in diffs:
        print(d)
    if diffs:
        sys.exit(1)
    print("OK")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
