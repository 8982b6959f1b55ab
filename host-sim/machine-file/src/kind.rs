//! Which of host-sim's input files a TOML table is, told apart by its top-level
//! keys, so that a file given to the wrong command is refused in one line naming
//! what it is and the command that reads it, instead of a list of keys the reader
//! did not expect (`host-sim impact` given a machine file listed five).
//!
//! | kind | told by | read by |
//! | --- | --- | --- |
//! | machine file | `[platform]` or `[[rotors]]` | `run`, `tune`, `calibrate`, `device-sim --machine` |
//! | tuning table | `[[rows]]` | a machine's `[controller].tuning_table`, `device table write` |
//! | impact case | `[body]` | `impact` |
//! | scenario | `[[expect]]`, or `machine = "FILE"` | `scenario` |
//!
//! The rules are tried in that order; a table none of them fits is left to the
//! reader, whose key-by-key problems then say what is missing.

use toml::Table;

use crate::input::{Location, Problem};

/// A kind of input file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// A machine file (docs/machine-file.md).
    Machine,
    /// A tuning table file (as `host-sim tune --write` writes it).
    TuningTable,
    /// An impact case file (docs/cli-impact.md).
    ImpactCase,
    /// A scenario file (docs/scenarios.md).
    Scenario,
}

impl FileKind {
    /// What `table` looks like, with the keys that tell it (`[platform] and
    /// [[rotors]]`); `None` when it looks like none of them.
    pub fn of(table: &Table) -> Option<(FileKind, String)> {
        let present = |keys: &[(&str, &str)]| -> Vec<String> {
            keys.iter()
                .filter(|(k, _)| table.contains_key(*k))
                .map(|(_, shown)| shown.to_string())
                .collect()
        };
        let machine = present(&[("platform", "[platform]"), ("rotors", "[[rotors]]")]);
        if !machine.is_empty() {
            return Some((FileKind::Machine, machine.join(" and ")));
        }
        if table.contains_key("rows") {
            return Some((FileKind::TuningTable, "[[rows]]".into()));
        }
        if table.contains_key("body") {
            return Some((FileKind::ImpactCase, "[body]".into()));
        }
        let named_machine = table.get("machine").is_some_and(|v| v.is_str());
        let scenario = present(&[("expect", "[[expect]]")]);
        if named_machine || !scenario.is_empty() {
            let mut by = scenario;
            if named_machine {
                by.insert(0, "machine = \"...\"".into());
            }
            return Some((FileKind::Scenario, by.join(" and ")));
        }
        None
    }

    /// The kind's name with its article: `a machine file`.
    pub fn name(self) -> &'static str {
        match self {
            FileKind::Machine => "a machine file",
            FileKind::TuningTable => "a tuning table",
            FileKind::ImpactCase => "an impact case",
            FileKind::Scenario => "a scenario",
        }
    }

    /// What takes a file of this kind.
    pub fn used_by(self) -> &'static str {
        match self {
            FileKind::Machine => {
                "use host-sim run (or tune, calibrate, device-sim --machine); see docs/machine-file.md"
            }
            FileKind::TuningTable => {
                "a machine file names it as [controller].tuning_table, host-sim device table write uploads it; see docs/tuning.md"
            }
            FileKind::ImpactCase => "use host-sim impact; see docs/cli-impact.md",
            FileKind::Scenario => "use host-sim scenario; see docs/scenarios.md",
        }
    }
}

/// The one problem of `table` (the file `file`) when it is recognisably another
/// kind of file than `expected`: `this is a machine file (it has [platform] and
/// [[rotors]]), not an impact case: use host-sim run ...`.
pub fn wrong_kind(file: &str, table: &Table, expected: FileKind) -> Option<Problem> {
    let (kind, by) = FileKind::of(table)?;
    (kind != expected).then(|| Problem {
        file: file.to_string(),
        location: Location::File,
        message: format!(
            "this is {} (it has {by}), not {}: {}",
            kind.name(),
            expected.name(),
            kind.used_by()
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kind(text: &str) -> Option<FileKind> {
        FileKind::of(&text.parse::<Table>().unwrap()).map(|(k, _)| k)
    }

    #[test]
    fn each_kind_is_told_by_its_keys() {
        assert_eq!(
            kind("[platform]\nmass = 1\n[[rotors]]\n[[contacts]]\n"),
            Some(FileKind::Machine)
        );
        // A machine file's [[contacts]] alone tells nothing: a case has them too.
        assert_eq!(kind("[[contacts]]\nfriction = 0.2\n"), None);
        assert_eq!(
            kind("[[rows]]\nspeed_rpm = 3000\n"),
            Some(FileKind::TuningTable)
        );
        assert_eq!(
            kind("law = \"newton\"\n[body]\n[[contacts]]\n"),
            Some(FileKind::ImpactCase)
        );
        assert_eq!(kind("machine = \"m.toml\"\n"), Some(FileKind::Scenario));
        assert_eq!(
            kind("[[expect]]\nkind = \"no_fault\"\n"),
            Some(FileKind::Scenario)
        );
        assert_eq!(kind("machine = 3\n"), None);
        assert_eq!(kind(""), None);
    }

    #[test]
    fn a_file_of_another_kind_is_one_problem_naming_both() {
        let table = "[platform]\n[[rotors]]\n".parse::<Table>().unwrap();
        let p = wrong_kind("m.toml", &table, FileKind::ImpactCase).unwrap();
        assert_eq!(
            crate::input::error_line(p).trim_end(),
            "error: m.toml: this is a machine file (it has [platform] and [[rotors]]), not an impact case: use host-sim run (or tune, calibrate, device-sim --machine); see docs/machine-file.md"
        );
        assert_eq!(wrong_kind("m.toml", &table, FileKind::Machine), None);
        let unknown = "x = 1\n".parse::<Table>().unwrap();
        assert_eq!(wrong_kind("x.toml", &unknown, FileKind::Machine), None);
    }
}
