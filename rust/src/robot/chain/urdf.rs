//! URDF → [`ChainModel`]: the serial chain from `base_link` (default: the root) to `tip_link`.
//!
//! Revolute, continuous and prismatic joints on the path become the chain's joints. Every
//! other link is rigidly attached to the nearest body above it, its inertia merged into
//! that body's: links behind fixed joints (as Pinocchio does), and links behind moving
//! joints off the path, which are held at q = 0. Links above the base belong to the world.
//! Errors name the element: an unsupported joint type, a missing link, a tip not below the
//! base, a closed chain, an inertia that is not positive definite, two links or joints of
//! one name, an origin that is not finite or out of range, a document nested too deeply.

use std::collections::{HashMap, HashSet};
use std::sync::Mutex;

use nalgebra::{Matrix3, Rotation3, Vector3};
use urdf_rs::JointType;

use super::model::{ChainModel, JointKind, JointSpec};
use super::spatial::{Pose, RigidInertia};
use crate::error::{short, Error, Result};

/// The most joints a chain may have (the simulation is compiled for 1 to 8).
pub const MAX_JOINTS: usize = 8;

/// The deepest element nesting a document may have. A URDF nests about five deep
/// (robot/link/visual/geometry/mesh); the XML reader urdf-rs uses builds and drops its tree
/// recursively, so 20 000 nested elements overflow the stack and kill the process.
pub const MAX_NESTING: usize = 100;

/// Largest |xyz| component of an origin [m]: no arm is a kilometre long, and the inertia's
/// m·c² terms overflow long before 1e300.
const MAX_OFFSET: f64 = 1e3;

/// Largest link mass [kg] and |inertia| entry [kg·m²]: a million tonnes is no arm, and
/// 1e300 overflows the dynamics' products into "inertia = NaN" far from its cause.
const MAX_MASS: f64 = 1e9;

/// Largest |rpy| angle [rad]: a file means an angle within a few turns; beyond 1e3 rad the
/// angle's own last bit is worth more than the 1e-13 rad the dynamics are checked to.
const MAX_ANGLE: f64 = 1e3;

/// How deeply `text`'s elements nest, counted without building a tree (comments, CDATA,
/// processing instructions and declarations skipped, quoted attribute values respected).
/// Stops counting past `limit`. Malformed text is left to the XML reader to report.
fn nesting_depth(text: &str, limit: usize) -> usize {
    let b = text.as_bytes();
    let (mut i, mut depth, mut deepest) = (0usize, 0usize, 0usize);
    let skip_to = |from: usize, end: &[u8]| {
        b[from..]
            .windows(end.len())
            .position(|w| w == end)
            .map_or(b.len(), |p| from + p + end.len())
    };
    while i < b.len() {
        if b[i] != b'<' {
            i += 1;
            continue;
        }
        let rest = &b[i..];
        if rest.starts_with(b"<!--") {
            i = skip_to(i + 4, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = skip_to(i + 9, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = skip_to(i + 2, b"?>");
        } else if rest.starts_with(b"<!") {
            i = skip_to(i + 2, b">");
        } else if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = skip_to(i + 2, b">");
        } else {
            // A start tag: to its '>' outside quotes; "/>" closes it at once.
            let mut j = i + 1;
            let mut quote = None;
            while j < b.len() {
                match (quote, b[j]) {
                    (None, q @ (b'"' | b'\'')) => quote = Some(q),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            let empty = j < b.len() && b[j - 1] == b'/';
            deepest = deepest.max(depth + 1);
            if deepest > limit {
                return deepest;
            }
            if !empty {
                depth += 1;
            }
            i = j + 1;
        }
    }
    deepest
}

/// Checks an `<origin>`: finite, |xyz| ≤ [`MAX_OFFSET`] m, |rpy| ≤ [`MAX_ANGLE`] rad.
fn check_origin(field: &str, p: &urdf_rs::Pose) -> Result<()> {
    for (name, v, max, unit) in [
        ("xyz", p.xyz.0, MAX_OFFSET, "m"),
        ("rpy", p.rpy.0, MAX_ANGLE, "rad"),
    ] {
        if !v.iter().all(|x| (-max..=max).contains(x)) {
            let shown: Vec<String> = v.iter().map(|x| short(*x)).collect();
            return Err(Error::parameter(
                &format!("{field} origin {name}"),
                format!("[{}]", shown.join(", ")),
                &format!("three finite numbers within ±{} {unit}", short(max)),
            ));
        }
    }
    Ok(())
}

/// The numbers of the document that nothing else checks: every joint's origin and limits,
/// every link's inertial origin; and one definition per link and joint name (urdf-rs keeps
/// them all and the last one would silently win).
fn check_document(robot: &urdf_rs::Robot) -> Result<()> {
    let mut seen = HashSet::new();
    for l in &robot.links {
        if !seen.insert(l.name.as_str()) {
            return Err(Error::parameter(
                &link_field(&l.name),
                "defined twice",
                "one <link> per name",
            ));
        }
        check_origin(
            &format!("{} inertial", link_field(&l.name)),
            &l.inertial.origin,
        )?;
    }
    let mut seen = HashSet::new();
    for j in &robot.joints {
        if !seen.insert(j.name.as_str()) {
            return Err(Error::parameter(
                &joint_field(&j.name),
                "defined twice",
                "one <joint> per name",
            ));
        }
        check_origin(&joint_field(&j.name), &j.origin)?;
        let l = &j.limit;
        for (name, v) in [
            ("lower", l.lower),
            ("upper", l.upper),
            ("effort", l.effort),
            ("velocity", l.velocity),
        ] {
            if v.is_nan() {
                return Err(Error::parameter(
                    &format!("{} limit {name}", joint_field(&j.name)),
                    v,
                    "a number (not NaN)",
                ));
            }
        }
    }
    Ok(())
}

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
        "mass {}, inertia [ixx {}, ixy {}, ixz {}, iyy {}, iyz {}, izz {}]",
        short(m),
        short(t.ixx),
        short(t.ixy),
        short(t.ixz),
        short(t.iyy),
        short(t.iyz),
        short(t.izz)
    );
    let field = format!("{} inertial", link_field(&link.name));
    if !(0.0..=MAX_MASS).contains(&m) || !tensor.iter().all(|v| (-MAX_MASS..=MAX_MASS).contains(v))
    {
        return Err(Error::parameter(
            &field,
            values,
            "finite, with mass from 0 to 1e9 kg and moments within ±1e9 kg·m²",
        ));
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
    let depth = nesting_depth(text, MAX_NESTING);
    if depth > MAX_NESTING {
        return Err(Error::parameter(
            "urdf",
            format!("elements nested more than {MAX_NESTING} deep"),
            &format!("a URDF document nested at most {MAX_NESTING} elements deep"),
        ));
    }
    let robot = urdf_rs::read_from_string(text).map_err(|e| {
        let first = e.to_string().lines().next().unwrap_or("").to_owned();
        Error::parameter(
            "urdf",
            format!("text of {} bytes", text.len()),
            &format!("a valid URDF document ({first})"),
        )
    })?;
    check_document(&robot)?;
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

    /// The nesting is counted as XML nests: comments, CDATA, declarations and quoted '>'
    /// do not count, empty elements close at once.
    #[test]
    fn nesting_depth_counts_elements() {
        assert_eq!(nesting_depth(PANDA, 1000), 4);
        let doc = r#"<?xml version="1.0"?><!DOCTYPE r><robot name="a>b"><!-- <x><y> -->
            <link name="l"/><![CDATA[<z><z>]]><link name='m'><inertial/></link></robot>"#;
        assert_eq!(nesting_depth(doc, 1000), 3);
        let deep = format!(
            "<robot>{}{}</robot>",
            "<x>".repeat(20_000),
            "</x>".repeat(20_000)
        );
        assert_eq!(nesting_depth(&deep, MAX_NESTING), MAX_NESTING + 1);
        let e = parse(&deep, None, "a").expect_err("too deep");
        assert_eq!(
            e.to_string(),
            "urdf = elements nested more than 100 deep is invalid: must be a URDF document \
             nested at most 100 elements deep"
        );
    }

    const TWO: &str = r#"<robot name="r">
        <link name="base"/>
        <link name="a"><inertial><mass value="1"/><origin xyz="0 0 0.5"/>
            <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
        <joint name="j" type="revolute"><parent link="base"/><child link="a"/>
            <origin xyz="0 0 1" rpy="0 0 0"/><axis xyz="0 1 0"/>
            <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
        </robot>"#;

    /// Two links or joints of one name are an error naming them, not "the last one wins".
    #[test]
    fn duplicate_names_are_rejected() {
        assert_eq!(parse(TWO, None, "a").expect("valid").dof(), 1);
        let link = TWO.replace(
            r#"<link name="base"/>"#,
            r#"<link name="base"/><link name="a"/>"#,
        );
        let e = parse(&link, None, "a").expect_err("two links 'a'");
        assert_eq!(
            e.to_string(),
            "urdf link 'a' = defined twice is invalid: must be one <link> per name"
        );
        let joint = TWO.replace(
            "</robot>",
            r#"<link name="b"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#,
        );
        let e = parse(&joint, None, "a").expect_err("two joints 'j'");
        assert_eq!(
            e.to_string(),
            "urdf joint 'j' = defined twice is invalid: must be one <joint> per name"
        );
    }

    /// Origins that are not finite or out of range, and NaN limits, name their element.
    #[test]
    fn origins_and_limits_are_checked() {
        for (from, to, message) in [
            (
                r#"xyz="0 0 1" rpy"#,
                r#"xyz="0 nan 1" rpy"#,
                "urdf joint 'j' origin xyz = [0, NaN, 1] is invalid: must be three finite \
                 numbers within ±1000 m",
            ),
            (
                r#"rpy="0 0 0""#,
                r#"rpy="0 1e300 0""#,
                "urdf joint 'j' origin rpy = [0, 1e300, 0] is invalid: must be three finite \
                 numbers within ±1000 rad",
            ),
            (
                r#"xyz="0 0 0.5""#,
                r#"xyz="-inf 0 0.5""#,
                "urdf link 'a' inertial origin xyz = [-inf, 0, 0.5] is invalid: must be three \
                 finite numbers within ±1000 m",
            ),
            (
                r#"upper="1""#,
                r#"upper="NaN""#,
                "urdf joint 'j' limit upper = NaN is invalid: must be a number (not NaN)",
            ),
            (
                r#"<mass value="1"/>"#,
                r#"<mass value="1e300"/>"#,
                "urdf link 'a' inertial = mass 1e300, inertia [ixx 1, ixy 0, ixz 0, iyy 1, \
                 iyz 0, izz 1] is invalid: must be finite, with mass from 0 to 1e9 kg and \
                 moments within ±1e9 kg·m²",
            ),
        ] {
            let text = TWO.replace(from, to);
            assert_ne!(text, TWO, "{from}");
            let e = parse(&text, None, "a").expect_err(to);
            assert_eq!(e.to_string(), message);
        }
    }
}
