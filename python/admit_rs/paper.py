"""The paper's simulation figures 5-20 as scenarios (SPEC §9), and their reproduction.

Defaults unless a figure says otherwise: k_e = 30 000 N/m, no wall-position error, z sine of
0.05 m at 1 rad/s, 10 s, T = 1 ms, 10 RK4 substeps, Scheme 2 with m = 1, b = 800.
``scenario(name)`` is a figure's first curve, ``scenarios(name)`` all of them, labelled;
``figure(name)`` draws one, ``reproduce(out_dir)`` all of them with a report.

The scenarios live in :mod:`admit_rs._paper_scenarios`, the runs and drawings in
:mod:`admit_rs.reproduction`; this module is the one place that offers both.

Example:
    >>> import admit_rs as ar
    >>> [s.label for s in ar.paper.scenarios("fig9")]
    ['CT, Scheme 2, b=200, k_a=0.1', 'CT, Scheme 2, b=400, k_a=0.1', 'CT, Scheme 2, b=800, k_a=0.1']
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from admit_rs import reproduction
from admit_rs._paper_scenarios import (
    FIGURES,
    SINE_FORCE,
    STEP_FORCE,
    VARIANT_SUFFIX,
    VARIANTS,
    Figure,
    figure_name,
    scenario,
    scenarios,
    variant_scenarios,
)

if TYPE_CHECKING:
    import polars as pl
    from matplotlib.figure import Figure as MplFigure

__all__ = [
    "FIGURES",
    "SINE_FORCE",
    "STEP_FORCE",
    "VARIANTS",
    "VARIANT_SUFFIX",
    "Figure",
    "figure",
    "figure_name",
    "reproduce",
    "scenario",
    "scenarios",
    "variant_scenarios",
]


def figure(name: str | int) -> MplFigure:
    """The paper's figure ``name`` (e.g. 14 or "fig14") as a matplotlib Figure."""
    return reproduction.figure(name)


def reproduce(
    out_dir: str | Path, figures: Iterable[str | int] | None = None, *, progress: bool = True
) -> pl.DataFrame:
    """Every figure (or ``figures``) as PNGs plus metrics.parquet, metrics.md and README.md
    in ``out_dir``; returns the metrics table. See :func:`admit_rs.reproduction.reproduce`."""
    return reproduction.reproduce(out_dir, figures, progress=progress)
