//! The words of persistent contact: a contact's mode between events, and the
//! contact forces at a state. Plain values below the rest of the plant.

use shared::impact::{SlipState, MAX_CONTACTS};

/// The mode of a contact between events.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactMode {
    /// Not touching, or touching and separating.
    Open,
    /// Touching, held by a normal force; tangential velocity held at zero.
    Stick,
    /// Touching, slipping along `+t`.
    SlipPositive,
    /// Touching, slipping along `-t`.
    SlipNegative,
}

impl ContactMode {
    pub(super) fn from_slip(s: SlipState) -> Self {
        match s {
            SlipState::Stick => ContactMode::Stick,
            SlipState::SlipPositive => ContactMode::SlipPositive,
            SlipState::SlipNegative => ContactMode::SlipNegative,
        }
    }

    pub(super) fn slip_state(self) -> SlipState {
        match self {
            ContactMode::SlipPositive => SlipState::SlipPositive,
            ContactMode::SlipNegative => SlipState::SlipNegative,
            _ => SlipState::Stick,
        }
    }

    pub(super) fn closed(self) -> bool {
        self != ContactMode::Open
    }

    /// The sign of a slipping contact's slip velocity, `None` when it sticks or is
    /// open.
    pub(super) fn slip_sign(self) -> Option<f64> {
        match self {
            ContactMode::SlipPositive => Some(1.0),
            ContactMode::SlipNegative => Some(-1.0),
            ContactMode::Stick | ContactMode::Open => None,
        }
    }

    /// The mode's name (the events CSV's detail, messages): `open`, `stick`,
    /// `slip+`, `slip-`.
    pub fn name(self) -> &'static str {
        match self {
            ContactMode::Open => "open",
            ContactMode::Stick => "stick",
            ContactMode::SlipPositive => "slip+",
            ContactMode::SlipNegative => "slip-",
        }
    }
}

/// The contact forces of persistent contact at a state, in the modes of that
/// moment: per contact in file order, N (0 for open contacts; impacts are
/// impulses, reported as events).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactForces {
    /// Normal force `lambda_n` of each contact, N (along the fundament's normal).
    pub normal: [f64; MAX_CONTACTS],
    /// Tangential force `lambda_t` of each contact, N (along `t = (-n_y, n_x)`).
    pub tangential: [f64; MAX_CONTACTS],
}
