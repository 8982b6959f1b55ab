//! `host-sim device telemetry`: the device's telemetry stream turned on, each frame
//! printed (readable lines or CSV) as it comes, a heartbeat every 50 ms (twice
//! per heartbeat period), the stream watched for silence, and turned off at the end
//! (`--count`, `--duration`, Ctrl-C, or a failure).
//!
//! A stream that goes silent ends the run: no frame for [`silence_limit`] (five
//! periods, at least a second) is the device's failure, whether it never sent one
//! (it acknowledged the stream but does not stream) or stopped (a line so noisy
//! that no frame crosses it whole). Without that watch a `--count` run waited for
//! ever, heartbeating all the while.

use std::path::Path;
use std::time::{Duration, Instant};

use shared::protocol::Request;

use super::args::TelemetryArgs;
use super::client::Client;
use super::report;
use super::requests::{command, HEARTBEAT_EVERY};
use crate::failure::{Console, Failure};
use crate::interrupt;
use crate::output::file::Staged;

/// The longest a stream at `period_ms` may go without a frame: five periods (a
/// few frames lost in a row on a noisy line are no silence), and at least 1 s (a
/// heartbeat's round trip, a slow line).
pub fn silence_limit(period_ms: u16) -> Duration {
    Duration::from_millis(5 * u64::from(period_ms)).max(Duration::from_secs(1))
}

/// The failure of a silent stream: `quiet_s` seconds without a frame after
/// `frames` frames.
fn silent(quiet_s: f64, period_ms: u16, frames: u64) -> Failure {
    Failure::Device(format!(
        "error: no telemetry from the device in {quiet_s:.1} s (it acknowledged StreamTelemetry \
         every {period_ms} ms; {frames} frames before): the device does not stream, or no frame \
         crosses the line whole"
    ))
}

/// Runs `host-sim device telemetry`: readable lines on `out` as the frames come,
/// and with `--csv` the frames as CSV rows into `csv` (staged, committed at the
/// end; `--csv -` is stdout, and then no readable lines).
pub fn run(
    client: &mut Client,
    a: &TelemetryArgs,
    mut csv: Option<(Staged, usize)>,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let lines = a.csv.as_deref() != Some(Path::new("-"));
    if let Some((set, i)) = &mut csv {
        set.write(*i, &format!("{}\n", report::CSV_HEADER))?;
    }
    interrupt::catch();
    command(
        client,
        &Request::StreamTelemetry {
            period_ms: a.period,
        },
    )?;
    let started = Instant::now();
    let end = a
        .duration
        .map(|d| (d, started + Duration::from_secs_f64(d)));
    let silence = silence_limit(a.period);
    // When the last frame came (the stream's start until the first).
    let mut last_frame = started;
    let mut frames: u64 = 0;
    let mut result = Ok(());
    'stream: loop {
        if interrupt::interrupted() {
            break;
        }
        if let Some((duration_s, _)) = end.filter(|(_, e)| Instant::now() >= *e) {
            // A run too short for the watch that saw no frame, though it lasted
            // two periods.
            if frames == 0 && duration_s * 1000.0 >= 2.0 * f64::from(a.period) {
                result = Err(silent(duration_s, a.period, frames));
            }
            break;
        }
        // A heartbeat, then frames until the next one is due.
        if let Err(e) = client.request(&Request::Heartbeat) {
            result = Err(Failure::from(e));
            break;
        }
        let next = Instant::now() + HEARTBEAT_EVERY;
        loop {
            for (at, report) in client.take_telemetry() {
                frames += 1;
                last_frame = last_frame.max(at);
                if lines {
                    out.print(&format!("{}\n", report::telemetry_line(&report)));
                }
                if let Some((set, i)) = &mut csv {
                    if let Err(e) = set.write(*i, &format!("{}\n", report::csv_row(&report))) {
                        result = Err(e);
                        break 'stream;
                    }
                }
                if a.count.is_some_and(|n| frames >= n) {
                    break 'stream;
                }
            }
            let now = Instant::now();
            if now.saturating_duration_since(last_frame) >= silence {
                result = Err(silent(silence.as_secs_f64(), a.period, frames));
                break 'stream;
            }
            if now >= next || interrupt::interrupted() {
                break;
            }
            let wait = next - now;
            let wait = end.map_or(wait, |(_, e)| wait.min(e.saturating_duration_since(now)));
            if wait.is_zero() {
                break;
            }
            if let Err(e) = client.pump(wait) {
                result = Err(Failure::from(e));
                break 'stream;
            }
        }
    }
    // The stream off, whatever ended it (tried even after a failure).
    let off = command(client, &Request::StreamTelemetry { period_ms: 0 });
    result?;
    off?;
    if let Some((set, _)) = csv {
        set.commit()?;
        if lines {
            let file = a.csv.as_deref().unwrap_or(Path::new("")).display();
            out.print(&format!("telemetry: {frames} frames written to {file}\n"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_silence_limit_is_five_periods_and_at_least_a_second() {
        assert_eq!(silence_limit(20), Duration::from_secs(1));
        assert_eq!(silence_limit(200), Duration::from_secs(1));
        assert_eq!(silence_limit(400), Duration::from_secs(2));
        assert_eq!(silence_limit(u16::MAX), Duration::from_millis(327_675));
    }
}
