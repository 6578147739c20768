"""Plots people expect: one run, a paper figure, and sweep tables."""

from __future__ import annotations

from admit_rs.plot.axes import parameter_unit
from admit_rs.plot.runs import Run, plot_paper_figure, plot_result
from admit_rs.plot.sweeps import (
    WORST_CASE,
    stability_map,
    sweep_heatmap,
    sweep_hist,
    sweep_scatter,
)

__all__ = [
    "WORST_CASE",
    "Run",
    "parameter_unit",
    "plot_paper_figure",
    "plot_result",
    "stability_map",
    "sweep_heatmap",
    "sweep_hist",
    "sweep_scatter",
]
