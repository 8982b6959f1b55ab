//! The simulated vibro driver: bodies, rotors, motors, contacts, sensors.
//!
//! - [`contact`]: a contact's mode between events, the contact forces at a state;
//! - [`model`]: the constant model (body-frame geometry, the coordinates of the
//!   bodies' trees) from a machine file;
//! - [`dynamics`]: equations of motion (`(x, y, theta, phi_1, phi_2)` for a single
//!   platform);
//! - [`motor`]: the brushed DC motors and their driver;
//! - [`integrator`]: Dormand-Prince 5(4) with dense output;
//! - [`simulator`]: the hybrid simulation (modes, events, impacts, Zeno, Painleve);
//! - [`progress`]: the progress guard (a budget of work per simulated
//!   millisecond) and why a run stopped early;
//! - [`sensors`]: encoders with index pulses, current measurement;
//! - [`outline`]: every body's outline (drawn, and kept off the fundament).
// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]
pub mod bridge;
pub mod contact;
pub mod dynamics;
pub mod integrator;
pub mod model;
pub mod motor;
pub mod outline;
pub mod progress;
pub mod sensors;
pub mod simulator;
