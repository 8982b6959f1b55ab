//! Travel of the reference machine with its rotors forced at constant speed
//! (3000 rpm, counter-rotating) and a fixed phase offset: the plant alone, no
//! controller.
//!
//! - The Zeno criterion does not change results: halving or doubling its
//!   threshold leaves the mean velocity within 1 % (it closes only the
//!   accumulation tails of landings, whose remaining flight it accounts for).
//! - Mirror symmetry: the reference platform is mirror-symmetric about its
//!   vertical centre line, and mirroring the machine maps the offset `d` to
//!   `360 - d` (docs/machine-file.md, "Conventions": the exciting force's line at `d/2`
//!   from +x mirrors to `180 - d/2`) and `x` to `-x`. So `v(360 - d) = -v(d)`, and the
//!   vertical-force offset 180 degrees gives no travel.
//! - The convention for the direction (docs/machine-file.md): near 90 degrees the force
//!   pushes up-and-right then down-and-left, and the platform travels right.

use host_sim::plant::simulator::Settings;
use tests::held::{held_rotors, mean_velocity as held_mean_velocity, reference_machine};

/// Mean velocity `(x(T) - x(T/2)) / (T/2)` of the reference machine with the
/// rotors forced at 3000 rpm and phase offset `offset_deg`, m/s.
fn mean_velocity(offset_deg: f64, t_end: f64, settings: Settings) -> f64 {
    let mut plant = held_rotors(&reference_machine(offset_deg, &[]), 3000.0, settings);
    held_mean_velocity(&mut plant, t_end / 2.0, t_end)
}

#[test]
fn zeno_threshold_does_not_change_the_mean_velocity() {
    let base = Settings::default();
    let v1 = mean_velocity(90.0, 4.0, base);
    assert!(v1.abs() > 1e-3, "the machine travels: {v1} m/s");
    for factor in [0.5, 2.0] {
        let s = Settings {
            zeno_velocity: base.zeno_velocity * factor,
            ..base
        };
        let v = mean_velocity(90.0, 4.0, s);
        assert!(
            (v - v1).abs() <= 0.01 * v1.abs(),
            "zeno_velocity x{factor}: {v} m/s vs {v1} m/s"
        );
    }
}

#[test]
fn travel_is_mirror_antisymmetric_in_the_offset() {
    let s = Settings::default();
    for d in [60.0, 90.0, 120.0] {
        let v = mean_velocity(d, 4.0, s);
        let mirrored = mean_velocity(360.0 - d, 4.0, s);
        assert!(
            (v + mirrored).abs() <= 0.01 * v.abs().max(1e-3),
            "v({d}) = {v}, v({}) = {mirrored}",
            360.0 - d
        );
    }
    // Near 90 degrees the platform travels right (docs/machine-file.md).
    assert!(mean_velocity(90.0, 4.0, s) > 0.0);
    // The vertical-force offset: no travel beyond rounding of a symmetric motion.
    // Symmetry gives this for free, a platform glued to the floor included; that
    // it hops every revolution is checked in `plant_unilateral.rs`.
    let v180 = mean_velocity(180.0, 4.0, s);
    assert!(v180.abs() < 1e-9, "v(180) = {v180}");
}

/// Samples the reference machine travelling (90 degrees, rotors held at 3000 rpm)
/// every 0.1 ms for `t_end` and returns, over the samples, the worst violation of
/// Coulomb's law and of the unilateral constraint by a closed foot, relative to its
/// force (`(|lambda_t| - mu lambda_n) / |lambda|` for a sticking foot,
/// `-lambda_n / |lambda|` for any closed foot), separately for the samples where
/// both feet stick and for the others, and how many samples had both feet sticking.
fn cone_violations(t_end: f64) -> (f64, f64, usize) {
    use host_sim::plant::contact::ContactMode;
    // The machine file's friction (both feet).
    let mu = 0.4;
    let mut plant = held_rotors(&reference_machine(90.0, &[]), 3000.0, Settings::default());
    let (mut worst_both, mut worst_other, mut both) = (0.0f64, 0.0f64, 0);
    let samples = (t_end / 1e-4).round() as usize;
    for k in 1..=samples {
        plant.advance_to(k as f64 * 1e-4, &mut |_| {}).unwrap();
        let forces = plant.contact_forces();
        let both_stick = plant.modes.iter().all(|m| *m == ContactMode::Stick);
        let mut worst = 0.0f64;
        for (j, mode) in plant.modes.iter().enumerate() {
            let [ln, lt] = forces[j];
            let scale = ln.abs() + lt.abs() + 1e-9;
            if *mode != ContactMode::Open {
                worst = worst.max(-ln / scale);
            }
            if *mode == ContactMode::Stick {
                worst = worst.max((lt.abs() - mu * ln) / scale);
            }
        }
        if both_stick {
            both += 1;
            worst_both = worst_both.max(worst);
        } else {
            worst_other = worst_other.max(worst);
        }
    }
    (worst_both, worst_other, both)
}

/// Both feet sticking together: the forces are fixed only up to the internal
/// force between the feet, and the plant shares it within both cones
/// (`shared::impact::split`): at every sample with both feet sticking, both are
/// inside their cones to 1e-6 of their force (the event location's accuracy).
#[test]
fn both_feet_sticking_stay_inside_their_cones() {
    let (worst_both, _, both) = cone_violations(2.0);
    assert!(both >= 10, "{both} samples with both feet sticking");
    assert!(
        worst_both <= 1e-6,
        "a sticking foot outside its cone by {worst_both} of its force"
    );
}

/// Every closed foot, at every sample: inside its cone, normal force >= 0.
///
/// Failed before the mode decision let every touching contact take a share
/// (`NormalRule::TargetAll`) and stopped re-closing a contact whose lift-off event
/// fired: when both feet stuck and their total friction reached the total cone
/// (t = 3.15 ms), the complementarity problem left foot 2 out (its acceleration
/// without contact forces is upward, +1.95 m/s^2, so `NormalRule::Target` treated
/// it as separating), the solution with foot 1 slipping alone pulled foot 2 down to
/// a normal acceleration <= 0, and foot 2 was closed as sticking without force; its
/// closed-contact force was then outside its cone (|lambda_t| / lambda_n up to 390)
/// with its stick event already negative, until it lifted off at 5.0 ms.
#[test]
fn closed_feet_obey_coulomb_and_unilaterality() {
    let (worst_both, worst_other, _) = cone_violations(2.0);
    let worst = worst_both.max(worst_other);
    assert!(
        worst <= 1e-6,
        "a closed foot violates its cone or pulls by {worst} of its force"
    );
}
