//! Element kernel timings (prints, never asserts): calls per second of the internal
//! force + tangent and of the inertia terms, on a deformed, rotated element.

use latdyn::element::*;
use latdyn::math::*;
use latdyn::model::BeamProps;
use std::time::Instant;

fn main() {
    let props = BeamProps {
        ea: 1e7,
        eiy: 1e3,
        eiz: 2e3,
        gj: 8e2,
        rho_a: 2.0,
        rho_iy: 1e-3,
        rho_iz: 2e-3,
    };
    let x1 = [0.1, 0.2, 0.3];
    let dir = normalize([1.0, 0.2, -0.1]);
    let x2 = add(x1, dir);
    let y = perpendicular(dir, [0.0, 0.0, 1.0]);
    let e = ElemData::new(props, from_cols(dir, y, cross(dir, y)), x1, x2);
    let q = rot_exp([0.3, -0.4, 0.5]);
    let s = ElemState {
        u1: [0.01, 0.0, 0.0],
        r1: mat_mul(&rot_exp([0.01, 0.02, -0.01]), &q),
        u2: sub(mat_vec(&q, e.chord0), e.chord0),
        r2: mat_mul(&rot_exp([-0.02, 0.01, 0.03]), &q),
    };
    let v = [0.1, 0.2, 0.3, 1.0, -1.0, 0.5, 0.0, 0.1, 0.2, 0.9, -1.1, 0.4];
    let n = 20000;
    let t = Instant::now();
    let mut acc = 0.0;
    for _ in 0..n {
        let (f, k) = internal_force_tangent(&e, std::hint::black_box(&s));
        acc += f[0] + k[3][4];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("internal_force_tangent: {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (f, k) = internal_force_tangent_columns(&e, std::hint::black_box(&s));
        acc += f[0] + k[3][4];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("  (12 dual passes:      {:.2} us/call)", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (m, sv, c) = inertia(&e, std::hint::black_box(&s), &v);
        acc += m[0][0] + sv[1] + c[2][3];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("inertia (M, S, C):      {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (m, sv, c) = inertia_columns(&e, std::hint::black_box(&s), &v);
        acc += m[0][0] + sv[1] + c[2][3];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("  (C by 12 passes:      {:.2} us/call)", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let (m, sv) = inertia_residual(&e, std::hint::black_box(&s), &v);
        acc += m[0][0] + sv[1];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("inertia_residual (M, S): {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let m = mass_matrix(&e, std::hint::black_box(&s));
        acc += m[0][0];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!("mass_matrix (M):        {:.2} us/call", dt * 1e6);
    let t = Instant::now();
    for _ in 0..n {
        let f = internal_force(&e, std::hint::black_box(&s));
        acc += f[0];
    }
    let dt = t.elapsed().as_secs_f64() / n as f64;
    println!(
        "internal_force:         {:.2} us/call   ({acc:.1})",
        dt * 1e6
    );
}
