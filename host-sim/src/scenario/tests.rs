//! Tests of the module's stages together.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use shared::controller::{Command, Direction};

use super::file::*;
use super::judge::*;
use super::*;

/// The directory of the reference machine.
fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples")
}

/// A problem's line as the user reads it.
fn said(p: &crate::machine::input::Problem) -> String {
    crate::machine::input::error_line(p).trim_end().to_string()
}

/// A scenario on the reference machine with `body` appended.
fn parse(body: &str) -> Result<Scenario, Vec<String>> {
    let text = format!("machine = \"vibro-driver.toml\"\n{body}");
    from_text("s.toml", &text, &examples()).map_err(|ps| ps.iter().map(said).collect())
}

#[test]
fn a_scenario_reads_with_its_defaults() {
    let s = parse(
        "[[commands]]\nt = 1.0\ncommand = \"hold\"\noffset_deg = -90\n\
         [[commands]]\nt = 0.0\ncommand = \"left\"\n\
         [[faults]]\nt = 2.0\nkind = \"current_offset\"\nrotor = 2\namps = -1.5\nduration = 0.5\n\
         [[expect]]\nkind = \"safe\"\nfrom = 9.0\n\
         [[expect]]\nkind = \"travel\"\ndirection = \"left\"\nbetween = [1.0, 2.0]\n",
    )
    .unwrap();
    // t_end and the speed from the machine; commands in time order.
    assert_eq!(s.t_end, 10.0);
    assert_eq!(s.commands[0].name, "left");
    assert_eq!(
        s.commands[0].command,
        Command::Travel {
            direction: Direction::Left,
            speed_rpm: 3000.0
        }
    );
    assert_eq!(
        s.commands[1].command,
        Command::HoldOffset {
            speed_rpm: 3000.0,
            offset_deg: 270.0
        }
    );
    assert_eq!(s.faults[0].until, Some(2.5));
    assert_eq!(
        s.faults[0].fault,
        InjectedFault::CurrentOffset {
            rotor: 1,
            amps: -1.5
        }
    );
    assert_eq!(
        s.expectations[0].1,
        Expectation::Safe {
            between: [9.0, 10.0]
        }
    );
    assert_eq!(
        s.expectations[1].1,
        Expectation::Travel {
            direction: Direction::Left,
            between: [1.0, 2.0],
            min_speed: DEFAULT_MIN_TRAVEL_SPEED
        }
    );
}

#[test]
fn every_problem_is_reported_with_its_key_path() {
    let e = parse(
        "t_end = 2.0\nset = [\"simulation.seed=2\"]\n\
         [[commands]]\nt = 0.0\ncommand = \"rigth\"\n\
         [[commands]]\nt = 0.5\ncommand = \"stop\"\n\
         [[commands]]\nt = 0.4996\ncommand = \"reset\"\n\
         [[commands]]\nt = 3.0\ncommand = \"heartbeat\"\n\
         [[faults]]\nt = 1.0\nkind = \"encodr\"\n\
         [[faults]]\nt = 1.0\nknd = \"estop\"\n\
         [[expect]]\nkind = \"fault\"\nfault = \"encoder\"\nwithin = [1.0, 5.0]\n\
         [[expect]]\nkind = \"state\"\nstate = \"idle\"\n\
         [[expect]]\nkind = \"travel\"\ndirection = \"up\"\nbetween = [1.0, 1.0]\n",
    )
    .unwrap_err();
    let expected = [
        "s.toml: commands[0].command: unknown value \"rigth\"; did you mean \"right\"?",
        "s.toml: faults[0].kind: unknown value \"encodr\"; did you mean \"encoder_dropout\"?",
        "s.toml: faults[1].kind: missing",
        "s.toml: faults[1].knd: unknown key; did you mean `kind`?",
        "s.toml: expect[1]: missing `within = [t0, t1]`",
        "s.toml: expect[2].direction: unknown value \"up\"",
        "s.toml: expect[2].between: must be [t0, t1] with t0 < t1",
        "s.toml: commands[2].t: 0.4996 s falls on the same control tick as commands[1].t = 0.5 s",
        "s.toml: commands[3].t: must be before the end, t_end = 2 s (got 3)",
        "s.toml: expect[0].within: must lie within the run, [0, 2] s",
    ];
    for x in expected {
        assert!(e.iter().any(|l| l.contains(x)), "missing {x:?} in {e:#?}");
    }
    assert_eq!(e.len(), expected.len(), "{e:#?}");
}

#[test]
fn a_scenario_needs_a_machine_and_an_expectation() {
    let e = from_text("s.toml", "t_end = 1\n", &examples()).unwrap_err();
    let e: Vec<String> = e.iter().map(said).collect();
    assert!(e[0].contains("machine: missing"), "{e:?}");
    assert!(e[1].contains("expect: is missing"), "{e:?}");
    let e = parse("[[expect]]\nkind = \"no_fault\"\n").map(|_| ());
    assert!(e.is_ok(), "{e:?}");
    let e = from_text(
        "s.toml",
        "machine = \"none.toml\"\n[[expect]]\nkind = \"no_fault\"\n",
        &examples(),
    )
    .unwrap_err();
    assert!(said(&e[0]).contains("machine: no such file"), "{e:?}");
}

#[test]
fn an_injection_holds_from_its_tick_to_its_end() {
    let f = Injection {
        t: 2.0,
        until: Some(2.5),
        fault: InjectedFault::Estop,
        key: "faults[0]".into(),
    };
    assert!(!f.active(1.999));
    assert!(f.active(2000.0 / 1000.0));
    assert!(f.active(2.499));
    assert!(!f.active(2500.0 / 1000.0));
    let forever = Injection { until: None, ..f };
    assert!(forever.active(1e9));
}

#[test]
fn phase_ranges_are_circular() {
    assert!(in_phase_range(355.0, [350.0, 370.0]));
    assert!(in_phase_range(5.0, [350.0, 370.0]));
    assert!(!in_phase_range(15.0, [350.0, 370.0]));
    assert!(in_phase_range(90.0, [80.0, 100.0]));
    assert!(!in_phase_range(270.0, [80.0, 100.0]));
}

#[test]
fn x_is_interpolated_between_samples() {
    let s = [(0.0, 0.0), (1.0, 2.0), (2.0, 2.0)];
    assert_eq!(x_at(&s, 0.5), 1.0);
    assert_eq!(x_at(&s, 1.0), 2.0);
    assert_eq!(x_at(&s, 5.0), 2.0);
    assert_eq!(x_at(&s, -1.0), 0.0);
}

/// Each expectation's verdict and what was measured.
fn measured(r: &Report) -> Vec<(bool, &str)> {
    r.outcomes
        .iter()
        .map(|o| (o.pass, o.measured.as_str()))
        .collect()
}

/// Expectations of every kind that this short run breaks, and some it keeps:
/// each is judged, none panics, and the failures say what was measured.
#[test]
fn every_kind_of_expectation_can_fail() {
    let s = parse(
        "t_end = 1.0\n\
         [[commands]]\nt = 0.0\ncommand = \"right\"\n\
         [[faults]]\nt = 0.9\nkind = \"estop\"\n\
         [[expect]]\nkind = \"state\"\nstate = \"running\"\nwithin = [0.0, 0.5]\n\
         [[expect]]\nkind = \"state\"\nstate = \"starting\"\nbetween = [0.0, 0.8]\n\
         [[expect]]\nkind = \"travel\"\ndirection = \"left\"\nbetween = [0.8, 0.9]\n\
         [[expect]]\nkind = \"speed\"\nrotor = 2\nrange_rpm = [2900, 3100]\nbetween = [0.1, 0.2]\n\
         [[expect]]\nkind = \"phase\"\nrange_deg = [170, 190]\nbetween = [0.0, 0.1]\n\
         [[expect]]\nkind = \"fault\"\nfault = \"stall\"\nwithin = [0.0, 1.0]\n\
         [[expect]]\nkind = \"no_fault\"\n\
         [[expect]]\nkind = \"safe\"\nfrom = 0.5\n\
         [[expect]]\nkind = \"fault\"\nfault = \"estop\"\nwithin = [0.9, 0.9]\n\
         [[expect]]\nkind = \"no_fault\"\nbetween = [0.0, 0.899]\n\
         [[expect]]\nkind = \"through_fundament\"\n\
         [[expect]]\nkind = \"tipped_over\"\nbody = \"platform\"\n",
    )
    .unwrap();
    let r = judge::run(&s);
    let got = measured(&r);
    let expected = [
        (false, "not reached; states in the window: starting (0 s)"),
        (false, "running at 0.71 s"),
        (false, "+"),
        (false, "rotor 2: "),
        (false, "not measured at 0 s (no index yet)"),
        (
            false,
            "not latched in the window (never latched; faults seen: estop at 0.9 s)",
        ),
        (false, "estop at 0.9 s"),
        (false, "starting at 0.5 s: enable true, duty [0.491, 0.478]"),
        (true, "latched at 0.9 s, safe to the end (1 s)"),
        (true, "none"),
        (false, "none: no body went through the fundament"),
        (false, "none: no free body tipped over"),
    ];
    assert_eq!(got.len(), expected.len());
    for ((pass, measured), (want_pass, want)) in got.iter().zip(expected) {
        assert_eq!(*pass, want_pass, "{measured}");
        assert!(measured.starts_with(want), "{measured:?} vs {want:?}");
    }
    assert!(!r.passed());
    assert_eq!(r.detections[0].latched, Some((vec!["estop".into()], 0.9)));
}

/// A scenario on the one-foot machine (`tests/fixtures/one-foot-machine.toml`,
/// which sinks through the floor at once) with `body` appended.
fn one_foot(body: &str) -> Result<Scenario, Vec<String>> {
    let text = format!("machine = \"one-foot-machine.toml\"\nt_end = 0.5\n{body}");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures");
    from_text("s.toml", &text, &dir).map_err(|ps| ps.iter().map(said).collect())
}

#[test]
fn a_body_through_the_floor_is_judged_and_is_no_travel() {
    let s = one_foot(
        "[[commands]]\nt = 0.0\ncommand = \"right\"\n\
         [[expect]]\nkind = \"travel\"\ndirection = \"left\"\nbetween = [0.2, 0.5]\n\
         [[expect]]\nkind = \"travel\"\ndirection = \"right\"\nbetween = [0.2, 0.5]\n\
         [[expect]]\nkind = \"through_fundament\"\n\
         [[expect]]\nkind = \"through_fundament\"\nwithin = [0.2, 0.5]\n\
         [[expect]]\nkind = \"tipped_over\"\nbody = \"platform\"\nwithin = [0.0, 0.5]\n",
    )
    .unwrap();
    let r = judge::run(&s);
    let got = measured(&r);
    // The platform sinks first at the row of 0.053 s and turns past 60 degrees
    // at 0.166 s: whichever way, the platform's x is no travel.
    let sank = "platform went through the fundament at t = 0.053 s";
    assert_eq!(
        got,
        [
            (false, format!("not a travel: {sank}").as_str()),
            (false, format!("not a travel: {sank}").as_str()),
            (true, sank),
            (false, format!("{sank} (outside the window)").as_str()),
            (
                true,
                "platform turned past simulation.max_tilt = 60 deg at t = 0.166 s"
            ),
        ]
    );
    assert!(
        r.warnings[0].starts_with("platform went through the fundament"),
        "{:?}",
        r.warnings
    );
    let table = report::table(&r);
    assert!(
        table.contains("warnings of the run:\n  - platform went through"),
        "{table}"
    );
}

#[test]
fn a_breach_expectation_names_a_body_there_is() {
    // The reference machine has the platform alone.
    let e = parse(
        "[[expect]]\nkind = \"through_fundament\"\nbody = \"plattform\"\n\
         [[expect]]\nkind = \"tipped_over\"\nbody = 3\n",
    )
    .unwrap_err();
    assert_eq!(e.len(), 2, "{e:#?}");
    assert!(
        e[0].ends_with("expect[1].body: must be a string (got 3)"),
        "{e:#?}"
    );
    assert_eq!(
        e[1],
        "error: s.toml: expect[0].body: no body named \"plattform\" (bodies: platform)"
    );
    // With the arm (hinged to the platform) and the loose block of
    // tests/fixtures/three-bodies.toml.
    let bodies = include_str!("../../../tests/fixtures/three-bodies.toml");
    let text = std::fs::read_to_string(examples().join("vibro-driver.toml")).unwrap() + bodies;
    let dir = machine_dir(&text);
    let e = from_text(
        "s.toml",
        "machine = \"m.toml\"\n\
         [[expect]]\nkind = \"tipped_over\"\nbody = \"arm\"\n\
         [[expect]]\nkind = \"tipped_over\"\nbody = \"block\"\nwithin = [0.0, 11.0]\n\
         [[expect]]\nkind = \"through_fundament\"\nbody = \"arm\"\n",
        &dir,
    )
    .map_err(|ps| ps.iter().map(said).collect::<Vec<_>>())
    .unwrap_err();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(
        e,
        [
            "error: s.toml: expect[0].body: \"arm\" is held by a joint: only a free body is judged for tipping over (free bodies: platform, block)",
            "error: s.toml: expect[1].within: must lie within the run, [0, 10] s (t_end = 10 s, the machine's simulation.t_end; got [0, 11] s)",
        ]
    );
}

/// A directory holding `text` as `m.toml`, the reference machine's tuning table
/// beside it.
fn machine_dir(text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("host-sim-scenario-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.toml"), text).unwrap();
    std::fs::copy(
        examples().join("vibro-driver.tuning.toml"),
        dir.join("vibro-driver.tuning.toml"),
    )
    .unwrap();
    dir
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Scenario files stitched from valid and broken lines are judged, never
    /// a panic.
    #[test]
    fn reading_never_panics(lines in proptest::collection::vec(0usize..24, 0..14)) {
        const LINES: [&str; 24] = [
            "t_end = 1.0", "t_end = -1", "set = [1]", "set = [\"x\"]",
            "[[commands]]", "t = 0.5", "t = nan", "command = \"hold\"",
            "command = \"right\"", "speed_rpm = 1e9", "offset_deg = \"x\"",
            "[[faults]]", "kind = \"jammed_rotor\"", "rotor = 2.5", "duration = 0",
            "[[expect]]", "kind = \"phase\"", "range_deg = [1]",
            "within = [0.5, 0.2]", "between = [0, 1]", "from = 2",
            "kind = \"safe\"", "[expect]", "expect = 3",
        ];
        let body: Vec<&str> = lines.iter().map(|&i| LINES[i]).collect();
        let _ = parse(&body.join("\n"));
    }
}
