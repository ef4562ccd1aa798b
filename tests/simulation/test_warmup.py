"""The warm-up before a timed run: it compiles every kernel the run will use."""

import subprocess
import sys

import pytest

from trackjam.config import load_scenario
from trackjam.simulation.build import WARM_STEPS, warm_up_scenario

# In a fresh process: count the compiled signatures of every numba kernel of trackjam after the
# warm-up and after the real run. The run must add none (nothing compiled inside its timing),
# and the warm-up must have added some (the check is not vacuous).
SCRIPT = """
import sys
from numba.core.registry import CPUDispatcher
from trackjam.config import load_scenario
from trackjam.simulation.loop import simulate  # every kernel module imported, no kernel called yet
from trackjam.simulation.warmup import warm_up

def signatures():
    return {f"{n}.{k}": len(v.signatures) for n, m in list(sys.modules.items()) if n.startswith("trackjam")
            for k, v in vars(m).items() if isinstance(v, CPUDispatcher)}

s = load_scenario("paper-fig3", sys.argv[1:])
start = signatures()
warm_up(s)
warm = signatures()
simulate(s)
after = signatures()
print(sum(warm.values()) - sum(start.values()), {k: v for k, v in after.items() if warm.get(k) != v})
"""

SMALL = ["steps=18", "filter.particles=300", "filter.birth_particles=100", "control.grasp.samples=200", "control.grasp.iterations=3"]


@pytest.mark.parametrize(
    "extra",
    [
        [],  # paper-fig3: GRASP, occluded at 14-17 so the fall-back search runs too
        ["control.solver=exact", "filter.birth=measurement"],
        ["control.solver=greedy", "control.fallback=hover", "filter.cue=null"],
    ],
)
def test_after_the_warm_up_the_run_compiles_nothing(extra):
    r = subprocess.run([sys.executable, "-c", SCRIPT, *SMALL, *extra], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    compiled, new_in_run = r.stdout.strip().split(" ", 1)
    assert int(compiled) > 0
    assert new_in_run == "{}"


def test_the_warm_up_twin_keeps_what_selects_kernels_and_shrinks_the_rest():
    s = load_scenario("paper-fig3", ["control.solver=exact", "agents.n_azimuth=4", "steps=50"])
    w = warm_up_scenario(s)
    assert w.steps == WARM_STEPS and w.filter.particles < 100 and w.control.grasp.iterations == 2
    assert w.target.appears == 1 and w.target.occlusions == []
    assert (w.control.solver, w.agents, w.antenna, w.sensor, w.fusion) == (s.control.solver, s.agents, s.antenna, s.sensor, s.fusion)
    assert w.filter.birth == s.filter.birth and w.filter.cue == s.filter.cue and w.seed == s.seed
