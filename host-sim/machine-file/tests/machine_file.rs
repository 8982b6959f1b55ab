//! The machine file (docs/machine-file.md) through `Machine::load`: the reference
//! example loads; every refusal names its key path and never panics; several problems
//! are reported together; `--set` overrides keys before checking; omitted sections take
//! the documented defaults.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

mod common;
use common::assert_problem;
use machine_file::input::{render, Location, Problem};
use machine_file::set;
use machine_file::{Machine, Sense};
use proptest::prelude::*;
use shared::impact::ImpactLaw;

/// The reference machine, `examples/vibro-driver.toml`.
fn reference_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vibro-driver.toml")
}

fn reference_text() -> String {
    std::fs::read_to_string(reference_path()).expect("the reference machine is readable")
}

/// Only the required sections; every optional section omitted.
const MINIMAL: &str = include_str!("../../../tests/fixtures/minimal-machine.toml");

/// A fresh directory for this test's files.
fn temp_dir() -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir =
        std::env::temp_dir().join(format!("host-sim-machine-file-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Writes `text` to a fresh `machine.toml` and returns its path.
fn write(text: &str) -> PathBuf {
    let path = temp_dir().join("machine.toml");
    std::fs::write(&path, text).expect("temp file");
    path
}

fn sets(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

/// Loads `text` from a temp file with `--set`s.
fn load(text: &str, set: &[&str]) -> Result<Machine, Vec<Problem>> {
    let path = write(text);
    let result = Machine::load(&path, &sets(set));
    // Leave no files behind; a failure to remove them is no failure of the test.
    let _ = std::fs::remove_dir_all(path.parent().expect("a temp dir"));
    result
}

/// The problems of a refused load.
fn refused(text: &str, set: &[&str]) -> Vec<Problem> {
    match load(text, set) {
        Ok(_) => panic!("accepted, with --set {set:?}"),
        Err(p) => p,
    }
}

/// The reference text with `set` written into the file (not on the command line).
fn reference_edited(set: &str) -> String {
    let mut table: toml::Table = toml::from_str(&reference_text()).unwrap();
    let (applied, problems) = set::apply(&mut table, &set::Override::command_line(&sets(&[set])));
    assert!(problems.is_empty() && applied.len() == 1, "{problems:?}");
    toml::to_string(&table).unwrap()
}

// ---------------------------------------------------------------------------------
// Accepted files

#[test]
fn the_reference_machine_loads() {
    let m = Machine::load(&reference_path(), &[]).unwrap_or_else(|e| panic!("{}", render(&e)));
    assert_eq!(m.fundament.normal, [0.0, 1.0]);
    assert_eq!(m.platform.mass, 2.0);
    assert_eq!(m.platform.position, [0.0, 0.03]);
    assert_eq!(m.contacts.len(), 2);
    assert_eq!(
        (m.contacts[0].name.as_str(), m.contacts[1].name.as_str()),
        ("K1", "K2")
    );
    assert_eq!(
        (m.rotors[0].name.as_str(), m.rotors[1].name.as_str()),
        ("left", "right")
    );
    assert_eq!(
        (m.rotors[0].sense, m.rotors[1].sense),
        (Sense::Ccw, Sense::Cw)
    );
    assert_eq!(m.rotors[0].motor.torque_constant, 0.02);
    assert_eq!(m.rotors[0].motor, m.rotors[1].motor);
    assert_eq!(m.drive.supply_voltage, 12.0);
    assert_eq!(m.sensors.encoder_counts, 4096);
    assert_eq!(m.controller.rate_hz, 1000.0);
    assert_eq!(m.controller.speed_rpm, 3000.0);
    // The table `host-sim tune --write` generated, beside the machine file.
    let table = m
        .controller
        .tuning_table
        .as_ref()
        .expect("the reference machine names its table");
    assert!(
        table.ends_with("examples/vibro-driver.tuning.toml"),
        "{table:?}"
    );
    assert!(table.exists());
    assert_eq!(m.law, ImpactLaw::Poisson);
    assert_eq!(m.simulation.seed, 1);
}

#[test]
fn the_reference_machine_lifts_at_its_speed() {
    // The example's claim: 2 m e omega^2 at speed_rpm is about twice the weight.
    let m = Machine::load(&reference_path(), &[]).unwrap();
    let omega = m.controller.speed_rpm * std::f64::consts::TAU / 60.0;
    let force: f64 = m
        .rotors
        .iter()
        .map(|r| r.eccentric_mass * r.eccentricity * omega * omega)
        .sum();
    let weight = m.total_mass() * 9.81;
    assert!((force - 39.478).abs() < 1e-3, "{force}");
    assert!((weight - 19.8162).abs() < 1e-9, "{weight}");
    assert!(force / weight > 1.9);
}

#[test]
fn omitted_sections_take_the_documented_defaults() {
    let m = load(MINIMAL, &[]).unwrap_or_else(|e| panic!("{}", render(&e)));
    assert_eq!(m.fundament.point, [0.0, 0.0]);
    assert_eq!(m.fundament.normal, [0.0, 1.0]);
    assert_eq!(m.fundament.gravity, [0.0, -9.81]);
    assert_eq!(m.platform.angle, 0.0);
    assert_eq!(m.platform.velocity, [0.0, 0.0]);
    assert_eq!(m.platform.angular_velocity, 0.0);
    assert_eq!(m.contacts[1].weight, 1.0);
    assert_eq!((m.rotors[1].angle, m.rotors[1].index_angle), (0.0, 0.0));
    assert_eq!(m.drive.bridge.decay, shared::drive::Decay::Slow);
    assert_eq!(m.drive.bridge.pwm_hz, 20_000);
    assert_eq!(m.sensors.encoder_counts, 4096);
    assert_eq!(m.sensors.current_noise, 0.0);
    assert_eq!(m.sensors.encoder_jitter, 0.0);
    assert_eq!(m.controller.rate_hz, 1000.0);
    assert_eq!(m.controller.speed_rpm, 3000.0);
    assert_eq!(m.controller.tuning_table, None);
    assert_eq!(m.law, ImpactLaw::Poisson);
    assert_eq!(m.simulation.t_end, 10.0);
    assert_eq!(m.simulation.output_step, 1.0e-3);
    assert_eq!(m.simulation.seed, 1);
}

#[test]
fn omitted_names_default_to_k_and_r_numbers() {
    let text = MINIMAL
        .replace("name = \"K2\"\n", "")
        .replace("name = \"left\"\n", "");
    let m = load(&text, &[]).unwrap();
    assert_eq!(m.contacts[1].name, "K2");
    assert_eq!(m.rotors[0].name, "R1");
}

#[test]
fn normals_are_normalised() {
    // A sloping floor, normal [-3, 4] / 5, moved 1 m down so that both feet are above
    // it: gaps 0.848 and 0.752 m.
    let m = load(
        MINIMAL,
        &["fundament.normal=[-3, 4]", "fundament.point=[0, -1]"],
    )
    .unwrap();
    let n = m.fundament.normal;
    assert!(
        (n[0] + 0.6).abs() < 1e-15 && (n[1] - 0.8).abs() < 1e-15,
        "{n:?}"
    );
}

#[test]
fn a_rotor_motor_overrides_the_machine_motor_key_by_key() {
    let text = MINIMAL.replace(
        "sense = \"cw\"\n",
        "sense = \"cw\"\n[rotors.motor]\nresistance = 3.0\ncurrent_limit = 1.5\n",
    );
    let m = load(&text, &[]).unwrap();
    let (left, right) = (&m.rotors[0].motor, &m.rotors[1].motor);
    assert_eq!(left.resistance, 2.0);
    assert_eq!((right.resistance, right.current_limit), (3.0, 1.5));
    // The keys it does not give are the machine's.
    assert_eq!(right.torque_constant, left.torque_constant);
    assert_eq!(right.inductance, 0.5e-3);
}

#[test]
fn motor_may_be_omitted_when_every_rotor_has_a_whole_one() {
    let motor = &MINIMAL[MINIMAL.find("[motor]").unwrap()..MINIMAL.find("[drive]").unwrap()];
    let own = motor.replace("[motor]", "[rotors.motor]");
    let text = MINIMAL
        .replace(motor, "")
        .replace("sense = \"ccw\"\n", &format!("sense = \"ccw\"\n{own}"))
        .replace("sense = \"cw\"\n", &format!("sense = \"cw\"\n{own}"));
    load(&text, &[]).unwrap_or_else(|e| panic!("{}", render(&e)));
    // One rotor without a whole motor: the missing keys are asked of [motor].
    let text = text.replacen("resistance = 2.0\n", "", 1);
    let e = refused(&text, &[]);
    assert_problem(&e, "motor", "missing; required: a table [motor]");
    assert_problem(&e, "motor", "resistance");
}

#[test]
fn a_plain_rotor_may_have_no_eccentric() {
    let m = load(
        MINIMAL,
        &["rotors.left.eccentric_mass=0", "rotors.left.eccentricity=0"],
    )
    .unwrap();
    assert_eq!(m.rotors[0].eccentric_mass, 0.0);
}

#[test]
fn the_tuning_table_is_resolved_against_the_machine_files_directory() {
    let text = format!("{MINIMAL}\n[controller]\ntuning_table = \"sub/t.toml\"\n");
    let path = write(&text);
    let m = Machine::load(&path, &[]).unwrap();
    let dir = path.parent().unwrap();
    assert_eq!(m.controller.tuning_table, Some(dir.join("sub/t.toml")));
    // Not read yet: a missing table is no problem here.
    assert!(!dir.join("sub/t.toml").exists());
    // An absolute path stays as it is.
    let m = Machine::load(&path, &sets(&["controller.tuning_table=\"/abs/t.toml\""])).unwrap();
    assert_eq!(
        m.controller.tuning_table,
        Some(PathBuf::from("/abs/t.toml"))
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_contact_exactly_on_the_fundament_is_accepted() {
    // Both feet at gap 0 on a floor through [1, 0], and gap 1e-3 above.
    load(MINIMAL, &["fundament.point=[1, 0]"]).unwrap();
    load(MINIMAL, &["contacts.K1.point=[-0.08, 1e-3]"]).unwrap();
}

/// Every problem at once: a geometry problem (a foot below the fundament) and a
/// bridge against the control rate are reported beside a bad rotor and a bad
/// body, not hidden by them.
#[test]
fn problems_of_every_stage_are_reported_together() {
    let text = reference_text()
        + "\n[[bodies]]\nname = \"element\"\nmass = -1.0\ninertia = 2e-5\nposition = [0.1, 0.2]\n";
    let problems = refused(
        &text,
        &[
            "contacts.K1.point=[-0.08, -0.01]",
            "rotors.left.eccentric_mass=-1",
            "drive.pwm_hz=100",
        ],
    );
    let text = render(&problems);
    for key in [
        "contacts[0].point",
        "rotors[0].eccentric_mass",
        "bodies[0].mass",
        "drive.pwm_hz",
    ] {
        assert!(
            text.contains(&format!("{key}:")),
            "{key} not reported:\n{text}"
        );
    }
}

// ---------------------------------------------------------------------------------
// Refusals: each names its key. Every case is checked twice: with the value written in
// the file, and with the reference file and the value on the command line.

/// `(--set, key path of the problem, a fragment of its message)`.
const REFUSALS: &[(&str, &str, &str)] = &[
    ("platform.mass=0", "platform.mass", "must be > 0 (got 0)"),
    ("platform.mass=-2", "platform.mass", "must be > 0 (got -2)"),
    ("platform.inertia=0", "platform.inertia", "must be > 0"),
    (
        "platform.mass=nan",
        "platform.mass",
        "must be a finite number (got nan)",
    ),
    (
        "platform.position=[0, inf]",
        "platform.position[1]",
        "must be a finite number (got inf)",
    ),
    (
        "platform.velocity=[1]",
        "platform.velocity",
        "must be an array of two numbers [x, y]",
    ),
    (
        "platform.angle=\"0\"",
        "platform.angle",
        "must be a number (got the string \"0\")",
    ),
    ("rotors.left.inertia=0", "rotors[0].inertia", "must be > 0"),
    (
        "rotors.right.eccentric_mass=-0.01",
        "rotors[1].eccentric_mass",
        "must be >= 0",
    ),
    (
        "rotors.left.eccentricity=-0.02",
        "rotors[0].eccentricity",
        "must be >= 0",
    ),
    (
        "rotors.left.eccentricity=0",
        "rotors[0].eccentricity",
        "must be > 0 when eccentric_mass > 0",
    ),
    (
        "contacts.K1.restitution=1.5",
        "contacts[0].restitution",
        "must be in [0, 1] (got 1.5)",
    ),
    (
        "contacts.K2.restitution=-0.1",
        "contacts[1].restitution",
        "must be in [0, 1]",
    ),
    (
        "contacts.K1.friction=-0.1",
        "contacts[0].friction",
        "must be >= 0 (got -0.1)",
    ),
    ("contacts.K2.weight=0", "contacts[1].weight", "must be > 0"),
    (
        "contacts.K2.name=\"K1\"",
        "contacts[1].name",
        "duplicate contact name \"K1\" (contacts[0] has it already)",
    ),
    (
        "contacts.K1.name=\"\"",
        "contacts[0].name",
        "must not be empty",
    ),
    (
        "rotors.right.name=\"left\"",
        "rotors[1].name",
        "duplicate rotor name \"left\"",
    ),
    (
        "contacts.K1.point=[-0.08, -0.01]",
        "contacts[0].point",
        "contact K1 is below the fundament at t = 0: gap n . (K - P) = -0.01 m",
    ),
    (
        "fundament.point=[0, 0.005]",
        "contacts[1].point",
        "gap n . (K - P) = -0.005 m",
    ),
    (
        "fundament.normal=[0, 0]",
        "fundament.normal",
        "must not be zero length",
    ),
    (
        "rotors.left.sense=\"ccww\"",
        "rotors[0].sense",
        "unknown value \"ccww\"; did you mean \"ccw\"? (allowed: ccw, cw)",
    ),
    (
        "rotors.right.sense=up",
        "rotors[1].sense",
        "(allowed: ccw, cw)",
    ),
    (
        "impact.law=\"poison\"",
        "impact.law",
        "did you mean \"poisson\"? (allowed: poisson, newton, stronge)",
    ),
    ("motor.resistance=0", "motor.resistance", "must be > 0"),
    ("motor.inductance=-1e-3", "motor.inductance", "must be > 0"),
    (
        "motor.torque_constant=0",
        "motor.torque_constant",
        "must be > 0",
    ),
    (
        "motor.coulomb_friction=-1e-3",
        "motor.coulomb_friction",
        "must be >= 0",
    ),
    (
        "motor.viscous_friction=-1e-6",
        "motor.viscous_friction",
        "must be >= 0",
    ),
    (
        "motor.current_limit=0",
        "motor.current_limit",
        "must be > 0",
    ),
    (
        "rotors.right.motor.resistance=-1",
        "rotors[1].motor.resistance",
        "must be > 0",
    ),
    (
        "drive.supply_voltage=0",
        "drive.supply_voltage",
        "must be > 0",
    ),
    (
        "drive.decay=medium",
        "drive.decay",
        "unknown value \"medium\" (allowed: slow, fast)",
    ),
    (
        "drive.pwm_hz=500",
        "drive.pwm_hz",
        "must be in [1000, 200000] (got 500)",
    ),
    ("drive.pwm_hz=2e4", "drive.pwm_hz", "must be an integer"),
    (
        "sensors.encoder_counts=1023",
        "sensors.encoder_counts",
        "must be a multiple of 4",
    ),
    (
        "sensors.encoder_counts=0",
        "sensors.encoder_counts",
        "must be in [4, ",
    ),
    (
        "sensors.encoder_counts=4096.0",
        "sensors.encoder_counts",
        "must be an integer",
    ),
    (
        "sensors.current_noise=-0.01",
        "sensors.current_noise",
        "must be >= 0",
    ),
    (
        "sensors.encoder_jitter=-1e-6",
        "sensors.encoder_jitter",
        "must be >= 0",
    ),
    ("controller.rate_hz=0", "controller.rate_hz", "must be > 0"),
    (
        "controller.rate_hz=200000",
        "controller.rate_hz",
        "must be in (0, 100000] Hz",
    ),
    (
        "controller.speed_rpm=-3000",
        "controller.speed_rpm",
        "must be > 0",
    ),
    (
        "controller.tuning_table=\"\"",
        "controller.tuning_table",
        "must not be empty",
    ),
    (
        "controller.tuning_table=3",
        "controller.tuning_table",
        "must be a string",
    ),
    ("simulation.t_end=0", "simulation.t_end", "must be > 0"),
    (
        "simulation.output_step=-1e-3",
        "simulation.output_step",
        "must be > 0",
    ),
    ("simulation.seed=-1", "simulation.seed", "must be >= 0"),
    (
        "simulation.seed=1.5",
        "simulation.seed",
        "must be an integer",
    ),
];

#[test]
fn every_refusal_names_its_key_when_written_in_the_file() {
    for (set, key, fragment) in REFUSALS {
        let e = refused(&reference_edited(set), &[]);
        assert_problem(&e, key, fragment);
        assert!(
            e.iter().all(|p| !p.message.contains("--set")),
            "{set}: {}",
            render(&e)
        );
    }
}

#[test]
fn every_refusal_names_its_key_and_its_set_when_given_by_set() {
    for (set, key, fragment) in REFUSALS {
        let e = refused(&reference_text(), &[set]);
        assert_problem(&e, key, fragment);
        // A problem at the key that was set says so; one at another key (the feet
        // below a fundament that was moved) stands as it is.
        if !set.starts_with("fundament.") {
            assert_problem(&e, key, &format!("(from --set {set})"));
        }
    }
}

#[test]
fn the_gap_message_gives_the_geometry() {
    let e = refused(&reference_text(), &["contacts.K1.point=[-0.08, -0.01]"]);
    let line = e[0].to_string();
    assert!(
        line.ends_with(
            "contacts[0].point: contact K1 is below the fundament at t = 0: gap n . (K - P) = -0.01 m (K = [-0.08, -0.01], fundament point P = [0, 0], normal n = [0, 1]); it must be >= 0, on or above the fundament (from --set contacts.K1.point=[-0.08, -0.01])"
        ),
        "{line}"
    );
}

#[test]
fn no_contact() {
    let none = MINIMAL[..MINIMAL.find("[[contacts]]").unwrap()].to_string()
        + &MINIMAL[MINIMAL.find("[[rotors]]").unwrap()..];
    let e = refused(&none, &[]);
    assert_problem(
        &e,
        "contacts",
        "no contact: at least one [[contacts]] table is required",
    );
}

#[test]
fn at_most_sixteen_contacts() {
    let contact = "[[contacts]]\npoint = [0.0, 0.0]\nrestitution = 0.3\nfriction = 0.4\n";
    let seventeen = MINIMAL.replacen(
        "[[rotors]]",
        &format!("{}[[rotors]]", contact.repeat(15)),
        1,
    );
    let e = refused(&seventeen, &[]);
    assert_problem(&e, "contacts", "17 contacts; at most 16 are allowed");
    // Sixteen are fine; the unnamed ones are K3 to K16.
    let sixteen = MINIMAL.replacen(
        "[[rotors]]",
        &format!("{}[[rotors]]", contact.repeat(14)),
        1,
    );
    let m = load(&sixteen, &[]).unwrap_or_else(|e| panic!("{}", render(&e)));
    assert_eq!(m.contacts[15].name, "K16");
}

#[test]
fn unknown_keys_get_a_did_you_mean() {
    let text = MINIMAL
        .replace("mass = 2.0", "mas = 2.0")
        .replace("[drive]", "[drive]\nsuply_voltage = 12\n")
        + "\n[simulaton]\nt_end = 1.0\n";
    let e = refused(&text, &[]);
    assert_problem(&e, "platform.mas", "unknown key; did you mean `mass`?");
    assert_problem(&e, "platform.mass", "missing; required: a number > 0");
    assert_problem(&e, "drive.suply_voltage", "did you mean `supply_voltage`?");
    assert_problem(&e, "simulaton", "unknown key; did you mean `simulation`?");
    let e = refused(
        &MINIMAL.replace("sense = \"cw\"", "sense = \"cw\"\neccentricty = 0.02"),
        &[],
    );
    assert_problem(&e, "rotors[1].eccentricty", "did you mean `eccentricity`?");
}

#[test]
fn required_sections_and_keys() {
    let no_drive = &MINIMAL[..MINIMAL.find("[drive]").unwrap()];
    assert_problem(
        &refused(no_drive, &[]),
        "drive",
        "missing; required: a table [drive]",
    );
    let e = refused(&MINIMAL.replace("inductance = 0.5e-3\n", ""), &[]);
    assert_problem(
        &e,
        "motor.inductance",
        "missing; required: a number > 0 (H)",
    );
    let e = refused(&MINIMAL.replace("sense = \"ccw\"\n", ""), &[]);
    assert_problem(&e, "rotors[0].sense", "missing; required: one of ccw, cw");
    let e = refused(&MINIMAL.replace("position = [0.0, 0.03]\n", ""), &[]);
    assert_problem(&e, "platform.position", "missing");
}

#[test]
fn several_problems_are_all_reported() {
    let text = reference_text()
        .replace("mass = 2.0 ", "mass = 0.0 ")
        .replace("inertia = 7.3e-3", "inertia = -1.0")
        .replace("law = \"poisson\"", "law = \"poison\"")
        .replace("seed = 1 ", "sed = 1 ");
    let e = refused(
        &text,
        &[
            "contacts.K1.friction=-1",
            "contacts.K9.friction=0.2",
            "rotors.left.sense=sideways",
            "nonsense",
        ],
    );
    // The --set problems first, then the file's.
    assert_eq!(e[0].file, "--set contacts.K9.friction=0.2");
    assert_eq!(e[1].file, "--set nonsense");
    assert_problem(&e, "platform.mass", "must be > 0");
    assert_problem(&e, "platform.inertia", "must be > 0");
    assert_problem(&e, "impact.law", "unknown value \"poison\"");
    assert_problem(&e, "simulation.sed", "did you mean `seed`?");
    assert_problem(
        &e,
        "contacts[0].friction",
        "(from --set contacts.K1.friction=-1)",
    );
    assert_problem(
        &e,
        "rotors[0].sense",
        "(from --set rotors.left.sense=sideways)",
    );
    assert_eq!(e.len(), 8, "{}", render(&e));
}

#[test]
fn a_missing_file_is_one_problem() {
    let dir = temp_dir();
    let e = Machine::load(&dir.join("none.toml"), &[]).unwrap_err();
    let _ = std::fs::remove_dir_all(dir);
    assert_eq!(e.len(), 1);
    assert!(e[0]
        .to_string()
        .ends_with("none.toml: cannot read the file: no such file"));
}

#[test]
fn a_syntax_error_is_one_problem_with_its_line() {
    let e = refused("[platform]\nmass = = 2\n", &["simulation.t_end=1", "oops"]);
    // The malformed --set is still reported; the well-formed one cannot be checked.
    assert_eq!(e.len(), 2, "{}", render(&e));
    assert_eq!(
        render(&e[..1]).trim_end(),
        "error: --set oops: expected KEY=VALUE (e.g. contacts.K1.friction=0.2)"
    );
    assert!(
        matches!(e[1].location, Location::Line { line: 2, .. }),
        "{e:?}"
    );
}

// ---------------------------------------------------------------------------------
// --set

#[test]
fn set_overrides_keys_by_path() {
    let m = load(
        MINIMAL,
        &[
            "contacts.K1.friction=0.2",
            "contacts.1.friction=0.25",
            "contacts[1].restitution=0.5",
            "platform.position=[0,0.1]",
            "rotors.left.eccentric_mass=0",
            "rotors.left.motor.resistance=3",
            "rotors[1].angle=1.5",
            "rotors.right.sense=ccw",
            "simulation.t_end=2",
            "controller.rate_hz=2000",
            "impact.law=newton",
            "sensors.encoder_counts=2048",
        ],
    )
    .unwrap_or_else(|e| panic!("{}", render(&e)));
    assert_eq!(m.contacts[0].friction, 0.2);
    assert_eq!(m.contacts[1].friction, 0.25);
    assert_eq!(m.contacts[1].restitution, 0.5);
    assert_eq!(m.platform.position, [0.0, 0.1]);
    assert_eq!(m.rotors[0].eccentric_mass, 0.0);
    // The rotor's own motor replaces resistance only, and only for that rotor.
    assert_eq!(m.rotors[0].motor.resistance, 3.0);
    assert_eq!(m.rotors[0].motor.torque_constant, 0.02);
    assert_eq!(m.rotors[1].motor.resistance, 2.0);
    assert_eq!(m.rotors[1].angle, 1.5);
    assert_eq!(m.rotors[1].sense, Sense::Ccw);
    // Sections the file omits are created.
    assert_eq!(m.simulation.t_end, 2.0);
    assert_eq!(m.simulation.output_step, 1.0e-3);
    assert_eq!(m.controller.rate_hz, 2000.0);
    assert_eq!(m.law, ImpactLaw::Newton);
    assert_eq!(m.sensors.encoder_counts, 2048);
}

#[test]
fn set_of_the_machine_motor_reaches_every_rotor_without_its_own() {
    let m = load(
        MINIMAL,
        &["rotors.left.motor.resistance=4", "motor.resistance=3"],
    )
    .unwrap();
    assert_eq!(m.rotors[0].motor.resistance, 4.0);
    assert_eq!(m.rotors[1].motor.resistance, 3.0);
}

#[test]
fn later_sets_win_and_renames_apply_in_order() {
    let m = load(
        MINIMAL,
        &[
            "simulation.t_end=2",
            "simulation.t_end=3",
            "contacts.K2.name=K3",
            "contacts.K3.friction=0.1",
        ],
    )
    .unwrap();
    assert_eq!(m.simulation.t_end, 3.0);
    assert_eq!(m.contacts[1].name, "K3");
    assert_eq!(m.contacts[1].friction, 0.1);
}

#[test]
fn bad_sets_are_refused_with_the_reason() {
    let cases: &[(&str, &str)] = &[
        (
            "contacts.K9.friction=0.2",
            "error: --set contacts.K9.friction=0.2: no contact named K9 (contacts: K1, K2)",
        ),
        (
            "rotors.middle.inertia=1",
            "error: --set rotors.middle.inertia=1: no rotor named middle (rotors: left, right)",
        ),
        (
            "contacts.7.friction=0.2",
            "error: --set contacts.7.friction=0.2: no contacts[7]: the file has 2 [[contacts]] tables, numbered from 0 (contacts: K1, K2)",
        ),
        (
            "contacts.K1.friction",
            "error: --set contacts.K1.friction: expected KEY=VALUE (e.g. contacts.K1.friction=0.2)",
        ),
        (
            "platform.mas=2",
            "error: --set platform.mas=2: unknown key `mas` in platform; did you mean `mass`? (allowed: mass, inertia, position, angle, velocity, angular_velocity)",
        ),
        (
            "simulaton.t_end=2",
            "error: --set simulaton.t_end=2: unknown key `simulaton` at the top level; did you mean `simulation`? (allowed: fundament, platform, bodies, joints, contacts, rotors, motor, drive, sensors, controller, impact, simulation)",
        ),
        (
            "rotors.left.motor.resistence=3",
            "error: --set rotors.left.motor.resistence=3: unknown key `resistence` in rotors.left.motor; did you mean `resistance`? (allowed: resistance, inductance, torque_constant, coulomb_friction, viscous_friction, current_limit)",
        ),
        (
            "platform=2",
            "error: --set platform=2: `platform` is a table; --set sets one key in it (keys: mass, inertia, position, angle, velocity, angular_velocity)",
        ),
        (
            "contacts.K1=2",
            "error: --set contacts.K1=2: `contacts.K1` names a contact, not a key; add one of its keys (name, point, restitution, friction, weight, body, against, face, normal)",
        ),
        (
            "contacts=2",
            "error: --set contacts=2: `contacts` is an array of tables; name one contact and a key, e.g. contacts.K1.point=...",
        ),
        (
            "platform.mass.kg=2",
            "error: --set platform.mass.kg=2: `platform.mass` is a value, not a table: nothing can be set below it",
        ),
        (
            "=2",
            "error: --set =2: empty key; expected KEY=VALUE (e.g. contacts.K1.friction=0.2)",
        ),
        (
            "contacts[0.friction=2",
            "error: --set contacts[0.friction=2: malformed key `contacts[0.friction`: expected `[INDEX]` after `contacts` (e.g. contacts[0].friction)",
        ),
    ];
    for (set, expected) in cases {
        let e = refused(MINIMAL, &[set]);
        assert_eq!(render(&e), format!("{expected}\n"), "{set}");
    }
}

#[test]
fn set_into_an_empty_array_names_the_missing_tables() {
    let none = MINIMAL[..MINIMAL.find("[[contacts]]").unwrap()].to_string()
        + &MINIMAL[MINIMAL.find("[[rotors]]").unwrap()..];
    let e = refused(&none, &["contacts.K1.friction=0.2"]);
    assert_eq!(
        render(&e[..1]).trim_end(),
        "error: --set contacts.K1.friction=0.2: no contact named K1: the file has no [[contacts]] tables"
    );
    // And the file's own problem besides.
    assert_problem(&e, "contacts", "no contact");
}

proptest! {
    /// Whatever the user types after --set, loading reports problems or succeeds;
    /// it never panics.
    #[test]
    fn arbitrary_sets_never_panic(arg in "[a-z_\\[\\]0-9.=\"\\-, ]{0,40}") {
        let text = reference_text();
        let dir = reference_path().parent().unwrap().to_path_buf();
        let _ = Machine::from_text("m.toml", &text, &dir, &[arg]);
    }

    /// Any known key set to any short value: no panic either.
    #[test]
    fn arbitrary_values_of_known_keys_never_panic(
        key in proptest::sample::select(set::key_paths()),
        value in "[a-z0-9.\\-\\[\\], \"]{0,12}",
    ) {
        let key = key.replace("contacts.NAME", "contacts.K1").replace("rotors.NAME", "rotors.right");
        let text = reference_text();
        let _ = Machine::from_text("m.toml", &text, Path::new(""), &[format!("{key}={value}")]);
    }
}

/// The bridges must take a new duty at least once per control tick: fewer timer
/// updates a second than control ticks is refused at `drive.pwm_hz`; above
/// 50 kHz the update comes every few periods, and 200 kHz (50 000 updates) still
/// serves a 50 kHz control rate.
#[test]
fn fewer_duty_updates_than_control_ticks_are_refused() {
    let e = refused(
        &reference_text(),
        &["drive.pwm_hz=2000", "controller.rate_hz=5000"],
    );
    assert_problem(
        &e,
        "drive.pwm_hz",
        "2000 Hz gives 2000 duty updates a second, fewer than [controller] rate_hz = 5000",
    );
    let ok = load(
        &reference_text(),
        &["drive.pwm_hz=200000", "controller.rate_hz=50000"],
    );
    assert!(ok.is_ok(), "{:?}", ok.err());
}
