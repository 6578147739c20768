//! How a run ended: completed, or diverged with when and why.

use crate::error::approx;

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
