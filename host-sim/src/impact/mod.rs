//! `host-sim impact CASE.toml [--law LAW] [--format table|json]`.
//!
//! Stages:
//! 1. read and check the case file ([`crate::impact::case`]): every problem at once;
//! 2. apply `--law`;
//! 3. solve with [`shared::impact::solve_body`];
//! 4. write the result ([`crate::impact::report`]) as a table or as JSON.

pub mod case;
pub mod report;

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use shared::impact::ImpactLaw;
use shared::impact::{solve_body, ImpactError, MAX_CONTACTS};

use crate::args::Format;
use crate::args::FormatArg;
use crate::failure::{Console, Failure};
use crate::help::epilogue;
use crate::impact::case::read_case;

/// Arguments of `host-sim impact`.
#[derive(Debug, Args)]
#[command(after_help = epilogue(
    &[
        "host-sim impact examples/impact/fig7-four-points.toml",
        "host-sim impact examples/impact/rocking-block.toml --law newton --format json",
    ],
    &[],
    &["docs/cli-impact.md"],
))]
pub struct ImpactArgs {
    /// The impact case file (TOML; see docs/cli-impact.md).
    #[arg(value_name = "CASE.toml")]
    pub case: PathBuf,
    /// Impact law, overriding the file's `law` (whose default is poisson).
    #[arg(long, value_enum, value_name = "LAW")]
    pub law: Option<LawArg>,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
}

/// An impact law named on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LawArg {
    /// Poisson: restitution impulse = R x compression impulse (the paper's).
    Poisson,
    /// Newton: normal velocity after = -R x normal velocity before.
    Newton,
    /// Stronge: restitution work = R^2 x compression work.
    Stronge,
}

impl From<LawArg> for ImpactLaw {
    fn from(law: LawArg) -> Self {
        match law {
            LawArg::Poisson => ImpactLaw::Poisson,
            LawArg::Newton => ImpactLaw::Newton,
            LawArg::Stronge => ImpactLaw::Stronge,
        }
    }
}

/// What a solver error means for the user: a problem that is the input's (a user
/// mistake), or the solver's own limit (a failed run).
pub fn explain(error: ImpactError, file: &str) -> Failure {
    match error {
        ImpactError::NoApproach => Failure::usage(format!(
            "{file}: no contact approaches (all normal velocities >= 0): nothing to solve"
        )),
        ImpactError::InvalidProblem => Failure::usage(format!(
            "{file}: the solver refused the problem as malformed (no contact, too many, or a number that is not finite)"
        )),
        ImpactError::TooManyEvents => Failure::run(format!(
            "{file}: internal failure: the solver gave up after too many slip/stick events (friction states chattering); please report this case file"
        )),
    }
}

/// Runs the command (stages of the module doc).
pub fn run(args: &ImpactArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    let file = args.case.display().to_string();

    // 1. Read and check.
    let mut case = read_case(&args.case)?;

    // 2. The command line's law wins over the file's.
    if let Some(law) = args.law {
        case.law = law.into();
    }

    // 3. Solve.
    let contacts = case.body_contacts();
    let result = solve_body::<f64, MAX_CONTACTS>(&case.body, case.pivot, &contacts, case.law)
        .map_err(|e| explain(e, &file))?;

    // 4. Write.
    console.print(&match args.format.format {
        Format::Table => report::table(&case, &result),
        Format::Json => report::json_text(&case, &result),
    });
    Ok(())
}
