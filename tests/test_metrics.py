"""Metric definitions in the repository and at run time; unknown names suggest (issue 13)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import admit_rs as ar
import polars as pl
import pytest
from admit_rs import metrics, reproduction

ROOT = Path(__file__).parent.parent


@pytest.fixture(scope="module")
def run() -> ar.Result:
    return ar.simulate(ar.paper.scenario("fig14").replace(duration=3.0))


def test_every_metric_is_defined_with_a_unit(run):
    assert set(run.metrics) == set(ar.METRICS)
    assert [n for n in ar.METRICS if n not in ("stable", "passed", "diverged")] == ar.METRIC_NAMES
    for m in ar.METRICS.values():
        assert m.unit and m.description and m.window and m.step_info
    assert ar.METRICS["z_rms_error"].unit == "m"
    assert ar.METRICS["contact_loss"].unit == "fraction (0–1)"
    assert ar.METRICS["overshoot_pct"].label == "overshoot_pct [%]"
    assert ar.METRICS["force_peak"].label == "force_peak [N]"
    assert ar.METRICS["stable"].label == "stable"
    assert ar.METRICS["settling_time"].step_info.startswith("SettlingTime")


def test_docs_metrics_md_is_generated_from_METRICS():
    doc = (ROOT / "docs" / "metrics.md").read_text()
    assert metrics.markdown() in doc
    for name in ar.METRICS:
        assert f"| `{name}` |" in doc
    assert "not percentages" in doc and "metres" in doc and "1339 %" in doc


def test_no_doc_cites_the_spec_for_metrics():
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        assert "SPEC §7" not in path.read_text(), path


def test_generated_metrics_table_has_units_in_headers(run):
    row = reproduction.metrics_row("fig14", 0, run)
    md = reproduction._markdown_table(pl.DataFrame([row]))
    header = md.splitlines()[0]
    labels = ["force_peak [N]", "z_rms_error [m]", "contact_loss [fraction]",
              "overshoot_pct [%]", "settling_time [s]", "force_oscillation [fraction]"]  # fmt: skip
    for label in labels:
        assert f" {label} " in header
    assert re.search(r"\| stable \| passed \| diverged \|$", header)


def test_unknown_metric_suggests_the_closest_name(run):
    with pytest.raises(ar.UnknownNameError) as info:
        run.metrics["overshoot"]
    err = info.value
    assert isinstance(err, KeyError) and isinstance(err, ar.AdmitError)
    assert err.suggestions[0] == "overshoot_pct"
    assert "did you mean 'overshoot_pct'" in str(err)
    assert run.metrics.get("overshoot") is None  # dict API otherwise unchanged
    assert math.isfinite(run.metrics["force_peak"])
