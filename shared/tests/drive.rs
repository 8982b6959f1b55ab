//! The H-bridge driver (`shared::drive`) over mock PWM outputs: the duty mapping
//! of both decay modes against the DRV8871's logic table, the order of the writes
//! on a reversal, clamping, NaN, the cut, and an input that fails.

use std::cell::RefCell;
use std::convert::Infallible;
use std::rc::Rc;

use embedded_hal::pwm::{ErrorType, SetDutyCycle};
use proptest::prelude::*;
use shared::drive::{compare, input_duties, period, BridgeError, Connection, Decay, HBridge, Part};

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

/// A bridge over two mocks of 8400 steps (TIM8 at 168 MHz, 20 kHz), and its log.
fn bridge(decay: Decay) -> (HBridge<Mock, Mock>, Log) {
    let log: Log = Rc::new(RefCell::new(Vec::new()));
    let mock = |input| Mock {
        input,
        max: 8400,
        log: log.clone(),
    };
    (HBridge::new(mock(1), mock(2), decay), log)
}

/// The mean winding voltage over a period, as a fraction of the supply, from the
/// parts of the period when every part conducts (no coast).
fn mean_voltage(parts: &[Part]) -> f32 {
    let mut start = 0.0;
    let mut v = 0.0;
    for p in parts {
        let u = match p.connection {
            Connection::Forward => 1.0,
            Connection::Reverse => -1.0,
            Connection::Short => 0.0,
            Connection::Open => f32::NAN,
        };
        v += (p.end - start) * u;
        start = p.end;
    }
    v
}

#[test]
fn slow_decay_drives_then_brakes_with_mean_voltage_d_vs() {
    // Forward 0.3: IN1 held high, IN2 high 70 % of the period: brake for 0.7, then
    // forward for 0.3 (the DRV8871's 1/1 then 1/0).
    assert_eq!(input_duties(0.3, Decay::Slow), [1.0, 0.7]);
    let parts = period(input_duties(0.3, Decay::Slow));
    assert_eq!(parts[0].connection, Connection::Short);
    assert!((parts[0].end - 0.7).abs() < 1e-6);
    assert_eq!(
        parts[1],
        Part {
            end: 1.0,
            connection: Connection::Forward
        }
    );
    assert_eq!(parts.len(), 2);
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
fn fast_decay_drives_then_coasts() {
    assert_eq!(input_duties(0.3, Decay::Fast), [0.3, 0.0]);
    assert_eq!(input_duties(-0.3, Decay::Fast), [0.0, 0.3]);
    let parts = period(input_duties(0.3, Decay::Fast));
    assert_eq!(
        parts.as_slice(),
        &[
            Part {
                end: 0.3,
                connection: Connection::Forward
            },
            Part {
                end: 1.0,
                connection: Connection::Open
            },
        ]
    );
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
        prop_assert!((mean_voltage(&parts) - d).abs() < 1e-6);
        prop_assert_eq!(parts.last().unwrap().end, 1.0);
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

/// A reversal passes through the decay mode's own off-state if the timer's
/// update event falls between the two writes. Fast decay, forward (IN1 PWM, IN2
/// low) to reverse: the falling input first, so the period in between coasts and
/// never brakes. Slow decay, forward (IN1 high, IN2 PWM) to reverse (IN1 PWM, IN2
/// high): the rising input first, so the period in between brakes (both high)
/// and never coasts or drives.
#[test]
fn reversal_passes_through_the_decay_modes_off_state() {
    let (mut b, log) = bridge(Decay::Fast);
    b.drive(0.6).unwrap();
    log.borrow_mut().clear();
    b.drive(-0.4).unwrap();
    assert_eq!(log.borrow().as_slice(), &[(1, 0), (2, 3360)]);
    assert_eq!(
        period([0.0, 0.0]).as_slice(),
        &[Part {
            end: 1.0,
            connection: Connection::Open
        }]
    );
    log.borrow_mut().clear();
    b.drive(0.2).unwrap();
    assert_eq!(log.borrow().as_slice(), &[(2, 0), (1, 1680)]);

    let (mut b, log) = bridge(Decay::Slow);
    b.drive(0.6).unwrap();
    log.borrow_mut().clear();
    b.drive(-0.4).unwrap();
    assert_eq!(log.borrow().as_slice(), &[(2, 8400), (1, 5040)]);
    // In between: IN1 still high, IN2 already high.
    assert_eq!(
        period([1.0, 1.0]).as_slice(),
        &[Part {
            end: 1.0,
            connection: Connection::Short
        }]
    );
    log.borrow_mut().clear();
    b.drive(0.3).unwrap();
    assert_eq!(log.borrow().as_slice(), &[(1, 8400), (2, 5880)]);
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
