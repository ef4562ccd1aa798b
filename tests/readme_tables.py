"""The column tables of the README and the docs pages, as the log-schema tests read them."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
SEVERAL_TARGETS = (ROOT / "docs" / "several-targets.md").read_text()  # the several-target guide


def first_column_names(heading: str, text: str = README) -> set[str]:
    """The names in the first column of the table after ``heading`` in ``text`` (the README by
    default; ``x_x/y/z`` -> three)."""
    part = text.split(heading, 1)[1]
    rows = [line for line in part.split("\n\n", 2)[1].splitlines() if line.startswith("| `")]
    names = set()
    for row in rows:
        for span in re.findall(r"`([^`]+)`", row.split(" | ")[0]):
            names |= {span[:-5] + k for k in "xyz"} if span.endswith("_x/y/z") else (
                set("xyz") if span == "x/y/z" else {span})
    return names


def closing_table_rows(text: str) -> dict[str, str]:
    """metric -> value of a run's closing table, as printed (rich's box) or as the README shows it."""
    rows = {}
    for line in text.splitlines():
        parts = [p.strip() for p in line.strip().strip("│").split("│")] if "│" in line else \
            re.split(r"\s{2,}", line.strip(), maxsplit=1)
        if len(parts) == 2 and parts[0] and parts[0] != "metric":
            rows[parts[0]] = parts[1]
    return rows
