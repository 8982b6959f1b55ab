//! `host-sim device-sim`: a [`SimDevice`] in real time behind a pseudo-terminal
//! (the default; its path is printed) or a TCP port (`--listen`), for
//! `host-sim device` to talk to without hardware; on the reference machine's
//! rotors with the platform held, or on a machine file's whole plant
//! (`--machine`, its platform free or `--platform-held`), its platform's true pose
//! streamed to a file (`--truth`, [`super::truth`]).
//!
//! The loop: read what the host sent (waiting at most a millisecond), run the
//! control ticks due by the wall clock, run the link task, write its frames. A TCP
//! device takes one connection at a time and keeps its state across connections,
//! as a powered board keeps its state while hosts come and go. A loop that falls
//! behind the clock catches up, up to [`MAX_CATCH_UP_TICKS`] at once; beyond that
//! it skips the time and says so ([`Watch::fell_behind`]), so the device's uptime
//! never drifts from the wall clock unnoticed.

use std::io;
use std::net::TcpListener;
use std::time::{Duration, Instant};

use super::args::DeviceSimArgs;
use super::plant::{Platform, PlatformPose};
use super::sim::{Noise, SimDevice};
use super::truth::TruthFile;
use crate::failure::{Console, Failure};
use crate::interrupt;
use crate::link::pipe::Port;
use crate::link::port::{PortSpec, TcpPort};
use crate::machine::{tuning_file, Machine};
use crate::numbers;
use crate::simulation::closed_loop::constants_warning;

/// Ticks the simulator runs at most in one go when it fell behind the clock
/// (a suspended process); beyond that it drops the time.
pub const MAX_CATCH_UP_TICKS: u64 = 200;

/// The longest a write to a TCP host may wait for room: a host that stops
/// reading loses bytes, as on a UART, and never holds up the ticks.
const WRITE_WAIT: Duration = Duration::from_millis(1);

/// Where the simulated device listens.
pub enum Endpoint {
    /// A pseudo-terminal's master side.
    #[cfg(unix)]
    Pty(crate::link::pty::Pty),
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
        crate::link::pty::Pty::open().map(Endpoint::Pty)
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
                        let _ = stream.set_write_timeout(Some(WRITE_WAIT));
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
                    match c.write_all(bytes) {
                        // No room within WRITE_WAIT: the rest is dropped.
                        Err(e)
                            if matches!(
                                e.kind(),
                                io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                            ) => {}
                        Err(_) => *conn = None,
                        Ok(()) => {}
                    }
                }
            }
        }
    }
}

/// What watches a device while it is served.
pub trait Watch {
    /// Whether to go on serving; asked between reads of the port.
    fn go_on(&mut self) -> bool;

    /// After every control tick; `false` ends the serving. Goes on by default.
    fn ticked(&mut self, _device: &SimDevice) -> bool {
        true
    }

    /// Whether the device's clock stands still now: no control tick runs while
    /// the link task still answers, as on a board whose control task a debugger
    /// holds. Asked between reads of the port; the time held is not caught up
    /// after. Never by default (a test's device holds its self-test running
    /// until the test has seen what a second host is told meanwhile).
    fn held(&mut self, _device: &SimDevice) -> bool {
        false
    }

    /// The loop fell more than [`MAX_CATCH_UP_TICKS`] behind the wall clock and
    /// skipped `skipped` of it: the device's uptime lags the clock by that much
    /// more. Nothing by default.
    fn fell_behind(&mut self, _skipped: Duration) {}
}

/// A [`Watch`] that serves while a closure says so.
struct While<F>(F);

impl<F: FnMut() -> bool> Watch for While<F> {
    fn go_on(&mut self) -> bool {
        (self.0)()
    }
}

/// How a device was served: its real-time budget.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Served {
    /// Control ticks run.
    pub ticks: u64,
    /// Wall-clock time served.
    pub wall: Duration,
    /// Wall-clock time spent in the control ticks (the simulated mechanics and
    /// the controller), the link task left out.
    pub busy: Duration,
    /// Wall-clock time skipped because the loop fell too far behind.
    pub skipped: Duration,
}

/// Run `device` in real time behind `endpoint` while `go()` holds.
pub fn serve(endpoint: &mut Endpoint, device: &mut SimDevice, go: impl FnMut() -> bool) -> Served {
    serve_watched(endpoint, device, &mut While(go))
}

/// Run `device` in real time behind `endpoint`, as `watch` says.
pub fn serve_watched(
    endpoint: &mut Endpoint,
    device: &mut SimDevice,
    watch: &mut dyn Watch,
) -> Served {
    let tick = Duration::from_millis(u64::from(device.tick_ms()));
    let start = Instant::now();
    let mut origin = start;
    let mut served = Served::default();
    let mut buf = [0u8; 1024];
    'serving: while watch.go_on() {
        let n = endpoint.read(&mut buf, Duration::from_millis(1));
        device.push_rx(&buf[..n]);
        if watch.held(device) {
            // The clock stands: the ticks due start from here once let go.
            let run = Duration::from_nanos(
                u64::try_from(tick.as_nanos())
                    .unwrap_or(u64::MAX)
                    .saturating_mul(served.ticks),
            );
            origin = Instant::now().checked_sub(run).unwrap_or(origin);
            let out = device.receive();
            endpoint.write(&out);
            continue;
        }
        let mut due = (origin.elapsed().as_nanos() / tick.as_nanos().max(1)) as u64;
        if due > served.ticks + MAX_CATCH_UP_TICKS {
            // Fell far behind (a suspended process, a machine too slow to
            // simulate in real time): skip the time, and say so.
            let dropped = due - served.ticks - MAX_CATCH_UP_TICKS;
            let skipped = tick * u32::try_from(dropped).unwrap_or(u32::MAX);
            origin += skipped;
            served.skipped += skipped;
            watch.fell_behind(skipped);
            due = served.ticks + MAX_CATCH_UP_TICKS;
        }
        while served.ticks < due {
            let busy = Instant::now();
            device.tick();
            served.busy += busy.elapsed();
            served.ticks += 1;
            // The link task runs between ticks, as on the board.
            let out = device.receive();
            endpoint.write(&out);
            if !watch.ticked(device) {
                break 'serving;
            }
        }
        let out = device.receive();
        endpoint.write(&out);
    }
    served.wall = start.elapsed();
    served
}

/// `host-sim device-sim`'s watch: Ctrl-C and `--duration` end it, the truth file
/// takes its rows, falling behind is said on stderr, a plant that stopped
/// advancing ends it (exit 1).
struct DeviceSimWatch<'c, 'w> {
    console: &'c mut Console<'w>,
    end: Option<Instant>,
    truth: Option<TruthFile>,
    /// Why the truth file could not be written on.
    failed: Option<Failure>,
    /// Why the plant stopped advancing, ending the device ([`SimDevice::stopped`]).
    stalled: Option<Failure>,
    /// Device time skipped so far.
    skipped: Duration,
}

impl Watch for DeviceSimWatch<'_, '_> {
    fn go_on(&mut self) -> bool {
        !interrupt::interrupted() && self.end.is_none_or(|e| Instant::now() < e)
    }

    fn ticked(&mut self, device: &SimDevice) -> bool {
        if let Some(why) = device.stopped() {
            self.stalled = Some(Failure::run(format!(
                "device-sim: the machine's plant stopped: {why}"
            )));
            return false;
        }
        let Some(truth) = self.truth.as_mut() else {
            return true;
        };
        match truth.record(u64::from(device.uptime_ms()), device.platform()) {
            Ok(()) => true,
            Err(e) => {
                self.failed = Some(e);
                false
            }
        }
    }

    fn fell_behind(&mut self, skipped: Duration) {
        self.skipped += skipped;
        self.console.note(&format!(
            "device-sim: fell behind the wall clock (the simulation too slow, or the process held up): skipped {:.3} s; the device's uptime now lags the clock by {:.3} s\n",
            skipped.as_secs_f64(),
            self.skipped.as_secs_f64()
        ));
    }
}

/// Whether a machine's control tick is a whole number of milliseconds: the link
/// counts the device's uptime in them.
fn check_whole_ms_tick(machine: &Machine, path: &std::path::Path) -> Result<(), Failure> {
    let rate = machine.controller.rate_hz;
    let tick_ms = 1000.0 / rate;
    if tick_ms.round() >= 1.0 && (tick_ms - tick_ms.round()).abs() <= 1e-9 * tick_ms {
        Ok(())
    } else {
        Err(Failure::usage(format!(
            "{}: controller.rate_hz: device-sim runs control ticks of whole milliseconds of uptime, as the link counts time: 1000 Hz, 500, 250, 200, ... (got {rate})",
            path.display()
        )))
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
            return Err(Failure::usage(format!(
                "{flag}: must be at least 1 (got 0)"
            )));
        }
    }
    // The link timeout goes to the controller as f32 (the firmware's type): it
    // must stay a positive finite number there too (1e-46 would become 0, 1e39
    // infinity).
    let as_f32 = |s: f64| {
        let f = s as f32;
        f.is_finite() && f > 0.0
    };
    for (flag, v, fits) in [
        ("--duration", args.duration, true),
        (
            "--link-timeout",
            args.link_timeout,
            args.link_timeout.is_none_or(as_f32),
        ),
    ] {
        match v {
            Some(s) if !(s.is_finite() && s > 0.0 && fits) => {
                return Err(Failure::usage(format!(
                    "{flag}: must be a number of seconds above 0 (got {})",
                    numbers::sig(s)
                )))
            }
            _ => {}
        }
    }
    // The machine, if any, and its controller, built before any port is opened.
    let noise = Noise {
        flip_every: args.flip_every,
        garbage_every: args.garbage_every,
    };
    let (device, mut what) = match &args.machine {
        None => (
            SimDevice::new(table, noise),
            "the reference controller at 1000 Hz on the reference machine's rotors, its platform held (motors, H-bridges, sensors)".to_string(),
        ),
        Some(path) => {
            let machine = Machine::load(path, &[])?;
            // The firmware's file: the controller's constants and table.
            let (firmware_path, firmware) = match &args.firmware_machine {
                None => (path, machine.clone()),
                Some(f) => (f, Machine::load(f, &[])?),
            };
            check_whole_ms_tick(&firmware, firmware_path)?;
            if let Some(w) = constants_warning(&firmware) {
                console.note(&format!("warning: {}: {w}\n", firmware_path.display()));
            }
            let whose = if args.firmware_machine.is_some() {
                format!("{}'s ", path.display())
            } else {
                "its ".to_string()
            };
            let (platform, plant) = if args.platform_held {
                (
                    Platform::Held,
                    format!("{whose}rotors, the platform held (motors, H-bridges, sensors)"),
                )
            } else {
                (
                    Platform::Free,
                    format!("{whose}whole plant (platform, contacts, motors, sensors)"),
                )
            };
            let bytes = std::fs::read(firmware_path).map_err(|e| {
                Failure::usage(format!("{}: cannot read: {e}", firmware_path.display()))
            })?;
            (
                SimDevice::with_machines(&machine, &firmware, platform, table, noise)?
                    .built_for(&bytes),
                format!(
                    "{}'s controller at {} Hz on {plant}",
                    firmware_path.display(),
                    firmware.controller.rate_hz
                ),
            )
        }
    };
    let mut device = match args.link_timeout {
        None => device,
        Some(s) => {
            what += &format!(", link timeout {} s (--link-timeout)", numbers::sig(s));
            device.with_link_timeout(s as f32)
        }
    };
    let endpoint = match &args.listen {
        None => open_pty(),
        Some(spec) => match PortSpec::parse(spec) {
            Ok(PortSpec::Tcp(addr)) => Endpoint::tcp(&addr)
                .map_err(|e| Failure::usage(format!("--listen: cannot listen on {addr}: {e}"))),
            _ => {
                return Err(Failure::usage(format!(
                    "--listen: `{spec}` is no TCP address: expected tcp:HOST:PORT, e.g. tcp:127.0.0.1:5555 (port 0: any free port)"
                )))
            }
        },
    };
    // A port in use or not ours to take is the user's to change.
    let mut endpoint = endpoint?;
    let truth = match &args.truth {
        None => None,
        Some(path) => Some(TruthFile::create(path)?),
    };
    let port = endpoint.port_name();
    // The port first, alone on its line, at once: scripts read it.
    console.print(&format!("port: {port}\n"));
    console.note(&format!(
        "device-sim: {what}, a simulated flash; \
         try `host-sim device --port {port} status`; Ctrl-C ends it\n"
    ));
    interrupt::catch();
    let start = device.platform();
    let mut watch = DeviceSimWatch {
        console,
        end: args
            .duration
            .map(|d| Instant::now() + Duration::from_secs_f64(d)),
        truth,
        failed: None,
        stalled: None,
        skipped: Duration::ZERO,
    };
    // The truth at power-on, then after every tick.
    watch.ticked(&device);
    let served = serve_watched(&mut endpoint, &mut device, &mut watch);
    // The truth at the last tick, where the stop fell between two rows.
    let mut failed = watch.failed.take();
    let stalled = watch.stalled.take();
    if let (Some(truth), None) = (watch.truth.as_mut(), &failed) {
        failed = truth
            .finish(u64::from(device.uptime_ms()), device.platform())
            .err();
    }
    console.note(&stopped_note(&device, &served, start));
    for w in device.warnings() {
        console.note(&format!("device-sim: warning: {w}\n"));
    }
    match failed.or(stalled) {
        Some(f) => Err(f),
        None => Ok(()),
    }
}

/// The last line on stderr: device time, how fast the simulation ran against the
/// clock, and the platform's travel from `start` if it is free and its motion is
/// a travel (no body through the fundament, none tipped over).
fn stopped_note(device: &SimDevice, served: &Served, start: PlatformPose) -> String {
    let uptime = f64::from(device.uptime_ms()) / 1000.0;
    let mut note = format!("device-sim: stopped after {uptime:.1} s of device time");
    let busy = served.busy.as_secs_f64();
    if busy > 0.0 {
        // Real-time factor: device time per second of wall time the ticks took.
        note += &format!(
            " (the control ticks took {busy:.2} s of it: {:.1}x real time)",
            uptime / busy
        );
    }
    let (a, b) = (start, device.platform());
    if device.platform_mode() == Platform::Held {
        // Nothing travels: the rotors alone turn.
    } else if let Some(why) = device.no_travel() {
        note += &format!("; no travel to report: {why} (see the warnings)");
    } else {
        note += &format!(
            "; the platform travelled {} m (x from {} to {} m)",
            numbers::fixed_signed(b.x - a.x, 4),
            numbers::fixed(a.x, 4),
            numbers::fixed(b.x, 4)
        );
    }
    note + "\n"
}

#[cfg(unix)]
fn open_pty() -> Result<Endpoint, Failure> {
    Endpoint::pty().map_err(|e| Failure::usage(format!("cannot open a pseudo-terminal: {e}")))
}

#[cfg(not(unix))]
fn open_pty() -> Result<Endpoint, Failure> {
    Err(Failure::usage(
        "pseudo-terminals need Unix; use --listen tcp:127.0.0.1:0",
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tcp_host_that_does_not_read_loses_bytes_and_holds_nothing_up() {
        let mut endpoint = Endpoint::tcp("127.0.0.1:0").unwrap();
        let addr = endpoint.port_name().trim_start_matches("tcp:").to_string();
        let host = std::net::TcpStream::connect(&addr).unwrap();
        let mut buf = [0u8; 16];
        while !matches!(&endpoint, Endpoint::Tcp { conn: Some(_), .. }) {
            endpoint.read(&mut buf, Duration::from_millis(1));
        }
        // 32 MB, more than the kernel's buffers hold for a host that never reads
        // (checked below: not all of it arrives).
        let (done, finished) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let chunk = vec![0x55u8; 64 * 1024];
            for _ in 0..512 {
                endpoint.write(&chunk);
            }
            let _ = done.send(matches!(endpoint, Endpoint::Tcp { conn: Some(_), .. }));
        });
        // Each write waits about WRITE_WAIT once the buffers are full (a few ms
        // at the kernel's timer granularity): seconds for the 512 writes, where
        // before they waited for ever.
        let still_connected = finished
            .recv_timeout(Duration::from_secs(30))
            .expect("the writes waited for the host to read");
        assert!(still_connected, "the host was dropped for not reading");
        // Some bytes were dropped: the test filled the buffers.
        let mut host = host;
        host.set_nonblocking(true).unwrap();
        let mut got = 0usize;
        let mut big = vec![0u8; 1 << 20];
        while let Ok(n) = std::io::Read::read(&mut host, &mut big) {
            if n == 0 {
                break;
            }
            got += n;
        }
        assert!(
            got < 512 * 64 * 1024,
            "all {got} bytes arrived: nothing filled"
        );
    }

    /// Holds the loop up once, for `stall`, between two reads once 10 ticks have
    /// run (never inside a catch-up), then serves 300 ticks more.
    struct Stall {
        stall: Duration,
        ticks: u64,
        /// The ticks run when the loop was held up.
        stalled_at: Option<u64>,
        /// The ticks run at the next look between reads after the hold-up.
        after_stall: Option<u64>,
        /// Each skip, with the ticks run before it.
        skipped: Vec<(u64, Duration)>,
    }

    impl Watch for Stall {
        fn go_on(&mut self) -> bool {
            match self.stalled_at {
                None if self.ticks >= 10 => {
                    std::thread::sleep(self.stall);
                    self.stalled_at = Some(self.ticks);
                    true
                }
                None => true,
                Some(at) => {
                    self.after_stall.get_or_insert(self.ticks);
                    self.ticks < at + 300
                }
            }
        }

        fn ticked(&mut self, _device: &SimDevice) -> bool {
            self.ticks += 1;
            true
        }

        fn fell_behind(&mut self, skipped: Duration) {
            self.skipped.push((self.ticks, skipped));
        }
    }

    /// A loop held up for 500 ticks' time catches up 200 ticks at once
    /// ([`MAX_CATCH_UP_TICKS`]) and reports the rest as skipped, never a silent
    /// drift. Nothing here bounds how long the machine took (a loaded machine
    /// may add skips of its own, before or after): the hold-up lasts at least its
    /// 500 ms, so the skip it causes is at least 290 ms (500 less the 200 caught
    /// up, 10 ms for rounding); the next look between reads comes exactly 200
    /// ticks later (the catch-up in one go); and the device's time plus the time
    /// skipped never runs ahead of the wall clock.
    #[test]
    fn falling_behind_is_caught_up_then_reported() {
        let mut endpoint = Endpoint::tcp("127.0.0.1:0").expect("listens");
        let mut device = SimDevice::new(None, Noise::default());
        let mut watch = Stall {
            stall: Duration::from_millis(500),
            ticks: 0,
            stalled_at: None,
            after_stall: None,
            skipped: Vec::new(),
        };
        let served = serve_watched(&mut endpoint, &mut device, &mut watch);
        let skipped: Duration = watch.skipped.iter().map(|(_, s)| *s).sum();
        assert_eq!(served.skipped, skipped);
        let at = watch.stalled_at.expect("held up");
        let (_, after) = watch
            .skipped
            .iter()
            .find(|(ticks, _)| *ticks == at)
            .unwrap_or_else(|| panic!("no skip after the hold-up: {:?}", watch.skipped));
        assert!(*after >= Duration::from_millis(290), "{:?}", watch.skipped);
        assert_eq!(
            watch.after_stall,
            Some(at + MAX_CATCH_UP_TICKS),
            "{:?}",
            watch.skipped
        );
        let tick = Duration::from_millis(u64::from(device.tick_ms()));
        let device_time = tick * u32::try_from(served.ticks).unwrap();
        assert!(device_time + skipped <= served.wall, "{served:?}");
    }
}
