//! The H-bridge of each motor as it is wired, and what the controller's duty
//! means on it: one mapping, used by the firmware to drive the bridge's inputs and
//! by the simulator to model the winding.
//!
//! # The bridge
//!
//! A two-input bridge of the DRV8871 class (TI, DRV8871 datasheet, "Device
//! Functional Modes", the logic table), each input driven by one PWM output:
//!
//! | IN1 | IN2 | OUT1 | OUT2 | the winding |
//! | --- | --- | --- | --- | --- |
//! | 0 | 0 | Z | Z | coast: every switch off; a current freewheels through the body diodes against the supply until it dies ([`Connection::Open`]) |
//! | 1 | 0 | H | L | forward: `+V_s` ([`Connection::Forward`]) |
//! | 0 | 1 | L | H | reverse: `-V_s` ([`Connection::Reverse`]) |
//! | 1 | 1 | L | L | brake: both low-side switches on, the winding shorted, 0 V ([`Connection::Short`]) |
//!
//! # Decay modes
//!
//! The controller asks for a signed duty `d` in `[-1, 1]`, meaning the mean winding
//! voltage `d V_s`. How the two inputs make it is the **decay mode**
//! ([`input_duties`]):
//!
//! - **Slow decay** ([`Decay::Slow`], the default): forward holds IN1 high and
//!   pulses IN2 with the high fraction `1 - d`, so the winding is driven forward
//!   for `d` of each period and shorted (brake) for the rest; reverse is the
//!   mirror. Every switch that conducts conducts both ways, so the winding sees
//!   `+V_s` then 0 V whatever the current's direction: its mean voltage is `d V_s`
//!   exactly, and a current against the drive brakes the rotor, returning energy
//!   to the supply while the winding is connected to it. Duty 0 brakes.
//! - **Fast decay** ([`Decay::Fast`]): forward pulses IN1 with the high fraction
//!   `d` and holds IN2 low, so the winding is driven for `d` of each period and
//!   coasts for the rest: the current freewheels through the body diodes against
//!   the supply (`-V_s` across the winding) and cannot reverse. At low duty or
//!   high back-EMF it dies within the period (discontinuous conduction) and the
//!   mean voltage is far from `d V_s`: at standstill the reference motor (2 ohm,
//!   0.5 mH, 12 V, 20 kHz) draws 3 mA at `d = 0.049` where slow decay gives
//!   0.29 A, and at 3000 rpm nothing at all where slow decay brakes with -2.8 A.
//!   Duty 0 coasts.
//!
//! The controller and its tuning assume slow decay; fast decay exists to model a
//! board wired or configured that way (the machine file's `[drive] decay`).
//!
//! # The PWM period
//!
//! Both inputs come from one timer counting up and down (centre-aligned PWM):
//! each input is high while the counter is below its compare value, so around
//! the counter's valley, for half its high fraction at each end of the period (the
//! period runs valley to valley). A period is symmetric about its middle, the
//! counter's peak ([`period`]): both high (brake) for half the smaller fraction,
//! the input with the larger fraction high alone up to half of it, both low
//! (coast) across the middle, then the same mirrored. In slow decay that is brake
//! around the valley and drive around the peak: the valley is the middle of the
//! brake, the peak the middle of the drive, whatever the duty, and the current
//! there is the period's mean (for a linear ripple) whichever of the two the
//! firmware samples at.
//!
//! # Changing the inputs
//!
//! The timer loads new compare values at its update event; if that falls between
//! the writes of the two inputs, one period runs with one input new and the other
//! old. [`HBridge::drive`] orders the writes so that this period is the decay
//! mode's own off-state: in slow decay the rising input is written first (the
//! period in between has both inputs at the higher of their old and new fractions:
//! a reversal brakes, both high, which slow decay does every period anyway); in
//! fast decay the falling input first (both at the lower: a reversal coasts, both
//! low, and never brakes, which fast decay must not). So a change while driving
//! never connects the winding in a way neither the old nor the new duty does.
//!
//! Switching on from coast is different: both inputs start low, a slow-decay duty
//! raises both, and whichever goes first, the period in between drives (forward
//! with IN1 alone high, reverse with IN2). No write order helps; the firmware
//! writes both with the outputs still off and forces the timer's update before
//! it enables them (`firmware/src/motor_out.rs`).

use embedded_hal::pwm::SetDutyCycle;

use crate::Enumerated;

/// How the two bridge inputs make a duty (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Decay {
    /// Drive, then brake: the mean winding voltage is `d V_s` in both current
    /// directions.
    #[default]
    Slow,
    /// Drive, then coast: the current freewheels through the body diodes and
    /// cannot reverse.
    Fast,
}

/// Both modes, the default first, named as the machine file writes them.
impl Enumerated for Decay {
    const ALL: &'static [Decay] = &[Decay::Slow, Decay::Fast];

    fn name(self) -> &'static str {
        match self {
            Decay::Slow => "slow",
            Decay::Fast => "fast",
        }
    }
}

/// The bridge as wired: decay mode and PWM frequency (the machine file's
/// `[drive] decay` and `pwm_hz`), the same constants for the firmware's timer and
/// the simulator's winding.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BridgeConfig {
    /// Decay mode.
    pub decay: Decay,
    /// PWM frequency, Hz.
    pub pwm_hz: u32,
}

impl BridgeConfig {
    /// The default: slow decay at 20 kHz (above hearing, and within what a
    /// DRV8871-class bridge switches with little loss; 4200 steps of duty on a
    /// 168 MHz centre-aligned timer).
    pub const DEFAULT: BridgeConfig = BridgeConfig {
        decay: Decay::Slow,
        pwm_hz: 20_000,
    };

    /// PWM periods per update event of the timer ([`MAX_UPDATE_HZ`]): the new
    /// compare values load, and the currents are sampled, once every this many
    /// periods (1 up to 50 kHz).
    pub const fn periods_per_update(self) -> u32 {
        let k = self.pwm_hz.div_ceil(MAX_UPDATE_HZ);
        if k == 0 {
            1
        } else {
            k
        }
    }
}

/// The clock of the board's bridge timer (TIM8 on APB2 at twice PCLK2, 84 MHz),
/// Hz: the firmware sets the timer up from it ([`CentreAligned::new`]), and the
/// processor in the loop reads the compare values against the same full scale.
pub const BOARD_TIMER_HZ: u32 = 168_000_000;

/// The fastest rate of the timer's update event, Hz: at each one the board's
/// ADC converts both currents and the supply (three conversions, about 10 us), so
/// two updates must be further apart than that; above 50 kHz of PWM the update
/// comes every [`BridgeConfig::periods_per_update`] periods.
pub const MAX_UPDATE_HZ: u32 = 50_000;

/// The setup of a 16-bit timer for centre-aligned PWM: prescaler, auto-reload and
/// repetition counter (the registers PSC, ARR, RCR of an STM32 advanced timer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CentreAligned {
    /// Prescaler: the counter runs at `timer_hz / (psc + 1)`.
    pub psc: u16,
    /// Auto-reload: the counter counts `0 -> arr -> 0`, a period of `2 arr` counts.
    pub arr: u16,
    /// Repetition counter: an update event every `rcr + 1` half periods, so
    /// `2 k - 1` for one every `k` periods ([`BridgeConfig::periods_per_update`]).
    pub rcr: u8,
}

impl CentreAligned {
    /// For `config` on a timer clocked at `timer_hz`: the smallest prescaler that
    /// fits the auto-reload in 16 bits, with
    ///
    /// ```text
    ///   f_pwm = timer_hz / ((psc + 1) * 2 * arr)        (RM0090 17.3.2, centre-aligned)
    /// ```
    ///
    /// rounded to the nearest `arr`. At 168 MHz and 20 kHz: `psc = 0`,
    /// `arr = 4200`, exact.
    pub const fn new(timer_hz: u32, config: BridgeConfig) -> CentreAligned {
        let pwm_hz = if config.pwm_hz == 0 { 1 } else { config.pwm_hz };
        // Counts of the undivided clock per half period.
        let half = (timer_hz as u64 + pwm_hz as u64) / (2 * pwm_hz as u64);
        let psc = (half.saturating_sub(1)) / 65_535;
        // Rounded to the nearest: (2 half + div) / (2 div).
        let div = psc + 1;
        let arr = (2 * half + div) / (2 * div);
        let k = config.periods_per_update();
        let rcr = 2 * k - 1;
        CentreAligned {
            psc: if psc > u16::MAX as u64 {
                u16::MAX
            } else {
                psc as u16
            },
            arr: if arr > u16::MAX as u64 {
                u16::MAX
            } else if arr == 0 {
                1
            } else {
                arr as u16
            },
            rcr: if rcr > u8::MAX as u32 {
                u8::MAX
            } else {
                rcr as u8
            },
        }
    }

    /// The PWM frequency this setup gives on a `timer_hz` clock, Hz.
    pub fn pwm_hz(self, timer_hz: u32) -> f64 {
        f64::from(timer_hz) / ((f64::from(self.psc) + 1.0) * 2.0 * f64::from(self.arr))
    }
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig::DEFAULT
    }
}

/// The duty the bridge is asked for: `duty` clamped to `[-1, 1]`, or `None` for a
/// NaN (the bridge then coasts: a NaN means something upstream is wrong).
pub fn clamp_duty(duty: f32) -> Option<f32> {
    if duty.is_nan() {
        None
    } else if duty > 1.0 {
        Some(1.0)
    } else if duty < -1.0 {
        Some(-1.0)
    } else {
        Some(duty)
    }
}

/// The high fractions `[IN1, IN2]` in `[0, 1]` of the two inputs for a signed duty
/// in `decay` mode (module documentation): slow decay `(1, 1 - d)` forward and
/// `(1 - |d|, 1)` reverse; fast decay `(d, 0)` forward and `(0, |d|)` reverse. The
/// duty is clamped to `[-1, 1]`; a NaN coasts, `[0, 0]`.
pub fn input_duties(duty: f32, decay: Decay) -> [f32; 2] {
    let Some(d) = clamp_duty(duty) else {
        return [0.0, 0.0];
    };
    match decay {
        Decay::Slow if d >= 0.0 => [1.0, 1.0 - d],
        Decay::Slow => [1.0 + d, 1.0],
        Decay::Fast if d >= 0.0 => [d, 0.0],
        Decay::Fast => [0.0, -d],
    }
}

/// What the winding is connected to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Connection {
    /// Both low-side switches on (IN1 = IN2 = 1): shorted, 0 V.
    Short,
    /// Driven forward (IN1 = 1, IN2 = 0): `+V_s`.
    Forward,
    /// Driven in reverse (IN1 = 0, IN2 = 1): `-V_s`.
    Reverse,
    /// Every switch off (IN1 = IN2 = 0): the current freewheels through the body
    /// diodes against the supply until it dies; then no current.
    Open,
}

impl Connection {
    /// The winding's voltage as a fraction of the supply: `+1` forward, `-1`
    /// reverse, `0` shorted; `None` open (the body diodes decide, by the current).
    pub fn fraction(self) -> Option<f32> {
        match self {
            Connection::Forward => Some(1.0),
            Connection::Reverse => Some(-1.0),
            Connection::Short => Some(0.0),
            Connection::Open => None,
        }
    }
}

/// The parts of a period as `(length, connection)`, lengths fractions of the
/// period.
pub fn lengths(parts: &[Part]) -> impl Iterator<Item = (f32, Connection)> + '_ {
    parts.iter().scan(0.0f32, |start, p| {
        let len = p.end - *start;
        *start = p.end;
        Some((len, p.connection))
    })
}

/// The winding's mean voltage over a period, a fraction of the supply: `sum_j
/// l_j u_j` over its parts; `None` if a part coasts (then the current decides,
/// and no mean voltage is exact). In slow decay it is the duty.
pub fn mean_fraction(parts: &[Part]) -> Option<f32> {
    lengths(parts).try_fold(0.0f32, |sum, (len, c)| Some(sum + len * c.fraction()?))
}

/// The parts of one PWM period, in order ([`period`]): at most five.
pub type Period = heapless::Vec<Part, 5>;

/// One part of a PWM period: the connection, up to `end` (a fraction of the
/// period, from its start).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Part {
    /// End of the part, a fraction of the period in `(0, 1]`.
    pub end: f32,
    /// What the winding is connected to during it.
    pub connection: Connection,
}

/// The parts of a PWM period with the inputs at the high fractions `inputs`
/// (centre-aligned, valley to valley; module documentation): both high (short)
/// up to half the smaller fraction, the larger one's connection up to half the
/// larger, coast across the middle, then mirrored. Parts of zero length are left
/// out and equal neighbours merged; the last part ends at 1.
///
/// ```text
///   0      lo/2      hi/2        1 - hi/2    1 - lo/2    1
///   | short | alone   |   open     |  alone    | short  |
/// ```
pub fn period(inputs: [f32; 2]) -> Period {
    let [a, b] = inputs.map(|x| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) });
    let (low, high, alone) = if a >= b {
        (b, a, Connection::Forward)
    } else {
        (a, b, Connection::Reverse)
    };
    let edges = [
        (0.5 * low, Connection::Short),
        (0.5 * high, alone),
        (1.0 - 0.5 * high, Connection::Open),
        (1.0 - 0.5 * low, alone),
        (1.0, Connection::Short),
    ];
    let mut parts = Period::new();
    let mut start = 0.0;
    for (end, connection) in edges {
        if end <= start {
            continue;
        }
        match parts.last_mut() {
            Some(last) if last.connection == connection => last.end = end,
            // At most five parts, one per edge: the capacity cannot overflow.
            _ => {
                let _ = parts.push(Part { end, connection });
            }
        }
        start = end;
    }
    parts
}

/// The compare value for a high fraction in `[0, 1]` of `max` (the timer's count
/// for always high), rounded to the nearest.
pub fn compare(fraction: f32, max: u16) -> u16 {
    // A float-to-integer `as` saturates at 0 and 65535, and takes NaN to 0.
    ((fraction * f32::from(max) + 0.5) as u16).min(max)
}

/// A bridge input that failed to take its value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BridgeError<A, B> {
    /// IN1's PWM output.
    In1(A),
    /// IN2's PWM output.
    In2(B),
}

/// One H-bridge: its two inputs as PWM outputs (embedded-hal 1.0
/// [`SetDutyCycle`], so the same driver runs on the board's timer channels and on
/// a host mock), and its decay mode.
pub struct HBridge<A, B> {
    in1: A,
    in2: B,
    decay: Decay,
    /// The compare values last written, `[IN1, IN2]`.
    written: [u16; 2],
}

impl<A: SetDutyCycle, B: SetDutyCycle> HBridge<A, B> {
    /// The bridge on these inputs, coasting (both inputs written low).
    pub fn new(in1: A, in2: B, decay: Decay) -> Self {
        let mut bridge = HBridge {
            in1,
            in2,
            decay,
            written: [0; 2],
        };
        // Best effort: an input that cannot be written is reported at the next
        // `drive` or `coast`.
        let _ = bridge.write([0, 0]);
        bridge
    }

    /// The decay mode.
    pub fn decay(&self) -> Decay {
        self.decay
    }

    /// The compare values last written, `[IN1, IN2]`.
    pub fn written(&self) -> [u16; 2] {
        self.written
    }

    /// Drive the signed duty `duty` (clamped to `[-1, 1]`; a NaN coasts): the
    /// inputs at [`input_duties`], written in the order that leaves the decay
    /// mode's off-state in between (module documentation). On an error of
    /// either input, both are written low (coast) as far as they can be, and the
    /// first error is returned.
    pub fn drive(&mut self, duty: f32) -> Result<(), BridgeError<A::Error, B::Error>> {
        let [f1, f2] = input_duties(duty, self.decay);
        let counts = [
            compare(f1, self.in1.max_duty_cycle()),
            compare(f2, self.in2.max_duty_cycle()),
        ];
        let result = self.write(counts);
        if result.is_err() {
            let _ = self.write([0, 0]);
        }
        result
    }

    /// Both inputs low: coast (no current is driven; a current flowing dies
    /// through the body diodes).
    pub fn coast(&mut self) -> Result<(), BridgeError<A::Error, B::Error>> {
        self.write([0, 0])
    }

    /// Write the compare values: in slow decay the input whose value rises first
    /// (in between, both at the higher value: brake), in fast decay the one whose
    /// value falls first (in between, both at the lower: coast).
    fn write(&mut self, counts: [u16; 2]) -> Result<(), BridgeError<A::Error, B::Error>> {
        let in1_first = match self.decay {
            Decay::Slow => counts[0] >= self.written[0],
            Decay::Fast => counts[0] <= self.written[0],
        };
        if in1_first {
            self.set_in1(counts[0])?;
            self.set_in2(counts[1])
        } else {
            self.set_in2(counts[1])?;
            self.set_in1(counts[0])
        }
    }

    fn set_in1(&mut self, c: u16) -> Result<(), BridgeError<A::Error, B::Error>> {
        self.in1.set_duty_cycle(c).map_err(BridgeError::In1)?;
        self.written[0] = c;
        Ok(())
    }

    fn set_in2(&mut self, c: u16) -> Result<(), BridgeError<A::Error, B::Error>> {
        self.in2.set_duty_cycle(c).map_err(BridgeError::In2)?;
        self.written[1] = c;
        Ok(())
    }

    /// The two inputs back.
    pub fn release(self) -> (A, B) {
        (self.in1, self.in2)
    }
}
