//! The board: pin map, clocks and peripheral setup (stm32f4xx-hal 0.23), and the
//! conversions from raw readings to the controller's units. `docs/hardware.md` is
//! the wiring reference; the pin map here and there must agree.
//!
//! | function | pins | peripheral |
//! | --- | --- | --- |
//! | H-bridge 1 IN1/IN2, H-bridge 2 IN1/IN2 | PC6, PC7, PC8, PC9 | TIM8 CH1..CH4 (AF3), `[drive] pwm_hz` (20 kHz), slow decay |
//! | encoder 1 A/B | PA15, PB3 | TIM2 CH1/CH2 (AF1), encoder mode, 32 bit, input filter |
//! | encoder 2 A/B | PA0, PA1 | TIM5 CH1/CH2 (AF2), encoder mode, 32 bit, input filter |
//! | encoder 1 Z (index) | PC4 | EXTI4, rising edge, held off until the next tick |
//! | encoder 2 Z (index) | PC5 | EXTI9_5, rising edge, held off until the next tick |
//! | current 1, current 2, supply voltage | PC0, PC1, PC2 | ADC1 IN10, IN11, IN12, at TIM8's update, DMA2 stream 0 (`sense`) |
//! | host link TX/RX | PA2, PA3 | USART2 (AF7) |
//! | E-stop (normally closed to GND), software path | PB0 | EXTI0, pull-up, rising edge = open |
//! | E-stop, the same contact, hardware path | PA6 | TIM8_BKIN (AF3), pull-up, active high |
//!
//! The E-stop contact goes to two pins joined on the board: PA6, TIM8's break
//! input, which clears MOE in hardware the moment the circuit opens (see
//! `motor_out`), and PB0, whose EXTI0 interrupt (priority 4) cuts in software and
//! whose level the controller reads every tick. Why not PA6 alone (an AF pin's
//! input still feeds EXTI): PA6 is EXTI line 6, which shares the EXTI9_5 vector
//! with the index of encoder 2 (PC5, EXTI5), so the E-stop would run at the index
//! task's priority and every index pulse would also enter the E-stop handler.
//! TIM8_BKIN exists only on PA6 on the 64-pin package (PI4 is not bonded out).
//!
//! Why TIM8 and not TIM1: on the 64-pin STM32F405RG, TIM1 CH4 exists only on PA11
//! (USB OTG FS D-), and CH2/CH3 only on PA9/PA10 (USB VBUS sense and ID). TIM8 is
//! the other advanced timer (same registers, MOE, break input) and has all four
//! channels on PC6..PC9, clear of USART2 (PA2/PA3) and USB (PA9..PA12).
//! TIM5 CH1/CH2 exist only on PA0/PA1 on this package, so TIM2 takes PA15/PB3
//! (JTDI/SWO: SWD debugging still works, SWO trace does not).

use shared::controller::{ResetCause, CONTROL_RATE_HZ};
use shared::protocol::BAUD_RATE;
use stm32f4xx_hal::gpio::{Edge, Input, Pull, PB0, PC4, PC5};
use stm32f4xx_hal::pac::{self, TIM2, TIM5, TIM7, USART2};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::qei::Qei;
use stm32f4xx_hal::rcc::Config;
use stm32f4xx_hal::serial::{self, Rx, Serial, Tx};
use stm32f4xx_hal::timer::{CounterHz, Event};

use crate::flash::ParamFlash;
use crate::motor_out::MotorOut;
use crate::sense::Sense;
use crate::watchdog::{self, Watchdog};

/// Frequency of the external crystal (HSE), Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// System clock, Hz: the STM32F405's maximum, from the HSE through the PLL.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// APB1 clock, Hz (its maximum; its timers TIM2..TIM7 count at twice this, 84 MHz).
pub const PCLK1_HZ: u32 = 42_000_000;
/// APB2 clock, Hz (its maximum; TIM1/TIM8 count at 168 MHz, ADC clock from it).
pub const PCLK2_HZ: u32 = 84_000_000;
// TIM8 counts at twice PCLK2, the clock `drive::PWM_TIMER` is set up for.
const _: () = assert!(crate::drive::TIMER_HZ == 2 * PCLK2_HZ);
/// TIM7's clock, Hz: twice PCLK1.
const TIM7_HZ: u32 = 2 * PCLK1_HZ;

/// Encoders counting down when their rotor turns in its driven sense: their
/// counts are negated so that the controller's counts increase (swapping A and B
/// does the same in wiring).
const ENCODER_INVERTED: [bool; 2] = [false, false];
/// Encoder input filter (TIMx_CCMR1 IC1F/IC2F = 0011: sampled at the timer's
/// 84 MHz, an edge counts after 8 equal samples, 95 ns). An edge of the reference
/// encoder (4096 counts a turn) at `encoder_max_speed_rpm` (6000) comes every
/// 2.4 us, 25 times the filter; ringing and spikes shorter than 95 ns are gone.
const ENCODER_FILTER: u8 = 0b0011;

/// The two quadrature encoders (TIM2, TIM5: 32-bit counters, x4 decoding).
pub struct Encoders {
    enc1: Qei<TIM2>,
    enc2: Qei<TIM5>,
}

impl Encoders {
    /// Both counters, in the controller's sense (increasing in the driven sense).
    pub fn counts(&self) -> [u32; 2] {
        [
            driven_count(self.enc1.count(), 0),
            driven_count(self.enc2.count(), 1),
        ]
    }
}

/// A raw counter of encoder `i` (0 or 1) in the controller's sense.
pub fn driven_count(raw: u32, i: usize) -> u32 {
    if ENCODER_INVERTED[i] {
        0u32.wrapping_sub(raw)
    } else {
        raw
    }
}

/// The raw counter of encoder `i` (0: TIM2, 1: TIM5), read without owning the
/// timer: for the index interrupts, which latch it. A plain register read.
pub fn raw_count(i: usize) -> u32 {
    // SAFETY: read-only access to a counter register.
    unsafe {
        if i == 0 {
            (*TIM2::ptr()).cnt().read().bits()
        } else {
            (*TIM5::ptr()).cnt().read().bits()
        }
    }
}

/// The index inputs' EXTI lines: encoder 1 on line 4 (PC4), encoder 2 on line 5
/// (PC5).
const INDEX_LINES: [u32; 2] = [4, 5];

/// Index debounce and storm guard: the index interrupt masks its own EXTI line
/// after it has latched the count, and the next control tick unmasks it (with the
/// pending edges of the hold-off cleared). So at most one index interrupt per
/// line and tick reaches the processor whatever the input does (a bouncing edge,
/// a broken wire picking up the PWM), and the count latched is the first edge's.
/// A real index comes once a turn: ten times a tick's length apart at 6000 rpm.
pub fn index_hold(i: usize) {
    let line = INDEX_LINES[i % 2];
    // SAFETY: clears one bit of the EXTI interrupt mask, from the index task
    // (priority 3), which alone clears it; the control tick sets it again.
    cortex_m::interrupt::free(|_| unsafe {
        (*pac::EXTI::ptr())
            .imr()
            .modify(|r, w| w.bits(r.bits() & !(1 << line)))
    });
}

/// Unmask the index lines held off since the last tick, their edges during the
/// hold-off dropped (see [`index_hold`]); a line not held keeps its pending edge,
/// which is a real index. Called by the control tick.
pub fn index_rearm() {
    let lines = (1 << INDEX_LINES[0]) | (1 << INDEX_LINES[1]);
    // SAFETY: writes 1 to the held lines' pending bits (clears them), then sets
    // their mask bits, with interrupts off so the index task cannot interleave.
    cortex_m::interrupt::free(|_| unsafe {
        let exti = &*pac::EXTI::ptr();
        let held = !exti.imr().read().bits() & lines;
        if held != 0 {
            exti.pr().write(|w| w.bits(held));
            exti.imr().modify(|r, w| w.bits(r.bits() | held));
        }
    });
}

/// Cycles of the 168 MHz core clock since TIM7's update event, the nominal start
/// of the control tick: TIM7 restarts from 0 at its update and counts at
/// `TIM7_HZ / (PSC + 1)`. Read at the control task's entry, it is the task's
/// latency (`shared::timing`).
pub fn tick_latency_cycles() -> u32 {
    // SAFETY: reads of TIM7's counter and prescaler.
    let (cnt, psc) = unsafe {
        let t = &*TIM7::ptr();
        (
            t.cnt().read().bits() & 0xffff,
            t.psc().read().bits() & 0xffff,
        )
    };
    cnt * (psc + 1) * (SYSCLK_HZ / TIM7_HZ)
}

/// Everything the app's tasks own, set up.
pub struct Board {
    /// TIM8 PWM onto the two H-bridges (outputs cut).
    pub motors: MotorOut,
    /// TIM2 and TIM5 in encoder mode.
    pub encoders: Encoders,
    /// ADC1 converting the current and supply inputs at TIM8's update.
    pub sense: Sense,
    /// Index input of encoder 1 (EXTI4).
    pub index1: PC4<Input>,
    /// Index input of encoder 2 (EXTI9_5).
    pub index2: PC5<Input>,
    /// E-stop input (EXTI0).
    pub estop: PB0<Input>,
    /// TIM7: update interrupt at the control rate.
    pub tick: CounterHz<TIM7>,
    /// USART2 transmitter.
    pub tx: Tx<USART2>,
    /// USART2 receiver, RX-not-empty interrupt on.
    pub rx: Rx<USART2>,
    /// The independent watchdog, started with `watchdog::Timeout::RUN`.
    pub watchdog: Watchdog,
    /// The flash controller, for the parameter sectors.
    pub flash: ParamFlash,
    /// Why the processor started.
    pub reset_cause: ResetCause,
}

/// Why the processor started, from RCC CSR: every flag logged, then cleared
/// (RMVF) so the next start reads its own cause. Only an independent-watchdog
/// reset counts as [`ResetCause::Watchdog`] for the controller (which then starts
/// in `Fault`); the window watchdog is not used. Several flags are normal at once:
/// a power-on sets POR and PIN (and BOR), a watchdog reset IWDG and PIN.
fn take_reset_cause(rcc: &pac::RCC) -> ResetCause {
    let csr = rcc.csr().read();
    defmt::info!(
        "reset flags (RCC_CSR {=u32:#010x}): low-power {=bool}, window watchdog {=bool}, independent watchdog {=bool}, software {=bool}, power-on {=bool}, pin {=bool}, brown-out {=bool}",
        csr.bits(),
        csr.lpwrrstf().bit_is_set(),
        csr.wwdgrstf().bit_is_set(),
        csr.wdgrstf().bit_is_set(),
        csr.sftrstf().bit_is_set(),
        csr.porrstf().bit_is_set(),
        csr.padrstf().bit_is_set(),
        csr.borrstf().bit_is_set()
    );
    let watchdog = csr.wdgrstf().bit_is_set();
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    if watchdog {
        ResetCause::Watchdog
    } else {
        ResetCause::PowerOn
    }
}

/// Set up clocks and peripherals; the motors stay cut. The clock security system
/// watches the crystal from the moment the PLL runs on it. The watchdog is
/// started last, so init's own time does not count against it.
///
/// A crystal that never starts hangs the clock setup (the HAL waits for HSE
/// ready without a limit) before TIM8 is set up: the bridge inputs are then
/// undriven and the bridges' own pull-downs hold them low (coast), and nothing is
/// logged after the reset flags.
pub fn setup(mut dp: pac::Peripherals) -> Board {
    // Reset cause first: the RCC is consumed by the clock setup.
    let reset_cause = take_reset_cause(&dp.RCC);

    // Clocks: HSE 8 MHz -> PLL -> 168 MHz SYSCLK, APB1 42 MHz, APB2 84 MHz.
    let mut rcc = dp.RCC.freeze(
        Config::hse(HSE_HZ.Hz())
            .sysclk(SYSCLK_HZ.Hz())
            .pclk1(PCLK1_HZ.Hz())
            .pclk2(PCLK2_HZ.Hz()),
    );
    // Clock security system: if the HSE stops, the core falls back to the HSI,
    // TIM8's break clears its outputs in hardware (a clock failure is a break
    // source of TIM1 and TIM8) and the NMI handler cuts and waits for the
    // watchdog (`exceptions`).
    rcc.cr().modify(|_, w| w.csson().set_bit());
    let mut syscfg = dp.SYSCFG.constrain(&mut rcc);
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    // H-bridges: TIM8 CH1..CH4 (the HAL's edge-aligned setup, made centre-aligned
    // at the machine's `pwm_hz` by `MotorOut::new`); the break input PA6 (AF3, pulled up,
    // the E-stop contact holds it low) set up before `MotorOut::new` arms the break.
    // Outputs off (MOE = 0) until the first tick that enables.
    let break_input = gpioa.pa6.into_alternate::<3>().internal_resistor(Pull::Up);
    let (pwm, (c1, c2, c3, c4)) = dp
        .TIM8
        .pwm_hz(crate::machine::MACHINE.bridge.pwm_hz.Hz(), &mut rcc);
    let motors = MotorOut::new(
        pwm,
        [
            c1.with(gpioc.pc6).erase(),
            c2.with(gpioc.pc7).erase(),
            c3.with(gpioc.pc8).erase(),
            c4.with(gpioc.pc9).erase(),
        ],
        break_input,
    );

    // Encoders: TIM2 on PA15/PB3, TIM5 on PA0/PA1, x4 quadrature decoding.
    let encoders = Encoders {
        // PA15/PB3 leave their JTAG function (AF0) for TIM2.
        enc1: dp
            .TIM2
            .qei((gpioa.pa15.into_input(), gpiob.pb3.into_input()), &mut rcc),
        enc2: dp.TIM5.qei((gpioa.pa0, gpioa.pa1), &mut rcc),
    };
    // Their input filters (the HAL leaves IC1F/IC2F at 0, no filter).
    // SAFETY: a 4-bit filter code in each input's field.
    unsafe {
        (*TIM2::ptr())
            .ccmr1_input()
            .modify(|_, w| w.ic1f().bits(ENCODER_FILTER).ic2f().bits(ENCODER_FILTER));
        (*TIM5::ptr())
            .ccmr1_input()
            .modify(|_, w| w.ic1f().bits(ENCODER_FILTER).ic2f().bits(ENCODER_FILTER));
    }

    // Index pulses: rising edge, each on its own EXTI line.
    let mut index1 = gpioc.pc4.into_pull_up_input();
    index1.make_interrupt_source(&mut syscfg);
    index1.trigger_on_edge(&mut dp.EXTI, Edge::Rising);
    index1.enable_interrupt(&mut dp.EXTI);
    let mut index2 = gpioc.pc5.into_pull_up_input();
    index2.make_interrupt_source(&mut syscfg);
    index2.trigger_on_edge(&mut dp.EXTI, Edge::Rising);
    index2.enable_interrupt(&mut dp.EXTI);

    // E-stop: pull-up, the normally closed contact to GND; rising = opened.
    let mut estop = gpiob.pb0.into_input().internal_resistor(Pull::Up);
    estop.make_interrupt_source(&mut syscfg);
    estop.trigger_on_edge(&mut dp.EXTI, Edge::Rising);
    estop.enable_interrupt(&mut dp.EXTI);

    // ADC1 and DMA2: conversions at TIM8's update (`sense`).
    let sense = Sense::new(
        dp.ADC1,
        &dp.ADC_COMMON,
        dp.DMA2,
        (
            gpioc.pc0.into_analog(),
            gpioc.pc1.into_analog(),
            gpioc.pc2.into_analog(),
        ),
        &mut rcc,
    );

    // Host link: USART2 8N1 at the protocol's baud rate, RX interrupt.
    let mut serial = Serial::new(
        dp.USART2,
        (gpioa.pa2, gpioa.pa3),
        serial::Config::default().baudrate(BAUD_RATE.bps()),
        &mut rcc,
    )
    .expect("USART2 config");
    serial.listen(serial::Event::RxNotEmpty);
    let (tx, rx) = serial.split();

    // Control tick: TIM7 (basic timer, 84 MHz) update interrupt at the control rate.
    let mut tick = dp.TIM7.counter_hz(&mut rcc);
    tick.start((CONTROL_RATE_HZ as u32).Hz())
        .expect("TIM7 rate");
    tick.listen(Event::Update);

    // A debugger halting the core stops TIM8, which then disables its outputs as
    // if MOE were 0: a breakpoint never leaves the motors driven.
    dp.DBGMCU
        .apb2_fz()
        .modify(|_, w| w.dbg_tim8_stop().set_bit());

    // Watchdog: frozen while a debugger halts the core, then started.
    let watchdog = watchdog::start(dp.IWDG, &dp.DBGMCU);

    Board {
        motors,
        encoders,
        sense,
        index1,
        index2,
        estop,
        tick,
        tx,
        rx,
        watchdog,
        flash: ParamFlash::new(dp.FLASH),
        reset_cause,
    }
}
