//! `host-sim impact` through the real binary: every refusal of docs/cli-impact.md
//! ("Bad input") exits 2 with the key path and a helpful message and never panics;
//! the example case files run and print the documented JSON.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde_json::Value;

mod common;
use common::{keys, run as host_sim};
use host_sim::impact::report::{CONTACT_KEYS, DOCUMENT_KEYS, SEGMENT_KEYS};

/// The example case of docs/cli-impact.md, valid.
const GOOD: &str = include_str!("fixtures/pinned-body.toml");

/// A second contact to append to [`GOOD`].
const SECOND: &str = r#"
[[contacts]]
name = "K2"
point = [-0.4, 0.3]
normal = [1.0, 0.0]
restitution = 0.5
friction = 0.2
"#;

/// Writes `text` to a fresh file and returns its path.
fn case_file(text: &str) -> String {
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let path = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("cli-impact-{}-{n}.toml", std::process::id()));
    std::fs::write(&path, text).expect("temp file");
    path.display().to_string()
}

/// Runs `impact` on `text`, expects a refusal, returns stderr.
fn refused(text: &str) -> String {
    let file = case_file(text);
    let run = host_sim(&["impact", &file]);
    assert_eq!(
        run.status, 2,
        "stdout: {}\nstderr: {}",
        run.stdout, run.stderr
    );
    assert!(run.stdout.is_empty(), "{}", run.stdout);
    for line in run.stderr.lines() {
        assert!(line.starts_with(&format!("error: {file}")), "{line}");
    }
    run.stderr
}

/// Asserts that one line of `stderr` names `key` and says `phrase`.
fn says(stderr: &str, key: &str, phrase: &str) {
    let prefix = format!(": {key}: ");
    assert!(
        stderr
            .lines()
            .any(|l| l.contains(&prefix) && l.contains(phrase)),
        "no line with `{key}` and `{phrase}` in:\n{stderr}"
    );
}

fn replace(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    GOOD.replace(from, to)
}

#[test]
fn the_documented_example_is_accepted() {
    let run = host_sim(&["impact", &case_file(GOOD)]);
    assert_eq!(run.status, 0, "{}", run.stderr);
    assert!(run.stderr.is_empty(), "{}", run.stderr);
}

#[test]
fn zero_mass_is_refused() {
    let e = refused(&replace("mass = 2.0", "mass = 0.0"));
    says(&e, "body.mass", "must be > 0 (got 0)");
}

#[test]
fn negative_inertia_is_refused() {
    let e = refused(&replace("inertia = 0.05", "inertia = -0.05"));
    says(&e, "body.inertia", "must be > 0 (got -0.05)");
}

#[test]
fn restitution_above_one_is_refused() {
    let e = refused(&replace("restitution = 0.6", "restitution = 1.2"));
    says(&e, "contacts[0].restitution", "must be in [0, 1] (got 1.2)");
}

#[test]
fn negative_restitution_is_refused() {
    let e = refused(&replace("restitution = 0.6", "restitution = -0.1"));
    says(&e, "contacts[0].restitution", "must be in [0, 1]");
}

#[test]
fn negative_friction_is_refused() {
    let e = refused(&(GOOD.to_string() + &SECOND.replace("friction = 0.2", "friction = -0.1")));
    says(&e, "contacts[1].friction", "must be >= 0 (got -0.1)");
}

#[test]
fn zero_length_normal_is_refused() {
    let e = refused(&replace("normal = [1.0, 0.0]", "normal = [0.0, 0.0]"));
    says(&e, "contacts[0].normal", "must not be zero length");
}

#[test]
fn nan_is_refused() {
    let e = refused(&replace("angular_velocity = 5.0", "angular_velocity = nan"));
    says(
        &e,
        "body.angular_velocity",
        "must be a finite number (got nan)",
    );
}

#[test]
fn infinity_in_a_vector_is_refused() {
    let e = refused(&replace("point = [-0.4, 0.25]", "point = [-0.4, -inf]"));
    says(
        &e,
        "contacts[0].point[1]",
        "must be a finite number (got -inf)",
    );
}

#[test]
fn unknown_key_gets_a_did_you_mean() {
    let e = refused(&replace(
        "inertia = 0.05",
        "inertia = 0.05\nangular_velocty = 1.0",
    ));
    says(
        &e,
        "body.angular_velocty",
        "unknown key; did you mean `angular_velocity`?",
    );
    says(&e, "body.angular_velocty", "allowed here: mass, inertia");
}

#[test]
fn unknown_section_gets_a_did_you_mean() {
    let e = refused(&(GOOD.to_string() + "[pivto]\npoint = [0.0, 0.0]\n"));
    says(&e, "pivto", "did you mean `pivot`?");
}

#[test]
fn duplicate_contact_names_are_refused() {
    let e = refused(&(GOOD.to_string() + &SECOND.replace("\"K2\"", "\"K\"")));
    says(&e, "contacts[1].name", "duplicate contact name \"K\"");
    says(&e, "contacts[1].name", "contacts[0]");
}

#[test]
fn no_contact_is_refused() {
    let text = &GOOD[..GOOD.find("[[contacts]]").unwrap()];
    let e = refused(text);
    says(&e, "contacts", "no contact: at least one [[contacts]]");
}

#[test]
fn more_than_sixteen_contacts_are_refused() {
    let mut text = GOOD.to_string();
    for i in 2..=17 {
        text += &SECOND.replace("\"K2\"", &format!("\"K{i}\""));
    }
    let e = refused(&text);
    says(&e, "contacts", "17 contacts; at most 16");
}

#[test]
fn non_positive_weight_is_refused() {
    let e = refused(&replace("weight = 1.0", "weight = 0.0"));
    says(&e, "contacts[0].weight", "must be > 0 (got 0)");
}

#[test]
fn velocity_inconsistent_with_the_pivot_is_refused() {
    let e = refused(&replace("velocity = [-0.5, 1.5]", "velocity = [-0.5, 1.4]"));
    says(&e, "body.velocity", "inconsistent with the pivot");
    // It says what the velocity should be.
    says(
        &e,
        "body.velocity",
        "omega x (C - O) = [-0.5, 1.5] (got [-0.5, 1.4])",
    );
}

#[test]
fn no_contact_approaching_is_refused() {
    let e = refused(
        &replace("angular_velocity = 5.0", "angular_velocity = -5.0")
            .replace("velocity = [-0.5, 1.5]", "velocity = [0.5, -1.5]"),
    );
    says(
        &e,
        "contacts",
        "no contact approaches (all normal velocities >= 0): nothing to solve",
    );
}

#[test]
fn an_unknown_law_is_refused() {
    let e = refused(&replace("law = \"poisson\"", "law = \"poison\""));
    says(
        &e,
        "law",
        "unknown value \"poison\"; did you mean \"poisson\"?",
    );
    says(&e, "law", "allowed: poisson, newton, stronge");
}

#[test]
fn a_missing_key_is_named() {
    let e = refused(&replace("mass = 2.0\n", ""));
    says(&e, "body.mass", "missing; required: a number > 0");
}

#[test]
fn a_free_body_needs_a_velocity() {
    let text = replace("[pivot]\npoint = [0.0, 0.0]\n", "").replace("velocity = [-0.5, 1.5]\n", "");
    let e = refused(&text);
    says(&e, "body.velocity", "missing; required for a free body");
}

#[test]
fn a_wrong_type_is_named() {
    let e = refused(&replace("mass = 2.0", "mass = \"2.0\""));
    says(&e, "body.mass", "must be a number (got the string \"2.0\")");
}

#[test]
fn every_problem_is_reported_at_once() {
    let text = replace("mass = 2.0", "mass = -2.0")
        .replace("friction = 0.3", "friction = -1.0")
        .replace("inertia = 0.05", "inertai = 0.05");
    let e = refused(&text);
    says(&e, "body.mass", "must be > 0");
    says(&e, "contacts[0].friction", "must be >= 0");
    says(&e, "body.inertai", "did you mean `inertia`?");
    says(&e, "body.inertia", "missing");
    assert_eq!(e.lines().count(), 4, "{e}");
}

#[test]
fn a_syntax_error_names_file_and_line() {
    let file = case_file(&replace("inertia = 0.05", "inertia = = 0.05"));
    let line = 1 + GOOD
        .lines()
        .position(|l| l.starts_with("inertia = 0.05"))
        .unwrap();
    let run = host_sim(&["impact", &file]);
    assert_eq!(run.status, 2);
    assert!(
        run.stderr.starts_with(&format!("error: {file}:{line}:")),
        "{}",
        run.stderr
    );
    assert!(run.stderr.contains("TOML syntax"), "{}", run.stderr);
    assert_eq!(run.stderr.lines().count(), 1, "{}", run.stderr);
}

#[test]
fn a_missing_file_is_a_user_mistake() {
    let run = host_sim(&["impact", "no/such/case.toml"]);
    run.refused("error: no/such/case.toml: cannot read the file: no such file");
}

#[test]
fn a_bad_option_value_exits_2() {
    let run = host_sim(&["impact", &case_file(GOOD), "--law", "hooke"]);
    run.refused("hooke");
    let run = host_sim(&["impact", &case_file(GOOD), "--format", "yaml"]);
    assert_eq!(run.status, 2);
}

// ---- The examples ----

const EXAMPLES: [&str; 4] = [
    "examples/impact/fig5-rotating-body.toml",
    "examples/impact/fig7-four-points.toml",
    "examples/impact/rocking-block.toml",
    "examples/impact/platform-two-feet.toml",
];

/// Runs an example with `--format json` and checks the document's shape.
fn example_json(file: &str, extra: &[&str]) -> Value {
    let mut args = vec!["impact", file, "--format", "json"];
    args.extend_from_slice(extra);
    let run = host_sim(&args);
    assert_eq!(run.status, 0, "{file}: {}", run.stderr);
    assert!(run.stderr.is_empty(), "{}", run.stderr);
    // One document, nothing else (from_str refuses trailing text).
    let doc: Value = serde_json::from_str(&run.stdout).expect("one JSON document");
    let pinned = doc.get("pivot").is_some();
    let expected: Vec<&str> = DOCUMENT_KEYS
        .into_iter()
        .filter(|&k| pinned || k != "pivot")
        .collect();
    assert_eq!(keys(&doc), expected, "{file}");
    for (_, c) in doc["contacts"].as_object().unwrap() {
        assert_eq!(keys(c), CONTACT_KEYS);
        for part in ["compression", "restitution"] {
            assert_eq!(keys(&c[part]), ["normal_impulse", "tangential_impulse"]);
        }
        for s in c["segments"].as_array().unwrap() {
            assert_eq!(keys(s), SEGMENT_KEYS);
        }
        assert!(c["case"].is_u64());
    }
    if pinned {
        assert_eq!(
            keys(&doc["pivot"]),
            ["impulse", "compression", "restitution"]
        );
    }
    assert!(doc["warnings"].is_array());
    doc
}

#[test]
fn every_example_runs_as_a_table() {
    for file in EXAMPLES {
        let run = host_sim(&["impact", file]);
        assert_eq!(run.status, 0, "{file}: {}", run.stderr);
        assert!(run.stdout.starts_with("law: poisson"), "{}", run.stdout);
        assert!(run.stdout.contains("warnings:"), "{}", run.stdout);
    }
}

#[test]
fn every_example_prints_the_documented_json() {
    for file in EXAMPLES {
        let doc = example_json(file, &[]);
        assert_eq!(doc["law"], "poisson");
    }
}

#[test]
fn the_law_option_overrides_the_file() {
    for law in ["newton", "stronge", "poisson"] {
        let doc = example_json(EXAMPLES[0], &["--law", law]);
        assert_eq!(doc["law"], law);
    }
}

fn close(got: &Value, want: f64) {
    let got = got.as_f64().expect("a number");
    assert!(
        (got - want).abs() <= 1e-9 * want.abs().max(1.0),
        "got {got}, want {want}"
    );
}

/// The numbers the comments of fig5-rotating-body.toml promise: the paper's
/// eqs. (5) and (6) with d = 0.1, h = 0.25, f = 0.3, R = 0.6, omega_0 = 4,
/// J_O = 0.06875.
#[test]
fn fig5_example_matches_the_papers_eq_5() {
    let doc = example_json(EXAMPLES[0], &[]);
    let (d, h, f, r, w0, j_o) = (0.1, 0.25, 0.3, 0.6, 4.0, 0.06875);
    let sni = j_o * w0 / (h + f * d);
    close(
        &doc["angular_velocity_after"],
        r * w0 * (d * f - h) / (h + f * d),
    );
    let k = &doc["contacts"]["K"];
    close(&k["compression"]["normal_impulse"], sni);
    close(&k["restitution"]["normal_impulse"], r * sni);
    close(&k["compression"]["tangential_impulse"], f * sni);
    close(&k["restitution"]["tangential_impulse"], -f * r * sni);
    assert_eq!(k["case"], 6);
    assert_eq!(k["case_name"], "reversal-in-restitution");
    close(&doc["pivot"]["compression"][0], -0.382142857142857);
    close(&doc["pivot"]["compression"][1], -1.1946428571428571);
    close(&doc["kinetic_energy_before"], 0.55);
}

/// fig7-four-points.toml: omega_2 = -omega_0 sum(R L^2) / sum(L^2) and eq. (9).
#[test]
fn fig7_example_matches_the_papers_eq_9() {
    let doc = example_json(EXAMPLES[1], &[]);
    let l = [0.1, 0.2, 0.3];
    let r = [0.2, 0.5, 0.8];
    let w0 = 3.0;
    let j_o = 0.0133333333333333 + 0.18f64.powi(2) + 0.02f64.powi(2);
    let sum_l2: f64 = l.iter().map(|x| x * x).sum();
    let sum_rl2: f64 = l.iter().zip(&r).map(|(x, e)| e * x * x).sum();
    close(&doc["angular_velocity_after"], -w0 * sum_rl2 / sum_l2);
    for (i, name) in ["K1", "K2", "K3"].iter().enumerate() {
        let c = &doc["contacts"][name];
        let s = l[i] * j_o * w0 / sum_l2;
        close(&c["compression"]["normal_impulse"], s);
        close(&c["restitution"]["normal_impulse"], r[i] * s);
        close(&c["tangential_impulse"], 0.0);
    }
}

/// rocking-block.toml: A sticks, angular momentum about A is conserved (Housner).
#[test]
fn rocking_block_example_conserves_angular_momentum_about_the_corner() {
    let doc = example_json(EXAMPLES[2], &[]);
    // H_A = J_C omega + m (C - A) x v_C = 0.04875 + 0.05625, I_A = J_C + m |AC|^2 = 0.13
    close(&doc["angular_velocity_after"], 0.105 / 0.13);
    let a = &doc["contacts"]["A"];
    close(&a["normal_velocity_after"], 0.0);
    close(&a["tangential_velocity_after"], 0.0);
    assert_eq!(a["case"], 7);
}

/// Defect: velocities near 1e300 gave a kinetic energy of `inf` (`null` in JSON)
/// without a word. Now a warning says the energy overflowed.
#[test]
fn an_overflowing_kinetic_energy_is_warned_about() {
    // Pinned: the centre's velocity follows omega x (C - O).
    let text = GOOD
        .replace("velocity = [-0.5, 1.5]", "velocity = [-5e300, 1.5e301]")
        .replace("angular_velocity = 5.0", "angular_velocity = 5e301");
    let file = case_file(&text);
    let r = host_sim(&["impact", &file, "--format", "json"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).unwrap();
    assert!(v["kinetic_energy_before"].is_null(), "{v}");
    let warnings = v["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .unwrap()
            .starts_with("kinetic energy out of range")),
        "{warnings:?}"
    );
}
