//! The layout of the estimate buffers: `n` component planes (position,
//! velocity, ...) of `per` elements each (`n_tracks * n_samples`, or the
//! ragged batch's flat samples), every plane contiguous, one after another
//! at a fixed plane stride.
//!
//! Two plane strides are accepted, told apart by the buffer's length alone
//! (so a wrong-sized buffer is still an error):
//! - `per` (the planes back to back, a C-contiguous `(n, ...)` array), and
//! - [`padded`]`::<T>(per)`: `per` rounded up to a whole 64-byte line, so
//!   that every plane starts at the same phase of a cache line as the first
//!   one. The kernels stream the position plane from its own line boundary;
//!   the other planes share those line boundaries only in this layout, or
//!   when `per` is a multiple of a line. Off them, the other planes take
//!   ordinary stores and whole batches run 25-120 % slower
//!   (docs/benchmarks.md, session 35, `bench/bench_layout.py`), which is why
//!   abkit's own fresh outputs use this layout.
//!
//! The buffer of the padded layout ends with the last plane: its length is
//! `(n - 1) * padded(per) + per`. The padding between planes is never read
//! or written.

/// Bytes of a cache line (the planes' alignment unit).
pub const LINE_BYTES: usize = 64;

/// `per` rounded up to a whole number of 64-byte lines of `T` (the plane
/// stride of the padded layout); `None` on overflow.
pub fn padded<T>(per: usize) -> Option<usize> {
    let line = (LINE_BYTES / std::mem::size_of::<T>()).max(1);
    per.checked_next_multiple_of(line)
}

/// The plane stride of a buffer of `len` elements holding `n` planes of
/// `per` elements: `per` or [`padded`]`(per)` (see the module docs);
/// `None` when `len` fits neither layout.
pub fn stride<T>(len: usize, n: usize, per: usize) -> Option<usize> {
    if n == 0 {
        return (len == 0).then_some(per);
    }
    if n.checked_mul(per) == Some(len) {
        return Some(per);
    }
    let pad = padded::<T>(per)?;
    let want = (n - 1).checked_mul(pad)?.checked_add(per)?;
    (want == len).then_some(pad)
}

/// The `n` planes of `out` (each `per` elements long), in order; `None`
/// when `out` fits neither layout (see [`stride`]).
pub fn split<T>(out: &mut [T], n: usize, per: usize) -> Option<Vec<&mut [T]>> {
    let s = stride::<T>(out.len(), n, per)?;
    let mut planes = Vec::with_capacity(n);
    let mut rest = out;
    for c in 0..n {
        let take = if c + 1 == n {
            rest.len()
        } else {
            s.min(rest.len())
        };
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(take);
        planes.push(head.get_mut(..per)?);
        rest = tail;
    }
    Some(planes)
}

/// The first two planes of `out` (see [`split`]); `None` when `out` fits
/// neither layout of `n` planes.
pub fn split2<T>(out: &mut [T], n: usize, per: usize) -> Option<(&mut [T], &mut [T])> {
    let s = stride::<T>(out.len(), n, per)?;
    if n < 2 {
        return None;
    }
    let (a, b) = out.split_at_mut(s);
    Some((a.get_mut(..per)?, b.get_mut(..per)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strides_of_both_layouts() {
        // f64: 8 per line; f32: 16.
        assert_eq!(padded::<f64>(13), Some(16));
        assert_eq!(padded::<f32>(13), Some(16));
        assert_eq!(padded::<f32>(17), Some(32));
        assert_eq!(padded::<f64>(16), Some(16));
        assert_eq!(padded::<f64>(0), Some(0));
        assert_eq!(stride::<f64>(3 * 13, 3, 13), Some(13));
        assert_eq!(stride::<f64>(2 * 16 + 13, 3, 13), Some(16));
        assert_eq!(stride::<f64>(3 * 16, 3, 13), None);
        assert_eq!(stride::<f64>(3 * 13 + 1, 3, 13), None);
        assert_eq!(stride::<f64>(13, 1, 13), Some(13));
        assert_eq!(stride::<f64>(0, 2, 0), Some(0));
        assert_eq!(stride::<f64>(0, 0, 5), Some(5));
        assert_eq!(stride::<f64>(1, 0, 5), None);
        assert_eq!(stride::<f64>(usize::MAX, 3, usize::MAX / 2), None);
    }

    #[test]
    fn planes_of_the_padded_layout() {
        let mut buf: Vec<f64> = (0..(2 * 16 + 13)).map(f64::from).collect();
        let p = split(&mut buf, 3, 13).unwrap();
        assert_eq!(p.len(), 3);
        assert!(p.iter().all(|q| q.len() == 13));
        assert_eq!(
            (p[0][0], p[1][0], p[2][0], p[2][12]),
            (0.0, 16.0, 32.0, 44.0)
        );
        let (x, v) = split2(&mut buf, 3, 13).unwrap();
        assert_eq!((x[12], v[0], v.len()), (12.0, 16.0, 13));
        let mut flat: Vec<f64> = (0..26).map(f64::from).collect();
        let p = split(&mut flat, 2, 13).unwrap();
        assert_eq!((p[0][12], p[1][0]), (12.0, 13.0));
        assert!(split(&mut flat, 2, 12).is_none());
        assert!(split2(&mut flat[..13], 1, 13).is_none());
    }
}
