//! Frequency extraction from simulated signals: Hann-windowed, zero-padded FFT with
//! Gaussian (log-parabolic) interpolation of the spectral peak.
//!
//! For a pure tone sampled over N_p periods the Hann main lobe is 4/N_p wide in relative
//! frequency; interpolating the log-magnitude of the three bins around the peak locates it
//! to a fraction of a bin, and the peak is then refined by a golden-section search on the
//! explained energy of a windowed least-squares sinusoid fit, which is exact for a pure
//! tone with an offset. Residual error below
//! 1e-5 relative for records of 5 periods or more (tested below).

use rustfft::{num_complex::Complex, FftPlanner};

/// Magnitude spectrum of a record: Hann window, weighted mean removed, zero-padded to
/// 8× (rounded up to a power of two).
pub struct Spectrum {
    /// bin spacing of the padded FFT [Hz] (finer than the resolution)
    pub df: f64,
    /// magnitude of bins 0..nfft/2
    pub mag: Vec<f64>,
    /// frequency resolution 1/T [Hz], T = n·dt the record length: two lines closer than
    /// this cannot be told apart (the Hann main lobe is ±2/T wide)
    pub resolution: f64,
    win: Vec<f64>,
}

/// A local maximum of a [`Spectrum`].
#[derive(Clone, Copy, Debug)]
pub struct Peak {
    /// frequency of the peak bin [Hz] (not interpolated; see [`Spectrum::refine`])
    pub f: f64,
    /// magnitude of the peak bin
    pub mag: f64,
    bin: usize,
}

impl Spectrum {
    /// None when the record is too short (fewer than 8 samples) or `dt` is not positive.
    pub fn new(x: &[f64], dt: f64) -> Option<Spectrum> {
        let n = x.len();
        if n < 8 || dt <= 0.0 {
            return None;
        }
        let win: Vec<f64> = (0..n)
            .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64).cos())
            .collect();
        let wsum: f64 = win.iter().sum();
        let mean = x.iter().zip(&win).map(|(v, w)| v * w).sum::<f64>() / wsum;
        let y: Vec<f64> = x.iter().zip(&win).map(|(v, w)| (v - mean) * w).collect();
        let nfft = (8 * n).next_power_of_two();
        let mut buf = vec![Complex::new(0.0, 0.0); nfft];
        for (b, v) in buf.iter_mut().zip(&y) {
            *b = Complex::new(*v, 0.0);
        }
        FftPlanner::new().plan_fft_forward(nfft).process(&mut buf);
        Some(Spectrum {
            df: 1.0 / (nfft as f64 * dt),
            mag: buf[..nfft / 2].iter().map(|c| c.norm()).collect(),
            resolution: 1.0 / (n as f64 * dt),
            win,
        })
    }

    /// Bin index range [lo, hi] covering f_min..f_max, None when empty.
    fn band(&self, f_min: f64, f_max: f64) -> Option<(usize, usize)> {
        let lo = ((f_min / self.df).floor() as usize).max(1);
        let hi = ((f_max / self.df).ceil() as usize).min(self.mag.len() - 1);
        (lo + 1 < hi).then_some((lo, hi))
    }

    /// Median bin magnitude between f_min and f_max: the noise floor a line must
    /// stand above (lines occupy few bins, so the median sees the floor).
    pub fn median(&self, f_min: f64, f_max: f64) -> f64 {
        let Some((lo, hi)) = self.band(f_min, f_max) else {
            return f64::NAN;
        };
        let mut v: Vec<f64> = self.mag[lo..=hi].to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    /// Every local maximum between f_min and f_max, strongest first.
    pub fn peaks(&self, f_min: f64, f_max: f64) -> Vec<Peak> {
        let Some((lo, hi)) = self.band(f_min, f_max) else {
            return Vec::new();
        };
        let m = &self.mag;
        let mut out: Vec<Peak> = (lo.max(1)..=hi.min(m.len() - 2))
            .filter(|&k| m[k] > 0.0 && m[k] > m[k - 1] && m[k] >= m[k + 1])
            .map(|k| Peak {
                f: k as f64 * self.df,
                mag: m[k],
                bin: k,
            })
            .collect();
        out.sort_by(|a, b| b.mag.total_cmp(&a.mag));
        out
    }

    /// Refined frequency [Hz] of a peak of this spectrum (`x`, `dt`: the record it was
    /// made from), as [`dominant_frequency`] refines the strongest one.
    pub fn refine(&self, x: &[f64], dt: f64, p: &Peak) -> f64 {
        self.refine_bin(x, dt, p.bin)
    }

    /// Interpolated and fitted frequency of the peak at bin k (0 < k < len − 1).
    fn refine_bin(&self, x: &[f64], dt: f64, k: usize) -> f64 {
        let (df, win) = (self.df, &self.win);
        let mag = |k: usize| self.mag[k];
        let (a, b, c) = (mag(k - 1).ln(), mag(k).ln(), mag(k + 1).ln());
        let denom = a - 2.0 * b + c;
        let delta = if denom.abs() > 0.0 {
            0.5 * (a - c) / denom
        } else {
            0.0
        };
        let f0 = (k as f64 + delta.clamp(-0.5, 0.5)) * df;
        // refine by the windowed least-squares fit of c + a cos ωt + b sin ωt: its explained
        // energy peaks exactly at the frequency of a pure real tone, with no bias from the
        // tone's negative-frequency image or an offset (which shift a plain DTFT peak)
        let dtft = |f: f64| -> f64 {
            let w = 2.0 * std::f64::consts::PI * f * dt;
            let mut g = [[0.0; 3]; 3];
            let mut r = [0.0; 3];
            for (i, v) in x.iter().enumerate() {
                let (sn, cs) = (w * i as f64).sin_cos();
                let basis = [1.0, cs, sn];
                for p in 0..3 {
                    r[p] += win[i] * basis[p] * v;
                    for q in 0..3 {
                        g[p][q] += win[i] * basis[p] * basis[q];
                    }
                }
            }
            let mut coef = r;
            if crate::linalg::dense_solve(&g.concat(), 3, &mut coef).is_err() {
                return 0.0;
            }
            coef.iter().zip(&r).map(|(c, b)| c * b).sum()
        };
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut a, mut b) = (f0 - df, f0 + df);
        let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
        let (mut fc, mut fd) = (dtft(c), dtft(d));
        for _ in 0..60 {
            if fc > fd {
                b = d;
                d = c;
                fd = fc;
                c = b - g * (b - a);
                fc = dtft(c);
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + g * (b - a);
                fd = dtft(d);
            }
            if b - a < 1e-10 * f0.abs().max(df) {
                break;
            }
        }
        0.5 * (a + b)
    }
}

/// Frequency [Hz] of the strongest spectral peak of `x` (uniform samples every `dt`
/// seconds) between `f_min` and `f_max`. None when the record is too short or flat.
pub fn dominant_frequency(x: &[f64], dt: f64, f_min: f64, f_max: f64) -> Option<f64> {
    let sp = Spectrum::new(x, dt)?;
    let (lo, hi) = sp.band(f_min, f_max)?;
    let k = (lo..=hi).max_by(|&a, &b| sp.mag[a].total_cmp(&sp.mag[b]))?;
    if sp.mag[k] == 0.0 || k == 0 || k + 1 >= sp.mag.len() {
        return None;
    }
    Some(sp.refine_bin(x, dt, k))
}

/// Frequencies of upward zero crossings of `x` about its mean: the mean period between
/// the first and last crossing (linear interpolation between samples). Robust for
/// clean single-mode signals; used to cross-check the FFT.
pub fn zero_crossing_frequency(t: &[f64], x: &[f64]) -> Option<f64> {
    let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
    let mut cross = Vec::new();
    for i in 1..x.len() {
        let (a, b) = (x[i - 1] - mean, x[i] - mean);
        if a < 0.0 && b >= 0.0 {
            cross.push(t[i - 1] + (t[i] - t[i - 1]) * (-a) / (b - a));
        }
    }
    if cross.len() < 2 {
        return None;
    }
    Some((cross.len() - 1) as f64 / (cross[cross.len() - 1] - cross[0]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refined_fft_peak_recovers_a_tone_to_1e_5_from_five_periods() {
        for &(f, periods, phase) in &[(1.37, 5.0, 0.3), (2.9, 7.3, 1.1), (0.41, 12.0, 2.0)] {
            let dt = 1.0 / (f * 40.0);
            let n = (periods / f / dt) as usize;
            let x: Vec<f64> = (0..n)
                .map(|i| (2.0 * std::f64::consts::PI * f * i as f64 * dt + phase).sin() + 0.2)
                .collect();
            let got = dominant_frequency(&x, dt, 0.1 * f, 10.0 * f).unwrap();
            assert!(((got - f) / f).abs() < 1e-5, "f={f}: {got}");
        }
    }

    #[test]
    fn strongest_of_two_tones_is_found_inside_the_band() {
        let dt = 0.01;
        let x: Vec<f64> = (0..2000)
            .map(|i| {
                let t = i as f64 * dt;
                (2.0 * std::f64::consts::PI * 1.0 * t).sin()
                    + 0.3 * (2.0 * std::f64::consts::PI * 7.0 * t).sin()
            })
            .collect();
        let f = dominant_frequency(&x, dt, 3.0, 20.0).unwrap();
        assert!((f - 7.0).abs() < 1e-3, "{f}");
    }
}
