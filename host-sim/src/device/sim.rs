//! A device without hardware: the firmware's control task and link task, as
//! its board binary (`firmware/src/bin/board.rs`) runs them, on a machine's
//! plant ([`PlantMechanics`]: the reference machine's rotors with its platform
//! held, or a machine file's, its platform free or held) and a simulated flash.
//!
//! - control tick ([`SimDevice::tick`], at the controller's rate): advance the
//!   plant one tick under the last outputs, take the command, a new tuning
//!   table and a self-test request from the [`LinkState`], step the [`Controller`]
//!   on the sensors' readings, publish the status and the self-test's report;
//! - link ([`SimDevice::receive`]): the received bytes through the firmware's
//!   [`Link`] (decode, answer, telemetry, flash writes on a [`SimFlash`]).
//!
//! [`Noise`] corrupts the line deterministically both ways (bit flips, garbage
//! between frames), for the host's retries to be tried.

use std::collections::VecDeque;

use shared::capture::{Capture, MachineFingerprint, BOARD_CAPACITY, RECORD_LEN};
use shared::controller::Inputs;
use shared::controller::{Controller, Outputs, Params, ResetCause, TuningTable};
use shared::protocol::link::{use_stored, Link, LinkState};
use shared::storage::{self, SimFlash};
use shared::tick::{self, Board, LinkPort};

use super::plant::{reference_bench, PlantMechanics, Platform, PlatformPose};
use crate::machine::input::Problem;
use crate::machine::Machine;
use crate::simulation::closed_loop::params;

/// Deterministic corruption of the line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Noise {
    /// Flip one bit of every Nth byte either way (counted separately each way).
    pub flip_every: Option<u32>,
    /// Send a burst of garbage (with sync bytes in it) before every Nth frame.
    pub garbage_every: Option<u32>,
}

/// Byte counters and a pseudo-random state for [`Noise`].
#[derive(Clone, Debug)]
struct NoiseState {
    noise: Noise,
    rx_bytes: u64,
    tx_bytes: u64,
    frames: u64,
    random: u64,
}

impl NoiseState {
    fn next_random(&mut self) -> u64 {
        // xorshift64*
        let mut x = self.random;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.random = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn corrupt(&mut self, byte: u8, rx: bool) -> u8 {
        let Some(every) = self.noise.flip_every.filter(|&n| n > 0) else {
            return byte;
        };
        let count = if rx {
            self.rx_bytes += 1;
            self.rx_bytes
        } else {
            self.tx_bytes += 1;
            self.tx_bytes
        };
        if count.checked_rem(u64::from(every)) == Some(0) {
            byte ^ (1 << (self.next_random() % 8))
        } else {
            byte
        }
    }

    /// Garbage to send before the next frame, if due.
    fn garbage(&mut self) -> Vec<u8> {
        self.frames += 1;
        match self.noise.garbage_every.filter(|&n| n > 0) {
            Some(every) if self.frames.checked_rem(u64::from(every)) == Some(0) => {
                let n = 1 + self.next_random() % 24;
                let mut out: Vec<u8> = (0..n).map(|_| self.next_random() as u8).collect();
                // A false start: a sync pattern and part of a header.
                out.extend_from_slice(&[0xA5, 0x5A, 0x01]);
                out
            }
            _ => Vec::new(),
        }
    }
}

/// The simulated device.
pub struct SimDevice {
    controller: Controller,
    mechanics: Box<PlantMechanics>,
    link: Link,
    state: LinkState,
    flash: SimFlash,
    rx: VecDeque<u8>,
    uptime_ms: u32,
    /// Milliseconds per control tick (1 at the reference 1 kHz).
    tick_ms: u32,
    noise: NoiseState,
    last: Option<Outputs>,
}

/// The board of the simulated device ([`shared::tick::Board`]): its sample is the
/// plant advanced one tick under the last outputs, which [`Board::apply`]
/// keeps for the next; the E-stop closed, the ticks on time.
struct MechanicsBoard<'a> {
    mechanics: &'a mut PlantMechanics,
    /// The outputs of the tick before (none before the first).
    last: &'a mut Option<Outputs>,
    /// The tick, s.
    dt: f64,
}

impl Board for MechanicsBoard<'_> {
    fn sample(&mut self) -> Inputs {
        let readings = self.mechanics.advance(self.last.as_ref(), self.dt);
        Inputs {
            encoder: readings.encoder,
            index: readings.index,
            current: readings.current,
            supply_voltage: self.mechanics.supply(),
            estop: false,
            timing: Default::default(),
            command: None,
        }
    }

    fn apply(&mut self, out: &Outputs) {
        *self.last = Some(*out);
    }
}

impl SimDevice {
    /// The reference controller (`Params::reference()`, 1 kHz) with `tuning` (a
    /// stored table in flash wins, as on the board; none is stored at first), on
    /// the reference machine's rotors, the platform held ([`reference_bench`]).
    pub fn new(tuning: Option<TuningTable>, noise: Noise) -> SimDevice {
        let bench = PlantMechanics::new(&reference_bench(), Platform::Held);
        SimDevice::on(Params::reference(), tuning, bench, noise)
    }

    /// `machine`'s controller (its parameters and tuning table, as `host-sim run`
    /// builds it), its table replaced by `tuning` if given (a stored table in
    /// flash wins over both, as on the board), on the machine's plant at its start
    /// state, the platform `platform`. Problems: the machine's tuning table file.
    pub fn with_machine(
        machine: &Machine,
        platform: Platform,
        tuning: Option<TuningTable>,
        noise: Noise,
    ) -> Result<SimDevice, Vec<Problem>> {
        SimDevice::with_machines(machine, machine, platform, tuning, noise)
    }

    /// The bench a real board is on: the controller `firmware` builds (the
    /// machine file the firmware was built for: its parameters and tuning table)
    /// on the plant of `truth` (the machine as it really is), as
    /// [`SimDevice::with_machine`] otherwise.
    pub fn with_machines(
        truth: &Machine,
        firmware: &Machine,
        platform: Platform,
        tuning: Option<TuningTable>,
        noise: Noise,
    ) -> Result<SimDevice, Vec<Problem>> {
        let params = params(firmware)?;
        let plant = PlantMechanics::new(truth, platform);
        Ok(SimDevice::on(params, tuning, plant, noise))
    }

    /// The controller of `params` (its table replaced by `tuning` if given, a
    /// stored table winning) on `mechanics`.
    fn on(
        mut params: Params,
        tuning: Option<TuningTable>,
        mechanics: PlantMechanics,
        noise: Noise,
    ) -> SimDevice {
        if let Some(t) = tuning {
            params.tuning = t;
        }
        let flash = SimFlash::new();
        let stored = storage::load(&flash);
        use_stored(&mut params, stored.as_ref());
        let controller = Controller::new(&params, ResetCause::PowerOn);
        // The board's capture buffer; a device lives as long as its process.
        let buffer = Box::leak(vec![[0u8; RECORD_LEN]; BOARD_CAPACITY].into_boxed_slice());
        let state = LinkState::at_start(&controller, stored.as_ref()).with_capture(Capture::new(
            buffer,
            MachineFingerprint::default(),
            params.tick_s(),
        ));
        let tick_ms = (params.tick_s() * 1000.0).round().max(1.0) as u32;
        SimDevice {
            mechanics: Box::new(mechanics),
            controller,
            link: Link::new(),
            state,
            flash,
            rx: VecDeque::new(),
            uptime_ms: 0,
            tick_ms,
            noise: NoiseState {
                noise,
                rx_bytes: 0,
                tx_bytes: 0,
                frames: 0,
                random: 0x9E37_79B9_7F4A_7C15,
            },
            last: None,
        }
    }

    /// The device with its controller's link timeout (`FaultLimits::link_timeout_s`,
    /// the firmware's 0.5 s by default) set to `link_timeout_s` seconds, above 0:
    /// the controller stops the motors (fault `link_lost`) that long after the
    /// last request while they start or run. Taken before the first tick: the
    /// controller is built anew from its parameters with that one limit changed.
    pub fn with_link_timeout(mut self, link_timeout_s: f32) -> SimDevice {
        debug_assert_eq!(self.uptime_ms, 0, "set before the device runs");
        let mut params = self.controller.params().clone();
        params.limits.link_timeout_s = link_timeout_s;
        self.controller = Controller::new(&params, ResetCause::PowerOn);
        self
    }

    /// The controller's link timeout, s.
    pub fn link_timeout_s(&self) -> f32 {
        self.controller.params().limits.link_timeout_s
    }

    /// The device's firmware built for the machine file of `bytes`: its
    /// captures carry the file's fingerprint (CRC-32 and length), as the
    /// board's build stamps them. Without it they carry none (0, 0).
    pub fn built_for(mut self, bytes: &[u8]) -> SimDevice {
        self.state.capture.set_machine(MachineFingerprint {
            crc32: shared::codec::crc::crc32(bytes),
            len: bytes.len() as u32,
        });
        self
    }

    /// Milliseconds per control tick.
    pub fn tick_ms(&self) -> u32 {
        self.tick_ms
    }

    /// Uptime, ms.
    pub fn uptime_ms(&self) -> u32 {
        self.uptime_ms
    }

    /// The state shared by the link and the control task.
    pub fn link_state(&self) -> &LinkState {
        &self.state
    }

    /// The simulated flash.
    pub fn flash(&self) -> &SimFlash {
        &self.flash
    }

    /// The rotor speeds, rpm (the simulation's truth, not the controller's
    /// estimate).
    pub fn speeds_rpm(&self) -> [f64; 2] {
        self.mechanics.speeds_rpm()
    }

    /// The platform's pose (the simulation's truth).
    pub fn platform(&self) -> PlatformPose {
        self.mechanics.platform()
    }

    /// Whether the platform is held or free.
    pub fn platform_mode(&self) -> Platform {
        self.mechanics.platform_mode()
    }

    /// The winding currents, A (the simulation's truth, not the board's reading).
    pub fn currents(&self) -> [f64; 2] {
        self.mechanics.currents()
    }

    /// What the simulation warned about so far.
    pub fn warnings(&self) -> Vec<String> {
        self.mechanics.warnings()
    }

    /// Why the platform's motion is no travel (a body through the fundament or
    /// tipped over), `None` while it is one.
    pub fn no_travel(&self) -> Option<String> {
        self.mechanics.no_travel()
    }

    /// Why the simulation cannot go on (the plant stopped advancing), if it
    /// cannot.
    pub fn stopped(&self) -> Option<String> {
        self.mechanics.stopped()
    }

    /// One control tick, as the firmware's control task ([`shared::tick::run`]).
    pub fn tick(&mut self) {
        self.uptime_ms = self.uptime_ms.wrapping_add(self.tick_ms);
        let dt = f64::from(self.tick_ms) / 1000.0;
        let mut board = MechanicsBoard {
            mechanics: self.mechanics.as_mut(),
            last: &mut self.last,
            dt,
        };
        let mut port = LinkPort::new(&mut self.state, self.uptime_ms);
        tick::run(&mut self.controller, &mut board, &mut port, dt as f32);
    }

    /// Bytes received from the host (corrupted first, if noise is set).
    pub fn push_rx(&mut self, bytes: &[u8]) {
        for &b in bytes {
            let b = self.noise.corrupt(b, true);
            self.rx.push_back(b);
        }
    }

    /// One pass of the link task at the current uptime, as the firmware's idle
    /// loop: every byte received so far decoded and answered, telemetry when due;
    /// the bytes to send back.
    pub fn receive(&mut self) -> Vec<u8> {
        let mut out = Vec::new();
        let now = self.uptime_ms;
        let rx = &mut self.rx;
        let state = &mut self.state;
        let noise = &mut self.noise;
        loop {
            let busy = self.link.poll(
                || rx.pop_front(),
                now,
                &mut *state,
                &mut self.flash,
                |frame| {
                    out.extend(noise.garbage());
                    for &b in frame {
                        out.push(noise.corrupt(b, false));
                    }
                },
            );
            if !busy {
                break;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::plant::reference_bench_with;
    use shared::controller::self_test::SelfTestStatus;
    use shared::controller::{Command, Direction, Faults, State};

    fn run(dev: &mut SimDevice, ms: u32) {
        for _ in 0..ms / dev.tick_ms() {
            dev.tick();
            if dev.link_state().status.state != State::Idle {
                // The host's heartbeat.
                dev.state.command.get_or_insert(Command::Heartbeat);
            }
        }
    }

    /// The reference controller from rest to 3000 rpm (travel right) on the
    /// reference machine's rotors, the platform held, driven `ms`: every tick the
    /// platform's pose is exactly its start pose; the largest winding current
    /// (A) read at the ticks' ends, and the device.
    fn bench_start(machine: &Machine, ms: u32) -> (f64, SimDevice) {
        let bench = PlantMechanics::new(machine, Platform::Held);
        let mut dev = SimDevice::on(Params::reference(), None, bench, Noise::default());
        let start = dev.platform();
        dev.state.command = Some(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        });
        let mut peak: f64 = 0.0;
        for _ in 0..ms {
            run(&mut dev, 1);
            assert_eq!(dev.platform(), start, "at {} ms", dev.uptime_ms());
            peak = dev.currents().iter().fold(peak, |p, i| p.max(i.abs()));
        }
        (peak, dev)
    }

    /// The rotors-only bench: the platform stays where it started (checked at
    /// every tick) while the controller brings the rotors to 3000 rpm through the
    /// plant's motors; the reference driver's 2 A limit is never passed.
    #[test]
    fn on_the_bench_the_platform_stays_and_the_rotors_reach_speed() {
        let dev = SimDevice::new(None, Noise::default());
        assert_eq!(dev.platform_mode(), Platform::Held);
        let (peak, dev) = bench_start(&reference_bench(), 3000);
        assert!(peak <= 2.0, "{peak} A");
        for v in dev.speeds_rpm() {
            assert!((v - 3000.0).abs() < 60.0, "{v} rpm");
        }
        assert_eq!(dev.link_state().status.state, State::Running);
        assert!(dev.warnings().is_empty(), "{:?}", dev.warnings());
    }

    /// The driver's current limit acts on the bench: the reference controller's
    /// start asks for more than 1 A (a driver limit of 10 A lets the current
    /// pass 1 A), and a driver limited to 1 A holds every winding current at
    /// most 1 A and reaches it, the rotors still getting to speed.
    #[test]
    fn on_the_bench_the_driver_holds_the_current_to_its_limit() {
        let unlimited = reference_bench_with(&["motor.current_limit=10"]);
        let (asked, _) = bench_start(&unlimited, 1500);
        assert!(asked > 1.1, "{asked} A");
        let limited = reference_bench_with(&["motor.current_limit=1"]);
        let (peak, dev) = bench_start(&limited, 3000);
        assert!(peak <= 1.0, "{peak} A");
        assert!(peak >= 0.999, "{peak} A");
        for v in dev.speeds_rpm() {
            assert!((v - 3000.0).abs() < 60.0, "{v} rpm");
        }
    }

    #[test]
    fn the_controller_runs_the_simulated_rotors() {
        let mut dev = SimDevice::new(None, Noise::default());
        dev.state.command = Some(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        });
        run(&mut dev, 4000);
        let s = dev.link_state().status;
        assert_eq!(s.state, State::Running, "{s:?}");
        assert!(s.faults.is_empty(), "{s:?}");
        for v in dev.speeds_rpm() {
            assert!((v - 3000.0).abs() < 60.0, "{v}");
        }
        assert!(s.telemetry.phase_loop_closed, "{s:?}");
        assert!(s.telemetry.phase_error_deg.abs() < 10.0, "{s:?}");
        dev.state.command = Some(Command::Stop);
        run(&mut dev, 4000);
        let s = dev.link_state().status;
        assert_eq!(s.state, State::Idle, "{s:?}");
        assert!(s.faults.is_empty(), "{s:?}");
    }

    /// Travel without a heartbeat: the firmware's controller latches `link_lost`
    /// 0.5 s after the command (taken at the first tick, 1 ms, the fault 500
    /// ticks later); with the link timeout set to 2 s, 2000 ticks later.
    #[test]
    fn the_link_timeout_is_the_one_set() {
        let lost_after = |dev: &mut SimDevice| {
            dev.state.command = Some(Command::Travel {
                direction: Direction::Right,
                speed_rpm: 3000.0,
            });
            let start = dev.uptime_ms();
            while !dev.link_state().status.faults.contains(Faults::LINK_LOST) {
                dev.tick();
                assert!(dev.uptime_ms() - start < 10_000, "no link_lost");
            }
            dev.uptime_ms() - start
        };
        let mut dev = SimDevice::new(None, Noise::default());
        assert_eq!(dev.link_timeout_s(), 0.5);
        assert_eq!(lost_after(&mut dev), 501);
        let mut dev = SimDevice::new(None, Noise::default()).with_link_timeout(2.0);
        assert_eq!(dev.link_timeout_s(), 2.0);
        assert_eq!(lost_after(&mut dev), 2001);
    }

    #[test]
    fn the_self_test_runs_on_request_and_its_result_is_stored() {
        let mut dev = SimDevice::new(None, Noise::default());
        dev.state.self_test_requested = true;
        let mut ms = 0;
        while dev.link_state().self_test.status != SelfTestStatus::Done {
            dev.tick();
            dev.receive();
            ms += 1;
            assert!(ms < 20_000, "{:?}", dev.link_state().self_test);
        }
        let result = dev.link_state().self_test.result;
        for r in result.rotors {
            assert!(r.passed(), "{r:?}");
            assert_eq!(r.counts_per_rev, 4096);
        }
        // Rotor 1 starts 30 degrees past its index, in count floor(30 / 360 x
        // 4096) = 341 of the turn, rotor 2 200 degrees, in count 2275: 3755 and
        // 1821 counts to the index.
        assert_eq!(result.rotors[0].index_offset_counts, 4096 - 341);
        assert_eq!(result.rotors[1].index_offset_counts, 4096 - 2275);
        // Stored with the table once the rotors rest.
        for _ in 0..3000 {
            dev.tick();
            dev.receive();
        }
        let stored = storage::load(dev.flash()).expect("a record");
        assert_eq!(stored.record.self_test, Some(result));
    }

    /// The reference machine file, with its tuning table.
    fn reference_machine() -> Machine {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/vibro-driver.toml");
        Machine::load(std::path::Path::new(path), &[]).expect("the reference machine")
    }

    /// The platform's `x` after `ms` more of device time (heartbeats as [`run`]),
    /// and the largest move of `x` in one tick on the way, m.
    fn travel(dev: &mut SimDevice, ms: u32) -> (f64, f64) {
        let mut x = dev.platform().x;
        let mut step: f64 = 0.0;
        for _ in 0..ms / dev.tick_ms() {
            run(dev, dev.tick_ms());
            let next = dev.platform().x;
            step = step.max((next - x).abs());
            x = next;
        }
        (x, step)
    }

    /// The device on the reference machine's whole plant holds 3000 rpm and 90
    /// degrees and travels right at the speed `host-sim run` (tune's `run_point`,
    /// the same plant and controller in the loop) finds for that point. The one
    /// difference is the start: the device takes the command at its first tick,
    /// after a tick of the plant with the windings open, one tick later than the
    /// run; on the same gait that shifts each end of the window of the mean
    /// velocity, `(x(T) - x(T/2)) / (T/2)`, by at most the platform's largest
    /// move in a tick, `d`: |v_device - v_run| <= 2 d / (T/2). The integrator's
    /// own error (rtol 1e-8) is orders of magnitude below that.
    #[test]
    fn the_whole_plant_travels_as_host_sim_run_finds() {
        let machine = reference_machine();
        let (speed, offset, t_end) = (3000.0, 90.0, 4.0);
        let expected = crate::sweep::run_point(&machine, speed, offset, t_end);
        assert_eq!(expected.not_held, None);
        assert!(expected.mean_velocity > 0.01, "{expected:?}");

        let mut dev =
            SimDevice::with_machine(&machine, Platform::Free, None, Noise::default()).unwrap();
        dev.state.command = Some(Command::HoldOffset {
            speed_rpm: speed as f32,
            offset_deg: offset as f32,
        });
        let half_ms = (t_end * 500.0) as u32;
        let (start, _) = travel(&mut dev, half_ms);
        let (end, d) = travel(&mut dev, half_ms);
        let v = (end - start) / (t_end / 2.0);
        let tolerance = 2.0 * d / (t_end / 2.0);
        assert!(
            (v - expected.mean_velocity).abs() <= tolerance,
            "device {v} m/s, run {} m/s, tolerance {tolerance}",
            expected.mean_velocity
        );

        // At speed, the offset held, no fault: what the host's status shows.
        let s = dev.link_state().status;
        assert_eq!(s.state, State::Running, "{s:?}");
        assert!(s.faults.is_empty(), "{s:?}");
        assert!(s.telemetry.phase_loop_closed, "{s:?}");
        assert!(s.telemetry.phase_error_deg.abs() < 5.0, "{s:?}");
        for v in dev.speeds_rpm() {
            assert!((v - speed).abs() < 30.0, "{v} rpm");
        }
    }

    /// With a machine, the controller is the machine's: its tuning table's offset
    /// for travel (77.2 degrees right at 3250 rpm in the reference machine's
    /// table), not the default table's 90 degrees.
    #[test]
    fn a_machine_brings_its_own_tuning_table() {
        let machine = reference_machine();
        let table_offset = params(&machine)
            .unwrap()
            .tuning
            .offset(Direction::Right, 3250.0);
        assert!((table_offset - 90.0).abs() > 1.0, "{table_offset}");
        let mut dev =
            SimDevice::with_machine(&machine, Platform::Free, None, Noise::default()).unwrap();
        dev.state.command = Some(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3250.0,
        });
        // Running by 1.5 s (the ramp to 3250 rpm takes about 0.8 s).
        run(&mut dev, 1500);
        assert_eq!(dev.link_state().status.state, State::Running);
        let target = dev.link_state().status.telemetry.target_offset_deg;
        assert!(
            (target - table_offset).abs() < 1e-3,
            "{target} vs {table_offset}"
        );
    }
}
