//! What several integration tests of `shared` use: frames and a decoder fed in
//! chunks ([`frames`]), the device's end of the link ([`device`]), the fuzzers'
//! generator and run length ([`fuzz`]), motor identifications ([`identities`]),
//! one checked store of a power-cut history ([`power_cut`]), tuning tables from
//! generated rows ([`tables`]), the controller tests' rotor rig ([`rig`]). Each
//! test uses a part of it.
#![allow(dead_code)]

pub mod device;
pub mod frames;
pub mod fuzz;
pub mod identities;
pub mod power_cut;
pub mod rig;
pub mod rng;
pub mod tables;
