//! The independent watchdog (IWDG, RM0090 section 19), at register level: its
//! timeout for the running loop, and a longer one around a flash sector erase.
//!
//! The IWDG counts down from `RLR` at the LSI divided by the prescaler and resets
//! the chip at 0; writing the feed key reloads it. Its clock, the LSI, is
//! 32 kHz nominal but 17-47 kHz over the STM32F405's range (datasheet, LSI
//! oscillator characteristics), so every timeout below is a range:
//!
//! ```text
//!   t = (RLR + 1) * div / f_LSI        (RM0090 19.3.3; f_LSI in 17..47 kHz)
//! ```
//!
//! | timeout | div | RLR | at 47 kHz | nominal 32 kHz | at 17 kHz |
//! | --- | --- | --- | --- | --- | --- |
//! | [`Timeout::RUN`] | 4 | 399 | 34 ms | 50 ms | 94 ms |
//! | [`Timeout::ERASE`] | 64 | 4095 | 5.6 s | 8.2 s | 15.4 s |
//!
//! `RUN` is what a hang of the control loop costs with the outputs at their last
//! duty (the hardware break and the E-stop interrupt still act): fed only by the
//! control task after a completed tick. `ERASE` covers a 128 KiB sector erase,
//! up to 2 s at 32-bit parallelism (datasheet `t_ERASE128KB`), during which every
//! instruction fetch from flash stalls, the control task's included: the loop
//! cannot run, so it cannot feed. An erase happens only with the motors stopped
//! (the link holds motion commands back while it stores).
//!
//! Changing `PR` and `RLR` takes up to 5 LSI periods to reach the watchdog's own
//! clock domain (`SR.PVU`, `SR.RVU`); [`set`] waits for that, bounded, then feeds,
//! so the new timeout counts from a full reload.

use stm32f4xx_hal::pac::{DBGMCU, IWDG};

/// A watchdog timeout: prescaler code and reload value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timeout {
    /// `IWDG_PR`: the divider is `4 << pr`.
    pr: u8,
    /// `IWDG_RLR` (12 bit).
    rlr: u16,
}

impl Timeout {
    /// The running loop's: 50 ms nominal (34-94 ms).
    pub const RUN: Timeout = Timeout { pr: 0, rlr: 399 };
    /// Around a sector erase: 8.2 s nominal (5.6-15.4 s), above its 2 s.
    pub const ERASE: Timeout = Timeout { pr: 4, rlr: 4095 };

    /// The timeout at an LSI of `lsi_hz`, ms.
    pub const fn ms_at(self, lsi_hz: u32) -> u32 {
        (self.rlr as u32 + 1) * (4 << self.pr) * 1000 / lsi_hz
    }
}

/// The LSI's range over the STM32F405's operating conditions, Hz (datasheet).
pub const LSI_MIN_HZ: u32 = 17_000;
/// See [`LSI_MIN_HZ`].
pub const LSI_MAX_HZ: u32 = 47_000;

// The running timeout stays within 100 ms at the slowest LSI, and the erase
// timeout holds a worst-case erase (2 s) twice over at the fastest.
const _: () = assert!(Timeout::RUN.ms_at(LSI_MIN_HZ) <= 100);
const _: () = assert!(Timeout::ERASE.ms_at(LSI_MAX_HZ) > 2_000 * 2);

/// The timeout's update did not reach the watchdog's clock domain in time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct UpdateTimedOut;

/// Polls of `IWDG_SR` before [`set`] gives up: over 2 ms at 168 MHz, against at
/// most 5 LSI periods (0.3 ms at 17 kHz).
const UPDATE_POLLS: u32 = 100_000;

/// The watchdog, owned by the control task, which alone feeds it.
pub struct Watchdog {
    _iwdg: IWDG,
}

fn iwdg() -> &'static stm32f4xx_hal::pac::iwdg::RegisterBlock {
    // SAFETY: the IWDG's registers are written only as below: the feed key (one
    // write), and the timeout by `set` under a critical section.
    unsafe { &*IWDG::ptr() }
}

/// Start the watchdog with [`Timeout::RUN`], frozen while a debugger halts the
/// core. Once started it cannot be stopped. If the timeout does not take, the
/// reset value stays (divider 4, `RLR` 4095: 512 ms nominal), which is logged.
pub fn start(iwdg: IWDG, dbgmcu: &DBGMCU) -> Watchdog {
    dbgmcu.apb1_fz().modify(|_, w| w.dbg_iwdg_stop().set_bit());
    iwdg.kr().write(|w| w.key().start());
    if set(Timeout::RUN).is_err() {
        defmt::error!("watchdog: the 50 ms timeout did not take; 512 ms in force");
    }
    Watchdog { _iwdg: iwdg }
}

impl Watchdog {
    /// Reload the counter: one more timeout before a reset.
    #[inline]
    pub fn feed(&mut self) {
        iwdg().kr().write(|w| w.key().feed());
    }
}

/// Set the timeout, wait until the watchdog took it, and feed. Callable from the
/// idle task (the flash store) while the control task feeds: the unlocked
/// writes run with interrupts off, as a feed in between would lock the
/// registers again. Err if the update did not complete (the old timeout may
/// still be in force).
pub fn set(timeout: Timeout) -> Result<(), UpdateTimedOut> {
    let r = iwdg();
    // A previous update still in progress (one that timed out) must end first
    // (RM0090 19.4: PR and RLR may change only with PVU and RVU clear).
    wait_updated(r)?;
    cortex_m::interrupt::free(|_| {
        r.kr().write(|w| w.key().unlock());
        // SAFETY: `pr` is a 3-bit prescaler code (0..=6), `rlr` a 12-bit value.
        r.pr().write(|w| unsafe { w.pr().bits(timeout.pr) });
        r.rlr().write(|w| unsafe { w.rl().bits(timeout.rlr) });
    });
    wait_updated(r)?;
    r.kr().write(|w| w.key().feed());
    Ok(())
}

/// Wait, bounded, until the prescaler and reload updates have reached the
/// watchdog's clock domain (SR.PVU and SR.RVU clear).
fn wait_updated(r: &stm32f4xx_hal::pac::iwdg::RegisterBlock) -> Result<(), UpdateTimedOut> {
    let mut polls = 0;
    while r.sr().read().bits() & 0b11 != 0 {
        polls += 1;
        if polls >= UPDATE_POLLS {
            return Err(UpdateTimedOut);
        }
    }
    Ok(())
}
