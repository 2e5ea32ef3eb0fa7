//! Campaign identity: what makes the shard files of one campaign one campaign again
//! (README "Campaigns on a cluster").
//!
//! A sweep's *definition* is everything that decides its variants' numbers: the model
//! file's text, the `--set` values, the table of varied parameter values (every variant of
//! the whole campaign, not only a shard's), the output time grid, the sensors, the solver
//! overrides (`--accuracy`), the derived quantities asked for (`--frequency`), the element
//! backend and precision, and the latdyn version. It is written as a JSON object (keys
//! sorted, floats in Rust's round-trip `{:?}` form) and hashed with SHA-256; the
//! hash is stored in every sweep and shard file (`campaign_hash`), together with a
//! readable identifier (`campaign_id` = model file stem + the hash's first 12 hex
//! digits). What does not change a number is left out: the thread count, the shard, the
//! model file's path, the output path and the command line, so array tasks on different
//! nodes, with different thread counts or mount points, agree on the campaign without
//! talking to each other.

use std::path::{Path, PathBuf};

use rust_hdf5::H5Dataset;
use sha2::{Digest, Sha256};

use crate::output::layout::{self, Reader};
use crate::output::{
    CampaignMeta, CampaignWriter, OutputError, OutputTarget, SensorMeta, VariantState,
    VariantStatus,
};

/// A campaign's identity and the variant table it was defined with (stored under
/// `/campaign` and in the root attributes `campaign_id`, `campaign_hash`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CampaignInfo {
    /// model file stem + the first 12 hex digits of `hash`
    pub id: String,
    /// SHA-256 (hex) of `definition`
    pub hash: String,
    /// the definition, a JSON object (see the module docs)
    pub definition: String,
    /// names of the varied parameters (the `--variants` columns, then the `--vary` names)
    pub varied: Vec<String>,
    /// per variant of the whole campaign (global index order), its varied values
    pub variants: Vec<Vec<f64>>,
    /// the `--set` overrides shared by every variant
    pub set: Vec<(String, f64)>,
}

/// What a campaign is defined by (see the module docs).
pub struct DefinitionInput<'a> {
    pub model_path: &'a Path,
    pub model_source: &'a str,
    pub set: &'a [(String, f64)],
    pub variants: &'a [Vec<(String, f64)>],
    pub time: &'a [f64],
    pub sensors: &'a [SensorMeta],
    pub accuracy: Option<f64>,
    /// `--frequency`: sensor name and component index
    pub frequency: Option<&'a (String, usize)>,
    pub backend: &'a str,
    pub precision: &'a str,
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// `{:?}` of an f64 is the shortest text that parses back to the same bits (and spells
/// NaN and infinities, which JSON numbers cannot).
fn num(x: f64) -> String {
    format!("{x:?}")
}

/// The campaign's definition, its hash and identifier. Fails if the variant rows do not
/// all name the same parameters in the same order (a caller bug: `ensemble::variants`
/// builds them so).
pub fn identify(d: &DefinitionInput) -> Result<CampaignInfo, String> {
    let varied: Vec<String> = d
        .variants
        .first()
        .map(|r| r.iter().map(|(n, _)| n.clone()).collect())
        .unwrap_or_default();
    let mut table = Sha256::new();
    let mut variants = Vec::with_capacity(d.variants.len());
    for (i, row) in d.variants.iter().enumerate() {
        if row.len() != varied.len() || row.iter().zip(&varied).any(|((n, _), v)| n != v) {
            return Err(format!(
                "variant {i} names other parameters than variant 0 ({})",
                varied.join(", ")
            ));
        }
        for (_, x) in row {
            table.update(x.to_le_bytes());
        }
        variants.push(row.iter().map(|(_, x)| *x).collect::<Vec<f64>>());
    }
    let mut time = Sha256::new();
    for t in d.time {
        time.update(t.to_le_bytes());
    }
    let mut set = d.set.to_vec();
    // the order of --set options does not change the campaign; a repeated name keeps its
    // order (the last one given wins when the model is compiled)
    set.sort_by(|a, b| a.0.cmp(&b.0));
    let def = serde_json::json!({
        "latdyn_version": env!("CARGO_PKG_VERSION"),
        "model_sha256": hex(&Sha256::digest(d.model_source.as_bytes())),
        "set": set.iter().map(|(n, x)| serde_json::json!([n, num(*x)])).collect::<Vec<_>>(),
        "varied": varied,
        "variants": d.variants.len(),
        "variants_sha256": hex(&table.finalize()),
        "time": {
            "n": d.time.len(),
            "first": d.time.first().map(|t| num(*t)),
            "last": d.time.last().map(|t| num(*t)),
            "sha256": hex(&time.finalize()),
        },
        "sensors": d.sensors.iter().map(|s| format!(
            "{}({})[{}]", s.name, s.components.join(","), s.units.join(",")
        )).collect::<Vec<_>>(),
        "accuracy": d.accuracy.map(num),
        "frequency": d.frequency.map(|(n, c)| format!("{n}.{c}")),
        "backend": d.backend,
        "precision": d.precision,
    });
    // serde_json's map is a BTreeMap (no `preserve_order` feature): keys come out sorted,
    // so the text, and with it the hash, depends on the content only
    let definition = def.to_string();
    let hash = hex(&Sha256::digest(definition.as_bytes()));
    let stem = d
        .model_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "campaign".into());
    Ok(CampaignInfo {
        id: format!("{stem}-{}", &hash[..12]),
        hash,
        definition,
        varied,
        variants,
        set,
    })
}

/// What differs between two definitions (their JSON texts), one entry per top-level key,
/// e.g. `model_sha256` or `variants_sha256`; empty when they are equal or unreadable.
pub fn differences(a: &str, b: &str) -> Vec<String> {
    let (Ok(a), Ok(b)) = (
        serde_json::from_str::<serde_json::Value>(a),
        serde_json::from_str::<serde_json::Value>(b),
    ) else {
        return Vec::new();
    };
    let (Some(a), Some(b)) = (a.as_object(), b.as_object()) else {
        return Vec::new();
    };
    let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| {
            let show = |v: Option<&serde_json::Value>| {
                v.map(|v| {
                    let s = v.to_string();
                    if s.chars().count() > 80 {
                        format!("{}…", s.chars().take(80).collect::<String>())
                    } else {
                        s
                    }
                })
                .unwrap_or_else(|| "absent".into())
            };
            format!("{k}: {} vs {}", show(a.get(k)), show(b.get(k)))
        })
        .collect()
}

/// A campaign file as `merge` and `sweep --resume` read it: its identity and the small
/// per-variant datasets (the sensor samples stay on disk).
pub struct CampaignFile {
    pub path: PathBuf,
    pub file: Reader,
    pub info: CampaignInfo,
    pub model_source: String,
    pub model_path: String,
    pub backend: String,
    pub precision: String,
    pub adapter: String,
    pub parameter_names: Vec<String>,
    /// [V][P]
    pub parameter_values: Vec<Vec<f64>>,
    pub time: Vec<f64>,
    pub global_index: Vec<usize>,
    pub status: Vec<VariantStatus>,
    pub derived: Vec<(String, Vec<f64>)>,
    /// the file has `/verification` (`sweep --verify`)
    pub has_verification: bool,
}

/// Why a file could not be read as a campaign file (path and reason).
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct ReadError {
    pub path: PathBuf,
    pub message: String,
}

impl CampaignFile {
    /// Open a sweep or shard file and read its identity and per-variant status. Files
    /// without `campaign_hash` (written by `run`, `statics --path`, `sweep --path` or a
    /// latdyn before campaign identities) are refused with that reason.
    pub fn open(path: &Path) -> Result<CampaignFile, ReadError> {
        let err = |message: String| ReadError {
            path: path.to_path_buf(),
            message,
        };
        crate::model::limits::regular_input(path).map_err(&err)?;
        let file =
            Reader::open(path).map_err(|e| err(format!("not a readable HDF5 file ({e})")))?;
        if file.root_attr(layout::attr::FORMAT).as_deref() != Some(layout::FORMAT) {
            return Err(err(
                "not a latdyn campaign file (no root attribute format = \
                            \"latdyn-campaign\")"
                    .into(),
            ));
        }
        let hash = file.root_attr(layout::attr::CAMPAIGN_HASH).ok_or_else(|| {
            err(
                "has no campaign identity (root attribute campaign_hash): only `sweep` files \
                 written by this latdyn version or later have one; rerun the sweep"
                    .into(),
            )
        })?;
        let id = file
            .root_attr(layout::attr::CAMPAIGN_ID)
            .unwrap_or_default();
        let ds = |name: &str| file.dataset(name).map_err(err);
        let f64s = |name: &str| file.f64s(name).map_err(err);
        let i64s = |name: &str| file.i64s(name).map_err(err);
        let strings = |name: &str| file.strings(name).map_err(err);
        let scalar_text = |name: &str| file.scalar_text(name).map_err(err);
        // before anything is allocated per variant of the campaign
        let limit = crate::model::Limits::from_env().map_err(err)?.variants;
        let n_declared = ds(layout::VARIANTS)?.shape().first().copied().unwrap_or(0);
        if n_declared as u64 > limit {
            return Err(err(format!(
                "/{}: {}",
                layout::VARIANTS,
                crate::model::limits::exceeded(
                    "variants of the campaign",
                    n_declared as f64,
                    "variants",
                    limit
                )
            )));
        }
        let definition = scalar_text(layout::DEFINITION)?;
        // the identity every merge and resume relies on: a hash that is not the stored
        // definition's was edited or damaged, and a merge carried it on unchecked
        let stored = hex(&Sha256::digest(definition.as_bytes()));
        if stored != hash {
            return Err(err(format!(
                "its campaign_hash ({}) is not the hash of its stored campaign definition \
                 ({stored}): the file was edited or damaged; rerun or restore it",
                crate::model::elide_long_words(&hash)
            )));
        }
        // the model text that `merge` and `--resume` compile the missing variants from
        // must be the one the definition names (until session 47 an edited
        // /model/source gave a merge's missing rows g = 1 where the campaign's is 9.81)
        let model_source = scalar_text(layout::MODEL_SOURCE)?;
        let named = serde_json::from_str::<serde_json::Value>(&definition)
            .ok()
            .and_then(|d| d["model_sha256"].as_str().map(str::to_string));
        let actual = hex(&Sha256::digest(model_source.as_bytes()));
        if named.as_deref() != Some(actual.as_str()) {
            return Err(err(format!(
                "its stored model text (/{}) is not the one its campaign definition names \
                 (model_sha256 {}, the text's {actual}): the file was edited or damaged; \
                 rerun or restore it",
                layout::MODEL_SOURCE,
                named.as_deref().unwrap_or("absent")
            )));
        }
        let varied = strings(layout::VARIED)?;
        let table = f64s(layout::VARIANTS)?;
        let n_total = ds(layout::VARIANTS)?.shape().first().copied().unwrap_or(0);
        let variants: Vec<Vec<f64>> = if varied.is_empty() {
            vec![Vec::new(); n_total]
        } else {
            table.chunks(varied.len()).map(<[f64]>::to_vec).collect()
        };
        let set: Vec<(String, f64)> = strings(layout::SET_NAMES)?
            .into_iter()
            .zip(f64s(layout::SET_VALUES)?)
            .collect();
        let parameter_names = strings(layout::PARAMETER_NAMES)?;
        let values = f64s(layout::PARAMETER_VALUES)?;
        let raw_index = i64s(layout::GLOBAL_INDEX)?;
        if let Some(g) = raw_index.iter().find(|&&g| g < 0) {
            return Err(err(format!("global index {g} is negative")));
        }
        let global_index: Vec<usize> = raw_index
            .into_iter()
            .map(|g| usize::try_from(g).unwrap_or(usize::MAX))
            .collect();
        let nv = global_index.len();
        let parameter_values: Vec<Vec<f64>> = if parameter_names.is_empty() {
            vec![Vec::new(); nv]
        } else {
            values
                .chunks(parameter_names.len())
                .map(<[f64]>::to_vec)
                .collect()
        };
        if parameter_values.len() != nv {
            return Err(err(format!(
                "/parameters/values has {} rows for {nv} variants",
                parameter_values.len()
            )));
        }
        if let Some(g) = global_index.iter().find(|&&g| g >= n_total) {
            return Err(err(format!(
                "global index {g} outside the campaign's {n_total} variants"
            )));
        }
        let col = |name: &str| -> Result<Vec<f64>, ReadError> {
            let v = f64s(name)?;
            if v.len() != nv {
                return Err(err(format!(
                    "/{name} has {} entries for {nv} variants",
                    v.len()
                )));
            }
            Ok(v)
        };
        let state = i64s(layout::STATE)?;
        let message = strings(layout::MESSAGE)?;
        let warnings = strings(layout::WARNINGS)?;
        let steps = i64s(layout::STEPS)?;
        let rejected = i64s(layout::REJECTED_STEPS)?;
        let (t_fail, wall_s) = (col(layout::T_FAIL)?, col(layout::WALL_S)?);
        let (growth, loss) = (col(layout::ENERGY_GROWTH)?, col(layout::ENERGY_LOSS)?);
        let tee = col(layout::TIME_ERROR_ESTIMATE)?;
        // a column written since some session: a file from before reads NaN
        let later_col = |name: &str| match file.has_dataset(name) {
            true => col(name),
            false => Ok(vec![f64::NAN; nv]),
        };
        // since session 24 ("no lock estimate") and 49 (run's mesh twin)
        let tee_lock = later_col(layout::TIME_ERROR_BEFORE_FIRST_LOCK)?;
        let mesh = later_col(layout::MESH_ERROR_ESTIMATE)?;
        if [
            state.len(),
            message.len(),
            warnings.len(),
            steps.len(),
            rejected.len(),
        ]
        .iter()
        .any(|&n| n != nv)
        {
            return Err(err(format!(
                "/status datasets do not all have {nv} entries"
            )));
        }
        let mut status = Vec::with_capacity(nv);
        for v in 0..nv {
            status.push(VariantStatus {
                state: VariantState::from_code(state[v])
                    .ok_or_else(|| err(format!("/status/state[{v}] = {} is no state", state[v])))?,
                message: message[v].clone(),
                t_fail: t_fail[v],
                steps: u64::try_from(steps[v]).unwrap_or(0),
                rejected_steps: u64::try_from(rejected[v]).unwrap_or(0),
                wall_s: wall_s[v],
                energy_growth: growth[v],
                energy_loss: loss[v],
                time_error_estimate: tee[v],
                time_error_before_first_lock: tee_lock[v],
                mesh_error_estimate: mesh[v],
                warnings: warnings[v].clone(),
            });
        }
        let mut derived = Vec::new();
        for n in file.names_in(layout::DERIVED) {
            derived.push((n.clone(), col(&layout::derived(&n))?));
        }
        let has_verification = file.has_group(layout::VERIFICATION);
        Ok(CampaignFile {
            path: path.to_path_buf(),
            info: CampaignInfo {
                id,
                hash,
                definition,
                varied,
                variants,
                set,
            },
            model_source,
            model_path: scalar_text(layout::MODEL_PATH)?,
            backend: file.root_attr(layout::attr::BACKEND).unwrap_or_default(),
            precision: file.root_attr(layout::attr::PRECISION).unwrap_or_default(),
            adapter: file.root_attr(layout::attr::ADAPTER).unwrap_or_default(),
            parameter_names,
            parameter_values,
            time: f64s(layout::TIME)?,
            global_index,
            status,
            derived,
            has_verification,
            file,
        })
    }

    /// The `/sensors/<name>` dataset.
    pub fn sensor(&self, name: &str) -> Result<H5Dataset, ReadError> {
        self.file
            .file()
            .dataset(&layout::sensor(name))
            .map_err(|e| ReadError {
                path: self.path.clone(),
                message: format!("no /sensors/{name} ({e})"),
            })
    }

    /// `/verification` as `sweep --verify` wrote it (None if the file has none); the
    /// component names of each sensor come from `sensors` (the campaign's).
    pub fn verification(
        &self,
        sensors: &[SensorMeta],
    ) -> Result<Option<crate::output::VerificationData>, ReadError> {
        if !self.has_verification {
            return Ok(None);
        }
        let err = |message: String| ReadError {
            path: self.path.clone(),
            message,
        };
        // through the reader, which checks the size each dataset claims before reading it
        let path = |name: &str| format!("{}/{name}", layout::VERIFICATION);
        let f64s = |name: &str| self.file.f64s(&path(name)).map_err(err);
        let i64s = |name: &str| self.file.i64s(&path(name)).map_err(err);
        let strings = |name: &str| self.file.strings(&path(name)).map_err(err);
        let one = |name: &str| -> Result<f64, ReadError> {
            f64s(name)?
                .first()
                .copied()
                .ok_or_else(|| err(format!("/verification/{name} is empty")))
        };
        let pairs = |v: Vec<f64>| v.chunks(2).map(|c| [c[0], c[c.len() - 1]]).collect();
        let elements: Vec<[usize; 2]> = i64s("elements")?
            .chunks(2)
            .map(|c| [c[0].max(0) as usize, c[c.len() - 1].max(0) as usize])
            .collect();
        let mut out = crate::output::VerificationData {
            target: one("target")?,
            target_source: self.file.scalar_text(&path("target_source")).map_err(err)?,
            variants: i64s("variants")?
                .into_iter()
                .map(|g| g.max(0) as usize)
                .collect(),
            status: strings("status")?,
            wall_s: f64s("wall_s")?,
            dt: pairs(f64s("dt")?),
            elements,
            max_rel_diff: one("max_rel_diff")?,
            warnings: strings("warnings")?,
            sensors: Vec::new(),
        };
        for s in sensors {
            let get = |g: &str| f64s(&format!("{g}/{}", s.name));
            out.sensors.push(crate::output::VerificationSensor {
                name: s.name.clone(),
                components: s.components.clone(),
                rel_diff: get("rel_diff")?,
                refined_min: get("refined_min")?,
                refined_max: get("refined_max")?,
            });
        }
        Ok(Some(out))
    }

    /// The variants of the whole campaign.
    pub fn n_total(&self) -> usize {
        self.info.variants.len()
    }
}

/// What `merge` found (printed by `merge --json`). Indices are global (0-based, as
/// `--shard` writes them).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MergeReport {
    pub campaign_id: String,
    pub campaign_hash: String,
    /// variants of the whole campaign
    pub variants: usize,
    pub completed: usize,
    /// in no shard, or never started in its shard (state pending)
    pub missing: Vec<usize>,
    pub failed: Vec<usize>,
    /// stopped by a signal (state interrupted), or started in a shard that was killed
    /// (state running)
    pub interrupted: Vec<usize>,
    /// held by more than one shard (the merge is refused)
    pub duplicated: Vec<usize>,
    /// what `sweep --resume` on the merged file runs: missing, failed and interrupted
    pub to_resume: Vec<usize>,
    pub shards: Vec<ShardReport>,
    /// shards with `/verification` (`sweep --verify`) when more than one has it (then
    /// the merged file has none; with one, it is carried over)
    pub verification_not_merged: Vec<String>,
    pub output: String,
    /// "complete" (every variant completed or failed), "incomplete" or "refused"
    pub status: String,
    pub message: String,
    pub wall_s: f64,
}

/// One input of a merge.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ShardReport {
    pub path: String,
    pub variants: usize,
    pub completed: usize,
}

/// Why a merge refused to write.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error("{0}")]
    Refused(String),
    #[error(transparent)]
    Output(#[from] OutputError),
    /// `sweep --resume`: a signal stopped the preparation of the variants to run (see
    /// [`resume_until`]); the file was not touched.
    #[error("{0}")]
    Interrupted(String),
}

/// Why a shard's stored parameter values cannot be its variants' (`None` if they can):
/// a value that is not finite (compiled parameters always are), or a varied or `--set`
/// parameter whose value is not the one the campaign's definition gives that variant.
/// `merge` copies the values as stored, so an edited table would label the samples
/// wrongly.
/// Only the rows `check` accepts are checked (`--resume` recomputes the others' values).
fn parameter_mismatch(f: &CampaignFile, check: impl Fn(usize) -> bool) -> Option<String> {
    let column = |name: &str| f.parameter_names.iter().position(|n| n == name);
    for (row, &g) in f.global_index.iter().enumerate() {
        if !check(row) {
            continue;
        }
        let values = &f.parameter_values[row];
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Some(format!(
                "/parameters/values of variant {g}: `{}` is {}",
                f.parameter_names[k], values[k]
            ));
        }
        let Some(defined) = f.info.variants.get(g) else {
            return Some(format!("variant {g} has no row in /campaign/variants"));
        };
        let given = f.info.set.iter().map(|(n, v)| (n.as_str(), *v)).chain(
            f.info
                .varied
                .iter()
                .map(String::as_str)
                .zip(defined.iter().copied()),
        );
        for (name, v) in given {
            if let Some(k) = column(name) {
                if values[k] != v {
                    return Some(format!(
                        "/parameters/values of variant {g}: `{name}` is {} where the \
                         campaign's definition gives {v}",
                        values[k]
                    ));
                }
            }
        }
    }
    None
}

/// Merge the shard files `inputs` of one campaign into `target` (see README "Campaigns
/// on a cluster"): every input must carry the same `campaign_hash`, and no global index
/// may be in two of them. The merged file has the layout of a single-process sweep of
/// the whole campaign (one row per global index, in order): the sensor chunks are copied
/// as stored (compressed bytes, no decoding), so the samples are bit for bit the shards';
/// a variant in no shard is pending with NaN samples and its parameter values compiled
/// from the stored model text. Memory: the per-variant status of the campaign and one
/// chunk (≤ 512 KiB) of samples. `report` is filled as far as the merge got, also when it
/// is refused.
pub fn merge(
    inputs: &[PathBuf],
    target: OutputTarget,
    command_line: &str,
    report: &mut MergeReport,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<(), MergeError> {
    let t0 = std::time::Instant::now();
    // a signal (SIGINT, SIGTERM: Slurm's scancel) stops the merge between shards and
    // between stored chunks; the target is left as it was and the temporary file removed
    let stopped = || stop.is_some_and(|s| s.load(std::sync::atomic::Ordering::SeqCst));
    let interrupted = |path: &Path| {
        MergeError::Interrupted(format!(
            "interrupted by a signal: nothing merged, {} left as it was",
            path.display()
        ))
    };
    let target_path = target.path().to_path_buf();
    report.output = target.path().display().to_string();
    if inputs.is_empty() {
        return Err(MergeError::Refused("merge: no shard files given".into()));
    }
    // pass 1: identities and indices, one file open at a time
    let mut owner: Vec<Option<(usize, usize)>> = Vec::new();
    let mut first: Option<CampaignFile> = None;
    let mut duplicated = Vec::new();
    let mut with_verification = Vec::new();
    for (k, p) in inputs.iter().enumerate() {
        if stopped() {
            return Err(interrupted(&target_path));
        }
        let f = CampaignFile::open(p)?;
        match &first {
            None => {
                report.campaign_id = f.info.id.clone();
                report.campaign_hash = f.info.hash.clone();
                report.variants = f.n_total();
                owner = vec![None; f.n_total()];
            }
            Some(f0) if f0.info.hash != f.info.hash => {
                let diff = differences(&f0.info.definition, &f.info.definition);
                return Err(MergeError::Refused(format!(
                    "{} belongs to another campaign than {} (campaign {} vs {}){}",
                    p.display(),
                    f0.path.display(),
                    f.info.id,
                    f0.info.id,
                    if diff.is_empty() {
                        String::new()
                    } else {
                        format!("; what differs: {}", diff.join("; "))
                    }
                )));
            }
            Some(f0) if f0.parameter_names != f.parameter_names => {
                return Err(MergeError::Refused(format!(
                    "{}: /parameters/names differ from those of {} (the same campaign \
                     compiles the same parameters: was the file edited?)",
                    p.display(),
                    f0.path.display()
                )));
            }
            Some(_) => {}
        }
        if let Some(why) = parameter_mismatch(&f, |_| true) {
            return Err(MergeError::Refused(format!(
                "{}: {why} (was the file edited?)",
                p.display()
            )));
        }
        let mut completed = 0;
        for (row, &g) in f.global_index.iter().enumerate() {
            if owner[g].is_some() {
                duplicated.push(g);
            }
            owner[g] = Some((k, row));
            completed += usize::from(f.status[row].state == VariantState::Completed);
        }
        report.shards.push(ShardReport {
            path: p.display().to_string(),
            variants: f.global_index.len(),
            completed,
        });
        if f.has_verification {
            with_verification.push(k);
        }
        if first.is_none() {
            first = Some(f);
        }
    }
    let first = first.expect("at least one input");
    if !duplicated.is_empty() {
        duplicated.sort_unstable();
        duplicated.dedup();
        report.duplicated = duplicated.clone();
        return Err(MergeError::Refused(format!(
            "{} global indices are in more than one shard ({}{}): each variant must come from \
             one shard only; leave out the repeated file",
            duplicated.len(),
            duplicated
                .iter()
                .take(20)
                .map(|g| g.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            if duplicated.len() > 20 { ", …" } else { "" }
        )));
    }
    let n = first.n_total();
    let np = first.parameter_names.len();
    // rows in no shard: parameters from the stored model text, as the sweep compiled them
    let mut parameter_values = vec![vec![f64::NAN; np]; n];
    let mut status = vec![VariantStatus::default(); n];
    let mut derived: Vec<(String, Vec<f64>)> = Vec::new();
    for (k, p) in inputs.iter().enumerate() {
        let f = if k == 0 {
            None
        } else {
            Some(CampaignFile::open(p)?)
        };
        let f = f.as_ref().unwrap_or(&first);
        for (row, &g) in f.global_index.iter().enumerate() {
            parameter_values[g] = f.parameter_values[row].clone();
            status[g] = f.status[row].clone();
        }
        for (name, col) in &f.derived {
            let i = match derived.iter().position(|(d, _)| d == name) {
                Some(i) => i,
                None => {
                    derived.push((name.clone(), vec![f64::NAN; n]));
                    derived.len() - 1
                }
            };
            for (row, &g) in f.global_index.iter().enumerate() {
                derived[i].1[g] = col[row];
            }
        }
    }
    for g in 0..n {
        if owner[g].is_none() {
            let mut sets = first.info.set.clone();
            sets.extend(
                first
                    .info
                    .varied
                    .iter()
                    .cloned()
                    .zip(first.info.variants[g].iter().copied()),
            );
            if let Ok(m) = crate::model::compile_str(&first.model_source, &first.model_path, &sets)
            {
                if m.params.len() == np {
                    parameter_values[g] = m.params.iter().map(|(_, v)| *v).collect();
                }
            }
        }
    }
    for (g, st) in status.iter().enumerate() {
        match (owner[g], st.state) {
            (None, _) | (_, VariantState::Pending) => report.missing.push(g),
            (_, VariantState::Completed) => report.completed += 1,
            (_, VariantState::Failed) => report.failed.push(g),
            (_, VariantState::Interrupted | VariantState::Running) => report.interrupted.push(g),
        }
    }
    report.to_resume = (0..n)
        .filter(|&g| status[g].state != VariantState::Completed || owner[g].is_none())
        .collect();
    let incomplete = !report.missing.is_empty() || !report.interrupted.is_empty();
    // the sensors and their components/units as the model defines them (the hash says
    // every shard has the same)
    let (sensors, grid) = {
        let mut sets = first.info.set.clone();
        if let Some(row) = first.info.variants.first() {
            sets.extend(first.info.varied.iter().cloned().zip(row.iter().copied()));
        }
        let m = crate::model::compile_str(&first.model_source, &first.model_path, &sets).map_err(
            |e| {
                MergeError::Refused(format!(
                    "{}: the stored model does not compile: {e}",
                    first.path.display()
                ))
            },
        )?;
        (
            SensorMeta::of_model(&m),
            crate::solver::dynamics::output_times(&m),
        )
    };
    let meta = CampaignMeta {
        command_line: command_line.to_string(),
        model_path: first.model_path.clone(),
        model_source: first.model_source.clone(),
        backend: first.backend.clone(),
        precision: first.precision.clone(),
        adapter: first.adapter.clone(),
        threads: 0,
        parameter_names: first.parameter_names.clone(),
        parameter_values,
        global_index: (0..n).collect(),
        time: first.time.clone(),
        sensors: sensors.clone(),
    };
    let info = first.info.clone();
    drop(first);
    // every shard's sensor datasets must be what the raw chunk copy below assumes: the
    // campaign's shape, latdyn's chunks, element type and filters (a file rewritten by
    // another tool would otherwise be copied into garbage or an unreadable file)
    for p in inputs {
        let f = CampaignFile::open(p)?;
        check_time_grid(&f.time, &grid, &p.display().to_string())?;
        let rows = f.global_index.len();
        for s in &sensors {
            let src = f
                .sensor(&s.name)
                .map_err(|e| MergeError::Refused(format!("{}: {}", p.display(), e.message)))?;
            if let Some(why) = sensor_copy_mismatch(&src, rows, meta.time.len(), s) {
                return Err(MergeError::Refused(format!(
                    "{}: /sensors/{}: {why}; merge copies the stored chunks as they are and \
                     refuses a shard whose sensors were not written by latdyn (rewritten by \
                     another tool?)",
                    p.display(),
                    s.name
                )));
            }
        }
    }
    // `sweep --verify` verifies in shard 1 only: its figures are the campaign's
    let verification = match with_verification.as_slice() {
        [k] => CampaignFile::open(&inputs[*k])?.verification(&sensors)?,
        more => {
            report.verification_not_merged = more
                .iter()
                .map(|&k| inputs[k].display().to_string())
                .collect();
            None
        }
    };
    // a shard that cannot be read is refused input (exit 2), not an output failure (5)
    let input_fault = std::cell::RefCell::new(None::<String>);
    let signalled = std::cell::Cell::new(false);
    if stopped() {
        return Err(interrupted(&target_path));
    }
    let mut fill = |out: &[H5Dataset]| -> Result<(), OutputError> {
        let bad = |p: &Path, m: String| {
            let m = format!("{}: {m}", p.display());
            *input_fault.borrow_mut() = Some(m.clone());
            OutputError::Invalid(m)
        };
        for p in inputs {
            let f = CampaignFile::open(p).map_err(|e| bad(p, e.message))?;
            for (s, ds) in sensors.iter().zip(out) {
                let src = f.sensor(&s.name).map_err(|e| bad(p, e.message))?;
                let rows = f.global_index.len();
                if rows == 0 {
                    continue;
                }
                let n_time = ds.shape()[1];
                let nc = s.components.len();
                let chunk_t = crate::output::chunk_times(nc, n_time);
                let (cs, co) = (src.chunk_dims(), Some(vec![1, chunk_t, nc]));
                if cs != co || src.shape()[1..] != ds.shape()[1..] {
                    return Err(bad(
                        p,
                        format!(
                            "/sensors/{}: shape {:?} chunks {cs:?}, the merged file has {:?} \
                             chunks {co:?}",
                            s.name,
                            src.shape(),
                            ds.shape(),
                        ),
                    ));
                }
                let chunks_t = n_time.div_ceil(chunk_t);
                for (row, &g) in f.global_index.iter().enumerate() {
                    if stopped() {
                        signalled.set(true);
                        return Err(OutputError::Invalid("interrupted by a signal".into()));
                    }
                    for ct in 0..chunks_t {
                        // a chunk never written (a variant that never ran) is absent in
                        // the shard and stays absent (reads NaN) in the merged file
                        let (bytes, mask) = match src.read_chunk_raw_at(&[row, ct, 0]) {
                            Ok(x) => x,
                            Err(e) if e.to_string().contains("has not been written") => continue,
                            Err(e) => {
                                return Err(bad(
                                    p,
                                    format!("reading /sensors/{} chunk {row},{ct}: {e}", s.name),
                                ))
                            }
                        };
                        ds.write_chunk_raw_at(&[g, ct, 0], &bytes, mask)
                            .map_err(|e| {
                                OutputError::Invalid(format!(
                                    "{}: copying /sensors/{}: {e}",
                                    p.display(),
                                    s.name
                                ))
                            })?;
                    }
                }
            }
        }
        Ok(())
    };
    let written = CampaignWriter::write_streamed(
        target,
        &meta,
        Some(info),
        status,
        derived,
        verification,
        if incomplete {
            "interrupted"
        } else {
            "complete"
        },
        &mut fill,
    );
    if let Err(e) = written {
        if signalled.get() {
            return Err(interrupted(&target_path));
        }
        return Err(match input_fault.into_inner() {
            Some(m) => MergeError::Refused(m),
            None => e.into(),
        });
    }
    report.status = if incomplete { "incomplete" } else { "complete" }.into();
    report.wall_s = t0.elapsed().as_secs_f64();
    Ok(())
}

/// Why the stored chunks of `src` (a `/sensors` dataset of a file with `rows` variants
/// and `n_time` output times) cannot be copied as they are for sensor `s`, or `None`.
fn sensor_copy_mismatch(
    src: &H5Dataset,
    rows: usize,
    n_time: usize,
    s: &SensorMeta,
) -> Option<String> {
    let nc = s.components.len();
    let want = [rows, n_time, nc];
    if src.shape() != want {
        return Some(format!(
            "shape {:?}, the campaign has {want:?} ({rows} variant(s) in the file, {n_time} \
             output times, {nc} components)",
            src.shape()
        ));
    }
    if rows == 0 || n_time == 0 {
        return None; // nothing stored, nothing copied
    }
    crate::output::raw_copy_mismatch(src, &[1, crate::output::chunk_times(nc, n_time), nc])
}

/// The hash fixes the output grid (every variant reports on the model's one), so a
/// stored /time that is not that grid was altered after the sweep wrote it; merged or
/// resumed, every sample would carry a wrong time.
fn check_time_grid(stored: &[f64], grid: &[f64], what: &str) -> Result<(), MergeError> {
    let bits = |v: &[f64], k: usize| v.get(k).map(|t| t.to_bits());
    match (0..grid.len().max(stored.len())).find(|&k| bits(stored, k) != bits(grid, k)) {
        None => Ok(()),
        Some(k) => {
            let show = |v: &[f64]| v.get(k).map_or("nothing".into(), |t| format!("{t:?} s"));
            Err(MergeError::Refused(format!(
                "{what}: /time is not the campaign's output grid ({} samples, {} stored): \
                 sample {k} reads {} where the model's grid has {}; the file was altered \
                 after the sweep wrote it",
                grid.len(),
                stored.len(),
                show(stored),
                show(grid),
            )))
        }
    }
}

/// What `sweep --resume FILE` runs, and the file reopened to take it.
pub struct Resume {
    pub prepared: crate::ensemble::Prepared,
    pub writer: CampaignWriter,
    /// per variant of `prepared`, its row in the file
    pub rows: Vec<usize>,
}

/// Reopen the campaign file at `target` for `sweep --resume`: refuses a file of another
/// campaign definition than `c` run on `stage` (naming what differs), then prepares the
/// file's variants that are not completed (pending, running, failed, interrupted, or
/// missing in a merge) and reopens the file with their rows cleared (state pending, NaN
/// samples); every completed row keeps its stored bytes. A variant that does not compile
/// is named as `origin` says (see [`crate::ensemble::Origin`]).
pub fn resume(
    target: OutputTarget,
    c: &crate::ensemble::Campaign,
    stage: &crate::ensemble::Stage,
    origin: &crate::ensemble::Origin,
) -> Result<Resume, MergeError> {
    resume_until(
        target,
        c,
        stage,
        origin,
        &std::sync::atomic::AtomicBool::new(false),
        None,
    )
}

/// [`resume`], its preparation stopped by `stop` (a signal's flag) between two variants
/// ([`crate::ensemble::prepare_rows_until`]): then [`MergeError::Interrupted`], and the
/// file is left as it was (it is only reopened for writing after the preparation).
///
/// With `mesh` (`sweep --mesh-check`), a completed variant it samples whose mesh error is
/// not in the file (NaN, and no warning that it could not be measured: the sweep stopped
/// before its twin ran) is run again too, so that it gets its twin: the resumed file then
/// holds what the sweep run whole holds (the run is deterministic, its samples are
/// rewritten as they were).
pub fn resume_until(
    target: OutputTarget,
    c: &crate::ensemble::Campaign,
    stage: &crate::ensemble::Stage,
    origin: &crate::ensemble::Origin,
    stop: &std::sync::atomic::AtomicBool,
    mesh: Option<&crate::verify::MeshSample>,
) -> Result<Resume, MergeError> {
    let f = CampaignFile::open(target.path())?;
    let unmeasured = |row: usize, s: &VariantStatus| {
        mesh.is_some_and(|m| f.global_index.get(row).is_some_and(|g| m.samples(*g)))
            && s.mesh_error_estimate.is_nan()
            && !s.warnings.contains("mesh error not measured")
    };
    let rerun: Vec<bool> = f
        .status
        .iter()
        .enumerate()
        .map(|(row, s)| s.state != VariantState::Completed || unmeasured(row, s))
        .collect();
    // a completed row keeps its stored values: an edited one would label its samples
    // wrongly, as `merge` refuses (until session 47 resume kept omega = 77 on the
    // samples of omega = 0 and marked the file complete; a probe)
    if let Some(why) = parameter_mismatch(&f, |row| !rerun.get(row).copied().unwrap_or(true)) {
        return Err(MergeError::Refused(format!(
            "--resume {}: {why} (was the file edited?)",
            f.path.display()
        )));
    }
    let rows: Vec<usize> = (0..rerun.len()).filter(|&r| rerun[r]).collect();
    // an index outside the campaign given now changes the definition: the hash tells
    let gis: Vec<usize> = rows
        .iter()
        .map(|&r| f.global_index[r])
        .filter(|&g| g < c.variants.len())
        .collect();
    let prepared = crate::ensemble::prepare_rows_until(c, gis, stop).map_err(|e| match e {
        e @ crate::ensemble::EnsembleError::Interrupted { .. } => MergeError::Interrupted(format!(
            "--resume {}: {e}; the file is left as it was",
            f.path.display()
        )),
        e => {
            let e = origin.name(e, &c.variants);
            MergeError::Refused(format!("--resume {}: {e}", f.path.display()))
        }
    })?;
    let now = crate::ensemble::identify(c, &prepared, stage)
        .map_err(|e| MergeError::Refused(e.to_string()))?;
    if now.hash != f.info.hash {
        let diff = differences(&f.info.definition, &now.definition);
        return Err(MergeError::Refused(format!(
            "--resume {}: the campaign definition changed (file: campaign {}, now: {}){}; \
             resume with the same model file, --vary/--variants, --set, --accuracy, \
             --frequency, backend and precision, and the same latdyn version",
            f.path.display(),
            f.info.id,
            now.id,
            if diff.is_empty() {
                String::new()
            } else {
                format!("; what differs: {}", diff.join("; "))
            }
        )));
    }
    let layout = prepared
        .models
        .first()
        .or(prepared.reference.as_ref())
        .ok_or_else(|| MergeError::Refused("--resume: no model compiled".into()))?;
    check_time_grid(
        &f.time,
        &crate::solver::dynamics::output_times(layout),
        &format!("--resume {}", f.path.display()),
    )?;
    let mut parameter_values = f.parameter_values.clone();
    for (v, &r) in rows.iter().enumerate() {
        parameter_values[r] = prepared.models[v].params.iter().map(|(_, x)| *x).collect();
    }
    let meta = CampaignMeta {
        command_line: c.command_line.clone(),
        model_path: f.model_path.clone(),
        model_source: f.model_source.clone(),
        backend: stage.backend.clone(),
        precision: stage.precision.clone(),
        adapter: stage.adapter.clone(),
        threads: c.threads,
        parameter_names: f.parameter_names.clone(),
        parameter_values,
        global_index: f.global_index.clone(),
        time: f.time.clone(),
        sensors: SensorMeta::of_model(layout),
    };
    let mut status = f.status.clone();
    let mut derived = f.derived.clone();
    for &r in &rows {
        status[r] = VariantStatus::default();
        for (_, d) in &mut derived {
            d[r] = f64::NAN;
        }
    }
    let datasets = meta
        .sensors
        .iter()
        .map(|s| f.sensor(&s.name))
        .collect::<Result<Vec<_>, _>>()?;
    for (ds, s) in datasets.iter().zip(&meta.sensors) {
        if let Some(why) = sensor_copy_mismatch(ds, f.global_index.len(), f.time.len(), s) {
            return Err(MergeError::Refused(format!(
                "--resume {}: /sensors/{}: {why}; --resume keeps the stored chunks of the \
                 completed variants as they are and refuses a file whose sensors were not \
                 written by latdyn (rewritten by another tool?)",
                f.path.display(),
                s.name
            )));
        }
    }
    let path = f.path.clone();
    let mut chunk = |k: usize, row: usize, ct: usize| -> Result<Option<Vec<u8>>, OutputError> {
        if rerun[row] {
            return Ok(None);
        }
        match datasets[k].read_chunk_raw_at(&[row, ct, 0]) {
            Ok((bytes, 0)) => Ok(Some(bytes)),
            Ok((_, mask)) => Err(OutputError::Invalid(format!(
                "{}: /sensors/{} chunk {row},{ct} skips filters (mask {mask}): not written by \
                 latdyn",
                path.display(),
                meta.sensors[k].name
            ))),
            Err(e) if e.to_string().contains("has not been written") => Ok(None),
            Err(e) => Err(OutputError::Invalid(format!(
                "{}: reading /sensors/{} chunk {row},{ct}: {e}",
                path.display(),
                meta.sensors[k].name
            ))),
        }
    };
    let verification = f.verification(&meta.sensors)?;
    let mut writer = CampaignWriter::reopen(
        target,
        &meta,
        Some(f.info.clone()),
        status,
        derived,
        &mut chunk,
    )?;
    if let Some(v) = &verification {
        writer.set_verification(v)?;
    }
    Ok(Resume {
        prepared,
        writer,
        rows,
    })
}

/// One variant run for a fraction of its time span by `sweep --plan` (see [`probe`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Probe {
    /// global index
    pub index: usize,
    /// the probe ran from 0 to this time (the variant's t_end × fraction)
    pub t_probe: f64,
    pub t_end: f64,
    /// compiling the variant's model [s] (a sweep compiles every variant once)
    pub compile_s: f64,
    /// the probe's time integration to `t_probe` [s]
    pub wall_s: f64,
    pub steps: usize,
    /// "completed", or why the probe stopped
    pub status: String,
    /// estimate of the whole variant: compile + setup + rate × t_end [s], from runs to
    /// t_probe / 2 and t_probe (wall = setup + rate × t)
    pub per_variant_s: f64,
}

/// Run the variants `indices` of `c` from 0 to `fraction` / 2 and `fraction` × t_end on
/// one CPU thread and time them: the cost per variant of the campaign, extrapolated
/// linearly in the simulated time (exact for fixed steps; with `--accuracy` the runs the
/// target needs over the short span may differ from those over the whole run). Each probe runs the sweep's own code path, so a variant that fails early
/// says so here.
pub fn probe(
    c: &crate::ensemble::Campaign,
    indices: &[usize],
    fraction: f64,
) -> Result<Vec<Probe>, crate::ensemble::EnsembleError> {
    let mut out = Vec::with_capacity(indices.len());
    for &g in indices {
        let t0 = std::time::Instant::now();
        let mut sets = c.base.clone();
        sets.extend(c.variants[g].iter().cloned());
        let mut m = crate::model::load(&c.model_path, &sets)
            .map_err(|e| crate::ensemble::EnsembleError::variant(g, &c.variants[g], e))?;
        if c.accuracy.is_some() {
            m.solver.accuracy = c.accuracy;
        }
        out.push(probe_model(m, g, t0.elapsed().as_secs_f64(), fraction));
    }
    Ok(out)
}

/// [`probe`] of the mesh twin of variant `g` (every beam's elements doubled at the
/// variant's step, [`crate::verify::mesh_twin_model`]), which `sweep --mesh-check` runs
/// after the campaign for a sampled variant: its cost beside the variants'. Under an
/// accuracy target the twin runs at the step the target chose, which the probe does not
/// know: it takes the model's `dt`. None where the twin has more free coordinates than
/// `max_dofs` (`--mesh-check auto` does not run it).
pub fn probe_twin(
    c: &crate::ensemble::Campaign,
    g: usize,
    fraction: f64,
    max_dofs: Option<usize>,
) -> Result<Option<Probe>, crate::ensemble::EnsembleError> {
    let t0 = std::time::Instant::now();
    let mut sets = c.base.clone();
    sets.extend(c.variants[g].iter().cloned());
    let named = |e: String| crate::ensemble::EnsembleError::variant(g, &c.variants[g], e);
    let m = crate::model::load(&c.model_path, &sets).map_err(|e| named(e.to_string()))?;
    let twin =
        crate::verify::mesh_twin_model(&c.model_path, &sets, &m, m.solver.dt).map_err(named)?;
    if max_dofs.is_some_and(|l| twin.n_eq > l) {
        return Ok(None);
    }
    Ok(Some(probe_model(
        twin,
        g,
        t0.elapsed().as_secs_f64(),
        fraction,
    )))
}

/// Time `m` (variant `g`, compiled in `compile_s`) over `fraction` / 2 and `fraction` of
/// its t_end and extrapolate to the whole run (see [`probe`]).
fn probe_model(mut m: crate::model::Model, g: usize, compile_s: f64, fraction: f64) -> Probe {
    let t_end = m.solver.t_end;
    // two runs, to half and to all of the probe span: wall = setup + rate × t, so
    // the setup (integrator, initial state) is not extrapolated with the time
    let mut runs = Vec::new();
    for f in [fraction / 2.0, fraction] {
        m.solver.t_end = t_end * f;
        let t1 = std::time::Instant::now();
        let (_, stats, err) = crate::solver::dynamics::run_with(&m, None, None, |_, _| {});
        runs.push((m.solver.t_end, t1.elapsed().as_secs_f64(), stats.steps, err));
    }
    let (ta, wa, _, _) = runs[0];
    let (tb, wb, steps, ref err) = runs[1];
    let rate = if tb > ta && wb > wa {
        (wb - wa) / (tb - ta)
    } else if tb > 0.0 {
        wb / tb
    } else {
        0.0
    };
    let setup = (wa - rate * ta).max(0.0);
    Probe {
        index: g,
        t_probe: tb,
        t_end,
        compile_s,
        wall_s: wb,
        steps,
        status: err
            .as_ref()
            .map_or_else(|| "completed".to_string(), |e| e.to_string()),
        per_variant_s: compile_s + setup + rate * t_end,
    }
}

/// Which variants a probe of `k` runs among `n`: spread evenly, first and last included.
pub fn probe_indices(n: usize, k: usize) -> Vec<usize> {
    if n == 0 || k == 0 {
        return Vec::new();
    }
    if k == 1 || n == 1 {
        return vec![0];
    }
    let mut v: Vec<usize> = (0..k.min(n))
        .map(|i| (i * (n - 1) + (k.min(n) - 1) / 2) / (k.min(n) - 1))
        .collect();
    v.dedup();
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input<'a>(
        src: &'a str,
        set: &'a [(String, f64)],
        variants: &'a [Vec<(String, f64)>],
        time: &'a [f64],
    ) -> DefinitionInput<'a> {
        DefinitionInput {
            model_path: Path::new("models/m.toml"),
            model_source: src,
            set,
            variants,
            time,
            sensors: &[],
            accuracy: None,
            frequency: None,
            backend: "cpu",
            precision: "f64",
        }
    }

    #[test]
    fn hash_changes_with_every_part_of_the_definition_and_not_with_set_order() {
        let v = |x: f64| vec![vec![("omega".to_string(), 1.0)], vec![("omega".into(), x)]];
        let set = vec![("a".to_string(), 1.0), ("b".to_string(), 2.0)];
        let set_rev: Vec<_> = set.iter().rev().cloned().collect();
        let (v2, v3) = (v(2.0), v(3.0));
        let t = [0.0, 0.5, 1.0];
        let base = identify(&input("x = 1", &set, &v2, &t)).unwrap();
        assert_eq!(base.hash.len(), 64);
        assert!(base.id.starts_with("m-") && base.id.len() == 2 + 12);
        assert_eq!(base, identify(&input("x = 1", &set_rev, &v2, &t)).unwrap());
        let others = [
            identify(&input("x = 2", &set, &v2, &t)).unwrap(),
            identify(&input("x = 1", &set[..1], &v2, &t)).unwrap(),
            identify(&input("x = 1", &set, &v3, &t)).unwrap(),
            identify(&input("x = 1", &set, &v2, &t[..2])).unwrap(),
        ];
        for (o, what) in others.iter().zip(["model", "set", "variants", "time"]) {
            assert_ne!(o.hash, base.hash, "{what}");
            assert!(!differences(&base.definition, &o.definition).is_empty());
        }
        let d = differences(&base.definition, &others[2].definition);
        assert_eq!(d.len(), 1, "{d:?}");
        assert!(d[0].starts_with("variants_sha256"), "{d:?}");
    }

    #[test]
    fn probes_spread_over_the_table_with_first_and_last() {
        assert_eq!(probe_indices(10, 3), vec![0, 5, 9]);
        assert_eq!(probe_indices(2, 3), vec![0, 1]);
        assert_eq!(probe_indices(1, 3), vec![0]);
        assert!(probe_indices(5, 0).is_empty());
    }
}
