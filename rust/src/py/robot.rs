//! Arm terms for Python: the three-link arm's closed form and a URDF chain's D, C, G, J
//! and forward dynamics at a given state.

use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::errors::{to_py_err, ParameterTypeError};
use super::params::{robot_params, urdf_params};
use crate::robot::chain::arm::{chain_info, chain_terms};
use crate::robot::chain::TaskKind;
use crate::robot::three_link::{Mat3, Vec3};
use crate::robot::{ArmModel, RobotModel, ThreeLinkArm};

fn matrix<'py>(py: Python<'py>, m: &Mat3) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..3)
        .map(|i| (0..3).map(|j| m[(i, j)]).collect())
        .collect();
    PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn vector<'py>(py: Python<'py>, v: &Vec3) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

fn checked_robot(robot: &Bound<'_, PyAny>) -> PyResult<ThreeLinkArm> {
    let params = robot_params(robot)?;
    params
        .validate()
        .map_err(|e| to_py_err(robot.py(), e.within("robot")))?;
    Ok(ThreeLinkArm::new(&params))
}

fn state3(v: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec3> {
    let a: [f64; 3] = v.extract().map_err(|_| {
        ParameterTypeError::new_err(format!("{name} must be a sequence of 3 numbers"))
    })?;
    Ok(Vec3::from(a))
}

/// D, C, G, J, J̇q̇, tip position and friction of the arm at (q, q̇).
#[pyfunction]
pub(super) fn robot_terms<'py>(
    robot: &Bound<'py, PyAny>,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let py = robot.py();
    let arm = checked_robot(robot)?;
    let (q, qd) = (state3(q, "q")?, state3(qd, "qd")?);
    let (k, d) = arm.evaluate(&q, &qd);
    let out = PyDict::new(py);
    out.set_item("position", vector(py, &k.position))?;
    out.set_item("jacobian", matrix(py, &k.jacobian)?)?;
    out.set_item("jdot_qd", vector(py, &k.jdot_qd))?;
    out.set_item("inertia", matrix(py, &d.inertia)?)?;
    out.set_item("coriolis", vector(py, &d.coriolis))?;
    out.set_item("gravity", vector(py, &d.gravity))?;
    out.set_item("friction", vector(py, &arm.model().friction(&qd)))?;
    Ok(out)
}

/// q̈ of eq. (1) for joint torques `tau` and a Cartesian force `tip_force` on the tip.
#[pyfunction]
pub(super) fn forward_dynamics<'py>(
    robot: &Bound<'py, PyAny>,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
    tip_force: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let arm = checked_robot(robot)?;
    let qdd = arm.forward_dynamics_at(
        &state3(q, "q")?,
        &state3(qd, "qd")?,
        &state3(tau, "tau")?,
        &state3(tip_force, "tip_force")?,
    );
    Ok(vector(robot.py(), &qdd))
}

fn rows<'py>(py: Python<'py>, flat: &[f64], cols: usize) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = flat.chunks(cols).map(<[f64]>::to_vec).collect();
    PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A URDF arm's D, C q̇, G, J (6×n), J̇q̇ (6), tip position and rotation, friction at (q, q̇);
/// with `tau` also q̈ (ABA) for that torque and the world force `tip_force` on the tip.
#[pyfunction]
#[pyo3(signature = (robot, q, qd, tau=None, tip_force=[0.0; 3]))]
pub(super) fn urdf_terms<'py>(
    robot: &Bound<'py, PyAny>,
    q: Vec<f64>,
    qd: Vec<f64>,
    tau: Option<Vec<f64>>,
    tip_force: [f64; 3],
) -> PyResult<Bound<'py, PyDict>> {
    let py = robot.py();
    let p = urdf_params(robot)?;
    let forward = tau.as_deref().map(|t| (t, tip_force));
    let t = py
        .detach(|| chain_terms(&p, &q, &qd, forward))
        .map_err(|e| to_py_err(py, e.within("robot")))?;
    let n = t.joints;
    let out = PyDict::new(py);
    out.set_item("inertia", rows(py, &t.inertia, n)?)?;
    out.set_item("coriolis", PyArray1::from_vec(py, t.coriolis))?;
    out.set_item("gravity", PyArray1::from_vec(py, t.gravity))?;
    out.set_item("jacobian", rows(py, &t.jacobian, n)?)?;
    out.set_item("jdot_qd", PyArray1::from_vec(py, t.jdot_qd))?;
    out.set_item("position", PyArray1::from_vec(py, t.position))?;
    out.set_item("rotation", rows(py, &t.rotation, 3)?)?;
    out.set_item("friction", PyArray1::from_vec(py, t.friction))?;
    if let Some(a) = t.acceleration {
        out.set_item("acceleration", PyArray1::from_vec(py, a))?;
    }
    Ok(out)
}

/// A URDF arm's joint names, position and effort limits, default q0 and task.
#[pyfunction]
pub(super) fn urdf_info<'py>(robot: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let py = robot.py();
    let p = urdf_params(robot)?;
    let i = chain_info(&p).map_err(|e| to_py_err(py, e.within("robot")))?;
    Ok(py_dict!(py, {
        "joint_names": i.joint_names,
        "lower": i.lower,
        "upper": i.upper,
        "effort": i.effort,
        "q0": i.q0,
        "task": match i.task { TaskKind::Position => "position", TaskKind::Pose => "pose" },
    }))
}
