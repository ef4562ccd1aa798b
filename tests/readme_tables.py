"""The column tables of the README and the docs pages, as the log-schema tests read them, and the
helpers that hold the pages' result tables to their committed files."""

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


# --- numbers and tables copied from committed result files (test_readme_results.py,
# test_swarm_doc_results.py) -----------------------------------------------------------------

NUM = r"[+-]?\d+(?:\.\d+)?(?:e[+-]?\d+)?"  # a number as the pages print it


def last_digit_unit(printed: str, sig: int | None = None, value: float = 0.0) -> float:
    """One unit of the last digit of ``printed``: from its decimals ("2.63" -> 0.01, "1.8e-07" ->
    1e-08), or, for a column printed to ``sig`` significant figures with trailing zeros dropped
    ("1.5" for 1.50262 at 3), from the magnitude."""
    import math

    if sig is not None and float(printed) != 0:
        magnitude = math.floor(math.log10(max(abs(float(printed)), abs(value))))
        return 10.0 ** (magnitude - sig + 1)
    mantissa, _, exponent = printed.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (int(exponent or 0) - decimals)


def differs_from_rounded(printed: str, value: float, scale: float = 1.0, sig: int | None = None, sign: int = 1) -> bool:
    """Whether ``printed`` (on the page's scale: x100 for a share in % or points, x1000 for ms) is
    not ``value`` rounded: farther than half a unit of its last digit, plus the CSV's own rounding
    to 6 significant figures."""
    shown = sign * float(printed) / scale
    tolerance = 0.5 * last_digit_unit(printed, sig, value * scale) / scale + 1e-5 * abs(value) + 1e-15
    return abs(shown - value) > tolerance


def table_start(text: str, anchor: str, name: str) -> int:
    """Where in ``text`` the first markdown table after ``anchor`` (found exactly once) starts."""
    assert text.count(anchor) == 1, f"{name}: lacks (or repeats) {anchor!r}"
    after = text.index(anchor)
    return after + re.search(r"^\|", text[after:], re.M).start()


def table_at(text: str, anchor: str, name: str) -> tuple[list[str], list[list[str]]]:
    """The header and the rows, each a list of cells, of the first markdown table after ``anchor``."""
    lines = []
    for line in text[table_start(text, anchor, name):].splitlines():
        if not line.startswith("|"):
            break
        lines.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    header, separator, *rows = lines
    assert set("".join(separator)) == {"-"}, f"{name}: no markdown table after {anchor!r}"
    return header, rows
