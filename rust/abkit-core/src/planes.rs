//! The layout of the estimate buffers: `n` component planes (position,
//! velocity, ...) of `per` elements each (`n_tracks * n_samples`, or the
//! ragged batch's flat samples), every plane contiguous, one after another
//! at a fixed plane stride.
//!
//! Two plane strides are accepted, told apart by the buffer's length alone
//! (so a wrong-sized buffer is still an error):
//! - `per` (the planes back to back, a C-contiguous `(n, ...)` array), and
//! - [`padded_stride`]`::<T>(n, per, row)`: `per` rounded up to whole
//!   64-byte lines, so that every plane starts at the same phase of a cache
//!   line as the first one, and then by as many more lines (fewer than a
//!   page) as it takes to keep the planes' concurrently written rows apart
//!   modulo 4 KiB; for buffers under 8 MiB (not streamed) `per` itself.
//!   The kernels stream the position plane from its own line boundary;
//!   the other planes share those line boundaries only in this layout, or
//!   when `per` is a multiple of a line. Off them, the other
//!   planes take ordinary stores and whole batches ran 25-120 % slower
//!   (docs/benchmarks.md, session 35, `bench/bench_layout.py`); on line
//!   boundaries but with a plane `c * stride + j * row` elements (rows `j`
//!   in flight at once) within 32 bytes of another modulo 4 KiB, 1.1-2.2x
//!   slower (session 36). abkit's own fresh outputs use this layout.
//!
//! The buffer of the padded layout ends with the last plane: its length is
//! `(n - 1) * stride + per`. The padding between planes is never read or
//! written.

/// Bytes of a cache line (the planes' alignment unit).
pub const LINE_BYTES: usize = 64;

/// The period of the address bits that make two streams collide (most
/// likely 4 KiB aliasing or cache-set conflicts: measured, not diagnosed).
const PAGE_BYTES: usize = 4096;

/// Rows of one plane a kernel writes at once (its lanes) that the padded
/// layout keeps apart from the other planes' rows.
const ROW_STREAMS: usize = 4;

/// The separation (bytes, modulo [`PAGE_BYTES`]) the padded layout keeps
/// between any two planes' rows in flight: every measured stride with 64
/// or more ran fast, most with 32 or less 1.1-2.2x slower (session 36;
/// one at 32 and one at 24 did not).
const MIN_SEPARATION: usize = 64;

/// Buffers (all planes) smaller than this (bytes) keep the planes back to
/// back: the kernels stream no output below it (`filter::NT_MIN_BYTES`),
/// so their planes' line phases do not matter, and the collisions were
/// measured only on streamed outputs.
pub const PAD_MIN_BYTES: usize = crate::filter::NT_MIN_BYTES;

/// `per` rounded up to a whole number of 64-byte lines of `T`; `None` on
/// overflow.
pub fn padded<T>(per: usize) -> Option<usize> {
    let line = (LINE_BYTES / std::mem::size_of::<T>()).max(1);
    per.checked_next_multiple_of(line)
}

/// The smallest circular distance (modulo [`PAGE_BYTES`]) between the
/// start of a row of one plane and a row of another, over planes `c` apart
/// (`0 < c < n`) and rows up to `rows - 1` apart, for plane and row
/// strides `d` and `r` bytes (both reduced modulo the page).
fn separation(d: usize, r: usize, n: usize, rows: usize) -> usize {
    let mut best = PAGE_BYTES;
    for c in 1..n {
        let pd = c * d % PAGE_BYTES;
        for j in 0..rows {
            let rj = j * r % PAGE_BYTES;
            for off in [(pd + rj) % PAGE_BYTES, (pd + PAGE_BYTES - rj) % PAGE_BYTES] {
                best = best.min(off.min(PAGE_BYTES - off));
            }
        }
    }
    best
}

/// The plane stride of the padded layout (see the module docs) for `n`
/// planes of `per` elements of `T` made of rows of `row` elements (`0`: one
/// flat sequence, as the ragged batches): the first whole number of lines
/// from [`padded`]`(per)` on whose planes' rows in flight (up to
/// `ROW_STREAMS` rows each) are at least `MIN_SEPARATION` bytes apart
/// modulo 4 KiB, or the best separated within a page of padding; `per`
/// itself (the planes back to back) for buffers under `PAD_MIN_BYTES`
/// (8 MiB) or a single plane. `None` on overflow.
pub fn padded_stride<T>(n: usize, per: usize, row: usize) -> Option<usize> {
    let size = std::mem::size_of::<T>().max(1);
    let line = (LINE_BYTES / size).max(1);
    if n < 2 || n.saturating_mul(per).saturating_mul(size) < PAD_MIN_BYTES {
        return Some(per);
    }
    let base = padded::<T>(per)?;
    let rows = per.checked_div(row).map_or(1, |r| r.clamp(1, ROW_STREAMS));
    let r = (row % PAGE_BYTES) * size % PAGE_BYTES;
    let mut best = (0, base);
    for k in 0..PAGE_BYTES / LINE_BYTES {
        let s = base.checked_add(k * line)?;
        let d = (s % PAGE_BYTES) * size % PAGE_BYTES;
        let sep = separation(d, r, n, rows);
        if sep >= MIN_SEPARATION {
            return Some(s);
        }
        if sep > best.0 {
            best = (sep, s);
        }
    }
    Some(best.1)
}

/// The plane stride of a buffer of `len` elements holding `n` planes of
/// `per` elements in rows of `row` (`0`: flat): `per` or
/// [`padded_stride`]`(n, per, row)` (see the module docs); `None` when
/// `len` fits neither layout.
pub fn stride<T>(len: usize, n: usize, per: usize, row: usize) -> Option<usize> {
    if n == 0 {
        return (len == 0).then_some(per);
    }
    if n.checked_mul(per) == Some(len) {
        return Some(per);
    }
    let pad = padded_stride::<T>(n, per, row)?;
    let want = (n - 1).checked_mul(pad)?.checked_add(per)?;
    (want == len).then_some(pad)
}

/// The `n` planes of `out` (each `per` elements long, in rows of `row`), in
/// order; `None` when `out` fits neither layout (see [`stride`]).
pub fn split<T>(out: &mut [T], n: usize, per: usize, row: usize) -> Option<Vec<&mut [T]>> {
    let s = stride::<T>(out.len(), n, per, row)?;
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
pub fn split2<T>(out: &mut [T], n: usize, per: usize, row: usize) -> Option<(&mut [T], &mut [T])> {
    let s = stride::<T>(out.len(), n, per, row)?;
    if n < 2 {
        return None;
    }
    let (a, b) = out.split_at_mut(s);
    Some((a.get_mut(..per)?, b.get_mut(..per)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The separation by brute force over every pair of rows in flight.
    fn brute(d: usize, r: usize, n: usize, rows: usize) -> usize {
        let mut best = PAGE_BYTES;
        for c1 in 0..n {
            for c2 in c1 + 1..n {
                for j1 in 0..rows {
                    for j2 in 0..rows {
                        let a = (c1 * d + j1 * r) % PAGE_BYTES;
                        let b = (c2 * d + j2 * r) % PAGE_BYTES;
                        let x = (a + PAGE_BYTES - b) % PAGE_BYTES;
                        best = best.min(x.min(PAGE_BYTES - x));
                    }
                }
            }
        }
        best
    }

    #[test]
    fn separation_matches_brute_force() {
        for d in (0..PAGE_BYTES).step_by(64) {
            for r in [0, 8, 808, 2176, 2208, 4000, 4088] {
                for n in 2..=6 {
                    for rows in 1..=4 {
                        assert_eq!(
                            separation(d, r, n, rows),
                            brute(d, r, n, rows),
                            "{d} {r} {n} {rows}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn padded_strides_avoid_the_measured_collisions() {
        // Session 36 (AMD EPYC, AVX2): 999 x 10,004 float64 planes 2,176 and
        // 2,240 bytes (mod 4 KiB) apart ran 1.4-2.2x slower than 2,304;
        // 1,000 x 10,000 three planes 1,088 / 1,216 / 1,664 apart 1.1-1.5x
        // slower than 1,024 (per itself, a whole number of lines); 99,999 x
        // 101 three planes 1,600 / 1,664 / 2,048 apart 1.2-1.9x slower
        // than 1,536.
        let at = |n: usize, nt: usize, ns: usize| {
            padded_stride::<f64>(n, nt * ns, ns).unwrap() * 8 % PAGE_BYTES
        };
        assert_eq!(at(2, 999, 10_004), 2304);
        assert_eq!(at(3, 999, 10_004), 2304);
        assert_eq!(at(2, 1000, 10_000), 1024);
        assert_eq!(at(3, 1000, 10_000), 1024);
        assert_eq!(at(3, 99_999, 101), 1536);
        for (n, nt, ns) in [
            (2, 999, 10_004),
            (3, 1000, 10_000),
            (3, 99_999, 101),
            (6, 70_000, 13),
            (3, 1, 1 << 20),
        ] {
            let s = padded_stride::<f64>(n, nt * ns, ns).unwrap();
            assert!(s >= nt * ns && s.is_multiple_of(8) && s - nt * ns < 8 + 512);
            let rows = (nt).clamp(1, ROW_STREAMS);
            assert!(separation(s * 8 % PAGE_BYTES, ns * 8 % PAGE_BYTES, n, rows) >= MIN_SEPARATION);
        }
        // Flat (ragged) planes: whole lines, not a multiple of the page apart.
        assert_eq!(
            padded_stride::<f32>(2, (1 << 20) + 13, 0),
            Some((1 << 20) + 16)
        );
        assert_eq!(padded_stride::<f64>(2, 1 << 20, 0), Some((1 << 20) + 8));
        // Buffers under 8 MiB and single planes: back to back.
        assert_eq!(
            padded_stride::<f64>(1, (1 << 20) + 13, 5),
            Some((1 << 20) + 13)
        );
        assert_eq!(padded_stride::<f64>(2, 15, 5), Some(15));
        assert_eq!(
            padded_stride::<f64>(2, (1 << 19) - 1, 0),
            Some((1 << 19) - 1)
        );
        assert_eq!(
            padded_stride::<f64>(2, 1 << 19, 1 << 19),
            Some((1 << 19) + 8)
        );
        assert_eq!(padded_stride::<f32>(3, 699_049, 1), Some(699_049));
    }

    #[test]
    fn strides_of_both_layouts() {
        // f64: 8 per line; f32: 16.
        assert_eq!(padded::<f64>(13), Some(16));
        assert_eq!(padded::<f32>(13), Some(16));
        assert_eq!(padded::<f32>(17), Some(32));
        assert_eq!(padded::<f64>(16), Some(16));
        assert_eq!(padded::<f64>(0), Some(0));
        let per = (1 << 20) + 13;
        let p = padded_stride::<f64>(3, per, per).unwrap();
        assert!(p > per && p.is_multiple_of(8));
        assert_eq!(stride::<f64>(3 * per, 3, per, per), Some(per));
        assert_eq!(stride::<f64>(2 * p + per, 3, per, per), Some(p));
        assert_eq!(stride::<f64>(3 * p, 3, per, per), None);
        assert_eq!(stride::<f64>(2 * (p + 8) + per, 3, per, per), None);
        assert_eq!(stride::<f64>(3 * per + 1, 3, per, per), None);
        assert_eq!(stride::<f64>(per, 1, per, per), Some(per));
        assert_eq!(stride::<f64>(3 * 13, 3, 13, 13), Some(13));
        assert_eq!(stride::<f64>(2 * 16 + 13, 3, 13, 13), None);
        assert_eq!(stride::<f64>(0, 2, 0, 0), Some(0));
        assert_eq!(stride::<f64>(0, 0, 5, 5), Some(5));
        assert_eq!(stride::<f64>(1, 0, 5, 5), None);
        assert_eq!(stride::<f64>(usize::MAX, 3, usize::MAX / 2, 1), None);
    }

    #[test]
    fn planes_of_the_padded_layout() {
        let per = (1 << 20) + 13;
        let p = padded_stride::<f64>(3, per, 0).unwrap();
        let mut buf: Vec<f64> = (0..(2 * p + per)).map(|i| i as f64).collect();
        let planes = split(&mut buf, 3, per, 0).unwrap();
        assert_eq!(planes.len(), 3);
        assert!(planes.iter().all(|q| q.len() == per));
        let at = |c: usize| (c * p) as f64;
        assert_eq!(
            (planes[0][0], planes[1][0], planes[2][0], planes[2][per - 1]),
            (at(0), at(1), at(2), at(2) + (per - 1) as f64)
        );
        let (x, v) = split2(&mut buf, 3, per, 0).unwrap();
        assert_eq!((x[per - 1], v[0], v.len()), ((per - 1) as f64, at(1), per));
        let mut flat: Vec<f64> = (0..26).map(f64::from).collect();
        let q = split(&mut flat, 2, 13, 0).unwrap();
        assert_eq!((q[0][12], q[1][0]), (12.0, 13.0));
        assert!(split(&mut flat, 2, 12, 0).is_none());
        assert!(split2(&mut flat[..13], 1, 13, 0).is_none());
    }
}
