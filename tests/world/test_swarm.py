"""Several truth targets: their own streams, times, occlusions and jamming responses; one target
is today's truth bit for bit."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.simulation.build import seed_tree, target_ids, target_params, targets_params
from trackjam.world.swarm import TruthSwarm, target_streams
from trackjam.world.target import TruthTarget

LIST = (
    "targets=[{id: a, initial: [20, 20, 20, 1.5, 2.0, 1.7], appears: 2, disappears: 12, occlusions: [[5, 6]]},"
    " {id: b, initial: null, appears: 4, occlusions: [[8, 9], [11, 11]]},"
    " {id: c, initial: [80, 80, 80, -1, 0, 0], response: {threshold_db: -40, steps: 2, action: hover}}]"
)


def _swarm(overrides, seed_node=None):
    s = load_scenario("paper-fig3", overrides)
    truth_seed = seed_tree(s.seed, s.n_agents)[0] if seed_node is None else seed_node
    return s, TruthSwarm.from_seed(targets_params(s), target_ids(s), truth_seed)


def _trace(swarm, steps):
    out = []
    for t in range(1, steps + 1):
        swarm.step(t)
        out.append((swarm.states.copy(), swarm.exists.copy(), swarm.detectable.copy()))
    return out


@pytest.mark.parametrize("overrides", [[], ["target.initial=null"], ["target.stochastic={birth_prob: 0.3, survival_prob: 0.8}"]])
def test_one_target_is_todays_truth_bit_for_bit(overrides):
    s, swarm = _swarm(overrides)
    truth_seed = seed_tree(s.seed, s.n_agents)[0]
    today = TruthTarget(target_params(s), np.random.default_rng(truth_seed))  # as the engine builds it
    assert swarm.ids == (0,)
    for t in range(1, 41):
        swarm.step(t)
        today.step(t)
        want = np.full(6, np.nan) if today.state is None else today.state
        assert np.array_equal(swarm.states[0], want, equal_nan=True)
        assert swarm.exists[0] == today.exists and swarm.detectable[0] == today.detectable


def test_target_streams_are_the_seed_nodes_children_however_often_asked():
    node = np.random.SeedSequence(7).spawn(3)[0]
    first = [g.uniform(size=4) for g in target_streams(node, 3)]
    node.spawn(5)  # spawning from the node elsewhere does not move the targets' streams
    again = [g.uniform(size=4) for g in target_streams(node, 3)]
    fresh = np.random.SeedSequence(7).spawn(3)[0]
    numpy_children = [np.random.default_rng(c).uniform(size=4) for c in fresh.spawn(2)]
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert np.array_equal(first[0], np.random.default_rng(np.random.SeedSequence(7).spawn(3)[0]).uniform(size=4))
    assert all(np.array_equal(a, b) for a, b in zip(first[1:], numpy_children))
    assert len({tuple(a) for a in first}) == 3


def test_adding_a_target_keeps_the_draws_of_those_before_it():
    two = LIST.rsplit(", {id: c", 1)[0] + "]"
    _, small = _swarm(["target=null", two])
    _, big = _swarm(["target=null", LIST])
    for (xs, es, ds), (xb, eb, db) in zip(_trace(small, 25), _trace(big, 25)):
        assert np.array_equal(xs, xb[:2], equal_nan=True) and np.array_equal(es, eb[:2]) and np.array_equal(ds, db[:2])


def test_each_target_enters_leaves_and_hides_on_its_own_script():
    _, swarm = _swarm(["target=null", LIST])
    trace = _trace(swarm, 20)
    for t, (x, exists, detectable) in enumerate(trace, start=1):
        assert list(exists) == [2 <= t <= 12, t >= 4, True]
        assert list(detectable) == [2 <= t <= 12 and not 5 <= t <= 6, t >= 4 and t not in (8, 9, 11), True]
        assert np.array_equal(np.isfinite(x).all(axis=1), exists) and np.isnan(x[~exists]).all()
        assert np.array_equal(swarm.ids, ("a", "b", "c"))
    assert np.array_equal(trace[1][0][0], [20, 20, 20, 1.5, 2.0, 1.7])  # a appears at step 2 at its x_0


def test_detectable_positions_hide_occluded_and_absent_targets():
    _, swarm = _swarm(["target=null", LIST])
    for t in range(1, 6):
        swarm.step(t)
    pos, det = swarm.detectable_positions, swarm.detectable
    assert list(det) == [False, True, True]  # a occluded at 5, b present from 4
    assert np.isnan(pos[0]).all() and np.array_equal(pos[1:], swarm.positions[1:])
    assert np.isfinite(swarm.positions[0]).all()


def test_two_random_targets_draw_from_different_streams():
    _, swarm = _swarm(["target=null", "targets=[{initial: null}, {initial: null}]"])
    first = swarm.first_positions
    assert np.isfinite(first).all() and not np.array_equal(first[0], first[1])
    swarm.step(1)
    assert np.array_equal(swarm.positions, first) and np.isnan(swarm.first_positions).all()


def test_only_the_jammed_target_with_a_response_is_downed():
    _, swarm = _swarm(["target=null", LIST])
    on = np.array([1.0, 1.0, 1.0])  # 0 dBW, above the -40 dBW threshold
    for t in range(1, 6):
        swarm.step(t)
        swarm.apply_jamming(t, on)
    assert swarm.downed_at == [None, None, 2]  # only c has a response; two jammed steps
    hover_at = swarm.positions[2].copy()
    swarm.step(6)
    assert np.array_equal(swarm.positions[2], hover_at) and np.array_equal(swarm.states[2, 3:], [0, 0, 0])


def test_a_swarm_needs_one_id_and_stream_per_target_and_unique_ids():
    s = load_scenario("paper-fig3")
    p = target_params(s)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="one id and one stream"):
        TruthSwarm([p, p], [0], [rng, rng])
    with pytest.raises(ValueError, match="unique"):
        TruthSwarm([p, p], [1, "1"], [rng, np.random.default_rng(1)])
    with pytest.raises(ValueError, match="one received power per target"):
        TruthSwarm([p], [0], [rng]).apply_jamming(1, np.ones(2))
