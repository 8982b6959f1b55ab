//! `host-sim merge PART... [--machine MACHINE.toml] [--write FILE] [--plot FILE.svg]
//! [--format table|json]`
//!
//! Combines the partial results of `host-sim tune --shard I/N` ([`super::part`])
//! into the output of the whole sweep, byte for byte what `host-sim tune` without
//! `--shard` prints and writes, `tune --robust` as well (docs/scale-out.md; a
//! fit's parts, `calibrate --shard`, go to `crate::calibrate::part::merge`, which
//! the command line picks by the first part's format):
//! 1. read and check every part on its own ([`part::read`]), then together
//!    ([`part::assemble`]): one sweep, the same N, each part once, none missing;
//!    every problem at once, exit 2, before any run;
//! 2. the machine file the parts name (or `--machine`), its SHA-256 checked against
//!    theirs, loaded with their `--set` overrides; the sweep checked against
//!    `tune`'s limits ([`grid_problems`]: a part cannot ask for what `tune`
//!    refuses, whoever recomputed its hashes);
//! 3. the outputs opened ([`Report::open`]), then the sweep concluded from the
//!    grid's outcomes ([`super::conclude`]: the best offsets with their check runs,
//!    at most two per speed, and the warnings) and reported ([`Report::finish`]),
//!    as `tune` does.

use std::path::PathBuf;
use std::time::Instant;

use super::part;
use super::robust;
use super::{conclude, grid_problems, Report};
use crate::failure::{Console, Failure, Kind};
use crate::numbers::count;
use crate::numbers::warning_count;
use crate::parts::{quote, read_machine_file, MergeArgs};
use crate::sweep::{load_machine, progress_bar, refuse_interrupted, table_problems};

/// Runs the command (stages of the module doc).
pub fn run(args: &MergeArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. The parts.
    let mut parts = Vec::new();
    let mut problems = Vec::new();
    for path in &args.parts {
        match part::read(path) {
            Ok(p) => parts.push((path.clone(), p)),
            Err(e) => problems.extend(e.into_reasons()),
        }
    }
    if !problems.is_empty() {
        return Err(Failure::new(Kind::Usage, problems));
    }
    let (first, runs) = part::assemble(&parts)?;

    // 2. The machine.
    let path = args
        .machine
        .clone()
        .unwrap_or_else(|| PathBuf::from(&first.machine.path));
    let (text, sha256) = read_machine_file(&path).map_err(|p| {
        Failure::usage(format!(
            "{p}: the machine file the parts were made from{}",
            if args.machine.is_none() {
                " (give its path with --machine)"
            } else {
                ""
            }
        ))
    })?;
    if sha256 != first.machine.sha256 {
        return Err(Failure::usage(format!(
            "{}: not the machine file the parts were made from (its sha256 is {sha256}, theirs {})",
            path.display(),
            first.machine.sha256
        )));
    }
    let machine = load_machine(&path, &text, &first.sweep.set)?;
    let grid = first.sweep.grid();
    // The range texts as the messages quote them: cut (a part is anyone's file).
    let (speeds, offsets) = (quote(&first.sweep.speeds), quote(&first.sweep.offsets));
    let refused = grid_problems(&machine, &grid, &speeds, &offsets);
    if !refused.is_empty() {
        // The parts are one sweep (checked): the first one names it.
        let file = parts[0].0.display();
        let reasons = refused
            .iter()
            .map(|p| format!("{file}: a sweep tune refuses: {p}"));
        return Err(Failure::new(Kind::Usage, reasons));
    }
    if args.output.write.is_some() {
        let problems = table_problems(&grid.speeds_rpm, &speeds);
        if !problems.is_empty() {
            return Err(Failure::new(Kind::Usage, problems));
        }
    }

    // 3. As `tune` (or `tune --robust`) from its runs on.
    let report = Report::open(&args.output)?;
    let request = first.sweep.request(&first.machine);
    let started = Instant::now();
    let parts_count = count(first.shard.count, "part");
    if let Some(r) = first.sweep.robust {
        // The machines the parts ran on, drawn again from the file as tune drew
        // them; their runs machine by machine.
        let (uncertainty, machines) =
            robust::machines(&path, &text, &first.sweep.set, r.samples, r.seed)?;
        let by_machine: Vec<Vec<_>> = runs
            .chunks(grid.points().len())
            .map(<[_]>::to_vec)
            .collect();
        let robust = robust::conclude(grid, uncertainty, r.seed, &machines, &by_machine);
        robust::finish(&robust, &by_machine[0], report, &request, console)?;
        console.note(&format!(
            "merge: {parts_count} of {} robust runs ({} x {} starts x {}) in {:.1} s{}\n",
            runs.len(),
            count(r.samples, "machine"),
            robust::STARTS,
            count(robust.points.len(), "point"),
            started.elapsed().as_secs_f64(),
            warning_count(&robust.warnings)
        ));
        return Ok(());
    }
    let progress = progress_bar("merge", crate::sweep::best::most_checks(&grid));
    let grid_runs = runs.len();
    let tuning = conclude(&machine, grid, runs, &progress);
    progress.finish_and_clear();
    refuse_interrupted("merge", "the check runs are incomplete")?;
    let seconds = started.elapsed().as_secs_f64();
    report.finish(&tuning, &request, console)?;
    console.note(&format!(
        "merge: {parts_count} of {grid_runs} grid runs, {} in {:.1} s on {}{}\n",
        count(tuning.run_count - grid_runs, "check run"),
        seconds,
        count(rayon::current_num_threads(), "thread"),
        warning_count(&tuning.warnings)
    ));
    Ok(())
}
