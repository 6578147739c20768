"""What a fit has found so far: values, intervals, how, the unidentified, keyed by path."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import stats


@dataclass
class Findings:
    """The fit's results as they accumulate (``CellFit``'s fields), and the confidence."""

    confidence: float
    values: dict[str, Any] = field(default_factory=dict)
    intervals: dict[str, Any] = field(default_factory=dict)
    unidentified: dict[str, str] = field(default_factory=dict)
    how: dict[str, str] = field(default_factory=dict)
    residual_std: dict[str, float] = field(default_factory=dict)
    touching: npt.NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """Where the tool touches: the fitted law's force is positive (else the segmentation's
    contact)."""
    contact_level: float | None = None
    """The median normal force read while touching [N] (None without contact)."""

    def t_quantile(self, dof: float) -> float:
        """Student's t two-sided quantile at the confidence, ``dof`` degrees of freedom."""
        return float(stats.t.ppf(0.5 + self.confidence / 2, max(dof, 1.0)))

    def put(self, path: str, value: Any, interval: Any, how: str) -> None:
        self.values[path] = value
        if interval is not None:
            self.intervals[path] = interval
        self.how[path] = how
