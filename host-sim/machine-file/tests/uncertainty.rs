//! `[uncertainty]`: ranges read and checked against the whole machine (each end
//! refused with the key and the check that fails), and the machines drawn from
//! them (the nominal first, then a Latin hypercube: every stratum of every range
//! holds one machine, deterministic for a seed).

mod common;

use std::path::Path;

use common::{assert_problem, reference_without_uncertainty};
use machine_file::input::render;
use machine_file::uncertainty::{latin_hypercube, Uncertainty};
use machine_file::Machine;

/// The reference machine with `section` as its `[uncertainty]` (its tuning table
/// read from `examples/`).
fn with(section: &str) -> String {
    format!(
        "{}\n[uncertainty]\n{section}",
        reference_without_uncertainty()
    )
}

fn dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples"))
}

fn read(section: &str) -> Result<Uncertainty, Vec<machine_file::input::Problem>> {
    Uncertainty::from_text("m.toml", &with(section), dir(), &[])
}

#[test]
fn ranges_are_read_with_every_element_a_star_stands_for() {
    let u = read(
        r#""contacts.*.restitution" = [0.2, 0.45]
"contacts.K1.friction" = [0.3, 0.5]
"rotors.right.motor.resistance" = [1.8, 2.4]
"platform.mass" = [2, 3]
"#,
    )
    .unwrap_or_else(|p| panic!("{}", render(&p)));
    let keys: Vec<(&str, Vec<&str>, f64, f64)> = u
        .ranges
        .iter()
        .map(|r| {
            let t = r.targets.iter().map(String::as_str).collect();
            (r.key.as_str(), t, r.low, r.high)
        })
        .collect();
    assert_eq!(
        keys,
        vec![
            (
                "contacts.*.restitution",
                vec!["contacts.0.restitution", "contacts.1.restitution"],
                0.2,
                0.45
            ),
            (
                "contacts.K1.friction",
                vec!["contacts.K1.friction"],
                0.3,
                0.5
            ),
            (
                "rotors.right.motor.resistance",
                vec!["rotors.right.motor.resistance"],
                1.8,
                2.4
            ),
            ("platform.mass", vec!["platform.mass"], 2.0, 3.0),
        ]
    );
    // The machine itself reads as without the section.
    let m = Machine::from_text("m.toml", &with(r#""platform.mass" = [2, 3]"#), dir(), &[]);
    assert!(m.is_ok(), "{}", render(&m.err().unwrap_or_default()));
}

#[test]
fn every_bad_range_is_refused_with_its_key_and_reason() {
    let text = with(
        r#""contacts.*.frction" = [0.3, 0.5]
"contacts.K2.restitution" = [0.2, 1.5]
"platform.mass" = [2, 1]
"platform.inertia" = [1e-3]
"rotors.*" = [1, 2]
"contacts.K9.friction" = [0.1, 0.2]
"controller.*.x" = [0, 1]
"rotors.left.sense" = [1, 2]
"#,
    );
    // Every command refuses the file (the machine's own check reads the section).
    let problems = Machine::from_text("m.toml", &text, dir(), &[]).unwrap_err();
    let at = |k: &str| format!("uncertainty.\"{k}\"");
    assert_problem(
        &problems,
        &at("contacts.*.frction"),
        "did you mean `friction`",
    );
    assert_problem(
        &problems,
        &at("contacts.K2.restitution"),
        "at HIGH = 1.5: contacts[1].restitution: must be in [0, 1]",
    );
    for k in ["platform.mass", "platform.inertia"] {
        assert_problem(
            &problems,
            &at(k),
            "must be [LOW, HIGH], two finite numbers with LOW < HIGH",
        );
    }
    assert_problem(&problems, &at("rotors.*"), "names a rotor, not a key");
    assert_problem(
        &problems,
        &at("contacts.K9.friction"),
        "no contact named K9",
    );
    assert_problem(
        &problems,
        &at("controller.*.x"),
        "`*` stands only for the element",
    );
    assert_problem(
        &problems,
        &at("rotors.left.sense"),
        "at LOW = 1: rotors[0].sense",
    );
    assert_eq!(problems.len(), 9, "{}", render(&problems));
}

#[test]
fn a_key_varied_by_two_ranges_is_refused() {
    let problems = read(
        r#""contacts.*.restitution" = [0.2, 0.45]
"contacts.K2.restitution" = [0.25, 0.3]
"#,
    )
    .unwrap_err();
    assert_problem(
        &problems,
        "uncertainty.\"contacts.K2.restitution\"",
        "varies contacts[1].restitution, which \"contacts.*.restitution\" varies too",
    );
}

#[test]
fn the_ranges_vary_the_machine_the_overrides_make() {
    // A --set moves the nominal friction out of nothing the range checks: the
    // range's ends are checked on the machine with the overrides.
    let text = with(r#""contacts.K1.restitution" = [0.2, 0.45]"#);
    let sets = ["contacts.K2.friction=0.25".to_string()];
    let u = Uncertainty::from_text("m.toml", &text, dir(), &sets).unwrap();
    assert_eq!(u.ranges.len(), 1);
    // A --set that breaks the machine is reported before the ranges.
    let bad = ["contacts.K2.friction=-1".to_string()];
    let problems = Uncertainty::from_text("m.toml", &text, dir(), &bad).unwrap_err();
    assert!(
        render(&problems).contains("contacts[1].friction"),
        "{}",
        render(&problems)
    );
}

#[test]
fn a_latin_hypercube_holds_one_point_in_every_stratum() {
    for (n, d, seed) in [(1, 3, 0), (7, 1, 1), (10, 3, 2), (64, 5, 3)] {
        let points = latin_hypercube(n, d, seed);
        assert_eq!(points.len(), n);
        for dim in 0..d {
            let mut strata: Vec<usize> = points
                .iter()
                .map(|p| {
                    assert!((0.0..1.0).contains(&p[dim]), "{}", p[dim]);
                    (p[dim] * n as f64).floor() as usize
                })
                .collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..n).collect::<Vec<_>>(), "n {n}, dimension {dim}");
        }
        assert_eq!(points, latin_hypercube(n, d, seed), "deterministic");
    }
    assert_ne!(latin_hypercube(10, 3, 1), latin_hypercube(10, 3, 2));
}

#[test]
fn the_machines_drawn_start_with_the_nominal_and_stay_within_the_ranges() {
    let text = with(
        r#""contacts.*.restitution" = [0.2, 0.45]
"motor.resistance" = [1.8, 2.4]
"#,
    );
    let u = Uncertainty::from_text("m.toml", &text, dir(), &[]).unwrap();
    let drawn = u.draw(9, 7);
    assert_eq!(drawn.len(), 9);
    assert!(drawn[0].is_empty(), "the nominal machine first");
    assert_eq!(drawn, u.draw(9, 7), "deterministic for a seed");
    let mut restitutions = Vec::new();
    for sets in &drawn[1..] {
        let m = Machine::from_text("m.toml", &text, dir(), sets)
            .unwrap_or_else(|p| panic!("{sets:?}: {}", render(&p)));
        // `*`: both contacts take the same number.
        let (e1, e2) = (m.contacts[0].restitution, m.contacts[1].restitution);
        assert_eq!(e1, e2);
        assert!((0.2..0.45).contains(&e1), "{e1}");
        let r = m.rotors[0].motor.resistance;
        assert!((1.8..2.4).contains(&r), "{r}");
        restitutions.push(e1);
    }
    // Eight machines, one in each eighth of the range.
    let mut strata: Vec<usize> = restitutions
        .iter()
        .map(|e| ((e - 0.2) / 0.25 * 8.0).floor() as usize)
        .collect();
    strata.sort_unstable();
    assert_eq!(strata, (0..8).collect::<Vec<_>>());
    // No ranges: the nominal machine alone.
    assert_eq!(
        Uncertainty::default().draw(5, 1),
        vec![Vec::<String>::new()]
    );
}

/// The reference machine says what it does not know: the ranges its comments
/// give for its estimates (the feet's restitution and friction, the motor's
/// resistance and torque constant), each around the file's own value, so that
/// `tune --robust` and `calibrate --fit` of those keys run on it as the README
/// shows them.
#[test]
fn the_reference_machine_gives_the_ranges_of_its_estimates() {
    let path = dir().join("vibro-driver.toml");
    let u = Uncertainty::load(&path, &[]).unwrap_or_else(|p| panic!("{}", render(&p)));
    let m = Machine::load(&path, &[]).unwrap_or_else(|p| panic!("{}", render(&p)));
    let motor = &m.rotors[0].motor;
    let nominal = [
        ("contacts.*.restitution", m.contacts[0].restitution),
        ("contacts.*.friction", m.contacts[0].friction),
        ("motor.resistance", motor.resistance),
        ("motor.torque_constant", motor.torque_constant),
    ];
    let keys: Vec<&str> = u.ranges.iter().map(|r| r.key.as_str()).collect();
    assert_eq!(keys, nominal.map(|(k, _)| k));
    for (r, (key, value)) in u.ranges.iter().zip(nominal) {
        assert!(
            r.low < value && value < r.high,
            "{key}: the file's {value} outside [{}, {}]",
            r.low,
            r.high
        );
    }
}
