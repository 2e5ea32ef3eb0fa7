//! The `modes` verb: at rest, in the rotating frame, and over `--vary`.

use anyhow::{anyhow, Context};
use latdyn::model::{self, Model};
use latdyn::solver::modes::{bending_share, mesh_order};

use crate::cli::ModesArgs;
use crate::emit;

pub(crate) fn modes(args: &ModesArgs) -> anyhow::Result<()> {
    if let Some(range) = &args.vary {
        return modes_vary(args, range);
    }
    let m = args.model.load()?;
    // the rotating-frame analysis refuses a model too large for its dense matrices itself,
    // first thing (`solver::modes::check_dense_size`)
    if let Some(spin) = latdyn::solver::rotating::find_spin(&m) {
        return rotating_modes(args, &m, spin);
    }
    // `lowest_modes` refuses it too, but only after the static equilibrium below, which
    // on such a model would take long before the refusal
    latdyn::solver::modes::check_dense_size(m.n_eq, false)
        .map_err(|e| anyhow!("{}: {e}", m.path))?;
    let preload = match args.about.as_str() {
        "static" => true,
        "reference" => false,
        _ => !m.loads.is_empty() || m.gravity != [0.0; 3],
    };
    // the static equilibrium's own warnings (an element beyond its small-deformation
    // range, measured as `statics` measures it) hold for the modes about it
    let mut static_warnings = Vec::new();
    let mut refined_static = None;
    let state = if preload {
        let mut sol = latdyn::solver::solve_statics(&m)
            .with_context(|| format!("{}: static equilibrium for the modes", m.path))?;
        (_, refined_static) = latdyn::solver::check_statics_mesh_keeping(
            &m,
            &mut sol,
            || {
                model::load_refined(
                    &args.model.model,
                    &args.model.set,
                    latdyn::solver::MESH_REFINE,
                )
                .map_err(|e| e.to_string())
            },
            None,
        );
        static_warnings = sol
            .report
            .warnings
            .iter()
            .map(|w| format!("the static equilibrium the modes are about: {w}"))
            .collect();
        sol.state
    } else {
        latdyn::joint::State::new(&m)
    };
    let mut md = latdyn::solver::modes::lowest_modes(&m, &state, args.count())
        .with_context(|| format!("{}: modes", m.path))?;
    md.warnings.splice(0..0, static_warnings);
    let count = args.count().min(md.frequencies_hz.len());
    let mesh = mesh_check(args, &args.model.set, &m, false, |rm| {
        let fine_state = match refined_static {
            Some((_, sol)) => sol.state,
            None if preload => {
                latdyn::solver::solve_statics(rm)
                    .map_err(|e| format!("its static equilibrium: {e}"))?
                    .state
            }
            None => latdyn::joint::State::new(rm),
        };
        let fine = latdyn::solver::modes::lowest_modes(rm, &fine_state, count)
            .map_err(|e| e.to_string())?;
        Ok(latdyn::solver::modes::mesh_error_by_mode(
            &md.frequencies_hz[..count],
            &fine.frequencies_hz,
            |k| {
                (!md.zero_frequency[k])
                    .then(|| mesh_order(bending_share(&m, &state, &[&md.shapes[k]])))
            },
        ))
    });
    md.warnings
        .extend(mesh.warning(&md.frequencies_hz[..count], ""));
    md.warnings.extend(fewer_modes(
        args.count_arg,
        md.frequencies_hz.len(),
        m.n_eq,
        "",
    ));
    let f = &md.frequencies_hz[..count];
    for w in &md.warnings {
        eprintln!("warning: {w}");
    }
    if args.model.json {
        let mut v = serde_json::json!({
            "frequencies_hz": f,
            "zero_frequency": &md.zero_frequency[..count],
            "error_estimates": &md.error_estimates[..count],
            "mesh_error_estimates": mesh.estimates,
            "mesh_elements": mesh.elements(),
            "warnings": md.warnings,
            "about": if preload { "static" } else { "reference" },
            "free_dofs": m.n_eq,
        });
        if args.shapes {
            v["shapes"] = serde_json::json!(md.shapes[..count]
                .iter()
                .map(|sh| {
                    m.dofs
                        .iter()
                        .map(|d| {
                            (
                                d.name.clone(),
                                serde_json::json!(d.eq.map(|e| sh[e]).unwrap_or(0.0)),
                            )
                        })
                        .collect::<serde_json::Map<String, serde_json::Value>>()
                })
                .collect::<Vec<_>>());
        }
        emit(&format!("{v}\n"))
    } else {
        let mut s = format!(
            "modes {} about the {} configuration ({} free dofs)\n",
            m.name,
            if preload {
                "static equilibrium"
            } else {
                "reference"
            },
            m.n_eq
        );
        for (k, x) in f.iter().enumerate() {
            let tag = if md.zero_frequency[k] {
                "  (zero frequency: rigid-body or mechanism motion)"
            } else {
                ""
            };
            s += &format!("  {:>3}  {:>14.6} Hz{}{tag}\n", k + 1, x, mesh.column(k));
        }
        emit(&s)
    }
}

/// What the mesh check of the modes found ([`mesh_check`]).
struct MeshCheck {
    /// per reported mode (None: a zero-frequency mode); None when not measured
    estimates: Option<Vec<Option<f64>>>,
    /// elements of the base and the refined model
    elements: (usize, usize),
    /// why it was not measured, where it was to be (a warning)
    not_measured: Option<String>,
}

impl MeshCheck {
    fn elements(&self) -> Option<[usize; 2]> {
        self.estimates
            .as_ref()
            .map(|_| [self.elements.0, self.elements.1])
    }

    /// The warning: the modes above the limit, or why the check could not be made.
    fn warning(&self, frequencies_hz: &[f64], what: &str) -> Option<String> {
        if let Some(why) = &self.not_measured {
            return Some(format!(
                "{what}mesh error of the frequencies not measured: {why}"
            ));
        }
        latdyn::solver::modes::mesh_warning(
            frequencies_hz,
            self.estimates.as_deref()?,
            self.elements,
            what,
        )
    }

    /// The text output's column for mode `k`.
    fn column(&self, k: usize) -> String {
        match self.estimates.as_ref().map(|e| e[k]) {
            Some(Some(e)) => format!("   mesh error {:>8.2e}", e),
            Some(None) => format!("   {:>19}", ""),
            None => String::new(),
        }
    }
}

/// The mesh check ([`mesh_check`]) of the lowest `count` rotating-frame modes `rm` of `m`.
fn rotating_mesh_check(
    args: &ModesArgs,
    set: &[(String, f64)],
    m: &Model,
    rm: &latdyn::solver::rotating::RotatingModes,
    count: usize,
) -> MeshCheck {
    let f = &rm.frequencies_hz[..count];
    mesh_check(args, set, m, true, |fm| {
        let spin = latdyn::solver::rotating::find_spin(fm)
            .ok_or("its hub does not turn at a constant speed")?;
        let fine = latdyn::solver::rotating::rotating_modes(fm, spin).map_err(|e| e.to_string())?;
        // modes about a state that is not an equilibrium compare with nothing
        if !fine.steady_converged {
            return Err("Newton found no steady rotating state of the refined model".into());
        }
        Ok(latdyn::solver::modes::mesh_error_by_mode(
            f,
            &fine.frequencies_hz,
            |k| {
                (f[k].abs() >= rm.resolution_hz).then(|| {
                    let share = rm.shapes.get(k).and_then(|z| {
                        let re: Vec<f64> = z.iter().map(|c| c.re).collect();
                        let im: Vec<f64> = z.iter().map(|c| c.im).collect();
                        bending_share(m, &rm.steady, &[&re, &im])
                    });
                    mesh_order(share)
                })
            },
        ))
    })
}

/// The one warning of `modes --vary` for its mesh checks: the values at which a
/// frequency's estimated mesh error is above the limit (the first few named, with their
/// worst mode), or those at which it could not be measured.
fn vary_mesh_warning(
    name: &str,
    values: &[f64],
    steps: &[latdyn::solver::rotating::RotatingModes],
    meshes: &[MeshCheck],
) -> Option<String> {
    let limit = latdyn::solver::MESH_ERROR_WARN;
    if let Some((v, c)) = values
        .iter()
        .zip(meshes)
        .find(|(_, c)| c.not_measured.is_some())
    {
        return c.warning(&[], &format!("{name}={v}: "));
    }
    let over: Vec<String> = values
        .iter()
        .zip(steps.iter().zip(meshes))
        .filter_map(|(v, (st, c))| {
            let e = c.estimates.as_ref()?;
            let (k, worst) = e
                .iter()
                .enumerate()
                .filter_map(|(k, x)| x.map(|x| (k, x)))
                .fold((0, 0.0f64), |a, b| if b.1 > a.1 { b } else { a });
            (worst > limit).then(|| {
                format!(
                    "{name}={v} (mode {} at {:.6} Hz, {:.2} %)",
                    k + 1,
                    st.frequencies_hz[k],
                    100.0 * worst
                )
            })
        })
        .collect();
    if over.is_empty() {
        return None;
    }
    let elements = meshes.first().map(|c| c.elements).unwrap_or_default();
    let (mut list, more) = latdyn::solver::modes::first_named(&over);
    if more > 0 {
        list += &format!(" and {more} more");
    }
    Some(format!(
        "mesh too coarse at {} of the {} values: {list}: the estimated mesh error of a \
         frequency is above the {} % limit (the worst mode at each value; all in \
         `mesh_error_estimates`; measured by solving again with twice the elements, {} in \
         all against {}; Richardson). Use more elements",
        over.len(),
        values.len(),
        100.0 * limit,
        elements.1,
        elements.0
    ))
}

/// Free coordinates of the refined model up to which `--mesh-check auto` measures: its
/// dense analysis grows as n³, measured on the cantilever at 3.1 s for 1 200 and 9.8 s
/// for 1 800 coordinates, 2.4 s and 6.2 s for 600 and 900 in the rotating frame (the
/// first-order form is twice the size), so about 6 s either way on top of an analysis
/// of an eighth of that.
const MESH_CHECK_DOFS: usize = 1500;
const MESH_CHECK_DOFS_ROTATING: usize = 900;

/// The mesh error of the modes of `m`: the model compiled again with every beam's
/// elements doubled (`MESH_REFINE`), given to `fine`, which returns the estimate per
/// reported mode. Models without beams have no mesh; `--mesh-check never` skips it;
/// under `auto` a refined model above [`MESH_CHECK_DOFS`] is not solved and the result
/// says why.
fn mesh_check(
    args: &ModesArgs,
    set: &[(String, f64)],
    m: &Model,
    rotating: bool,
    fine: impl FnOnce(&Model) -> Result<Vec<Option<f64>>, String>,
) -> MeshCheck {
    let refine = latdyn::solver::MESH_REFINE;
    let elements = (m.elem_data.len(), m.elem_data.len() * refine);
    let mut out = MeshCheck {
        estimates: None,
        elements,
        not_measured: None,
    };
    if m.elem_data.is_empty() || args.mesh_check == "never" {
        return out;
    }
    let result = model::load_refined(&args.model.model, set, refine)
        .map_err(|e| format!("twice the elements ({} in all) do not compile: {e}", elements.1))
        .and_then(|rm| {
            let bound = if rotating {
                MESH_CHECK_DOFS_ROTATING
            } else {
                MESH_CHECK_DOFS
            };
            if args.mesh_check == "auto" && rm.n_eq > bound {
                return Err(format!(
                    "twice the elements ({} in all) give {} free coordinates, above the {bound}                      the check makes by itself (a dense analysis, about 8 times as long as                      this one); `--mesh-check always` measures it",
                    elements.1, rm.n_eq
                ));
            }
            fine(&rm).map_err(|e| {
                format!(
                    "solving again with twice the elements ({} in all) failed: {e}",
                    elements.1
                )
            })
        });
    match result {
        Ok(e) => out.estimates = Some(e),
        Err(why) => out.not_measured = Some(why),
    }
    out
}

/// The warning when an explicit `--count` asks for more modes than the analysis has
/// (`have`; none without the option, whose default 10 is "up to ten"): the
/// model has fewer free coordinates than that, or some of them carry no mass (massless
/// directions are condensed out, see `solver::modes`), and only `have` are reported.
fn fewer_modes(count: Option<usize>, have: usize, free_dofs: usize, frame: &str) -> Option<String> {
    let count = count?;
    (count > have).then(|| {
        let why = if have < free_dofs {
            format!(
                "{free_dofs} free coordinates, {} of them massless directions without a \
                 mode of their own",
                free_dofs - have
            )
        } else {
            format!(
                "{free_dofs} free coordinate{}",
                if free_dofs == 1 { "" } else { "s" }
            )
        };
        let (modes, are) = if have == 1 {
            ("mode", "it is")
        } else {
            ("modes", "all are")
        };
        format!("--count {count}: the model has only {have} {modes}{frame} ({why}); {are} reported")
    })
}

/// Modes of a model with a hub at constant speed: about the steady rotating state, in
/// the rotating frame.
pub(crate) fn rotating_modes(
    args: &ModesArgs,
    m: &Model,
    spin: latdyn::solver::rotating::SteadySpin,
) -> anyhow::Result<()> {
    // the shapes tell bending modes from others for the mesh check's order
    let rm = latdyn::solver::rotating::rotating_modes_with_shapes(m, spin, args.count())
        .with_context(|| format!("{}: rotating-frame modes", m.path))?;
    let count = args.count().min(rm.frequencies_hz.len());
    let f = &rm.frequencies_hz[..count];
    let mut warnings: Vec<String> = rm.steady_warning().into_iter().collect();
    warnings.extend(rm.turning_loads.clone());
    warnings.extend(fewer_modes(
        args.count_arg,
        rm.frequencies_hz.len(),
        m.n_eq,
        " in the rotating frame",
    ));
    warnings.extend(rm.resolution_warning(count));
    warnings.extend(rm.instability_warning(count));
    let mesh = rotating_mesh_check(args, &args.model.set, m, &rm, count);
    warnings.extend(mesh.warning(f, ""));
    for w in &warnings {
        eprintln!("warning: {}: {w}", m.path);
    }
    if args.model.json {
        let v = serde_json::json!({
            "frequencies_hz": f,
            "damping_ratios": &rm.damping[..count],
            // as about a static state: within the eigen-solver's resolution of zero (a
            // free lag hinge read 1.44e-5 Hz with no flag, session 48's probe)
            "zero_frequency": f.iter().map(|x| x.abs() < rm.resolution_hz).collect::<Vec<_>>(),
            "mesh_error_estimates": mesh.estimates,
            "mesh_elements": mesh.elements(),
            "about": "steady_rotation",
            "omega_rad_s": rm.omega,
            "free_dofs": m.n_eq,
            "warnings": warnings,
        });
        emit(&format!("{v}\n"))
    } else {
        let mut s = format!(
            "modes {} in the frame rotating at {:.6} rad/s, about the steady state ({} free dofs)\n",
            m.name, rm.omega, m.n_eq
        );
        for (k, x) in f.iter().enumerate() {
            s += &format!("  {:>3}  {:>14.6} Hz{}\n", k + 1, x, mesh.column(k));
        }
        emit(&s)
    }
}

/// `modes --vary`: rotating-frame modes at each value of one parameter, tracked into
/// branches by MAC against the previous value's shapes.
pub(crate) fn modes_vary(args: &ModesArgs, range: &latdyn::ensemble::Range) -> anyhow::Result<()> {
    use latdyn::solver::rotating;
    if args.count() == 0 {
        return Err(anyhow!("--count must be at least 1"));
    }
    let base = model::load(&args.model.model, &args.model.set)?;
    if base.param(&range.name).is_none() {
        let names: Vec<&str> = base.params.iter().map(|(n, _)| n.as_str()).collect();
        return Err(anyhow!(
            "--vary {}: the model has no parameter `{}` (parameters: {})",
            range.name,
            range.name,
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ));
    }
    let values = range.values();
    // a few spare shapes per value: a branch whose mode has moved past others must
    // still find it among the candidates
    let want = args.count() + 4;
    let mut steps = Vec::with_capacity(values.len());
    let mut warnings: Vec<String> = Vec::new();
    let mut free_dofs = 0;
    let mut meshes = Vec::with_capacity(values.len());
    for &v in &values {
        let mut set = args.model.set.clone();
        set.retain(|(n, _)| *n != range.name);
        set.push((range.name.clone(), v));
        // a value that breaks the model is named, not only the model's line
        let m = model::load(&args.model.model, &set)
            .map_err(|e| anyhow!("--vary {}={v}: {e}", range.name))?;
        if m.param(&range.name).is_none() {
            return Err(anyhow!(
                "--vary {}: the model has no parameter `{}`",
                range.name,
                range.name
            ));
        }
        // a model with no hub at all is told so; the speed hint is for a range that
        // starts at rest (a probe in session 48 read it for `--vary EI` on a cantilever)
        if rotating::constant_rate_hub(&m).is_none() {
            return Err(anyhow!(
                "--vary {}: `modes --vary` follows the rotating-frame modes of a hub over its \
                 speed (a Campbell diagram), and no body of {} is driven at a constant \
                 speed; for the modes at several values of `{}`, run `latdyn modes {} --set \
                 {}=VALUE` per value",
                range.name,
                m.path,
                range.name,
                m.path,
                range.name
            ));
        }
        let spin = rotating::find_spin(&m).ok_or_else(|| {
            anyhow!(
                "--vary {}={v}: no body of {} turns at a constant nonzero speed; --vary \
                 follows rotating-frame modes, so every value must give a spinning hub \
                 (start a speed range just above 0, e.g. 1e-6)",
                range.name,
                m.path
            )
        })?;
        if free_dofs != 0 && free_dofs != m.n_eq {
            return Err(anyhow!(
                "--vary {}={v}: the number of free coordinates changes ({} → {}); modes \
                 can only be followed across values of the same topology",
                range.name,
                free_dofs,
                m.n_eq
            ));
        }
        free_dofs = m.n_eq;
        // too large for the dense matrices: refused by the analysis before it allocates
        let rm = rotating::rotating_modes_with_shapes(&m, spin, want)
            .with_context(|| format!("{}: rotating-frame modes at {}={v}", m.path, range.name))?;
        for w in rm.steady_warning().iter().chain(&rm.turning_loads) {
            eprintln!("warning: {}: {}={v}: {w}", m.path, range.name);
            warnings.push(format!("{}={v}: {w}", range.name));
        }
        let count = args.count().min(rm.frequencies_hz.len());
        if let Some(w) = rm.instability_warning(count) {
            eprintln!("warning: {}: {}={v}: {w}", m.path, range.name);
            warnings.push(format!("{}={v}: {w}", range.name));
        }
        meshes.push(rotating_mesh_check(args, &set, &m, &rm, count));
        steps.push(rm);
    }
    if let Some(w) = vary_mesh_warning(&range.name, &values, &steps, &meshes) {
        eprintln!("warning: {}: {w}", args.model.model.display());
        warnings.push(w);
    }
    let branches = rotating::track_branches(&steps, args.count());
    // the fewest modes of any value bound what is followed and sorted
    if let Some(have) = steps.iter().map(|s| s.frequencies_hz.len()).min() {
        if let Some(w) = fewer_modes(args.count_arg, have, free_dofs, " in the rotating frame") {
            eprintln!("warning: {}: {w}", args.model.model.display());
            warnings.push(w);
        }
    }
    let speeds: Vec<f64> = steps.iter().map(|s| s.omega).collect();
    if args.model.json {
        let list: Vec<serde_json::Value> = branches
            .iter()
            .enumerate()
            .map(|(k, b)| {
                serde_json::json!({
                    "branch": k + 1,
                    "frequencies_hz": b.frequencies_hz.iter().map(|x| x.is_finite().then_some(*x)).collect::<Vec<_>>(),
                    "damping_ratios": b.damping.iter().map(|x| x.is_finite().then_some(*x)).collect::<Vec<_>>(),
                    "mac": b.mac,
                })
            })
            .collect();
        let sorted: Vec<Vec<f64>> = steps
            .iter()
            .map(|s| s.frequencies_hz[..args.count().min(s.frequencies_hz.len())].to_vec())
            .collect();
        let v = serde_json::json!({
            "about": "steady_rotation",
            "parameter": range.name,
            "values": values,
            "omega_rad_s": speeds,
            "branches": list,
            "sorted_frequencies_hz": sorted,
            "mesh_error_estimates": meshes.iter().map(|c| c.estimates.clone()).collect::<Vec<_>>(),
            "mesh_elements": meshes.first().and_then(|c| c.elements()),
            "free_dofs": free_dofs,
            "warnings": warnings,
        });
        emit(&format!("{v}\n"))
    } else {
        let mut s = format!(
            "rotating-frame modes of {} followed by shape (MAC) over {} = {}..{} ({} values)\n",
            args.model.model.display(),
            range.name,
            range.start,
            range.stop,
            values.len()
        );
        s += &format!("  {:>12}", range.name);
        for k in 0..branches.len() {
            s += &format!("  {:>12}", format!("branch {} Hz", k + 1));
        }
        s += "  min MAC\n";
        for (i, v) in values.iter().enumerate() {
            s += &format!("  {v:>12.6}");
            let mut worst = 1.0f64;
            for b in &branches {
                s += &format!("  {:>12.6}", b.frequencies_hz[i]);
                worst = worst.min(b.mac[i]);
            }
            s += &format!("  {worst:.3}\n");
        }
        emit(&s)
    }
}
