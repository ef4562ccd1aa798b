"""The learning environment's reward: Eq. (12)'s objective at the true target, less a penalty
for every agent that Eq. (13) failed to protect.

reward_t = Xi^N_n(p_D^1, ..., p_D^N) - lambda * sum_i v_i, shared by every agent, where

- p_D^j is Eq. (9) evaluated at the TRUE target for the executed step: agent j at its new
  position, at its level, its cone pointing as ``antenna.pointing`` says (0 while the target is
  absent or occluded), so the reward is what the plan achieved, not what it hoped for at x_bar;
- v_i = 0 when agent i receives R_i < delta from its teammates (Eq. 13 holds), else
  1 + log10(R_i / delta): a jammed agent costs at least lambda, and one more per decade of excess;
- lambda is ``jam_penalty`` (default 1: one jammed agent outweighs the best detection).

With several targets (:class:`trackjam.env.swarm.SwarmParallelEnv`) the objective is summed over
the targets: reward_t = sum_k Xi^N_n(p_D^1k, ..., p_D^Nk) - lambda * sum_i v_i, p_D^jk agent j's
Eq. (9) at target k's true position (0 while k is absent or occluded, so such a target adds 0),
every agent counted whichever track its cone serves: a detection by an agent aimed elsewhere is
a detection. The sum, not the mean, so that losing a target never raises the reward, and one
step's reward lies in [-lambda sum_i v_i, K].
"""

from __future__ import annotations

import numpy as np

from trackjam.control.objective import at_least_probability


def violation(interference_w: np.ndarray, delta_w: float) -> np.ndarray:
    """v_i per agent: 0 while Eq. (13) holds, else 1 + log10(R_i / delta)."""
    r = np.asarray(interference_w, dtype=float)
    jammed = r >= delta_w
    v = np.zeros_like(r)
    v[jammed] = 1.0 + np.log10(r[jammed] / delta_w)
    return v


def reward_terms(p_d: np.ndarray, interference_w: np.ndarray, delta_w: float,
                 at_least: int) -> tuple[float, np.ndarray]:
    """Xi^N_n at the truth and every agent's violation v_i."""
    xi = float(at_least_probability(np.asarray(p_d, dtype=float), at_least))
    return xi, violation(interference_w, delta_w)


def swarm_reward_terms(p_d: np.ndarray, interference_w: np.ndarray, delta_w: float,
                       at_least: int) -> tuple[np.ndarray, np.ndarray]:
    """Xi^N_n at each true target (``p_d`` (N, K): each agent's p_D of each target) and every
    agent's violation v_i."""
    xi = np.asarray(at_least_probability(np.asarray(p_d, dtype=float).T, at_least), dtype=float)
    return xi, violation(interference_w, delta_w)


def team_reward(xi: float, v: np.ndarray, jam_penalty: float) -> float:
    """Xi^N_n less ``jam_penalty`` times the summed violations."""
    return xi - jam_penalty * float(np.sum(v))
