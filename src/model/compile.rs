//! Compilation of a parsed spec into the immutable [`Model`]: parameters are resolved,
//! beams are meshed, names become indices and every coordinate becomes a [`Dof`].
//!
//! Dof (and equation) order: node dofs in node order (translations x, y, z, then spin
//! x, y, z), then body dofs in file order, then hinge angles in joint order. Nodes are
//! the user's nodes in file order followed by each beam's interior nodes `BEAM:1`, ...

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::path::Path;

use super::error::ModelError;
use super::expr::{self, TimeFunction};
use super::limits::{self, Limits};
use super::spec::{self, *};
use super::types::*;
use crate::math::*;

type Result<T> = std::result::Result<T, ModelError>;

/// What `[initial]` asks for (see [`crate::model::spec::InitialSpec`]).
#[derive(Default)]
struct InitialStart {
    rotation: Option<(Vec3, Vec3)>,
    /// the span of `steady = true`, for the check that needs the compiled model
    steady: Option<Range<usize>>,
    /// `consistent_velocity` as written (None: not written)
    consistent_velocity: Option<bool>,
}

/// Reads and compiles a model file; `overrides` replace parameter values (`--set`).
pub fn load(path: &Path, overrides: &[(String, f64)]) -> Result<Model> {
    load_refined(path, overrides, 1)
}

/// [`load`] with the discretisation refined by `factor` after the parameters are
/// resolved (see [`compile_str_refined`]); `factor` 1 is [`load`].
pub fn load_refined(path: &Path, overrides: &[(String, f64)], factor: usize) -> Result<Model> {
    let file = path.display().to_string();
    let lim = Limits::from_env().map_err(|e| ModelError::file(&file, None, e))?;
    let text = limits::read_capped(path, lim.model_bytes, "model file")
        .map_err(|e| ModelError::file(&file, None, e))?;
    compile_str_refined(&text, &file, overrides, factor)
}

/// A model file read and parsed once, to be compiled with several sets of overrides (the
/// variants of a campaign): [`Parsed::compile`] gives what [`load`] of the same file with
/// those overrides gives, without reading and parsing the file again. It is `Sync`, so
/// variants can compile from it in parallel.
pub struct Parsed {
    text: String,
    file: String,
    spec: Spec,
    limits: Limits,
}

/// Reads and parses a model file once (see [`Parsed`]); the errors are those of [`load`]
/// that do not depend on the overrides.
pub fn parse_file(path: &Path) -> Result<Parsed> {
    let file = path.display().to_string();
    let limits = Limits::from_env().map_err(|e| ModelError::file(&file, None, e))?;
    let text = limits::read_capped(path, limits.model_bytes, "model file")
        .map_err(|e| ModelError::file(&file, None, e))?;
    let spec = spec::parse(&text, &file)?;
    Ok(Parsed {
        text,
        file,
        spec,
        limits,
    })
}

impl Parsed {
    /// [`load`] of the parsed file with `overrides` (`--set`).
    pub fn compile(&self, overrides: &[(String, f64)]) -> Result<Model> {
        Compiler {
            file: &self.file,
            text: &self.text,
            params: Params::default(),
            limits: self.limits,
            refine: 1,
        }
        .compile(&self.spec, overrides)
    }
}

/// Compiles model text; `path` names the file in messages and in `Model::path`.
pub fn compile_str(text: &str, path: &str, overrides: &[(String, f64)]) -> Result<Model> {
    compile_str_refined(text, path, overrides, 1)
}

/// [`compile_str`] with the discretisation refined by `factor` (≥ 1), whatever the
/// file's parameters are called: every beam gets `factor` × its element count, and the
/// solver's `dt`, `dt_min` and `dt_max` are divided by `factor`. The refined model
/// reports what the base model reports, at the same points and times:
/// - interior nodes that coincide with the base mesh keep their names (`BEAM:k` of the
///   base mesh is `BEAM:k` here), so supports, loads, joints and sensors that name
///   them act on the same material point; the new nodes between them are named
///   `BEAM:k+j/factor`;
/// - a `beam_displacement` sensor reads the nodes of the base mesh only (the same
///   components);
/// - `output_dt = 0` (every step) becomes the base `dt`: the output grid is unchanged.
///
/// `sweep --verify` runs variants refined by 2 against the campaign's own runs.
pub fn compile_str_refined(
    text: &str,
    path: &str,
    overrides: &[(String, f64)],
    factor: usize,
) -> Result<Model> {
    let limits = Limits::from_env().map_err(|e| ModelError::file(path, None, e))?;
    let spec = spec::parse(text, path)?;
    Compiler {
        file: path,
        text,
        params: Params::default(),
        limits,
        refine: factor.max(1),
    }
    .compile(&spec, overrides)
}

/// Parses a command-line `NAME=VALUE`; the value may be an expression of constants
/// (`T=2*pi`).
pub fn parse_set(s: &str) -> std::result::Result<(String, f64), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("expected NAME=VALUE, got `{s}`"))?;
    let name = name.trim();
    if name.is_empty() {
        return Err(format!("expected NAME=VALUE, got `{s}`"));
    }
    let v = expr::eval(value.trim(), &[]).map_err(|e| format!("--set {name}: {e}"))?;
    Ok((name.to_string(), v))
}

/// Names in definition order with a hash index, so that resolving a reference is O(1)
/// (a linear scan per interior node made meshing quadratic in the element count).
#[derive(Default)]
struct Names {
    list: Vec<String>,
    index: HashMap<String, usize>,
}

impl Names {
    fn from_list(list: Vec<String>) -> Names {
        let mut n = Names::default();
        for x in list {
            n.push(x);
        }
        n
    }
    /// Appends `name`; false (and nothing appended) if it is already there.
    fn push(&mut self, name: String) -> bool {
        if self.index.contains_key(&name) {
            return false;
        }
        self.index.insert(name.clone(), self.list.len());
        self.list.push(name);
        true
    }
    fn contains(&self, name: &str) -> bool {
        self.index.contains_key(name)
    }
    fn get(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }
}

impl std::ops::Deref for Names {
    type Target = [String];
    fn deref(&self) -> &[String] {
        &self.list
    }
}

/// Resolved parameters in file order with a hash index: an expression's names are found
/// in O(1), so a file of many parameters that refer to early ones compiles in linear time.
#[derive(Default)]
struct Params {
    list: Vec<(String, f64)>,
    index: HashMap<String, usize>,
}

impl Params {
    fn push(&mut self, name: String, v: f64) {
        self.index.insert(name.clone(), self.list.len());
        self.list.push((name, v));
    }
    fn contains(&self, name: &str) -> bool {
        self.index.contains_key(name)
    }
}

impl expr::Scope for Params {
    fn value(&self, name: &str) -> Option<f64> {
        self.index.get(name).map(|&i| self.list[i].1)
    }
}

struct Compiler<'a> {
    file: &'a str,
    text: &'a str,
    /// parameters resolved so far (all of them once parameters are done)
    params: Params,
    limits: Limits,
    /// refinement factor of the mesh and the time step (1: the model as written; see
    /// [`compile_str_refined`])
    refine: usize,
}

/// A joint after name resolution; becomes node kinematics once dofs are numbered.
struct JointDraft {
    node: usize,
    parent: Parent,
    /// index into `Model::hinges` for hinge joints
    hinge: Option<usize>,
}

enum Parent {
    Body(Option<usize>),
    Node(usize),
}

/// A hinge whose dof is created after all node and body dofs.
struct HingeDraft {
    name: String,
    axis_local: Vec3,
    stiffness: f64,
    damping: f64,
    lock_angle: Option<f64>,
    lock_time: Option<f64>,
    v0: f64,
    v0_explicit: bool,
}

struct BodyDraft {
    body: Body,
    dofs: Vec<DofDraft>,
}

enum DofDraft {
    Translate(Vec3, Dof),
    Rotate(Vec3, Dof),
    FreeRotation(Box<[Dof; 3]>, Vec3),
}

fn dof(name: String, mode: DofMode, q0: f64, v0: f64) -> Dof {
    Dof {
        name,
        mode,
        q0,
        v0,
        v0_explicit: false,
        eq: None,
    }
}

/// One `[[bodies.dofs]]` entry after numbering: its first global dof, whether it is a
/// rotation, and whether it is driven (a free_rotation is three free dofs).
#[derive(Clone, Copy)]
struct BodyDofRef {
    dof: usize,
    rotational: bool,
    driven: bool,
}

fn free_dof(name: String) -> Dof {
    dof(name, DofMode::Free, 0.0, 0.0)
}

impl Compiler<'_> {
    fn err(
        &self,
        span: Range<usize>,
        field: impl Into<String>,
        msg: impl std::fmt::Display,
    ) -> ModelError {
        ModelError::at(self.file, self.text, span, field, msg)
    }

    /// `[initial]`: the rigid rotation (ω, centre), the span of `steady = true`, and
    /// whether the velocity is made consistent (`consistent_velocity = true`).
    fn initial(&self, sec: &Spanned<InitialSpec>) -> Result<InitialStart> {
        const BOTH: &str = "give `angular_velocity` or `steady = true`, not both: a steady \
                            start takes its rotation from the hub's drive";
        const NEITHER: &str = "`[initial]` needs `angular_velocity` (a rigid rotation), \
                               `steady = true` (the steady rotation of a constant-speed hub) \
                               or `consistent_velocity = true`";
        const CENTER: &str = "a steady start turns about the hub's own axis: remove `center`";
        const STEADY_CONSISTENT: &str = "a steady start's velocity strains nothing already \
                                         (rigid rotation with the hub): remove \
                                         `consistent_velocity`";
        let ini = sec.get_ref();
        let steady = ini.steady.as_ref().filter(|s| *s.get_ref());
        let consistent = ini.consistent_velocity.as_ref().filter(|c| *c.get_ref());
        if let (Some(c), Some(_)) = (consistent, steady) {
            return Err(self.err(c.span(), "initial.consistent_velocity", STEADY_CONSISTENT));
        }
        let consistent_velocity = ini.consistent_velocity.as_ref().map(|c| *c.get_ref());
        match (&ini.angular_velocity, steady) {
            (Some(w), None) => {
                let omega = self.vec3(w, "initial.angular_velocity")?;
                let center = self.opt_vec3(&ini.center, "initial.center")?;
                Ok(InitialStart {
                    rotation: Some((omega, center)),
                    steady: None,
                    consistent_velocity,
                })
            }
            (None, Some(st)) => match &ini.center {
                Some(c) => Err(self.err(c.span(), "initial.center", CENTER)),
                None => Ok(InitialStart {
                    rotation: None,
                    steady: Some(st.span()),
                    consistent_velocity,
                }),
            },
            (Some(w), Some(_)) => Err(self.err(w.span(), "initial.angular_velocity", BOTH)),
            (None, None) if ini.consistent_velocity.is_some() => match &ini.center {
                Some(c) => Err(self.err(
                    c.span(),
                    "initial.center",
                    "`center` belongs to `angular_velocity`: give both or neither",
                )),
                None => Ok(InitialStart {
                    rotation: None,
                    steady: None,
                    consistent_velocity,
                }),
            },
            (None, None) => Err(self.err(sec.span(), "initial.angular_velocity", NEITHER)),
        }
    }

    fn num_at(&self, n: &Num, span: Range<usize>, field: &str) -> Result<f64> {
        match n {
            Num::Value(v) if v.is_finite() => Ok(*v),
            Num::Value(v) => Err(self.err(span, field, format!("value {v} is not finite"))),
            Num::Expr(s) => expr::eval_in(s, &self.params).map_err(|e| self.err(span, field, e)),
        }
    }

    fn num(&self, n: &Spanned<Num>, field: &str) -> Result<f64> {
        self.num_at(n.get_ref(), n.span(), field)
    }

    fn opt_num(&self, n: &Option<Spanned<Num>>, field: &str) -> Result<Option<f64>> {
        n.as_ref().map(|n| self.num(n, field)).transpose()
    }

    fn positive(&self, n: &Spanned<Num>, field: &str) -> Result<f64> {
        let v = self.num(n, field)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(
                n.span(),
                field,
                format!("must be > 0, is {}", super::value_text(v)),
            ))
        }
    }

    fn non_negative(&self, n: &Spanned<Num>, field: &str) -> Result<f64> {
        let v = self.num(n, field)?;
        if v >= 0.0 {
            Ok(v)
        } else {
            Err(self.err(
                n.span(),
                field,
                format!("must be >= 0, is {}", super::value_text(v)),
            ))
        }
    }

    fn integer(&self, n: &Spanned<Num>, field: &str, min: usize) -> Result<usize> {
        let v = self.num(n, field)?;
        if !v.is_finite()
            || (v - v.round()).abs() > 1e-9 * v.abs().max(1.0)
            || v.round() < min as f64
        {
            return Err(self.err(
                n.span(),
                field,
                format!("must be an integer >= {min}, is {}", super::value_text(v)),
            ));
        }
        // beyond 2^53 not every integer is a float, and no count here is meant that large
        if v > 9.007_199_254_740_992e15 {
            return Err(self.err(
                n.span(),
                field,
                format!("must be an integer below 2^53, is {}", super::value_text(v)),
            ));
        }
        Ok(v.round() as usize)
    }

    fn vec3(&self, v: &Spanned<Vector>, field: &str) -> Result<Vec3> {
        let items = v.get_ref();
        if items.len() != 3 {
            return Err(self.err(
                v.span(),
                field,
                format!("must have 3 components, has {}", items.len()),
            ));
        }
        let mut out = [0.0; 3];
        for (k, x) in items.iter().enumerate() {
            out[k] = self.num(x, &format!("{field}[{k}]"))?;
        }
        Ok(out)
    }

    fn opt_vec3(&self, v: &Option<Spanned<Vector>>, field: &str) -> Result<Vec3> {
        v.as_ref().map_or(Ok([0.0; 3]), |v| self.vec3(v, field))
    }

    /// `x`, `y` or `z` as 0, 1, 2 (`what` says which axes, for the message).
    fn axis_component(&self, c: &Spanned<String>, field: &str, what: &str) -> Result<usize> {
        ["x", "y", "z"]
            .iter()
            .position(|x| x == c.get_ref())
            .ok_or_else(|| {
                self.err(
                    c.span(),
                    field,
                    format!(
                        "unknown component `{}` (one of x, y, z: {what})",
                        c.get_ref()
                    ),
                )
            })
    }

    fn unit(&self, v: &Spanned<Vector>, field: &str) -> Result<Vec3> {
        let x = self.vec3(v, field)?;
        if !x.iter().all(|c| c.is_finite()) {
            return Err(self.err(v.span(), field, "has a non-finite component"));
        }
        // scaled by the largest component first: the norm of [1e308, 1e308, 0] overflows
        // (and of [1e-320, 0, 0] loses digits), which turned such an axis into zero
        let big = x.iter().fold(0.0f64, |a, c| a.max(c.abs()));
        if big == 0.0 {
            return Err(self.err(v.span(), field, "has zero length"));
        }
        let n = norm(x);
        if n.is_finite() && n > 1e-150 {
            // the plain normalisation where it cannot overflow or lose digits, so axes
            // stay bit-identical to earlier releases
            return Ok(scale(x, 1.0 / n));
        }
        let y = scaled_by_largest(x);
        Ok(scale(y, 1.0 / norm(y)))
    }

    fn required<'s, T>(
        &self,
        v: &'s Option<Spanned<T>>,
        owner: Range<usize>,
        field: &str,
        why: &str,
    ) -> Result<&'s Spanned<T>> {
        v.as_ref()
            .ok_or_else(|| self.err(owner, field, format!("missing field{why}")))
    }

    fn forbid<T>(&self, v: &Option<Spanned<T>>, field: &str, why: &str) -> Result<()> {
        match v {
            Some(v) => Err(self.err(v.span(), field, why)),
            None => Ok(()),
        }
    }

    fn name(&self, n: &Spanned<String>, field: &str) -> Result<String> {
        if n.get_ref().trim().is_empty() {
            Err(self.err(n.span(), field, "must not be empty"))
        } else {
            Ok(n.get_ref().clone())
        }
    }

    fn lookup(&self, names: &Names, n: &Spanned<String>, field: &str, what: &str) -> Result<usize> {
        names
            .get(n.get_ref())
            .ok_or_else(|| self.err(n.span(), field, format!("unknown {what} `{}`", n.get_ref())))
    }

    fn compile(mut self, spec: &Spec, overrides: &[(String, f64)]) -> Result<Model> {
        self.parameters(spec, overrides)?;
        if spec.repeat.is_empty() {
            // a file without repeats is compiled from its parsed spec, untouched
            return self.compile_expanded(spec, Vec::new());
        }
        let (expanded, origins, summary) =
            super::repeat::expand(spec, self.file, self.text, &self.params, &self.limits)?;
        self.compile_expanded(&expanded, summary)
            .map_err(|e| origins.relabel(e))
    }

    /// [`Self::compile`] after the parameters are resolved and the repeats expanded.
    fn compile_expanded(
        self,
        spec: &Spec,
        repeats: Vec<super::repeat::RepeatSummary>,
    ) -> Result<Model> {
        let sections = self.sections(spec)?;

        self.nonempty(spec)?;
        let mut node_names = Names::default();
        let mut x0 = Vec::new();
        for (i, n) in spec.nodes.iter().enumerate() {
            let f = format!("nodes[{i}]");
            let name = self.name(&n.get_ref().name, &format!("{f}.name"))?;
            if node_names.contains(&name) {
                return Err(self.err(
                    n.get_ref().name.span(),
                    format!("{f}.name"),
                    format!("duplicate node name `{name}`"),
                ));
            }
            node_names.push(name);
            x0.push(self.vec3(&n.get_ref().position, &format!("{f}.position"))?);
        }

        let bodies = self.bodies(spec)?;
        let size = model_size(&x0, &bodies);
        let (elements, beams) = self.beams(spec, &sections, &mut node_names, &mut x0, size)?;

        let mut supports: Vec<Option<SupportType>> = vec![None; node_names.len()];
        for (i, s) in spec.supports.iter().enumerate() {
            let f = format!("supports[{i}].node");
            let node = self.lookup(&node_names, &s.get_ref().node, &f, "node")?;
            if supports[node].is_some() {
                return Err(self.err(
                    s.get_ref().node.span(),
                    f,
                    format!("node `{}` already has a support", node_names[node]),
                ));
            }
            supports[node] = Some(*s.get_ref().kind.get_ref());
        }

        let body_names = Names::from_list(bodies.iter().map(|b| b.body.name.clone()).collect());
        let (joints, hinge_drafts, joint_names, joint_hinge) = self.joints(
            spec,
            &node_names,
            &x0,
            &supports,
            &bodies,
            &body_names,
            size,
        )?;

        // dofs, in the documented order; bounded before any is created
        let dof_bound = 6.0 * node_names.len() as f64
            + bodies
                .iter()
                .map(|b| 3.0 * b.dofs.len() as f64)
                .sum::<f64>()
            + hinge_drafts.len() as f64;
        if dof_bound > self.limits.dofs as f64 {
            return Err(ModelError::file(
                self.file,
                None,
                limits::exceeded(
                    &format!(
                        "the model's coordinates ({} nodes × 6, plus bodies and hinges)",
                        node_names.len()
                    ),
                    dof_bound,
                    "dofs",
                    self.limits.dofs,
                ),
            ));
        }
        let mut dofs: Vec<Dof> = Vec::new();
        let mut spins: Vec<Spin> = Vec::new();
        let mut node_kin = Vec::with_capacity(node_names.len());
        let mut joint_of_node: Vec<Option<usize>> = vec![None; node_names.len()];
        for (j, jd) in joints.iter().enumerate() {
            joint_of_node[jd.node] = Some(j);
        }
        // a node with dofs of its own but no element would make the system singular
        let mut on_element = vec![false; node_names.len()];
        for e in &elements {
            on_element[e.n1] = true;
            on_element[e.n2] = true;
        }
        for (i, n) in spec.nodes.iter().enumerate() {
            let has_dofs = joint_of_node[i].is_none() && supports[i] != Some(SupportType::Clamped);
            if has_dofs && !on_element[i] {
                return Err(self.err(
                    n.get_ref().name.span(),
                    format!("nodes[{i}].name"),
                    format!(
                        "node `{}` is on no beam and not held by a support or joint: its dofs \
                         would have neither stiffness nor mass",
                        node_names[i]
                    ),
                ));
            }
        }
        for n in 0..node_names.len() {
            let kin = if let Some(j) = joint_of_node[n] {
                let jd = &joints[j];
                match jd.parent {
                    Parent::Body(body) => {
                        let (xb, rb) =
                            body.map_or(([0.0; 3], I3), |b| (bodies[b].body.x0, bodies[b].body.r0));
                        NodeKin::OnBody {
                            body,
                            s: mat_t_vec(&rb, sub(x0[n], xb)),
                            hinge: jd.hinge,
                            r_rel: transpose(&rb),
                        }
                    }
                    Parent::Node(master) => NodeKin::OnNode {
                        master,
                        // node-to-node joints are always hinges (checked in `joints`)
                        hinge: jd.hinge.unwrap_or_default(),
                        r_rel: I3,
                    },
                }
            } else {
                let name = &node_names[n];
                let mut spin_group = |dofs: &mut Vec<Dof>| {
                    let d0 = dofs.len();
                    for c in ["rx", "ry", "rz"] {
                        dofs.push(free_dof(format!("{name}.{c}")));
                    }
                    spins.push(Spin {
                        dofs: [d0, d0 + 1, d0 + 2],
                        omega0: [0.0; 3],
                    });
                    Some(spins.len() - 1)
                };
                match supports[n] {
                    Some(SupportType::Clamped) => NodeKin::OnBody {
                        body: None,
                        s: x0[n],
                        hinge: None,
                        r_rel: I3,
                    },
                    Some(SupportType::Pinned) => NodeKin::Free {
                        trans: [None; 3],
                        spin: spin_group(&mut dofs),
                    },
                    _ => {
                        let d0 = dofs.len();
                        for c in ["x", "y", "z"] {
                            dofs.push(free_dof(format!("{name}.{c}")));
                        }
                        NodeKin::Free {
                            trans: [Some(d0), Some(d0 + 1), Some(d0 + 2)],
                            spin: spin_group(&mut dofs),
                        }
                    }
                }
            };
            node_kin.push(kin);
        }

        let mut model_bodies = Vec::with_capacity(bodies.len());
        let mut body_dofs: Vec<Vec<BodyDofRef>> = Vec::with_capacity(bodies.len());
        for bd in bodies {
            let mut body = bd.body;
            let mut refs = Vec::with_capacity(bd.dofs.len());
            for d in bd.dofs {
                refs.push(BodyDofRef {
                    dof: dofs.len(),
                    rotational: !matches!(d, DofDraft::Translate(..)),
                    driven: match &d {
                        DofDraft::Translate(_, q) | DofDraft::Rotate(_, q) => {
                            matches!(q.mode, DofMode::Driven(_))
                        }
                        DofDraft::FreeRotation(..) => false,
                    },
                });
                match d {
                    DofDraft::Translate(dir, q) => {
                        dofs.push(q);
                        body.chain.push(ChainLink::Translate {
                            dof: dofs.len() - 1,
                            dir,
                        });
                    }
                    DofDraft::Rotate(axis, q) => {
                        dofs.push(q);
                        body.chain.push(ChainLink::RotateFixedAxis {
                            dof: dofs.len() - 1,
                            axis,
                        });
                    }
                    DofDraft::FreeRotation(qs, omega0) => {
                        let d0 = dofs.len();
                        dofs.extend(*qs);
                        spins.push(Spin {
                            dofs: [d0, d0 + 1, d0 + 2],
                            omega0,
                        });
                        for k in 0..3 {
                            body.chain.push(ChainLink::SpinComponent {
                                dof: d0 + k,
                                spin: spins.len() - 1,
                                k,
                            });
                        }
                    }
                }
            }
            model_bodies.push(body);
            body_dofs.push(refs);
        }

        let mut hinges = Vec::with_capacity(hinge_drafts.len());
        for h in hinge_drafts {
            let mut q = dof(format!("{}.angle", h.name), DofMode::Free, 0.0, h.v0);
            q.v0_explicit = h.v0_explicit;
            dofs.push(q);
            hinges.push(Hinge {
                name: h.name,
                dof: dofs.len() - 1,
                axis_local: h.axis_local,
                stiffness: h.stiffness,
                damping: h.damping,
                angle_ref: 0.0,
                lock_angle: h.lock_angle,
                lock_time: h.lock_time,
            });
        }

        let mut hinge_of_dof = vec![None; dofs.len()];
        for (h, hinge) in hinges.iter().enumerate() {
            hinge_of_dof[hinge.dof] = Some(h);
        }
        let mut n_eq = 0;
        for d in dofs.iter_mut() {
            if matches!(d.mode, DofMode::Free) {
                d.eq = Some(n_eq);
                n_eq += 1;
            }
        }

        let mut loads = Vec::new();
        for (i, l) in spec.loads.iter().enumerate() {
            let f = format!("loads[{i}]");
            let l = l.get_ref();
            if let Some(fo) = &l.follower {
                if *fo.get_ref() {
                    return Err(self.err(
                        fo.span(),
                        format!("{f}.follower"),
                        "follower loads are not supported yet (loads keep their global \
                         direction: follower = false)",
                    ));
                }
            }
            let scale = l
                .scale
                .as_ref()
                .map(|sc| self.time_function(sc, &format!("{f}.scale")))
                .transpose()?;
            loads.push(NodeLoad {
                node: self.lookup(&node_names, &l.node, &format!("{f}.node"), "node")?,
                force: self.opt_vec3(&l.force, &format!("{f}.force"))?,
                moment: self.opt_vec3(&l.moment, &format!("{f}.moment"))?,
                scale,
            });
        }
        let start = match &spec.initial {
            None => InitialStart::default(),
            Some(sec) => self.initial(sec)?,
        };
        let (initial_rotation, initial_steady) = (start.rotation, start.steady);
        let gravity = match &spec.environment {
            Some(e) => self.opt_vec3(&e.get_ref().gravity, "environment.gravity")?,
            None => [0.0; 3],
        };

        let sensors = self.sensors(
            spec,
            &node_names,
            &beams,
            &body_names,
            &body_dofs,
            &joint_names,
            &joint_hinge,
        )?;
        let mut solver = self.solver(spec)?;
        solver.max_steps = self.limits.steps;
        if self.refine > 1 {
            // refined run: smaller steps on the base output grid
            let r = self.refine as f64;
            if solver.output_dt == 0.0 {
                solver.output_dt = solver.dt;
            }
            solver.dt /= r;
            solver.dt_min /= r;
            solver.dt_max /= r;
        }
        self.output_size(spec, &solver, &sensors)?;

        let name = match spec.model.as_ref().and_then(|m| m.get_ref().name.as_ref()) {
            Some(n) => n.get_ref().clone(),
            None => Path::new(self.file).file_stem().map_or_else(
                || self.file.to_string(),
                |s| s.to_string_lossy().into_owned(),
            ),
        };

        // hinge chains between nodes are checked acyclic where they are built
        let kin_order = super::types::kinematic_order(&node_kin)
            .expect("node hinge chains are acyclic after compilation");
        let elem_data = elements
            .iter()
            .map(|e| crate::element::ElemData::new(e.props, e.frame0, x0[e.n1], x0[e.n2]))
            .collect();
        let dof_eq: Vec<Option<usize>> = dofs.iter().map(|d| d.eq).collect();
        let rot_eq = rotation_equations(n_eq, &dof_eq, &spins, &hinges, &model_bodies);
        let (file, text) = (self.file, self.text);
        let model = Model {
            name,
            path: self.file.to_string(),
            source: self.text.to_string(),
            params: self.params.list,
            node_names: node_names.list,
            x0,
            node_kin,
            kin_order,
            elements,
            beams,
            bodies: model_bodies,
            dofs,
            spins,
            hinges,
            loads,
            gravity,
            sensors,
            solver,
            n_eq,
            initial_rotation,
            initial_steady: initial_steady.is_some(),
            initial_consistent_velocity: start.consistent_velocity,
            repeats,
            hinge_of_dof,
            elem_data,
            dof_eq,
            rot_eq,
        };
        if let Some(span) = initial_steady {
            if crate::solver::rotating::constant_rate_hub(&model).is_none() {
                return Err(ModelError::at(
                    file,
                    text,
                    span,
                    "initial.steady",
                    "a steady start needs a body rotation driven at a constant rate over the \
                     whole run (a hub with `drive = \"omega*t\"`); this model has none",
                ));
            }
        }
        Ok(model)
    }

    /// Parameters in file order; an expression may use the parameters before it. An
    /// override replaces the value (and so changes the parameters computed from it).
    fn parameters(&mut self, spec: &Spec, overrides: &[(String, f64)]) -> Result<()> {
        for (key, value) in &spec.parameters.0 {
            let name = key.get_ref();
            let f = format!("parameters.{name}");
            expr::check_param_name(name).map_err(|e| self.err(key.span(), &f, e))?;
            let v = match overrides.iter().rev().find(|(n, _)| n == name) {
                Some((_, v)) if !v.is_finite() => {
                    return Err(ModelError::file(
                        self.file,
                        Some(f),
                        format!("override value {v} is not finite"),
                    ))
                }
                Some((_, v)) => *v,
                None => match value.get_ref() {
                    ParamValue::Plain(n) => self.num_at(n, value.span(), &f),
                    ParamValue::Full(t) => self.num(&t.value, &format!("{f}.value")),
                }
                .map_err(|mut e| {
                    let later = spec
                        .parameters
                        .0
                        .iter()
                        .map(|(k, _)| k.get_ref())
                        .find(|k| {
                            !self.params.contains(k)
                                && e.message.contains(&format!("undefined parameter `{k}`"))
                        });
                    if let Some(k) = later {
                        e.message += &format!(
                            " (`{k}` is defined later: a parameter can only use those before it)"
                        );
                    }
                    e
                })?,
            };
            if let ParamValue::Full(t) = value.get_ref() {
                let from = if overrides.iter().any(|(n, _)| n == name) {
                    format!(" (--set {name}={v})")
                } else {
                    String::new()
                };
                let bad = |msg: String| self.err(key.span(), &f, format!("{msg}{from}"));
                if t.integer == Some(true) && v.fract() != 0.0 {
                    return Err(bad(format!(
                        "must be a whole number, is {}",
                        super::value_text(v)
                    )));
                }
                if let Some(lo) = self.opt_num(&t.min, &format!("{f}.min"))? {
                    if v < lo {
                        return Err(bad(format!("is {v}, below its minimum {lo}")));
                    }
                }
                if let Some(hi) = self.opt_num(&t.max, &format!("{f}.max"))? {
                    if v > hi {
                        return Err(bad(format!("is {v}, above its maximum {hi}")));
                    }
                }
            }
            self.params.push(name.clone(), v);
        }
        for (name, _) in overrides {
            if !self.params.contains(name) {
                let known: Vec<&str> = self.params.list.iter().map(|(n, _)| n.as_str()).collect();
                return Err(ModelError::file(
                    self.file,
                    Some(format!("--set {name}")),
                    format!(
                        "the model has no parameter `{name}` (parameters: {})",
                        if known.is_empty() {
                            "none".to_string()
                        } else {
                            known.join(", ")
                        }
                    ),
                ));
            }
        }
        Ok(())
    }

    fn sections(&self, spec: &Spec) -> Result<HashMap<String, BeamProps>> {
        let mut materials = HashMap::new();
        for (key, m) in &spec.materials.0 {
            let f = format!("materials.{}", key.get_ref());
            let m = m.get_ref();
            let e = self.positive(&m.e, &format!("{f}.E"))?;
            let g = self.positive(&m.g, &format!("{f}.G"))?;
            let rho = self.non_negative(&m.density, &format!("{f}.density"))?;
            materials.insert(key.get_ref().clone(), (e, g, rho));
        }
        let mut out = HashMap::new();
        for (key, s) in &spec.sections.0 {
            let f = format!("sections.{}", key.get_ref());
            let props = self.section(&f, s, &materials)?;
            out.insert(key.get_ref().clone(), props);
        }
        Ok(out)
    }

    fn section(
        &self,
        f: &str,
        s: &Spanned<Section>,
        materials: &HashMap<String, (f64, f64, f64)>,
    ) -> Result<BeamProps> {
        let span = s.span();
        let s = s.get_ref();
        let direct = [
            (&s.ea, "EA"),
            (&s.eiy, "EIy"),
            (&s.eiz, "EIz"),
            (&s.gj, "GJ"),
            (&s.rho_a, "rhoA"),
            (&s.rho_iy, "rhoIy"),
            (&s.rho_iz, "rhoIz"),
        ];
        let dims = [
            (&s.outer_diameter, "outer_diameter"),
            (&s.inner_diameter, "inner_diameter"),
            (&s.diameter, "diameter"),
            (&s.width, "width"),
            (&s.height, "height"),
        ];
        let Some(shape) = &s.shape else {
            for (v, k) in dims {
                self.forbid(v, &format!("{f}.{k}"), "only used with `shape`")?;
            }
            self.forbid(
                &s.material,
                &format!("{f}.material"),
                "only used with `shape`",
            )?;
            let req = |v: &Option<Spanned<Num>>, k: &str| -> Result<f64> {
                let fk = format!("{f}.{k}");
                self.positive(
                    self.required(
                        v,
                        span.clone(),
                        &fk,
                        " (direct properties need EA, EIy, EIz, GJ, rhoA)",
                    )?,
                    &fk,
                )
            };
            let rho_a = {
                let fk = format!("{f}.rhoA");
                self.non_negative(
                    self.required(
                        &s.rho_a,
                        span.clone(),
                        &fk,
                        " (direct properties need EA, EIy, EIz, GJ, rhoA)",
                    )?,
                    &fk,
                )?
            };
            let opt = |v: &Option<Spanned<Num>>, k: &str| -> Result<f64> {
                v.as_ref()
                    .map_or(Ok(0.0), |v| self.non_negative(v, &format!("{f}.{k}")))
            };
            return Ok(BeamProps {
                ea: req(&s.ea, "EA")?,
                eiy: req(&s.eiy, "EIy")?,
                eiz: req(&s.eiz, "EIz")?,
                gj: req(&s.gj, "GJ")?,
                rho_a,
                rho_iy: opt(&s.rho_iy, "rhoIy")?,
                rho_iz: opt(&s.rho_iz, "rhoIz")?,
            });
        };
        for (v, k) in direct {
            self.forbid(
                v,
                &format!("{f}.{k}"),
                "cannot be combined with `shape` (give direct properties or a shape, not both)",
            )?;
        }
        let shape = *shape.get_ref();
        let mf = format!("{f}.material");
        let mat = self.required(
            &s.material,
            span.clone(),
            &mf,
            " (a shape needs a material)",
        )?;
        let &(e, g, rho) = materials.get(mat.get_ref()).ok_or_else(|| {
            self.err(
                mat.span(),
                &mf,
                format!("unknown material `{}`", mat.get_ref()),
            )
        })?;
        let used: &[&str] = match shape {
            Shape::Tube => &["outer_diameter", "inner_diameter"],
            Shape::Circle => &["diameter"],
            Shape::Rectangle => &["width", "height"],
        };
        let shape_name = match shape {
            Shape::Tube => "tube",
            Shape::Circle => "circle",
            Shape::Rectangle => "rectangle",
        };
        for (v, k) in dims {
            if !used.contains(&k) {
                self.forbid(
                    v,
                    &format!("{f}.{k}"),
                    &format!("not used by shape `{shape_name}`"),
                )?;
            }
        }
        let mut d = HashMap::new();
        for (v, k) in dims {
            if used.contains(&k) {
                let fk = format!("{f}.{k}");
                let why = format!(" (shape `{shape_name}` needs {})", used.join(", "));
                let v = self.required(v, span.clone(), &fk, &why)?;
                let x = if k == "inner_diameter" {
                    self.non_negative(v, &fk)?
                } else {
                    self.positive(v, &fk)?
                };
                d.insert(k, (x, v.span()));
            }
        }
        let pi = std::f64::consts::PI;
        let (area, iy, iz, j) = match shape {
            Shape::Tube => {
                let (od, id) = (d["outer_diameter"].0, d["inner_diameter"].clone());
                if id.0 >= od {
                    return Err(self.err(
                        id.1,
                        format!("{f}.inner_diameter"),
                        format!("must be smaller than outer_diameter ({od}), is {}", id.0),
                    ));
                }
                let i = pi * (od.powi(4) - id.0.powi(4)) / 64.0;
                (pi * (od * od - id.0 * id.0) / 4.0, i, i, 2.0 * i)
            }
            Shape::Circle => {
                let dd = d["diameter"].0;
                let i = pi * dd.powi(4) / 64.0;
                (pi * dd * dd / 4.0, i, i, 2.0 * i)
            }
            Shape::Rectangle => {
                // width b along local y, height h along local z
                let (b, h) = (d["width"].0, d["height"].0);
                (
                    b * h,
                    b * h.powi(3) / 12.0,
                    h * b.powi(3) / 12.0,
                    rect_torsion(b, h),
                )
            }
        };
        let props = BeamProps {
            ea: e * area,
            eiy: e * iy,
            eiz: e * iz,
            gj: g * j,
            rho_a: rho * area,
            rho_iy: rho * iy,
            rho_iz: rho * iz,
        };
        // a diameter of 1e100 gives I = inf: every force of the element would be NaN
        let derived = [
            (props.ea, "EA"),
            (props.eiy, "EIy"),
            (props.eiz, "EIz"),
            (props.gj, "GJ"),
            (props.rho_a, "rhoA"),
            (props.rho_iy, "rhoIy"),
            (props.rho_iz, "rhoIz"),
        ];
        if let Some((v, k)) = derived.iter().find(|(v, _)| !v.is_finite()) {
            return Err(self.err(
                span,
                f,
                format!(
                    "the {shape_name}'s {k} is {v}: its dimensions and material overflow \
                     f64"
                ),
            ));
        }
        Ok(props)
    }

    fn bodies(&self, spec: &Spec) -> Result<Vec<BodyDraft>> {
        let mut out: Vec<BodyDraft> = Vec::new();
        let mut seen = HashSet::new();
        for (i, b) in spec.bodies.iter().enumerate() {
            let f = format!("bodies[{i}]");
            let span = b.span();
            let b = b.get_ref();
            let name = self.name(&b.name, &format!("{f}.name"))?;
            if name == "ground" || !seen.insert(name.clone()) {
                let why = if name == "ground" {
                    "`ground` is reserved for the fixed frame".to_string()
                } else {
                    format!("duplicate body name `{name}`")
                };
                return Err(self.err(b.name.span(), format!("{f}.name"), why));
            }
            let x0 = b
                .position
                .as_ref()
                .map_or(Ok([0.0; 3]), |p| self.vec3(p, &format!("{f}.position")))?;
            let r0 = match &b.axes {
                None => I3,
                Some(axes) => self.axes(axes, &format!("{f}.axes"))?,
            };
            let com = self.opt_vec3(&b.com, &format!("{f}.com"))?;
            let inertia = match &b.inertia {
                None => [[0.0; 3]; 3],
                Some(v) => self.inertia(v, &format!("{f}.inertia"))?,
            };
            let mass = match &b.mass {
                Some(m) if !b.dofs.is_empty() => self.positive(m, &format!("{f}.mass"))?,
                Some(m) => self.non_negative(m, &format!("{f}.mass"))?,
                None if !b.dofs.is_empty() => {
                    return Err(self.err(
                        span,
                        format!("{f}.mass"),
                        "missing field (a body with dofs needs a mass > 0)",
                    ));
                }
                None => 0.0,
            };
            let mut dofs = Vec::new();
            let mut rotated = false;
            for (k, d) in b.dofs.iter().enumerate() {
                let fd = format!("{f}.dofs[{k}]");
                let qname = format!("{name}.dofs[{k}]");
                let kind = *d.get_ref().kind.get_ref();
                if rotated {
                    let why = match kind {
                        DofType::Translation => "translations must come before the rotation",
                        _ => "a body has at most one rotation or free_rotation",
                    };
                    return Err(self.err(d.get_ref().kind.span(), format!("{fd}.type"), why));
                }
                dofs.push(match kind {
                    DofType::Translation | DofType::Rotation => {
                        let axis = self.required(&d.get_ref().axis, d.span(), &format!("{fd}.axis"), "")?;
                        let axis = self.unit(axis, &format!("{fd}.axis"))?;
                        let q = self.body_dof(d, &fd, qname)?;
                        if kind == DofType::Rotation {
                            rotated = true;
                            DofDraft::Rotate(axis, q)
                        } else {
                            DofDraft::Translate(axis, q)
                        }
                    }
                    DofType::FreeRotation => {
                        rotated = true;
                        let d = d.get_ref();
                        let why = "not used by free_rotation (three free spatial spins about the reference point)";
                        self.forbid(&d.axis, &format!("{fd}.axis"), why)?;
                        self.forbid(&d.drive, &format!("{fd}.drive"), why)?;
                        self.forbid(&d.initial, &format!("{fd}.initial"), why)?;
                        let fr = format!("{fd}.initial_rate");
                        let omega0 = match &d.initial_rate {
                            None => [0.0; 3],
                            Some(r) => match r.get_ref() {
                                NumOrVec::Vec(v) => self.vec3(&Spanned::new(r.span(), v.clone()), &fr)?,
                                NumOrVec::Num(_) => {
                                    return Err(self.err(r.span(), fr, "a free_rotation's initial_rate is an angular velocity vector [wx, wy, wz] (global frame)"));
                                }
                            },
                        };
                        let explicit = d.initial_rate.is_some();
                        let qs = ["x", "y", "z"].map(|c| {
                            let mut q = free_dof(format!("{qname}.{c}"));
                            q.v0_explicit = explicit;
                            q
                        });
                        DofDraft::FreeRotation(Box::new(qs), omega0)
                    }
                });
            }
            out.push(BodyDraft {
                body: Body {
                    name,
                    x0,
                    r0,
                    mass,
                    com,
                    inertia,
                    chain: Vec::new(),
                },
                dofs,
            });
        }
        Ok(out)
    }

    /// A translation or single rotation coordinate: driven, or free with initial values.
    fn body_dof(&self, d: &Spanned<DofSpec>, fd: &str, name: String) -> Result<Dof> {
        let d = d.get_ref();
        let Some(drive) = &d.drive else {
            let q0 = self
                .opt_num(&d.initial, &format!("{fd}.initial"))?
                .unwrap_or(0.0);
            let fr = format!("{fd}.initial_rate");
            let v0 = match &d.initial_rate {
                None => 0.0,
                Some(r) => match r.get_ref() {
                    NumOrVec::Num(n) => self.num_at(n, r.span(), &fr)?,
                    NumOrVec::Vec(_) => return Err(self.err(r.span(), fr, "must be a number")),
                },
            };
            let mut q = dof(name, DofMode::Free, q0, v0);
            q.v0_explicit = d.initial_rate.is_some();
            return Ok(q);
        };
        let why = "cannot be combined with `drive` (a driven dof starts where its drive does)";
        self.forbid(&d.initial, &format!("{fd}.initial"), why)?;
        self.forbid(&d.initial_rate, &format!("{fd}.initial_rate"), why)?;
        let tf = self.time_function(drive, &format!("{fd}.drive"))?;
        let [q0, v0, _] = tf.eval(0.0);
        Ok(dof(name, DofMode::Driven(tf), q0, v0))
    }

    /// A function of the time `t` and the parameters (a number is a constant).
    fn time_function(&self, n: &Spanned<Num>, field: &str) -> Result<TimeFunction> {
        match n.get_ref() {
            Num::Value(v) => {
                self.num_at(&Num::Value(*v), n.span(), field)?;
                Ok(TimeFunction::constant(*v))
            }
            Num::Expr(s) => {
                TimeFunction::new_in(s, &self.params).map_err(|e| self.err(n.span(), field, e))
            }
        }
    }

    fn axes(&self, axes: &Spanned<Vec<Spanned<Vector>>>, f: &str) -> Result<Mat3> {
        let v = axes.get_ref();
        if v.len() != 2 {
            return Err(self.err(
                axes.span(),
                f,
                format!("must be [x axis, y axis], has {} entries", v.len()),
            ));
        }
        // tiny or huge axes must neither underflow nor overflow below
        let x = scaled_by_largest(self.vec3(&v[0], &format!("{f}[0]"))?);
        let y = scaled_by_largest(self.vec3(&v[1], &format!("{f}[1]"))?);
        let nx = norm(x);
        let yp = sub(y, scale(x, dot(x, y) / (nx * nx)));
        if nx == 0.0 || norm(yp) <= 1e-9 * norm(y) {
            return Err(self.err(
                axes.span(),
                f,
                "degenerate: x must be non-zero and y not parallel to x",
            ));
        }
        // rounded table values are made exactly perpendicular; more than 1e-3 rad off
        // is a mistyped axis, which would otherwise turn the body silently
        let cos = (dot(x, y) / (nx * norm(y))).clamp(-1.0, 1.0);
        if cos.asin().abs() > AXES_SLACK {
            return Err(self.err(
                axes.span(),
                f,
                format!(
                    "x and y are not perpendicular: {:.4}° between them (at most \
                     {AXES_SLACK:e} rad off 90° is accepted and made exact)",
                    cos.acos().to_degrees()
                ),
            ));
        }
        let (x, y) = (normalize(x), normalize(yp));
        Ok(from_cols(x, y, cross(x, y)))
    }

    fn inertia(&self, v: &Spanned<Vec<Spanned<NumOrVec>>>, f: &str) -> Result<Mat3> {
        let shape_err = || {
            self.err(
                v.span(),
                f,
                "must be [Ixx, Iyy, Izz] or a 3x3 array of rows",
            )
        };
        let items = v.get_ref();
        if items.len() != 3 {
            return Err(shape_err());
        }
        let mut m = [[0.0; 3]; 3];
        for (r, item) in items.iter().enumerate() {
            let fr = format!("{f}[{r}]");
            match item.get_ref() {
                NumOrVec::Num(n)
                    if items
                        .iter()
                        .all(|x| matches!(x.get_ref(), NumOrVec::Num(_))) =>
                {
                    m[r][r] = self.num_at(n, item.span(), &fr)?;
                }
                NumOrVec::Vec(row)
                    if items
                        .iter()
                        .all(|x| matches!(x.get_ref(), NumOrVec::Vec(_))) =>
                {
                    m[r] = self.vec3(&Spanned::new(item.span(), row.clone()), &fr)?;
                }
                _ => return Err(shape_err()),
            }
        }
        let big = m.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
        let asymmetric = [(0, 1), (0, 2), (1, 2)]
            .iter()
            .any(|&(i, j)| (m[i][j] - m[j][i]).abs() > 1e-12 * big);
        if asymmetric {
            return Err(self.err(v.span(), f, "inertia not symmetric"));
        }
        // Sylvester's criterion
        let d1 = m[0][0];
        let d2 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let d3 = dot(col(&m, 0), cross(col(&m, 1), col(&m, 2)));
        if !(d1 > 0.0 && d2 > 0.0 && d3 > 0.0) {
            return Err(self.err(v.span(), f, "inertia not positive definite"));
        }
        // Every mass distribution has principal moments with a + b ≥ c (equal for a flat
        // one): a tensor that breaks it is a typo, not a body. The slack admits values
        // rounded to about six digits.
        let [a, b, c] = sym3_eigenvalues(&m);
        if c - (a + b) > 1e-6 * (a + b + c) {
            // six significant digits, printed shortest (0.1, not 1.000000e-1)
            let g = |x: f64| format!("{x:.5e}").parse::<f64>().unwrap_or(x);
            return Err(self.err(
                v.span(),
                f,
                format!(
                    "inertia of no mass distribution: its principal moments {}, {}, {} \
                     break the triangle inequality (the largest exceeds the sum of the \
                     other two, {}; a flat body has them equal)",
                    g(a),
                    g(b),
                    g(c),
                    g(a + b)
                ),
            ));
        }
        Ok(m)
    }

    fn beams(
        &self,
        spec: &Spec,
        sections: &HashMap<String, BeamProps>,
        node_names: &mut Names,
        x0: &mut Vec<Vec3>,
        size: f64,
    ) -> Result<(Vec<Element>, Vec<Beam>)> {
        let mut elements = Vec::new();
        let mut beams: Vec<Beam> = Vec::new();
        let mut beam_names = HashSet::new();
        for (bi, b) in spec.beams.iter().enumerate() {
            let f = format!("beams[{bi}]");
            let bspan = b.span();
            let b = b.get_ref();
            let name = self.name(&b.name, &format!("{f}.name"))?;
            if !beam_names.insert(name.clone()) {
                return Err(self.err(
                    b.name.span(),
                    format!("{f}.name"),
                    format!("duplicate beam name `{name}`"),
                ));
            }
            let n1 = self.lookup(node_names, &b.from, &format!("{f}.from"), "node")?;
            let n2 = self.lookup(node_names, &b.to, &format!("{f}.to"), "node")?;
            let n = self
                .integer(&b.elements, &format!("{f}.elements"), 1)?
                .saturating_mul(self.refine);
            // before meshing allocates anything for this beam
            let total = elements.len() as f64 + n as f64;
            if total > self.limits.elements as f64 {
                return Err(self.err(
                    b.elements.span(),
                    format!("{f}.elements"),
                    limits::exceeded(
                        &format!("element count of the model with this beam's {n}"),
                        total,
                        "elements",
                        self.limits.elements,
                    ),
                ));
            }
            let props = *sections.get(b.section.get_ref()).ok_or_else(|| {
                self.err(
                    b.section.span(),
                    format!("{f}.section"),
                    format!("unknown section `{}`", b.section.get_ref()),
                )
            })?;
            let (p1, p2) = (x0[n1], x0[n2]);
            if n1 == n2 || norm(sub(p2, p1)) <= 1e-12 * size {
                return Err(self.err(
                    bspan,
                    format!("{f}.to"),
                    "zero-length beam: `from` and `to` are at the same position",
                ));
            }
            let centre = b
                .arc_center
                .as_ref()
                .map(|c| self.vec3(c, &format!("{f}.arc_center")))
                .transpose()?;
            // the angle each element subtends times the arc's axis (global)
            let mut arc_turn = [0.0; 3];
            let points: Vec<Vec3> = match centre {
                None => (1..n)
                    .map(|k| add(p1, scale(sub(p2, p1), k as f64 / n as f64)))
                    .collect(),
                Some(c) => {
                    let fc = format!("{f}.arc_center");
                    let span = b.arc_center.as_ref().map_or(bspan.clone(), |a| a.span());
                    let (a, e) = (sub(p1, c), sub(p2, c));
                    let (ra, re) = (norm(a), norm(e));
                    if ra == 0.0 || re == 0.0 {
                        return Err(self.err(span, fc, "coincides with an end of the beam"));
                    }
                    if (ra - re).abs() > 1e-6 * ra.max(re) {
                        return Err(self.err(span, fc, format!("`from` and `to` are not equidistant from the centre (radii {ra} and {re})")));
                    }
                    let axb = cross(a, e);
                    if norm(axb) <= 1e-9 * ra * re {
                        return Err(self.err(span, fc, "`from`, `to` and the centre are collinear: the arc's plane is undefined"));
                    }
                    let theta = norm(axb).atan2(dot(a, e));
                    let axis = normalize(axb);
                    arc_turn = scale(axis, theta / n as f64);
                    (1..n)
                        .map(|k| add(c, mat_vec(&rot_axis(axis, theta * k as f64 / n as f64), a)))
                        .collect()
                }
            };
            let mut nodes = vec![n1];
            let r = self.refine;
            for (k, p) in points.into_iter().enumerate() {
                // refined: the nodes of the base mesh keep their names
                let nn = if (k + 1) % r == 0 {
                    format!("{name}:{}", (k + 1) / r)
                } else {
                    format!("{name}:{}+{}/{r}", (k + 1) / r, (k + 1) % r)
                };
                if !node_names.push(nn.clone()) {
                    return Err(self.err(
                        b.name.span(),
                        format!("{f}.name"),
                        format!("interior node name `{nn}` is already used by a node"),
                    ));
                }
                x0.push(p);
                nodes.push(x0.len() - 1);
            }
            nodes.push(n2);
            let hint = b
                .orientation
                .as_ref()
                .map(|o| self.unit(o, &format!("{f}.orientation")))
                .transpose()?;
            let mut elems = Vec::with_capacity(n);
            for k in 0..n {
                let (a, e) = (nodes[k], nodes[k + 1]);
                let d = sub(x0[e], x0[a]);
                let len = norm(d);
                if len <= 1e-12 * size {
                    return Err(self.err(
                        bspan.clone(),
                        format!("{f}.elements"),
                        format!("element {k} has zero length"),
                    ));
                }
                let x = scale(d, 1.0 / len);
                let y = match (hint, centre) {
                    (Some(h), _) => {
                        if norm(cross(x, h)) < 1e-6 {
                            let span = b.orientation.as_ref().map_or(bspan.clone(), |o| o.span());
                            return Err(self.err(
                                span,
                                format!("{f}.orientation"),
                                format!("parallel to element {k} of the beam"),
                            ));
                        }
                        perpendicular(x, h)
                    }
                    // towards the centre: the in-plane normal of the arc
                    (None, Some(c)) => perpendicular(x, sub(c, scale(add(x0[a], x0[e]), 0.5))),
                    (None, None) => perpendicular(x, least_parallel_axis(x)),
                };
                let frame0 = from_cols(x, y, cross(x, y));
                elements.push(Element {
                    n1: a,
                    n2: e,
                    props,
                    frame0,
                    beam: bi,
                    arc: mat_vec(&transpose(&frame0), arc_turn),
                });
                elems.push(elements.len() - 1);
            }
            beams.push(Beam {
                name,
                elements: elems,
                nodes,
            });
        }
        Ok((elements, beams))
    }

    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn joints(
        &self,
        spec: &Spec,
        node_names: &Names,
        x0: &[Vec3],
        supports: &[Option<SupportType>],
        bodies: &[BodyDraft],
        body_names: &Names,
        size: f64,
    ) -> Result<(Vec<JointDraft>, Vec<HingeDraft>, Names, Vec<Option<usize>>)> {
        let mut drafts: Vec<JointDraft> = Vec::new();
        // node -> its joint (index into drafts)
        let mut joint_at: HashMap<usize, usize> = HashMap::new();
        let mut hinges = Vec::new();
        let mut names = Names::default();
        let mut joint_hinge = Vec::new();
        for (i, js) in spec.joints.iter().enumerate() {
            let f = format!("joints[{i}]");
            let span = js.span();
            let j = js.get_ref();
            let name = self.name(&j.name, &format!("{f}.name"))?;
            if names.contains(&name) {
                return Err(self.err(
                    j.name.span(),
                    format!("{f}.name"),
                    format!("duplicate joint name `{name}`"),
                ));
            }
            let fnode = format!("{f}.node");
            let node = self.lookup(node_names, &j.node, &fnode, "node")?;
            if supports[node].is_some() {
                return Err(self.err(
                    j.node.span(),
                    fnode,
                    format!(
                        "node `{}` has a support as well as a joint",
                        node_names[node]
                    ),
                ));
            }
            if let Some(&other) = joint_at.get(&node) {
                return Err(self.err(
                    j.node.span(),
                    fnode,
                    format!(
                        "node `{}` already has joint `{}`",
                        node_names[node], names[other]
                    ),
                ));
            }
            let kind = *j.kind.get_ref();
            let parent = match (&j.body, &j.to_node) {
                (Some(_), Some(t)) => {
                    return Err(self.err(
                        t.span(),
                        format!("{f}.to_node"),
                        "give either `body` or `to_node`, not both",
                    ));
                }
                (None, None) => {
                    return Err(self.err(
                        span,
                        format!("{f}.body"),
                        "missing field (or `to_node`)",
                    ));
                }
                (Some(b), None) if b.get_ref() == "ground" => Parent::Body(None),
                (Some(b), None) => Parent::Body(Some(self.lookup(
                    body_names,
                    b,
                    &format!("{f}.body"),
                    "body",
                )?)),
                (None, Some(t)) => {
                    let ft = format!("{f}.to_node");
                    let m = self.lookup(node_names, t, &ft, "node")?;
                    if m == node {
                        return Err(self.err(t.span(), ft, "a node cannot be joined to itself"));
                    }
                    if kind == JointType::Rigid {
                        return Err(self.err(j.kind.span(), format!("{f}.type"), "a rigid joint between two nodes is not supported: let the beams share one node"));
                    }
                    let gap = norm(sub(x0[node], x0[m]));
                    if gap > 1e-9 * size {
                        return Err(self.err(t.span(), ft, format!("node `{}` is {gap} away from `{}`: a hinge joins nodes at the same position", node_names[node], node_names[m])));
                    }
                    Parent::Node(m)
                }
            };
            let hinge = match kind {
                JointType::Rigid => {
                    let why = "only used by hinge joints";
                    self.forbid(&j.axis, &format!("{f}.axis"), why)?;
                    for (v, k) in [
                        (&j.stiffness, "stiffness"),
                        (&j.damping, "damping"),
                        (&j.lock_angle, "lock_angle"),
                        (&j.lock_time, "lock_time"),
                        (&j.initial_rate, "initial_rate"),
                    ] {
                        self.forbid(v, &format!("{f}.{k}"), why)?;
                    }
                    None
                }
                JointType::Hinge => {
                    let fa = format!("{f}.axis");
                    let axis = self.unit(
                        self.required(&j.axis, span.clone(), &fa, " (a hinge needs an axis)")?,
                        &fa,
                    )?;
                    let axis_local = match parent {
                        Parent::Body(Some(b)) => mat_t_vec(&bodies[b].body.r0, axis),
                        _ => axis,
                    };
                    let opt_nn = |v: &Option<Spanned<Num>>, k: &str| -> Result<Option<f64>> {
                        v.as_ref()
                            .map(|v| self.non_negative(v, &format!("{f}.{k}")))
                            .transpose()
                    };
                    hinges.push(HingeDraft {
                        name: name.clone(),
                        axis_local,
                        stiffness: opt_nn(&j.stiffness, "stiffness")?.unwrap_or(0.0),
                        damping: opt_nn(&j.damping, "damping")?.unwrap_or(0.0),
                        lock_angle: self.opt_num(&j.lock_angle, &format!("{f}.lock_angle"))?,
                        lock_time: opt_nn(&j.lock_time, "lock_time")?,
                        v0: self
                            .opt_num(&j.initial_rate, &format!("{f}.initial_rate"))?
                            .unwrap_or(0.0),
                        v0_explicit: j.initial_rate.is_some(),
                    });
                    Some(hinges.len() - 1)
                }
            };
            joint_at.insert(node, drafts.len());
            drafts.push(JointDraft {
                node,
                parent,
                hinge,
            });
            names.push(name);
            joint_hinge.push(hinge);
        }
        // node-to-node chains must end at a node that is not itself hinged to another
        for (i, d) in drafts.iter().enumerate() {
            let mut chain = vec![d.node];
            let mut cur = d;
            while let Parent::Node(m) = cur.parent {
                chain.push(m);
                if chain.len() > drafts.len() + 1 {
                    // a cycle not through d: reported when its own joint comes up
                    break;
                }
                if m == d.node {
                    let path: Vec<&str> = chain.iter().map(|&n| node_names[n].as_str()).collect();
                    let t = spec.joints[i]
                        .get_ref()
                        .to_node
                        .as_ref()
                        .map_or(spec.joints[i].span(), |t| t.span());
                    return Err(self.err(
                        t,
                        format!("joints[{i}].to_node"),
                        format!("joints form a cycle: {}", path.join(" -> ")),
                    ));
                }
                match joint_at.get(&m) {
                    Some(&next) => cur = &drafts[next],
                    None => break,
                }
            }
        }
        Ok((drafts, hinges, names, joint_hinge))
    }

    #[allow(clippy::too_many_arguments)]
    fn sensors(
        &self,
        spec: &Spec,
        node_names: &Names,
        beams: &[Beam],
        body_names: &Names,
        body_dofs: &[Vec<BodyDofRef>],
        joint_names: &Names,
        joint_hinge: &[Option<usize>],
    ) -> Result<Vec<Sensor>> {
        let beam_names = Names::from_list(beams.iter().map(|b| b.name.clone()).collect());
        let mut out: Vec<Sensor> = Vec::new();
        let mut sensor_names = HashSet::new();
        for (i, ss) in spec.sensors.iter().enumerate() {
            let f = format!("sensors[{i}]");
            let span = ss.span();
            let s = ss.get_ref();
            let name = self.name(&s.name, &format!("{f}.name"))?;
            // a name every output format can hold (HDF5 link, CSV column), checked here
            // so `check` rejects it rather than the writer after the run
            crate::output::check_output_name(&name)
                .map_err(|e| self.err(s.name.span(), format!("{f}.name"), e))?;
            if !sensor_names.insert(name.clone()) {
                return Err(self.err(
                    s.name.span(),
                    format!("{f}.name"),
                    format!("duplicate sensor name `{name}`"),
                ));
            }
            let kind = *s.kind.get_ref();
            let present = [
                ("node", s.node.as_ref().map(|x| x.span())),
                ("beam", s.beam.as_ref().map(|x| x.span())),
                ("at", s.at.as_ref().map(|x| x.span())),
                ("component", s.component.as_ref().map(|x| x.span())),
                ("joint", s.joint.as_ref().map(|x| x.span())),
                ("body", s.body.as_ref().map(|x| x.span())),
                ("direction", s.direction.as_ref().map(|x| x.span())),
                ("dof", s.dof.as_ref().map(|x| x.span())),
                ("frame", s.frame.as_ref().map(|x| x.span())),
            ];
            let allowed: &[&str] = match kind {
                SensorType::Node | SensorType::Position => &["node"],
                SensorType::Section => &["beam", "at", "component", "frame"],
                SensorType::Hinge => &["joint"],
                SensorType::Body => &["body"],
                SensorType::Direction => &["node", "direction"],
                SensorType::Energy => &[],
                SensorType::Driver => &["body", "dof"],
                SensorType::BeamNodes => &["beam", "component"],
                SensorType::BodyFrame => &["node", "body", "component"],
            };
            for (k, sp) in present {
                if let (Some(sp), false) = (sp, allowed.contains(&k)) {
                    return Err(self.err(
                        sp,
                        format!("{f}.{k}"),
                        format!("not used by sensor type `{}`", kind.as_str()),
                    ));
                }
            }
            // optional keys are not mentioned as needed
            let needed: Vec<&str> = allowed
                .iter()
                .copied()
                .filter(|k| !(kind == SensorType::Section && matches!(*k, "component" | "frame")))
                .collect();
            let why = format!(
                " (sensor type `{}` needs {})",
                kind.as_str(),
                needed.join(", ")
            );
            let node = |fld: &Option<Spanned<String>>| -> Result<usize> {
                let fk = format!("{f}.node");
                self.lookup(
                    node_names,
                    self.required(fld, span.clone(), &fk, &why)?,
                    &fk,
                    "node",
                )
            };
            let kind = match kind {
                SensorType::Node => SensorKind::NodeDisplacement {
                    node: node(&s.node)?,
                },
                SensorType::Position => SensorKind::NodePosition {
                    node: node(&s.node)?,
                },
                SensorType::Direction => {
                    let node = node(&s.node)?;
                    let fd = format!("{f}.direction");
                    let dir =
                        self.unit(self.required(&s.direction, span.clone(), &fd, &why)?, &fd)?;
                    SensorKind::NodeDirection { node, dir }
                }
                SensorType::BodyFrame => {
                    let node = node(&s.node)?;
                    let fb = format!("{f}.body");
                    let body = self.lookup(
                        body_names,
                        self.required(&s.body, span.clone(), &fb, &why)?,
                        &fb,
                        "body",
                    )?;
                    let fc = format!("{f}.component");
                    let c = self.required(&s.component, span.clone(), &fc, &why)?;
                    let axis = self.axis_component(c, &fc, "a body axis")?;
                    SensorKind::BodyFrameDisplacement { node, body, axis }
                }
                SensorType::Body => {
                    let fb = format!("{f}.body");
                    SensorKind::BodyPose {
                        body: self.lookup(
                            body_names,
                            self.required(&s.body, span.clone(), &fb, &why)?,
                            &fb,
                            "body",
                        )?,
                    }
                }
                SensorType::Hinge => {
                    let fj = format!("{f}.joint");
                    let jn = self.required(&s.joint, span.clone(), &fj, &why)?;
                    let j = self.lookup(joint_names, jn, &fj, "joint")?;
                    let hinge = joint_hinge[j].ok_or_else(|| {
                        self.err(
                            jn.span(),
                            &fj,
                            format!("joint `{}` is rigid, not a hinge", jn.get_ref()),
                        )
                    })?;
                    SensorKind::HingeAngle { hinge }
                }
                SensorType::Section => {
                    if let Some(fr) = &s.frame {
                        if fr.get_ref() != "local" {
                            return Err(self.err(
                                fr.span(),
                                format!("{f}.frame"),
                                format!(
                                    "unknown frame `{}` (only `local`, the convected frame of \
                                     the section, is supported)",
                                    fr.get_ref()
                                ),
                            ));
                        }
                    }
                    let fb = format!("{f}.beam");
                    let b = self.lookup(
                        &beam_names,
                        self.required(&s.beam, span.clone(), &fb, &why)?,
                        &fb,
                        "beam",
                    )?;
                    let fa = format!("{f}.at");
                    let at_s = self.required(&s.at, span.clone(), &fa, &why)?;
                    let at = self.num(at_s, &fa)?;
                    if !(0.0..=1.0).contains(&at) {
                        return Err(self.err(
                            at_s.span(),
                            fa,
                            format!(
                                "must be in [0, 1] (fraction of the beam), is {}",
                                super::value_text(at)
                            ),
                        ));
                    }
                    let elems = &beams[b].elements;
                    let n = elems.len() as f64;
                    // The station is evaluated where it was asked for, not snapped to an
                    // element end or midpoint (which reported the root moment, −1.0, for
                    // at = 0.24 on one tip-loaded element whose moment there is −0.76):
                    // within an element the section forces are the element's own fields
                    // at any ξ ∈ [0, 1] (`section_forces`: N, Vy, Vz, T constant, My, Mz
                    // linear in ξ from the Hermite curvature), so the value at ξ is what
                    // the element represents there, exact wherever the element is (tip
                    // loads), and snapping to ξ = 0, ½, 1 only moved the station. With a
                    // distributed load the elements' moments jump at a node, so a station
                    // within 1e-9 of the beam length of a node is put on that node (the
                    // element after it, the last element's end at the tip): round-off in
                    // `at · n` does not choose the element.
                    let pos = at * n;
                    let pos = if (pos - pos.round()).abs() <= 1e-9 * n {
                        pos.round()
                    } else {
                        pos
                    };
                    let k = (pos.floor() as usize).min(elems.len() - 1);
                    let (element, xi) = (elems[k], (pos - k as f64).clamp(0.0, 1.0));
                    match &s.component {
                        None => SensorKind::Section { element, xi },
                        Some(c) => {
                            let component = SECTION_COMPONENTS
                                .iter()
                                .position(|x| x == c.get_ref())
                                .ok_or_else(|| {
                                    self.err(
                                        c.span(),
                                        format!("{f}.component"),
                                        format!(
                                            "unknown component `{}` (one of {})",
                                            c.get_ref(),
                                            SECTION_COMPONENTS.join(", ")
                                        ),
                                    )
                                })?;
                            SensorKind::SectionComponent {
                                element,
                                xi,
                                component,
                            }
                        }
                    }
                }
                SensorType::Energy => SensorKind::Energy,
                SensorType::Driver => {
                    let fb = format!("{f}.body");
                    let bn = self.required(&s.body, span.clone(), &fb, &why)?;
                    let b = self.lookup(body_names, bn, &fb, "body")?;
                    let fd = format!("{f}.dof");
                    let dn = self.required(&s.dof, span.clone(), &fd, &why)?;
                    let k = self.integer(dn, &fd, 0)?;
                    let refs = &body_dofs[b];
                    let r = refs.get(k).ok_or_else(|| {
                        self.err(
                            dn.span(),
                            &fd,
                            format!(
                                "body `{}` has {} dofs (indices from 0), no dof {k}",
                                bn.get_ref(),
                                refs.len()
                            ),
                        )
                    })?;
                    if !r.driven {
                        return Err(self.err(
                            dn.span(),
                            &fd,
                            format!(
                                "dof {k} of body `{}` is free, not driven: a driver sensor \
                                 needs a dof with `drive`",
                                bn.get_ref()
                            ),
                        ));
                    }
                    SensorKind::DriverForce {
                        dof: r.dof,
                        rotational: r.rotational,
                    }
                }
                SensorType::BeamNodes => {
                    let fb = format!("{f}.beam");
                    let b = self.lookup(
                        &beam_names,
                        self.required(&s.beam, span.clone(), &fb, &why)?,
                        &fb,
                        "beam",
                    )?;
                    let fc = format!("{f}.component");
                    let c = self.required(&s.component, span.clone(), &fc, &why)?;
                    let axis = self.axis_component(c, &fc, "a global axis")?;
                    SensorKind::BeamDisplacement {
                        // refined: the nodes of the base mesh (the same components)
                        nodes: beams[b]
                            .nodes
                            .iter()
                            .copied()
                            .step_by(self.refine)
                            .collect(),
                        axis,
                    }
                }
            };
            out.push(Sensor { name, kind });
        }
        Ok(out)
    }

    /// A model with nothing that moves: every verb would "solve" it without doing anything.
    fn nonempty(&self, spec: &Spec) -> Result<()> {
        if spec.beams.is_empty() && spec.bodies.is_empty() {
            return Err(ModelError::file(
                self.file,
                None,
                "model defines nothing to simulate: no [[beams]] and no [[bodies]]",
            ));
        }
        Ok(())
    }

    /// The values a run keeps (the time and every sensor component at every output
    /// sample), checked against the limit before `output_times` or a history allocates.
    fn output_size(&self, spec: &Spec, s: &SolverSettings, sensors: &[Sensor]) -> Result<()> {
        let steps = (s.t_end / s.dt - 1e-9).ceil();
        if steps > self.limits.steps as f64 {
            let sp = spec.solver.as_ref().map(|x| x.get_ref());
            let (field, span) = match sp {
                Some(SolverSpec { dt: Some(v), .. }) => ("solver.dt", v.span()),
                Some(SolverSpec { t_end: Some(v), .. }) => ("solver.t_end", v.span()),
                _ => ("solver", 0..0),
            };
            return Err(self.err(
                span,
                field,
                limits::exceeded(
                    &format!(
                        "time steps of the run (t_end {:e} / dt {:e})",
                        s.t_end, s.dt
                    ),
                    steps,
                    "steps",
                    self.limits.steps,
                ),
            ));
        }
        let dt_out = if s.output_dt > 0.0 { s.output_dt } else { s.dt };
        // as in dynamics::output_times
        let samples = super::types::output_intervals(s.t_end, dt_out) as f64 + 1.0;
        let components: usize = sensors
            .iter()
            .map(|x| crate::sensors::components(&x.kind).len())
            .sum();
        let values = samples * (components as f64 + 1.0);
        if values <= self.limits.output_values as f64 {
            return Ok(());
        }
        let sp = spec.solver.as_ref().map(|x| x.get_ref());
        let (field, span) = match sp {
            Some(SolverSpec {
                output_dt: Some(v), ..
            }) if s.output_dt > 0.0 => ("solver.output_dt", v.span()),
            Some(SolverSpec { dt: Some(v), .. }) => ("solver.dt", v.span()),
            Some(SolverSpec { t_end: Some(v), .. }) => ("solver.t_end", v.span()),
            _ => ("solver", 0..0),
        };
        Err(self.err(
            span,
            field,
            limits::exceeded(
                &format!(
                    "values to keep for the output, {} samples (t_end {:e} / interval {dt_out:e}) × \
                     ({components} sensor components + time)",
                    limits::count(samples),
                    s.t_end
                ),
                values,
                "output_values",
                self.limits.output_values,
            ),
        ))
    }

    fn solver(&self, spec: &Spec) -> Result<SolverSettings> {
        let mut s = SolverSettings::default();
        let Some(sp) = &spec.solver else {
            return Ok(s);
        };
        let solver_span = sp.span();
        let sp = sp.get_ref();
        let f = |k: &str| format!("solver.{k}");
        if let Some(v) = &sp.t_end {
            s.t_end = self.positive(v, &f("t_end"))?;
        }
        if let Some(v) = &sp.dt {
            s.dt = self.positive(v, &f("dt"))?;
        }
        if let Some(v) = &sp.output_dt {
            s.output_dt = self.non_negative(v, &f("output_dt"))?;
        }
        if let Some(v) = &sp.rho_inf {
            s.rho_inf = self.num(v, &f("rho_inf"))?;
            if !(0.0..=1.0).contains(&s.rho_inf) {
                return Err(self.err(
                    v.span(),
                    f("rho_inf"),
                    format!("must be in [0, 1], is {}", super::value_text(s.rho_inf)),
                ));
            }
        }
        if let Some(v) = &sp.tol {
            s.tol = self.positive(v, &f("tol"))?;
            // relative to the largest force term: above 1e-2 an unbalanced force of more
            // than 1 % of it passes (at ≥ 1 the undeformed state "converges" under any
            // load), so such a value is a mistake, not a choice (no warning channel here)
            if s.tol > MAX_TOL {
                return Err(self.err(
                    v.span(),
                    f("tol"),
                    format!(
                        "must be at most {MAX_TOL:e} (a relative residual; {} would accept \
                         states out of equilibrium by more than 1 % of the largest force)",
                        s.tol
                    ),
                ));
            }
        }
        if let Some(v) = &sp.max_iter {
            s.max_iter = self.integer(v, &f("max_iter"), 1)?;
        }
        if let Some(v) = &sp.newton {
            s.modified_newton = match v.get_ref().as_str() {
                "modified" => true,
                "full" => false,
                other => {
                    return Err(self.err(
                        v.span(),
                        f("newton"),
                        format!("must be \"modified\" or \"full\", is \"{other}\""),
                    ))
                }
            };
        }
        if let Some(v) = &sp.dt_min {
            s.dt_min = self.positive(v, &f("dt_min"))?;
        }
        // a run shorter than the smallest step would take no step and report its start
        // as its end
        if s.t_end < s.dt_min {
            let (field, span) = match (&sp.t_end, &sp.dt_min) {
                (Some(v), _) => (f("t_end"), v.span()),
                (None, Some(v)) => (f("dt_min"), v.span()),
                (None, None) => (f("t_end"), solver_span.clone()),
            };
            return Err(self.err(
                span,
                field,
                format!(
                    "t_end = {:e} s is below dt_min = {:e} s, the smallest step: no step \
                     could be taken",
                    s.t_end, s.dt_min
                ),
            ));
        }
        if let Some(v) = &sp.accuracy {
            let a = self.positive(v, &f("accuracy"))?;
            if a > MAX_ACCURACY {
                return Err(self.err(
                    v.span(),
                    f("accuracy"),
                    format!(
                        "must be at most {MAX_ACCURACY}, is {} (a relative error target; \
                         beyond 10 % the numbers are not worth computing)",
                        super::value_text(a)
                    ),
                ));
            }
            if a < accuracy_floor(s.tol) {
                return Err(self.err(v.span(), f("accuracy"), accuracy_below_floor(a, s.tol)));
            }
            s.accuracy = Some(a);
        }
        if let Some(v) = &sp.dt_max {
            s.dt_max = self.positive(v, &f("dt_max"))?;
            if s.dt_max < s.dt {
                return Err(self.err(
                    v.span(),
                    f("dt_max"),
                    format!(
                        "must be at least dt = {}, is {}",
                        super::value_text(s.dt),
                        super::value_text(s.dt_max)
                    ),
                ));
            }
        }
        if let Some(v) = &sp.load_steps {
            s.load_steps = self.integer(v, &f("load_steps"), 1)?;
        }
        if let Some(v) = &sp.rayleigh_alpha {
            s.rayleigh_alpha = self.non_negative(v, &f("rayleigh_alpha"))?;
        }
        if let Some(v) = &sp.rayleigh_beta {
            s.rayleigh_beta = self.non_negative(v, &f("rayleigh_beta"))?;
        }
        Ok(s)
    }
}

/// Saint-Venant torsion constant of a b × h rectangle (series approximation, within
/// about 0.5 % for all aspect ratios).
/// Which equations are angles: the dofs of spins and hinges, and the fixed-axis rotations
/// in the bodies' chains.
fn rotation_equations(
    n_eq: usize,
    dof_eq: &[Option<usize>],
    spins: &[Spin],
    hinges: &[Hinge],
    bodies: &[Body],
) -> Vec<bool> {
    let mut rot_eq = vec![false; n_eq];
    let mut mark = |d: usize| {
        if let Some(e) = dof_eq[d] {
            rot_eq[e] = true;
        }
    };
    for sp in spins {
        sp.dofs.iter().for_each(|&d| mark(d));
    }
    for h in hinges {
        mark(h.dof);
    }
    for b in bodies {
        for l in &b.chain {
            if let ChainLink::RotateFixedAxis { dof, .. } = l {
                mark(*dof);
            }
        }
    }
    rot_eq
}

fn rect_torsion(b: f64, h: f64) -> f64 {
    let (a, c) = if b >= h { (b, h) } else { (h, b) };
    a * c.powi(3) * (1.0 / 3.0 - 0.21 * (c / a) * (1.0 - c.powi(4) / (12.0 * a.powi(4))))
}

/// Largest `[solver] accuracy` (and `--accuracy`): a relative local error target.
pub const MAX_ACCURACY: f64 = 0.1;

/// Smallest accuracy target for a model whose Newton tolerance is `tol`: 100 × tol. Every
/// step's solution carries residual errors of the order of the tolerance, and the
/// time-error estimate stops falling there (measured on the blade, tol = 1e-8: 5.9e-9 at
/// dt = 7.6e-8 s, 6.3e-9 at 4.8e-9 s), so a smaller target cannot be told apart from it
/// and the controller would refine until the step limit (`--accuracy 1e-300` ran a
/// 21-million-step run).
pub fn accuracy_floor(tol: f64) -> f64 {
    100.0 * tol
}

/// The message for a target below [`accuracy_floor`].
pub fn accuracy_below_floor(target: f64, tol: f64) -> String {
    format!(
        "must be at least {:e} (100 × the Newton tolerance [solver] tol = {tol:e}, below which \
         the time-error estimate cannot be told from the solver's residual), is {target:e}; \
         lower `tol` as well for a smaller target",
        accuracy_floor(tol)
    )
}

/// Largest accepted `[solver] tol` (see the check in the solver table).
pub const MAX_TOL: f64 = 1e-2;

/// How far from perpendicular a body's given x and y axes may be [rad]: a table's
/// directions rounded to four digits are within about 1e-4.
const AXES_SLACK: f64 = 1e-3;

/// `x` divided by its largest |component| (unchanged if that is 0 or not finite):
/// divided, not multiplied by the reciprocal, which overflows for a subnormal component
/// (an axis [0, 5e-324, 0] became [NaN, inf, NaN]).
fn scaled_by_largest(x: Vec3) -> Vec3 {
    let big = x.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if big > 0.0 && big.is_finite() {
        x.map(|c| c / big)
    } else {
        x
    }
}

/// The global axis making the largest angle with `x` (ties: x before y before z).
fn least_parallel_axis(x: Vec3) -> Vec3 {
    let mut k = 0;
    for i in 1..3 {
        if x[i].abs() < x[k].abs() {
            k = i;
        }
    }
    let mut e = [0.0; 3];
    e[k] = 1.0;
    e
}

/// Diagonal of the bounding box of the user's nodes and bodies: the length scale for
/// coincidence tolerances.
fn model_size(x0: &[Vec3], bodies: &[BodyDraft]) -> f64 {
    let pts = x0.iter().copied().chain(bodies.iter().map(|b| b.body.x0));
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pts {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let d = norm(sub(hi, lo));
    if d.is_finite() && d > 0.0 {
        d
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CANTILEVER: &str = include_str!("../../models/cantilever.toml");
    const BEND45: &str = include_str!("../../models/bend45.toml");

    fn compile(text: &str) -> Model {
        compile_str(text, "t.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
    }

    fn fails(text: &str) -> ModelError {
        compile_str(text, "t.toml", &[]).expect_err("should not compile")
    }

    fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
        norm(sub(a, b)) <= tol
    }

    /// a straight free-free beam and whatever `extra` adds
    fn with_beam(extra: &str) -> String {
        format!(
            "[sections.s]\nEA = 1\nEIy = 1\nEIz = 1\nGJ = 1\nrhoA = 1\n\
             [[nodes]]\nname = \"a\"\nposition = [0, 0, 0]\n\
             [[nodes]]\nname = \"b\"\nposition = [2, 0, 0]\n\
             [[beams]]\nname = \"bm\"\nfrom = \"a\"\nto = \"b\"\nelements = 2\nsection = \"s\"\n{extra}"
        )
    }

    #[test]
    fn cantilever_mesh_dofs_and_sensors() {
        let m = compile(CANTILEVER);
        assert_eq!(m.name, "cantilever");
        assert_eq!(m.node_names.len(), 9);
        assert_eq!(m.node_names[2], "beam:1");
        assert_eq!(m.node_names[8], "beam:7");
        assert!(close(m.x0[2], [0.125, 0.0, 0.0], 1e-15));
        assert_eq!(m.elements.len(), 8);
        assert_eq!(m.beams[0].nodes[0], 0);
        assert_eq!(*m.beams[0].nodes.last().unwrap(), 1);
        assert_eq!((m.elements[0].n1, m.elements[0].n2), (0, 2));
        assert_eq!((m.elements[7].n1, m.elements[7].n2), (8, 1));
        assert_eq!(
            m.elements[3].frame0, I3,
            "beam along x: local axes are global"
        );
        assert_eq!(m.elements[0].props.eiy, 100.0);
        assert!(matches!(
            m.node_kin[0],
            NodeKin::OnBody {
                body: None,
                hinge: None,
                ..
            }
        ));
        assert!(matches!(
            m.node_kin[1],
            NodeKin::Free {
                trans: [Some(0), Some(1), Some(2)],
                spin: Some(0)
            }
        ));
        assert_eq!(m.spins[0].dofs, [3, 4, 5]);
        assert_eq!(m.dofs.len(), 48);
        assert_eq!(m.n_eq, 48);
        assert_eq!(m.dofs[0].name, "tip.x");
        assert_eq!(m.dofs[5].name, "tip.rz");
        assert!(m.dofs.iter().enumerate().all(|(i, d)| d.eq == Some(i)));
        assert_eq!(m.sensors[0].kind, SensorKind::NodeDisplacement { node: 1 });
        assert_eq!(
            m.sensors[1].kind,
            SensorKind::SectionComponent {
                element: 0,
                xi: 0.0,
                component: 4
            }
        );
        assert_eq!(m.solver.dt, 1e-3);
        assert_eq!(m.params[0], ("L".to_string(), 1.0));
        assert_eq!(m.source, CANTILEVER);
        assert_eq!(m.path, "t.toml");
    }

    #[test]
    fn overrides_replace_parameters_and_unknown_ones_fail() {
        let ov = [
            ("elements".to_string(), 4.0),
            ("P".to_string(), 5.0),
            ("L".to_string(), 2.0),
        ];
        let m = compile_str(CANTILEVER, "c.toml", &ov).unwrap();
        assert_eq!(m.elements.len(), 4);
        assert_eq!(m.loads[0].force, [0.0, 0.0, 5.0]);
        assert_eq!(m.x0[1], [2.0, 0.0, 0.0]);
        assert_eq!(m.param("P"), Some(5.0));
        let e = compile_str(CANTILEVER, "c.toml", &[("Q".to_string(), 1.0)]).unwrap_err();
        assert!(
            e.to_string().contains("`--set Q`") && e.to_string().contains("Q"),
            "{e}"
        );
        // a derived parameter follows its override
        let m = compile_str(BEND45, "b.toml", &[("E".to_string(), 2.0e7)]).unwrap();
        assert_eq!(m.param("G"), Some(1.0e7));
    }

    #[test]
    fn parameter_bounds_reject_values_outside_them_at_the_parameter_line() {
        let text = CANTILEVER.replace(
            "[parameters]\n",
            "[parameters]\nn = { value = 2, min = 1, max = \"2*3\", integer = true }\n",
        );
        let line = text.lines().position(|l| l.starts_with("n = {")).unwrap() + 1;
        assert!(compile_str(&text, "c.toml", &[]).is_ok());
        assert!(compile_str(&text, "c.toml", &[("n".to_string(), 6.0)]).is_ok());
        for (v, what) in [
            (0.0, "is 0, below its minimum 1 (--set n=0)"),
            (7.0, "is 7, above its maximum 6 (--set n=7)"),
            (2.5, "must be a whole number, is 2.5 (--set n=2.5)"),
        ] {
            let e = compile_str(&text, "c.toml", &[("n".to_string(), v)]).unwrap_err();
            assert_eq!(e.line, Some(line), "{e}");
            assert_eq!(e.field.as_deref(), Some("parameters.n"), "{e}");
            assert!(e.message.contains(what), "{e}");
        }
        // the file's own value is checked too, without a --set note
        let bad = text.replace("value = 2,", "value = 9,");
        let e = compile_str(&bad, "c.toml", &[]).unwrap_err();
        assert!(e.message.ends_with("is 9, above its maximum 6"), "{e}");
    }

    #[test]
    fn parse_set_accepts_numbers_and_constant_expressions() {
        assert_eq!(parse_set("P=10").unwrap(), ("P".to_string(), 10.0));
        assert_eq!(parse_set(" dt = 1e-4 ").unwrap(), ("dt".to_string(), 1e-4));
        assert!((parse_set("w=2*pi").unwrap().1 - std::f64::consts::TAU).abs() < 1e-15);
        assert!(parse_set("P").is_err());
        assert!(parse_set("=3").is_err());
        assert!(parse_set("P=abc").is_err());
    }

    #[test]
    fn bend45_nodes_lie_on_the_arc() {
        let m = compile(BEND45);
        let c = [0.0, 100.0, 0.0];
        assert_eq!(m.x0.len(), 9);
        for x in &m.x0 {
            assert!((norm(sub(*x, c)) - 100.0).abs() < 1e-9, "{x:?}");
        }
        let tip = [100.0 * (PI_4).sin(), 100.0 - 100.0 * (PI_4).cos(), 0.0];
        assert!(close(m.x0[1], tip, 1e-12));
        let chord = |e: &Element| norm(sub(m.x0[e.n2], m.x0[e.n1]));
        let l0 = chord(&m.elements[0]);
        assert!((l0 - 2.0 * 100.0 * (PI_4 / 16.0).sin()).abs() < 1e-9);
        for e in &m.elements {
            assert!((chord(e) - l0).abs() < 1e-9);
            let y = col(&e.frame0, 1);
            let mid = scale(add(m.x0[e.n1], m.x0[e.n2]), 0.5);
            assert!(
                dot(y, normalize(sub(c, mid))) > 1.0 - 1e-12,
                "local y points to the centre"
            );
            assert!(close(col(&e.frame0, 2), [0.0, 0.0, 1.0], 1e-12));
        }
        assert!((m.elements[0].props.gj - 5.0e6 * 0.1406).abs() < 1e-6);
        assert_eq!(m.sensors[0].kind, SensorKind::NodePosition { node: 1 });
        assert_eq!(m.solver.load_steps, 20);
    }
    const PI_4: f64 = std::f64::consts::FRAC_PI_4;

    #[test]
    fn section_shapes() {
        let text = |shape: &str| {
            format!(
                "[materials.m]\nE = 2\nG = 1\ndensity = 3\n[sections.s]\n{shape}\nmaterial = \"m\"\n\
                 [[nodes]]\nname = \"a\"\nposition = [0, 0, 0]\n[[nodes]]\nname = \"b\"\nposition = [1, 0, 0]\n\
                 [[beams]]\nname = \"bm\"\nfrom = \"a\"\nto = \"b\"\nelements = 1\nsection = \"s\"\n"
            )
        };
        let pi = std::f64::consts::PI;
        let p = compile(&text(
            "shape = \"tube\"\nouter_diameter = 2\ninner_diameter = 1",
        ))
        .elements[0]
            .props;
        let i = pi * 15.0 / 64.0;
        assert!((p.ea - 2.0 * pi * 3.0 / 4.0).abs() < 1e-12);
        assert!((p.eiy - 2.0 * i).abs() < 1e-12 && (p.eiz - 2.0 * i).abs() < 1e-12);
        assert!((p.gj - 2.0 * i).abs() < 1e-12);
        assert!(
            (p.rho_a - 3.0 * pi * 3.0 / 4.0).abs() < 1e-12 && (p.rho_iy - 3.0 * i).abs() < 1e-12
        );
        let p = compile(&text("shape = \"circle\"\ndiameter = 2")).elements[0].props;
        assert!((p.eiy - 2.0 * pi / 4.0).abs() < 1e-12);
        let p = compile(&text("shape = \"rectangle\"\nwidth = 2\nheight = 1")).elements[0].props;
        assert_eq!(p.ea, 4.0);
        assert!(
            (p.eiy - 2.0 * 2.0 / 12.0).abs() < 1e-12,
            "about y: b h^3/12"
        );
        assert!(
            (p.eiz - 2.0 * 8.0 / 12.0).abs() < 1e-12,
            "about z: h b^3/12"
        );
        assert!((p.rho_iz - 3.0 * 8.0 / 12.0).abs() < 1e-12);
        let j = 2.0 * (1.0 / 3.0 - 0.21 * 0.5 * (1.0 - 1.0 / (12.0 * 16.0)));
        assert!((p.gj - j).abs() < 1e-12);
        // square: the classic 0.1406 a^4 within the series' accuracy
        assert!((rect_torsion(1.0, 1.0) - 0.1406).abs() < 3e-4);
        assert!((rect_torsion(1.0, 10.0) - rect_torsion(10.0, 1.0)).abs() < 1e-12);

        let e = fails(&text(
            "shape = \"tube\"\nouter_diameter = 1\ninner_diameter = 1",
        ));
        assert_eq!(e.field.as_deref(), Some("sections.s.inner_diameter"));
        let e = fails(&text("shape = \"circle\"\ndiameter = 1\nEA = 3"));
        assert_eq!(e.field.as_deref(), Some("sections.s.EA"));
        let e = fails(&text("shape = \"circle\"\nwidth = 1"));
        assert_eq!(e.field.as_deref(), Some("sections.s.width"));
        let e = fails(&text("shape = \"rectangle\"\nwidth = 1"));
        assert_eq!(e.field.as_deref(), Some("sections.s.height"));
    }

    #[test]
    fn body_with_driven_rotation_and_hinged_beam() {
        let m = compile(&with_beam(
            "[parameters]\nw = 2\n\
             [[bodies]]\nname = \"hub\"\nposition = [0, 0, 0]\naxes = [[0, 1, 0], [-1, 0, 0]]\nmass = 3\ninertia = [1, 2, 3]\n\
             [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 0, 2]\ninitial = 0.5\n\
             [[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\ndrive = \"w*t^2\"\n\
             [[joints]]\nname = \"flap\"\nnode = \"a\"\nbody = \"hub\"\ntype = \"hinge\"\naxis = [0, 1, 0]\nstiffness = 5\ninitial_rate = 0.25\n\
             [[sensors]]\nname = \"h\"\ntype = \"hinge\"\njoint = \"flap\"\n",
        ));
        // node dofs: b (6) and bm:1 (6); then hub's two; then the hinge angle
        assert_eq!(m.dofs.len(), 15);
        assert_eq!(m.dofs[12].name, "hub.dofs[0]");
        assert_eq!(m.dofs[12].q0, 0.5);
        assert!(matches!(m.dofs[13].mode, DofMode::Driven(_)));
        assert_eq!(m.dofs[13].eq, None);
        assert_eq!(m.dofs[14].name, "flap.angle");
        assert_eq!(m.dofs[14].eq, Some(13));
        assert_eq!(m.dofs[14].v0, 0.25);
        assert_eq!(m.n_eq, 14);
        let body = &m.bodies[0];
        assert_eq!(
            body.inertia,
            [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
        );
        assert_eq!(
            body.chain,
            vec![
                ChainLink::Translate {
                    dof: 12,
                    dir: [0.0, 0.0, 1.0]
                },
                ChainLink::RotateFixedAxis {
                    dof: 13,
                    axis: [0.0, 0.0, 1.0]
                },
            ]
        );
        assert_eq!(col(&body.r0, 0), [0.0, 1.0, 0.0]);
        assert_eq!(col(&body.r0, 2), [0.0, 0.0, 1.0]);
        let h = &m.hinges[0];
        assert_eq!(h.dof, 14);
        assert_eq!(h.stiffness, 5.0);
        // global y is the body's x axis
        assert!(close(h.axis_local, [1.0, 0.0, 0.0], 1e-15));
        match &m.node_kin[0] {
            NodeKin::OnBody {
                body: Some(0),
                hinge: Some(0),
                s,
                r_rel,
            } => {
                assert_eq!(*s, [0.0; 3]);
                assert_eq!(
                    mat_mul(&body.r0, r_rel),
                    I3,
                    "initial node rotation is identity"
                );
            }
            k => panic!("{k:?}"),
        }
        assert_eq!(m.sensors[0].kind, SensorKind::HingeAngle { hinge: 0 });
        if let DofMode::Driven(f) = &m.dofs[13].mode {
            assert_eq!(f.eval(1.5), [4.5, 6.0, 4.0]);
        }
    }

    #[test]
    fn free_rotation_body_and_node_to_node_hinge() {
        let m = compile(&with_beam(
            "[[nodes]]\nname = \"c\"\nposition = [2, 0, 0]\n\
             [[bodies]]\nname = \"sat\"\nposition = [1, 1, 1]\nmass = 1\ninertia = [[2, 0.1, 0], [0.1, 2, 0], [0, 0, 1]]\n\
             [[bodies.dofs]]\ntype = \"free_rotation\"\ninitial_rate = [0, 0, 3]\n\
             [[joints]]\nname = \"j\"\nnode = \"c\"\nto_node = \"b\"\ntype = \"hinge\"\naxis = [0, 0, 5]\n\
             [[joints]]\nname = \"g\"\nnode = \"a\"\nbody = \"ground\"\ntype = \"rigid\"\n",
        ));
        assert_eq!(m.node_names, ["a", "b", "c", "bm:1"]);
        assert!(matches!(
            m.node_kin[2],
            NodeKin::OnNode {
                master: 1,
                hinge: 0,
                r_rel: I3
            }
        ));
        assert!(matches!(
            m.node_kin[0],
            NodeKin::OnBody {
                body: None,
                hinge: None,
                s: [0.0, 0.0, 0.0],
                r_rel: I3
            }
        ));
        assert_eq!(m.hinges[0].axis_local, [0.0, 0.0, 1.0]);
        // b and bm:1 free (12 dofs, spins 0 and 1), then the body's spin, then the hinge
        assert_eq!(m.spins.len(), 3);
        assert_eq!(m.spins[2].dofs, [12, 13, 14]);
        assert_eq!(m.spins[2].omega0, [0.0, 0.0, 3.0]);
        assert_eq!(
            m.bodies[0].chain[1],
            ChainLink::SpinComponent {
                dof: 13,
                spin: 2,
                k: 1
            }
        );
        assert_eq!(m.hinges[0].dof, 15);
        assert_eq!(m.n_eq, 16);
    }

    #[test]
    fn joint_and_body_errors() {
        let e = fails(&with_beam(
            "[[nodes]]\nname = \"c\"\nposition = [2, 0, 1e-3]\n\
             [[joints]]\nname = \"j\"\nnode = \"c\"\nto_node = \"b\"\ntype = \"hinge\"\naxis = [0, 0, 1]\n",
        ));
        assert_eq!(e.field.as_deref(), Some("joints[0].to_node"), "{e}");
        let e = fails(&with_beam(
            "[[nodes]]\nname = \"c\"\nposition = [2, 0, 0]\n\
             [[joints]]\nname = \"j\"\nnode = \"c\"\nto_node = \"b\"\ntype = \"hinge\"\naxis = [0, 0, 1]\n\
             [[joints]]\nname = \"k\"\nnode = \"b\"\nto_node = \"c\"\ntype = \"hinge\"\naxis = [0, 0, 1]\n",
        ));
        assert!(e.message.contains("cycle"), "{e}");
        let e = fails(&with_beam(
            "[[supports]]\nnode = \"a\"\ntype = \"clamped\"\n\
             [[joints]]\nname = \"j\"\nnode = \"a\"\nbody = \"ground\"\ntype = \"rigid\"\n",
        ));
        assert_eq!(e.field.as_deref(), Some("joints[0].node"));
        let e = fails(&with_beam(
            "[[joints]]\nname = \"j\"\nnode = \"a\"\nbody = \"ground\"\ntype = \"rigid\"\n\
             [[joints]]\nname = \"k\"\nnode = \"a\"\nbody = \"ground\"\ntype = \"rigid\"\n",
        ));
        assert!(e.message.contains("already has joint"), "{e}");
        let e = fails(&with_beam(
            "[[nodes]]\nname = \"lone\"\nposition = [5, 5, 5]\n",
        ));
        assert_eq!(e.field.as_deref(), Some("nodes[2].name"), "{e}");
        let e = fails(&with_beam(
            "[[joints]]\nname = \"j\"\nnode = \"a\"\nbody = \"ground\"\ntype = \"rigid\"\naxis = [1, 0, 0]\n",
        ));
        assert_eq!(e.field.as_deref(), Some("joints[0].axis"));
        let e = fails(&with_beam(
            "[[bodies]]\nname = \"h\"\nmass = 1\n\
             [[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\n\
             [[bodies.dofs]]\ntype = \"translation\"\naxis = [0, 0, 1]\n",
        ));
        assert_eq!(e.field.as_deref(), Some("bodies[0].dofs[1].type"));
        let e = fails(&with_beam(
            "[[bodies]]\nname = \"h\"\n[[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\ndrive = \"t\"\n",
        ));
        assert_eq!(e.field.as_deref(), Some("bodies[0].mass"));
        let e = fails(&with_beam(
            "[[bodies]]\nname = \"h\"\nmass = 1\ninertia = [[1, 2, 0], [0, 1, 0], [0, 0, 1]]\n",
        ));
        assert!(e.message.contains("not symmetric"), "{e}");
        let e = fails(&with_beam(
            "[[bodies]]\nname = \"h\"\nmass = 1\n[[bodies.dofs]]\ntype = \"translation\"\naxis = [1, 0, 0]\ndrive = \"t\"\ninitial = 1\n",
        ));
        assert_eq!(e.field.as_deref(), Some("bodies[0].dofs[0].initial"));
    }

    #[test]
    fn sensor_and_beam_errors() {
        let e = fails(&with_beam("[[sensors]]\nname = \"s\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0.5\ncomponent = \"Mx\"\n"));
        assert_eq!(e.field.as_deref(), Some("sensors[0].component"));
        let e = fails(&with_beam(
            "[[sensors]]\nname = \"s\"\ntype = \"section\"\nbeam = \"bm\"\nat = 1.5\n",
        ));
        assert_eq!(e.field.as_deref(), Some("sensors[0].at"));
        let e = fails(&with_beam(
            "[[sensors]]\nname = \"s\"\ntype = \"node\"\nnode = \"a\"\nbeam = \"bm\"\n",
        ));
        assert_eq!(e.field.as_deref(), Some("sensors[0].beam"));
        let e = fails(&with_beam("[[sensors]]\nname = \"s\"\ntype = \"node\"\n"));
        assert_eq!(e.field.as_deref(), Some("sensors[0].node"));
        let e = fails(&with_beam("[[sensors]]\nname = \"s\"\ntype = \"energy\"\n[[sensors]]\nname = \"s\"\ntype = \"energy\"\n"));
        assert!(e.message.contains("duplicate sensor"), "{e}");
        let e = fails(&with_beam(
            "[[sensors]]\nname = \"s\"\ntype = \"node\"\nnode = \"nowhere\"\n",
        ));
        assert!(e.message.contains("`nowhere`"), "{e}");
        let e = fails(&with_beam(
            "[[loads]]\nnode = \"bm:9\"\nforce = [1, 0, 0]\n",
        ));
        assert_eq!(e.field.as_deref(), Some("loads[0].node"));
        let e = fails(&with_beam("[[beams]]\nname = \"o\"\nfrom = \"a\"\nto = \"b\"\nelements = 1\nsection = \"s\"\norientation = [3, 0, 0]\n"));
        assert_eq!(e.field.as_deref(), Some("beams[1].orientation"));
        let e = fails(&with_beam(
            "[[beams]]\nname = \"o\"\nfrom = \"a\"\nto = \"b\"\nelements = 2.5\nsection = \"s\"\n",
        ));
        assert_eq!(e.field.as_deref(), Some("beams[1].elements"));
        let e = fails(&with_beam("[[beams]]\nname = \"o\"\nfrom = \"a\"\nto = \"b\"\nelements = 1\nsection = \"s\"\narc_center = [0.5, 5, 0]\n"));
        assert_eq!(e.field.as_deref(), Some("beams[1].arc_center"));
        assert!(e.message.contains("equidistant"), "{e}");
        let e = fails(&with_beam("[[beams]]\nname = \"o\"\nfrom = \"a\"\nto = \"b\"\nelements = 3\nsection = \"s\"\narc_center = [1, 0, 0]\n"));
        assert!(e.message.contains("collinear"), "{e}");
        let e = fails(&with_beam(
            "[[beams]]\nname = \"o\"\nfrom = \"a\"\nto = \"a\"\nelements = 3\nsection = \"s\"\n",
        ));
        assert!(e.message.contains("zero-length"), "{e}");
    }

    #[test]
    fn section_sensor_is_evaluated_at_the_requested_station() {
        // two elements: at = 0.2 is ξ = 0.4 of the first, not its midpoint; a station on a
        // node (or within round-off of one) is the start of the element after it
        let m = compile(&with_beam(
            "[[sensors]]\nname = \"s0\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0.2\n\
             [[sensors]]\nname = \"s1\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0.45\n\
             [[sensors]]\nname = \"s2\"\ntype = \"section\"\nbeam = \"bm\"\nat = 1\n\
             [[sensors]]\nname = \"d\"\ntype = \"direction\"\nnode = \"b\"\ndirection = [0, 2, 0]\n\
             [[sensors]]\nname = \"e\"\ntype = \"energy\"\n\
             [[sensors]]\nname = \"s3\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0.4999999999999\n\
             [[sensors]]\nname = \"s4\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0.5\n\
             [[sensors]]\nname = \"s5\"\ntype = \"section\"\nbeam = \"bm\"\nat = 0.75\n",
        ));
        let kinds: Vec<_> = m.sensors.iter().map(|s| s.kind.clone()).collect();
        assert_eq!(
            kinds[0],
            SensorKind::Section {
                element: 0,
                xi: 0.4
            }
        );
        assert_eq!(
            kinds[1],
            SensorKind::Section {
                element: 0,
                xi: 0.9
            }
        );
        for (k, element, xi) in [(5, 1, 0.0), (6, 1, 0.0), (7, 1, 0.5)] {
            assert_eq!(kinds[k], SensorKind::Section { element, xi }, "sensor {k}");
        }
        assert_eq!(
            kinds[2],
            SensorKind::Section {
                element: 1,
                xi: 1.0
            }
        );
        assert_eq!(
            kinds[3],
            SensorKind::NodeDirection {
                node: 1,
                dir: [0.0, 1.0, 0.0]
            }
        );
        assert_eq!(kinds[4], SensorKind::Energy);
        assert_eq!(m.sensor_index("e"), Some(4));
    }
}
