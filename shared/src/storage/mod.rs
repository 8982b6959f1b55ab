//! Parameters in flash: the tuning table, the self-test and the motor
//! identification results, in
//! two flash slots used in turn, so that a power cut during a write never loses
//! the last good copy (after ODrive's `Firmware/Drivers/STM32/nvm.c`).
//!
//! - the flash is any NOR flash driver through `embedded-storage`'s
//!   [`NorFlash`] and [`ReadNorFlash`] traits (offsets from the flash's start,
//!   erase in whole erase units of `ERASE_SIZE` bytes, program in units of
//!   `WRITE_SIZE` bytes that can only clear bits);
//! - `record`: the record layout (magic, version, length, sequence, payload,
//!   CRC-32) and its checks;
//! - `sim`: [`SimFlash`], a simulated flash that can lose power at any byte.
//!
//! # Two slots in turn
//!
//! The flash handed to [`load`] and [`store`] (a driver, or a partition of one) is
//! cut in two halves, the slots ([`slot_offset`]); each holds at most one record, at
//! its start, and each must be whole erase units. On the board the driver
//! (`firmware/src/flash.rs`) covers sectors 10 and 11 of the STM32F405 (128 KiB each
//! at `0x080C0000` and `0x080E0000`, kept out of the program by `memory.x`), so slot
//! 0 is sector 10 and slot 1 sector 11. [`load`] reads both and takes the valid one
//! with the newer sequence number. [`store`]:
//!
//! 1. finds the slot that does *not* hold the newest valid record (slot 0 when
//!    neither is valid);
//! 2. erases it (every byte `0xFF`);
//! 3. programs the record after its commit unit (the program units holding the
//!    magic: its first 4 bytes on a flash that programs words), then reads them back;
//! 4. programs the commit unit, the magic: the commit;
//! 5. reads the whole record back and parses it.
//!
//! # Why a power cut at any moment keeps the last good record
//!
//! The newest valid record is never erased nor written: only the other slot is.
//! Until the magic's last bit is programmed, the written slot's first word is not
//! [`MAGIC`] (erased `0xFFFFFFFF`, or a partly programmed word that still has
//! some of the 1 bits that should be 0), so its record is invalid and [`load`] returns
//! the previous one. A cut during the erase leaves that slot with the older record,
//! partly erased bytes, or `0xFF`: an older or invalid record, never a newer valid one
//! except with the chance of a CRC-32 collision (`2^-32`). Once the magic is
//! programmed, every other byte was programmed and verified before it, so the new
//! record is whole and, with the higher sequence number, the one [`load`] takes.
//! `tests/storage.rs` checks this with [`SimFlash`] cut after every byte of a store.
//!
//! # Any NOR flash
//!
//! The record's bytes do not depend on the flash. A flash that programs in units of
//! more than 4 bytes (8 or 32 on some chips) gets the record padded with `0xFF` (the
//! erased value: nothing programmed) to whole units, and its commit unit is the first
//! whole unit; units of 1 or 2 bytes commit the first 4 bytes in one write. Program
//! and read units up to [`MAX_UNIT`] bytes are supported; a flash with larger ones, or
//! whose halves are not whole erase units or too small for a record, is refused
//! ([`StoreError::Geometry`], and [`load`] finds nothing).
//!
//! # Motors stopped
//!
//! Erasing a 128 KiB sector takes about 1 s (2 s at most, STM32F405 datasheet,
//! `t_ERASE128KB` at 32-bit parallelism), and while the flash is busy the CPU stalls
//! on every fetch from flash: the control loop does not run. So the firmware writes
//! only when [`crate::controller::may_write_table`] says the driver is off and the
//! rotors at rest, it feeds or times its watchdog to outlast the erase, and it
//! restarts its control tick timing afterwards.

mod record;
mod sim;

pub use record::{
    encode_record, parse_record, Record, FORMAT_VERSION, MAGIC, PAYLOAD_LEN, RECORD_HEADER_LEN,
    RECORD_LEN, RECORD_WORDS, V1_PAYLOAD_LEN,
};
pub use sim::{SimError, SimFlash, SIM_SECTOR_BYTES, SIM_SECTOR_SIZE};

use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};

/// Largest program or read unit, bytes, the storage supports (the 256-bit flash
/// words of the largest STM32 parts).
pub const MAX_UNIT: usize = 32;

/// A record padded to whole units, with room for the largest unit.
const PADDED_MAX: usize = RECORD_LEN + MAX_UNIT;

/// A record found in flash.
#[derive(Clone, Debug, PartialEq)]
pub struct Stored {
    /// What it holds.
    pub record: Record,
    /// Its sequence number.
    pub sequence: u32,
    /// Its slot, 0 or 1 ([`slot_offset`]).
    pub slot: usize,
}

/// Why [`store`] failed. The previous record is intact in every case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The flash reported an error.
    Flash(E),
    /// A byte read back differs from the one written (worn or faulty flash).
    Verify,
    /// The flash does not fit the storage: program or read units above
    /// [`MAX_UNIT`], or halves that are not whole erase units or too small for a
    /// record (see the module documentation). Nothing was erased or written.
    Geometry,
}

/// Where slot `slot` (0 or 1) starts in a flash of `capacity` bytes: slot 0 at 0,
/// slot 1 at half the capacity, bytes. `None` for another slot.
pub fn slot_offset(capacity: usize, slot: usize) -> Option<u32> {
    let half = u32::try_from(capacity / 2).ok()?;
    match slot {
        0 => Some(0),
        1 => Some(half),
        _ => None,
    }
}

/// `n` rounded up to a multiple of `unit` (`unit` > 0).
const fn round_up(n: usize, unit: usize) -> usize {
    n.div_ceil(unit) * unit
}

/// The bytes read for a record from a flash that reads in units of `read_size`:
/// [`RECORD_LEN`] rounded up to whole units; `None` above [`MAX_UNIT`].
fn read_len(read_size: usize) -> Option<usize> {
    let unit = read_size.max(1);
    (unit <= MAX_UNIT).then(|| round_up(RECORD_LEN, unit))
}

/// How a record is written to a flash of type `F`: the commit unit (the first
/// bytes, which hold the magic, written last in one write) and the record's length
/// padded to whole units, bytes. The commit unit is the smallest multiple of
/// `WRITE_SIZE` that is at least 4 bytes (the magic) and whole read units; `None`
/// if that is above [`MAX_UNIT`].
fn write_units<F: NorFlash>() -> Option<(usize, usize)> {
    let (write, read) = (F::WRITE_SIZE.max(1), F::READ_SIZE.max(1));
    let mut unit = write;
    while unit <= MAX_UNIT && (unit < 4 || !unit.is_multiple_of(read)) {
        unit += write;
    }
    (unit <= MAX_UNIT).then(|| (unit, round_up(RECORD_LEN, unit)))
}

/// Whether sequence number `a` is newer than `b`, modulo `2^32` (serial number
/// arithmetic: the two records differ by one).
pub fn is_newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The record in slot `slot`, if valid.
fn read_slot<F: ReadNorFlash>(flash: &mut F, slot: usize) -> Option<Stored> {
    let offset = slot_offset(flash.capacity(), slot)?;
    let len = read_len(F::READ_SIZE)?;
    if !usize::try_from(offset)
        .ok()?
        .is_multiple_of(F::READ_SIZE.max(1))
        || len > flash.capacity() / 2
    {
        return None;
    }
    let mut padded = [0xFFu8; PADDED_MAX];
    flash.read(offset, padded.get_mut(..len)?).ok()?;
    let (record, sequence) = parse_record(padded.get(..len)?)?;
    Some(Stored {
        record,
        sequence,
        slot,
    })
}

/// The valid record with the newer sequence number, `None` if neither slot holds
/// a valid one (both equal: slot 0's). Takes the flash by value: pass `&mut flash`
/// (or, for a [`SimFlash`], `&flash`).
pub fn load<F: ReadNorFlash>(mut flash: F) -> Option<Stored> {
    match (read_slot(&mut flash, 0), read_slot(&mut flash, 1)) {
        (Some(a), Some(b)) => Some(if is_newer(b.sequence, a.sequence) {
            b
        } else {
            a
        }),
        (a, b) => a.or(b),
    }
}

/// Write `record` as the newest, in the slot that does not hold the newest valid
/// record (see the module documentation for the steps and the power-cut argument).
/// Returns where it went and its sequence number. Call only when
/// [`crate::controller::may_write_table`]. Takes the flash by value: pass
/// `&mut flash`.
pub fn store<F: NorFlash>(mut flash: F, record: &Record) -> Result<Stored, StoreError<F::Error>> {
    // The flash's units, and the slot's place and size.
    let (unit, padded_len) = write_units::<F>().ok_or(StoreError::Geometry)?;
    let half = flash.capacity() / 2;
    let whole_erase_units = half.is_multiple_of(F::ERASE_SIZE.max(1));
    if !whole_erase_units || !half.is_multiple_of(unit) || half < padded_len {
        return Err(StoreError::Geometry);
    }

    // 1. The other slot, and the next sequence number.
    let (slot, sequence) = match load(&mut flash) {
        Some(newest) => (1 - newest.slot, newest.sequence.wrapping_add(1)),
        None => (0, 1),
    };
    let start = slot_offset(flash.capacity(), slot).ok_or(StoreError::Geometry)?;
    let end = start
        .checked_add(u32::try_from(half).map_err(|_| StoreError::Geometry)?)
        .ok_or(StoreError::Geometry)?;
    let mut padded = [0xFFu8; PADDED_MAX];
    if let Some(bytes) = padded.get_mut(..RECORD_LEN) {
        bytes.copy_from_slice(&encode_record(record, sequence));
    }
    let (commit, body) = padded
        .get(..padded_len)
        .and_then(|p| p.split_at_checked(unit))
        .ok_or(StoreError::Geometry)?;
    let body_at = start.checked_add(unit as u32).ok_or(StoreError::Geometry)?;

    // 2. Erase it.
    flash.erase(start, end).map_err(StoreError::Flash)?;

    // 3. Everything after the commit unit; then read it back.
    flash.write(body_at, body).map_err(StoreError::Flash)?;
    let mut back = [0u8; PADDED_MAX];
    let back = back.get_mut(..body.len()).ok_or(StoreError::Geometry)?;
    flash.read(body_at, back).map_err(StoreError::Flash)?;
    if back != body {
        return Err(StoreError::Verify);
    }

    // 4. The commit: the unit holding the magic.
    flash.write(start, commit).map_err(StoreError::Flash)?;

    // 5. The whole record, read back and parsed.
    match read_slot(&mut flash, slot) {
        Some(stored) if stored.sequence == sequence && stored.record == *record => Ok(stored),
        _ => Err(StoreError::Verify),
    }
}
