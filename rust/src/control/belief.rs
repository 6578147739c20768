//! The controller's belief about a curved surface (SPEC §15): force is controlled along the
//! estimated surface's inward normal n̂ at the tip, and the motion follows the estimated
//! surface. With Y(t) = X0 + s(t) t̂₀ (t̂₀: §10's motion direction for the estimate's normal
//! at its point nearest X0), the reference is
//!
//!   X_d = p(Y) + x_a n̂(p(Y)),
//!
//! p(Y) the estimated surface's point nearest Y and n̂ its inward normal there
//! (`Environment::foot`): closed forms for a plane, a sphere and a cylinder, a converging
//! iteration for a height field. For a plane this is §10's formula. Ẋ_d and Ẍ_d are exact:
//! the geometry is evaluated on second-order jets (`crate::jet`).
//!
//! A plane keeps the task frame's closed form (and its bits); only a curved estimate is
//! held here, one run's per lane. A lane group evaluates its lanes one by one (a height
//! field's grid may differ per lane), except that a lane believing the same shape along the
//! same path as an earlier lane, at the same motion sample, takes that lane's foot: the same
//! function of the same bits (a sweep over stiffness, friction or gains shares it).

use std::hash::{DefaultHasher, Hasher};

use nalgebra::Vector3;

use crate::control::reference::Sample;
use crate::control::task::Desired;
use crate::jet::{self, Jet, V3};
use crate::robot::TaskVector;
use crate::scalar::Real;
use crate::world::surface::Environment;

/// One run's curved estimate, with the start X0 and the motion direction t̂₀.
#[derive(Debug, Clone, PartialEq)]
pub struct CurvedBelief {
    pub surface: Environment,
    pub start: TaskVector,
    pub tangent: TaskVector,
}

/// The curved estimates of one run (`f64`) or of the runs in a lane group.
#[derive(Debug, Clone, PartialEq)]
pub struct Belief {
    lanes: Vec<CurvedBelief>,
    /// In a lane group, each lane's `CurvedBelief::path_fingerprint` (empty for one run).
    paths: Vec<[u64; 2]>,
    /// For each lane, the first earlier lane believing the same shape from the same start
    /// along the same direction, bit for bit (a sweep over the wall's stiffness, friction
    /// or the gains): where their motion samples are equal too, that lane's foot is reused.
    /// Equal 128-bit fingerprints stand for equal numbers (a false match has odds of about
    /// 2⁻¹²⁸ per pair of lanes).
    twin: Vec<Option<usize>>,
}

fn jet_sample<T: Real>(s: &Sample<T>, l: usize) -> Jet {
    Jet::new(s.value.extract(l), s.rate.extract(l), s.accel.extract(l))
}

impl CurvedBelief {
    /// A 128-bit fingerprint of the numbers fixing the path X_d follows before x_a (the
    /// shape, X0 and t̂₀), bit for bit: two SipHash passes with different keys, streamed
    /// (a scanned part may hold millions of numbers; nothing is copied).
    fn path_fingerprint(&self) -> [u64; 2] {
        let mut hashers = [DefaultHasher::new(), DefaultHasher::new()];
        hashers[1].write_u64(0x9e37_79b9_7f4a_7c15);
        let mut put = |x: &[f64]| {
            for v in x {
                hashers.iter_mut().for_each(|h| h.write_u64(v.to_bits()));
            }
        };
        self.surface.shape_numbers(&mut put);
        put(self.start.as_slice());
        put(self.tangent.as_slice());
        hashers.map(|h| h.finish())
    }
}

impl Belief {
    pub fn new(belief: CurvedBelief) -> Self {
        Self {
            lanes: vec![belief],
            paths: Vec::new(),
            twin: Vec::new(),
        }
    }

    /// The lanes' beliefs, in lane order.
    pub fn pack<'a>(beliefs: impl IntoIterator<Item = &'a Belief>) -> Self {
        let lanes: Vec<CurvedBelief> = beliefs
            .into_iter()
            .flat_map(|b| b.lanes.iter().cloned())
            .collect();
        let mut b = Self {
            paths: lanes.iter().map(CurvedBelief::path_fingerprint).collect(),
            lanes,
            twin: Vec::new(),
        };
        b.find_twins();
        b
    }

    fn find_twins(&mut self) {
        let p = &self.paths;
        self.twin = (0..p.len())
            .map(|l| (0..l).find(|&m| p[m] == p[l]))
            .collect();
    }

    /// Lane `l` takes `b` (a new run's).
    pub fn put_lane(&mut self, l: usize, b: &Belief) {
        if let (Some(slot), Some(new)) = (self.lanes.get_mut(l), b.lanes.first()) {
            *slot = new.clone();
            if let Some(path) = self.paths.get_mut(l) {
                *path = new.path_fingerprint();
            }
            self.find_twins();
        }
    }

    /// X_d, Ẋ_d, Ẍ_d from the filter output x_a and the motion s(t), lane by lane.
    pub fn reference<T: Real>(&self, x_a: &Sample<T>, s: &Sample<T>) -> Desired<T> {
        let mut out = [[[0.0; 3]; 3]; 8];
        let mut feet = [([Jet::default(); 3], [Jet::default(); 3]); 8];
        for (l, (b, o)) in self.lanes.iter().zip(out.iter_mut()).enumerate() {
            let sl = jet_sample(s, l);
            // A twin lane at the same motion sample has this lane's foot already (the same
            // function of the same numbers, so the same bits).
            let same = |m: usize| {
                let sm = jet_sample(s, m);
                [sl.v, sl.d, sl.dd].map(f64::to_bits) == [sm.v, sm.d, sm.dd].map(f64::to_bits)
            };
            let (p, normal) = match self.twin.get(l).copied().flatten() {
                Some(m) if same(m) => feet[m],
                _ => {
                    let y: V3<Jet> = jet::plus(
                        &jet::constant(&b.start),
                        &jet::scaled(&jet::constant(&b.tangent), sl),
                    );
                    b.surface.foot(&y)
                }
            };
            feet[l] = (p, normal);
            let x = jet::plus(&p, &jet::scaled(&normal, jet_sample(x_a, l)));
            *o = [x.map(|j| j.v), x.map(|j| j.d), x.map(|j| j.dd)];
        }
        let v = |k: usize| Vector3::from_fn(|i, _| T::from_lanes(|l| out[l][k][i]));
        Desired {
            position: v(0),
            velocity: v(1),
            acceleration: v(2),
        }
    }

    /// The estimate's inward normal n̂ at the tip X (the force direction), lane by lane.
    pub fn normal_at<T: Real>(&self, tip: &Vector3<T>) -> Vector3<T> {
        let mut out = [[0.0; 3]; 8];
        for (l, (b, o)) in self.lanes.iter().zip(out.iter_mut()).enumerate() {
            let x = [tip[0].extract(l), tip[1].extract(l), tip[2].extract(l)];
            *o = b.surface.depth_normal(&x).1;
        }
        Vector3::from_fn(|i, _| T::from_lanes(|l| out[l][i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::task::{motion_direction, TaskFrame};
    use crate::world::round::SphereParams;
    use crate::world::surface::SurfaceParams;

    fn sample(value: f64, rate: f64, accel: f64) -> Sample {
        Sample { value, rate, accel }
    }

    /// On a sphere the reference stays at depth x_a below the surface, and its derivatives
    /// are those of the position (central differences of the jets' values).
    #[test]
    fn a_sphere_reference_follows_the_surface_with_exact_derivatives() {
        let start = TaskVector::new(0.7, 0.0, 0.9);
        let p = SurfaceParams::Sphere(SphereParams {
            radius: 0.2,
            normal: [1.0, 0.0, 0.0],
            ..SphereParams::default()
        });
        let surface = p.believed(&start).unwrap();
        let n0 = surface.normal();
        let b = Belief::new(CurvedBelief {
            surface,
            start,
            tangent: motion_direction(&n0),
        });
        let centre = start + n0 * 0.2;
        let at = |t: f64| {
            let s = sample(0.05 * t.sin(), 0.05 * t.cos(), -0.05 * t.sin());
            let x_a = sample(1e-3 * t, 1e-3, 0.0);
            b.reference(&x_a, &s)
        };
        for t in [0.3, 1.1, 2.0] {
            let d = at(t);
            // |X_d − c| = R − x_a.
            assert!(((d.position - centre).norm() - (0.2 - 1e-3 * t)).abs() < 1e-15);
            let h = 1e-5;
            let (a, z) = (at(t - h), at(t + h));
            let v = (z.position - a.position) / (2.0 * h);
            let acc = (z.velocity - a.velocity) / (2.0 * h);
            assert!((v - d.velocity).norm() < 1e-9, "{v} {}", d.velocity);
            assert!((acc - d.acceleration).norm() < 1e-7);
        }
        // The normal at a tip on the line to the centre is that line.
        let tip = start + TaskVector::new(0.0, 0.0, 0.05);
        let n = b.normal_at(&tip);
        assert!((n - (centre - tip).normalize()).norm() < 1e-15);
    }

    /// In a lane group, lanes believing the same height field (laws aside) share the foot
    /// where their motion samples agree, and every lane's reference is bit for bit the one
    /// it has alone, shared or not.
    #[test]
    fn lanes_share_a_foot_only_where_it_is_the_same() {
        use crate::scalar::F64x4;
        use crate::world::height_field::HeightFieldParams;
        use nalgebra::SimdValue;
        let start = TaskVector::new(0.7, 0.1, 0.9);
        let field = |bend: f64, stiffness: f64| {
            let heights: Vec<Vec<f64>> = (0..9)
                .map(|i| {
                    (0..9)
                        .map(|j| bend * ((i * i + 2 * j * j) as f64))
                        .collect()
                })
                .collect();
            let p = SurfaceParams::HeightField(HeightFieldParams {
                heights: heights.into(),
                stiffness,
                ..Default::default()
            });
            let surface = p.believed(&start).unwrap();
            let tangent = motion_direction(&surface.normal());
            Belief::new(CurvedBelief {
                surface,
                start,
                tangent,
            })
        };
        // Lanes 0, 1 and 3 believe one shape (their walls' stiffness differs); lane 2 not.
        let alone = [
            field(1e-4, 1e4),
            field(1e-4, 2e4),
            field(2e-4, 1e4),
            field(1e-4, 3e4),
        ];
        let group = Belief::pack(alone.iter());
        assert_eq!(group.twin, vec![None, Some(0), None, Some(0)]);
        let mut moved = group.clone();
        moved.put_lane(0, &alone[2]);
        assert_eq!(moved.twin, vec![None, None, Some(0), Some(1)]);
        // Lane 3's motion differs from lane 0's: its foot is its own.
        let at = [0.010, 0.010, 0.010, 0.013];
        let lanes = |f: fn(f64) -> f64| F64x4::from_lanes(|l| f(at[l]));
        let s = Sample::<F64x4> {
            value: lanes(|x| x),
            rate: lanes(|x| 2.0 * x),
            accel: lanes(|x| -x),
        };
        let x_a = Sample::<F64x4> {
            value: F64x4::from_lanes(|l| 1e-3 * l as f64),
            rate: F64x4::from_lanes(|_| 0.0),
            accel: F64x4::from_lanes(|_| 0.0),
        };
        let d = group.reference(&x_a, &s);
        for (l, b) in alone.iter().enumerate() {
            let (x_a, s) = (
                sample(x_a.value.extract(l), 0.0, 0.0),
                Sample {
                    value: s.value.extract(l),
                    rate: s.rate.extract(l),
                    accel: s.accel.extract(l),
                },
            );
            let r = b.reference(&x_a, &s);
            for (group, own) in [
                (&d.position, &r.position),
                (&d.velocity, &r.velocity),
                (&d.acceleration, &r.acceleration),
            ] {
                for i in 0..3 {
                    assert_eq!(group[i].extract(l).to_bits(), own[i].to_bits(), "lane {l}");
                }
            }
        }
    }

    /// A plane as a belief is the task frame's formula.
    #[test]
    fn a_plane_belief_is_the_frame() {
        let start = TaskVector::new(0.7, 0.1, 0.9);
        let p = SurfaceParams::Plane(crate::world::environment::WallParams {
            normal: [1.0, 0.0, -0.5],
            position_error: 0.003,
            ..Default::default()
        });
        let surface = p.believed(&start).unwrap();
        let n = surface.normal();
        let (_, x, _) = surface.tangent_plane().unwrap();
        let frame = TaskFrame::new(n, start, x);
        let b = Belief::new(CurvedBelief {
            surface,
            start,
            tangent: frame.tangent,
        });
        let (x_a, s) = (sample(2e-3, 0.1, -0.3), sample(0.04, 0.05, 0.2));
        let (d, f) = (b.reference(&x_a, &s), frame.force_reference(&x_a, &s));
        assert!((d.position - f.position).norm() < 1e-15);
        assert!((d.velocity - f.velocity).norm() < 1e-15);
        assert!((d.acceleration - f.acceleration).norm() < 1e-15);
    }
}
