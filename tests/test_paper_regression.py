"""The paper's world is untouched by the stage pipeline: every curve of figs 5-20 equals the
force trace (and, for position-only curves, the z trace) recorded by the core before the
loop became stages (tests/data/paper_force_traces.parquet, written by commit a11049f)."""

from pathlib import Path

import admit_rs as ar
import numpy as np
import polars as pl
import pytest

STORED = pl.read_parquet(Path(__file__).parent / "data" / "paper_force_traces.parquet")


@pytest.mark.parametrize("figure", [f"fig{i}" for i in range(5, 21)])
def test_every_curve_equals_the_stored_trace(figure):
    stored = STORED.filter(pl.col("figure") == figure)
    for curve, sc in enumerate(ar.paper.scenarios(figure)):
        ref = stored.filter(pl.col("curve") == curve).sort("k")
        assert ref.height == sc.samples, (figure, curve)
        assert ref["label"][0] == sc.label
        tr = ar.simulate(sc).trace
        np.testing.assert_allclose(tr["f"].to_numpy(), ref["f"].to_numpy(), rtol=0, atol=1e-9)
        if sc.admittance is None:
            np.testing.assert_allclose(tr["z"].to_numpy(), ref["z"].to_numpy(), rtol=0, atol=1e-12)
