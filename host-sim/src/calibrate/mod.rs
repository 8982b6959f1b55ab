//! `host-sim calibrate MACHINE --measured FILE.csv --fit KEY[,KEY...]
//! [--write OUT.toml] [--format table|json] [--t-end T] [--set KEY=VALUE]...`
//!
//! Fits keys of the machine file to the travel speeds measured on the real
//! machine (docs/calibration.md): by least squares
//! on the mean travel velocity of each measured run, within each key's range.
//!
//! Stages of [`run`]:
//! 1. read and check, every problem at once (exit 2) before any run: the machine
//!    file with the `--set`s (as `tune` runs it: two rotors, no tuning table), the
//!    fitted keys and their ranges ([`keys`]), the measured file ([`measured`]),
//!    `--t-end`, the output file (opened, staged);
//! 2. the fit ([`fit`]): one evaluation is one closed-loop run per distinct
//!    `(speed, offset)` of the measured file (`tune`'s [`run_point`], holding the
//!    offset from `t = 0`), all the runs of a batch of points in parallel; a run
//!    that does not hold its offset gives its rows the residual
//!    [`NOT_HELD_RESIDUAL_MPS`];
//! 3. the standard errors and the keys not identified ([`precision`]);
//! 4. the outputs ([`report`]): `--write` (the machine file with the fitted values,
//!    nothing else changed, checked to read back), then the result on stdout as a
//!    table or JSON, each row's residual in both; one summary line on stderr.

pub mod fit;
pub mod keys;
pub mod precision;
pub mod report;

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use rayon::prelude::*;

use crate::args::{FormatArg, MachineArg, SetArgs, TEndArg};
use crate::failure::{Console, Failure};
use crate::help::epilogue;
use crate::machine::input;
use crate::measured::{self, Row};
use crate::output::file::Staged;
use crate::simulation::closed_loop;
use crate::simulation::limits;
use crate::tune::report::count;
use crate::tune::sweep::{run_point, RunOutcome};
use crate::tune::{load_machine, progress_bar, read_machine_file, warning_count, DEFAULT_T_END};
use fit::Settings;
use keys::FitKey;

/// Arguments of `host-sim calibrate`.
#[derive(Debug, Args)]
#[command(mut_arg("t_end", |a| a.help("End time of each simulated run, s; the mean velocity is over the second half, as `tune`'s [default: 5]")))]
#[command(mut_arg("format", |a| a.help("Output format of the result")))]
#[command(after_help = epilogue(
    &[
        "host-sim device --port /dev/ttyUSB0 tune --speeds 3000 --offsets 0:180:30 --for 4 --out measured.csv",
        "host-sim calibrate examples/vibro-driver.toml --measured measured.csv --fit 'contacts.*.restitution'",
        "host-sim calibrate examples/vibro-driver.toml --measured measured.csv --fit 'contacts.*.restitution' --write calibrated.toml",
    ],
    &[],
    &["docs/calibration.md"],
))]
pub struct CalibrateArgs {
    /// The machine file.
    #[command(flatten)]
    pub machine: MachineArg,
    /// The measured travel: CSV `speed_rpm,offset_deg,velocity_mps[,weight]`, one
    /// row per run on the real machine (see docs/calibration.md).
    #[arg(long, value_name = "FILE.csv")]
    pub measured: PathBuf,
    /// The keys to fit, `--set` keys with `*` for every element together, e.g.
    /// `contacts.*.restitution,contacts.*.friction`.
    #[arg(
        long,
        value_name = "KEY[,KEY...]",
        value_delimiter = ',',
        required = true
    )]
    pub fit: Vec<String>,
    /// Write the machine file with the fitted values (everything else as it was).
    #[arg(long, value_name = "OUT.toml")]
    pub write: Option<PathBuf>,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
    /// End time.
    #[command(flatten)]
    pub t_end: TEndArg,
    /// Overrides.
    #[command(flatten)]
    pub set: SetArgs,
}

/// The residual of a row whose simulated run did not hold its offset, m/s: twice
/// the reference machine's fastest travel (50 mm/s at 3500 rpm), so that a fit
/// holding every offset always scores better than one that does not.
pub const NOT_HELD_RESIDUAL_MPS: f64 = 0.1;

/// What was read in stage 1.
pub struct Inputs {
    /// The machine file's text, as checked.
    pub text: String,
    /// The fitted keys.
    pub keys: Vec<FitKey>,
    /// The measured rows.
    pub rows: Vec<Row>,
    /// The distinct (speed rpm, offset degrees) points of the rows.
    pub points: Vec<(f64, f64)>,
    /// Each row's index in `points`.
    pub of_row: Vec<usize>,
    /// End time of each run, s.
    pub t_end: f64,
}

/// Stage 1 (without the output).
fn read_options(args: &CalibrateArgs) -> Result<Inputs, String> {
    let path = &args.machine.path;
    let (text, _) = read_machine_file(path)?;
    let machine = load_machine(path, &text, &args.set.keys)?;
    let params = closed_loop::params(&machine).map_err(|p| input::render(&p))?;
    let mut problems = Vec::new();
    let keys = keys::resolve(path, &text, &args.set.keys, &args.fit)
        .map_err(|e| problems.push(e))
        .ok();
    let speeds = (
        f64::from(params.min_speed_rpm),
        f64::from(params.max_speed_rpm),
    );
    let rows = measured::read(&args.measured, Some(speeds))
        .and_then(|(_, rows)| {
            // A file with a header alone (a sweep stopped before its first
            // answer) is well formed, but there is nothing to fit.
            if rows.is_empty() {
                Err(format!(
                    "error: {}: no rows after the header: one row per measured run\n",
                    args.measured.display()
                ))
            } else {
                Ok(rows)
            }
        })
        .map_err(|e| problems.push(e))
        .ok();
    let t_end = args.t_end.seconds.unwrap_or(DEFAULT_T_END);
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(format!(
            "error: --t-end {t_end}: must be a positive number of seconds\n"
        ));
    }
    for p in limits::check(&machine, t_end, "--t-end") {
        problems.push(p + "\n");
    }
    match (keys, rows) {
        (Some(keys), Some(rows)) if problems.is_empty() => {
            let (points, of_row) = measured::points(&rows);
            Ok(Inputs {
                text,
                keys,
                rows,
                points,
                of_row,
                t_end,
            })
        }
        _ => Err(problems
            .iter()
            .map(|p| {
                if p.ends_with('\n') {
                    p.clone()
                } else {
                    format!("{p}\n")
                }
            })
            .collect()),
    }
}

/// What stages 2 and 3 found, for the outputs.
pub struct Calibration {
    /// The fitted keys.
    pub keys: Vec<FitKey>,
    /// The measured rows.
    pub rows: Vec<Row>,
    /// The fitted value of each key (rounded as written).
    pub fitted: Vec<f64>,
    /// Each key's standard error, in its units.
    pub std_error: Vec<Option<f64>>,
    /// How far each key's fit may lie from the least-squares point by the
    /// search's last step, in its units.
    pub resolution: Vec<Option<f64>>,
    /// The search.
    pub fit: fit::Fit,
    /// The estimates behind the standard errors.
    pub precision: precision::Precision,
    /// Each row's simulated run at the fit.
    pub simulated: Vec<RunOutcome>,
    /// End time of each run, s.
    pub t_end: f64,
    /// Closed-loop runs made.
    pub runs: usize,
    /// What a user must know: keys not identified, runs not held, points refused.
    pub warnings: Vec<String>,
}

/// Runs the command (stages of the module doc).
pub fn run(args: &CalibrateArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. Inputs, then the output, before any run.
    let inputs = read_options(args).map_err(Failure::Usage)?;
    let mut staged = Staged::new();
    let out = staged.add_optional("--write", args.write.as_deref())?;

    // 2. and 3. The fit, with a progress bar on stderr (on a terminal).
    let started = Instant::now();
    let calibration = calibrate(args, inputs)?;
    let seconds = started.elapsed().as_secs_f64();

    // 4. The file, then the result.
    if let (Some(i), Some(path)) = (out, &args.write) {
        let (text, _) = read_machine_file(&args.machine.path).map_err(Failure::Usage)?;
        let written = report::machine_file(&args.machine.path, &text, &calibration, path)
            .map_err(Failure::Run)?;
        staged.write(i, &written)?;
    }
    staged.commit()?;
    console.print(&match args.format.format {
        crate::args::Format::Json => report::json(&calibration, args),
        crate::args::Format::Table => report::table(&calibration, args),
    });
    console.note(&format!(
        "calibrate: {} ({}) in {:.1} s on {}{}\n",
        count(calibration.fit.evaluations, "evaluation"),
        count(calibration.runs, "run"),
        seconds,
        count(rayon::current_num_threads(), "thread"),
        warning_count(&calibration.warnings)
    ));
    Ok(())
}

/// The runs of the fit: for a batch of trial points (normalised), the machines
/// with their values and one run per measured point on each, all in parallel.
struct Trials<'a> {
    args: &'a CalibrateArgs,
    inputs: &'a Inputs,
    progress: crate::output::progress::Progress,
    /// The runs of every point evaluated, by the bits of its coordinates.
    outcomes: HashMap<Vec<u64>, Vec<RunOutcome>>,
    /// The reader's refusal of each trial point it refused.
    refused: Vec<String>,
    /// Runs made.
    runs: usize,
}

/// The key of a point in [`Trials::outcomes`].
fn bits(u: &[f64]) -> Vec<u64> {
    u.iter().map(|x| x.to_bits()).collect()
}

impl Trials<'_> {
    /// The weighted residuals of every point of `batch` (not numbers for a point
    /// the reader refuses); `Err` on Ctrl-C.
    fn residuals(&mut self, batch: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, String> {
        let Inputs {
            text,
            keys,
            rows,
            points,
            of_row,
            t_end,
        } = self.inputs;
        // The machines, in order (a point the reader refuses has none).
        let machines: Vec<Option<_>> = batch
            .iter()
            .map(|u| {
                let mut sets = self.args.set.keys.clone();
                sets.extend(keys::sets_at(keys, u));
                load_machine(&self.args.machine.path, text, &sets)
                    .map_err(|e| self.refused.push(e.trim_end().to_string()))
                    .ok()
            })
            .collect();
        // Their runs, in parallel, collected in order.
        let jobs: Vec<(usize, usize)> = (0..batch.len())
            .filter(|&c| machines[c].is_some())
            .flat_map(|c| (0..points.len()).map(move |k| (c, k)))
            .collect();
        let progress = &self.progress;
        let done: Vec<RunOutcome> = jobs
            .par_iter()
            .map(|&(c, k)| {
                let (speed, offset) = points[k];
                let machine = machines[c].as_ref().expect("jobs have machines");
                let o = run_point(machine, speed, offset, *t_end);
                progress.inc(1);
                o
            })
            .collect();
        self.runs += done.len();
        if crate::interrupt::interrupted() {
            return Err(format!(
                "error: calibrate: {}: the fit is incomplete, nothing written",
                crate::interrupt::interruption()
            ));
        }
        // The residuals, point by point.
        let mut done = done.into_iter();
        let mut out = Vec::new();
        for (u, m) in batch.iter().zip(&machines) {
            if m.is_none() {
                out.push(vec![f64::NAN; rows.len()]);
                continue;
            }
            let sims: Vec<RunOutcome> = done.by_ref().take(points.len()).collect();
            out.push(row_residuals(rows, of_row, &sims));
            self.outcomes.insert(bits(u), sims);
        }
        Ok(out)
    }
}

/// Stages 2 and 3 on checked inputs.
pub fn calibrate(args: &CalibrateArgs, inputs: Inputs) -> Result<Calibration, Failure> {
    let keys = &inputs.keys;
    let p = keys.len();
    let settings = Settings::for_keys(p);
    let mut trials = Trials {
        args,
        inputs: &inputs,
        progress: progress_bar(
            "calibrate",
            settings.most_evaluations(1, p) * inputs.points.len(),
        ),
        outcomes: HashMap::new(),
        refused: Vec::new(),
        runs: 0,
    };
    let start: Vec<f64> = keys.iter().map(|k| k.u_of(k.nominal)).collect();
    let found = fit::fit(p, &[start], &settings, &mut |b| trials.residuals(b));
    trials.progress.finish_and_clear();
    let found = found.map_err(Failure::Run)?;

    // The runs at the fit, row by row.
    let sims = trials.outcomes.remove(&bits(&found.u)).unwrap_or_default();
    let simulated: Vec<RunOutcome> = inputs
        .of_row
        .iter()
        .filter_map(|&k| sims.get(k).cloned())
        .collect();
    if simulated.len() != inputs.rows.len() {
        return Err(Failure::Run(
            "error: calibrate: no point of the search ran (every one refused by the machine reader); nothing written".into(),
        ));
    }

    // 3. Standard errors and resolution, in the keys' units.
    let precision = precision::precision(&found.jacobian, found.ssr, settings.last_step);
    let in_units = |normalised: &[Option<f64>]| -> Vec<Option<f64>> {
        keys.iter()
            .zip(normalised)
            .map(|(k, s)| s.map(|s| s * k.width()))
            .collect()
    };
    let std_error = in_units(&precision.std_error_u);
    let resolution = in_units(&precision.resolution_u);
    let warnings = report::warnings(
        keys,
        &found,
        &precision,
        &std_error,
        &simulated,
        &trials.refused,
    );
    Ok(Calibration {
        fitted: keys
            .iter()
            .zip(&found.u)
            .map(|(k, u)| k.value_at(*u))
            .collect(),
        keys: keys.clone(),
        rows: inputs.rows.clone(),
        std_error,
        resolution,
        fit: found,
        precision,
        simulated,
        t_end: inputs.t_end,
        runs: trials.runs,
        warnings,
    })
}

/// The weighted residuals `sqrt(w) (v_sim - v_meas)` of `rows` (row `r` at point
/// `of_row[r]` of `sims`), m/s; [`NOT_HELD_RESIDUAL_MPS`] for a run not held.
pub fn row_residuals(rows: &[Row], of_row: &[usize], sims: &[RunOutcome]) -> Vec<f64> {
    rows.iter()
        .zip(of_row)
        .map(|(r, &k)| {
            let o = &sims[k];
            let e = match o.not_held {
                None => o.mean_velocity - r.velocity_mps,
                Some(_) => NOT_HELD_RESIDUAL_MPS,
            };
            r.weight.sqrt() * e
        })
        .collect()
}
