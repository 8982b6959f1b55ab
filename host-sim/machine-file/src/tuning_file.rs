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

use std::path::Path;

use shared::controller::{TuningTable, MAX_TUNING_ROWS};

use crate::input::{self, Limit, Need, Problem};

/// One row: speed, rpm; right and left offsets, degrees.
pub type Row = (f64, f64, f64);

/// Reads and checks a tuning table file: every problem with its key.
pub fn read(path: &Path) -> Result<Vec<Row>, Vec<Problem>> {
    let file = path.display().to_string();
    let text = input::read_text(path).map_err(|p| vec![p])?;
    parse(&file, &text)
}

/// Parses the text of a tuning table file named `file`.
pub fn parse(file: &str, text: &str) -> Result<Vec<Row>, Vec<Problem>> {
    let table = input::parse(file, text).map_err(|p| vec![p])?;
    let problems = input::Problems::new(file);
    let root = input::Section::root(&table, &problems);
    let mut rows = Vec::new();
    for row in root
        .sections("rows")
        .unwrap_or_default()
        .into_iter()
        .flatten()
    {
        let speed = row.number("speed_rpm", Need::Required, Limit::Positive);
        let right = row.number(
            "right_offset_deg",
            Need::Required,
            Limit::Between(0.0, 360.0),
        );
        let left = row.number(
            "left_offset_deg",
            Need::Required,
            Limit::Between(0.0, 360.0),
        );
        row.finish();
        if let (Some(s), Some(r), Some(l)) = (speed, right, left) {
            rows.push((s, r, l));
        }
    }
    root.finish();
    if rows.is_empty() && problems.is_empty() {
        problems.at(
            "rows",
            "needs at least one [[rows]] table (speed_rpm, right_offset_deg, left_offset_deg)",
        );
    }
    if rows.windows(2).any(|w| w[1].0 <= w[0].0) {
        problems.at("rows", "speeds must be strictly ascending");
    }
    if rows.len() > MAX_TUNING_ROWS {
        problems.at(
            "rows",
            format!(
                "at most {MAX_TUNING_ROWS} rows fit the controller's table (got {})",
                rows.len()
            ),
        );
    }
    problems.into_result(Some(rows))
}

/// The controller's table from checked rows.
pub fn table(rows: &[Row]) -> Option<TuningTable> {
    let rows: Vec<(f32, f32, f32)> = rows
        .iter()
        .map(|&(s, r, l)| (s as f32, r as f32, l as f32))
        .collect();
    TuningTable::from_rows(&rows).ok()
}

/// The file text for `rows`, with a header comment.
pub fn write(rows: &[Row], header: &str) -> String {
    let mut out = String::new();
    for line in header.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    for (s, r, l) in rows {
        out.push_str(&format!(
            "\n[[rows]]\nspeed_rpm = {s:.1}\nright_offset_deg = {r:.1}\nleft_offset_deg = {l:.1}\n"
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let rows = vec![(2500.0, 95.0, 265.0), (3000.0, 100.5, 259.5)];
        let text = write(&rows, "test");
        assert_eq!(parse("t.toml", &text).unwrap(), rows);
        assert!(table(&rows).is_some());
    }

    #[test]
    fn bad_tables_name_the_key() {
        let e = parse(
            "t.toml",
            "[[rows]]\nspeed_rpm = 3000\nright_offset_deg = 400\nleft_offset_deg = 10\n",
        )
        .unwrap_err();
        assert!(
            e[0].to_string().contains("rows[0].right_offset_deg"),
            "{}",
            e[0]
        );
        let e = parse(
            "t.toml",
            "[[rows]]\nspeed_rpm = 3000\nright_offset_deg = 90\nleft_offset_deg = 270\n[[rows]]\nspeed_rpm = 2000\nright_offset_deg = 90\nleft_offset_deg = 270\n",
        )
        .unwrap_err();
        assert!(e[0].to_string().contains("ascending"), "{}", e[0]);
        let e = parse("t.toml", "rows = 3").unwrap_err();
        assert!(!e.is_empty());
    }
}
