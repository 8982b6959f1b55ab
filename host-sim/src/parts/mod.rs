//! A computation in parts: a sweep (`host-sim tune --shard I/N`) or a fit's
//! multistart (`host-sim calibrate --shard I/N`) split into N partial results
//! that run anywhere, and `host-sim merge`, which reads them back, checks them
//! and concludes the whole. What both kinds of part share lives here: the shard
//! ([`Shard`], `--shard`), an input file named with its hash ([`HashedFile`],
//! [`read_machine_file`]), the hashes that tie a part to what made it
//! ([`sha256_hex`], [`spec_sha256`], [`unsealed_sha256`]), the one reader of a
//! part's JSON and the check that the N parts are all there
//! ([`shard_problems`]). Each kind's own fields, checks and merge are
//! `crate::tune::part` and `crate::calibrate::part`; docs/scale-out.md describes
//! the files for people.

use std::path::PathBuf;

use clap::Args;
use serde::{Deserialize, Serialize};

use crate::args::TuneOutputs;
use crate::help::epilogue;
use crate::sweep::MAX_POINTS;

mod hash;
mod read;

pub use hash::{sha256_hex, spec_sha256, unsealed_sha256};
pub(crate) use read::{is_sha256, quote, read_as};
pub use read::{read_machine_file, shard_problems, MAX_BYTES};

/// Which part of the grid: part `index` (from 1) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shard {
    /// I, from 1 to N.
    pub index: usize,
    /// N, the number of parts.
    pub count: usize,
}

impl Shard {
    /// Whether run `j` (0-based: grid point `k` on machine `m` is run
    /// `j = m P + k` of a grid of `P` points) is this part's.
    pub fn holds(self, j: usize) -> bool {
        j % self.count == self.index - 1
    }

    /// The runs of this part among `runs`, ascending (an iterator: `runs` may
    /// be a number a damaged part claims).
    pub fn runs(self, runs: usize) -> impl ExactSizeIterator<Item = usize> {
        (self.index - 1..runs).step_by(self.count)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// `--shard I/N`: whole numbers, `1 <= I <= N`, N at most [`MAX_POINTS`] (the
/// largest grid).
pub fn parse_shard(text: &str) -> Result<Shard, String> {
    let usage = || "expected I/N, part I of N with 1 <= I <= N, e.g. 1/4".to_string();
    let (i, n) = text.split_once('/').ok_or_else(usage)?;
    let whole = |s: &str| s.trim().parse::<usize>().ok();
    let (Some(index), Some(count)) = (whole(i), whole(n)) else {
        return Err(usage());
    };
    if count == 0 || count > MAX_POINTS {
        return Err(format!(
            "N must be from 1 to {MAX_POINTS} (the most grid points), got {count}"
        ));
    }
    if index == 0 || index > count {
        return Err(format!(
            "I must be from 1 to N = {count} (I counts from 1), got {index}"
        ));
    }
    Ok(Shard { index, count })
}

/// An input file a part was made from (the machine file, a fit's measured
/// file), as named and with its SHA-256.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HashedFile {
    /// As named on the command line (the outputs name it so).
    pub path: String,
    /// SHA-256 of its bytes, lowercase hex.
    pub sha256: String,
}

/// Arguments of `host-sim merge`.
#[derive(Debug, Args)]
#[command(after_help = epilogue(
    &[
        "host-sim tune examples/vibro-driver.toml --t-end 4 --shard 1/2 --out-part part1.json",
        "host-sim tune examples/vibro-driver.toml --t-end 4 --shard 2/2 --out-part part2.json",
        "host-sim merge part1.json part2.json --write my.tuning.toml --plot tune.svg",
    ],
    &[],
    &["docs/scale-out.md", "docs/tuning.md"],
))]
pub struct MergeArgs {
    /// The partial results of `host-sim tune --shard I/N` (with or without
    /// `--robust`) or of `host-sim calibrate --shard I/N`: all N parts of one
    /// sweep or fit, in any order.
    #[arg(value_name = "PART.json", required = true)]
    pub parts: Vec<PathBuf>,
    /// The machine file the parts were made from, when it is not where they name
    /// it (the same file: its SHA-256 must match theirs) [default: the path in the
    /// parts].
    #[arg(long, value_name = "MACHINE.toml")]
    pub machine: Option<PathBuf>,
    /// The outputs, as for `tune`.
    #[command(flatten)]
    pub output: TuneOutputs,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_split_the_grid() {
        assert_eq!(parse_shard("2/3"), Ok(Shard { index: 2, count: 3 }));
        for bad in ["0/3", "4/3", "1/0", "a/b", "1", "1/2/3", "", "1/10001"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
        // Every point in exactly one part.
        let parts: Vec<Vec<usize>> = (1..=3)
            .map(|index| Shard { index, count: 3 }.runs(8).collect())
            .collect();
        assert_eq!(parts, [vec![0, 3, 6], vec![1, 4, 7], vec![2, 5]]);
    }
}
