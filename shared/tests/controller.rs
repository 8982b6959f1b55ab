//! The controller (`shared::controller`) closed around a rotor model written here,
//! independent of host-sim's plant: two brushed DC motors with eccentric rotors,
//!
//! ```text
//!   J w' = k i - b w - tau_c sign(w) - m g e cos(theta + theta0) - tau_d
//!   i    = clamp((d V - k w) / R, -I_max, I_max)      (driver enabled; 0 when not)
//! ```
//!
//! integrated in `f64` with 20 substeps a tick, sampled by an ideal x4 encoder with
//! an index pulse at every whole turn (`count = c0 + floor(theta N / 2 pi)`, the
//! counter starting near `2^32` so that it wraps during the runs).

// The two rotors are indexed in parallel arrays (plant, counters, flags).
#![allow(clippy::needless_range_loop)]

use shared::controller::angle::{wrap_deg, wrap_deg_signed};
use shared::controller::{
    may_write_table, Bridge, Command, Controller, Direction, Faults, Inputs, Outputs, Params,
    ResetCause, RowField, SpeedEstimator, State, TableError, TickTiming, TuningTable,
};

use std::f64::consts::TAU;

mod support;
use support::rig::{Rotor, DT, N, SUBSTEPS};

/// The controller in the loop with two rotors.
struct Rig {
    ctl: Controller,
    rotors: [Rotor; 2],
    /// Counter value at `theta = 0`, per rotor.
    count_zero: [u32; 2],
    /// Encoder counter stuck at this value (a dead encoder).
    frozen: [Option<u32>; 2],
    /// Index pulses suppressed.
    no_index: [bool; 2],
    /// Measured currents replaced by these.
    current_override: [Option<f32>; 2],
    supply: f32,
    estop: bool,
    /// The loop's timing as the firmware would measure it.
    timing: TickTiming,
    /// Send a heartbeat every 100 ticks when no command is queued.
    heartbeat: bool,
    /// Command for the next tick.
    queued: Option<Command>,
    /// Index latches for the next sample (pulses crossed during the last tick).
    pending_index: [Option<u32>; 2],
    /// Ticks stepped.
    ticks: u64,
    /// Ticks since the last command or heartbeat sent.
    since_command: u64,
    last: Option<Outputs>,
}

impl Rig {
    fn new(params: &Params, theta: [f64; 2]) -> Rig {
        Rig {
            ctl: Controller::new(params, ResetCause::PowerOn),
            rotors: [Rotor::new(theta[0]), Rotor::new(theta[1])],
            // Near the top of the counter: it wraps after 3000 counts backwards
            // or 2000 forwards.
            count_zero: [u32::MAX - 1999, u32::MAX - 123_456],
            frozen: [None; 2],
            no_index: [false; 2],
            current_override: [None; 2],
            supply: 12.0,
            estop: false,
            timing: TickTiming::default(),
            heartbeat: true,
            queued: None,
            pending_index: [None; 2],
            ticks: 0,
            since_command: 0,
            last: None,
        }
    }

    fn reference() -> Rig {
        Rig::new(&Params::reference(), [0.0, 1.0])
    }

    fn count(&self, k: usize) -> u32 {
        let c = (self.rotors[k].theta * N as f64 / TAU).floor() as i64;
        self.count_zero[k].wrapping_add(c as u32)
    }

    fn command(&mut self, c: Command) {
        self.queued = Some(c);
    }

    /// One tick: sample, control, then integrate the plant over the tick.
    fn step(&mut self) -> Outputs {
        let before = [self.rotors[0].theta, self.rotors[1].theta];
        // The plant moved during the previous tick; the index pulses it crossed.
        let mut command = self.queued.take();
        if command.is_none() && self.heartbeat && self.since_command >= 100 {
            command = Some(Command::Heartbeat);
        }
        if command.is_some() {
            self.since_command = 0;
        } else {
            self.since_command += 1;
        }
        let inputs = Inputs {
            encoder: [0, 1].map(|k| self.frozen[k].unwrap_or_else(|| self.count(k))),
            index: self.pending_index,
            current: [0, 1]
                .map(|k| self.current_override[k].unwrap_or(self.rotors[k].current as f32)),
            supply_voltage: self.supply,
            estop: self.estop,
            command,
            timing: self.timing,
        };
        let out = self.ctl.step(&inputs, DT);
        let h = DT as f64 / SUBSTEPS as f64;
        for _ in 0..SUBSTEPS {
            for k in 0..2 {
                self.rotors[k].advance(out.duties()[k] as f64, out.bridges[k].is_driven(), h);
            }
        }
        // Index pulses crossed during this tick, reported at the next sample.
        for k in 0..2 {
            let m0 = (before[k] / TAU).floor() as i64;
            let m1 = (self.rotors[k].theta / TAU).floor() as i64;
            self.pending_index[k] = if m0 != m1 && !self.no_index[k] && self.frozen[k].is_none() {
                let m = m0.max(m1);
                Some(self.count_zero[k].wrapping_add((m * N as i64) as u32))
            } else {
                None
            };
        }
        self.ticks += 1;
        self.last = Some(out);
        out
    }

    /// Step `n` ticks; returns the last outputs.
    fn run(&mut self, n: usize) -> Outputs {
        let mut out = self.step();
        for _ in 1..n {
            out = self.step();
        }
        out
    }

    /// Step until `pred` holds (at most `max` ticks); returns the ticks taken.
    fn until(&mut self, max: usize, mut pred: impl FnMut(&Outputs) -> bool) -> Option<usize> {
        (1..=max).find(|_| {
            let out = self.step();
            pred(&out)
        })
    }

    fn speed_rpm(&self, k: usize) -> f64 {
        self.rotors[k].omega * 60.0 / TAU
    }

    /// The true phase offset `theta_1 - theta_2`, degrees in [0, 360).
    fn true_offset(&self) -> f32 {
        wrap_deg(((self.rotors[0].theta - self.rotors[1].theta) * 360.0 / TAU) as f32)
    }
}

/// Run to `Running` at `speed` rpm with `command`; panics if it does not get there.
fn start(rig: &mut Rig, command: Command) -> usize {
    rig.command(command);
    rig.until(5000, |o| o.state == State::Running)
        .expect("reaches running")
}

/// The command to travel in `direction` at `speed_rpm`.
fn travel(direction: Direction, speed_rpm: f32) -> Command {
    Command::Travel {
        direction,
        speed_rpm,
    }
}

/// Outputs in the safe state.
fn safe(o: &Outputs) -> bool {
    o.bridges == [Bridge::Off; 2]
}

#[test]
fn tuning_table_interpolates_circularly_across_zero() {
    let t: TuningTable = TuningTable::from_rows(&[
        (1000.0, 350.0, 190.0),
        (2000.0, 10.0, 170.0),
        (3000.0, 90.0, 270.0),
    ])
    .unwrap();
    // 350 -> 10 through 0, not through 180.
    let mid = t.offset(Direction::Right, 1500.0);
    assert!(wrap_deg_signed(mid).abs() < 1e-3, "{mid}");
    assert!((t.offset(Direction::Right, 1250.0) - 355.0).abs() < 1e-3);
    assert!((t.offset(Direction::Right, 1750.0) - 5.0).abs() < 1e-3);
    // 190 -> 170 through 180.
    assert!((t.offset(Direction::Left, 1500.0) - 180.0).abs() < 1e-3);
    // 10 -> 90 and 170 -> 270 along the shorter arcs.
    assert!((t.offset(Direction::Right, 2500.0) - 50.0).abs() < 1e-3);
    assert!((t.offset(Direction::Left, 2500.0) - 220.0).abs() < 1e-3);
    // Clamped outside the speed range, first row for NaN.
    assert_eq!(t.offset(Direction::Right, 0.0), 350.0);
    assert_eq!(t.offset(Direction::Left, 9000.0), 270.0);
    assert_eq!(t.offset(Direction::Right, f32::NAN), 350.0);
    // The default: 90 right, 270 left at every speed.
    let d: TuningTable = TuningTable::default();
    assert_eq!(d.offset(Direction::Right, 3000.0), 90.0);
    assert_eq!(d.offset(Direction::Left, 123.0), 270.0);
    // Refusals, each naming the row and the value; the ends of the ranges among
    // them: a speed of 0 and an offset of 360 (which is 0: one turn, each offset
    // written once).
    type T = TuningTable<4>;
    type Rows = &'static [(f32, f32, f32)];
    let (right, left) = (RowField::RightOffset, RowField::LeftOffset);
    let cases: [(Rows, TableError); 8] = [
        (&[], TableError::Empty),
        (
            &[(1.0, 0.0, 0.0); 5],
            TableError::TooManyRows {
                rows: 5,
                capacity: 4,
            },
        ),
        (
            &[(1.0, 0.0, 0.0), (1.0, 0.0, 0.0)],
            TableError::SpeedsNotIncreasing { row: 1 },
        ),
        (
            &[(1.0, f32::NAN, 0.0)],
            TableError::NotFinite {
                row: 0,
                field: right,
            },
        ),
        (&[(-1.0, 0.0, 0.0)], TableError::SpeedNotPositive { row: 0 }),
        (
            &[(1.0, 0.0, 361.0)],
            TableError::OffsetOutOfRange {
                row: 0,
                field: left,
            },
        ),
        (
            &[(0.0, 90.0, 270.0)],
            TableError::SpeedNotPositive { row: 0 },
        ),
        (
            &[(1.0, 360.0, 0.0)],
            TableError::OffsetOutOfRange {
                row: 0,
                field: right,
            },
        ),
    ];
    for (rows, error) in cases {
        assert_eq!(T::from_rows(rows), Err(error), "{rows:?}");
    }
    // 0 degrees, the last f32 below 360 and the smallest positive speed pass.
    let below = f32::from_bits(360.0_f32.to_bits() - 1);
    let t = T::from_rows(&[(f32::MIN_POSITIVE, 0.0, below)]).unwrap();
    assert_eq!(t.rows()[0].left_offset_deg, below);
    // The default table passes the rule it defines.
    let d = d.rows()[0];
    assert!(T::from_rows(&[(d.speed_rpm, d.right_offset_deg, d.left_offset_deg)]).is_ok());
}

#[test]
fn speed_estimate_is_exact_at_constant_speed_and_across_the_wrap() {
    // 200 counts a tick at 1 kHz, 4096 counts a turn: 2929.6875 rpm exactly.
    let mut e = SpeedEstimator::new(N, 0.005);
    let mut count = u32::MAX - 10_000;
    let mut wrapped = false;
    for _ in 0..400 {
        e.update(count, DT);
        let next = count.wrapping_add(200);
        wrapped |= next < count;
        count = next;
    }
    assert!(wrapped);
    let expected = TAU as f32 * 200.0 / (N as f32 * DT);
    let got = e.speed_rad_s();
    assert!(
        ((got - expected) / expected).abs() < 1e-5,
        "{got} vs {expected}"
    );
    // Backwards too.
    let mut e = SpeedEstimator::new(N, 0.005);
    let mut count = 5000u32;
    for _ in 0..400 {
        e.update(count, DT);
        count = count.wrapping_sub(37);
    }
    let expected = -(TAU as f32) * 37.0 / (N as f32 * DT);
    assert!(((e.speed_rad_s() - expected) / expected).abs() < 1e-5);

    // Through the controller, idle, with index pulses: telemetry in rpm.
    let mut ctl = Controller::new(&Params::reference(), ResetCause::PowerOn);
    let mut count = [u32::MAX - 3000, 17u32];
    let mut out = None;
    for _ in 0..400 {
        let index = count.map(|c| {
            // Index where the count (offset so that 0 is an index) crosses a turn.
            let before = c.wrapping_sub(200);
            ((c / N) != (before / N)).then_some((c / N) * N)
        });
        let inputs = Inputs {
            encoder: count,
            index,
            supply_voltage: 12.0,
            ..Inputs::default()
        };
        out = Some(ctl.step(&inputs, DT));
        count = count.map(|c| c.wrapping_add(200));
    }
    let out = out.unwrap();
    for k in 0..2 {
        assert!((out.telemetry.speed_rpm[k] - 2929.6875).abs() < 0.01);
    }
    assert_eq!(out.state, State::Idle, "{:?}", out.faults);
}

#[test]
fn speed_loop_reaches_the_reference_without_overshoot_and_holds_it() {
    let mut rig = Rig::reference();
    rig.command(Command::HoldOffset {
        speed_rpm: 3000.0,
        offset_deg: 180.0,
    });
    // Soft start: the ramp crosses the resonance band (1500 to 2500 rpm) at
    // 19 100 rpm/s, about 52 ms, the rest at 3000 rpm/s.
    let p = Params::reference();
    let [lo, hi] = p.resonance_band_rpm;
    let mut in_band = 0;
    let ticks = rig
        .until(5000, |o| {
            let ramp = 0.5 * (o.telemetry.speed_ref_rpm[0] + o.telemetry.speed_ref_rpm[1]);
            in_band += (ramp > lo && ramp < hi) as usize;
            o.state == State::Running
        })
        .unwrap();
    let expected = (hi - lo) / p.resonance_ramp_rpm_s / DT;
    assert!(
        (in_band as f32 - expected).abs() <= 3.0,
        "{in_band} ticks in the band"
    );
    // Soft start: about 1 s at 3000 rpm/s, less through the band.
    assert!(ticks > 500 && ticks < 1500, "{ticks}");
    let mut peak = [0.0f64; 2];
    let mut sum = [0.0f64; 2];
    for i in 0..3000 {
        rig.step();
        for k in 0..2 {
            peak[k] = peak[k].max(rig.speed_rpm(k));
            if i >= 2000 {
                sum[k] += rig.speed_rpm(k);
            }
        }
    }
    for k in 0..2 {
        let mean = sum[k] / 1000.0;
        eprintln!(
            "rotor {k}: {in_band} ticks in the band, running after {ticks} ticks, peak {:.1} rpm, mean {mean:.2} rpm",
            peak[k]
        );
        assert!(peak[k] < 3000.0 * 1.02, "rotor {k} peak {}", peak[k]);
        assert!((mean - 3000.0).abs() < 3.0, "rotor {k} mean {mean}");
    }
    assert_eq!(rig.last.unwrap().state, State::Running);
}

#[test]
fn phase_loop_holds_the_offset_against_a_disturbance() {
    for target in [90.0f32, 180.0, 270.0, 30.0] {
        let mut rig = Rig::new(&Params::reference(), [0.3, 2.5]);
        rig.rotors[0].gravity_phase = 0.0;
        rig.rotors[1].gravity_phase = 1.0;
        // A constant drag on rotor 2: a quarter of the driver's torque.
        rig.rotors[1].disturbance = 0.01;
        start(
            &mut rig,
            Command::HoldOffset {
                speed_rpm: 3000.0,
                offset_deg: target,
            },
        );
        rig.run(2000);
        let mut worst = 0.0f32;
        for _ in 0..1000 {
            let out = rig.step();
            let err = wrap_deg_signed(rig.true_offset() - target).abs();
            worst = worst.max(err);
            let seen = wrap_deg_signed(out.telemetry.phase_offset_deg - rig.true_offset());
            assert!(seen.abs() < 0.2, "measured offset off by {seen}");
        }
        eprintln!("target {target}: worst phase error {worst:.3} deg");
        assert!(worst < 3.0, "target {target}: worst {worst}");
    }
}

#[test]
fn direction_change_ramps_the_offset_through_180_not_0() {
    let mut rig = Rig::reference();
    start(&mut rig, travel(Direction::Right, 3000.0));
    rig.run(1500);
    let out = rig.last.unwrap();
    assert_eq!(out.telemetry.commanded_offset_deg, 90.0);
    for (direction, from, to) in [
        (Direction::Left, 90.0f32, 270.0f32),
        (Direction::Right, 270.0, 90.0),
    ] {
        rig.command(travel(direction, 3000.0));
        let mut prev = from;
        let mut near180 = f32::MAX;
        let mut near0 = f32::MAX;
        let mut worst_error = 0.0f32;
        for _ in 0..2000 {
            let out = rig.step();
            let o = out.telemetry.commanded_offset_deg;
            // Bounded rate: 180 degrees/s, 0.18 a tick.
            assert!(
                wrap_deg_signed(o - prev).abs() <= 0.18 + 1e-3,
                "{prev} -> {o}"
            );
            prev = o;
            near180 = near180.min((o - 180.0).abs());
            near0 = near0.min(o.min(360.0 - o));
            worst_error = worst_error.max(wrap_deg_signed(o - rig.true_offset()).abs());
            assert_eq!(out.state, State::Running);
        }
        eprintln!("{from} -> {to}: nearest 180 {near180}, nearest 0 {near0}, worst tracking {worst_error:.3}");
        assert_eq!(prev, to);
        assert!(near180 < 0.2, "passes 180: {near180}");
        assert!(near0 >= 89.9, "never near 0: {near0}");
        // The rotors follow the ramp closely.
        assert!(worst_error < 3.0, "{worst_error}");
    }
}

#[test]
fn travel_follows_the_tuning_table_with_the_speed() {
    let mut p = Params::reference();
    p.tuning = TuningTable::from_rows(&[(1000.0, 60.0, 300.0), (3000.0, 120.0, 240.0)]).unwrap();
    let mut rig = Rig::new(&p, [0.0, 0.5]);
    start(&mut rig, travel(Direction::Right, 3000.0));
    rig.run(1000);
    let out = rig.last.unwrap();
    assert_eq!(out.telemetry.target_offset_deg, 120.0);
    assert_eq!(out.telemetry.commanded_offset_deg, 120.0);
    assert!(wrap_deg_signed(rig.true_offset() - 120.0).abs() < 2.0);
    // Slower: the offset moves with the speed along the table.
    rig.command(travel(Direction::Right, 2000.0));
    let out = rig.run(2000);
    assert!((out.telemetry.commanded_offset_deg - 90.0).abs() < 1e-3);
    assert!(wrap_deg_signed(rig.true_offset() - 90.0).abs() < 2.0);
}

#[test]
fn a_reset_in_the_tick_of_a_new_fault_leaves_it_reported() {
    let mut rig = running();
    rig.current_override[0] = Some(f32::NAN);
    rig.run(1);
    // The second tick of the over-current detects it; a reset arrives with it.
    rig.current_override[0] = Some(3.0);
    rig.command(Command::ResetFaults);
    let out = rig.step();
    assert!(out.faults.contains(Faults::OVER_CURRENT));
    assert!(safe(&out));
    assert_eq!(format!("{}", out.faults), "over_current");
}

#[test]
fn stop_ramps_down_then_idles() {
    let mut rig = Rig::reference();
    start(&mut rig, travel(Direction::Left, 3000.0));
    rig.command(Command::Stop);
    let out = rig.step();
    assert_eq!(out.state, State::Stopping);
    assert!(out.drives());
    let ticks = rig.until(5000, |o| o.state == State::Idle).unwrap();
    eprintln!(
        "stop: idle after {ticks} ticks at {:.1} / {:.1} rpm",
        rig.speed_rpm(0),
        rig.speed_rpm(1)
    );
    // 3000 rpm at 3000 rpm/s, faster through the band: under a second.
    assert!(ticks < 1000, "{ticks}");
    assert!(rig.speed_rpm(0).abs() < 150.0 && rig.speed_rpm(1).abs() < 150.0);
    let out = rig.run(10);
    assert!(safe(&out));
}

/// Outputs are safe and the flag set in the tick of detection; returns the ticks
/// from the change to detection.
fn detect(rig: &mut Rig, flag: Faults, max: usize) -> usize {
    let mut n = 0;
    loop {
        n += 1;
        let out = rig.step();
        if !out.faults.is_empty() {
            assert!(
                out.faults.contains(flag),
                "expected {flag:?}, got {:?}",
                out.faults
            );
            assert!(safe(&out), "safe in the same tick");
            assert_eq!(out.state, State::Fault);
            return n;
        }
        assert!(n < max, "{flag:?} not detected in {max} ticks");
    }
}

/// Latched: still set after `ticks` more with the cause removed, motors off.
fn latched(rig: &mut Rig, flag: Faults) {
    for _ in 0..200 {
        let out = rig.step();
        assert!(out.faults.contains(flag));
        assert!(safe(&out));
    }
    // A run command is refused while latched.
    rig.command(travel(Direction::Right, 3000.0));
    let out = rig.step();
    assert!(out.telemetry.command_rejected);
    assert!(safe(&out));
    // Reset: idle, motors still off.
    rig.command(Command::ResetFaults);
    let out = rig.step();
    assert_eq!(out.state, State::Idle, "{:?}", out.faults);
    assert!(out.faults.is_empty());
    assert!(safe(&rig.run(100)));
}

fn running() -> Rig {
    let mut rig = Rig::reference();
    start(&mut rig, travel(Direction::Right, 3000.0));
    rig.run(500);
    rig
}

/// Ticks a timed check needs: `ceil(T / dt)`.
fn ticks(t: f32) -> usize {
    (t / DT - 1.0e-3).ceil() as usize
}

/// Ticks for the filtered speed to fall from `from` to `to` rpm once the counts
/// stop: `ceil(ln(from/to) / ln(1 + dt/tau))`.
fn fall_ticks(p: &Params, from: f32, to: f32) -> usize {
    ((from / to).ln() / (1.0 + DT / p.speed_filter_tau_s).ln()).ceil() as usize
}

#[test]
fn estop_cuts_at_once_and_needs_release() {
    let mut rig = running();
    rig.estop = true;
    assert_eq!(detect(&mut rig, Faults::ESTOP, 10), 1);
    // Reset refused while pressed.
    rig.command(Command::ResetFaults);
    let out = rig.step();
    assert!(out.faults.contains(Faults::ESTOP));
    assert!(safe(&out));
    rig.estop = false;
    latched(&mut rig, Faults::ESTOP);
}

/// A starved loop: a tick that starts a quarter of a tick late, or a previous tick
/// that worked half a tick, is a deadline fault at once while the motors are
/// driven (latched, motors off in that tick); in any state it is counted and
/// reported, the timing with it.
#[test]
fn a_missed_deadline_while_driving_is_a_fault_at_once() {
    let p = Params::reference();
    let (late, busy) = (p.limits.tick_late_max_s, p.limits.tick_busy_max_s);
    // The reference budget: a quarter and a half of the tick.
    assert!(late == 0.25e-3 && busy == 0.5e-3);
    // Within the budget, 4 % under either limit.
    let within = TickTiming {
        late_s: 0.96 * late,
        busy_s: 0.96 * busy,
    };
    for timing in [
        TickTiming {
            late_s: 1.04 * late,
            busy_s: 0.0,
        },
        TickTiming {
            late_s: 0.0,
            busy_s: 1.04 * busy,
        },
        TickTiming {
            late_s: f32::NAN,
            busy_s: 0.0,
        },
    ] {
        let mut rig = running();
        rig.timing = within;
        let out = rig.step();
        assert!(out.faults.is_empty(), "{timing:?}: {:?}", out.faults);
        assert_eq!(out.telemetry.overruns, 0);
        assert_eq!(
            (out.telemetry.tick_late_us, out.telemetry.tick_busy_us),
            (240, 480)
        );
        // Over it: the fault in that tick.
        rig.timing = timing;
        assert_eq!(detect(&mut rig, Faults::DEADLINE, 2), 1, "{timing:?}");
        assert_eq!(rig.last.unwrap().telemetry.overruns, 1);
        rig.timing = TickTiming::default();
        latched(&mut rig, Faults::DEADLINE);
    }
    // Idle: counted, not a fault (nothing to cut; a flash store stalls the loop
    // for seconds with the motors stopped).
    let mut rig = Rig::reference();
    rig.timing = TickTiming {
        late_s: 2.0,
        busy_s: 0.0,
    };
    let out = rig.run(3);
    assert!(out.faults.is_empty() && out.state == State::Idle);
    assert_eq!(out.telemetry.overruns, 3);
    assert_eq!(out.telemetry.tick_late_us, u16::MAX);
}

#[test]
fn over_current_within_its_time() {
    let mut rig = running();
    let p = Params::reference();
    rig.current_override[0] = Some(3.0);
    let n = detect(&mut rig, Faults::OVER_CURRENT, 100);
    assert!(n <= ticks(p.limits.over_current_time_s), "{n}");
    // Reset refused while the current is high.
    rig.command(Command::ResetFaults);
    assert!(rig.step().faults.contains(Faults::OVER_CURRENT));
    rig.current_override[0] = None;
    latched(&mut rig, Faults::OVER_CURRENT);
    // A NaN reading is an over-current too.
    let mut rig = running();
    rig.current_override[1] = Some(f32::NAN);
    assert!(detect(&mut rig, Faults::OVER_CURRENT, 100) <= 2);
}

#[test]
fn supply_out_of_range_within_its_time() {
    let p = Params::reference();
    for v in [20.0, 5.0, f32::NAN] {
        let mut rig = running();
        rig.supply = v;
        let n = detect(&mut rig, Faults::SUPPLY, 100);
        assert!(n <= ticks(p.limits.supply_time_s), "{v}: {n}");
        rig.supply = 12.0;
        latched(&mut rig, Faults::SUPPLY);
    }
}

#[test]
fn stall_within_its_bound_and_named_stall() {
    let p = Params::reference();
    let mut rig = running();
    rig.rotors[0].blocked = true;
    let n = detect(&mut rig, Faults::STALL, 2000);
    let bound = fall_ticks(&p, 3000.0, p.limits.stall_speed_rpm) + ticks(p.limits.stall_time_s) + 2;
    eprintln!("stall: {n} ticks (bound {bound})");
    assert!(n <= bound, "{n} > {bound}");
    assert!(!rig.last.unwrap().faults.contains(Faults::ENCODER));
    rig.rotors[0].blocked = false;
    latched(&mut rig, Faults::STALL);

    // A rotor jammed from the start.
    let mut rig = Rig::reference();
    rig.rotors[1].blocked = true;
    rig.command(travel(Direction::Right, 3000.0));
    detect(&mut rig, Faults::STALL, 2000);
}

#[test]
fn dead_encoder_is_an_encoder_fault_within_its_bound() {
    let p = Params::reference();
    let mut rig = running();
    rig.frozen[0] = Some(rig.count(0));
    let n = detect(&mut rig, Faults::ENCODER, 2000);
    let bound = fall_ticks(&p, 3000.0, p.limits.stall_speed_rpm)
        + ticks(p.limits.stall_time_s + p.limits.encoder_time_s)
        + 2;
    eprintln!("dead encoder: {n} ticks (bound {bound})");
    assert!(n <= bound, "{n} > {bound}");
    assert!(!rig.last.unwrap().faults.contains(Faults::STALL));
    rig.frozen[0] = None;
    latched(&mut rig, Faults::ENCODER);
}

#[test]
fn misplaced_index_and_count_jumps_are_encoder_faults_at_once() {
    // An index half a turn from where it belongs.
    let mut rig = running();
    let c = rig.count(1);
    rig.pending_index[1] = Some(c.wrapping_add(N / 2));
    assert_eq!(detect(&mut rig, Faults::ENCODER, 10), 1);

    // A jump of 3000 counts in a tick (44 000 rpm).
    let mut rig = running();
    rig.count_zero[0] = rig.count_zero[0].wrapping_add(3000);
    assert_eq!(detect(&mut rig, Faults::ENCODER, 10), 1);

    // No index at all: detected within a turn and the tolerance.
    let mut rig = Rig::reference();
    rig.no_index[0] = true;
    rig.command(travel(Direction::Right, 3000.0));
    detect(&mut rig, Faults::ENCODER, 3000);
    let turns = rig.rotors[0].theta / TAU;
    eprintln!("missing index: detected after {turns:.4} turns");
    assert!(turns < 1.0 + 1.0 / 4096.0 * 5.0 + 0.1, "{turns}");
}

#[test]
fn phase_lock_lost_within_its_time() {
    let p = Params::reference();
    let mut rig = running();
    // A drag beyond the driver's torque on rotor 2: it cannot keep up.
    rig.rotors[1].disturbance = 0.045;
    let mut first = None;
    let mut n = 0;
    loop {
        n += 1;
        let out = rig.step();
        if first.is_none() && out.telemetry.phase_error_deg.abs() > p.limits.phase_error_max_deg {
            first = Some(n);
        }
        if !out.faults.is_empty() {
            assert!(
                out.faults.contains(Faults::PHASE_LOCK_LOST),
                "{:?}",
                out.faults
            );
            assert!(safe(&out));
            break;
        }
        assert!(n < 5000);
    }
    let first = first.expect("error exceeded");
    eprintln!("phase lock lost: error above the limit at tick {first}, fault at {n}");
    // The monitor sees the error one tick later than the telemetry of the tick.
    assert!(
        n - first <= ticks(p.limits.phase_lost_time_s) + 1,
        "{first} {n}"
    );
    rig.rotors[1].disturbance = 0.0;
    latched(&mut rig, Faults::PHASE_LOCK_LOST);
}

#[test]
fn silent_link_within_its_timeout() {
    let p = Params::reference();
    let mut rig = running();
    rig.heartbeat = false;
    // The last command or heartbeat was `since_command` ticks ago.
    let already = rig.since_command as usize;
    let n = detect(&mut rig, Faults::LINK_LOST, 2000);
    assert_eq!(n + already, ticks(p.limits.link_timeout_s));
    rig.heartbeat = true;
    latched(&mut rig, Faults::LINK_LOST);

    // Heartbeats keep it alive; idle needs none.
    let mut rig = Rig::reference();
    rig.heartbeat = false;
    assert_eq!(rig.run(3000).state, State::Idle);
}

#[test]
fn watchdog_restart_is_a_fault_and_never_starts_the_motors() {
    let mut rig = Rig::reference();
    rig.ctl = Controller::new(&Params::reference(), ResetCause::Watchdog);
    assert_eq!(rig.ctl.state(), State::Fault);
    assert!(rig.ctl.faults().contains(Faults::WATCHDOG_RESET));
    let out = rig.run(1000);
    assert!(safe(&out));
    assert_eq!(out.faults.names().collect::<Vec<_>>(), ["watchdog_reset"]);
    latched(&mut rig, Faults::WATCHDOG_RESET);
    // Only a new run command starts them.
    rig.command(travel(Direction::Left, 2000.0));
    assert_eq!(rig.step().state, State::Starting);
}

#[test]
fn invalid_params_latch_a_fault_that_never_clears() {
    let mut p = Params::reference();
    p.encoder_counts = 0;
    let mut rig = Rig::new(&p, [0.0, 0.0]);
    assert_eq!(rig.ctl.params_error().unwrap().field, "encoder_counts");
    rig.command(Command::ResetFaults);
    let out = rig.run(10);
    assert!(out.faults.contains(Faults::PARAMS));
    assert!(safe(&out));
}

#[test]
fn out_of_range_commands_are_refused() {
    let mut rig = Rig::reference();
    for c in [
        Command::Travel {
            direction: Direction::Right,
            speed_rpm: f32::NAN,
        },
        travel(Direction::Right, 1.0e6),
        Command::HoldOffset {
            speed_rpm: 3000.0,
            offset_deg: f32::INFINITY,
        },
        Command::HoldOffset {
            speed_rpm: -3000.0,
            offset_deg: 90.0,
        },
    ] {
        rig.command(c);
        let out = rig.step();
        assert!(out.telemetry.command_rejected, "{c:?}");
        assert_eq!(out.state, State::Idle);
        assert!(safe(&out));
    }
}

#[test]
fn writes_only_with_the_driver_off_and_the_rotors_at_rest() {
    assert!(may_write_table(State::Idle, [0.0, 0.0]));
    assert!(may_write_table(State::Fault, [-10.0, 10.0]));
    assert!(!may_write_table(State::Idle, [10.5, 0.0]));
    assert!(!may_write_table(State::Idle, [0.0, f32::NAN]));
    for state in [State::Starting, State::Running, State::Stopping] {
        assert!(!may_write_table(state, [0.0, 0.0]));
    }
}
