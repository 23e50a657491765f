use super::*;
use crate::alphabeta::AlphaBeta;

#[test]
fn ab_design_matches_the_alphabeta_design_at_each_dt() {
    let (sw, sv) = (3.2, 32.0);
    let mut law = AbDesign::new(sw / sv);
    for &dt in &[1e-6, 0.01, 0.1, 0.7, 1.0, 3.3, 100.0, 1e4] {
        let d = AlphaBeta::from_noise(sw, sv, dt).unwrap();
        let s = law.step(dt).unwrap();
        // One square root and one division (ab_design_rate_gains) against
        // the two-branch closed form: within a few ulp.
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
        assert!(rel(s.k[0][0], d.alpha) < 2e-15, "dt={dt}");
        assert!(rel(s.k[1][0], d.beta / dt) < 2e-15, "dt={dt}");
        assert_eq!(s.phi, [[1.0, dt], [0.0, 1.0]]);
        assert_eq!(law.ab_gains(dt), Some((s.k[0][0], s.k[1][0])));
    }
}

#[test]
fn ab_design_by_subtraction_is_as_accurate() {
    // m = sqrt(lambda) <= AB_DESIGN_SMALL_SQRT forms w = 2 / (m + q) as
    // (q - m) / 4 (no division); above it with the division. Both sides of
    // the switch, densely, against the two-branch closed form of
    // AlphaBeta::from_noise: within a few ulp (the subtraction alone
    // would exceed 2e-15 above m ~ 6).
    let (sw, sv) = (1.0, 1.0);
    let law = AbDesign::new(sw / sv);
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    let mut worst: f64 = 0.0;
    for i in 0..4000 {
        // m = dt here: 1e-4 .. 10, and the switch and its neighbours.
        let dt = match i {
            0 => AB_DESIGN_SMALL_SQRT,
            1 => f64::from_bits(AB_DESIGN_SMALL_SQRT.to_bits() - 1),
            2 => f64::from_bits(AB_DESIGN_SMALL_SQRT.to_bits() + 1),
            _ => 10f64.powf(-4.0 + 5.0 * i as f64 / 4000.0),
        };
        let d = AlphaBeta::from_noise(sw, sv, dt).unwrap();
        let (a, g) = law.rate_gains(dt);
        worst = worst.max(rel(a, d.alpha)).max(rel(g, d.beta / dt));
    }
    assert!(worst < 2e-15, "{worst:e}");
}

#[test]
fn ab_design_limits_are_finite() {
    let law = AbDesign::new(1.0);
    assert_eq!(law.gains(1e-200), (0.0, 0.0));
    let (a, b) = law.gains(1e200);
    assert_eq!((a, b), (1.0, 2.0));
    // The rate gains: tiny dt (lambda underflows, sqrt(lambda) does not):
    // alpha ~ 2 sqrt(2 lambda) / 2, beta / dt ~ 2 v^2 / dt, both finite and
    // tiny; huge dt: the limit (1, 2 / dt).
    let (a, g) = law.rate_gains(1e-200);
    assert!(
        a > 0.0 && a < 1e-199 && (0.0..1e-190).contains(&g),
        "{a} {g}"
    );
    assert_eq!(law.rate_gains(1e200), (1.0, 2.0 / 1e200));
    assert_eq!(law.rate_gains(1e151), (1.0, 2.0 / 1e151));
    let (a, g) = law.rate_gains(1e149);
    assert!(a == 1.0 && (g * 1e149 - 2.0).abs() < 2e-15, "{a} {g}");
}

#[test]
fn abg_design_matches_from_noise_and_caches() {
    let mut law = AbgDesign::new(0.3, 0.2, 0.1, 1.0).unwrap();
    for &dt in &[0.05, 0.7, 0.7, 2.0, 0.05] {
        let [a, b, g] = crate::abg::from_noise(0.3, 0.2, 0.1, 1.0, dt).unwrap();
        let s = law.step(dt).unwrap();
        assert_eq!(s.k[0][0], a);
        assert_eq!(s.k[1][0], b / dt);
        assert_eq!(s.k[2][0], g / (dt * dt));
        assert_eq!(s.phi[0][2], 0.5 * dt * dt);
    }
    assert!(AbgDesign::new(-1.0, 0.2, 0.1, 1.0).is_err());
}

#[test]
fn abg_fixed_scales_rate_gains() {
    let mut law = AbgFixed {
        alpha: 0.5,
        beta: 0.3,
        cgamma: 0.05,
    };
    let s = law.step(2.0).unwrap();
    assert_eq!(s.k, [[0.5], [0.15], [0.0125]]);
}

#[test]
fn singer_design_is_the_steady_state_kalman_gain() {
    // Check K against the gain of the physical model's Riccati solution:
    // K = M H' / (H M H' + R) with M the stabilising solution for (Phi, Q).
    let (tau, q, sp) = (20.0, 2.0 * 1.0 / 20.0, 10.0);
    let mut law = SingerDesign::new(tau, q, sp).unwrap();
    for &dt in &[0.1, 1.0, 7.0] {
        let s = law.step(dt).unwrap();
        let (phi, qm) = crate::singer::model(dt, tau, q).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let rel = (s.phi[i][j] - phi[(i, j)]).abs() / phi[(i, j)].abs().max(1e-300);
                assert!(rel < 1e-13 || s.phi[i][j] == phi[(i, j)], "phi dt={dt}");
            }
        }
        // Iterate the Riccati recursion to convergence (independent route).
        let mut m = nalgebra::Matrix3::<f64>::identity() * 1e4;
        let r = sp * sp;
        let mut k = nalgebra::Vector3::zeros();
        for _ in 0..20_000 {
            let s0 = m[(0, 0)] + r;
            k = m.column(0) / s0;
            let p = m - k * m.row(0);
            m = phi * p * phi.transpose() + qm;
        }
        for i in 0..3 {
            let rel = (s.k[i][0] - k[i]).abs() / k[i].abs();
            assert!(rel < 1e-8, "dt={dt} i={i}: {} vs {}", s.k[i][0], k[i]);
        }
    }
    assert!(SingerDesign::new(0.0, 1.0, 1.0).is_err());
    assert!(SingerDesign::new(1.0, 1.0, -1.0).is_err());
}

#[test]
fn ab_backward_gain_is_the_rts_gain_of_the_riccati_solution() {
    // Independent route: iterate the Riccati recursion of the
    // white-acceleration model (Q = sigma_w^2 d d', d = [dt^2/2, dt],
    // R = sigma_v^2) to convergence, then A = P Phi' M^-1.
    let (sw, sv) = (0.7, 2.0);
    for &dt in &[0.05, 0.5, 3.0] {
        let phi = nalgebra::Matrix2::new(1.0, dt, 0.0, 1.0);
        let d = nalgebra::Vector2::new(dt * dt / 2.0, dt);
        let q = d * d.transpose() * (sw * sw);
        let r = sv * sv;
        let mut m = nalgebra::Matrix2::<f64>::identity() * 1e3;
        let mut p = m;
        for _ in 0..100_000 {
            let k = m.column(0) / (m[(0, 0)] + r);
            p = m - k * m.row(0);
            m = phi * p * phi.transpose() + q;
        }
        let a_ref = p * phi.transpose() * m.try_inverse().unwrap();
        let (phi_k, a) = AbBackward::Design(sw / sv).at(dt);
        assert_eq!(phi_k, [[1.0, dt], [0.0, 1.0]]);
        for i in 0..2 {
            for j in 0..2 {
                let rel = (a[i][j] - a_ref[(i, j)]).abs() / a_ref[(i, j)].abs().max(1e-12);
                assert!(
                    rel < 1e-9,
                    "dt={dt} A[{i}][{j}] = {} vs {}",
                    a[i][j],
                    a_ref[(i, j)]
                );
            }
        }
    }
}

#[test]
fn ab_backward_fixed_scales_with_dt() {
    let an = [[0.9, 0.3], [-0.2, 0.8]];
    let (_, a) = AbBackward::Fixed(an).at(2.0);
    assert_eq!(a, [[0.9, 0.6], [-0.1, 0.8]]);
}

/// Brute force: iterate the Riccati recursion of `(phi, q, r)` (position
/// measured) to convergence, then `A = P Phi' M^-1`.
fn brute_rts(
    phi: nalgebra::Matrix3<f64>,
    q: nalgebra::Matrix3<f64>,
    r: f64,
) -> nalgebra::Matrix3<f64> {
    let mut m = nalgebra::Matrix3::<f64>::identity() * 1e3;
    let mut p = m;
    for _ in 0..200_000 {
        let k = m.column(0) / (m[(0, 0)] + r);
        p = m - k * m.row(0);
        p = (p + p.transpose()) * 0.5;
        m = phi * p * phi.transpose() + q;
    }
    p * phi.transpose() * m.try_inverse().unwrap()
}

fn assert_close3(a: &[[f64; 3]; 3], b: &nalgebra::Matrix3<f64>, tol: f64, what: &str) {
    let scale = b.amax();
    for i in 0..3 {
        for j in 0..3 {
            let err = (a[i][j] - b[(i, j)]).abs();
            assert!(
                err <= tol * b[(i, j)].abs().max(1e-9 * scale),
                "{what}: A[{i}][{j}] = {} vs {}",
                a[i][j],
                b[(i, j)]
            );
        }
    }
}

#[test]
fn kin3_backward_abg_design_is_the_rts_gain_of_the_riccati_solution() {
    let noise = [0.3, 0.2, 0.1, 1.0];
    for &dt in &[0.3, 1.0, 2.5] {
        let phi = nalgebra::Matrix3::new(1.0, dt, 0.5 * dt * dt, 0.0, 1.0, dt, 0.0, 0.0, 1.0);
        let q = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(0.3, 0.2, 0.1));
        let a_ref = brute_rts(phi, q, 1.0);
        let (phi_k, a) = Kin3Backward::AbgDesign(noise).at(dt).unwrap();
        assert_eq!(phi_k, phi_ca(dt));
        assert_close3(&a, &a_ref, 1e-9, &format!("abg dt={dt}"));
    }
    // Only the acceleration driven (closed-form gains).
    let dt = 0.7;
    let phi = nalgebra::Matrix3::new(1.0, dt, 0.5 * dt * dt, 0.0, 1.0, dt, 0.0, 0.0, 1.0);
    let q = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(0.0, 0.0, 0.4));
    let (_, a) = Kin3Backward::AbgDesign([0.0, 0.0, 0.4, 2.0])
        .at(dt)
        .unwrap();
    assert_close3(&a, &brute_rts(phi, q, 2.0), 1e-9, "abg accel-only");
}

#[test]
fn kin3_backward_singer_is_the_rts_gain_of_the_riccati_solution() {
    let (tau, q, sp) = (20.0, 0.1, 10.0);
    for &dt in &[0.5, 1.0, 7.0] {
        let (phi, qm) = crate::singer::model(dt, tau, q).unwrap();
        let a_ref = brute_rts(phi, qm, sp * sp);
        let (phi_k, a) = Kin3Backward::Singer {
            tau,
            q,
            sigma_pos: sp,
        }
        .at(dt)
        .unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let rel = (phi_k[i][j] - phi[(i, j)]).abs() / phi[(i, j)].abs().max(1e-300);
                assert!(rel < 1e-13 || phi_k[i][j] == phi[(i, j)], "phi dt={dt}");
            }
        }
        assert_close3(&a, &a_ref, 1e-8, &format!("singer dt={dt}"));
    }
}

#[test]
fn kin3_backward_fixed_is_the_kalman_equivalent_gain_scaled_to_dt() {
    // Gains designed at h = 1; their Kalman-equivalent model (Corollary
    // noise ratios, h = 1 units) has A_N; at dt the physical gain is the
    // RTS gain of the model scaled so that the normalised model is the same.
    let [a, b, g] = crate::abg::from_noise(0.05, 0.02, 0.01, 1.0, 1.0).unwrap();
    let an = abg_backward_normalised(a, b, g).unwrap();
    let [qp, qv, qa] = crate::abg::noise_ratios(a, b, g, 1.0).unwrap();
    for &dt in &[1.0, 0.25, 4.0] {
        let phi = nalgebra::Matrix3::new(1.0, dt, 0.5 * dt * dt, 0.0, 1.0, dt, 0.0, 0.0, 1.0);
        // Physical noise of the same normalised model at dt.
        let q = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(
            qp,
            qv / (dt * dt),
            qa / dt.powi(4),
        ));
        let a_ref = brute_rts(phi, q, 1.0);
        let (_, a_dt) = Kin3Backward::Fixed(an).at(dt).unwrap();
        assert_close3(&a_dt, &a_ref, 1e-9, &format!("fixed dt={dt}"));
    }
}

#[test]
fn kin3_cache_returns_the_uncached_values() {
    let back = Kin3Backward::Singer {
        tau: 5.0,
        q: 0.3,
        sigma_pos: 2.0,
    };
    let mut c = Kin3Cache::default();
    for &dt in &[
        1.0, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 0.5, 1.0,
    ] {
        assert_eq!(c.get(&back, dt).unwrap(), back.at(dt).unwrap());
    }
    // A failing design is an error, not a cached value.
    assert!(c.get(&back, 1e-80).is_err());
    assert!(Kin3Backward::AbgDesign([0.0, 0.0, 0.1, 1.0])
        .at(1e-90)
        .is_err());
}

/// Max over rows of `max_j |a_ij - r_ij| / max_j |r_ij|`.
fn row_error(a: &[[f64; 3]; 3], r: &[[f64; 3]; 3]) -> f64 {
    (0..3)
        .map(|i| {
            let d = (0..3).fold(0.0_f64, |m, j| m.max((a[i][j] - r[i][j]).abs()));
            let s = (0..3).fold(0.0_f64, |m, j| m.max(r[i][j].abs()));
            d / s
        })
        .fold(0.0, f64::max)
}

/// 50-digit references (mpmath: doubling on the filter DARE with `h = 1`,
/// `Q = diag(q_p, q_v, q_a)`, `R = 1`, then `A = P Phi' M^-1`; the script of
/// `tests/test_abg_backward.py`), rounded to float64.
const BACKWARD_REF: [([f64; 3], [[f64; 3]; 3]); 6] = [
    (
        [1e12, 1e-4, 1e-16],
        [
            [
                9.99999999998e-13,
                -1.4037223132401918e-21,
                -9.90098800045732e-13,
            ],
            [
                9.999999985967777e-17,
                0.9999999985962825,
                -0.9900988702320926,
            ],
            [
                -4.900989404184583e-29,
                9.90098939715612e-15,
                0.9999998596292488,
            ],
        ],
    ),
    (
        [1.0, 0.0, 1e12],
        [
            [
                7.1553127296107e-06,
                -3.5776663645620708e-06,
                1.999957068251619e-12,
            ],
            [
                1.999978534017812,
                -0.9999892669729068,
                -7.999871204538861e-12,
            ],
            [
                -1.999978534017812,
                1.9999892669729067,
                7.999871204538861e-12,
            ],
        ],
    ),
    (
        [0.0, 1e12, 1e-16],
        [
            [2.999999999978e-12, -9.99999999994e-13, -4.99999999997e-13],
            [0.999999999997, 9.999999999939999e-13, -0.499999999999495],
            [4.9999999999849e-29, 5.00000000000495e-29, 0.99999999999999],
        ],
    ),
    (
        [0.0, 0.0, 1e-16],
        [
            [0.9999999950107605, -0.9999953683986105, 0.49785020023931037],
            [
                9.978478844386156e-09,
                0.999990736797221,
                -0.9957004004786207,
            ],
            [
                -9.978478844386156e-09,
                9.263202779105655e-06,
                0.9957004004786207,
            ],
        ],
    ),
    (
        [1e-4, 1e-12, 1e14],
        [
            [
                7.999890801727195e-07,
                -3.999946400861678e-07,
                1.9999967998849616e-14,
            ],
            [
                1.9999983999418407,
                -0.9999991999707203,
                -4.000393599451911e-14,
            ],
            [
                -1.9999983999418407,
                1.9999991999707203,
                4.000393599453911e-14,
            ],
        ],
    ),
    (
        [0.3, 0.2, 0.1],
        [
            [
                0.5582515271650439,
                -0.28129578837121116,
                -0.08447055382052304,
            ],
            [
                0.20694681175357532,
                0.4816517371989908,
                -0.27131596756928716,
            ],
            [
                -0.022668478556352067,
                0.15212310193611042,
                0.575562171441508,
            ],
        ],
    ),
];

#[test]
fn abg_backward_from_noise_matches_the_50_digit_rts_gain() {
    // 1 - alpha down to 4e-14 (the former float64 evaluation from the
    // rounded gains was off by ~eps / (1 - alpha) there) and slow poles.
    for (q, r) in BACKWARD_REF {
        let a = abg_backward_from_noise(q[0], q[1], q[2]).unwrap();
        let e = row_error(&a, &r);
        assert!(e <= 1e-13, "q={q:?}: row error {e:e}");
        // The design path at h = 1, sigma_m = 2 (the same normalised noise).
        let a2 = abg_backward_design(2.0 * q[0], 2.0 * q[1], 2.0 * q[2], 2.0, 1.0).unwrap();
        assert!(row_error(&a2, &r) <= 1e-13, "design q={q:?}");
    }
}

#[test]
fn abg_backward_normalised_of_exact_gains_agrees_with_the_noise_path() {
    // Where 1 - alpha is large and q_p, q_v are well inside the domain the
    // rounding of the gains does not matter: the gains' Kalman-equivalent
    // model is the noise model to ~eps (at q_p = 0 or q_v = 0 the rounded
    // gains' model has q_p, q_v of the size of the rounding, which moves
    // small gains' A_N by more: tests/test_abg_backward.py compares fixed
    // gains with the 50-digit gain of their own model).
    for q in [
        [0.3, 0.2, 0.1],
        [1e-2, 1e2, 1.0],
        [1.0, 0.5, 1e-8],
        [1e-4, 1e-2, 1e4],
    ] {
        let [a, b, g] = crate::abg::from_noise(q[0], q[1], q[2], 1.0, 1.0).unwrap();
        let x = abg_backward_normalised(a, b, g).unwrap();
        let y = abg_backward_from_noise(q[0], q[1], q[2]).unwrap();
        let e = row_error(&x, &y);
        assert!(e <= 1e-13, "q={q:?}: {e:e}");
    }
    // No steady-state covariance: an error, not a NaN gain.
    assert!(abg_backward_normalised(0.5, 0.01, 0.5).is_err());
    assert!(abg_backward_normalised(f64::NAN, 0.01, 0.5).is_err());
    assert!(abg_backward_from_noise(1.0, 1.0, 0.0).is_err());
    assert!(abg_backward_from_noise(-1.0, 1.0, 1.0).is_err());
    assert!(abg_backward_design(1.0, 1.0, 1.0, 0.0, 1.0).is_err());
}

#[test]
fn abg_backward_doubling_fallback_matches_the_50_digit_rts_gain() {
    for (q, r) in BACKWARD_REF {
        let a = backward_by_doubling(q).unwrap();
        let e = row_error(&a, &r);
        assert!(e <= 1e-13, "q={q:?}: row error {e:e}");
    }
}
