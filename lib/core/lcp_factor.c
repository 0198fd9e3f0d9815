/* lcp_factor.c - the factorisation behind the Dantzig pivoting of lcp.c
 * (docs/DESIGN.md 3.5): M_CC = L D U of the clamped block, bordered as an
 * index enters and downdated as one leaves, O(m^2) each, so that a pivot
 * never refactorises. For symmetric M (the contact matrices) U = L^T and
 * one triangle is stored (Baraff's and ODE's LDL^T). No pivoting: lcp.c
 * lets an index into C only with a clearly nonzero pivot. Also a small
 * dense LU for lcp.c's friction polish. */
#include <math.h>
#include <string.h>

#include "core.h"
#include "lcp.h"

/* A rank-one update whose new pivot cancels to this fraction of its terms
 * is treated as singular (never for symmetric positive definite blocks,
 * where the update only adds: d + alpha p^2 >= d). */
#define LDU_CANCEL 1e-13

size_t sc_ldu_size(int n, int sym)
{
    size_t nn = (size_t)n * (size_t)n;
    size_t doubles = nn * (sym ? 1u : 2u) + 3u * (size_t)n;
    return doubles * sizeof(double) + (size_t)n * sizeof(int);
}

void sc_ldu_init(sc_ldu *f, int n, int sym, void *mem)
{
    size_t nn = (size_t)n * (size_t)n;
    double *p = mem;
    f->n = n;
    f->m = 0;
    f->sym = sym;
    f->bordered = -1;
    f->l = p;
    p += nn;
    if (sym) {
        f->ut = f->l;
    } else {
        f->ut = p;
        p += nn;
    }
    f->d = p;
    p += n;
    f->x = p;
    p += n;
    f->y = p;
    p += n;
    f->idx = (int *)(void *)p;   /* ints after the doubles: aligned */
}

/* Solve T v = b in place for a unit lower triangular T stored by rows
 * (row r holds T[r][0..r-1]) with stride n. */
static void unit_lower_solve(const double *t, int n, int m, double *v)
{
    for (int r = 1; r < m; r++) {
        const double *row = t + (size_t)r * n;
        double s = v[r];
        for (int c = 0; c < r; c++)
            s -= row[c] * v[c];
        v[r] = s;
    }
}

/* Solve U v = b in place, U unit upper triangular given by its transpose
 * ut (row c of ut is column c of U), column-oriented so rows stay
 * contiguous. */
static void unit_upper_solve(const double *ut, int n, int m, double *v)
{
    for (int c = m - 1; c > 0; c--) {
        const double *col = ut + (size_t)c * n;
        double vc = v[c];
        for (int r = 0; r < c; r++)
            v[r] -= col[r] * vc;
    }
}

/* Prepare index j as factor position m (bordering):
 *   [A   b]   [L  0][D  0][U  u]
 *   [c^T a] = [l^T 1][0 e][0  1],  u = D^-1 L^-1 b, l = D^-1 U^-T c,
 *   e = a - l^T D u,
 * two triangular solves, O(m^2). The border is written to row m of l/ut
 * but only becomes part of the factorisation with sc_ldu_commit(). Returns
 * the new pivot e (the Schur complement of M_CC in M_{C+j,C+j}); *scale
 * gets the size of the terms it was computed from, for a singularity test. */
double sc_ldu_border(sc_ldu *f, const double *M, int j, double *scale)
{
    const int n = f->n, m = f->m;
    double *b = f->x, *c = f->y;
    double *lrow = f->l + (size_t)m * n, *urow = f->ut + (size_t)m * n;
    SC_ASSERT(m < n);
    for (int k = 0; k < m; k++) {
        b[k] = M[(size_t)f->idx[k] * n + j];
        c[k] = M[(size_t)j * n + f->idx[k]];
    }
    unit_lower_solve(f->l, n, m, b);
    if (!f->sym)
        unit_lower_solve(f->ut, n, m, c);
    else
        c = b;
    double e = M[(size_t)j * n + j], mag = fabs(e);
    for (int k = 0; k < m; k++) {
        double t = c[k] * b[k] / f->d[k];
        e -= t;
        mag += fabs(t);
        urow[k] = b[k] / f->d[k];
        if (!f->sym)
            lrow[k] = c[k] / f->d[k];
    }
    f->d[m] = e;
    f->idx[m] = j;
    f->bordered = j;
    if (scale)
        *scale = mag;
    return e;
}

void sc_ldu_commit(sc_ldu *f)
{
    SC_ASSERT(f->bordered >= 0 && f->m < f->n);
    f->m++;
    f->bordered = -1;
}

/* x = -U^{-1} u where u (row m of ut) is D^-1 L^-1 M_{C,j} of the last
 * border: the clamped part of Baraff's fdirection, x = -M_CC^-1 M_Cj,
 * reusing the border's forward solve (one more triangular solve). */
void sc_ldu_border_direction(const sc_ldu *f, double *x)
{
    const int n = f->n, m = f->m;
    const double *urow = f->ut + (size_t)m * n;
    SC_ASSERT(f->bordered >= 0);
    for (int k = 0; k < m; k++)
        x[k] = -urow[k];
    unit_upper_solve(f->ut, n, m, x);
}

/* v = M_CC^-1 v in place (factor order). */
void sc_ldu_solve(const sc_ldu *f, double *v)
{
    unit_lower_solve(f->l, f->n, f->m, v);
    for (int k = 0; k < f->m; k++)
        v[k] /= f->d[k];
    unit_upper_solve(f->ut, f->n, f->m, v);
}

/* Drop row and column k of a stored triangle, moving later rows up; the
 * dropped column entries below k go to x (they become the update vector). */
static void drop_row_col(double *t, int n, int m, int k, double *x)
{
    for (int r = k + 1; r < m; r++) {
        double *dst = t + (size_t)(r - 1) * n, *src = t + (size_t)r * n;
        x[r - 1] = src[k];
        memmove(dst, src, (size_t)k * sizeof(double));
        memmove(dst + k, src + k + 1, (size_t)(r - 1 - k) * sizeof(double));
    }
}

/* Remove factor position k. With A = L D U, deleting row and column k
 * leaves L'D'U' + d_k x y^T, where L', U' are L, U without row and column
 * k (still unit triangular) and x, y the deleted column of L and row of U
 * below/right of k. The rank-one term is folded back in by Bennett's
 * update (for U = L^T, Gill, Golub, Murray and Saunders' method C1), which
 * touches only positions >= k: O(m^2). Returns SC_ENUMERIC if an updated
 * pivot cancels (a singular block; impossible for positive definite M_CC). */
int sc_ldu_remove(sc_ldu *f, int k)
{
    const int n = f->n, m = f->m;
    double *x = f->x, *y = f->sym ? f->x : f->y;
    SC_ASSERT(k >= 0 && k < m);
    double alpha = f->d[k];
    drop_row_col(f->l, n, m, k, x);
    if (!f->sym)
        drop_row_col(f->ut, n, m, k, y);
    for (int r = k + 1; r < m; r++) {
        f->d[r - 1] = f->d[r];
        f->idx[r - 1] = f->idx[r];
    }
    f->m = m - 1;
    f->bordered = -1;
    for (int j = k; j < m - 1; j++) {
        double p = x[j], q = y[j], dj = f->d[j], add = alpha * p * q;
        double dbar = dj + add;
        if (!(fabs(dbar) > LDU_CANCEL * (fabs(dj) + fabs(add))))
            return SC_ENUMERIC;
        double bl = alpha * q / dbar, bu = alpha * p / dbar;
        alpha = alpha * dj / dbar;
        f->d[j] = dbar;
        if (p == 0.0 && q == 0.0)
            continue;   /* nothing to fold into the rows below */
        for (int r = j + 1; r < m - 1; r++) {
            double *lr = f->l + (size_t)r * n + j;
            x[r] -= p * *lr;
            *lr += bl * x[r];
            if (!f->sym) {
                double *ur = f->ut + (size_t)r * n + j;
                y[r] -= q * *ur;
                *ur += bu * y[r];
            }
        }
    }
    return SC_OK;
}

/* Gaussian elimination with partial pivoting of the dense m x m a
 * (row-major, stride m) in place: U above and on the diagonal, the
 * multipliers below it; piv[k] (when given) the row swapped with k at step
 * k; b (when given) eliminated along, swaps and all. SC_ENUMERIC if a
 * pivot is zero or not finite. */
static int lu_eliminate(int m, double *a, int *piv, double *b)
{
    for (int k = 0; k < m; k++) {
        int p = k;
        for (int r = k + 1; r < m; r++)
            if (fabs(a[(size_t)r * m + k]) > fabs(a[(size_t)p * m + k]))
                p = r;
        double pv = a[(size_t)p * m + k];
        if (pv == 0.0 || !isfinite(pv))
            return SC_ENUMERIC;
        if (piv)
            piv[k] = p;
        if (p != k) {
            for (int c = 0; c < m; c++) {
                double t = a[(size_t)k * m + c];
                a[(size_t)k * m + c] = a[(size_t)p * m + c];
                a[(size_t)p * m + c] = t;
            }
            if (b) {
                double t = b[k];
                b[k] = b[p];
                b[p] = t;
            }
        }
        for (int r = k + 1; r < m; r++) {
            double g = a[(size_t)r * m + k] / pv;
            a[(size_t)r * m + k] = g;
            if (g == 0.0)
                continue;
            for (int c = k + 1; c < m; c++)
                a[(size_t)r * m + c] -= g * a[(size_t)k * m + c];
            if (b)
                b[r] -= g * b[k];
        }
    }
    return SC_OK;
}

/* b = U^-1 b, U the upper triangle of a. */
static void lu_back(int m, const double *a, double *b)
{
    for (int r = m - 1; r >= 0; r--) {
        double s = b[r];
        for (int c = r + 1; c < m; c++)
            s -= a[(size_t)r * m + c] * b[c];
        b[r] = s / a[(size_t)r * m + r];
    }
}

int sc_lu_solve(int m, double *a, double *b)
{
    int rc = lu_eliminate(m, a, NULL, b);
    if (rc == SC_OK)
        lu_back(m, a, b);
    return rc;
}

int sc_lu_factor(int m, double *a, int *piv)
{
    return lu_eliminate(m, a, piv, NULL);
}

void sc_lu_solve_factored(int m, const double *a, const int *piv, double *b)
{
    for (int k = 0; k < m; k++) {
        if (piv[k] != k) {
            double t = b[k];
            b[k] = b[piv[k]];
            b[piv[k]] = t;
        }
        for (int r = k + 1; r < m; r++) {
            double g = a[(size_t)r * m + k];
            if (g != 0.0)
                b[r] -= g * b[k];
        }
    }
    lu_back(m, a, b);
}
