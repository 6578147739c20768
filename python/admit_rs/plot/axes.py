"""What the sweep plots share: axes labelled with units (from :data:`admit_rs.METRICS` and
the blocks' docs), log or categorical cells, tick labels that do not collide."""

from __future__ import annotations

import ast
import functools
import inspect
import re
import textwrap
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from matplotlib.ticker import NullLocator

from admit_rs.errors import ArgumentError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure



def _finish_grid_axes(
    ax: Axes,
    xe: npt.NDArray[np.float64],
    ye: npt.NDArray[np.float64],
    logx: bool,
    logy: bool,
    xlabel: str,
    ylabel: str,
    handles: list[Any],
) -> None:
    """Scales, limits (the cell edges), labels and the legend below a grid plot."""
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncols=2,
                  fontsize=8, frameon=False)  # fmt: skip

def parameter_unit(path: str) -> str:
    """The unit of a dotted parameter path, from its block's attribute docstring ("" if none).

    Example:
        >>> parameter_unit("wall.stiffness"), parameter_unit("admittance.b")
        ('N/m', 'N·s/m')
    """
    from admit_rs import config

    leaf = path.rsplit(".", 1)[-1]
    owner: Any = config.Scenario()
    for part in path.split(".")[:-1]:
        owner = getattr(owner, part, None)
    classes = [type(owner)] if owner is not None else []
    classes += [c for c in vars(config).values()
                if isinstance(c, type) and issubclass(c, config._Block)]  # fmt: skip
    for cls in classes:
        for klass in cls.__mro__:
            doc = _attribute_docs(klass).get(leaf)
            if doc is not None:
                found = re.search(r"\[([^\]]+)\]", doc)
                return found.group(1) if found else ""
    return ""


@functools.cache
def _attribute_docs(cls: type) -> dict[str, str]:
    """``{field: docstring}`` from the string literal under each annotated field."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    docs = {}
    for a, b in zip(body, body[1:], strict=False):
        if (isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name)
                and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant)
                and isinstance(b.value.value, str)):  # fmt: skip
            docs[a.target.id] = b.value.value
    return docs


def _metric_label(name: str, units: dict[str, str] | None = None) -> str:
    from admit_rs.metrics import METRICS

    if units and name in units:
        return f"{name} [{units[name]}]"
    return METRICS[name].label if name in METRICS else _with_unit(name, units)


def _with_unit(name: str, units: dict[str, str] | None = None) -> str:
    unit = (units or {}).get(name)
    if unit is None:
        unit = parameter_unit(name) if "." in name else ""
    return f"{name} [{unit}]" if unit else name


def _log_axis(values: npt.NDArray[np.float64], bins: int = 12) -> bool:
    """Whether values look log-uniform (random draws) or log-spaced (a grid)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0 or v.min() <= 0:
        return False
    distinct = np.unique(v)
    if distinct.size < 3:
        return bool(distinct[-1] / distinct[0] > 50)
    if distinct.size <= bins:  # a grid: geometric rather than arithmetic spacing
        lin, geo = np.diff(distinct), np.diff(np.log(distinct))
        return bool(np.std(geo) / np.mean(geo) < np.std(lin) / np.mean(lin))
    lo, hi = distinct[0], distinct[-1]
    if hi / lo < 5:
        return False
    # Draws: the median sits at the geometric middle for log-uniform, the arithmetic one
    # for uniform.
    med = np.log(np.median(v))
    return bool(abs(med - np.log(np.sqrt(lo * hi))) < abs(med - np.log((lo + hi) / 2)))


def _axis(
    values: npt.NDArray[np.float64], bins: int, log: bool = False
) -> tuple[npt.NDArray[np.float64], Any]:
    """Cell edges and each value's cell: distinct values if few, else equal-width bins
    (equal in log10 when ``log``)."""
    if log:
        edges, index = _axis(np.log10(values), bins)
        return 10.0**edges, index
    distinct = np.unique(values[np.isfinite(values)])
    if distinct.size == 0:
        raise ArgumentError("no finite values to place on the axis")
    if distinct.size <= bins:
        if distinct.size == 1:
            edges = np.array([distinct[0] - 0.5, distinct[0] + 0.5])
        else:
            mids = (distinct[1:] + distinct[:-1]) / 2
            edges = np.concatenate(
                [[distinct[0] - (mids[0] - distinct[0])], mids,
                 [distinct[-1] + (distinct[-1] - mids[-1])]]
            )  # fmt: skip
        return edges, np.searchsorted(distinct, values)
    edges = np.linspace(distinct[0], distinct[-1], bins + 1)
    return edges, np.clip(np.searchsorted(edges, values, side="right") - 1, 0, bins - 1)


def _crosses_zero(distinct: npt.NDArray[np.float64]) -> bool:
    """Positive values whose cells on a linear axis (edges halfway between values) would
    start below zero."""
    if distinct.size < 2 or distinct.min() <= 0:
        return False
    return bool(distinct[0] - (distinct[1] - distinct[0]) / 2 < 0)


def _categories(values: npt.NDArray[np.float64], bins: int) -> npt.NDArray[np.float64] | None:
    """The distinct values of a grid axis (at most ``bins`` of them, each repeated: a
    factorial grid lists every value once per value of the other axis), else ``None``."""
    v = values[np.isfinite(values)]
    distinct = np.unique(v)
    if 0 < distinct.size <= bins and (distinct.size < v.size or distinct.size == 1):
        return distinct
    return None


def _cell_axis(
    values: npt.NDArray[np.float64],
    bins: int,
    log: bool,
    categories: npt.NDArray[np.float64] | None,
) -> tuple[npt.NDArray[np.float64], Any, npt.NDArray[np.float64]]:
    """Cell edges, each value's cell and each value's plot coordinate: category index
    ``i`` spans [i - 0.5, i + 0.5]; otherwise the values themselves (see :func:`_axis`)."""
    if categories is not None:
        index = np.searchsorted(categories, values)
        edges = np.asarray(np.arange(categories.size + 1) - 0.5, dtype=np.float64)
        return edges, index, np.asarray(index, dtype=np.float64)
    edges, index = _axis(values, bins, log)
    return edges, index, values


def _tick_texts(values: npt.NDArray[np.float64]) -> list[str]:
    """Labels for category ticks, one style for the axis: plain (0.1, 800, 30000) or, when
    any value needs it, powers of ten ($3\\times10^{4}$)."""
    finite = np.abs(values[np.isfinite(values) & (values != 0)])
    if finite.size == 0 or (finite.min() >= 1e-3 and finite.max() < 1e5):
        return [f"{v:g}" for v in values]
    out = []
    for v in values:
        if v == 0 or not np.isfinite(v):
            out.append(f"{v:g}")
            continue
        mantissa, exponent = f"{v:.3e}".split("e")
        m = mantissa.rstrip("0").rstrip(".")
        power = f"10^{{{int(exponent)}}}"
        out.append(f"${power}$" if m == "1" else f"${m}\\times{power}$")
    return out


def _declutter(fig: Figure, ax: Axes) -> None:
    """Tick labels that do not overlap (nor touch: "3×10⁴4×10⁴" reads as one number).

    Measured on a drawn canvas. When the labels on an axis collide, its ticks are frozen
    (major and minor labels together, in order) and every 2nd, 3rd, ... label is kept
    until none collides."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)

    def colliding(axis: Any) -> bool:
        canvas.draw()
        renderer = canvas.get_renderer()
        # Padded by 1 px: labels less than 2 px apart collide.
        boxes = [label.get_window_extent(renderer).padded(1.0) for _, label in _shown(axis)]
        return any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1 :])

    for axis in (ax.xaxis, ax.yaxis):
        if not colliding(axis):
            continue
        ticks = sorted((float(loc), label.get_text()) for loc, label in _shown(axis))
        axis.set_minor_locator(NullLocator())
        for step in range(2, len(ticks) + 1):
            kept = ticks[::step]
            axis.set_ticks([loc for loc, _ in kept], labels=[text for _, text in kept])
            if not colliding(axis):
                break


def _shown(axis: Any) -> list[tuple[float, Any]]:
    """(location, label) of the tick labels that are drawn: visible, non-empty and inside
    the axis limits."""
    lo, hi = sorted(axis.get_view_interval())
    ticks = list(zip(axis.get_majorticklocs(), axis.get_ticklabels(), strict=False))
    ticks += list(zip(axis.get_minorticklocs(), axis.get_ticklabels(minor=True), strict=False))
    span = hi - lo
    return [(loc, label) for loc, label in ticks
            if label.get_visible() and label.get_text()
            and lo - 1e-9 * span <= loc <= hi + 1e-9 * span]  # fmt: skip
