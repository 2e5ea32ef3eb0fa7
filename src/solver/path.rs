//! Quasi-static path following: equilibrium states along a one-parameter family, through
//! limit points and snap-backs.
//!
//! The path parameter μ is either the load factor on the model's loads (loads × μ, as in
//! `statics` load stepping) or the pseudo-time of the drivers (every drive expression
//! evaluated at t = μ, loads at full value, no inertia). Continuation is Crisfield's
//! spherical arc-length method: each step travels a distance Δs in (Δu, ψΔμ), with ψ² the
//! squared size of the first tangent du/dμ so that both parts weigh alike at the start.
//! The corrector solves the quadratic constraint for δμ every iteration and keeps the root
//! whose increment is closest in direction to the step so far (Crisfield 1981 / 1991
//! §9.4.2); the predictor's sign follows the previous step (Feng's criterion: the tangent's
//! projection on the last increment), which turns μ back at a limit point and carries the
//! path around a snap-back. Δs adapts to the Newton iteration counts (Δs·√(I_d/I)).
//!
//! Indicators per converged point: the sign of det K (from a sparse LU, see
//! [`crate::linalg::SparseLuSymbolic::det_sign`]). A limit point is a sign change of Δμ
//! between consecutive steps; a sign change of det K without one is a bifurcation point
//! (an odd number of eigenvalues crossed zero with the load still rising).

use super::linear::{norm_inf, Convergence, NewtonSystem};
use super::statics::{self, StaticsError, MAX_NEWTON_ANGLE};
use crate::assembly::{Assembler, Coeffs};
use crate::joint::{self, State};
use crate::model::{DofMode, Model};
use crate::sensors;

/// What the path parameter μ scales.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    /// loads × μ (drivers at t = 0)
    Load,
    /// drive expressions at t = μ, loads at full value
    Drivers,
}

impl Control {
    pub fn label(self) -> &'static str {
        match self {
            Control::Load => "load",
            Control::Drivers => "drivers",
        }
    }
}

/// A stop criterion on one sensor component: the path ends where the component crosses
/// `value` (the crossing point itself is the last one, located by a secant on μ).
#[derive(Clone, Debug)]
pub struct Until {
    pub sensor: usize,
    pub component: usize,
    pub value: f64,
    /// as the user wrote it, for messages
    pub text: String,
}

#[derive(Clone, Debug)]
pub struct PathOptions {
    pub control: Control,
    /// the path ends on μ = max_param (landed on exactly) when it gets there
    pub max_param: f64,
    /// largest total arc length (in the scaled (u, ψμ) norm)
    pub max_length: f64,
    /// most converged points (including the start)
    pub max_points: usize,
    /// first Δμ (the first arc length follows from it)
    pub first_step: f64,
    /// largest arc length as a multiple of the first
    pub max_growth: f64,
    pub until: Option<Until>,
    /// end the path at its K-th limit point (the first point past it)
    pub limit_points: Option<usize>,
    /// set from outside (a signal): the path ends before its next step, `stopped_by`
    /// "interrupted", with the points so far
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

impl PathOptions {
    /// Whether [`Self::stop`] is set.
    fn stopped(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst))
    }

    /// Options ending the path at μ = `max_param`, with the first step of
    /// [`PathOptions::with_scale`] for the control's natural scale: 1 for the load factor
    /// (the loads as written), `max_param` for the drivers (their pseudo-time ends at
    /// t_end by default; [`crate::solver::path`]'s callers that know t_end pass it).
    pub fn new(control: Control, max_param: f64) -> PathOptions {
        let scale = match control {
            Control::Load => 1.0,
            Control::Drivers if max_param.is_finite() => max_param,
            Control::Drivers => 1.0,
        };
        PathOptions::with_scale(control, max_param, scale)
    }

    /// [`PathOptions::new`] with the natural scale of μ given: the first step is 2 % of
    /// `max_param` or of `scale`, whichever is smaller. `max_param` is where the user
    /// wants the path to stop, not how far the structure can be pushed in one step: with
    /// `--lambda-max 1e15` (in effect "no bound", stopping on `--max-points` or
    /// `--until`) a first step of 2e13 load factors was hopeless and 30 halvings did not
    /// bring it down to anything that converges. The scale of the load factor is that of
    /// the loads as written (λ = 1), so a large bound starts as an unbounded path does
    /// (Δλ = 0.02), and a bound ≤ `scale` (the default λ_max = 1, or a smaller one) keeps
    /// its 2 % exactly as before. Later steps grow by the arc-length control.
    pub fn with_scale(control: Control, max_param: f64, scale: f64) -> PathOptions {
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        PathOptions {
            control,
            max_param,
            max_length: f64::INFINITY,
            max_points: 2000,
            first_step: 0.02 * max_param.min(scale),
            max_growth: 4.0,
            until: None,
            limit_points: None,
            stop: None,
        }
    }
}

/// The control a model's path follows by default: the drivers when a drive changes over
/// [0, t_end], else the load factor.
pub fn default_control(model: &Model) -> Control {
    let t1 = model.solver.t_end;
    let moves = model.dofs.iter().any(|d| match &d.mode {
        DofMode::Driven(f) => f.eval(0.0)[0] != f.eval(t1)[0],
        _ => false,
    });
    if moves {
        Control::Drivers
    } else {
        Control::Load
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct LimitPoint {
    /// index of the path point nearest the fold (the one before Δμ turned)
    pub index: usize,
    pub lambda: f64,
    /// "max" (μ stops rising) or "min" (μ stops falling)
    pub kind: &'static str,
    /// the extremum of the parabola λ(s) through this point and its two neighbours on
    /// the path (s = arc length): the fold located between the path points
    pub lambda_fit: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Bifurcation {
    /// the first point with the new determinant sign
    pub index: usize,
    pub lambda: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("{0}")]
    Statics(#[from] StaticsError),
    #[error(
        "path: zero-stiffness motion at {what} = {mu:.6} that the drivers do not fix \
         (coordinate: share) {motions}; a mechanism needs its drivers (or supports, a hinge \
         stiffness) to determine every coordinate"
    )]
    Mechanism {
        what: &'static str,
        mu: f64,
        motions: String,
    },
    #[error(
        "path: no arc length down to {ds:.3e} converges at {what} = {mu:.6} after {points} \
         points ({iterations} Newton iterations; worst residual {residual:.3e} at dof `{dof}`)"
    )]
    Stalled {
        what: &'static str,
        mu: f64,
        ds: f64,
        points: usize,
        iterations: usize,
        residual: f64,
        dof: String,
    },
    /// The first step (plain Newton at μ = first step from the start) did not converge
    /// even halved [`MAX_HALVINGS`] times: the path has only its start.
    #[error(
        "path: no first step converged: plain Newton from the start at {what} = {first:.3e} \
         and at each of {halvings} halvings down to {smallest:.3e} failed, so the path has \
         only its start; give a smaller --first-step, and check that the model's loads or \
         drives are what you meant"
    )]
    FirstStep {
        what: &'static str,
        first: f64,
        smallest: f64,
        halvings: i32,
    },
    #[error("path: {0}")]
    Input(String),
    #[error("linear solver: {0}")]
    Linear(#[from] crate::linalg::LinalgError),
}

/// The computed path. On a failure part-way, the points so far and the error.
pub struct PathResult {
    pub control: Control,
    pub lambda: Vec<f64>,
    /// [point][sensor][component]
    pub sensors: Vec<Vec<Vec<f64>>>,
    /// sign of det K at each point (0: exactly singular)
    pub det_sign: Vec<i8>,
    /// Newton iterations of the step that reached each point (0 for the start)
    pub iterations: Vec<usize>,
    /// arc length travelled to each point
    pub arc: Vec<f64>,
    pub limit_points: Vec<LimitPoint>,
    pub bifurcations: Vec<Bifurcation>,
    pub rejected_steps: usize,
    pub newton_iterations: usize,
    /// why the path ended: "max_param", "until", "max_length", "max_points",
    /// "limit_points", "interrupted", "error"
    pub stopped_by: &'static str,
    /// hinges locked along the path: (hinge index, point index)
    pub locks: Vec<(usize, usize)>,
    pub error: Option<PathError>,
    pub state: State,
    /// the most deformed element over the path's points: (point index, its λ, the angle)
    /// (see [`crate::assembly::largest_deformation_angle`])
    pub largest_deformation: Option<(usize, f64, crate::assembly::DeformationAngle)>,
    /// driver control over a pseudo-time in which no drive changes: every point is the
    /// same equilibrium (warned)
    pub drives_still: bool,
}

impl PathResult {
    /// Whether the path was stopped from outside before it ended ([`PathOptions::stop`]).
    pub fn interrupted(&self) -> bool {
        self.stopped_by == "interrupted"
    }

    /// The error that ended the path, or why it stopped early; empty for a path that
    /// ended as asked.
    pub fn message(&self) -> String {
        match &self.error {
            Some(e) => e.to_string(),
            None if self.interrupted() => {
                "interrupted (SIGINT, SIGTERM or SIGHUP) before its end: the points so far".into()
            }
            None => String::new(),
        }
    }

    /// Warnings about the path's numbers: the small-deformation check of plain statics
    /// at the most deformed of its points (after a snap-back that need not be the last
    /// one; a failed path is checked over the points it reached), named by its index
    /// and λ.
    pub fn warnings(&self) -> Vec<String> {
        let still = self.drives_still.then(|| {
            "--control drivers, but no drive changes over the path's pseudo-time: every \
             point holds the same drives and the full loads (--control load follows the \
             loads instead)"
                .to_string()
        });
        let deformed = self
            .largest_deformation
            .as_ref()
            .and_then(|(k, lambda, d)| {
                d.warning(None).map(|w| {
                    format!(
                        "at path point {k} of {} (λ = {lambda:.6e}): {w}",
                        self.lambda.len()
                    )
                })
            });
        // a path that ran out of points ended where it was, not where asked
        // (`--first-step 1e-300`: 2 000 points at λ = 1e-300, reported as completed)
        let short = (self.stopped_by == "max_points").then(|| {
            format!(
                "the path stopped at its point limit ({} points, arc length {:.3e}) at \
                 λ = {:.6e}, before the end asked for: raise --max-points, or --first-step \
                 if the steps stayed small",
                self.lambda.len(),
                self.arc.last().copied().unwrap_or(0.0),
                self.lambda.last().copied().unwrap_or(0.0),
            )
        });
        still.into_iter().chain(deformed).chain(short).collect()
    }
}

/// Whether some driven coordinate takes another value somewhere in (0, `until`]
/// (sampled at 256 points, and at t_end and `until`): otherwise a path under driver
/// control has nothing to follow.
fn drives_change(model: &Model, until: f64) -> bool {
    let end = if until.is_finite() && until > 0.0 {
        until
    } else {
        model.solver.t_end
    };
    let mut times: Vec<f64> = (1..=256).map(|k| end * k as f64 / 256.0).collect();
    times.push(model.solver.t_end);
    model.dofs.iter().any(|d| match &d.mode {
        DofMode::Driven(f) => {
            let v0 = f.eval(0.0)[0];
            times.iter().any(|&t| f.eval(t)[0] != v0)
        }
        _ => false,
    })
}

/// Newton iterations a step aims at: the arc length grows after easier steps and shrinks
/// after harder ones by √(target / used) (Crisfield's rule).
const TARGET_ITERATIONS: f64 = 5.0;
/// Corrector iterations before a step is cut.
const MAX_CORRECTOR: usize = 15;
/// Halvings of the arc length below the first one before the path stalls.
const MAX_HALVINGS: i32 = 30;

struct Ctx<'a> {
    model: &'a Model,
    asm: Assembler,
    sys: NewtonSystem,
    control: Control,
}

impl Ctx<'_> {
    fn load_factor(&self, mu: f64) -> f64 {
        match self.control {
            Control::Load => mu,
            Control::Drivers => 1.0,
        }
    }

    /// Put the state at parameter μ (drivers) and refresh its kinematics.
    fn place(&self, s: &mut State, mu: f64) {
        if self.control == Control::Drivers {
            joint::apply_drivers(self.model, s, mu);
            // statics: the drivers' rates mean nothing here
            s.v.iter_mut().for_each(|v| *v = 0.0);
            s.a.iter_mut().for_each(|a| *a = 0.0);
        }
        joint::update_kinematics(self.model, s);
    }

    /// Residual (and factored tangent when `factor`) at (s, μ); the state is placed.
    fn eval(
        &mut self,
        s: &mut State,
        mu: f64,
        factor: bool,
    ) -> Result<crate::assembly::AssemblyInfo, crate::linalg::LinalgError> {
        self.place(s, mu);
        let c = Coeffs::statics(self.load_factor(mu));
        self.sys.evaluate(self.model, &self.asm, s, c, factor)
    }

    /// ∂r/∂μ at (s, μ), by equation, given `sys.r` = r(s, μ). Loads: exactly r(μ+1) − r(μ)
    /// (the residual is linear in the load factor). Drivers: a central difference over ±h
    /// in the pseudo-time; its O(h²) error only slows the corrector's convergence in μ,
    /// never the equilibrium it converges to. (A forward difference, one evaluation less,
    /// saved 4 % of the Mini-Mast path's time and moved its points near the fold.)
    /// Leaves `sys.r` as the residual at (s, μ).
    fn dr_dmu(&mut self, s: &mut State, mu: f64, h: f64) -> Vec<f64> {
        let r0 = self.sys.r.clone();
        let g = match self.control {
            Control::Load => {
                let c = Coeffs::statics(mu + 1.0);
                let _ = self.sys.evaluate(self.model, &self.asm, s, c, false);
                self.sys.r.iter().zip(&r0).map(|(a, b)| a - b).collect()
            }
            Control::Drivers => {
                let mut t = s.clone();
                let _ = self.eval(&mut t, mu + h, false);
                let rp = self.sys.r.clone();
                let _ = self.eval(&mut t, mu - h, false);
                rp.iter()
                    .zip(&self.sys.r)
                    .map(|(a, b)| (a - b) / (2.0 * h))
                    .collect()
            }
        };
        self.sys.r = r0;
        g
    }

    fn sample(&mut self, s: &mut State, mu: f64) -> Vec<Vec<f64>> {
        let model = self.model;
        self.place(s, mu);
        let mut gen = vec![0.0; model.dofs.len()];
        let lf = self.load_factor(mu);
        let info = self
            .asm
            .evaluate(model, s, Coeffs::statics(lf), &mut gen, None);
        let en = super::static_energies(model, s, lf, &info);
        model
            .sensors
            .iter()
            .map(|sn| sensors::sample(model, s, &sn.kind, &en, &gen))
            .collect()
    }

    /// Plain Newton at fixed μ (the last point landed on max_param, re-equilibration after
    /// a hinge locked). Some(iterations) when converged.
    fn newton_fixed(&mut self, s: &mut State, mu: f64) -> Result<Option<usize>, StaticsError> {
        self.place(s, mu);
        let lf = self.load_factor(mu);
        statics::newton(self.model, &self.asm, &mut self.sys, s, lf, None)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Follow the equilibrium path of `model` from its reference state (drivers at μ = 0).
pub fn follow(model: &Model, opts: &PathOptions) -> PathResult {
    let mut s = State::new(model);
    let mut res = PathResult {
        control: opts.control,
        lambda: Vec::new(),
        sensors: Vec::new(),
        det_sign: Vec::new(),
        iterations: Vec::new(),
        arc: Vec::new(),
        limit_points: Vec::new(),
        bifurcations: Vec::new(),
        rejected_steps: 0,
        newton_iterations: 0,
        stopped_by: "error",
        locks: Vec::new(),
        error: None,
        state: s.clone(),
        largest_deformation: None,
        drives_still: opts.control == Control::Drivers && !drives_change(model, opts.max_param),
    };
    // stopped before it began (a signal while other variants ran): no point at all,
    // not a first step taken after the signal
    if opts.stopped() {
        res.stopped_by = "interrupted";
        return res;
    }
    if let Err(e) = follow_into(model, opts, &mut s, &mut res) {
        res.stopped_by = "error";
        res.error = Some(e);
    }
    for lp in &mut res.limit_points {
        let i = lp.index;
        if i >= 1 && i + 1 < res.lambda.len() {
            let (s, l) = (&res.arc[i - 1..=i + 1], &res.lambda[i - 1..=i + 1]);
            if let Some(v) = parabola_extremum(s, l) {
                lp.lambda_fit = v;
            }
        }
    }
    // the fold lies between two path points, so the determinant's sign changes within a
    // point of it: that is the limit point itself, not a bifurcation
    let folds: Vec<usize> = res.limit_points.iter().map(|l| l.index).collect();
    res.bifurcations
        .retain(|b| !folds.iter().any(|&f| b.index + 1 >= f && b.index <= f + 1));
    res.state = s;
    res
}

fn follow_into(
    model: &Model,
    opts: &PathOptions,
    s: &mut State,
    res: &mut PathResult,
) -> Result<(), PathError> {
    if opts.max_param.is_nan() || opts.max_param <= 0.0 {
        return Err(PathError::Input(format!(
            "the largest path parameter must be positive, got {}",
            opts.max_param
        )));
    }
    if !(opts.first_step.is_finite() && opts.first_step > 0.0) {
        return Err(PathError::Input(format!(
            "the first step must be finite and positive, got {}",
            opts.first_step
        )));
    }
    let what = match opts.control {
        Control::Load => "load factor",
        Control::Drivers => "pseudo-time",
    };
    if opts.control == Control::Drivers {
        if let Some(msg) = joint::non_finite_input(model, 0.0) {
            return Err(PathError::Input(msg));
        }
    }
    let asm = Assembler::new(model);
    let sys = NewtonSystem::new(model, &asm, s)?;
    let mut cx = Ctx {
        model,
        asm,
        sys,
        control: opts.control,
    };
    // central-difference step in the pseudo-time: ~ε^(1/3) of the step scale
    let h_fd = 1e-5 * opts.first_step.max(f64::MIN_POSITIVE);

    // the start: drivers mode first brings the full loads on at μ = 0 (plain statics)
    let mut mu = 0.0;
    cx.place(s, mu);
    if opts.control == Control::Drivers {
        let mut at0 = model_at(model, s);
        let rep = statics::solve(model, &mut at0).map_err(|e| match e {
            StaticsError::FreeMotion { motions, .. } => PathError::Mechanism {
                what,
                mu: 0.0,
                motions,
            },
            e => PathError::Statics(e),
        })?;
        res.newton_iterations += rep.newton_iterations;
        *s = at0;
        cx.place(s, mu);
    }
    if cx.eval(s, mu, true).is_err() {
        return Err(mechanism(model, s, cx.load_factor(mu), what, mu)?);
    }
    let push = |cx: &mut Ctx, s: &mut State, res: &mut PathResult, mu: f64, it: usize, arc: f64| {
        let vals = cx.sample(s, mu);
        res.lambda.push(mu);
        res.sensors.push(vals);
        res.iterations.push(it);
        res.arc.push(arc);
        // a state the path passes through can be more deformed than its end (a snap-back)
        if let Some(d) = crate::assembly::largest_deformation_angle(cx.model, s) {
            if d.exceeds(res.largest_deformation.as_ref().map(|(_, _, w)| w)) {
                res.largest_deformation = Some((res.lambda.len() - 1, mu, d));
            }
        }
    };
    push(&mut cx, s, res, mu, 0, 0.0);
    let mut prev_sign = det_sign(&mut cx, s, mu);
    res.det_sign.push(prev_sign);

    // The first step is natural-parameter continuation: plain Newton at μ = first_step
    // from the tangent prediction. Its secant fixes the scaling ψ (|Δu|/Δμ) and the first
    // arc length. The tangent at μ = 0 would not do: a drive that starts smoothly (zero
    // rate at t = 0, as the Mini-Mast stroke) has du/dμ = 0 there.
    let g = cx.dr_dmu(s, mu, h_fd);
    let mut ut: Vec<f64> = g.iter().map(|x| -x).collect();
    cx.sys.solve_tangent(&mut ut)?;
    if !dot(&ut, &ut).is_finite() {
        return Err(mechanism(model, s, cx.load_factor(mu), what, mu)?);
    }
    let start = s.clone();
    let mut dmu0 = opts.first_step.min(opts.max_param);
    let mut halvings = 0;
    loop {
        let mut pred: Vec<f64> = ut.iter().map(|x| x * dmu0).collect();
        crate::assembly::limit_rotation_step(cx.model, &mut pred, MAX_NEWTON_ANGLE);
        joint::apply_increment(model, s, &pred);
        if let Some(it) = cx.newton_fixed(s, dmu0)? {
            res.newton_iterations += it;
            break;
        }
        s.clone_from(&start);
        res.rejected_steps += 1;
        dmu0 *= 0.5;
        halvings += 1;
        if halvings > MAX_HALVINGS {
            // not `Stalled`: its worst residual would be that of the untouched start
            // (λ = 0, residual 0), which says nothing about why the step failed
            s.clone_from(&start);
            cx.place(s, 0.0);
            return Err(PathError::FirstStep {
                what,
                first: opts.first_step.min(opts.max_param),
                smallest: dmu0 * 2.0,
                halvings: MAX_HALVINGS,
            });
        }
    }
    let du0 = state_diff(model, &start, s);
    let du2 = dot(&du0, &du0);
    let psi2 = if du2 > 0.0 { du2 / (dmu0 * dmu0) } else { 1.0 };
    let ds0 = (du2 + psi2 * dmu0 * dmu0).sqrt();
    mu = dmu0;
    let mut arc = ds0;
    push(&mut cx, s, res, mu, 0, arc);
    let sg = det_sign(&mut cx, s, mu);
    res.det_sign.push(sg);
    if sg != 0 {
        prev_sign = sg;
    }
    let mut ds = ds0;
    // largest arc length: that of a step of max_growth × first_step along the current
    // tangent, and at least max_growth × the first one. A drive that starts smoothly makes
    // the first step tiny in u (du/dλ = 0 at t = 0), so a bound fixed by it alone would
    // hold the whole stroke to tiny steps.
    let ds_floor = opts.max_growth * ds0;
    let ds_min = ds0 * 0.5f64.powi(MAX_HALVINGS);
    // previous accepted increment (Δu, Δμ), for the predictor's sign and the root choice
    let mut prev_du: Vec<f64> = du0;
    let mut prev_dmu = dmu0;
    let mut prev_dir = 1.0f64;
    let mut until_prev = opts
        .until
        .as_ref()
        .map(|u| res.sensors[0][u.sensor][u.component] - u.value);
    if mu >= opts.max_param {
        res.stopped_by = "max_param";
        return Ok(());
    }

    loop {
        if opts.stopped() {
            res.stopped_by = "interrupted";
            return Ok(());
        }
        if res.lambda.len() >= opts.max_points {
            res.stopped_by = "max_points";
            return Ok(());
        }
        if arc >= opts.max_length {
            res.stopped_by = "max_length";
            return Ok(());
        }
        // tangent at the converged point
        if cx.eval(s, mu, true).is_err() {
            return Err(mechanism(model, s, cx.load_factor(mu), what, mu)?);
        }
        let g = cx.dr_dmu(s, mu, h_fd);
        let mut ut: Vec<f64> = g.iter().map(|x| -x).collect();
        cx.sys.solve_tangent(&mut ut)?;
        let ds_max =
            ds_floor.max(opts.max_growth * opts.first_step * (dot(&ut, &ut) + psi2).sqrt());
        if ds_max.is_finite() {
            ds = ds.min(ds_max);
        }
        // Feng: keep going the way the last step went
        let orient = dot(&ut, &prev_du) + psi2 * prev_dmu;
        let sign = if orient < 0.0 { -1.0 } else { 1.0 };
        let saved = s.clone();
        let mut step = None;
        while step.is_none() {
            let dmu_pred = sign * ds / (dot(&ut, &ut) + psi2).sqrt();
            match corrector(&mut cx, s, mu, &ut, dmu_pred, ds, psi2, h_fd)? {
                Ok(st) => step = Some(st),
                Err(worst) => {
                    s.clone_from(&saved);
                    res.rejected_steps += 1;
                    ds *= 0.5;
                    if ds < ds_min {
                        cx.place(s, mu);
                        if let Some(StaticsError::FreeMotion { motions, .. }) =
                            statics::free_motions(model, s, cx.load_factor(mu))
                        {
                            return Err(PathError::Mechanism { what, mu, motions });
                        }
                        return Err(PathError::Stalled {
                            what,
                            mu,
                            ds,
                            points: res.lambda.len(),
                            iterations: res.newton_iterations,
                            residual: worst.1,
                            dof: worst.0,
                        });
                    }
                }
            }
        }
        let (du, dmu, iters) = step.expect("loop ends with a step");
        res.newton_iterations += iters;
        let new_mu = mu + dmu;

        // landing on max_param: redo this step as plain Newton at μ = max_param from the
        // last point (the crossing lies within one step)
        if new_mu >= opts.max_param && mu < opts.max_param {
            let mut t = saved.clone();
            let frac = (opts.max_param - mu) / dmu;
            let part: Vec<f64> = du.iter().map(|x| x * frac).collect();
            joint::apply_increment(model, &mut t, &part);
            if let Ok(Some(it)) = cx.newton_fixed(&mut t, opts.max_param) {
                res.newton_iterations += it;
                s.clone_from(&t);
                arc += ds * frac;
                push(&mut cx, s, res, opts.max_param, it, arc);
                res.det_sign.push(det_sign(&mut cx, s, opts.max_param));
                res.stopped_by = "max_param";
                return Ok(());
            }
            // else keep the arc-length point beyond it and stop there
            arc += ds;
            push(&mut cx, s, res, new_mu, iters, arc);
            res.det_sign.push(det_sign(&mut cx, s, new_mu));
            res.stopped_by = "max_param";
            return Ok(());
        }

        // hinge locks crossed in this step: lock at the angle, re-equilibrate at new_mu
        let mut locked_now = false;
        for (ih, h) in model.hinges.iter().enumerate() {
            if s.locked[ih] {
                continue;
            }
            let th = s.q[h.dof];
            let by_angle = h.reaches_lock_angle(saved.q[h.dof], th);
            let by_time = opts.control == Control::Drivers
                && h.lock_time.is_some_and(|tl| new_mu >= tl - 1e-12);
            if by_angle || by_time {
                if let (true, Some(la)) = (by_angle, h.lock_angle) {
                    s.q[h.dof] = la;
                }
                s.locked[ih] = true;
                res.locks.push((ih, res.lambda.len()));
                locked_now = true;
            }
        }
        if locked_now {
            match cx.newton_fixed(s, new_mu)? {
                Some(it) => res.newton_iterations += it,
                None => {
                    return Err(PathError::Stalled {
                        what,
                        mu: new_mu,
                        ds,
                        points: res.lambda.len(),
                        iterations: res.newton_iterations,
                        residual: f64::NAN,
                        dof: "(equilibrium after a hinge locked)".into(),
                    })
                }
            }
        }

        // accept
        arc += ds;
        let dir = dmu.signum();
        if dir != 0.0 && dir != prev_dir && res.lambda.len() > 1 {
            res.limit_points.push(LimitPoint {
                index: res.lambda.len() - 1,
                lambda: mu,
                kind: if prev_dir > 0.0 { "max" } else { "min" },
                lambda_fit: mu,
            });
        }
        let limit_here = dir != 0.0 && dir != prev_dir;
        if dir != 0.0 {
            prev_dir = dir;
        }
        mu = new_mu;
        push(&mut cx, s, res, mu, iters, arc);
        let sg = det_sign(&mut cx, s, mu);
        res.det_sign.push(sg);
        if sg != 0 && prev_sign != 0 && sg != prev_sign && !limit_here {
            res.bifurcations.push(Bifurcation {
                index: res.lambda.len() - 1,
                lambda: mu,
            });
        }
        if sg != 0 {
            prev_sign = sg;
        }
        prev_du = du;
        prev_dmu = dmu;
        ds *= (TARGET_ITERATIONS / (iters.max(1) as f64))
            .sqrt()
            .clamp(0.5, 2.0);

        if opts
            .limit_points
            .is_some_and(|k| res.limit_points.len() >= k)
        {
            res.stopped_by = "limit_points";
            return Ok(());
        }
        if let (Some(u), Some(p)) = (&opts.until, until_prev) {
            let now = res.sensors.last().expect("pushed")[u.sensor][u.component] - u.value;
            if now == 0.0 || now.signum() != p.signum() {
                res.stopped_by = "until";
                return Ok(());
            }
            until_prev = Some(now);
        }
    }
}

/// A copy of the state placed at μ = 0 (drivers), for the start-up statics solve.
fn model_at(model: &Model, s: &State) -> State {
    let mut t = s.clone();
    joint::update_kinematics(model, &mut t);
    t
}

fn mechanism(
    model: &Model,
    s: &State,
    load_factor: f64,
    what: &'static str,
    mu: f64,
) -> Result<PathError, PathError> {
    match statics::free_motions(model, s, load_factor) {
        Some(StaticsError::FreeMotion { motions, .. }) => {
            Ok(PathError::Mechanism { what, mu, motions })
        }
        _ => Ok(PathError::Mechanism {
            what,
            mu,
            motions: "(not named: the model is larger than the dense diagnosis handles, \
                      or the singularity is numerical)"
                .into(),
        }),
    }
}

fn det_sign(cx: &mut Ctx, s: &mut State, mu: f64) -> i8 {
    if cx.eval(s, mu, true).is_err() {
        return 0;
    }
    cx.sys
        .symbolic()
        .det_sign(&cx.sys.values)
        .map(|(sg, _)| sg)
        .unwrap_or(0)
}

/// A converged step (Δu, Δμ, iterations), or why it must be cut: (the worst residual's
/// coordinate or the reason, that residual).
type StepOutcome = Result<(Vec<f64>, f64, usize), (String, f64)>;

/// One arc-length step from the converged (s, μ) along tangent `ut` with predicted Δμ.
/// Ok(Ok((Δu, Δμ, iterations))) when converged; Ok(Err((dof, residual))) when the step
/// must be cut (diverged, no real root, too large a rotation).
#[allow(clippy::too_many_arguments)]
fn corrector(
    cx: &mut Ctx,
    s: &mut State,
    mu0: f64,
    ut: &[f64],
    dmu_pred: f64,
    ds: f64,
    psi2: f64,
    h_fd: f64,
) -> Result<StepOutcome, PathError> {
    let model = cx.model;
    let n = ut.len();
    let mut du: Vec<f64> = ut.iter().map(|x| x * dmu_pred).collect();
    let mut dmu = dmu_pred;
    {
        let mut pred = du.clone();
        crate::assembly::limit_rotation_step(cx.model, &mut pred, MAX_NEWTON_ANGLE);
        if pred != du {
            return Ok(Err((
                "(predictor rotation above the Newton limit)".into(),
                f64::NAN,
            )));
        }
    }
    joint::apply_increment(model, s, &du);
    let mut conv = Convergence::new(model.solver.tol, cx.asm.eval.unit_roundoff());
    let mut dr = vec![0.0; n];
    for it in 0..MAX_CORRECTOR {
        let mu = mu0 + dmu;
        let info = cx.eval(s, mu, true);
        let res = norm_inf(&cx.sys.r);
        if !res.is_finite() {
            return Ok(Err(("(non-finite residual)".into(), res)));
        }
        let scale = info.as_ref().map_or(0.0, |i| i.force_scale);
        if conv.converged(res, scale) {
            if !crate::assembly::deformation_in_range(model, s) {
                return Ok(Err(("(element deformation out of range)".into(), res)));
            }
            return Ok(Ok((du, dmu, it)));
        }
        if info.is_err() {
            return Ok(Err(statics::worst_dof(model, &cx.sys.r)));
        }
        let g = cx.dr_dmu(s, mu, h_fd);
        if cx.sys.solve_neg_residual(&mut dr).is_err() {
            return Ok(Err(statics::worst_dof(model, &cx.sys.r)));
        }
        let mut dt: Vec<f64> = g.iter().map(|x| -x).collect();
        if cx.sys.solve_tangent(&mut dt).is_err() {
            return Ok(Err(statics::worst_dof(model, &cx.sys.r)));
        }
        // (Δu + δr + δμ·δt)² + ψ²(Δμ + δμ)² = Δs²
        let w: Vec<f64> = du.iter().zip(&dr).map(|(a, b)| a + b).collect();
        let a1 = dot(&dt, &dt) + psi2;
        let a2 = 2.0 * (dot(&dt, &w) + psi2 * dmu);
        let a3 = dot(&w, &w) + psi2 * dmu * dmu - ds * ds;
        let disc = a2 * a2 - 4.0 * a1 * a3;
        if disc.is_nan() || disc < 0.0 {
            return Ok(Err(statics::worst_dof(model, &cx.sys.r)));
        }
        // numerically stable roots
        let q = -0.5 * (a2 + a2.signum() * disc.sqrt());
        let roots = if q != 0.0 {
            [q / a1, a3 / q]
        } else {
            [0.0, 0.0]
        };
        // the root whose new increment is closest in direction to the current one
        let cosine = |dl: f64| -> f64 {
            let uu: f64 = du
                .iter()
                .zip(&w)
                .zip(&dt)
                .map(|((a, wi), ti)| a * (wi + dl * ti))
                .sum();
            uu + psi2 * dmu * (dmu + dl)
        };
        let dl = if cosine(roots[0]) >= cosine(roots[1]) {
            roots[0]
        } else {
            roots[1]
        };
        let mut delta: Vec<f64> = dr.iter().zip(&dt).map(|(a, b)| a + dl * b).collect();
        // a correction at the coordinates' round-off: no representable state is closer to
        // equilibrium (a stiff model barely deformed, whose force scale is below the
        // round-off of EA times the coordinates), as in statics
        if norm_inf(&delta)
            <= Convergence::ROUNDOFF_CORRECTION * f64::EPSILON * statics::coord_scale(model)
        {
            if !crate::assembly::deformation_in_range(model, s) {
                return Ok(Err(("(element deformation out of range)".into(), res)));
            }
            return Ok(Ok((du, dmu, it)));
        }
        let before = delta.clone();
        crate::assembly::limit_rotation_step(cx.model, &mut delta, MAX_NEWTON_ANGLE);
        if delta != before {
            return Ok(Err((
                "(corrector rotation above the Newton limit)".into(),
                res,
            )));
        }
        joint::apply_increment(model, s, &delta);
        for (a, b) in du.iter_mut().zip(&delta) {
            *a += b;
        }
        dmu += dl;
    }
    let _ = cx.eval(s, mu0 + dmu, false);
    Ok(Err(statics::worst_dof(model, &cx.sys.r)))
}

/// Parse `SENSOR.COMPONENT=VALUE` (component by name, e.g. `load_point.y=-80`, or by
/// 0-based index) against `model`'s sensors.
pub fn parse_until(model: &Model, spec: &str) -> Result<Until, String> {
    let (lhs, val) = spec
        .split_once('=')
        .ok_or_else(|| format!("--until {spec}: expected SENSOR.COMPONENT=VALUE"))?;
    let value: f64 = val
        .trim()
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(|| format!("--until {spec}: `{val}` is not a finite number"))?;
    let (name, comp) = lhs
        .split_once('.')
        .ok_or_else(|| format!("--until {spec}: expected SENSOR.COMPONENT=VALUE"))?;
    let sensor = model.sensor_index(name).ok_or_else(|| {
        let names: Vec<&str> = model.sensors.iter().map(|s| s.name.as_str()).collect();
        format!(
            "--until {spec}: the model has no sensor `{name}` (it has {})",
            names.join(", ")
        )
    })?;
    let comps = sensors::components(&model.sensors[sensor].kind);
    let component = comps
        .iter()
        .position(|c| *c == comp)
        .or_else(|| comp.parse::<usize>().ok().filter(|&i| i < comps.len()))
        .ok_or_else(|| {
            format!(
                "--until {spec}: sensor `{name}` has no component `{comp}` (it has {})",
                comps.join(", ")
            )
        })?;
    Ok(Until {
        sensor,
        component,
        value,
        text: spec.to_string(),
    })
}

/// The `--json` object of one path.
pub fn to_json(model: &Model, r: &PathResult, wall_s: f64) -> serde_json::Value {
    let mut sens = serde_json::Map::new();
    for (k, sn) in model.sensors.iter().enumerate() {
        let vals: Vec<&Vec<f64>> = r.sensors.iter().map(|p| &p[k]).collect();
        sens.insert(
            sn.name.clone(),
            serde_json::json!({
                "values": vals,
                "components": sensors::components(&sn.kind),
            }),
        );
    }
    let locks: Vec<serde_json::Value> = r
        .locks
        .iter()
        .map(|&(h, i)| {
            serde_json::json!({
                "hinge": model.hinges[h].name,
                "index": i,
                "lambda": r.lambda.get(i),
            })
        })
        .collect();
    serde_json::json!({
        "control": r.control.label(),
        "lambda": r.lambda,
        "sensors": sens,
        "limit_points": r.limit_points,
        "bifurcations": r.bifurcations,
        "det_sign": r.det_sign,
        "arc_length": r.arc,
        "iterations": r.iterations,
        "hinge_locks": locks,
        "points": r.lambda.len(),
        "newton_iterations": r.newton_iterations,
        "rejected_steps": r.rejected_steps,
        "stopped_by": r.stopped_by,
        "status": if r.error.is_some() {
            "failed"
        } else if r.interrupted() {
            "interrupted"
        } else {
            "completed"
        },
        "message": r.message(),
        "warnings": r.warnings(),
        "wall_s": wall_s,
    })
}

/// Name of the extra dataset of path campaigns holding each point's path parameter.
pub const LAMBDA_SENSOR: &str = "path_lambda";

/// Campaign metadata for path results: `time` is the path parameter of a single path, or
/// the point index of a path sweep (variants have paths of different lengths and
/// parameter values), with the parameter itself in the extra sensor `path_lambda`.
pub fn campaign_meta(
    models: &[&Model],
    time: Vec<f64>,
    command_line: String,
    threads: usize,
) -> crate::output::CampaignMeta {
    use crate::output::{CampaignMeta, SensorMeta};
    let m = models[0];
    let mut sensors = SensorMeta::of_model(m);
    sensors.push(SensorMeta {
        name: LAMBDA_SENSOR.into(),
        components: vec!["lambda".into()],
        units: vec!["1".into()],
    });
    CampaignMeta {
        command_line,
        model_path: m.path.clone(),
        model_source: m.source.clone(),
        backend: "cpu".into(),
        precision: "f64".into(),
        adapter: String::new(),
        threads,
        parameter_names: m.params.iter().map(|(n, _)| n.clone()).collect(),
        parameter_values: models
            .iter()
            .map(|mm| mm.params.iter().map(|(_, v)| *v).collect())
            .collect(),
        global_index: (0..models.len()).collect(),
        time,
        sensors,
    }
}

/// Store path `r` as variant `v` of `w` (points at time indices 0..) and its status.
pub fn write_variant(
    w: &mut crate::output::CampaignWriter,
    v: usize,
    r: &PathResult,
    wall_s: f64,
) -> Result<(), crate::output::OutputError> {
    use crate::output::{VariantState, VariantStatus};
    for (i, (vals, mu)) in r.sensors.iter().zip(&r.lambda).enumerate() {
        let mut row = vals.clone();
        row.push(vec![*mu]);
        w.write_samples(v, i, &row)?;
    }
    let st = VariantStatus {
        state: if r.error.is_some() {
            VariantState::Failed
        } else if r.interrupted() {
            VariantState::Interrupted
        } else {
            VariantState::Completed
        },
        message: r.message(),
        t_fail: if r.error.is_some() || r.interrupted() {
            r.lambda.last().copied().unwrap_or(0.0)
        } else {
            f64::NAN
        },
        steps: r.lambda.len().saturating_sub(1) as u64,
        rejected_steps: r.rejected_steps as u64,
        wall_s,
        warnings: r.warnings().join("\n"),
        ..VariantStatus::default()
    };
    w.set_status(v, &st)
}

/// Paths of several variants in parallel on `threads` workers; each variant's path is
/// computed by the same sequential code as alone, so it is bit-identical to its own run.
pub fn follow_all(
    models: &[Model],
    opts: &[PathOptions],
    threads: usize,
) -> Vec<(PathResult, f64)> {
    use rayon::prelude::*;
    let work = || {
        models
            .par_iter()
            .zip(opts)
            .map(|(m, o)| {
                let t0 = std::time::Instant::now();
                let r = follow(m, o);
                (r, t0.elapsed().as_secs_f64())
            })
            .collect()
    };
    match rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
    {
        Ok(pool) => pool.install(work),
        Err(_) => work(),
    }
}

/// Extremum value of the parabola through (x[k], y[k]), k = 0..3 (x distinct); None when
/// the three points are collinear.
fn parabola_extremum(x: &[f64], y: &[f64]) -> Option<f64> {
    let (x0, x1, x2) = (x[0], x[1], x[2]);
    let d01 = (y[1] - y[0]) / (x1 - x0);
    let d12 = (y[2] - y[1]) / (x2 - x1);
    let c2 = (d12 - d01) / (x2 - x0);
    if !(c2.is_finite() && c2 != 0.0) {
        return None;
    }
    // y = y1 + b (x − x1) + c2 (x − x1)², b = slope at x1
    let b = d01 + c2 * (x1 - x0);
    let v = y[1] - b * b / (4.0 * c2);
    v.is_finite().then_some(v)
}

/// s1 − s0 by equation: coordinate differences, and for spins the rotation vector of
/// R1 R0ᵀ (the spatial increment `apply_increment` would take from s0 to s1).
fn state_diff(model: &Model, s0: &State, s1: &State) -> Vec<f64> {
    use crate::math::{mat_mul, rot_log, transpose};
    let mut d = vec![0.0; model.n_eq];
    for (i, dof) in model.dofs.iter().enumerate() {
        if let Some(e) = dof.eq {
            d[e] = s1.q[i] - s0.q[i];
        }
    }
    for (k, sp) in model.spins.iter().enumerate() {
        let w = rot_log(&mat_mul(&s1.spin[k], &transpose(&s0.spin[k])));
        for c in 0..3 {
            if let Some(e) = model.dofs[sp.dofs[c]].eq {
                d[e] = w[c];
            }
        }
    }
    d
}

/// The values `n_variants` paths of at most `max_points` points keep (sensor components,
/// λ and the time column), against the `output_values` limit (`LATDYN_LIMITS`), before
/// anything is run or allocated.
pub fn check_output_size(
    model: &Model,
    max_points: usize,
    n_variants: usize,
) -> Result<(), String> {
    let lim = crate::model::Limits::from_env()?;
    let per_point = 2.0
        + model
            .sensors
            .iter()
            .map(|s| sensors::components(&s.kind).len() as f64)
            .sum::<f64>();
    let total = per_point * max_points as f64 * n_variants as f64;
    if total > lim.output_values as f64 {
        return Err(crate::model::limits::exceeded(
            &format!(
                "values the paths keep, {} per point (sensor components + λ + time) × {} \
                 points (--max-points) × {} variants",
                crate::model::limits::count(per_point),
                max_points,
                n_variants
            ),
            total,
            "output_values",
            lim.output_values,
        ));
    }
    Ok(())
}
