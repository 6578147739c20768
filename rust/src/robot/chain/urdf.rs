//! URDF → [`ChainModel`]: the serial chain from `base_link` (default: the root) to `tip_link`.
//!
//! Revolute, continuous and prismatic joints on the path become the chain's joints. Every
//! other link is rigidly attached to the nearest body above it, its inertia merged into
//! that body's: links behind fixed joints (as Pinocchio does), and links behind moving
//! joints off the path, which are held at q = 0. Links above the base belong to the world.
//! Errors name the element: an unsupported joint type, a missing link, a tip not below the
//! base, a closed chain, an inertia that is not positive definite.

use std::collections::HashMap;
use std::sync::Mutex;

use nalgebra::{Matrix3, Rotation3, Vector3};
use urdf_rs::JointType;

use super::model::{ChainModel, JointKind, JointSpec};
use super::spatial::{Pose, RigidInertia};
use crate::error::{Error, Result};

/// The most joints a chain may have (the simulation is compiled for 1 to 8).
pub const MAX_JOINTS: usize = 8;

/// URDF `<origin xyz rpy>`: R = Rz(yaw) Ry(pitch) Rx(roll).
fn pose_of(p: &urdf_rs::Pose) -> Pose<f64> {
    let [r, pi, y] = p.rpy.0;
    Pose {
        rot: *Rotation3::from_euler_angles(r, pi, y).matrix(),
        pos: Vector3::from(p.xyz.0),
    }
}

fn link_field(link: &str) -> String {
    format!("urdf link '{link}'")
}

fn joint_field(joint: &str) -> String {
    format!("urdf joint '{joint}'")
}

/// The link's inertia about its own frame; checks mass ≥ 0 and a positive definite tensor
/// (positive semi-definite, e.g. all zero, for a massless link).
fn link_inertia(link: &urdf_rs::Link) -> Result<RigidInertia<f64>> {
    let i = &link.inertial;
    let m = i.mass.value;
    let t = &i.inertia;
    let tensor = Matrix3::new(
        t.ixx, t.ixy, t.ixz, //
        t.ixy, t.iyy, t.iyz, //
        t.ixz, t.iyz, t.izz,
    );
    let values = format!(
        "mass {m}, inertia [ixx {}, ixy {}, ixz {}, iyy {}, iyz {}, izz {}]",
        t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz
    );
    let field = format!("{} inertial", link_field(&link.name));
    if !(m.is_finite() && m >= 0.0) || tensor.iter().any(|v| !v.is_finite()) {
        return Err(Error::parameter(&field, values, "finite, with mass >= 0"));
    }
    // Physically valid: positive semi-definite principal moments that satisfy the triangle
    // inequality (a thin rod, axial moment 0, is allowed: SPEC §1's links are rods).
    let mut moments: Vec<f64> = tensor.symmetric_eigenvalues().iter().copied().collect();
    moments.sort_by(f64::total_cmp);
    let tol = 1e-12 * tensor.norm().max(f64::MIN_POSITIVE);
    let valid = moments[0] >= -tol && moments[0] + moments[1] >= moments[2] - tol;
    if !valid {
        return Err(Error::parameter(
            &field,
            values,
            "a positive (semi-)definite inertia tensor whose principal moments satisfy the triangle inequality",
        ));
    }
    let frame = pose_of(&i.origin);
    let i_com = frame.rot * tensor * frame.rot.transpose();
    Ok(RigidInertia::from_com(m, frame.pos, i_com))
}

/// A document with its base and tip links: what a parsed chain is remembered by.
type ParseKey = (String, Option<String>, String);

/// The chains parsed most recently. A sweep builds each run's arm from the same document
/// (twice: once to check every config before anything runs); reading a Panda's 5-KB URDF
/// costs about a millisecond, as much as 40 ms of its simulation in lanes (measured), so a
/// 16-run Panda sweep spent a fifth of its lane time parsing.
static PARSED: Mutex<Vec<(ParseKey, ChainModel)>> = Mutex::new(Vec::new());

/// How many parsed chains [`parse`] remembers (the oldest is forgotten first).
const REMEMBERED: usize = 8;

/// Parses `text` and extracts the chain from `base_link` to `tip_link`. The result is
/// remembered for the same arguments (parsing is a pure function of them); errors are not.
pub fn parse(text: &str, base_link: Option<&str>, tip_link: &str) -> Result<ChainModel> {
    let same = |(k, _): &&(ParseKey, ChainModel)| {
        k.0 == text && k.1.as_deref() == base_link && k.2 == tip_link
    };
    // A poisoned lock only means another thread panicked mid-update: the list is still a
    // list of finished parses, so it is used as it stands.
    let remembered = || PARSED.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, model)) = remembered().iter().find(same) {
        return Ok(model.clone());
    }
    let model = parse_document(text, base_link, tip_link)?;
    let mut list = remembered();
    if !list.iter().any(|e| same(&e)) {
        if list.len() == REMEMBERED {
            list.remove(0);
        }
        let key = (
            text.to_owned(),
            base_link.map(str::to_owned),
            tip_link.to_owned(),
        );
        list.push((key, model.clone()));
    }
    Ok(model)
}

/// [`parse`] without the memory.
fn parse_document(text: &str, base_link: Option<&str>, tip_link: &str) -> Result<ChainModel> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| {
        let first = e.to_string().lines().next().unwrap_or("").to_owned();
        Error::parameter(
            "urdf",
            format!("text of {} bytes", text.len()),
            &format!("a valid URDF document ({first})"),
        )
    })?;
    extract(&robot, base_link, tip_link)
}

fn extract(robot: &urdf_rs::Robot, base_link: Option<&str>, tip_link: &str) -> Result<ChainModel> {
    let links: HashMap<&str, &urdf_rs::Link> =
        robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
    let mut parent_joint: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    let mut children: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
    for j in &robot.joints {
        for (role, l) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains_key(l.as_str()) {
                return Err(Error::parameter(
                    &joint_field(&j.name),
                    format!("{role} link '{l}'"),
                    "a link defined in the URDF",
                ));
            }
        }
        if let Some(other) = parent_joint.insert(j.child.link.as_str(), j) {
            return Err(Error::parameter(
                &link_field(&j.child.link),
                format!("the child of joints '{}' and '{}'", other.name, j.name),
                "the child of one joint only (closed chains are not supported)",
            ));
        }
        children.entry(j.parent.link.as_str()).or_default().push(j);
    }
    let names = || {
        let mut v: Vec<&str> = robot.links.iter().map(|l| l.name.as_str()).collect();
        v.truncate(12);
        v.join(", ")
    };
    if !links.contains_key(tip_link) {
        return Err(Error::parameter(
            "tip_link",
            format!("'{tip_link}'"),
            &format!("a link of the URDF ({})", names()),
        ));
    }
    let roots: Vec<&str> = robot
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|l| !parent_joint.contains_key(l))
        .collect();
    let base = match base_link {
        Some(b) if !links.contains_key(b) => {
            return Err(Error::parameter(
                "base_link",
                format!("'{b}'"),
                &format!("a link of the URDF ({})", names()),
            ))
        }
        Some(b) => b,
        None => match roots.as_slice() {
            [root] => root,
            [] => {
                return Err(Error::parameter(
                    "urdf",
                    "a link graph without a root",
                    "a tree (closed chains are not supported)",
                ))
            }
            many => {
                return Err(Error::parameter(
                    "base_link",
                    "None",
                    &format!(
                        "one of the URDF's root links ({}) when it has several",
                        many.join(", ")
                    ),
                ))
            }
        },
    };
    // Walk up from the tip to the base: the path of joints, tip first.
    let mut path: Vec<&urdf_rs::Joint> = Vec::new();
    let mut at = tip_link;
    while at != base {
        match parent_joint.get(at) {
            Some(j) => {
                if path.len() > robot.joints.len() {
                    return Err(Error::parameter(
                        &link_field(at),
                        "on a cycle of joints",
                        "part of a tree (closed chains are not supported)",
                    ));
                }
                path.push(j);
                at = j.parent.link.as_str();
            }
            None => {
                return Err(Error::parameter(
                    "tip_link",
                    format!("'{tip_link}'"),
                    &format!("a link below base_link '{base}'"),
                ))
            }
        }
    }
    path.reverse();
    for j in &path {
        match j.joint_type {
            JointType::Revolute
            | JointType::Continuous
            | JointType::Prismatic
            | JointType::Fixed => {}
            ref other => {
                return Err(Error::parameter(
                    &joint_field(&j.name),
                    format!("type {}", format!("{other:?}").to_lowercase()),
                    "a revolute, continuous, prismatic or fixed joint",
                ))
            }
        }
    }
    let on_path: HashMap<&str, usize> = path
        .iter()
        .filter(|j| j.joint_type != JointType::Fixed)
        .enumerate()
        .map(|(k, j)| (j.name.as_str(), k))
        .collect();
    let n = on_path.len();
    if n == 0 || n > MAX_JOINTS {
        return Err(Error::parameter(
            "tip_link",
            format!("'{tip_link}' ({n} moving joints from '{base}')"),
            &format!("a chain of 1 to {MAX_JOINTS} revolute, continuous or prismatic joints"),
        ));
    }
    // Every link below the base: its body (0 = the world, k + 1 = joint k) and its frame in
    // that body's frame. Depth first from the base.
    let mut joints: Vec<Option<JointSpec>> = vec![None; n];
    let mut inertias = vec![RigidInertia::<f64>::zero(); n + 1];
    let mut tip = None;
    let mut stack: Vec<(&str, usize, Pose<f64>)> = vec![(base, 0, Pose::identity())];
    let mut visited = 0usize;
    while let Some((link, body, frame)) = stack.pop() {
        visited += 1;
        if visited > robot.links.len() {
            return Err(Error::parameter(
                &link_field(link),
                "reached twice",
                "part of a tree (closed chains are not supported)",
            ));
        }
        let inertia = link_inertia(links[link])?;
        if body > 0 {
            inertias[body] = inertias[body].add(&inertia.to_parent(&frame));
        }
        if link == tip_link {
            tip = Some((body, frame));
        }
        for j in children.get(link).into_iter().flatten() {
            let origin = frame.compose(&pose_of(&j.origin));
            match on_path.get(j.name.as_str()) {
                Some(&k) => {
                    let axis = Vector3::from(j.axis.xyz.0);
                    let norm = axis.norm();
                    if !(norm.is_finite() && norm > 1e-12) {
                        return Err(Error::parameter(
                            &format!("{} axis", joint_field(&j.name)),
                            format!("{:?}", j.axis.xyz.0),
                            "a non-zero finite vector",
                        ));
                    }
                    let (kind, lower, upper) = match j.joint_type {
                        JointType::Prismatic => {
                            (JointKind::Prismatic, j.limit.lower, j.limit.upper)
                        }
                        JointType::Continuous => {
                            (JointKind::Revolute, f64::NEG_INFINITY, f64::INFINITY)
                        }
                        _ => (JointKind::Revolute, j.limit.lower, j.limit.upper),
                    };
                    let (lower, upper) = if lower < upper {
                        (lower, upper)
                    } else {
                        (f64::NEG_INFINITY, f64::INFINITY)
                    };
                    let effort = if j.limit.effort > 0.0 {
                        j.limit.effort
                    } else {
                        f64::INFINITY
                    };
                    joints[k] = Some(JointSpec {
                        name: j.name.clone(),
                        kind,
                        axis: axis / norm,
                        tree: origin,
                        inertia: RigidInertia::zero(),
                        lower,
                        upper,
                        effort,
                    });
                    stack.push((j.child.link.as_str(), k + 1, Pose::identity()));
                }
                // Fixed, or moving off the path (held at q = 0): part of this body.
                None => stack.push((j.child.link.as_str(), body, origin)),
            }
        }
    }
    let (tip_body, tip_frame) = tip.expect("the tip is below the base");
    debug_assert_eq!(tip_body, n);
    let joints = joints
        .into_iter()
        .zip(inertias.into_iter().skip(1))
        .map(|(j, inertia)| {
            let mut j = j.expect("every path joint is below the base");
            j.inertia = inertia;
            j
        })
        .collect();
    Ok(ChainModel {
        base_link: base.to_owned(),
        tip_link: tip_link.to_owned(),
        joints,
        tip: tip_frame,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PANDA: &str = include_str!("../../../../examples/data/panda.urdf");
    const UR5: &str = include_str!("../../../../examples/data/ur5.urdf");

    /// A remembered chain is the chain a fresh parse gives, for each (document, base, tip);
    /// an error is reported afresh each time, and the memory stays bounded.
    #[test]
    fn remembered_chains_equal_fresh_parses() {
        for (text, tip) in [
            (PANDA, "panda_hand_tcp"),
            (PANDA, "panda_link4"),
            (UR5, "tool0"),
        ] {
            let fresh = parse_document(text, None, tip).expect("a valid chain");
            assert_eq!(parse(text, None, tip).expect("valid"), fresh);
            assert_eq!(parse(text, None, tip).expect("valid"), fresh);
        }
        let short = parse(PANDA, None, "panda_link4").expect("valid").dof();
        assert_eq!(short, 4);
        for _ in 0..2 {
            let e = parse(PANDA, None, "no_such_link").expect_err("no such link");
            assert!(e.to_string().contains("no_such_link"), "{e}");
        }
        for k in 0..2 * REMEMBERED {
            let text = format!("{PANDA}<!-- {k} -->");
            assert_eq!(parse(&text, None, "panda_link2").expect("valid").dof(), 2);
        }
        let held = PARSED.lock().unwrap_or_else(|e| e.into_inner()).len();
        assert!(held <= REMEMBERED, "{held}");
    }
}
