//! The controller's parameters: the machine's constants it needs, the loop gains,
//! ramps, fault limits and the tuning table, with the design rules that derive them
//! from the machine ([`Params::from_machine`]) and their checks ([`Params::validate`]).
//!
//! # Design of the defaults (reference machine in brackets)
//!
//! The rotor with its DC motor, the winding's inductance neglected (`L/R` = 0.25 ms,
//! a quarter of a tick):
//!
//! ```text
//!   J w' = k i - tau_load,   i = (d V - k w) / R
//!   =>  J w' = (k V / R) d - (k^2 / R) w - tau_load          (1)
//! ```
//!
//! a first-order plant from duty `d` to speed `w` with the electrical damping pole
//! `a = k^2 / (R J)` [20 /s, the 50 ms mechanical time constant].
//!
//! - **Speed filter** `tau_f = max(5 ms, 5 ticks)` [5 ms]: at 1 kHz and 4096 counts a
//!   turn one count in a tick is 14.6 rpm; averaging over about five ticks brings
//!   that quantisation ripple down to a few rpm.
//! - **Speed PI** with the feedforward `d_ff = (k w_ref + R J a_ref / k) / V` (the
//!   back-EMF and the torque of the reference's acceleration, from (1)). The PI zero
//!   cancels the plant pole, `ki / kp = a`, and the crossover is `w_c`:
//!   `kp = w_c R J / (k V)`, `ki = w_c k / V` [4.17e-3 per rad/s, 8.33e-2 per rad].
//!   With the filter's lag the loop is `w_c / (s (tau_f s + 1))`, damping
//!   `1 / (2 sqrt(w_c tau_f))`: `w_c = 1 / (4 tau_f)` [50 rad/s] makes it 1, a step
//!   without overshoot. 50 rad/s is far above the ramps' content and far below the
//!   1 kHz tick.
//! - **Phase PI** on the error `e` (rad) giving the speed difference `dw = w1 - w2`
//!   the phase needs: `(theta_1 - theta_2)' = w1 - w2`, so with the speed loops
//!   ideal `e'' + kp e' + ki e = 0`. `kp = w_c / 5` [10 /s] keeps it a decade-ish
//!   inside the speed loop; `ki = kp^2 / 4` [25 /s^2] makes the damping 1.
//! - **Trim** `|dw| <= min(300 rpm, 0.2 w_ramp)`: 300 rpm of difference pulls a 180
//!   degree error in about 0.1 s, while the exciting force `~ w^2` of each rotor
//!   changes by at most +-10 % at 3000 rpm; the 20 % cap keeps both references well
//!   above zero at low speed.
//! - **Speeds**: at most 80 % of the no-load speed `V / k` [4584 rpm]: the last
//!   20 % of the supply is headroom for acceleration and trim. At least 300 rpm,
//!   where the phase loop joins.
//! - **Ramps**: 3000 rpm/s [about 1 s to the working speed; the acceleration torque
//!   is 3e-3 N m, a tenth of the driver's]; across the resonance band half of what
//!   the current limit allows, `0.5 k I_max / J` [19 100 rpm/s: a 1000 rpm band in
//!   about 50 ms]. The offset ramps at 180 degrees/s [right to left in 1 s].
//! - **Faults**: see [`FaultLimits`].

use core::fmt;

use crate::drive::BridgeConfig;

use super::angle::{rad_s_to_rpm, rpm_to_rad_s};
use super::tuning::TuningTable;

/// The control rate of the reference machine, Hz: one constant for host-sim and the
/// firmware (the machine file's `[controller].rate_hz`).
pub const CONTROL_RATE_HZ: f32 = 1000.0;

/// Largest encoder resolution accepted, counts per turn: `2^24`, so that counts are
/// exact in `f32` and a turn's travel fits an `i32` many times over.
pub const MAX_ENCODER_COUNTS: u32 = 1 << 24;

/// The constants of one rotor and its motor the controller's feedforward and gains
/// use.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RotorModel {
    /// Winding resistance `R`, ohm, > 0.
    pub resistance_ohm: f32,
    /// Torque constant `k`, N m/A (= back-EMF constant, V s/rad), > 0.
    pub torque_constant: f32,
    /// Inertia `J` about the axis, eccentric mass included (`J_rotor + m e^2`),
    /// kg m^2, > 0.
    pub inertia_kg_m2: f32,
    /// The largest torque that holds the rotor back at low speed, N m, >= 0: the
    /// eccentric's weight torque `m e g` (greatest with the eccentric horizontal)
    /// plus the motor's Coulomb friction; 0 if unknown. Sizes the self-test's duty
    /// ([`super::self_test`]).
    pub load_torque_nm: f32,
}

/// How many unbalance rotors the machine has (its `[[rotors]]` tables): a build-time
/// item of the firmware and host-sim's reading of the machine file, not a stored
/// parameter.
///
/// - [`RotorCount::Two`]: rotor 1 and rotor 2 at one speed, their phase offset held
///   by the phase loop (the reference machine);
/// - [`RotorCount::One`]: rotor 1 alone, its speed held by the ramp and the speed
///   loop; no phase loop (a run command's offset and direction are accepted and
///   ignored); rotor 2's duty is exactly 0, its bridge is left off
///   ([`RotorCount::bridges_on`]) and its encoder, index and current are not read, so
///   no fault comes from a rotor that does not exist. The pairs of
///   [`super::Inputs`], [`super::Outputs`] and [`super::Telemetry`] keep two
///   entries; rotor 2's read 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RotorCount {
    /// Rotor 1 alone: speed only.
    One,
    /// Rotor 1 and rotor 2: speed and phase offset.
    #[default]
    Two,
}

impl RotorCount {
    /// 1 or 2.
    pub const fn count(self) -> usize {
        match self {
            RotorCount::One => 1,
            RotorCount::Two => 2,
        }
    }

    /// The count of `n` rotors: `None` unless 1 or 2.
    pub const fn from_count(n: usize) -> Option<RotorCount> {
        match n {
            1 => Some(RotorCount::One),
            2 => Some(RotorCount::Two),
            _ => None,
        }
    }

    /// Whether there is a rotor 2 (and a phase offset to hold).
    pub const fn has_rotor2(self) -> bool {
        matches!(self, RotorCount::Two)
    }

    /// Which H-bridges a tick drives, rotor 1's and rotor 2's, given whether the
    /// controller drives the motors (`driving`): both with it on two rotors; on
    /// one, rotor 1's with it and rotor 2's never (off: both inputs low, the
    /// winding open). A bridge not driven is off ([`super::Outputs::bridges`]).
    pub const fn bridges_on(self, driving: bool) -> [bool; 2] {
        [driving, driving && self.has_rotor2()]
    }
}

/// What [`Params::from_machine`] needs to know of the machine (its file's values).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MachineConstants {
    /// Control rate, Hz (`[controller].rate_hz`).
    pub rate_hz: f32,
    /// Encoder counts per turn after x4 decoding (`[sensors].encoder_counts`).
    pub encoder_counts: u32,
    /// Nominal supply voltage, V (`[drive].supply_voltage`).
    pub supply_voltage_v: f32,
    /// The driver's current limit, A (`motor.current_limit`, the smaller of the two).
    pub current_limit_a: f32,
    /// One rotor or two (`[[rotors]]`).
    pub rotor_count: RotorCount,
    /// Rotor 1 and rotor 2. With [`RotorCount::One`] rotor 2's entry is not used
    /// ([`Params::from_machine`] takes rotor 1's in its place;
    /// [`MachineConstants::from_physics`] writes rotor 1's there).
    pub rotors: [RotorModel; 2],
    /// Rotor speeds, rpm, `[low, high]`, where the platform responds badly (its
    /// resonances, or for a rigid platform the chattering around lift-off) and the
    /// ramps hurry through; `[0, 0]` for none.
    pub resonance_band_rpm: [f32; 2],
    /// The H-bridges as wired (`[drive] decay`, `pwm_hz`): what a duty means on them.
    pub bridge: BridgeConfig,
}

impl MachineConstants {
    /// The reference machine, `examples/vibro-driver.toml`: 1 kHz, 4096 counts,
    /// 12 V, 2 A, `R = 2 ohm`, `k = 0.02 N m/A`, `J = 6e-6 + 0.01 x 0.02^2 = 1e-5
    /// kg m^2`, load torque `m e g + T_c = 0.01 x 0.02 x 9.81 + 1e-3 = 2.962e-3 N m`.
    /// Resonance band 1500 to 2500 rpm: the platform (rigid, on rigid feet)
    /// lifts off from 2125 rpm, where the exciting force `2 m e w^2` equals the
    /// weight; from about half to 1.4 times the weight it chatters with irregular
    /// partial lift-offs, so the ramps cross that band quickly.
    pub const REFERENCE: MachineConstants = MachineConstants {
        rate_hz: CONTROL_RATE_HZ,
        encoder_counts: 4096,
        supply_voltage_v: 12.0,
        current_limit_a: 2.0,
        rotor_count: RotorCount::Two,
        rotors: [RotorModel {
            resistance_ohm: 2.0,
            torque_constant: 0.02,
            inertia_kg_m2: 1.0e-5,
            load_torque_nm: 2.962e-3,
        }; 2],
        resonance_band_rpm: [1500.0, 2500.0],
        bridge: BridgeConfig::DEFAULT,
    };
}

/// Speed PI gains of one rotor.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SpeedGains {
    /// Proportional gain, duty per rad/s.
    pub kp: f32,
    /// Integral gain, duty per rad (per rad/s of error and second).
    pub ki: f32,
}

/// Fault thresholds and times. Each fault's worst-case detection time follows from
/// them (the controller's module documentation lists the bounds).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultLimits {
    /// |duty| from which a rotor counts as driven for the stall and encoder checks
    /// [0.25: at rest that drives `min(0.25 V / R, I_max)` = 1.5 A, 0.03 N m, 15
    /// times the eccentric's weight torque `m g e`: a free rotor cannot stay slow].
    pub stall_duty: f32,
    /// Speed below which a driven rotor counts as not turning, rpm [100: the stall and encoder checks need a speed well under any run speed, above the rocking of a rotor at rest].
    pub stall_speed_rpm: f32,
    /// Filtered |current| from which a slow driven rotor counts as loaded (a stall),
    /// A; below it the low current says the rotor turns and the encoder is wrong
    /// [half the stall current at `stall_duty`: 0.75 A].
    pub stall_current_a: f32,
    /// Slow, driven and loaded this long is a stall, s [0.3: longer than a dead
    /// encoder on a free rotor takes to show a low current (about 0.13 s from full
    /// speed on the reference machine), short for the winding (2 A in 2 ohm, 2.4 J)].
    pub stall_time_s: f32,
    /// Slow, driven and unloaded this long is an encoder fault, s [0.05: fifty ticks of disagreement].
    pub encoder_time_s: f32,
    /// How far an index pulse may be from a whole number of turns after the
    /// previous one, and outside the counts travelled, counts [4: one line of the
    /// encoder, as an index gated to one quadrature state can land].
    pub index_tolerance_counts: u32,
    /// A count jump faster than this is an encoder fault, rpm [twice the no-load
    /// speed at the highest supply: 14 300 rpm; below the aliasing limit of half a
    /// turn a tick].
    pub encoder_max_speed_rpm: f32,
    /// |current| above this is an over-current, A [1.25 x the driver's limit: the
    /// driver holds the limit, so more means it failed or the bridge is shorted].
    pub over_current_a: f32,
    /// Over-current this long is a fault, s [2 ms, two ticks: one ADC glitch passes].
    pub over_current_time_s: f32,
    /// |phase error| above this while running counts as lost lock, degrees [45: the
    /// force line then leans 22.5 degrees off].
    pub phase_error_max_deg: f32,
    /// Lost lock this long is a fault, s [0.5: 25 turns at 3000 rpm; a direction
    /// change or a pull-in stays far below].
    pub phase_lost_time_s: f32,
    /// No command or heartbeat this long while starting or running is a lost link,
    /// s [0.5: the host sends a heartbeat at least every 0.2 s]. `f32::INFINITY`
    /// turns the check off (a lockstep simulation without a link).
    pub link_timeout_s: f32,
    /// Lowest supply, V [0.75 x nominal: 9 V].
    pub supply_min_v: f32,
    /// Highest supply, V [1.25 x nominal: 15 V, braking energy pumped back].
    pub supply_max_v: f32,
    /// Supply out of range this long is a fault, s [10 ms: rides through the ripple
    /// of a switching tick and an ADC glitch].
    pub supply_time_s: f32,
    /// A tick that starts this much after its nominal time missed its deadline, s
    /// [a quarter of the tick: 250 us at 1 kHz; a whole tick is at most about 1 600
    /// instructions (10 us at 168 MHz, `benchmarks/firmware.md`) and the
    /// interrupts above it a few us, so this much means something starved the loop].
    pub tick_late_max_s: f32,
    /// A tick whose work took this long missed its deadline, s [half the tick: 500
    /// us at 1 kHz, fifty times a whole tick's work].
    pub tick_busy_max_s: f32,
}

/// Everything the controller needs, fixed while it runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// Control rate, Hz: the nominal `dt` is `1 / rate_hz`.
    pub rate_hz: f32,
    /// Encoder counts per turn after x4 decoding, in [4, 2^24].
    pub encoder_counts: u32,
    /// Nominal supply voltage, V: used for the feedforward when the measurement is
    /// unusable.
    pub supply_nominal_v: f32,
    /// One rotor or two: with [`RotorCount::One`] the controller drives rotor 1
    /// alone, without the phase loop, and rotor 2's entries of `rotors` and
    /// `speed_gains` are rotor 1's, unused.
    pub rotor_count: RotorCount,
    /// Rotor 1 and rotor 2, for the feedforward.
    pub rotors: [RotorModel; 2],
    /// Time constant of the speed estimate's low-pass filter, s.
    pub speed_filter_tau_s: f32,
    /// Time constant of the current filter the stall check uses, s [5 ms: ten times
    /// `L/R`, irons out ADC noise and PWM ripple].
    pub current_filter_tau_s: f32,
    /// Speed PI gains of rotor 1 and rotor 2.
    pub speed_gains: [SpeedGains; 2],
    /// Lowest duty the speed loops write, in [-1, 0] [0: braking by the back-EMF
    /// through the shorted winding, never driving a rotor backwards].
    pub min_duty: f32,
    /// Phase loop proportional gain, (rad/s of speed difference) per rad.
    pub phase_kp: f32,
    /// Phase loop integral gain, (rad/s) per (rad s).
    pub phase_ki: f32,
    /// Largest speed difference `w1 - w2` the phase loop asks for, rpm.
    pub phase_trim_max_rpm: f32,
    /// Largest speed difference as a fraction of the ramped speed, in [0, 1].
    pub phase_trim_fraction: f32,
    /// The phase loop closes once the ramped speed is at least this, rpm.
    pub phase_loop_min_rpm: f32,
    /// Lowest speed a run command may ask for, rpm (>= `phase_loop_min_rpm`).
    pub min_speed_rpm: f32,
    /// Highest speed a run command may ask for, rpm.
    pub max_speed_rpm: f32,
    /// Speed ramp rate outside the resonance band, rpm/s.
    pub speed_ramp_rpm_s: f32,
    /// The resonance band, rpm, `[low, high]` (`low <= high`; equal for none).
    pub resonance_band_rpm: [f32; 2],
    /// Speed ramp rate inside the resonance band, rpm/s.
    pub resonance_ramp_rpm_s: f32,
    /// Offset ramp rate, degrees/s.
    pub offset_ramp_deg_s: f32,
    /// A stop ends (idle) once the ramp is at 0 and both speeds are below this, rpm.
    pub stop_speed_rpm: f32,
    /// ... or this long after the ramp reached 0, s (the rotors then coast).
    pub stop_timeout_s: f32,
    /// Fault thresholds and times.
    pub limits: FaultLimits,
    /// Offsets for travel by speed.
    pub tuning: TuningTable,
}

/// A parameter that fails [`Params::validate`]: the field and what it must be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamError {
    /// The field's path, e.g. `limits.stall_time_s`.
    pub field: &'static str,
    /// What it must be, e.g. `finite and >= 0`.
    pub requirement: &'static str,
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "controller parameter {}: must be {}",
            self.field, self.requirement
        )
    }
}

/// `Err` naming `field` unless `ok`.
fn check(ok: bool, field: &'static str, requirement: &'static str) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError { field, requirement })
    }
}

/// Finite and > 0.
fn positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

/// Finite and >= 0.
fn non_negative(x: f32) -> bool {
    x.is_finite() && x >= 0.0
}

/// `Err` naming `field` unless `x` is finite and > 0.
fn check_positive(x: f32, field: &'static str) -> Result<(), ParamError> {
    check(positive(x), field, "finite and > 0")
}

/// `Err` naming `field` unless `x` is finite and >= 0.
fn check_non_negative(x: f32, field: &'static str) -> Result<(), ParamError> {
    check(non_negative(x), field, "finite and >= 0")
}

impl Params {
    /// Parameters for a machine by the design rules of the module documentation,
    /// with the default tuning table.
    ///
    /// On a one-rotor machine rotor 2 is taken as a copy of rotor 1 for every rule
    /// below, so that the rules "over both rotors" (the slower one's speed, the
    /// weaker one's acceleration) give rotor 1's own values; rotor 2 is never
    /// driven.
    pub fn from_machine(m: &MachineConstants) -> Params {
        let v = m.supply_voltage_v;
        let rate = m.rate_hz;
        // The rotors that exist: on a one-rotor machine, rotor 1 in both places.
        let rotors = match m.rotor_count {
            RotorCount::Two => m.rotors,
            RotorCount::One => [m.rotors[0]; 2],
        };

        // Speed filter: 5 ms, never under 5 ticks; loop crossover for damping 1.
        let tau_f = if 5.0 / rate > 0.005 {
            5.0 / rate
        } else {
            0.005
        };
        let w_c = 1.0 / (4.0 * tau_f);
        let gains = |r: &RotorModel| SpeedGains {
            kp: w_c * r.resistance_ohm * r.inertia_kg_m2 / (r.torque_constant * v),
            ki: w_c * r.torque_constant / v,
        };

        // Phase loop a fifth of the speed loop, damping 1.
        let phase_kp = w_c / 5.0;
        let phase_ki = phase_kp * phase_kp / 4.0;

        // Speeds: 80 % of the slower rotor's no-load speed.
        let k_max = rotors[0].torque_constant.max(rotors[1].torque_constant);
        let no_load_rpm = rad_s_to_rpm(v / k_max);

        // Resonance ramp: half the acceleration the current limit allows.
        let accel = |r: &RotorModel| r.torque_constant * m.current_limit_a / r.inertia_kg_m2;
        let accel_max = accel(&rotors[0]).min(accel(&rotors[1]));
        let speed_ramp = 3000.0;
        let resonance_ramp = rad_s_to_rpm(0.5 * accel_max).max(speed_ramp);

        // Stall current: half of what a stalled rotor draws at the stall duty.
        let stall_duty = 0.25;
        let stall_i = |r: &RotorModel| (stall_duty * v / r.resistance_ohm).min(m.current_limit_a);
        let stall_current = 0.5 * stall_i(&rotors[0]).min(stall_i(&rotors[1]));

        // Encoder jumps: twice the no-load speed at the highest supply, under the
        // aliasing limit (half a turn a tick = 30 rate rpm).
        let supply_max = 1.25 * v;
        let jump_rpm = (2.0 * rad_s_to_rpm(supply_max / k_max)).min(0.8 * 30.0 * rate);

        let tick = 1.0 / rate;
        Params {
            rate_hz: rate,
            encoder_counts: m.encoder_counts,
            supply_nominal_v: v,
            rotor_count: m.rotor_count,
            rotors,
            speed_filter_tau_s: tau_f,
            current_filter_tau_s: 0.005,
            speed_gains: [gains(&rotors[0]), gains(&rotors[1])],
            min_duty: 0.0,
            phase_kp,
            phase_ki,
            phase_trim_max_rpm: 300.0,
            phase_trim_fraction: 0.2,
            phase_loop_min_rpm: 300.0,
            min_speed_rpm: 300.0,
            max_speed_rpm: 0.8 * no_load_rpm,
            speed_ramp_rpm_s: speed_ramp,
            resonance_band_rpm: m.resonance_band_rpm,
            resonance_ramp_rpm_s: resonance_ramp,
            offset_ramp_deg_s: 180.0,
            stop_speed_rpm: 100.0,
            stop_timeout_s: 2.0,
            limits: FaultLimits {
                stall_duty,
                stall_speed_rpm: 100.0,
                stall_current_a: stall_current,
                stall_time_s: 0.3,
                encoder_time_s: 0.05,
                index_tolerance_counts: 4.min(m.encoder_counts / 8),
                encoder_max_speed_rpm: jump_rpm,
                over_current_a: 1.25 * m.current_limit_a,
                over_current_time_s: (2.0 * tick).max(0.002),
                phase_error_max_deg: 45.0,
                phase_lost_time_s: 0.5,
                link_timeout_s: 0.5,
                supply_min_v: 0.75 * v,
                supply_max_v: supply_max,
                supply_time_s: (2.0 * tick).max(0.01),
                tick_late_max_s: 0.25 * tick,
                tick_busy_max_s: 0.5 * tick,
            },
            tuning: TuningTable::default(),
        }
    }

    /// [`Params::from_machine`] of [`MachineConstants::REFERENCE`].
    pub fn reference() -> Params {
        Params::from_machine(&MachineConstants::REFERENCE)
    }

    /// The nominal tick, s.
    pub fn tick_s(&self) -> f32 {
        1.0 / self.rate_hz
    }

    /// The first parameter that is out of its range, if any, in the order of the
    /// checks below: the machine and the filters, the loops, the speeds and
    /// ramps, the fault limits.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.validate_machine()?;
        self.validate_loops()?;
        self.validate_speeds()?;
        self.validate_limits()
    }

    /// The control rate, the encoder, the supply, the rotors' models and the
    /// filters' time constants.
    fn validate_machine(&self) -> Result<(), ParamError> {
        check(
            positive(self.rate_hz) && self.rate_hz <= 100_000.0,
            "rate_hz",
            "in (0, 100000] Hz",
        )?;
        check(
            (4..=MAX_ENCODER_COUNTS).contains(&self.encoder_counts),
            "encoder_counts",
            "in [4, 2^24]",
        )?;
        check_positive(self.supply_nominal_v, "supply_nominal_v")?;
        for r in &self.rotors {
            check_positive(r.resistance_ohm, "rotors.resistance_ohm")?;
            check_positive(r.torque_constant, "rotors.torque_constant")?;
            check_positive(r.inertia_kg_m2, "rotors.inertia_kg_m2")?;
            check_non_negative(r.load_torque_nm, "rotors.load_torque_nm")?;
        }
        check_non_negative(self.speed_filter_tau_s, "speed_filter_tau_s")?;
        check_non_negative(self.current_filter_tau_s, "current_filter_tau_s")
    }

    /// The speed loops' gains and lowest duty, the phase loop's gains, trim and
    /// closing speed.
    fn validate_loops(&self) -> Result<(), ParamError> {
        for g in &self.speed_gains {
            check_non_negative(g.kp, "speed_gains.kp")?;
            check_non_negative(g.ki, "speed_gains.ki")?;
        }
        check(
            self.min_duty.is_finite() && (-1.0..=0.0).contains(&self.min_duty),
            "min_duty",
            "in [-1, 0]",
        )?;
        check_non_negative(self.phase_kp, "phase_kp")?;
        check_non_negative(self.phase_ki, "phase_ki")?;
        check_non_negative(self.phase_trim_max_rpm, "phase_trim_max_rpm")?;
        check(
            (0.0..=1.0).contains(&self.phase_trim_fraction),
            "phase_trim_fraction",
            "in [0, 1]",
        )?;
        check_non_negative(self.phase_loop_min_rpm, "phase_loop_min_rpm")
    }

    /// The speed range a run command may ask for, the speed and offset ramps, the
    /// end of a stop.
    fn validate_speeds(&self) -> Result<(), ParamError> {
        check(
            positive(self.min_speed_rpm) && self.min_speed_rpm >= self.phase_loop_min_rpm,
            "min_speed_rpm",
            "finite, > 0 and >= phase_loop_min_rpm",
        )?;
        check(
            self.max_speed_rpm.is_finite() && self.max_speed_rpm >= self.min_speed_rpm,
            "max_speed_rpm",
            "finite and >= min_speed_rpm",
        )?;
        check_positive(self.speed_ramp_rpm_s, "speed_ramp_rpm_s")?;
        let [lo, hi] = self.resonance_band_rpm;
        check(
            non_negative(lo) && hi.is_finite() && lo <= hi,
            "resonance_band_rpm",
            "finite, 0 <= low <= high",
        )?;
        check_positive(self.resonance_ramp_rpm_s, "resonance_ramp_rpm_s")?;
        check_positive(self.offset_ramp_deg_s, "offset_ramp_deg_s")?;
        check_non_negative(self.stop_speed_rpm, "stop_speed_rpm")?;
        check_positive(self.stop_timeout_s, "stop_timeout_s")
    }

    /// The fault limits ([`FaultLimits`]), some against the encoder, the speed
    /// range, the rate and the nominal supply.
    fn validate_limits(&self) -> Result<(), ParamError> {
        let l = &self.limits;
        check(
            positive(l.stall_duty) && l.stall_duty <= 1.0,
            "limits.stall_duty",
            "in (0, 1]",
        )?;
        check_non_negative(l.stall_speed_rpm, "limits.stall_speed_rpm")?;
        check_non_negative(l.stall_current_a, "limits.stall_current_a")?;
        check_non_negative(l.stall_time_s, "limits.stall_time_s")?;
        check_non_negative(l.encoder_time_s, "limits.encoder_time_s")?;
        check(
            l.index_tolerance_counts < self.encoder_counts / 4,
            "limits.index_tolerance_counts",
            "below a quarter turn (encoder_counts / 4)",
        )?;
        // Counts a tick at the jump limit stay under half a turn (no aliasing).
        check(
            l.encoder_max_speed_rpm.is_finite()
                && l.encoder_max_speed_rpm >= self.max_speed_rpm
                && l.encoder_max_speed_rpm < 30.0 * self.rate_hz,
            "limits.encoder_max_speed_rpm",
            "finite, >= max_speed_rpm and < 30 rate_hz (half a turn a tick)",
        )?;
        check_positive(l.over_current_a, "limits.over_current_a")?;
        check_non_negative(l.over_current_time_s, "limits.over_current_time_s")?;
        check(
            positive(l.phase_error_max_deg) && l.phase_error_max_deg <= 180.0,
            "limits.phase_error_max_deg",
            "in (0, 180]",
        )?;
        check_non_negative(l.phase_lost_time_s, "limits.phase_lost_time_s")?;
        check(
            l.link_timeout_s > 0.0,
            "limits.link_timeout_s",
            "> 0 (infinite turns the check off)",
        )?;
        check(
            non_negative(l.supply_min_v)
                && l.supply_max_v.is_finite()
                && l.supply_min_v < l.supply_max_v,
            "limits.supply_min_v",
            "finite, 0 <= supply_min_v < supply_max_v",
        )?;
        check(
            l.supply_min_v <= self.supply_nominal_v && self.supply_nominal_v <= l.supply_max_v,
            "supply_nominal_v",
            "inside [limits.supply_min_v, limits.supply_max_v]",
        )?;
        check_non_negative(l.supply_time_s, "limits.supply_time_s")?;
        check_positive(l.tick_late_max_s, "limits.tick_late_max_s")?;
        check_positive(l.tick_busy_max_s, "limits.tick_busy_max_s")
    }

    /// The most counts a rotor can travel in `dt` s without an encoder fault.
    pub fn max_counts(&self, dt: f32) -> f32 {
        rpm_to_rad_s(self.limits.encoder_max_speed_rpm) * dt * self.encoder_counts as f32
            / super::angle::TURN_RAD
            + 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_params_are_valid_and_as_designed() {
        let p = Params::reference();
        assert_eq!(p.validate(), Ok(()));
        assert!((p.speed_gains[0].kp - 4.1667e-3).abs() < 1e-6);
        assert!((p.speed_gains[0].ki - 8.3333e-2).abs() < 1e-5);
        assert!((p.phase_kp - 10.0).abs() < 1e-4);
        assert!((p.phase_ki - 25.0).abs() < 1e-3);
        assert!((p.limits.stall_current_a - 0.75).abs() < 1e-6);
        assert!((p.max_speed_rpm - 4583.66).abs() < 0.1);
    }

    #[test]
    fn a_bad_parameter_is_named() {
        let mut p = Params::reference();
        p.limits.stall_time_s = f32::NAN;
        assert_eq!(p.validate().unwrap_err().field, "limits.stall_time_s");
    }

    /// A change that spoils one parameter, the field named and its requirement.
    type Case = (fn(&mut Params), &'static str, &'static str);

    /// One bad parameter of each group of checks is named with its requirement.
    #[test]
    fn each_group_names_its_parameter() {
        let cases: [Case; 6] = [
            (|p| p.rate_hz = 0.0, "rate_hz", "in (0, 100000] Hz"),
            (
                |p| p.rotors[1].load_torque_nm = -1.0,
                "rotors.load_torque_nm",
                "finite and >= 0",
            ),
            (
                |p| p.phase_trim_max_rpm = f32::NAN,
                "phase_trim_max_rpm",
                "finite and >= 0",
            ),
            (
                |p| p.stop_timeout_s = 0.0,
                "stop_timeout_s",
                "finite and > 0",
            ),
            (
                |p| p.limits.tick_busy_max_s = f32::INFINITY,
                "limits.tick_busy_max_s",
                "finite and > 0",
            ),
            (
                |p| p.supply_nominal_v = 2.0 * p.limits.supply_max_v,
                "supply_nominal_v",
                "inside [limits.supply_min_v, limits.supply_max_v]",
            ),
        ];
        for (spoil, field, requirement) in cases {
            let mut p = Params::reference();
            spoil(&mut p);
            assert_eq!(
                p.validate(),
                Err(ParamError { field, requirement }),
                "{field}"
            );
        }
    }
}
