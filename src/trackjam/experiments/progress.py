"""Progress of a sweep: a rich bar with the running means on a terminal, one plain line per
finished trial otherwise (logs, CI, pipes)."""

from __future__ import annotations

import math
import sys
from typing import Any, Callable, Mapping

from trackjam.errors import ConfigError, printable

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
        return "running means: " + ", ".join(parts)

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

    def trial(self, record) -> None:
        super().trial(record)
        c, k = int(record["config"]), int(record["trial"])
        print(
            f"[{len(self.records)}/{self.total}] config {c} ({self.labels[c]}) trial {k}: "
            f"incidents {float(record['jamming_incidents_per_agent']):.2f}, "
            f"OSPA {float(record['ospa_mean']):.2f} m | {self.means()}",
            flush=True,
        )


class _Bar(_Reporter):
    def start(self, records) -> None:
        super().start(records)
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        self.bar = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
            TimeRemainingColumn(), TextColumn("{task.fields[means]}"),
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
