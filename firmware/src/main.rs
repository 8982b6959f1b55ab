//! Firmware of the vibro driver for the STM32F405RG: two brushed DC motors with
//! unbalance rotors, driven by the shared phase controller.
//!
//! The app below only moves data; the logic lives elsewhere:
//! - `board`: pin map, clocks, peripheral setup, raw readings -> units;
//! - `motor_out`: signed duties -> H-bridge PWM, and the register-level `cut`;
//! - `link`: UART bytes -> protocol frames -> answers, telemetry;
//! - `panic`: the panic and HardFault handlers (motors off first);
//! - `shared::controller`: the control law, states and faults (host-tested).
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

mod board;
mod flash;
mod link;
mod motor_out;
mod panic;

/// The tuning table compiled in from `examples/vibro-driver.tuning.toml` (build.rs).
mod tuning {
    include!(concat!(env!("OUT_DIR"), "/tuning.rs"));
}

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use heapless::spsc::{Consumer, Producer};
    use shared::controller::{Controller, Inputs, Params, State, TuningTable, CONTROL_RATE_HZ};
    use shared::protocol::link::{no_telemetry, Link, LinkState};
    use shared::protocol::{SelfTestReport, SelfTestStatus, StatusReport};
    use shared::storage;
    use stm32f4xx_hal::gpio::{Input, PB0, PC4, PC5};
    use stm32f4xx_hal::pac::{TIM7, USART2};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::serial::{Rx, Tx};
    use stm32f4xx_hal::timer::{CounterHz, Flag};
    use stm32f4xx_hal::watchdog::IndependentWatchdog;

    use crate::board::{self, Encoders, Sense};
    use crate::flash::ParamFlash;
    use crate::link::RxRing;
    use crate::motor_out::{self, MotorOut};
    use crate::tuning::TUNING_ROWS;

    /// Milliseconds per control tick.
    const TICK_MS: u32 = 1000 / CONTROL_RATE_HZ as u32;

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
        watchdog: IndependentWatchdog,
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
        /// The state of the previous tick, to log changes.
        last_state: State,
    }

    #[init(local = [rx_ring: RxRing = RxRing::new()])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let b = board::setup(cx.device);

        // Parameters: the reference machine with the table stored in flash, or
        // the compiled-in one when none is stored (first start).
        let mut params = Params::reference();
        let stored = storage::load(&b.flash);
        match &stored {
            Some(s) => {
                defmt::info!("tuning table from flash, record {=u32}", s.sequence);
                params.tuning = s.record.tuning.clone();
            }
            None => match TuningTable::from_rows(&TUNING_ROWS) {
                Ok(table) => params.tuning = table,
                Err(e) => defmt::error!("compiled-in tuning table rejected: {}", e),
            },
        }
        let stored_self_test = stored
            .as_ref()
            .and_then(|s| s.record.self_test)
            .map(|result| SelfTestReport {
                status: SelfTestStatus::Done,
                result,
            });
        let controller = Controller::new(&params, b.reset_cause);
        if let Some(e) = controller.params_error() {
            defmt::error!(
                "parameters invalid: {=str} must be {=str}",
                e.field,
                e.requirement
            );
        }
        defmt::info!(
            "vibro driver {=str}: reset cause {}, state {=str}, {=usize} tuning rows",
            env!("CARGO_PKG_VERSION"),
            b.reset_cause,
            controller.state().name(),
            TUNING_ROWS.len()
        );

        let link = LinkState::new(
            StatusReport {
                uptime_ms: 0,
                state: controller.state(),
                faults: controller.faults(),
                telemetry: no_telemetry(),
            },
            controller.params().tuning.clone(),
            stored_self_test,
        );
        let (rx_in, rx_out) = cx.local.rx_ring.split();
        let last_state = controller.state();

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
                last_state,
            },
        )
    }

    /// E-stop circuit opened: cut the PWM now; the control task sees the open
    /// circuit at its next tick and the controller latches the fault.
    #[task(binds = EXTI0, priority = 4, local = [estop])]
    fn estop(cx: estop::Context) {
        cx.local.estop.clear_interrupt_pending_bit();
        motor_out::cut();
    }

    /// Index pulse of encoder 1: latch its count.
    #[task(binds = EXTI4, priority = 3, local = [index1], shared = [index])]
    fn index1(mut cx: index1::Context) {
        cx.local.index1.clear_interrupt_pending_bit();
        let count = board::driven_count(board::raw_count(0), 0);
        cx.shared.index.lock(|i| i[0] = Some(count));
    }

    /// Index pulse of encoder 2: latch its count.
    #[task(binds = EXTI9_5, priority = 3, local = [index2], shared = [index])]
    fn index2(mut cx: index2::Context) {
        cx.local.index2.clear_interrupt_pending_bit();
        let count = board::driven_count(board::raw_count(1), 1);
        cx.shared.index.lock(|i| i[1] = Some(count));
    }

    /// The control tick at CONTROL_RATE_HZ: sample, step, write, feed the watchdog.
    #[task(
        binds = TIM7,
        priority = 2,
        local = [controller, motors, encoders, sense, tick, watchdog, uptime_ms, last_state],
        shared = [index, link]
    )]
    fn control(mut cx: control::Context) {
        cx.local.tick.clear_flags(Flag::Update);
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(TICK_MS);

        // Stage 1: sample the inputs and take the latched index counts and command.
        let encoder = cx.local.encoders.counts();
        let index = cx.shared.index.lock(core::mem::take);
        let analog = cx.local.sense.read();
        let (command, new_tuning) = cx
            .shared
            .link
            .lock(|l| (l.command.take(), l.new_tuning.take()));
        if let Some(table) = new_tuning {
            if !cx.local.controller.set_tuning(table) {
                defmt::warn!("new tuning table not taken: motors running");
            }
        }
        let inputs = Inputs {
            encoder,
            index,
            current: analog.current,
            supply_voltage: analog.supply_voltage,
            estop: board::estop_open(),
            command,
        };

        // Stage 2: the controller, with the nominal tick.
        let dt = cx.local.controller.params().tick_s();
        let out = cx.local.controller.step(&inputs, dt);

        // Stage 3: write the outputs (fresh every tick; cut unless enabled).
        cx.local.motors.apply(out.duty, out.enable);

        // Stage 4: publish the status for the link.
        let status = StatusReport::from_outputs(*cx.local.uptime_ms, &out);
        cx.shared.link.lock(|l| l.status = status);
        if out.state != *cx.local.last_state {
            defmt::info!("state {=str}, faults {}", out.state.name(), out.faults);
            *cx.local.last_state = out.state;
        }

        // Stage 5: the tick completed: feed the watchdog. Also in Fault (a defined
        // safe state with the motors off): not feeding there would turn every
        // fault into a reset loop.
        cx.local.watchdog.feed();
    }

    /// USART2: move received bytes into the ring (dropped when it is full; the
    /// frame CRC then rejects the frame and the host sends it again).
    #[task(binds = USART2, priority = 1, local = [rx, rx_in])]
    fn uart_rx(cx: uart_rx::Context) {
        // Bounded: a byte time is 87 us, the loop never spins on a stuck flag.
        for _ in 0..16 {
            match cx.local.rx.read() {
                Ok(byte) => {
                    let _ = cx.local.rx_in.enqueue(byte);
                }
                Err(_) => break,
            }
        }
    }

    /// The link: decode, answer, stream telemetry; sleep when there is nothing.
    #[idle(local = [link, rx_out, tx, flash], shared = [link])]
    fn idle(mut cx: idle::Context) -> ! {
        loop {
            let now_ms = cx.shared.link.lock(|l| l.status.uptime_ms);
            let tx = &mut *cx.local.tx;
            let rx = &mut *cx.local.rx_out;
            let busy = cx.local.link.poll(
                || rx.dequeue(),
                now_ms,
                |f| cx.shared.link.lock(|l| f(l)),
                cx.local.flash,
                |bytes| {
                    let _ = tx.bwrite_all(bytes);
                },
            );
            if !busy {
                cortex_m::asm::wfi();
            }
        }
    }
}
