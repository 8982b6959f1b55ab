//! The event functions and where they cross zero.
//!
//! One function per condition ([`Watch`]), each positive until its event, never
//! combined; a mode just decided starts with each at least its margin from zero.
//! [`Plant::first_crossing`] finds the earliest event in a step: a change of sign,
//! or one of the cases without one (grazing, a whole flight, a dip inside the
//! step), located by Illinois false position on the dense output
//! ([`Plant::locate`]).

use super::super::dynamics::{ContactKinematics, Pose, Vector};
use super::super::integrator::Step;
use super::super::motor::Winding;
use super::{ContactMode, Plant, NY};

/// What an event function watches: each is positive until its event, and one
/// function watches one condition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Watch {
    /// Open contact `j`: its gap, m (impact, or the contact closes).
    Gap(usize),
    /// Closed contact `j`: its normal force plus `eps_F`, N (lift-off).
    NormalForce(usize),
    /// Sticking contact `j`: `mu lambda_n - |lambda_t| + eps_F`, N (the cone is
    /// exceeded).
    Cone(usize),
    /// Slipping contact `j`: `s u_t + eps_v`, m/s (the slip ends).
    SlipEnds(usize),
    /// Motor `k`'s current, A: driven, `I_lim - |i|` (the current limit is
    /// reached); coasting with a current, `s i` (it dies through the diodes).
    Current(usize),
    /// An unused slot (the second slot of an open contact).
    Nothing,
}

/// The earliest event of a step: its time, the state there, and whether only a
/// winding's current crossed (a coasting current dying, a current reaching its
/// driver's limit): such an event changes no contact and takes no trace rows.
pub(super) struct Crossing {
    pub(super) t: f64,
    pub(super) y: [f64; NY],
    pub(super) current_only: bool,
}

/// Where an event function gets its contacts' kinematics: a pose (and the
/// velocities) its caller built once for all the functions at a state, or built
/// from the state for the one function asked for.
#[derive(Clone, Copy)]
pub(super) enum Kinematics<'a> {
    Pose(&'a Pose, &'a Vector),
    FromState,
}

impl Plant {
    /// What event function `i` watches (see [`Watch`]): two slots per contact,
    /// then one per motor driver.
    pub(super) fn watch(&self, i: usize) -> Watch {
        let n = self.modes.len();
        if i >= 2 * n {
            return Watch::Current(i - 2 * n);
        }
        let j = i / 2;
        match (self.modes[j], i % 2) {
            (ContactMode::Open, 0) => Watch::Gap(j),
            (ContactMode::Open, _) => Watch::Nothing,
            (_, 0) => Watch::NormalForce(j),
            (ContactMode::Stick, _) => Watch::Cone(j),
            // Without friction the slip's direction changes no force: no event.
            (_, _) if self.model.contacts[j].law.friction == 0.0 => Watch::Nothing,
            (_, _) => Watch::SlipEnds(j),
        }
    }

    /// The event functions at `y`, each positive until its event and `<= 0`
    /// once it happened, one function per condition (never combined: a function
    /// that cannot change sign must not hide another's crossing). Slots `2j` and
    /// `2j + 1` are contact `j`'s:
    ///
    /// | mode | slot `2j` | slot `2j + 1` |
    /// | --- | --- | --- |
    /// | open | gap, m | (none: `+inf`) |
    /// | closed | `lambda_n + eps_F`, N (lift-off) | stick: `mu lambda_n - abs(lambda_t) + eps_F`, N (cone exceeded); slip: `s u_t + eps_v`, m/s (slip ends) |
    ///
    /// then each motor driver's `I_lim - |i|` (the current limit: the current's
    /// equation switches there). `eps_F` is [`Plant::force_tolerance`] and
    /// `eps_v` the velocity tolerance: a mode just decided starts with every
    /// function at least that far from zero (the mode decision's own tolerance is
    /// a thousandth of it), so a crossing is a change of sign, never a value that
    /// was already zero.
    pub(super) fn event_values(&self, y: &[f64; NY]) -> Vec<f64> {
        let needs_forces = self.modes.iter().any(|m| m.closed());
        let ev = needs_forces.then(|| self.evaluate(y));
        // One pose for every contact's kinematics at `y`.
        let v = self.model.v(y);
        let pose = Pose::new(&self.model, &self.model.q(y));
        let at = Kinematics::Pose(&pose, &v);
        (0..2 * self.modes.len() + self.model.rotors.len())
            .map(|i| self.event_value(self.watch(i), y, at, ev.as_ref()))
            .collect()
    }

    /// One event function, `watch`, at `y` (see [`Plant::event_values`]); `at`
    /// the pose there where the caller has it; `ev` the evaluation at `y` where
    /// the caller has it, else the contact forces are computed here, and only for
    /// the functions that need them (a normal force, a cone): locating a gap's or
    /// a slip's zero solves no contact problem.
    pub(super) fn event_value(
        &self,
        watch: Watch,
        y: &[f64; NY],
        at: Kinematics<'_>,
        ev: Option<&super::forces::Evaluation>,
    ) -> f64 {
        let kinematics = |j| match at {
            Kinematics::Pose(pose, v) => pose.contact(&self.model, j, v),
            Kinematics::FromState => self.contact_at(y, j),
        };
        let gap = |j| match at {
            Kinematics::Pose(pose, _) => pose.gap(&self.model, j),
            Kinematics::FromState => self.gap_at(y, j),
        };
        let forces = |j: usize| match ev {
            Some(e) => (e.lambda_n[j], e.lambda_t[j]),
            None => {
                let e = self.evaluate(y);
                (e.lambda_n[j], e.lambda_t[j])
            }
        };
        let eps_f = self.force_tolerance();
        match watch {
            Watch::Gap(j) => gap(j),
            Watch::NormalForce(j) => forces(j).0 + eps_f,
            Watch::Cone(j) => {
                let (ln, lt) = forces(j);
                self.model.contacts[j].law.friction * ln - lt.abs() + eps_f
            }
            Watch::SlipEnds(j) => {
                let s = if self.modes[j] == ContactMode::SlipNegative {
                    -1.0
                } else {
                    1.0
                };
                s * kinematics(j).u_t + self.settings.velocity_tolerance
            }
            Watch::Current(k) => match self.winding[k] {
                Winding::Voltage(_) => {
                    self.model.rotors[k].motor.current_limit - y[self.model.current(k)].abs()
                }
                Winding::Coast(_) if self.coast_sign[k] != 0.0 => {
                    self.coast_sign[k] * y[self.model.current(k)]
                }
                Winding::Coast(_) | Winding::Open => f64::INFINITY,
            },
            Watch::Nothing => f64::INFINITY,
        }
    }

    /// The earliest event in `step`, located on its dense output.
    ///
    /// A function that changes sign between the step's ends is located by
    /// [`Plant::locate`]. Three cases are found although both ends are positive,
    /// or both are past the event:
    /// - an open contact **grazing** the fundament inside the step, or making a
    ///   **whole flight** inside it (its gap, below);
    /// - a closed contact's function (normal force, cone, slip) that **dips**
    ///   below zero and comes back inside the step: the parabola through its
    ///   values at the step's start, middle and end ([`Plant::dip`]) predicts the
    ///   minimum, and the function there is checked on the dense output;
    /// - a closed contact whose normal force is already below `-eps_F` at the
    ///   step's start (a mode left inconsistent, which the mode decision should
    ///   never produce): the event is at the start, so a contact never stays
    ///   closed while its mode's equations make it pull.
    pub(super) fn first_crossing(
        &self,
        step: &Step<NY>,
        ev0: &[f64],
        ev1: &[f64],
    ) -> Option<Crossing> {
        // The earliest time, and whether only a winding's current crossed there.
        let mut best: Option<(f64, bool)> = None;
        let mut consider_kind = |te: f64, current: bool| match &mut best {
            Some((b, only)) if te == *b => *only &= current,
            Some((b, _)) if te > *b => {}
            _ => best = Some((te, current)),
        };
        // The event functions at the step's middle, computed once if needed.
        let t_mid = step.t0 + 0.5 * step.h;
        let mut mid: Option<Vec<f64>> = None;
        for i in 0..ev0.len() {
            let watch = self.watch(i);
            let f = |y: &[f64; NY]| self.event_value(watch, y, Kinematics::FromState, None);
            let mut consider = |te: f64| consider_kind(te, false);
            if ev0[i] > 0.0 && ev1[i] <= 0.0 {
                let te = self.locate(step, &f, step.t0, step.t1(), ev0[i], ev1[i]);
                consider_kind(te, matches!(watch, Watch::Current(_)));
                continue;
            }
            match watch {
                Watch::Gap(j) => {
                    if let Some(te) = self.gap_event_inside(step, j, ev0[i], ev1[i]) {
                        consider(te);
                    }
                }
                Watch::NormalForce(_) | Watch::Cone(_) | Watch::SlipEnds(_) => {
                    if ev0[i] > 0.0 && ev1[i] > 0.0 {
                        let fm = mid.get_or_insert_with(|| self.event_values(&step.at(t_mid)))[i];
                        if let Some(te) = self.dip(step, &f, [ev0[i], fm, ev1[i]]) {
                            consider(te);
                        }
                    } else if ev0[i] <= 0.0 && matches!(watch, Watch::NormalForce(_)) {
                        consider(step.t0);
                    }
                }
                Watch::Current(_) | Watch::Nothing => {}
            }
        }
        best.map(|(te, current_only)| {
            let (t, y) = if te >= step.t1() {
                (step.t1(), step.y1)
            } else if te <= step.t0 {
                (step.t0, step.y0)
            } else {
                (te, step.at(te))
            };
            Crossing { t, y, current_only }
        })
    }

    /// A dip of a function below zero inside `step` although it is positive at
    /// both ends: `values` at the start, the middle and the end. The parabola
    /// through them, `f(s) = f0 + b s + c s^2` on `s in [0, 1]` with
    /// `c = 2 (f1 - 2 fm + f0)`, `b = f1 - f0 - c`, has its minimum
    /// `f0 - b^2 / (4 c)` at `s = -b / (2 c)`; where that is `<= 0` inside the step
    /// (or the middle value itself is), the function is evaluated there on the
    /// dense output and, if it is past its event, the crossing before it is
    /// located.
    pub(super) fn dip(
        &self,
        step: &Step<NY>,
        f: &dyn Fn(&[f64; NY]) -> f64,
        values: [f64; 3],
    ) -> Option<f64> {
        let [f0, fm, f1] = values;
        let t_at = |s: f64| step.t0 + s * step.h;
        if fm <= 0.0 {
            return Some(self.locate(step, f, step.t0, t_at(0.5), f0, fm));
        }
        let c = 2.0 * (f1 - 2.0 * fm + f0);
        if c <= 0.0 {
            return None;
        }
        let b = f1 - f0 - c;
        let s_min = -b / (2.0 * c);
        if !(s_min > 0.0 && s_min < 1.0) || f0 - b * b / (4.0 * c) > 0.0 {
            return None;
        }
        let f_min = f(&step.at(t_at(s_min)));
        (f_min <= 0.0).then(|| self.locate(step, f, step.t0, t_at(s_min), f0, f_min))
    }

    /// The event of open contact `j` inside `step` where its gap does not change
    /// sign between the ends (`g0`, `g1`): grazing, or a whole flight.
    pub(super) fn gap_event_inside(
        &self,
        step: &Step<NY>,
        j: usize,
        g0: f64,
        g1: f64,
    ) -> Option<f64> {
        let gap = |y: &[f64; NY]| self.gap_at(y, j);
        let un = |y: &[f64; NY]| self.contact_at(y, j).u_n;
        let (u0, u1) = (un(&step.y0), un(&step.y1));
        if g0 > 0.0 && g1 > 0.0 {
            // Grazing: the gap may dip below zero and come back inside the step.
            // Its minimum is where u_n goes from - to +; check the gap there.
            if u0 < 0.0 && u1 > 0.0 {
                let neg_un = |y: &[f64; NY]| -un(y);
                let t_min = self.locate(step, &neg_un, step.t0, step.t1(), -u0, -u1);
                let g_min = gap(&step.at(t_min));
                if g_min <= 0.0 {
                    return Some(self.locate(step, &gap, step.t0, t_min, g0, g_min));
                }
            }
            return None;
        }
        if g0 > 0.0 || g1 > 0.0 || u1 >= -self.settings.velocity_tolerance {
            return None;
        }
        // An open contact that starts at the fundament (just after an impact or a
        // lift-off) and ends the step below it, approaching: a whole flight inside
        // the step. Bracket its apex (u_n from + to -), then the gap's root after
        // it.
        let apex = if u0 > 0.0 {
            self.locate(step, &un, step.t0, step.t1(), u0, u1)
        } else {
            step.t0
        };
        let g_apex = gap(&step.at(apex));
        if g_apex > 0.0 {
            return Some(self.locate(step, &gap, apex, step.t1(), g_apex, g1));
        }
        // Touching at the apex and sinking from there (a contact left open with
        // zero velocity whose force would have been negligible): the event is
        // where it sinks below the together gap, which it may not do within this
        // step.
        let below = |y: &[f64; NY]| gap(y) + self.settings.together_gap;
        let (b0, b1) = (below(&step.at(apex)), below(&step.y1));
        if b0 > 0.0 && b1 <= 0.0 {
            return Some(self.locate(step, &below, apex, step.t1(), b0, b1));
        }
        if b0 > 0.0 {
            return None;
        }
        // Already at the together gap's edge: the event is where it starts to
        // approach measurably (then an impact, however slow, which an
        // accumulation closes).
        let tol = self.settings.velocity_tolerance;
        let approach = |y: &[f64; NY]| un(y) + tol;
        let (a0, a1) = (approach(&step.at(apex)), approach(&step.y1));
        if a0 > 0.0 && a1 <= 0.0 {
            Some(self.locate(step, &approach, apex, step.t1(), a0, a1))
        } else {
            Some(apex)
        }
    }

    /// The force tolerance `eps_F` of the contact modes, N:
    /// [`super::Settings::force_tolerance`] of the machine's weight (of its mass times
    /// 1 m/s^2 where gravity is weaker). A closed contact's normal force stays
    /// above `-eps_F`; a sticking contact's friction within `eps_F` of its cone.
    pub fn force_tolerance(&self) -> f64 {
        let g = self.model.gravity;
        let g = (g[0] * g[0] + g[1] * g[1]).sqrt().max(1.0);
        self.settings.force_tolerance * self.model.total_mass() * g
    }

    /// Contact `j`'s gap at state `y`, m ([`Pose::gap`]).
    pub(super) fn gap_at(&self, y: &[f64; NY], j: usize) -> f64 {
        Pose::new(&self.model, &self.model.q(y)).gap(&self.model, j)
    }

    /// Contact `j`'s kinematics at state `y`.
    pub(super) fn contact_at(&self, y: &[f64; NY], j: usize) -> ContactKinematics {
        let (q, v) = (self.model.q(y), self.model.v(y));
        Pose::new(&self.model, &q).contact(&self.model, j, &v)
    }

    /// Illinois false position on the dense output for the function `f`, from
    /// `f(a) = fa > 0` to `f(b) = fb <= 0`; returns a time where `f <= 0`.
    pub(super) fn locate(
        &self,
        step: &Step<NY>,
        f: &dyn Fn(&[f64; NY]) -> f64,
        a: f64,
        b: f64,
        fa: f64,
        fb: f64,
    ) -> f64 {
        let (mut a, mut b, mut fa, mut fb) = (a, b, fa, fb);
        let mut side = 0i8;
        for _ in 0..200 {
            if b - a <= self.settings.event_time_tolerance {
                break;
            }
            let mut c = (a * fb - b * fa) / (fb - fa);
            if !(c > a && c < b) {
                c = 0.5 * (a + b);
            }
            let fc = f(&step.at(c));
            if fc > 0.0 {
                a = c;
                fa = fc;
                if side == 1 {
                    fb *= 0.5;
                }
                side = 1;
            } else {
                b = c;
                fb = fc;
                if side == -1 {
                    fa *= 0.5;
                }
                side = -1;
            }
        }
        b
    }
}
