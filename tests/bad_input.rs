//! Broken model files must fail with a message naming the file, the line and the field.

use std::path::{Path, PathBuf};

use latdyn::model::{compile_str, load};

fn dir(sub: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(sub)
}

/// (file, line, field, part of the message)
const CASES: &[(&str, usize, &str, &str)] = &[
    (
        "missing_field.toml",
        20,
        "beams[0].section",
        "missing field",
    ),
    ("wrong_type.toml", 24, "beams[0].elements", "invalid type"),
    ("unknown_key.toml", 30, "supports[0].angle", "unknown field"),
    ("zero_length_beam.toml", 20, "beams[0].to", "zero-length"),
    (
        "negative_stiffness.toml",
        8,
        "sections.main.EIz",
        "must be > 0",
    ),
    (
        "undefined_parameter.toml",
        7,
        "sections.main.EIy",
        "undefined parameter `EI_y`",
    ),
    ("nan_value.toml", 10, "sections.main.rhoA", "NaN"),
    (
        "unknown_body.toml",
        39,
        "joints[0].body",
        "unknown body `hubb`",
    ),
    (
        "sensor_unknown_body.toml",
        30,
        "sensors[0].body",
        "unknown body `hub`",
    ),
    (
        "undefined_in_drive.toml",
        34,
        "bodies[0].dofs[0].drive",
        "undefined parameter `omega`",
    ),
    ("zero_hinge_axis.toml", 32, "joints[0].axis", "zero length"),
    (
        "inertia_not_pd.toml",
        30,
        "bodies[0].inertia",
        "inertia not positive definite",
    ),
    (
        "inertia_breaks_triangle_inequality.toml",
        30,
        "bodies[0].inertia",
        "break the triangle inequality",
    ),
    (
        "axes_not_perpendicular.toml",
        31,
        "bodies[0].axes",
        "not perpendicular: 84.2894° between them",
    ),
    ("dt_zero.toml", 29, "solver.dt", "must be > 0"),
    (
        "t_end_below_dt_min.toml",
        28,
        "solver.t_end",
        "below dt_min = 1e-9 s, the smallest step",
    ),
    (
        "steady_start_on_a_spin_up.toml",
        63,
        "initial.steady",
        "needs a body rotation driven at a constant rate",
    ),
    (
        "consistent_velocity_with_steady_start.toml",
        80,
        "initial.consistent_velocity",
        "strains nothing already",
    ),
    (
        "accuracy_below_newton_tolerance.toml",
        31,
        "solver.accuracy",
        "100 × the Newton tolerance",
    ),
    ("syntax_error.toml", 25, "section", "invalid basic string"),
    (
        "control_character_in_comment.toml",
        3,
        "parameters",
        "control character U+001B is not allowed",
    ),
];

/// A file that is not UTF-8 is located by line and column, not by its byte offset alone
/// (session 48's probe: 433 fuzzed mutants read "invalid byte at offset 400").
#[test]
fn a_model_that_is_not_utf8_is_located_by_line_and_column() {
    let d = std::env::temp_dir().join(format!("latdyn-utf8-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("latin1.toml");
    std::fs::write(&p, b"[parameters]\nL = 1.0\n# na\xefve comment\n").unwrap();
    let msg = load(&p, &[]).unwrap_err().to_string();
    assert!(
        msg.contains("latin1.toml") && msg.contains("line 3, column 5") && msg.contains("0xef"),
        "{msg}"
    );
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn every_broken_model_is_reported_with_file_line_and_field() {
    for &(file, line, field, problem) in CASES {
        let path = dir("tests/bad_models").join(file);
        let err = match load(&path, &[]) {
            Ok(_) => panic!("{file}: compiled, but is broken"),
            Err(e) => e,
        };
        let msg = err.to_string();
        assert!(msg.contains(file), "{file}: no file name in `{msg}`");
        assert!(
            msg.contains(&format!(".toml:{line}:")),
            "{file}: expected line {line} in `{msg}`"
        );
        assert!(
            msg.contains(field),
            "{file}: expected field `{field}` in `{msg}`"
        );
        assert!(
            msg.contains(problem),
            "{file}: expected `{problem}` in `{msg}`"
        );
        assert_eq!(err.line, Some(line), "{file}");
    }
}

#[test]
fn every_broken_model_file_has_a_case() {
    let mut files: Vec<String> = std::fs::read_dir(dir("tests/bad_models"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut cased: Vec<String> = CASES.iter().map(|c| c.0.to_string()).collect();
    cased.sort();
    assert_eq!(files, cased);
}

#[test]
fn missing_file_and_unknown_override() {
    let e = load(Path::new("no/such/model.toml"), &[]).unwrap_err();
    assert!(
        e.to_string().starts_with("no/such/model.toml: cannot read"),
        "{e}"
    );
    let good = dir("models/cantilever.toml");
    let e = load(&good, &[("Pz".to_string(), 1.0)]).unwrap_err();
    assert!(e.to_string().contains("`--set Pz`"), "{e}");
}

#[test]
fn example_models_compile_with_the_expected_sizes() {
    let m = load(&dir("models/cantilever.toml"), &[]).unwrap();
    assert_eq!(
        (m.x0.len(), m.elements.len(), m.dofs.len(), m.n_eq),
        (9, 8, 48, 48)
    );
    assert_eq!(m.sensors.len(), 2);
    let m = load(&dir("models/cantilever.toml"), &[("elements".into(), 16.0)]).unwrap();
    assert_eq!((m.x0.len(), m.elements.len(), m.n_eq), (17, 16, 96));
    let m = load(&dir("models/bend45.toml"), &[]).unwrap();
    assert_eq!((m.x0.len(), m.elements.len(), m.n_eq), (9, 8, 48));
    assert_eq!(m.loads[0].force, [0.0, 0.0, 600.0]);
}

#[test]
fn garbage_never_panics() {
    let samples = [
        "",
        "[[beams]]",
        "nodes = 3",
        "[parameters]\nx = { value = \"y\" }",
        "[parameters]\nmax_load = 1",
        "[[nodes]]\nname = \"\"\nposition = [0, 0]",
        "[[bodies]]\nname = \"b\"\ninertia = [1, [1, 2, 3], 3]",
        "[[bodies]]\nname = \"b\"\naxes = [[1, 0, 0], [2, 0, 0]]",
        "[solver]\nmax_iter = 2.5",
        "[[sensors]]\nname = \"e\"\ntype = \"energy\"\nnode = 3",
        "[[bodies]]\nname = \"b\"\nmass = 1\n[[bodies.dofs]]\ntype = \"rotation\"\naxis = [0, 0, 1]\ndrive = \"sqrt(t)\"",
    ];
    for s in samples {
        if let Err(e) = compile_str(s, "g.toml", &[]) {
            assert!(e.to_string().starts_with("g.toml"), "{e}");
        }
    }
}

fn latdyn(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_latdyn"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("LATDYN_LIMITS")
        .output()
        .expect("run latdyn")
}

fn temp(name: &str, text: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("latdyn_bad_{}_{name}", std::process::id()));
    std::fs::write(&p, text).unwrap();
    p
}

/// Success, and the `--json` result object.
fn json_ok(args: &[&str]) -> serde_json::Value {
    let out = latdyn(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {err}");
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Exit code 2 and stderr containing `part`; returns stderr.
fn usage_error(args: &[&str], part: &str) -> String {
    let out = latdyn(args);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(part), "{args:?}: expected `{part}` in: {err}");
    err
}

#[test]
fn a_model_without_beams_or_bodies_is_refused_by_every_verb() {
    // an empty file was "solved" by every verb with exit 0
    let empty = temp("empty.toml", "");
    let nodes_only = temp(
        "nodes_only.toml",
        "[parameters]\nL = 1\n[[nodes]]\nname = \"a\"\nposition = [0, 0, 0]\n",
    );
    for p in [&empty, &nodes_only] {
        let p = p.to_str().unwrap();
        for verb in ["check", "statics", "modes", "run"] {
            usage_error(&[verb, p], "model defines nothing to simulate");
        }
    }
}

#[test]
fn vary_and_variants_name_each_parameter_once_and_errors_name_their_flag() {
    let m = "models/rotating_cantilever.toml";
    // the second range silently replaced the first
    let e = usage_error(
        &["sweep", m, "--vary", "omega=1:2:2", "--vary", "omega=3:4:2"],
        "--vary omega: given twice",
    );
    assert!(
        e.contains("omega=1:2:2") && e.contains("omega=3:4:2"),
        "{e}"
    );
    let dup = temp("dup.csv", "omega,EI,omega\n1,2,3\n");
    usage_error(
        &["sweep", m, "--variants", dup.to_str().unwrap()],
        "column `omega` appears twice in the header (columns 1 and 3)",
    );
    let one = temp("one.csv", "omega\n1\n");
    usage_error(
        &[
            "sweep",
            m,
            "--variants",
            one.to_str().unwrap(),
            "--vary",
            "omega=1:2:2",
        ],
        "--vary omega and --variants",
    );
    // these said `--set`
    let e = usage_error(
        &["sweep", m, "--vary", "omegax=1:2:2"],
        "--vary omegax: the model has no parameter",
    );
    assert!(!e.contains("--set"), "{e}");
    let e = usage_error(
        &["modes", m, "--vary", "omegax=1:2:2"],
        "--vary omegax: the model has no parameter",
    );
    assert!(!e.contains("--set"), "{e}");
    let unk = temp("unk.csv", "omegay\n1\n");
    let e = usage_error(
        &["sweep", m, "--variants", unk.to_str().unwrap()],
        "column `omegay`: the model has no parameter",
    );
    assert!(!e.contains("--set"), "{e}");
    let nan = temp("nan.csv", "omega\nNaN\n");
    usage_error(
        &["sweep", m, "--variants", nan.to_str().unwrap()],
        "`NaN` is not a finite number",
    );
}

#[test]
fn each_error_is_printed_once() {
    // a model error inside a sweep, and an output error, were printed two or three times
    let e = usage_error(
        &[
            "sweep",
            "tests/bad_models/dt_zero.toml",
            "--vary",
            "dt=1:2:2",
        ],
        "must be > 0",
    );
    assert_eq!(e.matches("must be > 0").count(), 1, "{e}");
    let e = usage_error(&["check", "no/such/model.toml"], "cannot read model file");
    assert_eq!(e.matches("No such file").count(), 1, "{e}");
}

#[test]
fn nested_two_argument_functions_parse_in_models() {
    // `max(0, min(t, 2 - t))` failed with "parentheses mismatch"
    let text = std::fs::read_to_string(dir("models/cantilever.toml"))
        .unwrap()
        .replace(
            "elements = 8",
            "elements = \"max(2, min(8, 2*5 - 1))\"\nclip = \"atan2(1, max(1, min(3, 4)))\"",
        );
    let m = compile_str(&text, "nest.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.param("elements"), Some(8.0));
    assert_eq!(m.param("clip"), Some(1f64.atan2(3.0)));
    assert_eq!(m.elements.len(), 8);
}

#[test]
fn expression_errors_are_located_without_library_internals() {
    let text = std::fs::read_to_string(dir("models/cantilever.toml"))
        .unwrap()
        .replace("elements = 8", "elements = \"2 sin(1)\"");
    let e = compile_str(&text, "bad.toml", &[]).unwrap_err().to_string();
    assert!(
        e.starts_with("bad.toml:14:12: field `parameters.elements`"),
        "{e}"
    );
    assert!(
        e.contains("missing operator before `sin` at character 3"),
        "{e}"
    );
    // exmex's own messages append its tokens in Debug form (operators as structs of
    // function pointers)
    assert!(!e.contains("left:") && !e.contains("0x"), "{e}");
}

#[test]
fn mini_mast_bay_count_outside_one_to_eighteen_is_refused_at_its_parameter() {
    usage_error(
        &["check", "models/minimast.toml", "--set", "bays=0"],
        "models/minimast.toml:54:1: field `parameters.bays`: is 0, below its minimum 1 (--set bays=0)",
    );
    usage_error(
        &["run", "models/minimast.toml", "--set", "bays=19", "--json"],
        "is 19, above its maximum 18",
    );
    usage_error(
        &["check", "models/minimast.toml", "--set", "bays=2.5"],
        "must be a whole number, is 2.5",
    );
    let out = latdyn(&["check", "models/minimast.toml", "--set", "bays=18"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn an_output_that_is_an_input_file_is_refused_and_the_input_kept() {
    // `run m.toml -o m.toml` replaced the model with the results (exit 0), and so did
    // `sweep --variants v.csv -o v.csv` with the variant table
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/pendulum.toml"),
    )
    .unwrap();
    let model = temp("self.toml", &text);
    let m = model.to_str().unwrap();
    usage_error(&["run", m, "-o", m], "it is the model file");
    usage_error(
        &["sweep", m, "--vary", "theta0=0.1:0.2:2", "-o", m],
        "it is the model file",
    );
    let csv = temp("self.csv", "theta0\n0.1\n");
    let c = csv.to_str().unwrap();
    usage_error(
        &["sweep", m, "--variants", c, "-o", c],
        "it is the --variants file",
    );
    // by another name: a hard link is the same file
    let link = std::env::temp_dir().join(format!("latdyn_bad_{}_link.toml", std::process::id()));
    let _ = std::fs::remove_file(&link);
    std::fs::hard_link(&model, &link).unwrap();
    usage_error(
        &["run", m, "-o", link.to_str().unwrap()],
        "it is the model file",
    );
    assert_eq!(std::fs::read_to_string(&model).unwrap(), text);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "theta0\n0.1\n");
}

#[test]
fn a_parameter_given_by_set_and_by_a_variation_is_refused_and_one_set_twice_is_noted() {
    // the variation's values silently replaced the --set value, and the last of two
    // --set values won without a word
    let m = "models/pendulum.toml";
    usage_error(
        &[
            "sweep",
            m,
            "--vary",
            "theta0=1:2:2",
            "--set",
            "theta0=5",
            "--set",
            "t_end=0.01",
        ],
        "--set theta0 and --vary theta0 both give `theta0`",
    );
    let one = temp("theta.csv", "theta0\n1\n");
    usage_error(
        &[
            "sweep",
            m,
            "--variants",
            one.to_str().unwrap(),
            "--set",
            "theta0=5",
        ],
        "--set theta0 and --variants",
    );
    // a value given twice: the last wins (a script extends a base command line), and a
    // note says which value it replaced
    let out = latdyn(&[
        "run",
        m,
        "--set",
        "t_end=0.5",
        "--set",
        "t_end=0.01",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("--set t_end given more than once: the last, 0.01, replaces 0.5"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let t = v["sensors"]["angle"]["t"].as_array().unwrap();
    assert_eq!(t.last().unwrap().as_f64(), Some(0.01));
}

#[test]
fn a_variant_that_breaks_the_model_is_named_by_its_csv_line_or_grid_point() {
    // the message named only the model's line, the same for every row: with 1000 rows
    // the bad one could not be found
    let m = "models/pendulum.toml";
    let bad = temp("bad_row.csv", "theta0,m\n0.1,1\n0.2,2\n0.3,-2\n0.4,3\n");
    let b = bad.to_str().unwrap();
    let e = usage_error(
        &["sweep", m, "--variants", b, "--set", "t_end=0.01"],
        "pendulum.toml:26:8: field `bodies[0].mass`: must be > 0, is -2",
    );
    assert!(
        e.contains(&format!("--variants {b} line 4: theta0=0.3, m=-2")),
        "{e}"
    );
    assert_eq!(e.matches("error:").count(), 1, "{e}");
    // lines as the file has them: a comment and a blank line before the header count
    let commented = temp(
        "bad_row_commented.csv",
        "# masses\n\ntheta0,m\n0.1,1\n# the next one is wrong\n0.2,-2\n",
    );
    let c = commented.to_str().unwrap();
    usage_error(
        &["sweep", m, "--variants", c, "--set", "t_end=0.01"],
        &format!("--variants {c} line 6: theta0=0.2, m=-2"),
    );
    // crossed with a grid: the row, and the grid point's values
    usage_error(
        &[
            "sweep",
            m,
            "--variants",
            b,
            "--vary",
            "d=0.5:1:2",
            "--set",
            "t_end=0.01",
        ],
        &format!("variant 4 (--variants {b} line 4: theta0=0.3, m=-2; --vary d=0.5)"),
    );
    // a grid alone: the values of the failing point (m = 2, 1, 0, theta0 fastest: the
    // first bad one is variant 4)
    usage_error(
        &[
            "sweep",
            m,
            "--vary",
            "m=2:0:3",
            "--vary",
            "theta0=0.1:0.2:2",
            "--set",
            "t_end=0.01",
        ],
        "variant 4 (--vary m=0, theta0=0.1): models/pendulum.toml:26:8: field `bodies[0].mass`",
    );
    // the other paths that compile the variants: --plan, --path
    usage_error(
        &[
            "sweep",
            m,
            "--variants",
            b,
            "--plan",
            "--probe",
            "4",
            "--set",
            "t_end=0.01",
        ],
        &format!("--variants {b} line 4: theta0=0.3, m=-2"),
    );
    // an element count of 0 in a row
    let zero = temp("zero_elements.csv", "elements,P\n8,1\n4,2\n0,3\n");
    let z = zero.to_str().unwrap();
    usage_error(
        &["sweep", "models/cantilever.toml", "--variants", z, "--path"],
        &format!(
            "variant 2 (--variants {z} line 4: elements=0, P=3): models/cantilever.toml:38:12: \
             field `beams[0].elements`"
        ),
    );
    // `--resume`: the variants a campaign file still lacks are compiled from the table
    // given now (variant 1, in shard 2 of 2, was never run: the merge has a gap)
    let masses = temp("masses.csv", "m\n1\n2\n3\n");
    let shard1 = std::env::temp_dir().join(format!("latdyn_bad_{}_s1.h5", std::process::id()));
    let merged = std::env::temp_dir().join(format!("latdyn_bad_{}_m.h5", std::process::id()));
    let (s1, mg) = (shard1.to_str().unwrap(), merged.to_str().unwrap());
    let short = ["--set", "t_end=0.01"];
    let mut args = vec!["sweep", m, "--variants", masses.to_str().unwrap()];
    args.extend(short);
    args.extend(["--shard", "1/2", "-o", s1]);
    let out = latdyn(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = latdyn(&["merge", s1, "-o", mg]);
    assert_eq!(
        out.status.code(),
        Some(4),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let changed = temp("masses_changed.csv", "m\n1\n-2\n3\n");
    let ch = changed.to_str().unwrap();
    let mut args = vec!["sweep", m, "--variants", ch];
    args.extend(short);
    args.extend(["--resume", mg]);
    usage_error(
        &args,
        &format!("--resume {mg}: variant 1 (--variants {ch} line 3: m=-2): "),
    );
    for p in [&shard1, &merged] {
        let _ = std::fs::remove_file(p);
    }

    // a value an expression turns into NaN
    let text = std::fs::read_to_string(dir("models/cantilever.toml"))
        .unwrap()
        .replace("EIy = \"EI\"", "EIy = \"sqrt(EI)\"");
    let sq = temp("sqrt.toml", &text);
    let roots = temp("sqrt.csv", "EI\n4\n9\n-1\n");
    let r = roots.to_str().unwrap();
    let e = usage_error(
        &["sweep", sq.to_str().unwrap(), "--variants", r],
        &format!("variant 2 (--variants {r} line 4: EI=-1): "),
    );
    assert!(e.contains("`sqrt(EI)` evaluates to NaN"), "{e}");

    // a good table still runs
    let good = temp("good_rows.csv", "theta0,m\n0.1,1\n0.2,2\n0.3,3\n");
    let v = json_ok(&[
        "sweep",
        m,
        "--variants",
        good.to_str().unwrap(),
        "--set",
        "t_end=0.01",
        "--json",
    ]);
    assert_eq!(v["variants"].as_array().map(Vec::len), Some(3), "{v}");
    assert_eq!(v["status"], "complete", "{v}");
    assert_eq!(v["failed_variants"], 0, "{v}");
}

#[test]
fn a_quoted_variants_field_may_hold_a_comma_and_a_doubled_quote_and_is_then_judged_as_a_number() {
    let m = "models/pendulum.toml";
    // split on commas before the quotes were removed: "1,5" made three fields, and the
    // error miscounted the columns ("3 values for 2 columns")
    let comma = temp(
        "quoted_comma.csv",
        "\"theta0\",\"m\"\n# a decimal comma\n\"0.1\",\"2\"\n\"1,5\",3\n",
    );
    let c = comma.to_str().unwrap();
    let e = usage_error(
        &["sweep", m, "--variants", c, "--set", "t_end=0.01"],
        &format!("{c}:4: column `theta0` (field 1): `1,5` is not a finite number"),
    );
    assert!(!e.contains("values for"), "{e}");
    // `""` inside quotes is one literal quote, a part of the field
    let dq = temp("quoted_quote.csv", "theta0,m\n0.1,1\n\"0.2\"\"\",2\n");
    let d = dq.to_str().unwrap();
    usage_error(
        &["sweep", m, "--variants", d, "--set", "t_end=0.01"],
        &format!("{d}:3: column `theta0` (field 1): `0.2\"` is not a finite number"),
    );
    // a quote not closed on its line, and text after a closing quote
    let open = temp("quoted_open.csv", "theta0,m\n\"0.1,1\n");
    let o = open.to_str().unwrap();
    usage_error(
        &["sweep", m, "--variants", o, "--set", "t_end=0.01"],
        &format!("{o}:2: field 1: the quote that opens it is not closed on this line"),
    );
    let after = temp("quoted_after.csv", "theta0,m\n\"0.1\"x,1\n");
    let a = after.to_str().unwrap();
    usage_error(
        &["sweep", m, "--variants", a, "--set", "t_end=0.01"],
        &format!("{a}:2: field 1: `x` follows its closing quote"),
    );
    // a spreadsheet's export: byte-order mark, CRLF, quoted names and values, spaces
    // around and inside the quotes; the values are read as written
    let ok = temp(
        "quoted_ok.csv",
        "\u{feff}\"theta0\", \"m\"\r\n\" 0.1 \",\"1\"\r\n0.2 , \"2\"\r\n",
    );
    let v = json_ok(&[
        "sweep",
        m,
        "--variants",
        ok.to_str().unwrap(),
        "--set",
        "t_end=0.01",
        "--json",
    ]);
    let params: Vec<(f64, f64)> = v["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| {
            let p = &x["parameters"];
            (p["theta0"].as_f64().unwrap(), p["m"].as_f64().unwrap())
        })
        .collect();
    assert_eq!(params, vec![(0.1, 1.0), (0.2, 2.0)]);
}
