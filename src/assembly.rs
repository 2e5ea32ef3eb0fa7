//! Assembly: element and body contributions, projected through the joint chains onto the
//! generalized coordinates, into a residual vector and a Jacobian.
//!
//! The Jacobian is `ck·K + cc·C + cm·M` with K the tangent stiffness (element tangents,
//! geometric stiffness of the joint maps, hinge springs), C the velocity derivative
//! (gyroscopic terms, hinge dampers, Rayleigh damping) and M the mass. The same call with
//! a [`PatternSink`] discovers the sparsity pattern once: every entry is visited whatever
//! its value, so the pattern never misses an entry a later state needs.
//!
//! Not in the Jacobian (Newton still converges, at a rate set by how small they are):
//! ∂(M(q)·a)/∂q, the configuration dependence of the mass matrix, of order |a|/L relative
//! to the M/(βh²) term; the velocity derivative of the chains' convective accelerations;
//! the load stiffness of distributed gravity on beams.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use crate::element::{self, CpuEval, ElemIn, ElemOut, ElementEval, Mat12, Vec12, NDOF};
use crate::joint::{self, Chain, State};
use crate::math::*;
use crate::model::Model;
use crate::solver::batch::{block_on, Posted, Slot};

/// Per-node gathered data: the node's chain and position (which the scatter needs
/// besides the element outputs) and its velocity and acceleration, formed once per node
/// although two elements meet there.
#[derive(Clone, Copy)]
struct Gathered {
    ch: Chain,
    y: Vec3,
    /// (ẋ, ω) and (ẍ, α) including the convective part; zero outside dynamics
    v6: [f64; 6],
    a6: [f64; 6],
}

/// Scratch of the element stage, sized once per model (the hot path does not allocate).
#[derive(Default)]
struct Scratch {
    /// per node, valid where `seen`
    nodes: Vec<Gathered>,
    seen: Vec<bool>,
    inputs: Vec<ElemIn>,
    out: Vec<ElemOut>,
}

/// Cumulative wall time of the assembly stages [s] (see [`Assembler::stage_times`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct AssemblyTimes {
    /// the element stage (CPU functions or GPU round trip)
    pub element_s: f64,
    /// everything else in `evaluate`: gather, projection through the chains, scatter
    pub assembly_s: f64,
    /// time a batch member spent waiting for its round beyond its own share of the
    /// element stage (the other members' work; zero outside a batch), in neither of the
    /// above
    pub waiting_s: f64,
    pub calls: u64,
}

/// Receives Jacobian entries by equation indices.
pub trait Sink {
    fn add(&mut self, row: usize, col: usize, v: f64);
    /// Whether the sink records where entries are rather than their values (then it
    /// must see every entry, zero or not).
    fn records_pattern(&self) -> bool {
        false
    }
    /// `a[k][l]` at (rows[k], cols[l]) for the present rows and columns, row by row: the
    /// same entries in the same order as that many [`Sink::add`] calls, in one dynamic
    /// call (each sink's copy of this body calls its own `add` statically).
    fn add_block6(
        &mut self,
        rows: &[Option<usize>; 6],
        cols: &[Option<usize>; 6],
        a: &[[f64; 6]; 6],
    ) {
        for (r, ak) in rows.iter().zip(a) {
            let Some(r) = *r else { continue };
            for (c, v) in cols.iter().zip(ak) {
                if let Some(c) = *c {
                    self.add(r, c, *v);
                }
            }
        }
    }
}

/// Dense row-major n×n.
pub struct DenseSink<'a> {
    pub n: usize,
    pub a: &'a mut [f64],
}
impl Sink for DenseSink<'_> {
    #[inline]
    fn add(&mut self, row: usize, col: usize, v: f64) {
        self.a[row * self.n + col] += v;
    }
}

/// Records which entries exist.
#[derive(Default)]
pub struct PatternSink {
    pub entries: Vec<(usize, usize)>,
}
impl Sink for PatternSink {
    fn add(&mut self, row: usize, col: usize, _v: f64) {
        self.entries.push((row, col));
    }
    fn records_pattern(&self) -> bool {
        true
    }
}

/// What to assemble.
#[derive(Clone, Copy, Debug)]
pub struct Coeffs {
    /// scale of the external loads (statics load stepping); 1 in dynamics
    pub load_factor: f64,
    /// include inertia (dynamics) or not (statics)
    pub inertia: bool,
    pub ck: f64,
    pub cc: f64,
    pub cm: f64,
}

impl Coeffs {
    /// Dynamics: full loads and inertia, Jacobian ck·K + cc·C + cm·M.
    pub fn dynamic(ck: f64, cc: f64, cm: f64) -> Coeffs {
        Coeffs {
            load_factor: 1.0,
            inertia: true,
            ck,
            cc,
            cm,
        }
    }
    /// Statics at a load factor: no inertia, Jacobian K.
    pub fn statics(load_factor: f64) -> Coeffs {
        Coeffs {
            load_factor,
            inertia: false,
            ck: 1.0,
            cc: 0.0,
            cm: 0.0,
        }
    }
}

/// The assembly stage's per-run data: the element stage it calls, scratch sized once
/// per model and cumulative timers. The model's constants (element data, equation maps)
/// live in [`Model`]; nothing here outlives the run or is shared between variants.
pub struct Assembler {
    /// the element stage: the CPU functions ([`Assembler::new`]) or another backend
    /// ([`Assembler::with_eval`], e.g. the GPU stage)
    pub eval: Arc<dyn ElementEval>,
    /// uncontended: `evaluate` takes `&self`, and one assembler serves one solver thread
    scratch: Mutex<Scratch>,
    /// a batch member's slot (see [`crate::solver::batch`]): [`Assembler::evaluate_async`]
    /// posts its element stage there instead of calling `eval`
    slot: Option<Arc<Slot>>,
    element_ns: AtomicU64,
    total_ns: AtomicU64,
    wait_ns: AtomicU64,
    calls: AtomicU64,
}

/// Scalars gathered during assembly.
#[derive(Clone, Copy, Debug, Default)]
pub struct AssemblyInfo {
    /// largest magnitude of any single force contribution: the scale for convergence tests
    pub force_scale: f64,
    pub strain_energy: f64,
    pub kinetic_energy: f64,
    /// potential energy of gravity, −Σ m g·x over beams and bodies
    pub gravity_energy: f64,
    /// power of the applied loads at this state, Σ s(t)(F·v + M·ω) over the nodes
    /// (dynamics only: zero when inertia is not assembled)
    pub load_power: f64,
    /// power the dampers take out at this state: Rayleigh damping forces dotted with the
    /// element velocities, plus Σ c θ̇² of the hinge dampers (dynamics only)
    pub damping_power: f64,
}

impl Assembler {
    /// An assembler whose element stage is the CPU functions.
    pub fn new(model: &Model) -> Assembler {
        Assembler::with_eval(model, Arc::new(CpuEval))
    }

    /// An assembler whose element stage is `eval`.
    pub fn with_eval(model: &Model, eval: Arc<dyn ElementEval>) -> Assembler {
        let ne = model.elements.len();
        let nn = model.x0.len();
        let empty = Gathered {
            ch: Chain::empty(),
            y: [0.0; 3],
            v6: [0.0; 6],
            a6: [0.0; 6],
        };
        Assembler {
            eval,
            scratch: Mutex::new(Scratch {
                nodes: vec![empty; nn],
                seen: vec![false; nn],
                inputs: vec![
                    ElemIn {
                        state: element::ElemState {
                            u1: [0.0; 3],
                            r1: I3,
                            u2: [0.0; 3],
                            r2: I3,
                        },
                        v12: [0.0; NDOF],
                        acc: [0.0; NDOF],
                    };
                    ne
                ],
                out: vec![ElemOut::default(); ne],
            }),
            slot: None,
            element_ns: AtomicU64::new(0),
            total_ns: AtomicU64::new(0),
            wait_ns: AtomicU64::new(0),
            calls: AtomicU64::new(0),
        }
    }

    /// An assembler of a batch member: [`Assembler::evaluate_async`] posts the element
    /// stage to `slot`, for the batch driver to evaluate with the other members' (`eval`
    /// is then the driver's stage, asked only for its precision and name).
    pub(crate) fn batched(model: &Model, eval: Arc<dyn ElementEval>, slot: Arc<Slot>) -> Assembler {
        Assembler {
            slot: Some(slot),
            ..Assembler::with_eval(model, eval)
        }
    }

    /// Cumulative time split of all `evaluate` calls so far.
    pub fn stage_times(&self) -> AssemblyTimes {
        let el = self.element_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        let tot = self.total_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        AssemblyTimes {
            element_s: el,
            assembly_s: (tot - el).max(0.0),
            waiting_s: self.wait_ns.load(Ordering::Relaxed) as f64 * 1e-9,
            calls: self.calls.load(Ordering::Relaxed),
        }
    }

    /// Evaluate the residual (generalized forces, by dof, in `gen`: inertia + internal −
    /// external; zero is equilibrium) and optionally the Jacobian into `sink`.
    /// `gen` has one entry per dof; for a driven dof it is the generalized force the
    /// driver must supply to impose its motion.
    ///
    /// A dispatcher over the terms, in a fixed order (the sums are bit-reproducible):
    /// elements, rigid bodies, nodal loads, hinge springs, then identity rows for frozen
    /// dofs.
    ///
    /// The element stage runs on the spot, also for a batch member's assembler (statics,
    /// the pattern discovery).
    pub fn evaluate(
        &self,
        model: &Model,
        s: &State,
        c: Coeffs,
        gen: &mut [f64],
        sink: Option<&mut dyn Sink>,
    ) -> AssemblyInfo {
        block_on(self.evaluate_in(false, model, s, c, gen, sink))
    }

    /// [`Assembler::evaluate`] with the element stage as an await point: a batch member's
    /// assembler posts it to its slot and resumes when the batch driver has evaluated it.
    pub async fn evaluate_async(
        &self,
        model: &Model,
        s: &State,
        c: Coeffs,
        gen: &mut [f64],
        sink: Option<&mut dyn Sink>,
    ) -> AssemblyInfo {
        self.evaluate_in(true, model, s, c, gen, sink).await
    }

    /// [`Assembler::evaluate_async`] when `batched` (a batch member posts its element
    /// stage to its slot), else [`Assembler::evaluate`] (on the spot).
    pub(crate) async fn evaluate_in(
        &self,
        batched: bool,
        model: &Model,
        s: &State,
        c: Coeffs,
        gen: &mut [f64],
        mut sink: Option<&mut dyn Sink>,
    ) -> AssemblyInfo {
        gen.iter_mut().for_each(|x| *x = 0.0);
        let mut info = AssemblyInfo::default();
        let t_start = Instant::now();
        let slot = if batched { self.slot.as_deref() } else { None };
        let waited = self
            .elements(slot, model, s, c, gen, sink.as_deref_mut(), &mut info)
            .await;
        bodies(model, s, c, gen, sink.as_deref_mut(), &mut info);
        loads(model, s, c, gen, sink.as_deref_mut(), &mut info);
        hinges(model, s, c, gen, sink.as_deref_mut(), &mut info);
        if let Some(sk) = sink {
            frozen_rows(model, s, sk);
        }
        let span = t_start.elapsed().as_nanos() as u64;
        self.total_ns
            .fetch_add(span.saturating_sub(waited), Ordering::Relaxed);
        self.calls.fetch_add(1, Ordering::Relaxed);
        info
    }

    /// The Jacobian pattern at `s`: every (row, col) that [`Assembler::evaluate`] with all
    /// coefficients 1 adds to a sink, each once or more, with zero values, without the
    /// element stage. An element's blocks (`scatter_pair`) and geometric stiffness
    /// (`Chain::geometric`) report every pair of their chains' active dofs whatever the
    /// values; bodies, loads, hinges and frozen rows are assembled as in `evaluate`. Not
    /// counted in [`Assembler::stage_times`].
    pub fn pattern(&self, model: &Model, s: &State, sink: &mut dyn Sink) {
        let c = Coeffs::dynamic(1.0, 1.0, 1.0);
        let mut gen = vec![0.0; model.dofs.len()];
        let mut info = AssemblyInfo::default();
        let zero: Mat12 = [[0.0; NDOF]; NDOF];
        for el in &model.elements {
            let (n1, n2) = (el.n1, el.n2);
            let ch = [
                joint::node_chain(model, s, n1),
                joint::node_chain(model, s, n2),
            ];
            let y = [
                joint::node_position(model, s, n1),
                joint::node_position(model, s, n2),
            ];
            scatter_pair(s, model, [&ch[0], &ch[1]], &y, &zero, sink);
            for nd in 0..2 {
                geometric(s, model, &ch[nd], y[nd], [0.0; 3], [0.0; 3], c.ck, sink);
            }
        }
        bodies(model, s, c, &mut gen, Some(&mut *sink), &mut info);
        loads(model, s, c, &mut gen, Some(&mut *sink), &mut info);
        hinges(model, s, c, &mut gen, Some(&mut *sink), &mut info);
        frozen_rows(model, s, sink);
    }

    /// The beam elements: gather each element's state, chains, velocities and
    /// accelerations; run the element stage on all of them at once (on the spot, or posted
    /// to `slot`); scatter forces and matrices through the chains. Returns the time [ns]
    /// spent waiting on the slot beyond this request's share of its round.
    #[allow(clippy::too_many_arguments)]
    async fn elements(
        &self,
        slot: Option<&Slot>,
        model: &Model,
        s: &State,
        c: Coeffs,
        gen: &mut [f64],
        mut sink: Option<&mut (dyn Sink + '_)>,
        info: &mut AssemblyInfo,
    ) -> u64 {
        let g = model.gravity;
        let gfac = if c.inertia { 1.0 } else { c.load_factor };
        let has_gravity = g != [0.0; 3];
        // (a statics Jacobian may carry a pseudo-mass too: `statics::relax`)
        let need_inertia = c.inertia || has_gravity || c.cm != 0.0;
        // taken out for the evaluation (moved, not copied), so no lock is held while a
        // batch member waits for its round
        let mut scratch =
            std::mem::take(&mut *self.scratch.lock().unwrap_or_else(|p| p.into_inner()));
        // (a) gather: element states, the nodes' chains, velocities and accelerations
        scratch.seen.iter_mut().for_each(|x| *x = false);
        for (ie, el) in model.elements.iter().enumerate() {
            for n in [el.n1, el.n2] {
                if scratch.seen[n] {
                    continue;
                }
                scratch.seen[n] = true;
                let ch = joint::node_chain(model, s, n);
                let y = joint::node_position(model, s, n);
                let (mut v6, mut a6) = ([0.0; 6], [0.0; 6]);
                if c.inertia {
                    let (vl, va) = ch.velocity(y, &s.v);
                    let (al, aa) = ch.velocity(y, &s.a);
                    let (cl, ca) = ch.convective_acc(y, &s.v);
                    v6[..3].copy_from_slice(&vl);
                    v6[3..].copy_from_slice(&va);
                    a6[..3].copy_from_slice(&add(al, cl));
                    a6[3..].copy_from_slice(&add(aa, ca));
                }
                scratch.nodes[n] = Gathered { ch, y, v6, a6 };
            }
            let es = joint::elem_state(model, s, ie);
            let (g1, g2) = (&scratch.nodes[el.n1], &scratch.nodes[el.n2]);
            let v12: Vec12 = std::array::from_fn(|j| if j < 6 { g1.v6[j] } else { g2.v6[j - 6] });
            let a12: Vec12 = std::array::from_fn(|j| if j < 6 { g1.a6[j] } else { g2.a6[j - 6] });
            // gravity: the consistent load of a uniform field is M times a rigid
            // translation by g, so it joins the acceleration that multiplies M
            let acc: Vec12 = std::array::from_fn(|j| {
                let gj = if j % 6 < 3 { g[j % 3] } else { 0.0 };
                a12[j] - gfac * gj
            });
            scratch.inputs[ie] = ElemIn {
                state: es,
                v12,
                acc,
            };
        }
        // (b) the element stage
        // without a Jacobian to assemble, K, M and C are not needed (unless stiffness-
        // proportional damping puts K into the residual)
        let tangent = sink.is_some() || model.solver.rayleigh_beta != 0.0;
        let mut waited = 0;
        let t_el = Instant::now();
        let (element_ns, evaluated) = match slot {
            None => {
                let r = if tangent {
                    self.eval.evaluate(
                        &model.elem_data,
                        &scratch.inputs,
                        need_inertia,
                        &mut scratch.out,
                    )
                } else {
                    self.eval.evaluate_residual(
                        &model.elem_data,
                        &scratch.inputs,
                        need_inertia,
                        &mut scratch.out,
                    )
                };
                (t_el.elapsed().as_nanos() as u64, r)
            }
            Some(slot) => {
                // the buffers travel to the driver and back (moved, not copied)
                let req = Posted {
                    inputs: std::mem::take(&mut scratch.inputs),
                    out: std::mem::take(&mut scratch.out),
                    residual: !tangent,
                    inertia: need_inertia,
                };
                let done = slot.evaluate(req).await;
                scratch.inputs = done.inputs;
                scratch.out = done.out;
                let own = (done.secs * 1e9) as u64;
                waited = (t_el.elapsed().as_nanos() as u64).saturating_sub(own);
                (own, done.result)
            }
        };
        if let Err(e) = evaluated {
            // a failed backend poisons the residual: Newton reports no convergence and
            // the variant is marked failed with the time, instead of a panic
            eprintln!("latdyn: {e}");
            for o in scratch.out.iter_mut() {
                o.f = [f64::NAN; NDOF];
            }
        }
        self.element_ns.fetch_add(element_ns, Ordering::Relaxed);
        self.wait_ns.fetch_add(waited, Ordering::Relaxed);
        // (c) scatter
        for (ie, el) in model.elements.iter().enumerate() {
            let ed = &model.elem_data[ie];
            let n1 = el.n1;
            let es = &scratch.inputs[ie].state;
            let (g1, g2) = (&scratch.nodes[el.n1], &scratch.nodes[el.n2]);
            let (ch, y) = ([&g1.ch, &g2.ch], [g1.y, g2.y]);
            let v12 = scratch.inputs[ie].v12;
            let o = &scratch.out[ie];
            let mut f = o.f;
            let k = &o.k;
            track(info, &f);
            info.strain_energy += o.energy;
            if has_gravity {
                info.gravity_energy += element::gravity_energy(ed, es, model.x0[n1], g);
            }
            let m = &o.m;
            if need_inertia {
                track(info, &o.finert);
                for i in 0..NDOF {
                    f[i] += o.finert[i];
                }
                if c.inertia {
                    info.kinetic_energy += 0.5 * (0..NDOF).map(|i| v12[i] * o.mv[i]).sum::<f64>();
                    let (ra, rb) = (model.solver.rayleigh_alpha, model.solver.rayleigh_beta);
                    if ra != 0.0 || rb != 0.0 {
                        // β K acts on the deformation rate only (see `deformation_rate`)
                        let vd = deformation_rate(y[0], y[1], &v12);
                        for i in 0..NDOF {
                            // K is stale in a residual-only evaluation, where β = 0
                            let kv: f64 = if rb != 0.0 {
                                (0..NDOF).map(|j| k[i][j] * vd[j]).sum()
                            } else {
                                0.0
                            };
                            let fd = ra * o.mv[i] + rb * kv;
                            f[i] += fd;
                            info.damping_power += fd * v12[i];
                        }
                    }
                }
            }
            for nd in 0..2 {
                let fl = [f[6 * nd], f[6 * nd + 1], f[6 * nd + 2]];
                let ml = [f[6 * nd + 3], f[6 * nd + 4], f[6 * nd + 5]];
                ch[nd].project(y[nd], fl, ml, gen);
            }
            if let Some(sk) = sink.as_deref_mut() {
                // Rayleigh damping adds α M + β K to the velocity matrix
                let (ra, rb) = (model.solver.rayleigh_alpha, model.solver.rayleigh_beta);
                let rayleigh = need_inertia && c.inertia && (ra != 0.0 || rb != 0.0);
                // the velocity matrix of β K P v, P the projection onto deformation rates
                let kp = if rayleigh && rb != 0.0 {
                    let p: Vec<Vec12> = (0..NDOF)
                        .map(|j| {
                            let unit: Vec12 = std::array::from_fn(|i| f64::from(u8::from(i == j)));
                            deformation_rate(y[0], y[1], &unit)
                        })
                        .collect();
                    let mut kp = [[0.0; NDOF]; NDOF];
                    for (i, row) in kp.iter_mut().enumerate() {
                        for (j, x) in row.iter_mut().enumerate() {
                            *x = (0..NDOF).map(|l| k[i][l] * p[j][l]).sum();
                        }
                    }
                    kp
                } else {
                    [[0.0; NDOF]; NDOF]
                };
                let mut comb = [[0.0; NDOF]; NDOF];
                for i in 0..NDOF {
                    for j in 0..NDOF {
                        let cij = if rayleigh {
                            o.c[i][j] + (ra * m[i][j] + rb * kp[i][j])
                        } else {
                            o.c[i][j]
                        };
                        comb[i][j] = c.ck * k[i][j] + c.cc * cij + c.cm * m[i][j];
                    }
                }
                scatter_pair(s, model, ch, &y, &comb, sk);
                for nd in 0..2 {
                    let fl = [f[6 * nd], f[6 * nd + 1], f[6 * nd + 2]];
                    let ml = [f[6 * nd + 3], f[6 * nd + 4], f[6 * nd + 5]];
                    geometric(s, model, ch[nd], y[nd], fl, ml, c.ck, sk);
                }
            }
        }
        *self.scratch.lock().unwrap_or_else(|p| p.into_inner()) = scratch;
        waited
    }
}

/// An element's nodal velocities [v₁, ω₁, v₂, ω₂] (global) less the rigid-body motion
/// they contain: the rate its deformation changes at, on which stiffness-proportional
/// damping β K acts. The rigid part turns with ω = d × (v₂ − v₁)/|d|² (the chord's
/// turn, d = y₂ − y₁) plus the mean spin about the chord, and moves with the mean
/// velocity at the midpoint; a rigid motion is returned as zero exactly. K itself does
/// not vanish on a rigid motion of a stressed element (it turns the element's forces,
/// K v = ω × f), so β K v damped the rigid spin of a centrifugally stretched rotor: a
/// free beam spinning in its plane at 10 rad/s lost 26 % of its kinetic energy in 2 s
/// at β = 1e-3, and a constant-speed hub needed a steady driving torque (found by a
/// probe in session 46).
fn deformation_rate(y1: Vec3, y2: Vec3, v12: &Vec12) -> Vec12 {
    let part = |k: usize| [v12[k], v12[k + 1], v12[k + 2]];
    let (v1, w1, v2, w2) = (part(0), part(3), part(6), part(9));
    let d = sub(y2, y1);
    let l2 = dot(d, d);
    if l2.is_nan() || l2 <= 0.0 {
        return *v12;
    }
    let turn = scale(cross(d, sub(v2, v1)), 1.0 / l2);
    let spin = scale(d, dot(d, scale(add(w1, w2), 0.5)) / l2);
    let w = add(turn, spin);
    let vm = scale(add(v1, v2), 0.5);
    let xm = scale(add(y1, y2), 0.5);
    let r1 = add(vm, cross(w, sub(y1, xm)));
    let r2 = add(vm, cross(w, sub(y2, xm)));
    let rigid = [r1, w, r2, w];
    std::array::from_fn(|i| v12[i] - rigid[i / 3][i % 3])
}

/// Largest force contribution so far: the scale of the convergence test.
fn track(info: &mut AssemblyInfo, v: &[f64]) {
    for x in v {
        info.force_scale = info.force_scale.max(x.abs());
    }
}

/// Rigid bodies on chains: gravity, d'Alembert force and moment (with the gyroscopic
/// term), their mass and gyroscopic matrices.
fn bodies(
    model: &Model,
    s: &State,
    c: Coeffs,
    gen: &mut [f64],
    mut sink: Option<&mut (dyn Sink + '_)>,
    info: &mut AssemblyInfo,
) {
    let g = model.gravity;
    let gfac = if c.inertia { 1.0 } else { c.load_factor };
    for (ib, body) in model.bodies.iter().enumerate() {
        if body.chain.is_empty() {
            continue;
        }
        let ch = joint::body_chain(model, s, ib);
        let r = s.body_r[ib];
        let y = add(s.body_x[ib], mat_vec(&r, body.com));
        let is = mat_mul(&mat_mul(&r, &body.inertia), &transpose(&r));
        info.gravity_energy -= body.mass * dot(g, y);
        let mut f = scale(g, -gfac * body.mass);
        let mut mom = [0.0; 3];
        let mut gyro = [[0.0; 3]; 3];
        if c.inertia {
            let (vl, w) = ch.velocity(y, &s.v);
            let (al, aa) = ch.velocity(y, &s.a);
            let (cl, ca) = ch.convective_acc(y, &s.v);
            let acc = add(al, cl);
            let alpha = add(aa, ca);
            let iw = mat_vec(&is, w);
            f = add(f, scale(acc, body.mass));
            mom = add(mat_vec(&is, alpha), cross(w, iw));
            info.kinetic_energy += 0.5 * body.mass * dot(vl, vl) + 0.5 * dot(w, iw);
            let sw = skew(w);
            let siw = skew(iw);
            let swi = mat_mul(&sw, &is);
            for i in 0..3 {
                for j in 0..3 {
                    gyro[i][j] = swi[i][j] - siw[i][j];
                }
            }
        }
        track(info, &f);
        track(info, &mom);
        ch.project(y, f, mom, gen);
        if let Some(sk) = sink.as_deref_mut() {
            let mut m6 = [[0.0; 6]; 6];
            for i in 0..3 {
                m6[i][i] = c.cm * body.mass;
                for j in 0..3 {
                    m6[3 + i][3 + j] = c.cm * is[i][j] + c.cc * gyro[i][j];
                }
            }
            scatter_block(s, model, &ch, y, &ch, y, &m6, sk);
            // The chain's turn of the body's weight only. Its inertial force and moment
            // turn with the chain too, and so do the accelerations they come from: on a
            // body turning about a hinge they cancel exactly (I θ̈ holds no θ), and
            // taking the inertial force as a dead load there added m ω² d² of spurious
            // stiffness: the pendulum released near upright took 1.2-1.6 Newton
            // iterations per step instead of 1, and the error transport, which solves with
            // this matrix, read its error 0.56× (dt = 1.25e-3) where the exact
            // linearisation reads 1.00×. In a longer chain what is left of the inertial
            // terms' derivative is the part the elements leave out too (∂(M(q)a)/∂q).
            geometric(
                s,
                model,
                &ch,
                y,
                scale(g, -gfac * body.mass),
                [0.0; 3],
                c.ck,
                sk,
            );
        }
    }
}

/// Nodal forces and moments, scaled by their time functions in dynamics and by the load
/// factor in statics; their load stiffness through the chains.
fn loads(
    model: &Model,
    s: &State,
    c: Coeffs,
    gen: &mut [f64],
    mut sink: Option<&mut (dyn Sink + '_)>,
    info: &mut AssemblyInfo,
) {
    for l in &model.loads {
        let ch = joint::node_chain(model, s, l.node);
        let y = joint::node_position(model, s, l.node);
        // time scales apply in dynamics; statics applies loads at full value
        let lf = if c.inertia {
            c.load_factor * l.scale.as_ref().map(|f| f.eval(s.t)[0]).unwrap_or(1.0)
        } else {
            c.load_factor
        };
        let f = scale(l.force, -lf);
        let m = scale(l.moment, -lf);
        if c.inertia {
            let (vl, w) = ch.velocity(y, &s.v);
            info.load_power -= dot(f, vl) + dot(m, w);
        }
        track(info, &f);
        track(info, &m);
        ch.project(y, f, m, gen);
        if let Some(sk) = sink.as_deref_mut() {
            geometric(s, model, &ch, y, f, m, c.ck, sk);
        }
    }
}

/// Hinge springs and dampers on their angle dofs (a locked hinge's row is frozen).
fn hinges(
    model: &Model,
    s: &State,
    c: Coeffs,
    gen: &mut [f64],
    mut sink: Option<&mut (dyn Sink + '_)>,
    info: &mut AssemblyInfo,
) {
    for (ih, h) in model.hinges.iter().enumerate() {
        let th = s.q[h.dof];
        let fh = h.stiffness * (th - h.angle_ref) + h.damping * s.v[h.dof];
        gen[h.dof] += fh;
        if c.inertia {
            info.damping_power += h.damping * s.v[h.dof] * s.v[h.dof];
        }
        info.strain_energy += 0.5 * h.stiffness * (th - h.angle_ref).powi(2);
        if let (Some(sk), Some(e)) = (sink.as_deref_mut(), model.dof_eq[h.dof]) {
            if !s.locked[ih] {
                sk.add(e, e, c.ck * h.stiffness + c.cc * h.damping);
            }
        }
    }
}

/// Frozen (locked) dofs: identity rows keep the matrix regular; their residual is zeroed
/// by [`gather`].
fn frozen_rows(model: &Model, s: &State, sk: &mut dyn Sink) {
    for (d, e) in model.dof_eq.iter().enumerate() {
        if let Some(e) = e {
            if !s.is_active(model, d) {
                sk.add(*e, *e, 1.0);
            }
        }
    }
}

/// Every element within its small-deformation range (see
/// [`element::deformation_in_range`]).
pub fn deformation_in_range(model: &Model, s: &State) -> bool {
    model
        .elem_data
        .iter()
        .enumerate()
        .all(|(ie, ed)| element::deformation_in_range(ed, &joint::elem_state(model, s, ie)))
}

/// The largest deformation angle of a state (see [`largest_deformation_angle`]).
#[derive(Clone, Debug, PartialEq)]
pub struct DeformationAngle {
    /// element index in the model
    pub element: usize,
    /// the beam the element belongs to, and its index there (from 0 at the `from` end)
    pub beam: String,
    pub index_in_beam: usize,
    /// elements in that beam
    pub beam_elements: usize,
    /// rotation of a node frame from the element's convected frame [rad]
    pub angle: f64,
}

/// Deformation angle above which [`deformation_angle_warning`] warns [rad]: where the
/// element's forces err by 1 %. The element measures each node's rotation θ from its
/// convected (chord) frame by its sine (the skew part of D = T_Cᵀ T_i, see
/// [`element::kinematics`]), and its strain energy is quadratic in the sines, so an end
/// force is k sin θ · d(sin θ)/dθ = k sin(2θ)/2 where the small-deformation theory has
/// k θ: relative error 1 − sin(2θ)/(2θ) = (2θ)²/6 − … ≈ 2θ²/3 (a twist θ_e per element
/// carries T = GJ/(2ℓ) sin 2θ_e). 2θ²/3 = 1 % gives θ = √0.015 = 0.1225 rad (7.0°); the
/// exact expression is 0.997 % there. (The sine alone, sin θ/θ ≈ 1 − θ²/6, errs by a
/// quarter of that: 1 % at 0.245 rad, where the forces are already 4 % off.) Checked on
/// the probes: a cantilever bent by a pure moment to 90° with 4 and 8 elements (end
/// angles 0.196 and 0.098 rad: 2θ²/3 = 2.6 % and 0.64 %) was 2.8 % and 0.65 % off at the
/// tip; one twisted by 1.25 rad with 4 and 16 elements (θ = 0.338, 0.078: 7.6 %, 0.41 %)
/// 8 % and 0.41 %.
pub const DEFORMATION_ANGLE_WARN: f64 = 0.1225;

/// The element whose node frame is rotated furthest from its convected frame at `s`, and
/// that angle (the deformation angle φ = sin θ as an angle, [`element::deformation_rotation_angles`]);
/// `None` for a model without elements.
pub fn largest_deformation_angle(model: &Model, s: &State) -> Option<DeformationAngle> {
    let (element, angle) = model
        .elem_data
        .iter()
        .enumerate()
        .map(|(ie, ed)| {
            let [a, b] = element::deformation_rotation_angles(ed, &joint::elem_state(model, s, ie));
            // NaN (a state that blew up) stays NaN (`f64::max` would drop it) and, made
            // positive, orders above every angle: it is no small deformation
            (
                ie,
                if a.is_nan() || b.is_nan() {
                    f64::NAN.abs()
                } else {
                    a.max(b)
                },
            )
        })
        .max_by(|x, y| x.1.total_cmp(&y.1))?;
    let b = &model.beams[model.elements[element].beam];
    Some(DeformationAngle {
        element,
        beam: b.name.clone(),
        index_in_beam: b.elements.iter().position(|&e| e == element).unwrap_or(0),
        beam_elements: b.elements.len(),
        angle,
    })
}

/// A warning when an element of state `s` deforms beyond [`DEFORMATION_ANGLE_WARN`]
/// (its forces more than 1 % off, the small-deformation-per-element assumption broken),
/// naming the element, the angle, the estimated error and the fix; `None` otherwise.
/// Statics adds it to its report; the dynamics may call it at output samples.
pub fn deformation_angle_warning(model: &Model, s: &State) -> Option<String> {
    largest_deformation_angle(model, s)?.warning(None)
}

impl DeformationAngle {
    /// Leading-order relative error of the element's forces at this angle, 2θ²/3 (see
    /// [`DEFORMATION_ANGLE_WARN`]).
    pub fn force_error(&self) -> f64 {
        2.0 * self.angle * self.angle / 3.0
    }

    /// Whether this angle replaces `worst` as the largest seen over several states (the
    /// samples of a run, the points of a path): a NaN angle never does, so a state that
    /// blew up, reported by its caller's own check, cannot hide a real one seen before.
    pub fn exceeds(&self, worst: Option<&DeformationAngle>) -> bool {
        !self.angle.is_nan() && worst.is_none_or(|w| self.angle > w.angle)
    }

    /// The warning for this angle when it exceeds [`DEFORMATION_ANGLE_WARN`] (`at`: the
    /// time of the run's sample it was seen at). A NaN angle is not warned here: the
    /// caller's own check reports a state that blew up.
    pub fn warning(&self, at: Option<f64>) -> Option<String> {
        if self.angle.is_nan() || self.angle <= DEFORMATION_ANGLE_WARN {
            return None;
        }
        Some(format!(
            "large deformation per element: {}element {} of beam `{}` ({} elements) has a \
             node frame turned {:.3} rad ({:.1}°) from its chord frame; the element measures \
             such angles by their sines, so its forces are off by about {:.1} % (2θ²/3; 1 % \
             at {DEFORMATION_ANGLE_WARN} rad). Use more elements on this beam (halving the \
             element length quarters the error)",
            at.map_or(String::new(), |t| format!("at t = {t:.4} s ")),
            self.index_in_beam,
            self.beam,
            self.beam_elements,
            self.angle,
            self.angle.to_degrees(),
            100.0 * self.force_error(),
        ))
    }
}

/// Scale a Newton increment so no angle changes by more than `max_angle` radians: full
/// steps across large rotations land on spurious equilibria.
pub fn limit_rotation_step(model: &Model, dx: &mut [f64], max_angle: f64) {
    let big = largest_step(model, dx, true);
    if big > max_angle {
        let f = max_angle / big;
        dx.iter_mut().for_each(|x| *x *= f);
    }
}

/// Largest magnitude of an increment's angle components (`angles`) or of its others.
pub fn largest_step(model: &Model, dx: &[f64], angles: bool) -> f64 {
    dx.iter()
        .zip(&model.rot_eq)
        .filter(|(_, r)| **r == angles)
        .fold(0.0f64, |m, (x, _)| m.max(x.abs()))
}

/// Residual by equation from the by-dof generalized forces (frozen dofs give 0).
pub fn gather(model: &Model, s: &State, gen: &[f64], r: &mut [f64]) {
    r.iter_mut().for_each(|x| *x = 0.0);
    for (d, e) in model.dof_eq.iter().enumerate() {
        if let Some(e) = e {
            if s.is_active(model, d) {
                r[*e] = gen[d];
            }
        }
    }
}

fn active_eq(s: &State, model: &Model, dof: usize) -> Option<usize> {
    if s.is_active(model, dof) {
        model.dof_eq[dof]
    } else {
        None
    }
}

/// Bᵀ A B for the two nodes of an element (A is 12×12 over both nodes).
fn scatter_pair(
    s: &State,
    model: &Model,
    ch: [&Chain; 2],
    y: &[Vec3; 2],
    a: &Mat12,
    sk: &mut dyn Sink,
) {
    for na in 0..2 {
        for nb in 0..2 {
            let mut blk = [[0.0; 6]; 6];
            for i in 0..6 {
                for j in 0..6 {
                    blk[i][j] = a[6 * na + i][6 * nb + j];
                }
            }
            scatter_block(s, model, ch[na], y[na], ch[nb], y[nb], &blk, sk);
        }
    }
}

/// B_aᵀ A B_b for a 6×6 block between points ya (chain a) and yb (chain b).
#[allow(clippy::too_many_arguments)]
fn scatter_block(
    s: &State,
    model: &Model,
    cha: &Chain,
    ya: Vec3,
    chb: &Chain,
    yb: Vec3,
    a: &[[f64; 6]; 6],
    sk: &mut dyn Sink,
) {
    if cha.is_unit_at(ya) && chb.is_unit_at(yb) {
        // B_a = B_b = I: the same entries in the same order as below, without the products
        let rows = std::array::from_fn(|k| active_eq(s, model, cha.cols[k].dof));
        let cols = std::array::from_fn(|l| active_eq(s, model, chb.cols[l].dof));
        sk.add_block6(&rows, &cols, a);
        return;
    }
    // A·B_b columns first, then B_aᵀ rows
    let mut ab = [[0.0; 6]; joint::MAXCHAIN];
    for l in 0..chb.n {
        let (tl, ta) = chb.twist(l, yb);
        let col6 = [tl[0], tl[1], tl[2], ta[0], ta[1], ta[2]];
        for i in 0..6 {
            ab[l][i] = (0..6).map(|j| a[i][j] * col6[j]).sum();
        }
    }
    for k in 0..cha.n {
        let Some(ek) = active_eq(s, model, cha.cols[k].dof) else {
            continue;
        };
        let (tl, ta) = cha.twist(k, ya);
        let row6 = [tl[0], tl[1], tl[2], ta[0], ta[1], ta[2]];
        for l in 0..chb.n {
            let Some(el) = active_eq(s, model, chb.cols[l].dof) else {
                continue;
            };
            let v: f64 = (0..6).map(|i| row6[i] * ab[l][i]).sum();
            sk.add(ek, el, v);
        }
    }
}

/// The geometric stiffness of a force and moment carried through a chain, times `ck`.
#[allow(clippy::too_many_arguments)]
fn geometric(
    s: &State,
    model: &Model,
    ch: &Chain,
    y: Vec3,
    f: Vec3,
    m: Vec3,
    ck: f64,
    sk: &mut dyn Sink,
) {
    if ch.is_unit_at(y) && !sk.records_pattern() {
        // every rotation axis passes through y and none turns: all its entries are zero
        return;
    }
    ch.geometric(y, f, m, |dk, dl, v| {
        if let (Some(ek), Some(el)) = (active_eq(s, model, dk), active_eq(s, model, dl)) {
            sk.add(ek, el, ck * v);
        }
    });
}
