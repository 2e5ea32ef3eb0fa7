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
    ("dt_zero.toml", 29, "solver.dt", "must be > 0"),
    ("syntax_error.toml", 25, "section", "invalid basic string"),
];

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
