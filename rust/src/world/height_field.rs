//! A scanned part as a height field (SPEC §15): n·X = x_e + h(u, v) over a grid of
//! heights centred on the tip's start X0, with (u, v) the coordinates of X − X0 along t̂
//! (§10's motion direction for n) and b̂ = n × t̂.
//!
//! h is bicubic Hermite between nodes, its node slopes h_u, h_v, h_uv from finite
//! differences of the heights (central inside, one-sided at the edges), so h is C¹ and
//! reproduces a linear field exactly. Beyond the grid the surface continues as the tangent
//! plane at the nearest edge point. δ = (n·X − x_e − h)/√(1 + |∇h|²), the inward normal
//! N ∝ n − h_u t̂ − h_v b̂ and δ̇ = N·Ẋ.

use std::collections::HashMap;
use std::hash::{DefaultHasher, Hasher};
use std::ops::{Add, Mul, Sub};
use std::sync::{Arc, Mutex, PoisonError, Weak};

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

/// A height field's rows of heights, shared: the runs of a sweep over one part hold one
/// copy (`HeightsInterner`), and their simulations one interpolation of it (`shared_grid`).
pub type Heights = Arc<Vec<Vec<f64>>>;

/// Gives equal height tables one allocation as a batch's scenarios are decoded one by one,
/// so that a sweep of 1 024 runs over a 300 × 300 grid holds one copy, not 1 024 (issue
/// #53, item 16). Equal means equal bits (keyed by a hash, then compared in full).
#[derive(Debug, Default)]
pub struct HeightsInterner {
    seen: HashMap<u64, Vec<Heights>>,
}

impl HeightsInterner {
    /// `heights`, or the equal table seen before.
    pub fn intern(&mut self, heights: &mut Heights) {
        let mut hasher = DefaultHasher::new();
        for row in heights.iter() {
            hasher.write_usize(row.len());
            row.iter().for_each(|h| hasher.write_u64(h.to_bits()));
        }
        let same = |a: &Heights, b: &Heights| {
            a.len() == b.len()
                && a.iter().zip(b.iter()).all(|(x, y)| {
                    x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
                })
        };
        let bucket = self.seen.entry(hasher.finish()).or_default();
        match bucket.iter().find(|known| same(known, heights)) {
            Some(known) => *heights = Arc::clone(known),
            None => bucket.push(Arc::clone(heights)),
        }
    }
}

/// The interpolated grids alive, by the heights they were built from and the spacing: a
/// grid is built once for any number of simulations over the same shared heights. The weak
/// reference to the heights keeps their address from being reused while the entry lives.
type GridCache = Vec<(Weak<Vec<Vec<f64>>>, [u64; 2], Weak<HeightGrid>)>;
static GRIDS: Mutex<GridCache> = Mutex::new(Vec::new());

/// The grid of `p` (valid): the one already built for the same shared heights and spacing
/// while it is alive, else a new one.
fn shared_grid(p: &HeightFieldParams) -> Arc<HeightGrid> {
    let spacing = p.spacing.map(f64::to_bits);
    // A panic elsewhere while the lock was held leaves a list that is still valid.
    let mut cache = GRIDS.lock().unwrap_or_else(PoisonError::into_inner);
    cache.retain(|(h, _, g)| h.strong_count() > 0 && g.strong_count() > 0);
    let hit = cache.iter().find_map(|(h, s, g)| {
        let same = *s == spacing && h.upgrade().is_some_and(|h| Arc::ptr_eq(&h, &p.heights));
        if same {
            g.upgrade()
        } else {
            None
        }
    });
    hit.unwrap_or_else(|| {
        let grid = Arc::new(HeightGrid::new(p));
        cache.push((Arc::downgrade(&p.heights), spacing, Arc::downgrade(&grid)));
        grid
    })
}

surface_params! {
    /// A height field (SPEC §15): heights over a grid centred on the tip's start.
    pub struct HeightFieldParams {
        /// Heights h[i][j] [m] at u_i = (i − (rows − 1)/2)·du, v_j = (j − (cols − 1)/2)·dv
        /// along n (positive: further into the part); at least 2×2, shifted so that
        /// h(0, 0) = 0.
        pub heights: Heights = Arc::new(vec![vec![0.0; 2]; 2]),
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
    /// (1/du, 1/dv): the grid is read by products, which are shorter than divisions on
    /// the RK4 stage's chain of dependent operations.
    per_metre: [f64; 2],
    nodes: Vec<[f64; 4]>,
}

/// Cubic Hermite basis on [0, 1]: the value weights (h00, h10, h01, h11) and their first
/// and second derivatives, over values, jets or lanes. `c` makes a constant and `k` scales
/// by one (for a jet, three products where a product with a constant jet takes nine).
#[inline(always)]
fn hermite<A>(t: A, c: impl Fn(f64) -> A, scale: impl Fn(f64, A) -> A) -> [[A; 4]; 3]
where
    A: Copy + Add<Output = A> + Sub<Output = A> + Mul<Output = A>,
{
    let (t2, t3) = (t * t, t * t * t);
    [
        [
            scale(2.0, t3) - scale(3.0, t2) + c(1.0),
            t3 - scale(2.0, t2) + t,
            scale(3.0, t2) - scale(2.0, t3),
            t3 - t2,
        ],
        [
            scale(6.0, t2) - scale(6.0, t),
            scale(3.0, t2) - scale(4.0, t) + c(1.0),
            scale(6.0, t) - scale(6.0, t2),
            scale(3.0, t2) - scale(2.0, t),
        ],
        [
            scale(12.0, t) - c(6.0),
            scale(6.0, t) - c(4.0),
            c(6.0) - scale(12.0, t),
            scale(6.0, t) - c(2.0),
        ],
    ]
}

/// One cell's [h, h_u, h_v, h_uu, h_uv, h_vv] in cell units from the Hermite weights along
/// u and v (`hermite`'s) and the corners' [h, h_u, h_v, h_uv] (`corners[a][b]`, a along u).
/// Summed along v first, so each node value meets one weight (44 products for h, h_u, h_v,
/// where the tensor form takes 96); corner data may be plain values while the weights are
/// jets. Callers that drop the second derivatives do not pay for them (all inlined).
///
/// Written as `#[inline(always)]` functions, not closures or `array::map`: the release
/// build called those out of line, compiled without the lane build's target features, so
/// every lane product in them became a function call (docs/performance-history.md §25).
#[inline(always)]
fn patch<A, N>(
    [wu, dwu, ddwu]: [[A; 4]; 3],
    [wv, dwv, ddwv]: [[A; 4]; 3],
    corners: &[[[N; 4]; 2]; 2],
) -> [A; 6]
where
    A: Copy + Add<Output = A> + Mul<Output = A> + Mul<N, Output = A>,
    N: Copy,
{
    let (value, slope, bend) = (
        along_v(&wv, corners),
        along_v(&dwv, corners),
        along_v(&ddwv, corners),
    );
    [
        along_u(&wu, value),
        along_u(&dwu, value),
        along_u(&wu, slope),
        along_u(&ddwu, value),
        along_u(&dwu, slope),
        along_u(&wu, bend),
    ]
}

/// At u-nodes 0 and 1, weighted along v by `w`: the interpolant of h and h_v (`g`, met
/// by the u value weights) and of h_u and h_uv (`k`, met by the u slope weights).
#[inline(always)]
fn along_v<A, N>(w: &[A; 4], corners: &[[[N; 4]; 2]; 2]) -> [(A, A); 2]
where
    A: Copy + Add<Output = A> + Mul<N, Output = A>,
    N: Copy,
{
    [at_node(w, &corners[0]), at_node(w, &corners[1])]
}

/// `along_v` at one u-node, from its two corners along v.
#[inline(always)]
fn at_node<A, N>(w: &[A; 4], [[f0, fu0, fv0, fuv0], [f1, fu1, fv1, fuv1]]: &[[N; 4]; 2]) -> (A, A)
where
    A: Copy + Add<Output = A> + Mul<N, Output = A>,
    N: Copy,
{
    (
        w[0] * *f0 + w[1] * *fv0 + w[2] * *f1 + w[3] * *fv1,
        w[0] * *fu0 + w[1] * *fuv0 + w[2] * *fu1 + w[3] * *fuv1,
    )
}

/// The u-direction sum of `along_v`'s node pair with the u weights `w`.
#[inline(always)]
fn along_u<A>(w: &[A; 4], [(g0, k0), (g1, k1)]: [(A, A); 2]) -> A
where
    A: Copy + Add<Output = A> + Mul<Output = A>,
{
    w[0] * g0 + w[1] * k0 + w[2] * g1 + w[3] * k1
}

/// A grid coordinate held inside [0, last] (NaN stays NaN; the callers check first).
#[inline(always)]
fn clamp_to(g: f64, last: f64) -> f64 {
    if g < 0.0 {
        0.0
    } else if g > last {
        last
    } else {
        g
    }
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
            per_metre: p.spacing.map(|d| 1.0 / d),
            nodes,
        };
        let centre = grid.eval(0.0_f64, 0.0).0;
        grid.nodes.iter_mut().for_each(|n| n[0] -= centre);
        grid
    }

    /// (h, h_u, h_v) at (u, v) [m, 1, 1] over values or jets (the controller's belief
    /// differentiates the surface along its path, SPEC §15). `HeightField`'s contact reads
    /// the grid the same way in lanes (`HeightField::heights`).
    pub fn eval<S: Smooth>(&self, u: S, v: S) -> (S, S, S) {
        let [h, hu, hv, ..] = self.read(u, v);
        (h, hu, hv)
    }

    /// [h, h_u, h_v, h_uu, h_uv, h_vv] at (u, v) [m, 1, 1, 1/m, 1/m, 1/m]. Beyond the grid
    /// h continues as the tangent plane at the nearest edge point, and the second
    /// derivatives are the edge point's (they steer `HeightField::foot`'s steps only).
    /// Inlined, so a caller that drops outputs does not compute them.
    #[inline(always)]
    fn read<S: Smooth>(&self, u: S, v: S) -> [S; 6] {
        let c = S::constant;
        let ([du, dv], [pu, pv]) = (self.spacing, self.per_metre);
        // Grid coordinates, node 0 at the first row/column.
        let gu = u * pu + c(self.centre(0));
        let gv = v * pv + c(self.centre(1));
        if !(gu.value().is_finite() && gv.value().is_finite()) {
            return [c(f64::NAN); 6];
        }
        let clamp = |g: S, last: f64| {
            let at = clamp_to(g.value(), last);
            if at == g.value() {
                g
            } else {
                c(at)
            }
        };
        let (cu, cv) = (clamp(gu, self.last(0)), clamp(gv, self.last(1)));
        let (i, j) = self.cell(cu.value(), cv.value());
        let (tu, tv) = (cu - c(i as f64), cv - c(j as f64));
        let scale = |x: f64, a: S| a * x;
        let weights = (hermite(tu, c, scale), hermite(tv, c, scale));
        let node = |a: usize, b: usize| self.nodes[(i + a) * self.cols + j + b];
        let corners = [[node(0, 0), node(0, 1)], [node(1, 0), node(1, 1)]];
        let [h, hu, hv, huu, huv, hvv] = patch(weights.0, weights.1, &corners);
        // Per cell → per metre; beyond the grid, the tangent plane at the edge point.
        let (hu, hv) = (hu * pu, hv * pv);
        [
            h + hu * (gu - cu) * du + hv * (gv - cv) * dv,
            hu,
            hv,
            huu * (pu * pu),
            huv * (pu * pv),
            hvv * (pv * pv),
        ]
    }

    /// The grid coordinate of u = 0 (axis 0) or v = 0 (axis 1).
    #[inline(always)]
    fn centre(&self, axis: usize) -> f64 {
        self.last(axis) / 2.0
    }

    /// The last node's grid coordinate along axis 0 (rows) or 1 (columns).
    #[inline(always)]
    fn last(&self, axis: usize) -> f64 {
        ([self.rows, self.cols][axis] - 1) as f64
    }

    /// The cell (i, j) holding clamped grid coordinates (cu, cv) ≥ 0.
    #[inline(always)]
    fn cell(&self, cu: f64, cv: f64) -> (usize, usize) {
        (
            (cu as usize).min(self.rows - 2),
            (cv as usize).min(self.cols - 2),
        )
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
    /// Each lane's grid in lanes: (du, dv), (1/du, 1/dv) and the grid coordinates of
    /// (u, v) = 0 (the cell lookup reads each lane's grid itself).
    spacing: [T; 2],
    per_metre: [T; 2],
    centre: [T; 2],
}

impl HeightField {
    /// The height field of `p` (valid) for a tip starting at `start`.
    pub fn new(p: &HeightFieldParams, start: &TaskVector) -> Result<Self> {
        let normal = unit_normal(&p.normal)?;
        let tangent = crate::control::task::motion_direction(&normal);
        let grid = shared_grid(p);
        Ok(Self {
            law: p.law(),
            normal,
            tangent,
            binormal: normal.cross(&tangent),
            start: *start,
            position: normal.dot(start) + p.gap,
            gap: p.gap,
            position_error: p.position_error,
            spacing: grid.spacing,
            per_metre: grid.per_metre,
            centre: [grid.centre(0), grid.centre(1)],
            grids: vec![grid],
        })
    }

    pub fn key(&self) -> ContactLawKey {
        self.law.key()
    }

    /// Every number fixing the shape and place (`Environment::shape_numbers`).
    pub fn shape_numbers(&self, put: &mut impl FnMut(&[f64])) {
        for v in [&self.start, &self.normal, &self.tangent, &self.binormal] {
            put(v.as_slice());
        }
        put(&[self.position, self.gap]);
        let g = &self.grids[0];
        put(&[g.rows as f64, g.cols as f64]);
        put(&g.spacing);
        g.nodes.iter().for_each(|n| put(n));
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
            spacing: [0, 1].map(|k| W::from_lanes(|i| f[i].spacing[k])),
            per_metre: [0, 1].map(|k| W::from_lanes(|i| f[i].per_metre[k])),
            centre: [0, 1].map(|k| W::from_lanes(|i| f[i].centre[k])),
        }
    }
}

impl<T: Real> HeightField<T> {
    /// Corner (a, b)'s [h, h_u, h_v, h_uv] in every lane's cell (`at[l]`: the cell's
    /// first node in lane l's grid), each gathered from the lane's own grid.
    #[inline(always)]
    fn corner(&self, at: &[usize; MAX_LANES], a: usize, b: usize) -> [T; 4] {
        let field = |k: usize| {
            T::from_lanes(|l| {
                let g = &self.grids[l];
                g.nodes[at[l] + a * g.cols + b][k]
            })
        };
        [field(0), field(1), field(2), field(3)]
    }

    /// (h, h_u, h_v) at (u, v), each lane on its own grid: [`HeightGrid::eval`]'s
    /// arithmetic in lanes (the same operations, so a lane's bits are a scalar run's),
    /// with only the cell lookup and the corner data read lane by lane.
    #[inline(always)]
    fn heights(&self, u: T, v: T) -> (T, T, T) {
        let c = |x: f64| T::splat(x);
        let ([du, dv], [pu, pv]) = (self.spacing, self.per_metre);
        let gu = u * pu + self.centre[0];
        let gv = v * pv + self.centre[1];
        let (mut cu, mut cv, mut i, mut j) = (
            [0.0; MAX_LANES],
            [0.0; MAX_LANES],
            [0.0; MAX_LANES],
            [0.0; MAX_LANES],
        );
        let mut at = [0usize; MAX_LANES];
        let mut finite = true;
        for (l, g) in self.grids.iter().enumerate().take(MAX_LANES) {
            let (a, b) = (gu.extract(l), gv.extract(l));
            let ok = a.is_finite() && b.is_finite();
            finite &= ok;
            // A non-finite lane reads cell (0, 0) and is made NaN below.
            let (a, b) = if ok {
                (clamp_to(a, g.last(0)), clamp_to(b, g.last(1)))
            } else {
                (0.0, 0.0)
            };
            let (ci, cj) = g.cell(a, b);
            (cu[l], cv[l], i[l], j[l]) = (a, b, ci as f64, cj as f64);
            at[l] = ci * g.cols + cj;
        }
        let lanes = |x: &[f64; MAX_LANES]| T::from_lanes(|l| x[l]);
        let (cu, cv) = (lanes(&cu), lanes(&cv));
        let (tu, tv) = (cu - lanes(&i), cv - lanes(&j));
        let scale = |x: f64, a: T| c(x) * a;
        let weights = (hermite(tu, c, scale), hermite(tv, c, scale));
        // Corner (a, b)'s [h, h_u, h_v, h_uv], each gathered from every lane's own grid.
        let corners = [
            [self.corner(&at, 0, 0), self.corner(&at, 0, 1)],
            [self.corner(&at, 1, 0), self.corner(&at, 1, 1)],
        ];
        let [h, hu, hv, ..] = patch(weights.0, weights.1, &corners);
        let (hu, hv) = (hu * pu, hv * pv);
        let out = (h + hu * (gu - cu) * du + hv * (gv - cv) * dv, hu, hv);
        if finite {
            return out;
        }
        let nan = |x: T| {
            T::from_lanes(|l| {
                if gu.extract(l).is_finite() && gv.extract(l).is_finite() {
                    x.extract(l)
                } else {
                    f64::NAN
                }
            })
        };
        (nan(out.0), nan(out.1), nan(out.2))
    }

    /// (δ, N) at tip position X.
    #[inline(always)]
    pub fn penetration_normal(&self, position: &Vector3<T>) -> (T, Vector3<T>) {
        let e = position - self.start;
        let (h, hu, hv) = self.heights(self.tangent.dot(&e), self.binormal.dot(&e));
        // 1/√s as √s · (1/s): the root and the division run side by side.
        let s = T::one() + hu * hu + hv * hv;
        let inv = s.simd_sqrt() * (T::one() / s);
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

/// Most Newton steps of [`HeightField::foot`]; it stops earlier, after a step that moved
/// (u, v) and their rates by at most [`FOOT_TOLERANCE`] (4–5 steps for a tool a few
/// millimetres off a part curved at 0.25 m).
pub const FOOT_STEPS: usize = 16;

/// [`HeightField::foot`] stops after a step whose largest |component| (of u, v and their
/// first and second time derivatives) is at most this times 1 + the largest |component| of
/// u and v after it.
pub const FOOT_TOLERANCE: f64 = 1e-12;

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
    /// jets. With Y − X0 = (y_t, y_b, y_n) along (t̂, b̂, n) and r = Y − P(u, v), it solves
    /// F = (r·P_u, r·P_v) = 0 by Newton's method from the point under Y, where
    /// P_u = t̂ + h_u n and J = ∂F/∂(u, v) = −P_·P_ + (r·n) ∇²h. Where J is not negative
    /// definite (Y beyond the centre of curvature), a step drops the curvature term
    /// (Gauss–Newton).
    ///
    /// On jets, J is taken on the values only: the step −J⁻¹F is then a fixed point of
    /// F's rates as well (J only sets how fast they converge), so Ẋ_d and Ẍ_d are those of
    /// the converged foot, and a step costs no jet division.
    pub fn foot<S: Smooth>(&self, y: &V3<S>) -> (V3<S>, V3<S>) {
        let c = S::constant;
        let grid = &self.grids[0];
        let e = jet::minus(y, &jet::constant(&self.start));
        let along = |d: &TaskVector| jet::dot(&jet::constant(d), &e);
        let (yt, yb) = (along(&self.tangent), along(&self.binormal));
        let yn = along(&self.normal) - c(self.gap);
        let (mut u, mut v) = (yt, yb);
        for _ in 0..FOOT_STEPS {
            let [h, hu, hv, ..] = grid.read(u, v);
            let rn = yn - h;
            let (f1, f2) = (yt - u + hu * rn, yb - v + hv * rn);
            let [_, _, _, huu, huv, hvv] = grid.read(u.value(), v.value());
            let (hu, hv, rn) = (hu.value(), hv.value(), rn.value());
            let (g11, g12, g22) = (1.0 + hu * hu, hu * hv, 1.0 + hv * hv);
            let (mut j11, mut j12, mut j22) = (rn * huu - g11, rn * huv - g12, rn * hvv - g22);
            if !(j11 < 0.0 && j11 * j22 - j12 * j12 > 0.0) {
                (j11, j12, j22) = (-g11, -g12, -g22);
            }
            let det = j11 * j22 - j12 * j12;
            let (du, dv) = (
                f2 * (j12 / det) - f1 * (j22 / det),
                f1 * (j12 / det) - f2 * (j11 / det),
            );
            (u, v) = (u + du, v + dv);
            // A jet's rates (m/s, m/s²) are compared as numbers with its value's scale.
            let scale = 1.0 + u.magnitude().max(v.magnitude());
            if du.magnitude().max(dv.magnitude()) <= FOOT_TOLERANCE * scale {
                break;
            }
        }
        self.point(u, v)
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
            heights: Arc::new(heights),
            spacing: [d, d],
            ..HeightFieldParams::default()
        }
    }

    /// Issue #53, item 16: equal tables (to the bit) share one allocation once interned,
    /// and simulations over one shared table share one interpolated grid while it lives.
    #[test]
    fn equal_heights_are_stored_and_interpolated_once() {
        let bump = |i: usize, j: usize| 1e-3 * ((i * 7 + j) % 5) as f64;
        let table = || -> Heights {
            Arc::new(
                (0..40)
                    .map(|i| (0..30).map(|j| bump(i, j)).collect())
                    .collect(),
            )
        };
        let (mut a, mut b) = (table(), table());
        let mut other = table();
        Arc::make_mut(&mut other)[0][0] = -0.0; // equal by ==, not by bits
        let mut interner = HeightsInterner::default();
        for h in [&mut a, &mut b, &mut other] {
            interner.intern(h);
        }
        assert!(Arc::ptr_eq(&a, &b));
        assert!(!Arc::ptr_eq(&a, &other));
        let start = TaskVector::new(0.7, 0.0, 0.9);
        let p = |heights: &Heights, d: f64| HeightFieldParams {
            heights: Arc::clone(heights),
            spacing: [d, d],
            ..HeightFieldParams::default()
        };
        let one = HeightField::new(&p(&a, 0.01), &start).unwrap();
        let two = HeightField::new(&p(&b, 0.01), &start).unwrap();
        let wider = HeightField::new(&p(&a, 0.02), &start).unwrap();
        assert!(Arc::ptr_eq(&one.grids[0], &two.grids[0]));
        assert!(!Arc::ptr_eq(&one.grids[0], &wider.grids[0]));
        // Once every field over it is gone, the grid is too: a later one is built anew and
        // equals it.
        let kept = Arc::downgrade(&one.grids[0]);
        drop((one, two));
        assert!(kept.upgrade().is_none());
        let again = HeightField::new(&p(&a, 0.01), &start).unwrap();
        assert_eq!(again.grids[0].nodes, HeightGrid::new(&p(&a, 0.01)).nodes);
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

    /// Newton's foot on jets equals the slow fixed-point iteration of the earlier code
    /// (project Y on the tangent plane, lift along n; 60 times) in value, rate and
    /// acceleration, along a polishing-like path 4 mm above, on and 3 mm inside a bulged,
    /// bumped part.
    #[test]
    fn newton_foot_equals_the_fixed_point_on_jets() {
        use crate::jet::Jet;
        let d = 0.005;
        let p = field(
            |u, v| {
                let bump = ((u - 0.03).powi(2) + (v + 0.01).powi(2)) / 4e-4;
                2.0 * u * u + v * v + 3e-4 * (-bump).exp()
            },
            41,
            41,
            d,
        );
        let start = TaskVector::new(0.7, 0.1, 0.9);
        let hf = HeightField::new(&p, &start).unwrap();
        let (t, b) = (jet::constant(&hf.tangent), jet::constant(&hf.binormal));
        let origin = jet::constant(&start);
        let mut worst = [0.0_f64; 3];
        for k in 0..200 {
            let time = k as f64 * 0.1;
            for off in [-0.004, 0.0, 0.003] {
                let s = Jet::new(0.05 * time.sin(), 0.05 * time.cos(), -0.05 * time.sin());
                let y = jet::plus(
                    &jet::plus(&origin, &jet::scaled(&t, s)),
                    &jet::scaled(&jet::constant(&hf.normal), Jet::constant(off)),
                );
                let mut e = jet::minus(&y, &origin);
                let (mut slow, mut normal) = hf.point(jet::dot(&t, &e), jet::dot(&b, &e));
                for _ in 0..60 {
                    let off = jet::dot(&jet::minus(&y, &slow), &normal);
                    e = jet::minus(&jet::minus(&y, &jet::scaled(&normal, off)), &origin);
                    (slow, normal) = hf.point(jet::dot(&t, &e), jet::dot(&b, &e));
                }
                let (fast, _) = hf.foot(&y);
                for (f, s) in fast.iter().zip(&slow) {
                    worst[0] = worst[0].max((f.v - s.v).abs());
                    worst[1] = worst[1].max((f.d - s.d).abs());
                    worst[2] = worst[2].max((f.dd - s.dd).abs());
                }
            }
        }
        // m, m/s, m/s²: the path's speed is 0.05 m/s, its acceleration 0.05 m/s².
        assert!(worst.iter().all(|w| *w < 1e-14), "{worst:?}");
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
        // The second derivatives (Newton's steps in `foot`) against differences of the
        // first, inside a cell.
        let (u, v, e) = (0.073, -0.041, 1e-6);
        let [_, _, _, huu, huv, hvv] = g.read(u, v);
        let (au, zu) = (g.eval(u - e, v), g.eval(u + e, v));
        let (av, zv) = (g.eval(u, v - e), g.eval(u, v + e));
        assert!((huu - (zu.1 - au.1) / (2.0 * e)).abs() < 1e-6, "{huu}");
        assert!((huv - (zv.1 - av.1) / (2.0 * e)).abs() < 1e-6, "{huv}");
        assert!((huv - (zu.2 - au.2) / (2.0 * e)).abs() < 1e-6, "{huv}");
        assert!((hvv - (zv.2 - av.2) / (2.0 * e)).abs() < 1e-6, "{hvv}");
        assert!(huu.abs() > 0.1 && hvv.abs() > 0.01, "{huu} {hvv}");
    }

    #[test]
    fn bad_grids_name_the_field() {
        let bad = |p: HeightFieldParams| p.validate().unwrap_err().to_string();
        assert!(bad(HeightFieldParams {
            heights: vec![vec![0.0; 3]].into(),
            ..HeightFieldParams::default()
        })
        .starts_with("heights = a 1×3 grid"));
        assert!(bad(HeightFieldParams {
            heights: vec![vec![0.0; 3], vec![0.0; 2]].into(),
            ..HeightFieldParams::default()
        })
        .starts_with("heights[1] = 2 values"));
        assert!(bad(HeightFieldParams {
            heights: vec![vec![0.0, f64::INFINITY], vec![0.0; 2]].into(),
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
