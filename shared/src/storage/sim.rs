//! [`SimFlash`]: a simulated NOR flash of two sectors for host tests, host-sim and the
//! firmware's `qemu` build, with the STM32F4's rules and a power cut that can be set
//! to happen after any number of bytes. It implements `embedded-storage`'s
//! [`NorFlash`] like the board's driver: two erase units of [`SIM_SECTOR_SIZE`]
//! bytes (128 KiB, as sectors 10 and 11 of the STM32F405), programmed in 4-byte
//! words, read byte by byte.
//!
//! Only the first [`SIM_SECTOR_BYTES`] of each sector are modelled (a record is
//! [`super::RECORD_LEN`] bytes); reading past them inside the sector gives `0xFF`,
//! programming there is [`SimError::OutOfRange`].
//!
//! # The power-cut model
//!
//! Work is counted in bytes: an erase changes the modelled bytes of each of its
//! sectors one after the other, in address order ([`SIM_SECTOR_BYTES`] bytes a
//! sector); programming changes its bytes in address order, word by word.
//! [`SimFlash::cut_after`]`(n)` lets `n` more bytes complete; the next byte is left
//! *half done* (an erase sets only its low 4 bits; a program clears only the 0 bits
//! of its low 4 bits), the operation returns [`SimError::PowerCut`], and so does
//! every later erase or program until [`SimFlash::power_on`]. Reads always work
//! (they model the next boot); a shared reference reads too (`load(&flash)`).

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashError, NorFlashErrorKind,
    ReadNorFlash,
};

/// Bytes modelled at the start of each sector.
pub const SIM_SECTOR_BYTES: usize = 1024;

/// Bytes of a sector, the erase unit: 128 KiB, as the STM32F405's parameter sectors.
pub const SIM_SECTOR_SIZE: u32 = 128 * 1024;

/// Sectors simulated: one for each slot of the store.
const SECTORS: usize = 2;

/// Why a [`SimFlash`] operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SimError {
    /// The power was cut during (or before) this operation.
    PowerCut,
    /// The range is outside the flash, or outside the modelled bytes of a sector
    /// (programming).
    OutOfRange,
    /// An offset or a length is not a whole number of program words (4 bytes) or
    /// erase units (sectors).
    Unaligned,
    /// The word is not erased: on the chip programming can only clear bits, and a
    /// second program of a word is a bug in the caller.
    NotErased,
}

impl NorFlashError for SimError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            SimError::OutOfRange => NorFlashErrorKind::OutOfBounds,
            SimError::Unaligned => NorFlashErrorKind::NotAligned,
            SimError::PowerCut | SimError::NotErased => NorFlashErrorKind::Other,
        }
    }
}

impl From<NorFlashErrorKind> for SimError {
    /// The error of a failed `embedded-storage` range check.
    fn from(kind: NorFlashErrorKind) -> Self {
        match kind {
            NorFlashErrorKind::NotAligned => SimError::Unaligned,
            _ => SimError::OutOfRange,
        }
    }
}

/// Two simulated sectors; see the module documentation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimFlash {
    /// The modelled bytes of each sector.
    bytes: [[u8; SIM_SECTOR_BYTES]; SECTORS],
    /// Bytes that may still complete before the power is cut; `None`: no cut set.
    budget: Option<usize>,
    /// The power is off.
    off: bool,
    /// Sector erases done (whole ones).
    erases: u32,
    /// Words programmed (whole ones).
    words: u32,
}

impl Default for SimFlash {
    fn default() -> Self {
        SimFlash::new()
    }
}

impl SimFlash {
    /// Both sectors erased (`0xFF`), no cut set.
    pub fn new() -> Self {
        SimFlash::filled(0xFF)
    }

    /// Every modelled byte `value` (0 models zeroed flash, as QEMU's has).
    pub fn filled(value: u8) -> Self {
        SimFlash {
            bytes: [[value; SIM_SECTOR_BYTES]; SECTORS],
            budget: None,
            off: false,
            erases: 0,
            words: 0,
        }
    }

    /// Let `bytes` more bytes of erasing or programming complete, then cut the
    /// power in the middle of the next one.
    pub fn cut_after(&mut self, bytes: usize) {
        self.budget = Some(bytes);
    }

    /// Power back on, no cut set.
    pub fn power_on(&mut self) {
        self.budget = None;
        self.off = false;
    }

    /// Whether the power is off (a cut happened).
    pub fn is_off(&self) -> bool {
        self.off
    }

    /// The modelled bytes of sector `sector` (0 or 1).
    pub fn sector_bytes(&self, sector: usize) -> Option<&[u8; SIM_SECTOR_BYTES]> {
        self.bytes.get(sector)
    }

    /// Xor the byte at `offset` with `mask` (a bit flip, whatever the rules): for
    /// tests of corrupt records.
    pub fn corrupt(&mut self, offset: u32, mask: u8) -> Result<(), SimError> {
        let (sector, at) = locate(offset).ok_or(SimError::OutOfRange)?;
        let byte = self.byte_mut(sector, at).ok_or(SimError::OutOfRange)?;
        *byte ^= mask;
        Ok(())
    }

    /// Whole sector erases done.
    pub fn erases(&self) -> u32 {
        self.erases
    }

    /// Whole words programmed.
    pub fn words_programmed(&self) -> u32 {
        self.words
    }

    /// The byte of sector `sector` at `at`.
    fn byte_mut(&mut self, sector: usize, at: usize) -> Option<&mut u8> {
        self.bytes.get_mut(sector)?.get_mut(at)
    }

    /// Take one byte of work: `true` if it completes, `false` if the power goes
    /// now (the byte is half done by the caller).
    fn work(&mut self) -> bool {
        match self.budget {
            Some(0) => {
                self.off = true;
                self.budget = None;
                false
            }
            Some(n) => {
                self.budget = Some(n - 1);
                true
            }
            None => true,
        }
    }

    /// Erase the modelled bytes of sector `sector`, byte by byte.
    fn erase_sector(&mut self, sector: usize) -> Result<(), SimError> {
        for at in 0..SIM_SECTOR_BYTES {
            let done = self.work();
            let byte = self.byte_mut(sector, at).ok_or(SimError::OutOfRange)?;
            if !done {
                // Half erased: the low nibble set, the high one as it was.
                *byte |= 0x0F;
                return Err(SimError::PowerCut);
            }
            *byte = 0xFF;
        }
        self.erases += 1;
        Ok(())
    }

    /// Program the word at `offset` (a multiple of 4) with `word`, byte by byte.
    fn program_word(&mut self, offset: u32, word: [u8; 4]) -> Result<(), SimError> {
        let (sector, at) = locate(offset).ok_or(SimError::OutOfRange)?;
        let erased = self
            .bytes
            .get(sector)
            .and_then(|s| s.get(at..at + 4))
            .ok_or(SimError::OutOfRange)?
            .iter()
            .all(|&b| b == 0xFF);
        if !erased {
            return Err(SimError::NotErased);
        }
        for (i, value) in word.into_iter().enumerate() {
            let done = self.work();
            let byte = self.byte_mut(sector, at + i).ok_or(SimError::OutOfRange)?;
            if !done {
                // Half programmed: only the low nibble's zeros cleared.
                *byte &= value | 0xF0;
                return Err(SimError::PowerCut);
            }
            *byte &= value;
        }
        self.words += 1;
        Ok(())
    }

    /// Read `out.len()` bytes from `offset`: what the chip would show.
    fn read_bytes(&self, offset: u32, out: &mut [u8]) -> Result<(), SimError> {
        check_read(self, offset, out.len())?;
        for (i, slot) in out.iter_mut().enumerate() {
            let at = offset.checked_add(i as u32).ok_or(SimError::OutOfRange)?;
            *slot = locate(at)
                .and_then(|(sector, at)| self.bytes.get(sector)?.get(at).copied())
                .unwrap_or(0xFF);
        }
        Ok(())
    }
}

/// The sector and the offset in it of `offset`, if that byte is modelled.
fn locate(offset: u32) -> Option<(usize, usize)> {
    let sector = usize::try_from(offset / SIM_SECTOR_SIZE).ok()?;
    let at = usize::try_from(offset % SIM_SECTOR_SIZE).ok()?;
    (sector < SECTORS && at < SIM_SECTOR_BYTES).then_some((sector, at))
}

impl ErrorType for SimFlash {
    type Error = SimError;
}

impl ReadNorFlash for SimFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), SimError> {
        self.read_bytes(offset, bytes)
    }

    fn capacity(&self) -> usize {
        SECTORS * SIM_SECTOR_SIZE as usize
    }
}

impl NorFlash for SimFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SIM_SECTOR_SIZE as usize;

    /// Erase the sectors of `[from, to)`, in order.
    fn erase(&mut self, from: u32, to: u32) -> Result<(), SimError> {
        if self.off {
            return Err(SimError::PowerCut);
        }
        check_erase(self, from, to)?;
        for sector in from / SIM_SECTOR_SIZE..to / SIM_SECTOR_SIZE {
            self.erase_sector(sector as usize)?;
        }
        Ok(())
    }

    /// Program `bytes` at `offset`, word by word in address order.
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), SimError> {
        if self.off {
            return Err(SimError::PowerCut);
        }
        check_write(self, offset, bytes.len())?;
        for (i, word) in bytes.chunks_exact(4).enumerate() {
            let at = offset
                .checked_add(4 * i as u32)
                .ok_or(SimError::OutOfRange)?;
            let word = <[u8; 4]>::try_from(word).map_err(|_| SimError::Unaligned)?;
            self.program_word(at, word)?;
        }
        Ok(())
    }
}

/// Reading through a shared reference: the simulation's reads change nothing, so
/// `load(&flash)` works on a flash that is only borrowed.
impl ErrorType for &SimFlash {
    type Error = SimError;
}

impl ReadNorFlash for &SimFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), SimError> {
        self.read_bytes(offset, bytes)
    }

    fn capacity(&self) -> usize {
        SimFlash::capacity(self)
    }
}
