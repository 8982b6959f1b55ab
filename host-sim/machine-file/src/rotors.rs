//! The machine's unbalance rotors, `[[rotors]]`: one or two.
//!
//! A machine with two rotors has the phase offset `theta_1 - theta_2` its
//! controller holds (the reference machine); a machine with one has no offset,
//! and its controller holds rotor 1's speed only
//! (`shared::controller::RotorCount::One`). [`Rotors`] holds one or two
//! [`Rotor`]s and no other count: its only constructor, [`Rotors::new`], refuses
//! the others, so rotor 1 always exists. It reads as a slice, `rotors[k]`,
//! `rotors.iter()`, `rotors.len()`, and its rotors may be changed in place but
//! none added or removed.

use std::ops::{Deref, DerefMut};

use shared::controller::RotorCount;

use crate::Rotor;

/// Rotor 1, and rotor 2 on a machine with two (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Rotors(Vec<Rotor>);

impl Rotors {
    /// The counts a machine may have: 1 or 2.
    pub const COUNTS: [usize; 2] = [1, 2];

    /// The rotors in file order, if there are one or two; else the list back.
    pub fn new(list: Vec<Rotor>) -> Result<Rotors, Vec<Rotor>> {
        match RotorCount::from_count(list.len()) {
            Some(_) => Ok(Rotors(list)),
            None => Err(list),
        }
    }

    /// One rotor or two.
    pub fn count(&self) -> RotorCount {
        // `new` admits one or two only.
        if self.0.len() == 1 {
            RotorCount::One
        } else {
            RotorCount::Two
        }
    }

    /// Rotor 1 (there is always one).
    pub fn rotor1(&self) -> &Rotor {
        // Never empty: see `new`; the slice pattern keeps this free of a panic.
        match self.0.as_slice() {
            [first, ..] => first,
            [] => unreachable!("Rotors::new refuses an empty list"),
        }
    }

    /// Rotor 2, on a machine with two.
    pub fn rotor2(&self) -> Option<&Rotor> {
        self.0.get(1)
    }

    /// The rotors, as a list.
    pub fn into_vec(self) -> Vec<Rotor> {
        self.0
    }
}

impl Deref for Rotors {
    type Target = [Rotor];

    fn deref(&self) -> &[Rotor] {
        &self.0
    }
}

impl DerefMut for Rotors {
    /// The rotors to change in place (a slice: none can be added or removed).
    fn deref_mut(&mut self) -> &mut [Rotor] {
        &mut self.0
    }
}

impl<'a> IntoIterator for &'a Rotors {
    type Item = &'a Rotor;
    type IntoIter = std::slice::Iter<'a, Rotor>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}
