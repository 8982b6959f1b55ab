//! The STM32F405's flash controller as a [`shared::storage::Flash`]: erase a
//! parameter sector, program 32-bit words, read (RM0090 section 3.6, "Flash
//! program/erase operations").
//!
//! Register level, not the HAL's `UnlockedFlash`: that one erases and programs
//! with 8-bit parallelism, which makes a 128 KiB sector erase take up to 4 s
//! (datasheet `t_ERASE128KB`, x8); with the 32-bit parallelism of a 2.7-3.6 V
//! supply it takes 1-2 s.
//!
//! While a sector is erased, every read of the flash stalls, instruction fetches
//! included (RM0090 3.5.4; the F405 has one bank): no task runs, the control
//! task neither, so nothing feeds the 50 ms watchdog. [`ParamFlash::erase`]
//! lengthens it to [`watchdog::Timeout::ERASE`] for the erase and restores
//! [`watchdog::Timeout::RUN`] after. The link stores only with the motors
//! stopped, and holds motion commands back until the store ends; the outputs
//! stay cut (MOE = 0) and the hardware break still acts. A word program stalls
//! reads for about 16 us, which the control loop rides through.
//!
//! Only the sectors of [`PARAM_SECTORS`] may be erased or programmed: any other
//! address is refused, so a bad record address can never touch the program.

use shared::storage::{Flash, Sector, PARAM_SECTORS};
use stm32f4xx_hal::pac::FLASH;

use crate::watchdog::{self, Timeout};

/// First and second key of `FLASH_KEYR` (RM0090 3.5.1).
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
/// `FLASH_CR.PSIZE` for 32-bit parallelism.
const PSIZE_X32: u8 = 0b10;

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// The address or sector is not one of the parameter sectors, or not aligned.
    OutOfRange,
    /// The controller stayed locked after the key sequence.
    Locked,
    /// `FLASH_SR` error bits after the operation (PGSERR, PGPERR, PGAERR, WRPERR,
    /// OPERR), as read.
    Status(u32),
    /// The watchdog could not be lengthened for an erase (nothing erased), or
    /// not set back to its running timeout after one.
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

    /// Whether `[address, address + len)` lies inside one parameter sector.
    fn in_params(address: u32, len: u32) -> bool {
        PARAM_SECTORS.iter().any(|s| {
            address >= s.address
                && address
                    .checked_add(len)
                    .is_some_and(|end| end <= s.address + s.size)
        })
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

impl Flash for ParamFlash {
    type Error = FlashError;

    /// Sector erase (RM0090 3.6.3): SER, SNB, PSIZE x32, then STRT.
    fn erase(&mut self, sector: &Sector) -> Result<(), FlashError> {
        if !PARAM_SECTORS.contains(sector) {
            return Err(FlashError::OutOfRange);
        }
        let snb = sector.number;
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
        let restored = watchdog::set(Timeout::RUN);
        if restored.is_err() {
            defmt::error!("watchdog not set back to its running timeout after an erase");
        }
        erased?;
        if !started {
            return Err(FlashError::MotorsDriven);
        }
        restored.map_err(|_| FlashError::Watchdog)
    }

    /// Word program (RM0090 3.6.4): PG with PSIZE x32, then one aligned word write.
    fn program_word(&mut self, address: u32, word: u32) -> Result<(), FlashError> {
        if address & 3 != 0 || !Self::in_params(address, 4) {
            return Err(FlashError::OutOfRange);
        }
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

    fn read(&self, address: u32, out: &mut [u8]) -> Result<(), FlashError> {
        let Ok(len) = u32::try_from(out.len()) else {
            return Err(FlashError::OutOfRange);
        };
        if !Self::in_params(address, len) {
            return Err(FlashError::OutOfRange);
        }
        for (i, byte) in out.iter_mut().enumerate() {
            // SAFETY: inside a parameter sector (checked above), always readable.
            *byte = unsafe { core::ptr::read_volatile((address as usize + i) as *const u8) };
        }
        Ok(())
    }
}
