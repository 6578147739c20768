"""Building blocks of a scenario (the public name of :mod:`admit_rs.blocks`).

Every block validates itself through the Rust core when it is constructed, so a bad value
fails where it is written, with a :class:`~admit_rs.errors.ParameterError` (a ``ValueError``)
that names the field, the value and the allowed range. Defaults are the paper preset
(SPEC §1-§6); ``Scenario()`` is the fig. 14 run (TDC, Scheme 2, b = 800, k_a = 1). The
blocks live one kind per module in :mod:`admit_rs.blocks`; this module keeps the names the
package and its users import.
"""

from __future__ import annotations

from admit_rs import blocks as _blocks
from admit_rs.blocks import *  # noqa: F403 (the blocks' public names, by their __all__)
from admit_rs.blocks import _BLOCKS, _DOCS
from admit_rs.blocks._base import (
    _CLASSES,
    _Block,
    _core_dict_with,
    _core_value,
    _python_error,
)
from admit_rs.blocks.paths import _check_path
from admit_rs.blocks.scenario import _UNIONS, _short
from admit_rs.blocks.tables import _slot_types

__all__ = [  # noqa: F405
    *_blocks.__all__,
    "_BLOCKS",
    "_CLASSES",
    "_DOCS",
    "_UNIONS",
    "_Block",
    "_check_path",
    "_core_dict_with",
    "_core_value",
    "_python_error",
    "_short",
    "_slot_types",
]
