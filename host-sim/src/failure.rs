//! One error model for every command: a command writes what it has to say through a
//! [`Console`] and returns `Result<(), Failure>`; [`crate::cli`] is the one place that
//! writes a failure's message and turns its kind into the exit status.
//!
//! | kind | exit status | examples |
//! | --- | --- | --- |
//! | [`Failure::Usage`] | 2 ([`EXIT_USAGE`]) | a bad or missing file, key or option, an output that cannot be written, a port that cannot be opened |
//! | [`Failure::Run`] | 1 ([`EXIT_FAILURE`]) | the solver gave up, a scenario's expectation does not hold, a run stopped by a signal (Ctrl-C, SIGTERM, SIGHUP) or by the plant's progress guard |
//! | [`Failure::Device`] | 1 ([`EXIT_FAILURE`]) | the device refused (Nack), did not answer, answered something else, or the port failed in use |
//!
//! Messages are whole lines as the user reads them (`error: FILE: KEY: what is
//! wrong, what is allowed`), several lines when several problems were found.

use std::io::Write;

use crate::machine::input::{render, Problem};

/// Exit status of a success.
pub const EXIT_OK: u8 = 0;
/// Exit status of a failed run or a device failure (not the user's mistake).
pub const EXIT_FAILURE: u8 = 1;
/// Exit status of a user mistake: bad input file or option (as clap's usage errors).
pub const EXIT_USAGE: u8 = 2;

/// Why a command failed, with its message (one or more lines).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Failure {
    /// The user's mistake: exit 2.
    Usage(String),
    /// The run itself failed: exit 1.
    Run(String),
    /// The device or the link to it failed: exit 1.
    Device(String),
}

impl Failure {
    /// The exit status this failure earns.
    pub fn status(&self) -> u8 {
        match self {
            Failure::Usage(_) => EXIT_USAGE,
            Failure::Run(_) | Failure::Device(_) => EXIT_FAILURE,
        }
    }

    /// The message, every line ending with a line break (empty when the command's
    /// output already said everything, as a scenario report does).
    pub fn message(&self) -> String {
        let (Failure::Usage(m) | Failure::Run(m) | Failure::Device(m)) = self;
        if m.is_empty() || m.ends_with('\n') {
            m.clone()
        } else {
            format!("{m}\n")
        }
    }
}

impl From<Vec<Problem>> for Failure {
    /// Problems found in an input file are the user's to fix.
    fn from(problems: Vec<Problem>) -> Self {
        Failure::Usage(render(&problems))
    }
}

/// Where a command's output goes: stdout for results, stderr for warnings and
/// progress. Written as it comes (streaming commands print while they run), a
/// closed pipe (`host-sim ... | head`) silently ignored.
pub struct Console<'w> {
    stdout: &'w mut dyn Write,
    stderr: &'w mut dyn Write,
}

impl<'w> Console<'w> {
    /// A console over two writers (the process's, or buffers in tests).
    pub fn new(stdout: &'w mut dyn Write, stderr: &'w mut dyn Write) -> Self {
        Console { stdout, stderr }
    }

    /// Writes `text` to stdout and flushes it.
    pub fn print(&mut self, text: &str) {
        let _ = self.stdout.write_all(text.as_bytes());
        let _ = self.stdout.flush();
    }

    /// Writes `text` to stderr.
    pub fn note(&mut self, text: &str) {
        let _ = self.stderr.write_all(text.as_bytes());
        let _ = self.stderr.flush();
    }
}
