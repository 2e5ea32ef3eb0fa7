#!/usr/bin/env python3
"""Independent reference for models/lee_frame.toml: Lee's frame in 2D, written apart from
latdyn (numpy only).

Element: the planar co-rotational Euler-Bernoulli beam of Crisfield (1991, vol. 1, ch. 7):
a linear local beam (N = EA u/l0, M1,2 = EI/l0 (4θ1+2θ2, 2θ1+4θ2)) in a frame that turns
with the chord; it converges to the extensible elastica under refinement.
Continuation: load control up to 8000, then switching DISPLACEMENT control (each step
prescribes the load point's u or v, whichever moved more in the last step, advanced by
0.25; λ is
an unknown of a bordered Newton solve, secant predictor) -- a different method from
latdyn's arc length, so the two share neither code nor algorithm.

Prints, per mesh (n elements per length 24, as the `elements` parameter of the TOML), the
limit load (the largest load on the path, a parabola in the path's (u, v) chord length
through the three largest samples) and the vertical deflection there, then the observed order and the Richardson
extrapolation; `--curve N` writes the path of mesh N as CSV (u, v, load) to stdout.
"""
import sys
import numpy as np

L, A, I, E, a = 120.0, 6.0, 2.0, 7.2e6, 24.0
EA, EI = E * A, E * I


def mesh(n):
    """nodes (x, y), elements (i, j), load node index, pinned nodes"""
    pts = []
    nc, na, nb = 5 * n, n, 4 * n
    for k in range(nc + 1):
        pts.append((0.0, L * k / nc))
    for k in range(1, na + 1):
        pts.append((a * k / na, L))
    load = len(pts) - 1
    for k in range(1, nb + 1):
        pts.append((a + (L - a) * k / nb, L))
    x = np.array(pts)
    els = [(k, k + 1) for k in range(len(pts) - 1)]
    return x, els, load, (0, len(pts) - 1)


def internal(x0, els, d, want_k=True):
    nd = 3 * len(x0)
    f = np.zeros(nd)
    K = np.zeros((nd, nd)) if want_k else None
    for (i, j) in els:
        idx = [3 * i, 3 * i + 1, 3 * i + 2, 3 * j, 3 * j + 1, 3 * j + 2]
        dx0 = x0[j] - x0[i]
        l0 = np.hypot(*dx0)
        b0 = np.arctan2(dx0[1], dx0[0])
        dx = dx0 + d[[3 * j, 3 * j + 1]] - d[[3 * i, 3 * i + 1]]
        ln = np.hypot(*dx)
        c, s = dx / ln
        b = np.arctan2(dx[1], dx[0])
        db = b - b0
        # same branch as the nodal rotations (they stay within ±π of the chord turn)
        t1 = d[3 * i + 2] - db
        t2 = d[3 * j + 2] - db
        t1 = (t1 + np.pi) % (2 * np.pi) - np.pi
        t2 = (t2 + np.pi) % (2 * np.pi) - np.pi
        N = EA * (ln - l0) / l0
        M1 = EI / l0 * (4 * t1 + 2 * t2)
        M2 = EI / l0 * (2 * t1 + 4 * t2)
        r = np.array([-c, -s, 0, c, s, 0])
        z = np.array([s, -c, 0, -s, c, 0])
        B = np.vstack([r, np.array([0, 0, 1, 0, 0, 0]) - z / ln,
                       np.array([0, 0, 0, 0, 0, 1]) - z / ln])
        fl = np.array([N, M1, M2])
        f[idx] += B.T @ fl
        if want_k:
            Kl = np.array([[EA / l0, 0, 0], [0, 4 * EI / l0, 2 * EI / l0],
                           [0, 2 * EI / l0, 4 * EI / l0]])
            Ke = B.T @ Kl @ B + np.outer(z, z) * N / ln \
                + (np.outer(r, z) + np.outer(z, r)) * (M1 + M2) / ln ** 2
            K[np.ix_(idx, idx)] += Ke
    return f, K


def path(n, du=0.25, umax=95.0, vmax=90.0):
    x0, els, load, pins = mesh(n)
    nd = 3 * len(x0)
    fixed = [3 * pins[0], 3 * pins[0] + 1, 3 * pins[1], 3 * pins[1] + 1]
    free = [k for k in range(nd) if k not in fixed]
    P = np.zeros(nd)
    P[3 * load + 1] = -1.0  # load = λ·(-1) along y
    kc = 3 * load  # horizontal displacement of the load point
    unk = [k for k in free if k != kc]
    d = np.zeros(nd)
    out = [(0.0, 0.0, 0.0)]
    # u grows quadratically from the unloaded state (du/dλ = 0 there), so the path starts
    # under load control up to 8000, where u ≈ 1 is a good parameter
    for lam in np.arange(1000.0, 8001.0, 1000.0):
        for it in range(50):
            f, K = internal(x0, els, d)
            R = f[free] - lam * P[free]
            if np.max(np.abs(R)) < 1e-9 * lam:
                break
            d[free] += np.linalg.solve(K[np.ix_(free, free)], -R)
        out.append((d[kc], d[3 * load + 1], lam))
    prev = (d.copy(), lam)
    prev2 = None
    kc_prev = kc
    while d[kc] < umax and d[3 * load + 1] > -vmax:
        # control whichever of the load point's displacements moved more in the last
        # step (switching displacement control), stepped by h along its last direction;
        # a step that does not converge is retried at half the size
        h = du
        while True:
            if prev2 is None:
                k, sgn = kc, 1.0
                d, lam = prev[0].copy(), prev[1]
            else:
                step = prev[0] - prev2[0]
                # the load point's u or v: where one turns, the other moves
                k = max((kc, kc + 1), key=lambda q: abs(step[q]))
                sgn = np.sign(step[k])
                # secant predictor scaled to the controlled increment
                c = h / abs(step[k])
                d = prev[0] + c * step
                lam = prev[1] + c * (prev[1] - prev2[1])
            target = prev[0][k] + sgn * h
            d[k] = target
            others = [q for q in free if q != k]
            ok = False
            for it in range(30):
                f, K = internal(x0, els, d)
                R = f[free] - lam * P[free]
                # absolute: 1e-9 of the limit load scale (round-off of the element
                # forces, ~1e7, is 1e-9 .. 1e-7)
                if np.max(np.abs(R)) < 1e-5:
                    ok = True
                    break
                J = np.zeros((len(free), len(free)))
                J[:, :len(others)] = K[np.ix_(free, others)]
                J[:, len(others)] = -P[free]
                x = np.linalg.solve(J, -R)
                d[others] += x[:len(others)]
                lam += x[len(others)]
            if ok:
                break
            h *= 0.5
            if h < du / 1024:
                raise SystemExit(f"n={n}: no convergence controlling dof {k} at {target}")
        prev2, prev = prev, (d.copy(), lam)
        out.append((d[kc], d[3 * load + 1], lam))
    return np.array(out)


def limit(p):
    """largest load: parabola in the chord length of (u, v) through the three largest"""
    k = int(np.argmax(p[:, 2]))
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])))])
    x, y = s[k - 1:k + 2], p[k - 1:k + 2, 2]
    d01 = (y[1] - y[0]) / (x[1] - x[0])
    d12 = (y[2] - y[1]) / (x[2] - x[1])
    c2 = (d12 - d01) / (x[2] - x[0])
    b = d01 + c2 * (x[1] - x[0])
    return y[1] - b * b / (4 * c2), p[k, 1]


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--curve":
        p = path(int(sys.argv[2]))
        print("u,v,load")
        for u, v, l in p:
            print(f"{u:.6f},{v:.6f},{l:.6f}")
        sys.exit(0)
    res = []
    for n in (1, 2, 4, 8):
        p = path(n, umax=30.0)
        lm, v = limit(p)
        res.append(lm)
        print(f"n={n:2d} elements={10 * n:3d}  limit load {lm:.3f}  at v = {v:.3f}")
    for k in range(2, len(res)):
        r = (res[k - 2] - res[k - 1]) / (res[k - 1] - res[k])
        p = np.log2(r)
        ext = res[k] + (res[k] - res[k - 1]) / (2 ** p - 1)
        print(f"meshes {10 * 2 ** (k - 2)}/{10 * 2 ** (k - 1)}/{10 * 2 ** k}: observed order {p:.2f}, extrapolated limit load {ext:.2f}")
