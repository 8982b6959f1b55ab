//! A fit's multistart in parts: `host-sim calibrate ... --shard I/N` evaluates
//! the starts `k` (0-based, in the order of [`fit::starts`], each distinct start
//! once) with `k % N == I - 1` and writes their runs as a partial result
//! ([`Part`], JSON); `host-sim merge` of the N parts ([`merge`]) checks them, takes
//! their runs as the evaluations of those starts and goes on with the fit from
//! there: the best starts, the local searches from them, the Jacobian, the
//! numerical noise and the outputs, through the very code of the unsharded
//! `calibrate` (`fit_and_report`), so its result is the unsharded one byte
//! for byte. docs/scale-out.md describes the format for people.
//!
//! The hashes are those of a sweep's parts ([`crate::parts`]):
//! - `fit_sha256`: SHA-256 of `machine.sha256`, one line feed, then the `fit`
//!   object as compact JSON (the measured file's hash, the keys, the `--set`s, the
//!   end time, the starts, the host-sim version: everything a run depends on);
//! - `part_sha256`: SHA-256 of the whole part as compact JSON with `part_sha256`
//!   empty: the above, the paths, the shard and every run.
//!
//! They find an edit, a damaged copy and a part of another fit, not a forger; the
//! values are checked too: every start is the one the fit makes at its index
//! (to the bit), its runs are the measured points' in their order, each as
//! `tune`'s run makes it ([`RunOutcome::problem`]).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::fit::{self, Settings};
use super::keys;
use super::{
    bits, fit_and_report, nominal_start, read_options, refusal, CalibrateArgs, Evaluated, Inputs,
    Trials,
};
use crate::args::{FormatArg, MachineArg, SetArgs, TEndArg};
use crate::failure::{Console, Failure, Kind, Reason};
use crate::machine::input;
use crate::numbers;
use crate::numbers::count;
use crate::output::file::Staged;
use crate::parts::{
    is_sha256, quote, read_as, sha256_hex, shard_problems, spec_sha256, unsealed_sha256,
    HashedFile, MergeArgs, Shard, MAX_BYTES,
};
use crate::sweep::RunOutcome;
use crate::sweep::{load_machine, progress_bar, refuse_interrupted};

/// The `format` of a fit's partial result.
pub const FORMAT: &str = "host-sim-calibrate-part";

/// The `version` of the format this host-sim writes and reads.
pub const VERSION: u64 = 1;

/// Everything besides the machine file that a start's runs depend on, and the
/// names the outputs give.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitSpec {
    /// The version of host-sim that ran it.
    pub host_sim_version: String,
    /// The measured file, as named on `calibrate`'s command line, and its SHA-256.
    pub measured: HashedFile,
    /// `--fit`, the keys as given.
    pub keys: Vec<String>,
    /// The `--set` overrides, in order.
    pub set: Vec<String>,
    /// End time of each run, s.
    pub t_end: f64,
    /// The distinct starts of the multistart.
    pub starts: usize,
}

/// The runs of one start.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartRuns {
    /// Its index among the distinct starts, from 0.
    pub start: usize,
    /// Its coordinates, each key's range normalised to [0, 1].
    pub u: Vec<f64>,
    /// The machine reader's refusal of its values, or `null`.
    pub refused: Option<String>,
    /// One run per measured point, in the points' order (none when refused).
    pub runs: Vec<RunOutcome>,
}

/// A fit's partial result ([module doc](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u64,
    /// The machine file.
    pub machine: HashedFile,
    /// The fit.
    pub fit: FitSpec,
    /// The hash of `machine.sha256` and `fit`.
    pub fit_sha256: String,
    /// Which part.
    pub shard: Shard,
    /// The part's starts, ascending.
    pub starts: Vec<StartRuns>,
    /// The hash of all of the above ([`Part::hash`]).
    pub part_sha256: String,
}

impl Part {
    /// `part_sha256`: SHA-256 of this part as compact JSON with `part_sha256`
    /// the empty string.
    pub fn hash(&self) -> String {
        unsealed_sha256(self, |p| p.part_sha256.clear())
    }

    /// Sets `fit_sha256` and `part_sha256` from the contents.
    pub fn seal(&mut self) {
        self.fit_sha256 = fit_sha256(&self.machine.sha256, &self.fit);
        self.part_sha256 = self.hash();
    }
}

/// `fit_sha256` ([module doc](self)).
pub fn fit_sha256(machine_sha256: &str, fit: &FitSpec) -> String {
    spec_sha256(machine_sha256, fit)
}

/// The distinct starts of a fit of `p` keys from `given` with `settings`, in
/// their order ([`fit::starts`], a start equal to an earlier one dropped: the
/// fit evaluates it once).
pub fn distinct_starts(p: usize, given: &[Vec<f64>], settings: &Settings) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = Vec::new();
    for u in fit::starts(p, given, settings) {
        if !out.iter().any(|v| bits(v) == bits(&u)) {
            out.push(u);
        }
    }
    out
}

/// `calibrate --shard`: evaluates the part's starts and writes the partial
/// result to `--out-part` (stdout by default), whole or not at all.
pub(crate) fn run_shard(
    args: &CalibrateArgs,
    shard: Shard,
    console: &mut Console<'_>,
) -> Result<(), Failure> {
    let inputs = read_options(args)?;
    let out = args.out_part.clone().unwrap_or_else(|| PathBuf::from("-"));
    let mut staged = Staged::new();
    let output = staged.add("--out-part", &out)?;

    let p = inputs.keys.len();
    let settings = Settings::for_keys(p);
    let starts = distinct_starts(p, &[nominal_start(&inputs.keys)], &settings);
    let mine: Vec<usize> = shard.runs(starts.len()).collect();
    let batch: Vec<Vec<f64>> = mine.iter().map(|&k| starts[k].clone()).collect();
    let points = inputs.data.speeds_offsets();
    let started = Instant::now();
    let mut trials = Trials {
        args,
        inputs: &inputs,
        progress: progress_bar("calibrate", batch.len() * points.len()),
        points,
        outcomes: HashMap::new(),
        preset: HashMap::new(),
        refused: Vec::new(),
        runs: 0,
    };
    let evaluated = trials.evaluate(&batch);
    trials.progress.finish_and_clear();
    let evaluated = evaluated?;
    refuse_interrupted("calibrate", "the part is incomplete")?;
    let runs = trials.runs;

    let mut part = Part {
        format: FORMAT.into(),
        version: VERSION,
        machine: HashedFile {
            path: args.machine.path.display().to_string(),
            sha256: sha256_hex(inputs.text.as_bytes()),
        },
        fit: FitSpec {
            host_sim_version: env!("CARGO_PKG_VERSION").to_string(),
            measured: HashedFile {
                path: args.measured_file().display().to_string(),
                sha256: inputs.measured_sha256.clone(),
            },
            keys: args.fit.clone(),
            set: args.set.keys.clone(),
            t_end: inputs.t_end,
            starts: starts.len(),
        },
        fit_sha256: String::new(),
        shard,
        starts: mine
            .iter()
            .zip(batch)
            .zip(evaluated)
            .map(|((&start, u), e)| match e {
                Ok(sims) => StartRuns {
                    start,
                    u,
                    refused: None,
                    runs: sims,
                },
                Err(why) => StartRuns {
                    start,
                    u,
                    refused: Some(why),
                    runs: Vec::new(),
                },
            })
            .collect(),
        part_sha256: String::new(),
    };
    part.seal();
    let mut text = serde_json::to_string_pretty(&part).map_err(|e| {
        Failure::run(format!(
            "calibrate --shard {shard}: the part does not serialize: {e}"
        ))
    })?;
    text.push('\n');
    staged.write(output, &text)?;
    staged.commit()?;
    console.note(&format!(
        "calibrate: part {shard}: {} of {} starts ({}) in {:.1} s on {}, written to {}\n",
        part.starts.len(),
        starts.len(),
        count(runs, "run"),
        started.elapsed().as_secs_f64(),
        count(rayon::current_num_threads(), "thread"),
        if out.as_os_str() == "-" {
            "stdout".to_string()
        } else {
            out.display().to_string()
        }
    ));
    Ok(())
}

/// Whether the first of `parts` is a fit's partial result (its `format`), so
/// that `merge` takes them as such; a file that cannot be read or is no part of
/// a fit is left to the sweep's merge, which says why.
pub fn names_a_fit(parts: &[PathBuf]) -> bool {
    parts
        .first()
        .and_then(|p| input::read_text_at_most(p, MAX_BYTES).ok())
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .is_some_and(|v| v.get("format") == Some(&Value::String(FORMAT.into())))
}

/// Reads the partial result `path` and checks it on its own: its format and
/// version, its fields, its hashes, its shard, the host-sim version, and its
/// runs as `tune`'s run makes them.
pub fn read(path: &Path) -> Result<Part, Failure> {
    let part: Part = read_as(path, FORMAT, VERSION, "host-sim calibrate --shard")?;
    let damaged = |why: String| {
        Failure::usage(format!(
            "{}: a damaged partial result: {why}",
            path.display()
        ))
    };
    if part.fit_sha256 != fit_sha256(&part.machine.sha256, &part.fit) {
        return Err(damaged(
            "fit_sha256 does not match the machine's hash and the fit it describes (the file was edited)".into(),
        ));
    }
    let this = env!("CARGO_PKG_VERSION");
    if part.fit.host_sim_version != this {
        return Err(Failure::usage(format!(
            "{}: a part of host-sim {}, this is host-sim {this}: run the parts and the merge with one host-sim",
            path.display(),
            quote(&part.fit.host_sim_version)
        )));
    }
    for (what, sha) in [
        ("machine.sha256", &part.machine.sha256),
        ("fit.measured.sha256", &part.fit.measured.sha256),
    ] {
        if !is_sha256(sha) {
            return Err(damaged(format!(
                "{what} {}: not a SHA-256 (64 lowercase hex digits)",
                input::quoted(sha)
            )));
        }
    }
    for (what, p) in [
        ("machine.path", &part.machine.path),
        ("fit.measured.path", &part.fit.measured.path),
    ] {
        if p.len() > input::MAX_PATH_SHOWN {
            return Err(damaged(format!(
                "{what} {}: longer than a path a file can be opened by ({} bytes)",
                input::quoted(p),
                input::MAX_PATH_SHOWN
            )));
        }
    }
    let Shard { index, count } = part.shard;
    let most = crate::sweep::MAX_POINTS;
    if count == 0 || count > most || index == 0 || index > count {
        return Err(damaged(format!(
            "shard {index}/{count}: not 1 <= I <= N <= {most}"
        )));
    }
    if part
        .starts
        .iter()
        .map(|s| s.start)
        .ne(part.shard.runs(part.fit.starts))
    {
        return Err(damaged(format!(
            "its starts are not the starts of part {}",
            part.shard
        )));
    }
    if part.part_sha256 != part.hash() {
        return Err(damaged(format!(
            "part {}: part_sha256 does not match its contents: its runs, its shard or its files' paths were edited after calibrate wrote it",
            part.shard
        )));
    }
    for s in &part.starts {
        if s.refused.is_some() && !s.runs.is_empty() {
            return Err(damaged(format!(
                "start {}: refused by the machine reader, yet with runs",
                s.start
            )));
        }
        for r in &s.runs {
            if let Some(why) = r.problem() {
                return Err(damaged(format!(
                    "start {} ({} rpm, {} deg): {why}",
                    s.start,
                    numbers::sig(r.speed_rpm),
                    numbers::sig(r.offset_deg)
                )));
            }
        }
    }
    Ok(part)
}

/// What differs between the fits of parts `a` and `b` (files `fa`, `fb`), one
/// phrase each; empty when they are one fit's.
fn differences(a: &Part, b: &Part, fa: &str, fb: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut differ = |what: &str, x: String, y: String| {
        out.push(format!(
            "{what} differs ({} in {fa}, {} in {fb})",
            quote(&x),
            quote(&y)
        ));
    };
    if a.machine.sha256 != b.machine.sha256 {
        differ(
            "the machine file",
            format!("sha256 {}", a.machine.sha256),
            format!("sha256 {}", b.machine.sha256),
        );
    }
    let (x, y) = (&a.fit, &b.fit);
    if x.measured.sha256 != y.measured.sha256 {
        differ(
            "the measured file",
            format!("sha256 {}", x.measured.sha256),
            format!("sha256 {}", y.measured.sha256),
        );
    }
    if x.keys != y.keys {
        differ("--fit", x.keys.join(","), y.keys.join(","));
    }
    if x.set != y.set {
        differ("--set", x.set.join(" "), y.set.join(" "));
    }
    if x.t_end.to_bits() != y.t_end.to_bits() {
        differ(
            "--t-end",
            format!("{} s", numbers::sig(x.t_end)),
            format!("{} s", numbers::sig(y.t_end)),
        );
    }
    // Every other field follows from those above (read checks the version).
    if x != y && x.starts != y.starts {
        differ(
            "the starts",
            format!("{}", x.starts),
            format!("{}", y.starts),
        );
    }
    out
}

/// `host-sim merge` of a fit's parts: checked on their own and together (one
/// fit, the same N, each part once, none missing), the machine and measured
/// files read where the parts name them and checked against their hashes, the
/// starts checked against those the fit makes, then the fit from the parts'
/// evaluations on (`fit_and_report`).
pub fn merge(args: &MergeArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    let parts = read_parts(args)?;
    check_one_fit(&parts)?;
    let first = &parts[0].1;
    let calibrate = calibrate_args(first, args);
    let inputs = read_options(&calibrate).map_err(|f| {
        f.ending_with(": the files the parts were made from (merge where calibrate ran)")
    })?;
    check_files(first, &inputs)?;
    let preset = evaluations(&parts, &calibrate, &inputs)?;
    fit_and_report(&calibrate, inputs, preset, console)
}

/// Every part read and checked on its own, with the options a fit's merge
/// refuses (`--machine`, `--plot`); every problem at once.
fn read_parts(args: &MergeArgs) -> Result<Vec<(PathBuf, Part)>, Failure> {
    let mut refused = Vec::new();
    if args.machine.is_some() {
        refused.push(Reason::new("merge: --machine: a fit's parts are merged where they were made (its outputs name the machine and measured files as calibrate was given them)"));
    }
    if args.output.plot.file.is_some() {
        refused.push(Reason::new("merge: --plot: calibrate has no plot; a fit's parts merge to --write OUT.toml and --format table|json"));
    }
    let mut parts = Vec::new();
    for path in &args.parts {
        match read(path) {
            Ok(p) => parts.push((path.clone(), p)),
            Err(e) => refused.extend(e.into_reasons()),
        }
    }
    if !refused.is_empty() {
        return Err(Failure::new(Kind::Usage, refused));
    }
    Ok(parts)
}

/// The parts together: one fit, the same N, each part once, none missing.
fn check_one_fit(parts: &[(PathBuf, Part)]) -> Result<(), Failure> {
    let (first_path, first) = &parts[0];
    let a = first_path.display().to_string();
    let mut problems = Vec::new();
    for (path, part) in &parts[1..] {
        let b = path.display().to_string();
        let d = differences(first, part, &a, &b);
        if !d.is_empty() {
            problems.push(format!(
                "{b}: a part of another fit than {a}: {}",
                d.join("; ")
            ));
        } else if part.shard.count != first.shard.count {
            problems.push(format!(
                "{b}: part {} but {a} is part {}: the parts disagree on N",
                part.shard, first.shard
            ));
        }
    }
    if problems.is_empty() {
        let given: Vec<(&Path, Shard)> =
            parts.iter().map(|(p, x)| (p.as_path(), x.shard)).collect();
        problems.extend(shard_problems(&given, "a fit"));
    }
    if !problems.is_empty() {
        return Err(Failure::new(Kind::Usage, problems));
    }
    Ok(())
}

/// The fit as calibrate was asked for it (the parts' fit), with the merge's
/// outputs.
fn calibrate_args(first: &Part, args: &MergeArgs) -> CalibrateArgs {
    let fit = &first.fit;
    CalibrateArgs {
        machine: MachineArg {
            path: PathBuf::from(&first.machine.path),
        },
        measured: Some(PathBuf::from(&fit.measured.path)),
        capture: None,
        firmware_machine: None,
        fit: fit.keys.clone(),
        write: args.output.write.clone(),
        format: FormatArg {
            format: args.output.format.format,
        },
        t_end: TEndArg {
            seconds: Some(fit.t_end),
        },
        set: SetArgs {
            keys: fit.set.clone(),
        },
        shard: None,
        out_part: None,
    }
}

/// The machine and measured files read again are those the parts were made
/// from: their SHA-256s match the parts'.
fn check_files(first: &Part, inputs: &Inputs) -> Result<(), Failure> {
    let fit = &first.fit;
    let sha = sha256_hex(inputs.text.as_bytes());
    let mut changed = Vec::new();
    if sha != first.machine.sha256 {
        changed.push(format!(
            "{}: not the machine file the parts were made from (its sha256 is {sha}, theirs {})",
            first.machine.path, first.machine.sha256
        ));
    }
    if inputs.measured_sha256 != fit.measured.sha256 {
        changed.push(format!(
            "{}: not the measured file the parts were made from (its sha256 is {}, theirs {})",
            fit.measured.path, inputs.measured_sha256, fit.measured.sha256
        ));
    }
    if !changed.is_empty() {
        return Err(Failure::new(Kind::Usage, changed));
    }
    Ok(())
}

/// The parts' evaluations by start, checked: their starts are those the fit
/// makes, their runs the measured points', a refused start refused by the
/// machine reader as it says.
fn evaluations(
    parts: &[(PathBuf, Part)],
    calibrate: &CalibrateArgs,
    inputs: &Inputs,
) -> Result<HashMap<Vec<u64>, Evaluated>, Failure> {
    let fit = &parts[0].1.fit;
    let p = inputs.keys.len();
    let starts = distinct_starts(p, &[nominal_start(&inputs.keys)], &Settings::for_keys(p));
    let points = inputs.data.speeds_offsets();
    let mut preset: HashMap<Vec<u64>, Evaluated> = HashMap::new();
    for (path, part) in parts {
        let damaged = |why: String| {
            Failure::usage(format!(
                "{}: a damaged partial result: {why}",
                path.display()
            ))
        };
        if part.fit.starts != starts.len() {
            return Err(damaged(format!(
                "{} starts, the fit of {} makes {}",
                part.fit.starts,
                count(p, "key"),
                starts.len()
            )));
        }
        for s in &part.starts {
            if bits(&s.u) != bits(&starts[s.start]) {
                return Err(damaged(format!(
                    "start {}: not the start the fit makes there",
                    s.start
                )));
            }
            let runs_match = s.runs.len() == points.len()
                && s.runs
                    .iter()
                    .zip(&points)
                    .all(|(r, &(speed, offset))| (r.speed_rpm, r.offset_deg) == (speed, offset));
            if s.refused.is_none() && !runs_match {
                return Err(damaged(format!(
                    "start {}: its runs are not the measured file's {}",
                    s.start,
                    count(points.len(), "point")
                )));
            }
            // A refusal is the reader's own (no run: checked here at once).
            let mut sets = fit.set.clone();
            sets.extend(keys::sets_at(&inputs.keys, &s.u));
            let reader = load_machine(&calibrate.machine.path, &inputs.text, &sets)
                .err()
                .map(|e| refusal(&e));
            if reader != s.refused {
                return Err(damaged(format!(
                    "start {}: refused: {} where the machine reader says {}",
                    s.start,
                    s.refused.as_deref().map_or("null".into(), input::quoted),
                    reader.as_deref().map_or("null".into(), input::quoted)
                )));
            }
            let evaluated = match &s.refused {
                Some(why) => Err(why.clone()),
                None => Ok(s.runs.clone()),
            };
            preset.insert(bits(&s.u), evaluated);
        }
    }
    Ok(preset)
}
