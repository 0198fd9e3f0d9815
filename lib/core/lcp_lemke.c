/* lcp_lemke.c - Lemke's complementary pivoting, the fallback of
 * sc_lcp_dantzig() (docs/DESIGN.md 3.5): lcp.c's principal pivoting needs
 * every clamped block to be nonsingular, which a non-symmetric PSD matrix
 * does not give, while Lemke's method processes every copositive-plus LCP
 * (Cottle, Pang and Stone, 2009, section 4.4). Ties in the ratio test are
 * broken lexicographically against cycling; the covering vector sets the
 * path. A pivot is a Gauss-Jordan step, O(n^2), on one allocation taken
 * only when the fallback runs. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "lcp.h"

/* Relative size below which a lexicographic key entry is rounding noise. */
#define LEMKE_NOISE 1e-11

/* Columns: w_0..w_{n-1} (the basis inverse lives there), z_0..z_{n-1}, z0. */
typedef struct lemke {
    int n, cols;
    double *t;        /* n x cols tableau, row-major */
    double *rhs;      /* values of the basic variables */
    int *basis;       /* column of the basic variable of each row */
    int *nz;          /* scratch: the pivot row's nonzero columns */
    double *ub;       /* per row: an upper bound of row_max() (leaving_row()) */
} lemke;

static double *row(const lemke *lk, int i)
{
    return lk->t + (size_t)i * lk->cols;
}

static void pivot(lemke *lk, int r, int c)
{
    double *tr = row(lk, r), p = tr[c];
    /* the pivot row's nonzero columns: the tableau stays sparse (the
     * basis inverse starts as I, the friction LCP's lambda rows hold three
     * entries), and a zero entry changes no other row */
    int *nz = lk->nz, m = 0;
    for (int j = 0; j < lk->cols; j++) {
        tr[j] /= p;
        if (tr[j] != 0.0)
            nz[m++] = j;
    }
    lk->rhs[r] /= p;
    lk->ub[r] /= fabs(p);
    int sparse = 2 * m < lk->cols;    /* else the plain loop (vectorised) */
    for (int i = 0; i < lk->n; i++) {
        double *ti = row(lk, i), g = ti[c];
        if (i == r || g == 0.0)
            continue;
        /* the row's bound follows its update: |a - g b| <= |a| + |g| |b| */
        lk->ub[i] += fabs(g) * lk->ub[r];
        if (sparse) {
            for (int k = 0; k < m; k++)
                ti[nz[k]] -= g * tr[nz[k]];
        } else {
            for (int j = 0; j < lk->cols; j++)
                ti[j] -= g * tr[j];
        }
        lk->rhs[i] -= g * lk->rhs[r];
    }
    lk->basis[r] = c;
    /* values that rounding left a hair off 0 are 0: degenerate rows must
     * tie exactly for the lexicographic rule to see them */
    double big = 0;
    for (int i = 0; i < lk->n; i++)
        big = max_d(big, fabs(lk->rhs[i]));
    for (int i = 0; i < lk->n; i++)
        if (fabs(lk->rhs[i]) <= 64.0 * (lk->n + 1.0) * DBL_EPSILON * big)
            lk->rhs[i] = 0;
}

/* The largest magnitude of row i's rhs and basis inverse entries. */
static double row_max(const lemke *lk, int i)
{
    const double *ti = row(lk, i);
    double big = fabs(lk->rhs[i]);
    for (int j = 0; j < lk->n; j++) {
        /* max_d() of finite magnitudes, without libm's call */
        double v = fabs(ti[j]);
        big = v > big ? v : big;
    }
    return big;
}

/* A candidate row of the ratio test and its key scale, row_max() over
 * the entering column's entry (s < 0: not computed yet). */
typedef struct cand {
    int i;
    double s;
} cand;

/* Entry j of candidate k's lexicographic key, (rhs, basis inverse row) /
 * entry: entries below LEMKE_NOISE of the row's largest are rounding of
 * an exact 0 and count as 0 (else noise decides degenerate ties). The
 * row's largest is an O(n) scan, once per candidate of every ratio test
 * (as much time as the pivots themselves); most keys are far above the
 * noise of the row's bound ub (lemke.ub, O(1) a row a pivot), which
 * settles them without it, to the same answer. ub is tightened to the
 * scan where one is made. */
static double cand_key(lemke *lk, cand *k, int j, int c)
{
    const double *ti = row(lk, k->i);
    double v = (j < 0 ? lk->rhs[k->i] : ti[j]) / ti[c];
    if (k->s < 0) {
        /* the margin covers the bound's own rounding */
        if (fabs(v) > LEMKE_NOISE * (lk->ub[k->i] / fabs(ti[c])) * (1 + 1e-9))
            return v;
        double big = row_max(lk, k->i);
        lk->ub[k->i] = big;
        k->s = big / fabs(ti[c]);
    }
    return fabs(v) <= LEMKE_NOISE * k->s ? 0.0 : v;
}

/* Is candidate a's key lexicographically below b's for entering column
 * c? The classic anti-cycling rule (ratios tie, then basis inverse rows). */
static int lex_less(lemke *lk, cand *a, cand *b, int c)
{
    for (int j = -1; j < lk->n; j++) {
        double x = cand_key(lk, a, j, c), y = cand_key(lk, b, j, c);
        if (fabs(x - y) > LEMKE_NOISE * max_d(fabs(x), fabs(y)))
            return x < y;
    }
    return a->i < b->i;
}

/* Ratio test on entering column c: -1 if nothing blocks (a ray). */
static int leaving_row(lemke *lk, int c)
{
    const int n = lk->n, z0 = 2 * n;
    double cmax = 0;
    for (int i = 0; i < n; i++)
        cmax = max_d(cmax, fabs(row(lk, i)[c]));
    double ptol = 64.0 * (n + 1.0) * DBL_EPSILON * cmax;
    cand kb = { -1, -1 };   /* the best so far, its scale kept over the search */
    for (int i = 0; i < n; i++) {
        if (row(lk, i)[c] <= ptol)
            continue;
        cand k = { i, -1 };
        if (kb.i < 0 || lex_less(lk, &k, &kb, c))
            kb = k;
    }
    int best = kb.i;
    /* z0 leaves on a tie: the path ends there */
    for (int i = 0; best >= 0 && i < n; i++) {
        if (lk->basis[i] != z0 || row(lk, i)[c] <= ptol)
            continue;
        double x = lk->rhs[i] / row(lk, i)[c], y = lk->rhs[best] / row(lk, best)[c];
        if (x <= y + 1e-12 * max_d(fabs(x), fabs(y)))
            best = i;
    }
    return best;
}

static int run(lemke *lk, const double *q, const double *d, long max_pivots, long *pivots)
{
    const int n = lk->n, z0 = 2 * n;
    /* z0 enters: the most negative q_i / d_i leaves, on a tie the last
     * such row - the lexicographic choice, which keeps every row of
     * [rhs | B^-1] lexicographically positive from here on */
    int r = 0;
    for (int i = 1; i < n; i++)
        if ((d ? q[i] / d[i] : q[i]) <= (d ? q[r] / d[r] : q[r]))
            r = i;
    if (q[r] >= 0)
        return SC_OK;   /* z = 0 */
    int enter = z0;
    for (;;) {
        if (++*pivots > max_pivots)
            return SC_EMAXITER;
        int leaving = lk->basis[r];
        pivot(lk, r, enter);
        if (leaving == z0)
            return SC_OK;
        enter = leaving < n ? leaving + n : leaving - n;   /* its complement */
        r = leaving_row(lk, enter);
        if (r < 0)
            return SC_ENOSOLUTION;   /* secondary ray */
    }
}

/* Recompute the basic z from the original data, M_BB z_B = -q_B (dense
 * solve, once), and keep it when it stays >= 0: removes the rounding the
 * Gauss-Jordan steps accumulated. The tableau memory is reused. */
static void polish(int n, const double *M, const double *q, double *z, lemke *lk)
{
    int *idx = lk->basis, m = 0;
    for (int i = 0; i < n; i++)
        if (lk->basis[i] >= n && lk->basis[i] < 2 * n)
            idx[m++] = lk->basis[i] - n;
    double *a = lk->t, *b = lk->rhs;
    for (int r = 0; r < m; r++) {
        b[r] = -q[idx[r]];
        for (int c = 0; c < m; c++)
            a[(size_t)r * m + c] = M[(size_t)idx[r] * n + idx[c]];
    }
    if (sc_lu_solve(m, a, b) != SC_OK)
        return;
    for (int r = 0; r < m; r++)
        if (!(b[r] >= 0.0))
            return;
    for (int r = 0; r < m; r++)
        z[idx[r]] = b[r];
}

int sc_lcp_lemke(int n, const double *M, const double *q, const double *d, double *z,
                 long max_pivots, long *pivots)
{
    size_t nd = (size_t)n, cols = 2 * nd + 1;
    lemke lk = { n, (int)cols, NULL, NULL, NULL, NULL, NULL };
    if (nd > SIZE_MAX / sizeof(double) / (cols + 3) / 2)
        return SC_ENOMEM;
    lk.t = malloc((nd * cols + 2 * nd) * sizeof(double) + (nd + cols) * sizeof(int));
    if (!lk.t)
        return SC_ENOMEM;
    lk.rhs = lk.t + nd * cols;
    lk.ub = lk.rhs + nd;
    lk.basis = (int *)(void *)(lk.ub + nd);
    lk.nz = lk.basis + nd;
    memset(lk.t, 0, nd * cols * sizeof(double));
    for (int i = 0; i < n; i++) {
        double *ti = row(&lk, i);
        ti[i] = 1;
        for (int j = 0; j < n; j++)
            ti[n + j] = -M[(size_t)i * n + j];
        ti[2 * n] = d ? -d[i] : -1;
        lk.rhs[i] = q[i];
        lk.ub[i] = max_d(fabs(q[i]), 1.0);   /* exact: the basis inverse is I */
        lk.basis[i] = i;
    }
    int rc = run(&lk, q, d, max_pivots, pivots);
    for (int i = 0; i < n; i++)
        z[i] = 0;
    for (int i = 0; i < n; i++)
        if (lk.basis[i] >= n && lk.basis[i] < 2 * n)
            z[lk.basis[i] - n] = max_d(lk.rhs[i], 0.0);
    if (rc == SC_OK)
        polish(n, M, q, z, &lk);
    free(lk.t);
    return rc;
}
