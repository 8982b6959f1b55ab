//! Ctrl-C (SIGINT, and SIGTERM) as a flag: the streaming device commands stop the
//! stream and the motors' heartbeat cleanly instead of dying mid-frame, and a long
//! run, scenario or tune sweep ends at its next control tick with its files whole.
//!
//! The handler is `signal-hook`'s flag: it only stores `true` into an atomic,
//! which is all a signal handler may safely do.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Once;

use signal_hook::consts::{SIGINT, SIGTERM};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// The handlers are installed once, however many commands ask.
static CATCH: Once = Once::new();

/// From now on, Ctrl-C sets the flag instead of ending the process.
pub fn catch() {
    CATCH.call_once(|| {
        for signal in [SIGINT, SIGTERM] {
            // Fails only for the signals no process may catch; these two it may,
            // and without the flag Ctrl-C still ends the process as before.
            let _ = signal_hook::flag::register(signal, &INTERRUPTED);
        }
    });
}

/// Whether Ctrl-C was pressed since [`catch`].
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}
