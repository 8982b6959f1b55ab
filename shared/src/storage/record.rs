//! The flash record: its byte layout, [`encode_record`] and the checks of
//! [`parse_record`].
//!
//! ```text
//!  offset  size  field
//!  0       4     magic MAGIC = "VIBT" (0x54424956 little-endian): written last (the commit)
//!  4       2     format version FORMAT_VERSION = 2, u16
//!  6       2     payload length PAYLOAD_LEN = 552, u16
//!  8       4     sequence number, u32 (one more at every store, compared modulo 2^32)
//!  12      552   payload:
//!                  0   row count u8, 1..=32
//!                  1   present u8: bit 0 the self-test, bit 1 the identification;
//!                      the others 0
//!                  2   2 reserved zero bytes
//!                  4   32 rows x (speed_rpm, right_offset_deg, left_offset_deg) f32;
//!                      rows past the count are zero
//!                  388 self-test, 24 bytes (codec::self_test), zero when absent
//!                  412 motor identification, 140 bytes (codec::identity), zero
//!                      when absent
//!  564     4     CRC-32/ISO-HDLC of bytes 0..564 (the magic as MAGIC included)
//! ```
//!
//! A record of format version 1, as a firmware before the motor identification
//! wrote it, is read too: its payload is the first 412 bytes above (present byte
//! 0 or 1: the self-test), its CRC at 424, and it holds no identification; the
//! next store writes version 2. The version and the length are read before the
//! CRC only to find where the CRC is; nothing else is used until it matches.
//!
//! Everything is little-endian (as the STM32 stores a programmed word). A record is
//! valid only if every check passes: the magic, the version, the payload length,
//! the CRC, then the payload's own rules (count, flags, reserved and unused bytes
//! zero, a tuning table [`TuningTable::from_rows`] accepts).
//!
//! # Erased and zeroed flash never validate
//!
//! Erased flash reads `0xFF`: magic `0xFFFFFFFF`, length `0xFFFF`; zeroed flash (the
//! QEMU model, or a cut mid-way) reads magic `0`, length 0. Both fail the magic and
//! the length checks, and the CRC check as well: CRC-32/ISO-HDLC of 424 bytes of
//! `0xFF` is not `0xFFFFFFFF` (only a run of exactly 4 bytes has that CRC), and of
//! 424 zero bytes is not 0 (the init makes it non-zero for every non-zero length).
//! `tests/storage.rs` checks both, for every length.

use crate::codec::crc::Crc32;
use crate::codec::wire::{flag_byte, Field, Reader, Writer};
use crate::codec::{IDENTITY_LEN, SELF_TEST_LEN, TUNING_ROW_LEN};
use crate::controller::identify::Identity;
use crate::controller::self_test::SelfTest;
use crate::controller::{TuningRow, TuningTable, DEFAULT_ROW_SPEED_RPM, MAX_TUNING_ROWS};

/// The commit word, first in the record and written last: the bytes `"VIBT"`. Not
/// `0xFFFFFFFF` (erased) nor `0` (zeroed), and no byte of it is `0xFF`, so a magic
/// whose programming was cut at any bit reads different.
pub const MAGIC: u32 = u32::from_le_bytes(*b"VIBT");

/// The record layout's version this firmware writes; it reads this one and
/// version 1 ([`V1_PAYLOAD_LEN`]), no other.
pub const FORMAT_VERSION: u16 = 2;

/// Bytes before the payload: magic, version, length, sequence.
pub const RECORD_HEADER_LEN: usize = 12;

/// Payload bytes of format version 1: counts and flags (4), [`MAX_TUNING_ROWS`]
/// rows, a [`SelfTest`].
pub const V1_PAYLOAD_LEN: usize = 4 + MAX_TUNING_ROWS * TUNING_ROW_LEN + SELF_TEST_LEN;

/// Payload bytes: version 1's and an [`Identity`].
pub const PAYLOAD_LEN: usize = V1_PAYLOAD_LEN + IDENTITY_LEN;

/// Bytes of the CRC at the end.
pub const RECORD_CRC_LEN: usize = 4;

/// Bytes of a whole record, a multiple of 4 (whole words).
pub const RECORD_LEN: usize = RECORD_HEADER_LEN + PAYLOAD_LEN + RECORD_CRC_LEN;

/// Words of a record.
pub const RECORD_WORDS: usize = RECORD_LEN / 4;

// A record is programmed in whole 32-bit words.
const _: () = assert!(RECORD_LEN & 3 == 0);

/// Bit of the present byte: a self-test result is stored.
const HAS_SELF_TEST: u8 = 1 << 0;
/// Bit of the present byte: a motor identification is stored.
const HAS_IDENTITY: u8 = 1 << 1;

/// What a record stores: the tuning table, the self-test and the motor
/// identification results.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Record {
    /// The tuning table to use.
    pub tuning: TuningTable,
    /// The latest self-test result, if one was stored.
    pub self_test: Option<SelfTest>,
    /// The latest motor identification, if one was stored.
    pub identity: Option<Identity>,
}

/// Write `record` with sequence number `sequence` as its [`RECORD_LEN`] bytes.
pub fn encode_record(record: &Record, sequence: u32) -> [u8; RECORD_LEN] {
    let mut bytes = [0u8; RECORD_LEN];
    let mut w = Writer::new(&mut bytes);

    // Header.
    w.u32(MAGIC);
    w.u16(FORMAT_VERSION);
    w.u16(PAYLOAD_LEN as u16);
    w.u32(sequence);

    // Payload: counts and flags, the rows in fixed slots, the self-test.
    let rows = record.tuning.rows();
    w.u8(rows.len().min(MAX_TUNING_ROWS) as u8);
    w.u8(flag_byte(&[
        (record.self_test.is_some(), HAS_SELF_TEST),
        (record.identity.is_some(), HAS_IDENTITY),
    ]));
    w.zeros(2);
    for slot in 0..MAX_TUNING_ROWS {
        match rows.get(slot) {
            Some(row) => row.write(&mut w),
            None => w.zeros(TUNING_ROW_LEN),
        }
    }
    match &record.self_test {
        Some(test) => test.write(&mut w),
        None => w.zeros(SELF_TEST_LEN),
    }
    match &record.identity {
        Some(identity) => identity.write(&mut w),
        None => w.zeros(IDENTITY_LEN),
    }
    // The layout fills the array exactly (checked by the tests).
    let end = w.finish().unwrap_or(0);

    // CRC of everything before it.
    let crc = Crc32::new()
        .update(bytes.get(..end).unwrap_or(&[]))
        .finish();
    if let Some(slot) = bytes.get_mut(end..end + RECORD_CRC_LEN) {
        slot.copy_from_slice(&crc.to_le_bytes());
    }
    bytes
}

/// Rows stored under the rule before tuning rows had one rule (same format version):
/// speeds `>= 0` and offsets in `[0, 360]`. The two values it took that the rule
/// refuses now mean what they meant: an offset of 360 degrees is 0 (a full turn),
/// and the default table's single row at speed 0 holds its offsets at every speed,
/// as a single row at [`DEFAULT_ROW_SPEED_RPM`] does. (host-sim never wrote a speed
/// of 0, so a table of several rows never had one.) Without this an updated
/// firmware would lose the stored table and self-test result.
fn from_earlier_rule(rows: &mut [(f32, f32, f32)]) {
    if let [(speed, _, _)] = rows {
        if *speed == 0.0 {
            *speed = DEFAULT_ROW_SPEED_RPM;
        }
    }
    for (_, right, left) in rows.iter_mut() {
        for offset in [right, left] {
            if *offset == 360.0 {
                *offset = 0.0;
            }
        }
    }
}

/// The record at the start of `bytes` (at least a version 1 record's length) and
/// its sequence number, if every check passes (see the module documentation).
pub fn parse_record(bytes: &[u8]) -> Option<(Record, u32)> {
    // The version says where the CRC is.
    let mut header = Reader::new(bytes.get(..RECORD_HEADER_LEN)?);
    let (_, version, length) = (header.u32()?, header.u16()?, header.u16()?);
    let payload_len = match version {
        1 => V1_PAYLOAD_LEN,
        FORMAT_VERSION => PAYLOAD_LEN,
        _ => return None,
    };
    if usize::from(length) != payload_len {
        return None;
    }
    let bytes = bytes.get(..RECORD_HEADER_LEN + payload_len + RECORD_CRC_LEN)?;

    // CRC first: it covers everything else.
    let (body, crc) = bytes.split_last_chunk::<RECORD_CRC_LEN>()?;
    if Crc32::new().update(body).finish() != u32::from_le_bytes(*crc) {
        return None;
    }

    // Header.
    let mut r = Reader::new(body);
    if r.u32()? != MAGIC {
        return None;
    }
    r.u16()?;
    r.u16()?;
    let sequence = r.u32()?;

    // Counts and flags.
    let count = usize::from(r.u8()?);
    let present = r.u8()?;
    let allowed = if version == 1 {
        HAS_SELF_TEST
    } else {
        HAS_SELF_TEST | HAS_IDENTITY
    };
    if present & !allowed != 0 {
        return None;
    }
    r.zeros(2)?;
    if !(1..=MAX_TUNING_ROWS).contains(&count) {
        return None;
    }

    // Rows: the first `count` make the table, the others are zero.
    let mut rows = [(0.0f32, 0.0f32, 0.0f32); MAX_TUNING_ROWS];
    for (slot, row) in rows.iter_mut().enumerate() {
        if slot < count {
            let TuningRow {
                speed_rpm,
                right_offset_deg,
                left_offset_deg,
            } = TuningRow::read(&mut r)?;
            *row = (speed_rpm, right_offset_deg, left_offset_deg);
        } else {
            r.zeros(TUNING_ROW_LEN)?;
        }
    }
    let rows = rows.get_mut(..count)?;
    from_earlier_rule(rows);
    let tuning = TuningTable::from_rows(rows).ok()?;

    // The self-test and the identification, or zeros.
    let self_test = if present & HAS_SELF_TEST != 0 {
        Some(SelfTest::read(&mut r)?)
    } else {
        r.zeros(SELF_TEST_LEN)?;
        None
    };
    let identity = if present & HAS_IDENTITY != 0 {
        Some(Identity::read(&mut r)?)
    } else {
        if version != 1 {
            r.zeros(IDENTITY_LEN)?;
        }
        None
    };
    r.is_empty().then_some((
        Record {
            tuning,
            self_test,
            identity,
        },
        sequence,
    ))
}
