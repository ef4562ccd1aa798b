"""Policies for the learning environment and a helper that rolls them out on seeds.

A policy is a function obs dict -> actions dict. ``solver_policy`` lets the engine's own
planning decide (greedy, GRASP or the exact optimum), ``random_policy`` draws uniform actions;
``rollout`` runs any of them, or a learned controller, on the same seeds so that they can be
compared run by run.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sized

import numpy as np

from trackjam.env.parallel import MAX_SEED, Planned, TrackjamParallelEnv

Policy = Callable[[dict], dict]
# the random policy's stream: the episode seed with this second word, so it is independent of the
# engine's streams (spawned from the seed alone) and repeats with the seed
RANDOM_POLICY_WORD = 1


def solver_policy(env: TrackjamParallelEnv, solver: str) -> Policy:
    """The team's plan by ``solver`` (one of greedy, grasp, exact), decided by the engine inside
    the step: the run is the one :func:`trackjam.simulate` gives with that solver and seed (with
    several targets, the swarm engine's moves, levels and served tracks)."""
    _check_env(env, "solver_policy")
    if not isinstance(solver, str) or solver not in env.solvers:  # a list was "unhashable type"
        raise ValueError(f"solver_policy: unknown solver {solver!r:.40}; choose from {', '.join(env.solvers)}")
    env.check_solver(solver)  # with the scenario's settings for it (GRASP's work cap, close_in)
    action = Planned(solver)

    def policy(obs: dict) -> dict:
        return {a: action for a in obs if a in env.agents}

    policy.__name__ = solver
    return policy


class RandomPolicy:
    """Uniform actions from every agent's action space, from a stream the episode seed fixes."""

    __name__ = "random"

    def __init__(self, env: TrackjamParallelEnv, seed: int = 0) -> None:
        self.env = env
        self.reset(seed)

    def reset(self, seed: int) -> None:
        self.rng = np.random.default_rng([_seed(seed, "random_policy"), RANDOM_POLICY_WORD])

    def __call__(self, obs: dict) -> dict:
        return {a: self.rng.integers(self.env.action_space(a).nvec) for a in self.env.agents}


def _seed(seed, where: str) -> int:
    """An episode seed: a whole number >= 0 (a bool, a fraction or a text is a mistake)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
        raise ValueError(f"{where}: seed {seed!r} must be an integer >= 0 and <= 2^63 - 1")
    return int(seed)


def random_policy(env: TrackjamParallelEnv, seed: int = 0) -> RandomPolicy:
    _check_env(env, "random_policy")
    return RandomPolicy(env, seed)


def _check_env(env, who: str) -> None:
    """``env`` is one of ours, or a wrapper of one such as :func:`trackjam.env.normalized` (None
    failed later, at the first step, with an AttributeError)."""
    if not isinstance(getattr(env, "unwrapped", None), TrackjamParallelEnv):
        raise TypeError(f"{who}: env must be trackjam.env.parallel_env(...)'s environment or a wrapper of it, "
                        f"got {type(env).__name__}")


def rollout(env: TrackjamParallelEnv, policy: Policy, seeds: Iterable[int],
            progress: Callable[[dict], None] | None = None) -> list[dict]:
    """One episode per seed; per episode the run summary (:func:`trackjam.metrics.summary.summarise`)
    with ``policy`` (its name), ``return`` (the summed shared reward), its two parts ``xi`` (summed
    Xi at the truth) and ``penalty`` (summed jam penalty), ``steps`` and ``end``.
    A policy with a ``reset(seed)`` method is reset at the start of each episode."""
    _check_env(env, "rollout")
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, Iterable):
        raise ValueError(f"rollout: seeds must be an iterable of integers >= 0 (one episode each), got {seeds!r}")
    # every argument checked before the first episode: a bad last seed, a policy or a progress that
    # cannot be called were found after the episodes before them had run, and their rows were lost
    # (seeds of known length are all checked first; a generator, which may not end, as it goes)
    # int() made 1.5 and 1.7 the same episode
    seeds = ([_seed(seed, "rollout") for seed in seeds] if isinstance(seeds, Sized)
             else (_seed(seed, "rollout") for seed in seeds))
    if not callable(policy):
        raise TypeError(f"rollout: policy must be callable (observations -> actions), got {type(policy).__name__}")
    if progress is not None and not callable(progress):
        raise TypeError(f"rollout: progress must be callable (one row each) or None, got {type(progress).__name__}")
    rows = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        if hasattr(policy, "reset"):
            policy.reset(int(seed))
        total, xi, violations, steps, end = 0.0, 0.0, 0.0, 0, ""
        while env.agents:
            obs, rewards, _, _, infos = env.step(policy(obs))
            total += next(iter(rewards.values()))
            xi += next(iter(infos.values()))["xi"]
            violations += sum(i["violation"] for i in infos.values())
            steps += 1
            end = next(iter(infos.values())).get("end", "")
        summary = env.sim.result().summary
        row = {**summary, "policy": getattr(policy, "__name__", type(policy).__name__), "seed": int(seed),
               "return": total, "xi": xi, "penalty": env.jam_penalty * violations, "steps": steps, "end": end}
        row.pop("solver", None)  # the scenario's solver, not necessarily who decided
        rows.append(row)
        if progress is not None:
            progress(row)
    return rows
