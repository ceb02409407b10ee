/* The float helpers every part of the kernel shares: Python's min and max as the Python
 * path calls them, an angle's cos and sin, pi as Python's math.pi, and the mark of the
 * inner loops' small functions.
 */
#ifndef HECKER_DYNAMICS_FLOATS_H
#define HECKER_DYNAMICS_FLOATS_H

#include <math.h>

/* The small functions of the solver's inner loop, always inlined (GCC left them as
 * calls); inlining changes no floating-point operation. */
#if defined(__GNUC__)
#define HD_HOT inline __attribute__((always_inline))
#else
#define HD_HOT __forceinline
#endif

/* math.pi, the double nearest pi. */
#define HD_PI 3.141592653589793

/* Python's min(x, y) and max(x, y): the first unless the second is strictly beyond it
 * (so for NaNs and signed zeros too). */
static HD_HOT double hd_min(double x, double y) { return y < x ? y : x; }
static HD_HOT double hd_max(double x, double y) { return y > x ? y : x; }

/* cos and sin of an angle as geometry/planar.py's cos_sin_of gives them: NaN for an
 * infinite one. Taken in one block, GCC calls glibc's sincos for both, which gives cos's
 * and sin's bits. */
static HD_HOT void hd_cos_sin(double angle, double *cos_sin)
{
    const double finite = isinf(angle) ? NAN : angle;
    cos_sin[0] = cos(finite);
    cos_sin[1] = sin(finite);
}

#endif
