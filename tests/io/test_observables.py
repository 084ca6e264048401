"""observables.csv's columns: the energy terms come from the model's one table of force groups."""

from __future__ import annotations

import csv

import pytest

from knotmm.engine.reporters import ObservablesReporter
from knotmm.engine.simulation import Simulation
from knotmm.io.observables import ENERGY_TERMS, OBSERVABLE_COLUMNS
from knotmm.model.forces import FORCE_GROUPS

#: The columns as files written so far have them (they must still read by these names).
WRITTEN = ("time", "step", "com_x", "com_y", "com_z", "e_bond", "e_bend", "e_steric",
           "e_gravity", "e_total", "max_bond", "timestep", "evaluations")


def test_the_columns_are_those_of_existing_files():
    assert OBSERVABLE_COLUMNS == WRITTEN


def test_the_energy_columns_are_the_force_groups_then_the_total():
    assert ENERGY_TERMS == (*FORCE_GROUPS, "total")
    energy_columns = [c for c in OBSERVABLE_COLUMNS if c.startswith("e_")]
    assert energy_columns == [f"e_{term}" for term in ENERGY_TERMS]


def test_a_row_holds_each_energy_under_its_name(tmp_path, trefoil40):
    sim = Simulation(trefoil40, platform="Reference", engine="python")
    sim.step(2)
    path = tmp_path / "observables.csv"
    reporter = ObservablesReporter(path, 1.0)
    reporter.report(sim, None)
    reporter.close()
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 1 and tuple(rows[0]) == WRITTEN
    energies = sim.energies()
    for term in ENERGY_TERMS:
        assert float(rows[0][f"e_{term}"]) == pytest.approx(energies[term], rel=1e-9, abs=1e-12)
    assert float(rows[0]["timestep"]) == pytest.approx(sim.timestep, rel=1e-5)
    assert int(rows[0]["step"]) == 2 and int(rows[0]["evaluations"]) == sim.n_evaluations
