//! The `check` verb: a model's summary and diagnostics, or the GPU adapters.

use std::io::Write;

use anyhow::Context;
use latdyn::model::DofMode;

use crate::cli::{CheckArgs, ModelArgs};

/// `latdyn check --gpu`: the adapters and what each backend choice would use.
pub(crate) fn check_gpu(json: bool) -> anyhow::Result<()> {
    use latdyn::gpu::{self, Precision};
    let list = gpu::adapter_summaries();
    let pick = |p: Precision, soft: bool| {
        gpu::select(p, soft)
            .map(|(_, s)| s.label())
            .unwrap_or_else(|e| format!("none ({e})"))
    };
    let text = if json {
        let v = serde_json::json!({
            "adapters": list.iter().map(|a| serde_json::json!({
                "name": a.name, "backend": a.backend, "device_type": a.device_type,
                "driver": a.driver, "shader_f64": a.shader_f64, "software": a.is_software(),
            })).collect::<Vec<_>>(),
            "gpu_f32": pick(Precision::F32, true),
            "gpu_f64": pick(Precision::F64, true),
            "auto_hardware": pick(Precision::F32, false),
        });
        format!("{v}\n")
    } else {
        let mut s = format!("GPU adapters: {}\n", list.len());
        for a in &list {
            s += &format!(
                "  {:<40} {:<7} {:<14} f64 {:<3} {}\n",
                a.name,
                a.backend,
                a.device_type,
                if a.shader_f64 { "yes" } else { "no" },
                a.driver
            );
        }
        s += &format!(
            "  --backend gpu --precision f32: {}\n",
            pick(Precision::F32, true)
        );
        s += &format!(
            "  --backend gpu --precision f64: {}\n",
            pick(Precision::F64, true)
        );
        s += &format!(
            "  --backend auto (hardware only, large batches): {}\n",
            pick(Precision::F32, false)
        );
        s
    };
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")
}

pub(crate) fn check(a: &CheckArgs) -> anyhow::Result<()> {
    if a.gpu {
        check_gpu(a.json)?;
    }
    match &a.model {
        Some(model) => check_model(&ModelArgs {
            model: model.clone(),
            set: a.set.clone(),
            json: a.json,
        }),
        None => Ok(()),
    }
}

/// How a run of `m` starts (`[initial]`), in a few words.
fn start(m: &latdyn::model::Model) -> String {
    let mut s = match (m.initial_steady, m.initial_rotation) {
        (true, _) => "steady rotation of the hub".to_string(),
        (false, Some((w, c))) => format!(
            "rigid rotation at [{}, {}, {}] rad/s about [{}, {}, {}]",
            w[0], w[1], w[2], c[0], c[1], c[2]
        ),
        (false, None) => "the reference configuration".to_string(),
    };
    s += match m.initial_consistent_velocity {
        Some(true) => ", the rates not given strain-free (consistent_velocity)",
        Some(false) => ", rates as given",
        None if m.initial_steady => "",
        None => ", rates as given (warned if they strain the structure)",
    };
    s
}

pub(crate) fn check_model(args: &ModelArgs) -> anyhow::Result<()> {
    let m = args.load()?;
    let driven = m
        .dofs
        .iter()
        .filter(|d| matches!(d.mode, DofMode::Driven(_)))
        .count();
    let sensors: Vec<&str> = m.sensors.iter().map(|s| s.name.as_str()).collect();
    let text = if args.json {
        let v = serde_json::json!({
            "model": m.name,
            "nodes": m.x0.len(),
            "elements": m.elements.len(),
            "bodies": m.bodies.len(),
            "hinges": m.hinges.len(),
            "dofs": m.dofs.len(),
            "free_dofs": m.n_eq,
            "sensors": sensors,
        });
        let mut v = v;
        if !m.repeats.is_empty() {
            // only for files with repeats: the output of every other file is unchanged
            v["beams"] = serde_json::json!(m.beams.len());
            v["repeats"] = serde_json::json!(m
                .repeats
                .iter()
                .map(|r| {
                    let mut o = serde_json::json!({
                        "path": r.path,
                        "index": r.index,
                        "from": r.from,
                        "to": r.to,
                        "iterations": r.iterations,
                    });
                    for (k, n) in latdyn::model::repeat::KINDS.iter().zip(r.counts) {
                        o[*k] = serde_json::json!(n);
                    }
                    o
                })
                .collect::<Vec<_>>());
        }
        format!("{v}\n")
    } else {
        let mut s = format!("model {} ({})\n", m.name, m.path);
        s += &format!("  nodes     {}\n", m.x0.len());
        s += &format!(
            "  elements  {} in {} beams\n",
            m.elements.len(),
            m.beams.len()
        );
        s += &format!("  bodies    {}\n", m.bodies.len());
        s += &format!("  hinges    {}\n", m.hinges.len());
        s += &format!(
            "  dofs      {} ({} free, {} driven)\n",
            m.dofs.len(),
            m.n_eq,
            driven
        );
        s += &format!("  loads     {}\n", m.loads.len());
        s += &format!("  sensors   {} [{}]\n", sensors.len(), sensors.join(", "));
        s += &format!("  start     {}\n", start(&m));
        for r in &m.repeats {
            let made: Vec<String> = latdyn::model::repeat::KINDS
                .iter()
                .zip(r.counts)
                .filter(|(_, n)| *n > 0)
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            s += &format!(
                "  repeat    {} {} = {}..{}: {} iterations, generated {}\n",
                r.path,
                r.index,
                r.from,
                r.to,
                r.iterations,
                if made.is_empty() {
                    "nothing of its own".to_string()
                } else {
                    made.join(", ")
                }
            );
        }
        if !m.params.is_empty() {
            let p: Vec<String> = m
                .params
                .iter()
                .map(|(n, v)| format!("{n}={}", latdyn::model::value_text(*v)))
                .collect();
            s += &format!("  params    {}\n", p.join(" "));
        }
        s
    };
    // write! rather than println!: a closed pipe must not panic
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")
}
