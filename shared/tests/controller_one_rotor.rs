//! The controller on a machine with one rotor (`RotorCount::One`): it holds rotor
//! 1's speed with the ramp and the speed loop, has no phase loop, never drives
//! rotor 2 and does not read rotor 2's sensors.
//!
//! Rotor 1 is a brushed DC motor with an eccentric written here (the equations of
//! `controller.rs`, independent of host-sim's plant),
//!
//! ```text
//!   J w' = k i - b w - tau_c sign(w) - m g e cos(theta) - tau_d
//!   i    = clamp((d V - k w) / R, -I_max, I_max)      (driver enabled; 0 when not)
//! ```
//!
//! sampled by an ideal x4 encoder with an index pulse at every whole turn. Rotor 2's
//! inputs are what a board without a second rotor could read: a floating counter
//! that jumps, index pulses at random, a current input at full scale or NaN. Each
//! check is made against the same inputs on a two-rotor machine, where they do
//! raise faults or move the speed references, so that the checks see the
//! mechanism and not a quiet input.

use shared::controller::{
    Bridge, Command, Controller, Direction, Faults, Inputs, MachineConstants, Outputs, Params,
    ResetCause, RotorCount, State,
};

use shared::controller::self_test::SelfTestStatus;

use std::f64::consts::TAU;

mod support;
use support::fuzz::Rng;
use support::rig::{Rotor, DT, N, SUBSTEPS, V};

/// The reference machine's parameters with `rotors` rotors.
fn params(rotors: RotorCount) -> Params {
    Params::from_machine(&MachineConstants {
        rotor_count: rotors,
        ..MachineConstants::REFERENCE
    })
}

/// What rotor 2's inputs read.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Rotor2 {
    /// A floating counter: a jump of 3000 counts a tick (about 44 000 rpm, far
    /// above the encoder's jump limit), an index pulse every 7th tick at a random
    /// count, and the current input at 50 A.
    Garbage,
    /// The current input reads NaN (a dead channel); the counter stands still.
    NanCurrent,
}

/// Rotor 1 in the loop, rotor 2's inputs as `rotor2`.
struct Rig {
    ctl: Controller,
    /// Rotor 1 (load torque: its `disturbance`).
    rotor: Rotor,
    rotor2: Rotor2,
    /// The generator of rotor 2's garbage.
    noise: Rng,
    counter2: u32,
    pending_index: Option<u32>,
    queued: Option<Command>,
    ticks: u64,
}

impl Rig {
    fn new(rotors: RotorCount, rotor2: Rotor2) -> Rig {
        Rig {
            ctl: Controller::new(&params(rotors), ResetCause::PowerOn),
            rotor: Rotor::new(0.3),
            rotor2,
            noise: Rng::new(0x1234_5678),
            counter2: 0,
            pending_index: None,
            queued: None,
            ticks: 0,
        }
    }

    fn random(&mut self) -> u32 {
        (self.noise.next_u64() >> 32) as u32
    }

    fn count(&self) -> u32 {
        ((self.rotor.theta * f64::from(N) / TAU).floor() as i64) as u32
    }

    /// One tick: sample, control, then integrate rotor 1 over the tick (rotor 2's
    /// duty is asserted 0 in every tick).
    fn step(&mut self) -> Outputs {
        let (index2, current2) = match self.rotor2 {
            Rotor2::Garbage => {
                self.counter2 = self.counter2.wrapping_add(3000);
                let index = self.ticks.is_multiple_of(7).then(|| self.random());
                (index, 50.0)
            }
            Rotor2::NanCurrent => (None, f32::NAN),
        };
        let command = self.queued.take().or(Some(Command::Heartbeat));
        let inputs = Inputs {
            encoder: [self.count(), self.counter2],
            index: [self.pending_index, index2],
            current: [self.rotor.current as f32, current2],
            supply_voltage: V as f32,
            command,
            ..Inputs::default()
        };
        let out = self.ctl.step(&inputs, DT);
        if self.ctl.params().rotor_count == RotorCount::One {
            assert_eq!(
                out.duties()[1].to_bits(),
                0.0f32.to_bits(),
                "rotor 2 driven"
            );
        }
        let before = self.rotor.theta;
        let h = f64::from(DT) / SUBSTEPS as f64;
        for _ in 0..SUBSTEPS {
            self.rotor
                .advance(f64::from(out.duties()[0]), out.drives(), h);
        }
        let (m0, m1) = ((before / TAU).floor(), (self.rotor.theta / TAU).floor());
        self.pending_index = (m0 != m1).then(|| ((m0.max(m1) as i64) * i64::from(N)) as u32);
        self.ticks += 1;
        out
    }

    fn run(&mut self, n: usize) -> Vec<Outputs> {
        (0..n).map(|_| self.step()).collect()
    }

    fn speed_rpm(&self) -> f64 {
        self.rotor.omega * 60.0 / TAU
    }
}

#[test]
fn one_rotor_holds_the_speed_of_rotor_1_against_a_load() {
    let mut rig = Rig::new(RotorCount::One, Rotor2::Garbage);
    rig.queued = Some(Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    });
    // The ramp from rest: 0 to 1500 rpm at 3000 rpm/s (0.5 s), the resonance band
    // to 2500 at 19 100 rpm/s (0.05 s), on to 3000 at 3000 rpm/s (0.17 s): running
    // once it is there, 0.72 s, with no phase loop to wait for.
    let start = rig.run(2000);
    let running = start
        .iter()
        .position(|o| o.state == State::Running)
        .expect("running without a phase loop");
    assert!(
        (700..740).contains(&running),
        "running after {running} ticks"
    );
    for o in &start {
        assert!(o.faults.is_empty(), "{:?}", o.faults);
        assert!(!o.telemetry.phase_valid && !o.telemetry.phase_loop_closed);
    }
    // Held: the true speed within 0.5 % over a second.
    for _ in 0..1000 {
        rig.step();
        assert!(
            (rig.speed_rpm() - 3000.0).abs() < 15.0,
            "{}",
            rig.speed_rpm()
        );
    }
    // A load of 5e-3 N m (1.7 times the eccentric's weight torque) comes on: the
    // speed dips, and the integral brings it back within 0.5 % in 0.3 s.
    rig.rotor.disturbance = 5.0e-3;
    let dip = rig
        .run(300)
        .iter()
        .map(|o| f64::from(o.telemetry.speed_rpm[0]))
        .fold(f64::INFINITY, f64::min);
    assert!(dip < 2990.0, "the load shows: {dip}");
    for _ in 0..500 {
        let o = rig.step();
        assert_eq!(o.state, State::Running);
        assert!(
            (rig.speed_rpm() - 3000.0).abs() < 15.0,
            "{}",
            rig.speed_rpm()
        );
    }
    // Rotor 2: no speed, reference, current or duty; its bridge off.
    let o = rig.step();
    assert_eq!(o.telemetry.speed_rpm[1], 0.0);
    assert_eq!(o.telemetry.speed_ref_rpm, [3000.0, 0.0]);
    assert_eq!(o.telemetry.current[1], 0.0);
    assert!(o.drives());
    assert_eq!(RotorCount::One.bridges_on(true), [true, false]);
    assert_eq!(RotorCount::Two.bridges_on(true), [true, true]);
    assert_eq!(RotorCount::One.bridges_on(false), [false, false]);
    // What the firmware and the simulation put on the bridges: the controller's
    // own word, rotor 2's bridge never driven.
    assert!(o.bridges[0].is_driven());
    assert_eq!(o.bridges[1], Bridge::Off);
    for o in rig.run(200) {
        assert_eq!(
            o.bridges[1],
            Bridge::Off,
            "rotor 2's bridge driven in {:?}",
            o.state
        );
    }
}

#[test]
fn no_phase_correction_on_one_rotor() {
    // Both encoders turn at 3000 rpm (204.8 counts a tick) with their index pulses
    // 1000 counts apart (an offset of 88 degrees), and the controller is asked to
    // hold 180 degrees. On two rotors the phase loop trims the references apart;
    // on one the reference of rotor 1 is the commanded speed, untrimmed.
    let trim = |rotors: RotorCount| -> (f32, bool, State) {
        let mut ctl = Controller::new(&params(rotors), ResetCause::PowerOn);
        let (mut c1, mut c2) = (0.0f64, 1000.0f64);
        let mut widest = 0.0f32;
        let mut closed = false;
        let mut state = State::Idle;
        for tick in 0..3000 {
            let (b1, b2) = (c1, c2);
            c1 += 204.8;
            c2 += 204.8;
            // Index at every whole turn of each counter (rotor 2's 1000 behind).
            let index = |before: f64, now: f64| {
                let turn = (now / f64::from(N)).floor();
                ((before / f64::from(N)).floor() != turn).then(|| (turn * f64::from(N)) as u32)
            };
            let command = match tick {
                // Idle ticks first, so that the filtered speeds are at 3000 rpm.
                200 => Command::HoldOffset {
                    speed_rpm: 3000.0,
                    offset_deg: 180.0,
                },
                _ => Command::Heartbeat,
            };
            let out = ctl.step(
                &Inputs {
                    encoder: [c1 as u32, c2 as u32],
                    index: [index(b1, c1), index(b2, c2)],
                    supply_voltage: 12.0,
                    current: [0.5, 0.5],
                    command: Some(command),
                    ..Inputs::default()
                },
                DT,
            );
            // Two rotors: these encoders do not answer the trim, so the lock is
            // lost after 0.5 s; the trim before that is what counts here.
            if rotors == RotorCount::One {
                assert!(out.faults.is_empty(), "{:?}", out.faults);
            } else if !out.faults.is_empty() {
                break;
            }
            if out.state.drives() {
                let [r1, r2] = out.telemetry.speed_ref_rpm;
                let d = if rotors == RotorCount::One {
                    // The ramp itself, no half-trim either way.
                    assert_eq!(r2, 0.0);
                    assert_eq!(out.duties()[1].to_bits(), 0.0f32.to_bits());
                    r1 - 3000.0
                } else {
                    r1 - r2
                };
                widest = widest.max(d.abs());
            }
            closed |= out.telemetry.phase_loop_closed;
            state = out.state;
        }
        (widest, closed, state)
    };
    let (two, two_closed, _) = trim(RotorCount::Two);
    assert!(two_closed && two > 100.0, "two rotors: trim {two} rpm");
    let (one, one_closed, one_state) = trim(RotorCount::One);
    assert!(!one_closed, "one rotor: the phase loop closed");
    // Started from the measured 3000 rpm, the ramp is at the target from the
    // first tick: exactly the commanded speed.
    assert_eq!(one, 0.0, "one rotor: reference off the commanded speed");
    assert_eq!(one_state, State::Running);
}

#[test]
fn rotor_2_sensors_raise_no_fault_on_one_rotor() {
    for rotor2 in [Rotor2::Garbage, Rotor2::NanCurrent] {
        // Idle, then a run and a stop: nothing latched on one rotor...
        let mut one = Rig::new(RotorCount::One, rotor2);
        one.run(100);
        one.queued = Some(Command::Travel {
            direction: Direction::Left,
            speed_rpm: 2000.0,
        });
        one.run(1500);
        one.queued = Some(Command::Stop);
        let stop = one.run(3000);
        assert!(
            stop.iter().all(|o| o.faults.is_empty()),
            "{rotor2:?}: {:?}",
            stop.iter().find(|o| !o.faults.is_empty())
        );
        assert_eq!(stop.last().map(|o| o.state), Some(State::Idle));

        // ...while the same inputs fault a two-rotor machine at once, idle.
        let mut two = Rig::new(RotorCount::Two, rotor2);
        let faults = two
            .run(20)
            .iter()
            .fold(Faults::NONE, |all, o| all | o.faults);
        let want = match rotor2 {
            Rotor2::Garbage => Faults::ENCODER | Faults::OVER_CURRENT,
            Rotor2::NanCurrent => Faults::OVER_CURRENT,
        };
        assert!(
            faults.contains(want),
            "{rotor2:?}: two rotors gave {faults}"
        );
    }
}

#[test]
fn one_rotor_self_test_tests_rotor_1_only() {
    // Rotor 2's current reads NaN: on two rotors that is an over-current at once
    // (rotor_2_sensors_raise_no_fault_on_one_rotor); here it is not read.
    let mut rig = Rig::new(RotorCount::One, Rotor2::NanCurrent);
    rig.step();
    assert!(rig.ctl.start_self_test());
    let mut ticks = 0;
    // Runs of ticks with rotor 1 driven.
    let mut drives = 0;
    let mut driven = false;
    while rig.ctl.state() == State::SelfTest && ticks < 20_000 {
        let o = rig.step();
        if o.duties()[0] > 0.0 && !driven {
            drives += 1;
        }
        driven = o.duties()[0] > 0.0;
        ticks += 1;
    }
    let report = rig.ctl.self_test_report();
    assert_eq!(report.status, SelfTestStatus::Done, "{report:?}");
    assert_eq!(rig.ctl.state(), State::Idle);
    let r = report.result;
    assert!(r.rotors[0].passed(), "{r:?}");
    assert_eq!(r.rotors[0].counts_per_rev, N);
    // Rotor 2: not run, all zero; the test passes for a one-rotor machine.
    assert_eq!(r.rotors[1], Default::default());
    assert!(r.passed_with(RotorCount::One));
    assert!(!r.passed_with(RotorCount::Two) && !r.passed());
    // Settle 0.2 s, one drive of rotor 1 (about half a second), its coast to rest
    // (about 0.7 s) and a settle of 0.2 s, and done: no second drive, and short
    // of the two-rotor test's 2.2 s.
    assert_eq!(drives, 1);
    assert!((1200..2000).contains(&ticks), "{ticks} ticks");
}
