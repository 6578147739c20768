"""Reproducing the paper: every figure, a metrics table and a report, from one call.

``reproduce(out_dir)`` runs every curve of figures 5-20, draws one PNG per figure
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

from admit_rs._paper_scenarios import (
    FIGURES,
    VARIANT_SUFFIX,
    VARIANTS,
    figure_name,
    scenarios,
    variant_scenarios,
)
from admit_rs.config import (
    AdmittanceFilter,
    ComputedTorque,
    ImpedanceReference,
    ModelFree,
    Scenario,
    Sine,
    TimeDelayControl,
)
from admit_rs.errors import ArgumentError
from admit_rs.metrics import METRICS
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
    """One table row: the curve's identity, its parameters, its metrics and verdict."""
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
    row["verdict"] = result.verdict
    return row


def figure(name: str | int, results: Sequence[Result] | None = None) -> Figure:
    """The paper's figure as a matplotlib Figure (runs its scenarios unless given)."""
    from admit_rs.plot import plot_paper_figure

    key = f"fig{name}" if isinstance(name, int) else name
    runs = list(results) if results is not None else run_figure(key)
    base = key.removesuffix(VARIANT_SUFFIX)
    info = FIGURES[figure_name(base)]
    title = f"Fig. {info.number}: {info.caption}"
    if base != key:
        title += f" — VARIANT: {VARIANTS[base]} (not the paper as written)"
    return plot_paper_figure(runs, title=title, size=FIGURE_SIZE)


AGREES = "agrees"
DIFFERS = "differs"
CANNOT = "cannot be reproduced"
STATUSES = (AGREES, DIFFERS, CANNOT)
"""The verdicts a claim can have; only :data:`AGREES` counts as agreeing."""


@dataclass(frozen=True)
class Verdict:
    """What we measured against the paper's claim(s), and whether they agree."""

    measured: str
    agrees: bool


@dataclass(frozen=True)
class Claim:
    """One checkable statement of the paper and its documented verdict.

    ``status`` is what docs/reproduction.md says (one of :data:`STATUSES`); ``measure``
    computes our number from the metrics table and whether it *holds* (matches the paper's
    statement). A claim is consistent when it holds exactly if its status is ``agrees``;
    reports print the status, or say the claim is out of date when it is inconsistent.
    """

    figure: str
    paper: str
    status: str
    measure: Callable[[pl.DataFrame], tuple[str, bool]]

    def judge(self, table: pl.DataFrame) -> tuple[str, str]:
        """(measured, printed verdict) for this claim on ``table``."""
        measured, holds = self.measure(table)
        if holds == (self.status == AGREES):
            return measured, self.status
        now = "holds" if holds else "does not hold"
        return measured, (f"OUT OF DATE: documented as {self.status!r} but the claim now {now};"
                          " update CLAIMS and docs/reproduction.md")  # fmt: skip


def _curves(table: pl.DataFrame, fig: str) -> pl.DataFrame:
    return table.filter(pl.col("figure") == fig).sort("curve")


def _fmt(values: Iterable[float], unit: str = "", digits: int = 3) -> str:
    return ", ".join(f"{v:.{digits}g}{unit}" for v in values)


def _increasing(values: Sequence[float]) -> bool:
    return all(b > a for a, b in zip(values, values[1:], strict=False))


Measure = Callable[[pl.DataFrame], tuple[str, bool]]


def _pos(fig: str) -> Measure:
    def check(t: pl.DataFrame) -> tuple[str, bool]:
        z = _curves(t, fig)["z_rms_error"][0]
        ct = _curves(t, "fig5")["z_rms_error"][0]
        if fig == "fig6":
            return f"z RMS {z * 1e3:.1f} mm vs CT {ct * 1e3:.2f} mm", z > 10 * ct
        return f"z RMS {z * 1e3:.2f} mm (CT {ct * 1e3:.2f} mm)", z < 1e-3

    return check


def _z_rms(fig: str, paper: float) -> Measure:
    """The paper's z RMS numbers: no unit and RMS definition fits all four."""

    def check(t: pl.DataFrame) -> tuple[str, bool]:
        z = _curves(t, fig)["z_rms_error"].to_list()
        return f"z RMS {_fmt(z, ' m')} (paper {paper})", all(
            abs(v - paper) <= 0.1 * paper for v in z
        )

    return check


def _fig8(t: pl.DataFrame) -> tuple[str, bool]:
    c = _curves(t, "fig8")["force_ss_error"]
    return (f"steady-state error Scheme 1 {c[0]:.2f} N, Scheme 2 {c[1]:.2f} N",
            c[0] > 1.0 and abs(c[1]) < 0.5)  # fmt: skip


def _fig9_slower(t: pl.DataFrame) -> tuple[str, bool]:
    rise = _curves(t, "fig9")["rise_time_63"].to_list()
    return f"63 % rise {_fmt(rise, ' s')} for b = 200, 400, 800", _increasing(rise)


def _fig9_overshoot(t: pl.DataFrame) -> tuple[str, bool]:
    c = _curves(t, "fig9")
    os, at = c["overshoot_pct"].to_list(), c["peak_time"].to_list()
    return (f"no overshoot at contact; the peaks ({_fmt(os, ' %')} over f_d, at t ="
            f" {_fmt(at, ' s')}) come from the z motion and grow with b",
            not _increasing(os))  # fmt: skip


def _fig10_fast(t: pl.DataFrame) -> tuple[str, bool]:
    rise = _curves(t, "fig10")["rise_time_63"][0]
    slow = _curves(t, "fig9")["rise_time_63"].to_list()
    return (f"63 % rise {rise * 1e3:.0f} ms at k_a = 1 (k_a = 0.1: {slow[-1]:.3g} s)",
            rise < 0.05)  # fmt: skip


def _fig10_overshoot(t: pl.DataFrame) -> tuple[str, bool]:
    os = _curves(t, "fig10")["overshoot_pct"].to_list()
    return (f"overshoot k_a=1: {os[0]:.2f} %, k_a=2: {os[1]:.1f} % (paper 0.45 %)",
            abs(os[1] - 0.45) < 0.5)  # fmt: skip


def _fig11_lag(t: pl.DataFrame) -> tuple[str, bool]:
    c = _curves(t, "fig11")
    rms, peak = c["force_rms_error"].to_list(), c["force_peak"].to_list()
    return (f"force RMS error {_fmt(rms, ' N')}, peak {_fmt(peak, ' N')} for b = 200, 400,"
            " 800", _increasing(rms) and _increasing(peak[::-1]))  # fmt: skip


def _fig11_z(t: pl.DataFrame) -> tuple[str, bool]:
    z = _curves(t, "fig11")["z_rms_error"].to_list()
    return f"z RMS {_fmt([v * 1e3 for v in z], ' mm')} for b = 200, 400, 800", max(z) < 1.2 * min(z)


def _model_free(fig: str, tdc: str) -> Measure:
    def check(t: pl.DataFrame) -> tuple[str, bool]:
        m, d = _curves(t, fig).row(0, named=True), _curves(t, tdc).row(0, named=True)
        return (f"z RMS {m['z_rms_error'] * 1e3:.0f} mm (TDC {d['z_rms_error'] * 1e3:.2f} mm),"
                f" peak force {m['force_peak']:.0f} N, contact lost {m['contact_loss']:.0%}",
                m["z_rms_error"] > 10 * d["z_rms_error"])  # fmt: skip

    return check


def _tdc(fig: str) -> Measure:
    def check(t: pl.DataFrame) -> tuple[str, bool]:
        c = _curves(t, fig)
        ss, z = c["force_ss_error"].to_list(), c["z_rms_error"].to_list()
        return (f"force error (last 2 s) {_fmt(ss, ' N', 2)}; z RMS"
                f" {_fmt([v * 1e3 for v in z], ' mm')}",
                all(abs(v) < 0.5 for v in ss) and max(z) < 1e-3)  # fmt: skip

    return check


def _peaks(fig: str, low: float, high: float) -> Measure:
    def check(t: pl.DataFrame) -> tuple[str, bool]:
        p = _curves(t, fig)["force_peak"].to_list()
        ok = all(low <= v <= high for v in p)
        if len(p) > 1:
            ok = ok and _increasing(p)
        return f"peak force {_fmt(p, ' N')}", ok

    return check


def _fig20_magnitude(t: pl.DataFrame) -> tuple[str, bool]:
    p = _curves(t, "fig20")["force_peak"].to_list()
    return (f"peak force {_fmt(p, ' N')} (paper 30 → 55 N)",
            abs(p[0] - 30.0) < 7.5 and abs(p[-1] - 55.0) < 13.75)  # fmt: skip


CLAIMS: tuple[Claim, ...] = (
    Claim("fig5", "perfect position tracking", AGREES, _pos("fig5")),
    Claim("fig6", "poor tracking without models", AGREES, _pos("fig6")),
    Claim("fig7", "TDC restores position tracking", AGREES, _pos("fig7")),
    Claim("fig8", "Scheme 1 keeps a force offset (eq. 26), Scheme 2 none (eq. 35)", AGREES,
          _fig8),
    Claim("fig8", "z RMS 0.0370", CANNOT, _z_rms("fig8", 0.0370)),
    Claim("fig9", "larger b: slower response", AGREES, _fig9_slower),
    Claim("fig9", "larger b: less overshoot", DIFFERS, _fig9_overshoot),
    Claim("fig10", "k_a = 1: faster contact", AGREES, _fig10_fast),
    Claim("fig10", "k_a = 2 gives 0.45 % overshoot", DIFFERS, _fig10_overshoot),
    Claim("fig10", "z RMS 0.0016", CANNOT, _z_rms("fig10", 0.0016)),
    Claim("fig11", "larger b: less overshoot, more lag", AGREES, _fig11_lag),
    Claim("fig11", "z RMS the same for all b", AGREES, _fig11_z),
    Claim("fig11", "z RMS 0.0370", CANNOT, _z_rms("fig11", 0.0370)),
    Claim("fig12", "poor tracking without models", AGREES, _model_free("fig12", "fig14")),
    Claim("fig12", "z RMS 3.2052", CANNOT, _z_rms("fig12", 3.2052)),
    Claim("fig13", "poor tracking without models", AGREES, _model_free("fig13", "fig16")),
    Claim("fig13", "z RMS 3.2052", CANNOT, _z_rms("fig13", 3.2052)),
    Claim("fig14", "tracking restored, small periodic force errors", AGREES, _tdc("fig14")),
    Claim("fig14", "z RMS 0.0044", CANNOT, _z_rms("fig14", 0.0044)),
    Claim("fig15", "good tracking for k_e = 10 000 ... 100 000", AGREES, _tdc("fig15")),
    Claim("fig16", "TDC restores tracking", AGREES, _tdc("fig16")),
    Claim("fig16", "z RMS 0.0044", CANNOT, _z_rms("fig16", 0.0044)),
    Claim("fig17", "force overshoot grows with k_e", AGREES, _peaks("fig17", 10.0, 30.0)),
    Claim("fig18", "first-contact overshoot over 60 N", AGREES, _peaks("fig18", 60.0, math.inf)),
    Claim("fig19", "overshoot reduced to ~40 N", AGREES, _peaks("fig19", 25.0, 50.0)),
    Claim("fig20", "overshoot grows with k_e", AGREES, _peaks("fig20", 0.0, math.inf)),
    Claim("fig20", "from 30 N to 55 N", DIFFERS, _fig20_magnitude),
)  # fmt: skip
"""Every checkable claim of the paper with its documented verdict: the one source for the
generated README and the summary table of docs/reproduction.md (:func:`claims_markdown`)."""


def judge_claims(table: pl.DataFrame) -> list[tuple[Claim, str, str]]:
    """(claim, measured, printed verdict) for the claims whose figures are in ``table``."""
    out = []
    present = set(table["figure"].to_list())
    for claim in CLAIMS:
        if claim.figure not in present:
            continue
        try:
            measured, printed = claim.judge(table)
        except (IndexError, ValueError, pl.exceptions.PolarsError):
            # A claim that compares with a figure not in this table cannot be judged.
            continue
        out.append((claim, measured, printed))
    return out


def claims_markdown(table: pl.DataFrame) -> str:
    """The claims table (figure, paper, measured, verdict) as Markdown."""
    lines = ["| figure | paper | measured | verdict |", "|---|---|---|---|"]
    for claim, measured, printed in judge_claims(table):
        lines.append(f"| {claim.figure} | {claim.paper} | {measured} | {printed} |")
    return "\n".join(lines) + "\n"


DOC_BEGIN = "<!-- claims table: generated from admit_rs.reproduction.CLAIMS -->"
DOC_END = "<!-- end of claims table -->"


def update_doc(path: str | Path, table: pl.DataFrame) -> bool:
    """Rewrites the claims table between :data:`DOC_BEGIN` and :data:`DOC_END` in ``path``
    (docs/reproduction.md) from ``table``; returns whether the file changed.

    ``admit-rs paper --out docs/paper-results --update-doc docs/reproduction.md`` does it
    after regenerating the figures.
    """
    path = Path(path)
    text = path.read_text()
    head, rest = text.split(DOC_BEGIN, 1)
    _, tail = rest.split(DOC_END, 1)
    new = f"{head}{DOC_BEGIN}\n{claims_markdown(table)}{DOC_END}{tail}"
    if new != text:
        path.write_text(new)
    return new != text


def verdicts(table: pl.DataFrame) -> dict[str, Verdict]:
    """Per figure in ``table``: its measured numbers and whether *every* claim agrees."""
    out: dict[str, Verdict] = {}
    for claim, measured, printed in judge_claims(table):
        prev = out.get(claim.figure)
        agrees = printed == AGREES
        if prev is None:
            out[claim.figure] = Verdict(measured, agrees)
        else:
            out[claim.figure] = Verdict(f"{prev.measured}; {measured}", prev.agrees and agrees)
    return out


def _figure_verdict(printed: Sequence[str]) -> str:
    if all(p == AGREES for p in printed):
        return AGREES
    if any(p == AGREES for p in printed):
        return "agrees in part"
    return DIFFERS if any(p != CANNOT for p in printed) else CANNOT


_TABLE_COLUMNS = [
    "force_ss_error", "force_rms_error", "force_peak", "overshoot_pct", "settling_time",
    "rise_time_63", "z_rms_error", "x_rms_error", "contact_loss", "force_oscillation",
    "stable", "passed", "diverged",
]  # fmt: skip


def _markdown_table(table: pl.DataFrame) -> str:
    """The metrics table; headers carry units (see ``docs/metrics.md``)."""
    cols = ["figure", "label", *[c for c in _TABLE_COLUMNS if c in table.columns]]
    heads = [METRICS[c].label if c in METRICS else c for c in cols]
    lines = ["| " + " | ".join(heads) + " |", "|" + "---|" * len(cols)]
    for row in table.select(cols).iter_rows():
        cells = []
        for v in row:
            if isinstance(v, float):
                cells.append("–" if math.isnan(v) else f"{v:.4g}")
            else:
                cells.append(str(v))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _stability_lines(table: pl.DataFrame, name: str) -> list[str]:
    rows = _curves(table, name)
    if "verdict" not in rows.columns:
        return []
    # Not assessed is not passed; the verdict says unstable or out of tolerance (SPEC §23).
    column = "passed" if "passed" in rows.columns else "stable"
    bad = rows.filter(~pl.col(column).fill_null(False))
    if bad.is_empty():
        return [f"- Verdict: every curve stable and within its criteria ({rows.height})"]
    return [f"- Verdict: **{r['label']}: {r['verdict']}**" for r in bad.iter_rows(named=True)]


def _report(table: pl.DataFrame, names: Sequence[str], variant_names: Sequence[str]) -> str:
    judged = judge_claims(table)
    by_figure: dict[str, list[tuple[Claim, str, str]]] = {}
    for item in judged:
        by_figure.setdefault(item[0].figure, []).append(item)
    out = [
        "# admit_rs: reproduction of Jung & Jeong's simulations\n",
        "Generated by `admit-rs paper`. Every curve is one scenario of `admit_rs.paper`;"
        " the metrics (defined in `docs/metrics.md`, units in the table headers) are in"
        " `metrics.parquet` / `metrics.md`. Each row below is one claim of the paper with the"
        " verdict documented in `docs/reproduction.md` (the same claim table,"
        " `admit_rs.reproduction.CLAIMS`): *agrees*, *differs* or *cannot be reproduced*."
        " `docs/reproduction.md` discusses each difference.\n",
        "| figure | paper's claim | measured | verdict |",
        "|---|---|---|---|",
    ]
    for name in names:
        for claim, measured, printed in by_figure.get(name, []):
            out.append(f"| {name} | {claim.paper} | {measured} | {printed} |")
    out.append("")
    for name in names:
        info = FIGURES[name]
        claims = by_figure.get(name, [])
        overall = _figure_verdict([p for _, _, p in claims]) if claims else "–"
        out.append(f"## Fig. {info.number}: {info.caption} — {overall}\n")
        out.append(f"![{name}]({name}.png)\n")
        for claim, measured, printed in claims:
            out.append(f"- Paper: {claim.paper}. Measured: {measured} — **{printed}**")
        out.extend(_stability_lines(table, name))
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
        raise ArgumentError(f"unknown figures {unknown}; choose from {list(FIGURES)}")
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
