//! One control tick, `Controller::step`, in the running state, on the host (f32, the
//! firmware's arithmetic): the reference parameters, travel right at 3000 rpm.
//!
//! The encoders are a synthetic stream: both rotors turn at exactly 3000 rpm, 204.8
//! counts a tick at 4096 counts a turn and 1 kHz, rotor 2 a quarter turn (1024
//! counts) behind rotor 1, so the measured offset is the default table's 90 degrees
//! for rightward travel; index pulses at every whole turn, counters wrapping at
//! `2^32`, a heartbeat every tick, 12 V, 0.1 A. The controller is warmed up on that
//! stream from idle until it reports running (the speed ramp takes about 0.72 s of
//! ticks), then each measured iteration advances the stream by one tick and steps.
//! The stream's own cost is measured alone as well, to be subtracted.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use shared::controller::{
    Command, Controller, Direction, Inputs, Params, ResetCause, State, CONTROL_RATE_HZ,
};

/// Counts per turn of the reference encoder (after x4 decoding).
const N: i64 = 4096;

/// Two ideal rotors at 3000 rpm, 90 degrees apart, as encoder readings.
struct Stream {
    /// Ticks since the start.
    tick: i64,
    /// The unwrapped counts of the previous tick.
    last: [i64; 2],
    /// The inputs of the current tick.
    inputs: Inputs,
}

impl Stream {
    fn new() -> Self {
        let mut s = Stream {
            tick: 0,
            last: [0, -N / 4],
            inputs: Inputs {
                current: [0.1; 2],
                supply_voltage: 12.0,
                command: Some(Command::Travel {
                    direction: Direction::Right,
                    speed_rpm: 3000.0,
                }),
                ..Inputs::default()
            },
        };
        s.inputs.encoder = s.last.map(|c| c as u32);
        s
    }

    /// The next tick's readings: `count_k = floor(204.8 k)` (exact: `1024 k / 5`),
    /// rotor 2 a quarter turn behind; an index latch where a whole turn was crossed.
    fn advance(&mut self) -> &Inputs {
        self.tick += 1;
        let c1 = (self.tick * 1024).div_euclid(5);
        let counts = [c1, c1 - N / 4];
        for (k, count) in counts.into_iter().enumerate() {
            let turn = count.div_euclid(N);
            self.inputs.index[k] = (turn > self.last[k].div_euclid(N)).then(|| (turn * N) as u32);
            self.inputs.encoder[k] = count as u32;
        }
        self.last = counts;
        if self.tick > 1 {
            self.inputs.command = Some(Command::Heartbeat);
        }
        &self.inputs
    }
}

fn bench(c: &mut Criterion) {
    let dt = 1.0 / CONTROL_RATE_HZ;
    let mut controller = Controller::new(&Params::reference(), ResetCause::PowerOn);
    let mut stream = Stream::new();
    controller.step(&stream.inputs, dt);

    // Warm up: from idle through the ramp to running, then a second more.
    let mut ticks = 0;
    while controller.state() != State::Running {
        controller.step(stream.advance(), dt);
        ticks += 1;
        assert!(ticks < 2000, "not running after {ticks} ticks");
    }
    for _ in 0..1000 {
        controller.step(stream.advance(), dt);
    }
    assert_eq!(controller.state(), State::Running);

    c.bench_function("controller step, running, 3000 rpm (f32)", |b| {
        b.iter(|| {
            let inputs = stream.advance();
            controller.step(black_box(inputs), black_box(dt))
        })
    });
    assert_eq!(controller.state(), State::Running, "left running");
    assert!(controller.faults().is_empty(), "{}", controller.faults());

    let mut alone = Stream::new();
    c.bench_function("synthetic encoder stream alone (subtract)", |b| {
        b.iter(|| black_box(alone.advance()).encoder)
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
