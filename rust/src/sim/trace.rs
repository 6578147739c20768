//! The recorded run: one column per quantity (structure of arrays), sample k at t_k.
//!
//! The columns live in one buffer, a block of `stride` samples each, in `trace_columns`
//! order, so the whole trace crosses to Python as one array that polars slices into
//! columns without a copy (one `pl.Series` per column costs about 17 µs, 0.5 ms a run).
//! The buffer is allocated uninitialised: zeroing it (a `calloc` of reused heap memory is a
//! `memset` of 2.4 MB for a 10-s run) was 1–2 % of a fig. 14 run, for values never read.

use std::mem::MaybeUninit;

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

impl Row<'_> {
    /// The sample's values in `trace_columns` order (the one place that orders them).
    #[inline(always)]
    fn values(&self) -> impl Iterator<Item = f64> + '_ {
        let task = [
            self.position[0],
            self.position[1],
            self.position[2],
            self.reference[0],
            self.reference[1],
            self.reference[2],
            self.f,
            self.f_measured,
            self.f_d,
            self.penetration,
            self.x_a,
            self.xa_dot,
            self.surface_force[0],
            self.surface_force[1],
            self.surface_force[2],
            self.f_t,
            self.slip_speed,
        ];
        std::iter::once(self.t)
            .chain(self.q.iter().copied())
            .chain(self.qd.iter().copied())
            .chain(task)
            .chain(self.tau.iter().copied())
            .chain(self.tau_cmd.iter().copied())
    }
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

    /// Whether the run had any contact force: a normal force other than 0 (NaN counts) or
    /// a friction force (NaN there means none at that sample).
    pub fn touches(&self) -> bool {
        self.f.iter().any(|&f| f != 0.0) || self.f_t.iter().any(|&t| t != 0.0 && !t.is_nan())
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

/// A recorded run: `len` samples of `trace_columns(joints)`, column c at
/// `data[c * stride..c * stride + len]`.
///
/// Invariant: those `len` samples of every column are initialised; the room after them
/// may not be, and is never read.
#[derive(Default)]
pub struct Trace {
    joints: usize,
    /// The sample index of the first row: 0, unless a fresh run was set to start later
    /// (`Simulation::set_state`).
    first: usize,
    stride: usize,
    len: usize,
    data: Vec<MaybeUninit<f64>>,
}

/// A trace moved out whole: `names[c]`'s samples are `data[c * len..(c + 1) * len]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FlatTrace {
    pub names: Vec<String>,
    pub len: usize,
    pub data: Vec<f64>,
}

/// Index of the first task column (x), after t, q and q̇.
const fn task_start(joints: usize) -> usize {
    1 + 2 * joints
}

impl Trace {
    /// An empty trace with room for `capacity` samples (uninitialised: nothing writes the
    /// room before the run does, and pages it never reaches are never touched).
    pub fn new(joints: usize, capacity: usize) -> Self {
        let mut data = Vec::new();
        data.reserve_exact(Self::width(joints) * capacity);
        // SAFETY: the elements are `MaybeUninit`, which needs no initialisation, and the
        // capacity was just reserved.
        unsafe { data.set_len(Self::width(joints) * capacity) };
        Self {
            joints,
            first: 0,
            stride: capacity,
            len: 0,
            data,
        }
    }

    /// Number of columns.
    fn width(joints: usize) -> usize {
        task_start(joints) + TASK_COLUMNS.len() + 2 * joints
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn joints(&self) -> usize {
        self.joints
    }

    #[inline(always)]
    pub fn push(&mut self, r: &Row) {
        if self.len == self.stride {
            self.grow();
        }
        let (stride, k) = (self.stride, self.len);
        for (c, v) in r.values().enumerate() {
            self.data[c * stride + k].write(v);
        }
        self.len += 1;
    }

    /// Doubles the room (a stepped run that outlives its planned samples).
    #[cold]
    fn grow(&mut self) {
        let mut bigger = Self::new(self.joints, (2 * self.stride).max(64));
        for c in 0..Self::width(self.joints) {
            bigger.fill(c, self.column(c));
        }
        bigger.len = self.len;
        bigger.first = self.first;
        *self = bigger;
    }

    /// Keeps the first `len` samples.
    pub fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }

    /// The sample index of the first row.
    pub fn first(&self) -> usize {
        self.first
    }

    /// Empty, its first row to be sample `first` (a fresh run started there).
    pub fn start_at(&mut self, first: usize) {
        self.len = 0;
        self.first = first;
    }

    /// Drops every sample and makes room for `capacity` (a run started again).
    pub fn clear(&mut self, capacity: usize) {
        if self.stride < capacity {
            *self = Self::new(self.joints, capacity);
        }
        self.len = 0;
        self.first = 0;
    }

    /// Column `c` (in `trace_columns` order).
    pub(crate) fn column(&self, c: usize) -> &[f64] {
        let recorded = &self.data[c * self.stride..c * self.stride + self.len];
        // SAFETY: a column's first `len` samples are initialised (the type's invariant), and
        // `MaybeUninit<f64>` has `f64`'s layout.
        unsafe { &*(recorded as *const [MaybeUninit<f64>] as *const [f64]) }
    }

    /// Writes `values` at the start of column `c` (which then holds at least that many
    /// initialised samples; `len` is the caller's to set).
    fn fill(&mut self, c: usize, values: &[f64]) {
        let room = &mut self.data[c * self.stride..c * self.stride + values.len()];
        for (slot, &v) in room.iter_mut().zip(values) {
            slot.write(v);
        }
    }

    /// Column `name` (a name of `trace_columns`), or None.
    pub fn named(&self, name: &str) -> Option<&[f64]> {
        let c = trace_columns(self.joints).iter().position(|n| n == name)?;
        Some(self.column(c))
    }

    /// A task column by its place in `TASK_COLUMNS`.
    fn task(&self, i: usize) -> &[f64] {
        self.column(task_start(self.joints) + i)
    }

    pub fn t(&self) -> &[f64] {
        self.column(0)
    }

    /// Calls `each` with every sample in order, as the loop recorded it.
    pub fn for_each_row(&self, mut each: impl FnMut(&Row)) {
        let n = self.joints;
        let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
        let (mut tau, mut tau_cmd) = (vec![0.0; n], vec![0.0; n]);
        let task_cols = task_start(n);
        let tau_cols = task_cols + TASK_COLUMNS.len();
        let at = |c: usize, i: usize| self.column(c)[i];
        for i in 0..self.len {
            for j in 0..n {
                q[j] = at(1 + j, i);
                qd[j] = at(1 + n + j, i);
                tau[j] = at(tau_cols + j, i);
                tau_cmd[j] = at(tau_cols + n + j, i);
            }
            let task = |k: usize| at(task_cols + k, i);
            each(&Row {
                t: at(0, i),
                q: &q,
                qd: &qd,
                position: [task(0), task(1), task(2)],
                reference: [task(3), task(4), task(5)],
                f: task(6),
                f_measured: task(7),
                f_d: task(8),
                penetration: task(9),
                x_a: task(10),
                xa_dot: task(11),
                surface_force: [task(12), task(13), task(14)],
                f_t: task(15),
                slip_speed: task(16),
                tau: &tau,
                tau_cmd: &tau_cmd,
            });
        }
    }

    /// The whole trace as one buffer of `len`-sample blocks. A run that used all its room
    /// moves out without a copy; one that ended early closes the gaps in place.
    pub fn into_flat(mut self) -> FlatTrace {
        let len = self.len;
        let width = Self::width(self.joints);
        if len != self.stride {
            for c in 1..width {
                let from = c * self.stride;
                self.data.copy_within(from..from + len, c * len);
            }
        }
        self.data.truncate(width * len);
        let mut data = std::mem::ManuallyDrop::new(self.data);
        let (ptr, length, capacity) = (data.as_mut_ptr(), data.len(), data.capacity());
        // SAFETY: the buffer is now the `width` columns' first `len` samples, back to back,
        // all initialised (the invariant, moved by `copy_within`); `MaybeUninit<f64>` has
        // `f64`'s size and alignment, so the allocation is a valid `Vec<f64>`'s.
        let data = unsafe { Vec::from_raw_parts(ptr.cast::<f64>(), length, capacity) };
        FlatTrace {
            names: trace_columns(self.joints),
            len,
            data,
        }
    }

    /// Columns with their names (copies).
    pub fn into_named_columns(self) -> Vec<(String, Vec<f64>)> {
        let names = trace_columns(self.joints);
        (0..names.len())
            .map(|c| self.column(c).to_vec())
            .zip(names)
            .map(|(col, name)| (name, col))
            .collect()
    }
}

/// One accessor per task column, by its place in `TASK_COLUMNS`.
macro_rules! task_column_accessors {
    ($($index:literal $name:ident),* $(,)?) => {
        impl Trace {
            $(
                #[doc = concat!("The `", stringify!($name), "` column.")]
                pub fn $name(&self) -> &[f64] {
                    self.task($index)
                }
            )*
        }
    };
}

task_column_accessors!(
    0 x, 1 y, 2 z, 3 x_ref, 4 y_ref, 5 z_ref, 6 f, 7 f_measured, 8 f_d, 9 penetration,
    10 x_a, 11 xa_dot, 12 fx, 13 fy, 14 fz, 15 f_t, 16 slip_speed,
);

/// The recorded samples by column name (the room ahead is not shown).
impl std::fmt::Debug for Trace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = trace_columns(self.joints);
        let mut map = f.debug_map();
        for (c, name) in names.iter().enumerate() {
            map.entry(name, &self.column(c));
        }
        map.finish()
    }
}

/// A copy of the recorded samples only (a stepped run's room ahead is not copied).
impl Clone for Trace {
    fn clone(&self) -> Self {
        let mut copy = Self::new(self.joints, self.len);
        for c in 0..Self::width(self.joints) {
            copy.fill(c, self.column(c));
        }
        copy.len = self.len;
        copy.first = self.first;
        copy
    }
}

/// Equal samples in every column, whatever room each has left.
impl PartialEq for Trace {
    fn eq(&self, other: &Self) -> bool {
        self.joints == other.joints
            && self.first == other.first
            && self.len == other.len
            && (0..Self::width(self.joints)).all(|c| self.column(c) == other.column(c))
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

    /// Pushes `count` samples into a 2-joint `trace`, value 1000 c + k in column c of
    /// sample k (so a misplaced value shows); returns each sample's values.
    fn fill(trace: &mut Trace, count: usize) -> Vec<Vec<f64>> {
        (0..count)
            .map(|k| {
                let v = |c: usize| (1000 * c + k) as f64;
                let (q, qd) = ([v(1), v(2)], [v(3), v(4)]);
                let (tau, tau_cmd) = ([v(22), v(23)], [v(24), v(25)]);
                let row = Row {
                    t: v(0),
                    q: &q,
                    qd: &qd,
                    position: [v(5), v(6), v(7)],
                    reference: [v(8), v(9), v(10)],
                    f: v(11),
                    f_measured: v(12),
                    f_d: v(13),
                    penetration: v(14),
                    x_a: v(15),
                    xa_dot: v(16),
                    surface_force: [v(17), v(18), v(19)],
                    f_t: v(20),
                    slip_speed: v(21),
                    tau: &tau,
                    tau_cmd: &tau_cmd,
                };
                trace.push(&row);
                let values: Vec<f64> = row.values().collect();
                assert_eq!(values, (0..26).map(v).collect::<Vec<_>>());
                values
            })
            .collect()
    }

    #[test]
    fn a_trace_grows_past_its_room_and_keeps_every_sample() {
        let mut tr = Trace::new(2, 3);
        let rows = fill(&mut tr, 200);
        assert_eq!(tr.len(), 200);
        let mut seen = Vec::new();
        tr.for_each_row(|row| seen.push(row.values().collect::<Vec<_>>()));
        assert_eq!(seen, rows);
        assert_eq!(tr.f()[150], 11150.0);
        assert_eq!(tr.named("tau_cmd2").unwrap()[7], 25007.0);
        assert_eq!(tr.named("no such column"), None);
    }

    #[test]
    fn a_flat_trace_holds_each_column_in_one_block_also_after_an_early_end() {
        for (room, pushed, kept) in [(10, 10, 10), (10, 7, 7), (10, 9, 4), (4, 9, 9), (5, 0, 0)] {
            let mut tr = Trace::new(2, room);
            let rows = fill(&mut tr, pushed);
            tr.truncate(kept);
            let columns = tr.clone().into_named_columns();
            let flat = tr.into_flat();
            assert_eq!(flat.len, kept);
            assert_eq!(flat.names, trace_columns(2));
            assert_eq!(flat.data.len(), kept * flat.names.len());
            for (c, (name, column)) in columns.iter().enumerate() {
                assert_eq!(&flat.names[c], name);
                assert_eq!(&flat.data[c * kept..(c + 1) * kept], column.as_slice());
                let expected: Vec<f64> = rows[..kept].iter().map(|r| r[c]).collect();
                assert_eq!(column, &expected, "column {name}, room {room}, kept {kept}");
            }
        }
    }

    #[test]
    fn a_clone_copies_the_samples_and_equality_ignores_the_room() {
        let (mut a, mut b) = (Trace::new(2, 50), Trace::new(2, 4));
        fill(&mut a, 6);
        fill(&mut b, 6);
        assert_eq!(a, b);
        let copy = a.clone();
        assert_eq!(copy, a);
        assert_eq!(copy.len(), 6);
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        b.truncate(5);
        assert_ne!(a, b);
        b.clear(100);
        assert!(b.is_empty());
        fill(&mut b, 6);
        assert_eq!(a, b);
        assert_ne!(Trace::new(2, 4), Trace::new(3, 4));
    }
}
