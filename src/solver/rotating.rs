//! Steady rotation and modes seen in the rotating frame.
//!
//! A model whose body turns at a constant driven rate Ω about a fixed axis (a rotor hub)
//! has a relative equilibrium: every other coordinate at rest in the frame turning with the
//! hub, the structure centrifugally stretched. Perturbations ξ measured in that frame obey
//! M ξ̈ + C ξ̇ + K ξ = 0 with constant matrices that hold centrifugal stiffening, spin
//! softening (K) and gyroscopic coupling (C). They are obtained here by differentiating
//! the full nonlinear residual along the rotating-frame maps
//!   node translation: v = Ω×(x−c) + ξ̇,  a = Ω×(Ω×(x−c)) + 2Ω×ξ̇ + ξ̈,
//!   node/body spin:   ω = Ω + ξ̇,         α = Ω×ξ̇ + ξ̈,
//!   hinge angles:     v = ξ̇,             a = ξ̈,
//! by central differences of the residual (step 1e-6 relative: truncation ~1e-12, round-off
//! ~1e-10 of the force scale). The steady state comes from Newton on the same residual
//! with that Jacobian. The quadratic eigenproblem is solved in first-order form after
//! condensing massless coordinates; its eigenvalues are the frequencies in the rotating
//! frame (for an articulated blade the rigid flap mode sits at exactly Ω).

use crate::assembly::{Assembler, Coeffs};
use crate::joint::{self, State};
use crate::linalg::{dense_solve, general_eig, LinalgError};
use crate::math::*;
use crate::model::{ChainLink, DofMode, Model, NodeKin};

/// A constant-speed rotation found in the model.
#[derive(Clone, Copy, Debug)]
pub struct Spin {
    /// angular velocity vector (global)
    pub omega: Vec3,
    /// a point on the axis
    pub center: Vec3,
    /// the driven dof
    pub dof: usize,
}

/// The first body rotation dof driven at constant rate (zero acceleration over the run),
/// if any; a zero rate counts as no spin.
pub fn find_spin(model: &Model) -> Option<Spin> {
    for b in &model.bodies {
        for l in &b.chain {
            if let ChainLink::RotateFixedAxis { dof, axis } = *l {
                if let DofMode::Driven(f) = &model.dofs[dof].mode {
                    let t_end = model.solver.t_end;
                    let samples = [0.0, 0.37 * t_end, t_end];
                    let r0 = f.eval(0.0)[1];
                    let steady = samples.iter().all(|&t| {
                        let [_, v, a] = f.eval(t);
                        (v - r0).abs() <= 1e-12 * r0.abs().max(1.0) && a.abs() <= 1e-12
                    });
                    if steady && r0 != 0.0 {
                        return Some(Spin {
                            omega: scale(axis, r0),
                            center: b.x0,
                            dof,
                        });
                    }
                }
            }
        }
    }
    None
}

/// How each free dof moves in the rotating frame.
#[derive(Clone, Copy, Debug)]
enum Role {
    /// component k of the translation of a point whose dof group is `group`
    Trans { dir: Vec3, point: Point },
    /// component k of a spin
    SpinC { k: usize },
    /// an angle relative to its parent: no frame terms
    Relative,
}

#[derive(Clone, Copy, Debug)]
enum Point {
    Node(usize),
    Body(usize),
}

fn roles(model: &Model) -> Vec<Role> {
    let mut r = vec![Role::Relative; model.dofs.len()];
    for (n, nk) in model.node_kin.iter().enumerate() {
        if let NodeKin::Free { trans, spin } = nk {
            for (k, t) in trans.iter().enumerate() {
                if let Some(d) = t {
                    let mut dir = [0.0; 3];
                    dir[k] = 1.0;
                    r[*d] = Role::Trans {
                        dir,
                        point: Point::Node(n),
                    };
                }
            }
            if let Some(sp) = spin {
                for k in 0..3 {
                    r[model.spins[*sp].dofs[k]] = Role::SpinC { k };
                }
            }
        }
    }
    for (b, body) in model.bodies.iter().enumerate() {
        for l in &body.chain {
            match *l {
                ChainLink::Translate { dof, dir } => {
                    r[dof] = Role::Trans {
                        dir,
                        point: Point::Body(b),
                    }
                }
                ChainLink::SpinComponent { dof, k, .. } => r[dof] = Role::SpinC { k },
                _ => {}
            }
        }
    }
    r
}

struct Frame<'a> {
    model: &'a Model,
    asm: Assembler,
    spin: Spin,
    roles: Vec<Role>,
    /// base state (reference or current steady estimate)
    base: State,
    gen: Vec<f64>,
    r: Vec<f64>,
}

impl Frame<'_> {
    /// State for rotating-frame perturbation (ξ, ξ̇, ξ̈) from the base, at t = 0.
    fn state(&self, xi: &[f64], xid: &[f64], xidd: &[f64]) -> State {
        let m = self.model;
        let mut s = self.base.clone();
        joint::apply_increment(m, &mut s, xi);
        joint::update_kinematics(m, &mut s);
        let w = self.spin.omega;
        // group the translation rates of each point to form Ω × ξ̇
        let rate_of = |pt: Point| -> Vec3 {
            let mut acc = [0.0; 3];
            for (d, role) in self.roles.iter().enumerate() {
                if let (Role::Trans { dir, point }, Some(e)) = (role, m.dofs[d].eq) {
                    let same = match (point, pt) {
                        (Point::Node(a), Point::Node(b)) => *a == b,
                        (Point::Body(a), Point::Body(b)) => *a == b,
                        _ => false,
                    };
                    if same {
                        acc = add(acc, scale(*dir, xid[e]));
                    }
                }
            }
            acc
        };
        let mut spin_rate = vec![[0.0; 3]; m.spins.len()];
        for (k, sp) in m.spins.iter().enumerate() {
            for c in 0..3 {
                if let Some(e) = m.dofs[sp.dofs[c]].eq {
                    spin_rate[k][c] = xid[e];
                }
            }
        }
        for (d, role) in self.roles.iter().enumerate() {
            let Some(e) = m.dofs[d].eq else { continue };
            match *role {
                Role::Trans { dir, point } => {
                    let x = match point {
                        Point::Node(n) => joint::node_position(m, &s, n),
                        Point::Body(b) => s.body_x[b],
                    };
                    let r = sub(x, self.spin.center);
                    let xd = rate_of(point);
                    s.v[d] = dot(dir, cross(w, r)) + xid[e];
                    s.a[d] =
                        dot(dir, add(cross(w, cross(w, r)), scale(cross(w, xd), 2.0))) + xidd[e];
                }
                Role::SpinC { k } => {
                    let group = m
                        .spins
                        .iter()
                        .position(|sp| sp.dofs.contains(&d))
                        .unwrap_or(0);
                    s.v[d] = w[k] + xid[e];
                    s.a[d] = cross(w, spin_rate[group])[k] + xidd[e];
                }
                Role::Relative => {
                    s.v[d] = xid[e];
                    s.a[d] = xidd[e];
                }
            }
        }
        s
    }

    fn residual(&mut self, xi: &[f64], xid: &[f64], xidd: &[f64]) -> Vec<f64> {
        let s = self.state(xi, xid, xidd);
        let c = Coeffs::dynamic(0.0, 0.0, 0.0);
        self.asm.evaluate(self.model, &s, c, &mut self.gen, None);
        self.asm.gather(self.model, &s, &self.gen, &mut self.r);
        self.r.clone()
    }

    /// Dense ∂r/∂(ξ, ξ̇, ξ̈) by central differences, row-major n×n each.
    fn jacobians(&mut self, need_c_m: bool) -> [Vec<f64>; 3] {
        let n = self.asm.n_eq;
        let z = vec![0.0; n];
        let mut out = [vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]];
        let kinds = if need_c_m { 3 } else { 1 };
        for (kind, mat) in out.iter_mut().enumerate().take(kinds) {
            for j in 0..n {
                let h = if kind == 0 { 1e-6 } else { 1e-4 };
                let mut p = z.clone();
                p[j] = h;
                let mut mneg = z.clone();
                mneg[j] = -h;
                let (rp, rm) = match kind {
                    0 => (self.residual(&p, &z, &z), self.residual(&mneg, &z, &z)),
                    1 => (self.residual(&z, &p, &z), self.residual(&z, &mneg, &z)),
                    _ => (self.residual(&z, &z, &p), self.residual(&z, &z, &mneg)),
                };
                for i in 0..n {
                    mat[i * n + j] = (rp[i] - rm[i]) / (2.0 * h);
                }
            }
        }
        out
    }
}

/// Result of a rotating-frame modal analysis.
#[derive(Clone, Debug)]
pub struct RotatingModes {
    pub omega: f64,
    /// frequencies seen in the rotating frame [Hz], ascending
    pub frequencies_hz: Vec<f64>,
    /// modal damping ratios (gyroscopic systems: ~0; negative = unstable)
    pub damping: Vec<f64>,
    /// Newton iterations of the steady-state solve
    pub steady_iterations: usize,
}

/// Find the steady rotating state and the modes about it.
pub fn rotating_modes(model: &Model, spin: Spin) -> Result<RotatingModes, LinalgError> {
    let mut base = State::new(model);
    joint::apply_drivers(model, &mut base, 0.0);
    let n = model.n_eq;
    let mut fr = Frame {
        model,
        asm: Assembler::new(model),
        spin,
        roles: roles(model),
        base,
        gen: vec![0.0; model.dofs.len()],
        r: vec![0.0; n],
    };
    let z = vec![0.0; n];
    let mut iters = 0;
    for it in 0..30 {
        iters = it;
        let r = fr.residual(&z, &z, &z);
        let scale_f = {
            let s = fr.state(&z, &z, &z);
            let c = Coeffs::dynamic(0.0, 0.0, 0.0);
            fr.asm.evaluate(model, &s, c, &mut fr.gen, None).force_scale
        };
        let res = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if res <= 1e-10 * scale_f.max(f64::MIN_POSITIVE) {
            break;
        }
        let [k, _, _] = fr.jacobians(false);
        let mut dx: Vec<f64> = r.iter().map(|x| -x).collect();
        dense_solve(&k, n, &mut dx)?;
        fr.asm.limit_rotation_step(&mut dx, 0.5);
        let mut b = fr.base.clone();
        joint::apply_increment(model, &mut b, &dx);
        joint::update_kinematics(model, &mut b);
        fr.base = b;
    }
    let [k, c, m] = fr.jacobians(true);
    let (freqs, damping) = quadratic_eig(&k, &c, &m, n)?;
    Ok(RotatingModes {
        omega: norm(spin.omega),
        frequencies_hz: freqs,
        damping,
        steady_iterations: iters,
    })
}

/// Frequencies [Hz] and damping ratios of M ẍ + C ẋ + K x = 0 (one per conjugate pair),
/// massless coordinates condensed statically first.
pub fn quadratic_eig(
    k: &[f64],
    c: &[f64],
    m: &[f64],
    n: usize,
) -> Result<(Vec<f64>, Vec<f64>), LinalgError> {
    let mmax = (0..n).map(|i| m[i * n + i].abs()).fold(0.0, f64::max);
    let keep: Vec<usize> = (0..n)
        .filter(|&i| m[i * n + i].abs() > 1e-12 * mmax)
        .collect();
    let drop: Vec<usize> = (0..n)
        .filter(|&i| m[i * n + i].abs() <= 1e-12 * mmax)
        .collect();
    let (nk, nd) = (keep.len(), drop.len());
    let sub = |a: &[f64], rows: &[usize], cols: &[usize]| -> Vec<f64> {
        rows.iter()
            .flat_map(|&i| cols.iter().map(move |&j| a[i * n + j]))
            .collect()
    };
    let mut kk = sub(k, &keep, &keep);
    let ck = sub(c, &keep, &keep);
    let mk = sub(m, &keep, &keep);
    if nd > 0 {
        let kdd = sub(k, &drop, &drop);
        let kdk = sub(k, &drop, &keep);
        let kkd = sub(k, &keep, &drop);
        for col in 0..nk {
            let mut rhs: Vec<f64> = (0..nd).map(|r| -kdk[r * nk + col]).collect();
            dense_solve(&kdd, nd, &mut rhs)?;
            for row in 0..nk {
                kk[row * nk + col] += (0..nd).map(|r| kkd[row * nd + r] * rhs[r]).sum::<f64>();
            }
        }
    }
    // first-order form [0 I; −M⁻¹K −M⁻¹C]
    let mut minv_k = kk.clone();
    let mut minv_c = ck.clone();
    for col in 0..nk {
        let mut a: Vec<f64> = (0..nk).map(|r| kk[r * nk + col]).collect();
        dense_solve(&mk, nk, &mut a)?;
        let mut b: Vec<f64> = (0..nk).map(|r| ck[r * nk + col]).collect();
        dense_solve(&mk, nk, &mut b)?;
        for r in 0..nk {
            minv_k[r * nk + col] = a[r];
            minv_c[r * nk + col] = b[r];
        }
    }
    let n2 = 2 * nk;
    let mut a = vec![0.0; n2 * n2];
    for i in 0..nk {
        a[i * n2 + nk + i] = 1.0;
        for j in 0..nk {
            a[(nk + i) * n2 + j] = -minv_k[i * nk + j];
            a[(nk + i) * n2 + nk + j] = -minv_c[i * nk + j];
        }
    }
    let ev = general_eig(&a, n2)?;
    let mut modes: Vec<(f64, f64)> = ev
        .into_iter()
        .filter(|(_, im)| *im > 0.0)
        .map(|(re, im)| {
            let wn = (re * re + im * im).sqrt();
            (im / (2.0 * std::f64::consts::PI), -re / wn)
        })
        .collect();
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(modes.into_iter().unzip())
}
