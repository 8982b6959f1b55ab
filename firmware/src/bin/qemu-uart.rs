//! The QEMU app with the link on the emulated USART2 (`docs/firmware-qemu.md`,
//! "The link on the emulated USART"): the control task on SysTick with the rotor
//! model, as in the binary `qemu`; the link served on USART2 as on the board (an
//! RX interrupt filling a ring, `Link::poll` in `idle`), for a real host on
//! QEMU's `-serial`; defmt over semihosting. No checks and no exit: it runs until
//! QEMU is stopped (a panic or a fault exits with status 1). Built with the
//! feature `qemu` and run by `scripts/firmware-qemu-device.sh`.
#![no_std]
#![no_main]

use defmt_semihosting as _; // global defmt logger over semihosting

firmware::exception_handlers!(firmware::qemu::safe_state::Uart);

// Every log line carries the control tick.
defmt::timestamp!("{=u32:05}", firmware::qemu::tick());

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use heapless::spsc::{Consumer, Producer};
    use shared::controller::{Controller, TickTiming};
    use shared::protocol::link::{Link, LinkState};
    use shared::storage::SimFlash;

    use firmware::drive::Drive;
    use firmware::link::{self, RxRing};
    use firmware::log::Logger;
    use firmware::port::serve;
    use firmware::qemu::plant::{Injected, Plant};
    use firmware::qemu::pwm::{self, SimPwm};
    use firmware::qemu::uart::{self, UartRx, UartTx};
    use firmware::qemu::{self, cycles};
    use firmware::start::{start_in_qemu, CaptureBuffer, CAPTURE_BUFFER};
    use firmware::{exceptions, TICK_MS};

    #[shared]
    struct Shared {
        /// Status, pending command, table: between the control and the link task.
        link: LinkState,
    }

    #[local]
    struct Local {
        controller: Controller,
        plant: Plant,
        /// The bridges, through the board's driver over emulated compare registers.
        drive: Drive<SimPwm>,
        uptime_ms: u32,
        flash: SimFlash,
        rx: UartRx,
        tx: UartTx,
        rx_in: Producer<'static, u8>,
        rx_out: Consumer<'static, u8>,
    }

    #[init(local = [rx_ring: RxRing = RxRing::new(), capture: CaptureBuffer = CAPTURE_BUFFER])]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        exceptions::setup(&mut cx.core.SCB, &mut cx.core.MPU);
        let mut syst = cx.core.SYST;
        // No RCC: the USART's registers only (QEMU needs no clock for it).
        let (rx, tx) = uart::split(cx.device.USART2);
        let (rx_in, rx_out) = cx.local.rx_ring.split();

        let (flash, controller, link) = start_in_qemu(cx.local.capture);
        defmt::info!("qemu-uart: the link on USART2 at 115200 baud");

        cycles::start(&mut syst, cycles::RELOAD);

        (
            Shared { link },
            Local {
                controller,
                plant: Plant::new(),
                drive: pwm::drive(),
                uptime_ms: 0,
                flash,
                rx,
                tx,
                rx_in,
                rx_out,
            },
        )
    }

    /// The control tick at CONTROL_RATE_HZ: sample the model, step, drive the
    /// model, publish. The same stages as the board's `control`.
    #[task(
        binds = SysTick,
        priority = 2,
        local = [controller, plant, drive, uptime_ms],
        shared = [link]
    )]
    fn control(mut cx: control::Context) {
        qemu::next_tick();
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(TICK_MS);
        // Nothing injected: the model as it is. No timing: this build runs QEMU
        // on the host's real-time clock (no -icount), where the tick's latency is
        // the host's scheduling, not the firmware's (hundreds of microseconds
        // under load): the deadline check is the binary `qemu`'s, on a
        // deterministic clock.
        qemu::control::tick(
            cx.local.controller,
            cx.local.plant,
            cx.local.drive,
            &Injected::default(),
            TickTiming::default(),
            *cx.local.uptime_ms,
            &mut cx.shared.link,
        );
    }

    /// USART2: move received bytes into the ring (counted and dropped when it is
    /// full; the frame CRC then rejects the frame and the host sends it again).
    #[task(binds = USART2, priority = 1, local = [rx, rx_in])]
    fn uart_rx(cx: uart_rx::Context) {
        for _ in 0..16 {
            match cx.local.rx.read() {
                Some(byte) => link::receive(cx.local.rx_in, byte),
                None => break,
            }
        }
    }

    /// The link, as on the board: decode, answer, stream telemetry; sleep when
    /// there is nothing.
    #[idle(local = [link: Link = Link::new(), rx_out, tx, flash, logger: Logger = Logger::new()], shared = [link])]
    fn idle(mut cx: idle::Context) -> ! {
        loop {
            let tx = &mut *cx.local.tx;
            let busy = serve(
                cx.local.link,
                cx.local.rx_out,
                &mut cx.shared.link,
                cx.local.flash,
                cx.local.logger,
                |bytes| tx.write_all(bytes),
            );
            if !busy {
                cortex_m::asm::wfi();
            }
        }
    }
}
