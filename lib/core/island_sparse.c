/* island_sparse.c - a big island's whole contact LCP, exact, by an active
 * set: which rows sit at a bound decided by full Newton steps (block
 * principal pivoting) on the convex problem the LCP is the optimality
 * condition of, each step's linear system solved by a sparse Cholesky
 * factor (CHOLMOD), until a step keeps every row's place; the answer is
 * then verified as Dantzig's are (docs/DESIGN.md 11).
 *
 * The system is solved in the bodies' velocities, not in the rows'
 * impulses: with the compliance c of the exact solves (COMPLIANCE), a free
 * row's impulse is z = -(J u + d) / c, and the velocities u of the movable
 * bodies solve (M + sum_free J^T J / c) u = M u* + sum_held J^T z - sum_free
 * J^T d / c, six unknowns a body whatever its contacts (a body in a pile
 * has tens of rows; the rows' own matrix would be many times larger). The
 * same answer as (A + c I) z = -q on the free rows, A = J M^-1 J^T. */
#include <cholmod.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_rows.h"
#include "vecmath.h"

/* A row's place: free (w = 0 between its bounds) or held at a bound. */
enum { AS_FREE, AS_LO, AS_HI };

/* The answer must meet Dantzig's verification (lcp.c): every violation at
 * most AS_VERIFY (n+1) eps S_i, S_i the magnitude of the terms of w_i. */
#define AS_VERIFY 1000.0
/* ... or AS_FLOOR m/s, the rounding the velocities' system leaves where
 * the scale is near 0 (a push-out of a few micrometres): the exact
 * solves' own residuals reach 1e-13 to 1e-12 m/s on piles. */
#define AS_FLOOR 1e-12
/* Factorisations (sets of places) at most: Newton's method on a convex
 * piecewise quadratic takes a few (a stack or a pyramid 1 to 5); a pile of
 * bolts whose friction does not settle within these goes to block
 * Gauss-Seidel instead (contact.c), before it costs many factors. */
#define AS_MAX_ITER 12
#define AS_STALL 2
/* Rounds of friction bounds taken from the last normal impulses at most;
 * refinement steps of each solve. */
#define AS_BOUND_ROUNDS 12
#define AS_REFINE 2

#define AS_MASS 19

typedef struct as_ctx {
    const gs_problem *pb;
    int n;                    /* rows */
    int nslots;               /* velocity slots (u has 6 each) */
    int *var;                 /* slot -> first unknown (6 each), -1: not movable */
    int nvar;
    double *mass;             /* per slot: m, the world inertia 3 x 3 and its
                                 inverse (AS_MASS doubles) */
    double comp;              /* c */
    int round;                /* of the friction fixed point (bounds_fixed()) */
    double *d;                /* per row: off plus J u of its immovable side */
    double *mu_star;          /* M u* per unknown (u*: u without the impulses) */
    double *ustar;            /* |u*| per unknown */
    double *duabs;            /* sum over rows of |M^-1 J_r^T z_r| per unknown */
    /* the pattern of K: upper triangle, compressed columns of 6 x 6 blocks */
    int *kp, *ki;
    int *roff;                /* row -> offset of its (a, b) block's column 0 entry, -1 */
    cholmod_common cm;
    cholmod_sparse *K;
    cholmod_factor *L;
    cholmod_dense *B;
} as_ctx;

/* Row r's Jacobian on its movable slot side t (0: a, 1: b), or NULL. */
static const double *jac(const row *rw, int t)
{
    return t == 0 ? (rw->ma ? rw->ja : NULL) : (rw->mb ? rw->jb : NULL);
}

/* Bounds of row r given z (friction: +-mu z_normal). */
static void bounds(const as_ctx *s, const double *z, int r, double *lo, double *hi)
{
    row_bounds(s->pb, z, r, lo, hi);
}

/* Row r's bounds in a round of the friction fixed point, from the normal
 * impulses zb: in the first round, friction of a contact whose normal has
 * no impulse yet sticks (unbounded) rather than sliding freely (bounds 0):
 * a resting structure solved cold then finds its normal loads with its
 * friction holding, as it does, and later rounds bound it by them. */
static void bounds_fixed(const as_ctx *s, const double *zb, int r, double *lo, double *hi)
{
    row_bounds(s->pb, zb, r, lo, hi);
    const int *fx = s->pb->findex;
    if (s->round == 0 && fx && fx[r] >= 0 && !(zb[fx[r]] > 0)) {
        *lo = -INFINITY;
        *hi = INFINITY;
    }
}

static int cmp_int(const void *x, const void *y)
{
    int a = *(const int *)x, b = *(const int *)y;
    return (a > b) - (a < b);
}

/* The unknowns, masses and the block pattern of K: slot t's block column
 * holds the slots s < t that share a row with it (ascending), then its
 * own diagonal block's upper triangle. Arrays from malloc (CHOLMOD's own
 * are, and they outlive any arena order). */
static int as_pattern(as_ctx *s, const sc_body *bodies, const int *slot_body)
{
    const row *rows = s->pb->rows;
    int n = s->n, ns = s->nslots;
    s->var = malloc((size_t)ns * sizeof *s->var);
    s->mass = malloc((size_t)ns * AS_MASS * sizeof *s->mass);
    s->roff = malloc((size_t)(n > 0 ? n : 1) * sizeof *s->roff);
    int *cnt = calloc((size_t)ns + 1, sizeof *cnt);
    int *adj = malloc((size_t)(n > 0 ? n : 1) * sizeof *adj);
    int *pos = malloc((size_t)(ns > n ? ns : n) * sizeof *pos + sizeof *pos);
    int rc = SC_ENOMEM;
    if (!s->var || !s->mass || !s->roff || !cnt || !adj || !pos)
        goto out;
    int nv = 0;
    for (int t = 0; t < ns; t++) {
        const sc_body *b = &bodies[slot_body[t]];
        s->var[t] = movable(b) ? 6 * nv++ : -1;
        if (movable(b)) {
            double *m = &s->mass[AS_MASS * t];
            m[0] = 1 / b->inv_mass;
            memcpy(m + 10, b->iw, 9 * sizeof *m);
            if (!m3_inverse(m + 1, b->iw)) {
                rc = SC_ENUMERIC;
                goto out;
            }
        }
    }
    s->nvar = 6 * nv;
    /* the pairs (lo, hi) of movable slots sharing a row, grouped by hi,
     * each once: counted, listed, sorted, deduplicated */
    for (int r = 0; r < n; r++) {
        s->roff[r] = -1;
        if (rows[r].ma && rows[r].mb && rows[r].la != rows[r].lb)
            cnt[(rows[r].la > rows[r].lb ? rows[r].la : rows[r].lb) + 1]++;
    }
    for (int t = 0; t < ns; t++)
        cnt[t + 1] += cnt[t];
    memcpy(pos, cnt, (size_t)ns * sizeof *pos);
    for (int r = 0; r < n; r++)
        if (rows[r].ma && rows[r].mb && rows[r].la != rows[r].lb) {
            int hi = rows[r].la > rows[r].lb ? rows[r].la : rows[r].lb;
            int lo = rows[r].la + rows[r].lb - hi;
            adj[pos[hi]++] = lo;
        }
    int *nb = pos;            /* per slot: distinct lower neighbours */
    for (int t = 0; t < ns; t++) {
        int a = cnt[t], b = cnt[t + 1], u = a;
        qsort(&adj[a], (size_t)(b - a), sizeof *adj, cmp_int);
        for (int k = a; k < b; k++)
            if (k == a || adj[k] != adj[k - 1])
                adj[u++] = adj[k];
        nb[t] = u - a;
    }
    /* columns: slot t's 6 columns, column k: 6 per lower neighbour, then
     * k + 1 of its diagonal block */
    size_t nnz = 0;
    for (int t = 0; t < ns; t++)
        if (s->var[t] >= 0)
            nnz += 36 * (size_t)nb[t] + 21;
    if (nnz > (size_t)1 << 30) {
        rc = SC_ETOOMANY;
        goto out;
    }
    s->kp = malloc((size_t)(s->nvar + 1) * sizeof *s->kp);
    s->ki = malloc((nnz > 0 ? nnz : 1) * sizeof *s->ki);
    if (!s->kp || !s->ki)
        goto out;
    int p = 0;
    for (int t = 0; t < ns; t++) {
        if (s->var[t] < 0)
            continue;
        int c0 = s->var[t];
        for (int k = 0; k < 6; k++) {
            s->kp[c0 + k] = p;
            for (int j = 0; j < nb[t]; j++) {
                int v = s->var[adj[cnt[t] + j]];
                for (int i = 0; i < 6; i++)
                    s->ki[p++] = v + i;
            }
            for (int i = 0; i <= k; i++)
                s->ki[p++] = c0 + i;
        }
    }
    s->kp[s->nvar] = p;
    /* each coupling row's block: the position of lo in hi's list */
    for (int r = 0; r < n; r++)
        if (rows[r].ma && rows[r].mb && rows[r].la != rows[r].lb) {
            int hi = rows[r].la > rows[r].lb ? rows[r].la : rows[r].lb;
            int lo = rows[r].la + rows[r].lb - hi;
            int *f = bsearch(&lo, &adj[cnt[hi]], (size_t)nb[hi], sizeof *adj, cmp_int);
            s->roff[r] = (int)(f - &adj[cnt[hi]]) * 6;
        }
    rc = SC_OK;
out:
    free(pos);
    free(adj);
    free(cnt);
    return rc;
}

/* Entry (row i of slot lo's block, column k of slot hi's block) of K for
 * a coupling block at list offset off (roff), or the diagonal block. */
static double *k_off(const as_ctx *s, double *kx, int hi, int off, int i, int k)
{
    return &kx[s->kp[s->var[hi] + k] + off + i];
}

static double *k_diag(const as_ctx *s, double *kx, int t, int i, int k)
{
    /* column k of the diagonal block starts k(k+1)/2 + 6 k nb entries
     * after column 0's; the diagonal part is the column's tail */
    int col = s->var[t] + k;
    return &kx[s->kp[col + 1] - (k + 1) + i];
}

/* K's values for the free rows of ef: M, plus J_r^T J_r / c of each. */
static void as_matrix(as_ctx *s, const unsigned char *ef)
{
    double *kx = s->K->x;
    memset(kx, 0, (size_t)s->kp[s->nvar] * sizeof *kx);
    for (int t = 0; t < s->nslots; t++) {
        if (s->var[t] < 0)
            continue;
        const double *m = &s->mass[AS_MASS * t];
        for (int k = 0; k < 3; k++)
            *k_diag(s, kx, t, k, k) = m[0];
        for (int k = 0; k < 3; k++)
            for (int i = 0; i <= k; i++)
                *k_diag(s, kx, t, 3 + i, 3 + k) = m[1 + 3 * i + k];
    }
    double ic = 1 / s->comp;
    for (int r = 0; r < s->n; r++) {
        if (ef[r] != AS_FREE)
            continue;
        const row *rw = &s->pb->rows[r];
        for (int t = 0; t < 2; t++) {
            const double *j = jac(rw, t);
            if (!j)
                continue;
            int sl = t ? rw->lb : rw->la;
            for (int k = 0; k < 6; k++)
                for (int i = 0; i <= k; i++)
                    *k_diag(s, kx, sl, i, k) += j[i] * j[k] * ic;
        }
        if (s->roff[r] >= 0) {
            int hi = rw->la > rw->lb ? rw->la : rw->lb;
            const double *jl = hi == rw->la ? rw->jb : rw->ja, *jh = hi == rw->la ? rw->ja : rw->jb;
            for (int k = 0; k < 6; k++)
                for (int i = 0; i < 6; i++)
                    *k_off(s, kx, hi, s->roff[r], i, k) += jl[i] * jh[k] * ic;
        }
    }
}

/* y = K x from the upper triangle. */
static void k_mul(const as_ctx *s, const double *x, double *y)
{
    const double *kx = s->K->x;
    memset(y, 0, (size_t)s->nvar * sizeof *y);
    for (int j = 0; j < s->nvar; j++)
        for (int p = s->kp[j]; p < s->kp[j + 1]; p++) {
            int i = s->ki[p];
            y[i] += kx[p] * x[j];
            if (i != j)
                y[j] += kx[p] * x[i];
        }
}

/* J_r u over the movable sides (u per unknown). */
static double j_u(const as_ctx *s, const row *rw, const double *u)
{
    double v = 0;
    if (rw->ma)
        v += dot6(rw->ja, &u[s->var[rw->la]]);
    if (rw->mb)
        v += dot6(rw->jb, &u[s->var[rw->lb]]);
    return v;
}

/* b += J_r^T z over the movable sides. */
static void jt_add(const as_ctx *s, const row *rw, double z, double *b)
{
    if (rw->ma)
        for (int k = 0; k < 6; k++)
            b[s->var[rw->la] + k] += rw->ja[k] * z;
    if (rw->mb)
        for (int k = 0; k < 6; k++)
            b[s->var[rw->lb] + k] += rw->jb[k] * z;
}

/* The value a held row is held at, from z's normal impulses. */
static double held_value(const as_ctx *s, const double *z, const unsigned char *ef, int r)
{
    double lo, hi;
    bounds_fixed(s, z, r, &lo, &hi);
    return ef[r] == AS_HI ? hi : lo;
}

/* The right-hand side for the places ef, held rows at their values from
 * the normal impulses in zb (written into z): M u* + sum_held J^T z -
 * sum_free J^T d / c. */
static void as_rhs(const as_ctx *s, const unsigned char *ef, const double *zb, double *z,
                   double *b)
{
    memcpy(b, s->mu_star, (size_t)s->nvar * sizeof *b);
    for (int r = 0; r < s->n; r++) {
        const row *rw = &s->pb->rows[r];
        if (ef[r] != AS_FREE) {
            z[r] = held_value(s, zb, ef, r);
            jt_add(s, rw, z[r], b);
        } else {
            jt_add(s, rw, -s->d[r] / s->comp, b);
        }
    }
}

/* u = K^-1 b with AS_REFINE steps of refinement. */
static int as_solve(as_ctx *s, const double *b, double *u, double *tmp)
{
    size_t nv = (size_t)s->nvar;
    double *bx = s->B->x;
    memcpy(bx, b, nv * sizeof *bx);
    for (int it = 0; it <= AS_REFINE; it++) {
        cholmod_dense *X = cholmod_solve(CHOLMOD_A, s->L, s->B, &s->cm);
        if (!X)
            return SC_ENUMERIC;
        const double *dx = X->x;
        for (size_t i = 0; i < nv; i++)
            u[i] = it ? u[i] + dx[i] : dx[i];
        cholmod_free_dense(&X, &s->cm);
        if (it == AS_REFINE)
            break;
        k_mul(s, u, tmp);
        for (size_t i = 0; i < nv; i++)
            bx[i] = b[i] - tmp[i];
    }
    return SC_OK;
}

/* Each row's scale S_i, what rounding in w_i is relative to (lcp.c's
 * |q_i| + sum_j |A_ij z_j|): |d_i| + c |z_i| + |J_i| (|u*| + sum_r
 * |M^-1 J_r^T z_r|), the velocities before they cancel. */
static void as_scale(as_ctx *s, const double *z, double *sc)
{
    memset(s->duabs, 0, (size_t)s->nvar * sizeof *s->duabs);
    for (int r = 0; r < s->n; r++) {
        const row *rw = &s->pb->rows[r];
        if (rw->ma)
            for (int k = 0; k < 6; k++)
                s->duabs[s->var[rw->la] + k] += fabs(rw->wa[k] * z[r]);
        if (rw->mb)
            for (int k = 0; k < 6; k++)
                s->duabs[s->var[rw->lb] + k] += fabs(rw->wb[k] * z[r]);
    }
    for (int r = 0; r < s->n; r++) {
        const row *rw = &s->pb->rows[r];
        double a = fabs(s->d[r]) + s->comp * fabs(z[r]);
        for (int t = 0; t < 2; t++) {
            const double *j = jac(rw, t);
            if (!j)
                continue;
            int v = s->var[t ? rw->lb : rw->la];
            for (int k = 0; k < 6; k++)
                a += fabs(j[k]) * (s->ustar[v + k] + s->duabs[v + k]);
        }
        sc[r] = a;
    }
}

/* Whether (z, w) meets the boxed conditions within AS_VERIFY (n+1) eps S_i
 * at every row, as lcp.c's check() verifies a Dantzig answer: z inside its
 * bounds, w > 0 only at lo, w < 0 only at hi (weighed by the distance to
 * the bound over max |z|). *worst: the largest violation, m/s. */
static int as_check(const as_ctx *s, const double *z, const double *w, const double *sc,
                    double *worst)
{
    double zs = DBL_MIN, eps_n = (s->n + 1) * DBL_EPSILON, wmax = 0;
    int ok = 1;
    for (int i = 0; i < s->n; i++)
        zs = max_d(zs, fabs(z[i]));
    for (int i = 0; i < s->n; i++) {
        double lo, hi;
        bounds(s, z, i, &lo, &hi);
        double tol = max_d(AS_VERIFY * eps_n * sc[i], AS_FLOOR);
        double wp = max_d(w[i], 0), wm = max_d(-w[i], 0), v = 0;
        if (!isfinite(z[i]) || !isfinite(w[i]) || z[i] < lo || z[i] > hi)
            v = INFINITY;
        if (wp > 0)
            v = max_d(v, isinf(lo) ? wp : min_d(wp, (z[i] - lo) * wp / zs));
        if (wm > 0)
            v = max_d(v, isinf(hi) ? wm : min_d(wm, (hi - z[i]) * wm / zs));
        if (!(v <= tol))
            ok = 0;
        wmax = max_d(wmax, v);
    }
    *worst = wmax;
    return ok;
}

/* Each row's impulse at velocities u with bounds from the normal
 * impulses zb, z = clamp(-(J u + d) / c, lo, hi), into z, and its place:
 * free inside its bounds or on one, else held at the one it passed
 * (friction whose bounds are 0 is held at 0). A row on its bound is free:
 * a resting contact whose bodies do not approach yet, as in a stack whose
 * lower contacts take the load first, then carries its share in the same
 * step instead of one level a step. */
static void as_places(const as_ctx *s, const double *zb, const double *u, double *z,
                      unsigned char *ef)
{
    for (int r = 0; r < s->n; r++) {
        double lo, hi;
        bounds_fixed(s, zb, r, &lo, &hi);
        double v = -(j_u(s, &s->pb->rows[r], u) + s->d[r]) / s->comp;
        ef[r] = lo == hi ? AS_LO : v < lo ? AS_LO : v > hi ? AS_HI : AS_FREE;
        z[r] = ef[r] == AS_LO ? lo : ef[r] == AS_HI ? hi : v;
    }
}

/* The first places, from the warm start z and its w = J u + d + c z
 * (where u holds it): a row inside its bounds is free, and so is one on a
 * bound whose w does not push it there (w = 0: a resting contact, or a
 * stack's contact above one that takes the load first); friction whose
 * bounds are 0 is held at 0. Not the places at u: there the velocities
 * before this frame's impulses settle (gravity's h g) over the tiny
 * compliance put every friction row at a bound. */
static void as_guess(const as_ctx *s, const double *zb, const double *z, const double *u,
                     unsigned char *ef)
{
    for (int r = 0; r < s->n; r++) {
        double lo, hi;
        bounds_fixed(s, zb, r, &lo, &hi);
        double w = j_u(s, &s->pb->rows[r], u) + s->d[r] + s->comp * z[r];
        ef[r] = lo == hi                 ? AS_LO
                : z[r] <= lo && w > 0 ? AS_LO
                : z[r] >= hi && w < 0 ? AS_HI
                                      : AS_FREE;
    }
}

/* The convex function Newton's method minimises, up to a constant: 1/2
 * u^T M u - u^T M u* + sum_r phi_r(J_r u + d_r), phi(y) = max over z in
 * the bounds of -z y - c z^2 / 2 (its gradient M (u - u*) - J^T z(u)). y
 * holds n doubles of scratch. */
static double as_objective(const as_ctx *s, const double *zb, const double *u, double *y)
{
    double f = 0;
    for (int t = 0; t < s->nslots; t++) {
        if (s->var[t] < 0)
            continue;
        const double *m = &s->mass[AS_MASS * t];
        const double *ut = &u[s->var[t]], *ms = &s->mu_star[s->var[t]];
        double mw[3];
        m3_mulv(mw, m + 1, ut + 3);
        for (int k = 0; k < 3; k++)
            f += 0.5 * (m[0] * ut[k] * ut[k] + ut[k + 3] * mw[k]) - ut[k] * ms[k] -
                 ut[k + 3] * ms[k + 3];
    }
    for (int r = 0; r < s->n; r++) {
        double lo, hi;
        bounds_fixed(s, zb, r, &lo, &hi);
        y[r] = j_u(s, &s->pb->rows[r], u) + s->d[r];
        double z = min_d(max_d(-y[r] / s->comp, lo), hi);
        f += -z * y[r] - 0.5 * s->comp * z * z;
    }
    return f;
}

/* u = u* + M^-1 J^T z (per unknown). */
static void as_velocities(const as_ctx *s, const double *z, double *u)
{
    memcpy(u, s->mu_star, (size_t)s->nvar * sizeof *u);
    for (int r = 0; r < s->n; r++)
        jt_add(s, &s->pb->rows[r], z[r], u);
    for (int t = 0; t < s->nslots; t++) {
        if (s->var[t] < 0)
            continue;
        double *ut = &u[s->var[t]], tmp6[6];
        const double *m = &s->mass[AS_MASS * t];
        for (int k = 0; k < 3; k++)
            tmp6[k] = ut[k] / m[0];
        m3_mulv(tmp6 + 3, m + 10, ut + 3);
        memcpy(ut, tmp6, sizeof tmp6);
    }
}

/* The movable velocities as unknowns (uv, from u), M u* = M u - J^T z, its
 * magnitudes |u*|, and each row's constant d: off and its immovable side's
 * J u. */
static void as_begin(as_ctx *s, const double *u, const double *z, double *uv)
{
    const gs_problem *pb = s->pb;
    for (int t = 0; t < s->nslots; t++) {
        if (s->var[t] < 0)
            continue;
        double *ut = uv + s->var[t], *ms = s->mu_star + s->var[t];
        memcpy(ut, &u[6 * t], 6 * sizeof *ut);
        const double *m = s->mass + AS_MASS * t;
        for (int k = 0; k < 3; k++)
            ms[k] = m[0] * ut[k];
        m3_mulv(ms + 3, m + 1, ut + 3);
    }
    for (int r = 0; r < s->n; r++) {
        const row *rw = &pb->rows[r];
        jt_add(s, rw, -z[r], s->mu_star);
        s->d[r] = pb->off[r] + (rw->ma ? 0 : dot6(rw->ja, &u[6 * rw->la])) +
                  (rw->mb ? 0 : dot6(rw->jb, &u[6 * rw->lb]));
    }
    for (int t = 0; t < s->nslots; t++) {
        if (s->var[t] < 0)
            continue;
        const double *m = s->mass + AS_MASS * t, *ms = s->mu_star + s->var[t];
        double *us = s->ustar + s->var[t];
        for (int k = 0; k < 3; k++)
            us[k] = fabs(ms[k] / m[0]);
        m3_mulv(us + 3, m + 10, ms + 3);
        for (int k = 3; k < 6; k++)
            us[k] = fabs(us[k]);
    }
}

static void as_free(as_ctx *s)
{
    if (s->B)
        cholmod_free_dense(&s->B, &s->cm);
    if (s->L)
        cholmod_free_factor(&s->L, &s->cm);
    if (s->K)
        cholmod_free_sparse(&s->K, &s->cm);
    cholmod_finish(&s->cm);
    free(s->duabs);
    free(s->ustar);
    free(s->mu_star);
    free(s->d);
    free(s->ki);
    free(s->kp);
    free(s->roff);
    free(s->mass);
    free(s->var);
}

/* CHOLMOD for one solve: no printing, a simplicial factor (no BLAS threads:
 * the same bits on any machine load), AMD ordering. */
static int as_start(as_ctx *s)
{
    cholmod_start(&s->cm);
    s->cm.print = 0;
    s->cm.supernodal = CHOLMOD_SIMPLICIAL;
    s->cm.final_ll = 0;
    s->cm.nmethods = 1;
    s->cm.method[0].ordering = CHOLMOD_AMD;
    s->cm.postorder = 1;
    size_t nv = (size_t)s->nvar, nnz = (size_t)s->kp[s->nvar];
    s->K = cholmod_allocate_sparse(nv, nv, nnz, 1, 1, 1, CHOLMOD_REAL, &s->cm);
    s->B = s->K ? cholmod_allocate_dense(nv, 1, nv, CHOLMOD_REAL, &s->cm) : NULL;
    if (!s->B)
        return SC_ENOMEM;
    memcpy(s->K->p, s->kp, (nv + 1) * sizeof *s->kp);
    memcpy(s->K->i, s->ki, nnz * sizeof *s->ki);
    s->L = cholmod_analyze(s->K, &s->cm);
    return s->L ? SC_OK : SC_ENOMEM;
}

int sc_island_active_set(const gs_problem *pb, const sc_body *bodies, const int *slot_body,
                         int nslots, double *z, double *u, sc_solve_info *info)
{
    int n = pb->nrows;
    as_ctx s = { .pb = pb, .n = n, .nslots = nslots };
    int rc = as_pattern(&s, bodies, slot_body);
    size_t nn = (size_t)n, nv = (size_t)(s.nvar > 0 ? s.nvar : 1);
    double *rbuf = rc == SC_OK ? malloc(5 * nn * sizeof *rbuf) : NULL;
    double *vbuf = rbuf ? malloc(4 * nv * sizeof *vbuf) : NULL;
    unsigned char *st = vbuf ? malloc(3 * nn) : NULL;
    s.d = st ? malloc(nn * sizeof *s.d) : NULL;
    s.mu_star = s.d ? malloc(nv * sizeof *s.mu_star) : NULL;
    s.ustar = s.mu_star ? malloc(nv * sizeof *s.ustar) : NULL;
    s.duabs = s.ustar ? malloc(nv * sizeof *s.duabs) : NULL;
    if (rc == SC_OK && !s.duabs)
        rc = SC_ENOMEM;
    if (rc == SC_OK && s.nvar == 0)
        rc = SC_ENUMERIC;     /* nothing movable: not an island to solve */
    if (rc == SC_OK)
        rc = as_start(&s);
    if (rc != SC_OK) {
        as_free(&s);
        free(st);
        free(vbuf);
        free(rbuf);
        return rc == SC_ETOOMANY ? SC_ENUMERIC : rc;
    }
    double *x = rbuf, *w = rbuf + nn, *sc = rbuf + 2 * nn, *zb = rbuf + 3 * nn,
           *xe = rbuf + 4 * nn;
    double *uv = vbuf, *b = vbuf + nv, *tmp = vbuf + 2 * nv, *tmp2 = vbuf + 3 * nv;
    unsigned char *ef = st + nn, *ef2 = st + 2 * nn;
    as_begin(&s, u, z, uv);
    s.comp = 0;
    for (int r = 0; r < n; r++)
        s.comp = max_d(s.comp, a_entry(&pb->rows[r], &pb->rows[r]));
    s.comp *= COMPLIANCE;
    memcpy(x, z, nn * sizeof *x);
    int iter = 0, done = 0, factored = 0, rounds = 0;
    double worst = INFINITY;
    memcpy(zb, x, nn * sizeof *zb);
    /* Inner: full Newton steps on the convex problem the bounds fixed at
     * +-mu times the normal impulses zb make (as_places() says which row
     * sits where); it ends when a step keeps every row's place. Outer: the answer is checked against its
     * own bounds, and zb becomes its normals when it fails (lcp.c's
     * friction fixed point). A new set of places costs a factorisation. */
    as_guess(&s, zb, x, uv, ef);
    int first = 1, stall = 0, last_changed = n + 1;
    while (rc == SC_OK && iter < AS_MAX_ITER && rounds < AS_BOUND_ROUNDS) {
        if (!factored) {
            iter++;
            as_matrix(&s, ef);
            if (!cholmod_factorize(s.K, s.L, &s.cm) || s.cm.status != CHOLMOD_OK) {
                rc = SC_ENUMERIC;
                break;
            }
            factored = 1;
        }
        /* the Newton target: the velocities of these places */
        as_rhs(&s, ef, zb, x, b);
        rc = as_solve(&s, b, tmp, tmp2);
        if (rc != SC_OK)
            break;
        /* the full step (the block principal pivoting step), from the
         * guess or where it lowers the objective; where it does not, or
         * where the places that change stop getting fewer, the island
         * goes to block Gauss-Seidel (a line search would take tiny steps
         * on the stiff compliance, and a bolt pile's friction rarely
         * settles: docs/DESIGN.md 11) */
        double f0 = as_objective(&s, zb, uv, sc), f1 = as_objective(&s, zb, tmp, sc);
        if (!first && !(f1 <= f0 + 1e-12 * fabs(f0)))
            break;
        first = 0;
        memcpy(uv, tmp, (size_t)s.nvar * sizeof *uv);
        memcpy(ef2, ef, nn);
        as_places(&s, zb, uv, x, ef);
        int changed = 0;
        for (int r = 0; r < n; r++)
            changed += ef2[r] != ef[r];
        if (changed > 0) {
            if (changed >= last_changed && ++stall >= AS_STALL)
                break;
            last_changed = changed;
            factored = 0;
            continue;
        }
        /* the held rows at the bounds of the answer's own impulses, free
         * ones within rounding of a bound on it, the velocities and w of
         * exactly these impulses */
        for (int r = 0; r < n; r++) {
            double lo, hi;
            bounds(&s, x, r, &lo, &hi);
            xe[r] = ef[r] != AS_FREE ? (ef[r] == AS_HI ? hi : lo) : min_d(max_d(x[r], lo), hi);
        }
        as_velocities(&s, xe, tmp);
        for (int r = 0; r < n; r++)
            w[r] = j_u(&s, &pb->rows[r], tmp) + s.d[r] + s.comp * xe[r];
        as_scale(&s, xe, sc);
        if (as_check(&s, xe, w, sc, &worst)) {
            memcpy(x, xe, nn * sizeof *x);
            done = 1;
            break;
        }
        if (!pb->findex)
            break;            /* no friction bounds to move: rounding */
        rounds++;
        s.round = rounds;
        stall = 0;
        last_changed = n + 1;
        memcpy(zb, x, nn * sizeof *zb);
        memcpy(ef2, ef, nn);
        as_places(&s, zb, uv, x, ef);
        factored = memcmp(ef2, ef, nn) == 0;
    }
    info->as_iterations += iter;
    info->as_iterations_max = iter > info->as_iterations_max ? iter : info->as_iterations_max;
    if (s.L) {
        long fnz = (long)s.cm.lnz;
        info->factor_nnz_max = fnz > info->factor_nnz_max ? fnz : info->factor_nnz_max;
    }
    if (rc == SC_OK && !done)
        rc = SC_ENUMERIC;
    if (rc == SC_OK) {
        for (int r = 0; r < n; r++)
            if (x[r] != z[r]) {
                local_apply(&pb->rows[r], x[r] - z[r], u);
                z[r] = x[r];
            }
        if (!pb->pseudo)
            info->residual_exact = max_d(info->residual_exact, worst);
    }
    as_free(&s);
    free(st);
    free(vbuf);
    free(rbuf);
    return rc;
}
