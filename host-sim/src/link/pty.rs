//! The pseudo-terminal `device-sim` serves: a pair made by the `serialport` crate,
//! the master side the device's end (its UART), the slave side `/dev/pts/N` the
//! end a host opens as it would a serial port. Both sides raw: no byte translated.
//!
//! The slave side is held open here too, so that a host closing it does not hang
//! up the master. The master's writes never wait: what does not fit is dropped, as
//! a UART's transmitter sends whether anyone listens or not (a pseudo-terminal
//! nobody reads fills up).

use std::io::{self, Write};
use std::os::fd::AsRawFd;
use std::time::Duration;

use nix::fcntl::{fcntl, FcntlArg, OFlag};
use serialport::{SerialPort, TTYPort};

use super::serial::read_within;

/// A pseudo-terminal pair.
pub struct Pty {
    /// The master side, non-blocking.
    master: TTYPort,
    /// The slave's path, `/dev/pts/N`.
    path: String,
    /// The slave side, held open.
    _slave: TTYPort,
}

impl Pty {
    /// A new pseudo-terminal, both sides raw.
    pub fn open() -> io::Result<Pty> {
        let (master, slave) = TTYPort::pair()?;
        fcntl(master.as_raw_fd(), FcntlArg::F_SETFL(OFlag::O_NONBLOCK))?;
        let path = slave
            .name()
            .ok_or_else(|| io::Error::other("the pseudo-terminal's slave side has no name"))?;
        Ok(Pty {
            master,
            path,
            _slave: slave,
        })
    }

    /// The slave's path, the `--port` a host opens.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Bytes from the host, waiting at most `timeout` for the first.
    pub fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        read_within(&mut self.master, buf, timeout)
    }

    /// Write what fits now and drop the rest.
    pub fn write_or_drop(&mut self, mut bytes: &[u8]) {
        if self.master.set_timeout(Duration::ZERO).is_err() {
            return;
        }
        while !bytes.is_empty() {
            match self.master.write(bytes) {
                Ok(n) if n > 0 => bytes = &bytes[n..],
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                _ => return,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::port::PortSpec;

    /// Up to `n` bytes from `read` (20 ms a try, a second in all).
    fn gather(n: usize, mut read: impl FnMut(&mut [u8]) -> io::Result<usize>) -> Vec<u8> {
        let mut got = Vec::new();
        let mut buf = [0u8; 16];
        for _ in 0..50 {
            let k = read(&mut buf).unwrap();
            got.extend_from_slice(&buf[..k]);
            if got.len() >= n {
                break;
            }
        }
        got
    }

    #[test]
    fn a_pty_carries_bytes_both_ways_untranslated() {
        let wait = Duration::from_millis(20);
        let mut pty = Pty::open().unwrap();
        let mut host = PortSpec::Serial(pty.path().to_string()).open().unwrap();
        // Raw both ways: no byte translated (CR, LF, ^C, XON, DEL pass through).
        let to_device = [0xA5, 0x5A, 0x00, 0x0A, 0x0D, 0x03, 0x11];
        host.write_all(&to_device).unwrap();
        let got = gather(to_device.len(), |buf| pty.read_timeout(buf, wait));
        assert_eq!(got, to_device);
        let to_host = [0x0D, 0x0A, 0x7F];
        pty.write_or_drop(&to_host);
        let got = gather(to_host.len(), |buf| host.read_timeout(buf, wait));
        assert_eq!(got, to_host);
    }

    #[test]
    fn a_pty_nobody_reads_drops_instead_of_waiting() {
        let mut pty = Pty::open().unwrap();
        let (done, finished) = std::sync::mpsc::channel();
        // Far more than the kernel holds for a reader that never comes, in
        // chunks that do not divide its buffer: one finds room for part of it.
        std::thread::spawn(move || {
            let chunk = [0x55u8; 3000];
            for _ in 0..400 {
                pty.write_or_drop(&chunk);
            }
            let _ = done.send(());
        });
        assert!(
            finished.recv_timeout(Duration::from_secs(10)).is_ok(),
            "a write waited for a reader"
        );
    }
}
