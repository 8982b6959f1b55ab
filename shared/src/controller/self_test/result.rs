//! What the first-run self-test measured, and where it stands: the values the
//! controller produces. Their bytes (in a message and in the flash record) are
//! `crate::codec`'s business, not the controller's.
//!
//! What the self-test ([`super`], run by the controller in
//! [`crate::controller::State::SelfTest`]) measures, per rotor, with the motors driven
//! gently one at a time (this is its result):
//! - motor polarity: the winding current followed the duty's sign;
//! - encoder polarity: the counts followed the current's sign;
//! - the index pulse: seen at all, and where;
//! - counts per revolution: the counts between two index pulses.
//!
//! With only an encoder and a current sense, which way the rotor really turned is
//! not measurable (a motor swapped at its own terminals and a swapped encoder read
//! as all good): the mechanical sense must be checked by eye during the test.

/// One rotor's self-test result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RotorSelfTest {
    /// The rotor moved and the winding current (positive when driving forward)
    /// followed the positive test duty: the bridge, the winding and the current
    /// sense agree. False: the motor's leads are swapped between the bridge and the
    /// current sense, the current sense is reversed or dead, or the rotor did not
    /// turn. Leads swapped at the motor itself pass: check the sense by eye.
    pub motor_polarity_ok: bool,
    /// The rotor moved and the encoder counted the way the current pushed (up for a
    /// positive current). False: channels A and B are swapped, the current sense is
    /// dead, or the rotor did not turn.
    pub encoder_polarity_ok: bool,
    /// An index pulse was seen while the rotor was driven.
    pub index_seen: bool,
    /// Counts between two consecutive index pulses (after x4 decoding), as measured;
    /// 0 when fewer than two were seen. Compare with the machine file's
    /// `counts_per_rev`.
    pub counts_per_rev: u32,
    /// Counts from the rotor's position at the start of the test (at rest, the
    /// eccentric hanging down) to the first index pulse, in the driven sense, in
    /// `[0, counts_per_rev)`; 0 when no index was seen.
    pub index_offset_counts: u32,
}

impl RotorSelfTest {
    /// Polarities right, index seen, a revolution measured.
    pub fn passed(&self) -> bool {
        self.motor_polarity_ok
            && self.encoder_polarity_ok
            && self.index_seen
            && self.counts_per_rev > 0
    }
}

/// The self-test result of both rotors (rotor 1 first).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfTest {
    /// Per rotor, in the machine file's order.
    pub rotors: [RotorSelfTest; 2],
}

impl SelfTest {
    /// Both rotors passed ([`RotorSelfTest::passed`]).
    pub fn passed(&self) -> bool {
        self.rotors.iter().all(RotorSelfTest::passed)
    }

    /// The rotors a machine with `rotors` has passed: both, or rotor 1 alone on a
    /// one-rotor machine (whose test leaves rotor 2's result all zero). The result
    /// itself, and its bytes in a message or the flash record, do not say how many
    /// rotors the machine has.
    pub fn passed_with(&self, rotors: crate::controller::RotorCount) -> bool {
        self.rotors[..rotors.count()]
            .iter()
            .all(RotorSelfTest::passed)
    }
}

/// Where a self-test stands ([`SelfTestReport::status`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SelfTestStatus {
    /// None has run since the table was written, or ever: the result is all zero.
    NotRun,
    /// One is running; the result is not final.
    Running,
    /// The last one completed; the result is its measurements (whether they pass is
    /// [`SelfTest::passed`]).
    Done,
    /// The last one was stopped (a fault, the E-stop, a stop command); the result
    /// is what it had measured.
    Aborted,
}

/// The self-test as the controller reports it ([`crate::controller::Controller::self_test_report`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfTestReport {
    /// Where it stands.
    pub status: SelfTestStatus,
    /// Its measurements.
    pub result: SelfTest,
}
