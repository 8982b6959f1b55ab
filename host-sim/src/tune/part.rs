//! A part of a sweep: `host-sim tune --shard I/N` runs the grid points `k` (0-based,
//! in [`Grid::points`] order) with `k % N == I - 1` and writes their outcomes as a
//! partial result ([`Part`], JSON); `host-sim merge` ([`super::merge`]) reads the N
//! parts ([`read`]), checks that they are one sweep's and complete ([`assemble`]),
//! and puts the outcomes back in grid order. docs/scale-out.md describes the
//! format for people.
//!
//! Three hashes tie a part to its sweep and to what `tune` wrote:
//! - `machine.sha256`: SHA-256 of the machine file's bytes as read;
//! - `sweep_sha256`: SHA-256 of `machine.sha256` (64 lowercase hex digits), one
//!   line feed, then the `sweep` object as compact JSON (serde_json, keys in the
//!   order of [`Sweep`], numbers in shortest round-trip form): the machine file,
//!   the host-sim version, the `--set` overrides, the speeds, the offsets and the
//!   end time, everything that changes a run's outcome;
//! - `part_sha256`: SHA-256 of the whole part as compact JSON with `part_sha256`
//!   itself empty ([`Part::hash`]): the above, the machine file's path, the shard
//!   and every run's outcome, everything the merged result depends on.
//!
//! A part whose hashes do not match its contents was edited or damaged and is
//! refused. They guard against accidents (an edit, a truncated copy, parts of
//! two sweeps), not against a forger, who can recompute them. So the values are
//! checked too, as `tune` checks its options ([`read`], and `merge` applies
//! tune's limits to the sweep a part names), and the machine file is read as
//! every input file is: a regular file of bounded size.
//!
//! Numbers are written in serde_json's shortest round-trip form and read back with
//! its `float_roundtrip` parser, so a merged outcome is the run's own `f64`, bit for
//! bit; a mean velocity that is not finite is written as the string `"NaN"`,
//! `"inf"` or `"-inf"`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use rayon::prelude::*;

use super::robust::{MAX_SAMPLES, STARTS};
use super::{Request, TuneArgs};
use crate::failure::{Console, Failure, Kind};
use crate::machine::{input, Machine};
use crate::numbers;
use crate::output::file::Staged;
use crate::parts::{
    is_sha256, quote, read_as, shard_problems, spec_sha256, unsealed_sha256, HashedFile, Shard,
};
use crate::sweep::{progress_bar, refuse_interrupted, MAX_POINTS};
use crate::sweep::{run_point, Grid, RunOutcome};

/// The `format` of a partial result.
pub const FORMAT: &str = "host-sim-tune-part";

/// The `version` of the format this host-sim writes and reads (2: with
/// `part_sha256`; 3: with each run's `not_a_travel`; 4: with `sweep.robust` and
/// each run's `machine`; 5: each run's outcome in its `run` object).
pub const VERSION: u64 = 5;

/// Everything besides the machine file that changes a run's outcome, and the
/// range texts the outputs name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sweep {
    /// The version of host-sim that ran it.
    pub host_sim_version: String,
    /// The `--set` overrides, in order.
    pub set: Vec<String>,
    /// `--speeds` as given (or the default range's text).
    pub speeds: String,
    /// `--offsets` as given (or the default).
    pub offsets: String,
    /// The grid's speeds, rpm, ascending.
    pub speeds_rpm: Vec<f64>,
    /// The grid's offsets, degrees in [0, 360), ascending.
    pub offsets_deg: Vec<f64>,
    /// End time of each run, s.
    pub t_end: f64,
    /// `tune --robust`'s machines, `null` for the plain sweep (the nominal
    /// machine alone).
    pub robust: Option<RobustSweep>,
}

/// The machines of a robust sweep (`tune --robust --samples S --seed X`): the
/// nominal one and `S - 1` drawn from the file's `[uncertainty]`, each from
/// [`STARTS`] starts: machine `m` is sample `m / STARTS` from start `m % STARTS`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobustSweep {
    /// `--samples`.
    pub samples: usize,
    /// `--seed`.
    pub seed: u64,
}

/// The outcome of grid point `point` on machine `machine`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartRun {
    /// Its index in grid order, from 0.
    pub point: usize,
    /// The machine it ran on: 0 in the plain sweep; in a robust one, sample
    /// `machine / 3` from start `machine % 3` ([`RobustSweep`]).
    pub machine: usize,
    /// What the run gave, as `tune` makes it.
    pub run: RunOutcome,
}

/// A partial result ([module doc](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u64,
    /// The machine file.
    pub machine: HashedFile,
    /// The sweep.
    pub sweep: Sweep,
    /// The hash of `machine.sha256` and `sweep` ([module doc](self)).
    pub sweep_sha256: String,
    /// Which part.
    pub shard: Shard,
    /// The outcomes of the part's grid points, ascending.
    pub runs: Vec<PartRun>,
    /// The hash of all of the above ([`Part::hash`]).
    pub part_sha256: String,
}

impl Part {
    /// `part_sha256` ([module doc](self)): SHA-256 of this part as compact JSON
    /// (keys in the order of [`Part`], numbers in shortest round-trip form) with
    /// `part_sha256` the empty string.
    pub fn hash(&self) -> String {
        unsealed_sha256(self, |p| p.part_sha256.clear())
    }

    /// Sets `sweep_sha256` and `part_sha256` from the contents.
    pub fn seal(&mut self) {
        self.sweep_sha256 = spec_sha256(&self.machine.sha256, &self.sweep);
        self.part_sha256 = self.hash();
    }
}

impl Sweep {
    /// The sweep of `grid` as `request` asked for it, on the machines of
    /// `robust` (`None`: the plain sweep).
    pub fn new(grid: &Grid, request: &Request, robust: Option<RobustSweep>) -> Sweep {
        Sweep {
            host_sim_version: env!("CARGO_PKG_VERSION").to_string(),
            set: request.set.clone(),
            speeds: request.speeds_text.clone(),
            offsets: request.offsets_text.clone(),
            speeds_rpm: grid.speeds_rpm.clone(),
            offsets_deg: grid.offsets_deg.clone(),
            t_end: grid.t_end,
            robust,
        }
    }

    /// The machines each grid point runs on: 1 in the plain sweep, `S` times
    /// [`STARTS`] in a robust one.
    pub fn machines(&self) -> usize {
        self.robust.map_or(1, |r| r.samples * STARTS)
    }

    /// The runs of the sweep: `M P` for `M` machines and `P` grid points.
    pub fn run_count(&self) -> usize {
        self.machines() * self.speeds_rpm.len() * self.offsets_deg.len()
    }

    /// Run `j`, `(machine, grid point)`: `j = m P + k`, machine by machine.
    pub fn run(&self, j: usize) -> (usize, usize) {
        let points = self.speeds_rpm.len() * self.offsets_deg.len();
        (j / points, j % points)
    }

    /// The grid.
    pub fn grid(&self) -> Grid {
        Grid {
            speeds_rpm: self.speeds_rpm.clone(),
            offsets_deg: self.offsets_deg.clone(),
            t_end: self.t_end,
        }
    }

    /// How it was asked for, with the machine file as `tune` named it and its
    /// SHA-256.
    pub fn request(&self, machine: &HashedFile) -> Request {
        Request {
            machine_path: PathBuf::from(&machine.path),
            machine_sha256: machine.sha256.clone(),
            set: self.set.clone(),
            speeds_text: self.speeds.clone(),
            offsets_text: self.offsets.clone(),
        }
    }

    /// What differs between `self` (of file `a`) and `other` (of file `b`), one
    /// phrase each, the values quoted cut ([`input::cut`]); empty when they are
    /// the same sweep.
    fn differences(&self, other: &Sweep, a: &str, b: &str) -> Vec<String> {
        let mut out = Vec::new();
        let mut differ = |what: &str, x: String, y: String| {
            let (x, y) = (quote(&x), quote(&y));
            out.push(format!("{what} differs ({x} in {a}, {y} in {b})"));
        };
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| numbers::sig(*x))
                .collect::<Vec<_>>()
                .join(", ")
        };
        if self.host_sim_version != other.host_sim_version {
            differ(
                "the host-sim version",
                self.host_sim_version.clone(),
                other.host_sim_version.clone(),
            );
        }
        if self.set != other.set {
            let set = |s: &[String]| {
                if s.is_empty() {
                    "none".to_string()
                } else {
                    s.join(" ")
                }
            };
            differ("--set", set(&self.set), set(&other.set));
        }
        if self.speeds != other.speeds || self.speeds_rpm != other.speeds_rpm {
            differ(
                "--speeds",
                format!("{} = [{}] rpm", self.speeds, list(&self.speeds_rpm)),
                format!("{} = [{}] rpm", other.speeds, list(&other.speeds_rpm)),
            );
        }
        if self.offsets != other.offsets || self.offsets_deg != other.offsets_deg {
            differ(
                "--offsets",
                format!("{} = [{}] deg", self.offsets, list(&self.offsets_deg)),
                format!("{} = [{}] deg", other.offsets, list(&other.offsets_deg)),
            );
        }
        if self.t_end.to_bits() != other.t_end.to_bits() {
            differ(
                "--t-end",
                format!("{} s", numbers::sig(self.t_end)),
                format!("{} s", numbers::sig(other.t_end)),
            );
        }
        if self.robust != other.robust {
            let robust = |r: Option<RobustSweep>| match r {
                Some(r) => format!("--samples {} --seed {}", r.samples, r.seed),
                None => "none: the plain sweep".to_string(),
            };
            differ("--robust", robust(self.robust), robust(other.robust));
        }
        out
    }

    /// Why the grid is not one `tune` makes (a hand-made or damaged file), if it
    /// is not: ranges empty, not ascending, offsets outside [0, 360), too many
    /// points, an end time that is not a positive number, a robust sweep's
    /// samples not from 1 to [`MAX_SAMPLES`].
    fn problem(&self) -> Option<String> {
        let ascending = |v: &[f64]| v.windows(2).all(|w| w[0] < w[1]);
        let (s, o) = (&self.speeds_rpm, &self.offsets_deg);
        if s.is_empty() || !ascending(s) || !s.iter().all(|x| x.is_finite() && *x > 0.0) {
            Some("speeds_rpm: not positive speeds, ascending".into())
        } else if o.is_empty() || !ascending(o) || !o.iter().all(|x| (0.0..360.0).contains(x)) {
            Some("offsets_deg: not offsets in [0, 360), ascending".into())
        } else if s.len().saturating_mul(o.len()) > MAX_POINTS {
            Some(format!("more than {MAX_POINTS} grid points"))
        } else if !(self.t_end.is_finite() && self.t_end > 0.0) {
            Some("t_end: not a positive number of seconds".into())
        } else {
            self.robust
                .filter(|r| !(1..=MAX_SAMPLES).contains(&r.samples))
                .map(|r| {
                    format!(
                        "robust.samples {}: not a count of machines from 1 to {MAX_SAMPLES}",
                        r.samples
                    )
                })
        }
    }
}

/// `tune --shard` (and `tune --robust --shard`): runs the part's runs, grid
/// points on `machines` (the one machine of the plain sweep; a robust sweep's
/// machines of [`RobustSweep`] in their order), and writes the partial result to
/// `--out-part` (stdout by default), whole or not at all.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_shard(
    args: &TuneArgs,
    shard: Shard,
    machines: &[&Machine],
    robust: Option<RobustSweep>,
    grid: Grid,
    request: &Request,
    console: &mut Console<'_>,
) -> Result<(), Failure> {
    let sweep = Sweep::new(&grid, request, robust);
    let all = sweep.run_count();
    let held = shard.runs(all).len();
    let command = if robust.is_some() {
        "tune --robust"
    } else {
        "tune"
    };
    // A part merge reads: at most as many runs as the largest grid
    // ([`MAX_BYTES`] holds them with every warning kept).
    if held > MAX_POINTS {
        return Err(Failure::usage(format!(
            "{command} --shard {shard}: {} runs in this part, at most {MAX_POINTS} a part: the sweep has {} runs, give N of at least {}",
            held,
            all,
            all.div_ceil(MAX_POINTS)
        )));
    }
    let mine: Vec<usize> = shard.runs(all).collect();
    let out = args.out_part.clone().unwrap_or_else(|| PathBuf::from("-"));
    let mut staged = Staged::new();
    let output = staged.add("--out-part", &out)?;

    let started = Instant::now();
    let points = grid.points();
    let progress = progress_bar(command, mine.len());
    let runs: Vec<RunOutcome> = mine
        .par_iter()
        .map(|&j| {
            let (m, k) = sweep.run(j);
            let (speed, offset) = points[k];
            let outcome = run_point(machines[m], speed, offset, grid.t_end);
            progress.inc(1);
            outcome
        })
        .collect();
    progress.finish_and_clear();
    refuse_interrupted("tune", "the part is incomplete")?;
    let seconds = started.elapsed().as_secs_f64();

    let mut part = Part {
        format: FORMAT.into(),
        version: VERSION,
        machine: HashedFile {
            path: request.machine_path.display().to_string(),
            sha256: request.machine_sha256.clone(),
        },
        sweep: sweep.clone(),
        sweep_sha256: String::new(),
        shard,
        runs: mine
            .iter()
            .zip(runs)
            .map(|(&j, run)| PartRun {
                point: sweep.run(j).1,
                machine: sweep.run(j).0,
                run,
            })
            .collect(),
        part_sha256: String::new(),
    };
    part.seal();
    let mut text = serde_json::to_string_pretty(&part).map_err(|e| {
        Failure::run(format!(
            "{command} --shard {shard}: the part does not serialize: {e}"
        ))
    })?;
    text.push('\n');
    staged.write(output, &text)?;
    staged.commit()?;
    console.note(&format!(
        "{command}: part {shard}: {} of {} {} in {:.1} s on {}, written to {}\n",
        part.runs.len(),
        all,
        if robust.is_some() {
            "runs"
        } else {
            "grid runs"
        },
        seconds,
        crate::numbers::count(rayon::current_num_threads(), "thread"),
        if out.as_os_str() == "-" {
            "stdout".to_string()
        } else {
            out.display().to_string()
        }
    ));
    Ok(())
}

/// Reads the partial result `path` (a regular file of at most [`crate::parts::MAX_BYTES`])
/// and checks it on its own: its format and version, its fields, its hashes,
/// its shard, that its runs are exactly its grid points, and that a run that
/// held its offset has a mean velocity (a number, as [`run_point`] makes it).
///
/// [`run_point`]: crate::sweep::run_point
pub fn read(path: &Path) -> Result<Part, Failure> {
    let part: Part = read_as(path, FORMAT, VERSION, "host-sim tune --shard")?;
    let damaged = |why: String| {
        Failure::usage(format!(
            "{}: a damaged partial result: {why}",
            path.display()
        ))
    };
    if part.sweep_sha256 != spec_sha256(&part.machine.sha256, &part.sweep) {
        return Err(damaged(
            "sweep_sha256 does not match the machine's hash and the sweep it describes (the file was edited)".into(),
        ));
    }
    if let Some(why) = part.sweep.problem() {
        return Err(damaged(why));
    }
    // merge's check runs are this host-sim's: the parts' runs must be too.
    let this = env!("CARGO_PKG_VERSION");
    if part.sweep.host_sim_version != this {
        return Err(Failure::usage(format!(
            "{}: a part of host-sim {}, this is host-sim {this}: run the parts and the merge with one host-sim",
            path.display(),
            quote(&part.sweep.host_sim_version)
        )));
    }
    // The machine file's hash and path as `tune` writes them: a path no file can
    // have is not opened, and no output names it.
    if !is_sha256(&part.machine.sha256) {
        return Err(damaged(format!(
            "machine.sha256 {}: not a SHA-256 (64 lowercase hex digits)",
            input::quoted(&part.machine.sha256)
        )));
    }
    if part.machine.path.len() > input::MAX_PATH_SHOWN {
        return Err(damaged(format!(
            "machine.path {}: longer than a path a file can be opened by ({} bytes)",
            input::quoted(&part.machine.path),
            input::MAX_PATH_SHOWN
        )));
    }
    let Shard { index, count } = part.shard;
    if count == 0 || count > MAX_POINTS || index == 0 || index > count {
        return Err(damaged(format!(
            "shard {index}/{count}: not 1 <= I <= N <= {MAX_POINTS}"
        )));
    }
    let points = part.sweep.grid().points();
    let mut mine = part.shard.runs(part.sweep.run_count());
    let same = part.runs.iter().all(|r| {
        mine.next().is_some_and(|j| {
            (r.machine, r.point) == part.sweep.run(j)
                && (r.run.speed_rpm, r.run.offset_deg) == points[r.point]
        })
    }) && mine.next().is_none();
    if !same {
        return Err(damaged(format!(
            "its runs are not the runs of part {}",
            part.shard
        )));
    }
    if part.part_sha256 != part.hash() {
        return Err(damaged(format!(
            "part {}: part_sha256 does not match its contents: its runs, its shard or its machine file's path were edited after tune wrote it",
            part.shard
        )));
    }
    // As `run_point` makes them ([`RunOutcome::problem`]).
    for r in &part.runs {
        if let Some(why) = r.run.problem() {
            let on = if part.sweep.robust.is_some() {
                format!(" on machine {}", r.machine)
            } else {
                String::new()
            };
            return Err(damaged(format!(
                "run {}{on} ({} rpm, {} deg): {why}",
                r.point,
                numbers::sig(r.run.speed_rpm),
                numbers::sig(r.run.offset_deg),
            )));
        }
    }
    Ok(part)
}

/// The parts `(file, part)` as one sweep: the first part's, with every run's
/// outcome in run order ([`Sweep::run`]: the grid's points in grid order,
/// machine by machine). Refused, every problem naming the files: parts of
/// different sweeps (what differs), parts that disagree on N, a part given
/// twice, a part missing.
pub fn assemble(parts: &[(PathBuf, Part)]) -> Result<(Part, Vec<RunOutcome>), Failure> {
    let Some((first_path, first)) = parts.first() else {
        return Err(Failure::usage("merge: no parts given"));
    };
    let a = first_path.display().to_string();
    let mut problems = Vec::new();
    for (path, part) in &parts[1..] {
        let b = path.display().to_string();
        let mut differences = Vec::new();
        if part.machine.sha256 != first.machine.sha256 {
            differences.push(format!(
                "the machine file differs (sha256 {} in {a}, {} in {b})",
                first.machine.sha256, part.machine.sha256
            ));
        }
        differences.extend(first.sweep.differences(&part.sweep, &a, &b));
        if !differences.is_empty() {
            problems.push(format!(
                "{b}: a part of another sweep than {a}: {}",
                differences.join("; ")
            ));
        } else if part.shard.count != first.shard.count {
            problems.push(format!(
                "{b}: part {} but {a} is part {}: the parts disagree on N",
                part.shard, first.shard
            ));
        }
    }
    if problems.is_empty() {
        let given: Vec<(&Path, Shard)> = parts
            .iter()
            .map(|(p, part)| (p.as_path(), part.shard))
            .collect();
        problems.extend(shard_problems(&given, "a sweep"));
    }
    if !problems.is_empty() {
        return Err(Failure::new(Kind::Usage, problems));
    }
    // The grid's own speeds and offsets (equal to the runs', checked by `read`).
    let points = first.sweep.grid().points();
    let all = first.sweep.run_count();
    let count = points.len();
    let mut runs: Vec<Option<RunOutcome>> = vec![None; all];
    for (_, part) in parts {
        for r in &part.runs {
            runs[r.machine * count + r.point] = Some(RunOutcome {
                speed_rpm: points[r.point].0,
                offset_deg: points[r.point].1,
                ..r.run.clone()
            });
        }
    }
    // Every run is some part's (each part checked on its own, none missing).
    let runs = runs.into_iter().flatten().collect::<Vec<_>>();
    if runs.len() != all {
        return Err(Failure::usage(
            "merge: the parts do not cover the sweep (an internal error)",
        ));
    }
    Ok((first.clone(), runs))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_reads_back_bit_for_bit() {
        // Numbers whose shortest form the default parser may read an ulp off.
        let values = [
            0.1 + 0.2,
            2.2250738585072014e-308,
            5e-324,
            1.7976931348623157e308,
            0.026978362416430108,
            -1.297364141220728e-7,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for v in values {
            let part_run = PartRun {
                point: 0,
                machine: 0,
                run: RunOutcome {
                    speed_rpm: 3000.0,
                    offset_deg: 0.1 * 3.0,
                    mean_velocity: v,
                    not_held: None,
                    not_a_travel: None,
                    plant_warnings: vec![],
                },
            };
            let back: PartRun =
                serde_json::from_str(&serde_json::to_string_pretty(&part_run).unwrap()).unwrap();
            assert_eq!(back.run.mean_velocity.to_bits(), v.to_bits(), "{v}");
            assert_eq!(
                back.run.offset_deg.to_bits(),
                part_run.run.offset_deg.to_bits()
            );
        }
    }
}
