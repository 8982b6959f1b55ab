//! `[uncertainty]`: the ranges within which some of the machine file's numbers are
//! not known (docs/machine-file.md, "`[uncertainty]`: what is not known"), and machines
//! drawn from them.
//!
//! ```toml
//! [uncertainty]
//! "contacts.*.restitution" = [0.2, 0.45]   # every contact together
//! "contacts.K1.friction" = [0.3, 0.5]      # one contact
//! "rotors.*.motor.resistance" = [1.8, 2.4]
//! ```
//!
//! A key is a `--set` key ([`crate::set`]): an element of `[[contacts]]`,
//! `[[rotors]]`, `[[bodies]]` or `[[joints]]` by its name or index, or `*` for every
//! element of the array together (one number drawn for all). A value is
//! `[LOW, HIGH]`, two finite numbers with `LOW < HIGH`.
//!
//! Checked like every key (exit 2, the key named): the key must be one `--set`
//! takes; the machine file with the key at `LOW`, and with it at `HIGH`, must pass
//! every check of the machine file (so `[0.2, 1.5]` for a restitution is refused at
//! `HIGH`, with the restitution's own message). Each end is checked with the other
//! keys at their file values; a range's ends are the extremes its machines take.
//!
//! **Machines drawn from the ranges** ([`Uncertainty::draw`]): the nominal machine
//! (the file's values) first, then a Latin hypercube of the ranges (McKay, Beckman &
//! Conover, *Technometrics* 21, 1979): with `n` points, each range is cut into `n`
//! equal strata and every stratum holds exactly one point, the strata paired at
//! random across ranges, each point uniform within its stratum. Deterministic for a
//! seed (SplitMix64, Steele, Lea & Flood, OOPSLA 2014; no dependency, the same
//! numbers on every platform).

use std::path::Path;

use toml::{Table, Value};

use crate::input::{cut, Location, Problem, Problems, MAX_QUOTED};
use crate::set;

/// The section's name in the machine file.
pub const SECTION: &str = "uncertainty";

/// One uncertain key.
#[derive(Clone, Debug, PartialEq)]
pub struct Range {
    /// The key as written (`contacts.*.restitution`).
    pub key: String,
    /// The `--set` keys it stands for, elements by index (`contacts.0.restitution`,
    /// `contacts.1.restitution`): one for a key without `*`.
    pub targets: Vec<String>,
    /// Lowest value.
    pub low: f64,
    /// Highest value.
    pub high: f64,
}

/// The `[uncertainty]` of a machine file: its ranges in file order (empty when the
/// file has none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Uncertainty {
    /// The ranges.
    pub ranges: Vec<Range>,
}

impl Uncertainty {
    /// Reads and checks the `[uncertainty]` of the machine file at `path` with the
    /// `--set` overrides `sets` (the machine the ranges vary); every problem at once.
    pub fn load(path: &Path, sets: &[String]) -> Result<Uncertainty, Vec<Problem>> {
        let text = crate::input::read_text(path).map_err(|p| vec![p])?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Uncertainty::from_text(&path.display().to_string(), &text, dir, sets)
    }

    /// [`Uncertainty::load`] from the text of a machine file named `file`.
    pub fn from_text(
        file: &str,
        text: &str,
        dir: &Path,
        sets: &[String],
    ) -> Result<Uncertainty, Vec<Problem>> {
        // The machine's checks, `[uncertainty]`'s included (`check`, from
        // `Machine::from_text`); then the ranges they passed, read again without
        // checking their ends twice.
        crate::Machine::from_text(file, text, dir, sets)?;
        let mut table = crate::input::parse(file, text).map_err(|p| vec![p])?;
        let _ = set::apply(&mut table, &set::Override::command_line(sets));
        let problems = Problems::new(file);
        let ranges = read(&table, &problems);
        problems.into_result(Some(Uncertainty { ranges }))
    }

    /// The `--set` arguments that put every range at the fraction `u[i]` of its way
    /// from `LOW` (0) to `HIGH` (1): `LOW + u (HIGH - LOW)` for each target.
    pub fn sets_at(&self, u: &[f64]) -> Vec<String> {
        let mut out = Vec::new();
        for (r, ui) in self.ranges.iter().zip(u) {
            let value = r.low + ui * (r.high - r.low);
            for t in &r.targets {
                out.push(format!("{t}={value:?}"));
            }
        }
        out
    }

    /// `n` machines as `--set` arguments over the file's: the nominal one (no
    /// argument) first, then `n - 1` points of a Latin hypercube of the ranges
    /// drawn with `seed` (see the module documentation). Without ranges, the
    /// nominal machine alone, whatever `n`.
    pub fn draw(&self, n: usize, seed: u64) -> Vec<Vec<String>> {
        let mut out = vec![Vec::new()];
        if self.ranges.is_empty() || n < 2 {
            return out;
        }
        for point in latin_hypercube(n - 1, self.ranges.len(), seed) {
            out.push(self.sets_at(&point));
        }
        out
    }
}

/// `n` points of a Latin hypercube in `[0, 1)^d`: along every dimension the points
/// fall one in each of the strata `[k / n, (k + 1) / n)`.
pub fn latin_hypercube(n: usize, d: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SplitMix64(seed);
    let mut points = vec![vec![0.0; d]; n];
    for dim in 0..d {
        // A random order of the strata (Fisher-Yates), one stratum per point.
        let mut strata: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = (rng.next() % (i as u64 + 1)) as usize;
            strata.swap(i, j);
        }
        for (p, k) in points.iter_mut().zip(strata) {
            p[dim] = (k as f64 + rng.unit()) / n as f64;
        }
    }
    points
}

/// SplitMix64: a 64-bit generator with a full period, its output mixed from a
/// Weyl sequence.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`: the top 53 bits.
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The arrays of tables whose elements `*` stands for.
const ARRAYS: [&str; 4] = ["contacts", "rotors", "bodies", "joints"];

/// Checks `[uncertainty]` of the parsed machine file `table` (which passed the
/// machine's checks), recording problems in `problems`: each range as
/// [`read`] reads it, then its ends against the whole machine.
pub(crate) fn check(table: &Table, problems: &Problems, dir: &Path) {
    for range in read(table, problems) {
        let at = at(&range.key);
        for (end, x) in [("LOW", range.low), ("HIGH", range.high)] {
            let sets: Vec<String> = range.targets.iter().map(|t| format!("{t}={x:?}")).collect();
            let mut varied = table.clone();
            // The keys were applied by `read`: nothing is refused here.
            let _ = set::apply(&mut varied, &set::Override::command_line(&sets));
            let file_problems = Problems::new("");
            let _ = crate::check(&varied, &file_problems, dir);
            for p in file_problems.into_vec() {
                let place = match &p.location {
                    Location::Key(k) => format!("{k}: "),
                    _ => String::new(),
                };
                problems.at(&at, format!("at {end} = {x}: {place}{}", p.message));
            }
        }
    }
}

/// The key path of range `key` in messages: `uncertainty."contacts.*.friction"`
/// (the key [`cut`] at [`MAX_QUOTED`]).
fn at(key: &str) -> String {
    format!("{SECTION}.\"{}\"", cut(key, MAX_QUOTED))
}

/// The ranges of `[uncertainty]` in `table` whose form and keys are right (two
/// numbers, a key `--set` takes, `*` where it may stand, one range a key); the
/// others recorded in `problems`. Their ends are not checked against the machine
/// ([`check`] does that).
fn read(table: &Table, problems: &Problems) -> Vec<Range> {
    let mut out = Vec::new();
    let Some(section) = table.get(SECTION) else {
        return out;
    };
    let Value::Table(entries) = section else {
        problems.at(
            SECTION,
            format!(
                "must be a table [{SECTION}] of \"KEY\" = [LOW, HIGH] (got a {})",
                section.type_str()
            ),
        );
        return out;
    };
    // The machine file's key each range varies (the reader's path,
    // `contacts[1].restitution`), with the range that varies it: one range a key.
    let mut varied_by: Vec<(String, String)> = Vec::new();
    for (key, value) in entries {
        let at = at(key);
        let Some((low, high)) = bounds(value) else {
            problems.at(
                &at,
                format!(
                    "must be [LOW, HIGH], two finite numbers with LOW < HIGH (got {})",
                    cut(&value.to_string(), MAX_QUOTED)
                ),
            );
            continue;
        };
        let targets = match expand(table, key) {
            Ok(t) => t,
            Err(message) => {
                problems.at(&at, message);
                continue;
            }
        };
        let sets: Vec<String> = targets.iter().map(|t| format!("{t}={low:?}")).collect();
        let (applied, refused) =
            set::apply(&mut table.clone(), &set::Override::command_line(&sets));
        if let Some(p) = refused.first() {
            // The key itself, as `--set` refuses it.
            problems.at(&at, p.message.clone());
            continue;
        }
        let mut alone = true;
        for a in &applied {
            match varied_by.iter().find(|(path, _)| *path == a.key_path) {
                Some((path, other)) => {
                    problems.at(
                        &at,
                        format!(
                            "varies {path}, which \"{}\" varies too: one range a key",
                            cut(other, MAX_QUOTED)
                        ),
                    );
                    alone = false;
                }
                None => varied_by.push((a.key_path.clone(), key.clone())),
            }
        }
        if alone {
            out.push(Range {
                key: key.clone(),
                targets,
                low,
                high,
            });
        }
    }
    out
}

/// `[LOW, HIGH]`: two finite numbers (integers taken as numbers), `LOW < HIGH`.
fn bounds(value: &Value) -> Option<(f64, f64)> {
    let Value::Array(items) = value else {
        return None;
    };
    let number = |v: &Value| match v {
        Value::Float(x) => Some(*x),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    };
    match items.as_slice() {
        [a, b] => {
            let (low, high) = (number(a)?, number(b)?);
            (low.is_finite() && high.is_finite() && low < high).then_some((low, high))
        }
        _ => None,
    }
}

/// The `--set` keys `key` stands for in the parsed machine file `table`: itself,
/// or with its `*` segment replaced by the index of every element of the array
/// before it. `Err`: why `*` cannot stand there.
pub fn expand(table: &Table, key: &str) -> Result<Vec<String>, String> {
    let segments: Vec<&str> = key.split('.').collect();
    let stars: Vec<usize> = (0..segments.len())
        .filter(|&i| segments[i] == "*")
        .collect();
    match stars.as_slice() {
        [] => Ok(vec![key.to_string()]),
        [1] if ARRAYS.contains(&segments[0]) => {
            let count = match table.get(segments[0]) {
                Some(Value::Array(items)) => items.len(),
                _ => 0,
            };
            if count == 0 {
                return Err(format!(
                    "`*` stands for every element of [[{}]], and the file has none",
                    segments[0]
                ));
            }
            Ok((0..count)
                .map(|i| {
                    let mut s: Vec<String> = segments.iter().map(|s| s.to_string()).collect();
                    s[1] = i.to_string();
                    s.join(".")
                })
                .collect())
        }
        _ => Err(format!(
            "`*` stands only for the element right after an array of tables ({}), e.g. contacts.*.friction",
            ARRAYS.join(", ")
        )),
    }
}
