/* Plain C reference kernels for bench/run.py (compiled there with
 * gcc -O3 -march=native -shared -fPIC, loaded with ctypes).
 *
 * The alpha-beta filter with the two-point start, on C-contiguous
 * (n_tracks, n_samples) measurements without NaN:
 *   k = 0:  x = z0, v = NaN
 *   k = 1:  x = z1, v = (z1 - z0) / T
 *   k >= 2: xp = x + T v; e = z - xp; x = xp + alpha e; v = v + (beta/T) e
 * Arithmetic in double for both I/O precisions (as abkit does).
 *
 * ab_*       : the straightforward loop, one track after the other (the
 *              "plain C -O3" entry of the benchmark).
 * ab_*_x8    : diagnostic only: 8 tracks interleaved in one loop, to show
 *              how much of the per-track dependency chain interleaving
 *              recovers (not part of the comparison tables' targets).
 * copy2_* / copy3_* : the bandwidth ceiling: read z once, write the same
 *              output bytes as the filter (2 or 3 estimate arrays).
 * copy2seg_* / copy3seg_* : the same with 8 segments of z interleaved, one 64-byte line
 *              of each per step (more concurrent streams for the prefetchers,
 *              as a kernel interleaving 8 tracks has).
 * copy2nt_* / copy3nt_* : the same with non-temporal (streaming) stores,
 *              which skip the read-for-ownership of the output lines.
 * copy2ntx_* : as copy2nt_*, but each output streamed from its own first
 *              64-byte boundary (z read at the matching offsets), so it
 *              streams whole lines whatever the outputs' mutual alignment
 *              (bench_layout.py).
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <immintrin.h>

#define DEFINE_AB(NAME, TYPE)                                                  \
    void NAME(const TYPE *restrict z, TYPE *restrict pos, TYPE *restrict vel,  \
              ptrdiff_t nt, ptrdiff_t ns, double alpha, double beta,           \
              double t) {                                                      \
        const double g = beta / t;                                             \
        for (ptrdiff_t i = 0; i < nt; i++) {                                   \
            const TYPE *zi = z + i * ns;                                       \
            TYPE *xo = pos + i * ns, *vo = vel + i * ns;                       \
            if (ns < 1) continue;                                              \
            xo[0] = zi[0];                                                     \
            vo[0] = (TYPE)NAN;                                                 \
            if (ns < 2) continue;                                              \
            double x = zi[1], v = ((double)zi[1] - (double)zi[0]) / t;         \
            xo[1] = (TYPE)x;                                                   \
            vo[1] = (TYPE)v;                                                   \
            for (ptrdiff_t k = 2; k < ns; k++) {                               \
                double xp = x + t * v;                                         \
                double e = (double)zi[k] - xp;                                 \
                x = xp + alpha * e;                                            \
                v = v + g * e;                                                 \
                xo[k] = (TYPE)x;                                               \
                vo[k] = (TYPE)v;                                               \
            }                                                                  \
        }                                                                      \
    }

DEFINE_AB(ab_f64, double)
DEFINE_AB(ab_f32, float)

/* 8 tracks per loop: 8 independent dependency chains in flight. */
#define L 8
#define DEFINE_AB_X8(NAME, TYPE, SCALAR)                                       \
    void NAME(const TYPE *restrict z, TYPE *restrict pos, TYPE *restrict vel,  \
              ptrdiff_t nt, ptrdiff_t ns, double alpha, double beta,           \
              double t) {                                                      \
        const double g = beta / t;                                             \
        ptrdiff_t i0 = 0;                                                      \
        if (ns >= 2) {                                                         \
            for (; i0 + L <= nt; i0 += L) {                                    \
                double x[L], v[L];                                             \
                for (int j = 0; j < L; j++) {                                  \
                    const TYPE *zi = z + (i0 + j) * ns;                        \
                    TYPE *xo = pos + (i0 + j) * ns, *vo = vel + (i0 + j) * ns; \
                    xo[0] = zi[0];                                             \
                    vo[0] = (TYPE)NAN;                                         \
                    x[j] = zi[1];                                              \
                    v[j] = ((double)zi[1] - (double)zi[0]) / t;                \
                    xo[1] = (TYPE)x[j];                                        \
                    vo[1] = (TYPE)v[j];                                        \
                }                                                              \
                for (ptrdiff_t k = 2; k < ns; k++) {                           \
                    for (int j = 0; j < L; j++) {                              \
                        ptrdiff_t o = (i0 + j) * ns + k;                       \
                        double xp = x[j] + t * v[j];                           \
                        double e = (double)z[o] - xp;                          \
                        x[j] = xp + alpha * e;                                 \
                        v[j] = v[j] + g * e;                                   \
                        pos[o] = (TYPE)x[j];                                   \
                        vel[o] = (TYPE)v[j];                                   \
                    }                                                          \
                }                                                              \
            }                                                                  \
        }                                                                      \
        SCALAR(z + i0 * ns, pos + i0 * ns, vel + i0 * ns, nt - i0, ns, alpha,  \
               beta, t);                                                       \
    }

DEFINE_AB_X8(ab_f64_x8, double, ab_f64)
DEFINE_AB_X8(ab_f32_x8, float, ab_f32)

#define DEFINE_COPY2(NAME, TYPE)                                               \
    void NAME(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              ptrdiff_t n) {                                                   \
        for (ptrdiff_t k = 0; k < n; k++) {                                    \
            TYPE zk = z[k];                                                    \
            a[k] = zk;                                                         \
            b[k] = zk;                                                         \
        }                                                                      \
    }

#define DEFINE_COPY3(NAME, TYPE)                                               \
    void NAME(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              TYPE *restrict c, ptrdiff_t n) {                                 \
        for (ptrdiff_t k = 0; k < n; k++) {                                    \
            TYPE zk = z[k];                                                    \
            a[k] = zk;                                                         \
            b[k] = zk;                                                         \
            c[k] = zk;                                                         \
        }                                                                      \
    }

DEFINE_COPY2(copy2_f64, double)
DEFINE_COPY2(copy2_f32, float)
DEFINE_COPY3(copy3_f64, double)
DEFINE_COPY3(copy3_f32, float)

/* 8 segments, one cache line of each per step. */
#define SEG 8
#define DEFINE_COPY2SEG(NAME, TYPE)                                            \
    void NAME(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              ptrdiff_t n) {                                                   \
        enum { W = 64 / sizeof(TYPE) };                                        \
        ptrdiff_t m = n / SEG, k = 0;                                          \
        for (; k + W <= m; k += W)                                             \
            for (int s = 0; s < SEG; s++)                                      \
                for (int j = 0; j < W; j++) {                                  \
                    TYPE v = z[s * m + k + j];                                 \
                    a[s * m + k + j] = v;                                      \
                    b[s * m + k + j] = v;                                      \
                }                                                              \
        for (int s = 0; s < SEG; s++)                                          \
            for (ptrdiff_t j = k; j < m; j++) {                                \
                a[s * m + j] = z[s * m + j];                                   \
                b[s * m + j] = z[s * m + j];                                   \
            }                                                                  \
        for (ptrdiff_t j = SEG * m; j < n; j++) {                              \
            a[j] = z[j];                                                       \
            b[j] = z[j];                                                       \
        }                                                                      \
    }

DEFINE_COPY2SEG(copy2seg_f64, double)
DEFINE_COPY2SEG(copy2seg_f32, float)

#define DEFINE_COPY3SEG(NAME, TYPE)                                            \
    void NAME(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              TYPE *restrict c, ptrdiff_t n) {                                 \
        enum { W = 64 / sizeof(TYPE) };                                        \
        ptrdiff_t m = n / SEG, k = 0;                                          \
        for (; k + W <= m; k += W)                                             \
            for (int s = 0; s < SEG; s++)                                      \
                for (int j = 0; j < W; j++) {                                  \
                    TYPE v = z[s * m + k + j];                                 \
                    a[s * m + k + j] = v;                                      \
                    b[s * m + k + j] = v;                                      \
                    c[s * m + k + j] = v;                                      \
                }                                                              \
        for (int s = 0; s < SEG; s++)                                          \
            for (ptrdiff_t j = k; j < m; j++)                                  \
                a[s * m + j] = b[s * m + j] = c[s * m + j] = z[s * m + j];     \
        for (ptrdiff_t j = SEG * m; j < n; j++) a[j] = b[j] = c[j] = z[j];     \
    }

DEFINE_COPY3SEG(copy3seg_f64, double)
DEFINE_COPY3SEG(copy3seg_f32, float)

/* Non-temporal stores (AVX-512 or AVX; plain stores otherwise). The outputs
 * are peeled to 64-byte alignment; if they are not mutually aligned the
 * plain loop is used (the driver reports which). */
#if defined(__AVX512F__)
#define NT_BYTES 64
#define NT_D(p, v) _mm512_stream_pd((p), (v))
#define NT_S(p, v) _mm512_stream_ps((p), (v))
#define LD_D(p) _mm512_loadu_pd(p)
#define LD_S(p) _mm512_loadu_ps(p)
#define NT_AVAILABLE 2
#elif defined(__AVX__)
#define NT_BYTES 32
#define NT_D(p, v) _mm256_stream_pd((p), (v))
#define NT_S(p, v) _mm256_stream_ps((p), (v))
#define LD_D(p) _mm256_loadu_pd(p)
#define LD_S(p) _mm256_loadu_ps(p)
#define NT_AVAILABLE 1
#else
#define NT_AVAILABLE 0
#endif

int nt_available(void) { return NT_AVAILABLE; }

#define ALIGNED(p) ((((uintptr_t)(p)) & 63) == 0)

#if NT_AVAILABLE
#define DEFINE_COPYNT(NAME2, NAME3, TYPE, NT, LD)                              \
    int NAME2(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              ptrdiff_t n) {                                                   \
        enum { W = NT_BYTES / sizeof(TYPE) };                                  \
        ptrdiff_t k = 0;                                                       \
        int used = 0;                                                          \
        while (k < n && !ALIGNED(a + k)) {                                     \
            a[k] = z[k];                                                       \
            b[k] = z[k];                                                       \
            k++;                                                               \
        }                                                                      \
        if (ALIGNED(b + k)) {                                                  \
            used = 1;                                                          \
            for (; k + W <= n; k += W) {                                       \
                NT(a + k, LD(z + k));                                          \
                NT(b + k, LD(z + k));                                          \
            }                                                                  \
        }                                                                      \
        for (; k < n; k++) {                                                   \
            a[k] = z[k];                                                       \
            b[k] = z[k];                                                       \
        }                                                                      \
        _mm_sfence();                                                          \
        return used;                                                           \
    }                                                                          \
    int NAME3(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              TYPE *restrict c, ptrdiff_t n) {                                 \
        enum { W = NT_BYTES / sizeof(TYPE) };                                  \
        ptrdiff_t k = 0;                                                       \
        int used = 0;                                                          \
        while (k < n && !ALIGNED(a + k)) {                                     \
            a[k] = b[k] = c[k] = z[k];                                         \
            k++;                                                               \
        }                                                                      \
        if (ALIGNED(b + k) && ALIGNED(c + k)) {                                \
            used = 1;                                                          \
            for (; k + W <= n; k += W) {                                       \
                NT(a + k, LD(z + k));                                          \
                NT(b + k, LD(z + k));                                          \
                NT(c + k, LD(z + k));                                          \
            }                                                                  \
        }                                                                      \
        for (; k < n; k++) a[k] = b[k] = c[k] = z[k];                          \
        _mm_sfence();                                                          \
        return used;                                                           \
    }
DEFINE_COPYNT(copy2nt_f64, copy3nt_f64, double, NT_D, LD_D)
DEFINE_COPYNT(copy2nt_f32, copy3nt_f32, float, NT_S, LD_S)
#define DEFINE_COPYNTX(NAME2, TYPE, NT, LD)                                    \
    int NAME2(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              ptrdiff_t n) {                                                   \
        enum { W = NT_BYTES / sizeof(TYPE) };                                  \
        ptrdiff_t ka = 0, kb = 0;                                              \
        while (ka < n && !ALIGNED(a + ka)) { a[ka] = z[ka]; ka++; }            \
        while (kb < n && !ALIGNED(b + kb)) { b[kb] = z[kb]; kb++; }            \
        /* one pass: both outputs' lines at nearly the same z offset */        \
        ptrdiff_t d = kb - ka;                                                 \
        ptrdiff_t k = ka;                                                      \
        for (; k + W <= n && k + d + W <= n; k += W) {                         \
            NT(a + k, LD(z + k));                                              \
            NT(b + k + d, LD(z + k + d));                                      \
        }                                                                      \
        for (ptrdiff_t j = k; j < n; j++) a[j] = z[j];                         \
        for (ptrdiff_t j = k + d; j < n; j++) b[j] = z[j];                     \
        _mm_sfence();                                                          \
        return 1;                                                              \
    }
DEFINE_COPYNTX(copy2ntx_f64, double, NT_D, LD_D)
DEFINE_COPYNTX(copy2ntx_f32, float, NT_S, LD_S)
#else
#define DEFINE_COPYNT(NAME2, NAME3, TYPE)                                      \
    int NAME2(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              ptrdiff_t n) {                                                   \
        for (ptrdiff_t k = 0; k < n; k++) a[k] = b[k] = z[k];                  \
        return 0;                                                              \
    }                                                                          \
    int NAME3(const TYPE *restrict z, TYPE *restrict a, TYPE *restrict b,      \
              TYPE *restrict c, ptrdiff_t n) {                                 \
        for (ptrdiff_t k = 0; k < n; k++) a[k] = b[k] = c[k] = z[k];           \
        return 0;                                                              \
    }
DEFINE_COPYNT(copy2nt_f64, copy3nt_f64, double)
DEFINE_COPYNT(copy2nt_f32, copy3nt_f32, float)
int copy2ntx_f64(const double *restrict z, double *restrict a, double *restrict b, ptrdiff_t n) {
    return copy2nt_f64(z, a, b, n);
}
int copy2ntx_f32(const float *restrict z, float *restrict a, float *restrict b, ptrdiff_t n) {
    return copy2nt_f32(z, a, b, n);
}
#endif

/* Allocation alone: make every page of a fresh buffer exist by writing one
 * byte per 4 KiB (the first write to a page faults it in: the kernel maps
 * and zeroes it; with transparent huge pages one fault per 2 MiB). This is
 * what the memory of a new output costs before anything is written to it. */
void touch_pages(char *p, ptrdiff_t nbytes) {
    volatile char *q = p;
    for (ptrdiff_t k = 0; k < nbytes; k += 4096) q[k] = 0;
    if (nbytes > 0) q[nbytes - 1] = 0;
}
