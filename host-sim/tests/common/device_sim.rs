//! A `host-sim device-sim` this test started, talked to with `host-sim device`,
//! and the truth file it streams (`--truth`: `t,x,y,angle` of the platform).

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, Stdio};
use std::thread::JoinHandle;

use super::Run;

fn host_sim(args: &[&str]) -> Run {
    let mut cmd = super::host_sim();
    cmd.args(args).stdin(Stdio::null());
    super::finish(cmd)
}

/// The link timeout of the device-sims the tests start, s, unless a test names
/// its own (`--link-timeout 0.5`, the firmware's, where the test is about it):
/// a test hands the link from one `host-sim device` process to the next (a
/// `travel` returns at once, the next command keeps the link), and on a loaded
/// machine a process may start later than the firmware's 0.5 s after the last
/// request. Five minutes is a hang, not a slow start.
pub const LINK_TIMEOUT_S: &str = "300";

/// How long the device-sims the tests start run at most, s, unless a test names
/// its own `--duration`: each is killed by its handle when its test ends, so
/// this only ends one whose test was killed; ten minutes is no test's wait.
pub const LIFETIME_S: &str = "600";

/// A `host-sim device-sim` process this test started, killed by its handle if
/// the test ends early.
pub struct DeviceSim {
    child: Child,
    /// Its port, as `--port` takes it.
    pub port: String,
    stderr: Option<JoinHandle<String>>,
}

impl DeviceSim {
    /// `host-sim device-sim --listen tcp:127.0.0.1:0 args...`, its port read.
    pub fn start(args: &[&str]) -> DeviceSim {
        let mut all = vec!["--listen", "tcp:127.0.0.1:0"];
        all.extend_from_slice(args);
        DeviceSim::spawn(&all)
    }

    /// `host-sim device-sim args...` behind a pseudo-terminal (`/dev/pts/N`), its
    /// port read.
    pub fn start_pty(args: &[&str]) -> DeviceSim {
        DeviceSim::spawn(args)
    }

    /// `host-sim device-sim args...`, its port read from its first line; with
    /// `--link-timeout` [`LINK_TIMEOUT_S`] and `--duration` [`LIFETIME_S`]
    /// unless `args` name them.
    fn spawn(args: &[&str]) -> DeviceSim {
        let mut cmd = super::host_sim();
        cmd.arg("device-sim").args(args);
        for (flag, default) in [
            ("--link-timeout", LINK_TIMEOUT_S),
            ("--duration", LIFETIME_S),
        ] {
            if !args.contains(&flag) {
                cmd.args([flag, default]);
            }
        }
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("device-sim runs");
        let mut err = child.stderr.take().expect("piped");
        let stderr = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = err.read_to_string(&mut s);
            s
        });
        let mut first = String::new();
        BufReader::new(child.stdout.take().expect("piped"))
            .read_line(&mut first)
            .expect("the port line");
        let port = first
            .trim()
            .strip_prefix("port: ")
            .unwrap_or_else(|| panic!("first line {first:?}"))
            .to_string();
        DeviceSim {
            child,
            port,
            stderr: Some(stderr),
        }
    }

    /// `host-sim device --port PORT args...`, which must succeed.
    pub fn device(&self, args: &[&str]) -> String {
        let mut all = vec!["device", "--port", &self.port];
        all.extend_from_slice(args);
        let r = host_sim(&all);
        assert_eq!(r.status, 0, "{args:?}: {}{}", r.stdout, r.stderr);
        r.stdout
    }

    /// The device's uptime, s, from `status`.
    pub fn uptime(&self) -> f64 {
        let status = self.device(&["status"]);
        let line = status
            .lines()
            .find(|l| l.starts_with("uptime"))
            .unwrap_or_else(|| panic!("{status}"));
        line.trim_start_matches("uptime")
            .trim()
            .trim_end_matches(" s")
            .parse()
            .unwrap_or_else(|e| panic!("{line}: {e}"))
    }

    /// The board dies: its process killed (the link lost at once).
    pub fn kill(&mut self) {
        let _ = self.child.kill();
    }

    /// Ctrl-C to the process this test started, by its id; its exit status and
    /// stderr.
    pub fn interrupt(mut self) -> (i32, String) {
        let pid = nix::unistd::Pid::from_raw(i32::try_from(self.child.id()).unwrap());
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
        let status = self.child.wait().expect("ends");
        let stderr = self.stderr.take().unwrap().join().unwrap();
        (status.code().unwrap_or(-1), stderr)
    }
}

impl Drop for DeviceSim {
    fn drop(&mut self) {
        if self.stderr.is_some() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The truth file's rows `(t, x, y, angle)` so far, the header checked.
pub fn truth_rows(path: &Path) -> Vec<[f64; 4]> {
    let text = std::fs::read_to_string(path).expect("the truth file");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,x,y,angle"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|f| f.parse().expect(l)).collect();
            assert_eq!(v.len(), 4, "{l}");
            [v[0], v[1], v[2], v[3]]
        })
        .collect()
}

/// `x` at the last row at or before `t`.
pub fn x_at(rows: &[[f64; 4]], t: f64) -> f64 {
    rows.iter()
        .take_while(|r| r[0] <= t)
        .last()
        .unwrap_or_else(|| panic!("no row by {t} s"))[1]
}
