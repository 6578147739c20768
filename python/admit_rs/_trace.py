"""The core's recorded run as a Polars DataFrame."""

from __future__ import annotations

from typing import TYPE_CHECKING

import polars as pl

if TYPE_CHECKING:
    from admit_rs._core import FlatTrace


def trace_frame(trace: FlatTrace) -> pl.DataFrame:
    """The DataFrame of a trace the core moved out whole (one buffer, column c at
    ``data[c * len:(c + 1) * len]``): one Series over the buffer, sliced per column without
    a copy. Polars has a fixed cost per Series built from an array, paid 30 times for the
    paper's arm; a slice costs a fraction of it (docs/performance-history.md §28, §29)."""
    n = trace["len"]
    flat = pl.Series(trace["data"])
    return pl.DataFrame([flat.slice(c * n, n).alias(name) for c, name in enumerate(trace["names"])])
