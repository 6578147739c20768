//! Task directions (SPEC §10): force is controlled along the wall normal n, motion follows
//! the in-plane direction t̂ = normalise(e_z − (e_z·n) n) (e_x if n ∥ e_z).
//!
//! X_d = X0 + (x̂_e + x_a − n·X0) n + s(t) t̂; for n = e_x this is exactly SPEC §3,
//! X_d = [x̂_e + x_a, y0, z0 + s].

use nalgebra::Vector3;

use crate::control::reference::Sample;
use crate::robot::TaskVector;
use crate::scalar::{pack_vector, put, put_vector, Real, Wide};

/// Desired tip position, velocity and acceleration at one sample (over `f64` or lanes).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Desired<T: Real = f64> {
    pub position: Vector3<T>,
    pub velocity: Vector3<T>,
    pub acceleration: Vector3<T>,
}

impl<T: Real> Desired<T> {
    /// `self` in the lanes of `mask`, `other` elsewhere.
    #[inline(always)]
    pub fn select(&self, mask: T::SimdBool, other: &Self) -> Self {
        let pick = |a: &Vector3<T>, b: &Vector3<T>| a.zip_map(b, |x, y| x.select(mask, y));
        Self {
            position: pick(&self.position, &other.position),
            velocity: pick(&self.velocity, &other.velocity),
            acceleration: pick(&self.acceleration, &other.acceleration),
        }
    }
}

/// The directions of one task and the fixed part of its reference: one run's (`f64`), or
/// four runs' in lanes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskFrame<T: Real = f64> {
    /// Unit normal n: the force direction.
    pub normal: Vector3<T>,
    /// Unit tangent t̂: the motion direction.
    pub tangent: Vector3<T>,
    /// The start X0.
    pub start: Vector3<T>,
    /// X0 − (n·X0) n: the start's part in the plane through the origin, so that
    /// X_d = in_plane + (x̂_e + x_a) n + s t̂ is exact for n = e_x.
    in_plane: Vector3<T>,
    /// The controller's estimate x̂_e of the wall along n.
    pub wall_estimate: T,
    /// N·n̂: the part of the true normal force along the controlled direction n̂, what a
    /// sensor axis along n̂ reads (1 when the estimate's normal is the true one).
    pub force_projection: T,
}

impl<W: Real> TaskFrame<W> {
    /// Four runs' frames in lanes.
    pub fn pack<const L: usize>(f: [&TaskFrame; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            normal: pack_vector(f.map(|f| &f.normal)),
            tangent: pack_vector(f.map(|f| &f.tangent)),
            start: pack_vector(f.map(|f| &f.start)),
            in_plane: pack_vector(f.map(|f| &f.in_plane)),
            wall_estimate: W::from_lanes(|i| f[i].wall_estimate),
            force_projection: W::from_lanes(|i| f[i].force_projection),
        }
    }

    /// Lane `l` takes `f` (a new run).
    pub fn put_lane(&mut self, l: usize, f: &TaskFrame) {
        put_vector(&mut self.normal, l, &f.normal);
        put_vector(&mut self.tangent, l, &f.tangent);
        put_vector(&mut self.start, l, &f.start);
        put_vector(&mut self.in_plane, l, &f.in_plane);
        put(&mut self.wall_estimate, l, f.wall_estimate);
        put(&mut self.force_projection, l, f.force_projection);
    }
}

/// The motion direction t̂ = normalise(e_z − (e_z·n) n) for a unit normal n (e_x if n ∥ e_z).
pub fn motion_direction(normal: &TaskVector) -> TaskVector {
    let ez = TaskVector::z();
    let t = ez - normal * ez.dot(normal);
    if t.norm() < 1e-9 {
        TaskVector::x()
    } else {
        t / t.norm()
    }
}

impl TaskFrame {
    /// `normal` must be a unit vector.
    pub fn new(normal: TaskVector, start: TaskVector, wall_estimate: f64) -> Self {
        let tangent = motion_direction(&normal);
        Self {
            normal,
            tangent,
            start,
            in_plane: start - normal * normal.dot(&start),
            wall_estimate,
            force_projection: 1.0,
        }
    }

    /// The frame of an estimated plane (n̂, x̂_e) over a true surface of normal `true_normal`.
    pub fn estimated(
        normal: TaskVector,
        start: TaskVector,
        wall_estimate: f64,
        true_normal: &TaskVector,
    ) -> Self {
        Self {
            force_projection: true_normal.dot(&normal),
            ..Self::new(normal, start, wall_estimate)
        }
    }

    /// The component of `v` along n.
    #[inline]
    pub fn along_normal(&self, v: &TaskVector) -> f64 {
        self.normal.dot(v)
    }

    /// The component of `v` along t̂.
    #[inline]
    pub fn along_tangent(&self, v: &TaskVector) -> f64 {
        self.tangent.dot(v)
    }
}

impl<T: Real> TaskFrame<T> {
    /// Force control (SPEC §10): X_d = X0 + (x̂_e + x_a − n·X0) n + s(t) t̂ from the filter
    /// output x_a and the motion s(t), with its rate and acceleration.
    #[inline(always)]
    pub fn force_reference(&self, x_a: &Sample<T>, s: &Sample<T>) -> Desired<T> {
        let (n, t) = (&self.normal, &self.tangent);
        Desired {
            position: self.in_plane + n * (self.wall_estimate + x_a.value) + t * s.value,
            velocity: n * x_a.rate + t * s.rate,
            acceleration: n * x_a.accel + t * s.accel,
        }
    }

    /// Position-only control: X_d = X0 + s(t) t̂.
    #[inline]
    pub fn motion_reference(&self, s: &Sample<T>) -> Desired<T> {
        let t = &self.tangent;
        Desired {
            position: self.start + t * s.value,
            velocity: t * s.rate,
            acceleration: t * s.accel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(value: f64, rate: f64, accel: f64) -> Sample {
        Sample { value, rate, accel }
    }

    /// With n = e_x the reference is SPEC §3's, bit for bit.
    #[test]
    fn paper_wall_gives_the_paper_reference() {
        let x0 = TaskVector::new(0.734056, 0.0, 0.964056);
        let f = TaskFrame::new(TaskVector::x(), x0, 0.744056);
        assert_eq!(f.tangent, TaskVector::z());
        let d = f.force_reference(&sample(0.0012, 0.3, -2.0), &sample(0.04, 0.05, -0.04));
        assert_eq!(
            d.position,
            TaskVector::new(0.744056 + 0.0012, 0.0, 0.964056 + 0.04)
        );
        assert_eq!(d.velocity, TaskVector::new(0.3, 0.0, 0.05));
        assert_eq!(d.acceleration, TaskVector::new(-2.0, 0.0, -0.04));
        let m = f.motion_reference(&sample(0.04, 0.05, -0.04));
        assert_eq!(m.position, TaskVector::new(0.734056, 0.0, 0.964056 + 0.04));
    }

    #[test]
    fn tilted_wall_moves_in_its_plane() {
        let a = 30f64.to_radians();
        let n = TaskVector::new(a.cos(), 0.0, -a.sin());
        let x0 = TaskVector::new(0.7, 0.1, 0.9);
        let f = TaskFrame::new(n, x0, n.dot(&x0) + 0.01);
        assert!(f.tangent.dot(&n).abs() < 1e-15);
        assert!((f.tangent.norm() - 1.0).abs() < 1e-15);
        assert!(f.tangent[2] > 0.0);
        let d = f.force_reference(&sample(0.002, 0.0, 0.0), &sample(0.05, 0.0, 0.0));
        assert!((f.along_normal(&(d.position - x0)) - 0.012).abs() < 1e-15);
        assert!((f.along_tangent(&(d.position - x0)) - 0.05).abs() < 1e-15);
        // n ∥ e_z: motion along e_x.
        let top = TaskFrame::new(TaskVector::z(), x0, 0.9);
        assert_eq!(top.tangent, TaskVector::x());
    }

    /// Four frames in lanes give four scalar references, bit for bit.
    #[test]
    fn lanes_reference_as_four_scalar_frames() {
        use crate::scalar::{lane_of, F64x4};
        let frames: [TaskFrame; 4] = std::array::from_fn(|i| {
            let a = (10.0 * i as f64).to_radians();
            let n = TaskVector::new(a.cos(), 0.0, -a.sin());
            let x0 = TaskVector::new(0.7, 0.01 * i as f64, 0.9);
            TaskFrame::new(n, x0, n.dot(&x0) + 0.001 * i as f64)
        });
        let lanes = TaskFrame::<F64x4>::pack(frames.each_ref());
        let xa: [Sample; 4] =
            std::array::from_fn(|i| sample(0.001 * i as f64, 0.3, -2.0 + i as f64));
        let s: [Sample; 4] = std::array::from_fn(|i| sample(0.04 * i as f64, 0.05, -0.04));
        let d = lanes.force_reference(&Sample::pack(xa.each_ref()), &Sample::pack(s.each_ref()));
        let m = lanes.motion_reference(&Sample::pack(s.each_ref()));
        for i in 0..4 {
            let e = frames[i].force_reference(&xa[i], &s[i]);
            assert_eq!(lane_of(&d.position, i), e.position);
            assert_eq!(lane_of(&d.velocity, i), e.velocity);
            assert_eq!(lane_of(&d.acceleration, i), e.acceleration);
            assert_eq!(
                lane_of(&m.position, i),
                frames[i].motion_reference(&s[i]).position
            );
        }
    }
}
