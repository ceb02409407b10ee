/* The float helpers every part of the kernel shares: Python's min and max as the Python
 * path calls them, pi as Python's math.pi, and the mark of the inner loops' small
 * functions.
 */
#ifndef HECKER_DYNAMICS_FLOATS_H
#define HECKER_DYNAMICS_FLOATS_H

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

#endif
