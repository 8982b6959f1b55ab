//! What an impact did: impulses by phase, the paper's interaction case and the
//! slip/stick history of every contact, and warnings.

use super::MAX_SEGMENTS;
use crate::real::Real;

/// The two phases of an impact (the paper's Fig. 2: `tau_1` and `tau_2`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Phase {
    /// Until every active contact's normal velocity is zero.
    Compression,
    /// From the end of compression until the impact law ends the impact.
    Restitution,
}

impl Phase {
    /// `compression` or `restitution`.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Compression => "compression",
            Phase::Restitution => "restitution",
        }
    }
}

/// The friction state of a contact along a piece of the impulse path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlipState {
    /// Slipping along `+t` (friction impulse along `-t`).
    SlipPositive,
    /// Slipping along `-t` (friction impulse along `+t`).
    SlipNegative,
    /// Sticking: tangential velocity held at zero by a force inside the cone.
    Stick,
}

impl SlipState {
    /// `slip+`, `slip-` or `stick`.
    pub fn name(self) -> &'static str {
        match self {
            SlipState::SlipPositive => "slip+",
            SlipState::SlipNegative => "slip-",
            SlipState::Stick => "stick",
        }
    }

    /// The slip sign `s`: +1, -1, or 0 for stick.
    pub fn sign<T: Real>(self) -> T {
        match self {
            SlipState::SlipPositive => T::ONE,
            SlipState::SlipNegative => -T::ONE,
            SlipState::Stick => T::ZERO,
        }
    }
}

/// The paper's seven impact interaction cases (its list after eq. (1)), plus 0 for a
/// contact that receives no impulse. Numbering fixed by docs/impact-model.md ("The
/// seven interaction cases"), which `host-sim impact` prints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InteractionCase {
    /// 0: no impulse at this contact.
    Inactive = 0,
    /// 1: full slip in one direction.
    Slip = 1,
    /// 2: full slip in one direction starting from zero tangential velocity.
    SlipFromRest = 2,
    /// 3: slip that stops and sticks during compression.
    StickInCompression = 3,
    /// 4: slip that stops and sticks during restitution.
    StickInRestitution = 4,
    /// 5: slip that reverses during compression.
    ReversalInCompression = 5,
    /// 6: slip that reverses during restitution.
    ReversalInRestitution = 6,
    /// 7: no slip.
    NoSlip = 7,
}

impl InteractionCase {
    /// The documented case number (0 to 7).
    pub fn number(self) -> u8 {
        self as u8
    }

    /// A short name: `inactive`, `slip`, `slip-from-rest`, `stick-in-compression`,
    /// `stick-in-restitution`, `reversal-in-compression`, `reversal-in-restitution`,
    /// `no-slip`.
    pub fn name(self) -> &'static str {
        match self {
            InteractionCase::Inactive => "inactive",
            InteractionCase::Slip => "slip",
            InteractionCase::SlipFromRest => "slip-from-rest",
            InteractionCase::StickInCompression => "stick-in-compression",
            InteractionCase::StickInRestitution => "stick-in-restitution",
            InteractionCase::ReversalInCompression => "reversal-in-compression",
            InteractionCase::ReversalInRestitution => "reversal-in-restitution",
            InteractionCase::NoSlip => "no-slip",
        }
    }
}

/// One piece of a contact's history: a phase and a friction state held while the
/// contact's impulses went from `[start, end]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<T> {
    /// The phase the segment lies in.
    pub phase: Phase,
    /// The friction state along it.
    pub state: SlipState,
    /// Accumulated normal impulse of this contact at the segment's start and end, N s.
    pub normal_impulse: [T; 2],
    /// Accumulated tangential impulse of this contact at the segment's start and
    /// end, N s.
    pub tangential_impulse: [T; 2],
}

/// What the impact did at one contact.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactOutcome<T> {
    /// Total normal impulse, N s (>= 0, along `n`).
    pub normal_impulse: T,
    /// Total tangential (friction) impulse, N s (along `t`).
    pub tangential_impulse: T,
    /// Normal and tangential impulse of the compression phase, N s.
    pub compression: [T; 2],
    /// Normal and tangential impulse of the restitution phase, N s.
    pub restitution: [T; 2],
    /// Normal velocity before the impact, m/s.
    pub normal_velocity_before: T,
    /// Normal velocity after the impact, m/s.
    pub normal_velocity_after: T,
    /// Tangential velocity before the impact, m/s.
    pub tangential_velocity_before: T,
    /// Tangential velocity after the impact, m/s.
    pub tangential_velocity_after: T,
    /// The paper's interaction case.
    pub case: InteractionCase,
    /// The history, in order; consecutive pieces with the same phase and state are
    /// merged. `truncated` is set where it held more than [`MAX_SEGMENTS`].
    pub segments: heapless::Vec<Segment<T>, MAX_SEGMENTS>,
    /// True when the history had more segments than fit.
    pub truncated: bool,
}

impl<T: Real> ContactOutcome<T> {
    /// Back to the default (no impulse, no history) in place: the history's
    /// storage is not rewritten, only emptied.
    pub fn clear(&mut self) {
        self.normal_impulse = T::ZERO;
        self.tangential_impulse = T::ZERO;
        self.compression = [T::ZERO; 2];
        self.restitution = [T::ZERO; 2];
        self.normal_velocity_before = T::ZERO;
        self.normal_velocity_after = T::ZERO;
        self.tangential_velocity_before = T::ZERO;
        self.tangential_velocity_after = T::ZERO;
        self.case = InteractionCase::Inactive;
        self.segments.clear();
        self.truncated = false;
    }
}

impl<T: Real> Default for ContactOutcome<T> {
    fn default() -> Self {
        ContactOutcome {
            normal_impulse: T::ZERO,
            tangential_impulse: T::ZERO,
            compression: [T::ZERO; 2],
            restitution: [T::ZERO; 2],
            normal_velocity_before: T::ZERO,
            normal_velocity_after: T::ZERO,
            tangential_velocity_before: T::ZERO,
            tangential_velocity_after: T::ZERO,
            case: InteractionCase::Inactive,
            segments: heapless::Vec::new(),
            truncated: false,
        }
    }
}

/// Warnings of an impact, as bit flags.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Warnings(pub u8);

impl Warnings {
    /// The impact raised the kinetic energy (possible with Newton's law and friction,
    /// and with Poisson's law at several contacts with unequal restitution).
    pub const ENERGY_GAINED: Warnings = Warnings(1);
    /// A contact still approaches after the impact.
    pub const PENETRATION_LEFT: Warnings = Warnings(2);
    /// Jamming (self-locking): a contact whose slip would not separate it under
    /// friction (the paper's `h < f d`, where its eq. (5) is not physical).
    pub const JAMMING: Warnings = Warnings(4);
    /// No consistent set of contact states was found at some event; the solver took
    /// the closest one.
    pub const INCONSISTENT: Warnings = Warnings(8);

    /// True when every flag of `other` is set.
    pub fn contains(self, other: Warnings) -> bool {
        self.0 & other.0 == other.0
    }
    /// Sets the flags of `other`.
    pub fn insert(&mut self, other: Warnings) {
        self.0 |= other.0;
    }
    /// True when no flag is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// The result of one impact.
#[derive(Clone, Debug)]
pub struct ImpactOutcome<T, const N: usize> {
    /// Number of contacts (as in the problem).
    pub len: usize,
    /// Per-contact results; entries >= `len` are default.
    pub contacts: [ContactOutcome<T>; N],
    /// Kinetic energy change `P . (u_before + u_after) / 2`, J (exact for any
    /// mechanism with Delassus matrix `W`).
    pub energy_change: T,
    /// Warnings raised.
    pub warnings: Warnings,
}

impl<T: Real, const N: usize> Default for ImpactOutcome<T, N> {
    /// No contact: storage for [`super::solver::solve_into`].
    fn default() -> Self {
        ImpactOutcome {
            len: 0,
            contacts: core::array::from_fn(|_| ContactOutcome::default()),
            energy_change: T::ZERO,
            warnings: Warnings::default(),
        }
    }
}
