//! [`SimFlash`]: a simulated pair of parameter sectors for host tests and host-sim,
//! with the STM32F4's rules and a power cut that can be set to happen after any
//! number of bytes.
//!
//! Only the first [`SIM_SECTOR_BYTES`] of each of the [`PARAM_SECTORS`] are
//! modelled (a record is [`super::RECORD_LEN`] bytes); reading past them inside the
//! sector gives `0xFF`, programming there is [`SimError::OutOfRange`].
//!
//! # The power-cut model
//!
//! Work is counted in bytes: an erase changes the modelled bytes of its sector one
//! after the other, in address order ([`SIM_SECTOR_BYTES`] bytes); programming a
//! word changes its 4 bytes in address order. [`SimFlash::cut_after`]`(n)` lets `n`
//! more bytes complete; the next byte is left *half done* (an erase sets only its
//! low 4 bits; a program clears only the 0 bits of its low 4 bits), the operation
//! returns [`SimError::PowerCut`], and so does every later erase or program until
//! [`SimFlash::power_on`]. Reads always work (they model the next boot).

use super::{Flash, Sector, PARAM_SECTORS};

/// Bytes modelled at the start of each sector.
pub const SIM_SECTOR_BYTES: usize = 1024;

/// Why a [`SimFlash`] operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SimError {
    /// The power was cut during (or before) this operation.
    PowerCut,
    /// The address is outside the modelled bytes, or the sector is not a parameter
    /// sector.
    OutOfRange,
    /// The address is not a multiple of 4.
    Unaligned,
    /// The word is not erased: on the chip programming can only clear bits, and a
    /// second program of a word is a bug in the caller.
    NotErased,
}

/// Two simulated parameter sectors; see the [module documentation](self).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimFlash {
    /// The modelled bytes of each sector.
    bytes: [[u8; SIM_SECTOR_BYTES]; 2],
    /// Bytes that may still complete before the power is cut; `None`: no cut set.
    budget: Option<usize>,
    /// The power is off.
    off: bool,
    /// Erases done (whole ones).
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
            bytes: [[value; SIM_SECTOR_BYTES]; 2],
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

    /// The modelled bytes of sector `slot` (0 or 1) of [`PARAM_SECTORS`].
    pub fn sector_bytes(&self, slot: usize) -> Option<&[u8; SIM_SECTOR_BYTES]> {
        self.bytes.get(slot)
    }

    /// Xor the byte at `address` with `mask` (a bit flip, whatever the rules): for
    /// tests of corrupt records.
    pub fn corrupt(&mut self, address: u32, mask: u8) -> Result<(), SimError> {
        let (slot, offset) = locate(address).ok_or(SimError::OutOfRange)?;
        let byte = self.byte_mut(slot, offset).ok_or(SimError::OutOfRange)?;
        *byte ^= mask;
        Ok(())
    }

    /// Whole erases done.
    pub fn erases(&self) -> u32 {
        self.erases
    }

    /// Whole words programmed.
    pub fn words_programmed(&self) -> u32 {
        self.words
    }

    /// The byte of sector `slot` at `offset`.
    fn byte_mut(&mut self, slot: usize, offset: usize) -> Option<&mut u8> {
        self.bytes.get_mut(slot)?.get_mut(offset)
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
}

/// The parameter sector and the offset in it of `address`, if it is modelled.
fn locate(address: u32) -> Option<(usize, usize)> {
    PARAM_SECTORS.iter().enumerate().find_map(|(slot, s)| {
        let offset = usize::try_from(address.checked_sub(s.address)?).ok()?;
        (offset < SIM_SECTOR_BYTES).then_some((slot, offset))
    })
}

impl Flash for SimFlash {
    type Error = SimError;

    fn erase(&mut self, sector: &Sector) -> Result<(), SimError> {
        if self.off {
            return Err(SimError::PowerCut);
        }
        let slot = PARAM_SECTORS
            .iter()
            .position(|s| s == sector)
            .ok_or(SimError::OutOfRange)?;
        for offset in 0..SIM_SECTOR_BYTES {
            let done = self.work();
            let byte = self.byte_mut(slot, offset).ok_or(SimError::OutOfRange)?;
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

    fn program_word(&mut self, address: u32, word: u32) -> Result<(), SimError> {
        if self.off {
            return Err(SimError::PowerCut);
        }
        if address & 3 != 0 {
            return Err(SimError::Unaligned);
        }
        let (slot, offset) = locate(address).ok_or(SimError::OutOfRange)?;
        let erased = self
            .bytes
            .get(slot)
            .and_then(|s| s.get(offset..offset + 4))
            .ok_or(SimError::OutOfRange)?
            .iter()
            .all(|&b| b == 0xFF);
        if !erased {
            return Err(SimError::NotErased);
        }
        for (i, value) in word.to_le_bytes().into_iter().enumerate() {
            let done = self.work();
            let byte = self
                .byte_mut(slot, offset + i)
                .ok_or(SimError::OutOfRange)?;
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

    fn read(&self, address: u32, out: &mut [u8]) -> Result<(), SimError> {
        let sector = PARAM_SECTORS
            .iter()
            .find(|s| address >= s.address && address - s.address < s.size)
            .ok_or(SimError::OutOfRange)?;
        for (i, slot) in out.iter_mut().enumerate() {
            let a = address.checked_add(i as u32).ok_or(SimError::OutOfRange)?;
            if a - sector.address >= sector.size {
                return Err(SimError::OutOfRange);
            }
            *slot = match locate(a) {
                Some((s, offset)) => self
                    .bytes
                    .get(s)
                    .and_then(|b| b.get(offset))
                    .copied()
                    .unwrap_or(0xFF),
                None => 0xFF,
            };
        }
        Ok(())
    }
}
