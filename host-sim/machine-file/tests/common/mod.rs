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
