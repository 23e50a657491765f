//! Unit tests of `batch` (a child module of it, so private items are in reach).

use super::*;

#[test]
fn parallel_and_serial_agree_and_first_error_wins() {
    let n = PARALLEL_THRESHOLD * 3 + 17;
    let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let mut out = vec![0.0; 2 * n];
    map_rows([&x], 2, &mut out, |[a], o| {
        o[0] = a * 2.0;
        o[1] = a + 1.0;
        Ok(())
    })
    .unwrap();
    for i in 0..n {
        assert_eq!(out[2 * i], 2.0 * i as f64);
        assert_eq!(out[2 * i + 1], i as f64 + 1.0);
    }
    let err = map_rows([&x], 1, &mut out[..n], |[a], o| {
        if a >= 20_000.0 {
            Err(Error::domain("x", "small", a))
        } else {
            o[0] = a;
            Ok(())
        }
    })
    .unwrap_err();
    assert_eq!(err.0, 20_000);
}

#[test]
fn length_mismatch_is_an_error() {
    let a = [1.0, 2.0];
    let b = [1.0];
    let mut out = [0.0; 2];
    assert!(map_rows([&a[..], &b[..]], 1, &mut out, |_, _| Ok(())).is_err());
}

#[test]
fn touch_pages_writes_one_zero_per_page() {
    for parallel in [false, true] {
        for len in [0usize, 1, 4095, 4096, 4097, (5 << 20) + 123] {
            let mut buf = vec![7u8; len];
            touch_pages(&mut buf, parallel);
            for (i, &b) in buf.iter().enumerate() {
                let want = if i % PAGE == 0 { 0 } else { 7 };
                assert_eq!(b, want, "byte {i} of {len} (parallel {parallel})");
            }
        }
    }
}
