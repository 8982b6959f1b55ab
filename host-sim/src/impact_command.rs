//! `host-sim impact CASE.toml [--law LAW] [--format table|json]`.
//!
//! Stages:
//! 1. read and check the case file ([`crate::impact_case`]): every problem at once;
//! 2. apply `--law`;
//! 3. solve with [`shared::impact::solve_body`];
//! 4. write the result ([`crate::impact_report`]) as a table or as JSON.

use shared::impact::{solve_body, ImpactError, MAX_CONTACTS};

use crate::cli::{Format, ImpactArgs, Output, EXIT_FAILURE, EXIT_OK, EXIT_USAGE};
use crate::impact_case::read_case;
use crate::{impact_report, input};

/// What a solver error means for the user, and the exit status it earns:
/// a problem that is the input's (2), or the solver's own limit (1).
pub fn explain(error: ImpactError) -> (&'static str, u8) {
    match error {
        ImpactError::NoApproach => (
            "no contact approaches (all normal velocities >= 0): nothing to solve",
            EXIT_USAGE,
        ),
        ImpactError::InvalidProblem => (
            "the solver refused the problem as malformed (no contact, too many, or a number that is not finite)",
            EXIT_USAGE,
        ),
        ImpactError::TooManyEvents => (
            "internal failure: the solver gave up after too many slip/stick events (friction states chattering); please report this case file",
            EXIT_FAILURE,
        ),
    }
}

/// Runs the command (stages of the module doc).
pub fn run(args: &ImpactArgs) -> Output {
    let file = args.case.display().to_string();

    // 1. Read and check.
    let mut case = match read_case(&args.case) {
        Ok(case) => case,
        Err(problems) => {
            return Output {
                stderr: input::render(&problems),
                status: EXIT_USAGE,
                ..Output::default()
            }
        }
    };

    // 2. The command line's law wins over the file's.
    if let Some(law) = args.law {
        case.law = law.into();
    }

    // 3. Solve.
    let contacts = case.body_contacts();
    let result = match solve_body::<f64, MAX_CONTACTS>(&case.body, case.pivot, &contacts, case.law)
    {
        Ok(result) => result,
        Err(error) => {
            let (message, status) = explain(error);
            return Output {
                stderr: format!("error: {file}: {message}\n"),
                status,
                ..Output::default()
            };
        }
    };

    // 4. Write.
    let stdout = match args.format {
        Format::Table => impact_report::table(&case, &result),
        Format::Json => impact_report::json_text(&case, &result),
    };
    Output {
        stdout,
        stderr: String::new(),
        status: EXIT_OK,
    }
}
