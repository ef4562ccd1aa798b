"""Progress of a sweep: a rich bar with the running means on a terminal, one plain line per
finished trial otherwise (logs, CI, pipes)."""

from __future__ import annotations

import math
import sys
import threading
import time
from typing import Any, Callable, Mapping

from trackjam.errors import ConfigError, printable

HEARTBEAT_S = 60.0  # with no trial finished for this long, the plain lines say the sweep is still at work

Shown = tuple[tuple[str, str, str], ...]  # (label, key of a trial record, format) of each running mean
PAPER_SHOWN: Shown = (("incidents", "jamming_incidents_per_agent", "{:.2f}"), ("OSPA", "ospa_mean", "{:.2f} m"),
                      ("P_target", "target_received_w_mean", "{:.3g} W"))
SWARM_SHOWN: Shown = (("held", "held_share", "{:.0%}"), ("downed", "downed_share", "{:.0%}"),
                      ("OSPA", "ospa_mean", "{:.2f} m"), ("incidents", "jamming_incidents_per_agent", "{:.2f}"))


class _Reporter:
    def __init__(self, experiment, configurations: list[dict], total: int) -> None:
        self.name = experiment.name
        self.shown = experiment.shown
        self.labels = {c["config"]: c["label"] for c in configurations}
        self.total = total
        self.records: list[Mapping[str, Any]] = []

    def means(self) -> str:
        n = len(self.records)
        if not n:
            return ""
        parts = []
        for label, key, fmt in self.shown:
            values = [float(r[key]) for r in self.records if not math.isnan(float(r[key]))]
            parts.append(f"{label} {fmt.format(sum(values) / len(values)) if values else '-'}")
        # pooled over the configurations (a line about one configuration's trial had read as its own)
        which = " over all configurations" if len(self.labels) > 1 else ""
        return f"running means{which}: " + ", ".join(parts)

    def note(self, line: str) -> None:
        """One line on stderr: what a resume found (damaged or foreign files), or what the workers do first."""
        print(f"{self.name}: {printable(line)}", file=sys.stderr, flush=True)  # it names files in OUT

    def start(self, records: list[Mapping[str, Any]]) -> None:
        self.records = list(records)
        self.resumed = len(records)

    def trial(self, record: Mapping[str, Any]) -> None:
        self.records.append(record)

    def stop(self) -> None:
        pass


class _Silent(_Reporter):
    def note(self, line: str) -> None:
        pass


class _Lines(_Reporter):
    def start(self, records) -> None:
        super().start(records)
        if self.resumed:
            print(f"{self.name}: {self.resumed} of {self.total} trials found in OUT, resuming", flush=True)
        # a trial of 100,000 steps runs for many minutes: a line every HEARTBEAT_S without one done
        self.started = self.last = time.monotonic()
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.beat = threading.Thread(target=self._heartbeat, name="trackjam-progress", daemon=True)
        self.beat.start()

    def _heartbeat(self) -> None:
        while not self.done.wait(HEARTBEAT_S / 4):
            with self.lock:
                now = time.monotonic()
                if now - self.last < HEARTBEAT_S:
                    continue
                self.last = now
                try:
                    print(f"{self.name}: still at work, {len(self.records)} of {self.total} trials done after "
                          f"{_elapsed(now - self.started)}", flush=True)
                except (OSError, ValueError):  # a closed or broken stdout: the trial lines say so, not a thread
                    return

    def stop(self) -> None:
        self.done.set()
        self.beat.join()

    def trial(self, record) -> None:
        with self.lock:
            self.last = time.monotonic()
            self._line(record)

    def _line(self, record) -> None:
        super().trial(record)
        c, k = int(record["config"]), int(record["trial"])
        # the trial's own values of the first two figures the experiment shows (incidents and
        # OSPA for the paper's), then the running means of all of them
        own = ", ".join(f"{label} {fmt.format(float(record[key]))}" for label, key, fmt in self.shown[:2])
        print(f"[{len(self.records)}/{self.total}] config {c} ({self.labels[c]}) trial {k}: {own} | {self.means()}",
              flush=True)


def _elapsed(seconds: float) -> str:
    """``1 h 02 min``, ``5 min 00 s`` or ``42 s``."""
    m, sec = divmod(int(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min" if h else f"{m} min {sec:02d} s" if m else f"{sec} s"


class _Bar(_Reporter):
    def start(self, records) -> None:
        super().start(records)
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        # the elapsed time ticks while a long first trial runs, when the bar itself cannot move
        self.bar = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TimeRemainingColumn(), TextColumn("{task.fields[means]}"),
        )
        self.task = self.bar.add_task(self.name, total=self.total, completed=self.resumed, means=self.means())
        self.bar.start()

    def trial(self, record) -> None:
        super().trial(record)
        self.bar.update(self.task, completed=len(self.records), means=self.means())

    def stop(self) -> None:
        self.bar.stop()


class _Callback(_Reporter):
    def __init__(self, fn: Callable[[Mapping, int, int], None], *args) -> None:
        super().__init__(*args)
        self.fn = fn

    def trial(self, record) -> None:
        super().trial(record)
        self.fn(record, len(self.records), self.total)


def make_reporter(progress, experiment, configurations: list[dict], total: int) -> _Reporter:
    """``progress``: "auto", "bar", "lines", "none", or a callable ``(record, done, total)``."""
    if callable(progress):
        return _Callback(progress, experiment, configurations, total)
    if progress == "auto":
        progress = "bar" if sys.stdout.isatty() else "lines"
    kinds = {"bar": _Bar, "lines": _Lines, "none": _Silent}
    if progress not in kinds:
        raise ConfigError(f"progress must be one of auto, bar, lines, none, got {progress!r}")
    return kinds[progress](experiment, configurations, total)
