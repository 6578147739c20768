"""Exceptions of admit_rs, under one root, :class:`AdmitError`.

Every exception class admit_rs defines (warning categories aside) derives from
:class:`AdmitError` but ``SweepInterrupted``, and also from the built-in exception a caller
would expect.

- :class:`ParameterError` (also a ``ValueError``): a value outside its range, with the
  field's dotted path, its value and the allowed range (also as attributes ``field``,
  ``value`` and ``allowed``).
- :class:`UnknownParameterError` (also a ``TypeError``): a keyword, dotted path or TOML
  key that names no field, with the closest valid names (attribute ``suggestions``).
- :class:`ParameterTypeError` (also a ``TypeError``): a value of the wrong type (a str
  where a number goes, a bool where a count goes, a block where another kind belongs),
  naming the field or argument.
- :class:`ArgumentError` (also a ``ValueError``): arguments of a call that do not fit
  together or are empty (a path in both ``vary`` and ``grid``, an empty grid axis).
- :class:`admit_rs.UnknownNameError` (also a ``KeyError``; in :mod:`admit_rs._names`): an
  unknown metric, table column, state entry or paper figure, with the closest valid names.
- :class:`AnalysisError` (also a ``ValueError``): a scenario :mod:`admit_rs.analysis`
  cannot linearise (no contact equilibrium, a singular one, no wall or force loop).
- :class:`ExportError` (also a ``ValueError``): a scenario an export target cannot
  express faithfully (:mod:`admit_rs.export`).
- ``DistributionError``, ``CheckpointMismatchError`` (also ``ValueError``) and
  ``SweepInterrupted`` (a ``KeyboardInterrupt`` only, not an AdmitError: that is an
  ``Exception``, and ``except Exception`` must not swallow a Ctrl-C) of
  :mod:`admit_rs.sweep`.

Every "did you mean" suggestion comes from :func:`closest`, with one cutoff
(:data:`CLOSE_MATCH_CUTOFF`).

This module imports nothing from the Rust extension: the extension raises the classes
defined here.

Example:
    >>> import admit_rs as ar
    >>> try:
    ...     ar.Wall(stifness=5000)
    ... except ar.AdmitError as e:
    ...     print(type(e).__name__, isinstance(e, TypeError), e)
    UnknownParameterError True Wall: unknown keyword 'stifness'; did you mean stiffness?
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Any

__all__ = [
    "AdmitError",
    "AnalysisError",
    "ArgumentError",
    "ExportError",
    "ParameterError",
    "ParameterTypeError",
    "UnknownParameterError",
]


class AdmitError(Exception):
    """Root of the exceptions admit_rs defines."""


class ParameterError(AdmitError, ValueError):
    """A parameter outside its allowed range; ``field``, ``value`` and ``allowed`` say
    which and why."""

    field: str
    value: str
    allowed: str


class UnknownParameterError(AdmitError, TypeError):
    """A keyword, dotted path or TOML key that names no field. ``name`` is the unknown
    name, ``suggestions`` the closest valid ones (possibly empty)."""

    def __init__(self, message: str, name: str = "", suggestions: Iterable[str] = ()) -> None:
        super().__init__(message)
        self.name = name
        self.suggestions = list(suggestions)


class ParameterTypeError(AdmitError, TypeError):
    """A value of the wrong type for a field or an argument; the message names it and what
    it must be."""


class ArgumentError(AdmitError, ValueError):
    """Arguments of a call that do not fit together, or an empty one; the message says
    which."""


class AnalysisError(AdmitError, ValueError):
    """A scenario the linear analysis cannot handle: no contact equilibrium (the wall out of
    reach, f_d ≤ 0), a singular equilibrium (a pole at 1, e.g. ``admittance.ka = 0``), or a
    scenario without a wall or force loop. The message says which."""


class ExportError(AdmitError, ValueError):
    """A scenario that an export target cannot express faithfully; the message says why
    and names the nearest faithful alternative."""


CLOSE_MATCH_CUTOFF = 0.6
"""The least :class:`difflib.SequenceMatcher` ratio at which a valid name is suggested for
an unknown one (difflib's own default). Every did-you-mean message of admit_rs goes through
:func:`closest`, so they all suggest the same names for the same typo."""


def closest(name: str, valid: Iterable[str], n: int = 3) -> list[str]:
    """The up to ``n`` valid names closest to ``name``, best first: those whose difflib
    ratio to it is at least :data:`CLOSE_MATCH_CUTOFF`.

    Example:
        >>> from admit_rs.errors import closest
        >>> closest("stifness", ["stiffness", "damping", "model"])
        ['stiffness']
        >>> closest("zzz", ["stiffness", "damping"])
        []
    """
    return difflib.get_close_matches(name, list(valid), n=n, cutoff=CLOSE_MATCH_CUTOFF)


def unknown(message: str, name: str, valid: Iterable[str]) -> UnknownParameterError:
    """``message; did you mean a, b?`` or, without a close match, ``message; valid: ...``
    (the list only when it is short)."""
    valid = list(valid)
    close = closest(name, valid)
    if close:
        hint = f"; did you mean {', '.join(close)}?"
    elif len(valid) <= 16:
        hint = f"; valid: {', '.join(valid)}"
    else:
        hint = ""
    return UnknownParameterError(f"{message}{hint}", name, close)


SHOWN_ITEMS = 8
"""How many elements of a sequence an error message shows (then "… (n in all)")."""


def shown(value: Any) -> str:
    """``value`` in few characters for an error message, exactly where that is short: a
    float as ``repr`` (the shortest text that reads back, ``1e+300`` rather than 301
    digits), an int of more than 16 digits in scientific notation, a sequence by its first
    :data:`SHOWN_ITEMS` elements, a long string cut at 60 characters.

    Example:
        >>> from admit_rs.errors import shown
        >>> shown(-1e300), shown(10**400), shown(list(range(20)))
        ('-1e+300', '≈1.00000e+400', '[0, 1, 2, 3, 4, 5, 6, 7, … (20 in all)]')
    """
    if isinstance(value, bool):
        return repr(value)
    if isinstance(value, int):
        digits = str(abs(value))
        if len(digits) <= 16:
            return str(value)
        sign = "-" if value < 0 else ""
        return f"≈{sign}{digits[0]}.{digits[1:6]}e+{len(digits) - 1}"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return repr(value) if len(value) <= 60 else repr(value[:60]) + f"… ({len(value)} chars)"
    if isinstance(value, list | tuple):
        items = [shown(v) for v in value[:SHOWN_ITEMS]]
        more = f", … ({len(value)} in all)" if len(value) > SHOWN_ITEMS else ""
        if isinstance(value, tuple) and len(value) == 1:
            return f"({items[0]},)"
        open_, close = ("[", "]") if isinstance(value, list) else ("(", ")")
        return f"{open_}{', '.join(items)}{more}{close}"
    text = repr(value)
    return text if len(text) <= 80 else text[:80] + "…"


def _copy(err: ParameterError, message: str, field: str) -> ParameterError:
    new = ParameterError(message)
    new.field, new.value, new.allowed = field, err.value, err.allowed
    return new


def for_run(err: ParameterError, run_id: int) -> ParameterError:
    """The same error, saying which run of a sweep it belongs to (``run_id`` attribute)."""
    field = getattr(err, "field", "")
    new = _copy(err, f"run_id {run_id}: {field} = {err.value} is invalid: must be {err.allowed}",
                field)  # fmt: skip
    new.run_id = run_id  # type: ignore[attr-defined]
    return new


def within(err: ParameterError, prefix: str) -> ParameterError:
    """The same error with ``prefix.`` in front of its field (its place in a scenario)."""
    field = f"{prefix}.{err.field}"
    return _copy(err, f"{field} = {err.value} is invalid: must be {err.allowed}", field)
