//! The reference machine with the controller in the loop (`host-sim run --command`):
//! the physics the closed loop must show, against references that do not come from
//! the controller.
//!
//! - Travel: commanded right it travels right, commanded left it travels left.
//! - Mirror antisymmetry: `v(360 - d) = -v(d)` for a held offset `d`.
//!   The machine is mirror-symmetric about its vertical centre line with rotor 1
//!   (ccw) on the left and rotor 2 (cw) on the right. The mirror `x -> -x` maps the
//!   left ccw rotor onto the right cw one: it swaps rotor 1 and rotor 2, and maps an
//!   eccentric angle `phi` to `pi - phi`. With both index angles 0 the encoder
//!   angles become `theta_1' = pi + theta_2`, `theta_2' = theta_1 - pi`, so the
//!   offset `theta_1 - theta_2 = d` becomes `360 - d` and the travel `x` becomes
//!   `-x`. The controller treats the rotors alike up to that swap: the phase loop
//!   gives rotor 1 `+dw/2` and rotor 2 `-dw/2`, and the error and `dw` change sign
//!   with the offset. It is not symmetric at start-up, though: the phase loop closes
//!   at the offset it measures, and an offset on the other side of 180 degrees than
//!   the target is reached through 180 (`shared::controller::ramp::OffsetRamp`).
//!   From the reference machine's start (both eccentrics along +x, offset 0) the
//!   loop closes at about 3 degrees, so a target of 300 takes the long way through
//!   180 and one of 60 the short one: the two runs are not mirror images. Started
//!   with both eccentrics hanging down (`phi = -90` degrees, their rest position
//!   under gravity), the start is its own mirror image (offset exactly 180), both
//!   runs stay identical until the loop closes at 180 and then ramp 120 degrees to
//!   either side: mirror images in exact arithmetic. What breaks the symmetry is
//!   rounding (the contacts and rotors are summed in file order, not mirrored
//!   order), which the impacts amplify; the plant alone shows the property to 1 %
//!   (`plant_travel.rs`), and that is the tolerance here. Measured (release, this
//!   commit): the pairs agree to 1e-5 of the velocity.
//! - The vertical-force offset 180 degrees gives no travel: by the mirror argument
//!   `v(180) = -v(180)`; checked from the reference machine's own (asymmetric)
//!   start, so that it is not the trivial symmetric case, against 5 % of the
//!   travel at 90 degrees (measured: 0.1 mm/s, 0.4 %). No travel is also what a
//!   platform glued to the floor gives; that it hops every revolution at 180
//!   degrees, in closed loop too, is checked in `plant_unilateral.rs`.
//! - A second method: the mean velocity at a held offset agrees with the plant
//!   alone with both rotors forced at exactly the commanded speed and offset (no
//!   controller, no motors), within 5 %. The two differ by design: an impact jerks
//!   a free rotor (an eccentric of `m e = 2e-4 kg m` on `J = 1e-5 kg m^2` changes
//!   its speed by `m e dv / J`, about 6 rad/s for a 0.3 m/s jump of the platform),
//!   which the speed loop (crossover 50 rad/s) corrects only over the next
//!   revolutions, while the forced rotors never change speed. Measured (release,
//!   this commit): at 90 degrees the closed loop travels 1.8 % slower over 1.5 to
//!   3 s and 3.6 % slower in the long run (5 to 10 s); at 60 degrees 1.4 % and
//!   1.0 % slower.
//! - The phase offset measured from the plant's true rotor angles (the summary's,
//!   not the controller's encoder counts) holds within a degree of the commanded
//!   one, and the rotors' true mean speeds within 2 rpm of the commanded speed.
//! - Determinism: two identical runs, with sensor noise on, give the same bits.
//!
//! The controller reaches `running` at about 0.71 s (the speed ramp: 1488 rpm at
//! 3000 rpm/s, the resonance band to 2508 rpm in 53 ms, 492 rpm more at
//! 3000 rpm/s). Runs are
//! 2 to 3 s so that the statistics over the second half (the summary's, from `T/2`)
//! see the held offset. The tests hold whether or not the machine file names a
//! tuning table: they check directions and physics, and read the offset a travel
//! command asks for from the controller's telemetry.

use std::f64::consts::FRAC_PI_2;
use std::sync::OnceLock;

use host_sim::plant::simulator::Settings;
use host_sim::simulation::closed_loop::ControllerDriver;
use host_sim::simulation::summary::{impact_times, SummaryBuilder};
use host_sim::simulation::trace::Summary;
use host_sim::simulation::{simulate, RunOptions, RunResult};
use shared::controller::{Command, Direction, State};
use tests::held::{held_rotors, mean_velocity, reference_machine};
use tests::machine::TestMachine;

/// The commanded rotor speed, rpm (the reference machine's `speed_rpm`).
const SPEED_RPM: f64 = 3000.0;

/// The smallest travel speed that counts as travelling, m/s: a sixth of the
/// 26 to 30 mm/s the plant alone travels at 60 to 90 degrees (forced rotors).
const TRAVELS: f64 = 5e-3;

/// Where the eccentrics are at `t = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Start {
    /// As the machine file has it: both along +x of the platform (offset 0).
    Reference,
    /// Both hanging down, `phi = -90` degrees: the mirror image of itself (offset
    /// 180).
    Hanging,
}

impl Start {
    /// The `--set` overrides of this start.
    fn sets(self) -> Vec<String> {
        match self {
            Start::Reference => Vec::new(),
            Start::Hanging => (0..2)
                .map(|k| format!("rotors.{k}.angle={}", -FRAC_PI_2))
                .collect(),
        }
    }
}

/// What a closed-loop run gave.
struct ClosedLoop {
    /// The run: summary, trace and events.
    result: RunResult,
    /// The controller's state at the end.
    state: State,
    /// The offset the controller was holding at the end (its telemetry's target:
    /// the table's for a travel command), degrees.
    target_offset_deg: f64,
    /// When the controller first reported `running`, s.
    running_at: Option<f64>,
}

impl ClosedLoop {
    fn summary(&self) -> &Summary {
        &self.result.summary
    }
}

/// Runs the reference machine from `start`, with `sets` overrides, under `command`
/// given at `t = 0`, to `t_end`.
fn closed_loop(command: Command, start: Start, sets: &[String], t_end: f64) -> ClosedLoop {
    let mut all = start.sets();
    all.extend_from_slice(sets);
    let machine = TestMachine::example().sets(&all).machine();
    let mut driver =
        ControllerDriver::new(&machine, vec![(0.0, command)]).expect("the controller starts");
    driver.record_history(true);
    let options = RunOptions::new(t_end);
    let result = simulate(&machine, &mut driver, &options);
    let last = driver.last().expect("the controller ran");
    ClosedLoop {
        state: last.state,
        target_offset_deg: f64::from(last.telemetry.target_offset_deg),
        running_at: driver
            .history
            .iter()
            .find(|(_, o)| o.state == State::Running)
            .map(|(t, _)| *t),
        result,
    }
}

/// Holds `offset_deg` at [`SPEED_RPM`].
fn hold(offset_deg: f32) -> Command {
    Command::HoldOffset {
        speed_rpm: SPEED_RPM as f32,
        offset_deg,
    }
}

/// Travels in `direction` at [`SPEED_RPM`] (the tuning table's offset).
fn travel(direction: Direction) -> Command {
    Command::Travel {
        direction,
        speed_rpm: SPEED_RPM as f32,
    }
}

// The runs several tests share, each computed once: tests run in parallel, and a
// second test asking for a run waits for the first to finish it.

/// Travel right, reference start, 3 s.
fn right() -> &'static ClosedLoop {
    static RUN: OnceLock<ClosedLoop> = OnceLock::new();
    RUN.get_or_init(|| closed_loop(travel(Direction::Right), Start::Reference, &[], 3.0))
}

/// Hold 90 degrees, hanging start, 3 s.
fn hold_90() -> &'static ClosedLoop {
    static RUN: OnceLock<ClosedLoop> = OnceLock::new();
    RUN.get_or_init(|| closed_loop(hold(90.0), Start::Hanging, &[], 3.0))
}

/// Hold 60 degrees, hanging start, 3 s.
fn hold_60() -> &'static ClosedLoop {
    static RUN: OnceLock<ClosedLoop> = OnceLock::new();
    RUN.get_or_init(|| closed_loop(hold(60.0), Start::Hanging, &[], 3.0))
}

/// A healthy run: running at the end, no fault, no warning, running since
/// before 1 s.
fn assert_healthy(run: &ClosedLoop, what: &str) {
    let s = run.summary();
    assert_eq!(run.state, State::Running, "{what}: state at the end");
    assert!(s.faults.is_empty(), "{what}: faults {:?}", s.faults);
    assert!(s.warnings.is_empty(), "{what}: warnings {:?}", s.warnings);
    let t = run.running_at.expect("reaches running");
    assert!(t < 1.0, "{what}: running only from {t} s");
}

/// The plant alone with both rotors forced at [`SPEED_RPM`] (rotor 1 ccw, rotor 2
/// cw) and the phase offset `offset_deg`: the mean velocity over `[t0, t1]`, m/s.
/// The rotors start so that the offset `theta_1 - theta_2 = phi_1 + phi_2` (index
/// angles 0, rotor 2 cw) is `offset_deg`.
fn forced_rotors_velocity(offset_deg: f64, t0: f64, t1: f64) -> f64 {
    let m = reference_machine(offset_deg, &[]);
    let mut plant = held_rotors(&m, SPEED_RPM, Settings::default());
    mean_velocity(&mut plant, t0, t1)
}

/// The phase offset of a two-rotor run's summary, degrees.
fn offset(s: &Summary) -> f64 {
    s.phase_offset_deg.expect("two rotors have a phase offset")
}

/// `|a - b|` wrapped to [0, 180], degrees.
fn angle_between_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

#[test]
fn travels_right_when_commanded_right() {
    let run = right();
    assert_healthy(run, "right");
    let v = run.summary().mean_velocity;
    assert!(v > TRAVELS, "commanded right: mean velocity {v} m/s");
}

#[test]
fn travels_left_when_commanded_left() {
    let run = closed_loop(travel(Direction::Left), Start::Reference, &[], 3.0);
    assert_healthy(&run, "left");
    let v = run.summary().mean_velocity;
    assert!(v < -TRAVELS, "commanded left: mean velocity {v} m/s");
}

/// `v(360 - d) = -v(d)` within 1 %, from the hanging start; the rotors' mean speeds
/// swap and the measured offsets mirror.
fn assert_mirror_antisymmetric(d: f32, run: &ClosedLoop) {
    let mirrored = closed_loop(hold(360.0 - d), Start::Hanging, &[], run.summary().t_end);
    let (a, b) = (run.summary(), mirrored.summary());
    assert_healthy(run, "offset d");
    assert_healthy(&mirrored, "offset 360 - d");
    assert!(a.mean_velocity > TRAVELS, "v({d}) = {}", a.mean_velocity);
    assert!(
        (a.mean_velocity + b.mean_velocity).abs() <= 0.01 * a.mean_velocity.abs(),
        "v({d}) = {}, v({}) = {}",
        a.mean_velocity,
        360.0 - d,
        b.mean_velocity
    );
    // Rotor 1 of one run is rotor 2 of the other.
    for k in 0..2 {
        let (r, s) = (a.rotor_speed_rpm[k], b.rotor_speed_rpm[1 - k]);
        assert!((r - s).abs() < 0.1, "rotor speeds {r} and {s} rpm");
    }
    let (a_offset, b_offset) = (offset(a), offset(b));
    let mirrored_offset = 360.0 - b_offset;
    assert!(
        angle_between_deg(a_offset, mirrored_offset) < 0.1,
        "offsets {a_offset} and {b_offset}"
    );
}

#[test]
fn mean_velocity_is_antisymmetric_in_the_offset_at_60_degrees() {
    assert_mirror_antisymmetric(60.0, hold_60());
}

#[test]
fn mean_velocity_is_antisymmetric_in_the_offset_at_90_degrees() {
    assert_mirror_antisymmetric(90.0, hold_90());
}

#[test]
fn the_vertical_force_offset_gives_no_travel() {
    // From the reference start (offset 0 at rest): not its own mirror image.
    let run = closed_loop(hold(180.0), Start::Reference, &[], 3.0);
    assert_healthy(&run, "180");
    let v = run.summary().mean_velocity;
    // 5 % of the travel at 90 degrees.
    let v90 = forced_rotors_velocity(90.0, 1.0, 2.0);
    assert!(
        v.abs() < 0.05 * v90.abs(),
        "v(180) = {v} m/s, v(90) = {v90} m/s"
    );
}

#[test]
fn held_offset_travels_as_with_forced_rotors() {
    for (d, run) in [(60.0, hold_60()), (90.0, hold_90())] {
        let v = run.summary().mean_velocity;
        let half = run.summary().t_end / 2.0;
        let forced = forced_rotors_velocity(d, half, 2.0 * half);
        assert!(
            (v - forced).abs() <= 0.05 * forced.abs(),
            "offset {d}: closed loop {v} m/s, forced rotors {forced} m/s"
        );
    }
}

#[test]
fn the_measured_offset_holds_the_commanded_one() {
    for (what, run) in [("right", right()), ("60", hold_60()), ("90", hold_90())] {
        let s = run.summary();
        assert!(
            s.phase_error_deg_rms < 1.0,
            "{what}: RMS phase error {} degrees",
            s.phase_error_deg_rms
        );
        let off = angle_between_deg(offset(s), run.target_offset_deg);
        assert!(
            off < 0.5,
            "{what}: mean offset {} degrees, commanded {}",
            offset(s),
            run.target_offset_deg
        );
    }
}

#[test]
fn rotor_speeds_hold_the_commanded_speed() {
    for (what, run) in [("right", right()), ("60", hold_60()), ("90", hold_90())] {
        for (k, r) in run.summary().rotor_speed_rpm.iter().enumerate() {
            assert!(
                (r - SPEED_RPM).abs() < 2.0,
                "{what}: rotor {} at {r} rpm",
                k + 1
            );
        }
    }
}

#[test]
fn two_identical_runs_give_identical_results() {
    // With current noise (a shunt amplifier's 0.01 A) and encoder edge jitter, so
    // that the seeded noise streams take part; past the start into running.
    let noise = |seed: u64| {
        vec![
            "sensors.current_noise=0.01".to_string(),
            "sensors.encoder_jitter=1e-6".to_string(),
            format!("simulation.seed={seed}"),
        ]
    };
    let command = travel(Direction::Right);
    let a = closed_loop(command, Start::Reference, &noise(1), 1.0);
    let b = closed_loop(command, Start::Reference, &noise(1), 1.0);
    assert_eq!(a.state, State::Running);
    assert_eq!(
        format!("{:?}", a.result.summary),
        format!("{:?}", b.result.summary)
    );
    assert_eq!(a.result.rows.len(), b.result.rows.len());
    for (ra, rb) in a.result.rows.iter().zip(&b.result.rows) {
        assert_eq!(format!("{ra:?}"), format!("{rb:?}"));
    }
    assert_eq!(
        format!("{:?}", a.result.events),
        format!("{:?}", b.result.events)
    );
    assert_eq!(a.result.steps, b.result.steps);

    // The noise is in play: another seed takes another path.
    let c = closed_loop(command, Start::Reference, &noise(2), 1.0);
    assert_ne!(
        format!("{:?}", a.result.rows),
        format!("{:?}", c.result.rows),
        "seed 2 gives the same trace as seed 1"
    );
}

/// The summary is built row by row while the run goes, with its midpoint fixed
/// before it starts. On a real run (travel right, its rows kept), the travel speed
/// and the rotor speeds computed here from the stored rows, by the definitions
/// (`(x(T) - x(T/2)) / (T/2)` with `x(T/2)` interpolated linearly between the rows
/// around it), are the summary's; and so is the whole summary computed afresh from
/// the stored rows.
#[test]
fn the_summary_built_row_by_row_is_the_one_of_the_stored_rows() {
    let run = right();
    let rows = &run.result.rows;
    let s = run.summary();
    let last = rows.last().expect("rows");
    let half = 0.5 * (rows[0].t + last.t);
    let i = rows.partition_point(|r| r.t <= half);
    let (a, b) = (&rows[i - 1], &rows[i]);
    let at_half = |f: fn(&host_sim::simulation::trace::TraceRow) -> f64| {
        f(a) + (f(b) - f(a)) * (half - a.t) / (b.t - a.t)
    };
    let duration = last.t - half;
    let v = (last.x - at_half(|r| r.x)) / duration;
    assert!(
        (s.mean_velocity - v).abs() <= 1e-12 * v.abs().max(1e-6),
        "{} vs {v}",
        s.mean_velocity
    );
    let w1 = (last.phi1 - at_half(|r| r.phi1)) / duration * 30.0 / std::f64::consts::PI;
    assert!(
        (s.rotor_speed_rpm[0].abs() - w1.abs()).abs() <= 1e-9 * w1.abs(),
        "{:?} vs {w1}",
        s.rotor_speed_rpm
    );
    let machine = TestMachine::example().machine();
    // The same rows and events through a builder of their own.
    let mut builder = SummaryBuilder::new(&machine, rows[0].t, last.t);
    for r in rows {
        builder.push(r);
    }
    let impacts = impact_times(&run.result.events).len();
    let again = builder.finish(impacts, None, s.warnings.clone());
    assert_eq!(again.mean_velocity, s.mean_velocity);
    assert_eq!(again.rotor_speed_rpm, s.rotor_speed_rpm);
    assert_eq!(again.phase_offset_deg, s.phase_offset_deg);
    assert_eq!(again.impacts, s.impacts);
}
