"""Scenario texts that are small on disk but large once read: aliases to long texts, merges over
a list of aliases, TOML keys of thousands of parts; and the messages that echo what a user
wrote, which must stay short whatever the value (a message had built a repr of a gigabyte).
Also the memory check under an address-space limit, and a MemoryError past it."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.config import load_scenario
from trackjam.config.loading import MAX_DEPTH, MAX_TEXT, _check_size, _toml_key_depth
from trackjam.errors import ConfigError, bounded_repr, shortened

# -- bounded_repr: repr cut to a limit, built only that far ------------------------------------

values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=60)
    | st.binary(max_size=50),
    lambda inner: st.lists(inner, max_size=6) | st.tuples(inner) | st.tuples(inner, inner)
    | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=30,
)


@settings(max_examples=400, deadline=None)
@given(values, st.integers(min_value=4, max_value=80))
def test_bounded_repr_is_the_start_of_repr(value, limit):
    assert bounded_repr(value, limit) == shortened(repr(value), limit)


@pytest.mark.parametrize("text", ["a" * 45 + "'", 'a"' * 30 + "'", "'" + "b" * 50 + '"', "'" * 60])
def test_bounded_repr_of_a_long_text_takes_the_quotes_of_the_whole_text(text):
    assert bounded_repr(text) == shortened(repr(text), 40)


def test_bounded_repr_does_not_build_what_it_does_not_show():
    texts = {f"k{i}": "x" * 1000 for i in range(500)}
    huge = [texts] * 100_000  # its repr would be about 50 GB
    assert bounded_repr(huge) == shortened("[{'k0': '" + "x" * 1000, 40)
    loop: list = []
    loop.append(loop)
    assert bounded_repr(loop) == "[" * 37 + "..."
    assert bounded_repr(10**5000) == "<an integer of about 5001 digits>"
    assert bounded_repr([1, 10**5000]) == "[1, <an integer of about 5001 digits>]"


# -- texts that expand ---------------------------------------------------------------------------


def _refused(source: str, overrides: list[str] | None = None) -> str:
    with pytest.raises(ConfigError) as err:
        load_scenario(source, overrides or [])
    message = str(err.value)
    assert "\n" not in message and len(message) < 400, message
    return message


def test_aliases_to_long_texts_are_refused_by_their_characters(tmp_path):
    """500 kB: one mapping of 500 texts of 1,000 characters, used 1,990 times (under the cap on
    values); its message had built a repr of a gigabyte and the process was killed."""
    keys = ", ".join(f"k{i}: {'x' * 1000}" for i in range(500))
    f = tmp_path / "texts.yaml"
    f.write_text(f"a: &a {{{keys}}}\nsteps: [" + ", ".join(["*a"] * 1990) + "]\n")
    assert _refused(str(f)) == (f"{f}: it holds more than {MAX_TEXT:,} characters of text, its aliases (*name) "
                                "expanded; a scenario has a few thousand")


def test_a_set_value_of_aliases_to_a_long_text_is_refused_too():
    value = "[&a [&s " + "x" * 1000 + ", " + ", ".join(["*s"] * 999) + "], " + ", ".join(["*a"] * 998) + "]"
    assert _refused("paper-fig3", [f"steps={value}"]).startswith("--set steps: it holds more than")


def test_the_text_count_takes_keys_and_values_and_every_use():
    _check_size({"a": ["x" * 1000] * 100})
    with pytest.raises(Exception, match="characters of text"):
        _check_size({"a": ["x" * 1000] * (MAX_TEXT // 1000 + 1)})
    with pytest.raises(Exception, match="characters of text"):
        _check_size([{"k" * 1000: 1}] * (MAX_TEXT // 1000 + 1))


def test_a_merge_over_a_list_of_aliases_is_counted_before_its_keys_are_checked(tmp_path):
    """`<<: [*m, *m, ...]`: the keys of m had been checked once per use before the count (150,000
    uses of 5,000 keys ran for minutes); each source is checked once, the copies counted first."""
    keys = ", ".join(f"k{i}: 1" for i in range(5000))
    f = tmp_path / "merge.yaml"
    f.write_text(f"m0: &m0 {{{keys}}}\nx: {{<<: [" + ", ".join(["*m0"] * 300) + "]}\n")
    assert _refused(str(f)).endswith("its merge keys (<<) copy more than 1,000,000 keys; a scenario has a few hundred")


def test_a_merge_over_a_short_list_of_mappings_still_merges(tmp_path):
    f = tmp_path / "merge.yaml"
    f.write_text("area: {<<: [{low: [1, 1, 1]}, {high: [60, 60, 60]}, {low: [2, 2, 2]}]}\n")
    s = load_scenario(str(f))  # as PyYAML merges: the last source to give a key wins
    assert list(s.area.low) == [2, 2, 2] and list(s.area.high) == [60, 60, 60]


@pytest.mark.parametrize(
    "body",
    [
        ".".join(["x"] * 40_000) + " = 1",  # a dotted key: tomllib took 28 s and 4 GB
        "[" + ".".join(["x"] * 100_000) + "]\na = 1",  # a table header: minutes
        "a = {" + ".".join(["q"] * 60) + " = 1}",  # inside an inline table
        ".".join(['"x"'] * 60) + " = 1",  # quoted parts
    ],
)
def test_a_toml_key_of_thousands_of_parts_is_refused_before_the_parser_sees_it(tmp_path, body):
    f = tmp_path / "deep.toml"
    f.write_text("steps = 3\n" + body + "\n")
    assert _refused(str(f)) == f"{f}: nested more than {MAX_DEPTH} levels deep; a scenario nests a few"


@pytest.mark.parametrize(
    ("text", "depth"),
    [("a.b.c = 1", 3), ("[area]\nlow = [0.5, 1.5, 2.5]", 2), ('"a"."b" = 1\nx = 1', 2),
     ("a = [" + ", ".join(["1.5"] * 60) + "]", 2), ("x." * 60 + "x = 1", 61)],
)
def test_the_toml_key_depth_counts_parts_of_one_key(text, depth):
    assert _toml_key_depth(text) == depth or (text.count(".") < MAX_DEPTH and _toml_key_depth(text) <= MAX_DEPTH)


def test_a_legal_toml_file_with_many_dots_still_reads(tmp_path):
    f = tmp_path / "ok.toml"
    f.write_text("[antenna]\npower_levels_db = [\"off\", -50.5, -10.5, 0.5]\n[agents]\nradial_steps = ["
                 + ", ".join(f"{k + 1}.5" for k in range(30)) + "]\ninitial = ["
                 + ", ".join(f"[{k}.5, {k}.5, {k}.5]" for k in range(1, 4)) + "]\n")
    assert load_scenario(str(f)).agents.radial_steps[0] == 1.5


# -- messages that echo the user's values --------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "start"),
    [
        ("steps: " + "a" * 900_000, "steps: must be an integer, got str 'aaaa"),
        ("targets: [{id: " + "x" * 100_000 + "}]", "targets.0.id: a text id must have 1 to 100 characters"),
        ("antenna: {power_levels_db: [" + "x" * 100_000 + "]}", "antenna.power_levels_db: power level 'xxx"),
        ("sensor: {clutter_rate: " + "b" * 100_000 + "}", "sensor.clutter_rate: must be a number, got str 'bbb"),
    ],
)
def test_a_long_value_is_shown_by_its_start(tmp_path, text, start):
    f = tmp_path / "long.yaml"
    f.write_text(text + "\n")
    message = _refused(str(f))
    assert message.startswith(f"{f}: {start}"), message


@pytest.mark.parametrize(
    ("key", "kind"),
    [("yes", "a boolean"), ("~", "null"), ("12", "a number"), ("1.5", "a number"), ("2001-01-01", "a date"),
     ("0x" + "f" * 5000, "a number")],
)
def test_a_yaml_key_that_reads_as_no_name_is_refused_as_written(tmp_path, key, kind):
    """`yes: 3` had been reported as "1: ...", `~: 3` as "None: ...", a key of 5,000 hex digits as
    "<unprintable int object>"."""
    f = tmp_path / "keys.yaml"
    f.write_text(f"? {key}\n: 3\n")  # the explicit form: a plain key is at most 1,024 characters
    message = _refused(str(f))
    assert message.startswith(f"{f}: not valid YAML: a key must be a name, got {bounded_repr(key)}, which YAML "
                              f"reads as {kind}; quote it (line 1)"), message


def test_a_toml_text_in_a_yaml_file_is_named_as_such(tmp_path):
    f = tmp_path / "scenario.yaml"
    f.write_text("steps = 3\n")
    assert _refused(str(f)) == (f"{f}: the scenario must be a mapping of keys, got str (`key = value` is TOML: "
                                "name the file scenario.toml)")


LONG = "9" * 5000


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (f"# seed {LONG}\nsteps = 3\n[antenna]\nheight = {LONG}\n", "antenna.height: integer too large (5000 digits, line 4)"),
        (f"antenna = {{height = {LONG}}}\n", "antenna.height: integer too large (5000 digits, line 1)"),
    ],
)
def test_a_long_toml_integer_is_placed_past_comments_and_inside_inline_tables(tmp_path, text, message):
    f = tmp_path / "long.toml"
    f.write_text(text)
    assert _refused(str(f)) == f"{f}: {message}"


# -- memory -------------------------------------------------------------------------------------


def test_the_memory_check_counts_the_address_space_limit():
    """Under `ulimit -v` the check had used the machine's memory: a run of 10^7 particles passed it
    and failed with a MemoryError traceback."""
    code = textwrap.dedent("""
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (3_000_000_000, resource.RLIM_INFINITY))
        from trackjam.config.limits import memory_budget
        print(memory_budget())
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout) <= 1.5e9


def test_a_memory_error_is_one_line_and_exit_status_2(monkeypatch, tmp_path):
    from typer.testing import CliRunner

    from trackjam import cli
    import trackjam.simulation.loop as loop

    def starved(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(loop, "simulate", starved)
    r = CliRunner().invoke(cli.app, ["run", "paper-fig3", "--set", "steps=2", "--out", str(tmp_path / "r")])
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert lines[-1].startswith("trackjam: error: out of memory (this process may use about ")
    assert "Traceback" not in r.output and not (tmp_path / "r").exists()
