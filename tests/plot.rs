//! The `plot` verb: charts of a campaign file written with `CampaignWriter`, as SVG and
//! PNG, and its error messages (`campbell_crossings` itself: tests/frequency.rs).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use latdyn::frequency::campbell_crossings;
use latdyn::output::{CampaignMeta, CampaignWriter, SensorMeta, VariantState, VariantStatus};

/// Southwell data of the Campbell campaign: ω² = W0² + K·Ω² (rad/s).
const W0: f64 = 20.0;
const K: f64 = 1.5;

fn dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("plot");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn out(name: &str) -> PathBuf {
    let p = dir().join(name);
    let _ = std::fs::remove_file(&p);
    p
}

fn latdyn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run latdyn")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A campaign over `omegas` (rad/s): sensors `tip` (x, z in m) and `moment` (my in N·m)
/// over 0..2 s, sine-like at each variant's omega; `/derived/first_bending_hz` from the
/// Southwell law. With `fail_last`, the last variant fails half-way (NaN afterwards).
fn write_campaign(path: &Path, omegas: &[f64], fail_last: bool) {
    let n_t = 201;
    let time: Vec<f64> = (0..n_t).map(|i| 0.01 * i as f64).collect();
    let meta = CampaignMeta {
        command_line: "latdyn sweep models/rotor.toml -o campaign.h5".into(),
        model_path: "models/rotor.toml".into(),
        model_source: "# rotor\n".into(),
        backend: "cpu".into(),
        precision: "f64".into(),
        adapter: String::new(),
        threads: 1,
        parameter_names: vec!["omega".into(), "L".into()],
        parameter_values: omegas.iter().map(|&w| vec![w, 2.0]).collect(),
        global_index: Vec::new(),
        time: time.clone(),
        sensors: vec![
            SensorMeta {
                name: "tip".into(),
                components: vec!["x".into(), "z".into()],
                units: vec!["m".into(), "m".into()],
            },
            SensorMeta {
                name: "moment".into(),
                components: vec!["my".into()],
                units: vec!["N·m".into()],
            },
        ],
    };
    let mut w = CampaignWriter::create(path, &meta).unwrap();
    let nv = omegas.len();
    for (v, &om) in omegas.iter().enumerate() {
        let failed = fail_last && v + 1 == nv;
        let n_written = if failed { n_t / 2 } else { n_t };
        let wf = 2.0 + om; // response frequency, rad/s
        for (i, &t) in time.iter().enumerate().take(n_written) {
            let z = 0.1 * (wf * t).sin() * (-0.3 * t).exp();
            let x = 1.0 - 0.01 * (wf * t).cos();
            w.write_samples(v, i, &[vec![x, z], vec![-250.0 * z + 2.0 * (wf * t).cos()]])
                .unwrap();
        }
        let state = if failed {
            VariantState::Failed
        } else {
            VariantState::Completed
        };
        w.set_status(
            v,
            &VariantStatus {
                state,
                ..Default::default()
            },
        )
        .unwrap();
        let f = (W0 * W0 + K * om * om).sqrt() / std::f64::consts::TAU;
        w.set_derived("first_bending_hz", v, f).unwrap();
    }
    w.finish("complete").unwrap();
}

/// Small campaign: omega = 1, 2, 3; the last variant failed half-way. One file per test
/// (`name`): the tests run in parallel.
fn small(name: &str) -> PathBuf {
    let p = out(&format!("{name}.h5"));
    write_campaign(&p, &[1.0, 2.0, 3.0], true);
    p
}

/// Campbell campaign: omega = 0, 5, …, 40 rad/s.
fn campbell_file() -> (PathBuf, Vec<f64>) {
    campbell_file_named("campbell.h5")
}

/// [`campbell_file`] under another name (the tests run in parallel).
fn campbell_file_named(name: &str) -> (PathBuf, Vec<f64>) {
    let omegas: Vec<f64> = (0..9).map(|i| 5.0 * i as f64).collect();
    let p = out(name);
    write_campaign(&p, &omegas, false);
    (p, omegas)
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "latdyn failed ({}):\n{}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Exit code 2 and `needles` in the message.
fn fails(o: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "expected exit 2, stderr:\n{err}");
    assert!(err.contains("error:"), "{err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks {n:?}:\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
}

/// An SVG file with these texts.
fn check_svg(p: &Path, texts: &[&str]) -> String {
    let text = std::fs::read_to_string(p).unwrap();
    assert!(text.contains("<svg"), "{}: not SVG", p.display());
    assert!(
        text.len() > 2000,
        "{}: {} bytes only",
        p.display(),
        text.len()
    );
    for t in texts {
        assert!(text.contains(t), "{} lacks {t:?}", p.display());
    }
    text
}

/// A PNG file that decodes to the expected size and is not blank.
fn check_png(p: &Path, size: (u32, u32)) {
    let bytes = std::fs::read(p).unwrap();
    assert!(
        bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
        "{}: no PNG signature",
        p.display()
    );
    assert!(
        bytes.len() > 5000,
        "{}: {} bytes only",
        p.display(),
        bytes.len()
    );
    let dec = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), size);
    let px = &buf[..info.buffer_size()];
    let dark = px.chunks(3).filter(|c| c.iter().all(|&v| v < 100)).count();
    let colored = px
        .chunks(3)
        .filter(|c| c.iter().max().unwrap() - c.iter().min().unwrap() > 80)
        .count();
    assert!(
        dark > 500,
        "{}: too little text/axes ({dark} dark px)",
        p.display()
    );
    assert!(
        colored > 500,
        "{}: no coloured lines ({colored} px)",
        p.display()
    );
}

#[test]
fn sensor_time_histories() {
    let h5 = small("sensor_time_histories");
    for ext in ["svg", "png"] {
        let img = out(&format!("sensor.{ext}"));
        let o = latdyn(&["plot", s(&h5), "--sensor", "tip.z", "-o", s(&img)]);
        ok(&o);
        if ext == "svg" {
            let t = check_svg(
                &img,
                &[
                    "t [s]",
                    "tip.z [m]",
                    "omega=1",
                    "omega=3 (failed)",
                    "models/rotor.toml",
                ],
            );
            // L is the same in every variant: not in the legend.
            assert!(!t.contains("L=2"));
        } else {
            check_png(&img, (1000, 640));
        }
    }

    // All components of a sensor plus another sensor, two variants, JSON summary.
    let img = out("sensors2.svg");
    let o = latdyn(&[
        "plot",
        s(&h5),
        "--sensor",
        "tip",
        "--sensor",
        "moment.my",
        "--variants",
        "0,2",
        "--json",
        "-o",
        s(&img),
        "--title",
        "two sensors",
    ]);
    ok(&o);
    check_svg(
        &img,
        &[
            "tip.x, tip.z [m]; moment.my [N·m]",
            "tip.x: omega=1",
            "moment.my: omega=3",
            "two sensors",
        ],
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["lines"].as_array().unwrap().len(), 6, "{v}");

    // A different size, to PNG.
    let img = out("sensor_small.png");
    ok(&latdyn(&[
        "plot",
        s(&h5),
        "--sensor",
        "moment",
        "--size",
        "640x400",
        "-o",
        s(&img),
    ]));
    check_png(&img, (640, 400));
}

#[test]
fn cross_plot() {
    let h5 = small("cross_plot");
    for ext in ["svg", "png"] {
        let img = out(&format!("phase.{ext}"));
        ok(&latdyn(&[
            "plot",
            s(&h5),
            "--x",
            "tip.z",
            "--y",
            "moment.my",
            "-o",
            s(&img),
        ]));
        if ext == "svg" {
            check_svg(&img, &["tip.z [m]", "moment.my [N·m]", "omega=2"]);
        } else {
            check_png(&img, (1000, 640));
        }
    }
}

#[test]
fn campbell_diagram() {
    let (h5, omegas) = campbell_file();
    let img = out("campbell.svg");
    let o = latdyn(&[
        "plot",
        s(&h5),
        "--campbell",
        "omega",
        "--derived",
        "first_bending_hz",
        "--southwell",
        "20,1.5",
        "--json",
        "-o",
        s(&img),
    ]);
    ok(&o);
    check_svg(
        &img,
        &[
            "omega [rad/s]",
            "first_bending_hz [rad/s]",
            "1Ω",
            "6Ω",
            "3Ω @ Ω=",
            "Southwell",
            "Campbell",
        ],
    );

    // The crossings on stdout are those of the library function on the same points.
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    let got: Vec<(usize, f64)> = v["crossings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["harmonic"].as_u64().unwrap() as usize,
                c["omega"].as_f64().unwrap(),
            )
        })
        .collect();
    let y: Vec<f64> = omegas
        .iter()
        .map(|&w| (W0 * W0 + K * w * w).sqrt())
        .collect();
    let want = campbell_crossings(&omegas, &y, 6);
    assert_eq!(got.len(), want.len(), "{v}");
    for ((n, a), (m, b)) in got.iter().zip(&want) {
        assert_eq!(n, m);
        assert!((a - b).abs() < 1e-9 * b.abs().max(1.0), "{a} vs {b}");
    }
    // n = 2..6 cross once each, near the exact Ω = W0/sqrt(n² - K); 1Ω never does.
    let ns: Vec<usize> = got.iter().map(|c| c.0).collect();
    assert_eq!(ns, [2, 3, 4, 5, 6]);
    for &(n, om) in &got {
        let exact = W0 / ((n * n) as f64 - K).sqrt();
        assert!(
            (om - exact).abs() < 0.1 * exact,
            "{n}Ω at {om}, exact {exact}"
        );
    }
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("crossing: 2Ω at omega ="), "{err}");

    // In Hz, to PNG; same crossings.
    let img = out("campbell_hz.png");
    let o = latdyn(&[
        "plot",
        s(&h5),
        "--campbell",
        "omega",
        "--derived",
        "first_bending_hz",
        "--units",
        "hz",
        "--json",
        "-o",
        s(&img),
    ]);
    ok(&o);
    check_png(&img, (1000, 640));
    let v2: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v2["crossings"].as_array().unwrap().len(), 5);
    let img = out("campbell_hz.svg");
    ok(&latdyn(&[
        "plot",
        s(&h5),
        "--campbell",
        "omega",
        "--derived",
        "first_bending_hz",
        "--units",
        "hz",
        "-o",
        s(&img),
    ]));
    check_svg(&img, &["first_bending_hz [Hz]", "2Ω @ Ω="]);
}

#[test]
fn errors_are_clear_and_exit_2() {
    let h5 = small("errors_are_clear_and_exit_2");
    let img = out("never.svg");
    let _ = std::fs::remove_file(&img);
    let hs = s(&h5);
    fails(
        &latdyn(&["plot", "no/such/file.h5", "--sensor", "tip", "-o", s(&img)]),
        &["no/such/file.h5", "no such file"],
    );
    fails(
        &latdyn(&["plot", hs, "--sensor", "tipp", "-o", s(&img)]),
        &["no sensor \"tipp\"", "sensors: moment, tip"],
    );
    fails(
        &latdyn(&["plot", hs, "--sensor", "tip.q", "-o", s(&img)]),
        &["no component \"q\"", "components: x, z"],
    );
    fails(
        &latdyn(&["plot", hs, "--x", "tip", "--y", "moment.my", "-o", s(&img)]),
        &["2 components", "tip.x, tip.z"],
    );
    fails(
        &latdyn(&["plot", hs, "--sensor", "tip.z", "-o", "out.pdf"]),
        &[".svg or .png"],
    );
    fails(
        &latdyn(&[
            "plot",
            hs,
            "--sensor",
            "tip.z",
            "--variants",
            "0,7",
            "-o",
            s(&img),
        ]),
        &["no variant 7", "3 variants"],
    );
    fails(
        &latdyn(&[
            "plot",
            hs,
            "--campbell",
            "speed",
            "--derived",
            "first_bending_hz",
            "-o",
            s(&img),
        ]),
        &["no parameter \"speed\"", "omega, L"],
    );
    fails(
        &latdyn(&[
            "plot",
            hs,
            "--campbell",
            "omega",
            "--derived",
            "f2",
            "-o",
            s(&img),
        ]),
        &["no derived quantity \"f2\"", "first_bending_hz"],
    );
    fails(
        &latdyn(&[
            "plot",
            hs,
            "--campbell",
            "omega",
            "--derived",
            "first_bending_hz",
            "--southwell",
            "20",
            "-o",
            s(&img),
        ]),
        &["two numbers"],
    );
    // No kind of plot chosen, or two: clap's usage error (also exit 2).
    assert_eq!(latdyn(&["plot", hs, "-o", s(&img)]).status.code(), Some(2));
    assert_eq!(
        latdyn(&[
            "plot",
            hs,
            "--sensor",
            "tip",
            "--campbell",
            "omega",
            "--derived",
            "x",
            "-o",
            s(&img)
        ])
        .status
        .code(),
        Some(2)
    );
    // Not an HDF5 file.
    let bogus = out("bogus.h5");
    std::fs::write(&bogus, "not hdf5").unwrap();
    fails(
        &latdyn(&["plot", s(&bogus), "--sensor", "tip", "-o", s(&img)]),
        &["bogus.h5", "HDF5"],
    );
    assert!(!img.exists(), "no image is written on error");
}

#[test]
fn many_variants_are_thinned() {
    let p = out("many.h5");
    let omegas: Vec<f64> = (0..30).map(|i| i as f64).collect();
    write_campaign(&p, &omegas, false);
    let img = out("many.svg");
    let o = latdyn(&["plot", s(&p), "--sensor", "tip.z", "--json", "-o", s(&img)]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let lines = v["lines"].as_array().unwrap();
    assert_eq!(lines.len(), 20, "{v}");
    assert_eq!(lines[0], "omega=0");
    assert_eq!(lines[19], "omega=29");
    assert!(String::from_utf8_lossy(&o.stderr).contains("drawing 20 of 30 variants"));
    // Asking for more than 20 lines explicitly is an error.
    let all: Vec<String> = (0..21).map(|i| i.to_string()).collect();
    fails(
        &latdyn(&[
            "plot",
            s(&p),
            "--sensor",
            "tip.z",
            "--variants",
            &all.join(","),
            "-o",
            s(&img),
        ]),
        &["at most 20"],
    );
}

/// Charts follow the output policy of `run` and `sweep`: a symlink or a directory at the
/// path is refused (the link's target untouched), a missing directory fails, and a
/// successful chart leaves no drawing file or lock beside it.
#[test]
fn chart_outputs_follow_the_output_safety_policy() {
    let h5 = small("chart_output_policy");
    let d = dir().join("policy");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "keep me").unwrap();
    let link = d.join("link.svg");
    std::os::unix::fs::symlink(&victim, &link).unwrap();
    let o = latdyn(&["plot", s(&h5), "--sensor", "tip.z", "-o", s(&link)]);
    fails(&o, &["symbolic link"]);
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
    let sub = d.join("adir.png");
    std::fs::create_dir_all(&sub).unwrap();
    let o = latdyn(&["plot", s(&h5), "--sensor", "tip.z", "-o", s(&sub)]);
    fails(&o, &["directory"]);
    let missing = d.join("nodir").join("x.svg");
    let o = latdyn(&["plot", s(&h5), "--sensor", "tip.z", "-o", s(&missing)]);
    fails(&o, &["nodir"]);
    let good = d.join("good.svg");
    ok(&latdyn(&[
        "plot",
        s(&h5),
        "--sensor",
        "tip.z",
        "-o",
        s(&good),
    ]));
    check_svg(&good, &[]);
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["adir.png", "good.svg", "link.svg", "victim.txt"]);
}

/// `--harmonics` is bounded: 1e9 harmonics asked for 56 GB and aborted (exit 134).
#[test]
fn a_campbell_diagram_with_absurdly_many_harmonics_is_refused() {
    let o = latdyn(&[
        "plot",
        "nonexistent.h5",
        "--campbell",
        "omega",
        "--harmonics",
        "1000000000",
        "-o",
        "never.svg",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("from 1 to 100"), "{err}");
}

/// A `modes --vary` branch whose values go negative (a divergence: −s/2π, a growth rate)
/// leaves those values out of the Campbell chart and says so; the chart's axis starts at
/// 0, and they were drawn there as a flat 0 Hz branch (a probe, session 46).
#[test]
fn a_divergent_branch_is_left_out_of_the_campbell_chart_with_a_note() {
    let (h5, omegas) = campbell_file_named("campbell_divergent.h5");
    let freqs: Vec<f64> = omegas
        .iter()
        .map(|&w| {
            if (10.0..=20.0).contains(&w) {
                -1.5
            } else {
                3.0 + 0.1 * w
            }
        })
        .collect();
    let branches = serde_json::json!({
        "omega_rad_s": omegas,
        "branches": [{"branch": 1, "frequencies_hz": freqs, "damping_ratios": [], "mac": []}],
    });
    let modes = out("divergent_modes.json");
    std::fs::write(&modes, branches.to_string()).unwrap();
    let img = out("campbell_divergent.svg");
    let o = latdyn(&[
        "plot",
        s(&h5),
        "--campbell",
        "omega",
        "--derived",
        "first_bending_hz",
        "--modes",
        s(&modes),
        "-o",
        s(&img),
    ]);
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("3 values between omega = 10 and 20 are divergent"),
        "{err}"
    );
}

/// `plot` and `merge` refuse an input that is not a regular file before opening it:
/// opening a FIFO blocks until a writer comes (session 48's probe: `plot` hung on one),
/// and `merge` called /dev/zero "no such file".
#[test]
fn plot_and_merge_refuse_a_fifo_or_a_device_as_input_without_blocking() {
    let fifo = out("fifo.h5");
    let _ = std::fs::remove_file(&fifo);
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("skipped: mkfifo is not available");
        return;
    }
    let t0 = std::time::Instant::now();
    let o = latdyn(&[
        "plot",
        s(&fifo),
        "--sensor",
        "tip",
        "-o",
        s(&out("fifo.svg")),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("is a FIFO, not a regular file"), "{e}");
    let o = latdyn(&["merge", "/dev/zero", s(&fifo), "-o", s(&out("merged.h5"))]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("/dev/zero: is a character device"), "{e}");
    assert!(t0.elapsed().as_secs() < 20, "took {:?}", t0.elapsed());
    std::fs::remove_file(&fifo).ok();
}
