//! The H-bridge driver (`shared::drive`) over mock PWM outputs: the duty mapping
//! of both decay modes against the DRV8871's logic table, the order of the writes
//! on a reversal, clamping, NaN, the cut, and an input that fails.

use std::cell::RefCell;
use std::convert::Infallible;
use std::rc::Rc;

use embedded_hal::pwm::{ErrorType, SetDutyCycle};
use proptest::prelude::*;
use shared::drive::{
    compare, input_duties, mean_fraction, period, BridgeConfig, BridgeError, CentreAligned,
    Connection, Decay, HBridge, Part, MAX_UPDATE_HZ,
};

/// Every write to either input, in order: (input 1 or 2, compare value).
type Log = Rc<RefCell<Vec<(u8, u16)>>>;

/// A PWM output of `max` steps that records its writes.
struct Mock {
    input: u8,
    max: u16,
    log: Log,
}

impl ErrorType for Mock {
    type Error = Infallible;
}

impl SetDutyCycle for Mock {
    fn max_duty_cycle(&self) -> u16 {
        self.max
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.log.borrow_mut().push((self.input, duty));
        Ok(())
    }
}

/// A bridge over two mocks of 8400 steps, and its log.
fn bridge(decay: Decay) -> (HBridge<Mock, Mock>, Log) {
    let log: Log = Rc::new(RefCell::new(Vec::new()));
    let mock = |input| Mock {
        input,
        max: 8400,
        log: log.clone(),
    };
    (HBridge::new(mock(1), mock(2), decay), log)
}

#[test]
fn slow_decay_brakes_around_the_valley_and_drives_around_the_peak() {
    // Forward 0.3: IN1 held high, IN2 high 70 % of the period around the valley:
    // brake for 0.35, forward for 0.3 around the peak, brake for 0.35 (the
    // DRV8871's 1/1, 1/0, 1/1).
    assert_eq!(input_duties(0.3, Decay::Slow), [1.0, 0.7]);
    let parts = period(input_duties(0.3, Decay::Slow));
    let ends: Vec<f32> = parts.iter().map(|p| p.end).collect();
    let connections: Vec<Connection> = parts.iter().map(|p| p.connection).collect();
    assert_eq!(
        connections,
        [Connection::Short, Connection::Forward, Connection::Short]
    );
    for (end, want) in ends.iter().zip([0.35, 0.65, 1.0]) {
        assert!((end - want).abs() < 1e-6, "{ends:?}");
    }
    // Reverse mirrored.
    assert_eq!(input_duties(-0.25, Decay::Slow), [0.75, 1.0]);
    // Duty 0 brakes the whole period; full duty drives it.
    assert_eq!(
        period(input_duties(0.0, Decay::Slow)).as_slice(),
        &[Part {
            end: 1.0,
            connection: Connection::Short
        }]
    );
    assert_eq!(
        period(input_duties(1.0, Decay::Slow)).as_slice(),
        &[Part {
            end: 1.0,
            connection: Connection::Forward
        }]
    );
    assert_eq!(
        period(input_duties(-1.0, Decay::Slow)).as_slice(),
        &[Part {
            end: 1.0,
            connection: Connection::Reverse
        }]
    );
}

#[test]
fn fast_decay_drives_then_coasts_centred_on_the_valley() {
    assert_eq!(input_duties(0.3, Decay::Fast), [0.3, 0.0]);
    assert_eq!(input_duties(-0.3, Decay::Fast), [0.0, 0.3]);
    // Forward around the valley (0.15 at each end of the period), coast across the
    // middle.
    let parts = period(input_duties(0.3, Decay::Fast));
    let connections: Vec<Connection> = parts.iter().map(|p| p.connection).collect();
    assert_eq!(
        connections,
        [Connection::Forward, Connection::Open, Connection::Forward]
    );
    assert!((parts[0].end - 0.15).abs() < 1e-6 && (parts[1].end - 0.85).abs() < 1e-6);
    assert_eq!(parts[2].end, 1.0);
    // Duty 0 coasts.
    assert_eq!(
        period(input_duties(0.0, Decay::Fast)).as_slice(),
        &[Part {
            end: 1.0,
            connection: Connection::Open
        }]
    );
}

proptest! {
    /// In slow decay the winding is never left open and its mean voltage is the
    /// duty (a fraction of the supply), in both directions.
    #[test]
    fn slow_decay_mean_voltage_is_the_duty(d in -1.0f32..=1.0) {
        let parts = period(input_duties(d, Decay::Slow));
        prop_assert!(parts.iter().all(|p| p.connection != Connection::Open));
        prop_assert!((mean_fraction(&parts).unwrap() - d).abs() < 1e-6);
        prop_assert_eq!(parts.last().unwrap().end, 1.0);
    }

    /// Whatever the inputs, each is high for its fraction of the period (IN1 in
    /// short and forward, IN2 in short and reverse), centred on the valley: the
    /// period reads the same backwards (mirrored about the peak at 0.5).
    #[test]
    fn each_input_is_high_for_its_fraction_centred_on_the_valley(a in 0.0f32..=1.0, b in 0.0f32..=1.0) {
        let parts = period([a, b]);
        prop_assert_eq!(parts.last().unwrap().end, 1.0);
        let mut start = 0.0;
        let (mut high1, mut high2) = (0.0, 0.0);
        let mut spans = Vec::new();
        for p in &parts {
            let len = p.end - start;
            prop_assert!(len > 0.0);
            match p.connection {
                Connection::Short => { high1 += len; high2 += len; }
                Connection::Forward => high1 += len,
                Connection::Reverse => high2 += len,
                Connection::Open => {}
            }
            spans.push((start, p.end, p.connection));
            start = p.end;
        }
        prop_assert!((high1 - a).abs() < 1e-6 && (high2 - b).abs() < 1e-6, "{parts:?}");
        // Mirror: the connection at t is the one at 1 - t.
        for k in 1..64 {
            let t = k as f32 / 64.0 + 1e-4;
            let at = |t: f32| spans.iter().find(|(s, e, _)| *s <= t && t < *e).map(|x| x.2);
            let (u, v) = (at(t), at(1.0 - t));
            let near_edge = spans.iter().any(|(s, e, _)| (s - t).abs() < 1e-3 || (e - t).abs() < 1e-3
                || (s - (1.0 - t)).abs() < 1e-3 || (e - (1.0 - t)).abs() < 1e-3);
            prop_assert!(near_edge || u == v, "t {t}: {u:?} vs {v:?} in {parts:?}");
        }
    }

    /// In fast decay the driven part is the duty, the rest coasts, and the two
    /// inputs are never high together (no brake).
    #[test]
    fn fast_decay_never_brakes(d in -1.0f32..=1.0) {
        let [a, b] = input_duties(d, Decay::Fast);
        prop_assert!(a == 0.0 || b == 0.0);
        let parts = period([a, b]);
        prop_assert!(parts.iter().all(|p| p.connection != Connection::Short));
        let driven: f32 = parts.iter().fold((0.0, 0.0), |(start, sum), p| {
            let len = p.end - start;
            (p.end, sum + if matches!(p.connection, Connection::Forward | Connection::Reverse) { len } else { 0.0 })
        }).1;
        prop_assert!((driven - d.abs()).abs() < 1e-6);
    }

    /// Whatever the duty and the decay, the compare values are within the timer's
    /// range and the driver wrote exactly `input_duties` rounded to it.
    #[test]
    fn written_values_round_the_mapping(d in -2.0f32..2.0, fast in any::<bool>()) {
        let decay = if fast { Decay::Fast } else { Decay::Slow };
        let (mut b, _) = bridge(decay);
        b.drive(d).unwrap();
        let f = input_duties(d, decay);
        prop_assert_eq!(b.written(), [compare(f[0], 8400), compare(f[1], 8400)]);
        prop_assert!(b.written().iter().all(|c| *c <= 8400));
    }
}

#[test]
fn duty_is_clamped_and_nan_coasts() {
    for decay in [Decay::Slow, Decay::Fast] {
        assert_eq!(input_duties(7.0, decay), input_duties(1.0, decay));
        assert_eq!(input_duties(-7.0, decay), input_duties(-1.0, decay));
        assert_eq!(input_duties(f32::NAN, decay), [0.0, 0.0]);
        assert_eq!(input_duties(f32::INFINITY, decay), input_duties(1.0, decay));
        let (mut b, _) = bridge(decay);
        b.drive(0.5).unwrap();
        b.drive(f32::NAN).unwrap();
        assert_eq!(b.written(), [0, 0], "{decay:?}: NaN coasts");
    }
    assert_eq!(compare(1.0, 8400), 8400);
    assert_eq!(compare(0.0, 8400), 0);
    assert_eq!(compare(f32::NAN, 8400), 0);
    assert_eq!(compare(0.5, 8400), 4200);
    assert_eq!(compare(1.5, 8400), 8400);
}

/// The inputs' high fractions in the period between the two writes of a change,
/// if the timer's update falls there: the first write's input new, the other as
/// `old` (the compare values before the change), over the mocks' 8400 steps.
fn between(old: [u16; 2], first: (u8, u16)) -> [f32; 2] {
    let mut mid = old;
    mid[usize::from(first.0 - 1)] = first.1;
    mid.map(|c| f32::from(c) / 8400.0)
}

/// A reversal passes through the decay mode's own off-state if the timer's
/// update event falls between the two writes. Fast decay, forward (IN1 PWM, IN2
/// low) to reverse and back: the falling input first, so the period in between
/// coasts and never brakes. Slow decay, forward (IN1 high, IN2 PWM) to reverse
/// (IN1 PWM, IN2 high) and back: the rising input first, so the period in
/// between brakes (both high) and never coasts or drives.
#[test]
fn reversal_passes_through_the_decay_modes_off_state() {
    type Change = (f32, [(u8, u16); 2]);
    let cases: [(Decay, f32, [Change; 2], Connection); 2] = [
        (
            Decay::Fast,
            0.6,
            [(-0.4, [(1, 0), (2, 3360)]), (0.2, [(2, 0), (1, 1680)])],
            Connection::Open,
        ),
        (
            Decay::Slow,
            0.6,
            [
                (-0.4, [(2, 8400), (1, 5040)]),
                (0.3, [(1, 8400), (2, 5880)]),
            ],
            Connection::Short,
        ),
    ];
    for (decay, start, changes, off) in cases {
        let (mut b, log) = bridge(decay);
        b.drive(start).unwrap();
        for (d, writes) in changes {
            let old = b.written();
            log.borrow_mut().clear();
            b.drive(d).unwrap();
            assert_eq!(log.borrow().as_slice(), &writes, "{decay:?} to {d}");
            assert_eq!(
                period(between(old, writes[0])).as_slice(),
                &[Part {
                    end: 1.0,
                    connection: off
                }],
                "{decay:?} to {d}: the period between the writes"
            );
        }
    }
}

proptest! {
    /// Any change while driving: the period between the two writes connects the
    /// winding only as the old period, the new one, or the decay mode's off-state
    /// (brake in slow decay, coast in fast) does: never the other way round.
    /// (Switching on from coast is not a change while driving: from both inputs
    /// low the two writes of a slow-decay duty both rise, and no order avoids a
    /// driven period in between; the firmware loads both at once there.)
    #[test]
    fn a_change_never_drives_the_way_neither_duty_does(
        d0 in -1.0f32..=1.0,
        d1 in -1.0f32..=1.0,
        fast in any::<bool>(),
    ) {
        let decay = if fast { Decay::Fast } else { Decay::Slow };
        let off = if fast { Connection::Open } else { Connection::Short };
        let (mut b, log) = bridge(decay);
        b.drive(d0).unwrap();
        let old = b.written();
        log.borrow_mut().clear();
        b.drive(d1).unwrap();
        let first = log.borrow()[0];
        let to_fractions = |c: [u16; 2]| c.map(|v| f32::from(v) / 8400.0);
        let allowed: Vec<Connection> = period(to_fractions(old))
            .iter()
            .chain(period(to_fractions(b.written())).iter())
            .map(|p| p.connection)
            .chain([off])
            .collect();
        for p in period(between(old, first)) {
            prop_assert!(
                allowed.contains(&p.connection),
                "{decay:?} {d0} -> {d1}: {:?} in between", p.connection
            );
        }
    }
}

#[test]
fn coast_writes_both_inputs_low() {
    for decay in [Decay::Slow, Decay::Fast] {
        let (mut b, log) = bridge(decay);
        assert_eq!(log.borrow().as_slice(), &[(1, 0), (2, 0)], "new() coasts");
        b.drive(-0.8).unwrap();
        b.coast().unwrap();
        assert_eq!(b.written(), [0, 0]);
        assert_eq!(
            period([0.0, 0.0]).as_slice(),
            &[Part {
                end: 1.0,
                connection: Connection::Open
            }]
        );
    }
}

/// An output that fails: the error names the input, and the driver leaves both
/// inputs low as far as it can.
#[test]
fn a_failing_input_is_reported_and_the_other_is_left_low() {
    struct Broken;
    impl ErrorType for Broken {
        type Error = embedded_hal::pwm::ErrorKind;
    }
    impl SetDutyCycle for Broken {
        fn max_duty_cycle(&self) -> u16 {
            100
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
            if duty == 0 {
                Ok(())
            } else {
                Err(embedded_hal::pwm::ErrorKind::Other)
            }
        }
    }
    let log: Log = Rc::new(RefCell::new(Vec::new()));
    let good = Mock {
        input: 1,
        max: 100,
        log: log.clone(),
    };
    let mut b = HBridge::new(good, Broken, Decay::Fast);
    assert_eq!(b.drive(0.5), Ok(()));
    assert_eq!(
        b.drive(-0.5),
        Err(BridgeError::In2(embedded_hal::pwm::ErrorKind::Other))
    );
    assert_eq!(b.written(), [0, 0]);
    assert_eq!(log.borrow().last(), Some(&(1, 0)));
}

/// The timer setup for centre-aligned PWM on TIM8's 168 MHz clock.
#[test]
fn centre_aligned_timer_setup() {
    let at = |pwm_hz| {
        CentreAligned::new(
            168_000_000,
            BridgeConfig {
                decay: Decay::Slow,
                pwm_hz,
            },
        )
    };
    assert_eq!(
        at(20_000),
        CentreAligned {
            psc: 0,
            arr: 4200,
            rcr: 1
        }
    );
    // 1 kHz needs the prescaler: 84 000 counts a half period do not fit 16 bits.
    assert_eq!(
        at(1_000),
        CentreAligned {
            psc: 1,
            arr: 42_000,
            rcr: 1
        }
    );
    // 200 kHz: an update (and a current sample) every 4 periods, 50 kHz.
    assert_eq!(at(200_000).rcr, 7);
    assert_eq!(at(200_000).arr, 420);
}

proptest! {
    /// Over the machine file's range of PWM frequencies the setup fits the
    /// registers, gives the frequency to within one count of the half period, and
    /// never updates faster than the ADC can sample.
    #[test]
    fn centre_aligned_setup_fits_and_is_accurate(pwm_hz in 1_000u32..=200_000) {
        let config = BridgeConfig { decay: Decay::Slow, pwm_hz };
        let t = CentreAligned::new(168_000_000, config);
        prop_assert!(t.arr >= 400);
        let f = t.pwm_hz(168_000_000);
        prop_assert!(((f - f64::from(pwm_hz)) / f64::from(pwm_hz)).abs() < 1.0 / f64::from(t.arr), "{t:?}: {f} Hz");
        let k = config.periods_per_update();
        prop_assert_eq!(u32::from(t.rcr), 2 * k - 1);
        prop_assert!(f64::from(pwm_hz) / f64::from(k) <= f64::from(MAX_UPDATE_HZ));
        prop_assert!(k == 1 || f64::from(pwm_hz) / f64::from(k - 1) > f64::from(MAX_UPDATE_HZ));
    }
}
