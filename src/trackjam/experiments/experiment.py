"""What an experiment is: the configurations it compares, the panels of its figure, and the
experiment itself (its trials, metrics, base preset and trial function). The experiments
themselves are in :mod:`trackjam.experiments.definitions` and, for several targets,
:mod:`trackjam.experiments.swarm`."""

from __future__ import annotations

import math

from dataclasses import dataclass, field
from typing import Any, Callable

from trackjam.config import Scenario
from trackjam.experiments.progress import PAPER_SHOWN, Shown
from trackjam.experiments.summary import METRICS, QUALITY, Count, Metric, Pair

BASE_PRESET = "paper-fig3"

# How an experiment's trials differ: the paper's trial draw of Section VI, Fig. 3 itself with
# the seed of trial k (configuration-independent, so every configuration sees the same truth), or
# the swarm draw of each (K, N) cell (experiments/swarm.py).
DRAW, SEED, SWARM = "draw", "seed", "swarm"


@dataclass(frozen=True)
class Configuration:
    """One column of a comparison: ``index`` is 1-based (Table I's "Config. #")."""

    index: int
    label: str
    settings: dict[str, Any] = field(default_factory=dict)  # dotted scenario keys
    cell: tuple[int, int] | None = None  # a swarm cell: (targets K, agents N)
    one_target: bool = False  # a K = 1 swarm cell run on the one-target engine

    @property
    def columns(self) -> dict[str, Any]:
        """What summary.csv says of a swarm cell beside the common columns."""
        if self.cell is None:
            return {}
        return {"targets": self.cell[0], "agents": self.cell[1], "engine": "one-target" if self.one_target else "swarm"}


@dataclass(frozen=True)
class Panel:
    """One panel of an experiment's figure: a bar per configuration and series, with its 95 %
    interval, clipped at ``floor`` and ``ceiling`` (the metric's physical bounds: a share's
    t-interval over 2 trials had reached 2.5); ``empty`` is written in a panel no trial gives a
    value to."""

    title: str
    ylabel: str
    series: tuple[tuple[str, str | None], ...]  # (metric or count stem, legend or None)
    floor: float = 0.0
    log: bool | None = None  # a log axis; None: when several series are all positive (powers)
    ceiling: float = math.inf
    empty: str = "no trial gives a value here"


FIG4_PANELS = (
    Panel("(a) jamming incidents", "incidents per trial per agent", (("incidents", None),)),
    Panel("(b) received power", "W", (("target_received_w", "target"), ("agent_received_w", "agents"))),
    Panel("(c) transmit power", "W per agent per step", (("transmit_w", None),)),
    Panel("(d) tracking error", "OSPA [m]", (("ospa", None),)),
)


@dataclass(frozen=True)
class Experiment:
    """A comparison of ``configurations`` on the same trials. It names what it summarises
    (``metrics``: summary.csv's mean/ci95 columns, and ``counts``: its k-of-n columns, read from
    each trial's record) and what its figure shows (``panels``, over those); the metrics default
    to the paper's five and the track quality, the counts to none, the panels to Fig. 4's. Its ``trials`` are the
    paper's draw (DRAW), Fig. 3 with trial k's seed (SEED) or the swarm draw per cell (SWARM);
    ``base_settings`` are dotted keys of its own on its base ``preset``."""

    name: str
    description: str
    configurations: tuple[Configuration, ...]
    figure: str  # file name of its figure in OUT
    panels: tuple[Panel, ...] = FIG4_PANELS
    metrics: tuple[Metric, ...] = METRICS + QUALITY
    xlabel: str = ""  # below the figure; ticks are the configurations' labels unless it is set
    counts: tuple[Count, ...] = ()
    trials: str = DRAW
    base_settings: dict[str, Any] = field(default_factory=dict)
    preset: str = BASE_PRESET  # the base scenario
    trial: Callable[[Scenario], dict] | None = None  # its trial function; None: the engine's simulate_trial
    figure_style: str = "bars"  # "bars" per configuration, or "lines": against K, one line per N
    shown: Shown = PAPER_SHOWN  # the running means of the progress display
    grid: str | None = None  # a swarm experiment's grid, KxN (experiments/swarm.py)
    pairs: tuple[Pair, ...] = ()  # paired comparisons (a, b, label) written to paired.csv

    def __post_init__(self) -> None:
        # a hand-built experiment (README, Extending trackjam): two configurations of one index
        # shared one trial file and one summary row, a figure "../x.png" was written outside
        # --out, "fig" failed in matplotlib once every trial had run
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"experiment name: expected a non-empty text, got {self.name!r:.40}")
        if not isinstance(self.configurations, tuple) or not self.configurations or not all(
                isinstance(c, Configuration) for c in self.configurations):
            raise ValueError(f"experiment {self.name}: configurations must be a non-empty tuple of Configuration")
        indices = [c.index for c in self.configurations]
        if any(isinstance(i, bool) or not isinstance(i, int) or i < 1 for i in indices) or len(set(indices)) < len(indices):
            raise ValueError(f"experiment {self.name}: configuration indices must be distinct whole numbers >= 1, "
                             f"got {indices}")
        if any(not isinstance(c.settings, dict) for c in self.configurations):
            raise ValueError(f"experiment {self.name}: a configuration's settings must be a dict of dotted keys")
        figure = self.figure
        if (not isinstance(figure, str) or figure != figure.strip() or "/" in figure or "\\" in figure
                or figure.startswith(".") or not figure.lower().endswith((".png", ".pdf", ".svg"))
                or figure.lower() in {"summary.csv", "timing.csv", "paired.csv"}):
            raise ValueError(f"experiment {self.name}: figure must be a file name in --out ending in .png, .pdf or "
                             f".svg, got {figure!r:.60}")
        if self.trials not in (DRAW, SEED, SWARM):
            raise ValueError(f"experiment {self.name}: trials must be one of {DRAW!r}, {SEED!r}, {SWARM!r}, "
                             f"got {self.trials!r:.40}")
        if not isinstance(self.base_settings, dict):
            raise ValueError(f"experiment {self.name}: base_settings must be a dict of dotted keys")
        if self.trial is not None and not callable(self.trial):
            raise ValueError(f"experiment {self.name}: trial must be a function of a scenario, got "
                             f"{type(self.trial).__name__}")
        unknown_pairs = [p for p in self.pairs if p[0] not in indices or p[1] not in indices]
        if unknown_pairs:
            raise ValueError(f"experiment {self.name}: pairs {unknown_pairs} name configurations it does not have "
                             f"({indices})")
        stems = {m[0] for m in self.metrics + self.counts}
        unknown = [stem for p in self.panels for stem, _ in p.series if stem not in stems]
        if unknown:
            raise ValueError(f"experiment {self.name}: panels show {unknown}, which are not among its metrics")
        keys = {m[1] for m in self.metrics}
        if any(key not in keys for _, key, _ in self.shown):
            if self.shown is not PAPER_SHOWN:
                missing = [key for _, key, _ in self.shown if key not in keys]
                raise ValueError(f"experiment {self.name}: shown names {missing}, which are not among its metrics' keys")
            # an experiment of its own metrics: the progress shows its first three (the paper's
            # incidents and OSPA, which its trial function need not return, had been a KeyError)
            object.__setattr__(self, "shown", tuple((stem, key, "{:.3g}") for stem, key, _ in self.metrics[:3]))

    @property
    def swept_keys(self) -> set[str]:
        return {k for c in self.configurations for k in c.settings}
