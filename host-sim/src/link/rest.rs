//! The machine at rest after a stop, as its status says: an accepted `Stop` is
//! not a stopped machine (the rotors ramp down for a second or more, and a
//! device may acknowledge a stop and run on), so the commands that stop it ask
//! the status until it is at rest, within a bound, and report what the status
//! says.
//!
//! At rest is the device's own rule for a table write and the self-test
//! ([`may_write_table`]): the driver off (state `idle`, or `fault` with the
//! motors switched off) and both rotors below
//! [`shared::controller::WRITE_MAX_SPEED_RPM`] (10 rpm). So a command that
//! returns "at rest" can be followed by `device table write` at once.

use std::time::{Duration, Instant};

use shared::controller::may_write_table;
use shared::protocol::{Request, Response, StatusReport};

use crate::failure::Failure;
use crate::link::client::Client;
use crate::link::requests::{ask, unexpected, HEARTBEAT_EVERY};
use crate::numbers;

/// Longest wait for rest after a stop when the command has no `--timeout`, s:
/// from 3000 rpm the simulated board's rotors are at rest about 1 s after the
/// stop; ten times that is a machine that does not stop.
pub const REST_TIMEOUT_S: f64 = 10.0;

/// The status of the machine, asked again and again (each question keeps the
/// link alive).
pub trait Poll {
    /// The latest status.
    fn status(&mut self) -> Result<StatusReport, Failure>;
    /// Let `wait` pass (reading the line meanwhile).
    fn wait(&mut self, wait: Duration) -> Result<(), Failure>;
}

impl Poll for Client {
    fn status(&mut self) -> Result<StatusReport, Failure> {
        match ask(self, &Request::GetStatus)? {
            Response::Status(s) => Ok(s),
            other => Err(unexpected(&Request::GetStatus, &other)),
        }
    }

    fn wait(&mut self, wait: Duration) -> Result<(), Failure> {
        self.pump(wait).map_err(Failure::from)
    }
}

/// Whether the status says the machine is at rest ([module doc](self)).
pub fn at_rest(s: &StatusReport) -> bool {
    may_write_table(s.state, s.telemetry.speed_rpm)
}

/// What the status says of the motion, for messages: `state idle, rotors at
/// 0.0 and 0.0 rpm`.
pub fn motion(s: &StatusReport) -> String {
    format!(
        "state {}, rotors at {} and {} rpm",
        s.state.name(),
        numbers::fixed(f64::from(s.telemetry.speed_rpm[0]), 1),
        numbers::fixed(f64::from(s.telemetry.speed_rpm[1]), 1)
    )
}

/// How the wait for rest ended: the last status, and the seconds waited.
#[derive(Clone, Debug, PartialEq)]
pub struct Rest {
    /// Whether that status is at rest ([`at_rest`]).
    pub reached: bool,
    /// The last status asked.
    pub status: StatusReport,
    /// Seconds from the first question to the last.
    pub after_s: f64,
}

impl Rest {
    /// The outcome for people: `at rest after 0.9 s (state idle, rotors at 9.6
    /// and 9.7 rpm)`, or `not at rest 10.0 s after the stop: state running,
    /// rotors at 3000.0 and 3000.0 rpm`.
    pub fn describe(&self) -> String {
        if self.reached {
            format!(
                "at rest after {:.1} s ({})",
                self.after_s,
                motion(&self.status)
            )
        } else {
            format!(
                "not at rest {:.1} s after the stop: {}",
                self.after_s,
                motion(&self.status)
            )
        }
    }
}

/// Asks the status every [`HEARTBEAT_EVERY`] until the machine is at rest or
/// `timeout_s` has passed; a failed question is the failure.
pub fn await_rest(link: &mut dyn Poll, timeout_s: f64) -> Result<Rest, Failure> {
    let start = Instant::now();
    loop {
        let status = link.status()?;
        let after_s = start.elapsed().as_secs_f64();
        let reached = at_rest(&status);
        if reached || after_s >= timeout_s {
            return Ok(Rest {
                reached,
                status,
                after_s,
            });
        }
        link.wait(HEARTBEAT_EVERY)?;
    }
}

/// The device's uptime the machine must stay at rest before a self-test, s: a
/// rotor that swings as a pendulum (its eccentric under gravity, the platform
/// free) passes below 10 rpm at each turn of its swing, for some milliseconds;
/// on the reference machine half a swing takes about 0.22 s
/// (`pi sqrt(J / (m g e))`, J = 1e-5 kg m^2, m g e = 1.96e-3 N m).
pub const REST_HOLD_S: f64 = 0.5;

/// Asks the status every [`HEARTBEAT_EVERY`] until every status for `hold_s`
/// of the device's uptime has been at rest ([`at_rest`]), or `timeout_s` (the
/// host's clock) has passed; a failed question is the failure. The hold is
/// measured on the device's clock, so a busy host neither shortens nor
/// lengthens it.
pub fn await_steady_rest(
    link: &mut dyn Poll,
    hold_s: f64,
    timeout_s: f64,
) -> Result<Rest, Failure> {
    await_steady(link, hold_s, timeout_s, at_rest)
}

/// [`await_steady_rest`] with `still` in place of [`at_rest`].
pub fn await_steady(
    link: &mut dyn Poll,
    hold_s: f64,
    timeout_s: f64,
    still: fn(&StatusReport) -> bool,
) -> Result<Rest, Failure> {
    let start = Instant::now();
    let mut since: Option<u32> = None;
    loop {
        let status = link.status()?;
        let after_s = start.elapsed().as_secs_f64();
        since = still(&status).then(|| since.unwrap_or(status.uptime_ms));
        let held =
            since.is_some_and(|u0| f64::from(status.uptime_ms.wrapping_sub(u0)) >= hold_s * 1e3);
        if held || after_s >= timeout_s {
            return Ok(Rest {
                reached: held,
                status,
                after_s,
            });
        }
        link.wait(HEARTBEAT_EVERY)?;
    }
}

#[cfg(test)]
mod tests {
    use shared::controller::{Faults, State, Telemetry};
    use shared::protocol::link::no_telemetry;

    use super::*;

    fn status(state: State, rpm: f32) -> StatusReport {
        StatusReport {
            uptime_ms: 0,
            state,
            faults: Faults::NONE,
            telemetry: Telemetry {
                speed_rpm: [rpm, rpm],
                ..no_telemetry()
            },
            rx_dropped: 0,
        }
    }

    /// A machine that ramps down by 1000 rpm a question from `rpm`, or runs on.
    struct Ramp {
        rpm: f32,
        runs_on: bool,
    }

    impl Poll for Ramp {
        fn status(&mut self) -> Result<StatusReport, Failure> {
            if self.runs_on {
                return Ok(status(State::Running, self.rpm));
            }
            self.rpm = (self.rpm - 1000.0).max(0.0);
            let state = if self.rpm > 0.0 {
                State::Stopping
            } else {
                State::Idle
            };
            Ok(status(state, self.rpm))
        }

        fn wait(&mut self, _: Duration) -> Result<(), Failure> {
            Ok(())
        }
    }

    /// An idle machine whose rotor swings (speeds in rpm, one per question, the
    /// last one repeated), the uptime 50 ms on at each question.
    struct Swing {
        rpm: Vec<f32>,
        asked: usize,
    }

    impl Poll for Swing {
        fn status(&mut self) -> Result<StatusReport, Failure> {
            let rpm = self.rpm[self.asked.min(self.rpm.len() - 1)];
            let mut s = status(State::Idle, rpm);
            s.uptime_ms = 50 * self.asked as u32;
            self.asked += 1;
            Ok(s)
        }

        fn wait(&mut self, _: Duration) -> Result<(), Failure> {
            std::thread::sleep(Duration::from_millis(1));
            Ok(())
        }
    }

    #[test]
    fn a_rotor_swinging_through_zero_is_not_at_rest_until_it_stays_there() {
        // Through 0 at every turn of the swing, then still from question 8 on.
        let swing = vec![130.0, 0.0, -130.0, 0.0, 130.0, 5.0, -60.0, 20.0, 0.0];
        let r = await_steady_rest(
            &mut Swing {
                rpm: swing.clone(),
                asked: 0,
            },
            0.5,
            10.0,
        )
        .unwrap();
        assert!(r.reached);
        // At rest from question 8 (400 ms) on: held at 900 ms.
        assert_eq!(r.status.uptime_ms, 900);
        // A machine that swings on is not at rest however often it passes 0.
        let r = await_steady_rest(
            &mut Swing {
                rpm: swing[..8].iter().cycle().take(400).copied().collect(),
                asked: 0,
            },
            0.5,
            0.2,
        )
        .unwrap();
        assert!(!r.reached, "{r:?}");
    }

    #[test]
    fn rest_is_idle_or_fault_with_both_rotors_below_10_rpm() {
        assert!(at_rest(&status(State::Idle, 9.0)));
        assert!(at_rest(&status(State::Fault, 0.0)));
        assert!(!at_rest(&status(State::Idle, 11.0)));
        assert!(!at_rest(&status(State::Stopping, 0.0)));
        assert!(!at_rest(&status(State::Running, 3000.0)));
    }

    #[test]
    fn the_wait_ends_at_rest_or_says_what_the_status_says() {
        let r = await_rest(
            &mut Ramp {
                rpm: 3000.0,
                runs_on: false,
            },
            10.0,
        )
        .unwrap();
        assert!(r.reached);
        assert_eq!(r.status.telemetry.speed_rpm, [0.0, 0.0]);
        assert!(r
            .describe()
            .ends_with("(state idle, rotors at 0.0 and 0.0 rpm)"));
        // A device that acknowledged the stop and runs on.
        let r = await_rest(
            &mut Ramp {
                rpm: 3000.0,
                runs_on: true,
            },
            0.0,
        )
        .unwrap();
        assert!(!r.reached);
        assert!(
            r.describe()
                .ends_with("s after the stop: state running, rotors at 3000.0 and 3000.0 rpm"),
            "{}",
            r.describe()
        );
    }
}
