"""The distributions a sweep draws its varied parameters from (``ar.sweep(vary=...)``):
:class:`Uniform`, :class:`LogUniform`, :class:`Normal` (optionally truncated) and
:class:`Choice`, each drawn from the run's own generator (:mod:`admit_rs.sweep`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from admit_rs.errors import (
    AdmitError,
)

__all__ = ["Choice", "DistributionError", "LogUniform", "Normal", "Uniform"]


class DistributionError(AdmitError, ValueError):
    """A distribution with impossible parameters (low > high, negative sigma, ...)."""


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise DistributionError(f"{name} = {value} is invalid: must be finite")
    return value


@dataclass(frozen=True)
class Uniform:
    """Uniform on [low, high]."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if _finite("low", self.low) > _finite("high", self.high):
            raise DistributionError(f"Uniform: low = {self.low} > high = {self.high}")

    def draw(self, rng: np.random.Generator) -> float:
        return float(rng.uniform(self.low, self.high))


@dataclass(frozen=True)
class LogUniform:
    """log-uniform on [low, high], 0 < low ≤ high (for stiffnesses and gains)."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if _finite("low", self.low) <= 0:
            raise DistributionError(f"LogUniform: low = {self.low} is invalid: must be > 0")
        if self.low > _finite("high", self.high):
            raise DistributionError(f"LogUniform: low = {self.low} > high = {self.high}")

    def draw(self, rng: np.random.Generator) -> float:
        return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))


@dataclass(frozen=True)
class Normal:
    """Normal(mean, std), optionally truncated to [low, high] by rejection."""

    mean: float
    std: float
    low: float | None = None
    high: float | None = None

    MAX_TRIES = 10_000

    def __post_init__(self) -> None:
        _finite("mean", self.mean)
        if _finite("std", self.std) < 0:
            raise DistributionError(f"Normal: std = {self.std} is invalid: must be >= 0")
        lo = -math.inf if self.low is None else float(self.low)
        hi = math.inf if self.high is None else float(self.high)
        if math.isnan(lo) or math.isnan(hi) or lo > hi:
            raise DistributionError(f"Normal: bounds [{self.low}, {self.high}] are empty")
        if self.std == 0 and not lo <= self.mean <= hi:
            raise DistributionError(f"Normal: std = 0 and mean {self.mean} outside the bounds")

    def draw(self, rng: np.random.Generator) -> float:
        lo = -math.inf if self.low is None else self.low
        hi = math.inf if self.high is None else self.high
        for _ in range(self.MAX_TRIES):
            x = float(rng.normal(self.mean, self.std))
            if lo <= x <= hi:
                return x
        raise DistributionError(
            f"Normal({self.mean}, {self.std}) truncated to [{lo}, {hi}]: no draw inside the"
            f" bounds in {self.MAX_TRIES} tries; the bounds are too far in the tail"
        )


@dataclass(frozen=True)
class Choice:
    """One of ``values`` (numbers, strings or building blocks), optionally weighted."""

    values: tuple[Any, ...]
    weights: tuple[float, ...] | None = field(default=None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", tuple(self.values))
        if not self.values:
            raise DistributionError("Choice: values is empty")
        if self.weights is not None:
            w = tuple(float(x) for x in self.weights)
            if len(w) != len(self.values) or any(not math.isfinite(x) or x < 0 for x in w):
                raise DistributionError("Choice: weights must be one finite w >= 0 per value")
            if sum(w) <= 0:
                raise DistributionError("Choice: weights sum to 0")
            object.__setattr__(self, "weights", w)

    def draw(self, rng: np.random.Generator) -> Any:
        p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
        return self.values[int(rng.choice(len(self.values), p=p))]


Distribution = Uniform | LogUniform | Normal | Choice


