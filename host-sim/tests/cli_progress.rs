//! The progress guard through the real binary (docs/plant-model.md, "The progress
//! guard"): a run whose plant stops advancing in simulated time ends with exit 1
//! and a message naming the time, the contacts and their modes, its files whole;
//! a step size underflow ends it the same way; `tune`, `calibrate`, `scenario`
//! and `device-sim` each report such a run as what it is.
//!
//! The machines that stall: the reference machine set spinning at 500 rad/s
//! (`--set platform.angular_velocity=500`), whose steps shrink to 1e-10 s once it
//! lands at 3.53 s. Before the guard it took days (some 50 s of CPU a simulated
//! millisecond). Eight collinear feet, whose mode decision by enumeration found no
//! consistent contact force at 0.544 s and took seconds each time it was asked
//! again (months for the run), now finish: their decision is Lemke's method.
//! Each run here is bounded by [`LIMIT`] only to stop a hang, never timed.

use std::fs;
use std::path::PathBuf;
use std::time::Duration;

use serde_json::Value;

mod common;
use common::{finish_within, host_sim, reference_without_uncertainty, root, whole_csv};

/// A run that the guard fails to end is killed after this and the test fails.
const LIMIT: Duration = Duration::from_secs(600);

/// `host-sim args` from the repository root, bounded by [`LIMIT`].
fn run(args: &[&str]) -> common::Run {
    let mut cmd = host_sim();
    cmd.args(args).current_dir(root());
    finish_within(cmd, LIMIT)
}

/// A scratch path `name`.
fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-progress", name)
}

/// The reference machine standing on `feet` collinear feet: K1 and K2 where the
/// file has them, the others spread evenly between, alike
/// (`benchmarks/contacts_scaling.py`'s variants), written as `name`.
fn on_feet(feet: usize, name: &str) -> PathBuf {
    let text = reference_without_uncertainty();
    let (x1, x2) = (-0.08f64, 0.08f64);
    assert!(text.contains("point = [-0.08, 0.0]") && text.contains("point = [0.08, 0.0]"));
    // K1 and K2, kept, have the friction of the feet added.
    assert_eq!(
        text.matches(&format!("\nfriction = {FEET_FRICTION:?}\n"))
            .count(),
        2
    );
    let mut extra = String::new();
    for i in 1..feet - 1 {
        let x = x1 + (x2 - x1) * i as f64 / (feet - 1) as f64;
        extra += &format!(
            "[[contacts]]\nname = \"K{}\"\npoint = [{x:?}, 0.0]\nrestitution = 0.3\nfriction = {FEET_FRICTION:?}\nweight = 1.0\n\n",
            i + 2
        );
    }
    let at = text.find("[[rotors]]").expect("a [[rotors]] table");
    let path = scratch(name);
    fs::write(&path, format!("{}{extra}{}", &text[..at], &text[at..])).unwrap();
    path
}

/// The reference machine with `lines` added to its `[simulation]`, written as
/// `name`.
fn with_simulation(lines: &str, name: &str) -> PathBuf {
    let text = reference_without_uncertainty();
    assert!(text.contains("\n[simulation]\n"));
    let path = scratch(name);
    fs::write(
        &path,
        text.replace("\n[simulation]\n", &format!("\n[simulation]\n{lines}\n")),
    )
    .unwrap();
    path
}

/// The time a message's `at t = T s` names.
fn time_in(message: &str, after: &str) -> f64 {
    let rest = &message[message
        .find(after)
        .unwrap_or_else(|| panic!("{after:?} in {message}"))
        + after.len()..];
    rest.split(' ').next().unwrap().parse().unwrap()
}

#[test]
fn a_run_that_stops_advancing_ends_with_the_time_the_contacts_and_their_modes_its_files_whole() {
    let (trace, events) = (scratch("spin-trace.csv"), scratch("spin-events.csv"));
    let m = root().join("examples/vibro-driver.toml");
    let r = run(&[
        "run",
        m.to_str().unwrap(),
        "--command",
        "right",
        "--set",
        "platform.angular_velocity=500",
        "--out",
        trace.to_str().unwrap(),
        "--events",
        events.to_str().unwrap(),
    ]);
    assert_eq!(r.status, 1, "{}", r.stderr);
    assert!(r.stdout.is_empty(), "no summary: {}", r.stdout);
    assert!(
        r.stderr.starts_with("error: run: no progress at t = "),
        "{}",
        r.stderr
    );
    assert!(
        r.stderr.contains(": more than 100000 integrator steps and events within 1 ms of simulated time (simulation.progress_budget); contacts K1 open (gap "),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains(", K2 open (gap "), "{}", r.stderr);
    assert!(
        r.stderr
            .trim_end()
            .ends_with("; the files asked for hold the run up to there, no summary"),
        "{}",
        r.stderr
    );
    // Stopped where it stalled, after the landing (at 3.53 s), long before 10 s.
    let t = time_in(&r.stderr, "no progress at t = ");
    assert!((3.5..3.6).contains(&t), "{}", r.stderr);
    let last_impact = time_in(&r.stderr, "last event impact at t = ");
    assert!(last_impact <= t && last_impact > 3.5, "{}", r.stderr);
    // The trace up to the stop, its last row there; the events up to their last.
    let rows = whole_csv(&trace);
    let last: f64 = rows.last().unwrap()[0].parse().unwrap();
    assert!((last - t).abs() < 1e-9, "last row at {last}, stop at {t}");
    let events = whole_csv(&events);
    let impact: f64 = events.last().unwrap()[0].parse().unwrap();
    assert!((impact - last_impact).abs() < 1e-9);
}

/// `run MACHINE --command right --t-end T --format json` finishes: exit 0, a JSON
/// summary to `t_end`, and no step taken past an event. The summary.
fn closed_loop_finishes(m: &std::path::Path, t_end: f64, what: &str) -> Value {
    closed_loop_finishes_with(m, t_end, what, FEET_FRICTION, &[])
}

/// [`closed_loop_finishes`] with `extra` arguments, every impact in the cone of
/// the largest friction coefficient `mu` of the machine's feet.
fn closed_loop_finishes_with(
    m: &std::path::Path,
    t_end: f64,
    what: &str,
    mu: f64,
    extra: &[&str],
) -> Value {
    let t = t_end.to_string();
    let events = m.with_extension("events.csv");
    let mut args = vec![
        "run",
        m.to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        &t,
        "--events",
        events.to_str().unwrap(),
        "--format",
        "json",
    ];
    args.extend_from_slice(extra);
    let r = run(&args);
    assert_eq!(r.status, 0, "{what}: {}", r.stderr);
    impacts_inside_cones(&events, mu, what);
    let summary: Value = serde_json::from_str(&r.stdout).expect("a JSON summary");
    assert_eq!(summary["t_end"], t_end, "{what}: {}", r.stdout);
    // The warning is in the summary (and on stderr when the run is not JSON).
    assert!(
        !r.stderr.contains("no progress") && !r.stdout.contains("no progress"),
        "{what}: a step was taken past an event: {}{}",
        r.stderr,
        r.stdout
    );
    summary
}

/// The friction coefficient of every foot of the machines written here.
const FEET_FRICTION: f64 = 0.4;

/// Every impact of the events file `path` pushes and stays in its foot's friction
/// cone: `P_n >= 0` exactly and `|P_t| <= mu P_n` (to rounding). Many collinear
/// feet make the impact's contact system singular, and its solve used to accept
/// normal rates down to its tolerance: sixteen feet wrote 4 866 impacts of 18 025
/// rows with `P_n` down to -2.6e-11 N s, a foot that pulls.
fn impacts_inside_cones(path: &std::path::Path, mu: f64, what: &str) {
    let rows = whole_csv(path);
    let text = fs::read_to_string(path).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let (kind, pn, pt) = (
        col("kind"),
        col("normal_impulse"),
        col("tangential_impulse"),
    );
    let mut impacts = 0;
    for r in rows.iter().filter(|r| r[kind] == "impact") {
        let (p_n, p_t): (f64, f64) = (r[pn].parse().unwrap(), r[pt].parse().unwrap());
        assert!(p_n >= 0.0, "{what}: a foot pulls: {r:?}");
        assert!(
            p_t.abs() <= mu * p_n * (1.0 + 1e-12) + 1e-300,
            "{what}: outside the friction cone: {r:?}"
        );
        impacts += 1;
    }
    assert!(impacts > 0, "{what}: no impact in {}", path.display());
}

/// Eight collinear feet through 0.544 s, where their mode decision used to find
/// no consistent contact force after 40 000 candidates and the run stalled (the
/// guard ended it there, with `progress_budget` lowered to 30): the decision by
/// Lemke's method is bounded, and the run finishes at the default budget with its
/// summary and without a step taken past an event.
#[test]
fn eight_collinear_feet_pass_their_former_stall_and_finish() {
    closed_loop_finishes(&on_feet(8, "eight.toml"), 1.0, "eight feet");
}

/// Sixteen collinear feet through 0.576 s, where the run used to end by the
/// guard: the platform rocks about K2, the fifteen other feet hop in flights
/// shorter than a step (1.5e-4 s), so every step started with their gaps at
/// rounding size and ended below the fundament, and the gap's root was found
/// within 5e-14 s of the step's start (rounding there too), not at the landing
/// after the apex; the same event again at each step. The landing after the apex
/// is located, and the run finishes 1 s of the closed loop with its summary,
/// travelling right.
#[test]
fn sixteen_collinear_feet_pass_their_rocking_hops_and_finish() {
    let summary = closed_loop_finishes(&on_feet(16, "sixteen.toml"), 1.0, "sixteen feet");
    let v = summary["mean_velocity"].as_f64().expect("a mean velocity");
    assert!(v > 0.0, "not travelling right: {summary}");
    // The mechanism, not only the finish: the platform lands flat and all feet
    // strike at once, so sixteen collinear feet between the two make the two
    // feet's gait (benchmarks/plant.md: 33.300 against 33.302 mm/s over 10 s).
    let two = closed_loop_finishes(&on_feet(2, "two.toml"), 1.0, "two feet");
    let v2 = two["mean_velocity"].as_f64().expect("a mean velocity");
    assert!(
        (v / v2 - 1.0).abs() < 1e-3,
        "sixteen feet travel at {v} m/s, two at {v2} m/s"
    );
}

/// The reference machine on eight feet at `points` (platform frame at t = 0, m),
/// each with `restitution`, written as `name`: its two feet replaced.
fn on_points(points: &[[f64; 2]], restitution: f64, name: &str) -> PathBuf {
    let text = reference_without_uncertainty();
    let first = text.find("[[contacts]]").expect("a [[contacts]] table");
    let rotors = text.find("[[rotors]]").expect("a [[rotors]] table");
    let mut feet = String::new();
    for (i, p) in points.iter().enumerate() {
        feet += &format!(
            "[[contacts]]\nname = \"K{}\"\npoint = [{:?}, {:?}]\nrestitution = {restitution:?}\nfriction = {FEET_FRICTION:?}\n\n",
            i + 1,
            p[0],
            p[1]
        );
    }
    let path = scratch(name);
    fs::write(
        &path,
        format!("{}{feet}{}", &text[..first], &text[rotors..]),
    )
    .unwrap();
    path
}

/// Machines that ran past 300 s of CPU before the mode decision by Lemke's method
/// (issue 24), each with eight feet: at heights 0 to 7 mm in no order (not
/// collinear), in two coincident groups of four (the two feet of the file, each
/// four times), and collinear with restitution 1. Each finishes 2 s of the closed
/// loop with its summary, at the default progress budget, without a step taken
/// past an event, and travels (the platform neither through the floor nor tipped).
#[test]
fn degenerate_feet_finish_and_travel() {
    let x = |i: usize| -0.08 + 0.16 * i as f64 / 7.0;
    let heights = [0.0, 7.0, 1.0, 6.0, 2.0, 5.0, 3.0, 4.0];
    let uneven: Vec<[f64; 2]> = (0..8).map(|i| [x(i), 1e-3 * heights[i]]).collect();
    let pairs: Vec<[f64; 2]> = (0..8)
        .map(|i| [if i < 4 { -0.08 } else { 0.08 }, 0.0])
        .collect();
    let collinear: Vec<[f64; 2]> = (0..8).map(|i| [x(i), 0.0]).collect();
    for (name, points, restitution) in [
        ("uneven.toml", &uneven, 0.3),
        ("pairs.toml", &pairs, 0.3),
        ("elastic.toml", &collinear, 1.0),
    ] {
        let summary = closed_loop_finishes(&on_points(points, restitution, name), 2.0, name);
        assert!(
            summary["mean_velocity"].is_number(),
            "{name}: no travel: {summary}"
        );
    }
}

#[test]
fn a_step_size_underflow_ends_the_run_instead_of_holding_the_state() {
    // Fast decay at rtol 1e-12: the steps shrink below 1e-14 s at 1.4 us (the
    // winding's current meets a corner no event function marks). The run used to
    // hold the state to the end of the tick, warn, and give a summary.
    let m = root().join("examples/vibro-driver.toml");
    let r = run(&[
        "run",
        m.to_str().unwrap(),
        "--command",
        "right",
        "--set",
        "drive.decay=fast",
        "--set",
        "simulation.rtol=1e-12",
        "--t-end",
        "0.01",
    ]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert!(r.stdout.is_empty(), "{}", r.stdout);
    assert!(
        r.stderr.starts_with(
            "error: run: integrator step size underflow at t = 0.000001400 s: the next step, "
        ),
        "{}",
        r.stderr
    );
    assert!(
        r.stderr
            .contains(" s, is below 1e-14 s; contacts K1 stick, K2 stick; last event "),
        "{}",
        r.stderr
    );
}

#[test]
fn tune_and_calibrate_count_a_run_that_stops_advancing_as_no_travel_and_say_why() {
    // A budget below what the runs need (some 30 a millisecond) ends each early.
    let m = root().join("examples/vibro-driver.toml");
    let r = run(&[
        "tune",
        m.to_str().unwrap(),
        "--speeds",
        "3000:3000:250",
        "--offsets",
        "0:90:90",
        "--t-end",
        "1",
        "--set",
        "simulation.progress_budget=10",
        "--format",
        "json",
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).unwrap();
    let grid = v["grid"].as_array().unwrap();
    assert_eq!(grid.len(), 2);
    for p in grid {
        assert!(p["mean_velocity"].is_null(), "{p}");
        let why = p["not_a_travel"].as_str().unwrap();
        assert!(
            why.starts_with("no progress at t = ")
                && why.contains("more than 10 integrator steps and events"),
            "{why}"
        );
    }

    let measured = scratch("measured.csv");
    fs::write(
        &measured,
        "speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n",
    )
    .unwrap();
    let m = common::uncertain_machine("cli-progress", "\"contacts.*.friction\" = [0.2, 0.6]\n");
    let r = run(&[
        "calibrate",
        m.to_str().unwrap(),
        "--measured",
        measured.to_str().unwrap(),
        "--fit",
        "contacts.*.friction",
        "--set",
        "simulation.progress_budget=10",
        "--set",
        "simulation.t_end=1",
    ]);
    let all = r.stdout + &r.stderr;
    assert!(
        all.contains(
            "3000 rpm 90 deg: the simulated run was no travel at the fit (no progress at t = "
        ),
        "{all}"
    );
}

#[test]
fn a_scenario_whose_plant_stops_advancing_judges_nothing() {
    let m = with_simulation("", "spinning.toml");
    let text = fs::read_to_string(&m)
        .unwrap()
        .replace("angular_velocity = 0.0 ", "angular_velocity = 500.0 ");
    assert!(text.contains("angular_velocity = 500.0 "));
    fs::write(&m, text).unwrap();
    let s = scratch("spinning-scenario.toml");
    fs::write(
        &s,
        format!(
            "machine = '{}'\nt_end = 4.0\n\n[[commands]]\nt = 0.0\ncommand = \"right\"\nspeed_rpm = 3000\n\n[[expect]]\nkind = \"state\"\nstate = \"running\"\nwithin = [1.0, 4.0]\n",
            m.display()
        ),
    )
    .unwrap();
    let r = run(&["scenario", s.to_str().unwrap()]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert!(r.stdout.is_empty(), "{}", r.stdout);
    assert!(
        r.stderr
            .starts_with("error: scenario: no progress at t = 3.5"),
        "{}",
        r.stderr
    );
    assert!(
        r.stderr.trim_end().ends_with(": nothing judged"),
        "{}",
        r.stderr
    );
}

#[test]
fn device_sim_ends_when_its_plant_stops_advancing() {
    let m = with_simulation("progress_budget = 10", "budget-10.toml");
    let r = run(&[
        "device-sim",
        "--machine",
        m.to_str().unwrap(),
        "--listen",
        "tcp:127.0.0.1:0",
    ]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    // Within its first millisecond: the run needs more than 10 there.
    assert!(
        r.stderr
            .contains("error: device-sim: the machine's plant stopped: no progress at t = 0.000"),
        "{}",
        r.stderr
    );
    assert!(
        r.stderr
            .contains(": more than 10 integrator steps and events within 1 ms"),
        "{}",
        r.stderr
    );
}

/// A foot of [`hinged_feet_keep_pushing`]: name, body, point (m), restitution,
/// friction.
type Foot = (&'static str, &'static str, [f64; 2], f64, f64);

/// Two bodies hinged by a spring, on eight feet along one line (the layout of
/// `benchmarks/contacts_random.py --seed 9 --bodies 2`): the platform on K1 to K4,
/// a 0.5 kg sled on K5 to K8. At 0.5163 s the four standing feet go from stick to
/// slip together. Their equations then leave the normal forces undetermined (four
/// slipping feet on two bodies joined by a pin, on one line), and their
/// weighted minimum-norm split put K5, which the mode decision left at zero
/// force, at -0.563 N: below the lift-off threshold right after the decision, so
/// the same event came back at the same instant until a step was taken past it
/// (284 times in 10 s). Now a foot the decision leaves at the boundary opens where
/// closing it would make it pull, and the forces are split among every solution
/// of the modes' equations where the internal forces alone cannot keep every foot
/// pushing. Run to 2.8 s: at 2.7308 s, after an impact, the decision closed K4
/// slipping at +0.02 N, and the projection of the state onto the closed
/// contacts (the platform turned by 1e-6 rad to bring K4, 51 nm up, onto the
/// floor) put it at -0.26 N; the decision is now checked where it projects.
#[test]
fn two_hinged_bodies_on_feet_along_one_line_keep_every_foot_pushing() {
    let feet: [Foot; 8] = [
        ("K1", "platform", [-0.0429, 4.34e-06], 0.46, 0.21),
        ("K2", "platform", [-0.0415, 3.97e-06], 0.46, 0.34),
        ("K3", "platform", [-0.022, 0.0], 0.13, 0.24),
        ("K4", "platform", [0.0295, 0.0], 0.33, 0.78),
        ("K5", "sled", [0.1195, 0.0], 0.53, 0.58),
        ("K6", "sled", [0.1664, 0.0], 0.54, 0.8),
        ("K7", "sled", [0.1703, 2.74e-06], 0.13, 0.72),
        ("K8", "sled", [0.1923, 2.6e-05], 0.13, 0.68),
    ];
    hinged_feet_keep_pushing("two-bodies", &feet, 2500.0, 0.00162, 2.8);
}

/// The layout of `benchmarks/contacts_random.py --seed 6 --bodies 2`: the
/// platform on K1, K2 and the sled on K3 to K5, all four standing feet sticking
/// after 0.6016 s with K4's share of the load falling to zero. There no split of
/// the internal forces holds every cone, and the split of least violation was
/// sought coordinate by coordinate: it stopped at a corner with every foot 3.6 N
/// outside (K4 at -3.6 N in the row at the event), where one within 1e-8 N
/// existed an instant before. Now it is the solution of one strictly convex
/// problem ([`shared::impact::split`]), continuous in the state, so the event is
/// where the forces reach the threshold.
#[test]
fn hinged_feet_leaving_their_cones_together_leave_them_continuously() {
    let feet: [Foot; 5] = [
        ("K1", "platform", [-0.0604, 0.0], 0.26, 0.66),
        ("K2", "platform", [0.0822, 0.0], 0.24, 0.38),
        ("K3", "sled", [0.1068, 3.42e-07], 0.36, 0.36),
        ("K4", "sled", [0.1222, 0.0], 0.37, 0.22),
        ("K5", "sled", [0.1899, 0.0], 0.31, 0.37),
    ];
    hinged_feet_keep_pushing("cones-together", &feet, 159.0, 0.00684, 1.2);
}

/// The layout of `benchmarks/contacts_random.py --seed 19 --bodies 2`: six feet
/// on the platform, K3 and K4 1.3 mm apart, and the sled on K7, K8. Near
/// 0.569 s the platform's slipping feet share their load only along the
/// solutions of their modes' equations, whose matrix is there close to losing
/// two ranks: the null vector Gauss-Jordan elimination gave changed direction
/// between two states 1e-13 s apart, the forces jumped, and the lift-off was
/// found with K2 and K4 at -0.0022 N. Now the null space is the singular
/// vectors' (one-sided Jacobi), which move continuously.
#[test]
fn feet_sharing_along_a_nearly_twice_singular_system_lift_off_at_the_threshold() {
    let feet: [Foot; 8] = [
        ("K1", "platform", [-0.0913, 6.07e-07], 0.54, 0.4),
        ("K2", "platform", [-0.0593, 0.0], 0.33, 0.38),
        ("K3", "platform", [0.0782, 0.0], 0.33, 0.38),
        ("K4", "platform", [0.0795, 2.02e-08], 0.6, 0.63),
        ("K5", "platform", [0.089, 1.79e-07], 0.32, 0.24),
        ("K6", "platform", [0.0964, 3.17e-07], 0.33, 0.75),
        ("K7", "sled", [0.1445, 0.0], 0.29, 0.79),
        ("K8", "sled", [0.1818, 0.0], 0.26, 0.54),
    ];
    hinged_feet_keep_pushing("nearly-singular", &feet, 123.0, 0.951, 0.7);
}

/// The layout of `benchmarks/contacts_random.py --seed 30 --bodies 2`: at
/// 1.0474 s K1 strikes while K2 slips at a speed within the velocity tolerance of
/// zero. Ending that slip exactly (the least velocity change that zeroes it and
/// keeps the closed contacts' normal velocities) turned K1, open and just
/// bounced off at +12 mm/s, into a foot approaching at 3 mm/s; K1 then closed
/// with it and the decision left K2 at -1.6 N. Now the change keeps every
/// touching foot that it would make approach at its normal velocity too.
#[test]
fn a_slip_ended_beside_a_foot_that_just_struck_leaves_both_pushing() {
    let feet: [Foot; 4] = [
        ("K1", "platform", [-0.0136, 0.0], 0.58, 0.56),
        ("K2", "platform", [0.0488, 0.0], 0.47, 0.71),
        ("K3", "sled", [0.1321, 0.0], 0.41, 0.3),
        ("K4", "sled", [0.1916, 0.0], 0.4, 0.69),
    ];
    hinged_feet_keep_pushing("slip-ended", &feet, 154.0, 0.628, 1.2);
}

/// The reference machine on `feet` (the platform's and, with `sled`, a 0.5 kg
/// sled's hinged right of it by a spring of that stiffness, N m/rad, and
/// damping, N m s/rad), as `benchmarks/contacts_random.py` writes it; the file
/// `NAME.toml` in the scratch folder.
fn on_feet_of(name: &str, feet: &[Foot], sled: Option<(f64, f64)>) -> PathBuf {
    let text = reference_without_uncertainty();
    let first = text.find("[[contacts]]").expect("a [[contacts]] table");
    let rotors = text.find("[[rotors]]").expect("a [[rotors]] table");
    let mut tables = String::new();
    for (name, body, p, e, mu) in feet {
        tables += &format!(
            "[[contacts]]\nname = \"{name}\"\nbody = \"{body}\"\npoint = [{:?}, {:?}]\nrestitution = {e:?}\nfriction = {mu:?}\n\n",
            p[0], p[1]
        );
    }
    let sled = sled.map_or(String::new(), |(stiffness, damping)| format!("\n[[bodies]]\nname = \"sled\"\nmass = 0.5\ninertia = 4.5e-4\nposition = [0.155, 0.015]\n\n[[joints]]\nname = \"hitch\"\nkind = \"revolute\"\nbodies = [\"platform\", \"sled\"]\npoint = [0.1025, 0.015]\nstiffness = {stiffness:?}\ndamping = {damping:?}\n"));
    let path = scratch(&format!("{name}.toml"));
    fs::write(
        &path,
        format!("{}{tables}{}{sled}", &text[..first], &text[rotors..]),
    )
    .unwrap();
    path
}

/// The layout of `benchmarks/contacts_random.py --seed 1 --bodies 1`: K3 and K4
/// 1.8 mm apart and level within 0.54 um. At 0.9096 s they land together at
/// 0.115 m/s, and the impulse path chatters between their friction states
/// beyond the solver's 256 pieces: the impact was left unsolved, the contacts
/// kept approaching, and the run stepped past the event (22 um into the floor).
/// Now such an impact is solved as one complementarity problem at velocity
/// level and reported. Checked: the run finishes without a step past an event,
/// the warning names the instant, and each foot of that impact ends as
/// Newton's law says: no impulse and separating at least at `e` times its
/// approach, or an impulse and exactly that.
#[test]
fn an_impact_whose_impulse_path_chatters_is_solved_at_velocity_level() {
    let feet: [Foot; 4] = [
        ("K1", "platform", [-0.0797, 2.51e-06], 0.19, 0.61),
        ("K2", "platform", [-0.0718, 0.0], 0.22, 0.35),
        ("K3", "platform", [0.0173, 0.0], 0.18, 0.39),
        ("K4", "platform", [0.0191, 5.36e-07], 0.32, 0.31),
    ];
    let path = on_feet_of("chatter", &feet, None);
    let summary = closed_loop_finishes_with(&path, 1.0, "chatter", 0.61, &[]);
    let warnings = summary["warnings"].to_string();
    assert!(
        warnings.contains("solved at velocity level") && !warnings.contains("not solved"),
        "{warnings}"
    );
    let rows: Vec<Vec<String>> = whole_csv(&path.with_extension("events.csv"))
        .into_iter()
        .filter(|r| r[8] == "velocity level")
        .collect();
    assert!(rows.len() >= 2, "{rows:?}");
    for r in &rows {
        let e = feet.iter().find(|f| f.0 == r[2]).unwrap().3;
        let (before, after, p_n): (f64, f64, f64) = (
            r[3].parse().unwrap(),
            r[4].parse().unwrap(),
            r[5].parse().unwrap(),
        );
        let target = -e * before;
        let tol = 1e-6 * before.abs();
        if p_n > 0.0 {
            assert!((after - target).abs() <= tol, "{r:?}");
        } else {
            assert!(after >= target - tol, "{r:?}");
        }
    }
}

/// The platform on `feet` with a 0.5 kg sled hinged right of it by a spring of
/// `stiffness` (N m/rad) and `damping` (N m s/rad), as
/// `benchmarks/contacts_random.py` writes it, run closed loop for `t_end` s.
/// Checked: the run finishes without a step past an event, every impact in its
/// cone, and no closed foot pulls below the lift-off threshold `-eps_F` in any
/// trace row, the rows written at events included (the one before an event has
/// the old modes' forces at the event, where they are continuous: at the
/// threshold, not beyond it).
fn hinged_feet_keep_pushing(name: &str, feet: &[Foot], stiffness: f64, damping: f64, t_end: f64) {
    let path = on_feet_of(name, feet, Some((stiffness, damping)));
    let trace = path.with_extension("trace.csv");
    let mu_most = feet.iter().map(|f| f.4).fold(0.0, f64::max);
    closed_loop_finishes_with(
        &path,
        t_end,
        name,
        mu_most,
        &["--out", trace.to_str().unwrap()],
    );
    let text = fs::read_to_string(&trace).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let forces: Vec<usize> = (0..header.len())
        .filter(|&c| header[c].starts_with("fn_"))
        .collect();
    assert_eq!(forces.len(), feet.len(), "{header:?}");
    // eps_F: Settings::force_tolerance, 1e-6, of the machine's weight; 1 % more
    // for the lift-off's location.
    let weight = (2.02 + 0.5) * 9.81;
    let eps_f = 1e-6 * weight;
    let rows = whole_csv(&trace);
    for row in &rows {
        for &c in &forces {
            let f: f64 = row[c].parse().unwrap();
            assert!(
                f >= -1.01 * eps_f,
                "{name}: t = {}: {} = {f} N",
                row[0],
                header[c]
            );
        }
    }
    assert!(
        rows.len() as f64 > 900.0 * t_end,
        "{name}: {} rows",
        rows.len()
    );
}
