//! How a run ended: completed, or diverged with when and why.

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
                "joint {} velocity {velocity:.2} rad/s reached the velocity limit",
                joint + 1
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
