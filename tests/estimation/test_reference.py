"""At its default particle counts (10k + 2k birth) the filter is compared with a high-particle
reference (50k + 200k, without the two-scan proposal) when evidence is weak: one agent 6.5-8.5 m
from the target, p_D = 0.95 (6 / r)^2, clutter as configured, the filter starting from nothing
(e_0 = 0).

The comparison is built so that it has no selection bias. Positions are compared on the steps a
reference run confirms (e > 0.5); a run compared on the steps it selected itself looks better
than it is (its lucky steps are the ones picked: two reference runs of different seeds differ by
about 0.35 m that way, and the earlier form of this test, which selected with the very reference
run it compared against, put half of its 0.97 m gap there). So each draw runs the reference
``REFERENCE_RUNS`` times; each run in turn selects the steps, and the filter is compared with the
mean of the *other* reference runs on them. A reference run put in the filter's place must then
show no gap (checked below)."""

import functools
import math

import numpy as np

from trackjam.config import load_scenario
from trackjam.radio.antenna import detection_probability
from trackjam.radio.measurement import sample_scan
from trackjam.world.motion import cv_step
from trackjam.world.target import reflect
from trackjam.simulation.build import antenna_model, make_filter

DRAWS, STEPS, REPEATS, REFERENCE_RUNS = 20, 12, 4, 4
CUTOFF = 10.0  # position errors are capped as OSPA caps them (c = 10 m)
DEFAULT = load_scenario("paper-fig3")
# the resampling options of ours for a new track (README, "The filter against a high-particle reference")
OPTIONS = load_scenario("paper-fig3", filter__reserve_memory=1, filter__velocity_jitter=0.5)
FILTERS = {"default": DEFAULT, "options": OPTIONS}
REFERENCE = load_scenario("paper-fig3", filter__particles=50_000, filter__birth_particles=200_000)
ANT = antenna_model(DEFAULT)


def scenario_draw(k):
    """Truth of Eq. (1) from a uniform start (velocity within +-3 m/s per axis) and the scans of
    one agent that keeps a fixed offset of 6.5-8.5 m from it, antenna on the target."""
    rng = np.random.default_rng(np.random.SeedSequence([2021, k]))
    x = np.r_[rng.uniform(25, 75, 3), rng.uniform(-3, 3, 3)]
    d = rng.normal(size=3)
    offset = -rng.uniform(6.5, 8.5) * d / np.linalg.norm(d)
    steps = []
    for t in range(STEPS):
        if t:
            x = reflect(cv_step(x, rng, DEFAULT.target.accel_var), DEFAULT.area.low, DEFAULT.area.high)
        u = x[:3] + offset
        p_d = float(detection_probability(x[:3], u, x[:3], ANT.l_max, ANT))
        Z, _ = sample_scan(rng, x, u, p_d, DEFAULT.sensor.noise_std, DEFAULT.sensor.clutter_rate, ANT.max_range)
        steps.append((x.copy(), u, Z))
    return steps


def run(scenario, steps, seed, **kw):
    """Existence and capped position error of one filter run over a draw's scans, per step."""
    f = make_filter(scenario, np.random.default_rng(seed), **kw)
    e, err = [], []
    for x, u, Z in steps:
        f.predict()
        est = f.update(Z, u, x[:3], ANT.l_max)
        e.append(est.existence)
        err.append(min(float(np.linalg.norm(est.mean[:3] - x[:3])), CUTOFF))
    return np.array(e), np.array(err)


@functools.cache
def reference_runs(k):
    """Draw k's ``REFERENCE_RUNS`` reference runs."""
    steps = scenario_draw(k)
    return [run(REFERENCE, steps, 10_000 * (j + 1) + k, two_scan=False) for j in range(REFERENCE_RUNS)]


@functools.cache
def mean_run(which, k):
    """The mean existence and error of ``REPEATS`` runs of the filter of ``FILTERS[which]`` on
    draw k."""
    steps = scenario_draw(k)
    repeats = [run(FILTERS[which], steps, 20_000 + 100 * k + r) for r in range(REPEATS)]
    return np.mean([e for e, _ in repeats], axis=0), np.mean([p for _, p in repeats], axis=0)


def gaps(candidate, refs):
    """(mean existence gap over the steps, position gaps on the selected steps) of ``candidate``
    (e, err) against the reference runs ``refs``: each run selects the steps it confirms and the
    candidate is compared with the mean of the others there."""
    e_gap = np.mean(candidate[0] - np.mean([e for e, _ in refs], axis=0))
    pos = []
    for j, (e_sel, _) in enumerate(refs):
        others = [p for i, (_, p) in enumerate(refs) if i != j]
        held = e_sel > 0.5
        pos.extend(candidate[1][held] - np.mean(others, axis=0)[held])
    return e_gap, pos


def summary(which):
    """Existence gap (mean, standard error over draws) and pooled position gap (mean, standard
    error, steps) of a filter (``which``: "default" or "options") or, for
    ``which = None``, of reference run 0 against the other reference runs."""
    ge, gp = [], []
    for k in range(DRAWS):
        refs = reference_runs(k)
        e, p = gaps(refs[0], refs[1:]) if which is None else gaps(mean_run(which, k), refs)
        ge.append(e)
        gp.extend(p)
    return np.mean(ge), np.std(ge) / math.sqrt(DRAWS), np.mean(gp), np.std(gp) / math.sqrt(len(gp)), len(gp)


def test_the_comparison_has_no_selection_bias():
    """A reference run in the filter's place shows no gap; compared on the steps it selected
    itself (the earlier design) it would look about 0.35 m better than the others."""
    ge, se_e, gp, se_p, n = summary(None)
    print(f"reference vs reference: existence {ge:+.4f} ± {se_e:.4f}, position {gp:+.3f} ± {se_p:.3f} m ({n} steps)")
    assert n >= 30
    assert abs(ge) < 3 * se_e + 0.01
    assert abs(gp) < 3 * se_p + 0.1


def test_default_filter_against_the_high_particle_reference_under_weak_evidence():
    ge, se_e, gp, se_p, n = summary("default")
    print(f"default vs reference: existence {ge:+.4f} ± {se_e:.4f}, position {gp:+.3f} ± {se_p:.3f} m ({n} steps)")
    assert n >= 100  # enough confirmed steps to judge positions
    # measured: -0.034 ± 0.012 in existence and +0.72 ± 0.08 m in position (README, "Our
    # decisions"); the filter before the two-scan proposal (proposal share 0.5, reserve n / 5)
    # was -0.067 and +1.79 m in the earlier, biased comparison
    assert abs(ge) < 0.05
    assert gp < 1.0  # a margin for other machines' rounding, which moves particles (the old filter: 1.79)


def test_the_resampling_options_narrow_the_gap():
    """`filter.reserve_memory: 1` and `filter.velocity_jitter: 0.5` at the default particle
    counts: the gaps shrink, on the same draws and seeds as the default's (measured: -0.006 ±
    0.010 and +0.28 ± 0.07 m; a reference run in the filter's place: -0.006 and +0.12 m)."""
    ge, se_e, gp, se_p, n = summary("options")
    ge0, _, gp0, _, _ = summary("default")
    print(f"with the options: existence {ge:+.4f} ± {se_e:.4f}, position {gp:+.3f} ± {se_p:.3f} m ({n} steps)")
    assert abs(ge) < 0.025 and abs(ge) < abs(ge0) - 0.01
    assert gp < 0.5 and gp < gp0 - 0.2
