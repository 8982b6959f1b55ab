//! Runs that ask for too much are refused with the key and the limit (they used to
//! run forever or fill the memory), and a long run stops cleanly on Ctrl-C with
//! its files whole.

use std::process::Command;
use std::time::{Duration, Instant};

mod common;
use common::{finish_within, host_sim, machine, root, scratch};

/// Long enough for a refusal (milliseconds) on a loaded machine; the defects these
/// tests guard against never end.
const LIMIT: Duration = Duration::from_secs(60);

fn refused(args: &[&str], key: &str, limit: &str) {
    let mut cmd = host_sim();
    cmd.args(args).current_dir(root());
    let r = finish_within(cmd, LIMIT);
    r.refused(key);
    r.refused(limit);
}

#[test]
fn an_endless_run_is_refused_naming_the_key_and_the_limit() {
    let m = machine();
    let m = m.to_str().unwrap();
    refused(
        &["run", m, "--command", "right", "--t-end", "1e300"],
        "--t-end 1e300",
        "at most 3600 s",
    );
    refused(
        &[
            "run",
            m,
            "--command",
            "right",
            "--set",
            "simulation.t_end=1e300",
        ],
        "simulation.t_end",
        "at most 3600 s",
    );
    refused(
        &[
            "tune",
            m,
            "--speeds",
            "3000",
            "--offsets",
            "90",
            "--t-end",
            "1e300",
        ],
        "--t-end",
        "at most 3600 s",
    );
}

#[test]
fn a_trace_step_that_would_fill_the_memory_is_refused() {
    let m = machine();
    refused(
        &[
            "run",
            m.to_str().unwrap(),
            "--command",
            "right",
            "--set",
            "simulation.output_step=1e-300",
        ],
        "simulation.output_step 1e-300",
        "at most 1e7",
    );
}

#[test]
fn an_endless_scenario_is_refused() {
    let file = scratch("cli-limits", "long.toml");
    let machine = machine();
    std::fs::write(
        &file,
        format!(
            "machine = {:?}\nt_end = 1e300\n[[commands]]\nt = 0.0\ncommand = \"right\"\n[[expect]]\nkind = \"no_fault\"\n",
            machine.to_str().unwrap()
        ),
    )
    .unwrap();
    refused(
        &["scenario", file.to_str().unwrap()],
        "long.toml: t_end",
        "at most 3600 s",
    );
}

/// Ctrl-C (SIGINT) in a long run: it ends within seconds, exit 1, saying where it
/// stopped, and the trace file holds whole rows up to there.
#[test]
fn ctrl_c_ends_a_long_run_with_its_files_whole() {
    let out = scratch("cli-limits", "partial.csv");
    let _ = std::fs::remove_file(&out);
    let mut cmd = host_sim();
    cmd.args([
        "run",
        machine().to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        "3600",
        "--out",
        out.to_str().unwrap(),
    ])
    .current_dir(root());
    let started = Instant::now();
    let child_cmd = std::sync::Arc::new(std::sync::Mutex::new(None::<u32>));
    // Interrupt it once it has simulated a while: SIGINT through `kill`, as a
    // terminal's Ctrl-C sends it.
    let pid_slot = child_cmd.clone();
    let interrupter = std::thread::spawn(move || loop {
        std::thread::sleep(Duration::from_millis(100));
        if let Some(pid) = *pid_slot.lock().unwrap() {
            std::thread::sleep(Duration::from_millis(1500));
            let ok = Command::new("kill")
                .args(["-INT", &pid.to_string()])
                .status()
                .is_ok_and(|s| s.success());
            assert!(ok, "kill -INT {pid}");
            return;
        }
    });
    let r = common::finish_within_with(cmd, LIMIT, |pid| {
        *child_cmd.lock().unwrap() = Some(pid);
    });
    interrupter.join().unwrap();
    assert_eq!(r.status, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("interrupted by SIGINT (Ctrl-C) at t = "),
        "{}",
        r.stderr
    );
    assert!(
        r.stdout.is_empty(),
        "no summary of half a run: {}",
        r.stdout
    );
    assert!(started.elapsed() < LIMIT);
    let text = std::fs::read_to_string(&out).expect("the trace was written");
    assert!(text.ends_with('\n'));
    let mut lines = text.lines();
    let columns = lines.next().unwrap().split(',').count();
    let mut n = 0;
    for line in lines {
        assert_eq!(line.split(',').count(), columns, "a cut row: {line}");
        n += 1;
    }
    assert!(n > 10, "{n} rows");
}

/// `tune` checks its output files before the sweep: an unwritable `--write` is
/// refused at once, not after the runs (here one run of an hour, which the
/// refusal must not wait for).
#[test]
fn tune_refuses_an_unwritable_output_before_the_sweep() {
    let m = machine();
    refused(
        &[
            "tune",
            m.to_str().unwrap(),
            "--speeds",
            "3000",
            "--offsets",
            "90",
            "--t-end",
            "3600",
            "--write",
            "no-such-dir/t.toml",
        ],
        "no-such-dir/t.toml",
        "No such file",
    );
}

/// Every input file of every command is read through the one reader: a regular
/// file of at most 4 MiB. `/dev/zero` never ends (it filled the memory at
/// 400 MB/s) and opening a named pipe no one writes to waits for ever: both are
/// refused before they are opened, naming the file; so is a directory and a
/// file past the limit.
#[test]
fn an_input_file_is_a_regular_file_of_bounded_size() {
    let fifo = scratch("cli-limits", "pipe.toml");
    let _ = std::fs::remove_file(&fifo);
    let made = Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    let big = scratch("cli-limits", "big.toml");
    std::fs::write(&big, "#".repeat((4 << 20) + 1)).unwrap();
    let dir = scratch("cli-limits", "a-directory.toml");
    std::fs::create_dir_all(&dir).unwrap();
    let (fifo, big, dir) = (
        fifo.to_str().unwrap(),
        big.to_str().unwrap(),
        dir.to_str().unwrap(),
    );
    let m = machine();
    let m = m.to_str().unwrap();
    let device = "a device, not a regular file";
    let pipe = "a named pipe (FIFO), not a regular file";
    // The first cases end on a reader without these checks too (and fail the
    // test there), before those that would wait or fill the memory.
    let cases: &[(&[&str], &str, &str)] = &[
        (
            &["run", big, "--command", "right"],
            big,
            "too large (4194305 bytes): an input file of this kind has at most 4194304 bytes (4 MiB)",
        ),
        (&["run", dir, "--command", "right"], dir, "a directory, not a regular file"),
        (&["run", fifo, "--command", "right"], fifo, pipe),
        (&["impact", fifo], fifo, pipe),
        (&["tune", fifo], fifo, pipe),
        (
            &["calibrate", m, "--measured", fifo, "--fit", "contacts.*.friction"],
            fifo,
            pipe,
        ),
        (&["run", "/dev/zero", "--command", "right"], "/dev/zero", device),
        (
            &["run", m, "--command", "right", "--set", "controller.tuning_table=/dev/zero"],
            "/dev/zero",
            device,
        ),
        (&["scenario", "/dev/zero"], "/dev/zero", device),
    ];
    for (args, file, why) in cases {
        let mut cmd = host_sim();
        cmd.args(*args).current_dir(root());
        let r = finish_within(cmd, LIMIT);
        r.refused(&format!("error: {file}: cannot read the file: {why}"));
    }
}
