//! Charts of a campaign results file (the HDF5 layout of [`crate::output`]) as SVG or
//! PNG, for the `plot` verb.
//!
//! Three kinds of chart:
//! - time histories of sensor components ([`plot_sensors`]), one line per variant;
//! - one sensor component against another ([`plot_phase`]): phase or cross plots;
//! - a Campbell diagram ([`plot_campbell`]): a derived frequency of each variant against
//!   a parameter (rotor speed Ω in rad/s), with the rotor harmonics n·Ω, an optional
//!   Southwell curve and the crossings of the data with the harmonics
//!   ([`latdyn::frequency::campbell_crossings`]).
//!
//! Drawing uses `plotters` with the DejaVu Sans font embedded in the binary (registered
//! with plotters' `ab_glyph` text renderer), so PNG text is the same on every machine and
//! no system font library is needed. The image format follows the output extension.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Once;

use latdyn::frequency::campbell_crossings;
use latdyn::output::layout::{self, Reader};
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

/// Most lines drawn in one time-history or cross plot: beyond this a legend is unreadable.
pub const MAX_LINES: usize = 20;

/// Errors of the plot module: the file, a selection, or the drawing.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The results file cannot be read, or lacks something asked for.
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    /// An invalid request (option values, image format).
    #[error("{0}")]
    Invalid(String),
    /// The data cannot be drawn (nothing finite, values beyond what an axis can span);
    /// the caller names the file.
    #[error("{0}")]
    Data(String),
    /// Drawing or writing the image failed.
    #[error("{}: {message}", path.display())]
    Draw { path: PathBuf, message: String },
}

/// Image format, from the output file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Svg,
    Png,
}

impl ImageFormat {
    /// `.svg` or `.png` (any case); anything else is an error.
    pub fn from_path(path: &Path) -> Result<Self, PlotError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("svg") => Ok(ImageFormat::Svg),
            Some("png") => Ok(ImageFormat::Png),
            _ => Err(PlotError::Invalid(format!(
                "{}: unknown image format: the output file must end in .svg or .png",
                path.display()
            ))),
        }
    }
}

/// Options common to every chart.
#[derive(Clone, Debug)]
pub struct PlotOptions {
    /// Chart title; `None` = the model path stored in the file (or the file name).
    pub title: Option<String>,
    /// Image size in pixels (SVG: user units).
    pub size: (u32, u32),
    /// Variants (row indices of the file) to plot; `None` = all.
    pub variants: Option<Vec<usize>>,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            title: None,
            size: (1000, 640),
            variants: None,
        }
    }
}

/// What a chart shows, for the caller to report.
#[derive(Clone, Debug, Default)]
pub struct PlotSummary {
    /// Legend labels of the lines drawn.
    pub lines: Vec<String>,
    /// Remarks for the user (variants left out, missing samples).
    pub notes: Vec<String>,
}

/// A Campbell diagram's result: the summary plus the crossings.
#[derive(Clone, Debug, Default)]
pub struct CampbellSummary {
    pub summary: PlotSummary,
    /// (harmonic n, rotor speed Ω in the parameter's units) of each crossing.
    pub crossings: Vec<(usize, f64)>,
    /// (branch number from 1, harmonic n, Ω) where an eigenvalue branch crosses n·Ω;
    /// a branch that lies on n·Ω itself (a rigid flap mode at exactly Ω) is not counted.
    pub branch_crossings: Vec<(usize, usize, f64)>,
}

/// Units of the Campbell diagram's frequency axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FreqUnits {
    /// rad/s: y = 2π·f.
    RadPerS,
    /// Hz: y = f.
    Hz,
}

impl FreqUnits {
    /// `rad` (also `rad/s`) or `hz`.
    pub fn parse(s: &str) -> Result<Self, PlotError> {
        match s.to_ascii_lowercase().as_str() {
            "rad" | "rad/s" | "rads" => Ok(FreqUnits::RadPerS),
            "hz" => Ok(FreqUnits::Hz),
            _ => Err(PlotError::Invalid(format!(
                "--units {s:?}: expected hz or rad"
            ))),
        }
    }

    fn label(self) -> &'static str {
        match self {
            FreqUnits::RadPerS => "rad/s",
            FreqUnits::Hz => "Hz",
        }
    }

    /// Factor from rad/s to these units.
    fn per_rad_s(self) -> f64 {
        match self {
            FreqUnits::RadPerS => 1.0,
            FreqUnits::Hz => 1.0 / std::f64::consts::TAU,
        }
    }
}

/// What a Campbell diagram plots.
#[derive(Clone, Debug)]
pub struct CampbellSpec {
    /// Parameter on the x axis: the rotor speed Ω in rad/s.
    pub parameter: String,
    /// `/derived/<NAME>`: a frequency in Hz per variant.
    pub derived: String,
    pub units: FreqUnits,
    /// Southwell curve y = sqrt(W0² + K·Ω²), W0 in the y axis units, K dimensionless
    /// (Ω converted to the y units first).
    pub southwell: Option<(f64, f64)>,
    /// Highest rotor harmonic n drawn (n·Ω for n = 1..=harmonics).
    pub harmonics: usize,
    /// Eigenvalue branches drawn beside the data (`latdyn modes --vary --json`).
    pub branches: Vec<EigenBranch>,
}

/// One mode followed across rotor speeds by `latdyn modes --vary`: Ω [rad/s] and the
/// rotating-frame frequency [Hz] at each speed (NaN where it was not matched).
#[derive(Clone, Debug)]
pub struct EigenBranch {
    pub label: String,
    pub omega: Vec<f64>,
    pub frequencies_hz: Vec<f64>,
}

/// Read the branches of a `latdyn modes MODEL --vary omega=A:B:N --json` output file.
pub fn read_branches(path: &Path) -> Result<Vec<EigenBranch>, PlotError> {
    let err = |message: String| PlotError::File {
        path: path.to_path_buf(),
        message,
    };
    let text = fs::read_to_string(path).map_err(|e| err(format!("reading: {e}")))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
        err(format!(
            "not JSON ({e}); expected the output of `latdyn modes --vary ... --json`"
        ))
    })?;
    let nums = |x: &serde_json::Value| -> Option<Vec<f64>> {
        x.as_array()
            .map(|a| a.iter().map(|y| y.as_f64().unwrap_or(f64::NAN)).collect())
    };
    let omega = v.get("omega_rad_s").and_then(nums).ok_or_else(|| {
        err(
            "no `omega_rad_s` array: expected the output of `latdyn modes --vary ... --json`"
                .into(),
        )
    })?;
    let list = v
        .get("branches")
        .and_then(|b| b.as_array())
        .ok_or_else(|| {
            err(
                "no `branches` array: expected the output of `latdyn modes --vary ... --json`"
                    .into(),
            )
        })?;
    let mut out = Vec::new();
    for (k, b) in list.iter().enumerate() {
        let f = b
            .get("frequencies_hz")
            .and_then(nums)
            .ok_or_else(|| err(format!("branch {}: no `frequencies_hz` array", k + 1)))?;
        if f.len() != omega.len() {
            return Err(err(format!(
                "branch {}: {} frequencies for {} speeds",
                k + 1,
                f.len(),
                omega.len()
            )));
        }
        out.push(EigenBranch {
            label: format!("eigenvalue branch {}", k + 1),
            omega: omega.clone(),
            frequencies_hz: f,
        });
    }
    if out.is_empty() {
        return Err(err("no branches in the file".into()));
    }
    Ok(out)
}

/// Parse `A,B` (two numbers), e.g. the `--southwell W0,K` option.
pub fn parse_pair(s: &str) -> Result<(f64, f64), PlotError> {
    let bad = || PlotError::Invalid(format!("{s:?}: expected two numbers A,B"));
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    let a: f64 = a.trim().parse().map_err(|_| bad())?;
    let b: f64 = b.trim().parse().map_err(|_| bad())?;
    if !a.is_finite() || !b.is_finite() {
        return Err(bad());
    }
    Ok((a, b))
}

/// Parse an image size `WxH` (pixels, 100..=8000 each).
pub fn parse_size(s: &str) -> Result<(u32, u32), PlotError> {
    let bad = || PlotError::Invalid(format!("{s:?}: expected an image size WxH, e.g. 1000x640"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(100..=8000).contains(&w) || !(100..=8000).contains(&h) {
        return Err(PlotError::Invalid(format!(
            "{s:?}: image width and height must be 100 to 8000 pixels"
        )));
    }
    Ok((w, h))
}

/// A sensor dataset's description (`/sensors/<NAME>` and its attributes).
#[derive(Clone, Debug)]
pub struct SensorInfo {
    pub name: String,
    pub components: Vec<String>,
    pub units: Vec<String>,
}

/// One sensor component selected for plotting.
#[derive(Clone, Debug)]
pub struct Channel {
    pub sensor: String,
    pub component: usize,
    /// `NAME.COMPONENT`
    pub name: String,
    pub unit: String,
}

impl Channel {
    /// `NAME.COMPONENT [unit]` (no brackets without a unit).
    pub fn axis_label(&self) -> String {
        with_unit(&self.name, &self.unit)
    }
}

fn with_unit(name: &str, unit: &str) -> String {
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// An open results file.
pub struct Campaign {
    path: PathBuf,
    reader: Reader,
    /// The model path stored in the file (empty if none).
    pub model_path: String,
    pub time: Vec<f64>,
    pub time_units: String,
    pub parameter_names: Vec<String>,
    /// Per variant, one value per parameter.
    pub parameter_values: Vec<Vec<f64>>,
    pub n_variants: usize,
    /// `/status/state` per variant (empty if absent).
    pub states: Vec<i32>,
    /// `/status/t_fail` per variant (empty if absent): where a failed or interrupted
    /// variant stopped; its samples after it were never written (they read NaN).
    pub t_fail: Vec<f64>,
}

impl Campaign {
    /// Open a results file and read its small datasets (time, parameters, status).
    pub fn open(path: &Path) -> Result<Self, PlotError> {
        let err = |message: String| PlotError::File {
            path: path.to_path_buf(),
            message,
        };
        latdyn::model::limits::regular_input(path).map_err(&err)?;
        let reader = Reader::open(path)
            .map_err(|e| err(format!("not a readable HDF5 results file ({e})")))?;
        if !reader.has_dataset(layout::TIME) {
            return Err(err(
                "not a latdyn results file (no /time dataset; `run -o FILE.h5` writes one)".into(),
            ));
        }
        // every dataset read whole is first checked for the size its shape claims
        // (`Reader::sized`): a 16 KB file can claim 10¹⁰ output times or variants
        let time_ds = reader.sized(layout::TIME).map_err(&err)?;
        let time = if time_ds.total_elements() == 0 {
            Vec::new()
        } else {
            time_ds
                .read_raw::<f64>()
                .map_err(|e| err(format!("reading /time: {e}")))?
        };
        let time_units = time_ds
            .attr(layout::attr::UNITS)
            .and_then(|a| a.read_string())
            .unwrap_or_else(|_| "s".into());
        let parameter_names = if reader.has_dataset(layout::PARAMETER_NAMES) {
            reader.strings(layout::PARAMETER_NAMES).map_err(&err)?
        } else {
            Vec::new()
        };
        let n_sensor_variants = match reader.names_in(layout::SENSORS).first() {
            Some(n) => match reader.file().dataset(&layout::sensor(n)) {
                Ok(ds) => {
                    let rows = ds.shape().first().copied().unwrap_or(0);
                    // only the row count is used here (the samples are checked when read)
                    if let Some(why) =
                        layout::oversized_claim(&layout::sensor(n), &[rows], ds.element_size())
                    {
                        return Err(err(why));
                    }
                    rows
                }
                Err(_) => 0,
            },
            None => 0,
        };
        let parameter_values = if reader.has_dataset(layout::PARAMETER_VALUES) {
            let ds = reader.sized(layout::PARAMETER_VALUES).map_err(&err)?;
            let shape = ds.shape();
            let (nv, np) = (shape.first().copied().unwrap_or(0), parameter_names.len());
            if np == 0 {
                vec![Vec::new(); nv]
            } else {
                // checked on the shape, before the read allocates it
                if shape.len() != 2 || shape[1] != np {
                    return Err(err(format!(
                        "/parameters/values has shape {shape:?}, expected [variants, {np}] \
                         ({np} names in /parameters/names)"
                    )));
                }
                let raw = reader.f64s(layout::PARAMETER_VALUES).map_err(&err)?;
                if raw.len() != nv * np {
                    return Err(err(format!(
                        "/parameters/values has {} values, expected {nv} × {np}",
                        raw.len()
                    )));
                }
                raw.chunks(np).map(<[f64]>::to_vec).collect()
            }
        } else if !parameter_names.is_empty() {
            // (a damaged header hides the dataset: the labels would index empty rows)
            return Err(err(format!(
                "/parameters/names holds {} names but /parameters/values is missing or \
                 unreadable",
                parameter_names.len()
            )));
        } else {
            vec![Vec::new(); n_sensor_variants]
        };
        let n_variants = parameter_values.len();
        // a refused claim is an error; a missing or unreadable status only loses the
        // labels and the failure times
        let refused = |name: &str| {
            reader
                .file()
                .dataset(name)
                .ok()
                .and_then(|d| layout::oversized_claim(name, &d.shape(), d.element_size()))
                .map(&err)
        };
        for name in [layout::STATE, layout::T_FAIL] {
            if let Some(e) = refused(name) {
                return Err(e);
            }
        }
        let states = reader
            .i64s(layout::STATE)
            .map(|v| v.into_iter().map(|x| x as i32).collect())
            .unwrap_or_default();
        let t_fail = reader.f64s(layout::T_FAIL).unwrap_or_default();
        let model_path = reader
            .scalar_text(layout::MODEL_PATH)
            .map(|t| t.trim().to_string())
            .unwrap_or_default();
        Ok(Campaign {
            path: path.to_path_buf(),
            reader,
            model_path,
            time,
            time_units,
            parameter_names,
            parameter_values,
            n_variants,
            states,
            t_fail,
        })
    }

    fn err(&self, message: String) -> PlotError {
        PlotError::File {
            path: self.path.clone(),
            message,
        }
    }

    /// Default chart title: the model path stored in the file, else the file name.
    pub fn default_title(&self) -> String {
        if self.model_path.is_empty() {
            self.path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        } else {
            self.model_path.clone()
        }
    }

    /// Names of the `/sensors` datasets.
    pub fn sensor_names(&self) -> Vec<String> {
        self.reader.names_in(layout::SENSORS)
    }

    /// Names of the `/derived` datasets.
    pub fn derived_names(&self) -> Vec<String> {
        self.reader.names_in(layout::DERIVED)
    }

    /// A sensor's components and units (from its attributes; `c0`, `c1`, … and no units
    /// if they cannot be read).
    pub fn sensor_info(&self, name: &str) -> Result<SensorInfo, PlotError> {
        let names = self.sensor_names();
        if !names.iter().any(|n| n == name) {
            return Err(self.err(format!(
                "no sensor {name:?} in the file (sensors: {})",
                list_or_none(&names)
            )));
        }
        let ds = self.sensor_dataset(name)?;
        let m = self
            .reader
            .sensor_meta(name, &ds)
            .map_err(|e| self.err(e))?;
        Ok(SensorInfo {
            name: m.name,
            components: m.components,
            units: m.units,
        })
    }

    fn sensor_dataset(&self, name: &str) -> Result<layout::Dataset, PlotError> {
        self.reader
            .file()
            .dataset(&layout::sensor(name))
            .map_err(|e| self.err(format!("reading /sensors/{name}: {e}")))
    }

    /// Resolve `NAME` or `NAME.COMPONENT` to channels: every component of `NAME` when
    /// none is given. A sensor name containing dots is matched whole first.
    pub fn channels(&self, sel: &str) -> Result<Vec<Channel>, PlotError> {
        let names = self.sensor_names();
        let (sensor, comp) = if names.iter().any(|n| n == sel) {
            (sel, None)
        } else if let Some((s, c)) = sel.rsplit_once('.') {
            if names.iter().any(|n| n == s) {
                (s, Some(c))
            } else {
                return Err(self.err(format!(
                    "no sensor {s:?} in the file (sensors: {})",
                    list_or_none(&names)
                )));
            }
        } else {
            (sel, None)
        };
        let info = self.sensor_info(sensor)?;
        let make = |k: usize| Channel {
            sensor: info.name.clone(),
            component: k,
            name: format!("{}.{}", info.name, info.components[k]),
            unit: info.units[k].clone(),
        };
        match comp {
            None => Ok((0..info.components.len()).map(make).collect()),
            Some(c) => match info.components.iter().position(|x| x == c) {
                Some(k) => Ok(vec![make(k)]),
                None => Err(self.err(format!(
                    "sensor {:?} has no component {c:?} (components: {})",
                    info.name,
                    info.components.join(", ")
                ))),
            },
        }
    }

    /// One channel, which must name a single component.
    pub fn channel(&self, sel: &str) -> Result<Channel, PlotError> {
        let mut ch = self.channels(sel)?;
        if ch.len() == 1 {
            Ok(ch.remove(0))
        } else {
            let comps: Vec<String> = ch.iter().map(|c| c.name.clone()).collect();
            Err(self.err(format!(
                "sensor {sel:?} has {} components: pick one ({})",
                ch.len(),
                comps.join(", ")
            )))
        }
    }

    /// Samples of a channel for one variant over the time grid (NaN where not written).
    pub fn samples(&self, ch: &Channel, variant: usize) -> Result<Vec<f64>, PlotError> {
        let ds = self.sensor_dataset(&ch.sensor)?;
        let shape = ds.shape();
        if shape.len() != 3 || variant >= shape[0] {
            return Err(self.err(format!(
                "/sensors/{} has shape {shape:?}, no variant {variant}",
                ch.sensor
            )));
        }
        let (nt, nc) = (shape[1], shape[2]);
        // sizes checked before the read allocates nt × nc values: the time grid was read
        // whole, so a shape that disagrees with it is a claim, not data
        if nt > self.time.len() || nc > layout::MAX_SENSOR_COMPONENTS || ch.component >= nc {
            return Err(self.err(format!(
                "/sensors/{} has shape {shape:?}: expected at most {} output times (/time) \
                 and {} components",
                ch.sensor,
                self.time.len(),
                layout::MAX_SENSOR_COMPONENTS
            )));
        }
        // and the whole dataset against what latdyn writes (variants × times × components
        // within the output-values limit): the slice read is one variant of it
        if let Some(why) =
            layout::oversized_claim(&layout::sensor(&ch.sensor), &shape, ds.element_size())
        {
            return Err(self.err(why));
        }
        if nt == 0 {
            return Ok(Vec::new());
        }
        let raw = ds
            .read_slice::<f64>(&[variant, 0, 0], &[1, nt, nc])
            .map_err(|e| self.err(format!("reading /sensors/{}: {e}", ch.sensor)))?;
        Ok(raw.chunks(nc).map(|r| r[ch.component]).collect())
    }

    /// Which samples of `variant` were never written, so read NaN by design rather than
    /// as data; `None` for none (a completed variant, or a file without status).
    ///
    /// - A path campaign (`statics --path`, `sweep --path`: the sensor `path_lambda`):
    ///   the points a path did not reach, where λ is NaN (shorter paths are NaN-padded
    ///   to the longest, and `/time` is the point index there, so `t_fail` (a λ) does
    ///   not locate them).
    /// - A variant not completed (pending, running, failed, interrupted): its samples at
    ///   and after `/status/t_fail`, all of them when that is NaN (never run, still
    ///   running, or a panic). A run writes each output time it reaches and stops at
    ///   t_fail, the time of its last accepted step; "at" covers a failure at the start
    ///   (t_fail = 0, the first sample never written).
    ///
    /// A λ that cannot be read falls back to the status: the notes never stop a chart.
    fn unwritten(&self, variant: usize) -> Option<Vec<bool>> {
        let lambda = latdyn::solver::path::LAMBDA_SENSOR;
        if self.sensor_names().iter().any(|n| n == lambda) {
            let ch = Channel {
                sensor: lambda.to_string(),
                component: 0,
                name: format!("{lambda}.lambda"),
                unit: String::new(),
            };
            if let Ok(l) = self.samples(&ch, variant) {
                let mut mask: Vec<bool> = l.iter().map(|x| x.is_nan()).collect();
                mask.resize(self.time.len(), true);
                return Some(mask);
            }
        }
        match self.states.get(variant) {
            None | Some(2) => None,
            Some(_) => {
                let tf = self.t_fail.get(variant).copied().unwrap_or(f64::NAN);
                Some(self.time.iter().map(|&t| tf.is_nan() || t >= tf).collect())
            }
        }
    }

    /// A note for the NaN samples of `ch` in `variant` (`y`, over the time grid) that are
    /// data rather than samples never written ([`Campaign::unwritten`]): how many, of
    /// which line, and where the first is.
    ///
    /// The NaN tail of a failed, interrupted, pending or running variant, and the padding
    /// of a shorter path, get no note: the legend already says `(failed)`,
    /// `(interrupted)` or `(pending)`, the line visibly ends there and `/status/message`
    /// says why, so a note would repeat on every chart of a campaign with a failure and
    /// teach users to skip the notes, hiding the one that matters: a NaN inside the
    /// samples a variant did write (a completed variant, or before a failure), which no
    /// legend shows and a broken line alone does not explain.
    fn nan_note(&self, ch: &Channel, variant: usize, y: &[f64], notes: &mut Vec<String>) {
        if !y.iter().any(|v| v.is_nan()) {
            return;
        }
        let unwritten = self.unwritten(variant);
        let expected = |i: usize| unwritten.as_ref().is_some_and(|m| m.get(i) != Some(&false));
        let nan: Vec<usize> = (0..y.len())
            .filter(|&i| y[i].is_nan() && !expected(i))
            .collect();
        let Some(&first) = nan.first() else {
            return;
        };
        // `variant 2 (omega=3, failed)`: the row index --variants takes, and the legend's
        // words
        let words: Vec<String> = self
            .varying_parameters(variant)
            .into_iter()
            .chain(self.state_word(variant).map(String::from))
            .collect();
        let which = if words.is_empty() {
            format!("variant {variant}")
        } else {
            format!("variant {variant} ({})", words.join(", "))
        };
        let at = self
            .time
            .get(first)
            .map(|&t| format!("; the first at t = {} {}", fmt_num(t), self.time_units))
            .unwrap_or_default();
        notes.push(format!(
            "{} NaN sample(s) of {} in {which} not drawn (the line breaks there{at})",
            nan.len(),
            ch.name
        ));
    }

    /// `/derived/<NAME>` (one value per variant).
    pub fn derived(&self, name: &str) -> Result<Vec<f64>, PlotError> {
        let names = self.derived_names();
        if !names.iter().any(|n| n == name) {
            return Err(self.err(format!(
                "no derived quantity {name:?} in the file (derived: {})",
                list_or_none(&names)
            )));
        }
        self.reader
            .f64s(&layout::derived(name))
            .map_err(|e| self.err(e))
    }

    /// Values of one parameter over the variants.
    pub fn parameter(&self, name: &str) -> Result<Vec<f64>, PlotError> {
        let k = self
            .parameter_names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| {
                self.err(format!(
                    "no parameter {name:?} in the file (parameters: {})",
                    list_or_none(&self.parameter_names)
                ))
            })?;
        Ok(self.parameter_values.iter().map(|row| row[k]).collect())
    }

    /// Legend label of a variant: the parameters that differ between variants
    /// (`omega=3, L=2`), else `variant k`; ` (failed)` if its status says so.
    pub fn variant_label(&self, v: usize) -> String {
        let mut s = self
            .varying_parameters(v)
            .unwrap_or_else(|| format!("variant {v}"));
        if let Some(w) = self.state_word(v) {
            s += &format!(" ({w})");
        }
        s
    }

    /// `omega=3, L=2`: the parameters that differ between variants, with this one's
    /// values; `None` if none differ.
    fn varying_parameters(&self, v: usize) -> Option<String> {
        let varying: Vec<usize> = (0..self.parameter_names.len())
            .filter(|&k| {
                let f0 = self.parameter_values.first().map_or(f64::NAN, |r| r[k]);
                self.parameter_values
                    .iter()
                    .any(|r| r[k] != f0 && !(r[k].is_nan() && f0.is_nan()))
            })
            .collect();
        (!varying.is_empty()).then(|| {
            varying
                .iter()
                .map(|&k| {
                    format!(
                        "{}={}",
                        self.parameter_names[k],
                        fmt_num(self.parameter_values[v][k])
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        })
    }

    /// `failed`, `interrupted` or `pending` as `/status/state` says (`None` otherwise).
    fn state_word(&self, v: usize) -> Option<&'static str> {
        match self.states.get(v) {
            Some(3) => Some("failed"),
            Some(4) => Some("interrupted"),
            Some(0) => Some("pending"),
            _ => None,
        }
    }

    /// The variants to draw: those asked for (checked), or all, thinned evenly to fit
    /// `MAX_LINES` lines of `lines_per_variant` each (with a note).
    fn select_variants(
        &self,
        asked: Option<&[usize]>,
        lines_per_variant: usize,
        notes: &mut Vec<String>,
    ) -> Result<Vec<usize>, PlotError> {
        let cap = (MAX_LINES / lines_per_variant.max(1)).max(1);
        if let Some(a) = asked {
            if let Some(&bad) = a.iter().find(|&&v| v >= self.n_variants) {
                return Err(self.err(format!(
                    "no variant {bad}: the file has {} variants (0 to {})",
                    self.n_variants,
                    self.n_variants.saturating_sub(1)
                )));
            }
            if a.len() * lines_per_variant > MAX_LINES {
                return Err(PlotError::Invalid(format!(
                    "{} lines asked for ({} variants × {lines_per_variant} components): at most \
                     {MAX_LINES} are drawn; pick fewer with --variants",
                    a.len() * lines_per_variant,
                    a.len()
                )));
            }
            return Ok(a.to_vec());
        }
        if self.n_variants == 0 {
            return Err(self.err("the file has no variants".into()));
        }
        if self.n_variants <= cap {
            return Ok((0..self.n_variants).collect());
        }
        let picked: Vec<usize> = if cap == 1 {
            vec![0]
        } else {
            let mut p: Vec<usize> = (0..cap)
                .map(|i| (i * (self.n_variants - 1) + (cap - 1) / 2) / (cap - 1))
                .collect();
            p.dedup();
            p
        };
        notes.push(format!(
            "drawing {} of {} variants (at most {MAX_LINES} lines; choose with --variants)",
            picked.len(),
            self.n_variants
        ));
        Ok(picked)
    }
}

fn list_or_none(names: &[String]) -> String {
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

/// A number for labels: 4 significant digits, no trailing zeros (`3`, `0.1235`, `1e+09`).
pub fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor() as i32;
    if (-3..5).contains(&e) {
        let decimals = (3 - e).max(0) as usize;
        trim_zeros(&format!("{v:.decimals$}"))
    } else {
        let s = format!("{v:.3e}");
        match s.split_once('e') {
            Some((m, x)) => format!("{}e{x}", trim_zeros(m)),
            None => s,
        }
    }
}

fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

/// Axis tick labels: up to 6 significant digits, so 0.30000000000000004 shows as 0.3.
fn fmt_tick(v: f64) -> String {
    if v.abs() < 1e-12 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:.3e}");
        return match s.split_once('e') {
            Some((m, x)) => format!("{}e{x}", trim_zeros(m)),
            None => s,
        };
    }
    let e = a.log10().floor() as i32;
    let decimals = (5 - e).max(0) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

// ---------------------------------------------------------------------------------------
// Chart kinds

/// Time histories of sensor components: one line per (selected variant, component).
pub fn plot_sensors(
    c: &Campaign,
    sensors: &[String],
    opts: &PlotOptions,
    out: &Path,
) -> Result<PlotSummary, PlotError> {
    let format = ImageFormat::from_path(out)?;
    if sensors.is_empty() {
        return Err(PlotError::Invalid("no --sensor given".into()));
    }
    let mut channels = Vec::new();
    for s in sensors {
        channels.extend(c.channels(s)?);
    }
    if c.time.is_empty() {
        return Err(c.err("the file has no output times".into()));
    }
    let mut summary = PlotSummary::default();
    let variants =
        c.select_variants(opts.variants.as_deref(), channels.len(), &mut summary.notes)?;
    let many = channels.len() > 1;
    let mut lines = Vec::new();
    let bad_times = c.time.iter().filter(|t| t.is_nan()).count();
    if bad_times > 0 {
        summary.notes.push(format!(
            "{bad_times} of the {} output times in /time are NaN: their samples are not drawn",
            c.time.len()
        ));
    }
    for ch in &channels {
        for &v in &variants {
            let y = c.samples(ch, v)?;
            c.nan_note(ch, v, &y, &mut summary.notes);
            let label = if many {
                format!("{}: {}", ch.name, c.variant_label(v))
            } else {
                c.variant_label(v)
            };
            lines.push(Line {
                label,
                points: c.time.iter().copied().zip(y).collect(),
                color: lines.len(),
                markers: false,
                dashed: false,
            });
        }
    }
    // Consecutive channels with one unit share it: "tip.x, tip.z [m]; moment.my [N·m]".
    let mut groups: Vec<(Vec<&str>, &str)> = Vec::new();
    for ch in &channels {
        match groups.last_mut() {
            Some((names, unit)) if *unit == ch.unit => names.push(&ch.name),
            _ => groups.push((vec![&ch.name], &ch.unit)),
        }
    }
    let y_label = groups
        .iter()
        .map(|(names, unit)| with_unit(&names.join(", "), unit))
        .collect::<Vec<_>>()
        .join("; ");
    let title = opts.title.clone().unwrap_or_else(|| c.default_title());
    let fig = Figure {
        title,
        x_label: with_unit("t", &c.time_units),
        y_label,
        lines,
        ..Default::default()
    };
    finish(fig, format, opts.size, out, summary)
}

/// Work-precision chart: error against cost on log-log axes, one line with markers per
/// configuration (points in the order given). Non-positive values cannot be drawn on a
/// log axis and are left out (a zero error is reported in the table instead).
pub fn plot_work_precision(
    curves: &[(String, Vec<(f64, f64)>)],
    title: &str,
    x_label: &str,
    y_label: &str,
    size: (u32, u32),
    out: &Path,
) -> Result<PlotSummary, PlotError> {
    let format = ImageFormat::from_path(out)?;
    let lines = curves
        .iter()
        .enumerate()
        .map(|(i, (label, pts))| Line {
            label: label.clone(),
            points: pts
                .iter()
                .filter(|(x, y)| *x > 0.0 && *y > 0.0)
                .map(|(x, y)| (x.log10(), y.log10()))
                .collect(),
            color: i,
            markers: true,
            dashed: false,
        })
        .collect();
    let fig = Figure {
        title: title.to_string(),
        x_label: x_label.to_string(),
        y_label: y_label.to_string(),
        lines,
        log_axes: true,
        ..Default::default()
    };
    finish(fig, format, size, out, PlotSummary::default())
}

/// One sensor component against another (phase or cross plot), one line per variant.
pub fn plot_phase(
    c: &Campaign,
    x: &str,
    y: &str,
    opts: &PlotOptions,
    out: &Path,
) -> Result<PlotSummary, PlotError> {
    let format = ImageFormat::from_path(out)?;
    let (cx, cy) = (c.channel(x)?, c.channel(y)?);
    let mut summary = PlotSummary::default();
    let variants = c.select_variants(opts.variants.as_deref(), 1, &mut summary.notes)?;
    let mut lines = Vec::new();
    for &v in &variants {
        let (xs, ys) = (c.samples(&cx, v)?, c.samples(&cy, v)?);
        c.nan_note(&cx, v, &xs, &mut summary.notes);
        if cy.name != cx.name {
            c.nan_note(&cy, v, &ys, &mut summary.notes);
        }
        lines.push(Line {
            label: c.variant_label(v),
            points: xs.into_iter().zip(ys).collect(),
            color: lines.len(),
            markers: false,
            dashed: false,
        });
    }
    let title = opts.title.clone().unwrap_or_else(|| c.default_title());
    let fig = Figure {
        title,
        x_label: cx.axis_label(),
        y_label: cy.axis_label(),
        lines,
        start_markers: true,
        ..Default::default()
    };
    finish(fig, format, opts.size, out, summary)
}

/// Campbell diagram: `/derived/<NAME>` (Hz) against a parameter (Ω, rad/s), with the
/// rotor harmonics n·Ω, an optional Southwell curve and the crossings marked.
pub fn plot_campbell(
    c: &Campaign,
    spec: &CampbellSpec,
    opts: &PlotOptions,
    out: &Path,
) -> Result<CampbellSummary, PlotError> {
    let format = ImageFormat::from_path(out)?;
    let omega = c.parameter(&spec.parameter)?;
    let f_hz = c.derived(&spec.derived)?;
    let mut notes = Vec::new();
    let variants: Vec<usize> = match &opts.variants {
        Some(a) => {
            if let Some(&bad) = a.iter().find(|&&v| v >= c.n_variants) {
                return Err(c.err(format!(
                    "no variant {bad}: the file has {} variants",
                    c.n_variants
                )));
            }
            a.clone()
        }
        None => (0..c.n_variants).collect(),
    };
    let mut pts: Vec<(f64, f64)> = Vec::new();
    let mut missing = 0;
    for &v in &variants {
        let (x, f) = (omega[v], f_hz.get(v).copied().unwrap_or(f64::NAN));
        if x.is_finite() && f.is_finite() {
            pts.push((x, std::f64::consts::TAU * f));
        } else {
            missing += 1;
        }
    }
    if missing > 0 {
        notes.push(format!(
            "{missing} of {} variants have no {} value: left out",
            variants.len(),
            spec.derived
        ));
    }
    if pts.is_empty() {
        return Err(c.err(format!(
            "no variant has both {} and /derived/{} values",
            spec.parameter, spec.derived
        )));
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let xs: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let ys_rad: Vec<f64> = pts.iter().map(|p| p.1).collect();
    let crossings = campbell_crossings(&xs, &ys_rad, spec.harmonics);

    let k = spec.units.per_rad_s();
    let data: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x, y * k)).collect();
    let x_lo = xs[0].min(0.0);
    let mut x_hi = xs[xs.len() - 1];
    if x_hi <= x_lo {
        x_hi = x_lo + 1.0;
    }
    let y_data_max = data.iter().map(|p| p.1).fold(0.0, f64::max);
    let mut y_hi = if y_data_max > 0.0 {
        1.15 * y_data_max
    } else {
        1.0
    };
    // Enough room for the 1Ω line to show across the chart when the data lie low.
    if y_hi < 0.25 * x_hi * k {
        y_hi = 0.25 * x_hi * k;
    }

    let mut lines = vec![Line {
        label: match spec.units {
            FreqUnits::RadPerS => format!("2π·{}", spec.derived),
            FreqUnits::Hz => spec.derived.clone(),
        },
        points: data,
        color: 0,
        markers: true,
        dashed: false,
    }];
    let mut extra = Vec::new();
    if let Some((w0, kk)) = spec.southwell {
        let n = 200;
        let pts: Vec<(f64, f64)> = (0..=n)
            .map(|i| {
                let x = x_lo + (x_hi - x_lo) * i as f64 / n as f64;
                let om = x * k;
                (x, (w0 * w0 + kk * om * om).max(0.0).sqrt())
            })
            .collect();
        let top = pts.iter().map(|p| p.1).fold(0.0, f64::max);
        if top > y_hi && top < 3.0 * y_hi {
            y_hi = 1.05 * top;
        }
        extra.push(Line {
            label: format!(
                "Southwell √(W0² + K·Ω²), W0={}, K={}",
                fmt_num(w0),
                fmt_num(kk)
            ),
            points: pts,
            color: 1,
            markers: false,
            dashed: true,
        });
    }
    let mut branch_crossings = Vec::new();
    for (b, br) in spec.branches.iter().enumerate() {
        // a negative value is a divergence's growth rate (−s/2π, `latdyn modes`), not a
        // frequency: left out, and said; the chart's axis starts at 0, and it was drawn
        // there as a 0 Hz branch (a probe, session 46)
        let divergent: Vec<f64> = br
            .omega
            .iter()
            .zip(&br.frequencies_hz)
            .filter(|(_, f)| **f < 0.0)
            .map(|(&x, _)| x)
            .collect();
        if let (Some(lo), Some(hi)) = (divergent.first(), divergent.last()) {
            notes.push(format!(
                "branch {} ({}): {} values between {} = {} and {} are divergent (negative: \
                 a growth rate, not a frequency; `latdyn modes` warns them) and are not drawn",
                b + 1,
                br.label,
                divergent.len(),
                spec.parameter,
                fmt_num(*lo),
                fmt_num(*hi)
            ));
        }
        let y_rad: Vec<f64> = br
            .frequencies_hz
            .iter()
            .map(|f| {
                if *f < 0.0 {
                    f64::NAN
                } else {
                    std::f64::consts::TAU * f
                }
            })
            .collect();
        for (n, om) in campbell_crossings(&br.omega, &y_rad, spec.harmonics) {
            let nf = n as f64;
            // a branch on n·Ω everywhere (to 1e-3) is that harmonic, not a resonance
            let on_line = br.omega.iter().zip(&y_rad).all(|(&x, &y)| {
                !(x.is_finite() && y.is_finite()) || (y - nf * x).abs() <= 1e-3 * nf * x.abs()
            });
            if !on_line {
                branch_crossings.push((b + 1, n, om));
            }
        }
        let pts: Vec<(f64, f64)> = br
            .omega
            .iter()
            .copied()
            .zip(y_rad.iter().map(|y| y * k))
            .collect();
        let top = pts
            .iter()
            .map(|p| p.1)
            .filter(|y| y.is_finite())
            .fold(0.0, f64::max);
        if top > y_hi && top < 2.0 * y_hi {
            y_hi = 1.05 * top;
        }
        extra.push(Line {
            label: br.label.clone(),
            points: pts,
            color: 2 + b,
            markers: false,
            dashed: false,
        });
    }
    // The model curves under the data.
    extra.append(&mut lines);
    let lines = extra;

    let harmonics: Vec<Guide> = (1..=spec.harmonics)
        .map(|n| {
            let nk = n as f64 * k;
            // Clip n·Ω to the chart box.
            let x_end = if nk * x_hi > y_hi { y_hi / nk } else { x_hi };
            let x0 = x_lo.max(0.0);
            Guide {
                from: (x0, nk * x0),
                to: (x_end, nk * x_end),
                label: format!("{n}Ω"),
            }
        })
        .collect();
    let marks: Vec<Mark> = crossings
        .iter()
        .map(|&(n, om)| Mark {
            at: (om, n as f64 * om * k),
            label: format!("{n}Ω @ Ω={}", fmt_num(om)),
        })
        .collect();

    let title = opts.title.clone().unwrap_or_else(|| c.default_title());
    let fig = Figure {
        title: format!("{title}: Campbell diagram"),
        x_label: format!("{} [rad/s]", spec.parameter),
        y_label: match spec.units {
            FreqUnits::RadPerS => format!("ω = 2π·{} [{}]", spec.derived, spec.units.label()),
            FreqUnits::Hz => format!("{} [{}]", spec.derived, spec.units.label()),
        },
        lines,
        guides: harmonics,
        guide_legend: (spec.harmonics > 0).then(|| "rotor harmonics n·Ω".to_string()),
        marks,
        x_range: Some((x_lo, x_hi)),
        y_range: Some((0.0, y_hi)),
        ..Default::default()
    };
    let summary = finish(
        fig,
        format,
        opts.size,
        out,
        PlotSummary {
            lines: Vec::new(),
            notes,
        },
    )?;
    Ok(CampbellSummary {
        summary,
        crossings,
        branch_crossings,
    })
}

// ---------------------------------------------------------------------------------------
// Drawing

/// A data line: points (NaN breaks it), legend label, palette index.
struct Line {
    label: String,
    points: Vec<(f64, f64)>,
    color: usize,
    /// Circles at the points.
    markers: bool,
    /// Dashed (a model curve) rather than solid.
    dashed: bool,
}

/// A dotted reference line with a text label at its end.
struct Guide {
    from: (f64, f64),
    to: (f64, f64),
    label: String,
}

/// A marked point with a text label.
struct Mark {
    at: (f64, f64),
    label: String,
}

#[derive(Default)]
struct Figure {
    title: String,
    x_label: String,
    y_label: String,
    lines: Vec<Line>,
    guides: Vec<Guide>,
    /// Legend entry for the guides (one for all).
    guide_legend: Option<String>,
    marks: Vec<Mark>,
    /// Mark the first finite point of each line.
    start_markers: bool,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
    /// The points are log10 of the data: ticks read 10^v.
    log_axes: bool,
}

/// Line colours: Tableau 10, then darker variants.
const PALETTE: [(u8, u8, u8); 20] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
    (17, 70, 110),
    (170, 80, 0),
    (20, 100, 20),
    (140, 20, 20),
    (90, 60, 120),
    (90, 50, 40),
    (160, 60, 130),
    (60, 60, 60),
    (120, 120, 10),
    (10, 120, 130),
];

fn color(i: usize) -> RGBColor {
    let (r, g, b) = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

/// Register the embedded font once (plotters' `ab_glyph` renderer has no system fonts).
fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
        let _ = plotters::style::register_font("sans-serif", FontStyle::Bold, dejavu::sans::bold());
    });
}

/// Draw the figure to `out` and return the summary with the legend labels filled in.
fn finish(
    fig: Figure,
    format: ImageFormat,
    size: (u32, u32),
    out: &Path,
    mut summary: PlotSummary,
) -> Result<PlotSummary, PlotError> {
    if !fig
        .lines
        .iter()
        .any(|l| l.points.iter().any(|p| p.0.is_finite() && p.1.is_finite()))
    {
        return Err(PlotError::Data(
            "nothing to draw: no selected sample is finite (they are NaN, not written: \
             variants not run yet?, or infinite)"
                .into(),
        ));
    }
    check_axis_ranges(&fig)?;
    let infinite: usize = fig
        .lines
        .iter()
        .flat_map(|l| l.points.iter())
        .filter(|p| p.0.is_infinite() || p.1.is_infinite())
        .count();
    if infinite > 0 {
        summary.notes.push(format!(
            "{infinite} infinite sample(s) not drawn (the lines break there)"
        ));
    }
    register_fonts();
    let draw_err = |message: String| PlotError::Draw {
        path: out.to_path_buf(),
        message,
    };
    match format {
        ImageFormat::Svg => {
            // Render to memory first: plotters' SVG backend writes the file on drop and
            // cannot report an I/O error there.
            let mut text = String::new();
            {
                let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                draw(&root, &fig).map_err(draw_err)?;
                root.present().map_err(|e| draw_err(e.to_string()))?;
            }
            fs::write(out, text).map_err(|e| draw_err(format!("writing the image: {e}")))?;
        }
        ImageFormat::Png => {
            // Encode in memory, then write: the image crate's file errors are terse.
            let (w, h) = size;
            let mut buf = vec![0u8; (w * h * 3) as usize];
            {
                let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
                draw(&root, &fig).map_err(draw_err)?;
                root.present().map_err(|e| draw_err(e.to_string()))?;
            }
            let mut png_bytes = Vec::new();
            {
                let mut enc = png::Encoder::new(&mut png_bytes, w, h);
                enc.set_compression(png::Compression::Best);
                enc.set_color(png::ColorType::Rgb);
                enc.set_depth(png::BitDepth::Eight);
                let mut wr = enc
                    .write_header()
                    .map_err(|e| draw_err(format!("encoding PNG: {e}")))?;
                wr.write_image_data(&buf)
                    .map_err(|e| draw_err(format!("encoding PNG: {e}")))?;
            }
            fs::write(out, png_bytes).map_err(|e| draw_err(format!("writing the image: {e}")))?;
        }
    }
    summary.lines = fig.lines.iter().map(|l| l.label.clone()).collect();
    Ok(summary)
}

/// Largest magnitude an axis end may have. plotters' tick search scales the axis width
/// by powers of ten and loops forever once that overflows (an axis from 0 to 1.7e308, or
/// ±1e308): keep eight decades of headroom below `f64::MAX`.
pub const MAX_AXIS_MAGNITUDE: f64 = 1e300;

/// The axis ranges `draw` will use: the figure's own, or the padded range of the data.
fn axis_ranges(fig: &Figure) -> ((f64, f64), (f64, f64)) {
    let x = fig.x_range.unwrap_or_else(|| {
        padded_range(fig.lines.iter().flat_map(|l| l.points.iter().map(|p| p.0)))
    });
    let y = fig.y_range.unwrap_or_else(|| {
        padded_range(fig.lines.iter().flat_map(|l| l.points.iter().map(|p| p.1)))
    });
    (x, y)
}

/// Refuse axes no chart can show (values beyond ±[`MAX_AXIS_MAGNITUDE`]), naming the
/// line and the value, rather than hang in the tick computation.
fn check_axis_ranges(fig: &Figure) -> Result<(), PlotError> {
    let (xr, yr) = axis_ranges(fig);
    for (axis, r, given, pick) in [
        ("x", xr, fig.x_range.is_some(), 0usize),
        ("y", yr, fig.y_range.is_some(), 1usize),
    ] {
        let coord = |p: &(f64, f64)| if pick == 0 { p.0 } else { p.1 };
        // data within ±MAX pad to an axis within ±1.1 MAX; a given range may reach 10 MAX
        let within = if given {
            r.0.is_finite()
                && r.1.is_finite()
                && r.0.abs().max(r.1.abs()) <= 10.0 * MAX_AXIS_MAGNITUDE
        } else {
            fig.lines
                .iter()
                .flat_map(|l| l.points.iter().map(coord))
                .all(|v| !v.is_finite() || v.abs() <= MAX_AXIS_MAGNITUDE)
        };
        if within {
            continue;
        }
        // the data value that took the axis there (largest finite magnitude)
        let worst = fig
            .lines
            .iter()
            .flat_map(|l| l.points.iter().map(move |p| (l, coord(p))))
            .filter(|(_, v)| v.is_finite())
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
        let axis_name = if axis == "x" {
            &fig.x_label
        } else {
            &fig.y_label
        };
        let what = match worst {
            Some((l, v)) if !given => format!(
                "line \"{}\" reaches {v:e} on the {axis} axis ({axis_name})",
                l.label
            ),
            _ => format!(
                "the {axis} axis ({axis_name}) would span {:e} to {:e}",
                r.0, r.1
            ),
        };
        return Err(PlotError::Data(format!(
            "cannot draw: {what}, beyond ±{MAX_AXIS_MAGNITUDE:e}, the widest range a chart \
             axis can show; plot components or variants whose values stay within it \
             (e.g. --sensor NAME.COMPONENT)"
        )));
    }
    Ok(())
}

/// Range of the finite values, padded by 5 % (or ±1 / ±10 % when degenerate).
fn padded_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo <= 1e-12 * hi.abs().max(lo.abs()) {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - d, hi + d);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Split a polyline at non-finite points.
fn segments(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for &p in points {
        if p.0.is_finite() && p.1.is_finite() {
            cur.push(p);
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (w, _h) = root.dim_in_pixel();
    let fs = (w as f64 / 1000.0 * 16.0).clamp(11.0, 32.0);
    let fsi = fs.round() as u32;
    let (x_range, y_range) = axis_ranges(fig);
    let log = fig.log_axes;
    // log ticks fall between decades too: two significant digits read better there
    let tick = |v: f64| {
        if log {
            let x = 10f64.powf(v);
            let digits = (1 - x.log10().floor() as i32).max(0) as usize;
            if (1e-3..1e5).contains(&x) {
                trim_zeros(&format!("{x:.digits$}"))
            } else {
                format!("{x:.1e}")
            }
        } else {
            fmt_tick(v)
        }
    };
    let mut chart = ChartBuilder::on(root)
        .caption(&fig.title, ("sans-serif", 1.3 * fs).into_font())
        .margin(fsi)
        .x_label_area_size(3 * fsi)
        .y_label_area_size(5 * fsi)
        .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(fig.x_label.as_str())
        .y_desc(fig.y_label.as_str())
        .axis_desc_style(("sans-serif", fs).into_font())
        .label_style(("sans-serif", 0.85 * fs).into_font())
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .max_light_lines(4)
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(200, 200, 200))
        .draw()
        .map_err(e)?;

    let width = (fs / 8.0).round().max(1.0) as u32;
    let small = ("sans-serif", 0.85 * fs).into_font();

    // Guides (rotor harmonics) under the data: grey dotted lines, labelled at their end.
    let guide_style = ShapeStyle {
        color: RGBColor(110, 110, 110).to_rgba(),
        filled: false,
        stroke_width: width,
    };
    for (i, g) in fig.guides.iter().enumerate() {
        let anno = chart
            .draw_series(DashedLineSeries::new(
                [g.from, g.to],
                2 * width,
                4 * width,
                guide_style,
            ))
            .map_err(e)?;
        if i == 0 {
            if let Some(label) = &fig.guide_legend {
                anno.label(label.as_str()).legend(move |(x, y)| {
                    DashedPathElement::new(
                        [(x, y), (x + 2 * fsi as i32, y)],
                        2 * width,
                        4 * width,
                        guide_style,
                    )
                });
            }
        }
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(g.to)
                    + Text::new(
                        g.label.clone(),
                        (-(2 * fsi as i32), 2),
                        small.clone().color(&RGBColor(80, 80, 80)),
                    ),
            ))
            .map_err(e)?;
    }

    for line in &fig.lines {
        let c = color(line.color);
        let style = c.stroke_width(width + 1);
        let segs = segments(&line.points);
        let legend_end = |x: i32| x + 2 * fsi as i32;
        if line.dashed {
            let (dash, gap) = (5 * width, 3 * width);
            chart
                .draw_series(
                    segs.iter()
                        .map(|s| DashedPathElement::new(s.clone(), dash, gap, style)),
                )
                .map_err(e)?
                .label(line.label.as_str())
                .legend(move |(x, y)| {
                    DashedPathElement::new([(x, y), (legend_end(x), y)], dash, gap, style)
                });
        } else {
            chart
                .draw_series(segs.iter().map(|s| PathElement::new(s.clone(), style)))
                .map_err(e)?
                .label(line.label.as_str())
                .legend(move |(x, y)| PathElement::new([(x, y), (legend_end(x), y)], style));
        }
        if line.markers {
            chart
                .draw_series(
                    segs.iter()
                        .flatten()
                        .map(|&p| Circle::new(p, 2 + width, c.filled())),
                )
                .map_err(e)?;
        }
        if fig.start_markers {
            if let Some(&p) = segs.first().and_then(|s| s.first()) {
                chart
                    .draw_series(std::iter::once(Circle::new(p, 2 + width, c.filled())))
                    .map_err(e)?;
            }
        }
    }

    if !fig.marks.is_empty() {
        let mc = RGBColor(200, 0, 0);
        let anno = chart
            .draw_series(
                fig.marks
                    .iter()
                    .map(|m| Circle::new(m.at, 4 + width, mc.stroke_width(width + 1))),
            )
            .map_err(e)?;
        anno.label("crossings").legend(move |(x, y)| {
            Circle::new((x + fsi as i32, y), 4 + width, mc.stroke_width(width + 1))
        });
        // Labels in pixel space, stacked so that neighbouring crossings stay readable.
        let font = small.clone().color(&mc);
        let anchors: Vec<(i32, i32)> = fig
            .marks
            .iter()
            .map(|m| chart.backend_coord(&m.at))
            .collect();
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        let mut sizes = Vec::new();
        for m in &fig.marks {
            let (w, h) = root.estimate_text_size(&m.label, &font).map_err(e)?;
            sizes.push((w as i32, h as i32));
        }
        let boxes = layout_labels(
            &anchors,
            &sizes,
            (xr.start, xr.end),
            (yr.start, yr.end),
            fsi as i32,
        );
        for ((m, &(px, py)), &(l, t, w, h)) in fig.marks.iter().zip(&anchors).zip(&boxes) {
            // Leader from the marker to the nearest corner of a displaced label.
            let near_y = if t > py { t } else { t + h };
            if (near_y - py).abs() > h + fsi as i32 {
                root.draw(&PathElement::new(
                    vec![(px, py), (l, near_y)],
                    mc.mix(0.6).stroke_width(1),
                ))
                .map_err(e)?;
            }
            root.draw(&Rectangle::new(
                [(l - 2, t - 1), (l + w + 2, t + h + 1)],
                WHITE.mix(0.8).filled(),
            ))
            .map_err(e)?;
            root.draw(&Text::new(m.label.clone(), (l, t), font.clone()))
                .map_err(e)?;
        }
    }

    chart
        .configure_series_labels()
        .label_font(("sans-serif", 0.85 * fs).into_font())
        .legend_area_size(2 * fsi + fsi / 2)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .position(if fig.guides.is_empty() {
            SeriesLabelPosition::UpperRight
        } else {
            SeriesLabelPosition::LowerRight
        })
        .draw()
        .map_err(e)?;
    Ok(())
}

/// Place text boxes (`sizes`, pixels) near their anchors inside the plot box `xr` × `yr`
/// without overlapping each other: above-right of the anchor, moved up (or, at the top,
/// down) a line at a time until free, never over a marker. Returns (left, top, width, height) per label.
fn layout_labels(
    anchors: &[(i32, i32)],
    sizes: &[(i32, i32)],
    xr: (i32, i32),
    yr: (i32, i32),
    gap: i32,
) -> Vec<(i32, i32, i32, i32)> {
    let mut order: Vec<usize> = (0..anchors.len()).collect();
    order.sort_by_key(|&i| (anchors[i].0, -anchors[i].1));
    // The markers themselves (radius ~gap/2) must stay visible.
    let r = gap / 2;
    let mut placed: Vec<(i32, i32, i32, i32)> = anchors
        .iter()
        .map(|&(x, y)| (x - r, y - r, 2 * r, 2 * r))
        .collect();
    let mut out = vec![(0, 0, 0, 0); anchors.len()];
    let overlaps = |a: &(i32, i32, i32, i32), b: &(i32, i32, i32, i32)| {
        a.0 < b.0 + b.2 + 4 && b.0 < a.0 + a.2 + 4 && a.1 < b.1 + b.3 + 2 && b.1 < a.1 + a.3 + 2
    };
    for i in order {
        let (px, py) = anchors[i];
        let (w, h) = sizes[i];
        let mut l = px + gap / 2;
        if l + w > xr.1 {
            l = (px - gap / 2 - w).max(xr.0);
        }
        let step = h + 3;
        let free = |t: i32, placed: &[(i32, i32, i32, i32)]| {
            let b = (l, t, w, h);
            !placed.iter().any(|p| overlaps(&b, p))
        };
        let mut t = py - gap / 2 - h;
        // Upwards first, then downwards below the anchor.
        let mut found = None;
        while t >= yr.0 {
            if free(t, &placed) {
                found = Some(t);
                break;
            }
            t -= step;
        }
        if found.is_none() {
            t = py + gap / 2;
            while t + h <= yr.1 {
                if free(t, &placed) {
                    found = Some(t);
                    break;
                }
                t += step;
            }
        }
        let t = found.unwrap_or((py - gap / 2 - h).max(yr.0));
        placed.push((l, t, w, h));
        out[i] = (l, t, w, h);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_formats() {
        assert_eq!(fmt_num(3.0), "3");
        assert_eq!(fmt_num(0.123456), "0.1235");
        assert_eq!(fmt_num(2e9), "2e9");
        assert_eq!(fmt_num(-12.5), "-12.5");
        assert_eq!(fmt_tick(0.30000000000000004), "0.3");
        assert_eq!(fmt_tick(1e-15), "0");
        assert_eq!(fmt_tick(2.5e7), "2.5e7");
    }

    #[test]
    fn parse_options() {
        assert_eq!(parse_pair("10, 1.5").unwrap(), (10.0, 1.5));
        assert!(parse_pair("10").is_err());
        assert_eq!(parse_size("800x600").unwrap(), (800, 600));
        assert!(parse_size("800").is_err());
        assert!(ImageFormat::from_path(Path::new("a.pdf")).is_err());
        assert_eq!(
            ImageFormat::from_path(Path::new("a.PNG")).unwrap(),
            ImageFormat::Png
        );
    }

    #[test]
    fn labels_do_not_overlap() {
        // Five crossings a few pixels apart, as in a Campbell diagram at low speed.
        let anchors: Vec<(i32, i32)> = (0..5).map(|i| (100 + 8 * i, 300 - 3 * i)).collect();
        let sizes = vec![(90, 14); 5];
        let b = layout_labels(&anchors, &sizes, (50, 900), (40, 560), 16);
        for i in 0..5 {
            assert!(b[i].1 >= 40 && b[i].1 + b[i].3 <= 560);
            for j in 0..i {
                let (p, q) = (b[i], b[j]);
                let apart =
                    p.0 >= q.0 + q.2 || q.0 >= p.0 + p.2 || p.1 >= q.1 + q.3 || q.1 >= p.1 + p.3;
                assert!(apart, "{p:?} overlaps {q:?}");
            }
        }
    }
}
