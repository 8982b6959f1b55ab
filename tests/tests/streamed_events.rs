//! A run's events go to the observer tick by tick (so a long run keeps none in
//! memory): the batches, joined, are the run's events in time order, the same the
//! run keeps when asked, with the controller's state changes merged in; and the
//! summary counts the distinct impact times of them all.

use host_sim::event::{EventKind, EventRow};
use host_sim::simulation::closed_loop::ControllerDriver;
use host_sim::simulation::summary::impact_times;
use host_sim::simulation::{simulate_observed, Observer, RunOptions};
use shared::controller::{Command, Direction};
use tests::machine::TestMachine;

/// Collects the batches.
#[derive(Default)]
struct Batches(Vec<Vec<EventRow>>);

impl Observer for Batches {
    fn events(&mut self, batch: &[EventRow]) {
        self.0.push(batch.to_vec());
    }
}

fn run(keep_events: bool) -> (host_sim::simulation::RunResult, Batches) {
    let m = TestMachine::example().machine();
    let travel = Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    };
    let mut driver = ControllerDriver::new(&m, vec![(0.0, travel)]).expect("the controller");
    let mut options = RunOptions::new(1.5);
    options.keep_rows = false;
    options.keep_events = keep_events;
    let mut batches = Batches::default();
    let result = simulate_observed(&m, &mut driver, &options, &mut batches);
    (result, batches)
}

#[test]
fn events_stream_tick_by_tick_as_the_run_keeps_them() {
    let (kept, seen) = run(true);
    let (streamed, seen_too) = run(false);
    assert!(streamed.events.is_empty(), "kept without keep_events");
    let joined: Vec<EventRow> = seen.0.iter().flatten().cloned().collect();
    let joined_too: Vec<EventRow> = seen_too.0.iter().flatten().cloned().collect();
    assert_eq!(joined, kept.events);
    assert_eq!(joined_too, kept.events);
    // Many batches, each in time order and after the last.
    assert!(seen.0.len() > 100, "{} batches", seen.0.len());
    let mut last = f64::NEG_INFINITY;
    for e in &joined {
        assert!(e.t >= last, "{} after {}", e.t, last);
        last = e.t;
    }
    // Impacts and the controller's own events are both there.
    assert!(joined.iter().any(|e| e.kind == EventKind::Impact));
    assert!(
        joined.iter().any(|e| e.contact.is_empty()),
        "no controller event"
    );
    // The count is the distinct impact times of them all, kept or not.
    let impacts = impact_times(&kept.events).len();
    assert!(impacts > 100, "{impacts} impacts");
    assert_eq!(kept.summary.impacts, impacts);
    assert_eq!(streamed.summary.impacts, impacts);
    assert_eq!(kept.summary, streamed.summary);
}
