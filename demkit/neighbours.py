"""Pair lists: which pairs (i, j), i < j, the pair loop visits.

A pair list hands the compiled loop an (P, 2) int64 array of candidate pairs. Interactions never
see how it was built, so a cell list with a skin can replace :class:`AllPairs` later without
changing them; per-pair history is stored in rows that follow this array.
"""
from __future__ import annotations

import numpy as np


class AllPairs:
    """Every pair i < j: exact for any cutoff, O(N^2) memory and work (use for small N)."""

    def build(self, particles):
        """Return the (P, 2) int64 array of pairs for the current positions."""
        n = len(particles)
        i, j = np.triu_indices(n, k=1)
        return np.ascontiguousarray(np.stack([i, j], axis=1).astype(np.int64))

    def needs_rebuild(self, particles):
        """All pairs never change."""
        return False

    def __repr__(self):
        return "AllPairs()"
