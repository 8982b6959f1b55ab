//! The measured travel file: one row per run on the real machine
//! (docs/calibration.md, "The measured travel file").
//! `host-sim device tune` writes it ([`crate::device::measured`] appends to it),
//! `host-sim calibrate` reads it; both with this one reader.
//!
//! ```text
//! # measured on the bench, 2 May
//! speed_rpm,offset_deg,velocity_mps,weight
//! 3000,0,0.0012,1
//! 3000,90,0.0301,1
//! 3000,90,0.0297,1
//! ```
//!
//! - a leading byte order mark (a spreadsheet's UTF-8 CSV) is skipped;
//! - the first line that is not blank nor a `#` comment is the header: the columns
//!   `speed_rpm`, `offset_deg`, `velocity_mps` and optionally `weight`, each once,
//!   in any order, nothing else;
//! - every other line (blank lines and `#` comments skipped) is one run: the
//!   header's number of fields, each a finite number within its bound: the speed,
//!   rpm, within the controller's speed range when the reader is given it, else
//!   in (0, [`MAX_SPEED_RPM`]]; the offset, degrees, within one turn either way
//!   ([`MAX_OFFSET_DEG`], wrapped to [0, 360)); the mean travel velocity, m/s
//!   (positive rightward), within [`MAX_VELOCITY_MPS`] either way; the weight in
//!   [[`MIN_WEIGHT`], [`MAX_WEIGHT`]], 1 when the column is absent;
//! - repeated rows (the same speed and offset) are separate measurements;
//! - a file may have no rows yet (a sweep started and stopped before its first
//!   answer).
//!
//! Every problem at once, each said as one line, `error: FILE: line N: COLUMN:
//! what is wrong (got ...)`; past [`MAX_PROBLEMS`] the rest are counted, and a field
//! quoted is cut past [`MAX_QUOTED`] bytes. A file over [`MAX_BYTES`] is refused
//! unread ([`read_each`], which gives the rows one by one and keeps none).

use std::path::Path;

use crate::failure::{Failure, Kind};
use crate::machine::input::{self, Problem, MAX_QUOTED};
use crate::numbers;
use crate::numbers::decimals;
use crate::simulation::trace::MAX_VELOCITY_MPS;
use shared::controller::angle::{wrap_deg_f64, wrap_deg_signed_f64};

/// The columns every file has, in the order a new file is written.
pub const COLUMNS: [&str; 3] = ["speed_rpm", "offset_deg", "velocity_mps"];
/// The optional column.
pub const WEIGHT: &str = "weight";

/// Every column, the optional one last: a [`Header`] holds indices into this.
const ALL: [&str; 4] = [COLUMNS[0], COLUMNS[1], COLUMNS[2], WEIGHT];

/// Two speeds (rpm) or offsets (degrees) closer than this are the same point.
pub const SAME_POINT: f64 = 1e-6;

/// Highest speed of a row when the reader has no controller to ask, rpm: 1000
/// turns a second, ten times the no-load speed of the small DC motors that
/// drive unbalance rotors (the reference machine's 12 V motor: 5730 rpm). A
/// larger number is another column's or another unit's, and as an `f32` on the
/// link it could be infinite.
pub const MAX_SPEED_RPM: f64 = 60_000.0;

/// Largest offset of a row either way, degrees: one turn. An offset is an angle
/// between two rotors; a number beyond a turn is another column's (a speed of
/// 3000 in the offset column would wrap to 120 deg unnoticed).
pub const MAX_OFFSET_DEG: f64 = 360.0;

/// Smallest and largest weight of a row. Weights are relative (the weighted
/// mean and the fit's estimates do not change when every weight is multiplied
/// by one number), so a file can always be scaled into these; a ratio of up to
/// 1e12 between rows keeps every weighted sum far from overflow.
pub const MIN_WEIGHT: f64 = 1e-6;
/// See [`MIN_WEIGHT`].
pub const MAX_WEIGHT: f64 = 1e6;

/// Why the value `v` of column `k` (an index into `speed_rpm, offset_deg,
/// velocity_mps, weight`) is refused: what is allowed. `speed_range` as for
/// [`parse`].
fn refusal(k: usize, v: f64, speed_range: Option<(f64, f64)>) -> Option<String> {
    let within = |lo: f64, hi: f64, unit: &str| {
        (!(lo..=hi).contains(&v))
            .then(|| format!("within [{}, {}]{unit}", numbers::sig(lo), numbers::sig(hi)))
    };
    match (k, speed_range) {
        (0, Some((lo, hi))) if !(v > 0.0 && v >= lo && v <= hi) => Some(format!(
            "within the controller's speed range [{}, {}] rpm",
            numbers::sig(lo),
            numbers::sig(hi)
        )),
        (0, Some(_)) => None,
        (0, None) => (!(v > 0.0 && v <= MAX_SPEED_RPM))
            .then(|| format!("> 0 and at most {} rpm", numbers::sig(MAX_SPEED_RPM))),
        (1, _) => within(
            -MAX_OFFSET_DEG,
            MAX_OFFSET_DEG,
            " degrees (one turn either way)",
        ),
        (2, _) => within(-MAX_VELOCITY_MPS, MAX_VELOCITY_MPS, " m/s"),
        _ => within(
            MIN_WEIGHT,
            MAX_WEIGHT,
            " (weights are relative: scale them)",
        ),
    }
}

/// Why the velocity `v`, m/s, cannot be a row of a measured file, if it cannot
/// (the bound of [`parse`]): for the rows `device tune` appends.
pub fn velocity_refusal(v: f64) -> Option<String> {
    if !v.is_finite() {
        return Some("must be a finite number".to_string());
    }
    refusal(2, v, None).map(|allowed| format!("must be {allowed}"))
}

/// Decimals of the numbers in a row written ([`Header::row`]): 1e-6 rpm, deg and
/// m/s (1 um/s). A point read back is within `SAME_POINT / 2` of the one written;
/// a velocity measured as a distance typed in mm over seconds keeps every digit
/// typed down to 1 um over 1 s.
pub const ROW_PLACES: usize = 6;

/// One measured run.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Line number in the file, from 1 (for messages and reports).
    pub line: usize,
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset held, degrees in [0, 360).
    pub offset_deg: f64,
    /// Measured mean travel velocity, m/s (positive rightward).
    pub velocity_mps: f64,
    /// Weight of the row (> 0; 1 without the column): its variance is taken as
    /// `sigma^2 / weight`, and repeated rows average by it.
    pub weight: f64,
}

impl Row {
    /// Whether the row is at `speed_rpm` and `offset_deg` within [`SAME_POINT`]
    /// (offsets compared around the turn: `-90` is `270`).
    pub fn is_at(&self, speed_rpm: f64, offset_deg: f64) -> bool {
        (self.speed_rpm - speed_rpm).abs() <= SAME_POINT
            && wrap_deg_signed_f64(self.offset_deg - offset_deg).abs() <= SAME_POINT
    }
}

/// A file's columns in its header's order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// Per field, its column: an index into `speed_rpm, offset_deg,
    /// velocity_mps, weight`.
    order: Vec<usize>,
}

impl Default for Header {
    /// The header of a new file: [`COLUMNS`], no weight.
    fn default() -> Self {
        Header {
            order: (0..COLUMNS.len()).collect(),
        }
    }
}

impl Header {
    /// The header line (without its line break).
    pub fn line(&self) -> String {
        let names: Vec<&str> = self.order.iter().map(|&k| ALL[k]).collect();
        names.join(",")
    }

    /// Whether the file has the weight column.
    pub fn weighted(&self) -> bool {
        self.order.contains(&3)
    }

    /// One row in this header's column order (without its line break), weight 1
    /// when the column is there. Each number is rounded to [`ROW_PLACES`] decimals
    /// and written in its shortest form: a velocity of 128.68 mm in 4 s is
    /// `0.03217`, not the `0.032170000000000004` that `128.68e-3 / 4` is in
    /// binary; a grid point `21.599999999999998` is `21.6`.
    pub fn row(&self, speed_rpm: f64, offset_deg: f64, velocity_mps: f64) -> String {
        let cell = |k: usize| match k {
            0 => decimals(speed_rpm, ROW_PLACES),
            1 => decimals(offset_deg, ROW_PLACES),
            2 => decimals(velocity_mps, ROW_PLACES),
            _ => "1".to_string(),
        };
        let cells: Vec<String> = self.order.iter().map(|&k| cell(k)).collect();
        cells.join(",")
    }
}

/// The largest measured file read, bytes: 64 MiB, some 4 million rows of
/// `3000,90,0.0301234` (a sweep on the machine writes one row a run, a few
/// hundred). The reader holds the whole text, so this bounds its memory.
pub const MAX_BYTES: u64 = 64 << 20;

/// The most problems one message lists; the rest are counted.
pub const MAX_PROBLEMS: usize = 50;

/// Reads and checks the file at `path` ([`parse_each`]), row by row: `each` gets
/// every row, none is kept here. A file over [`MAX_BYTES`] is refused unread.
pub fn read_each(
    path: &Path,
    speed_range: Option<(f64, f64)>,
    each: &mut dyn FnMut(Row),
) -> Result<Header, Failure> {
    let text = read_bounded(path)?;
    parse_each(&path.display().to_string(), &text, speed_range, each)
}

/// The text of the file at `path` through the one reader of input files (a
/// regular file, at most [`MAX_BYTES`] of it read: a device, a FIFO or a file
/// that never ends is refused too); a file too large is told how to shrink.
pub fn read_bounded(path: &Path) -> Result<String, Problem> {
    input::read_text_at_most(path, MAX_BYTES).map_err(|mut p| {
        if p.message.contains("too large") {
            p.message += ": a measured file holds one row a run; average repeated runs into one row, with their count as its weight";
        }
        p
    })
}

/// The header and rows of the text of a measured file named `file`, or every
/// problem ([`parse_each`]).
pub fn parse(
    file: &str,
    text: &str,
    speed_range: Option<(f64, f64)>,
) -> Result<(Header, Vec<Row>), Failure> {
    let mut rows = Vec::new();
    let header = parse_each(file, text, speed_range, &mut |r| rows.push(r))?;
    Ok((header, rows))
}

/// The header of the text of a measured file named `file`, each of its rows given
/// to `each` in order; or every problem, the user's to fix (the first
/// [`MAX_PROBLEMS`], then their count; a field longer than [`MAX_QUOTED`] cut).
/// `speed_range`, when given, is the controller's `[min_speed_rpm,
/// max_speed_rpm]`, rpm; without it a speed need only be above 0. `each` may
/// have seen rows of a file that is refused.
pub fn parse_each(
    file: &str,
    text: &str,
    speed_range: Option<(f64, f64)>,
    each: &mut dyn FnMut(Row),
) -> Result<Header, Failure> {
    let mut problems = Problems::default();
    // A spreadsheet's "CSV UTF-8" starts with a byte order mark: not part of the
    // header's first name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));

    // The header: which column each field holds.
    let Some((header_line, header)) = lines.next() else {
        return Err(Failure::usage(format!(
            "{file}: no header: expected the line `{},{WEIGHT}` (weight optional), then one row per run",
            COLUMNS.join(",")
        )));
    };
    let mut order = Vec::new();
    for name in header.split(',').map(str::trim) {
        match ALL.iter().position(|c| *c == name) {
            Some(k) if !order.contains(&k) => order.push(k),
            Some(_) => problems.push(format!(
                "{file}: line {header_line}: header: column `{name}` twice"
            )),
            None => problems.push(format!(
                "{file}: line {header_line}: header: unknown column `{}` (allowed: {})",
                input::cut(name, MAX_QUOTED),
                ALL.join(", ")
            )),
        }
    }
    for (k, c) in COLUMNS.iter().enumerate() {
        if !order.contains(&k) {
            problems.push(format!(
                "{file}: line {header_line}: header: missing column `{c}` (expected {},{WEIGHT}; weight optional)",
                COLUMNS.join(",")
            ));
        }
    }
    if !problems.is_empty() {
        return Err(problems.into_failure());
    }
    let header = Header { order };

    // The rows.
    for (line, l) in lines {
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        if cells.len() != header.order.len() {
            problems.push(format!(
                "{file}: line {line}: {} fields, the header has {} ({})",
                cells.len(),
                header.order.len(),
                header.line()
            ));
            continue;
        }
        // Per column, its value when allowed.
        let mut values = [None, None, None, Some(1.0)];
        for (&k, cell) in header.order.iter().zip(&cells) {
            let Some(v) = cell.parse::<f64>().ok().filter(|v| v.is_finite()) else {
                problems.push(format!(
                    "{file}: line {line}: {}: must be a finite number (got {:?})",
                    ALL[k],
                    input::cut(cell, MAX_QUOTED)
                ));
                continue;
            };
            match refusal(k, v, speed_range) {
                Some(allowed) => problems.push(format!(
                    "{file}: line {line}: {}: must be {allowed} (got {})",
                    ALL[k],
                    input::cut(cell, MAX_QUOTED)
                )),
                None => values[k] = Some(v),
            }
        }
        if let [Some(speed_rpm), Some(offset), Some(velocity_mps), Some(weight)] = values {
            each(Row {
                line,
                speed_rpm,
                offset_deg: wrap_deg_f64(offset) + 0.0,
                velocity_mps,
                weight,
            });
        }
    }
    if problems.is_empty() {
        Ok(header)
    } else {
        Err(problems.into_failure())
    }
}

/// The problems of a file: the first [`MAX_PROBLEMS`] kept, the rest counted.
#[derive(Default)]
struct Problems {
    kept: Vec<String>,
    more: usize,
}

impl Problems {
    fn push(&mut self, message: String) {
        if self.kept.len() < MAX_PROBLEMS {
            self.kept.push(message);
        } else {
            self.more += 1;
        }
    }

    fn is_empty(&self) -> bool {
        self.kept.is_empty()
    }

    /// The user's failure, the problems kept, then `... and N more problems`
    /// after them when some were left out.
    fn into_failure(self) -> Failure {
        let failure = Failure::new(Kind::Usage, self.kept);
        if self.more == 0 {
            return failure;
        }
        failure.with_detail(format!(
            "... and {} more problem{} (the first {MAX_PROBLEMS} are listed)",
            self.more,
            if self.more == 1 { "" } else { "s" }
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RANGE: Option<(f64, f64)> = Some((500.0, 4500.0));

    fn rows(text: &str) -> Vec<Row> {
        parse("m.csv", text, RANGE).unwrap().1
    }

    fn err(text: &str) -> String {
        parse("m.csv", text, RANGE).unwrap_err().message()
    }

    #[test]
    fn rows_read_with_and_without_weights() {
        let rows =
            rows("# measured\nspeed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n\n3000,-90,-0.03\n");
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1].line, 5);
        assert_eq!(rows[1].offset_deg, 270.0);
        assert_eq!(rows[0].weight, 1.0);
        assert!(rows[1].is_at(3000.0, -90.0) && !rows[1].is_at(3000.0, 90.0));
        let (header, rows) = parse(
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
        assert!(header.weighted());
        assert_eq!(header.line(), "weight,velocity_mps,offset_deg,speed_rpm");
    }

    #[test]
    fn a_byte_order_mark_is_not_part_of_the_header() {
        let rows = rows("\u{feff}speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n");
        assert_eq!((rows.len(), rows[0].line), (1, 2));
    }

    #[test]
    fn a_header_alone_is_a_file_with_no_rows_yet() {
        let (header, rows) = parse("m.csv", "speed_rpm,offset_deg,velocity_mps\n", None).unwrap();
        assert!(rows.is_empty());
        assert_eq!(header, Header::default());
        assert!(!header.weighted());
    }

    #[test]
    fn rows_are_written_in_the_header_order_and_read_back() {
        let header = Header::default();
        assert_eq!(header.line(), "speed_rpm,offset_deg,velocity_mps");
        assert_eq!(header.row(3000.0, 90.0, 0.0125), "3000,90,0.0125");
        // device tune's velocity of 128.68 mm in 4 s, a grid offset 0.1 + 0.2:
        // the decimals typed, not the binary residue.
        assert_eq!(
            header.row(3000.0, 0.1 + 0.2, 128.68 * 1e-3 / 4.0),
            "3000,0.3,0.03217"
        );
        let (header, _) =
            parse("m.csv", "velocity_mps,weight,speed_rpm,offset_deg\n", None).unwrap();
        let text = format!("{}\n{}\n", header.line(), header.row(2500.0, 270.5, -3e-5));
        assert_eq!(
            text,
            "velocity_mps,weight,speed_rpm,offset_deg\n-0.00003,1,2500,270.5\n"
        );
        let (_, rows) = parse("m.csv", &text, None).unwrap();
        assert_eq!(
            (
                rows[0].speed_rpm,
                rows[0].offset_deg,
                rows[0].velocity_mps,
                rows[0].weight
            ),
            (2500.0, 270.5, -3e-5, 1.0)
        );
    }

    #[test]
    fn every_problem_with_its_line_and_column() {
        assert_eq!(
            err("speed_rpm,offset,velocity_mps\n"),
            "error: m.csv: line 1: header: unknown column `offset` (allowed: speed_rpm, offset_deg, velocity_mps, weight)\n\
             error: m.csv: line 1: header: missing column `offset_deg` (expected speed_rpm,offset_deg,velocity_mps,weight; weight optional)\n"
        );
        assert!(err("# c\nspeed_rpm,offset_deg,velocity_mps,speed_rpm\n")
            .contains("error: m.csv: line 2: header: column `speed_rpm` twice"));
        assert!(err("").starts_with("error: m.csv: no header"));
        assert!(err("# only a comment\n\n").starts_with("error: m.csv: no header"));
        let e = err(
            "speed_rpm,offset_deg,velocity_mps,weight\n3000,90,fast,1\n3000,90,0.03,-1\n9000,90,0.03,1\n3000,90\n3000,nan,0.1,1\n",
        );
        assert_eq!(
            e,
            "error: m.csv: line 2: velocity_mps: must be a finite number (got \"fast\")\n\
             error: m.csv: line 3: weight: must be within [1e-6, 1e6] (weights are relative: scale them) (got -1)\n\
             error: m.csv: line 4: speed_rpm: must be within the controller's speed range [500, 4500] rpm (got 9000)\n\
             error: m.csv: line 5: 2 fields, the header has 4 (speed_rpm,offset_deg,velocity_mps,weight)\n\
             error: m.csv: line 6: offset_deg: must be a finite number (got \"nan\")\n"
        );
    }

    #[test]
    fn without_the_controller_a_speed_need_only_be_above_0() {
        let text = "speed_rpm,offset_deg,velocity_mps\n9000,90,0.03\n0,90,0.1\n";
        assert_eq!(
            parse("m.csv", text, None).unwrap_err().message(),
            "error: m.csv: line 3: speed_rpm: must be > 0 and at most 60000 rpm (got 0)\n"
        );
        assert!(err(text).contains("line 3: speed_rpm: must be within"));
    }

    /// Rows a float reads but no measurement gives: each refused with its line,
    /// column and bound (issue 23: weights of 1e308 overflowed the weighted mean,
    /// velocities of 1e308 made a table).
    #[test]
    fn numbers_beyond_their_bounds_are_refused() {
        let text = "speed_rpm,offset_deg,velocity_mps,weight\n\
                    3000,90,0.03,1e308\n\
                    3000,135,1e308,1\n\
                    1e308,90,0.03,1\n\
                    3000,1e300,0.03,1\n\
                    3000,90,-10.5,1e-7\n\
                    60000,-360,-10,1e-6\n\
                    3000,360,10,1e6\n";
        assert_eq!(
            parse("m.csv", text, None).unwrap_err().message(),
            "error: m.csv: line 2: weight: must be within [1e-6, 1e6] (weights are relative: scale them) (got 1e308)\n\
             error: m.csv: line 3: velocity_mps: must be within [-10, 10] m/s (got 1e308)\n\
             error: m.csv: line 4: speed_rpm: must be > 0 and at most 60000 rpm (got 1e308)\n\
             error: m.csv: line 5: offset_deg: must be within [-360, 360] degrees (one turn either way) (got 1e300)\n\
             error: m.csv: line 6: velocity_mps: must be within [-10, 10] m/s (got -10.5)\n\
             error: m.csv: line 6: weight: must be within [1e-6, 1e6] (weights are relative: scale them) (got 1e-7)\n"
        );
        // The bounds themselves are allowed.
        let ok = "speed_rpm,offset_deg,velocity_mps,weight\n60000,-360,-10,1e-6\n3000,360,10,1e6\n";
        assert_eq!(parse("m.csv", ok, None).unwrap().1.len(), 2);
        assert_eq!(velocity_refusal(0.03), None);
        assert_eq!(
            velocity_refusal(1e305).as_deref(),
            Some("must be within [-10, 10] m/s")
        );
        assert_eq!(
            velocity_refusal(f64::INFINITY).as_deref(),
            Some("must be a finite number")
        );
    }

    /// A long field is quoted cut, with its length; past the most problems, the
    /// rest are counted.
    #[test]
    fn messages_stay_short() {
        let long = "x".repeat(10_000_000);
        let e = err(&format!(
            "speed_rpm,offset_deg,velocity_mps\n3000,90,{long}\n"
        ));
        assert_eq!(
            e,
            format!(
                "error: m.csv: line 2: velocity_mps: must be a finite number (got \"{}... (10000000 bytes)\")\n",
                "x".repeat(MAX_QUOTED)
            )
        );
        let e = err(&format!("speed_rpm,offset_deg,{long}\n"));
        assert!(e.len() < 400, "{}", e.len());
        // A number that reads (as 0) but is refused.
        let zeros = "0".repeat(10_000_000);
        let e = err(&format!(
            "speed_rpm,offset_deg,velocity_mps\n0.{zeros}1,90,0.1\n"
        ));
        assert_eq!(
            e,
            format!(
                "error: m.csv: line 2: speed_rpm: must be within the controller's speed range [500, 4500] rpm (got 0.{}... (10000003 bytes))\n",
                "0".repeat(MAX_QUOTED - 2)
            )
        );
        let bad = "3000,90,fast\n".repeat(MAX_PROBLEMS + 7);
        let e = err(&format!("speed_rpm,offset_deg,velocity_mps\n{bad}"));
        assert_eq!(e.lines().count(), MAX_PROBLEMS + 1);
        assert!(e.ends_with(&format!(
            "\n... and 7 more problems (the first {MAX_PROBLEMS} are listed)\n"
        )));
    }

    /// Rows go to the caller one by one, in order; a file over the size limit is
    /// refused before it is parsed.
    #[test]
    fn a_file_is_read_row_by_row_within_its_size() {
        let dir = std::env::temp_dir().join(format!("host-sim-measured-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.csv");
        std::fs::write(
            &path,
            "speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n3000,0,0.01\n",
        )
        .unwrap();
        let mut lines = Vec::new();
        read_each(&path, None, &mut |r| lines.push(r.line)).unwrap();
        assert_eq!(lines, [2, 3]);
        // Past the limit: refused, whatever it holds (a sparse file of zeros).
        let big = std::fs::File::create(&path).unwrap();
        big.set_len(MAX_BYTES + 1).unwrap();
        let e = read_each(&path, None, &mut |_| panic!("no row"))
            .unwrap_err()
            .message();
        assert_eq!(
            e,
            format!(
                "error: {}: cannot read the file: too large (67108865 bytes): an input file of this kind has at most 67108864 bytes (64 MiB): a measured file holds one row a run; average repeated runs into one row, with their count as its weight\n",
                path.display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
