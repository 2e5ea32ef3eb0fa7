//! Ensembles: many variants of one model in one run, written to one HDF5 file.
//!
//! Every variant is compiled from the same file with its own parameter values; all must
//! share the topology (nodes, elements, coordinates, sensors) and the output time grid,
//! which is checked before any work starts. Variants are split into batches (in variant
//! order, see [`batch_size`]) that run in parallel on a rayon pool; the variants of a
//! batch advance in lockstep on one worker, each with its own state and step control, and
//! every round of their element stages is one call of the element stage
//! ([`crate::solver::batch`]). A variant that cuts its step only posts in more rounds, and
//! one that fails is marked failed while the others complete. Each variant runs exactly
//! the code path of a single `run` (a batch of one), so its numbers are bit-identical to
//! running it alone, in any batch. Each finished variant's samples go into the campaign file, which is
//! flushed (rewritten atomically) at most every 2 s and at the end; on Ctrl-C the
//! variants in flight stop before their next time step, their samples so far are kept,
//! and the file is finished as "interrupted". If the file cannot be written mid-campaign
//! (disk full, directory removed), no new variant starts, the variants in flight stop at
//! their next time step, the last flushed file stays as it was, and the outcomes are
//! still returned ([`run_to`]) so the caller can report them.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use rayon::prelude::*;

use crate::assembly::Assembler;
use crate::element::{CpuEval, ElementEval};
use crate::joint::State;
use crate::linalg::SparseLuSymbolic;
use crate::model::{self, Model};
use crate::output::{
    CampaignMeta, CampaignWriter, OutputError, OutputTarget, SensorMeta, VariantState,
    VariantStatus,
};
use crate::sensors;
use crate::solver::batch::{drive, panic_message, BatchCounts, Member, Slot};
use crate::solver::dynamics::StageTimes;
use crate::solver::dynamics::{self, DynamicsError};
use crate::solver::linear::NewtonSystem;
use crate::verify::MeshTwinSkip;

#[derive(Debug, thiserror::Error)]
pub enum EnsembleError {
    // transparent: with `{0}` and a source, a chain printer shows the message twice
    #[error(transparent)]
    Model(#[from] model::ModelError),
    #[error(transparent)]
    Output(#[from] OutputError),
    // (a field of megabytes in a --variants CSV is cut in the message)
    #[error("{}", model::elide_long_words(.0))]
    Invalid(String),
    /// A problem of one variant (its model does not compile with its values, or it does
    /// not fit the others): `at` names the variant, by its index and values (see
    /// [`Origin::name`] for where the user gave them), `message` is the problem (a model
    /// error keeps the model's file, line and field).
    #[error(
        "{}: {}",
        model::elide_long_words(at),
        model::elide_long_words(message)
    )]
    Variant {
        index: usize,
        at: String,
        message: String,
    },
    /// A signal stopped the preparation ([`prepare_until`]) before every variant was
    /// compiled: nothing ran.
    #[error(
        "interrupted by a signal while preparing the variants ({compiled} of {total} \
         compiled)"
    )]
    Interrupted { compiled: usize, total: usize },
}

impl EnsembleError {
    /// A problem of variant `index` with parameter values `values`.
    pub fn variant(index: usize, values: &[(String, f64)], message: impl ToString) -> Self {
        EnsembleError::Variant {
            index,
            at: Origin::default().describe(index, values),
            message: message.to_string(),
        }
    }
}

/// One variant's parameter values, by name (a `--variants` row, a `--vary` grid point, or
/// both).
pub type Values = Vec<(String, f64)>;

/// Where the variants of a sweep come from (see [`variants_with_origin`]), to name a
/// variant in a message the way the user gave it: a campaign of 1000 rows whose third
/// one breaks the model must say which row, not only the model's line. The variants are
/// the `--variants` rows (in file order) each crossed with the `--vary` grid (see
/// [`variants`]); the default knows nothing and names a variant by its index and values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Origin {
    /// the `--variants` file and the line of each of its rows, in order (1-based, counting
    /// the header, comments and blank lines as the file has them)
    pub csv: Option<(PathBuf, Vec<usize>)>,
    /// the leading values of each variant that come from its CSV row (its columns); the
    /// others are its point of the `--vary` grid
    pub csv_columns: usize,
    /// points of the `--vary` grid (1 without `--vary`; 0: unknown)
    pub grid_points: usize,
}

impl Origin {
    /// Variant `index` with parameter values `values`, as a message names it:
    /// `variant 7 (--variants rows.csv line 4: EI=-1; --vary L=2)`.
    pub fn describe(&self, index: usize, values: &[(String, f64)]) -> String {
        let line = match (&self.csv, self.grid_points) {
            (Some((path, lines)), g) if g > 0 => lines
                .get(index / g)
                .map(|l| (path, *l))
                .filter(|_| self.csv_columns <= values.len()),
            _ => None,
        };
        let parts = match line {
            Some((path, l)) => {
                let (row, point) = values.split_at(self.csv_columns);
                let mut s = format!("--variants {} line {l}", path.display());
                if !row.is_empty() {
                    s += &format!(": {}", describe(row));
                }
                if !point.is_empty() {
                    s += &format!("; --vary {}", describe(point));
                }
                s
            }
            None if self.grid_points > 0 && self.csv.is_none() && !values.is_empty() => {
                format!("--vary {}", describe(values))
            }
            None => describe(values),
        };
        if parts.is_empty() {
            format!("variant {index}")
        } else {
            format!("variant {index} ({parts})")
        }
    }

    /// `e`, when it is the problem of one variant ([`EnsembleError::Variant`]), with that
    /// variant named by [`Origin::describe`] (`variants`: the campaign's, by global
    /// index); other errors as they are.
    pub fn name(&self, e: EnsembleError, variants: &[Vec<(String, f64)>]) -> EnsembleError {
        match e {
            EnsembleError::Variant { index, at, message } => EnsembleError::Variant {
                index,
                at: variants.get(index).map_or(at, |v| self.describe(index, v)),
                message,
            },
            e => e,
        }
    }
}

/// Shortest time between two flushes of the campaign file [s]: each flush rewrites the
/// file, so flushing after every short variant would serialise the workers.
const FLUSH_INTERVAL_S: f64 = 2.0;

/// Default variants per batch of a CPU campaign (`sweep --batch`), measured in
/// docs/bench/batch.md.
pub const DEFAULT_BATCH: usize = 8;

/// Variants per batch: `batch` (at least 1), but no more than keep every one of `threads`
/// workers busy: a batch runs on one worker, so 10 variants in batches of 8 on 2 threads
/// would leave one thread with 8 variants and the other with 2.
pub fn batch_size(batch: usize, variants: usize, threads: usize) -> usize {
    batch.clamp(1, variants.div_ceil(threads.max(1)).max(1))
}

/// A `--vary NAME=START:STOP:COUNT` range.
#[derive(Clone, Debug, PartialEq)]
pub struct Range {
    pub name: String,
    pub start: f64,
    pub stop: f64,
    pub count: usize,
}

impl Range {
    /// Parse `NAME=START:STOP:COUNT` (START, STOP may be expressions such as `2*pi`).
    pub fn parse(s: &str) -> Result<Range, String> {
        let (name, rest) = s
            .split_once('=')
            .ok_or_else(|| format!("`{s}`: expected NAME=START:STOP:COUNT"))?;
        let parts: Vec<&str> = rest.split(':').collect();
        if parts.len() != 3 {
            return Err(format!("`{s}`: expected NAME=START:STOP:COUNT"));
        }
        let num = |t: &str| model::expr::eval(t.trim(), &[]).map_err(|e| format!("`{s}`: {e}"));
        let count: usize = parts[2]
            .trim()
            .parse()
            .map_err(|_| format!("`{s}`: COUNT must be a positive integer"))?;
        if count == 0 {
            return Err(format!("`{s}`: COUNT must be at least 1"));
        }
        // before anything allocates one entry per value
        let limit = model::Limits::from_env()?.variants;
        if count as u64 > limit {
            return Err(format!(
                "`{s}`: {}",
                model::limits::exceeded("COUNT (values)", count as f64, "variants", limit)
            ));
        }
        Ok(Range {
            name: name.trim().to_string(),
            start: num(parts[0])?,
            stop: num(parts[1])?,
            count,
        })
    }

    pub fn values(&self) -> Vec<f64> {
        if self.count == 1 {
            return vec![self.start];
        }
        let n = (self.count - 1) as f64;
        let span = self.stop - self.start;
        if span.is_finite() {
            // the last value is STOP itself, as numpy's linspace gives it: start + span
            // rounds (1e-3:2.5e-4:4 ended at 2.4999999999999999e-4, so the variant was not
            // bit-identical to `run --set dt=2.5e-4`; a probe, session 47). A campaign
            // written before whose last value was an ulp off is refused by --resume as a
            // changed definition (variants_sha256), not resumed with other values.
            (0..self.count)
                .map(|i| {
                    if i + 1 == self.count {
                        self.stop
                    } else {
                        self.start + span * i as f64 / n
                    }
                })
                .collect()
        } else {
            // a span past f64 (1e308 to -1e308) made every value but the first NaN; the
            // weighted form stays finite (the arithmetic above is kept where it is finite,
            // so campaigns keep their parameter values bit for bit)
            (0..self.count)
                .map(|i| {
                    let f = i as f64 / n;
                    self.start * (1.0 - f) + self.stop * f
                })
                .collect()
        }
    }
}

/// The variants of a sweep: the `--vary` grid, the rows of a `--variants` CSV, or every
/// row crossed with the grid. Checked before anything is allocated per variant: each
/// parameter is given by one source only, names a parameter of the model (loaded with
/// the `--set` overrides `base`), and the variant count and the values the campaign keeps
/// stay within the limits (see [`model::limits`]).
pub fn variants(
    model_path: &Path,
    base: &[(String, f64)],
    vary: &[Range],
    csv: Option<&Path>,
) -> Result<Vec<Vec<(String, f64)>>, EnsembleError> {
    variants_with_origin(model_path, base, vary, csv).map(|(v, _)| v)
}

/// [`variants`], with where each one comes from (its CSV line, its grid point), for
/// messages about one variant (see [`Origin::name`]).
pub fn variants_with_origin(
    model_path: &Path,
    base: &[(String, f64)],
    vary: &[Range],
    csv: Option<&Path>,
) -> Result<(Vec<Values>, Origin), EnsembleError> {
    let lim = model::Limits::from_env().map_err(EnsembleError::Invalid)?;
    for (i, r) in vary.iter().enumerate() {
        if let Some(first) = vary[..i].iter().find(|x| x.name == r.name) {
            return Err(EnsembleError::Invalid(format!(
                "--vary {}: given twice ({}={}:{}:{} and {}={}:{}:{}); vary a parameter once \
                 (list arbitrary values in a --variants CSV)",
                r.name,
                first.name,
                first.start,
                first.stop,
                first.count,
                r.name,
                r.start,
                r.stop,
                r.count
            )));
        }
    }
    // a parameter both set and varied: the variants' values would silently replace the
    // one given with --set
    if let Some(r) = vary.iter().find(|r| base.iter().any(|(n, _)| *n == r.name)) {
        return Err(EnsembleError::Invalid(format!(
            "--set {} and --vary {} both give `{}`: give each parameter in one of them",
            r.name, r.name, r.name
        )));
    }
    let grid_count: f64 = vary.iter().map(|r| r.count as f64).product();
    let too_many = |n: f64, what: &str| {
        EnsembleError::Invalid(model::limits::exceeded(what, n, "variants", lim.variants))
    };
    if grid_count > lim.variants as f64 {
        return Err(too_many(grid_count, "--vary: variants of the grid"));
    }
    let (rows, lines) = match csv {
        Some(p) => {
            let (rows, lines) = read_variants_table(p)?;
            (Some(rows), lines)
        }
        None => (None, Vec::new()),
    };
    if let (Some(rows), Some(p)) = (&rows, csv) {
        if let Some(r) = vary
            .iter()
            .find(|r| rows[0].iter().any(|(n, _)| *n == r.name))
        {
            return Err(EnsembleError::Invalid(format!(
                "--vary {} and --variants {} both set `{}`: give each parameter in one of them",
                r.name,
                p.display(),
                r.name
            )));
        }
        if let Some((n, _)) = base
            .iter()
            .find(|(n, _)| rows[0].iter().any(|(c, _)| c == n))
        {
            return Err(EnsembleError::Invalid(format!(
                "--set {n} and --variants {} both give `{n}`: give each parameter in one of them",
                p.display()
            )));
        }
        let total = rows.len() as f64 * grid_count;
        if total > lim.variants as f64 {
            return Err(too_many(
                total,
                "--variants rows × --vary grid: variants of the campaign",
            ));
        }
    }
    let m = model::load(model_path, base)?;
    let known = |n: &str| m.params.iter().any(|(p, _)| p == n);
    let names: Vec<&str> = m.params.iter().map(|(n, _)| n.as_str()).collect();
    let listed = if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    };
    if let Some(r) = vary.iter().find(|r| !known(&r.name)) {
        return Err(EnsembleError::Invalid(format!(
            "--vary {}: the model has no parameter `{}` (parameters: {listed})",
            r.name, r.name
        )));
    }
    if let (Some(rows), Some(p)) = (&rows, csv) {
        if let Some((n, _)) = rows[0].iter().find(|(n, _)| !known(n)) {
            return Err(EnsembleError::Invalid(format!(
                "--variants {}: column `{n}`: the model has no parameter `{n}` (parameters: \
                 {listed})",
                p.display()
            )));
        }
    }
    let n_var = rows.as_ref().map_or(1.0, |r| r.len() as f64) * grid_count;
    let per_variant = dynamics::output_times(&m).len() as f64
        * (1.0
            + m.sensors
                .iter()
                .map(|s| sensors::components(&s.kind).len() as f64)
                .sum::<f64>());
    if per_variant * n_var > lim.output_values as f64 {
        return Err(EnsembleError::Invalid(model::limits::exceeded(
            &format!(
                "values the campaign keeps, {} per variant (output samples × (sensor \
                 components + time)) × {} variants",
                model::limits::count(per_variant),
                model::limits::count(n_var)
            ),
            per_variant * n_var,
            "output_values",
            lim.output_values,
        )));
    }
    let g = grid(vary)?;
    let origin = Origin {
        csv_columns: rows.as_ref().map_or(0, |r| r[0].len()),
        csv: csv.map(|p| (p.to_path_buf(), lines)),
        grid_points: g.len(),
    };
    let list = match rows {
        None => g,
        // the CSV rows crossed with the --vary grid
        Some(rows) => rows
            .iter()
            .flat_map(|r| {
                g.iter().map(move |x| {
                    let mut v = r.clone();
                    v.extend(x.iter().cloned());
                    v
                })
            })
            .collect(),
    };
    Ok((list, origin))
}

/// The full grid of several ranges (last range varies fastest); callers check its size
/// first (see [`variants`]).
pub fn grid(ranges: &[Range]) -> Result<Vec<Vec<(String, f64)>>, EnsembleError> {
    let mut out: Vec<Vec<(String, f64)>> = vec![vec![]];
    let total: f64 = ranges.iter().map(|r| r.count as f64).product();
    for r in ranges {
        // limits raised past the machine (`LATDYN_LIMITS=variants=1e18`) let a grid of
        // 2.8e14 variants ask for 103 GB here, which aborted (exit 134)
        let want = out.len().saturating_mul(r.count);
        let mut next = Vec::new();
        next.try_reserve_exact(want).map_err(|_| {
            EnsembleError::Invalid(format!(
                "the grid of --vary ranges has {} variants: their list alone does not fit \
                 in memory (at least {} bytes); vary fewer values (LATDYN_LIMITS key \
                 `variants` bounds a campaign for this reason)",
                model::limits::count(total),
                model::limits::count(
                    want as f64 * std::mem::size_of::<Vec<(String, f64)>>() as f64
                )
            ))
        })?;
        for row in &out {
            for v in r.values() {
                let mut row = row.clone();
                row.push((r.name.clone(), v));
                next.push(row);
            }
        }
        out = next;
    }
    Ok(out)
}

/// The fields of one CSV line (RFC 4180 on one physical line): separated by commas,
/// each without its surrounding white space. A field in double quotes may contain commas,
/// and `""` inside the quotes is one literal quote; the quotes and the white space just
/// inside them are dropped (a spreadsheet's `" 1.5 "` is 1.5). The split respects the
/// quotes, so `"1,5",2` is two fields, the first `1,5` (which is then not a number, and
/// is reported as such instead of miscounting the columns). The error says what is wrong
/// with the line: a quote not closed on it, or text after a closing quote.
fn split_csv_line(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut rest = line;
    loop {
        let column = fields.len() + 1;
        let t = rest.trim_start();
        let Some(q) = t.strip_prefix('"') else {
            match t.split_once(',') {
                Some((f, r)) => {
                    fields.push(f.trim().to_string());
                    rest = r;
                    continue;
                }
                None => {
                    fields.push(t.trim().to_string());
                    return Ok(fields);
                }
            }
        };
        let mut f = String::new();
        let mut it = q.char_indices();
        let after = loop {
            match it.next() {
                Some((i, '"')) if q[i + 1..].starts_with('"') => {
                    it.next();
                    f.push('"');
                }
                Some((i, '"')) => break q[i + 1..].trim_start(),
                Some((_, c)) => f.push(c),
                None => {
                    return Err(format!(
                        "field {column}: the quote that opens it is not closed on this line \
                         (a quote inside a quoted field is written twice, `\"\"`)"
                    ))
                }
            }
        };
        fields.push(f.trim().to_string());
        match after.strip_prefix(',') {
            Some(r) => rest = r,
            None if after.is_empty() => return Ok(fields),
            None => {
                let junk = after.split(',').next().unwrap_or(after).trim_end();
                return Err(format!(
                    "field {column}: `{junk}` follows its closing quote (a quote inside a \
                     quoted field is written twice, `\"\"`)"
                ));
            }
        }
    }
}

/// Variants from a CSV file: a header of parameter names, one row of values per variant
/// (fields may be quoted; a leading byte-order mark is skipped).
pub fn read_variants_csv(path: &Path) -> Result<Vec<Vec<(String, f64)>>, EnsembleError> {
    read_variants_table(path).map(|(rows, _)| rows)
}

/// [`read_variants_csv`], with the line of each row in the file (1-based, the header and
/// any comment or blank line counted).
fn read_variants_table(path: &Path) -> Result<(Vec<Values>, Vec<usize>), EnsembleError> {
    let lim = model::Limits::from_env().map_err(EnsembleError::Invalid)?;
    let text = model::limits::read_capped(path, lim.model_bytes, "--variants file")
        .map_err(|e| EnsembleError::Invalid(format!("{}: {e}", path.display())))?;
    // a spreadsheet's export may begin with a byte-order mark and quote its fields
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (header_ln, header) = lines
        .next()
        .ok_or_else(|| EnsembleError::Invalid(format!("{}: empty file", path.display())))?;
    let names: Vec<String> = split_csv_line(header).map_err(|e| {
        EnsembleError::Invalid(format!("{}:{}: {e}", path.display(), header_ln + 1))
    })?;
    for (i, n) in names.iter().enumerate() {
        if n.is_empty() {
            return Err(EnsembleError::Invalid(format!(
                "{}: header column {} has no name",
                path.display(),
                i + 1
            )));
        }
        if names[..i].contains(n) {
            return Err(EnsembleError::Invalid(format!(
                "{}: column `{n}` appears twice in the header (columns {} and {})",
                path.display(),
                names[..i].iter().position(|x| x == n).map_or(0, |k| k + 1),
                i + 1
            )));
        }
    }
    let mut rows = Vec::new();
    let mut row_lines = Vec::new();
    for (ln, line) in lines {
        if rows.len() as u64 >= lim.variants {
            return Err(EnsembleError::Invalid(format!(
                "{}: {}",
                path.display(),
                model::limits::exceeded(
                    "variant rows",
                    (rows.len() + 1) as f64,
                    "variants",
                    lim.variants
                )
            )));
        }
        let vals = split_csv_line(line)
            .map_err(|e| EnsembleError::Invalid(format!("{}:{}: {e}", path.display(), ln + 1)))?;
        if vals.len() != names.len() {
            return Err(EnsembleError::Invalid(format!(
                "{}:{}: {} values for {} columns",
                path.display(),
                ln + 1,
                vals.len(),
                names.len()
            )));
        }
        let mut row = Vec::new();
        for (k, (n, v)) in names.iter().zip(&vals).enumerate() {
            let x: f64 = v
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| {
                    EnsembleError::Invalid(format!(
                        "{}:{}: column `{n}` (field {}): `{v}` is not a finite number{}",
                        path.display(),
                        ln + 1,
                        k + 1,
                        if v.contains(',') {
                            " (write the decimal point as `.`)"
                        } else {
                            ""
                        }
                    ))
                })?;
            row.push((n.clone(), x));
        }
        rows.push(row);
        row_lines.push(ln + 1);
    }
    if rows.is_empty() {
        return Err(EnsembleError::Invalid(format!(
            "{}: no variant rows under the header",
            path.display()
        )));
    }
    Ok((rows, row_lines))
}

/// What to run.
#[derive(Clone, Debug)]
pub struct Campaign {
    pub model_path: PathBuf,
    /// `--set` overrides shared by all variants
    pub base: Vec<(String, f64)>,
    /// per-variant overrides (all rows name the same parameters)
    pub variants: Vec<Vec<(String, f64)>>,
    pub threads: usize,
    /// variants per batch: advanced in lockstep on one worker thread, their element
    /// stages evaluated together (see [`crate::solver::batch`] and [`batch_size`])
    pub batch: usize,
    pub output: Option<PathBuf>,
    /// (K, N): run only variants with index % N == K − 1
    pub shard: Option<(usize, usize)>,
    /// `--accuracy`: overrides every variant's `[solver] accuracy`
    pub accuracy: Option<f64>,
    /// sensor (and component) whose dominant frequency becomes `first_bending_hz`
    pub frequency_sensor: Option<(String, usize)>,
    pub command_line: String,
}

/// Summary of one sensor over a run.
#[derive(Clone, Debug)]
pub struct SensorSummary {
    pub min: Vec<f64>,
    pub max: Vec<f64>,
    pub last: Vec<f64>,
}

/// Outcome of one variant.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub global_index: usize,
    pub parameters: Vec<(String, f64)>,
    pub state: VariantState,
    pub message: String,
    pub t_fail: f64,
    pub steps: usize,
    pub rejected_steps: usize,
    pub newton_iterations: usize,
    /// with an accuracy target: the runs made to meet it and their steps together (see
    /// `RunStats::accuracy_runs`); 0 without
    pub accuracy_runs: usize,
    pub accuracy_steps: usize,
    /// from its batch's start to its end: the variants of a batch share one thread, so
    /// this includes the other variants' work until it ended
    pub wall_s: f64,
    /// wall time per stage (element, assembly, factorization, output incl. file writes)
    pub times: StageTimes,
    pub sensors: Vec<SensorSummary>,
    pub derived: Vec<(String, f64)>,
    /// growth of the energy balance (see `RunStats::energy_growth`; None where not run)
    pub energy_growth: Option<f64>,
    /// numerical loss of the energy balance (see `RunStats::energy_loss`)
    pub energy_loss: Option<f64>,
    /// estimated relative time-discretisation error (see `RunStats::time_error_estimate`)
    pub time_error_estimate: Option<f64>,
    /// the same just before the first hinge lock (see
    /// `RunStats::time_error_before_first_lock`; None without one)
    pub time_error_before_first_lock: Option<f64>,
    /// estimated relative mesh error from its mesh twin (`--mesh-check`, see
    /// [`crate::verify::MeshSample`]; None where not measured)
    pub mesh_error_estimate: Option<f64>,
    /// warnings about the variant's numbers, each naming its likely cause (energy
    /// balance, time error, `first_bending_hz: <kind>: ...` from `--frequency`, see
    /// crate::frequency)
    pub warnings: Vec<String>,
    /// full histories, kept only when asked for (single runs)
    pub history: Option<dynamics::History>,
    /// the variant ended in a panic (a bug in latdyn), caught and marked failed
    pub panicked: bool,
    /// after an output failure: whether the file's last good write holds this variant's
    /// result (`false`: it ran, but the file shows it running or pending, and
    /// `sweep --resume` reruns it); `None` when there is no file or it was written whole
    pub in_file: Option<bool>,
}

/// Outcomes of a campaign run by [`run_to`], with the error that stopped its output.
pub struct CampaignRun {
    /// one per variant of this shard; variants never started (after an output error)
    /// are [`VariantState::Pending`]
    pub outcomes: Vec<Outcome>,
    /// the campaign file could not be written mid-run (the last flush is what is on disk)
    pub output_error: Option<OutputError>,
    /// what `--verify` measured (see [`run_verified_to`])
    pub verification: Option<crate::verify::Verification>,
    /// what `--mesh-check` measured on its sampled variants of this shard (in the order
    /// of [`crate::verify::MeshSample::variants`]), with the wall time of all twins;
    /// None where no twin was to run
    pub mesh: Option<(Vec<crate::verify::VariantMesh>, f64)>,
    /// calls of the element stage and the requests they carried (see
    /// [`crate::solver::batch`])
    pub batch: BatchCounts,
}

/// Compiled variants with their checked common layout.
pub struct Prepared {
    pub models: Vec<Model>,
    pub global_index: Vec<usize>,
    pub parameter_names: Vec<String>,
    pub time: Vec<f64>,
    /// one symbolic LU analysis shared by all variants (they share the pattern)
    pub symbolic: Option<Arc<SparseLuSymbolic>>,
    /// the model with the shared overrides, compiled only when this shard has no variant:
    /// the campaign file still gets its parameter names, time grid and (empty) sensors
    pub reference: Option<Model>,
}

/// `/derived/` name of a sampled variant's first bending frequency's mesh error
/// (`sweep --frequency` with `--mesh-check`, see [`crate::verify::frequency_mesh_error`]).
pub const FIRST_BENDING_MESH_ERROR: &str = "first_bending_mesh_error";

/// Compile every variant (of this shard) and check they share topology and time grid.
pub fn prepare(c: &Campaign) -> Result<Prepared, EnsembleError> {
    prepare_until(c, &AtomicBool::new(false))
}

/// [`prepare`], stopped by `stop` (a signal's flag) between two variants: a campaign of
/// large models spends seconds compiling before any variant runs, and Ctrl-C there must
/// end it as cleanly as during the run. Then [`EnsembleError::Interrupted`] is returned.
pub fn prepare_until(c: &Campaign, stop: &AtomicBool) -> Result<Prepared, EnsembleError> {
    let n_all = c.variants.len();
    let (k, n) = c.shard.unwrap_or((1, 1));
    if n == 0 || k == 0 || k > n {
        return Err(EnsembleError::Invalid(format!(
            "--shard {k}/{n}: need 1 ≤ K ≤ N"
        )));
    }
    let global_index: Vec<usize> = (0..n_all).filter(|i| i % n == k - 1).collect();
    prepare_rows_until(c, global_index, stop)
}

/// [`prepare`] for the variants with these global indices (`sweep --resume`: the ones
/// a campaign file still lacks), whatever the shard.
pub fn prepare_rows(c: &Campaign, global_index: Vec<usize>) -> Result<Prepared, EnsembleError> {
    prepare_rows_until(c, global_index, &AtomicBool::new(false))
}

/// [`prepare_rows`], stopped by `stop` as [`prepare_until`].
pub fn prepare_rows_until(
    c: &Campaign,
    global_index: Vec<usize>,
    stop: &AtomicBool,
) -> Result<Prepared, EnsembleError> {
    if let Some(g) = global_index.iter().find(|&&g| g >= c.variants.len()) {
        return Err(EnsembleError::Invalid(format!(
            "variant {g} is outside the campaign's {} variants",
            c.variants.len()
        )));
    }
    // The file is read and parsed once; each variant compiles its own parameter values
    // from the parsed spec (the same model as `model::load`), on the campaign's threads.
    // The first failing variant (in order) is the one reported, as when compiled in turn,
    // named with its values (the model error alone points at the model's line, the same
    // for every variant).
    let parsed = model::parse_file(&c.model_path)?;
    let total = global_index.len();
    let compiled = std::sync::atomic::AtomicUsize::new(0);
    let interrupted = || EnsembleError::Interrupted {
        compiled: compiled.load(Ordering::SeqCst),
        total,
    };
    let compile = |gi: usize| -> Result<Model, EnsembleError> {
        // checked before each variant: the ones in flight finish (one compile is short)
        if stop.load(Ordering::SeqCst) {
            return Err(interrupted());
        }
        let mut sets = c.base.clone();
        sets.extend(c.variants[gi].iter().cloned());
        let mut m = parsed
            .compile(&sets)
            .map_err(|e| EnsembleError::variant(gi, &c.variants[gi], e))?;
        if c.accuracy.is_some() {
            m.solver.accuracy = c.accuracy;
        }
        compiled.fetch_add(1, Ordering::SeqCst);
        Ok(m)
    };
    let models: Vec<Model> = if c.threads > 1 && global_index.len() > 1 {
        let results: Vec<Result<Model, EnsembleError>> = rayon::ThreadPoolBuilder::new()
            .num_threads(c.threads)
            .build()
            .map_err(|e| EnsembleError::Invalid(format!("thread pool: {e}")))?
            .install(|| global_index.par_iter().map(|&gi| compile(gi)).collect());
        if stop.load(Ordering::SeqCst) {
            return Err(interrupted());
        }
        results.into_iter().collect::<Result<_, _>>()?
    } else {
        global_index
            .iter()
            .map(|&gi| compile(gi))
            .collect::<Result<_, _>>()?
    };
    // a signal after the last variant compiled: the checks below and the symbolic
    // analysis are quick, the run checks the flag before its first step
    let reference = if models.is_empty() {
        let mut sets = c.base.clone();
        sets.extend(c.variants.first().into_iter().flatten().cloned());
        Some(
            parsed
                .compile(&sets)
                .map_err(|e| match c.variants.first() {
                    Some(v) => EnsembleError::variant(0, v, e),
                    None => e.into(),
                })?,
        )
    } else {
        None
    };
    let layout = models.first().or(reference.as_ref());
    let parameter_names: Vec<String> = match layout {
        Some(m) => m.params.iter().map(|(n, _)| n.clone()).collect(),
        None => Vec::new(),
    };
    let time = layout.map(dynamics::output_times).unwrap_or_default();
    if let Some(first) = models.first() {
        let sig = topology(first);
        for (m, &gi) in models.iter().zip(&global_index).skip(1) {
            let s = topology(m);
            if s != sig {
                return Err(EnsembleError::variant(
                    gi,
                    &c.variants[gi],
                    format!(
                        "changes the model's topology ({s}) against variant {} ({sig}): all \
                         variants of a campaign must share nodes, elements, coordinates and \
                         sensors",
                        global_index[0],
                    ),
                ));
            }
            if dynamics::output_times(m) != time {
                return Err(EnsembleError::variant(
                    gi,
                    &c.variants[gi],
                    "has another output time grid (t_end, dt, output_dt): all variants must \
                     report on the same grid",
                ));
            }
        }
    }
    let symbolic = models.first().and_then(|m| {
        let asm = Assembler::new(m);
        let st = State::new(m);
        NewtonSystem::new(m, &asm, &st)
            .ok()
            .map(|sys| Arc::clone(sys.symbolic()))
    });
    Ok(Prepared {
        models,
        global_index,
        parameter_names,
        time,
        symbolic,
        reference,
    })
}

fn describe(p: &[(String, f64)]) -> String {
    p.iter()
        .map(|(n, v)| format!("{n}={v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Topology signature: what must not change between variants.
fn topology(m: &Model) -> String {
    let sensors: Vec<String> = m
        .sensors
        .iter()
        .map(|s| format!("{}:{}", s.name, sensors::components(&s.kind).len()))
        .collect();
    format!(
        "{} nodes, {} elements, {} coordinates ({} free), sensors [{}]",
        m.x0.len(),
        m.elements.len(),
        m.dofs.len(),
        m.n_eq,
        sensors.join(" ")
    )
}

/// Where a campaign's element stage runs (see `crate::gpu`), and what the campaign file
/// records about it.
#[derive(Clone)]
pub struct Stage {
    /// "cpu" or "gpu"
    pub backend: String,
    /// "f64" or "f32"
    pub precision: String,
    /// GPU adapter label, empty on the CPU
    pub adapter: String,
    /// makes each variant's element stage (None: the CPU functions)
    pub make: Option<Arc<dyn Fn() -> Arc<dyn ElementEval> + Send + Sync>>,
}

impl Stage {
    pub fn cpu() -> Stage {
        Stage {
            backend: "cpu".into(),
            precision: "f64".into(),
            adapter: String::new(),
            make: None,
        }
    }

    /// The context of one run on its own (a single run, a mesh twin, a refined run of
    /// `--verify`): stopped by `stop`, its element stage made by this stage, no shared
    /// symbolic analysis.
    pub fn run_context<'a>(&self, stop: &'a AtomicBool) -> dynamics::RunContext<'a> {
        dynamics::RunContext {
            stop: Some(stop),
            symbolic: None,
            eval: self.make.as_ref().map(|make| make()),
        }
    }
}

/// Run the prepared variants. `stop` ends the campaign early (Ctrl-C); `progress` is
/// called after each finished variant with (done, total).
pub fn run(
    c: &Campaign,
    p: &Prepared,
    stop: &AtomicBool,
    keep_history: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<Outcome>, EnsembleError> {
    run_on(c, p, stop, keep_history, progress, &Stage::cpu())
}

/// [`run`] with the element stage of every variant from `stage` (each variant's solver is
/// unchanged; only its element evaluations go elsewhere, e.g. to a shared GPU stage).
pub fn run_on(
    c: &Campaign,
    p: &Prepared,
    stop: &AtomicBool,
    keep_history: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
    stage: &Stage,
) -> Result<Vec<Outcome>, EnsembleError> {
    let target = c.output.as_deref().map(OutputTarget::claim).transpose()?;
    let r = run_to(c, p, stop, keep_history, progress, stage, target)?;
    match r.output_error {
        Some(e) => Err(e.into()),
        None => Ok(r.outcomes),
    }
}

/// [`run_on`] writing to `target` (claimed by the caller, before its preparations), for
/// callers that report the outcomes even when the output failed mid-run: an error
/// writing the file stops the campaign (no new variant starts, those in flight stop at
/// their next time step) and is returned beside the outcomes. Errors before any
/// variant ran (the file cannot be created) are returned as `Err`.
pub fn run_to(
    c: &Campaign,
    p: &Prepared,
    stop: &AtomicBool,
    keep_history: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
    stage: &Stage,
    target: Option<OutputTarget>,
) -> Result<CampaignRun, EnsembleError> {
    run_verified_to(
        c,
        p,
        stop,
        keep_history,
        progress,
        stage,
        target,
        None,
        None,
    )
}

/// [`run_to`], then, when `verify` names variants (global indices of this shard, see
/// [`crate::verify::select`]), their refined runs on the same pool
/// ([`crate::verify::run`]) once every variant has finished; what they measured is
/// returned and written to the campaign file (`/verification`) before it is finished.
/// Nothing is verified after an output error or an interruption. Before that, the
/// variants `mesh` samples get their mesh twins ([`crate::verify::measure_mesh`]), the
/// same as `run` gives each run: their figures and warnings go to their rows.
#[allow(clippy::too_many_arguments)]
pub fn run_verified_to(
    c: &Campaign,
    p: &Prepared,
    stop: &AtomicBool,
    keep_history: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
    stage: &Stage,
    target: Option<OutputTarget>,
    verify: Option<&[usize]>,
    mesh: Option<&crate::verify::MeshSample>,
) -> Result<CampaignRun, EnsembleError> {
    let writer = match target {
        Some(target) => {
            let first = p.models.first().or(p.reference.as_ref());
            let meta = CampaignMeta {
                command_line: c.command_line.clone(),
                model_path: c.model_path.display().to_string(),
                model_source: first.map(|m| m.source.clone()).unwrap_or_default(),
                backend: stage.backend.clone(),
                precision: stage.precision.clone(),
                adapter: stage.adapter.clone(),
                threads: c.threads,
                parameter_names: p.parameter_names.clone(),
                parameter_values: p
                    .models
                    .iter()
                    .map(|m| m.params.iter().map(|(_, v)| *v).collect())
                    .collect(),
                global_index: p.global_index.clone(),
                time: p.time.clone(),
                sensors: first.map(SensorMeta::of_model).unwrap_or_default(),
            };
            let info = identify(c, p, stage)?;
            Some(CampaignWriter::create_with(target, &meta, Some(info))?)
        }
        None => None,
    };
    run_core(
        c,
        p,
        stop,
        keep_history,
        progress,
        stage,
        writer,
        None,
        verify,
        mesh,
    )
}

/// `sweep --resume`: run the prepared variants (see [`prepare_rows`]) into `writer`, an
/// existing campaign file reopened ([`CampaignWriter::reopen`]), variant `v` of `p` going
/// to the file's row `rows[v]`; the file is finished as for [`run_to`]. The variants of
/// `mesh` among those run get their mesh twins, as in [`run_verified_to`].
#[allow(clippy::too_many_arguments)]
pub fn run_resume(
    c: &Campaign,
    p: &Prepared,
    stop: &AtomicBool,
    progress: &(dyn Fn(usize, usize) + Sync),
    stage: &Stage,
    writer: CampaignWriter,
    rows: &[usize],
    mesh: Option<&crate::verify::MeshSample>,
) -> Result<CampaignRun, EnsembleError> {
    if rows.len() != p.models.len() {
        return Err(EnsembleError::Invalid(format!(
            "resume: {} rows for {} variants",
            rows.len(),
            p.models.len()
        )));
    }
    run_core(
        c,
        p,
        stop,
        false,
        progress,
        stage,
        Some(writer),
        Some(rows),
        None,
        mesh,
    )
}

#[allow(clippy::too_many_arguments)]
fn run_core(
    c: &Campaign,
    p: &Prepared,
    stop: &AtomicBool,
    keep_history: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
    stage: &Stage,
    writer: Option<CampaignWriter>,
    rows: Option<&[usize]>,
    verify: Option<&[usize]>,
    mesh: Option<&crate::verify::MeshSample>,
) -> Result<CampaignRun, EnsembleError> {
    let nv = p.models.len();
    // the positions (in `p`) of the variants whose mesh twin runs after the campaign
    // (a model without beams has no mesh): their histories are kept until then, with
    // the step their run was made at
    let sampled: Vec<bool> = p
        .global_index
        .iter()
        .zip(&p.models)
        .map(|(g, m)| mesh.is_some_and(|s| s.samples(*g)) && !m.elem_data.is_empty())
        .collect();
    type Kept = (
        usize,
        dynamics::History,
        f64,
        Option<crate::frequency::FirstBending>,
    );
    let kept: Mutex<Vec<Kept>> = Mutex::new(Vec::new());
    let writer = writer.map(Mutex::new);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let last_flush = Mutex::new(Instant::now());
    let write_err: Mutex<Option<OutputError>> = Mutex::new(None);
    let output_failed = AtomicBool::new(false);
    // Which results the file holds if a write fails: each variant's write gets a number
    // (under the writer's lock), and each good flush records the last number it carried.
    let writes = AtomicU64::new(0);
    let flushed = AtomicU64::new(0);
    let written_as: Vec<AtomicU64> = (0..nv).map(|_| AtomicU64::new(u64::MAX)).collect();
    let record_err = |e: OutputError| {
        let mut g = write_err.lock().unwrap_or_else(|p| p.into_inner());
        if g.is_none() {
            *g = Some(e);
        }
        // nothing more can reach the file: stop the variants in flight, start no more
        output_failed.store(true, Ordering::SeqCst);
        stop.store(true, Ordering::SeqCst);
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(c.threads.max(1))
        .build()
        .map_err(|e| EnsembleError::Invalid(format!("thread pool: {e}")))?;
    let counts = Mutex::new(BatchCounts::default());
    // What becomes of a variant once its run ended (or panicked): its outcome, and its
    // samples and status in the file (written when the variant ends, completed, failed or
    // interrupted alike, so workers do not contend for the writer per sample).
    let finish = |v: usize, result: std::thread::Result<dynamics::RunResult>, wall: f64| {
        let m = &p.models[v];
        let row = rows.map_or(v, |r| r[v]);
        let mut panicked = None;
        let (hist, mut stats, err) = match result {
            Ok(r) => r,
            Err(panic) => {
                panicked = Some(format!(
                    "internal error: {} (this is a bug in latdyn; please report it)",
                    panic_message(&*panic)
                ));
                (
                    dynamics::History {
                        t: Vec::new(),
                        values: vec![Vec::new(); m.sensors.len()],
                    },
                    dynamics::RunStats::default(),
                    None,
                )
            }
        };
        let (state, message, t_fail) = match (&err, &panicked) {
            (_, Some(msg)) => (VariantState::Failed, msg.clone(), f64::NAN),
            (None, None) => (VariantState::Completed, String::new(), f64::NAN),
            (Some(e @ DynamicsError::Interrupted { .. }), _) => {
                let msg = if output_failed.load(Ordering::SeqCst) {
                    format!("{e} (stopped: the output file could not be written)")
                } else {
                    e.to_string()
                };
                (VariantState::Interrupted, msg, e.time())
            }
            (Some(e), _) => (VariantState::Failed, e.to_string(), e.time()),
        };
        let summaries = summarize(m, &hist);
        let mut derived = Vec::new();
        let mut warnings = stats.warnings();
        let mut first_bending = None;
        if let (Some((name, comp)), VariantState::Completed) = (&c.frequency_sensor, state) {
            if let Some(k) = m.sensor_index(name) {
                let x: Vec<f64> = hist.values[k].iter().map(|s| s[*comp]).collect();
                let dt = hist.t.get(1).map(|t1| t1 - hist.t[0]).unwrap_or(0.0);
                let fb = crate::frequency::first_bending(m, (k, *comp), &x, dt);
                derived.push(("first_bending_hz".to_string(), fb.hz));
                if let Some(e) = fb.eig_hz {
                    derived.push(("first_bending_eig_hz".to_string(), e));
                }
                warnings.extend(fb.warnings.iter().cloned());
                first_bending = Some(fb);
            }
        }
        let t_out = Instant::now();
        if sampled[v] && state == VariantState::Completed {
            kept.lock().unwrap_or_else(|p| p.into_inner()).push((
                v,
                hist.clone(),
                stats.accuracy_dt.unwrap_or(m.solver.dt),
                first_bending,
            ));
        }
        if let Some(w) = &writer {
            let mut g = w.lock().unwrap_or_else(|p| p.into_inner());
            let st = VariantStatus::of_run(
                state,
                message.clone(),
                t_fail,
                &stats,
                wall,
                warnings.join("\n"),
            );
            let mut r = Ok(());
            for ti in 0..hist.t.len() {
                let vals: Vec<Vec<f64>> = hist.values.iter().map(|s| s[ti].clone()).collect();
                r = r.and_then(|_| g.write_samples(row, ti, &vals));
            }
            r = r.and_then(|_| g.set_status(row, &st));
            for (n, x) in &derived {
                r = r.and_then(|_| g.set_derived(n, row, *x));
            }
            let seq = writes.fetch_add(1, Ordering::SeqCst) + 1;
            written_as[v].store(seq, Ordering::SeqCst);
            // a flush rewrites the whole file: at most every few seconds
            let mut last = last_flush.lock().unwrap_or_else(|p| p.into_inner());
            if last.elapsed().as_secs_f64() > FLUSH_INTERVAL_S {
                r = r.and_then(|_| g.flush());
                if r.is_ok() {
                    flushed.store(seq, Ordering::SeqCst);
                }
                *last = Instant::now();
            }
            if let Err(e) = r {
                record_err(e);
            }
        }
        stats.times.output_s += t_out.elapsed().as_secs_f64();
        let d = done.fetch_add(1, Ordering::Relaxed) + 1;
        progress(d, nv);
        Outcome {
            global_index: p.global_index[v],
            parameters: c.variants[p.global_index[v]].clone(),
            state,
            message,
            t_fail,
            steps: stats.steps,
            rejected_steps: stats.rejected_steps,
            newton_iterations: stats.newton_iterations,
            accuracy_runs: stats.accuracy_runs,
            accuracy_steps: stats.accuracy_steps,
            wall_s: wall,
            times: stats.times,
            sensors: summaries,
            derived,
            energy_growth: stats.energy_growth,
            energy_loss: stats.energy_loss,
            time_error_estimate: stats.time_error_estimate,
            time_error_before_first_lock: stats.time_error_before_first_lock,
            mesh_error_estimate: None,
            warnings,
            history: keep_history.then_some(hist),
            panicked: panicked.is_some(),
            in_file: None,
        }
    };
    // One batch: its variants advance in lockstep on one worker, each round of their
    // element stages one call of the batch's stage.
    let run_batch = |batch: std::ops::Range<usize>| -> Vec<Outcome> {
        let mut outcomes: Vec<Option<Outcome>> = vec![None; batch.len()];
        let eval = stage.make.as_ref().map(|make| make());
        let ctx = dynamics::RunContext {
            stop: Some(stop),
            symbolic: p.symbolic.as_ref(),
            eval: eval.clone(),
        };
        let t0 = Instant::now();
        let mut members = Vec::with_capacity(batch.len());
        let mut member_variant = Vec::with_capacity(batch.len());
        for v in batch.clone() {
            // a variant not begun when the output failed or a signal came stays pending
            // (`merge` counts it missing, not interrupted: it never ran)
            let why = if output_failed.load(Ordering::SeqCst) {
                Some("the output file could not be written")
            } else if stop.load(Ordering::SeqCst) {
                Some("interrupted by a signal before it began")
            } else {
                None
            };
            if let Some(why) = why {
                outcomes[v - batch.start] = Some(not_run(c, p, v, keep_history, why));
                continue;
            }
            if let Some(w) = &writer {
                let st = VariantStatus {
                    state: VariantState::Running,
                    ..Default::default()
                };
                let row = rows.map_or(v, |r| r[v]);
                if let Err(e) = w
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .set_status(row, &st)
                {
                    record_err(e);
                }
            }
            let m = &p.models[v];
            let slot = Slot::new();
            let ctx = &ctx;
            let run_slot = Arc::clone(&slot);
            members.push(Member {
                elems: &m.elem_data,
                slot,
                run: Box::pin(async move {
                    // fault injection for tests/output_faults.rs: a panic inside the
                    // first variant's simulation (unset: nothing happens)
                    if v == 0
                        && std::env::var_os("LATDYN_FAULT_PANIC").is_some_and(|x| x == "variant")
                    {
                        panic!("injected panic in a variant (LATDYN_FAULT_PANIC=variant)");
                    }
                    // no factor size: an outcome has none
                    dynamics::run_member(m, ctx, run_slot, false, |_, _| {}).await
                }),
            });
            member_variant.push(v);
        }
        let cpu: Arc<dyn ElementEval> = Arc::new(CpuEval);
        let n = drive(eval.as_deref().unwrap_or(&*cpu), members, |k, result| {
            let v = member_variant[k];
            let wall = t0.elapsed().as_secs_f64();
            outcomes[v - batch.start] = Some(finish(v, result, wall));
        });
        counts.lock().unwrap_or_else(|p| p.into_inner()).add(&n);
        outcomes.into_iter().flatten().collect()
    };
    let size = batch_size(c.batch, nv, c.threads);
    let batches: Vec<std::ops::Range<usize>> = (0..nv)
        .step_by(size)
        .map(|a| a..(a + size).min(nv))
        .collect();
    let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        pool.install(|| {
            batches
                .into_par_iter()
                .flat_map_iter(run_batch)
                .collect::<Vec<Outcome>>()
        })
    }));
    let mut outcomes = match ran {
        Ok(o) => o,
        // A bug outside any one variant's run (those are caught in `drive`): the hook has
        // printed it. The file gets every result written so far and is marked interrupted,
        // not left `running`, so `sweep --resume` completes it; then the panic goes on.
        Err(panic) => {
            stop.store(true, Ordering::SeqCst);
            if let Some(w) = writer {
                let w = w.into_inner().unwrap_or_else(|p| p.into_inner());
                let path = w.path().display().to_string();
                match w.finish("interrupted") {
                    Ok(()) => eprintln!(
                        "the campaign stopped there; {path} holds every variant finished \
                         before and is marked interrupted (`sweep --resume` completes it)"
                    ),
                    Err(e) => eprintln!("the campaign stopped there; {e}"),
                }
            }
            std::panic::resume_unwind(panic);
        }
    };
    let batch_counts = counts.into_inner().unwrap_or_else(|p| p.into_inner());
    let mut output_error = write_err.into_inner().unwrap_or_else(|p| p.into_inner());
    // the campaign's own state: a signal during the verification leaves it complete
    let stopped = stop.load(Ordering::SeqCst);
    let mesh_report = match mesh {
        Some(plan) if output_error.is_none() && !stopped => {
            // every variant's result on disk before the twins (they take two to three
            // times a variant's run): a signal or a kill during them keeps the campaign
            if let Some(w) = &writer {
                let seq = writes.load(Ordering::SeqCst);
                match w.lock().unwrap_or_else(|p| p.into_inner()).flush() {
                    Ok(()) => flushed.store(seq, Ordering::SeqCst),
                    Err(e) => {
                        output_error.get_or_insert(e);
                    }
                }
            }
            let t0 = Instant::now();
            let mut kept = kept.into_inner().unwrap_or_else(|p| p.into_inner());
            // campaign order, whatever order the variants ended in
            kept.sort_by_key(|(v, ..)| *v);
            let measured: Vec<(usize, Result<crate::verify::RunMeshError, MeshTwinSkip>)> = pool
                .install(|| {
                    kept.par_iter()
                        .map(|(v, hist, dt, fb)| {
                            let mut sets = c.base.clone();
                            sets.extend(c.variants[p.global_index[*v]].iter().cloned());
                            let ctx = stage.run_context(stop);
                            let m = &p.models[*v];
                            let frequency = c
                                .frequency_sensor
                                .as_ref()
                                .and_then(|(name, comp)| Some((m.sensor_index(name)?, *comp)))
                                .zip(fb.as_ref());
                            let r = crate::verify::measure_mesh(
                                &c.model_path,
                                &sets,
                                m,
                                hist,
                                *dt,
                                plan.max_dofs,
                                &ctx,
                                frequency,
                            );
                            (*v, r)
                        })
                        .collect()
                });
            let mut report = Vec::with_capacity(measured.len());
            for (v, r) in measured {
                let row = rows.map_or(v, |r| r[v]);
                let warning = match &r {
                    Ok(e) => {
                        let w: Vec<String> = e
                            .warning()
                            .into_iter()
                            .chain(e.frequency_warning())
                            .collect();
                        (!w.is_empty()).then(|| w.join("\n"))
                    }
                    // the row keeps no mark: `sweep --resume` measures it (see
                    // `campaign::resume`); the sweep says it was stopped
                    Err(MeshTwinSkip::Interrupted) => None,
                    Err(MeshTwinSkip::Failed(why)) => Some(crate::verify::mesh_not_measured(why)),
                };
                let estimate = r.as_ref().ok().map(|e| e.estimate);
                let frequency = r.as_ref().ok().and_then(|e| e.first_bending);
                let o = &mut outcomes[v];
                o.mesh_error_estimate = estimate;
                o.warnings
                    .extend(warning.iter().flat_map(|w| w.lines().map(String::from)));
                if let Some(x) = frequency {
                    o.derived.push((FIRST_BENDING_MESH_ERROR.to_string(), x));
                }
                if let Some(w) = &writer {
                    let mut g = w.lock().unwrap_or_else(|p| p.into_inner());
                    let mut r = g.set_mesh_check(row, estimate, warning.as_deref());
                    if let Some(x) = frequency {
                        r = r.and_then(|_| g.set_derived(FIRST_BENDING_MESH_ERROR, row, x));
                    }
                    if let Err(e) = r {
                        output_error.get_or_insert(e);
                    }
                }
                report.push(crate::verify::VariantMesh {
                    global_index: p.global_index[v],
                    result: r,
                });
            }
            Some((report, t0.elapsed().as_secs_f64()))
        }
        _ => None,
    };
    let verification = match verify {
        Some(chosen) if output_error.is_none() && !stopped => Some(pool.install(|| {
            crate::verify::run(
                c,
                &p.models,
                &p.global_index,
                &outcomes,
                chosen,
                stop,
                stage,
            )
        })),
        _ => None,
    };
    if let Some(w) = writer {
        let mut w = w.into_inner().unwrap_or_else(|p| p.into_inner());
        if let Some(v) = &verification {
            if let Err(e) = w.set_verification(&v.data()) {
                output_error.get_or_insert(e);
            }
        }
        let status = if stopped { "interrupted" } else { "complete" };
        // after an output error this last write usually fails too (the last good flush
        // stays); the first error is the one to report
        match w.finish(status) {
            Ok(()) if output_error.is_none() => {}
            Ok(()) => flushed.store(u64::MAX - 1, Ordering::SeqCst),
            Err(e) => {
                output_error.get_or_insert(e);
            }
        }
        if output_error.is_some() {
            let good = flushed.load(Ordering::SeqCst);
            // the batches are collected in order: outcome v is variant v
            for (o, seq) in outcomes.iter_mut().zip(&written_as) {
                if o.state != VariantState::Pending {
                    o.in_file = Some(seq.load(Ordering::SeqCst) <= good);
                }
            }
        }
    }
    Ok(CampaignRun {
        outcomes,
        output_error,
        verification,
        mesh: mesh_report,
        batch: batch_counts,
    })
}

/// The identity of campaign `c` (see [`crate::campaign`]): the same for every shard of
/// it, whatever the thread count.
pub fn identify(
    c: &Campaign,
    p: &Prepared,
    stage: &Stage,
) -> Result<crate::campaign::CampaignInfo, EnsembleError> {
    let first = p.models.first().or(p.reference.as_ref());
    let sensors = first.map(SensorMeta::of_model).unwrap_or_default();
    crate::campaign::identify(&crate::campaign::DefinitionInput {
        model_path: &c.model_path,
        model_source: first.map(|m| m.source.as_str()).unwrap_or_default(),
        set: &c.base,
        variants: &c.variants,
        time: &p.time,
        sensors: &sensors,
        accuracy: c.accuracy,
        frequency: c.frequency_sensor.as_ref(),
        backend: &stage.backend,
        precision: &stage.precision,
    })
    .map_err(EnsembleError::Invalid)
}

/// The outcome of a variant not started (`why`: the output had already failed, or a
/// signal had come).
fn not_run(c: &Campaign, p: &Prepared, v: usize, keep_history: bool, why: &str) -> Outcome {
    let m = &p.models[v];
    Outcome {
        global_index: p.global_index[v],
        parameters: c.variants[p.global_index[v]].clone(),
        state: VariantState::Pending,
        message: format!("not run: {why}"),
        t_fail: f64::NAN,
        steps: 0,
        rejected_steps: 0,
        newton_iterations: 0,
        accuracy_runs: 0,
        accuracy_steps: 0,
        wall_s: 0.0,
        times: StageTimes::default(),
        sensors: summarize(m, &dynamics::History::default()),
        derived: Vec::new(),
        energy_growth: None,
        energy_loss: None,
        time_error_estimate: None,
        time_error_before_first_lock: None,
        mesh_error_estimate: None,
        warnings: Vec::new(),
        history: keep_history.then(|| dynamics::History {
            t: Vec::new(),
            values: vec![Vec::new(); m.sensors.len()],
        }),
        panicked: false,
        in_file: None,
    }
}

/// Extremes and last value of every sensor component over a history.
pub fn summarize(m: &Model, h: &dynamics::History) -> Vec<SensorSummary> {
    m.sensors
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let nc = sensors::components(&s.kind).len();
            let vals = h.values.get(k).map(|v| v.as_slice()).unwrap_or(&[]);
            let fold = |f: fn(f64, f64) -> f64, init: f64| -> Vec<f64> {
                (0..nc)
                    .map(|c| vals.iter().map(|v| v[c]).fold(init, f))
                    .collect()
            };
            SensorSummary {
                min: fold(f64::min, f64::INFINITY),
                max: fold(f64::max, f64::NEG_INFINITY),
                last: vals.last().cloned().unwrap_or_else(|| vec![f64::NAN; nc]),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_range_whose_span_passes_f64_gives_finite_values_and_others_are_unchanged() {
        let r = super::Range::parse("x=1e308:-1e308:3").unwrap();
        assert_eq!(r.values(), vec![1e308, 0.0, -1e308]);
        let r = super::Range::parse("x=0.1:0.7:4").unwrap();
        let plain: Vec<f64> = (0..3).map(|i| 0.1 + (0.7 - 0.1) * i as f64 / 3.0).collect();
        assert_eq!(r.values()[..3], plain);
    }

    #[test]
    fn a_range_ends_exactly_on_its_stop_value() {
        for (spec, stop) in [
            ("dt=1e-3:2.5e-4:4", 2.5e-4),
            ("dt=1e-3:3e-4:2", 3e-4),
            ("x=0:0.3:4", 0.3),
        ] {
            let v = super::Range::parse(spec).unwrap().values();
            assert_eq!(*v.last().unwrap(), stop, "{spec}: {v:?}");
        }
    }

    #[test]
    fn a_variant_is_named_by_its_csv_line_and_grid_point() {
        use super::Origin;
        let v = |p: &[(&str, f64)]| -> Vec<(String, f64)> {
            p.iter().map(|(n, x)| (n.to_string(), *x)).collect()
        };
        // two rows (lines 2 and 5) crossed with a grid of 3 points
        let o = Origin {
            csv: Some(("rows.csv".into(), vec![2, 5])),
            csv_columns: 1,
            grid_points: 3,
        };
        assert_eq!(
            o.describe(4, &v(&[("EI", -1.0), ("L", 2.0)])),
            "variant 4 (--variants rows.csv line 5: EI=-1; --vary L=2)"
        );
        let rows = Origin {
            grid_points: 1,
            csv_columns: 2,
            ..o.clone()
        };
        assert_eq!(
            rows.describe(1, &v(&[("EI", -1.0), ("L", 2.0)])),
            "variant 1 (--variants rows.csv line 5: EI=-1, L=2)"
        );
        let grid = Origin {
            grid_points: 6,
            ..Origin::default()
        };
        assert_eq!(
            grid.describe(3, &v(&[("EI", 0.0), ("L", 2.0)])),
            "variant 3 (--vary EI=0, L=2)"
        );
        // nothing known, or an index past the table: the values alone
        assert_eq!(
            Origin::default().describe(3, &v(&[("EI", 0.0)])),
            "variant 3 (EI=0)"
        );
        assert_eq!(o.describe(9, &v(&[("EI", 0.0)])), "variant 9 (EI=0)");
        assert_eq!(Origin::default().describe(0, &[]), "variant 0");
    }

    #[test]
    fn a_spreadsheet_export_with_a_byte_order_mark_and_quotes_reads_as_plain_csv() {
        let dir = std::env::temp_dir().join(format!("latdyn-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("variants.csv");
        std::fs::write(
            &path,
            "\u{feff}\"omega\", EI\r\n\"1.5\",2\r\n3, \" 4 \"\r\n",
        )
        .unwrap();
        let rows = super::read_variants_csv(&path).unwrap();
        let want = vec![
            vec![("omega".to_string(), 1.5), ("EI".to_string(), 2.0)],
            vec![("omega".to_string(), 3.0), ("EI".to_string(), 4.0)],
        ];
        assert_eq!(rows, want);
    }
}
