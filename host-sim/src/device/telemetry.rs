//! `host-sim device telemetry`: the device's telemetry stream
//! ([`super::telemetry_stream`]) printed as readable lines or CSV rows until
//! `--count`, `--duration` or Ctrl-C, or served to a live page by
//! [`super::live`] with `--serve`.

use std::path::Path;

use shared::protocol::StatusReport;

use super::args::TelemetryArgs;
use super::telemetry_stream::{stream, Sink};
use super::{live, report};
use crate::failure::{Console, Failure};
use crate::link::client::Client;
use crate::output::file::Staged;

/// The frames printed: readable lines on the console, CSV rows into a staged
/// file, until `--count`.
struct Printed<'a, 'c> {
    lines: bool,
    csv: Option<&'a mut (Staged, usize)>,
    count: Option<u64>,
    frames: u64,
    out: &'a mut Console<'c>,
}

impl Sink for Printed<'_, '_> {
    fn frame(&mut self, report: &StatusReport) -> Result<bool, Failure> {
        self.frames += 1;
        if self.lines {
            self.out
                .print(&format!("{}\n", report::telemetry_line(report)));
        }
        if let Some((set, i)) = &mut self.csv {
            set.write(*i, &format!("{}\n", report::csv_row(report)))?;
        }
        Ok(self.count.is_none_or(|n| self.frames < n))
    }
}

/// Runs `host-sim device telemetry`: readable lines on `out` as the frames come,
/// and with `--csv` the frames as CSV rows into `csv` (staged, committed at the
/// end; `--csv -` is stdout, and then no readable lines); with `--serve` the live
/// page of the device at `--port` `device` instead ([`live::run`]).
pub fn run(
    client: &mut Client,
    a: &TelemetryArgs,
    device: &str,
    mut csv: Option<(Staged, usize)>,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    if let Some(addr) = &a.serve {
        return live::run(client, a, addr, device, out);
    }
    let lines = a.csv.as_deref() != Some(Path::new("-"));
    if let Some((set, i)) = &mut csv {
        set.write(*i, &format!("{}\n", report::csv_header()))?;
    }
    let mut printed = Printed {
        lines,
        csv: csv.as_mut(),
        count: a.count,
        frames: 0,
        out,
    };
    let frames = stream(client, a.period, a.duration, &mut printed)?;
    if let Some((set, _)) = csv {
        set.commit()?;
        if lines {
            let file = a.csv.as_deref().unwrap_or(Path::new("")).display();
            out.print(&format!("telemetry: {frames} frames written to {file}\n"));
        }
    }
    Ok(())
}
