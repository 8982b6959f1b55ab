//! What several tests of the machine file use.

use machine_file::input::{render, Location, Problem};

/// Asserts a problem at `key` whose message contains `fragment`.
pub fn assert_problem(problems: &[Problem], key: &str, fragment: &str) {
    let hit = problems
        .iter()
        .any(|p| p.location == Location::Key(key.to_string()) && p.message.contains(fragment));
    assert!(
        hit,
        "no problem at `{key}` containing {fragment:?}; got:\n{}",
        render(problems)
    );
}

/// The reference machine's text without its own `[uncertainty]` (the file's last
/// section), for the tests that give their own ranges.
#[allow(dead_code)]
pub fn reference_without_uncertainty() -> &'static str {
    let text = include_str!("../../../../examples/vibro-driver.toml");
    let (machine, ranges) = text
        .split_once("\n[uncertainty]\n")
        .expect("the reference machine's [uncertainty]");
    assert!(!ranges.contains("\n["), "[uncertainty] is the last section");
    machine
}
