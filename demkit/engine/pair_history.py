"""The per-pair history of a neighbour list (friction springs, rolling and twisting, functions of your own)
carried across a rebuild by the tags of its two spheres (demkit.engine.neighbours.rebuild): the rows that are
not all zero saved with their pair's tags before the build, put back on the same pairs after it (a pair no
longer listed loses its row)."""
import numpy as np
from numba import njit

#: inlined into the list builder (demkit.engine.neighbours: the same options as its helpers)
HELPER = dict(cache=True, fastmath={"contract", "arcp"}, error_model="numpy", inline="always")


@njit(**HELPER)
def count_kept(start, end, history):
    """How many entries have a history that is not all zero."""
    kept = 0
    for i in range(end.shape[0]):
        for p in range(start[i], end[i]):
            for h in range(history.shape[1]):
                if history[p, h] != 0.0:
                    kept += 1
                    break
    return kept


@njit(**HELPER)
def save_rows(start, end, partner, history, tag, owners, partners, rows):
    """Copy the non-zero history rows, with the tags of their pair, into owners/partners/rows."""
    k = 0
    for i in range(end.shape[0]):
        for p in range(start[i], end[i]):
            nonzero = False
            for h in range(history.shape[1]):
                nonzero = nonzero or history[p, h] != 0.0
            if nonzero:
                owners[k] = tag[i]
                partners[k] = tag[partner[p]]
                for h in range(history.shape[1]):
                    rows[k, h] = history[p, h]
                k += 1


@njit(**HELPER)
def saved_history(pl, tag):
    """(owner tags, partner tags, rows) of the list's entries whose history is not all zero."""
    kept = count_kept(pl.start, pl.end, pl.history)
    owners = np.empty(kept, dtype=np.int64)
    partners = np.empty(kept, dtype=np.int64)
    rows = np.empty((kept, pl.history.shape[1]))
    save_rows(pl.start, pl.end, pl.partner, pl.history, tag, owners, partners, rows)
    return owners, partners, rows


@njit(**HELPER)
def put_rows(start, end, partner, history, where, owners, partners, rows):
    """Zero the history of every entry, then put each saved row on its pair's entry, if listed."""
    for i in range(end.shape[0]):
        for p in range(start[i], end[i]):
            for h in range(history.shape[1]):
                history[p, h] = 0.0
    for k in range(owners.shape[0]):
        i = where[owners[k]]
        j = where[partners[k]]
        for p in range(start[i], end[i]):
            if partner[p] == j:
                for h in range(history.shape[1]):
                    history[p, h] = rows[k, h]
                break


@njit(**HELPER)
def restore_history(pl, tag, owners, partners, rows):
    """Size the history to the (new) list and put the saved rows back by tag."""
    if pl.history.shape[0] < pl.partner.shape[0]:
        pl.history = np.zeros((pl.partner.shape[0], pl.history.shape[1]))
    where = np.empty(tag.shape[0], dtype=np.int64)
    for i in range(tag.shape[0]):
        where[tag[i]] = i
    put_rows(pl.start, pl.end, pl.partner, pl.history, where, owners, partners, rows)
