//! The H-bridge in the plant (`host_sim::plant::bridge`, the machine file's
//! `[drive] decay` and `pwm_hz`) against closed forms of the armature circuit over
//! a PWM period, with the rotor held at a constant speed (so the back-EMF
//! `E = k omega` is constant) and the platform held.
//!
//! The circuit `L di/dt = u - R i - E`, `tau = L / R`, period `T`, duty `d`,
//! supply `V_s`; `a = (V_s - E) / R` and `b = (V_s + E) / R`:
//!
//! - **Slow decay** (drive, then brake): the winding sees `V_s` then 0 V whatever
//!   the current's sign, a linear circuit, so the periodic steady state has the
//!   mean current `(d V_s - E) / R`.
//! - **Fast decay** (drive, then coast through the body diodes, `-V_s` while a
//!   positive current flows, nothing once it has died):
//!   the timer is centre-aligned, so a period drives for `d/2` at each end and
//!   coasts in the middle; in the periodic steady state that is the same
//!   waveform as drive-then-coast shifted by `d T / 2`, with the same mean, so the
//!   closed forms below take the period from the start of the drive:
//!   - *continuous conduction* (the current never reaches zero): the periodic
//!     state starts each period at
//!     `i0 = (a (1 - e1) e2 - b (1 - e2)) / (1 - e1 e2)`, `e1 = exp(-d T / tau)`,
//!     `e2 = exp(-(1 - d) T / tau)`, and since the circuit is linear while it
//!     conducts the mean current is `((2 d - 1) V_s - E) / R`;
//!   - *discontinuous conduction* (`i0` above would be negative): each period
//!     starts at 0, rises to `i1 = a (1 - e1)`, falls to zero at
//!     `t_z = tau ln((i1 + b) / b)` and rests; the mean current is
//!     `(a (d T - tau (1 - e1)) - b t_z + (i1 + b) tau (1 - exp(-t_z / tau))) / T`.
//!
//! For the reference motor (2 ohm, 0.5 mH, 12 V, 20 kHz) these give what the
//! first board would draw with a fast-decay drive against what the
//! controller assumes (slow decay): at standstill and `d = 0.049` (the
//! self-test's duty) 2.9 mA against 0.294 A; at `d = 0.5` 0.273 A against 3 A; at
//! 3000 rpm and `d = 0.049` 0.9 mA against -2.85 A (braking). (The diodes' forward
//! drops, not modelled, lower the fast-decay figures a little more.)
//!
//! The plant's mean current is measured from its dense output over whole periods
//! once the transient has died (20 electrical time constants), 4000 samples a
//! period, trapezoidal: its error is far below the tolerances, which are set by
//! the integrator's (`rtol = 1e-8` on a current scale of the 10 A limit here).

use std::f64::consts::PI;
use tests::initial_state;

use host_sim::machine::Machine;
use host_sim::plant::bridge::BridgeCommand;
use host_sim::plant::model::PlantModel;
use host_sim::plant::simulator::{Holds, Output, Plant, Settings};
use host_sim::simulation::trace::EndState;
use shared::controller::{Faults, State};
use tests::held::{held_plant, reference_machine};

const R: f64 = 2.0;
const L: f64 = 0.5e-3;
const VS: f64 = 12.0;
const K: f64 = 0.02;
const T: f64 = 1.0 / 20_000.0;

/// The reference machine with the `--set` override `set` and a current limit high
/// enough to stay out of the way (10 A).
fn machine_with(set: String) -> Machine {
    reference_machine(0.0, &[set, "motor.current_limit=10".to_string()])
}

/// Rotors and platform held.
fn all_held() -> Holds {
    Holds {
        platform: true,
        rotors: true,
        ..Holds::default()
    }
}

/// The reference machine with `decay`, a current limit high enough to stay out
/// of the way (10 A), and its rotors and platform held, rotor speeds `rpm`.
fn held(decay: &str, rpm: f64) -> (Machine, Plant) {
    let m = machine_with(format!("drive.decay={decay}"));
    let plant = held_plant(&m, rpm, Settings::default(), all_held());
    (m, plant)
}

/// The circuit's constants above are the reference machine file's.
#[test]
fn the_constants_are_the_reference_machines() {
    let (m, _) = held("slow", 0.0);
    let motor = &m.rotors[0].motor;
    assert_eq!(
        (motor.resistance, motor.inductance, motor.torque_constant),
        (R, L, K)
    );
    assert_eq!(m.drive.supply_voltage, VS);
    assert_eq!(1.0 / f64::from(m.drive.bridge.pwm_hz), T);
}

/// Mean current of rotor 1 over each of the periods `[0, count)` (in its driven
/// sense, which is rotor 1's ccw), driven at `duty` from t = 0, A.
fn period_means(decay: &str, rpm: f64, duty: f64, count: usize) -> Vec<f64> {
    let (_, mut plant) = held(decay, rpm);
    plant.set_bridges([BridgeCommand::Duty(duty), BridgeCommand::Off]);
    let per_period = 4000;
    let dt = T / per_period as f64;
    let total = count * per_period;
    let mut next = 0usize;
    let mut sums = vec![0.0; count];
    let mut last: Option<f64> = None;
    plant
        .advance_to(count as f64 * T, &mut |out| {
            if let Output::Dense(step, upto) = out {
                while next <= total {
                    let t = next as f64 * dt;
                    if t > upto {
                        break;
                    }
                    let i = step.at(t)[10];
                    if let Some(prev) = last {
                        sums[(next - 1) / per_period] += 0.5 * (prev + i) * dt;
                    }
                    last = Some(i);
                    next += 1;
                }
            }
        })
        .unwrap();
    assert_eq!(next, total + 1, "sampled every point");
    sums.iter().map(|s| s / T).collect()
}

/// Mean current of rotor 1 over periods `[n0, n0 + count)`, A.
fn mean_current(decay: &str, rpm: f64, duty: f64, n0: usize, count: usize) -> f64 {
    let means = period_means(decay, rpm, duty, n0 + count);
    means[n0..].iter().sum::<f64>() / count as f64
}

/// The closed forms of the module documentation: `(continuous, mean current)`.
fn fast_decay_closed_form(d: f64, rpm: f64) -> (bool, f64) {
    let tau = L / R;
    let e = K * rpm * PI / 30.0;
    let (a, b) = ((VS - e) / R, (VS + e) / R);
    let e1 = (-d * T / tau).exp();
    let e2 = (-(1.0 - d) * T / tau).exp();
    let i0 = (a * (1.0 - e1) * e2 - b * (1.0 - e2)) / (1.0 - e1 * e2);
    if i0 > 0.0 {
        return (true, ((2.0 * d - 1.0) * VS - e) / R);
    }
    let i1 = a * (1.0 - e1);
    let tz = tau * ((i1 + b) / b).ln();
    let mean =
        (a * (d * T - tau * (1.0 - e1)) - b * tz + (i1 + b) * tau * (1.0 - (-tz / tau).exp())) / T;
    (false, mean)
}

/// The transient dies in 20 time constants (`exp(-20) = 2e-9`): 5 ms, 100
/// periods; then 20 periods.
const SETTLED: usize = 100;
const PERIODS: usize = 20;

#[test]
fn slow_decay_mean_current_is_d_vs_minus_e_over_r() {
    for (d, rpm) in [
        (0.049, 0.0),
        (0.5, 0.0),
        (0.049, 3000.0),
        (0.9, 3000.0),
        (-0.3, 0.0),
    ] {
        let got = mean_current("slow", rpm, d, SETTLED, PERIODS);
        let e = K * rpm * PI / 30.0;
        let want = (d * VS - e) / R;
        assert!(
            (got - want).abs() < 1e-6,
            "d {d}, {rpm} rpm: {got} A vs {want} A"
        );
    }
}

/// Slow decay, from the switch-on on, period by period: the plant (the period's
/// mean voltage on the winding) against the switched circuit, solved exactly part
/// by part (`L di/dt = u - R i - E`, `u` = 0 in the brake around the valley,
/// `V_s` in the drive around the peak; here, not through the plant or
/// `shared::drive`).
///
/// Why they differ, and by how much at most: both are linear with the same decay
/// over a period, `r = exp(-T / tau)`, so the currents at the period starts obey
/// `i_{n+1} = r i_n + K` with their own `K`, and their difference is
/// `delta_n = c (1 - r^n)`, `c` the switched current's steady offset at the period
/// start (the middle of the brake) from the mean. The period means obey
/// `L (i_{n+1} - i_n) / T = d V_s - R mean_n - E` exactly in both, so
/// `mean_sw - mean_avg = -(tau / T)(delta_{n+1} - delta_n) = -(tau / T)(1 - r) c r^n`:
/// at most `(tau / T)(1 - r) |c|` (3.4 mA at d = 0.5), and zero once settled.
#[test]
fn slow_decay_period_means_follow_the_switched_circuit() {
    let tau = L / R;
    let r = (-T / tau).exp();
    for (d, rpm) in [
        (0.5, 0.0),
        (0.049, 0.0),
        (0.6, 3000.0),
        (0.9, 3000.0),
        (-0.3, 0.0),
    ] {
        let e = K * rpm * PI / 30.0;
        // Forward: brake (1 - d)/2, drive d at +V_s, brake (1 - d)/2; reverse at -V_s.
        let a: f64 = d;
        let drive = VS * a.signum();
        let parts = [
            (0.5 * (1.0 - a.abs()), 0.0),
            (a.abs(), drive),
            (0.5 * (1.0 - a.abs()), 0.0),
        ];
        let n = 120;
        let mut i = 0.0;
        let mut switched = Vec::new();
        for _ in 0..n {
            let mut integral = 0.0;
            for (len, u) in parts {
                let h = len * T;
                let target = (u - e) / R;
                integral += target * h + (i - target) * tau * (1.0 - (-h / tau).exp());
                i = target + (i - target) * (-h / tau).exp();
            }
            switched.push(integral / T);
        }
        // The switched steady state at the period start, and its offset c.
        let mut i_ss = 0.0;
        for _ in 0..2000 {
            for (len, u) in parts {
                let target = (u - e) / R;
                i_ss = target + (i_ss - target) * (-len * T / tau).exp();
            }
        }
        let c = i_ss - (d * VS - e) / R;
        let bound = (tau / T) * (1.0 - r) * c.abs();
        let plant = period_means("slow", rpm, d, n);
        for (k, (p, s)) in plant.iter().zip(&switched).enumerate() {
            let diff = (p - s).abs();
            let settled = k >= 100;
            let allowed = if settled {
                1e-6
            } else {
                bound * r.powi(k as i32) + 1e-6
            };
            assert!(
                diff <= allowed,
                "d {d}, {rpm} rpm, period {k}: plant {p} A, switched {s} A, |diff| {diff:.3e} > {allowed:.3e}"
            );
        }
    }
}

#[test]
fn fast_decay_mean_current_follows_the_closed_forms() {
    // Discontinuous at standstill and low duty, continuous at high duty.
    for (d, rpm, continuous) in [
        (0.049, 0.0, false),
        (0.5, 0.0, false),
        (0.049, 3000.0, false),
        (0.7, 3000.0, false),
        (0.9, 3000.0, true),
        (0.95, 0.0, true),
    ] {
        let (cont, want) = fast_decay_closed_form(d, rpm);
        assert_eq!(cont, continuous, "d {d}, {rpm} rpm: conduction mode");
        let got = mean_current("fast", rpm, d, SETTLED, PERIODS);
        assert!(
            (got - want).abs() < 1e-6 + 1e-6 * want.abs(),
            "d {d}, {rpm} rpm: {got} A vs {want} A"
        );
    }
}

/// What the controller reads (`Plant::mean_currents`, the winding current's mean
/// over the last `advance_to`, one control tick of 1 ms = 20 PWM periods) once the
/// transient has died: the closed forms above, in both decay modes, in the
/// continuous and the discontinuous case. The tick is a whole number of periods,
/// so the tick's mean is the periods' mean.
#[test]
fn the_current_a_tick_reads_is_the_closed_form_mean() {
    let tick = 1e-3;
    let settled_ticks = 6; // 6 ms: 24 electrical time constants
    for (decay, d, rpm) in [
        ("slow", 0.049, 0.0),
        ("slow", 0.5, 3000.0),
        ("slow", -0.3, 0.0),
        ("fast", 0.049, 0.0),
        ("fast", 0.5, 0.0),
        ("fast", 0.9, 3000.0),
    ] {
        let (_, mut plant) = held(decay, rpm);
        plant.set_bridges([BridgeCommand::Duty(d), BridgeCommand::Off]);
        for k in 1..=settled_ticks {
            plant.advance_to(k as f64 * tick, &mut |_| {}).unwrap();
        }
        plant
            .advance_to((settled_ticks + 1) as f64 * tick, &mut |_| {})
            .unwrap();
        let got = plant.mean_currents()[0];
        let want = match decay {
            "slow" => (d * VS - K * rpm * PI / 30.0) / R,
            _ => fast_decay_closed_form(d, rpm).1,
        };
        assert!(
            (got - want).abs() < 1e-6 + 1e-6 * want.abs(),
            "{decay}, d {d}, {rpm} rpm: the tick reads {got} A, the closed form is {want} A"
        );
    }
}

/// What the first board would have done with the self-test's duty at standstill:
/// the closed forms, the plant, and the ratio the issue reported (a hundred times
/// less current than the controller expects).
#[test]
fn fast_decay_at_the_self_tests_duty_barely_drives() {
    let slow = mean_current("slow", 0.0, 0.049, SETTLED, PERIODS);
    let fast = mean_current("fast", 0.0, 0.049, SETTLED, PERIODS);
    assert!((slow - 0.294).abs() < 1e-6, "{slow}");
    assert!((fast - 0.00285).abs() < 1e-5, "{fast}");
    // At 3000 rpm slow decay brakes with -2.85 A, fast decay does nothing.
    let slow = mean_current("slow", 3000.0, 0.049, SETTLED, PERIODS);
    let fast = mean_current("fast", 3000.0, 0.049, SETTLED, PERIODS);
    assert!(slow < -2.8 && fast.abs() < 1e-3, "{slow} A, {fast} A");
}

/// A duty takes effect at the next PWM period start (the timer's preload), off
/// at once (the main output enable), and a coasting current dies through the
/// body diodes in `tau ln(1 + i R / (V_s + E))`, not at once.
#[test]
fn the_bridge_switches_as_the_timer_does() {
    // Off at 50.3 periods: the current freewheels to zero, at rest, from the slow
    // decay's 3 A... after 50 periods of d = 0.5 at standstill.
    let (_, mut plant) = held("slow", 0.0);
    plant.set_bridges([BridgeCommand::Duty(0.5), BridgeCommand::Off]);
    plant.advance_to(50.0 * T, &mut |_| {}).unwrap();
    let i_on = plant.currents()[0];
    assert!(
        (i_on - 3.0 * (1.0 - (-50.0 * T / (L / R)).exp())).abs() < 1e-6,
        "{i_on}"
    );
    plant.advance_to(50.3 * T, &mut |_| {}).unwrap();
    let t_off = plant.t;
    plant.set_bridges([BridgeCommand::Off, BridgeCommand::Off]);
    // It decays under -V_s - R i: zero at tau ln(1 + i R / V_s).
    let i_cut = plant.currents()[0];
    let t_zero = (L / R) * (1.0 + i_cut * R / VS).ln();
    plant
        .advance_to(t_off + 0.99 * t_zero, &mut |_| {})
        .unwrap();
    assert!(plant.currents()[0] > 0.0, "still flowing");
    plant
        .advance_to(t_off + 1.01 * t_zero, &mut |_| {})
        .unwrap();
    assert_eq!(plant.currents()[0], 0.0, "died at {t_zero} s");
    plant.advance_to(t_off + 20.0 * T, &mut |_| {}).unwrap();
    assert_eq!(plant.currents()[0], 0.0, "and stays dead");

    // A duty commanded in the middle of a period waits for the next period start.
    let (_, mut plant) = held("slow", 0.0);
    plant.advance_to(2.4 * T, &mut |_| {}).unwrap();
    plant.set_bridges([BridgeCommand::Duty(1.0), BridgeCommand::Off]);
    plant.advance_to(2.99 * T, &mut |_| {}).unwrap();
    assert_eq!(plant.currents()[0], 0.0, "nothing before the period start");
    plant.advance_to(3.5 * T, &mut |_| {}).unwrap();
    let i = plant.currents()[0];
    let want = (VS / R) * (1.0 - (-0.5 * T / (L / R)).exp());
    assert!((i - want).abs() < 1e-6, "{i} vs {want}");
}

/// Above 50 kHz of PWM the timer updates every few periods (the board's ADC
/// samples at each update and needs about 10 us for its three conversions): at
/// 200 kHz every 4 periods, so a duty commanded in period 1 waits for period 4.
#[test]
fn above_50_khz_a_duty_waits_for_the_update_every_few_periods() {
    let t = 1.0 / 200_000.0;
    let m = machine_with("drive.pwm_hz=200000".to_string());
    let mut plant = Plant::new(
        PlantModel::new(&m),
        initial_state(&m),
        Settings::default(),
        all_held(),
    );
    plant.advance_to(1.5 * t, &mut |_| {}).unwrap();
    plant.set_bridges([BridgeCommand::Duty(1.0), BridgeCommand::Off]);
    plant.advance_to(3.99 * t, &mut |_| {}).unwrap();
    assert_eq!(
        plant.currents()[0],
        0.0,
        "nothing before the update at period 4"
    );
    plant.advance_to(5.0 * t, &mut |_| {}).unwrap();
    let i = plant.currents()[0];
    let want = (VS / R) * (1.0 - (-t / (L / R)).exp());
    assert!((i - want).abs() < 1e-6, "{i} vs {want}");
}

/// The controller on a bridge wired for fast decay (`--command right`): the speed
/// ramp starts at low duty, where fast decay draws almost no current (2.9 mA at
/// the self-test's duty at standstill), so the rotors never start and the
/// controller, driving without counts, latches its encoder fault within a second.
/// The same machine in slow decay travels right at 3000 rpm.
#[test]
fn the_controller_cannot_start_the_rotors_on_a_fast_decay_bridge() {
    use host_sim::simulation::closed_loop::ControllerDriver;
    use host_sim::simulation::{simulate, RunOptions};
    use shared::controller::{Command, Direction};
    for decay in ["slow", "fast"] {
        let m = reference_machine(0.0, &[format!("drive.decay={decay}")]);
        let command = Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        };
        let mut driver = ControllerDriver::new(&m, vec![(0.0, command)]).expect("starts");
        let options = RunOptions::new(2.0);
        let run = simulate(&m, &mut driver, &options);
        let s = &run.summary;
        if decay == "slow" {
            assert_eq!(s.state, EndState::Controller(State::Running), "{s:?}");
            assert!(
                s.rotor_speed_rpm.iter().all(|w| (w - 3000.0).abs() < 5.0),
                "{s:?}"
            );
        } else {
            assert_eq!(s.state, EndState::Controller(State::Fault), "{s:?}");
            assert!(s.faults.contains(Faults::ENCODER), "{s:?}");
            assert!(s.rotor_speed_rpm.iter().all(|w| w.abs() < 1.0), "{s:?}");
        }
    }
}

/// The processor in the loop's command, the inputs' high fractions as the timer
/// holds them (`compare / ARR`, ARR 4200 at 20 kHz), drives as the duty on the
/// timer's grid does, and a duty between two steps of the grid as that step:
/// the quantisation the timer makes. In both decay modes, at standstill.
#[test]
fn the_timers_inputs_drive_as_the_duty_they_quantise() {
    use shared::drive::{compare, input_duties, Decay};
    const ARR: u16 = 4200;
    let current = |decay: &str, command: BridgeCommand| {
        let (_, mut plant) = held(decay, 0.0);
        plant.set_bridges([command, BridgeCommand::Off]);
        plant.advance_to(60.0 * T, &mut |_| {}).unwrap();
        plant.currents()[0]
    };
    for (decay, mode) in [("slow", Decay::Slow), ("fast", Decay::Fast)] {
        // 0.3 + 1e-5 lies between two steps of 1/4200; the timer holds 0.3.
        let asked = 0.3 + 1e-5;
        let held_by_timer =
            input_duties(asked as f32, mode).map(|f| f32::from(compare(f, ARR)) / f32::from(ARR));
        let from_inputs = current(decay, BridgeCommand::Inputs(held_by_timer));
        let on_grid = current(decay, BridgeCommand::Duty(0.3));
        let off_grid = current(decay, BridgeCommand::Duty(asked));
        assert!(
            (from_inputs - on_grid).abs() < 1e-12,
            "{decay}: {from_inputs} vs {on_grid}"
        );
        assert!(
            (from_inputs - off_grid).abs() > 1e-6,
            "{decay}: {from_inputs} vs {off_grid}"
        );
    }
}
