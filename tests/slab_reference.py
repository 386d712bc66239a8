"""An independent reference for slab sums: the dipole energy of a layer periodic along two lattice
vectors, summed directly over its in-plane copies (no Ewald splitting, no wave vectors).

The sum over the copies n of U_ij = A [m_i.m_j r^2 - 3 (m_i.r)(m_j.r)] / r^5 converges absolutely in two
dimensions, but slowly (the tail beyond a radius R falls as 1/R). It is split by a smooth window
w(rho) = erfc((rho - R) / sigma) / 2 of the in-plane distance rho: the copies are summed with w, and
(1 - w) U, smooth on the lattice's scale, is summed as its integral over the plane divided by the cell's
area S (Poisson's summation formula: the first neglected term is of order exp(-(pi sigma / L)^2) for
the lattice's longest side L; 3e-10 at sigma = 1.5 L). The integral over the directions in the plane
leaves, with h the distance across the layer,

    int (1 - w) U d^2rho = 2 pi A int_0^inf rho (1 - w) [c1 (rho^2 + h^2) - (3/2) c2 rho^2 - 3 c3 h^2]
                                                  / (rho^2 + h^2)^(5/2) d rho,

c1 = m_i.m_j, c2 = m_ix m_jx + m_iy m_jy (in-plane), c3 = m_iz m_jz, by Gauss-Legendre quadrature
over the window's edge and in closed form beyond it.
"""
import math

import numpy as np
from scipy import special


def layer_energy(position, dipole, a1, a2, prefactor=1.0, radius=10.0, width=1.5):
    """Dipole energy of the (N, 3) spheres and all their copies at n1 a1 + n2 a2 (in-plane vectors
    in x and y), the window at ``radius`` and ``width`` times the longer lattice vector."""
    x = np.asarray(position, dtype=float)
    m = np.asarray(dipole, dtype=float)
    a1, a2 = np.asarray(a1, dtype=float), np.asarray(a2, dtype=float)
    side = max(np.linalg.norm(a1), np.linalg.norm(a2))
    r_mid, sigma = radius * side, width * side
    reach = r_mid + 7.0 * sigma  # w < 1e-22 beyond
    area = abs(a1[0] * a2[1] - a1[1] * a2[0])
    shortest = area / side  # the cell's smallest height
    count = int(math.ceil(reach / shortest)) + 2
    n1, n2 = np.meshgrid(np.arange(-count, count + 1), np.arange(-count, count + 1), indexing="ij")
    shifts = n1.reshape(-1, 1) * a1 + n2.reshape(-1, 1) * a2  # (K, 3)
    total = 0.0
    for i in range(len(x)):
        d = x[None, :, :] - x[i] + shifts[:, None, :]  # (K, N, 3): x_j + n - x_i
        r2 = np.einsum("knc,knc->kn", d, d)
        rho = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
        keep = (rho < reach) & (r2 > 1e-20)
        r2s = np.where(keep, r2, 1.0)
        mi_d = d @ m[i]
        mj_d = np.einsum("knc,nc->kn", d, m)
        u = (m @ m[i])[None, :] * r2s - 3.0 * mi_d * mj_d
        w = 0.5 * special.erfc((rho - r_mid) / sigma)
        total += 0.5 * prefactor * float(np.sum(np.where(keep, w * u / r2s ** 2.5, 0.0)))
    # the integral of (1 - w) U, for every pair at once: Gauss-Legendre over the window's edge
    # (where 1 - w rises from 1e-40 to 1 - 1e-40), in closed form beyond it (1 - w = 1 there)
    h = x[None, :, 2] - x[:, None, 2]
    c1 = m @ m.T
    c2 = m[:, None, 0] * m[None, :, 0] + m[:, None, 1] * m[None, :, 1]
    c3 = m[:, None, 2] * m[None, :, 2]
    lo, hi = max(r_mid - 9.0 * sigma, 0.0), r_mid + 9.0 * sigma
    nodes, weights = np.polynomial.legendre.leggauss(400)
    rho = 0.5 * (hi - lo) * nodes + 0.5 * (hi + lo)
    u = rho[:, None, None] ** 2 + h[None] ** 2
    edge = rho[:, None, None] * 0.5 * special.erfc(-(rho[:, None, None] - r_mid) / sigma) * (
        (c1 - 1.5 * c2)[None] * rho[:, None, None] ** 2 + (c1 - 3.0 * c3)[None] * h[None] ** 2) / u ** 2.5
    inner = 0.5 * (hi - lo) * np.tensordot(weights, edge, axes=1)
    ua = hi * hi + h * h  # int_hi^inf rho^3 / u^(5/2) and rho / u^(5/2) d rho
    beyond = (c1 - 1.5 * c2) * (ua ** -0.5 - h * h * ua ** -1.5 / 3.0) + (c1 - 3.0 * c3) * h * h * ua ** -1.5 / 3.0
    total += 0.5 * prefactor * 2.0 * math.pi * float(np.sum(inner + beyond)) / area
    return total


def square_lattice_sum():
    """sum over the square lattice Z^2 without 0 of |n|^-3 = 4 zeta(3/2) beta(3/2) (Dirichlet's beta:
    beta(s) = 4^-s [zeta(s, 1/4) - zeta(s, 3/4)] with Hurwitz's zeta): 9.0336216831..."""
    s = 1.5
    return 4.0 * special.zeta(s) * (special.zeta(s, 0.25) - special.zeta(s, 0.75)) / 4.0 ** s
