"""One entry point for the step's cooperative control, and the one registry of its solvers.

``SOLVERS`` maps each ``control.solver`` name to a function ``(problem, rngs, options) ->
Solution``: ``greedy`` (Eq. 11, each agent alone), ``grasp`` (the paper's distributed GRASP,
Section V-D), ``exact`` (ours: the proven optimum of Eqs. 12-13, within a time budget). A new
solver is one function registered with ``@register("name")`` (and its name added to the
configuration's choices, which a test holds equal to this registry).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from trackjam.control.exact import solve_exact
from trackjam.control.fallback import fallback_levels
from trackjam.control.grasp import solve_grasp
from trackjam.arguments import real, whole
from trackjam.control.greedy import solve_greedy
from trackjam.control.problem import Problem, Solution, build_problem

__all__ = ["SOLVERS", "Problem", "Solution", "SolverOptions", "build_problem", "fallback_levels", "register", "solve"]


@dataclass(frozen=True)
class SolverOptions:
    """What a solver may read beyond the problem (each uses its own)."""

    samples: int = 10000  # n_s, GRASP joint samples per iteration
    iterations: int = 100  # n_I, GRASP iterations
    neighbours: int = 6  # GRASP: the list u-, u+ are drawn from
    threads: int = 1  # GRASP: agents' searches side by side (same result)
    time_limit_s: float | None = 1.0  # exact: budget of the search [s]; None: none
    node_limit: int = 0  # exact: budget in search nodes; 0: none

    def __post_init__(self) -> None:
        # the configuration's bounds (trackjam.config): a caller of solve() met none, and
        # samples=10**12 ran GRASP's compiled loop, which no Ctrl-C stops, for hours
        whole("samples", self.samples, 1, 100_000_000)
        whole("iterations", self.iterations, 1, 1_000_000)
        whole("neighbours", self.neighbours, 2, 1000)
        whole("threads", self.threads, 1, 1024)
        if self.time_limit_s is not None:
            real("time_limit_s", self.time_limit_s, 0.0, 3600.0, above=True)
        whole("node_limit", self.node_limit, 0, 10**12)


Solver = Callable[[Problem, Sequence[np.random.Generator], SolverOptions], Solution]

SOLVERS: dict[str, Solver] = {}


def register(name: str) -> Callable[[Solver], Solver]:
    """Register ``fn`` as the solver called ``name`` (a non-empty text, not taken)."""
    if not isinstance(name, str) or not name.strip():  # a list was "unhashable type", 5 and "" were taken
        raise ValueError(f"register: a solver's name must be a non-empty text, got {name!r:.40}")

    def add(fn: Solver) -> Solver:
        if not callable(fn):  # 5 was taken, and failed at the first step with "'int' object is not callable"
            raise TypeError(f"register({name!r}): expected a function (problem, rngs, options) -> Solution, "
                            f"got {type(fn).__name__}")
        if name in SOLVERS:
            raise ValueError(f"solver {name!r} is registered twice")
        SOLVERS[name] = fn
        return fn

    return add


@register("greedy")
def _greedy(problem: Problem, rngs: Sequence[np.random.Generator], options: SolverOptions) -> Solution:
    return solve_greedy(problem)


@register("grasp")
def _grasp(problem: Problem, rngs: Sequence[np.random.Generator], options: SolverOptions) -> Solution:
    return solve_grasp(problem, list(rngs), samples=options.samples, iterations=options.iterations,
                       neighbours=options.neighbours, threads=options.threads)


@register("exact")
def _exact(problem: Problem, rngs: Sequence[np.random.Generator], options: SolverOptions) -> Solution:
    return solve_exact(problem, time_limit_s=options.time_limit_s, node_limit=options.node_limit)


def solve(problem: Problem, solver: str, rngs: list[np.random.Generator], samples: int = 10000,
          iterations: int = 100, neighbours: int = 6, threads: int = 1, time_limit_s: float | None = 1.0,
          node_limit: int = 0) -> Solution:
    """Joint control of the step by the registered ``solver``.

    ``rngs`` holds one generator per agent (only ``grasp`` draws from them); ``samples`` = n_s,
    ``iterations`` = n_I and ``neighbours`` (the list u-, u+ are drawn from) are GRASP's;
    ``threads`` lets GRASP run the agents' searches concurrently (same result).
    ``time_limit_s`` [s] (None: none) and ``node_limit`` (0: none) bound ``exact``'s search,
    which then returns its best plan with ``optimal`` False and a certified ``gap``.
    """
    if solver not in SOLVERS:
        raise ValueError(f"unknown solver {solver!r}; expected one of {', '.join(SOLVERS)}")
    options = SolverOptions(samples=samples, iterations=iterations, neighbours=neighbours, threads=threads,
                            time_limit_s=time_limit_s, node_limit=node_limit)
    solution = SOLVERS[solver](problem, rngs, options)
    if not isinstance(solution, Solution):  # None failed later, deep in the team, with an AttributeError
        raise TypeError(f"solver {solver!r} returned {type(solution).__name__}, not a Solution")
    return solution
