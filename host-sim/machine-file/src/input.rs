//! Checked reading of TOML input files (impact cases, machine files).
//!
//! Reading a file never stops at the first mistake: every problem is recorded with
//! the full key path it concerns (`contacts[2].friction`, `body.mass`), what is wrong
//! and what is allowed, and all of them are returned together, each said as one
//! line ([`error_line`]):
//!
//! ```text
//! error: case.toml: contacts[2].friction: must be >= 0 (got -0.1)
//! error: case.toml: body.mas: unknown key; did you mean `mass`? (allowed here: mass, inertia, ...)
//! error: case.toml:7:12: TOML syntax: invalid string
//! ```
//!
//! Stages of reading a file (see [`load`]):
//! 1. read the text ([`read_text`]): a regular file of bounded size; a missing,
//!    unreadable, special or too large file is one problem;
//! 2. parse the TOML ([`parse`]): a syntax error is one problem with its line and column;
//! 3. walk the tables with [`Section`]: each typed read checks the type, rejects NaN and
//!    infinities, checks the allowed range, and records the key as known;
//!    [`Section::finish`] then reports every key that was never asked for as unknown,
//!    with a "did you mean" suggestion among the known keys;
//! 4. cross-key checks by the caller ([`Problems::at`]);
//! 5. [`Problems::into_result`]: the value, or every problem at once.
//!
//! Array elements are numbered from 0, as in TOML tools (`contacts[0]` is the first
//! `[[contacts]]` table).

use std::cell::RefCell;
use std::fmt;
use std::path::Path;

use shared::Enumerated;
use toml::{Table, Value};

/// Where in a file a problem lies.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Location {
    /// The file as a whole (it cannot be read, or a problem involves several keys).
    File,
    /// A line and column (1-based), for syntax errors.
    Line {
        /// Line number, from 1.
        line: usize,
        /// Column number in characters, from 1.
        column: usize,
    },
    /// A key path such as `contacts[2].friction`.
    Key(String),
}

/// One problem found in an input file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// The file, as the user named it.
    pub file: String,
    /// Where in the file.
    pub location: Location,
    /// What is wrong and what is allowed, one line.
    pub message: String,
}

impl fmt::Display for Problem {
    /// `FILE: KEY: MESSAGE`, `FILE:LINE:COLUMN: MESSAGE` or `FILE: MESSAGE`: the
    /// problem's text, which [`error_line`] says to the user.
    /// The file name, key path and message each [`cut`] at [`MAX_PATH_SHOWN`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = cut(&self.file, MAX_PATH_SHOWN);
        let message = cut(&self.message, MAX_PATH_SHOWN);
        match &self.location {
            Location::File => write!(f, "{file}: {message}"),
            Location::Line { line, column } => write!(f, "{file}:{line}:{column}: {message}"),
            Location::Key(key) => write!(f, "{file}: {}: {message}", cut(key, MAX_PATH_SHOWN)),
        }
    }
}

/// One problem as the user reads it: `error: `, its text and a line break. The
/// one place that prefix is written: host-sim prints every failure's problems
/// through it, and the firmware's build its refusals of a machine file
/// ([`render`]).
pub fn error_line(text: impl fmt::Display) -> String {
    format!("error: {text}\n")
}

/// Formats problems one per line ([`error_line`]).
pub fn render(problems: &[Problem]) -> String {
    problems.iter().map(error_line).collect()
}

/// The problems found so far in one file. Shared by every [`Section`] of the file,
/// which also records here every number it read with the limit it was checked
/// against ([`Problems::numbers`]).
#[derive(Debug)]
pub struct Problems {
    file: String,
    list: RefCell<Vec<Problem>>,
    numbers: RefCell<Vec<NumberRead>>,
}

/// A number [`Section::number`] read and accepted: where, its value (or the
/// default it took) and the range it was checked against, as the reader declares
/// it (so a caller needing a key's valid range asks the reader, not a copy).
#[derive(Clone, Debug, PartialEq)]
pub struct NumberRead {
    /// The key path, elements numbered from 0 (`contacts[0].restitution`).
    pub key_path: String,
    /// The value read, or the default taken for a missing key.
    pub value: f64,
    /// The range it was checked against.
    pub limit: Limit,
}

impl Problems {
    /// No problem yet in `file` (the name as the user gave it).
    pub fn new(file: impl Into<String>) -> Self {
        Problems {
            file: file.into(),
            list: RefCell::new(Vec::new()),
            numbers: RefCell::new(Vec::new()),
        }
    }

    /// Every number read so far with [`Section::number`] and accepted, in the
    /// order read.
    pub fn numbers(&self) -> Vec<NumberRead> {
        self.numbers.borrow().clone()
    }

    /// The file's name.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// Records a problem at a key path.
    pub fn at(&self, key_path: &str, message: impl Into<String>) {
        self.push(Location::Key(key_path.to_string()), message.into());
    }

    /// Records a problem about the file as a whole.
    pub fn whole_file(&self, message: impl Into<String>) {
        self.push(Location::File, message.into());
    }

    fn push(&self, location: Location, message: String) {
        self.list.borrow_mut().push(Problem {
            file: self.file.clone(),
            location,
            message,
        });
    }

    /// True when no problem was recorded.
    pub fn is_empty(&self) -> bool {
        self.list.borrow().is_empty()
    }

    /// The problems recorded, in the order found.
    pub fn into_vec(self) -> Vec<Problem> {
        self.list.into_inner()
    }

    /// `Ok(value)` when no problem was recorded and `value` is there, else every
    /// problem recorded (a `None` without a problem is reported as an internal error
    /// rather than lost).
    pub fn into_result<T>(self, value: Option<T>) -> Result<T, Vec<Problem>> {
        match value {
            Some(v) if self.is_empty() => Ok(v),
            None if self.is_empty() => {
                self.whole_file("internal error: the file was refused without a reason");
                Err(self.into_vec())
            }
            _ => Err(self.into_vec()),
        }
    }
}

/// The largest input file [`read_text`] reads, bytes: 4 MiB. The reference
/// machine file is 7 kB and a tuning table, a scenario or an impact case a few;
/// a file this large is a mistake (a log, an image, a device), and reading no
/// more keeps a mistake from filling the memory.
pub const MAX_FILE_BYTES: u64 = 4 << 20;

/// Reads a whole text file of at most [`MAX_FILE_BYTES`]
/// ([`read_text_at_most`]); a missing, unreadable, special or too large file is
/// one problem.
pub fn read_text(path: &Path) -> Result<String, Problem> {
    read_text_at_most(path, MAX_FILE_BYTES)
}

/// Reads a whole text file of at most `limit` bytes: the one way every command
/// reads an input file. Only a regular file is read (a symbolic link is
/// followed): a directory, a named pipe (FIFO, whose opening alone would wait
/// for a writer for ever), a device (`/dev/zero` never ends) or a socket is
/// refused from its metadata before it is opened, and again from the metadata
/// of the file opened. The size is checked before reading, and the read itself
/// takes at most `limit + 1` bytes, so a file that grows while it is read, or
/// that reports no size (`/proc`), is still refused past `limit`.
pub fn read_text_at_most(path: &Path, limit: u64) -> Result<String, Problem> {
    let problem = |message: String| Problem {
        file: path.display().to_string(),
        location: Location::File,
        message,
    };
    let cannot = |e: std::io::Error| problem(format!("cannot read the file: {}", io_reason(&e)));
    let check = |meta: &std::fs::Metadata| {
        if !meta.is_file() {
            Err(problem(format!(
                "cannot read the file: {}, not a regular file (an input file is read whole)",
                file_kind(meta)
            )))
        } else if meta.len() > limit {
            Err(problem(too_large(Some(meta.len()), limit)))
        } else {
            Ok(())
        }
    };
    check(&std::fs::metadata(path).map_err(cannot)?)?;
    let file = std::fs::File::open(path).map_err(cannot)?;
    let meta = file.metadata().map_err(cannot)?;
    check(&meta)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::io::Read::read_to_end(
        &mut std::io::Read::take(file, limit.saturating_add(1)),
        &mut bytes,
    )
    .map_err(cannot)?;
    if bytes.len() as u64 > limit {
        return Err(problem(too_large(None, limit)));
    }
    String::from_utf8(bytes).map_err(|_| problem("cannot read the file: not UTF-8 text".into()))
}

/// Why a file of `size` bytes (`None`: more than `limit`, found while reading
/// it) is refused.
fn too_large(size: Option<u64>, limit: u64) -> String {
    let size = match size {
        Some(n) => format!("{n} bytes"),
        None => format!("more than {limit} bytes"),
    };
    const MIB: u64 = 1 << 20;
    let mib = if limit.is_multiple_of(MIB) {
        format!(" ({} MiB)", limit / MIB)
    } else {
        String::new()
    };
    format!(
        "cannot read the file: too large ({size}): an input file of this kind has at most {limit} bytes{mib}"
    )
}

/// What a file that is not a regular file is, for people.
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a named pipe (FIFO)";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// A short reason for an I/O error, without Rust's `(os error N)` noise.
pub fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".to_string(),
        std::io::ErrorKind::PermissionDenied => "permission denied".to_string(),
        std::io::ErrorKind::InvalidData => "not UTF-8 text".to_string(),
        _ => {
            let text = e.to_string();
            match text.split_once(" (os error") {
                Some((reason, _)) => reason.to_lowercase(),
                None => text,
            }
        }
    }
}

/// Parses TOML text; a syntax error is one problem with its line and column.
pub fn parse(file: &str, text: &str) -> Result<Table, Problem> {
    text.parse::<Table>().map_err(|e| {
        let location = match e.span() {
            Some(span) => {
                let (line, column) = line_column(text, span.start);
                Location::Line { line, column }
            }
            None => Location::File,
        };
        // toml's messages can span several lines ("invalid key\nexpected ..."):
        // one problem, one line.
        let message = e
            .message()
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join("; ");
        Problem {
            file: file.to_string(),
            location,
            message: format!("TOML syntax: {message}"),
        }
    })
}

/// Reads and parses a TOML file (stages 1 and 2 of the module doc).
pub fn load(path: &Path) -> Result<Table, Problem> {
    let text = read_text(path)?;
    parse(&path.display().to_string(), &text)
}

/// 1-based line and column (in characters) of byte offset `at` in `text`.
fn line_column(text: &str, at: usize) -> (usize, usize) {
    let at = at.min(text.len());
    let before = text.get(..at).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

/// Whether a key must be there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Need<T> {
    /// Missing is a problem.
    Required,
    /// Missing means this value.
    Default(T),
    /// Missing is allowed: the read returns `None`.
    Optional,
}

/// The range a number must lie in. Every number must also be finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Limit {
    /// Any finite number.
    Any,
    /// `> 0`.
    Positive,
    /// `>= 0`.
    NonNegative,
    /// In `[lo, hi]`, both ends included.
    Between(f64, f64),
    /// `>= lo`.
    AtLeast(f64),
}

impl Limit {
    /// Whether `x` (finite) satisfies the limit.
    fn admits(self, x: f64) -> bool {
        match self {
            Limit::Any => true,
            Limit::Positive => x > 0.0,
            Limit::NonNegative => x >= 0.0,
            Limit::Between(lo, hi) => (lo..=hi).contains(&x),
            Limit::AtLeast(lo) => x >= lo,
        }
    }

    /// What is allowed, as in `must be > 0`.
    pub fn describe(self) -> String {
        match self {
            Limit::Any => "a finite number".to_string(),
            Limit::Positive => "> 0".to_string(),
            Limit::NonNegative => ">= 0".to_string(),
            Limit::Between(lo, hi) => format!("in [{}, {}]", number(lo), number(hi)),
            Limit::AtLeast(lo) => format!(">= {}", number(lo)),
        }
    }
}

/// A number for a message: plain notation for ordinary magnitudes, scientific
/// otherwise, and `nan`, `inf`, `-inf` as TOML writes them.
pub fn number(x: f64) -> String {
    if x.is_nan() {
        "nan".to_string()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_string()
    } else if x == 0.0 || (1e-4..1e15).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A vector for a message: `[x, y]`.
pub fn vector(v: [f64; 2]) -> String {
    format!("[{}, {}]", number(v[0]), number(v[1]))
}

/// The most bytes of a value quoted from an input file in a message (a string,
/// a key, a name, a field): a longer one is [`cut`], so that a 3 MB value does
/// not become a 3 MB line.
pub const MAX_QUOTED: usize = 40;

/// The most bytes of a file name, a key path or a message in a [`Problem`]'s
/// line: longer ones are [`cut`]. 4096 is `PATH_MAX` on Linux, the longest path
/// a file can be opened by, so a file name is cut only where no file has it (a
/// `tuning_table` of 3 MB); no message of the reader's comes near it (a value
/// in one is cut at [`MAX_QUOTED`]).
pub const MAX_PATH_SHOWN: usize = 4096;

/// `s` for a message: whole when at most `max` bytes, else its first `max` bytes
/// (to a character's boundary) and `... (N bytes)`, N its whole length. The one
/// cut of every message of host-sim and its readers.
pub fn cut(s: &str, max: usize) -> String {
    if s.len() <= max {
        return s.to_string();
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}... ({} bytes)", &s[..end], s.len())
}

/// The most bytes [`cut`]`(s, max)` gives, whatever `s`: `max`, then `... (N
/// bytes)` with N of at most 20 digits (a `usize`).
pub const fn cut_bound(max: usize) -> usize {
    max + "... ( bytes)".len() + 20
}

/// `s` quoted for a message, [`cut`] at [`MAX_QUOTED`]: `"ccw"`,
/// `"qqq... (3000000 bytes)"`.
pub fn quoted(s: &str) -> String {
    format!("{:?}", cut(s, MAX_QUOTED))
}

/// What a TOML value is, for "got ..." in messages.
fn shown(value: &Value) -> String {
    let text = match value {
        Value::String(s) => format!("the string {}", quoted(s)),
        Value::Integer(i) => i.to_string(),
        Value::Float(x) => number(*x),
        Value::Boolean(b) => b.to_string(),
        Value::Datetime(d) => format!("the date-time {d}"),
        Value::Array(a) if a.is_empty() => "an empty array".to_string(),
        Value::Array(_) => value.to_string(),
        Value::Table(_) => "a table".to_string(),
    };
    // Keep messages on one short line.
    cut(&text.replace('\n', " "), MAX_QUOTED)
}

/// The known key closest to `unknown`, if any is close enough to be a likely typo.
pub fn suggest<'k>(unknown: &str, known: &[&'k str]) -> Option<&'k str> {
    let lower = unknown.to_lowercase();
    known
        .iter()
        .map(|k| (*k, strsim::jaro_winkler(&lower, &k.to_lowercase())))
        // 0.8: close enough to catch transpositions, a missing or extra letter, and
        // `contact` for `contacts`; far enough to not suggest `mass` for `name`.
        .filter(|(_, score)| *score >= 0.8)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// A value read from a number: the checks a typed read applies.
fn finite_number(value: &Value) -> Result<f64, String> {
    let x = match value {
        Value::Float(x) => *x,
        Value::Integer(i) => *i as f64,
        other => return Err(format!("must be a number (got {})", shown(other))),
    };
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("must be a finite number (got {})", number(x)))
    }
}

/// One TOML table being read, with its key path. Every read records the key as
/// known; [`Section::finish`] reports the keys never read as unknown.
#[derive(Debug)]
pub struct Section<'a> {
    table: &'a Table,
    path: String,
    problems: &'a Problems,
    known: RefCell<Vec<&'static str>>,
}

impl<'a> Section<'a> {
    /// The top level of a file.
    pub fn root(table: &'a Table, problems: &'a Problems) -> Self {
        Section::at_path(table, String::new(), problems)
    }

    fn at_path(table: &'a Table, path: String, problems: &'a Problems) -> Self {
        Section {
            table,
            path,
            problems,
            known: RefCell::new(Vec::new()),
        }
    }

    /// The key path of this table (empty at the top level).
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The full key path of `key` in this table (a key from the file [`cut`] at
    /// [`MAX_QUOTED`]: the schema's are shorter).
    pub fn key_path(&self, key: &str) -> String {
        let key = cut(key, MAX_QUOTED);
        if self.path.is_empty() {
            key
        } else {
            format!("{}.{key}", self.path)
        }
    }

    /// The problems of the file this table belongs to.
    pub fn problems(&self) -> &'a Problems {
        self.problems
    }

    /// Records a problem at `key` of this table.
    pub fn problem(&self, key: &str, message: impl Into<String>) {
        self.problems.at(&self.key_path(key), message);
    }

    /// True when `key` is present (and records it as known).
    pub fn has(&self, key: &'static str) -> bool {
        self.mark(key);
        self.table.contains_key(key)
    }

    fn mark(&self, key: &'static str) {
        let mut known = self.known.borrow_mut();
        if !known.contains(&key) {
            known.push(key);
        }
    }

    /// The raw value of `key`, handling [`Need`]: `Err(Some(default))` for a missing
    /// defaulted key, `Err(None)` for a missing key (reported when required).
    fn raw<T>(&self, key: &'static str, need: &Need<T>, what: &str) -> Result<&'a Value, Option<T>>
    where
        T: Clone,
    {
        self.mark(key);
        match (self.table.get(key), need) {
            (Some(v), _) => Ok(v),
            (None, Need::Required) => {
                self.problem(key, format!("missing; required: {what}"));
                Err(None)
            }
            (None, Need::Default(d)) => Err(Some(d.clone())),
            (None, Need::Optional) => Err(None),
        }
    }

    /// A finite number within `limit`. `None` when missing (reported if required) or
    /// invalid (reported).
    pub fn number(&self, key: &'static str, need: Need<f64>, limit: Limit) -> Option<f64> {
        let what = match limit {
            Limit::Any => "a number".to_string(),
            l => format!("a number {}", l.describe()),
        };
        let read = self.number_by(key, need, &what, |x| {
            if limit.admits(x) {
                Ok(())
            } else {
                Err(limit.describe())
            }
        });
        if let Some(value) = read {
            self.problems.numbers.borrow_mut().push(NumberRead {
                key_path: self.key_path(key),
                value,
                limit,
            });
        }
        read
    }

    /// A finite number that `rule` accepts: `rule(x)` is `Err(requirement)` for a
    /// refused `x`, reported as `must be REQUIREMENT (got X)`; `what` says what is
    /// required when the key is missing. For a rule kept elsewhere (the controller's
    /// for a tuning row).
    pub fn number_by(
        &self,
        key: &'static str,
        need: Need<f64>,
        what: &str,
        rule: impl Fn(f64) -> Result<(), String>,
    ) -> Option<f64> {
        let value = match self.raw(key, &need, what) {
            Ok(v) => v,
            Err(default) => return default,
        };
        let checked = finite_number(value).and_then(|x| {
            rule(x)
                .map(|()| x)
                .map_err(|requirement| format!("must be {requirement} (got {})", number(x)))
        });
        match checked {
            Ok(x) => Some(x),
            Err(message) => {
                self.problem(key, message);
                None
            }
        }
    }

    /// An integer within `limit`. Floats are refused, even whole ones.
    pub fn integer(&self, key: &'static str, need: Need<i64>, limit: Limit) -> Option<i64> {
        let what = match limit {
            Limit::Any => "an integer".to_string(),
            l => format!("an integer {}", l.describe()),
        };
        let value = match self.raw(key, &need, &what) {
            Ok(v) => v,
            Err(default) => return default,
        };
        match value {
            Value::Integer(i) if limit.admits(*i as f64) => Some(*i),
            Value::Integer(i) => {
                self.problem(key, format!("must be {} (got {i})", limit.describe()));
                None
            }
            other => {
                self.problem(key, format!("must be an integer (got {})", shown(other)));
                None
            }
        }
    }

    /// A plane vector `[x, y]` of two finite numbers, each within `limit`.
    pub fn vec2(&self, key: &'static str, need: Need<[f64; 2]>, limit: Limit) -> Option<[f64; 2]> {
        let value = match self.raw(key, &need, "an array of two numbers [x, y]") {
            Ok(v) => v,
            Err(default) => return default,
        };
        let items = match value {
            Value::Array(a) if a.len() == 2 => a,
            other => {
                self.problem(
                    key,
                    format!(
                        "must be an array of two numbers [x, y] (got {})",
                        shown(other)
                    ),
                );
                return None;
            }
        };
        let mut out = [0.0; 2];
        let mut ok = true;
        for (i, item) in items.iter().enumerate() {
            let item_path = format!("{key}[{i}]");
            match finite_number(item) {
                Ok(x) if limit.admits(x) => out[i] = x,
                Ok(x) => {
                    self.problem(
                        &item_path,
                        format!("must be {} (got {})", limit.describe(), number(x)),
                    );
                    ok = false;
                }
                Err(message) => {
                    self.problem(&item_path, message);
                    ok = false;
                }
            }
        }
        ok.then_some(out)
    }

    /// A string.
    pub fn string(&self, key: &'static str, need: Need<String>) -> Option<String> {
        let value = match self.raw(key, &need, "a string") {
            Ok(v) => v,
            Err(default) => return default,
        };
        match value {
            Value::String(s) => Some(s.clone()),
            other => {
                self.problem(key, format!("must be a string (got {})", shown(other)));
                None
            }
        }
    }

    /// Two strings, `[A, B]`.
    pub fn string_pair(&self, key: &'static str, need: Need<[String; 2]>) -> Option<[String; 2]> {
        let value = match self.raw(key, &need, "two names, [A, B]") {
            Ok(v) => v,
            Err(default) => return default,
        };
        let pair = match value {
            Value::Array(a) if a.len() == 2 => match (&a[0], &a[1]) {
                (Value::String(x), Value::String(y)) => Some([x.clone(), y.clone()]),
                _ => None,
            },
            _ => None,
        };
        if pair.is_none() {
            self.problem(
                key,
                format!("must be two names, [A, B] (got {})", shown(value)),
            );
        }
        pair
    }

    /// A boolean.
    pub fn boolean(&self, key: &'static str, need: Need<bool>) -> Option<bool> {
        let value = match self.raw(key, &need, "true or false") {
            Ok(v) => v,
            Err(default) => return default,
        };
        match value {
            Value::Boolean(b) => Some(*b),
            other => {
                self.problem(key, format!("must be true or false (got {})", shown(other)));
                None
            }
        }
    }

    /// One of the values of `T`, read by name ([`Enumerated::name`]): a name not
    /// among them is a problem listing those that are, with a "did you mean" for
    /// a near miss.
    pub fn one_of<T: Enumerated>(&self, key: &'static str, need: Need<T>) -> Option<T> {
        let names: Vec<&'static str> = T::ALL.iter().map(|v| v.name()).collect();
        let need = match need {
            Need::Required => Need::Required,
            Need::Default(v) => Need::Default(v.name()),
            Need::Optional => Need::Optional,
        };
        self.choice(key, need, &names).and_then(T::from_name)
    }

    /// One of the strings `allowed`, with a "did you mean" for a near miss.
    pub fn choice(
        &self,
        key: &'static str,
        need: Need<&'static str>,
        allowed: &[&'static str],
    ) -> Option<&'static str> {
        let list = allowed.join(", ");
        let value = match self.raw(key, &need, &format!("one of {list}")) {
            Ok(v) => v,
            Err(default) => return default,
        };
        let Value::String(s) = value else {
            self.problem(key, format!("must be one of {list} (got {})", shown(value)));
            return None;
        };
        if let Some(hit) = allowed.iter().find(|a| **a == s.as_str()) {
            return Some(hit);
        }
        let hint = match suggest(s, allowed) {
            Some(near) => format!("; did you mean \"{near}\"?"),
            None => String::new(),
        };
        self.problem(
            key,
            format!("unknown value {}{hint} (allowed: {list})", quoted(s)),
        );
        None
    }

    /// A sub-table `[key]` (or an inline table). `None` when missing (reported if
    /// required) or not a table (reported).
    pub fn section(&self, key: &'static str, need: Need<()>) -> Option<Section<'a>> {
        let value = match self.raw(key, &need, &format!("a table [{}]", self.key_path(key))) {
            Ok(v) => v,
            Err(_) => return None,
        };
        match value {
            Value::Table(t) => Some(Section::at_path(t, self.key_path(key), self.problems)),
            other => {
                self.problem(
                    key,
                    format!(
                        "must be a table [{}] (got {})",
                        self.key_path(key),
                        shown(other)
                    ),
                );
                None
            }
        }
    }

    /// The tables of an array of tables `[[key]]`, each with its path `key[i]`, in
    /// file order. An element that is not a table is reported and stands as `None`,
    /// so indices and the count stay those of the file. A missing key gives an empty
    /// list (the caller says whether that is allowed); `None` when the value is not an
    /// array (reported).
    pub fn sections(&self, key: &'static str) -> Option<Vec<Option<Section<'a>>>> {
        let value = match self.raw::<()>(key, &Need::Optional, "") {
            Ok(v) => v,
            Err(_) => return Some(Vec::new()),
        };
        let expected = format!("an array of tables [[{}]]", self.key_path(key));
        let Value::Array(items) = value else {
            self.problem(key, format!("must be {expected} (got {})", shown(value)));
            return None;
        };
        let list = items
            .iter()
            .enumerate()
            .map(|(i, item)| {
                let path = format!("{}[{i}]", self.key_path(key));
                match item {
                    Value::Table(t) => Some(Section::at_path(t, path, self.problems)),
                    other => {
                        self.problems.at(
                            &path,
                            format!(
                                "must be a table, as an element of {expected} (got {})",
                                shown(other)
                            ),
                        );
                        None
                    }
                }
            })
            .collect();
        Some(list)
    }

    /// `n / |n|` for the vector read at `key`, refusing a zero (or overflowing)
    /// length; `meaning` says what the direction is, for the message.
    pub fn unit_vector(&self, key: &'static str, n: [f64; 2], meaning: &str) -> Option<[f64; 2]> {
        // |n|^2 must be a positive finite number for n / |n| to be a direction.
        let len2 = n[0] * n[0] + n[1] * n[1];
        if len2 > 0.0 && len2.is_finite() {
            let len = len2.sqrt();
            return Some([n[0] / len, n[1] / len]);
        }
        let message = if len2 == 0.0 {
            format!(
                "must not be zero length: it is {meaning}, e.g. [0, 1] (got {})",
                vector(n)
            )
        } else {
            format!(
                "is too long to normalise (got {}); use a unit vector",
                vector(n)
            )
        };
        self.problem(key, message);
        None
    }

    /// Reports every key of this table that no read asked for, with a "did you
    /// mean" among the keys that were asked for, and the list of those.
    /// Call it once, after the last read of this table.
    pub fn finish(&self) {
        let known = self.known.borrow().clone();
        for key in self.table.keys() {
            if known.contains(&key.as_str()) {
                continue;
            }
            let hint = match suggest(key, &known) {
                Some(near) => format!("; did you mean `{near}`?"),
                None => String::new(),
            };
            let allowed = if known.is_empty() {
                "no keys are allowed here".to_string()
            } else {
                format!("allowed here: {}", known.join(", "))
            };
            self.problems.at(
                &self.key_path(key),
                format!("unknown key{hint} ({allowed})"),
            );
        }
    }
}

/// A named element of an array of tables (`[[contacts]]`, `[[rotors]]`) as read.
pub struct Named<T> {
    /// Whether the file gives the name (else the default, or refused).
    pub given: bool,
    /// The name, given or default; `None` when the given one is refused.
    pub name: Option<String>,
    /// The element's values; `None` when some key is missing or refused.
    pub value: Option<T>,
}

/// An element's `name`: given (non-empty), or `{prefix}{i+1}` when absent.
pub fn read_name(s: &Section, index: usize, prefix: &str) -> (bool, Option<String>) {
    let given = s.string("name", Need::Optional);
    match given {
        Some(n) if n.is_empty() => {
            s.problem(
                "name",
                format!(
                    "must not be empty (omit it for the default {prefix}{})",
                    index + 1
                ),
            );
            (true, None)
        }
        Some(n) => (true, Some(n)),
        None if s.has("name") => (true, None), // not a string, reported
        None => (false, Some(format!("{prefix}{}", index + 1))),
    }
}

/// The `[[contacts]]` array of a file: at least one, at most [`MAX_CONTACTS`] (the
/// impact solver's limit: `why` says it in the file's words), names unique
/// ([`check_names`]). The checked contacts, named, when all is well.
///
/// [`MAX_CONTACTS`]: shared::impact::MAX_CONTACTS
pub fn check_contact_list<T>(
    root: &Section,
    list: Vec<Named<T>>,
    why: &str,
) -> Option<Vec<(String, T)>> {
    let limit = shared::impact::MAX_CONTACTS;
    if list.is_empty() {
        root.problem(
            "contacts",
            "no contact: at least one [[contacts]] table is required",
        );
        return None;
    }
    let mut ok = check_names(root, "contacts", "contact", &list);
    if list.len() > limit {
        root.problem(
            "contacts",
            format!("{} contacts; at most {limit} are allowed {why}", list.len()),
        );
        ok = false;
    }
    let contacts = list
        .into_iter()
        .map(|k| Some((k.name?, k.value?)))
        .collect::<Option<Vec<_>>>();
    contacts.filter(|_| ok)
}

/// Unique names among `list` (problems reported on `root`); `what` is the element
/// (`contact`, `rotor`), `array` its key.
pub fn check_names<T>(root: &Section, array: &str, what: &str, list: &[Named<T>]) -> bool {
    let mut ok = true;
    let mut seen: Vec<(&str, usize)> = Vec::new();
    for (i, element) in list.iter().enumerate() {
        let Some(name) = element.name.as_deref() else {
            continue;
        };
        if let Some((_, first)) = seen.iter().find(|(n, _)| *n == name) {
            let message = if element.given {
                format!(
                    "duplicate {what} name {} ({array}[{first}] has it already); names must be unique",
                    quoted(name)
                )
            } else {
                format!(
                    "this {what}'s default name {} is already used by {array}[{first}]; give it a unique name",
                    quoted(name)
                )
            };
            root.problem(&format!("{array}[{i}].name"), message);
            ok = false;
        } else {
            seen.push((name, i));
        }
    }
    ok
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> Table {
        parse("t.toml", text).expect("test TOML parses")
    }

    fn lines(problems: Problems) -> Vec<String> {
        problems
            .into_vec()
            .iter()
            .map(|p| error_line(p).trim_end().to_string())
            .collect()
    }

    /// `read_text_at_most(path, limit)` on a thread, failing the test if it has
    /// not returned within 20 s (a read that waits for ever fails, not hangs).
    fn read_within(path: &Path, limit: u64) -> Result<String, String> {
        let path = path.to_path_buf();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(
                read_text_at_most(&path, limit).map_err(|p| error_line(p).trim_end().to_string()),
            );
        });
        rx.recv_timeout(std::time::Duration::from_secs(20))
            .expect("the read returned")
    }

    #[test]
    fn only_a_regular_file_of_bounded_size_is_read() {
        let dir = std::env::temp_dir().join(format!("machine-file-read-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let small = dir.join("small.toml");
        std::fs::write(&small, "x = 1\n").unwrap();
        assert_eq!(read_within(&small, 6), Ok("x = 1\n".into()));
        let message = read_within(&small, 5).unwrap_err();
        assert!(
            message.ends_with("small.toml: cannot read the file: too large (6 bytes): an input file of this kind has at most 5 bytes"),
            "{message}"
        );
        std::fs::write(dir.join("latin1.toml"), b"x = \"\xe9\"\n").unwrap();
        let message = read_within(&dir.join("latin1.toml"), 100).unwrap_err();
        assert!(
            message.ends_with("cannot read the file: not UTF-8 text"),
            "{message}"
        );
        let message = read_within(&dir, 100).unwrap_err();
        assert!(
            message.ends_with("cannot read the file: a directory, not a regular file (an input file is read whole)"),
            "{message}"
        );
        let message = read_within(&dir.join("none.toml"), 100).unwrap_err();
        assert!(
            message.ends_with("cannot read the file: no such file"),
            "{message}"
        );
        #[cfg(unix)]
        {
            // A device that never ends, and a named pipe no one writes to: both
            // refused before they are opened.
            let message = read_within(Path::new("/dev/zero"), MAX_FILE_BYTES).unwrap_err();
            assert_eq!(
                message,
                "error: /dev/zero: cannot read the file: a device, not a regular file (an input file is read whole)"
            );
            let fifo = dir.join("fifo.toml");
            let _ = std::fs::remove_file(&fifo);
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let message = read_within(&fifo, MAX_FILE_BYTES).unwrap_err();
                assert!(
                    message.ends_with("fifo.toml: cannot read the file: a named pipe (FIFO), not a regular file (an input file is read whole)"),
                    "{message}"
                );
            } else {
                panic!("mkfifo is needed for this test");
            }
        }
        // A regular file that reports no size (0) and has more: cut at the limit
        // while read, not trusted.
        #[cfg(target_os = "linux")]
        {
            let maps = Path::new("/proc/self/maps");
            assert_eq!(std::fs::metadata(maps).unwrap().len(), 0);
            let message = read_within(maps, 16).unwrap_err();
            assert!(
                message.ends_with("cannot read the file: too large (more than 16 bytes): an input file of this kind has at most 16 bytes"),
                "{message}"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn numbers_are_checked_with_their_key_path() {
        let t = table("[a]\nx = -1.0\ny = nan\nz = \"s\"\nw = 3\n");
        let p = Problems::new("t.toml");
        let root = Section::root(&t, &p);
        let a = root.section("a", Need::Required).unwrap();
        assert_eq!(a.number("x", Need::Required, Limit::Positive), None);
        assert_eq!(a.number("y", Need::Required, Limit::Any), None);
        assert_eq!(a.number("z", Need::Required, Limit::Any), None);
        assert_eq!(a.number("w", Need::Required, Limit::Any), Some(3.0));
        assert_eq!(a.number("v", Need::Default(2.0), Limit::Any), Some(2.0));
        assert_eq!(a.number("u", Need::Required, Limit::Any), None);
        a.finish();
        root.finish();
        assert_eq!(
            lines(p),
            [
                "error: t.toml: a.x: must be > 0 (got -1)",
                "error: t.toml: a.y: must be a finite number (got nan)",
                "error: t.toml: a.z: must be a number (got the string \"s\")",
                "error: t.toml: a.u: missing; required: a number",
            ]
        );
    }

    #[test]
    fn unknown_keys_get_a_suggestion_and_the_allowed_list() {
        let t = table("mas = 1.0\nzzz = 2\nmass = 1.0\n");
        let p = Problems::new("t.toml");
        let root = Section::root(&t, &p);
        root.number("mass", Need::Required, Limit::Positive);
        root.number("inertia", Need::Optional, Limit::Positive);
        root.finish();
        let l = lines(p);
        assert_eq!(l.len(), 2, "{l:?}");
        assert!(
            l[0].contains("t.toml: mas: unknown key; did you mean `mass`?"),
            "{l:?}"
        );
        assert!(l[0].contains("allowed here: mass, inertia"), "{l:?}");
        assert!(!l[1].contains("did you mean"), "{l:?}");
    }

    #[test]
    fn array_of_tables_elements_are_numbered_from_zero() {
        let t = table("[[c]]\nf = 1\n[[c]]\nf = -1\n");
        let p = Problems::new("t.toml");
        let root = Section::root(&t, &p);
        for s in root.sections("c").unwrap().into_iter().flatten() {
            s.number("f", Need::Required, Limit::NonNegative);
            s.finish();
        }
        root.finish();
        assert_eq!(lines(p), ["error: t.toml: c[1].f: must be >= 0 (got -1)"]);
    }

    #[test]
    fn vectors_report_the_bad_element() {
        let t = table("v = [1.0, inf]\nw = [1.0]\n");
        let p = Problems::new("t.toml");
        let root = Section::root(&t, &p);
        assert_eq!(root.vec2("v", Need::Required, Limit::Any), None);
        assert_eq!(root.vec2("w", Need::Required, Limit::Any), None);
        root.finish();
        let l = lines(p);
        assert_eq!(
            l[0],
            "error: t.toml: v[1]: must be a finite number (got inf)"
        );
        assert!(
            l[1].contains("w: must be an array of two numbers [x, y]"),
            "{l:?}"
        );
    }

    #[test]
    fn choices_suggest_the_nearest() {
        let t = table("law = \"poison\"\n");
        let p = Problems::new("t.toml");
        let root = Section::root(&t, &p);
        let got = root.choice("law", Need::Default("poisson"), &["poisson", "newton"]);
        assert_eq!(got, None);
        root.finish();
        let l = lines(p);
        assert!(l[0].contains("law: unknown value \"poison\"; did you mean \"poisson\"?"));
        assert!(l[0].contains("allowed: poisson, newton"));
    }

    #[test]
    fn syntax_errors_give_line_and_column() {
        let e = parse("t.toml", "a = 1\nb = = 2\n").unwrap_err();
        assert_eq!(e.location, Location::Line { line: 2, column: 5 });
        let s = render(&[e]);
        assert!(s.starts_with("error: t.toml:2:5: TOML syntax: "), "{s}");
        assert_eq!(s.lines().count(), 1, "{s}");
    }

    #[test]
    fn line_column_counts_characters() {
        assert_eq!(line_column("ab\ncdé\nf", 8), (3, 1));
        assert_eq!(line_column("ab\ncdé\nf", 4), (2, 2));
    }

    #[test]
    fn long_fields_are_cut_with_their_length() {
        assert_eq!(cut("fast", 4), "fast");
        assert_eq!(cut("faster", 4), "fast... (6 bytes)");
        // Never inside a character: "é" is 2 bytes.
        assert_eq!(cut("aéb", 2), "a... (4 bytes)");
        let huge = "q".repeat(10_000_000);
        assert!(cut(&huge, 400).len() <= cut_bound(400));
        assert_eq!(quoted("ccw"), "\"ccw\"");
        assert_eq!(
            quoted(&"q".repeat(41)),
            format!("\"{}... (41 bytes)\"", "q".repeat(40))
        );
    }

    #[test]
    fn numbers_in_messages() {
        assert_eq!(number(-0.1), "-0.1");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(f64::NEG_INFINITY), "-inf");
        assert_eq!(number(2.0), "2");
    }
}
