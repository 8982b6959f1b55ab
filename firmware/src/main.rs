//! Firmware of the vibro driver for the STM32F405RG.
//!
//! PLACEHOLDER until the firmware issue: this app only sets the clocks, logs its
//! version over defmt (RTT) and sleeps. It exists so that the build (target, linker
//! scripts, root `memory.x`, profiles, RTIC 2 with the HAL, the `shared` crate) is
//! set up and checked in CI the way the real controller app will need it. It drives
//! no motor and reads no sensor.
#![no_std]
#![no_main]

use defmt_rtt as _; // global defmt logger over RTT
use panic_probe as _; // panics print over defmt, then the probe stops

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::rcc::Config;

    /// Frequency of the external crystal on the board (HSE).
    const HSE_HZ: u32 = 8_000_000;
    /// System clock: the STM32F405's maximum, reached through the PLL from the HSE.
    const SYSCLK_HZ: u32 = 168_000_000;

    #[shared]
    struct Shared {}

    #[local]
    struct Local {}

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        // Clocks: 8 MHz crystal -> PLL -> 168 MHz; the HAL picks the bus prescalers.
        let rcc = cx
            .device
            .RCC
            .freeze(Config::hse(HSE_HZ.Hz()).sysclk(SYSCLK_HZ.Hz()));

        defmt::info!(
            "vibro driver firmware {=str} (placeholder), sysclk {=u32} Hz",
            env!("CARGO_PKG_VERSION"),
            rcc.clocks.sysclk().raw()
        );

        (Shared {}, Local {})
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        // Nothing to do yet: sleep until an interrupt.
        loop {
            cortex_m::asm::wfi();
        }
    }
}
