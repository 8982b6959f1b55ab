//! What the simulated device drives and senses: [`Mechanics`], one control tick at
//! a time. Two kinds: the simple rotors of [`super::rotors`] (the bench, the
//! platform lifted; `host-sim device-sim` without a machine) and the whole machine
//! of a machine file, [`super::plant`] (`host-sim device-sim --machine`).

use shared::controller::Outputs;

use crate::simulation::board::Readings;

/// The platform's pose: its centre of mass and angle, as the trace of `host-sim
/// run --out` gives them (columns `x`, `y`, `angle`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlatformPose {
    /// Centre of mass along the floor, m (+x right).
    pub x: f64,
    /// Centre of mass height, m (+y up).
    pub y: f64,
    /// Angle, rad (counter-clockwise positive, 0 level as at the start).
    pub angle: f64,
}

/// The motors, rotors and whatever they shake, with the board's sensors.
pub trait Mechanics: Send {
    /// Advance `dt` s with the controller's outputs `out` on the H-bridges (the
    /// windings open before the first); what the sensors read at the end.
    fn advance(&mut self, out: Option<&Outputs>, dt: f64) -> Readings;

    /// The supply voltage the board measures, V.
    fn supply(&self) -> f32;

    /// The rotor speeds, rpm, in each rotor's driven sense (the simulation's
    /// truth, not the controller's estimate; 0 for a rotor there is not).
    fn speeds_rpm(&self) -> [f64; 2];

    /// The platform's pose, if there is a platform.
    fn platform(&self) -> Option<PlatformPose> {
        None
    }

    /// What the simulation warned about so far (deduplicated).
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }

    /// Why the platform's motion so far is no travel, in a few words (a body went
    /// through the fundament or tipped over, [`crate::simulation::breach`]);
    /// `None` while it is one.
    fn no_travel(&self) -> Option<String> {
        None
    }

    /// Why the simulation cannot go on, if it cannot: the plant stopped advancing
    /// (its progress guard, a step size underflow; [`crate::plant::progress`]).
    /// `None` while it goes on.
    fn stopped(&self) -> Option<String> {
        None
    }
}
