"""An independent model of latdyn's time-error estimate, for a linear cantilever.

The generalized-alpha step (Arnold-Bruels form: equilibrium at t_{n+1}, auxiliary
acceleration) on a linear Euler-Bernoulli cantilever of Hermite elements with consistent
translational and rotary mass, loaded at its tip by a force applied at t = 0 (the start
consistent: a_0 = M^-1 F), and beside it the estimate as the README and
src/solver/dynamics.rs describe it, written from those formulas and not from the code:
the local error on the first two steps e = c_q h^2 (aux_{n+1} - aux_n) in the
coordinates and e_v = c_v h^3 (second difference of aux) in the velocities, from the
third on the weighted sums of the last four aux that are exact for cubic accelerations, carried from step to step by
the scheme's own linear recursion (exact here: the system is linear), capped band by
band of spatial frequency every 8 steps and at the last (the bands split by the low-pass
filters L_k = (M + k h^2 K)^-1 M with k = beta (1 - alpha_f)/(1 - alpha_m), the step
matrix's, and k = 3, 30, 300: the bands I - L_1, L_1 - L_3, L_3 - L_30 and L_30 - L_300
each hold their share of the error's root moment to the largest root moment their share
of the displacement over the window of those steps has shown), and read there, mapped to
the root bending moment EI w''(0). Prints, as JSON, the largest |estimated deviation| of
the root moment over the readings divided by the moment's range over the steps (the
figure `time_error_by_sensor` reports), and the range.

usage: python3 estimator_model.py RHO_INF DT T_END [ELEMENTS EI RHOA RHOI L P]
"""
import json
import sys

import numpy as np


def main():
    args = [float(a) for a in sys.argv[1:]]
    rho, h, t_end = args[0], args[1], args[2]
    rest_args = [8, 100.0, 1.0, 1e-4, 1.0, 1.0]
    rest_args[: len(args) - 3] = args[3:]
    n_el, ei, rho_a, rho_i, length, p = rest_args
    n_el = int(n_el)
    am = (2 * rho - 1) / (rho + 1)
    af = rho / (rho + 1)
    gam = 0.5 + af - am
    beta = 0.25 * (gam + 0.5) ** 2
    cq = beta - 1 / 6 + 0.5 * (am - af)
    cv = 1 / 12 + (am - af) * (af - 0.5)
    cfac = (1 - af) / (1 - am)
    # the local error's weights on the auxiliary accelerations a~_{n+1}, a~_n, a~_{n-1},
    # a~_{n-2} (README "How it is computed"), with d = alpha_f - alpha_m, and on the
    # changes da_n, da_{n-1}, da_{n-2}
    d = af - am
    q = af * af * d
    wx = [
        -(180 * q + 60 * af * d + 45 * d - 360 * beta + 38) / 360,
        (180 * q - 35 * d - 120 * beta + 3) / 120,
        -(180 * q - 60 * af * d - 55 * d - 12) / 120,
        (180 * q - 120 * af * d - 15 * d - 7) / 360,
    ]
    wv = [
        -(24 * q + 12 * af * d + 10 * d - 24 * gam + 9) / 24,
        (72 * q + 12 * af * d - 6 * d - 24 * gam + 5) / 24,
        -(72 * q - 12 * af * d - 18 * d - 5) / 24,
        (24 * q - 12 * af * d - 2 * d - 1) / 24,
    ]
    ux = [wx[0], wx[0] + wx[1], -wx[3]]
    uv = [wv[0], wv[0] + wv[1], -wv[3]]

    le = length / n_el
    ke = ei / le**3 * np.array([
        [12, 6 * le, -12, 6 * le],
        [6 * le, 4 * le**2, -6 * le, 2 * le**2],
        [-12, -6 * le, 12, -6 * le],
        [6 * le, 2 * le**2, -6 * le, 4 * le**2],
    ])
    me = rho_a * le / 420 * np.array([
        [156, 22 * le, 54, -13 * le],
        [22 * le, 4 * le**2, 13 * le, -3 * le**2],
        [54, 13 * le, 156, -22 * le],
        [-13 * le, -3 * le**2, -22 * le, 4 * le**2],
    ])
    mr = rho_i / (30 * le) * np.array([
        [36, 3 * le, -36, 3 * le],
        [3 * le, 4 * le**2, -3 * le, -le**2],
        [-36, -3 * le, 36, -3 * le],
        [3 * le, -le**2, -3 * le, 4 * le**2],
    ])
    n = 2 * (n_el + 1)
    k = np.zeros((n, n))
    m = np.zeros((n, n))
    for e in range(n_el):
        i = list(range(2 * e, 2 * e + 4))
        k[np.ix_(i, i)] += ke
        m[np.ix_(i, i)] += me + mr
    k, m = k[2:, 2:], m[2:, 2:]
    n -= 2
    f = np.zeros(n)
    f[-2] = p
    # root moment EI w''(0) of the first element (its first node clamped)
    sens = np.zeros(n)
    sens[0], sens[1] = ei * 6 / le**2, -ei * 2 / le

    steps = int(round(t_end / h))
    x, v = np.zeros(n), np.zeros(n)
    a = np.linalg.solve(m, f)
    aux = a.copy()
    gx, gv, ga, gacc = (np.zeros(n) for _ in range(4))
    da_prev = []
    bp, gp = h * h * beta * cfac, h * gam * cfac
    s_inv = np.linalg.inv(m + bp * k)
    # the band filters and the window of the band caps
    filters = [s_inv @ m] + [np.linalg.solve(m + kk * h * h * k, m) for kk in (3.0, 30.0, 300.0)]
    every = 8
    x_window = np.zeros(n)
    band_max = [0.0] * len(filters)
    y_lo = y_hi = 0.0
    worst = 0.0
    for step in range(steps):
        rest = (af * a - am * aux) / (1 - am)
        xp = x + h * v + h * h * (0.5 - beta) * aux + h * h * beta * rest
        a1 = s_inv @ (f - k @ xp)
        aux1 = cfac * a1 + rest
        x1 = xp + bp * a1
        v1 = v + h * (1 - gam) * aux + h * gam * aux1
        da = aux1 - aux
        if len(da_prev) == 2:
            # third and later steps (all equal here): sums exact for cubic accelerations
            ds = [da] + da_prev
            ev = h * sum(u * d for u, d in zip(uv, ds))
            e = h * h * sum(u * d for u, d in zip(ux, ds)) - beta / gam * h * ev
        else:
            e = cq * h * h * da
            ev = cv * h**3 * (da / h - da_prev[0] / h) / h if da_prev else 0 * da
        da_prev = [da] + da_prev[:1]
        rest_g = (af * gacc - am * ga) / (1 - am)
        gx0 = gx + h * gv + h * h * (0.5 - beta) * ga + h * h * beta * rest_g + e + bp / gp * ev
        gv0 = gv + h * (1 - gam) * ga + h * gam * rest_g + ev
        gnew = s_inv @ (-k @ gx0)
        ga = rest_g + cfac * gnew
        gx, gv, gacc = gx0 + bp * gnew, gv0 + gp * gnew, gnew
        x, v, a, aux = x1, v1, a1, aux1
        y = sens @ x
        y_lo, y_hi = min(y_lo, y), max(y_hi, y)
        if (step + 1) % every == 0 or step + 1 == steps:
            # every band is cut from the error as it came from the transport
            originals = [gx, gv, ga, gacc]
            errors = list(originals)
            for band in range(len(filters)):
                def part(z):
                    low = [lp @ z for lp in filters]
                    return z - low[0] if band == 0 else low[band - 1] - low[band]
                band_max[band] = max(band_max[band], abs(sens @ part(x - x_window)))
                dev = abs(sens @ part(gx))
                if dev > band_max[band]:
                    keep = band_max[band] / dev
                    errors = [e - (1 - keep) * part(z) for e, z in zip(errors, originals)]
            gx, gv, ga, gacc = errors
            x_window = x.copy()
            worst = max(worst, abs(sens @ gx))
    print(json.dumps({"estimate": worst / (y_hi - y_lo), "range": y_hi - y_lo}))


main()
