//! The motor identification ([`shared::controller::identify`]) against motors whose
//! constants are known: a DC motor with inductance, Coulomb friction that sticks
//! at rest (Karnopp's model), viscous friction, an eccentric under gravity or
//! none, an encoder of 4096 counts and the tick's mean current, stepped at 1 kHz
//! with 50 substeps. The identification is given the machine file's constants
//! (its settings derive from them) and must find the motor's own.

use shared::controller::identify::{
    IdentifyConfig, IdentifyRun, IdentifySample, IdentifyStatus, Identity, RotorIdentity, Shortfall,
};
use shared::controller::{
    Bridge, Command, Controller, Direction, Inputs, MachineConstants, Params, ResetCause,
    RotorCount, RotorModel, State,
};
use std::f64::consts::TAU;

/// Control tick, s.
const DT: f64 = 1e-3;
/// Substeps per tick.
const SUBSTEPS: usize = 50;
/// Encoder counts per turn.
const N: u32 = 4096;
/// Supply, V.
const SUPPLY: f64 = 12.0;
/// Gravity, m/s^2.
const G: f64 = 9.81;

/// A motor and its rotor, as they really are.
#[derive(Clone, Copy, Debug)]
struct Truth {
    resistance: f64,
    inductance: f64,
    torque_constant: f64,
    /// Inertia with the eccentric's `m e^2`, kg m^2.
    inertia: f64,
    coulomb: f64,
    viscous: f64,
    /// `m e`, kg m (0: no eccentric).
    unbalance: f64,
}

impl Truth {
    /// The reference machine's motor (examples/vibro-driver.toml).
    const REFERENCE: Truth = Truth {
        resistance: 2.0,
        inductance: 0.5e-3,
        torque_constant: 0.02,
        inertia: 6.0e-6 + 0.01 * 0.02 * 0.02,
        coulomb: 1.0e-3,
        viscous: 1.0e-6,
        unbalance: 0.01 * 0.02,
    };

    /// The controller's model of it: what a machine file with these values gives.
    fn model(&self) -> RotorModel {
        RotorModel {
            resistance_ohm: self.resistance as f32,
            torque_constant: self.torque_constant as f32,
            inertia_kg_m2: self.inertia as f32,
            load_torque_nm: (self.unbalance * G + self.coulomb) as f32,
        }
    }
}

/// One rotor in motion.
#[derive(Clone, Copy, Debug)]
struct Rotor {
    truth: Truth,
    /// Angle from the eccentric hanging down, rad, not wrapped.
    theta: f64,
    omega: f64,
    current: f64,
    /// The encoder's count at `theta = 0`.
    count0: u32,
    /// The controller's filtered speed, rpm.
    speed_rpm: f64,
    last_count: u32,
    /// The count latched at the last index pulse of the tick (the index at
    /// `theta = 0` modulo a turn), taken by [`Rotor::index`].
    index: Option<u32>,
}

impl Rotor {
    fn new(truth: Truth, theta: f64) -> Self {
        let mut r = Rotor {
            truth,
            theta,
            omega: 0.0,
            current: 0.0,
            count0: 1_000_000,
            speed_rpm: 0.0,
            last_count: 0,
            index: None,
        };
        r.last_count = r.count();
        r
    }

    fn count(&self) -> u32 {
        let counts = (self.theta * f64::from(N) / TAU).floor() as i64;
        self.count0.wrapping_add(counts as u32)
    }

    /// One tick under `bridge`: returns the tick's mean current.
    fn tick(&mut self, bridge: Bridge) -> f64 {
        let t = self.truth;
        let h = DT / SUBSTEPS as f64;
        let mut amps = 0.0;
        for _ in 0..SUBSTEPS {
            // The winding: driven at the mean voltage, or open (coasting, its
            // current dying through the diodes against the supply).
            let di = match bridge {
                Bridge::Driven(d) => {
                    (f64::from(d) * SUPPLY
                        - t.resistance * self.current
                        - t.torque_constant * self.omega)
                        / t.inductance
                }
                Bridge::Off => {
                    if self.current == 0.0 {
                        0.0
                    } else {
                        (-SUPPLY * self.current.signum() - t.resistance * self.current)
                            / t.inductance
                    }
                }
            };
            let next = self.current + di * h;
            self.current = if matches!(bridge, Bridge::Off) && next * self.current <= 0.0 {
                0.0
            } else {
                next
            };
            // The rotor: the eccentric's weight torque `-m e g sin(theta)` (theta
            // from hanging down), Karnopp's friction.
            let drive = t.torque_constant * self.current
                - t.unbalance * G * self.theta.sin()
                - t.viscous * self.omega;
            if self.omega.abs() < 1e-6 && drive.abs() <= t.coulomb {
                self.omega = 0.0;
            } else {
                let direction = if self.omega.abs() >= 1e-6 {
                    self.omega.signum()
                } else {
                    drive.signum()
                };
                let next = self.omega + (drive - t.coulomb * direction) / t.inertia * h;
                // Friction stops the rotor; it does not reverse it.
                self.omega = if next * direction < 0.0 { 0.0 } else { next };
            }
            let turns_before = (self.theta / TAU).floor();
            self.theta += self.omega * h;
            let turns_after = (self.theta / TAU).floor();
            if turns_after != turns_before {
                // Crossed theta = 2 pi k: the encoder's count there.
                let k = turns_after.max(turns_before) as i64;
                self.index = Some(self.count0.wrapping_add((k * i64::from(N)) as u32));
            }
            amps += self.current;
        }
        // The controller's speed: counts over the tick, filtered (5 ms).
        let count = self.count();
        let raw = f64::from(count.wrapping_sub(self.last_count) as i32) / f64::from(N) * 60.0 / DT;
        self.last_count = count;
        self.speed_rpm += (raw - self.speed_rpm) * (DT / (5e-3 + DT));
        amps / SUBSTEPS as f64
    }
}

/// A small deterministic noise source (SplitMix64), for the current sense.
struct Noise(u64);

impl Noise {
    /// Normal with standard deviation `sigma` (Box-Muller).
    fn normal(&mut self, sigma: f64) -> f64 {
        let mut unit = || {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let (u1, u2) = (unit().max(1e-300), unit());
        sigma * (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
    }
}

/// The controller's parameters for a machine file whose motors are `file`.
fn params(file: [Truth; 2], rotors: RotorCount) -> Params {
    let m = MachineConstants {
        rotor_count: rotors,
        rotors: file.map(|t| t.model()),
        ..MachineConstants::REFERENCE
    };
    Params::from_machine(&m)
}

/// Runs the identification on `truth` with settings from `file`; returns its
/// result and the seconds it took.
fn identify(truth: [Truth; 2], file: [Truth; 2], noise_a: f64) -> (Identity, f64) {
    let p = params(file, RotorCount::Two);
    let mut rotors = [Rotor::new(truth[0], 0.3), Rotor::new(truth[1], -0.2)];
    let mut run = IdentifyRun::new(IdentifyConfig::from_params(&p));
    let mut noise = Noise(7);
    let mut bridges = [Bridge::Off; 2];
    let mut ticks = 0u32;
    loop {
        let amps = [0, 1].map(|k| rotors[k].tick(bridges[k]) + noise.normal(noise_a));
        let sample = IdentifySample {
            encoder: [rotors[0].count(), rotors[1].count()],
            current: amps.map(|a| a as f32),
            supply_voltage: SUPPLY as f32,
            speed_rpm: [rotors[0].speed_rpm as f32, rotors[1].speed_rpm as f32],
        };
        let step = run.step(&sample, DT as f32);
        bridges = step.bridges;
        ticks += 1;
        if step.done {
            break;
        }
        assert!(ticks < 120_000, "the identification never ends");
    }
    (run.result(), f64::from(ticks) * DT)
}

/// `value` within `tolerance` (relative) of `truth`.
fn within(name: &str, value: f32, truth: f64, tolerance: f64, r: &RotorIdentity) {
    let error = (f64::from(value) - truth) / truth;
    assert!(
        error.abs() <= tolerance,
        "{name}: {value} against {truth} ({:+.2} %, allowed {} %)\n{r:#?}",
        100.0 * error,
        100.0 * tolerance
    );
}

fn check(r: &RotorIdentity, t: &Truth, tolerance: f64, friction_tolerance: f64) {
    assert_eq!(r.shortfall, None, "{r:#?}");
    within(
        "resistance",
        r.resistance_ohm.value,
        t.resistance,
        tolerance,
        r,
    );
    within(
        "torque constant",
        r.torque_constant.value,
        t.torque_constant,
        tolerance,
        r,
    );
    within("inertia", r.inertia_kg_m2.value, t.inertia, tolerance, r);
    within(
        "coulomb friction",
        r.coulomb_friction_nm.value,
        t.coulomb,
        friction_tolerance,
        r,
    );
}

/// A motor without an eccentric, its file right: every constant to 1 %.
#[test]
fn a_motor_without_an_eccentric_gives_its_constants() {
    let t = Truth {
        unbalance: 0.0,
        inertia: 6.0e-6,
        ..Truth::REFERENCE
    };
    let (id, seconds) = identify([t; 2], [t; 2], 0.0);
    for r in &id.rotors {
        check(r, &t, 0.01, 0.01);
    }
    println!("{seconds} s: {:#?}", id.rotors[0]);
}

/// The reference motor with its eccentric, its file right.
#[test]
fn the_reference_motor_with_its_eccentric() {
    let t = Truth::REFERENCE;
    let (id, seconds) = identify([t; 2], [t; 2], 0.0);
    for r in &id.rotors {
        check(r, &t, 0.02, 0.05);
    }
    println!("{seconds} s: {:#?}", id.rotors[0]);
}

/// Motors 10 to 30 % off their file, unlike each other.
fn unlike_motors() -> [Truth; 2] {
    let file = Truth::REFERENCE;
    [
        Truth {
            resistance: 2.0 * 0.8,
            torque_constant: 0.02 * 1.15,
            inertia: file.inertia * 1.25,
            coulomb: 1.0e-3 * 1.3,
            viscous: 1.0e-6 * 0.7,
            ..file
        },
        Truth {
            resistance: 2.0 * 1.2,
            torque_constant: 0.02 * 0.85,
            inertia: file.inertia * 0.8,
            coulomb: 1.0e-3 * 0.75,
            viscous: 1.0e-6 * 1.3,
            ..file
        },
    ]
}

/// Every value within `sigmas` of its standard errors of the truth.
fn covered(r: &RotorIdentity, t: &Truth, sigmas: f64) {
    for (name, e, truth) in [
        ("resistance", r.resistance_ohm, t.resistance),
        ("torque constant", r.torque_constant, t.torque_constant),
        ("coulomb friction", r.coulomb_friction_nm, t.coulomb),
        ("viscous friction", r.viscous_friction, t.viscous),
        ("inertia", r.inertia_kg_m2, t.inertia),
    ] {
        let off = (f64::from(e.value) - truth).abs();
        assert!(
            off <= sigmas * f64::from(e.std_error),
            "{name}: {} +- {} does not cover {truth}\n{r:#?}",
            e.value,
            e.std_error
        );
    }
}

/// Motors 10 to 30 % off their file, unlike each other, an ideal current sense:
/// each value within 5 % (friction 20 %, both kinds), and within three of its
/// standard errors.
#[test]
fn motors_unlike_their_file_are_found() {
    let truth = unlike_motors();
    let (id, _) = identify(truth, [Truth::REFERENCE; 2], 0.0);
    for (r, t) in id.rotors.iter().zip(&truth) {
        check(r, t, 0.05, 0.2);
        within(
            "viscous friction",
            r.viscous_friction.value,
            t.viscous,
            0.2,
            r,
        );
        covered(r, t, 3.0);
    }
}

/// The same with 0.01 A of noise on the current sense (a shunt amplifier's, as
/// the machine file's `current_noise` describes): resistance, torque constant
/// and inertia still within 5 %, Coulomb friction within 20 %; the viscous
/// friction, a twentieth of the friction torque at these speeds, is what the
/// noise blurs most, and its standard error says so: every value within three
/// of its standard errors.
#[test]
fn noise_shows_in_the_standard_errors() {
    let truth = unlike_motors();
    let (id, _) = identify(truth, [Truth::REFERENCE; 2], 0.01);
    for (r, t) in id.rotors.iter().zip(&truth) {
        check(r, t, 0.05, 0.2);
        covered(r, t, 3.0);
        let relative = f64::from(r.viscous_friction.std_error) / t.viscous;
        assert!(relative > 0.05, "the noise shows in b's error: {relative}");
    }
}

/// A rotor with too little holding it (an eccentric-free rotor whose file
/// claims an eccentric): the standstill levels turn it, and it says so.
#[test]
fn a_rotor_that_will_not_hold_still_says_so() {
    let truth = Truth {
        unbalance: 0.0,
        coulomb: 1.0e-4,
        ..Truth::REFERENCE
    };
    let (id, _) = identify([truth; 2], [Truth::REFERENCE; 2], 0.0);
    assert_eq!(
        id.rotors[0].shortfall,
        Some(Shortfall::NoStandstill),
        "{id:#?}"
    );
}

/// The settings the module documentation quotes for the reference machine: hold
/// currents 0.018 to 0.074 A at duties 0.003 to 0.012, the top speed's duty 0.14
/// (750 rpm), and about 9 s a rotor.
#[test]
fn the_reference_settings_are_as_documented() {
    let c = IdentifyConfig::from_params(&Params::reference());
    let t = Truth::REFERENCE;
    let amps = |d: f32| f64::from(d) * SUPPLY / t.resistance;
    let hold = c.hold_duty[0];
    assert!((amps(hold[0]) - 0.0185).abs() < 5e-4, "{hold:?}");
    assert!((amps(hold[3]) - 0.074).abs() < 5e-4, "{hold:?}");
    assert!((f64::from(hold[0]) - 0.003).abs() < 5e-4 && (f64::from(hold[3]) - 0.012).abs() < 5e-4);
    assert!(
        (c.speed_duty[0][0] - 0.14).abs() < 5e-3,
        "{:?}",
        c.speed_duty
    );
    let (_, seconds) = identify([t; 2], [t; 2], 0.0);
    assert!((14.0..=22.0).contains(&seconds), "{seconds} s");
    // The worst case every timeout allows, which `device identify --timeout`'s
    // default covers (docs/cli-device.md).
    assert_eq!(shared::controller::identify::WORST_ROTOR_S, 60.0);
}

/// On a one-rotor machine rotor 2's bridge stays off and only rotor 1 is
/// identified; an abort marks the rotor under test and drives nothing after.
#[test]
fn one_rotor_and_an_abort() {
    let t = Truth::REFERENCE;
    let p = params([t; 2], RotorCount::One);
    let mut rotor = Rotor::new(t, 0.1);
    let mut run = IdentifyRun::new(IdentifyConfig::from_params(&p));
    let mut bridge = Bridge::Off;
    for tick in 0..3000 {
        let amps = rotor.tick(bridge);
        let step = run.step(
            &IdentifySample {
                encoder: [rotor.count(), 0],
                current: [amps as f32, 0.0],
                supply_voltage: SUPPLY as f32,
                speed_rpm: [rotor.speed_rpm as f32, 0.0],
            },
            DT as f32,
        );
        assert_eq!(step.bridges[1], Bridge::Off, "tick {tick}");
        bridge = step.bridges[0];
    }
    assert_eq!(run.rotor(), Some(0));
    assert_eq!(run.result().rotors_run, 1);
    run.abort();
    assert!(run.is_done());
    assert_eq!(run.result().rotors[0].shortfall, Some(Shortfall::Aborted));
    let step = run.step(
        &IdentifySample {
            encoder: [rotor.count(), 0],
            current: [0.0; 2],
            supply_voltage: SUPPLY as f32,
            speed_rpm: [0.0; 2],
        },
        DT as f32,
    );
    assert!(step.done && step.bridges == [Bridge::Off; 2]);
}

/// The controller runs the identification from `start_identify` to idle, on
/// two reference motors: state `identify` meanwhile, then `Done` with the
/// motors' constants; run commands are refused while it runs.
#[test]
fn the_controller_runs_it() {
    let t = Truth::REFERENCE;
    let p = params([t; 2], RotorCount::Two);
    let mut c = Controller::new(&p, ResetCause::PowerOn);
    let mut rotors = [Rotor::new(t, 0.3), Rotor::new(t, -0.2)];
    let mut bridges = [Bridge::Off; 2];
    let inputs = |rotors: &[Rotor; 2], amps: [f64; 2], command| Inputs {
        encoder: [rotors[0].count(), rotors[1].count()],
        current: amps.map(|a| a as f32),
        supply_voltage: SUPPLY as f32,
        command,
        ..Inputs::default()
    };
    c.step(&inputs(&rotors, [0.0; 2], None), DT as f32);
    assert!(c.start_identify());
    assert!(!c.start_self_test(), "one procedure at a time");
    let mut ticks = 0;
    loop {
        let amps = [0, 1].map(|k| rotors[k].tick(bridges[k]));
        let index = [0, 1].map(|k| rotors[k].index.take());
        let command = (ticks == 100).then_some(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        });
        let out = c.step(
            &Inputs {
                index,
                ..inputs(&rotors, amps, command)
            },
            DT as f32,
        );
        if ticks == 100 {
            assert!(out.telemetry.command_rejected, "a run command is refused");
        }
        bridges = out.bridges;
        ticks += 1;
        if out.state != State::Identify {
            assert_eq!(
                out.state,
                State::Idle,
                "faults {:?} after {ticks} ticks",
                out.faults
            );
            assert_eq!(out.bridges, [Bridge::Off; 2]);
            break;
        }
        assert!(ticks < 40_000, "never ends");
    }
    let report = c.identify_report();
    assert_eq!(report.status, IdentifyStatus::Done);
    for r in &report.identity.rotors {
        check(r, &t, 0.02, 0.05);
    }
}

/// A stop aborts it (idle) and the E-stop does too (fault), the bridges off in
/// that very tick; the rotor under test is marked aborted.
#[test]
fn a_stop_or_the_estop_aborts_it() {
    let t = Truth::REFERENCE;
    for estop in [false, true] {
        let mut c = Controller::new(&params([t; 2], RotorCount::Two), ResetCause::PowerOn);
        let mut rotors = [Rotor::new(t, 0.3), Rotor::new(t, -0.2)];
        let mut bridges = [Bridge::Off; 2];
        assert!(c.start_identify());
        for tick in 0..3000 {
            let amps = [0, 1].map(|k| rotors[k].tick(bridges[k]));
            let index = [0, 1].map(|k| rotors[k].index.take());
            let last = tick == 2999;
            let out = c.step(
                &Inputs {
                    encoder: [rotors[0].count(), rotors[1].count()],
                    index,
                    current: amps.map(|a| a as f32),
                    supply_voltage: SUPPLY as f32,
                    estop: last && estop,
                    command: (last && !estop).then_some(Command::Stop),
                    ..Inputs::default()
                },
                DT as f32,
            );
            bridges = out.bridges;
            if last {
                assert_eq!(out.bridges, [Bridge::Off; 2], "estop {estop}");
                assert_eq!(out.state, if estop { State::Fault } else { State::Idle });
            } else {
                assert_eq!(out.state, State::Identify);
            }
        }
        let report = c.identify_report();
        assert_eq!(report.status, IdentifyStatus::Aborted);
        // Rotor 1 under test, rotor 2 not yet run: neither reads as measured.
        for r in &report.identity.rotors {
            assert_eq!(r.shortfall, Some(Shortfall::Aborted));
        }
    }
}

/// The link's copy of the report follows a new run even where it ends as the
/// last one did: a run stopped after rotor 1 finished, then a second stopped in
/// its first tick, leave the link reporting the second (nothing measured), not
/// the first's rotor 1.
#[test]
fn the_link_reports_the_latest_run() {
    use shared::protocol::link::{no_telemetry, LinkState};
    use shared::protocol::StatusReport;
    let t = Truth::REFERENCE;
    let mut c = Controller::new(&params([t; 2], RotorCount::Two), ResetCause::PowerOn);
    let mut link = LinkState::new(
        StatusReport {
            uptime_ms: 0,
            state: c.state(),
            faults: c.faults(),
            telemetry: no_telemetry(),
            rx_dropped: 0,
        },
        c.params().tuning.clone(),
        None,
    );
    let mut rotors = [Rotor::new(t, 0.3), Rotor::new(t, -0.2)];
    let mut bridges = [Bridge::Off; 2];
    let mut tick =
        |c: &mut Controller, link: &mut LinkState, rotors: &mut [Rotor; 2], stop: bool| {
            let amps = [0, 1].map(|k| rotors[k].tick(bridges[k]));
            let index = [0, 1].map(|k| rotors[k].index.take());
            let inputs = Inputs {
                encoder: [rotors[0].count(), rotors[1].count()],
                index,
                current: amps.map(|a| a as f32),
                supply_voltage: SUPPLY as f32,
                command: stop.then_some(Command::Stop),
                ..Inputs::default()
            };
            let out = c.step(&inputs, DT as f32);
            bridges = out.bridges;
            link.publish(0, &inputs, &out, c);
        };
    assert!(c.start_identify());
    let mut ticks = 0;
    while c.identify_progress().rotors_finished < 1 {
        tick(&mut c, &mut link, &mut rotors, false);
        ticks += 1;
        assert!(ticks < 30_000, "rotor 1 never finished");
    }
    tick(&mut c, &mut link, &mut rotors, true);
    assert_eq!(link.identify.status, IdentifyStatus::Aborted);
    assert_eq!(
        link.identify.identity.rotors[0].shortfall, None,
        "rotor 1 kept"
    );
    // Rest, then a second run stopped at once.
    for _ in 0..3000 {
        tick(&mut c, &mut link, &mut rotors, false);
    }
    assert!(c.start_identify());
    tick(&mut c, &mut link, &mut rotors, true);
    assert_eq!(link.identify.status, IdentifyStatus::Aborted);
    assert_eq!(
        link.identify.identity.rotors[0].shortfall,
        Some(Shortfall::Aborted),
        "the second run's report, not the first's"
    );
}
