//! `host-sim tune MACHINE [--speeds A:B:STEP] [--offsets A:B:STEP] [--t-end T]
//! [--write FILE] [--plot FILE.svg] [--format table|json] [--set KEY=VALUE]...
//! [--shard I/N [--out-part FILE.json]]`
//!
//! Sweeps rotor speed and phase offset in closed loop and finds, at every speed,
//! the offset that travels right fastest and the one that travels left fastest
//! (docs/tuning.md).
//!
//! A machine with one rotor has no phase offset and its controller no tuning
//! table to use: `tune` refuses it (exit 2, `one_rotor_refusal`).
//!
//! Stages of [`run`]:
//! 1. read and check the machine file with the `--set` overrides, and the options
//!    into a [`crate::sweep::Grid`]: every problem at once, exit 2, before any run;
//! 2. sweep: one closed-loop run per grid point ([`crate::sweep::run_point`]: the `shared`
//!    controller holding the point's offset, `Command::HoldOffset` from `t = 0`),
//!    in parallel on all cores; results are collected by grid index, so the output
//!    is the same whatever the number of threads;
//! 3. best offsets per speed and direction ([`crate::sweep::best::best_offsets`]): the grid's extreme,
//!    refined by a parabola through it and its two neighbours in offset, the
//!    refined offset checked by one more run (also in parallel);
//! 4. warnings: runs whose offset was not held, speeds with no travel one way;
//! 5. outputs ([`Report`]): `--write` and `--plot` files, each whole or not at
//!    all, then the result on stdout as a table or JSON; one summary line on stderr.
//!
//! With `--shard I/N` stage 2 runs only the grid points `k` with `k % N == I - 1`
//! and, instead of stages 3 to 5, writes their outcomes as a partial result
//! ([`part`]); `host-sim merge` ([`merge`]) reads the N parts back into the whole
//! grid's outcomes and goes on with stages 3 to 5 through the same functions
//! ([`conclude`], [`Report`]), so its output is the unsharded one byte for byte.
//! With `--robust --shard I/N` the parts split the robust runs (point `k` on
//! machine `m` is run `j = m P + k`), and `merge` goes on through
//! [`robust::conclude`] and [`robust::finish`].
//!
//! With `--robust` ([`robust`]) stage 2 runs every point on the machines the
//! file's `[uncertainty]` allows, from three starts each, and stages 3 to 5 are
//! [`robust::conclude`] and its outputs: the offsets that travel their way on all
//! of them with the best 10th percentile.

pub mod merge;
pub mod part;
pub mod plot;
pub mod report;
pub mod robust;

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::args::Format;
use crate::args::TuneOutputs;
use crate::args::{MachineArg, SetArgs, TEndArg};
use crate::failure::{Console, Failure, Kind};
use crate::help::epilogue;
use crate::machine::tuning_file;
use crate::machine::Machine;
use crate::numbers;
use crate::numbers::count;
use crate::numbers::warning_count;
use crate::output::file::Staged;
use crate::output::progress::Progress;
use crate::parts::{read_machine_file, Shard};
use crate::simulation::closed_loop;
use crate::simulation::limits;
use crate::sweep::best::Tuning;
use crate::sweep::best::{best_offsets, warnings};
use crate::sweep::default_speeds;
use crate::sweep::run_points;
use crate::sweep::wrap_offsets;
use crate::sweep::Grid;
use crate::sweep::RunOutcome;
use crate::sweep::{
    load_machine, progress_bar, refuse_interrupted, table_problems, DEFAULT_T_END, MAX_POINTS,
};
use crate::sweep::{parse_offsets, parse_speeds, Range};
use report::table_file;
use report::tuning_json;
use report::tuning_table;

/// Arguments of `host-sim tune`.
#[derive(Debug, Args)]
#[command(mut_arg("t_end", |a| a.help("End time of each run, s; the mean velocity is over the second half [default: 5]")))]
#[command(after_help = epilogue(
    &[
        "host-sim tune examples/vibro-driver.toml --speeds 2750:3000:250 --offsets 0:360:90 --t-end 4",
        "host-sim tune examples/vibro-driver.toml --write my.tuning.toml --plot tune.svg",
        "host-sim tune examples/vibro-driver.toml --shard 1/2 --out-part part1.json",
    ],
    &[],
    &["docs/tuning.md", "docs/scale-out.md (--shard)"],
))]
pub struct TuneArgs {
    /// The machine file.
    #[command(flatten)]
    pub machine: MachineArg,
    /// Rotor speeds, rpm: `A:B:STEP` from A to B, both included, or one value
    /// (default: `[controller].speed_rpm` -500 to +500 in steps of 250).
    #[arg(long, value_name = "A:B:STEP", allow_hyphen_values = true, value_parser = parse_speeds)]
    pub speeds: Option<Range>,
    /// Phase offsets, degrees: `A:B:STEP` from A to B, both included (360 is 0
    /// and runs once), or one value [default: 0:360:15].
    #[arg(long, value_name = "A:B:STEP", allow_hyphen_values = true, value_parser = parse_offsets)]
    pub offsets: Option<Range>,
    /// End time.
    #[command(flatten)]
    pub t_end: TEndArg,
    /// The outputs.
    #[command(flatten)]
    pub output: TuneOutputs,
    /// Overrides.
    #[command(flatten)]
    pub set: SetArgs,
    /// Run only part I of N of the runs (the grid points k with k % N == I - 1,
    /// in grid order; with --robust, the runs j = m P + k of point k on machine
    /// m with j % N == I - 1) and write a partial result for `host-sim merge`
    /// instead of the outputs (see docs/scale-out.md).
    #[arg(long, value_name = "I/N", value_parser = crate::parts::parse_shard, conflicts_with_all = ["write", "plot", "format"])]
    pub shard: Option<Shard>,
    /// Where `--shard` writes its partial result, written whole (`-`: stdout)
    /// [default: -].
    #[arg(long, value_name = "FILE.json", requires = "shard")]
    pub out_part: Option<PathBuf>,
    /// Evaluate every point on machines drawn from the file's `[uncertainty]`, from
    /// three starts each, and choose the offsets that travel their way on all of
    /// them with the best 10th percentile (see docs/tuning.md, "Robust tuning").
    #[arg(long)]
    pub robust: bool,
    /// Machines of `--robust`: the nominal one and N - 1 drawn [default: 8].
    #[arg(long, value_name = "N", requires = "robust", value_parser = parse_samples)]
    pub samples: Option<usize>,
    /// Seed of `--robust`'s draw [default: 1].
    #[arg(long, value_name = "S", requires = "robust")]
    pub seed: Option<u64>,
}

/// `--samples N`: a count from 1 to [`robust::MAX_SAMPLES`].
fn parse_samples(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (1..=robust::MAX_SAMPLES).contains(&n) => Ok(n),
        _ => Err(format!(
            "expected a count of machines from 1 to {} (got {text:?})",
            robust::MAX_SAMPLES
        )),
    }
}

/// How a sweep was asked for: what its outputs name besides its results (the
/// table's title, the tuning file's "regenerate with" command, the plot's title).
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// The machine file as named on the command line.
    pub machine_path: PathBuf,
    /// The SHA-256 of the machine file's text that was checked and run.
    pub machine_sha256: String,
    /// The `--set` overrides, in order.
    pub set: Vec<String>,
    /// `--speeds` as given, or the default range's text.
    pub speeds_text: String,
    /// `--offsets` as given, or the default.
    pub offsets_text: String,
}

/// Default `--offsets`: every 15 degrees around the turn (24 runs a speed; 360
/// is 0 and runs once). Fine enough for the parabola through the best three.
pub const DEFAULT_OFFSETS: &str = "0:360:15";

/// Stage 1: the machine ([`load_machine`]) and the grid, with how they were
/// asked for (for the outputs).
fn read_options(args: &TuneArgs) -> Result<(Machine, Grid, Request, String), Failure> {
    let (text, machine_sha256) = read_machine_file(&args.machine.path)?;
    let machine = load_machine(&args.machine.path, &text, &args.set.keys)?;
    let (lo, hi) = closed_loop::speed_range_rpm(&machine);
    let mut problems = Vec::new();

    // Speeds: given, or around the nominal speed.
    let (speeds_rpm, speeds_text) = match &args.speeds {
        Some(r) => (r.points.clone(), r.text.clone()),
        None => {
            let (s, t) = default_speeds(machine.controller.speed_rpm, lo, hi);
            if s.is_empty() {
                problems.push(format!(
                    "tune: [controller].speed_rpm = {} is outside the controller's speed range [{}, {}] rpm; give --speeds",
                    numbers::sig(machine.controller.speed_rpm),
                    numbers::sig(lo),
                    numbers::sig(hi)
                ));
            }
            (s, t)
        }
    };

    // Offsets: at most one turn (checked by the parser), wrapped to [0, 360).
    let default_offsets;
    let offsets_range = match &args.offsets {
        Some(r) => r,
        None => {
            default_offsets = parse_offsets(DEFAULT_OFFSETS).expect("the default range is valid");
            &default_offsets
        }
    };
    let offsets_text = offsets_range.text.clone();
    let grid = Grid {
        speeds_rpm,
        offsets_deg: wrap_offsets(&offsets_range.points),
        t_end: args.t_end.seconds.unwrap_or(DEFAULT_T_END),
    };
    problems.extend(grid_problems(&machine, &grid, &speeds_text, &offsets_text));
    if args.output.write.is_some() {
        problems.extend(table_problems(&grid.speeds_rpm, &speeds_text));
    }
    if !problems.is_empty() {
        return Err(Failure::new(Kind::Usage, problems));
    }
    let request = Request {
        machine_path: args.machine.path.clone(),
        machine_sha256,
        set: args.set.keys.clone(),
        speeds_text,
        offsets_text,
    };
    Ok((machine, grid, request, text))
}

/// What `tune` refuses in a sweep of `grid` on `machine` (with `--speeds` given
/// as `speeds_text`, `--offsets` as `offsets_text`), one text each: speeds
/// outside the controller's range, an end time that is not a positive number
/// or beyond one run's limits ([`limits::check`], the trace rows of
/// `simulation.output_step` included), more than [`MAX_POINTS`] runs. The one
/// definition for `tune`'s options and for the sweep a part of `merge` names.
pub fn grid_problems(
    machine: &Machine,
    grid: &Grid,
    speeds_text: &str,
    offsets_text: &str,
) -> Vec<String> {
    let (lo, hi) = closed_loop::speed_range_rpm(machine);
    let mut problems = Vec::new();
    let outside: Vec<String> = grid
        .speeds_rpm
        .iter()
        .filter(|v| !(**v >= lo && **v <= hi))
        .map(|v| numbers::sig(*v))
        .collect();
    if !outside.is_empty() {
        problems.push(format!(
            "--speeds {speeds_text}: {} rpm outside the controller's speed range [{}, {}] rpm (min_speed_rpm to max_speed_rpm, 80 % of the no-load speed): the controller would refuse the command",
            outside.join(", "),
            numbers::sig(lo),
            numbers::sig(hi)
        ));
    }
    let t_end = grid.t_end;
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(format!(
            "--t-end {t_end}: must be a positive number of seconds"
        ));
    }
    problems.extend(limits::check(machine, t_end, "--t-end"));
    let (s, o) = (grid.speeds_rpm.len(), grid.offsets_deg.len());
    if s.saturating_mul(o) > MAX_POINTS {
        problems.push(format!(
            "--speeds {speeds_text} --offsets {offsets_text}: {s} speeds x {o} offsets = {} runs, at most {MAX_POINTS}",
            s.saturating_mul(o)
        ));
    }
    problems
}

/// Runs the command (stages of the module doc).
pub fn run(args: &TuneArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. The machine and the grid.
    let (machine, grid, request, text) = read_options(args)?;
    if args.robust {
        let (path, sets) = (&args.machine.path, &args.set.keys);
        let samples = args.samples.unwrap_or(robust::DEFAULT_SAMPLES);
        let seed = args.seed.unwrap_or(robust::DEFAULT_SEED);
        let (uncertainty, machines) = robust::machines(path, &text, sets, samples, seed)?;
        if let Some(shard) = args.shard {
            let on: Vec<&Machine> = machines.iter().map(|m| &m.2).collect();
            let robust = Some(part::RobustSweep { samples, seed });
            return part::run_shard(args, shard, &on, robust, grid, &request, console);
        }
        return robust::run(args, uncertainty, &machines, grid, &request, console);
    }
    if let Some(shard) = args.shard {
        return part::run_shard(args, shard, &[&machine], None, grid, &request, console);
    }
    // The output files, checked and opened before the sweep: a path that cannot
    // be written is refused at once, not after minutes of runs.
    let report = Report::open(&args.output)?;

    // 2.-4. The sweep, with its progress on stderr; the total counts the check
    // runs from the start.
    let started = Instant::now();
    let progress = progress_bar(
        "tune",
        grid.points().len() + crate::sweep::best::most_checks(&grid),
    );
    let tuning = tune(&machine, grid, &progress);
    progress.finish_and_clear();
    refuse_interrupted("tune", "the sweep is incomplete")?;
    let seconds = started.elapsed().as_secs_f64();

    // 5. Files, then the result.
    report.finish(&tuning, &request, console)?;
    console.note(&format!(
        "tune: {} runs in {:.1} s on {}{}\n",
        tuning.run_count,
        seconds,
        count(rayon::current_num_threads(), "thread"),
        warning_count(&tuning.warnings)
    ));
    Ok(())
}

/// Stages 2 to 4 on a checked machine and grid.
pub fn tune(machine: &Machine, grid: Grid, progress: &Progress) -> Tuning {
    let points = grid.points();
    let runs = run_points(machine, &points, grid.t_end, progress);
    conclude(machine, grid, runs, progress)
}

/// Stages 3 and 4 on the outcomes of every grid point, in [`Grid::points`] order:
/// the best offsets (with their check runs) and the warnings. `tune` calls it on
/// its own runs, `merge` on the runs the parts made.
pub fn conclude(
    machine: &Machine,
    grid: Grid,
    runs: Vec<RunOutcome>,
    progress: &Progress,
) -> Tuning {
    let (right, left, checks) = best_offsets(machine, &grid, &runs, progress);
    let warnings = warnings(&grid, &runs, &right, &left);
    Tuning {
        run_count: runs.len() + checks,
        grid,
        runs,
        right,
        left,
        warnings,
    }
}

/// Stage 5: the outputs of a sweep, opened before its runs ([`Report::open`]) and
/// written after them ([`Report::finish`]).
pub struct Report {
    pub(crate) staged: Staged,
    /// The tuning table's output and path (`--write`).
    pub(crate) table: Option<(usize, PathBuf)>,
    /// The plot's output (`--plot`).
    pub(crate) plot: Option<usize>,
    pub(crate) format: Format,
}

impl Report {
    /// Checks and opens the output files: a path that cannot be written is
    /// refused before any run.
    pub fn open(output: &TuneOutputs) -> Result<Report, Failure> {
        let mut staged = Staged::new();
        let table = match &output.write {
            Some(p) => Some((staged.add("--write", p)?, p.clone())),
            None => None,
        };
        let plot = staged.add_optional("--plot", output.plot.file.as_deref())?;
        Ok(Report {
            staged,
            table,
            plot,
            format: output.format.format,
        })
    }

    /// Writes the files (all or none), then the result on stdout: printed
    /// whether or not the files could be written (the table cannot be made, an
    /// output cannot be written), so that the sweep is never thrown away; their
    /// error comes after it.
    pub fn finish(
        self,
        tuning: &Tuning,
        request: &Request,
        console: &mut Console<'_>,
    ) -> Result<(), Failure> {
        let result = match self.format {
            Format::Json => tuning_json(tuning),
            Format::Table => tuning_table(tuning, &request.machine_path),
        };
        let written = self.write(tuning, request);
        console.print(&result);
        written
    }

    /// The files of [`Report::finish`], all or none.
    fn write(mut self, tuning: &Tuning, request: &Request) -> Result<(), Failure> {
        if let Some((i, path)) = &self.table {
            if tuning.right.is_empty() || tuning.left.is_empty() {
                return Err(Failure::run("--write: no speed has a best offset both ways (no run gave a mean velocity): nothing written; the sweep is above"));
            }
            let text = table_file(tuning, request, path);
            // What is written must read back as a table the controller takes.
            let readable = tuning_file::parse(&path.display().to_string(), &text)
                .ok()
                .and_then(|rows| tuning_file::table(&rows).ok());
            if readable.is_none() {
                return Err(Failure::run(format!(
                    "--write {}: the table does not read back (an internal error)",
                    path.display()
                )));
            }
            self.staged.write(*i, &text)?;
        }
        if let Some(i) = self.plot {
            let title = format!("host-sim tune {}", request.machine_path.display());
            self.staged.write(i, &plot::plot_svg(tuning, &title))?;
        }
        self.staged.commit()
    }
}

#[cfg(test)]
mod tests;
