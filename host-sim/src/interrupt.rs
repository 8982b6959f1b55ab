//! SIGINT (Ctrl-C), SIGTERM and SIGHUP (the terminal closed) as a flag: the
//! streaming device commands stop the stream and the motors' heartbeat cleanly
//! instead of dying mid-frame, and a long run, scenario, tune sweep or fit ends at
//! its next control tick (or run) with its files whole and a message naming the
//! signal. The three are handled alike; the command's exit status is 1, as for
//! any run that did not complete ([`crate::failure`]).
//!
//! The handler is `signal-hook`'s flag: it only stores the signal's number into an
//! atomic, which is all a signal handler may safely do. SIGKILL cannot be caught:
//! what it leaves is [`crate::output::file`]'s concern.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Once;

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// The number of the last signal caught, 0 before any.
static CAUGHT: AtomicUsize = AtomicUsize::new(0);

/// The handlers are installed once, however many commands ask.
static CATCH: Once = Once::new();

/// The signals caught, with the name a message gives each.
const SIGNALS: [(i32, &str); 3] = [
    (SIGINT, "SIGINT (Ctrl-C)"),
    (SIGTERM, "SIGTERM"),
    (SIGHUP, "SIGHUP"),
];

/// From now on, SIGINT, SIGTERM and SIGHUP set the flag instead of ending the
/// process.
pub fn catch() {
    CATCH.call_once(|| {
        for (signal, _) in SIGNALS {
            // Fails only for the signals no process may catch; these it may, and
            // without the flag the signal ends the process by its default action.
            let _ = signal_hook::flag::register_usize(signal, &CAUGHT, signal as usize);
        }
    });
}

/// Whether one of the signals arrived since [`catch`].
pub fn interrupted() -> bool {
    CAUGHT.load(Ordering::SeqCst) != 0
}

/// The flag itself, non-zero once a signal arrived since [`catch`]: for a loop
/// that checks it more often than a command does, without knowing of signals
/// (the plant's integrator, [`crate::plant::simulator::Plant::stop_when`]).
pub fn flag() -> &'static AtomicUsize {
    &CAUGHT
}

/// What ended the command, for its message: "interrupted by SIGTERM" (the signal's
/// name), or "interrupted" where none was caught (a test's stand-in operator).
pub fn interruption() -> String {
    describe(CAUGHT.load(Ordering::SeqCst))
}

/// [`interruption`] for signal number `caught` (0: none).
fn describe(caught: usize) -> String {
    match SIGNALS.iter().find(|(s, _)| *s as usize == caught) {
        Some((_, name)) => format!("interrupted by {name}"),
        None => "interrupted".to_string(),
    }
}
