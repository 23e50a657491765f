//! Unit tests of `riccati` (a child module of it, so private items are in reach).

use super::*;

fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(r, c, v)
}

#[test]
fn scalar_dare_matches_closed_form() {
    // a=2, b=1, q=1, r=1: x^2 - 4x - 1 = 0 -> x = 2 + sqrt(5).
    let d = solve_dare(
        &m(1, 1, &[2.0]),
        &m(1, 1, &[1.0]),
        &m(1, 1, &[1.0]),
        &m(1, 1, &[1.0]),
        None,
    )
    .unwrap();
    assert!((d.x[(0, 0)] - (2.0 + 5f64.sqrt())).abs() < 1e-13);
    assert!(d.rho < 1.0);
}

#[test]
fn singular_r_benchmark_darex3() {
    let a = m(2, 2, &[2.0, -1.0, 1.0, 0.0]);
    let b = m(2, 1, &[1.0, 0.0]);
    let q = m(2, 2, &[0.0, 0.0, 0.0, 1.0]);
    let r = m(1, 1, &[0.0]);
    let d = solve_dare(&a, &b, &q, &r, None).unwrap();
    assert!(d.residual < 1e-14, "{d:?}");
}

#[test]
fn unweighted_unit_circle_mode_is_no_solution() {
    let e = solve_dare(
        &m(1, 1, &[1.0]),
        &m(1, 1, &[1.0]),
        &m(1, 1, &[0.0]),
        &m(1, 1, &[1.0]),
        None,
    );
    assert!(matches!(e, Err(Error::NoSolution(_))), "{e:?}");
    let rot = m(2, 2, &[0.6, -0.8, 0.8, 0.6]);
    let e = solve_dare(
        &rot,
        &m(2, 1, &[1.0, 0.0]),
        &DMatrix::zeros(2, 2),
        &m(1, 1, &[1.0]),
        None,
    );
    assert!(matches!(e, Err(Error::NoSolution(_))), "{e:?}");
    // Unstable and not stabilisable.
    let e = solve_dare(
        &m(1, 1, &[2.0]),
        &m(1, 1, &[0.0]),
        &m(1, 1, &[1.0]),
        &m(1, 1, &[1.0]),
        None,
    );
    assert!(matches!(e, Err(Error::NoSolution(_))), "{e:?}");
}

#[test]
fn bad_input() {
    let one = m(1, 1, &[1.0]);
    let e = solve_dare(&m(1, 1, &[f64::NAN]), &one, &one, &one, None);
    assert!(matches!(e, Err(Error::Domain { name: "A", .. })));
    let e = solve_dare(&one, &one, &m(2, 2, &[1.0, 0.5, 0.0, 1.0]), &one, None);
    assert!(matches!(e, Err(Error::Shape(_))));
    let e = solve_dare(
        &m(2, 2, &[1.0; 4]),
        &m(2, 1, &[1.0; 2]),
        &m(2, 2, &[1.0, 0.5, 0.0, 1.0]),
        &one,
        None,
    );
    assert!(matches!(e, Err(Error::Domain { name: "Q", .. })));
    let e = solve_dare(&DMatrix::zeros(0, 0), &one, &one, &one, None);
    assert!(matches!(e, Err(Error::Shape(_))));
}

#[test]
fn kalman_constant_velocity() {
    let f = m(2, 2, &[1.0, 1.0, 0.0, 1.0]);
    let h = m(1, 2, &[1.0, 0.0]);
    let q = m(2, 2, &[0.25, 0.5, 0.5, 1.0]);
    let r = m(1, 1, &[1.0]);
    let k = kalman_steady_state(&f, &h, &q, &r).unwrap();
    // Riccati iteration to convergence.
    let mut p = DMatrix::<f64>::identity(2, 2);
    for _ in 0..10_000 {
        let s = (&h * &p * h.transpose())[(0, 0)] + 1.0;
        let pf = &p - &p * h.transpose() * &h * &p / s;
        p = &f * pf * f.transpose() + &q;
    }
    assert!((&k.p_pred - &p).amax() < 1e-12 * p.amax());
    assert!(k.rho < 1.0);
}
