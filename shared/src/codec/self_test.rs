//! The self-test's bytes, the same in the flash record and in the
//! [`crate::protocol::Response::SelfTest`] payload: one rotor's result in
//! [`ROTOR_SELF_TEST_LEN`] bytes, both rotors' in [`SELF_TEST_LEN`], and the report
//! (status and result) in [`SELF_TEST_REPORT_LEN`].
//!
//! ```text
//!  one rotor (12 bytes)
//!  0   flags u8: bit 0 motor polarity ok, bit 1 encoder polarity ok, bit 2 index seen,
//!      the others 0
//!  1   3 reserved zero bytes
//!  4   counts_per_rev u32
//!  8   index_offset_counts u32
//!
//!  both rotors (24 bytes): rotor 1, then rotor 2
//!
//!  report (28 bytes)
//!  0   status u8: 0 not run, 1 running, 2 done, 3 aborted
//!  1   3 reserved zero bytes
//!  4   both rotors
//! ```

use crate::controller::self_test::{RotorSelfTest, SelfTest, SelfTestReport, SelfTestStatus};

use super::wire::{flag_byte, Field, Reader, Writer};

/// Bytes of one rotor's self-test result.
pub const ROTOR_SELF_TEST_LEN: usize = 12;
/// Bytes of both rotors' self-test results.
pub const SELF_TEST_LEN: usize = 2 * ROTOR_SELF_TEST_LEN;
/// Bytes of a self-test report: status, reserved, both rotors.
pub const SELF_TEST_REPORT_LEN: usize = 4 + SELF_TEST_LEN;

/// Bit of [`RotorSelfTest::motor_polarity_ok`] in a rotor's flag byte.
const MOTOR_POLARITY_OK: u8 = 1 << 0;
/// Bit of [`RotorSelfTest::encoder_polarity_ok`].
const ENCODER_POLARITY_OK: u8 = 1 << 1;
/// Bit of [`RotorSelfTest::index_seen`].
const INDEX_SEEN: u8 = 1 << 2;

/// Code of a self-test status (the layout above).
fn status_code(status: SelfTestStatus) -> u8 {
    match status {
        SelfTestStatus::NotRun => 0,
        SelfTestStatus::Running => 1,
        SelfTestStatus::Done => 2,
        SelfTestStatus::Aborted => 3,
    }
}

/// The self-test status of code `b`, if there is one.
fn status_from_code(b: u8) -> Option<SelfTestStatus> {
    [
        SelfTestStatus::NotRun,
        SelfTestStatus::Running,
        SelfTestStatus::Done,
        SelfTestStatus::Aborted,
    ]
    .into_iter()
    .find(|s| status_code(*s) == b)
}

impl Field for RotorSelfTest {
    fn write(&self, w: &mut Writer<'_>) {
        w.u8(flag_byte(&[
            (self.motor_polarity_ok, MOTOR_POLARITY_OK),
            (self.encoder_polarity_ok, ENCODER_POLARITY_OK),
            (self.index_seen, INDEX_SEEN),
        ]));
        w.zeros(3);
        w.u32(self.counts_per_rev);
        w.u32(self.index_offset_counts);
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
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

impl Field for SelfTest {
    fn write(&self, w: &mut Writer<'_>) {
        for rotor in &self.rotors {
            rotor.write(w);
        }
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        Some(SelfTest {
            rotors: [RotorSelfTest::read(r)?, RotorSelfTest::read(r)?],
        })
    }
}

impl Field for SelfTestReport {
    fn write(&self, w: &mut Writer<'_>) {
        w.u8(status_code(self.status));
        w.zeros(3);
        self.result.write(w);
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        let status = status_from_code(r.u8()?)?;
        r.zeros(3)?;
        Some(SelfTestReport {
            status,
            result: SelfTest::read(r)?,
        })
    }
}
