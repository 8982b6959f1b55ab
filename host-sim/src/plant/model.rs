//! The constant model of the simulated machine (MuJoCo's `mjModel`): the machine
//! file turned into body-frame geometry and a layout of generalized coordinates.
//! The changing state lives in the plant ([`super::simulator::Plant::y`]).
//!
//! **Coordinates.** Planar rigid bodies joined by revolute joints into trees:
//! - a tree not hinged to the fundament has a free root: `(x, y, theta)`, its centre
//!   of mass and its angle (the platform of a one-body machine: exactly the
//!   coordinates of the single-platform plant);
//! - a tree hinged to the fundament has its root on that hinge: its angle only;
//! - every further body of a tree: its angle (world, not relative to its parent);
//! - then each rotor's eccentric angle `phi_k` in the frame of the body carrying it.
//!
//! With world angles a point of body `b` is `p = base + sum_a R(theta_a) s_a` over
//! the bodies `a` from the root to `b` (`s_a` constant in `a`'s frame: the hinge of
//! the next body, or the point itself), so its velocity is linear in `q'` with one
//! column per angle, `z x R(theta_a) s_a` (Featherstone, *Rigid Body Dynamics
//! Algorithms*, 2008, ch. 4, for trees in minimal coordinates). Every body's
//! reference point is its centre of mass for a free root and its hinge otherwise.

use shared::impact::{ContactLaw, ImpactLaw};
use shared::vec2::{sub, unrotate};

use crate::machine::bodies::{FUNDAMENT, PLATFORM};
use crate::machine::{Machine, MotorParams};

use crate::machine::bodies::{MAX_DOF, MAX_ROTORS};

/// Capacity of the integrated state: `q`, `q'` (up to [`MAX_DOF`] each) and the
/// winding currents; a machine uses the first [`PlantModel::ny`].
pub const NY: usize = 2 * MAX_DOF + MAX_ROTORS;

/// How a body hangs in its tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mount {
    /// A tree's free root: its centre of mass is coordinates `x`, `x + 1`.
    Free {
        /// Index of its `x` coordinate.
        x: usize,
    },
    /// A tree's root hinged to the fundament at `pivot` (world, m).
    Pinned {
        /// The hinge, world, m.
        pivot: [f64; 2],
    },
    /// Hinged to body `parent` at `joint` (the parent's frame, from its reference
    /// point, m).
    Child {
        /// The parent body.
        parent: usize,
        /// The hinge in the parent's frame, m.
        joint: [f64; 2],
    },
}

/// A rigid body of the machine.
#[derive(Clone, Debug)]
pub struct BodyModel {
    /// Name (`platform` for the first).
    pub name: String,
    /// Mass without eccentric masses, kg.
    pub mass: f64,
    /// Inertia about its centre of mass, kg m^2.
    pub inertia: f64,
    /// How it hangs in its tree.
    pub mount: Mount,
    /// Index of its angle coordinate (world angle).
    pub angle: usize,
    /// Its centre of mass from its reference point, body frame, m (zero for a
    /// free root).
    pub com: [f64; 2],
    /// The bodies from its tree's root down to itself.
    pub chain: Vec<usize>,
}

/// An unbalance rotor, in the frame of the body carrying it.
#[derive(Clone, Debug)]
pub struct RotorModel {
    /// The body carrying it.
    pub body: usize,
    /// Index of its eccentric angle coordinate `phi`.
    pub phi: usize,
    /// Axis position from the body's reference point, body frame, m.
    pub axis: [f64; 2],
    /// Eccentric mass, kg.
    pub mass: f64,
    /// Eccentricity, m.
    pub eccentricity: f64,
    /// Inertia about the axis without the eccentric mass, kg m^2.
    pub inertia: f64,
    /// `+1` ccw, `-1` cw: the driven sense.
    pub sense: f64,
    /// Eccentric angle of the index pulse, rad.
    pub index_angle: f64,
    /// Its motor.
    pub motor: MotorParams,
}

/// What a contact point strikes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Face {
    /// The fundament's line ([`PlantModel::ground_point`], [`PlantModel::normal`]).
    Fundament,
    /// A flat face fixed on a body.
    Body {
        /// The body.
        body: usize,
        /// A point of the face, that body's frame from its reference point, m.
        point: [f64; 2],
        /// The face's unit normal, that body's frame, towards the contact's body.
        normal: [f64; 2],
    },
}

/// A contact point fixed on a body, against a face.
#[derive(Clone, Debug)]
pub struct ContactPoint {
    /// Name (K1, K2, ...).
    pub name: String,
    /// The body the point is fixed on.
    pub body: usize,
    /// Position from that body's reference point, body frame, m.
    pub point: [f64; 2],
    /// What it strikes.
    pub face: Face,
    /// Restitution, friction and weight.
    pub law: ContactLaw<f64>,
}

/// A revolute joint's torsional spring-damper: torque `-k (alpha - alpha_0) - c alpha'`
/// on body `b` and its reaction on body `a`, `alpha = theta_b - theta_a` (the
/// fundament's angle is 0).
#[derive(Clone, Debug)]
pub struct Spring {
    /// Name of the joint.
    pub name: String,
    /// The first body of `bodies = [A, B]` (`None`: the fundament).
    pub a: Option<usize>,
    /// The second body (`None`: the fundament).
    pub b: Option<usize>,
    /// Stiffness, N m/rad.
    pub stiffness: f64,
    /// Damping, N m s/rad.
    pub damping: f64,
    /// Relative angle at which the spring is relaxed, rad.
    pub rest_angle: f64,
}

/// The machine, ready to simulate.
#[derive(Clone, Debug)]
pub struct PlantModel {
    /// The bodies, the platform first; parents before their children in
    /// [`PlantModel::order`].
    pub bodies: Vec<BodyModel>,
    /// The bodies in coordinate order (every parent before its children).
    pub order: Vec<usize>,
    /// Each free root's `x` coordinate and its tree's mass (bodies, then the
    /// eccentric masses they carry), kg.
    pub free_roots: Vec<(usize, f64)>,
    /// Number of generalized coordinates.
    pub dof: usize,
    /// Number of the bodies' coordinates (the rotors' follow).
    pub body_dof: usize,
    /// The rotors (one or two).
    pub rotors: Vec<RotorModel>,
    /// The joints with a spring or a damper.
    pub springs: Vec<Spring>,
    /// The contact points.
    pub contacts: Vec<ContactPoint>,
    /// A point of the fundament line, m.
    pub ground_point: [f64; 2],
    /// Unit normal of the fundament, towards the machine.
    pub normal: [f64; 2],
    /// Unit tangent `t = (-n_y, n_x)`.
    pub tangent: [f64; 2],
    /// Gravity, m/s^2.
    pub gravity: [f64; 2],
    /// The impact law.
    pub law: ImpactLaw,
    /// Supply voltage of the motor driver, V.
    pub supply_voltage: f64,
    /// The H-bridges as wired (`[drive] decay`, `pwm_hz`).
    pub bridge: shared::drive::BridgeConfig,
    /// Whether the closed forms of one free body carrying its rotors are used
    /// where the model is one ([`PlantModel::one_free_body`]); off only to test
    /// them against the generic pass.
    closed_forms: bool,
}

/// One free body and its rotors, the constants of the closed forms of its mass
/// matrix and forces (coordinates `x, y` of its reference point, its angle, each
/// rotor's `phi`), read from the model where they are used
/// ([`PlantModel::one_free_body`]): never kept, so never older than the model.
#[derive(Clone, Debug)]
pub struct OneFreeBody {
    /// The reference point's `x` coordinate (`y` follows).
    pub x: usize,
    /// The body's angle coordinate.
    pub theta: usize,
    /// The body's mass, kg.
    pub mass: f64,
    /// The body's centre of mass from its reference point (body frame, m).
    pub com: [f64; 2],
    /// The whole machine's mass, kg.
    pub total_mass: f64,
    /// Every inertia about its own point, summed, kg m^2: the body's and the
    /// rotors' (all turn with the body's angle).
    pub total_inertia: f64,
    /// Each rotor: its `phi` coordinate, its axis from the body's reference point
    /// (body frame, m), its eccentric mass, kg, and inertia about it, kg m^2.
    pub rotors: [(usize, [f64; 2], f64, f64); MAX_ROTORS],
}

impl OneFreeBody {
    /// The constants of `model` if it is one free body carrying every rotor.
    fn of(model: &PlantModel) -> Option<Self> {
        let [body] = &model.bodies[..] else {
            return None;
        };
        let Mount::Free { x } = body.mount else {
            return None;
        };
        let mut rotors = [(0, [0.0; 2], 0.0, 0.0); MAX_ROTORS];
        for (k, r) in model.rotors.iter().enumerate() {
            rotors[k] = (r.phi, r.axis, r.mass, r.inertia);
        }
        Some(OneFreeBody {
            x,
            theta: body.angle,
            mass: body.mass,
            com: body.com,
            total_mass: body.mass + model.rotors.iter().map(|r| r.mass).sum::<f64>(),
            total_inertia: body.inertia + model.rotors.iter().map(|r| r.inertia).sum::<f64>(),
            rotors,
        })
    }
}

/// `R(-angle) v`: a world vector in a body's frame.
fn to_body(angle: f64, v: [f64; 2]) -> [f64; 2] {
    unrotate(angle.sin_cos(), v)
}

/// A body of the file as the layout reads it.
struct FileBody<'a> {
    name: &'a str,
    rigid: &'a crate::machine::Platform,
}

/// A joint of the file as the layout reads it: its two bodies by their index in
/// [`file_bodies`] (`None`: the fundament) and its hinge at t = 0, world, m.
type FileJoint = (Option<usize>, Option<usize>, [f64; 2]);

/// The bodies of machine `m`, the platform first, then `[[bodies]]` in file order.
fn file_bodies(m: &Machine) -> Vec<FileBody<'_>> {
    let mut file = vec![FileBody {
        name: PLATFORM,
        rigid: &m.platform,
    }];
    file.extend(m.bodies.iter().map(|b| FileBody {
        name: &b.name,
        rigid: &b.rigid,
    }));
    file
}

/// The layout of the bodies' coordinates (the module doc's): trees in the order
/// of their first body, each from its root, depth first.
struct Layout {
    /// How each body hangs in its tree (`None` until laid out).
    mount: Vec<Option<Mount>>,
    /// Each body's angle coordinate.
    angle: Vec<usize>,
    /// Each body's reference point at t = 0, world, m: its centre of mass for a
    /// free root, its hinge otherwise.
    reference: Vec<[f64; 2]>,
    /// Each body's parent, `None` for a root.
    parent_of: Vec<Option<usize>>,
    /// The bodies in coordinate order (every parent before its children).
    order: Vec<usize>,
    /// The coordinates laid out so far: at the end, the bodies' count of them.
    next: usize,
}

impl Layout {
    /// The layout of the bodies `file` joined by `joints` (trees, every name
    /// known: the machine file's checks).
    fn of(file: &[FileBody<'_>], joints: &[FileJoint]) -> Self {
        let n = file.len();
        let mut layout = Layout {
            mount: vec![None; n],
            angle: vec![0; n],
            reference: vec![[0.0; 2]; n],
            parent_of: vec![None; n],
            order: Vec::with_capacity(n),
            next: 0,
        };
        for first in 0..n {
            if layout.mount[first].is_some() {
                continue;
            }
            let tree = tree_of(first, joints);
            let root = layout.place_root(first, &tree, file, joints);
            layout.place_descendants(root, file, joints);
        }
        layout
    }

    /// Lays out the root of `tree` (whose first body is `first`): the body hinged
    /// to the fundament, on that hinge, with its angle; else `first`, free, with
    /// its centre of mass and angle. Returns the root.
    fn place_root(
        &mut self,
        first: usize,
        tree: &[usize],
        file: &[FileBody<'_>],
        joints: &[FileJoint],
    ) -> usize {
        let pinned = joints.iter().find_map(|&(a, b, p)| match (a, b) {
            (None, Some(x)) | (Some(x), None) if tree.contains(&x) => Some((x, p)),
            _ => None,
        });
        match pinned {
            Some((root, pivot)) => {
                self.mount[root] = Some(Mount::Pinned { pivot });
                self.angle[root] = self.next;
                self.reference[root] = pivot;
                self.next += 1;
                root
            }
            None => {
                self.mount[first] = Some(Mount::Free { x: self.next });
                self.angle[first] = self.next + 2;
                self.reference[first] = file[first].rigid.position;
                self.next += 3;
                first
            }
        }
    }

    /// Lays out the bodies below `root`, depth first: every body's children after
    /// it, each hinged to its parent with its angle.
    fn place_descendants(&mut self, root: usize, file: &[FileBody<'_>], joints: &[FileJoint]) {
        let mut stack = vec![root];
        while let Some(p) = stack.pop() {
            self.order.push(p);
            let mut children = Vec::new();
            for &(a, b, point) in joints {
                for (x, y) in [(a, b), (b, a)] {
                    if let (Some(x), Some(y)) = (x, y) {
                        if x == p && self.mount[y].is_none() {
                            let joint = to_body(file[p].rigid.angle, sub(point, self.reference[p]));
                            self.mount[y] = Some(Mount::Child { parent: p, joint });
                            self.parent_of[y] = Some(p);
                            self.angle[y] = self.next;
                            self.reference[y] = point;
                            self.next += 1;
                            children.push(y);
                        }
                    }
                }
            }
            stack.extend(children.into_iter().rev());
        }
    }

    /// World point `p` (t = 0) in body `b`'s frame, from its reference point.
    fn local(&self, file: &[FileBody<'_>], b: usize, p: [f64; 2]) -> [f64; 2] {
        to_body(file[b].rigid.angle, sub(p, self.reference[b]))
    }

    /// The bodies of `file` as laid out, each with its chain from its tree's
    /// root.
    fn body_models(&self, file: &[FileBody<'_>]) -> Vec<BodyModel> {
        (0..file.len())
            .map(|b| {
                let mut chain = vec![b];
                while let Some(p) = self.parent_of[*chain.last().expect("chain starts at b")] {
                    chain.push(p);
                }
                chain.reverse();
                let r = file[b].rigid;
                BodyModel {
                    name: file[b].name.to_string(),
                    mass: r.mass,
                    inertia: r.inertia,
                    mount: self.mount[b].expect("every body is in a tree"),
                    angle: self.angle[b],
                    com: self.local(file, b, r.position),
                    chain,
                }
            })
            .collect()
    }
}

/// The tree of body `first`: every body joined to it through `joints`, `first`
/// first, then breadth first.
fn tree_of(first: usize, joints: &[FileJoint]) -> Vec<usize> {
    let mut tree = vec![first];
    let mut k = 0;
    while k < tree.len() {
        for &(a, b, _) in joints {
            for (x, y) in [(a, b), (b, a)] {
                if let (Some(x), Some(y)) = (x, y) {
                    if x == tree[k] && !tree.contains(&y) {
                        tree.push(y);
                    }
                }
            }
        }
        k += 1;
    }
    tree
}

/// The index in `file` of the body `name` names (a checked machine names known
/// bodies).
fn body_of(file: &[FileBody<'_>], name: &str) -> usize {
    find_body(file, name).expect("a checked machine names known bodies")
}

/// The index of the body named `name`, `None` for a name that is not a body's
/// (a joint's `fundament`).
fn find_body(file: &[FileBody<'_>], name: &str) -> Option<usize> {
    file.iter().position(|b| b.name == name)
}

/// The rotors of `m`, each in the frame of the body carrying it, their `phi`
/// coordinates after the bodies'.
fn rotor_models(m: &Machine, file: &[FileBody<'_>], layout: &Layout) -> Vec<RotorModel> {
    m.rotors
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let body = body_of(file, &r.body);
            RotorModel {
                body,
                phi: layout.next + k,
                axis: layout.local(file, body, r.axis),
                mass: r.eccentric_mass,
                eccentricity: r.eccentricity,
                inertia: r.inertia,
                sense: r.sense.sign(),
                index_angle: r.index_angle,
                motor: r.motor.clone(),
            }
        })
        .collect()
}

/// The contact points of `m`, each in the frame of its body, against the
/// fundament's line or a face in the frame of the body it strikes.
fn contact_points(m: &Machine, file: &[FileBody<'_>], layout: &Layout) -> Vec<ContactPoint> {
    m.contacts
        .iter()
        .map(|c| {
            let body = body_of(file, &c.ends.body);
            let face = if c.ends.against == FUNDAMENT {
                Face::Fundament
            } else {
                let a = body_of(file, &c.ends.against);
                let normal = c
                    .ends
                    .normal
                    .expect("a checked contact against a body has a normal");
                Face::Body {
                    body: a,
                    point: layout.local(file, a, c.ends.face.unwrap_or(c.point)),
                    normal: to_body(file[a].rigid.angle, normal),
                }
            };
            ContactPoint {
                name: c.name.clone(),
                body,
                point: layout.local(file, body, c.point),
                face,
                law: ContactLaw {
                    restitution: c.restitution,
                    friction: c.friction,
                    weight: c.weight,
                },
            }
        })
        .collect()
}

/// The joints of `m` with a spring or a damper (`joints`: their bodies), relaxed
/// at their `rest_angle`, else at their relative angle at t = 0.
fn springs(m: &Machine, file: &[FileBody<'_>], joints: &[FileJoint]) -> Vec<Spring> {
    m.joints
        .iter()
        .zip(joints)
        .filter(|(j, _)| j.stiffness > 0.0 || j.damping > 0.0)
        .map(|(j, &(a, b, _))| {
            let world = |x: Option<usize>| x.map_or(0.0, |x| file[x].rigid.angle);
            Spring {
                name: j.name.clone(),
                a,
                b,
                stiffness: j.stiffness,
                damping: j.damping,
                rest_angle: j.rest_angle.unwrap_or(world(b) - world(a)),
            }
        })
        .collect()
}

impl PlantModel {
    /// The model of a checked machine file (its bodies in trees, every name known,
    /// no loops: the machine file's checks).
    pub fn new(m: &Machine) -> Self {
        let file = file_bodies(m);
        // The joints as (body A, body B, world point), `None` for the fundament.
        let joints: Vec<FileJoint> = m
            .joints
            .iter()
            .map(|j| {
                (
                    find_body(&file, &j.bodies[0]),
                    find_body(&file, &j.bodies[1]),
                    j.point,
                )
            })
            .collect();
        let layout = Layout::of(&file, &joints);
        let body_dof = layout.next;
        let bodies = layout.body_models(&file);
        let rotors = rotor_models(m, &file, &layout);
        let contacts = contact_points(m, &file, &layout);
        let springs = springs(m, &file, &joints);
        let nrm = m.fundament.normal;
        let mut model = PlantModel {
            bodies,
            order: layout.order,
            free_roots: Vec::new(),
            dof: body_dof + m.rotors.len(),
            body_dof,
            rotors,
            springs,
            contacts,
            ground_point: m.fundament.point,
            normal: nrm,
            tangent: [-nrm[1], nrm[0]],
            gravity: m.fundament.gravity,
            law: m.law,
            supply_voltage: m.drive.supply_voltage,
            bridge: m.drive.bridge,
            closed_forms: true,
        };
        model.free_roots = (0..model.bodies.len())
            .filter_map(|b| match model.bodies[b].mount {
                Mount::Free { x } => Some((x, model.tree_mass(b))),
                _ => None,
            })
            .collect();
        model
    }

    /// The constants of the closed forms where the machine is one free body
    /// carrying its rotors (the reference machine, every single-platform file):
    /// its mass matrix and forces then have closed forms
    /// ([`super::dynamics::Frame::assemble_into`]). Read from the bodies and
    /// rotors as they are now, at every use: a model edited after
    /// [`PlantModel::new`] takes the closed forms of what it became.
    pub fn one_free_body(&self) -> Option<OneFreeBody> {
        if self.closed_forms {
            OneFreeBody::of(self)
        } else {
            None
        }
    }

    /// The model without the closed forms: every evaluation by the generic pass
    /// (to test the closed forms against it).
    #[cfg(test)]
    pub(crate) fn without_closed_forms(mut self) -> Self {
        self.closed_forms = false;
        self
    }

    /// Length of the integrated state: `q`, `q'`, one current per rotor.
    pub fn ny(&self) -> usize {
        2 * self.dof + self.rotors.len()
    }

    /// Index of rotor `k`'s winding current in the state.
    pub fn current(&self, k: usize) -> usize {
        2 * self.dof + k
    }

    /// The coordinates `q` of state `y` (zero past [`PlantModel::dof`]).
    pub fn q(&self, y: &[f64; NY]) -> [f64; MAX_DOF] {
        let mut q = [0.0; MAX_DOF];
        q[..self.dof].copy_from_slice(&y[..self.dof]);
        q
    }

    /// The velocities `q'` of state `y`.
    pub fn v(&self, y: &[f64; NY]) -> [f64; MAX_DOF] {
        let mut v = [0.0; MAX_DOF];
        v[..self.dof].copy_from_slice(&y[self.dof..2 * self.dof]);
        v
    }

    /// The winding currents of state `y`, A (0 for a rotor the machine does not
    /// have).
    pub fn currents(&self, y: &[f64; NY]) -> [f64; MAX_ROTORS] {
        let mut i = [0.0; MAX_ROTORS];
        for (k, c) in i.iter_mut().enumerate().take(self.rotors.len()) {
            *c = y[self.current(k)];
        }
        i
    }

    /// Total mass: the bodies and the eccentric masses, kg.
    pub fn total_mass(&self) -> f64 {
        let bodies = self.bodies.iter().fold(0.0, |s, b| s + b.mass);
        self.rotors.iter().fold(bodies, |s, r| s + r.mass)
    }

    /// The mass of the tree whose root is `root`: its bodies, then the eccentric
    /// masses they carry, kg.
    pub fn tree_mass(&self, root: usize) -> f64 {
        let in_tree = |b: usize| self.bodies[b].chain[0] == root;
        let bodies = (0..self.bodies.len())
            .filter(|b| in_tree(*b))
            .fold(0.0, |s, b| s + self.bodies[b].mass);
        self.rotors
            .iter()
            .filter(|r| in_tree(r.body))
            .fold(bodies, |s, r| s + r.mass)
    }

    /// The state at `t = 0` of machine file `m` (the one this model was made of):
    /// each free root's centre of mass, angle and velocities, every other body's
    /// angle and angular velocity, the eccentric angles in their bodies' frames,
    /// rotors at rest relative to their bodies, no current. Layout:
    /// `(q, q', i)`, `q` as the module doc orders it.
    pub fn initial_state(&self, m: &Machine) -> [f64; NY] {
        let n = self.dof;
        let mut y = [0.0; NY];
        for (b, body) in self.bodies.iter().enumerate() {
            let r = if b == 0 {
                &m.platform
            } else {
                &m.bodies[b - 1].rigid
            };
            if let Mount::Free { x } = body.mount {
                y[x] = r.position[0];
                y[x + 1] = r.position[1];
                y[n + x] = r.velocity[0];
                y[n + x + 1] = r.velocity[1];
            }
            y[body.angle] = r.angle;
            y[n + body.angle] = r.angular_velocity;
        }
        for (rotor, r) in self.rotors.iter().zip(&m.rotors) {
            y[rotor.phi] = r.angle;
        }
        y
    }
}
