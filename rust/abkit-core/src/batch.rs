//! Element-wise evaluation of scalar solvers over arrays.
//!
//! The design functions are cheap (tens of nanoseconds), so small batches run
//! serially; large ones are split into chunks on rayon's global pool (never a
//! pool per call). The result of element `i` never depends on the chunking,
//! so output is bit-identical for any thread count.

use crate::{Error, Result};
use rayon::prelude::*;

/// Below this many elements a batch runs on the calling thread.
pub const PARALLEL_THRESHOLD: usize = 16_384;
const CHUNK: usize = 4_096;

/// Apply `f` to each element of `inputs` (all slices of equal length) and
/// write its `width` outputs to `out[i * width..(i + 1) * width]`.
///
/// Returns the first error in index order, tagged with the element index.
pub fn map_rows<const NIN: usize, F>(
    inputs: [&[f64]; NIN],
    width: usize,
    out: &mut [f64],
    f: F,
) -> std::result::Result<(), (usize, Error)>
where
    F: Fn([f64; NIN], &mut [f64]) -> Result<()> + Sync,
{
    let n = inputs.first().map_or(0, |s| s.len());
    if inputs.iter().any(|s| s.len() != n) || out.len() != n * width {
        return Err((
            0,
            Error::Shape(format!(
                "inputs of lengths {:?} and output of length {} (width {width})",
                inputs.iter().map(|s| s.len()).collect::<Vec<_>>(),
                out.len()
            )),
        ));
    }
    if width == 0 {
        return Ok(());
    }
    let run_chunk = |start: usize, chunk: &mut [f64]| -> std::result::Result<(), (usize, Error)> {
        for (j, row) in chunk.chunks_exact_mut(width).enumerate() {
            let i = start + j;
            let args: [f64; NIN] = std::array::from_fn(|k| inputs[k][i]);
            f(args, row).map_err(|e| (i, e))?;
        }
        Ok(())
    };
    if n < PARALLEL_THRESHOLD {
        run_chunk(0, out)
    } else {
        let results: Vec<std::result::Result<(), (usize, Error)>> = out
            .par_chunks_mut(CHUNK * width)
            .enumerate()
            .map(|(c, chunk)| run_chunk(c * CHUNK, chunk))
            .collect();
        results.into_iter().collect()
    }
}

/// Bytes per page touched by [`touch_pages`].
pub const PAGE: usize = 4096;

/// Write one zero byte per [`PAGE`] of `buf` (a fresh allocation whose pages
/// may not be mapped yet), so that the pages are faulted in before a kernel
/// streams its outputs into them; in parallel on rayon's pool (chunks of
/// 2 MiB) if `parallel`. The bytes written were zero already or are
/// overwritten by the kernel (the callers' outputs).
pub fn touch_pages(buf: &mut [u8], parallel: bool) {
    let touch = |c: &mut [u8]| {
        for b in c.iter_mut().step_by(PAGE) {
            // A volatile write: the touch must happen even if the byte is
            // never read before the kernel writes it.
            // SAFETY: `b` is a valid, exclusive reference to one byte.
            unsafe { std::ptr::write_volatile(b, 0) };
        }
    };
    const CHUNK: usize = 2 << 20;
    if parallel && buf.len() > CHUNK {
        buf.par_chunks_mut(CHUNK).for_each(touch);
    } else {
        touch(buf);
    }
}

#[cfg(test)]
#[path = "tests/batch.rs"]
mod tests;
