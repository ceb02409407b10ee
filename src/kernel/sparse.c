/* The joint rows' factorizations: hecker_dynamics/contact/sparse.py, operation for
 * operation (see sparse.h). */
#include <math.h>
#include <stdlib.h>

#include "sparse.h"

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
        p->work = malloc((2 * (size_t)n + 2 * (size_t)slots + 1) * sizeof(double));
        if (p->position == NULL || p->work == NULL)
            return -1;
        for (long k = 0; k < slots; ++k)
            p->position[p->above_slot[k]] = k;
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

/* The same without the lists: row i scattered into a dense vector; as each of its columns
 * k (ascending) is finished, column k's entries L[r, k] above row i (kept by columns, in
 * the work: those before row i's own, position[slot]) update the entries (i, r) still to
 * come. Every entry takes the same subtractions in the same order, at the cost of the
 * updates alone. */
static void hd_factor_scattered(const hd_pattern *p, const double *lower, long i, double *low,
                                const double *diag, const int *out)
{
    const long *columns = p->columns, *above_start = p->above_start;
    const long *above_row = p->above_row, *position = p->position;
    double *x = p->work, *column = p->work + 2 * p->n;
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot)
        x[columns[slot]] = lower[slot];
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
        const long k = columns[slot], at = position[slot];
        if (out[k]) {  /* a row left out or dropped: its entries stay zero, its updates too */
            column[at] = 0.0;
            continue;
        }
        const double l = x[k] / diag[k];
        low[slot] = column[at] = l;
        const double t = l * diag[k];
        for (long e = above_start[k]; e < at; ++e)
            x[above_row[e]] -= t * column[e];
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
    double *column_l = p->work + 2 * p->n, *column_u = column_l + p->start[p->n];
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot)
        x[columns[slot]] = lower[slot], y[columns[slot]] = upper[slot];
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
        const long k = columns[slot], at = position[slot];
        if (out[k]) {  /* a row dropped: its entries stay zero, its updates too */
            upper[slot] = column_l[at] = column_u[at] = 0.0;
            continue;
        }
        const double l = x[k] * diag[k], u = y[k];
        low[slot] = column_l[at] = l;
        upper[slot] = column_u[at] = u;
        for (long e = above_start[k]; e < at; ++e) {
            const long r = above_row[e];
            x[r] -= l * column_u[e];  /* L[i, k] U[k, r] */
            y[r] -= column_l[e] * u;  /* L[r, k] U[k, i] */
        }
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
