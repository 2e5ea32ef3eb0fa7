//! The names of the campaign file's layout (see the [module docs](super#layout)) and the
//! one reader of it: the writer ([`super::CampaignWriter`]), `merge` / `sweep --resume`
//! ([`crate::campaign::CampaignFile`]) and the `plot` verb take every group, dataset and
//! attribute name from here, and read through [`Reader`]. The status encoding is
//! [`super::VariantState`] (`code`, `from_code`, `label`).

use std::collections::HashMap;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use rust_hdf5::format::global_heap::{decode_vlen_reference, GlobalHeapCollection};
use rust_hdf5::format::FormatContext;
use rust_hdf5::{DatatypeMessage, H5Dataset, H5File};

use super::SensorMeta;

/// Most components a `/sensors` dataset may claim when read: latdyn's sensors have a
/// dozen at most, and a reader builds one name per component before reading any data.
pub const MAX_SENSOR_COMPONENTS: usize = 1024;

/// Why a dataset is refused before it is read: the size its shape claims (`shape`, with
/// `element_size` bytes per element) exceeds what a file latdyn writes within the limits
/// of `LATDYN_LIMITS` ([`crate::model::limits`]) can hold; `None` if it may be read.
///
/// A chunked or resizable dataset whose chunks were never written reads back as its fill
/// value, so a 16 KB file can claim 10¹⁰ values: the claim is a number in the file, not
/// data, and reading it would allocate (and fill) that much. The bounds follow from the
/// limits every writer checks before it runs (a larger claim is not latdyn's writing):
/// - `/time` (and `/xarray/time`): output times ≤ `output_values`, since a run, sweep or
///   path keeps output times × (sensor components + 1) × variants ≤ `output_values`
///   values;
/// - `/sensors/<NAME>` [V, T, C]: V·T·C ≤ `output_values`, by the same product;
/// - a per-variant dataset (`/parameters/values`, `/status/*`, `/derived/*`,
///   `/campaign/variants`, `/sensors/*` rows): at most `variants` rows, since a sweep
///   (every shard, a merge) has at most that many variants and a run has one;
/// - any other dataset read whole (`/parameters/names`, `/campaign/*`, `/verification/*`,
///   the scalar texts): at most `output_values` elements and 8 × `output_values` bytes,
///   the memory the limit grants a campaign's values. No writer checks these directly,
///   but they hold one value per parameter, variant or sensor: `/parameters/values`, the
///   largest, holds variants × parameters, within it up to 1 000 parameters at the
///   largest campaign the variants limit allows (the shipped models have at most 79).
/// - `/model/source`: at most `model_bytes` bytes (the model file it copies was read
///   under that limit).
pub fn oversized_claim(name: &str, shape: &[usize], element_size: usize) -> Option<String> {
    let lim = match crate::model::Limits::from_env() {
        Ok(l) => l,
        Err(e) => return Some(e),
    };
    let name = name.trim_start_matches('/');
    let elements = shape.iter().fold(1.0f64, |n, &d| n * d as f64);
    // `claim` of `what` over `limit` (`rule` says why that bounds it); raising `key` to
    // `raise_to` would let it be read
    let refuse = |claim: f64, what: &str, rule: &str, limit: f64, key: &str, raise_to: f64| {
        let count = crate::model::limits::count;
        let env = crate::model::limits::ENV;
        let raise = if raise_to <= 1e18 {
            format!(
                "; if it really holds that many, raise the limit: {env}={key}={}",
                count(raise_to.ceil())
            )
        } else {
            String::new()
        };
        format!(
            "/{name} claims {} {what} (shape {shape:?}), refused before reading: {rule} \
             (limit {}: {env} key `{key}`). The file is damaged or not latdyn's{raise}",
            count(claim),
            count(limit),
        )
    };
    let per_variant = name == PARAMETER_VALUES
        || name == VARIANTS
        || [STATUS, DERIVED, SENSORS]
            .iter()
            .any(|g| name.strip_prefix(g).is_some_and(|r| r.starts_with('/')));
    let (out_values, variants) = (lim.output_values as f64, lim.variants as f64);
    if name == TIME || name == "xarray/time" {
        let n = shape.first().copied().unwrap_or(1) as f64;
        if n > out_values {
            return Some(refuse(
                n,
                "output times",
                "a file latdyn writes has at most as many output times as the output-values \
                 limit, since a run, sweep or path keeps output times × (sensor components \
                 + 1) × variants within it",
                out_values,
                "output_values",
                n,
            ));
        }
    }
    if per_variant {
        let n = shape.first().copied().unwrap_or(1) as f64;
        if n > variants {
            return Some(refuse(
                n,
                "variants",
                "a campaign latdyn writes has at most the variants limit",
                variants,
                "variants",
                n,
            ));
        }
    }
    if elements > out_values {
        return Some(refuse(
            elements,
            "values",
            "latdyn reads no dataset of more values than the output-values limit, the \
             values it keeps for a campaign",
            out_values,
            "output_values",
            elements,
        ));
    }
    let bytes = elements * element_size as f64;
    if name == MODEL_SOURCE && bytes > lim.model_bytes as f64 {
        return Some(refuse(
            bytes,
            "bytes",
            "it copies a model file, which latdyn reads up to the model-bytes limit",
            lim.model_bytes as f64,
            "model_bytes",
            bytes,
        ));
    }
    if bytes > 8.0 * out_values {
        return Some(refuse(
            bytes,
            "bytes",
            "latdyn reads no dataset of more bytes than 8 per value of the output-values \
             limit",
            8.0 * out_values,
            "output_values",
            bytes / 8.0,
        ));
    }
    None
}

/// A dataset of an open file (the HDF5 crate's handle).
pub use rust_hdf5::H5Dataset as Dataset;

/// Root attribute `format` of every campaign file.
pub const FORMAT: &str = "latdyn-campaign";

/// Root attributes.
pub mod attr {
    pub const LATDYN_VERSION: &str = "latdyn_version";
    pub const COMMAND_LINE: &str = "command_line";
    pub const BACKEND: &str = "backend";
    pub const PRECISION: &str = "precision";
    pub const ADAPTER: &str = "adapter";
    pub const THREADS: &str = "threads";
    pub const COMPLETE: &str = "complete";
    pub const STATUS: &str = "status";
    pub const FAILED_VARIANTS: &str = "failed_variants";
    pub const FORMAT: &str = "format";
    pub const FORMAT_VERSION: &str = "format_version";
    pub const CAMPAIGN_ID: &str = "campaign_id";
    pub const CAMPAIGN_HASH: &str = "campaign_hash";
    /// on `/time` and `/xarray/time`
    pub const UNITS: &str = "units";
    /// on `/sensors/<NAME>`: the component names (str [C]); `UNITS`: their units
    pub const COMPONENTS: &str = "components";
    /// on `/status/state`: the state names indexed by code
    pub const LABELS: &str = "labels";
}

/// Groups and datasets (paths from the root, without the leading `/`).
pub const MODEL: &str = "model";
pub const MODEL_SOURCE: &str = "model/source";
pub const MODEL_PATH: &str = "model/path";
pub const PARAMETERS: &str = "parameters";
pub const PARAMETER_NAMES: &str = "parameters/names";
pub const PARAMETER_VALUES: &str = "parameters/values";
pub const TIME: &str = "time";
pub const SENSORS: &str = "sensors";
pub const DERIVED: &str = "derived";
pub const STATUS: &str = "status";
pub const STATE: &str = "status/state";
pub const MESSAGE: &str = "status/message";
pub const T_FAIL: &str = "status/t_fail";
pub const STEPS: &str = "status/steps";
pub const REJECTED_STEPS: &str = "status/rejected_steps";
pub const WALL_S: &str = "status/wall_s";
pub const ENERGY_GROWTH: &str = "status/energy_growth";
pub const ENERGY_LOSS: &str = "status/energy_loss";
pub const TIME_ERROR_ESTIMATE: &str = "status/time_error_estimate";
pub const TIME_ERROR_BEFORE_FIRST_LOCK: &str = "status/time_error_before_first_lock";
pub const MESH_ERROR_ESTIMATE: &str = "status/mesh_error_estimate";
pub const WARNINGS: &str = "status/warnings";
pub const GLOBAL_INDEX: &str = "status/global_index";
pub const CAMPAIGN: &str = "campaign";
pub const DEFINITION: &str = "campaign/definition";
pub const VARIED: &str = "campaign/varied";
pub const VARIANTS: &str = "campaign/variants";
pub const SET_NAMES: &str = "campaign/set_names";
pub const SET_VALUES: &str = "campaign/set_values";
pub const VERIFICATION: &str = "verification";
pub const XARRAY: &str = "xarray";

/// `sensors/<name>`
pub fn sensor(name: &str) -> String {
    format!("{SENSORS}/{name}")
}

/// `derived/<name>`
pub fn derived(name: &str) -> String {
    format!("{DERIVED}/{name}")
}

/// The last component of a layout path (the name inside its group).
pub fn leaf(path: &str) -> &str {
    path.rsplit_once('/').map_or(path, |(_, n)| n)
}

/// A campaign file open for reading. Errors are messages naming the dataset (`no
/// /NAME (...)`, `reading /NAME: ...`); the caller adds the file path.
pub struct Reader {
    path: PathBuf,
    file: H5File,
}

impl Reader {
    /// Open `path` as HDF5; the error is the HDF5 library's message.
    pub fn open(path: &Path) -> Result<Reader, String> {
        let file = H5File::open(path).map_err(|e| e.to_string())?;
        Ok(Reader {
            path: path.to_path_buf(),
            file,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The open file, for what this reader does not cover (the sensor samples of
    /// `merge`, `/verification`).
    pub fn file(&self) -> &H5File {
        &self.file
    }

    /// A string attribute of the root group.
    pub fn root_attr(&self, name: &str) -> Option<String> {
        self.file.attr_string(name).ok()
    }

    /// A dataset, or `no /NAME (...)`.
    pub fn dataset(&self, name: &str) -> Result<H5Dataset, String> {
        self.file
            .dataset(name)
            .map_err(|e| format!("no /{name} ({e})"))
    }

    /// A dataset to be read whole, once the size its shape claims is checked
    /// ([`oversized_claim`]): `no /NAME (...)` or why its claim is refused.
    pub fn sized(&self, name: &str) -> Result<H5Dataset, String> {
        let d = self.dataset(name)?;
        match oversized_claim(name, &d.shape(), d.element_size()) {
            Some(why) => Err(why),
            None => Ok(d),
        }
    }

    /// A float64 dataset's values (empty for an empty dataset); the reads below all check
    /// the size the dataset claims first ([`Reader::sized`]).
    pub fn f64s(&self, name: &str) -> Result<Vec<f64>, String> {
        let d = self.sized(name)?;
        if d.total_elements() == 0 {
            return Ok(Vec::new());
        }
        d.read_raw::<f64>()
            .map_err(|e| format!("reading /{name}: {e}"))
    }

    /// An integer dataset's values as i64 (empty for an empty dataset).
    pub fn i64s(&self, name: &str) -> Result<Vec<i64>, String> {
        let d = self.sized(name)?;
        if d.total_elements() == 0 {
            return Ok(Vec::new());
        }
        d.read_numeric_as::<i64>()
            .map_err(|e| format!("reading /{name}: {e}"))
    }

    /// A string dataset's values (empty for an empty dataset).
    pub fn strings(&self, name: &str) -> Result<Vec<String>, String> {
        let d = self.sized(name)?;
        if d.total_elements() == 0 {
            return Ok(Vec::new());
        }
        d.read_strings()
            .map_err(|e| format!("reading /{name}: {e}"))
    }

    /// A scalar string dataset (`/model/source`, `/campaign/definition`), NUL padding
    /// removed.
    pub fn scalar_text(&self, name: &str) -> Result<String, String> {
        let d = self.sized(name)?;
        // a file rewritten by h5py stores a Python str as a variable-length string, whose
        // raw bytes are a heap reference: read as text, that was garbage (a merged
        // definition of reference bytes, "the stored model does not compile", NUL bytes
        // in a chart's title; a probe, session 46)
        if let Ok(DatatypeMessage::VarLenString { .. }) = d.datatype() {
            let mut all = d
                .read_strings_lossy()
                .map_err(|e| format!("reading /{name}: {e}"))?;
            if all.len() != 1 {
                return Err(format!(
                    "/{name} holds {} strings where one text is expected",
                    all.len()
                ));
            }
            return Ok(all.remove(0));
        }
        d.read_raw_bytes()
            .map(|b| {
                String::from_utf8_lossy(&b)
                    .trim_end_matches('\0')
                    .to_string()
            })
            .map_err(|e| format!("reading /{name}: {e}"))
    }

    /// Whether the dataset exists.
    pub fn has_dataset(&self, name: &str) -> bool {
        self.file.dataset(name).is_ok()
    }

    /// Whether the group exists.
    pub fn has_group(&self, group: &str) -> bool {
        self.file.root_group().group(group).is_ok()
    }

    /// Names of the datasets in a group, sorted (empty if there is no such group).
    pub fn names_in(&self, group: &str) -> Vec<String> {
        let mut v = self
            .file
            .root_group()
            .group(group)
            .ok()
            .and_then(|g| g.dataset_names().ok())
            .unwrap_or_default();
        v.sort();
        v
    }

    /// A sensor's name, components and units from its attributes; `c0`, `c1`, … and no
    /// units where they cannot be read. `ds` is the `/sensors/<name>` dataset. Refused
    /// (before any allocation) when the dataset claims more than
    /// [`MAX_SENSOR_COMPONENTS`] components: a 16 KB file can claim 10⁹.
    pub fn sensor_meta(&self, name: &str, ds: &H5Dataset) -> Result<SensorMeta, String> {
        let n_comp = ds.shape().get(2).copied().unwrap_or(1);
        if n_comp > MAX_SENSOR_COMPONENTS {
            return Err(format!(
                "/sensors/{name}: shape {:?} claims {n_comp} components; a latdyn sensor has \
                 at most {MAX_SENSOR_COMPONENTS} (the file is damaged or not latdyn's)",
                ds.shape()
            ));
        }
        let mut components = self
            .string_array_attr(ds, attr::COMPONENTS)
            .unwrap_or_default();
        if components.len() != n_comp {
            components = (0..n_comp).map(|c| format!("c{c}")).collect();
        }
        let mut units = self.string_array_attr(ds, attr::UNITS).unwrap_or_default();
        if units.len() != n_comp {
            units = vec![String::new(); n_comp];
        }
        Ok(SensorMeta {
            name: name.to_string(),
            components,
            units,
        })
    }

    /// A string-array attribute of a dataset (variable-length or fixed-length strings).
    ///
    /// rust-hdf5 0.7.9 (the newest) reads only scalar string attributes, so
    /// variable-length arrays are decoded here, the one place that knows the format:
    /// the attribute holds one global-heap reference per element.
    pub fn string_array_attr(&self, ds: &H5Dataset, name: &str) -> Option<Vec<String>> {
        let attr = ds.attr(name).ok()?;
        let raw = attr.read_raw().ok()?;
        match attr.datatype().ok()? {
            DatatypeMessage::FixedString { size, .. } => {
                let size = (size as usize).max(1);
                Some(
                    raw.chunks(size)
                        .map(|c| {
                            String::from_utf8_lossy(c)
                                .trim_end_matches(['\0', ' '])
                                .to_string()
                        })
                        .collect(),
                )
            }
            DatatypeMessage::VarLenString { .. } => self.vlen_strings(&raw).ok(),
            _ => None,
        }
    }

    /// Resolve variable-length string references through the file's global heap.
    fn vlen_strings(&self, raw: &[u8]) -> std::io::Result<Vec<String>> {
        let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, m.to_string());
        let base = self.file.userblock_size();
        let mut f = std::fs::File::open(&self.path)?;
        let mut sb = [0u8; 16];
        f.seek(SeekFrom::Start(base))?;
        f.read_exact(&mut sb)?;
        if &sb[..8] != b"\x89HDF\r\n\x1a\n" {
            return Err(bad("no superblock signature"));
        }
        let (sizeof_addr, sizeof_size) = match sb[8] {
            0 | 1 => (sb[13], sb[14]),
            _ => (sb[9], sb[10]),
        };
        let ctx = FormatContext {
            sizeof_addr,
            sizeof_size,
        };
        let ref_size = 4 + sizeof_addr as usize + 4;
        let ss = sizeof_size as usize;
        let mut heaps: HashMap<u64, GlobalHeapCollection> = HashMap::new();
        let mut out = Vec::with_capacity(raw.len() / ref_size);
        for r in raw.chunks_exact(ref_size) {
            let (_len, addr, index) =
                decode_vlen_reference(r, &ctx).map_err(|e| bad(&e.to_string()))?;
            if addr == 0 || addr == u64::MAX {
                out.push(String::new());
                continue;
            }
            if let std::collections::hash_map::Entry::Vacant(e) = heaps.entry(addr) {
                let mut head = vec![0u8; 8 + ss];
                f.seek(SeekFrom::Start(base + addr))?;
                f.read_exact(&mut head)?;
                if &head[..4] != b"GCOL" {
                    return Err(bad("bad global heap signature"));
                }
                let mut n = 0u64;
                for (i, b) in head[8..8 + ss].iter().enumerate() {
                    n |= u64::from(*b) << (8 * i);
                }
                let size = usize::try_from(n).map_err(|_| bad("heap size"))?;
                if !(16..=1 << 30).contains(&size) {
                    return Err(bad("implausible global heap size"));
                }
                let mut buf = vec![0u8; size];
                f.seek(SeekFrom::Start(base + addr))?;
                f.read_exact(&mut buf)?;
                let (coll, _) =
                    GlobalHeapCollection::decode(&buf, &ctx).map_err(|e| bad(&e.to_string()))?;
                e.insert(coll);
            }
            let idx = u16::try_from(index).map_err(|_| bad("heap index"))?;
            let obj = heaps[&addr]
                .get_object(idx)
                .ok_or_else(|| bad("missing heap object"))?;
            out.push(String::from_utf8_lossy(obj).into_owned());
        }
        Ok(out)
    }
}
