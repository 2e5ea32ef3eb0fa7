fn beam(n: usize, f: [f64; 3], m: [f64; 3]) -> latdyn::model::Model {
    let text = format!(r#"
[parameters]
L = 1.0
[sections.s]
EA = 1.0e7
EIy = 100.0
EIz = 100.0
GJ = 80.0
rhoA = 1.0
[[nodes]]
name = "root"
position = [0, 0, 0]
[[nodes]]
name = "tip"
position = ["L", 0, 0]
[[beams]]
name = "beam"
from = "root"
to = "tip"
elements = {n}
section = "s"
[[supports]]
node = "root"
type = "clamped"
[[loads]]
node = "tip"
force = [{}, {}, {}]
moment = [{}, {}, {}]
[[sensors]]
name = "tip"
type = "node"
node = "tip"
[solver]
load_steps = 1
"#, f[0], f[1], f[2], m[0], m[1], m[2]);
    latdyn::model::compile_str(&text, "p.toml", &[]).unwrap()
}
fn main() {
    for n in [5, 10, 20, 40, 80] {
        let s = latdyn::solver::solve_statics(&beam(n, [0.0, 0.0, 1000.0], [0.0; 3])).unwrap();
        let t = &s.sensors[0];
        println!("elastica n={n}: u {:.6} w {:.6} th {:.6} {:?}", -t[0], t[2], -t[4], s.report);
    }
    for n in [8, 16, 32, 64] {
        let s = latdyn::solver::solve_statics(&beam(n, [0.0; 3], [0.0, std::f64::consts::PI * 100.0, 0.0])).unwrap();
        let t = &s.sensors[0];
        println!("half roll n={n}: x {:.6} z {:.6} th {:.6} {:?}", 1.0 + t[0], t[2], t[4], s.report);
    }
}
