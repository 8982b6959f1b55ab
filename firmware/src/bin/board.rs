//! The board's app: the firmware on the STM32F405RG, defmt over RTT (probe-rs
//! reads it). `cd firmware && cargo run --release` builds and flashes it.
//!
//! The app only moves data; the logic is the library's modules and `shared`
//! (the crate's documentation lists them).
//!
//! # Tasks, by urgency (higher number preempts lower)
//!
//! | priority | task | binds | does |
//! | --- | --- | --- | --- |
//! | 4 | `estop` | EXTI0 | cuts the PWM at once when the E-stop circuit opens |
//! | 3 | `index1`, `index2` | EXTI4, EXTI9_5 | latch the encoder count at the index pulse |
//! | 2 | `control` | TIM7 | 1 kHz: sample, `Controller::step`, write duties, feed the watchdog |
//! | 1 | `uart_rx` | USART2 | push received bytes into the ring |
//! | 0 | `idle` | - | decode frames, answer, send telemetry, sleep |
#![no_std]
#![no_main]

use defmt_rtt as _; // global defmt logger over RTT

firmware::exception_handlers!(firmware::exceptions::Board);

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use core::sync::atomic::{AtomicU32, Ordering};

    use cortex_m::peripheral::DWT;
    use heapless::spsc::{Consumer, Producer};
    use shared::controller::{Controller, CONTROL_RATE_HZ};
    use shared::protocol::link::{Link, LinkState};
    use shared::timing::TickClock;
    use stm32f4xx_hal::gpio::{Input, PB0, PC4, PC5};
    use stm32f4xx_hal::pac::{TIM7, USART2};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::serial::{self, Rx, Tx};
    use stm32f4xx_hal::timer::{CounterHz, Flag};

    use firmware::board::{self, Encoders};
    use firmware::control::BoardIo;
    use firmware::flash::ParamFlash;
    use firmware::link::{self, RxRing};
    use firmware::log::Logger;
    use firmware::motor_out::{self, MotorOut};
    use firmware::port::{run_tick, serve};
    use firmware::sense::Sense;
    use firmware::start::{start, CaptureBuffer, CAPTURE_BUFFER};
    use firmware::watchdog::Watchdog;
    use firmware::{exceptions, TICK_MS};

    /// Core clock cycles per control tick.
    const TICK_CYCLES: u32 = board::SYSCLK_HZ / CONTROL_RATE_HZ as u32;

    /// Time since start, ms, counted by the control task: the defmt timestamp.
    static UPTIME_MS: AtomicU32 = AtomicU32::new(0);
    defmt::timestamp!("{=u32:tms}", UPTIME_MS.load(Ordering::Relaxed));

    #[shared]
    struct Shared {
        /// Encoder counts latched by the index interrupts since the last tick.
        index: [Option<u32>; 2],
        /// Status, pending command, table: between the control and the link task.
        link: LinkState,
    }

    #[local]
    struct Local {
        controller: Controller,
        motors: MotorOut,
        encoders: Encoders,
        sense: Sense,
        tick: CounterHz<TIM7>,
        watchdog: Watchdog,
        /// The tick's lateness and duration, on the DWT cycle counter.
        clock: TickClock,
        index1: PC4<Input>,
        index2: PC5<Input>,
        estop: PB0<Input>,
        rx: Rx<USART2>,
        tx: Tx<USART2>,
        rx_in: Producer<'static, u8>,
        rx_out: Consumer<'static, u8>,
        link: Link,
        flash: ParamFlash,
        /// Time since start, ms, counted in control ticks.
        uptime_ms: u32,
    }

    #[init(local = [rx_ring: RxRing = RxRing::new(), capture: CaptureBuffer = CAPTURE_BUFFER])]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        // Faults to their own handlers, which cut first, and a stack overflow
        // caught while a handler can still run.
        exceptions::setup(&mut cx.core.SCB, &mut cx.core.MPU);
        // The cycle counter, for the tick's timing.
        cx.core.DCB.enable_trace();
        cx.core.DWT.enable_cycle_counter();

        let mut b = board::setup(cx.device);

        // Parameters: the reference machine with the table stored in flash, or
        // the compiled-in one when none is stored (first start).
        let (controller, link) = start(&mut b.flash, b.reset_cause, cx.local.capture);
        let (rx_in, rx_out) = cx.local.rx_ring.split();

        (
            Shared {
                index: [None; 2],
                link,
            },
            Local {
                controller,
                motors: b.motors,
                encoders: b.encoders,
                sense: b.sense,
                tick: b.tick,
                watchdog: b.watchdog,
                clock: TickClock::new(board::SYSCLK_HZ, TICK_CYCLES),
                index1: b.index1,
                index2: b.index2,
                estop: b.estop,
                rx: b.rx,
                tx: b.tx,
                rx_in,
                rx_out,
                link: Link::new(),
                flash: b.flash,
                uptime_ms: 0,
            },
        )
    }

    /// E-stop circuit opened: cut the PWM now and latch the opening; the control
    /// task takes the latch (and reads the pins) at its next tick and the
    /// controller latches the fault.
    #[task(binds = EXTI0, priority = 4, local = [estop])]
    fn estop(cx: estop::Context) {
        cx.local.estop.clear_interrupt_pending_bit();
        motor_out::cut();
        firmware::estop::latch();
    }

    /// Index pulse of encoder 1: hold the line off until the next tick
    /// (`board::index_hold`), latch its count.
    #[task(binds = EXTI4, priority = 3, local = [index1], shared = [index])]
    fn index1(mut cx: index1::Context) {
        // Masked first: an edge after this cannot enter again before the tick.
        board::index_hold(0);
        cx.local.index1.clear_interrupt_pending_bit();
        latch_index(0, &mut cx.shared.index);
    }

    /// Index pulse of encoder 2: hold the line off until the next tick, latch its
    /// count.
    #[task(binds = EXTI9_5, priority = 3, local = [index2], shared = [index])]
    fn index2(mut cx: index2::Context) {
        // Masked first: an edge after this cannot enter again before the tick.
        board::index_hold(1);
        cx.local.index2.clear_interrupt_pending_bit();
        latch_index(1, &mut cx.shared.index);
    }

    /// Latch encoder `k`'s counter for the next tick: the first index edge since
    /// the tick counts (a later one, before the hold-off, does not overwrite it).
    fn latch_index(k: usize, index: &mut impl rtic::Mutex<T = [Option<u32>; 2]>) {
        let count = board::driven_count(board::raw_count(k), k);
        index.lock(|i| {
            i[k].get_or_insert(count);
        });
    }

    /// The control tick at CONTROL_RATE_HZ: time, sample, step, write, publish,
    /// feed the watchdog. No log line is formatted here (`log`).
    #[task(
        binds = TIM7,
        priority = 2,
        local = [controller, motors, encoders, sense, tick, watchdog, clock, uptime_ms],
        shared = [index, link]
    )]
    fn control(mut cx: control::Context) {
        // Stage 0: the tick's timing, first (the latency from TIM7's update).
        let timing = cx
            .local
            .clock
            .begin(DWT::cycle_count(), board::tick_latency_cycles());
        cx.local.tick.clear_flags(Flag::Update);
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(TICK_MS);
        UPTIME_MS.store(*cx.local.uptime_ms, Ordering::Relaxed);

        // Stages 1 to 4: sample (the latched index counts and E-stop taken, the
        // index lines held off re-armed), take the command, step with the
        // nominal tick, write the outputs (fresh every tick; cut unless enabled),
        // publish the status for the link.
        let mut hw = BoardIo {
            encoders: cx.local.encoders,
            index: &mut cx.shared.index,
            sense: cx.local.sense,
            motors: cx.local.motors,
            timing,
        };
        run_tick(
            cx.local.controller,
            &mut hw,
            &mut cx.shared.link,
            *cx.local.uptime_ms,
        );

        // Stage 5: the tick completed: feed the watchdog. Also in Fault (a defined
        // safe state with the motors off): not feeding there would turn every
        // fault into a reset loop, and lose the fault's report with it.
        cx.local.watchdog.feed();
        cx.local.clock.end(DWT::cycle_count());
    }

    /// USART2: move received bytes into the ring; a byte the ring cannot take,
    /// or lost to an overrun, noise or a framing error, is counted and dropped
    /// (the frame CRC then rejects the frame and the host sends it again).
    #[task(binds = USART2, priority = 1, local = [rx, rx_in])]
    fn uart_rx(cx: uart_rx::Context) {
        // Bounded: a byte time is 87 us, the loop never spins on a stuck flag.
        for _ in 0..16 {
            match cx.local.rx.read() {
                Ok(byte) => link::receive(cx.local.rx_in, byte),
                Err(stm32f4xx_hal::nb::Error::WouldBlock) => break,
                // An overrun lost the byte that came in, and the HAL's read of the
                // data register (which clears the error) drops the one before.
                Err(stm32f4xx_hal::nb::Error::Other(serial::Error::Overrun)) => {
                    link::count_dropped();
                    link::count_dropped();
                }
                // Noise, framing, parity: the byte read is dropped.
                Err(stm32f4xx_hal::nb::Error::Other(_)) => link::count_dropped(),
            }
        }
    }

    /// The link: decode, answer, stream telemetry; the log; sleep when there is
    /// nothing to do.
    #[idle(local = [link, rx_out, tx, flash, logger: Logger = Logger::new()], shared = [link])]
    fn idle(mut cx: idle::Context) -> ! {
        loop {
            let tx = &mut *cx.local.tx;
            let busy = serve(
                cx.local.link,
                cx.local.rx_out,
                &mut cx.shared.link,
                cx.local.flash,
                cx.local.logger,
                |bytes| {
                    let _ = tx.bwrite_all(bytes);
                },
            );
            if !busy {
                // Sleep unless a byte came meanwhile (checked with interrupts off:
                // one arriving between the check and the WFI still wakes it).
                let rx = &*cx.local.rx_out;
                cortex_m::interrupt::free(|_| {
                    if !rx.ready() {
                        cortex_m::asm::wfi();
                    }
                });
            }
        }
    }
}
