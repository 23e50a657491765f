//! Alpha-beta filter design and steady-state analysis.
//!
//! Source: J. H. Painter, D. Kerstetter, S. Jowers, "Reconciling Steady-State
//! Kalman and Alpha-Beta Filter Design", IEEE Trans. AES 26(6), Nov. 1990
//! (paper 000, cross-checked with its second transcription 003). Printed
//! formulas that failed their numerical check are listed in `docs/errata.md`.
//!
//! # Normalisation
//! Everything here is dimensionless. The state is (position / sigma_v,
//! velocity * T / sigma_v); the measurement noise has unit variance; the
//! process noise of the paper's model (white acceleration held over each
//! period, eq (2)) is `Q_N = r * [[1, 2], [2, 4]]` with the SNR
//! `r = ((sigma_w T^2 / 2) / sigma_v)^2` of eq (9). The filter gains are
//! `(alpha, beta)` and the physical gains are `(g1, g2) = (alpha, beta / T)`
//! (eq (5)).
//!
//! # Numerically stable forms
//! The printed closed forms (eqs (12), (14)) cancel at both ends of the SNR
//! range. All Kalman quantities are computed instead from
//! `u = sqrt(1 - alpha)` and `v = 1 - u`, obtained without cancellation from
//! Kalata's tracking index `lambda = sigma_w T^2 / sigma_v = 2 sqrt(r)`:
//!
//! ```text
//! S = sqrt(lambda) sqrt(lambda + 8),  D = lambda + 4 + S
//! u = 4 / D,  v = (lambda + S) / D
//! alpha = v (1 + u),  beta = 2 v^2,  1 - alpha = u^2
//! P_filt = [[alpha, beta], [beta, 4 v^3 / u]]
//! P_pred = P_filt / u^2   (element-wise; exact)
//! ```
//!
//! (`u` is the smaller root of `2u^2 - (4 + lambda) u + 2 = 0`, which is
//! `beta = lambda u` with `beta = 2 (1 - u)^2`.)

use crate::{Error, Result};

/// Damping ratio of every Kalman-optimal alpha-beta filter under the
/// impulse-invariant mapping (15): `1 / sqrt(2)`.
pub const KALMAN_DAMPING: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Relative tolerance of [`AlphaBeta::kalman_optimal`].
pub const KALMAN_RTOL: f64 = 1e-9;

/// Names of the values written by [`AlphaBeta::write_row`], in order.
pub const FIELDS: [&str; 32] = [
    "alpha",
    "beta",
    "r",
    "tracking_index",
    "kalman_optimal",
    "damping",
    "omega_n_T",
    "bandwidth_T",
    "p11",
    "p12",
    "p22",
    "m11",
    "m12",
    "m22",
    "pole1_re",
    "pole1_im",
    "pole2_re",
    "pole2_im",
    "stable",
    "valid",
    "vrr_position_filtered",
    "vrr_velocity_filtered",
    "vrr_position_predicted",
    "vrr_velocity_predicted",
    "lag_position_filtered",
    "lag_velocity_filtered",
    "lag_position_predicted",
    "lag_velocity_predicted",
    "b1_T",
    "b2_T2",
    "zero_T",
    "one_minus_alpha",
];

/// Steady-state covariance of a fixed-gain alpha-beta filter, normalised
/// (see the module docs): `[c11, c12, c22]` of the symmetric 2x2 matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance {
    /// Filtered (a posteriori) error covariance.
    pub filtered: [f64; 3],
    /// Predicted (one step ahead, a priori) error covariance.
    pub predicted: [f64; 3],
}

/// A complete alpha-beta design or analysis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaBeta {
    /// Position gain.
    pub alpha: f64,
    /// Velocity gain times the period (`beta = g2 * T`).
    pub beta: f64,
    /// `1 - alpha`, kept separately because it is known more accurately than
    /// `alpha` for Kalman designs at high SNR.
    pub one_minus_alpha: f64,
    /// The SNR `r` whose Kalman design has this `alpha` (eq (9)); `+inf` when
    /// `alpha >= 1` (no Kalman design has such a gain).
    pub r: f64,
    /// Kalata's tracking index `lambda = 2 sqrt(r)`.
    pub tracking_index: f64,
    /// Whether `beta` is the Kalman `beta` for this `alpha` to [`KALMAN_RTOL`].
    pub kalman_optimal: bool,
    /// Damping ratio `delta` of the impulse-invariant continuous equivalent (15).
    pub damping: f64,
    /// `omega_n * T = sqrt(beta)` (15).
    pub omega_n_t: f64,
    /// Noise bandwidth times period, `B_N T`, eq (16).
    pub bandwidth_t: f64,
    /// Steady-state covariance at the model SNR `r`.
    pub covariance: Covariance,
    /// Closed-loop poles (z-plane) as (re, im).
    pub poles: [(f64, f64); 2],
    /// Jury stability of the closed loop: `alpha > 0, beta > 0, 2 alpha + beta < 4`.
    pub stable: bool,
    /// The paper's design region: stable, `alpha < 1` and `sqrt(beta) <= pi`.
    pub valid: bool,
    /// Variance reduction ratios (covariance with measurement noise only).
    pub vrr: Covariance,
    /// Steady-state lag under constant acceleration `a`: position in units of
    /// `a T^2`, velocity in units of `a T`; `[position, velocity]`.
    pub lag_filtered: [f64; 2],
    /// As `lag_filtered`, for the one-step prediction.
    pub lag_predicted: [f64; 2],
}

fn check_pos(name: &'static str, x: f64) -> Result<f64> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(Error::domain(name, "finite and > 0", x))
    }
}

/// `(u, v) = (sqrt(1 - alpha), 1 - sqrt(1 - alpha))` of the Kalman design with
/// tracking index `lambda`, without cancellation or intermediate overflow.
///
/// `u = 4 / (lambda + 4 + S)`, `v = (lambda + S) / (lambda + 4 + S)` with
/// `S = sqrt(lambda (lambda + 8))`; for `lambda >= 1` the same is evaluated as
/// `w = (4/lambda) / (1 + sqrt(1 + 8/lambda))`, `u = w / (1 + w)`, `v = 1 / (1 + w)`.
#[inline]
pub fn kalman_uv_from_lambda(lambda: f64) -> (f64, f64) {
    if lambda >= 1.0 {
        let w = (4.0 / lambda) / (1.0 + (1.0 + 8.0 / lambda).sqrt());
        (w / (1.0 + w), 1.0 / (1.0 + w))
    } else {
        let s = lambda.sqrt() * (lambda + 8.0).sqrt();
        let d = lambda + 4.0 + s;
        (4.0 / d, (lambda + s) / d)
    }
}

/// `alpha = 1 - u^2 = v (1 + u)`, evaluated in the form that rounds correctly
/// (never above 1).
#[inline]
pub fn kalman_alpha(u: f64, v: f64) -> f64 {
    if u < 0.5 {
        1.0 - u * u
    } else {
        v * (1.0 + u)
    }
}

/// Kalman `beta` for a given `alpha` in (0, 1): `2 (alpha / (1 + sqrt(1 - alpha)))^2`.
pub fn kalman_beta(alpha: f64) -> f64 {
    let u = (1.0 - alpha).sqrt();
    let v = alpha / (1.0 + u);
    2.0 * v * v
}

/// Noise bandwidth times period of eq (16) from the gains:
/// `B_N T = (beta + (alpha - beta/2)^2) / (4 alpha + 2 beta)`.
///
/// This is eq (16), `sqrt(beta)/(8 delta) (1 + (2 delta - sqrt(beta))^2)`,
/// with `delta` from (15) substituted; it has no square root and no
/// cancellation.
pub fn bandwidth_t_from_gains(alpha: f64, beta: f64) -> f64 {
    // Scaled by m = max(alpha, beta) so that nothing overflows for huge gains.
    let m = alpha.max(beta);
    let (a, b) = (alpha / m, beta / m);
    let c = a - 0.5 * b;
    let den = 4.0 * a + 2.0 * b;
    b / den + m * (c * (c / den))
}

/// Eq (16) as printed: `B_N T = sqrt(beta) / (8 delta) * (1 + (2 delta - sqrt(beta))^2)`,
/// as a function of `x = omega_n T = sqrt(beta)`.
pub fn bandwidth_t_from_x(x: f64, damping: f64) -> f64 {
    let c = 2.0 * damping - x;
    x * (1.0 + c * c) / (8.0 * damping)
}

fn bandwidth_t_dx(x: f64, damping: f64) -> f64 {
    (3.0 * x * x - 8.0 * damping * x + 1.0 + 4.0 * damping * damping) / (8.0 * damping)
}

/// Largest `omega_n T` of a stable alpha-beta filter with positive `alpha` at
/// this damping: `min(4 delta, 1 / delta)`.
pub fn max_omega_n_t(damping: f64) -> f64 {
    (4.0 * damping).min(1.0 / damping)
}

/// Steady-state covariance of the fixed-gain filter with gains `(alpha, beta)`
/// when the true (normalised) process noise is `r * [[1, 2], [2, 4]]` and the
/// measurement noise has unit variance.
///
/// Closed-form solution of the discrete Lyapunov equation
/// `M = F ((I - K h) M (I - K h)^T + K K^T) F^T + Q`, `P = (I - K h) M (I - K h)^T + K K^T`,
/// split into its measurement-noise part (the variance reduction ratios) and
/// its process-noise part:
///
/// ```text
/// D = alpha (4 - 2 alpha - beta)
/// M = [2a^2 + ab + 2b, b (2a + b), 2b^2] / D + r [2, 2a + b, 2a^2 + ab + 2b] / (a b)
/// P = [2a^2 - 3ab + 2b, b (2a - b), 2b^2] / D + r [2(1-a)^2, (1-a)(2a - b), 2a^2 - 3ab + 2b] / (a b)
/// ```
///
/// Entries are `+inf` for an unstable filter (no steady state exists).
pub fn fixed_gain_covariance(alpha: f64, beta: f64, one_minus_alpha: f64, r: f64) -> Covariance {
    let (a, b, c) = (alpha, beta, one_minus_alpha);
    if !jury_stable(a, b) {
        return Covariance {
            filtered: [f64::INFINITY; 3],
            predicted: [f64::INFINITY; 3],
        };
    }
    // 4 - 2a - b and 2a^2 - 3ab + 2b cancel near (alpha, beta) = (1, 2), the
    // high-SNR end of the Kalman curve: evaluate them as if in twice the
    // working precision (exact products and compensated sums).
    let d = a * dot2(&[(4.0, 1.0), (-2.0, a), (-1.0, b)]);
    let ab = a * b;
    let s_pred = 2.0 * a * a + ab + 2.0 * b;
    let s_filt = dot2(&[(2.0 * a, a), (2.0, b), (-2.0 * a, b), (-a, b)]);
    let (mv, pv) = (
        [s_pred / d, b * (2.0 * a + b) / d, 2.0 * b * b / d],
        [s_filt / d, b * (2.0 * a - b) / d, 2.0 * b * b / d],
    );
    if r == 0.0 {
        return Covariance {
            filtered: pv,
            predicted: mv,
        };
    }
    let mw = [2.0 / ab, (2.0 * a + b) / ab, s_pred / ab];
    let pw = [2.0 * c * c / ab, c * (2.0 * a - b) / ab, s_filt / ab];
    Covariance {
        filtered: std::array::from_fn(|i| pv[i] + r * pw[i]),
        predicted: std::array::from_fn(|i| mv[i] + r * mw[i]),
    }
}

/// Steady-state error covariance of a filter with gains `(alpha, beta)` when
/// the true SNR is `r_true` (the paper's "if the actual values differ"
/// remark): validated wrapper of [`fixed_gain_covariance`].
///
/// Errors if the gains are not positive or the loop is unstable (no steady
/// state), or `r_true` is negative or not finite.
pub fn error_covariance(alpha: f64, beta: f64, r_true: f64) -> Result<Covariance> {
    check_pos("alpha", alpha)?;
    check_pos("beta", beta)?;
    if !(r_true.is_finite() && r_true >= 0.0) {
        return Err(Error::domain("r_true", "finite and >= 0", r_true));
    }
    if !jury_stable(alpha, beta) {
        return Err(Error::domain(
            "beta",
            format!(
                "< 4 - 2*alpha = {} for a stable filter (no steady state exists otherwise)",
                4.0 - 2.0 * alpha
            ),
            beta,
        ));
    }
    Ok(fixed_gain_covariance(alpha, beta, 1.0 - alpha, r_true))
}

/// Error-free transformation `a + b = s + e`.
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `sum(x * y)` computed as if in twice the working precision (Ogita, Rump &
/// Oishi's Dot2): exact products by FMA, compensated summation.
fn dot2(terms: &[(f64, f64)]) -> f64 {
    let (mut s, mut c) = (0.0_f64, 0.0_f64);
    for &(x, y) in terms {
        let p = x * y;
        let ep = x.mul_add(y, -p);
        let (t, es) = two_sum(s, p);
        s = t;
        c += ep + es;
    }
    s + c
}

/// Jury stability of the alpha-beta closed loop `z^2 - (2 - a - b) z + (1 - a)`.
pub fn jury_stable(alpha: f64, beta: f64) -> bool {
    alpha > 0.0 && beta > 0.0 && 2.0 * alpha + beta < 4.0
}

fn poles(alpha: f64, beta: f64) -> [(f64, f64); 2] {
    // z^2 - tr z + det, with disc = tr^2 - 4 det = (alpha + beta)^2 - 4 beta.
    let tr = 2.0 - alpha - beta;
    let det = 1.0 - alpha;
    let sb = beta.sqrt();
    let disc = (alpha + beta - 2.0 * sb) * (alpha + beta + 2.0 * sb);
    if disc >= 0.0 {
        let q = 0.5 * (tr + tr.signum() * disc.sqrt());
        let z1 = if q != 0.0 { q } else { 0.0 };
        let z2 = if q != 0.0 { det / q } else { 0.0 };
        let (lo, hi) = if z1 <= z2 { (z1, z2) } else { (z2, z1) };
        [(hi, 0.0), (lo, 0.0)]
    } else {
        let im = 0.5 * (-disc).sqrt();
        [(0.5 * tr, im), (0.5 * tr, -im)]
    }
}

impl AlphaBeta {
    /// Analyse arbitrary gains (Kalman-optimal or not).
    ///
    /// `alpha` and `beta` must be finite and positive; anything else about
    /// them (stability, the paper's region) is reported, not rejected.
    pub fn analyze(alpha: f64, beta: f64) -> Result<Self> {
        check_pos("alpha", alpha)?;
        check_pos("beta", beta)?;
        Ok(Self::build(alpha, beta, 1.0 - alpha, None))
    }

    /// Kalman design from the SNR `r = ((sigma_w T^2/2)/sigma_v)^2`, eqs (9)-(14).
    pub fn from_snr(r: f64) -> Result<Self> {
        check_pos("r", r)?;
        Self::kalman_from_lambda(2.0 * r.sqrt(), Some(r)).representable("r", r)
    }

    /// Kalman design from the physical noise: white acceleration `sigma_w`,
    /// measurement noise `sigma_v`, period `t`.
    pub fn from_noise(sigma_w: f64, sigma_v: f64, t: f64) -> Result<Self> {
        check_pos("sigma_w", sigma_w)?;
        check_pos("sigma_v", sigma_v)?;
        check_pos("T", t)?;
        let lambda = (sigma_w / sigma_v) * t * t;
        if !(lambda.is_finite() && lambda > 0.0) {
            return Err(Error::domain(
                "sigma_w*T**2/sigma_v",
                "representable as a finite positive float64 (it over- or underflows)",
                lambda,
            ));
        }
        Self::kalman_from_lambda(lambda, None).representable("sigma_w*T**2/sigma_v", lambda)
    }

    /// Kalman design from Kalata's tracking index `lambda = sigma_w T^2 / sigma_v`.
    pub fn from_tracking_index(lambda: f64) -> Result<Self> {
        check_pos("lam", lambda)?;
        Self::kalman_from_lambda(lambda, None).representable("lam", lambda)
    }

    /// Kalman design from the normalised tracking error variance
    /// `sigma_t^2 / sigma_v^2 = alpha` (eq (14)), in closed form.
    pub fn from_tracking_error(ratio: f64) -> Result<Self> {
        if !(ratio > 0.0 && ratio < 1.0) {
            return Err(Error::domain("ratio", "in the open interval (0, 1)", ratio));
        }
        let u = (1.0 - ratio).sqrt();
        let v = ratio / (1.0 + u);
        let lambda = 2.0 * v * v / u;
        let mut ab = Self::kalman_from_uv(u, v, lambda, None);
        // The user's ratio is alpha exactly (eq (14)); keep it bit for bit.
        ab.alpha = ratio;
        ab.covariance.filtered[0] = ratio;
        ab.representable("ratio", ratio)
    }

    /// Deterministic design from damping and natural frequency, eqs (6)-(7), (15):
    /// `beta = (omega_n T)^2`, `alpha = 2 delta sqrt(beta) - beta / 2`.
    pub fn from_natural_frequency(omega_n: f64, t: f64, damping: f64) -> Result<Self> {
        check_pos("omega_n", omega_n)?;
        check_pos("T", t)?;
        check_pos("damping", damping)?;
        let x = omega_n * t;
        let xmax = max_omega_n_t(damping);
        if !(x.is_finite() && x > 0.0 && x < xmax) {
            return Err(Error::domain(
                "omega_n*T",
                format!(
                    "in (0, {xmax:.17}) for a stable filter with positive alpha at damping={damping}"
                ),
                x,
            ));
        }
        let ab = Self::from_x_damping(x, damping);
        if !(ab.stable && ab.alpha > 0.0) {
            return Err(Error::domain(
                "omega_n*T",
                format!(
                    "inside the stable region at damping={damping} (it rounds onto its boundary)"
                ),
                x,
            ));
        }
        Ok(ab)
    }

    /// Deterministic design from the noise-bandwidth x period product `B_N T`
    /// and the damping ratio, eqs (15)-(16).
    ///
    /// Eq (16) is inverted for `x = omega_n T` on `(0, min(4 delta, 1/delta))`
    /// (positive `alpha`, stable loop). Where (16) is not monotone there
    /// (`sqrt(3)/2 < delta < 1`), the smallest root is taken: the
    /// lowest-gain filter with that bandwidth.
    pub fn from_bandwidth(bn_t: f64, damping: f64) -> Result<Self> {
        check_pos("bn_t", bn_t)?;
        check_pos("damping", damping)?;
        let x = invert_bandwidth(bn_t, damping)?;
        let ab = Self::from_x_damping(x, damping);
        if ab.stable && ab.alpha > 0.0 {
            Ok(ab)
        } else {
            Err(Error::domain(
                "bn_t",
                format!(
                    "inside the stable region at damping={damping} (it rounds onto its boundary)"
                ),
                bn_t,
            ))
        }
    }

    fn from_x_damping(x: f64, damping: f64) -> Self {
        let alpha = x * (2.0 * damping - 0.5 * x);
        let beta = x * x;
        Self::build(alpha, beta, 1.0 - alpha, None)
    }

    fn kalman_from_lambda(lambda: f64, r: Option<f64>) -> Self {
        let (u, v) = kalman_uv_from_lambda(lambda);
        Self::kalman_from_uv(u, v, lambda, r)
    }

    /// Kalman designs are stable in exact arithmetic; reject inputs so extreme
    /// that the float64 gains round onto or past the stability boundary.
    fn representable(self, name: &'static str, value: f64) -> Result<Self> {
        if self.stable {
            Ok(self)
        } else {
            Err(Error::domain(
                name,
                format!(
                    "moderate enough that the Kalman gains are representable in float64 \
                     inside the stable region (they round to alpha={}, beta={})",
                    self.alpha, self.beta
                ),
                value,
            ))
        }
    }

    fn kalman_from_uv(u: f64, v: f64, lambda: f64, r: Option<f64>) -> Self {
        let alpha = kalman_alpha(u, v);
        let beta = 2.0 * v * v;
        let u2 = u * u;
        let p22 = 4.0 * v * v * v / u;
        let cov = Covariance {
            filtered: [alpha, beta, p22],
            predicted: [alpha / u2, beta / u2, p22 / u],
        };
        let r = r.unwrap_or(0.25 * lambda * lambda);
        let mut ab = Self::build(alpha, beta, u2, Some((r, lambda, cov)));
        ab.kalman_optimal = true;
        ab.damping = KALMAN_DAMPING;
        ab
    }

    fn build(
        alpha: f64,
        beta: f64,
        one_minus_alpha: f64,
        kalman: Option<(f64, f64, Covariance)>,
    ) -> Self {
        let stable = jury_stable(alpha, beta);
        let sb = beta.sqrt();
        let damping = (alpha + 0.5 * beta) / (2.0 * sb);
        let (r, lambda, covariance, kalman_optimal) = match kalman {
            Some((r, lambda, cov)) => (r, lambda, cov, true),
            None if alpha < 1.0 => {
                let u = one_minus_alpha.sqrt();
                let v = alpha / (1.0 + u);
                let lambda = 2.0 * v * v / u;
                let r = 0.25 * lambda * lambda;
                let beta_k = 2.0 * v * v;
                let optimal = (beta - beta_k).abs() <= KALMAN_RTOL * beta_k;
                let cov = fixed_gain_covariance(alpha, beta, one_minus_alpha, r);
                (r, lambda, cov, optimal)
            }
            None => {
                let inf = [f64::INFINITY; 3];
                (
                    f64::INFINITY,
                    f64::INFINITY,
                    Covariance {
                        filtered: inf,
                        predicted: inf,
                    },
                    false,
                )
            }
        };
        let vrr = fixed_gain_covariance(alpha, beta, one_minus_alpha, 0.0);
        let (lag_filtered, lag_predicted) = if stable {
            (
                [one_minus_alpha / beta, (alpha - 0.5 * beta) / beta],
                [1.0 / beta, (alpha + 0.5 * beta) / beta],
            )
        } else {
            ([f64::INFINITY; 2], [f64::INFINITY; 2])
        };
        AlphaBeta {
            alpha,
            beta,
            one_minus_alpha,
            r,
            tracking_index: lambda,
            kalman_optimal,
            damping,
            omega_n_t: sb,
            bandwidth_t: bandwidth_t_from_gains(alpha, beta),
            covariance,
            poles: poles(alpha, beta),
            stable,
            valid: stable && alpha < 1.0 && sb <= std::f64::consts::PI,
            vrr,
            lag_filtered,
            lag_predicted,
        }
    }

    /// Write the values named by [`FIELDS`] to `out` (booleans as 0.0 / 1.0).
    pub fn write_row(&self, out: &mut [f64]) {
        let b = |x: bool| if x { 1.0 } else { 0.0 };
        let c = self.alpha - 0.5 * self.beta;
        let row = [
            self.alpha,
            self.beta,
            self.r,
            self.tracking_index,
            b(self.kalman_optimal),
            self.damping,
            self.omega_n_t,
            self.bandwidth_t,
            self.covariance.filtered[0],
            self.covariance.filtered[1],
            self.covariance.filtered[2],
            self.covariance.predicted[0],
            self.covariance.predicted[1],
            self.covariance.predicted[2],
            self.poles[0].0,
            self.poles[0].1,
            self.poles[1].0,
            self.poles[1].1,
            b(self.stable),
            b(self.valid),
            self.vrr.filtered[0],
            self.vrr.filtered[2],
            self.vrr.predicted[0],
            self.vrr.predicted[2],
            self.lag_filtered[0],
            self.lag_filtered[1],
            self.lag_predicted[0],
            self.lag_predicted[1],
            c,
            self.beta,
            if c != 0.0 {
                -self.beta / c
            } else {
                f64::NEG_INFINITY
            },
            self.one_minus_alpha,
        ];
        out[..FIELDS.len()].copy_from_slice(&row);
    }
}

/// Solve eq (16) for `x = omega_n T` given `B_N T` and the damping.
///
/// Safeguarded Newton iteration on the first monotone branch of (16) inside
/// `(0, min(4 delta, 1/delta))`; converges to full precision.
pub fn invert_bandwidth(bn_t: f64, damping: f64) -> Result<f64> {
    check_pos("bn_t", bn_t)?;
    check_pos("damping", damping)?;
    let d = damping;
    let xmax = max_omega_n_t(d);
    // First critical point of (16): root of 3x^2 - 8 d x + 1 + 4 d^2.
    let c = 1.0 + 4.0 * d * d;
    let disc = 64.0 * d * d - 12.0 * c;
    let mut hi = xmax;
    let mut hi_is_open = true;
    if disc > 0.0 {
        let xc = 2.0 * c / (8.0 * d + disc.sqrt());
        if xc < xmax {
            hi = xc;
            hi_is_open = false;
        }
    }
    let fhi = bandwidth_t_from_x(hi, d);
    // At an open bound (the stability limit) stay a few ulps inside: the bound
    // itself is a marginally stable filter.
    let too_big = if hi_is_open {
        bn_t >= fhi * (1.0 - 8.0 * f64::EPSILON)
    } else {
        bn_t > fhi
    };
    if too_big {
        return Err(Error::domain(
            "bn_t",
            format!(
                "below {fhi:.12} (the largest noise bandwidth of a stable alpha-beta filter with positive alpha at damping={d})"
            ),
            bn_t,
        ));
    }
    let mut lo = 0.0_f64;
    let mut x = (8.0 * d * bn_t / c).min(0.5 * hi);
    for _ in 0..200 {
        let f = bandwidth_t_from_x(x, d) - bn_t;
        if f == 0.0 {
            return Ok(x);
        }
        if f < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let df = bandwidth_t_dx(x, d);
        let mut xn = x - f / df;
        if !(xn > lo && xn < hi && xn.is_finite()) {
            xn = 0.5 * (lo + hi);
        }
        if (xn - x).abs() <= 4.0 * f64::EPSILON * x.abs() || hi - lo <= 4.0 * f64::EPSILON * hi {
            return Ok(xn);
        }
        x = xn;
    }
    Ok(x)
}

#[cfg(test)]
#[path = "tests/alphabeta.rs"]
mod tests;
