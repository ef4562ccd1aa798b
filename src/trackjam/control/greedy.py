"""The single-agent controller of Eq. (11): each agent alone maximises its own p_D at x_bar
(planning over the belief: its own p_D averaged over the samples, sum_s w_s p_D(x_s)).

Ties go to the lower power level, then to the lower displacement index (hover first), so an
agent that cannot see x_bar from anywhere hovers with its antenna off. Eq. (13) does not enter
the choice; the returned :class:`Solution` still reports whether it holds.
"""

from __future__ import annotations

import numpy as np

from trackjam.control.objective import to_solution
from trackjam.control.problem import Problem, Solution


def greedy_choice(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Candidate slots and levels of Eq. (11), agent by agent (ties: lower level, lower move)."""
    N = problem.n_agents
    cand = np.zeros(N, dtype=np.int64)
    level = np.zeros(N, dtype=np.int64)
    p_s, w = problem.objective_tables()
    score = 0.0
    for s in range(len(w)):  # one sample of weight 1 leaves p_D as it is
        score = score + w[s] * p_s[s]
    for i in range(N):
        # level-major flattening: np.argmax's first maximum is the lowest level, then lowest move
        by_level = score[i, : problem.n_cand[i], :].T.ravel()
        k = int(np.argmax(by_level))
        level[i], cand[i] = divmod(k, int(problem.n_cand[i]))
    return cand, level


def solve_greedy(problem: Problem) -> Solution:
    cand, level = greedy_choice(problem)
    return to_solution(problem, cand, level)
