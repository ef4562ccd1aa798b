"""The engines handed something that is not a scenario name it in one exception, instead of an
AttributeError on its first attribute deep inside."""

import pytest

import trackjam
from trackjam.simulation.engine import Simulation
from trackjam.simulation.swarm import SwarmSimulation


@pytest.mark.parametrize("make", [trackjam.simulate, Simulation, SwarmSimulation])
@pytest.mark.parametrize("bad, kind", [("paper-fig3", "str"), ({"steps": 3}, "dict"), (None, "NoneType")])
def test_what_is_not_a_scenario_is_named(make, bad, kind):
    with pytest.raises(TypeError, match=rf"^scenario: expected a Scenario \(trackjam.load_scenario\(...\)\), got {kind}$"):
        make(bad)
