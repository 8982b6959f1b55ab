//! The peripheral layer's replacement in QEMU (cargo feature `qemu`;
//! `docs/firmware-qemu.md`). QEMU 7.2's `netduinoplus2` emulates the core, the
//! NVIC, SysTick and the USARTs, but not RCC, GPIO, TIM1/TIM8, the watchdog or
//! flash writes, so the `qemu` binaries:
//!
//! - ticks the control task from SysTick ([`cycles`]) instead of TIM7;
//! - reads and drives a model of the two rotors and encoders ([`plant`]) instead
//!   of the encoder timers, ADC and H-bridges, through the board's own bridge
//!   driver (`Drive`) over emulated compare registers ([`pwm`]);
//! - stores parameters in RAM ([`shared::storage::SimFlash`]);
//! - runs a scripted host in `idle` ([`script`], over [`host`]) that talks to the
//!   real `Link::poll` in bytes, and injects faults into the model ([`world`]);
//! - measures the stack ([`stack`]) and the control step's instruction count
//!   ([`counter`]);
//! - logs over semihosting and exits with the verdict of its checks ([`checks`]).
//!
//! The binary `qemu` runs the scripted host; the binary `qemu-uart` leaves out the
//! scripted host, its checks and the measurements and serves the link on the
//! emulated USART2 ([`uart`]), for a real host (`host-sim device --port tcp:...`)
//! to talk to; its run lasts until QEMU is stopped. Both tick the controller
//! through [`control`] and reach their safe state through [`safe_state`].

pub mod checks;
pub mod control;
pub mod counter;
pub mod cycles;
pub mod host;
pub mod plant;
pub mod pwm;
pub mod report;
pub mod safe_state;
pub mod script;
pub mod stack;
pub mod uart;
pub mod world;

use core::sync::atomic::{AtomicU32, Ordering};

/// Control ticks since start.
static TICK: AtomicU32 = AtomicU32::new(0);

/// The control tick number: 0 before the first tick. The `qemu` binaries' log
/// timestamp: firmware time, the same every run.
pub fn tick() -> u32 {
    TICK.load(Ordering::Relaxed)
}

/// Count one more control tick; its number.
pub fn next_tick() -> u32 {
    TICK.fetch_add(1, Ordering::Relaxed) + 1
}
