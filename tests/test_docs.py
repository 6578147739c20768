"""Every example in the package's docstrings runs and prints what it says."""

from __future__ import annotations

import doctest
import importlib

import pytest

BLOCKS = ["actuator", "approach", "controller", "criteria", "force_control", "robot",
          "scenario", "sensor", "signal", "surface"]
MODULES = ["admit_rs", *(f"admit_rs.blocks.{m}" for m in BLOCKS), "admit_rs.errors",
           "admit_rs.export", "admit_rs.simulation", "admit_rs.sweep", "admit_rs.paper",
           "admit_rs.reproduction", "admit_rs.metrics", "admit_rs.plot.sweeps",
           "admit_rs.plot.axes", "admit_rs._names", "admit_rs.analysis.linear",
           "admit_rs.analysis.forced", "admit_rs.analysis._checks",
           "admit_rs._paper_scenarios"]  # fmt: skip


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
