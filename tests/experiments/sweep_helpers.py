"""A cheap stand-in for the simulation, a ``python -m sweep_helpers`` entry that runs a sweep
with it (the interrupted-sweep tests kill that process), and the helpers those tests share.

``fake_trial`` is a deterministic function of the scenario (its seed, opening angle, number of
controls and the drawn positions), so an engine that loses, duplicates, reorders or mixes up
trials changes summary.csv. ``TRACKJAM_FAKE_SLEEP`` (seconds) makes each trial slow enough to
be interrupted; it does not change any result.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from trackjam.config import Scenario


def fake_trial(scenario: Scenario) -> dict:
    time.sleep(float(os.environ.get("TRACKJAM_FAKE_SLEEP", "0")))
    rng = np.random.default_rng(scenario.seed)
    u = np.asarray(scenario.agents.initial)
    x = np.asarray(scenario.target.initial[:3])
    d = np.linalg.norm(u - x, axis=1)
    theta = scenario.antenna.opening_angle_deg
    incidents = rng.integers(0, scenario.steps + 1, size=len(u)) * theta / 120.0
    ospa = np.abs(rng.normal(2.0, 1.0, size=scenario.steps))
    return {
        "jamming_incidents_per_agent": float(np.mean(np.floor(incidents))),
        "jamming_incidents": [int(v) for v in np.floor(incidents)],
        "target_received_w_mean": float(np.sum(1.0 / (1.0 + d**2))),
        "agent_received_w_mean": float(1e-4 * rng.uniform() * len(scenario.agents.radial_steps)),
        "transmit_w_mean": float(rng.choice([0.0, 1e-5, 0.1995, 1.122])),
        "ospa_mean": float(ospa.mean()),
        # the track quality a real trial reports: shares of the steps, a re-acquisition or not
        "held_share": float(np.mean(ospa < 2.0)),
        "false_track_share": float(np.mean((ospa >= 2.0) & (ospa < 3.0))),
        "missed_share": float(np.mean(ospa >= 3.0)),
        "ceiling_share": float(np.mean(d <= 8.0)),
        "reacquired_after_last_spell": float(rng.uniform() < 0.5),
        "step_s_mean": time.perf_counter() % 1.0,  # wall time: varies on purpose
        "solve_s_mean": 0.001,
        "steps": {"t": np.arange(1, scenario.steps + 1), "ospa": ospa},
    }


HERE = Path(__file__).resolve().parent
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]), "NUMBA_NUM_THREADS": "1"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(args: list[str], env=ENV) -> subprocess.Popen:
    # its own session: killing its process group kills it and its children, nothing else
    return subprocess.Popen(
        [sys.executable, *args], env=env, start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )


def kill(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    p.wait()


def wait_for_files(folder: Path, n: int, proc: subprocess.Popen | None = None, limit_s: float = 60) -> None:
    t0 = time.monotonic()
    while len(list(folder.glob("c*.parquet"))) < n:
        assert proc is None or proc.poll() is None, "the sweep ended before it could be interrupted"
        assert time.monotonic() - t0 < limit_s, "no trial finished"
        time.sleep(0.05)


def failing_trial(scenario: Scenario) -> dict:
    """``fake_trial``, except that trial 1 of every configuration raises."""
    if scenario.name.endswith("-t1"):
        raise RuntimeError(f"{scenario.name} failed")
    return fake_trial(scenario)


def killed_trial(scenario: Scenario) -> dict:
    """``fake_trial``, except that trial 1 of configuration 2 kills its own worker process, as the
    kernel's out-of-memory killer would, while ``TRACKJAM_KILL_TRIAL`` is set."""
    if scenario.name.endswith("-c2-t1") and os.environ.get("TRACKJAM_KILL_TRIAL"):
        os.kill(os.getpid(), signal.SIGKILL)
    return fake_trial(scenario)


def holding_trial(scenario: Scenario) -> dict:
    """A trial of an experiment with metrics of its own: shares of steps held, on a false
    track and missed (they sum to 1), plus the wall times every trial reports."""
    rng = np.random.default_rng(scenario.seed)
    held, false, missed = rng.dirichlet([4.0, 1.0, 2.0])
    return {"held_share": float(held), "false_share": float(false), "missed_share": float(missed),
            "step_s_mean": 0.01, "solve_s_mean": 0.001}


SWEEP = dict(trials=2, steps=3, seed=7, progress="none", trial=fake_trial)  # 2 configurations x 2 trials


if __name__ == "__main__":
    from sweep_helpers import fake_trial as trial  # by module name, so workers can import it

    from trackjam.experiments.engine import run_experiment

    name, out, workers = sys.argv[1], sys.argv[2], int(sys.argv[3])
    run_experiment(name, trials=int(sys.argv[4]), steps=3, seed=7, workers=workers, out=out,
                   progress="lines", trial=trial)
