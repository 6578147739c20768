//! The environment: a unilateral spring wall normal to x (SPEC §2).

use crate::error::{check, Result};

/// Wall parameters. The controller never sees `stiffness` or `position`; it is told
/// `position + position_error`.
#[derive(Debug, Clone, PartialEq)]
pub struct WallParams {
    /// Environment stiffness k_e [N/m]. Default 30 000.
    pub stiffness: f64,
    /// Wall position x_e [m]; `None` means the tip's x at q0 (touching with zero force).
    pub position: Option<f64>,
    /// Error of the controller's estimate: x̂_e = x_e + position_error [m]. Default 0.
    pub position_error: f64,
}

impl Default for WallParams {
    fn default() -> Self {
        Self {
            stiffness: 30_000.0,
            position: None,
            position_error: 0.0,
        }
    }
}

impl WallParams {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("stiffness", self.stiffness)?;
        if let Some(x) = self.position {
            check::finite("position", x)?;
        }
        check::finite("position_error", self.position_error)
    }
}

/// A wall with its position resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall {
    pub stiffness: f64,
    pub position: f64,
    pub position_error: f64,
}

impl Wall {
    pub fn new(p: &WallParams, x_at_q0: f64) -> Self {
        Self {
            stiffness: p.stiffness,
            position: p.position.unwrap_or(x_at_q0),
            position_error: p.position_error,
        }
    }

    /// Contact force f = k_e (x − x_e) while x > x_e, else 0 (the sensor reads it exactly).
    #[inline]
    pub fn force(&self, x: f64) -> f64 {
        let penetration = x - self.position;
        if penetration > 0.0 {
            self.stiffness * penetration
        } else {
            0.0
        }
    }

    /// x̂_e: where the controller believes the wall is.
    #[inline]
    pub fn estimated_position(&self) -> f64 {
        self.position + self.position_error
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unilateral_spring() {
        let w = Wall::new(&WallParams::default(), 0.5);
        assert_eq!(w.force(0.4), 0.0);
        assert_eq!(w.force(0.5), 0.0);
        assert!((w.force(0.5001) - 3.0).abs() < 1e-9);
        let w = Wall::new(
            &WallParams {
                position: Some(0.7),
                position_error: 0.01,
                ..WallParams::default()
            },
            0.5,
        );
        assert_eq!(w.position, 0.7);
        assert!((w.estimated_position() - 0.71).abs() < 1e-15);
    }

    #[test]
    fn negative_stiffness_rejected() {
        let p = WallParams {
            stiffness: -1.0,
            ..WallParams::default()
        };
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("stiffness = -1"));
    }
}
