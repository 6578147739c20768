"""admit_rs: admittance force tracking control of robot manipulators.

Simulate and analyse the admittance (position-based) force control schemes of Jung &
Jeong with a Rust core: computed torque, model-free and time-delayed inner loops,
Scheme 1 / Scheme 2 admittance filters, an uncertain wall.

Example:
    >>> import admit_rs as ar
    >>> r = ar.simulate(ar.paper.scenario("fig14"))
    >>> r.stable, r.trace.height, abs(r.metrics["force_ss_error"]) < 0.5
    (True, 10001, True)
"""

from admit_rs import analysis, export, metrics, paper, plot, ui
from admit_rs._core import METRIC_NAMES, TRACE_COLUMNS, __version__
from admit_rs._names import UnknownNameError
from admit_rs.config import (
    Actuator,
    AdmittanceFilter,
    ComputedTorque,
    Criteria,
    Cylinder,
    ForceSensor,
    GuardedApproach,
    HeightField,
    ImpedanceReference,
    ModelError,
    ModelFree,
    Robot,
    Sampled,
    Scenario,
    Sine,
    Sphere,
    Step,
    Surface,
    TimeDelayControl,
    UrdfArm,
    Wall,
    describe,
    parameter_paths,
)
from admit_rs.errors import (
    AdmitError,
    AnalysisError,
    ArgumentError,
    ExportError,
    ParameterError,
    ParameterTypeError,
    UnknownParameterError,
)
from admit_rs.identification import CellFit, identify
from admit_rs.metrics import METRICS, Metric
from admit_rs.recording import LogError, read_log
from admit_rs.simulation import Result, Simulation, SubstepWarning, simulate
from admit_rs.sweep import (
    CheckpointMismatchError,
    CheckpointWarning,
    Choice,
    DistributionError,
    LaneBuildWarning,
    LogUniform,
    Normal,
    SweepInterrupted,
    Uniform,
    sweep,
)

__all__ = [
    "METRICS",
    "METRIC_NAMES",
    "TRACE_COLUMNS",
    "Actuator",
    "AdmitError",
    "AnalysisError",
    "AdmittanceFilter",
    "CheckpointMismatchError",
    "CheckpointWarning",
    "Choice",
    "DistributionError",
    "ExportError",
    "LaneBuildWarning",
    "LogError",
    "CellFit",
    "LogUniform",
    "Metric",
    "Normal",
    "SweepInterrupted",
    "Uniform",
    "ComputedTorque",
    "Criteria",
    "Cylinder",
    "ForceSensor",
    "GuardedApproach",
    "HeightField",
    "ImpedanceReference",
    "ModelError",
    "ModelFree",
    "ParameterError",
    "ParameterTypeError",
    "ArgumentError",
    "Result",
    "Robot",
    "UrdfArm",
    "Sampled",
    "Scenario",
    "Simulation",
    "Sine",
    "Sphere",
    "Step",
    "SubstepWarning",
    "Surface",
    "TimeDelayControl",
    "UnknownNameError",
    "UnknownParameterError",
    "Wall",
    "__version__",
    "analysis",
    "describe",
    "export",
    "metrics",
    "paper",
    "parameter_paths",
    "plot",
    "read_log",
    "identify",
    "simulate",
    "sweep",
    "ui",
]
