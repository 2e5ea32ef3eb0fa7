//! Joint bodies, hinges and drivers: the map from the generalized coordinates (body
//! translations and rotations, node translations and spins, hinge angles) to the
//! position and orientation of every beam node (paper eqs. 13-14).
//!
//! Each node's motion is a chain of links, root to leaf (body translations, body
//! rotation, hinge, master-node hinge, …). A unit rate of link k moves a point y by the
//! twist column (w_k × (y − p_k), w_k) for a rotation about axis w_k through p_k, or
//! (d_k, 0) for a translation. From these columns come, without constraint equations:
//! node velocities, the convective (velocity-squared) accelerations of the chain, the
//! projection of nodal forces on the coordinates (Bᵀf) and the geometric stiffness of that
//! projection (the derivative of B at fixed force), all allocation-free.

use crate::math::*;
use crate::model::{ChainLink, DofMode, Model, NodeKin};

/// Longest kinematic chain a node may have (body translations 3 + rotations 3 + hinges).
pub const MAXCHAIN: usize = 12;

/// Mutable per-run state: coordinates, their rates and accelerations, plus the node and
/// body configurations the kinematics stage derives from them.
#[derive(Debug)]
pub struct State {
    pub t: f64,
    /// scalar coordinate values (spin components: unused, the rotation is in `spin`)
    pub q: Vec<f64>,
    /// rates (spin components: spatial angular velocity)
    pub v: Vec<f64>,
    /// accelerations
    pub a: Vec<f64>,
    pub spin: Vec<Mat3>,
    /// hinges that have locked (their angle is frozen from then on)
    pub locked: Vec<bool>,
    // derived by `update_kinematics`
    pub body_x: Vec<Vec3>,
    pub body_r: Vec<Mat3>,
    /// node displacement from the reference position, and rotation from the reference
    pub node_u: Vec<Vec3>,
    pub node_r: Vec<Mat3>,
}

impl Clone for State {
    fn clone(&self) -> State {
        State {
            t: self.t,
            q: self.q.clone(),
            v: self.v.clone(),
            a: self.a.clone(),
            spin: self.spin.clone(),
            locked: self.locked.clone(),
            body_x: self.body_x.clone(),
            body_r: self.body_r.clone(),
            node_u: self.node_u.clone(),
            node_r: self.node_r.clone(),
        }
    }

    /// Reuses the buffers: the integrator copies states every Newton iteration and must
    /// not allocate there.
    fn clone_from(&mut self, o: &State) {
        self.t = o.t;
        self.q.clone_from(&o.q);
        self.v.clone_from(&o.v);
        self.a.clone_from(&o.a);
        self.spin.clone_from(&o.spin);
        self.locked.clone_from(&o.locked);
        self.body_x.clone_from(&o.body_x);
        self.body_r.clone_from(&o.body_r);
        self.node_u.clone_from(&o.node_u);
        self.node_r.clone_from(&o.node_r);
    }
}

impl State {
    pub fn new(model: &Model) -> State {
        let nd = model.dofs.len();
        let mut s = State {
            t: 0.0,
            q: model.dofs.iter().map(|d| d.q0).collect(),
            v: model.dofs.iter().map(|d| d.v0).collect(),
            a: vec![0.0; nd],
            spin: vec![I3; model.spins.len()],
            locked: vec![false; model.hinges.len()],
            body_x: model.bodies.iter().map(|b| b.x0).collect(),
            body_r: model.bodies.iter().map(|b| b.r0).collect(),
            node_u: vec![[0.0; 3]; model.x0.len()],
            node_r: vec![I3; model.x0.len()],
        };
        for sp in &model.spins {
            for k in 0..3 {
                s.v[sp.dofs[k]] = sp.omega0[k];
            }
        }
        if let Some((omega, c)) = model.initial_rotation {
            initial_rigid_rotation(model, &mut s, omega, c);
        }
        apply_drivers(model, &mut s, 0.0);
        update_kinematics(model, &mut s);
        s
    }

    /// Is dof `d` currently solved for (free and not frozen by a locked hinge)?
    pub fn is_active(&self, model: &Model, d: usize) -> bool {
        model.dofs[d].eq.is_some() && !self.frozen(model, d)
    }

    fn frozen(&self, model: &Model, d: usize) -> bool {
        model.hinge_of_dof[d].is_some_and(|h| self.locked[h])
    }
}

/// Initial rates of the free dofs from the rigid field v(x) = ω × (x − c) (`[initial]`);
/// rates given explicitly in the file and driven dofs keep theirs, hinges start at 0.
fn initial_rigid_rotation(model: &Model, s: &mut State, omega: Vec3, c: Vec3) {
    let set = |s: &mut State, d: usize, v: f64| {
        let dof = &model.dofs[d];
        if matches!(dof.mode, DofMode::Free) && !dof.v0_explicit {
            s.v[d] = v;
        }
    };
    for (n, kin) in model.node_kin.iter().enumerate() {
        if let NodeKin::Free { trans, spin } = kin {
            let vel = cross(omega, sub(model.x0[n], c));
            for k in 0..3 {
                if let Some(d) = trans[k] {
                    set(s, d, vel[k]);
                }
            }
            if let Some(sp) = spin {
                for (&d, &w) in model.spins[*sp].dofs.iter().zip(&omega) {
                    set(s, d, w);
                }
            }
        }
    }
    for b in 0..model.bodies.len() {
        // the initial reference point, including initial translations
        let vel = cross(omega, sub(body_pose(model, s, b).0, c));
        for link in &model.bodies[b].chain {
            match *link {
                ChainLink::Translate { dof, dir } => set(s, dof, dot(dir, vel)),
                ChainLink::RotateFixedAxis { dof, axis } => set(s, dof, dot(axis, omega)),
                ChainLink::SpinComponent { dof, k, .. } => set(s, dof, omega[k]),
                ChainLink::Hinge { dof, .. } => set(s, dof, 0.0),
            }
        }
    }
    for h in &model.hinges {
        set(s, h.dof, 0.0);
    }
}

/// Set driven coordinates (value, rate, acceleration) at time `t`.
pub fn apply_drivers(model: &Model, s: &mut State, t: f64) {
    s.t = t;
    for (i, d) in model.dofs.iter().enumerate() {
        if let DofMode::Driven(f) = &d.mode {
            let [q, v, a] = f.eval(t);
            s.q[i] = q;
            s.v[i] = v;
            s.a[i] = a;
        }
    }
}

/// The first drive or load time factor that is not finite at time `t` (value, rate or
/// acceleration of a drive; value of a load's factor), described by its field and text.
/// A NaN or infinity there is the model's input, not a solver failure, and must be named
/// as such (it would otherwise show up as Newton failing with the step cut to dt_min).
pub fn non_finite_input(model: &Model, t: f64) -> Option<String> {
    for d in &model.dofs {
        if let DofMode::Driven(f) = &d.mode {
            let v = f.eval(t);
            if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                let what = ["value", "rate (d/dt)", "acceleration (d²/dt²)"][k];
                return Some(format!(
                    "the drive of `{}` = `{}` has a non-finite {what} ({})",
                    d.name, f.source, v[k]
                ));
            }
        }
    }
    for (i, l) in model.loads.iter().enumerate() {
        if let Some(f) = &l.scale {
            let v = f.eval(t)[0];
            if !v.is_finite() {
                let node = model.node_names.get(l.node).map_or("?", |s| s.as_str());
                return Some(format!(
                    "the time factor of load {} (node `{node}`) `scale = {}` is {v}",
                    i + 1,
                    f.source
                ));
            }
        }
    }
    None
}

/// Apply a solver increment `dx` (indexed by equation number) to the coordinates:
/// scalars add, spins update multiplicatively R ← exp(skew(Δ)) R.
pub fn apply_increment(model: &Model, s: &mut State, dx: &[f64]) {
    for (i, d) in model.dofs.iter().enumerate() {
        if let Some(eq) = d.eq {
            if s.is_active(model, i) {
                s.q[i] += dx[eq];
            }
        }
    }
    for (k, sp) in model.spins.iter().enumerate() {
        let mut w = [0.0; 3];
        for c in 0..3 {
            if let Some(eq) = model.dofs[sp.dofs[c]].eq {
                w[c] = dx[eq];
            }
        }
        if w != [0.0; 3] {
            s.spin[k] = orthonormalize(&mat_mul(&rot_exp(w), &s.spin[k]));
        }
    }
}

/// The states `base` ± h·`direction` (by equation index; spins turned through the
/// exponential map), with h = 1e-6 / max|direction|, and h: a mode shape linearised by
/// central differences, (f(s₊) − f(s₋)) / 2h. None for a zero or non-finite direction.
pub fn poses_about(model: &Model, base: &State, direction: &[f64]) -> Option<(State, State, f64)> {
    let big = direction.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if big == 0.0 || !big.is_finite() {
        return None;
    }
    let h = 1e-6 / big;
    let pose = |sgn: f64| {
        let dx: Vec<f64> = direction.iter().map(|x| sgn * h * x).collect();
        let mut s = base.clone();
        apply_increment(model, &mut s, &dx);
        update_kinematics(model, &mut s);
        s
    };
    Some((pose(1.0), pose(-1.0), h))
}

fn body_pose(model: &Model, s: &State, b: usize) -> (Vec3, Mat3) {
    let body = &model.bodies[b];
    let mut x = body.x0;
    let mut r = body.r0;
    for link in &body.chain {
        match *link {
            ChainLink::Translate { dof, dir } => x = add(x, scale(dir, s.q[dof])),
            ChainLink::RotateFixedAxis { dof, axis } => {
                r = mat_mul(&rot_axis(axis, s.q[dof]), &body.r0)
            }
            ChainLink::SpinComponent { spin, k, .. } => {
                if k == 0 {
                    r = mat_mul(&s.spin[spin], &body.r0)
                }
            }
            ChainLink::Hinge { .. } => {}
        }
    }
    (x, r)
}

/// Derive body and node configurations from the coordinates (stage 1 of every step).
pub fn update_kinematics(model: &Model, s: &mut State) {
    for b in 0..model.bodies.len() {
        let (x, r) = body_pose(model, s, b);
        s.body_x[b] = x;
        s.body_r[b] = r;
    }
    // masters come before their slaves in `kin_order`
    for &n in &model.kin_order {
        let (u, r) = match &model.node_kin[n] {
            NodeKin::Free { trans, spin } => {
                let mut u = [0.0; 3];
                for k in 0..3 {
                    if let Some(d) = trans[k] {
                        u[k] = s.q[d];
                    }
                }
                (u, spin.map(|sp| s.spin[sp]).unwrap_or(I3))
            }
            NodeKin::OnBody {
                body,
                s: sb,
                hinge,
                r_rel,
            } => {
                let (xb, rb) = match body {
                    Some(b) => (s.body_x[*b], s.body_r[*b]),
                    None => ([0.0; 3], I3),
                };
                let x = add(xb, mat_vec(&rb, *sb));
                let mut r = rb;
                if let Some(h) = hinge {
                    let hg = &model.hinges[*h];
                    r = mat_mul(&r, &rot_axis(hg.axis_local, s.q[hg.dof]));
                }
                (sub(x, model.x0[n]), mat_mul(&r, r_rel))
            }
            NodeKin::OnNode {
                master,
                hinge,
                r_rel,
            } => {
                let hg = &model.hinges[*hinge];
                let r = mat_mul(&s.node_r[*master], &rot_axis(hg.axis_local, s.q[hg.dof]));
                (s.node_u[*master], mat_mul(&r, r_rel))
            }
        };
        s.node_u[n] = u;
        s.node_r[n] = r;
    }
}

/// One twist column of a chain at the current configuration.
#[derive(Clone, Copy, Debug, Default)]
pub struct Col {
    pub dof: usize,
    pub rot: bool,
    /// rotation axis or translation direction (unit, global)
    pub w: Vec3,
    /// a point on the rotation axis
    pub p: Vec3,
    /// the axis turns with upstream rotations (hinge axes fixed in a moving parent)
    pub moves: bool,
}

/// A node's or body's chain of twist columns, root first.
#[derive(Clone, Copy, Debug)]
pub struct Chain {
    pub n: usize,
    pub cols: [Col; MAXCHAIN],
}

impl Chain {
    pub fn empty() -> Chain {
        Chain {
            n: 0,
            cols: [Col::default(); MAXCHAIN],
        }
    }
    fn push(&mut self, c: Col) {
        assert!(self.n < MAXCHAIN, "kinematic chain longer than {MAXCHAIN}");
        self.cols[self.n] = c;
        self.n += 1;
    }
    pub fn cols(&self) -> &[Col] {
        &self.cols[..self.n]
    }

    /// Whether the columns at point y are the six unit twists of a free node in the order
    /// x, y, z, rx, ry, rz with the rotation axes through y: the chain's projection is
    /// then the identity, and the assembly's products with it reduce to copies (the
    /// general products with exact zeros and ones give the same values).
    #[inline]
    pub fn is_unit_at(&self, y: Vec3) -> bool {
        self.n == 6
            && self.cols[..6].iter().enumerate().all(|(k, c)| {
                let axis = k % 3;
                c.rot == (k >= 3)
                    && !c.moves
                    && (0..3).all(|i| c.w[i] == if i == axis { 1.0 } else { 0.0 })
                    && (!c.rot || c.p == y)
            })
    }

    /// Linear and angular parts of column k at point y.
    #[inline]
    pub fn twist(&self, k: usize, y: Vec3) -> (Vec3, Vec3) {
        let c = &self.cols[k];
        if c.rot {
            (cross(c.w, sub(y, c.p)), c.w)
        } else {
            (c.w, [0.0; 3])
        }
    }

    /// Velocity (linear at y, angular) for coordinate rates `v` (all dofs).
    pub fn velocity(&self, y: Vec3, v: &[f64]) -> (Vec3, Vec3) {
        if self.is_unit_at(y) {
            let d: [usize; 6] = std::array::from_fn(|k| self.cols[k].dof);
            return ([v[d[0]], v[d[1]], v[d[2]]], [v[d[3]], v[d[4]], v[d[5]]]);
        }
        let mut lin = [0.0; 3];
        let mut ang = [0.0; 3];
        for k in 0..self.n {
            let (l, a) = self.twist(k, y);
            let qd = v[self.cols[k].dof];
            lin = add(lin, scale(l, qd));
            ang = add(ang, scale(a, qd));
        }
        (lin, ang)
    }

    /// Σ_k q̇_k d/dt(column_k): the acceleration of y at zero coordinate accelerations.
    pub fn convective_acc(&self, y: Vec3, v: &[f64]) -> (Vec3, Vec3) {
        if self.is_unit_at(y) {
            // fixed directions and axes through y that move with it: no convective part
            return ([0.0; 3], [0.0; 3]);
        }
        let (ydot, _) = self.velocity(y, v);
        let mut lin = [0.0; 3];
        let mut ang = [0.0; 3];
        let mut omega_up = [0.0; 3];
        for k in 0..self.n {
            let c = self.cols[k];
            let qd = v[c.dof];
            if c.rot {
                let wdot = if c.moves {
                    cross(omega_up, c.w)
                } else {
                    [0.0; 3]
                };
                // velocity of the axis point from the upstream links
                let mut pdot = [0.0; 3];
                for l in 0..k {
                    let (tl, _) = self.twist(l, c.p);
                    pdot = add(pdot, scale(tl, v[self.cols[l].dof]));
                }
                let r = sub(y, c.p);
                let dl = add(cross(wdot, r), cross(c.w, sub(ydot, pdot)));
                lin = add(lin, scale(dl, qd));
                ang = add(ang, scale(wdot, qd));
                omega_up = add(omega_up, scale(c.w, qd));
            }
        }
        (lin, ang)
    }

    /// Generalized forces Q_k = column_kᵀ (f at y, m) added into `out` (indexed by dof).
    pub fn project(&self, y: Vec3, f: Vec3, m: Vec3, out: &mut [f64]) {
        for k in 0..self.n {
            let (l, a) = self.twist(k, y);
            out[self.cols[k].dof] += dot(l, f) + dot(a, m);
        }
    }

    /// Geometric stiffness of the projection: G[k][l] = ∂Q_k/∂q_l at fixed spatial (f, m)
    /// applied at the point y that moves with the chain. Calls `sink(dof_k, dof_l, value)`.
    pub fn geometric(&self, y: Vec3, f: Vec3, m: Vec3, mut sink: impl FnMut(usize, usize, f64)) {
        for k in 0..self.n {
            let ck = self.cols[k];
            if !ck.rot {
                continue; // translation directions are fixed in space
            }
            let r = sub(y, ck.p);
            let mom = add(m, cross(r, f));
            for l in 0..self.n {
                let cl = self.cols[l];
                let val = if l < k {
                    if cl.rot {
                        let axis_turn = if ck.moves {
                            dot(cross(cl.w, ck.w), mom)
                        } else {
                            0.0
                        };
                        axis_turn + dot(ck.w, cross(cross(cl.w, r), f))
                    } else {
                        0.0
                    }
                } else if l == k {
                    dot(ck.w, cross(cross(ck.w, r), f))
                } else {
                    let (dy, _) = self.twist(l, y);
                    dot(ck.w, cross(dy, f))
                };
                // every pair is reported, zero or not, so pattern discovery sees it
                sink(ck.dof, cl.dof, val);
            }
        }
    }
}

/// The chain of body `b` (its reference point carries it).
pub fn body_chain(model: &Model, s: &State, b: usize) -> Chain {
    let mut ch = Chain::empty();
    push_body_links(model, s, b, &mut ch);
    ch
}

fn push_body_links(model: &Model, s: &State, b: usize, ch: &mut Chain) {
    let xb = s.body_x[b];
    for link in &model.bodies[b].chain {
        match *link {
            ChainLink::Translate { dof, dir } => ch.push(Col {
                dof,
                rot: false,
                w: dir,
                p: [0.0; 3],
                moves: false,
            }),
            ChainLink::RotateFixedAxis { dof, axis } => ch.push(Col {
                dof,
                rot: true,
                w: axis,
                p: xb,
                moves: false,
            }),
            ChainLink::SpinComponent { dof, k, .. } => {
                let mut w = [0.0; 3];
                w[k] = 1.0;
                ch.push(Col {
                    dof,
                    rot: true,
                    w,
                    p: xb,
                    moves: false,
                })
            }
            ChainLink::Hinge { .. } => {}
        }
    }
}

/// The chain of node `n` at the current configuration.
pub fn node_chain(model: &Model, s: &State, n: usize) -> Chain {
    let mut ch = Chain::empty();
    push_node_links(model, s, n, &mut ch);
    ch
}

fn push_node_links(model: &Model, s: &State, n: usize, ch: &mut Chain) {
    let xn = add(model.x0[n], s.node_u[n]);
    match &model.node_kin[n] {
        NodeKin::Free { trans, spin } => {
            for (k, t) in trans.iter().enumerate() {
                if let Some(dof) = *t {
                    let mut w = [0.0; 3];
                    w[k] = 1.0;
                    ch.push(Col {
                        dof,
                        rot: false,
                        w,
                        p: [0.0; 3],
                        moves: false,
                    });
                }
            }
            if let Some(sp) = spin {
                for k in 0..3 {
                    let mut w = [0.0; 3];
                    w[k] = 1.0;
                    ch.push(Col {
                        dof: model.spins[*sp].dofs[k],
                        rot: true,
                        w,
                        p: xn,
                        moves: false,
                    });
                }
            }
        }
        NodeKin::OnBody { body, hinge, .. } => {
            let rb = match body {
                Some(b) => {
                    push_body_links(model, s, *b, ch);
                    s.body_r[*b]
                }
                None => I3,
            };
            if let Some(h) = hinge {
                let hg = &model.hinges[*h];
                ch.push(Col {
                    dof: hg.dof,
                    rot: true,
                    w: mat_vec(&rb, hg.axis_local),
                    p: xn,
                    moves: true,
                });
            }
        }
        NodeKin::OnNode { master, hinge, .. } => {
            push_node_links(model, s, *master, ch);
            let hg = &model.hinges[*hinge];
            ch.push(Col {
                dof: hg.dof,
                rot: true,
                w: mat_vec(&s.node_r[*master], hg.axis_local),
                p: xn,
                moves: true,
            });
        }
    }
}

/// The nodal state of element `e` (displacements and rotations of its two nodes).
#[inline]
pub fn elem_state(model: &Model, s: &State, e: usize) -> crate::element::ElemState {
    let el = &model.elements[e];
    crate::element::ElemState {
        u1: s.node_u[el.n1],
        r1: s.node_r[el.n1],
        u2: s.node_u[el.n2],
        r2: s.node_r[el.n2],
    }
}

/// Current position of node n.
#[inline]
pub fn node_position(model: &Model, s: &State, n: usize) -> Vec3 {
    add(model.x0[n], s.node_u[n])
}
