//! Impacts: the `shared` solver on the whole mechanism's Delassus matrix, Zeno
//! accumulations closed plastically, and Painleve configurations resolved by a
//! tangential impact (Genot & Brogliato 1999).

use shared::impact::lcp::{find_direction, NormalRule, Tolerances};
use shared::impact::{solve, solve_into, ImpactLaw, MAX_CONTACTS};

use super::super::dynamics::row_dot;
use super::{ContactMode, Plant};
use crate::event::{EventKind, EventRow};
use crate::machine::bodies::MAX_DOF;

impl Plant {
    /// One impact of the contacts `set` (all within the together gap).
    pub(super) fn impact(&mut self, set: &[usize]) {
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let mut kept = self.contact_system(&frame, &v, set, None);
        // The outcomes solved where they are read, in the storage kept with the
        // problem (each holds the capacity's histories).
        let sys = &mut *kept;
        let [first, plastic] = &mut sys.outcomes;
        let outcome = match solve_into(&sys.problem, first) {
            Ok(()) => &*first,
            Err(e) => {
                if !self.impact_at_velocity_level(set, sys, e) {
                    self.warn(format!("impact at t = {:.9} s not solved: {e:?}", self.t));
                }
                self.recycle(kept);
                return;
            }
        };
        let approach = (0..set.len())
            .map(|r| -sys.problem.u_n[r])
            .fold(0.0, f64::max);
        let rebound = (0..set.len())
            .filter(|r| outcome.contacts[*r].normal_impulse > 0.0)
            .map(|r| outcome.contacts[r].normal_velocity_after)
            .fold(0.0, f64::max);

        // Zeno: a rebound slower than the threshold ends an accumulation; close it
        // plastically and report the accumulation point.
        let zeno = rebound > 0.0 && rebound < self.settings.zeno_velocity;
        let outcome = if zeno {
            for r in 0..set.len() {
                sys.problem.contacts[r].restitution = 0.0;
            }
            match solve_into(&sys.problem, plastic) {
                Ok(()) => &*plastic,
                Err(_) => outcome,
            }
        } else {
            outcome
        };

        // Velocity jump: q'+ = q'- + M^-1 J^T P.
        for (r, &j) in set.iter().enumerate() {
            let c = &outcome.contacts[r];
            let n = self.model.dof;
            for i in 0..n {
                self.y[n + i] +=
                    c.normal_impulse * sys.minv_jn[r][i] + c.tangential_impulse * sys.minv_jt[r][i];
            }
            if c.normal_impulse > 0.0 || sys.problem.u_n[r] < 0.0 {
                self.events.push(EventRow {
                    t: self.t,
                    kind: EventKind::Impact,
                    contact: self.model.contacts[j].name.clone(),
                    normal_velocity_before: c.normal_velocity_before,
                    normal_velocity_after: c.normal_velocity_after,
                    normal_impulse: c.normal_impulse,
                    tangential_impulse: c.tangential_impulse,
                    case: Some(c.case.number()),
                    detail: String::new(),
                });
            }
        }
        self.impacts += 1;
        self.fsal = None;
        let warnings = outcome.warnings;
        self.recycle(kept);
        if !warnings.is_empty() {
            let w = warnings;
            use shared::impact::Warnings as W;
            if w.contains(W::ENERGY_GAINED) && self.model.law != ImpactLaw::Newton {
                self.warn(
                    "impacts: energy gained at an impact (unequal restitution at several contacts)"
                        .into(),
                );
            }
            if w.contains(W::PENETRATION_LEFT) {
                self.warn("impacts: a contact still approached after an impact".into());
            }
            if w.contains(W::INCONSISTENT) {
                self.warn("impacts: inconsistent contact states inside an impact".into());
            }
        }
        if zeno {
            // Remaining flight time of the accumulation: 2 v+ / (a (1 - e)).
            let e = (rebound / approach).clamp(0.0, 0.999_999);
            let acc = self.free_normal_acceleration(set);
            let remaining = if acc < 0.0 {
                2.0 * rebound / (-acc * (1.0 - e))
            } else {
                0.0
            };
            let at = self.t + remaining;
            self.mark(set, EventKind::Zeno, &format!("accumulation_time={at:.12}"));
        }
    }

    /// The impact of the contacts `set` (their problem in `sys`) as one linear
    /// complementarity problem at velocity level, where the impulse path could
    /// not be followed (`why`: it chattered between friction states beyond the
    /// solver's pieces, seen on two feet 1.8 mm apart and level within 0.5 um).
    /// Returns false where that problem has no solution either.
    ///
    /// Newton's restitution at each contact and Coulomb's cone on the impulses,
    /// the friction states from the velocities after (Moreau's impact law at
    /// velocity level, as event-capturing schemes take every impact; Acary &
    /// Brogliato, *Numerical Methods for Nonsmooth Dynamical Systems*, 2008,
    /// sec. 10.1):
    ///
    /// ```text
    ///   u_n+ = u_n- + (W P)_n,   0 <= P_n  _|_  u_n+ + e u_n- >= 0,
    ///   stick: u_t+ = 0, |P_t| <= mu P_n;  slip: P_t = -mu P_n sign(u_t+)
    /// ```
    ///
    /// It leaves out what the path resolves inside the impact (a slip that
    /// reverses during compression, Poisson's and Stronge's laws), so it is
    /// reported: a warning names the instant, and the event rows carry no
    /// interaction case. Energy gained by it (unequal restitution at coupled
    /// contacts) is reported too: `dT = P . (u- + W P / 2)`.
    fn impact_at_velocity_level(
        &mut self,
        set: &[usize],
        sys: &super::forces::ContactSystem,
        why: shared::impact::ImpactError,
    ) -> bool {
        let p = &sys.problem;
        let m = set.len();
        let mut target = [0.0; MAX_CONTACTS];
        let mut scale_v = 0.0f64;
        for r in 0..m {
            target[r] = (-p.contacts[r].restitution * p.u_n[r]).max(0.0);
            scale_v = scale_v.max(p.u_n[r].abs()).max(p.u_t[r].abs());
        }
        let tol = Tolerances {
            velocity: 1e-9 * scale_v,
            impulse: 1e-9 * scale_v * self.model.total_mass(),
            zero_slip: 0.0,
        };
        let zero_slip = [0.0; MAX_CONTACTS];
        let d = find_direction(
            p,
            &p.u_n,
            &p.u_t,
            &zero_slip,
            NormalRule::TargetAll(&target),
            &tol,
        );
        if !d.consistent || !d.ends_at_one {
            return false;
        }
        let n = self.model.dof;
        let mut work = 0.0;
        for (r, &j) in set.iter().enumerate() {
            let (pn, pt) = (d.x[r], d.y[r]);
            work += pn * (p.u_n[r] + 0.5 * d.du_n[r]) + pt * (p.u_t[r] + 0.5 * d.du_t[r]);
            for i in 0..n {
                self.y[n + i] += pn * sys.minv_jn[r][i] + pt * sys.minv_jt[r][i];
            }
            if pn > 0.0 || p.u_n[r] < 0.0 {
                self.events.push(EventRow {
                    t: self.t,
                    kind: EventKind::Impact,
                    contact: self.model.contacts[j].name.clone(),
                    normal_velocity_before: p.u_n[r],
                    normal_velocity_after: p.u_n[r] + d.du_n[r],
                    normal_impulse: pn,
                    tangential_impulse: pt,
                    case: None,
                    detail: "velocity level".into(),
                });
            }
        }
        self.impacts += 1;
        self.fsal = None;
        self.warn(format!(
            "impact at t = {:.9} s solved at velocity level (Newton's restitution, friction states from the velocities after): its impulse path was not followed ({why:?})",
            self.t
        ));
        // The kinetic energy's scale: the approach's, (mass) u^2 / 2.
        if work > 1e-9 * self.model.total_mass() * scale_v * scale_v {
            self.warn(format!(
                "impacts: energy gained at the velocity-level impact at t = {:.9} s ({work:.3e} J)",
                self.t
            ));
        }
        true
    }

    /// An event row of `kind` at each contact of `set`, with `detail`, and no
    /// velocities or impulses (a Zeno closure, a Painleve configuration).
    fn mark(&mut self, set: &[usize], kind: EventKind, detail: &str) {
        for &j in set {
            self.events.push(EventRow {
                t: self.t,
                kind,
                contact: self.model.contacts[j].name.clone(),
                normal_velocity_before: 0.0,
                normal_velocity_after: 0.0,
                normal_impulse: 0.0,
                tangential_impulse: 0.0,
                case: None,
                detail: detail.to_string(),
            });
        }
    }

    /// The largest (least negative) normal acceleration without contact forces
    /// among `set`, m/s^2.
    pub(super) fn free_normal_acceleration(&self, set: &[usize]) -> f64 {
        let q = self.q();
        let v = self.v();
        let n = self.model.dof;
        let frame = self.frame(&q);
        let open = vec![ContactMode::Open; self.modes.len()];
        let e = self.evaluate_with_modes(&self.y, &open);
        let mut acc = [0.0; MAX_DOF];
        acc[..n].copy_from_slice(&e.ydot[n..2 * n]);
        set.iter()
            .map(|&j| {
                let k = frame.contact(&self.model, j, &v);
                row_dot(&k.j_n, &acc, self.model.dof) + k.bias_n
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// A Painleve configuration: the contact problem has no consistent solution
    /// (or its only way out is unbounded). Reported, and resolved by a tangential
    /// impact: the impulse-space problem of the touching contacts, which under
    /// friction develops a normal impulse even from zero normal velocity until the
    /// slip stops (Genot & Brogliato 1999).
    ///
    /// `detail`: the events' detail (which configuration); `why`: what the mode
    /// decision found (Lemke's method ended at a ray after so many pivots, or its
    /// cap; a dynamic jam), named in the warning.
    pub(super) fn painleve(&mut self, set: &[usize], detail: &str, why: &str) {
        self.mark(set, EventKind::Painleve, detail);
        self.warn(format!(
            "contacts: Painleve configuration at t = {:.9} s ({why}), resolved by a tangential impact",
            self.t
        ));
        // Tangential impact (Genot & Brogliato 1999): the impulse-space problem of
        // the touching contacts started at zero normal velocity (a tiny approach,
        // 1e-6 of the slip speed, so that the solver runs its compression). Under
        // the jam the normal impulse grows, with friction at the cone, until the
        // slip stops; plastic (restitution 0): nothing was stored by an approach.
        if self.resolving_painleve {
            for &j in set {
                self.modes[j] = ContactMode::Stick;
            }
            self.project();
            self.fsal = None;
            return;
        }
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let sys = self.contact_system(&frame, &v, set, None);
        let mut problem = sys.problem.clone();
        let slip = (0..set.len())
            .map(|r| problem.u_t[r].abs())
            .fold(0.0, f64::max);
        for r in 0..set.len() {
            problem.u_n[r] = problem.u_n[r].min(-1e-6 * slip.max(self.settings.velocity_tolerance));
            problem.contacts[r].restitution = 0.0;
        }
        match solve(&problem) {
            Ok(outcome) => {
                for (r, &j) in set.iter().enumerate() {
                    let c = &outcome.contacts[r];
                    let n = self.model.dof;
                    for i in 0..n {
                        self.y[n + i] += c.normal_impulse * sys.minv_jn[r][i]
                            + c.tangential_impulse * sys.minv_jt[r][i];
                    }
                    self.events.push(EventRow {
                        t: self.t,
                        kind: EventKind::Impact,
                        contact: self.model.contacts[j].name.clone(),
                        normal_velocity_before: sys.problem.u_n[r],
                        normal_velocity_after: c.normal_velocity_after,
                        normal_impulse: c.normal_impulse,
                        tangential_impulse: c.tangential_impulse,
                        case: Some(c.case.number()),
                        detail: "tangential impact".into(),
                    });
                }
                self.impacts += 1;
            }
            Err(e) => {
                // The solver could not resolve it: hold the contacts stuck by the
                // least velocity change (a plastic tangential impulse without the
                // cone), and say so.
                self.warn(format!(
                    "contacts: tangential impact at t = {:.9} s not solved ({e:?}); contacts held",
                    self.t
                ));
                let mut rows: Vec<([f64; MAX_DOF], [f64; MAX_DOF], f64)> = Vec::new();
                for r in 0..set.len() {
                    rows.push((sys.kin[r].j_n, sys.minv_jn[r], sys.kin[r].u_n.min(0.0)));
                    rows.push((sys.kin[r].j_t, sys.minv_jt[r], sys.kin[r].u_t));
                }
                self.project_rows(&rows);
            }
        }
        self.fsal = None;
        // The modes from the velocities after the tangential impact; a second
        // Painleve configuration at the same instant holds the contacts stuck.
        self.resolving_painleve = true;
        self.settle();
        self.resolving_painleve = false;
    }
}
