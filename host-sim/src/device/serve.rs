//! `host-sim device-sim`: a [`SimDevice`] in real time behind a pseudo-terminal
//! (the default; its path is printed) or a TCP port (`--listen`), for
//! `host-sim device` to talk to without hardware.
//!
//! The loop: read what the host sent (waiting at most a millisecond), run the
//! control ticks due by the wall clock, run the link task, write its frames. A TCP
//! device takes one connection at a time and keeps its state across connections,
//! as a powered board keeps its state while hosts come and go.

use std::io;
use std::net::TcpListener;
use std::time::{Duration, Instant};

use super::args::DeviceSimArgs;
use super::port::{Port, PortSpec, TcpPort};
use super::sim::{Noise, SimDevice};
use crate::failure::{Console, Failure};
use crate::interrupt;
use crate::machine::tuning_file;

/// Ticks the simulator runs at most in one go when it fell behind the clock
/// (a suspended process); beyond that it drops the time.
const MAX_CATCH_UP_TICKS: u64 = 200;

/// Where the simulated device listens.
pub enum Endpoint {
    /// A pseudo-terminal's master side.
    #[cfg(unix)]
    Pty(super::pty::Pty),
    /// A TCP listener and the connection being served.
    Tcp {
        /// The listener (non-blocking).
        listener: TcpListener,
        /// The host connected now.
        conn: Option<TcpPort>,
    },
}

impl Endpoint {
    /// A new pseudo-terminal.
    #[cfg(unix)]
    pub fn pty() -> io::Result<Endpoint> {
        super::pty::Pty::open().map(Endpoint::Pty)
    }

    /// Listen on `addr` (`HOST:PORT`).
    pub fn tcp(addr: &str) -> io::Result<Endpoint> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        Ok(Endpoint::Tcp {
            listener,
            conn: None,
        })
    }

    /// What to give `host-sim device --port`.
    pub fn port_name(&self) -> String {
        match self {
            #[cfg(unix)]
            Endpoint::Pty(p) => p.path().to_string(),
            Endpoint::Tcp { listener, .. } => match listener.local_addr() {
                Ok(a) => format!("tcp:{a}"),
                Err(_) => "tcp:?".into(),
            },
        }
    }

    /// Bytes from the host, waiting at most `timeout`.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> usize {
        match self {
            #[cfg(unix)]
            Endpoint::Pty(p) => p.read_timeout(buf, timeout).unwrap_or(0),
            Endpoint::Tcp { listener, conn } => {
                if conn.is_none() {
                    if let Ok((stream, _)) = listener.accept() {
                        let _ = stream.set_nonblocking(false);
                        *conn = Some(TcpPort::from_stream(stream));
                    } else {
                        std::thread::sleep(timeout);
                        return 0;
                    }
                }
                match conn.as_mut().map(|c| c.read_timeout(buf, timeout)) {
                    Some(Ok(n)) => n,
                    // Closed: wait for the next host.
                    _ => {
                        *conn = None;
                        0
                    }
                }
            }
        }
    }

    /// Bytes to the host (dropped when none is connected, as a UART's).
    fn write(&mut self, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        match self {
            #[cfg(unix)]
            Endpoint::Pty(p) => p.write_or_drop(bytes),
            Endpoint::Tcp { conn, .. } => {
                if let Some(c) = conn {
                    if c.write_all(bytes).is_err() {
                        *conn = None;
                    }
                }
            }
        }
    }
}

/// Run `device` in real time behind `endpoint` while `go()` holds.
pub fn serve(endpoint: &mut Endpoint, device: &mut SimDevice, mut go: impl FnMut() -> bool) {
    let tick = Duration::from_millis(u64::from(device.tick_ms()));
    let mut origin = Instant::now();
    let mut ticks: u64 = 0;
    let mut buf = [0u8; 1024];
    while go() {
        let n = endpoint.read(&mut buf, Duration::from_millis(1));
        device.push_rx(&buf[..n]);
        let mut due = (origin.elapsed().as_nanos() / tick.as_nanos().max(1)) as u64;
        if due > ticks + MAX_CATCH_UP_TICKS {
            // Fell far behind (a suspended process): drop the time.
            let dropped = due - ticks - MAX_CATCH_UP_TICKS;
            origin += tick * u32::try_from(dropped).unwrap_or(u32::MAX);
            due = ticks + MAX_CATCH_UP_TICKS;
        }
        while ticks < due {
            device.tick();
            ticks += 1;
            // The link task runs between ticks, as on the board.
            let out = device.receive();
            endpoint.write(&out);
        }
        let out = device.receive();
        endpoint.write(&out);
    }
}

/// Runs `host-sim device-sim`.
pub fn run(args: &DeviceSimArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    let table = match &args.table {
        None => None,
        Some(path) => Some(tuning_file::read_table(path)?),
    };
    for (flag, v) in [
        ("--flip-every", args.flip_every),
        ("--garbage-every", args.garbage_every),
    ] {
        if v == Some(0) {
            return Err(Failure::Usage(format!(
                "error: {flag}: must be at least 1 (got 0)"
            )));
        }
    }
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            return Err(Failure::Usage(format!(
                "error: --duration: must be a number of seconds above 0 (got {d})"
            )));
        }
    }
    let endpoint = match &args.listen {
        None => open_pty(),
        Some(spec) => match PortSpec::parse(spec) {
            Ok(PortSpec::Tcp(addr)) => Endpoint::tcp(&addr)
                .map_err(|e| format!("error: --listen: cannot listen on {addr}: {e}")),
            _ => {
                return Err(Failure::Usage(format!(
                    "error: --listen: `{spec}` is no TCP address: expected tcp:HOST:PORT, e.g. tcp:127.0.0.1:5555 (port 0: any free port)"
                )))
            }
        },
    };
    // A port in use or not ours to take is the user's to change.
    let mut endpoint = endpoint.map_err(Failure::Usage)?;
    let noise = Noise {
        flip_every: args.flip_every,
        garbage_every: args.garbage_every,
    };
    let mut device = SimDevice::new(table, noise);
    let port = endpoint.port_name();
    // The port first, alone on its line, at once: scripts read it.
    console.print(&format!("port: {port}\n"));
    console.note(&format!(
        "device-sim: the reference controller at {} Hz on simulated rotors, a simulated flash; \
         try `host-sim device --port {port} status`; Ctrl-C ends it\n",
        1000 / device.tick_ms()
    ));
    interrupt::catch();
    let end = args
        .duration
        .map(|d| Instant::now() + Duration::from_secs_f64(d));
    serve(&mut endpoint, &mut device, || {
        !interrupt::interrupted() && end.is_none_or(|e| Instant::now() < e)
    });
    console.note(&format!(
        "device-sim: stopped after {:.1} s of device time\n",
        f64::from(device.uptime_ms()) / 1000.0
    ));
    Ok(())
}

#[cfg(unix)]
fn open_pty() -> Result<Endpoint, String> {
    Endpoint::pty().map_err(|e| format!("error: cannot open a pseudo-terminal: {e}"))
}

#[cfg(not(unix))]
fn open_pty() -> Result<Endpoint, String> {
    Err("error: pseudo-terminals need Unix; use --listen tcp:127.0.0.1:0".into())
}
