"""The virial of the dipolar Ewald sum's reciprocal and surface terms (for :func:`demkit.measure.stress`).

The reciprocal energy (half of k-space, each k with its -k; A the prefactor, V the box volume)

    U = (4 pi A / V) sum_k g(k) |S(k)|^2,   g = exp(-k^2 / 4 alpha^2) / k^2,   S(k) = sum_j (m_j.k) exp(i k.x_j),

under a homogeneous strain x -> (1 + eps) x of spheres and box (moments unchanged) keeps every phase
k.x (k -> (1 - eps^T) k) while V, k^2 and m.k change. Its virial, W_ab = -dU/d eps_ba at eps = 0 in
the convention of the pair virial sum d_a F_b, is

    W_ab = (4 pi A / V) sum_k g [ |S|^2 (delta_ab - 2 k_a k_b (1/k^2 + 1/(4 alpha^2))) + 2 Re(S* T_a) k_b ],

with T_a(k) = sum_j m_ja exp(i k.x_j). The self term does not depend on positions or volume (no
virial); the surface term of vacuum boundaries, (2 pi A / 3V) |sum m|^2, adds (2 pi A / 3V) |sum m|^2
delta_ab, and a slab's layer term (2 pi A / V') M_a^2 (demkit.interactions.slab, V' the drawn-out box)
adds (2 pi A / V') M_a^2 delta_ab likewise. A P3M sum's mesh part is the Ewald reciprocal sum at its
splitting alpha to its accuracy: its virial is this one's with the wave vectors that accuracy needs. The real-space pairs are pair
forces (:meth:`demkit.Scene.pair_forces`).
"""
from __future__ import annotations

import math

import numpy as np

#: wave vectors per block of the phase matrix (block x N complex numbers at a time)
BLOCK = 512


def half_space(box, kmax, kcut):
    """(K, 3) wave vectors 2 pi (p/Lx, q/Ly, r/Lz) with |k| <= kcut, one of each pair +-k (the set the
    compiled sum visits: p > 0, or p = 0 and q > 0, or p = q = 0 and r > 0)."""
    axes = [np.arange(-m, m + 1) for m in kmax]
    p, q, r = (a.ravel() for a in np.meshgrid(*axes, indexing="ij"))
    keep = (p > 0) | ((p == 0) & ((q > 0) | ((q == 0) & (r > 0))))
    k = np.stack([p[keep], q[keep], r[keep]], axis=1) * (2.0 * math.pi / np.asarray(box, dtype=np.float64))
    return k[np.einsum("ij,ij->i", k, k) <= kcut * kcut * (1 + 1e-9)]


def reciprocal_virial(position, dipole, box, prefactor, alpha, vacuum, kmax, kcut, layer=None):
    """(W (3, 3), each sphere's share (N, 3, 3)) of the reciprocal and surface terms (module
    docstring). Sphere j's share takes its part of |S|^2 and of Re(S* T_a), Re(S* (m_j.k) e^(ik.x_j))
    and Re(S* m_ja e^(ik.x_j)), and of the surface term (m_j . sum m): the shares add up to W. A slab's
    ``layer`` (``box`` then the drawn-out box summed) adds its term (2 pi A / V') M_a^2 delta_ab."""
    x = np.asarray(position, dtype=np.float64)
    m = np.asarray(dipole, dtype=np.float64)
    box = np.asarray(box, dtype=np.float64)
    volume = float(np.prod(box))
    k = half_space(box, kmax, kcut)
    k2 = np.einsum("ij,ij->i", k, k)
    g = np.exp(-k2 / (4.0 * alpha * alpha)) / k2
    shares = np.zeros((len(x), 3, 3))
    for s in range(0, len(k), BLOCK):
        kb, gb, k2b = k[s:s + BLOCK], g[s:s + BLOCK], k2[s:s + BLOCK]
        phase = np.exp(1j * (kb @ x.T))                            # e^(ik.x_j), (B, N)
        mk = m @ kb.T                                              # m_j.k, (N, B)
        big_s = np.einsum("kj,jk->k", phase, mk)                   # S(k)
        own = (big_s.conj()[:, None] * phase).real                 # Re(S* e^(ik.x_j)), (B, N)
        u = own * mk.T                                             # sphere j's part of |S|^2
        shape = gb * (1.0 / k2b + 0.25 / (alpha * alpha))
        diagonal = gb @ u
        for a in range(3):
            shares[:, a, a] += diagonal
        shares -= 2.0 * np.einsum("kj,ka,kb->jab", shape[:, None] * u, kb, kb)
        shares += 2.0 * np.einsum("kj,ja,kb->jab", gb[:, None] * own, m, kb)
    shares *= 4.0 * math.pi * prefactor / volume
    if vacuum:
        surface = 2.0 * math.pi * prefactor / (3.0 * volume) * (m @ m.sum(axis=0))
        for a in range(3):
            shares[:, a, a] += surface
    if layer is not None:
        term = 2.0 * math.pi * prefactor / volume * m[:, layer.axis] * m[:, layer.axis].sum()
        for a in range(3):
            shares[:, a, a] += term
    return shares.sum(axis=0), shares

