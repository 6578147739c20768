"""The ``admit-rs`` command line.

admit-rs paper --out paper-results          # every figure, metrics table, report
admit-rs paper --figure 14 --out results    # one figure
admit-rs run SCENARIO.toml [-o trace.parquet] [--plot run.png] [--format json|table]
admit-rs tune fig14 --vary admittance.b=100:3000 --vary admittance.ka=0.2:5 \
    --over wall.stiffness=1e4:1e5 --max-overshoot 15      # predict, search, verify
admit-rs ui [SCENARIO.toml | figNN] [--port P] [--no-browser]   # the tuning page

Exit codes: 0 success, 2 invalid input, 3 run not stable, 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from PyPI
    import tomli as tomllib

from admit_rs.errors import AnalysisError, ArgumentError, ParameterError, ParameterTypeError

if TYPE_CHECKING:
    from admit_rs.config import Scenario

EXIT_CODES = """exit codes:
  0    success (run: the scenario is stable and passes its criteria)
  2    invalid input: bad parameter, unknown key, unreadable TOML, missing file, bad usage
  3    run: the scenario is unstable, out of tolerance (stable, but a criterion
       fails) or too short to assess (see "verdict");
       tune: the simulation did not verify the tuned gains
  130  interrupted (Ctrl-C); sweep writes the finished runs first"""


def _paper(args: argparse.Namespace) -> int:
    from admit_rs.reproduction import AGREES, judge_claims, reproduce

    start = time.perf_counter()
    table = reproduce(args.out, args.figure, progress=not args.no_progress)
    elapsed = time.perf_counter() - start
    print(f"wrote {table.height} curves of {len(set(table['figure']))} figures to {args.out}"
          f" in {elapsed:.1f} s")  # fmt: skip
    by_verdict: dict[str, list[str]] = {}
    for claim, _, printed in judge_claims(table):
        if printed != AGREES:
            by_verdict.setdefault(printed, []).append(f"{claim.figure} ({claim.paper})")
    for printed, claims in by_verdict.items():
        print(f"{printed} (see {args.out}/README.md): {'; '.join(claims)}")
    if args.update_doc is not None:
        from admit_rs.reproduction import update_doc

        changed = update_doc(args.update_doc, table)
        print(f"{args.update_doc}: claims table {'updated' if changed else 'unchanged'}")
    return 0


def _read_toml(path: Path | str) -> dict[str, Any]:
    """A TOML file's tables; a file that cannot be read as TOML (not UTF-8, invalid, nested
    deeper than the parser recurses) is a ParameterError naming the file."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError) as e:
        why = {
            UnicodeDecodeError: "not UTF-8 text",
            RecursionError: "nested too deeply to read",
        }.get(type(e), str(e).splitlines()[0] if str(e) else "invalid TOML")
        err = ParameterError(f"{path} is invalid: must be a TOML file ({why})")
        err.field, err.value, err.allowed = str(path), str(path), "a TOML file"
        raise err from None


def _resolve_urdf(table: dict[str, Any], toml_path: Path) -> dict[str, Any]:
    """A URDF arm's relative ``path`` is relative to the TOML file that names it."""
    robot = table.get("robot")
    if isinstance(robot, dict) and "path" in robot and "urdf" not in robot:
        path = Path(robot["path"])
        if not path.is_absolute():
            table = {**table, "robot": {**robot, "path": str(toml_path.parent / path)}}
    return table


def _scenario_argument(name: str) -> Scenario:
    """A command's scenario: a TOML file (a URDF path in it relative to the file), else a
    paper figure (``fig14``, ``14``, ``fig9:2`` for its second curve), as ``ui`` takes."""
    from admit_rs import paper
    from admit_rs.config import Scenario

    path = Path(name)
    if path.suffix == ".toml" or path.exists():
        data = _read_toml(path)
        return Scenario.from_dict(_resolve_urdf(data.get("scenario", data), path))
    fig, _, curve = name.partition(":")
    curves = paper.scenarios(f"fig{fig}" if fig.isdigit() else fig)
    if not curve:
        return curves[0]
    if not curve.isdigit() or not 1 <= int(curve) <= len(curves):
        raise ArgumentError(f"{name}: {fig} has curves 1 to {len(curves)}")
    return curves[int(curve) - 1]


def _run(args: argparse.Namespace) -> int:
    from admit_rs.simulation import simulate

    scenario = _scenario_argument(str(args.scenario))
    result = simulate(scenario)
    if args.output:
        result.trace.write_parquet(args.output)
    if args.plot:
        result.plot().savefig(args.plot, dpi=100)
    report = {"stable": result.stable, "passed": result.passed, "diverged": result.diverged,
              "verdict": result.verdict,
              "diverged_at": result.diverged_at, "divergence_cause": result.divergence_cause,
              "metrics": dict(result.metrics)}  # fmt: skip
    if args.format == "table":
        print(_table(report))
    else:
        print(json.dumps(_json_safe(report), indent=2, allow_nan=False))
    return 0 if result.passed is True else 3


def _json_safe(value: Any) -> Any:
    """NaN and ±inf become ``null`` (JSON has no NaN); numpy scalars become Python ones."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str | int):
        return value
    f = float(value)
    return f if math.isfinite(f) else None


_SETTLED = frozenset({
    "force_ss_error", "force_rms_error", "overshoot_pct", "settling_time", "rise_time_63",
    "rise_time_10_90", "peak_time", "step_overshoot_pct", "step_peak_time",
})  # fmt: skip
"""Metrics that describe a settled response: for a run that is not stable they are marked."""


def _table(report: dict[str, Any]) -> str:
    from admit_rs.metrics import METRICS

    settled = report["stable"] is True
    rows = [("verdict", report["verdict"], "")]
    for name, value in report["metrics"].items():
        unit = METRICS[name].unit if name in METRICS else ""
        if value is None:
            text = "null"
        elif isinstance(value, bool):
            text = str(value)
        else:
            text = f"{value:.6g}"
        text = "–" if text == "nan" else text
        if not settled and name in _SETTLED and text != "–":
            text += " *"  # a number of an unsettled run: not a good response
        rows.append((name, text, "" if unit.startswith("bool") else unit))
    width = max(len(r[0]) for r in rows)
    vwidth = max(len(r[1]) for r in rows[1:])
    lines = [f"{n:<{width}}  {v:>{vwidth}}  {u}".rstrip() for n, v, u in rows]
    what = {None: "not assessed", False: "NOT STABLE", True: "OUT OF TOLERANCE"}[
        report["stable"]]
    if report["passed"] is not True:
        lines.insert(0, f"{what}: {report['verdict']}")
    if not settled:
        lines.append(f"* the run is {what.lower()}: these numbers describe no settled "
                     "response (steady error, rise, overshoot); do not read them as its "
                     "performance")  # fmt: skip
    return "\n".join(lines)


def load_sweep(path: Path) -> dict[str, Any]:
    """Reads a sweep TOML (see examples/stiffness_sweep.toml) into ``sweep()`` arguments."""
    from admit_rs import paper
    from admit_rs.config import Scenario
    from admit_rs.sweep import Choice, LogUniform, Normal, Uniform

    data = _read_toml(path)
    known = {"base", "scenario", "overrides", "vary", "grid", "samples", "seed", "chunk_size"}
    unknown = set(data) - known
    if unknown:
        raise ParameterTypeError(
            f"{path}: unknown keys {sorted(unknown)}; allowed: {sorted(known)}"
        )
    if "scenario" in data:
        scenario = Scenario.from_dict(_resolve_urdf(data["scenario"], Path(path)))
    else:
        scenario = paper.scenario(data.get("base", "fig14"))
    scenario = scenario.replace(**data.get("overrides", {}))
    dists = {"uniform": Uniform, "loguniform": LogUniform, "normal": Normal, "choice": Choice}
    vary = {}
    for name, spec in data.get("vary", {}).items():
        spec = dict(spec)
        kind = str(spec.pop("dist", "")).lower()
        if kind not in dists:
            raise ParameterTypeError(f"vary.{name}.dist = {kind!r}: one of {sorted(dists)}")
        vary[name] = dists[kind](**spec)
    return {
        "scenario": scenario,
        "vary": vary,
        "grid": data.get("grid", {}),
        "samples": data.get("samples"),
        "seed": data.get("seed", 0),
        "chunk_size": data.get("chunk_size", 256),
    }


def _sweep(args: argparse.Namespace) -> int:
    from admit_rs.sweep import SweepInterrupted, sweep

    kwargs = load_sweep(args.definition)
    start = time.perf_counter()
    try:
        table = sweep(
            **kwargs,
            threads=args.threads,
            checkpoint=args.checkpoint,
            progress=not args.no_progress,
        )
    except SweepInterrupted as e:
        e.table.write_parquet(args.output)
        print(f"interrupted: wrote the {e.table.height} finished runs to {args.output}",
              file=sys.stderr)  # fmt: skip
        return 130
    assert not isinstance(table, tuple)
    elapsed = time.perf_counter() - start
    table.write_parquet(args.output)
    unstable = int((table["stable"] == False).sum())  # noqa: E712 (a polars mask)
    out_of_tolerance = int(((table["stable"] == True) & (table["passed"] == False)).sum())  # noqa: E712
    unassessed = table["stable"].null_count()
    print(f"{table.height} runs in {elapsed:.1f} s ({table.height / elapsed:.0f} runs/s),"
          f" {unstable} unstable, {out_of_tolerance} out of tolerance, {unassessed} not"
          f" assessed -> {args.output}")  # fmt: skip
    return 0


def _range(text: str) -> tuple[str, tuple[float, float]]:
    """``path=lo:hi`` → (path, (lo, hi))."""
    path, sep, bounds = text.partition("=")
    lo, sep2, hi = bounds.partition(":")
    if not (sep and sep2 and path):
        raise argparse.ArgumentTypeError(f"{text!r}: expected PATH=LO:HI")
    try:
        return path.strip(), (float(lo), float(hi))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: LO and HI must be numbers") from None


def _tune(args: argparse.Namespace) -> int:
    from admit_rs.analysis import tune

    scenario = _scenario_argument(str(args.scenario))
    start = time.perf_counter()
    result = tune(scenario, vary=dict(args.vary), over=dict(args.over),
                  max_overshoot_pct=args.max_overshoot, stability_margin=args.margin,
                  verify_duration=args.verify_duration)  # fmt: skip
    elapsed = time.perf_counter() - start
    if args.format == "table":
        # The terminal's width (COLUMNS, else 80): a table wider than it wraps numbers and
        # verdicts mid-word (issue #53, item 20).
        print(result.report(shutil.get_terminal_size((80, 24)).columns))
        print(f"({result.evaluated} predictions, {elapsed:.1f} s)")
    else:
        report = {"gains": result.gains, "verified": result.verified,
                  "worst_predicted_settling_time": result.worst_settling_time,
                  "rounds": result.rounds,
                  "predicted": result.predicted.to_dicts(),
                  "verification": result.verification.to_dicts(),
                  "predictions": result.evaluated, "seconds": elapsed}  # fmt: skip
        print(json.dumps(_json_safe(report), indent=2, allow_nan=False))
    return 0 if result.verified else 3


def _ui(args: argparse.Namespace) -> int:
    from admit_rs import ui

    try:
        ui.serve(args.scenario, port=args.port, open_browser=not args.no_browser)
    except KeyboardInterrupt:  # how a server is stopped: not a failure
        print("admit-rs ui: stopped", file=sys.stderr)
    except ImportError as e:
        print(f"admit-rs: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # the port is taken, or not ours to bind
        print(f"admit-rs: error: cannot serve on 127.0.0.1:{args.port}: {e.strerror or e}",
              file=sys.stderr)  # fmt: skip
        return 2
    return 0


def _identify(args: argparse.Namespace) -> int:
    """Reads the log, fits the cell on its first part, checks it on the rest, writes the
    report and the fitted scenario (fig. 14's loop on the arm, the fitted wall and sensor)."""
    import polars as pl
    from tqdm.auto import tqdm

    from admit_rs import export, paper
    from admit_rs.blocks.controller import TimeDelayControl
    from admit_rs.blocks.robot import UrdfArm
    from admit_rs.identification import identify
    from admit_rs.recording import read_log

    if not 0 < args.holdout < 0.9:
        raise ValueError(f"--holdout {args.holdout} is invalid: must be in (0, 0.9)")
    out: Path = args.out
    steps = ["read the log", "fit the cell", "check it on the held-out part", "write"]
    bar = tqdm(total=len(steps), unit="step", disable=args.no_progress)
    bar.set_description(steps[0])
    arm = UrdfArm(args.urdf, args.tip, q0=tuple(args.q0) if args.q0 else None)
    log = read_log(args.log, robot=arm)
    split = int(round(log.height * (1 - args.holdout)))
    bar.update()
    bar.set_description(steps[1])
    fit = identify(log.head(split), arm, surface=args.surface)
    bar.update()
    bar.set_description(steps[2])
    held = log.slice(split).with_columns(pl.col("t") - pl.col("t").first())
    report = fit.report(out, held, arm, title=f"Cell fitted from {Path(args.log).name}")
    bar.update()
    bar.set_description(steps[3])
    base = paper.scenario("fig14").replace(robot=arm, controller=TimeDelayControl.for_arm(arm))
    export.toml(fit.scenario(base), out / "cell.toml")
    bar.update()
    bar.close()
    print(fit)
    print(f"{fit.check(held, arm)}\nwrote {report}, {out / 'check.png'} and {out / 'cell.toml'}")
    return 0


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="admit-rs",
        description="Admittance force tracking control of robot manipulators (Jung & Jeong).",
        epilog=EXIT_CODES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="command", required=True)
    paper = sub.add_parser("paper", help="reproduce the paper's figures 5-20 and a metrics table")
    paper.add_argument("--out", type=Path, default=Path("paper-results"), help="output folder")
    paper.add_argument(
        "--figure", type=int, action="append", choices=range(5, 21), metavar="N",
        help="only figure N (5-20); repeat for several",
    )  # fmt: skip
    paper.add_argument("--no-progress", action="store_true", help="no progress bar")
    paper.add_argument("--update-doc", type=Path, metavar="MD",
                       help="rewrite the claims table in this Markdown file"
                            " (docs/reproduction.md)")  # fmt: skip
    paper.set_defaults(func=_paper)
    run = sub.add_parser("run", help="run one scenario from a TOML file, print its metrics",
                         epilog=EXIT_CODES,
                         formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    run.add_argument("scenario", help="TOML file (Scenario.to_dict layout) or a paper figure "
                     "(fig14, fig9:2 for its 2nd curve)")  # fmt: skip
    run.add_argument("-o", "--output", type=Path, help="write the trace as Parquet")
    run.add_argument("--plot", type=Path, help="write the standard plot as PNG")
    run.add_argument("--format", choices=("json", "table"), default="json",
                     help="json (default; NaN printed as null) or a table with units")  # fmt: skip
    run.set_defaults(func=_run)
    sw = sub.add_parser("sweep", help="run a Monte Carlo / grid sweep from a TOML file")
    sw.add_argument("definition", type=Path, help="sweep TOML (see examples/)")
    sw.add_argument("-o", "--output", type=Path, required=True, help="results Parquet file")
    sw.add_argument("--threads", type=int, help="Rust threads (default: all cores)")
    sw.add_argument("--checkpoint", type=Path, help="folder for resumable chunk files")
    sw.add_argument("--no-progress", action="store_true", help="no progress bar")
    sw.set_defaults(func=_sweep)
    tn = sub.add_parser(
        "tune", epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter,
        help="choose gains for the worst case of an uncertain box, predicted then simulated",
    )  # fmt: skip
    tn.add_argument("scenario", help="TOML file (Scenario.to_dict layout) or a paper figure "
                                     "name such as fig14")  # fmt: skip
    tn.add_argument("--vary", type=_range, action="append", required=True, metavar="PATH=LO:HI",
                    help="a gain to choose, e.g. admittance.b=100:3000; repeat")  # fmt: skip
    tn.add_argument("--over", type=_range, action="append", required=True, metavar="PATH=LO:HI",
                    help="an uncertain parameter, e.g. wall.stiffness=1e4:1e5; repeat")  # fmt: skip
    tn.add_argument("--max-overshoot", type=float, default=10.0, help="percent (default 10)")
    tn.add_argument("--margin", type=float, default=0.001,
                    help="spectral radius <= 1 - margin (default 0.001)")  # fmt: skip
    tn.add_argument("--verify-duration", type=float, help="seconds per verification run")
    tn.add_argument("--format", choices=("json", "table"), default="table")
    tn.set_defaults(func=_tune)
    ui = sub.add_parser("ui", help="the tuning page: sliders that re-simulate live, in a browser")
    ui.add_argument("scenario", nargs="?", default="fig14",
                    help="a paper figure (fig14, fig9:2 for its 2nd curve) or a TOML file "
                         "(default fig14)")  # fmt: skip
    ui.add_argument("--port", type=int, default=None, help="port on 127.0.0.1 (default: free)")
    ui.add_argument("--no-browser", action="store_true", help="do not open a browser")
    ui.set_defaults(func=_ui)
    ident = sub.add_parser(
        "identify", help="fit your cell (surface, sensor, tool) from a recording, and check it",
        epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    ident.add_argument("log", help="a ROS 2 bag (folder, .db3, .mcap), a ROS 1 .bag, or a "
                                   ".csv / .parquet table (docs/recording.md)")  # fmt: skip
    ident.add_argument("--urdf", type=Path, required=True, help="the arm's URDF file")
    ident.add_argument("--tip", required=True, help="the tip (tool) link the sensor reads in")
    ident.add_argument("--q0", type=float, nargs="+", help="the arm's start joints (default: "
                                                           "the URDF's zero)")  # fmt: skip
    ident.add_argument("--out", type=Path, required=True,
                       help="folder for report.md, check.png and cell.toml")  # fmt: skip
    ident.add_argument("--holdout", type=float, default=0.25,
                       help="the last part of the log kept to check the fit "
                            "(default 0.25)")  # fmt: skip
    ident.add_argument("--surface", choices=("plane", "sphere"), default="plane",
                       help="the part's shape: a plane (default) or a ball touched from "
                            "outside")  # fmt: skip
    ident.add_argument("--no-progress", action="store_true", help="no progress bar")
    ident.set_defaults(func=_identify)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (
        ParameterError, AnalysisError, TypeError, ValueError, FileNotFoundError,
        tomllib.TOMLDecodeError, KeyError,
    ) as e:  # fmt: skip
        print(f"admit-rs: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("admit-rs: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
