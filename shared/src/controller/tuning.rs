//! The tuning table: the best phase offset for rightward and for leftward travel at
//! each rotor speed, as `host-sim tune --write` finds it on the simulator and the
//! machine file's `[controller].tuning_table` names it.
//!
//! Between two rows the offset is interpolated linearly in speed and *circularly* in
//! offset (along the shorter arc, [`lerp_deg`]): rows at 350 and 10 degrees give 0
//! half-way, not 180. Outside the table's speed range the nearest row holds. Without
//! a table the default is 90 degrees for right and 270 for left at every speed: the
//! force along `offset / 2` (docs/machine-file.md, "Conventions") then leans 45
//! degrees from the vertical, up and right (or up and left) every revolution.
//!
//! The rule for rows is [`TuningTable::from_rows`] with [`RowField::check`]: 1 to
//! [`MAX_TUNING_ROWS`] rows, speeds > 0 rpm and strictly increasing, offsets in
//! [0, 360) degrees. The tuning file's reader (host-sim and the firmware's build),
//! the device link (a table it receives) and the flash record all apply it.

use core::fmt;

use super::angle::{lerp_deg, wrap_deg, TURN_DEG};
use super::Direction;

/// Most rows a [`TuningTable`] holds by default (a sweep every 100 rpm from 0 to
/// 3100 rpm, or every 250 up to 7750).
pub const MAX_TUNING_ROWS: usize = 32;

/// The default offset for rightward travel, degrees.
pub const DEFAULT_RIGHT_OFFSET_DEG: f32 = 90.0;
/// The default offset for leftward travel, degrees.
pub const DEFAULT_LEFT_OFFSET_DEG: f32 = 270.0;

/// The speed of the default table's one row, rpm. One row holds at every speed, so
/// its speed only has to be a valid one (> 0): 300 rpm, the lowest speed a run may
/// ask for (`min_speed_rpm` of [`super::Params::from_machine`]), where the phase
/// loop joins.
pub const DEFAULT_ROW_SPEED_RPM: f32 = 300.0;

/// One row of a tuning table.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TuningRow {
    /// Rotor speed, rpm, > 0.
    pub speed_rpm: f32,
    /// Best offset for rightward travel at this speed, degrees in [0, 360).
    pub right_offset_deg: f32,
    /// Best offset for leftward travel at this speed, degrees in [0, 360).
    pub left_offset_deg: f32,
}

impl TuningRow {
    /// The offset of `direction` in this row, degrees.
    pub fn offset(&self, direction: Direction) -> f32 {
        match direction {
            Direction::Right => self.right_offset_deg,
            Direction::Left => self.left_offset_deg,
        }
    }
}

/// A value of a row, named as [`TuningRow`]'s fields and the tuning file's keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RowField {
    /// `speed_rpm`.
    Speed,
    /// `right_offset_deg`.
    RightOffset,
    /// `left_offset_deg`.
    LeftOffset,
}

impl RowField {
    /// The values of a row, in the order of `(speed_rpm, right_offset_deg,
    /// left_offset_deg)`.
    pub const ALL: [RowField; 3] = [RowField::Speed, RowField::RightOffset, RowField::LeftOffset];

    /// The field's name, as the tuning file's key.
    pub fn key(self) -> &'static str {
        match self {
            RowField::Speed => "speed_rpm",
            RowField::RightOffset => "right_offset_deg",
            RowField::LeftOffset => "left_offset_deg",
        }
    }

    /// What a value of this field must be, as in "must be > 0".
    pub fn requirement(self) -> &'static str {
        match self {
            RowField::Speed => "> 0",
            RowField::RightOffset | RowField::LeftOffset => "in [0, 360)",
        }
    }

    /// The rule for one value of row `row` on its own: finite; a speed > 0 (a row
    /// is the best offset *while turning*; the controller never runs at 0 rpm); an
    /// offset in [0, 360) degrees (one turn, each offset written once: 360 is 0).
    /// `None` when `x` passes.
    pub fn check(self, row: usize, x: f32) -> Option<TableError> {
        let field = self;
        if !x.is_finite() {
            return Some(TableError::NotFinite { row, field });
        }
        let ok = match self {
            RowField::Speed => x > 0.0,
            RowField::RightOffset | RowField::LeftOffset => (0.0..TURN_DEG).contains(&x),
        };
        match (ok, self) {
            (true, _) => None,
            (false, RowField::Speed) => Some(TableError::SpeedNotPositive { row }),
            (false, _) => Some(TableError::OffsetOutOfRange { row, field }),
        }
    }
}

/// Why rows do not make a tuning table. `row` counts from 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TableError {
    /// No row at all.
    Empty,
    /// More rows than the table holds.
    TooManyRows {
        /// Rows given.
        rows: usize,
        /// Rows the table holds.
        capacity: usize,
    },
    /// A value is NaN or infinite.
    NotFinite {
        /// The row.
        row: usize,
        /// The value.
        field: RowField,
    },
    /// A speed of 0 or below.
    SpeedNotPositive {
        /// The row.
        row: usize,
    },
    /// A speed not above the previous row's (speeds must increase strictly).
    SpeedsNotIncreasing {
        /// The row.
        row: usize,
    },
    /// An offset outside [0, 360) degrees.
    OffsetOutOfRange {
        /// The row.
        row: usize,
        /// The offset.
        field: RowField,
    },
}

impl TableError {
    /// What the rows must be, as in "must be > 0".
    pub fn requirement(&self) -> &'static str {
        match self {
            TableError::Empty => "at least one row",
            TableError::TooManyRows { .. } => "at most as many rows as the table holds",
            TableError::NotFinite { .. } => "a finite number",
            TableError::SpeedNotPositive { .. } => RowField::Speed.requirement(),
            TableError::SpeedsNotIncreasing { .. } => "above the previous row's speed",
            TableError::OffsetOutOfRange { field, .. } => field.requirement(),
        }
    }
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableError::Empty => write!(f, "the tuning table has no row"),
            TableError::TooManyRows { rows, capacity } => write!(
                f,
                "the tuning table has {rows} rows, at most {capacity} are allowed"
            ),
            TableError::NotFinite { row, field } | TableError::OffsetOutOfRange { row, field } => {
                write!(
                    f,
                    "row {row}: {} must be {}",
                    field.key(),
                    self.requirement()
                )
            }
            TableError::SpeedNotPositive { row } | TableError::SpeedsNotIncreasing { row } => {
                write!(f, "row {row}: speed_rpm must be {}", self.requirement())
            }
        }
    }
}

/// Speed -> best offset for right and left travel, up to `N` rows sorted by speed.
#[derive(Clone, Debug, PartialEq)]
pub struct TuningTable<const N: usize = MAX_TUNING_ROWS> {
    /// Rows, speeds strictly increasing, offsets in [0, 360).
    rows: heapless::Vec<TuningRow, N>,
}

impl<const N: usize> Default for TuningTable<N> {
    /// [`TuningTable::default_offsets`].
    fn default() -> Self {
        TuningTable::default_offsets()
    }
}

impl<const N: usize> TuningTable<N> {
    /// The default: one row (at [`DEFAULT_ROW_SPEED_RPM`]), 90 degrees right and 270
    /// left at every speed (empty if `N` is 0, which [`TuningTable::offset`] treats
    /// the same way).
    pub fn default_offsets() -> Self {
        let mut rows = heapless::Vec::new();
        // Fails only when N == 0; the empty table gives the same offsets.
        let _ = rows.push(TuningRow {
            speed_rpm: DEFAULT_ROW_SPEED_RPM,
            right_offset_deg: DEFAULT_RIGHT_OFFSET_DEG,
            left_offset_deg: DEFAULT_LEFT_OFFSET_DEG,
        });
        TuningTable { rows }
    }

    /// A table from `(speed_rpm, right_offset_deg, left_offset_deg)` rows: at least
    /// one, at most `N`; each value by [`RowField::check`] (finite, speeds > 0,
    /// offsets in [0, 360)); speeds strictly increasing. The one rule for a tuning
    /// table: the tuning file's reader, the device link and the flash record all
    /// take rows through it.
    pub fn from_rows(rows: &[(f32, f32, f32)]) -> Result<Self, TableError> {
        if rows.is_empty() {
            return Err(TableError::Empty);
        }
        if rows.len() > N {
            return Err(TableError::TooManyRows {
                rows: rows.len(),
                capacity: N,
            });
        }
        let mut table = heapless::Vec::new();
        let mut previous: Option<f32> = None;
        for (row, &(speed, right, left)) in rows.iter().enumerate() {
            let values = RowField::ALL.into_iter().zip([speed, right, left]);
            if let Some(e) = values.filter_map(|(field, x)| field.check(row, x)).next() {
                return Err(e);
            }
            if previous.is_some_and(|p| speed <= p) {
                return Err(TableError::SpeedsNotIncreasing { row });
            }
            previous = Some(speed);
            // In [0, 360) already; a -0 is stored as +0.
            let pushed = table.push(TuningRow {
                speed_rpm: speed,
                right_offset_deg: wrap_deg(right),
                left_offset_deg: wrap_deg(left),
            });
            // Cannot fail: rows.len() <= N was checked.
            if pushed.is_err() {
                return Err(TableError::TooManyRows {
                    rows: rows.len(),
                    capacity: N,
                });
            }
        }
        Ok(TuningTable { rows: table })
    }

    /// The rows, speeds increasing.
    pub fn rows(&self) -> &[TuningRow] {
        &self.rows
    }

    /// The offset for travel in `direction` at `speed_rpm`, degrees in [0, 360):
    /// linear in speed between the two neighbouring rows, along the shorter arc in
    /// offset; the first (last) row below (above) the table; the first row for a
    /// NaN speed; the defaults (90 / 270) for an empty table.
    pub fn offset(&self, direction: Direction, speed_rpm: f32) -> f32 {
        let rows = self.rows();
        let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
            return match direction {
                Direction::Right => DEFAULT_RIGHT_OFFSET_DEG,
                Direction::Left => DEFAULT_LEFT_OFFSET_DEG,
            };
        };
        if speed_rpm.is_nan() || speed_rpm <= first.speed_rpm {
            return first.offset(direction);
        }
        if speed_rpm >= last.speed_rpm {
            return last.offset(direction);
        }
        // The segment [a, b] with a.speed < speed <= b.speed.
        for pair in rows.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if speed_rpm <= b.speed_rpm {
                let t = (speed_rpm - a.speed_rpm) / (b.speed_rpm - a.speed_rpm);
                return lerp_deg(a.offset(direction), b.offset(direction), t);
            }
        }
        last.offset(direction)
    }
}
