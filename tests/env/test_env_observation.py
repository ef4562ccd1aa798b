"""An agent's observation vector, built directly from its parts (no environment): every entry
lands under its name in ``observation_layout``, and ``observation_bounds`` bounds exactly the
entries the layout says are bounded."""

import numpy as np
import pytest

from trackjam.env.observation import STATE, observation_bounds, observation_layout, observe
from trackjam.estimation.bernoulli import Estimate
from trackjam.simulation.agent import Message


def estimate(base: float, e: float) -> Estimate:
    return Estimate(existence=e, mean=base + np.arange(6.0), cov=np.eye(6))


def message(k: int) -> Message:
    # whole numbers and quarters: exact in float32, and different for every sender and field
    return Message(sender=k, kind="prediction", stamp=3, position=np.array([k, k + 0.25, k + 0.5]) * 10,
                   estimate=estimate(100.0 * (k + 1), 0.25 * (k + 1)))


@pytest.mark.parametrize("j, heard", [(0, [1, 2, 3]), (2, [0, 3]), (3, [1])])
def test_each_teammates_block_holds_what_that_teammate_sent(j, heard):
    N = 4
    own = estimate(-50.0, 0.75)
    position = np.array([1.0, 2.0, 3.0])
    obs = observe(j, position, own, [message(k) for k in heard], N, 0.5)
    assert obs.dtype == np.float32 and obs.shape == (len(observation_layout(N)),)
    o = dict(zip(observation_layout(N), obs.tolist()))
    expected = {"own.x": 1.0, "own.y": 2.0, "own.z": 3.0, "own.est.e": 0.75, "time": 0.5}
    expected |= {f"own.est.{s}": -50.0 + i for i, s in enumerate(STATE)}
    # teammates in index order, skipping j: slot 1 is the lowest other index
    for slot, k in enumerate((k for k in range(N) if k != j), start=1):
        if k in heard:
            m = message(k)
            expected[f"mate{slot}.received"] = 1.0
            expected |= {f"mate{slot}.{a}": float(v) for a, v in zip("xyz", m.position)}
            expected |= {f"mate{slot}.pred.{s}": float(v) for s, v in zip(STATE, m.estimate.mean)}
            expected[f"mate{slot}.pred.e"] = m.estimate.existence
        else:  # nothing heard: the whole block is 0
            expected |= {name: 0.0 for name in o if name.startswith(f"mate{slot}.")}
    assert o == expected


def test_the_bounds_hold_the_own_position_in_the_area_and_flags_in_the_unit_interval():
    low, high = np.array([-5.0, 0.0, 2.0]), np.array([60.0, 70.0, 80.0])
    lo, hi = observation_bounds(3, low, high)
    names = observation_layout(3)
    for i, name in enumerate(names):
        if name in ("own.x", "own.y", "own.z"):
            k = "xyz".index(name[-1])
            assert (lo[i], hi[i]) == (low[k], high[k]), name
        elif name.endswith((".e", ".received")) or name == "time":
            assert (lo[i], hi[i]) == (0.0, 1.0), name
        else:  # estimates and announced positions: unbounded
            assert (lo[i], hi[i]) == (-np.inf, np.inf), name
