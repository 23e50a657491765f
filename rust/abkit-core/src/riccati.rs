//! The discrete algebraic Riccati equation (DARE) and the steady-state
//! Kalman filter it gives.
//!
//! [`solve_dare`] solves, with scipy's meaning of the arguments,
//!
//! ```text
//! A' X A - X - (A' X B + S) (R + B' X B)^-1 (B' X A + S') + Q = 0
//! ```
//!
//! for the unique symmetric *stabilising* solution (the closed loop
//! `A - B K`, `K = (R + B' X B)^-1 (B' X A + S')`, has spectral radius < 1).
//!
//! # Algorithm
//! The structure-preserving doubling algorithm (SDA) of Chu, Fan and Lin
//! (2005). With `S` folded into `A` and `Q` (`A0 = A - B R^-1 S'`,
//! `H0 = Q - S R^-1 S'`, `G0 = B R^-1 B'`) it iterates
//!
//! ```text
//! W = I + G_k H_k
//! A_k+1 = A_k W^-1 A_k
//! G_k+1 = G_k + A_k W^-1 G_k A_k'
//! H_k+1 = H_k + A_k' H_k W^-1 A_k
//! ```
//!
//! and `H_k -> X` quadratically when a stabilising solution exists.
//!
//! A singular (or nearly singular) `R` is handled exactly by a shift: for any
//! symmetric `Y`, `X` solves the DARE iff `Z = X - Y` solves the DARE with
//! `R + B' Y B`, `S + A' Y B`, `Q + A' Y A - Y` (an algebraic identity).
//! With `Y = c I` the shifted `R` is nonsingular whenever `B` has full column
//! rank on the null space of `R`, which is where `R + B' X B` can be
//! nonsingular at all for `X` near a multiple of the identity.
//!
//! # Checks on every result
//! Every solution is returned only after (1) its relative residual is below
//! [`RESIDUAL_TOL`] and (2) the closed-loop spectral radius (from a real
//! Schur form) is below `1 - `[`STABILITY_MARGIN`]. Otherwise the error is
//! [`Error::NoSolution`]: in particular when a unit-circle mode of `A` is not
//! weighted by `Q` (where scipy returns a non-stabilising `X`).

use crate::{Error, Result};
use nalgebra::{DMatrix, Schur, SymmetricEigen};

/// Largest accepted relative residual of a returned solution.
pub const RESIDUAL_TOL: f64 = 1e-8;
/// The closed-loop spectral radius must be below `1 - STABILITY_MARGIN`.
pub const STABILITY_MARGIN: f64 = 1e-12;
/// Relative asymmetry accepted in `Q` and `R`.
pub const SYMMETRY_RTOL: f64 = 1e-10;
const MAX_ITER: usize = 100;

/// A stabilising DARE solution and its checks.
#[derive(Debug, Clone, PartialEq)]
pub struct Dare {
    /// The stabilising solution `X` (symmetric).
    pub x: DMatrix<f64>,
    /// `K = (R + B' X B)^-1 (B' X A + S')`.
    pub k: DMatrix<f64>,
    /// Spectral radius of `A - B K`.
    pub rho: f64,
    /// `||residual||_F / (||A'XA||_F + ||X||_F + ||Q||_F + ||(A'XB+S) K||_F)`.
    pub residual: f64,
    /// Doubling steps taken.
    pub iterations: usize,
}

/// The steady-state Kalman filter of `x+ = F x + w`, `z = H x + v`,
/// `cov(w) = Q`, `cov(v) = R`.
#[derive(Debug, Clone, PartialEq)]
pub struct KalmanSteadyState {
    /// Prediction (a priori) covariance: the DARE solution.
    pub p_pred: DMatrix<f64>,
    /// Filter-form gain `K = P H' (H P H' + R)^-1` (the update `x + K (z - H x)`).
    pub k_filt: DMatrix<f64>,
    /// Predictor-form gain `F K` (the one-step predictor `x+ = F x + F K (z - H x)`).
    pub k_pred: DMatrix<f64>,
    /// Filtered (a posteriori) covariance, Joseph form `(I - K H) P (I - K H)' + K R K'`.
    pub p_filt: DMatrix<f64>,
    /// Innovation covariance `H P H' + R`.
    pub innovation: DMatrix<f64>,
    /// Spectral radius of the predictor `F - F K H`.
    pub rho: f64,
}

fn fro(m: &DMatrix<f64>) -> f64 {
    m.norm()
}

fn check_finite(name: &'static str, m: &DMatrix<f64>) -> Result<()> {
    match m.iter().find(|v| !v.is_finite()) {
        Some(&v) => Err(Error::domain(name, "finite (no NaN or Inf entries)", v)),
        None => Ok(()),
    }
}

fn check_square(name: &'static str, m: &DMatrix<f64>, n: usize) -> Result<()> {
    if m.nrows() != n || m.ncols() != n {
        return Err(Error::Shape(format!(
            "{name} must be {n}x{n}, got {}x{}",
            m.nrows(),
            m.ncols()
        )));
    }
    Ok(())
}

fn check_symmetric(name: &'static str, m: &DMatrix<f64>) -> Result<()> {
    let scale = m.amax();
    let asym = (m - m.transpose()).amax();
    if asym > SYMMETRY_RTOL * scale {
        return Err(Error::domain(
            name,
            format!("symmetric (max |{name} - {name}'| = {asym:e})"),
            asym,
        ));
    }
    Ok(())
}

fn sym(m: DMatrix<f64>) -> DMatrix<f64> {
    (&m + m.transpose()) * 0.5
}

/// Spectral radius of a square matrix, from its real Schur form.
pub fn spectral_radius(m: &DMatrix<f64>) -> Result<f64> {
    if m.nrows() == 0 {
        return Ok(0.0);
    }
    let n = m.nrows();
    let schur = Schur::try_new(m.clone(), f64::EPSILON, 1000 * n.max(10))
        .ok_or_else(|| Error::NoSolution("the closed-loop Schur form did not converge".into()))?;
    Ok(schur
        .complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max))
}

/// Solve `M Y = rhs` for nonsingular `M` (LU), or report `what` as singular.
fn solve(m: &DMatrix<f64>, rhs: &DMatrix<f64>, what: &str) -> Result<DMatrix<f64>> {
    let y = m
        .clone()
        .lu()
        .solve(rhs)
        .ok_or_else(|| Error::NoSolution(format!("{what} is singular")))?;
    if y.iter().all(|v| v.is_finite()) {
        Ok(y)
    } else {
        Err(Error::NoSolution(format!(
            "{what} is singular to working precision"
        )))
    }
}

/// Reciprocal 2-norm condition number of a symmetric matrix (0 if singular).
fn rcond_sym(m: &DMatrix<f64>) -> f64 {
    if m.nrows() == 0 {
        return 1.0;
    }
    match SymmetricEigen::try_new(m.clone(), f64::EPSILON, 1000 * m.nrows().max(10)) {
        Some(e) => {
            let big = e.eigenvalues.amax();
            let small = e
                .eigenvalues
                .iter()
                .fold(f64::INFINITY, |a, v| a.min(v.abs()));
            if big > 0.0 {
                small / big
            } else {
                0.0
            }
        }
        None => 0.0,
    }
}

/// Validate the DARE data; returns `(n, m)`.
fn validate(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<(usize, usize)> {
    let n = a.nrows();
    if n == 0 {
        return Err(Error::Shape("A must be at least 1x1, got n = 0".into()));
    }
    check_square("A", a, n)?;
    if b.nrows() != n || b.ncols() == 0 {
        return Err(Error::Shape(format!(
            "B must be {n}xm with m >= 1, got {}x{}",
            b.nrows(),
            b.ncols()
        )));
    }
    let m = b.ncols();
    check_square("Q", q, n)?;
    check_square("R", r, m)?;
    if let Some(s) = s {
        if s.nrows() != n || s.ncols() != m {
            return Err(Error::Shape(format!(
                "S must be {n}x{m}, got {}x{}",
                s.nrows(),
                s.ncols()
            )));
        }
        check_finite("S", s)?;
    }
    check_finite("A", a)?;
    check_finite("B", b)?;
    check_finite("Q", q)?;
    check_finite("R", r)?;
    check_symmetric("Q", q)?;
    check_symmetric("R", r)?;
    Ok((n, m))
}

/// Closed-loop gain, residual and spectral radius of a candidate `X`.
fn check_solution(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, f64, f64)> {
    let xb = x * b;
    let rr = sym(r + b.transpose() * &xb);
    let axb_s = a.transpose() * &xb + s;
    let k = solve(&rr, &axb_s.transpose(), "R + B' X B")?;
    let axa = a.transpose() * x * a;
    let corr = &axb_s * &k;
    let res = &axa - x - &corr + q;
    let den = fro(&axa) + fro(x) + fro(q) + fro(&corr);
    let rel = if den > 0.0 {
        fro(&res) / den
    } else {
        fro(&res)
    };
    let rho = spectral_radius(&(a - b * &k))?;
    Ok((k, rel, rho))
}

/// Solve the DARE for its stabilising solution (see the module docs).
///
/// `s = None` means `S = 0`. Errors: [`Error::Shape`] / [`Error::Domain`]
/// (naming `A`, `B`, `Q`, `R` or `S`) for malformed data,
/// [`Error::NoSolution`] when no stabilising solution exists or it cannot be
/// computed to [`RESIDUAL_TOL`].
pub fn solve_dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Dare> {
    let (n, m) = validate(a, b, q, r, s)?;
    let q = sym(q.clone());
    let r_in = sym(r.clone());
    let s_in = match s {
        Some(s) => s.clone(),
        None => DMatrix::zeros(n, m),
    };
    // Equilibrate the input space: with E = diag(1/sqrt(|R_ii|)) (1 where
    // R_ii = 0), (B E, E R E, S E) has the same solution X, and a badly
    // scaled but nonsingular R is not mistaken for a singular one.
    let e = DMatrix::from_diagonal(&nalgebra::DVector::from_fn(m, |i, _| {
        let d = r_in[(i, i)].abs();
        if d > 0.0 {
            1.0 / d.sqrt()
        } else {
            1.0
        }
    }));
    let b_in = b;
    let b = &(b_in * &e);
    let r = sym(&e * &r_in * &e);
    let s0 = &s_in * &e;

    // Shift X = Y + Z with Y = c I when R is (nearly) singular.
    let c = if rcond_sym(&r) < 1e-10 {
        let nb = fro(b);
        let cand = fro(&q).max(if nb > 0.0 { fro(&r) / (nb * nb) } else { 0.0 });
        if cand > 0.0 && cand.is_finite() {
            cand
        } else {
            1.0
        }
    } else {
        0.0
    };
    let eye = DMatrix::<f64>::identity(n, n);
    let (r1, s1, q1) = if c > 0.0 {
        let y = &eye * c;
        (
            sym(&r + b.transpose() * &y * b),
            &s0 + a.transpose() * &y * b,
            sym(&q + a.transpose() * &y * a - &y),
        )
    } else {
        (r.clone(), s0.clone(), q.clone())
    };
    if rcond_sym(&r1) < 1e-14 {
        return Err(Error::NoSolution(
            "R + B' X B is singular for every X tried (R singular on a direction B does not reach)"
                .into(),
        ));
    }
    let rinv_bt = solve(&r1, &b.transpose(), "R")?; // R^-1 B'
    let rinv_st = solve(&r1, &s1.transpose(), "R")?; // R^-1 S'
    let mut ak = a - b * &rinv_st;
    let mut hk = sym(&q1 - &s1 * &rinv_st);
    let mut gk = sym(b * &rinv_bt);

    let mut iterations = 0;
    let mut polish = false;
    for it in 1..=MAX_ITER {
        iterations = it;
        let w = &eye + &gk * &hk;
        let mut rhs = DMatrix::<f64>::zeros(n, 2 * n);
        rhs.columns_mut(0, n).copy_from(&ak);
        rhs.columns_mut(n, n).copy_from(&gk);
        let v = solve(&w, &rhs, "I + G H in the doubling iteration")?;
        let v1 = v.columns(0, n).into_owned(); // W^-1 A
        let v2 = v.columns(n, n).into_owned(); // W^-1 G
        let a_next = &ak * &v1;
        let g_next = sym(&gk + &ak * v2 * ak.transpose());
        let h_next = sym(&hk + ak.transpose() * &hk * &v1);
        let dh = fro(&(&h_next - &hk));
        let hn = fro(&h_next);
        ak = a_next;
        gk = g_next;
        hk = h_next;
        if !hk.iter().all(|v| v.is_finite()) || !gk.iter().all(|v| v.is_finite()) {
            return Err(Error::NoSolution(format!(
                "no stabilising solution: the doubling iteration diverged after {it} steps \
                 (a mode on or outside the unit circle is not stabilisable or not detectable)"
            )));
        }
        // Quadratic convergence: once the update is at rounding level, one
        // more step polishes and the iteration stops. Without convergence
        // the checks below decide.
        if polish || hn == 0.0 {
            break;
        }
        polish = dh <= 1e-14 * hn;
    }
    let x = if c > 0.0 { sym(hk + &eye * c) } else { hk };
    let (k, residual, rho) = check_solution(a, b_in, &q, &r_in, &s_in, &x)?;
    if rho.is_nan() || rho >= 1.0 - STABILITY_MARGIN {
        return Err(Error::NoSolution(format!(
            "no stabilising solution: closed-loop spectral radius {rho} >= 1 \
             (a mode on or outside the unit circle is not stabilisable by B or not weighted by Q)"
        )));
    }
    if residual.is_nan() || residual > RESIDUAL_TOL {
        return Err(Error::NoSolution(format!(
            "the computed solution has relative residual {residual:e} > {RESIDUAL_TOL:e} \
             (the problem is too ill-conditioned)"
        )));
    }
    Ok(Dare {
        x,
        k,
        rho,
        residual,
        iterations,
    })
}

/// Steady-state Kalman filter of `(F, H, Q, R)`: the DARE with
/// `(A, B) = (F', H')`, then the gains and filtered covariance.
pub fn kalman_steady_state(
    f: &DMatrix<f64>,
    h: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<KalmanSteadyState> {
    let n = f.nrows();
    if n == 0 {
        return Err(Error::Shape("F must be at least 1x1, got n = 0".into()));
    }
    check_square("F", f, n)?;
    if h.ncols() != n || h.nrows() == 0 {
        return Err(Error::Shape(format!(
            "H must be px{n} with p >= 1, got {}x{}",
            h.nrows(),
            h.ncols()
        )));
    }
    let p = h.nrows();
    check_square("Q", q, n)?;
    check_square("R", r, p)?;
    check_finite("F", f)?;
    check_finite("H", h)?;
    let dare = solve_dare(&f.transpose(), &h.transpose(), q, r, None)?;
    kalman_from_prediction(f, h, r, dare.x)
}

/// Gains and filtered covariance from a prediction covariance `P`.
pub fn kalman_from_prediction(
    f: &DMatrix<f64>,
    h: &DMatrix<f64>,
    r: &DMatrix<f64>,
    p_pred: DMatrix<f64>,
) -> Result<KalmanSteadyState> {
    let n = f.nrows();
    let innovation = sym(h * &p_pred * h.transpose() + r);
    let pht = &p_pred * h.transpose();
    let k_filt = solve(&innovation, &pht.transpose(), "H P H' + R")?.transpose();
    let ikh = DMatrix::<f64>::identity(n, n) - &k_filt * h;
    let p_filt = sym(&ikh * &p_pred * ikh.transpose() + &k_filt * r * k_filt.transpose());
    let k_pred = f * &k_filt;
    let rho = spectral_radius(&(f - &k_pred * h))?;
    if rho.is_nan() || rho >= 1.0 {
        // The DARE's closed loop was stable, but the gain recomputed from
        // P in the filter form is not: P is too inaccurate for this problem.
        return Err(Error::NoSolution(format!(
            "the steady-state predictor F - F K H computed from the solution is not stable \
             (spectral radius {rho:e}): the problem is too ill-conditioned"
        )));
    }
    Ok(KalmanSteadyState {
        p_pred,
        k_filt,
        k_pred,
        p_filt,
        innovation,
        rho,
    })
}

#[cfg(test)]
#[path = "tests/riccati.rs"]
mod tests;
