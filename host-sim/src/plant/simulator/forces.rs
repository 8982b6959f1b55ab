//! Contact forces in persistent contact: the motion in the current modes.
//!
//! Stages of [`Plant::evaluate_with_modes`]:
//! 1. the accelerations without contact forces, `a_0 = M^-1 Q`;
//! 2. the contact problem of the closed contacts ([`Plant::contact_system`]): the
//!    Delassus blocks of `W = J M^-1 J^T` and the contact accelerations `J a_0`
//!    plus the velocity-product parts;
//! 3. the forces from the modes' equations (`shared::impact::lcp::solve_states`):
//!    closed contacts at zero normal acceleration, sticking ones at zero
//!    tangential acceleration, slipping ones with `lambda_t = -mu s lambda_n`;
//! 4. where redundant feet (sticking or slipping) leave internal forces free,
//!    the split with every normal force `>= 0` and every sticking force inside
//!    its cone ([`Plant::share_within_cones`], `shared::impact::split`);
//! 5. `q'' = a_0 + M^-1 J^T lambda`.

use shared::impact::lcp::{solve_states_into, Direction};
use shared::impact::linalg::Solved;
use shared::impact::split::{within_cones, within_mode_equations};
use shared::impact::{ImpactOutcome, ImpactProblem, SlipState, MAX_CONTACTS};

use super::super::dynamics::{row_dot, ContactKinematics, Frame, Vector};
use super::{ContactMode, Plant, NY};
use crate::machine::bodies::MAX_DOF;

/// An evaluation with the state and modes it was made at.
pub(super) type CachedEvaluation = ([f64; NY], [ContactMode; MAX_CONTACTS], Evaluation);

/// Contact forces and accelerations at a state, in the current modes. Entries
/// past the model's (its state's [`super::super::model::PlantModel::ny`], its
/// contacts) are zero: [`Plant::evaluate_with_modes_into`] never writes them.
#[derive(Clone, Default)]
pub(super) struct Evaluation {
    pub(super) ydot: [f64; NY],
    /// Normal force of each contact (0 when open), N.
    pub(super) lambda_n: [f64; MAX_CONTACTS],
    /// Tangential force of each contact, N.
    pub(super) lambda_t: [f64; MAX_CONTACTS],
    /// Each closed slipping contact's normal coefficient relative to its normal
    /// compliance, `(W_nn - mu s W_nt) / W_nn` ([`normal_coefficient`]; `+inf` for
    /// the other contacts): the dynamic jam's event function.
    pub(super) jam: [f64; MAX_CONTACTS],
}

/// A slipping contact's normal coefficient relative to its normal compliance,
/// `(W_nn - mu s W_nt) / W_nn` (dimensionless), row `r` of `problem`, `s` the sign
/// of its slip. Its normal acceleration is `A lambda_n + B` with
/// `A = W_nn - mu s W_nt` (its own row: the friction `lambda_t = -mu s lambda_n`
/// slipping against `s`), so where the ratio falls to zero a pressing contact's
/// force `-B / A` grows without bound: the dynamic jam of Genot and Brogliato
/// (*New results on Painleve paradoxes*, 1999; Painleve's rod at 45 degrees in
/// `examples/painleve-rod.toml`). It is the contact's own coefficient: with other
/// closed contacts it leaves out their coupling, exact for one closed contact.
pub(super) fn normal_coefficient(
    problem: &ImpactProblem<f64, MAX_CONTACTS>,
    r: usize,
    s: f64,
) -> f64 {
    let mu = problem.contacts[r].friction;
    let w_nn = problem.w_nn[r][r];
    (w_nn - mu * s * problem.w_nt[r][r]) / w_nn
}

/// A contact problem assembled for a set of contacts (the first
/// `problem.len` rows of each array; the rest is left from earlier problems).
pub(super) struct ContactSystem {
    pub(super) problem: ImpactProblem<f64, MAX_CONTACTS>,
    pub(super) minv_jn: [Vector; MAX_CONTACTS],
    pub(super) minv_jt: [Vector; MAX_CONTACTS],
    pub(super) kin: [ContactKinematics; MAX_CONTACTS],
    pub(super) base_n: [f64; MAX_CONTACTS],
    pub(super) base_t: [f64; MAX_CONTACTS],
    /// Where an impact of these contacts is solved (`shared::impact::solve_into`):
    /// its outcome, and a Zeno closure's plastic one.
    pub(super) outcomes: [ImpactOutcome<f64, MAX_CONTACTS>; 2],
}

impl ContactSystem {
    /// An empty problem under `law`.
    pub(super) fn new(law: shared::impact::ImpactLaw) -> Self {
        ContactSystem {
            problem: ImpactProblem::new(law),
            minv_jn: [[0.0; MAX_DOF]; MAX_CONTACTS],
            minv_jt: [[0.0; MAX_DOF]; MAX_CONTACTS],
            kin: [ContactKinematics::default(); MAX_CONTACTS],
            base_n: [0.0; MAX_CONTACTS],
            base_t: [0.0; MAX_CONTACTS],
            outcomes: Default::default(),
        }
    }
}

/// What every evaluation fills and reads, kept from one to the next so that
/// nothing of the capacity (12 coordinates, 16 contacts: 13 KB a contact
/// problem) is zeroed or copied at each of the integrator's stages.
pub(super) struct Scratch {
    pub(super) frame: Frame,
    system: ContactSystem,
    /// The closed contacts' forces and rates (every field written by each solve).
    direction: Direction<f64, MAX_CONTACTS>,
    /// The contact problem of the last impact or mode decision, handed back
    /// ([`Plant::recycle`]) for the next one ([`Plant::contact_system`]).
    spare: Option<Box<ContactSystem>>,
}

impl Scratch {
    pub(super) fn new(model: &super::super::model::PlantModel) -> Self {
        Scratch {
            frame: Frame::empty(model),
            system: ContactSystem::new(model.law),
            direction: Direction::default(),
            spare: None,
        }
    }
}

impl Plant {
    /// Accelerations and contact forces at `y` in the current modes.
    pub(super) fn evaluate(&self, y: &[f64; NY]) -> Evaluation {
        self.with_evaluation(y, Evaluation::clone)
    }

    /// `read` of the evaluation at `y` in the current modes, where it is kept: the
    /// last one is (the event functions at a step's end ask for the state the
    /// integrator's last stage has just evaluated, FSAL), and a new one is made in
    /// its place, so that neither is copied whole (`read` takes what it needs).
    /// `read` must not evaluate the plant itself.
    pub(super) fn with_evaluation<R>(
        &self,
        y: &[f64; NY],
        read: impl FnOnce(&Evaluation) -> R,
    ) -> R {
        let mut modes = [ContactMode::Open; MAX_CONTACTS];
        modes[..self.modes.len()].copy_from_slice(&self.modes);
        let mut cache = self.last_evaluation.borrow_mut();
        let kept = matches!(cache.as_ref(), Some((yc, mc, _))
            if yc == y && *mc == modes && self.winding == self.last_winding.get());
        let (yc, mc, e) = cache.get_or_insert_with(|| ([0.0; NY], modes, Evaluation::default()));
        if !kept {
            self.evaluate_with_modes_into(y, &self.modes, e);
            *yc = *y;
            *mc = modes;
            self.last_winding.set(self.winding);
        }
        read(e)
    }

    /// Accelerations and contact forces at `y` with the contacts in `modes`.
    pub(super) fn evaluate_with_modes(&self, y: &[f64; NY], modes: &[ContactMode]) -> Evaluation {
        let mut e = Evaluation::default();
        self.evaluate_with_modes_into(y, modes, &mut e);
        e
    }

    /// [`Plant::evaluate_with_modes`] written into `out`: the entries of the
    /// model's state and contacts.
    pub(super) fn evaluate_with_modes_into(
        &self,
        y: &[f64; NY],
        modes: &[ContactMode],
        out: &mut Evaluation,
    ) {
        self.evaluations.set(self.evaluations.get() + 1);
        let n = self.model.dof;
        let q = self.model.q(y);
        let v = self.model.v(y);
        let (tau, di) = self.motor_rates(y, &v);
        let scratch = &mut *self.scratch.borrow_mut();
        let frame = &mut scratch.frame;
        let mut f = frame.assemble_into(&self.model, &q, &self.held, Some((&v, &tau)));
        for (fi, held) in f.iter_mut().zip(self.held) {
            if held {
                *fi = 0.0;
            }
        }
        let mut acc = frame.solve(&f);

        // Closed contacts: forces from their mode's equations.
        let (lambda_n, lambda_t, jam) = (&mut out.lambda_n, &mut out.lambda_t, &mut out.jam);
        lambda_n[..modes.len()].fill(0.0);
        lambda_t[..modes.len()].fill(0.0);
        jam[..modes.len()].fill(f64::INFINITY);
        // The closed contacts, without allocating (this runs at every stage).
        let mut closed_buf = [0usize; MAX_CONTACTS];
        let mut n_closed = 0;
        for (j, m) in modes.iter().enumerate() {
            if m.closed() {
                closed_buf[n_closed] = j;
                n_closed += 1;
            }
        }
        let closed = &closed_buf[..n_closed];
        if !closed.is_empty() {
            let sys = &mut scratch.system;
            self.fill_contact_system(frame, &v, closed, Some(&acc), sys);
            let mut active = [false; MAX_CONTACTS];
            let mut mode = [SlipState::Stick; MAX_CONTACTS];
            for (r, &j) in closed.iter().enumerate() {
                active[r] = true;
                mode[r] = modes[j].slip_state();
                if let Some(s) = modes[j].slip_sign() {
                    if sys.problem.contacts[r].friction > 0.0 {
                        jam[j] = normal_coefficient(&sys.problem, r, s);
                    }
                }
            }
            let zeros = [0.0; MAX_CONTACTS];
            // No solution of the closed contacts' equations: no contact force (the
            // mode is re-decided at the next event).
            let d = &mut scratch.direction;
            if let Some((_, how)) = solve_states_into(
                &sys.problem,
                &sys.base_n,
                &sys.base_t,
                &active,
                &mode,
                Some(&zeros),
                None,
                d,
            ) {
                let (x, y, motion) = self.share_within_cones(closed, modes, sys, d, how);
                // The internal forces do no work: accelerations from either split,
                // unless the split changed the slipping contacts' motion.
                let (fx, fy) = if motion { (&x, &y) } else { (&d.x, &d.y) };
                for (r, &j) in closed.iter().enumerate() {
                    lambda_n[j] = x[r];
                    lambda_t[j] = y[r];
                    for i in 0..n {
                        acc[i] += fx[r] * sys.minv_jn[r][i] + fy[r] * sys.minv_jt[r][i];
                    }
                }
            }
        }
        let ydot = &mut out.ydot;
        ydot[..n].copy_from_slice(&v[..n]);
        ydot[n..2 * n].copy_from_slice(&acc[..n]);
        for k in 0..self.model.rotors.len() {
            ydot[self.model.current(k)] = di[k];
        }
    }

    /// The closed contacts' forces with the internal forces chosen so that every
    /// normal force is `>= 0` and every sticking contact is inside its cone (three
    /// slipping feet of one body can also share their load in more than one
    /// way: the mode decision takes one where none pulls), where the equations left them
    /// undetermined ([`shared::impact::split`], the same split the mode decision's
    /// stick check uses). Where no split holds every cone, the forces are left where
    /// the largest violation is smallest, and the stick event function
    /// (`mu lambda_n - |lambda_t|`) reports it.
    ///
    /// Where no split of the internal forces keeps every normal force `>= 0` and
    /// a closed contact slips, the split is sought among every solution of the
    /// modes' equations (`shared::impact::split::within_mode_equations`): their
    /// slipping contacts' motion is then not fixed by the equations, and the
    /// mode decision chose one such solution where none pulls (two hinged bodies
    /// slipping on feet along one line: the internal forces alone left a foot at
    /// -0.56 N right after the decision). The third value is true when that split
    /// is the one taken: the accelerations then follow from its forces.
    pub(super) fn share_within_cones(
        &self,
        closed: &[usize],
        modes: &[ContactMode],
        sys: &ContactSystem,
        d: &Direction<f64, MAX_CONTACTS>,
        how: Solved,
    ) -> ([f64; MAX_CONTACTS], [f64; MAX_CONTACTS], bool) {
        let (mut x, mut y) = (d.x, d.y);
        let mut active = [false; MAX_CONTACTS];
        let mut mode = [SlipState::Stick; MAX_CONTACTS];
        for (r, &j) in closed.iter().enumerate() {
            active[r] = true;
            mode[r] = modes[j].slip_state();
        }
        // How far contact r's forces miss: a pull, or a sticking force outside
        // its cone, N (<= 0 when they hold).
        let miss = |r: usize, x: &[f64; MAX_CONTACTS], y: &[f64; MAX_CONTACTS]| {
            let cone = if mode[r] == SlipState::Stick {
                y[r].abs() - sys.problem.contacts[r].friction * x[r]
            } else {
                f64::NEG_INFINITY
            };
            cone.max(-x[r])
        };
        let inside = |x: &[f64; MAX_CONTACTS], y: &[f64; MAX_CONTACTS]| {
            (0..closed.len()).all(|r| miss(r, x, y) <= 1e-9 * (x[r].abs() + y[r].abs()))
        };
        if inside(&x, &y) || how == Solved::Unique {
            return (x, y, false);
        }
        let scale =
            (0..closed.len()).fold(f64::MIN_POSITIVE, |s, r| s.max(x[r].abs()).max(y[r].abs()));
        // Never finer than the mode decision's tolerance on forces (a thousandth of
        // eps_F, `decide_modes`): a split the decision found within it is found
        // here too, rather than replaced by the least violation.
        let tol = (1e-9 * scale).max(1e-3 * self.force_tolerance());
        let split = within_cones(&sys.problem, &active, &mode, true, &mut x, &mut y, tol);
        let slipping = (0..closed.len()).any(|r| mode[r] != SlipState::Stick);
        if split.feasible() || !slipping {
            return (x, y, false);
        }
        let (mut mx, mut my) = (d.x, d.y);
        if within_mode_equations(&sys.problem, &active, &mode, &mut mx, &mut my, tol).feasible() {
            return (mx, my, true);
        }
        // Neither holds every cone: the forces of least violation, of the larger
        // set where it misses by less. Near where the modes' equations stop having
        // a split without a pulling foot, their least violation tends to zero, so
        // the forces (and the lift-off event's function) stay continuous there
        // rather than jumping to the internal forces' least violation.
        let violation = |x: &[f64; MAX_CONTACTS], y: &[f64; MAX_CONTACTS]| {
            (0..closed.len()).fold(0.0f64, |v, r| v.max(miss(r, x, y)))
        };
        if violation(&mx, &my) < violation(&x, &y) {
            (mx, my, true)
        } else {
            (x, y, false)
        }
    }

    /// The contact problem of the contacts `set`: Delassus matrix
    /// `W = J M^-1 J^T` (rotors free unless held), `M^-1 J^T`, and, given the
    /// accelerations without contact forces, the contact accelerations they add to.
    /// In the storage the last one handed back ([`Plant::recycle`]), where there is
    /// one: only its first `set.len()` rows are written and read, so that an
    /// impact or a mode decision neither zeroes nor moves the problem's capacity.
    pub(super) fn contact_system(
        &self,
        frame: &Frame,
        v: &Vector,
        set: &[usize],
        acc_free: Option<&Vector>,
    ) -> Box<ContactSystem> {
        let spare = self.scratch.borrow_mut().spare.take();
        let mut sys = spare.unwrap_or_else(|| Box::new(ContactSystem::new(self.model.law)));
        self.fill_contact_system(frame, v, set, acc_free, &mut sys);
        sys
    }

    /// Hands a contact problem from [`Plant::contact_system`] back for the next.
    pub(super) fn recycle(&self, sys: Box<ContactSystem>) {
        self.scratch.borrow_mut().spare = Some(sys);
    }

    /// [`Plant::contact_system`] written into `sys`: its first `set.len()` rows.
    pub(super) fn fill_contact_system(
        &self,
        frame: &Frame,
        v: &Vector,
        set: &[usize],
        acc_free: Option<&Vector>,
        sys: &mut ContactSystem,
    ) {
        let dof = self.model.dof;
        sys.problem.len = set.len();
        sys.problem.law = self.model.law;
        for (r, &j) in set.iter().enumerate() {
            sys.kin[r] = frame.contact(&self.model, j, v);
            let k = &sys.kin[r];
            sys.minv_jn[r] = frame.solve(&k.j_n);
            sys.minv_jt[r] = frame.solve(&k.j_t);
            sys.problem.u_n[r] = k.u_n;
            sys.problem.u_t[r] = k.u_t;
            sys.problem.contacts[r] = self.model.contacts[j].law;
            let (base_n, base_t) = match acc_free {
                Some(a) => (
                    row_dot(&k.j_n, a, dof) + k.bias_n,
                    row_dot(&k.j_t, a, dof) + k.bias_t,
                ),
                None => (0.0, 0.0),
            };
            sys.base_n[r] = base_n;
            sys.base_t[r] = base_t;
        }
        for r in 0..set.len() {
            for c in 0..set.len() {
                let (jn, jt) = (&sys.kin[r].j_n, &sys.kin[r].j_t);
                sys.problem.w_nn[r][c] = row_dot(jn, &sys.minv_jn[c], dof);
                sys.problem.w_nt[r][c] = row_dot(jn, &sys.minv_jt[c], dof);
                sys.problem.w_tt[r][c] = row_dot(jt, &sys.minv_jt[c], dof);
            }
        }
    }
}
