//! The simulated vibro driver: platform, rotors, motors, contacts, sensors.
pub mod motor;
pub mod sensors;
