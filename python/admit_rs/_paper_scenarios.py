"""The paper's simulation figures 5-20: captions, claims and their scenarios (SPEC §9).

The data behind :mod:`admit_rs.paper`, which re-exports everything here; use it through
``admit_rs.paper``. This module sits below :mod:`admit_rs.reproduction` (which runs and
draws these scenarios), so that ``paper`` can offer both without an import cycle.

Example:
    >>> import admit_rs as ar
    >>> [s.label for s in ar.paper.scenarios("fig15")]
    ['TDC, Scheme 2, k_e=10 000', 'TDC, Scheme 2, k_e=50 000', 'TDC, Scheme 2, k_e=100 000']
"""

from __future__ import annotations

from dataclasses import dataclass

from admit_rs._names import UnknownNameError
from admit_rs.config import (
    AdmittanceFilter,
    ComputedTorque,
    Controller,
    ModelFree,
    Scenario,
    Sine,
    Step,
    TimeDelayControl,
    Wall,
)

STEP_FORCE = Step(value=10.0)
"""f_d = 10 N from t = 0."""
SINE_FORCE = Sine(offset=10.0, amplitude=5.0, omega=1.0)
"""f_d = 10 + 5 sin(t) N."""


@dataclass(frozen=True)
class Figure:
    """One figure of the paper: its caption and what the paper says about it."""

    number: int
    caption: str
    claim: str


FIGURES: dict[str, Figure] = {
    f"fig{f.number}": f
    for f in [
        Figure(5, "Position control of model-based control", "perfect position tracking"),
        Figure(6, "Position control of nonmodel-based control", "poor tracking without models"),
        Figure(7, "Position control of TDC", "TDC restores position tracking"),
        Figure(
            8,
            "Force control under model-based control, k_a = 0.1",
            "Scheme 1 keeps a force offset (eq. 26), Scheme 2 none (eq. 35); z RMS 0.0370",
        ),
        Figure(
            9,
            "Model-based control (Scheme 2): damping b for a step command",
            "larger b: less overshoot, slower response",
        ),
        Figure(
            10,
            "Force control under model-based control, k_a = 1 and 2",
            "k_a = 1 faster contact, z RMS 0.0016; k_a = 2 gives 0.45 % overshoot",
        ),
        Figure(
            11,
            "Model-based control (Scheme 2): damping b for a sinusoidal command",
            "larger b: less overshoot, more lag; z RMS the same (0.0370) for all b",
        ),
        Figure(12, "Nonmodel-based control (Scheme 2), step", "poor tracking; z RMS 3.2052"),
        Figure(13, "Nonmodel-based control (Scheme 2), sine", "poor tracking; z RMS 3.2052"),
        Figure(
            14,
            "Nonmodel-based control with TDC (Scheme 2), step",
            "tracking restored, small periodic force errors; z RMS 0.0044",
        ),
        Figure(
            15,
            "TDC for different environment stiffness, step",
            "good tracking for k_e = 10 000 ... 100 000",
        ),
        Figure(16, "Nonmodel-based control with TDC (Scheme 2), sine", "z RMS 0.0044"),
        Figure(
            17,
            "TDC for different environment stiffness, sine",
            "force overshoot grows with k_e",
        ),
        Figure(
            18,
            "Scheme 2 without TDC, wall-position error 0.01 m",
            "first-contact overshoot over 60 N",
        ),
        Figure(19, "Scheme 2 with TDC, wall-position error 0.01 m", "overshoot reduced to ~40 N"),
        Figure(
            20,
            "TDC for different stiffness with wall-position error, sine",
            "overshoot grows with k_e (30 N to 55 N), good tracking after contact",
        ),
    ]
}


def _ct() -> ComputedTorque:
    return ComputedTorque(command_divisor=0.1)


def _run(
    label: str,
    controller: Controller,
    *,
    b: float = 800.0,
    ka: float = 1.0,
    k: float = 0.0,
    sine: bool = False,
    stiffness: float = 30_000.0,
    position_error: float = 0.0,
) -> Scenario:
    return Scenario(
        controller=controller,
        wall=Wall(stiffness=stiffness, position_error=position_error),
        admittance=AdmittanceFilter(m=1.0, b=b, k=k, ka=ka),
        force_reference=SINE_FORCE if sine else STEP_FORCE,
        label=label,
    )


def _position_only(label: str, controller: Controller) -> Scenario:
    return Scenario(controller=controller, wall=None, admittance=None, label=label)


def _stiffness_label(prefix: str, ke: float) -> str:
    thousands = f"{ke:_.0f}".replace("_", " ")
    return f"{prefix}, k_e={thousands}"


def _build(name: str) -> list[Scenario]:
    tdc, mf = TimeDelayControl(), ModelFree()
    match name:
        case "fig5":
            return [_position_only("CT, position only", _ct())]
        case "fig6":
            return [_position_only("MF, position only", mf)]
        case "fig7":
            return [_position_only("TDC, position only", tdc)]
        case "fig8":
            return [
                _run("CT, Scheme 1, k=400, k_a=0.1", _ct(), k=400.0, ka=0.1),
                _run("CT, Scheme 2, k_a=0.1", _ct(), ka=0.1),
            ]
        case "fig9":
            return [
                _run(f"CT, Scheme 2, b={b}, k_a=0.1", _ct(), b=b, ka=0.1) for b in (200, 400, 800)
            ]
        case "fig10":
            return [_run(f"CT, Scheme 2, b=800, k_a={ka}", _ct(), ka=ka) for ka in (1, 2)]
        case "fig11":
            return [
                _run(f"CT, Scheme 2, sine, b={b}, k_a=0.1", _ct(), b=b, ka=0.1, sine=True)
                for b in (200, 400, 800)
            ]
        case "fig12":
            return [_run("MF, Scheme 2, k_a=1", mf)]
        case "fig13":
            return [_run("MF, Scheme 2, sine, k_a=1", mf, sine=True)]
        case "fig14":
            return [_run("TDC, Scheme 2, k_a=1", tdc)]
        case "fig15":
            return [
                _run(_stiffness_label("TDC, Scheme 2", ke), tdc, stiffness=ke)
                for ke in (10_000.0, 50_000.0, 100_000.0)
            ]
        case "fig16":
            return [_run("TDC, Scheme 2, sine, k_a=1", tdc, sine=True)]
        case "fig17":
            return [
                _run(_stiffness_label("TDC, Scheme 2, sine", ke), tdc, stiffness=ke, sine=True)
                for ke in (10_000.0, 50_000.0, 100_000.0)
            ]
        case "fig18":
            return [_run("MF, Scheme 2, wall error 0.01 m", mf, position_error=0.01)]
        case "fig19":
            return [_run("TDC, Scheme 2, wall error 0.01 m", tdc, position_error=0.01)]
        case "fig20":
            return [
                _run(
                    _stiffness_label("TDC, sine, wall error 0.01 m", ke),
                    tdc,
                    stiffness=ke,
                    position_error=0.01,
                    sine=True,
                )
                for ke in (10_000.0, 30_000.0, 50_000.0, 100_000.0)
            ]
    raise UnknownNameError("figure", name, FIGURES)


VARIANT_SUFFIX = "-variant"
VARIANTS: dict[str, str] = {
    "fig9": "K_A⁻¹ on the feedback only",
    "fig10": "K_A⁻¹ on the feedback only",
    "fig14": "K_A⁻¹ on the feedback only",
}
"""Figures with a labelled variant: a different reading of eq. (39) that the paper's text
allows, V = Ẍ_d + K_A⁻¹(K_D ė + K_P e). SPEC §4 (the default) applies K_A⁻¹ literally."""


def variant_scenarios(figure: str | int) -> list[Scenario]:
    """A figure's curves under the variant reading of eq. (39) (see :data:`VARIANTS`)."""
    name = figure_name(figure)
    if name not in VARIANTS:
        raise KeyError(f"no variant for {name!r}; variants exist for {', '.join(VARIANTS)}")
    return [
        sc.replace(
            **{"controller.scale_feedforward": False},
            label=f"{sc.label} [variant: {VARIANTS[name]}]",
        )
        for sc in scenarios(name)
    ]


def figure_name(figure: str | int) -> str:
    """The key of a figure in :data:`FIGURES` ("fig14" for 14 or "fig14").

    Anything else raises :class:`admit_rs.UnknownNameError` (a ``KeyError``) naming the
    value, the paper's figures and the closest ones.

    Example:
        >>> from admit_rs.paper import figure_name
        >>> figure_name(14), figure_name("fig9")
        ('fig14', 'fig9')
        >>> figure_name("fig99")
        Traceback (most recent call last):
        ...
        admit_rs._names.UnknownNameError: unknown figure 'fig99'; did you mean 'fig9' or ...
    """
    name = f"fig{figure}" if isinstance(figure, int) else str(figure)
    if name not in FIGURES:
        raise UnknownNameError("figure", name, FIGURES)
    return name


def scenarios(figure: str | int) -> list[Scenario]:
    """Every curve of a figure ("fig5" ... "fig20", or the number), each labelled.

    An unknown figure raises :class:`admit_rs.UnknownNameError` (see :func:`figure_name`).
    """
    return _build(figure_name(figure))


def scenario(figure: str | int) -> Scenario:
    """The first curve of a figure."""
    return scenarios(figure)[0]
