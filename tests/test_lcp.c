/* test_lcp.c - the LCP solver (lib/core/lcp.c, lcp_factor.c, lcp_lemke.c):
 * answers checked independently (long double residuals, exhaustive
 * enumeration, Lemke's method written here, projected Gauss-Seidel,
 * rigid-body momentum balance), never "did not crash". An internal test:
 * it calls sc_lcp_dantzig / sc_lcp_boxed through lib/core/lcp.h.
 * Run from the repository root (reads tests/data/siconos/). */
#include <float.h>
#include <glob.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "core.h"
#include "lcp.h"

/* A double-precision answer is right when every violation is below
 * TEST_TOL (n+1) eps S_i, S_i = |q_i| + sum_j |M_ij z_j| being the size of
 * the terms that make w_i (so (n+1) eps S_i bounds the rounding of w_i).
 * The solver accepts 1000 (n+1) eps S_i; the test allows ten times that. */
#define TEST_TOL 1e4
#define SICONOS_DIR "tests/data/siconos/"

/* ---- small tools ------------------------------------------------------- */

typedef struct rng { uint64_t s; } rng;

static double urand(rng *r)   /* xorshift64*: [0, 1), reproducible */
{
    r->s ^= r->s >> 12;
    r->s ^= r->s << 25;
    r->s ^= r->s >> 27;
    return (double)((r->s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

static double srnd(rng *r)
{
    return 2.0 * urand(r) - 1.0;
}

static double *vec(int n)
{
    double *v = calloc((size_t)(n > 0 ? n : 1), sizeof(double));
    assert_non_null(v);
    return v;
}

static double *mat(int n)
{
    return vec(n * n);
}

static double tol_rel(int n)
{
    return TEST_TOL * (n + 1.0) * DBL_EPSILON;
}

/* ---- independent check of a (boxed) LCP answer ---------------------------- */

/* w = M z + q in long double, S_i, and the conditions stated as states:
 * at lo (w >= 0), at hi (w <= 0) or inside (w = 0), each within the test
 * tolerance. lo/hi NULL = the standard LCP (0, +inf). Also checks that
 * the solver's w is M z + q. Returns 1 if all hold; *worst gets the
 * largest violation relative to S_i. */
static int answer_ok(int n, const double *M, const double *q, const double *lo,
                     const double *hi, const double *z, const double *w, double *worst)
{
    double zmax = 0, tr = tol_rel(n), bad = 0;
    int ok = 1;
    for (int i = 0; i < n; i++) {
        if (!isfinite(z[i]))
            return 0;
        zmax = fmax(zmax, fabs(z[i]));
    }
    double tz = tr * zmax;
    for (int i = 0; i < n; i++) {
        long double acc = q[i], s = fabsl((long double)q[i]);
        for (int j = 0; j < n; j++) {
            acc += (long double)M[(size_t)i * n + j] * z[j];
            s += fabsl((long double)M[(size_t)i * n + j] * z[j]);
        }
        double wi = (double)acc, tw = tr * (double)s + DBL_MIN;
        double l = lo ? lo[i] : 0.0, h = hi ? hi[i] : INFINITY;
        int at_lo = z[i] - l <= tz, at_hi = h - z[i] <= tz;
        double v = 0;
        if (z[i] < l - tz || z[i] > h + tz)
            v = INFINITY;
        else if (at_lo && at_hi)
            v = 0;
        else if (at_lo)
            v = fmax(0.0, -wi);
        else if (at_hi)
            v = fmax(0.0, wi);
        else
            v = fabs(wi);
        v = fmax(v, fabs(w[i] - wi));
        if (!(v <= tw))
            ok = 0;
        bad = fmax(bad, v / ((double)s + DBL_MIN));
    }
    if (worst)
        *worst = bad;
    return ok;
}

/* Friction rows get the bounds +-mu |z_normal| of the answer itself. */
static void friction_bounds(int n, const double *lo, const double *hi, const int *findex,
                            const double *mu, const double *z, double *blo, double *bhi)
{
    for (int i = 0; i < n; i++) {
        double b = findex[i] >= 0 ? mu[i] * fabs(z[findex[i]]) : 0;
        blo[i] = findex[i] >= 0 ? -b : lo[i];
        bhi[i] = findex[i] >= 0 ? b : hi[i];
    }
}

/* ---- independent solvers --------------------------------------------------- */

/* Solve a x = b (m x m, row-major, destroyed) by Gaussian elimination with
 * partial pivoting in long double; 0 if a pivot is below tiny. */
static int gauss(int m, long double *a, long double *b, long double tiny)
{
    for (int k = 0; k < m; k++) {
        int p = k;
        for (int r = k + 1; r < m; r++)
            if (fabsl(a[r * m + k]) > fabsl(a[p * m + k]))
                p = r;
        if (fabsl(a[p * m + k]) <= tiny)
            return 0;
        for (int c = 0; c < m; c++) {
            long double t = a[k * m + c];
            a[k * m + c] = a[p * m + c];
            a[p * m + c] = t;
        }
        long double t = b[k];
        b[k] = b[p];
        b[p] = t;
        for (int r = k + 1; r < m; r++) {
            long double g = a[r * m + k] / a[k * m + k];
            for (int c = k; c < m; c++)
                a[r * m + c] -= g * a[k * m + c];
            b[r] -= g * b[k];
        }
    }
    for (int r = m - 1; r >= 0; r--) {
        long double s = b[r];
        for (int c = r + 1; c < m; c++)
            s -= a[r * m + c] * b[c];
        b[r] = s / a[r * m + r];
    }
    return 1;
}

/* Exhaustive enumeration (n <= 12): every complementary set C with M_CC
 * nonsingular, z_C = -M_CC^-1 q_C, z = 0 elsewhere; keeps those with z >= 0
 * and w >= 0 (to 1e-9 relative). Returns how many; the first in zsol. */
static int enumerate(int n, const double *M, const double *q, double *zsol)
{
    long double a[144], b[12], z[12];
    double scale = 0;
    int found = 0;
    for (int i = 0; i < n * n; i++)
        scale = fmax(scale, fabs(M[i]));
    for (int i = 0; i < n; i++)
        scale = fmax(scale, fabs(q[i]));
    for (unsigned mask = 0; mask < (1u << n); mask++) {
        int idx[12], m = 0;
        for (int i = 0; i < n; i++)
            if (mask >> i & 1)
                idx[m++] = i;
        for (int r = 0; r < m; r++) {
            b[r] = -q[idx[r]];
            for (int c = 0; c < m; c++)
                a[r * m + c] = M[idx[r] * n + idx[c]];
        }
        if (!gauss(m, a, b, 1e-12L * scale))
            continue;
        for (int i = 0; i < n; i++)
            z[i] = 0;
        for (int r = 0; r < m; r++)
            z[idx[r]] = b[r];
        int ok = 1;
        for (int i = 0; i < n && ok; i++) {
            long double w = q[i];
            for (int j = 0; j < n; j++)
                w += M[i * n + j] * z[j];
            ok = z[i] >= -1e-9L * scale && w >= -1e-9L * scale;
        }
        if (ok && found++ == 0)
            for (int i = 0; i < n; i++)
                zsol[i] = (double)z[i];
    }
    return found;
}

/* Lemke's complementary pivoting with covering vector e (the classic
 * tableau [I -M -e | q]), ties to the lowest row, z0 preferred. Returns 1
 * with z, 0 on a secondary ray or after max_piv pivots. *pivots counts. */
static int lemke(int n, const double *M, const double *q, double *z, long max_piv, long *pivots)
{
    int cols = 2 * n + 1;   /* w_0.., z_0.., z0 */
    double *t = calloc((size_t)n * cols, sizeof(double)), *rhs = vec(n);
    int *basis = calloc((size_t)n, sizeof(int));
    assert_true(t && basis);
    for (int i = 0; i < n; i++) {
        t[i * cols + i] = 1;
        for (int j = 0; j < n; j++)
            t[i * cols + n + j] = -M[i * n + j];
        t[i * cols + 2 * n] = -1;
        rhs[i] = q[i];
        basis[i] = i;
    }
    int r = 0, enter = 2 * n, ok = 0;
    long piv = 0;
    for (int i = 1; i < n; i++)
        if (rhs[i] < rhs[r])
            r = i;
    if (rhs[r] >= 0) {
        ok = 1;
        goto done;
    }
    for (;;) {
        double p = t[r * cols + enter];
        for (int c = 0; c < cols; c++)
            t[r * cols + c] /= p;
        rhs[r] /= p;
        for (int i = 0; i < n; i++) {
            double g = t[i * cols + enter];
            if (i == r || g == 0)
                continue;
            for (int c = 0; c < cols; c++)
                t[i * cols + c] -= g * t[r * cols + c];
            rhs[i] -= g * rhs[r];
        }
        int leaving = basis[r];
        basis[r] = enter;
        if (leaving == 2 * n) {
            ok = 1;
            break;
        }
        if (++piv > max_piv)
            break;
        enter = leaving < n ? leaving + n : leaving - n;
        r = -1;
        double best = INFINITY;
        for (int i = 0; i < n; i++) {
            double g = t[i * cols + enter];
            if (g <= 1e-12)
                continue;
            double ratio = rhs[i] / g, slack = r < 0 ? 0 : 1e-12 * fabs(best);
            if (r < 0 || ratio < best - slack || (ratio <= best + slack && basis[i] == 2 * n)) {
                best = ratio;
                r = i;
            }
        }
        if (r < 0)
            break;   /* secondary ray */
    }
done:
    for (int i = 0; i < n; i++)
        z[i] = 0;
    for (int i = 0; i < n; i++)
        if (basis[i] >= n && basis[i] < 2 * n)
            z[basis[i] - n] = rhs[i];
    if (pivots)
        *pivots = piv;
    free(t);
    free(rhs);
    free(basis);
    return ok;
}

/* Projected Gauss-Seidel for a boxed LCP with a symmetric positive
 * definite, diagonally dominant M (a contraction there): z to ~1e-14. */
static void pgs(int n, const double *M, const double *q, const double *lo, const double *hi,
                double *z)
{
    for (int i = 0; i < n; i++)
        z[i] = fmin(fmax(0.0, lo[i]), hi[i]);
    for (int sweep = 0; sweep < 2000; sweep++) {
        double change = 0;
        for (int i = 0; i < n; i++) {
            double r = q[i];
            for (int j = 0; j < n; j++)
                r += M[i * n + j] * z[j];
            double zi = fmin(fmax(z[i] - r / M[i * n + i], lo[i]), hi[i]);
            change = fmax(change, fabs(zi - z[i]));
            z[i] = zi;
        }
        if (change == 0)
            break;
    }
}

/* ---- matrices ---------------------------------------------------------------- */

/* Symmetric positive definite: B B^T / n + delta I. */
static void make_spd(rng *r, int n, double delta, double *M)
{
    double *B = mat(n);
    for (int i = 0; i < n * n; i++)
        B[i] = srnd(r);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double s = 0;
            for (int k = 0; k < n; k++)
                s += B[i * n + k] * B[j * n + k];
            M[i * n + j] = s / n + (i == j ? delta : 0);
        }
    free(B);
}

/* Symmetric PSD of rank r < n: B B^T with B n x r. */
static void make_psd(rng *g, int n, int rank, double *M)
{
    double *B = vec(n * rank);
    for (int i = 0; i < n * rank; i++)
        B[i] = srnd(g);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double s = 0;
            for (int k = 0; k < rank; k++)
                s += B[i * rank + k] * B[j * rank + k];
            M[i * n + j] = s;
        }
    free(B);
}

/* Non-symmetric P-matrices: kind 0 = positive definite plus a skew part
 * (x^T M x > 0, hence P), kind 1 = strictly row diagonally dominant with a
 * positive diagonal (P by Gershgorin on every principal block). */
static void make_p(rng *r, int n, int kind, double *M)
{
    if (kind == 0) {
        make_spd(r, n, 0.2, M);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < i; j++) {
                double k = 2.0 * srnd(r);
                M[i * n + j] += k;
                M[j * n + i] -= k;
            }
        return;
    }
    for (int i = 0; i < n; i++) {
        double s = 0;
        for (int j = 0; j < n; j++)
            if (j != i) {
                M[i * n + j] = srnd(r);
                s += fabs(M[i * n + j]);
            }
        M[i * n + i] = s + 0.1 + urand(r);
    }
}

static int is_symmetric(int n, const double *M)
{
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++)
            if (M[i * n + j] != M[j * n + i])
                return 0;
    return 1;
}

/* PSD test: Cholesky of (M + M^T)/2 + tau I with tau = 1e-12 max|M| n
 * (positive definite after that shift <=> no eigenvalue below -tau). */
static int is_psd(int n, const double *M)
{
    long double *a = calloc((size_t)n * n, sizeof(long double));
    double mx = 0;
    assert_non_null(a);
    for (int i = 0; i < n * n; i++)
        mx = fmax(mx, fabs(M[i]));
    long double tau = 1e-12L * mx * n + LDBL_MIN;
    int ok = 1;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            a[i * n + j] = 0.5L * ((long double)M[i * n + j] + M[j * n + i]) + (i == j ? tau : 0);
    for (int k = 0; k < n && ok; k++) {
        if (!(a[k * n + k] > 0)) {
            ok = 0;
            break;
        }
        long double d = sqrtl(a[k * n + k]);
        for (int i = k; i < n; i++)
            a[i * n + k] /= d;
        for (int j = k + 1; j < n; j++)
            for (int i = j; i < n; i++)
                a[i * n + j] -= a[i * n + k] * a[j * n + k];
    }
    free(a);
    return ok;
}

/* P-matrix test by all principal minors (n <= 12). */
static int is_p(int n, const double *M)
{
    long double a[144];
    double mx = 0;
    for (int i = 0; i < n * n; i++)
        mx = fmax(mx, fabs(M[i]));
    for (unsigned mask = 1; mask < (1u << n); mask++) {
        int idx[12], m = 0;
        for (int i = 0; i < n; i++)
            if (mask >> i & 1)
                idx[m++] = i;
        for (int r = 0; r < m; r++)
            for (int c = 0; c < m; c++)
                a[r * m + c] = M[idx[r] * n + idx[c]];
        /* determinant by elimination with partial pivoting, sign tracked */
        long double det = 1;
        for (int k = 0; k < m; k++) {
            int p = k;
            for (int r = k + 1; r < m; r++)
                if (fabsl(a[r * m + k]) > fabsl(a[p * m + k]))
                    p = r;
            if (p != k) {
                for (int c = 0; c < m; c++) {
                    long double t = a[k * m + c];
                    a[k * m + c] = a[p * m + c];
                    a[p * m + c] = t;
                }
                det = -det;
            }
            det *= a[k * m + k];
            if (fabsl(a[k * m + k]) <= 1e-12L * mx)
                break;
            for (int r = k + 1; r < m; r++) {
                long double g = a[r * m + k] / a[k * m + k];
                for (int c = k; c < m; c++)
                    a[r * m + c] -= g * a[k * m + c];
            }
        }
        if (!(det > 1e-12L * powl(mx, m)))
            return 0;
    }
    return 1;
}

/* ---- rigid-body contact matrices ---------------------------------------------- */

/* A box body: mass, world inverse inertia, centre. */
typedef struct body {
    double m, iinv[9], c[3];
} body;

static body box_body(double m, double hx, double hy, double hz, double yaw, double cx,
                     double cy, double cz)
{
    body b = { m, { 0 }, { cx, cy, cz } };
    double I[3] = { m * (hy * hy + hz * hz) / 3, m * (hx * hx + hz * hz) / 3,
                    m * (hx * hx + hy * hy) / 3 };
    double R[9] = { cos(yaw), -sin(yaw), 0, sin(yaw), cos(yaw), 0, 0, 0, 1 };
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += R[i * 3 + k] * R[j * 3 + k] / I[k];
            b.iinv[i * 3 + j] = s;
        }
    return b;
}

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* A contact system: nb bodies (6 velocity coordinates each), rows of J
 * (relative velocity of body b minus body a along d at point p; a or b
 * may be -1 = the static world). */
typedef struct csys {
    int nb, rows, cap;
    const body *bodies;
    double *J;      /* rows x 6 nb */
} csys;

static void add_row(csys *s, int a, int b, const double p[3], const double d[3])
{
    assert_true(s->rows < s->cap);
    double *row = s->J + (size_t)s->rows * 6 * s->nb;
    int who[2] = { a, b };
    for (int k = 0; k < 2; k++) {
        if (who[k] < 0)
            continue;
        double sign = k == 0 ? -1.0 : 1.0, r[3], rxd[3];
        for (int i = 0; i < 3; i++)
            r[i] = p[i] - s->bodies[who[k]].c[i];
        cross(r, d, rxd);
        for (int i = 0; i < 3; i++) {
            row[6 * who[k] + i] += sign * d[i];
            row[6 * who[k] + 3 + i] += sign * rxd[i];
        }
    }
    s->rows++;
}

/* W x: the inverse mass matrix applied to a 6 nb vector. */
static void apply_w(const csys *s, const double *x, double *out)
{
    for (int b = 0; b < s->nb; b++) {
        const body *bd = &s->bodies[b];
        for (int i = 0; i < 3; i++) {
            out[6 * b + i] = x[6 * b + i] / bd->m;
            double a = 0;
            for (int j = 0; j < 3; j++)
                a += bd->iinv[i * 3 + j] * x[6 * b + 3 + j];
            out[6 * b + 3 + i] = a;
        }
    }
}

/* A = J W J^T and q = J u: the velocity-level contact LCP (the paper's
 * V' = A P + V) for bodies moving with u (gravity already applied). */
static void build_lcp(const csys *s, const double *u, double *A, double *q)
{
    int n = s->rows, k = 6 * s->nb;
    double *wj = vec(k);
    for (int j = 0; j < n; j++) {
        apply_w(s, s->J + (size_t)j * k, wj);
        for (int i = 0; i < n; i++) {
            double a = 0;
            for (int c = 0; c < k; c++)
                a += s->J[(size_t)i * k + c] * wj[c];
            A[i * n + j] = a;
        }
    }
    for (int i = 0; i < n; i++) {
        double a = 0;
        for (int c = 0; c < k; c++)
            a += s->J[(size_t)i * k + c] * u[c];
        q[i] = a;
    }
    free(wj);
}

/* u' = u + W J^T p: velocities after the impulses. */
static void velocities_after(const csys *s, const double *u, const double *p, double *out)
{
    int k = 6 * s->nb;
    double *f = vec(k);
    for (int i = 0; i < s->rows; i++)
        for (int c = 0; c < k; c++)
            f[c] += s->J[(size_t)i * k + c] * p[i];
    apply_w(s, f, out);
    for (int c = 0; c < k; c++)
        out[c] += u[c];
    free(f);
}

/* Contact points under a face of half extents hx, hy (rotated by yaw) at
 * height z: the 4 corners, then (npts == 8) the 4 edge midpoints, which
 * are redundant: rank(J) stays 3 per face. */
static void face_points(double cx, double cy, double z, double hx, double hy, double yaw,
                        int npts, double (*out)[3])
{
    static const double corner[8][2] = { { 1, 1 },  { -1, 1 }, { -1, -1 }, { 1, -1 },
                                         { 0, 1 },  { -1, 0 }, { 0, -1 },  { 1, 0 } };
    for (int k = 0; k < npts; k++) {
        double x = corner[k][0] * hx, y = corner[k][1] * hy;
        out[k][0] = cx + cos(yaw) * x - sin(yaw) * y;
        out[k][1] = cy + sin(yaw) * x + cos(yaw) * y;
        out[k][2] = z;
    }
}

/* ---- the standard LCP: random P-matrices ----------------------------------------- */

static void solve_and_check(int n, const double *M, const double *q, double *z, double *w,
                            sc_lcp_info *info)
{
    int rc = sc_lcp_dantzig(n, M, q, z, w, info);
    assert_int_equal(rc, SC_OK);
    double worst;
    assert_true(answer_ok(n, M, q, NULL, NULL, z, w, &worst));
    /* the solver's claim (lib/core/lcp.c): residual, in units of w, at most
     * 1000 (n+1) eps max_i S_i */
    double smax = 0;
    for (int i = 0; i < n; i++) {
        double si = fabs(q[i]);
        for (int j = 0; j < n; j++)
            si += fabs(M[i * n + j] * z[j]);
        smax = fmax(smax, si);
    }
    assert_true(info->residual >= 0 && info->residual <= 1000.0 * (n + 1) * DBL_EPSILON * smax);
}

/* For a P-matrix the solution is unique: z must equal the independent one. */
static void assert_same_z(int n, const double *z, const double *zref, double rel)
{
    double zmax = 1e-300;
    for (int i = 0; i < n; i++)
        zmax = fmax(zmax, fabs(zref[i]));
    for (int i = 0; i < n; i++) {
        if (!(fabs(z[i] - zref[i]) <= rel * zmax))
            print_message("n=%d i=%d z=%.17g ref=%.17g\n", n, i, z[i], zref[i]);
        assert_true(fabs(z[i] - zref[i]) <= rel * zmax);
    }
}

static void test_random_p_matrices_satisfy_complementarity(void **state)
{
    (void)state;
    static const int sizes[] = { 1, 2, 3, 5, 8, 10, 20, 50, 100 };
    rng r = { 0x5eed0001u };
    int problems = 0;
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        int n = sizes[s];
        for (int kind = 0; kind < 3; kind++) {
            for (int rep = 0; rep < (n <= 10 ? 6 : 2); rep++) {
                double *M = mat(n), *q = vec(n), *z = vec(n), *w = vec(n), *zref = vec(n);
                if (kind == 2)
                    make_spd(&r, n, 0.1, M);
                else
                    make_p(&r, n, kind, M);
                for (int i = 0; i < n; i++)
                    q[i] = srnd(&r);
                sc_lcp_info info;
                solve_and_check(n, M, q, z, w, &info);
                /* unique solution: compare with enumeration or Lemke */
                if (n <= 10) {
                    assert_int_equal(enumerate(n, M, q, zref), 1);
                } else {
                    long piv;
                    assert_true(lemke(n, M, q, zref, 100L * n, &piv));
                }
                assert_same_z(n, z, zref, 1e-8);
                /* about one pivot per index (Baraff's observation) on
                 * symmetric problems; strongly skew ones take more */
                assert_true(info.pivots <= (kind == 2 ? 2L : 8L) * n);
                problems++;
                free(M);
                free(q);
                free(z);
                free(w);
                free(zref);
            }
        }
    }
    assert_true(problems > 100);
}

/* Symmetric PSD of low rank: the solution set is convex and w is unique
 * (for PSD M, (w1 - w2).(z1 - z2) <= 0 forces M(z1 - z2) = 0). */
static void test_low_rank_psd_matrices_give_the_unique_w(void **state)
{
    (void)state;
    rng r = { 0x5eed0002u };
    for (int n = 2; n <= 10; n++) {
        for (int rep = 0; rep < 6; rep++) {
            int rank = 1 + (int)(urand(&r) * (n - 1));
            double *M = mat(n), *q = vec(n), *z = vec(n), *w = vec(n), *zref = vec(n);
            make_psd(&r, n, rank, M);
            /* feasible by construction: q = w* - M z* with z*, w* >= 0 */
            double *zs = vec(n);
            for (int i = 0; i < n; i++)
                zs[i] = urand(&r) < 0.5 ? urand(&r) : 0;
            for (int i = 0; i < n; i++) {
                double a = 0;
                for (int j = 0; j < n; j++)
                    a += M[i * n + j] * zs[j];
                q[i] = (zs[i] == 0 ? urand(&r) : 0) - a;
            }
            sc_lcp_info info;
            solve_and_check(n, M, q, z, w, &info);
            assert_true(enumerate(n, M, q, zref) >= 1);
            for (int i = 0; i < n; i++) {
                double wr = q[i], s = fabs(q[i]);
                for (int j = 0; j < n; j++) {
                    wr += M[i * n + j] * zref[j];
                    s += fabs(M[i * n + j] * zref[j]) + fabs(M[i * n + j] * z[j]);
                }
                assert_true(fabs(w[i] - wr) <= 1e-9 * (s + 1e-300));
            }
            free(M);
            free(q);
            free(z);
            free(w);
            free(zref);
            free(zs);
        }
    }
}

/* Larger low-rank PSD problems (n up to 60), checked by the residual. */
static void test_large_singular_psd_problems_are_solved(void **state)
{
    (void)state;
    rng r = { 0x5eed0003u };
    static const int sizes[] = { 20, 40, 60 };
    for (size_t s = 0; s < 3; s++) {
        int n = sizes[s];
        double *M = mat(n), *q = vec(n), *z = vec(n), *w = vec(n), *zs = vec(n);
        make_psd(&r, n, n / 3, M);
        for (int i = 0; i < n; i++)
            zs[i] = urand(&r) < 0.5 ? urand(&r) : 0;
        for (int i = 0; i < n; i++) {
            double a = 0;
            for (int j = 0; j < n; j++)
                a += M[i * n + j] * zs[j];
            q[i] = (zs[i] == 0 ? urand(&r) : 0) - a;
        }
        sc_lcp_info info;
        solve_and_check(n, M, q, z, w, &info);
        free(M);
        free(q);
        free(z);
        free(w);
        free(zs);
    }
}

/* Non-symmetric PSD matrices, M = B B^T + K with K skew (x^T M x =
 * |B^T x|^2 >= 0), pure skew-symmetric ones included: a zero diagonal
 * pivot with a nonsingular 2x2 block, which principal pivoting on single
 * indices cannot pass (the solver falls back on Lemke's method). Every
 * feasible PSD problem (these are built feasible) must be solved. */
static void test_nonsymmetric_psd_problems_are_solved(void **state)
{
    (void)state;
    rng r = { 0x5eed000au };
    for (int rep = 0; rep < 40; rep++) {
        int n = 2 + rep % 9, rank = rep % 3 == 0 ? 0 : 1 + rep % (n - 1 > 0 ? n - 1 : 1);
        double *M = mat(n), *q = vec(n), *z = vec(n), *w = vec(n), *zs = vec(n);
        if (rank > 0)
            make_psd(&r, n, rank, M);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < i; j++) {
                double k = srnd(&r);
                M[i * n + j] += k;
                M[j * n + i] -= k;
            }
        for (int i = 0; i < n; i++)
            zs[i] = urand(&r) < 0.5 ? urand(&r) : 0;
        for (int i = 0; i < n; i++) {
            double a = 0;
            for (int j = 0; j < n; j++)
                a += M[i * n + j] * zs[j];
            q[i] = (zs[i] == 0 ? urand(&r) : 0) - a;
        }
        assert_true(is_psd(n, M));
        sc_lcp_info info;
        solve_and_check(n, M, q, z, w, &info);
        free(M);
        free(q);
        free(z);
        free(w);
        free(zs);
    }
}

/* ---- contact matrices from rigid bodies ---------------------------------------------- */

#define G 9.81
#define DT 0.01

/* One box resting on the floor with npts contacts: it must come to rest
 * (every post-impulse velocity 0) and the normal impulses must carry its
 * weight for one step, sum p = m g dt. */
static void box_on_floor(int npts, double yaw)
{
    body b = box_body(2.0, 0.3, 0.2, 0.1, yaw, 0.05, -0.02, 0.1);
    double J[8 * 6] = { 0 }, pts[8][3], up[3] = { 0, 0, 1 };
    csys s = { 1, 0, 8, &b, J };
    face_points(b.c[0], b.c[1], 0.0, 0.3, 0.2, yaw, npts, pts);
    for (int k = 0; k < npts; k++)
        add_row(&s, -1, 0, pts[k], up);
    double u[6] = { 0, 0, -G * DT, 0, 0, 0 }, A[64], q[8], z[8], w[8], after[6];
    build_lcp(&s, u, A, q);
    sc_lcp_info info;
    int n = npts;
    assert_int_equal(sc_lcp_dantzig(n, A, q, z, w, &info), SC_OK);
    assert_true(answer_ok(n, A, q, NULL, NULL, z, w, NULL));
    double sum = 0;
    for (int k = 0; k < n; k++)
        sum += z[k];
    /* momentum: m (0 - (-g dt)) = sum p, to rounding of the solve */
    assert_true(fabs(sum - b.m * G * DT) <= 1e-12 * b.m * G * DT);
    velocities_after(&s, u, z, after);
    for (int c = 0; c < 6; c++)
        assert_true(fabs(after[c]) <= 1e-12 * G * DT / 0.1);
    for (int k = 0; k < n; k++)
        assert_true(fabs(w[k]) <= 1e-12 * G * DT);
}

static void test_box_on_floor_with_four_contacts_comes_to_rest(void **state)
{
    (void)state;
    box_on_floor(4, 0.0);
    box_on_floor(4, 0.7);
}

static void test_box_on_floor_with_eight_redundant_contacts_comes_to_rest(void **state)
{
    (void)state;
    /* 8 rows of rank 3: J W J^T is only positive semidefinite */
    box_on_floor(8, 0.0);
    box_on_floor(8, 0.3);
}

/* A stack of boxes, each face with 8 contacts (redundant): every interface
 * carries the weight above it for one step, everything comes to rest. */
static void test_stack_of_boxes_with_redundant_contacts_carries_the_weight(void **state)
{
    (void)state;
    enum { NB = 4, NP = 8, N = NB * NP };
    body bodies[NB];
    double hz = 0.1, yaw = 0.2;
    for (int k = 0; k < NB; k++)
        bodies[k] = box_body(1.0 + k, 0.3, 0.3, hz, yaw, 0, 0, hz * (2 * k + 1));
    double *J = vec(N * 6 * NB), pts[NP][3], up[3] = { 0, 0, 1 };
    csys s = { NB, 0, N, bodies, J };
    for (int k = 0; k < NB; k++) {
        face_points(0, 0, 2 * hz * k, 0.3, 0.3, yaw, NP, pts);
        for (int p = 0; p < NP; p++)
            add_row(&s, k - 1, k, pts[p], up);
    }
    double u[6 * NB] = { 0 }, *A = mat(N), q[N], z[N], w[N], after[6 * NB];
    for (int k = 0; k < NB; k++)
        u[6 * k + 2] = -G * DT;
    build_lcp(&s, u, A, q);
    assert_true(is_psd(N, A));
    sc_lcp_info info;
    assert_int_equal(sc_lcp_dantzig(N, A, q, z, w, &info), SC_OK);
    assert_true(answer_ok(N, A, q, NULL, NULL, z, w, NULL));
    for (int k = 0; k < NB; k++) {
        double above = 0, sum = 0;
        for (int j = k; j < NB; j++)
            above += bodies[j].m * G * DT;
        for (int p = 0; p < NP; p++)
            sum += z[k * NP + p];
        assert_true(fabs(sum - above) <= 1e-11 * above);
    }
    velocities_after(&s, u, z, after);
    for (int c = 0; c < 6 * NB; c++)
        assert_true(fabs(after[c]) <= 1e-11 * G * DT / hz);
    print_message("stack of %d boxes, %d contacts: %ld pivots, residual %.2g\n", NB, N,
                  info.pivots, info.residual);
    free(J);
    free(A);
}

/* A spinning, sliding box landing on one edge: contacts that separate get
 * no impulse and a positive post-velocity; checked against momentum. */
static void test_landing_box_impulses_respect_momentum(void **state)
{
    (void)state;
    body b = box_body(1.5, 0.25, 0.15, 0.1, 0.4, 0, 0, 0.1);
    double J[8 * 6] = { 0 }, pts[8][3], up[3] = { 0, 0, 1 };
    csys s = { 1, 0, 8, &b, J };
    face_points(0, 0, 0, 0.25, 0.15, 0.4, 8, pts);
    for (int k = 0; k < 8; k++)
        add_row(&s, -1, 0, pts[k], up);
    double u[6] = { 0.3, -0.1, -1.2, 2.0, -3.0, 0.5 }, A[64], q[8], z[8], w[8], after[6];
    build_lcp(&s, u, A, q);
    sc_lcp_info info;
    assert_int_equal(sc_lcp_dantzig(8, A, q, z, w, &info), SC_OK);
    assert_true(answer_ok(8, A, q, NULL, NULL, z, w, NULL));
    velocities_after(&s, u, z, after);
    /* J u' = w: the post-impact normal velocities are the LCP's w */
    for (int k = 0; k < 8; k++) {
        double v = 0;
        for (int c = 0; c < 6; c++)
            v += J[k * 6 + c] * after[c];
        assert_true(fabs(v - w[k]) <= 1e-12 * 10);
        assert_true(v >= -1e-12);
    }
    /* linear momentum: m dv_z = sum p (the normal is z), no change in x, y */
    double sum = 0;
    for (int k = 0; k < 8; k++)
        sum += z[k];
    assert_true(fabs(b.m * (after[2] - u[2]) - sum) <= 1e-12 * sum);
    assert_true(fabs(after[0] - u[0]) <= 1e-15 && fabs(after[1] - u[1]) <= 1e-15);
}

/* ---- siconos problems --------------------------------------------------------------- */

/* Format (tests/data/siconos/README.md): n, storage (0), rows, cols, then
 * the dense matrix's own "rows cols", the matrix column by column, q. */
static int load_siconos(const char *path, int *pn, double **pM, double **pq)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    int n, storage, r, c, r2, c2, ok = 1;
    ok = fscanf(f, "%d %d %d %d %d %d", &n, &storage, &r, &c, &r2, &c2) == 6 &&
         storage == 0 && n > 0 && n <= 1000 && r == n && c == n && r2 == n && c2 == n;
    double *M = ok ? mat(n) : NULL, *q = ok ? vec(n) : NULL;
    for (int j = 0; ok && j < n; j++)
        for (int i = 0; ok && i < n; i++)
            ok = fscanf(f, "%lf", &M[i * n + j]) == 1;
    for (int i = 0; ok && i < n; i++)
        ok = fscanf(f, "%lf", &q[i]) == 1;
    fclose(f);
    if (!ok) {
        free(M);
        free(q);
        return 0;
    }
    *pn = n;
    *pM = M;
    *pq = q;
    return 1;
}

static const char *rc_name(int rc)
{
    switch (rc) {
    case SC_OK: return "SC_OK";
    case SC_ENOSOLUTION: return "SC_ENOSOLUTION";
    case SC_EMAXITER: return "SC_EMAXITER";
    case SC_ENUMERIC: return "SC_ENUMERIC";
    default: return "other";
    }
}

/* Every file in tests/data/siconos/ (globbed, so a new one is run too). */
static void test_every_siconos_problem_is_solved_or_refused(void **state)
{
    (void)state;
    glob_t g;
    assert_int_equal(glob(SICONOS_DIR "*.dat", 0, NULL, &g), 0);
    assert_true(g.gl_pathc >= 17);
    int solved = 0, guaranteed = 0;
    print_message("%-38s %3s %-5s %-15s %6s %9s %s\n", "problem", "n", "class", "result",
                  "pivots", "rel.resid", "enumeration");
    for (size_t k = 0; k < g.gl_pathc; k++) {
        int n = 0;
        double *M = NULL, *q = NULL;
        assert_true(load_siconos(g.gl_pathv[k], &n, &M, &q));
        double *z = vec(n), *w = vec(n), *zref = vec(n), worst = 0;
        int p = n <= 12 && is_p(n, M), psd = is_psd(n, M), sym = is_symmetric(n, M);
        sc_lcp_info info;
        int rc = sc_lcp_dantzig(n, M, q, z, w, &info);
        if (rc == SC_OK) {
            /* never SC_OK with a wrong answer */
            assert_true(answer_ok(n, M, q, NULL, NULL, z, w, &worst));
            solved++;
        } else {
            assert_true(rc == SC_ENOSOLUTION || rc == SC_EMAXITER || rc == SC_ENUMERIC);
        }
        /* the classes Cottle-Dantzig (and Lemke) are guaranteed to process;
         * all of these have a solution */
        if (p || psd) {
            assert_int_equal(rc, SC_OK);
            guaranteed++;
        }
        char enumr[32] = "-";
        if (n <= 12) {
            int count = enumerate(n, M, q, zref);
            snprintf(enumr, sizeof enumr, "%d basic sol.", count);
            if (p) {
                assert_int_equal(count, 1);
                assert_same_z(n, z, zref, 1e-9);
            }
        }
        print_message("%-38s %3d %-5s %-15s %6ld %9.2g %s\n", strrchr(g.gl_pathv[k], '/') + 1,
                      n, p ? "P" : psd ? (sym ? "PSD-s" : "PSD") : "-", rc_name(rc),
                      info.pivots, rc == SC_OK ? worst : NAN, enumr);
        free(M);
        free(q);
        free(z);
        free(w);
        free(zref);
    }
    print_message("%d of %zu solved (%d in a guaranteed class)\n", solved, g.gl_pathc,
                  guaranteed);
    globfree(&g);
    assert_true(guaranteed >= 11);
}

/* ---- classic hard instances ---------------------------------------------------------- */

/* Murty's matrix: upper triangular, 1 on the diagonal, 2 above (a P-matrix,
 * every principal minor 1). With q_i = -(2^(n+1) - 2^(i+1)) the unique
 * solution is z = 2^n e_{n-1}, and principal pivoting in index order walks
 * all 2^n - 1 complementary bases; with q = -1 it is z = e_{n-1}. */
static void murty(int n, int exponential, double *M, double *q)
{
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++)
            M[i * n + j] = j == i ? 1 : j > i ? 2 : 0;
        q[i] = exponential ? -(ldexp(1, n + 1) - ldexp(1, i + 1)) : -1;
    }
}

static void test_murty_example_is_solved_or_hits_the_pivot_limit(void **state)
{
    (void)state;
    for (int n = 2; n <= 16; n++) {
        double M[256], q[16], z[16], w[16], zref[16] = { 0 };
        for (int e = 0; e < 2; e++) {
            murty(n, e, M, q);
            zref[n - 1] = e ? ldexp(1, n) : 1;
            sc_lcp_info info;
            int rc = sc_lcp_dantzig(n, M, q, z, w, &info);
            if (!e || (1L << n) - 1 <= 10L * n + 100) {
                assert_int_equal(rc, SC_OK);
                assert_same_z(n, z, zref, 1e-15);
                /* the path length: 2n - 1, or all 2^n - 1 bases */
                assert_int_equal(info.pivots, e ? (1L << n) - 1 : 2L * n - 1);
            } else {
                assert_int_equal(rc, SC_EMAXITER);
            }
        }
        /* Lemke's method (here) is exponential on it too, but has no limit */
        long piv;
        murty(n, 1, M, q);
        assert_true(lemke(n, M, q, z, 1L << 20, &piv));
        assert_same_z(n, z, zref, 1e-12);
        zref[n - 1] = 0;
    }
}

static void test_q_nonnegative_gives_zero_without_pivots(void **state)
{
    (void)state;
    rng r = { 0x5eed0004u };
    double M[100], q[10], z[10], w[10];
    make_spd(&r, 10, 0.1, M);
    for (int i = 0; i < 10; i++)
        q[i] = i % 3 == 0 ? 0.0 : urand(&r);
    sc_lcp_info info;
    assert_int_equal(sc_lcp_dantzig(10, M, q, z, w, &info), SC_OK);
    assert_int_equal(info.pivots, 0);
    for (int i = 0; i < 10; i++) {
        assert_true(z[i] == 0.0);
        assert_true(w[i] == q[i]);
    }
}

/* Degenerate problems: q = w* - M z* with z*_i = w*_i = 0 for a third of
 * the indices (both zero at the solution) and q_i = 0 rows. */
static void test_degenerate_q_with_zeros_is_solved(void **state)
{
    (void)state;
    rng r = { 0x5eed0005u };
    for (int rep = 0; rep < 40; rep++) {
        int n = 3 + rep % 8;
        double *M = mat(n), *q = vec(n), *z = vec(n), *w = vec(n), *zs = vec(n), *zref = vec(n);
        if (rep % 2)
            make_spd(&r, n, 0.05, M);
        else
            make_p(&r, n, rep % 4 == 0, M);
        for (int i = 0; i < n; i++)
            zs[i] = i % 3 == 0 ? 0 : (urand(&r) < 0.5 ? 1 + urand(&r) : 0);
        for (int i = 0; i < n; i++) {
            double a = 0;
            for (int j = 0; j < n; j++)
                a += M[i * n + j] * zs[j];
            q[i] = (zs[i] == 0 && i % 3 != 0 ? urand(&r) : 0) - a;
        }
        sc_lcp_info info;
        solve_and_check(n, M, q, z, w, &info);
        assert_int_equal(enumerate(n, M, q, zref) >= 1, 1);
        free(M);
        free(q);
        free(z);
        free(w);
        free(zs);
        free(zref);
    }
    /* q = 0: z = 0 */
    double M[4] = { 2, 1, 1, 2 }, q[2] = { 0, 0 }, z[2], w[2];
    assert_int_equal(sc_lcp_solve(2, M, q, z, w), SC_OK);
    assert_true(z[0] == 0 && z[1] == 0 && w[0] == 0 && w[1] == 0);
}

/* Infeasible problems: an error code, never SC_OK. */
static void test_infeasible_problems_return_an_error(void **state)
{
    (void)state;
    double z[3], w[3];
    /* PSD, w_0 + w_1 = q_0 + q_1 = -2 < 0 for every z */
    double M1[4] = { 1, -1, -1, 1 }, q1[2] = { -1, -1 };
    assert_int_equal(sc_lcp_solve(2, M1, q1, z, w), SC_ENOSOLUTION);
    /* M = 0 (PSD): w = q has a negative entry */
    double M2[9] = { 0 }, q2[3] = { 1, -1, 2 };
    assert_int_equal(sc_lcp_solve(3, M2, q2, z, w), SC_ENOSOLUTION);
    /* M = -I (not PSD): w = -z - 1 < 0 */
    double M3[4] = { -1, 0, 0, -1 }, q3[2] = { -1, -1 };
    int rc = sc_lcp_solve(2, M3, q3, z, w);
    assert_true(rc == SC_ENOSOLUTION || rc == SC_ENUMERIC || rc == SC_EMAXITER);
    /* rank one, M = v v^T with v = (1, -1, 2): w = t v + q with t = v.z
     * needs t >= 1 (row 0) and t <= -1 (row 1) */
    double M4[9] = { 1, -1, 2, -1, 1, -2, 2, -2, 4 }, q4[3] = { -1, -1, -1 };
    assert_int_equal(sc_lcp_solve(3, M4, q4, z, w), SC_ENOSOLUTION);
}

/* ---- error paths ----------------------------------------------------------------------- */

static void test_bad_arguments_are_rejected(void **state)
{
    (void)state;
    double M[4] = { 2, 0, 0, 2 }, q[2] = { -1, 1 }, z[2], w[2];
    sc_lcp_info info;
    assert_int_equal(sc_lcp_dantzig(-1, M, q, z, w, &info), SC_EINVAL);
    assert_int_equal(sc_lcp_dantzig(2, NULL, q, z, w, &info), SC_EINVAL);
    assert_int_equal(sc_lcp_dantzig(2, M, q, NULL, w, &info), SC_EINVAL);
    assert_int_equal(sc_lcp_dantzig(0, NULL, NULL, NULL, NULL, &info), SC_OK);
    assert_int_equal(info.pivots, 0);
    M[1] = NAN;
    assert_int_equal(sc_lcp_dantzig(2, M, q, z, w, NULL), SC_EINVAL);
    M[1] = INFINITY;
    assert_int_equal(sc_lcp_solve(2, M, q, z, w), SC_EINVAL);
    M[1] = 0;
    q[1] = NAN;
    assert_int_equal(sc_lcp_solve(2, M, q, z, w), SC_EINVAL);
    q[1] = -INFINITY;
    assert_int_equal(sc_lcp_solve(2, M, q, z, w), SC_EINVAL);
    q[1] = 1;
    assert_int_equal(sc_lcp_solve(2, M, q, z, w), SC_OK);
    assert_true(fabs(z[0] - 0.5) < 1e-15 && z[1] == 0);

    double lo[2] = { 0, 0 }, hi[2] = { 1, 1 }, mu[2] = { 0.5, 0.5 };
    int fx[2] = { -1, 0 };
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, NULL, NULL, z, w, NULL), SC_OK);
    lo[0] = 2;   /* lo > hi */
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, NULL, NULL, z, w, NULL), SC_EINVAL);
    lo[0] = NAN;
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, NULL, NULL, z, w, NULL), SC_EINVAL);
    lo[0] = INFINITY;
    hi[0] = INFINITY;
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, NULL, NULL, z, w, NULL), SC_EINVAL);
    lo[0] = 0;
    hi[0] = 1;
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, fx, NULL, z, w, NULL), SC_EINVAL);
    mu[1] = -1;
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, fx, mu, z, w, NULL), SC_EINVAL);
    mu[1] = NAN;
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, fx, mu, z, w, NULL), SC_EINVAL);
    mu[1] = 0.5;
    fx[1] = 1;   /* its own normal */
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, fx, mu, z, w, NULL), SC_EINVAL);
    fx[1] = 2;   /* out of range */
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, fx, mu, z, w, NULL), SC_EINVAL);
    fx[0] = 1;
    fx[1] = 0;   /* a chain: the normal is itself a friction row */
    assert_int_equal(sc_lcp_boxed(2, M, q, lo, hi, fx, mu, z, w, NULL), SC_EINVAL);
    assert_int_equal(sc_lcp_boxed(0, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL),
                     SC_OK);
}

/* Same input, same bits (the cluster merges results from any node). */
static void test_solutions_are_bit_identical_across_runs(void **state)
{
    (void)state;
    rng r = { 0x5eed0006u };
    int n = 40;
    double *M = mat(n), *q = vec(n), *z1 = vec(n), *z2 = vec(n), *w1 = vec(n), *w2 = vec(n);
    make_psd(&r, n, 15, M);
    for (int i = 0; i < n; i++)
        q[i] = srnd(&r);
    int rc1 = sc_lcp_solve(n, M, q, z1, w1), rc2 = sc_lcp_solve(n, M, q, z2, w2);
    assert_int_equal(rc1, rc2);
    assert_memory_equal(z1, z2, n * sizeof(double));
    assert_memory_equal(w1, w2, n * sizeof(double));
    free(M);
    free(q);
    free(z1);
    free(z2);
    free(w1);
    free(w2);
}

/* ---- the factorisation ------------------------------------------------------------------ */

/* After any sequence of borderings and removals, L D U reproduces M_CC and
 * solves with it (symmetric and non-symmetric storage). */
static void test_factor_updates_reproduce_the_clamped_block(void **state)
{
    (void)state;
    rng r = { 0x5eed0007u };
    int n = 30;
    for (int sym = 0; sym < 2; sym++) {
        double *M = mat(n);
        if (sym)
            make_spd(&r, n, 0.5, M);
        else
            make_p(&r, n, 1, M);
        void *mem = malloc(sc_ldu_size(n, sym));
        assert_non_null(mem);
        sc_ldu f;
        sc_ldu_init(&f, n, sym, mem);
        int in[30] = { 0 };
        double worst = 0;
        for (int step = 0; step < 300; step++) {
            int j = (int)(urand(&r) * n);
            if (!in[j]) {
                double scale, piv = sc_ldu_border(&f, M, j, &scale);
                assert_true(piv > 0);   /* P or SPD: positive pivots */
                sc_ldu_commit(&f);
            } else {
                int k = 0;
                while (f.idx[k] != j)
                    k++;
                assert_int_equal(sc_ldu_remove(&f, k), SC_OK);
            }
            in[j] = !in[j];
            int m = f.m;
            for (int a = 0; a < m; a++)
                for (int b = 0; b < m; b++) {
                    double s = 0;
                    for (int p = 0; p <= (a < b ? a : b); p++) {
                        double L = p == a ? 1 : f.l[a * n + p], U = p == b ? 1 : f.ut[b * n + p];
                        s += L * f.d[p] * U;
                    }
                    worst = fmax(worst, fabs(s - M[f.idx[a] * n + f.idx[b]]));
                }
        }
        /* entries are O(1..n): a few hundred updates leave ~1e-13 */
        assert_true(worst < 1e-11);
        free(mem);
        free(M);
    }
}

/* ---- boxed LCP ---------------------------------------------------------------------------- */

/* Finite bounds: the boxed LCP is the standard LCP of size 2n in (z - lo,
 * w^-) with matrix [M I; -I 0] and q' = (M lo + q, hi - lo), solved here by
 * Lemke (the matrix is PSD for PSD M, so Lemke processes it). */
static void test_boxed_matches_lemke_on_the_doubled_problem(void **state)
{
    (void)state;
    rng r = { 0x5eed0008u };
    for (int rep = 0; rep < 30; rep++) {
        int n = 2 + rep % 9, nn = 2 * n;
        double *M = mat(n), *q = vec(n), *lo = vec(n), *hi = vec(n), *z = vec(n), *w = vec(n);
        double *B = mat(nn), *qb = vec(nn), *zb = vec(nn);
        make_spd(&r, n, 0.1, M);
        for (int i = 0; i < n; i++) {
            q[i] = 3 * srnd(&r);
            lo[i] = urand(&r) < 0.7 ? -urand(&r) : 0.2 * srnd(&r);
            hi[i] = lo[i] + (urand(&r) < 0.2 ? 0 : 0.05 + urand(&r));
        }
        sc_lcp_info info;
        assert_int_equal(sc_lcp_boxed(n, M, q, lo, hi, NULL, NULL, z, w, &info), SC_OK);
        assert_true(answer_ok(n, M, q, lo, hi, z, w, NULL));
        for (int i = 0; i < n; i++) {
            double a = q[i];
            for (int j = 0; j < n; j++) {
                B[i * nn + j] = M[i * n + j];
                a += M[i * n + j] * lo[j];
            }
            B[i * nn + n + i] = 1;
            B[(n + i) * nn + i] = -1;
            qb[i] = a;
            qb[n + i] = hi[i] - lo[i];
        }
        long piv;
        assert_true(lemke(nn, B, qb, zb, 1000, &piv));
        for (int i = 0; i < n; i++)
            zb[i] += lo[i];
        /* strictly convex QP: z is unique */
        assert_same_z(n, z, zb, 1e-9);
        free(M);
        free(q);
        free(lo);
        free(hi);
        free(z);
        free(w);
        free(B);
        free(qb);
        free(zb);
    }
}

/* Infinite bounds (equality rows, one-sided rows) and boxes that exclude
 * 0 (lo > 0, hi < 0), against projected Gauss-Seidel on a diagonally
 * dominant SPD matrix. */
static void test_boxed_with_infinite_and_shifted_bounds_matches_pgs(void **state)
{
    (void)state;
    rng r = { 0x5eed0009u };
    for (int rep = 0; rep < 20; rep++) {
        int n = 3 + rep % 12;
        double *M = mat(n), *q = vec(n), *lo = vec(n), *hi = vec(n), *z = vec(n), *w = vec(n);
        double *zp = vec(n);
        for (int i = 0; i < n; i++)
            for (int j = 0; j <= i; j++)
                M[i * n + j] = M[j * n + i] = 0.3 * srnd(&r) / n;
        for (int i = 0; i < n; i++)
            M[i * n + i] = 1 + urand(&r);
        for (int i = 0; i < n; i++) {
            q[i] = 2 * srnd(&r);
            switch (i % 5) {
            case 0: lo[i] = -INFINITY; hi[i] = INFINITY; break;   /* equality */
            case 1: lo[i] = 0; hi[i] = INFINITY; break;           /* contact */
            case 2: lo[i] = -INFINITY; hi[i] = 0.2; break;
            case 3: lo[i] = 0.3; hi[i] = 0.8; break;              /* excludes 0 */
            default: lo[i] = -0.7; hi[i] = -0.1; break;
            }
        }
        sc_lcp_info info;
        assert_int_equal(sc_lcp_boxed(n, M, q, lo, hi, NULL, NULL, z, w, &info), SC_OK);
        assert_true(answer_ok(n, M, q, lo, hi, z, w, NULL));
        pgs(n, M, q, lo, hi, zp);
        assert_same_z(n, z, zp, 1e-10);
        free(M);
        free(q);
        free(lo);
        free(hi);
        free(z);
        free(w);
        free(zp);
    }
}

/* A singular equality block (two identical equality rows) with consistent
 * data: a solution exists and must be found; with inconsistent data, an
 * error. */
static void test_boxed_redundant_equalities(void **state)
{
    (void)state;
    double M[9] = { 1, 1, 0, 1, 1, 0, 0, 0, 2 }, q[3] = { -1, -1, 1 };
    double lo[3] = { -INFINITY, -INFINITY, 0 }, hi[3] = { INFINITY, INFINITY, INFINITY };
    double z[3], w[3];
    assert_int_equal(sc_lcp_boxed(3, M, q, lo, hi, NULL, NULL, z, w, NULL), SC_OK);
    assert_true(answer_ok(3, M, q, lo, hi, z, w, NULL));
    assert_true(fabs(z[0] + z[1] - 1) < 1e-14);
    q[1] = -2;
    int rc = sc_lcp_boxed(3, M, q, lo, hi, NULL, NULL, z, w, NULL);
    assert_true(rc == SC_ENOSOLUTION || rc == SC_ENUMERIC);
}

/* Friction: a flat box on the floor, 4 contacts, each a normal row and two
 * tangent rows (x, y) bounded by +-mu p_n (findex). Sliding at v0 for one
 * step of dt: if v0 <= mu g dt it sticks (u' = 0), else it keeps sliding at
 * v0 - mu g dt with total friction mu m g dt. */
static void box_with_friction(int NP, double v0, double mu_value, double *vx_after,
                              double *friction)
{
    enum { NMAX = 3 * 8 };
    int N = 3 * NP;
    body b = box_body(3.0, 0.5, 0.4, 0.05, 0.0, 0, 0, 0.05);
    double J[NMAX * 6] = { 0 }, pts[8][3];
    double dirs[3][3] = { { 0, 0, 1 }, { 1, 0, 0 }, { 0, 1, 0 } };
    csys s = { 1, 0, N, &b, J };
    face_points(0, 0, 0, 0.5, 0.4, 0.0, NP, pts);
    int findex[NMAX];
    double mu[NMAX], lo[NMAX], hi[NMAX];
    for (int d = 0; d < 3; d++)
        for (int k = 0; k < NP; k++) {
            int row = s.rows;
            add_row(&s, -1, 0, pts[k], dirs[d]);
            findex[row] = d == 0 ? -1 : k;
            mu[row] = mu_value;
            lo[row] = d == 0 ? 0 : -INFINITY;   /* ignored for friction rows */
            hi[row] = INFINITY;
        }
    double u[6] = { v0, 0, -G * DT, 0, 0, 0 }, A[NMAX * NMAX], q[NMAX], z[NMAX], w[NMAX];
    double after[6], blo[NMAX], bhi[NMAX];
    build_lcp(&s, u, A, q);
    sc_lcp_info info;
    assert_int_equal(sc_lcp_boxed(N, A, q, lo, hi, findex, mu, z, w, &info), SC_OK);
    friction_bounds(N, lo, hi, findex, mu, z, blo, bhi);
    assert_true(answer_ok(N, A, q, blo, bhi, z, w, NULL));
    velocities_after(&s, u, z, after);
    double pn = 0, px = 0;
    for (int k = 0; k < NP; k++) {
        pn += z[k];
        px += z[NP + k];
    }
    assert_true(fabs(pn - b.m * G * DT) <= 1e-12 * b.m * G * DT);
    for (int c = 1; c < 6; c++)
        assert_true(fabs(after[c]) <= 1e-12);
    *vx_after = after[0];
    *friction = px;
}

static void test_friction_sticks_below_and_slides_above_the_coulomb_limit(void **state)
{
    (void)state;
    double mu = 0.5, m = 3.0, limit = mu * G * DT, vx, fx;
    /* 4 contacts, then 8 (redundant: normals and tangents both rank 3) */
    for (int np = 4; np <= 8; np += 4) {
        /* sticks: friction impulse -m v0 stops it */
        box_with_friction(np, 0.5 * limit, mu, &vx, &fx);
        assert_true(fabs(vx) <= 1e-12);
        assert_true(fabs(fx + m * 0.5 * limit) <= 1e-12 * m * limit);
        /* slides: friction at the cone, mu m g dt */
        box_with_friction(np, 3.0 * limit, mu, &vx, &fx);
        assert_true(fabs(vx - 2.0 * limit) <= 1e-12);
        assert_true(fabs(fx + mu * m * G * DT) <= 1e-12 * m * limit);
        /* mu = 0: no friction at all */
        box_with_friction(np, 3.0 * limit, 0.0, &vx, &fx);
        assert_true(fabs(vx - 3.0 * limit) <= 1e-12 && fx == 0.0);
    }
}

/* A separating contact carries no normal impulse, hence no friction. */
static void test_friction_of_a_separating_contact_is_zero(void **state)
{
    (void)state;
    double M[9] = { 2, 0.5, 0, 0.5, 2, 0, 0, 0, 2 }, q[3] = { 1.0, -3.0, 0.5 };
    double lo[3] = { 0, 0, 0 }, hi[3] = { INFINITY, 0, 0 }, mu[3] = { 0, 0.8, 0.8 };
    int findex[3] = { -1, 0, 0 };
    double z[3], w[3];
    assert_int_equal(sc_lcp_boxed(3, M, q, lo, hi, findex, mu, z, w, NULL), SC_OK);
    assert_true(z[0] == 0 && z[1] == 0 && z[2] == 0);
}

/* A captured pile LCP (tests/data/friction/): n, M, q, lo, hi, findex,
 * mu (the caller frees them). */
typedef struct pile_lcp {
    int n;
    double *M, *q, *mu, *lo, *hi;
    int *fx;
} pile_lcp;

static void load_pile_file(const char *path, pile_lcp *p)
{
    FILE *fp = fopen(path, "r");
    assert_non_null(fp);
    int n, nc, rc0;
    assert_int_equal(fscanf(fp, "%d %d %d", &n, &nc, &rc0), 3);
    assert_true(n > 0 && n <= 64);
    p->n = n;
    p->M = malloc((size_t)n * n * sizeof *p->M);
    p->q = malloc(n * sizeof *p->q);
    p->mu = malloc(n * sizeof *p->mu);
    p->lo = malloc(n * sizeof *p->lo);
    p->hi = malloc(n * sizeof *p->hi);
    p->fx = malloc(n * sizeof *p->fx);
    for (int i = 0; i < n * n; i++)
        assert_int_equal(fscanf(fp, "%lf", &p->M[i]), 1);
    for (int i = 0; i < n; i++) {
        assert_int_equal(fscanf(fp, "%lf %d %lf %lf", &p->q[i], &p->fx[i], &p->mu[i], &p->lo[i]),
                         4);
        p->hi[i] = INFINITY;
        if (p->fx[i] >= 0)
            p->lo[i] = -INFINITY;
    }
    fclose(fp);
}

static void free_pile(pile_lcp *p)
{
    free(p->M), free(p->q), free(p->mu), free(p->lo), free(p->hi), free(p->fx);
}

/* z against Coulomb's conditions for p with matrix M, within 1e-9 of the
 * largest |z| and |q|, and velocities within slack besides. */
static void check_coulomb(const pile_lcp *p, const double *M, const double *z, double slack)
{
    int n = p->n;
    double zs = 0, ws = 0;
    for (int i = 0; i < n; i++) {
        zs = fmax(zs, fabs(z[i]));
        ws = fmax(ws, fabs(p->q[i]));
    }
    for (int i = 0; i < n; i++) {
        double wi = p->q[i];
        for (int j = 0; j < n; j++)
            wi += M[i * n + j] * z[j];
        double tz = 1e-9 * zs, tw = 1e-9 * ws + slack;
        if (p->fx[i] < 0) {       /* normal: z >= 0, w >= 0, z w = 0 */
            assert_true(z[i] >= -tz && wi >= -tw);
            assert_true(fmin(z[i], wi) <= fmax(tz, tw));
        } else {                  /* friction: inside the box with w = 0,
                                     or at a bound with w opposing */
            double b = p->mu[i] * z[p->fx[i]];
            assert_true(fabs(z[i]) <= b + tz);
            if (fabs(z[i]) < b - tz)
                assert_true(fabs(wi) <= tw);
            else
                assert_true(z[i] * wi <= tw * zs);
        }
    }
}

/* Solves a captured pile LCP with sc_lcp_boxed and checks the answer
 * against Coulomb's conditions here; its info in *li. */
static void solve_pile_file(const char *path, sc_lcp_info *li)
{
    pile_lcp p;
    load_pile_file(path, &p);
    double *z = calloc(p.n, sizeof *z), *w = malloc(p.n * sizeof *w);
    assert_int_equal(sc_lcp_boxed(p.n, p.M, p.q, p.lo, p.hi, p.fx, p.mu, z, w, li), SC_OK);
    check_coulomb(&p, p.M, z, 0);
    free(z), free(w);
    free_pile(&p);
}

/* Real pile islands on which the fixed point on the friction bounds
 * cycles. */
static const char *const cycling[] = { "tests/data/friction/pile_4contacts.txt",
                                       "tests/data/friction/pile_4contacts_b.txt",
                                       "tests/data/friction/pile_8contacts.txt" };

/* Those (tests/data/friction/): solved exactly (by Lemke's method on the
 * friction LCP), checked here against Coulomb's conditions. */
static void test_pile_friction_that_cycles_is_solved_exactly(void **state)
{
    (void)state;
    for (size_t f = 0; f < sizeof cycling / sizeof *cycling; f++) {
        sc_lcp_info li;
        solve_pile_file(cycling[f], &li);
        assert_int_equal(li.lemke, 1);     /* the fixed point did cycle */
        assert_int_equal(li.guessed, 0);
    }
}

/* The fixed point's rounds alone (sc_lcp_boxed_rounds_in(), for a
 * caller that keeps an answer of its own), damped: on two of the piles
 * where the plain rounds cycle they settle, on answers that meet
 * Coulomb's conditions; on the third, a failure without Lemke's method
 * or a guess; started from the full solve's answer, all three settle. */
static void test_friction_rounds_alone_damped_settle_some_cycles(void **state)
{
    (void)state;
    static const int settles[] = { 1, 0, 1 };
    _Static_assert(sizeof settles / sizeof *settles == sizeof cycling / sizeof *cycling,
                   "one outcome per pile");
    for (size_t f = 0; f < sizeof cycling / sizeof *cycling; f++) {
        pile_lcp p;
        load_pile_file(cycling[f], &p);
        double *z = calloc(p.n, sizeof *z), *w = malloc(p.n * sizeof *w);
        double *z2 = malloc(p.n * sizeof *z2), *w2 = malloc(p.n * sizeof *w2);
        sc_lcp_info li;
        int rc = sc_lcp_boxed_rounds_in(NULL, p.n, p.M, p.q, p.lo, p.hi, p.fx, p.mu, z, w, &li);
        assert_int_equal(rc == SC_OK, settles[f]);
        if (rc == SC_OK)
            check_coulomb(&p, p.M, z, 0);
        assert_int_equal(li.lemke, 0);
        assert_int_equal(li.guessed, 0);
        memset(z, 0, p.n * sizeof *z);
        assert_int_equal(sc_lcp_boxed(p.n, p.M, p.q, p.lo, p.hi, p.fx, p.mu, z, w, &li), SC_OK);
        memcpy(z2, z, p.n * sizeof *z2);
        assert_int_equal(sc_lcp_boxed_rounds_in(NULL, p.n, p.M, p.q, p.lo, p.hi, p.fx, p.mu, z2,
                                                w2, &li),
                         SC_OK);
        check_coulomb(&p, p.M, z2, 0);
        free(z), free(w), free(z2), free(w2);
        free_pile(&p);
    }
}

/* Pile LCPs on which the fixed point cycles and Lemke's path from the
 * covering vector e fails (a secondary ray, or an answer that fails
 * verification): solved exactly on the path of another covering vector,
 * before any guess. */
static void test_pile_friction_that_lemke_misses_is_solved_on_another_cover(void **state)
{
    (void)state;
    const char *files[] = { "tests/data/friction/pile_4contacts_cover.txt",
                            "tests/data/friction/pile_8contacts_cover.txt" };
    for (size_t f = 0; f < sizeof files / sizeof *files; f++) {
        sc_lcp_info li;
        solve_pile_file(files[f], &li);
        assert_int_equal(li.lemke, 1);
        assert_true(li.covers >= 1);
        assert_int_equal(li.guessed, 0);
    }
}

/* Pile LCPs on which the fixed point fails and so do Lemke's paths from
 * every covering vector tried (six): solved exactly by the fixed point
 * started from projected Gauss-Seidel's iterate. */
static void test_pile_friction_that_lemke_misses_is_solved_from_a_guess(void **state)
{
    (void)state;
    const char *files[] = { "tests/data/friction/pile_5contacts_guess.txt",
                            "tests/data/friction/pile_7contacts_guess.txt" };
    for (size_t f = 0; f < sizeof files / sizeof *files; f++) {
        sc_lcp_info li;
        solve_pile_file(files[f], &li);
        assert_int_equal(li.lemke, 1);
        assert_int_equal(li.covers, 5);
        assert_int_equal(li.guessed, 1);
    }
}

/* Pile LCPs of near-redundant contacts (eigenvalues 6e-5 to 131) on which
 * the fixed point, Lemke's method and the guess all fail: solved by
 * sc_lcp_raised_in() with the diagonal raised by at most 1e-6 of its
 * largest entry, exactly for the raised matrix, and within that share
 * times |z| for the captured one. */
static void test_pile_friction_that_fails_is_solved_with_a_raised_diagonal(void **state)
{
    (void)state;
    const char *files[] = { "tests/data/friction/pile_5contacts_raised.txt",
                            "tests/data/friction/pile_16contacts_raised.txt" };
    for (size_t f = 0; f < sizeof files / sizeof *files; f++) {
        pile_lcp p;
        load_pile_file(files[f], &p);
        int n = p.n;
        double *A = malloc((size_t)n * n * sizeof *A), *z = calloc(n, sizeof *z);
        double *w = malloc(n * sizeof *w);
        memcpy(A, p.M, (size_t)n * n * sizeof *A);
        sc_lcp_info li;
        assert_int_not_equal(sc_lcp_boxed(n, A, p.q, p.lo, p.hi, p.fx, p.mu, z, w, &li), SC_OK);
        assert_int_equal(li.lemke, 1);
        double share = -1, dmax = 0, zs = 0;
        assert_int_equal(sc_lcp_raised_in(NULL, n, A, p.q, p.lo, p.hi, p.fx, p.mu, z, w, &li,
                                          &share),
                         SC_OK);
        assert_true(share > 0 && share <= 1e-6);
        for (int i = 0; i < n; i++) {
            dmax = fmax(dmax, p.M[i * n + i]);
            zs = fmax(zs, fabs(z[i]));
        }
        for (int i = 0; i < n; i++) {
            /* the diagonal raised by that share, nothing else changed */
            for (int j = 0; j < n; j++)
                assert_true(i == j ? fabs(A[i * n + i] - p.M[i * n + i] - share * dmax) <=
                                         1e-9 * share * dmax + 4 * DBL_EPSILON * A[i * n + i]
                                   : A[i * n + j] == p.M[i * n + j]);
        }
        check_coulomb(&p, A, z, 0);
        check_coulomb(&p, p.M, z, 1.01 * share * dmax * zs);
        free(A), free(z), free(w);
        free_pile(&p);
    }
}

/* A warm start from the answer takes no more pivots than a cold start
 * and gives the same answer; a wrong guess still gives the right one. */
static void test_warm_start_reuses_the_answer(void **state)
{
    (void)state;
    enum { N = 30 };
    double M[N * N], q[N], z[N], zc[N], w[N];
    rng r = { 0x5eed000bu };
    make_spd(&r, N, 0.1, M);
    for (int i = 0; i < N; i++)
        q[i] = srnd(&r);
    sc_lcp_info cold, warm, wrong;
    assert_int_equal(sc_lcp_dantzig_in(NULL, N, M, q, zc, w, &cold), SC_OK);
    memcpy(z, zc, sizeof z);
    assert_int_equal(sc_lcp_dantzig_warm_in(NULL, N, M, q, z, w, &warm), SC_OK);
    assert_true(warm.pivots < cold.pivots);
    for (int i = 0; i < N; i++)
        assert_true(fabs(z[i] - zc[i]) <= 1e-9 * (1 + fabs(zc[i])));
    for (int i = 0; i < N; i++)
        z[i] = (i % 3) ? 1.0 : 0.0;      /* a poor guess */
    assert_int_equal(sc_lcp_dantzig_warm_in(NULL, N, M, q, z, w, &wrong), SC_OK);
    for (int i = 0; i < N; i++)
        assert_true(fabs(z[i] - zc[i]) <= 1e-9 * (1 + fabs(zc[i])));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random_p_matrices_satisfy_complementarity),
        cmocka_unit_test(test_low_rank_psd_matrices_give_the_unique_w),
        cmocka_unit_test(test_large_singular_psd_problems_are_solved),
        cmocka_unit_test(test_nonsymmetric_psd_problems_are_solved),
        cmocka_unit_test(test_box_on_floor_with_four_contacts_comes_to_rest),
        cmocka_unit_test(test_box_on_floor_with_eight_redundant_contacts_comes_to_rest),
        cmocka_unit_test(test_stack_of_boxes_with_redundant_contacts_carries_the_weight),
        cmocka_unit_test(test_landing_box_impulses_respect_momentum),
        cmocka_unit_test(test_every_siconos_problem_is_solved_or_refused),
        cmocka_unit_test(test_murty_example_is_solved_or_hits_the_pivot_limit),
        cmocka_unit_test(test_q_nonnegative_gives_zero_without_pivots),
        cmocka_unit_test(test_degenerate_q_with_zeros_is_solved),
        cmocka_unit_test(test_infeasible_problems_return_an_error),
        cmocka_unit_test(test_bad_arguments_are_rejected),
        cmocka_unit_test(test_solutions_are_bit_identical_across_runs),
        cmocka_unit_test(test_factor_updates_reproduce_the_clamped_block),
        cmocka_unit_test(test_boxed_matches_lemke_on_the_doubled_problem),
        cmocka_unit_test(test_boxed_with_infinite_and_shifted_bounds_matches_pgs),
        cmocka_unit_test(test_boxed_redundant_equalities),
        cmocka_unit_test(test_friction_sticks_below_and_slides_above_the_coulomb_limit),
        cmocka_unit_test(test_friction_of_a_separating_contact_is_zero),
        cmocka_unit_test(test_pile_friction_that_cycles_is_solved_exactly),
        cmocka_unit_test(test_friction_rounds_alone_damped_settle_some_cycles),
        cmocka_unit_test(test_pile_friction_that_lemke_misses_is_solved_on_another_cover),
        cmocka_unit_test(test_pile_friction_that_lemke_misses_is_solved_from_a_guess),
        cmocka_unit_test(test_pile_friction_that_fails_is_solved_with_a_raised_diagonal),
        cmocka_unit_test(test_warm_start_reuses_the_answer),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
