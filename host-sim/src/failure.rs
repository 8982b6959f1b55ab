//! One error model for every command: a command writes what it has to say through a
//! [`Console`] and returns `Result<(), Failure>`; [`crate::cli`] is the one place that
//! writes a failure's message and turns its kind into the exit status.
//!
//! | kind | exit status | examples |
//! | --- | --- | --- |
//! | [`Kind::Usage`] | 2 ([`EXIT_USAGE`]) | a bad or missing file, key or option, an output that cannot be written, a port that cannot be opened |
//! | [`Kind::Run`] | 1 ([`EXIT_FAILURE`]) | the solver gave up, a scenario's expectation does not hold, a run stopped by a signal (Ctrl-C, SIGTERM, SIGHUP) or by the plant's progress guard |
//! | [`Kind::Device`] | 1 ([`EXIT_FAILURE`]) | the device refused (Nack), did not answer, answered something else, or the port failed in use |
//!
//! A failure says what is wrong as [`Reason`]s, several when several problems were
//! found: each a text (`FILE: KEY: what is wrong, what is allowed`, or `OPTION
//! VALUE: ...`) and the lines that follow it as they are (an example to copy,
//! where a log is). [`Failure::message`] writes each text as one line after
//! `error: ` ([`input::error_line`], the one place that prefix is written), then
//! its detail lines. A failure whose command already said everything (a failed
//! scenario's report) has no reason and writes nothing.

use std::io::Write;

use crate::machine::input::{self, Problem};

/// Exit status of a success.
pub const EXIT_OK: u8 = 0;
/// Exit status of a failed run or a device failure (not the user's mistake).
pub const EXIT_FAILURE: u8 = 1;
/// Exit status of a user mistake: bad input file or option (as clap's usage errors).
pub const EXIT_USAGE: u8 = 2;

/// Whose failure it is, which decides the exit status.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// The user's mistake: exit 2.
    Usage,
    /// The run itself failed: exit 1.
    Run,
    /// The device or the link to it failed: exit 1.
    Device,
}

impl Kind {
    /// The exit status a failure of this kind earns.
    pub fn status(self) -> u8 {
        match self {
            Kind::Usage => EXIT_USAGE,
            Kind::Run | Kind::Device => EXIT_FAILURE,
        }
    }
}

/// One thing wrong: its text, said as an error, and the lines that follow it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reason {
    /// What is wrong, one line, without the `error: ` that says it.
    pub text: String,
    /// Lines written after the text as they are: a hint, an example to copy,
    /// where a log is.
    pub detail: Vec<String>,
}

impl Reason {
    /// A reason of one line.
    pub fn new(text: impl Into<String>) -> Self {
        Reason {
            text: text.into(),
            detail: Vec::new(),
        }
    }
}

impl From<String> for Reason {
    fn from(text: String) -> Self {
        Reason::new(text)
    }
}

impl From<&str> for Reason {
    fn from(text: &str) -> Self {
        Reason::new(text)
    }
}

impl From<Problem> for Reason {
    /// A problem of an input file: `FILE: KEY: MESSAGE`.
    fn from(problem: Problem) -> Self {
        Reason::new(problem.to_string())
    }
}

/// Why a command failed: its kind and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure {
    kind: Kind,
    reasons: Vec<Reason>,
}

impl Failure {
    /// A failure of `kind` for every reason given, in order.
    pub fn new<R: Into<Reason>>(kind: Kind, reasons: impl IntoIterator<Item = R>) -> Self {
        Failure {
            kind,
            reasons: reasons.into_iter().map(Into::into).collect(),
        }
    }

    /// The user's mistake, one reason.
    pub fn usage(text: impl Into<String>) -> Self {
        Failure::new(Kind::Usage, [text.into()])
    }

    /// The run failed, one reason.
    pub fn run(text: impl Into<String>) -> Self {
        Failure::new(Kind::Run, [text.into()])
    }

    /// The device or its link failed, one reason.
    pub fn device(text: impl Into<String>) -> Self {
        Failure::new(Kind::Device, [text.into()])
    }

    /// A failure the command's output has already said in full (a failed
    /// scenario's report): its status, and nothing more written.
    pub fn reported(kind: Kind) -> Self {
        Failure {
            kind,
            reasons: Vec::new(),
        }
    }

    /// The same reasons as another kind of failure.
    pub fn of_kind(self, kind: Kind) -> Self {
        Failure { kind, ..self }
    }

    /// The failure with `line` written after its last reason, as it is (a failure
    /// that says nothing, [`Failure::reported`], stays silent).
    pub fn with_detail(mut self, line: impl Into<String>) -> Self {
        if let Some(last) = self.reasons.last_mut() {
            last.detail.push(line.into());
        }
        self
    }

    /// The failure with its first reason's text changed by `change` (a failure
    /// that says nothing stays silent).
    pub fn map_text(mut self, change: impl FnOnce(&str) -> String) -> Self {
        if let Some(first) = self.reasons.first_mut() {
            first.text = change(&first.text);
        }
        self
    }

    /// The failure with `words` at the end of its last line (its last reason's
    /// last detail line, else its text): what the whole failure is about.
    pub fn ending_with(mut self, words: &str) -> Self {
        if let Some(last) = self.reasons.last_mut() {
            match last.detail.last_mut() {
                Some(line) => line.push_str(words),
                None => last.text.push_str(words),
            }
        }
        self
    }

    /// Its reasons, to say with others in one failure.
    pub fn into_reasons(self) -> Vec<Reason> {
        self.reasons
    }

    /// Whose failure it is.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// The exit status this failure earns.
    pub fn status(&self) -> u8 {
        self.kind.status()
    }

    /// What is wrong without the `error: ` that says it, for a message that
    /// quotes the failure: each reason's text and its detail lines, one a line,
    /// with no line break at the end.
    pub fn text(&self) -> String {
        self.reasons
            .iter()
            .flat_map(|r| std::iter::once(&r.text).chain(&r.detail))
            .map(String::as_str)
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// The message as the user reads it, every line ending with a line break:
    /// each reason as an `error: ` line ([`input::error_line`]) and its detail
    /// lines (empty when the command's output already said everything).
    pub fn message(&self) -> String {
        let mut out = String::new();
        for reason in &self.reasons {
            out.push_str(&input::error_line(&reason.text));
            for line in &reason.detail {
                out.push_str(line);
                out.push('\n');
            }
        }
        out
    }
}

impl From<Vec<Problem>> for Failure {
    /// Problems found in an input file are the user's to fix.
    fn from(problems: Vec<Problem>) -> Self {
        Failure::new(Kind::Usage, problems)
    }
}

impl From<Problem> for Failure {
    /// A problem found in an input file is the user's to fix.
    fn from(problem: Problem) -> Self {
        Failure::new(Kind::Usage, [problem])
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::input::Location;

    #[test]
    fn each_reason_is_one_error_line_and_its_detail_follows_as_it_is() {
        let f = Failure::new(Kind::Usage, ["--t-end -1: must be positive", "two"])
            .with_detail("  an example")
            .with_detail("(docs/cli-run.md)");
        assert_eq!(
            f.message(),
            "error: --t-end -1: must be positive\nerror: two\n  an example\n(docs/cli-run.md)\n"
        );
        assert_eq!(
            f.text(),
            "--t-end -1: must be positive\ntwo\n  an example\n(docs/cli-run.md)"
        );
        assert_eq!(f.status(), EXIT_USAGE);
        assert_eq!(Failure::device("gone").status(), EXIT_FAILURE);
        let said = Failure::reported(Kind::Run);
        assert_eq!(said.message(), "");
        assert_eq!(said.status(), EXIT_FAILURE);
    }

    #[test]
    fn a_failure_is_quoted_and_added_to_without_its_prefix() {
        let f = Failure::device("3000 rpm: the port failed").map_text(|t| format!("{t}; stopped"));
        assert_eq!(f.text(), "3000 rpm: the port failed; stopped");
        let f = Failure::usage("a")
            .with_detail("... and 2 more")
            .ending_with(": the parts' files");
        assert_eq!(f.message(), "error: a\n... and 2 more: the parts' files\n");
        assert_eq!(
            Failure::usage("a").ending_with("!").message(),
            "error: a!\n"
        );
        let run = Failure::usage("a").of_kind(Kind::Run);
        assert_eq!((run.kind(), run.status()), (Kind::Run, EXIT_FAILURE));
        let both = Failure::new(
            Kind::Usage,
            [Failure::usage("a"), Failure::usage("b")]
                .into_iter()
                .flat_map(Failure::into_reasons),
        );
        assert_eq!(both.message(), "error: a\nerror: b\n");
    }

    #[test]
    fn a_file_problem_is_said_with_its_file_and_key() {
        let p = Problem {
            file: "m.toml".into(),
            location: Location::Key("platform.mass".into()),
            message: "must be > 0 (got -1)".into(),
        };
        let f = Failure::from(vec![p]);
        assert_eq!(f.kind(), Kind::Usage);
        assert_eq!(
            f.message(),
            "error: m.toml: platform.mass: must be > 0 (got -1)\n"
        );
    }
}
