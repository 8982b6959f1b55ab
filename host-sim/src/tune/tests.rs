//! Tests of the module's stages together.

use crate::sweep::best::*;
use crate::sweep::*;

#[test]
fn ranges_include_both_ends() {
    assert_eq!(
        parse_range("2500:3500:250").unwrap(),
        [2500.0, 2750.0, 3000.0, 3250.0, 3500.0]
    );
    assert_eq!(parse_range("3000").unwrap(), [3000.0]);
    assert_eq!(parse_range("3000:3000:10").unwrap(), [3000.0]);
    // B not on the steps: appended.
    assert_eq!(
        parse_range("0:100:30").unwrap(),
        [0.0, 30.0, 60.0, 90.0, 100.0]
    );
    // Rounding: 0.1 x 3600 lands on 360 exactly.
    let r = parse_range("0:360:0.1").unwrap();
    assert_eq!(r.len(), 3601);
    assert_eq!(r[3600], 360.0);
}

#[test]
fn bad_ranges_name_the_reason() {
    for (text, why) in [
        ("0:360:0", "STEP must be > 0"),
        ("0:360:-15", "STEP must be > 0"),
        ("360:0:15", "B must be >= A"),
        ("nan:360:15", "finite"),
        ("0:inf:15", "finite"),
        ("0:360", "expected A:B:STEP"),
        ("a:b:c", "expected A:B:STEP"),
        ("", "expected A:B:STEP"),
        ("0:1e9:1e-9", "at most 10000"),
        ("0:10001:1", "at most 10000"),
    ] {
        let e = parse_range(text).unwrap_err();
        assert!(e.contains(why), "{text}: {e}");
    }
    assert!(parse_range("0:9999:1").is_ok());
}

#[test]
fn offsets_wrap_and_run_once() {
    let o = wrap_offsets(&parse_range("0:360:90").unwrap());
    assert_eq!(o, [0.0, 90.0, 180.0, 270.0]);
    let o = wrap_offsets(&[-90.0, 0.0, 90.0, -0.0, 360.0, 720.0 - 1e-12]);
    assert_eq!(o, [0.0, 90.0, 270.0]);
    assert!(o[0].is_sign_positive());
    let grid = |offsets_deg: Vec<f64>| Grid {
        speeds_rpm: vec![3000.0],
        offsets_deg,
        t_end: 1.0,
    };
    assert!(grid(vec![0.0, 90.0, 180.0, 270.0]).circular());
    assert!(grid(vec![10.0, 130.0, 250.0]).circular());
    assert!(!grid(vec![0.0, 30.0, 60.0, 90.0]).circular());
    assert!(!grid(vec![0.0, 180.0]).circular());
}

#[test]
fn the_vertex_of_a_known_parabola() {
    // v = 3 - 0.01 (x - 97)^2 through 80, 90, 100 (uneven around the vertex).
    let p = |x: f64| 3.0 - 0.01 * (x - 97.0) * (x - 97.0);
    let (x, v) = parabola_vertex(
        [80.0, 90.0, 110.0],
        [p(80.0), p(90.0), p(110.0)],
        Way::Right,
    )
    .unwrap();
    assert!((x - 97.0).abs() < 1e-9, "{x}");
    assert!((v - 3.0).abs() < 1e-9, "{v}");
    // The mirror image is a trough for the left.
    let (x, v) = parabola_vertex(
        [80.0, 90.0, 110.0],
        [-p(80.0), -p(90.0), -p(110.0)],
        Way::Left,
    )
    .unwrap();
    assert!((x - 97.0).abs() < 1e-9 && (v + 3.0).abs() < 1e-9);
    // Degenerate: flat, the wrong curvature, not a number.
    assert!(parabola_vertex([0.0, 1.0, 2.0], [1.0, 1.0, 1.0], Way::Right).is_err());
    assert!(parabola_vertex([0.0, 1.0, 2.0], [1.0, 0.0, 1.0], Way::Right).is_err());
    assert!(parabola_vertex([0.0, 1.0, 2.0], [0.0, 1.0, 0.0], Way::Left).is_err());
    assert!(parabola_vertex([0.0, 1.0, 2.0], [0.0, f64::NAN, 0.0], Way::Right).is_err());
    assert!(parabola_vertex([0.0, 0.0, 2.0], [0.0, 1.0, 0.0], Way::Right).is_err());
}

fn outcome(speed: f64, offset: f64, v: f64) -> RunOutcome {
    RunOutcome {
        speed_rpm: speed,
        offset_deg: offset,
        mean_velocity: v,
        not_held: None,
        not_a_travel: None,
        plant_warnings: vec![],
    }
}

/// A sweep of `v(offset) = sin(offset - 10 deg)` at two speeds.
fn synthetic() -> (Grid, Vec<RunOutcome>) {
    let grid = Grid {
        speeds_rpm: vec![2500.0, 3000.0],
        offsets_deg: (0..24).map(|i| f64::from(i) * 15.0).collect(),
        t_end: 4.0,
    };
    let runs = grid
        .points()
        .into_iter()
        .map(|(s, o)| outcome(s, o, 0.02 * (o - 10.0).to_radians().sin()))
        .collect();
    (grid, runs)
}

#[test]
fn candidates_refine_around_the_extreme_circularly() {
    let (grid, runs) = synthetic();
    let right = candidates(&grid, &runs, Way::Right);
    assert_eq!(right.len(), 2);
    assert_eq!(runs[right[0].grid_index].offset_deg, 105.0);
    let x = right[0].vertex.clone().unwrap();
    assert!((x - 100.0).abs() < 0.5, "{x}");
    let left = candidates(&grid, &runs, Way::Left);
    assert_eq!(runs[left[1].grid_index].offset_deg, 285.0);
    assert!((left[1].vertex.clone().unwrap() - 280.0).abs() < 0.5);
    // An extreme at offset 0 takes 345 as its left neighbour.
    let mut runs = runs;
    for r in &mut runs {
        r.mean_velocity = 0.02 * (r.offset_deg - 355.0).to_radians().cos();
    }
    let right = candidates(&grid, &runs, Way::Right);
    assert_eq!(runs[right[0].grid_index].offset_deg, 0.0);
    let x = right[0].vertex.clone().unwrap();
    assert!((x - 355.0).abs() < 0.5, "{x}");
}

#[test]
fn runs_that_did_not_hold_their_offset_are_not_chosen() {
    let (grid, mut runs) = synthetic();
    let i = runs.iter().position(|r| r.offset_deg == 105.0).unwrap();
    runs[i].not_held = Some("the controller ended `fault`".into());
    runs[i].mean_velocity = 1.0;
    let right = candidates(&grid, &runs, Way::Right);
    assert_ne!(right[0].grid_index, i);
    assert_eq!(runs[right[0].grid_index].offset_deg, 90.0);
    // At an end of a partial range there is no fit.
    let partial = Grid {
        speeds_rpm: vec![3000.0],
        offsets_deg: vec![0.0, 30.0, 60.0, 90.0],
        t_end: 4.0,
    };
    let runs: Vec<RunOutcome> = partial
        .points()
        .into_iter()
        .map(|(s, o)| outcome(s, o, o))
        .collect();
    let right = candidates(&partial, &runs, Way::Right);
    assert!(right[0].vertex.as_ref().unwrap_err().contains("end"));
}

#[test]
fn speeds_without_travel_one_way_are_warned() {
    let (grid, mut runs) = synthetic();
    for r in &mut runs {
        r.mean_velocity = r.mean_velocity.abs() + 1e-3;
    }
    let best = |way: Way| -> Vec<Best> {
        candidates(&grid, &runs, way)
            .into_iter()
            .map(|c| Best {
                speed_rpm: c.speed_rpm,
                offset_deg: runs[c.grid_index].offset_deg,
                mean_velocity: runs[c.grid_index].mean_velocity,
                grid_offset_deg: runs[c.grid_index].offset_deg,
                grid_mean_velocity: runs[c.grid_index].mean_velocity,
                refinement: Refinement::Parabola,
            })
            .collect()
    };
    let w = warnings(&grid, &runs, &best(Way::Right), &best(Way::Left));
    assert_eq!(w.len(), 2, "{w:?}");
    assert!(
        w[0].starts_with("2500 rpm: no offset travels left"),
        "{w:?}"
    );
}

#[test]
fn velocities_for_people() {
    assert_eq!(mm_s(0.0292), "+29.2");
    assert_eq!(mm_s(-0.00002), "0.0");
    assert_eq!(mm_s(-0.0304), "-30.4");
    assert_eq!(mm_s(f64::NAN), "nan");
}

/// A run keeps at most `MAX_PLANT_WARNINGS` plant warnings and counts the rest,
/// each text cut; what it keeps is no problem, more or longer is (`merge`'s test
/// of a part's runs).
#[test]
fn a_runs_texts_are_bounded() {
    let mut o = outcome(3000.0, 90.0, 0.03);
    o.plant_warnings = (0..20)
        .map(|i| format!("contacts: Painleve at t = {i} s"))
        .collect();
    o.not_held = Some("x".repeat(10_000));
    assert!(o.problem().is_some());
    let b = o.bounded();
    assert_eq!(b.plant_warnings.len(), MAX_PLANT_WARNINGS + 1);
    assert_eq!(
        b.plant_warnings.last().unwrap(),
        "... and 12 more plant warnings in this run"
    );
    assert!(b.not_held.as_ref().unwrap().ends_with("... (10000 bytes)"));
    assert_eq!(b.problem(), None);
    // The mean velocity: within the measured file's bound, a number where the
    // run gave a speed, none where it was no travel.
    for (v, not_a_travel, ok) in [
        (10.0, None, true),
        (10.5, None, false),
        (f64::NAN, None, false),
        (f64::NAN, Some("through the floor"), true),
        (0.01, Some("through the floor"), false),
    ] {
        let mut o = outcome(3000.0, 90.0, v);
        o.not_a_travel = not_a_travel.map(String::from);
        assert_eq!(
            o.problem().is_none(),
            ok,
            "{v} {not_a_travel:?}: {:?}",
            o.problem()
        );
    }
}
