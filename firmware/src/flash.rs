//! The STM32F405's parameter sectors as an `embedded-storage` NOR flash
//! ([`NorFlash`], what `shared::storage` writes its records through): erase whole
//! sectors, program 32-bit words, read (RM0090 section 3.6, "Flash program/erase
//! operations").
//!
//! The flash this driver shows is sectors 10 and 11 only (`PARAM_BASE`, 128 KiB
//! each, kept out of the program by `memory.x`): offset 0 is `0x080C0000` (sector
//! 10), offset 128 Ki `0x080E0000` (sector 11), and the capacity is 256 KiB. An offset
//! beyond them is out of bounds, so no offset can reach the program. Erase ranges are
//! whole sectors (`ERASE_SIZE` 128 KiB); programs are whole aligned words
//! (`WRITE_SIZE` 4).
//!
//! Register level, not the HAL's `UnlockedFlash`: that one erases and programs
//! with 8-bit parallelism, which makes a 128 KiB sector erase take up to 4 s
//! (datasheet `t_ERASE128KB`, x8); with the 32-bit parallelism of a 2.7-3.6 V
//! supply it takes 1-2 s.
//!
//! While a sector is erased, every read of the flash stalls, instruction fetches
//! included (RM0090 3.5.4; the F405 has one bank): no task runs, the control
//! task neither, so nothing feeds the 50 ms watchdog. Each sector's erase
//! lengthens it to [`watchdog::Timeout::ERASE`] and restores
//! [`watchdog::Timeout::RUN`] after; if that cannot be restored, the bridges are
//! cut and the board waits for the watchdog reset (and starts in `Fault`). The link stores only with the motors
//! stopped, and holds motion commands back until the store ends; the outputs
//! stay cut (MOE = 0) and the hardware break still acts. A word program stalls
//! reads for about 16 us, which the control loop rides through.

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashError, NorFlashErrorKind,
    ReadNorFlash,
};
use stm32f4xx_hal::pac::FLASH;

use crate::watchdog::{self, Timeout};

/// First and second key of `FLASH_KEYR` (RM0090 3.5.1).
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
/// `FLASH_CR.PSIZE` for 32-bit parallelism.
const PSIZE_X32: u8 = 0b10;

/// Address of offset 0: sector 10 (RM0090, table 5 "Flash module organization").
const PARAM_BASE: u32 = 0x080C_0000;
/// Sector number of offset 0, as `FLASH_CR.SNB` takes it.
const FIRST_SECTOR: u8 = 10;
/// Bytes of each parameter sector.
const SECTOR_SIZE: u32 = 128 * 1024;
/// Parameter sectors: 10 and 11, the last two of the 1 MiB flash.
const SECTORS: u32 = 2;
// They end where the flash ends (1 MiB at 0x08000000).
const _: () = assert!(PARAM_BASE + SECTORS * SECTOR_SIZE == 0x0810_0000);

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// The range is outside the parameter sectors.
    OutOfRange,
    /// An offset or a length is not whole words (program) or whole sectors (erase).
    NotAligned,
    /// The controller stayed locked after the key sequence.
    Locked,
    /// `FLASH_SR` error bits after the operation (PGSERR, PGPERR, PGAERR, WRPERR,
    /// OPERR), as read.
    Status(u32),
    /// The watchdog could not be lengthened for an erase (nothing erased). One
    /// that cannot be set back to its running timeout after an erase does not
    /// return: the board waits, bridges cut, for the watchdog reset.
    Watchdog,
    /// The bridges' outputs were enabled: no erase, which would stall the control
    /// task for seconds with the motors driven.
    MotorsDriven,
}

/// `FLASH_SR` error bits: OPERR (1), WRPERR (4), PGAERR (5), PGPERR (6), PGSERR (7).
const SR_ERRORS: u32 = (1 << 1) | (1 << 4) | (1 << 5) | (1 << 6) | (1 << 7);

/// The flash controller, locked between operations.
pub struct ParamFlash {
    flash: FLASH,
}

impl ParamFlash {
    /// Take the flash controller (locked).
    pub fn new(flash: FLASH) -> Self {
        flash.cr().modify(|_, w| w.lock().set_bit());
        ParamFlash { flash }
    }

    /// Unlock, run `op`, wait until not busy, check the error bits, lock again.
    fn with_unlocked(&mut self, op: impl FnOnce(&FLASH)) -> Result<(), FlashError> {
        let f = &self.flash;
        while f.sr().read().bsy().bit_is_set() {}
        if f.cr().read().lock().bit_is_set() {
            f.keyr().write(|w| unsafe { w.key().bits(KEY1) });
            f.keyr().write(|w| unsafe { w.key().bits(KEY2) });
        }
        if f.cr().read().lock().bit_is_set() {
            return Err(FlashError::Locked);
        }
        // Clear stale error flags (write 1 to clear).
        f.sr().write(|w| unsafe { w.bits(SR_ERRORS | 1) });
        op(f);
        cortex_m::asm::dsb();
        while f.sr().read().bsy().bit_is_set() {}
        let errors = f.sr().read().bits() & SR_ERRORS;
        f.cr()
            .modify(|_, w| w.ser().clear_bit().pg().clear_bit().lock().set_bit());
        flush_data_cache(f);
        if errors != 0 {
            return Err(FlashError::Status(errors));
        }
        Ok(())
    }
}

/// Reset the flash data cache so that reads after an erase or a program see the
/// new contents (RM0090 3.5.2: the cache is reset only while disabled).
fn flush_data_cache(f: &FLASH) {
    let enabled = f.acr().read().dcen().bit_is_set();
    f.acr().modify(|_, w| w.dcen().clear_bit());
    f.acr().modify(|_, w| w.dcrst().set_bit());
    f.acr().modify(|_, w| w.dcrst().clear_bit());
    if enabled {
        f.acr().modify(|_, w| w.dcen().set_bit());
    }
}

impl ParamFlash {
    /// Sector erase (RM0090 3.6.3): SER, SNB, PSIZE x32, then STRT; the watchdog
    /// lengthened around it, and never with the bridges' outputs on.
    fn erase_sector(&mut self, snb: u8) -> Result<(), FlashError> {
        // The watchdog outlasts the stall (module documentation), or no erase.
        watchdog::set(Timeout::ERASE).map_err(|_| FlashError::Watchdog)?;
        let mut started = false;
        let erased = self.with_unlocked(|f| {
            f.cr().modify(|_, w| unsafe {
                w.pg().clear_bit();
                w.ser().set_bit();
                w.snb().bits(snb);
                w.psize().bits(PSIZE_X32)
            });
            // Never with the bridges on (the link checks the motors stopped and
            // holds run commands and self-tests back while it stores; this is the
            // last line): the check and the start with interrupts off, so the
            // control task cannot set MOE in between.
            cortex_m::interrupt::free(|_| {
                if !crate::motor_out::outputs_enabled() {
                    f.cr().modify(|_, w| w.strt().set_bit());
                    started = true;
                }
            });
        });
        if watchdog::set(Timeout::RUN).is_err() {
            // The loop would run on under the erase's seconds-long timeout, where
            // a hang must end within 100 ms: the one safe state left is the reset.
            // Bridges off, interrupts off (nothing runs, nothing feeds), and the
            // watchdog resets the chip within Timeout::ERASE; the next start reads
            // the watchdog flag and the controller starts in Fault.
            defmt::error!("watchdog not set back to its running timeout after an erase: bridges cut, waiting for the watchdog reset");
            crate::motor_out::cut();
            cortex_m::interrupt::disable();
            loop {
                cortex_m::asm::wfi();
            }
        }
        erased?;
        if !started {
            return Err(FlashError::MotorsDriven);
        }
        Ok(())
    }

    /// Word program (RM0090 3.6.4): PG with PSIZE x32, then one aligned word write
    /// at `address` (checked by the caller: an aligned word of a parameter sector).
    fn program_word(&mut self, address: u32, word: u32) -> Result<(), FlashError> {
        self.with_unlocked(|f| {
            f.cr().modify(|_, w| unsafe {
                w.ser().clear_bit();
                w.psize().bits(PSIZE_X32);
                w.pg().set_bit()
            });
            // SAFETY: `address` is an aligned word inside a parameter sector, which
            // memory.x keeps out of the program; the controller is unlocked with PG.
            unsafe { core::ptr::write_volatile(address as *mut u32, word) };
        })
    }
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfRange => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            _ => NorFlashErrorKind::Other,
        }
    }
}

impl From<NorFlashErrorKind> for FlashError {
    /// The error of a failed `embedded-storage` range check.
    fn from(kind: NorFlashErrorKind) -> Self {
        match kind {
            NorFlashErrorKind::NotAligned => FlashError::NotAligned,
            _ => FlashError::OutOfRange,
        }
    }
}

impl ErrorType for ParamFlash {
    type Error = FlashError;
}

impl ReadNorFlash for ParamFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        check_read(self, offset, bytes.len())?;
        let start = PARAM_BASE + offset;
        for (i, byte) in bytes.iter_mut().enumerate() {
            // SAFETY: inside the parameter sectors (checked above), always readable.
            *byte = unsafe { core::ptr::read_volatile((start as usize + i) as *const u8) };
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        (SECTORS * SECTOR_SIZE) as usize
    }
}

impl NorFlash for ParamFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SECTOR_SIZE as usize;

    /// Erase the sectors of `[from, to)` (whole sectors), one after the other.
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        check_erase(self, from, to)?;
        for index in from / SECTOR_SIZE..to / SECTOR_SIZE {
            let snb = FIRST_SECTOR + u8::try_from(index).map_err(|_| FlashError::OutOfRange)?;
            self.erase_sector(snb)?;
        }
        Ok(())
    }

    /// Program `bytes` (whole aligned words) at `offset`, word by word in address
    /// order, each word little-endian as the core stores it.
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        check_write(self, offset, bytes.len())?;
        let mut address = PARAM_BASE + offset;
        for word in bytes.chunks_exact(4) {
            let word = <[u8; 4]>::try_from(word).map_err(|_| FlashError::NotAligned)?;
            self.program_word(address, u32::from_le_bytes(word))?;
            address += 4;
        }
        Ok(())
    }
}
