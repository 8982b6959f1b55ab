//! Reading what a part names and what it is: the machine file with its hash, a
//! part's JSON of one format and version, the numbers that may not be finite, and
//! the check that the N parts given are each there once.

use std::path::Path;

use serde_json::Value;

use super::hash::sha256_hex;
use super::Shard;
use crate::failure::Failure;
use crate::machine::input::{self, Problem};

/// The largest partial result read, bytes: 64 MiB. A run's outcome takes about
/// 200 bytes, so the largest grid, 10 000 runs, about 2 MB; with the most plant
/// warnings and the longest texts a run keeps ([`crate::sweep::MAX_PLANT_WARNINGS`],
/// [`crate::sweep::MAX_REASON_BYTES`]) under 5 KB a run, 50 MB.
pub const MAX_BYTES: u64 = 64 << 20;

/// The machine file's text and the SHA-256 of it: read once, so that the hash a
/// partial result names is of the very text checked and run.
pub fn read_machine_file(path: &Path) -> Result<(String, String), Problem> {
    let text = input::read_text(path)?;
    let sha256 = sha256_hex(text.as_bytes());
    Ok((text, sha256))
}

/// A field of a part for a message: [`input::cut`] at [`input::MAX_QUOTED`] (a
/// part is a file anyone can write: a 10 MB field must not make a 10 MB line).
pub(crate) fn quote(field: &str) -> String {
    input::cut(field, input::MAX_QUOTED)
}

/// Whether `s` is a SHA-256 as a part writes it: 64 lowercase hex digits.
pub(crate) fn is_sha256(s: &str) -> bool {
    s.len() == 64
        && s.bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

/// Reads the partial result `path` (a regular file of at most [`MAX_BYTES`]) of
/// `format` and `version`, written by `command` (for the messages): JSON, its
/// `format` and `version` (before its fields, so that a file of another kind or
/// version is named so), then its fields, every one there and of its type (no
/// other). The one reader of `tune`'s and `calibrate`'s parts.
pub(crate) fn read_as<P: serde::de::DeserializeOwned>(
    path: &Path,
    format: &str,
    version: u64,
    command: &str,
) -> Result<P, Failure> {
    let not_a_part = |why: &str| {
        Failure::usage(format!(
            "{}: not a partial result of `{command}`: {why}",
            path.display()
        ))
    };
    let text = input::read_text_at_most(path, MAX_BYTES)?;
    let value: Value =
        serde_json::from_str(&text).map_err(|e| not_a_part(&format!("not JSON ({e})")))?;
    match value.get("format") {
        Some(Value::String(f)) if f == format => {}
        Some(f) => {
            return Err(not_a_part(&format!(
                "its format is {}, not {format:?}",
                quote(&f.to_string())
            )))
        }
        None => return Err(not_a_part(&format!("no \"format\": {format:?}"))),
    }
    if value.get("version").and_then(Value::as_u64) != Some(version) {
        return Err(Failure::usage(format!(
            "{}: partial result version {}: this host-sim reads version {version}",
            path.display(),
            quote(&value.get("version").unwrap_or(&Value::Null).to_string())
        )));
    }
    // serde's message quotes the value it refused: cut as the reader's are.
    serde_json::from_value(value).map_err(|e| {
        Failure::usage(format!(
            "{}: a damaged partial result: {}",
            path.display(),
            input::cut(&e.to_string(), input::MAX_PATH_SHOWN)
        ))
    })
}

/// What is wrong with the shards `given` (each part's file and shard, all of one
/// N, the first's): a part given twice, a part missing (`whole` names what the N
/// parts make, `a sweep` or `a fit`); one text each.
pub fn shard_problems(given: &[(&Path, Shard)], whole: &str) -> Vec<String> {
    let mut problems = Vec::new();
    let Some(count) = given.first().map(|g| g.1.count) else {
        return problems;
    };
    let mut seen: Vec<Option<&Path>> = vec![None; count];
    for &(path, shard) in given {
        match seen[shard.index - 1] {
            Some(other) => problems.push(format!(
                "{}: part {shard} again ({} is part {shard} too)",
                path.display(),
                other.display(),
            )),
            None => seen[shard.index - 1] = Some(path),
        }
    }
    let missing: Vec<String> = (1..=count)
        .filter(|i| seen[i - 1].is_none())
        .map(|i| i.to_string())
        .collect();
    if !missing.is_empty() {
        let shown: Vec<String> = seen
            .iter()
            .zip(1..)
            .filter_map(|(p, i)| p.map(|p| format!("{i}/{count} ({})", p.display())))
            .collect();
        problems.push(format!(
            "merge: part{} {} of {count} missing: given {}; {whole} in {count} parts needs all of them",
            if missing.len() == 1 { "" } else { "s" },
            missing.join(", "),
            shown.join(", ")
        ));
    }
    problems
}
