#!/usr/bin/env python3
"""Check campaign files with h5py, the reference reader.

Usage:
  python3 tests/read_campaign.py CAMPAIGN.h5
      the reference campaign written by tests/hdf5_output.rs; prints OK
  python3 tests/read_campaign.py --any FILE.h5
      any campaign file: opens every object, reads every dataset and attribute (an
      object h5py cannot open fails here), then prints one JSON line: root status,
      failed_variants, /status/state, parameter names, sensor shapes, and per variant
      the number of finite samples (tests/output_faults.rs, tests/hdf5_output.rs)
"""
import json
import math
import sys

import h5py
import numpy as np

N_TIME = 5
FAILED_SAMPLES = 3  # variant 1 fails after this many output times


def value(v, t, s, c):
    # Same formula as value() in tests/hdf5_output.rs.
    return 100.0 * v + 10.0 * t + s + 0.1 * c + 0.5


def as_str(x):
    return x.decode() if isinstance(x, bytes) else str(x)


def check(path):
    with h5py.File(path, "r") as f:
        a = f.attrs
        assert as_str(a["status"]) == "complete", a["status"]
        assert int(a["complete"]) == 1, a["complete"]
        assert int(a["failed_variants"]) == 1, a["failed_variants"]
        assert int(a["threads"]) == 2
        assert as_str(a["backend"]) == "cpu"
        assert as_str(a["precision"]) == "f64"
        assert as_str(a["latdyn_version"]), "latdyn_version is empty"
        assert as_str(a["command_line"]).startswith("latdyn run ")
        assert as_str(a["format"]) == "latdyn-campaign"
        assert int(a["format_version"]) == 1

        src = f["model/source"].asstr()[()]
        assert src == '# a beam\n[model]\nname = "beam" # ünïcode\n', repr(src)
        assert f["model/path"].asstr()[()] == "models/beam.toml"

        assert list(f["parameters/names"].asstr()[:]) == ["E", "L"]
        pv = f["parameters/values"][:]
        assert pv.dtype == np.float64 and pv.shape == (2, 2), pv
        assert np.array_equal(pv, [[1e9, 2.0], [2e9, 3.0]]), pv

        t = f["time"][:]
        assert t.dtype == np.float64 and t.shape == (N_TIME,)
        assert np.allclose(t, 0.1 * np.arange(N_TIME))

        for s, (name, comps, units) in enumerate(
            [("tip", ["z"], ["m"]), ("pose", ["x", "y", "rz"], ["m", "m", "rad"])]
        ):
            ds = f["sensors"][name]
            assert ds.dtype == np.float64
            assert ds.shape == (2, N_TIME, len(comps)), ds.shape
            assert ds.chunks is not None, "not chunked"
            assert ds.compression == "gzip", ds.compression
            assert math.isnan(ds.fillvalue), ds.fillvalue
            assert [as_str(x) for x in ds.attrs["components"]] == comps
            assert [as_str(x) for x in ds.attrs["units"]] == units
            d = ds[:]
            for v in range(2):
                for ti in range(N_TIME):
                    for c in range(len(comps)):
                        x = d[v, ti, c]
                        if v == 1 and ti >= FAILED_SAMPLES:
                            assert math.isnan(x), (name, v, ti, c, x)
                        else:
                            assert x == value(v, ti, s, c), (name, v, ti, c, x)

        st = f["status"]
        assert list(st["state"][:]) == [2, 3]
        labels = [as_str(x) for x in st["state"].attrs["labels"]]
        assert labels == ["pending", "running", "completed", "failed", "interrupted"]
        msg = list(st["message"].asstr()[:])
        assert msg == ["", "Newton iteration diverged at t = 0.25 s"], msg
        assert math.isnan(st["t_fail"][0]) and st["t_fail"][1] == 0.25
        assert st["steps"].dtype == np.int64 and list(st["steps"][:]) == [100, 42]
        assert list(st["rejected_steps"][:]) == [3, 7]
        assert list(st["wall_s"][:]) == [0.5, 0.25]
        eg = st["energy_growth"][:]
        assert eg[0] == 2e-7 and math.isnan(eg[1]), eg
        assert st["global_index"].dtype == np.int64
        assert list(st["global_index"][:]) == [4, 7]

        d = f["derived/first_bending_hz"][:]
        assert d.shape == (2,) and d[0] == 1.25 and math.isnan(d[1]), d
    print("OK")


def summary(path):
    with h5py.File(path, "r") as f:
        for k in f.attrs:
            f.attrs[k]

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                obj[()]
            for k in obj.attrs:
                obj.attrs[k]

        f.visititems(visit)
        # every link of a group must open (a NUL in a name once made two links one)
        for g in ("model", "parameters", "sensors", "status", "derived"):
            assert g in f, f"missing group /{g}"
            for k in f[g]:
                f[g][k]
        state = [int(x) for x in f["status/state"][:]]
        finite = [0] * len(state)
        sensors = {}
        for name, ds in f["sensors"].items():
            sensors[name] = list(ds.shape)
            d = ds[:]
            for v in range(len(state)):
                finite[v] += int(np.isfinite(d[v]).sum())
        out = {
            "status": as_str(f.attrs["status"]),
            "complete": int(f.attrs["complete"]),
            "failed_variants": int(f.attrs["failed_variants"]),
            "command_line": as_str(f.attrs["command_line"]),
            "state": state,
            "parameter_names": list(f["parameters/names"].asstr()[:]),
            "messages": list(f["status/message"].asstr()[:]),
            "sensors": sensors,
            "finite_samples": finite,
            "n_time": int(f["time"].shape[0]),
        }
    print(json.dumps(out))


if __name__ == "__main__":
    if sys.argv[1] == "--any":
        summary(sys.argv[2])
    else:
        check(sys.argv[1])
