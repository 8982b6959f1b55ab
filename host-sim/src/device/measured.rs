//! The measured file of `host-sim device tune` open for
//! appending; its format, reader and row formatting are [`crate::measured`]'s, the
//! one `host-sim calibrate` reads with.
//!
//! [`MeasuredFile::create`] starts a file (the header, synced);
//! [`MeasuredFile::resume`] reads an existing one, every row checked, and keeps its
//! header's column order for the rows appended; [`MeasuredFile::append`] adds a row
//! and syncs it to disk before returning, so that a sweep cut short at any moment
//! keeps every answer given.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::failure::Failure;
use crate::machine::input;
use crate::measured::{self, Header, Row};
use crate::output::csv::csv_number;
use shared::controller::angle::wrap_deg_f64;

/// A measured file open for appending.
#[derive(Debug)]
pub struct MeasuredFile {
    path: PathBuf,
    file: File,
    /// The file's columns: appended rows follow their order (weight 1 when the
    /// weight column is there).
    header: Header,
    /// The file ends without a line break (a row cut short by a crash is
    /// refused; a whole last row without one gets it before the next).
    needs_newline: bool,
    /// The line the next row appended is on, from 1.
    next_line: usize,
    /// Every row, those read and those appended.
    pub rows: Vec<Row>,
}

/// "FILE: what", the user's to fix.
fn usage(path: &Path, what: impl std::fmt::Display) -> Failure {
    Failure::usage(format!("{}: {what}", path.display()))
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
        let header = Header::default();
        file.write_all(format!("{}\n", header.line()).as_bytes())
            .and_then(|()| file.sync_all())
            .map_err(|e| usage(path, format!("--out: cannot write the header: {e}")))?;
        Ok(MeasuredFile {
            path: path.to_path_buf(),
            file,
            header,
            needs_newline: false,
            next_line: 2,
            rows: Vec::new(),
        })
    }

    /// Opens the existing file at `path` to continue it: its header and every
    /// row checked ([`measured::parse`]; speeds above 0, as `--speeds`'), every
    /// problem at once.
    pub fn resume(path: &Path) -> Result<MeasuredFile, Failure> {
        let text =
            input::read_text(path).map_err(|p| usage(path, format!("--resume: {}", p.message)))?;
        let (header, rows) = measured::parse(&path.display().to_string(), &text, None)?;
        let file = OpenOptions::new().append(true).open(path).map_err(|e| {
            usage(
                path,
                format!("--resume: cannot open the file to append: {e}"),
            )
        })?;
        Ok(MeasuredFile {
            path: path.to_path_buf(),
            file,
            header,
            needs_newline: !text.ends_with('\n'),
            next_line: text.lines().count() + 1,
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

    /// Appends the row (weight 1 when the file has the column), in the file's
    /// column order, and syncs it to disk before returning. A failure here is the
    /// run's (the disk full, the file removed): exit 1.
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
        line.push_str(&self.header.row(speed_rpm, offset_deg, velocity_mps));
        line.push('\n');
        self.file
            .write_all(line.as_bytes())
            .and_then(|()| self.file.sync_data())
            .map_err(|e| {
                Failure::run(format!(
                    "{}: cannot append the measurement ({} rpm, {} deg): {e}",
                    self.path.display(),
                    csv_number(speed_rpm),
                    csv_number(offset_deg)
                ))
            })?;
        self.needs_newline = false;
        self.rows.push(Row {
            line: self.next_line,
            speed_rpm,
            offset_deg: wrap_deg_f64(offset_deg) + 0.0,
            velocity_mps,
            weight: 1.0,
        });
        self.next_line += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch path `name`, no file there.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("host-sim-measured-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        let _ = std::fs::remove_file(&path);
        path
    }

    #[test]
    fn appended_rows_read_back_and_a_file_is_never_overwritten() {
        let path = scratch("m.csv");
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
        let lines: Vec<usize> = f.rows.iter().map(|r| r.line).collect();
        assert_eq!(lines, [2, 3, 4]);
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn a_file_in_its_own_column_order_is_continued_in_it() {
        let path = scratch("reordered.csv");
        let text = "# bench, 2 May\nweight,offset_deg,velocity_mps,speed_rpm\n2,-90,-0.03,3000\n# cut here";
        std::fs::write(&path, text).unwrap();
        let mut f = MeasuredFile::resume(&path).unwrap();
        assert!(f.has(3000.0, 270.0) && !f.has(3000.0, 90.0));
        f.append(3000.0, 90.0, 0.0125).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{text}\n1,90,0.0125,3000\n")
        );
        assert_eq!(f.rows[1].line, 5);
        // Read back as a new resume (and calibrate) reads it: the same rows.
        let again = MeasuredFile::resume(&path).unwrap();
        assert_eq!(again.rows, f.rows);
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn a_bad_file_is_refused_with_every_problem() {
        let path = scratch("bad.csv");
        std::fs::write(
            &path,
            "speed_rpm,offset_deg,velocity_mps\n0,90,0.1\n3000,x,0.1\n",
        )
        .unwrap();
        let e = MeasuredFile::resume(&path).unwrap_err();
        let file = path.display();
        assert_eq!(e.status(), crate::failure::EXIT_USAGE);
        assert_eq!(
            e.message(),
            format!(
                "error: {file}: line 2: speed_rpm: must be > 0 and at most 60000 rpm (got 0)\n\
                 error: {file}: line 3: offset_deg: must be a finite number (got \"x\")\n"
            )
        );
        let _ = std::fs::remove_file(&path);
    }
}
