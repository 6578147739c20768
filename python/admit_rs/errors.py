"""Exceptions raised by admit_rs.

``ParameterError`` subclasses ``ValueError``: every invalid parameter raises it with the
field's dotted path, its value and the allowed range (also as attributes ``field``,
``value`` and ``allowed``). Unknown keywords and wrong types raise ``TypeError``.
"""

from admit_rs._core import AdmitError, ParameterError

__all__ = ["AdmitError", "ParameterError"]


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
