//! Tuning tables built from generated rows.

use shared::controller::TuningTable;

/// The table whose speeds are the running sums of the rows' first column (so they
/// rise), each with its row's right and left offsets.
pub fn table_from_steps(steps: Vec<(f32, f32, f32)>) -> TuningTable {
    let mut speed = 0.0;
    let rows: Vec<(f32, f32, f32)> = steps
        .into_iter()
        .map(|(step, right, left)| {
            speed += step;
            (speed, right, left)
        })
        .collect();
    TuningTable::from_rows(&rows).unwrap()
}
