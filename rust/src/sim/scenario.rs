//! What defines one run: the scenario's parameters and their validation.

use crate::control::approach::ApproachParams;
use crate::control::filter::ForceControlParams;
use crate::control::params::ControllerParams;
use crate::control::reference::Signal;
use crate::error::{check, short, Error, Result};
use crate::robot::chain::UrdfArmParams;
use crate::robot::RobotParams;
use crate::sim::criteria::CriteriaParams;
use crate::world::actuator::ActuatorParams;
use crate::world::height_field::HeightsInterner;
use crate::world::sensor::SensorParams;
use crate::world::surface::SurfaceParams;

/// Largest run accepted, in samples: a trace this long already takes ~1.5 GB.
pub const MAX_SAMPLES: usize = 10_000_000;
/// RK4 substeps per period unless a scenario says otherwise (and `"auto"`'s count when no
/// run it tried touched anything).
pub const DEFAULT_SUBSTEPS: usize = 10;

/// Largest number of RK4 substeps per control period.
pub const MAX_SUBSTEPS: usize = 10_000;

/// The arm: the paper's three-link arm in closed form, or a serial chain from a URDF.
/// Tagged by `kind` (`"three_link"`, `"urdf"`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum RobotConfig {
    ThreeLink(RobotParams),
    Urdf(UrdfArmParams),
}

impl Default for RobotConfig {
    fn default() -> Self {
        RobotConfig::ThreeLink(RobotParams::default())
    }
}

impl From<RobotParams> for RobotConfig {
    fn from(p: RobotParams) -> Self {
        RobotConfig::ThreeLink(p)
    }
}

impl RobotConfig {
    /// Checks the parameters (parsing the URDF) and returns the joint count.
    pub fn validate(&self) -> Result<usize> {
        match self {
            RobotConfig::ThreeLink(p) => p.validate().map(|()| 3),
            RobotConfig::Urdf(p) => p.dof(),
        }
    }

    /// The three-link arm's parameters, if that is the arm.
    pub fn three_link(&self) -> Option<&RobotParams> {
        match self {
            RobotConfig::ThreeLink(p) => Some(p),
            RobotConfig::Urdf(_) => None,
        }
    }
}

/// Everything that defines one run. Defaults are the paper preset of fig. 14.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ScenarioConfig {
    /// The arm (plant): the paper's three-link arm or a URDF arm.
    pub robot: RobotConfig,
    /// The surface the tool touches (SPEC §15): Wall, Sphere, Cylinder or HeightField; ``None``: free space.
    pub wall: Option<SurfaceParams>,
    /// The controller's belief about the surface (SPEC §15): force along its normal n̂, motion along its tangent, x̂_e its position + position_error; its stiffness and damping are not read. ``None``: the true wall offset by its position_error.
    pub wall_estimate: Option<SurfaceParams>,
    /// The inner position loop: ComputedTorque, ModelFree or TimeDelayControl.
    pub controller: ControllerParams,
    /// The outer force loop; ``None`` is position-only control (x held at X0 x).
    pub admittance: Option<ForceControlParams>,
    /// A guarded approach (SPEC §16) before force control takes over; ``None``: force control from t = 0.
    pub approach: Option<ApproachParams>,
    /// Desired contact force f_d(t) [N].
    pub force_reference: Signal,
    /// Desired motion s(t) along t̂ from the start [m]; z_d = z0 + s(t) for the paper's wall.
    pub z_reference: Signal,
    /// The force sensor; the default reads the force exactly.
    pub sensor: SensorParams,
    /// The motors; the default applies the command exactly.
    pub actuator: ActuatorParams,
    /// Seed of the sensor noise (0 to 2^53). Sweeps derive each run's from (seed, run_id).
    #[serde(deserialize_with = "crate::schema::fields::seed")]
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 1000.0, "scale": "linear", "unit": ""}))]
    pub seed: u64,
    /// Controller period T [s].
    pub period: f64,
    /// RK4 substeps per period (1 to 10000), or ``"auto"``: the fewest whose force trace is within ``tolerance`` of the exact one, estimated by comparing whole runs (Richardson, docs/substeps.md).
    pub substeps: Substeps,
    /// Largest error [N] on the force trace (f and f_t at every sample) that ``substeps="auto"`` accepts; not read for a fixed count.
    pub tolerance: f64,
    /// Run length [s], a multiple of ``period``.
    #[schemars(extend("x-ui" = {"min": 0.5, "max": 30.0, "scale": "linear", "step": 0.5}))]
    pub duration: f64,
    /// A run stops as unstable when any |q̇| reaches this [rad/s].
    pub velocity_limit: f64,
    /// What a run must meet to be called stable (SPEC §17).
    pub criteria: CriteriaParams,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        Self {
            robot: RobotConfig::default(),
            wall: Some(SurfaceParams::default()),
            wall_estimate: None,
            controller: ControllerParams::TimeDelay(Default::default()),
            admittance: Some(ForceControlParams::Admittance(Default::default())),
            approach: None,
            force_reference: Signal::Step {
                value: 10.0,
                time: 0.0,
                initial: 0.0,
            },
            z_reference: Signal::Sine {
                offset: 0.0,
                amplitude: 0.05,
                omega: 1.0,
                phase: 0.0,
            },
            sensor: SensorParams::default(),
            actuator: ActuatorParams::default(),
            seed: 0,
            period: 1e-3,
            substeps: Substeps::Count(DEFAULT_SUBSTEPS),
            tolerance: 1e-4,
            duration: 10.0,
            velocity_limit: 100.0,
            criteria: CriteriaParams::default(),
        }
    }
}

impl ScenarioConfig {
    /// The height tables of its surfaces shared with equal ones `interner` has seen (a
    /// batch decoded run by run keeps one copy of each part, issue #53 item 16).
    pub fn share_heights(&mut self, interner: &mut HeightsInterner) {
        for surface in [&mut self.wall, &mut self.wall_estimate]
            .into_iter()
            .flatten()
        {
            if let SurfaceParams::HeightField(p) = surface {
                interner.intern(&mut p.heights);
            }
        }
    }

    /// Checks every field; errors name the field by its dotted path.
    pub fn validate(&self) -> Result<()> {
        let joints = self.robot.validate().map_err(|e| e.within("robot"))?;
        if let Some(w) = &self.wall {
            w.validate().map_err(|e| e.within("wall"))?;
        }
        if let Some(w) = &self.wall_estimate {
            w.validate().map_err(|e| e.within("wall_estimate"))?;
        }
        self.controller
            .validate()
            .map_err(|e| e.within("controller"))?;
        check::positive("period", self.period)?;
        if let Some(a) = &self.admittance {
            a.validate(self.period)
                .map_err(|e| e.within("admittance"))?;
        }
        if let Some(a) = &self.approach {
            a.validate().map_err(|e| e.within("approach"))?;
            if !matches!(self.admittance, Some(ForceControlParams::Admittance(_))) {
                return Err(Error::parameter(
                    "approach",
                    "a GuardedApproach",
                    "None unless admittance is an admittance filter (the approach hands \
                     over to its state; position-only control and the eq. 20 reference \
                     have none)",
                ));
            }
        }
        self.force_reference
            .validate()
            .map_err(|e| e.within("force_reference"))?;
        self.z_reference
            .validate()
            .map_err(|e| e.within("z_reference"))?;
        self.sensor.validate().map_err(|e| e.within("sensor"))?;
        // A sampled low-pass cannot cut above the Nyquist frequency: such a cut-off names
        // no filter the loop can realise (α = 1 − exp(−2π f_c T) only approaches 1).
        let nyquist = 0.5 / self.period;
        if let Some(fc) = self.sensor.cutoff.filter(|&fc| fc > nyquist) {
            return Err(Error::parameter(
                "sensor.cutoff",
                fc,
                &format!(
                    "at most the Nyquist frequency 1/(2·period) = {} Hz, or None for no filter",
                    short(nyquist)
                ),
            ));
        }
        self.actuator
            .validate(joints)
            .map_err(|e| e.within("actuator"))?;
        check::positive("duration", self.duration)?;
        check::positive("velocity_limit", self.velocity_limit)?;
        self.criteria.validate().map_err(|e| e.within("criteria"))?;
        if let Substeps::Count(n) = self.substeps {
            if n == 0 || n > MAX_SUBSTEPS {
                return Err(Error::parameter("substeps", n, SUBSTEPS_ALLOWED));
            }
        }
        check::positive("tolerance", self.tolerance)?;
        let periods = self.duration / self.period;
        if periods.round() + 1.0 > MAX_SAMPLES as f64 {
            return Err(Error::parameter(
                "duration",
                self.duration,
                &format!(
                    "at most {} periods of {} s",
                    MAX_SAMPLES - 1,
                    short(self.period)
                ),
            ));
        }
        if (periods - periods.round()).abs() > 1e-6 * periods.max(1.0) {
            return Err(Error::parameter(
                "duration",
                self.duration,
                &format!("a whole multiple of period = {}", short(self.period)),
            ));
        }
        Ok(())
    }

    /// N = D/T + 1 samples.
    pub fn samples(&self) -> usize {
        (self.duration / self.period).round() as usize + 1
    }

    /// This scenario with `substeps` fixed at `count` (how `"auto"` runs its candidates).
    pub fn with_substeps(&self, count: usize) -> Self {
        Self {
            substeps: Substeps::Count(count),
            ..self.clone()
        }
    }
}

const SUBSTEPS_ALLOWED: &str = "an integer from 1 to 10000, or \"auto\"";

/// `Scenario.substeps`: a fixed count of RK4 substeps per period, or `"auto"`, the fewest
/// that meet `Scenario.tolerance` (`sim::substep_choice`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Substeps {
    Count(usize),
    Auto,
}

impl schemars::JsonSchema for Substeps {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Substeps".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "anyOf": [
                {"type": "integer", "minimum": 1, "maximum": MAX_SUBSTEPS},
                {"const": "auto"}
            ]
        })
    }
}

impl Substeps {
    /// The fixed count, `None` for `"auto"`.
    pub fn count(self) -> Option<usize> {
        match self {
            Substeps::Count(n) => Some(n),
            Substeps::Auto => None,
        }
    }
}

impl serde::Serialize for Substeps {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Substeps::Count(n) => s.serialize_u64(*n as u64),
            Substeps::Auto => s.serialize_str("auto"),
        }
    }
}

impl<'de> serde::Deserialize<'de> for Substeps {
    /// A whole number from 1 to `MAX_SUBSTEPS` (an integral float too: TOML and NumPy write
    /// `2.0`), or the word `"auto"`; anything else is a parameter error naming both.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Given {
            Int(u64),
            Float(f64),
            Word(String),
        }
        let bad =
            |shown: String| serde::de::Error::custom(Error::parameter("", shown, SUBSTEPS_ALLOWED));
        let n = match Given::deserialize(d)? {
            Given::Word(w) if w == "auto" => return Ok(Substeps::Auto),
            Given::Word(w) => return Err(bad(format!("{w:?}"))),
            Given::Int(n) => n,
            Given::Float(v) if v.fract() == 0.0 && (0.0..=MAX_SUBSTEPS as f64).contains(&v) => {
                v as u64
            }
            Given::Float(v) => return Err(bad(short(v))),
        };
        if n == 0 || n > MAX_SUBSTEPS as u64 {
            return Err(bad(n.to_string()));
        }
        Ok(Substeps::Count(n as usize))
    }
}

#[cfg(test)]
impl ScenarioConfig {
    /// A test fixture: computed torque with contact compensation and stiff gains (X follows
    /// X_d closely, the "ideal inner loop" of the paper's analysis), the motion held at z0.
    pub(crate) fn ideal_inner_loop(admittance: crate::control::filter::AdmittanceParams) -> Self {
        use crate::control::params::{ComputedTorqueParams, PositionGains};
        Self {
            controller: ControllerParams::ComputedTorque(ComputedTorqueParams {
                gains: PositionGains::new(1.0, 200.0, 1e4),
                contact_compensation: true,
                ..Default::default()
            }),
            admittance: Some(ForceControlParams::Admittance(admittance)),
            z_reference: Signal::Step {
                value: 0.0,
                time: 0.0,
                initial: 0.0,
            },
            ..Self::default()
        }
    }
}
