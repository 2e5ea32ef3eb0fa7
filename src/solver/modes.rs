//! Linearised free vibration about a state (the reference, or the static equilibrium
//! under the model's loads): K φ = ω² M φ with K the full tangent (material and
//! geometric stiffness, so preloads stiffen or soften) and M the consistent mass.
//! Coordinates without mass (for example torsion of a section given no rotary inertia)
//! are condensed out statically first, which is exact for massless coordinates.

use crate::assembly::{Assembler, Coeffs, DenseSink};
use crate::joint::{self, State};
use crate::linalg::{dense_solve, generalized_sym_eig, LinalgError};
use crate::model::Model;

#[derive(Debug, Clone)]
pub struct Modes {
    /// natural frequencies [Hz], ascending; a negative value means an unstable
    /// (negative-stiffness) mode of that |frequency|
    pub frequencies_hz: Vec<f64>,
    /// mode shapes by equation index (column k = mode k), mass-normalised
    pub shapes: Vec<Vec<f64>>,
}

/// Dense K (tangent at load factor 1) and M at state `s`, row-major n_eq × n_eq.
pub fn matrices(model: &Model, s: &State) -> (Vec<f64>, Vec<f64>) {
    let asm = Assembler::new(model);
    let n = asm.n_eq;
    let mut gen = vec![0.0; model.dofs.len()];
    let mut k = vec![0.0; n * n];
    let mut m = vec![0.0; n * n];
    let mut s0 = s.clone();
    joint::update_kinematics(model, &mut s0);
    // stiffness: static forces only (no inertia), so the geometric terms see the preload
    asm.evaluate(
        model,
        &s0,
        Coeffs::statics(1.0),
        &mut gen,
        Some(&mut DenseSink { n, a: &mut k }),
    );
    let mut sm = s0.clone();
    sm.v.iter_mut().for_each(|x| *x = 0.0);
    sm.a.iter_mut().for_each(|x| *x = 0.0);
    asm.evaluate(
        model,
        &sm,
        Coeffs::dynamic(0.0, 0.0, 1.0),
        &mut gen,
        Some(&mut DenseSink { n, a: &mut m }),
    );
    (k, m)
}

/// Natural frequencies and mode shapes about state `s`.
pub fn modes(model: &Model, s: &State) -> Result<Modes, LinalgError> {
    let (mut k, m) = matrices(model, s);
    let n = model.n_eq;
    // symmetrise: K is symmetric at equilibrium up to round-off and spin-ordering terms
    for i in 0..n {
        for j in 0..i {
            let a = 0.5 * (k[i * n + j] + k[j * n + i]);
            k[i * n + j] = a;
            k[j * n + i] = a;
        }
    }
    let mdiag_max = (0..n).map(|i| m[i * n + i]).fold(0.0, f64::max);
    let massive: Vec<usize> = (0..n)
        .filter(|&i| m[i * n + i] > 1e-12 * mdiag_max)
        .collect();
    let massless: Vec<usize> = (0..n)
        .filter(|&i| m[i * n + i] <= 1e-12 * mdiag_max)
        .collect();
    let nm = massive.len();
    let ns = massless.len();
    let sub = |a: &[f64], rows: &[usize], cols: &[usize]| -> Vec<f64> {
        let mut o = Vec::with_capacity(rows.len() * cols.len());
        for &i in rows {
            for &j in cols {
                o.push(a[i * n + j]);
            }
        }
        o
    };
    let mut kmm = sub(&k, &massive, &massive);
    let mmm = sub(&m, &massive, &massive);
    // condensation map: x_s = T x_m with T = −K_ss⁻¹ K_sm
    let mut t = vec![0.0; ns * nm];
    if ns > 0 {
        let kss = sub(&k, &massless, &massless);
        let ksm = sub(&k, &massless, &massive);
        for c in 0..nm {
            let mut rhs: Vec<f64> = (0..ns).map(|r| -ksm[r * nm + c]).collect();
            if dense_solve(&kss, ns, &mut rhs).is_err() {
                // the massless coordinates have a free motion of their own (a free-free
                // beam's rigid twist without rotary inertia): condensation is undefined
                return regularized(&k, &m, n, &massless, mdiag_max);
            }
            for r in 0..ns {
                t[r * nm + c] = rhs[r];
            }
        }
        let kms = sub(&k, &massive, &massless);
        for i in 0..nm {
            for j in 0..nm {
                let mut acc = 0.0;
                for r in 0..ns {
                    acc += kms[i * ns + r] * t[r * nm + j];
                }
                kmm[i * nm + j] += acc;
            }
        }
        for i in 0..nm {
            for j in 0..i {
                let a = 0.5 * (kmm[i * nm + j] + kmm[j * nm + i]);
                kmm[i * nm + j] = a;
                kmm[j * nm + i] = a;
            }
        }
    }
    let (lam, vecs) = generalized_sym_eig(&kmm, &mmm, nm)?;
    let mut freqs = Vec::with_capacity(nm);
    let mut shapes = Vec::with_capacity(nm);
    for (c, l) in lam.iter().enumerate() {
        let w = l.abs().sqrt() / (2.0 * std::f64::consts::PI);
        freqs.push(if *l < 0.0 { -w } else { w });
        let mut full = vec![0.0; n];
        for (i, &gi) in massive.iter().enumerate() {
            full[gi] = vecs[c * nm + i];
        }
        for (r, &gi) in massless.iter().enumerate() {
            full[gi] = (0..nm).map(|j| t[r * nm + j] * vecs[c * nm + j]).sum();
        }
        shapes.push(full);
    }
    Ok(Modes {
        frequencies_hz: freqs,
        shapes,
    })
}

/// Fallback when massless coordinates cannot be condensed: give them a mass 1e-10 of the
/// largest diagonal mass and drop the modes that live in them (kinetic-energy share above
/// one half), which are the artificial ones.
fn regularized(
    k: &[f64],
    m: &[f64],
    n: usize,
    massless: &[usize],
    mdiag_max: f64,
) -> Result<Modes, LinalgError> {
    let eps = 1e-10 * mdiag_max;
    let mut mr = m.to_vec();
    for &i in massless {
        mr[i * n + i] += eps;
    }
    let (lam, vecs) = generalized_sym_eig(k, &mr, n)?;
    let mut freqs = Vec::new();
    let mut shapes = Vec::new();
    for (c, l) in lam.iter().enumerate() {
        let v = &vecs[c * n..(c + 1) * n];
        let share: f64 = massless.iter().map(|&i| eps * v[i] * v[i]).sum();
        if share > 0.5 {
            continue;
        }
        let w = l.abs().sqrt() / (2.0 * std::f64::consts::PI);
        freqs.push(if *l < 0.0 { -w } else { w });
        shapes.push(v.to_vec());
    }
    Ok(Modes {
        frequencies_hz: freqs,
        shapes,
    })
}
