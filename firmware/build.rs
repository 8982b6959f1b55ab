//! Build script of the firmware:
//!
//! 1. puts the repository's root `memory.x` (the one memory layout of the
//!    STM32F405RG) on the linker's search path, where cortex-m-rt's `link.x`
//!    includes it;
//! 2. compiles in the reference tuning table: reads
//!    `../examples/vibro-driver.tuning.toml` and writes `OUT_DIR/tuning.rs` with
//!    `TUNING_ROWS: [(f32, f32, f32); N]`, rows of `(speed_rpm, right_offset_deg,
//!    left_offset_deg)` in the file's order, for `TuningTable::from_rows` at init.
//!
//! The tuning file is parsed by hand (no build-dependency): only `[[rows]]` tables
//! with the three keys `speed_rpm`, `right_offset_deg`, `left_offset_deg` set to
//! numbers, `#` comments and blank lines. Anything else fails the build with the
//! line number, so a file the firmware would misread never builds.

use std::env;
use std::fs;
use std::path::{Path, PathBuf};

/// The tuning table compiled into the firmware, relative to `firmware/`.
const TUNING_FILE: &str = "../examples/vibro-driver.tuning.toml";

fn main() {
    let manifest_dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));

    // memory.x: copy into OUT_DIR rather than pointing at the root: the search path
    // then holds nothing but memory.x, so no other file there can shadow a linker
    // script.
    let memory_x = manifest_dir.join("..").join("memory.x");
    fs::copy(&memory_x, out_dir.join("memory.x"))
        .unwrap_or_else(|e| panic!("cannot copy {}: {e}", memory_x.display()));
    println!("cargo:rustc-link-search={}", out_dir.display());

    // Tuning table: parse, then write as a Rust const.
    let tuning = manifest_dir.join(TUNING_FILE);
    let rows = parse_tuning(&tuning);
    let mut code = String::from(
        "/// Rows `(speed_rpm, right_offset_deg, left_offset_deg)` of the tuning table\n\
         /// compiled in by build.rs from `examples/vibro-driver.tuning.toml`.\n",
    );
    code.push_str(&format!(
        "pub const TUNING_ROWS: [(f32, f32, f32); {}] = [\n",
        rows.len()
    ));
    for (speed, right, left) in &rows {
        code.push_str(&format!("    ({speed:?}, {right:?}, {left:?}),\n"));
    }
    code.push_str("];\n");
    fs::write(out_dir.join("tuning.rs"), code).expect("cannot write tuning.rs");

    // Rebuild when the layout, the table or this script changes.
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed={}", tuning.display());
    println!("cargo:rerun-if-changed=build.rs");
}

/// The rows of the tuning file at `path`; panics (fails the build) naming the line
/// of anything it does not understand, or a row with a key missing.
fn parse_tuning(path: &Path) -> Vec<(f32, f32, f32)> {
    let text =
        fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    // One row as it is read: the three keys, each set at most once.
    let mut rows: Vec<[Option<f32>; 3]> = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let where_ = || format!("{}:{}", path.display(), n + 1);
        if line.is_empty() {
            continue;
        }
        if line == "[[rows]]" {
            rows.push([None; 3]);
            continue;
        }
        let (key, value) = line
            .split_once('=')
            .unwrap_or_else(|| panic!("{}: expected `key = number`", where_()));
        let slot = match key.trim() {
            "speed_rpm" => 0,
            "right_offset_deg" => 1,
            "left_offset_deg" => 2,
            other => panic!("{}: unknown key `{other}`", where_()),
        };
        let value: f32 = value
            .trim()
            .parse()
            .unwrap_or_else(|e| panic!("{}: not a number: {e}", where_()));
        let row = rows
            .last_mut()
            .unwrap_or_else(|| panic!("{}: key outside a [[rows]] table", where_()));
        if row[slot].replace(value).is_some() {
            panic!("{}: key set twice in one row", where_());
        }
    }
    rows.iter()
        .enumerate()
        .map(|(i, r)| match r {
            [Some(s), Some(a), Some(b)] => (*s, *a, *b),
            _ => panic!("{}: row {i} lacks a key", path.display()),
        })
        .collect()
}
