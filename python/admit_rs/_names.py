"""Unknown names (metrics, table columns, state entries, paper figures) raise one error that
suggests the closest ones (:func:`admit_rs.errors.closest`).

Example:
    >>> import admit_rs as ar
    >>> r = ar.simulate(ar.paper.scenario("fig14").replace(duration=0.5))
    >>> r.metrics["overshoot"]
    Traceback (most recent call last):
    ...
    admit_rs._names.UnknownNameError: unknown metric 'overshoot'; did you mean 'overshoot_pct' ...
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from admit_rs.errors import AdmitError, closest

__all__ = ["MetricsDict", "UnknownNameError", "check_column"]


class UnknownNameError(AdmitError, KeyError):
    """An unknown metric, column, state entry or figure name; ``name``, ``kind`` and
    ``suggestions`` (from :func:`admit_rs.errors.closest`) say which. The message lists
    the ``valid`` names in the order given.

    A ``KeyError`` (so ``except KeyError`` keeps working) and an ``AdmitError``.
    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        valid = [str(v) for v in valid]
        self.kind, self.name = kind, name
        self.suggestions = closest(name, valid)
        hint = (
            f"did you mean {' or '.join(repr(s) for s in self.suggestions)}? "
            if self.suggestions
            else ""
        )
        super().__init__(f"unknown {kind} {name!r}; {hint}valid: {', '.join(valid)}")

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


class MetricsDict(dict[str, Any]):
    """A run's metrics: a plain ``dict`` whose unknown keys raise :class:`UnknownNameError`."""

    def __missing__(self, key: str) -> Any:
        raise UnknownNameError("metric", str(key), sorted(self.keys()))


def check_column(columns: Iterable[str], name: str, kind: str = "column") -> str:
    """Returns ``name`` if it is one of ``columns``, else raises :class:`UnknownNameError`."""
    columns = list(columns)
    if name not in columns:
        raise UnknownNameError(kind, name, sorted(columns))
    return name
