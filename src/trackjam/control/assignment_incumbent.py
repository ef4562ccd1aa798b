"""The starting incumbent of the several-target exact search (ours): a feasible plan built agent
by agent and improved one agent at a time, so that the branch and bound prunes from its first
nodes instead of from the plan where every agent hovers at level 0.

Construction: the agents in the search's placing order each take the (move, level, target) of
best team objective over the agents placed so far (Eq. 13 checked over the whole team, the
unplaced agents at their start: hovering at level 0, serving target 0, so the plan stays
feasible whenever the start is); ties to the lower target, then candidate, then level. Ascent:
in agent order, each agent takes its best choice given all the others when that is strictly
better, until a whole round changes nothing.

From that start alone the search met its final incumbent late (often in the last tenth of its
nodes), so it pruned little. On the 85 planning steps of swarm-3, seeds 1-3 (K = 1 to 4 aims,
N = 5), the 82 searches that finished within 3 million nodes from it visited 3.06
million nodes in all, 0.50 million from this start; 84 of the 85 finish from it.
``tests/control/test_assignment_incumbent.py`` holds the kernel to a plain-numpy twin.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trackjam.control.assignment_grasp import _feasible
from trackjam.control.grasp import _sample_xi


@njit(cache=True)
def _placed_value(pz, gain, levels_w, delta, n, kind, constrained, C, pair, target, placed, kk, p, q):
    """The team objective over the placed agents (the others serve nobody), or -inf when Eq.
    (13), over every agent, is enforced and broken."""
    N = pair.shape[0]
    K = pz.shape[0]
    L = levels_w.shape[0]
    zero = pz.shape[2] - 1
    if constrained and not _feasible(gain, levels_w, delta, C, pair, target, L):
        return -np.inf
    acc = 0.0 if kind == 0 else np.inf
    for k in range(K):
        m = 0
        for i in range(N):
            if placed[i] and target[i] == k:
                kk[i] = pair[i]
                m += 1
            else:
                kk[i] = zero
        x = 0.0 if m == 0 else _sample_xi(pz[k], kk, min(n, m), p, q)
        acc = acc + x if kind == 0 else min(acc, x)
    return acc


@njit(cache=True)
def _best_choice(pz, gain, levels_w, delta, n, kind, constrained, C, n_cand, pair, target, placed, kk, p, q, i,
                 best):
    """Agent i's first choice (target, then candidate, then level) of value above ``best``, the
    others fixed; it is left in ``pair[i]``, ``target[i]`` (unchanged when none is) and its
    value returned."""
    L = levels_w.shape[0]
    bp = pair[i]
    bt = target[i]
    for k in range(pz.shape[0]):
        for c in range(n_cand[i]):
            for lv in range(L):
                pair[i] = c * L + lv
                target[i] = k
                v = _placed_value(pz, gain, levels_w, delta, n, kind, constrained, C, pair, target, placed, kk, p, q)
                if v > best:
                    best = v
                    bp = c * L + lv
                    bt = k
    pair[i] = bp
    target[i] = bt
    return best


@njit(cache=True)
def kernel_incumbent(pz, gain, levels_w, delta, n, kind, constrained, n_cand, order, pair, target):
    """Construction in ``order``, then ascent (the module docstring); ``gain`` and the plan in
    agent order, ``pair`` (c * L + l) and ``target`` (N,) the start on entry and the result on
    return. Returns the plan's team objective (-inf: infeasible under Eq. 13)."""
    N = n_cand.shape[0]
    C = gain.shape[2] // pz.shape[0]
    kk = np.empty(N, dtype=np.int64)
    p = np.empty(N)
    q = np.empty(n + 1)
    placed = np.zeros(N, dtype=np.bool_)
    for d in range(N):
        placed[order[d]] = True
        _best_choice(pz, gain, levels_w, delta, n, kind, constrained, C, n_cand, pair, target, placed, kk, p, q,
                     order[d], -np.inf)
    # every agent placed: the value is the team objective itself (kernel_targets_value's sums)
    best = _placed_value(pz, gain, levels_w, delta, n, kind, constrained, C, pair, target, placed, kk, p, q)
    changed = True
    while changed:
        changed = False
        for i in range(N):
            v = _best_choice(pz, gain, levels_w, delta, n, kind, constrained, C, n_cand, pair, target, placed, kk,
                             p, q, i, best)
            if v > best:
                best = v
                changed = True
    return best
