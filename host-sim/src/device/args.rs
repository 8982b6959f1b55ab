//! The command lines of `host-sim device` and `host-sim device-sim`.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};

use crate::args::Format;
use crate::help::epilogue;
use crate::link::client::DEFAULT_RETRIES;
use crate::sweep::{parse_offsets, parse_speeds, Range};

/// The end of a `device` command's `--help`: its `examples`, and the document.
fn help(examples: &[&str]) -> String {
    epilogue(examples, &[], &["docs/cli-device.md"])
}

/// Arguments of `host-sim device`.
#[derive(Debug, Args)]
#[command(after_help = help(&[
    "host-sim device --port /dev/ttyUSB0 status",
    "host-sim device --port tcp:127.0.0.1:5555 travel right --speed 3000 --for 10",
    "host-sim device --port /dev/ttyUSB0 telemetry --serve",
]))]
pub struct DeviceArgs {
    /// The device: a serial port (`/dev/ttyUSB0`, `/dev/pts/N`), opened raw at
    /// 115200 baud 8N1, or `tcp:HOST:PORT` (a socket carrying the same bytes).
    #[arg(long, value_name = "PORT", global = true)]
    pub port: Option<String>,
    /// Tries of a request after the first, each after its answer timeout (100 ms;
    /// 5 s for a table write).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_RETRIES, global = true)]
    pub retries: u32,
    /// What to ask of the device.
    #[command(subcommand)]
    pub command: DeviceCommand,
}

/// The requests `host-sim device` makes.
#[derive(Debug, Subcommand)]
pub enum DeviceCommand {
    /// State, faults and the latest telemetry.
    #[command(after_help = help(&["host-sim device --port /dev/ttyUSB0 status"]))]
    Status,
    /// Travel right or left: both rotors at `--speed`, the phase offset from the
    /// device's tuning table.
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 travel right --speed 3000 --for 10",
        "host-sim device --port /dev/ttyUSB0 travel left --speed 2800",
    ]))]
    Travel(TravelArgs),
    /// Ramp both rotors down to rest.
    #[command(after_help = help(&["host-sim device --port /dev/ttyUSB0 stop"]))]
    Stop,
    /// Run both rotors at `--speed` and hold the phase offset `--offset`.
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 hold --speed 3000 --offset 90 --for 10",
    ]))]
    Hold(HoldArgs),
    /// Clear the latched faults whose cause is gone.
    #[command(after_help = help(&["host-sim device --port /dev/ttyUSB0 reset"]))]
    Reset,
    /// Stream telemetry (readable lines, or CSV), keeping the link alive with
    /// heartbeats; Ctrl-C ends it.
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 telemetry --count 10",
        "host-sim device --port /dev/ttyUSB0 telemetry --period 20 --duration 5 --csv telemetry.csv",
        "host-sim device --port /dev/ttyUSB0 telemetry --serve",
    ]))]
    Telemetry(TelemetryArgs),
    /// Run the self-test (motors stopped, no fault) and print its result per rotor;
    /// first waits for the rotors at rest for 0.5 s (at most 10 s).
    #[command(after_help = help(&["host-sim device --port /dev/ttyUSB0 self-test"]))]
    SelfTest(SelfTestArgs),
    /// Measure each motor (resistance, torque constant, Coulomb and viscous
    /// friction, the rotor's inertia) with the motors stopped first, one rotor
    /// at a time, and print the values with their standard errors; with
    /// `--machine` beside the file's, with `--write` into a copy of it.
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 identify --machine examples/vibro-driver.toml",
        "host-sim device --port /dev/ttyUSB0 identify --machine examples/vibro-driver.toml --write identified.toml",
    ]))]
    Identify(IdentifyArgs),
    /// Record every control tick of a window on the board (sample, command,
    /// outputs, state) from a trigger and write it as a capture file; with
    /// `--travel` or `--hold` the capture starts that run, stops it after the
    /// window and waits for rest before reading.
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 capture --for 2 --travel right --speed 3000 --out travel.csv",
        "host-sim device --port /dev/ttyUSB0 capture --for 1 --trigger fault --out fault.csv",
    ]))]
    Capture(CaptureArgs),
    /// Read or write the device's tuning table (the file format of `host-sim tune
    /// --write`).
    #[command(subcommand)]
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 table read --out table.toml",
        "host-sim device --port /dev/ttyUSB0 table write examples/vibro-driver.tuning.toml",
    ]))]
    Table(TableCommand),
    /// Sweep speed and offset on the machine: hold each grid point for `--for` S,
    /// ask the operator the distance travelled, append it to a measured file;
    /// `--write` makes the tuning table from it.
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 tune --speeds 3000 --offsets 0:180:30 --for 4 --out measured.csv",
        "host-sim device --port /dev/ttyUSB0 tune --speeds 3000 --offsets 0:180:30 --for 4 --resume measured.csv --write my.tuning.toml",
    ]))]
    Tune(DeviceTuneArgs),
}

/// A travel direction on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DirectionArg {
    /// Towards +x.
    Right,
    /// Towards -x.
    Left,
}

/// Arguments of `host-sim device travel`.
#[derive(Debug, Args)]
pub struct TravelArgs {
    /// Which way.
    #[arg(value_enum, value_name = "right|left")]
    pub direction: DirectionArg,
    /// Rotor speed, rpm (> 0; the device refuses speeds outside its range).
    #[arg(long, value_name = "RPM", allow_negative_numbers = true)]
    pub speed: f32,
    /// Keep the link alive for S seconds (a heartbeat every 50 ms), then stop and
    /// wait until the rotors are at rest (below 10 rpm, at most 10 s), so a
    /// `table write` may follow; Ctrl-C ends the hold early the same way, exit 1.
    /// Without it the command returns at once and the device stops the motors
    /// (fault link_lost) 0.5 s after the last request, unless another command
    /// (`telemetry`) keeps the link alive.
    #[arg(long = "for", value_name = "S", allow_negative_numbers = true)]
    pub for_s: Option<f64>,
}

/// Arguments of `host-sim device hold`.
#[derive(Debug, Args)]
pub struct HoldArgs {
    /// Phase offset to hold, degrees (wrapped to [0, 360)).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub offset: f32,
    /// Rotor speed, rpm (> 0).
    #[arg(long, value_name = "RPM", allow_negative_numbers = true)]
    pub speed: f32,
    /// Keep the link alive for S seconds, then stop and wait for rest (as for
    /// `travel`).
    #[arg(long = "for", value_name = "S", allow_negative_numbers = true)]
    pub for_s: Option<f64>,
}

/// Arguments of `host-sim device telemetry`.
#[derive(Debug, Args)]
pub struct TelemetryArgs {
    /// Stream period, ms (20 to 65535).
    #[arg(long, value_name = "MS", default_value_t = 100)]
    pub period: u16,
    /// Stop after S seconds (default: at Ctrl-C).
    #[arg(
        long,
        value_name = "S",
        allow_negative_numbers = true,
        conflicts_with = "count"
    )]
    pub duration: Option<f64>,
    /// Stop after N frames.
    #[arg(long, value_name = "N")]
    pub count: Option<u64>,
    /// Write CSV (a header, then a row per frame) to FILE, written whole at the
    /// end, or to stdout with `-` instead of the readable lines.
    #[arg(long, value_name = "FILE|-")]
    pub csv: Option<PathBuf>,
    /// Serve a live page of the stream at http://ADDR/ instead of printing it
    /// (default 127.0.0.1:8321; port 0: any free port); its one command is Stop.
    #[arg(
        long,
        value_name = "ADDR",
        num_args = 0..=1,
        default_missing_value = "127.0.0.1:8321",
        conflicts_with_all = ["csv", "count"]
    )]
    pub serve: Option<String>,
    /// Let `--serve` listen on an address other machines can reach.
    #[arg(long, requires = "serve")]
    pub allow_remote: bool,
}

/// Arguments of `host-sim device self-test`.
#[derive(Debug, Args)]
pub struct SelfTestArgs {
    /// Give up when the self-test has not finished after S seconds.
    #[arg(
        long,
        value_name = "S",
        default_value_t = 30.0,
        allow_negative_numbers = true
    )]
    pub timeout: f64,
}

/// Arguments of `host-sim device identify`.
#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// Give up when the identification has not finished after S seconds
    /// (default: above the worst case its own timeouts allow, 60 s a rotor, for
    /// two rotors and the link).
    #[arg(
        long,
        value_name = "S",
        default_value_t = 2.0 * f64::from(shared::controller::identify::WORST_ROTOR_S) + 30.0,
        allow_negative_numbers = true
    )]
    pub timeout: f64,
    /// The machine file the board was built for: its values are printed beside
    /// the measured ones.
    #[arg(long, value_name = "MACHINE.toml")]
    pub machine: Option<PathBuf>,
    /// Write the machine file with the measured motor keys and rotor inertias,
    /// every comment kept (needs `--machine`).
    #[arg(long, value_name = "OUT.toml", requires = "machine")]
    pub write: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}

/// What starts a capture's recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TriggerArg {
    /// The next control tick.
    Now,
    /// The next command other than a heartbeat (a travel, hold, stop, reset),
    /// or a self-test or identification started.
    Command,
    /// The next change of the controller's state.
    State,
    /// The next fault.
    Fault,
}

/// Arguments of `host-sim device capture`.
#[derive(Debug, Args)]
pub struct CaptureArgs {
    /// The window, s: every control tick of it is recorded (at most the
    /// device's buffer, 2.048 s at 1 kHz on the board).
    #[arg(long = "for", value_name = "S", allow_negative_numbers = true)]
    pub for_s: f64,
    /// What starts the recording (default: `command` with `--travel` or
    /// `--hold`, else `now`).
    #[arg(long, value_enum)]
    pub trigger: Option<TriggerArg>,
    /// Start this travel once armed (needs `--speed`).
    #[arg(long, value_enum, value_name = "right|left")]
    pub travel: Option<DirectionArg>,
    /// Start holding this phase offset, degrees, once armed (needs `--speed`).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub hold: Option<f32>,
    /// The rotor speed of `--travel` or `--hold`, rpm.
    #[arg(long, value_name = "RPM", allow_negative_numbers = true)]
    pub speed: Option<f32>,
    /// Give up when the capture is not done S seconds after it was armed.
    #[arg(long, value_name = "S", default_value_t = super::capture::DEFAULT_TIMEOUT_S, allow_negative_numbers = true)]
    pub timeout: f64,
    /// The capture file to write (whole, or not at all).
    #[arg(long, value_name = "FILE.csv")]
    pub out: std::path::PathBuf,
}

/// `host-sim device table ...`.
#[derive(Debug, Subcommand)]
pub enum TableCommand {
    /// Download the tuning table in use (to stdout, or to `--out`).
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 table read",
        "host-sim device --port /dev/ttyUSB0 table read --out table.toml",
    ]))]
    Read {
        /// Write the table file here (whole) instead of stdout.
        #[arg(long, value_name = "FILE.toml")]
        out: Option<PathBuf>,
    },
    /// Upload a tuning table file: stored in the device's flash and used from
    /// then on (motors stopped only).
    #[command(after_help = help(&[
        "host-sim device --port /dev/ttyUSB0 table write examples/vibro-driver.tuning.toml",
    ]))]
    Write {
        /// The tuning table file (as `host-sim tune --write` writes it).
        #[arg(value_name = "FILE.toml")]
        file: PathBuf,
    },
}

/// How `device tune` measures the travel of a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MeasureArg {
    /// Ask the operator for the distance travelled (a line on stdin).
    Prompt,
}

/// Arguments of `host-sim device tune`.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("file").required(true).args(["out", "resume"])))]
pub struct DeviceTuneArgs {
    /// Rotor speeds, rpm: `A:B:STEP` from A to B, both included, or one value.
    #[arg(long, value_name = "A:B:STEP", allow_hyphen_values = true, value_parser = parse_speeds)]
    pub speeds: Range,
    /// Phase offsets, degrees: `A:B:STEP` from A to B, both included (360 is 0
    /// and runs once), or one value.
    #[arg(long, value_name = "A:B:STEP", allow_hyphen_values = true, value_parser = parse_offsets)]
    pub offsets: Range,
    /// Measure each point over S seconds of holding it (velocity = distance / S).
    #[arg(long = "for", value_name = "S", allow_negative_numbers = true)]
    pub for_s: f64,
    /// Seconds to let the gait settle once the offset is held, before the mark.
    #[arg(
        long,
        value_name = "S",
        default_value_t = 2.0,
        allow_negative_numbers = true
    )]
    pub settle: f64,
    /// Give up on a point (stop, exit 1) when its offset is not held S seconds
    /// after the hold was sent, or the rotors not at rest S seconds after the stop.
    #[arg(
        long,
        value_name = "S",
        default_value_t = 10.0,
        allow_negative_numbers = true
    )]
    pub timeout: f64,
    /// How the travel is measured.
    #[arg(long, value_enum, value_name = "prompt", default_value = "prompt")]
    pub measure: MeasureArg,
    /// The measured file to start (it must not exist): a header, then a row per
    /// answer, appended at once.
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// A measured file to continue: its grid points already measured are skipped.
    #[arg(long, value_name = "FILE.csv", conflicts_with = "out")]
    pub resume: Option<PathBuf>,
    /// Make the tuning table from all the file's measurements after the sweep
    /// (the peak fit of `host-sim tune`), written whole.
    #[arg(long, value_name = "TABLE.toml")]
    pub write: Option<PathBuf>,
}

/// Arguments of `host-sim device-sim`.
#[derive(Debug, Args)]
#[command(after_help = help(&[
    "host-sim device-sim",
    "host-sim device-sim --machine examples/vibro-driver.toml --listen tcp:127.0.0.1:5555",
    "host-sim device --port tcp:127.0.0.1:5555 status",
    "host-sim device-sim --machine truth.toml --firmware-machine examples/vibro-driver.toml",
]))]
pub struct DeviceSimArgs {
    /// Listen on `tcp:HOST:PORT` (port 0: any free port) instead of opening a
    /// pseudo-terminal. The first line printed is the `--port` to give
    /// `host-sim device`.
    #[arg(long, value_name = "tcp:HOST:PORT")]
    pub listen: Option<String>,
    /// The machine behind the link: its whole plant (platform, contacts, motors,
    /// sensors, as `host-sim run` simulates it) and its controller parameters and
    /// tuning table, instead of the reference controller on the reference
    /// machine's rotors with the platform held.
    #[arg(long, value_name = "MACHINE.toml")]
    pub machine: Option<PathBuf>,
    /// The machine file the simulated board's firmware was built for: its
    /// controller's constants and tuning table come from it, the plant from
    /// `--machine` (the machine as it really is), as on a bench where the file
    /// is a guess (default: `--machine` itself).
    #[arg(long, value_name = "FILE.toml", requires = "machine")]
    pub firmware_machine: Option<PathBuf>,
    /// Hold the machine's platform (and every other body) still at its start
    /// pose: only the rotors turn, as on a bench with the platform clamped.
    #[arg(long, requires = "machine")]
    pub platform_held: bool,
    /// Stream the platform's true pose to FILE.csv as the device runs: a row
    /// `t,x,y,angle` every 10 ms of uptime, flushed (needs `--machine`).
    #[arg(long, value_name = "FILE.csv", requires = "machine")]
    pub truth: Option<PathBuf>,
    /// The tuning table the device starts with (default: the machine's, else 90
    /// deg right, 270 left at every speed).
    #[arg(long, value_name = "FILE.toml")]
    pub table: Option<PathBuf>,
    /// Corrupt the line: flip one bit of every Nth byte, either way.
    #[arg(long, value_name = "N")]
    pub flip_every: Option<u32>,
    /// Corrupt the line: send garbage before every Nth frame.
    #[arg(long, value_name = "N")]
    pub garbage_every: Option<u32>,
    /// Exit after S seconds (default: at Ctrl-C).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// The simulated board's link timeout, s: while the motors start or run, the
    /// controller stops them (fault link_lost) this long after the last request
    /// (default: the firmware's 0.5 s). Longer for a slow or busy host, whose
    /// next command may come later than 0.5 s after the last.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub link_timeout: Option<f64>,
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::{Cli, Command};

    fn device(args: &[&str]) -> DeviceArgs {
        let mut all = vec!["host-sim", "device"];
        all.extend_from_slice(args);
        match Cli::try_parse_from(all).expect("parses").command {
            Command::Device(a) => a,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_port_goes_before_or_after_the_command() {
        let a = device(&["--port", "/dev/ttyUSB0", "status"]);
        assert_eq!(a.port.as_deref(), Some("/dev/ttyUSB0"));
        let a = device(&["travel", "left", "--speed", "3000", "--port", "tcp:h:1"]);
        assert_eq!(a.port.as_deref(), Some("tcp:h:1"));
        assert_eq!(a.retries, DEFAULT_RETRIES);
        let DeviceCommand::Travel(t) = a.command else {
            panic!("not travel");
        };
        assert_eq!(
            (t.direction, t.speed, t.for_s),
            (DirectionArg::Left, 3000.0, None)
        );
        let a = device(&["--port", "p", "hold", "--offset", "-30", "--speed", "2800"]);
        assert!(
            matches!(a.command, DeviceCommand::Hold(HoldArgs { offset, .. }) if offset == -30.0)
        );
        let a = device(&["--port", "p", "table", "write", "t.toml"]);
        assert!(matches!(
            a.command,
            DeviceCommand::Table(TableCommand::Write { .. })
        ));
    }
}
