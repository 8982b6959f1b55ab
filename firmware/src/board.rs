//! The board: pin map, clocks and peripheral setup (stm32f4xx-hal 0.23), and the
//! conversions from raw readings to the controller's units. `docs/hardware.md` is
//! the wiring reference; the pin map here and there must agree.
//!
//! | function | pins | peripheral |
//! | --- | --- | --- |
//! | H-bridge 1 IN1/IN2, H-bridge 2 IN1/IN2 | PC6, PC7, PC8, PC9 | TIM8 CH1..CH4 (AF3), `[drive] pwm_hz` (20 kHz), slow decay |
//! | encoder 1 A/B | PA15, PB3 | TIM2 CH1/CH2 (AF1), encoder mode, 32 bit |
//! | encoder 2 A/B | PA0, PA1 | TIM5 CH1/CH2 (AF2), encoder mode, 32 bit |
//! | encoder 1 Z (index) | PC4 | EXTI4, rising edge |
//! | encoder 2 Z (index) | PC5 | EXTI9_5, rising edge |
//! | current 1, current 2, supply voltage | PC0, PC1, PC2 | ADC1 IN10, IN11, IN12 |
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
use stm32f4xx_hal::adc::config::{AdcConfig, Clock, SampleTime};
use stm32f4xx_hal::adc::Adc;
use stm32f4xx_hal::gpio::{Analog, Edge, Input, Pull, PB0, PC0, PC1, PC2, PC4, PC5};
use stm32f4xx_hal::pac::{self, ADC1, TIM2, TIM5, TIM7, USART2};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::qei::Qei;
use stm32f4xx_hal::rcc::Config;
use stm32f4xx_hal::serial::{self, Rx, Serial, Tx};
use stm32f4xx_hal::timer::{CounterHz, Event};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use crate::flash::ParamFlash;
use crate::motor_out::MotorOut;

/// Frequency of the external crystal (HSE), Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// System clock, Hz: the STM32F405's maximum, from the HSE through the PLL.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// APB1 clock, Hz (its maximum; its timers TIM2..TIM7 count at twice this, 84 MHz).
pub const PCLK1_HZ: u32 = 42_000_000;
/// APB2 clock, Hz (its maximum; TIM1/TIM8 count at 168 MHz, ADC clock from it).
pub const PCLK2_HZ: u32 = 84_000_000;
/// PWM frequency of the H-bridge inputs, Hz: the machine file's `[drive] pwm_hz`
/// (default 20 kHz: above hearing, within what a DRV8871-class bridge switches,
/// up to 200 kHz, with little switching loss; TIM8 at 168 MHz gives 8400 steps of
/// duty), the frequency the simulator's bridge runs at.
pub const PWM_HZ: u32 = crate::machine::MACHINE.bridge.pwm_hz;

/// Independent watchdog timeout, ms. It must outlast the longest stall of the
/// control loop that is not a fault: a 128 KiB flash sector erase (parameter
/// store), at most 2 s (STM32F405 datasheet, t_ERASE128KB), during which the CPU
/// may stall on flash reads. The IWDG counts the LSI, nominally 32 kHz but 17..47
/// kHz over the chip's range: 4000 ms nominal is at least 4000 x 32 / 47 = 2.7 s.
pub const WATCHDOG_TIMEOUT_MS: u32 = 4_000;

/// ADC reference (VDDA = VREF+), V.
const VREF_V: f32 = 3.3;
/// ADC full scale, counts (12 bit).
const ADC_FULL_SCALE: f32 = 4095.0;
/// Current sense: output at zero current, V (a bidirectional amplifier biased at
/// mid-supply, e.g. an INA240A1 with REF at VDDA/2).
const CURRENT_ZERO_V: f32 = 1.65;
/// Current sense gain, V/A (e.g. 5 mOhm shunt x gain 20 = 0.1 V/A: +-16 A span).
const CURRENT_V_PER_A: f32 = 0.1;
/// Sign of each current reading: +1 when a positive sense voltage means the
/// motor is driven forward (its driven sense), -1 otherwise. Check on the bench.
const CURRENT_SIGN: [f32; 2] = [1.0, 1.0];
/// Supply divider ratio `V_bus / V_pin` (e.g. 100 kOhm over 10 kOhm: 11, so
/// 3.3 V at the pin is 36.3 V on the bus).
const SUPPLY_DIVIDER: f32 = 11.0;
/// Encoders counting down when their rotor turns in its driven sense: their
/// counts are negated so that the controller's counts increase (swapping A and B
/// does the same in wiring).
const ENCODER_INVERTED: [bool; 2] = [false, false];
/// ADC sample time: 84 cycles at 21 MHz = 4 us, for source impedances up to
/// tens of kOhm (the supply divider). Three conversions take about 14 us a tick.
const SAMPLE_TIME: SampleTime = SampleTime::Cycles_84;

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

/// Whether the E-stop circuit is open (pressed, or a wire broken): PB0 high or PA6
/// (TIM8_BKIN) high (pulled up; the closed contact holds them at GND), or TIM8's
/// break has cut the outputs since the last tick that did not drive (a break the
/// pins no longer show: a short opening, or a fault on the PA6 side only). Register
/// reads, callable from anywhere.
pub fn estop_open() -> bool {
    // SAFETY: read-only access to the input data registers of GPIOA and GPIOB.
    let (pb0, pa6) = unsafe {
        (
            (*pac::GPIOB::ptr()).idr().read().idr0().bit_is_set(),
            (*pac::GPIOA::ptr()).idr().read().idr6().bit_is_set(),
        )
    };
    pb0 || pa6 || crate::motor_out::break_tripped()
}

/// ADC1 and the three analog inputs.
pub struct Sense {
    adc: Adc<ADC1>,
    current1: PC0<Analog>,
    current2: PC1<Analog>,
    supply: PC2<Analog>,
}

/// One tick's analog readings in the controller's units.
pub struct Analog3 {
    /// Winding currents, A, positive driving forward.
    pub current: [f32; 2],
    /// Supply voltage, V.
    pub supply_voltage: f32,
}

impl Sense {
    /// Convert the three channels one after the other (blocking, about 14 us), at
    /// whatever point of the PWM period the tick falls. Conversions triggered by
    /// TIM8 at the middle of the on-time, read without waiting, are the next step:
    /// `docs/hardware.md`, "ADC triggering", has the plan and why it waits for a
    /// board.
    pub fn read(&mut self) -> Analog3 {
        let volts = |raw: u16| f32::from(raw) * (VREF_V / ADC_FULL_SCALE);
        let c1 = volts(self.adc.convert(&self.current1, SAMPLE_TIME));
        let c2 = volts(self.adc.convert(&self.current2, SAMPLE_TIME));
        let vs = volts(self.adc.convert(&self.supply, SAMPLE_TIME));
        // i = s (v - v0) / gain
        Analog3 {
            current: [
                CURRENT_SIGN[0] * (c1 - CURRENT_ZERO_V) / CURRENT_V_PER_A,
                CURRENT_SIGN[1] * (c2 - CURRENT_ZERO_V) / CURRENT_V_PER_A,
            ],
            supply_voltage: vs * SUPPLY_DIVIDER,
        }
    }
}

/// Everything the app's tasks own, set up.
pub struct Board {
    /// TIM8 PWM onto the two H-bridges (outputs cut).
    pub motors: MotorOut,
    /// TIM2 and TIM5 in encoder mode.
    pub encoders: Encoders,
    /// ADC1 with the current and supply inputs.
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
    /// The independent watchdog, started with [`WATCHDOG_TIMEOUT_MS`].
    pub watchdog: IndependentWatchdog,
    /// The flash controller, for the parameter sectors.
    pub flash: ParamFlash,
    /// Why the processor started.
    pub reset_cause: ResetCause,
}

/// Why the processor started, from RCC CSR, then clear the flags (RMVF) so the
/// next start reads its own cause. Only an independent-watchdog reset counts as
/// [`ResetCause::Watchdog`]; the window watchdog is not used.
fn take_reset_cause(rcc: &pac::RCC) -> ResetCause {
    let watchdog = rcc.csr().read().wdgrstf().bit_is_set();
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    if watchdog {
        ResetCause::Watchdog
    } else {
        ResetCause::PowerOn
    }
}

/// Set up clocks and peripherals; the motors stay cut. The watchdog is started
/// last, so init's own time does not count against it.
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
    let mut syscfg = dp.SYSCFG.constrain(&mut rcc);
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    // H-bridges: TIM8 CH1..CH4 at PWM_HZ; the break input PA6 (AF3, pulled up,
    // the E-stop contact holds it low) set up before `MotorOut::new` arms the break.
    // Outputs off (MOE = 0) until the first tick that enables.
    let break_input = gpioa.pa6.into_alternate::<3>().internal_resistor(Pull::Up);
    let (pwm, (c1, c2, c3, c4)) = dp.TIM8.pwm_hz(PWM_HZ.Hz(), &mut rcc);
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

    // ADC1: 84 MHz / 4 = 21 MHz (the F405's ADC allows at most 36 MHz).
    let adc = Adc::new(
        dp.ADC1,
        true,
        AdcConfig::default().clock(Clock::Pclk2_div_4),
        &mut rcc,
    );
    let sense = Sense {
        adc,
        current1: gpioc.pc0.into_analog(),
        current2: gpioc.pc1.into_analog(),
        supply: gpioc.pc2.into_analog(),
    };

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
    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    watchdog.stop_on_debug(&dp.DBGMCU, true);
    watchdog.start(WATCHDOG_TIMEOUT_MS.millis());

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
