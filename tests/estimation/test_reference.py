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
show no gap (checked below).

The draws, not the steps, are the independent units: a draw's dozen selected steps share one
truth and one set of reference runs, and a slipped run errs on all of them at once. So the
standard error of a position gap is taken over the draws (a cluster-robust one); treated as
independent, the ~400 steps give one three times too small. Each filter runs ``REPEATS`` = 16
times a draw: with 4, the position gap moved by 0.2-0.4 m from one set of filter seeds to
another (the options' 0.28 to 0.52 m, the default's 0.72 to 1.10 m over four sets)."""

import functools
import math

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.radio.antenna import detection_probability
from trackjam.radio.measurement import sample_scan
from trackjam.world.motion import cv_step
from trackjam.world.target import reflect
from trackjam.simulation.build import antenna_model, make_filter

DRAWS, STEPS, REPEATS, REFERENCE_RUNS = 20, 12, 16, 4
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


def clustered(groups):
    """Mean of the pooled values and its standard error over the groups (the draws), each
    group's values summed: a cluster-robust standard error."""
    values = np.concatenate(groups)
    m = float(np.mean(values))
    g = len(groups)
    return m, math.sqrt(sum(float(np.sum(np.asarray(x) - m)) ** 2 for x in groups) * g / (g - 1)) / len(values)


def per_draw(which):
    """Each draw's (existence gap, position gaps) of a filter (``which``: "default" or
    "options") or, for ``which = None``, of reference run 0 against the other reference runs."""
    out = []
    for k in range(DRAWS):
        refs = reference_runs(k)
        out.append(gaps(refs[0], refs[1:]) if which is None else gaps(mean_run(which, k), refs))
    return out


def summary(draws):
    """Of :func:`per_draw`'s figures: existence gap (mean, standard error over draws), pooled
    position gap (mean, standard error over the steps as if independent), the number of steps
    and the position gap's standard error over the draws."""
    ge = [e for e, _ in draws]
    gp = [x for _, p in draws for x in p]
    _, se_draws = clustered([np.asarray(p) for _, p in draws])
    return (np.mean(ge), np.std(ge) / math.sqrt(DRAWS), np.mean(gp), np.std(gp) / math.sqrt(len(gp)), len(gp),
            se_draws)


def test_the_cluster_robust_error_is_the_plain_one_for_one_value_a_group():
    """One value a group: the standard error over groups is the plain one (ddof = 1)."""
    x = np.random.default_rng(1).normal(size=25)
    m, se = clustered([x[i:i + 1] for i in range(25)])
    assert m == pytest.approx(x.mean()) and se == pytest.approx(x.std(ddof=1) / math.sqrt(25))
    # groups moving together: the error over groups is larger than the pooled one
    g = [np.full(10, v) + 0.01 * np.arange(10) for v in x]
    assert clustered(g)[1] > 2.5 * np.concatenate(g).std() / math.sqrt(250)


def test_the_comparison_has_no_selection_bias():
    """A reference run in the filter's place shows no gap; compared on the steps it selected
    itself (the earlier design) it would look about 0.35 m better than the others."""
    ge, se_e, gp, se_p, n, se_d = summary(per_draw(None))
    print(f"reference vs reference: existence {ge:+.4f} ± {se_e:.4f}, position {gp:+.3f} ± {se_d:.3f} m "
          f"(standard error over draws; {se_p:.3f} over the {n} steps as if independent)")
    assert n >= 30
    assert abs(ge) < 3 * se_e + 0.01
    assert abs(gp) < 3 * se_p + 0.1


def test_default_filter_against_the_high_particle_reference_under_weak_evidence():
    ge, se_e, gp, se_p, n, se_d = summary(per_draw("default"))
    print(f"default vs reference: existence {ge:+.4f} ± {se_e:.4f}, position {gp:+.3f} ± {se_d:.3f} m ({n} steps)")
    assert n >= 100  # enough confirmed steps to judge positions
    # measured with 16 runs a draw: -0.030 in existence and +0.70 ± 0.22 m in position (README,
    # "Our decisions"); the filter before the two-scan proposal (proposal share 0.5, reserve n / 5)
    # was -0.067 and +1.79 m in the earlier, biased comparison
    assert abs(ge) < 0.05
    assert gp < 1.25  # 4 runs a draw gave 0.72-1.10 m over four seed sets; 16 runs halve that spread


def test_the_resampling_options_narrow_the_gap():
    """`filter.reserve_memory: 1` and `filter.velocity_jitter: 0.5` at the default particle
    counts, on the same draws, steps and seeds as the default's, paired draw by draw (measured
    with 16 runs a draw: existence -0.005 against the default's -0.030, position +0.25 against
    +0.70 m, the paired position difference -0.45 ± 0.18 m, standard error over the draws)."""
    opt, dflt = per_draw("options"), per_draw("default")
    ge, se_e, gp, se_p, n, se_d = summary(opt)
    ge0 = summary(dflt)[0]
    print(f"with the options: existence {ge:+.4f} ± {se_e:.4f}, position {gp:+.3f} ± {se_d:.3f} m ({n} steps)")
    assert abs(ge) < 0.025 and abs(ge) < abs(ge0) - 0.01
    diff, se = clustered([np.asarray(po) - np.asarray(pd) for (_, po), (_, pd) in zip(opt, dflt)])
    print(f"options - default, paired by step: {diff:+.3f} ± {se:.3f} m (standard error over draws)")
    assert gp < 0.6 and diff < -0.1
