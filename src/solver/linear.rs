//! The Newton system: a fixed sparsity pattern discovered once by a pattern-only assembly,
//! values refilled every iteration, faer sparse LU with the symbolic analysis reused.

use crate::assembly::{Assembler, AssemblyInfo, Coeffs, PatternSink, Sink};
use crate::joint::State;
use crate::linalg::{LinalgError, SparseLu, SparseLuSymbolic, SparsePattern};
use crate::model::Model;
use std::sync::Arc;
use std::time::Instant;

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

/// Wall time spent per stage of the Newton iterations, accumulated over a run.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// element arrays (mass, internal force, tangent, quadratic-velocity terms)
    pub element_s: f64,
    /// everything else of the residual/Jacobian assembly (kinematics chains, scatter)
    pub assembly_s: f64,
    /// sparse numeric LU and the solves
    pub factorization_s: f64,
    /// sensor sampling and result writing
    pub output_s: f64,
}

impl StageTimes {
    pub fn add(&mut self, o: &StageTimes) {
        self.element_s += o.element_s;
        self.assembly_s += o.assembly_s;
        self.factorization_s += o.factorization_s;
        self.output_s += o.output_s;
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
    pub times: StageTimes,
}

impl NewtonSystem {
    pub fn new(model: &Model, asm: &Assembler, s: &State) -> Result<NewtonSystem, LinalgError> {
        Self::with_symbolic(model, asm, s, None)
    }

    /// As [`NewtonSystem::new`], reusing `symbolic` when it was analysed for this very
    /// pattern (the COLAMD ordering and symbolic LU then happen once per campaign).
    pub fn with_symbolic(
        model: &Model,
        asm: &Assembler,
        s: &State,
        symbolic: Option<&Arc<SparseLuSymbolic>>,
    ) -> Result<NewtonSystem, LinalgError> {
        let mut ps = PatternSink::default();
        let mut gen = vec![0.0; model.dofs.len()];
        let all = Coeffs::dynamic(1.0, 1.0, 1.0);
        asm.evaluate(model, s, all, &mut gen, Some(&mut ps));
        for i in 0..asm.n_eq {
            ps.entries.push((i, i));
        }
        let pattern = SparsePattern::new(asm.n_eq, &ps.entries);
        let lu = match symbolic {
            Some(sym) if sym.analyses(&pattern) => SparseLu::from_symbolic(Arc::clone(sym)),
            _ => SparseLu::new(&pattern)?,
        };
        Ok(NewtonSystem {
            values: vec![0.0; pattern.nnz()],
            pattern,
            lu,
            gen,
            r: vec![0.0; asm.n_eq],
            times: StageTimes::default(),
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
        let t0 = Instant::now();
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
        let t1 = Instant::now();
        self.times.assembly_s += (t1 - t0).as_secs_f64();
        if factor {
            let r = self.lu.factor(&self.values);
            self.times.factorization_s += t1.elapsed().as_secs_f64();
            r?;
        }
        Ok(info)
    }

    /// The symbolic factorization, for sharing with other variants of the same pattern.
    pub fn symbolic(&self) -> &Arc<SparseLuSymbolic> {
        self.lu.symbolic()
    }

    /// Solve J Δ = −r with the last factorization.
    pub fn solve_neg_residual(&mut self, dx: &mut [f64]) -> Result<(), LinalgError> {
        let t0 = Instant::now();
        for (d, r) in dx.iter_mut().zip(&self.r) {
            *d = -r;
        }
        self.lu.solve_in_place(dx);
        self.times.factorization_s += t0.elapsed().as_secs_f64();
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
