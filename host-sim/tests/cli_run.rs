//! `host-sim run` through the real binary: the documented JSON summary, the trace and
//! events CSV headers, the plot, determinism, and clear refusals (exit 2, no panic)
//! for bad files and options.

use std::path::PathBuf;

use serde_json::Value;

mod common;
use common::{keys, machine, run, run_machine};
use host_sim::run::report::{FINAL_KEYS, SUMMARY_KEYS};

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-run", name)
}

#[test]
fn json_summary_has_the_documented_keys_in_order() {
    let r = run_machine(
        "run",
        &["--open-loop", "12,12", "--t-end", "0.5", "--format", "json"],
    );
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    assert_eq!(keys(&v), SUMMARY_KEYS);
    assert_eq!(keys(&v["final"]), FINAL_KEYS);
    assert_eq!(v["state"], "open-loop");
    assert_eq!(v["t_end"], 0.5);
    assert_eq!(v["phase_error_deg_rms"], 0.0);
    // Both motors at 12 V spin up in their driven sense.
    for k in 0..2 {
        assert!(v["rotor_speed_rpm"][k].as_f64().unwrap() > 1000.0, "{v}");
    }
}

/// The reference machine open loop at 12 V for 0.4 s, writing the trace, the
/// events and the plot to scratch files named after `tag`: their paths.
fn open_loop_files(tag: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (out, events, plot) = (
        scratch(&format!("{tag}-t.csv")),
        scratch(&format!("{tag}-e.csv")),
        scratch(&format!("{tag}-p.svg")),
    );
    let r = run_writing("12,12", "0.4", [&out, &events, &plot]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    (out, events, plot)
}

/// An open-loop run of the reference machine (`--open-loop volts`, `--t-end`)
/// writing its trace, events and plot to `files`.
fn run_writing(volts: &str, t_end: &str, files: [&PathBuf; 3]) -> common::Run {
    let [out, events, plot] = files.map(|f| f.to_str().unwrap());
    run_machine(
        "run",
        &[
            "--open-loop",
            volts,
            "--t-end",
            t_end,
            "--out",
            out,
            "--events",
            events,
            "--plot",
            plot,
        ],
    )
}

#[test]
fn files_are_written_with_the_documented_headers() {
    let (out, events, plot) = open_loop_files("headers");
    let trace = std::fs::read_to_string(&out).unwrap();
    assert!(trace.starts_with(
        "t,x,y,angle,vx,vy,omega,phi1,phi2,omega1,omega2,i1,i2,duty1,duty2,fn_K1,ft_K1,fn_K2,ft_K2\n"
    ));
    // One row per output step (1 ms) at least, times non-decreasing.
    let times: Vec<f64> = trace
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert!(times.len() >= 401, "{} rows", times.len());
    assert!(times.windows(2).all(|w| w[1] >= w[0]));
    let ev = std::fs::read_to_string(&events).unwrap();
    assert!(ev.starts_with(
        "t,kind,contact,normal_velocity_before,normal_velocity_after,normal_impulse,tangential_impulse,case,detail,body,against\n"
    ));
    assert!(
        (ev.contains(",impact,K1,") || ev.contains(",impact,K2,"))
            && ev.contains(",platform,fundament\n"),
        "{ev}"
    );
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
}

/// The trace's contact forces (`fn_<name>`, `ft_<name>`). At t = 0 the machine
/// stands at rest on both feet with no current yet (the winding's inductance) and
/// both eccentrics along +x: the platform is held, and each eccentric starts to
/// fall about its axis, `psi'' = -m g e / (I + m e^2)`, so the feet carry the
/// weight less the eccentrics' downward acceleration `e |psi''|`:
/// `fn_K1 + fn_K2 = g (M_tot - sum m^2 e^2 / (I + m e^2))`, without friction.
/// While it hops, a closed foot is never pulled beyond the force tolerance
/// `eps_F` (1e-6 of the weight), an open one has no force, and no foot's friction
/// leaves its cone (`|ft| <= 0.4 fn`) by more: the row just before a lift-off or
/// a slip event shows the force at the event's threshold, `eps_F` past the
/// boundary, to the event location's error (1 % of `eps_F` allowed).
#[test]
fn trace_has_contact_forces_that_never_pull() {
    let (out, _, _) = open_loop_files("forces");
    let trace = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = trace
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    let (g, m, e, i) = (9.81, 0.01, 0.02, 6e-6);
    let weight = 2.02 * g;
    let held = g * (2.02 - 2.0 * m * m * e * e / (i + m * e * e));
    let first = &rows[0];
    assert!(
        (first[15] + first[17] - held).abs() < 1e-9 * weight,
        "{first:?}"
    );
    assert!(
        first[16].abs() < 1e-12 && first[18].abs() < 1e-12,
        "{first:?}"
    );
    let tolerance = 1.01e-6 * weight;
    let (mut loaded, mut free) = (0, 0);
    for row in &rows {
        for (fn_, ft) in [(row[15], row[16]), (row[17], row[18])] {
            assert!(fn_ >= -tolerance, "a foot pulls: {row:?}");
            assert!(
                ft.abs() <= 0.4 * fn_.max(0.0) + tolerance,
                "outside its cone: {row:?}"
            );
            if fn_ > 0.0 {
                loaded += 1;
            } else if ft == 0.0 {
                free += 1;
            }
        }
    }
    assert!(loaded > 100 && free > 100, "{loaded} loaded, {free} free");
}

#[test]
fn same_file_and_seed_give_identical_output() {
    let args = ["--open-loop", "12,11", "--t-end", "0.6", "--format", "json"];
    let a = run_machine("run", &args);
    let b = run_machine("run", &args);
    assert_eq!(a.status, 0);
    assert_eq!(a.stdout, b.stdout);
}

#[test]
fn bad_options_are_refused_with_exit_2() {
    let m = machine();
    let m = m.to_str().unwrap();
    let r = run(&["run", m, "--open-loop", "12"]);
    r.refused("--open-loop 12: 1 voltage for a machine with 2 rotors");
    assert!(r.stderr.contains("coast"), "{}", r.stderr);
    let r = run(&["run", m, "--open-loop", "12,a"]);
    r.refused("'12,a' for '--open-loop");
    assert!(r.stderr.contains("coast"), "{}", r.stderr);
    let r = run(&["run", m]);
    r.refused("--open-loop");
    let r = run(&["run", m, "--open-loop", "coast", "--t-end", "-1"]);
    r.refused("--t-end");
    let r = run(&[
        "run",
        m,
        "--open-loop",
        "coast",
        "--set",
        "contacts.K9.friction=0.2",
    ]);
    r.refused("K9");
}

#[test]
fn bad_machine_file_names_the_key() {
    let f = scratch("bad.toml");
    let text = std::fs::read_to_string(machine())
        .unwrap()
        .replace("friction = 0.4", "friction = -0.4");
    std::fs::write(&f, text).unwrap();
    let r = run(&["run", f.to_str().unwrap(), "--open-loop", "coast"]);
    r.refused("contacts[0].friction");
}

#[test]
fn unwritable_output_is_refused_and_nothing_is_left() {
    let target = scratch("no-such-dir").join("t.csv");
    let r = run_machine(
        "run",
        &[
            "--open-loop",
            "coast",
            "--t-end",
            "0.05",
            "--out",
            target.to_str().unwrap(),
        ],
    );
    r.refused(&format!(
        "error: --out: cannot write {}: ",
        target.display()
    ));
    assert!(!target.exists());
}

/// Defect: with one output unwritable, the others were written before the refusal.
/// Now every path is checked and staged first: exit 2, nothing left behind.
#[test]
fn one_unwritable_output_leaves_none_of_the_others() {
    let dir = scratch("set");
    std::fs::create_dir_all(&dir).unwrap();
    let (out, events) = (dir.join("ok.csv"), dir.join("ev.csv"));
    let plot = dir.join("UNWRITABLE").join("p.svg");
    let r = run_writing("coast", "0.05", [&out, &events, &plot]);
    assert_eq!(r.status, 2, "{}", r.stderr);
    assert!(
        r.stderr
            .contains(&format!("error: --plot: cannot write {}: ", plot.display())),
        "{}",
        r.stderr
    );
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

/// Defect: a symbolic link was replaced by a regular file (its target untouched),
/// and `/dev/null` could not be written by a user (the rename needs /dev).
#[test]
fn outputs_follow_links_and_write_through_special_files() {
    let dir = scratch("links");
    std::fs::create_dir_all(&dir).unwrap();
    let real = dir.join("real.csv");
    std::fs::write(&real, "old").unwrap();
    let link = dir.join("link.csv");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let base = ["--open-loop", "coast", "--t-end", "0.05"];
    let mut args = base.to_vec();
    args.extend(["--out", link.to_str().unwrap(), "--events", "/dev/null"]);
    let r = run_machine("run", &args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let meta = std::fs::symlink_metadata(&link).unwrap();
    assert!(meta.file_type().is_symlink(), "the link was replaced");
    assert!(std::fs::read_to_string(&real).unwrap().starts_with("t,x,y"));
    // `-`: the trace on stdout, then the summary.
    let mut args = base.to_vec();
    args.extend(["--out", "-", "--format", "json"]);
    let r = run_machine("run", &args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(r.stdout.starts_with("t,x,y"), "{}", &r.stdout[..80]);
    assert!(r.stdout.contains("\"mean_velocity\""));
}

/// Defect: `--speed -3000` was taken for an option `-3` and the message did not
/// name `--speed`.
#[test]
fn a_negative_speed_is_refused_naming_the_option() {
    let r = run_machine("run", &["--command", "right", "--speed", "-3000"]);
    r.refused("--speed -3000");
}

/// `--out /dev/stdout` with stdout redirected to a file, and `--out FILE` naming
/// that same file: the trace then the summary, in order, through the one stream
/// (opening the file again would write over it from its start); the link in /dev
/// stays a link.
#[test]
fn an_output_naming_stdout_goes_through_stdout() {
    let m = machine();
    let file = scratch("own-stdout.txt");
    for out in ["/dev/stdout", file.to_str().unwrap()] {
        let link_before = std::fs::symlink_metadata("/dev/stdout")
            .ok()
            .map(|m| m.file_type());
        let sink = std::fs::File::create(&file).unwrap();
        let mut cmd = common::host_sim();
        cmd.args([
            "run",
            m.to_str().unwrap(),
            "--open-loop",
            "coast",
            "--t-end",
            "0.05",
            "--out",
            out,
            "--format",
            "json",
        ])
        .stdout(sink);
        let status = cmd.status().unwrap();
        assert!(status.success());
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(text.starts_with("t,x,y,"), "{out}: {}", &text[..40]);
        let json = text.find("\n{").expect("the summary follows the trace");
        assert!(text[json..].contains("\"mean_velocity\""));
        let link_after = std::fs::symlink_metadata("/dev/stdout")
            .ok()
            .map(|m| m.file_type());
        assert_eq!(link_before, link_after, "/dev/stdout was replaced");
    }
}

/// `--out - | head`: a reader that goes away is not an error worth a message.
#[test]
fn a_closed_pipe_on_stdout_is_not_an_error() {
    let m = machine();
    let mut child = common::host_sim()
        .args([
            "run",
            m.to_str().unwrap(),
            "--open-loop",
            "coast",
            "--t-end",
            "0.5",
            "--out",
            "-",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("error"), "{stderr}");
}

/// A further body gets its own trace columns after the platform's.
#[test]
fn a_further_body_is_traced_in_its_own_columns() {
    // A free body that touches nothing: it falls, y = y0 - g t^2 / 2, while the
    // machine runs beside it.
    let text = std::fs::read_to_string(machine()).unwrap()
        + "\n[[bodies]]\nname = \"element\"\nmass = 0.05\ninertia = 2e-5\nposition = [0.1, 0.2]\n";
    let file = scratch("bodies.toml");
    std::fs::write(&file, text).unwrap();
    let out = scratch("bodies.csv");
    let r = run(&[
        "run",
        file.to_str().unwrap(),
        "--open-loop",
        "12,12",
        "--t-end",
        "0.1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let trace = std::fs::read_to_string(&out).unwrap();
    let header: Vec<&str> = trace.lines().next().unwrap().split(',').collect();
    let tail = &header[header.len() - 6..];
    assert_eq!(
        tail,
        [
            "x_element",
            "y_element",
            "angle_element",
            "vx_element",
            "vy_element",
            "omega_element"
        ]
    );
    let last: Vec<f64> = trace
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let (t, y, vy) = (last[0], last[last.len() - 5], last[last.len() - 2]);
    assert!((t - 0.1).abs() < 1e-12, "t = {t}");
    assert!((y - (0.2 - 9.81 * t * t / 2.0)).abs() < 1e-9, "y = {y}");
    assert!((vy + 9.81 * t).abs() < 1e-9, "vy = {vy}");
}

/// The controller in the loop of a machine whose rotors' angles are not the 4th
/// and 5th coordinates: an arm hinged to the platform on a spring comes before
/// them (x, y, theta, theta_arm, phi_1, phi_2). The encoders read each rotor's own
/// angle: the speeds are held and the phase loop locks, with no fault (reading
/// the arm's angle as rotor 1's, the controller latched an encoder fault).
#[test]
fn the_controller_reads_the_rotors_behind_a_further_body() {
    let text = std::fs::read_to_string(machine()).unwrap()
        + "\n[[bodies]]\nname = \"arm\"\nmass = 0.05\ninertia = 2e-5\nposition = [0.05, 0.1]\n\n[[joints]]\nname = \"hinge\"\nkind = \"revolute\"\nbodies = [\"platform\", \"arm\"]\npoint = [0.05, 0.06]\nstiffness = 5.0\ndamping = 0.01\n";
    let file = scratch("arm.toml");
    std::fs::write(&file, text).unwrap();
    std::fs::copy(
        common::root().join("examples/vibro-driver.tuning.toml"),
        scratch("vibro-driver.tuning.toml"),
    )
    .unwrap();
    let r = run(&[
        "run",
        file.to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        "2",
        "--format",
        "json",
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(v["faults"], serde_json::json!([]), "{v}");
    assert_eq!(v["state"], "running", "{v}");
    for k in 0..2 {
        let rpm = v["rotor_speed_rpm"][k].as_f64().unwrap();
        assert!((rpm - 3000.0).abs() < 30.0, "rotor {}: {rpm} rpm", k + 1);
    }
    let err = v["phase_error_deg_rms"].as_f64().unwrap();
    assert!(err < 5.0, "phase error {err} deg RMS");
}

/// In fast decay the winding's current dies behind the diodes in every PWM period
/// (discontinuous conduction at 3 V): that is an event of the winding only, located
/// but with no trace rows and no contact decision. The trace has its regular rows
/// and two per event of the events file, not two per PWM period (it had 16 202
/// rows for these 0.2 s).
#[test]
fn a_dying_coast_current_takes_no_trace_rows() {
    let (out, events) = (scratch("coast-t.csv"), scratch("coast-e.csv"));
    let r = run_machine(
        "run",
        &[
            "--open-loop",
            "3,3",
            "--set",
            "drive.decay=fast",
            "--t-end",
            "0.2",
            "--out",
            out.to_str().unwrap(),
            "--events",
            events.to_str().unwrap(),
        ],
    );
    assert_eq!(r.status, 0, "{}", r.stderr);
    let rows = std::fs::read_to_string(&out).unwrap().lines().count() - 1;
    let event_rows = std::fs::read_to_string(&events).unwrap().lines().count() - 1;
    // 201 regular rows (0 to 0.2 s every 1 ms), two per event at most.
    assert!(
        rows <= 201 + 2 * event_rows,
        "{rows} rows, {event_rows} events"
    );
}

/// `[simulation].rtol` reaches the integrator: a looser tolerance gives other
/// numbers (not the default's to the bit) that agree with the default's to the
/// integration's accuracy (measured: the mean velocity 2e-6 of itself apart at
/// 1e-5 and 8e-6 at 1e-3, the loosest allowed; the impacts the same); outside
/// [1e-12, 1e-3] it is refused. The run holds 81.1 degrees, the offset this was
/// measured at, rather than the shipped table's, which moves with the plant: the
/// impact count is not the same at every point (at 90 degrees, 3 s, 1e-3 counts
/// 2459 impact instants against 2460 at 1e-8).
#[test]
fn the_integrators_tolerance_is_a_machine_key() {
    let m = machine();
    let summary = |rtol: &str| {
        let r = run(&[
            "run",
            m.to_str().unwrap(),
            "--command",
            "right",
            "--offset",
            "81.1",
            "--t-end",
            "3",
            "--format",
            "json",
            "--set",
            &format!("simulation.rtol={rtol}"),
        ]);
        assert_eq!(r.status, 0, "{}", r.stderr);
        serde_json::from_str::<serde_json::Value>(&r.stdout).unwrap()
    };
    let fine = summary("1e-8");
    let v = |s: &serde_json::Value| s["mean_velocity"].as_f64().unwrap();
    for rtol in ["1e-5", "1e-3"] {
        let loose = summary(rtol);
        assert_ne!(
            v(&fine).to_bits(),
            v(&loose).to_bits(),
            "rtol {rtol} ignored"
        );
        assert!(
            (v(&fine) - v(&loose)).abs() < 1e-4 * v(&fine).abs(),
            "rtol {rtol}: {} against {}",
            v(&fine),
            v(&loose)
        );
        assert_eq!(fine["impacts"], loose["impacts"], "rtol {rtol}");
    }
    let r = run(&["run", m.to_str().unwrap(), "--set", "simulation.rtol=1e-2"]);
    r.refused("simulation.rtol: must be in [1e-12, 0.001] (got 0.01)");
}

/// Two outputs streamed into one stream would interleave their lines: refused
/// before the run, exit 2, nothing written.
#[test]
fn two_outputs_into_one_stream_are_refused() {
    let m = machine();
    for (out, events) in [("-", "-"), ("/dev/stdout", "-")] {
        let r = run(&[
            "run",
            m.to_str().unwrap(),
            "--command",
            "right",
            "--t-end",
            "0.1",
            "--out",
            out,
            "--events",
            events,
        ]);
        r.refused(&format!(
            "error: --events: cannot write -: `--out {out}` writes to that stream already: give each output its own stream"
        ));
        assert!(r.stdout.is_empty(), "{}", r.stdout);
    }
}

/// A controller that cannot be built (its tuning table does not parse) is refused
/// before any output is opened: not a trace header on stdout first.
#[test]
fn a_bad_tuning_table_writes_nothing() {
    let dir = scratch("bad-table");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bad.toml"), "garbage = [").unwrap();
    let text = std::fs::read_to_string(machine()).unwrap().replace(
        "tuning_table = \"vibro-driver.tuning.toml\"",
        "tuning_table = \"bad.toml\"",
    );
    let file = dir.join("m.toml");
    std::fs::write(&file, text).unwrap();
    let r = run(&[
        "run",
        file.to_str().unwrap(),
        "--command",
        "right",
        "--out",
        "-",
    ]);
    r.refused("bad.toml:1:12: TOML syntax");
    assert!(r.stdout.is_empty(), "{}", r.stdout);
}

/// Issue 23: the reference machine without its right foot
/// (`tests/fixtures/one-foot-machine.toml`) tips over and sinks through the floor;
/// the summary printed "mean velocity -13.4 mm/s" and "warnings: none". Now the
/// table and the JSON give no travel, say why, and the warnings say what went
/// through, where first and how deep.
#[test]
fn a_machine_through_the_floor_has_no_travel() {
    let one_foot = common::root().join("tests/fixtures/one-foot-machine.toml");
    let one_foot = one_foot.to_str().unwrap();
    // The command docs/cli-run.md shows, and the lines it quotes.
    let r = run(&["run", one_foot, "--command", "right"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let t = &r.stdout;
    for quoted in [
        "mean velocity (second half)              not a travel",
        "distance                                 not a travel",
        "final angle                   -1.97317 (-113.055 deg)  rad",
        "  - platform went through the fundament (only contact points meet it): first the lowest point of rotor \"right\"'s eccentric circle, more than 1 mm below at t = 0.053 s; deepest 134.018 mm below (the lowest point of rotor \"right\"'s eccentric circle, t = 6.002 s)",
        "  - platform tipped over: first turned more than simulation.max_tilt = 60 deg from its angle at t = 0 at t = 0.166 s; furthest -171.898 deg (t = 0.394 s)",
    ] {
        assert!(t.lines().any(|l| l == quoted), "no line {quoted:?} in\n{t}");
    }
    let line = |start: &str| {
        t.lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no {start} line in\n{t}"))
    };
    assert_eq!(
        t.lines().nth(1),
        Some("not a travel: platform went through the fundament at t = 0.053 s (the warnings say more)"),
        "{t}"
    );
    assert!(line("mean velocity").ends_with("not a travel"), "{t}");
    assert!(line("distance").ends_with("not a travel"), "{t}");
    assert!(!t.contains("warnings: none"), "{t}");

    let r = run(&[
        "run",
        one_foot,
        "--command",
        "right",
        "--t-end",
        "1",
        "--format",
        "json",
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    assert_eq!(keys(&v), SUMMARY_KEYS);
    assert!(
        v["mean_velocity"].is_null() && v["distance"].is_null(),
        "{v}"
    );
    assert_eq!(
        v["not_a_travel"],
        "platform went through the fundament at t = 0.053 s"
    );
    assert_eq!(v["warnings"].as_array().unwrap().len(), 2, "{v}");
    // The final state is still the run's: the platform lies below the floor.
    assert!(v["final"]["position"][1].as_f64().unwrap() < -0.05, "{v}");

    // The reference machine, on both feet: a travel, `not_a_travel` null.
    let r = run_machine(
        "run",
        &["--command", "right", "--t-end", "1", "--format", "json"],
    );
    let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    assert!(v["mean_velocity"].as_f64().unwrap() > 0.01, "{v}");
    assert!(v["not_a_travel"].is_null(), "{v}");
    assert_eq!(v["warnings"], serde_json::json!([]));
}
