"""Physical bounds of the configuration and the resource check: a scenario that validates can
run on this machine without overflow, NaN or an allocation it cannot hold.

The bounds are generous for drones (lengths up to 100 km, speeds up to 1000 m/s, powers between
-200 and 60 dBW); the resource check estimates, from the scenario alone, the memory a run holds
at once (particles x agents, the planning tables N x N x C x C, the logs) and the work of one
step (particles x measurements x agents, GRASP samples x iterations x agents, and planning over
the belief: points x agents x candidates x levels), and refuses a
scenario past half the machine's memory or past ``MAX_STEP_WORK`` operations a step, naming the
key that grew it.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

from trackjam.errors import ConfigError, shortened

MAX_LENGTH = 1e5  # m: coordinates, heights, radii, standard deviations of positions
MAX_SPEED = 1e3  # m/s
MAX_ACCEL_VAR = 1e4  # m^2/s^4, an acceleration standard deviation of 100 m/s^2
MIN_EXTENT = 1.0  # m: the smallest side of the area
DBW_MIN, DBW_MAX = -200.0, 60.0  # dBW: 1e-20 W to 1 MW
MIN_ANGLE_DEG, MAX_ANGLE_DEG = 0.1, 170.0  # deg; past 170 the clutter range h_a / cos(theta_a / 2) explodes
MAX_STEPS = 100_000
MAX_THREADS = 1024  # control.grasp.threads' bound, and TRACKJAM_THREADS'
NUMBA_MAX_THREADS = 2**31 - 1  # NUMBA_NUM_THREADS: numba sets no bound of its own; a C int's
MAX_AGENTS = 64
MAX_STEP_WORK = 1e9  # elementary operations a step (about 5 to 30 s on one core)
NAME_MAX = 100
# the swarm engine's budgets (several targets), mirrored here because the configuration imports
# nothing of the engine (tests/test_config_hostile.py holds them equal): an agent's LMB filter
# keeps at most MAX_TRACKS tracks and MAX_BIRTHS births a scan (sum_j r_B(y_j) <= lambda_B = 0.1,
# births below r = 1e-3 are pruned), and the team plans at most MAX_AIMS aims
MAX_TRACKS = 20
MAX_BIRTHS = 100
MAX_AIMS = 4
# an experiment builds every (configuration, trial) scenario up front (about 1 ms each, without
# a word): the cap keeps that under half a minute
MAX_TRIAL_RUNS = 20_000
WORKER_BYTES = 3e8  # a worker process with numpy, numba and trackjam loaded (about 200 MB) and its trial's copies

_NAME = re.compile(r"[^\W][\w.+-]*")

# the defaults the check compares a key to when it says which key made a scenario too big
_DEFAULTS = {
    "agents.initial": 3, "agents.radial_steps": 3, "agents.n_inclination": 8, "agents.n_azimuth": 8,
    "filter.particles": 10_000, "filter.birth_particles": 2000, "sensor.clutter_rate": 3.0,
    "steps": 30, "control.grasp.samples": 10_000, "control.grasp.iterations": 100, "targets": 3,
    "control.belief_samples": 16, "comms.delay_steps": 1,
}
# covariance intersection of k estimates (SLSQP over the simplex, numerical gradients): about
# CI_OPS_BASE + CI_OPS_K2 k^2 operations, measured 3.3 ms at k = 3, 16 ms at 16, 0.36 s at 32 and
# 0.68 s at 64 (the iterations vary, hence the loose fit); 64 targets seen by 64 agents had
# spent 56 s of a step in the swarm engine's track fusion, which the cap did not count
CI_OPS_BASE, CI_OPS_K2 = 3e5, 2.5e4


def fusion_ops(k: int) -> float:
    """Operations of one covariance intersection of ``k`` estimates."""
    return CI_OPS_BASE + (CI_OPS_K2 * k * k if k > 2 else 0.0)


# planning over the belief (control.plan_over: belief), measured on 3 to 32 agents and 48 to 8192
# belief points S (up to control.belief_samples from each agent) at about 10 ns an operation:
# tabulating p_D at every point, (S, N, C, L), costs about 20 operations an entry (0.4-0.9 us per
# point, agent and candidate at L = 4 levels, the greedy choice over it 0.04 us an entry); the
# exact solver, when its time budget runs out, bounds its open branches by a numpy pass per
# point and depth, about 800 operations per point and agent squared (14 s of a 16 s step at
# N = 32, S = 2048, time_limit_s = 1); a GRASP evaluation costs S times the point's
BELIEF_TABLE_OPS = 20.0
BELIEF_EXACT_OPS = 800.0


MAX_SEED = 2**63 - 1  # the scenario's `seed`; numpy's generators take more, the logs' int64 columns do not


def shown_integer(value: Any) -> str:
    """An option's value as a one-line message shows it: an integer of more than 30 digits by
    its size, not its digits."""
    return f"{value}" if not isinstance(value, int) or abs(value) < 10**30 else "(an integer of more than 30 digits)"


def check_seed(seed: Any) -> None:
    """Refuse (one line, naming --seed) a seed of a run or an experiment outside [0, 2^63 - 1]."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ConfigError(f"--seed {shown_integer(seed)}: must be an integer in [0, 2^63 - 1]")


def check_name(name: str) -> None:
    """A scenario name names a folder: no separators, no markup, no leading dot, not too long."""
    if not 1 <= len(name) <= NAME_MAX or not _NAME.fullmatch(name) or name.startswith("_"):
        shown = name if len(name) <= 40 else name[:37] + "..."
        raise ValueError(
            f"{shown!r} is not a safe folder name: use 1 to {NAME_MAX} letters, digits, '_', '-', '+' or '.', "
            "starting with a letter or digit"
        )


def memory_budget() -> float:
    """Half of the memory this process may use: the machine's, or its cgroup's limit or its
    address-space limit (``ulimit -v``) if lower [bytes]. Under `ulimit -v 4000000` a run of
    10^7 particles had passed the check and failed with a MemoryError traceback."""
    total = 8e9
    try:
        total = float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit.isdigit():
            total = min(total, float(limit))
    except OSError:
        pass
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY and soft > 0:
            total = min(total, float(soft))
    except (ImportError, OSError, ValueError):  # no resource module (Windows)
        pass
    return total / 2


def measurements_bound(clutter_rate: float) -> float:
    """Measurements per scan that Poisson(lambda_c) clutter plus the target nearly never exceeds."""
    return clutter_rate + 6 * math.sqrt(clutter_rate) + 1


def candidates_bound(radial_steps: int, n_inclination: int, n_azimuth: int) -> int:
    """Eq. (3)'s distinct displacements plus hover, counted without building them.

    Per radial step: the poles (phi = 0, and phi = pi when N_phi is even) once each, and every
    other inclination with all N_theta azimuths; phi and 2 pi - phi give the same vectors when
    N_theta is even (the azimuth turns by pi), so then only phi in (0, pi) counts."""
    poles = 1 + (n_inclination % 2 == 0)
    if n_azimuth % 2 == 0:
        others = math.ceil(n_inclination / 2) - 1
    else:
        others = n_inclination - poles
    return radial_steps * (poles + others * n_azimuth) + 1


def estimate(s: Any) -> dict[str, tuple[float, tuple[str, ...]]]:
    """Named resource figures of a scenario, each with the keys that drive it.

    ``memory_*`` in bytes, ``work_*`` in elementary operations of one step."""
    N = len(s.agents.initial)
    C = candidates_bound(len(s.agents.radial_steps), s.agents.n_inclination, s.agents.n_azimuth)
    L = len(s.antenna.power_levels_db)
    m = measurements_bound(s.sensor.clutter_rate)
    n, n_b = s.filter.particles, s.filter.birth_particles
    moves = ("agents.n_inclination", "agents.n_azimuth", "agents.radial_steps", "agents.initial")
    particles = ("filter.particles", "filter.birth_particles", "agents.initial")
    out = {
        # gain[i, j, ci, cj] and p_d[i, c, l] of the planning problem (float64)
        "memory_tables": (8.0 * (N * N * C * C + N * C * L), moves),
        # each agent keeps n particles of 6 states (+ weights, + the prediction's noise); one update
        # at a time holds n + n_b of them several times over and the birth proposal's n_b x m offsets
        "memory_particles": (
            N * n * 8.0 * 14 + (n + n_b) * 8.0 * 30 + n_b * m * 24.0,
            particles + ("sensor.clutter_rate",),
        ),
        # the measurement log (6 columns) and the per-agent log (about 25 columns)
        "memory_logs": (s.steps * N * 8.0 * (6 * m + 25), ("steps", "sensor.clutter_rate", "agents.initial")),
        # with fusion.share: scans every agent weighs every teammate's scan too (N^2 updates a step)
        "work_filter": (N * (N if s.fusion.share == "scans" else 1) * (n + n_b) * (m + 1.0),
                        particles + ("sensor.clutter_rate",)),
        # a lost or late message (or a failed channel) leaves each agent planning from its own
        # inbox: every agent builds its own table (measured 19.6 s a step at 64 agents with
        # comms.delay_steps: 1, against 0.64 s)
        "work_tables": (float(N * N * C * C) * (N if _split(s) else 1), moves),
    }
    if s.control.solver == "grasp":
        # GRASP's neighbour lists: a C x C x 3 distance array, its norms and their argsort
        # (measured about 40 bytes a pair: 257 MB over greedy at C = 1,803)
        out["memory_neighbours"] = (40.0 * C * C, moves)
    several = s.targets is not None and len(s.targets) > 1
    if several:
        out.update(_swarm_estimate(s, N, C, L, m))
    elif s.fusion.share == "posteriors" and N > 2:
        # agents holding the same messages fuse once; lost messages, or stale ones coasted for
        # each agent, give every agent an inbox of its own
        own = s.comms.loss > 0 or (s.comms.delay_steps > 0 and s.comms.stale == "coast")
        out["work_fusion"] = ((N if own else 1) * fusion_ops(N), ("agents.initial",))
    if s.comms.delay_steps:
        # messages in flight: each step every agent sends its prediction, plan and posterior (or
        # scan) to the N - 1 others, held for delay_steps steps; an entry per recipient (about
        # 128 bytes) and the message itself (its estimate or scan, about 2.5 kB + 24 per
        # measurement); measured 3.5 kB per message and sender at N = 16, 4.7 kB here. With
        # several targets a message holds the sender's tracks (about 0.5 kB each, up to MAX_TRACKS)
        body = 2500.0 + 24.0 * m + (512.0 * MAX_TRACKS if several else 0.0)
        out["memory_messages"] = (
            min(s.comms.delay_steps, s.steps) * N * 3.0 * ((N - 1) * 128.0 + body),
            ("comms.delay_steps", "agents.initial"),
        )
    # planning over the belief (one target; the swarm engine refuses it): S points, each agent's
    # control.belief_samples when every agent believes or searches
    belief = s.control.plan_over == "belief" and not several
    S = N * s.control.belief_samples if belief else 1
    if belief:
        keys = ("control.belief_samples", "agents.initial")
        exact = BELIEF_EXACT_OPS * N if s.control.solver == "exact" else 0.0
        # p_D at every point (S, N, C, L) and, for exact, its ranked copy and suffix maximum
        out["memory_belief"] = (8.0 * S * N * C * L * (3 if s.control.solver == "exact" else 1), keys)
        out["work_belief"] = (float(S) * N * (C * L * BELIEF_TABLE_OPS + exact), keys)
    if s.control.solver == "grasp":
        out["work_grasp"] = (
            float(N) * s.control.grasp.samples * s.control.grasp.iterations * N * S,
            ("control.grasp.samples", "control.grasp.iterations", "agents.initial")
            + (("control.belief_samples",) if belief else ()),
        )
    return out


def _split(s: Any) -> bool:
    """Whether the agents can plan from inboxes of their own: lost or late messages, failures."""
    return s.comms.loss > 0 or s.comms.delay_steps > 0 or bool(s.comms.failures)


def _swarm_estimate(s: Any, N: int, C: int, L: int, m: float) -> dict[str, tuple[float, tuple[str, ...]]]:
    """The swarm engine's figures, which replace the one-target filter's and tables: each agent
    holds a confirmed track of n particles per target (up to MAX_TRACKS), the other tracks and
    the births of its scan at n_b, and updates them by its own scan or, with ``fusion.share:
    scans``, by every agent's; the plan's gains cover K_a = min(K, MAX_AIMS) aims per agent."""
    n, n_b = s.filter.particles, s.filter.birth_particles
    held = min(len(s.targets), MAX_TRACKS)
    per_agent = held * n + (MAX_TRACKS - held) * min(n, n_b) + min(m, MAX_BIRTHS) * n_b
    scans = N if s.fusion.share == "scans" else 1
    aims = min(len(s.targets), MAX_AIMS)
    particles = ("filter.particles", "filter.birth_particles", "agents.initial", "targets")
    moves = ("agents.n_inclination", "agents.n_azimuth", "agents.radial_steps", "agents.initial")
    # the logs hold the ids as text (4 bytes a character): a column of each target's row per step
    # and of every measurement's; a run holds about 4 times the rows' bytes (small arrays per step,
    # then the columns and the Parquet tables): 93 kB a step measured on swarm-3 at lambda_c = 50
    id_bytes = 4.0 * max(len(str(tg.id)) for tg in s.targets)
    per_step = 4 * (N * (8.0 * (6 * m + 25) + m * id_bytes) + len(s.targets) * (2 * id_bytes + 120.0))
    return {
        "memory_logs": (s.steps * per_step, ("steps", "sensor.clutter_rate", "agents.initial", "targets")),
        "memory_particles": (N * per_agent * 8.0 * 14, particles),
        "work_filter": (N * scans * per_agent * (m + 1.0), particles + ("sensor.clutter_rate",)),
        # the planner holds about three copies of its tables at once (measured: 7.6 GB at 64
        # agents against 2.5 GB counted once, 1.95 GB at 40 against 0.96)
        "memory_tables": (3 * 8.0 * (N * N * (aims * C) ** 2 + aims * (N * N * C * C + 2 * N * C * L + N)), moves),
        # under the comms faults each agent can hold a view of its own: a table and two fusions each
        "work_tables": (float(N * N * (aims * C) ** 2) * (N if _split(s) else 1), moves),
        # the predicted and the posterior tracks fused a step, a cluster of up to N per track
        "work_fusion": (2.0 * held * fusion_ops(N) * (N if _split(s) else 1), ("agents.initial", "targets")),
    }


def _value(s: Any, key: str) -> float:
    node = s
    for part in key.split("."):
        node = getattr(node, part)
    return float(len(node)) if isinstance(node, (list, tuple)) else float(node)


def _culprit(s: Any, keys: tuple[str, ...]) -> str:
    """The key furthest above its default (relative), the one a user most likely set too high."""
    return max(keys, key=lambda k: _value(s, k) / _DEFAULTS[k])


def _bytes(b: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= size:
            return f"{b / size:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def run_memory(s: Any) -> float:
    """The memory a run of ``s`` holds at once, by :func:`estimate` [bytes]."""
    return sum(b for k, (b, _) in estimate(s).items() if k.startswith("memory_"))


def check_trial_runs(trials: int, configurations: int) -> None:
    """Refuse (one line, naming --trials) an experiment whose plan alone would not end: every
    (configuration, trial) scenario is built and checked before the first trial runs."""
    runs = trials * configurations
    if runs > MAX_TRIAL_RUNS:
        counted = (f"{runs:,} trial runs ({configurations} configurations x {trials:,} trials)" if trials < 10**30
                   else "more than 10^30 trial runs")
        raise ConfigError(f"--trials {shown_integer(trials)}: {counted}, past the cap of {MAX_TRIAL_RUNS:,}; lower --trials")


def check_workers(workers: int, trial_memory: float) -> None:
    """Refuse (one line, naming --workers) a local pool that cannot fit this machine: each worker
    is a process of about ``WORKER_BYTES`` holding one trial at a time."""
    each = WORKER_BYTES + trial_memory
    budget = memory_budget()
    if workers > budget / each:  # compared exactly: workers * each overflowed a float past 309 digits
        most = max(1, int(budget // each))
        held = (f"{workers} worker processes would hold about {_bytes(workers * each)} of memory," if workers < 10**30
                else f"that many worker processes of about {_bytes(each)} each would hold")
        raise ConfigError(
            f"--workers {shown_integer(workers)}: {held} more than half of this machine's ({_bytes(2 * budget)}); "
            f"use at most {most}"
        )


def check_resources(s: Any) -> None:
    """Raise ValueError (one line, naming the key) when a run of ``s`` cannot fit this machine."""
    figures = estimate(s)
    memory = {k: v for k, v in figures.items() if k.startswith("memory_")}
    total = sum(b for b, _ in memory.values())
    budget = memory_budget()
    if total > budget:
        _, keys = max(memory.values(), key=lambda bk: bk[0])
        key = _culprit(s, keys)
        raise ValueError(
            f"{key}: a run would hold about {_bytes(total)} of memory, more than half of this machine's "
            f"({_bytes(2 * budget)}); lower {key}"
        )
    for name, (ops, keys) in figures.items():
        if name.startswith("work_") and ops > MAX_STEP_WORK:
            key = _culprit(s, keys)
            raise ValueError(
                f"{key}: one step would take about {ops:.2g} operations ({name.removeprefix('work_')}), "
                f"past the cap of {MAX_STEP_WORK:.0g}; lower {key}"
            )


def threads_variable(name: str, unset: str) -> int | None:
    """The whole number of threads in [1, MAX_THREADS] that the environment variable ``name``
    sets, None when it is unset or empty; anything else is refused in one line (``unset`` says
    what leaving it unset means)."""
    env = os.environ.get(name)
    if not env:
        return None
    text = env.strip()
    if not (text.isdecimal() and len(text) <= 4 and 1 <= int(text) <= MAX_THREADS):
        raise ConfigError(f"{name}={shortened(env, 40)!r}: must be a whole number of threads in "
                          f"[1, {MAX_THREADS}] (or unset: {unset})")
    return int(text)


def check_environment() -> None:
    """Refuse, in one line, a setting in the environment that a command would trip over:
    ``TRACKJAM_THREADS`` (read when a run builds its GRASP), ``NUMBA_NUM_THREADS`` (read by
    numba when it loads: 0 or -1 raised inside numba, text was a warning with a traceback), any
    other ``NUMBA_*`` variable numba cannot parse (:func:`_numba_variables`),
    ``NUMBA_DISABLE_JIT`` and a ``MPLBACKEND`` matplotlib does not know (:func:`_matplotlib_backend`). Every command checks them before it loads anything, so that
    `validate` refuses what `run` would."""
    threads_variable("TRACKJAM_THREADS", "one per agent up to the CPU count")
    env = os.environ.get("NUMBA_NUM_THREADS")
    if env is not None:  # numba's own variable, read as numba reads it: int(), set even when empty
        try:
            n = int(env)
        except ValueError:
            n = 0
        if not 1 <= n <= NUMBA_MAX_THREADS:
            raise ConfigError(f"NUMBA_NUM_THREADS={shortened(env, 40)!r}: must be a whole number of threads >= 1 "
                              "(or unset: numba's default, the CPU count)")
    if any(k.startswith("NUMBA_") and k != "NUMBA_NUM_THREADS" for k in os.environ):
        _numba_variables()
    if "MPLBACKEND" in os.environ:
        _matplotlib_backend()


# matplotlib's own backends (matplotlib.rcsetup); another name is checked by loading matplotlib
MATPLOTLIB_BACKENDS = frozenset({
    "gtk3agg", "gtk3cairo", "gtk4agg", "gtk4cairo", "macosx", "nbagg", "notebook", "qtagg", "qtcairo", "qt5agg",
    "qt5cairo", "tkagg", "tkcairo", "webagg", "wx", "wxagg", "wxcairo", "agg", "cairo", "pdf", "pgf", "ps", "svg",
    "template",
})


def _matplotlib_backend() -> None:
    """``MPLBACKEND``, read as matplotlib reads it when it loads (paid only when it is set): a
    name it does not know made ``import matplotlib`` raise, so a run simulated every step and
    then failed with a traceback where it draws its figure, writing nothing."""
    import sys

    value = os.environ["MPLBACKEND"]
    if "matplotlib" in sys.modules or value.lower() in MATPLOTLIB_BACKENDS or value.startswith("module://"):
        return  # known without loading matplotlib (0.25 s), which CI's common MPLBACKEND=Agg would pay on every command
    try:
        import matplotlib  # noqa: F401
    except ValueError:
        sys.modules.pop("matplotlib", None)
        raise ConfigError(f"MPLBACKEND={shortened(value, 40)!r}: matplotlib does not know this backend; unset it "
                          "(trackjam draws its figures with Agg, which needs no display) or name one of matplotlib's") from None


_UNPARSED = re.compile(r"Environment variable '(\w+)' is defined but its associated value '(.*?)' could not be parsed",
                       re.DOTALL)


def _numba_variables() -> None:
    """numba's other variables, read as numba reads them when it loads (the import is paid only
    when one is set). One it cannot parse was a warning of about ten lines with a traceback, and
    numba went on with its default; ``NUMBA_DISABLE_JIT=1`` ran every kernel as Python, which
    failed at the first compiled intrinsic with a traceback of 160 lines (and would have made a
    run take hours)."""
    import sys
    import warnings

    if "numba" not in sys.modules:  # loaded now, its warnings are caught; loaded before, they were said
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            import numba.core.config  # noqa: F401
        for w in caught:
            if m := _UNPARSED.search(str(w.message)):
                raise ConfigError(f"{m.group(1)}={shortened(m.group(2), 40)!r}: numba cannot read this value "
                                  "(see numba's documentation of its environment variables), or unset it")
    from numba.core import config

    if config.DISABLE_JIT:
        raise ConfigError("NUMBA_DISABLE_JIT: trackjam's kernels must be compiled (uncompiled, a run would take "
                          "hours, and one kernel uses an LLVM intrinsic that has no Python form); unset it")
