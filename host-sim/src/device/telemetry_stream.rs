//! The device's telemetry stream, for `device telemetry` (printed, to CSV) and
//! for its live page ([`super::live`]): the stream turned on, each frame handed
//! to a [`Sink`] as it comes, a heartbeat every 50 ms (twice per heartbeat
//! period), the stream watched for silence, and turned off at the end (enough
//! frames, the duration, Ctrl-C, or a failure).
//!
//! A stream that goes silent ends the run: no frame for [`silence_limit`] (five
//! periods, at least a second) is the device's failure, whether it never sent one
//! (it acknowledged the stream but does not stream) or stopped (a line so noisy
//! that no frame crosses it whole). Without that watch a `--count` run waited for
//! ever, heartbeating all the while.

use shared::controller::Command;
use std::time::{Duration, Instant};

use shared::protocol::{Request, StatusReport};

use crate::failure::Failure;
use crate::interrupt;
use crate::link::client::Client;
use crate::link::requests::{command, HEARTBEAT_EVERY};

/// The longest the link is read without the [`Sink`] being asked for requests of
/// its own ([`Sink::between`]).
const POLL: Duration = Duration::from_millis(20);

/// The longest a stream at `period_ms` may go without a frame: five periods (a
/// few frames lost in a row on a noisy line are no silence), and at least 1 s (a
/// heartbeat's round trip, a slow line).
pub fn silence_limit(period_ms: u16) -> Duration {
    Duration::from_millis(5 * u64::from(period_ms)).max(Duration::from_secs(1))
}

/// The failure of a silent stream: `quiet_s` seconds without a frame after
/// `frames` frames.
fn silent(quiet_s: f64, period_ms: u16, frames: u64) -> Failure {
    Failure::device(format!(
        "no telemetry from the device in {quiet_s:.1} s (it acknowledged StreamTelemetry \
         every {period_ms} ms; {frames} frames before): the device does not stream, or no frame \
         crosses the line whole"
    ))
}

/// Where the frames of a [`stream`] go.
pub trait Sink {
    /// A frame came; `Ok(false)` ends the stream (enough frames).
    fn frame(&mut self, report: &StatusReport) -> Result<bool, Failure>;

    /// Between reads of the link, at least every 20 ms: requests of the sink's
    /// own through `client` (the live page's Stop).
    fn between(&mut self, _client: &mut Client) -> Result<(), Failure> {
        Ok(())
    }
}

/// Streams telemetry every `period_ms` into `sink` until it has enough, for
/// `duration_s` seconds, or until Ctrl-C; the frames it got. The stream is turned
/// off at the end whatever ended it (tried even after a failure).
pub fn stream(
    client: &mut Client,
    period_ms: u16,
    duration_s: Option<f64>,
    sink: &mut dyn Sink,
) -> Result<u64, Failure> {
    interrupt::catch();
    command(client, &Request::StreamTelemetry { period_ms })?;
    let result = watch(client, period_ms, duration_s, sink);
    let off = command(client, &Request::StreamTelemetry { period_ms: 0 });
    let frames = result?;
    off?;
    Ok(frames)
}

/// The stream after it was turned on: heartbeats, frames into `sink`, the
/// silence watch.
fn watch(
    client: &mut Client,
    period_ms: u16,
    duration_s: Option<f64>,
    sink: &mut dyn Sink,
) -> Result<u64, Failure> {
    let started = Instant::now();
    let end = duration_s.map(|d| (d, started + Duration::from_secs_f64(d)));
    let silence = silence_limit(period_ms);
    // When the last frame came (the stream's start until the first).
    let mut last_frame = started;
    let mut frames: u64 = 0;
    loop {
        if interrupt::interrupted() {
            return Ok(frames);
        }
        if let Some((duration_s, _)) = end.filter(|(_, e)| Instant::now() >= *e) {
            // A run too short for the watch that saw no frame, though it lasted
            // two periods.
            if frames == 0 && duration_s * 1000.0 >= 2.0 * f64::from(period_ms) {
                return Err(silent(duration_s, period_ms, frames));
            }
            return Ok(frames);
        }
        // A heartbeat, then frames until the next one is due.
        client.request(&Request::Command(Command::Heartbeat))?;
        let next = Instant::now() + HEARTBEAT_EVERY;
        loop {
            for (at, report) in client.take_telemetry() {
                frames += 1;
                last_frame = last_frame.max(at);
                if !sink.frame(&report)? {
                    return Ok(frames);
                }
            }
            sink.between(client)?;
            let now = Instant::now();
            if now.saturating_duration_since(last_frame) >= silence {
                return Err(silent(silence.as_secs_f64(), period_ms, frames));
            }
            if now >= next || interrupt::interrupted() {
                break;
            }
            let wait = (next - now).min(POLL);
            let wait = end.map_or(wait, |(_, e)| wait.min(e.saturating_duration_since(now)));
            if wait.is_zero() {
                break;
            }
            client.pump(wait)?;
        }
    }
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
