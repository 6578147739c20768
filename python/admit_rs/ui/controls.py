"""What the tuning page controls, read from the blocks' one declaration (SPEC §14, §18).

Each slider is a field whose Rust declaration carries an ``x-ui`` hint in its JSON schema
(``_core.schema()``): a typical range, a scale (``linear`` or ``log``) and, when the field's
doc has no ``[unit]`` bracket, a unit. Nothing here lists fields: the controls of a scenario
are found by walking its blocks (the ones it holds: a computed-torque scenario shows no
``inertia``, a position-only one no filter). The page state is a set of overrides by dotted
path on a base scenario (a paper figure's curve or a TOML file), written to and read from
the URL query (``?admittance.b=200&wall.stiffness=1e6``).

Nothing here imports Bokeh: it is the page's model, tested on its own.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import sys
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from admit_rs import _core, paper
from admit_rs.config import Scenario, _Block
from admit_rs.errors import AdmitError, ParameterError, closest

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from PyPI
    import tomli as tomllib

__all__ = [
    "BASE_KEY",
    "Control",
    "QueryError",
    "base_names",
    "controls",
    "load_base",
    "parse_query",
    "query_string",
    "register_upload",
]

BASE_KEY = "scenario"
"""The query key naming the base scenario: a paper figure (``fig14``), one curve of a
multi-curve figure (``fig9:2``, counted from 1), a TOML file's path or an uploaded file
(``upload:<sha256[:12]>``)."""

SEED_PATH = "seed"

_UNIT = re.compile(r"\[([^\]]+)\]")
_SCHEMA: dict[str, Any] = _core.schema()


class QueryError(AdmitError, ValueError):
    """A URL query the page cannot apply (a value that is not a number, an unknown path, an
    unknown base scenario); the message says which parameter and why."""


@dataclass(frozen=True)
class Control:
    """One slider: a numeric field of the scenario, by dotted path.

    ``low``/``high`` are the field's typical range (``x-ui`` in its schema), widened to hold
    the current value; ``scale`` is ``"log"`` (the slider moves log10 of the value) or
    ``"linear"``; ``integer`` fields step by 1; ``nullable`` fields may be off (``None``:
    no filter, no limit), ``value`` is ``None`` then. ``per_joint`` holds a per-joint
    value the slider would replace by one number for every joint."""

    path: str
    block: str
    name: str
    doc: str
    unit: str
    low: float
    high: float
    scale: str
    integer: bool
    nullable: bool
    value: float | None
    step: float | None = None
    per_joint: tuple[float, ...] | None = None

    @property
    def title(self) -> str:
        return f"{self.name} [{self.unit}]" if self.unit else self.name

    def to_slider(self, value: float) -> float:
        """The slider position of a field value (log10 on a log scale)."""
        if self.scale == "log":
            return math.log10(max(value, self.low))
        return value

    def from_slider(self, position: float) -> float | int:
        """The field value of a slider position: whole numbers for integer fields, else
        three significant digits on a log scale (``398``, not ``398.107…``) and the step's
        precision on a linear one, so that values and URLs stay readable."""
        if self.integer:
            return int(round(position))
        if self.scale == "log":
            return _round_sig(10.0**position, 3)
        step = self.slider_step
        digits = max(0, -math.floor(math.log10(step)) + 1) if step > 0 else 12
        return round(position, digits) + 0.0  # no "-0.0" in URLs

    @property
    def slider_range(self) -> tuple[float, float]:
        return (self.to_slider(self.low), self.to_slider(self.high))

    @property
    def slider_step(self) -> float:
        if self.integer:
            return 1.0
        if self.step is not None:
            return float(self.step) if self.scale == "linear" else float(self.step)
        lo, hi = self.slider_range
        return (hi - lo) / 400.0


def _round_sig(x: float, digits: int) -> float:
    if x == 0 or not math.isfinite(x):
        return x
    return float(f"{x:.{digits}g}")


def schema_key(block: _Block) -> str:
    """The block's key in ``_core.schema()`` (the core's registry)."""
    return block._key


def _nullable(prop: Mapping[str, Any]) -> bool:
    t = prop.get("type")
    if isinstance(t, list) and "null" in t:
        return True
    return any(alt.get("type") == "null" for alt in prop.get("anyOf", ()))


def _integer(prop: Mapping[str, Any]) -> bool:
    t = prop.get("type")
    return t == "integer" or (isinstance(t, list) and "integer" in t)


def unit_of(prop: Mapping[str, Any]) -> str:
    """The field's unit: ``x-ui.unit`` if given, else the first ``[…]`` of its doc
    (``"Damping [N·s/m]."`` → ``N·s/m``); ``dimensionless`` is no unit."""
    hint = prop.get("x-ui", {})
    if "unit" in hint:
        return str(hint["unit"])
    m = _UNIT.search(prop.get("description", ""))
    unit = m.group(1) if m else ""
    return "" if unit == "dimensionless" else unit


def _control(
    path: str, block: str, name: str, prop: Mapping[str, Any], value: Any
) -> Control | None:
    hint = prop["x-ui"]
    per_joint: tuple[float, ...] | None = None
    if isinstance(value, tuple | list):
        if not value or not all(isinstance(v, int | float) for v in value):
            return None  # a matrix (inertia given as rows): no one slider can hold it
        if path.endswith("sensor.bias"):
            # A bias per tip-frame axis, not per joint: one number there is a bias along
            # n̂ (ForceSensor.bias), another thing, so no slider stands for the vector.
            return None
        per_joint = tuple(float(v) for v in value)
        shown: float | None = max(per_joint) if len(set(per_joint)) > 1 else per_joint[0]
        if len(set(per_joint)) == 1:
            per_joint = None
    elif value is None:
        shown = None
    elif isinstance(value, bool) or not isinstance(value, int | float):
        return None
    else:
        shown = float(value)
    low, high, scale = float(hint["min"]), float(hint["max"]), str(hint["scale"])
    if shown is not None and math.isfinite(shown):
        if scale == "log" and shown > 0:
            low, high = min(low, shown), max(high, shown)
        elif scale == "linear":
            low, high = min(low, shown), max(high, shown)
    return Control(
        path=path, block=block, name=name, doc=" ".join(prop.get("description", "").split()),
        unit=unit_of(prop), low=low, high=high, scale=scale, integer=_integer(prop),
        nullable=_nullable(prop), value=shown,
        step=float(hint["step"]) if "step" in hint else None, per_joint=per_joint,
    )  # fmt: skip


def controls(scenario: Scenario) -> list[Control]:
    """The sliders of ``scenario``: every field with an ``x-ui`` hint in the schema of the
    blocks it holds, depth first in field order (scenario-level fields last), by dotted
    path."""
    out: list[Control] = []
    top: list[Control] = []

    def walk(block: _Block, prefix: str, into: list[Control]) -> None:
        props = _SCHEMA[schema_key(block)]["properties"]
        for f in dataclasses.fields(block):  # type: ignore[arg-type]
            value = getattr(block, f.name)
            path = f"{prefix}{f.name}"
            if isinstance(value, _Block):
                walk(value, f"{path}.", out)
                continue
            prop = props.get(f.name, {})
            if "x-ui" in prop:
                c = _control(path, prefix.rstrip(".") or "scenario", f.name, prop, value)
                if c is not None:
                    into.append(c)

    walk(scenario, "", top)
    return out + top


# -- the base scenario ---------------------------------------------------------------------


def base_names() -> list[tuple[str, str]]:
    """(name, label) of every paper figure's curve: ``fig14``, ``fig9:2``, …"""
    out: list[tuple[str, str]] = []
    for fig in paper.FIGURES:
        curves = paper.scenarios(fig)
        for i, sc in enumerate(curves, start=1):
            name = fig if i == 1 else f"{fig}:{i}"
            out.append((name, f"{name}: {sc.label}" if sc.label else name))
    return out


def load_base(name: str) -> Scenario:
    """The base scenario ``name``: a paper figure (``fig14``, ``14``), one of its curves
    (``fig9:2``), a TOML file (``path/to/scenario.toml``, in the layout ``admit-rs run``
    reads) or one uploaded to this server (:func:`register_upload`). Errors are
    :class:`QueryError` or the scenario's own ParameterError."""
    text = str(name).strip()
    if text.startswith(UPLOAD_PREFIX):
        return _load_upload(text)
    if text.endswith(".toml") or "/" in text or Path(text).suffix:
        return _load_toml(Path(text))
    fig, _, curve = text.partition(":")
    fig = f"fig{fig}" if fig.isdigit() else fig
    if fig not in paper.FIGURES:
        near = closest(fig, paper.FIGURES)
        hint = f"; did you mean {', '.join(near)}?" if near else ""
        raise QueryError(
            f"{BASE_KEY}={text}: no paper figure or TOML file of that name{hint} "
            "(figures fig5 to fig20, curves as fig9:2, or a path ending in .toml)"
        )
    curves = paper.scenarios(fig)
    if not curve:
        return curves[0]
    if not curve.isdigit() or not 1 <= int(curve) <= len(curves):
        raise QueryError(f"{BASE_KEY}={text}: {fig} has curves 1 to {len(curves)}")
    return curves[int(curve) - 1]


def _load_toml(path: Path) -> Scenario:
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise QueryError(f"{BASE_KEY}={path}: no such file") from None
    except OSError as e:
        raise QueryError(f"{BASE_KEY}={path}: cannot read it ({e.strerror})") from None
    return _scenario_of_toml(raw, f"{BASE_KEY}={path}", path.parent)


def _scenario_of_toml(raw: bytes, what: str, folder: Path) -> Scenario:
    """The scenario of a TOML file's bytes; a relative URDF path is relative to ``folder``."""
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        first = str(e).splitlines()[0] if str(e) else "invalid TOML"
        raise QueryError(f"{what}: not a valid TOML file ({first})") from None
    table = data.get("scenario", data)
    if not isinstance(table, dict):
        raise QueryError(f"{what}: [scenario] must be a table")
    robot = table.get("robot")
    if isinstance(robot, dict) and "path" in robot and "urdf" not in robot:
        p = Path(robot["path"])
        if not p.is_absolute():
            table = {**table, "robot": {**robot, "path": str(folder / p)}}
    return Scenario.from_dict(table)


UPLOAD_PREFIX = "upload:"
"""Base names of uploaded TOML files: ``upload:`` and the first 12 hex digits of the file's
SHA-256, so that the same file is the same name (and the same link)."""
MAX_UPLOADS = 64
_UPLOADS: dict[str, Scenario] = {}
_UPLOADS_LOCK = threading.Lock()


def register_upload(raw: bytes, filename: str) -> str:
    """Reads an uploaded TOML file (its bytes; ``filename`` for messages) and keeps its
    scenario in this process under the base name it returns (``upload:<sha256[:12]>``),
    which :func:`load_base`, and so a link, then accepts while this server runs (the last
    :data:`MAX_UPLOADS` files). A relative URDF path in it is relative to the server's
    working directory (an upload has no folder). Errors as :func:`load_base`'s."""
    name = UPLOAD_PREFIX + hashlib.sha256(raw).hexdigest()[:12]
    scenario = _scenario_of_toml(raw, f"uploaded file {filename}", Path.cwd())
    with _UPLOADS_LOCK:
        _UPLOADS.pop(name, None)
        _UPLOADS[name] = scenario
        while len(_UPLOADS) > MAX_UPLOADS:
            del _UPLOADS[next(iter(_UPLOADS))]
    return name


def _load_upload(name: str) -> Scenario:
    with _UPLOADS_LOCK:
        scenario = _UPLOADS.get(name)
    if scenario is None:
        raise QueryError(f"{BASE_KEY}={name}: an uploaded file this server does not hold "
                         "(uploads last while the server runs): upload the file again")  # fmt: skip
    return scenario


# -- the URL query -------------------------------------------------------------------------


def format_value(value: float | int | None) -> str:
    """A value as the query writes it: ``200``, ``1e+06``→``1000000``, ``0.005``, ``none``."""
    if value is None:
        return "none"
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    v = float(value)
    if v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return repr(v)


def _parse_value(path: str, text: str, control: Control | None) -> float | int | None:
    raw = text.strip()
    if raw.lower() in ("none", "off", "null"):
        if control is not None and not control.nullable:
            raise QueryError(f"{path}={text}: {path} cannot be off (it takes a number)")
        return None
    if control is not None and control.integer:
        try:  # exactly, digit by digit: float() would round a seed above 2^53
            return int(raw)
        except ValueError:
            pass
    try:
        value = float(raw)
    except ValueError:
        raise QueryError(f"{path}={text}: not a number") from None
    if not math.isfinite(value):
        raise QueryError(f"{path}={text}: must be a finite number")
    if control is not None and control.integer:
        if not value.is_integer():
            raise QueryError(f"{path}={text}: must be a whole number")
        return int(value)
    return value


def parse_query(
    query: Mapping[str, Iterable[str]], base: Scenario
) -> tuple[dict[str, float | int | None], list[str]]:
    """The overrides a URL query sets on ``base`` and the errors of the ones it cannot
    (each a sentence naming the parameter; a bad one is left out, the others apply).

    Every key but :data:`BASE_KEY` is a dotted path of a slider of ``base`` (another path,
    even a valid field, is refused: the page could not show it), a value a number or
    ``none`` for a field that may be off. Each value is checked by the block it lands in,
    so an out-of-range one is refused with the block's own message."""
    by_path = {c.path: c for c in controls(base)}
    overrides: dict[str, float | int | None] = {}
    errors: list[str] = []
    for key, values in query.items():
        if key == BASE_KEY:
            continue
        texts = list(values)
        text = texts[-1] if texts else ""
        control = by_path.get(key)
        if control is None:
            near = closest(key, by_path)
            hint = f"; did you mean {', '.join(near)}?" if near else ""
            errors.append(f"{key}={text}: not a parameter of this page{hint}")
            continue
        try:
            value = _parse_value(key, text, control)
            base.replace(**{**overrides, key: value})
        except QueryError as e:
            errors.append(str(e))
            continue
        except (ParameterError, TypeError, ValueError) as e:
            errors.append(f"{key}={text}: {e}")
            continue
        overrides[key] = value
    return overrides, errors


def query_string(base_name: str | None, overrides: Mapping[str, float | int | None]) -> str:
    """``?scenario=fig14&admittance.b=200`` (paths in the order they were set); ``""`` when
    there is nothing to say. Dotted paths and figure names need no escaping."""
    from urllib.parse import quote

    parts = [] if base_name is None else [f"{BASE_KEY}={quote(base_name, safe='/:.')}"]
    parts += [f"{k}={quote(format_value(v), safe='.+-')}" for k, v in overrides.items()]
    return "?" + "&".join(parts) if parts else ""
