//! The measured travel file of `host-sim calibrate`: one row per run on the real
//! machine (spec `machine.md`, "Additions"; docs/calibration.md).
//!
//! ```text
//! speed_rpm,offset_deg,velocity_mps,weight
//! 3000,0,0.0012,1
//! 3000,90,0.0301,1
//! 3000,90,0.0297,1
//! ```
//!
//! - the first line that is not blank nor a `#` comment is the header: the columns
//!   `speed_rpm`, `offset_deg`, `velocity_mps` and optionally `weight`, each once,
//!   in any order, nothing else;
//! - every other line (blank lines and `#` comments skipped) is one run: finite
//!   numbers; the speed, rpm, within the controller's speed range; the offset,
//!   degrees, any value (wrapped to [0, 360)); the mean travel velocity, m/s
//!   (positive rightward); the weight, > 0, 1 when the column is absent;
//! - repeated rows (the same speed and offset) are separate measurements.
//!
//! Every problem at once, one line each, naming the file, the line and the column.

use std::path::Path;

use crate::machine::input;
use crate::output::text;
use crate::simulation::summary::wrap_deg_360;

/// The columns every file has, in the written order.
pub const COLUMNS: [&str; 3] = ["speed_rpm", "offset_deg", "velocity_mps"];
/// The optional column.
pub const WEIGHT: &str = "weight";

/// One measured run.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Line number in the file, from 1 (for messages and the report).
    pub line: usize,
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset held, degrees in [0, 360).
    pub offset_deg: f64,
    /// Measured mean travel velocity, m/s (positive rightward).
    pub velocity_mps: f64,
    /// Weight of the row in the fit (> 0; 1 without the column): its variance is
    /// taken as `sigma^2 / weight`.
    pub weight: f64,
}

/// Reads and checks the file at `path`; `speed_range` is the controller's
/// `[min_speed_rpm, max_speed_rpm]`.
pub fn read(path: &Path, speed_range: (f64, f64)) -> Result<Vec<Row>, String> {
    let text = input::read_text(path).map_err(|p| input::render(&[p]))?;
    parse(&path.display().to_string(), &text, speed_range)
}

/// [`read`] from the text of a file named `file`.
pub fn parse(file: &str, text: &str, speed_range: (f64, f64)) -> Result<Vec<Row>, String> {
    let mut problems = Vec::new();
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));

    // The header: which column holds what.
    let Some((header_line, header)) = lines.next() else {
        return Err(format!(
            "error: {file}: no header: expected the line `{},{WEIGHT}` (weight optional), then one row per run\n",
            COLUMNS.join(",")
        ));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut at = [None; 4];
    for (i, name) in names.iter().enumerate() {
        let slot = COLUMNS
            .iter()
            .chain(std::iter::once(&WEIGHT))
            .position(|c| c == name);
        match slot {
            Some(k) if at[k].is_none() => at[k] = Some(i),
            Some(_) => problems.push(format!(
                "error: {file}:{header_line}: header: column `{name}` twice"
            )),
            None => problems.push(format!(
                "error: {file}:{header_line}: header: unknown column `{name}` (allowed: {}, {WEIGHT})",
                COLUMNS.join(", ")
            )),
        }
    }
    for (k, c) in COLUMNS.iter().enumerate() {
        if at[k].is_none() {
            problems.push(format!(
                "error: {file}:{header_line}: header: missing column `{c}` (expected {},{WEIGHT}; weight optional)",
                COLUMNS.join(",")
            ));
        }
    }
    if !problems.is_empty() {
        return Err(problems.join("\n") + "\n");
    }

    // The rows.
    let (lo, hi) = speed_range;
    let mut rows = Vec::new();
    for (line, l) in lines {
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            problems.push(format!(
                "error: {file}:{line}: {} fields, the header has {}",
                cells.len(),
                names.len()
            ));
            continue;
        }
        let mut value = |k: usize, name: &str| -> Option<f64> {
            let cell = cells[at[k]?];
            match cell.parse::<f64>() {
                Ok(x) if x.is_finite() => Some(x),
                _ => {
                    problems.push(format!(
                        "error: {file}:{line}: {name}: must be a finite number (got {cell:?})"
                    ));
                    None
                }
            }
        };
        let speed = value(0, COLUMNS[0]);
        let offset = value(1, COLUMNS[1]);
        let velocity = value(2, COLUMNS[2]);
        let weight = if at[3].is_some() {
            value(3, WEIGHT)
        } else {
            Some(1.0)
        };
        let speed = speed.filter(|s| {
            let ok = *s >= lo && *s <= hi;
            if !ok {
                problems.push(format!(
                    "error: {file}:{line}: speed_rpm: {} is outside the controller's speed range [{}, {}] rpm",
                    text::sig(*s),
                    text::sig(lo),
                    text::sig(hi)
                ));
            }
            ok
        });
        let weight = weight.filter(|w| {
            if *w <= 0.0 {
                problems.push(format!(
                    "error: {file}:{line}: weight: must be > 0 (got {})",
                    text::sig(*w)
                ));
            }
            *w > 0.0
        });
        if let (Some(speed_rpm), Some(offset), Some(velocity_mps), Some(weight)) =
            (speed, offset, velocity, weight)
        {
            rows.push(Row {
                line,
                speed_rpm,
                offset_deg: wrap_deg_360(offset) + 0.0,
                velocity_mps,
                weight,
            });
        }
    }
    if rows.is_empty() && problems.is_empty() {
        problems.push(format!(
            "error: {file}: no rows after the header: one row per measured run"
        ));
    }
    if problems.is_empty() {
        Ok(rows)
    } else {
        Err(problems.join("\n") + "\n")
    }
}

/// The distinct points `(speed, offset)` of `rows` in the order first met, and
/// for each row the index of its point: the runs one evaluation needs.
pub fn points(rows: &[Row]) -> (Vec<(f64, f64)>, Vec<usize>) {
    let mut points: Vec<(f64, f64)> = Vec::new();
    let mut of_row = Vec::new();
    for r in rows {
        let key = (r.speed_rpm, r.offset_deg);
        let i = match points.iter().position(|p| *p == key) {
            Some(i) => i,
            None => {
                points.push(key);
                points.len() - 1
            }
        };
        of_row.push(i);
    }
    (points, of_row)
}

#[cfg(test)]
mod tests {
    use super::*;

    const RANGE: (f64, f64) = (500.0, 4500.0);

    fn err(text: &str) -> String {
        parse("m.csv", text, RANGE).unwrap_err()
    }

    #[test]
    fn rows_read_with_and_without_weights() {
        let rows = parse(
            "m.csv",
            "# measured\nspeed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n\n3000,-90,-0.03\n",
            RANGE,
        )
        .unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1].line, 5);
        assert_eq!(rows[1].offset_deg, 270.0);
        assert_eq!(rows[0].weight, 1.0);
        let rows = parse(
            "m.csv",
            "weight, velocity_mps,offset_deg,speed_rpm\n2,0.03,360,3000\n",
            RANGE,
        )
        .unwrap();
        assert_eq!(
            rows[0],
            Row {
                line: 2,
                speed_rpm: 3000.0,
                offset_deg: 0.0,
                velocity_mps: 0.03,
                weight: 2.0
            }
        );
    }

    #[test]
    fn every_problem_with_its_line_and_column() {
        assert_eq!(
            err("speed_rpm,offset,velocity_mps\n"),
            "error: m.csv:1: header: unknown column `offset` (allowed: speed_rpm, offset_deg, velocity_mps, weight)\n\
             error: m.csv:1: header: missing column `offset_deg` (expected speed_rpm,offset_deg,velocity_mps,weight; weight optional)\n"
        );
        assert!(err("speed_rpm,offset_deg,velocity_mps,speed_rpm\n")
            .contains("column `speed_rpm` twice"));
        assert!(err("").contains("error: m.csv: no header"));
        assert!(err("speed_rpm,offset_deg,velocity_mps\n").contains("no rows after the header"));
        let e = err(
            "speed_rpm,offset_deg,velocity_mps,weight\n3000,90,fast,1\n3000,90,0.03,-1\n9000,90,0.03,1\n3000,90\n3000,nan,0.1,1\n",
        );
        assert_eq!(
            e,
            "error: m.csv:2: velocity_mps: must be a finite number (got \"fast\")\n\
             error: m.csv:3: weight: must be > 0 (got -1)\n\
             error: m.csv:4: speed_rpm: 9000 is outside the controller's speed range [500, 4500] rpm\n\
             error: m.csv:5: 2 fields, the header has 4\n\
             error: m.csv:6: offset_deg: must be a finite number (got \"nan\")\n"
        );
    }

    #[test]
    fn repeated_rows_share_one_point() {
        let rows = parse(
            "m.csv",
            "speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n3000,0,0.01\n3000,450,0.031\n",
            RANGE,
        )
        .unwrap();
        let (points, of_row) = points(&rows);
        assert_eq!(points, vec![(3000.0, 90.0), (3000.0, 0.0)]);
        assert_eq!(of_row, vec![0, 1, 0]);
    }
}
