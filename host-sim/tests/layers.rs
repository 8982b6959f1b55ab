//! host-sim's imports point one way (docs/development.md, "The layers"), read
//! from its source text:
//!
//! - every module of `host-sim/src` uses only modules on lower lines of the
//!   layers' picture in docs/development.md, and the picture names exactly the
//!   tree's modules;
//! - every crate of the project names in its `Cargo.toml` only the project's
//!   crates the crates' picture there allows;
//! - the plant uses no part of host-sim above it: below `plant/` there is only the
//!   machine file's crate (`crate::machine`) and the events' plain rows
//!   (`crate::event`), and `event.rs` uses nothing of the crate;
//! - the plant's modules (`model`, `contact`, `dynamics`, `simulator` with its own
//!   files, ...) form no circle: a module that uses a sibling never is used by it,
//!   through any chain. A module's own folder (`simulator/`, the parts of one
//!   `impl Plant`) counts as the module.
//!
//! Paths are found wherever they are written (`use` lines and paths inside the
//! code), except in comments, in a file's `#[cfg(test)]` module at its end and in
//! the test files `tests.rs` beside a module's code; a single `#[cfg(test)]` item
//! inside the code (a method of an `impl`) does not end the reading.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// `host-sim/src`.
fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The `text` blocks of docs/development.md's section "The layers": the crates'
/// picture, then the modules' (the block after the marker comment).
fn layer_pictures() -> (String, String) {
    let doc = fs::read_to_string(root().join("docs/development.md")).unwrap();
    let section = doc
        .split("### The layers")
        .nth(1)
        .expect("docs/development.md has the section \"The layers\"");
    let blocks: Vec<&str> = section
        .split("```text\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .collect();
    assert!(blocks.len() >= 2, "two pictures in \"The layers\"");
    (blocks[0].to_string(), blocks[1].to_string())
}

/// The modules' picture as module -> layer (1 the ground).
fn module_layers(picture: &str) -> BTreeMap<String, u32> {
    let mut layers = BTreeMap::new();
    for line in picture.lines().filter(|l| !l.trim().is_empty()) {
        let mut words = line.split_whitespace();
        let layer: u32 = words
            .next()
            .and_then(|w| w.parse().ok())
            .unwrap_or_else(|| panic!("a layer's line starts with its number: {line:?}"));
        for m in words {
            assert!(
                layers.insert(m.to_string(), layer).is_none(),
                "{m} twice in the picture"
            );
        }
    }
    layers
}

/// host-sim's top-level modules: each `src/NAME.rs` and `src/NAME/` but
/// `lib.rs` and `main.rs`, and `machine` (the machine-file crate under
/// host-sim's name).
fn top_modules() -> BTreeSet<String> {
    let mut modules: BTreeSet<String> = fs::read_dir(src())
        .unwrap()
        .filter_map(|e| {
            let path = e.unwrap().path();
            let name = path.file_stem()?.to_str()?.to_string();
            let rust = path.is_dir() || path.extension().is_some_and(|x| x == "rs");
            (rust && name != "lib" && name != "main").then_some(name)
        })
        .collect();
    modules.insert("machine".to_string());
    modules
}

/// Every source file of module `m` (its file, or every file under its folder).
fn files_of(m: &str) -> Vec<PathBuf> {
    let file = src().join(format!("{m}.rs"));
    if file.is_file() {
        return vec![file];
    }
    let mut files = Vec::new();
    let mut folders = vec![src().join(m)];
    while let Some(folder) = folders.pop() {
        for e in fs::read_dir(&folder).into_iter().flatten() {
            let path = e.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|x| x == "rs")
                && path.file_name().is_some_and(|n| n != "tests.rs")
            {
                files.push(path);
            }
        }
    }
    files.sort();
    files
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
    let all: Vec<&str> = text.lines().collect();
    for (i, line) in all.iter().enumerate() {
        let t = line.trim_start();
        // The test module at a file's end stops the reading; a single test-only
        // item (a method inside an `impl`) is read as code.
        if t.starts_with("#[cfg(test)]") {
            let next = all[i + 1..]
                .iter()
                .map(|l| l.trim_start())
                .find(|l| !l.is_empty());
            if next.is_some_and(|l| l.split_whitespace().any(|w| w == "mod")) {
                break;
            }
            continue;
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
fn the_modules_use_only_the_layers_below_them() {
    let layers = module_layers(&layer_pictures().1);
    let tree = top_modules();
    let pictured: BTreeSet<String> = layers.keys().cloned().collect();
    assert_eq!(
        pictured, tree,
        "the layers' picture in docs/development.md names exactly the modules of host-sim/src"
    );
    // The test sees what it must: the commands use the simulation.
    let mut wrong = Vec::new();
    let mut seen = 0;
    for (m, &layer) in &layers {
        for file in files_of(m) {
            for (n, line) in code(&file) {
                for used in first_segments(&line, "crate::") {
                    let Some(&below) = layers.get(&used) else {
                        continue;
                    };
                    if used == *m {
                        continue;
                    }
                    seen += 1;
                    if below >= layer {
                        wrong.push(format!(
                            "{}:{n}: {m} (layer {layer}) uses {used} (layer {below})",
                            shown(&file)
                        ));
                    }
                }
            }
        }
    }
    assert!(seen > 100, "only {seen} paths read");
    assert!(
        wrong.is_empty(),
        "a module uses one on its own layer or above (docs/development.md, \"The layers\"):\n{}",
        wrong.join("\n")
    );
}

/// The utilities every layer above them may take, which the modules' table leaves out of its
/// column "uses".
const UTILITIES: [&str; 5] = ["args", "help", "interrupt", "numbers", "failure"];

/// What each module imports of host-sim's other modules, from its code.
fn module_uses(modules: &BTreeSet<String>) -> BTreeMap<String, BTreeSet<String>> {
    let mut uses = BTreeMap::new();
    for m in modules {
        let used: &mut BTreeSet<String> = uses.entry(m.clone()).or_default();
        for file in files_of(m) {
            for (_, line) in code(&file) {
                used.extend(
                    first_segments(&line, "crate::")
                        .into_iter()
                        .filter(|u| u != m && modules.contains(u)),
                );
            }
        }
    }
    uses
}

#[test]
fn the_modules_table_says_what_each_module_uses() {
    let doc = fs::read_to_string(root().join("docs/development.md")).unwrap();
    let table = doc
        .split("### The modules")
        .nth(1)
        .expect("docs/development.md has the section \"The modules\"");
    let modules = top_modules();
    let uses = module_uses(&modules);
    let mut wrong = Vec::new();
    let mut rows = 0;
    for row in table.lines().filter(|l| l.starts_with("| `")) {
        let name: String = row[3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if !modules.contains(&name) {
            continue;
        }
        rows += 1;
        let last = row.trim_end_matches('|').rsplit(" | ").next().unwrap_or("");
        let said: BTreeSet<String> = last
            .split('`')
            .skip(1)
            .step_by(2)
            .filter(|w| modules.contains(*w))
            .map(str::to_string)
            .collect();
        let code: BTreeSet<String> = uses[&name]
            .iter()
            .filter(|u| !UTILITIES.contains(&u.as_str()))
            .cloned()
            .collect();
        // `cli` dispatches to every command: its row says so in words.
        if name != "cli" && said != code {
            wrong.push(format!(
                "{name}: the table says {said:?}, the code uses {code:?}"
            ));
        }
    }
    assert_eq!(
        rows,
        modules.len(),
        "a row for every module of host-sim/src"
    );
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn the_crates_use_only_what_the_picture_allows() {
    let crates = ["firmware", "tests", "host-sim", "machine-file", "shared"];
    let manifest = |c: &str| match c {
        "machine-file" => root().join("host-sim/machine-file/Cargo.toml"),
        _ => root().join(c).join("Cargo.toml"),
    };
    let mut allowed: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    let picture = layer_pictures().0;
    for line in picture.lines().filter(|l| l.contains("->")) {
        let (user, uses) = line.split_once("->").unwrap();
        let user = crates
            .into_iter()
            .find(|c| user.split_whitespace().next() == Some(*c))
            .unwrap_or_else(|| panic!("a crate's line starts with its name: {line:?}"));
        let named = uses
            .split(|c: char| c.is_whitespace() || c == ',' || c == '(' || c == ')')
            .filter_map(|w| crates.into_iter().find(|c| *c == w));
        allowed.entry(user).or_default().extend(named);
    }
    assert_eq!(
        allowed.len(),
        crates.len(),
        "every crate in the picture: {allowed:?}"
    );
    let mut wrong = Vec::new();
    for c in crates {
        let text = fs::read_to_string(manifest(c)).unwrap();
        for line in text.lines() {
            let name = line.split('=').next().unwrap_or("").trim();
            if line.contains("path =") && crates.contains(&name) && !allowed[c].contains(name) {
                wrong.push(format!("{c} names {name}"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "a crate uses one the picture in docs/development.md does not allow:\n{}",
        wrong.join("\n")
    );
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
    // A test-only method is skipped over; the test module ends the reading.
    let lines = lines_of(
        "impl A {\n    #[cfg(test)]\n    fn t() {}\n    fn g() { crate::x::y(); }\n}\n#[cfg(test)]\nmod tests {\n    use crate::z;\n}\n",
    );
    assert!(
        lines.iter().any(|(_, l)| l.contains("crate::x")),
        "{lines:?}"
    );
    assert!(
        !lines.iter().any(|(_, l)| l.contains("crate::z")),
        "{lines:?}"
    );
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
