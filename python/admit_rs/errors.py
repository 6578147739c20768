"""Exceptions raised by admit_rs.

``ParameterError`` subclasses ``ValueError``: every invalid parameter raises it with the
field's dotted path, its value and the allowed range (also as attributes ``field``,
``value`` and ``allowed``). Unknown keywords and wrong types raise ``TypeError``.
"""

from admit_rs._core import AdmitError, ParameterError

__all__ = ["AdmitError", "ParameterError"]


def within(err: ParameterError, prefix: str) -> ParameterError:
    """The same error with ``prefix.`` in front of its field (its place in a scenario)."""
    field = f"{prefix}.{err.field}"
    new = ParameterError(f"{field} = {err.value} is invalid: must be {err.allowed}")
    new.field, new.value, new.allowed = field, err.value, err.allowed
    return new
