"""Predict before you simulate (SPEC §12): the closed loop over one controller period,
linearised about its steady contact equilibrium, and what it predicts.

- :func:`linearize` → a python-control ``StateSpace(A, B, C, D, dt=T)`` on the full state
  (plant, filter, controller memory, sensor, actuator), input δf_d, outputs δf, δx (along
  the wall normal n) and δz (along the motion direction t̂).
- :func:`predict` → the steady-state errors, step metrics, poles and a stable verdict; with
  the motion running, the predicted force oscillation, loss of contact and ``passed``.
- :func:`forced_response` → the force the linearised loop predicts with the references and
  the friction reversals they drive (SPEC §23).
- :func:`stability_map` → :func:`predict` over a grid of two parameters, in Rust on all
  cores, as a Polars table (draw it with :func:`admit_rs.plot.stability_map`).
- :func:`tune` → the gains that minimise the worst-case predicted settling time over a box
  of uncertain parameters, checked by simulating the box's corners and centre.

How the linearisation is built and what it assumes: docs/analysis.md.
"""

from admit_rs.analysis._checks import friction_gain
from admit_rs.analysis.forced import ForcedResponse, forced_response
from admit_rs.analysis.linear import (
    NO_EQUILIBRIUM,
    PREDICTION_NAMES,
    Margins,
    linearize,
    predict,
    stability_map,
)
from admit_rs.analysis.tuning import TuneResult, tune
from admit_rs.errors import AnalysisError

__all__ = [
    "NO_EQUILIBRIUM",
    "PREDICTION_NAMES",
    "AnalysisError",
    "ForcedResponse",
    "Margins",
    "TuneResult",
    "forced_response",
    "friction_gain",
    "linearize",
    "predict",
    "stability_map",
    "tune",
]
