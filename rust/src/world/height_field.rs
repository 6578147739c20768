//! A scanned part as a height field (SPEC §15): n·X = x_e + h(u, v) over a grid of
//! heights centred on the tip's start X0, with (u, v) the coordinates of X − X0 along t̂
//! (§10's motion direction for n) and b̂ = n × t̂.
//!
//! h is bicubic Hermite between nodes, its node slopes h_u, h_v, h_uv from finite
//! differences of the heights (central inside, one-sided at the edges), so h is C¹ and
//! reproduces a linear field exactly. Beyond the grid the surface continues as the tangent
//! plane at the nearest edge point. δ = (n·X − x_e − h)/√(1 + |∇h|²), the inward normal
//! N ∝ n − h_u t̂ − h_v b̂ and δ̇ = N·Ẋ.

use std::sync::Arc;

use nalgebra::Vector3;

use crate::contact::{Contact, Surface, TipMotion};
use crate::error::{check, Error, Result};
use crate::jet::{self, Smooth, V3};
use crate::robot::TaskVector;
use crate::scalar::{Real, Wide};
use crate::world::contact_law::{surface_params, ContactLaw, ContactLawKey};
use crate::world::environment::unit_normal;

/// Most grid nodes accepted (4 values of 8 bytes each are kept per node: 64 MB).
pub const MAX_NODES: usize = 2_000_000;
/// The widest lane group a height field is read in.
const MAX_LANES: usize = 8;

/// Largest |height| and spacing accepted [m].
pub const MAX_SIZE: f64 = 1e3;

surface_params! {
    /// A height field (SPEC §15): heights over a grid centred on the tip's start.
    pub struct HeightFieldParams {
        /// Heights h[i][j] [m] at u_i = (i − (rows − 1)/2)·du, v_j = (j − (cols − 1)/2)·dv
        /// along n (positive: further into the part); at least 2×2, shifted so that
        /// h(0, 0) = 0.
        pub heights: Vec<Vec<f64>> = vec![vec![0.0; 2]; 2],
        /// Grid spacing (du, dv) [m] along t̂ and b̂ = n × t̂.
        pub spacing: [f64; 2] = [0.01, 0.01],
        /// Normal n pointing into the part (any length; normalised): heights are measured
        /// along it. Force is controlled along n, motion along t̂ = normalise(e_z − (e_z·n) n).
        pub normal: [f64; 3] = [1.0, 0.0, 0.0],
    }
}

impl HeightFieldParams {
    pub fn validate(&self) -> Result<()> {
        self.validate_contact()?;
        unit_normal(&self.normal)?;
        for (i, d) in self.spacing.iter().enumerate() {
            check::positive_up_to(&format!("spacing[{i}]"), *d, MAX_SIZE, "m")?;
        }
        let rows = self.heights.len();
        let cols = self.heights.first().map_or(0, Vec::len);
        if rows < 2 || cols < 2 || rows.saturating_mul(cols) > MAX_NODES {
            return Err(Error::parameter(
                "heights",
                format!("a {rows}×{cols} grid"),
                &format!("at least 2×2 and at most {MAX_NODES} nodes"),
            ));
        }
        for (i, row) in self.heights.iter().enumerate() {
            if row.len() != cols {
                return Err(Error::parameter(
                    &format!("heights[{i}]"),
                    format!("{} values", row.len()),
                    &format!("{cols} values, as in row 0"),
                ));
            }
            for (j, h) in row.iter().enumerate() {
                if !(h.is_finite() && h.abs() <= MAX_SIZE) {
                    return Err(Error::parameter(
                        &format!("heights[{i}][{j}]"),
                        *h,
                        &format!("finite, |h| <= {MAX_SIZE} m"),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The grid with its node slopes: (h, du·h_u, dv·h_v, du·dv·h_uv) per node, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightGrid {
    rows: usize,
    cols: usize,
    spacing: [f64; 2],
    nodes: Vec<[f64; 4]>,
}

/// Cubic Hermite basis on [0, 1]: (value weights h00, h10, h01, h11) and their derivatives.
#[inline(always)]
fn hermite<S: Smooth>(t: S) -> ([S; 4], [S; 4]) {
    let c = S::constant;
    let (t2, t3) = (t * t, t * t * t);
    (
        [
            c(2.0) * t3 - c(3.0) * t2 + c(1.0),
            t3 - c(2.0) * t2 + t,
            c(3.0) * t2 - c(2.0) * t3,
            t3 - t2,
        ],
        [
            c(6.0) * t2 - c(6.0) * t,
            c(3.0) * t2 - c(4.0) * t + c(1.0),
            c(6.0) * t - c(6.0) * t2,
            c(3.0) * t2 - c(2.0) * t,
        ],
    )
}

impl HeightGrid {
    /// The grid of `p` (valid), shifted so that h(0, 0) = 0.
    pub fn new(p: &HeightFieldParams) -> Self {
        let (rows, cols) = (p.heights.len(), p.heights[0].len());
        let h = |i: usize, j: usize| p.heights[i][j];
        // Node slopes in units of one cell: central differences inside, one-sided at the
        // edges (exact for a linear field either way).
        let diff = |lo: f64, hi: f64, span: usize| (hi - lo) / span as f64;
        let slope_u = |i: usize, j: usize| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(rows - 1));
            diff(h(a, j), h(b, j), b - a)
        };
        let mut nodes = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            for j in 0..cols {
                let (a, b) = (j.saturating_sub(1), (j + 1).min(cols - 1));
                let hv = diff(h(i, a), h(i, b), b - a);
                let huv = diff(slope_u(i, a), slope_u(i, b), b - a);
                nodes.push([h(i, j), slope_u(i, j), hv, huv]);
            }
        }
        let mut grid = Self {
            rows,
            cols,
            spacing: p.spacing,
            nodes,
        };
        let centre = grid.eval(0.0_f64, 0.0).0;
        grid.nodes.iter_mut().for_each(|n| n[0] -= centre);
        grid
    }

    /// (h, h_u, h_v) at (u, v) [m, 1, 1]: over values, or over jets (the controller's
    /// belief differentiates the surface along its path, SPEC §15).
    pub fn eval<S: Smooth>(&self, u: S, v: S) -> (S, S, S) {
        let c = S::constant;
        let [du, dv] = self.spacing;
        // Grid coordinates, node 0 at the first row/column.
        let gu = u / c(du) + c((self.rows - 1) as f64 / 2.0);
        let gv = v / c(dv) + c((self.cols - 1) as f64 / 2.0);
        let (max_u, max_v) = ((self.rows - 1) as f64, (self.cols - 1) as f64);
        if !(gu.value().is_finite() && gv.value().is_finite()) {
            let nan = c(f64::NAN);
            return (nan, nan, nan);
        }
        let clamp = |g: S, max: f64| {
            if g.value() < 0.0 {
                c(0.0)
            } else if g.value() > max {
                c(max)
            } else {
                g
            }
        };
        let (cu, cv) = (clamp(gu, max_u), clamp(gv, max_v));
        let (i, j) = (
            (cu.value().floor() as usize).min(self.rows - 2),
            (cv.value().floor() as usize).min(self.cols - 2),
        );
        let (tu, tv) = (cu - c(i as f64), cv - c(j as f64));
        let ((wu, dwu), (wv, dwv)) = (hermite(tu), hermite(tv));
        let (mut h, mut hu, mut hv) = (c(0.0), c(0.0), c(0.0));
        let along_u = [
            (wu[0], wu[1], dwu[0], dwu[1]),
            (wu[2], wu[3], dwu[2], dwu[3]),
        ];
        let along_v = [
            (wv[0], wv[1], dwv[0], dwv[1]),
            (wv[2], wv[3], dwv[2], dwv[3]),
        ];
        for (a, &(wa0, wa1, da0, da1)) in along_u.iter().enumerate() {
            for (b, &(wb0, wb1, db0, db1)) in along_v.iter().enumerate() {
                let [f, fu, fv, fuv] = self.nodes[(i + a) * self.cols + j + b].map(c);
                h = h + f * wa0 * wb0 + fu * wa1 * wb0 + fv * wa0 * wb1 + fuv * wa1 * wb1;
                hu = hu + f * da0 * wb0 + fu * da1 * wb0 + fv * da0 * wb1 + fuv * da1 * wb1;
                hv = hv + f * wa0 * db0 + fu * wa1 * db0 + fv * wa0 * db1 + fuv * wa1 * db1;
            }
        }
        // Per cell → per metre; beyond the grid, the tangent plane at the edge point.
        let (hu, hv) = (hu / c(du), hv / c(dv));
        (h + hu * (gu - cu) * c(du) + hv * (gv - cv) * c(dv), hu, hv)
    }
}

/// A height field resolved for a start X0: over `f64`, or four in lanes (each lane reads
/// its own grid).
#[derive(Debug, Clone, PartialEq)]
pub struct HeightField<T: Real = f64> {
    pub law: ContactLaw<T>,
    /// n, t̂ and b̂ = n × t̂.
    pub normal: Vector3<T>,
    pub tangent: Vector3<T>,
    pub binormal: Vector3<T>,
    pub start: Vector3<T>,
    /// x_e = n·X0 + gap.
    pub position: T,
    pub gap: T,
    pub position_error: T,
    /// One grid per lane.
    grids: Vec<Arc<HeightGrid>>,
}

impl HeightField {
    /// The height field of `p` (valid) for a tip starting at `start`.
    pub fn new(p: &HeightFieldParams, start: &TaskVector) -> Result<Self> {
        let normal = unit_normal(&p.normal)?;
        let tangent = crate::control::task::motion_direction(&normal);
        let grid = Arc::new(HeightGrid::new(p));
        Ok(Self {
            law: p.law(),
            normal,
            tangent,
            binormal: normal.cross(&tangent),
            start: *start,
            position: normal.dot(start) + p.gap,
            gap: p.gap,
            position_error: p.position_error,
            grids: vec![grid],
        })
    }

    pub fn key(&self) -> ContactLawKey {
        self.law.key()
    }

    /// The surface's point above X0 (along n) and its inward normal there.
    pub fn nearest_to_start(&self) -> (TaskVector, TaskVector) {
        let (_, hu, hv) = self.grids[0].eval(0.0_f64, 0.0);
        let n = self.normal - self.tangent * hu - self.binormal * hv;
        (self.start + self.normal * self.gap, n / n.norm())
    }
}

impl<W: Real> HeightField<W> {
    /// L height fields of one key in lanes.
    pub fn pack<const L: usize>(f: [&HeightField; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(f.iter().all(|x| x.key() == f[0].key()));
        let p = |g: fn(&HeightField) -> f64| W::from_lanes(|i| g(f[i]));
        let v = |g: fn(&HeightField) -> TaskVector| {
            Vector3::from_fn(|j, _| W::from_lanes(|i| g(f[i])[j]))
        };
        Self {
            law: ContactLaw::pack(f.map(|x| &x.law)),
            normal: v(|x| x.normal),
            tangent: v(|x| x.tangent),
            binormal: v(|x| x.binormal),
            start: v(|x| x.start),
            position: p(|x| x.position),
            gap: p(|x| x.gap),
            position_error: p(|x| x.position_error),
            grids: f.iter().map(|x| x.grids[0].clone()).collect(),
        }
    }
}

impl<T: Real> HeightField<T> {
    /// (δ, N) at tip position X; each lane evaluates its own grid.
    #[inline(always)]
    pub fn penetration_normal(&self, position: &Vector3<T>) -> (T, Vector3<T>) {
        let e = position - self.start;
        let (u, v) = (self.tangent.dot(&e), self.binormal.dot(&e));
        // Each lane's cell differs: the grids are read lane by lane.
        let mut out = [(0.0, 0.0, 0.0); MAX_LANES];
        for (l, (o, g)) in out.iter_mut().zip(&self.grids).enumerate() {
            *o = g.eval(u.extract(l), v.extract(l));
        }
        let h = T::from_lanes(|l| out[l].0);
        let hu = T::from_lanes(|l| out[l].1);
        let hv = T::from_lanes(|l| out[l].2);
        let scale = (T::one() + hu * hu + hv * hv).simd_sqrt();
        let inv = T::one() / scale;
        let normal = (self.normal - self.tangent * hu - self.binormal * hv) * inv;
        let delta = (self.normal.dot(position) - self.position - h) * inv;
        (delta, normal)
    }
}

impl HeightField {
    /// (δ, N) at Y over values or jets (the controller's belief, SPEC §15), as
    /// [`HeightField::penetration_normal`] computes them.
    pub fn depth_normal<S: Smooth>(&self, y: &V3<S>) -> (S, V3<S>) {
        let c = S::constant;
        let e = jet::minus(y, &jet::constant(&self.start));
        let (n, t, b) = (
            jet::constant(&self.normal),
            jet::constant(&self.tangent),
            jet::constant(&self.binormal),
        );
        let (h, hu, hv) = self.grids[0].eval(jet::dot(&t, &e), jet::dot(&b, &e));
        let inv = c(1.0) / (c(1.0) + hu * hu + hv * hv).sqrt();
        let normal = jet::scaled(
            &jet::minus(&jet::minus(&n, &jet::scaled(&t, hu)), &jet::scaled(&b, hv)),
            inv,
        );
        let delta = (jet::dot(&n, y) - c(self.position) - h) * inv;
        (delta, normal)
    }
}

/// Iterations of [`HeightField::foot`]: each shrinks the error by about |Y − p|·κ (κ the
/// curvature), 1e-2 for a tool a few millimetres off a part curved at 0.3 m.
pub const FOOT_ITERATIONS: usize = 8;

impl HeightField {
    /// The surface point at (u, v) and the inward normal there, over values or jets.
    fn point<S: Smooth>(&self, u: S, v: S) -> (V3<S>, V3<S>) {
        let c = S::constant;
        let (n, t, b) = (
            jet::constant(&self.normal),
            jet::constant(&self.tangent),
            jet::constant(&self.binormal),
        );
        let (h, hu, hv) = self.grids[0].eval(u, v);
        let point = jet::plus(
            &jet::plus(&jet::constant(&self.start), &jet::scaled(&t, u)),
            &jet::plus(&jet::scaled(&b, v), &jet::scaled(&n, c(self.gap) + h)),
        );
        let inv = c(1.0) / (c(1.0) + hu * hu + hv * hv).sqrt();
        let normal = jet::minus(&jet::minus(&n, &jet::scaled(&t, hu)), &jet::scaled(&b, hv));
        (point, jet::scaled(&normal, inv))
    }

    /// The foot of the perpendicular from Y to the surface (its nearest point, for a Y
    /// closer than the radius of curvature) and the inward normal there, over values or
    /// jets: Y projected on the tangent plane at the current point, then lifted onto the
    /// surface along n, [`FOOT_ITERATIONS`] times from the point under Y.
    pub fn foot<S: Smooth>(&self, y: &V3<S>) -> (V3<S>, V3<S>) {
        let (t, b) = (jet::constant(&self.tangent), jet::constant(&self.binormal));
        let start = jet::constant(&self.start);
        let mut e = jet::minus(y, &start);
        let (mut p, mut normal) = self.point(jet::dot(&t, &e), jet::dot(&b, &e));
        for _ in 0..FOOT_ITERATIONS {
            let off = jet::dot(&jet::minus(y, &p), &normal);
            e = jet::minus(&jet::minus(y, &jet::scaled(&normal, off)), &start);
            (p, normal) = self.point(jet::dot(&t, &e), jet::dot(&b, &e));
        }
        (p, normal)
    }
}

impl<T: Real> Surface<T> for HeightField<T> {
    #[inline(always)]
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T> {
        let (penetration, normal) = self.penetration_normal(&tip.position());
        self.law.contact_at(penetration, normal, tip)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::environment::{Wall, WallParams};

    fn field(f: impl Fn(f64, f64) -> f64, rows: usize, cols: usize, d: f64) -> HeightFieldParams {
        let heights = (0..rows)
            .map(|i| {
                (0..cols)
                    .map(|j| {
                        let u = (i as f64 - (rows - 1) as f64 / 2.0) * d;
                        let v = (j as f64 - (cols - 1) as f64 / 2.0) * d;
                        f(u, v)
                    })
                    .collect()
            })
            .collect();
        HeightFieldParams {
            heights,
            spacing: [d, d],
            ..HeightFieldParams::default()
        }
    }

    /// A linear field is the tilted plane, inside the grid and beyond it.
    #[test]
    fn a_linear_field_is_a_tilted_plane() {
        let start = TaskVector::new(0.7, 0.1, 0.9);
        let p = field(|u, v| 0.2 * u - 0.1 * v + 0.03, 7, 5, 0.02);
        p.validate().unwrap();
        let hf = HeightField::new(&p, &start).unwrap();
        // n = e_x, t̂ = e_z, b̂ = e_x × e_z = −e_y: N ∝ e_x − 0.2 e_z − 0.1 e_y.
        let normal = [1.0, -0.1, -0.2];
        let w = Wall::new(
            &WallParams {
                normal,
                ..WallParams::default()
            },
            &start,
        )
        .unwrap();
        for (du, dv, dn) in [(0.0, 0.0, 0.001), (0.05, -0.03, -0.002), (0.4, 0.3, 0.01)] {
            let x = start + TaskVector::new(dn, -dv, du);
            let (delta, n) = hf.penetration_normal(&x);
            assert!((delta - w.penetration(&x)).abs() < 1e-15, "{delta}");
            assert!((n - w.normal).norm() < 1e-15);
        }
    }

    /// The foot of the perpendicular on a grid sampled from a ball is the ball's nearest
    /// point (to the grid's accuracy), 5 mm off the surface and 4 cm aside.
    #[test]
    fn the_foot_is_the_nearest_point() {
        let r = 0.3;
        let p = field(|u, v| r - (r * r - u * u - v * v).sqrt(), 81, 81, 0.002);
        let start = TaskVector::new(0.7, 0.1, 0.9);
        let hf = HeightField::new(&p, &start).unwrap();
        let centre = start + TaskVector::x() * r;
        let y = start + TaskVector::new(-0.005, 0.01, 0.04);
        let (foot, normal) = hf.foot(&[y[0], y[1], y[2]]);
        let exact = centre + (y - centre).normalize() * r;
        assert!(
            (TaskVector::from(foot) - exact).norm() < 1e-7,
            "{foot:?} {exact}"
        );
        assert!((TaskVector::from(normal) - (centre - exact).normalize()).norm() < 1e-5);
    }

    /// The bicubic interpolant passes through the nodes and is C¹ across cell edges.
    #[test]
    fn bicubic_interpolates_and_is_smooth() {
        let f = |u: f64, v: f64| (8.0 * u).sin() * 0.01 + (5.0 * v).cos() * 0.005;
        let p = field(f, 9, 9, 0.05);
        let g = HeightGrid::new(&p);
        let shift = f(0.0, 0.0);
        let (h, _, _) = g.eval(0.05_f64, -0.1);
        assert!((h - (f(0.05, -0.1) - shift)).abs() < 1e-15);
        let eps = 1e-9;
        let (left, right) = (g.eval(0.05 - eps, 0.013_f64), g.eval(0.05 + eps, 0.013_f64));
        assert!((left.1 - right.1).abs() < 1e-6);
        assert!((left.0 - right.0).abs() < 1e-9);
    }

    #[test]
    fn bad_grids_name_the_field() {
        let bad = |p: HeightFieldParams| p.validate().unwrap_err().to_string();
        assert!(bad(HeightFieldParams {
            heights: vec![vec![0.0; 3]],
            ..HeightFieldParams::default()
        })
        .starts_with("heights = a 1×3 grid"));
        assert!(bad(HeightFieldParams {
            heights: vec![vec![0.0; 3], vec![0.0; 2]],
            ..HeightFieldParams::default()
        })
        .starts_with("heights[1] = 2 values"));
        assert!(bad(HeightFieldParams {
            heights: vec![vec![0.0, f64::INFINITY], vec![0.0; 2]],
            ..HeightFieldParams::default()
        })
        .starts_with("heights[0][1] = inf"));
        assert!(bad(HeightFieldParams {
            spacing: [0.01, -1.0],
            ..HeightFieldParams::default()
        })
        .starts_with("spacing[1] = -1"));
    }
}
