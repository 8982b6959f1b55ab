//! The scripted QEMU app (`docs/firmware-qemu.md`): the firmware on QEMU's
//! `netduinoplus2`, the control task on SysTick with the rotor model, a scripted
//! host in `idle`; defmt over semihosting; exits with the verdict of its checks.
//! Built with the feature `qemu` and run by `scripts/firmware-qemu.sh`.
#![no_std]
#![no_main]

use defmt_semihosting as _; // global defmt logger over semihosting

firmware::exception_handlers!(firmware::qemu::safe_state::Scripted);

// Every log line carries the control tick: firmware time, the same every run.
defmt::timestamp!("{=u32:05}", firmware::qemu::tick());

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use shared::controller::Controller;
    use shared::protocol::link::{Link, LinkState};
    use shared::storage::SimFlash;

    use firmware::drive::Drive;
    use firmware::log::Logger;
    use firmware::qemu::cycles::SysTickClock;
    use firmware::qemu::plant::Plant;
    use firmware::qemu::pwm::{self, SimPwm};
    use firmware::qemu::report::report;
    use firmware::qemu::script::{Io, Progress, Script};
    use firmware::qemu::world::World;
    use firmware::qemu::{self, cycles, stack};
    use firmware::start::{start_in_qemu, CaptureBuffer, CAPTURE_BUFFER};
    use firmware::{exceptions, TICK_MS};

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

    #[init(local = [capture: CaptureBuffer = CAPTURE_BUFFER])]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        exceptions::setup(&mut cx.core.SCB, &mut cx.core.MPU);
        stack::paint();
        let mut syst = cx.core.SYST;

        // Calibrate SysTick against a loop of known length (interrupts are off).
        syst.set_clock_source(cortex_m::peripheral::syst::SystClkSource::Core);
        syst.set_reload(0x00FF_FFFF);
        syst.clear_current();
        syst.enable_counter();
        let calibration = cycles::calibrate();
        syst.disable_counter();

        // No board::setup: RCC waits would hang in QEMU.
        let (flash, controller, link) = start_in_qemu(cx.local.capture);

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
                drive: pwm::drive(),
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
        *cx.local.uptime_ms = cx.local.uptime_ms.wrapping_add(TICK_MS);

        let injected = cx.shared.world.lock(|w| w.injected);
        let (out, counts) = qemu::control::tick(
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
        // The verdict, or the pended interrupt's default handler ends the run.
        cx.local.script.end()
    }
}
