//! The measured file of `host-sim device tune` (issue 14, section 2): CSV with the
//! header `speed_rpm,offset_deg,velocity_mps` or `speed_rpm,offset_deg,velocity_mps,weight`,
//! then one row per run: rotor speed (rpm, > 0), phase offset (degrees, any finite
//! angle), mean platform velocity (m/s, + right), and an optional weight (> 0,
//! default 1).
//!
//! [`MeasuredFile::create`] starts a file (the header, synced); [`MeasuredFile::resume`]
//! reads an existing one, every row checked; [`MeasuredFile::append`] adds a row
//! and syncs it to disk before returning, so that a sweep cut short at any moment
//! keeps every answer given.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::failure::Failure;
use crate::output::csv::csv_number;
use crate::simulation::summary::wrap_deg_180;

/// The columns of every row.
pub const HEADER: &str = "speed_rpm,offset_deg,velocity_mps";

/// The columns with the optional weight.
pub const HEADER_WEIGHTED: &str = "speed_rpm,offset_deg,velocity_mps,weight";

/// Two speeds (rpm) or offsets (degrees) closer than this are the same point.
pub const SAME_POINT: f64 = 1e-6;

/// One row: a run at a grid point and the velocity measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset, degrees (as written; not wrapped).
    pub offset_deg: f64,
    /// Mean platform velocity, m/s (+ right).
    pub velocity_mps: f64,
    /// Weight of the row among repeated ones (1 without the column).
    pub weight: f64,
}

impl Measured {
    /// Whether the row is at `speed_rpm` and `offset_deg` (offsets compared
    /// around the turn).
    pub fn is_at(&self, speed_rpm: f64, offset_deg: f64) -> bool {
        (self.speed_rpm - speed_rpm).abs() <= SAME_POINT
            && wrap_deg_180(self.offset_deg - offset_deg).abs() <= SAME_POINT
    }
}

/// A measured file open for appending.
#[derive(Debug)]
pub struct MeasuredFile {
    path: PathBuf,
    file: File,
    /// The file has the weight column: appended rows carry a weight of 1.
    weighted: bool,
    /// The file ends without a line break (a row cut short by a crash is
    /// refused; a whole last row without one gets it before the next).
    needs_newline: bool,
    /// Every row, those read and those appended.
    pub rows: Vec<Measured>,
}

/// "error: FILE: what", the user's to fix.
fn usage(path: &Path, what: impl std::fmt::Display) -> Failure {
    Failure::Usage(format!("error: {}: {what}", path.display()))
}

/// The refusal of an `--out` file that exists.
pub fn exists(path: &Path) -> Failure {
    usage(
        path,
        format!(
            "--out: the file exists: continue it with --resume {}, or name a new file (it is never overwritten)",
            path.display()
        ),
    )
}

impl MeasuredFile {
    /// Starts a new file at `path` with the header, synced to disk. A file there
    /// already is refused (never overwritten).
    pub fn create(path: &Path) -> Result<MeasuredFile, Failure> {
        let mut file = OpenOptions::new()
            .append(true)
            .create_new(true)
            .open(path)
            .map_err(|e| match e.kind() {
                std::io::ErrorKind::AlreadyExists => exists(path),
                _ => usage(path, format!("--out: cannot create the file: {e}")),
            })?;
        file.write_all(format!("{HEADER}\n").as_bytes())
            .and_then(|()| file.sync_all())
            .map_err(|e| usage(path, format!("--out: cannot write the header: {e}")))?;
        Ok(MeasuredFile {
            path: path.to_path_buf(),
            file,
            weighted: false,
            needs_newline: false,
            rows: Vec::new(),
        })
    }

    /// Opens the existing file at `path` to continue it: its header and every
    /// row checked ([`parse`]).
    pub fn resume(path: &Path) -> Result<MeasuredFile, Failure> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| usage(path, format!("--resume: cannot read the file: {e}")))?;
        let (rows, weighted) = parse(&text).map_err(|why| usage(path, why))?;
        let file = OpenOptions::new().append(true).open(path).map_err(|e| {
            usage(
                path,
                format!("--resume: cannot open the file to append: {e}"),
            )
        })?;
        Ok(MeasuredFile {
            path: path.to_path_buf(),
            file,
            weighted,
            needs_newline: !text.ends_with('\n'),
            rows,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether a row is at `speed_rpm`, `offset_deg`.
    pub fn has(&self, speed_rpm: f64, offset_deg: f64) -> bool {
        self.rows.iter().any(|r| r.is_at(speed_rpm, offset_deg))
    }

    /// Appends `row` (weight 1) and syncs it to disk before returning. A
    /// failure here is the run's (the disk full, the file removed): exit 1.
    pub fn append(
        &mut self,
        speed_rpm: f64,
        offset_deg: f64,
        velocity_mps: f64,
    ) -> Result<(), Failure> {
        let mut line = String::new();
        if self.needs_newline {
            line.push('\n');
        }
        line.push_str(&format!(
            "{},{},{}",
            csv_number(speed_rpm),
            csv_number(offset_deg),
            csv_number(velocity_mps)
        ));
        if self.weighted {
            line.push_str(",1");
        }
        line.push('\n');
        self.file
            .write_all(line.as_bytes())
            .and_then(|()| self.file.sync_data())
            .map_err(|e| {
                Failure::Run(format!(
                    "error: {}: cannot append the measurement ({} rpm, {} deg): {e}",
                    self.path.display(),
                    csv_number(speed_rpm),
                    csv_number(offset_deg)
                ))
            })?;
        self.needs_newline = false;
        self.rows.push(Measured {
            speed_rpm,
            offset_deg,
            velocity_mps,
            weight: 1.0,
        });
        Ok(())
    }
}

/// The rows of a measured file's `text` and whether it has the weight column, or
/// what is wrong: the header, or a row (numbered from 1 after the header, with
/// its line and column), and what is allowed. Empty lines are skipped.
pub fn parse(text: &str) -> Result<(Vec<Measured>, bool), String> {
    let mut lines = text.lines().enumerate();
    let header = lines.next().map_or("", |(_, l)| l.trim());
    let weighted = match header {
        HEADER => false,
        HEADER_WEIGHTED => true,
        _ => {
            return Err(format!(
                "line 1: the header must be `{HEADER}` or `{HEADER_WEIGHTED}` (got {header:?})"
            ))
        }
    };
    let columns: Vec<&str> = header.split(',').collect();
    let mut rows = Vec::new();
    for (i, line) in lines {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let at = format!("row {} (line {})", rows.len() + 1, i + 1);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != columns.len() {
            return Err(format!(
                "{at}: {} fields, the header has {} ({})",
                fields.len(),
                columns.len(),
                columns.join(",")
            ));
        }
        let mut values = [1.0; 4];
        for (k, (field, column)) in fields.iter().zip(&columns).enumerate() {
            let v = field.parse::<f64>().ok().filter(|v| v.is_finite());
            let ok = match (*column, v) {
                (_, None) => false,
                ("speed_rpm" | "weight", Some(v)) => v > 0.0,
                (_, Some(_)) => true,
            };
            if !ok {
                let allowed = match *column {
                    "speed_rpm" => "a number of rpm above 0",
                    "weight" => "a number above 0",
                    "offset_deg" => "a finite number of degrees",
                    _ => "a finite number of m/s",
                };
                return Err(format!("{at}: {column}: must be {allowed} (got {field:?})"));
            }
            values[k] = v.unwrap_or(1.0);
        }
        rows.push(Measured {
            speed_rpm: values[0],
            offset_deg: values[1],
            velocity_mps: values[2],
            weight: values[3],
        });
    }
    Ok((rows, weighted))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_read_with_and_without_weights() {
        let (rows, weighted) =
            parse("speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n\n3000,-30,-1e-3\n").unwrap();
        assert!(!weighted);
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1].offset_deg, -30.0);
        assert_eq!(rows[1].weight, 1.0);
        assert!(rows[1].is_at(3000.0, 330.0));
        let (rows, weighted) =
            parse("speed_rpm,offset_deg,velocity_mps,weight\n2500,0,0.01,2\n").unwrap();
        assert!(weighted);
        assert_eq!(rows[0].weight, 2.0);
    }

    #[test]
    fn bad_files_name_the_row_and_the_column() {
        for (text, expect) in [
            ("", "line 1: the header must be"),
            ("speed,offset,v\n", "line 1: the header must be"),
            (
                "speed_rpm,offset_deg,velocity_mps\n3000,90\n",
                "row 1 (line 2): 2 fields, the header has 3",
            ),
            (
                "speed_rpm,offset_deg,velocity_mps\n3000,90,0.1\n0,90,0.1\n",
                "row 2 (line 3): speed_rpm: must be a number of rpm above 0 (got \"0\")",
            ),
            (
                "speed_rpm,offset_deg,velocity_mps\n3000,x,0.1\n",
                "row 1 (line 2): offset_deg: must be a finite number of degrees",
            ),
            (
                "speed_rpm,offset_deg,velocity_mps\n3000,1,NaN\n",
                "velocity_mps: must be a finite number of m/s",
            ),
            (
                "speed_rpm,offset_deg,velocity_mps,weight\n3000,1,0,-1\n",
                "weight: must be a number above 0",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert!(e.contains(expect), "{text:?}: {e}");
        }
    }

    #[test]
    fn appended_rows_read_back_and_a_file_is_never_overwritten() {
        let dir = std::env::temp_dir().join(format!("host-sim-measured-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.csv");
        let _ = std::fs::remove_file(&path);
        let mut f = MeasuredFile::create(&path).unwrap();
        f.append(3000.0, 90.0, 0.0125).unwrap();
        drop(f);
        let e = MeasuredFile::create(&path).unwrap_err();
        assert!(
            e.message()
                .contains("the file exists: continue it with --resume"),
            "{e:?}"
        );
        // A last row without its line break (written by hand) gets one first.
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("3000,180,-0.5");
        std::fs::write(&path, &text).unwrap();
        let mut f = MeasuredFile::resume(&path).unwrap();
        assert!(f.has(3000.0, 90.0) && f.has(3000.0, 180.0) && !f.has(3000.0, 0.0));
        f.append(3000.0, 0.0, -0.002).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "speed_rpm,offset_deg,velocity_mps\n3000,90,0.0125\n3000,180,-0.5\n3000,0,-0.002\n"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
