/* The joint rows' factorizations: hecker_dynamics/contact/sparse.py, repeated operation for
 * operation (the order of the rows and where their factors can be non-zero are computed in
 * Python once per scene and handed over as a pattern). */
#ifndef HECKER_DYNAMICS_SPARSE_H
#define HECKER_DYNAMICS_SPARSE_H

/* contact/sparse.py: DEPENDENT, a pivot at most this fraction of its diagonal drops its row
 * (scaled per row by Pattern.lightest: hd_pattern.dependent). */
#define HD_DEPENDENT 1e-10
/* The most updates a pattern keeps listed (16 bytes each); beyond, the factorizations
 * scatter each row into a dense vector and update it by columns, in the same order. */
#define HD_MOST_UPDATES 4000000L

/* contact/sparse.py: Pattern. Row i's columns (ascending) are columns[start[i] .. start[i + 1]),
 * each a slot of the factors' arrays; column i's slots, by ascending row, are
 * above_row/above_slot[above_start[i] .. above_start[i + 1]). */
typedef struct {
    long n;
    long *start, *columns;
    /* contact/sparse.py: Pattern.dependent, per row the fraction of its diagonal at or below
     * which its pivot drops it. */
    double *dependent;
    long *above_start, *above_row, *above_slot;
    /* The updates of each entry, in the order the factorizations subtract them: slot s
     * (row i, column j) takes (a, b) = update_a/update_b[update_start[s] ..
     * update_start[s + 1]): the slots of (i, k) and (j, k), k ascending, k < j (the merge
     * of the two rows' patterns, done once; update_start NULL: too many to keep). */
    long *update_start, *update_a, *update_b;
    /* Without the lists: each slot's place in the column lists; per column, the last column
     * of its supernode (the run of consecutive columns c0 .. c1 where each column's rows
     * below it are the next column and that column's rows: a row below c1 holds all of
     * them or none, a row inside holds c0 .. itself - 1, each at consecutive slots); and
     * 4 n + 2 slots of work (the rows being factored, dense; a supernode's rows gathered;
     * the factors by columns). */
    long *position, *last;
    double *work;
} hd_pattern;

/* Take `start` (n + 1), `columns` (start[n]) and `dependent` (n), which the pattern owns from
 * now on, and make the column lists; 0, or -1 out of memory. */
int hd_pattern_init(hd_pattern *p, long n, long *start, long *columns, double *dependent);
void hd_pattern_free(hd_pattern *p);

/* contact/sparse.py: factor, K = L D L^T for the rows `active` marks (NULL: all); `out` marks the
 * rows left out or dropped. */
void hd_factor(const hd_pattern *p, const double *diagonal, const double *lower,
               const int *active, double *low, double *diag, int *out);
/* contact/sparse.py: substitute, x in place of the right-hand side. */
void hd_substitute(const hd_pattern *p, const double *low, const double *diag, const int *out,
                   double *x);
/* contact/sparse.py: lu; `upper` (the transpose of A's strict upper triangle, by slots) becomes
 * U's, `diag` the reciprocals of U's diagonal. */
void hd_lu(const hd_pattern *p, const double *diagonal, const double *lower, double *upper,
           double *low, double *diag, int *out);
/* contact/sparse.py: lu_solve, x in place of the right-hand side. */
void hd_lu_solve(const hd_pattern *p, const double *low, const double *upper,
                 const double *diag, const int *out, double *x);

#endif
