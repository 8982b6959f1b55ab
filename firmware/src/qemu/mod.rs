//! The `qemu` build's replacement of the peripheral layer (cargo feature `qemu`;
//! `docs/firmware-qemu.md`). QEMU 7.2's `netduinoplus2` emulates the core, the
//! NVIC, SysTick and the USARTs, but not RCC, GPIO, TIM1/TIM8, the watchdog or
//! flash writes, so this build:
//!
//! - ticks the control task from SysTick ([`cycles`]) instead of TIM7;
//! - reads and drives a model of the two rotors and encoders ([`plant`]) instead
//!   of the encoder timers, ADC and H-bridges, through the board's own bridge
//!   driver (`Drive`) over emulated compare registers ([`pwm`]);
//! - stores parameters in RAM ([`shared::storage::SimFlash`]);
//! - runs a scripted host in `idle` ([`script`], over [`host`]) that talks to the
//!   real `Link::poll` in bytes, and injects faults into the model ([`world`]);
//! - measures the stack ([`stack`]) and the control step's instruction count;
//! - logs over semihosting and exits with the verdict of its checks ([`checks`]).
//!
//! With the cargo feature `qemu-uart` as well, the scripted host, its checks and
//! the measurements are left out: the link runs on the emulated USART2 ([`uart`]),
//! for a real host (`host-sim device --port tcp:...`) to talk to, and the run
//! lasts until QEMU is stopped.

// `qemu-uart` uses only `exit` (the panic handler's).
#[cfg_attr(feature = "qemu-uart", allow(dead_code, unused_macros, unused_imports))]
pub mod checks;
#[cfg_attr(feature = "qemu-uart", allow(dead_code))]
pub mod cycles;
#[cfg(not(feature = "qemu-uart"))]
pub mod host;
#[cfg_attr(feature = "qemu-uart", allow(dead_code))]
pub mod plant;
pub mod pwm;
#[cfg(not(feature = "qemu-uart"))]
pub mod script;
#[cfg(not(feature = "qemu-uart"))]
pub mod stack;
#[cfg(feature = "qemu-uart")]
pub mod uart;
#[cfg(not(feature = "qemu-uart"))]
pub mod world;

use core::sync::atomic::{AtomicU32, Ordering};

/// Control ticks since start.
static TICK: AtomicU32 = AtomicU32::new(0);

/// The control tick number: 0 before the first tick.
pub fn tick() -> u32 {
    TICK.load(Ordering::Relaxed)
}

/// Count one more control tick; its number.
pub fn next_tick() -> u32 {
    TICK.fetch_add(1, Ordering::Relaxed) + 1
}

// Every log line carries the control tick: firmware time, the same every run.
defmt::timestamp!("{=u32:05}", tick());
