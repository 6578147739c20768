//! The recorded run: one column per quantity (structure of arrays), sample k at t_k.

/// Names of the scalar columns, in trace order after the joint columns q, q̇.
const TASK_COLUMNS: [&str; 17] = [
    "x",
    "y",
    "z",
    "x_ref",
    "y_ref",
    "z_ref",
    "f",
    "f_measured",
    "f_d",
    "penetration",
    "x_a",
    "xa_dot",
    "fx",
    "fy",
    "fz",
    "f_t",
    "slip_speed",
];

/// Column names of a trace of an `joints`-joint arm, in order: t, q1..qn, qd1..qn, x, y, z,
/// x_ref, y_ref, z_ref, f, f_measured, f_d, penetration, x_a, xa_dot, fx, fy, fz, f_t,
/// slip_speed, tau1..n, tau_cmd1..n.
pub fn trace_columns(joints: usize) -> Vec<String> {
    let joint = |prefix: &'static str| (1..=joints).map(move |j| format!("{prefix}{j}"));
    std::iter::once("t".to_owned())
        .chain(joint("q"))
        .chain(joint("qd"))
        .chain(TASK_COLUMNS.iter().map(|c| (*c).to_owned()))
        .chain(joint("tau"))
        .chain(joint("tau_cmd"))
        .collect()
}

/// One sample of the loop, as recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row<'a> {
    pub t: f64,
    pub q: &'a [f64],
    pub qd: &'a [f64],
    /// Tip position [x, y, z].
    pub position: [f64; 3],
    /// Desired tip position X_d.
    pub reference: [f64; 3],
    /// True contact force along n.
    pub f: f64,
    /// What the sensor reported.
    pub f_measured: f64,
    pub f_d: f64,
    /// n·X − x_e (NaN without a wall).
    pub penetration: f64,
    pub x_a: f64,
    pub xa_dot: f64,
    /// The true force on the surface [fx, fy, fz] (world frame): f N − F_t.
    pub surface_force: [f64; 3],
    /// |F_t|, the friction force's magnitude.
    pub f_t: f64,
    /// |v_t|, the tip's speed within the contact's tangent plane (NaN in free space).
    pub slip_speed: f64,
    /// Applied torque.
    pub tau: &'a [f64],
    /// Commanded torque.
    pub tau_cmd: &'a [f64],
}

/// The forces of a run apart from its trace: the true normal force f and the friction
/// force's magnitude f_t at every sample (what `substeps = "auto"` compares between runs).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ForceLog {
    pub f: Vec<f64>,
    pub f_t: Vec<f64>,
}

impl ForceLog {
    pub fn with_capacity(samples: usize) -> Self {
        Self {
            f: Vec::with_capacity(samples),
            f_t: Vec::with_capacity(samples),
        }
    }

    pub fn push(&mut self, f: f64, f_t: f64) {
        self.f.push(f);
        self.f_t.push(f_t);
    }

    pub fn clear(&mut self) {
        self.f.clear();
        self.f_t.clear();
    }

    pub fn len(&self) -> usize {
        self.f.len()
    }

    pub fn is_empty(&self) -> bool {
        self.f.is_empty()
    }

    /// The largest difference between two runs' forces, max over samples of |Δf| and
    /// |Δf_t|: infinite when one run took samples the other did not (it diverged sooner)
    /// or one value is NaN where the other is not.
    pub fn distance(&self, other: &ForceLog) -> f64 {
        if self.len() != other.len() {
            return f64::INFINITY;
        }
        let gap = |a: &[f64], b: &[f64]| {
            a.iter().zip(b).fold(0.0_f64, |m, (x, y)| {
                let d = (x - y).abs();
                if d.is_nan() {
                    // Both NaN (no such value at this sample) agree; one NaN does not.
                    if x.is_nan() && y.is_nan() {
                        m
                    } else {
                        f64::INFINITY
                    }
                } else {
                    m.max(d)
                }
            })
        };
        gap(&self.f, &other.f).max(gap(&self.f_t, &other.f_t))
    }
}

/// A recorded run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    pub t: Vec<f64>,
    pub q: Vec<Vec<f64>>,
    pub qd: Vec<Vec<f64>>,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub z: Vec<f64>,
    pub x_ref: Vec<f64>,
    pub y_ref: Vec<f64>,
    pub z_ref: Vec<f64>,
    pub f: Vec<f64>,
    pub f_measured: Vec<f64>,
    pub f_d: Vec<f64>,
    pub penetration: Vec<f64>,
    pub x_a: Vec<f64>,
    pub xa_dot: Vec<f64>,
    pub fx: Vec<f64>,
    pub fy: Vec<f64>,
    pub fz: Vec<f64>,
    pub f_t: Vec<f64>,
    pub slip_speed: Vec<f64>,
    pub tau: Vec<Vec<f64>>,
    pub tau_cmd: Vec<Vec<f64>>,
}

impl Trace {
    pub fn new(joints: usize, capacity: usize) -> Self {
        let col = || Vec::with_capacity(capacity);
        let joint_cols = || (0..joints).map(|_| col()).collect::<Vec<_>>();
        Self {
            t: col(),
            q: joint_cols(),
            qd: joint_cols(),
            x: col(),
            y: col(),
            z: col(),
            x_ref: col(),
            y_ref: col(),
            z_ref: col(),
            f: col(),
            f_measured: col(),
            f_d: col(),
            penetration: col(),
            x_a: col(),
            xa_dot: col(),
            fx: col(),
            fy: col(),
            fz: col(),
            f_t: col(),
            slip_speed: col(),
            tau: joint_cols(),
            tau_cmd: joint_cols(),
        }
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    pub fn joints(&self) -> usize {
        self.q.len()
    }

    #[inline(always)]
    pub fn push(&mut self, r: &Row) {
        self.t.push(r.t);
        for (c, v) in self.q.iter_mut().zip(r.q) {
            c.push(*v);
        }
        for (c, v) in self.qd.iter_mut().zip(r.qd) {
            c.push(*v);
        }
        self.x.push(r.position[0]);
        self.y.push(r.position[1]);
        self.z.push(r.position[2]);
        self.x_ref.push(r.reference[0]);
        self.y_ref.push(r.reference[1]);
        self.z_ref.push(r.reference[2]);
        self.f.push(r.f);
        self.f_measured.push(r.f_measured);
        self.f_d.push(r.f_d);
        self.penetration.push(r.penetration);
        self.x_a.push(r.x_a);
        self.xa_dot.push(r.xa_dot);
        self.fx.push(r.surface_force[0]);
        self.fy.push(r.surface_force[1]);
        self.fz.push(r.surface_force[2]);
        self.f_t.push(r.f_t);
        self.slip_speed.push(r.slip_speed);
        for (c, v) in self.tau.iter_mut().zip(r.tau) {
            c.push(*v);
        }
        for (c, v) in self.tau_cmd.iter_mut().zip(r.tau_cmd) {
            c.push(*v);
        }
    }

    /// Keeps the first `len` samples.
    pub fn truncate(&mut self, len: usize) {
        self.columns_mut().into_iter().for_each(|c| c.truncate(len));
    }

    /// Every column in the order of `trace_columns` (the one place that lists them).
    fn columns_mut(&mut self) -> Vec<&mut Vec<f64>> {
        let mut out = vec![&mut self.t];
        out.extend(self.q.iter_mut());
        out.extend(self.qd.iter_mut());
        out.extend([
            &mut self.x,
            &mut self.y,
            &mut self.z,
            &mut self.x_ref,
            &mut self.y_ref,
            &mut self.z_ref,
            &mut self.f,
            &mut self.f_measured,
            &mut self.f_d,
            &mut self.penetration,
            &mut self.x_a,
            &mut self.xa_dot,
            &mut self.fx,
            &mut self.fy,
            &mut self.fz,
            &mut self.f_t,
            &mut self.slip_speed,
        ]);
        out.extend(self.tau.iter_mut());
        out.extend(self.tau_cmd.iter_mut());
        out
    }

    /// Columns with their names, moved out (no copy).
    pub fn into_named_columns(mut self) -> Vec<(String, Vec<f64>)> {
        let names = trace_columns(self.joints());
        let cols = self.columns_mut().into_iter().map(std::mem::take);
        names.into_iter().zip(cols).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_match_columns() {
        let mut tr = Trace::new(2, 4);
        let row = Row {
            t: 0.5,
            q: &[1.0, 2.0],
            qd: &[3.0, 4.0],
            position: [5.0, 6.0, 7.0],
            reference: [8.0, 9.0, 10.0],
            f: 11.0,
            f_measured: 12.0,
            f_d: 13.0,
            penetration: 14.0,
            x_a: 15.0,
            xa_dot: 16.0,
            surface_force: [22.0, 23.0, 24.0],
            f_t: 25.0,
            slip_speed: 26.0,
            tau: &[18.0, 19.0],
            tau_cmd: &[20.0, 21.0],
        };
        tr.push(&row);
        let named = tr.clone().into_named_columns();
        assert_eq!(named.len(), trace_columns(2).len());
        let value = |name: &str| named.iter().find(|(n, _)| n == name).unwrap().1[0];
        assert_eq!(value("t"), 0.5);
        assert_eq!(value("qd2"), 4.0);
        assert_eq!(value("z_ref"), 10.0);
        assert_eq!(value("f_measured"), 12.0);
        assert_eq!(value("tau_cmd2"), 21.0);
        assert_eq!(value("fy"), 23.0);
        assert_eq!(value("slip_speed"), 26.0);
        tr.truncate(0);
        assert!(tr.is_empty());
    }
}
