"""Control for several targets (ours, issue 12): every agent chooses its move, its level and the
target its cone serves; the registry of the K-target solvers and their one entry point.

``ASSIGNMENT_SOLVERS`` maps the names of ``control.solver`` to functions ``(problem, rngs,
options) -> AssignmentSolution`` taking the one-target :class:`SolverOptions`: ``greedy``
(Eq. 11 with a choice of target), ``grasp`` (the paper's GRASP over (move, level, target)),
``exact`` (branch and bound, the proven optimum within a budget). It is a registry of its own,
beside :data:`trackjam.control.solve.SOLVERS` (whose names it repeats), so the one-target
solvers are untouched; with one aim each solver returns the one-target solver's plan.
The problem, its objective and the rules per target are in :mod:`assignment_problem`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Callable, Sequence

import numpy as np

from trackjam.control.assignment_exact import solve_assignment_exact
from trackjam.control.assignment_grasp import solve_assignment_grasp
from trackjam.control.assignment_problem import (
    OBJECTIVES,
    AssignmentProblem,
    AssignmentSolution,
    build_assignment,
    solve_assignment_greedy,
)
from trackjam.control.solve import SolverOptions

__all__ = ["ASSIGNMENT_SOLVERS", "OBJECTIVES", "AssignmentProblem", "AssignmentSolution", "SolverOptions",
           "build_assignment", "register_assignment", "solve_assignment"]

AssignmentSolver = Callable[[AssignmentProblem, Sequence[np.random.Generator], SolverOptions], AssignmentSolution]

ASSIGNMENT_SOLVERS: dict[str, AssignmentSolver] = {}


def register_assignment(name: str) -> Callable[[AssignmentSolver], AssignmentSolver]:
    """Register ``fn`` as the K-target solver called ``name`` (a non-empty text, not taken), as
    :func:`trackjam.control.solve.register` does a one-target solver."""
    if not isinstance(name, str) or not name.strip():  # 5 and "" were taken, a list was "unhashable type"
        raise ValueError(f"register_assignment: a solver's name must be a non-empty text, got {name!r:.40}")

    def add(fn: AssignmentSolver) -> AssignmentSolver:
        if not callable(fn):  # 5 was taken, and failed at the swarm's first plan with "'int' object is not callable"
            raise TypeError(f"register_assignment({name!r}): expected a function (problem, rngs, options) -> "
                            f"AssignmentSolution, got {type(fn).__name__}")
        if name in ASSIGNMENT_SOLVERS:
            raise ValueError(f"assignment solver {name!r} is registered twice")
        ASSIGNMENT_SOLVERS[name] = fn
        return fn

    return add


@register_assignment("greedy")
def _greedy(problem: AssignmentProblem, rngs: Sequence[np.random.Generator],
            options: SolverOptions) -> AssignmentSolution:
    return solve_assignment_greedy(problem)


@register_assignment("grasp")
def _grasp(problem: AssignmentProblem, rngs: Sequence[np.random.Generator],
           options: SolverOptions) -> AssignmentSolution:
    return solve_assignment_grasp(problem, list(rngs), samples=options.samples, iterations=options.iterations,
                                  neighbours=options.neighbours, threads=options.threads)


@register_assignment("exact")
def _exact(problem: AssignmentProblem, rngs: Sequence[np.random.Generator],
           options: SolverOptions) -> AssignmentSolution:
    return solve_assignment_exact(problem, time_limit_s=options.time_limit_s, node_limit=options.node_limit)


def solve_assignment(problem: AssignmentProblem, solver: str, rngs: Sequence[np.random.Generator],
                     options: SolverOptions = SolverOptions()) -> AssignmentSolution:
    """The step's joint control for K targets by the registered ``solver`` (``rngs``: one
    generator per agent, each agent's plan stream; only ``grasp`` draws from them).

    Checked first: ``problem`` an :class:`AssignmentProblem` (:func:`build_assignment`),
    ``solver`` a registered name, ``rngs`` a list (any iterable) of numpy Generators, one per
    agent for ``grasp`` (the others draw nothing and take any number, none too), ``options`` a
    :class:`SolverOptions` (which checks its own fields)."""
    if not isinstance(problem, AssignmentProblem):
        raise TypeError(f"problem: expected an AssignmentProblem (build_assignment(...)), got {type(problem).__name__}")
    if not isinstance(solver, str):
        raise TypeError(f"solver: expected a solver's name, one of {', '.join(ASSIGNMENT_SOLVERS)}, "
                        f"got {type(solver).__name__} {solver!r:.40}")
    if solver not in ASSIGNMENT_SOLVERS:
        raise ValueError(f"solver: unknown solver {solver!r:.40}; expected one of {', '.join(ASSIGNMENT_SOLVERS)}")
    if isinstance(rngs, (str, bytes, np.random.Generator)) or not isinstance(rngs, Iterable):
        raise TypeError(f"rngs: expected a list of numpy Generators, one per agent, got {type(rngs).__name__}")
    rngs = list(rngs)
    for j, rng in enumerate(rngs):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rngs[{j}]: expected a numpy Generator (numpy.random.default_rng(seed)), "
                            f"got {type(rng).__name__} {rng!r:.40}")
    if solver == "grasp" and len(rngs) != problem.n_agents:
        raise ValueError(f"rngs: grasp draws from one generator per agent ({problem.n_agents}), got {len(rngs)}")
    if not isinstance(options, SolverOptions):
        raise TypeError(f"options: expected a SolverOptions (SolverOptions(samples=..., ...)), got {type(options).__name__}")
    solution = ASSIGNMENT_SOLVERS[solver](problem, rngs, options)
    if not isinstance(solution, AssignmentSolution):  # None failed later, deep in the swarm engine
        raise TypeError(f"assignment solver {solver!r} returned {type(solution).__name__}, not an AssignmentSolution")
    return solution
