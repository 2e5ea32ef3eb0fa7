//! Resource limits, checked from the sizes a model and a command imply before anything of
//! that size is allocated.
//!
//! The defaults keep a mistyped number (`--set elements=1e9`, `dt = 1e-12` with every
//! step written out, `--vary omega=1:2:100000000`) from taking the machine's memory; they
//! are far above what the shipped models need. A real model that needs more raises them
//! with the environment variable `LATDYN_LIMITS`, a comma-separated list of `KEY=VALUE`
//! (`LATDYN_LIMITS=elements=4e6,output_values=1e9`). Keys: see [`KEYS`].
//!
//! Not raisable, because no real input comes near them: the length and nesting depth of
//! an expression (see `expr`) and the number of worker threads (see [`max_threads`]).

use std::io::Read;
use std::path::Path;

/// Name of the environment variable that raises (or lowers) the limits.
pub const ENV: &str = "LATDYN_LIMITS";

/// The keys `LATDYN_LIMITS` accepts, with what each one bounds.
pub const KEYS: [(&str, &str); 7] = [
    (
        "model_bytes",
        "size of a model file or a --variants CSV file in bytes",
    ),
    ("elements", "beam elements of a model (all beams together)"),
    ("dofs", "coordinates (degrees of freedom) of a model"),
    (
        "output_values",
        "sensor values a run or campaign keeps: output samples × (sensor components + 1 for \
         the time) × variants",
    ),
    (
        "variants",
        "variants of a sweep (--vary grid × --variants rows) or values of `modes --vary`",
    ),
    (
        "steps",
        "time steps of one run, t_end / dt (each run that `--accuracy` makes, too)",
    ),
    (
        "dense_bytes",
        "bytes of the dense matrices of `modes` and of a steady start (`[initial] steady`): \
         8 n×n f64 matrices, 16 for rotating-frame modes (n = free coordinates)",
    ),
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    pub model_bytes: u64,
    pub elements: u64,
    pub dofs: u64,
    pub output_values: u64,
    pub variants: u64,
    pub steps: u64,
    pub dense_bytes: u64,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            // a generated model of 100 000 explicit nodes is about 10 MB of TOML
            model_bytes: 64 << 20,
            // compiling and solving take about 27 kB per element (`run` of the spin-up
            // beam on 20 000 and 40 000 elements: 0.90 and 1.45 GB, session 48; a probe
            // measured `statics` and `run` on 100 000 at 2.75 and 2.98 GB): at 1e6 that is
            // 27 GB, more than this machine class's 24 GiB, and the allocator aborted a
            // model under the limit. So the limit is also held to what the memory holds at
            // `BYTES_PER_UNIT` (about 900 000 elements in 24 GiB)
            elements: 1_000_000u64.min(memory_cap("elements").unwrap_or(u64::MAX)),
            // 6 per node plus bodies and hinges: the element limit with room to spare
            dofs: 10_000_000,
            // 8 bytes each in the file, and more in memory while a run keeps its history
            output_values: 100_000_000,
            // each variant is a compiled model held in memory for the campaign
            variants: 100_000,
            // time, not memory: a step of the smallest model costs about 10 µs, so this is
            // about 20 minutes of the smallest and hours of a shipped one; the largest
            // shipped run (a reference at dt = 7.8e-6 over 12 s) takes 1.5e6. `dt = 1e-12`
            // typed for 1e-2 must not start a run that never ends.
            steps: 100_000_000,
            // memory grows as n² and time as n³ (3564 coordinates, the 18-bay Mini-Mast,
            // take about 8 minutes): 5792 coordinates at rest, 4096 in the rotating frame
            dense_bytes: 2 << 30,
        }
    }
}

impl Limits {
    /// The defaults with the values of `LATDYN_LIMITS` applied.
    pub fn from_env() -> Result<Limits, String> {
        match std::env::var(ENV) {
            Ok(s) => Limits::parse(&s),
            Err(std::env::VarError::NotPresent) => Ok(Limits::default()),
            Err(e) => Err(format!("{ENV}: {e}")),
        }
    }

    /// The defaults with `KEY=VALUE,...` applied (VALUE a positive integer, `1e6` allowed).
    pub fn parse(s: &str) -> Result<Limits, String> {
        let mut l = Limits::default();
        let mut seen: Vec<&str> = Vec::new();
        for item in s.split(',').map(str::trim).filter(|x| !x.is_empty()) {
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| format!("{ENV}: expected KEY=VALUE, got `{item}`"))?;
            let (k, v) = (k.trim(), v.trim());
            // which of two values was meant is not for us to guess
            if seen.contains(&k) {
                return Err(format!("{ENV}: key `{k}` is given twice"));
            }
            seen.push(k);
            let x: f64 = v
                .parse()
                .map_err(|_| format!("{ENV}: {k}: `{v}` is not a number"))?;
            if !(x >= 1.0 && x.fract() == 0.0 && x <= 1e18) {
                return Err(format!(
                    "{ENV}: {k}: must be a whole number from 1 to 1e18, is {v}"
                ));
            }
            // a value raised past what this machine's memory can hold is held to that (the
            // allocation would abort the program instead of failing with a message)
            let x = (x as u64).min(memory_cap(k).map_or(u64::MAX, |c| c.max(default_of(k))));
            match k {
                "model_bytes" => l.model_bytes = x,
                "elements" => l.elements = x,
                "dofs" => l.dofs = x,
                "output_values" => l.output_values = x,
                "variants" => l.variants = x,
                "steps" => l.steps = x,
                "dense_bytes" => l.dense_bytes = x,
                _ => {
                    let keys: Vec<&str> = KEYS.iter().map(|(k, _)| *k).collect();
                    return Err(format!(
                        "{ENV}: unknown key `{k}` (keys: {})",
                        keys.join(", ")
                    ));
                }
            }
        }
        Ok(l)
    }
}

/// Bytes of memory one unit of each memory-bound key takes, for [`memory_cap`]. An
/// element 28 kB, as measured (see [`Limits::default`]; until session 48 a lower bound
/// of 4 kB, which let a default-limited model abort in the allocator); the others lower
/// bounds, so that the cap stops only what cannot fit (values a thousand times too
/// large), not a large model that might run with swap: a coordinate 500 bytes; an output
/// value 8 bytes (its f64); a variant 4 kB (a compiled model is far larger); a byte of a
/// dense matrix or of a model file, itself.
const BYTES_PER_UNIT: [(&str, u64); 6] = [
    ("elements", 28_000),
    ("dofs", 500),
    ("output_values", 8),
    ("variants", 4_096),
    ("dense_bytes", 1),
    ("model_bytes", 1),
];

/// This machine's memory in bytes (`MemTotal` of /proc/meminfo), if it can be read.
pub fn memory_bytes() -> Option<u64> {
    static MEM: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    *MEM.get_or_init(|| {
        let text = std::fs::read_to_string("/proc/meminfo").ok()?;
        let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        kb.checked_mul(1024)
    })
}

/// The most of `key` this machine's memory can hold ([`BYTES_PER_UNIT`]), if the key is
/// memory-bound and the memory is known. `LATDYN_LIMITS` cannot raise a limit past it (a
/// model that large would make the allocator abort); a default above it stays.
pub fn memory_cap(key: &str) -> Option<u64> {
    Some(memory_bytes()? / bytes_per_unit(key)?)
}

fn bytes_per_unit(key: &str) -> Option<u64> {
    BYTES_PER_UNIT.iter().find(|(k, _)| *k == key).map(|p| p.1)
}

fn default_of(key: &str) -> u64 {
    let d = Limits::default();
    match key {
        "model_bytes" => d.model_bytes,
        "elements" => d.elements,
        "dofs" => d.dofs,
        "output_values" => d.output_values,
        "variants" => d.variants,
        "steps" => d.steps,
        "dense_bytes" => d.dense_bytes,
        _ => u64::MAX,
    }
}

/// The message for a quantity over its limit: what, how much, the limit, how to raise it.
/// `value` is an f64 so that sizes beyond any integer type (1e300 samples) print as they are.
/// A limit that `LATDYN_LIMITS` raised to the machine's memory ([`memory_cap`]) says so.
pub fn exceeded(what: &str, value: f64, key: &str, limit: u64) -> String {
    if memory_cap(key) == Some(limit) && (limit != default_of(key) || key == "elements") {
        let per = bytes_per_unit(key).unwrap_or(1);
        return format!(
            "{what}: {} exceeds what this machine's memory ({:.1} GiB) can hold, about \
             {limit}{} (LATDYN_LIMITS key `{key}` is held to that)",
            count(value),
            memory_bytes().unwrap_or(0) as f64 / f64::from(1u32 << 30),
            if per > 1 {
                format!(" at {per} bytes each")
            } else {
                String::new()
            },
        );
    }
    format!(
        "{what}: {} exceeds the limit of {limit} (set by {ENV}, key `{key}`; if you \
         really need more, raise it, e.g. {ENV}={key}={})",
        count(value),
        limit.saturating_mul(10)
    )
}

/// A count for messages: exact below 1e15, else in scientific notation.
pub fn count(x: f64) -> String {
    if x.abs() < 1e15 {
        format!("{}", x as u64)
    } else {
        format!("{x:e}")
    }
}

/// Reads a text file of at most `cap` bytes, refusing anything that is not a regular file
/// (a device such as /dev/zero, a FIFO, a directory) before opening it, so that neither
/// an endless stream nor a blocking open can hang the program.
pub fn read_capped(path: &Path, cap: u64, what: &str) -> Result<String, String> {
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read {what}: {e}"))?;
    if !meta.is_file() {
        return Err(format!(
            "cannot read {what}: not a regular file ({})",
            file_kind(&meta)
        ));
    }
    if meta.len() > cap {
        return Err(exceeded(
            &format!("{what} size in bytes"),
            meta.len() as f64,
            "model_bytes",
            cap,
        ));
    }
    let f = std::fs::File::open(path).map_err(|e| format!("cannot read {what}: {e}"))?;
    let mut bytes = Vec::new();
    // the file may grow between the size check and the read: never read past the cap
    f.take(cap + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read {what}: {e}"))?;
    if bytes.len() as u64 > cap {
        return Err(exceeded(
            &format!("{what} size in bytes"),
            bytes.len() as f64,
            "model_bytes",
            cap,
        ));
    }
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        // where an editor shows it (a probe in session 48: the byte offset alone)
        let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
        let start = bytes[..at]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |k| k + 1);
        let column = 1 + String::from_utf8_lossy(&bytes[start..at]).chars().count();
        format!(
            "cannot read {what}: not UTF-8 text: line {line}, column {column}: invalid byte \
             0x{:02x} (byte offset {at}); save the file as UTF-8",
            bytes[at]
        )
    })
}

/// An input file that must be a regular file, checked before it is opened: opening a FIFO
/// blocks until a writer comes (`plot` of a FIFO hung, session 48), and a device or a
/// directory is no results file. "no such file" where nothing is there.
pub fn regular_input(path: &Path) -> Result<(), String> {
    match std::fs::metadata(path) {
        Ok(meta) if meta.is_file() => Ok(()),
        Ok(meta) => Err(format!("is {}, not a regular file", file_kind(&meta))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err("no such file".into()),
        Err(e) => Err(format!("cannot read it: {e}")),
    }
}

fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

/// Most worker threads a campaign may ask for: 4 per core, at least 256. More only costs
/// memory and scheduling; 100 000 threads made the machine unresponsive.
pub fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (4 * cores).max(256)
}

/// Parses a `--threads` value: a whole number from 1 to [`max_threads`].
pub fn parse_threads(s: &str) -> Result<usize, String> {
    let n: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a whole number of threads"))?;
    let max = max_threads();
    if n == 0 {
        return Err("must be at least 1 (leave --threads out to use every core)".to_string());
    }
    if n > max {
        return Err(format!(
            "{n} threads exceed the limit of {max} (4 per core, at least 256)"
        ));
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A limit raised far past the machine is held to its memory, and the message says
    /// so instead of inviting a larger value (before, the allocation aborted the program).
    #[test]
    fn limits_raised_past_the_machines_memory_are_held_to_it() {
        let Some(mem) = memory_bytes() else {
            eprintln!("skipped: /proc/meminfo not readable");
            return;
        };
        let l = Limits::parse("elements=1e18,dense_bytes=1e18,output_values=1e18").unwrap();
        // (the element default is itself held to the memory since session 48)
        assert_eq!(l.elements, mem / 28_000);
        assert_eq!(l.dense_bytes, mem.max(Limits::default().dense_bytes));
        assert_eq!(
            l.output_values,
            (mem / 8).max(Limits::default().output_values)
        );
        // (on a machine under 4 GB the cap is below the default, which then stays)
        if l.elements != Limits::default().elements {
            let m = exceeded("beam elements", 1e12, "elements", l.elements);
            assert!(m.contains("this machine's memory"), "{m}");
        }
        // the defaults' messages invite a raise, but for an element default held to the
        // memory, which names the memory
        let m = exceeded("variants", 1e12, "variants", Limits::default().variants);
        assert!(m.contains("raise it"), "{m}");
        let m = exceeded(
            "beam elements",
            1e12,
            "elements",
            Limits::default().elements,
        );
        match Limits::default().elements < 1_000_000 {
            true => assert!(m.contains("this machine's memory"), "{m}"),
            false => assert!(m.contains("raise it"), "{m}"),
        }
    }

    #[test]
    fn env_syntax_and_errors() {
        let l = Limits::parse("elements=2e6, variants=5").unwrap();
        assert_eq!(l.variants, 5);
        // (held to the memory only on a machine under 8 GB)
        if memory_cap("elements").is_none_or(|c| c >= 2_000_000) {
            assert_eq!(l.elements, 2_000_000);
        }
        assert_eq!(l.dofs, Limits::default().dofs);
        let l = Limits::parse("dense_bytes=1e5").unwrap();
        assert_eq!(l.dense_bytes, 100_000);
        assert_eq!(Limits::default().dense_bytes, 2 << 30);
        assert!(Limits::parse("dense=5")
            .unwrap_err()
            .contains("dense_bytes"));
        assert!(Limits::parse("elements").unwrap_err().contains("KEY=VALUE"));
        assert!(Limits::parse("elems=5")
            .unwrap_err()
            .contains("unknown key"));
        assert!(Limits::parse("elements=0").is_err());
        assert!(Limits::parse("elements=1.5").is_err());
        assert!(Limits::parse("elements=nan").is_err());
        // a key given twice was decided silently by the last one
        assert!(Limits::parse("elements=5, elements=7")
            .unwrap_err()
            .contains("key `elements` is given twice"));
    }

    #[test]
    fn threads_are_bounded() {
        assert!(parse_threads("0").unwrap_err().contains("at least 1"));
        assert_eq!(parse_threads("3"), Ok(3));
        assert!(parse_threads("100000").unwrap_err().contains("limit"));
        assert!(parse_threads("-1").is_err());
    }

    #[test]
    fn non_regular_files_are_refused_unread() {
        let e = read_capped(Path::new("/dev/zero"), 1 << 20, "model file").unwrap_err();
        assert!(e.contains("character device"), "{e}");
        let e = read_capped(Path::new("/"), 1 << 20, "model file").unwrap_err();
        assert!(e.contains("directory"), "{e}");
    }
}
