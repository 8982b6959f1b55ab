//! The byte pipe to the device: a serial port (a USB-serial adapter, a
//! pseudo-terminal) opened raw at [`BAUD_RATE`] 8N1, or a TCP socket carrying the
//! same bytes (`tcp:HOST:PORT`, as QEMU's `-serial tcp::PORT,server,nowait`
//! exposes an emulated USART, or as `host-sim device-sim --listen` serves).

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use shared::protocol::BAUD_RATE;

/// How long connecting to a TCP port may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// A byte pipe with a read timeout.
pub trait Port {
    /// Read what has come, waiting at most `timeout` for the first byte; `Ok(0)`
    /// when nothing came in time.
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Write every byte of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
}

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
            PortSpec::Serial(path) => open_serial(path),
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

#[cfg(unix)]
fn open_serial(path: &str) -> Result<Box<dyn Port>, String> {
    Ok(Box::new(unix::FdPort::open_serial(path, BAUD_RATE)?))
}

#[cfg(not(unix))]
fn open_serial(path: &str) -> Result<Box<dyn Port>, String> {
    let _ = BAUD_RATE;
    Err(format!(
        "{path}: serial ports are supported on Unix only here; use tcp:HOST:PORT"
    ))
}

/// File descriptors: serial ports through termios, pseudo-terminals, `poll`.
#[cfg(unix)]
pub mod unix {
    use std::ffi::CStr;
    use std::fs::{File, OpenOptions};
    use std::io::{self, Read, Write};
    use std::os::fd::{AsRawFd, RawFd};
    use std::os::unix::fs::OpenOptionsExt;
    use std::time::Duration;

    use super::Port;

    /// A serial port or a pseudo-terminal's master side.
    pub struct FdPort {
        file: File,
    }

    /// The termios speed constant of `baud`.
    fn speed(baud: u32) -> Option<libc::speed_t> {
        Some(match baud {
            9_600 => libc::B9600,
            19_200 => libc::B19200,
            38_400 => libc::B38400,
            57_600 => libc::B57600,
            115_200 => libc::B115200,
            230_400 => libc::B230400,
            _ => return None,
        })
    }

    /// Put the terminal `fd` in raw mode: 8 data bits, no parity, 1 stop bit, no
    /// echo, no line editing, no flow control, no translation of any byte; at
    /// `baud` if given (a pseudo-terminal ignores the speed).
    pub fn make_raw(fd: RawFd, baud: Option<u32>) -> io::Result<()> {
        // SAFETY: `termios` is plain data, filled by tcgetattr before use; `fd` is
        // an open descriptor owned by the caller.
        unsafe {
            let mut t: libc::termios = std::mem::zeroed();
            if libc::tcgetattr(fd, &mut t) != 0 {
                return Err(io::Error::last_os_error());
            }
            libc::cfmakeraw(&mut t);
            t.c_cflag &= !(libc::CSTOPB | libc::PARENB | libc::CRTSCTS | libc::CSIZE);
            t.c_cflag |= libc::CS8 | libc::CLOCAL | libc::CREAD;
            t.c_iflag &= !(libc::IXON | libc::IXOFF | libc::IXANY);
            t.c_cc[libc::VMIN] = 0;
            t.c_cc[libc::VTIME] = 0;
            if let Some(baud) = baud {
                let s = speed(baud).ok_or_else(|| {
                    io::Error::new(io::ErrorKind::InvalidInput, "unsupported baud rate")
                })?;
                if libc::cfsetispeed(&mut t, s) != 0 || libc::cfsetospeed(&mut t, s) != 0 {
                    return Err(io::Error::last_os_error());
                }
            }
            if libc::tcsetattr(fd, libc::TCSANOW, &t) != 0 {
                return Err(io::Error::last_os_error());
            }
        }
        Ok(())
    }

    /// Wait up to `timeout` until `fd` is readable; `false` on timeout or on a
    /// signal (the caller checks its interrupt flag).
    pub fn wait_readable(fd: RawFd, timeout: Duration) -> io::Result<bool> {
        let mut p = libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
        // SAFETY: one valid pollfd.
        let r = unsafe { libc::poll(&mut p, 1, ms) };
        if r < 0 {
            let e = io::Error::last_os_error();
            return if e.kind() == io::ErrorKind::Interrupted {
                Ok(false)
            } else {
                Err(e)
            };
        }
        Ok(r > 0)
    }

    impl FdPort {
        /// Open the serial device `path` raw at `baud` 8N1.
        pub fn open_serial(path: &str, baud: u32) -> Result<FdPort, String> {
            let file = OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
                .open(path)
                .map_err(|e| format!("{path}: cannot open the serial port: {e}"))?;
            make_raw(file.as_raw_fd(), Some(baud)).map_err(|e| {
                format!("{path}: cannot set the serial port to {baud} baud 8N1 raw (is it a serial device?): {e}")
            })?;
            // SAFETY: the descriptor is open; flushing drops stale input only.
            unsafe {
                libc::tcflush(file.as_raw_fd(), libc::TCIOFLUSH);
            }
            Ok(FdPort { file })
        }

        /// A port on an already open, non-blocking descriptor.
        pub fn from_file(file: File) -> FdPort {
            FdPort { file }
        }

        /// Write what fits now and drop the rest, as a UART's transmitter sends
        /// whether anyone listens or not (a pseudo-terminal nobody reads fills up).
        pub fn write_or_drop(&mut self, mut bytes: &[u8]) {
            while !bytes.is_empty() {
                match self.file.write(bytes) {
                    Ok(n) if n > 0 => bytes = &bytes[n..],
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    _ => return,
                }
            }
        }

        /// The descriptor.
        pub fn fd(&self) -> RawFd {
            self.file.as_raw_fd()
        }
    }

    impl Port for FdPort {
        fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
            if !wait_readable(self.fd(), timeout)? {
                return Ok(0);
            }
            match self.file.read(buf) {
                Ok(n) => Ok(n),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
                    ) =>
                {
                    Ok(0)
                }
                Err(e) => Err(e),
            }
        }

        fn write_all(&mut self, mut bytes: &[u8]) -> io::Result<()> {
            // Non-blocking: wait for room when the driver's buffer is full.
            while !bytes.is_empty() {
                match self.file.write(bytes) {
                    Ok(0) => return Err(io::Error::from(io::ErrorKind::WriteZero)),
                    Ok(n) => bytes = &bytes[n..],
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                        let mut p = libc::pollfd {
                            fd: self.fd(),
                            events: libc::POLLOUT,
                            revents: 0,
                        };
                        // SAFETY: one valid pollfd.
                        unsafe { libc::poll(&mut p, 1, 100) };
                    }
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e),
                }
            }
            Ok(())
        }
    }

    /// A pseudo-terminal: the master side (the device's end) and the path of the
    /// slave side (the end a host opens like a serial port), which is kept open
    /// here too so that a host closing it does not hang up the master.
    pub struct Pty {
        /// The master side.
        pub master: FdPort,
        /// The slave's path, `/dev/pts/N`.
        pub path: String,
        /// The slave side, held open.
        _slave: File,
    }

    /// Open a new pseudo-terminal, both sides raw.
    pub fn open_pty() -> io::Result<Pty> {
        // SAFETY: posix_openpt returns a new descriptor or -1; the File takes
        // ownership of it at once. ptsname_r writes a NUL-terminated path into the
        // buffer of the length given.
        unsafe {
            let fd = libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY | libc::O_NONBLOCK);
            if fd < 0 {
                return Err(io::Error::last_os_error());
            }
            let master = <File as std::os::fd::FromRawFd>::from_raw_fd(fd);
            if libc::grantpt(fd) != 0 || libc::unlockpt(fd) != 0 {
                return Err(io::Error::last_os_error());
            }
            let mut name = [0 as libc::c_char; 128];
            if libc::ptsname_r(fd, name.as_mut_ptr(), name.len()) != 0 {
                return Err(io::Error::last_os_error());
            }
            let path = CStr::from_ptr(name.as_ptr()).to_string_lossy().into_owned();
            let slave = OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
                .open(&path)?;
            make_raw(slave.as_raw_fd(), None)?;
            make_raw(fd, None)?;
            Ok(Pty {
                master: FdPort::from_file(master),
                path,
                _slave: slave,
            })
        }
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

    #[cfg(unix)]
    #[test]
    fn a_pty_carries_bytes_both_ways() {
        let mut pty = unix::open_pty().unwrap();
        let mut host = PortSpec::Serial(pty.path.clone()).open().unwrap();
        host.write_all(&[0xA5, 0x5A, 0x00, 0x0A, 0x0D, 0x03, 0x11])
            .unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 16];
        for _ in 0..50 {
            let n = pty
                .master
                .read_timeout(&mut buf, Duration::from_millis(20))
                .unwrap();
            got.extend_from_slice(&buf[..n]);
            if got.len() >= 7 {
                break;
            }
        }
        // Raw: no byte translated (CR, LF, ^C, XON pass through).
        assert_eq!(got, [0xA5, 0x5A, 0x00, 0x0A, 0x0D, 0x03, 0x11]);
        pty.master.write_all(&[0x0D, 0x0A, 0x7F]).unwrap();
        let mut got = Vec::new();
        for _ in 0..50 {
            let n = host
                .read_timeout(&mut buf, Duration::from_millis(20))
                .unwrap();
            got.extend_from_slice(&buf[..n]);
            if got.len() >= 3 {
                break;
            }
        }
        assert_eq!(got, [0x0D, 0x0A, 0x7F]);
    }
}
