"""The filter's particles meet the walls as the truth does."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.config import load_scenario
from trackjam.estimation.kernels import kernel_reflect
from trackjam.world.target import reflect
from trackjam.simulation.build import make_filter

LOW, HIGH = np.zeros(3), np.full(3, 100.0)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(*[st.floats(-150, 250)] * 3, *[st.floats(-10, 10)] * 3), min_size=1, max_size=20))
def test_compiled_reflection_matches_the_truths(rows):
    X = np.array(rows, dtype=float)
    expected = np.array([reflect(x, LOW, HIGH) for x in X])
    kernel_reflect(X, LOW, HIGH)
    assert np.allclose(X, expected)
    assert np.all((X[:, :3] >= 0) & (X[:, :3] <= 100))


def test_predicted_particles_stay_in_the_area_unless_told_otherwise():
    for walls, inside in (("reflect", True), ("none", False)):
        s = load_scenario("paper-fig3", [f"filter.walls={walls}", "filter.particles=2000"])
        f = make_filter(s, np.random.default_rng(0))
        f.reset_to(0.9, np.array([99.0, 50, 50, 6, 0, 0]), np.diag([0.1] * 3 + [0.1] * 3))
        f.predict()
        X = f.particles
        assert bool(np.all(X[:, 0] <= 100)) is inside
        if inside:
            assert np.mean(X[:, 3] < 0) > 0.9  # they bounced
