"""The cell's force model, written once for the fit and for the check: the contact law's
normal force and the direction of Coulomb friction (SPEC §15, §21)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from admit_rs.blocks.surface import Wall
from admit_rs.identification.least_squares import Array

STICTION_VELOCITY: float = next(
    float(f.default)  # type: ignore[arg-type]  # a generated field: its default is a float
    for f in dataclasses.fields(Wall)
    if f.name == "stiction_velocity"
)
"""v_s [m/s] used for friction when none is given: ``Wall.stiction_velocity``'s default."""


def normal_force(depth: Array, rate: Array, stiffness: float, damping: float,
                 exponent: float = 1.0) -> Array:  # fmt: skip
    """f = max(δ^p (k + c δ̇), 0), δ = max(depth, 0): Kelvin–Voigt at p = 1, Hunt–Crossley
    otherwise; a surface never pulls."""
    delta = np.maximum(depth, 0.0)
    return np.maximum(delta**exponent * (stiffness + damping * rate), 0.0)  # type: ignore[no-any-return]


def friction_direction(velocity: Array, normal: Array, stiction_velocity: float) -> Array:
    """g = v_t / √(|v_t|² + v_s²) per sample: friction is −μ f g on the tool and the sensor
    reads +μ f g (the regularised Coulomb law, SPEC §15). ``normal``: one unit normal, or one
    per sample."""
    vt = velocity - np.sum(velocity * normal, axis=-1, keepdims=True) * normal
    speed = np.linalg.norm(vt, axis=1)
    return vt / np.sqrt(speed**2 + stiction_velocity**2)[:, None]  # type: ignore[no-any-return]


def contact_geometry(values: Mapping[str, Any], x: Array) -> tuple[Array, Array]:
    """The fitted surface at tip positions ``x``: the penetration before clipping (δ, one
    per sample) and the unit normal N into the surface (one per sample). A plane (``values``
    with ``wall.normal``, ``wall.position``): δ = n·X − x_e along n. A sphere touched from
    outside (``wall.centre``, ``wall.radius``): δ = R − |X − c| along the line to c."""
    if "wall.centre" in values:
        towards = np.asarray(values["wall.centre"], dtype=float) - x
        distance = np.linalg.norm(towards, axis=1)
        return values["wall.radius"] - distance, towards / distance[:, None]
    n = np.asarray(values["wall.normal"], dtype=float)
    n = n / np.linalg.norm(n)
    return x @ n - values["wall.position"], np.broadcast_to(n, x.shape)
