//! The case reader never panics, whatever the file holds (docs/cli-impact.md, "Bad
//! input": "without a panic"), and what it accepts the solver and the report take
//! without panic.

use clap::Parser;
use host_sim::cli::{self, Cli};
use host_sim::impact::case::parse_case;
use host_sim::impact::report;
use proptest::prelude::*;
use shared::impact::{solve_body, MAX_CONTACTS};

/// The example case of docs/cli-impact.md with every number a placeholder `{}`.
const TEMPLATE: &str = r#"law = "{}"
[body]
mass = {}
inertia = {}
position = [{}, {}]
angular_velocity = {}
[pivot]
point = [{}, {}]
[[contacts]]
name = "K"
point = [{}, {}]
normal = [{}, {}]
restitution = {}
friction = {}
[[contacts]]
name = "{}"
point = [{}, {}]
normal = [{}, {}]
restitution = {}
friction = {}
weight = {}
"#;

/// A TOML number: ordinary, extreme, or not finite.
fn toml_number() -> impl Strategy<Value = String> {
    prop_oneof![
        8 => (-2.0f64..2.0).prop_map(|x| format!("{x:?}")),
        1 => Just("0.0".to_string()),
        1 => Just("nan".to_string()),
        1 => Just("-inf".to_string()),
        1 => Just("1e300".to_string()),
        1 => Just("1e-300".to_string()),
        1 => Just("\"text\"".to_string()),
    ]
}

fn fill(template: &str, values: &[String]) -> String {
    let mut out = String::new();
    let mut parts = template.split("{}");
    out.push_str(parts.next().unwrap_or(""));
    for (part, value) in parts.zip(values.iter().cycle()) {
        out.push_str(value);
        out.push_str(part);
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
        let _ = parse_case("fuzz.toml", &text);
    }

    #[test]
    fn arbitrary_numbers_never_panic(
        law in prop_oneof![Just("poisson"), Just("newton"), Just("stronge"), Just("hooke")],
        name in prop_oneof![Just("K"), Just("K2"), Just("")],
        numbers in proptest::collection::vec(toml_number(), 22),
    ) {
        let mut values = vec![law.to_string()];
        values.extend(numbers[..13].iter().cloned());
        values.push(name.to_string());
        values.extend(numbers[13..].iter().cloned());
        let text = fill(TEMPLATE, &values);
        if let Ok(case) = parse_case("fuzz.toml", &text) {
            if let Ok(r) = solve_body::<f64, MAX_CONTACTS>(
                &case.body, case.pivot, &case.body_contacts(), case.law,
            ) {
                let _ = report::json_text(&case, &r);
                let _ = report::table(&case, &r);
            }
        }
    }
}

/// The command itself on a file that does not exist: a refusal, not a panic.
#[test]
fn the_command_refuses_a_missing_file() {
    let out = cli::run(
        Cli::try_parse_from([
            "host-sim",
            "impact",
            "does/not/exist.toml",
            "--format",
            "json",
        ])
        .unwrap(),
    );
    assert_eq!(out.status, 2);
    assert!(out.stdout.is_empty());
}

/// A valid free-body case with two contacts, random within sensible ranges.
const FREE: &str = r#"law = "{}"
[body]
mass = {}
inertia = {}
position = [0.0, 0.1]
velocity = [{}, {}]
angular_velocity = {}
[[contacts]]
point = [{}, 0.0]
normal = [{}, 1.0]
restitution = {}
friction = {}
[[contacts]]
point = [{}, 0.0]
normal = [0.0, 1.0]
restitution = {}
friction = {}
"#;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Accepted cases go through the solver and both outputs without panic, and the
    /// JSON is one document.
    #[test]
    fn valid_cases_solve_without_panic(
        law in prop_oneof![Just("poisson"), Just("newton"), Just("stronge")],
        mass in 0.1f64..10.0,
        inertia in 1e-3f64..1.0,
        vx in -1.0f64..1.0,
        vy in -2.0f64..0.0,
        omega in -5.0f64..5.0,
        x1 in -0.5f64..0.0,
        tilt in -0.5f64..0.5,
        r1 in 0.0f64..=1.0,
        f1 in 0.0f64..1.5,
        x2 in 0.01f64..0.5,
        r2 in 0.0f64..=1.0,
        f2 in 0.0f64..1.5,
    ) {
        let values: Vec<String> = [mass, inertia, vx, vy, omega, x1, tilt, r1, f1, x2, r2, f2]
            .iter()
            .map(|x| format!("{x:?}"))
            .collect();
        let mut all = vec![law.to_string()];
        all.extend(values);
        let text = fill(FREE, &all);
        let case = match parse_case("fuzz.toml", &text) {
            Ok(case) => case,
            // Only "nothing approaches" may refuse these.
            Err(p) => {
                prop_assert!(p.iter().all(|p| p.message.contains("no contact approaches")), "{p:?}");
                return Ok(());
            }
        };
        if let Ok(r) = solve_body::<f64, MAX_CONTACTS>(
            &case.body, case.pivot, &case.body_contacts(), case.law,
        ) {
            let json = report::json_text(&case, &r);
            prop_assert!(serde_json::from_str::<serde_json::Value>(&json).is_ok());
            let _ = report::table(&case, &r);
        }
    }
}
