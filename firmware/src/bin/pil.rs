//! Processor in the loop (`docs/pil.md`): the firmware on QEMU's
//! `netduinoplus2` with `host-sim run --firmware` as its board. The control task
//! on SysTick at the board's rate runs the board's tick (`shared::tick::run`)
//! with the link's port; its sample and outputs are records exchanged with the
//! host (`firmware::pil::board`), and the link's UART bytes travel in the same
//! records: received ones into the RX ring the board's UART interrupt fills, sent
//! ones from `idle`'s `Link::poll`. defmt over semihosting. No watchdog (QEMU
//! emulates none); a panic or fault cuts the emulated bridges and exits with
//! status 1, as does a channel that fails. Built with the feature `pil`.
#![no_std]
#![no_main]

use defmt_semihosting as _; // global defmt logger over semihosting

firmware::exception_handlers!(firmware::qemu::safe_state::Uart);

// Every log line carries the control tick: firmware time, the same every run.
defmt::timestamp!("{=u32:05}", firmware::qemu::tick());

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use heapless::spsc::{Consumer, Producer};
    use shared::controller::Controller;
    use shared::pil::Hello;
    use shared::protocol::link::{Link, LinkState};
    use shared::storage::SimFlash;

    use firmware::drive::Drive;
    use firmware::link::RxRing;
    use firmware::log::Logger;
    use firmware::machine::{MACHINE_FILE, MACHINE_FILE_CRC32, MACHINE_FILE_LEN};
    use firmware::pil::board::{PilBoard, PilLink};
    use firmware::pil::{self, TxRing};
    use firmware::port::{run_tick, serve};
    use firmware::qemu::counter;
    use firmware::qemu::cycles::{self, SysTickClock};
    use firmware::qemu::pwm::{self, SimPwm};
    use firmware::start::{start_in_qemu, CaptureBuffer, CAPTURE_BUFFER};
    use firmware::{exceptions, qemu, TICK_MS};

    #[shared]
    struct Shared {
        /// Status, pending command, table: between the control and the link task.
        link: LinkState,
    }

    #[local]
    struct Local {
        controller: Controller,
        /// The bridges, through the board's driver over emulated compare registers.
        drive: Drive<SimPwm>,
        uptime_ms: u32,
        /// The control tick's timing, in SysTick counts.
        clock: SysTickClock,
        /// The record channel to the host.
        pil: PilLink,
        flash: SimFlash,
        rx_in: Producer<'static, u8>,
        rx_out: Consumer<'static, u8>,
        tx_in: Producer<'static, u8>,
        tx_out: Consumer<'static, u8>,
    }

    #[init(local = [
        rx_ring: RxRing = RxRing::new(),
        tx_ring: TxRing = TxRing::new(),
        capture: CaptureBuffer = CAPTURE_BUFFER,
    ])]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        exceptions::setup(&mut cx.core.SCB, &mut cx.core.MPU);
        let mut syst = cx.core.SYST;
        let (rx_in, rx_out) = cx.local.rx_ring.split();
        let (tx_in, tx_out) = cx.local.tx_ring.split();

        let (flash, controller, link) = start_in_qemu(cx.local.capture);
        let hello = Hello::new(
            MACHINE_FILE_CRC32,
            MACHINE_FILE_LEN,
            TICK_MS * 1000,
            MACHINE_FILE,
        );
        let pil = PilLink::start(&hello);
        defmt::info!("pil: the host is the board ({=str})", MACHINE_FILE);

        cycles::start(&mut syst, cycles::RELOAD);

        (
            Shared { link },
            Local {
                controller,
                drive: pwm::drive(),
                uptime_ms: 0,
                clock: SysTickClock::new(cycles::RELOAD),
                pil,
                flash,
                rx_in,
                rx_out,
                tx_in,
                tx_out,
            },
        )
    }

    /// The control tick at CONTROL_RATE_HZ: the board's stages (sample, command,
    /// step, outputs, publish) with the host as the board.
    #[task(
        binds = SysTick,
        priority = 2,
        local = [controller, drive, uptime_ms, clock, pil, rx_in, tx_out],
        shared = [link]
    )]
    fn control(mut cx: control::Context) {
        let tick = qemu::next_tick();
        let timing = cx.local.clock.begin(tick);
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(TICK_MS);
        let mut board = PilBoard {
            link: cx.local.pil,
            drive: cx.local.drive,
            tx: cx.local.tx_out,
            rx: cx.local.rx_in,
            tick,
            timing,
            last_busy_ns: cx.local.clock.last_busy_ns(),
            uptime_ms: *cx.local.uptime_ms,
            estop: false,
            next_late_us: 0,
        };
        run_tick(
            cx.local.controller,
            &mut board,
            &mut cx.shared.link,
            *cx.local.uptime_ms,
        );
        cx.local.clock.end();
        // A starved loop injected by the host: the core kept busy past the
        // next tick's timer event, which the next tick's clock sees as its
        // lateness.
        if board.next_late_us > 0 {
            let late = u32::from(board.next_late_us) * (cycles::SYSTICK_HZ / 1_000_000);
            cycles::spin(counter::now().saturating_add(late), cycles::RELOAD);
        }
    }

    /// The link, as on the board: decode, answer, stream telemetry; its sent
    /// bytes queued for the next record; sleep when there is nothing.
    #[idle(local = [link: Link = Link::new(), rx_out, tx_in, flash, logger: Logger = Logger::new(), tx_lost: u32 = 0], shared = [link])]
    fn idle(mut cx: idle::Context) -> ! {
        loop {
            let tx = &mut *cx.local.tx_in;
            let busy = serve(
                cx.local.link,
                cx.local.rx_out,
                &mut cx.shared.link,
                cx.local.flash,
                cx.local.logger,
                |bytes| {
                    for &b in bytes {
                        if tx.enqueue(b).is_err() {
                            pil::count_tx_dropped();
                        }
                    }
                },
            );
            let lost = pil::tx_dropped();
            if lost != *cx.local.tx_lost {
                defmt::error!("pil: {=u32} sent bytes lost (the TX ring full)", lost);
                *cx.local.tx_lost = lost;
            }
            if !busy {
                cortex_m::asm::wfi();
            }
        }
    }
}
