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
//! K as the assembler's analytic tangent of the elastic forces (the one Newton uses in
//! statics and dynamics) plus central differences (step 1e-6) of the rest of the residual
//! (inertia, gravity); C and M by central differences (see `Frame::stiffness` for why the
//! elastic part must not be differenced). The steady state comes from Newton on the same residual
//! with that Jacobian, shifted by a multiple of the mass matrix that fades with the
//! residual (pseudo-transient continuation) so that it is the stable one. The quadratic eigenproblem is solved in first-order form after
//! condensing massless coordinates; its eigenvalues are the frequencies in the rotating
//! frame (for an articulated blade the rigid flap mode sits at exactly Ω).

use crate::assembly::{Assembler, Coeffs, DenseSink};
use crate::joint::{self, State};
use crate::linalg::{dense_solve, general_eig_balancing, DenseLu, LinalgError};
use crate::math::*;
use crate::model::{ChainLink, DofMode, Model, NodeKin};

/// Iteration limit of the steady-state solve.
const STEADY_MAX_ITER: usize = 50;
/// What a steady start stopped by its run's signal returns (see [`steady_start`]).
pub const STEADY_INTERRUPTED: &str = "the steady start was interrupted";

/// Why a steady state may not exist, said wherever one was not found.
const DIVERGENCE_HINT: &str = "the speed may be past a divergence of the structure (an \
                               axial bar diverges at Ω·L·sqrt(ρA/EA) = π/2)";

/// A constant-speed rotation found in the model.
#[derive(Clone, Copy, Debug)]
pub struct SteadySpin {
    /// angular velocity vector (global)
    pub omega: Vec3,
    /// a point on the axis
    pub center: Vec3,
    /// the driven dof
    pub dof: usize,
}

/// The first body rotation dof driven at constant rate (zero acceleration over the run),
/// if any; a zero rate counts as no spin.
pub fn find_spin(model: &Model) -> Option<SteadySpin> {
    constant_rate_hub(model).filter(|s| s.omega != [0.0; 3])
}

/// The first body rotation dof driven at constant rate over the run, at rest included
/// (`omega` zero).
pub fn constant_rate_hub(model: &Model) -> Option<SteadySpin> {
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
                    if steady {
                        return Some(SteadySpin {
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
    /// the model without gravity: its static residual (`Coeffs::statics(1.0)`) is the
    /// elastic part of the rotating-frame residual (element forces, hinge springs, the
    /// nodal loads at full value), whose tangent the assembler gives analytically
    elastic: Model,
    asm: Assembler,
    spin: SteadySpin,
    roles: Vec<Role>,
    /// base state (reference or current steady estimate)
    base: State,
    gen: Vec<f64>,
    r: Vec<f64>,
    /// a run's stop flag (a signal): the steady start's dense Newton checks it between
    /// columns of its matrices and between iterations
    stop: Option<&'a std::sync::atomic::AtomicBool>,
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

    /// Whether the run this frame serves was told to stop (the matrices built since are
    /// incomplete; the caller checks before using them).
    fn stopped(&self) -> bool {
        self.stop
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst))
    }

    fn residual(&mut self, xi: &[f64], xid: &[f64], xidd: &[f64]) -> Vec<f64> {
        let s = self.state(xi, xid, xidd);
        let c = Coeffs::dynamic(0.0, 0.0, 0.0);
        self.asm.evaluate(self.model, &s, c, &mut self.gen, None);
        crate::assembly::gather(self.model, &s, &self.gen, &mut self.r);
        self.r.clone()
    }

    /// The residual less its elastic part ([`Frame::elastic`]'s static residual at the
    /// same state): inertia in the rotating frame, gravity, and the nodal loads' time
    /// factor at t = 0 minus 1. Smooth on the scale of the geometry, not of EA/h.
    fn inertial_residual(&mut self, xi: &[f64]) -> Vec<f64> {
        let z = vec![0.0; xi.len()];
        let s = self.state(xi, &z, &z);
        let c = Coeffs::dynamic(0.0, 0.0, 0.0);
        self.asm.evaluate(self.model, &s, c, &mut self.gen, None);
        let mut r = vec![0.0; xi.len()];
        crate::assembly::gather(self.model, &s, &self.gen, &mut r);
        self.asm
            .evaluate(&self.elastic, &s, Coeffs::statics(1.0), &mut self.gen, None);
        crate::assembly::gather(&self.elastic, &s, &self.gen, &mut self.r);
        for (a, b) in r.iter_mut().zip(&self.r) {
            *a -= *b;
        }
        r
    }

    /// Dense ∂r/∂ξ, row-major n×n: the elastic part from the assembler's analytic tangent
    /// (the one Newton uses in statics and dynamics), the rest by central differences of
    /// [`Frame::inertial_residual`].
    ///
    /// Why not central differences of the whole residual: a step h across an element of
    /// length ℓ stretches it by O(h²/ℓ), so the difference quotient of the elastic forces
    /// carries a truncation error ~EA·h²/ℓ³ in the transverse stiffness, against a
    /// centrifugal (geometric) stiffness ~T/ℓ that sets the low rotating-frame modes:
    /// a relative error ~EA·h²/(T·ℓ²), i.e. growing as EA·n². Measured on a hinged blade
    /// (EA = 1e10, 32 elements, Ω̄ = 1; rigid flap exactly Ω): the flap frequency's ω²
    /// was off by 7.1, 7.4e-2, 7.3e-4 and ~3e-6 at h = 1e-5, 1e-6, 1e-7, 1e-8 — h², a
    /// truncation, not round-off. The remainder differenced here is smooth on the scale
    /// of the geometry, and its round-off (the elastic forces cancelling) is ~ε·EA/ℓ per
    /// entry, independent of h.
    fn stiffness(&mut self) -> Vec<f64> {
        let n = self.model.n_eq;
        let z = vec![0.0; n];
        let mut mat = vec![0.0; n * n];
        let s = self.state(&z, &z, &z);
        self.asm.evaluate(
            &self.elastic,
            &s,
            Coeffs::statics(1.0),
            &mut self.gen,
            Some(&mut DenseSink { n, a: &mut mat }),
        );
        let h = 1e-6;
        for j in 0..n {
            if self.stopped() {
                break;
            }
            let mut p = z.clone();
            p[j] = h;
            let rp = self.inertial_residual(&p);
            p[j] = -h;
            let rm = self.inertial_residual(&p);
            for i in 0..n {
                mat[i * n + j] += (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        mat
    }

    /// Dense ∂r/∂ξ̇ or ∂r/∂ξ̈ by central differences (exact up to round-off: the residual
    /// is quadratic in ξ̇ and linear in ξ̈), row-major n×n. ∂r/∂ξ: [`Frame::stiffness`].
    fn jacobian(&mut self, wrt: Rate) -> Vec<f64> {
        let n = self.model.n_eq;
        let z = vec![0.0; n];
        let mut mat = vec![0.0; n * n];
        let h = 1e-4;
        for j in 0..n {
            if self.stopped() {
                break;
            }
            let mut p = z.clone();
            p[j] = h;
            let mut mneg = z.clone();
            mneg[j] = -h;
            let (rp, rm) = match wrt {
                Rate::Velocity => (self.residual(&z, &p, &z), self.residual(&z, &mneg, &z)),
                Rate::Acceleration => (self.residual(&z, &z, &p), self.residual(&z, &z, &mneg)),
            };
            for i in 0..n {
                mat[i * n + j] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        mat
    }
}

/// Which rate of the rotating-frame perturbation a Jacobian is taken with respect to.
#[derive(Clone, Copy, Debug)]
enum Rate {
    Velocity,
    Acceleration,
}

/// Result of a rotating-frame modal analysis.
#[derive(Clone, Debug)]
pub struct RotatingModes {
    pub omega: f64,
    /// frequencies seen in the rotating frame [Hz], ascending
    pub frequencies_hz: Vec<f64>,
    /// below this [Hz] a frequency is not resolved ([`QuadraticModes::resolution_hz`])
    pub resolution_hz: f64,
    /// modal damping ratios (gyroscopic systems: ~0; negative = unstable)
    pub damping: Vec<f64>,
    /// Newton iterations of the steady-state solve
    pub steady_iterations: usize,
    /// whether the steady state's residual met its tolerance (else the modes are about a
    /// state that is not an equilibrium: the speed may be past a divergence)
    pub steady_converged: bool,
    /// complex mode shapes of the lowest modes (as many as asked for with
    /// [`rotating_modes_with_shapes`]), by equation index; empty otherwise
    pub shapes: Vec<Vec<C64>>,
    /// M·shape for each shape (M = [`Self::mass`]), for the mass-weighted MAC
    pub mass_shapes: Vec<Vec<C64>>,
    /// rotating-frame mass matrix about the steady state (row-major n×n, symmetric):
    /// the MAC of a shape from another step against these shapes must be weighted with
    /// this one matrix, not with that step's own
    pub mass: Vec<f64>,
    /// for each shape: the share of its beam motion that is deformation, see
    /// [`deformation_share`] (0 = every beam moves rigidly, e.g. the rigid flap mode of
    /// an articulated blade; 0.3 or more for bending modes)
    pub deformation: Vec<f64>,
    /// the steady rotating state the modes are about (coordinates in the ground frame at
    /// t = 0), for mapping shapes to sensors
    pub steady: State,
    /// what of gravity and the loads was left out because it crosses the spin axis
    /// (`turning_loads_averaged`), said wherever these modes are reported
    pub turning_loads: Option<String>,
}

/// Modes whose [`RotatingModes::deformation`] is below this move their beams rigidly
/// (hinge, mechanism or hub modes): measured 4e-5 to 1.5e-4 for the rigid flap of the
/// shipped blade (Ω = 1 to 12 rad/s), 0.3 to 0.96 for its elastic flap and lag modes, so
/// any value from 1e-3 to 0.2 separates them; 0.05 leaves margin on both sides.
pub const RIGID_DEFORMATION: f64 = 0.05;

impl RotatingModes {
    /// A warning naming the reported modes (of the lowest `count`) whose frequency is
    /// below the eigen-solver's resolution, or None.
    pub fn resolution_warning(&self, count: usize) -> Option<String> {
        let low: Vec<String> = self
            .frequencies_hz
            .iter()
            .take(count)
            .enumerate()
            .filter(|(_, f)| f.abs() < self.resolution_hz)
            .map(|(k, f)| format!("{} ({f:.3e} Hz)", k + 1))
            .collect();
        (!low.is_empty()).then(|| {
            format!(
                "mode{} {} within the eigen-solver's round-off scale of zero in this model, \
                 about {:.2e} Hz: a motion of zero frequency (a free hinge with nothing to \
                 hold it in the rotating frame) or a near-double root (the ±iΩ pair of a \
                 hinge on a slow hub) is found only to within about that, so the frequency may be off by up \
                 to as much (the shipped blade's rigid flap at Ω = 1e-4 rad/s reads \
                 3.6e-6 Hz for 1.6e-5; at 1e-3 rad/s it is within 3e-5 of Ω/2π)",
                if low.len() > 1 { "s" } else { "" },
                low.join(", "),
                self.resolution_hz
            )
        })
    }

    /// The modes among the first `count` whose motion grows about the steady state: a
    /// divergence (a real root s > 0, reported as −s/2π Hz) or a flutter (a complex pair
    /// whose real part exceeds the eigen-solver's round-off, damping ratio < 0). One
    /// warning naming each with its growth rate, or None. Until session 46 neither was
    /// warned, and a divergence was not even listed.
    pub fn instability_warning(&self, count: usize) -> Option<String> {
        let two_pi = 2.0 * std::f64::consts::PI;
        let tol = two_pi * self.resolution_hz;
        let unstable: Vec<String> = (0..count.min(self.frequencies_hz.len()))
            .filter_map(|k| {
                let (f, z) = (self.frequencies_hz[k], self.damping[k]);
                if f < 0.0 {
                    return Some(format!(
                        "{} (divergence: grows at {:.6} 1/s without oscillating, reported as \
                         {f:.6} Hz)",
                        k + 1,
                        -two_pi * f
                    ));
                }
                let growth = -z * two_pi * f / (1.0 - z * z).max(f64::MIN_POSITIVE).sqrt();
                (z < 0.0 && growth > tol).then(|| {
                    format!(
                        "{} (flutter at {f:.6} Hz: grows at {growth:.6} 1/s, damping ratio \
                         {z:.3e})",
                        k + 1
                    )
                })
            })
            .collect();
        (!unstable.is_empty()).then(|| {
            let (named, more) = crate::solver::modes::first_named(&unstable);
            let more = match more {
                0 => String::new(),
                k => format!(" and {k} more"),
            };
            format!(
                "the steady rotation is unstable in mode{} {named}{more}: a disturbance grows \
                 instead of vibrating about it (a spinning shaft between the critical speeds \
                 of its two bending stiffnesses diverges); `latdyn run` shows the growth",
                if unstable.len() > 1 { "s" } else { "" },
            )
        })
    }

    /// Index (into the ascending frequencies) of the lowest mode that deforms a beam
    /// (deformation share ≥ [`RIGID_DEFORMATION`]) and has a nonzero frequency, among
    /// the modes with shapes. None when no such mode was found.
    pub fn first_elastic(&self) -> Option<usize> {
        (0..self.deformation.len())
            .find(|&k| self.deformation[k] >= RIGID_DEFORMATION && self.frequencies_hz[k] > 0.0)
    }
}

/// Find the steady rotating state and the modes about it.
pub fn rotating_modes(model: &Model, spin: SteadySpin) -> Result<RotatingModes, LinalgError> {
    rotating_modes_with_shapes(model, spin, 0)
}

/// As [`rotating_modes`], with the complex shapes of the lowest `shapes` modes.
pub fn rotating_modes_with_shapes(
    model: &Model,
    spin: SteadySpin,
    shapes: usize,
) -> Result<RotatingModes, LinalgError> {
    // before the dense matrices (`sweep --frequency` comes here without the CLI's check)
    crate::solver::modes::check_dense_size(model.n_eq, true).map_err(LinalgError::Other)?;
    let (turned, turning_loads) = turning_loads_averaged(model, spin);
    let (mut fr, iters, converged) = steady_frame(&turned, spin, None)?;
    let n = model.n_eq;
    let k = fr.stiffness();
    let c = fr.jacobian(Rate::Velocity);
    let m = fr.jacobian(Rate::Acceleration);
    let qm = quadratic_modes(&k, &c, &m, n, shapes)?;
    // the mass matrix is symmetric (kinetic energy); for the MAC's inner product take its
    // symmetric part, free of the differencing round-off, so the Hermitian forms are real
    let m_sym: Vec<f64> = (0..n * n)
        .map(|ij| 0.5 * (m[ij] + m[(ij % n) * n + ij / n]))
        .collect();
    let mass_shapes = qm.shapes.iter().map(|x| mat_vec(&m_sym, x)).collect();
    let deformation = qm
        .shapes
        .iter()
        .map(|x| deformation_share(model, &fr.base, x))
        .collect();
    Ok(RotatingModes {
        omega: norm(spin.omega),
        frequencies_hz: qm.frequencies_hz,
        resolution_hz: qm.resolution_hz,
        damping: qm.damping,
        steady_iterations: iters,
        steady_converged: converged,
        shapes: qm.shapes,
        mass_shapes,
        mass: m_sym,
        deformation,
        steady: fr.base.clone(),
        turning_loads,
    })
}

/// Gravity and nodal loads have no steady rotating state where they cross the spin axis:
/// seen from the rotor, such a load turns once per revolution, and the rotor's motion
/// is periodic, not steady (a Floquet problem). Held fixed in the rotating frame, as the
/// analysis would hold it, it set a deflection and a geometric stiffness that depend on
/// where the load pointed at t = 0: a probe (session 48) read the rotating cantilever's
/// first mode (Ω = 10 rad/s, hub radius 0.5) 7.6 % low with gravity along −x, 7.1 % high
/// along +x, and at g = 100 a divergence that is not there, all without a word. The
/// analysis keeps each one's average over a revolution, its part along the axis, and
/// says what it left out. Returns the model to analyse and that note, if any.
fn turning_loads_averaged(
    model: &Model,
    spin: SteadySpin,
) -> (std::borrow::Cow<'_, Model>, Option<String>) {
    let w = norm(spin.omega);
    let axis = scale(spin.omega, 1.0 / w);
    let across = |v: Vec3| sub(v, scale(axis, dot(v, axis)));
    // a share of the load's own size below which its cross part is round-off of its
    // direction (an axis written as [0, 0, 1] turned by the file's own expressions)
    let crosses = |v: Vec3| norm(across(v)) > 1e-9 * norm(v);
    let g = crosses(model.gravity);
    let loads: Vec<String> = model
        .loads
        .iter()
        .filter(|l| crosses(l.force) || crosses(l.moment))
        .map(|l| {
            format!(
                "`{}`",
                model.node_names.get(l.node).map_or("?", |n| n.as_str())
            )
        })
        .collect();
    if !g && loads.is_empty() {
        return (std::borrow::Cow::Borrowed(model), None);
    }
    let mut m = model.clone();
    m.gravity = sub(m.gravity, across(m.gravity));
    for l in &mut m.loads {
        l.force = sub(l.force, across(l.force));
        l.moment = sub(l.moment, across(l.moment));
    }
    let mut what = Vec::new();
    if g {
        what.push(format!(
            "gravity's {:.6e} m/s² across the spin axis",
            norm(across(model.gravity))
        ));
    }
    if !loads.is_empty() {
        what.push(format!(
            "the parts across the spin axis of the loads at node{} {}",
            if loads.len() == 1 { "" } else { "s" },
            loads.join(", ")
        ));
    }
    let note = format!(
        "{} {} once per revolution as seen from the rotor, so with {} the rotor has no \
         steady state: the steady rotation and these modes keep only the average over a \
         revolution (the part along the spin axis); the periodic response and any \
         parametric effect of what was left out are not analysed (`latdyn run` integrates \
         them)",
        what.join(" and "),
        if what.len() == 1 && loads.is_empty() {
            "turns"
        } else {
            "turn"
        },
        if what.len() == 1 && loads.is_empty() {
            "it"
        } else {
            "them"
        },
    );
    (std::borrow::Cow::Owned(m), Some(note))
}

/// The steady rotating state: Newton on the rotating-frame residual from the unstressed
/// reference (see the comment inside), with the number of iterations taken and whether
/// the residual met its tolerance.
fn steady_frame<'a>(
    model: &'a Model,
    spin: SteadySpin,
    stop: Option<&'a std::sync::atomic::AtomicBool>,
) -> Result<(Frame<'a>, usize, bool), LinalgError> {
    // its Newton works on dense n×n matrices: `run` of the rotating cantilever with
    // 3 000 elements (`[initial] steady = true`) spent 40 minutes in it before the first
    // step, and 100 000 elements would abort on the allocation
    crate::solver::modes::check_dense_size(model.n_eq, false).map_err(LinalgError::Other)?;
    let mut base = State::new(model);
    joint::apply_drivers(model, &mut base, 0.0);
    let n = model.n_eq;
    let mut elastic = model.clone();
    elastic.gravity = [0.0; 3];
    let mut fr = Frame {
        model,
        elastic,
        asm: Assembler::new(model),
        spin,
        roles: roles(model),
        base,
        gen: vec![0.0; model.dofs.len()],
        r: vec![0.0; n],
        stop,
    };
    let z = vec![0.0; n];
    // Steady state: Newton on r(ξ) = 0, regularised by pseudo-transient continuation.
    // Plain Newton from the unstressed reference is attracted to the wrong equilibrium:
    // there the structure carries no centrifugal tension yet, so the tangent lacks the
    // geometric stiffness that holds a hinged blade in the plane of rotation and is
    // indefinite (for a blade tilted by β about a hinge, −Ω² I sin²β along the flap),
    // and the first step flaps the blade *up* towards the unstable relative equilibrium
    // along the axis. Centrifugal softening is bounded by Ω²·M (−½ Σ m |Ω × r|² has
    // Hessian ⪰ −Ω² M), so with μ = Ω² the matrix K + μ M is at least the elastic
    // stiffness at the unstressed start (no negative direction) and the step descends
    // towards the stable steady state (here: −0.158 rad, the tilt being 0.157); μ then
    // shrinks with the residual (switched evolution relaxation), which gives back
    // Newton's quadratic convergence at the end.
    let m_metric = fr.jacobian(Rate::Acceleration);
    let mu0 = dot(spin.omega, spin.omega);
    // The residual's round-off floor: a position rounded to ε·|x| moves the elastic force
    // by up to max|K_ii|·ε·|x| (axial EA/ℓ). On a hub barely turning (Ω = 1e-6) the
    // centrifugal forces, hence 1e-10 of the force scale, are far below it, and Newton
    // chasing the noise along a flap direction stiffened only by Ω²·I swung a hinged
    // blade about (rigid flap 0.12 Hz for 1.6e-7); within this floor the state is an
    // equilibrium as far as f64 can tell.
    let noise = {
        let s = fr.state(&z, &z, &z);
        let mut k = vec![0.0; n * n];
        fr.asm.evaluate(
            &fr.elastic,
            &s,
            Coeffs::statics(1.0),
            &mut fr.gen,
            Some(&mut DenseSink { n, a: &mut k }),
        );
        let kdiag = (0..n).fold(0.0f64, |m, i| m.max(k[i * n + i].abs()));
        let xmax = (0..model.x0.len()).fold(0.0f64, |m, nd| {
            m.max(norm(sub(joint::node_position(model, &s, nd), spin.center)))
        });
        f64::EPSILON * kdiag * xmax
    };
    let mut res0 = None;
    let mut iters = 0;
    let mut converged = false;
    for it in 0..STEADY_MAX_ITER {
        iters = it;
        if fr.stopped() {
            return Err(LinalgError::Other(STEADY_INTERRUPTED.into()));
        }
        let r = fr.residual(&z, &z, &z);
        let scale_f = {
            let s = fr.state(&z, &z, &z);
            let c = Coeffs::dynamic(0.0, 0.0, 0.0);
            fr.asm.evaluate(model, &s, c, &mut fr.gen, None).force_scale
        };
        let res = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if res <= (1e-10 * scale_f).max(noise).max(f64::MIN_POSITIVE) {
            converged = true;
            break;
        }
        let res0 = *res0.get_or_insert(res);
        let mu = mu0 * (res / res0).min(1.0);
        let kt = fr.stiffness();
        if fr.stopped() {
            return Err(LinalgError::Other(STEADY_INTERRUPTED.into()));
        }
        // Solved by an LU that rejects only zero pivots (`DenseLu`): K is graded (axial
        // rows EA/ℓ, a hinge's flap row Ω²·I), and on a hub barely turning the flap pivot
        // is legitimately far below n·ε·max|K|, where `dense_solve` would call it singular.
        // Should the pivot be exactly zero or the step not finite (a motion with neither
        // stiffness nor centrifugal restoring force), μ is raised from a floor at which
        // μ·M clears n·ε·max|K| 1000-fold: a shifted step is still a descent step. (The
        // central differences of the whole residual used to hide such motions behind
        // their truncation error ~EA·h²/ℓ³, see `Frame::stiffness`.)
        let kmax = kt.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let mmax = m_metric.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let floor = if mmax > 0.0 {
            1e3 * n as f64 * f64::EPSILON * kmax / mmax
        } else {
            0.0
        };
        let mut mu_try = mu;
        let mut tries = 0;
        let mut dx = loop {
            let mut k = kt.clone();
            for (kij, mij) in k.iter_mut().zip(&m_metric) {
                *kij += mu_try * mij;
            }
            let mut dx: Vec<f64> = r.iter().map(|x| -x).collect();
            match DenseLu::new(&k, n).and_then(|lu| lu.solve(&mut dx)) {
                Ok(()) => break dx,
                Err(_) if tries < 4 && floor > 0.0 => {
                    tries += 1;
                    mu_try = (100.0 * mu_try).max(floor);
                }
                Err(e) => return Err(e),
            }
        };
        crate::assembly::limit_rotation_step(fr.model, &mut dx, 0.5);
        let mut b = fr.base.clone();
        joint::apply_increment(model, &mut b, &dx);
        joint::update_kinematics(model, &mut b);
        fr.base = b;
    }
    Ok((fr, iters, converged))
}

/// `[initial] steady = true`: the state at t = 0 of the steady rotation of the model's
/// constant-speed hub: positions centrifugally stretched, every point moving with the hub
/// (v = Ω × r, a = Ω × (Ω × r)), hinges at rest relative to their parents. Starting the
/// unstretched reference in rigid rotation instead sets off the undamped axial modes (the
/// centrifugal load applied as a step), whose ringing pumps the flap motion: the rotating
/// cantilever at Ω̄ = 50 grew its tip flap 150× from the pulse's response, and its history
/// then depended on every step's error.
///
/// `stop` (a run's signal flag) ends the search early with [`STEADY_INTERRUPTED`]: its
/// dense Newton on a fine mesh takes tens of seconds (the rotating cantilever on 400
/// elements: a signal at 1.5 s ended the run 31 s later, past Slurm's 30 s grace, a
/// probe in session 48).
pub fn steady_start(
    model: &Model,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<State, String> {
    let spin = constant_rate_hub(model).ok_or_else(|| {
        "a steady start needs a body rotation driven at a constant rate".to_string()
    })?;
    if spin.omega == [0.0; 3] {
        // a hub at rest: the unstressed reference is its steady state
        return Ok(State::new(model));
    }
    let (fr, iters, converged) = steady_frame(model, spin, stop).map_err(|e| match e {
        LinalgError::Other(m) if m == STEADY_INTERRUPTED => m,
        e => format!("steady rotation: {e}"),
    })?;
    if !converged {
        return Err(format!(
            "the steady rotation was not found: Newton did not converge in {} iterations; \
             {DIVERGENCE_HINT}",
            iters + 1
        ));
    }
    let z = vec![0.0; model.n_eq];
    Ok(fr.state(&z, &z, &z))
}

impl RotatingModes {
    /// The warning for modes about a steady state that was not found, if so.
    pub fn steady_warning(&self) -> Option<String> {
        (!self.steady_converged).then(|| {
            format!(
                "the steady rotating state was not found at {:.6} rad/s (Newton on the \
                 rotating-frame residual did not converge in {STEADY_MAX_ITER} iterations): \
                 these modes are about a state that is not an equilibrium; \
                 {DIVERGENCE_HINT}",
                self.omega
            )
        })
    }
}

/// Share of a mode's beam motion that is deformation rather than rigid motion of each
/// beam: the mode's real and imaginary parts are mapped (linearised about `base` by
/// central differences) to every beam node's displacement u_i and rotation θ_i, the
/// best rigid motion of each beam (u = a + φ × x, θ = φ; rotations weighted by the
/// beam's length so both count in metres) is fitted by least squares, and the share is
/// √(Σ residual² / Σ motion²) over all beams. A mode that moves no beam node (a body
/// alone) has share 0. Independent of frequencies and of the hub speed, so it tells a
/// hinge's rigid flap (share ~0 whatever its frequency, spring or hinge offset) from
/// elastic bending (share ~0.3 or more).
pub fn deformation_share(model: &Model, base: &State, shape: &[C64]) -> f64 {
    let (mut res2, mut tot2) = (0.0, 0.0);
    for part in 0..2 {
        let p: Vec<f64> = shape
            .iter()
            .map(|z| if part == 0 { z.re } else { z.im })
            .collect();
        let Some((sp, sm, h)) = joint::poses_about(model, base, &p) else {
            continue;
        };
        for beam in &model.beams {
            let x: Vec<Vec3> = beam
                .nodes
                .iter()
                .map(|&nd| joint::node_position(model, base, nd))
                .collect();
            let nn = x.len().max(1) as f64;
            let c = scale(x.iter().fold([0.0; 3], |a, &b| add(a, b)), 1.0 / nn);
            let len = x
                .iter()
                .fold(0.0f64, |m, &xi| m.max(norm(sub(xi, c))))
                .max(f64::MIN_POSITIVE);
            // rows: u_i ≈ a − skew(x_i − c) φ (3 rows), len·θ_i ≈ len·φ (3 rows)
            let mut g = [0.0; 36];
            let mut r = [0.0; 6];
            let mut rows: Vec<([f64; 6], f64)> = Vec::with_capacity(6 * beam.nodes.len());
            for (i, &nd) in beam.nodes.iter().enumerate() {
                let u = scale(sub(sp.node_u[nd], sm.node_u[nd]), 0.5 / h);
                let dr = mat_mul(&sp.node_r[nd], &transpose(&sm.node_r[nd]));
                let th = scale(rot_log(&dr), 0.5 / h);
                let y = sub(x[i], c);
                let sk = skew(y);
                for k in 0..3 {
                    let mut row = [0.0; 6];
                    row[k] = 1.0;
                    for j in 0..3 {
                        row[3 + j] = -sk[k][j];
                    }
                    rows.push((row, u[k]));
                    let mut row = [0.0; 6];
                    row[3 + k] = len;
                    rows.push((row, len * th[k]));
                }
            }
            for (row, b) in &rows {
                for i in 0..6 {
                    r[i] += row[i] * b;
                    for j in 0..6 {
                        g[i * 6 + j] += row[i] * row[j];
                    }
                }
            }
            let mut coef = r;
            if dense_solve(&g, 6, &mut coef).is_err() {
                continue;
            }
            for (row, b) in &rows {
                let fit: f64 = row.iter().zip(&coef).map(|(a, c)| a * c).sum();
                res2 += (b - fit).powi(2);
                tot2 += b * b;
            }
        }
    }
    if tot2 > 0.0 {
        (res2 / tot2).sqrt()
    } else {
        0.0
    }
}

/// M x for a real row-major n×n M and a complex x of length n.
fn mat_vec(m: &[f64], x: &[C64]) -> Vec<C64> {
    let n = x.len();
    (0..n)
        .map(|i| (0..n).fold(C64::ZERO, |acc, j| acc + x[j].scale(m[i * n + j])))
        .collect()
}

/// A complex number, just what the shape computation and MAC need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct C64 {
    pub re: f64,
    pub im: f64,
}

impl C64 {
    pub const ZERO: C64 = C64 { re: 0.0, im: 0.0 };
    pub fn new(re: f64, im: f64) -> C64 {
        C64 { re, im }
    }
    pub fn scale(self, a: f64) -> C64 {
        C64::new(a * self.re, a * self.im)
    }
    pub fn conj(self) -> C64 {
        C64::new(self.re, -self.im)
    }
    pub fn abs(self) -> f64 {
        self.re.hypot(self.im)
    }
}

impl std::ops::Add for C64 {
    type Output = C64;
    fn add(self, o: C64) -> C64 {
        C64::new(self.re + o.re, self.im + o.im)
    }
}

impl std::ops::Sub for C64 {
    type Output = C64;
    fn sub(self, o: C64) -> C64 {
        C64::new(self.re - o.re, self.im - o.im)
    }
}

impl std::ops::Mul for C64 {
    type Output = C64;
    fn mul(self, o: C64) -> C64 {
        C64::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}

impl std::ops::Div for C64 {
    type Output = C64;
    fn div(self, o: C64) -> C64 {
        let d = o.re * o.re + o.im * o.im;
        C64::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
}

/// Solve the complex dense system A x = b in place (row-major n×n, partial pivoting).
/// An exactly zero pivot is replaced by a tiny one: inverse iteration solves with a
/// nearly singular matrix on purpose, and only the direction of the result matters.
fn complex_solve(a: &mut [C64], n: usize, b: &mut [C64]) {
    let big = a.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    let tiny = 1e-300f64.max(f64::EPSILON * f64::EPSILON * big);
    for col in 0..n {
        let p = (col..n)
            .max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))
            .unwrap_or(col);
        if p != col {
            for j in 0..n {
                a.swap(p * n + j, col * n + j);
            }
            b.swap(p, col);
        }
        if a[col * n + col].abs() < tiny {
            a[col * n + col] = C64::new(tiny, 0.0);
        }
        let piv = a[col * n + col];
        for i in col + 1..n {
            let f = a[i * n + col] / piv;
            if f == C64::ZERO {
                continue;
            }
            for j in col..n {
                let v = a[col * n + j];
                a[i * n + j] = a[i * n + j] - f * v;
            }
            b[i] = b[i] - f * b[col];
        }
    }
    for i in (0..n).rev() {
        let mut acc = b[i];
        for j in i + 1..n {
            acc = acc - a[i * n + j] * b[j];
        }
        b[i] = acc / a[i * n + i];
    }
}

/// Modal assurance criterion of two complex shapes, mass-weighted:
/// |aᴴ M b|² / ((aᴴ M a)(bᴴ M b)), with `ma` = M a and `mb` = M b for one and the same
/// real symmetric positive semi-definite M. 1 = same shape (up to a complex factor),
/// 0 = M-orthogonal; never above 1 (Cauchy–Schwarz in the M inner product), which holds
/// only when both products use the same M: mixing the mass matrices of two operating
/// points is not an inner product and can exceed 1.
pub fn mac(a: &[C64], ma: &[C64], b: &[C64], mb: &[C64]) -> f64 {
    let dot = |x: &[C64], y: &[C64]| {
        x.iter()
            .zip(y)
            .fold(C64::ZERO, |acc, (p, q)| acc + p.conj() * *q)
    };
    let ab = dot(a, mb);
    // Hermitian forms of a symmetric M: real
    let aa = dot(a, ma).re;
    let bb = dot(b, mb).re;
    if aa <= 0.0 || bb <= 0.0 {
        return 0.0;
    }
    (ab.re * ab.re + ab.im * ab.im) / (aa * bb)
}

/// One mode followed across the values of a parameter (rotor speeds).
#[derive(Clone, Debug, Default)]
pub struct Branch {
    /// frequency at each value [Hz]; NaN where no mode could be matched
    pub frequencies_hz: Vec<f64>,
    pub damping: Vec<f64>,
    /// MAC of the match against the branch's shape at the previous value (1 at the first)
    pub mac: Vec<f64>,
}

/// Follow the lowest `count` modes of `steps[0]` across the steps by their shapes (MAC),
/// not by their frequency order, so that two branches whose frequencies cross keep their
/// identity. Each step must hold shapes for at least `count` modes (a few more let a
/// branch find its mode when others move down past it). Matching is greedy on the
/// largest MAC; a branch's reference shape is renewed only by a confident match
/// (MAC ≥ 0.8), so a value landing exactly on a crossing, where the two shapes mix,
/// does not hand the branch over to the other mode.
pub fn track_branches(steps: &[RotatingModes], count: usize) -> Vec<Branch> {
    let Some(first) = steps.first() else {
        return Vec::new();
    };
    let count = count.min(first.shapes.len());
    let mut branches: Vec<Branch> = (0..count)
        .map(|k| Branch {
            frequencies_hz: vec![first.frequencies_hz[k]],
            damping: vec![first.damping[k]],
            mac: vec![1.0],
        })
        .collect();
    let mut refs: Vec<Vec<C64>> = first.shapes[..count].to_vec();
    for st in &steps[1..] {
        let nc = st.shapes.len();
        let mut pairs: Vec<(f64, usize, usize)> = Vec::with_capacity(count * nc);
        for (b, x) in refs.iter().enumerate() {
            if st.mass.len() != x.len() * x.len() {
                continue;
            }
            // the reference shape weighted with this step's mass matrix, like the
            // candidates: one M in all three products of the MAC
            let mx = mat_vec(&st.mass, x);
            for c in 0..nc {
                if x.len() == st.shapes[c].len() {
                    pairs.push((mac(x, &mx, &st.shapes[c], &st.mass_shapes[c]), b, c));
                }
            }
        }
        pairs.sort_by(|p, q| q.0.total_cmp(&p.0));
        let mut got: Vec<Option<(usize, f64)>> = vec![None; count];
        let mut taken = vec![false; nc];
        for (v, b, c) in pairs {
            if got[b].is_none() && !taken[c] {
                got[b] = Some((c, v));
                taken[c] = true;
            }
        }
        for (b, g) in got.iter().enumerate() {
            let br = &mut branches[b];
            match *g {
                Some((c, v)) => {
                    br.frequencies_hz.push(st.frequencies_hz[c]);
                    br.damping.push(st.damping[c]);
                    br.mac.push(v);
                    if v >= 0.8 {
                        refs[b] = st.shapes[c].clone();
                    }
                }
                None => {
                    br.frequencies_hz.push(f64::NAN);
                    br.damping.push(f64::NAN);
                    br.mac.push(0.0);
                }
            }
        }
    }
    branches
}

/// Frequencies [Hz] and damping ratios of M ẍ + C ẋ + K x = 0 (one per conjugate pair),
/// massless coordinates condensed statically first.
pub fn quadratic_eig(
    k: &[f64],
    c: &[f64],
    m: &[f64],
    n: usize,
) -> Result<(Vec<f64>, Vec<f64>), LinalgError> {
    let q = quadratic_modes(k, c, m, n, 0)?;
    Ok((q.frequencies_hz, q.damping))
}

/// Eigen-solution of M ẍ + C ẋ + K x = 0: ascending frequencies, damping ratios and the
/// complex shapes of the lowest `shapes` modes (full length n, massless coordinates
/// recovered from the condensation; largest component scaled to 1).
pub struct QuadraticModes {
    pub frequencies_hz: Vec<f64>,
    /// the eigen-solver's resolution [Hz]: a near-double root (the ±iΩ pair of a hinge
    /// on a slow hub) is found only to within about this, so a lower frequency is not
    /// resolved
    pub resolution_hz: f64,
    pub damping: Vec<f64>,
    pub shapes: Vec<Vec<C64>>,
}

/// Eigenvalues (re, im) and the eigen-solver's resolution near 0 [rad/s].
type Spectrum = (Vec<(f64, f64)>, f64);

/// Eigenvalues of M ẍ + C ẋ + K x = 0 (condensed, nk × nk) with the eigen-solver's
/// resolution near 0 [rad/s]: the first-order form shifted and inverted,
/// B = (A − σI)⁻¹ with A = [0 I; −M⁻¹K −M⁻¹C] and σ = −s real, built from one LU of
/// Q(σ) = σ²M + σC + K. The eigen-solver's error is absolute on the scale of the
/// matrix: on A that scale is the stiffest mode's ω² (axial, 1e14 rad²/s² for a 40-element
/// rotor of EA = 1e10), which swamped the low modes (a cantilever at Ω = 1000 rad/s read
/// 228.6 Hz with a damping ratio of 0.95 for a 563.9 Hz lag mode); on B it is 1/s, the
/// low modes'. s is the lowest √(K_ii/M_ii), a Rayleigh quotient, so at or above the
/// lowest frequency; anything from 1e-6 to 1e8 times that keeps the low modes to
/// round-off. None when Q(σ) cannot be factored at three shifts (σ on a real root).
fn shift_invert_eig(
    kk: &[f64],
    ck: &[f64],
    mk: &[f64],
    nk: usize,
) -> Result<Option<Spectrum>, LinalgError> {
    let s = (0..nk)
        .map(|i| kk[i * nk + i] / mk[i * nk + i])
        .filter(|r| r.is_finite() && *r > 0.0)
        .fold(f64::INFINITY, f64::min)
        .sqrt();
    let s = if s.is_finite() && s > 0.0 { s } else { 1.0 };
    for f in [1.0, 1.37, 0.71] {
        let sigma = -s * f;
        let s = -sigma;
        let q: Vec<f64> = (0..nk * nk)
            .map(|ij| sigma * sigma * mk[ij] + sigma * ck[ij] + kk[ij])
            .collect();
        let Ok(lu) = DenseLu::new(&q, nk) else {
            continue;
        };
        // (A − σI)[u; v] = [a; b] ⇔ u = −Q(σ)⁻¹ (M b + (C + σM) a), v = a + σu
        let n2 = 2 * nk;
        let mut b = vec![0.0; n2 * n2];
        let mut u = vec![0.0; nk];
        for j in 0..n2 {
            for (r, x) in u.iter_mut().enumerate() {
                *x = if j < nk {
                    ck[r * nk + j] + sigma * mk[r * nk + j]
                } else {
                    mk[r * nk + j - nk]
                };
            }
            if lu.solve(&mut u).is_err() {
                return Ok(None);
            }
            // balanced with the state [x; ẋ/|σ|]: x and ẋ of a mode at |λ| ≫ |σ| differ
            // by |λ|, and unbalanced B carried entries ~1 for eigenvalues ≤ 1/|σ|
            let (up, down) = if j < nk { (1.0, 1.0 / s) } else { (s, 1.0) };
            for r in 0..nk {
                b[r * n2 + j] = -u[r] * up;
                b[(nk + r) * n2 + j] = (-sigma * u[r] + if r == j { 1.0 } else { 0.0 }) * down;
            }
        }
        // balanced in place, so the round-off scale below is the balanced matrix's (the
        // one the eigen-solver works on), not that of the coordinates' units
        let theta = general_eig_balancing(&mut b, n2)?;
        let ev: Vec<(f64, f64)> = theta
            .into_iter()
            .filter(|(re, im)| re * re + im * im > 0.0)
            .map(|(re, im)| {
                let d = re * re + im * im;
                (sigma + re / d, -im / d)
            })
            .collect();
        // a double root of B is found within about √ε·max|B|, which near λ = 0
        // (θ = 1/|σ|) is √ε·max|B|·σ² in λ
        let bmax = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        return Ok(Some((
            ev,
            10.0 * f64::EPSILON.sqrt() * bmax * sigma * sigma,
        )));
    }
    Ok(None)
}

/// The eigenvalues of the unshifted first-order form, [`shift_invert_eig`]'s fallback.
fn companion_eig(kk: &[f64], ck: &[f64], mk: &[f64], nk: usize) -> Result<Spectrum, LinalgError> {
    // first-order form [0 I; −M⁻¹K −M⁻¹C]
    let mut minv_k = kk.to_vec();
    let mut minv_c = ck.to_vec();
    for col in 0..nk {
        let mut a: Vec<f64> = (0..nk).map(|r| kk[r * nk + col]).collect();
        dense_solve(mk, nk, &mut a)?;
        let mut b: Vec<f64> = (0..nk).map(|r| ck[r * nk + col]).collect();
        dense_solve(mk, nk, &mut b)?;
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
    let ev = general_eig_balancing(&mut a, n2)?;
    // a double root is found within about √(ε·max|A|)
    let amax = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    Ok((ev, 10.0 * (f64::EPSILON * amax).sqrt()))
}

/// [`quadratic_eig`] plus shapes. The eigenvalues come from the first-order companion
/// matrix; each wanted shape then from two steps of inverse iteration on the quadratic
/// pencil Q(λ) = λ²M + λC + K at that eigenvalue (size of the condensed system, not
/// twice it), which converges in one step because the shift is the eigenvalue itself.
pub fn quadratic_modes(
    k: &[f64],
    c: &[f64],
    m: &[f64],
    n: usize,
    shapes: usize,
) -> Result<QuadraticModes, LinalgError> {
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
    // condensation map x_drop = T x_keep, T = −K_dd⁻¹ K_dk (row-major nd × nk)
    let mut tmap = vec![0.0; nd * nk];
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
            for r in 0..nd {
                tmap[r * nk + col] = rhs[r];
            }
        }
    }
    // A zero-frequency motion (a free hinge on a hub barely turning: λ = ±iΩ, Ω = 1e-6)
    // comes out of the eigen-solver as a pair within its round-off (`tol0`) of 0, as
    // often real as imaginary; a real pair is reported as one 0 Hz mode rather than
    // dropped, so the modes above keep their places in the list.
    let (ev, tol0) = match shift_invert_eig(&kk, &ck, &mk, nk)? {
        Some(found) => found,
        None => companion_eig(&kk, &ck, &mk, nk)?,
    };
    let mut reals: Vec<f64> = ev
        .iter()
        .filter(|(re, im)| *im == 0.0 && re.abs() <= tol0)
        .map(|(re, _)| *re)
        .collect();
    reals.sort_by(|p, q| p.abs().total_cmp(&q.abs()));
    reals.truncate(reals.len().div_ceil(2));
    // A real root beyond the round-off that is positive is a divergence: the motion grows
    // as e^{st} without oscillating (a shaft of unequal bending stiffnesses spinning
    // between its two critical speeds). It is reported as the non-rotating analysis
    // reports a negative stiffness, −s/2π "Hz", with damping ratio −1; until session 46
    // it was left out, and the analysis read as stable. (Its mirror root −s, and the
    // real roots of an overdamped mode, both decaying, are not modes of their own here.)
    let growing: Vec<f64> = ev
        .iter()
        .filter(|(re, im)| *im == 0.0 && *re > tol0)
        .map(|(re, _)| *re)
        .collect();
    let mut modes: Vec<(f64, f64, f64, f64)> = ev
        .into_iter()
        .filter(|(_, im)| *im > 0.0)
        .map(|(re, im)| {
            let wn = (re * re + im * im).sqrt();
            (im / (2.0 * std::f64::consts::PI), -re / wn, re, im)
        })
        .chain(reals.into_iter().map(|re| (0.0, 0.0, re, 0.0)))
        .chain(
            growing
                .into_iter()
                .map(|s| (-s / (2.0 * std::f64::consts::PI), -1.0, s, 0.0)),
        )
        .collect();
    modes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out_shapes = Vec::new();
    for &(_, _, re, im) in modes.iter().take(shapes) {
        let lam = C64::new(re, im);
        // shift a hair off the eigenvalue so the factorisation stays finite
        let h = 1e-10 * lam.abs().max(f64::MIN_POSITIVE);
        let sigma = lam + C64::new(h, h);
        let s2 = sigma * sigma;
        let q: Vec<C64> = (0..nk * nk)
            .map(|ij| s2.scale(mk[ij]) + sigma.scale(ck[ij]) + C64::new(kk[ij], 0.0))
            .collect();
        // deterministic start vector with no special symmetry
        let mut x: Vec<C64> = (0..nk)
            .map(|i| C64::new(1.0 + 0.37 * (i as f64).sin(), 0.21 * (1.3 * i as f64).cos()))
            .collect();
        for _ in 0..2 {
            let mut qq = q.clone();
            complex_solve(&mut qq, nk, &mut x);
            let big = x.iter().fold(0.0f64, |m, z| m.max(z.abs()));
            if !(big.is_finite() && big > 0.0) {
                return Err(LinalgError::NonFinite);
            }
            x.iter_mut().for_each(|z| *z = z.scale(1.0 / big));
        }
        let mut full = vec![C64::ZERO; n];
        for (i, &gi) in keep.iter().enumerate() {
            full[gi] = x[i];
        }
        for (r, &gi) in drop.iter().enumerate() {
            full[gi] = (0..nk).fold(C64::ZERO, |acc, j| acc + x[j].scale(tmap[r * nk + j]));
        }
        // phase and scale: largest component = 1
        let imax = (0..n)
            .max_by(|&i, &j| full[i].abs().total_cmp(&full[j].abs()))
            .unwrap_or(0);
        let p = full[imax];
        if p.abs() > 0.0 {
            full.iter_mut().for_each(|z| *z = *z / p);
        }
        out_shapes.push(full);
    }
    Ok(QuadraticModes {
        frequencies_hz: modes.iter().map(|m| m.0).collect(),
        resolution_hz: tol0 / (2.0 * std::f64::consts::PI),
        damping: modes.iter().map(|m| m.1).collect(),
        shapes: out_shapes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [−1, 1).
    fn noise(k: usize) -> f64 {
        let x = ((k as f64 + 1.0) * 12.9898).sin() * 43_758.545_3;
        2.0 * (x - x.floor()) - 1.0
    }

    /// A symmetric positive definite n×n matrix, A Aᵀ + I, scaled by `s`.
    fn spd(n: usize, seed: usize, s: f64) -> Vec<f64> {
        let a: Vec<f64> = (0..n * n).map(|k| noise(seed + k)).collect();
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                let v: f64 = (0..n).map(|k| a[i * n + k] * a[j * n + k]).sum();
                m[i * n + j] = s * (v + if i == j { 1.0 } else { 0.0 });
            }
        }
        m
    }

    fn shape(n: usize, seed: usize) -> Vec<C64> {
        (0..n)
            .map(|i| C64::new(noise(seed + 2 * i), noise(seed + 2 * i + 1)))
            .collect()
    }

    fn step(m: Vec<f64>, shapes: Vec<Vec<C64>>, f: f64) -> RotatingModes {
        let mass_shapes = shapes.iter().map(|x| mat_vec(&m, x)).collect();
        RotatingModes {
            omega: 1.0,
            frequencies_hz: (0..shapes.len()).map(|k| f * (k + 1) as f64).collect(),
            resolution_hz: 0.0,
            damping: vec![0.0; shapes.len()],
            steady_iterations: 0,
            steady_converged: true,
            shapes,
            mass_shapes,
            mass: m,
            deformation: Vec::new(),
            steady: State {
                t: 0.0,
                q: Vec::new(),
                v: Vec::new(),
                a: Vec::new(),
                spin: Vec::new(),
                locked: Vec::new(),
                body_x: Vec::new(),
                body_r: Vec::new(),
                node_u: Vec::new(),
                node_r: Vec::new(),
            },
            turning_loads: None,
        }
    }

    #[test]
    fn mac_is_between_zero_and_one_and_one_for_a_complex_multiple() {
        let n = 7;
        let m = spd(n, 11, 1.0);
        for t in 0..20 {
            let a = shape(n, 100 * t + 1);
            let b = shape(n, 100 * t + 50);
            let v = mac(&a, &mat_vec(&m, &a), &b, &mat_vec(&m, &b));
            assert!((0.0..=1.0).contains(&v), "MAC {v}");
            // the same shape with another phase and length
            let z = C64::new(noise(t), 1.0 + noise(t + 7));
            let c: Vec<C64> = a.iter().map(|x| *x * z).collect();
            let v = mac(&a, &mat_vec(&m, &a), &c, &mat_vec(&m, &c));
            assert!((v - 1.0).abs() < 1e-13, "MAC {v}");
        }
    }

    #[test]
    fn tracking_weighs_both_shapes_with_one_mass_matrix() {
        // The same two shapes at two speeds whose mass matrices differ (the rotating-frame
        // M depends on the steady state). Weighting the old shape with the old M and the
        // new one with the new M is no inner product: it gave the ratio of the two masses
        // (> 1 here) for identical shapes.
        let n = 6;
        let (a, b) = (shape(n, 3), shape(n, 40));
        let steps = [
            step(spd(n, 5, 1.0), vec![a.clone(), b.clone()], 1.0),
            step(spd(n, 9, 1.7), vec![a.clone(), b.clone()], 1.1),
        ];
        let old = mac(&a, &steps[0].mass_shapes[0], &a, &steps[1].mass_shapes[0]);
        assert!(old > 1.0, "{old}");
        let br = track_branches(&steps, 2);
        for x in &br {
            assert!((x.mac[1] - 1.0).abs() < 1e-13, "{:?}", x.mac);
        }
        assert_eq!(br[0].frequencies_hz, vec![1.0, 1.1]);
        assert_eq!(br[1].frequencies_hz, vec![2.0, 2.2]);
    }
}
