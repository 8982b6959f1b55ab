//! `host-sim device-sim --truth FILE.csv`: the platform's true pose, streamed as
//! the simulated device runs, for tests and demonstrations to compare with what
//! the host believes (a person measuring the travel with a ruler, say).
//!
//! The file is a live stream, not an output written whole: it is created (or
//! emptied) at start, its header `t,x,y,angle` first, then one row every
//! [`TRUTH_PERIOD_MS`] of device uptime, each row flushed as it is written, so a
//! reader tailing it sees rows at most one period plus a tick old; a last row at
//! the device's last tick when it stops between two. Columns, fixed:
//! `t` the device's uptime, s (0 at start, the link's time base); `x`, `y` the
//! platform's centre of mass, m, and `angle` its angle, rad (counter-clockwise
//! positive): the columns of `host-sim run --out` of the same name.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::plant::PlatformPose;
use crate::failure::{Failure, Kind};
use crate::numbers::fixed;
use crate::output::file::Target;

/// The truth file's header line.
pub const TRUTH_HEADER: &str = "t,x,y,angle";

/// Device time between rows, ms: 100 rows a second, fine enough to follow the
/// platform's travel (mm/s) and to see the hop of each revolution at low speed,
/// coarse enough that a test's reader keeps up (a row per control tick would be
/// 1000 a second).
pub const TRUTH_PERIOD_MS: u32 = 10;

/// The truth file being written.
pub struct TruthFile {
    path: PathBuf,
    out: BufWriter<File>,
    /// Uptime of the next row, ms.
    next_ms: u64,
    /// Uptime of the last row written, ms.
    last_ms: Option<u64>,
}

impl TruthFile {
    /// Creates (or empties) `path` and writes the header. A path that cannot be
    /// written, a directory, or stdout (which carries the port line) is the user's
    /// to change.
    pub fn create(path: &Path) -> Result<TruthFile, Failure> {
        let refuse = |why: String| {
            Failure::usage(format!("--truth: cannot write {}: {why}", path.display()))
        };
        let file = match Target::of(path).map_err(&refuse)? {
            Target::Regular(p) => OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(true)
                .open(p),
            Target::Special(p) => OpenOptions::new().write(true).open(p),
            Target::Stdout | Target::Stderr => {
                return Err(refuse(
                    "stdout and stderr carry the port line and the notes: give a file".into(),
                ))
            }
        }
        .map_err(|e| refuse(e.to_string()))?;
        let mut truth = TruthFile {
            path: path.to_path_buf(),
            out: BufWriter::new(file),
            next_ms: 0,
            last_ms: None,
        };
        truth
            .line(TRUTH_HEADER)
            .map_err(|f| f.of_kind(Kind::Usage))?;
        Ok(truth)
    }

    /// The row at uptime `uptime_ms` if one is due (the first at 0, then every
    /// [`TRUTH_PERIOD_MS`]), flushed. A failure of the run says why the file
    /// cannot be written on (the disk full, say).
    pub fn record(&mut self, uptime_ms: u64, pose: PlatformPose) -> Result<(), Failure> {
        if uptime_ms < self.next_ms {
            return Ok(());
        }
        self.next_ms = (uptime_ms / u64::from(TRUTH_PERIOD_MS) + 1) * u64::from(TRUTH_PERIOD_MS);
        self.row(uptime_ms, pose)
    }

    /// The last row, at uptime `uptime_ms`, unless a row was written there.
    pub fn finish(&mut self, uptime_ms: u64, pose: PlatformPose) -> Result<(), Failure> {
        if self.last_ms == Some(uptime_ms) {
            return Ok(());
        }
        self.row(uptime_ms, pose)
    }

    fn row(&mut self, uptime_ms: u64, pose: PlatformPose) -> Result<(), Failure> {
        self.last_ms = Some(uptime_ms);
        // Micrometres and microradians: far below what a run moves in a period.
        let row = format!(
            "{:.3},{},{},{}",
            uptime_ms as f64 / 1000.0,
            fixed(pose.x, 6),
            fixed(pose.y, 6),
            fixed(pose.angle, 6)
        );
        self.line(&row)
    }

    fn line(&mut self, line: &str) -> Result<(), Failure> {
        writeln!(self.out, "{line}")
            .and_then(|()| self.out.flush())
            .map_err(|e| {
                Failure::run(format!(
                    "--truth: cannot write {}: {e}",
                    self.path.display()
                ))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("truth-{}-{name}", std::process::id()))
    }

    #[test]
    fn rows_come_every_period_and_at_the_end_flushed_after_the_header() {
        let path = scratch("rows.csv");
        let mut t = TruthFile::create(&path).unwrap();
        let pose = |x| PlatformPose {
            x,
            y: 0.03,
            angle: -0.001,
        };
        for ms in 0..=25 {
            t.record(ms, pose(f64::from(ms as u32) * 1e-4)).unwrap();
        }
        t.finish(25, pose(25e-4)).unwrap();
        // Read while the writer is still open: every row is there already.
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "t,x,y,angle\n\
             0.000,0.000000,0.030000,-0.001000\n\
             0.010,0.001000,0.030000,-0.001000\n\
             0.020,0.002000,0.030000,-0.001000\n\
             0.025,0.002500,0.030000,-0.001000\n"
        );
        // No second row at the same time.
        t.finish(25, pose(25e-4)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
        drop(t);
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn a_path_that_cannot_be_written_is_a_usage_error() {
        let dir = std::env::temp_dir();
        let e = TruthFile::create(&dir).err().expect("refused");
        assert_eq!(e.status(), 2);
        assert!(
            e.message().starts_with("error: --truth: cannot write "),
            "{e:?}"
        );
        assert!(e.message().contains("is a directory"), "{e:?}");
        let missing = dir.join("no-such-dir-for-truth").join("t.csv");
        let e = TruthFile::create(&missing).err().expect("refused");
        assert!(e.message().contains("No such file"), "{e:?}");
        let e = TruthFile::create(Path::new("-")).err().expect("refused");
        assert!(e.message().contains("give a file"), "{e:?}");
    }
}
