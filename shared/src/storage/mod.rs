//! Parameters in flash (issue 5): the tuning table and the self-test results, in
//! two flash sectors used in turn, so that a power cut during a write never loses
//! the last good copy (after ODrive's `Firmware/Drivers/STM32/nvm.c`).
//!
//! - [`Flash`]: what the storage needs from the chip (erase, program words, read),
//!   with the STM32F4's rules;
//! - [`record`]: the record layout (magic, version, length, sequence, payload,
//!   CRC-32) and its checks;
//! - [`sim`]: [`SimFlash`], a simulated flash that can lose power at any byte.
//!
//! # Two sectors in turn
//!
//! Sectors 10 and 11 of the STM32F405 ([`PARAM_SECTORS`], 128 KiB each at
//! `0x080C0000` and `0x080E0000`, kept out of the program by `memory.x`) each hold
//! at most one record, at the start of the sector. [`load`] reads both and takes the
//! valid one with the newer sequence number. [`store`]:
//!
//! 1. finds the sector that does *not* hold the newest valid record (sector 10 when
//!    neither is valid);
//! 2. erases it (every byte `0xFF`);
//! 3. programs the record's words from the second to the last (everything but the
//!    magic), then reads them back;
//! 4. programs the first word, the magic: the commit;
//! 5. reads the whole record back and parses it.
//!
//! # Why a power cut at any moment keeps the last good record
//!
//! The newest valid record is never erased nor written: only the other sector is.
//! Until the magic's last bit is programmed, the written sector's first word is not
//! [`record::MAGIC`] (erased `0xFFFFFFFF`, or a partly programmed word that still has
//! some of the 1 bits that should be 0), so its record is invalid and [`load`] returns
//! the previous one. A cut during the erase leaves that sector with the older record,
//! partly erased bytes, or `0xFF`: an older or invalid record, never a newer valid one
//! except with the chance of a CRC-32 collision (`2^-32`). Once the magic is
//! programmed, every other word was programmed and verified before it, so the new
//! record is whole and, with the higher sequence number, the one [`load`] takes.
//! `tests/storage.rs` checks this with [`SimFlash`] cut after every byte of a store.
//!
//! # Motors stopped
//!
//! Erasing a 128 KiB sector takes about 1 s (2 s at most, STM32F405 datasheet,
//! `t_ERASE128KB` at 32-bit parallelism), and while the flash is busy the CPU stalls
//! on every fetch from flash: the control loop does not run. So the firmware writes
//! only when [`crate::controller::may_write_table`] says the driver is off and the
//! rotors at rest, it feeds or times its watchdog to outlast the erase, and it
//! restarts its control tick timing afterwards.

pub mod record;
pub mod sim;

pub use record::{encode_record, parse_record, Record, MAGIC, RECORD_LEN};
pub use sim::{SimError, SimFlash};

/// A flash sector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sector {
    /// Sector number, as the erase command takes it (`FLASH_CR.SNB` on the STM32F4).
    pub number: u8,
    /// First byte's address.
    pub address: u32,
    /// Size, bytes.
    pub size: u32,
}

/// The two parameter sectors of the STM32F405 (RM0090, table 5 "Flash module
/// organization"): sectors 10 and 11, 128 KiB each.
pub const PARAM_SECTORS: [Sector; 2] = [
    Sector {
        number: 10,
        address: 0x080C_0000,
        size: 128 * 1024,
    },
    Sector {
        number: 11,
        address: 0x080E_0000,
        size: 128 * 1024,
    },
];

/// What the storage needs from a flash, with the STM32F4's rules:
///
/// - an erase works on a whole sector and sets every byte to `0xFF`; it is slow
///   (about 1 s for 128 KiB);
/// - programming works on aligned 32-bit words (the 32-bit parallelism of a 2.7 to
///   3.6 V supply) and can only turn 1 bits into 0: a word is programmed once
///   after an erase (programming a word that is not erased is an error here);
/// - a word reads back as it was programmed, least significant byte first.
pub trait Flash {
    /// Why an operation failed (the controller's error flags; a power cut in
    /// [`SimFlash`]).
    type Error: core::fmt::Debug;

    /// Erase `sector`: every byte `0xFF`. Blocks until done.
    fn erase(&mut self, sector: &Sector) -> Result<(), Self::Error>;

    /// Program the word at `address` (a multiple of 4) with `word` (bytes
    /// `word.to_le_bytes()`). Blocks until done.
    fn program_word(&mut self, address: u32, word: u32) -> Result<(), Self::Error>;

    /// Read `out.len()` bytes from `address`.
    fn read(&self, address: u32, out: &mut [u8]) -> Result<(), Self::Error>;
}

/// A record found in flash.
#[derive(Clone, Debug, PartialEq)]
pub struct Stored {
    /// What it holds.
    pub record: Record,
    /// Its sequence number.
    pub sequence: u32,
    /// The index of its sector in [`PARAM_SECTORS`] (0 or 1).
    pub slot: usize,
}

/// Why [`store`] failed. The previous record is intact in every case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The flash reported an error.
    Flash(E),
    /// A word read back differs from the one written (worn or faulty flash).
    Verify,
}

/// Whether sequence number `a` is newer than `b`, modulo `2^32` (serial number
/// arithmetic: the two records differ by one).
pub fn is_newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The record in sector `slot`, if valid.
fn read_slot<F: Flash + ?Sized>(flash: &F, slot: usize) -> Option<Stored> {
    let sector = PARAM_SECTORS.get(slot)?;
    let mut bytes = [0u8; RECORD_LEN];
    flash.read(sector.address, &mut bytes).ok()?;
    let (record, sequence) = parse_record(&bytes)?;
    Some(Stored {
        record,
        sequence,
        slot,
    })
}

/// The valid record with the newer sequence number, `None` if neither sector holds
/// a valid one (both equal: the first sector's).
pub fn load<F: Flash + ?Sized>(flash: &F) -> Option<Stored> {
    match (read_slot(flash, 0), read_slot(flash, 1)) {
        (Some(a), Some(b)) => Some(if is_newer(b.sequence, a.sequence) {
            b
        } else {
            a
        }),
        (a, b) => a.or(b),
    }
}

/// Write `record` as the newest, in the sector that does not hold the newest valid
/// record (see the module documentation for the steps and the power-cut argument).
/// Returns where it went and its sequence number. Call only when
/// [`crate::controller::may_write_table`].
pub fn store<F: Flash + ?Sized>(
    flash: &mut F,
    record: &Record,
) -> Result<Stored, StoreError<F::Error>> {
    // 1. The other sector, and the next sequence number.
    let (slot, sequence) = match load(flash) {
        Some(newest) => (1 - newest.slot, newest.sequence.wrapping_add(1)),
        None => (0, 1),
    };
    let Some(sector) = PARAM_SECTORS.get(slot) else {
        return Err(StoreError::Verify);
    };
    let bytes = encode_record(record, sequence);

    // 2. Erase it.
    flash.erase(sector).map_err(StoreError::Flash)?;

    // 3. Every word but the magic, in address order; then read them back.
    let mut address = sector.address;
    for word in bytes.chunks_exact(4).skip(1) {
        address += 4;
        let w = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
        flash.program_word(address, w).map_err(StoreError::Flash)?;
    }
    let mut back = [0u8; RECORD_LEN];
    flash
        .read(sector.address, &mut back)
        .map_err(StoreError::Flash)?;
    if back.get(4..) != bytes.get(4..) {
        return Err(StoreError::Verify);
    }

    // 4. The commit: the magic.
    flash
        .program_word(sector.address, MAGIC)
        .map_err(StoreError::Flash)?;

    // 5. The whole record, read back and parsed.
    match read_slot(flash, slot) {
        Some(stored) if stored.sequence == sequence && stored.record == *record => Ok(stored),
        _ => Err(StoreError::Verify),
    }
}
