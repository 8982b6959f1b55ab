//! Darboux-Keller integration of an impact in impulse space (stub, being written).
use super::outcome::ImpactOutcome;
use super::problem::ImpactProblem;
use crate::real::Real;

/// Why an impact problem could not be solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImpactError {
    /// No contact approaches: nothing to solve.
    NoApproach,
    /// The problem is malformed: no contact, more than capacity, or a number that is
    /// not finite.
    InvalidProblem,
    /// The impulse path needed more pieces than the solver allows (chattering between
    /// friction states).
    TooManyEvents,
}

/// Solves one impact.
pub fn solve<T: Real, const N: usize>(
    _problem: &ImpactProblem<T, N>,
) -> Result<ImpactOutcome<T, N>, ImpactError> {
    Err(ImpactError::InvalidProblem)
}
