#!/usr/bin/env python3
"""Open a latdyn campaign in xarray (group "xarray", engine h5netcdf) and check it
against h5py, the reference reader.

Usage: python3 tests/xarray_campaign.py CAMPAIGN.h5 PARAMETER VALUE SENSOR

Checks: named dimensions (variant, time, SENSOR_component) with their coordinates (the
global indices, the output times, the component names); every varied parameter a
coordinate on `variant`; selecting PARAMETER nearest to VALUE gives that variant's whole
history, bit for bit as h5py reads /sensors/SENSOR. Prints OK. (tests/campaign.rs)
"""
import sys

import h5py
import numpy as np
import xarray as xr


def main(path, param, value, sensor):
    value = float(value)
    ds = xr.open_dataset(path, engine="h5netcdf", group="xarray")
    comp = f"{sensor}_component"
    assert ds[sensor].dims == ("variant", "time", comp), ds[sensor].dims
    assert ds[param].dims == ("variant",), ds[param].dims
    assert param in ds.coords, list(ds.coords)
    with h5py.File(path, "r") as f:
        names = list(f["parameters/names"].asstr()[:])
        varied = list(f["campaign/varied"].asstr()[:])
        col = f["parameters/values"][:, names.index(param)]
        gi = f["status/global_index"][:]
        v = int(np.argmin(np.abs(col - value)))
        history = f[f"sensors/{sensor}"][v]
        time = f["time"][:]
        comps = [c.decode() if isinstance(c, bytes) else str(c)
                 for c in f[f"sensors/{sensor}"].attrs["components"]]
        state = f["status/state"][:]
    for p in varied:
        assert p in ds.coords and ds[p].dims == ("variant",), p
    assert list(ds["variant"].values) == list(gi)
    assert np.array_equal(ds["time"].values, time)
    assert list(ds[comp].values) == comps, (list(ds[comp].values), comps)
    assert np.array_equal(ds["state"].values, state)
    # xarray indexes only dimension coordinates; a parameter coordinate gets its index
    # with set_xindex (README "Campaign output": xarray)
    sel = ds.set_xindex(param).sel({param: value}, method="nearest")
    assert float(sel[param]) == col[v], (float(sel[param]), col[v])
    assert int(sel["variant"]) == int(gi[v])
    got = sel[sensor].values
    assert got.shape == history.shape, (got.shape, history.shape)
    assert np.array_equal(got.view(np.uint64), history.view(np.uint64)), "history differs"
    one = sel[sensor].sel({comp: comps[-1]}).values
    assert np.array_equal(one.view(np.uint64), history[:, -1].view(np.uint64))
    print("OK")


if __name__ == "__main__":
    main(*sys.argv[1:5])
