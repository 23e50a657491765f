use super::*;
use crate::alphabeta::AlphaBeta;

#[test]
fn ab_design_matches_the_alphabeta_design_at_each_dt() {
    let (sw, sv) = (3.2, 32.0);
    let mut law = AbDesign { ratio: sw / sv };
    for &dt in &[1e-6, 0.01, 0.1, 0.7, 1.0, 3.3, 100.0, 1e4] {
        let d = AlphaBeta::from_noise(sw, sv, dt).unwrap();
        let s = law.step(dt).unwrap();
        assert_eq!(s.k[0][0], d.alpha, "dt={dt}");
        assert_eq!(s.k[1][0], d.beta / dt, "dt={dt}");
        assert_eq!(s.phi, [[1.0, dt], [0.0, 1.0]]);
    }
}

#[test]
fn ab_design_limits_are_finite() {
    let law = AbDesign { ratio: 1.0 };
    assert_eq!(law.gains(1e-200), (0.0, 0.0));
    let (a, b) = law.gains(1e200);
    assert_eq!((a, b), (1.0, 2.0));
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
