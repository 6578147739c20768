//! Spatial (6-D) algebra after Featherstone, *Rigid Body Dynamics Algorithms* (2008), ch. 2.
//!
//! Motion vectors m = [ω; v] and force vectors f = [n; f] (angular part first, linear part at
//! the frame's origin). A [`Pose`] places a child frame in its parent (rotation R: child axes
//! in parent coordinates; p: child origin in parent coordinates); its Plücker motion transform
//! parent → child is X = [[Rᵀ, 0], [−Rᵀ[p]×, Rᵀ]] (eq. 2.24 with E = Rᵀ, r = p).
//!
//! Everything is generic over the scalar `T` ([`Real`]: nalgebra's `SimdRealField`), so the
//! same code runs on `f64` and on SIMD lanes, and nothing allocates.

use nalgebra::{Matrix3, Matrix6, Vector3};

pub use crate::scalar::Real;
use crate::scalar::{cross, zeros};

/// A 6-D spatial vector: motion [ω; v] or force [n; f].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SVec<T: Real> {
    pub ang: Vector3<T>,
    pub lin: Vector3<T>,
}

impl<T: Real> SVec<T> {
    #[inline(always)]
    pub fn new(ang: Vector3<T>, lin: Vector3<T>) -> Self {
        Self { ang, lin }
    }

    #[inline(always)]
    pub fn zero() -> Self {
        Self::new(zeros(), zeros())
    }

    /// Motion cross product v ×ₘ m (eq. 2.31).
    #[inline(always)]
    pub fn cross_motion(&self, m: &SVec<T>) -> SVec<T> {
        SVec::new(
            cross(&self.ang, &m.ang),
            cross(&self.ang, &m.lin) + cross(&self.lin, &m.ang),
        )
    }

    /// Force cross product v ×* f (eq. 2.32).
    #[inline(always)]
    pub fn cross_force(&self, f: &SVec<T>) -> SVec<T> {
        SVec::new(
            cross(&self.ang, &f.ang) + cross(&self.lin, &f.lin),
            cross(&self.ang, &f.lin),
        )
    }

    /// The scalar product of a motion and a force vector.
    #[inline(always)]
    pub fn dot(&self, f: &SVec<T>) -> T {
        self.ang.dot(&f.ang) + self.lin.dot(&f.lin)
    }

    #[inline(always)]
    pub fn scale(&self, s: T) -> SVec<T> {
        SVec::new(self.ang * s, self.lin * s)
    }

    #[inline(always)]
    pub fn add(&self, o: &SVec<T>) -> SVec<T> {
        SVec::new(self.ang + o.ang, self.lin + o.lin)
    }

    #[inline(always)]
    pub fn sub(&self, o: &SVec<T>) -> SVec<T> {
        SVec::new(self.ang - o.ang, self.lin - o.lin)
    }

    /// Reads a 6-vector [ang; lin] out of a 6×6 matrix product.
    #[inline(always)]
    pub fn from_matrix_column(m: &nalgebra::Vector6<T>) -> Self {
        SVec::new(
            Vector3::new(m[0], m[1], m[2]),
            Vector3::new(m[3], m[4], m[5]),
        )
    }

    #[inline(always)]
    pub fn to_vector6(&self) -> nalgebra::Vector6<T> {
        nalgebra::Vector6::new(
            self.ang[0],
            self.ang[1],
            self.ang[2],
            self.lin[0],
            self.lin[1],
            self.lin[2],
        )
    }
}

/// The skew matrix [a]× with [a]× b = a × b.
#[inline(always)]
pub fn skew<T: Real>(a: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -a[2], a[1], a[2], z, -a[0], -a[1], a[0], z)
}

/// A frame placed in its parent: rotation (child axes in parent coordinates) and origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose<T: Real> {
    pub rot: Matrix3<T>,
    pub pos: Vector3<T>,
}

impl<T: Real> Pose<T> {
    #[inline(always)]
    pub fn identity() -> Self {
        let (zero, one) = (T::zero(), T::one());
        Self {
            rot: mat3(|i, j| if i == j { one } else { zero }),
            pos: Vector3::new(zero, zero, zero),
        }
    }

    /// This pose followed by `child` (a frame placed in this one).
    #[inline(always)]
    pub fn compose(&self, child: &Pose<T>) -> Pose<T> {
        Pose {
            rot: mul3(&self.rot, &child.rot),
            pos: self.pos + mul3v(&self.rot, &child.pos),
        }
    }

    /// A point given in this frame, in the parent's coordinates.
    #[inline(always)]
    pub fn transform_point(&self, p: &Vector3<T>) -> Vector3<T> {
        self.pos + mul3v(&self.rot, p)
    }

    /// Motion vector from parent to child coordinates: X m (eq. 2.24).
    #[inline(always)]
    pub fn motion_to_child(&self, m: &SVec<T>) -> SVec<T> {
        SVec::new(
            mul3tv(&self.rot, &m.ang),
            mul3tv(&self.rot, &(m.lin - cross(&self.pos, &m.ang))),
        )
    }

    /// Force vector from child to parent coordinates: Xᵀ f (= X* of the inverse, eq. 2.25).
    #[inline(always)]
    pub fn force_to_parent(&self, f: &SVec<T>) -> SVec<T> {
        let lin = mul3v(&self.rot, &f.lin);
        SVec::new(mul3v(&self.rot, &f.ang) + cross(&self.pos, &lin), lin)
    }

    /// The 6×6 motion transform X (parent → child).
    #[inline(always)]
    pub fn motion_matrix(&self) -> Matrix6<T> {
        let rt = self.rot.transpose();
        let mut x = Matrix6::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&rt);
        x.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(-(rt * skew(&self.pos))));
        x
    }
}

/// A rotation of `angle` about the unit `axis` (Rodrigues).
#[inline(always)]
pub fn axis_angle<T: Real>(axis: &Vector3<T>, (s, c): (T, T)) -> Matrix3<T> {
    let k = skew(axis);
    Pose::identity().rot + k * s + mul3(&k, &k) * (T::one() - c)
}

/// m Rot(axis, θ) for `(s, c)` = (sin θ, cos θ). For an axis along ±e_k (every joint of
/// common URDF arms) two columns of m turn: 12 products instead of Rodrigues' formula and a
/// 3×3 product (a fifth of a lane Panda evaluation went there), and cos θ enters exactly.
#[inline(always)]
pub fn turn<T: Real>(m: &Matrix3<T>, axis: &Vector3<T>, (s, c): (T, T)) -> Matrix3<T> {
    let (zero, one) = (T::zero(), T::one());
    for k in 0..3 {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let along = axis[i].simd_eq(zero) & axis[j].simd_eq(zero) & axis[k].simd_abs().simd_eq(one);
        if T::all(along) {
            // Rot(±e_k, θ) turns e_i toward ±e_j.
            let sa = s * axis[k];
            let mi = Vector3::new(m[(0, i)], m[(1, i)], m[(2, i)]);
            let mj = Vector3::new(m[(0, j)], m[(1, j)], m[(2, j)]);
            let (ni, nj) = (mi * c + mj * sa, mj * c - mi * sa);
            let mut out = *m;
            for r in 0..3 {
                out[(r, i)] = ni[r];
                out[(r, j)] = nj[r];
            }
            return out;
        }
    }
    mul3(m, &axis_angle(axis, (s, c)))
}

/// The 3×3 products the articulated-body pass runs, written out entry by entry. Why not
/// nalgebra's `*`: in the lanes' AVX2 function LLVM declined to inline its generic product
/// for [`crate::scalar::F64x4`], and a product left out of line runs as baseline x86-64
/// code (two-wide, through the stack) — a third of the lane ABA's time (measured).
#[inline(always)]
fn mat3<T: Real>(f: impl Fn(usize, usize) -> T) -> Matrix3<T> {
    Matrix3::new(
        f(0, 0),
        f(0, 1),
        f(0, 2),
        f(1, 0),
        f(1, 1),
        f(1, 2),
        f(2, 0),
        f(2, 1),
        f(2, 2),
    )
}

/// a b.
#[inline(always)]
pub(crate) fn mul3<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>) -> Matrix3<T> {
    mat3(|i, j| a[(i, 0)] * b[(0, j)] + a[(i, 1)] * b[(1, j)] + a[(i, 2)] * b[(2, j)])
}

/// a bᵀ.
#[inline(always)]
pub(crate) fn mul3_t<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>) -> Matrix3<T> {
    mat3(|i, j| a[(i, 0)] * b[(j, 0)] + a[(i, 1)] * b[(j, 1)] + a[(i, 2)] * b[(j, 2)])
}

/// a v.
#[inline(always)]
pub(crate) fn mul3v<T: Real>(a: &Matrix3<T>, v: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        a[(0, 0)] * v[0] + a[(0, 1)] * v[1] + a[(0, 2)] * v[2],
        a[(1, 0)] * v[0] + a[(1, 1)] * v[1] + a[(1, 2)] * v[2],
        a[(2, 0)] * v[0] + a[(2, 1)] * v[1] + a[(2, 2)] * v[2],
    )
}

/// aᵀ v.
#[inline(always)]
pub(crate) fn mul3tv<T: Real>(a: &Matrix3<T>, v: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        a[(0, 0)] * v[0] + a[(1, 0)] * v[1] + a[(2, 0)] * v[2],
        a[(0, 1)] * v[0] + a[(1, 1)] * v[1] + a[(2, 1)] * v[2],
        a[(0, 2)] * v[0] + a[(1, 2)] * v[1] + a[(2, 2)] * v[2],
    )
}

/// [p]× m: the columns of m crossed from the left by p.
#[inline(always)]
fn cross_columns<T: Real>(p: &Vector3<T>, m: &Matrix3<T>) -> Matrix3<T> {
    let x = cross(p, &Vector3::new(m[(0, 0)], m[(1, 0)], m[(2, 0)]));
    let y = cross(p, &Vector3::new(m[(0, 1)], m[(1, 1)], m[(2, 1)]));
    let z = cross(p, &Vector3::new(m[(0, 2)], m[(1, 2)], m[(2, 2)]));
    Matrix3::new(x[0], y[0], z[0], x[1], y[1], z[1], x[2], y[2], z[2])
}

/// m [p]×: the rows of m crossed from the right by p.
#[inline(always)]
fn rows_cross<T: Real>(m: &Matrix3<T>, p: &Vector3<T>) -> Matrix3<T> {
    let x = cross(&Vector3::new(m[(0, 0)], m[(0, 1)], m[(0, 2)]), p);
    let y = cross(&Vector3::new(m[(1, 0)], m[(1, 1)], m[(1, 2)]), p);
    let z = cross(&Vector3::new(m[(2, 0)], m[(2, 1)], m[(2, 2)]), p);
    Matrix3::new(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2])
}

/// A symmetric spatial (rigid or articulated) inertia by 3×3 blocks, I = [[A, B], [Bᵀ, C]]
/// (A, C symmetric): the force of a motion [ω; v] is [A ω + B v; Bᵀ ω + C v]. Three
/// blocks instead of a 6×6 matrix: 27 numbers, and the products ABA needs touch only the
/// blocks they use (in lanes, 36 vectors of a 6×6 do not fit the registers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatialInertia<T: Real> {
    pub a: Matrix3<T>,
    pub b: Matrix3<T>,
    pub c: Matrix3<T>,
}

impl<T: Real> SpatialInertia<T> {
    /// A rigid body's inertia [[Ī, [h]×], [[h]×ᵀ, m 1]] (eq. 2.63).
    #[inline(always)]
    pub fn rigid(i: &RigidInertia<T>) -> Self {
        let hx = skew(&i.h);
        Self {
            a: i.ibar,
            b: hx,
            c: mat3(|r, k| if r == k { i.mass } else { T::zero() }),
        }
    }

    /// The blocks of a 6×6 matrix (its upper-right and diagonal blocks).
    pub fn from_matrix(m: &Matrix6<T>) -> Self {
        Self {
            a: m.fixed_view::<3, 3>(0, 0).into_owned(),
            b: m.fixed_view::<3, 3>(0, 3).into_owned(),
            c: m.fixed_view::<3, 3>(3, 3).into_owned(),
        }
    }

    /// The 6×6 matrix.
    pub fn matrix(&self) -> Matrix6<T> {
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.a);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&self.b);
        m.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&self.b.transpose());
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.c);
        m
    }

    /// I m, a force.
    #[inline(always)]
    pub fn apply(&self, m: &SVec<T>) -> SVec<T> {
        SVec::new(
            mul3v(&self.a, &m.ang) + mul3v(&self.b, &m.lin),
            mul3tv(&self.b, &m.ang) + mul3v(&self.c, &m.lin),
        )
    }

    /// I − U Uᵀ s for U = [u_ang; u_lin] (ABA's articulated → apparent inertia).
    #[inline(always)]
    pub fn minus_outer(&self, u: &SVec<T>, s: T) -> Self {
        let outer = |x: &Vector3<T>, y: &Vector3<T>| mat3(|i, j| x[i] * y[j] * s);
        Self {
            a: self.a - outer(&u.ang, &u.ang),
            b: self.b - outer(&u.ang, &u.lin),
            c: self.c - outer(&u.lin, &u.lin),
        }
    }

    #[inline(always)]
    pub fn add(&self, o: &Self) -> Self {
        Self {
            a: self.a + o.a,
            b: self.b + o.b,
            c: self.c + o.c,
        }
    }

    /// Xᵀ I X: this inertia, given in the child frame that `pose` places, in the parent's
    /// coordinates. With the rotated blocks A' = R A Rᵀ (B', C' alike) and P = [p]×,
    /// Xᵀ I X = [[A' − B'P + P B'ᵀ − P C'P, B' + P C'], [(B' + P C')ᵀ, C']].
    #[inline(always)]
    pub fn to_parent(&self, pose: &Pose<T>) -> Self {
        let r = &pose.rot;
        let (a, b, c) = (
            mul3_t(&mul3(r, &self.a), r),
            mul3_t(&mul3(r, &self.b), r),
            mul3_t(&mul3(r, &self.c), r),
        );
        // Products with P = [p]× as cross products: P M has columns p × M_j; M P has rows
        // M_iᵀ × p, so −B'P + P B'ᵀ has entries (p × b_i)_j + (p × b_j)_i (b_i: rows of B').
        let p = pose.pos;
        let pc = cross_columns(&p, &c);
        let upper = b + pc;
        let corner =
            a - rows_cross(&b, &p) + cross_columns(&p, &b.transpose()) - rows_cross(&pc, &p);
        Self {
            a: corner,
            b: upper,
            c,
        }
    }
}

/// A rigid body's spatial inertia about a frame's origin: mass m, first moment h = m c and
/// the rotational inertia Ī about the origin (eq. 2.63).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidInertia<T: Real> {
    pub mass: T,
    pub h: Vector3<T>,
    pub ibar: Matrix3<T>,
}

impl<T: Real> RigidInertia<T> {
    pub fn zero() -> Self {
        Self {
            mass: T::zero(),
            h: Vector3::zeros(),
            ibar: Matrix3::zeros(),
        }
    }

    /// From the mass, the centre of mass c and the inertia I_c about it (all in this frame):
    /// Ī = I_c + m [c]× [c]×ᵀ (parallel axes).
    pub fn from_com(mass: T, com: Vector3<T>, i_com: Matrix3<T>) -> Self {
        let cx = skew(&com);
        Self {
            mass,
            h: com * mass,
            ibar: i_com + cx * cx.transpose() * mass,
        }
    }

    /// I m: the momentum of motion m, [Ī ω + h × v; m v − h × ω].
    #[inline(always)]
    pub fn apply(&self, m: &SVec<T>) -> SVec<T> {
        SVec::new(
            T::mat3_vec(&self.ibar, &m.ang) + cross(&self.h, &m.lin),
            m.lin * self.mass - cross(&self.h, &m.ang),
        )
    }

    /// The same body seen from the parent frame, this frame being placed by `pose`.
    pub fn to_parent(&self, pose: &Pose<T>) -> Self {
        let h = pose.rot * self.h;
        // Ī about the new origin: rotate, then shift by p (parallel axes for the first moment).
        let r = pose.rot;
        let ic_rot = r * self.ibar * r.transpose();
        let p = pose.pos;
        let (px, hx) = (skew(&p), skew(&h));
        // Ī' = R Ī Rᵀ − [p]×[h]× − [h + m p]×[p]×, from Ī' = Σ m_k [x_k]×[x_k]×ᵀ, x_k = p + R y_k.
        let ibar = ic_rot - px * hx - skew(&(h + p * self.mass)) * px;
        Self {
            mass: self.mass,
            h: h + p * self.mass,
            ibar,
        }
    }

    pub fn add(&self, o: &Self) -> Self {
        Self {
            mass: self.mass + o.mass,
            h: self.h + o.h,
            ibar: self.ibar + o.ibar,
        }
    }

    pub fn scaled(&self, s: T) -> Self {
        Self {
            mass: self.mass * s,
            h: self.h * s,
            ibar: self.ibar * s,
        }
    }

    /// The 6×6 matrix [[Ī, [h]×], [[h]×ᵀ, m 1]].
    pub fn matrix(&self) -> Matrix6<T> {
        SpatialInertia::rigid(self).matrix()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> Pose<f64> {
        let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
        Pose {
            rot: axis_angle(&axis, 0.7f64.sin_cos()),
            pos: Vector3::new(0.1, -0.4, 0.25),
        }
    }

    fn body() -> RigidInertia<f64> {
        let i = Matrix3::new(0.3, 0.01, -0.02, 0.01, 0.2, 0.03, -0.02, 0.03, 0.25);
        RigidInertia::from_com(2.5, Vector3::new(0.05, -0.1, 0.2), i)
    }

    #[test]
    fn transforms_agree_with_their_matrices() {
        let x = pose();
        let m = SVec::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(1.0, -2.0, 0.5));
        let by_matrix = SVec::from_matrix_column(&(x.motion_matrix() * m.to_vector6()));
        assert!((x.motion_to_child(&m).to_vector6() - by_matrix.to_vector6()).norm() < 1e-14);
        let f = SVec::new(Vector3::new(0.4, -0.2, 0.1), Vector3::new(3.0, 1.0, -2.0));
        let by_matrix = x.motion_matrix().transpose() * f.to_vector6();
        assert!((x.force_to_parent(&f).to_vector6() - by_matrix).norm() < 1e-14);
        // Power is frame-invariant: (X m)·f_child = m·(Xᵀ f_child).
        let power = x.motion_to_child(&m).dot(&f) - m.dot(&x.force_to_parent(&f));
        assert!(power.abs() < 1e-14);
    }

    #[test]
    fn inertia_moves_like_its_matrix() {
        let (x, i) = (pose(), body());
        // I_parent = Xᵀ I_child X (eq. 2.66).
        let expect = x.motion_matrix().transpose() * i.matrix() * x.motion_matrix();
        assert!((i.to_parent(&x).matrix() - expect).norm() < 1e-13);
        // An articulated inertia (any symmetric 6×6) by blocks, as ABA moves it.
        let mut ia = i.matrix();
        ia += nalgebra::Matrix6::from_fn(|r, c| {
            0.01 * (r + 2 * c) as f64 + 0.01 * (c + 2 * r) as f64
        });
        let dense = x.motion_matrix().transpose() * ia * x.motion_matrix();
        let blocks = SpatialInertia::from_matrix(&ia).to_parent(&x).matrix();
        assert!((blocks - dense).norm() < 1e-13);
        let m = SVec::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(1.0, -2.0, 0.5));
        assert!((i.apply(&m).to_vector6() - i.matrix() * m.to_vector6()).norm() < 1e-14);
    }

    /// A turn about ±e_k (two columns turned) is Rodrigues' rotation, and a general axis
    /// takes Rodrigues' formula.
    #[test]
    fn turn_about_base_axes_is_rodrigues() {
        let m = pose().rot;
        for axis in [
            Vector3::x(),
            Vector3::y(),
            Vector3::z(),
            -Vector3::x(),
            -Vector3::y(),
            -Vector3::z(),
            Vector3::new(0.3, -0.5, 0.8).normalize(),
        ] {
            for angle in [0.0f64, 0.4, -2.9, 7.0] {
                let sc = angle.sin_cos();
                let expect = m * axis_angle(&axis, sc);
                assert!(
                    (turn(&m, &axis, sc) - expect).norm() < 1e-15,
                    "{axis} {angle}"
                );
            }
        }
    }

    #[test]
    fn cross_products_are_dual() {
        let v = SVec::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(1.0, -2.0, 0.5));
        let m = SVec::new(Vector3::new(-0.7, 0.4, 0.2), Vector3::new(0.3, 0.1, -0.9));
        let f = SVec::new(Vector3::new(0.4, -0.2, 0.1), Vector3::new(3.0, 1.0, -2.0));
        // (v ×ₘ m)·f = −m·(v ×* f) (eq. 2.33).
        let s: f64 = v.cross_motion(&m).dot(&f) + m.dot(&v.cross_force(&f));
        assert!(s.abs() < 1e-14);
    }
}
