/* The kernel's SIMD width: lanes of doubles, two (hd_v2, the narrow phase's two edges at
 * once, manifold.c) or HD_LANES (hd_v4, the coloured solve's four blocks, wide.c). Each
 * lane gets the same IEEE operations as one double, so lanes give the bits one double at
 * a time gives.
 *
 * GCC's and Clang's vector extensions (HD_VECTORS 1), else a struct of scalars: hd_v2's
 * helpers then work lane by lane, and wide.c solves every unit one by one.
 */
#ifndef HECKER_DYNAMICS_SIMD_H
#define HECKER_DYNAMICS_SIMD_H

#include <stdint.h>

#include "floats.h"

#define HD_LANES 4

/* Functions built twice, AVX2 and the baseline, the CPU choosing at load time: the same
 * IEEE operations either way (no contraction into fused multiply-adds, setup.py). */
#if defined(__x86_64__) && defined(__GLIBC__)
#define HD_PER_CPU __attribute__((target_clones("avx2", "default")))
#else
#define HD_PER_CPU
#endif

#if defined(__GNUC__)
#define HD_VECTORS 1
/* The vector helpers are always inlined, so no vector crosses a call and the ABI of
 * passing one (which AVX changes) never applies. */
#pragma GCC diagnostic ignored "-Wpsabi"
typedef double hd_v2 __attribute__((vector_size(16), aligned(16)));
typedef int64_t hd_m2 __attribute__((vector_size(16), aligned(16)));
typedef double hd_v4 __attribute__((vector_size(32), aligned(32)));
typedef int64_t hd_m4 __attribute__((vector_size(32), aligned(32)));
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

static HD_HOT hd_v2 hd_v2_pair(double first, double second) { return (hd_v2){first, second}; }
static HD_HOT hd_v2 hd_v2_all(double x) { return (hd_v2){x, x}; }
static HD_HOT hd_v2 hd_v2_sub(hd_v2 x, hd_v2 y) { return x - y; }
static HD_HOT hd_v2 hd_v2_mul(hd_v2 x, hd_v2 y) { return x * y; }
static HD_HOT hd_v2 hd_v2_add(hd_v2 x, hd_v2 y) { return x + y; }
/* t < s ? t : s, lane by lane: MINPD's own rule, for NaNs and zeros too. */
static HD_HOT hd_v2 hd_v2_min(hd_v2 t, hd_v2 s)
{
#if defined(__SSE2__)
    return _mm_min_pd(t, s);
#else
    const hd_m2 m = t < s;
    return (hd_v2)(((hd_m2)t & m) | ((hd_m2)s & ~m));
#endif
}
static HD_HOT void hd_v2_store(double *out, hd_v2 x)
{
    out[0] = x[0];
    out[1] = x[1];
}
#else
#define HD_VECTORS 0
typedef struct { double lane[2]; } hd_v2;
typedef struct { double lane[HD_LANES]; } hd_v4;
static HD_HOT hd_v2 hd_v2_pair(double first, double second) { return (hd_v2){{first, second}}; }
static HD_HOT hd_v2 hd_v2_all(double x) { return (hd_v2){{x, x}}; }
static HD_HOT hd_v2 hd_v2_sub(hd_v2 x, hd_v2 y)
{
    return (hd_v2){{x.lane[0] - y.lane[0], x.lane[1] - y.lane[1]}};
}
static HD_HOT hd_v2 hd_v2_mul(hd_v2 x, hd_v2 y)
{
    return (hd_v2){{x.lane[0] * y.lane[0], x.lane[1] * y.lane[1]}};
}
static HD_HOT hd_v2 hd_v2_add(hd_v2 x, hd_v2 y)
{
    return (hd_v2){{x.lane[0] + y.lane[0], x.lane[1] + y.lane[1]}};
}
static HD_HOT hd_v2 hd_v2_min(hd_v2 t, hd_v2 s)
{
    return (hd_v2){{t.lane[0] < s.lane[0] ? t.lane[0] : s.lane[0],
                    t.lane[1] < s.lane[1] ? t.lane[1] : s.lane[1]}};
}
static HD_HOT void hd_v2_store(double *out, hd_v2 x)
{
    out[0] = x.lane[0];
    out[1] = x.lane[1];
}
#endif

#endif
