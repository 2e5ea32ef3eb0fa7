#!/usr/bin/env python3
"""Open a latdyn campaign in xarray (group "xarray", engine h5netcdf) and check it
against h5py, the reference reader.

Usage: python3 tests/xarray_campaign.py CAMPAIGN.h5 PARAMETER VALUE SENSOR

Checks: named dimensions with their coordinates (the output times, the component names);
the variant axis named after the campaign's one varied parameter when it orders the
campaign (a --vary range: dims (PARAMETER, time, SENSOR_component), the global indices a
coordinate `variant` on it), else `variant` (the global indices) with every varied
parameter a coordinate on it; selecting PARAMETER nearest to VALUE gives that variant's
whole history, bit for bit as h5py reads /sensors/SENSOR: with the literal
`ds.sel(omega=VALUE, method="nearest")` on a --vary omega campaign, after
`set_xindex(PARAMETER)` on the `variant` axis. Prints OK (and the axis). (tests/campaign.rs)
"""
import sys

import h5py
import numpy as np
import xarray as xr


def main(path, param, value, sensor):
    value = float(value)
    ds = xr.open_dataset(path, engine="h5netcdf", group="xarray")
    comp = f"{sensor}_component"
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
    axis = param if param in ds.dims else "variant"
    assert ds[sensor].dims == (axis, "time", comp), ds[sensor].dims
    assert ds["state"].dims == (axis,), ds["state"].dims
    assert "variant" in ds.coords and ds["variant"].dims == (axis,), list(ds.coords)
    for p in varied:
        assert p in ds.coords and ds[p].dims == (axis,), p
    assert list(ds["variant"].values) == list(gi)
    assert np.array_equal(ds[param].values, col)
    assert np.array_equal(ds["time"].values, time)
    assert list(ds[comp].values) == comps, (list(ds[comp].values), comps)
    assert np.array_equal(ds["state"].values, state)
    if axis == param:
        # the one varied parameter is the dimension coordinate (README "Campaign output")
        assert varied == [param], varied
        if param == "omega":
            sel = ds.sel(omega=value, method="nearest")
        else:
            sel = ds.sel({param: value}, method="nearest")
    else:
        # several varied parameters, or an unordered table: xarray indexes only dimension
        # coordinates, so a parameter coordinate gets its index with set_xindex, and
        # "nearest" needs it sorted
        sel = ds.set_xindex(param).sortby(param).sel({param: value}, method="nearest")
    assert float(sel[param]) == col[v], (float(sel[param]), col[v])
    assert int(sel["variant"]) == int(gi[v])
    got = sel[sensor].values
    assert got.shape == history.shape, (got.shape, history.shape)
    assert np.array_equal(got.view(np.uint64), history.view(np.uint64)), "history differs"
    one = sel[sensor].sel({comp: comps[-1]}).values
    assert np.array_equal(one.view(np.uint64), history[:, -1].view(np.uint64))
    print("OK", axis)


if __name__ == "__main__":
    main(*sys.argv[1:5])
