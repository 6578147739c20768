//! The world around the controller: the environment the tip touches, the force sensor that
//! reports it and the actuators that turn commands into torque (SPEC §10).

pub mod actuator;
pub mod contact_law;
pub mod environment;
pub mod height_field;
pub mod round;
pub mod sensor;
pub mod surface;
