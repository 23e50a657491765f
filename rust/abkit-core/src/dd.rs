//! Double-double arithmetic (about 32 significant digits) for the few
//! small, cancellation-prone computations that are done once per design
//! (the steady-state RTS backward gain of the alpha-beta-gamma filter,
//! `irregular.rs`). Sums and products after Dekker / Knuth (`two_sum`,
//! `two_prod` by fused multiply-add); the division refines the quotient
//! twice. Not a general-purpose type: only what those computations need.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// `hi + lo` with `|lo| <= ulp(hi) / 2`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Dd {
    pub hi: f64,
    pub lo: f64,
}

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

#[inline]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

impl Dd {
    pub const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };
    pub const ONE: Dd = Dd { hi: 1.0, lo: 0.0 };

    #[inline]
    pub fn new(x: f64) -> Dd {
        Dd { hi: x, lo: 0.0 }
    }

    #[inline]
    fn norm(hi: f64, lo: f64) -> Dd {
        let (hi, lo) = quick_two_sum(hi, lo);
        Dd { hi, lo }
    }

    /// The nearest float64.
    #[inline]
    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    /// Exact multiplication by a power of two.
    #[inline]
    pub fn scale2(self, p: f64) -> Dd {
        Dd {
            hi: self.hi * p,
            lo: self.lo * p,
        }
    }

    #[inline]
    pub fn is_finite(self) -> bool {
        self.hi.is_finite() && self.lo.is_finite()
    }
}

impl Neg for Dd {
    type Output = Dd;
    #[inline]
    fn neg(self) -> Dd {
        Dd {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Add for Dd {
    type Output = Dd;
    #[inline]
    fn add(self, b: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, b.hi);
        let (t, f) = two_sum(self.lo, b.lo);
        let (s, e) = quick_two_sum(s, e + t);
        Dd::norm(s, e + f)
    }
}

impl Sub for Dd {
    type Output = Dd;
    #[inline]
    fn sub(self, b: Dd) -> Dd {
        self + (-b)
    }
}

impl Mul for Dd {
    type Output = Dd;
    #[inline]
    fn mul(self, b: Dd) -> Dd {
        let p = self.hi * b.hi;
        let e = self.hi.mul_add(b.hi, -p);
        Dd::norm(p, e + (self.hi * b.lo + self.lo * b.hi))
    }
}

impl Div for Dd {
    type Output = Dd;
    #[inline]
    fn div(self, b: Dd) -> Dd {
        let q1 = self.hi / b.hi;
        let r = self - b * Dd::new(q1);
        let q2 = r.hi / b.hi;
        let r = r - b * Dd::new(q2);
        let q3 = r.hi / b.hi;
        let (q1, q2) = quick_two_sum(q1, q2);
        Dd { hi: q1, lo: q2 } + Dd::new(q3)
    }
}

/// 3x3 matrix of double-doubles (row-major).
pub(crate) type M3 = [[Dd; 3]; 3];

pub(crate) fn m3_from(a: &[[f64; 3]; 3]) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| Dd::new(a[i][j])))
}

pub(crate) fn m3_eye() -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| if i == j { Dd::ONE } else { Dd::ZERO }))
}

pub(crate) fn m3_mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

pub(crate) fn m3_add(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] + b[i][j]))
}

pub(crate) fn m3_t(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// `(a + a') / 2`.
pub(crate) fn m3_sym(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (a[i][j] + a[j][i]).scale2(0.5)))
}

/// Largest `|a_ij|` (float64).
pub(crate) fn m3_amax(a: &M3) -> f64 {
    a.iter().flatten().fold(0.0_f64, |m, v| m.max(v.hi.abs()))
}

/// `a^-1 b` by Gaussian elimination with partial pivoting; `None` on a
/// zero pivot or a non-finite result.
#[allow(clippy::needless_range_loop)] // dense elimination: indices are clearer
pub(crate) fn m3_solve(a: &M3, b: &M3) -> Option<M3> {
    let mut a = *a;
    let mut b = *b;
    for k in 0..3 {
        let p = (k..3).max_by(|&i, &j| a[i][k].hi.abs().total_cmp(&a[j][k].hi.abs()))?;
        if a[p][k].hi == 0.0 {
            return None;
        }
        a.swap(k, p);
        b.swap(k, p);
        for i in k + 1..3 {
            let f = a[i][k] / a[k][k];
            for j in k..3 {
                a[i][j] = a[i][j] - f * a[k][j];
            }
            for j in 0..3 {
                b[i][j] = b[i][j] - f * b[k][j];
            }
        }
    }
    let mut x = [[Dd::ZERO; 3]; 3];
    for j in 0..3 {
        for i in (0..3).rev() {
            let mut s = b[i][j];
            for (l, xl) in x.iter().enumerate().skip(i + 1) {
                s = s - a[i][l] * xl[j];
            }
            x[i][j] = s / a[i][i];
        }
    }
    x.iter().flatten().all(|v| v.is_finite()).then_some(x)
}

/// `m^-1 b` for a symmetric positive definite `m`, by the `L D L'`
/// factorisation of `m` equilibrated by powers of two near
/// `1 / sqrt(m_ii)` (exact scaling); `None` if `m` is not positive definite
/// (a pivot `<= 0`) or the result is not finite.
pub(crate) fn m3_spd_solve(m: &M3, b: &M3) -> Option<M3> {
    let mut s = [1.0_f64; 3];
    for (i, si) in s.iter_mut().enumerate() {
        let d = m[i][i].hi;
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        // 2^-round(log2(d)/2): exact, within a factor sqrt(2) of 1/sqrt(d).
        *si = (2.0_f64).powi(-((d.log2() * 0.5).round() as i32));
    }
    let ms: M3 = std::array::from_fn(|i| std::array::from_fn(|j| m[i][j].scale2(s[i] * s[j])));
    let bs: M3 = std::array::from_fn(|i| std::array::from_fn(|j| b[i][j].scale2(s[i])));
    // L D L'.
    let mut l = m3_eye();
    let mut d = [Dd::ZERO; 3];
    for j in 0..3 {
        let mut dj = ms[j][j];
        for k in 0..j {
            dj = dj - l[j][k] * l[j][k] * d[k];
        }
        if !(dj.hi > 0.0 && dj.is_finite()) {
            return None;
        }
        d[j] = dj;
        for i in j + 1..3 {
            let mut v = ms[i][j];
            for k in 0..j {
                v = v - l[i][k] * l[j][k] * d[k];
            }
            l[i][j] = v / dj;
        }
    }
    let mut x = [[Dd::ZERO; 3]; 3];
    for c in 0..3 {
        let mut y = [Dd::ZERO; 3];
        for i in 0..3 {
            let mut v = bs[i][c];
            for k in 0..i {
                v = v - l[i][k] * y[k];
            }
            y[i] = v;
        }
        for (yi, di) in y.iter_mut().zip(d) {
            *yi = *yi / di;
        }
        for i in (0..3).rev() {
            let mut v = y[i];
            for k in i + 1..3 {
                v = v - l[k][i] * x[k][c];
            }
            x[i][c] = v;
        }
    }
    for (i, row) in x.iter_mut().enumerate() {
        for v in row.iter_mut() {
            *v = v.scale2(s[i]);
        }
    }
    x.iter().flatten().all(|v| v.is_finite()).then_some(x)
}

/// `x` with `a x = b` (`N x N`, one right-hand side) by Gaussian
/// elimination with partial pivoting; `None` on a zero pivot or a
/// non-finite result.
#[allow(clippy::needless_range_loop)] // dense elimination: indices are clearer
pub(crate) fn solve_n<const N: usize>(mut a: [[Dd; N]; N], mut b: [Dd; N]) -> Option<[Dd; N]> {
    for k in 0..N {
        let p = (k..N).max_by(|&i, &j| a[i][k].hi.abs().total_cmp(&a[j][k].hi.abs()))?;
        if a[p][k].hi == 0.0 {
            return None;
        }
        a.swap(k, p);
        b.swap(k, p);
        for i in k + 1..N {
            let f = a[i][k] / a[k][k];
            for j in k..N {
                a[i][j] = a[i][j] - f * a[k][j];
            }
            b[i] = b[i] - f * b[k];
        }
    }
    let mut x = [Dd::ZERO; N];
    for i in (0..N).rev() {
        let mut s = b[i];
        for l in i + 1..N {
            s = s - a[i][l] * x[l];
        }
        x[i] = s / a[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The symmetric solution of the Stein equation `X = F X F' + W`
/// (`W` symmetric), as a 6 x 6 linear system in the upper triangle.
pub(crate) fn stein3(f: &M3, w: &M3) -> Option<M3> {
    const IDX: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
    let pos = |a: usize, b: usize| {
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        IDX.iter().position(|&e| e == (a, b)).unwrap_or(0)
    };
    let mut m = [[Dd::ZERO; 6]; 6];
    let mut rhs = [Dd::ZERO; 6];
    for (r, &(i, j)) in IDX.iter().enumerate() {
        m[r][r] = Dd::ONE;
        for a in 0..3 {
            for b in 0..3 {
                let c = pos(a, b);
                m[r][c] = m[r][c] - f[i][a] * f[j][b];
            }
        }
        rhs[r] = w[i][j];
    }
    let x = solve_n(m, rhs)?;
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| x[pos(i, j)])
    }))
}
