"""Building blocks of a scenario: frozen, keyword-only dataclasses, one module per kind.

Every block validates itself through the Rust core when it is constructed, so a bad value
fails where it is written, with a :class:`~admit_rs.errors.ParameterError` (a ``ValueError``)
that names the field, the value and the allowed range. Each block's fields are written from
its Rust declaration (``admit_rs._codegen``); its kind tag and the family it belongs to come
from the core's registry (``admit_rs._registry``). Defaults are the paper preset (SPEC
§1-§6); ``Scenario()`` is the fig. 14 run (TDC, Scheme 2, b = 800, k_a = 1).
"""

from __future__ import annotations

from admit_rs.blocks._base import (
    _CLASSES,
    ArrayLike3,
    Vector3,
    _attribute_docs,
    _Block,
    _document_fields,
    _guard_init,
)
from admit_rs.blocks.actuator import Actuator
from admit_rs.blocks.approach import GuardedApproach
from admit_rs.blocks.controller import (
    ComputedTorque,
    Controller,
    ModelError,
    ModelFree,
    TimeDelayControl,
)
from admit_rs.blocks.criteria import Criteria
from admit_rs.blocks.force_control import AdmittanceFilter, ForceControl, ImpedanceReference
from admit_rs.blocks.paths import parameter_paths
from admit_rs.blocks.robot import Robot, UrdfArm
from admit_rs.blocks.scenario import Scenario, describe
from admit_rs.blocks.sensor import ForceSensor
from admit_rs.blocks.signal import Sampled, Signal, Sine, Step
from admit_rs.blocks.surface import Cylinder, HeightField, Sphere, Surface, Wall

__all__ = [
    "Actuator",
    "AdmittanceFilter",
    "ArrayLike3",
    "ComputedTorque",
    "Controller",
    "Criteria",
    "Cylinder",
    "ForceControl",
    "ForceSensor",
    "GuardedApproach",
    "HeightField",
    "ImpedanceReference",
    "ModelError",
    "ModelFree",
    "Robot",
    "Sampled",
    "Scenario",
    "Signal",
    "Sine",
    "Sphere",
    "Step",
    "Surface",
    "TimeDelayControl",
    "UrdfArm",
    "Vector3",
    "Wall",
    "describe",
    "parameter_paths",
]

_BLOCKS: tuple[type[_Block], ...] = tuple(_CLASSES.values())
"""Every public block type: the class of each kind of the core's registry, found as each is
defined rather than listed, so a new block cannot miss its unknown-keyword guard and field
docs (tests/test_errors.py checks every block ``admit_rs`` exports against this)."""

_DOCS = _attribute_docs()
for _cls in _BLOCKS:
    _guard_init(_cls)
    _document_fields(_cls, _DOCS)
