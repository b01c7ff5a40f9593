/* store/ptex/ptexfilter_simd.c - the AVX2 + FMA + F16C inner loops of the Ptex filters,
 * chosen at run time when the CPU has them (pf_have_avx2); elsewhere ptexfilter.c's and
 * ptexfilter_kernel.c's portable loops run. Platform code lives here so that those stay
 * portable.
 *
 * The window loop (pf_apply_avx2): a separable kernel applied to a window of texels of any
 * type (u8, u16, half, float) and 1..4 channels, specialised per type and per row length, so
 * no per-texel switch and each value converted once. With 1, 2 or 4 channels a row of the
 * window is uw * nc contiguous values that tile 8 lanes: each row is converted 8 values at a
 * time and accumulated down the columns with the row's weight (one FMA per 8 values per row);
 * the column sums are dotted with the column weights (built in registers from scalar loads:
 * a vector load of weights just stored one by one stalls on store forwarding) once at the
 * end. The loads of a row's last 8 values may run up to 31 bytes past the window, so past the
 * face's data at the end of an arena: every arena a filter reads (the set's, the resolution
 * table's, a native file's texel section) is followed by at least 64 readable bytes. The
 * lanes past the window are cleared after conversion, so a NaN or Inf beside the window never
 * leaks in. With 3 channels each texel is one 4-lane vector, weighted along the row and the
 * row into the sum (Ptex's order; lane 3 holds whatever follows and is never read).
 *
 * The kernel (pf_kernel_eval2_avx2): the gaussian or bicubic-family weights of both axes, 8
 * at a time, with the portable code's operations in its order (no fused multiply-adds), so
 * the weights are bit for bit the portable ones.
 *
 * The fused path of a kernel inside one face (pf_fast_select: one function per texel type and
 * channel count, chosen once per batch): box and width-4 kernels built for both axes at once
 * in one SSE vector (lane 0 u, lane 1 v) with pk_build's operations in its order, the
 * width-4 weights of both axes in one 8-lane evaluation when each has at most 4 taps, zeros
 * stripped with a mask, and the same window loop; no pk is built and nothing crosses a
 * function boundary per query. The width-4 filters' common case (w4_body: 4 taps each way,
 * none zero) runs first with its shape as constants and everything in registers, without
 * a stack frame; 5 to 8 taps go to its out-of-line instance, the rest (and the box, whose
 * function pf_fast_select gives directly) to that general fused code (pf_fgen).
 * It declines (returns 0) whatever it does not take, and the
 * general path then runs: results are bit for bit those of the general path
 * (test_ptexfilter_simd).
 *
 * The width-4 filters' common case 8 queries at a time (pf_w4x8_select, after
 * ptexfilter_lanes.c's klanes8 has classified the block): w4_body's set-up and taps lane by
 * lane in 8-lane vectors (one lane a query), its operations in its order, so bit for bit;
 * the kernels that overhang their face handed over as w4_body hands them over; a query on or
 * near a texel centre, whose kernel has zero taps at an end of an axis (the bicubic family's
 * tap at distance 2, (0, k, k', k''); Catmull-Rom's at distance 1 too, (0, 0, 1, 0)),
 * stripped as w4_tail strips it, lane by lane (w4x8_strip: the taps moved down by the
 * leading zeros, +0 from the stripped length on, the window's first texel moved on and its
 * test against the face redone). The 4 x 4 window: for 1-channel u8 and u16 texels in the
 * vectors too (w4x8_body: the window rows gathered, a stripped lane's rows past its length
 * masked off); for the other types and channel counts (w4x8_each) per lane served, w4_tail's
 * own window loop on the taps transposed out of the vectors (a stripped lane: window_fused,
 * or w4_win1 for 1 channel, on its stripped shape).
 *
 * The box filter's in-face case 8 queries at a time (pf_box8_select, after klanes8): box_axes'
 * set-up of both axes, its zero-weight test, the inside test, the weight and the scale lane
 * by lane in 8-lane vectors, its operations in its order; the kernels that overhang their
 * face handed over as fast_body hands them over. The window of 1, 2 or 3 taps each way: for
 * 1-channel u8 and u16 texels in the vectors (3 rows gathered, a row past a lane's taps not
 * read, a column past them weighted +0, which for finite texels is what window4's cleared
 * lane gives); for the others per lane served, fast_body's window with the lane's shape as
 * constants (box8_win: the same function, its loops unrolled).
 *
 * The width-4 kernels the per-query path builds itself (pf_b8_select: a width of a quarter
 * face or more, or a face under 8 x 8 texels; ptexfilter.c's kernel_declined_with), 8 at a
 * time in blocks that offer the 8-query fused path under 3 lanes: pk_width4_axis' four
 * bands of the clamped width lane by lane (under 1/4 and [1/4, 1/2) evaluated as one, their
 * taps x1 + i step; [1/2, 1) and 1 or more hermite taps), the strip and the weight, the
 * kernels and weights handed to ptexfilter.c's kernel_built (apply, the walk or eval_kernel).
 *
 * Windows of at most 2 x 2 texels (pf_small_select: the pieces of a bilinear kernel split
 * at face edges): the same window loop with the shape as constants, one function per texel
 * type and channel count, so a piece costs no dispatch; bit for bit pf_apply_avx2.
 Four (two) one-texel windows in one call (pf_small4_select, pf_small2_select: the pieces of
 * a width-4 kernel at resolution 1 x 1 split at a regular corner, or folded at a boundary
 * and split at one edge): the same small-window code four (two) times in order.
 *
 * The Traverse walk of a bilinear 2 x 2 kernel over plain faces (pf_edge2_select,
 * ptexfilter_walk.h): ptexfilter.c's split walk for that kernel, its pieces in registers and
 * their windows summed inline by the same small-window code (no call per piece, which
 * spilled every piece around each call); at a corner of valence other than 4
 * (tv_corner_other) corner_other_small's steps on the one-texel corner piece, the walk's
 * weight changed as it changes it.
 *
 * The width-4 filters' kernels on faces without neighbours, 8 at a time after klanes8:
 * kernel_r0's of a face or more (pf_r0x8_select), kernel_iso's of half a face to a face
 * (pf_iso8_select), and those of a quarter to half a face at resolution 2 x 2 with evaluated
 * taps (pf_q8_select: up to the window's shape and weights; ptexfilter.c sums the window):
 * pk_width4_axis, the strip, the fold at the face's edges (or Discard's drop) and the weight
 * lane by lane. Kernels inside a constant face (pf_cst8_select): the box's (box8_axis) and
 * the width-4 filters' under a quarter face, the inside test and pk_weight lane by lane.
 *
 * The in-face bilinear of half texels (pf_bilinear_half_select): F16C conversions, then the
 * portable bilinear's multiplies and adds in its order (no fused multiply-adds), so the
 * results are the portable loop's for every finite value.
 *
 * Owns: nothing but these loops. The window sums run in a different order than the portable
 * loop (and than Ptex for 1, 2 and 4 channels: columns first), so results differ from them by
 * float rounding only.
 */
#include "ptexfilter_kernel.h"

#include <stddef.h>

#include "ptexfilter_lanes.h"
#include "ptexfilter_walk.h"

#include "sample.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#include <immintrin.h>

int pf_have_avx2(void)
{
    __builtin_cpu_init();
    if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma"))
        return 0;
#ifdef __clang__
    /* clang's __builtin_cpu_supports has no "f16c": CPUID leaf 1, ECX bit 29 (slow in a VM,
     * where CPUID traps: callers ask once per batch) */
    unsigned a, b, c, d;
    return __get_cpuid(1, &a, &b, &c, &d) && (c >> 29 & 1);
#else
    return __builtin_cpu_supports("f16c"); /* reads what libgcc found at start-up */
#endif
}

#define PF_TARGET __attribute__((target("avx2,fma,f16c"), always_inline)) static inline

/* 8 values of type dt (0 u8, 1 u16, 2 half, 3 float: st_dtype) from p, as floats. */
PF_TARGET __m256 load8(const uint8_t *p, unsigned dt)
{
    switch (dt) {
    case 0:
        return _mm256_cvtepi32_ps(
            _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(const void *)p)));
    case 1:
        return _mm256_cvtepi32_ps(
            _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(const void *)p)));
    case 2:
        return _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(const void *)p));
    default:
        return _mm256_loadu_ps((const float *)(const void *)p);
    }
}

/* 4 values of type DT from p as floats: one 3-channel texel (the 4th lane is the next value
 * or slack: finite or not, it stays in lane 3, which no caller reads), or the at most 4
 * values of a short window row (window4 masks the lanes past the row). */
PF_TARGET __m128 load4(const uint8_t *p, unsigned DT)
{
    switch (DT) {
    case 0: {
        int x;
        __builtin_memcpy(&x, p, 4);
        return _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(x)));
    }
    case 1:
        return _mm_cvtepi32_ps(_mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(const void *)p)));
    case 2:
        return _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(const void *)p));
    default:
        return _mm_loadu_ps((const float *)(const void *)p);
    }
}

/* window() for a row of at most 4 values (uw * nc <= 4: the small windows of edge pieces and
 * small faces) in 4 lanes: the same operations on the same lanes in the same order (the
 * upper 4 lanes of window() hold +0 there, which the fold adds as "+ 0"), so bit for bit
 * window()'s result. */
PF_TARGET __m128 window4(const uint8_t *base, size_t rowb, unsigned DT, unsigned nc,
                         const float *ku, int uw, const float *kv, int vw, __m128 acc)
{
    int nt = uw * (int)nc;
    __m128 tail = _mm_castsi128_ps(_mm_cmpgt_epi32(_mm_set1_epi32(nt), _mm_setr_epi32(0, 1, 2, 3)));
    __m128 col = _mm_setzero_ps();
    for (int j = 0; j < vw; j++)
        col = _mm_fmadd_ps(_mm_and_ps(load4(base + (size_t)j * rowb, DT), tail),
                           _mm_set1_ps(kv[j]), col);
    const __m128 z = _mm_setzero_ps();
    __m128 q;
    if (nc == 4) {
        q = _mm_add_ps(_mm_mul_ps(col, _mm_set1_ps(ku[0])), z);
        return _mm_add_ps(acc, q);
    }
    if (nc == 2) {
        __m128 k = _mm_setr_ps(ku[0], uw > 1 ? ku[1] : 0.0f, 0.0f, 0.0f);
        q = _mm_add_ps(_mm_fmadd_ps(col, _mm_unpacklo_ps(k, k), z), z);
    } else {
        __m128 k = _mm_setr_ps(ku[0], uw > 1 ? ku[1] : 0.0f, uw > 2 ? ku[2] : 0.0f,
                               uw > 3 ? ku[3] : 0.0f);
        q = _mm_add_ps(_mm_fmadd_ps(col, k, z), z);
    }
    __m128 h = _mm_add_ps(q, _mm_movehl_ps(q, q));
    if (nc == 2)
        return _mm_add_ps(acc, _mm_movelh_ps(h, z));
    return _mm_add_ss(acc, _mm_add_ss(h, _mm_shuffle_ps(h, h, 1)));
}

/* The whole window for type DT and NV vectors per row (both constants where inlined, so
 * the column sums stay in registers): col[b] += kv[j] * row j, then the dot with the column
 * weights, folded into acc by channel. */
PF_TARGET __m128 window(const uint8_t *base, size_t rowb, unsigned DT, unsigned nc,
                        const float *ku, int uw, const float *kv, int vw, int NV, __m128 acc)
{
    enum { MAXV = (PK_MAX * 4 + 7) / 8 };
    if (NV == 1 && uw * (int)nc <= 4)
        return window4(base, rowb, DT, nc, ku, uw, kv, vw, acc);
    size_t vb = (size_t)8 << (DT == 0 ? 0 : DT == 3 ? 2 : 1); /* bytes per 8 values */
    int ne = uw * (int)nc;
    int nt = ne - 8 * (NV - 1); /* values in the last vector, 1..8 */
    __m256 tail = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
        _mm256_set1_epi32(nt), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))); /* lanes < nt */
    __m256 col[MAXV];
    for (int b = 0; b < NV; b++)
        col[b] = _mm256_setzero_ps();
    for (int j = 0; j < vw; j++) {
        const uint8_t *p = base + (size_t)j * rowb;
        __m256 w = _mm256_set1_ps(kv[j]);
        for (int b = 0; b + 1 < NV; b++)
            col[b] = _mm256_fmadd_ps(load8(p + (size_t)b * vb, DT), w, col[b]);
        __m256 last = _mm256_and_ps(load8(p + (size_t)(NV - 1) * vb, DT), tail);
        col[NV - 1] = _mm256_fmadd_ps(last, w, col[NV - 1]);
    }
    /* the column weights, one per value, made in registers from scalar loads (the weights
     * were just stored, some one by one: a vector load of them would stall on store
     * forwarding): vector b holds ku[e / nc] for e = 8b .. 8b+7, zero past the window */
#define KU(t) ((t) < uw ? ku[t] : 0.0f)
    __m256 s;
    if (nc == 4) {
        s = _mm256_mul_ps(col[0], _mm256_set_m128(_mm_set1_ps(KU(1)), _mm_set1_ps(ku[0])));
        for (int b = 1; b < NV; b++)
            s = _mm256_fmadd_ps(col[b], _mm256_set_m128(_mm_set1_ps(KU(2 * b + 1)),
                                                        _mm_set1_ps(ku[2 * b])), s);
    } else if (nc == 2) {
        s = _mm256_setzero_ps();
        for (int b = 0; b < NV; b++) {
            int t = 4 * b;
            __m128 k = _mm_setr_ps(ku[t], KU(t + 1), KU(t + 2), KU(t + 3));
            __m256 wb = _mm256_set_m128(_mm_unpackhi_ps(k, k), _mm_unpacklo_ps(k, k));
            s = _mm256_fmadd_ps(col[b], wb, s);
        }
    } else {
        s = _mm256_setzero_ps();
        for (int b = 0; b < NV; b++) {
            int t = 8 * b;
            __m256 wb = _mm256_setr_ps(ku[t], KU(t + 1), KU(t + 2), KU(t + 3), KU(t + 4),
                                       KU(t + 5), KU(t + 6), KU(t + 7));
            s = _mm256_fmadd_ps(col[b], wb, s);
        }
    }
#undef KU
    __m128 q = _mm_add_ps(_mm256_castps256_ps128(s), _mm256_extractf128_ps(s, 1)); /* lane % 4 */
    if (nc == 4)
        return _mm_add_ps(acc, q);
    __m128 h = _mm_add_ps(q, _mm_movehl_ps(q, q)); /* lanes 0, 1: lane % 2 */
    if (nc == 2)
        return _mm_add_ps(acc, _mm_movelh_ps(h, _mm_setzero_ps()));
    return _mm_add_ss(acc, _mm_add_ss(h, _mm_shuffle_ps(h, h, 1)));
}

/* 3 channels: the texels do not tile 8 lanes, so each texel is a 4-lane vector, weighted
 * along the row, then the row weighted into acc (Ptex's order). */
PF_TARGET __m128 window3(const uint8_t *base, size_t rowb, unsigned DT, const float *ku, int uw,
                         const float *kv, int vw, __m128 acc)
{
    size_t ts = (size_t)3 << (DT == 0 ? 0 : DT == 3 ? 2 : 1);
    for (int j = 0; j < vw; j++) {
        const uint8_t *p = base + (size_t)j * rowb;
        __m128 row = _mm_mul_ps(load4(p, DT), _mm_set1_ps(ku[0]));
        for (int i = 1; i < uw; i++)
            row = _mm_fmadd_ps(load4(p + (size_t)i * ts, DT), _mm_set1_ps(ku[i]), row);
        acc = _mm_fmadd_ps(row, _mm_set1_ps(kv[j]), acc);
    }
    return acc;
}

/* The window loop for rows of more than 8 values (window_dt's rarer cases), called out of
 * line (pf_winlong_DT_NC), so that its column sums' stack frame is not set up for the short
 * rows of most windows. */
PF_TARGET __m128 window_long(const uint8_t *base, size_t rowb, unsigned DT, unsigned NC,
                             const float *ku, int uw, const float *kv, int vw, int nv,
                             __m128 acc)
{
    switch (nv) {
    case 2: return window(base, rowb, DT, NC, ku, uw, kv, vw, 2, acc);
    case 3: return window(base, rowb, DT, NC, ku, uw, kv, vw, 3, acc);
    case 4: return window(base, rowb, DT, NC, ku, uw, kv, vw, 4, acc);
    case 5: return window(base, rowb, DT, NC, ku, uw, kv, vw, 5, acc);
    default: return window(base, rowb, DT, NC, ku, uw, kv, vw, nv, acc);
    }
}

#define PF_WINLONG(DT, NC)                                                                  \
    __attribute__((target("avx2,fma,f16c"), noinline)) static __m128 pf_winlong_##DT##_##NC( \
        const uint8_t *base, size_t rowb, const float *ku, int uw, const float *kv, int vw,  \
        int nv, __m128 acc)                                                                 \
    {                                                                                       \
        return window_long(base, rowb, DT, NC, ku, uw, kv, vw, nv, acc);                    \
    }
#define PF_WINLONG_NC(DT) PF_WINLONG(DT, 1) PF_WINLONG(DT, 2) PF_WINLONG(DT, 4)
PF_WINLONG_NC(0)
PF_WINLONG_NC(1)
PF_WINLONG_NC(2)
PF_WINLONG_NC(3)

/* The window loop for texels of type DT with NC channels (both constants): NC == 3 one
 * texel a vector, else the row length's number of 8-value vectors (1 here, 2..5 unrolled in
 * window_long). */
PF_TARGET __m128 window_dt(const uint8_t *base, size_t rowb, unsigned DT, unsigned NC,
                           const float *ku, int uw, const float *kv, int vw, __m128 acc)
{
    if (NC == 3) { /* rows of 1 to 4 texels unrolled (the pieces of split kernels) */
        switch (uw) {
        case 1: return window3(base, rowb, DT, ku, 1, kv, vw, acc);
        case 2: return window3(base, rowb, DT, ku, 2, kv, vw, acc);
        case 3: return window3(base, rowb, DT, ku, 3, kv, vw, acc);
        case 4: return window3(base, rowb, DT, ku, 4, kv, vw, acc);
        default: return window3(base, rowb, DT, ku, uw, kv, vw, acc);
        }
    }
    int nv = (uw * (int)NC + 7) / 8;
    if (nv < 1)
        return acc;
    if (nv == 1)
        return window(base, rowb, DT, NC, ku, uw, kv, vw, 1, acc);
    switch (DT * 4 + NC) {
#define PF_LONG_CASE(D, N)                                                                  \
    case D * 4 + N: return pf_winlong_##D##_##N(base, rowb, ku, uw, kv, vw, nv, acc);
#define PF_LONG_CASES(D) PF_LONG_CASE(D, 1) PF_LONG_CASE(D, 2) PF_LONG_CASE(D, 4)
    PF_LONG_CASES(0)
    PF_LONG_CASES(1)
    PF_LONG_CASES(2)
    PF_LONG_CASES(3)
#undef PF_LONG_CASES
#undef PF_LONG_CASE
    default: return acc; /* NC == 3 returned above */
    }
}

/* The fused paths' window (fast_body, w4_body; at most 8 taps a side): NC == 3 one texel
 * a vector, else 1 to 4 8-value vectors a row, each count an instance of window. */
PF_TARGET __m128 window_fused(const uint8_t *base, size_t rowb, unsigned DT, unsigned NC,
                              const float *ku, int nu, const float *kv, int nv)
{
    __m128 acc = _mm_setzero_ps();
    if (NC == 3)
        return window3(base, rowb, DT, ku, nu, kv, nv, acc);
    switch ((nu * (int)NC + 7) / 8) {
    case 1: return window(base, rowb, DT, NC, ku, nu, kv, nv, 1, acc);
    case 2: return window(base, rowb, DT, NC, ku, nu, kv, nv, 2, acc);
    case 3: return window(base, rowb, DT, NC, ku, nu, kv, nv, 3, acc);
    default: return window(base, rowb, DT, NC, ku, nu, kv, nv, 4, acc);
    }
}

/* out[ch] = channel ch of acc times scale, for the NC channels. */
PF_TARGET void put_scaled(float *out, __m128 acc, float scale, unsigned NC)
{
    float r[4];
    _mm_storeu_ps(r, acc);
    for (unsigned ch = 0; ch < NC; ch++)
        out[ch] = r[ch] * scale;
}

/* window4 for 1-channel u8 or u16 texels (DT) with the window's shape (uw, vw <= 4) as
 * constants, every row unrolled, and the lanes past the row not cleared: the same
 * operations on the same lanes in the same order but for that mask, and it changes no bit.
 * A lane past the row (i >= uw) sums finite values (integer texels, finite weights) into
 * a column c, which the dot weights +0: fma(c, +0, +0) is +0 for any finite c, as
 * fma(+0, +0, +0) is for the cleared lane. The lanes < uw are window4's. */
PF_TARGET __m128 window4_int(const uint8_t *base, size_t rowb, unsigned DT, const float *ku,
                             int uw, const float *kv, int vw, __m128 acc)
{
    __m128 col = _mm_setzero_ps();
    _Pragma("GCC unroll 4") for (int j = 0; j < vw; j++)
        col = _mm_fmadd_ps(load4(base + (size_t)j * rowb, DT), _mm_set1_ps(kv[j]), col);
    const __m128 z = _mm_setzero_ps();
    __m128 k = uw == 4 ? _mm_loadu_ps(ku)
                       : _mm_setr_ps(ku[0], uw > 1 ? ku[1] : 0.0f, uw > 2 ? ku[2] : 0.0f, 0.0f);
    __m128 q = _mm_add_ps(_mm_fmadd_ps(col, k, z), z);
    __m128 h = _mm_add_ps(q, _mm_movehl_ps(q, q));
    return _mm_add_ss(acc, _mm_add_ss(h, _mm_shuffle_ps(h, h, 1)));
}

/* window_dt with rows of 1 to 4 texels (the pieces of the walked 4 x 4 and box kernels, most
 * windows of pf_window_select's callers) as constants: the same window() on the same values
 * (window_dt gives it its vector count (uw NC + 7) / 8 too, out of line from 2 on), so the
 * same bits, with the row's masks and column weights made from constants and the 2-vector
 * rows of 4-channel texels inline (no call, no stack frame for window_long's column sums).
 * Longer rows and 3 channels (window_dt unrolls those itself) go to window_dt. */
PF_TARGET __m128 window_piece(const uint8_t *base, size_t rowb, unsigned DT, unsigned NC,
                              const float *ku, int uw, const float *kv, int vw, __m128 acc)
{
    if (NC == 3)
        return window_dt(base, rowb, DT, NC, ku, uw, kv, vw, acc);
    switch (uw) {
    case 1: return window(base, rowb, DT, NC, ku, 1, kv, vw, 1, acc);
    case 2: return window(base, rowb, DT, NC, ku, 2, kv, vw, ((int)NC * 2 + 7) / 8, acc);
    case 3: return window(base, rowb, DT, NC, ku, 3, kv, vw, ((int)NC * 3 + 7) / 8, acc);
    case 4: return window(base, rowb, DT, NC, ku, 4, kv, vw, ((int)NC * 4 + 7) / 8, acc);
    default: return window_dt(base, rowb, DT, NC, ku, uw, kv, vw, acc);
    }
}

/* window_piece, for 1-channel u8 and u16 texels with windows of at most 4 x 4 (uw - 1 and
 * vw - 1 in [0, 4)): window4_int with the shape as constants (a jump table; no stack frame:
 * pf_win_ gives the rest, whose column sums may need one, to window_piece out of line). */
PF_TARGET __m128 window_small_int(const uint8_t *base, size_t rowb, unsigned DT,
                                  const float *ku, int uw, const float *kv, int vw, __m128 acc)
{
    switch ((uw - 1) * 4 + vw - 1) {
#define PF_INT_CASE(U, V)                                                                   \
    case (U - 1) * 4 + V - 1: return window4_int(base, rowb, DT, ku, U, kv, V, acc);
#define PF_INT_CASES(U) PF_INT_CASE(U, 1) PF_INT_CASE(U, 2) PF_INT_CASE(U, 3) PF_INT_CASE(U, 4)
    PF_INT_CASES(1)
    PF_INT_CASES(2)
    PF_INT_CASES(3)
    PF_INT_CASES(4)
#undef PF_INT_CASES
#undef PF_INT_CASE
    default: __builtin_unreachable();
    }
}

#define PF_WIN(DT, NC)                                                                      \
    __attribute__((target("avx2,fma,f16c"), noinline)) static pf_v4 pf_winrest_##DT##_##NC( \
        const uint8_t *base, size_t rowb, const float *ku, int uw, const float *kv, int vw,  \
        pf_v4 acc)                                                                          \
    {                                                                                       \
        return (pf_v4)window_piece(base, rowb, DT, NC, ku, uw, kv, vw, (__m128)acc);        \
    }                                                                                       \
    __attribute__((target("avx2,fma,f16c"))) static pf_v4 pf_win_##DT##_##NC(               \
        const uint8_t *base, size_t rowb, const float *ku, int uw, const float *kv, int vw,  \
        pf_v4 acc)                                                                          \
    {                                                                                       \
        if (!(NC == 1 && DT <= 1)) /* window_piece here: no jump to pf_winrest */          \
            return (pf_v4)window_piece(base, rowb, DT, NC, ku, uw, kv, vw, (__m128)acc);    \
        if (((unsigned)(uw - 1) | (unsigned)(vw - 1)) < 4)                                 \
            return (pf_v4)window_small_int(base, rowb, DT, ku, uw, kv, vw, (__m128)acc);    \
        return pf_winrest_##DT##_##NC(base, rowb, ku, uw, kv, vw, acc);                     \
    }
#define PF_WIN_NC(DT) PF_WIN(DT, 1) PF_WIN(DT, 2) PF_WIN(DT, 3) PF_WIN(DT, 4)
PF_WIN_NC(0)
PF_WIN_NC(1)
PF_WIN_NC(2)
PF_WIN_NC(3)

/* The entry of a [type][channels - 1] table of window functions, NULL out of range or
 * without AVX2 (pf_window_select, pf_small_select). */
static pf_window_fn pick_window(const pf_window_fn fns[4][4], unsigned dt, unsigned nc)
{
    if (dt > 3 || nc < 1 || nc > 4 || !pf_have_avx2())
        return NULL;
    return fns[dt][nc - 1];
}

pf_window_fn pf_window_select(unsigned dt, unsigned nc)
{
    static const pf_window_fn fns[4][4] = {
        {pf_win_0_1, pf_win_0_2, pf_win_0_3, pf_win_0_4},
        {pf_win_1_1, pf_win_1_2, pf_win_1_3, pf_win_1_4},
        {pf_win_2_1, pf_win_2_2, pf_win_2_3, pf_win_2_4},
        {pf_win_3_1, pf_win_3_2, pf_win_3_3, pf_win_3_4},
    };
    return pick_window(fns, dt, nc);
}

pf_v4 pf_apply_avx2(const uint8_t *base, size_t rowb, const pk *k, unsigned dt, unsigned nc,
                    pf_v4 acc)
{
    pf_window_fn w = pf_window_select(dt, nc);
    if (!w || k->uw <= 0 || k->vw <= 0)
        return acc;
    return w(base, rowb, k->kub + k->ku0, k->uw, k->kvb + k->kv0, k->vw, acc);
}

/* 2^y at 8 points for y in [-126, 0]: kernel_eval's exp2 polynomial (ptexfilter_kernel.c),
 * the same operations in the same order; the callers clamp y (or know it is in range). */
PF_TARGET __m256 exp2_8(__m256 y)
{
    __m256i ii = _mm256_cvttps_epi32(_mm256_sub_ps(y, _mm256_set1_ps(0.5f)));
    __m256 f = _mm256_sub_ps(y, _mm256_cvtepi32_ps(ii));
    __m256 q = _mm256_set1_ps(0.000154035304f);
    q = _mm256_add_ps(_mm256_set1_ps(0.00133335581f), _mm256_mul_ps(f, q));
    q = _mm256_add_ps(_mm256_set1_ps(0.00961812911f), _mm256_mul_ps(f, q));
    q = _mm256_add_ps(_mm256_set1_ps(0.0555041087f), _mm256_mul_ps(f, q));
    q = _mm256_add_ps(_mm256_set1_ps(0.240226507f), _mm256_mul_ps(f, q));
    q = _mm256_add_ps(_mm256_set1_ps(0.693147181f), _mm256_mul_ps(f, q));
    q = _mm256_add_ps(_mm256_set1_ps(1.0f), _mm256_mul_ps(f, q));
    __m256i bits = _mm256_slli_epi32(_mm256_add_epi32(ii, _mm256_set1_epi32(127)), 23);
    return _mm256_mul_ps(q, _mm256_castsi256_ps(bits));
}

/* The width-4 kernel function at 8 points: the same operations in the same order as
 * ptexfilter_kernel.c's kernel_eval (no fused multiply-adds), so the weights are bit for bit
 * the portable ones. */
PF_TARGET __m256 kernel8_as(const pk_params *p, __m256 x, int gauss)
{
    const float *c = p->coeffs;
    if (gauss) {
        __m256 y = _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(x, x), _mm256_set1_ps(-2.0f)),
                                 _mm256_set1_ps(1.44269504f));
        y = _mm256_max_ps(y, _mm256_set1_ps(-126.0f));
        return exp2_8(y);
    }
    __m256 a = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), x);
    __m256 inner = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(c[0]), a),
                                               _mm256_set1_ps(c[1])), a);
    inner = _mm256_add_ps(_mm256_mul_ps(inner, a), _mm256_set1_ps(c[2]));
    __m256 outer = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(c[3]), a), _mm256_set1_ps(c[4]));
    outer = _mm256_add_ps(_mm256_mul_ps(outer, a), _mm256_set1_ps(c[5]));
    outer = _mm256_add_ps(_mm256_mul_ps(outer, a), _mm256_set1_ps(c[6]));
    __m256 m1 = _mm256_cmp_ps(a, _mm256_set1_ps(1.0f), _CMP_LT_OQ);
    __m256 m2 = _mm256_cmp_ps(a, _mm256_set1_ps(2.0f), _CMP_LT_OQ);
    return _mm256_or_ps(_mm256_and_ps(inner, m1), _mm256_andnot_ps(m1, _mm256_and_ps(outer, m2)));
}

/* kernel8_as for p's filter. */
PF_TARGET __m256 kernel8(const pk_params *p, __m256 x)
{
    return kernel8_as(p, x, p->ftype == ST_FILTER_PTEX_GAUSSIAN);
}

/* The sums in order of a's lanes below na and b's below nb (na, nb <= 8; s + a[0] + a[1] +
 * ... in lane 0, the same of b in lane 1), the other lanes cleared to +0 first: adding +0
 * changes no sum that starts at +0 (such a sum is never -0). The lanes paired (a[i], b[i])
 * so that both axes take one addition a tap. */
PF_TARGET __m128 sum2_lanes(__m256 a, int na, __m256 b, int nb, __m128 s)
{
    const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    a = _mm256_and_ps(a, _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(na), iota)));
    b = _mm256_and_ps(b, _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(nb), iota)));
    __m256 lo = _mm256_unpacklo_ps(a, b), hi = _mm256_unpackhi_ps(a, b);
    __m128 l0 = _mm256_castps256_ps128(lo), h0 = _mm256_castps256_ps128(hi);
    __m128 l1 = _mm256_extractf128_ps(lo, 1), h1 = _mm256_extractf128_ps(hi, 1);
    s = _mm_add_ps(s, l0);                     /* taps 0 */
    s = _mm_add_ps(s, _mm_movehl_ps(l0, l0)); /* 1 */
    s = _mm_add_ps(s, h0);                     /* 2 */
    s = _mm_add_ps(s, _mm_movehl_ps(h0, h0)); /* 3 */
    s = _mm_add_ps(s, l1);                     /* 4 */
    s = _mm_add_ps(s, _mm_movehl_ps(l1, l1)); /* 5 */
    s = _mm_add_ps(s, h1);                     /* 6 */
    return _mm_add_ps(s, _mm_movehl_ps(h1, h1)); /* 7 */
}

/* Both axes' weights (8, or 16 for more than 8 taps) stored; with SUMS (a constant) their
 * sums in order (sum2_lanes) in lanes 0 and 1 of the result, else nothing summed. */
PF_TARGET __m128 eval2(const pk_params *p, float x1u, float su, float *wu, int nu, float x1v,
                       float sv, float *wv, int nv, int SUMS)
{
    const __m256 i0 = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 i1 = _mm256_setr_ps(8, 9, 10, 11, 12, 13, 14, 15);
    __m256 su8 = _mm256_set1_ps(su), sv8 = _mm256_set1_ps(sv);
    __m256 xu = _mm256_set1_ps(x1u), xv = _mm256_set1_ps(x1v);
    __m256 a = kernel8(p, _mm256_add_ps(xu, _mm256_mul_ps(i0, su8)));
    __m256 b = kernel8(p, _mm256_add_ps(xv, _mm256_mul_ps(i0, sv8)));
    _mm256_storeu_ps(wu, a);
    _mm256_storeu_ps(wv, b);
    __m128 s = _mm_setzero_ps();
    if (SUMS)
        s = sum2_lanes(a, nu, b, nv, s);
    if (__builtin_expect(nu > 8 || nv > 8, 0)) {
        a = _mm256_setzero_ps();
        b = _mm256_setzero_ps();
        if (nu > 8)
            _mm256_storeu_ps(wu + 8, a = kernel8(p, _mm256_add_ps(xu, _mm256_mul_ps(i1, su8))));
        if (nv > 8)
            _mm256_storeu_ps(wv + 8, b = kernel8(p, _mm256_add_ps(xv, _mm256_mul_ps(i1, sv8))));
        if (SUMS)
            s = sum2_lanes(a, nu - 8, b, nv - 8, s);
    }
    return s;
}

/* One axis' weights stored; with SUMS their sum in order in lane 0. */
PF_TARGET __m128 eval1(const pk_params *p, float x1, float s, float *w, int n, int SUMS)
{
    __m256 s8 = _mm256_set1_ps(s), x = _mm256_set1_ps(x1), z = _mm256_setzero_ps();
    __m256 a = kernel8(p, _mm256_add_ps(x, _mm256_mul_ps(_mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7),
                                                         s8)));
    _mm256_storeu_ps(w, a);
    __m128 r = _mm_setzero_ps();
    if (SUMS)
        r = sum2_lanes(a, n, z, 0, r);
    if (__builtin_expect(n > 8, 0)) {
        a = kernel8(p, _mm256_add_ps(x, _mm256_mul_ps(
                                            _mm256_setr_ps(8, 9, 10, 11, 12, 13, 14, 15), s8)));
        _mm256_storeu_ps(w + 8, a);
        if (SUMS)
            r = sum2_lanes(a, n - 8, z, 0, r);
    }
    return r;
}

__attribute__((target("avx2,fma,f16c")))
void pf_kernel_eval2_avx2(const pk_params *p, float x1u, float su, float *wu, int nu,
                          float x1v, float sv, float *wv, int nv)
{
    eval2(p, x1u, su, wu, nu, x1v, sv, wv, nv, 0);
}

__attribute__((target("avx2,fma,f16c")))
void pf_kernel_eval1_avx2(const pk_params *p, float x1, float s, float *w, int n)
{
    eval1(p, x1, s, w, n, 0);
}

__attribute__((target("avx2,fma,f16c")))
pf_v4 pf_kernel_eval2s_avx2(const pk_params *p, float x1u, float su, float *wu, int nu,
                            float x1v, float sv, float *wv, int nv)
{
    return (pf_v4)eval2(p, x1u, su, wu, nu, x1v, sv, wv, nv, 1);
}

__attribute__((target("avx2,fma,f16c")))
float pf_kernel_eval1s_avx2(const pk_params *p, float x1, float s, float *w, int n)
{
    return _mm_cvtss_f32(eval1(p, x1, s, w, n, 1));
}

/* ---- the fused path of a kernel inside one face (pf_fast_select) ------------------------ */

/* Both axes of Ptex's box filter at once (lane 0 u, lane 1 v), pk_build's arithmetic in its
 * order: the resolution, first texel, taps (1..3) and weights of each axis, and each axis'
 * weights summed in order (pk_weight's factors). 0 when a weight at an end is 0 (the
 * general path strips it). */
PF_TARGET int box_axes(float u, float v, float uw, float vw, int fulog2, int fvlog2, int *res,
                       int *k0, int *kw, float *ku, float *kv, float *sum)
{
    __m128 x = _mm_setr_ps(u, v, 0.0f, 0.0f), w = _mm_setr_ps(uw, vw, 1.0f, 1.0f);
    const __m128 one = _mm_set1_ps(1.0f), half = _mm_set1_ps(0.5f);
    const __m128i e127 = _mm_set1_epi32(127);
    w = _mm_min_ps(w, one);                                   /* uw < 1 ? uw : 1 */
    __m128 lo = _mm_castsi128_ps(_mm_slli_epi32(
        _mm_sub_epi32(e127, _mm_setr_epi32(fulog2, fvlog2, 0, 0)), 23));
    w = _mm_max_ps(w, lo);                                    /* uw > lu ? uw : lu */
    __m128i r = _mm_sub_epi32(e127, _mm_and_si128(_mm_srli_epi32(_mm_castps_si128(w), 23),
                                                  _mm_set1_epi32(0xff)));
    __m128 rf = _mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(r, e127), 23)); /* 2^res */
    x = _mm_mul_ps(x, rf);
    w = _mm_mul_ps(w, rf);
    __m128 hw = _mm_mul_ps(half, w);
    __m128 x1 = _mm_sub_ps(x, hw), x2 = _mm_add_ps(x, hw);
    __m128 x1f = _mm_floor_ps(x1), x2c = _mm_ceil_ps(x2);
    __m128i a = _mm_cvttps_epi32(x1f);
    __m128i n = _mm_sub_epi32(_mm_cvttps_epi32(x2c), a);
    n = _mm_min_epi32(_mm_max_epi32(n, _mm_set1_epi32(1)), _mm_set1_epi32(3));
    __m128 f1 = _mm_sub_ps(one, _mm_sub_ps(x1, x1f)), f2 = _mm_sub_ps(one, _mm_sub_ps(x2c, x2));
    /* both axes' weights and sums in the lanes, pk_build's and pk_weight's operations:
     * 1 tap f1 + f2 - 1; 2 taps f1, f2 (sum f1 + f2); 3 taps f1, 1, f2 (sum (f1 + 1) + f2) */
    __m128 s12 = _mm_add_ps(f1, f2);
    __m128 w1 = _mm_sub_ps(s12, one);
    __m128 s3 = _mm_add_ps(_mm_add_ps(f1, one), f2);
    __m128 n1 = _mm_castsi128_ps(_mm_cmpeq_epi32(n, _mm_set1_epi32(1)));
    __m128 n3 = _mm_castsi128_ps(_mm_cmpeq_epi32(n, _mm_set1_epi32(3)));
    const __m128 z = _mm_setzero_ps();
    /* a zero weight at an end: the one weight (1 tap), else f1 or f2 */
    __m128 bad = _mm_or_ps(_mm_and_ps(n1, _mm_cmpeq_ps(w1, z)),
                           _mm_andnot_ps(n1, _mm_or_ps(_mm_cmpeq_ps(f1, z), _mm_cmpeq_ps(f2, z))));
    if (_mm_movemask_ps(bad) & 3)
        return 0;
    __m128 k0v = _mm_blendv_ps(f1, w1, n1);
    __m128 k1v = _mm_blendv_ps(f2, one, n3);
    __m128 sm = _mm_blendv_ps(_mm_blendv_ps(s12, s3, n3), w1, n1);
    __m128 k01 = _mm_unpacklo_ps(k0v, k1v); /* k0u k1u k0v k1v */
    _mm_storel_pi((__m64 *)(void *)ku, k01);
    _mm_storeh_pi((__m64 *)(void *)kv, k01);
    ku[2] = _mm_cvtss_f32(f2);
    kv[2] = _mm_cvtss_f32(_mm_shuffle_ps(f2, f2, 1));
    res[0] = _mm_cvtsi128_si32(r);
    res[1] = _mm_extract_epi32(r, 1);
    k0[0] = _mm_cvtsi128_si32(a);
    k0[1] = _mm_extract_epi32(a, 1);
    kw[0] = _mm_cvtsi128_si32(n);
    kw[1] = _mm_extract_epi32(n, 1);
    sum[0] = _mm_cvtss_f32(sm);
    sum[1] = _mm_cvtss_f32(_mm_shuffle_ps(sm, sm, 1));
    return 1;
}

/* Both axes of a width-4 kernel (lane 0 u, lane 1 v) whose widths are under 1/4
 * (width4_axis's first case), its arithmetic in its order: resolution, first texel, taps,
 * offset and step of the kernel's arguments. 0 when a width is 1/4 or more or an axis has
 * more than 8 taps. */
PF_TARGET int w4_axes(float u, float v, float uw, float vw, int fulog2, int fvlog2, int *res,
                      int *k0, int *kw, float *x1, float *step)
{
    const __m128i e127 = _mm_set1_epi32(127);
    __m128 x = _mm_setr_ps(u, v, 0.0f, 0.0f), w = _mm_setr_ps(uw, vw, 0.0f, 0.0f);
    __m128 lo = _mm_castsi128_ps(_mm_slli_epi32(
        _mm_sub_epi32(e127, _mm_setr_epi32(fulog2, fvlog2, 0, 0)), 23));
    w = _mm_max_ps(w, lo);                                    /* !(uw >= lo) -> lo */
    if (_mm_movemask_ps(_mm_cmpge_ps(w, _mm_set1_ps(.25f))) & 3)
        return 0;
    __m128i r = _mm_sub_epi32(e127, _mm_and_si128(_mm_srli_epi32(_mm_castps_si128(w), 23),
                                                  _mm_set1_epi32(0xff)));
    /* 2^res (res is 3..30 here: widths under 1/4, at least 2^-ulog2) */
    __m128 rf = _mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(r, e127), 23));
    __m128 upix = _mm_sub_ps(_mm_mul_ps(x, rf), _mm_set1_ps(0.5f));
    __m128 uwpix = _mm_mul_ps(w, rf);
    __m128 dupix = _mm_mul_ps(_mm_set1_ps(2.0f), uwpix);
    __m128i u1 = _mm_cvttps_epi32(_mm_ceil_ps(_mm_sub_ps(upix, dupix)));
    __m128i u2 = _mm_cvttps_epi32(_mm_ceil_ps(_mm_add_ps(upix, dupix)));
    __m128i n = _mm_sub_epi32(u2, u1);
    if (_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(n, _mm_set1_epi32(8)))) & 3)
        return 0;
    __m128 x1v = _mm_div_ps(_mm_sub_ps(_mm_cvtepi32_ps(u1), upix), uwpix);
    __m128 sv = _mm_div_ps(_mm_set1_ps(1.0f), uwpix);
    int R[4], A[4], N[4];
    float X[4], S[4];
    _mm_storeu_si128((__m128i *)(void *)R, r);
    _mm_storeu_si128((__m128i *)(void *)A, u1);
    _mm_storeu_si128((__m128i *)(void *)N, n);
    _mm_storeu_ps(X, x1v);
    _mm_storeu_ps(S, sv);
    for (int ax = 0; ax < 2; ax++) {
        res[ax] = R[ax];
        k0[ax] = A[ax];
        kw[ax] = N[ax];
        x1[ax] = X[ax];
        step[ax] = S[ax];
    }
    return 1;
}

/* The first and last nonzero of the n weights in w (n <= 8): strips the zeros as
 * pk_strip_zeros does, moving the rest to w[0]; 0 when every weight is 0. */
PF_TARGET int strip8(__m256 w, int n, float *out, int *k0, int *kw)
{
    unsigned m = (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(w, _mm256_setzero_ps(), _CMP_NEQ_UQ));
    m &= (1u << n) - 1u;
    if (!m)
        return 0;
    int a = __builtin_ctz(m), b = 31 - __builtin_clz(m);
    __m256i idx = _mm256_add_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
                                   _mm256_set1_epi32(a));
    _mm256_storeu_ps(out, _mm256_permutevar8x32_ps(w, idx));
    *k0 += a;
    *kw = b - a + 1;
    return 1;
}

/* pk_accumulate(w, n) (1 <= n <= 8; reads w[0 .. 4), and w[4 .. 8) when n > 4) in lane 0:
 * 0 + w[0] + w[1] + ... in order, in registers, the lanes past n cleared to +0 first (adding
 * +0 changes no sum: a running sum that starts at +0 is never -0). */
PF_TARGET __m128 sum_in_order(const float *w, int n)
{
    const __m128i idx = _mm_setr_epi32(0, 1, 2, 3);
    __m128i nn = _mm_set1_epi32(n);
    __m128 s = _mm_setzero_ps();
    for (int b = 0; b < 2; b++) {
        __m128 x = _mm_and_ps(_mm_loadu_ps(w + 4 * b),
                              _mm_castsi128_ps(_mm_cmpgt_epi32(nn, idx)));
        s = _mm_add_ss(s, x);
        s = _mm_add_ss(s, _mm_shuffle_ps(x, x, 1));
        s = _mm_add_ss(s, _mm_movehl_ps(x, x));
        s = _mm_add_ss(s, _mm_shuffle_ps(x, x, 3));
        if (n <= 4)
            break;
        nn = _mm_sub_epi32(nn, _mm_set1_epi32(4));
    }
    return s;
}

/* The kernel the fused path built, handed to the general path (weights at index 0). The
 * weights are copied as a fixed number of values (the loops were two memcpy calls): 3 per
 * axis for the box (box_axes writes ku[0 .. 3) and kv[0 .. 3), nu, nv <= 3), else 8 (strip8
 * writes 8, nu, nv <= 8); the values past nu and nv are never read. */
PF_TARGET int hand_over(pk *k, int ru, int rv, int u0, int v0, const float *ku, int nu,
                        const float *kv, int nv, int box)
{
    if (!k)
        return 0;
    k->ulog2 = ru;
    k->vlog2 = rv;
    k->u = u0;
    k->v = v0;
    k->uw = nu;
    k->vw = nv;
    k->ku0 = k->kv0 = k->rot = 0;
    if (box) {
        for (int i = 0; i < 3; i++) {
            k->kub[i] = ku[i];
            k->kvb[i] = kv[i];
        }
    } else {
        _mm256_storeu_ps(k->kub, _mm256_loadu_ps(ku));
        _mm256_storeu_ps(k->kvb, _mm256_loadu_ps(kv));
    }
    return 2;
}

PF_TARGET int fast_body(const pk_params *p, const uint8_t *const *px, int fulog2, int fvlog2,
                        float u, float v, float uw, float vw, float *out, pk *kout,
                        unsigned DT, unsigned NC)
{
    float ku[32], kv[8]; /* ku: window() may name up to 4 vectors of lanes (it reads < nu) */
    int ru, rv, u0, v0, nu, nv;
    float total;
    if (p->ftype == ST_FILTER_PTEX_BOX) {
        int res[2], k0[2], kw[2];
        float sum[2];
        if (!box_axes(u, v, uw, vw, fulog2, fvlog2, res, k0, kw, ku, kv, sum))
            return 0;
        ru = res[0], rv = res[1], u0 = k0[0], v0 = k0[1], nu = kw[0], nv = kw[1];
        if (u0 < 0 || v0 < 0 || u0 + nu > (1 << ru) || v0 + nv > (1 << rv))
            return hand_over(kout, ru, rv, u0, v0, ku, nu, kv, nv, 1);
        total = sum[0] * sum[1];
    } else {
        int res[2], k0[2], kw[2];
        float x1[2], st[2];
        const __m256 i0 = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
        __m256 wu, wv;
        if (!w4_axes(u, v, uw, vw, fulog2, fvlog2, res, k0, kw, x1, st)) {
            /* a width of 1/4 face or more (or more than 8 taps): eval builds it (building it
             * here and handing it over, tried, made black / clamp / quad gaussian and bicubic
             * 2x slower at footprints 4 and 16) */
            return 0;
        } else {
            ru = res[0], rv = res[1], u0 = k0[0], v0 = k0[1], nu = kw[0], nv = kw[1];
            if (nu <= 4 && nv <= 4) { /* both axes in one evaluation: u in lanes 0-3, v 4-7 */
                const __m256 i4 = _mm256_setr_ps(0, 1, 2, 3, 0, 1, 2, 3);
                __m256 x0 = _mm256_setr_m128(_mm_set1_ps(x1[0]), _mm_set1_ps(x1[1]));
                __m256 s8 = _mm256_setr_m128(_mm_set1_ps(st[0]), _mm_set1_ps(st[1]));
                wu = kernel8(p, _mm256_add_ps(x0, _mm256_mul_ps(i4, s8)));
                wv = _mm256_permute2f128_ps(wu, wu, 0x11); /* lanes 4-7 to 0-3 */
            } else {
                wu = kernel8(p, _mm256_add_ps(_mm256_set1_ps(x1[0]),
                                              _mm256_mul_ps(i0, _mm256_set1_ps(st[0]))));
                wv = kernel8(p, _mm256_add_ps(_mm256_set1_ps(x1[1]),
                                              _mm256_mul_ps(i0, _mm256_set1_ps(st[1]))));
            }
        }
        if (!strip8(wu, nu, ku, &u0, &nu) || !strip8(wv, nv, kv, &v0, &nv))
            return 0;
        if (u0 < 0 || v0 < 0 || u0 + nu > (1 << ru) || v0 + nv > (1 << rv))
            return hand_over(kout, ru, rv, u0, v0, ku, nu, kv, nv, 0);
        /* pk_weight: each axis summed in order */
        total = _mm_cvtss_f32(sum_in_order(ku, nu)) * _mm_cvtss_f32(sum_in_order(kv, nv));
    }
    if (!(total > 0.0f))
        return 0;
    int resu = 1 << ru;
    size_t ts = (size_t)NC << (DT == 0 ? 0 : DT == 3 ? 2 : 1);
    const uint8_t *d = px[(unsigned)ru * ((unsigned)fvlog2 + 1u) + (unsigned)rv];
    const uint8_t *base = d + ((size_t)v0 * (size_t)resu + (size_t)u0) * ts;
    size_t rowb = (size_t)resu * ts;
    __m128 acc = window_fused(base, rowb, DT, NC, ku, nu, kv, nv);
    float one = DT == 0 ? 255.0f : DT == 1 ? 65535.0f : 1.0f;
    put_scaled(out, acc, 1.0f / (total * one), NC);
    return 1;
}

/* fast_body out of line (pf_fgen_DT_NC): the box, and the width-4 kernels w4_body does not
 * take, so that w4_body's common case runs without fast_body's stack frame. */
#define PF_FGEN(DT, NC)                                                                     \
    __attribute__((target("avx2,fma,f16c"), noinline)) static int pf_fgen_##DT##_##NC(      \
        const pk_params *p, const uint8_t *const *px, int fu, int fv, float u, float v,     \
        float uw, float vw, float *out, pk *kout)                                           \
    {                                                                                       \
        return fast_body(p, px, fu, fv, u, v, uw, vw, out, kout, DT, NC);                   \
    }
#define PF_FGEN_NC(DT) PF_FGEN(DT, 1) PF_FGEN(DT, 2) PF_FGEN(DT, 3) PF_FGEN(DT, 4)
PF_FGEN_NC(0)
PF_FGEN_NC(1)
PF_FGEN_NC(2)
PF_FGEN_NC(3)

/* Lane j of a in every lane (j constant once the rows are unrolled: a shuffle). */
PF_TARGET __m256 bcast8(__m256 a, int j)
{
    return _mm256_set1_ps(a[j]);
}

/* The 1-channel window of w4_body: nv rows (NV, a constant) of nu <= 8 values, with
 * window4's (nu <= 4) or window's (NV = 1) operations in their order: each column summed
 * down the rows with one FMA a row (row j's weight lane j of kv), then the dot with the
 * column weights ku (zero past nu) and the fold, lane % 4, lane % 2, lanes 0 + 1, into +0.
 * Integer texels are finite, so the lanes past the row need no clearing: their column sums
 * meet a zero weight and give +0, as the cleared lanes do; half and float ones are cleared. */
#define PF_W4ROWS(NV)                                                                       \
    do {                                                                                    \
        _Pragma("GCC unroll 8") for (int j = 0; j < (NV); j++) {                            \
            const uint8_t *rp = base + (size_t)j * rowb;                                    \
            if (short4) {                                                                   \
                __m128 t = load4(rp, DT);                                                   \
                if (DT >= 2)                                                                \
                    t = _mm_and_ps(t, tail4);                                               \
                c4 = _mm_fmadd_ps(t, _mm256_castps256_ps128(bcast8(kv, j)), c4);            \
            } else {                                                                        \
                __m256 t = load8(rp, DT);                                                   \
                if (DT >= 2)                                                                \
                    t = _mm256_and_ps(t, tail8);                                            \
                c8 = _mm256_fmadd_ps(t, bcast8(kv, j), c8);                                 \
            }                                                                               \
        }                                                                                   \
    } while (0)

/* w4_tail's 1-channel window: nu, nv <= 8 taps from lane 0 of ku, kv (+0 past them), the
 * window's first texel at base, rows rowb bytes apart: PF_W4ROWS down the rows, then the
 * dot with the column weights and the fold (window4's operations for nu <= 4). */
PF_TARGET float w4_win1(const uint8_t *base, size_t rowb, __m256 ku, __m256 kv, int nu, int nv,
                        unsigned DT)
{
    const __m256i idx8 = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 z8 = _mm256_setzero_ps();
    int short4 = nu <= 4;
    __m128 tail4 = _mm_castsi128_ps(_mm_cmpgt_epi32(_mm_set1_epi32(nu), _mm_setr_epi32(0, 1, 2, 3)));
    __m256 tail8 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(nu), idx8));
    __m128 c4 = _mm_setzero_ps();
    __m256 c8 = _mm256_setzero_ps();
    switch (nv) {
    case 1: PF_W4ROWS(1); break;
    case 2: PF_W4ROWS(2); break;
    case 3: PF_W4ROWS(3); break;
    case 4: PF_W4ROWS(4); break;
    case 5: PF_W4ROWS(5); break;
    case 6: PF_W4ROWS(6); break;
    case 7: PF_W4ROWS(7); break;
    default: PF_W4ROWS(8); break;
    }
    const __m128 z = _mm_setzero_ps();
    __m128 q;
    if (short4)
        q = _mm_add_ps(_mm_fmadd_ps(c4, _mm256_castps256_ps128(ku), z), z);
    else {
        __m256 s8 = _mm256_fmadd_ps(c8, ku, z8);
        q = _mm_add_ps(_mm256_castps256_ps128(s8), _mm256_extractf128_ps(s8, 1));
    }
    __m128 h = _mm_add_ps(q, _mm_movehl_ps(q, q));
    __m128 res = _mm_add_ss(z, _mm_add_ss(h, _mm_movehdup_ps(h)));
    return _mm_cvtss_f32(res);
}

/* w4_body's second half: the taps ku, kv (from lane 0, +0 past nu, nv), their sums s
 * (lanes 0, 1), the window's first texel (u0, v0) at resolution (ru, rv). STRIP: strips
 * zero taps at the ends first (pk_strip_zeros, strip8) and tests the window against the
 * face itself; else outside says whether it overhangs. Hands the kernel over, declines, or
 * writes the NC values and returns 1, as fast_body. */
PF_TARGET int w4_tail(__m256 ku, __m256 kv, __m128 s, int nu, int nv, int u0, int v0, int ru,
                      int rv, const uint8_t *const *px, int fvlog2, float *out, pk *kout,
                      unsigned DT, unsigned NC, int STRIP, int outside)
{
    const __m256i idx8 = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 z8 = _mm256_setzero_ps();
    if (STRIP) { /* pk_strip_zeros (strip8): the zero taps at both ends of each axis */
        unsigned mu = (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(ku, z8, _CMP_NEQ_UQ)) &
                      ((1u << nu) - 1u);
        unsigned mv = (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(kv, z8, _CMP_NEQ_UQ)) &
                      ((1u << nv) - 1u);
        if (!mu || !mv)
            return 0;
        int au = __builtin_ctz(mu), av = __builtin_ctz(mv);
        int nu2 = 32 - __builtin_clz(mu) - au, nv2 = 32 - __builtin_clz(mv) - av;
        if (au || nu2 != nu) {
            ku = _mm256_and_ps(_mm256_permutevar8x32_ps(ku, _mm256_add_epi32(idx8, _mm256_set1_epi32(au))),
                               _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(nu2), idx8)));
            u0 += au;
            nu = nu2;
        }
        if (av || nv2 != nv) {
            kv = _mm256_and_ps(_mm256_permutevar8x32_ps(kv, _mm256_add_epi32(idx8, _mm256_set1_epi32(av))),
                               _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(nv2), idx8)));
            v0 += av;
            nv = nv2;
        }
        outside = u0 < 0 || v0 < 0 || u0 + nu > (1 << ru) || v0 + nv > (1 << rv);
    }
    if (outside) { /* handed over */
        if (!kout)
            return 0;
        float kub[8], kvb[8];
        _mm256_storeu_ps(kub, ku);
        _mm256_storeu_ps(kvb, kv);
        return hand_over(kout, ru, rv, u0, v0, kub, nu, kvb, nv, 0);
    }
    float total = _mm_cvtss_f32(_mm_mul_ss(s, _mm_movehdup_ps(s)));
    if (!(total > 0.0f))
        return 0;
    int resu = 1 << ru;
    size_t ts = (size_t)NC << (DT == 0 ? 0 : DT == 3 ? 2 : 1);
    const uint8_t *d = px[(unsigned)ru * ((unsigned)fvlog2 + 1u) + (unsigned)rv];
    const uint8_t *base = d + ((size_t)v0 * (size_t)resu + (size_t)u0) * ts;
    size_t rowb = (size_t)resu * ts;
    float one = DT == 0 ? 255.0f : DT == 1 ? 65535.0f : 1.0f;
    float scale = 1.0f / (total * one);
    if (NC == 1) {
        out[0] = w4_win1(base, rowb, ku, kv, nu, nv, DT) * scale;
        return 1;
    }
    float kub[32], kvb[8]; /* window() may name up to 4 vectors of lanes (it reads < nu) */
    _mm256_storeu_ps(kub, ku);
    _mm256_storeu_ps(kvb, kv);
    put_scaled(out, window_fused(base, rowb, DT, NC, kub, nu, kvb, nv), scale, NC);
    return 1;
}

/* w4_tail with the strip, out of line (pf_w4tail_DT_NC): a 4 x 4 kernel with a zero tap
 * (coherent queries on texel centres: bicubic taps at distance 2). */
#define PF_W4TAIL(DT, NC)                                                                   \
    __attribute__((target("avx2,fma,f16c"), noinline)) static int pf_w4tail_##DT##_##NC(   \
        __m256 ku, __m256 kv, __m128 s, int nu, int nv, int u0, int v0, int ru, int rv,    \
        const uint8_t *const *px, int fvlog2, float *out, pk *kout)                        \
    {                                                                                       \
        return w4_tail(ku, kv, s, nu, nv, u0, v0, ru, rv, px, fvlog2, out, kout, DT, NC, 1, \
                       0);                                                                  \
    }
#define PF_W4TAIL_NC(DT) PF_W4TAIL(DT, 1) PF_W4TAIL(DT, 2) PF_W4TAIL(DT, 3) PF_W4TAIL(DT, 4)
PF_W4TAIL_NC(0)
PF_W4TAIL_NC(1)
PF_W4TAIL_NC(2)
PF_W4TAIL_NC(3)

typedef int (*pf_w4tail_fn)(__m256 ku, __m256 kv, __m128 s, int nu, int nv, int u0, int v0,
                            int ru, int rv, const uint8_t *const *px, int fvlog2, float *out,
                            pk *kout);

/* The fused width-4 path's common case, in registers: both widths under 1/4 face, every tap
 * nonzero (nothing to strip), the window inside the face or handed over whole. The same
 * arithmetic as w4_axes, kernel8, strip8 (a no-op here), sum_in_order and window in their
 * order, so bit for bit fast_body; anything else goes to fast_body (gen, out of line).
 * A width-4 axis has 4 to 8 taps: its width in texels of the resolution chosen (uwpix) lies
 * in [1, 2), so 4 uwpix rounds out to 4..8 taps; 4 each way (uwpix 1: a power-of-two width,
 * or the width clamped to a texel) is the case WIDE = 0 takes with the shape as constants
 * (one 8-lane kernel evaluation, u in lanes 0-3, v in 4-7); the others go to the WIDE = 1
 * instance (wide, out of line, so that its registers cost the common case nothing). */
PF_TARGET int w4_body(const pk_params *p, const uint8_t *const *px, int fulog2, int fvlog2,
                      float u, float v, float uw, float vw, float *out, pk *kout,
                      unsigned DT, unsigned NC, int WIDE, pf_fast_fn gen, pf_fast_fn wide,
                      pf_w4tail_fn strip)
{
    const __m128i e127 = _mm_set1_epi32(127);
    __m128 x = _mm_setr_ps(u, v, 0.0f, 0.0f), w = _mm_setr_ps(uw, vw, 0.0f, 0.0f);
    __m128 lo = _mm_castsi128_ps(_mm_slli_epi32(
        _mm_sub_epi32(e127, _mm_setr_epi32(fulog2, fvlog2, 0, 0)), 23));
    w = _mm_max_ps(w, lo);
    if (_mm_movemask_ps(_mm_cmpge_ps(w, _mm_set1_ps(.25f))) & 3)
        return 0;
    __m128i r = _mm_sub_epi32(e127, _mm_and_si128(_mm_srli_epi32(_mm_castps_si128(w), 23),
                                                  _mm_set1_epi32(0xff)));
    __m128 rf = _mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(r, e127), 23));
    __m128 upix = _mm_sub_ps(_mm_mul_ps(x, rf), _mm_set1_ps(0.5f));
    __m128 uwpix = _mm_mul_ps(w, rf);
    __m128 dupix = _mm_mul_ps(_mm_set1_ps(2.0f), uwpix);
    __m128i u1 = _mm_cvttps_epi32(_mm_ceil_ps(_mm_sub_ps(upix, dupix)));
    __m128i u2 = _mm_cvttps_epi32(_mm_ceil_ps(_mm_add_ps(upix, dupix)));
    __m128i n = _mm_sub_epi32(u2, u1);
    int nu = 4, nv = 4;
    if (!WIDE) {
        if ((_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(n, _mm_set1_epi32(4)))) & 3) != 3)
            return wide(p, px, fulog2, fvlog2, u, v, uw, vw, out, kout);
    } else {
        nu = _mm_cvtsi128_si32(n), nv = _mm_extract_epi32(n, 1);
        if (nu < 1 || nu > 8 || nv < 1 || nv > 8)
            return gen(p, px, fulog2, fvlog2, u, v, uw, vw, out, kout);
    }
    __m128 x1v = _mm_div_ps(_mm_sub_ps(_mm_cvtepi32_ps(u1), upix), uwpix);
    __m128 sv = _mm_div_ps(_mm_set1_ps(1.0f), uwpix);
    const __m256i idx8 = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 z8 = _mm256_setzero_ps();
    __m256 ku, kv; /* taps in lanes from 0, +0 past the last */
    __m128 s;      /* the axis sums in lanes 0 (u) and 1 (v) */
    if (!WIDE) {   /* both axes in one evaluation: u in lanes 0-3, v 4-7 */
        const __m256 i4 = _mm256_setr_ps(0, 1, 2, 3, 0, 1, 2, 3);
        const __m256i sel = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1);
        __m256 x0 = _mm256_permutevar8x32_ps(_mm256_castps128_ps256(x1v), sel);
        __m256 s8 = _mm256_permutevar8x32_ps(_mm256_castps128_ps256(sv), sel);
        __m256 k = kernel8(p, _mm256_add_ps(x0, _mm256_mul_ps(i4, s8)));
        int zero = _mm256_movemask_ps(_mm256_cmp_ps(k, z8, _CMP_EQ_OQ));
        /* sum_in_order of each axis, both at once: lanes (u_i, v_i) added in i's order */
        __m128 a = _mm256_castps256_ps128(k), b = _mm256_extractf128_ps(k, 1);
        __m128 t0 = _mm_unpacklo_ps(a, b), t1 = _mm_unpackhi_ps(a, b);
        s = _mm_add_ps(_mm_setzero_ps(), t0);
        s = _mm_add_ps(s, _mm_movehl_ps(t0, t0));
        s = _mm_add_ps(s, t1);
        s = _mm_add_ps(s, _mm_movehl_ps(t1, t1));
        ku = _mm256_zextps128_ps256(a);
        kv = _mm256_zextps128_ps256(b);
        if (zero) /* a zero tap (+0 or -0; NaN is not: strip8's compare): stripped */
            return strip(ku, kv, s, 4, 4, _mm_cvtsi128_si32(u1), _mm_extract_epi32(u1, 1),
                         _mm_cvtsi128_si32(r), _mm_extract_epi32(r, 1), px, fvlog2, out,
                         kout);
    } else {
        const __m256 i0 = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
        ku = kernel8(p, _mm256_add_ps(_mm256_set1_ps(_mm_cvtss_f32(x1v)),
                                      _mm256_mul_ps(i0, _mm256_set1_ps(_mm_cvtss_f32(sv)))));
        kv = kernel8(p, _mm256_add_ps(
                            _mm256_set1_ps(_mm_cvtss_f32(_mm_movehdup_ps(x1v))),
                            _mm256_mul_ps(i0, _mm256_set1_ps(_mm_cvtss_f32(_mm_movehdup_ps(sv))))));
        __m256 lu = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(nu), idx8));
        __m256 lv = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(nv), idx8));
        ku = _mm256_and_ps(ku, lu);
        kv = _mm256_and_ps(kv, lv);
        /* the sums below run over the taps before stripping: the zeros stripped lie before
         * the first nonzero tap (+0 + ±0 is +0) or after the last (s + ±0 is s for s not
         * -0), so they are strip8's sums */
        __m256 t0 = _mm256_unpacklo_ps(ku, kv), t1 = _mm256_unpackhi_ps(ku, kv);
        __m128 a0 = _mm256_castps256_ps128(t0), a1 = _mm256_castps256_ps128(t1);
        __m128 b0 = _mm256_extractf128_ps(t0, 1), b1 = _mm256_extractf128_ps(t1, 1);
        s = _mm_add_ps(_mm_setzero_ps(), a0);
        s = _mm_add_ps(s, _mm_movehl_ps(a0, a0));
        s = _mm_add_ps(s, a1);
        s = _mm_add_ps(s, _mm_movehl_ps(a1, a1));
        s = _mm_add_ps(s, b0);
        s = _mm_add_ps(s, _mm_movehl_ps(b0, b0));
        s = _mm_add_ps(s, b1);
        s = _mm_add_ps(s, _mm_movehl_ps(b1, b1));
    }
    int ru = _mm_cvtsi128_si32(r), rv = _mm_extract_epi32(r, 1);
    int u0 = _mm_cvtsi128_si32(u1), v0 = _mm_extract_epi32(u1, 1);
    if (WIDE)
        return w4_tail(ku, kv, s, nu, nv, u0, v0, ru, rv, px, fvlog2, out, kout, DT, NC, 1,
                       0);
    /* the window inside the face (first texel >= 0, last < 2^res) */
    __m128i lim = _mm_sllv_epi32(_mm_set1_epi32(1), r);
    __m128i out_of = _mm_or_si128(_mm_cmpgt_epi32(_mm_setzero_si128(), u1),
                                  _mm_cmpgt_epi32(u2, lim));
    return w4_tail(ku, kv, s, 4, 4, u0, v0, ru, rv, px, fvlog2, out, kout, DT, NC, 0,
                   _mm_movemask_ps(_mm_castsi128_ps(out_of)) & 3);
}

#define PF_FAST(DT, NC)                                                                     \
    __attribute__((target("avx2,fma,f16c"), noinline)) static int pf_w4wide_##DT##_##NC(   \
        const pk_params *p, const uint8_t *const *px, int fu, int fv, float u, float v,     \
        float uw, float vw, float *out, pk *kout)                                           \
    {                                                                                       \
        return w4_body(p, px, fu, fv, u, v, uw, vw, out, kout, DT, NC, 1,                   \
                       pf_fgen_##DT##_##NC, NULL, NULL);                                    \
    }                                                                                       \
    __attribute__((target("avx2,fma,f16c"))) static int pf_fast_##DT##_##NC(                \
        const pk_params *p, const uint8_t *const *px, int fu, int fv, float u, float v,     \
        float uw, float vw, float *out, pk *kout)                                           \
    {                                                                                       \
        return w4_body(p, px, fu, fv, u, v, uw, vw, out, kout, DT, NC, 0,                   \
                       pf_fgen_##DT##_##NC, pf_w4wide_##DT##_##NC, pf_w4tail_##DT##_##NC);  \
    }
#define PF_FAST_NC(DT) PF_FAST(DT, 1) PF_FAST(DT, 2) PF_FAST(DT, 3) PF_FAST(DT, 4)
PF_FAST_NC(0)
PF_FAST_NC(1)
PF_FAST_NC(2)
PF_FAST_NC(3)

/* ---- the width-4 filters' common case, 8 queries at a time (pf_w4x8_select) ------------ */

/* The even (0, 2, 4, 6) and odd (1, 3, 5, 7) 32-bit lanes of v as 64-bit lanes, zero-extended. */
PF_TARGET __m256i even64(__m256i v)
{
    return _mm256_and_si256(v, _mm256_set1_epi64x(0xffffffffLL));
}
PF_TARGET __m256i odd64(__m256i v)
{
    return _mm256_srli_epi64(v, 32);
}

/* One axis of w4_body's set-up for 8 queries, lane by lane its operations in its order: x
 * the coordinates, bw the widths, lg the faces' log2 sizes. Sets the resolution r, the first
 * texel u1, the first tap's position x1 and the step st, and the lanes whose window
 * overhangs the face (outside); returns the lanes of w4_body's common case along this axis:
 * width under 1/4 (after the clamp to a texel) and 4 taps. */
PF_TARGET __m256i w4x8_axis(__m256 x, __m256 bw, __m256i lg, __m256i *r, __m256i *u1o,
                            __m256 *x1, __m256 *st, __m256i *outside)
{
    const __m256i e127 = _mm256_set1_epi32(127);
    __m256 lo = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_sub_epi32(e127, lg), 23));
    __m256 w = _mm256_max_ps(bw, lo);
    __m256i ok = _mm256_castps_si256(_mm256_cmp_ps(w, _mm256_set1_ps(.25f), _CMP_NGE_UQ));
    __m256i rr = _mm256_sub_epi32(e127, _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(w), 23),
                                                         _mm256_set1_epi32(0xff)));
    __m256 rf = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(rr, e127), 23));
    __m256 upix = _mm256_sub_ps(_mm256_mul_ps(x, rf), _mm256_set1_ps(0.5f));
    __m256 uwpix = _mm256_mul_ps(w, rf);
    __m256 dupix = _mm256_mul_ps(_mm256_set1_ps(2.0f), uwpix);
    __m256i u1 = _mm256_cvttps_epi32(_mm256_ceil_ps(_mm256_sub_ps(upix, dupix)));
    __m256i u2 = _mm256_cvttps_epi32(_mm256_ceil_ps(_mm256_add_ps(upix, dupix)));
    ok = _mm256_and_si256(ok, _mm256_cmpeq_epi32(_mm256_sub_epi32(u2, u1), _mm256_set1_epi32(4)));
    /* inside: u1 >= 0, u2 <= 2^r */
    __m256i lim = _mm256_sllv_epi32(_mm256_set1_epi32(1), rr);
    *outside = _mm256_or_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), u1),
                               _mm256_cmpgt_epi32(u2, lim));
    *x1 = _mm256_div_ps(_mm256_sub_ps(_mm256_cvtepi32_ps(u1), upix), uwpix);
    *st = _mm256_div_ps(_mm256_set1_ps(1.0f), uwpix);
    *r = rr;
    *u1o = u1;
    return ok;
}

/* Tap t of 8 queries (x1 + t * st, kernel8's function), stored to k; *sum += it, and *z the
 * lanes where it is zero (+0 or -0; not NaN: strip8's compare), which w4_tail strips when
 * they lie at an end of the axis (w4x8_ends). The gaussian's taps that count are never zero:
 * *z is left alone for it. */
PF_TARGET __m256 w4x8_tap(const pk_params *p, __m256 x1, __m256 st, int t, float *k,
                          __m256 *sum, __m256i *z, int G)
{
    /* The lanes that count (w4x8_axis' common case) have a step st = 1 / uwpix in (1/2, 1]
     * and x1 in [-2, -1], so |x| <= 2: tap 0 is x1 itself (x1 + 0 st differs from it only
     * in the sign of a zero, which x * x and |x| drop); the gaussian's clamp of its exponent
     * to -126 never applies (it is above -12), and (x x) -2 log2(e), whose product by -2 is
     * exact, is x x times the float -2 log2(e) (twice 1.44269504f, exact): the same
     * roundings, so kernel8's weights bit for bit. The other lanes' weights are not used. */
    __m256 x = t ? _mm256_add_ps(x1, _mm256_mul_ps(_mm256_set1_ps((float)t), st)) : x1;
    __m256 w;
    if (G) { /* 2^y for y >= -12 is never 0: the gaussian's taps that count are not zero */
        __m256 y = _mm256_mul_ps(_mm256_mul_ps(x, x), _mm256_set1_ps(-2.0f * 1.44269504f));
        w = exp2_8(y);
    } else {
        w = kernel8_as(p, x, 0);
        *z = _mm256_castps_si256(_mm256_cmp_ps(w, _mm256_setzero_ps(), _CMP_EQ_OQ));
    }
    *sum = _mm256_add_ps(*sum, w);
    _mm256_storeu_ps(k, w);
    return w;
}

/* w4_tail's strip of one axis (pk_strip_zeros), lane by lane: z[t] the lanes whose tap t is
 * zero. Sets *lead, the zero taps before the first nonzero one (0..3), and *n, the taps from
 * it to the last nonzero one (1..4; interior zeros kept, as strip8 keeps them); returns the
 * lanes whose 4 taps are all zero (w4_tail declines those). */
PF_TARGET __m256i w4x8_ends(const __m256i *z, __m256i *lead, __m256i *n)
{
    __m256i z01 = _mm256_and_si256(z[0], z[1]), z012 = _mm256_and_si256(z01, z[2]);
    __m256i z32 = _mm256_and_si256(z[3], z[2]), z321 = _mm256_and_si256(z32, z[1]);
    /* the masks are -1 where set: minus their sums count the zeros at each end */
    __m256i a = _mm256_add_epi32(_mm256_add_epi32(z[0], z01), z012); /* -lead */
    __m256i b = _mm256_add_epi32(_mm256_add_epi32(z[3], z32), z321); /* -trail */
    *lead = _mm256_sub_epi32(_mm256_setzero_si256(), a);
    *n = _mm256_add_epi32(_mm256_set1_epi32(4), _mm256_add_epi32(a, b));
    return _mm256_and_si256(z012, z[3]);
}

/* The taps tk[0..3] of each lane moved lead lanes down (tap lead to 0: w4_tail's permute by
 * the leading zeros), and every tap from n on made +0 (w4_tail's mask of the lanes past the
 * stripped length): lanes with lead 0 and n 4 are left as they are. */
PF_TARGET void w4x8_shift(float (*tk)[8], __m256i lead, __m256i n)
{
    __m256 k0 = _mm256_loadu_ps(tk[0]), k1 = _mm256_loadu_ps(tk[1]);
    __m256 k2 = _mm256_loadu_ps(tk[2]), k3 = _mm256_loadu_ps(tk[3]);
    const __m256i one = _mm256_set1_epi32(1), two = _mm256_set1_epi32(2);
    __m256 m1 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(lead, one), one));
    __m256 m2 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(lead, two), two));
    /* by 1 where lead is odd, then by 2 where lead is 2 or 3 */
    k0 = _mm256_blendv_ps(k0, k1, m1);
    k1 = _mm256_blendv_ps(k1, k2, m1);
    k2 = _mm256_blendv_ps(k2, k3, m1);
    k3 = _mm256_andnot_ps(m1, k3);
    k0 = _mm256_blendv_ps(k0, k2, m2);
    k1 = _mm256_blendv_ps(k1, k3, m2);
    k2 = _mm256_andnot_ps(m2, k2);
    k3 = _mm256_andnot_ps(m2, k3);
    /* +0 from tap n on (n >= 1 in every lane that counts) */
    k1 = _mm256_and_ps(k1, _mm256_castsi256_ps(_mm256_cmpgt_epi32(n, one)));
    k2 = _mm256_and_ps(k2, _mm256_castsi256_ps(_mm256_cmpgt_epi32(n, two)));
    k3 = _mm256_and_ps(k3, _mm256_castsi256_ps(_mm256_cmpgt_epi32(n, _mm256_set1_epi32(3))));
    _mm256_storeu_ps(tk[0], k0);
    _mm256_storeu_ps(tk[1], k1);
    _mm256_storeu_ps(tk[2], k2);
    _mm256_storeu_ps(tk[3], k3);
}

/* w4_tail's test after a strip along one axis: the window of n taps from u0 overhangs the
 * face (u0 < 0 or past 2^r). */
PF_TARGET __m256i w4x8_over(__m256i u0, __m256i n, __m256i r)
{
    __m256i end = _mm256_add_epi32(u0, n);
    return _mm256_or_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), u0),
                           _mm256_cmpgt_epi32(end, _mm256_sllv_epi32(_mm256_set1_epi32(1), r)));
}

/* The first NCOL (<= 4) texels of one window row of 8 queries, type DT (u8 or u16), 1
 * channel, as floats per column: ae, ao the rows' addresses of the even and odd queries
 * (64-bit lanes), me, mo their gather masks (sign bits; a lane masked off gives 0). Reads 8
 * bytes a row (past a u8 row, or past a row of fewer than 4 u16 texels: the arenas'
 * slack). */
PF_TARGET void w4x8_row(__m256i ae, __m256i ao, __m256i me, __m256i mo, unsigned DT,
                        __m256 *t, int NCOL)
{
    const __m256i z = _mm256_setzero_si256();
    __m256i ge = _mm256_mask_i64gather_epi64(z, (const long long *)0, ae, me, 1);
    __m256i go = _mm256_mask_i64gather_epi64(z, (const long long *)0, ao, mo, 1);
    /* the first dword of each query's qword in query order: [q0 q1 q2 q3 | q4 q5 q6 q7]
     * (the 4 u8 texels, or the first 2 u16); x2 the second (the next 2 u16) */
    __m256i lo = _mm256_unpacklo_epi32(ge, go), hi = _mm256_unpackhi_epi32(ge, go);
    __m256i x = _mm256_unpacklo_epi64(lo, hi);
    if (DT == 0) {
        const __m256i ff = _mm256_set1_epi32(0xff);
        _Pragma("GCC unroll 4") for (int i = 0; i < NCOL; i++) {
            __m256i c = i ? _mm256_srli_epi32(x, 8 * i) : x;
            t[i] = _mm256_cvtepi32_ps(i < 3 ? _mm256_and_si256(c, ff) : c);
        }
    } else {
        const __m256i ffff = _mm256_set1_epi32(0xffff);
        __m256i x2 = NCOL > 2 ? _mm256_unpackhi_epi64(lo, hi) : x;
        _Pragma("GCC unroll 4") for (int i = 0; i < NCOL; i++) {
            __m256i d = i < 2 ? x : x2;
            t[i] = _mm256_cvtepi32_ps(i & 1 ? _mm256_srli_epi32(d, 16) : _mm256_and_si256(d, ffff));
        }
    }
}

/* The level's data of 8 queries: px[ru * (fvlog2 + 1) + rv] of each face's row (k->px[j]),
 * gathered for the lanes whose sign bit is set in me (even queries, 64-bit lanes) and mo
 * (odd), into *de and *dof (0 for the others). */
PF_TARGET void w4x8_data(const pf_klanes *k, __m256i ru, __m256i rv, __m256i lv, __m256i me,
                         __m256i mo, __m256i *de, __m256i *dof)
{
    __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(ru, _mm256_add_epi32(lv, _mm256_set1_epi32(1))), rv);
    __m256i p0 = _mm256_loadu_si256((const __m256i *)(const void *)&k->px[0]);
    __m256i p1 = _mm256_loadu_si256((const __m256i *)(const void *)&k->px[4]);
    __m256i pe = _mm256_permute4x64_epi64(_mm256_unpacklo_epi64(p0, p1), 0xD8);
    __m256i po = _mm256_permute4x64_epi64(_mm256_unpackhi_epi64(p0, p1), 0xD8);
    const __m256i z = _mm256_setzero_si256();
    *de = _mm256_mask_i64gather_epi64(
        z, (const long long *)0, _mm256_add_epi64(pe, _mm256_slli_epi64(even64(idx), 3)), me, 1);
    *dof = _mm256_mask_i64gather_epi64(
        z, (const long long *)0, _mm256_add_epi64(po, _mm256_slli_epi64(odd64(idx), 3)), mo, 1);
}

/* A handed-over kernel's resolution (ulog2, vlog2) and first texel (u, v). */
PF_TARGET void pk_origin(pk *kj, int ulog2, int vlog2, int u, int v)
{
    kj->ulog2 = ulog2;
    kj->vlog2 = vlog2;
    kj->u = u;
    kj->v = v;
}

/* The 4 taps of 8 lanes (k[t]: tap t of each lane) stored lane by lane: lane j's at 4 j. */
PF_TARGET void w4x8_bylane(const __m256 *k, float *out)
{
    __m256 a0 = _mm256_unpacklo_ps(k[0], k[1]), a1 = _mm256_unpackhi_ps(k[0], k[1]);
    __m256 a2 = _mm256_unpacklo_ps(k[2], k[3]), a3 = _mm256_unpackhi_ps(k[2], k[3]);
    __m256 r0 = _mm256_shuffle_ps(a0, a2, 0x44), r1 = _mm256_shuffle_ps(a0, a2, 0xEE);
    __m256 r2 = _mm256_shuffle_ps(a1, a3, 0x44), r3 = _mm256_shuffle_ps(a1, a3, 0xEE);
    /* r_i holds lanes i (low half) and i + 4 (high half) */
    _mm256_storeu_ps(out + 0, _mm256_permute2f128_ps(r0, r1, 0x20));
    _mm256_storeu_ps(out + 8, _mm256_permute2f128_ps(r2, r3, 0x20));
    _mm256_storeu_ps(out + 16, _mm256_permute2f128_ps(r0, r1, 0x31));
    _mm256_storeu_ps(out + 24, _mm256_permute2f128_ps(r2, r3, 0x31));
}

/* The first texel's address (v0 2^r + u0) << sh past the level's data (de, dof: the even and
 * odd queries' 64-bit lanes), and the row length 2^r << sh (resu: 2^r), of 1-channel
 * texels of 1 << sh bytes: *ae, *ao and *re, *ro. */
PF_TARGET void w4x8_rows(__m256i de, __m256i dof, __m256i u0, __m256i v0, __m256i resu, int sh,
                         __m256i *ae, __m256i *ao, __m256i *re, __m256i *ro)
{
    *ae = _mm256_add_epi64(
        de, _mm256_slli_epi64(_mm256_add_epi64(_mm256_mul_epu32(v0, resu), even64(u0)), sh));
    *ao = _mm256_add_epi64(
        dof, _mm256_slli_epi64(_mm256_add_epi64(_mm256_mul_epu32(odd64(v0), odd64(resu)),
                                                odd64(u0)), sh));
    *re = _mm256_slli_epi64(even64(resu), sh);
    *ro = _mm256_slli_epi64(odd64(resu), sh);
}

/* The lanes of ok whose window overhangs the face (out_of) handed over as w4_tail hands
 * them over (hand_over): kout[j] the 4 x 4 kernel (resolution r, first texel (u0, v0), the
 * taps tu[t][j], tv[t][j]), wout[j] its weight (total). Returns their mask. With 3 lanes or
 * more the 4 ints and the taps of every lane are transposed at once (w4x8_bylane), each lane
 * then a few 16-byte copies; with fewer, lane by lane from the vectors' lanes. */
PF_TARGET unsigned w4x8_hand(__m256i ok, __m256i out_of, __m256 total, __m256i ru, __m256i rv,
                             __m256i u0, __m256i v0, const float (*tu)[8], const float (*tv)[8], pk *kout,
                             float *wout)
{
    unsigned ho = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(ok, out_of)));
    if (!ho)
        return 0;
    _mm256_storeu_ps(wout, total);
    _Static_assert(offsetof(pk, vlog2) == 4 && offsetof(pk, u) == 8 && offsetof(pk, v) == 12 &&
                       offsetof(pk, uw) == 16 && offsetof(pk, kv0) == 28 &&
                       offsetof(pk, rot) == 32 && PK_MAX >= 8,
                   "pk: ulog2 vlog2 u v, then uw vw ku0 kv0, rot");
    const __m128i shape = _mm_setr_epi32(4, 4, 0, 0); /* uw, vw, ku0, kv0 */
    if (pf_bits_atleast(ho, 3)) {
        float KU[32], KV[32], RO[32]; /* lane j's at 4 j */
        __m256 ro[4] = {_mm256_castsi256_ps(ru), _mm256_castsi256_ps(rv),
                        _mm256_castsi256_ps(u0), _mm256_castsi256_ps(v0)};
        __m256 ku[4] = {_mm256_loadu_ps(tu[0]), _mm256_loadu_ps(tu[1]), _mm256_loadu_ps(tu[2]),
                        _mm256_loadu_ps(tu[3])};
        __m256 kv[4] = {_mm256_loadu_ps(tv[0]), _mm256_loadu_ps(tv[1]), _mm256_loadu_ps(tv[2]),
                        _mm256_loadu_ps(tv[3])};
        w4x8_bylane(ro, RO);
        w4x8_bylane(ku, KU);
        w4x8_bylane(kv, KV);
        for (unsigned m = ho; m; m &= m - 1) {
            size_t j = (size_t)__builtin_ctz(m);
            pk *kj = kout + j;
            _mm_storeu_ps((float *)(void *)kj, _mm_loadu_ps(RO + 4 * j));
            _mm_storeu_si128((__m128i *)(void *)&kj->uw, shape);
            kj->rot = 0;
            _mm256_storeu_ps(kj->kub, _mm256_zextps128_ps256(_mm_loadu_ps(KU + 4 * j)));
            _mm256_storeu_ps(kj->kvb, _mm256_zextps128_ps256(_mm_loadu_ps(KV + 4 * j)));
        }
        return ho;
    }
    int R[2][8], O[2][8];
    _mm256_storeu_si256((__m256i *)(void *)R[0], ru);
    _mm256_storeu_si256((__m256i *)(void *)R[1], rv);
    _mm256_storeu_si256((__m256i *)(void *)O[0], u0);
    _mm256_storeu_si256((__m256i *)(void *)O[1], v0);
    for (unsigned m = ho; m; m &= m - 1) {
        int j = __builtin_ctz(m);
        pk *kj = kout + j;
        pk_origin(kj, R[0][j], R[1][j], O[0][j], O[1][j]);
        _mm_storeu_si128((__m128i *)(void *)&kj->uw, shape);
        kj->rot = 0;
        _mm256_storeu_ps(kj->kub, _mm256_setr_ps(tu[0][j], tu[1][j], tu[2][j], tu[3][j],
                                                 0.0f, 0.0f, 0.0f, 0.0f));
        _mm256_storeu_ps(kj->kvb, _mm256_setr_ps(tv[0][j], tv[1][j], tv[2][j], tv[3][j],
                                                 0.0f, 0.0f, 0.0f, 0.0f));
    }
    return ho;
}

/* Both axes of a block's queries (w4x8_axis on u and on v), the log2 v resolutions kept for the
 * texel addresses; returns the lanes klanes8 marked fast whose 4 x 4 taps lie inside the face. */
typedef struct {
    __m256i ru, rv, u0, v0, ou, ov, lv;
    __m256 xu, stu, xv, stv;
} w4x8_ax;

PF_TARGET __m256i w4x8_axes(const pf_klanes *k, w4x8_ax *a)
{
    const __m256i one = _mm256_set1_epi32(1);
    __m256i fast = _mm256_cmpgt_epi32(
        _mm256_and_si256(_mm256_srlv_epi32(_mm256_set1_epi32((int)k->fast),
                                           _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)), one),
        _mm256_setzero_si256());
    __m256i lu = _mm256_loadu_si256((const __m256i *)(const void *)k->ulog2);
    a->lv = _mm256_loadu_si256((const __m256i *)(const void *)k->vlog2);
    __m256i ok = _mm256_and_si256(fast, w4x8_axis(_mm256_loadu_ps(k->u), _mm256_loadu_ps(k->bu), lu,
                                                  &a->ru, &a->u0, &a->xu, &a->stu, &a->ou));
    return _mm256_and_si256(ok, w4x8_axis(_mm256_loadu_ps(k->v), _mm256_loadu_ps(k->bv), a->lv,
                                          &a->rv, &a->v0, &a->xv, &a->stv, &a->ov));
}

/* The strip of both axes of the lanes of *ok with a zero tap at an end (w4_tail's, above):
 * zu, zv the zero taps (w4x8_tap), tu, tv the taps, moved in place (w4x8_shift); the
 * window's first texel (a->u0, a->v0) moved on by the leading zeros and the overhang test
 * (a->ou, a->ov) redone on the stripped lengths, which go to *nu, *nv (4 in the other
 * lanes). Lanes with every tap of an axis zero are cleared from *ok (w4_tail declines them).
 * Returns the lanes of *ok stripped (a zero at an end of either axis). */
PF_TARGET __m256i w4x8_strip(float (*tu)[8], float (*tv)[8], const __m256i *zu,
                             const __m256i *zv, w4x8_ax *a, __m256i *ok, __m256i *nu,
                             __m256i *nv)
{
    __m256i au, av;
    __m256i dead = _mm256_or_si256(w4x8_ends(zu, &au, nu), w4x8_ends(zv, &av, nv));
    *ok = _mm256_andnot_si256(dead, *ok);
    w4x8_shift(tu, au, *nu);
    w4x8_shift(tv, av, *nv);
    a->u0 = _mm256_add_epi32(a->u0, au);
    a->v0 = _mm256_add_epi32(a->v0, av);
    a->ou = w4x8_over(a->u0, *nu, a->ru);
    a->ov = w4x8_over(a->v0, *nv, a->rv);
    __m256i ends = _mm256_or_si256(_mm256_or_si256(zu[0], zu[3]), _mm256_or_si256(zv[0], zv[3]));
    return _mm256_and_si256(ends, *ok);
}

/* 8 queries of a width-4 filter on 1-channel u8 or u16 texels (DT), the block's set-up k
 * (klanes8): the lanes of k->fast that w4_body would serve in its common case (4 x 4 taps,
 * none zero, the window inside the face, total weight > 0), or with w4_tail's strip of the
 * zero taps at either end of an axis (w4x8_strip: the window after it inside the face), get
 * w4_body's result, lane by
 * lane its operations in its order, so bit for bit; out[j] for those lanes j written, their
 * mask returned. The lanes of that case but for a window that overhangs the face get the
 * kernel w4_body hands over in kout[j] and its weight in wout[j], their mask in *over. The other lanes are left alone
 * (the caller serves them one by one). Queries are even/odd-split for the 64-bit address
 * arithmetic and gathers; the 16 texels of a query's window are 4 row gathers of 8 bytes.
 * The 8 taps come first, each stored (the hand-over reads them); the window's rows and
 * its dot then take them from memory (FMA operands), so that few vectors are live across
 * the gathers. */
PF_TARGET unsigned w4x8_body(const pk_params *p, const pf_klanes *k, float *out, pk *kout,
                             float *wout, unsigned *over, unsigned DT, int G)
{
    const __m256i one = _mm256_set1_epi32(1);
    w4x8_ax a;
    __m256i ok = w4x8_axes(k, &a);
    if (_mm256_testz_si256(ok, ok))
        return *over = 0;
    float tu[4][8], tv[4][8]; /* the taps: the window's, and the kernels handed over */
    __m256 sv = _mm256_setzero_ps(), su = _mm256_setzero_ps();
    __m256i zu[4], zv[4]; /* the lanes whose tap t is zero */
    _Pragma("GCC unroll 4") for (int t = 0; t < 4; t++)
        w4x8_tap(p, a.xv, a.stv, t, tv[t], &sv, &zv[t], G);
    _Pragma("GCC unroll 4") for (int t = 0; t < 4; t++)
        w4x8_tap(p, a.xu, a.stu, t, tu[t], &su, &zu[t], G);
    /* the weight su sv (pk_weight's (0 + k0 + .. + k3) (0 + ..)) */
    __m256 total = _mm256_mul_ps(su, sv);
    __m256i hand = ok, nv = _mm256_set1_epi32(4); /* nv: the rows of each lane's window */
    if (!G) {
        __m256i ends = _mm256_or_si256(_mm256_or_si256(zu[0], zu[3]),
                                       _mm256_or_si256(zv[0], zv[3]));
        if (!_mm256_testz_si256(ends, ok)) {
            /* a zero tap at an end (on or near a texel centre: the bicubic family's tap at
             * distance 2, Catmull-Rom's at 1 too): w4_tail strips the zeros at both ends,
             * the window moved on by the leading ones, and tests it against the face
             * again; of those, the ones still overhanging are left to the per-query path
             * (not handed over) */
            __m256i nu;
            __m256i strip = w4x8_strip(tu, tv, zu, zv, &a, &ok, &nu, &nv);
            hand = _mm256_andnot_si256(strip, ok);
        }
    }
    /* the window overhangs the face: handed over (w4_tail's hand_over) */
    __m256i out_of = _mm256_or_si256(a.ou, a.ov);
    *over = w4x8_hand(hand, out_of, total, a.ru, a.rv, a.u0, a.v0, tu, tv, kout, wout);
    const __m256 zf = _mm256_setzero_ps();
    ok = _mm256_andnot_si256(out_of, ok);
    ok = _mm256_and_si256(ok, _mm256_castps_si256(_mm256_cmp_ps(total, zf, _CMP_GT_OQ)));
    unsigned done = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(ok));
    if (!done)
        return 0;
    __m256 scale = _mm256_div_ps(_mm256_set1_ps(1.0f),
                                 _mm256_mul_ps(total, _mm256_set1_ps(DT == 0 ? 255.0f : 65535.0f)));
    /* the taps from memory from here on (not kept in registers across the gathers) */
    const float(*ku)[8] = tu, (*kv)[8] = tv;
    __asm__("" : "+r"(ku), "+r"(kv) : "m"(tu), "m"(tv));
    __m256i me = _mm256_slli_epi64(ok, 32), mo = ok; /* sign bits: even / odd lanes */
    __m256i de, dof;
    w4x8_data(k, a.ru, a.rv, a.lv, me, mo, &de, &dof);
    /* first texel (v0 * 2^ru + u0) * ts, rows 2^ru * ts bytes apart */
    const int sh = DT == 0 ? 0 : 1;
    __m256i resu = _mm256_sllv_epi32(one, a.ru);
    __m256i ae, ao, re, ro;
    w4x8_rows(de, dof, a.u0, a.v0, resu, sh, &ae, &ao, &re, &ro);
    /* w4_tail's window: fma(t, kv_j, col) down the rows from +0. A lane stripped along v to
     * nv rows: its rows from nv on (past the face, perhaps past the level) are not read but
     * gathered as 0 and weighted +0, so col + (+0): col (never -0: a sum from +0). One
     * stripped along u to nu taps has its columns from nu on weighted +0 in the dot: +0, as
     * in w4_tail (integer texels are finite), read from the row's next texels (inside the
     * face, or the arena's slack) */
    __m256 col[4] = {zf, zf, zf, zf};
    _Pragma("GCC unroll 4") for (int j = 0; j < 4; j++) {
        __m256 t[4];
        __m256i mj = j ? _mm256_and_si256(ok, _mm256_cmpgt_epi32(nv, _mm256_set1_epi32(j))) : ok;
        w4x8_row(ae, ao, j ? _mm256_slli_epi64(mj, 32) : me, j ? mj : mo, DT, t, 4);
        __m256 w = _mm256_loadu_ps(kv[j]);
        _Pragma("GCC unroll 4") for (int i = 0; i < 4; i++)
            col[i] = _mm256_fmadd_ps(t[i], w, col[i]);
        ae = _mm256_add_epi64(ae, re);
        ao = _mm256_add_epi64(ao, ro);
    }
    /* its dot with the column weights (q_i = col_i ku_i + 0 + 0) and its fold
     * (q0 + q2) + (q1 + q3), into +0 */
    __m256 q0 = _mm256_add_ps(_mm256_fmadd_ps(col[0], _mm256_loadu_ps(ku[0]), zf), zf);
    __m256 q1 = _mm256_add_ps(_mm256_fmadd_ps(col[1], _mm256_loadu_ps(ku[1]), zf), zf);
    __m256 q2 = _mm256_add_ps(_mm256_fmadd_ps(col[2], _mm256_loadu_ps(ku[2]), zf), zf);
    __m256 q3 = _mm256_add_ps(_mm256_fmadd_ps(col[3], _mm256_loadu_ps(ku[3]), zf), zf);
    __m256 res = _mm256_add_ps(zf, _mm256_add_ps(_mm256_add_ps(q0, q2), _mm256_add_ps(q1, q3)));
    _mm256_maskstore_ps(out, ok, _mm256_mul_ps(res, scale));
    return done;
}


/* window_fused(base, rowb, DT, NC, ku, 4, kv, 4) (w4_tail's window of a 4 x 4 kernel) with
 * every loop unrolled: the same operations on the same lanes in the same order (window3 for
 * 3 channels; window4 for 1, window with one or two vectors a row for 2 and 4, whose masks
 * of the lanes past the row are all ones here and left out), so bit for bit its result. */
PF_TARGET __m128 w4x8_win(const uint8_t *base, size_t rowb, const float *ku, const float *kv,
                          unsigned DT, unsigned NC)
{
    const __m128 z = _mm_setzero_ps();
    if (NC == 3) {
        size_t ts = (size_t)3 << (DT == 0 ? 0 : DT == 3 ? 2 : 1);
        __m128 k0 = _mm_set1_ps(ku[0]), k1 = _mm_set1_ps(ku[1]), k2 = _mm_set1_ps(ku[2]),
               k3 = _mm_set1_ps(ku[3]);
        __m128 acc = z;
        _Pragma("GCC unroll 4") for (int j = 0; j < 4; j++) {
            const uint8_t *p = base + (size_t)j * rowb;
            __m128 row = _mm_mul_ps(load4(p, DT), k0);
            row = _mm_fmadd_ps(load4(p + ts, DT), k1, row);
            row = _mm_fmadd_ps(load4(p + 2 * ts, DT), k2, row);
            row = _mm_fmadd_ps(load4(p + 3 * ts, DT), k3, row);
            acc = _mm_fmadd_ps(row, _mm_set1_ps(kv[j]), acc);
        }
        return acc;
    }
    __m128 k = _mm_loadu_ps(ku);
    if (NC == 1) {
        __m128 col = z;
        _Pragma("GCC unroll 4") for (int j = 0; j < 4; j++)
            col = _mm_fmadd_ps(load4(base + (size_t)j * rowb, DT), _mm_set1_ps(kv[j]), col);
        __m128 q = _mm_add_ps(_mm_fmadd_ps(col, k, z), z);
        __m128 h = _mm_add_ps(q, _mm_movehl_ps(q, q));
        return _mm_add_ss(z, _mm_add_ss(h, _mm_shuffle_ps(h, h, 1)));
    }
    size_t vb = (size_t)8 << (DT == 0 ? 0 : DT == 3 ? 2 : 1); /* bytes per 8 values */
    __m256 c0 = _mm256_setzero_ps(), c1 = _mm256_setzero_ps();
    _Pragma("GCC unroll 4") for (int j = 0; j < 4; j++) {
        const uint8_t *p = base + (size_t)j * rowb;
        __m256 w = _mm256_set1_ps(kv[j]);
        c0 = _mm256_fmadd_ps(load8(p, DT), w, c0);
        if (NC == 4)
            c1 = _mm256_fmadd_ps(load8(p + vb, DT), w, c1);
    }
    __m256 sv;
    if (NC == 4) { /* (ku0 x 4, ku1 x 4) and (ku2 x 4, ku3 x 4) from the 4 taps */
        __m256 k8 = _mm256_castps128_ps256(k);
        sv = _mm256_mul_ps(c0, _mm256_permutevar8x32_ps(
                                   k8, _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1)));
        sv = _mm256_fmadd_ps(c1, _mm256_permutevar8x32_ps(
                                     k8, _mm256_setr_epi32(2, 2, 2, 2, 3, 3, 3, 3)), sv);
    } else {
        sv = _mm256_fmadd_ps(c0, _mm256_set_m128(_mm_unpackhi_ps(k, k), _mm_unpacklo_ps(k, k)),
                             _mm256_setzero_ps());
    }
    __m128 q = _mm_add_ps(_mm256_castps256_ps128(sv), _mm256_extractf128_ps(sv, 1));
    if (NC == 4)
        return _mm_add_ps(z, q);
    __m128 h = _mm_add_ps(q, _mm_movehl_ps(q, q));
    return _mm_add_ps(z, _mm_movelh_ps(h, z));
}

/* put_scaled (out[ch] = channel ch of acc times scale) with the NC values stored at once. */
PF_TARGET void w4x8_put(float *out, __m128 acc, float scale, unsigned NC)
{
    __m128 r = _mm_mul_ps(acc, _mm_set1_ps(scale));
    if (NC == 4)
        _mm_storeu_ps(out, r);
    else if (NC == 1)
        _mm_store_ss(out, r);
    else {
        _mm_storel_pi((__m64 *)(void *)out, r);
        if (NC == 3)
            _mm_store_ss(out + 2, _mm_movehl_ps(r, r));
    }
}

/* The 64-bit lanes of the even (e: 0, 2, 4, 6) and odd (o: 1, 3, 5, 7) queries stored in
 * query order. */
PF_TARGET void box8_lanes64(__m256i e, __m256i o, uint64_t *out)
{
    __m256i lo = _mm256_unpacklo_epi64(e, o), hi = _mm256_unpackhi_epi64(e, o); /* 0 1 4 5, 2 3 6 7 */
    _mm256_storeu_si256((__m256i *)(void *)out, _mm256_permute2x128_si256(lo, hi, 0x20));
    _mm256_storeu_si256((__m256i *)(void *)(out + 4), _mm256_permute2x128_si256(lo, hi, 0x31));
}

/* 8 queries of a width-4 filter on texels of type DT with NC channels (every type and channel
 * count but 1-channel u8 and u16, which w4x8_body takes), the block's set-up k (klanes8):
 * the same lanes as w4x8_body served, handed over or left alone. The set-up, the taps of
 * both axes, their sums and the weight run 8 lanes at a time as in w4x8_body; then each lane
 * served runs w4_tail's window (window_fused with 4 x 4 taps: the same function on the same
 * taps) and put_scaled, its texel address computed in the vectors (64-bit lanes, even and
 * odd queries apart) and its taps transposed from the vectors into 4 per lane. */
PF_TARGET unsigned w4x8_each(const pk_params *p, const pf_klanes *k, float *out, pk *kout,
                             float *wout, unsigned *over, unsigned DT, unsigned NC, int G)
{
    const __m256i one = _mm256_set1_epi32(1);
    w4x8_ax a;
    __m256i ok = w4x8_axes(k, &a);
    __m256i ru = a.ru, rv = a.rv, u0 = a.u0, v0 = a.v0, ou = a.ou, ov = a.ov, lv = a.lv;
    __m256 xu = a.xu, stu = a.stu, xv = a.xv, stv = a.stv;
    if (_mm256_testz_si256(ok, ok))
        return *over = 0;
    float tu[4][8], tv[4][8]; /* the taps, for the kernels handed over */
    __m256 ku[4], kv[4], sv = _mm256_setzero_ps(), su = _mm256_setzero_ps();
    __m256i zu[4], zv[4]; /* the lanes whose tap t is zero */
    _Pragma("GCC unroll 4") for (int t = 0; t < 4; t++)
        kv[t] = w4x8_tap(p, xv, stv, t, tv[t], &sv, &zv[t], G);
    _Pragma("GCC unroll 4") for (int t = 0; t < 4; t++)
        ku[t] = w4x8_tap(p, xu, stu, t, tu[t], &su, &zu[t], G);
    __m256 total = _mm256_mul_ps(su, sv);
    __m256i hand = ok, nu = _mm256_set1_epi32(4), nv = nu;
    unsigned strip = 0; /* the lanes stripped (as in w4x8_body) */
    if (!G) {
        __m256i ends = _mm256_or_si256(_mm256_or_si256(zu[0], zu[3]),
                                       _mm256_or_si256(zv[0], zv[3]));
        if (!_mm256_testz_si256(ends, ok)) {
            /* as w4x8_body; each such lane's window is w4_tail's (window_fused, or w4_win1
             * for 1 channel) on its stripped taps */
            __m256i sl = w4x8_strip(tu, tv, zu, zv, &a, &ok, &nu, &nv);
            u0 = a.u0, v0 = a.v0, ou = a.ou, ov = a.ov;
            hand = _mm256_andnot_si256(sl, ok);
            strip = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(sl));
            _Pragma("GCC unroll 4") for (int t = 0; t < 4; t++) {
                ku[t] = _mm256_loadu_ps(tu[t]);
                kv[t] = _mm256_loadu_ps(tv[t]);
            }
        }
    }
    __m256i out_of = _mm256_or_si256(ou, ov);
    *over = w4x8_hand(hand, out_of, total, ru, rv, u0, v0, tu, tv, kout, wout);
    const __m256 zf = _mm256_setzero_ps();
    ok = _mm256_andnot_si256(out_of, ok);
    ok = _mm256_and_si256(ok, _mm256_castps_si256(_mm256_cmp_ps(total, zf, _CMP_GT_OQ)));
    unsigned done = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(ok));
    if (!done)
        return 0;
    /* w4_tail's scale 1 / (total * one), and the first texel's address d + (v0 2^ru + u0) ts
     * and the row length 2^ru ts of each lane (< 2^32 texels a level: exact in mul_epu32) */
    float S[8];
    float onev = DT == 0 ? 255.0f : DT == 1 ? 65535.0f : 1.0f;
    _mm256_storeu_ps(S, _mm256_div_ps(_mm256_set1_ps(1.0f),
                                      _mm256_mul_ps(total, _mm256_set1_ps(onev))));
    __m256i de, dof;
    w4x8_data(k, ru, rv, lv, _mm256_slli_epi64(ok, 32), ok, &de, &dof);
    const __m256i ts = _mm256_set1_epi64x((long long)(NC << (DT == 0 ? 0 : DT == 3 ? 2 : 1)));
    __m256i resu = _mm256_sllv_epi32(one, ru);
    __m256i ae = _mm256_add_epi64(
        de, _mm256_mul_epu32(_mm256_add_epi64(_mm256_mul_epu32(v0, resu), even64(u0)), ts));
    __m256i ao = _mm256_add_epi64(
        dof, _mm256_mul_epu32(_mm256_add_epi64(_mm256_mul_epu32(odd64(v0), odd64(resu)),
                                               odd64(u0)), ts));
    uint64_t A[8], RB[8]; /* in lane order */
    box8_lanes64(ae, ao, A);
    box8_lanes64(_mm256_mul_epu32(resu, ts), _mm256_mul_epu32(odd64(resu), ts), RB);
    /* the taps by lane: lane j's 4 at 4 j */
    float KU[32], KV[32];
    w4x8_bylane(ku, KU);
    w4x8_bylane(kv, KV);
    if (!(strip & done)) {
        for (unsigned m = done; m; m &= m - 1) {
            unsigned j = (unsigned)__builtin_ctz(m);
            const uint8_t *base = (const uint8_t *)(uintptr_t)A[j];
            __m128 acc = w4x8_win(base, (size_t)RB[j], KU + 4 * j, KV + 4 * j, DT, NC);
            w4x8_put(out + (size_t)j * NC, acc, S[j], NC);
        }
        return done;
    }
    int NU[8], NV[8]; /* the taps of each axis after the strip */
    _mm256_storeu_si256((__m256i *)(void *)NU, nu);
    _mm256_storeu_si256((__m256i *)(void *)NV, nv);
    for (unsigned m = done; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        const uint8_t *base = (const uint8_t *)(uintptr_t)A[j];
        if (!(strip >> j & 1)) {
            w4x8_put(out + (size_t)j * NC,
                     w4x8_win(base, (size_t)RB[j], KU + 4 * j, KV + 4 * j, DT, NC), S[j], NC);
        } else if (NC == 1) { /* w4_tail's 1-channel window on the lane's taps, +0 past */
            __m256 kuj = _mm256_zextps128_ps256(_mm_loadu_ps(KU + 4 * j));
            __m256 kvj = _mm256_zextps128_ps256(_mm_loadu_ps(KV + 4 * j));
            out[j] = w4_win1(base, (size_t)RB[j], kuj, kvj, NU[j], NV[j], DT) * S[j];
        } else {
            w4x8_put(out + (size_t)j * NC,
                     window_fused(base, (size_t)RB[j], DT, NC, KU + 4 * j, NU[j], KV + 4 * j,
                                  NV[j]),
                     S[j], NC);
        }
    }
    return done;
}

#define PF_W4X8(DT)                                                                         \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pf_w4x8_##DT##_g(              \
        const pk_params *p, const pf_klanes *k, float *out, pk *kout, float *wo,           \
        unsigned *over)                                                                     \
    {                                                                                       \
        return w4x8_body(p, k, out, kout, wo, over, DT, 1);                                 \
    }                                                                                       \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pf_w4x8_##DT##_c(              \
        const pk_params *p, const pf_klanes *k, float *out, pk *kout, float *wo,           \
        unsigned *over)                                                                     \
    {                                                                                       \
        return w4x8_body(p, k, out, kout, wo, over, DT, 0);                                 \
    }
PF_W4X8(0)
PF_W4X8(1)

#define PF_W4X8E(DT, NC)                                                                    \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pf_w4x8e_##DT##_##NC##_g(      \
        const pk_params *p, const pf_klanes *k, float *out, pk *kout, float *wo,           \
        unsigned *over)                                                                     \
    {                                                                                       \
        return w4x8_each(p, k, out, kout, wo, over, DT, NC, 1);                             \
    }                                                                                       \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pf_w4x8e_##DT##_##NC##_c(      \
        const pk_params *p, const pf_klanes *k, float *out, pk *kout, float *wo,           \
        unsigned *over)                                                                     \
    {                                                                                       \
        return w4x8_each(p, k, out, kout, wo, over, DT, NC, 0);                             \
    }
PF_W4X8E(0, 2) PF_W4X8E(0, 3) PF_W4X8E(0, 4)
PF_W4X8E(1, 2) PF_W4X8E(1, 3) PF_W4X8E(1, 4)
PF_W4X8E(2, 1) PF_W4X8E(2, 2) PF_W4X8E(2, 3) PF_W4X8E(2, 4)
PF_W4X8E(3, 1) PF_W4X8E(3, 2) PF_W4X8E(3, 3) PF_W4X8E(3, 4)

pf_w4x8_fn pf_w4x8_select(unsigned dt, unsigned nc, unsigned ftype)
{
#define E(D, N) {pf_w4x8e_##D##_##N##_g, pf_w4x8e_##D##_##N##_c}
    static const pf_w4x8_fn fns[4][4][2] = {
        {{pf_w4x8_0_g, pf_w4x8_0_c}, E(0, 2), E(0, 3), E(0, 4)},
        {{pf_w4x8_1_g, pf_w4x8_1_c}, E(1, 2), E(1, 3), E(1, 4)},
        {E(2, 1), E(2, 2), E(2, 3), E(2, 4)},
        {E(3, 1), E(3, 2), E(3, 3), E(3, 4)},
    };
#undef E
    if (ftype <= ST_FILTER_PTEX_BOX || ftype > ST_FILTER_PTEX_MITCHELL || nc < 1 || nc > 4 ||
        dt > 3 || !pf_have_avx2())
        return NULL;
    return fns[dt][nc - 1][ftype == ST_FILTER_PTEX_GAUSSIAN ? 0 : 1];
}

/* ---- the box filter's in-face case, 8 queries at a time (pf_box8_select) --------------- */

/* One axis of box_axes for 8 queries, lane by lane its operations in its order: x the
 * coordinates, bw the widths, lg the faces' log2 sizes. r the resolution, a the first texel,
 * n the taps (1..3), t0, t1, t2 box_axes' ku[0], ku[1], ku[2] (w1 or f1, f2 or 1, f2: those
 * at n and past are no taps), sm the axis' sum (pk_weight's factor), bad the lanes with a
 * zero weight at an end (box_axes declines them). */
typedef struct {
    __m256i r, a, n, bad;
    __m256 t0, t1, t2, sm;
} box8_ax;

PF_TARGET void box8_axis(__m256 x, __m256 bw, __m256i lg, box8_ax *o)
{
    const __m256 one = _mm256_set1_ps(1.0f), half = _mm256_set1_ps(0.5f);
    const __m256 z = _mm256_setzero_ps();
    const __m256i e127 = _mm256_set1_epi32(127);
    __m256 w = _mm256_min_ps(bw, one);                        /* uw < 1 ? uw : 1 */
    __m256 lo = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_sub_epi32(e127, lg), 23));
    w = _mm256_max_ps(w, lo);                                 /* uw > lu ? uw : lu */
    __m256i r = _mm256_sub_epi32(e127, _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(w), 23),
                                                        _mm256_set1_epi32(0xff)));
    __m256 rf = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(r, e127), 23));
    x = _mm256_mul_ps(x, rf);
    w = _mm256_mul_ps(w, rf);
    __m256 hw = _mm256_mul_ps(half, w);
    __m256 x1 = _mm256_sub_ps(x, hw), x2 = _mm256_add_ps(x, hw);
    __m256 x1f = _mm256_floor_ps(x1), x2c = _mm256_ceil_ps(x2);
    __m256i a = _mm256_cvttps_epi32(x1f);
    __m256i n = _mm256_sub_epi32(_mm256_cvttps_epi32(x2c), a);
    n = _mm256_min_epi32(_mm256_max_epi32(n, _mm256_set1_epi32(1)), _mm256_set1_epi32(3));
    __m256 f1 = _mm256_sub_ps(one, _mm256_sub_ps(x1, x1f));
    __m256 f2 = _mm256_sub_ps(one, _mm256_sub_ps(x2c, x2));
    __m256 s12 = _mm256_add_ps(f1, f2);
    __m256 w1 = _mm256_sub_ps(s12, one);
    __m256 s3 = _mm256_add_ps(_mm256_add_ps(f1, one), f2);
    __m256 n1 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(n, _mm256_set1_epi32(1)));
    __m256 n3 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(n, _mm256_set1_epi32(3)));
    __m256 bad = _mm256_or_ps(_mm256_and_ps(n1, _mm256_cmp_ps(w1, z, _CMP_EQ_OQ)),
                              _mm256_andnot_ps(n1, _mm256_or_ps(_mm256_cmp_ps(f1, z, _CMP_EQ_OQ),
                                                                _mm256_cmp_ps(f2, z, _CMP_EQ_OQ))));
    o->r = r;
    o->a = a;
    o->n = n;
    o->bad = _mm256_castps_si256(bad);
    o->t0 = _mm256_blendv_ps(f1, w1, n1);
    o->t1 = _mm256_blendv_ps(f2, one, n3);
    o->t2 = f2;
    o->sm = _mm256_blendv_ps(_mm256_blendv_ps(s12, s3, n3), w1, n1);
}

/* The lanes of ok whose window overhangs the face (out_of) handed over as fast_body hands a
 * box kernel over (hand_over with box: 3 weights an axis): kout[j], its weight wout[j]
 * (total). Returns their mask. */
PF_TARGET unsigned box8_hand(__m256i ok, __m256i out_of, __m256 total, const box8_ax *au,
                             const box8_ax *av, pk *kout, float *wout)
{
    unsigned ho = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(ok, out_of)));
    if (ho) {
        _mm256_storeu_ps(wout, total);
        int I[6][8];
        float T[6][8];
        _mm256_storeu_si256((__m256i *)(void *)I[0], au->r);
        _mm256_storeu_si256((__m256i *)(void *)I[1], av->r);
        _mm256_storeu_si256((__m256i *)(void *)I[2], au->a);
        _mm256_storeu_si256((__m256i *)(void *)I[3], av->a);
        _mm256_storeu_si256((__m256i *)(void *)I[4], au->n);
        _mm256_storeu_si256((__m256i *)(void *)I[5], av->n);
        _mm256_storeu_ps(T[0], au->t0);
        _mm256_storeu_ps(T[1], au->t1);
        _mm256_storeu_ps(T[2], au->t2);
        _mm256_storeu_ps(T[3], av->t0);
        _mm256_storeu_ps(T[4], av->t1);
        _mm256_storeu_ps(T[5], av->t2);
        for (unsigned m = ho; m; m &= m - 1) {
            int j = __builtin_ctz(m);
            pk *kj = kout + j;
            pk_origin(kj, I[0][j], I[1][j], I[2][j], I[3][j]);
            kj->uw = I[4][j];
            kj->vw = I[5][j];
            kj->ku0 = kj->kv0 = kj->rot = 0;
            for (int t = 0; t < 3; t++) {
                kj->kub[t] = T[t][j];
                kj->kvb[t] = T[3 + t][j];
            }
        }
    }
    return ho;
}

/* fast_body's box window of one lane (window_fused with nu x nv taps, 1..3 each way, as
 * constants: case (nu - 1) * 3 + nv - 1), so its loops unroll: the same function on the
 * same taps. */
PF_TARGET __m128 box8_win(int c, const uint8_t *base, size_t rowb, const float *ku,
                          const float *kv, unsigned DT, unsigned NC)
{
    switch (c) {
    case 0: return window_fused(base, rowb, DT, NC, ku, 1, kv, 1);
    case 1: return window_fused(base, rowb, DT, NC, ku, 1, kv, 2);
    case 2: return window_fused(base, rowb, DT, NC, ku, 1, kv, 3);
    case 3: return window_fused(base, rowb, DT, NC, ku, 2, kv, 1);
    case 4: return window_fused(base, rowb, DT, NC, ku, 2, kv, 2);
    case 5: return window_fused(base, rowb, DT, NC, ku, 2, kv, 3);
    case 6: return window_fused(base, rowb, DT, NC, ku, 3, kv, 1);
    case 7: return window_fused(base, rowb, DT, NC, ku, 3, kv, 2);
    default: return window_fused(base, rowb, DT, NC, ku, 3, kv, 3);
    }
}

/* 8 queries of the box filter on texels of type DT with NC channels, the block's set-up k
 * (klanes8): the lanes of k->fast that fast_body serves (no zero weight at an end, the
 * window inside the face, total weight > 0) get its result, lane by lane its operations in
 * its order, so bit for bit; out + j * NC written for those lanes j, their mask returned.
 * The lanes whose window overhangs the face get the kernel fast_body hands over in kout[j]
 * and its pk_weight in wout[j], their mask in *over. The other lanes are left alone (the
 * caller serves them one by one). box_axes' set-up of both axes, the weight, the scale and
 * each lane's first texel and row length run 8 lanes at a time. The window: for 1-channel
 * u8 and u16 texels (VEC) in the vectors too, 3 rows of 8 queries gathered (a row of a lane
 * past its taps not read, a column past them weighted +0: integer texels are finite, so
 * that adds +0 where the per-query window adds a cleared lane's +0); for the others, per
 * lane served, fast_body's window with the lane's shape as constants (box8_win). */
PF_TARGET unsigned box8(const pf_klanes *k, float *out, pk *kout, float *wout, unsigned *over,
                        unsigned DT, unsigned NC)
{
    const __m256i one = _mm256_set1_epi32(1);
    const __m256 zf = _mm256_setzero_ps();
    __m256i ok = _mm256_cmpgt_epi32(
        _mm256_and_si256(_mm256_srlv_epi32(_mm256_set1_epi32((int)k->fast),
                                           _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)), one),
        _mm256_setzero_si256());
    box8_ax au, av;
    __m256i lv = _mm256_loadu_si256((const __m256i *)(const void *)k->vlog2);
    box8_axis(_mm256_loadu_ps(k->u), _mm256_loadu_ps(k->bu),
              _mm256_loadu_si256((const __m256i *)(const void *)k->ulog2), &au);
    box8_axis(_mm256_loadu_ps(k->v), _mm256_loadu_ps(k->bv), lv, &av);
    ok = _mm256_andnot_si256(_mm256_or_si256(au.bad, av.bad), ok);
    if (_mm256_testz_si256(ok, ok))
        return *over = 0;
    /* inside: a >= 0 and a + n <= 2^r along both axes */
    const __m256i z = _mm256_setzero_si256();
    __m256i out_of = _mm256_or_si256(
        _mm256_or_si256(_mm256_cmpgt_epi32(z, au.a),
                        _mm256_cmpgt_epi32(_mm256_add_epi32(au.a, au.n), _mm256_sllv_epi32(one, au.r))),
        _mm256_or_si256(_mm256_cmpgt_epi32(z, av.a),
                        _mm256_cmpgt_epi32(_mm256_add_epi32(av.a, av.n), _mm256_sllv_epi32(one, av.r))));
    __m256 total = _mm256_mul_ps(au.sm, av.sm); /* sum[0] * sum[1] */
    *over = box8_hand(ok, out_of, total, &au, &av, kout, wout);
    ok = _mm256_andnot_si256(out_of, ok);
    ok = _mm256_and_si256(ok, _mm256_castps_si256(_mm256_cmp_ps(total, zf, _CMP_GT_OQ)));
    unsigned done = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(ok));
    if (!done)
        return 0;
    const float onev = DT == 0 ? 255.0f : DT == 1 ? 65535.0f : 1.0f;
    __m256 scale = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_mul_ps(total, _mm256_set1_ps(onev)));
    __m256i me = _mm256_slli_epi64(ok, 32), mo = ok; /* sign bits: even / odd lanes */
    __m256i de, dof;
    w4x8_data(k, au.r, av.r, lv, me, mo, &de, &dof);
    const int sh = DT == 0 ? 0 : DT == 3 ? 2 : 1;
    __m256i resu = _mm256_sllv_epi32(one, au.r);
    const int VEC = NC == 1 && DT <= 1;
    if (VEC) {
        /* first texel (v0 2^ru + u0) ts, rows 2^ru ts bytes apart */
        __m256i ae, ao, re, ro;
        w4x8_rows(de, dof, au.a, av.a, resu, sh, &ae, &ao, &re, &ro);
        /* the taps of each lane, +0 past its last (rows past it are not read: 0) */
        __m256 kv[3] = {av.t0, av.t1, av.t2};
        __m256 col[3] = {zf, zf, zf};
        _Pragma("GCC unroll 3") for (int j = 0; j < 3; j++) {
            __m256i rm = ok;
            if (j) {
                rm = _mm256_and_si256(rm, _mm256_cmpgt_epi32(av.n, _mm256_set1_epi32(j)));
                kv[j] = _mm256_and_ps(kv[j], _mm256_castsi256_ps(rm));
            }
            __m256 t[3];
            w4x8_row(ae, ao, _mm256_slli_epi64(rm, 32), rm, DT, t, 3);
            _Pragma("GCC unroll 3") for (int i = 0; i < 3; i++)
                col[i] = _mm256_fmadd_ps(t[i], kv[j], col[i]);
            ae = _mm256_add_epi64(ae, re);
            ao = _mm256_add_epi64(ao, ro);
        }
        /* window4's dot (q_i = col_i ku_i + 0 + 0, lane 3's +0) and fold into +0 */
        __m256 ku1 = _mm256_and_ps(au.t1, _mm256_castsi256_ps(_mm256_cmpgt_epi32(au.n, one)));
        __m256 ku2 = _mm256_and_ps(au.t2, _mm256_castsi256_ps(
                                              _mm256_cmpgt_epi32(au.n, _mm256_set1_epi32(2))));
        __m256 q0 = _mm256_add_ps(_mm256_fmadd_ps(col[0], au.t0, zf), zf);
        __m256 q1 = _mm256_add_ps(_mm256_fmadd_ps(col[1], ku1, zf), zf);
        __m256 q2 = _mm256_add_ps(_mm256_fmadd_ps(col[2], ku2, zf), zf);
        __m256 h0 = _mm256_add_ps(q0, q2), h1 = _mm256_add_ps(q1, zf);
        __m256 res = _mm256_add_ps(zf, _mm256_add_ps(h0, h1));
        _mm256_maskstore_ps(out, ok, _mm256_mul_ps(res, scale));
        return done;
    }
    const __m256i ts = _mm256_set1_epi64x((long long)(NC << sh));
    __m256i ae = _mm256_add_epi64(
        de, _mm256_mul_epu32(_mm256_add_epi64(_mm256_mul_epu32(av.a, resu), even64(au.a)), ts));
    __m256i ao = _mm256_add_epi64(
        dof, _mm256_mul_epu32(_mm256_add_epi64(_mm256_mul_epu32(odd64(av.a), odd64(resu)),
                                               odd64(au.a)), ts));
    uint64_t A[8], RB[8]; /* in lane order */
    box8_lanes64(ae, ao, A);
    box8_lanes64(_mm256_mul_epu32(resu, ts), _mm256_mul_epu32(odd64(resu), ts), RB);
    float S[8];
    int C[8];
    _mm256_storeu_ps(S, scale);
    _mm256_storeu_si256((__m256i *)(void *)C,
                        _mm256_add_epi32(_mm256_mullo_epi32(_mm256_sub_epi32(au.n, one),
                                                            _mm256_set1_epi32(3)),
                                         _mm256_sub_epi32(av.n, one)));
    /* the taps by lane: lane j's 3 at 4 j */
    float KU[32], KV[32];
    const __m256 tu[4] = {au.t0, au.t1, au.t2, zf}, tv[4] = {av.t0, av.t1, av.t2, zf};
    w4x8_bylane(tu, KU);
    w4x8_bylane(tv, KV);
    for (unsigned m = done; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        const uint8_t *base = (const uint8_t *)(uintptr_t)A[j];
        __m128 acc = box8_win(C[j], base, (size_t)RB[j], KU + 4 * j, KV + 4 * j, DT, NC);
        w4x8_put(out + (size_t)j * NC, acc, S[j], NC);
    }
    return done;
}

#define PF_BOX8(DT, NC)                                                                     \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pf_box8_##DT##_##NC(           \
        const pk_params *p, const pf_klanes *k, float *out, pk *kout, float *wo,           \
        unsigned *over)                                                                     \
    {                                                                                       \
        (void)p;                                                                            \
        return box8(k, out, kout, wo, over, DT, NC);                                        \
    }
#define PF_BOX8_NC(DT) PF_BOX8(DT, 1) PF_BOX8(DT, 2) PF_BOX8(DT, 3) PF_BOX8(DT, 4)
PF_BOX8_NC(0)
PF_BOX8_NC(1)
PF_BOX8_NC(2)
PF_BOX8_NC(3)

pf_w4x8_fn pf_box8_select(unsigned dt, unsigned nc)
{
#define PF_ROW(DT) {pf_box8_##DT##_1, pf_box8_##DT##_2, pf_box8_##DT##_3, pf_box8_##DT##_4}
    static const pf_w4x8_fn fns[4][4] = {PF_ROW(0), PF_ROW(1), PF_ROW(2), PF_ROW(3)};
#undef PF_ROW
    if (nc < 1 || nc > 4 || dt > 3 || !pf_have_avx2())
        return NULL;
    return fns[dt][nc - 1];
}

/* ---- windows of at most 2 x 2 texels (pf_small_select) ---------------------------------- */

/* window() / window3() with NV = 1 (uw * nc <= 8) and the window's shape as constants: the
 * same operations as pf_apply_avx2 on such a window, without its dispatch. */
PF_TARGET pf_v4 small_body(const uint8_t *base, size_t rowb, const float *ku, int uw,
                           const float *kv, int vw, pf_v4 acc4, unsigned DT, unsigned NC)
{
    __m128 acc = (__m128)acc4;
#define PF_SMALL(UW, VW)                                                                    \
    (NC == 3 ? window3(base, rowb, DT, ku, UW, kv, VW, acc)                                 \
     : NC == 1 && DT <= 1 ? window4_int(base, rowb, DT, ku, UW, kv, VW, acc)                \
                          : window(base, rowb, DT, NC, ku, UW, kv, VW, 1, acc))
    switch ((uw - 1) * 2 + (vw - 1)) {
    case 0: return (pf_v4)PF_SMALL(1, 1);
    case 1: return (pf_v4)PF_SMALL(1, 2);
    case 2: return (pf_v4)PF_SMALL(2, 1);
    default: return (pf_v4)PF_SMALL(2, 2);
    }
#undef PF_SMALL
}

#define PF_SMALLFN(DT, NC)                                                                  \
    __attribute__((target("avx2,fma,f16c"))) static pf_v4 pf_small_##DT##_##NC(             \
        const uint8_t *base, size_t rowb, const float *ku, int uw, const float *kv, int vw, \
        pf_v4 acc)                                                                          \
    {                                                                                       \
        return small_body(base, rowb, ku, uw, kv, vw, acc, DT, NC);                         \
    }
#define PF_SMALLFN_NC(DT) PF_SMALLFN(DT, 1) PF_SMALLFN(DT, 2) PF_SMALLFN(DT, 3) PF_SMALLFN(DT, 4)
PF_SMALLFN_NC(0)
PF_SMALLFN_NC(1)
PF_SMALLFN_NC(2)
PF_SMALLFN_NC(3)

pf_window_fn pf_small_select(unsigned dt, unsigned nc)
{
    static const pf_window_fn fns[4][4] = {
        {pf_small_0_1, pf_small_0_2, pf_small_0_3, pf_small_0_4},
        {pf_small_1_1, pf_small_1_2, pf_small_1_3, pf_small_1_4},
        {pf_small_2_1, pf_small_2_2, pf_small_2_3, pf_small_2_4},
        {pf_small_3_1, pf_small_3_2, pf_small_3_3, pf_small_3_4},
    };
    return pick_window(fns, dt, nc);
}

/* pf_small4_select (pf_small2_select): small_body with uw = vw = 1 (its switch folded), four
 * (two) times in order. */
#define PF_SMALL4FN(DT, NC)                                                                 \
    __attribute__((target("avx2,fma,f16c"))) static pf_v4 pf_small4_##DT##_##NC(            \
        const pf_tex4 *t, size_t rowb, pf_v4 acc)                                           \
    {                                                                                       \
        acc = small_body(t->p[0], rowb, t->ku[0], 1, t->kv[0], 1, acc, DT, NC);             \
        acc = small_body(t->p[1], rowb, t->ku[1], 1, t->kv[1], 1, acc, DT, NC);             \
        acc = small_body(t->p[2], rowb, t->ku[2], 1, t->kv[2], 1, acc, DT, NC);             \
        return small_body(t->p[3], rowb, t->ku[3], 1, t->kv[3], 1, acc, DT, NC);            \
    }
#define PF_SMALL4FN_NC(DT) PF_SMALL4FN(DT, 1) PF_SMALL4FN(DT, 2) PF_SMALL4FN(DT, 3) PF_SMALL4FN(DT, 4)
PF_SMALL4FN_NC(0)
PF_SMALL4FN_NC(1)
PF_SMALL4FN_NC(2)
PF_SMALL4FN_NC(3)

#define PF_SMALL2FN(DT, NC)                                                                 \
    __attribute__((target("avx2,fma,f16c"))) static pf_v4 pf_small2_##DT##_##NC(            \
        const pf_tex4 *t, size_t rowb, pf_v4 acc)                                           \
    {                                                                                       \
        acc = small_body(t->p[0], rowb, t->ku[0], 1, t->kv[0], 1, acc, DT, NC);             \
        return small_body(t->p[1], rowb, t->ku[1], 1, t->kv[1], 1, acc, DT, NC);            \
    }
#define PF_SMALL2FN_NC(DT) PF_SMALL2FN(DT, 1) PF_SMALL2FN(DT, 2) PF_SMALL2FN(DT, 3) PF_SMALL2FN(DT, 4)
PF_SMALL2FN_NC(0)
PF_SMALL2FN_NC(1)
PF_SMALL2FN_NC(2)
PF_SMALL2FN_NC(3)

pf_small4_fn pf_small4_select(unsigned dt, unsigned nc)
{
#define PF_ROW(DT) {pf_small4_##DT##_1, pf_small4_##DT##_2, pf_small4_##DT##_3, pf_small4_##DT##_4}
    static const pf_small4_fn fns[4][4] = {PF_ROW(0), PF_ROW(1), PF_ROW(2), PF_ROW(3)};
#undef PF_ROW
    if (nc < 1 || nc > 4 || dt > 3 || !pf_have_avx2())
        return NULL;
    return fns[dt][nc - 1];
}

pf_small4_fn pf_small2_select(unsigned dt, unsigned nc)
{
#define PF_ROW(DT) {pf_small2_##DT##_1, pf_small2_##DT##_2, pf_small2_##DT##_3, pf_small2_##DT##_4}
    static const pf_small4_fn fns[4][4] = {PF_ROW(0), PF_ROW(1), PF_ROW(2), PF_ROW(3)};
#undef PF_ROW
    if (nc < 1 || nc > 4 || dt > 3 || !pf_have_avx2())
        return NULL;
    return fns[dt][nc - 1];
}

/* ---- the Traverse walk of a 2 x 2 kernel over plain faces (pf_edge2_select) -------------
 * ptexfilter.c's split_apply_small for the common case: each step names the pk2 operation
 * (ptexfilter.c) it stands for; weights are only moved, swapped and, in a reduction, summed
 * in pairs (p2_downres), and each piece's window goes through small_body (pf_small's code)
 * in the walk's order: corner, the piece past the u edge, the piece past the v edge, the
 * rest. bilinear_kernel's 2 x 2 kernel overhangs an edge by one of its two taps (first
 * texel -1 or 2^r - 1), so each split leaves one tap on each side; anything else declines. */

typedef struct tv2 {
    int lu, lv, u, v, nu, nv;   /* as pk2's ulog2, vlog2, u, v, uw, vw */
    __m128 w;                   /* ku[0], ku[1], kv[0], kv[1] */
} tv2;

/* p2_rotate */
PF_TARGET tv2 tv_rotate(tv2 k, int rot)
{
    rot &= 3;
    if (rot == 0)
        return k;
    if (rot != 3) { /* flip u */
        k.u = (1 << k.lu) - k.u - k.nu;
        if (k.nu == 2)
            k.w = _mm_shuffle_ps(k.w, k.w, _MM_SHUFFLE(3, 2, 0, 1));
    }
    if (rot != 1) { /* flip v */
        k.v = (1 << k.lv) - k.v - k.nv;
        if (k.nv == 2)
            k.w = _mm_shuffle_ps(k.w, k.w, _MM_SHUFFLE(2, 3, 1, 0));
    }
    if (rot != 2) { /* swap the axes */
        tv2 t = k;
        k.lu = t.lv, k.lv = t.lu, k.u = t.v, k.v = t.u, k.nu = t.nv, k.nv = t.nu;
        k.w = _mm_shuffle_ps(t.w, t.w, _MM_SHUFFLE(1, 0, 3, 2));
    }
    return k;
}

/* apply_small on face af (p2_downres to its resolution, the guard, the window): 0 (decline)
 * when af is constant or a subface or the piece does not lie inside it. */
PF_TARGET int tv_apply(const pf_walk *w, tv2 k, int af, __m128 *acc, unsigned DT, unsigned NC)
{
    const st_face *A = &w->faces[af];
    if (A->flags & (ST_FACE_CONSTANT | ST_FACE_SUBFACE))
        return 0;
    for (; k.lu > A->ulog2; k.lu--) {
        if (!(k.u & 1) && k.nu == 2) {
            k.w = _mm_move_ss(k.w, _mm_add_ss(k.w, _mm_shuffle_ps(k.w, k.w, 1)));
            k.nu = 1;
        }
        k.u /= 2;
    }
    for (; k.lv > A->vlog2; k.lv--) {
        if (!(k.v & 1) && k.nv == 2) {
            __m128 s = _mm_add_ss(_mm_movehl_ps(k.w, k.w), _mm_shuffle_ps(k.w, k.w, 3));
            k.w = _mm_shuffle_ps(k.w, _mm_unpacklo_ps(s, s), _MM_SHUFFLE(1, 0, 1, 0));
            k.nv = 1;
        }
        k.v /= 2;
    }
    int resu = 1 << k.lu;
    if (k.u < 0 || k.v < 0 || k.u + k.nu > resu || k.v + k.nv > (1 << k.lv))
        return 0;
    const uint8_t *d = w->px[w->base[af] + (size_t)k.lu * (A->vlog2 + 1u) + (size_t)k.lv];
    size_t rowb = (size_t)resu * w->ts;
    float wt[4];
    _mm_storeu_ps(wt, k.w);
    *acc = (__m128)small_body(d + (size_t)k.v * rowb + (size_t)k.u * w->ts, rowb, wt, k.nu,
                              wt + 2, k.nv, (pf_v4)*acc, DT, NC);
    return 1;
}

/* across_small for a plain neighbour across edge eid of face F */
PF_TARGET int tv_across(const pf_walk *w, tv2 k, const st_face *F, int eid, __m128 *acc,
                        unsigned DT, unsigned NC)
{
    return tv_apply(w, tv_rotate(k, eid - F->adjedge[eid] + 2), F->adjface[eid], acc, DT, NC);
}

/* corner_other_small (ptexfilter.c: apply_to_corner at a vertex of valence other than 4,
 * no subface around it) for a one-texel piece k: its ring walk; with two faces or more
 * between the neighbours the piece rotated, made symmetric (p2_make_symmetric on one texel:
 * the coarser resolution, the two weights' sum in both, the first scaled down to the
 * initial weight) and applied on each, *wt adjusted; with none, dropped, its weight
 * removed from *wt; 0 (decline) with one (a ring open past it: untested), a subface, or a
 * piece tv_apply declines. */
PF_TARGET int tv_corner_other(const pf_walk *w, tv2 k, int f, int eid, __m128 *acc, float *wt,
                              unsigned DT, unsigned NC)
{
    enum { MAXV = 10 }; /* apply_to_corner's */
    int af = f, ae = eid, cface[MAXV], cedge[MAXV], ncorners = 0;
    if (k.nu != 1 || k.nv != 1)
        return 0;
    for (int i = 0; i < MAXV; i++) {
        const st_face *A = &w->faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || (af == f && ae == eid)) {
            ncorners = i - 2;
            break;
        }
        if (w->faces[af].flags & ST_FACE_SUBFACE)
            return 0;
        cface[i] = af;
        cedge[i] = ae;
    }
    if (ncorners == 1)
        return 0;
    if (ncorners < 1) { /* p2_weight of the one-texel piece */
        *wt -= (0.0f + k.w[0]) * (0.0f + k.w[2]);
        return 1;
    }
    tv2 s = tv_rotate(k, eid + 2);
    float ku0 = s.w[0], kv0 = s.w[2];
    float w0 = (0.0f + ku0) * (0.0f + kv0); /* p2_weight */
    for (; s.lu > s.lv; s.lu--)             /* p2_downres of one tap */
        s.u /= 2;
    for (; s.lv > s.lu; s.lv--)
        s.v /= 2;
    float sum = ku0 + kv0, a = sum, nw = 0;
    nw += sum;
    nw *= nw;
    float scale = nw == 0 ? 1.f : w0 / nw;
    if (scale < 1) {
        if (scale < -1) {
            a *= -1;
            nw = -nw;
        } else {
            a *= scale;
            nw = w0;
        }
    }
    s.w = _mm_setr_ps(a, 0.0f, sum, 0.0f);
    for (int i = 1; i <= ncorners; i++)
        if (!tv_apply(w, tv_rotate(s, 2 - cedge[i] + 2), cface[i], acc, DT, NC))
            return 0;
    *wt += nw * (float)ncorners - w0;
    return 1;
}

/* corner_small at a regular vertex (valence 4, no subface around it); at the others
 * tv_corner_other. */
PF_TARGET int tv_corner(const pf_walk *w, tv2 k, int f, int eid, __m128 *acc, float *wt,
                        unsigned DT, unsigned NC)
{
    int af = f, ae = eid, cf = -1, ce = 0;
    for (int i = 0; i < 4; i++) {
        const st_face *A = &w->faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || (w->faces[af].flags & ST_FACE_SUBFACE) || (af == f && ae == eid) != (i == 3))
            return tv_corner_other(w, k, f, eid, acc, wt, DT, NC);
        if (i == 1) {
            cf = af;
            ce = ae;
        }
    }
    return tv_apply(w, tv_rotate(k, eid - ce + 2), cf, acc, DT, NC);
}

/* p2_split_r (past, 1) / p2_split_l (0) of a one-tap overhang in u: k keeps the tap inside
 * its face, the piece returned holds the one past the edge (first texel 0 past the right
 * edge, resu - 1 past the left), each with its own weight and one tap wide. */
PF_TARGET tv2 tv_split_u(tv2 *k, int past, int resu)
{
    tv2 p = *k;
    p.nu = k->nu = 1;
    __m128 second = _mm_shuffle_ps(k->w, k->w, _MM_SHUFFLE(3, 2, 1, 1)); /* ku[1] first */
    if (past) {
        p.u = 0;
        p.w = second;
    } else {
        p.u = resu - 1;
        k->u = 0;
        k->w = second;
    }
    return p;
}

/* p2_split_t (past, 1) / p2_split_b (0) in v, as tv_split_u. */
PF_TARGET tv2 tv_split_v(tv2 *k, int past, int resv)
{
    tv2 p = *k;
    p.nv = k->nv = 1;
    __m128 second = _mm_shuffle_ps(k->w, k->w, _MM_SHUFFLE(3, 3, 1, 0)); /* kv[1] first */
    if (past) {
        p.v = 0;
        p.w = second;
    } else {
        p.v = resv - 1;
        k->v = 0;
        k->w = second;
    }
    return p;
}

PF_TARGET int edge2_body(const pf_walk *w, int f, int ulog2, int vlog2, int u, int v, float fu,
                         float fv, float *out, unsigned DT, unsigned NC)
{
    /* bilinear_walk's kernel: the taps of a zero fraction left out */
    int nu = fu != 0.0f ? 2 : 1, nv = fv != 0.0f ? 2 : 1;
    float ku[2] = {1.0f - fu, fu}, kv[2] = {1.0f - fv, fv};
    const st_face *F = &w->faces[f];
    tv2 k = {ulog2, vlog2, u, v, nu, nv, _mm_setr_ps(ku[0], ku[1], kv[0], kv[1])};
    int resu = 1 << k.lu, resv = 1 << k.lv;
    int sr = k.u + k.nu > resu, sl = k.u < 0, st = k.v + k.nv > resv, sb = k.v < 0;
    int eu = sr ? 1 : sl ? 3 : -1, ev = st ? 2 : sb ? 0 : -1;
    if ((eu >= 0 && (F->adjface[eu] < 0 || k.nu != 2 || k.u != (sr ? resu - 1 : -1))) ||
        (ev >= 0 && (F->adjface[ev] < 0 || k.nv != 2 || k.v != (st ? resv - 1 : -1))))
        return 0; /* a boundary (folds), or not a one-tap overhang */
    __m128 acc = _mm_setzero_ps();
    /* bilinear_walk's weight: p2_weight, changed at a corner of valence other than 4 */
    float weight = pk_accumulate(ku, nu) * pk_accumulate(kv, nv);
    if (eu >= 0) {
        tv2 ka = tv_split_u(&k, sr, resu);
        if (ev >= 0) {
            tv2 kc = tv_split_v(&ka, st, resv); /* that piece's corner */
            if (!tv_corner(w, kc, f, sr ? (st ? 2 : 1) : (st ? 3 : 0), &acc, &weight, DT, NC))
                return 0;
        }
        if (!tv_across(w, ka, F, eu, &acc, DT, NC))
            return 0;
    }
    if (ev >= 0) {
        tv2 ka = tv_split_v(&k, st, resv);
        if (!tv_across(w, ka, F, ev, &acc, DT, NC))
            return 0;
    }
    /* the rest lies inside f (plain), at a resolution f has: apply_small without its checks */
    const uint8_t *d = w->px[w->base[f] + (size_t)k.lu * (F->vlog2 + 1u) + (size_t)k.lv];
    size_t rowb = w->ts << k.lu;
    float wr[4];
    _mm_storeu_ps(wr, k.w);
    pf_v4 sum = small_body(d + (size_t)k.v * rowb + (size_t)k.u * w->ts, rowb, wr, k.nu, wr + 2,
                           k.nv, (pf_v4)acc, DT, NC);
    /* bilinear_walk's division: by the total weight (p2_weight) times the type's one value */
    float one = DT == ST_DT_U8 ? 255.0f : DT == ST_DT_U16 ? 65535.0f : 1.0f;
    float scale = 1.0f / (weight * one);
    for (unsigned ch = 0; ch < NC; ch++)
        out[ch] = sum[ch] * scale;
    return 1;
}

#define PF_EDGE2FN(DT, NC)                                                                  \
    __attribute__((target("avx2,fma,f16c"))) static int pf_edge2_##DT##_##NC(               \
        const pf_walk *w, int f, int ulog2, int vlog2, int u, int v, float fu, float fv,    \
        float *out)                                                                         \
    {                                                                                       \
        return edge2_body(w, f, ulog2, vlog2, u, v, fu, fv, out, DT, NC);                   \
    }
#define PF_EDGE2FN_NC(DT) PF_EDGE2FN(DT, 1) PF_EDGE2FN(DT, 2) PF_EDGE2FN(DT, 3) PF_EDGE2FN(DT, 4)
PF_EDGE2FN_NC(0)
PF_EDGE2FN_NC(1)
PF_EDGE2FN_NC(2)
PF_EDGE2FN_NC(3)

pf_edge2_fn pf_edge2_select(unsigned dt, unsigned nc)
{
    static const pf_edge2_fn fns[4][4] = {
        {pf_edge2_0_1, pf_edge2_0_2, pf_edge2_0_3, pf_edge2_0_4},
        {pf_edge2_1_1, pf_edge2_1_2, pf_edge2_1_3, pf_edge2_1_4},
        {pf_edge2_2_1, pf_edge2_2_2, pf_edge2_2_3, pf_edge2_2_4},
        {pf_edge2_3_1, pf_edge2_3_2, pf_edge2_3_3, pf_edge2_3_4},
    };
    if (dt > 3 || nc < 1 || nc > 4 || !pf_have_avx2())
        return NULL;
    return fns[dt][nc - 1];
}

/* Bilinear of 2 x 2 half texels (4 values each, F16C): the same operations in the same
 * order as ptexfilter.c's portable bilinear, (t00 k0 + t01 fu) kv0 + (t10 k0 + t11 fu) fv. */
__attribute__((target("avx2,fma,f16c")))
static pf_v4 bilinear_half(const uint8_t *p, size_t ts, size_t rowb, float ku0, float fu,
                           float kv0, float fv)
{
    __m128 a = _mm_set1_ps(ku0), b = _mm_set1_ps(fu);
    __m128 r0 = _mm_add_ps(_mm_mul_ps(load4(p, 2), a), _mm_mul_ps(load4(p + ts, 2), b));
    __m128 r1 = _mm_add_ps(_mm_mul_ps(load4(p + rowb, 2), a),
                           _mm_mul_ps(load4(p + rowb + ts, 2), b));
    return (pf_v4)_mm_add_ps(_mm_mul_ps(r0, _mm_set1_ps(kv0)), _mm_mul_ps(r1, _mm_set1_ps(fv)));
}

pf_bilinear_half_fn pf_bilinear_half_select(void)
{
    return pf_have_avx2() ? bilinear_half : NULL;
}

pf_fast_fn pf_fast_select(unsigned dt, unsigned nc, unsigned ftype)
{
    /* the width-4 filters' (w4_body first), and the box's (fast_body) */
    static const pf_fast_fn fns[4][4] = {
        {pf_fast_0_1, pf_fast_0_2, pf_fast_0_3, pf_fast_0_4},
        {pf_fast_1_1, pf_fast_1_2, pf_fast_1_3, pf_fast_1_4},
        {pf_fast_2_1, pf_fast_2_2, pf_fast_2_3, pf_fast_2_4},
        {pf_fast_3_1, pf_fast_3_2, pf_fast_3_3, pf_fast_3_4},
    };
    static const pf_fast_fn box[4][4] = {
        {pf_fgen_0_1, pf_fgen_0_2, pf_fgen_0_3, pf_fgen_0_4},
        {pf_fgen_1_1, pf_fgen_1_2, pf_fgen_1_3, pf_fgen_1_4},
        {pf_fgen_2_1, pf_fgen_2_2, pf_fgen_2_3, pf_fgen_2_4},
        {pf_fgen_3_1, pf_fgen_3_2, pf_fgen_3_3, pf_fgen_3_4},
    };
    if (ftype < ST_FILTER_PTEX_BOX || ftype > ST_FILTER_PTEX_MITCHELL || dt > 3 || nc < 1 ||
        nc > 4 || !pf_have_avx2())
        return NULL;
    return ftype == ST_FILTER_PTEX_BOX ? box[dt][nc - 1] : fns[dt][nc - 1];
}

/* ---- kernels at resolution 1 x 1 on faces without neighbours (pf_r0x8_select) ----------- */

/* pk_hermite_blur lane by lane, its operations in its order: |x| < 1 ? (2|x| - 3)|x||x| + 1
 * : 0 (pk_width4_axis' vector form is the same). */
PF_TARGET __m256 hermite8(__m256 x)
{
    const __m256 c1 = _mm256_set1_ps(1.0f);
    __m256 a = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), x);
    __m256 h = _mm256_mul_ps(_mm256_sub_ps(_mm256_mul_ps(_mm256_set1_ps(2.0f), a),
                                           _mm256_set1_ps(3.0f)),
                             a);
    h = _mm256_add_ps(_mm256_mul_ps(h, a), c1);
    return _mm256_and_ps(h, _mm256_cmp_ps(a, c1, _CMP_LT_OQ));
}

/* One axis of kernel_r0's kernel (ptexfilter.c's build_r0_axis) lane by lane, x in [0, 1):
 * the 2 taps at x - 1/2 rounded down (-1 or 0: the face's one texel is 0), w0 the hermite
 * weight (pk_hermite_blur's operations in its order) and w1 = 1 - w0; a zero tap stripped.
 * in: the tap on the face's texel (w1 at -1, w0 at 0); *s the axis' pk_accumulate ((0 + w0)
 * + w1 = w0 + w1, or 0 + the one tap = the one tap + the stripped 0: no weight is -0), *a
 * fold_r0's weight (black: the tap on the face; else the folded sum w0 + w1, whichever tap
 * is first: a sum of two), *one the lanes with a single tap. Returns the lanes with a tap on the face (a single tap past it
 * makes an overhang as wide as the window, which the fold declines). */
PF_TARGET __m256 r0x8_axis(__m256 x, int black, __m256 *a, __m256 *s, __m256 *one)
{
    const __m256 c1 = _mm256_set1_ps(1.0f), z = _mm256_setzero_ps();
    __m256 upix = _mm256_sub_ps(x, _mm256_set1_ps(.5f));
    __m256 t = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(upix)); /* pk_floor */
    __m256 lo = _mm256_cmp_ps(t, upix, _CMP_GT_OQ);
    __m256 ui = _mm256_sub_ps(t, _mm256_and_ps(lo, c1));
    __m256 w0 = hermite8(_mm256_sub_ps(upix, ui));
    __m256 w1 = _mm256_sub_ps(c1, w0);
    __m256 neg = _mm256_cmp_ps(ui, z, _CMP_LT_OQ); /* first tap at -1 */
    __m256 z0 = _mm256_cmp_ps(w0, z, _CMP_EQ_OQ), z1 = _mm256_cmp_ps(w1, z, _CMP_EQ_OQ);
    __m256 in = _mm256_blendv_ps(w0, w1, neg);
    *one = _mm256_or_ps(z0, z1);
    *s = _mm256_add_ps(w0, w1); /* the tap + 0 where one is stripped */
    *a = black ? in : *s;
    /* two taps, or one on the texel: w0 zero with the first tap at -1, w1 zero with it at 0 */
    return _mm256_or_ps(_mm256_andnot_ps(*one, _mm256_castsi256_ps(_mm256_set1_epi32(-1))),
                        _mm256_or_ps(_mm256_and_ps(z0, neg), _mm256_andnot_ps(neg, z1)));
}

/* The weight of r0x8's and iso8's lanes m (ok: those they take), from each axis' sum (su,
 * sv) and, in Discard, the sum of the taps it keeps (ku, kv): the scale (1 / (weight x the
 * type's one), kernel_walk_wr's division) into S, Discard's coverage into cov (weight /
 * total, 0 where total is; never over 1, kernel_walk_wr's clamp: what an axis keeps is at
 * most its sum, and rounding keeps the order of the products) and its zero-weight lanes
 * dropped. Returns the lanes left. */
PF_TARGET unsigned nonb8_weight(int discard, unsigned m, __m256 ok, __m256 su, __m256 sv,
                                __m256 ku, __m256 kv, unsigned DT, float *S, float *cov)
{
    const __m256 c1 = _mm256_set1_ps(1.0f), z = _mm256_setzero_ps();
    __m256 total = _mm256_mul_ps(su, sv), weight = total;
    if (discard) {
        weight = _mm256_mul_ps(ku, kv);
        __m256 cv = _mm256_and_ps(_mm256_div_ps(weight, total),
                                  _mm256_cmp_ps(total, z, _CMP_NEQ_OQ));
        ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(weight, z, _CMP_GT_OQ),
                                             _mm256_cmp_ps(cv, z, _CMP_GT_OQ)));
        _mm256_storeu_ps(cov, cv);
    }
    m &= (unsigned)_mm256_movemask_ps(ok);
    const float one = DT == 0 ? 255.0f : DT == 1 ? 65535.0f : 1.0f;
    _mm256_storeu_ps(S, _mm256_div_ps(c1, _mm256_mul_ps(weight, _mm256_set1_ps(one))));
    return m;
}

PF_TARGET unsigned r0x8(int blu, int blv, int discard, const pf_klanes *k, float *out,
                        float *cov, unsigned DT, unsigned NC)
{
    const __m256 c1 = _mm256_set1_ps(1.0f);
    __m256 bu = _mm256_loadu_ps(k->bu), bv = _mm256_loadu_ps(k->bv);
    unsigned m = k->nonb & (unsigned)_mm256_movemask_ps(_mm256_and_ps(
                               _mm256_cmp_ps(bu, c1, _CMP_GE_OQ), _mm256_cmp_ps(bv, c1, _CMP_GE_OQ)));
    if (!m)
        return 0;
    __m256 au, su, ou, av, sv, ov;
    __m256 ok = _mm256_and_ps(r0x8_axis(_mm256_loadu_ps(k->u), blu | discard, &au, &su, &ou),
                              r0x8_axis(_mm256_loadu_ps(k->v), blv | discard, &av, &sv, &ov));
    ok = _mm256_andnot_ps(_mm256_and_ps(ou, ov), ok); /* inside the face: the per-query path */
    float A[8], B[8], S[8];
    m = nonb8_weight(discard, m, ok, su, sv, au, av, DT, S, cov);
    if (!m)
        return 0;
    _mm256_storeu_ps(A, au);
    _mm256_storeu_ps(B, av);
    for (unsigned r = m; r; r &= r - 1) {
        unsigned j = (unsigned)__builtin_ctz(r);
        pf_v4 acc = small_body(k->px[j][0], 0, A + j, 1, B + j, 1, (pf_v4){0, 0, 0, 0}, DT, NC);
        w4x8_put(out + (size_t)j * NC, (__m128)acc, S[j], NC);
        if (!discard)
            cov[j] = 1.0f;
    }
    return m;
}

/* One axis of kernel_iso's kernel at resolution 2 (a width w in [1/2, 1) on a face of 2 or
 * more texels: pk_width4_axis' 4 hermite taps from texel -2 or 0, its operations in its
 * order) lane by lane, with pk_strip_zeros and pf_fold_axis after it: the nonzero taps are
 * one run (|x1 + i| s falls then rises), so the taps on the face's 2 texels that are not
 * zero are the window (*at its first texel, *n 1 or 2, *k0 and *k1 its weights), the
 * others the overhang, folded onto the edge texel's weight ((0 + t0) + t1 onto t2 from -2,
 * (0 + t2) + t3 onto t1 from 0: stripped zeros add +0, and no weight is -0) unless black.
 * *s the 4 taps' sum in order (pk_accumulate of the stripped ones: the same bits), *kept
 * the window's own taps' sum (Discard's weight), *over the lanes with an overhang. Returns
 * the lanes with a tap on the face. */
PF_TARGET __m256 iso8_axis(__m256 x, __m256 w, int black, __m256i *at, __m256i *n,
                           __m256 *k0, __m256 *k1, __m256 *s, __m256 *kept, __m256 *over)
{
    const __m256 c1 = _mm256_set1_ps(1.0f), z = _mm256_setzero_ps();
    __m256 upix = _mm256_sub_ps(_mm256_mul_ps(x, _mm256_set1_ps(2.0f)), _mm256_set1_ps(.5f));
    __m256 xm = _mm256_sub_ps(x, _mm256_set1_ps(.5f));
    __m256 t = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(xm)); /* pk_floor */
    __m256 fl = _mm256_sub_ps(t, _mm256_and_ps(_mm256_cmp_ps(t, xm, _CMP_GT_OQ), c1));
    __m256 neg = _mm256_cmp_ps(fl, z, _CMP_LT_OQ);           /* taps from -2, else from 0 */
    __m256 x1 = _mm256_sub_ps(_mm256_add_ps(fl, fl), upix);  /* (float)(fl * 2) - upix */
    __m256 st = _mm256_div_ps(c1, _mm256_add_ps(_mm256_mul_ps(w, _mm256_set1_ps(1.5f)),
                                                _mm256_set1_ps(.5f)));
    __m256 xa0 = _mm256_add_ps(x1, z), xa2 = _mm256_add_ps(x1, _mm256_set1_ps(2.0f));
    __m256 xs[4] = {_mm256_mul_ps(_mm256_add_ps(xa0, z), st),
                    _mm256_mul_ps(_mm256_add_ps(xa0, c1), st),
                    _mm256_mul_ps(_mm256_add_ps(xa2, z), st),
                    _mm256_mul_ps(_mm256_add_ps(xa2, c1), st)};
    __m256 tp[4];
    for (int i = 0; i < 4; i++)
        tp[i] = hermite8(xs[i]);
    *s = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(_mm256_add_ps(z, tp[0]), tp[1]), tp[2]),
                       tp[3]);
    __m256 l0 = _mm256_blendv_ps(tp[0], tp[2], neg), r0 = _mm256_blendv_ps(tp[1], tp[3], neg);
    __m256 o = _mm256_blendv_ps(_mm256_add_ps(_mm256_add_ps(z, tp[2]), tp[3]),
                                _mm256_add_ps(_mm256_add_ps(z, tp[0]), tp[1]), neg);
    __m256 l = l0, r = r0;
    if (!black) {
        l = _mm256_blendv_ps(l0, _mm256_add_ps(l0, o), neg);
        r = _mm256_blendv_ps(_mm256_add_ps(r0, o), r0, neg);
    }
    __m256 nzl = _mm256_cmp_ps(l0, z, _CMP_NEQ_OQ), nzr = _mm256_cmp_ps(r0, z, _CMP_NEQ_OQ);
    *over = _mm256_cmp_ps(o, z, _CMP_NEQ_OQ);
    *k0 = _mm256_blendv_ps(r, l, nzl);
    *k1 = r;
    *kept = _mm256_add_ps(l0, r0);
    *at = _mm256_add_epi32(_mm256_castps_si256(nzl), _mm256_set1_epi32(1)); /* 0 or 1 */
    *n = _mm256_sub_epi32(_mm256_setzero_si256(),
                          _mm256_add_epi32(_mm256_castps_si256(nzl), _mm256_castps_si256(nzr)));
    return _mm256_or_ps(nzl, nzr);
}

/* kernel_iso's kernels of widths in [1/2, 1) along both axes (resolution 2 x 2) on faces of
 * 2 x 2 texels or more without neighbours, 8 at a time: pf_r0x8_fn's contract for them
 * (lanes of k->nonb), the lanes whose kernel overhangs the face served (Traverse and Clamp:
 * kernel_iso's fold and window, the weight the 4 taps' sums' product; Discard: the overhang
 * dropped, pf_walk_fold's kept weight and kernel_walk_wr's coverage), the window the small
 * window's, as put_window picks it for at most 2 x 2 texels. */
PF_TARGET unsigned iso8(int blu, int blv, int discard, const pf_klanes *k, float *out,
                        float *cov, unsigned DT, unsigned NC)
{
    const __m256 c1 = _mm256_set1_ps(1.0f), h = _mm256_set1_ps(.5f);
    __m256 bu = _mm256_loadu_ps(k->bu), bv = _mm256_loadu_ps(k->bv);
    __m256i lg = _mm256_and_si256(
        _mm256_cmpgt_epi32(_mm256_loadu_si256((const __m256i *)(const void *)k->ulog2), _mm256_setzero_si256()),
        _mm256_cmpgt_epi32(_mm256_loadu_si256((const __m256i *)(const void *)k->vlog2), _mm256_setzero_si256()));
    __m256 in = _mm256_and_ps(
        _mm256_and_ps(_mm256_cmp_ps(bu, h, _CMP_GE_OQ), _mm256_cmp_ps(bu, c1, _CMP_LT_OQ)),
        _mm256_and_ps(_mm256_cmp_ps(bv, h, _CMP_GE_OQ), _mm256_cmp_ps(bv, c1, _CMP_LT_OQ)));
    unsigned m = k->nonb & (unsigned)_mm256_movemask_ps(_mm256_and_ps(in, _mm256_castsi256_ps(lg)));
    if (!m)
        return 0;
    __m256i atu, nu, atv, nv;
    __m256 ku0, ku1, su, kpu, ou, kv0, kv1, sv, kpv, ov;
    __m256 ok = _mm256_and_ps(
        iso8_axis(_mm256_loadu_ps(k->u), bu, blu | discard, &atu, &nu, &ku0, &ku1, &su, &kpu, &ou),
        iso8_axis(_mm256_loadu_ps(k->v), bv, blv | discard, &atv, &nv, &kv0, &kv1, &sv, &kpv, &ov));
    ok = _mm256_and_ps(ok, _mm256_or_ps(ou, ov)); /* inside the face: the per-query path */
    float U[16], V[16], S[8];
    m = nonb8_weight(discard, m, ok, su, sv, kpu, kpv, DT, S, cov);
    if (!m)
        return 0;
    int32_t AU[8], AV[8], NU[8], NV[8];
    /* lane j's weights at U + 2 j, V + 2 j */
    _mm256_storeu_ps(U, _mm256_unpacklo_ps(ku0, ku1));
    _mm256_storeu_ps(U + 8, _mm256_unpackhi_ps(ku0, ku1));
    _mm256_storeu_ps(V, _mm256_unpacklo_ps(kv0, kv1));
    _mm256_storeu_ps(V + 8, _mm256_unpackhi_ps(kv0, kv1));
    _mm256_storeu_si256((__m256i *)(void *)AU, atu);
    _mm256_storeu_si256((__m256i *)(void *)AV, atv);
    _mm256_storeu_si256((__m256i *)(void *)NU, nu);
    _mm256_storeu_si256((__m256i *)(void *)NV, nv);
    /* unpacklo / hi pair lanes within each 128-bit half: lane j's pair is at this index */
    static const unsigned char at2[8] = {0, 2, 8, 10, 4, 6, 12, 14};
    const size_t ts = (size_t)NC << (DT == 0 ? 0 : DT == 3 ? 2 : 1);
    for (unsigned r = m; r; r &= r - 1) {
        unsigned j = (unsigned)__builtin_ctz(r);
        const uint8_t *d = k->px[j][k->vlog2[j] + 2]; /* resolution (1, 1) */
        pf_v4 acc = small_body(d + ((size_t)AV[j] * 2 + (size_t)AU[j]) * ts, 2 * ts,
                               U + at2[j], NU[j], V + at2[j], NV[j], (pf_v4){0, 0, 0, 0}, DT,
                               NC);
        w4x8_put(out + (size_t)j * NC, (__m128)acc, S[j], NC);
        if (!discard)
            cov[j] = 1.0f;
    }
    return m;
}

/* The instances of r0x8 and iso8 (F) per texel type and channel count, and their tables. */
#define PF_NONB8(F, DT, NC)                                                                 \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pf_##F##_##DT##_##NC(          \
        int blu, int blv, int discard, const pf_klanes *k, float *out, float *cov)         \
    {                                                                                       \
        return F(blu, blv, discard, k, out, cov, DT, NC);                                   \
    }
#define PF_NONB8_DT(F, DT) PF_NONB8(F, DT, 1) PF_NONB8(F, DT, 2) PF_NONB8(F, DT, 3) PF_NONB8(F, DT, 4)
#define PF_NONB8_ALL(F) PF_NONB8_DT(F, 0) PF_NONB8_DT(F, 1) PF_NONB8_DT(F, 2) PF_NONB8_DT(F, 3)
PF_NONB8_ALL(r0x8)
PF_NONB8_ALL(iso8)
#define PF_ROW(F, DT) {pf_##F##_##DT##_1, pf_##F##_##DT##_2, pf_##F##_##DT##_3, pf_##F##_##DT##_4}
static const pf_r0x8_fn nonb8_fns[2][4][4] = {
    {PF_ROW(r0x8, 0), PF_ROW(r0x8, 1), PF_ROW(r0x8, 2), PF_ROW(r0x8, 3)},
    {PF_ROW(iso8, 0), PF_ROW(iso8, 1), PF_ROW(iso8, 2), PF_ROW(iso8, 3)},
};
#undef PF_ROW

static pf_r0x8_fn nonb8_select(int iso, unsigned dt, unsigned nc)
{
    if (nc < 1 || nc > 4 || dt > 3 || !pf_have_avx2())
        return NULL;
    return nonb8_fns[iso][dt][nc - 1];
}

pf_r0x8_fn pf_r0x8_select(unsigned dt, unsigned nc) { return nonb8_select(0, dt, nc); }
pf_r0x8_fn pf_iso8_select(unsigned dt, unsigned nc) { return nonb8_select(1, dt, nc); }

/* (int)pk_ceil(x) of 8 floats: the rounding instruction's ceiling, truncated (the same
 * integers: pk_ceil differs from it only in the sign of a zero). */
PF_TARGET __m256i iceil8(__m256 x)
{
    return _mm256_cvttps_epi32(_mm256_ceil_ps(x));
}

/* pk_strip_zeros' ends, a tap at a time: where tap i's weight t is not zero
 * (pk_nonzero_mask's unordered compare) the first nonzero tap *a moves down to i and the
 * last *b up to i, lane by lane. */
PF_TARGET void nz_ends8(__m256 t, int i, __m256i *a, __m256i *b)
{
    __m256i nz = _mm256_castps_si256(_mm256_cmp_ps(t, _mm256_setzero_ps(), _CMP_NEQ_UQ));
    *a = _mm256_blendv_epi8(*a, _mm256_min_epi32(*a, _mm256_set1_epi32(i)), nz);
    *b = _mm256_blendv_epi8(*b, _mm256_set1_epi32(i), nz);
}

/* One axis of pf_q8 for 8 lanes: x the coordinates, bw the widths, lg the faces' log2
 * sizes. pk_width4_axis lane by lane (the width clamped to the face's texel first, NaN to
 * it as well; the band's branch: taps from u1 = (int)ceil(upix - 2) rounded down to even to
 * (int)ceil(upix + 2) + 1 rounded down to even, x1 = u1 - upix, step 1), the weights as
 * pf_kernel_eval2_avx2 evaluates them (x1 + i * 1 is x1 + i). For (u, v) in [0, 1) the
 * taps start at -2 or 0 (4 or 6 of them) or at 2 (4; other lanes are not ok): the taps on
 * texels 0..3 are w[q] = t[q + 2], t[q] or t[q - 2], the overhang t0, t1 (left, from -2),
 * t4, t5 (right, 6 from 0) or t2, t3 (right, from 2). pk_strip_zeros keeps the taps from
 * the first to the last nonzero one (pa, pb their texels): the window is [max(pa, 0),
 * min(pb, 3)] (first, n), it overhangs where pa < 0 or pb > 3, and the fold declines where
 * it lies past the face. Sums in tap order from 0
 * (pk_accumulate): zero taps add +0 and change no bits (no weight is -0, no sum of nonzero
 * weights is -0), so the whole kernel's sum is the stripped one's (*s), the texels' 0..3
 * the kept one (*kept, Discard), the overhang's the fold's; a fold adds it to w[0] or w[3]
 * (an overhang of zeros adds +0). black: no fold. */
typedef struct {
    __m256 w[4], s, kept, ok, over;
    __m256i first, n;
} q8_ax;

PF_TARGET void q8_axis(const pk_params *p, __m256 x, __m256 bw, __m256i lg, int black,
                       q8_ax *o)
{
    const __m256 q4 = _mm256_set1_ps(.25f), h = _mm256_set1_ps(.5f), c2 = _mm256_set1_ps(2.0f);
    const __m256 z = _mm256_setzero_ps();
    const __m256i even = _mm256_set1_epi32(~1);
    const __m256i i0 = _mm256_setzero_si256(), i3 = _mm256_set1_epi32(3);
    __m256 w = pf_w4_clamp8(bw, lg);
    __m256 band = _mm256_and_ps(_mm256_cmp_ps(w, q4, _CMP_GE_OQ), _mm256_cmp_ps(w, h, _CMP_LT_OQ));
    __m256 upix = _mm256_sub_ps(_mm256_mul_ps(x, _mm256_set1_ps(4.0f)), h);
    __m256i u1 = _mm256_and_si256(iceil8(_mm256_sub_ps(upix, c2)), even);
    __m256i u2 = _mm256_and_si256(
        _mm256_add_epi32(iceil8(_mm256_add_ps(upix, c2)), _mm256_set1_epi32(1)),
        even);
    __m256i kw = _mm256_sub_epi32(u2, u1);
    __m256i neg = _mm256_cmpeq_epi32(u1, _mm256_set1_epi32(-2)), zero = _mm256_cmpeq_epi32(u1, i0);
    __m256i six = _mm256_cmpeq_epi32(kw, _mm256_set1_epi32(6));
    __m256i four = _mm256_cmpeq_epi32(kw, _mm256_set1_epi32(4));
    /* from -2 or 0 with 4 or 6 taps, or from 2 with 4 */
    __m256 shape = _mm256_castsi256_ps(_mm256_or_si256(
        _mm256_and_si256(_mm256_or_si256(neg, zero), _mm256_or_si256(six, four)),
        _mm256_and_si256(_mm256_cmpeq_epi32(u1, _mm256_set1_epi32(2)), four)));
    __m256 x1 = _mm256_sub_ps(_mm256_cvtepi32_ps(u1), upix);
    __m256 t[6];
    for (int i = 0; i < 6; i++)
        t[i] = kernel8(p, _mm256_add_ps(x1, _mm256_set1_ps((float)i)));
    t[4] = _mm256_and_ps(t[4], _mm256_castsi256_ps(six)); /* no taps past the fourth */
    t[5] = _mm256_and_ps(t[5], _mm256_castsi256_ps(six));
    /* the first and last nonzero tap */
    __m256i a = _mm256_set1_epi32(6), b = _mm256_set1_epi32(-1);
    for (int i = 0; i < 6; i++)
        nz_ends8(t[i], i, &a, &b);
    __m256i pa = _mm256_add_epi32(u1, a), pb = _mm256_add_epi32(u1, b);
    /* a tap left (b >= 0), on the face: pa <= 3 and pb >= 0 */
    __m256i on = _mm256_andnot_si256(
        _mm256_or_si256(_mm256_cmpgt_epi32(i0, b),
                        _mm256_or_si256(_mm256_cmpgt_epi32(pa, i3), _mm256_cmpgt_epi32(i0, pb))),
        _mm256_set1_epi32(-1));
    o->ok = _mm256_and_ps(_mm256_and_ps(band, shape), _mm256_castsi256_ps(on));
    o->over = _mm256_castsi256_ps(_mm256_or_si256(_mm256_cmpgt_epi32(i0, pa),
                                                  _mm256_cmpgt_epi32(pb, i3)));
    o->first = _mm256_max_epi32(pa, i0);
    o->n = _mm256_sub_epi32(_mm256_add_epi32(_mm256_min_epi32(pb, i3), _mm256_set1_epi32(1)),
                            o->first);
    __m256 s = z;
    for (int i = 0; i < 6; i++)
        s = _mm256_add_ps(s, t[i]);
    o->s = s;
    /* texels 0..3: taps 2..5 from -2, 0..3 from 0, none, none, 0, 1 from 2 */
    __m256 nf = _mm256_castsi256_ps(neg), zf = _mm256_castsi256_ps(zero);
    o->w[0] = _mm256_blendv_ps(_mm256_and_ps(t[0], zf), t[2], nf);
    o->w[1] = _mm256_blendv_ps(_mm256_and_ps(t[1], zf), t[3], nf);
    o->w[2] = _mm256_blendv_ps(_mm256_blendv_ps(t[0], t[2], zf), t[4], nf);
    o->w[3] = _mm256_blendv_ps(_mm256_blendv_ps(t[1], t[3], zf), t[5], nf);
    o->kept = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(_mm256_add_ps(z, o->w[0]), o->w[1]),
                                          o->w[2]),
                            o->w[3]);
    if (!black) {
        __m256 l = _mm256_and_ps(_mm256_add_ps(_mm256_add_ps(z, t[0]), t[1]), nf);
        __m256 r = _mm256_andnot_ps(nf, _mm256_blendv_ps(_mm256_add_ps(_mm256_add_ps(z, t[2]), t[3]),
                                                         _mm256_add_ps(_mm256_add_ps(z, t[4]), t[5]),
                                                         zf));
        o->w[3] = _mm256_add_ps(o->w[3], r); /* pk_merge_r first, then _l */
        o->w[0] = _mm256_add_ps(o->w[0], l);
    }
}

/* pf_q8_fn */
__attribute__((target("avx2,fma,f16c"))) static unsigned q8(const pk_params *p,
                                                            const pf_klanes *k, unsigned m,
                                                            int blu, int blv, int discard,
                                                            unsigned dt, pf_q8 *t)
{
    const __m256 z = _mm256_setzero_ps(), c1 = _mm256_set1_ps(1.0f);
    q8_ax au, av;
    q8_axis(p, _mm256_loadu_ps(k->u), _mm256_loadu_ps(k->bu),
            _mm256_loadu_si256((const __m256i *)(const void *)k->ulog2), blu | discard, &au);
    q8_axis(p, _mm256_loadu_ps(k->v), _mm256_loadu_ps(k->bv),
            _mm256_loadu_si256((const __m256i *)(const void *)k->vlog2), blv | discard, &av);
    __m256 ok = _mm256_and_ps(au.ok, av.ok), over = _mm256_or_ps(au.over, av.over);
    __m256 total = _mm256_mul_ps(au.s, av.s), weight = total, cv = c1;
    if (discard) {
        /* the kept taps' weight and its share of the total; lanes keeping none are left to
         * eval_kernel. Inside the face the window holds every nonzero tap, so the kept sum is
         * the total's bits (the taps it leaves are zeros added first or last) and the share
         * 1 where the total is in (0, +inf): Traverse's result, as eval_kernel gives it */
        weight = _mm256_mul_ps(au.kept, av.kept);
        cv = _mm256_and_ps(_mm256_div_ps(weight, total), _mm256_cmp_ps(total, z, _CMP_NEQ_OQ));
        cv = _mm256_blendv_ps(cv, c1, _mm256_cmp_ps(cv, c1, _CMP_GT_OQ));
        ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(weight, z, _CMP_GT_OQ),
                                             _mm256_cmp_ps(cv, z, _CMP_GT_OQ)));
    }
    m &= (unsigned)_mm256_movemask_ps(ok);
    if (!m)
        return 0;
    const float one = dt == 0 ? 255.0f : dt == 1 ? 65535.0f : 1.0f;
    _mm256_storeu_ps(t->scale, _mm256_div_ps(c1, _mm256_mul_ps(weight, _mm256_set1_ps(one))));
    _mm256_storeu_ps(t->cov, cv);
    /* the small window: an overhang and at most 2 x 2 taps ((n - 1) unsigned < 2 each) */
    __m256i two = _mm256_set1_epi32(2), n1 = _mm256_set1_epi32(1);
    __m256i sm = _mm256_and_si256(
        _mm256_cmpgt_epi32(two, _mm256_sub_epi32(au.n, n1)),
        _mm256_cmpgt_epi32(two, _mm256_sub_epi32(av.n, n1)));
    t->small = (unsigned)_mm256_movemask_ps(_mm256_and_ps(over, _mm256_castsi256_ps(sm)));
    _mm256_storeu_si256((__m256i *)(void *)t->u, au.first);
    _mm256_storeu_si256((__m256i *)(void *)t->v, av.first);
    _mm256_storeu_si256((__m256i *)(void *)t->nu, au.n);
    _mm256_storeu_si256((__m256i *)(void *)t->nv, av.n);
    /* lane j's 4 weights at wu[j]: the 4 x 8 transposed (unpack within halves, then the
     * 128-bit halves: lanes 0-3 in the low half of each, 4-7 in the high) */
    for (int a = 0; a < 2; a++) {
        const __m256 *w = a ? av.w : au.w;
        float(*d)[4] = a ? t->wv : t->wu;
        __m256 l01 = _mm256_unpacklo_ps(w[0], w[1]), h01 = _mm256_unpackhi_ps(w[0], w[1]);
        __m256 l23 = _mm256_unpacklo_ps(w[2], w[3]), h23 = _mm256_unpackhi_ps(w[2], w[3]);
        __m256 r0 = _mm256_shuffle_ps(l01, l23, 0x44), r1 = _mm256_shuffle_ps(l01, l23, 0xee);
        __m256 r2 = _mm256_shuffle_ps(h01, h23, 0x44), r3 = _mm256_shuffle_ps(h01, h23, 0xee);
        /* r0 = lanes 0 and 4, r1 = 1 and 5, r2 = 2 and 6, r3 = 3 and 7 */
        _mm256_storeu_ps(d[0], _mm256_permute2f128_ps(r0, r1, 0x20));
        _mm256_storeu_ps(d[2], _mm256_permute2f128_ps(r2, r3, 0x20));
        _mm256_storeu_ps(d[4], _mm256_permute2f128_ps(r0, r1, 0x31));
        _mm256_storeu_ps(d[6], _mm256_permute2f128_ps(r2, r3, 0x31));
    }
    return m;
}

pf_q8_fn pf_q8_select(void)
{
    return pf_have_avx2() ? q8 : NULL;
}

/* One axis of pf_b8 for 8 lanes (x the coordinates, bw the widths, lg the faces' log2
 * sizes; m the lanes wanted): pk_width4_axis after its clamp of the width w to a texel of
 * the face (NaN to it too), in its three bands of widths under 1 (the lanes past 1 are
 * not ok). Under 1/4: resolution r = res_from_width(w) (the exponent's), upix = x 2^r -
 * 1/2, uwpix = w 2^r, taps from (int)ceil(upix - 2 uwpix) to (int)ceil(upix + 2 uwpix)
 * (4 to 8: uwpix is in [1, 2)), x1 = (u1 - upix) / uwpix, step 1 / uwpix. [1/4, 1/2):
 * resolution 2, upix = 4 x - 1/2, taps from (int)ceil(upix - 2) rounded down to even to
 * (int)ceil(upix + 2) + 1 rounded down to even (4 or 6), x1 = u1 - upix, step 1: the
 * first band's steps with uwpix 1 (a division by 1 and a product with 1 are exact), so
 * one evaluation for both, x1 + i step as pf_kernel_eval2_avx2 evaluates it. [1/2, 1):
 * resolution 1, 4 taps from pk_ifloor(x - 1/2) * 2, pk_width4_axis' hermite weights with
 * its operations in its order (((x1 + {0, 0, 2, 2}) + {0, 1, 0, 1}) * s, |.|, ((2x - 3) x)
 * x + 1 below 1, else 0). t[0..8) the taps (+0 past the last), s their sum in order from 0
 * (pk_accumulate of the stripped ones: zero taps add +0, and no such sum is -0), then
 * pk_strip_zeros' window: the first nonzero tap k0, the window's first texel at and its n
 * taps; ok: a band and a nonzero tap. */
typedef struct {
    __m256 t[8], s, ok;
    __m256i lg, at, n, k0;
} b8_ax;

PF_TARGET void b8_axis(const pk_params *p, __m256 x, __m256 bw, __m256i lg, unsigned m,
                       int GAUSS, b8_ax *o)
{
    const __m256 q4 = _mm256_set1_ps(.25f), h = _mm256_set1_ps(.5f), c1 = _mm256_set1_ps(1.0f);
    const __m256 c2 = _mm256_set1_ps(2.0f), z = _mm256_setzero_ps();
    const __m256i e127 = _mm256_set1_epi32(127), i0 = _mm256_setzero_si256();
    const __m256i even = _mm256_set1_epi32(~1);
    __m256 w = pf_w4_clamp8(bw, lg);
    __m256 lth = _mm256_cmp_ps(w, h, _CMP_LT_OQ), ltq = _mm256_cmp_ps(w, q4, _CMP_LT_OQ);
    __m256 ba = _mm256_andnot_ps(ltq, lth);                               /* [1/4, 1/2) */
    __m256 bb = _mm256_andnot_ps(lth, _mm256_cmp_ps(w, c1, _CMP_LT_OQ)); /* [1/2, 1) */
    __m256 bc = _mm256_cmp_ps(w, c1, _CMP_GE_OQ);                        /* 1 or more */
    __m256 be = _mm256_or_ps(ltq, ba);                                    /* evaluated */
    __m256i bai = _mm256_castps_si256(ba);
    unsigned me = (unsigned)_mm256_movemask_ps(be) & m, mb = (unsigned)_mm256_movemask_ps(bb) & m;
    unsigned mc = (unsigned)_mm256_movemask_ps(bc) & m;
    __m256i u1 = i0, kw = i0;
    __m256i r = _mm256_sub_epi32(e127, _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(w), 23),
                                                        _mm256_set1_epi32(0xff)));
    r = _mm256_min_epi32(_mm256_max_epi32(r, i0), _mm256_set1_epi32(30));
    r = _mm256_blendv_epi8(r, _mm256_set1_epi32(2), bai);
    __m256 sum = z;
    __m256i a = _mm256_set1_epi32(8), b = _mm256_set1_epi32(-1);
    _Pragma("GCC unroll 8") for (int i = 0; i < 8; i++) o->t[i] = z;
    if (me) {
        __m256 rf = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(r, e127), 23));
        __m256 upix = _mm256_sub_ps(_mm256_mul_ps(x, rf), h);
        __m256 uwpix = _mm256_blendv_ps(_mm256_mul_ps(w, rf), c1, ba);
        __m256 dupix = _mm256_mul_ps(c2, uwpix);
        u1 = iceil8(_mm256_sub_ps(upix, dupix));
        __m256i u2 = iceil8(_mm256_add_ps(upix, dupix));
        u1 = _mm256_blendv_epi8(u1, _mm256_and_si256(u1, even), bai);
        u2 = _mm256_blendv_epi8(u2, _mm256_and_si256(_mm256_add_epi32(u2, _mm256_set1_epi32(1)), even),
                                bai);
        kw = _mm256_sub_epi32(u2, u1);
        /* at most 8 taps (always but where float spacing at 2^r texels is too coarse) */
        be = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(kw, _mm256_set1_epi32(8))),
                              be);
        kw = _mm256_and_si256(kw, _mm256_castps_si256(be));
        __m256 x1 = _mm256_div_ps(_mm256_sub_ps(_mm256_cvtepi32_ps(u1), upix), uwpix);
        __m256 st = _mm256_div_ps(c1, uwpix);
        /* the taps of the wanted lanes' longest kernel */
        __m256i kmax = _mm256_and_si256(
            kw, _mm256_castps_si256(_mm256_and_ps(be, _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                                                           _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128) &
                                                               _mm256_set1_epi32((int)m),
                                                           i0)))));
        kmax = _mm256_max_epi32(kmax, _mm256_shuffle_epi32(kmax, 0x4e));
        kmax = _mm256_max_epi32(kmax, _mm256_shuffle_epi32(kmax, 0xb1));
        kmax = _mm256_max_epi32(kmax, _mm256_permute2x128_si256(kmax, kmax, 1));
        int nt = _mm256_cvtsi256_si32(kmax);
        _Pragma("GCC unroll 8") for (int i = 0; i < 8; i++) {
            if (i >= nt)
                break;
            __m256 t = kernel8_as(p, _mm256_add_ps(x1, _mm256_mul_ps(_mm256_set1_ps((float)i), st)),
                                  GAUSS);
            o->t[i] = _mm256_and_ps(t, _mm256_castsi256_ps(_mm256_cmpgt_epi32(kw, _mm256_set1_epi32(i))));
        }
    }
    if (mb) {
        __m256 upix = _mm256_sub_ps(_mm256_mul_ps(x, c2), h);
        __m256i ku = _mm256_slli_epi32(_mm256_cvttps_epi32(_mm256_floor_ps(_mm256_sub_ps(x, h))), 1);
        __m256 x1 = _mm256_sub_ps(_mm256_cvtepi32_ps(ku), upix);
        __m256 s = _mm256_div_ps(c1, _mm256_add_ps(_mm256_mul_ps(w, _mm256_set1_ps(1.5f)), h));
        const __m256 ab = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
        _Pragma("GCC unroll 4") for (int i = 0; i < 4; i++) {
            __m256 xi = _mm256_add_ps(_mm256_add_ps(x1, _mm256_set1_ps(i & 2 ? 2.0f : 0.0f)),
                                      _mm256_set1_ps(i & 1 ? 1.0f : 0.0f));
            xi = _mm256_and_ps(_mm256_mul_ps(xi, s), ab);
            __m256 hh = _mm256_add_ps(
                _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(_mm256_mul_ps(c2, xi),
                                                          _mm256_set1_ps(3.0f)),
                                            xi),
                              xi),
                c1);
            hh = _mm256_and_ps(hh, _mm256_and_ps(_mm256_cmp_ps(xi, c1, _CMP_LT_OQ), bb));
            o->t[i] = _mm256_or_ps(o->t[i], hh); /* the evaluated lanes are +0 here */
        }
        u1 = _mm256_blendv_epi8(u1, ku, _mm256_castps_si256(bb));
        r = _mm256_blendv_epi8(r, _mm256_set1_epi32(1), _mm256_castps_si256(bb));
    }
    if (mc) {
        /* resolution 0, 2 taps from pk_floor(x - 1/2) (floor's value: they differ only in
         * the sign of a zero, which the hermite's |.| drops), hermite_blur of the distance
         * to it, then 1 minus that */
        __m256 upix = _mm256_sub_ps(x, h);
        __m256 ui = _mm256_floor_ps(upix);
        __m256 d = _mm256_and_ps(_mm256_sub_ps(upix, ui),
                                 _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)));
        __m256 w0 = _mm256_add_ps(
            _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(_mm256_mul_ps(c2, d), _mm256_set1_ps(3.0f)),
                                        d),
                          d),
            c1);
        w0 = _mm256_and_ps(w0, _mm256_cmp_ps(d, c1, _CMP_LT_OQ));
        __m256 w1 = _mm256_sub_ps(c1, w0);
        o->t[0] = _mm256_or_ps(o->t[0], _mm256_and_ps(w0, bc)); /* the others' lanes: +0 */
        o->t[1] = _mm256_or_ps(o->t[1], _mm256_and_ps(w1, bc));
        u1 = _mm256_blendv_epi8(u1, _mm256_cvttps_epi32(ui), _mm256_castps_si256(bc));
        r = _mm256_blendv_epi8(r, i0, _mm256_castps_si256(bc));
    }
    if (GAUSS) {
        /* the gaussian's taps are never zero (exp2 of at least -126; NaN to -126): the
         * evaluated ones kept whole, the first at 0; the hermite lanes' ends from their 4
         * taps (+0 past them) */
        _Pragma("GCC unroll 8") for (int i = 0; i < 8; i++) sum = _mm256_add_ps(sum, o->t[i]);
        a = i0;
        b = _mm256_sub_epi32(kw, _mm256_set1_epi32(1));
        if (mb | mc) {
            __m256i ah = _mm256_set1_epi32(8), bh = _mm256_set1_epi32(-1);
            _Pragma("GCC unroll 4") for (int i = 0; i < 4; i++) nz_ends8(o->t[i], i, &ah, &bh);
            __m256i hm = _mm256_castps_si256(_mm256_or_ps(bb, bc));
            a = _mm256_blendv_epi8(a, ah, hm);
            b = _mm256_blendv_epi8(b, bh, hm);
        }
    } else {
        _Pragma("GCC unroll 8") for (int i = 0; i < 8; i++) {
            sum = _mm256_add_ps(sum, o->t[i]);
            nz_ends8(o->t[i], i, &a, &b);
        }
    }
    o->lg = r;
    o->s = sum;
    o->ok = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(i0, b)),
                             _mm256_or_ps(_mm256_or_ps(be, bb), bc));
    o->k0 = a;
    o->at = _mm256_add_epi32(u1, a);
    o->n = _mm256_sub_epi32(_mm256_add_epi32(b, _mm256_set1_epi32(1)), a);
}

/* The 8 x 8 transpose: r[j] lane i = a[i] lane j. */
PF_TARGET void tr8x8(const __m256 a[8], __m256 r[8])
{
    __m256 l01 = _mm256_unpacklo_ps(a[0], a[1]), h01 = _mm256_unpackhi_ps(a[0], a[1]);
    __m256 l23 = _mm256_unpacklo_ps(a[2], a[3]), h23 = _mm256_unpackhi_ps(a[2], a[3]);
    __m256 l45 = _mm256_unpacklo_ps(a[4], a[5]), h45 = _mm256_unpackhi_ps(a[4], a[5]);
    __m256 l67 = _mm256_unpacklo_ps(a[6], a[7]), h67 = _mm256_unpackhi_ps(a[6], a[7]);
    __m256 q0 = _mm256_shuffle_ps(l01, l23, 0x44), q1 = _mm256_shuffle_ps(l01, l23, 0xee);
    __m256 q2 = _mm256_shuffle_ps(h01, h23, 0x44), q3 = _mm256_shuffle_ps(h01, h23, 0xee);
    __m256 q4 = _mm256_shuffle_ps(l45, l67, 0x44), q5 = _mm256_shuffle_ps(l45, l67, 0xee);
    __m256 q6 = _mm256_shuffle_ps(h45, h67, 0x44), q7 = _mm256_shuffle_ps(h45, h67, 0xee);
    r[0] = _mm256_permute2f128_ps(q0, q4, 0x20);
    r[1] = _mm256_permute2f128_ps(q1, q5, 0x20);
    r[2] = _mm256_permute2f128_ps(q2, q6, 0x20);
    r[3] = _mm256_permute2f128_ps(q3, q7, 0x20);
    r[4] = _mm256_permute2f128_ps(q0, q4, 0x31);
    r[5] = _mm256_permute2f128_ps(q1, q5, 0x31);
    r[6] = _mm256_permute2f128_ps(q2, q6, 0x31);
    r[7] = _mm256_permute2f128_ps(q3, q7, 0x31);
}

/* pf_b8_fn, GAUSS: the gaussian (else the bicubic family) */
PF_TARGET unsigned b8(const pk_params *p, const pf_klanes *k, unsigned m, pk *kout, float *wout,
                      int GAUSS)
{
    /* not kernel_r0's (both widths as given 1 or more); under 4 lanes left: none (the
     * per-query build costs less) */
    const __m256 c1 = _mm256_set1_ps(1.0f);
    __m256 r0 = _mm256_and_ps(_mm256_cmp_ps(_mm256_loadu_ps(k->bu), c1, _CMP_GE_OQ),
                              _mm256_cmp_ps(_mm256_loadu_ps(k->bv), c1, _CMP_GE_OQ));
    m &= ~(unsigned)_mm256_movemask_ps(r0);
    if (!pf_bits_atleast(m, 4))
        return 0;
    b8_ax au, av;
    __m256i lgu = _mm256_loadu_si256((const __m256i *)(const void *)k->ulog2);
    __m256i lgv = _mm256_loadu_si256((const __m256i *)(const void *)k->vlog2);
    b8_axis(p, _mm256_loadu_ps(k->u), _mm256_loadu_ps(k->bu), lgu, m, GAUSS, &au);
    b8_axis(p, _mm256_loadu_ps(k->v), _mm256_loadu_ps(k->bv), lgv, m, GAUSS, &av);
    __m256 ok = _mm256_and_ps(au.ok, av.ok);
    m &= (unsigned)_mm256_movemask_ps(ok);
    if (!m)
        return 0;
    float wt[8];
    _mm256_storeu_ps(wt, _mm256_mul_ps(au.s, av.s)); /* pk_build_w4s' wu * wv */
    _Static_assert(offsetof(pk, vlog2) == 4 && offsetof(pk, u) == 8 && offsetof(pk, v) == 12 &&
                       offsetof(pk, uw) == 16 && offsetof(pk, vw) == 20 &&
                       offsetof(pk, ku0) == 24 && offsetof(pk, kv0) == 28 &&
                       offsetof(pk, rot) == 32 && PK_MAX >= 8,
                   "pk: ulog2 vlog2 u v uw vw ku0 kv0, then rot");
    __m256 hd[8] = {_mm256_castsi256_ps(au.lg), _mm256_castsi256_ps(av.lg),
                    _mm256_castsi256_ps(au.at), _mm256_castsi256_ps(av.at),
                    _mm256_castsi256_ps(au.n),  _mm256_castsi256_ps(av.n),
                    _mm256_castsi256_ps(au.k0), _mm256_castsi256_ps(av.k0)};
    __m256 rh[8], ru[8], rv[8];
    tr8x8(hd, rh);
    tr8x8(au.t, ru);
    tr8x8(av.t, rv);
    for (unsigned r = m; r; r &= r - 1) {
        unsigned j = (unsigned)__builtin_ctz(r);
        pk *kj = kout + j;
        _mm256_storeu_ps((float *)(void *)kj, rh[j]);
        kj->rot = 0;
        _mm256_storeu_ps(kj->kub, ru[j]);
        _mm256_storeu_ps(kj->kvb, rv[j]);
        wout[j] = wt[j];
    }
    return m;
}

__attribute__((target("avx2,fma,f16c"))) static unsigned b8_gauss(const pk_params *p,
                                                                  const pf_klanes *k,
                                                                  unsigned m, pk *kout,
                                                                  float *wout)
{
    return b8(p, k, m, kout, wout, 1);
}
__attribute__((target("avx2,fma,f16c"))) static unsigned b8_cubic(const pk_params *p,
                                                                  const pf_klanes *k,
                                                                  unsigned m, pk *kout,
                                                                  float *wout)
{
    return b8(p, k, m, kout, wout, 0);
}

pf_b8_fn pf_b8_select(unsigned ftype)
{
    if (!pf_have_avx2() || ftype <= ST_FILTER_PTEX_BOX)
        return NULL;
    return ftype == ST_FILTER_PTEX_GAUSSIAN ? b8_gauss : b8_cubic;
}

/* One axis of pf_cst8's width-4 kernel, 8 lanes: pk_width4_axis' branch for a width under
 * 1/4 (after the clamp to the face's texel, NaN clamped too; the lanes at 1/4 or more are
 * not ok): resolution r = 127 - the width's exponent (0..30), upix = x 2^r - 0.5, uwpix =
 * w 2^r, taps from (int)ceil(upix - 2 uwpix) to (int)ceil(upix + 2 uwpix) (at most 8, else
 * not ok), x1 = (u1 - upix) / uwpix, step 1 / uwpix; the weights as pf_kernel_eval2_avx2
 * evaluates them (x1 + i step). *s the taps' sum in order from 0 (pk_accumulate of the
 * stripped ones: zero taps add +0). ok: a nonzero tap, and the first to the last nonzero
 * one lie on [0, 2^r). */
PF_TARGET __m256 cst8_w4_axis(const pk_params *p, __m256 x, __m256 w, __m256 *s)
{
    const __m256 z = _mm256_setzero_ps(), h = _mm256_set1_ps(.5f);
    const __m256i e127 = _mm256_set1_epi32(127), i0 = _mm256_setzero_si256();
    __m256 ok = _mm256_cmp_ps(w, _mm256_set1_ps(.25f), _CMP_LT_OQ);
    __m256i r = _mm256_sub_epi32(e127, _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(w), 23),
                                                        _mm256_set1_epi32(0xff)));
    r = _mm256_min_epi32(_mm256_max_epi32(r, i0), _mm256_set1_epi32(30));
    __m256 rf = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(r, e127), 23));
    __m256 upix = _mm256_sub_ps(_mm256_mul_ps(x, rf), h);
    __m256 uwpix = _mm256_mul_ps(w, rf);
    __m256 dupix = _mm256_mul_ps(_mm256_set1_ps(2.0f), uwpix);
    __m256i u1 = iceil8(_mm256_sub_ps(upix, dupix));
    __m256i u2 = iceil8(_mm256_add_ps(upix, dupix));
    __m256i kw = _mm256_sub_epi32(u2, u1);
    ok = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(kw, _mm256_set1_epi32(8))), ok);
    __m256 x1 = _mm256_div_ps(_mm256_sub_ps(_mm256_cvtepi32_ps(u1), upix), uwpix);
    __m256 st = _mm256_div_ps(_mm256_set1_ps(1.0f), uwpix);
    __m256i a = _mm256_set1_epi32(8), b = _mm256_set1_epi32(-1);
    __m256 sum = z;
    /* the taps of the ok lanes' longest kernel (most have 4 or 5) */
    __m256i kmax = _mm256_and_si256(kw, _mm256_castps_si256(ok));
    kmax = _mm256_max_epi32(kmax, _mm256_shuffle_epi32(kmax, 0x4e));
    kmax = _mm256_max_epi32(kmax, _mm256_shuffle_epi32(kmax, 0xb1));
    kmax = _mm256_max_epi32(kmax, _mm256_permute2x128_si256(kmax, kmax, 1));
    int nt = _mm256_cvtsi256_si32(kmax);
    for (int i = 0; i < 8 && i < nt; i++) {
        __m256 t = kernel8(p, _mm256_add_ps(x1, _mm256_mul_ps(_mm256_set1_ps((float)i), st)));
        __m256i in = _mm256_cmpgt_epi32(kw, _mm256_set1_epi32(i));
        t = _mm256_and_ps(t, _mm256_castsi256_ps(in)); /* past the taps: +0 */
        sum = _mm256_add_ps(sum, t);
        nz_ends8(t, i, &a, &b);
    }
    *s = sum;
    __m256i pa = _mm256_add_epi32(u1, a), pb1 = _mm256_add_epi32(_mm256_add_epi32(u1, b),
                                                                   _mm256_set1_epi32(1));
    __m256i res = _mm256_sllv_epi32(_mm256_set1_epi32(1), r);
    __m256i bad = _mm256_or_si256(_mm256_cmpgt_epi32(i0, b),
                                  _mm256_or_si256(_mm256_cmpgt_epi32(i0, pa),
                                                  _mm256_cmpgt_epi32(pb1, res)));
    return _mm256_andnot_ps(_mm256_castsi256_ps(bad), ok);
}

/* The weight of pf_cst8's lanes ok from the axes' sums: in (0, +inf), stored at w. */
PF_TARGET unsigned cst8_weight(unsigned m, __m256 ok, __m256 su, __m256 sv, float *w)
{
    __m256 tw = _mm256_mul_ps(su, sv); /* pk_weight */
    ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(tw, _mm256_setzero_ps(), _CMP_GT_OQ),
                                         _mm256_cmp_ps(tw, _mm256_set1_ps(3.40282347e38f),
                                                       _CMP_LE_OQ)));
    _mm256_storeu_ps(w, tw);
    return m & (unsigned)_mm256_movemask_ps(ok);
}

/* pf_cst8_fn for the width-4 filters */
__attribute__((target("avx2,fma,f16c"))) static unsigned cst8_w4(const pk_params *p,
                                                                const pf_klanes *k,
                                                                unsigned m, float *w)
{
    __m256 su, sv, q4 = _mm256_set1_ps(.25f);
    __m256 wu = pf_w4_clamp8(_mm256_loadu_ps(k->bu),
                           _mm256_loadu_si256((const __m256i *)(const void *)k->ulog2));
    __m256 wv = pf_w4_clamp8(_mm256_loadu_ps(k->bv),
                           _mm256_loadu_si256((const __m256i *)(const void *)k->vlog2));
    m &= (unsigned)_mm256_movemask_ps(_mm256_and_ps(_mm256_cmp_ps(wu, q4, _CMP_LT_OQ),
                                                    _mm256_cmp_ps(wv, q4, _CMP_LT_OQ)));
    if (!m) /* no width under 1/4: no taps evaluated */
        return 0;
    __m256 ok = cst8_w4_axis(p, _mm256_loadu_ps(k->u), wu, &su);
    ok = _mm256_and_ps(ok, cst8_w4_axis(p, _mm256_loadu_ps(k->v), wv, &sv));
    return cst8_weight(m, ok, su, sv, w);
}

/* pf_cst8_fn for the box: box8_axis' kernel (no zero weight at an end), inside the face */
__attribute__((target("avx2,fma,f16c"))) static unsigned cst8_box(const pk_params *p,
                                                                 const pf_klanes *k,
                                                                 unsigned m, float *w)
{
    (void)p;
    const __m256i z = _mm256_setzero_si256(), one = _mm256_set1_epi32(1);
    box8_ax au, av;
    box8_axis(_mm256_loadu_ps(k->u), _mm256_loadu_ps(k->bu),
              _mm256_loadu_si256((const __m256i *)(const void *)k->ulog2), &au);
    box8_axis(_mm256_loadu_ps(k->v), _mm256_loadu_ps(k->bv),
              _mm256_loadu_si256((const __m256i *)(const void *)k->vlog2), &av);
    __m256i bad = _mm256_or_si256(
        _mm256_or_si256(au.bad, av.bad),
        _mm256_or_si256(
            _mm256_or_si256(_mm256_cmpgt_epi32(z, au.a),
                            _mm256_cmpgt_epi32(_mm256_add_epi32(au.a, au.n), _mm256_sllv_epi32(one, au.r))),
            _mm256_or_si256(_mm256_cmpgt_epi32(z, av.a),
                            _mm256_cmpgt_epi32(_mm256_add_epi32(av.a, av.n), _mm256_sllv_epi32(one, av.r)))));
    return cst8_weight(m, _mm256_castsi256_ps(_mm256_andnot_si256(bad, _mm256_set1_epi32(-1))),
                       au.sm, av.sm, w);
}

pf_cst8_fn pf_cst8_select(unsigned ftype)
{
    if (!pf_have_avx2())
        return NULL;
    return ftype == ST_FILTER_PTEX_BOX ? cst8_box : cst8_w4;
}

#else

int pf_have_avx2(void)
{
    return 0;
}

pf_v4 pf_apply_avx2(const uint8_t *base, size_t rowb, const pk *k, unsigned dt, unsigned nc,
                    pf_v4 acc)
{
    (void)base; (void)rowb; (void)k; (void)dt; (void)nc;
    return acc;
}

void pf_kernel_eval2_avx2(const pk_params *p, float x1u, float su, float *wu, int nu,
                          float x1v, float sv, float *wv, int nv)
{
    pk_kernel_eval(p, x1u, su, wu, nu);
    pk_kernel_eval(p, x1v, sv, wv, nv);
}

void pf_kernel_eval1_avx2(const pk_params *p, float x1, float s, float *w, int n)
{
    pk_kernel_eval(p, x1, s, w, n);
}

pf_v4 pf_kernel_eval2s_avx2(const pk_params *p, float x1u, float su, float *wu, int nu,
                            float x1v, float sv, float *wv, int nv)
{
    pk_kernel_eval(p, x1u, su, wu, nu);
    pk_kernel_eval(p, x1v, sv, wv, nv);
    return (pf_v4){pk_accumulate(wu, nu), pk_accumulate(wv, nv), 0.0f, 0.0f};
}

float pf_kernel_eval1s_avx2(const pk_params *p, float x1, float s, float *w, int n)
{
    pk_kernel_eval(p, x1, s, w, n);
    return pk_accumulate(w, n);
}

pf_fast_fn pf_fast_select(unsigned dt, unsigned nc, unsigned ftype)
{
    (void)dt; (void)nc; (void)ftype;
    return NULL;
}

pf_window_fn pf_window_select(unsigned dt, unsigned nc)
{
    (void)dt; (void)nc;
    return NULL;
}

pf_w4x8_fn pf_w4x8_select(unsigned dt, unsigned nc, unsigned ftype)
{
    (void)dt; (void)nc; (void)ftype;
    return NULL;
}

pf_window_fn pf_small_select(unsigned dt, unsigned nc)
{
    (void)dt; (void)nc;
    return NULL;
}

pf_small4_fn pf_small4_select(unsigned dt, unsigned nc)
{
    (void)dt; (void)nc;
    return NULL;
}

pf_small4_fn pf_small2_select(unsigned dt, unsigned nc)
{
    (void)dt; (void)nc;
    return NULL;
}

pf_w4x8_fn pf_box8_select(unsigned dt, unsigned nc)
{
    (void)dt; (void)nc;
    return NULL;
}

/* no 8-lane folds off x86 */
pf_r0x8_fn pf_r0x8_select(unsigned dt, unsigned nc) { return (void)dt, (void)nc, NULL; }
pf_r0x8_fn pf_iso8_select(unsigned dt, unsigned nc) { return (void)dt, (void)nc, NULL; }
pf_q8_fn pf_q8_select(void) { return NULL; }
pf_b8_fn pf_b8_select(unsigned ftype) { return (void)ftype, NULL; }
pf_cst8_fn pf_cst8_select(unsigned ftype) { return (void)ftype, NULL; }

pf_bilinear_half_fn pf_bilinear_half_select(void)
{
    return NULL;
}

pf_edge2_fn pf_edge2_select(unsigned dt, unsigned nc)
{
    (void)dt; (void)nc;
    return NULL;
}

#endif
