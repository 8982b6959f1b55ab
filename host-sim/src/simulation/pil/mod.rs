//! Processor in the loop (`host-sim run --firmware ELF`, `docs/pil.md`): the
//! firmware's binary `pil` on QEMU drives the plant in place of the controller
//! in the loop ([`super::closed_loop`]). At every control tick `t_k = k / rate`
//! (tick `n = k + 1` of the firmware):
//!
//! 1. the plant's sensors are sampled as for the controller in the loop
//!    ([`PlantBoard`]'s sample, with a scenario's faults) and sent with the
//!    UART bytes the host's link sends until the next tick ([`host`]) as the
//!    record [`Sample`] of tick `n` (the firmware's link decodes them after the
//!    tick's step: a command due by tick `n + 1` is taken there);
//! 2. the firmware's record [`Drive`] of tick `n` comes back: TIM8's compare
//!    values and main output enable, which the plant's bridges take as the
//!    timer's inputs ([`BridgeCommand::Inputs`]: `compare / ARR`, with `ARR` of
//!    the board's timer for the machine's `[drive]`, quantised as the timer
//!    quantises it), the tick's status report (for the events and the
//!    summary) and the bytes the firmware's link sent;
//! 3. the plant advances one control period.
//!
//! Before tick 1 the firmware's [`Hello`] must name the machine file simulated
//! (its CRC-32 and length) and the machine's tick period.
//!
//! A [`Script`] (the identification, the capture) may ask the firmware's link
//! more than the run's commands: at every exchange it is given the answers
//! received since the last one and says what to send; every answer is kept
//! ([`FirmwareDriver::answers`]). A script that has what it came for may end
//! the run ([`Driver::finished`]); one that fails ends it as a lost firmware
//! does.

pub mod host;
pub mod script;
pub mod session;

use std::path::{Path, PathBuf};

use shared::controller::{Bridge, Command, Outputs, RotorCount};
use shared::drive::{CentreAligned, BOARD_TIMER_HZ};
use shared::pil::{Bytes, Drive, Hello, Sample, MAX_LATE_US};
use shared::protocol::StatusReport;
use shared::tick::Board;

use crate::event::EventRow;
use crate::failure::{Failure, Kind};
use crate::machine::Machine;
use crate::plant::bridge::BridgeCommand;
use crate::plant::simulator::Plant;
use crate::simulation::board::{BoardSensors, Injected, PlantBoard};
use crate::simulation::closed_loop::{controller_events, params, LastTick};
use crate::simulation::Driver;
use host::{Answer, Host};
use script::Script;
use session::Session;

/// The command that builds the ELF.
pub const BUILD: &str = "cd firmware && cargo build --release --features pil --bin pil";

/// The firmware in the loop.
pub struct FirmwareDriver {
    session: Option<Session>,
    elf: PathBuf,
    sensors: BoardSensors,
    supply: f64,
    rotor_count: RotorCount,
    /// The bridge timer's full scale, `ARR`.
    arr: u16,
    host: Host,
    /// Faults injected now (scenarios): on the sample as [`PlantBoard`] makes
    /// it, on the bridges' supply, on the link (frames not delivered), and how
    /// late the next tick starts (the firmware spins past its timer event).
    pub injected: Injected,
    /// The last tick's outputs as the board shows them: the status report's
    /// state, faults and telemetry, the bridges' duties and enable.
    outputs: Option<Outputs>,
    /// The control period, s.
    dt: f64,
    /// The firmware's tick number of the next exchange.
    tick: u32,
    events: Vec<EventRow>,
    failure: Option<Failure>,
    log: String,
    /// Whether the log's decoder had to be killed (its log may be cut).
    log_cut: bool,
    /// The control task's instructions per tick, from the drive records.
    cost: TickCost,
    /// What the host asks beyond the commands, if anything.
    script: Option<Box<dyn Script>>,
    /// Every answer to the script's requests, in order.
    answers: Vec<Answer>,
}

/// The firmware's control task's instructions per tick: each drive record's
/// `busy_ns`, one instruction a nanosecond of QEMU's virtual clock under
/// `-icount shift=0` (`firmware::qemu::cycles` checks that ratio).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickCost {
    /// Ticks counted.
    pub ticks: u64,
    /// Their instructions, summed.
    pub total: u64,
    /// The most in one tick.
    pub max: u32,
}

impl TickCost {
    fn add(&mut self, instructions: u32) {
        self.ticks += 1;
        self.total += u64::from(instructions);
        self.max = self.max.max(instructions);
    }

    /// The mean instructions per tick (none before a tick).
    pub fn mean(&self) -> Option<f64> {
        (self.ticks > 0).then(|| self.total as f64 / self.ticks as f64)
    }
}

impl FirmwareDriver {
    /// QEMU started on `elf` for `machine` (read from `machine_path`), its
    /// [`Hello`] checked; the host's link sends `schedule`'s commands.
    pub fn start(
        machine: &Machine,
        machine_path: &Path,
        elf: &Path,
        schedule: Vec<(f64, Command)>,
    ) -> Result<Self, Failure> {
        if !elf.is_file() {
            return Err(Failure::usage(format!(
                "--firmware {}: no such file; build it with `{BUILD}` (VIBRO_MACHINE=FILE for another machine file than examples/vibro-driver.toml)",
                elf.display()
            )));
        }
        let missing: Vec<String> = [session::QEMU, session::DEFMT_PRINT]
            .into_iter()
            .filter_map(session::missing_tool)
            .collect();
        if !missing.is_empty() {
            return Err(Failure::new(Kind::Usage, missing));
        }
        let bytes = std::fs::read(machine_path)
            .map_err(|e| Failure::usage(format!("{}: {e}", machine_path.display())))?;
        let rate = machine.controller.rate_hz;
        let p = params(machine)?;
        let mut session =
            Session::start(elf).map_err(|e| Failure::run(format!("--firmware: {e}")))?;
        let mut buf = [0u8; Hello::LEN];
        session.receive(&mut buf).map_err(|e| {
            Failure::usage(format!(
                "--firmware {}: no hello record from the firmware ({e}): is it the binary `pil`? build it with `{BUILD}`",
                elf.display()
            ))
        })?;
        let hello = Hello::parse(&buf).map_err(|e| {
            Failure::usage(format!(
                "--firmware {}: its first record is no PIL hello ({e}): is it the binary `pil`? build it with `{BUILD}`",
                elf.display()
            ))
        })?;
        let crc = shared::codec::crc::crc32(&bytes);
        if (hello.machine_crc, hello.machine_len) != (crc, bytes.len() as u32) {
            return Err(Failure::usage(format!(
                "--firmware {}: built for the machine file {} (CRC-32 {:08x}, {} bytes), not for {} (CRC-32 {crc:08x}, {} bytes): rebuild it with `cd firmware && VIBRO_MACHINE={} cargo build --release --features pil --bin pil`",
                elf.display(),
                String::from_utf8_lossy(hello.path_bytes()),
                hello.machine_crc,
                hello.machine_len,
                machine_path.display(),
                bytes.len(),
                std::fs::canonicalize(machine_path)
                    .unwrap_or_else(|_| machine_path.to_path_buf())
                    .display(),
            )));
        }
        let tick_us = (1e6 / rate).round() as u32;
        if hello.tick_us != tick_us {
            return Err(Failure::usage(format!(
                "--firmware {}: ticks every {} us, the machine's rate_hz {rate} every {tick_us} us",
                elf.display(),
                hello.tick_us
            )));
        }
        Ok(FirmwareDriver {
            session: Some(session),
            elf: elf.to_path_buf(),
            sensors: BoardSensors::new(machine),
            supply: machine.drive.supply_voltage,
            rotor_count: p.rotor_count,
            arr: CentreAligned::new(BOARD_TIMER_HZ, machine.drive.bridge).arr,
            host: Host::new(schedule),
            injected: Injected::default(),
            outputs: None,
            dt: 1.0 / rate,
            tick: 1,
            events: Vec::new(),
            failure: None,
            log: String::new(),
            log_cut: false,
            cost: TickCost::default(),
            script: None,
            answers: Vec::new(),
        })
    }

    /// Let `script` ask the firmware's link, from the first exchange on.
    pub fn with_script(mut self, script: Box<dyn Script>) -> Self {
        self.script = Some(script);
        self
    }

    /// Every answer to the script's requests so far, in order (all of them
    /// after [`FirmwareDriver::finish`]).
    pub fn answers(&self) -> &[Answer] {
        &self.answers
    }

    /// Stop QEMU and keep the firmware's log ([`FirmwareDriver::log`]) and
    /// the answers of the last exchange.
    pub fn finish(&mut self) {
        self.answers.extend(self.host.answers());
        if let Some(s) = self.session.take() {
            let (log, whole) = s.finish();
            self.log = log;
            self.log_cut = !whole;
        }
    }

    /// The firmware's decoded defmt log (after [`FirmwareDriver::finish`]).
    pub fn log(&self) -> &str {
        &self.log
    }

    /// The control task's instructions per tick so far.
    pub fn cost(&self) -> TickCost {
        self.cost
    }

    /// What the host's link noticed (a request refused, frames lost).
    pub fn warnings(&self) -> Vec<String> {
        let mut w = self.host.warnings();
        if self.log_cut {
            w.push(format!(
                "the firmware's log may be cut: its decoder ({}) had not ended {} s after QEMU was stopped and was killed",
                session::DEFMT_PRINT,
                session::DECODER_S
            ));
        }
        w
    }

    /// One exchange: the sample of tick `self.tick` out, its drive record in.
    fn exchange(&mut self, t: f64, plant: &Plant) -> Result<Drive, String> {
        let mut board = PlantBoard {
            sensors: &mut self.sensors,
            plant,
            t,
            injected: &self.injected,
            supply: self.injected.supply(self.supply),
            bridges: ([BridgeCommand::Off; 2], [0.0; 2]),
        };
        let inputs = board.sample();
        if let Some(script) = self.script.as_mut() {
            let answers = self.host.answers();
            for r in script.step(t, &answers) {
                self.host.ask(r);
            }
            self.answers.extend(answers);
            if let Some(why) = script.failure() {
                return Err(why);
            }
        }
        // The bytes the UART receives until the next tick: the link decodes them
        // after this tick's step, so that a command due by the next tick is
        // taken there, as the controller in the loop takes it.
        let mut rx = Bytes::default();
        self.host
            .send(t + self.dt, self.injected.link_lost, &mut rx);
        let sample = Sample {
            tick: self.tick,
            encoder: inputs.encoder,
            index: inputs.index,
            current: inputs.current,
            supply_voltage: inputs.supply_voltage,
            estop: inputs.estop,
            // Below MAX_LATE_US: a scenario asking more is refused before the run.
            next_late_us: (self.injected.tick_late_s * 1e6)
                .round()
                .clamp(0.0, f64::from(MAX_LATE_US - 1)) as u16,
            rx,
        };
        let session = self.session.as_mut().ok_or("the firmware has stopped")?;
        session.send(&sample.to_bytes())?;
        let mut buf = [0u8; Drive::LEN];
        session.receive(&mut buf)?;
        let drive = Drive::parse(&buf, self.tick)
            .map_err(|e| format!("the firmware's record of tick {} refused: {e}", self.tick))?;
        self.host.received(drive.tx.as_slice());
        self.cost.add(drive.busy_ns);
        self.tick += 1;
        Ok(drive)
    }

    /// The plant's bridge commands for the timer's state, and the duties to
    /// record (`IN1 - IN2` high fractions: the duty in either decay mode).
    fn bridges_of(&self, d: &Drive) -> ([BridgeCommand; 2], [f64; 2]) {
        if !d.enabled {
            return ([BridgeCommand::Off; 2], [0.0; 2]);
        }
        let arr = f32::from(self.arr);
        let f = |ch: usize| (f32::from(d.compare[ch]) / arr).min(1.0);
        let inputs = [0, 1].map(|k| [f(2 * k), f(2 * k + 1)]);
        (
            inputs.map(BridgeCommand::Inputs),
            inputs.map(|[a, b]| f64::from(a - b)),
        )
    }

    /// The last tick's outputs as the board shows them.
    pub fn last(&self) -> Option<&Outputs> {
        self.outputs.as_ref()
    }

    fn observe(&mut self, t: f64, s: StatusReport) {
        // The previous tick's, before this tick's outputs replace them.
        let before = self.outputs.map(|o| (o.state, o.faults));
        self.events
            .extend(controller_events(t, before, s.state, s.faults));
    }
}

impl Driver for FirmwareDriver {
    fn before_tick(&mut self, _t: f64, plant: &mut Plant) {
        plant.set_supply(self.injected.supply(self.supply));
    }

    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        if self.failure.is_some() || self.session.is_none() {
            return ([BridgeCommand::Off; 2], [0.0; 2]);
        }
        match self.exchange(t, plant) {
            Ok(drive) => {
                self.observe(t, drive.status);
                let bridges = self.bridges_of(&drive);
                self.outputs = Some(Outputs {
                    // Both inputs low is a coasting bridge, off, as the
                    // plant's bridge reads it.
                    bridges: [0, 1].map(|k| match bridges.0[k] {
                        BridgeCommand::Off | BridgeCommand::Inputs([0.0, 0.0]) => Bridge::Off,
                        _ => Bridge::Driven(bridges.1[k] as f32),
                    }),
                    state: drive.status.state,
                    faults: drive.status.faults,
                    telemetry: drive.status.telemetry,
                });
                bridges
            }
            Err(_) if crate::interrupt::interrupted() => {
                // Ctrl-C or SIGTERM: the run ends at this tick as any run does
                // (its observer), with what was simulated up to there.
                self.finish();
                ([BridgeCommand::Off; 2], [0.0; 2])
            }
            Err(e) => {
                self.failure = Some(Failure::run(format!(
                    "--firmware {}: at t = {t} s: {e}",
                    self.elf.display()
                )));
                self.finish();
                ([BridgeCommand::Off; 2], [0.0; 2])
            }
        }
    }

    fn last_tick(&self) -> Option<LastTick<'_>> {
        Some(LastTick {
            last: self.outputs.as_ref(),
            rotors: self.rotor_count,
        })
    }

    fn events(&mut self) -> Vec<EventRow> {
        std::mem::take(&mut self.events)
    }

    fn failure(&self) -> Option<Failure> {
        self.failure.clone()
    }

    fn finished(&self) -> bool {
        self.script.as_ref().is_some_and(|s| s.ends_run())
    }
}
