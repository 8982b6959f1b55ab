//! The arguments several commands share, declared once and flattened into each
//! command's own arguments: the machine file, `--set`, `--t-end`, `--format`,
//! `--plot`. A command whose help says more about one of them changes only that
//! argument's help text (`mut_arg`), not its meaning.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

/// The machine file a command reads.
#[derive(Clone, Debug, Args)]
pub struct MachineArg {
    /// The machine file (TOML; see docs/machine-file.md).
    #[arg(id = "machine", value_name = "MACHINE.toml")]
    pub path: PathBuf,
}

/// `--set KEY=VALUE`, repeatable.
#[derive(Clone, Debug, Default, Args)]
pub struct SetArgs {
    /// Override a key of the machine file, e.g. `contacts.K1.friction=0.2`
    /// (repeatable).
    #[arg(id = "set", long = "set", value_name = "KEY=VALUE")]
    pub keys: Vec<String>,
}

/// `--t-end T`: the simulated end time, s.
#[derive(Clone, Debug, Default, Args)]
pub struct TEndArg {
    /// End time, s.
    #[arg(
        id = "t_end",
        long = "t-end",
        value_name = "T",
        allow_negative_numbers = true
    )]
    pub seconds: Option<f64>,
}

/// `--format table|json`.
#[derive(Clone, Debug, Args)]
pub struct FormatArg {
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}

/// `--plot FILE.svg`.
#[derive(Clone, Debug, Default, Args)]
pub struct PlotArg {
    /// Write a plot as SVG.
    #[arg(id = "plot", long = "plot", value_name = "FILE.svg")]
    pub file: Option<PathBuf>,
}

/// The outputs of a sweep, the same for `tune` and `merge`.
#[derive(Debug, Args)]
#[command(mut_arg("plot", |a| a.help("Write a plot of mean velocity against offset, one line per speed, as SVG")))]
#[command(mut_arg("format", |a| a.help("Output format of the result")))]
pub struct TuneOutputs {
    /// Write the tuning table (best offsets per speed) that
    /// `[controller].tuning_table` names.
    #[arg(long, value_name = "FILE.toml")]
    pub write: Option<PathBuf>,
    /// The plot.
    #[command(flatten)]
    pub plot: PlotArg,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
}

/// How a command prints its result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Aligned text for people.
    Table,
    /// One JSON document for programs.
    Json,
}
