fn main() {
    let path = std::path::Path::new("models/bend45.toml");
    for n in [8.0, 16.0, 32.0, 64.0] {
        let m = latdyn::model::load(path, &[("elements".into(), n), ("P".into(), 600.0)]).unwrap();
        let sol = latdyn::solver::solve_statics(&m).unwrap();
        println!("{n} {:?} {:?}", sol.sensors[0], sol.report);
    }
}
