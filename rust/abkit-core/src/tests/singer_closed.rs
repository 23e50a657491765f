//! Unit tests of `singer_closed` (a child module of it, so private items are in reach).

use super::*;
use crate::singer::steady_state_numeric;

#[test]
fn closed_form_matches_numeric_on_easy_cases() {
    for &(theta, qn, rv) in &[
        (0.1, 0.2, f64::INFINITY),
        (1.0, 1.0, 0.5),
        (0.5, 1e-2, 2.0),
        (0.0, 1.0, f64::INFINITY),
    ] {
        let c = steady_state_closed(theta, qn, rv).unwrap();
        let n = steady_state_numeric(theta, qn, rv).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let d = (n.p_pred[(i, i)] * n.p_pred[(j, j)]).sqrt();
                assert!((c.p_pred[(i, j)] - n.p_pred[(i, j)]).abs() < 1e-10 * d);
            }
        }
    }
}

#[test]
fn cubic_roots_are_roots() {
    for &(al, be, ga) in &[(6.0, 11.0, 6.0), (1.0, 1.0, 1.0), (7.5, 20.0, 21.0)] {
        for x in cubic_roots(al, be, ga) {
            let p = ((x - al) * x + be) * x - ga;
            assert!(p.norm() < 1e-12 * (1.0 + al.abs() + be.abs() + ga.abs()));
        }
    }
}
