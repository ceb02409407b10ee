/* The joint rows' factorizations: hecker_dynamics/contact/sparse.py, operation for
 * operation (see sparse.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "simd.h"
#include "sparse.h"

static long hd_lmin(long a, long b) { return a < b ? a : b; }

/* a[e] -= t * b[e] for e < count: each entry one product and one subtraction, as a scalar
 * loop rounds them, four entries at once where the compiler has vectors (AVX where the
 * CPU has it). */
static HD_PER_CPU void hd_subtract_scaled(double *a, const double *b, double t, long count)
{
    long e = 0;
#if HD_VECTORS
    const hd_v4 scale = {t, t, t, t};
    for (; e + HD_LANES <= count; e += HD_LANES) {
        hd_v4 x, y;
        memcpy(&x, a + e, sizeof x);
        memcpy(&y, b + e, sizeof y);
        x -= scale * y;
        memcpy(a + e, &x, sizeof x);
    }
#endif
    for (; e < count; ++e)
        a[e] -= t * b[e];
}

int hd_pattern_init(hd_pattern *p, long n, long *start, long *columns, double *dependent)
{
    p->n = n, p->start = start, p->columns = columns, p->dependent = dependent;
    const long slots = start[n];
    p->above_start = calloc((size_t)n + 1, sizeof(long));
    p->above_row = malloc(((size_t)slots + 1) * sizeof(long));
    p->above_slot = malloc(((size_t)slots + 1) * sizeof(long));
    if (p->above_start == NULL || p->above_row == NULL || p->above_slot == NULL)
        return -1;
    for (long s = 0; s < slots; ++s)
        p->above_start[columns[s] + 1] += 1;
    for (long i = 0; i < n; ++i)
        p->above_start[i + 1] += p->above_start[i];
    long *fill = malloc(((size_t)n + 1) * sizeof(long));
    if (fill == NULL)
        return -1;
    for (long i = 0; i < n; ++i)
        fill[i] = p->above_start[i];
    for (long i = 0; i < n; ++i)  /* rows in ascending order: each column's list ascends */
        for (long s = start[i]; s < start[i + 1]; ++s) {
            const long at = fill[columns[s]]++;
            p->above_row[at] = i, p->above_slot[at] = s;
        }
    free(fill);
    /* The updates in all: per column k, a pair of its rows j < i (L[i, j] is then in the
     * pattern too). Too many to keep: the factorizations scatter. */
    long updates = 0;
    for (long k = 0; k < n && updates <= HD_MOST_UPDATES; ++k) {
        const long count = p->above_start[k + 1] - p->above_start[k];
        updates += count * (count - 1) / 2;
    }
    if (updates > HD_MOST_UPDATES) {
        p->position = malloc(((size_t)slots + 1) * sizeof(long));
        p->last = malloc(((size_t)n + 1) * sizeof(long));
        p->work = malloc((4 * (size_t)n + 2 * (size_t)slots + 1) * sizeof(double));
        if (p->position == NULL || p->last == NULL || p->work == NULL)
            return -1;
        for (long k = 0; k < slots; ++k)
            p->position[p->above_slot[k]] = k;
        const long *above_start = p->above_start, *above_row = p->above_row;
        for (long c = n - 1; c >= 0; --c) {  /* column c joins c + 1's supernode */
            const long count = above_start[c + 1] - above_start[c];
            int joins = c + 1 < n && count == above_start[c + 2] - above_start[c + 1] + 1
                        && above_row[above_start[c]] == c + 1;
            for (long e = 1; joins && e < count; ++e)
                joins = above_row[above_start[c] + e] == above_row[above_start[c + 1] + e - 1];
            p->last[c] = joins ? p->last[c + 1] : c;
        }
        return 0;
    }
    /* The merges of contact/sparse.py's factor and lu, once: count, then fill. */
    p->update_start = calloc((size_t)slots + 1, sizeof(long));
    if (p->update_start == NULL)
        return -1;
    for (int pass = 0; pass < 2; ++pass) {
        long count = 0;
        for (long i = 0; i < n; ++i)
            for (long slot = start[i]; slot < start[i + 1]; ++slot) {
                const long j = columns[slot];
                long a = start[i], b = start[j];
                if (pass == 1)
                    p->update_start[slot] = count;
                while (a < slot && b < start[j + 1]) {
                    if (columns[a] == columns[b]) {
                        if (pass == 1)
                            p->update_a[count] = a, p->update_b[count] = b;
                        ++count, ++a, ++b;
                    } else if (columns[a] < columns[b]) {
                        ++a;
                    } else {
                        ++b;
                    }
                }
            }
        if (pass == 0) {
            p->update_a = malloc(((size_t)count + 1) * sizeof(long));
            p->update_b = malloc(((size_t)count + 1) * sizeof(long));
            if (p->update_a == NULL || p->update_b == NULL)
                return -1;
        } else {
            p->update_start[slots] = count;
        }
    }
    return 0;
}

void hd_pattern_free(hd_pattern *p)
{
    free(p->start);
    free(p->columns);
    free(p->dependent);
    free(p->above_start);
    free(p->above_row);
    free(p->above_slot);
    free(p->update_start);
    free(p->update_a);
    free(p->update_b);
    free(p->position);
    free(p->last);
    free(p->work);
}

/* Row i of L D L^T (its slots of `low`), each entry's updates subtracted in ascending k:
 * from the listed pairs of slots. Those through a row left out or dropped subtract +0.0,
 * which changes no bit: contact/sparse.py skips them, the scattered path below too, but
 * here testing every update would cost more than it saves where no row drops (a chain). */
static void hd_factor_listed(const hd_pattern *p, const double *lower, long i, double *low,
                             const double *diag, const int *out)
{
    const long *columns = p->columns;
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
        const long j = columns[slot];
        if (out[j])
            continue;
        double s = lower[slot];
        for (long u = p->update_start[slot]; u < p->update_start[slot + 1]; ++u) {
            const long a = p->update_a[u], b = p->update_b[u];
            s -= low[a] * diag[columns[a]] * low[b];
        }
        low[slot] = s / diag[j];
    }
}

/* The same without the lists: row i scattered into a dense vector x; as each of its columns
 * k (ascending) is finished, column k's entries L[r, k] above row i (kept by columns, in
 * the work: those before row i's own, position[slot]) update the entries (i, r) still to
 * come. Row i's columns come in supernodes (sparse.h: hd_pattern.last), and a supernode's
 * columns all update the rows of its first column's list, each column from its own place
 * in it on: those entries of x are gathered once a supernode (`rows`: rows[0] its first
 * column's, rows[e + 1] the e-th row of that column's list, those before row i), each
 * column's updates run over consecutive entries of both, and the rows below the
 * supernode go back into x. Every entry takes the same subtractions in the same order,
 * at the cost of the updates alone. */
static void hd_factor_scattered(const hd_pattern *p, const double *lower, long i, double *low,
                                const double *diag, const int *out)
{
    const long *columns = p->columns, *above_start = p->above_start;
    const long *above_row = p->above_row, *position = p->position;
    double *x = p->work, *rows = p->work + p->n, *column = p->work + 4 * p->n;
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot)
        x[columns[slot]] = lower[slot];
    for (long slot = p->start[i]; slot < p->start[i + 1];) {
        const long first = columns[slot], *below = above_row + above_start[first];
        const long width = hd_lmin(p->last[first], i - 1) - first + 1;
        const long above = position[slot] - above_start[first];  /* its rows before row i */
        rows[0] = x[first];
        for (long e = 0; e < above; ++e)
            rows[e + 1] = x[below[e]];
        for (long d = 0; d < width; ++d, ++slot) {
            const long k = first + d, at = position[slot];
            if (out[k]) {  /* a row left out or dropped: its entries stay zero, its updates too */
                column[at] = 0.0;
                continue;
            }
            const double l = rows[d] / diag[k];
            low[slot] = column[at] = l;
            hd_subtract_scaled(rows + d + 1, column + above_start[k], l * diag[k],
                               at - above_start[k]);
        }
        for (long e = width - 1; e < above; ++e)
            x[below[e]] = rows[e + 1];
    }
}

void hd_factor(const hd_pattern *p, const double *diagonal, const double *lower,
               const int *active, double *low, double *diag, int *out)
{
    const long n = p->n, *start = p->start, *columns = p->columns;
    for (long s = 0; s < start[n]; ++s)
        low[s] = 0.0;
    for (long i = 0; i < n; ++i) {
        out[i] = active != NULL && !active[i];
        diag[i] = 0.0;
    }
    for (long i = 0; i < n; ++i) {
        if (out[i])
            continue;
        if (p->update_start != NULL)
            hd_factor_listed(p, lower, i, low, diag, out);
        else
            hd_factor_scattered(p, lower, i, low, diag, out);
        double s = diagonal[i];
        for (long slot = start[i]; slot < start[i + 1]; ++slot)
            s -= low[slot] * diag[columns[slot]] * low[slot];
        if (s > p->dependent[i] * diagonal[i])
            diag[i] = s;
        else
            out[i] = 1;
    }
}

void hd_substitute(const hd_pattern *p, const double *low, const double *diag, const int *out,
                   double *x)
{
    const long n = p->n, *start = p->start, *columns = p->columns;
    for (long i = 0; i < n; ++i) {
        if (out[i]) {
            x[i] = 0.0;
            continue;
        }
        double s = x[i];
        for (long slot = start[i]; slot < start[i + 1]; ++slot)
            s -= low[slot] * x[columns[slot]];
        x[i] = s;
    }
    for (long i = 0; i < n; ++i)
        if (!out[i])
            x[i] = x[i] / diag[i];
    for (long i = n - 1; i >= 0; --i) {
        if (out[i])
            continue;
        double s = x[i];
        for (long k = p->above_start[i]; k < p->above_start[i + 1]; ++k)
            s -= low[p->above_slot[k]] * x[p->above_row[k]];
        x[i] = s;
    }
}

/* Row i of L and column i of U (hd_factor_listed, hd_factor_scattered). */
static void hd_lu_listed(const hd_pattern *p, const double *lower, long i, double *upper,
                         double *low, const double *diag, const int *out)
{
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
        const long j = p->columns[slot];
        if (out[j]) {
            upper[slot] = 0.0;
            continue;
        }
        double s = lower[slot], t = upper[slot];
        for (long u = p->update_start[slot]; u < p->update_start[slot + 1]; ++u) {
            const long a = p->update_a[u], b = p->update_b[u];
            s -= low[a] * upper[b];  /* L[i, k] U[k, j] */
            t -= low[b] * upper[a];  /* L[j, k] U[k, i] */
        }
        low[slot] = s * diag[j];
        upper[slot] = t;
    }
}

static void hd_lu_scattered(const hd_pattern *p, const double *lower, long i, double *upper,
                            double *low, const double *diag, const int *out)
{
    const long *columns = p->columns, *above_start = p->above_start;
    const long *above_row = p->above_row, *position = p->position;
    double *x = p->work, *y = p->work + p->n;  /* row i of L, column i of U */
    double *rows_x = p->work + 2 * p->n, *rows_y = p->work + 3 * p->n;
    double *column_l = p->work + 4 * p->n, *column_u = column_l + p->start[p->n];
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot)
        x[columns[slot]] = lower[slot], y[columns[slot]] = upper[slot];
    for (long slot = p->start[i]; slot < p->start[i + 1];) {
        const long first = columns[slot], *below = above_row + above_start[first];
        const long width = hd_lmin(p->last[first], i - 1) - first + 1;
        const long above = position[slot] - above_start[first];
        rows_x[0] = x[first], rows_y[0] = y[first];
        for (long e = 0; e < above; ++e)
            rows_x[e + 1] = x[below[e]], rows_y[e + 1] = y[below[e]];
        for (long d = 0; d < width; ++d, ++slot) {
            const long k = first + d, at = position[slot];
            if (out[k]) {  /* a row dropped: its entries stay zero, its updates too */
                upper[slot] = column_l[at] = column_u[at] = 0.0;
                continue;
            }
            const double l = rows_x[d] * diag[k], u = rows_y[d];
            low[slot] = column_l[at] = l;
            upper[slot] = column_u[at] = u;
            /* L[i, k] U[k, r] and L[r, k] U[k, i] */
            hd_subtract_scaled(rows_x + d + 1, column_u + above_start[k], l, at - above_start[k]);
            hd_subtract_scaled(rows_y + d + 1, column_l + above_start[k], u, at - above_start[k]);
        }
        for (long e = width - 1; e < above; ++e)
            x[below[e]] = rows_x[e + 1], y[below[e]] = rows_y[e + 1];
    }
}

void hd_lu(const hd_pattern *p, const double *diagonal, const double *lower, double *upper,
           double *low, double *diag, int *out)
{
    const long n = p->n, *start = p->start;
    for (long s = 0; s < start[n]; ++s)
        low[s] = 0.0;
    for (long i = 0; i < n; ++i) {
        out[i] = 0;
        diag[i] = 0.0;
    }
    for (long i = 0; i < n; ++i) {
        if (p->update_start != NULL)
            hd_lu_listed(p, lower, i, upper, low, diag, out);
        else
            hd_lu_scattered(p, lower, i, upper, low, diag, out);
        double s = diagonal[i];
        for (long slot = start[i]; slot < start[i + 1]; ++slot)
            s -= low[slot] * upper[slot];
        if (fabs(s) > p->dependent[i] * fabs(diagonal[i]))
            diag[i] = 1.0 / s;
        else
            out[i] = 1;
    }
}

void hd_lu_solve(const hd_pattern *p, const double *low, const double *upper,
                 const double *diag, const int *out, double *x)
{
    const long n = p->n, *start = p->start, *columns = p->columns;
    for (long i = 0; i < n; ++i) {
        double s = x[i];
        for (long slot = start[i]; slot < start[i + 1]; ++slot)
            s -= low[slot] * x[columns[slot]];
        x[i] = s;
    }
    for (long i = n - 1; i >= 0; --i) {
        if (out[i]) {
            x[i] = 0.0;
            continue;
        }
        double s = x[i];
        for (long k = p->above_start[i]; k < p->above_start[i + 1]; ++k)
            s -= upper[p->above_slot[k]] * x[p->above_row[k]];
        x[i] = s * diag[i];
    }
}
