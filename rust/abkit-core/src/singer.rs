//! The Singer (exponentially correlated acceleration, ECA) target model and
//! the steady state of its Kalman filter.
//!
//! Source: Y.-K. Yoon, S.-M. Hong, "Closed-Form Solution of ECA
//! Target-Tracking Filter using Position and Velocity Measurements" (paper
//! 001), and R. A. Singer, IEEE Trans. AES-6, 473-483, 1970 (its ref. [1])
//! for the process noise. Printed formulas that failed their numerical check
//! are listed in `docs/errata.md`.
//!
//! # Model
//! Continuous time: `x = (position, velocity, acceleration)`,
//! `a' = -a / tau + w` with `w` white of spectral density `q = 2 sigma_m^2 / tau`.
//! Sampled every `T` with `theta = T / tau` (eq (2)):
//!
//! ```text
//! Phi = [[1, T, T^2 phi2(-theta)], [0, 1, T phi1(-theta)], [0, 0, exp(-theta)]]
//! ```
//!
//! (`T^2 phi2(-theta) = tau^2 (theta - 1 + e^-theta)`, `T phi1(-theta) = tau (1 - e^-theta)`),
//! and `Q = q [q_ij]` with Singer's exact `q_ij`, evaluated here as
//! `q_ij = T^(6-i-j) g_ij(theta)` (see [`singer_g`]). `phi_k` are the
//! exponential-integrator functions `phi_k(z) = sum_j z^j / (j + k)!`.
//! `tau = inf` (`theta = 0`) is the continuous white-jerk (constant
//! acceleration) model with `Q = q [[T^5/20, T^4/8, T^3/6], [., T^3/3, T^2/2], [., ., T]]`.
//!
//! # Normalisation
//! The steady-state solvers work on the dimensionless model with state
//! `(position / sigma_pos, velocity T / sigma_pos, acceleration T^2 / sigma_pos)`:
//! `Phi_N = [[1, 1, phi2], [0, 1, phi1], [0, 0, e^-theta]]`,
//! `Q_N = q_N [g_ij]` with `q_N = q T^5 / sigma_pos^2` (`= 2 theta p2^2` with
//! `p2 = sigma_m T^2 / sigma_pos`), `H_N = [[1, 0, 0], [0, 1, 0]]` (or its first
//! row), `R_N = diag(1, r_v^2)` with `r_v = sigma_vel T / sigma_pos`.

use crate::riccati;
use crate::{Error, Result};
use nalgebra::{DMatrix, Matrix3};

/// `phi_k(z) = sum_{j>=0} z^j / (j + k)!` for `k <= 5`, accurate to a few ulps
/// times 50 for real `z <= 0` (series for `|z| <= 1`, upward recurrence
/// `phi_k = (phi_{k-1} - 1/(k-1)!) / z` beyond).
pub fn phi_k(k: usize, z: f64) -> f64 {
    const INV_FACT: [f64; 7] = [
        1.0,
        1.0,
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
    ];
    if z.abs() <= 1.0 {
        let mut term = INV_FACT[k.min(6)];
        let mut sum = 0.0;
        let mut j = 0usize;
        loop {
            sum += term;
            j += 1;
            term *= z / (j + k) as f64;
            if term.abs() <= 1e-18 * sum.abs() || j > 60 {
                return sum + term;
            }
        }
    }
    let mut p = z.exp();
    for i in 1..=k {
        p = (p - INV_FACT[i - 1]) / z;
    }
    p
}

/// Singer's `q_ij` divided by `T^(6-i-j)`, as functions of `theta = T / tau`:
/// `[g11, g12, g13, g22, g23, g33]`.
///
/// For `theta <= 2` the cancellation-free forms
///
/// ```text
/// g11 = (32 phi5(-2t) - 4 phi4(-t)) / 2
/// g12 = (16 phi4(-2t) - 2 phi4(-t) - 2 phi3(-t)) / 2
/// g13 = (8 phi3(-2t) - 2 phi2(-t)) / 2
/// g22 = 4 phi3(-2t) - 2 phi3(-t)
/// g23 = phi1(-t)^2 / 2
/// g33 = phi1(-2t)
/// ```
///
/// (exact rewritings of Singer's expressions), beyond it Singer's
/// expressions, which no longer cancel there, divided by `2 theta^k` term
/// by term so that nothing overflows for huge `theta`.
pub fn singer_g(theta: f64) -> [f64; 6] {
    let t = theta;
    if t <= 2.0 {
        [
            (32.0 * phi_k(5, -2.0 * t) - 4.0 * phi_k(4, -t)) / 2.0,
            (16.0 * phi_k(4, -2.0 * t) - 2.0 * phi_k(4, -t) - 2.0 * phi_k(3, -t)) / 2.0,
            (8.0 * phi_k(3, -2.0 * t) - 2.0 * phi_k(2, -t)) / 2.0,
            4.0 * phi_k(3, -2.0 * t) - 2.0 * phi_k(3, -t),
            phi_k(1, -t).powi(2) / 2.0,
            phi_k(1, -2.0 * t),
        ]
    } else {
        // Singer's expressions divided by 2 theta^k term by term, so that
        // nothing overflows for huge theta (where e^-theta = 0).
        let x = (-t).exp();
        let x2 = x * x;
        let t2 = t * t;
        let g11 = (1.0 - x2 - 4.0 * t * x) / (2.0 * t2 * t2 * t) + 1.0 / (t2 * t2) - 1.0 / (t2 * t)
            + 1.0 / (3.0 * t2);
        let g12 = (x2 + 1.0 - 2.0 * x + 2.0 * t * x) / (2.0 * t2 * t2) - 1.0 / (t2 * t)
            + 1.0 / (2.0 * t2);
        let g13 = (1.0 - x2 - 2.0 * t * x) / (2.0 * t2 * t);
        let g22 = (4.0 * x - 3.0 - x2) / (2.0 * t2 * t) + 1.0 / t2;
        let g23 = (1.0 - x) * (1.0 - x) / (2.0 * t2);
        let g33 = (1.0 - x2) / (2.0 * t);
        [g11, g12, g13, g22, g23, g33]
    }
}

fn sym3(g: [f64; 6]) -> Matrix3<f64> {
    Matrix3::new(g[0], g[1], g[2], g[1], g[3], g[4], g[2], g[4], g[5])
}

/// Physical `(Phi, Q)` for period `t`, correlation time `tau` (may be
/// `+inf`) and white-noise spectral density `q`.
pub fn model(t: f64, tau: f64, q: f64) -> Result<(Matrix3<f64>, Matrix3<f64>)> {
    if !(t.is_finite() && t > 0.0) {
        return Err(Error::domain("T", "finite and > 0", t));
    }
    if tau.is_nan() || tau <= 0.0 {
        return Err(Error::domain("tau", "> 0 (inf allowed)", tau));
    }
    if !(q.is_finite() && q >= 0.0) {
        return Err(Error::domain("q", "finite and >= 0", q));
    }
    let theta = t / tau;
    let (phi_n, g) = normalized_model(theta)?;
    let d = [1.0, t, t * t];
    let phi = Matrix3::from_fn(|i, j| phi_n[(i, j)] * d[j] / d[i]);
    let gm = sym3(g);
    // Q_ij = q g_ij T^(6-i-j) (1-based i, j; 0-based: T^(5-i-j)).
    let qm = Matrix3::from_fn(|i, j| q * gm[(i, j)] * t.powi(5 - (i + j) as i32));
    Ok((phi, qm))
}

/// The dimensionless `Phi_N` and `[g_ij]` of the module docs.
pub fn normalized_model(theta: f64) -> Result<(Matrix3<f64>, [f64; 6])> {
    if !(theta.is_finite() && theta >= 0.0) {
        return Err(Error::domain("T/tau", "finite and >= 0", theta));
    }
    let phi = Matrix3::new(
        1.0,
        1.0,
        phi_k(2, -theta),
        0.0,
        1.0,
        phi_k(1, -theta),
        0.0,
        0.0,
        (-theta).exp(),
    );
    Ok((phi, singer_g(theta)))
}

/// Which steady-state solver to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// The generic Riccati solver ([`riccati::solve_dare`]).
    Numeric,
    /// The paper's Hamiltonian route.
    ClosedForm,
    /// Closed form, falling back to numeric when its checks fail.
    Auto,
}

impl Method {
    /// From the code used by the bindings: 0 numeric, 1 closed form, 2 auto.
    pub fn from_code(c: f64) -> Result<Self> {
        if c == 0.0 {
            Ok(Method::Numeric)
        } else if c == 1.0 {
            Ok(Method::ClosedForm)
        } else if c == 2.0 {
            Ok(Method::Auto)
        } else {
            Err(Error::domain(
                "method",
                "0 (numeric), 1 (closed-form) or 2 (auto)",
                c,
            ))
        }
    }
}

/// Steady state of the normalised Singer filter.
#[derive(Debug, Clone, PartialEq)]
pub struct SteadyState {
    /// Prediction covariance (eq (6)), normalised.
    pub p_pred: Matrix3<f64>,
    /// Kalman gain (eq (7)), 3 x p with p = 1 or 2 (columns beyond p are zero).
    pub k: [[f64; 2]; 3],
    /// Filtered covariance (eq (8)).
    pub p_filt: Matrix3<f64>,
    /// Steady-state fixed-interval smoothing covariance (eq (22)).
    pub p_smooth: Matrix3<f64>,
    /// The three Hamiltonian eigenvalues outside the unit circle, `(re, im)`,
    /// sorted by decreasing modulus.
    pub eigenvalues: [(f64, f64); 3],
    /// The method that produced the result (never `Auto`).
    pub method_used: Method,
    /// `Phi_N`.
    pub phi: Matrix3<f64>,
    /// `Q_N`.
    pub q: Matrix3<f64>,
}

/// Number of values written by [`SteadyState::write_row`].
pub const ROW_WIDTH: usize = 9 + 6 + 9 + 9 + 6 + 1 + 9 + 9;

impl SteadyState {
    /// Flatten: P_pred (9, row-major), K (3x2 row-major), P_filt (9),
    /// P_smooth (9), eigenvalues (re, im) x 3, method (0 numeric, 1 closed
    /// form), Phi_N (9), Q_N (9).
    pub fn write_row(&self, out: &mut [f64]) {
        let mut i = 0;
        let mut put = |v: f64| {
            out[i] = v;
            i += 1;
        };
        let m9 = |m: &Matrix3<f64>, put: &mut dyn FnMut(f64)| {
            for r in 0..3 {
                for c in 0..3 {
                    put(m[(r, c)]);
                }
            }
        };
        m9(&self.p_pred, &mut put);
        for row in &self.k {
            put(row[0]);
            put(row[1]);
        }
        m9(&self.p_filt, &mut put);
        m9(&self.p_smooth, &mut put);
        for (re, im) in self.eigenvalues {
            put(re);
            put(im);
        }
        put(match self.method_used {
            Method::ClosedForm => 1.0,
            _ => 0.0,
        });
        m9(&self.phi, &mut put);
        m9(&self.q, &mut put);
    }
}

fn to_d(m: &Matrix3<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(3, 3, |i, j| m[(i, j)])
}

/// The measurement model: `(H_N, R_N)` for `r_v = sigma_vel T / sigma_pos`
/// (`+inf`: position only).
fn measurement(rv: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    if rv.is_infinite() {
        (
            DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]),
            DMatrix::from_element(1, 1, 1.0),
        )
    } else {
        (
            DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
            DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, rv * rv]),
        )
    }
}

fn validate(theta: f64, qn: f64, rv: f64) -> Result<()> {
    if !(theta.is_finite() && theta >= 0.0) {
        return Err(Error::domain("T/tau", "finite and >= 0", theta));
    }
    if !(qn.is_finite() && qn > 0.0) {
        return Err(Error::domain("q T^5 / sigma_pos^2", "finite and > 0", qn));
    }
    if rv.is_nan() || rv <= 0.0 {
        return Err(Error::domain(
            "sigma_vel T / sigma_pos",
            "> 0 (inf for position only)",
            rv,
        ));
    }
    Ok(())
}

/// Steady state of the normalised Singer filter with `theta = T / tau`,
/// `q_N = q T^5 / sigma_pos^2` and `r_v = sigma_vel T / sigma_pos`
/// (`+inf` for position-only measurements).
pub fn steady_state(theta: f64, qn: f64, rv: f64, method: Method) -> Result<SteadyState> {
    validate(theta, qn, rv)?;
    match method {
        Method::Numeric => steady_state_numeric(theta, qn, rv),
        Method::ClosedForm => crate::singer_closed::steady_state_closed(theta, qn, rv),
        Method::Auto => crate::singer_closed::steady_state_closed(theta, qn, rv)
            .or_else(|_| steady_state_numeric(theta, qn, rv)),
    }
}

/// The numeric route: [`riccati::kalman_steady_state`] on the normalised model.
pub fn steady_state_numeric(theta: f64, qn: f64, rv: f64) -> Result<SteadyState> {
    validate(theta, qn, rv)?;
    let (phi, g) = normalized_model(theta)?;
    let q = sym3(g) * qn;
    let (h, r) = measurement(rv);
    let ks = riccati::kalman_steady_state(&to_d(&phi), &h, &to_d(&q), &r)?;
    let p = Matrix3::from_fn(|i, j| ks.p_pred[(i, j)]);
    finish(theta, phi, q, rv, p, Method::Numeric)
}

/// K, P_filt, P_smooth and eigenvalues from the prediction covariance.
pub(crate) fn finish(
    _theta: f64,
    phi: Matrix3<f64>,
    q: Matrix3<f64>,
    rv: f64,
    p: Matrix3<f64>,
    method_used: Method,
) -> Result<SteadyState> {
    // A variance whose true value is below the solvers' tolerance (1e-8 of
    // ||P||) can come out slightly negative; beyond 1e-7 of ||P|| the
    // solution is wrong, not rounded (fuzzing: theta = 0.757 with q and the
    // velocity noise at 1e-71 gave a position variance of -4.7e-50 next to
    // the other variances' 3e-72 and 6e-72). Python raises this as
    // LinAlgError and zeroes the variances within the tolerance.
    let scale = p.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if let Some(i) = (0..3).find(|&i| p[(i, i)].is_nan() || p[(i, i)] < -1e-7 * scale) {
        return Err(Error::NoSolution(format!(
            "the computed prediction covariance has a negative variance P[{i},{i}] = {:e} \
             (max |P| = {scale:e}): the problem is too ill-conditioned for the solver",
            p[(i, i)]
        )));
    }
    let (h, r) = measurement(rv);
    let ks = riccati::kalman_from_prediction(&to_d(&phi), &h, &r, to_d(&p))?;
    if ks.rho.is_nan() || ks.rho >= 1.0 {
        return Err(Error::NoSolution(format!(
            "steady-state predictor is not stable (spectral radius {})",
            ks.rho
        )));
    }
    let mut k = [[0.0; 2]; 3];
    for (i, row) in k.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate().take(h.nrows()) {
            *v = ks.k_filt[(i, j)];
        }
    }
    let p_filt = Matrix3::from_fn(|i, j| ks.p_filt[(i, j)]);
    let p_smooth = smoother_covariance(&phi, &p, &p_filt)?;
    // Hamiltonian eigenvalues outside the unit circle: reciprocals of the
    // closed-loop (predictor) eigenvalues.
    let closed = to_d(&phi) - &ks.k_pred * &h;
    let eig = closed_loop_eigenvalues(&closed)?;
    let mut lam: Vec<(f64, f64)> = eig
        .iter()
        .map(|&(re, im)| {
            let d = re * re + im * im;
            if d == 0.0 {
                (f64::INFINITY, 0.0)
            } else {
                (re / d, -im / d)
            }
        })
        .collect();
    lam.sort_by(|a, b| {
        let ma = a.0.hypot(a.1);
        let mb = b.0.hypot(b.1);
        mb.total_cmp(&ma).then(b.1.total_cmp(&a.1))
    });
    let eigenvalues = [lam[0], lam[1], lam[2]];
    Ok(SteadyState {
        p_pred: p,
        k,
        p_filt,
        p_smooth,
        eigenvalues,
        method_used,
        phi,
        q,
    })
}

fn closed_loop_eigenvalues(m: &DMatrix<f64>) -> Result<Vec<(f64, f64)>> {
    let schur = nalgebra::Schur::try_new(m.clone(), f64::EPSILON, 10_000)
        .ok_or_else(|| Error::NoSolution("closed-loop Schur form did not converge".into()))?;
    Ok(schur
        .complex_eigenvalues()
        .iter()
        .map(|z| (z.re, z.im))
        .collect())
}

/// Steady-state smoothing covariance from eq (22):
/// `P_s - A P_s A' = P_filt - A P A'`, `A = P_filt Phi' P^-1`,
/// solved as a 9x9 Kronecker system.
pub fn smoother_covariance(
    phi: &Matrix3<f64>,
    p: &Matrix3<f64>,
    p_filt: &Matrix3<f64>,
) -> Result<Matrix3<f64>> {
    let p_inv_phi_pf = p
        .lu()
        .solve(&(phi * p_filt))
        .ok_or_else(|| Error::NoSolution("the prediction covariance is singular".into()))?;
    let a = p_inv_phi_pf.transpose(); // P_filt Phi' P^-1 (P, P_filt symmetric)
    let c = p_filt - a * p * a.transpose();
    // vec(A X A') = (A kron A) vec(X) (column-major vec).
    let mut m = DMatrix::<f64>::identity(9, 9);
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                for l in 0..3 {
                    // row index of X_ij: i + 3 j; column of X_kl: k + 3 l.
                    m[(i + 3 * j, k + 3 * l)] -= a[(i, k)] * a[(j, l)];
                }
            }
        }
    }
    let rhs = DMatrix::from_fn(9, 1, |r, _| c[(r % 3, r / 3)]);
    let x = m
        .lu()
        .solve(&rhs)
        .ok_or_else(|| Error::NoSolution("the smoother Lyapunov equation is singular".into()))?;
    let ps = Matrix3::from_fn(|i, j| x[(i + 3 * j, 0)]);
    Ok((ps + ps.transpose()) * 0.5)
}

#[cfg(test)]
#[path = "tests/singer.rs"]
mod tests;
