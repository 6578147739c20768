"""Exceptions raised by admit_rs.

``ParameterError`` subclasses ``ValueError``: every invalid parameter raises it with the
field's dotted path, its value and the allowed range (also as attributes ``field``,
``value`` and ``allowed``). Unknown keywords and wrong types raise ``TypeError``.
"""

from admit_rs._core import AdmitError, ParameterError

__all__ = ["AdmitError", "ParameterError"]
