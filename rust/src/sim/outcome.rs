//! How a run ended: completed, or diverged with when and why; and, for `substeps = "auto"`,
//! the count its search chose (`sim::substep_choice`) and how that search ended.

use crate::error::approx;

/// Below this observed order the runs are not converging (a run is accepted only above it:
/// first order, a switch inside a substep, still converges).
pub const MIN_ORDER: f64 = 0.5;
/// The most substeps `"auto"` tries.
pub const MAX_AUTO_SUBSTEPS: usize = 256;

/// Why a run stopped early.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Divergence {
    /// A joint position or velocity became NaN or infinite.
    NonFiniteState,
    /// The control law produced a NaN or infinite torque.
    NonFiniteTorque,
    /// |q̇_joint| reached the velocity limit.
    VelocityLimit { joint: usize, velocity: f64 },
    /// The Jacobian became singular, so the control law has no answer.
    SingularJacobian,
}

impl std::fmt::Display for Divergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Divergence::NonFiniteState => write!(f, "joint state became non-finite"),
            Divergence::NonFiniteTorque => write!(f, "control torque became non-finite"),
            Divergence::VelocityLimit { joint, velocity } => write!(
                f,
                "joint {} velocity {} rad/s reached the velocity limit",
                joint + 1,
                approx(*velocity)
            ),
            Divergence::SingularJacobian => {
                write!(
                    f,
                    "the Jacobian became singular (arm at a kinematic singularity)"
                )
            }
        }
    }
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    Completed,
    /// Stopped at `time` [s]; the trace holds every sample before it.
    Diverged {
        time: f64,
        cause: Divergence,
    },
}

impl Outcome {
    pub fn is_diverged(&self) -> bool {
        matches!(self, Outcome::Diverged { .. })
    }
}

/// How the search ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Standing {
    /// The chosen count's estimated error is within the tolerance.
    Met,
    /// The run diverged at both counts of the last pair and their traces differ by more
    /// than the tolerance: more substeps move when the loop diverges, not whether.
    Diverged,
    /// The traces stopped converging as the count grew (observed order below 0.5 twice in a
    /// row: a bouncing or chaotic contact has no trace to converge to).
    NotConverging,
    /// [`MAX_AUTO_SUBSTEPS`] did not meet the tolerance.
    Limit,
    /// No run tried had any contact force (a position-only run, a surface never touched):
    /// a tolerance in newtons cannot judge them, so the run is the default count's.
    NotAssessed,
}

impl Standing {
    pub fn name(self) -> &'static str {
        match self {
            Standing::Met => "met",
            Standing::Diverged => "diverged",
            Standing::NotConverging => "not converging",
            Standing::Limit => "limit",
            Standing::NotAssessed => "not assessed",
        }
    }
}

/// What `"auto"` chose for one run.
#[derive(Debug, Clone, PartialEq)]
pub struct SubstepChoice {
    /// The count of the run returned.
    pub substeps: usize,
    /// Its estimated largest error on f and f_t over the run [N]; for a run that does not
    /// converge or diverges, the difference between its two finest runs (infinite when
    /// they did not take the same samples).
    pub error: f64,
    pub tolerance: f64,
    pub standing: Standing,
    /// The convergence order the estimate used (the observed one, at most 4); NaN when two
    /// runs agreed so closely that none was needed (the estimate credits the slowest, 0.5).
    pub order: f64,
    /// The counts run, in order.
    pub tried: Vec<usize>,
}

impl SubstepChoice {
    pub fn met(&self) -> bool {
        self.standing == Standing::Met
    }

    /// One sentence a user reads: the count, the estimate and, when unmet, why.
    pub fn describe(&self) -> String {
        let tried = self
            .tried
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(", ");
        let (n, e, tol, p) = (
            self.substeps,
            approx(self.error),
            approx(self.tolerance),
            self.order,
        );
        match self.standing {
            Standing::Met if p.is_nan() => format!(
                "substeps=\"auto\" chose {n}: estimated force error {e} N <= tolerance {tol} N \
                 (Richardson at the slowest order credited, {MIN_ORDER}; tried {tried})"
            ),
            Standing::Met => format!(
                "substeps=\"auto\" chose {n}: estimated force error {e} N <= tolerance {tol} N \
                 (Richardson, observed order {p:.1}; tried {tried})"
            ),
            Standing::Diverged => format!(
                "substeps=\"auto\": the run diverges at every count tried, so its trace has \
                 no error bound (its two finest runs differ by {e} N, tolerance {tol} N); \
                 this is the finest run, {n} substeps (tried {tried})"
            ),
            Standing::NotConverging => format!(
                "substeps=\"auto\": the traces stopped converging as substeps grew (a \
                 bouncing or chaotic contact), so the tolerance is not met: the two finest \
                 runs differ by {e} N, tolerance {tol} N; this is the finest run, {n} \
                 substeps (tried {tried})"
            ),
            Standing::Limit => format!(
                "substeps=\"auto\" reached {n} substeps without meeting the tolerance: \
                 estimated force error {e} N, tolerance {tol} N (observed order {p:.1}; \
                 tried {tried})"
            ),
            Standing::NotAssessed => format!(
                "substeps=\"auto\" could not assess the tolerance: no run tried had any \
                 contact force, and the tolerance {tol} N is on the force trace; this is \
                 the default count, {n} substeps (tried {tried}); fix `substeps` to a count \
                 whose positions and torques you have checked"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The velocity in a cause keeps six significant figures at any magnitude: 1e300 in a
    /// few characters (`{:.2}` wrote 303), 0.004 not as "0.00".
    #[test]
    fn velocities_print_short() {
        let cause = |velocity| Divergence::VelocityLimit { joint: 1, velocity }.to_string();
        assert_eq!(
            cause(-1e300 / 3.0),
            "joint 2 velocity -3.33333e299 rad/s reached the velocity limit"
        );
        assert_eq!(
            cause(0.004_252_391),
            "joint 2 velocity 0.00425239 rad/s reached the velocity limit"
        );
        assert_eq!(
            cause(113.4291),
            "joint 2 velocity 113.429 rad/s reached the velocity limit"
        );
    }
}
