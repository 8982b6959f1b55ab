//! The results of the first-run self-test, stored with the tuning table
//! ([`super::record`]) and read over the UART ([`crate::protocol::Request::ReadSelfTest`]).
//!
//! What the self-test ([`crate::controller::self_test`], run by the controller in
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

use crate::codec::wire::{Reader, Writer};

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

/// Bit of [`RotorSelfTest::motor_polarity_ok`] in a rotor's flag byte.
const MOTOR_POLARITY_OK: u8 = 1 << 0;
/// Bit of [`RotorSelfTest::encoder_polarity_ok`].
const ENCODER_POLARITY_OK: u8 = 1 << 1;
/// Bit of [`RotorSelfTest::index_seen`].
const INDEX_SEEN: u8 = 1 << 2;

impl RotorSelfTest {
    /// Bytes on the wire and in flash: flags `u8` (bit 0 motor polarity ok, bit 1
    /// encoder polarity ok, bit 2 index seen, others 0), 3 reserved zero bytes,
    /// `counts_per_rev` `u32`, `index_offset_counts` `u32`, little-endian.
    pub const LEN: usize = 12;

    /// Polarities right, index seen, a revolution measured.
    pub fn passed(&self) -> bool {
        self.motor_polarity_ok
            && self.encoder_polarity_ok
            && self.index_seen
            && self.counts_per_rev > 0
    }

    /// Append the [`Self::LEN`] bytes.
    pub(crate) fn write(&self, w: &mut Writer<'_>) {
        let mut flags = 0;
        if self.motor_polarity_ok {
            flags |= MOTOR_POLARITY_OK;
        }
        if self.encoder_polarity_ok {
            flags |= ENCODER_POLARITY_OK;
        }
        if self.index_seen {
            flags |= INDEX_SEEN;
        }
        w.u8(flags);
        w.zeros(3);
        w.u32(self.counts_per_rev);
        w.u32(self.index_offset_counts);
    }

    /// Read [`Self::LEN`] bytes; `None` if too few, or an unknown flag or a
    /// reserved byte is set.
    pub(crate) fn read(r: &mut Reader<'_>) -> Option<Self> {
        let flags = r.u8()?;
        if flags & !(MOTOR_POLARITY_OK | ENCODER_POLARITY_OK | INDEX_SEEN) != 0 {
            return None;
        }
        r.zeros(3)?;
        Some(RotorSelfTest {
            motor_polarity_ok: flags & MOTOR_POLARITY_OK != 0,
            encoder_polarity_ok: flags & ENCODER_POLARITY_OK != 0,
            index_seen: flags & INDEX_SEEN != 0,
            counts_per_rev: r.u32()?,
            index_offset_counts: r.u32()?,
        })
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
    /// Bytes on the wire and in flash: rotor 1's [`RotorSelfTest::LEN`] bytes, then
    /// rotor 2's.
    pub const LEN: usize = 2 * RotorSelfTest::LEN;

    /// Both rotors passed ([`RotorSelfTest::passed`]).
    pub fn passed(&self) -> bool {
        self.rotors.iter().all(RotorSelfTest::passed)
    }

    /// Append the [`Self::LEN`] bytes.
    pub(crate) fn write(&self, w: &mut Writer<'_>) {
        for rotor in &self.rotors {
            rotor.write(w);
        }
    }

    /// Read [`Self::LEN`] bytes (see [`RotorSelfTest::read`]).
    pub(crate) fn read(r: &mut Reader<'_>) -> Option<Self> {
        Some(SelfTest {
            rotors: [RotorSelfTest::read(r)?, RotorSelfTest::read(r)?],
        })
    }
}
