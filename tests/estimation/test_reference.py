"""At its default particle counts (10k + 2k birth) the filter matches a high-particle reference
(50k + 200k, without the two-scan proposal) when evidence is weak: one agent 6.5-8.5 m from the
target, p_D = 0.95 (6 / r)^2, clutter as configured, the filter starting from nothing (e_0 = 0)."""

import math

import numpy as np

from trackjam.config import load_scenario
from trackjam.radio.antenna import detection_probability
from trackjam.radio.measurement import sample_scan
from trackjam.world.motion import cv_step
from trackjam.world.target import reflect
from trackjam.simulation.build import antenna_model, make_filter

DRAWS, STEPS, REPEATS = 20, 12, 4
CUTOFF = 10.0  # position errors are capped as OSPA caps them (c = 10 m)
DEFAULT = load_scenario("paper-fig3")
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
    f = make_filter(scenario, np.random.default_rng(seed), **kw)
    e, err = [], []
    for x, u, Z in steps:
        f.predict()
        est = f.update(Z, u, x[:3], ANT.l_max)
        e.append(est.existence)
        err.append(min(float(np.linalg.norm(est.mean[:3] - x[:3])), CUTOFF))
    return np.array(e), np.array(err)


def test_default_filter_matches_the_high_particle_reference_under_weak_evidence():
    gaps_e, pooled, draws_confirmed = [], [], 0
    for k in range(DRAWS):
        steps = scenario_draw(k)
        e_ref, err_ref = run(REFERENCE, steps, 10_000 + k, two_scan=False)
        runs = [run(DEFAULT, steps, 20_000 + 100 * k + r) for r in range(REPEATS)]
        e = np.mean([a for a, _ in runs], axis=0)
        err = np.mean([b for _, b in runs], axis=0)
        gaps_e.append(np.mean(e - e_ref))
        held = e_ref > 0.5
        draws_confirmed += int(held.any())
        pooled.extend(err[held] - err_ref[held])
    gap_e, se_e = np.mean(gaps_e), np.std(gaps_e) / math.sqrt(DRAWS)
    gap_pos = np.mean(pooled)
    print(f"existence gap {gap_e:+.4f} ± {se_e:.4f}, position gap {gap_pos:+.3f} m "
          f"over {len(pooled)} steps the reference confirmed, in {draws_confirmed} draws")
    assert draws_confirmed >= 12 and len(pooled) >= 60  # enough confirmed steps to judge positions
    # the filter before the two-scan proposal (proposal share 0.5, reserve n / 5) measured
    # -0.067 and +1.79 m on these draws; the Monte Carlo error of the existence gap is ~0.01
    assert abs(gap_e) < 0.04
    assert gap_pos < 1.2
