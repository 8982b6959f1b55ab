//! The impact model: impacts at one or several points at once, with per-contact
//! restitution and Coulomb friction (the reference paper, *Mechanism motion studies
//! with collisions at several points*; docs/impact-model.md).
//!
//! Layers, from numerics to mechanics:
//! - `outcome`'s `SlipState` (slip either way or stick) at the bottom: the
//!   problem's friction coupling of a contact depends on it;
//! - `problem`: the impact problem in contact coordinates: the Delassus matrix
//!   `W = J M^-1 J^T`, pre-impact contact velocities, per-contact laws. A plain
//!   struct that can be dumped and solved on its own.
//! - `solver`: Darboux-Keller integration in impulse space, piecewise exactly,
//!   with events where a slip stops, sticks or reverses, and where compression and
//!   restitution end.
//! - [`lcp`] and [`linalg`]: the small dense linear algebra and the complementarity
//!   problem that shares the normal impulse between contacts.
//! - [`split`]: the internal forces that the equations leave undetermined with
//!   several closed contacts, shared within the friction cones.
//! - `outcome`: what an impact did at every contact: impulses by phase, the paper's
//!   seven interaction cases, the slip/stick history, warnings.
//! - `body`: one rigid body in plane motion, free or pinned at a pivot, turned into
//!   an impact problem and back (the paper's Fig. 5 and Fig. 7 bodies).

mod body;
pub mod lcp;
pub mod lemke;
pub mod linalg;
mod outcome;
mod problem;
mod solver;
pub mod split;

pub use body::{body_problem, solve_body, BodyContact, BodyImpact, PivotImpulse, PlanarBody};
pub use outcome::{
    ContactOutcome, ImpactOutcome, InteractionCase, Phase, Segment, SlipState, Warnings,
};
pub use problem::{ContactLaw, ImpactLaw, ImpactProblem};
pub use solver::{solve, solve_into, ImpactError};

/// Most contacts one impact problem can hold.
pub const MAX_CONTACTS: usize = 16;
/// Most history segments recorded per contact.
pub const MAX_SEGMENTS: usize = 16;
