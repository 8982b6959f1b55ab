//! What the controller sees of the plant: each rotor's quadrature encoder with its
//! index pulse, and each winding's current measurement, with their noise.
//!
//! # Encoder angle
//!
//! The phase convention of docs/machine-file.md ("Conventions"): a rotor's encoder
//! angle is `theta = s (phi - index_angle)`, with `phi` the eccentric angle in the
//! platform frame and `s = +1` for a ccw rotor, `-1` for cw ([`encoder_angle`]). So
//! `theta` grows when the rotor is driven forward, whichever its sense, and the index
//! pulse fires where `theta` is a multiple of `2 pi`.
//!
//! # Determinism
//!
//! Every noise source is its own [`NoiseStream`]: a ChaCha8 generator seeded from the
//! machine's `simulation.seed` and set to a stream id fixed per [`Channel`]. A
//! channel's readings depend only on the seed, its id and its own calls, never on
//! which other channels exist or how often they are sampled, so the same seed gives
//! bit-identical readings (with the same binary: the normal samples use the
//! platform's `ln`, `sin`, `cos`).

use std::f64::consts::TAU;

use rand::rngs::ChaCha8Rng;
use rand::{Rng, SeedableRng};

use crate::machine::{Rotor, Sense, Sensors};

/// A measurement channel, which names its noise stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// The encoder of rotor `n` (0 for rotor 1, 1 for rotor 2): its edge jitter.
    Encoder(usize),
    /// The current sensor of rotor `n`'s winding: its measurement noise.
    Current(usize),
}

impl Channel {
    /// The ChaCha stream id: the kind in the high 32 bits (1 encoder, 2 current), the
    /// rotor in the low ones. Fixed: changing an id changes every pinned noisy output.
    pub fn stream(self) -> u64 {
        match self {
            Channel::Encoder(n) => (1 << 32) | (n as u64 & 0xffff_ffff),
            Channel::Current(n) => (2 << 32) | (n as u64 & 0xffff_ffff),
        }
    }
}

/// A seeded source of standard normal samples, one per measurement channel.
#[derive(Debug)]
pub struct NoiseStream {
    /// `ChaCha8Rng::seed_from_u64(seed)` set to the channel's stream.
    rng: ChaCha8Rng,
    /// The second value of the last Box-Muller pair, not yet used.
    spare: Option<f64>,
}

impl NoiseStream {
    /// The stream of `channel` under `seed` (the machine's `simulation.seed`).
    pub fn new(seed: u64, channel: Channel) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(channel.stream());
        NoiseStream { rng, spare: None }
    }

    /// The next sample of `N(0, 1)`, by the Box-Muller transform (Box, Muller, "A note
    /// on the generation of random normal deviates", Ann. Math. Statist. 29 (1958)
    /// 610-611):
    ///
    /// ```text
    ///   z0 = sqrt(-2 ln u1) cos(2 pi u2),  z1 = sqrt(-2 ln u1) sin(2 pi u2)
    /// ```
    ///
    /// with `u1` in `(0, 1]` and `u2` in `[0, 1)` from the top 53 bits of two 64-bit
    /// outputs; `z0` is returned and `z1` kept for the next call. Written out rather
    /// than taken from a distributions crate so that the sequence is defined here and
    /// cannot change with a dependency's version. `u1 >= 2^-53` caps `|z|` at
    /// `sqrt(106 ln 2) = 8.6`, a tail of probability 1e-17.
    pub fn standard_normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // Two uniforms from 53-bit integers, exact in f64.
        const SCALE: f64 = 1.0 / (1u64 << 53) as f64;
        let u1 = ((self.rng.next_u64() >> 11) + 1) as f64 * SCALE;
        let u2 = (self.rng.next_u64() >> 11) as f64 * SCALE;
        // The Box-Muller pair.
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (TAU * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
}

impl Clone for NoiseStream {
    /// The same stream at the same position: the clone and the original continue
    /// with identical samples.
    fn clone(&self) -> Self {
        NoiseStream {
            rng: ChaCha8Rng::deserialize_state(&self.rng.serialize_state()),
            spare: self.spare,
        }
    }
}

/// The encoder angle `theta = s (phi - index_angle)` (docs/machine-file.md,
/// "Conventions"), rad, with `s = +1` for ccw and `-1` for cw.
pub fn encoder_angle(sense: Sense, index_angle: f64, phi: f64) -> f64 {
    sense.sign() * (phi - index_angle)
}

/// One sample of an encoder, as the controller reads it at a control tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderReading {
    /// The sampling instant, s.
    pub t: f64,
    /// The counter, `floor(theta N / (2 pi))` modulo `2^32`, counts (`N` the counts per
    /// revolution). Travel between two readings is `b.count.wrapping_sub(a.count)`
    /// read as `i32`.
    pub count: u32,
    /// The count latched at the last index pulse since the previous sample, `None`
    /// when there was none. It is `m N` modulo `2^32` for the pulse at
    /// `theta = 2 pi m`, in either direction of travel: the count of the index
    /// position itself, as an index gated to one quadrature state gives.
    pub index_count: Option<u32>,
    /// Whether an index pulse has been seen at all since the encoder started: until
    /// then the controller knows the count's phase only from the counter's start
    /// value.
    pub index_seen: bool,
}

/// A rotor's quadrature encoder (after x4 decoding) with one index pulse per
/// revolution, read at discrete instants.
///
/// The counter is a 32-bit hardware timer in encoder mode (as STM32 TIM2 and TIM5):
/// it wraps at `2^32` counts, 1e6 revolutions at 4096 counts per revolution, and the
/// controller differences readings with `wrapping_sub`. It starts at the absolute
/// value `floor(theta N / (2 pi))` (as if zeroed at an index pulse before `t = 0`).
/// Edge timing jitter, standard deviation `sigma` (s), is modelled as the angle taken
/// at a shifted time, `theta(t + dt) = theta + theta' dt` with `dt ~ N(0, sigma^2)`,
/// before quantisation: one normal sample per reading, none when `sigma = 0`.
#[derive(Clone, Debug)]
pub struct Encoder {
    /// Counts per revolution `N`, >= 1.
    counts_per_rev: u32,
    /// The rotor's driven sense.
    sense: Sense,
    /// The eccentric angle at which the index pulse fires, rad.
    index_angle: f64,
    /// Standard deviation of the edge timing jitter, s.
    jitter: f64,
    /// The jitter's noise.
    noise: NoiseStream,
    /// `floor(count / N)` (unwrapped) at the previous sample: the revolution number
    /// whose index crossings the next sample compares against.
    revolution: i64,
    /// Whether an index pulse has been seen since the start.
    index_seen: bool,
}

impl Encoder {
    /// An encoder of `counts_per_rev` counts per revolution (0 is taken as 1) on a
    /// rotor of this `sense` and `index_angle` (rad), with edge jitter `jitter` (s),
    /// starting where the eccentric angle is `phi0` (rad), its noise from `noise`.
    pub fn new(
        counts_per_rev: u32,
        sense: Sense,
        index_angle: f64,
        jitter: f64,
        phi0: f64,
        noise: NoiseStream,
    ) -> Self {
        let mut encoder = Encoder {
            counts_per_rev: counts_per_rev.max(1),
            sense,
            index_angle,
            jitter,
            noise,
            revolution: 0,
            index_seen: false,
        };
        // The reference revolution from the exact start angle (no jitter drawn).
        let theta0 = encoder_angle(sense, index_angle, phi0);
        encoder.revolution = encoder.revolution_of(encoder.unwrapped_count(theta0));
        encoder
    }

    /// The encoder of rotor `n` (0 or 1) of a machine, at the rotor's start angle, its
    /// jitter from the stream [`Channel::Encoder`]`(n)` of `seed`.
    pub fn for_rotor(n: usize, rotor: &Rotor, sensors: &Sensors, seed: u64) -> Self {
        Encoder::new(
            sensors.encoder_counts,
            rotor.sense,
            rotor.index_angle,
            sensors.encoder_jitter,
            rotor.angle,
            NoiseStream::new(seed, Channel::Encoder(n)),
        )
    }

    /// Counts per revolution.
    pub fn counts_per_rev(&self) -> u32 {
        self.counts_per_rev
    }

    /// Reads the encoder at time `t` (s), the rotor's eccentric angle `phi` (rad, not
    /// wrapped) and its rate `phi_dot` (rad/s), both in the platform frame.
    ///
    /// Stages: the jittered encoder angle; its count; the index crossings since the
    /// previous sample, found by comparing revolution numbers so that any number of
    /// counts and pulses between samples is caught. A pulse crossed and crossed back
    /// between two samples leaves no trace (the revolution number is unchanged),
    /// as with an index flag polled at the control tick.
    pub fn sample(&mut self, t: f64, phi: f64, phi_dot: f64) -> EncoderReading {
        // The jittered angle and its count.
        let theta = self.jittered_angle(phi, phi_dot);
        let count = self.unwrapped_count(theta);
        // Index pulses fire where the count crosses a multiple of N; going up the
        // last one crossed is at the new revolution, going down at the one above it.
        let revolution = self.revolution_of(count);
        let last_index = match revolution.cmp(&self.revolution) {
            std::cmp::Ordering::Greater => Some(revolution),
            std::cmp::Ordering::Less => Some(revolution + 1),
            std::cmp::Ordering::Equal => None,
        };
        self.revolution = revolution;
        self.index_seen |= last_index.is_some();
        let n = i64::from(self.counts_per_rev);
        EncoderReading {
            t,
            count: wrap(count),
            index_count: last_index.map(|m| wrap(m.wrapping_mul(n))),
            index_seen: self.index_seen,
        }
    }

    /// `theta + theta' dt`, `dt ~ N(0, sigma^2)`, with `theta' = s phi'`.
    fn jittered_angle(&mut self, phi: f64, phi_dot: f64) -> f64 {
        let theta = encoder_angle(self.sense, self.index_angle, phi);
        if self.jitter == 0.0 {
            return theta;
        }
        let dt = self.jitter * self.noise.standard_normal();
        theta + self.sense.sign() * phi_dot * dt
    }

    /// `floor(theta N / (2 pi))` without wrapping (saturating far beyond any run;
    /// NaN gives 0).
    fn unwrapped_count(&self, theta: f64) -> i64 {
        (theta * f64::from(self.counts_per_rev) / TAU).floor() as i64
    }

    /// `floor(count / N)`.
    fn revolution_of(&self, count: i64) -> i64 {
        count.div_euclid(i64::from(self.counts_per_rev))
    }
}

/// An unwrapped count as the 32-bit counter shows it: modulo `2^32`.
fn wrap(count: i64) -> u32 {
    count as u32
}

/// A winding's current measurement (shunt and ADC), in the motor's driven sense:
/// `i_measured = i + offset + n`, `n ~ N(0, sigma^2)`.
#[derive(Clone, Debug)]
pub struct CurrentSensor {
    /// Standard deviation of the noise, A (one normal sample per reading when > 0,
    /// none when 0).
    pub noise_std: f64,
    /// A constant offset, A: 0 for a healthy sensor, set for fault injection.
    pub offset: f64,
    /// The noise.
    noise: NoiseStream,
}

impl CurrentSensor {
    /// A sensor with noise `noise_std` (A) drawn from `noise`, no offset.
    pub fn new(noise_std: f64, noise: NoiseStream) -> Self {
        CurrentSensor {
            noise_std,
            offset: 0.0,
            noise,
        }
    }

    /// The current sensor of rotor `n` (0 or 1) of a machine, its noise from the
    /// stream [`Channel::Current`]`(n)` of `seed`.
    pub fn for_rotor(n: usize, sensors: &Sensors, seed: u64) -> Self {
        CurrentSensor::new(
            sensors.current_noise,
            NoiseStream::new(seed, Channel::Current(n)),
        )
    }

    /// Measures the winding current `i` (A): `i + offset + N(0, sigma^2)`.
    pub fn measure(&mut self, i: f64) -> f64 {
        let reading = i + self.offset;
        if self.noise_std == 0.0 {
            return reading;
        }
        reading + self.noise_std * self.noise.standard_normal()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: u32 = 4096;
    /// One count, rad.
    const COUNT: f64 = TAU / N as f64;

    /// A noiseless encoder on a rotor with index angle 0.3 rad, starting at theta = 0.1.
    fn encoder(sense: Sense, counts: u32) -> Encoder {
        let phi0 = 0.3 + sense.sign() * 0.1;
        Encoder::new(
            counts,
            sense,
            0.3,
            0.0,
            phi0,
            NoiseStream::new(1, Channel::Encoder(0)),
        )
    }

    /// The eccentric angle where a ccw rotor with index angle 0.3 has `theta`.
    fn phi_ccw(theta: f64) -> f64 {
        0.3 + theta
    }

    #[test]
    fn counts_are_exact_floors_at_known_angles() {
        let mut e = encoder(Sense::Ccw, N);
        // Within a count, a quarter and three quarters in: floor is the count itself.
        for k in [0i64, 1, 7, 4095, 4096, 123_457, -1, -4096, -4097] {
            for frac in [0.25, 0.75] {
                let theta = (k as f64 + frac) * COUNT;
                let r = e.sample(0.0, phi_ccw(theta), 0.0);
                assert_eq!(r.count, k as u32, "k = {k}, frac = {frac}");
            }
        }
        // Exactly at the index angle: count 0.
        let r = e.sample(0.0, 0.3, 0.0);
        assert_eq!(r.count, 0);
        // Negative counts read as the wrapped counter.
        let r = e.sample(0.0, phi_ccw(-2.5 * COUNT), 0.0);
        assert_eq!(r.count, u32::MAX - 2);
    }

    #[test]
    fn counter_wraps_at_2_pow_32_like_a_hardware_timer() {
        let mut e = encoder(Sense::Ccw, N);
        // Just below 2^32 counts (about 1e6 revolutions), then 20 counts on.
        let start = (1u64 << 32) as f64 - 10.0;
        let a = e.sample(0.0, phi_ccw((start + 0.5) * COUNT), 0.0);
        assert_eq!(a.count, u32::MAX - 9);
        let b = e.sample(0.001, phi_ccw((start + 20.5) * COUNT), 0.0);
        assert_eq!(b.count, 10);
        assert_eq!(b.count.wrapping_sub(a.count), 20);
        // Backwards through zero: 5 down to -5 is -10 counts.
        let c = e.sample(0.002, phi_ccw(5.5 * COUNT), 0.0);
        let d = e.sample(0.003, phi_ccw(-4.5 * COUNT), 0.0);
        assert_eq!(d.count.wrapping_sub(c.count) as i32, -10);
        // The index at 2^32 counts (revolution 2^20) latches 0 after wrapping.
        let mut f = encoder(Sense::Ccw, N);
        f.sample(0.0, phi_ccw((start + 0.5) * COUNT), 0.0);
        let g = f.sample(0.001, phi_ccw((start + 20.5) * COUNT), 0.0);
        assert_eq!(g.index_count, Some(0));
    }

    #[test]
    fn index_crossings_are_caught_in_both_directions_and_across_many_counts() {
        let mut e = encoder(Sense::Ccw, N);
        // Start at theta = 0.1 rad (revolution 0): no pulse yet.
        let r = e.sample(0.0, phi_ccw(0.1), 0.0);
        assert_eq!((r.index_count, r.index_seen), (None, false));
        // Up by 3.6 revolutions in one sample (14745 counts): pulses at 1, 2, 3 rev,
        // the last latched.
        let r = e.sample(0.001, phi_ccw(3.7 * TAU), 0.0);
        assert_eq!(r.index_count, Some(3 * N));
        assert!(r.index_seen);
        // Within revolution 3: none new, but one has been seen.
        let r = e.sample(0.002, phi_ccw(3.9 * TAU), 0.0);
        assert_eq!((r.index_count, r.index_seen), (None, true));
        // Down to 0.1 rev: pulses at 3, 2, 1 rev, the last one crossed is 1 rev.
        let r = e.sample(0.003, phi_ccw(0.1 * TAU), 0.0);
        assert_eq!(r.index_count, Some(N));
        // Down through the index itself: 0 rev, count 0.
        let r = e.sample(0.004, phi_ccw(-0.1 * TAU), 0.0);
        assert_eq!(r.index_count, Some(0));
        // Up through it again: the same latched count, direction-independent.
        let r = e.sample(0.005, phi_ccw(0.05 * TAU), 0.0);
        assert_eq!(r.index_count, Some(0));
        // Down below: the pulse at -1 rev latches -N.
        let r = e.sample(0.006, phi_ccw(-1.5 * TAU), 0.0);
        assert_eq!(r.index_count, Some((-(N as i64)) as u32));
        // Sampled again in the same revolution: nothing new.
        let r = e.sample(0.007, phi_ccw(-1.2 * TAU), 0.0);
        assert_eq!(r.index_count, None);
    }

    #[test]
    fn index_fires_at_the_index_angle_for_each_sense() {
        // The pulse sits at phi = index_angle; count 0 there in both senses.
        for sense in [Sense::Ccw, Sense::Cw] {
            let mut e = encoder(sense, N);
            let s = sense.sign();
            e.sample(0.0, 0.3 + s * 0.5, 0.0);
            let r = e.sample(0.001, 0.3 - s * 0.5 * COUNT, 0.0);
            assert_eq!(r.index_count, Some(0), "{sense:?}");
            assert_eq!(r.count, u32::MAX, "{sense:?}");
        }
    }

    #[test]
    fn cw_rotor_counts_up_when_driven_forward() {
        // Driven forward, a cw rotor's phi decreases and theta = -(phi - index) grows.
        let mut e = encoder(Sense::Cw, N);
        let mut last = e.sample(0.0, 0.3 - 0.1, -100.0);
        for step in 1..=100 {
            let phi = 0.3 - 0.1 - 0.1 * step as f64;
            let r = e.sample(step as f64 * 1e-3, phi, -100.0);
            let travelled = r.count.wrapping_sub(last.count) as i32;
            assert!(travelled > 0, "step {step}: {travelled}");
            last = r;
        }
        // 10 rad of travel is 10 / (2 pi) N counts.
        let expected = ((0.1 + 10.0) / COUNT).floor() as u32;
        assert_eq!(last.count, expected);
        assert!(last.index_seen);
    }

    #[test]
    fn zero_noise_gives_exact_values() {
        // No jitter: the count is the floor of the exact angle, whatever the speed.
        let mut e = encoder(Sense::Ccw, N);
        let theta = 17.25 * COUNT;
        assert_eq!(e.sample(0.0, phi_ccw(theta), 1e4).count, 17);
        // No current noise: the reading is the current (plus the offset) exactly.
        let mut c = CurrentSensor::new(0.0, NoiseStream::new(3, Channel::Current(0)));
        for i in [0.0, 1.234_567_890_123, -2.0, 1e-300] {
            assert_eq!(c.measure(i), i);
        }
        c.offset = 0.25;
        assert_eq!(c.measure(1.5), 1.75);
    }

    /// Mean, standard deviation and the fraction within one standard deviation of the
    /// mean `mu` for `sigma`.
    fn statistics(xs: &[f64], mu: f64, sigma: f64) -> (f64, f64, f64) {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let within = xs.iter().filter(|x| (*x - mu).abs() < sigma).count() as f64 / n;
        (mean, var.sqrt(), within)
    }

    /// Checks samples of `N(mu, sigma^2)` at 5 standard deviations of each estimator:
    /// the mean's `sigma / sqrt(n)`, the sample standard deviation's
    /// `sigma / sqrt(2 (n - 1))`, and the binomial `sqrt(p (1 - p) / n)` of the
    /// fraction within one sigma, `p = erf(1 / sqrt 2) = 0.682689`. A false failure at
    /// 5 sigma has probability 6e-7 per check, and the seed is fixed anyway; a wrong
    /// scale by 1 % or a wrong shape shows up.
    fn assert_normal(xs: &[f64], mu: f64, sigma: f64) {
        let n = xs.len() as f64;
        let (mean, sd, within) = statistics(xs, mu, sigma);
        assert!((mean - mu).abs() < 5.0 * sigma / n.sqrt(), "mean {mean}");
        assert!(
            (sd - sigma).abs() < 5.0 * sigma / (2.0 * (n - 1.0)).sqrt(),
            "sd {sd}"
        );
        let p = 0.682_689_492_137_086;
        assert!(
            (within - p).abs() < 5.0 * (p * (1.0 - p) / n).sqrt(),
            "within {within}"
        );
    }

    #[test]
    fn current_noise_has_the_right_mean_and_standard_deviation() {
        let mut c = CurrentSensor::new(0.05, NoiseStream::new(1, Channel::Current(1)));
        c.offset = -0.02;
        let xs: Vec<f64> = (0..200_000).map(|_| c.measure(1.3)).collect();
        assert_normal(&xs, 1.3 - 0.02, 0.05);
    }

    #[test]
    fn encoder_jitter_is_an_angle_error_of_speed_times_normal_time() {
        // sigma = 1 us at phi' = -300 rad/s on a cw rotor (forward): an angle error
        // of 3e-4 rad. A fine encoder (2^24 counts, 3.7e-7 rad) measures it through
        // the counts; the floor's bias of half a count and its 1/12 count^2 of variance
        // are below the tolerances (8.8 and 800 counts).
        let counts = 1u32 << 24;
        let count = TAU / f64::from(counts);
        let (sigma, phi_dot) = (1e-6, -300.0);
        let mut e = Encoder::new(
            counts,
            Sense::Cw,
            0.3,
            sigma,
            0.3,
            NoiseStream::new(9, Channel::Encoder(1)),
        );
        // theta = 1000.5 counts, held still except for the jitter.
        let phi = 0.3 - 1000.5 * count;
        let xs: Vec<f64> = (0..200_000)
            .map(|k| f64::from(e.sample(k as f64 * 1e-3, phi, phi_dot).count as i32) + 0.5)
            .collect();
        assert_normal(&xs, 1000.5, 300.0 * sigma / count);
        // At standstill timing jitter moves nothing.
        assert_eq!(e.sample(0.0, phi, 0.0).count, 1000);
    }

    #[test]
    fn same_seed_gives_identical_noise_whatever_else_is_sampled() {
        let run = |seed: u64, interleave: bool| {
            let mut c = CurrentSensor::new(0.1, NoiseStream::new(seed, Channel::Current(0)));
            let mut other = CurrentSensor::new(0.1, NoiseStream::new(seed, Channel::Current(1)));
            let mut e = Encoder::new(
                N,
                Sense::Ccw,
                0.0,
                1e-5,
                0.0,
                NoiseStream::new(seed, Channel::Encoder(0)),
            );
            (0..1000)
                .map(|k| {
                    if interleave {
                        other.measure(0.0);
                    }
                    let phi = k as f64 * 0.01;
                    (
                        c.measure(0.5).to_bits(),
                        e.sample(k as f64 * 1e-3, phi, 300.0).count,
                    )
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(run(7, false), run(7, false));
        assert_eq!(run(7, false), run(7, true));
        assert_ne!(run(7, false), run(8, false));
        // Different channels under one seed are different streams.
        let mut a = NoiseStream::new(7, Channel::Current(0));
        let mut b = NoiseStream::new(7, Channel::Current(1));
        let mut c = NoiseStream::new(7, Channel::Encoder(0));
        let (xa, xb, xc) = (
            a.standard_normal(),
            b.standard_normal(),
            c.standard_normal(),
        );
        assert!(xa != xb && xa != xc && xb != xc);
    }

    #[test]
    fn a_cloned_stream_continues_identically() {
        let mut a = NoiseStream::new(5, Channel::Encoder(0));
        for _ in 0..3 {
            a.standard_normal();
        }
        let mut b = a.clone();
        for _ in 0..100 {
            assert_eq!(a.standard_normal().to_bits(), b.standard_normal().to_bits());
        }
    }

    #[test]
    fn channel_streams_are_distinct() {
        let ids = [
            Channel::Encoder(0),
            Channel::Encoder(1),
            Channel::Current(0),
            Channel::Current(1),
        ]
        .map(Channel::stream);
        for (k, a) in ids.iter().enumerate() {
            assert!(ids[k + 1..].iter().all(|b| a != b));
        }
    }
}
