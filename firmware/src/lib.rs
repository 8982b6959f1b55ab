//! Firmware of the vibro driver for the STM32F405RG: two brushed DC motors with
//! unbalance rotors, driven by the shared phase controller.
//!
//! This library holds what the firmware's apps share; each app is one binary in
//! `src/bin/` with one `#[rtic::app]`, which only moves data between these
//! modules and `shared`:
//!
//! | binary | runs on | app |
//! | --- | --- | --- |
//! | `board` | the STM32F405RG board (`cargo run --release` flashes it) | tasks on TIM7, EXTI, USART2; defmt over RTT |
//! | `qemu` (feature `qemu`) | QEMU's `netduinoplus2` | the control task on SysTick with the rotor model, a scripted host in `idle`; defmt over semihosting, exits with its verdict |
//! | `qemu-uart` (feature `qemu`) | QEMU's `netduinoplus2` | the control task as in `qemu`, the link served on USART2 for a real host |
//! | `pil` (feature `pil`) | QEMU's `netduinoplus2` | the control task on SysTick with host-sim's plant as its board, the link's bytes in the same records (`docs/pil.md`) |
//!
//! The modules:
//! - [`board`]: pin map, clocks, peripheral setup, raw readings -> units;
//! - [`estop`]: the E-stop's pins, TIM8's break flag and the interrupt's latch;
//! - [`drive`]: signed duties -> the two H-bridges' inputs (`shared::drive`), on
//!   the board and in QEMU;
//! - [`motor_out`]: the board's TIM8 under `drive`, its break input and main
//!   output enable, and the register-level `cut`;
//! - [`sense`]: the currents and the supply, converted at TIM8's update by ADC1
//!   into a DMA buffer, read by the tick without waiting;
//! - [`control`]: the board at a control tick (`shared::tick::Board`);
//! - [`start`]: the controller and the link's state at start;
//! - [`port`]: the link's state as the control tick's port, and its lock; a tick
//!   run with it, and idle's pass of the link;
//! - [`link`]: the UART's byte ring and its count of lost bytes;
//! - [`log`]: what the control task has to say, logged by idle;
//! - [`exceptions`]: the panic handler and every fault, NMI and unexpected
//!   interrupt handler (motors off first), one set per binary;
//! - [`watchdog`]: the independent watchdog, at register level (its timeout, and
//!   the longer one around a flash erase);
//! - [`flash`]: the parameter sectors as a NOR flash;
//! - `qemu` (feature `qemu`): what replaces the peripheral layer in QEMU;
//! - `pil` (feature `pil`): the board of the binary `pil`, host-sim over
//!   semihosting records;
//! - [`machine`], [`tuning`]: the machine's constants and the tuning table,
//!   compiled in by build.rs;
//! - `shared::controller`: the control law, states and faults (host-tested).
//!
//! The feature `qemu` only adds the `qemu` module and the semihosting crates:
//! every module the board uses is the same with it.
#![no_std]

pub mod board;
pub mod control;
pub mod drive;
pub mod estop;
pub mod exceptions;
pub mod flash;
pub mod link;
pub mod log;
pub mod motor_out;
#[cfg(feature = "pil")]
pub mod pil;
pub mod port;
#[cfg(feature = "qemu")]
pub mod qemu;
pub mod sense;
pub mod start;
pub mod watchdog;

/// Milliseconds per control tick.
pub const TICK_MS: u32 = 1000 / shared::controller::CONTROL_RATE_HZ as u32;

/// The tuning table compiled in (build.rs): `VIBRO_TUNING`, else the machine
/// file's `tuning_table`.
pub mod tuning {
    include!(concat!(env!("OUT_DIR"), "/tuning.rs"));
}

/// The machine's constants compiled in from the machine file (build.rs,
/// `VIBRO_MACHINE`, default `examples/vibro-driver.toml`).
pub mod machine {
    include!(concat!(env!("OUT_DIR"), "/machine.rs"));
}
