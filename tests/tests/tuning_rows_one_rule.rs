//! Tuning rows are checked by one rule wherever they enter.
//!
//! Root cause: the rule for a tuning table's rows was written three times and the
//! copies disagreed. host-sim's tuning file reader refused a speed of 0, while the
//! controller's `TuningTable::from_rows` (which the device link applies to a table it
//! receives) and the firmware's build script took it; all three took an offset of
//! 360 degrees though offsets are documented in [0, 360). A table could so pass the
//! firmware's build or a board's link and be refused by host-sim, or the other way.
//!
//! Now the rule is `shared`'s (`RowField::check`, `TuningTable::from_rows`): speeds
//! above 0 and strictly ascending, offsets in [0, 360), 1 to `MAX_TUNING_ROWS` rows;
//! the tuning file reader (`machine-file`) applies it to the `f32` values the
//! controller gets, and the firmware's build reads tables with that reader. This
//! test hands the same rows to every path: the controller, the device link, the
//! tuning file reader and the firmware's build.

use std::path::{Path, PathBuf};

use machine_file::input::render;
use machine_file::tuning_file;
use shared::controller::{TuningTable, MAX_TUNING_ROWS};
use shared::protocol::{Frame, Message, MessageId, ParseError, Request};

#[allow(dead_code)]
#[path = "../../firmware/build.rs"]
mod firmware_build;

/// A row: speed, rpm; right and left offsets, degrees.
type Row = (f32, f32, f32);

/// What each path makes of `rows`: controller, link, file reader, firmware build.
/// `Ok(())` where the path takes them; the reader's and the build's problems as
/// they print.
fn every_path(name: &str, rows: &[Row]) -> [Result<(), String>; 4] {
    let controller = TuningTable::<MAX_TUNING_ROWS>::from_rows(rows)
        .map(drop)
        .map_err(|e| e.to_string());

    // The link: a WriteTuningTable frame's payload, row count then f32 triples.
    let mut payload = vec![rows.len() as u8];
    for (s, r, l) in rows {
        for v in [s, r, l] {
            payload.extend_from_slice(&v.to_le_bytes());
        }
    }
    let frame = Frame {
        id: MessageId::WriteTuningTable as u8,
        seq: 0,
        payload: &payload,
    };
    let link = match Request::parse(&frame) {
        Ok(_) => Ok(()),
        Err(ParseError::BadValue) => Err("BadValue".to_string()),
        Err(other) => panic!("{name}: the frame is malformed: {other:?}"),
    };

    // The file, written as a user would.
    let text: String = rows
        .iter()
        .map(|(s, r, l)| {
            format!(
                "[[rows]]\nspeed_rpm = {s:?}\nright_offset_deg = {r:?}\nleft_offset_deg = {l:?}\n"
            )
        })
        .collect();
    let path = scratch(&format!("{name}.tuning.toml"), &text);
    let reader = tuning_file::read(&path).map(drop).map_err(|p| render(&p));
    let build = firmware_build::tuning_rows(Some(&path))
        .map(drop)
        .map_err(|p| render(&p));
    [controller, link, reader, build]
}

/// `text` written to the scratch file `name`.
fn scratch(name: &str, text: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("tuning_rows_one_rule");
    tests::scratch_file(&dir, name, text)
}

#[test]
fn a_speed_of_zero_and_an_offset_of_360_are_refused_by_every_path() {
    let cases: [(&str, &[Row], &str); 4] = [
        (
            "speed_zero",
            &[(0.0, 90.0, 270.0), (3000.0, 80.0, 280.0)],
            "rows[0].speed_rpm: must be > 0 (got 0)",
        ),
        (
            "offset_360",
            &[(3000.0, 360.0, 270.0)],
            "rows[0].right_offset_deg: must be in [0, 360) (got 360)",
        ),
        (
            "negative_offset",
            &[(3000.0, 90.0, -0.5)],
            "rows[0].left_offset_deg: must be in [0, 360) (got -0.5)",
        ),
        (
            "speeds_not_ascending",
            &[(3000.0, 90.0, 270.0), (3000.0, 80.0, 280.0)],
            "rows: speeds must be strictly ascending",
        ),
    ];
    for (name, rows, message) in cases {
        let [controller, link, reader, build] = every_path(name, rows);
        assert!(controller.is_err(), "{name}: the controller took it");
        assert_eq!(link, Err("BadValue".into()), "{name}: the link");
        // The reader and the build say the same, naming the file and the key.
        let reader = reader.expect_err(name);
        assert!(reader.contains(message), "{name}: {reader}");
        assert!(
            reader.contains(&format!("{name}.tuning.toml: ")),
            "{reader}"
        );
        assert_eq!(build, Err(reader), "{name}: the build");
    }
}

#[test]
fn the_ends_that_pass_pass_every_path() {
    // The smallest offset, the largest f32 below 360, a small speed.
    let below = f32::from_bits(360.0_f32.to_bits() - 1);
    let rows = [(0.5, 0.0, below), (3000.0, 359.9, 0.0)];
    for (path, result) in ["controller", "link", "reader", "build"]
        .iter()
        .zip(every_path("ends", &rows))
    {
        assert_eq!(result, Ok(()), "{path}");
    }
}
