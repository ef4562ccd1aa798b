"""Cooperative control (Sections V-B to V-D): the joint objective Xi^N_n, the interference
constraints of Eq. (13), and the greedy, GRASP and exact solvers."""

from trackjam.control.fallback import fallback_levels
from trackjam.control.problem import Problem, Solution, build_problem
from trackjam.control.solve import SOLVERS, SolverOptions, register, solve

__all__ = ["SOLVERS", "Problem", "Solution", "SolverOptions", "build_problem", "fallback_levels", "register", "solve"]
