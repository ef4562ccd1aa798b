"""One entry point for the step's cooperative control: build the problem, pick a solver.

Solvers (``control.solver``): ``greedy`` (Eq. 11, each agent alone), ``grasp`` (the paper's
distributed GRASP, Section V-D), ``exact`` (ours: the proven optimum of Eqs. 12-13).
"""

from __future__ import annotations

import numpy as np

from trackjam.control.exact import solve_exact
from trackjam.control.fallback import fallback_levels
from trackjam.control.grasp import solve_grasp
from trackjam.control.greedy import solve_greedy
from trackjam.control.problem import Problem, Solution, build_problem

SOLVERS = ("greedy", "grasp", "exact")

__all__ = ["SOLVERS", "Problem", "Solution", "build_problem", "fallback_levels", "solve"]


def solve(problem: Problem, solver: str, rngs: list[np.random.Generator], samples: int = 10000,
          iterations: int = 100, neighbours: int = 6, threads: int = 1, time_limit_s: float | None = 1.0,
          node_limit: int = 0) -> Solution:
    """Joint control of the step by ``solver``.

    ``rngs`` holds one generator per agent (only ``grasp`` draws from them); ``samples`` = n_s,
    ``iterations`` = n_I and ``neighbours`` (the list u-, u+ are drawn from) are GRASP's;
    ``threads`` lets GRASP run the agents' searches concurrently (same result).
    ``time_limit_s`` [s] (None: none) and ``node_limit`` (0: none) bound ``exact``'s search,
    which then returns its best plan with ``optimal`` False and a certified ``gap``.
    """
    if solver == "greedy":
        return solve_greedy(problem)
    if solver == "grasp":
        return solve_grasp(problem, rngs, samples=samples, iterations=iterations,
                           neighbours=neighbours, threads=threads)
    if solver == "exact":
        return solve_exact(problem, time_limit_s=time_limit_s, node_limit=node_limit)
    raise ValueError(f"unknown solver {solver!r}; expected one of {', '.join(SOLVERS)}")
