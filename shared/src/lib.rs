//! `shared`: the `no_std`, heap-free core of the vibro driver.
//!
//! The same code runs on the STM32F405 firmware (in `f32`) and in the host
//! simulator (in `f64`):
//! - [`impact`]: the impact model of the reference paper (simultaneous impacts at
//!   several points with restitution and Coulomb friction), integrated in impulse
//!   space piecewise exactly;
//! - [`drive`]: the H-bridge as wired (decay mode, PWM period) and its driver over
//!   embedded-hal's PWM outputs: what a duty means, for the firmware and the plant;
//! - [`controller`]: the motor controller: speed loops, phase-lock loop,
//!   ramps, tuning table, latched faults and the self-test, one `step(inputs, dt)`
//!   per tick in `f32`; it knows nothing of bytes, flash or frames;
//! - [`codec`]: the bytes under the protocol and the storage: CRC-16/CCITT-FALSE and
//!   CRC-32/ISO-HDLC, little-endian fields read and written with bounds checks, the
//!   layouts of the controller's values (self-test result, tuning row);
//! - [`storage`]: the tuning table and self-test results in two flash slots used in
//!   turn over any NOR flash (`embedded-storage`), each record with a magic word, a
//!   version, a sequence number and a CRC-32;
//! - [`protocol`]: the UART protocol: frames with a length and two CRCs, a
//!   decoder that never trusts a length, the messages and the answer to every frame;
//! - [`tick`]: one control tick for every board (sample, command, step, apply,
//!   publish) over a [`tick::Board`] and a [`tick::Port`];
//! - [`timing`]: the control tick's lateness and duration from a cycle counter, for
//!   the controller's deadline check;
//! - [`real`]: the scalar trait that makes the numerics generic over `f32` and `f64`;
//! - [`vec2`]: plane vectors, for the impact model, the plant and the tests;
//! - [`Enumerated`]: values with a name in files and outputs, and the list of them.
//!
//! `real`, `vec2` and `Enumerated` are the ground. Above them the controller is
//! the bottom layer; `codec` uses it, `storage` uses both, `protocol` uses all
//! three, and `tick` the controller and the protocol's link.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// Numeric kernels index several parallel arrays with one loop variable; iterator
// chains would hide the formulas they implement.
#![allow(clippy::needless_range_loop)]

pub mod capture;
pub mod codec;
pub mod controller;
pub mod drive;
pub mod impact;
mod named;
pub mod pil;
pub mod protocol;
pub mod real;
pub mod storage;
pub mod tick;
pub mod timing;
pub mod vec2;

pub use named::Enumerated;
pub use real::Real;
