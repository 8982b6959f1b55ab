//! Progress of a long command on stderr: a bar redrawn in place when stderr is a
//! terminal; otherwise (a log file, a pipe, CI) one line every
//! [`DEFAULT_EVERY_S`] seconds, as cargo and rsync do off a terminal, so that a
//! sweep of minutes is not silent for minutes:
//!
//! ```text
//! tune: 48/120 runs, 25 s elapsed, ~38 s left
//! ```
//!
//! The total is fixed when the progress starts (a sweep counts its check runs
//! in it from the start), so the count and the estimate never jump back.
//!
//! [`EVERY_ENV`] sets the interval off a terminal, in seconds (0: a line at every
//! step): for tests, which must not wait on the clock.

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Seconds between two lines off a terminal, by default.
pub const DEFAULT_EVERY_S: f64 = 5.0;

/// The environment variable that sets the seconds between two lines off a
/// terminal (a number >= 0; 0: a line at every step).
pub const EVERY_ENV: &str = "VIBRO_PROGRESS_EVERY";

/// Progress of `total` steps of a command, on stderr ([module doc](self)).
/// Shared by threads (`inc` from each).
pub struct Progress {
    /// On a terminal: the bar.
    bar: Option<ProgressBar>,
    /// Off a terminal: the lines.
    lines: Option<Lines>,
}

/// The lines off a terminal.
struct Lines {
    /// What heads a line (`tune`).
    name: String,
    /// What is counted (`runs`).
    unit: String,
    total: u64,
    done: AtomicU64,
    started: Instant,
    every: Duration,
    /// When the last line was written (since `started`), and where lines go.
    last: Mutex<(Duration, Box<dyn Write + Send>)>,
}

impl Progress {
    /// Progress of `total` `unit` (`runs`, `ms simulated`) headed `name`
    /// (`tune`), on stderr: a bar on a terminal, else lines every
    /// [`EVERY_ENV`] (default [`DEFAULT_EVERY_S`]) seconds. A value of
    /// [`EVERY_ENV`] that is not a number >= 0 is said on stderr, and the
    /// default taken.
    pub fn new(name: &str, total: u64, unit: &str) -> Progress {
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            if let Ok(style) = ProgressStyle::with_template(&format!(
                "{name} {{bar:40}} {{pos}}/{{len}} {unit}, {{elapsed}} elapsed, ~{{eta}} left"
            )) {
                bar.set_style(style);
            }
            return Progress {
                bar: Some(bar),
                lines: None,
            };
        }
        let every = match std::env::var(EVERY_ENV) {
            Err(_) => DEFAULT_EVERY_S,
            Ok(text) => parse_every(&text).unwrap_or_else(|| {
                eprintln!(
                    "warning: {EVERY_ENV}={text:?}: not a number of seconds >= 0; a progress line every {DEFAULT_EVERY_S} s"
                );
                DEFAULT_EVERY_S
            }),
        };
        Progress::lines(
            name,
            total,
            unit,
            Duration::from_secs_f64(every),
            Box::new(std::io::stderr()),
        )
    }

    /// Progress written as lines to `out`, one at most every `every`.
    fn lines(
        name: &str,
        total: u64,
        unit: &str,
        every: Duration,
        out: Box<dyn Write + Send>,
    ) -> Progress {
        Progress {
            bar: None,
            lines: Some(Lines {
                name: name.to_string(),
                unit: unit.to_string(),
                total,
                done: AtomicU64::new(0),
                started: Instant::now(),
                every,
                last: Mutex::new((Duration::ZERO, out)),
            }),
        }
    }

    /// `n` more steps done.
    pub fn inc(&self, n: u64) {
        if n == 0 {
            return;
        }
        if let Some(bar) = &self.bar {
            bar.inc(n);
        }
        if let Some(lines) = &self.lines {
            lines.done.fetch_add(n, Ordering::Relaxed);
            lines.tick();
        }
    }

    /// `done` steps done in all.
    pub fn set_position(&self, done: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(done);
        }
        if let Some(lines) = &self.lines {
            lines.done.store(done, Ordering::Relaxed);
            lines.tick();
        }
    }

    /// The end: the bar is cleared (the command's own summary follows).
    pub fn finish_and_clear(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl Lines {
    /// A line, if one is due.
    fn tick(&self) {
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        let elapsed = self.started.elapsed();
        if !due(elapsed, last.0, self.every) {
            return;
        }
        last.0 = elapsed;
        // Read under the lock: the lines' counts never go back.
        let done = self.done.load(Ordering::Relaxed);
        let text = line(&self.name, done, self.total, &self.unit, elapsed);
        let _ = writeln!(last.1, "{text}");
        let _ = last.1.flush();
    }
}

/// [`EVERY_ENV`]'s value as seconds: a finite number >= 0.
fn parse_every(text: &str) -> Option<f64> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|s| s.is_finite() && *s >= 0.0 && *s <= 1e9)
}

/// Whether a line is due at `elapsed`, the last at `last`: `every` has passed
/// since (the first line comes `every` after the start).
fn due(elapsed: Duration, last: Duration, every: Duration) -> bool {
    elapsed >= last + every
}

/// One line: `tune: 48/120 runs, 25 s elapsed, ~38 s left`. The estimate of
/// what is left is the time so far per step times the steps left, from the
/// first step on.
fn line(name: &str, done: u64, total: u64, unit: &str, elapsed: Duration) -> String {
    let mut text = format!(
        "{name}: {done}/{total} {unit}, {} elapsed",
        duration(elapsed.as_secs_f64())
    );
    if done > 0 && done <= total {
        let left = elapsed.as_secs_f64() * (total - done) as f64 / done as f64;
        text.push_str(&format!(", ~{} left", duration(left)));
    }
    text
}

/// Seconds for people: `42 s`, `3 min 12 s`, `2 h 5 min`.
fn duration(s: f64) -> String {
    let s = s.round() as u64;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {} s", s / 60, s % 60),
        _ => format!("{} h {} min", s / 3600, s % 3600 / 60),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    /// A writer the test reads back.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_line_says_done_total_elapsed_and_what_is_left() {
        let s = Duration::from_secs;
        assert_eq!(
            line("tune", 48, 120, "runs", s(25)),
            "tune: 48/120 runs, 25 s elapsed, ~38 s left"
        );
        assert_eq!(
            line("calibrate", 0, 700, "runs", s(5)),
            "calibrate: 0/700 runs, 5 s elapsed"
        );
        assert_eq!(
            line("run", 1000, 4000, "ms simulated", s(100)),
            "run: 1000/4000 ms simulated, 1 min 40 s elapsed, ~5 min 0 s left"
        );
        assert_eq!(duration(7500.0), "2 h 5 min");
    }

    #[test]
    fn a_line_is_due_every_interval_and_at_every_step_with_0() {
        let ms = Duration::from_millis;
        let every = Duration::from_secs(5);
        assert!(!due(ms(4999), ms(0), every));
        assert!(due(ms(5000), ms(0), every));
        assert!(!due(ms(9000), ms(5000), every));
        assert!(due(ms(10_100), ms(5000), every));
        assert!(due(ms(5000), ms(5000), Duration::ZERO));
        assert_eq!(parse_every(" 0 "), Some(0.0));
        assert_eq!(parse_every("2.5"), Some(2.5));
        for bad in ["-1", "nan", "inf", "soon", ""] {
            assert_eq!(parse_every(bad), None, "{bad}");
        }
    }

    /// With the interval 0 every step writes a line, from every thread, the
    /// counts in order and the total fixed; with a long one, none.
    #[test]
    fn lines_off_a_terminal_count_up_to_the_fixed_total() {
        let out = Shared::default();
        let p = Progress::lines("tune", 40, "runs", Duration::ZERO, Box::new(out.clone()));
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| (0..10).for_each(|_| p.inc(1)));
            }
        });
        p.finish_and_clear();
        let text = String::from_utf8(out.0.lock().unwrap().clone()).unwrap();
        let counts: Vec<u64> = text
            .lines()
            .map(|l| {
                let rest = l.strip_prefix("tune: ").unwrap();
                assert!(rest.contains("/40 runs, "), "{l}");
                rest.split('/').next().unwrap().parse().unwrap()
            })
            .collect();
        assert_eq!(counts.len(), 40, "{text}");
        assert!(counts.windows(2).all(|w| w[0] <= w[1]), "{counts:?}");
        assert_eq!(counts.last(), Some(&40));

        let quiet = Shared::default();
        let p = Progress::lines(
            "tune",
            40,
            "runs",
            Duration::from_secs(3600),
            Box::new(quiet.clone()),
        );
        p.inc(40);
        assert!(quiet.0.lock().unwrap().is_empty());
    }
}
