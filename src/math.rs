//! Small fixed-size linear algebra and rotations, f64, allocation-free.
//!
//! `Vec3 = [f64; 3]`, `Mat3 = [[f64; 3]; 3]` indexed `m[row][col]`; a rotation matrix's
//! columns are the rotated frame's axes in global coordinates.

pub type Vec3 = [f64; 3];
pub type Mat3 = [[f64; 3]; 3];

pub const I3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

#[inline]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}
#[inline]
pub fn normalize(a: Vec3) -> Vec3 {
    scale(a, 1.0 / norm(a))
}
#[inline]
pub fn col(m: &Mat3, j: usize) -> Vec3 {
    [m[0][j], m[1][j], m[2][j]]
}
#[inline]
pub fn from_cols(a: Vec3, b: Vec3, c: Vec3) -> Mat3 {
    [[a[0], b[0], c[0]], [a[1], b[1], c[1]], [a[2], b[2], c[2]]]
}
#[inline]
pub fn mat_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}
#[inline]
pub fn mat_t_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}
pub fn transpose(a: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[j][i];
        }
    }
    c
}
pub fn skew(a: Vec3) -> Mat3 {
    [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]]
}

/// Rotation matrix exp(skew(phi)) (Rodrigues), accurate for small and large angles.
pub fn rot_exp(phi: Vec3) -> Mat3 {
    let th2 = dot(phi, phi);
    let th = th2.sqrt();
    // series below 1e-4 keeps full f64 accuracy of sin(θ)/θ and (1-cos θ)/θ²
    let (a, b) = if th < 1e-4 {
        (1.0 - th2 / 6.0, 0.5 - th2 / 24.0)
    } else {
        (th.sin() / th, (1.0 - th.cos()) / th2)
    };
    let k = skew(phi);
    let k2 = mat_mul(&k, &k);
    let mut r = I3;
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] += a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

/// Rotation about a unit axis by angle theta.
pub fn rot_axis(axis: Vec3, theta: f64) -> Mat3 {
    rot_exp(scale(axis, theta))
}

/// Rotation vector of a rotation matrix (inverse of `rot_exp`), angle in [0, π].
pub fn rot_log(r: &Mat3) -> Vec3 {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let c = ((tr - 1.0) * 0.5).clamp(-1.0, 1.0);
    let w = [r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]];
    let s = 0.5 * norm(w);
    let th = s.atan2(c);
    if th < 1e-6 {
        return scale(w, 0.5 * (1.0 + th * th / 6.0));
    }
    if th < std::f64::consts::PI - 1e-6 {
        return scale(w, th / (2.0 * s));
    }
    // near π: axis from the symmetric part, sign from w where it is informative
    let mut axis = [0.0; 3];
    let d = [r[0][0], r[1][1], r[2][2]];
    let k = if d[0] >= d[1] && d[0] >= d[2] {
        0
    } else if d[1] >= d[2] {
        1
    } else {
        2
    };
    axis[k] = ((d[k] - c) / (1.0 - c)).max(0.0).sqrt();
    for j in 0..3 {
        if j != k {
            axis[j] = (r[j][k] + r[k][j]) / (2.0 * (1.0 - c) * axis[k]);
        }
    }
    let axis = normalize(axis);
    let sign = if dot(axis, w) < 0.0 { -1.0 } else { 1.0 };
    scale(axis, sign * th)
}

/// Re-orthonormalise a rotation matrix drifting through round-off (polar-like, one step).
pub fn orthonormalize(r: &Mat3) -> Mat3 {
    let x = normalize(col(r, 0));
    let z = normalize(cross(x, col(r, 1)));
    let y = cross(z, x);
    from_cols(x, y, z)
}

/// A unit vector perpendicular to `x`, as close as possible to `hint`
/// (Gram-Schmidt); falls back to a coordinate axis if `hint` is parallel to `x`.
pub fn perpendicular(x: Vec3, hint: Vec3) -> Vec3 {
    let x = normalize(x);
    let try_hint = |h: Vec3| {
        let p = sub(h, scale(x, dot(h, x)));
        let n = norm(p);
        if n > 1e-8 * norm(h).max(1e-300) {
            Some(scale(p, 1.0 / n))
        } else {
            None
        }
    };
    if let Some(p) = try_hint(hint) {
        return p;
    }
    for h in [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]] {
        if let Some(p) = try_hint(h) {
            if dot(h, x).abs() < 0.9 {
                return p;
            }
        }
    }
    try_hint([1.0, 0.0, 0.0]).unwrap_or([0.0, 1.0, 0.0])
}

/// Eigenvalues of a symmetric 3×3 matrix, ascending (the trigonometric closed form of
/// Smith, CACM 4(4) 1961): to round-off of the largest magnitude for distinct ones, to
/// about √ε of it for a double one, where the arccosine's argument sits at ±1; their sum
/// is the trace to round-off.
pub fn sym3_eigenvalues(a: &Mat3) -> [f64; 3] {
    let p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if p1 == 0.0 {
        let mut d = [a[0][0], a[1][1], a[2][2]];
        d.sort_by(f64::total_cmp);
        return d;
    }
    let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let p2 = (a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let mut b = *a;
    for (i, row) in b.iter_mut().enumerate() {
        for x in row.iter_mut() {
            *x /= p;
        }
        row[i] -= q / p;
    }
    let det = dot(col(&b, 0), cross(col(&b, 1), col(&b, 2)));
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let hi = q + 2.0 * p * phi.cos();
    let lo = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    [lo, 3.0 * q - hi - lo, hi]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sym3_eigenvalues_recover_a_rotated_diagonal() {
        let r = rot_exp([0.3, -0.7, 1.1]);
        for d in [
            [1.0, 2.0, 4.0],
            [3.0, 3.0, 5.0],
            [2.0, 2.0, 2.0],
            [1e-6, 1.0, 1.0],
        ] {
            let dm = [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]];
            let j = mat_mul(&mat_mul(&r, &dm), &transpose(&r));
            let e = sym3_eigenvalues(&j);
            // √ε ≈ 1.5e-8 of the scale near a double eigenvalue (measured 1.7e-8 for
            // [3, 3, 5] against 5)
            for k in 0..3 {
                assert!((e[k] - d[k]).abs() < 1e-7 * d[2], "{d:?}: {e:?}");
            }
            let tr = j[0][0] + j[1][1] + j[2][2];
            assert!((e.iter().sum::<f64>() - tr).abs() < 1e-14 * tr);
        }
    }

    #[test]
    #[allow(clippy::approx_constant)] // 3.14159 is meant to be just below π, not π
    fn rot_log_inverts_rot_exp_over_the_whole_angle_range() {
        for &th in &[0.0, 1e-9, 1e-5, 0.3, 1.0, 2.5, 3.1, 3.14159] {
            let axis = normalize([0.3, -0.5, 0.8]);
            let phi = scale(axis, th);
            let back = rot_log(&rot_exp(phi));
            for k in 0..3 {
                assert!(
                    (back[k] - phi[k]).abs() < 1e-9,
                    "θ={th}: {back:?} vs {phi:?}"
                );
            }
        }
    }
}
