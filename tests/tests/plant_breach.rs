//! A run says when a body went through the fundament or tipped over
//! (`host_sim::simulation::breach`, issue 23), and only then:
//!
//! - the reference machine standing, travelling either way, holding offsets at
//!   speeds drawn at random, open loop, on a level floor and on tilted ones (the
//!   whole machine turned with its floor and gravity), and the paper's Fig. 8
//!   machine, never trigger it; nor does the reference machine on narrow feet
//!   (x = +-0.01 m), which rocks about them by a few degrees (issue 23: the
//!   bounding box's corner beside a foot, no part of the machine, went 1.3 mm
//!   through the floor);
//! - a platform falling head first (its only foot on top) is found at the first
//!   trace row after its eccentric circle's lowest point is 1 mm below the floor,
//!   on level and tilted floors at heights drawn at random: free fall along the
//!   floor's normal, `h(t) = h_0 - g t^2 / 2`;
//! - a platform whose centre of mass starts below the floor is found at t = 0;
//! - a free body turned past `[simulation] max_tilt` is found at the first row
//!   past it, and not below it.

use host_sim::machine::Machine;
use host_sim::simulation::breach::{BreachKind, BELOW_TOLERANCE};
use host_sim::simulation::closed_loop::ControllerDriver;
use host_sim::simulation::trace::Summary;
use host_sim::simulation::{simulate, OpenLoop, OpenLoopDriver, RunOptions, RunResult};
use shared::controller::{Command, Direction};
use tests::machine::{TestMachine, DRIVE_12V, REFERENCE_MOTOR};
use tests::Rng;

/// `p` turned by `a` rad about the origin, as TOML.
fn turned(p: [f64; 2], a: f64) -> String {
    let (s, c) = a.sin_cos();
    format!("[{:?}, {:?}]", c * p[0] - s * p[1], s * p[0] + c * p[1])
}

/// The `--set` keys that turn the reference machine with its floor and gravity by
/// `a` rad about the origin: it stands on its feet on a floor tilted by `a`.
fn tilted(a: f64) -> Vec<String> {
    vec![
        format!("fundament.normal={}", turned([0.0, 1.0], a)),
        format!("fundament.gravity={}", turned([0.0, -9.81], a)),
        format!("platform.position={}", turned([0.0, 0.03], a)),
        format!("platform.angle={a:?}"),
        format!("contacts.K1.point={}", turned([-0.08, 0.0], a)),
        format!("contacts.K2.point={}", turned([0.08, 0.0], a)),
        format!("rotors.left.axis={}", turned([-0.03, 0.03], a)),
        format!("rotors.right.axis={}", turned([0.03, 0.03], a)),
    ]
}

/// A run of `machine` to `t_end` driven by the controller with `command`.
fn commanded(machine: &Machine, command: Command, t_end: f64) -> RunResult {
    let mut driver = ControllerDriver::new(machine, vec![(0.0, command)]).expect("controller");
    simulate(machine, &mut driver, &RunOptions::new(t_end))
}

/// A run of `machine` to `t_end` in open loop.
fn open_loop(machine: &Machine, mode: OpenLoop, t_end: f64) -> RunResult {
    let mut driver = OpenLoopDriver::new(mode, machine.drive.supply_voltage);
    simulate(machine, &mut driver, &RunOptions::new(t_end))
}

/// No breach, no "not a travel", no warning of one.
fn assert_kept(s: &Summary, what: &str) {
    assert!(s.breaches.is_empty(), "{what}: {:?}", s.breaches);
    assert_eq!(s.not_a_travel(), None, "{what}");
    assert!(
        !s.warnings
            .iter()
            .any(|w| w.contains("fundament") || w.contains("tipped")),
        "{what}: {:?}",
        s.warnings
    );
}

#[test]
fn the_reference_machine_never_goes_through_its_floor() {
    let mut rng = Rng::new(23);
    for a in [0.0, -0.2, 0.15] {
        let m = TestMachine::example().sets(&tilted(a)).machine();
        let travel = |direction| Command::Travel {
            direction,
            speed_rpm: 3000.0,
        };
        let mut runs = vec![
            (
                "right".to_string(),
                commanded(&m, travel(Direction::Right), 1.5),
            ),
            (
                "left".to_string(),
                commanded(&m, travel(Direction::Left), 1.5),
            ),
        ];
        for _ in 0..2 {
            let (speed, offset) = (rng.uniform(2500.0, 3500.0), rng.uniform(0.0, 360.0));
            let hold = Command::HoldOffset {
                speed_rpm: speed as f32,
                offset_deg: offset as f32,
            };
            runs.push((
                format!("hold {offset:.1} deg at {speed:.0} rpm"),
                commanded(&m, hold, 1.5),
            ));
        }
        if a == 0.0 {
            runs.push(("stop".to_string(), commanded(&m, Command::Stop, 0.5)));
            for v in [[12.0, 12.0], [12.0, -12.0]] {
                let run = open_loop(&m, OpenLoop::Voltages(v), 1.5);
                runs.push((format!("open loop {v:?} V"), run));
            }
        }
        for (what, run) in &runs {
            assert_kept(&run.summary, &format!("floor tilted {a} rad, {what}"));
        }
        // It travelled, on the level floor: the check did not pass for want of
        // motion.
        if a == 0.0 {
            assert!(
                runs[0].1.summary.mean_velocity > 0.01,
                "{:?}",
                runs[0].1.summary
            );
        }
    }
}

#[test]
fn the_reference_machine_on_narrow_feet_rocks_without_going_through() {
    // Its feet at x = +-0.01 m, under its rotor axes' inner sides: holding the
    // offset 180 degrees (the force straight up and down) it hops and rocks about
    // one foot, then the other. Its eccentric circles' lowest points pass 9.3 mm
    // above the floor at its largest rock; the bounding box's lower left corner
    // (x = -0.05 m at the feet's height) went 1.3 mm below it at t = 2.8 s.
    let m = TestMachine::example()
        .set("contacts.K1.point", "[-0.01, 0.0]")
        .set("contacts.K2.point", "[0.01, 0.0]")
        .machine();
    let hold = Command::HoldOffset {
        speed_rpm: 3000.0,
        offset_deg: 180.0,
    };
    let run = commanded(&m, hold, 3.0);
    assert_kept(&run.summary, "narrow feet, holding 180 deg");
    // It rocked: more than a degree either way (the reach the box's corner had).
    let most = run.rows.iter().map(|r| r.angle.abs()).fold(0.0, f64::max);
    assert!(most > 1f64.to_radians(), "largest rock {most} rad");
}

#[test]
fn the_paper_fig8_machine_never_goes_through_its_floor() {
    let m = TestMachine::file("examples/paper-fig8.toml").machine();
    let run = open_loop(&m, OpenLoop::Voltage(12.0), 1.5);
    assert_kept(&run.summary, "paper-fig8, open loop 12 V");
    assert!(run.summary.mean_velocity.abs() > 1e-3, "{:?}", run.summary);
}

/// A platform at `[0, h]` on a floor through the origin tilted by `a` rad, its
/// gravity along the floor's normal, one rotor at its centre of mass
/// (eccentricity 0.02 m) and its only contact point 0.1 m above it: it falls
/// head first, its outline the eccentric circle and the point above it.
fn head_first(h: f64, a: f64) -> Machine {
    let text = format!(
        "[fundament]\nnormal = {n}\ngravity = {g}\n\
         [platform]\nmass = 2.0\ninertia = 7.3e-3\nposition = [0.0, {h:?}]\n\
         [[contacts]]\nname = \"top\"\npoint = [0.0, {top:?}]\nrestitution = 0.3\nfriction = 0.4\n\
         [[rotors]]\nname = \"centre\"\naxis = [0.0, {h:?}]\neccentric_mass = 0.01\n\
         eccentricity = 0.02\ninertia = 6.0e-6\nsense = \"ccw\"\n\
",
        n = turned([0.0, 1.0], a),
        g = turned([0.0, -9.81], a),
        top = h + 0.1,
    );
    TestMachine::new("head-first.toml")
        .with(&text)
        .with(REFERENCE_MOTOR)
        .with(DRIVE_12V)
        .machine()
}

#[test]
fn a_platform_falling_head_first_is_found_when_it_crosses_the_floor() {
    let mut rng = Rng::new(0x23);
    let (e, g, step) = (0.02, 9.81, 1e-3);
    for _ in 0..8 {
        let (h, a) = (rng.uniform(0.05, 0.4), rng.uniform(-0.3, 0.3));
        let m = head_first(h, a);
        // Its lowest probe: its eccentric circle's lowest point along
        // n = (-sin a, cos a), e below the centre's h cos a. Free fall along n: it
        // is 1 mm below the floor at t* = sqrt(2 (h_low + 1 mm) / g).
        let low = h * a.cos() - e;
        let t_star = (2.0 * (low + BELOW_TOLERANCE) / g).sqrt();
        let run = open_loop(&m, OpenLoop::Voltage(0.0), t_star + 0.01);
        let s = &run.summary;
        let what = format!("h {h:.3} m, floor tilted {a:.3} rad: {:?}", s.breaches);
        let b = s.breaches.first().expect(&what);
        assert_eq!(b.body, "platform", "{what}");
        // The first trace row at or after t* (rows every 1 ms).
        assert!(
            b.t >= t_star - 1e-9 && b.t <= t_star + step + 1e-9,
            "t* {t_star}: {what}"
        );
        let BreachKind::Fundament { first, .. } = &b.kind else {
            panic!("{what}");
        };
        assert_eq!(
            first, "the lowest point of rotor \"centre\"'s eccentric circle",
            "{what}"
        );
        assert_eq!(
            s.not_a_travel().as_deref(),
            Some(
                format!(
                    "platform went through the fundament at t = {} s",
                    host_sim::numbers::sig(b.t)
                )
                .as_str()
            ),
        );
        // Before t* - step it was not yet through: the same machine run to there.
        let before = open_loop(&m, OpenLoop::Voltage(0.0), t_star - step);
        assert_kept(&before.summary, &format!("{what}, before t*"));
    }
}

#[test]
fn a_platform_sunk_below_the_floor_is_found_at_once() {
    // The reference platform's centre of mass 10 mm below the floor, its feet on it.
    let m = TestMachine::example()
        .set("platform.position", "[0.0, -0.01]")
        .machine();
    let run = open_loop(&m, OpenLoop::Coast, 0.05);
    let b = &run.summary.breaches[0];
    assert_eq!((b.body.as_str(), b.t), ("platform", 0.0));
    let BreachKind::Fundament { first, deepest, .. } = &b.kind else {
        panic!("{b:?}");
    };
    assert_eq!(first, "its centre of mass");
    assert!(*deepest >= 0.01, "{b:?}");
}

#[test]
fn a_free_body_turned_past_max_tilt_is_found_at_the_first_row_past_it() {
    // Open loop at 12 V the reference platform pitches by a few tenths of a degree.
    let limit = 1e-3; // rad
    let m = TestMachine::example()
        .sets(&[format!("simulation.max_tilt={limit}")])
        .machine();
    let run = open_loop(&m, OpenLoop::Voltages([12.0, 12.0]), 1.0);
    let first_past = run
        .rows
        .iter()
        .find(|r| r.angle.abs() > limit)
        .expect("it pitches past 1 mrad");
    let b = &run.summary.breaches[0];
    assert_eq!((b.body.as_str(), b.t), ("platform", first_past.t), "{b:?}");
    let BreachKind::Tilt { largest, .. } = b.kind else {
        panic!("{b:?}");
    };
    let most = run.rows.iter().map(|r| r.angle.abs()).fold(0.0, f64::max);
    assert_eq!(largest.abs(), most);
    assert!(!b.through_fundament());
    // With the default limit (60 degrees) the same run is kept.
    let m = TestMachine::example().machine();
    assert_kept(
        &open_loop(&m, OpenLoop::Voltages([12.0, 12.0]), 1.0).summary,
        "default max_tilt",
    );
}
