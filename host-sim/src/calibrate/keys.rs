//! The keys `host-sim calibrate --fit` varies: each a `--set` key, with `*` for
//! every element of an array together (as `[uncertainty]`'s keys), searched within
//! a range:
//! - the file's `[uncertainty]` range for the same machine keys, when it has one;
//! - else the key's valid range as the machine reader checks it
//!   ([`Machine::numbers`]: `contacts.*.restitution` in [0, 1]); a key whose valid
//!   range has no finite ends (`friction >= 0`) needs an `[uncertainty]` range.
//!
//! The search works on the box-normalised coordinate `u` in [0, 1] of each key
//! (`value = LOW + u (HIGH - LOW)`), and every value it tries is rounded to 6
//! significant digits first, so that the value reported, the one `--write` writes
//! and the one the residuals were simulated with are the same number.

use std::path::Path;

use crate::failure::{Failure, Kind, Reason};
use crate::machine::input::{self, Limit, NumberRead};
use crate::machine::set;
use crate::machine::uncertainty::{self, Uncertainty};
use crate::machine::Machine;
use crate::numbers;

/// Where a key's search range comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// The machine file's `[uncertainty]` range of the key.
    Uncertainty,
    /// The key's valid range (the machine reader's check).
    Valid,
}

impl Bound {
    /// For the report: `[uncertainty]` or `valid range`.
    pub fn name(self) -> &'static str {
        match self {
            Bound::Uncertainty => "[uncertainty]",
            Bound::Valid => "valid range",
        }
    }
}

/// One fitted key.
#[derive(Clone, Debug, PartialEq)]
pub struct FitKey {
    /// The key as given (`contacts.*.restitution`).
    pub key: String,
    /// The `--set` keys it stands for (`contacts.0.restitution`, ...).
    pub targets: Vec<String>,
    /// The machine reader's key paths of the targets (`contacts[0].restitution`).
    pub key_paths: Vec<String>,
    /// Lowest value searched.
    pub low: f64,
    /// Highest value searched.
    pub high: f64,
    /// Where the range comes from.
    pub bound: Bound,
    /// The file's value (the mean over the targets when they differ).
    pub nominal: f64,
}

impl FitKey {
    /// The value at the normalised coordinate `u` (clamped to [0, 1]), rounded
    /// to 6 significant digits and kept within the range.
    pub fn value_at(&self, u: f64) -> f64 {
        let x = self.low + u.clamp(0.0, 1.0) * (self.high - self.low);
        let rounded = numbers::sig(x).parse::<f64>().unwrap_or(x);
        rounded.clamp(self.low, self.high)
    }

    /// The normalised coordinate of `value`.
    pub fn u_of(&self, value: f64) -> f64 {
        (value - self.low) / (self.high - self.low)
    }

    /// The width of the range.
    pub fn width(&self) -> f64 {
        self.high - self.low
    }
}

/// The `--set` arguments putting every key `keys[i]` at the normalised `u[i]`.
pub fn sets_at(keys: &[FitKey], u: &[f64]) -> Vec<String> {
    let mut out = Vec::new();
    for (k, ui) in keys.iter().zip(u) {
        let value = k.value_at(*ui);
        for t in &k.targets {
            out.push(format!("{t}={value:?}"));
        }
    }
    out
}

/// The fitted keys `fit` of the machine file `path` (its `text`, with the `--set`s
/// `sets`), checked: every problem at once, the user's to fix.
pub fn resolve(
    path: &Path,
    text: &str,
    sets: &[String],
    fit: &[String],
) -> Result<Vec<FitKey>, Failure> {
    let file = path.display().to_string();
    let dir = path.parent().unwrap_or(Path::new(""));
    let numbers = Machine::numbers(&file, text, dir, sets)?;
    let ranges = Uncertainty::from_text(&file, text, dir, sets)?;
    let mut table = input::parse(&file, text)?;
    let (set_applied, _) = set::apply(&mut table, &set::Override::command_line(sets));

    let mut problems = Vec::new();
    let mut keys: Vec<FitKey> = Vec::new();
    for key in fit {
        match resolve_one(&file, &table, &numbers, &ranges, key) {
            Ok(k) => {
                // One key, one fit; a fitted key is not also set.
                if let Some(other) = keys
                    .iter()
                    .find(|o| o.key_paths.iter().any(|p| k.key_paths.contains(p)))
                {
                    problems.push(Reason::new(format!(
                        "--fit {key}: varies a key that --fit {} varies too: one fit a key",
                        other.key
                    )));
                } else if let Some(s) = set_applied
                    .iter()
                    .find(|a| k.key_paths.contains(&a.key_path))
                {
                    problems.push(Reason::new(format!(
                        "--fit {key}: --set {} sets {} too: a fitted key is not also set",
                        s.arg, s.key_path
                    )));
                } else {
                    keys.push(k);
                }
            }
            Err(refused) => problems.extend(refused.into_reasons()),
        }
    }
    if keys.is_empty() && problems.is_empty() {
        problems.push(Reason::new(
            "--fit: no key to fit (e.g. --fit contacts.*.restitution)",
        ));
    }
    if problems.is_empty() {
        Ok(keys)
    } else {
        Err(Failure::new(Kind::Usage, problems))
    }
}

/// The reader's key paths of the `--set` keys `targets` (all of which apply).
fn key_paths(table: &toml::Table, targets: &[String]) -> Result<Vec<String>, String> {
    let sets: Vec<String> = targets.iter().map(|t| format!("{t}=0")).collect();
    let (applied, refused) = set::apply(&mut table.clone(), &set::Override::command_line(&sets));
    match refused.first() {
        Some(p) => Err(p.message.clone()),
        None => Ok(applied.into_iter().map(|a| a.key_path).collect()),
    }
}

/// One `--fit` key: its targets, range and nominal value.
fn resolve_one(
    file: &str,
    table: &toml::Table,
    numbers: &[NumberRead],
    ranges: &Uncertainty,
    key: &str,
) -> Result<FitKey, Failure> {
    let refuse = |why: String| Failure::usage(format!("--fit {key}: {why}"));
    let targets = uncertainty::expand(table, key).map_err(refuse)?;
    let paths = key_paths(table, &targets).map_err(refuse)?;
    let mut read = Vec::new();
    for p in &paths {
        // A rotor's own motor key the file leaves to `[motor]` is `[motor]`'s
        // number there: its value and its limit.
        let inherited = machine_motor_key(p);
        let found = numbers.iter().find(|n| n.key_path == *p).or_else(|| {
            numbers
                .iter()
                .find(|n| Some(&n.key_path) == inherited.as_ref())
        });
        match found {
            Some(n) => read.push((p, n)),
            None => {
                return Err(refuse(format!(
                    "{p} is not a number this machine reads (calibrate fits real-valued keys: not strings, integers, or keys the machine does not use)"
                )))
            }
        }
    }
    let nominal = read.iter().map(|(_, n)| n.value).sum::<f64>() / read.len() as f64;

    // The range: `[uncertainty]`'s for the same keys, else the narrowest one
    // that holds each of them, else the valid one.
    let same = covering_range(table, ranges, &paths);
    let (low, high, bound) = match same {
        Some(r) => (r.low, r.high, Bound::Uncertainty),
        None => {
            let (mut low, mut high) = (f64::NEG_INFINITY, f64::INFINITY);
            for (p, n) in &read {
                if let Limit::Between(lo, hi) = n.limit {
                    low = low.max(lo);
                    high = high.min(hi);
                } else {
                    return Err(Failure::usage(format!(
                        "{file}: --fit {key}: {} must be {} and has no finite range to search: give its range in the file's [uncertainty], e.g. \"{key}\" = [{}, {}] (docs/calibration.md)",
                        p,
                        n.limit.describe(),
                        numbers::sig(example_range(n.value).0),
                        numbers::sig(example_range(n.value).1),
                    )));
                }
            }
            (low, high, Bound::Valid)
        }
    };
    if !(nominal >= low && nominal <= high) {
        return Err(Failure::usage(format!(
            "{file}: --fit {key}: the file's value {} lies outside the range searched [{}, {}] ({}): widen the range or correct the value",
            numbers::sig(nominal),
            numbers::sig(low),
            numbers::sig(high),
            bound.name()
        )));
    }
    Ok(FitKey {
        key: key.to_string(),
        targets,
        key_paths: paths,
        low,
        high,
        bound,
        nominal,
    })
}

/// The `[uncertainty]` range of a fitted key whose reader's key paths are
/// `paths`: the range of exactly those keys; else the range, of those that
/// hold every one of them, with the fewest keys (file order between equals).
/// A range holds a key it names (`contacts.*.friction` holds `contacts[0].friction`:
/// what is uncertain for every foot is uncertain for one), and the machine's
/// `motor.KEY` holds each rotor's `rotors[i].motor.KEY` (`[motor]` is every
/// rotor's motor until a rotor's own table replaces the key: the same make of
/// motor, the same range).
fn covering_range<'r>(
    table: &toml::Table,
    ranges: &'r Uncertainty,
    paths: &[String],
) -> Option<&'r uncertainty::Range> {
    let mut mine = paths.to_vec();
    mine.sort();
    let mut best: Option<(&uncertainty::Range, usize)> = None;
    for r in &ranges.ranges {
        let Ok(mut theirs) = key_paths(table, &r.targets) else {
            continue;
        };
        theirs.sort();
        if theirs == mine {
            return Some(r);
        }
        let holds = |p: &String| {
            theirs.contains(p) || machine_motor_key(p).is_some_and(|m| theirs.contains(&m))
        };
        if mine.iter().all(holds) && best.is_none_or(|(_, n)| theirs.len() < n) {
            best = Some((r, theirs.len()));
        }
    }
    best.map(|(r, _)| r)
}

/// The machine's motor key (`motor.resistance`) that a rotor's own motor key
/// (`rotors[1].motor.resistance`) replaces; `None` for any other key path.
pub fn machine_motor_key(key_path: &str) -> Option<String> {
    let rest = key_path.strip_prefix("rotors[")?;
    let (index, key) = rest.split_once("].motor.")?;
    (index.parse::<usize>().is_ok() && !key.contains('.')).then(|| format!("motor.{key}"))
}

/// A range to suggest around `value`: half to one and a half times it (or -1 to 1
/// around 0).
fn example_range(value: f64) -> (f64, f64) {
    if value == 0.0 {
        (-1.0, 1.0)
    } else {
        let (a, b) = (0.5 * value, 1.5 * value);
        (a.min(b), a.max(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference machine without its own `[uncertainty]` (the file's last
    /// section): these tests give their own ranges, or none.
    fn reference() -> &'static str {
        include_str!("../../../examples/vibro-driver.toml")
            .split_once("\n[uncertainty]\n")
            .expect("the reference machine's [uncertainty]")
            .0
    }

    fn with(extra: &str) -> String {
        format!("{}\n{extra}", reference())
    }

    /// The keys, or the failure's message as the user reads it.
    fn keys(text: &str, fit: &[&str]) -> Result<Vec<FitKey>, String> {
        let fit: Vec<String> = fit.iter().map(|s| s.to_string()).collect();
        resolve(Path::new("m.toml"), text, &[], &fit).map_err(|f| f.message())
    }

    #[test]
    fn ranges_from_uncertainty_or_the_reader() {
        let text = with("[uncertainty]\n\"contacts.*.friction\" = [0.2, 0.6]\n");
        let k = keys(&text, &["contacts.*.restitution", "contacts.*.friction"]).unwrap();
        assert_eq!((k[0].low, k[0].high, k[0].bound), (0.0, 1.0, Bound::Valid));
        assert_eq!(
            k[0].key_paths,
            ["contacts[0].restitution", "contacts[1].restitution"]
        );
        assert_eq!(k[0].nominal, 0.3);
        assert_eq!(
            (k[1].low, k[1].high, k[1].bound),
            (0.2, 0.6, Bound::Uncertainty)
        );
        assert_eq!(
            sets_at(&k[1..], &[0.5]),
            ["contacts.0.friction=0.4", "contacts.1.friction=0.4"]
        );
        // A key named by its element matches the range of the same keys.
        let text = with("[uncertainty]\n\"contacts.K1.friction\" = [0.3, 0.5]\n");
        let k = keys(&text, &["contacts.0.friction"]).unwrap();
        assert_eq!((k[0].low, k[0].high), (0.3, 0.5));
    }

    /// A key without a range of its own takes the narrowest range that holds
    /// it: a `*` range holds each element, the machine's `motor.KEY` each
    /// rotor's own motor key; a range of its own comes first.
    #[test]
    fn a_range_that_holds_the_key_serves_it() {
        let text = with(
            "[uncertainty]\n\"contacts.*.friction\" = [0.2, 0.6]\n\"motor.resistance\" = [1.5, 3.0]\n\"rotors.1.motor.resistance\" = [1.8, 2.6]\n",
        );
        let k = keys(
            &text,
            &[
                "contacts.K1.friction",
                "rotors.0.motor.resistance",
                "rotors.right.motor.resistance",
            ],
        )
        .unwrap();
        let ranges: Vec<(f64, f64, Bound)> = k.iter().map(|k| (k.low, k.high, k.bound)).collect();
        assert_eq!(
            ranges,
            [
                (0.2, 0.6, Bound::Uncertainty),
                (1.5, 3.0, Bound::Uncertainty),
                (1.8, 2.6, Bound::Uncertainty),
            ]
        );
        assert_eq!(k[1].key_paths, ["rotors[0].motor.resistance"]);
        assert_eq!(k[1].nominal, 2.0);
        // Every rotor together: both held by `motor.resistance`, not by the
        // range of rotor 2 alone.
        let k = keys(&text, &["rotors.*.motor.resistance"]).unwrap();
        assert_eq!((k[0].low, k[0].high), (1.5, 3.0));
        assert_eq!(
            machine_motor_key("rotors[1].motor.torque_constant").as_deref(),
            Some("motor.torque_constant")
        );
        assert_eq!(machine_motor_key("rotors[1].inertia"), None);
        assert_eq!(machine_motor_key("motor.resistance"), None);
    }

    #[test]
    fn values_are_rounded_and_kept_in_range() {
        let k = &keys(reference(), &["contacts.K1.restitution"]).unwrap()[0];
        assert_eq!(k.value_at(1.0 / 3.0), 0.333333);
        assert_eq!(k.value_at(2.0), 1.0);
        assert_eq!(k.value_at(-1.0), 0.0);
    }

    #[test]
    fn refusals_name_the_key_and_what_is_allowed() {
        let e = keys(reference(), &["contacts.*.friction"]).unwrap_err();
        assert_eq!(
            e,
            "error: m.toml: --fit contacts.*.friction: contacts[0].friction must be >= 0 and has no finite range to search: give its range in the file's [uncertainty], e.g. \"contacts.*.friction\" = [0.2, 0.6] (docs/calibration.md)\n"
        );
        let e = keys(reference(), &["contacts.*.frction"]).unwrap_err();
        assert!(
            e.starts_with("error: --fit contacts.*.frction: unknown key `frction`"),
            "{e}"
        );
        let e = keys(reference(), &["controller.tuning_table"]).unwrap_err();
        assert!(e.contains("is not a number this machine reads"), "{e}");
        let e = keys(
            reference(),
            &["contacts.*.restitution", "contacts.K2.restitution"],
        )
        .unwrap_err();
        assert!(e.contains("one fit a key"), "{e}");
        let text = with("[uncertainty]\n\"contacts.*.friction\" = [0.5, 0.6]\n");
        let e = keys(&text, &["contacts.*.friction"]).unwrap_err();
        assert_eq!(
            e,
            "error: m.toml: --fit contacts.*.friction: the file's value 0.4 lies outside the range searched [0.5, 0.6] ([uncertainty]): widen the range or correct the value\n"
        );
        let sets = ["contacts.K1.restitution=0.2".to_string()];
        let e = resolve(
            Path::new("m.toml"),
            reference(),
            &sets,
            &["contacts.*.restitution".into()],
        )
        .unwrap_err()
        .message();
        assert!(e.contains("a fitted key is not also set"), "{e}");
    }
}
