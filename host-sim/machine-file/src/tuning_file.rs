//! The tuning table file: rotor speed -> best phase offset for rightward and for
//! leftward travel, as `host-sim tune --write` stores it, a machine file's
//! `[controller].tuning_table` names it, and the firmware compiles it in.
//!
//! ```toml
//! # written by host-sim tune
//! [[rows]]
//! speed_rpm = 3000.0        # rotor speed, rpm, ascending
//! right_offset_deg = 95.0   # phase offset for rightward travel, degrees [0, 360)
//! left_offset_deg = 265.0   # phase offset for leftward travel, degrees [0, 360)
//! ```
//!
//! The controller interpolates linearly in speed and circularly in offset
//! (`shared::controller::TuningTable`); outside the table's speeds it holds the
//! nearest row.
//!
//! Reading a table (see [`parse`]):
//! 1. the TOML, and every `[[rows]]` table's three keys, each a finite number;
//! 2. each value by the controller's rule for it (`RowField::check`: speed > 0,
//!    offsets in [0, 360)), on the `f32` the controller gets, reported at its key;
//! 3. the table as a whole by the controller's own `TuningTable::from_rows`: 1 to
//!    `MAX_TUNING_ROWS` rows, speeds strictly ascending.
//!
//! So a file reads if and only if the controller takes its rows: host-sim, the
//! firmware's build and a board's link apply one rule.

use std::path::Path;

use shared::controller::{RowField, TableError, TuningTable, MAX_TUNING_ROWS};

use crate::input::{self, number, Need, Problem, Problems};
use crate::kind::{self, FileKind};

/// One row: speed, rpm; right and left offsets, degrees.
pub type Row = (f64, f64, f64);

/// Reads and checks a tuning table file: every problem with its key.
pub fn read(path: &Path) -> Result<Vec<Row>, Vec<Problem>> {
    let file = path.display().to_string();
    let text = input::read_text(path).map_err(|p| vec![p])?;
    parse(&file, &text)
}

/// Reads and checks a tuning table file into the controller's table.
pub fn read_table(path: &Path) -> Result<TuningTable, Vec<Problem>> {
    let rows = read(path)?;
    // The rows `read` accepts are the rows the controller takes: its rule made them.
    table(&rows).map_err(|e| {
        let problems = Problems::new(path.display().to_string());
        report(&problems, e);
        problems.into_vec()
    })
}

/// Parses the text of a tuning table file named `file` (the stages of the module
/// documentation).
pub fn parse(file: &str, text: &str) -> Result<Vec<Row>, Vec<Problem>> {
    // Stage 1: the TOML and the keys.
    let toml = input::parse(file, text).map_err(|p| vec![p])?;
    if let Some(p) = kind::wrong_kind(file, &toml, FileKind::TuningTable) {
        return Err(vec![p]);
    }
    let problems = Problems::new(file);
    let root = input::Section::root(&toml, &problems);
    let mut rows = Vec::new();
    let sections = root.sections("rows").unwrap_or_default();
    for (i, row) in sections.into_iter().enumerate() {
        let Some(row) = row else { continue }; // not a table, reported
                                               // Stage 2: each value by the controller's rule.
        let values = RowField::ALL.map(|field| {
            let what = format!("a number {}", field.requirement());
            row.number_by(field.key(), Need::Required, &what, |x| {
                value_rule(i, field, x)
            })
        });
        row.finish();
        if let [Some(s), Some(r), Some(l)] = values {
            rows.push((s, r, l));
        }
    }
    root.finish();
    // Stage 3: the table as a whole, once every row reads.
    if problems.is_empty() {
        if let Err(e) = table(&rows) {
            report(&problems, e);
        }
    }
    problems.into_result(Some(rows))
}

/// The controller's rule for value `field` of row `row`, on the `f32` it gets:
/// `Err` says what the value must be (and what `f32` made of it, when that is
/// what fails).
fn value_rule(row: usize, field: RowField, x: f64) -> Result<(), String> {
    let single = x as f32;
    match field.check(row, single) {
        None => Ok(()),
        Some(e) if f64::from(single) == x => Err(e.requirement().to_string()),
        Some(e) => Err(format!(
            "{} as the controller's f32, which makes it {}",
            e.requirement(),
            number(f64::from(single))
        )),
    }
}

/// A problem of the table as a whole (a value's problems are reported with it).
fn report(problems: &Problems, e: TableError) {
    match e {
        TableError::Empty => problems.at(
            "rows",
            "needs at least one [[rows]] table (speed_rpm, right_offset_deg, left_offset_deg)",
        ),
        TableError::SpeedsNotIncreasing { .. } => {
            problems.at("rows", "speeds must be strictly ascending")
        }
        TableError::TooManyRows { rows, capacity } => problems.at(
            "rows",
            format!("at most {capacity} rows fit the controller's table (got {rows})"),
        ),
        TableError::NotFinite { row, field } | TableError::OffsetOutOfRange { row, field } => {
            problems.at(
                &format!("rows[{row}].{}", field.key()),
                format!("must be {}", e.requirement()),
            )
        }
        TableError::SpeedNotPositive { row } => problems.at(
            &format!("rows[{row}].{}", RowField::Speed.key()),
            format!("must be {}", e.requirement()),
        ),
    }
}

/// The controller's table of `rows` (as `f32`), or why it refuses them: always a
/// table for rows [`parse`] accepts.
pub fn table(rows: &[Row]) -> Result<TuningTable, TableError> {
    let rows: Vec<(f32, f32, f32)> = rows
        .iter()
        .map(|&(s, r, l)| (s as f32, r as f32, l as f32))
        .collect();
    TuningTable::<MAX_TUNING_ROWS>::from_rows(&rows)
}

/// The file text for `rows`, with a header comment. Values are written with one
/// decimal; an offset that rounds up to 360.0 is written as 0.0, the same offset
/// inside [0, 360).
pub fn write(rows: &[Row], header: &str) -> String {
    let offset = |o: f64| match format!("{o:.1}") {
        full_turn if full_turn == "360.0" => "0.0".to_string(),
        text => text,
    };
    let mut out = String::new();
    for line in header.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    for (s, r, l) in rows {
        out.push_str(&format!(
            "\n[[rows]]\nspeed_rpm = {s:.1}\nright_offset_deg = {}\nleft_offset_deg = {}\n",
            offset(*r),
            offset(*l)
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table file of one row.
    fn one_row(speed: &str, right: &str, left: &str) -> String {
        format!(
            "[[rows]]\nspeed_rpm = {speed}\nright_offset_deg = {right}\nleft_offset_deg = {left}\n"
        )
    }

    /// The problems of `text`, one line each.
    fn problems(text: &str) -> String {
        input::render(&parse("t.toml", text).unwrap_err())
    }

    #[test]
    fn round_trip() {
        let rows = vec![(2500.0, 95.0, 265.0), (3000.0, 100.5, 259.5)];
        let text = write(&rows, "test");
        assert_eq!(parse("t.toml", &text).unwrap(), rows);
        assert!(table(&rows).is_ok());
    }

    #[test]
    fn an_offset_that_rounds_to_a_full_turn_is_written_as_zero() {
        let rows = [(3000.0, 359.96, 0.04)];
        let text = write(&rows, "test");
        assert!(
            text.contains("right_offset_deg = 0.0\nleft_offset_deg = 0.0\n"),
            "{text}"
        );
        assert_eq!(parse("t.toml", &text).unwrap(), [(3000.0, 0.0, 0.0)]);
    }

    #[test]
    fn bad_tables_name_the_key() {
        assert_eq!(
            problems(&one_row("3000", "400", "10")),
            "error: t.toml: rows[0].right_offset_deg: must be in [0, 360) (got 400)\n"
        );
        let e = problems(
            "[[rows]]\nspeed_rpm = 3000\nright_offset_deg = 90\nleft_offset_deg = 270\n[[rows]]\nspeed_rpm = 2000\nright_offset_deg = 90\nleft_offset_deg = 270\n",
        );
        assert_eq!(
            e,
            "error: t.toml: rows: speeds must be strictly ascending\n"
        );
        assert!(!problems("rows = 3").is_empty());
        assert_eq!(
            problems("[[rows]]\nspeed_rpm = 3000\n"),
            "error: t.toml: rows[0].right_offset_deg: missing; required: a number in [0, 360)\n\
             error: t.toml: rows[0].left_offset_deg: missing; required: a number in [0, 360)\n"
        );
    }

    #[test]
    fn the_ends_of_the_ranges_are_the_controllers() {
        // A speed of 0 and an offset of 360 are refused, each at its key.
        assert_eq!(
            problems(&one_row("0", "360", "-1")),
            "error: t.toml: rows[0].speed_rpm: must be > 0 (got 0)\n\
             error: t.toml: rows[0].right_offset_deg: must be in [0, 360) (got 360)\n\
             error: t.toml: rows[0].left_offset_deg: must be in [0, 360) (got -1)\n"
        );
        // The controller's f32 decides: just below 360 in f64 is 360 in f32, and two
        // speeds apart in f64 may be one in f32.
        assert_eq!(
            problems(&one_row("3000", "359.99999999", "0")),
            "error: t.toml: rows[0].right_offset_deg: must be in [0, 360) as the controller's \
             f32, which makes it 360 (got 359.99999999)\n"
        );
        assert_eq!(
            problems(&one_row("1e300", "0", "0")),
            "error: t.toml: rows[0].speed_rpm: must be a finite number as the controller's \
             f32, which makes it inf (got 1e300)\n"
        );
        let close = format!(
            "{}{}",
            one_row("3000", "0", "0"),
            one_row("3000.00001", "0", "0")
        );
        assert_eq!(
            problems(&close),
            "error: t.toml: rows: speeds must be strictly ascending\n"
        );
        // 0 degrees and a tiny speed pass.
        assert!(parse("t.toml", &one_row("1e-3", "0", "359.9")).is_ok());
    }

    #[test]
    fn too_many_rows() {
        let text: String = (1..=MAX_TUNING_ROWS + 1)
            .map(|k| one_row(&format!("{}", 100 * k), "90", "270"))
            .collect();
        assert_eq!(
            problems(&text),
            "error: t.toml: rows: at most 32 rows fit the controller's table (got 33)\n"
        );
    }
}
