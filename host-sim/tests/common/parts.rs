//! What the tests of `tune --shard` and `merge` share: running host-sim in a
//! directory, reading and resealing a part, and the check that merged parts give
//! the whole sweep's outputs byte for byte.

use std::path::{Path, PathBuf};

use host_sim::tune::part::Part;

use super::Run;

/// A fresh scratch directory `name` of the test binary `tag`, with the reference
/// machine file copied in as `m.toml` (its tuning table beside it, as the file
/// names it), so that every directory names the machine alike.
pub fn scratch_with_machine(tag: &str, name: &str) -> PathBuf {
    let d = super::scratch(tag, name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch directory");
    let examples = super::machine().parent().unwrap().to_path_buf();
    std::fs::copy(super::machine(), d.join("m.toml")).unwrap();
    std::fs::copy(
        examples.join("vibro-driver.tuning.toml"),
        d.join("vibro-driver.tuning.toml"),
    )
    .unwrap();
    d
}

/// Runs `host-sim` with `args` in directory `cwd`.
pub fn run_in(cwd: &Path, args: &[&str]) -> Run {
    let mut cmd = super::host_sim();
    cmd.args(args).current_dir(cwd);
    super::finish(cmd)
}

/// `host-sim merge args...` in `cwd`.
pub fn merge(cwd: &Path, args: &[&str]) -> Run {
    let mut all = vec!["merge"];
    all.extend_from_slice(args);
    run_in(cwd, &all)
}

/// The bytes of file `p`.
pub fn bytes(p: PathBuf) -> Vec<u8> {
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// A partial result whose hashes can be computed again: a sweep's or a fit's.
pub trait Sealed: serde::Serialize + serde::de::DeserializeOwned {
    /// Sets its hashes from its contents.
    fn seal(&mut self);
}

impl Sealed for Part {
    fn seal(&mut self) {
        Part::seal(self)
    }
}

impl Sealed for host_sim::calibrate::part::Part {
    fn seal(&mut self) {
        host_sim::calibrate::part::Part::seal(self)
    }
}

/// Part `name` in `d` with `edit` made and its hashes computed again, written as
/// `out`: what someone who recomputes them makes.
pub fn resealed<P: Sealed>(d: &Path, name: &str, out: &str, edit: impl FnOnce(&mut P)) {
    let mut part: P = serde_json::from_slice(&bytes(d.join(name))).unwrap();
    edit(&mut part);
    part.seal();
    let text = serde_json::to_string_pretty(&part).unwrap();
    std::fs::write(d.join(out), text).unwrap();
}

/// The parts `parts` in `sharded` merged with the file options `outputs` give
/// the whole sweep's table (`table`, run in `whole` with `outputs`) on stdout,
/// `note` on stderr and its files byte for byte (the files `outputs` names
/// after `--write` and `--plot`); merged in reverse order with `--format json`,
/// its JSON (`json`).
pub fn merges_to_the_whole(
    sharded: &Path,
    whole: &Path,
    parts: &[&str],
    outputs: &[&str],
    (table, json): (&Run, &Run),
    note: &str,
) {
    let mut args = parts.to_vec();
    args.extend_from_slice(outputs);
    let merged = merge(sharded, &args);
    assert_eq!(merged.status, 0, "{}", merged.stderr);
    assert!(merged.stderr.contains(note), "{}", merged.stderr);
    assert_eq!(merged.stdout, table.stdout);
    let files = outputs
        .windows(2)
        .filter(|w| w[0] == "--write" || w[0] == "--plot")
        .map(|w| w[1]);
    for file in files {
        assert_eq!(
            bytes(sharded.join(file)),
            bytes(whole.join(file)),
            "{file} differs"
        );
    }
    let mut args: Vec<&str> = parts.iter().rev().copied().collect();
    args.extend_from_slice(&["--format", "json"]);
    let merged = merge(sharded, &args);
    assert_eq!(merged.status, 0, "{}", merged.stderr);
    assert_eq!(merged.stdout, json.stdout);
}
