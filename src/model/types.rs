//! The compiled, immutable model: flat arrays in solver vocabulary.
//!
//! `compile()` turns a parsed spec plus parameter values into this. Everything the stages
//! need is here; nothing here changes during a run (per-run state lives in `State`).

use crate::math::{Mat3, Vec3};

/// Cross-section and material data of one beam element, already resolved to numbers.
/// Local axes: x along the element, y = the beam's `orientation` vector made
/// perpendicular to x, z = x × y. `eiy` resists bending about local y (displacement
/// along z), `eiz` bending about local z (displacement along y).
/// Generic over the number type so the element code can read four elements' properties
/// from SIMD lanes (`BeamProps<crate::element::ad::F4>`); the model's are `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamProps<B = f64> {
    pub ea: B,
    pub eiy: B,
    pub eiz: B,
    pub gj: B,
    /// mass per unit length [kg/m]
    pub rho_a: B,
    /// rotary inertia per unit length about local y, ∫ρ z² dA [kg·m]
    pub rho_iy: B,
    /// rotary inertia per unit length about local z, ∫ρ y² dA [kg·m]
    pub rho_iz: B,
}

/// One two-node beam element.
#[derive(Clone, Debug)]
pub struct Element {
    pub n1: usize,
    pub n2: usize,
    pub props: BeamProps,
    /// Initial convected frame T_C0 (columns: x along n1→n2, y, z), in the global frame.
    pub frame0: Mat3,
    /// index of the beam (spec `[[beams]]` entry) this element belongs to
    pub beam: usize,
    /// On an arc (`arc_center`): the angle the element subtends times the arc's axis, in
    /// the element's frame0 components; the arc's section at station ξ stands turned
    /// from the chord by (ξ − ½) times it. Zero on a straight beam.
    pub arc: Vec3,
}

/// A beam as the user wrote it: a chain of elements.
#[derive(Clone, Debug)]
pub struct Beam {
    pub name: String,
    /// element indices from the `from` end to the `to` end
    pub elements: Vec<usize>,
    /// node indices from `from` to `to` (elements.len() + 1 entries)
    pub nodes: Vec<usize>,
}

/// How a scalar coordinate moves: solved for, or prescribed by a time function.
#[derive(Clone, Debug)]
pub enum DofMode {
    Free,
    /// prescribed value q(t), with exact first and second time derivatives
    Driven(crate::model::expr::TimeFunction),
}

/// One scalar generalized coordinate (translation along an axis, an angle, one component
/// of a spin increment). Spin components have no scalar value of their own: their
/// configuration lives in a rotation matrix (see `Spin`).
#[derive(Clone, Debug)]
pub struct Dof {
    pub name: String,
    pub mode: DofMode,
    /// initial value (ignored for spin components) and initial rate
    pub q0: f64,
    pub v0: f64,
    /// the initial rate was given in the file (`initial_rate`): it overrides the rigid
    /// field of `Model::initial_rotation`
    pub v0_explicit: bool,
    /// index among the free dofs (the unknowns), None if driven
    pub eq: Option<usize>,
}

/// Three dofs whose configuration is a rotation matrix updated multiplicatively:
/// R ← exp(skew(Δ)) R, Δ a spatial (global-frame) rotation increment.
#[derive(Clone, Debug)]
pub struct Spin {
    /// dof indices of the x, y, z spatial components
    pub dofs: [usize; 3],
    /// initial angular velocity (global frame)
    pub omega0: Vec3,
}

/// One column of a kinematic chain: the motion produced by a unit rate of one dof.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChainLink {
    /// translation of everything downstream along a fixed global direction
    Translate { dof: usize, dir: Vec3 },
    /// rotation of everything downstream about a fixed global axis through a point that
    /// is itself moved by upstream links (a body's single rotation coordinate)
    RotateFixedAxis { dof: usize, axis: Vec3 },
    /// one spatial component (k = 0, 1, 2) of a spin group, about the body/node origin
    SpinComponent { dof: usize, spin: usize, k: usize },
    /// a revolute hinge; its axis is fixed in the parent (body or master node) frame and
    /// so turns with every upstream rotation. `hinge` indexes `Model::hinges`.
    Hinge { dof: usize, hinge: usize },
}

impl ChainLink {
    /// The coordinate whose rate drives this link.
    pub fn dof(&self) -> usize {
        match *self {
            ChainLink::Translate { dof, .. }
            | ChainLink::RotateFixedAxis { dof, .. }
            | ChainLink::SpinComponent { dof, .. }
            | ChainLink::Hinge { dof, .. } => dof,
        }
    }
}

/// What a body's origin and orientation are made of.
#[derive(Clone, Debug)]
pub struct Body {
    pub name: String,
    /// reference point and orientation in the initial configuration
    pub x0: Vec3,
    pub r0: Mat3,
    pub mass: f64,
    /// centre of mass relative to the reference point, body frame
    pub com: Vec3,
    /// inertia tensor about the centre of mass, body frame
    pub inertia: Mat3,
    /// links in order: translations first, then at most one rotation kind
    pub chain: Vec<ChainLink>,
}

/// How a node's position and orientation are obtained.
#[derive(Clone, Debug)]
pub enum NodeKin {
    /// independent node: 0..3 translation dofs (fixed components stay at the initial
    /// position) and an optional spin group (None = orientation fixed at identity)
    Free {
        trans: [Option<usize>; 3],
        spin: Option<usize>,
    },
    /// rigidly fixed to a body (`body` = None means ground): x = X_B + R_B s,
    /// R_n = R_B R_rel, optionally through a hinge (R_n = R_B Rot(a,θ) R_rel)
    OnBody {
        body: Option<usize>,
        /// attachment point in the body frame, relative to the body reference point
        s: Vec3,
        hinge: Option<usize>,
        /// R_rel such that the initial node rotation is identity
        r_rel: Mat3,
    },
    /// joined to another node by a revolute hinge: same position, R_n = R_m Rot(a,θ) R_rel
    OnNode {
        master: usize,
        hinge: usize,
        r_rel: Mat3,
    },
}

/// Node order with masters before slaves; `None` if the `OnNode` links form a cycle.
/// Each node's master chain is walked once (nodes already placed end the walk), so this
/// is linear in the node count; repeated passes over all nodes were quadratic for a long
/// chain of node-to-node hinges. Roots keep their index order.
pub fn kinematic_order(node_kin: &[NodeKin]) -> Option<Vec<usize>> {
    const NEW: u8 = 0;
    const ON_PATH: u8 = 1;
    const PLACED: u8 = 2;
    let n = node_kin.len();
    let mut mark = vec![NEW; n];
    let mut order = Vec::with_capacity(n);
    let mut path = Vec::new();
    for start in 0..n {
        let mut i = start;
        loop {
            match mark[i] {
                PLACED => break,
                ON_PATH => return None,
                _ => {}
            }
            mark[i] = ON_PATH;
            path.push(i);
            match &node_kin[i] {
                NodeKin::OnNode { master, .. } if *master < n => i = *master,
                NodeKin::OnNode { .. } => return None,
                _ => break,
            }
        }
        while let Some(k) = path.pop() {
            mark[k] = PLACED;
            order.push(k);
        }
    }
    Some(order)
}

/// A revolute hinge: one angle dof about an axis fixed in the parent frame.
#[derive(Clone, Debug)]
pub struct Hinge {
    pub name: String,
    pub dof: usize,
    /// unit axis in the parent's frame (body frame, or master node's rotated frame)
    pub axis_local: Vec3,
    /// rotational spring [N·m/rad] about `angle_ref`, damper [N·m·s/rad]
    pub stiffness: f64,
    pub damping: f64,
    pub angle_ref: f64,
    /// the hinge becomes rigid when its angle reaches `lock_angle` or at `lock_time`
    pub lock_angle: Option<f64>,
    pub lock_time: Option<f64>,
}

impl Hinge {
    /// Whether the hinge angle going from `from` to `to` reaches or crosses its
    /// `lock_angle` (false without one): the one rule of dynamics, paths and statics.
    pub fn reaches_lock_angle(&self, from: f64, to: f64) -> bool {
        self.lock_angle.is_some_and(|la| {
            let (before, now) = (from - la, to - la);
            now == 0.0 || before.signum() != now.signum()
        })
    }
}

/// A dead (non-follower) load on a node, global frame, scaled by the load factor.
#[derive(Clone, Debug)]
pub struct NodeLoad {
    pub node: usize,
    pub force: Vec3,
    pub moment: Vec3,
    /// time factor s(t) on force and moment, applied in dynamics only (statics applies
    /// loads at full value)
    pub scale: Option<crate::model::expr::TimeFunction>,
}

impl NodeLoad {
    /// The time factor, where the load has one and applies something (a load of zero
    /// force and moment has no impulse to miss, whatever its factor does).
    pub fn time_factor(&self) -> Option<&crate::model::expr::TimeFunction> {
        let applies = self.force.iter().chain(&self.moment).any(|c| *c != 0.0);
        self.scale.as_ref().filter(|_| applies)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum SensorKind {
    /// node displacement (3) and rotation vector of R_n (3), global frame
    NodeDisplacement { node: usize },
    /// node position (3), global frame
    NodePosition { node: usize },
    /// section forces at fraction `xi` ∈ [0,1] of element `element`, in the convected frame:
    /// [N, Vy, Vz, T, My, Mz]
    Section { element: usize, xi: f64 },
    /// one component of the above section forces (name from `SECTION_COMPONENTS`)
    SectionComponent {
        element: usize,
        xi: f64,
        component: usize,
    },
    /// hinge angle and rate
    HingeAngle { hinge: usize },
    /// body reference point position (3) and rotation vector (3)
    BodyPose { body: usize },
    /// a node's displacement projected on a global direction (scalar)
    NodeDirection { node: usize, dir: Vec3 },
    /// displacement of a node seen from a body: the change of its position in the body
    /// frame, component `axis` (0, 1, 2 = body x, y, z)
    BodyFrameDisplacement {
        node: usize,
        body: usize,
        axis: usize,
    },
    /// kinetic, strain energy, work of drivers
    Energy,
    /// generalized force the driver of (global) dof `dof` supplies; `rotational`: a
    /// moment [N·m] rather than a force [N]
    DriverForce { dof: usize, rotational: bool },
    /// displacement of each node of a beam (from → to) along global axis `axis` (0, 1, 2)
    BeamDisplacement { nodes: Vec<usize>, axis: usize },
}

pub const SECTION_COMPONENTS: [&str; 6] = ["N", "Vy", "Vz", "T", "My", "Mz"];

#[derive(Clone, Debug)]
pub struct Sensor {
    pub name: String,
    pub kind: SensorKind,
}

/// A last output interval shorter than this share of `output_dt` is merged into the one
/// before it, which then ends at `t_end`: `t_end = 0.01` over `output_dt = 0.0033333333`
/// left a 1e-10 s interval whose step could not be factored (the mass over h² swamps
/// everything), and the run failed (session 48's probe). A grid within 1e-9 of whole
/// intervals was already treated so.
pub const OUTPUT_SLIVER: f64 = 1e-6;

/// Output intervals of a run from 0 to `t_end` sampled every `dt_out` (at least one).
pub fn output_intervals(t_end: f64, dt_out: f64) -> usize {
    (t_end / dt_out - OUTPUT_SLIVER).ceil().max(1.0) as usize
}

/// Time integration and solver settings, from the model's `[solver]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSettings {
    pub t_end: f64,
    pub dt: f64,
    /// output sampling interval (0 = every step)
    pub output_dt: f64,
    /// generalized-α spectral radius at infinite frequency
    pub rho_inf: f64,
    /// Newton: relative residual tolerance and maximum iterations
    pub tol: f64,
    pub max_iter: usize,
    /// Newton Jacobian policy in dynamics: `false` = factorize every iteration (full
    /// Newton); `true` = factorize at the first iteration of a step and reuse it while
    /// the residual contracts at least 4× per iteration (modified Newton)
    pub modified_newton: bool,
    /// smallest step before the run gives up
    pub dt_min: f64,
    /// relative local error target of the adaptive step controller (`None`: fixed steps
    /// of `dt`, cut only where Newton fails); with a target `dt` is the first step
    pub accuracy: Option<f64>,
    /// largest step the controller may take (infinite: bounded by the output grid only)
    pub dt_max: f64,
    /// Rayleigh damping C = alpha M + beta K (element level)
    pub rayleigh_alpha: f64,
    pub rayleigh_beta: f64,
    /// statics: number of initial load steps
    pub load_steps: usize,
    /// most time steps one run may take (`LATDYN_LIMITS` key `steps`): checked against
    /// t_end / dt when the model is compiled, and by `--accuracy` before each run
    pub max_steps: u64,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            t_end: 1.0,
            dt: 1e-3,
            output_dt: 0.0,
            rho_inf: 0.9,
            tol: 1e-8,
            max_iter: 25,
            modified_newton: true,
            dt_min: 1e-9,
            accuracy: None,
            dt_max: f64::INFINITY,
            rayleigh_alpha: 0.0,
            rayleigh_beta: 0.0,
            load_steps: 1,
            max_steps: super::Limits::default().steps,
        }
    }
}

/// The compiled model of one variant.
#[derive(Clone, Debug)]
pub struct Model {
    pub name: String,
    /// path of the model file (for messages) and its full text (stored in output files)
    pub path: String,
    pub source: String,
    /// resolved parameter values, in file order
    pub params: Vec<(String, f64)>,
    pub node_names: Vec<String>,
    /// initial (reference) node positions
    pub x0: Vec<Vec3>,
    pub node_kin: Vec<NodeKin>,
    /// nodes in an order where every `OnNode` master precedes its slaves, so the
    /// kinematics stage resolves them in one allocation-free pass
    pub kin_order: Vec<usize>,
    pub elements: Vec<Element>,
    pub beams: Vec<Beam>,
    pub bodies: Vec<Body>,
    pub dofs: Vec<Dof>,
    pub spins: Vec<Spin>,
    pub hinges: Vec<Hinge>,
    /// the hinge whose angle each dof is (`hinges[h].dof == d`), so that asking whether a
    /// dof is frozen by a locked hinge costs O(1), not a scan of every hinge (which made
    /// the assembly quadratic in the model's size: 270 hinges in the 18-bay Mini-Mast)
    pub hinge_of_dof: Vec<Option<usize>>,
    pub loads: Vec<NodeLoad>,
    pub gravity: Vec3,
    pub sensors: Vec<Sensor>,
    pub solver: SolverSettings,
    /// number of free dofs (unknowns)
    pub n_eq: usize,
    /// `[initial]`: rigid rotation (omega, center) the free dofs start in
    pub initial_rotation: Option<(Vec3, Vec3)>,
    /// `[initial] steady = true`: the run starts in the steady rotation of the model's
    /// constant-speed hub ([`crate::solver::rotating::steady_start`]) instead of the
    /// unstretched reference
    pub initial_steady: bool,
    /// `[initial] consistent_velocity`: `Some(true)`, the free coordinates without an
    /// explicit initial rate start with the velocity that strains nothing
    /// ([`crate::solver::start`]); `None` (not written), the start is checked and a
    /// velocity that strains the structure is warned; `Some(false)`, taken as given
    pub initial_consistent_velocity: Option<bool>,
    /// what each `[[repeat]]` generated (empty for a file without repeats)
    pub repeats: Vec<super::repeat::RepeatSummary>,
    /// each element's undeformed constants (reference frame, chord, length, section) in
    /// the form the element stage reads, parallel to `elements`: compiled once here so
    /// that every run, solver and backend of this model reads the same array
    pub elem_data: Vec<crate::element::ElemData>,
    /// `dofs[d].eq` as a dense array: the scatter reads it for every chain column
    pub dof_eq: Vec<Option<usize>>,
    /// equations that are angles (spins, hinges, body rotations): Newton limits their step
    pub rot_eq: Vec<bool>,
}

impl Model {
    pub fn param(&self, name: &str) -> Option<f64> {
        self.params.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
    pub fn node_index(&self, name: &str) -> Option<usize> {
        self.node_names.iter().position(|n| n == name)
    }
    pub fn sensor_index(&self, name: &str) -> Option<usize> {
        self.sensors.iter().position(|s| s.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on(master: usize) -> NodeKin {
        NodeKin::OnNode {
            master,
            hinge: 0,
            r_rel: crate::math::I3,
        }
    }

    fn root() -> NodeKin {
        NodeKin::Free {
            trans: [None; 3],
            spin: None,
        }
    }

    #[test]
    fn kinematic_order_puts_masters_first_and_finds_cycles() {
        // 3 -> 1 -> 4 -> 0 (root), 2 root
        let kin = vec![root(), on(4), root(), on(1), on(0)];
        let order = kinematic_order(&kin).unwrap();
        assert_eq!(order.len(), 5);
        let pos = |k: usize| order.iter().position(|&x| x == k).unwrap();
        assert!(pos(0) < pos(4) && pos(4) < pos(1) && pos(1) < pos(3));
        assert!(kinematic_order(&[on(1), on(2), on(1)]).is_none());
        assert!(kinematic_order(&[on(0)]).is_none());
        // a chain of 200 000 hinged nodes: one walk, not one pass per link
        let long: Vec<NodeKin> = std::iter::once(root())
            .chain((1..200_000).map(|k| on(k - 1)))
            .collect();
        assert_eq!(kinematic_order(&long).unwrap().len(), 200_000);
    }
}
