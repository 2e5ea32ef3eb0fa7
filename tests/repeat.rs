//! `[[repeat]]` in the model format: generated entries compile to exactly the model the
//! same entries written out by hand give (bit for bit, through a run), and mistakes in
//! a template are reported at the template with the index value that failed.

mod common;
use common::*;
use latdyn::model::{compile_str, Model};
use latdyn::solver::dynamics::run;

fn bay_text() -> String {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/minimast_bay.toml");
    std::fs::read_to_string(p).unwrap()
}

/// models/minimast_bay.toml with its three hand-written corners replaced by one
/// `[[repeat]]` over the corner k = 1..3. The rotations by 0, +120 and -120 degrees are
/// written with per-corner parameters `cr{k}`, `sr{k}` chosen so that every expression
/// evaluates to the same bits as the hand-written one (corner 1: `1*x - 0*y` is `x`
/// exactly; corner 3: `c3*x - (-s3)*y` is `c3*x + s3*y` exactly).
fn bay_with_corner_repeat() -> String {
    let text = bay_text();
    let a = text.find("# ---------------- corner 1").unwrap();
    let b = text.find("# ---------------- sensors").unwrap();
    let rot = |p: &str, x: &str, y: &str, z: &str| {
        format!("{p} = [\"cr{{k}}*{x} - sr{{k}}*{y}\", \"sr{{k}}*{x} + cr{{k}}*{y}\", \"{z}\"]\n")
    };
    let mut t = String::from("[[repeat]]\nindex = \"k\"\nto = 3\n");
    for (name, x, y) in [
        ("la{k}", "xLA", "yLA"),
        ("lb{k}", "xLB", "yLB"),
        ("da{k}", "xDA", "yDA"),
        ("ma{k}", "xM", "yM"),
        ("mb{k}", "xM", "yM"),
        ("db{k - 3*floor(k/3) + 1}", "xDB", "yDB"),
    ] {
        t += &format!("[[repeat.nodes]]\nname = \"{name}\"\n");
        t += &rot("position", x, y, "zj");
    }
    for (name, from, to, sec) in [
        ("longeron{k}", "la{k}", "lb{k}", "longeron"),
        ("diagonal{k}_a", "da{k}", "ma{k}", "diagonal"),
        (
            "diagonal{k}_b",
            "db{k - 3*floor(k/3) + 1}",
            "mb{k}",
            "diagonal",
        ),
    ] {
        t += &format!(
            "[[repeat.beams]]\nname = \"{name}\"\nfrom = \"{from}\"\nto = \"{to}\"\n\
             elements = \"elements\"\nsection = \"{sec}\"\n"
        );
    }
    for (name, node, body, ax) in [
        ("longeron{k}_A", "la{k}", "ground", "la"),
        ("longeron{k}_B", "lb{k}", "upper", "lb"),
        ("diagonal{k}_A", "da{k}", "ground", "da"),
        ("diagonal{k}_B", "db{k - 3*floor(k/3) + 1}", "upper", "db"),
    ] {
        t += &format!(
            "[[repeat.joints]]\nname = \"{name}\"\nnode = \"{node}\"\nbody = \"{body}\"\n\
             type = \"hinge\"\n"
        );
        t += &rot(
            "axis",
            &format!("{ax}X"),
            &format!("{ax}Y"),
            &format!("{ax}Z"),
        );
    }
    t += "[[repeat.joints]]\nname = \"diagonal{k}_mid\"\nnode = \"mb{k}\"\n\
          to_node = \"ma{k}\"\ntype = \"hinge\"\nlock_angle = \"mid_lock_angle\"\n";
    t += &rot("axis", "mX", "mY", "mZ");
    let params = "cr1 = 1\nsr1 = 0\ncr2 = \"c3\"\nsr2 = \"s3\"\ncr3 = \"c3\"\nsr3 = \"-s3\"\n";
    let out = format!("{}{}\n{}", &text[..a], t, &text[b..]);
    out.replacen(
        "s3 = \"sin(2*pi/3)\"\n",
        &format!("s3 = \"sin(2*pi/3)\"\n{params}"),
        1,
    )
}

fn compile(text: &str, sets: &[(&str, f64)]) -> Model {
    let o: Vec<(String, f64)> = sets.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    compile_str(text, "gen.toml", &o).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn corner_repeat_of_the_minimast_bay_runs_bit_identical_to_the_hand_written_bay() {
    let sets = [("elements", 2.0), ("t_end", 0.3), ("dt", 2e-3)];
    let hand = shipped("minimast_bay.toml", &sets);
    let text = bay_with_corner_repeat();
    assert!(text.contains("[[repeat]]") && !text.contains("name = \"la2\""));
    let gen = compile(&text, &sets);
    assert_eq!(gen.node_names, hand.node_names);
    assert_eq!(gen.x0, hand.x0, "node positions, bit for bit");
    let axes = |m: &Model| m.hinges.iter().map(|h| h.axis_local).collect::<Vec<_>>();
    assert_eq!(axes(&gen), axes(&hand), "hinge axes, bit for bit");
    assert_eq!(gen.dofs.len(), hand.dofs.len());
    assert_eq!(gen.repeats.len(), 1);
    assert_eq!(gen.repeats[0].iterations, 3);
    assert_eq!(gen.repeats[0].counts, [18, 9, 0, 0, 0, 15, 0]);
    let (hh, _, e1) = run(&hand, |_, _| {});
    let (hg, _, e2) = run(&gen, |_, _| {});
    assert!(e1.is_none() && e2.is_none(), "{e1:?} {e2:?}");
    assert_eq!(hh.t, hg.t);
    // every sensor value at every output time, compared as bits
    assert_eq!(hh.values, hg.values);
}

#[test]
fn a_repeat_of_one_with_the_whole_bay_inside_is_the_hand_written_bay() {
    // every node, beam and joint of the bay moved under one `[[repeat]]` with to = 1:
    // the hand-written text itself, so names and expressions need no index
    let text = bay_text();
    let a = text.find("# ---------------- corner 1").unwrap();
    let b = text.find("# ---------------- sensors").unwrap();
    let body = text[a..b]
        .replace("[[nodes]]", "[[repeat.nodes]]")
        .replace("[[beams]]", "[[repeat.beams]]")
        .replace("[[joints]]", "[[repeat.joints]]");
    let gen_text = format!(
        "{}[[repeat]]\nindex = \"bay\"\nto = 1\n{}{}",
        &text[..a],
        body,
        &text[b..]
    );
    let sets = [("elements", 2.0)];
    let hand = shipped("minimast_bay.toml", &sets);
    let gen = compile(&gen_text, &sets);
    assert_eq!(gen.node_names, hand.node_names);
    assert_eq!(gen.x0, hand.x0);
    assert_eq!(
        format!("{:?}", gen.node_kin),
        format!("{:?}", hand.node_kin)
    );
    assert_eq!(format!("{:?}", gen.dofs), format!("{:?}", hand.dofs));
    assert_eq!(
        format!("{:?}", gen.elements),
        format!("{:?}", hand.elements)
    );
}

const CHAIN: &str = r#"
[parameters]
n = 4
h = 0.5
[sections.s]
EA = 1e6
EIy = 1e3
EIz = 1e3
GJ = 1e3
rhoA = 1.0
[[nodes]]
name = "p0"
position = [0, 0, 0]
[[supports]]
node = "p0"
type = "clamped"
[[repeat]]
index = "i"
to = "n"
  [[repeat.nodes]]
  name = "p{i}"
  position = [0, 0, "i*h"]
  [[repeat.beams]]
  name = "b{i}"
  from = "p{i-1}"
  to = "p{i}"
  elements = 1
  section = "s"
[[sensors]]
name = "tip"
type = "node"
node = "p{n}"
"#;

#[test]
fn a_chain_of_n_links_follows_its_count_parameter() {
    // `{n}` outside a repeat is not substituted: the tip sensor names the node literally
    let text = CHAIN.replace("node = \"p{n}\"", "node = \"p4\"");
    let m = compile(&text, &[]);
    assert_eq!(m.beams.len(), 4);
    assert_eq!(m.x0.last().unwrap(), &[0.0, 0.0, 2.0]);
    let e = compile_str(&text, "chain.toml", &[("n".into(), 3.0)]).unwrap_err();
    // shrinking the chain leaves the tip sensor's node undefined
    assert!(e.to_string().contains("unknown node `p4`"), "{e}");
    let m = compile(&text, &[("n", 9.0)]);
    assert_eq!(m.beams.len(), 9);
    assert_eq!(m.x0[9], [0.0, 0.0, 4.5]);
}

#[test]
fn an_out_of_range_reference_names_the_template_line_field_and_index() {
    // links point forward to p{i+1}: the last one names a node that does not exist
    let text = CHAIN
        .replace("from = \"p{i-1}\"", "from = \"p{i}\"")
        .replace("to = \"p{i}\"", "to = \"p{i+1}\"")
        .replace("node = \"p{n}\"", "node = \"p1\"");
    let e = compile_str(&text, "chain.toml", &[]).unwrap_err();
    let line = text.lines().position(|l| l.contains("p{i+1}")).unwrap() + 1;
    assert_eq!(e.line, Some(line), "{e}");
    assert_eq!(e.field.as_deref(), Some("repeat[0].beams[0].to"), "{e}");
    assert!(
        e.message.contains("unknown node `p5`") && e.message.contains("generated for i = 4"),
        "{e}"
    );
    assert!(
        e.to_string().starts_with(&format!("chain.toml:{line}:")),
        "{e}"
    );
}

#[test]
fn template_mistakes_are_errors_at_the_template() {
    let cases: [(&str, &str, &str, &str); 6] = [
        (
            "name = \"p{i}\"",
            "name = \"p{i\"",
            "repeat[0].nodes[0].name",
            "without `}`",
        ),
        (
            "name = \"p{i}\"",
            "name = \"p{i/2}\"",
            "repeat[0].nodes[0].name",
            "not a whole number",
        ),
        (
            "name = \"p{i}\"",
            "name = \"p{j}\"",
            "repeat[0].nodes[0].name",
            "undefined parameter `j`",
        ),
        (
            "index = \"i\"",
            "index = \"h\"",
            "repeat[0].index",
            "name of a parameter",
        ),
        (
            "to = \"n\"",
            "to = \"n + 0.5\"",
            "repeat[0].to",
            "whole number",
        ),
        ("to = \"n\"", "to = -3", "repeat[0].to", "below from - 1"),
    ];
    for (from, to, field, msg) in cases {
        let text = CHAIN
            .replacen(from, to, 1)
            .replace("node = \"p{n}\"", "node = \"p1\"");
        let e = compile_str(&text, "chain.toml", &[]).unwrap_err();
        assert_eq!(e.field.as_deref(), Some(field), "{to}: {e}");
        assert!(e.message.contains(msg), "{to}: {e}");
        assert!(e.line.is_some(), "{to}: {e}");
    }
    // an empty range generates nothing (a repeat as an optional part)
    let text = CHAIN
        .replace("to = \"n\"", "to = 0")
        .replace("node = \"p{n}\"", "node = \"p0\"");
    let e = compile_str(&text, "chain.toml", &[]).unwrap_err();
    assert!(e.message.contains("nothing to simulate"), "{e}");
    // an unknown key in a template is a parse error with its path
    let text = CHAIN.replace("  elements = 1\n", "  elements = 1\n  colour = 2\n");
    let e = compile_str(&text, "chain.toml", &[]).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("repeat[0].beams[0].colour"), "{e}");
}

#[test]
fn check_prints_the_expanded_counts() {
    let dir = std::env::temp_dir().join(format!("latdyn-repeat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("chain.toml");
    std::fs::write(&p, CHAIN.replace("node = \"p{n}\"", "node = \"p7\"")).unwrap();
    let out = latdyn(&["check", p.to_str().unwrap(), "--set", "n=7"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text} {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("  nodes     8\n"), "{text}");
    assert!(text.contains("  elements  7 in 7 beams\n"), "{text}");
    assert!(
        text.contains("  repeat    repeat[0] i = 1..7: 7 iterations, generated 7 nodes, 7 beams\n"),
        "{text}"
    );
    let out = latdyn(&["check", p.to_str().unwrap(), "--set", "n=7", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["repeats"][0]["beams"], 7);
    assert_eq!(v["beams"], 7);
    // a file without repeats prints what it printed before: no repeat keys
    let out = latdyn(&["check", "models/cantilever.toml", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v.get("repeats").is_none() && v.get("beams").is_none());
    let _ = std::fs::remove_dir_all(&dir);
}
