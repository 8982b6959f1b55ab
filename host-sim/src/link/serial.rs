//! A serial port as the device's byte pipe, through the `serialport` crate: opened
//! raw at [`BAUD_RATE`] baud, 8 data bits, no parity, 1 stop bit, no flow
//! control, no byte translated; reads that wait at most a given time.

use std::io::{self, Write};
use std::time::Duration;

use serialport::{ClearBuffer, DataBits, ErrorKind, FlowControl, Parity, SerialPort, StopBits};
use shared::protocol::BAUD_RATE;

use super::pipe::Port;

/// The longest a write may wait for room in the driver's buffer. The largest
/// frame (a 32-row table, under 450 bytes) takes 40 ms at 115200 baud; a port that
/// takes none of it in a second is stuck (the adapter gone, its buffer held).
const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// A serial port (a USB-serial adapter, a pseudo-terminal's slave side).
pub struct SerialLine {
    port: Box<dyn SerialPort>,
}

impl SerialLine {
    /// Open the serial device `path` raw at [`BAUD_RATE`] 8N1, its stale input
    /// dropped; `Err` says what is wrong, for `--port`.
    pub fn open(path: &str) -> Result<SerialLine, String> {
        // A path that is not there, said in the system's words (Windows names its
        // ports COM1.., which are no files).
        #[cfg(unix)]
        std::fs::metadata(path).map_err(|e| format!("{path}: cannot open the serial port: {e}"))?;
        let builder = serialport::new(path, BAUD_RATE)
            .data_bits(DataBits::Eight)
            .parity(Parity::None)
            .stop_bits(StopBits::One)
            .flow_control(FlowControl::None)
            .timeout(WRITE_TIMEOUT);
        // Not locked to this process: a second command on the same port (a `stop`
        // while `telemetry` runs) gets through.
        #[cfg(unix)]
        let builder = builder.exclusive(false);
        let port = builder.open().map_err(|e| match e.kind() {
            ErrorKind::Io(_) | ErrorKind::NoDevice | ErrorKind::InvalidInput => {
                format!("{path}: cannot open the serial port: {e}")
            }
            ErrorKind::Unknown => format!(
                "{path}: cannot set the serial port to {BAUD_RATE} baud 8N1 raw (is it a serial device?): {e}"
            ),
        })?;
        // Bytes that came before we listened belong to no request of ours.
        let _ = port.clear(ClearBuffer::All);
        Ok(SerialLine { port })
    }
}

/// Read what has come on `port`, waiting at most `timeout` for the first byte;
/// `Ok(0)` when nothing came in time (or a signal came).
pub fn read_within(
    port: &mut dyn SerialPort,
    buf: &mut [u8],
    timeout: Duration,
) -> io::Result<usize> {
    port.set_timeout(timeout)?;
    match port.read(buf) {
        Ok(n) => Ok(n),
        Err(e)
            if matches!(
                e.kind(),
                io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
            ) =>
        {
            Ok(0)
        }
        Err(e) => Err(e),
    }
}

impl Port for SerialLine {
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        read_within(self.port.as_mut(), buf, timeout)
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.set_timeout(WRITE_TIMEOUT)?;
        Write::write_all(&mut self.port, bytes)
    }
}
