//! Element-layer checks (Chrono-style): tangent against finite differences, invariance
//! under rigid motion, mass matrix against exact rigid-body inertia, inertia terms
//! against the exact rigid-rotation inertial force and their velocity derivative.

use super::reference::*;
use super::*;
use crate::math::*;
use crate::model::BeamProps;

/// Deterministic pseudo-random numbers in [-1, 1) (no test may depend on a seed it cannot
/// reproduce).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
    fn vec(&mut self, s: f64) -> Vec3 {
        [self.next() * s, self.next() * s, self.next() * s]
    }
}

fn props() -> BeamProps {
    BeamProps {
        ea: 3.0e6,
        eiy: 2.0e3,
        eiz: 5.0e3,
        gj: 1.5e3,
        rho_a: 2.7,
        rho_iy: 0.013,
        rho_iz: 0.021,
    }
}

/// An element from a random point in a random direction, and a random deformed state:
/// large rigid rotation and translation plus moderate deformation.
fn random_case(rng: &mut Lcg, deform: f64) -> (ElemData, ElemState) {
    let (e, s, _) = random_case_x(rng, deform);
    (e, s)
}

/// As `random_case`, also returning node 1's reference position.
fn random_case_x(rng: &mut Lcg, deform: f64) -> (ElemData, ElemState, Vec3) {
    let x1 = rng.vec(2.0);
    let dir = normalize(rng.vec(1.0));
    let len = 0.7 + 0.3 * rng.next().abs();
    let x2 = add(x1, scale(dir, len));
    let y = perpendicular(dir, rng.vec(1.0));
    let frame0 = from_cols(dir, y, cross(dir, y));
    let e = ElemData::new(props(), frame0, x1, x2);
    let q = rot_exp(rng.vec(2.0));
    let t = rng.vec(1.0);
    let rigid = |x: Vec3| add(mat_vec(&q, x), t);
    let s = ElemState {
        u1: sub(add(rigid(x1), rng.vec(deform * len)), x1),
        r1: mat_mul(&rot_exp(rng.vec(deform)), &q),
        u2: sub(add(rigid(x2), rng.vec(deform * len)), x2),
        r2: mat_mul(&rot_exp(rng.vec(deform)), &q),
    };
    (e, s, x1)
}

/// An undeformed random element turned rigidly by a large random rotation about node 1;
/// returns the element, its state and the current node positions.
fn rigidly_rotated_case(rng: &mut Lcg) -> (ElemData, ElemState, Vec3, Vec3) {
    let (e, _, x10) = random_case_x(rng, 0.0);
    let q = rot_exp(rng.vec(2.0));
    let s = ElemState {
        u1: [0.0; 3],
        r1: q,
        u2: sub(mat_vec(&q, e.chord0), e.chord0),
        r2: q,
    };
    (e, s, x10, add(x10, mat_vec(&q, e.chord0)))
}

/// State perturbed by h along element dof k (spins applied multiplicatively).
fn perturbed(s: &ElemState, k: usize, h: f64) -> ElemState {
    let mut p = *s;
    let mut d = [0.0; 3];
    d[k % 3] = h;
    match k / 3 {
        0 => p.u1 = add(p.u1, d),
        1 => p.r1 = mat_mul(&rot_exp(d), &p.r1),
        2 => p.u2 = add(p.u2, d),
        _ => p.r2 = mat_mul(&rot_exp(d), &p.r2),
    }
    p
}

fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, x| m.max(x.abs()))
}

#[test]
fn tangent_equals_finite_differences_of_internal_force_at_random_deformed_states() {
    // Central differences with h = 1e-6 have truncation error ~h² K''' ≈ 1e-12 relative
    // and round-off ~ε|f|/h ≈ 1e-10|f|; 1e-6 relative to the largest entry leaves margin.
    let mut rng = Lcg(7);
    for case in 0..40 {
        let (e, s) = random_case(&mut rng, 0.08);
        let (f, k) = internal_force_tangent(&e, &s);
        let f2 = internal_force(&e, &s);
        for j in 0..NDOF {
            assert!((f[j] - f2[j]).abs() <= 1e-9 * max_abs(&f));
        }
        let kmax = k.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for col in 0..NDOF {
            let fp = internal_force(&e, &perturbed(&s, col, h));
            let fm = internal_force(&e, &perturbed(&s, col, -h));
            for row in 0..NDOF {
                let fd = (fp[row] - fm[row]) / (2.0 * h);
                worst = worst.max((fd - k[row][col]).abs() / kmax);
            }
        }
        assert!(
            worst < 1e-6,
            "case {case}: tangent vs FD relative error {worst:e}"
        );
    }
}

#[test]
fn internal_force_is_the_gradient_of_strain_energy() {
    let mut rng = Lcg(11);
    for _ in 0..20 {
        let (e, s) = random_case(&mut rng, 0.05);
        let f = internal_force(&e, &s);
        let h = 1e-6;
        for j in 0..NDOF {
            let up = strain_energy(&e, &perturbed(&s, j, h));
            let um = strain_energy(&e, &perturbed(&s, j, -h));
            let fd = (up - um) / (2.0 * h);
            assert!(
                (fd - f[j]).abs() < 1e-6 * max_abs(&f),
                "dof {j}: {fd} vs {}",
                f[j]
            );
        }
    }
}

#[test]
fn rigid_motion_of_an_undeformed_element_gives_zero_internal_force() {
    let mut rng = Lcg(3);
    for _ in 0..50 {
        let (e, _, x1) = random_case_x(&mut rng, 0.0);
        // large rotation (up to ~3.4 rad) about node 1 and a large translation
        let q = rot_exp(rng.vec(2.0));
        let t = rng.vec(10.0);
        let s = ElemState {
            u1: t,
            r1: q,
            u2: add(t, sub(mat_vec(&q, e.chord0), e.chord0)),
            r2: q,
        };
        let _ = x1;
        let f = internal_force(&e, &s);
        // scale: a 1e-3 rad deformation would give moments ~EI/L·1e-3 ≈ 5
        assert!(max_abs(&f) < 1e-8, "rigid motion gave force {f:?}");
        assert!(strain_energy(&e, &s).abs() < 1e-18);
    }
}

#[test]
fn rigidly_rotating_a_deformed_element_rotates_its_forces_and_keeps_its_energy() {
    let mut rng = Lcg(5);
    for _ in 0..30 {
        let (e, s) = random_case(&mut rng, 0.1);
        let f = internal_force(&e, &s);
        let u = strain_energy(&e, &s);
        let q = rot_exp(rng.vec(2.5));
        let t = rng.vec(5.0);
        // rotate the current configuration about node 1's current position, then translate
        let s2 = ElemState {
            u1: add(s.u1, t),
            r1: mat_mul(&q, &s.r1),
            u2: add(
                s.u1,
                add(
                    t,
                    sub(mat_vec(&q, add(e.chord0, sub(s.u2, s.u1))), e.chord0),
                ),
            ),
            r2: mat_mul(&q, &s.r2),
        };
        let f2 = internal_force(&e, &s2);
        let u2 = strain_energy(&e, &s2);
        assert!((u - u2).abs() <= 1e-10 * u.abs().max(1e-12));
        let scale_f = max_abs(&f);
        // moments are taken about the nodes, so each 3-block simply rotates
        for b in 0..4 {
            let v = [f[3 * b], f[3 * b + 1], f[3 * b + 2]];
            let rv = mat_vec(&q, v);
            for i in 0..3 {
                assert!((rv[i] - f2[3 * b + i]).abs() < 1e-9 * scale_f);
            }
        }
    }
}

/// Nodal velocity vector of the rigid field v(x) = d + ω × x.
fn rigid_velocity(x1: Vec3, x2: Vec3, d: Vec3, w: Vec3) -> Vec12 {
    let v1 = add(d, cross(w, x1));
    let v2 = add(d, cross(w, x2));
    [
        v1[0], v1[1], v1[2], w[0], w[1], w[2], v2[0], v2[1], v2[2], w[0], w[1], w[2],
    ]
}

fn quad(m: &Mat12, a: &Vec12, b: &Vec12) -> f64 {
    let mut s = 0.0;
    for i in 0..NDOF {
        for j in 0..NDOF {
            s += a[i] * m[i][j] * b[j];
        }
    }
    s
}

/// Exact mass, first moment and inertia tensor (about the origin) of a straight
/// undeformed element with principal section axes t_c2, t_c3.
fn exact_rigid_inertia(e: &ElemData, s: &ElemState, x1: Vec3, x2: Vec3) -> (f64, Vec3, Mat3) {
    let p = &e.props;
    let l = e.l0;
    let m = p.rho_a * l;
    let c = scale(add(x1, x2), 0.5);
    let k = deformation(e, s);
    let ey = col(&k.tc, 1);
    let ez = col(&k.tc, 2);
    let dir = col(&k.tc, 0);
    let mut j = [[0.0; 3]; 3];
    // line: ρA∫(|x|²I − xxᵀ) over the segment = m(|c|²I − ccᵀ) + (mL²/12)(I − ddᵀ)
    let add_term = |j: &mut Mat3, w: f64, a: Vec3| {
        let aa = dot(a, a);
        for r in 0..3 {
            for q in 0..3 {
                j[r][q] += w * ((if r == q { aa } else { 0.0 }) - a[r] * a[q]);
            }
        }
    };
    add_term(&mut j, m, c);
    add_term(&mut j, m * l * l / 12.0, dir);
    // section: ∫ρy² = ρI_z along e_y, ∫ρz² = ρI_y along e_z
    add_term(&mut j, p.rho_iz * l, ey);
    add_term(&mut j, p.rho_iy * l, ez);
    (m, scale(c, m), j)
}

#[test]
fn mass_matrix_reproduces_exact_mass_first_and_second_moments_of_a_rigid_element() {
    let mut rng = Lcg(13);
    for _ in 0..30 {
        let (e, s, x1, x2) = rigidly_rotated_case(&mut rng);
        let m = mass_matrix(&e, &s);
        let (mass, s1, j) = exact_rigid_inertia(&e, &s, x1, x2);
        for _ in 0..5 {
            let (d, w) = (rng.vec(1.0), rng.vec(1.0));
            let v = rigid_velocity(x1, x2, d, w);
            // 2T = m|d|² + 2 d·(ω × S1) + ωᵀJω
            let exact = mass * dot(d, d) + 2.0 * dot(d, cross(w, s1)) + dot(w, mat_vec(&j, w));
            let got = quad(&m, &v, &v);
            assert!(
                (got - exact).abs() < 1e-11 * exact.abs(),
                "2T = {got} vs exact {exact}"
            );
        }
    }
}

/// Cholesky succeeds iff the matrix is symmetric positive definite.
fn is_spd(m: &Mat12) -> bool {
    let mut l = [[0.0; NDOF]; NDOF];
    for i in 0..NDOF {
        for j in 0..=i {
            if (m[i][j] - m[j][i]).abs() > 1e-12 * m[i][i].abs() {
                return false;
            }
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s <= 0.0 {
                    return false;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    true
}

#[test]
fn mass_matrix_is_symmetric_positive_definite_in_deformed_states() {
    let mut rng = Lcg(17);
    for _ in 0..30 {
        let (e, s) = random_case(&mut rng, 0.1);
        assert!(is_spd(&mass_matrix(&e, &s)));
    }
}

#[test]
fn inertial_force_of_steady_rigid_rotation_is_the_exact_centripetal_and_gyroscopic_load() {
    // For v(x) = ω × x with constant ω: ẍ = ω × (ω × x). The generalized inertial force
    // M a + S, contracted with a rigid virtual motion (δd, δω), must equal
    // δd·(ω × (ω × S1)) + δω·(ω × Jω).
    let mut rng = Lcg(19);
    for _ in 0..20 {
        let (e, s, x1, x2) = rigidly_rotated_case(&mut rng);
        let w = rng.vec(3.0);
        let v = rigid_velocity(x1, x2, [0.0; 3], w);
        let acc_node = |x: Vec3| cross(w, cross(w, x));
        let a1 = acc_node(x1);
        let a2 = acc_node(x2);
        let a = [
            a1[0], a1[1], a1[2], 0.0, 0.0, 0.0, a2[0], a2[1], a2[2], 0.0, 0.0, 0.0,
        ];
        let (m, sv, _) = inertia(&e, &s, &v);
        let mut finert = sv;
        for i in 0..NDOF {
            for j in 0..NDOF {
                finert[i] += m[i][j] * a[j];
            }
        }
        let (_, s1, jt) = exact_rigid_inertia(&e, &s, x1, x2);
        for _ in 0..4 {
            let (dd, dw) = (rng.vec(1.0), rng.vec(1.0));
            let dv = rigid_velocity(x1, x2, dd, dw);
            let got: f64 = (0..NDOF).map(|i| dv[i] * finert[i]).sum();
            let exact = dot(dd, cross(w, cross(w, s1))) + dot(dw, cross(w, mat_vec(&jt, w)));
            let scale_ = (dot(w, w) * (norm(s1) + norm(mat_vec(&jt, [1.0, 1.0, 1.0])))).max(1.0);
            assert!((got - exact).abs() < 1e-10 * scale_, "{got} vs {exact}");
        }
    }
}

#[test]
fn gyroscopic_matrix_is_the_velocity_derivative_of_the_quadratic_velocity_vector() {
    let mut rng = Lcg(23);
    for _ in 0..20 {
        let (e, s) = random_case(&mut rng, 0.1);
        let mut v = [0.0; NDOF];
        for x in v.iter_mut() {
            *x = rng.next() * 2.0;
        }
        let (_, _, c) = inertia(&e, &s, &v);
        let h = 1e-5;
        let cmax = c.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
        for k in 0..NDOF {
            let mut vp = v;
            let mut vm = v;
            vp[k] += h;
            vm[k] -= h;
            let (_, sp, _) = inertia(&e, &s, &vp);
            let (_, sm, _) = inertia(&e, &s, &vm);
            for j in 0..NDOF {
                // S is quadratic in v: central differences are exact up to round-off
                let fd = (sp[j] - sm[j]) / (2.0 * h);
                assert!((fd - c[j][k]).abs() < 1e-7 * cmax, "C[{j}][{k}]");
            }
        }
    }
}

#[test]
fn elongation_is_computed_without_cancellation() {
    // A 1e-9 strain on an element far from the origin: ℓ − L0 from the difference of
    // lengths would lose ~7 digits; the (2X·d + d·d)/(|X+d|+|X|) form keeps them.
    let x1 = [1.0e3, 2.0e3, -1.5e3];
    let dir = normalize([0.3, 0.4, 0.5]);
    let x2 = add(x1, scale(dir, 2.0));
    let y = perpendicular(dir, [0.0, 0.0, 1.0]);
    let e = ElemData::new(props(), from_cols(dir, y, cross(dir, y)), x1, x2);
    let s = ElemState {
        u1: [0.0; 3],
        r1: I3,
        u2: scale(dir, 2.0e-9),
        r2: I3,
    };
    let k = deformation(&e, &s);
    assert!(
        (k.u1 - 2.0e-9).abs() < 1e-20 + 1e-6 * 2.0e-9,
        "u1 = {:e}",
        k.u1
    );
}

#[test]
fn closed_form_force_tangent_and_mass_equal_the_hyper_dual_reference() {
    // Two independent routes to the same derivatives: closed-form gradient (+ dual
    // numbers for the tangent) against hyper-dual differentiation of the energy and the
    // position field. Agreement to 1e-9 relative rules out algebra slips in either.
    let mut rng = Lcg(29);
    for _ in 0..30 {
        let (e, s) = random_case(&mut rng, 0.15);
        let (f, k) = internal_force_tangent(&e, &s);
        let (fr, kr) = internal_force_tangent_ad(&e, &s);
        let fs = max_abs(&fr);
        let ks = kr.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
        for i in 0..NDOF {
            assert!(
                (f[i] - fr[i]).abs() < 1e-9 * fs,
                "f[{i}] {} vs {}",
                f[i],
                fr[i]
            );
            for j in 0..NDOF {
                assert!(
                    (k[i][j] - kr[i][j]).abs() < 1e-9 * ks,
                    "K[{i}][{j}] {} vs {}",
                    k[i][j],
                    kr[i][j]
                );
            }
        }
        let m = mass_matrix(&e, &s);
        let mr = mass_matrix_ad(&e, &s);
        let ms = mr.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
        for i in 0..NDOF {
            for j in 0..NDOF {
                assert!((m[i][j] - mr[i][j]).abs() < 1e-12 * ms, "M[{i}][{j}]");
            }
        }
    }
}

/// A deformed element with nodal velocities (zero when `at_rest`) and accelerations.
fn random_motion(rng: &mut Lcg, at_rest: bool) -> (ElemData, ElemState, Vec12, Vec12) {
    let (e, s) = random_case(rng, 0.05);
    let v12: Vec12 = std::array::from_fn(|_| if at_rest { 0.0 } else { rng.next() });
    let acc: Vec12 = std::array::from_fn(|_| 10.0 * rng.next());
    (e, s, v12, acc)
}

#[test]
fn residual_only_evaluation_is_bit_identical_to_the_full_one_without_tangents() {
    // modified Newton mixes both evaluations within a step: they must agree exactly on
    // what the residual uses (f, energy, the inertial force M·acc + S, M·v), or the
    // converged state would depend on when the Jacobian was refreshed
    let mut rng = Lcg(7);
    for case in 0..50 {
        // every fifth case at rest: the full evaluation then takes the f64 path too
        let (e, s, v12, acc) = random_motion(&mut rng, case % 5 == 0);
        let i = ElemIn { state: s, v12, acc };
        let (mut full, mut res) = (ElemOut::default(), ElemOut::default());
        // the matrices of an earlier evaluation, which a residual-only one leaves alone
        let stale = [[f64::NAN; NDOF]; NDOF];
        (res.k, res.m, res.c) = (stale, stale, stale);
        CpuEval::one(&e, &i, true, &mut full);
        CpuEval::one_residual(&e, &i, true, &mut res);
        // the stage shares one gradient among force, energy and inertia; each must stay
        // what the stand-alone functions give
        let alone = inertia_residual(&e, &s, &v12, &acc);
        assert_eq!(res.f, internal_force(&e, &s));
        assert_eq!(res.energy, strain_energy(&e, &s));
        assert_eq!(
            (res.s, res.finert, res.mv),
            (alone.s, alone.finert, alone.mv)
        );
        assert_eq!(full.f, res.f);
        assert_eq!(full.energy, res.energy);
        assert_eq!(full.s, res.s);
        assert_eq!(full.finert, res.finert);
        assert_eq!(full.mv, res.mv);
        assert!(res
            .k
            .iter()
            .flatten()
            .chain(res.c.iter().flatten())
            .chain(res.m.iter().flatten())
            .all(|x| x.is_nan()));
        // and the products are those of the M it returns, to round-off
        let mut viam = full;
        viam.products_from_m(&i);
        let sc = max_abs(&viam.finert).max(1e-300);
        for r in 0..NDOF {
            assert!(
                (viam.finert[r] - full.finert[r]).abs() <= 1e-13 * sc,
                "finert[{r}]"
            );
            assert!(
                (viam.mv[r] - full.mv[r]).abs() <= 1e-13 * max_abs(&viam.mv).max(1e-300),
                "mv[{r}]"
            );
        }
    }
}

#[test]
fn a_residual_at_unchanged_positions_and_velocities_reuses_forces_bit_for_bit() {
    // the time-error estimate's mass products change only the accelerations: the stage
    // then forms only M·acc, and every output must equal a fresh evaluation's
    let mut rng = Lcg(11);
    for case in 0..40 {
        let (e, s, v12, a1) = random_motion(&mut rng, case % 4 == 0);
        let a2: Vec12 = std::array::from_fn(|_| 10.0 * rng.next());
        let mut memo = ElemOut::default();
        if case % 2 == 0 {
            CpuEval::one(
                &e,
                &ElemIn {
                    state: s,
                    v12,
                    acc: a1,
                },
                true,
                &mut memo,
            );
        } else {
            CpuEval::one_residual(
                &e,
                &ElemIn {
                    state: s,
                    v12,
                    acc: a1,
                },
                true,
                &mut memo,
            );
        }
        let i2 = ElemIn {
            state: s,
            v12,
            acc: a2,
        };
        assert_eq!(memo.forces_of, Some(memo_key(&i2)));
        CpuEval::one_residual(&e, &i2, true, &mut memo);
        let mut fresh = ElemOut::default();
        CpuEval::one_residual(&e, &i2, true, &mut fresh);
        assert_eq!(
            (memo.f, memo.energy, memo.s, memo.finert, memo.mv),
            (fresh.f, fresh.energy, fresh.s, fresh.finert, fresh.mv)
        );
        // a moved node, a changed velocity or no inertia is a fresh evaluation
        let mut moved = i2;
        moved.state.u2[0] += 1e-9;
        let mut slow = i2;
        slow.v12[3] += 1e-9;
        for other in [moved, slow] {
            let mut again = memo;
            CpuEval::one_residual(&e, &other, true, &mut again);
            // the key held is overwritten in place with the new positions and velocities
            assert_eq!(again.forces_of, Some(memo_key(&other)));
            let mut fresh = ElemOut::default();
            CpuEval::one_residual(&e, &other, true, &mut fresh);
            assert_eq!(
                (again.f, again.s, again.finert),
                (fresh.f, fresh.s, fresh.finert)
            );
        }
        let mut statics = memo;
        CpuEval::one_residual(&e, &i2, false, &mut statics);
        assert_eq!((statics.finert, statics.forces_of), ([0.0; NDOF], None));
    }
}

#[test]
fn vector_lane_tangents_are_bit_identical_to_one_pass_per_column() {
    // the dual reference takes one vector-dual pass with 9 lanes (node 1's translation
    // columns are the negated node 2's); each lane must do exactly the arithmetic of its
    // own scalar pass, or the two references would not check the same thing
    let mut rng = Lcg(41);
    for _ in 0..50 {
        let (e, s) = random_case(&mut rng, 0.1);
        let (f, k) = internal_force_tangent_dual(&e, &s);
        let (fr, kr) = internal_force_tangent_columns(&e, &s);
        assert_eq!(f, fr);
        assert_eq!(k, kr);
    }
}

/// max |K − K_ref| / max |K_ref|
fn rel_diff(k: &Mat12, kr: &Mat12) -> f64 {
    let scale = kr.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
    let d = (0..NDOF)
        .flat_map(|i| (0..NDOF).map(move |j| (i, j)))
        .map(|(i, j)| (k[i][j] - kr[i][j]).abs())
        .fold(0.0, f64::max);
    d / scale
}

/// An element whose node 1 is bent by `angle` about t_c3 (node 2 by a random fraction
/// of it): node 1's y axis n tilts towards the chord, n·t_c2 = cos(angle), so a/b and its
/// derivative grow without bound as the angle nears 90° (the convected frame's singular
/// position, far beyond the element's range of 60°).
fn near_singular_case(rng: &mut Lcg, angle: f64) -> (ElemData, ElemState) {
    let (e, mut s) = random_case(rng, 0.02);
    let (t1, t2) = node_frames(&e, &s);
    let k = kinematics(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
    let ax = [k.tc[0][2], k.tc[1][2], k.tc[2][2]];
    s.r1 = mat_mul(&rot_exp(scale(ax, angle)), &s.r1);
    s.r2 = mat_mul(&rot_exp(scale(ax, angle * rng.next())), &s.r2);
    (e, s)
}

#[test]
fn closed_form_tangent_equals_the_dual_number_tangent_to_round_off() {
    // The Newton Jacobian changed route (closed form instead of the dual pass); it must
    // be the same matrix, or the iterations would lose their quadratic convergence. Cases:
    // large rotations with small to large deformation, twisted nodes (torsion near the
    // range limit), and node 1 turned about the chord nearly to the frame's singular
    // position (n·t_c2 → 0, where a/b and its derivative blow up). f must be unchanged.
    let mut rng = Lcg(2026);
    let mut worst = 0.0f64;
    let check = |e: &ElemData, s: &ElemState, what: &str, worst: &mut f64| {
        let (f, k) = internal_force_tangent(e, s);
        let (fr, kr) = internal_force_tangent_dual(e, s);
        assert_eq!(f, fr, "{what}: f changed");
        let d = rel_diff(&k, &kr);
        assert!(d < 1e-12, "{what}: max |K − K_dual| / max |K| = {d:e}");
        *worst = worst.max(d);
    };
    for case in 0..400 {
        let deform = [0.0, 1e-4, 0.02, 0.1, 0.3][case % 5];
        let (e, s) = random_case(&mut rng, deform);
        check(
            &e,
            &s,
            &format!("random case {case} deform {deform}"),
            &mut worst,
        );
    }
    for case in 0..100 {
        // node 2 twisted about the chord by up to ±1 rad against node 1
        let (e, mut s) = random_case(&mut rng, 0.05);
        let (t1, t2) = node_frames(&e, &s);
        let k = kinematics(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
        let ax = [k.tc[0][0], k.tc[1][0], k.tc[2][0]];
        s.r2 = mat_mul(&rot_exp(scale(ax, rng.next())), &s.r2);
        check(&e, &s, &format!("twisted case {case}"), &mut worst);
    }
    for case in 0..100 {
        let angle = [1.0, 1.3, 1.45, 1.52][case % 4] * if case % 8 < 4 { 1.0 } else { -1.0 };
        let (e, s) = near_singular_case(&mut rng, angle);
        check(
            &e,
            &s,
            &format!("near-singular case {case} angle {angle}"),
            &mut worst,
        );
    }
    eprintln!("closed-form vs dual tangent: worst max|ΔK|/max|K| = {worst:e}");
}

#[test]
fn inertia_from_gradient_time_derivatives_equals_the_hyper_dual_reference() {
    // M, S and C from one dual-number pass of the closed-form field gradients (ġ along
    // the nodal velocities, with the spin-ordering correction of `inertia_full`) against M
    // from the f64 gradients and S, C from one hyper-dual pass over the position field
    // per column: independent routes. A wrong sign or a missing term shows at O(1); the
    // routes' round-off (each sums ~10³ products) measured 1.5e-15 of C's largest entry,
    // 6.6e-16 of S's, M identical; 1e-13 (~500 ulp) leaves room for other states
    // without hiding a real term
    let mut rng = Lcg(41);
    for case in 0..50 {
        let (e, s) = random_case(&mut rng, 0.1);
        let v: Vec12 = std::array::from_fn(|_| 3.0 * rng.next());
        let (m, sv, c) = inertia(&e, &s, &v);
        let (mr, svr, cr) = inertia_columns(&e, &s, &v);
        let ms = mr.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
        let cs = cr.iter().map(|r| max_abs(r)).fold(0.0, f64::max);
        let ss = max_abs(&svr);
        for i in 0..NDOF {
            assert!(
                (sv[i] - svr[i]).abs() <= 1e-13 * ss,
                "case {case} S[{i}] {} vs {}",
                sv[i],
                svr[i]
            );
            for j in 0..NDOF {
                assert!(
                    (m[i][j] - mr[i][j]).abs() <= 1e-13 * ms,
                    "case {case} M[{i}][{j}]"
                );
                assert!(
                    (c[i][j] - cr[i][j]).abs() <= 1e-13 * cs,
                    "case {case} C[{i}][{j}] {} vs {}",
                    c[i][j],
                    cr[i][j]
                );
            }
        }
    }
}

#[test]
fn second_order_jets_give_the_hyper_dual_second_derivative_bit_for_bit() {
    // the production S takes H(v, v) from one Jet2 pass instead of a hyper-dual pass
    // along (v, v); the jets form the same products in the same order, so nothing moves
    let mut rng = Lcg(11);
    for _ in 0..100 {
        let (e, s) = random_case(&mut rng, 0.1);
        let v: Vec12 = std::array::from_fn(|_| 3.0 * rng.next());
        let (t1, t2) = node_frames(&e, &s);
        let pos = (s.u1, s.u2, &t1, &t2);
        let jets = super::inertia::field_jets(&e, pos, &v);
        // what production takes: the second-order parts alone, reduced as they are formed
        let second = super::inertia::field_second(&e, pos, &v);
        let hd = super::inertia::field_derivs(&e, &s, &t1, &t2, &v, &v);
        for ((jg, hg), sg) in jets.iter().zip(&hd).zip(&second) {
            for ((jf, hf), sf) in jg.iter().zip(hg).zip(sg) {
                for ((j, h), x) in jf.iter().zip(hf).zip(sf) {
                    assert_eq!((j.v, j.d, j.d, j.dd), (h.v, h.a, h.b, h.ab));
                    assert_eq!(x.to_bits(), h.ab.to_bits());
                }
            }
        }
    }
}

#[test]
fn factored_field_products_equal_the_gradient_rows_to_round_off() {
    // M x, M v and S from the factored gradients (no 36 × 12 rows) against the rows:
    // M = Σ w gᵀg formed explicitly, S projected through the rows
    let mut rng = Lcg(23);
    for case in 0..200 {
        let (e, s) = random_case(&mut rng, 0.1);
        let v: Vec12 = std::array::from_fn(|_| if case % 7 == 0 { 0.0 } else { 3.0 * rng.next() });
        let acc: Vec12 = std::array::from_fn(|_| 10.0 * rng.next());
        let (t1, t2) = node_frames(&e, &s);
        let g = gradient(e.chord0, e.l0, s.u1, s.u2, &t1, &t2);
        let new = super::inertia::inertia_forces(&e, &s, &g, &(t1, t2), &v, &acc);
        let (m, sv, _) = reference::inertia_columns(&e, &s, &v);
        let ma: Vec12 = std::array::from_fn(|i| (0..NDOF).map(|j| m[i][j] * acc[j]).sum());
        let mv: Vec12 = std::array::from_fn(|i| (0..NDOF).map(|j| m[i][j] * v[j]).sum());
        let scale = max_abs(&ma).max(max_abs(&sv)).max(max_abs(&mv)).max(1e-300);
        for i in 0..NDOF {
            assert!(
                (new.finert[i] - (ma[i] + sv[i])).abs() <= 1e-12 * scale,
                "finert[{i}] case {case}"
            );
            assert!(
                (new.mv[i] - mv[i]).abs() <= 1e-12 * scale,
                "mv[{i}] case {case}"
            );
            assert!(
                (new.s[i] - sv[i]).abs() <= 1e-12 * scale,
                "s[{i}] case {case}"
            );
        }
    }
}

/// Every number of an output as bits (so +0 and −0, and NaN payloads, count as different).
fn out_bits(o: &ElemOut, matrices: bool) -> Vec<u64> {
    let mut b: Vec<u64> =
        o.f.iter()
            .chain(&o.s)
            .chain(&o.finert)
            .chain(&o.mv)
            .map(|x| x.to_bits())
            .collect();
    b.push(o.energy.to_bits());
    if matrices {
        b.extend(
            o.k.iter()
                .chain(&o.m)
                .chain(&o.c)
                .flatten()
                .map(|x| x.to_bits()),
        );
    }
    b
}

/// Eleven elements with their own sections and lengths (two full groups of four lanes and
/// a partial one), every third at rest, so lanes mix moving and resting elements.
fn lane_cases(seed: u64) -> (Vec<ElemData>, Vec<ElemIn>) {
    let mut rng = Lcg(seed);
    (0..11)
        .map(|c| {
            let (mut e, s, v12, acc) = random_motion(&mut rng, c % 3 == 0);
            let f = 1.0 + 0.5 * rng.next();
            let p = &mut e.props;
            (p.ea, p.eiy, p.eiz, p.gj) = (p.ea * f, p.eiy / f, p.eiz * f * f, p.gj * (2.0 - f));
            (p.rho_a, p.rho_iy, p.rho_iz) = (p.rho_a * f, p.rho_iy * f * f, p.rho_iz / f);
            (e, ElemIn { state: s, v12, acc })
        })
        .unzip()
}

#[test]
fn elements_in_simd_lanes_give_the_bits_each_element_gives_alone() {
    // the stage evaluates four elements per lane group; a variant's numbers must not
    // depend on which elements (of its own or of other variants) share its lanes
    let (elems, inputs) = lane_cases(31);
    for inertia in [true, false] {
        let mut lanes = vec![ElemOut::default(); elems.len()];
        CpuEval
            .evaluate(&elems, &inputs, inertia, &mut lanes)
            .unwrap();
        let mut res = vec![ElemOut::default(); elems.len()];
        CpuEval
            .evaluate_residual(&elems, &inputs, inertia, &mut res)
            .unwrap();
        for (k, (e, i)) in elems.iter().zip(&inputs).enumerate() {
            let mut alone = ElemOut::default();
            CpuEval::one(e, i, inertia, &mut alone);
            assert_eq!(
                out_bits(&lanes[k], true),
                out_bits(&alone, true),
                "full, element {k}"
            );
            assert_eq!(lanes[k].forces_of, alone.forces_of);
            let mut alone = ElemOut::default();
            CpuEval::one_residual(e, i, inertia, &mut alone);
            assert_eq!(
                out_bits(&res[k], false),
                out_bits(&alone, false),
                "residual, element {k}"
            );
            assert_eq!(res[k].forces_of, alone.forces_of);
        }
    }
}

#[test]
fn a_batch_fills_lanes_across_requests_and_each_request_keeps_its_own_bits() {
    // requests of different lengths and kinds (full, residual-only after a full one at
    // the same positions, i.e. memoised, and without inertia) in one batched call
    let (elems, inputs) = lane_cases(37);
    let parts = [0..5, 5..7, 7..11];
    let mut outs: Vec<Vec<ElemOut>> = parts
        .iter()
        .map(|r| vec![ElemOut::default(); r.len()])
        .collect();
    // the second request was evaluated in full before: its residual reuses the forces
    CpuEval
        .evaluate(&elems[5..7], &inputs[5..7], true, &mut outs[1])
        .unwrap();
    let mut later = inputs.clone();
    for i in later.iter_mut() {
        i.acc = i.acc.map(|a| 0.5 * a + 1.0);
    }
    let kinds = [(false, true), (true, true), (true, false)];
    let mut expect = outs.clone();
    for ((r, (residual, inertia)), o) in parts.iter().zip(kinds).zip(expect.iter_mut()) {
        for ((e, i), o) in elems[r.clone()]
            .iter()
            .zip(&later[r.clone()])
            .zip(o.iter_mut())
        {
            if residual {
                CpuEval::one_residual(e, i, inertia, o);
            } else {
                CpuEval::one(e, i, inertia, o);
            }
        }
    }
    let mut reqs: Vec<EvalRequest<'_>> = parts
        .iter()
        .zip(kinds)
        .zip(outs.iter_mut())
        .map(|((r, (residual, inertia)), out)| EvalRequest {
            elems: &elems[r.clone()],
            inputs: &later[r.clone()],
            out,
            residual,
            inertia,
        })
        .collect();
    CpuEval.evaluate_batch(&mut reqs).unwrap();
    for (k, ((o, x), (residual, _))) in outs.iter().zip(&expect).zip(kinds).enumerate() {
        for (a, b) in o.iter().zip(x) {
            assert_eq!(
                out_bits(a, !residual),
                out_bits(b, !residual),
                "request {k}"
            );
            assert_eq!(a.forces_of, b.forces_of, "request {k}");
        }
    }
}

#[test]
fn every_number_types_multiply_add_is_its_product_plus_the_addend_rounded_as_f64_rounds_it() {
    // `Real::madd` is how the stage fuses its multiply-add streams; the lanes, duals and
    // jets must round it as the plain f64 evaluation does (values of a dual or a lane
    // bit-identical to f64's `madd`), a jet's second derivative must keep the hyper-dual
    // one's bits along (u, u) (S comes from jets, its reference from hyper-duals), and each
    // part must be the product rule's a·b + c to round-off.
    use super::ad::{Dual, DualVec, HyperDual, Jet2, Real, F4};
    let mut rng = Lcg(24);
    // to round-off of the terms' sizes (a sum that cancels keeps their absolute error)
    let close = |x: f64, terms: &[f64]| {
        let y: f64 = terms.iter().sum();
        (x - y).abs() <= 4.0 * f64::EPSILON * terms.iter().map(|t| t.abs()).sum::<f64>()
    };
    for _ in 0..200 {
        let r: [f64; 9] = std::array::from_fn(|_| 10.0 * rng.next());
        let f = r[0].madd(r[1], r[2]);
        assert!(close(f, &[r[0] * r[1], r[2]]));
        let lanes = F4::splat(r[0]).madd(F4::splat(r[1]), F4::splat(r[2]));
        assert!(lanes.to_array().iter().all(|x| x.to_bits() == f.to_bits()));

        let (a, b, c) = (
            Dual::new(r[0], r[3]),
            Dual::new(r[1], r[4]),
            Dual::new(r[2], r[5]),
        );
        let m = a.madd(b, c);
        assert_eq!(m.v.to_bits(), f.to_bits());
        assert!(close(m.d, &[r[0] * r[4], r[3] * r[1], r[5]]));
        let dv = DualVec::<1>::new(r[0], [r[3]])
            .madd(DualVec::new(r[1], [r[4]]), DualVec::new(r[2], [r[5]]));
        assert_eq!(
            (dv.v.to_bits(), dv.d[0].to_bits()),
            (f.to_bits(), m.d.to_bits())
        );

        let (ja, jb, jc) = (
            Jet2::new(r[0], r[3], r[6]),
            Jet2::new(r[1], r[4], r[7]),
            Jet2::new(r[2], r[5], r[8]),
        );
        let h = |j: Jet2| HyperDual::new(j.v, j.d, j.d, j.dd);
        let jm = ja.madd(jb, jc);
        let hm = h(ja).madd(h(jb), h(jc));
        assert_eq!(
            [jm.v, jm.d, jm.d, jm.dd].map(f64::to_bits),
            [hm.v, hm.a, hm.b, hm.ab].map(f64::to_bits)
        );
        assert_eq!(
            (jm.v.to_bits(), jm.d.to_bits()),
            (f.to_bits(), m.d.to_bits())
        );
        let second = [r[0] * r[7], 2.0 * r[3] * r[4], r[6] * r[1], r[8]];
        assert!(close(jm.dd, &second), "{} vs {second:?}", jm.dd);
        // and the plain products keep the same agreement
        let (jp, hp) = (ja * jb, h(ja) * h(jb));
        assert_eq!(
            [jp.v, jp.d, jp.d, jp.dd].map(f64::to_bits),
            [hp.v, hp.a, hp.b, hp.ab].map(f64::to_bits)
        );
    }
}
