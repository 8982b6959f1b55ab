//! At an event: impacts until nothing approaches, then the contacts' modes from
//! the complementarity problem at acceleration level, and the projection of the
//! state onto the closed contacts' constraints.

use shared::impact::lcp::{find_direction, Direction, NormalRule, Tolerances};
use shared::impact::lemke::Outcome;
use shared::impact::linalg::{solve_weighted_in, DIM};
use shared::impact::MAX_CONTACTS;

use super::super::dynamics::{row_dot, ContactKinematics, Pose, Vector};
use super::events::JAM_RATIO;
use super::forces::normal_coefficient;
use super::{ContactMode, Plant};
use crate::event::{EventKind, EventRow};
use crate::machine::bodies::MAX_DOF;

/// The least change `dx = -M^-1 J^T W^+ r` that zeroes `J x + r` for rows
/// `(J, M^-1 J^T, r)`, with `W = J M^-1 J^T` (weighted minimum norm where singular).
pub(super) fn least_change(rows: &[(Vector, Vector, f64)]) -> Option<Vector> {
    // Storage sized to the rows (two contacts' projection fits 4 x 4): the same
    // arithmetic as in `DIM x DIM`, without its zero fills.
    match rows.len() {
        0 => None,
        1..=4 => least_change_in::<4>(rows),
        5..=8 => least_change_in::<8>(rows),
        9..=16 => least_change_in::<16>(rows),
        _ => least_change_in::<DIM>(rows),
    }
}

/// [`least_change`] in storage of `D x D`.
fn least_change_in<const D: usize>(rows: &[(Vector, Vector, f64)]) -> Option<Vector> {
    let n = rows.len().min(D);
    let mut w = [[0.0; D]; D];
    let mut b = [0.0f64; D];
    for r in 0..n {
        for c in 0..n {
            w[r][c] = row_dot(&rows[r].0, &rows[c].1, MAX_DOF);
        }
        b[r] = -rows[r].2;
    }
    let (x, _) = solve_weighted_in(&w, &b, &[1.0; D], n)?;
    let mut dx = [0.0; MAX_DOF];
    for r in 0..n {
        for i in 0..MAX_DOF {
            dx[i] += x[r] * rows[r].1[i];
        }
    }
    Some(dx)
}

impl Plant {
    /// At an event: impacts where contacts approach, then the contacts' modes from
    /// the complementarity problem at acceleration level; the last event handled
    /// is kept for a stop's message (the events themselves go to the caller).
    pub(super) fn settle(&mut self) {
        self.settle_contacts();
        if let Some(e) = self.events.last() {
            self.last_event = Some((e.kind, e.t));
        }
    }

    /// [`Plant::settle`]'s impacts and modes.
    fn settle_contacts(&mut self) {
        // A current that reached its driver's limit is held there.
        self.clamp_currents();
        // Whether the next decision is checked at the state it projects onto.
        let mut check = true;
        for _ in 0..16 {
            let mut kin = self.kinematics();
            let touching: Vec<usize> = (0..kin.len())
                .filter(|j| kin[*j].gap <= self.settings.together_gap)
                .collect();
            if touching
                .iter()
                .any(|j| kin[*j].u_n < -self.settings.velocity_tolerance)
            {
                self.impact(&touching);
                continue;
            }
            if self.end_slips(&touching, &kin) {
                kin = self.kinematics();
            }
            self.decide_modes(&touching, &kin);
            if check && self.pulls_where_projected() {
                // Decided again from the state projected onto the closed
                // contacts, once: that decision stands.
                check = false;
                continue;
            }
            return;
        }
        self.warn(format!(
            "contacts: no consistent state after 16 impacts at t = {:.9} s",
            self.t
        ));
    }

    /// Whether a closed contact pulls (normal force below `-eps_F`) at the
    /// current state in the current modes: after a decision, the state
    /// projected onto the closed contacts' constraints.
    ///
    /// The decision is made at the state before the projection, which moves a
    /// touching foot up to the together gap onto the fundament. Where the forces
    /// are sensitive to the pose (two hinged bodies slipping on their feet),
    /// that moved them: a foot decided at +0.02 N was at -0.26 N after a turn of
    /// the platform by 1e-6 rad, and its lift-off came at the same instant with
    /// a trace row of the pulling foot between. The evaluation is the one the
    /// next step starts from (kept for it), so the check costs nothing there.
    fn pulls_where_projected(&self) -> bool {
        if !self.modes.iter().any(|m| m.closed()) {
            return false;
        }
        let eps_f = self.force_tolerance();
        let y = self.y;
        self.with_evaluation(&y, |e| {
            self.modes
                .iter()
                .enumerate()
                .any(|(j, m)| m.closed() && e.lambda_n[j] < -eps_f)
        })
    }

    /// Every contact's kinematics at the current state.
    fn kinematics(&self) -> Vec<ContactKinematics> {
        let q = self.q();
        let v = self.v();
        let pose = Pose::new(&self.model, &q);
        (0..self.model.contacts.len())
            .map(|j| pose.contact(&self.model, j, &v))
            .collect()
    }

    /// Ends exactly the slips that ended (their event fires within the velocity
    /// tolerance of zero): the least mass-weighted velocity change that zeroes
    /// their slip and keeps the closed contacts' normal velocities, so the choice
    /// between stick and slip starts from zero slip and cannot chatter. Returns
    /// true where it changed the velocities.
    ///
    /// The open contacts among the `touching` that the change would make approach
    /// (a foot that has just struck, beside one whose slip ended: 3 mm/s) keep
    /// their normal velocity too: the friction impulse is one the floor can give
    /// without another impact. (Left free, such a foot closed while approaching,
    /// and the decision made for it left its neighbour pulling, -1.6 N.)
    ///
    /// Still needed with the cone-aware stick check (it is about the slip
    /// velocity, not the split): without it `closed_loop` takes 89 s instead of
    /// 1.6 s, `plant_references` 332 s instead of 0.3 s, and
    /// `both_feet_sticking_stay_inside_their_cones` fails. Only where friction can
    /// stop the slip: the snap is the friction impulse that would have ended it; a
    /// frictionless contact has none (and no slip-end event), so nothing may
    /// change its slip.
    fn end_slips(&mut self, touching: &[usize], kin: &[ContactKinematics]) -> bool {
        let modes = &self.modes;
        let ending: Vec<usize> = (0..modes.len())
            .filter(|&j| {
                matches!(
                    modes[j],
                    ContactMode::SlipPositive | ContactMode::SlipNegative
                ) && kin[j].u_t.abs() <= 2.0 * self.settings.velocity_tolerance
                    && self.model.contacts[j].law.friction > 0.0
            })
            .collect();
        if ending.is_empty() {
            return false;
        }
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let mut rows = Vec::new();
        for (j, mode) in self.modes.iter().enumerate() {
            if mode.closed() {
                let k = frame.contact(&self.model, j, &v);
                rows.push((k.j_n, frame.solve(&k.j_n), k.u_n));
                if ending.contains(&j) || *mode == ContactMode::Stick {
                    rows.push((k.j_t, frame.solve(&k.j_t), k.u_t));
                }
            }
        }
        let before = self.y;
        self.project_rows(&rows);
        let tolerance = self.settings.velocity_tolerance;
        let after = self.kinematics();
        let turned: Vec<usize> = touching
            .iter()
            .copied()
            .filter(|&j| {
                !self.modes[j].closed() && kin[j].u_n >= -tolerance && after[j].u_n < -tolerance
            })
            .collect();
        if !turned.is_empty() {
            self.y = before;
            for &j in &turned {
                let k = frame.contact(&self.model, j, &v);
                rows.push((k.j_n, frame.solve(&k.j_n), 0.0));
            }
            self.project_rows(&rows);
        }
        true
    }

    /// The modes of the touching contacts (not approaching) from the
    /// complementarity problem at acceleration level; the rest open.
    pub(super) fn decide_modes(&mut self, touching: &[usize], kin: &[ContactKinematics]) {
        let old = self.modes.clone();
        let mut new = vec![ContactMode::Open; self.modes.len()];
        let candidates: Vec<usize> = touching
            .iter()
            .copied()
            .filter(|j| kin[*j].u_n <= self.settings.velocity_tolerance)
            .collect();
        if !candidates.is_empty() && !self.close_candidates(&candidates, kin, &mut new) {
            return;
        }
        self.push_mode_changes(&old, &new, kin);
        self.modes = new;
        self.fsal = None;
        self.project();
    }

    /// The modes of the `candidates` (touching, not approaching) written into
    /// `new` from the complementarity problem at acceleration level: the active
    /// set closed in its friction states, the rest open. `false` when no
    /// consistent modes were found or a contact is at its dynamic jam: the
    /// Painleve rule has then handled the event.
    fn close_candidates(
        &mut self,
        candidates: &[usize],
        kin: &[ContactKinematics],
        new: &mut [ContactMode],
    ) -> bool {
        let (mut d, coefficient, tol_f) = self.solve_mode_problem(candidates, kin);
        if self.painleve_if_inconsistent(candidates, &d) {
            return false;
        }
        if self.painleve_at_dynamic_jam(candidates, &mut d, &coefficient, tol_f) {
            return false;
        }
        // The active set is closed, in its friction states; the rest open. A
        // contact at the boundary (no force and no acceleration) is active
        // when it can be (the enumeration tries the larger sets first): its
        // lift-off is then the event where its force goes below -eps_F.
        for (r, &j) in candidates.iter().enumerate() {
            if d.active[r] {
                new[j] = ContactMode::from_slip(d.mode[r]);
            }
        }
        self.open_boundary_contacts_that_pull(candidates, &d.x, tol_f, new);
        true
    }

    /// The complementarity problem of the `candidates` at acceleration level,
    /// solved: its answer (active set, friction states, normal forces), each
    /// slipping contact's normal coefficient (infinite otherwise; for the dynamic
    /// jam) and the problem's force tolerance `tol_f`, N.
    fn solve_mode_problem(
        &self,
        candidates: &[usize],
        kin: &[ContactKinematics],
    ) -> (Direction<f64, MAX_CONTACTS>, [f64; MAX_CONTACTS], f64) {
        // The contact problem at acceleration level: with every contact open,
        // the accelerations a_0 = M^-1 Q, and the contact accelerations they
        // give (`base_n`, `base_t`); W = J M^-1 J^T.
        let open = vec![ContactMode::Open; self.modes.len()];
        let free = self.evaluate_with_modes(&self.y, &open);
        let n = self.model.dof;
        let mut acc = [0.0; MAX_DOF];
        acc[..n].copy_from_slice(&free.ydot[n..2 * n]);
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let sys = self.contact_system(&frame, &v, candidates, Some(&acc));
        // Slip states from the slip velocities, with zero below the tolerance.
        let mut slip = [0.0; MAX_CONTACTS];
        for (r, &j) in candidates.iter().enumerate() {
            if kin[j].u_t.abs() > self.settings.velocity_tolerance {
                slip[r] = kin[j].u_t;
            }
        }
        // The complementarity problem (normal force >= 0, normal acceleration
        // >= 0, one of them zero; a sticking force inside its cone, a slipping
        // one on its edge against the slip, a contact at zero slip slipping
        // only the way it then moves), solved for all candidates together,
        // whatever event brought us here. Its tolerance is a thousandth of the
        // event functions' margin `eps_F` (and never below rounding), so the
        // condition whose event fired is violated by a thousand times the
        // tolerance and cannot be chosen again: a contact whose normal force
        // reached -eps_F opens, a sticking contact whose friction left its
        // cone by eps_F slips.
        let eps_f = self.force_tolerance();
        let m = candidates.len();
        let scale_a = sys.base_n[..m]
            .iter()
            .chain(sys.base_t[..m].iter())
            .fold(1.0, |m: f64, a| m.max(a.abs()));
        let mass = self.model.total_mass();
        let tol_f = (1e-3 * eps_f).max(1e-13 * scale_a * mass);
        // (The slips are already zero below the velocity tolerance.)
        let tol = Tolerances {
            velocity: tol_f / mass,
            impulse: tol_f,
            zero_slip: 0.0,
        };
        let zeros = [0.0; MAX_CONTACTS];
        let d = find_direction(
            &sys.problem,
            &sys.base_n,
            &sys.base_t,
            &slip,
            NormalRule::TargetAll(&zeros),
            &tol,
        );
        // Each slipping contact's normal coefficient, for the dynamic jam.
        let mut coefficient = [f64::INFINITY; MAX_CONTACTS];
        for (r, c) in coefficient.iter_mut().enumerate().take(candidates.len()) {
            let s = ContactMode::from_slip(d.mode[r]).slip_sign();
            if let (Some(s), true) = (s, sys.problem.contacts[r].friction > 0.0) {
                *c = normal_coefficient(&sys.problem, r, s);
            }
        }
        self.recycle(sys);
        (d, coefficient, tol_f)
    }

    /// No consistent modes found within Lemke's pivot cap (a ray, the cap, or an
    /// answer that failed its check): the Painleve rule, once, for the
    /// `candidates` (`true`: applied).
    fn painleve_if_inconsistent(
        &mut self,
        candidates: &[usize],
        d: &Direction<f64, MAX_CONTACTS>,
    ) -> bool {
        if d.consistent && d.ends_at_one {
            return false;
        }
        let why = match d.outcome {
            Outcome::Ray { pivots, .. } => format!("a ray after {pivots} pivots"),
            Outcome::Cap { pivots } => format!("no decision within {pivots} pivots"),
            Outcome::Inexact { pivots } => {
                format!("an answer that failed its check after {pivots} pivots")
            }
            Outcome::Solved { .. } => "no consistent friction states".into(),
        };
        self.painleve(
            candidates,
            "no consistent contact force; tangential impact",
            &format!("the mode decision ended at {why}"),
        );
        true
    }

    /// A contact the decision `d` left slipping at its dynamic jam (its normal
    /// coefficient `(W_nn - mu s W_nt) / W_nn`, in `coefficient`, at most twice
    /// the jam event's ratio: the force `-B / A` grows without bound with a
    /// bounded impulse, Genot and Brogliato 1999): pressing (its force above
    /// `tol_f`, N), it takes an impact without collision, the tangential impact
    /// of the Painleve rule, which stops its slip (`true`: applied); not
    /// pressing, it lifts off (the zero-force solution, which needs no impulse),
    /// left out of `d`'s active set. A rigid contact cannot choose between the
    /// two where both are consistent (beyond the jam `A < 0`: lift-off, or a slip
    /// whose force only compliance could say is unstable); this rule takes the
    /// one that gains no energy and never loops: after the impact the contact
    /// sticks.
    fn painleve_at_dynamic_jam(
        &mut self,
        candidates: &[usize],
        d: &mut Direction<f64, MAX_CONTACTS>,
        coefficient: &[f64; MAX_CONTACTS],
        tol_f: f64,
    ) -> bool {
        for (r, &j) in candidates.iter().enumerate() {
            if !d.active[r] || coefficient[r] > 2.0 * JAM_RATIO {
                continue;
            }
            if d.x[r] > tol_f {
                let why = format!(
                    "a dynamic jam of {}: its normal coefficient (W_nn - mu s W_nt) / W_nn = {:.3e}, its force {:.6} N and growing without bound",
                    self.model.contacts[j].name,
                    coefficient[r],
                    d.x[r]
                );
                self.painleve(candidates, "dynamic jam; tangential impact", &why);
                return true;
            }
            d.active[r] = false;
        }
        false
    }

    /// An event for every contact whose mode changes from `old` to `new`:
    /// contact, lift-off, stick or slip (its velocities `kin`, no impulse).
    fn push_mode_changes(
        &mut self,
        old: &[ContactMode],
        new: &[ContactMode],
        kin: &[ContactKinematics],
    ) {
        for j in 0..new.len() {
            let (a, b) = (old[j], new[j]);
            if a == b {
                continue;
            }
            let kind = match (a.closed(), b.closed(), b) {
                (false, true, _) => EventKind::Contact,
                (true, false, _) => EventKind::Liftoff,
                (true, true, ContactMode::Stick) => EventKind::Stick,
                (true, true, _) => EventKind::Slip,
                (false, false, _) => continue,
            };
            self.events.push(EventRow {
                t: self.t,
                kind,
                contact: self.model.contacts[j].name.clone(),
                normal_velocity_before: kin[j].u_n,
                normal_velocity_after: kin[j].u_n,
                normal_impulse: 0.0,
                tangential_impulse: 0.0,
                case: None,
                detail: b.name().into(),
            });
        }
    }

    /// Opens the contacts the decision left at the boundary (no force within
    /// `tol_f`, N, yet closed) where the modes' own forces would make one pull.
    ///
    /// The decision's forces `x` (one per candidate) solve its complementarity
    /// problem with such a contact carrying nothing; closed, the contact joins the
    /// modes' equations, and where those leave the forces undetermined (feet of
    /// two hinged bodies on one line) their weighted minimum-norm solution may
    /// differ from the decision's, with the boundary contact pulling: two bodies
    /// on eight feet had one at -0.56 N right after the decision, below the
    /// lift-off threshold, and the same event came back at the same instant until
    /// a step was taken past it. Open, with no force and no normal acceleration
    /// (to the tolerance), it satisfies the problem as well, and the forces of the
    /// others are the decision's. The most pulling one is opened first, then the
    /// forces are evaluated again.
    fn open_boundary_contacts_that_pull(
        &self,
        candidates: &[usize],
        x: &[f64; MAX_CONTACTS],
        tol_f: f64,
        new: &mut [ContactMode],
    ) {
        // The common decision leaves no contact at the boundary: no evaluation.
        let at_boundary = |new: &[ContactMode]| {
            candidates
                .iter()
                .enumerate()
                .any(|(r, &j)| new[j].closed() && x[r] <= tol_f)
        };
        for _ in 0..candidates.len() {
            if !at_boundary(new) {
                return;
            }
            let e = self.evaluate_with_modes(&self.y, new);
            let pulling = candidates
                .iter()
                .enumerate()
                .filter(|&(r, &j)| new[j].closed() && x[r] <= tol_f && e.lambda_n[j] < -tol_f)
                .min_by(|a, b| e.lambda_n[*a.1].total_cmp(&e.lambda_n[*b.1]));
            match pulling {
                Some((_, &j)) => new[j] = ContactMode::Open,
                None => return,
            }
        }
    }

    /// Projects the state onto the closed contacts' constraints: velocities
    /// (`u_n = 0`, and `u_t = 0` when sticking) by the mass-weighted least change
    /// `dq' = -M^-1 J^T W^+ (J q')`, and positions (`gap = 0`) likewise.
    pub(super) fn project(&mut self) {
        let closed: Vec<usize> = (0..self.modes.len())
            .filter(|j| self.modes[*j].closed())
            .collect();
        if closed.is_empty() {
            return;
        }
        let q = self.q();
        let v = self.v();
        let mut vel_rows = Vec::new();
        let mut pos_rows = Vec::new();
        {
            // The frame in the evaluations' scratch (this runs after every step
            // with a closed contact).
            let frame = &mut self.scratch.borrow_mut().frame;
            frame.assemble_into(&self.model, &q, &self.held, None);
            for &j in &closed {
                let k = frame.contact(&self.model, j, &v);
                let minv_n = frame.solve(&k.j_n);
                vel_rows.push((k.j_n, minv_n, k.u_n));
                pos_rows.push((k.j_n, minv_n, k.gap));
                if self.modes[j] == ContactMode::Stick {
                    vel_rows.push((k.j_t, frame.solve(&k.j_t), k.u_t));
                }
            }
        }
        self.project_rows(&vel_rows);
        // Positions: one Gauss-Newton step on the gaps.
        if let Some(dq) = least_change(&pos_rows) {
            for i in 0..self.model.dof {
                self.y[i] += dq[i];
            }
        }
    }

    /// Applies the least mass-weighted velocity change that zeroes the rows.
    pub(super) fn project_rows(&mut self, rows: &[(Vector, Vector, f64)]) {
        if let Some(dv) = least_change(rows) {
            let n = self.model.dof;
            for i in 0..n {
                self.y[n + i] += dv[i];
            }
        }
    }
}
