//! The Newton system: a fixed sparsity pattern discovered once by a pattern-only assembly,
//! values refilled every iteration, faer sparse LU with the symbolic analysis reused.

use crate::assembly::{Assembler, AssemblyInfo, Coeffs, PatternSink, Sink};
use crate::joint::State;
use crate::linalg::{LinalgError, SparseLu, SparsePattern};
use crate::model::Model;

struct SparseSink<'a> {
    pattern: &'a SparsePattern,
    values: &'a mut [f64],
}
impl Sink for SparseSink<'_> {
    #[inline]
    fn add(&mut self, row: usize, col: usize, v: f64) {
        // the pattern came from the same assembly code, so every entry has a slot
        let k = self
            .pattern
            .slot(row, col)
            .expect("entry outside the assembled pattern");
        self.values[k] += v;
    }
}

pub struct NewtonSystem {
    pub pattern: SparsePattern,
    pub values: Vec<f64>,
    lu: SparseLu,
    /// by-dof generalized forces of the last evaluation
    pub gen: Vec<f64>,
    /// residual by equation
    pub r: Vec<f64>,
}

impl NewtonSystem {
    pub fn new(model: &Model, asm: &Assembler, s: &State) -> Result<NewtonSystem, LinalgError> {
        let mut ps = PatternSink::default();
        let mut gen = vec![0.0; model.dofs.len()];
        let all = Coeffs::dynamic(1.0, 1.0, 1.0);
        asm.evaluate(model, s, all, &mut gen, Some(&mut ps));
        for i in 0..asm.n_eq {
            ps.entries.push((i, i));
        }
        let pattern = SparsePattern::new(asm.n_eq, &ps.entries);
        let lu = SparseLu::new(&pattern)?;
        Ok(NewtonSystem {
            values: vec![0.0; pattern.nnz()],
            pattern,
            lu,
            gen,
            r: vec![0.0; asm.n_eq],
        })
    }

    /// Evaluate residual and Jacobian at `s`; factor the Jacobian when `factor` is set.
    pub fn evaluate(
        &mut self,
        model: &Model,
        asm: &Assembler,
        s: &State,
        c: Coeffs,
        factor: bool,
    ) -> Result<AssemblyInfo, LinalgError> {
        self.values.iter_mut().for_each(|v| *v = 0.0);
        let info = if factor {
            let mut sink = SparseSink {
                pattern: &self.pattern,
                values: &mut self.values,
            };
            asm.evaluate(model, s, c, &mut self.gen, Some(&mut sink))
        } else {
            asm.evaluate(model, s, c, &mut self.gen, None)
        };
        asm.gather(model, s, &self.gen, &mut self.r);
        if factor {
            self.lu.factor(&self.values)?;
        }
        Ok(info)
    }

    /// Solve J Δ = −r with the last factorization.
    pub fn solve_neg_residual(&self, dx: &mut [f64]) -> Result<(), LinalgError> {
        for (d, r) in dx.iter_mut().zip(&self.r) {
            *d = -r;
        }
        self.lu.solve_in_place(dx);
        if dx.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(LinalgError::NonFinite)
        }
    }
}

/// Infinity norm.
pub fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}
