//! Shared by the examples: large buffers on transparent huge pages, as
//! NumPy allocates them (`madvise(MADV_HUGEPAGE)` for arrays of 4 MiB and
//! more). Without them the examples measure 4 KiB-page TLB misses that a
//! call from Python does not have (on an AMD EPYC, 10^7-sample batches
//! 1.3-1.6 ns per sample instead of 0.9-1.0).

/// A vector of `n` values `f(i)` whose pages are advised as huge before
/// they are first touched (Linux; elsewhere an ordinary vector).
pub fn thp_vec<T>(n: usize, f: impl FnMut(usize) -> T) -> Vec<T> {
    let mut v = thp_capacity(n);
    v.extend((0..n).map(f));
    v
}

/// An empty vector with room for `n` values on huge pages (see
/// [`thp_vec`]).
pub fn thp_capacity<T>(n: usize) -> Vec<T> {
    let mut v: Vec<T> = Vec::with_capacity(n);
    #[cfg(target_os = "linux")]
    {
        extern "C" {
            fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
        }
        const HUGE: usize = 2 << 20;
        const MADV_HUGEPAGE: i32 = 14;
        let a = v.as_mut_ptr() as usize;
        let e = a + n * std::mem::size_of::<T>();
        let (a2, e2) = (a.next_multiple_of(HUGE), e - e % HUGE);
        if e2 > a2 {
            // SAFETY: [a2, e2) lies inside the vector's allocation; the
            // advice changes only how the kernel backs the pages (the call
            // may fail, which is harmless).
            unsafe { madvise(a2 as *mut std::ffi::c_void, e2 - a2, MADV_HUGEPAGE) };
        }
    }
    v
}
