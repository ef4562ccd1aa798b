"""The log schema is the one declaration of the logs' columns: runs follow it, the README's
output tables document exactly it."""

import re

import numpy as np

from trackjam.config import load_scenario
from trackjam.simulation.loop import simulate
from trackjam.simulation.schema import AGENTS, MEASUREMENTS, STEPS

from readme_tables import README, first_column_names

def test_readme_documents_exactly_the_steps_columns():
    assert first_column_names("`steps.parquet`, one row per step") == {c.name for c in STEPS}


def test_readme_documents_exactly_the_agents_columns():
    assert first_column_names("`agents.parquet`, one row per (step, agent)") == {c.name for c in AGENTS}


def test_readme_names_every_measurements_column():
    sentence = README.split("`measurements.parquet`, one row per measurement", 1)[1].split("\n\n", 1)[0]
    assert set(re.findall(r"`([^`]+)`", sentence)) == {c.name for c in MEASUREMENTS}


def test_a_run_writes_exactly_the_declared_columns_and_dtypes():
    r = simulate(load_scenario("paper-fig3", ["control.solver=exact", "steps=3", "filter.particles=500",
                                              "filter.birth_particles=100"]))
    for cols, schema in ((r.steps, STEPS), (r.agents, AGENTS), (r.measurements, MEASUREMENTS)):
        assert list(cols) == [c.name for c in schema]
        for c in schema:
            kind = np.asarray(cols[c.name]).dtype.kind
            assert kind == np.dtype(c.dtype).kind, (c.name, kind, c.dtype)
