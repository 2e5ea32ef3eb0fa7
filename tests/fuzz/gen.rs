//! The latdyn fuzzer, shared by the long campaign (`examples/fuzz.rs`) and the time-boxed
//! CI run (`tests/fuzz.rs`): a structure-aware generator of model files, mutators of the
//! shipped models and of command lines, and the oracle that classifies every outcome.
//!
//! Stable Rust only (no cargo-fuzz, no nightly sanitizers): coverage guidance is replaced
//! by a generator that knows the model format, so most cases get past the TOML parser and
//! reach compilation, meshing and the solvers.
//!
//! Process layout (why): a panic can be caught in-process, but an allocation failure
//! aborts the whole process and a hang cannot be interrupted from inside. So the model
//! cases run in a *worker* child process (this same executable, started in worker mode),
//! one case per line on its stdin, one result line back on its stdout. The parent keeps the
//! case it sent, so when the worker dies (abort, signal) or stays silent past the hang
//! limit (killed), the parent knows the exact input and saves it. Command-line cases run
//! the `latdyn` binary as a subprocess under the same limits. Every child runs under
//! `ulimit -v` so a runaway allocation fails fast instead of swapping the machine.
//!
//! A finding is: a panic, an abort or any death by signal, a case running longer than the
//! hang limit (20 s), a CLI exit code outside {0, 2, 3, 4, 5} (so 70, the internal-error
//! code a caught panic exits with, is a finding too), or stdout that is not one JSON value
//! after a successful `--json` command.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

/// A case running longer than this is a hang (issue 15: "hangs over 20 s").
pub const HANG_LIMIT: Duration = Duration::from_secs(20);
/// Address-space limit of every child [KiB]: the solver needs a few hundred MB at most
/// for the small models generated here; 4 GiB lets every legitimate case run and turns a
/// multi-GB allocation into an immediate allocation failure (an abort, a finding) instead
/// of minutes of paging on a shared machine.
pub const CHILD_MEM_KIB: u64 = 4 << 20;
/// Models larger than this are compiled but not analysed in-process: the fuzzer looks for
/// crashes, not for slow valid runs (the dense modes matrices are n² doubles).
pub const MAX_ANALYSIS_EQ: usize = 240;
pub const MAX_ANALYSIS_ELEMENTS: usize = 120;
/// Line prefix of worker replies (libtest may print its own lines on the same stdout).
pub const REPLY: &str = "@@FUZZ ";
/// Environment variable that turns a test binary into a worker.
pub const WORKER_ENV: &str = "LATDYN_FUZZ_WORKER";

// ---------------------------------------------------------------------------------------
// PRNG: SplitMix64. Written here rather than taken from `rand` so the fuzzer needs no
// dependency and a seed reproduces the same cases on every platform and version.

#[derive(Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9e37_79b9_7f4a_7c15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in 0..n (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
    pub fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below(hi - lo + 1)
    }
    /// True with probability 1/n.
    pub fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len())]
    }
}

// ---------------------------------------------------------------------------------------
// Cases

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Analysis {
    /// compile only
    Load,
    Statics,
    Modes,
    /// a few dynamics steps
    Dynamics(u32),
}

#[derive(Clone, Debug)]
pub enum Case {
    /// In-process: `latdyn::model::compile_str(text, overrides)`, then a capped analysis.
    Model {
        text: String,
        set: Vec<(String, f64)>,
        analysis: Analysis,
    },
    /// The `latdyn` binary with `args`, run in a fresh directory holding `files`.
    Cli {
        args: Vec<String>,
        files: Vec<(String, String)>,
    },
}

impl Case {
    pub fn to_json(&self) -> Value {
        match self {
            Case::Model {
                text,
                set,
                analysis,
            } => {
                let (a, steps) = match analysis {
                    Analysis::Load => ("load", 0),
                    Analysis::Statics => ("statics", 0),
                    Analysis::Modes => ("modes", 0),
                    Analysis::Dynamics(k) => ("dynamics", *k),
                };
                json!({
                    "kind": "model",
                    "analysis": a,
                    "steps": steps,
                    // f64 as Rust text, so NaN and inf survive JSON
                    "set": set.iter().map(|(n, v)| json!([n, format!("{v:?}")])).collect::<Vec<_>>(),
                    "text": text,
                })
            }
            Case::Cli { args, files } => json!({
                "kind": "cli",
                "args": args,
                "files": files.iter().map(|(n, c)| json!([n, c])).collect::<Vec<_>>(),
            }),
        }
    }

    pub fn from_json(v: &Value) -> Result<Case, String> {
        let s = |v: &Value| v.as_str().map(str::to_string).ok_or("expected a string");
        match v["kind"].as_str() {
            Some("model") => {
                let analysis = match v["analysis"].as_str() {
                    Some("load") => Analysis::Load,
                    Some("statics") => Analysis::Statics,
                    Some("modes") => Analysis::Modes,
                    Some("dynamics") => Analysis::Dynamics(v["steps"].as_u64().unwrap_or(1) as u32),
                    other => return Err(format!("unknown analysis {other:?}")),
                };
                let mut set = Vec::new();
                for p in v["set"].as_array().ok_or("set: expected an array")? {
                    let name = s(&p[0])?;
                    let val: f64 = s(&p[1])?.parse().map_err(|e| format!("set value: {e}"))?;
                    set.push((name, val));
                }
                Ok(Case::Model {
                    text: s(&v["text"])?,
                    set,
                    analysis,
                })
            }
            Some("cli") => {
                let args = v["args"]
                    .as_array()
                    .ok_or("args: expected an array")?
                    .iter()
                    .map(s)
                    .collect::<Result<Vec<_>, _>>()?;
                let mut files = Vec::new();
                for f in v["files"].as_array().ok_or("files: expected an array")? {
                    files.push((s(&f[0])?, s(&f[1])?));
                }
                Ok(Case::Cli { args, files })
            }
            other => Err(format!("unknown case kind {other:?}")),
        }
    }

    pub fn is_cli(&self) -> bool {
        matches!(self, Case::Cli { .. })
    }
}

// ---------------------------------------------------------------------------------------
// Generator: TOML text written directly (not through a serializer) so it can hold what
// a serializer never writes: huge integer literals, duplicate keys, odd strings.

/// Numbers that break arithmetic: zeros of both signs, the extremes of f64, subnormals,
/// NaN, infinities, the i64 edges, a literal past i64, and plain values.
const NUM_LITERALS: &[&str] = &[
    "0",
    "-0.0",
    "1",
    "-1",
    "0.5",
    "2",
    "3",
    "1.5",
    "-2.5",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e-308",
    "5e-324",
    "-1e-308",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999",
    "1e20",
    "1e9",
    "1e-9",
    "1e-12",
    "1e6",
    "123456.789",
    "0.0001",
    "1e400",
];

/// Names that are not plain identifiers: unicode, path separators, NUL, control
/// characters, format strings, very long.
fn odd_name(r: &mut Rng) -> String {
    match r.below(16) {
        0 => String::new(),
        1 => "a/b".into(),
        2 => "..".into(),
        3 => ".".into(),
        4 => "x\u{0}y".into(),
        5 => "\u{0}".into(),
        6 => "ünïcødé_Ω".into(),
        7 => "名前".into(),
        8 => "s".repeat(r.range(256, 70_000)),
        9 => " ".into(),
        10 => "tab\there".into(),
        11 => "new\nline".into(),
        12 => "%s%n{}".into(),
        13 => "\u{202e}rtl".into(),
        14 => "/abs".into(),
        _ => "dup".into(),
    }
}

/// TOML basic string with every control character escaped.
pub fn toml_str(s: impl AsRef<str>) -> String {
    let s = s.as_ref();
    let mut o = String::with_capacity(s.len() + 2);
    o.push('"');
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 || c as u32 == 0x7f => {
                o.push_str(&format!("\\u{:04X}", c as u32))
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

const FUNCS1: &[&str] = &[
    "sin", "cos", "tan", "asin", "acos", "atan", "exp", "ln", "log", "sqrt", "abs", "signum",
    "sinh", "cosh", "tanh", "floor", "ceil", "round", "log2", "log10", "fract", "trunc",
];
const FUNCS2: &[&str] = &["min", "max", "atan2"];

/// A random expression in `names` (and `t` when `time`), including the hostile kinds:
/// deep nesting, unknown names, division by zero, huge literals, syntax errors.
pub fn gen_expr(r: &mut Rng, names: &[String], time: bool, depth: u32) -> String {
    if depth > 5 || r.one_in(3) {
        return match r.below(10) {
            0..=2 => format!("{}", r.range(0, 20) as f64 / 4.0),
            3 => r.pick(NUM_LITERALS).to_string(),
            4 if time => "t".into(),
            5 if !names.is_empty() => r.pick(names).clone(),
            6 => r
                .pick(&["pi", "PI", "E", "e", "undefined_name", "x1", "Ω"])
                .to_string(),
            7 => format!("{}e{}", r.range(1, 9), r.range(0, 400) as i64 - 200),
            _ => "1".into(),
        };
    }
    let d = depth + 1;
    match r.below(14) {
        0..=3 => {
            let op = *r.pick(&["+", "-", "*", "/", "^"]);
            format!(
                "{} {op} {}",
                gen_expr(r, names, time, d),
                gen_expr(r, names, time, d)
            )
        }
        4..=5 => format!("{}({})", r.pick(FUNCS1), gen_expr(r, names, time, d)),
        6..=7 => format!(
            "{}({}, {})",
            r.pick(FUNCS2),
            gen_expr(r, names, time, d),
            gen_expr(r, names, time, d)
        ),
        8 => format!("({})", gen_expr(r, names, time, d)),
        9 => format!("-{}", gen_expr(r, names, time, d)),
        10 => r
            .pick(&[
                "1/0",
                "0/0",
                "-1/0",
                "1e308*10",
                "sqrt(-1)",
                "ln(0)",
                "0^0",
                "0^-1",
                "(-8)^(1/3)",
                "acos(2)",
                "t/0",
                "1/t",
                "exp(1000)",
                "exp(t*1e6)",
                "max(0, min(t, 2 - t))",
                "atan2(1, min(t, 1))",
                "min(max(t,1),max(t,2))",
            ])
            .to_string(),
        11 => {
            // deep nesting (a parser's recursion depth)
            let n = r.range(10, 3000);
            format!("{}t{}", "(".repeat(n), ")".repeat(n))
        }
        12 => {
            // long flat expression (parse time)
            let n = r.range(10, 3000);
            vec!["t"; n].join("+")
        }
        _ => r
            .pick(&[
                "",
                " ",
                "(",
                ")",
                "1 +",
                "sin",
                "sin()",
                "min(1)",
                "min(1,2,3)",
                ",",
                "1,2",
                "t t",
                "2**3",
                "1e",
                "e1e",
                "--1",
                "!t",
                "sin(t",
                "max(0, min(t, 2 - t)",
                "\u{0}",
                "𝛑",
                "t^^2",
                "[1]",
            ])
            .to_string(),
    }
}

/// A numeric field: a literal (plain or extreme) or an expression string.
fn gen_num(r: &mut Rng, names: &[String], time: bool, tame: bool) -> String {
    if tame {
        return format!("{}", r.range(1, 20) as f64 / 10.0);
    }
    match r.below(10) {
        0..=3 => format!(
            "{}",
            (r.unit() * 4.0 - 1.0) * 10f64.powi(r.range(0, 3) as i32)
        ),
        4..=5 => r.pick(NUM_LITERALS).to_string(),
        6 if !names.is_empty() => toml_str(r.pick(names)),
        _ => toml_str(gen_expr(r, names, time, 0)),
    }
}

fn gen_vec(r: &mut Rng, names: &[String], time: bool, tame: bool) -> String {
    if !tame && r.one_in(12) {
        return r
            .pick(&[
                "[]",
                "[1, 2]",
                "[1, 2, 3, 4]",
                "[[1], 2, 3]",
                "\"1\"",
                "[1e308, 1e308, 0]",
                "[0, 0, 0]",
                "[nan, 0, 0]",
                "[inf, -inf, 0]",
                "[1e-308, 1e-308, 1e-308]",
                "{}",
                "[true, 1, 2]",
            ])
            .to_string();
    }
    format!(
        "[{}, {}, {}]",
        gen_num(r, names, time, tame),
        gen_num(r, names, time, tame),
        gen_num(r, names, time, tame)
    )
}

/// A name from `pool`, or now and then an odd or unknown one.
fn ref_name(r: &mut Rng, pool: &[String], tame: bool) -> String {
    if pool.is_empty() || (!tame && r.one_in(15)) {
        return toml_str(odd_name(r));
    }
    toml_str(r.pick(pool))
}

fn gen_elements(r: &mut Rng, names: &[String], tame: bool) -> String {
    if tame || r.below(10) < 7 {
        return format!("{}", r.range(1, 6));
    }
    match r.below(14) {
        0 => "0".into(),
        1 => "-1".into(),
        2 => "1.5".into(),
        3 => "nan".into(),
        4 => "inf".into(),
        // the known resource defects (issue 15: elements = 1e20 panics, 1e9 aborts);
        // rarer than the rest so a campaign spends its time elsewhere
        5 if r.one_in(8) => r
            .pick(&["1e20", "1e9", "99999999999999999999", "1e8"])
            .to_string(),
        6 => "\"elements\"".into(),
        7 => format!("{}", r.range(7, 60)),
        8 if !names.is_empty() => toml_str(r.pick(names)),
        9 => "true".into(),
        10 => "\"2^3\"".into(),
        11 => "1e-300".into(),
        12 => "\"1/0\"".into(),
        _ => "1".into(),
    }
}

/// A complete model file with random but plausible structure. `tame` keeps numbers and
/// sizes benign (for CLI runs that must finish quickly); otherwise any field may be
/// extreme, malformed or missing.
pub fn gen_model(r: &mut Rng, tame: bool) -> String {
    let mut t = String::new();
    let wild = !tame;
    if r.one_in(3) {
        t += "[model]\n";
        t += &format!(
            "name = {}\n",
            toml_str(&if wild && r.one_in(3) {
                odd_name(r)
            } else {
                "fuzz".into()
            })
        );
        if r.one_in(2) {
            t += "description = \"generated\"\n";
        }
    }
    // parameters
    let mut params: Vec<String> = Vec::new();
    let np = r.range(0, 6);
    if np > 0 || r.one_in(4) {
        t += "[parameters]\n";
    }
    for i in 0..np {
        let name = if wild && r.one_in(10) {
            r.pick(&[
                "t", "sin", "min1", "maxx", "atan2y", "pi", "E", "e", "1x", "a-b", "ü", "elements",
            ])
            .to_string()
        } else {
            r.pick(&[
                "L", "EI", "EA", "GJ", "rhoA", "P", "omega", "T", "elements", "n", "k", "m", "g",
            ])
            .to_string()
                + &if tame || r.one_in(2) {
                    format!("{i}")
                } else {
                    String::new()
                }
        };
        let key = if name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') && !name.is_empty()
        {
            name.clone()
        } else {
            toml_str(&name)
        };
        let v = gen_num(r, &params, false, tame);
        if r.one_in(4) {
            t += &format!("{key} = {{ value = {v}, unit = \"m\", description = \"d\" }}\n");
        } else {
            t += &format!("{key} = {v}\n");
        }
        params.push(name);
    }
    // materials and sections
    let mut sections: Vec<String> = vec!["main".into()];
    if r.one_in(3) {
        t += "[materials.steel]\n";
        t += &format!(
            "E = {}\nG = {}\ndensity = {}\n",
            gen_num(r, &params, false, tame),
            gen_num(r, &params, false, tame),
            gen_num(r, &params, false, tame)
        );
    }
    let ns = if wild { r.range(0, 2) } else { 1 };
    for k in 0..ns.max(usize::from(tame)) {
        let name = if k == 0 {
            "main".to_string()
        } else {
            format!("s{k}")
        };
        sections.push(name.clone());
        t += &format!("[sections.{name}]\n");
        if wild && r.one_in(4) {
            match r.below(3) {
                0 => t += &format!("shape = \"tube\"\nouter_diameter = {}\ninner_diameter = {}\nmaterial = \"steel\"\n", gen_num(r, &params, false, false), gen_num(r, &params, false, false)),
                1 => t += &format!("shape = \"circle\"\ndiameter = {}\nmaterial = {}\n", gen_num(r, &params, false, false), ref_name(r, &["steel".into()], tame)),
                _ => t += &format!("shape = \"rectangle\"\nwidth = {}\nheight = {}\nmaterial = \"steel\"\n", gen_num(r, &params, false, false), gen_num(r, &params, false, false)),
            }
        } else {
            for key in ["EA", "EIy", "EIz", "GJ", "rhoA", "rhoIy", "rhoIz"] {
                if wild && r.one_in(12) {
                    continue;
                }
                let v = if tame {
                    match key {
                        "EA" => "1e5".to_string(),
                        "rhoIy" | "rhoIz" => "0.0".to_string(),
                        _ => format!("{}", r.range(1, 100)),
                    }
                } else {
                    gen_num(r, &params, false, false)
                };
                t += &format!("{key} = {v}\n");
            }
        }
    }
    // nodes
    let nn = if tame { r.range(2, 4) } else { r.range(0, 5) };
    let mut nodes: Vec<String> = Vec::new();
    for i in 0..nn {
        let name = if wild && r.one_in(12) {
            odd_name(r)
        } else {
            format!("n{i}")
        };
        let pos = if tame || r.below(3) > 0 {
            // spread out so beams have length
            format!(
                "[{}, {}, {}]",
                i as f64 + r.unit(),
                r.unit() * 0.1,
                r.unit() * 0.1
            )
        } else {
            gen_vec(r, &params, false, tame)
        };
        t += &format!("[[nodes]]\nname = {}\nposition = {pos}\n", toml_str(&name));
        nodes.push(name);
    }
    // beams
    let nb = if tame { nn - 1 } else { r.range(0, 4) };
    let mut beams: Vec<String> = Vec::new();
    for i in 0..nb {
        let name = if wild && r.one_in(12) {
            odd_name(r)
        } else {
            format!("b{i}")
        };
        let (from, to) = if tame {
            (i, i + 1)
        } else if r.below(3) > 0 {
            let a = r.below(nodes.len().max(1));
            (a, (a + 1) % nodes.len().max(1))
        } else {
            (r.below(nodes.len().max(1)), r.below(nodes.len().max(1)))
        };
        let nm = |k: usize| nodes.get(k).cloned().unwrap_or_else(|| "nowhere".into());
        t += &format!(
            "[[beams]]\nname = {}\nfrom = {}\nto = {}\nelements = {}\nsection = {}\n",
            toml_str(&name),
            toml_str(nm(from)),
            toml_str(nm(to)),
            gen_elements(r, &params, tame),
            ref_name(r, &sections, tame)
        );
        if wild && r.one_in(4) {
            t += &format!("orientation = {}\n", gen_vec(r, &params, false, false));
        }
        if wild && r.one_in(6) {
            t += &format!("arc_center = {}\n", gen_vec(r, &params, false, false));
        }
        beams.push(name);
    }
    // supports
    if !nodes.is_empty() && (tame || r.below(4) > 0) {
        t += &format!(
            "[[supports]]\nnode = {}\ntype = \"clamped\"\n",
            toml_str(&nodes[0])
        );
    }
    if wild && r.one_in(3) {
        t += &format!(
            "[[supports]]\nnode = {}\ntype = {}\n",
            ref_name(r, &nodes, tame),
            toml_str(r.pick(&["clamped", "pinned", "free", "welded", ""]))
        );
    }
    // loads
    for _ in 0..r.range(0, 2) {
        t += &format!("[[loads]]\nnode = {}\n", ref_name(r, &nodes, tame));
        if r.below(4) > 0 {
            t += &format!("force = {}\n", gen_vec(r, &params, false, tame));
        }
        if r.one_in(2) {
            t += &format!("moment = {}\n", gen_vec(r, &params, false, tame));
        }
        if r.one_in(3) {
            t += &format!(
                "scale = {}\n",
                if tame {
                    "\"min(t, 1)\"".into()
                } else {
                    toml_str(gen_expr(r, &params, true, 0))
                }
            );
        }
        if wild && r.one_in(8) {
            t += "follower = true\n";
        }
    }
    if r.one_in(3) {
        t += &format!(
            "[environment]\ngravity = {}\n",
            gen_vec(r, &params, false, tame)
        );
    }
    if wild && r.one_in(8) {
        t += &format!(
            "[initial]\nangular_velocity = {}\n",
            gen_vec(r, &params, false, false)
        );
        if r.one_in(2) {
            t += &format!("center = {}\n", gen_vec(r, &params, false, false));
        }
    }
    // bodies
    let mut bodies: Vec<String> = Vec::new();
    let mut driven: Vec<(String, usize)> = Vec::new();
    for i in 0..r.range(0, if tame { 1 } else { 2 }) {
        let name = if wild && r.one_in(12) {
            odd_name(r)
        } else {
            format!("body{i}")
        };
        t += &format!(
            "[[bodies]]\nname = {}\nposition = {}\n",
            toml_str(&name),
            gen_vec(r, &params, false, tame)
        );
        if tame || r.below(4) > 0 {
            t += &format!("mass = {}\n", gen_num(r, &params, false, tame));
        }
        if r.one_in(2) {
            t += &format!("com = {}\n", gen_vec(r, &params, false, tame));
        }
        if r.below(3) > 0 {
            if wild && r.one_in(3) {
                t += &format!(
                    "inertia = [{}, {}, {}]\n",
                    gen_vec(r, &params, false, false),
                    gen_vec(r, &params, false, false),
                    gen_vec(r, &params, false, false)
                );
            } else if tame {
                // principal moments of some body: c between |a − b| and a + b
                let a = r.range(1, 20) as f64 / 10.0;
                let b = r.range(1, 20) as f64 / 10.0;
                let c = (a - b).abs() + 2.0 * a.min(b) * r.range(1, 10) as f64 / 10.0;
                t += &format!("inertia = [{a}, {b}, {c}]\n");
            } else {
                t += &format!("inertia = {}\n", gen_vec(r, &params, false, tame));
            }
        }
        if wild && r.one_in(6) {
            t += "axes = [[1, 0, 0], [1, 0, 0]]\n";
        }
        for k in 0..r.range(0, if tame { 1 } else { 2 }) {
            let kind = if tame {
                *r.pick(&["translation", "rotation", "free_rotation"])
            } else {
                *r.pick(&["translation", "rotation", "free_rotation", "spin"])
            };
            t += &format!("  [[bodies.dofs]]\n  type = \"{kind}\"\n");
            if kind != "free_rotation" || (wild && r.one_in(4)) {
                t += &format!("  axis = {}\n", gen_vec(r, &params, false, tame));
            }
            if r.one_in(2) && !(tame && kind == "free_rotation") {
                let d = if tame {
                    "\"0.1*t\"".to_string()
                } else {
                    toml_str(gen_expr(r, &params, true, 0))
                };
                t += &format!("  drive = {d}\n");
                driven.push((name.clone(), k));
            } else if r.one_in(2) && !(tame && kind == "free_rotation") {
                t += &format!("  initial = {}\n", gen_num(r, &params, false, tame));
            }
            if wild && r.one_in(3) {
                t += &format!(
                    "  initial_rate = {}\n",
                    if kind == "free_rotation" {
                        gen_vec(r, &params, false, false)
                    } else {
                        gen_num(r, &params, false, false)
                    }
                );
            }
        }
        bodies.push(name);
    }
    // joints
    let mut joints: Vec<String> = Vec::new();
    // tame: at most one joint, on the free end, to a body or the ground (node 0 is
    // clamped, and a node-to-node hinge needs two nodes at one position)
    for i in 0..r.range(
        0,
        if nodes.len() > 1 {
            if tame {
                1
            } else {
                2
            }
        } else {
            0
        },
    ) {
        let name = if wild && r.one_in(12) {
            odd_name(r)
        } else {
            format!("j{i}")
        };
        let node = if tame {
            nodes[nodes.len() - 1].clone()
        } else {
            nodes[nodes.len() - 1 - r.below(nodes.len().min(2))].clone()
        };
        t += &format!(
            "[[joints]]\nname = {}\nnode = {}\n",
            toml_str(&name),
            toml_str(&node)
        );
        if wild && r.one_in(3) && nodes.len() > 1 {
            t += &format!("to_node = {}\n", ref_name(r, &nodes, tame));
        } else {
            let mut pool = bodies.clone();
            pool.push("ground".into());
            t += &format!("body = {}\n", ref_name(r, &pool, tame));
        }
        let hinge = tame || r.below(3) > 0;
        t += &format!("type = \"{}\"\n", if hinge { "hinge" } else { "rigid" });
        if hinge || (wild && r.one_in(4)) {
            t += &format!("axis = {}\n", gen_vec(r, &params, false, tame));
        }
        for key in [
            "stiffness",
            "damping",
            "lock_angle",
            "lock_time",
            "initial_rate",
        ] {
            if r.one_in(4) {
                t += &format!("{key} = {}\n", gen_num(r, &params, false, tame));
            }
        }
        joints.push(name);
    }
    // sensors
    for i in 0..r.range(0, 4) {
        // odd sensor names also in tame models: they reach the output writers of `run`
        // and `sweep -o` (HDF5 link names, CSV headers)
        let name = if (wild && r.one_in(5)) || (tame && r.one_in(8)) {
            odd_name(r)
        } else {
            format!("s{i}")
        };
        let mut kinds = vec!["node", "position", "direction", "energy"];
        if !tame || !beams.is_empty() {
            kinds.extend(["section", "beam_nodes"]);
        }
        if !tame || !joints.is_empty() {
            kinds.push("hinge");
        }
        if !tame || !bodies.is_empty() {
            kinds.push("body");
        }
        if !tame {
            kinds.push("body_frame");
        }
        if !tame || !driven.is_empty() {
            kinds.push("driver");
        }
        if !tame {
            kinds.push("bogus");
        }
        let kind = *r.pick(&kinds);
        t += &format!(
            "[[sensors]]\nname = {}\ntype = \"{kind}\"\n",
            toml_str(&name)
        );
        match kind {
            "node" | "position" => t += &format!("node = {}\n", ref_name(r, &nodes, tame)),
            "direction" => {
                t += &format!(
                    "node = {}\ndirection = {}\n",
                    ref_name(r, &nodes, tame),
                    gen_vec(r, &params, false, tame)
                )
            }
            "section" => {
                t += &format!(
                    "beam = {}\nat = {}\n",
                    ref_name(r, &beams, tame),
                    if tame {
                        format!("{}", r.unit())
                    } else {
                        gen_num(r, &params, false, false)
                    }
                );
                if r.one_in(2) {
                    t += &format!(
                        "component = {}\n",
                        toml_str(r.pick(&["N", "Vy", "Vz", "T", "My", "Mz", "Q", ""]))
                    );
                }
                if r.one_in(5) {
                    t += &format!("frame = {}\n", toml_str(r.pick(&["local", "global"])));
                }
            }
            "beam_nodes" => {
                t += &format!(
                    "beam = {}\ncomponent = {}\n",
                    ref_name(r, &beams, tame),
                    toml_str(r.pick(if tame {
                        &["x", "y", "z"][..]
                    } else {
                        &["x", "y", "z", "w"][..]
                    }))
                )
            }
            "hinge" => t += &format!("joint = {}\n", ref_name(r, &joints, tame)),
            "body" => t += &format!("body = {}\n", ref_name(r, &bodies, tame)),
            "body_frame" => {
                t += &format!(
                    "body = {}\nnode = {}\ncomponent = {}\n",
                    ref_name(r, &bodies, tame),
                    ref_name(r, &nodes, tame),
                    toml_str(r.pick(&["x", "y", "z", "q"]))
                )
            }
            "driver" => {
                if let (false, Some((b, k))) = (driven.is_empty(), driven.first().cloned()) {
                    t += &format!(
                        "body = {}\ndof = {}\n",
                        toml_str(&b),
                        if wild && r.one_in(3) {
                            gen_num(r, &params, false, false)
                        } else {
                            k.to_string()
                        }
                    );
                } else {
                    t += &format!(
                        "body = {}\ndof = {}\n",
                        ref_name(r, &bodies, tame),
                        gen_num(r, &params, false, tame)
                    );
                }
            }
            _ => {}
        }
    }
    // solver
    if tame || r.below(3) > 0 {
        t += "[solver]\n";
        let pick = |r: &mut Rng, tame_v: &str, wild_vs: &[&str], params: &[String]| -> String {
            if tame {
                tame_v.to_string()
            } else if r.one_in(3) {
                r.pick(wild_vs).to_string()
            } else if r.one_in(6) {
                gen_num(r, params, false, false)
            } else {
                tame_v.to_string()
            }
        };
        let x = &[
            "0", "-1", "1e-300", "nan", "inf", "1e300", "5e-324", "1e-9", "1",
        ];
        t += &format!("t_end = {}\n", pick(r, "0.02", x, &params));
        t += &format!("dt = {}\n", pick(r, "0.005", x, &params));
        if r.one_in(2) {
            t += &format!("output_dt = {}\n", pick(r, "0.01", x, &params));
        }
        if r.one_in(2) {
            t += &format!(
                "rho_inf = {}\n",
                pick(r, "0.9", &["0", "1", "2", "-1", "nan", "0.5"], &params)
            );
        }
        if r.one_in(2) {
            t += &format!(
                "tol = {}\n",
                pick(
                    r,
                    "1e-8",
                    &["2", "1e300", "0", "1e-300", "-1", "nan", "1e-16"],
                    &params
                )
            );
        }
        if r.one_in(2) {
            t += &format!(
                "max_iter = {}\n",
                pick(
                    r,
                    "25",
                    &["0", "1", "-1", "1.5", "1e9", "1e20", "nan"],
                    &params
                )
            );
        }
        if r.one_in(3) {
            let choices: &[&str] = if tame {
                &["modified", "full"]
            } else {
                &["modified", "full", "quasi", ""]
            };
            t += &format!("newton = {}\n", toml_str(r.pick(choices)));
        }
        if r.one_in(3) {
            t += &format!(
                "load_steps = {}\n",
                pick(r, "2", &["0", "-1", "1.5", "1e4", "nan"], &params)
            );
        }
        if r.one_in(4) {
            t += &format!(
                "dt_min = {}\n",
                pick(r, "1e-9", &["0", "-1", "1", "nan", "1e-300"], &params)
            );
        }
        if r.one_in(4) {
            t += &format!(
                "rayleigh_alpha = {}\nrayleigh_beta = {}\n",
                pick(r, "0.0", &["-1", "1e300", "nan"], &params),
                pick(r, "0.0", &["-1", "1e300", "nan"], &params)
            );
        }
    }
    if wild && r.one_in(20) {
        t += *r.pick(&[
            "unknown_key = 1\n",
            "[solver]\ndt = 1\n",
            "[[nodes]]\n",
            "[bogus]\nx = 1\n",
        ]);
    }
    t
}

// ---------------------------------------------------------------------------------------
// Mutators of existing model files

fn extreme_value(r: &mut Rng) -> toml::Value {
    use toml::Value as V;
    match r.below(16) {
        0 => V::Float(0.0),
        1 => V::Float(-0.0),
        2 => V::Float(1e308),
        3 => V::Float(-1e308),
        4 => V::Float(1e-308),
        5 => V::Float(f64::NAN),
        6 => V::Float(f64::INFINITY),
        7 => V::Float(f64::NEG_INFINITY),
        8 => V::Integer(i64::MAX),
        9 => V::Integer(i64::MIN),
        10 => V::Integer(0),
        11 => V::Integer(-1),
        12 => V::Float(5e-324),
        13 => V::Float(1e20),
        14 => V::Float(0.5),
        _ => V::Integer(r.range(2, 100) as i64),
    }
}

fn other_type(r: &mut Rng, names: &[String]) -> toml::Value {
    use toml::Value as V;
    match r.below(7) {
        0 => {
            let time = r.one_in(2);
            V::String(gen_expr(r, names, time, 0))
        }
        1 => V::Boolean(r.one_in(2)),
        2 => V::Array(vec![]),
        3 => V::Array(vec![extreme_value(r), extreme_value(r), extreme_value(r)]),
        4 => V::Table(toml::map::Map::new()),
        5 => V::String(odd_name(r)),
        _ => extreme_value(r),
    }
}

/// Every (path, is_leaf) in a TOML tree; a path is a list of keys and array indices.
#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Idx(usize),
}

fn collect_paths(v: &toml::Value, path: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    match v {
        toml::Value::Table(t) => {
            for (k, c) in t {
                path.push(Seg::Key(k.clone()));
                out.push(path.clone());
                collect_paths(c, path, out);
                path.pop();
            }
        }
        toml::Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                path.push(Seg::Idx(i));
                out.push(path.clone());
                collect_paths(c, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn get_mut<'a>(v: &'a mut toml::Value, path: &[Seg]) -> Option<&'a mut toml::Value> {
    let mut cur = v;
    for s in path {
        cur = match (s, cur) {
            (Seg::Key(k), toml::Value::Table(t)) => t.get_mut(k)?,
            (Seg::Idx(i), toml::Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// Parameter names of a model text (for `--set` mutations); empty when it does not parse.
pub fn param_names(text: &str) -> Vec<String> {
    match text.parse::<toml::Table>() {
        Ok(t) => t
            .get("parameters")
            .and_then(|p| p.as_table())
            .map(|p| p.keys().cloned().collect())
            .unwrap_or_default(),
        Err(_) => Vec::new(),
    }
}

/// TOML-value mutations: extremes for numbers, type swaps, odd strings and expressions,
/// deleted, duplicated and unknown keys and array entries. None when the text is not TOML.
pub fn mutate_value(r: &mut Rng, text: &str, max_ops: usize) -> Option<String> {
    let mut root = toml::Value::Table(text.parse::<toml::Table>().ok()?);
    let names = param_names(text);
    for _ in 0..r.range(1, max_ops.max(1)) {
        let mut paths = Vec::new();
        collect_paths(&root, &mut Vec::new(), &mut paths);
        if paths.is_empty() {
            break;
        }
        let p = r.pick(&paths).clone();
        let (last, parent) = p.split_last()?;
        let op = r.below(9);
        if op <= 5 {
            let Some(v) = get_mut(&mut root, &p) else {
                continue;
            };
            *v = match (op, &*v) {
                (0..=2, toml::Value::Float(_) | toml::Value::Integer(_)) => extreme_value(r),
                (0..=1, toml::Value::String(_)) => {
                    let time = r.one_in(2);
                    toml::Value::String(gen_expr(r, &names, time, 0))
                }
                (2, toml::Value::String(_)) => toml::Value::String(odd_name(r)),
                (3, toml::Value::Array(a)) if !a.is_empty() => {
                    // an entry more (duplicate) or one fewer
                    let mut a = a.clone();
                    if r.one_in(2) {
                        let e = a[r.below(a.len())].clone();
                        a.push(e);
                    } else {
                        a.remove(r.below(a.len()));
                    }
                    toml::Value::Array(a)
                }
                _ => other_type(r, &names),
            };
            continue;
        }
        let Some(container) = get_mut(&mut root, parent) else {
            continue;
        };
        match (op, last, container) {
            (6, Seg::Key(k), toml::Value::Table(t)) => {
                t.remove(k);
            }
            (6, Seg::Idx(i), toml::Value::Array(a)) => {
                a.remove(*i);
            }
            (7, _, toml::Value::Table(t)) => {
                t.insert(
                    r.pick(&[
                        "unknown", "elements", "name", "dt", "axis", "drive", "mass", "node",
                    ])
                    .to_string(),
                    other_type(r, &names),
                );
            }
            (_, Seg::Idx(i), toml::Value::Array(a)) => {
                let e = a[*i].clone();
                a.insert(*i, e);
            }
            _ => {}
        }
    }
    toml::to_string(&root).ok()
}

/// Byte-level mutations: truncation, bit flips, inserted bytes and tokens, repeated and
/// deleted lines. The result is made UTF-8 (lossily) since models are read as text.
pub fn mutate_bytes(r: &mut Rng, text: &str) -> String {
    let mut b = text.as_bytes().to_vec();
    for _ in 0..r.range(1, 4) {
        let n = b.len();
        match r.below(7) {
            0 => b.truncate(r.below(n + 1)),
            1 if n > 0 => {
                let i = r.below(n);
                b[i] ^= 1 << r.below(8);
            }
            2 => {
                let tok = *r.pick(&[
                    "[",
                    "]]",
                    "=",
                    "\"",
                    "\n[[beams]]\n",
                    "{",
                    "}",
                    "\n[parameters]\n",
                    "#",
                    "\\",
                    "1e999",
                    "'''",
                    "\u{0}",
                    "\n\n[solver]\nt_end = 1e300\n",
                    ",",
                    ".",
                    "-",
                ]);
                let i = r.below(n + 1);
                b.splice(i..i, tok.bytes());
            }
            3 => {
                let i = r.below(n + 1);
                let bytes: Vec<u8> = (0..r.range(1, 8)).map(|_| r.next_u64() as u8).collect();
                b.splice(i..i, bytes);
            }
            4 | 5 => {
                // repeat or delete a whole line
                let lines: Vec<&[u8]> = b.split(|c| *c == b'\n').collect();
                if lines.is_empty() {
                    continue;
                }
                let k = r.below(lines.len());
                let mut out: Vec<u8> = Vec::with_capacity(n + 64);
                for (j, l) in lines.iter().enumerate() {
                    if j == k && r.one_in(2) {
                        continue;
                    }
                    out.extend_from_slice(l);
                    out.push(b'\n');
                    if j == k {
                        out.extend_from_slice(l);
                        out.push(b'\n');
                    }
                }
                b = out;
            }
            _ => {
                // replace a digit run with an extreme literal
                if let Some(i) = (0..8)
                    .map(|_| r.below(n.max(1)))
                    .find(|&i| b.get(i).is_some_and(u8::is_ascii_digit))
                {
                    let mut j = i;
                    while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.') {
                        j += 1;
                    }
                    let lit =
                        *r.pick(&["1e308", "0", "99999999999999999999", "nan", "-1", "1e-308"]);
                    b.splice(i..j, lit.bytes());
                }
            }
        }
    }
    String::from_utf8_lossy(&b).into_owned()
}

fn extreme_f64(r: &mut Rng) -> f64 {
    *r.pick(&[
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        2.0,
        1e308,
        -1e308,
        1e-308,
        5e-324,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e20,
        1e9,
        1e6,
        1e-9,
        100.0,
        3.0,
    ])
}

// ---------------------------------------------------------------------------------------
// Seeds: the shipped models (and the hand-written bad and test models)

pub fn seed_models() -> Vec<(String, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    for dir in ["models", "tests/models", "tests/bad_models"] {
        let Ok(rd) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        let mut paths: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
        paths.sort();
        for p in paths {
            if p.extension().is_some_and(|e| e == "toml") {
                if let Ok(t) = std::fs::read_to_string(&p) {
                    out.push((
                        p.file_name()
                            .unwrap_or_default()
                            .to_string_lossy()
                            .into_owned(),
                        t,
                    ));
                }
            }
        }
    }
    out
}

fn pick_analysis(r: &mut Rng) -> Analysis {
    match r.below(8) {
        0..=2 => Analysis::Load,
        3..=4 => Analysis::Statics,
        5 => Analysis::Modes,
        _ => Analysis::Dynamics(r.range(1, 12) as u32),
    }
}

/// A model case: generated, a mutated seed, or a seed with extreme `--set` values.
pub fn gen_model_case(r: &mut Rng, seeds: &[(String, String)]) -> Case {
    // the mix favours nearly valid models (one mutation away from valid), since a model
    // that fails to compile never reaches assembly, the elements or the solvers
    let text = match r.below(20) {
        0..=5 => gen_model(r, true),
        6..=9 => {
            let g = gen_model(r, true);
            mutate_value(r, &g, 1).unwrap_or(g)
        }
        10..=11 => gen_model(r, false),
        12..=13 if !seeds.is_empty() => {
            let s = &r.pick(seeds).1;
            mutate_value(r, s, 1).unwrap_or_else(|| mutate_bytes(r, s))
        }
        14 if !seeds.is_empty() => {
            let s = &r.pick(seeds).1;
            mutate_value(r, s, 4).unwrap_or_else(|| mutate_bytes(r, s))
        }
        15 if !seeds.is_empty() => {
            let s = r.pick(seeds).1.clone();
            mutate_bytes(r, &s)
        }
        16..=17 if !seeds.is_empty() => r.pick(seeds).1.clone(),
        _ => {
            let g = gen_model(r, false);
            if r.one_in(2) {
                mutate_bytes(r, &g)
            } else {
                mutate_value(r, &g, 4).unwrap_or(g)
            }
        }
    };
    let mut set = Vec::new();
    let names = param_names(&text);
    if r.one_in(3) {
        for _ in 0..r.range(1, 2) {
            let name = if names.is_empty() || r.one_in(10) {
                "nope".to_string()
            } else {
                r.pick(&names).clone()
            };
            let mut v = extreme_f64(r);
            // the known resource defect; seldom, as in gen_elements
            if name == "elements" && v.abs() > 1e4 && !r.one_in(8) {
                v = 3.0;
            }
            set.push((name, v));
        }
    }
    Case::Model {
        text,
        set,
        analysis: pick_analysis(r),
    }
}

// ---------------------------------------------------------------------------------------
// Command-line cases

fn set_arg(r: &mut Rng, names: &[String]) -> String {
    let name = if names.is_empty() || r.one_in(6) {
        r.pick(&["nope", "", "ü", "a b", "elements"]).to_string()
    } else {
        r.pick(names).clone()
    };
    let v = match r.below(8) {
        0 => r
            .pick(&[
                "1e308", "-1e308", "nan", "inf", "1/0", "0/0", "", "=", "1e400", "2*pi", "t", "x",
                "1,2", "--json",
            ])
            .to_string(),
        1 => gen_expr(r, &[], false, 2),
        _ => format!("{}", r.range(0, 30) as f64 / 10.0),
    };
    if r.one_in(12) {
        return name; // no `=`
    }
    format!("{name}={v}")
}

fn vary_arg(r: &mut Rng, names: &[String]) -> String {
    let name = if names.is_empty() || r.one_in(6) {
        "nope".to_string()
    } else {
        r.pick(names).clone()
    };
    let spec = match r.below(10) {
        0 => "1:2:0".to_string(),
        1 => "2:1:3".to_string(),
        2 => "nan:1:2".to_string(),
        3 => "1:inf:2".to_string(),
        4 => "1:2".to_string(),
        5 => "1:2:-1".to_string(),
        6 => "1:2:1.5".to_string(),
        // the known resource defect (1e8 variants abort); seldom
        7 if r.one_in(10) => "1:2:100000000".to_string(),
        8 => "1:1:1".to_string(),
        _ => format!("{}:{}:{}", r.range(0, 3), r.range(1, 4), r.range(1, 3)),
    };
    format!("{name}={spec}")
}

fn csv_text(r: &mut Rng, names: &[String]) -> String {
    let n = || names.first().cloned().unwrap_or_else(|| "x".into());
    match r.below(10) {
        0 => String::new(),
        1 => "\n\n".into(),
        2 => format!("{}\n", n()),
        3 => format!("{0},{0}\n1,2\n", n()),
        4 => format!("{}\nnan\ninf\n1e308\n", n()),
        5 => format!("{}\n1,2,3\n", n()),
        6 => "\u{feff}a,b\n1\n".into(),
        7 => format!("{}\n\"1\"\n \n", n()),
        8 => format!("{},nope\n1,2\n", n()),
        _ => format!("{}\n1\n2\n", n()),
    }
}

/// A command line for the `latdyn` binary with the files it refers to. Models that must
/// run (`run`, `sweep`) are tame generated ones, so a slow but valid run is not mistaken
/// for a hang; `check`, `statics` and `modes` also get mutated shipped models.
pub fn gen_cli_case(r: &mut Rng, seeds: &[(String, String)]) -> Case {
    let verb = *r.pick(&[
        "check",
        "check",
        "statics",
        "modes",
        "run",
        "run",
        "sweep",
        "sweep",
        "sweep",
        "plot",
        "frobnicate",
        "",
    ]);
    let heavy = matches!(verb, "run" | "sweep");
    let model = if heavy || seeds.is_empty() || r.one_in(2) {
        let tame = heavy || r.one_in(2);
        gen_model(r, tame)
    } else if r.one_in(2) {
        let s = &r.pick(seeds).1;
        mutate_value(r, s, 3).unwrap_or_else(|| s.clone())
    } else {
        r.pick(seeds).1.clone()
    };
    let names = param_names(&model);
    let mut files = vec![("m.toml".to_string(), model)];
    let mut args: Vec<String> = Vec::new();
    if !verb.is_empty() {
        args.push(verb.into());
    }
    if verb == "plot" {
        let bytes: String = (0..r.range(0, 600))
            .map(|_| (r.next_u64() as u8 & 0x7f) as char)
            .collect();
        files.push((
            "in.h5".into(),
            if r.one_in(3) {
                format!("\u{89}HDF\r\n\u{1a}\n{bytes}")
            } else {
                bytes
            },
        ));
        args.push(r.pick(&["in.h5", "missing.h5", "m.toml", "."]).to_string());
        args.extend([
            "-o".to_string(),
            r.pick(&["p.svg", "p.png", "p.txt", "nodir/p.svg", "."])
                .to_string(),
        ]);
        match r.below(3) {
            0 => args.extend([
                "--sensor".into(),
                r.pick(&["s0", "s0.x", "", "ü"]).to_string(),
            ]),
            1 => args.extend(["--x".into(), "s0.x".into(), "--y".into(), "s0.y".into()]),
            _ => args.extend([
                "--campbell".into(),
                "omega".into(),
                "--derived".into(),
                "f".into(),
            ]),
        }
        if r.one_in(3) {
            args.extend([
                "--size".into(),
                r.pick(&["0x0", "1x1", "100000x100000", "axb", "-1x5"])
                    .to_string(),
            ]);
        }
        if r.one_in(2) {
            args.push("--json".into());
        }
        return Case::Cli { args, files };
    }
    args.push(
        r.pick(&[
            "m.toml",
            "m.toml",
            "m.toml",
            "m.toml",
            "missing.toml",
            ".",
            "/dev/null",
            "sub",
        ])
        .to_string(),
    );
    if r.below(3) > 0 {
        args.push("--json".into());
    }
    for _ in 0..r.range(0, 2) {
        args.extend(["--set".into(), set_arg(r, &names)]);
    }
    match verb {
        "modes" => {
            if r.one_in(2) {
                args.extend([
                    "--count".into(),
                    r.pick(&["0", "1", "3", "1000000", "-1", "x"]).to_string(),
                ]);
            }
            if r.one_in(3) {
                args.extend([
                    "--about".into(),
                    r.pick(&["static", "reference", "auto", "bogus"])
                        .to_string(),
                ]);
            }
            if r.one_in(3) {
                args.push("--shapes".into());
            }
            if r.one_in(4) {
                args.extend(["--vary".into(), vary_arg(r, &names)]);
            }
        }
        "run" | "sweep" => {
            args.extend([
                "--backend".into(),
                if r.one_in(20) {
                    r.pick(&["gpu", "auto", "tpu"]).to_string()
                } else {
                    "cpu".into()
                },
            ]);
            if r.one_in(6) {
                args.extend([
                    "--precision".into(),
                    r.pick(&["f32", "f64", "f16"]).to_string(),
                ]);
            }
            if r.below(3) > 0 {
                let o = *r.pick(&[
                    "out.h5",
                    "out.h5",
                    "out.csv",
                    "nodir/x.h5",
                    ".",
                    "sub",
                    "link.h5",
                    "exists.h5",
                    "",
                    "out",
                    "-",
                ]);
                args.extend(["-o".into(), o.into()]);
            }
            if verb == "sweep" {
                for _ in 0..r.range(0, 2) {
                    args.extend(["--vary".into(), vary_arg(r, &names)]);
                }
                if r.one_in(3) {
                    files.push(("v.csv".into(), csv_text(r, &names)));
                    args.extend([
                        "--variants".into(),
                        r.pick(&["v.csv", "v.csv", "missing.csv", "."]).to_string(),
                    ]);
                }
                if r.one_in(3) {
                    // 100000 threads is the known hang of issue 15; seldom
                    let th = if r.one_in(20) {
                        "100000"
                    } else {
                        *r.pick(&["0", "1", "2", "-1", "x"])
                    };
                    args.extend(["--threads".into(), th.into()]);
                } else {
                    args.extend(["--threads".into(), "1".into()]);
                }
                if r.one_in(3) {
                    args.extend([
                        "--shard".into(),
                        r.pick(&[
                            "0/0",
                            "1/1",
                            "5/10",
                            "3/2",
                            "a/b",
                            "1/0",
                            "2/3",
                            "1/18446744073709551615",
                        ])
                        .to_string(),
                    ]);
                }
                if r.one_in(4) {
                    args.extend([
                        "--frequency".into(),
                        r.pick(&["s0", "s0.x", "nope", "", "s0.zz"]).to_string(),
                    ]);
                }
            }
        }
        _ => {}
    }
    if r.one_in(15) {
        // flags in the wrong place, unknown flags, repeated flags
        let junk = r
            .pick(&[
                "--bogus",
                "--json",
                "-o",
                "--set",
                "--",
                "-",
                "--threads=2",
                "--vary",
            ])
            .to_string();
        let i = r.below(args.len() + 1);
        args.insert(i, junk);
    }
    // a process argument cannot hold NUL (spawn refuses it)
    for a in &mut args {
        a.retain(|c| c != '\0');
    }
    Case::Cli { args, files }
}

// ---------------------------------------------------------------------------------------
// Outcomes

#[derive(Clone, Debug)]
pub struct Outcome {
    /// outcome class: one of the `ok`-like classes or a finding class
    pub class: String,
    /// for findings: a signature that groups findings of one cause
    pub sig: String,
    pub detail: String,
}

impl Outcome {
    fn ok(class: &str) -> Outcome {
        Outcome {
            class: class.into(),
            sig: String::new(),
            detail: String::new(),
        }
    }
    pub fn is_finding(&self) -> bool {
        matches!(
            self.class.as_str(),
            "panic" | "abort" | "hang" | "bad_exit" | "bad_json" | "internal_error"
        )
    }
}

/// The cause of a death by signal, from the child's stderr: the runtime's own message
/// when there is one (allocation failure, stack overflow, a panic while panicking),
/// else the last line.
fn abort_reason(stderr: &str) -> String {
    for key in [
        "memory allocation of",
        "has overflowed its stack",
        "panicked at",
        "fatal runtime error",
    ] {
        if let Some(l) = stderr.lines().find(|l| l.contains(key)) {
            // the thread name and id vary: keep what follows them
            let l = l
                .split_once("' (")
                .map_or(l, |(_, r)| r.split_once(") ").map_or(r, |(_, x)| x));
            let mut s = normalize(l);
            if key == "panicked at" {
                let msg = stderr
                    .lines()
                    .skip_while(|x| !x.contains(key))
                    .nth(1)
                    .unwrap_or("");
                s = format!("{s} {}", normalize(msg));
            }
            return s;
        }
    }
    normalize(
        stderr
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or(""),
    )
}

/// Digits replaced by `N`, so one cause with different sizes is one signature.
fn normalize(s: &str) -> String {
    let mut o = String::new();
    let mut prev_digit = false;
    for c in s.chars().take(160) {
        if c.is_ascii_digit() {
            if !prev_digit {
                o.push('N');
            }
            prev_digit = true;
        } else {
            o.push(c);
            prev_digit = false;
        }
    }
    o
}

// ---------------------------------------------------------------------------------------
// Worker side (in-process cases)

static PANIC_INFO: Mutex<Option<String>> = Mutex::new(None);

/// The innermost `latdyn::` function of a printed backtrace, with its source line.
fn latdyn_frame(bt: &str) -> String {
    let mut lines = bt.lines();
    while let Some(l) = lines.next() {
        if let Some((_, f)) = l.trim().split_once(": ") {
            if f.starts_with("latdyn::") {
                let at = lines.next().unwrap_or("").trim();
                return match at.strip_prefix("at ") {
                    Some(p) => {
                        let p = p
                            .rsplit_once("/src/")
                            .map_or(p.to_string(), |(_, x)| format!("src/{x}"));
                        format!("{f} ({p})")
                    }
                    None => f.to_string(),
                };
            }
        }
    }
    String::new()
}

/// A dynamics case still running after this is stopped before its next time step and
/// counted as `stopped_slow`: a valid model that needs millions of steps (say EI = 1e20,
/// where Newton only converges at dt/10⁴) is a slow run, not a crash, and must not eat
/// the hang limit. Statics has no stop hook: a statics case over the hang limit is a hang.
pub const SLOW_CASE: Duration = Duration::from_secs(3);
static STOP: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
/// case number and start of the current case, for the worker's slow-case timer
static CASE_CLOCK: Mutex<(u64, Option<Instant>)> = Mutex::new((0, None));

/// The panic's message and the innermost latdyn function on the stack (from a backtrace;
/// the panic location alone is often inside std, e.g. `capacity overflow`).
fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = if let Some(s) = info.payload().downcast_ref::<&str>() {
            s.to_string()
        } else if let Some(s) = info.payload().downcast_ref::<String>() {
            s.clone()
        } else {
            "(non-string payload)".into()
        };
        let loc = info
            .location()
            .map(|l| format!("{}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let bt = std::backtrace::Backtrace::force_capture().to_string();
        let frame = latdyn_frame(&bt);
        let s = format!("{} | at {loc} | in {frame}", normalize(&msg));
        if let Ok(mut g) = PANIC_INFO.lock() {
            *g = Some(s);
        }
    }));
}

/// Runs one in-process case; panics are caught and reported as findings.
pub fn run_model_case(case: &Case) -> Outcome {
    let Case::Model {
        text,
        set,
        analysis,
    } = case
    else {
        return Outcome::ok("not_a_model_case");
    };
    if let Ok(mut g) = PANIC_INFO.lock() {
        *g = None;
    }
    let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        model_case_body(text, set, *analysis)
    }));
    match res {
        Ok(class) => Outcome::ok(class),
        Err(_) => {
            let sig = PANIC_INFO
                .lock()
                .ok()
                .and_then(|g| g.clone())
                .unwrap_or_else(|| "panic (no info)".into());
            Outcome {
                class: "panic".into(),
                sig: format!("panic: {sig}"),
                detail: String::new(),
            }
        }
    }
}

fn model_case_body(text: &str, set: &[(String, f64)], analysis: Analysis) -> &'static str {
    let m = match latdyn::model::compile_str(text, "fuzz.toml", set) {
        Ok(m) => m,
        Err(e) => {
            // errors are formatted as a user would see them (Display must not panic)
            let _ = e.to_string();
            return "model_error";
        }
    };
    if analysis == Analysis::Load {
        return "loaded";
    }
    if m.n_eq > MAX_ANALYSIS_EQ || m.elements.len() > MAX_ANALYSIS_ELEMENTS {
        return "loaded_too_big";
    }
    let mut m = m;
    // caps that keep one case short (the fuzzer looks for crashes, not slow valid runs)
    m.solver.max_iter = m.solver.max_iter.min(50);
    m.solver.load_steps = m.solver.load_steps.min(64);
    match analysis {
        Analysis::Load => "loaded",
        Analysis::Statics => match latdyn::solver::solve_statics(&m) {
            Ok(_) => "solved",
            Err(e) => {
                let _ = e.to_string();
                "solve_failed"
            }
        },
        Analysis::Modes => {
            if let Some(spin) = latdyn::solver::rotating::find_spin(&m) {
                return match latdyn::solver::rotating::rotating_modes(&m, spin) {
                    Ok(_) => "solved",
                    Err(_) => "solve_failed",
                };
            }
            // about the static equilibrium when loaded (geometric stiffness), as `modes` does
            let preload = !m.loads.is_empty() || m.gravity != [0.0; 3];
            let s = if preload {
                match latdyn::solver::solve_statics(&m) {
                    Ok(sol) => sol.state,
                    Err(_) => return "solve_failed",
                }
            } else {
                latdyn::joint::State::new(&m)
            };
            match latdyn::solver::modes::modes(&m, &s) {
                Ok(_) => "solved",
                Err(_) => "solve_failed",
            }
        }
        Analysis::Dynamics(k) => {
            let dt = m.solver.dt;
            if dt.is_finite() && dt > 0.0 {
                m.solver.t_end = m.solver.t_end.min(dt * k as f64);
            }
            m.solver.output_dt = 0.0;
            let (_, _, err) = latdyn::solver::dynamics::run_until(&m, Some(&STOP), |_, _| {});
            match err {
                None => "solved",
                Some(latdyn::solver::dynamics::DynamicsError::Interrupted { .. }) => "stopped_slow",
                Some(e) => {
                    let _ = e.to_string();
                    "solve_failed"
                }
            }
        }
    }
}

/// Worker main loop: one JSON case per stdin line, one reply line per case. Runs on a
/// thread with the 8 MiB stack of a CLI main thread, so recursion depth findings are the
/// same in the test harness (2 MiB test threads), the example and the binary.
pub fn worker_main() {
    let t = std::thread::Builder::new()
        .stack_size(8 << 20)
        .spawn(worker_loop);
    if let Ok(h) = t {
        let _ = h.join();
    }
}

fn worker_loop() {
    install_panic_hook();
    std::thread::spawn(|| loop {
        std::thread::sleep(Duration::from_millis(100));
        if let Ok(g) = CASE_CLOCK.lock() {
            if g.1.is_some_and(|t| t.elapsed() > SLOW_CASE) {
                STOP.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        }
    });
    let stdin = std::io::stdin();
    let mut out = std::io::stdout();
    for line in stdin.lock().lines() {
        let Ok(line) = line else { break };
        let o = match serde_json::from_str::<Value>(&line)
            .map_err(|e| e.to_string())
            .and_then(|v| Case::from_json(&v))
        {
            Ok(c) => {
                if let Ok(mut g) = CASE_CLOCK.lock() {
                    *g = (g.0 + 1, Some(Instant::now()));
                }
                STOP.store(false, std::sync::atomic::Ordering::Relaxed);
                let o = run_model_case(&c);
                if let Ok(mut g) = CASE_CLOCK.lock() {
                    g.1 = None;
                }
                o
            }
            Err(e) => Outcome::ok(&format!("bad_case {e}")),
        };
        let reply = json!({"class": o.class, "sig": o.sig});
        if writeln!(out, "{REPLY}{reply}")
            .and_then(|_| out.flush())
            .is_err()
        {
            break;
        }
    }
}

// ---------------------------------------------------------------------------------------
// Parent side

/// Wraps `cmd` so it runs under the address-space limit (no libc dependency: the shell's
/// `ulimit` sets RLIMIT_AS, then `exec` replaces the shell).
fn limited(program: &Path, args: &[String]) -> Command {
    let mut c = Command::new("/bin/sh");
    c.arg("-c")
        .arg(format!(
            "ulimit -v {CHILD_MEM_KIB} 2>/dev/null; exec \"$0\" \"$@\""
        ))
        .arg(program)
        .args(args);
    c
}

pub struct Worker {
    child: Child,
    stdin: ChildStdin,
    replies: Receiver<String>,
    stderr_tail: Arc<Mutex<String>>,
}

impl Worker {
    /// `cmd`: program and arguments that start this executable in worker mode.
    pub fn spawn(cmd: &[String], env: &[(String, String)]) -> std::io::Result<Worker> {
        let mut c = limited(Path::new(&cmd[0]), &cmd[1..]);
        for (k, v) in env {
            c.env(k, v);
        }
        let mut child = c
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()?;
        let stdin = child
            .stdin
            .take()
            .ok_or_else(|| std::io::Error::other("no stdin"))?;
        let stdout = child
            .stdout
            .take()
            .ok_or_else(|| std::io::Error::other("no stdout"))?;
        let mut stderr = child
            .stderr
            .take()
            .ok_or_else(|| std::io::Error::other("no stderr"))?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                // libtest prints `test NAME ... ` without a newline before the first reply
                if let Some(at) = line.find(REPLY) {
                    if tx.send(line[at + REPLY.len()..].to_string()).is_err() {
                        break;
                    }
                }
            }
        });
        let tail = Arc::new(Mutex::new(String::new()));
        let t2 = tail.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = stderr.read(&mut buf) {
                if n == 0 {
                    break;
                }
                if let Ok(mut g) = t2.lock() {
                    g.push_str(&String::from_utf8_lossy(&buf[..n]));
                    let len = g.len();
                    if len > 8192 {
                        let cut = g
                            .char_indices()
                            .map(|(i, _)| i)
                            .find(|&i| i >= len - 4096)
                            .unwrap_or(0);
                        g.drain(..cut);
                    }
                }
            }
        });
        Ok(Worker {
            child,
            stdin,
            replies: rx,
            stderr_tail: tail,
        })
    }

    /// Sends one case; Err(outcome) when the worker died or hung (it is then dead).
    pub fn run(&mut self, case: &Case, limit: Duration) -> Result<Outcome, Outcome> {
        let line = format!("{}\n", case.to_json());
        let sent = self
            .stdin
            .write_all(line.as_bytes())
            .and_then(|_| self.stdin.flush());
        let reply = if sent.is_ok() {
            self.replies.recv_timeout(limit)
        } else {
            Err(RecvTimeoutError::Disconnected)
        };
        match reply {
            Ok(r) => {
                let v: Value = serde_json::from_str(&r).unwrap_or(Value::Null);
                Ok(Outcome {
                    class: v["class"].as_str().unwrap_or("bad_reply").to_string(),
                    sig: v["sig"].as_str().unwrap_or("").to_string(),
                    detail: String::new(),
                })
            }
            Err(RecvTimeoutError::Timeout) => {
                let _ = self.child.kill();
                let _ = self.child.wait();
                Err(Outcome {
                    class: "hang".into(),
                    sig: format!(
                        "hang: in-process {} over {} s",
                        case.to_json()["analysis"].as_str().unwrap_or("?"),
                        limit.as_secs()
                    ),
                    detail: String::new(),
                })
            }
            Err(RecvTimeoutError::Disconnected) => {
                let status = self.child.wait();
                // the stderr reader may still be draining the last lines
                std::thread::sleep(Duration::from_millis(50));
                let tail = self
                    .stderr_tail
                    .lock()
                    .map(|g| g.clone())
                    .unwrap_or_default();
                let how = match status {
                    Ok(s) => {
                        use std::os::unix::process::ExitStatusExt;
                        match s.signal() {
                            Some(sig) => format!("signal {sig}"),
                            None => format!("exit {:?}", s.code()),
                        }
                    }
                    Err(e) => format!("wait failed: {e}"),
                };
                Err(Outcome {
                    class: "abort".into(),
                    sig: format!("abort ({how}): {}", abort_reason(&tail)),
                    detail: tail,
                })
            }
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs a CLI case in `dir` (emptied first) and judges it.
pub fn run_cli_case(bin: &Path, case: &Case, dir: &Path, limit: Duration) -> Outcome {
    let Case::Cli { args, files } = case else {
        return Outcome::ok("not_a_cli_case");
    };
    let _ = std::fs::remove_dir_all(dir);
    if let Err(e) = std::fs::create_dir_all(dir.join("sub")) {
        return Outcome::ok(&format!("setup_failed {e}"));
    }
    for (name, content) in files {
        let _ = std::fs::write(dir.join(name), content);
    }
    // an existing result and a symlink, both inside the case directory (the fuzzer runs
    // as root on CI machines: no path may point outside)
    let _ = std::fs::write(dir.join("exists.h5"), b"not hdf5");
    let _ = std::os::unix::fs::symlink("exists.h5", dir.join("link.h5"));
    let stdout = std::fs::File::create(dir.join(".stdout"));
    let stderr = std::fs::File::create(dir.join(".stderr"));
    let (Ok(so), Ok(se)) = (stdout, stderr) else {
        return Outcome::ok("setup_failed");
    };
    let t0 = Instant::now();
    let mut child = match limited(bin, args)
        .current_dir(dir)
        // a panic prints its backtrace: the signature names the latdyn function
        .env("RUST_BACKTRACE", "1")
        .stdin(Stdio::null())
        .stdout(so)
        .stderr(se)
        .spawn()
    {
        Ok(c) => c,
        Err(e) => return Outcome::ok(&format!("spawn_failed {e}")),
    };
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break s,
            Ok(None) if t0.elapsed() > limit => {
                let _ = child.kill();
                let _ = child.wait();
                return Outcome {
                    class: "hang".into(),
                    sig: format!(
                        "hang: cli `{}` over {} s",
                        args.first().map(String::as_str).unwrap_or(""),
                        limit.as_secs()
                    ),
                    detail: String::new(),
                };
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(
                if t0.elapsed() < Duration::from_millis(50) {
                    1
                } else {
                    10
                },
            )),
            Err(e) => return Outcome::ok(&format!("wait_failed {e}")),
        }
    };
    let out = std::fs::read(dir.join(".stdout")).unwrap_or_default();
    let err = String::from_utf8_lossy(&std::fs::read(dir.join(".stderr")).unwrap_or_default())
        .into_owned();
    let verb = args.first().cloned().unwrap_or_default();
    use std::os::unix::process::ExitStatusExt;
    if let Some(sig) = status.signal() {
        return Outcome {
            class: "abort".into(),
            sig: format!("abort (cli {verb}, signal {sig}): {}", abort_reason(&err)),
            detail: err,
        };
    }
    let code = status.code().unwrap_or(-1);
    match code {
        0 | 2 | 3 | 4 | 5 => {}
        70 => {
            return Outcome {
                class: "internal_error".into(),
                sig: format!(
                    "exit 70 (cli {verb}): {}",
                    normalize(err.lines().find(|l| !l.trim().is_empty()).unwrap_or(""))
                ),
                detail: err,
            }
        }
        101 => {
            // Rust's panic exit code: name the panic site
            // `thread 'main' (PID) panicked at FILE:LINE:COL:` without the thread id
            let at = err
                .lines()
                .find_map(|l| l.split_once("panicked at ").map(|x| x.1))
                .unwrap_or("")
                .to_string();
            let msg = err
                .lines()
                .skip_while(|l| !l.contains("panicked at"))
                .nth(1)
                .unwrap_or("");
            return Outcome {
                class: "panic".into(),
                sig: format!(
                    "panic (cli {verb}): {} | at {at} | in {}",
                    normalize(msg),
                    latdyn_frame(&err)
                ),
                detail: err,
            };
        }
        c => {
            return Outcome {
                class: "bad_exit".into(),
                sig: format!("exit {c} (cli {verb})"),
                detail: err,
            }
        }
    }
    let json = args.iter().any(|a| a == "--json");
    let help = args
        .iter()
        .any(|a| matches!(a.as_str(), "--help" | "-h" | "--version" | "-V" | "help"));
    if code == 0 && json && !help && serde_json::from_slice::<Value>(&out).is_err() {
        return Outcome {
            class: "bad_json".into(),
            sig: format!("bad json (cli {verb})"),
            detail: String::from_utf8_lossy(&out).chars().take(2000).collect(),
        };
    }
    Outcome::ok(&format!("cli_exit_{code}"))
}

// ---------------------------------------------------------------------------------------
// Campaign

pub struct Config {
    pub seed: u64,
    /// stop after this many cases, or when the time is up, whichever first
    pub cases: u64,
    pub duration: Option<Duration>,
    /// one case in `cli_every` runs the binary (they cost a process each); 0 = none
    pub cli_every: u64,
    pub bin: Option<PathBuf>,
    pub worker_cmd: Vec<String>,
    pub worker_env: Vec<(String, String)>,
    /// findings (one input per signature) are written here
    pub out: PathBuf,
    pub hang_limit: Duration,
    pub progress: bool,
}

#[derive(Default)]
pub struct Report {
    pub cases: u64,
    pub seconds: f64,
    /// outcome class -> count
    pub classes: BTreeMap<String, u64>,
    /// finding signature -> (count, file of the first input)
    pub findings: BTreeMap<String, (u64, PathBuf)>,
    pub worker_restarts: u64,
}

impl Report {
    pub fn finding_count(&self) -> u64 {
        self.findings.values().map(|(n, _)| n).sum()
    }
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} cases in {:.1} s ({:.0} cases/s), {} worker restarts\n",
            self.cases,
            self.seconds,
            self.cases as f64 / self.seconds.max(1e-9),
            self.worker_restarts
        );
        for (k, v) in &self.classes {
            s += &format!("  {k:<24} {v}\n");
        }
        if self.findings.is_empty() {
            s += "findings: none\n";
        } else {
            s += &format!(
                "findings: {} in {} distinct causes\n",
                self.finding_count(),
                self.findings.len()
            );
            for (sig, (n, p)) in &self.findings {
                s += &format!("  {n:>7} × {sig}\n          input: {}\n", p.display());
            }
        }
        s
    }
}

fn hash_str(s: &str) -> u64 {
    // FNV-1a: stable across runs (file names of findings)
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in s.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// Records an outcome; the first input of each finding signature is saved.
fn record(rep: &mut Report, cfg: &Config, case: &Case, o: &Outcome) {
    *rep.classes.entry(o.class.clone()).or_default() += 1;
    if !o.is_finding() {
        return;
    }
    let entry = rep.findings.entry(o.sig.clone()).or_insert_with(|| {
        let p = cfg
            .out
            .join(format!("{}-{:016x}.json", o.class, hash_str(&o.sig)));
        let _ = std::fs::create_dir_all(&cfg.out);
        let mut v = case.to_json();
        v["finding"] = json!(o.sig);
        if !o.detail.is_empty() {
            v["stderr_tail"] = json!(o
                .detail
                .chars()
                .rev()
                .take(3000)
                .collect::<String>()
                .chars()
                .rev()
                .collect::<String>());
        }
        let _ = std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap_or_default());
        if cfg.progress {
            eprintln!("finding: {} -> {}", o.sig, p.display());
        }
        (0, p)
    });
    entry.0 += 1;
}

/// Replays `cases` (regression inputs) then generates new ones until the budget is spent.
pub fn campaign(cfg: &Config, replay: &[Case]) -> std::io::Result<Report> {
    let seeds = seed_models();
    let mut rep = Report::default();
    let t0 = Instant::now();
    let mut worker: Option<Worker> = None;
    let dir = std::env::temp_dir().join(format!("latdyn-fuzz-{}-{}", std::process::id(), cfg.seed));
    let mut next_report = Instant::now() + Duration::from_secs(10);
    let mut i: u64 = 0;
    loop {
        let case = if let Some(c) = replay.get(i as usize) {
            c.clone()
        } else {
            if i >= cfg.cases + replay.len() as u64
                || cfg.duration.is_some_and(|d| t0.elapsed() >= d)
            {
                break;
            }
            // every case from its own seed: case i of seed S can be regenerated alone
            let mut r = Rng::new(cfg.seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ i);
            if cfg.bin.is_some() && cfg.cli_every > 0 && i.is_multiple_of(cfg.cli_every) {
                gen_cli_case(&mut r, &seeds)
            } else {
                gen_model_case(&mut r, &seeds)
            }
        };
        i += 1;
        let o = if case.is_cli() {
            match &cfg.bin {
                Some(b) => run_cli_case(b, &case, &dir, cfg.hang_limit),
                None => Outcome::ok("cli_skipped_no_binary"),
            }
        } else {
            if worker.is_none() {
                worker = Some(Worker::spawn(&cfg.worker_cmd, &cfg.worker_env)?);
                rep.worker_restarts += 1;
            }
            match worker.as_mut().map(|w| w.run(&case, cfg.hang_limit)) {
                Some(Ok(o)) => o,
                Some(Err(o)) => {
                    worker = None;
                    o
                }
                None => Outcome::ok("no_worker"),
            }
        };
        rep.cases += 1;
        record(&mut rep, cfg, &case, &o);
        if cfg.progress && Instant::now() >= next_report {
            next_report = Instant::now() + Duration::from_secs(10);
            let s = t0.elapsed().as_secs_f64();
            eprintln!(
                "{} cases, {:.0}/s, {} findings ({} distinct)",
                rep.cases,
                rep.cases as f64 / s,
                rep.finding_count(),
                rep.findings.len()
            );
        }
    }
    rep.worker_restarts = rep.worker_restarts.saturating_sub(1);
    rep.seconds = t0.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    Ok(rep)
}

/// Every `*.json` case in `dir`, sorted by name.
pub fn load_cases(dir: &Path) -> Result<Vec<(PathBuf, Case)>, String> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Ok(out);
    };
    let mut paths: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    paths.sort();
    for p in paths {
        let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        let v: Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))?;
        out.push((
            p.clone(),
            Case::from_json(&v).map_err(|e| format!("{}: {e}", p.display()))?,
        ));
    }
    Ok(out)
}
