//! The byte pipe to the device: a serial port (a USB-serial adapter, a
//! pseudo-terminal; [`super::serial`]) opened raw at 115200 baud 8N1, or a TCP
//! socket carrying the same bytes (`tcp:HOST:PORT`, as QEMU's
//! `-serial tcp::PORT,server,nowait` exposes an emulated USART, or as
//! `host-sim device-sim --listen` serves).

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use super::pipe::Port;
use super::serial::SerialLine;

/// How long connecting to a TCP port may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// How `--port` names a device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PortSpec {
    /// A serial device path (`/dev/ttyUSB0`, `/dev/pts/3`).
    Serial(String),
    /// `tcp:HOST:PORT`.
    Tcp(String),
}

impl PortSpec {
    /// `tcp:HOST:PORT` or a path; `Err` says what is wrong and what is allowed.
    pub fn parse(text: &str) -> Result<PortSpec, String> {
        if let Some(addr) = text.strip_prefix("tcp:") {
            let ok = addr
                .rsplit_once(':')
                .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok());
            if !ok {
                return Err(format!(
                    "`{text}` is no TCP address: expected tcp:HOST:PORT, e.g. tcp:127.0.0.1:5555"
                ));
            }
            Ok(PortSpec::Tcp(addr.to_string()))
        } else if text.is_empty() {
            Err("empty: expected a serial device path (e.g. /dev/ttyUSB0) or tcp:HOST:PORT".into())
        } else {
            Ok(PortSpec::Serial(text.to_string()))
        }
    }

    /// Open the port.
    pub fn open(&self) -> Result<Box<dyn Port>, String> {
        match self {
            PortSpec::Tcp(addr) => Ok(Box::new(TcpPort::connect(addr)?)),
            PortSpec::Serial(path) => Ok(Box::new(SerialLine::open(path)?)),
        }
    }
}

/// A TCP connection.
pub struct TcpPort {
    stream: TcpStream,
}

impl TcpPort {
    /// Connect to `HOST:PORT`.
    pub fn connect(addr: &str) -> Result<TcpPort, String> {
        let addrs: Vec<_> = addr
            .to_socket_addrs()
            .map_err(|e| format!("tcp:{addr}: cannot resolve the address: {e}"))?
            .collect();
        let mut last = None;
        for a in addrs {
            match TcpStream::connect_timeout(&a, CONNECT_TIMEOUT) {
                Ok(stream) => {
                    // Frames are small; send each at once.
                    let _ = stream.set_nodelay(true);
                    return Ok(TcpPort { stream });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(match last {
            Some(e) => format!("tcp:{addr}: cannot connect: {e}"),
            None => format!("tcp:{addr}: the address resolves to nothing"),
        })
    }

    /// An accepted connection (the device simulator's side).
    pub fn from_stream(stream: TcpStream) -> TcpPort {
        let _ = stream.set_nodelay(true);
        TcpPort { stream }
    }
}

impl Port for TcpPort {
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        // A zero timeout means "block" to the socket.
        let timeout = timeout.max(Duration::from_millis(1));
        self.stream.set_read_timeout(Some(timeout))?;
        match self.stream.read(buf) {
            Ok(0) => Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "the other end closed the connection",
            )),
            Ok(n) => Ok(n),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(0)
            }
            Err(e) => Err(e),
        }
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        Write::write_all(&mut self.stream, bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn port_specs() {
        assert_eq!(
            PortSpec::parse("tcp:127.0.0.1:5555"),
            Ok(PortSpec::Tcp("127.0.0.1:5555".into()))
        );
        assert_eq!(
            PortSpec::parse("/dev/ttyUSB0"),
            Ok(PortSpec::Serial("/dev/ttyUSB0".into()))
        );
        for bad in ["tcp:", "tcp:host", "tcp::5", "tcp:h:99999", ""] {
            assert!(PortSpec::parse(bad).is_err(), "{bad}");
        }
    }
}
