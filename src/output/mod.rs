//! HDF5 campaign output: one file per campaign (a set of variants of one model, run
//! over a common output time grid), readable by h5py and the HDF5 command-line tools.
//!
//! Written with the pure-Rust `rust-hdf5` crate: no system HDF5 library is needed.
//!
//! # Layout
//!
//! `V` = number of variants in this file, `T` = number of output times, `P` = number of
//! parameters, `C` = components of a sensor. Strings are UTF-8.
//!
//! ```text
//! /                        attrs: latdyn_version, command_line, backend, precision,
//!                                 adapter (str; GPU adapter, empty on the CPU)
//!                                 threads (int64), complete (int64, 0/1),
//!                                 status (str: "running" | "complete" | "interrupted"),
//!                                 failed_variants (int64: variants in state failed;
//!                                 "complete" only says the campaign ran to its end),
//!                                 format = "latdyn-campaign", format_version = 1 (int64)
//! /model/source            str (scalar): the model file text
//! /model/path              str (scalar): the model file path as given
//! /parameters/names        str [P]
//! /parameters/values       float64 [V, P]
//! /time                    float64 [T], attr units = "s"
//! /sensors/<NAME>          float64 [V, T, C], chunked [1, ≤T, C], shuffle + deflate,
//!                          fill value NaN; attrs components (str [C]), units (str [C])
//! /status/state            int32 [V]: 0 pending, 1 running, 2 completed, 3 failed,
//!                          4 interrupted; attr labels = the names indexed by code
//! /status/message          str [V] (empty unless the variant failed or was interrupted)
//! /status/t_fail           float64 [V] (NaN unless set)
//! /status/steps            int64 [V]
//! /status/rejected_steps   int64 [V]
//! /status/wall_s           float64 [V] (NaN until set)
//! /status/energy_growth    float64 [V]: growth of the energy balance (see
//!                          `RunStats::energy_growth`; > 1e-3 means probably unstable),
//!                          NaN where not yet run
//! /status/energy_loss      float64 [V]: numerical loss of the energy balance (see
//!                          `RunStats::energy_loss`; above `ENERGY_LOSS_LIMIT` the step
//!                          is too large), NaN where not yet run
//! /status/time_error_estimate float64 [V]: estimated time-discretisation error of the
//!                          sensors relative to their range, largest over the sensors
//!                          (README "Accuracy"), NaN where not run
//! /status/time_error_before_first_lock float64 [V]: the same just before the variant's
//!                          first hinge lock, NaN without a lock (files written before
//!                          session 24 lack it; read as NaN)
//! /status/mesh_error_estimate float64 [V]: estimated mesh error of the sensors relative
//!                          to their range, measured by `run`'s mesh twin (README
//!                          "Accuracy") and, in a sweep, for the variants `--mesh-check`
//!                          samples; NaN where not measured (files written before
//!                          session 49 lack it, read as NaN)
//! /status/warnings         str [V]: the variant's warnings, one per line (empty: none)
//! /status/global_index     int64 [V]: index of each variant in the whole campaign
//!                          (differs from the row index when the campaign is sharded)
//! /derived/<NAME>          float64 [V], NaN where not set (only names ever set exist)
//! ```
//!
//! A sweep (every shard of it) also records its campaign's identity (see
//! [`crate::campaign`]; `N` = variants of the whole campaign, `Q` = varied parameters,
//! `S` = `--set` values):
//!
//! ```text
//! /                        attrs: campaign_id (str), campaign_hash (str: SHA-256 hex)
//! /campaign/definition     str (scalar): the JSON object the hash is taken of
//! /campaign/varied         str [Q]: names of the varied parameters
//! /campaign/variants       float64 [N, Q]: their values, per global index
//! /campaign/set_names      str [S], /campaign/set_values float64 [S]: the --set values
//! /xarray                  the campaign labelled for xarray (netCDF-4 dimension scales;
//!                          only when V > 0 and T > 0):
//! /xarray/variant          int64 [V]: dimension scale `variant` (global indices)
//! /xarray/time             float64 [T]: dimension scale `time` (a copy of /time)
//! /xarray/<NAME>_component str [C]: dimension scale, the component names of a sensor
//! /xarray/<PARAM>          float64 [V]: each varied parameter, on `variant`
//! /xarray/<NAME>           hard link to /sensors/<NAME>, dims (variant, time,
//!                          <NAME>_component); attr coordinates = the varied parameters
//! /xarray/<DERIVED>, /xarray/state   hard links to /derived/*, /status/state (variant)
//! ```
//!
//! When the campaign varies one parameter whose values are strictly monotonic in global
//! index order (a `--vary` range; see [`xarray_axis`]), that parameter names the variant
//! axis instead: `/xarray/<PARAM>` is the dimension scale `<PARAM>`, and
//! `/xarray/variant` (the global indices) a coordinate on it (attr coordinates =
//! `variant`), so `sel(<PARAM>=..., method="nearest")` needs no `set_xindex`.
//!
//! Attaching the scales gives /sensors/*, /derived/* and /status/state a
//! `DIMENSION_LIST` attribute (and `coordinates`); the samples are not copied.
//!
//! A campaign run with `sweep --verify K` also has (README "Discretisation error of a
//! campaign"; `K` =
//! variants verified, `W` = warnings):
//!
//! ```text
//! /verification/target         float64 (scalar): the relative difference above which a
//!                              warning is raised
//! /verification/target_source  str (scalar): "--accuracy", "[solver] accuracy" or
//!                              "default"
//! /verification/variants       int64 [K]: global indices of the variants verified
//! /verification/status         str [K]: "verified", or why the variant was not
//! /verification/wall_s         float64 [K]: wall time of each refined run
//! /verification/dt             float64 [K, 2]: solver dt of the base and the refined run
//! /verification/elements       int64 [K, 2]: element count of the base and refined mesh
//! /verification/max_rel_diff   float64 (scalar): largest relative difference (NaN if
//!                              no variant was verified)
//! /verification/warnings       str [W]
//! /verification/rel_diff/<NAME>     float64 [K, C]: per variant and component, the
//!                              change of the extremes relative to the scale (NaN
//!                              where not verified); attr components (str [C])
//! /verification/refined_min/<NAME>  float64 [K, C]: extremes of the refined runs
//! /verification/refined_max/<NAME>  float64 [K, C]
//! ```
//!
//! Samples never written read back as NaN (the fill value of `/sensors/*`).
//!
//! # Durability
//!
//! The writer keeps the whole campaign in memory. [`CampaignWriter::flush`] writes a
//! complete HDF5 file next to the target (`.<name>.<pid>.tmp`), `fsync`s it and renames
//! it over the target, then `fsync`s the directory: the file at `path` is always a
//! complete, valid HDF5 file (the previous flush's or this one's), so a crash or Ctrl-C
//! loses only what was written after the last flush. [`CampaignWriter::create`] does a
//! first flush, so an unwritable path fails at once.
//!
//! Cost of a flush: each sensor chunk (one variant, up to [`CHUNK_ELEMENTS`] values) is
//! compressed once per flush in which it changed, and kept compressed in memory; every
//! flush then writes the whole (compressed) file. Memory: 8 bytes per sample value plus
//! the compressed copy. Measured at 1000 variants × 1000 times × 10 sensors × 3
//! components (240 MB of samples, noisy data → 209 MB file, 2-core machine): a flush
//! that recompresses everything takes 5.5 s, a flush after one more variant 0.5 s
//! (writing + fsync of the file). So flush per finished variant or on a timer, not per
//! time step (`tests/hdf5_output.rs`, ignored test `flush_cost_large_campaign`).
//!
//! A writer dropped without [`CampaignWriter::finish`] leaves the last flushed file
//! (status "running"). A reader that has the file open during a flush keeps seeing the
//! old version (the rename replaces the directory entry, not the data).
//!
//! # The output path
//!
//! [`OutputTarget::claim`] is the one gate for every output file (HDF5 and CSV), taken
//! before any simulation:
//! - an existing target must be a regular file: a directory, FIFO, device or socket is
//!   refused;
//! - a symbolic link is refused, at the target and at its lock file: latdyn neither
//!   writes through a symlink nor replaces one (give the real path);
//! - the directory must exist and be writable: a temporary file is created there;
//! - an exclusive lock (`File::try_lock`) on the sidecar `<path>.lock`, held until the
//!   file is finished, so two processes cannot write one file: the second is refused,
//!   naming the first (its pid and command line are in the lock file), and the first's
//!   file is untouched. The lock file is removed when the writer ends normally; one left
//!   by a killed process is harmless (the kernel released its lock).
//!
//! Every write is a complete file at a temporary path in the same directory, renamed
//! over the target (atomic on POSIX file systems).

pub mod layout;

use layout::{attr, leaf};

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use rust_hdf5::format::messages::filter::{apply_filters, FilterPipeline};
use rust_hdf5::{DatatypeMessage, H5File, H5Group};

/// Writes the sensor chunks of a streamed file into its `/sensors` datasets (see
/// [`CampaignWriter::write_streamed`]).
pub type FillChunks<'a> = dyn FnMut(&[rust_hdf5::H5Dataset]) -> Result<(), OutputError> + 'a;

/// The command line as the user typed it, for the files and lock files that record it.
/// An argument that is not valid UTF-8 (a path with a Latin-1 byte) is shown lossily
/// (U+FFFD) instead of panicking as `std::env::args` does.
pub fn command_line() -> String {
    std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

/// `path` with `suffix` appended to its file name, byte for byte (a name that is not
/// UTF-8 keeps its bytes: a lossy name could make two paths share a lock file).
fn sibling_with_suffix(path: &Path, prefix: &str, suffix: &str) -> PathBuf {
    let mut name = std::ffi::OsString::from(prefix);
    name.push(path.file_name().unwrap_or_default());
    name.push(suffix);
    path.with_file_name(name)
}

/// Why the stored chunks of `/sensors/<name>` dataset `ds` (of a file latdyn is to copy
/// them from, `merge` or `sweep --resume`) cannot be copied as stored bytes into a file
/// latdyn writes, or `None` if they can: its chunks must be `chunk` and it must hold
/// little-endian IEEE float64 through the filters latdyn's writer uses (shuffle of 8-byte
/// elements, then deflate at any level). Another pipeline (no shuffle, no compression,
/// a checksum, another compressor) or element type would be read back as garbage after a
/// raw copy: a decoder of the shuffled pipeline decodes unshuffled bytes into other
/// numbers without any error.
pub fn raw_copy_mismatch(ds: &rust_hdf5::H5Dataset, chunk: &[usize]) -> Option<String> {
    use rust_hdf5::format::messages::filter::{FILTER_DEFLATE, FILTER_SHUFFLE};
    let chunks = ds.chunk_dims();
    if chunks.as_deref() != Some(chunk) {
        return Some(format!(
            "its chunks are {}, latdyn writes {chunk:?}",
            chunks.map_or("none (not chunked)".to_string(), |c| format!("{c:?}"))
        ));
    }
    match ds.datatype() {
        Ok(DatatypeMessage::FloatingPoint {
            size: 8,
            byte_order: rust_hdf5::ByteOrder::LittleEndian,
            bit_offset: 0,
            bit_precision: 64,
            exponent_size: 11,
            mantissa_size: 52,
            exponent_bias: 1023,
            ..
        }) => {}
        Ok(other) => {
            return Some(format!(
                "its element type is {other:?}, latdyn writes little-endian float64"
            ))
        }
        Err(e) => return Some(format!("its element type cannot be read ({e})")),
    }
    let filters = match ds.filters() {
        Ok(f) => f,
        Err(e) => return Some(format!("its filter pipeline cannot be read ({e})")),
    };
    let name = |id: u16| match id {
        FILTER_SHUFFLE => "shuffle".to_string(),
        FILTER_DEFLATE => "deflate".to_string(),
        3 => "fletcher32".to_string(),
        other => format!("filter {other}"),
    };
    let ok = matches!(
        filters.as_slice(),
        [sh, de] if sh.id == FILTER_SHUFFLE
            && (sh.cd_values.is_empty() || sh.cd_values[0] == 8)
            && de.id == FILTER_DEFLATE
    );
    if ok {
        None
    } else {
        let shown: Vec<String> = filters.iter().map(|f| name(f.id)).collect();
        Some(format!(
            "its filter pipeline is {}, latdyn writes [shuffle, deflate]",
            if shown.is_empty() {
                "empty (uncompressed)".to_string()
            } else {
                format!("[{}]", shown.join(", "))
            }
        ))
    }
}

/// Longest sensor or derived-quantity name, in bytes (UTF-8). The HDF5 layout stores
/// names as link names, which this library cannot read back from 65 536 bytes on (the
/// file was written, then `plot` found no such sensor and `merge` failed); 255 is the
/// common file-name limit and far more than any readable CSV column or legend needs.
pub const MAX_NAME_BYTES: usize = 255;

/// Target number of f64 values in one sensor chunk (512 KiB uncompressed).
pub const CHUNK_ELEMENTS: usize = 65_536;

/// Time samples per chunk of a sensor with `n_comp` components over `n_time` output
/// times: chunks are [1, this, n_comp], whatever the number of variants, so a shard's
/// chunks are the whole campaign's chunks.
pub fn chunk_times(n_comp: usize, n_time: usize) -> usize {
    (CHUNK_ELEMENTS / n_comp.max(1)).clamp(1, n_time.max(1))
}

/// Deflate level of the sensor datasets (after the shuffle filter).
const DEFLATE_LEVEL: u32 = 4;

/// Version of this layout, stored as the root attribute `format_version`.
pub const FORMAT_VERSION: i64 = 1;

/// One sensor of the campaign: its dataset name and per-component names and units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SensorMeta {
    pub name: String,
    pub components: Vec<String>,
    pub units: Vec<String>,
}

impl SensorMeta {
    /// The model's sensors as the campaign layout names them.
    pub fn of_model(m: &crate::model::Model) -> Vec<SensorMeta> {
        m.sensors
            .iter()
            .map(|s| SensorMeta {
                name: s.name.clone(),
                components: crate::sensors::components(&s.kind)
                    .iter()
                    .map(|x| x.to_string())
                    .collect(),
                units: crate::sensors::units(&s.kind)
                    .iter()
                    .map(|x| x.to_string())
                    .collect(),
            })
            .collect()
    }
}

/// Everything known about a campaign before it runs.
///
/// The number of variants is `parameter_values.len()`; `global_index` has one entry per
/// variant (or is empty, meaning `0..V`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CampaignMeta {
    pub command_line: String,
    pub model_path: String,
    pub model_source: String,
    pub backend: String,
    pub precision: String,
    /// GPU adapter of the element stage ("name (backend, device type)"), empty on the CPU
    pub adapter: String,
    pub threads: usize,
    pub parameter_names: Vec<String>,
    /// Per variant, one value per parameter name.
    pub parameter_values: Vec<Vec<f64>>,
    pub global_index: Vec<usize>,
    pub time: Vec<f64>,
    pub sensors: Vec<SensorMeta>,
}

impl CampaignMeta {
    /// The layout of one run of `m` (`run -o`): a single variant holding the model's
    /// parameters, global index 0, on the model's output grid, one thread.
    pub fn single_run(
        m: &crate::model::Model,
        stage: &crate::ensemble::Stage,
        command_line: String,
    ) -> CampaignMeta {
        CampaignMeta {
            command_line,
            model_path: m.path.clone(),
            model_source: m.source.clone(),
            backend: stage.backend.clone(),
            precision: stage.precision.clone(),
            adapter: stage.adapter.clone(),
            threads: 1,
            parameter_names: m.params.iter().map(|(n, _)| n.clone()).collect(),
            parameter_values: vec![m.params.iter().map(|(_, v)| *v).collect()],
            global_index: vec![0],
            time: crate::solver::dynamics::output_times(m),
            sensors: SensorMeta::of_model(m),
        }
    }
}

/// Outcome of one variant, stored under `/status`.
#[derive(Clone, Debug, PartialEq)]
pub struct VariantStatus {
    pub state: VariantState,
    pub message: String,
    pub t_fail: f64,
    pub steps: u64,
    pub rejected_steps: u64,
    pub wall_s: f64,
    /// growth of the energy balance, NaN where not defined
    pub energy_growth: f64,
    /// loss of the energy balance, NaN where not defined
    pub energy_loss: f64,
    /// estimated relative time-discretisation error, NaN where not run
    pub time_error_estimate: f64,
    /// the same just before the first hinge lock, NaN without a lock
    pub time_error_before_first_lock: f64,
    /// estimated relative mesh error (`run`'s mesh twin), NaN where not measured
    pub mesh_error_estimate: f64,
    /// warnings about the variant's numbers, one per line
    pub warnings: String,
}

impl Default for VariantStatus {
    /// A pending variant: empty message, NaN times, zero steps.
    fn default() -> Self {
        VariantStatus {
            state: VariantState::Pending,
            message: String::new(),
            t_fail: f64::NAN,
            steps: 0,
            rejected_steps: 0,
            wall_s: f64::NAN,
            energy_growth: f64::NAN,
            energy_loss: f64::NAN,
            time_error_estimate: f64::NAN,
            time_error_before_first_lock: f64::NAN,
            mesh_error_estimate: f64::NAN,
            warnings: String::new(),
        }
    }
}

impl VariantStatus {
    /// The status of a variant that ended in `state` after a run with these statistics
    /// (`t_fail` NaN unless it failed or was interrupted; `warnings` one per line).
    pub fn of_run(
        state: VariantState,
        message: String,
        t_fail: f64,
        stats: &crate::solver::dynamics::RunStats,
        wall_s: f64,
        warnings: String,
    ) -> VariantStatus {
        VariantStatus {
            state,
            message,
            t_fail,
            steps: stats.steps as u64,
            rejected_steps: stats.rejected_steps as u64,
            wall_s,
            energy_growth: stats.energy_growth.unwrap_or(f64::NAN),
            energy_loss: stats.energy_loss.unwrap_or(f64::NAN),
            time_error_estimate: stats.time_error_estimate.unwrap_or(f64::NAN),
            time_error_before_first_lock: stats.time_error_before_first_lock.unwrap_or(f64::NAN),
            mesh_error_estimate: f64::NAN,
            warnings,
        }
    }
}

/// State of one variant; stored as its [`code`](VariantState::code) in `/status/state`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VariantState {
    #[default]
    Pending,
    Running,
    Completed,
    Failed,
    Interrupted,
}

impl VariantState {
    /// All states, indexed by their code.
    pub const ALL: [VariantState; 5] = [
        VariantState::Pending,
        VariantState::Running,
        VariantState::Completed,
        VariantState::Failed,
        VariantState::Interrupted,
    ];

    /// Integer code stored in `/status/state`.
    pub fn code(self) -> i32 {
        match self {
            VariantState::Pending => 0,
            VariantState::Running => 1,
            VariantState::Completed => 2,
            VariantState::Failed => 3,
            VariantState::Interrupted => 4,
        }
    }

    /// Inverse of [`code`](VariantState::code).
    pub fn from_code(code: i64) -> Option<VariantState> {
        usize::try_from(code)
            .ok()
            .and_then(|c| Self::ALL.get(c).copied())
    }

    /// Lower-case name (the `labels` attribute of `/status/state`).
    pub fn label(self) -> &'static str {
        match self {
            VariantState::Pending => "pending",
            VariantState::Running => "running",
            VariantState::Completed => "completed",
            VariantState::Failed => "failed",
            VariantState::Interrupted => "interrupted",
        }
    }
}

/// Errors of the campaign writer.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output file (or its temporary sibling) cannot be created, written or renamed.
    #[error("cannot write output {}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
    /// The HDF5 library refused an operation.
    #[error("HDF5 error writing {} ({what}): {message}", path.display())]
    Hdf5 {
        path: PathBuf,
        what: String,
        message: String,
    },
    /// Inconsistent campaign description, or an argument out of range (a caller bug).
    #[error("HDF5 output: {0}")]
    Invalid(String),
}

/// An output path claimed for writing: validated, its directory shown writable, and
/// locked against other processes (see the [module docs](self#the-output-path)). The
/// lock is held until this value is dropped.
#[derive(Debug)]
pub struct OutputTarget {
    path: PathBuf,
    lock_path: PathBuf,
    lock: Option<fs::File>,
}

/// What is at `p`, refusing anything but a regular file or nothing.
fn check_regular(p: &Path, what: &str) -> Result<(), String> {
    match fs::symlink_metadata(p) {
        Ok(m) => {
            let ft = m.file_type();
            let kind = if ft.is_symlink() {
                Some(
                    "a symbolic link (latdyn does not write through or replace symlinks; \
                     give the real path)",
                )
            } else if ft.is_dir() {
                Some("a directory")
            } else if ft.is_file() {
                None
            } else {
                #[cfg(unix)]
                {
                    use std::os::unix::fs::FileTypeExt;
                    Some(if ft.is_fifo() {
                        "a FIFO"
                    } else if ft.is_char_device() || ft.is_block_device() {
                        "a device"
                    } else if ft.is_socket() {
                        "a socket"
                    } else {
                        "not a regular file"
                    })
                }
                #[cfg(not(unix))]
                Some("not a regular file")
            };
            match kind {
                Some(k) => Err(format!("{what} is {k}, not a regular file")),
                None => Ok(()),
            }
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(format!("{what}: {e}")),
    }
}

/// Both handles name the same file (the lock file was not replaced in between).
fn same_file(a: &fs::Metadata, b: &fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        a.dev() == b.dev() && a.ino() == b.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (a, b);
        true
    }
}

impl OutputTarget {
    /// Validate `path`, check its directory is writable (a temporary file is created and
    /// removed there) and take the exclusive lock `<path>.lock`. Every refusal is an
    /// [`OutputError::Io`] whose message says why; nothing at `path` is touched.
    pub fn claim(path: &Path) -> Result<OutputTarget, OutputError> {
        let err = |kind: io::ErrorKind, msg: String| OutputError::Io {
            path: path.to_path_buf(),
            source: io::Error::new(kind, msg),
        };
        let io_err = |source: io::Error| OutputError::Io {
            path: path.to_path_buf(),
            source,
        };
        match path.file_name() {
            Some(_) => {}
            None => {
                return Err(err(
                    io::ErrorKind::InvalidInput,
                    "the path names no file".into(),
                ))
            }
        };
        check_regular(path, "it").map_err(|m| err(io::ErrorKind::InvalidInput, m))?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        match fs::metadata(dir) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => {
                return Err(err(
                    io::ErrorKind::NotADirectory,
                    format!("{} is not a directory", dir.display()),
                ))
            }
            Err(e) => {
                return Err(err(
                    e.kind(),
                    format!("its directory {}: {e}", dir.display()),
                ))
            }
        }
        let lock_path = sibling_with_suffix(path, "", ".lock");
        for _ in 0..8 {
            check_regular(
                &lock_path,
                &format!("the lock file {}", lock_path.display()),
            )
            .map_err(|m| err(io::ErrorKind::InvalidInput, m))?;
            let mut f = fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&lock_path)
                .map_err(io_err)?;
            match f.try_lock() {
                Ok(()) => {}
                Err(fs::TryLockError::WouldBlock) => {
                    use io::Read;
                    let mut holder = String::new();
                    let _ = f.read_to_string(&mut holder);
                    let holder = holder.trim();
                    return Err(err(
                        io::ErrorKind::ResourceBusy,
                        format!(
                            "another latdyn process is writing it ({}); wait for it to end or \
                             choose another path (lock file {})",
                            if holder.is_empty() {
                                "pid unknown"
                            } else {
                                holder
                            },
                            lock_path.display()
                        ),
                    ));
                }
                Err(fs::TryLockError::Error(e)) => return Err(io_err(e)),
            }
            // A writer that just finished removes its lock file before unlocking: a lock
            // on that removed file guards nothing, so take the lock file anew.
            let current = fs::symlink_metadata(&lock_path).ok();
            let mine = f.metadata().ok();
            if !matches!((current, mine), (Some(a), Some(b)) if same_file(&a, &b)) {
                continue;
            }
            {
                use io::Write;
                let _ = f.set_len(0);
                let _ = writeln!(f, "pid {}: {}", std::process::id(), command_line());
            }
            let target = OutputTarget {
                path: path.to_path_buf(),
                lock_path,
                lock: Some(f),
            };
            // Show the directory writable before any work: the way every write goes.
            let probe = target.tmp_path();
            let _ = fs::remove_file(&probe);
            fs::File::create_new(&probe).map_err(io_err)?;
            let _ = fs::remove_file(&probe);
            return Ok(target);
        }
        Err(err(
            io::ErrorKind::ResourceBusy,
            format!(
                "the lock file {} keeps being replaced by other processes",
                lock_path.display()
            ),
        ))
    }

    /// The claimed path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary sibling every write goes through (`.<name>.<pid>.tmp`).
    fn tmp_path(&self) -> PathBuf {
        sibling_with_suffix(&self.path, ".", &format!(".{}.tmp", std::process::id()))
    }

    /// Replace the file with `bytes`: written to the temporary sibling, `fsync`ed,
    /// renamed over the target, directory `fsync`ed. On failure the previous file stays.
    pub fn replace_with(&self, bytes: &[u8]) -> Result<(), OutputError> {
        let tmp = self.tmp_path();
        let r = (|| {
            use io::Write;
            let _ = fs::remove_file(&tmp);
            let mut f = fs::File::create_new(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(source) = r {
            let _ = fs::remove_file(&tmp);
            return Err(OutputError::Io {
                path: self.path.clone(),
                source,
            });
        }
        self.commit(&tmp)
    }

    /// Rename the finished temporary file over the target and make the rename durable.
    fn commit(&self, tmp: &Path) -> Result<(), OutputError> {
        // the target may have been replaced by something else since the claim
        check_regular(&self.path, "it").map_err(|m| OutputError::Io {
            path: self.path.clone(),
            source: io::Error::new(io::ErrorKind::InvalidInput, m),
        })?;
        fs::rename(tmp, &self.path).map_err(|source| {
            let _ = fs::remove_file(tmp);
            OutputError::Io {
                path: self.path.clone(),
                source,
            }
        })?;
        if let Some(dir) = self.path.parent() {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            if let Ok(d) = fs::File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }
}

impl Drop for OutputTarget {
    fn drop(&mut self) {
        if let Some(f) = self.lock.take() {
            // removed while still locked: see `claim` for why that order is safe
            let _ = fs::remove_file(&self.lock_path);
            let _ = f.unlock();
        }
    }
}

/// Samples of one sensor for all variants, with a cache of its compressed chunks.
struct SensorBuf {
    meta: SensorMeta,
    n_comp: usize,
    /// Time samples per chunk.
    chunk_t: usize,
    /// Chunks along time per variant.
    chunks_t: usize,
    /// Row-major [V, T, C], NaN where never written.
    data: Vec<f64>,
    /// Per chunk (variant-major): filtered bytes, `None` if never written.
    compressed: Vec<Option<Vec<u8>>>,
    /// Per chunk: written since it was last compressed.
    dirty: Vec<bool>,
}

/// What `sweep --verify` measured, as written under `/verification` (see the layout in
/// the module docs; `K` = variants verified).
#[derive(Clone, Debug, Default)]
pub struct VerificationData {
    pub target: f64,
    pub target_source: String,
    /// global indices [K]
    pub variants: Vec<usize>,
    /// [K]: "verified" or why not
    pub status: Vec<String>,
    /// [K]: wall time of each refined run
    pub wall_s: Vec<f64>,
    /// [K]: solver dt of the base and the refined run
    pub dt: Vec<[f64; 2]>,
    /// [K]: element count of the base and the refined mesh
    pub elements: Vec<[usize; 2]>,
    pub max_rel_diff: f64,
    pub warnings: Vec<String>,
    pub sensors: Vec<VerificationSensor>,
}

/// One sensor's verification figures, each [K, C] row-major.
#[derive(Clone, Debug, Default)]
pub struct VerificationSensor {
    pub name: String,
    pub components: Vec<String>,
    pub rel_diff: Vec<f64>,
    pub refined_min: Vec<f64>,
    pub refined_max: Vec<f64>,
}

/// Incremental writer of one campaign file. See the [module docs](self) for the layout
/// and the durability contract.
///
/// Holds plain data only (no open file between flushes), so it is `Send` and `Sync`.
pub struct CampaignWriter {
    path: PathBuf,
    tmp_path: PathBuf,
    target: OutputTarget,
    meta: CampaignMeta,
    n_variants: usize,
    n_time: usize,
    global_index: Vec<usize>,
    sensors: Vec<SensorBuf>,
    status: Vec<VariantStatus>,
    /// Insertion-ordered derived quantities, NaN where not set.
    derived: Vec<(String, Vec<f64>)>,
    pipeline: FilterPipeline,
    /// Something changed since the last successful flush.
    dirty: bool,
    /// `/verification`, once set
    verification: Option<VerificationData>,
    /// `/campaign` and the root attributes `campaign_id`, `campaign_hash` (sweeps)
    campaign: Option<crate::campaign::CampaignInfo>,
}

/// Whether `name` can name a sensor or derived quantity in every output format: an HDF5
/// link (`/sensors/<NAME>`: no '/', not empty; NUL would truncate the link and make
/// two sensors one), a CSV column `NAME.COMPONENT` (no ',', '"', '.', line breaks) and
/// the `NAME.COMPONENT` arguments of `sweep --frequency` and `plot`. The model compiler
/// calls this for sensor names, so `check` rejects what the writers could not write.
pub fn check_output_name(name: &str) -> Result<(), String> {
    if name.len() > MAX_NAME_BYTES {
        let head: String = name.chars().take(32).collect();
        return Err(format!(
            "name {head:?}… is {} bytes long and cannot be written to the output files: at \
             most {MAX_NAME_BYTES} bytes (HDF5 link names of 64 KiB and more cannot be read \
             back; 255 also keeps CSV columns and chart legends usable)",
            name.len()
        ));
    }
    let bad = if name.trim().is_empty() {
        Some("it is empty")
    } else if name.contains('/') {
        Some("it contains '/' (an HDF5 path separator)")
    } else if name.contains('.') {
        Some("it contains '.' (it separates a sensor from its component: NAME.COMPONENT)")
    } else if name.contains(',') || name.contains('"') {
        Some("it contains ',' or '\"' (CSV column names)")
    } else if name.chars().any(char::is_control) {
        Some("it contains a control character (NUL, tab, line break, ...)")
    } else if name.trim() != name {
        Some("it starts or ends with white space")
    } else {
        None
    };
    match bad {
        Some(why) => Err(format!(
            "name {name:?} cannot be written to the output files: {why}; use letters, \
             digits, '_' or '-'"
        )),
        None => Ok(()),
    }
}

fn check_name(kind: &str, name: &str) -> Result<(), OutputError> {
    check_output_name(name).map_err(|e| OutputError::Invalid(format!("{kind} {e}")))
}

impl CampaignWriter {
    /// Claim `path` ([`OutputTarget::claim`]: a regular file or nothing, no symlink, not
    /// locked by another process), validate `meta`, then write the initial file (all
    /// samples NaN, every variant pending, status "running"), replacing any file there.
    /// Fails at once with [`OutputError::Io`] if the path is refused or cannot be written.
    pub fn create(path: &Path, meta: &CampaignMeta) -> Result<Self, OutputError> {
        Self::create_at(OutputTarget::claim(path)?, meta)
    }

    /// [`create`](Self::create) on a path claimed earlier (before slow preparations).
    pub fn create_at(target: OutputTarget, meta: &CampaignMeta) -> Result<Self, OutputError> {
        Self::create_with(target, meta, None)
    }

    /// [`create_at`](Self::create_at) for a campaign with an identity (a sweep): the
    /// first file written already carries `campaign_id`, `campaign_hash` and `/campaign`.
    pub fn create_with(
        target: OutputTarget,
        meta: &CampaignMeta,
        campaign: Option<crate::campaign::CampaignInfo>,
    ) -> Result<Self, OutputError> {
        let mut w = Self::build(target, meta, campaign, true)?;
        w.flush()?;
        Ok(w)
    }

    /// The writer's state for `meta`, nothing written yet; without `samples`, no sensor
    /// sample is held in memory (a streamed file: [`write_streamed`](Self::write_streamed)).
    fn build(
        target: OutputTarget,
        meta: &CampaignMeta,
        campaign: Option<crate::campaign::CampaignInfo>,
        samples: bool,
    ) -> Result<Self, OutputError> {
        let n_variants = meta.parameter_values.len();
        let n_time = meta.time.len();
        for (v, row) in meta.parameter_values.iter().enumerate() {
            if row.len() != meta.parameter_names.len() {
                return Err(OutputError::Invalid(format!(
                    "variant {v} has {} parameter values, expected {} (parameter_names)",
                    row.len(),
                    meta.parameter_names.len()
                )));
            }
        }
        let global_index = if meta.global_index.is_empty() {
            (0..n_variants).collect()
        } else if meta.global_index.len() == n_variants {
            meta.global_index.clone()
        } else {
            return Err(OutputError::Invalid(format!(
                "global_index has {} entries for {n_variants} variants",
                meta.global_index.len()
            )));
        };
        let mut sensors = Vec::with_capacity(meta.sensors.len());
        for (i, s) in meta.sensors.iter().enumerate() {
            check_name("sensor", &s.name)?;
            if meta.sensors[..i].iter().any(|o| o.name == s.name) {
                return Err(OutputError::Invalid(format!(
                    "duplicate sensor name {:?}",
                    s.name
                )));
            }
            let n_comp = s.components.len();
            if n_comp == 0 {
                return Err(OutputError::Invalid(format!(
                    "sensor {:?} has no components",
                    s.name
                )));
            }
            if s.units.len() != n_comp {
                return Err(OutputError::Invalid(format!(
                    "sensor {:?} has {} components but {} units",
                    s.name,
                    n_comp,
                    s.units.len()
                )));
            }
            let chunk_t = chunk_times(n_comp, n_time);
            let chunks_t = n_time.div_ceil(chunk_t);
            let n_chunks = if samples { n_variants * chunks_t } else { 0 };
            let n_values = if samples {
                n_variants * n_time * n_comp
            } else {
                0
            };
            sensors.push(SensorBuf {
                meta: s.clone(),
                n_comp,
                chunk_t,
                chunks_t,
                data: vec![f64::NAN; n_values],
                compressed: vec![None; n_chunks],
                dirty: vec![false; n_chunks],
            });
        }
        let path = target.path().to_path_buf();
        let tmp_path = target.tmp_path();
        let w = CampaignWriter {
            path,
            tmp_path,
            target,
            meta: CampaignMeta {
                global_index: global_index.clone(),
                ..meta.clone()
            },
            n_variants,
            n_time,
            global_index,
            sensors,
            status: vec![VariantStatus::default(); n_variants],
            derived: Vec::new(),
            pipeline: FilterPipeline::shuffle_deflate(8, DEFLATE_LEVEL),
            dirty: true,
            verification: None,
            campaign,
        };
        Ok(w)
    }

    /// Reopen a campaign file to complete it (`sweep --resume`): the writer starts with
    /// `meta`, `status` and `derived` as given, and each sensor chunk (sensor index in
    /// `meta.sensors`, row, chunk index along time) as `chunk` returns it: the stored,
    /// filtered bytes, kept as they are (so the samples stay bit for bit), or `None` for a
    /// chunk that reads NaN (a row to be run again). Nothing is written until the next
    /// flush or finish.
    pub fn reopen(
        target: OutputTarget,
        meta: &CampaignMeta,
        campaign: Option<crate::campaign::CampaignInfo>,
        status: Vec<VariantStatus>,
        derived: Vec<(String, Vec<f64>)>,
        chunk: &mut dyn FnMut(usize, usize, usize) -> Result<Option<Vec<u8>>, OutputError>,
    ) -> Result<Self, OutputError> {
        let mut w = Self::build(target, meta, campaign, true)?;
        if status.len() != w.n_variants || derived.iter().any(|(_, d)| d.len() != w.n_variants) {
            return Err(OutputError::Invalid(format!(
                "reopen: status and derived need {} entries",
                w.n_variants
            )));
        }
        w.status = status;
        w.derived = derived;
        for (k, s) in w.sensors.iter_mut().enumerate() {
            for row in 0..w.n_variants {
                for ct in 0..s.chunks_t {
                    s.compressed[row * s.chunks_t + ct] = chunk(k, row, ct)?;
                }
            }
        }
        w.dirty = false;
        Ok(w)
    }

    /// Set the parameter values of `variant` (`sweep --resume`: a row a merge could not
    /// fill from a shard gets the values of the model it is run with).
    pub fn set_parameters(&mut self, variant: usize, values: &[f64]) -> Result<(), OutputError> {
        self.check_variant(variant)?;
        if values.len() != self.meta.parameter_names.len() {
            return Err(OutputError::Invalid(format!(
                "variant {variant}: {} parameter values for {} names",
                values.len(),
                self.meta.parameter_names.len()
            )));
        }
        self.meta.parameter_values[variant] = values.to_vec();
        self.dirty = true;
        Ok(())
    }

    /// Write a whole campaign file at `target` in one pass, its sensor samples coming from
    /// `fill` instead of memory: `fill` gets the `/sensors` datasets (in `meta.sensors`
    /// order, chunked [1, ≤T, C] as [`create`](Self::create) makes them) and writes
    /// their chunks (`write_chunk_raw_at`), so the memory is what `fill` holds (`merge`:
    /// one chunk), not the campaign. Everything else (status, derived, `/campaign`) is
    /// given here. The file appears at `target` atomically when complete.
    #[allow(clippy::too_many_arguments)]
    pub fn write_streamed(
        target: OutputTarget,
        meta: &CampaignMeta,
        campaign: Option<crate::campaign::CampaignInfo>,
        status: Vec<VariantStatus>,
        derived: Vec<(String, Vec<f64>)>,
        verification: Option<VerificationData>,
        file_status: &str,
        fill: &mut FillChunks<'_>,
    ) -> Result<(), OutputError> {
        let mut w = Self::build(target, meta, campaign, false)?;
        if status.len() != w.n_variants || derived.iter().any(|(_, d)| d.len() != w.n_variants) {
            return Err(OutputError::Invalid(format!(
                "write_streamed: status and derived need {} entries",
                w.n_variants
            )));
        }
        for (name, _) in &derived {
            check_name("derived", name)?;
        }
        w.status = status;
        w.derived = derived;
        if let Some(v) = &verification {
            w.set_verification(v)?;
        }
        w.write_file_with(file_status, Some(fill))
    }

    /// Variants (rows) of the file.
    pub fn n_variants(&self) -> usize {
        self.n_variants
    }

    /// Path of the campaign file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Store the samples of all sensors of `variant` at output time `t_index`:
    /// `values[s]` holds the components of sensor `s` in `CampaignMeta::sensors` order.
    pub fn write_samples(
        &mut self,
        variant: usize,
        t_index: usize,
        values: &[Vec<f64>],
    ) -> Result<(), OutputError> {
        self.check_variant(variant)?;
        if t_index >= self.n_time {
            return Err(OutputError::Invalid(format!(
                "time index {t_index} out of range (the grid has {} times)",
                self.n_time
            )));
        }
        if values.len() != self.sensors.len() {
            return Err(OutputError::Invalid(format!(
                "write_samples got {} sensors, the campaign has {}",
                values.len(),
                self.sensors.len()
            )));
        }
        for (s, v) in self.sensors.iter().zip(values) {
            if v.len() != s.n_comp {
                return Err(OutputError::Invalid(format!(
                    "sensor {:?} got {} values, it has {} components",
                    s.meta.name,
                    v.len(),
                    s.n_comp
                )));
            }
        }
        for (s, v) in self.sensors.iter_mut().zip(values) {
            let at = (variant * self.n_time + t_index) * s.n_comp;
            s.data[at..at + s.n_comp].copy_from_slice(v);
            s.dirty[variant * s.chunks_t + t_index / s.chunk_t] = true;
        }
        self.dirty = true;
        Ok(())
    }

    /// Set the status of `variant` (state, message, failure time, step counts, wall time).
    pub fn set_status(&mut self, variant: usize, st: &VariantStatus) -> Result<(), OutputError> {
        self.check_variant(variant)?;
        self.status[variant] = st.clone();
        self.dirty = true;
        Ok(())
    }

    /// Record the mesh check of `variant` after its run: `/status/mesh_error_estimate`
    /// (NaN: not measured) and, where it warns, one more line of `/status/warnings`.
    pub fn set_mesh_check(
        &mut self,
        variant: usize,
        estimate: Option<f64>,
        warning: Option<&str>,
    ) -> Result<(), OutputError> {
        self.check_variant(variant)?;
        let st = &mut self.status[variant];
        st.mesh_error_estimate = estimate.unwrap_or(f64::NAN);
        if let Some(w) = warning {
            if !st.warnings.is_empty() {
                st.warnings.push('\n');
            }
            st.warnings.push_str(w);
        }
        self.dirty = true;
        Ok(())
    }

    /// Set `/derived/<name>` of `variant` (the dataset appears at the first call for a
    /// name, NaN for the other variants).
    pub fn set_derived(
        &mut self,
        name: &str,
        variant: usize,
        value: f64,
    ) -> Result<(), OutputError> {
        self.check_variant(variant)?;
        check_name("derived", name)?;
        let n = self.n_variants;
        let column = match self.derived.iter().position(|(d, _)| d == name) {
            Some(i) => &mut self.derived[i].1,
            None => {
                self.derived.push((name.to_string(), vec![f64::NAN; n]));
                &mut self.derived.last_mut().expect("just pushed").1
            }
        };
        column[variant] = value;
        self.dirty = true;
        Ok(())
    }

    /// Set `/verification` (written at the next flush or finish).
    pub fn set_verification(&mut self, v: &VerificationData) -> Result<(), OutputError> {
        for x in &v.sensors {
            check_name("sensor", &x.name)?;
            let kc = v.variants.len() * x.components.len();
            if [&x.rel_diff, &x.refined_min, &x.refined_max]
                .iter()
                .any(|a| a.len() != kc)
            {
                return Err(OutputError::Invalid(format!(
                    "verification of sensor {:?}: expected {kc} values per figure",
                    x.name
                )));
            }
        }
        let k = v.variants.len();
        if [v.status.len(), v.wall_s.len(), v.dt.len(), v.elements.len()]
            .iter()
            .any(|&n| n != k)
        {
            return Err(OutputError::Invalid(
                "verification: one status, wall time, dt and element count per variant".into(),
            ));
        }
        self.verification = Some(v.clone());
        self.dirty = true;
        Ok(())
    }

    /// Make everything written so far durable: rewrite the file (temporary file,
    /// `fsync`, atomic rename). The root `status` is "interrupted" if any variant is in
    /// state Interrupted, else "running"; `complete` is 0. A no-op if nothing changed.
    pub fn flush(&mut self) -> Result<(), OutputError> {
        if !self.dirty {
            return Ok(());
        }
        let status = if self
            .status
            .iter()
            .any(|s| s.state == VariantState::Interrupted)
        {
            "interrupted"
        } else {
            "running"
        };
        self.write_file(status)?;
        self.dirty = false;
        Ok(())
    }

    /// Write the final file with root `status` = `status` ("complete" → `complete` = 1,
    /// or "interrupted"). Any other status is an error, but the file is still written
    /// (as "interrupted") so no data is lost.
    pub fn finish(mut self, status: &str) -> Result<(), OutputError> {
        match status {
            "complete" | "interrupted" => self.write_file(status),
            other => {
                self.write_file("interrupted")?;
                Err(OutputError::Invalid(format!(
                    "finish status must be \"complete\" or \"interrupted\", got {other:?} \
                     (file written as \"interrupted\")"
                )))
            }
        }
    }

    fn check_variant(&self, variant: usize) -> Result<(), OutputError> {
        if variant >= self.n_variants {
            return Err(OutputError::Invalid(format!(
                "variant {variant} out of range (the file has {} variants)",
                self.n_variants
            )));
        }
        Ok(())
    }

    /// Compress the chunks written since the last flush.
    fn compress_dirty(&mut self) -> Result<(), OutputError> {
        let n_time = self.n_time;
        for s in &mut self.sensors {
            let chunk_len = s.chunk_t * s.n_comp;
            let mut raw = Vec::with_capacity(chunk_len * 8);
            for (k, dirty) in s.dirty.iter_mut().enumerate() {
                if !*dirty {
                    continue;
                }
                let (v, ct) = (k / s.chunks_t, k % s.chunks_t);
                let t0 = ct * s.chunk_t;
                let t1 = (t0 + s.chunk_t).min(n_time);
                let from = (v * n_time + t0) * s.n_comp;
                let to = (v * n_time + t1) * s.n_comp;
                raw.clear();
                for x in &s.data[from..to] {
                    raw.extend_from_slice(&x.to_le_bytes());
                }
                // The last chunk along time hangs past the extent: pad it with NaN.
                for _ in (to - from)..chunk_len {
                    raw.extend_from_slice(&f64::NAN.to_le_bytes());
                }
                let bytes = apply_filters(&self.pipeline, &raw).map_err(|e| OutputError::Hdf5 {
                    path: self.path.clone(),
                    what: format!("compressing /sensors/{}", s.meta.name),
                    message: e.to_string(),
                })?;
                s.compressed[k] = Some(bytes);
                *dirty = false;
            }
        }
        Ok(())
    }

    fn write_file(&mut self, status: &str) -> Result<(), OutputError> {
        self.write_file_with(status, None)
    }

    fn write_file_with(
        &mut self,
        status: &str,
        fill: Option<&mut FillChunks<'_>>,
    ) -> Result<(), OutputError> {
        self.compress_dirty()?;
        let io_err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| OutputError::Io { path, source }
        };
        // Probe with std first: a plain io::Error is the clearest message for a missing
        // directory, a full disk or a permission problem.
        let _ = fs::remove_file(&self.tmp_path);
        fs::File::create_new(&self.tmp_path).map_err(io_err(&self.path))?;
        let result = self.write_hdf5(status, fill);
        if let Err(e) = result {
            let _ = fs::remove_file(&self.tmp_path);
            return Err(e);
        }
        self.target.commit(&self.tmp_path)
    }

    /// Write the whole file to the temporary path (closed and synced on return).
    fn write_hdf5(
        &self,
        status: &str,
        fill: Option<&mut FillChunks<'_>>,
    ) -> Result<(), OutputError> {
        let tmp = self.tmp_path.clone();
        let h5 = |what: &str| -> Box<dyn Fn(rust_hdf5::Hdf5Error) -> OutputError> {
            let what = what.to_string();
            let path = tmp.clone();
            Box::new(move |e: rust_hdf5::Hdf5Error| OutputError::Hdf5 {
                path: path.clone(),
                what: what.clone(),
                message: e.to_string(),
            })
        };
        let file = H5File::options()
            .best_effort_locking()
            .create(&tmp)
            .map_err(h5("create"))?;
        match self.write_objects(&file, status, &h5, fill) {
            Ok(()) => file.close().map_err(h5("close")),
            Err(e) => {
                // closed explicitly: dropping it would print rust-hdf5's own warning
                // about a file that is removed anyway
                let _ = file.close();
                Err(e)
            }
        }
    }

    /// Every object of the file (see the layout in the module docs).
    fn write_objects<E>(
        &self,
        file: &H5File,
        status: &str,
        h5: &E,
        fill: Option<&mut FillChunks<'_>>,
    ) -> Result<(), OutputError>
    where
        E: Fn(&str) -> Box<dyn Fn(rust_hdf5::Hdf5Error) -> OutputError>,
    {
        let m = &self.meta;
        let nv = self.n_variants;

        // Root attributes.
        file.set_attr_string(attr::LATDYN_VERSION, env!("CARGO_PKG_VERSION"))
            .map_err(h5("root attrs"))?;
        file.set_attr_string(attr::COMMAND_LINE, &m.command_line)
            .map_err(h5("root attrs"))?;
        file.set_attr_string(attr::BACKEND, &m.backend)
            .map_err(h5("root attrs"))?;
        file.set_attr_string(attr::PRECISION, &m.precision)
            .map_err(h5("root attrs"))?;
        file.set_attr_string(attr::ADAPTER, &m.adapter)
            .map_err(h5("root attrs"))?;
        file.set_attr_numeric(attr::THREADS, &(m.threads as i64))
            .map_err(h5("root attrs"))?;
        file.set_attr_numeric(attr::COMPLETE, &i64::from(status == "complete"))
            .map_err(h5("root attrs"))?;
        file.set_attr_string(attr::STATUS, status)
            .map_err(h5("root attrs"))?;
        let failed = self
            .status
            .iter()
            .filter(|s| s.state == VariantState::Failed)
            .count();
        file.set_attr_numeric(attr::FAILED_VARIANTS, &(failed as i64))
            .map_err(h5("root attrs"))?;
        file.set_attr_string(attr::FORMAT, layout::FORMAT)
            .map_err(h5("root attrs"))?;
        file.set_attr_numeric(attr::FORMAT_VERSION, &FORMAT_VERSION)
            .map_err(h5("root attrs"))?;

        // /model
        let model = file
            .create_group(layout::MODEL)
            .map_err(h5(&slash(layout::MODEL)))?;
        write_scalar_string(&model, leaf(layout::MODEL_SOURCE), &m.model_source)
            .map_err(h5(&slash(layout::MODEL_SOURCE)))?;
        write_scalar_string(&model, leaf(layout::MODEL_PATH), &m.model_path)
            .map_err(h5(&slash(layout::MODEL_PATH)))?;

        // /parameters
        let params = file
            .create_group(layout::PARAMETERS)
            .map_err(h5(&slash(layout::PARAMETERS)))?;
        let names: Vec<&str> = m.parameter_names.iter().map(String::as_str).collect();
        write_strings(&params, leaf(layout::PARAMETER_NAMES), &names)
            .map_err(h5(&slash(layout::PARAMETER_NAMES)))?;
        let values: Vec<f64> = m.parameter_values.iter().flatten().copied().collect();
        write_f64(
            &params,
            leaf(layout::PARAMETER_VALUES),
            &[nv, names.len()],
            &values,
        )
        .map_err(h5(&slash(layout::PARAMETER_VALUES)))?;

        // /time
        let time = file
            .new_dataset::<f64>()
            .shape([self.n_time])
            .create(layout::TIME)
            .map_err(h5(&slash(layout::TIME)))?;
        if self.n_time > 0 {
            time.write_raw(&m.time).map_err(h5(&slash(layout::TIME)))?;
        }
        set_ds_string_attr(&time, attr::UNITS, "s").map_err(h5(&slash(layout::TIME)))?;

        // /sensors
        let sensors = file
            .create_group(layout::SENSORS)
            .map_err(h5(&slash(layout::SENSORS)))?;
        let mut datasets = Vec::with_capacity(self.sensors.len());
        for s in &self.sensors {
            let what = slash(&layout::sensor(&s.meta.name));
            let shape = [nv, self.n_time, s.n_comp];
            let b = sensors
                .new_dataset::<f64>()
                .shape(shape)
                .fill_value(f64::NAN);
            let ds = if nv == 0 || self.n_time == 0 {
                b.create(&s.meta.name).map_err(h5(&what))?
            } else {
                let ds = b
                    .chunk(&[1, s.chunk_t, s.n_comp])
                    .filter_pipeline(self.pipeline.clone())
                    .create(&s.meta.name)
                    .map_err(h5(&what))?;
                for (k, bytes) in s.compressed.iter().enumerate() {
                    if let Some(bytes) = bytes {
                        let coords = [k / s.chunks_t, k % s.chunks_t, 0];
                        ds.write_chunk_raw_at(&coords, bytes, 0)
                            .map_err(h5(&what))?;
                    }
                }
                ds
            };
            let comps: Vec<&str> = s.meta.components.iter().map(String::as_str).collect();
            let units: Vec<&str> = s.meta.units.iter().map(String::as_str).collect();
            set_ds_string_array_attr(&ds, attr::COMPONENTS, &comps).map_err(h5(&what))?;
            set_ds_string_array_attr(&ds, attr::UNITS, &units).map_err(h5(&what))?;
            datasets.push(ds);
        }
        if let Some(fill) = fill {
            if nv > 0 && self.n_time > 0 {
                fill(&datasets)?;
            }
        }

        // /status
        let st = file
            .create_group(layout::STATUS)
            .map_err(h5(&slash(layout::STATUS)))?;
        let codes: Vec<i32> = self.status.iter().map(|s| s.state.code()).collect();
        let state = st
            .new_dataset::<i32>()
            .shape([nv])
            .create(leaf(layout::STATE))
            .map_err(h5(&slash(layout::STATE)))?;
        if nv > 0 {
            state.write_raw(&codes).map_err(h5(&slash(layout::STATE)))?;
        }
        let labels: Vec<&str> = VariantState::ALL.iter().map(|s| s.label()).collect();
        set_ds_string_array_attr(&state, attr::LABELS, &labels)
            .map_err(h5(&slash(layout::STATE)))?;
        let messages: Vec<&str> = self.status.iter().map(|s| s.message.as_str()).collect();
        write_strings(&st, leaf(layout::MESSAGE), &messages)
            .map_err(h5(&slash(layout::MESSAGE)))?;
        type Column = fn(&VariantStatus) -> f64;
        let f64_columns: [(&str, Column); 7] = [
            (layout::T_FAIL, |s| s.t_fail),
            (layout::WALL_S, |s| s.wall_s),
            (layout::ENERGY_GROWTH, |s| s.energy_growth),
            (layout::ENERGY_LOSS, |s| s.energy_loss),
            (layout::TIME_ERROR_ESTIMATE, |s| s.time_error_estimate),
            (layout::TIME_ERROR_BEFORE_FIRST_LOCK, |s| {
                s.time_error_before_first_lock
            }),
            (layout::MESH_ERROR_ESTIMATE, |s| s.mesh_error_estimate),
        ];
        for (name, f) in f64_columns {
            let values: Vec<f64> = self.status.iter().map(f).collect();
            write_f64(&st, leaf(name), &[nv], &values).map_err(h5(&slash(name)))?;
        }
        let warnings: Vec<&str> = self.status.iter().map(|s| s.warnings.as_str()).collect();
        write_strings(&st, leaf(layout::WARNINGS), &warnings)
            .map_err(h5(&slash(layout::WARNINGS)))?;
        let icol = |f: fn(&VariantStatus) -> u64| {
            self.status
                .iter()
                .map(|s| i64::try_from(f(s)).unwrap_or(i64::MAX))
                .collect::<Vec<_>>()
        };
        write_i64(&st, leaf(layout::STEPS), &icol(|s| s.steps))
            .map_err(h5(&slash(layout::STEPS)))?;
        write_i64(
            &st,
            leaf(layout::REJECTED_STEPS),
            &icol(|s| s.rejected_steps),
        )
        .map_err(h5(&slash(layout::REJECTED_STEPS)))?;
        let gi: Vec<i64> = self
            .global_index
            .iter()
            .map(|&g| i64::try_from(g).unwrap_or(i64::MAX))
            .collect();
        write_i64(&st, leaf(layout::GLOBAL_INDEX), &gi)
            .map_err(h5(&slash(layout::GLOBAL_INDEX)))?;

        // /derived
        let derived = file
            .create_group(layout::DERIVED)
            .map_err(h5(&slash(layout::DERIVED)))?;
        for (name, values) in &self.derived {
            write_f64(&derived, name, &[nv], values).map_err(h5(&slash(&layout::derived(name))))?;
        }

        if let Some(v) = &self.verification {
            write_verification(file, v, h5)?;
        }

        if let Some(c) = &self.campaign {
            write_campaign(file, c, h5)?;
            if nv > 0 && self.n_time > 0 {
                self.write_xarray(file, c, &datasets, h5)?;
            }
        }

        Ok(())
    }

    /// `/xarray` (see the layout in the module docs): netCDF-4 dimension scales, so
    /// `xarray.open_dataset(path, engine="h5netcdf", group="xarray")` names every axis.
    /// The sensors, derived quantities and states are hard links to the datasets above
    /// (no copy); attaching the scales adds `DIMENSION_LIST` to them, which h5py readers
    /// ignore.
    fn write_xarray<E>(
        &self,
        file: &H5File,
        c: &crate::campaign::CampaignInfo,
        sensors: &[rust_hdf5::H5Dataset],
        h5: &E,
    ) -> Result<(), OutputError>
    where
        E: Fn(&str) -> Box<dyn Fn(rust_hdf5::Hdf5Error) -> OutputError>,
    {
        let e = |what: &str| h5(&format!("/xarray{what}"));
        let m = &self.meta;
        let g = file.create_group(layout::XARRAY).map_err(e(""))?;
        // one name space in the group: the first use of a name wins (a parameter named
        // like a sensor keeps its value in /parameters only)
        let mut used: Vec<String> = vec!["variant".into(), "time".into()];
        let gi: Vec<i64> = self
            .global_index
            .iter()
            .map(|&x| i64::try_from(x).unwrap_or(i64::MAX))
            .collect();
        // the variant axis is named after the one varied parameter when its values order
        // the whole campaign strictly (a `--vary` range), so `sel(omega=..., method=
        // "nearest")` works as it stands; otherwise it is `variant`
        let axis = xarray_axis(c, &m.parameter_names).filter(|(name, _)| !used.contains(name));
        let variant = g
            .new_dataset::<i64>()
            .shape([gi.len()])
            .create("variant")
            .map_err(e("/variant"))?;
        variant.write_raw(&gi).map_err(e("/variant"))?;
        set_ds_string_attr(
            &variant,
            "long_name",
            "global index of the variant in the campaign",
        )
        .map_err(e("/variant"))?;
        let mut coords = Vec::new();
        let axis_ds = match &axis {
            None => {
                variant.set_scale(Some("variant")).map_err(e("/variant"))?;
                variant
            }
            Some((name, k)) => {
                let what = format!("/{name}");
                let col: Vec<f64> = m.parameter_values.iter().map(|row| row[*k]).collect();
                let ds = g
                    .new_dataset::<f64>()
                    .shape([col.len()])
                    .create(name)
                    .map_err(e(&what))?;
                ds.write_raw(&col).map_err(e(&what))?;
                ds.set_scale(Some(name)).map_err(e(&what))?;
                variant.attach_scale(0, &ds).map_err(e("/variant"))?;
                used.push(name.clone());
                coords.push("variant");
                ds
            }
        };
        let variant = axis_ds;
        let time = g
            .new_dataset::<f64>()
            .shape([self.n_time])
            .create("time")
            .map_err(e("/time"))?;
        time.write_raw(&m.time).map_err(e("/time"))?;
        time.set_scale(Some("time")).map_err(e("/time"))?;
        set_ds_string_attr(&time, "units", "s").map_err(e("/time"))?;
        for name in &c.varied {
            let Some(k) = m.parameter_names.iter().position(|p| p == name) else {
                continue;
            };
            if used.contains(name) {
                continue;
            }
            let what = format!("/{name}");
            let col: Vec<f64> = m.parameter_values.iter().map(|row| row[k]).collect();
            let ds = g
                .new_dataset::<f64>()
                .shape([col.len()])
                .create(name)
                .map_err(e(&what))?;
            ds.write_raw(&col).map_err(e(&what))?;
            ds.attach_scale(0, &variant).map_err(e(&what))?;
            used.push(name.clone());
            coords.push(name.as_str());
        }
        let coords = coords.join(" ");
        for (s, ds) in self.sensors.iter().zip(sensors) {
            let name = &s.meta.name;
            let dim = format!("{name}_component");
            if used.contains(name) || used.contains(&dim) {
                continue;
            }
            let what = format!("/{name}");
            let comps: Vec<&str> = s.meta.components.iter().map(String::as_str).collect();
            let cds = g.write_vlen_strings(&dim, &comps).map_err(e(&what))?;
            cds.set_scale(Some(&dim)).map_err(e(&what))?;
            g.link(name, &slash(&layout::sensor(name)))
                .map_err(e(&what))?;
            ds.attach_scale(0, &variant).map_err(e(&what))?;
            ds.attach_scale(1, &time).map_err(e(&what))?;
            ds.attach_scale(2, &cds).map_err(e(&what))?;
            if !coords.is_empty() {
                set_ds_string_attr(ds, "coordinates", &coords).map_err(e(&what))?;
            }
            used.push(name.clone());
            used.push(dim);
        }
        let mut per_variant: Vec<(String, String)> = self
            .derived
            .iter()
            .map(|(n, _)| (n.clone(), slash(&layout::derived(n))))
            .collect();
        per_variant.push((leaf(layout::STATE).into(), slash(layout::STATE)));
        for (name, path) in per_variant {
            if used.contains(&name) {
                continue;
            }
            let what = format!("/{name}");
            let ds = file.dataset_writer(&path[1..]).map_err(e(&what))?;
            g.link(&name, &path).map_err(e(&what))?;
            ds.attach_scale(0, &variant).map_err(e(&what))?;
            if !coords.is_empty() {
                set_ds_string_attr(&ds, "coordinates", &coords).map_err(e(&what))?;
            }
            used.push(name);
        }
        Ok(())
    }
}

/// The parameter that names the variant axis of `/xarray`, with its column in
/// `/parameters/values`: the campaign's only varied parameter when its values, in global
/// index order, are finite and strictly monotonic (a `--vary` range, or a one-column
/// `--variants` table in order), so it is a valid xarray index in every shard and in the
/// merged file alike (a subset of a strictly monotonic sequence is one). None otherwise:
/// the axis is `variant`.
pub fn xarray_axis(
    c: &crate::campaign::CampaignInfo,
    parameter_names: &[String],
) -> Option<(String, usize)> {
    let [name] = c.varied.as_slice() else {
        return None;
    };
    let k = parameter_names.iter().position(|p| p == name)?;
    let col: Vec<f64> = c
        .variants
        .iter()
        .filter_map(|r| r.first().copied())
        .collect();
    if col.len() != c.variants.len() || col.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let up = col.windows(2).all(|w| w[0] < w[1]);
    let down = col.windows(2).all(|w| w[0] > w[1]);
    (up || down).then(|| (name.clone(), k))
}

/// `/` + a layout path: the name in error messages.
fn slash(path: &str) -> String {
    format!("/{path}")
}

/// `campaign_id`, `campaign_hash` and `/campaign` (see the layout in the module docs).
fn write_campaign<E>(
    file: &H5File,
    c: &crate::campaign::CampaignInfo,
    h5: &E,
) -> Result<(), OutputError>
where
    E: Fn(&str) -> Box<dyn Fn(rust_hdf5::Hdf5Error) -> OutputError>,
{
    file.set_attr_string(attr::CAMPAIGN_ID, &c.id)
        .map_err(h5("root attrs"))?;
    file.set_attr_string(attr::CAMPAIGN_HASH, &c.hash)
        .map_err(h5("root attrs"))?;
    let g = file
        .create_group(layout::CAMPAIGN)
        .map_err(h5(&slash(layout::CAMPAIGN)))?;
    write_scalar_string(&g, leaf(layout::DEFINITION), &c.definition)
        .map_err(h5(&slash(layout::DEFINITION)))?;
    let varied: Vec<&str> = c.varied.iter().map(String::as_str).collect();
    write_strings(&g, leaf(layout::VARIED), &varied).map_err(h5(&slash(layout::VARIED)))?;
    let values: Vec<f64> = c.variants.iter().flatten().copied().collect();
    write_f64(
        &g,
        leaf(layout::VARIANTS),
        &[c.variants.len(), varied.len()],
        &values,
    )
    .map_err(h5(&slash(layout::VARIANTS)))?;
    let names: Vec<&str> = c.set.iter().map(|(n, _)| n.as_str()).collect();
    write_strings(&g, leaf(layout::SET_NAMES), &names).map_err(h5(&slash(layout::SET_NAMES)))?;
    let values: Vec<f64> = c.set.iter().map(|(_, x)| *x).collect();
    write_f64(&g, leaf(layout::SET_VALUES), &[values.len()], &values)
        .map_err(h5(&slash(layout::SET_VALUES)))?;
    Ok(())
}

/// `/verification` (see the layout in the module docs).
fn write_verification<E>(file: &H5File, v: &VerificationData, h5: &E) -> Result<(), OutputError>
where
    E: Fn(&str) -> Box<dyn Fn(rust_hdf5::Hdf5Error) -> OutputError>,
{
    let e = |what: &str| h5(&format!("/verification{what}"));
    let g = file.create_group(layout::VERIFICATION).map_err(e(""))?;
    let scalar = |name: &str, x: f64| -> H5Result<()> {
        g.new_dataset::<f64>()
            .scalar()
            .create(name)?
            .write_raw(&[x])
    };
    scalar("target", v.target).map_err(e("/target"))?;
    write_scalar_string(&g, "target_source", &v.target_source).map_err(e("/target_source"))?;
    let k = v.variants.len();
    let idx: Vec<i64> = v
        .variants
        .iter()
        .map(|&i| i64::try_from(i).unwrap_or(i64::MAX))
        .collect();
    write_i64(&g, "variants", &idx).map_err(e("/variants"))?;
    let status: Vec<&str> = v.status.iter().map(String::as_str).collect();
    write_strings(&g, "status", &status).map_err(e("/status"))?;
    write_f64(&g, "wall_s", &[k], &v.wall_s).map_err(e("/wall_s"))?;
    let dt: Vec<f64> = v.dt.iter().flatten().copied().collect();
    write_f64(&g, "dt", &[k, 2], &dt).map_err(e("/dt"))?;
    let elements: Vec<i64> = v
        .elements
        .iter()
        .flatten()
        .map(|&n| i64::try_from(n).unwrap_or(i64::MAX))
        .collect();
    let ds = g
        .new_dataset::<i64>()
        .shape([k, 2])
        .create("elements")
        .map_err(e("/elements"))?;
    if k > 0 {
        ds.write_raw(&elements).map_err(e("/elements"))?;
    }
    scalar("max_rel_diff", v.max_rel_diff).map_err(e("/max_rel_diff"))?;
    let warnings: Vec<&str> = v.warnings.iter().map(String::as_str).collect();
    write_strings(&g, "warnings", &warnings).map_err(e("/warnings"))?;
    type Figure = fn(&VerificationSensor) -> &Vec<f64>;
    let figures: [(&str, Figure); 3] = [
        ("rel_diff", |x| &x.rel_diff),
        ("refined_min", |x| &x.refined_min),
        ("refined_max", |x| &x.refined_max),
    ];
    for (group, get) in figures {
        let sub = g.create_group(group).map_err(e(&format!("/{group}")))?;
        for x in &v.sensors {
            let what = format!("/{group}/{}", x.name);
            let nc = x.components.len();
            let ds = sub
                .new_dataset::<f64>()
                .shape([k, nc])
                .create(&x.name)
                .map_err(e(&what))?;
            if k * nc > 0 {
                ds.write_raw(get(x)).map_err(e(&what))?;
            }
            let comps: Vec<&str> = x.components.iter().map(String::as_str).collect();
            set_ds_string_array_attr(&ds, attr::COMPONENTS, &comps).map_err(e(&what))?;
        }
    }
    Ok(())
}

type H5Result<T> = Result<T, rust_hdf5::Hdf5Error>;

/// A scalar fixed-length UTF-8 string dataset (h5py: `ds[()].decode()` or
/// `ds.asstr()[()]`).
fn write_scalar_string(g: &H5Group, name: &str, value: &str) -> H5Result<()> {
    let mut bytes = value.as_bytes().to_vec();
    if bytes.is_empty() {
        bytes.push(0); // HDF5 strings are at least one byte; null padding reads as ""
    }
    let ds = g
        .new_dataset::<u8>()
        .datatype(DatatypeMessage::FixedString {
            size: u32::try_from(bytes.len()).unwrap_or(u32::MAX),
            padding: 1, // null pad
            charset: 1, // UTF-8
        })
        .scalar()
        .create(name)?;
    ds.write_raw_bytes(&bytes)
}

/// A 1-D variable-length UTF-8 string dataset. An empty list gets a dataset without
/// storage: `write_vlen_strings` would give it a zero-byte data block, which the HDF5
/// library (h5py) refuses to open ("invalid dataset size").
fn write_strings(g: &H5Group, name: &str, values: &[&str]) -> H5Result<()> {
    if values.is_empty() {
        g.new_dataset::<u8>()
            .datatype(DatatypeMessage::VarLenString {
                padding: 0,
                charset: 1, // UTF-8
            })
            .shape([0usize])
            .create(name)?;
        return Ok(());
    }
    g.write_vlen_strings(name, values).map(|_| ())
}

fn write_f64(g: &H5Group, name: &str, shape: &[usize], values: &[f64]) -> H5Result<()> {
    let ds = g.new_dataset::<f64>().shape(shape).create(name)?;
    if !values.is_empty() {
        ds.write_raw(values)?;
    }
    Ok(())
}

fn write_i64(g: &H5Group, name: &str, values: &[i64]) -> H5Result<()> {
    let ds = g.new_dataset::<i64>().shape([values.len()]).create(name)?;
    if !values.is_empty() {
        ds.write_raw(values)?;
    }
    Ok(())
}

fn set_ds_string_attr(ds: &rust_hdf5::H5Dataset, name: &str, value: &str) -> H5Result<()> {
    ds.new_attr::<rust_hdf5::VarLenUnicode>()
        .shape(())
        .create(name)?
        .write_string(value)
}

fn set_ds_string_array_attr(
    ds: &rust_hdf5::H5Dataset,
    name: &str,
    values: &[&str],
) -> H5Result<()> {
    ds.new_attr::<rust_hdf5::VarLenUnicode>()
        .shape([values.len()])
        .create(name)?
        .write_string_array(values)
}
