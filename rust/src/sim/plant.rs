//! The plant: the true arm against the environment, integrated by fixed-step RK4 with
//! substeps while the applied torque is held (zero-order hold, SPEC §6). The environment's
//! force is evaluated inside every RK4 stage from that stage's state.

use nalgebra::SVector;

use crate::contact::Surface;
use crate::robot::{ArmModel, ConfigOf, JointVector, RobotModel};
use crate::scalar::Real;
use crate::world::surface::{Environment, SurfaceVisitor};

/// Whether this CPU runs the AVX2 + FMA builds of the step loop (`Plant::advance`,
/// `Simulation::run`). std caches the answer, so asking costs a load and a branch.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn has_avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// Joint positions and velocities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantState<const N: usize> {
    pub q: JointVector<N>,
    pub qd: JointVector<N>,
}

/// The true arm and environment. Owns the state; `advance` moves it one control period.
#[derive(Debug, Clone)]
pub struct Plant<R: RobotModel<N>, const N: usize> {
    arm: R,
    environment: Environment,
    substeps: usize,
    substep: f64,
    initial: PlantState<N>,
    state: PlantState<N>,
    /// The arm's per-configuration values at `state.q`, shared by the measurement, a
    /// controller's model and the next period's first RK4 stage.
    config: ConfigOf<R, N>,
}

impl<R: RobotModel<N>, const N: usize> Plant<R, N> {
    pub fn new(
        arm: R,
        environment: Environment,
        initial: PlantState<N>,
        period: f64,
        substeps: usize,
    ) -> Self {
        let config = arm.model().configure(&initial.q);
        Self {
            arm,
            environment,
            substeps,
            substep: period / substeps as f64,
            initial,
            state: initial,
            config,
        }
    }

    pub fn reset(&mut self) {
        self.set_state(self.initial);
    }

    pub fn arm(&self) -> &R {
        &self.arm
    }

    /// What the tip touches.
    pub fn environment(&self) -> &Environment {
        &self.environment
    }

    #[inline]
    pub fn state(&self) -> &PlantState<N> {
        &self.state
    }

    pub fn set_state(&mut self, state: PlantState<N>) {
        self.state = state;
        self.config = self.arm.model().configure(&state.q);
    }

    /// The state, joint by joint, its configuration values left stale until
    /// [`Self::refresh_config`]: for the lanes, which evaluate theirs from the packed state
    /// and never read each plant's.
    #[inline(always)]
    pub(crate) fn write_state(&mut self, q: impl Fn(usize) -> f64, qd: impl Fn(usize) -> f64) {
        for j in 0..N {
            self.state.q[j] = q(j);
            self.state.qd[j] = qd(j);
        }
    }

    /// The configuration values of the current state, after [`Self::set_state_deferred`].
    pub(crate) fn refresh_config(&mut self) {
        self.config = self.arm.model().configure(&self.state.q);
    }

    /// Stage 1: the tip kinematics at the current state (what the robot's encoders give)
    /// and, for a pose task (`pose`), the tip's orientation terms.
    #[inline(always)]
    pub fn measure(
        &self,
        pose: bool,
    ) -> (
        crate::robot::Kinematics<N>,
        Option<crate::robot::Orientation<N>>,
    ) {
        self.arm.model().measure(&self.config, &self.state.qd, pose)
    }

    /// The tip frame's rotation at the current state (a tip-frame sensor's R).
    pub fn tip_rotation(&self) -> nalgebra::Matrix3<f64> {
        self.arm.model().tip_rotation(&self.config)
    }

    /// One control period: `substeps` classical RK4 steps with τ held.
    ///
    /// Dispatched like `Simulation::run` (AVX2 + FMA code when the CPU has them, baseline
    /// x86-64 otherwise; the same bits either way), for callers that step a plant alone.
    #[inline]
    pub fn advance(&mut self, tau: &JointVector<N>) {
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: the features `advance_avx2` is compiled for were detected just above.
            return unsafe { self.advance_avx2(tau) };
        }
        self.advance_inlined(tau)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn advance_avx2(&mut self, tau: &JointVector<N>) {
        self.advance_inlined(tau)
    }

    /// `advance` without the dispatch, for `Simulation`, which dispatches its whole step
    /// loop once and inlines this into it.
    #[inline(always)]
    pub(crate) fn advance_inlined(&mut self, tau: &JointVector<N>) {
        let (q, qd) = rk4_period_on(
            self.arm.model(),
            &self.environment,
            (self.state.q, self.state.qd),
            self.config,
            self.substep,
            self.substeps,
            tau,
        );
        // A fresh evaluation, so angle-addition rounding never outlives a period.
        self.set_state(PlantState { q, qd });
    }

    /// Substeps per period.
    pub(crate) fn substeps(&self) -> usize {
        self.substeps
    }

    /// The substep h [s].
    pub(crate) fn substep(&self) -> f64 {
        self.substep
    }

    /// The arm's per-configuration values at the current state.
    pub(crate) fn config(&self) -> &ConfigOf<R, N> {
        &self.config
    }
}

/// What RK4 needs of a plant, over any scalar (one run, or runs in SIMD lanes).
pub(crate) trait Stages<T: Real, const N: usize> {
    /// The arm's per-configuration values (its trig).
    type Config: Copy;

    /// q̈ at a stage whose configuration values are `c`, with τ held.
    fn acceleration(
        &self,
        c: &Self::Config,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
    ) -> SVector<T, N>;

    /// The values at `shifted` = q + `delta`, given those at q, into `out`.
    fn shift(
        &self,
        c: &Self::Config,
        delta: &SVector<T, N>,
        shifted: &SVector<T, N>,
        out: &mut Self::Config,
    );
}

/// An arm against one surface (of a known type), as RK4's stages see it, over any scalar.
pub(crate) struct Touching<'a, A, S> {
    arm: &'a A,
    surface: &'a S,
}

impl<T: Real, A: ArmModel<T, N>, S: Surface<T>, const N: usize> Stages<T, N>
    for Touching<'_, A, S>
{
    type Config = A::Config;

    #[inline(always)]
    fn acceleration(
        &self,
        c: &A::Config,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
    ) -> SVector<T, N> {
        self.arm.accelerate(c, qd, tau, self.surface).0
    }

    #[inline(always)]
    fn shift(
        &self,
        c: &A::Config,
        delta: &SVector<T, N>,
        shifted: &SVector<T, N>,
        out: &mut A::Config,
    ) {
        self.arm.configure_shifted(c, delta, shifted, out);
    }
}

/// One control period of `arm` against `environment` ([`rk4_period`]), the environment
/// matched once per period ([`Environment::visit`]): a plane runs an RK4 loop holding only
/// the plane's contact code; any other environment, one loop shared by them all.
#[inline(always)]
pub(crate) fn rk4_period_on<T: Real, A: ArmModel<T, N>, const N: usize>(
    arm: &A,
    environment: &Environment<T>,
    start: (SVector<T, N>, SVector<T, N>),
    config: A::Config,
    h: T,
    substeps: usize,
    tau: &SVector<T, N>,
) -> (SVector<T, N>, SVector<T, N>) {
    struct Period<'a, T: Real, A: ArmModel<T, N>, const N: usize> {
        arm: &'a A,
        start: (SVector<T, N>, SVector<T, N>),
        config: A::Config,
        h: T,
        substeps: usize,
        tau: &'a SVector<T, N>,
    }
    impl<T: Real, A: ArmModel<T, N>, const N: usize> SurfaceVisitor<T> for Period<'_, T, A, N> {
        type Output = (SVector<T, N>, SVector<T, N>);
        // Inlined where optimised (into the AVX2 loops, whose features an out-of-line
        // copy would lose). Not in a debug build: there the inlined periods of every arm
        // of the match share one stack frame without overlapping, which overflowed a test
        // thread's stack on a chain's kilobyte-sized stage values.
        #[cfg_attr(not(debug_assertions), inline(always))]
        #[cfg_attr(debug_assertions, inline(never))]
        fn visit<S: Surface<T>>(self, surface: &S) -> Self::Output {
            let stages = Touching {
                arm: self.arm,
                surface,
            };
            rk4_period(
                &stages,
                self.start,
                self.config,
                self.h,
                self.substeps,
                self.tau,
            )
        }
    }
    environment.visit(Period {
        arm,
        start,
        config,
        h,
        substeps,
        tau,
    })
}

/// One control period of `substeps` classical RK4 steps of `h` from `(q, q̇)` with τ held,
/// over any scalar. `config` is the arm's values at q. Returns the new (q, q̇).
#[inline(always)]
pub(crate) fn rk4_period<T: Real, S: Stages<T, N>, const N: usize>(
    stages: &S,
    (mut q, mut qd): (SVector<T, N>, SVector<T, N>),
    config: S::Config,
    h: T,
    substeps: usize,
    tau: &SVector<T, N>,
) -> (SVector<T, N>, SVector<T, N>) {
    let (two, six) = (T::splat(2.0), T::splat(6.0));
    // The stages' values are written into one buffer (a chain's are kilobytes: returned by
    // value they were copied at every stage); the next substep's start is copied back once.
    let mut c1 = config;
    let mut stage = config;
    for _ in 0..substeps {
        let a1 = stages.acceleration(&c1, &qd, tau);
        let (d2, qd2) = (qd * (h / two), qd + a1 * (h / two));
        stages.shift(&c1, &d2, &(q + d2), &mut stage);
        let a2 = stages.acceleration(&stage, &qd2, tau);
        let (d3, qd3) = (qd2 * (h / two), qd + a2 * (h / two));
        stages.shift(&c1, &d3, &(q + d3), &mut stage);
        let a3 = stages.acceleration(&stage, &qd3, tau);
        let (d4, qd4) = (qd3 * h, qd + a3 * h);
        stages.shift(&c1, &d4, &(q + d4), &mut stage);
        let a4 = stages.acceleration(&stage, &qd4, tau);
        let dq = (qd + (qd2 + qd3) * two + qd4) * (h / six);
        q += dq;
        stages.shift(&c1, &dq, &q, &mut stage);
        c1 = stage;
        qd += (a1 + (a2 + a3) * two + a4) * (h / six);
    }
    (q, qd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::three_link::{Trig, Vec3};
    use crate::robot::{RobotParams, ThreeLinkArm};
    use crate::world::environment::{ContactModel, Wall, WallParams};

    /// RK4 is fourth order: halving the step cuts the error ~16×.
    #[test]
    fn fourth_order_convergence() {
        // Smooth dynamics: tanh(q̇/0.01) friction is stiff enough to hide the order.
        let p = RobotParams {
            coulomb_friction: [0.0; 3],
            ..RobotParams::default()
        };
        let start = PlantState {
            q: Vec3::from(p.q0),
            qd: Vec3::new(0.5, -0.3, 0.2),
        };
        let run = |substeps: usize| {
            let mut plant = Plant::new(
                ThreeLinkArm::new(&p),
                Environment::Free,
                start,
                0.01,
                substeps,
            );
            for _ in 0..20 {
                plant.advance(&Vec3::new(1.0, 40.0, 8.0));
            }
            plant.state().q
        };
        let reference = run(256);
        let e1 = (run(4) - reference).norm();
        let e2 = (run(8) - reference).norm();
        let ratio = e1 / e2;
        assert!(ratio > 13.0 && ratio < 19.0, "ratio {ratio}");
    }

    /// The arm at q0 with the wall 2 mm inside the tip, starting at `qd`.
    fn pressed_into_wall(qd: Vec3) -> (ThreeLinkArm, Wall, PlantState<3>) {
        pressed_into(&WallParams::default(), qd)
    }

    fn pressed_into(p: &WallParams, qd: Vec3) -> (ThreeLinkArm, Wall, PlantState<3>) {
        let arm = ThreeLinkArm::new(&RobotParams::default());
        let q = arm.initial_position();
        let mut wall = Wall::new(p, &arm.forward_kinematics(&q)).unwrap();
        wall.position -= 0.002;
        (arm, wall, PlantState { q, qd })
    }

    /// A shoulder torque below gravity's, so the arm sags into the wall, with a slow wobble.
    fn sagging_torque(period: usize, yaw: f64) -> Vec3 {
        Vec3::new(yaw, 45.0 + 5.0 * (period as f64 * 0.01).sin(), 10.0)
    }

    /// Classical RK4 written out, `substeps` steps of `h` with τ held: the reference the
    /// plant is checked against.
    fn textbook_rk4(
        f: &impl Fn(&Vec3, &Vec3, &Vec3) -> Vec3,
        mut q: Vec3,
        mut qd: Vec3,
        t: &Vec3,
        h: f64,
        substeps: usize,
    ) -> (Vec3, Vec3) {
        for _ in 0..substeps {
            let a1 = f(&q, &qd, t);
            let (q2, qd2) = (q + qd * (h / 2.0), qd + a1 * (h / 2.0));
            let a2 = f(&q2, &qd2, t);
            let (q3, qd3) = (q + qd2 * (h / 2.0), qd + a2 * (h / 2.0));
            let a3 = f(&q3, &qd3, t);
            let (q4, qd4) = (q + qd3 * h, qd + a3 * h);
            let a4 = f(&q4, &qd4, t);
            q += (qd + (qd2 + qd3) * 2.0 + qd4) * (h / 6.0);
            qd += (a1 + (a2 + a3) * 2.0 + a4) * (h / 6.0);
        }
        (q, qd)
    }

    /// The plant's RK4 (stage trig by angle addition) against a textbook RK4 that evaluates
    /// sin and cos afresh at every stage: one second of fig. 14-like motion, with contact.
    #[test]
    fn matches_textbook_rk4() {
        let (arm, wall, start) = pressed_into_wall(Vec3::new(0.0, 0.4, -0.6));
        let tau = |k: usize| sagging_torque(k, 0.0);
        let (h, substeps) = (1e-4, 10);
        let mut plant = Plant::new(
            arm.clone(),
            Environment::Plane(wall),
            start,
            h * 10.0,
            substeps,
        );
        let (mut q, mut qd) = (start.q, start.qd);
        let mut contact_periods = 0;
        let f =
            |q: &Vec3, qd: &Vec3, t: &Vec3| arm.model().accelerate(&Trig::new(q), qd, t, &wall).0;
        for k in 0..1000 {
            let t = tau(k);
            plant.advance(&t);
            if wall.force(&arm.forward_kinematics(&q), &Vec3::zeros()) > 0.0 {
                contact_periods += 1;
            }
            (q, qd) = textbook_rk4(&f, q, qd, &t, h, substeps);
        }
        let s = plant.state();
        assert!(
            contact_periods > 100,
            "in contact for {contact_periods} periods"
        );
        assert!((s.q - q).abs().max() < 1e-14, "{}", (s.q - q).abs().max());
        assert!(
            (s.qd - qd).abs().max() < 1e-14,
            "{}",
            (s.qd - qd).abs().max()
        );
    }

    /// The closed-form stage (contact through Jᵀ n, Coulomb friction last) against the
    /// generic path: J q̇ for the wall's rate, F = −f n, and eq. (1) solved from D, C, G.
    /// A damped wall tilted 30° about y, one second with contact.
    #[test]
    fn closed_form_stage_matches_the_generic_one_on_a_damped_tilted_wall() {
        let a = 30f64.to_radians();
        let p = WallParams {
            normal: [a.cos(), 0.0, -a.sin()],
            damping: 50.0,
            model: ContactModel::KelvinVoigt,
            ..WallParams::default()
        };
        let (arm, wall, start) = pressed_into(&p, Vec3::new(0.0, 0.4, -0.6));
        let (h, substeps) = (1e-4, 10);
        let mut plant = Plant::new(
            arm.clone(),
            Environment::Plane(wall),
            start,
            h * 10.0,
            substeps,
        );
        let f = |q: &Vec3, qd: &Vec3, t: &Vec3| {
            let c = Trig::new(q);
            let k = arm.model().kinematics(&c, qd);
            let force = wall.force(&k.position, &(k.jacobian * qd));
            arm.model()
                .forward_dynamics(&c, qd, t, &(wall.normal * -force))
        };
        let (mut q, mut qd) = (start.q, start.qd);
        let mut contact_periods = 0;
        for k in 0..1000 {
            let t = sagging_torque(k, 0.0);
            plant.advance(&t);
            if wall.penetration(&arm.forward_kinematics(&q)) > 0.0 {
                contact_periods += 1;
            }
            (q, qd) = textbook_rk4(&f, q, qd, &t, h, substeps);
        }
        assert!(contact_periods > 100, "{contact_periods}");
        let s = plant.state();
        assert!((s.q - q).abs().max() < 1e-11, "{}", (s.q - q).abs().max());
        assert!(
            (s.qd - qd).abs().max() < 1e-9,
            "{}",
            (s.qd - qd).abs().max()
        );
    }

    /// The AVX2 + FMA build of `advance` (taken on this machine when the CPU has them) and
    /// the baseline build give the same bits.
    #[test]
    fn instruction_sets_agree_bit_for_bit() {
        let (arm, wall, start) = pressed_into_wall(Vec3::new(0.1, 0.4, -0.6));
        let mut dispatched = Plant::new(arm, Environment::Plane(wall), start, 1e-3, 10);
        let mut baseline = dispatched.clone();
        for k in 0..500 {
            let tau = sagging_torque(k, 0.5);
            dispatched.advance(&tau);
            baseline.advance_inlined(&tau);
            assert_eq!(dispatched.state(), baseline.state(), "period {k}");
        }
    }

    /// Holding exactly the gravity torque keeps the arm at rest (friction is zero at q̇ = 0).
    #[test]
    fn gravity_torque_holds_still() {
        let arm = ThreeLinkArm::new(&RobotParams::default());
        let q0 = arm.initial_position();
        let g = arm
            .model()
            .dynamics(&Trig::new(&q0), &Vec3::zeros())
            .gravity;
        let start = PlantState {
            q: q0,
            qd: Vec3::zeros(),
        };
        let mut plant = Plant::new(arm, Environment::Free, start, 1e-3, 10);
        for _ in 0..1000 {
            plant.advance(&g);
        }
        assert!((plant.state().q - q0).abs().max() < 1e-12);
    }
}
