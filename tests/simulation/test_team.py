"""A team distributed in fact: each agent decides from the messages it received, and the seeded
fault model (loss, delay, failures) changes what it knows, never what it pretends to know."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.control.exact import enumerate_optimum
from trackjam.control.problem import build_problem
from trackjam.control.solve import solve
from trackjam.radio.antenna import received_power
from trackjam.simulation.agent import Message
from trackjam.simulation.loop import simulate
from trackjam.simulation.team import Exchange, TeamSettings
from trackjam.world.moves import displacement_set
from trackjam.simulation.build import antenna_model

FAST = ["control.solver=exact", "steps=8", "filter.particles=500", "filter.birth_particles=100"]


def run(*extra):
    return simulate(load_scenario("paper-fig3", FAST + list(extra)))


def by_agent(r, col, n=3):
    return r.agents[col].reshape(-1, n)


def settings(**kw):
    return TeamSettings(existence_rule="mean", feedback=True, searching=False, accel_var=0.5, **kw)


def test_every_agent_hears_the_whole_team_when_nothing_is_lost():
    r = run()
    assert np.all(r.agents["heard"] == 3)


def test_with_every_message_lost_each_agent_plans_alone():
    r = run("comms.loss=1")
    assert np.all(r.agents["heard"] == 1)
    # the team still acts: agents move and transmit on their own estimates
    assert np.any(r.agents["level_index"] > 0)


def test_a_delay_makes_every_teammate_stale():
    r = run("comms.delay_steps=1")
    assert np.all(r.agents["heard"] == 1)


def test_a_failed_publisher_is_heard_by_nobody_but_still_hears():
    r = run('comms.failures=[{"agent": 1, "step": 4, "mode": "publisher"}]')
    heard, t = by_agent(r, "heard"), r.steps["t"]
    assert np.all(heard[t < 4] == 3)
    assert np.all(heard[t >= 4, 0] == 2) and np.all(heard[t >= 4, 2] == 2)
    assert np.all(heard[t >= 4, 1] == 3)


def test_a_failed_channel_cuts_both_ways():
    r = run('comms.failures=[{"agent": 2, "step": 3, "mode": "channel"}]')
    heard, t = by_agent(r, "heard"), r.steps["t"]
    assert np.all(heard[t >= 3, 2] == 1)
    assert np.all(heard[t >= 3, :2] == 2)


def test_a_broken_down_agent_hovers_silent_and_dark():
    r = run('comms.failures=[{"agent": 0, "step": 5, "mode": "breakdown"}]')
    t = r.steps["t"]
    mode, power = by_agent(r, "mode"), by_agent(r, "power_w")
    x = np.stack([by_agent(r, k)[:, 0] for k in "xyz"], axis=1)
    assert np.all(mode[t >= 5, 0] == "down") and np.all(power[t >= 5, 0] == 0)
    assert np.allclose(x[t >= 5], x[t == 5])
    assert np.all(np.isnan(by_agent(r, "existence")[t >= 5, 0]))
    assert np.all(by_agent(r, "measurements")[t >= 5, 0] == 0)
    assert np.all(by_agent(r, "heard")[t >= 5, 1:] == 2)
    # the team's report comes from the lowest working agent and stays a probability
    assert np.all((r.steps["existence"] >= 0) & (r.steps["existence"] <= 1))


def test_losses_are_seeded():
    a, b = run("comms.loss=0.4"), run("comms.loss=0.4")
    for k in ("x", "level_index", "heard", "existence"):
        assert np.array_equal(a.agents[k], b.agents[k], equal_nan=True)


def test_each_message_is_lost_with_the_configured_probability():
    n, rounds, p = 4, 3000, 0.3
    ex = Exchange(n, settings(loss=p), np.random.default_rng(0))
    got = 0
    for t in range(1, rounds + 1):
        boxes = ex.send(t, "prediction", [Message(j, "prediction", t) for j in range(n)])
        got += sum(len(b) - 1 for b in boxes)  # own message always arrives
    sent = rounds * n * (n - 1)
    share = got / sent
    half_width = 4 * np.sqrt(p * (1 - p) / sent)
    assert abs(share - (1 - p)) < half_width


def test_delayed_messages_arrive_exactly_late():
    ex = Exchange(2, settings(delay_steps=2), np.random.default_rng(0))
    stamps = []
    for t in range(1, 6):
        boxes = ex.send(t, "posterior", [Message(0, "posterior", t), Message(1, "posterior", t)])
        stamps.append([m.stamp for m in boxes[1] if m.sender == 0])
    assert stamps == [[], [], [1], [2], [3]]


def test_a_message_due_after_the_last_step_is_never_queued():
    # at comms.delay_steps 1000 every message of a short run had been held to the end (64 agents
    # x 1000 steps: 12 million entries, 777 MB); none of them could ever arrive
    ex = Exchange(2, settings(delay_steps=2, last_step=4), np.random.default_rng(0))
    stamps = []
    for t in range(1, 5):
        boxes = ex.send(t, "posterior", [Message(0, "posterior", t), Message(1, "posterior", t)])
        stamps.append([m.stamp for m in boxes[1] if m.sender == 0])
        assert all(arrival <= 4 for arrival, _ in ex.pending)
    assert stamps == [[], [], [1], [2]] and not ex.pending  # what is due by step 4 still arrives


def test_a_run_whose_delay_outlasts_it_queues_nothing_and_acts_as_before(monkeypatch):
    from trackjam.simulation import team as team_module
    from trackjam.simulation.engine import Simulation

    s = load_scenario("paper-fig3", FAST + ["steps=4", "comms.delay_steps=6"])
    queued = []
    original = team_module.Exchange.send

    def spy(self, t, kind, messages):
        out = original(self, t, kind, messages)
        queued.append(sum(len(v) for v in self.pending.values()))
        return out

    monkeypatch.setattr(team_module.Exchange, "send", spy)
    sim = Simulation(s)
    while not sim.done:
        sim.step()
    assert queued and max(queued) == 0
    # the same run with the messages queued (no last step known): the same logs
    monkeypatch.setattr(team_module.Exchange, "send", original)
    from dataclasses import replace

    old = Simulation(s)
    old.c = replace(old.c, team=replace(old.c.team, last_step=None))
    old.team.exchange.s = old.c.team
    while not old.done:
        old.step()
    a, b = sim.result(), old.result()
    for col in a.agents:
        if not col.endswith("_s"):
            np.testing.assert_array_equal(a.agents[col], b.agents[col])
    for col in a.steps:
        if not col.endswith("_s"):
            np.testing.assert_array_equal(a.steps[col], b.steps[col])
    assert old.team.exchange.pending  # it had held messages that never arrive


def test_a_late_message_waits_for_its_own_round_of_the_step():
    """A posterior a step late arrives in the posterior round of the next step, although the
    prediction round of that step comes first (it used to be dropped there)."""
    ex = Exchange(2, settings(delay_steps=1), np.random.default_rng(0))
    got = []
    for t in range(1, 4):
        ex.send(t, "prediction", [Message(0, "prediction", t), Message(1, "prediction", t)])
        ex.send(t, "plan", [Message(0, "plan", t), Message(1, "plan", t)])
        boxes = ex.send(t, "posterior", [Message(0, "posterior", t), Message(1, "posterior", t)])
        got.append([(m.kind, m.stamp) for m in boxes[1] if m.sender == 0])
    assert got == [[], [("posterior", 1)], [("posterior", 2)]]


def test_a_late_posterior_is_coasted_to_now_by_eq_1():
    from trackjam.estimation.bernoulli import Estimate
    from trackjam.simulation.team import coasted_posteriors
    from trackjam.world.motion import cv_matrices

    x = np.array([1.0, 2.0, 3.0, 0.5, -1.0, 2.0])
    P = np.diag([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    late = [Message(1, "posterior", 3, estimate=Estimate(0.8, x, P), prior_existence=0.7),
            Message(1, "posterior", 2, estimate=Estimate(0.6, x, P)),
            Message(2, "posterior", 4, estimate=Estimate(0.3, None, None))]
    out = coasted_posteriors(late, 5, accel_var=0.5)
    assert [(m.sender, m.stamp) for m in out] == [(1, 3), (2, 4)]  # each sender's latest only
    Phi, Gamma = cv_matrices(1.0)
    Q = 0.5 * Gamma @ Gamma.T
    mean, cov = Phi @ Phi @ x, Phi @ (Phi @ P @ Phi.T + Q) @ Phi.T + Q  # two steps by hand
    np.testing.assert_allclose(out[0].estimate.mean, mean)
    np.testing.assert_allclose(out[0].estimate.cov, cov)
    assert out[0].estimate.existence == 0.8 and out[0].prior_existence == 0.7
    assert out[1].estimate.mean is None and out[1].estimate.existence == 0.3


@pytest.mark.parametrize("stale, fused", [("drop", 1), ("coast", 3)])
def test_with_a_delay_each_agent_fuses_its_teammates_late_posteriors_only_when_coasting(monkeypatch, stale, fused):
    import trackjam.simulation.team as team

    sizes = []
    fuse = team.fuse_unchecked

    def spy(estimates, *args, **kwargs):
        sizes.append(len(estimates))
        return fuse(estimates, *args, **kwargs)

    monkeypatch.setattr(team, "fuse_unchecked", spy)
    run("comms.delay_steps=1", f"comms.stale={stale}")
    # step 1: nothing has arrived yet; from step 2 on, each agent holds its own fresh posterior
    # and, when coasting, its two teammates' posteriors of the step before
    assert sizes[:3] == [1, 1, 1] and set(sizes[3:]) == {fused}


@pytest.mark.parametrize("stale", ["drop", "coast"])
def test_with_a_delay_and_shared_scans_each_filter_weighs_its_teammates_late_scans_when_coasting(monkeypatch, stale):
    """fusion.share: scans with comms.delay_steps = 1: a teammate's scan of step t reaches a
    filter at step t + 1, marked one step late and taken from where the teammate stood at t;
    under ``drop`` no teammate's scan is weighed."""
    from trackjam.estimation.bernoulli import BernoulliFilter

    seen, positions = [], []
    update = BernoulliFilter.update

    def spy(self, Z, u, aim, level_w, others=()):
        seen.append([(o.lag, tuple(o.u)) for o in others])
        positions.append(tuple(u))
        return update(self, Z, u, aim, level_w, others)

    monkeypatch.setattr(BernoulliFilter, "update", spy)
    run("fusion.share=scans", "comms.delay_steps=1", f"comms.stale={stale}")
    steps = [seen[k:k + 3] for k in range(0, len(seen), 3)]
    at = [positions[k:k + 3] for k in range(0, len(positions), 3)]
    assert steps[0] == [[], [], []]
    for t in range(1, len(steps)):
        for j in range(3):
            want = [(1, at[t - 1][k]) for k in range(3) if k != j] if stale == "coast" else []
            assert steps[t][j] == want


def test_a_late_scan_weighs_each_particle_where_eq1_puts_it_lag_steps_before():
    from trackjam.estimation.bernoulli import Scan
    from trackjam.radio.measurement import h

    s = load_scenario("paper-fig3")
    ant = antenna_model(s)
    rng = np.random.default_rng(3)
    X = np.c_[rng.uniform(20, 40, (50, 3)), rng.normal(0, 3, (50, 3))]
    u, aim = np.array([25.0, 25.0, 25.0]), np.array([32.0, 30.0, 31.0])
    then = X.copy()
    then[:, :3] -= 2 * X[:, 3:]
    scan = Scan.of(h(then[:3], u) + 0.01, u, aim, ant.l_max, ant)
    args = (ant, s.sensor.noise_std, np.log(3.0))
    np.testing.assert_array_equal(scan.late(2).log_factors(X, *args), scan.log_factors(then, *args))
    assert not np.array_equal(scan.late(2).log_factors(X, *args), scan.log_factors(X, *args))


@pytest.mark.parametrize("seed", range(6))
def test_a_guarded_teammate_is_protected_by_the_exact_plan(seed):
    """A teammate heard from only long ago is a receiver with no moves and no say in Xi: the
    exact plan is the brute-force optimum of that problem and never jams it."""
    s = load_scenario("paper-fig3")

    ant = antenna_model(s)
    rng = np.random.default_rng(seed)
    aim = rng.uniform(30, 70, 3)
    planned = aim + rng.normal(0, 8, (2, 3))
    guard = aim + rng.normal(0, 6, (1, 3))
    D = displacement_set([3.0], 4, 8)
    problem = build_problem(np.vstack([planned, guard]), aim, D, ant, s.area.low, s.area.high, 1, True).guarded(2)
    sol = solve(problem, "exact", [])
    best_value, _, _ = enumerate_optimum(problem)
    assert sol.objective == pytest.approx(best_value)
    assert sol.move[2] == 0
    moved = planned + D[sol.move[:2]]
    levels_w = ant.levels_w[sol.level]
    at_guard = received_power(guard[0], moved, np.repeat(aim[None], 2, 0), levels_w[:2], ant).sum()
    assert at_guard < ant.delta_w


def test_the_log_says_whether_the_plan_is_proven_optimal():
    exact = run()
    tracking = exact.steps["mode"] == "track"
    assert tracking.any()
    assert np.all(exact.steps["optimal"][tracking]) and np.all(exact.steps["gap"][tracking] == 0)
    grasp = simulate(load_scenario("paper-fig3", ["control.solver=grasp", "control.grasp.samples=50", "control.grasp.iterations=3",
                                                  "steps=3", "filter.particles=500", "filter.birth_particles=100"]))
    assert not grasp.steps["optimal"].any() and np.all(np.isnan(grasp.steps["gap"]))


def test_an_exact_search_out_of_time_logs_its_certified_gap():
    six = [[30, 30, 30], [20, 10, 10], [10, 15, 15], [25, 25, 12], [15, 28, 22], [28, 12, 26]]
    r = simulate(load_scenario("paper-fig3", FAST[1:] + [f"agents.initial={six}", "control.solver=exact",
                                                         "control.time_limit_s=0.0001", "steps=2"]))
    stopped = ~r.steps["optimal"] & (r.steps["mode"] == "track")
    assert stopped.any()
    assert np.all(r.steps["gap"][stopped] > 0)


def test_a_node_budget_stops_the_same_searches_in_every_run():
    """control.node_limit: the search stops after that many nodes, whatever the clock says, so a
    run repeats exactly; without it the same steps are searched to the proven optimum."""
    six = [[30, 30, 30], [20, 10, 10], [10, 15, 15], [25, 25, 12], [15, 28, 22], [28, 12, 26]]
    base = FAST[1:] + [f"agents.initial={six}", "control.solver=exact", "control.time_limit_s=3600", "steps=2"]
    capped = [simulate(load_scenario("paper-fig3", base + ["control.node_limit=20"])) for _ in range(2)]
    tracking = capped[0].steps["mode"] == "track"
    stopped = ~capped[0].steps["optimal"] & tracking
    assert stopped.any() and np.all(capped[0].steps["gap"][stopped] > 0)
    for col in ("optimal", "gap", "objective"):
        np.testing.assert_array_equal(capped[0].steps[col], capped[1].steps[col])
    for col in ("level_index", "x", "y", "z"):
        np.testing.assert_array_equal(capped[0].agents[col], capped[1].agents[col])
    free = simulate(load_scenario("paper-fig3", base))
    assert np.all(free.steps["optimal"][free.steps["mode"] == "track"])


@pytest.mark.parametrize("loss, others", [(0.0, 2), (1.0, 0)])
def test_sharing_scans_updates_each_filter_with_every_scan_it_received(monkeypatch, loss, others):
    """fusion.share: scans: each agent's update gets its teammates' scans of the step (none when
    every message is lost), and the team's report is its lowest-index agent's own estimate."""
    from trackjam.estimation.bernoulli import BernoulliFilter

    seen = []
    update = BernoulliFilter.update

    def spy(self, Z, u, aim, level_w, others=()):
        seen.append(len(others))
        return update(self, Z, u, aim, level_w, others)

    monkeypatch.setattr(BernoulliFilter, "update", spy)
    r = run("fusion.share=scans", f"comms.loss={loss}")
    assert seen == [others] * (8 * 3)
    ex = by_agent(r, "existence")
    np.testing.assert_array_equal(r.steps["existence"], ex[:, 0])


def test_a_spread_out_track_is_not_reported():
    """fusion.report_spread: a track whose fused position spread exceeds the bound is not
    reported; a bound no track reaches changes nothing."""
    base = run()
    loose = run("fusion.report_spread=100000")
    tight = run("fusion.report_spread=0.001")
    for a in "xyz":
        np.testing.assert_array_equal(loose.steps[f"est_{a}"], base.steps[f"est_{a}"])
        assert np.all(np.isnan(tight.steps[f"est_{a}"]))
    assert np.any(np.isfinite(base.steps["est_x"]))
    np.testing.assert_array_equal(tight.steps["existence"], base.steps["existence"])


def test_a_team_that_believes_the_target_hidden_does_not_report_it(monkeypatch):
    """filter.visibility: the report needs P(exists and visible) > 0.5, the set the OSPA judges;
    without the mode the report is the paper's e_hat > 0.5."""
    from trackjam.estimation.fusion import FusedEstimate
    from trackjam.simulation.engine import Simulation, seen
    from trackjam.simulation.team import Team

    mean, cov = np.arange(6.0), np.eye(6)
    assert seen(FusedEstimate(0.9, mean, cov, np.ones(1))) == 0.9
    assert seen(FusedEstimate(0.9, mean, cov, np.ones(1), visible=0.5)) == pytest.approx(0.45)
    reports = []
    for visible in (None, 0.9, 0.5):
        monkeypatch.setattr(Team, "fuse", lambda self, posteriors, v=visible: FusedEstimate(0.9, mean, cov, np.ones(1), v))
        reports.append(Simulation(load_scenario("paper-fig3", FAST)).step().step["estimate"])
    np.testing.assert_array_equal(reports[0], mean[:3])
    np.testing.assert_array_equal(reports[1], mean[:3])
    assert reports[2] is None


def test_the_coasted_track_goes_on_from_the_last_coast_and_equals_the_coast_from_the_track_bit_for_bit():
    # coasting from the track at each step made a long search quadratic in its length (49 ms a
    # step after 6,000 steps of it); going on from the last coast is the same products in order
    from trackjam.simulation.agent import Agent
    from trackjam.world.motion import cv_coast

    rng = np.random.default_rng(3)
    mean, A = rng.normal(size=6) * 10, rng.normal(size=(6, 6))
    cov = A @ A.T + np.eye(6)
    agent = Agent(0, np.zeros(3), np.zeros(3), None, rng, rng)
    assert agent.coasted_track(0.5) is None
    agent.remember(0.9, mean, cov)
    for k in range(0, 40):
        if k:
            agent.remember(0.1, None, None)  # a step without a track
        x, P = agent.coasted_track(0.5)
        x_ref, P_ref = cv_coast(mean, cov, 0.5, k)
        assert np.array_equal(x, x_ref) and np.array_equal(P, P_ref), k
        x[:] = 0.0  # the caller's copy: the kept coast is not changed by it
    assert np.array_equal(agent.coasted_track(1.0)[0], cv_coast(mean, cov, 1.0, 39)[0])  # another accel_var
    agent.remember(0.9, mean + 1.0, cov)  # a new track: coasted from it
    assert np.array_equal(agent.coasted_track(0.5)[0], mean + 1.0)


@pytest.mark.parametrize("preset, extra", [("paper-fig3", ["control.grasp.samples=300", "control.grasp.iterations=5"]),
                                          ("pursuit", [])])
def test_with_every_message_delivered_every_agent_decides_the_same_x_bar_and_plan(monkeypatch, preset, extra):
    # the team acts as one: each agent forms x_bar from the same predictions and adopts the same
    # best plan, though its filter draws its own random numbers (under share: scans the agents'
    # own estimates differ), as the README says
    from trackjam.simulation import team as team_module

    from trackjam.control.pursuit import pursuit_aim

    decided, own = [], []
    original = team_module.Team.decide

    def spy(self, displacements, ant, low, high, *args, **kwargs):
        # each agent's x_bar from its own inbox, computed apart (decide computes it once per inbox)
        own.append([pursuit_aim([m.estimate for m in self.fresh(j)], np.array([m.position for m in self.fresh(j)]),
                                self.settings.aim, low, high) for j in self.working()])
        out = original(self, displacements, ant, low, high, *args, **kwargs)
        decided.append(out[0])
        return out

    monkeypatch.setattr(team_module.Team, "decide", spy)
    r = simulate(load_scenario(preset, ["steps=8", "filter.particles=500", "filter.birth_particles=100"] + extra))
    assert len(decided) == 8
    for step, apart in zip(decided, own):
        assert len({d.mode for d in step}) == 1 and all(d.heard == 3 for d in step)
        assert all(a is None for a in apart) or all(np.array_equal(a, apart[0]) for a in apart)
        for d, a in zip(step, apart):
            assert (d.x_bar is None and a is None) or np.array_equal(d.x_bar, a)
        aims = [d.aim for d in step]
        assert all(v is None for v in aims) or all(np.array_equal(v, aims[0]) for v in aims)
    if preset == "pursuit":  # its own estimates are each agent's own
        assert np.any(np.ptp(by_agent(r, "existence"), axis=1) > 0)


def test_greedy_at_its_own_prediction_is_eq_11_as_printed_agent_by_agent(monkeypatch):
    # control.greedy_aim: own (the paper's Eq. 11): an agent whose own predicted existence exceeds
    # 0.5 aims at its own predicted mean x_tilde^j, plans alone and applies its own choice, the
    # argmax of its own p_D there (ties: lower level, then lower move), found here by brute force
    from trackjam.simulation import team as team_module

    seen = []
    original = team_module.Team.decide

    def spy(self, displacements, ant, low, high, *args, **kwargs):
        heard = {j: self.fresh(j) for j in self.working()}
        out = original(self, displacements, ant, low, high, *args, **kwargs)
        seen.append((heard, out[0], displacements, ant, low, high))
        return out

    monkeypatch.setattr(team_module.Team, "decide", spy)
    # share: scans keeps the agents' own estimates apart (feedback makes them one under posteriors)
    simulate(load_scenario("paper-fig3", ["steps=10", "filter.particles=500", "filter.birth_particles=100",
                                          "control.solver=greedy", "control.greedy_aim=own",
                                          "fusion.share=scans", "antenna.pointing=aim"]))
    own_steps = apart = 0
    for heard, decisions, displacements, ant, low, high in seen:
        aims = []
        for j, d in enumerate(decisions):
            mine = next(m for m in heard[j] if m.sender == j)
            if mine.estimate.existence <= 0.5:
                continue
            own_steps += 1
            np.testing.assert_array_equal(d.aim, np.clip(mine.estimate.mean[:3], low, high))
            aims.append(d.aim)
            positions = np.array([m.position for m in heard[j]])
            p = build_problem(positions, d.aim, displacements, ant, low, high, 1, True)
            i = [m.sender for m in heard[j]].index(j)
            best = max(((p.p_d[i, c, level], -level, -c) for c in range(p.n_cand[i]) for level in range(p.n_levels)))
            assert (d.level, d.move) == (-best[1], int(p.move[i, -best[2]]))
        apart += len(aims) > 1 and not all(np.array_equal(a, aims[0]) for a in aims)
    assert own_steps >= 10 and apart >= 1  # the agents did aim at their own, different predictions


def test_greedy_aim_is_refused_where_it_cannot_hold_and_warned_where_it_does_nothing():
    import trackjam
    from trackjam.config.warnings import scenario_warnings
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError, match="control.greedy_aim `own`.*control.plan_over `point`"):
        load_scenario("paper-fig3", ["control.solver=greedy", "control.greedy_aim=own", "control.plan_over=belief"])
    # pursuit plans over the belief itself: the line says to set point, not to "leave" it
    with pytest.raises(ConfigError, match=r"set control.plan_over `point` with it \(it is `belief`\), or leave "
                                          r"control.greedy_aim `team`"):
        load_scenario("pursuit", ["control.solver=greedy", "control.greedy_aim=own"])
    lines = scenario_warnings(load_scenario("paper-fig3", ["control.greedy_aim=own"]))
    assert any(line.startswith("control.greedy_aim: own has no effect under control.solver: grasp") for line in lines)
    assert not any("greedy_aim" in line for line in scenario_warnings(
        load_scenario("paper-fig3", ["control.solver=greedy", "control.greedy_aim=own"])))
    with pytest.raises(ConfigError, match="control.greedy_aim: 'own' is not simulated with several targets"):
        trackjam.simulation.build.build_swarm(load_scenario("swarm-3", ["control.solver=greedy",
                                                                      "control.greedy_aim=own"]))
