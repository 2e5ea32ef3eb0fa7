"""Independent reference for the rotating cantilever (references.md §2): flapwise natural
frequencies of a uniform inextensible Euler-Bernoulli beam clamped at the rotation axis,
from a linear finite-element eigenproblem with cubic Hermite elements and the
centrifugal geometric stiffness of the exact axial force N(x) = ρAΩ²(L² − x²)/2
(EI w'''' − (N w')' + ρA ẅ = 0; flapwise, so no −Ω²m softening term). Nondimensional:
L = EI = ρA = 1. Used only to supply the Ω̄ = 5 value that the table lacks; validated
against the table rows Ω̄ = 4 and 6."""
import numpy as np


def flap_frequencies(Omega, n_el=200, count=3):
    L, EI, rhoA = 1.0, 1.0, 1.0
    h = L / n_el
    ndof = 2 * (n_el + 1)
    K = np.zeros((ndof, ndof))
    M = np.zeros((ndof, ndof))
    # Gauss points (5) for the geometric stiffness with N(x) quadratic
    gp, gw = np.polynomial.legendre.leggauss(5)
    kb = EI / h ** 3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                 [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    me = rhoA * h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                    [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    for e in range(n_el):
        x0 = e * h
        kg = np.zeros((4, 4))
        for xi, w in zip(gp, gw):
            s = (xi + 1) / 2
            x = x0 + s * h
            N = rhoA * Omega ** 2 * (L * L - x * x) / 2
            # derivatives of Hermite shape functions w.r.t. x
            dN = np.array([(-6 * s + 6 * s * s) / h, 1 - 4 * s + 3 * s * s,
                           (6 * s - 6 * s * s) / h, -2 * s + 3 * s * s])
            kg += N * np.outer(dN, dN) * w * h / 2
        idx = slice(2 * e, 2 * e + 4)
        K[idx, idx] += kb + kg
        M[idx, idx] += me
    K, M = K[2:, 2:], M[2:, 2:]
    lam = np.linalg.eigvals(np.linalg.solve(M, K))
    return np.sort(np.sqrt(np.real(lam)))[:count]


if __name__ == "__main__":
    for Om in [0, 4, 5, 6]:
        print(Om, flap_frequencies(Om))
