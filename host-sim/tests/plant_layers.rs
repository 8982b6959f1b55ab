//! The plant's imports point one way (docs/development.md, "host-sim's
//! structure"), read from its source text:
//!
//! - the plant uses no part of host-sim above it: below `plant/` there is only the
//!   machine file's crate (`crate::machine`) and the events' plain rows
//!   (`crate::event`), and `event.rs` uses nothing of the crate;
//! - the plant's modules (`model`, `contact`, `dynamics`, `simulator` with its own
//!   files, ...) form no circle: a module that uses a sibling never is used by it,
//!   through any chain. A module's own folder (`simulator/`, the parts of one
//!   `impl Plant`) counts as the module.
//!
//! Paths are found wherever they are written (`use` lines and paths inside the
//! code), except in comments and in a file's `#[cfg(test)]` module at its end.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// `host-sim/src`.
fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// `path` from `host-sim/src`, for a message.
fn shown(path: &Path) -> String {
    path.strip_prefix(src())
        .unwrap_or(path)
        .display()
        .to_string()
}

/// What host-sim's own modules the plant may use (besides itself).
const PLANT_USES: [&str; 2] = ["machine", "event"];

/// A source file's code: comment lines dropped, and its test module (from
/// `#[cfg(test)]` on) cut off.
fn code(path: &Path) -> Vec<(usize, String)> {
    lines_of(&fs::read_to_string(path).unwrap())
}

/// [`code`] of `text`, with its line numbers: a `use` statement over several
/// lines (rustfmt's form of a long list) joined into its first, so that every
/// path it names is read.
fn lines_of(text: &str) -> Vec<(usize, String)> {
    let mut lines: Vec<(usize, String)> = Vec::new();
    let mut open_use = false;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        if t.starts_with("#[cfg(test)]") {
            break;
        }
        if t.starts_with("//") {
            continue;
        }
        if open_use {
            let last = lines.last_mut().expect("the statement's first line");
            last.1.push(' ');
            last.1.push_str(t);
        } else {
            lines.push((i + 1, line.to_string()));
        }
        let is_use = ["use ", "pub use ", "pub(crate) use ", "pub(super) use "]
            .iter()
            .any(|u| t.starts_with(u));
        open_use = (open_use || is_use) && !t.contains(';');
    }
    lines
}

/// The first segment of every path that starts with `prefix` (`crate::`,
/// `super::`, `super::super::`) on `line`: `prefix::a::B` gives `a`,
/// `prefix::{a::B, c}` gives `a` and `c`.
fn first_segments(line: &str, prefix: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (at, _) in line.match_indices(prefix) {
        // Not the tail of a longer path (`super::super::` when looking for `super::`).
        let before = &line[..at];
        if before.ends_with("::") || before.ends_with(|c: char| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let after = &line[at + prefix.len()..];
        let Some(group) = after.strip_prefix('{') else {
            let name: String = after
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() && name != "super" {
                found.push(name);
            }
            continue;
        };
        // The group's items, split at its own commas.
        let mut depth = 0;
        let mut item = String::new();
        for c in group.chars() {
            match c {
                '{' => depth += 1,
                '}' | ',' if depth == 0 => {
                    let name: String = item
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        found.push(name);
                    }
                    item.clear();
                    if c == '}' {
                        break;
                    }
                    continue;
                }
                '}' => depth -= 1,
                _ => {}
            }
            item.push(c);
        }
    }
    found
}

/// The plant's modules: each `plant/NAME.rs` (and `plant/NAME/`), `mod.rs` aside.
fn plant_modules() -> BTreeSet<String> {
    fs::read_dir(src().join("plant"))
        .unwrap()
        .filter_map(|e| {
            let path = e.unwrap().path();
            let name = path.file_stem()?.to_str()?.to_string();
            (name != "mod").then_some(name)
        })
        .collect()
}

/// Every source file of the plant, with the plant module it belongs to and the
/// prefix by which it names its siblings.
fn plant_files(modules: &BTreeSet<String>) -> Vec<(PathBuf, String, &'static str)> {
    let plant = src().join("plant");
    let mut files = Vec::new();
    for m in modules {
        let file = plant.join(format!("{m}.rs"));
        if file.is_file() {
            files.push((file, m.clone(), "super::"));
        }
        let folder = plant.join(m);
        if folder.is_dir() {
            let mut inner: Vec<PathBuf> = fs::read_dir(&folder)
                .unwrap()
                .map(|e| e.unwrap().path())
                .collect();
            inner.sort();
            for f in inner {
                assert!(
                    f.extension().is_some_and(|x| x == "rs"),
                    "{}: the test reads one level of files under a plant module",
                    f.display()
                );
                files.push((f, m.clone(), "super::super::"));
            }
        }
    }
    files
}

/// Who uses whom among the plant's modules, with where: `uses[a][b]` = the first
/// `file:line` where `a` names `b`.
type Uses = BTreeMap<String, BTreeMap<String, String>>;

/// A circle in `uses`, as its modules in order (the first repeated at the end).
fn circle(uses: &Uses) -> Option<Vec<String>> {
    fn visit(
        m: &str,
        uses: &Uses,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == m) {
            let mut c = path[at..].to_vec();
            c.push(m.to_string());
            return Some(c);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.to_string());
        for next in uses.get(m).into_iter().flat_map(|u| u.keys()) {
            if let Some(c) = visit(next, uses, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    uses.keys()
        .find_map(|m| visit(m, uses, &mut Vec::new(), &mut done))
}

#[test]
fn the_plant_uses_only_the_machine_file_and_the_event_rows_below_it() {
    let modules = plant_modules();
    let mut files: Vec<PathBuf> = plant_files(&modules).into_iter().map(|f| f.0).collect();
    files.push(src().join("plant/mod.rs"));
    let mut wrong = Vec::new();
    for file in &files {
        for (n, line) in code(file) {
            for m in first_segments(&line, "crate::") {
                if m != "plant" && !PLANT_USES.contains(&m.as_str()) {
                    wrong.push(format!("{}:{n}: crate::{m}", shown(file)));
                }
            }
        }
    }
    for (n, line) in code(&src().join("event.rs")) {
        for m in first_segments(&line, "crate::") {
            wrong.push(format!("event.rs:{n}: crate::{m}"));
        }
    }
    assert!(
        wrong.is_empty(),
        "the plant uses only {PLANT_USES:?} of host-sim, and event.rs nothing:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn the_plants_modules_form_no_circle() {
    let modules = plant_modules();
    let mut uses = Uses::new();
    for (file, owner, sibling) in plant_files(&modules) {
        for (n, line) in code(&file) {
            let named = first_segments(&line, sibling)
                .into_iter()
                .chain(first_segments(&line, "crate::plant::"));
            for m in named {
                if m != owner && modules.contains(&m) {
                    uses.entry(owner.clone())
                        .or_default()
                        .entry(m)
                        .or_insert_with(|| format!("{}:{n}", shown(&file)));
                }
            }
        }
    }
    // The test sees what it must: the dynamics use the model, the simulator both.
    assert!(uses["dynamics"].contains_key("model"), "{uses:?}");
    assert!(uses["simulator"].contains_key("dynamics"), "{uses:?}");
    if let Some(c) = circle(&uses) {
        let links: Vec<String> = c
            .windows(2)
            .map(|w| format!("{} uses {} ({})", w[0], w[1], uses[&w[0]][&w[1]]))
            .collect();
        panic!("an import circle in the plant:\n{}", links.join("\n"));
    }
}

#[test]
fn paths_are_read_as_the_compiler_reads_them() {
    // A list over several lines, as rustfmt writes a long one.
    let lines =
        lines_of("use super::{\n    dynamics::Pose,\n    model::{Mount, NY},\n};\nfn f() {}\n");
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert_eq!(lines[0].0, 1);
    assert_eq!(
        first_segments(&lines[0].1, "super::"),
        ["dynamics", "model"]
    );
    assert_eq!(lines[1], (5, "fn f() {}".to_string()));
    let line = "use super::super::{dynamics::{Frame, Vector}, model::MAX_DOF};";
    assert_eq!(
        first_segments(line, "super::super::"),
        ["dynamics", "model"]
    );
    assert!(first_segments(line, "super::").is_empty());
    assert_eq!(
        first_segments(
            "fn f(m: &super::super::model::PlantModel) {}",
            "super::super::"
        ),
        ["model"]
    );
    assert_eq!(
        first_segments("use crate::simulation::trace::TraceRow;", "crate::"),
        ["simulation"]
    );
    assert_eq!(
        first_segments("use super::{ContactMode, Plant};", "super::"),
        ["ContactMode", "Plant"]
    );
    let mut uses = Uses::new();
    uses.entry("a".into())
        .or_default()
        .insert("b".into(), "x".into());
    uses.entry("b".into())
        .or_default()
        .insert("a".into(), "y".into());
    assert_eq!(
        circle(&uses),
        Some(vec!["a".into(), "b".into(), "a".into()])
    );
    uses.get_mut("b").unwrap().clear();
    assert_eq!(circle(&uses), None);
}
