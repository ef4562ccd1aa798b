"""The one entry point: every solver answers in the same terms, on the paper's Fig. 3 start."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.control import build_problem, solve
from trackjam.world.moves import scenario_displacements


@pytest.fixture(scope="module")
def fig3_problem(antenna):
    s = load_scenario("paper-fig3")
    c = s.control
    return build_problem(np.array(s.agents.initial), np.array(s.target.initial[:3]), scenario_displacements(s),
                         antenna, s.area.low, s.area.high, c.at_least, c.constraints)


def test_solvers_share_one_answer_shape(fig3_problem):
    P = fig3_problem
    rngs = [np.random.default_rng([0, j]) for j in range(3)]
    out = {name: solve(P, name, rngs, samples=500, iterations=10) for name in ("greedy", "grasp", "exact")}
    for sol in out.values():
        assert sol.move.shape == (3,) and sol.level.shape == (3,)
        assert np.all((sol.move >= 0) & (sol.move < 79))
    assert out["exact"].feasible and out["grasp"].feasible
    assert out["grasp"].objective <= out["exact"].objective
    # greedy ignores Eq. (13): its value is at least the constrained optimum's, and it jams here
    assert out["greedy"].objective >= out["exact"].objective and not out["greedy"].feasible


def test_unknown_solver_is_an_error(fig3_problem):
    with pytest.raises(ValueError):
        solve(fig3_problem, "annealing", [])
