//! The closed-form steady state of the Singer filter: Yoon & Hong's route
//! through Vaughan's 6x6 Hamiltonian, on the normalised model of
//! [`crate::singer`].
//!
//! 1. `H_f = [[F^-T, F^-T M], [Q F^-T, F + Q F^-T M]]`, `M = H' R^-1 H`
//!    (`F^-1` in closed form: `[[1, -1, phi2(theta)], [0, 1, -phi1(theta)], [0, 0, e^theta]]`).
//! 2. The characteristic polynomial `l^6 + a l^5 + b l^4 + c l^3 + b l^2 + a l + 1`
//!    (eq (12)). The paper's `a` is used (it is `-tr H_f`); its printed
//!    `b` and `c` fail the check against `numpy.poly` (docs/errata.md), so
//!    `b` and `-c` are computed as the sums of the 2x2 and 3x3 principal
//!    minors of `H_f`.
//! 3. `X_i = l_i + 1/l_i` are the roots of the cubic (16)
//!    `X^3 - alpha X^2 + beta X - gamma = 0`, `alpha = -a`, `beta = b - 3`,
//!    `gamma = -c + 2a` (eq (14)): one real root `X_3` by Cardano /
//!    Viete, the other two from eq (15), all polished by a Newton step.
//! 4. `l_i = (X_i + sqrt(X_i^2 - 4)) / 2` with the root of modulus > 1,
//!    then refined by Newton steps on `det(l I - H_f)` evaluated by LU
//!    ([`refine_lambda`]; the sextic's rounded coefficients limit the
//!    accuracy of the roots otherwise).
//! 5. Eigenvectors by a structured null space instead of the printed (17):
//!    `(l I - H_f) w = 0` is equivalent to `(l F' - I) u = M v`,
//!    `(l I - F) v = l Q u` (`w = (u, v)`), so `u` spans the null space of
//!    the 3x3 `N(l) = l F' - I - l M (l I - F)^-1 Q` (a cross product of two
//!    of its rows) and `v = l (l I - F)^-1 Q u`.
//! 6. `P = W21 W11^-1` (eq (18)) in complex arithmetic; `P` must come out
//!    real.
//!
//! Every result passes checks before it is returned (else
//! [`Error::NoSolution`], on which `Method::Auto` falls back to the numeric
//! solver): eigenvalues off the unit circle by a margin, a well-conditioned
//! `W11`, a negligible imaginary part of `P`, a symmetric positive definite
//! `P`, and a relative Riccati residual below [`CLOSED_FORM_RESIDUAL_TOL`].

use crate::singer::{finish, normalized_model, phi_k, Method, SteadyState};
use crate::{Error, Result};
use nalgebra::{Complex, Matrix3, Matrix6, Vector3};

type C = Complex<f64>;

/// Largest relative Riccati residual accepted from the closed form.
pub const CLOSED_FORM_RESIDUAL_TOL: f64 = 1e-13;

fn fail(msg: impl Into<String>) -> Error {
    Error::NoSolution(format!("closed form rejected: {}", msg.into()))
}

/// The Hamiltonian `H_f` of the normalised model and its blocks.
pub struct Hamiltonian {
    /// `H_f`.
    pub h: Matrix6<f64>,
    /// `Phi_N`.
    pub f: Matrix3<f64>,
    /// `Q_N`.
    pub q: Matrix3<f64>,
    /// `M = H' R^-1 H = diag(1, 1/r_v^2, 0)`.
    pub m: Matrix3<f64>,
}

/// Build `H_f` (step 1).
pub fn hamiltonian(theta: f64, qn: f64, rv: f64) -> Result<Hamiltonian> {
    let (f, g) = normalized_model(theta)?;
    let q = Matrix3::new(g[0], g[1], g[2], g[1], g[3], g[4], g[2], g[4], g[5]) * qn;
    let ey = theta.exp();
    if !ey.is_finite() {
        return Err(fail("exp(T/tau) overflows (Phi^-1 is not representable)"));
    }
    let finv = Matrix3::new(
        1.0,
        -1.0,
        phi_k(2, theta),
        0.0,
        1.0,
        -phi_k(1, theta),
        0.0,
        0.0,
        ey,
    );
    let fit = finv.transpose();
    let v = if rv.is_infinite() {
        0.0
    } else {
        1.0 / (rv * rv)
    };
    let m = Matrix3::from_diagonal(&Vector3::new(1.0, v, 0.0));
    let fitm = fit * m;
    let qfit = q * fit;
    let mut h = Matrix6::zeros();
    h.fixed_view_mut::<3, 3>(0, 0).copy_from(&fit);
    h.fixed_view_mut::<3, 3>(0, 3).copy_from(&fitm);
    h.fixed_view_mut::<3, 3>(3, 0).copy_from(&qfit);
    h.fixed_view_mut::<3, 3>(3, 3).copy_from(&(f + qfit * m));
    Ok(Hamiltonian { h, f, q, m })
}

/// `(a, b, c)` of eq (12) (step 2): `a = -tr H_f` (the paper's `a`),
/// `b = E2`, `c = -E3`, the sums of the 2x2 and 3x3 principal minors of
/// `H_f` (the elementary symmetric functions of its eigenvalues; unlike
/// Newton's identities on traces of powers, these do not cancel when one
/// eigenvalue dominates).
pub fn char_coefficients(h: &Matrix6<f64>) -> (f64, f64, f64) {
    let a = -h.trace();
    let mut e2 = 0.0;
    let mut e3 = 0.0;
    for i in 0..6 {
        for j in (i + 1)..6 {
            e2 += h[(i, i)] * h[(j, j)] - h[(i, j)] * h[(j, i)];
            for k in (j + 1)..6 {
                let m = |r: usize, c: usize| h[([i, j, k][r], [i, j, k][c])];
                e3 += m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
                    - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
                    + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0));
            }
        }
    }
    (a, e2, -e3)
}

fn cubic_newton(alpha: f64, beta: f64, gamma: f64, x: C) -> C {
    let p = ((x - alpha) * x + beta) * x - gamma;
    let dp = (x * 3.0 - 2.0 * alpha) * x + beta;
    if dp.norm() > 0.0 {
        let step = p / dp;
        if step.re.is_finite() && step.im.is_finite() {
            return x - step;
        }
    }
    x
}

/// Roots of `X^3 - alpha X^2 + beta X - gamma` (step 3): the real root
/// `X_3` in closed form, `X_1,2` from eq (15), each polished by one Newton
/// step.
pub fn cubic_roots(alpha: f64, beta: f64, gamma: f64) -> [C; 3] {
    // X = t + alpha/3: t^3 + p t + r = 0.
    let s = alpha / 3.0;
    let p = beta - alpha * s;
    let r = -2.0 * s * s * s + beta * s - gamma;
    let disc = (r / 2.0).powi(2) + (p / 3.0).powi(3);
    let t3 = if disc >= 0.0 {
        let sq = disc.sqrt();
        let w = -r / 2.0 - r.signum() * sq; // no cancellation
        let u = w.cbrt();
        let v = if u != 0.0 { -p / (3.0 * u) } else { 0.0 };
        u + v
    } else {
        // Three real roots (p < 0): Viete; take the one of largest modulus.
        let m = 2.0 * (-p / 3.0).sqrt();
        let arg = ((3.0 * r / (p * m)) * 2.0).clamp(-1.0, 1.0);
        let phi = arg.acos() / 3.0;
        let cands = [
            m * phi.cos(),
            m * (phi - 2.0 * std::f64::consts::PI / 3.0).cos(),
            m * (phi - 4.0 * std::f64::consts::PI / 3.0).cos(),
        ];
        cands.iter().copied().fold(0.0, |acc: f64, v| {
            if (v + s).abs() > (acc + s).abs() {
                v
            } else {
                acc
            }
        })
    };
    let x3 = cubic_newton(alpha, beta, gamma, C::new(t3 + s, 0.0));
    // Eq (15): X_1,2 = ((alpha - X3) +- sqrt((alpha - X3)^2 - 4 gamma / X3)) / 2.
    let sum = C::new(alpha, 0.0) - x3;
    let prod = C::new(gamma, 0.0) / x3;
    let disc = (sum * sum - prod * 4.0).sqrt();
    // The larger-modulus root first, the other as prod / it (no cancellation).
    let big = if (sum + disc).norm() >= (sum - disc).norm() {
        (sum + disc) * 0.5
    } else {
        (sum - disc) * 0.5
    };
    let small = if big.norm() > 0.0 {
        prod / big
    } else {
        C::new(0.0, 0.0)
    };
    [
        cubic_newton(alpha, beta, gamma, big),
        cubic_newton(alpha, beta, gamma, small),
        x3,
    ]
}

/// Newton refinement of an eigenvalue `l` of `H_f` on the characteristic
/// polynomial evaluated through an LU factorisation (not through the
/// rounded coefficients a, b, c): with `A(l) = [[l F' - I, -M], [-l Q, l I - F]]`
/// (`det A(l) = det F det(l I - H_f)`, see step 5),
/// `d/dl log det A = tr(A^-1 A')`, `A' = [[F', 0], [-Q, I]]`. Two steps,
/// each kept only if it does not increase the step size.
pub fn refine_lambda(ham: &Hamiltonian, l0: C) -> C {
    let f = cm(&ham.f);
    let q = cm(&ham.q);
    let m = cm(&ham.m);
    let mut dprime = Matrix6::<C>::zeros();
    dprime
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&f.transpose());
    dprime.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-q));
    dprime
        .fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&Matrix3::<C>::identity());
    let eye = Matrix3::<C>::identity();
    let mut l = l0;
    let mut last = f64::INFINITY;
    for _ in 0..3 {
        let mut a = Matrix6::<C>::zeros();
        a.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(f.transpose() * l - eye));
        a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-m));
        a.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-q * l));
        a.fixed_view_mut::<3, 3>(3, 3).copy_from(&(eye * l - f));
        let Some(sol) = a.lu().solve(&dprime) else {
            return l; // exactly singular: l is an eigenvalue
        };
        let tr = sol.trace();
        if !(tr.re.is_finite() && tr.im.is_finite()) || tr.norm() == 0.0 {
            return l;
        }
        let step = C::new(1.0, 0.0) / tr;
        if step.norm() > last || step.norm() > 0.5 * (l.norm() - 1.0).max(1e-300) * 4.0 {
            return l;
        }
        last = step.norm();
        l -= step;
        if last <= 1e-16 * l.norm() {
            break;
        }
    }
    l
}

/// `l` with `l + 1/l = X` and `|l| >= 1` (step 4).
pub fn lambda_outside(x: C) -> C {
    let d = (x * x - 4.0).sqrt();
    if (x + d).norm() >= (x - d).norm() {
        (x + d) * 0.5
    } else {
        (x - d) * 0.5
    }
}

fn cm(m: &Matrix3<f64>) -> Matrix3<C> {
    m.map(|v| C::new(v, 0.0))
}

/// Null vector of a (numerically) rank-2 complex 3x3 matrix: the largest
/// cross product of two of its rows (`r . (r x s) = 0` holds bilinearly
/// over the complex numbers, which is what `N u = 0` needs).
fn null_vector(n: &Matrix3<C>) -> Vector3<C> {
    let row = |i: usize| Vector3::new(n[(i, 0)], n[(i, 1)], n[(i, 2)]);
    let cross = |a: Vector3<C>, b: Vector3<C>| {
        Vector3::new(
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        )
    };
    let cands = [
        cross(row(0), row(1)),
        cross(row(0), row(2)),
        cross(row(1), row(2)),
    ];
    let norm = |v: &Vector3<C>| v.iter().map(|z| z.norm_sqr()).sum::<f64>();
    let mut best = cands[0];
    for c in &cands[1..] {
        if norm(c) > norm(&best) {
            best = *c;
        }
    }
    best
}

/// Eigenvector `(u, v)` of `H_f` for `l` (step 5).
fn eigenvector(ham: &Hamiltonian, l: C) -> Result<(Vector3<C>, Vector3<C>)> {
    let f = cm(&ham.f);
    let q = cm(&ham.q);
    let m = cm(&ham.m);
    let eye = Matrix3::<C>::identity();
    let li_f = eye * l - f;
    let li_f_inv = li_f
        .try_inverse()
        .ok_or_else(|| fail("l I - Phi is singular"))?;
    let n = f.transpose() * l - eye - m * li_f_inv * q * l;
    let u = null_vector(&n);
    let v = li_f_inv * q * u * l;
    Ok((u, v))
}

/// The closed-form steady state (see the module docs).
pub fn steady_state_closed(theta: f64, qn: f64, rv: f64) -> Result<SteadyState> {
    let ham = hamiltonian(theta, qn, rv)?;
    let (a, b, c) = char_coefficients(&ham.h);
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return Err(fail("characteristic coefficients are not finite"));
    }
    let (alpha, beta, gamma) = (-a, b - 3.0, -c + 2.0 * a);
    let xs = cubic_roots(alpha, beta, gamma);
    let lams: Vec<C> = xs
        .iter()
        .map(|&x| refine_lambda(&ham, lambda_outside(x)))
        .collect();
    for l in &lams {
        if !(l.re.is_finite() && l.im.is_finite()) || l.norm() < 1.0 + 1e-6 {
            return Err(fail(format!(
                "an eigenvalue is on or too near the unit circle (|l| = {})",
                l.norm()
            )));
        }
    }
    let mut w11 = Matrix3::<C>::zeros();
    let mut w21 = Matrix3::<C>::zeros();
    for (j, &l) in lams.iter().enumerate() {
        let (u, v) = eigenvector(&ham, l)?;
        // The paper's normalisation w_1 = 1 (eq (17)), when possible.
        let s = if u[0].norm() > 0.0 {
            u[0]
        } else {
            C::new(1.0, 0.0)
        };
        for i in 0..3 {
            w11[(i, j)] = u[i] / s;
            w21[(i, j)] = v[i] / s;
        }
    }
    // Conditioning of W11 after row and column equilibration (P = W21 W11^-1
    // is invariant under column scaling; row scaling is a state scaling).
    let w11_inv = w11.try_inverse().ok_or_else(|| fail("W11 is singular"))?;
    let mut eq = w11;
    for i in 0..3 {
        let r = (0..3).map(|j| eq[(i, j)].norm()).fold(0.0, f64::max);
        if r > 0.0 {
            for j in 0..3 {
                eq[(i, j)] /= r;
            }
        }
    }
    for j in 0..3 {
        let c = (0..3).map(|i| eq[(i, j)].norm()).fold(0.0, f64::max);
        if c > 0.0 {
            for i in 0..3 {
                eq[(i, j)] /= c;
            }
        }
    }
    let norm1 = |m: &Matrix3<C>| {
        (0..3)
            .map(|j| (0..3).map(|i| m[(i, j)].norm()).sum::<f64>())
            .fold(0.0, f64::max)
    };
    let cond = match eq.try_inverse() {
        Some(inv) => norm1(&eq) * norm1(&inv),
        None => f64::INFINITY,
    };
    if !(cond.is_finite() && cond < 1e8) {
        return Err(fail(format!("W11 is ill-conditioned (condition {cond:e})")));
    }
    let pc = w21 * w11_inv;
    let pmax = pc.iter().map(|z| z.re.abs()).fold(0.0, f64::max);
    let imax = pc.iter().map(|z| z.im.abs()).fold(0.0, f64::max);
    if !(pmax.is_finite() && imax <= 1e-8 * pmax) {
        return Err(fail(format!(
            "P = W21 W11^-1 is not real (|Im| / |Re| = {:e})",
            imax / pmax
        )));
    }
    let p = pc.map(|z| z.re);
    let p = (p + p.transpose()) * 0.5;
    // Positive definite and a Riccati fixed point.
    if p.cholesky().is_none() {
        return Err(fail("P is not positive definite"));
    }
    let resid = riccati_residual(&ham, &p, rv);
    if resid.is_nan() || resid > CLOSED_FORM_RESIDUAL_TOL {
        return Err(fail(format!(
            "relative Riccati residual {resid:e} > {CLOSED_FORM_RESIDUAL_TOL:e}"
        )));
    }
    finish(theta, ham.f, ham.q, rv, p, Method::ClosedForm)
}

/// `max |Phi (P - P H' S^-1 H P) Phi' + Q - P|_ij / sqrt(P_ii P_jj)`.
fn riccati_residual(ham: &Hamiltonian, p: &Matrix3<f64>, rv: f64) -> f64 {
    // P - P H' (H P H' + R)^-1 H P for H = first one or two unit rows.
    let np = if rv.is_infinite() { 1 } else { 2 };
    let mut s = nalgebra::Matrix2::<f64>::zeros();
    for i in 0..np {
        for j in 0..np {
            s[(i, j)] = p[(i, j)];
        }
    }
    s[(0, 0)] += 1.0;
    if np == 2 {
        s[(1, 1)] += rv * rv;
    } else {
        s[(1, 1)] = 1.0;
    }
    let sinv = match s.try_inverse() {
        Some(x) => x,
        None => return f64::INFINITY,
    };
    let mut ph = nalgebra::Matrix3x2::<f64>::zeros();
    for i in 0..3 {
        for j in 0..np {
            ph[(i, j)] = p[(i, j)];
        }
    }
    let pf = p - ph * sinv * ph.transpose();
    let next = ham.f * pf * ham.f.transpose() + ham.q;
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let d = (p[(i, i)] * p[(j, j)]).sqrt();
            worst = worst.max((next[(i, j)] - p[(i, j)]).abs() / d);
        }
    }
    if worst.is_nan() {
        f64::INFINITY
    } else {
        worst
    }
}

#[cfg(test)]
#[path = "tests/singer_closed.rs"]
mod tests;
