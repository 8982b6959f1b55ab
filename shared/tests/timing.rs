//! `shared::timing::TickClock`: lateness from the timer latency and from the
//! interval between starts, the previous tick's duration, the counter's wrap.

use shared::timing::TickClock;

/// 168 MHz, 1 kHz ticks.
const HZ: u32 = 168_000_000;
const PERIOD: u32 = 168_000;

fn us(cycles: u32) -> f32 {
    cycles as f32 / HZ as f32 * 1e6
}

#[test]
fn on_time_ticks_are_not_late_and_report_the_previous_duration() {
    let mut c = TickClock::new(HZ, PERIOD);
    let first = c.begin(1_000, 300);
    assert!((first.late_s * 1e6 - us(300)).abs() < 1e-3);
    assert_eq!(first.busy_s, 0.0, "no previous tick");
    c.end(1_000 + 1_680); // 10 us of work
    let second = c.begin(1_000 + PERIOD, 300);
    assert!((second.late_s * 1e6 - us(300)).abs() < 1e-3);
    assert!((second.busy_s * 1e6 - 10.0).abs() < 1e-3);
}

#[test]
fn a_tick_delayed_past_a_whole_period_is_late_by_the_interval() {
    // The timer wrapped once more: its latency reads small (20 us), but the start
    // came 2.1 periods after the previous one: 1.1 ms late.
    let mut c = TickClock::new(HZ, PERIOD);
    c.begin(0, 0);
    c.end(1_000);
    let t = c.begin(2 * PERIOD + PERIOD / 10, 3_360);
    assert!((t.late_s - 1.1e-3).abs() < 1e-7, "{t:?}");
}

#[test]
fn a_late_tick_followed_by_an_early_one_counts_only_the_late_one() {
    let mut c = TickClock::new(HZ, PERIOD);
    c.begin(0, 0);
    let late = c.begin(PERIOD + 50_400, 50_400); // 300 us late, both ways
    assert!((late.late_s - 300e-6).abs() < 1e-8);
    let next = c.begin(2 * PERIOD, 0); // on schedule again: 0.7 periods later
    assert_eq!(next.late_s, 0.0);
}

#[test]
fn the_counter_wraps() {
    let mut c = TickClock::new(HZ, PERIOD);
    let start = u32::MAX - 1_000;
    c.begin(start, 0);
    c.end(start.wrapping_add(3_360)); // 20 us across the wrap
    let t = c.begin(start.wrapping_add(PERIOD), 0);
    assert_eq!(t.late_s, 0.0);
    assert!((t.busy_s - 20e-6).abs() < 1e-9);
}

#[test]
fn a_long_tick_shows_in_the_next_ones_busy() {
    // 600 us of work (over the controller's budget of half a tick, 500 us) is
    // what the next tick reports.
    let mut c = TickClock::new(HZ, PERIOD);
    c.begin(0, 0);
    c.end(100_800);
    let t = c.begin(PERIOD, 0);
    assert!((t.busy_s - 600e-6).abs() < 1e-8);
}
