"""Reproducing the paper: every figure, a metrics table and a report, from one call.

``reproduce(out_dir)`` runs every curve of figures 5-20 (SPEC §9), draws one PNG per figure
laid out like the paper's panels, and writes ``metrics.parquet``, ``metrics.md`` and a
``README.md`` that shows each figure with its caption, the paper's claim and our measured
number side by side.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import polars as pl

from admit_rs.config import (
    AdmittanceFilter,
    ComputedTorque,
    ImpedanceReference,
    ModelFree,
    Scenario,
    Sine,
    TimeDelayControl,
)
from admit_rs.paper import FIGURES, VARIANT_SUFFIX, VARIANTS, scenarios, variant_scenarios
from admit_rs.simulation import Result, simulate

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FIGURE_SIZE = (15.0, 8.0)
"""Inches; saved at 100 dpi, so every PNG is 1500 × 800 pixels."""
DPI = 100


def _controller_name(sc: Scenario) -> str:
    return {ComputedTorque: "CT", ModelFree: "MF", TimeDelayControl: "TDC"}[type(sc.controller)]


def run_figure(name: str | int) -> list[Result]:
    """Simulates every curve of one figure ("fig9", or "fig9-variant" for its variant)."""
    key = f"fig{name}" if isinstance(name, int) else name
    if key.endswith(VARIANT_SUFFIX):
        return [simulate(sc) for sc in variant_scenarios(key.removesuffix(VARIANT_SUFFIX))]
    return [simulate(sc) for sc in scenarios(key)]


def metrics_row(figure: str, curve: int, result: Result) -> dict[str, object]:
    """One table row: the curve's identity, its parameters and its SPEC §7 metrics."""
    sc = result.scenario
    adm = sc.admittance
    row: dict[str, object] = {
        "figure": figure,
        "curve": curve,
        "label": sc.label,
        "controller": _controller_name(sc),
        "scheme": (
            "position only"
            if adm is None
            else "impedance (eq. 20)"
            if isinstance(adm, ImpedanceReference)
            else "Scheme 1"
            if adm.k > 0
            else "Scheme 2"
        ),
        "b": adm.b if isinstance(adm, AdmittanceFilter) else math.nan,
        "k": adm.k if isinstance(adm, AdmittanceFilter) else math.nan,
        "ka": adm.ka if isinstance(adm, AdmittanceFilter) else math.nan,
        "stiffness": sc.wall.stiffness if sc.wall is not None else math.nan,
        "position_error": sc.wall.position_error if sc.wall is not None else math.nan,
        "force_reference": "sine" if isinstance(sc.force_reference, Sine) else "step",
    }
    row.update(result.metrics)
    return row


def figure(name: str | int, results: Sequence[Result] | None = None) -> Figure:
    """The paper's figure as a matplotlib Figure (runs its scenarios unless given)."""
    from admit_rs.plot import plot_paper_figure

    key = f"fig{name}" if isinstance(name, int) else name
    runs = list(results) if results is not None else run_figure(key)
    base = key.removesuffix(VARIANT_SUFFIX)
    info = FIGURES[base]
    title = f"Fig. {info.number}: {info.caption}"
    if base != key:
        title += f" — VARIANT: {VARIANTS[base]} (not the paper as written)"
    return plot_paper_figure(runs, title=title, size=FIGURE_SIZE)


@dataclass(frozen=True)
class Verdict:
    """What we measured against the paper's claim, and whether they agree."""

    measured: str
    agrees: bool


def _curves(table: pl.DataFrame, fig: str) -> pl.DataFrame:
    return table.filter(pl.col("figure") == fig).sort("curve")


def _fmt(values: Iterable[float], unit: str = "", digits: int = 3) -> str:
    return ", ".join(f"{v:.{digits}g}{unit}" for v in values)


def _increasing(values: Sequence[float]) -> bool:
    return all(b > a for a, b in zip(values, values[1:], strict=False))


def _verdicts() -> dict[str, Callable[[pl.DataFrame], Verdict]]:
    def pos(fig: str, other: str | None = None) -> Callable[[pl.DataFrame], Verdict]:
        def check(t: pl.DataFrame) -> Verdict:
            z = _curves(t, fig)["z_rms_error"][0]
            ct = _curves(t, "fig5")["z_rms_error"][0]
            if fig == "fig6":
                return Verdict(f"z RMS {z * 1e3:.1f} mm vs CT {ct * 1e3:.2f} mm", z > 10 * ct)
            return Verdict(f"z RMS {z * 1e3:.2f} mm (CT {ct * 1e3:.2f} mm)", z < 1e-3)

        return check

    def fig8(t: pl.DataFrame) -> Verdict:
        c = _curves(t, "fig8")["force_ss_error"]
        return Verdict(
            f"steady-state error Scheme 1 {c[0]:.2f} N, Scheme 2 {c[1]:.2f} N",
            c[0] > 1.0 and abs(c[1]) < 0.5,
        )

    def fig9(t: pl.DataFrame) -> Verdict:
        c = _curves(t, "fig9")
        rise, os = c["rise_time_63"].to_list(), c["overshoot_pct"].to_list()
        at = c["peak_time"].to_list()
        return Verdict(
            f"63 % rise {_fmt(rise, ' s')} for b = 200, 400, 800; no overshoot at contact;"
            f" the peaks ({_fmt(os, ' %')} over f_d, at t = {_fmt(at, ' s')}) come from the"
            " z motion and grow with b",
            _increasing(rise) and not _increasing(os),
        )

    def fig10(t: pl.DataFrame) -> Verdict:
        c = _curves(t, "fig10")
        os = c["overshoot_pct"].to_list()
        z = c["z_rms_error"][0]
        return Verdict(
            f"overshoot k_a=1: {os[0]:.2f} %, k_a=2: {os[1]:.1f} % (paper 0.45 %);"
            f" z RMS {z * 1e3:.2f} mm",
            abs(os[1] - 0.45) < 0.5,
        )

    def fig11(t: pl.DataFrame) -> Verdict:
        z = _curves(t, "fig11")["z_rms_error"].to_list()
        return Verdict(
            f"z RMS {_fmt([v * 1e3 for v in z], ' mm')} for b = 200, 400, 800",
            max(z) < 1.2 * min(z),
        )

    def model_free(fig: str, tdc: str) -> Callable[[pl.DataFrame], Verdict]:
        def check(t: pl.DataFrame) -> Verdict:
            m, d = _curves(t, fig).row(0, named=True), _curves(t, tdc).row(0, named=True)
            return Verdict(
                f"z RMS {m['z_rms_error'] * 1e3:.0f} mm (TDC {d['z_rms_error'] * 1e3:.2f} mm),"
                f" peak force {m['force_peak']:.0f} N, contact lost {m['contact_loss']:.0%}",
                m["z_rms_error"] > 10 * d["z_rms_error"],
            )

        return check

    def tdc(fig: str) -> Callable[[pl.DataFrame], Verdict]:
        def check(t: pl.DataFrame) -> Verdict:
            c = _curves(t, fig)
            ss, z = c["force_ss_error"].to_list(), c["z_rms_error"].to_list()
            return Verdict(
                f"force error (last 2 s) {_fmt(ss, ' N', 2)}; z RMS"
                f" {_fmt([v * 1e3 for v in z], ' mm')}",
                all(abs(v) < 0.5 for v in ss) and max(z) < 1e-3,
            )

        return check

    def peaks(fig: str, low: float, high: float) -> Callable[[pl.DataFrame], Verdict]:
        def check(t: pl.DataFrame) -> Verdict:
            p = _curves(t, fig)["force_peak"].to_list()
            ok = all(low <= v <= high for v in p)
            if len(p) > 1:
                ok = ok and _increasing(p)
            return Verdict(f"peak force {_fmt(p, ' N')}", ok)

        return check

    def fig20(t: pl.DataFrame) -> Verdict:
        # The paper: overshoot grows with k_e "from 30 N to 55 N" (k_e 10 000 to 100 000).
        p = _curves(t, "fig20")["force_peak"].to_list()
        return Verdict(
            f"peak force {_fmt(p, ' N')} (paper 30 → 55 N)",
            _increasing(p) and abs(p[0] - 30.0) < 7.5 and abs(p[-1] - 55.0) < 13.75,
        )

    return {
        "fig5": pos("fig5"),
        "fig6": pos("fig6"),
        "fig7": pos("fig7"),
        "fig8": fig8,
        "fig9": fig9,
        "fig10": fig10,
        "fig11": fig11,
        "fig12": model_free("fig12", "fig14"),
        "fig13": model_free("fig13", "fig16"),
        "fig14": tdc("fig14"),
        "fig15": tdc("fig15"),
        "fig16": tdc("fig16"),
        "fig17": peaks("fig17", 10.0, 30.0),
        "fig18": peaks("fig18", 60.0, math.inf),
        "fig19": peaks("fig19", 25.0, 50.0),
        "fig20": fig20,
    }


def verdicts(table: pl.DataFrame) -> dict[str, Verdict]:
    """Our measured number against each figure's claim, for the figures in ``table``."""
    present = set(table["figure"].to_list())
    out = {}
    for fig, check in _verdicts().items():
        try:
            if fig in present:
                out[fig] = check(table)
        except (IndexError, pl.exceptions.PolarsError):
            # A claim that compares with a figure not in this table cannot be judged.
            continue
    return out


def _markdown_table(table: pl.DataFrame) -> str:
    cols = [
        "figure", "label", "force_ss_error", "force_rms_error", "force_peak", "overshoot_pct",
        "settling_time", "rise_time_63", "z_rms_error", "x_rms_error", "contact_loss", "stable",
    ]  # fmt: skip
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in table.select(cols).iter_rows():
        cells = []
        for v in row:
            if isinstance(v, float):
                cells.append("–" if math.isnan(v) else f"{v:.4g}")
            else:
                cells.append(str(v))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _report(table: pl.DataFrame, names: Sequence[str], variant_names: Sequence[str]) -> str:
    judged = verdicts(table)
    out = [
        "# admit_rs: reproduction of Jung & Jeong's simulations\n",
        "Generated by `admit-rs paper`. Every curve is one scenario of `admit_rs.paper`"
        " (SPEC §9); metrics follow SPEC §7 and are in `metrics.parquet` / `metrics.md`."
        " See `docs/reproduction.md` in the repository for the discussion of each"
        " difference.\n",
        "| figure | paper's claim | measured | verdict |",
        "|---|---|---|---|",
    ]
    for name in names:
        v = judged.get(name)
        verdict = "–" if v is None else ("agrees" if v.agrees else "differs")
        measured = "–" if v is None else v.measured
        out.append(f"| {name} | {FIGURES[name].claim} | {measured} | {verdict} |")
    out.append("")
    for name in names:
        info = FIGURES[name]
        v = judged.get(name)
        out.append(f"## Fig. {info.number}: {info.caption}\n")
        out.append(f"![{name}]({name}.png)\n")
        out.append(f"- Paper: {info.claim}")
        if v is not None:
            out.append(f"- Measured: {v.measured} — **{'agrees' if v.agrees else 'differs'}**")
        out.append("")
    if variant_names:
        out.append(
            "## Labelled variants (a different reading of eq. 39, not the paper as written)\n"
        )
        for name in variant_names:
            out.append(f"![{name}]({name}.png)\n")
        variant_rows = table.filter(pl.col("figure").is_in(list(variant_names)))
        out.append(_markdown_table(variant_rows))
    return "\n".join(out)


def reproduce(
    out_dir: str | Path,
    figures: Iterable[str | int] | None = None,
    *,
    progress: bool = True,
    variants: bool = True,
) -> pl.DataFrame:
    """Runs the paper's figures and writes PNGs, ``metrics.parquet``, ``metrics.md`` and
    ``README.md`` into ``out_dir``. Returns the metrics table (one row per curve).
    With ``variants``, figures listed in :data:`admit_rs.paper.VARIANTS` are also drawn
    under the variant reading as ``figN-variant.png`` (rows with figure ``figN-variant``).

    Example:
        >>> import admit_rs as ar, tempfile
        >>> table = ar.paper.reproduce(tempfile.mkdtemp(), figures=[8], progress=False)
        >>> table["label"].to_list()
        ['CT, Scheme 1, k=400, k_a=0.1', 'CT, Scheme 2, k_a=0.1']
    """
    from tqdm.auto import tqdm

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = [f"fig{f}" if isinstance(f, int) else f for f in (figures or FIGURES)]
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ValueError(f"unknown figures {unknown}; choose from {list(FIGURES)}")
    jobs = names + [n + VARIANT_SUFFIX for n in names if variants and n in VARIANTS]
    rows: list[dict[str, object]] = []
    bar = tqdm(jobs, desc="paper figures", unit="fig", disable=not progress)
    for name in bar:
        bar.set_postfix_str(name)
        results = run_figure(name)
        rows.extend(metrics_row(name, i, r) for i, r in enumerate(results))
        fig = figure(name, results)
        fig.savefig(out / f"{name}.png", dpi=DPI)
    table = pl.DataFrame(rows)
    table.write_parquet(out / "metrics.parquet")
    (out / "metrics.md").write_text(_markdown_table(table))
    (out / "README.md").write_text(_report(table, names, jobs[len(names) :]))
    return table
