//! Firmware of the vibro driver for the STM32F405RG: two brushed DC motors with
//! unbalance rotors, driven by the shared phase controller.
//!
//! The app below only moves data; the logic lives elsewhere:
//! - `board`: pin map, clocks, peripheral setup, raw readings -> units;
//! - `estop`: the E-stop's pins, TIM8's break flag and the interrupt's latch;
//! - `drive`: signed duties -> the two H-bridges' inputs (`shared::drive`), in
//!   both builds;
//! - `motor_out`: the board's TIM8 under `drive`, its break input and main output
//!   enable, and the register-level `cut`;
//! - `sense`: the currents and the supply, converted at TIM8's update by ADC1
//!   into a DMA buffer, read by the tick without waiting;
//! - `link`: UART bytes -> protocol frames -> answers, telemetry;
//! - `log`: what the control task has to say, logged by idle;
//! - `exceptions`: the panic handler and every fault, NMI and unexpected
//!   interrupt handler (motors off first);
//! - `watchdog`: the independent watchdog, at register level (its timeout, and
//!   the longer one around a flash erase);
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
//!
//! # The `qemu` build
//!
//! With the cargo feature `qemu` the same controller and link run on QEMU's
//! `netduinoplus2` machine, which has no RCC, GPIO, TIM1/TIM8, watchdog or flash
//! controller: the app `qemu_app` (module `qemu`) ticks the control task from
//! SysTick, reads a model of the rotors instead of the board, stores parameters in
//! RAM ([`shared::storage::SimFlash`]) and runs a scripted host in `idle`; it logs
//! over semihosting and exits with the result of its checks. The control stages
//! that touch no peripheral ([`start`], [`link_port`]) are the ones below, shared
//! by both apps, and both run their tick through [`shared::tick::run`]. See `docs/firmware-qemu.md`.
#![no_std]
#![no_main]

#[cfg(not(feature = "qemu"))]
use defmt_rtt as _; // global defmt logger over RTT
#[cfg(feature = "qemu")]
use defmt_semihosting as _; // global defmt logger over semihosting (QEMU)

#[cfg(not(feature = "qemu"))]
mod board;
mod drive;
#[cfg(not(feature = "qemu"))]
mod estop;
mod exceptions;
#[cfg(not(feature = "qemu"))]
mod flash;
#[cfg(any(not(feature = "qemu"), feature = "qemu-uart"))]
mod link;
mod log;
#[cfg(not(feature = "qemu"))]
mod motor_out;
#[cfg(feature = "qemu")]
mod qemu;
#[cfg(not(feature = "qemu"))]
mod sense;
#[cfg(not(feature = "qemu"))]
mod watchdog;

/// RTIC's lock on the link's state (shared with the control task), as the lock
/// `shared::protocol::link::Link::poll` takes for each access.
pub struct Locked<'a, M>(pub &'a mut M);

impl<M: rtic::Mutex<T = LinkState>> shared::protocol::link::StateLock for Locked<'_, M> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut LinkState) -> R) -> R {
        self.0.lock(f)
    }
}

/// Milliseconds per control tick.
const TICK_MS: u32 = 1000 / shared::controller::CONTROL_RATE_HZ as u32;

/// The tuning table compiled in (build.rs): `VIBRO_TUNING`, else the machine
/// file's `tuning_table`.
mod tuning {
    include!(concat!(env!("OUT_DIR"), "/tuning.rs"));
}

/// The machine's constants compiled in from the machine file (build.rs,
/// `VIBRO_MACHINE`, default `examples/vibro-driver.toml`).
mod machine {
    include!(concat!(env!("OUT_DIR"), "/machine.rs"));
}

use embedded_storage::nor_flash::ReadNorFlash;
use shared::controller::{Controller, Params, ResetCause, TuningTable};
#[cfg(feature = "qemu")]
use shared::controller::{Outputs, SelfTestReport};
use shared::protocol::link::{use_stored, LinkState};
use shared::storage;

/// The controller and the link's state at start: the compiled-in machine with the
/// tuning table stored in `flash` (`&mut` the driver, or `&` a simulated flash), or
/// the compiled-in one when none is stored (first start); the stored self-test
/// result, if any.
fn start<F: ReadNorFlash>(flash: F, reset_cause: ResetCause) -> (Controller, LinkState) {
    let mut params = Params::from_machine(&machine::MACHINE);
    let stored = storage::load(flash);
    match &stored {
        Some(s) => defmt::info!("tuning table from flash, record {=u32}", s.sequence),
        None => match TuningTable::from_rows(&tuning::TUNING_ROWS) {
            Ok(table) => params.tuning = table,
            Err(e) => defmt::error!("compiled-in tuning table rejected: {}", e),
        },
    }
    use_stored(&mut params, stored.as_ref());
    let controller = Controller::new(&params, reset_cause);
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
        reset_cause,
        controller.state().name(),
        tuning::TUNING_ROWS.len()
    );
    if !machine::MACHINE.rotor_count.has_rotor2() {
        defmt::info!("one rotor: its speed held, no phase loop; motor 2's bridge off");
    }
    let link = LinkState::at_start(&controller, stored.as_ref());
    (controller, link)
}

/// Control stages 2 and 5 over the link's state ([`shared::tick::Port`]): the
/// pending command taken (a newly stored tuning table handed to the controller,
/// a requested self-test started), the status and the self-test's published.
/// What the controller refused is flagged for idle's log after the tick
/// ([`log_refusals`]).
fn link_port<M: rtic::Mutex<T = LinkState>>(
    link: &mut M,
    uptime_ms: u32,
) -> shared::tick::LinkPort<Locked<'_, M>> {
    shared::tick::LinkPort::new(Locked(link), uptime_ms)
}

/// Flags for idle's log what the controller refused in a tick's port.
fn log_refusals(taken: &shared::protocol::link::ForTick) {
    if taken.tuning_refused {
        log::note(log::Event::TuningRefused);
    }
    if taken.self_test_refused {
        log::note(log::Event::SelfTestRefused);
    }
}

/// SysTick counts of one `qemu` control tick.
#[cfg(feature = "qemu")]
#[derive(Clone, Copy, Debug, Default)]
pub struct TickCounts {
    /// `Controller::step` alone.
    pub step: u32,
    /// The whole tick (sample, command, step, bridge driver, publish) without the
    /// rotor model's integration, which stands in for the motors, not for code
    /// the board runs.
    pub tick: u32,
}

/// The board of the `qemu` builds ([`shared::tick::Board`]): the rotor model
/// sampled, the bridges' inputs written through the board's driver (both coasting
/// when the controller does not enable them or the E-stop is open, as the board's
/// E-stop handler and break cut them), then the model run for one tick with
/// `injected`. The model's integration stands in for the motors, not for code the
/// board runs: its SysTick counts are kept apart (`model`), and so are the
/// instants around the controller's step (`stepping`, `stepped`).
#[cfg(feature = "qemu")]
struct QemuBoard<'a> {
    plant: &'a mut qemu::plant::Plant,
    drive: &'a mut drive::Drive<qemu::pwm::SimPwm>,
    injected: &'a qemu::plant::Injected,
    timing: shared::controller::TickTiming,
    /// SysTick counts of the model's tick.
    model: u32,
    /// When the sample was taken (the step follows the command's take).
    sampled: u32,
    /// When the outputs came to be applied (the step's end).
    stepped: u32,
}

#[cfg(feature = "qemu")]
impl shared::tick::Board for QemuBoard<'_> {
    fn sample(&mut self) -> shared::controller::Inputs {
        let s = self.plant.sample();
        let sample = shared::controller::Inputs {
            encoder: s.encoder,
            index: s.index,
            current: s.current,
            supply_voltage: s.supply_voltage,
            estop: self.injected.estop_open,
            command: None,
            timing: self.timing,
        };
        self.sampled = qemu::cycles::now();
        sample
    }

    fn apply(&mut self, out: &Outputs) {
        use qemu::cycles::{elapsed, now};
        self.stepped = now();
        let estop = self.injected.estop_open;
        self.drive
            .apply(out.duty, out.bridges.map(|on| on && !estop));
        let model_start = now();
        self.plant.step(self.injected);
        self.model = elapsed(model_start, now());
    }
}

/// The link's port of the `qemu` builds: the board's, with the instant the
/// command was taken (the controller's step starts there).
#[cfg(feature = "qemu")]
struct QemuPort<P> {
    port: P,
    taken: u32,
}

#[cfg(feature = "qemu")]
impl<P: shared::tick::Port> shared::tick::Port for QemuPort<P> {
    fn take(&mut self, controller: &mut Controller) -> Option<shared::controller::Command> {
        let command = self.port.take(controller);
        self.taken = qemu::cycles::now();
        command
    }

    fn publish(&mut self, out: &Outputs, self_test: SelfTestReport) {
        self.port.publish(out, self_test);
    }
}

/// One control tick of the `qemu` builds on the rotor model: [`shared::tick::run`]
/// on the [`QemuBoard`], with the nominal tick and the tick's `timing`. Timed in
/// SysTick counts ([`TickCounts`]): the step from the command's take to the
/// outputs' apply (the step and the copy of its inputs), the whole tick without
/// the model.
#[cfg(feature = "qemu")]
fn qemu_tick(
    controller: &mut Controller,
    plant: &mut qemu::plant::Plant,
    drive: &mut drive::Drive<qemu::pwm::SimPwm>,
    injected: &qemu::plant::Injected,
    timing: shared::controller::TickTiming,
    uptime_ms: u32,
    link: &mut impl rtic::Mutex<T = LinkState>,
) -> (Outputs, TickCounts) {
    use qemu::cycles::{elapsed, now};
    let start = now();
    let mut board = QemuBoard {
        plant,
        drive,
        injected,
        timing,
        model: 0,
        sampled: start,
        stepped: start,
    };
    let mut port = QemuPort {
        port: link_port(link, uptime_ms),
        taken: start,
    };
    let dt = controller.params().tick_s();
    let out = shared::tick::run(controller, &mut board, &mut port, dt);
    log_refusals(&port.port.taken);
    let step = elapsed(port.taken, board.stepped);
    let tick = elapsed(start, now()).saturating_sub(board.model);
    (out, TickCounts { step, tick })
}

#[cfg(not(feature = "qemu"))]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use core::sync::atomic::{AtomicU32, Ordering};

    use cortex_m::peripheral::DWT;
    use heapless::spsc::{Consumer, Producer};
    use shared::controller::{Controller, Inputs, TickTiming, CONTROL_RATE_HZ};
    use shared::protocol::link::{Link, LinkState};
    use shared::timing::TickClock;
    use stm32f4xx_hal::gpio::{Input, PB0, PC4, PC5};
    use stm32f4xx_hal::pac::{TIM7, USART2};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::serial::{self, Rx, Tx};
    use stm32f4xx_hal::timer::{CounterHz, Flag};

    use crate::board::{self, Encoders};
    use crate::flash::ParamFlash;
    use crate::link::{self, RxRing};
    use crate::log::Logger;
    use crate::motor_out::{self, MotorOut};
    use crate::sense::Sense;
    use crate::watchdog::Watchdog;

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

    #[init(local = [rx_ring: RxRing = RxRing::new()])]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        // Faults to their own handlers, which cut first, and a stack overflow
        // caught while a handler can still run (`exceptions`).
        crate::exceptions::enable_fault_exceptions(&mut cx.core.SCB);
        crate::exceptions::guard_stack(&mut cx.core.MPU);
        // The cycle counter, for the tick's timing.
        cx.core.DCB.enable_trace();
        cx.core.DWT.enable_cycle_counter();

        let mut b = board::setup(cx.device);

        // Parameters: the reference machine with the table stored in flash, or
        // the compiled-in one when none is stored (first start).
        let (controller, link) = crate::start(&mut b.flash, b.reset_cause);
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
        crate::estop::latch();
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

    /// The board at a control tick ([`shared::tick::Board`]): the encoders, the
    /// index counts latched by the index tasks, the ADC's means, the E-stop, the
    /// tick's timing; the outputs to TIM8 through `motor_out`.
    struct BoardIo<'a, I> {
        encoders: &'a mut Encoders,
        index: &'a mut I,
        sense: &'a mut Sense,
        motors: &'a mut MotorOut,
        timing: TickTiming,
    }

    impl<I: rtic::Mutex<T = [Option<u32>; 2]>> shared::tick::Board for BoardIo<'_, I> {
        fn sample(&mut self) -> Inputs {
            let encoder = self.encoders.counts();
            let index = self.index.lock(core::mem::take);
            board::index_rearm();
            let analog = self.sense.read();
            Inputs {
                encoder,
                index,
                current: analog.current,
                supply_voltage: analog.supply_voltage,
                estop: crate::estop::take_latch() | crate::estop::open(),
                command: None,
                timing: self.timing,
            }
        }

        fn apply(&mut self, out: &shared::controller::Outputs) {
            self.motors.apply(out.duty, out.bridges);
        }
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
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(crate::TICK_MS);
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
        let mut port = crate::link_port(&mut cx.shared.link, *cx.local.uptime_ms);
        let dt = cx.local.controller.params().tick_s();
        shared::tick::run(cx.local.controller, &mut hw, &mut port, dt);
        crate::log_refusals(&port.taken);

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
                Ok(byte) => {
                    if cx.local.rx_in.enqueue(byte).is_err() {
                        link::count_dropped();
                    }
                }
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
            let dropped = link::dropped();
            let status = cx.shared.link.lock(|l| {
                l.rx_dropped = dropped;
                l.status
            });
            cx.local.logger.poll(&status);
            let tx = &mut *cx.local.tx;
            let rx = &mut *cx.local.rx_out;
            let busy = cx.local.link.poll(
                || rx.dequeue(),
                status.uptime_ms,
                crate::Locked(&mut cx.shared.link),
                cx.local.flash,
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

/// The `qemu` build's app (docs/firmware-qemu.md): the control task on SysTick
/// with the rotor model, the scripted host in `idle`.
#[cfg(all(feature = "qemu", not(feature = "qemu-uart")))]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod qemu_app {
    use shared::controller::{Controller, ResetCause};
    use shared::protocol::link::{Link, LinkState};
    use shared::storage::SimFlash;

    use crate::drive::Drive;
    use crate::log::Logger;
    use crate::qemu::cycles::SysTickClock;
    use crate::qemu::plant::Plant;
    use crate::qemu::pwm::SimPwm;
    use crate::qemu::script::{self, Io, Progress, Script};
    use crate::qemu::world::World;
    use crate::qemu::{self, checks, cycles, stack};

    #[shared]
    struct Shared {
        /// Status, pending command, table: between the control and the link task.
        link: LinkState,
        /// Injected faults and observed facts: between the control task and the script.
        world: World,
    }

    #[local]
    struct Local {
        controller: Controller,
        plant: Plant,
        /// The bridges, through the board's driver over emulated compare registers.
        drive: Drive<SimPwm>,
        uptime_ms: u32,
        /// The control tick's timing, in SysTick counts.
        clock: SysTickClock,
        flash: SimFlash,
        /// SysTick calibration: `(instructions, counts)` of a known loop.
        calibration: (u32, u32),
    }

    #[init]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        crate::exceptions::enable_fault_exceptions(&mut cx.core.SCB);
        crate::exceptions::guard_stack(&mut cx.core.MPU);
        stack::paint();
        let mut syst = cx.core.SYST;

        // Calibrate SysTick against a loop of known length (interrupts are off).
        syst.set_clock_source(cortex_m::peripheral::syst::SystClkSource::Core);
        syst.set_reload(0x00FF_FFFF);
        syst.clear_current();
        syst.enable_counter();
        let calibration = cycles::calibrate();
        syst.disable_counter();

        // No board::setup: RCC waits would hang in QEMU. Flash in RAM, erased as
        // QEMU's unwritten flash reads (0x00), so nothing is stored at start.
        let flash = SimFlash::filled(0x00);
        let (controller, link) = crate::start(&flash, ResetCause::PowerOn);

        // The control tick.
        cycles::start(&mut syst, cycles::RELOAD);

        (
            Shared {
                link,
                world: World::default(),
            },
            Local {
                controller,
                plant: Plant::new(),
                drive: Drive::new(SimPwm::channels(), crate::machine::MACHINE.bridge.decay),
                uptime_ms: 0,
                clock: SysTickClock::new(cycles::RELOAD),
                flash,
                calibration,
            },
        )
    }

    /// The control tick at CONTROL_RATE_HZ: sample the model, step, drive the
    /// model, publish. The same stages as the board's `control`.
    #[task(
        binds = SysTick,
        priority = 2,
        local = [controller, plant, drive, uptime_ms, clock],
        shared = [link, world]
    )]
    fn control(mut cx: control::Context) {
        // The task's stack use: painted below its stack pointer here, measured
        // at the end from idle's stack pointer (the exception frame included).
        let sp = cortex_m::register::msp::read() as usize;
        stack::paint_window(sp);
        // The tick's timing from SysTick, as the board's from TIM7 and DWT.
        let tick = qemu::next_tick();
        let timing = cx.local.clock.begin(tick);
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(crate::TICK_MS);

        let injected = cx.shared.world.lock(|w| w.injected);
        let (out, counts) = crate::qemu_tick(
            cx.local.controller,
            cx.local.plant,
            cx.local.drive,
            &injected,
            timing,
            *cx.local.uptime_ms,
            &mut cx.shared.link,
        );
        let plant = &*cx.local.plant;
        cx.shared
            .world
            .lock(|w| w.observe(tick, &out, plant, counts));
        let used = stack::above_idle(stack::window_lowest(sp));
        let overrun_us = cx.shared.world.lock(|w| {
            w.control_stack = w.control_stack.max(used);
            core::mem::take(&mut w.injected.overrun_us)
        });
        if overrun_us > 0 {
            cycles::spin(
                overrun_us.saturating_mul(cycles::SYSTICK_HZ / 1_000_000),
                cycles::RELOAD,
            );
        }
        cx.local.clock.end();
    }

    /// The scripted host, once per control tick; then the measurements and the
    /// verdict.
    #[idle(local = [flash, calibration, link: Link = Link::new(), script: Script = Script::new(), logger: Logger = Logger::new()], shared = [link, world])]
    fn idle(mut cx: idle::Context) -> ! {
        // The stack init used; from here on, what the run uses.
        let init_stack = stack::used();
        stack::reset();
        stack::paint();
        let mut seen = 0;
        loop {
            // Sleep until the next control tick (checked with interrupts off, so
            // a tick between the check and the WFI still wakes it).
            stack::record_idle_sp();
            let tick = cortex_m::interrupt::free(|_| {
                let t = qemu::tick();
                if t == seen {
                    cortex_m::asm::wfi();
                }
                t
            });
            if tick == seen {
                continue;
            }
            seen = tick;
            let status = cx.shared.link.lock(|l| l.status);
            cx.local.logger.poll(&status);
            let mut io = Io {
                tick,
                link: cx.local.link,
                flash: cx.local.flash,
                state: &mut cx.shared.link,
                world: &mut cx.shared.world,
            };
            if cx.local.script.run(&mut io) == Progress::Done || cx.local.script.completed() {
                break;
            }
        }
        let run_stack = stack::used();
        report(
            init_stack,
            run_stack,
            *cx.local.calibration,
            &mut cx.shared.world,
        );
        if cx.local.script.armed() {
            // The last step: the default handler ends the run (`script`).
            script::pend_unexpected();
            for _ in 0..1000 {
                cortex_m::asm::nop();
            }
            checks::check!(false, "the pended interrupt reached the default handler");
        }
        checks::finish()
    }

    /// Log the measurements (lines starting with `measure:`, left out of the
    /// comparison with the expected output) and check them against the goals.
    fn report(
        init_stack: usize,
        run_stack: usize,
        calibration: (u32, u32),
        world: &mut impl rtic::Mutex<T = World>,
    ) {
        let (ins, counts) = calibration;
        defmt::info!(
            "measure: calibration: {=u32} instructions in {=u32} SysTick counts",
            ins,
            counts
        );
        let (off, driving, tick_off, tick_driving, control_stack) = world.lock(|w| {
            (
                w.cost_off,
                w.cost_driving,
                w.tick_off,
                w.tick_driving,
                w.control_stack,
            )
        });
        for (what, cost) in [
            ("control step, motors off", off),
            ("control step, driving", driving),
            ("control tick without the rotor model, motors off", tick_off),
            (
                "control tick without the rotor model, driving",
                tick_driving,
            ),
        ] {
            defmt::info!(
                "measure: {=str}: {=u32} ticks, mean {=u32} / max {=u32} SysTick counts = mean {=u32} / max {=u32} instructions",
                what,
                cost.steps,
                cost.mean(),
                cost.max,
                cycles::instructions(cost.mean(), calibration),
                cycles::instructions(cost.max, calibration)
            );
        }
        defmt::info!(
            "measure: stack used: init {=usize} bytes, run {=usize} bytes (scripted host included), of {=usize}; control task {=usize} bytes on top of idle",
            init_stack,
            run_stack,
            stack::size(),
            control_stack
        );
    }
}

/// The `qemu-uart` build's app (docs/firmware-qemu.md, "The link on the emulated
/// USART"): the control task on SysTick with the rotor model, as in `qemu_app`;
/// the link served on USART2 as on the board (an RX interrupt filling a ring,
/// `Link::poll` in `idle`), for a real host on QEMU's `-serial`. No checks and no
/// exit: it runs until QEMU is stopped (a panic or a fault exits with status 1).
#[cfg(feature = "qemu-uart")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod qemu_uart_app {
    use heapless::spsc::{Consumer, Producer};
    use shared::controller::{Controller, ResetCause, TickTiming};
    use shared::protocol::link::{Link, LinkState};
    use shared::storage::SimFlash;

    use crate::drive::Drive;
    use crate::link;
    use crate::link::RxRing;
    use crate::log::Logger;
    use crate::qemu::plant::{Injected, Plant};
    use crate::qemu::pwm::SimPwm;
    use crate::qemu::uart::{self, UartRx, UartTx};
    use crate::qemu::{self, cycles};

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

    #[init(local = [rx_ring: RxRing = RxRing::new()])]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        crate::exceptions::enable_fault_exceptions(&mut cx.core.SCB);
        crate::exceptions::guard_stack(&mut cx.core.MPU);
        let mut syst = cx.core.SYST;
        // No RCC: the USART's registers only (QEMU needs no clock for it).
        let (rx, tx) = uart::split(cx.device.USART2);
        let (rx_in, rx_out) = cx.local.rx_ring.split();

        // Flash in RAM, erased as QEMU's unwritten flash reads (0x00).
        let flash = SimFlash::filled(0x00);
        let (controller, link) = crate::start(&flash, ResetCause::PowerOn);
        defmt::info!("qemu-uart: the link on USART2 at 115200 baud");

        cycles::start(&mut syst, cycles::RELOAD);

        (
            Shared { link },
            Local {
                controller,
                plant: Plant::new(),
                drive: Drive::new(SimPwm::channels(), crate::machine::MACHINE.bridge.decay),
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
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(crate::TICK_MS);
        // Nothing injected: the model as it is. No timing: this build runs QEMU
        // on the host's real-time clock (no -icount), where the tick's latency is
        // the host's scheduling, not the firmware's (hundreds of microseconds
        // under load): the deadline check is the `qemu` build's, on a
        // deterministic clock.
        crate::qemu_tick(
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
                Some(byte) => {
                    if cx.local.rx_in.enqueue(byte).is_err() {
                        link::count_dropped();
                    }
                }
                None => break,
            }
        }
    }

    /// The link, as on the board: decode, answer, stream telemetry; sleep when
    /// there is nothing.
    #[idle(local = [link: Link = Link::new(), rx_out, tx, flash, logger: Logger = Logger::new()], shared = [link])]
    fn idle(mut cx: idle::Context) -> ! {
        loop {
            let dropped = link::dropped();
            let status = cx.shared.link.lock(|l| {
                l.rx_dropped = dropped;
                l.status
            });
            cx.local.logger.poll(&status);
            let now_ms = status.uptime_ms;
            let tx = &mut *cx.local.tx;
            let rx = &mut *cx.local.rx_out;
            let busy = cx.local.link.poll(
                || rx.dequeue(),
                now_ms,
                crate::Locked(&mut cx.shared.link),
                cx.local.flash,
                |bytes| tx.write_all(bytes),
            );
            if !busy {
                cortex_m::asm::wfi();
            }
        }
    }
}
