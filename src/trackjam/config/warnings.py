"""Suspicious but legal values: each gives one line of warning and the run goes on."""

from __future__ import annotations

from trackjam.config.model import Scenario

NARROW_ANGLE_DEG = 5.0


def scenario_warnings(s: Scenario) -> list[str]:
    """One line per suspicious value of ``s``, naming its key."""
    out = []
    theta = s.antenna.opening_angle_deg
    if theta < NARROW_ANGLE_DEG:
        out.append(
            f"antenna.opening_angle_deg: {theta:g} deg is a very narrow cone (radians by mistake? "
            f"{theta:g} rad is {theta * 57.29577951308232:.0f} deg)"
        )
    listed = s.targets is not None
    for k, t in enumerate(s.target_list):
        key = f"targets[{k}]" if listed else "target"
        if t.stochastic is None and t.appears > s.steps:
            out.append(f"{key}.appears: step {t.appears} comes after the last step ({s.steps}); the target never appears")
        late = [f"[{a}, {b}]" for a, b in t.occlusions if b > s.steps and a <= s.steps]
        if late:
            out.append(f"{key}.occlusions: {_few(late)} reach past the last step ({s.steps})")
        # a preset shortened with `--set steps=5`: its occlusion [14, 17] simply never comes
        after = [f"[{a}, {b}]" for a, b in t.occlusions if a > s.steps]
        if after:
            out.append(f"{key}.occlusions: {_few(after)} start after the last step ({s.steps}), so this run has "
                       f"{'none of them' if len(after) > 1 else 'no such occlusion'}")
    late = [f"comms.failures[{k}]" for k, f in enumerate(s.comms.failures) if f.step > s.steps]
    if late:
        out.append(f"{_few(late)}: start after the last step ({s.steps}); the agent never fails")
    if s.comms.delay_steps >= s.steps and s.n_agents > 1:
        out.append(f"comms.delay_steps: {s.comms.delay_steps} is not less than steps ({s.steps}); no teammate's "
                   "message ever arrives, and each agent acts alone on its own filter")
    c = s.control
    if c.belief_at_least is not None and c.plan_over != "belief":
        out.append(f"control.belief_at_least: {c.belief_at_least} has no effect under control.plan_over: {c.plan_over} "
                   "(it is the n of the steps planned over the belief)")
    if c.belief_spread is not None and c.plan_over != "belief":
        out.append(f"control.belief_spread: {c.belief_spread:g} m has no effect under control.plan_over: {c.plan_over} "
                   "(it bounds plan_over: belief)")
    samples = type(c).model_fields["belief_samples"].default
    if c.belief_samples != samples and c.plan_over != "belief":
        out.append(f"control.belief_samples: {c.belief_samples} has no effect under control.plan_over: {c.plan_over} "
                   "(it is the sample size of the steps planned over the belief)")
    if c.greedy_aim != "team" and c.solver != "greedy":
        out.append(f"control.greedy_aim: {c.greedy_aim} has no effect under control.solver: {c.solver} (it is where "
                   "greedy, Eq. 11, evaluates p_D; only the learning environment's Planned('greedy') would read it)")
    if s.oracle is not None and s.oracle != type(s.oracle)() and not any(
            a <= s.steps for t in s.target_list for a, _ in t.occlusions):
        out.append("oracle: has no effect in this run, which has no occlusion (each oracle acts before, during or "
                   "after an occlusion of the target)")
    if s.filter.association_misses and (s.targets is None or len(s.targets) < 2):
        out.append("filter.association_misses: true has no effect with one target (its Bernoulli filter has no "
                   "association; the LMB filters of several targets have)")
    if s.filter.team_proposals and s.fusion.share != "scans":
        out.append("filter.team_proposals: true has no effect under fusion.share: posteriors (it draws the births "
                   "near the teammates' scans, which only fusion.share: scans gives an agent)")
    diagonal = sum((h - l) ** 2 for l, h in zip(s.area.low, s.area.high)) ** 0.5
    if s.metrics.gate >= diagonal:
        out.append(f"metrics.gate: {s.metrics.gate:g} m is at least the area's diagonal ({diagonal:.3g} m); every "
                   "confirmed estimate counts as held and none as a false track")
    at: dict[tuple, list[int]] = {}
    for j, u in enumerate(s.agents.initial):
        at.setdefault(tuple(u), []).append(j)
    for u, js in at.items():
        if len(js) > 1:
            which = _few([f"[{j}]" for j in js])
            out.append(f"agents.initial: {which} start at the same position {list(u)}")
    return out


def _few(items: list[str], shown: int = 3) -> str:
    """The first ``shown`` items and how many more: 1000 late failures had made a warning of
    20,961 characters."""
    return ", ".join(items[:shown]) + (f" and {len(items) - shown} more" if len(items) > shown else "")
