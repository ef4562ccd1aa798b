"""The resampling options of ours for a new track (`filter.reserve_memory`,
`filter.velocity_jitter`): what each changes in the particle set, that both leave the filter
exactly as before when off, and that a weighted set still represents the same density."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.estimation.bernoulli import NEVER
from trackjam.radio.measurement import h
from trackjam.simulation.build import antenna_model, make_filter

ANT = antenna_model(load_scenario("paper-fig3"))
U = np.array([40.0, 40.0, 40.0])
TARGET = np.array([46.0, 44.0, 43.0])  # 7.8 m from U, on the antenna's axis


def scenario(**kw):
    return load_scenario("paper-fig3", **{f"filter__{k}": v for k, v in kw.items()})


def near(f, point, radius):
    """Particles of the surviving density within ``radius`` of ``point`` (positions)."""
    return int(np.sum(np.linalg.norm(f.particles[:, :3] - point, axis=1) < radius))


def seen_then_missed(seed, seen=1, **kw):
    """A filter from nothing: ``seen`` scans holding the measurement of a target at rest (no
    clutter), then an empty scan. Returns the particles near the target after the last
    detection and the filter after the miss."""
    f = make_filter(scenario(**kw), np.random.default_rng(seed))
    z = h(TARGET[None, :], U)
    for _ in range(seen):
        f.predict()
        f.update(z, U, TARGET, ANT.l_max)
    after_seen = near(f, TARGET, 3.0)
    f.predict()
    f.update(np.empty((0, 3)), U, TARGET, ANT.l_max)
    return after_seen, f


def test_off_the_options_change_nothing():
    """0 and 0.0 are the filter as it was: the same draws, the same particles, bit for bit."""
    a = make_filter(scenario(), np.random.default_rng(5))
    b = make_filter(scenario(reserve_memory=0, velocity_jitter=0.0), np.random.default_rng(5))
    z = h(TARGET[None, :], U)
    for Z in (z, np.empty((0, 3)), z + [0.3, 0.01, 0.0]):
        for f in (a, b):
            f.predict()
            f.update(Z, U, TARGET, ANT.l_max)
        assert np.array_equal(a.particles, b.particles) and np.array_equal(a.log_w, b.log_w)
        assert a.estimate().existence == b.estimate().existence


def test_a_track_seen_once_then_missed_keeps_its_reserved_slots():
    """Without memory a miss returns a track seen once to the plain resampling, which keeps about
    its weight's share of its particles (a few dozen); with `reserve_memory: 1` the particles
    the last scan supported keep the reserved slots, min(3 n_b, 0.4 n) = 3600 of the 9,000."""
    seen0, plain = seen_then_missed(3)
    seen1, kept = seen_then_missed(3, reserve_memory=1)
    assert seen0 == seen1 > 1000  # the detection itself: the same draws, no memory to use yet
    assert near(plain, TARGET, 5.0) < 200
    assert near(kept, TARGET, 5.0) > 3000
    ages, counts = np.unique(kept._age, return_counts=True)
    assert ages.tolist() == [1, NEVER] and counts[0] == 3600


def test_memory_lasts_its_number_of_scans():
    """The reserve counts a line supported 0..m scans ago, no older: after a detection and two
    empty scans memory 1 has let the track go, memory 2 keeps it."""
    counts = {}
    for m in (1, 2):
        _, f = seen_then_missed(3, reserve_memory=m)
        f.predict()
        f.update(np.empty((0, 3)), U, TARGET, ANT.l_max)
        counts[m] = near(f, TARGET, 8.0)
        assert set(np.unique(f._age)) <= {2, NEVER}  # no scan since has supported anything
    assert counts[1] < 200 < 2500 < counts[2]


def test_the_velocity_kernel_moves_only_the_extra_copies_and_only_their_velocities():
    rng = np.random.default_rng(0)
    f = make_filter(scenario(velocity_jitter=0.5), np.random.default_rng(1))
    X = np.c_[rng.uniform(0, 100, (500, 3)), rng.uniform(-3, 3, (500, 3))]
    w = np.ones(500)
    w[:5] = 0.5  # five supported particles hold 0.5 % of the weight: the reserve applies
    w /= w.sum()
    supported = np.zeros(500, dtype=bool)
    supported[:5] = True
    X_new, log_w, parents = f._resample(X, w, supported, 400)
    reserve = min(3 * f.n_b, int(0.4 * 400))
    assert np.all(supported[parents[:reserve]]) and not np.any(supported[parents[reserve:]])
    assert np.array_equal(X_new[:, :3], X[parents, :3])  # positions untouched
    first = np.r_[True, parents[1:reserve] != parents[:reserve - 1]]
    assert np.array_equal(X_new[:reserve][first], X[parents[:reserve]][first])  # each parent's first copy kept
    dv = X_new[:reserve][~first, 3:] - X[parents[:reserve]][~first, 3:]
    assert dv.shape[0] == reserve - 5
    assert np.all(dv != 0) and abs(dv.std() - 0.5) < 0.05 and abs(dv.mean()) < 0.05
    assert np.array_equal(X_new[reserve:], X[parents[reserve:]])  # the rest: plain copies
    # the weights are those of the split resampling: each part keeps its mass
    assert np.isclose(np.exp(log_w[:reserve]).sum(), w[:5].sum()) and np.isclose(np.exp(log_w).sum(), 1.0)


def test_the_velocity_kernel_leaves_a_tracked_target_alone():
    """Once the supported particles carry their share of the slots the resampling is plain and
    nothing is jittered."""
    f = make_filter(scenario(velocity_jitter=0.5), np.random.default_rng(1))
    X = np.random.default_rng(0).uniform(0, 10, (100, 6))
    w = np.full(100, 0.01)
    supported = np.zeros(100, dtype=bool)
    supported[:80] = True
    X_new, _, parents = f._resample(X, w, supported, 50)
    assert np.array_equal(X_new, X[parents])


@pytest.mark.parametrize("key, value", [("reserve_memory", -1), ("reserve_memory", 101), ("reserve_memory", 1.5),
                                        ("velocity_jitter", -0.1), ("velocity_jitter", float("nan")),
                                        ("velocity_jitter", 1e9)])
def test_bad_values_are_one_line_naming_the_key(key, value):
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        scenario(**{key: value})
    message = str(err.value)
    assert f"filter.{key}" in message and "\n" not in message
