"""The one entry point: every solver answers in the same terms, on the paper's Fig. 3 start."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.control import build_problem, solve
from trackjam.simulation.build import displacements as scenario_displacements


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


def test_exact_honours_its_budget_through_the_dispatch(fig3_problem):
    full = solve(fig3_problem, "exact", [])
    assert full.optimal and full.gap == 0.0
    capped = solve(fig3_problem, "exact", [], node_limit=1)
    assert capped.nodes == 1 and not capped.optimal and capped.objective + capped.gap >= full.objective - 1e-12
    for name in ("greedy", "grasp"):
        sol = solve(fig3_problem, name, [np.random.default_rng([0, j]) for j in range(3)], samples=50, iterations=2)
        assert not sol.optimal and np.isnan(sol.gap)  # no certificate from a heuristic


@pytest.mark.parametrize("key, value, words", [
    ("time_limit_s", "0", "greater than 0"), ("time_limit_s", "-1", "greater than 0"),
    ("time_limit_s", "1e9", "less than or equal to 3600"), ("time_limit_s", ".nan", "finite"),
    ("node_limit", "-1", "greater than or equal to 0"), ("node_limit", "1.5", "integer"),
    ("node_limit", "1e13", "less than or equal to"), ("node_limit", "true", "integer"),
])
def test_a_bad_search_budget_is_one_line_naming_the_key(key, value, words):
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        load_scenario("paper-fig3", [f"control.{key}={value}"])
    assert "\n" not in str(info.value) and f"control.{key}" in str(info.value) and words in str(info.value)


def test_the_configuration_offers_exactly_the_registered_solvers():
    import typing

    from trackjam.config.model import Control
    from trackjam.control.solve import SOLVERS

    assert set(typing.get_args(Control.model_fields["solver"].annotation)) == set(SOLVERS)


def test_a_registered_function_is_a_solver(fig3_problem):
    from trackjam.control.solve import SOLVERS, register
    from trackjam.control.objective import to_solution

    @register("all-off-test")
    def all_off(problem, rngs, options):
        n = problem.n_agents
        return to_solution(problem, np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64))

    try:
        sol = solve(fig3_problem, "all-off-test", [])
        assert np.all(sol.move == 0) and np.all(sol.level == 0) and sol.feasible
        with pytest.raises(ValueError):
            register("all-off-test")(all_off)
    finally:
        del SOLVERS["all-off-test"]


def test_a_scenario_naming_a_script_registered_solver_is_told_where_such_a_solver_runs():
    # it had been pydantic's bare "Input should be 'greedy', 'grasp' or 'exact'"
    from trackjam.control.solve import SOLVERS, register
    from trackjam.errors import ConfigError

    register("cautious-test")(lambda problem, rngs, options: None)
    try:
        with pytest.raises(ConfigError, match=r"'cautious-test' is a solver registered from a script: solve\(\), "
                                              r"solver_policy\(\) and Planned take it"):
            load_scenario("paper-fig3", ["control.solver=cautious-test"])
    finally:
        del SOLVERS["cautious-test"]
    with pytest.raises(ConfigError) as err:  # a name nobody registered gets no such hint
        load_scenario("paper-fig3", ["control.solver=cautious-test"])
    assert "registered" not in str(err.value)


@pytest.mark.parametrize("name, fn, error, words", [
    (["a"], lambda p, r, o: None, ValueError, "register: a solver's name must be a non-empty text"),
    ("", lambda p, r, o: None, ValueError, "register: a solver's name must be a non-empty text"),
    ("five-test", 5, TypeError, "register('five-test'): expected a function"),
])
def test_register_refuses_what_is_not_a_named_function(name, fn, error, words):
    # all were taken, and failed at a run's first step (or as "unhashable type")
    from trackjam.control.solve import SOLVERS, register

    before = dict(SOLVERS)
    with pytest.raises(error) as err:
        register(name)(fn)
    assert str(err.value).startswith(words) and SOLVERS == before


def test_a_solver_that_returns_no_solution_is_named(fig3_problem):
    from trackjam.control.solve import SOLVERS, register

    register("none-test")(lambda problem, rngs, options: None)
    try:
        with pytest.raises(TypeError, match="^solver 'none-test' returned NoneType, not a Solution$"):
            solve(fig3_problem, "none-test", [])
    finally:
        del SOLVERS["none-test"]
