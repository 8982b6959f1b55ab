//! The commands the README and the docs show run as written on the shipped files,
//! and the shipped tuning table is what its own header's command writes. (The
//! transcripts of the other blocks, `$ host-sim ...` and its output, are run and
//! compared by `documented_transcripts.rs`; both find the blocks with
//! `common::docs`.)
//!
//! **Which blocks.** Every fenced block tagged `sh`, `bash` or `shell` in
//! `README.md` and `docs/*.md` is exactly one of:
//!
//! - listed in [`NOT_RUN`], with the reason (a board, a cluster, a CI gate that
//!   runs it), found by a piece of its text; an entry that finds no block, or
//!   finds two, fails the test;
//! - the regeneration of the shipped tuning table (docs/tuning.md, "The
//!   reference table"): its command must be the table header's with `--plot FILE`
//!   added, and [`the_shipped_tuning_table_is_what_its_header_command_writes`]
//!   runs that;
//! - run: the whole block by `bash -e -o pipefail`, in a scratch copy of
//!   `examples/` and `scripts/` (nothing in the repository is written), with the
//!   `host-sim` under test first on `PATH`; it must exit 0. A command of a run
//!   block that the rules below do not know fails the test: a new command in
//!   the docs is run or listed, never skipped.
//!
//! **What differs from the docs' text**, command by command (logical lines, `\`
//! continuations joined):
//!
//! - `cargo run --release -p host-sim --` is `host-sim`: the binary under test,
//!   built from the same source;
//! - `firmware/target/thumbv7em-none-eabihf/release/pil` is that ELF in the
//!   repository (the CI step `test` builds it before the tests; without it or
//!   QEMU, outside CI, the block is skipped and the report says so);
//! - placeholders: `my-machine.toml` is a copy of `examples/vibro-driver.toml`
//!   (its tuning table beside it) in the scratch directory; `/dev/ttyUSB0` is a
//!   `host-sim device-sim --machine my-machine.toml --truth truth.csv` this test
//!   starts (its TCP port); `travel.csv` is a measured travel file of three rows
//!   (3000 rpm at 60, 90 and 120 degrees, the speeds `tune` finds there), while
//!   `measured.csv` is what the README's `device tune` measures;
//! - short times, only where the command gives none: `run --t-end 0.5` (not
//!   `run --identify`, which ends with the firmware's identification, 17.7 s of
//!   simulated time in about 2 s); `tune
//!   --speeds 3000 --offsets 0:360:90`; `tune` and `calibrate` `--t-end 4` and
//!   `--set simulation.rtol=1e-3` (the same table as the default tolerance on the
//!   reference machine, docs/tuning.md, "A faster sweep"), but not `calibrate
//!   --capture` (its replays are as long as the capture, which takes neither). `T = 4` holds every
//!   offset from `T/2` on: the reference machine holds each by 1.18 s at the
//!   latest at 2500 to 3500 rpm (docs/tuning.md, "Defaults and why"), and the
//!   test checks it of every run: a block that runs `tune` or `calibrate` must
//!   say of no run that its offset was `not held` or that it was `not a travel`
//!   (`no travel`), so its numbers are its sweep's, not a shortened run's; `device travel`,
//!   `hold`, `tune` and `capture`: `--for 0.5` whatever the docs say, and `device tune
//!   --settle 0.2`; `replay` as it is; `device telemetry` without `--count` or `--duration` gets
//!   `--duration 2`, standing for the operator's Ctrl-C;
//! - `device tune` asks the operator how far the platform went: this test
//!   answers from the device-sim's truth file, the platform's travel between
//!   the `mark:` and the `end:` line, in mm.
//!
//! Cost (2026-11-28, the 2-core VM, test profile): about 3 minutes of CPU for
//! both tests: the tuning table's regeneration (190 runs of 5 s) about one, the
//! three calibrations (about 75 evaluations each) most of the rest; the device
//! commands run in real time (about 25 s).

#![cfg(unix)]

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod common;
use common::device_sim::{truth_rows, DeviceSim};
use common::docs::{self, Block};

/// The processor in the loop's ELF as the docs name it (relative to the
/// repository's root); run with the one built there.
const PIL_ELF: &str = "firmware/target/thumbv7em-none-eabihf/release/pil";

/// Blocks not run here: (file, a piece of the block's text, why).
const NOT_RUN: &[(&str, &str, &str)] = &[
    (
        "docs/pil.md",
        "--features pil --bin pil && cd ..",
        "the firmware's binary `pil`: the CI step `test` builds it first",
    ),
    (
        "docs/pil.md",
        "-semihosting-config enable=on,target=native -icount shift=0,sleep=off -kernel firmware.elf",
        "the command host-sim itself starts in its temporary directory, with the named pipes it makes there",
    ),
    (
        "README.md",
        "scripts/test-all.sh",
        "the CI gates themselves: `run_main` runs scripts/run.sh, CI runs scripts/test-all.sh",
    ),
    (
        "README.md",
        "cargo install --locked probe-rs-tools",
        "installs the flasher (about 5 minutes from crates.io), which needs a debug probe and a board",
    ),
    (
        "README.md",
        "cd firmware && cargo run --release",
        "flashes a board through a debug probe",
    ),
    (
        "README.md",
        "VIBRO_MACHINE=/path/to/my-machine.toml cargo run",
        "flashes a board through a debug probe",
    ),
    (
        "docs/cli-device.md",
        "--bin qemu-uart",
        "the firmware in QEMU: the gate `firmware_qemu_device` (scripts/firmware-qemu-device.sh) runs these commands",
    ),
    (
        "docs/development.md",
        "stress-ng --cpu 2 --timeout 0 &",
        "the whole CI three times with both cores kept busy (about an hour): run by hand before a change to timing, as the section says",
    ),
    (
        "docs/development.md",
        "VIBRO_FUZZ_ITERS=10000000",
        "a long fuzzing campaign: `cargo test` runs the same fuzzers with their default counts",
    ),
    (
        "docs/development.md",
        "cd firmware && cargo build --release\n",
        "the firmware's build: the gate `firmware_build`",
    ),
    (
        "docs/development.md",
        "cd firmware && cargo run --release\n",
        "flashes a board through a debug probe",
    ),
    (
        "docs/firmware-qemu.md",
        "bash scripts/firmware-qemu.sh",
        "the gate `firmware_qemu`",
    ),
    (
        "docs/firmware-qemu.md",
        "timeout 60 qemu-system-arm",
        "what scripts/firmware-qemu.sh runs, after building the firmware: the gate `firmware_qemu`",
    ),
    (
        "docs/firmware-qemu.md",
        "bash scripts/firmware-qemu-device.sh",
        "the gate `firmware_qemu_device`",
    ),
    (
        "docs/firmware.md",
        "VIBRO_TUNING=/path/to/my.tuning.toml",
        "the firmware's build for a machine, then flashing a board",
    ),
    (
        "docs/firmware.md",
        "VIBRO_MACHINE=../tests/fixtures/one-rotor-machine.toml cargo build",
        "the firmware's build: the gate `firmware_clippy` builds the one-rotor machine's",
    ),
    (
        "docs/paper-fig8.md",
        "python3 scripts/paper-fig8-sweep.py",
        "a 9-minute sweep; the gate `scripts` checks that it parses and refuses a bad argument",
    ),
    (
        "docs/scale-out.md",
        "deploy/slurm/submit.sh 8",
        "needs Slurm: the gate `slurm` (scripts/slurm-check.sh) submits the same scripts to a one-node Slurm",
    ),
    (
        "docs/scale-out.md",
        "JOB_COMPLETION_INDEX",
        "runs in a Kubernetes pod, the machine file mounted at /machine and the parts at /parts",
    ),
    (
        "docs/scale-out.md",
        "kubectl create configmap",
        "needs a Kubernetes cluster",
    ),
];

/// The shipped tuning table, relative to the repository's root.
const TABLE: &str = "examples/vibro-driver.tuning.toml";

/// The shell blocks of README.md and docs/*.md, in file order.
fn shell_blocks() -> Vec<Block> {
    docs::blocks().into_iter().filter(Block::is_shell).collect()
}

/// The block's lines with `\` continuations joined.
fn logical_lines(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut current = String::new();
    for line in text.lines() {
        let piece = if current.is_empty() {
            line
        } else {
            line.trim_start()
        };
        match piece.strip_suffix('\\') {
            Some(head) => {
                current.push_str(head.trim_end());
                current.push(' ');
            }
            None => {
                current.push_str(piece);
                out.push(std::mem::take(&mut current));
            }
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Where `host-sim` starts as a command in `line` (not as a part of a path).
fn command_start(line: &str) -> Option<usize> {
    line.match_indices("host-sim ").map(|(i, _)| i).find(|&i| {
        i == 0
            || line[..i]
                .chars()
                .last()
                .is_some_and(|c| c.is_whitespace() || ";&|(".contains(c))
    })
}

/// A command's words and what follows it on its line (`&`, `&&`, `|`, `;`, a
/// comment), from `host-sim` on.
fn split_command(rest: &str) -> (Vec<String>, String) {
    let words: Vec<&str> = rest.split_whitespace().collect();
    let end = words
        .iter()
        .position(|w| ["&", "&&", "|", "||", ";"].contains(w) || w.starts_with('#'))
        .unwrap_or(words.len());
    for w in &words[..end] {
        for q in ['\'', '"'] {
            assert!(
                !w.starts_with(q) || (w.len() > 1 && w.ends_with(q)),
                "a quoted word with spaces in `{rest}`: this test splits words at spaces"
            );
        }
    }
    let command = words[..end].iter().map(|w| w.to_string()).collect();
    (command, words[end..].join(" "))
}

fn has(words: &[String], option: &str) -> bool {
    words
        .iter()
        .any(|w| w == option || w.starts_with(&format!("{option}=")))
}

/// `host-sim ARGS...` as this test runs it (the rules of the module's doc), or
/// why it cannot.
fn shorten(mut words: Vec<String>) -> Result<Vec<String>, String> {
    let add = |words: &mut Vec<String>, option: &str, value: &str| {
        if !has(words, option) {
            words.extend([option.to_string(), value.to_string()]);
        }
    };
    let sets_rtol = |words: &[String]| {
        words
            .windows(2)
            .any(|w| w[0] == "--set" && w[1].trim_matches('\'').starts_with("simulation.rtol="))
    };
    match words.get(1).map(String::as_str) {
        Some("run") if has(&words, "--identify") => {}
        Some("run") => add(&mut words, "--t-end", "0.5"),
        Some("calibrate") if has(&words, "--capture") => {}
        Some(sub @ ("tune" | "calibrate")) => {
            if sub == "tune" {
                add(&mut words, "--speeds", "3000");
                add(&mut words, "--offsets", "0:360:90");
            }
            add(&mut words, "--t-end", "4");
            if !sets_rtol(&words) {
                words.extend(["--set".into(), "simulation.rtol=1e-3".into()]);
            }
        }
        Some("merge" | "impact" | "scenario" | "replay") => {}
        Some("device") => {
            let known = [
                "status",
                "travel",
                "hold",
                "stop",
                "reset",
                "telemetry",
                "self-test",
                "identify",
                "capture",
                "table",
                "tune",
            ];
            let sub = words
                .iter()
                .skip(2)
                .find(|w| known.contains(&w.as_str()))
                .ok_or("a device command this test does not know")?
                .clone();
            if let Some(i) = words.iter().position(|w| w == "--for") {
                words[i + 1] = "0.5".into();
            }
            match sub.as_str() {
                "tune" => add(&mut words, "--settle", "0.2"),
                "telemetry" if has(&words, "--serve") => {
                    return Err("`telemetry --serve` runs until Ctrl-C".into())
                }
                "telemetry" if !has(&words, "--count") => add(&mut words, "--duration", "2"),
                _ => {}
            }
        }
        _ => return Err("a command this test does not know how to run".into()),
    }
    Ok(words)
}

/// A block's script as this test runs it: every `host-sim` command shortened,
/// the board's port in place of `/dev/ttyUSB0`.
fn script(block: &Block, port: Option<&str>) -> String {
    let mut out = String::new();
    for line in logical_lines(&block.text) {
        let mut line = line.replace("cargo run --release -p host-sim -- ", "host-sim ");
        if let Some(port) = port {
            line = line.replace("/dev/ttyUSB0", port);
        }
        if let Some(at) = command_start(&line) {
            let (words, tail) = split_command(&line[at..]);
            let words = shorten(words.clone())
                .unwrap_or_else(|why| panic!("{}: `{}`: {why}", block.place(), words.join(" ")));
            line = format!("{}{} {tail}", &line[..at], words.join(" "));
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

/// A fresh scratch directory named `tag` holding copies of the repository's
/// `examples/`, `scripts/`, `tests/scenarios/` and `tests/fixtures/`, an empty
/// `docs/`, `my-machine.toml` (the
/// reference machine) with its tuning table beside it, and `travel.csv`.
fn workspace(tag: &str) -> PathBuf {
    let dir = common::scratch(tag, "work");
    let _ = std::fs::remove_dir_all(&dir);
    let root = common::root();
    common::copy_dir(&root.join("examples"), &dir.join("examples"));
    common::copy_dir(&root.join("scripts"), &dir.join("scripts"));
    for shipped in ["tests/scenarios", "tests/fixtures"] {
        common::copy_dir(&root.join(shipped), &dir.join(shipped));
    }
    std::fs::create_dir_all(dir.join("docs")).expect("docs/");
    for (from, to) in [
        ("vibro-driver.toml", "my-machine.toml"),
        ("vibro-driver.tuning.toml", "vibro-driver.tuning.toml"),
    ] {
        std::fs::copy(root.join("examples").join(from), dir.join(to)).expect("a copy");
    }
    // The reference machine's own speeds at these points (`host-sim tune
    // examples/vibro-driver.toml --speeds 3000 --offsets 60:120:30`), m/s.
    std::fs::write(
        dir.join("travel.csv"),
        "speed_rpm,offset_deg,velocity_mps\n3000,60,0.0263\n3000,90,0.0333\n3000,120,0.0255\n",
    )
    .expect("travel.csv");
    dir
}

/// A directory holding `host-sim`, the binary under test, for `PATH`.
fn bin_dir(work: &Path) -> PathBuf {
    let bin = work.join("bin");
    std::fs::create_dir_all(&bin).expect("bin/");
    let link = bin.join("host-sim");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_host-sim"), &link).expect("a link");
    bin
}

/// Runs `script` with bash in `work`, answering `device tune` from `truth`;
/// its exit status, stdout and stderr. A script still running after `limit` is
/// killed with its children (a hang fails rather than stalls the suite).
fn run_script(work: &Path, script: &str, truth: &Path, limit: Duration) -> (i32, String, String) {
    use std::os::unix::process::CommandExt;
    let path = format!(
        "{}:{}",
        bin_dir(work).display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut child = Command::new("bash")
        .args(["-e", "-o", "pipefail", "-c", script])
        .current_dir(work)
        .env("PATH", path)
        .process_group(0)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bash runs");
    let done = Arc::new(AtomicBool::new(false));
    let group = nix::unistd::Pid::from_raw(-i32::try_from(child.id()).unwrap());
    let watchdog = {
        let done = done.clone();
        std::thread::spawn(move || {
            let start = Instant::now();
            while !done.load(Ordering::SeqCst) {
                if start.elapsed() > limit {
                    let _ = nix::sys::signal::kill(group, nix::sys::signal::Signal::SIGKILL);
                    return true;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
            false
        })
    };
    let mut err = child.stderr.take().expect("piped");
    let stderr = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let mut stdin = child.stdin.take();
    let mut said = String::new();
    let mut mark = None;
    let x_now = || truth_rows(truth).last().expect("a truth row")[1];
    for line in BufReader::new(child.stdout.take().expect("piped")).lines() {
        let line = line.expect("stdout");
        if line.starts_with("mark: ") {
            mark = Some(x_now());
        } else if line.starts_with("end: ") {
            let x0 = mark.take().expect("a mark line before the end line");
            let mm = (x_now() - x0) * 1000.0;
            if let Some(input) = stdin.as_mut() {
                writeln!(input, "{mm:.2}").expect("the answer");
            }
        }
        said.push_str(&line);
        said.push('\n');
    }
    drop(stdin.take());
    let status = child.wait().expect("bash ends");
    done.store(true, Ordering::SeqCst);
    let killed = watchdog.join().expect("the watchdog");
    let stderr = stderr.join().expect("stderr");
    assert!(
        !killed,
        "still running after {limit:?}:\n{script}\n{said}{stderr}"
    );
    (status.code().unwrap_or(-1), said, stderr)
}

/// The command in the shipped table's header (`#   host-sim tune ...`).
fn header_command(table: &str) -> Vec<String> {
    let line = table
        .lines()
        .take_while(|l| l.starts_with('#'))
        .find_map(|l| {
            l.strip_prefix('#')
                .map(str::trim)
                .filter(|l| l.starts_with("host-sim tune "))
        })
        .unwrap_or_else(|| panic!("{TABLE}: no `host-sim tune` command in its header"));
    line.split_whitespace().map(String::from).collect()
}

fn shipped_table() -> String {
    std::fs::read_to_string(common::root().join(TABLE)).expect("the shipped table")
}

#[test]
fn every_command_the_readme_and_docs_show_runs_as_written() {
    let blocks = shell_blocks();
    // Every entry of NOT_RUN finds exactly one block.
    for (file, needle, _) in NOT_RUN {
        let found = blocks
            .iter()
            .filter(|b| b.file == *file && b.text.contains(needle))
            .count();
        assert_eq!(
            found, 1,
            "NOT_RUN ({file}, {needle:?}) finds {found} blocks"
        );
    }
    let work = workspace("documented-commands");
    let truth = work.join("truth.csv");
    let header = header_command(&shipped_table());
    let mut device: Option<DeviceSim> = None;
    let mut report = Vec::new();
    for block in &blocks {
        if let Some((_, _, why)) = NOT_RUN
            .iter()
            .find(|(f, n, _)| block.file == *f && block.text.contains(n))
        {
            report.push(format!("{}: not run: {why}", block.place()));
            continue;
        }
        if block.text.contains(&format!("--write {TABLE}")) && block.file == "docs/tuning.md" {
            // The regeneration of the shipped table: the header's command.
            let line = logical_lines(&block.text).concat();
            let line = line.replace("cargo run --release -p host-sim -- ", "host-sim ");
            let (mut words, _) = split_command(&line[command_start(&line).expect("host-sim")..]);
            let plot = words.iter().position(|w| w == "--plot").expect("--plot");
            words.drain(plot..plot + 2);
            assert_eq!(
                words,
                header,
                "{}: the table's regeneration is not the command in {TABLE}'s header",
                block.place()
            );
            report.push(format!(
                "{}: the shipped table's regeneration: run by the_shipped_tuning_table_is_what_its_header_command_writes",
                block.place()
            ));
            continue;
        }
        let port = block.text.contains("/dev/ttyUSB0").then(|| {
            let dev = device.get_or_insert_with(|| {
                DeviceSim::start(&[
                    "--machine",
                    work.join("my-machine.toml").to_str().unwrap(),
                    "--truth",
                    truth.to_str().unwrap(),
                ])
            });
            dev.port.clone()
        });
        let mut script = script(block, port.as_deref());
        if script.contains(PIL_ELF) {
            // The processor in the loop: the ELF the CI step `test` builds.
            let Some(elf) = common::pil_firmware() else {
                report.push(format!(
                    "{}: skipped: no firmware or QEMU here",
                    block.place()
                ));
                continue;
            };
            script = script.replace(PIL_ELF, elf.to_str().expect("a UTF-8 path"));
        }
        let start = Instant::now();
        let (status, stdout, stderr) = run_script(&work, &script, &truth, Duration::from_secs(900));
        assert_eq!(
            status,
            0,
            "{}: the block fails (exit {status}) as this test runs it:\n{script}\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
            block.place()
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", block.place());
        if script.contains("host-sim tune") || script.contains("host-sim calibrate") {
            for said in ["not held", "not a travel", "no travel"] {
                assert!(
                    !stdout.contains(said) && !stderr.contains(said),
                    "{}: a run of the shortened sweep was {said:?}:\n{script}\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
                    block.place()
                );
            }
        }
        report.push(format!(
            "{}: ran in {:.1} s:\n{}",
            block.place(),
            start.elapsed().as_secs_f64(),
            script.trim_end()
        ));
    }
    eprintln!("{}", report.join("\n"));
}

/// The shipped table is what the command in its header writes now: a change to
/// the plant, the controller or the sweep that moves the table fails here until
/// the table is regenerated (with that command, from the repository's root).
#[test]
fn the_shipped_tuning_table_is_what_its_header_command_writes() {
    let shipped = shipped_table();
    let command = header_command(&shipped);
    let write = command
        .iter()
        .position(|w| w == "--write")
        .expect("--write");
    assert_eq!(
        command.get(write + 1).map(String::as_str),
        Some(TABLE),
        "the header's command must write the shipped table"
    );
    let work = workspace("shipped-table");
    let mut cmd = common::host_sim();
    cmd.args(&command[1..]).current_dir(&work);
    let r = common::finish(cmd);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let written = std::fs::read_to_string(work.join(TABLE)).expect("the table written");
    assert!(
        written == shipped,
        "{TABLE} is not what its header's command writes now; regenerate it from the repository's root with\n  {}\n--- shipped\n{shipped}\n--- written now\n{written}",
        command.join(" ")
    );
}
