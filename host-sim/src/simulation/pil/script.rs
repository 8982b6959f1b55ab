//! What the host's end of the firmware's link asks beyond the run's commands: a
//! [`Script`] decides, at every exchange, from the answers received since the
//! last one, the requests to send ([`super::host::Host::ask`]), as `host-sim
//! device` decides its next request from the board's last answer. The
//! identification and the capture of `host-sim run --firmware` are scripts
//! (`run/asks/`).
//!
//! Time here is the simulation's, the firmware's own clock (one control tick a
//! `1 / rate_hz`).

use shared::protocol::Request;

use super::host::Answer;

/// What the host asks of the firmware, exchange by exchange.
pub trait Script {
    /// At the exchange of the control tick at `t`, s, with `answers` received
    /// since the last call, in order: the requests to send now, in order.
    fn step(&mut self, t: f64, answers: &[Answer]) -> Vec<Request>;

    /// Whether the run may end after this tick: the script has what it came
    /// for (the identification's report). `false` by default: the run's own
    /// end time ends it.
    fn ends_run(&self) -> bool {
        false
    }

    /// Why it cannot go on (the firmware refused a request, answered another
    /// thing, or not in time): the run fails at this tick.
    fn failure(&self) -> Option<String>;
}
