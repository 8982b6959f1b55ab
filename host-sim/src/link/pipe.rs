//! The byte pipe every link runs over: a serial line, a TCP socket, a
//! pseudo-terminal.

use std::io;
use std::time::Duration;

/// A byte pipe with a read timeout.
pub trait Port {
    /// Read what has come, waiting at most `timeout` for the first byte; `Ok(0)`
    /// when nothing came in time.
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Write every byte of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
}
