//! Near-optimal alpha-beta-gamma filters (Chen & Chui, paper 004).
//!
//! Source: G. Chen, C. K. Chui, "On near-optimal linear digital tracking
//! filters". Printed formulas that failed their numerical check are listed in
//! `docs/errata.md` ("Paper 004") and re-derived by
//! `docs/errata_checks_004.py`.
//!
//! # Convention and normalisation
//! Gains are in the paper's convention: the *filter-form* gain (the update
//! `y = y_pred + w (z - position_pred)`) is `w = [alpha, beta/h, gamma/h^2]`,
//! `Phi^-1` times the limiting (predictor-form) Kalman gain `K`. Internally
//! everything runs with `h = 1` on the scaled state (position, velocity h,
//! acceleration h^2), where the gains are dimensionless; the process noise
//! `Q = diag(sigma_p, sigma_v, sigma_a)` becomes
//! `diag(sigma_p, sigma_v h^2, sigma_a h^4)` (the paper's *variances*), and
//! the measurement noise variance is `sigma_m`.

use crate::riccati::{kalman_steady_state, solve_dare};
use crate::{Error, Result};
use nalgebra::{DMatrix, Matrix3, Matrix4, Schur, SymmetricEigen, Vector3};

/// Relative tolerance of the equality / sign conditions (rounding of gains
/// that satisfy a condition with equality, e.g. `sigma_p = 0`).
pub const COND_RTOL: f64 = 1e-9;

fn finite(name: &'static str, x: f64) -> Result<f64> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(Error::domain(name, "finite", x))
    }
}

fn positive(name: &'static str, x: f64) -> Result<f64> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(Error::domain(name, "finite and > 0", x))
    }
}

fn nonneg(name: &'static str, x: f64) -> Result<f64> {
    if x.is_finite() && x >= 0.0 {
        Ok(x)
    } else {
        Err(Error::domain(name, "finite and >= 0", x))
    }
}

fn phi1() -> Matrix3<f64> {
    Matrix3::new(1.0, 1.0, 0.5, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0)
}

/// Closed-form limiting gains when only the acceleration is driven
/// (`Q = diag(0, 0, sigma_a)`, or Bar-Shalom's discrete Wiener process
/// acceleration `Q = sigma_a g g'`, `g = [h^2/2, h, 1]` = `Phi e3`: the same
/// innovations, the same gains), from the tracking index
/// `lam = sqrt(sigma_a / sigma_m) h^2`.
///
/// With `s = sqrt(1 - alpha)`, `u = 1 - s`: `alpha = u (2 - u)`,
/// `beta = 2 u^2`, `gamma = 2 u^3 / (2 - u)`, where `u` in (0, 1) is the root
/// of `2 u^3 = lam (1 - u)(2 - u)` (equivalently `2 (1-s)^3 = lam s (1+s)`).
/// The cubic is monotone on (0, 1); solved by safeguarded Newton in `u`
/// (`lam <= 1`) or in `s` (`lam > 1`), to full precision.
pub fn from_tracking_index(lam: f64) -> Result<[f64; 3]> {
    positive("lam", lam)?;
    let u = if lam <= 1.0 {
        // g(u) = 2u^3 - lam (1-u)(2-u), increasing on [0, 1].
        let g = |u: f64| 2.0 * u * u * u - lam * (1.0 - u) * (2.0 - u);
        let dg = |u: f64| 6.0 * u * u + lam * (3.0 - 2.0 * u);
        newton_bracketed(g, dg, 0.0, 1.0, lam.cbrt().min(0.5))
    } else {
        // f(s) = 2(1-s)^3 - lam s (1+s), decreasing on [0, 1].
        let f = |s: f64| 2.0 * (1.0 - s).powi(3) - lam * s * (1.0 + s);
        let df = |s: f64| -6.0 * (1.0 - s).powi(2) - lam * (1.0 + 2.0 * s);
        let s = newton_bracketed(f, df, 0.0, 1.0, (2.0 / lam).min(0.5));
        1.0 - s
    };
    let alpha = u * (2.0 - u);
    let beta = 2.0 * u * u;
    let gamma = 2.0 * u * u * u / (2.0 - u);
    if !(alpha > 0.0 && alpha < 1.0 && gamma > 0.0) {
        return Err(Error::domain(
            "lam",
            format!(
                "moderate enough that the gains are representable in float64 \
                 (they round to alpha={alpha}, beta={beta}, gamma={gamma})"
            ),
            lam,
        ));
    }
    Ok([alpha, beta, gamma])
}

/// Limiting gains `[alpha, beta, gamma]` for the continuous white-noise
/// jerk model (`Q = q [[h^5/20, h^4/8, h^3/6], [h^4/8, h^3/3, h^2/2],
/// [h^3/6, h^2/2, h]]`, `R = sigma_m`) from `lam = sqrt(q h / sigma_m) h^2`.
/// No closed form: the checked Riccati solver.
pub fn from_tracking_index_continuous(lam: f64) -> Result<[f64; 3]> {
    positive("lam", lam)?;
    let l2 = lam * lam;
    if !(l2.is_finite() && l2 > 0.0) {
        return Err(Error::domain(
            "lam",
            "such that lam**2 is a finite positive float64",
            lam,
        ));
    }
    let s = l2.max(1.0);
    let base = [
        1.0 / 20.0,
        1.0 / 8.0,
        1.0 / 6.0,
        1.0 / 8.0,
        1.0 / 3.0,
        0.5,
        1.0 / 6.0,
        0.5,
        1.0,
    ];
    let q = DMatrix::from_row_slice(3, 3, &base) * (l2 / s);
    let f = DMatrix::from_row_slice(3, 3, &[1.0, 1.0, 0.5, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]);
    let hm = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]);
    let r = DMatrix::from_element(1, 1, 1.0 / s);
    let k = kalman_steady_state(&f, &hm, &q, &r)?.k_filt;
    Ok([k[(0, 0)], k[(1, 0)], k[(2, 0)]])
}

/// Newton's method for a monotone function with a sign change on `[lo, hi]`,
/// falling back to bisection whenever a step leaves the bracket.
fn newton_bracketed(
    f: impl Fn(f64) -> f64,
    df: impl Fn(f64) -> f64,
    mut lo: f64,
    mut hi: f64,
    x0: f64,
) -> f64 {
    let inc = f(hi) > f(lo);
    let mut x = x0;
    for _ in 0..200 {
        let fx = f(x);
        if fx == 0.0 {
            return x;
        }
        if (fx < 0.0) == inc {
            lo = x;
        } else {
            hi = x;
        }
        let d = df(x);
        let mut xn = x - fx / d;
        if !(xn > lo && xn < hi && xn.is_finite()) {
            xn = 0.5 * (lo + hi);
        }
        if (xn - x).abs() <= 2.0 * f64::EPSILON * x.abs().max(f64::MIN_POSITIVE) {
            return xn;
        }
        x = xn;
    }
    x
}

/// Stable pole `p` (`|p| < 1`) and `u = 1 - p` of one root `y` of the
/// spectral polynomial: `(1 - p)^2 + p y = 0`, i.e. `p^2 - (2 - y) p + 1 = 0`
/// (reciprocal roots) and `u^2 - y u + y = 0`. Both are taken from the
/// larger-magnitude root of their quadratic and the product of the roots,
/// so neither cancels; `w = y - 4` (given for roots near 4, poles near -1)
/// replaces the cancelling `y - 4`.
fn stable_pole(
    y: nalgebra::Complex<f64>,
    w: Option<f64>,
) -> (nalgebra::Complex<f64>, nalgebra::Complex<f64>) {
    use nalgebra::Complex;
    let (y, d) = match w {
        Some(w) => (
            Complex::new(4.0 + w, 0.0),
            Complex::new(((4.0 + w) * w).sqrt(), 0.0),
        ),
        None => (y, (y * (y - 4.0)).sqrt()),
    };
    let b = Complex::new(2.0, 0.0) - y;
    let big = if (b + d).norm() >= (b - d).norm() {
        b + d
    } else {
        b - d
    };
    let p = Complex::new(2.0, 0.0) / big;
    let ub = if (y + d).norm() >= (y - d).norm() {
        y + d
    } else {
        y - d
    };
    let (ua, uc) = (ub * 0.5, y * 2.0 / ub);
    let one = Complex::new(1.0, 0.0);
    let u = if (one - ua - p).norm() <= (one - uc - p).norm() {
        ua
    } else {
        uc
    };
    (p, u)
}

/// Limiting gains `[alpha, beta, gamma, 1 - alpha]` (h = 1 units,
/// `Q = diag(qp, qv, qa)`, `R = 1`) in closed form by spectral factorisation, accurate to a
/// few ulps over the whole domain (`None` outside the range where the
/// polynomial is evaluated without over/underflow; the caller then uses the
/// Riccati solver).
///
/// The measurement's third difference `(z - 1)^3 z_k` has the spectrum
/// `S(y) = y^3 + qp y^2 + (qv - qa/4) y + qa` in `y = |z - 1|^2` (`|z + 1|^2
/// = 4 - y`), and equals `B(z) e_k` with `B` the monic characteristic
/// polynomial of the closed loop `(I - w H) Phi`, `sigma_e^2 B(z) B(1/z) =
/// S`. Each root `y_i` of `S` gives one pole `p_i` by `(1 - p)^2 + p y = 0`,
/// `|p| < 1`. With `u_i = 1 - p_i` (roots of `p(1 + u)`, see `analyze`):
/// `gamma = u1 u2 u3`, `beta = e2(u) - 3 gamma / 2`,
/// `alpha = e1(u) - e2(u) + e3(u)` and `1 - alpha = p1 p2 p3` (the form
/// without cancellation is used on each side of 1/2). All terms of the
/// symmetric functions are positive (`Re u > 0`), so nothing cancels: the
/// Riccati/Corollary formulation instead solves for `alpha` near 1 and
/// divides by the cancelling `1 - alpha` (see docs/abg.md, "Accuracy").
pub fn spectral_gains(qp: f64, qv: f64, qa: f64) -> Option<[f64; 4]> {
    use nalgebra::Complex;
    let (c2, c1, c0) = (qp, qv - 0.25 * qa, qa);
    let s = |y: f64| ((y + c2) * y + c1) * y + c0;
    let ds = |y: f64| (3.0 * y + 2.0 * c2) * y + c1;
    // Fujiwara's bound on the roots' moduli.
    let bound = 2.0 * c2.max(c1.abs().sqrt()).max((0.5 * c0).cbrt());
    if !(bound.is_finite() && (1e-90..=1e90).contains(&bound)) {
        return None;
    }
    // A negative real root exists (S(0) = qa > 0, S(-inf) < 0): safeguarded Newton.
    let (mut lo, mut hi, mut x) = (-bound, 0.0_f64, -bound);
    for _ in 0..400 {
        let fx = s(x);
        if fx == 0.0 {
            break;
        }
        if fx < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let mut xn = x - fx / ds(x);
        if !(xn > lo && xn < hi) {
            xn = 0.5 * (lo + hi);
        }
        let done = (xn - x).abs() <= 2.0 * f64::EPSILON * x.abs();
        x = xn;
        if done {
            break;
        }
    }
    let y0 = x;
    if !(y0 < 0.0 && s(y0).is_finite()) {
        return None;
    }
    // Deflate: S = (y - y0)(y^2 + d1 y + d0); d0 = -qa / y0 exactly, d1 by
    // whichever of the two Vieta forms has the smaller rounding error.
    let d0 = -c0 / y0;
    let e_sum = c2.abs() + y0.abs();
    let e_lin = (d0.abs() + qv + 0.25 * qa) / y0.abs();
    let d1 = if e_sum <= e_lin {
        c2 + y0
    } else {
        (d0 - c1) / y0
    };
    let disc = Complex::new(d1 * d1 - 4.0 * d0, 0.0).sqrt();
    let t = if d1 >= 0.0 {
        (Complex::new(d1, 0.0) + disc) * -0.5
    } else {
        (Complex::new(d1, 0.0) - disc) * -0.5
    };
    if t.norm() == 0.0 || !t.re.is_finite() || !t.im.is_finite() {
        return None;
    }
    let roots = [Complex::new(y0, 0.0), t, Complex::new(d0, 0.0) / t];
    let mut p = [Complex::new(0.0, 0.0); 3];
    let mut u = [Complex::new(0.0, 0.0); 3];
    for (i, y) in roots.into_iter().enumerate() {
        let mut w = None;
        // (A real root is never in [0, 4]: S > 0 there; one computed just
        // below 4 is a root just above it, rounded.)
        if y.im == 0.0 && y.re > 3.0 && y.re < 8.0 {
            // Root near 4 (pole near -1): solve S(4 + w) = 0 for w directly.
            let (t2, t1, t0) = (
                12.0 + qp,
                48.0 + 8.0 * qp + qv - 0.25 * qa,
                64.0 + 16.0 * qp + 4.0 * qv,
            );
            let mut wv = (y.re - 4.0).max(0.0);
            for _ in 0..8 {
                let f = ((wv + t2) * wv + t1) * wv + t0;
                let df = (3.0 * wv + 2.0 * t2) * wv + t1;
                let wn = wv - f / df;
                if !(wn > 0.0 && wn.is_finite()) {
                    break;
                }
                let done = (wn - wv).abs() <= f64::EPSILON * wv;
                wv = wn;
                if done {
                    break;
                }
            }
            w = Some(wv);
        }
        let (pi, ui) = stable_pole(y, w);
        p[i] = pi;
        u[i] = ui;
    }
    let e1 = u[0] + u[1] + u[2];
    let e2 = u[0] * u[1] + u[0] * u[2] + u[1] * u[2];
    let e3 = u[0] * u[1] * u[2];
    let om = (p[0] * p[1] * p[2]).re;
    let gamma = e3.re;
    let beta = (e2 - e3 * 1.5).re;
    let alpha = if om > 0.5 {
        (e1 - e2 + e3).re
    } else {
        1.0 - om
    };
    let ok = p.iter().all(|z| z.norm() < 1.0)
        && om > 0.0
        && alpha > 0.0
        && alpha <= 1.0
        && beta > 0.0
        && gamma > 0.0
        && gamma.is_finite()
        && beta.is_finite();
    ok.then_some([alpha, beta, gamma, om])
}

/// The dimensionless noise `[q_p, q_v, q_a] = [sigma_p, sigma_v h^2,
/// sigma_a h^4] / sigma_m` of the `h = 1`, `R = 1` model (unvalidated; see
/// [`from_noise`]).
pub fn normalised_noise(sp: f64, sv: f64, sa: f64, sm: f64, h: f64) -> [f64; 3] {
    let h2 = h * h;
    [sp / sm, sv / sm * h2, sa / sm * (h2 * h2)]
}

/// Limiting Kalman gains `[alpha, beta, gamma]` (paper convention) for
/// `Q = diag(sigma_p, sigma_v, sigma_a)`, `R = sigma_m` (variances), period `h`.
///
/// `sigma_a = 0` has no limiting gain (Lemma 2): [`Error::NoSolution`].
/// Uses the closed form of [`from_tracking_index`] when
/// `sigma_p = sigma_v = 0`, the spectral closed form [`spectral_gains`]
/// otherwise (accurate to a few ulps, `tests/test_abg_accuracy.py`), and the
/// Riccati solver only where that form's polynomial would over/underflow
/// (roots beyond `1e+-90`). A process noise so much larger than the
/// measurement noise that `alpha` rounds to 1 is an [`Error::Domain`] on
/// `sigma_m` (as [`from_tracking_index`] for `lam`).
pub fn from_noise(sp: f64, sv: f64, sa: f64, sm: f64, h: f64) -> Result<[f64; 3]> {
    nonneg("sigma_p", sp)?;
    nonneg("sigma_v", sv)?;
    nonneg("sigma_a", sa)?;
    positive("sigma_m", sm)?;
    positive("h", h)?;
    if sa == 0.0 {
        return Err(Error::NoSolution(
            "sigma_a = 0: no limiting Kalman gain exists (Lemma 2: [Phi, S] is not \
             stabilisable, the acceleration mode is not driven)"
                .into(),
        ));
    }
    let [qp, qv, qa] = normalised_noise(sp, sv, sa, sm, h);
    for (name, v) in [
        ("sigma_p/sigma_m", qp),
        ("sigma_v*h**2/sigma_m", qv),
        ("sigma_a*h**4/sigma_m", qa),
    ] {
        if !v.is_finite() || (name.starts_with("sigma_a") && v <= 0.0) {
            return Err(Error::domain(
                name,
                "representable as a finite (positive) float64 (it over- or underflows)",
                v,
            ));
        }
    }
    if qp == 0.0 && qv == 0.0 {
        return from_tracking_index(qa.sqrt());
    }
    if let Some([alpha, beta, gamma, om]) = spectral_gains(qp, qv, qa) {
        if !(alpha < 1.0 && om > 0.0) {
            return Err(Error::domain(
                "sigma_m",
                format!(
                    "large enough that 1 - alpha is representable (the process noise over the \
                     measurement noise is so large that alpha rounds to 1; 1 - alpha = {om:e})"
                ),
                sm,
            ));
        }
        return Ok([alpha, beta, gamma]);
    }
    // Outside the range of the closed form (roots beyond 1e+-90): the
    // checked Riccati solver, Newton-polished.
    // Gains are invariant under a common scaling of Q and R.
    let scale = qp.max(qv).max(qa).max(1.0);
    let f = DMatrix::from_row_slice(3, 3, phi1().as_slice()).transpose();
    let hm = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]);
    let q = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![
        qp / scale,
        qv / scale,
        qa / scale,
    ]));
    let r = DMatrix::from_element(1, 1, 1.0 / scale);
    let kss = kalman_steady_state(&f, &hm, &q, &r)?;
    let x0 = [kss.k_filt[(0, 0)], kss.k_filt[(1, 0)], kss.k_filt[(2, 0)]];
    Ok(polish(x0, [qp, qv, qa]))
}

/// Scaled residual of the Corollary's (iv)-(vi), multiplied out by
/// `1 - alpha`, at gains `x` for the target ratios `t` (h = 1 units).
fn corollary_residual(x: [f64; 3], t: [f64; 3]) -> (Vector3<f64>, f64) {
    let [a, b, g] = x;
    let om = 1.0 - a;
    let f = Vector3::new(
        a * a + a * b + 0.5 * a * g - 2.0 * b - t[0] * om,
        b * b - 2.0 * a * g - t[1] * om,
        g * g - t[2] * om,
    );
    let s = [
        a * a + a * b + 0.5 * a * g + 2.0 * b + t[0] * om,
        b * b + 2.0 * a * g + t[1] * om,
        g * g + t[2] * om,
    ];
    let norm = (0..3).fold(0.0_f64, |m, i| {
        m.max(f[i].abs() / s[i].max(f64::MIN_POSITIVE))
    });
    (f, norm)
}

/// Newton polish of Riccati gains on the Corollary's closed-form inverse
/// map: a step is kept only if it lowers the scaled residual, so the result
/// is never worse than the Riccati solution.
fn polish(mut x: [f64; 3], t: [f64; 3]) -> [f64; 3] {
    let (mut f, mut norm) = corollary_residual(x, t);
    for _ in 0..4 {
        if norm <= 4.0 * f64::EPSILON {
            break;
        }
        let [a, b, g] = x;
        let j = Matrix3::new(
            2.0 * a + b + 0.5 * g + t[0],
            a - 2.0,
            0.5 * a,
            -2.0 * g + t[1],
            2.0 * b,
            -2.0 * a,
            t[2],
            0.0,
            2.0 * g,
        );
        let Some(dx) = j.lu().solve(&f) else { break };
        let xn = [x[0] - dx[0], x[1] - dx[1], x[2] - dx[2]];
        if !(xn[0] > 0.0 && xn[0] < 1.0 && xn[2] > 0.0 && xn.iter().all(|v| v.is_finite())) {
            break;
        }
        let (fn_, nn) = corollary_residual(xn, t);
        if nn < norm {
            x = xn;
            f = fn_;
            norm = nn;
        } else {
            break;
        }
    }
    x
}

/// The Corollary's matrix P~ (iii), built from the gains.
pub fn p_tilde(a: f64, b: f64, g: f64) -> Matrix3<f64> {
    let p22 = b * (a + b + 0.25 * g) - 0.5 * g * (2.0 + a);
    let p23 = g * (a + 0.5 * b);
    Matrix3::new(a, b, g, b, p22, p23, g, p23, g * (b + g))
}

/// Corollary (i)-(iii): `[near_optimal, (i), (ii), min eigenvalue of P~]`
/// (flags as 0/1). `(ii)` and `(iii)` hold with equality at the boundary
/// (`sigma_p = 0`, `sigma_v = 0`), so they are tested to [`COND_RTOL`].
pub fn near_optimal_conditions(a: f64, b: f64, g: f64) -> Result<[f64; 4]> {
    finite("alpha", a)?;
    finite("beta", b)?;
    finite("gamma", g)?;
    let c1 = a > 0.0 && a < 1.0 && g > 0.0;
    let lo = (2.0 * a * g).max(0.0).sqrt();
    let hi = if a < 2.0 {
        a / (2.0 - a) * (a + 0.5 * g)
    } else {
        f64::NAN
    };
    let tol = COND_RTOL * (a.abs() + b.abs() + g.abs());
    let c2 = b >= lo - tol && b <= hi + tol;
    let pt = p_tilde(a, b, g);
    let emin = SymmetricEigen::new(pt)
        .eigenvalues
        .iter()
        .fold(f64::INFINITY, |m, &e| m.min(e));
    let scale = pt.amax().max(f64::MIN_POSITIVE);
    let c3 = emin >= -COND_RTOL * scale;
    let flag = |x: bool| if x { 1.0 } else { 0.0 };
    Ok([flag(c1 && c2 && c3), flag(c1), flag(c2), emin])
}

/// Corollary (iv)-(vi): `[sigma_p/sigma_m, sigma_v/sigma_m, sigma_a/sigma_m]`
/// for which the gains are near-optimal. Errors (naming the gain) when the
/// gains are not near-optimal for any noise.
pub fn noise_ratios(a: f64, b: f64, g: f64, h: f64) -> Result<[f64; 3]> {
    positive("h", h)?;
    finite("beta", b)?;
    if !(a > 0.0 && a < 1.0) {
        return Err(Error::domain(
            "alpha",
            "in the open interval (0, 1) (Corollary (i))",
            a,
        ));
    }
    if !(g.is_finite() && g > 0.0) {
        return Err(Error::domain("gamma", "finite and > 0 (Corollary (i))", g));
    }
    let one_m = 1.0 - a;
    let np = a * a + a * b + 0.5 * a * g - 2.0 * b;
    let np_scale = a * a + (a * b).abs() + 0.5 * a * g + 2.0 * b.abs();
    let nv = b * b - 2.0 * a * g;
    let nv_scale = b * b + 2.0 * a * g;
    let clamp = |n: f64, s: f64| {
        if n < 0.0 && n >= -COND_RTOL * s {
            0.0
        } else {
            n
        }
    };
    let (np, nv) = (clamp(np, np_scale), clamp(nv, nv_scale));
    if nv < 0.0 {
        return Err(Error::domain(
            "beta",
            format!(
                ">= sqrt(2*alpha*gamma) = {} (Corollary (ii): sigma_v >= 0)",
                (2.0 * a * g).sqrt()
            ),
            b,
        ));
    }
    if np < 0.0 {
        return Err(Error::domain(
            "beta",
            format!(
                "<= alpha/(2-alpha)*(alpha+gamma/2) = {} (Corollary (ii): sigma_p >= 0)",
                a / (2.0 - a) * (a + 0.5 * g)
            ),
            b,
        ));
    }
    let [_, _, _, emin] = near_optimal_conditions(a, b, g)?;
    if emin < -COND_RTOL * p_tilde(a, b, g).amax() {
        return Err(Error::domain(
            "gamma",
            "such that the Corollary's matrix P~ (iii) is nonnegative definite \
             (the gains are not near-optimal for any noise); min eigenvalue",
            emin,
        ));
    }
    let h2 = h * h;
    Ok([np / one_m, nv / one_m / h2, g * g / one_m / (h2 * h2)])
}

/// Jury's stability conditions for the alpha-beta-gamma closed loop
/// `p(z) = z^3 - (3 - a - b - g/2) z^2 + (3 - 2a - b + g/2) z - (1 - a)`
/// as margins (all > 0 iff every pole is inside the unit circle):
/// `[p(1) = g, -p(-1) = 4 - 2a - b (times 2), 1 - |1 - a|,
/// a (2 - a) - |a^2 + a b + a g/2 - 2a - g|]`.
pub fn jury_margins(a: f64, b: f64, g: f64) -> Result<[f64; 4]> {
    finite("alpha", a)?;
    finite("beta", b)?;
    finite("gamma", g)?;
    Ok([
        g,
        4.0 - 2.0 * a - b,
        1.0 - (1.0 - a).abs(),
        a * (2.0 - a) - (a * a + a * b + 0.5 * a * g - 2.0 * a - g).abs(),
    ])
}

/// Names of the values written by [`Analysis::write_row`], in order.
pub const FIELDS: [&str; 40] = [
    "alpha",
    "beta",
    "gamma",
    "near_optimal",
    "p_tilde_min_eig",
    "q_p",
    "q_v",
    "q_a",
    "stable",
    "spectral_radius",
    "pole1_re",
    "pole1_im",
    "pole2_re",
    "pole2_im",
    "pole3_re",
    "pole3_im",
    "vrr_position_filtered",
    "vrr_velocity_filtered",
    "vrr_acceleration_filtered",
    "vrr_position_predicted",
    "vrr_velocity_predicted",
    "vrr_acceleration_predicted",
    "p11",
    "p12",
    "p13",
    "p22",
    "p23",
    "p33",
    "m11",
    "m12",
    "m13",
    "m22",
    "m23",
    "m33",
    "lag_position_filtered",
    "lag_velocity_filtered",
    "lag_acceleration_filtered",
    "lag_position_predicted",
    "lag_velocity_predicted",
    "lag_acceleration_predicted",
];

/// Steady-state analysis of arbitrary gains (paper convention, `h = 1`
/// units: position in `sqrt(sigma_m)`, velocity per `h`, acceleration per
/// `h^2`; lags in units of `j h^3`, `j h^2`, `j h` for a constant jerk `j`).
#[derive(Debug, Clone, PartialEq)]
pub struct Analysis {
    /// Gains.
    pub gains: [f64; 3],
    /// `[near_optimal, (i), (ii), min eig P~]` of [`near_optimal_conditions`].
    pub conditions: [f64; 4],
    /// Normalised noise ratios `[sigma_p, sigma_v h^2, sigma_a h^4] / sigma_m`
    /// for which the gains are near-optimal (NaN if none).
    pub q: [f64; 3],
    /// Spectral radius of `(I - w H) Phi`.
    pub rho: f64,
    /// All poles strictly inside the unit circle (decided on `u = z - 1`).
    pub stable: bool,
    /// Closed-loop poles `(re, im)`, by decreasing modulus.
    pub poles: [(f64, f64); 3],
    /// Measurement-noise-only covariances (filtered, predicted), 3x3.
    pub vrr: (Matrix3<f64>, Matrix3<f64>),
    /// Covariances at the model noise `q` (filtered, predicted); NaN if none.
    pub cov: (Matrix3<f64>, Matrix3<f64>),
    /// Constant-jerk lag (filtered, predicted).
    pub lag: (Vector3<f64>, Vector3<f64>),
}

/// Steady-state covariance of the filtered error of the fixed-gain filter
/// with (scaled) gain `w` for process noise `q` and unit measurement noise:
/// `P = B P B' + (I - w H) Q (I - w H)' + w w'`, `B = (I - w H) Phi`
/// (Kronecker solve), and `M = Phi P Phi' + Q`.
pub fn lyapunov(w: &Vector3<f64>, q: &Matrix3<f64>) -> Result<(Matrix3<f64>, Matrix3<f64>)> {
    let phi = phi1();
    let mut ikh = Matrix3::identity();
    for i in 0..3 {
        ikh[(i, 0)] -= w[i];
    }
    let b = ikh * phi;
    let n = ikh * q * ikh.transpose() + w * w.transpose();
    let mut big = DMatrix::<f64>::identity(9, 9);
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                for l in 0..3 {
                    // vec index row-major: (i, k) -> 3 i + k.
                    big[(3 * i + k, 3 * j + l)] -= b[(i, j)] * b[(k, l)];
                }
            }
        }
    }
    let rhs = DMatrix::from_fn(9, 1, |r, _| n[(r / 3, r % 3)]);
    let sol = big
        .lu()
        .solve(&rhs)
        .ok_or_else(|| Error::NoSolution("the Lyapunov system is singular".into()))?;
    let p = Matrix3::from_fn(|i, j| 0.5 * (sol[3 * i + j] + sol[3 * j + i]));
    let m = phi * p * phi.transpose() + q;
    Ok((p, m))
}

/// Roots of `x^2 + p x + q` as `(re, im)`, without cancellation.
fn quadratic_roots(p: f64, q: f64) -> [(f64, f64); 2] {
    let disc = 0.25 * p * p - q;
    if disc >= 0.0 {
        let t = -0.5 * p - (0.5 * p).signum() * disc.sqrt();
        if t == 0.0 {
            [(0.0, 0.0), (0.0, 0.0)]
        } else {
            [(t, 0.0), (q / t, 0.0)]
        }
    } else {
        let im = (-disc).sqrt();
        [(-0.5 * p, im), (-0.5 * p, -im)]
    }
}

/// Roots of `x^3 + c2 x^2 + c1 x + c0` as `(re, im)`: eigenvalues of the
/// companion matrix, scaled (`x = s y`) to entries of order one, then
/// Newton-polished on the polynomial (small roots next to a large one are
/// otherwise only accurate to `eps` times the largest).
fn cubic_roots(c2: f64, c1: f64, c0: f64) -> Result<Vec<(f64, f64)>> {
    use nalgebra::Complex;
    if c0 == 0.0 {
        let [r1, r2] = quadratic_roots(c2, c1);
        return Ok(vec![r1, r2, (0.0, 0.0)]);
    }
    let s = c2.abs().max(c1.abs().sqrt()).max(c0.abs().cbrt());
    let s = if s > 0.0 && s.is_finite() { s } else { 1.0 };
    let comp = DMatrix::from_row_slice(
        3,
        3,
        &[
            -c2 / s,
            -(c1 / s) / s,
            -((c0 / s) / s) / s,
            1.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
        ],
    );
    let p = |z: Complex<f64>| ((z + c2) * z + c1) * z + c0;
    let dp = |z: Complex<f64>| (z * 3.0 + 2.0 * c2) * z + c1;
    Ok(eig_sorted(comp)?
        .into_iter()
        .map(|(re, im)| {
            let mut z = Complex::new(re * s, im * s);
            let mut pz = p(z).norm();
            for _ in 0..4 {
                let d = dp(z);
                if d.norm() == 0.0 || !pz.is_finite() {
                    break;
                }
                let zn = z - p(z) / d;
                let pn = p(zn).norm();
                if pn < pz && zn.re.is_finite() && zn.im.is_finite() {
                    z = zn;
                    pz = pn;
                } else {
                    break;
                }
            }
            (z.re, if im == 0.0 { 0.0 } else { z.im })
        })
        .collect())
}

/// Eigenvalues of a small real matrix as `(re, im)`, by decreasing modulus.
fn eig_sorted(m: DMatrix<f64>) -> Result<Vec<(f64, f64)>> {
    let n = m.nrows();
    let schur = Schur::try_new(m, f64::EPSILON, 1000 * n.max(10))
        .ok_or_else(|| Error::NoSolution("the Schur form did not converge".into()))?;
    let mut ev: Vec<(f64, f64)> = schur
        .complex_eigenvalues()
        .iter()
        .map(|z| (z.re, z.im))
        .collect();
    ev.sort_by(|x, y| {
        let (mx, my) = (x.0.hypot(x.1), y.0.hypot(y.1));
        my.total_cmp(&mx).then(y.1.total_cmp(&x.1))
    });
    Ok(ev)
}

impl Analysis {
    /// Analyse gains `[alpha, beta, gamma]` (paper convention).
    pub fn analyze(a: f64, b: f64, g: f64) -> Result<Self> {
        let conditions = near_optimal_conditions(a, b, g)?;
        let w = Vector3::new(a, b, g);
        let phi = phi1();
        let mut ikh: Matrix3<f64> = Matrix3::identity();
        for i in 0..3 {
            ikh[(i, 0)] -= w[i];
        }
        // Poles of p(z) = z^3 - (3 - a - b - g/2) z^2 + (3 - 2a - b + g/2) z
        // - (1 - a), the characteristic polynomial of (I - w H) Phi. Small
        // gains put all three near z = 1: there the roots u = z - 1 of
        // p(1 + u) = u^3 + (a + b + g/2) u^2 + (b + 3g/2) u + g are accurate;
        // elsewhere (e.g. near-deadbeat gains, poles near 0) p(z) itself is.
        let near_one = a + b + 0.5 * g <= 1.0;
        let (c2, c1, c0) = if near_one {
            (a + b + 0.5 * g, b + 1.5 * g, g)
        } else {
            (
                -(3.0 - a - b - 0.5 * g),
                3.0 - 2.0 * a - b + 0.5 * g,
                -(1.0 - a),
            )
        };
        let roots = cubic_roots(c2, c1, c0)?;
        // |z|^2 - 1, for z = 1 + u without cancellation.
        let excess = |x: &(f64, f64)| {
            if near_one {
                2.0 * x.0 + x.0 * x.0 + x.1 * x.1
            } else {
                x.0 * x.0 + x.1 * x.1 - 1.0
            }
        };
        let stable = roots.iter().all(|x| excess(x) < 0.0);
        let shift = if near_one { 1.0 } else { 0.0 };
        let mut poles = [(0.0, 0.0); 3];
        for (p, x) in poles.iter_mut().zip(roots.iter()) {
            *p = (shift + x.0, x.1);
        }
        poles.sort_by(|x, y| {
            let (mx, my) = (x.0.hypot(x.1), y.0.hypot(y.1));
            my.total_cmp(&mx).then(y.1.total_cmp(&x.1))
        });
        let rho = poles.iter().fold(0.0_f64, |m, z| m.max(z.0.hypot(z.1)));
        let q = if conditions[0] == 1.0 {
            noise_ratios(a, b, g, 1.0).unwrap_or([f64::NAN; 3])
        } else {
            [f64::NAN; 3]
        };
        let inf = Matrix3::from_element(f64::INFINITY);
        let nan = Matrix3::from_element(f64::NAN);
        let (vrr, cov, lag) = if stable {
            let vrr = lyapunov(&w, &Matrix3::zeros())?;
            let cov = if q[0].is_nan() {
                (nan, nan)
            } else {
                lyapunov(&w, &Matrix3::from_diagonal(&Vector3::new(q[0], q[1], q[2])))?
            };
            // Constant jerk j = 1: x+ = Phi x + d; e_pred+ = Phi (I - w H) e_pred + d.
            let d = Vector3::new(1.0 / 6.0, 0.5, 1.0);
            let sys = Matrix3::identity() - phi * ikh;
            let ep = sys
                .lu()
                .solve(&d)
                .ok_or_else(|| Error::NoSolution("the lag system is singular".into()))?;
            let ef = ikh * ep;
            (vrr, cov, (ef, ep))
        } else {
            let vinf = Vector3::from_element(f64::INFINITY);
            ((inf, inf), (inf, inf), (vinf, vinf))
        };
        Ok(Analysis {
            gains: [a, b, g],
            conditions,
            q,
            rho,
            stable,
            poles,
            vrr,
            cov,
            lag,
        })
    }

    /// Write the values named by [`FIELDS`].
    pub fn write_row(&self, out: &mut [f64]) {
        let mut v: Vec<f64> = Vec::with_capacity(FIELDS.len());
        v.extend_from_slice(&self.gains);
        v.push(self.conditions[0]);
        v.push(self.conditions[3]);
        v.extend_from_slice(&self.q);
        v.push(if self.stable { 1.0 } else { 0.0 });
        v.push(self.rho);
        for p in &self.poles {
            v.push(p.0);
            v.push(p.1);
        }
        for m in [&self.vrr.0, &self.vrr.1] {
            v.extend([m[(0, 0)], m[(1, 1)], m[(2, 2)]]);
        }
        for m in [&self.cov.0, &self.cov.1] {
            v.extend([
                m[(0, 0)],
                m[(0, 1)],
                m[(0, 2)],
                m[(1, 1)],
                m[(1, 2)],
                m[(2, 2)],
            ]);
        }
        v.extend(self.lag.0.iter());
        v.extend(self.lag.1.iter());
        out[..FIELDS.len()].copy_from_slice(&v);
    }
}

/// Theorem 2's matrix Sigma~ (ix), corrected: `sigma~44 = theta - sigma~14`
/// (see the errata; the printed `sigma~44` is wrong).
pub fn sigma_tilde(a: f64, b: f64, g: f64, th: f64, r: f64) -> Matrix4<f64> {
    let rm = r - 1.0;
    let c = rm - th * r;
    let s11 = (c * a + r / rm * th * b - r * (r + 1.0) / (2.0 * rm * rm) * th * g) / rm;
    let s12 = (c * b + th * r / rm * g) / rm;
    let s13 = c * g / rm;
    let s14 = r * th / rm * (a - b / rm + (r + 1.0) / (2.0 * rm * rm) * g);
    let s22 = 0.25 * (4.0 * a + b) * (b + g) + 0.75 * (b * b - 2.0 * a * g) - c / rm * g;
    let s23 = (a + 0.5 * b) * g;
    let s24 = r * th / rm * (b - g / rm);
    let s33 = (b + g) * g;
    let s34 = r * th / rm * g;
    let s44 = th - s14;
    Matrix4::new(
        s11, s12, s13, s14, s12, s22, s23, s24, s13, s23, s33, s34, s14, s24, s34, s44,
    )
}

/// Names of the values written by [`coloured`].
pub const COLOURED_FIELDS: [&str; 17] = [
    "cond_i",
    "cond_ii",
    "cond_iii",
    "cond_iv",
    "cond_v",
    "alpha_plus_theta_minus_1",
    "sigma_tilde_min_eig",
    "sigma_p_over_sigma_a",
    "sigma_v_over_sigma_a",
    "sigma_m_over_sigma_a",
    "riccati_alpha",
    "riccati_beta",
    "riccati_gamma",
    "riccati_theta",
    "gain_mismatch",
    "conditions_hold",
    "near_optimal",
];

/// Theorem 2 (coloured measurement noise, `G = 0`, `F = r`): the
/// conditions, the (corrected) noise ratios and, independently, the limiting
/// gain of the augmented 4-state model with those ratios (`R = 0`).
pub fn coloured(a: f64, b: f64, g: f64, th: f64, r: f64, h: f64) -> Result<[f64; 17]> {
    finite("alpha", a)?;
    finite("beta", b)?;
    finite("theta", th)?;
    positive("h", h)?;
    if !(g.is_finite() && g != 0.0) {
        return Err(Error::domain(
            "gamma",
            "finite and nonzero (Theorem 2 needs sigma_a != 0)",
            g,
        ));
    }
    if !(r.is_finite() && r.abs() < 1.0 && r != 0.0) {
        return Err(Error::domain(
            "r",
            "in (-1, 1) and nonzero (Theorem 2: F = [r] != 0, |r| < 1)",
            r,
        ));
    }
    let rm = r - 1.0;
    let st = sigma_tilde(a, b, g, th, r);
    let c1 = (2.0 * a + 2.0 * b + g) * g;
    let c2 = rm * (rm - r * th) * a + r * th * b - r * (r + 1.0) / (2.0 * rm) * th * g;
    let c3 = 4.0 * st[(1, 1)];
    let c4 = (b + g) * g;
    let c5 = st[(3, 3)];
    let closure = a + th - 1.0;
    let emin = SymmetricEigen::new(st)
        .eigenvalues
        .iter()
        .fold(f64::INFINITY, |m, &e| m.min(e));
    let h2 = h * h;
    let h4 = h2 * h2;
    let qv = h2 / (g * g) * (b * b - 2.0 * a * g);
    let qp = h4 / (2.0 * g * g)
        * ((2.0 * a + 2.0 * b + g) * a
            - 4.0 * (rm - r * th) / rm * b
            - 4.0 * r * th / (rm * rm) * g);
    let qm = h4 / (g * g) * ((1.0 - r * r) * st[(3, 3)] + r * r * th * th);
    let scale = st.amax().max(a.abs()).max(f64::MIN_POSITIVE);
    let tol = COND_RTOL * scale;
    // Not in the printed theorem (see the errata): the ratios must be >= 0.
    let rtol = |x: f64| x >= -COND_RTOL * (1.0 + x.abs()) * h4.max(1.0);
    let conditions_hold = rtol(qp)
        && rtol(qv)
        && rtol(qm)
        && c1 > 0.0
        && c2 > 0.0
        && c3 >= -tol
        && c4 >= -tol
        && c5 >= -tol
        && emin >= -tol
        && closure.abs() <= tol;
    let mut kr = [f64::NAN; 4];
    let mut mismatch = f64::NAN;
    let nq = [qp / h4, qv / h2, qm / h4];
    if nq
        .iter()
        .all(|&x| x.is_finite() && x >= -COND_RTOL * (1.0 + x.abs()))
    {
        // Scaled state (x, v h, a h^2, noise): Q = diag(sp, sv h^2, sa h^4, sm)
        // divided by sa h^4.
        let qd = [nq[0].max(0.0), nq[1].max(0.0), 1.0, nq[2].max(0.0)];
        if let Ok(k) = coloured_gain(qd, r) {
            kr = k;
            let given = [a, b, g, th];
            mismatch = (0..4).fold(0.0_f64, |m, i| {
                m.max((kr[i] - given[i]).abs() / given[i].abs().max(1.0))
            });
        }
    }
    let near = conditions_hold && mismatch <= 1e-6;
    let flag = |x: bool| if x { 1.0 } else { 0.0 };
    Ok([
        c1,
        c2,
        c3,
        c4,
        c5,
        closure,
        emin,
        qp,
        qv,
        qm,
        kr[0],
        kr[1],
        kr[2],
        kr[3],
        mismatch,
        flag(conditions_hold),
        flag(near),
    ])
}

/// Limiting gain `[alpha, beta, gamma, theta]` (paper convention) of the
/// augmented coloured-noise model in scaled units (`h = 1`):
/// `Q = diag(q)`, `F = diag(Phi, r)`, `H = [1, 0, 0, 1]`, `R = 0`.
fn coloured_gain(q: [f64; 4], r: f64) -> Result<[f64; 4]> {
    let s = q.iter().fold(1.0_f64, |m, &x| m.max(x));
    let mut f = DMatrix::<f64>::zeros(4, 4);
    let p = phi1();
    for i in 0..3 {
        for j in 0..3 {
            f[(i, j)] = p[(i, j)];
        }
    }
    f[(3, 3)] = r;
    let hm = DMatrix::from_row_slice(1, 4, &[1.0, 0.0, 0.0, 1.0]);
    let qm = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        4,
        q.iter().map(|x| x / s),
    ));
    let zero = DMatrix::<f64>::zeros(1, 1);
    let d = solve_dare(&f.transpose(), &hm.transpose(), &qm, &zero, None)?;
    let ph = &d.x * hm.transpose();
    let s0 = (&hm * &ph)[(0, 0)];
    if !(s0 > 0.0 && s0.is_finite()) {
        return Err(Error::NoSolution(
            "the innovation variance of the coloured-noise filter is not positive".into(),
        ));
    }
    Ok([
        ph[(0, 0)] / s0,
        ph[(1, 0)] / s0,
        ph[(2, 0)] / s0,
        ph[(3, 0)] / s0,
    ])
}

/// Near-optimal alpha-beta-gamma-theta gains (paper convention) for
/// coloured measurement noise: the limiting Kalman gain of the augmented
/// model with `Q = diag(sigma_p, sigma_v, sigma_a)`, noise
/// `v+ = r v + eta`, `var eta = sigma_m`, no white measurement noise.
pub fn coloured_from_noise(sp: f64, sv: f64, sa: f64, sm: f64, r: f64, h: f64) -> Result<[f64; 4]> {
    nonneg("sigma_p", sp)?;
    nonneg("sigma_v", sv)?;
    nonneg("sigma_a", sa)?;
    nonneg("sigma_m", sm)?;
    positive("h", h)?;
    if !(r.is_finite() && r.abs() < 1.0) {
        return Err(Error::domain("r", "in the open interval (-1, 1)", r));
    }
    if sa == 0.0 {
        return Err(Error::NoSolution(
            "sigma_a = 0: no limiting Kalman gain exists (Lemma 2 / Theorem 1 need sigma_a != 0)"
                .into(),
        ));
    }
    let h2 = h * h;
    let qa = sa * h2 * h2;
    let q = [sp / qa, sv * h2 / qa, 1.0, sm / qa];
    if !q.iter().all(|x| x.is_finite()) {
        return Err(Error::domain(
            "sigma_a*h**4",
            "large enough that the noise ratios are representable in float64",
            qa,
        ));
    }
    coloured_gain(q, r)
}

/// Width of the row written by [`decoupled`]: numerators 4 x 4 (position,
/// velocity, acceleration, noise; coefficients of `z_k .. z_{k-3}`),
/// denominator 5 (`1, -a1, -a2, -a3, -a4`), poles 4 x (re, im), stable,
/// spectral radius.
pub const DECOUPLED_WIDTH: usize = 16 + 5 + 8 + 2;

/// Theorem 3 (corrected): the four uncoupled recursive filters of the
/// alpha-beta-gamma-theta filter as `lfilter` coefficients, its poles
/// (eigenvalues of `A`) and stability.
pub fn decoupled(
    a: f64,
    b: f64,
    g: f64,
    th: f64,
    r: f64,
    h: f64,
) -> Result<[f64; DECOUPLED_WIDTH]> {
    finite("alpha", a)?;
    finite("beta", b)?;
    finite("gamma", g)?;
    finite("theta", th)?;
    finite("r", r)?;
    positive("h", h)?;
    let mut out = [0.0; DECOUPLED_WIDTH];
    let pos = [
        a,
        -2.0 * a - r * a + b + 0.5 * g,
        a - b + 0.5 * g + (2.0 * a - b - 0.5 * g) * r,
        -(a - b + 0.5 * g) * r,
    ];
    let vel = [
        b / h,
        -((2.0 + r) * b - g) / h,
        (b - g + (2.0 * b - g) * r) / h,
        -(b - g) * r / h,
    ];
    let gh = g / (h * h);
    let acc = [gh, -(2.0 + r) * gh, (1.0 + 2.0 * r) * gh, -r * gh];
    let noise = [th, -3.0 * th, 3.0 * th, -th];
    let a1 = -a - b - 0.5 * g + (1.0 - th) * r + 3.0;
    let a2 = 2.0 * a + b - 0.5 * g + (a + b + 0.5 * g + 3.0 * th - 3.0) * r - 3.0;
    let a3 = -a + (-2.0 * a - b + 0.5 * g - 3.0 * th + 3.0) * r + 1.0;
    let a4 = (a + th - 1.0) * r;
    out[..4].copy_from_slice(&pos);
    out[4..8].copy_from_slice(&vel);
    out[8..12].copy_from_slice(&acc);
    out[12..16].copy_from_slice(&noise);
    out[16..21].copy_from_slice(&[1.0, -a1, -a2, -a3, -a4]);
    // A = Phi_c - w [1, h, h^2/2, r] in the scaled state (h = 1).
    let w = [a, b, g, th];
    let row = [1.0, 1.0, 0.5, r];
    let mut am = DMatrix::<f64>::zeros(4, 4);
    let p = phi1();
    for i in 0..3 {
        for j in 0..3 {
            am[(i, j)] = p[(i, j)];
        }
    }
    am[(3, 3)] = r;
    for i in 0..4 {
        for j in 0..4 {
            am[(i, j)] -= w[i] * row[j];
        }
    }
    let ev = eig_sorted(am)?;
    let mut rho = 0.0_f64;
    for (i, z) in ev.iter().take(4).enumerate() {
        out[21 + 2 * i] = z.0;
        out[22 + 2 * i] = z.1;
        rho = rho.max(z.0.hypot(z.1));
    }
    out[29] = if rho < 1.0 { 1.0 } else { 0.0 };
    out[30] = rho;
    Ok(out)
}

#[cfg(test)]
#[path = "tests/abg.rs"]
mod tests;
