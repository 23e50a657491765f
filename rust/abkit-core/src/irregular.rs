//! Gain laws for irregular sampling: the transition `Phi(dt)` and the
//! filter-form gain `K(dt)` of a kinematic filter as functions of the step
//! `dt_k = t_k - t_{k-1}`.
//!
//! Two schedules:
//!
//! - **design** (filters built from noise statistics): at every step the
//!   steady-state Kalman design for that `dt`:
//!   - alpha-beta ([`AbDesign`]): Kalata's tracking index
//!     `lambda = (sigma_w / sigma_v) dt^2` (`= 2 sqrt(r)`,
//!     `r = ((sigma_w dt^2 / 2) / sigma_v)^2`), then `(alpha, beta)` by the
//!     stable closed form of [`crate::alphabeta::kalman_uv_from_lambda`],
//!     `K = [alpha, beta / dt]`;
//!   - alpha-beta-gamma ([`AbgDesign`]): [`crate::abg::from_noise`] at
//!     `h = dt` (closed form when only the acceleration is driven, checked
//!     Riccati solver otherwise), `K = [alpha, beta/dt, gamma/dt^2]` in the
//!     paper's (Chen & Chui) convention;
//!   - Singer ([`SingerDesign`]): [`crate::singer::steady_state`] of the
//!     normalised model at `theta = dt / tau`, `q_N = q dt^5 / sigma_pos^2`
//!     (closed form with numeric fallback), back to physical units
//!     `K = [K1, K2/dt, K3/dt^2]`.
//!
//!   The two laws that need a solver keep a small cache keyed by `dt` (the
//!   last [`CACHE_SLOTS`] distinct steps), so regularly sampled or
//!   quantised timestamps cost one design per distinct step.
//! - **fixed** (filters given gains): the gains `alpha, beta, gamma` stay
//!   fixed, only the prediction and the rate gains use `dt`:
//!   `K = [alpha, beta/dt, c gamma/dt^2]` ([`AbFixed`], [`AbgFixed`]).
//!
//! All laws predict with the kinematic transition of their model:
//! `[[1, dt], [0, 1]]`, `[[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]` or the
//! Singer `Phi(dt)` of [`crate::singer::normalized_model`].
#![allow(clippy::needless_range_loop)]

use crate::alphabeta::{kalman_alpha, kalman_uv_from_lambda};
use crate::dd::{
    m3_add, m3_amax, m3_eye, m3_from, m3_mul, m3_solve, m3_spd_solve, m3_sym, m3_t, stein3, Dd, M3,
};
use crate::{Error, Result};

/// The model of one step: `x_p = phi x`, `x = x_p + k (z - H x_p)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step<const N: usize, const M: usize> {
    /// Transition over the step.
    pub phi: [[f64; N]; N],
    /// Filter-form gain.
    pub k: [[f64; M]; N],
}

/// A gain law: the step model as a function of `dt > 0`.
///
/// `step` may fail (a solver finding no steady state at that `dt`); the
/// kernels report the failure with the track and sample.
pub trait GainLaw<const N: usize, const M: usize>: Clone + Send + Sync {
    /// The step model for the interval `dt` (finite and > 0).
    fn step(&mut self, dt: f64) -> Result<Step<N, M>>;

    /// Alpha-beta laws (`N = 2`, `M = 1`, `Phi = [[1, dt], [0, 1]]`,
    /// `H = [1, 0]`): the gains `(alpha, beta / dt)` of [`GainLaw::step`],
    /// for the kernels' fast path. `None` for every other law.
    #[inline(always)]
    fn ab_gains(&mut self, _dt: f64) -> Option<(f64, f64)> {
        None
    }

    /// Alpha-beta laws the vector lanes of the track kernel compute
    /// themselves (with exactly the arithmetic of [`GainLaw::ab_gains`]).
    /// `None` for every other law.
    #[inline(always)]
    fn ab_law(&self) -> Option<AbLaw> {
        None
    }
}

/// The alpha-beta gain laws the vector lanes know.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AbLaw {
    /// Fixed gains: `K = [alpha, beta / dt]`.
    Fixed {
        /// Position gain.
        alpha: f64,
        /// Dimensionless velocity gain.
        beta: f64,
    },
    /// The steady-state Kalman design at every `dt` (`ratio = sigma_w / sigma_v`).
    Design {
        /// `sigma_w / sigma_v`.
        ratio: f64,
    },
}

/// A constant step model (the regular-sampling filter; `dt` ignored).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constant<const N: usize, const M: usize>(pub Step<N, M>);

impl<const N: usize, const M: usize> GainLaw<N, M> for Constant<N, M> {
    #[inline(always)]
    fn step(&mut self, _dt: f64) -> Result<Step<N, M>> {
        Ok(self.0)
    }
}

/// `[[1, dt], [0, 1]]`.
#[inline(always)]
pub fn phi_cv(dt: f64) -> [[f64; 2]; 2] {
    [[1.0, dt], [0.0, 1.0]]
}

/// `[[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]`.
#[inline(always)]
pub fn phi_ca(dt: f64) -> [[f64; 3]; 3] {
    [[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]]
}

/// Alpha-beta gains kept fixed: `K = [alpha, beta/dt]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbFixed {
    /// Position gain.
    pub alpha: f64,
    /// Velocity gain (dimensionless; the physical gain is `beta/dt`).
    pub beta: f64,
}

impl GainLaw<2, 1> for AbFixed {
    #[inline(always)]
    fn step(&mut self, dt: f64) -> Result<Step<2, 1>> {
        Ok(Step {
            phi: phi_cv(dt),
            k: [[self.alpha], [self.beta / dt]],
        })
    }

    #[inline(always)]
    fn ab_gains(&mut self, dt: f64) -> Option<(f64, f64)> {
        Some((self.alpha, self.beta / dt))
    }

    #[inline(always)]
    fn ab_law(&self) -> Option<AbLaw> {
        Some(AbLaw::Fixed {
            alpha: self.alpha,
            beta: self.beta,
        })
    }
}

/// The steady-state Kalman alpha-beta design of the white-acceleration
/// model at each `dt` (`ratio = sigma_w / sigma_v`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbDesign {
    /// `sigma_w / sigma_v` (finite, > 0).
    ratio: f64,
    /// `sqrt(ratio)`, taken once (the per-step law needs only it).
    sqrt_ratio: f64,
}

impl AbDesign {
    /// The design law of `ratio = sigma_w / sigma_v` (finite, > 0; the
    /// callers validate it).
    pub fn new(ratio: f64) -> Self {
        Self {
            ratio,
            sqrt_ratio: ratio.sqrt(),
        }
    }

    /// `sigma_w / sigma_v`.
    pub fn ratio(&self) -> f64 {
        self.ratio
    }

    /// `(alpha, beta)` of the Kalman design at `dt`: tracking index
    /// `lambda = ratio dt^2`, then the closed form of paper 000 (same
    /// arithmetic as [`crate::alphabeta::AlphaBeta::from_noise`]).
    /// `lambda` rounding to 0 (tiny `dt`) gives `(0, 0)`, pure prediction;
    /// `lambda = inf` gives `(1, 2)`.
    #[inline(always)]
    pub fn gains(&self, dt: f64) -> (f64, f64) {
        let lambda = self.ratio * dt * dt;
        let (u, v) = kalman_uv_from_lambda(lambda);
        (kalman_alpha(u, v), 2.0 * v * v)
    }

    /// `(alpha, beta / dt)` of the Kalman design at `dt`, the gains the
    /// filters use: [`ab_design_rate_gains`] with this law's ratio.
    #[inline(always)]
    pub fn rate_gains(&self, dt: f64) -> (f64, f64) {
        ab_design_rate_gains(self.sqrt_ratio, dt)
    }
}

/// `sqrt` of the tracking index above which [`ab_design_rate_gains`]
/// returns the limit `(1, 2 / dt)` (`lambda >= 1e300`; `alpha` rounds to 1
/// and `beta` to 2 long before).
pub const AB_DESIGN_BIG_SQRT: f64 = 1e150;

/// `sqrt` of the tracking index up to which [`ab_design_rate_gains`] forms
/// `w = (q - m) / 4` by a subtraction (`lambda <= 4`, beyond the usual
/// tracking range), above it as `2 / (m + q)` (the same number:
/// `(q - m)(q + m) = q^2 - m^2 = 8`; the subtraction's relative error grows
/// like `m^2`: max relative error of `alpha` and `beta / dt` 5.5e-16 for
/// `m <= 2` against 660-digit arithmetic, 1.4e-15 for `2 < m <= 4` and
/// 3e-15 up to 8 by the subtraction).
pub const AB_DESIGN_SMALL_SQRT: f64 = 2.0;

/// `(alpha, beta / dt)` of the steady-state Kalman alpha-beta design at
/// `dt` (`ratio = sigma_w / sigma_v`, `sqrt_ratio = sqrt(ratio)`), with one
/// square root, no division for `lambda <= 4` (one above) and seven other
/// operations (the irregular-timestamp kernels evaluate it at every step).
///
/// Paper 000's closed form in the tracking index `lambda = ratio dt^2`
/// (as in [`crate::alphabeta::kalman_uv_from_lambda`]):
/// `u = sqrt(1 - alpha) = 4 / d`, `v = 1 - u = (lambda + S) / d`,
/// `S = sqrt(lambda (lambda + 8))`, `d = lambda + S + 4`, `beta = 2 v^2`.
/// Here in `m = sqrt(lambda) = sqrt(ratio) dt`: with `q = sqrt(m^2 + 8)`,
/// `lambda + S = m (m + q)`, so `v = m (m + q) / (m (m + q) + 4)`
/// `= m w`, `w = (q - m) / 4 = 2 / (m + q)` (multiply out:
/// `(q - m)(q + m) = 8`); then `alpha = 1 - u^2 = v (2 - v)` and, since
/// `m / dt = sqrt(ratio)`, `beta / dt = 2 v^2 / dt = (2 sqrt(ratio)) v w`
/// without a division by `dt`. `w` by the subtraction for
/// `m <= `[`AB_DESIGN_SMALL_SQRT`] (`q - m >= 1.4`: no cancellation), by
/// the division above it; `2 - v` is in `[1, 2]`. Each result is within a
/// few ulp of the exact design (5.5e-16 relative against 660-digit
/// arithmetic, also where `lambda` underflows: `m` does not), and
/// `alpha <= 1` (capped, for the rounding of `v` near 1).
/// `m >= `[`AB_DESIGN_BIG_SQRT`] gives the limit `(1, 2 / dt)`. No fused
/// operations: the same bits on every CPU.
///
/// The vector lanes of the track kernel (`ragged_simd.rs`) do exactly
/// these IEEE operations in this order, so both give bit-identical gains.
#[inline(always)]
pub fn ab_design_rate_gains(sqrt_ratio: f64, dt: f64) -> (f64, f64) {
    let m = sqrt_ratio * dt;
    if m >= AB_DESIGN_BIG_SQRT {
        return (1.0, 2.0 / dt);
    }
    let q = (m * m + 8.0).sqrt();
    let w = if m <= AB_DESIGN_SMALL_SQRT {
        (q - m) * 0.25
    } else {
        2.0 / (m + q)
    };
    let v = m * w;
    let alpha = (v * (2.0 - v)).min(1.0);
    (alpha, (2.0 * sqrt_ratio) * (v * w))
}

impl GainLaw<2, 1> for AbDesign {
    #[inline(always)]
    fn step(&mut self, dt: f64) -> Result<Step<2, 1>> {
        let (a, g) = self.rate_gains(dt);
        Ok(Step {
            phi: phi_cv(dt),
            k: [[a], [g]],
        })
    }

    #[inline(always)]
    fn ab_gains(&mut self, dt: f64) -> Option<(f64, f64)> {
        Some(self.rate_gains(dt))
    }

    #[inline(always)]
    fn ab_law(&self) -> Option<AbLaw> {
        Some(AbLaw::Design { ratio: self.ratio })
    }
}

/// Backward (RTS) gain of the steady-state alpha-beta smoother at step `dt`:
/// `A = P_filt Phi^T P_pred^-1` of the design at that step, in physical
/// units `A = D A_N D^-1`, `D = diag(1, 1/dt)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AbBackward {
    /// The Kalman design at each `dt` (`ratio = sigma_w / sigma_v`):
    /// `A_N = P_N Phi_N^T M_N^-1` with the normalised filtered covariance
    /// `P_N = [[alpha, beta], [beta, c]]`, `c = 4 v^3 / u` (paper 000; see
    /// [`crate::alphabeta`]) and the predicted one from `P = (I - K H) M`:
    /// `M_N = [[alpha, beta], [beta, c u^2 + beta^2]] / u^2`.
    Design(f64),
    /// Fixed gains: a constant normalised backward gain `A_N`.
    Fixed([[f64; 2]; 2]),
}

impl AbBackward {
    /// `(Phi(dt), A(dt))`.
    pub fn at(&self, dt: f64) -> ([[f64; 2]; 2], [[f64; 2]; 2]) {
        let an = match *self {
            AbBackward::Fixed(a) => a,
            AbBackward::Design(ratio) => {
                let lambda = ratio * dt * dt;
                let (u, v) = kalman_uv_from_lambda(lambda);
                let (al, be) = (kalman_alpha(u, v), 2.0 * v * v);
                let c = 4.0 * v * v * v / u;
                let u2 = u * u;
                // P = [[al, be], [be, c]], M = [[al, be], [be, c u^2 + be^2]] / u^2;
                // A_N = P Phi_N^T M^-1 with Phi_N^T = [[1, 0], [1, 1]].
                let pp = [[al + be, be], [be + c, c]];
                let (m11, m12, m22) = (al / u2, be / u2, c + be * be / u2);
                let det = m11 * m22 - m12 * m12;
                let mi = [[m22 / det, -m12 / det], [-m12 / det, m11 / det]];
                std::array::from_fn(|i| {
                    std::array::from_fn(|j| pp[i][0] * mi[0][j] + pp[i][1] * mi[1][j])
                })
            }
        };
        (
            phi_cv(dt),
            [[an[0][0], an[0][1] * dt], [an[1][0] / dt, an[1][1]]],
        )
    }
}

/// Alpha-beta-gamma gains kept fixed: `K = [alpha, beta/dt, c gamma/dt^2]`
/// (`c` of the convention: 1/2 standard, 1 Chen & Chui, 2 g-h-k).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbgFixed {
    /// Position gain.
    pub alpha: f64,
    /// Velocity gain.
    pub beta: f64,
    /// `c * gamma`, the acceleration gain times `dt^2`.
    pub cgamma: f64,
}

impl GainLaw<3, 1> for AbgFixed {
    #[inline(always)]
    fn step(&mut self, dt: f64) -> Result<Step<3, 1>> {
        Ok(Step {
            phi: phi_ca(dt),
            k: [[self.alpha], [self.beta / dt], [self.cgamma / (dt * dt)]],
        })
    }
}

/// Number of distinct steps remembered by [`DtCache`].
pub const CACHE_SLOTS: usize = 8;

/// The last [`CACHE_SLOTS`] distinct `dt` and their step models (round robin).
#[derive(Debug, Clone, Copy)]
pub struct DtCache<const N: usize, const M: usize> {
    keys: [f64; CACHE_SLOTS],
    vals: [Step<N, M>; CACHE_SLOTS],
    next: usize,
}

impl<const N: usize, const M: usize> Default for DtCache<N, M> {
    fn default() -> Self {
        DtCache {
            keys: [f64::NAN; CACHE_SLOTS],
            vals: [Step {
                phi: [[0.0; N]; N],
                k: [[0.0; M]; N],
            }; CACHE_SLOTS],
            next: 0,
        }
    }
}

impl<const N: usize, const M: usize> DtCache<N, M> {
    /// The cached model for `dt`, or `make(dt)` (stored on success).
    #[inline]
    pub fn get(
        &mut self,
        dt: f64,
        make: impl FnOnce(f64) -> Result<Step<N, M>>,
    ) -> Result<Step<N, M>> {
        for i in 0..CACHE_SLOTS {
            if self.keys[i] == dt {
                return Ok(self.vals[i]);
            }
        }
        let s = make(dt)?;
        self.keys[self.next] = dt;
        self.vals[self.next] = s;
        self.next = (self.next + 1) % CACHE_SLOTS;
        Ok(s)
    }
}

/// The limiting Kalman alpha-beta-gamma design of Chen & Chui at each `dt`:
/// process noise variances `Q = diag(sigma_p, sigma_v, sigma_a)`, measurement
/// variance `sigma_m` (see [`crate::abg::from_noise`]).
#[derive(Debug, Clone, Copy)]
pub struct AbgDesign {
    /// `[sigma_p, sigma_v, sigma_a, sigma_m]` (variances).
    pub noise: [f64; 4],
    cache: DtCache<3, 1>,
}

impl AbgDesign {
    /// Validated law (the noise as for [`crate::abg::from_noise`]).
    pub fn new(sigma_p: f64, sigma_v: f64, sigma_a: f64, sigma_m: f64) -> Result<Self> {
        // Validate once at a unit step (domain errors name the parameter).
        crate::abg::from_noise(sigma_p, sigma_v, sigma_a, sigma_m, 1.0)?;
        Ok(AbgDesign {
            noise: [sigma_p, sigma_v, sigma_a, sigma_m],
            cache: DtCache::default(),
        })
    }

    /// The Chen & Chui gains `[alpha, beta, gamma]` at `dt`.
    pub fn gains(&self, dt: f64) -> Result<[f64; 3]> {
        abg_gains(self.noise, dt)
    }
}

fn abg_gains(noise: [f64; 4], dt: f64) -> Result<[f64; 3]> {
    let [sp, sv, sa, sm] = noise;
    crate::abg::from_noise(sp, sv, sa, sm, dt)
}

impl GainLaw<3, 1> for AbgDesign {
    fn step(&mut self, dt: f64) -> Result<Step<3, 1>> {
        let noise = self.noise;
        self.cache.get(dt, |dt| {
            let [a, b, g] = abg_gains(noise, dt)?;
            Ok(Step {
                phi: phi_ca(dt),
                k: [[a], [b / dt], [g / (dt * dt)]],
            })
        })
    }
}

/// The steady-state Kalman filter of the Singer model (position-only
/// measurements) at each `dt`.
#[derive(Debug, Clone, Copy)]
pub struct SingerDesign {
    /// Manoeuvre correlation time (> 0, `inf` allowed).
    pub tau: f64,
    /// White-noise spectral density of the acceleration (> 0).
    pub q: f64,
    /// Rms position measurement error (> 0).
    pub sigma_pos: f64,
    cache: DtCache<3, 1>,
}

impl SingerDesign {
    /// Validated law.
    pub fn new(tau: f64, q: f64, sigma_pos: f64) -> Result<Self> {
        if tau.is_nan() || tau <= 0.0 {
            return Err(Error::domain("tau", "> 0 (inf allowed)", tau));
        }
        if !(q.is_finite() && q > 0.0) {
            return Err(Error::domain("q", "finite and > 0", q));
        }
        if !(sigma_pos.is_finite() && sigma_pos > 0.0) {
            return Err(Error::domain("sigma_pos", "finite and > 0", sigma_pos));
        }
        Ok(SingerDesign {
            tau,
            q,
            sigma_pos,
            cache: DtCache::default(),
        })
    }

    /// The physical step model at `dt` (uncached).
    pub fn design(&self, dt: f64) -> Result<Step<3, 1>> {
        singer_step(self.tau, self.q, self.sigma_pos, dt)
    }
}

/// The normalised Singer steady state at `dt` (`theta = dt / tau`,
/// `q_N = q dt^5 / sigma_pos^2`) and the scaling `d = [1, dt, dt^2]` back
/// to physical units (`x_N = diag(d) x`).
fn singer_steady(
    tau: f64,
    q: f64,
    sigma_pos: f64,
    dt: f64,
) -> Result<(crate::singer::SteadyState, [f64; 3])> {
    let theta = dt / tau;
    let s = dt * dt / sigma_pos;
    let qn = q * dt * s * s;
    if !(qn.is_finite() && qn > 0.0) {
        return Err(Error::domain(
            "q dt^5 / sigma_pos^2",
            "representable as a finite, positive float64 (dt too small or too large)",
            qn,
        ));
    }
    let ss = crate::singer::steady_state(theta, qn, f64::INFINITY, crate::singer::Method::Auto)?;
    Ok((ss, [1.0, dt, dt * dt]))
}

fn singer_step(tau: f64, q: f64, sigma_pos: f64, dt: f64) -> Result<Step<3, 1>> {
    let (ss, d) = singer_steady(tau, q, sigma_pos, dt)?;
    Ok(Step {
        phi: std::array::from_fn(|i| std::array::from_fn(|j| ss.phi[(i, j)] * d[j] / d[i])),
        k: std::array::from_fn(|i| [ss.k[i][0] / d[i]]),
    })
}

impl GainLaw<3, 1> for SingerDesign {
    fn step(&mut self, dt: f64) -> Result<Step<3, 1>> {
        let (tau, q, sp) = (self.tau, self.q, self.sigma_pos);
        self.cache.get(dt, |dt| singer_step(tau, q, sp, dt))
    }
}

/// `(Phi(dt), A(dt))` of one backward (RTS) step of a 3-state smoother.
pub type Kin3Gain = ([[f64; 3]; 3], [[f64; 3]; 3]);

/// `A = P Phi^T M^-1` (the RTS backward gain from the filtered covariance
/// `P` and the predicted one `M`, symmetric positive definite), with `M`
/// equilibrated by its diagonal before the inversion (the normalised
/// covariances of small gains span many decades). `None` if `M` is not
/// positive definite or the result is not finite.
pub fn rts_gain3(
    p: &nalgebra::Matrix3<f64>,
    phi: &nalgebra::Matrix3<f64>,
    m: &nalgebra::Matrix3<f64>,
) -> Option<[[f64; 3]; 3]> {
    if (0..3).any(|i| !(m[(i, i)] > 0.0 && m[(i, i)].is_finite())) {
        return None;
    }
    let s = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::from_fn(|i, _| {
        1.0 / m[(i, i)].sqrt()
    }));
    let ms = s * m * s;
    let ms = (ms + ms.transpose()) * 0.5;
    let chol = nalgebra::Cholesky::new(ms)?;
    let minv = s * chol.inverse() * s;
    let a = p * phi.transpose() * minv;
    let out: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| a[(i, j)]));
    out.iter().flatten().all(|v| v.is_finite()).then_some(out)
}

/// `Phi_N` (`h = 1`).
const PHI_N: [[f64; 3]; 3] = [[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]];

/// `A = P Phi_N' M^-1` in double-double from the predicted covariance `M`
/// (symmetric positive definite) and the filtered one `P` (symmetric), as
/// `A' = M^-1 (Phi_N P)`; `None` if `M` is not positive definite or the
/// result is not finite in float64.
fn rts_gain3_dd(p: &M3, m: &M3) -> Option<[[f64; 3]; 3]> {
    let at = m3_spd_solve(m, &m3_mul(&m3_from(&PHI_N), p))?;
    let out: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| at[j][i].to_f64()));
    out.iter().flatten().all(|v| v.is_finite()).then_some(out)
}

/// Normalised backward gain `A_N = P_N Phi_N^T M_N^-1` (`h = 1` units,
/// `Phi_N = [[1, 1, 1/2], [0, 1, 1], [0, 0, 1]]`) of the steady-state
/// Kalman alpha-beta-gamma filter with near-optimal gains `(alpha, beta,
/// gamma)` (paper convention): the predicted covariance is
/// `M_N = P~ / (1 - alpha)` (Chen & Chui, Corollary (iii); see
/// [`crate::abg::p_tilde`]) and the filtered one `P_N = (I - w H) M_N`,
/// `w = [alpha, beta, gamma]`. The scale of `M_N` cancels in `A_N`.
///
/// The gains are taken as exact: `P~`, `(I - w H) P~` (which cancels as
/// `alpha -> 1`: `p22 - beta^2`, `1 - alpha`, ...) and the solve with the
/// nearly singular `P~` are evaluated in double-double, so the result is the
/// backward gain of these float64 gains to about float64 precision over the
/// whole domain (docs/abg.md, "Backward (smoother) gains"). The gain is
/// sensitive to the gains themselves near `alpha = 1` (relative
/// perturbations of `1 - alpha` pass through): gains that were rounded from
/// a noise design carry that rounding, which is why the design uses
/// [`abg_backward_from_noise`].
pub fn abg_backward_normalised(alpha: f64, beta: f64, gamma: f64) -> Result<[[f64; 3]; 3]> {
    let finite = alpha.is_finite() && beta.is_finite() && gamma.is_finite();
    finite
        .then(|| {
            let a = Dd::new(alpha);
            backward_of_gains(Dd::ONE - a, a, Dd::new(beta), Dd::new(gamma))
        })
        .flatten()
        .ok_or_else(|| {
            Error::NoSolution(format!(
                "the gains alpha={alpha}, beta={beta}, gamma={gamma} (Chen & Chui convention) \
                 have no positive definite steady-state covariance (Corollary (iii)): no RTS \
                 backward gain"
            ))
        })
}

/// `A_N` from the gains in double-double: `M = P~` (the scale `1 / (1 -
/// alpha)` cancels), `P = (I - w H) P~` with its first row `(1 - alpha)`
/// times that of `P~` (`om = 1 - alpha` given, not formed from `a`).
fn backward_of_gains(om: Dd, a: Dd, b: Dd, g: Dd) -> Option<[[f64; 3]; 3]> {
    let p22 = b * (a + b + g.scale2(0.25)) - (g * (Dd::new(2.0) + a)).scale2(0.5);
    let p23 = g * (a + b.scale2(0.5));
    let m: M3 = [[a, b, g], [b, p22, p23], [g, p23, g * (b + g)]];
    let w = [a, b, g];
    let p: M3 = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            if i == 0 {
                om * m[0][j]
            } else {
                m[i][j] - w[i] * m[0][j]
            }
        })
    });
    rts_gain3_dd(&m3_sym(&p), &m)
}

/// Normalised backward gain `A_N` (as [`abg_backward_normalised`]) of the
/// steady-state Kalman filter of the noise model itself: `h = 1`,
/// `Q = diag(qp, qv, qa)`, `R = 1` (the normalised noise of
/// [`crate::abg::from_noise`]).
///
/// Computed from the noise, not from rounded gains (from which `1 - alpha`
/// is known only to `eps / (1 - alpha)`), in double-double arithmetic
/// (`dd.rs`): Newton (Hewer) steps of the Riccati equation started
/// from the float64 spectral gains of [`crate::abg::spectral_gains`] (with
/// their `1 - alpha`), each step a Stein equation whose closed loop takes
/// `1 - alpha` as given, until the gains settle (two or more steps); then `A_N` from
/// those gains as in [`abg_backward_normalised`]. Where the spectral form
/// is unavailable or Newton does not settle: the doubling algorithm in
/// double-double plus two Newton steps. Accurate to ~1e-13 of each row's
/// largest entry (a few ulps almost everywhere) over the whole domain of
/// the design (`tests/test_abg_backward.py`, docs/abg.md "Backward
/// (smoother) gains"); computed once per distinct step and cached by the
/// smoothers.
pub fn abg_backward_from_noise(qp: f64, qv: f64, qa: f64) -> Result<[[f64; 3]; 3]> {
    let fail = |why: &str| {
        Error::NoSolution(format!(
            "no steady-state RTS backward gain for the normalised noise q_p={qp}, q_v={qv}, \
             q_a={qa}: {why}"
        ))
    };
    if !(qp >= 0.0 && qv >= 0.0 && qa > 0.0 && qp.is_finite() && qv.is_finite() && qa.is_finite()) {
        return Err(fail("q_p, q_v must be finite and >= 0, q_a finite and > 0"));
    }
    let q = [qp, qv, qa];
    // Fast path: Newton from the float64 spectral gains (a few ulps, with
    // 1 - alpha), accepted once the gains have settled to double-double.
    if let Some([alpha, beta, gamma, om]) = crate::abg::spectral_gains(qp, qv, qa) {
        let mut gains = [om, alpha, beta, gamma].map(Dd::new);
        for step in 0..4 {
            let Some(x) = hewer_step(&gains, q) else {
                break;
            };
            let next = gains_of(&x);
            // The first step moves the float64 gains by ~1e-16; later ones
            // by the rounding of the Stein solve (~1e-32 times its
            // condition number) once converged.
            let settled = step >= 1
                && (0..4).all(|i| {
                    let d = (next[i] - gains[i]).hi.abs();
                    d <= 1e-24 * next[i].hi.abs()
                });
            gains = next;
            if settled {
                if let Some(a) = backward_of_gains(gains[0], gains[1], gains[2], gains[3]) {
                    return Ok(a);
                }
                break;
            }
        }
    }
    backward_by_doubling(q).map_err(fail)
}

/// The fallback of [`abg_backward_from_noise`]: the doubling algorithm in
/// double-double from scratch, two Newton steps, `A_N` of the gains.
fn backward_by_doubling(q: [f64; 3]) -> std::result::Result<[[f64; 3]; 3], &'static str> {
    let [qp, qv, qa] = q;
    // X = A' X (I + G X)^-1 A + Q with A = Phi', G = e1 e1' (R = 1): X = M.
    let eye = m3_eye();
    let mut a = m3_t(&m3_from(&PHI_N));
    let mut g = [[Dd::ZERO; 3]; 3];
    g[0][0] = Dd::ONE;
    let mut x = m3_from(&[[qp, 0.0, 0.0], [0.0, qv, 0.0], [0.0, 0.0, qa]]);
    let mut converged = false;
    for _ in 0..200 {
        let w = m3_solve(&m3_add(&eye, &m3_mul(&g, &x)), &eye).ok_or("singular doubling step")?;
        let aw = m3_mul(&a, &w);
        let at = m3_t(&a);
        let gn = m3_sym(&m3_add(&g, &m3_mul(&m3_mul(&aw, &g), &at)));
        let xn = m3_sym(&m3_add(&x, &m3_mul(&at, &m3_mul(&m3_mul(&x, &w), &a))));
        let an = m3_mul(&aw, &a);
        let diff: M3 = std::array::from_fn(|i| std::array::from_fn(|j| xn[i][j] - x[i][j]));
        let change = m3_amax(&diff) / m3_amax(&xn);
        let small = m3_amax(&an);
        a = an;
        g = gn;
        x = xn;
        if !(change.is_finite() && small.is_finite()) {
            return Err("the doubling iteration over/underflowed");
        }
        if change <= 1e-33 && small <= 1e-20 {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err("the doubling iteration did not converge");
    }
    // Newton (Hewer) steps from the doubling solution, which loses digits
    // when q_a is large.
    let mut gains = gains_of(&x);
    for _ in 0..2 {
        match hewer_step(&gains, q) {
            Some(xn) => gains = gains_of(&xn),
            None => break,
        }
    }
    backward_of_gains(gains[0], gains[1], gains[2], gains[3])
        .ok_or("the predicted covariance is not positive definite")
}

/// `[1 - alpha, alpha, beta, gamma]` of the predicted covariance `x`
/// (`R = 1`): `x e1 / (x11 + 1)`, `1 - alpha = 1 / (x11 + 1)`.
fn gains_of(x: &M3) -> [Dd; 4] {
    let d = x[0][0] + Dd::ONE;
    [Dd::ONE / d, x[0][0] / d, x[1][0] / d, x[2][0] / d]
}

/// One Newton (Hewer) step of the normalised filter Riccati equation from
/// the filter gain `w = [alpha, beta, gamma]` (`gains = [1 - alpha, w]`):
/// the predicted covariance of that gain, `X = F X F' + Q + K K'`,
/// `F = Phi (I - w e1')`, `K = Phi w`, where `(I - w e1')_11 = 1 - alpha`
/// is taken as given (no cancellation). `None` if the Stein equation is
/// singular or the result is not a covariance.
fn hewer_step(gains: &[Dd; 4], q: [f64; 3]) -> Option<M3> {
    let phi = m3_from(&PHI_N);
    let w = [gains[1], gains[2], gains[3]];
    let mut l = m3_eye();
    l[0][0] = gains[0];
    for i in 1..3 {
        l[i][0] = -w[i];
    }
    let f = m3_mul(&phi, &l);
    let k: [Dd; 3] =
        std::array::from_fn(|i| phi[i][0] * w[0] + phi[i][1] * w[1] + phi[i][2] * w[2]);
    let mut wq: M3 = std::array::from_fn(|i| std::array::from_fn(|j| k[i] * k[j]));
    for (i, qi) in q.into_iter().enumerate() {
        wq[i][i] = wq[i][i] + Dd::new(qi);
    }
    let x = m3_sym(&stein3(&f, &wq)?);
    (x[0][0].hi > 0.0 && x.iter().flatten().all(|v| v.is_finite())).then_some(x)
}

/// [`abg_backward_from_noise`] for the physical noise of
/// [`crate::abg::from_noise`] at period `h` (validated as there: the same
/// errors, naming the parameter).
pub fn abg_backward_design(
    sigma_p: f64,
    sigma_v: f64,
    sigma_a: f64,
    sigma_m: f64,
    h: f64,
) -> Result<[[f64; 3]; 3]> {
    crate::abg::from_noise(sigma_p, sigma_v, sigma_a, sigma_m, h)?;
    let [qp, qv, qa] = crate::abg::normalised_noise(sigma_p, sigma_v, sigma_a, sigma_m, h);
    abg_backward_from_noise(qp, qv, qa)
}

/// Physical backward step from the normalised one: `Phi = D^-1 Phi_N D`,
/// `A = D^-1 A_N D`, `D = diag(1, dt, dt^2)`.
fn kin3_physical(phi_n: &[[f64; 3]; 3], a_n: &[[f64; 3]; 3], dt: f64) -> Kin3Gain {
    let d = [1.0, dt, dt * dt];
    (
        std::array::from_fn(|i| std::array::from_fn(|j| phi_n[i][j] * d[j] / d[i])),
        std::array::from_fn(|i| std::array::from_fn(|j| a_n[i][j] * d[j] / d[i])),
    )
}

/// Backward (RTS) gain of the steady-state smoothers of the 3-state
/// kinematic filters at step `dt`: `A(dt) = P_filt Phi(dt)^T P_pred^-1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kin3Backward {
    /// The alpha-beta-gamma design at each `dt` (`[sigma_p, sigma_v,
    /// sigma_a, sigma_m]`, as [`AbgDesign`]): the gains of
    /// [`crate::abg::from_noise`] at `h = dt` (validation), the backward
    /// gain from the noise itself ([`abg_backward_design`]); `Phi = phi_ca(dt)`.
    AbgDesign([f64; 4]),
    /// The Singer steady state at each `dt` (as [`SingerDesign`]):
    /// `A_N = P_filt,N Phi_N^T P_pred,N^-1` of [`crate::singer::steady_state`]
    /// at `theta = dt / tau`, `q_N = q dt^5 / sigma_pos^2`.
    Singer {
        /// Manoeuvre correlation time.
        tau: f64,
        /// Acceleration noise spectral density.
        q: f64,
        /// Rms position measurement error.
        sigma_pos: f64,
    },
    /// Fixed gains: a constant normalised backward gain `A_N` (that of the
    /// Kalman-equivalent model of the gains) with `Phi = phi_ca(dt)`.
    Fixed([[f64; 3]; 3]),
}

impl Kin3Backward {
    /// `(Phi(dt), A(dt))` (uncached; see [`Kin3Cache`]).
    pub fn at(&self, dt: f64) -> Result<Kin3Gain> {
        let phi_n = PHI_N;
        let out = match *self {
            Kin3Backward::Fixed(a_n) => kin3_physical(&phi_n, &a_n, dt),
            Kin3Backward::AbgDesign(noise) => {
                let [sp, sv, sa, sm] = noise;
                kin3_physical(&phi_n, &abg_backward_design(sp, sv, sa, sm, dt)?, dt)
            }
            Kin3Backward::Singer { tau, q, sigma_pos } => {
                let (ss, _) = singer_steady(tau, q, sigma_pos, dt)?;
                let a_n = rts_gain3(&ss.p_filt, &ss.phi, &ss.p_pred).ok_or_else(|| {
                    Error::NoSolution(
                        "the Singer steady state has no positive definite predicted covariance"
                            .into(),
                    )
                })?;
                let phi_n: [[f64; 3]; 3] =
                    std::array::from_fn(|i| std::array::from_fn(|j| ss.phi[(i, j)]));
                kin3_physical(&phi_n, &a_n, dt)
            }
        };
        if out
            .0
            .iter()
            .chain(out.1.iter())
            .flatten()
            .all(|v| v.is_finite())
        {
            Ok(out)
        } else {
            Err(Error::domain(
                "dt",
                "a step at which the transition and backward gain are representable in float64 \
                 (overflow); rescale t",
                dt,
            ))
        }
    }
}

/// The backward steps of the last [`CACHE_SLOTS`] distinct `dt` (keyed by
/// the bits of `dt`; round robin), so that a track's smoothing costs one
/// design per distinct step.
#[derive(Debug, Clone, Copy)]
pub struct Kin3Cache {
    keys: [u64; CACHE_SLOTS],
    vals: [Kin3Gain; CACHE_SLOTS],
    used: usize,
    next: usize,
}

impl Default for Kin3Cache {
    fn default() -> Self {
        Kin3Cache {
            keys: [0; CACHE_SLOTS],
            vals: [([[0.0; 3]; 3], [[0.0; 3]; 3]); CACHE_SLOTS],
            used: 0,
            next: 0,
        }
    }
}

impl Kin3Cache {
    /// `back.at(dt)`, cached.
    pub fn get(&mut self, back: &Kin3Backward, dt: f64) -> Result<Kin3Gain> {
        let key = dt.to_bits();
        for i in 0..self.used {
            if self.keys[i] == key {
                return Ok(self.vals[i]);
            }
        }
        let v = back.at(dt)?;
        self.keys[self.next] = key;
        self.vals[self.next] = v;
        self.next = (self.next + 1) % CACHE_SLOTS;
        self.used = (self.used + 1).min(CACHE_SLOTS);
        Ok(v)
    }
}

#[cfg(test)]
#[path = "tests/irregular.rs"]
mod tests;
