/* island_sparse.c - a big island's whole contact LCP, exact, by an active
 * set: which rows sit at a bound decided by full Newton steps on the
 * piecewise linear equations the LCP and its friction bounds make, each
 * step's linear system solved by a sparse LU factor (KLU), until a step
 * keeps every row's place; the answer is then verified as Dantzig's are
 * (docs/DESIGN.md 11).
 *
 * The system is solved in the bodies' velocities, not in the rows'
 * impulses: with the compliance c of the exact solves (COMPLIANCE), a free
 * row's impulse is z = -(J u + d) / c, and the velocities u of the movable
 * bodies solve (M + sum_free J^T J / c) u = M u* + sum_held J^T z - sum_free
 * J^T d / c, six unknowns a body whatever its contacts (a body in a pile
 * has tens of rows; the rows' own matrix would be many times larger). The
 * same answer as (A + c I) z = -q on the free rows, A = J M^-1 J^T.
 * Friction held at a bound is z_t = s mu z_n: with a free normal it moves
 * with u too, which makes the system unsymmetric, hence LU, not Cholesky;
 * the coupling inside the step settles what a fixed point on the bounds
 * (lcp.c) takes rounds for. */
#include <float.h>
#include <klu.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_rows.h"
#include "island_schur.h"
#include "vecmath.h"

/* A row's place: free (w = 0 between its bounds) or held at a bound.
 * Friction held at a bound is held at +-mu times its normal's impulse,
 * whatever place that normal has: the coupling is in the Newton system. */
enum { AS_FREE, AS_LO, AS_HI };

/* The answer must meet Dantzig's verification (lcp.c): every violation at
 * most AS_VERIFY (n+1) eps S_i, S_i the magnitude of the terms of w_i. */
#define AS_VERIFY 1000.0
/* ... or AS_FLOOR m/s, the rounding the velocities' system leaves where
 * the scale is near 0 (a push-out of a few micrometres): the exact
 * solves' own residuals reach 1e-13 to 1e-12 m/s on piles. */
#define AS_FLOOR 1e-12
/* Factorisations (sets of places) at most: Newton's method on the
 * piecewise linear equations takes a few (a stack or a pyramid 1 to 5);
 * an island whose places do not settle within these goes to block
 * Gauss-Seidel instead (contact.c), before it costs many factors. */
#define AS_MAX_ITER 12
#define AS_STALL 2
/* A step that changes more than 1/AS_CHURN of the places gives up at once:
 * a structure's steps change a few in a hundred, a bolt pile's friction a
 * quarter to a half, step after step, and never settles (docs/DESIGN.md
 * 11): block Gauss-Seidel takes it before it costs more factors. */
#define AS_CHURN 8
/* Refinement steps of each solve: one factor's, the subdomains'. */
#define AS_REFINE 2
#define AS_REFINE_SUB 6

#define AS_MASS 19

/* Subdomains (island_schur.c): an island of at least 2 AS_PART_BODIES
 * movable bodies is cut into one part per AS_PART_BODIES (at most
 * AS_MAX_PARTS) along the contact graph from its resting contacts up, so
 * that a stack or a pile splits by height. The count depends on the
 * island only, never on the workers: the same bits on any machine. */
#define AS_PART_BODIES 32
#define AS_MAX_PARTS 16

typedef struct as_ctx {
    const gs_problem *pb;
    int n;                    /* rows */
    int nslots;               /* velocity slots (u has 6 each) */
    int *var;                 /* slot -> first unknown (6 each), -1: not movable */
    int nvar;
    double *mass;             /* per slot: m, the world inertia 3 x 3 and its
                                 inverse (AS_MASS doubles) */
    double comp;              /* c */
    double *d;                /* per row: off plus J u of its immovable side */
    double *mu_star;          /* M u* per unknown (u*: u without the impulses) */
    double *ustar;            /* |u*| per unknown */
    double *duabs;            /* sum over rows of |M^-1 J_r^T z_r| per unknown */
    /* K in compressed columns of 6 x 6 blocks: slot t's six columns hold
     * the slots that share a row with it and itself (ascending, deg[t] of
     * them), six rows each */
    int *kp, *ki, *deg;
    int *rpos;                /* per row, 4: position of side p's slot in side
                                 q's list at [2 p + q], -1: a side not movable */
    double *kx;
    klu_common kc;
    klu_symbolic *sym;
    klu_numeric *num;
    sc_schur *sch;            /* subdomains, or NULL: one factor */
    const sc_task_runner *runner;   /* the subdomains' threads */
    sc_arena *arena;
} as_ctx;

/* Row r's Jacobian on its movable slot side t (0: a, 1: b), or NULL. */
static const double *jac(const row *rw, int t)
{
    return t == 0 ? (rw->ma ? rw->ja : NULL) : (rw->mb ? rw->jb : NULL);
}

static int side_slot(const row *rw, int t)
{
    return t ? rw->lb : rw->la;
}

/* Bounds of row r given z (friction: +-mu z_normal). */
static void bounds(const as_ctx *s, const double *z, int r, double *lo, double *hi)
{
    row_bounds(s->pb, z, r, lo, hi);
}

static int friction_row(const as_ctx *s, int r)
{
    return s->pb->findex && s->pb->findex[r] >= 0;
}

static int cmp_int(const void *x, const void *y)
{
    int a = *(const int *)x, b = *(const int *)y;
    return (a > b) - (a < b);
}

/* The unknowns, masses and the block pattern of K (both triangles: the
 * friction coupling makes K unsymmetric): slot t's block column holds the
 * slots that share a row with it and itself, ascending. A friction row
 * couples to its normal, which must join the same two bodies (a contact's
 * rows do); otherwise SC_ENUMERIC. Arrays from malloc (KLU's own are, and
 * they outlive any arena order). */
static int as_pattern(as_ctx *s, const sc_body *bodies, const int *slot_body)
{
    const row *rows = s->pb->rows;
    int n = s->n, ns = s->nslots;
    s->var = malloc((size_t)ns * sizeof *s->var);
    s->deg = malloc((size_t)ns * sizeof *s->deg);
    s->mass = malloc((size_t)ns * AS_MASS * sizeof *s->mass);
    s->rpos = malloc(4 * (size_t)(n > 0 ? n : 1) * sizeof *s->rpos);
    int *cnt = calloc((size_t)ns + 1, sizeof *cnt);
    int *adj = malloc(2 * (size_t)(n + ns) * sizeof *adj + sizeof *adj);
    int *pos = malloc((size_t)(ns > 0 ? ns : 1) * sizeof *pos);
    int rc = SC_ENOMEM;
    if (!s->var || !s->deg || !s->mass || !s->rpos || !cnt || !adj || !pos)
        goto out;
    rc = SC_ENUMERIC;
    for (int r = 0; r < n; r++)
        if (friction_row(s, r)) {
            const row *f = &rows[s->pb->findex[r]];
            if (f->la != rows[r].la || f->lb != rows[r].lb || f->ma != rows[r].ma ||
                f->mb != rows[r].mb)
                goto out;
        }
    int nv = 0;
    for (int t = 0; t < ns; t++) {
        const sc_body *b = &bodies[slot_body[t]];
        s->var[t] = movable(b) ? 6 * nv++ : -1;
        if (movable(b)) {
            double *m = &s->mass[AS_MASS * t];
            m[0] = 1 / b->inv_mass;
            memcpy(m + 10, b->iw, 9 * sizeof *m);
            if (!m3_inverse(m + 1, b->iw))
                goto out;
        }
    }
    s->nvar = 6 * nv;
    /* each movable slot's list: itself and the other side of every row
     * joining two movable slots; counted, listed, sorted, deduplicated */
    for (int t = 0; t < ns; t++)
        cnt[t + 1] = s->var[t] >= 0;
    for (int r = 0; r < n; r++)
        if (rows[r].ma && rows[r].mb && rows[r].la != rows[r].lb) {
            cnt[rows[r].la + 1]++;
            cnt[rows[r].lb + 1]++;
        }
    for (int t = 0; t < ns; t++)
        cnt[t + 1] += cnt[t];
    memcpy(pos, cnt, (size_t)ns * sizeof *pos);
    for (int t = 0; t < ns; t++)
        if (s->var[t] >= 0)
            adj[pos[t]++] = t;
    for (int r = 0; r < n; r++)
        if (rows[r].ma && rows[r].mb && rows[r].la != rows[r].lb) {
            adj[pos[rows[r].la]++] = rows[r].lb;
            adj[pos[rows[r].lb]++] = rows[r].la;
        }
    size_t nnz = 0;
    for (int t = 0; t < ns; t++) {
        int a = cnt[t], b = cnt[t + 1], u = a;
        qsort(&adj[a], (size_t)(b - a), sizeof *adj, cmp_int);
        for (int k = a; k < b; k++)
            if (k == a || adj[k] != adj[k - 1])
                adj[u++] = adj[k];
        s->deg[t] = u - a;
        nnz += 36 * (size_t)s->deg[t];
    }
    if (nnz > (size_t)1 << 30)
        goto out;
    rc = SC_ENOMEM;
    s->kp = malloc((size_t)(s->nvar + 1) * sizeof *s->kp);
    s->ki = malloc((nnz > 0 ? nnz : 1) * sizeof *s->ki);
    s->kx = malloc((nnz > 0 ? nnz : 1) * sizeof *s->kx);
    if (!s->kp || !s->ki || !s->kx)
        goto out;
    int p = 0;
    for (int t = 0; t < ns; t++) {
        if (s->var[t] < 0)
            continue;
        for (int k = 0; k < 6; k++) {
            s->kp[s->var[t] + k] = p;
            for (int j = 0; j < s->deg[t]; j++)
                for (int i = 0; i < 6; i++)
                    s->ki[p++] = s->var[adj[cnt[t] + j]] + i;
        }
    }
    s->kp[s->nvar] = p;
    for (int r = 0; r < n; r++)
        for (int sp = 0; sp < 2; sp++)
            for (int sq = 0; sq < 2; sq++) {
                int *rp = &s->rpos[4 * r + 2 * sp + sq];
                *rp = -1;
                if (!jac(&rows[r], sp) || !jac(&rows[r], sq))
                    continue;
                int v = side_slot(&rows[r], sp), t = side_slot(&rows[r], sq);
                int *f = bsearch(&v, &adj[cnt[t]], (size_t)s->deg[t], sizeof *adj, cmp_int);
                *rp = (int)(f - &adj[cnt[t]]);
            }
    rc = SC_OK;
out:
    free(pos);
    free(adj);
    free(cnt);
    return rc;
}

/* Entry (row i of the slot at position pos in slot t's list, column k of
 * slot t) of K. */
static double *k_at(const as_ctx *s, int t, int pos, int i, int k)
{
    return &s->kx[s->kp[s->var[t]] + 6 * (k * s->deg[t] + pos) + i];
}

/* K += g J_p^T J_q over the sides p of row r and q of row f (which joins
 * the same slots). */
static void k_add(as_ctx *s, int r, const row *rr, const row *rf, double g)
{
    for (int sp = 0; sp < 2; sp++)
        for (int sq = 0; sq < 2; sq++) {
            int pos = s->rpos[4 * r + 2 * sp + sq];
            if (pos < 0)
                continue;
            const double *jp = jac(rr, sp), *jq = jac(rf, sq);
            int t = side_slot(rr, sq);
            for (int k = 0; k < 6; k++) {
                double *col = k_at(s, t, pos, 0, k), gk = g * jq[k];
                for (int i = 0; i < 6; i++)
                    col[i] += jp[i] * gk;
            }
        }
}

/* A friction row held at a bound, and the sign of the bound. */
static double held_sign(unsigned char e)
{
    return e == AS_HI ? 1.0 : -1.0;
}

/* K for the places ef: M, plus J_r^T J_r / c of each free row, plus
 * s mu J_t^T J_n / c of each friction row t held at the bound s mu z_n of
 * a free normal n (z_t = s mu z_n moves with u through z_n = -(J_n u +
 * d_n) / c). */
static void as_matrix(as_ctx *s, const unsigned char *ef)
{
    memset(s->kx, 0, (size_t)s->kp[s->nvar] * sizeof *s->kx);
    const gs_problem *pb = s->pb;
    for (int t = 0; t < s->nslots; t++) {
        if (s->var[t] < 0)
            continue;
        const double *m = &s->mass[AS_MASS * t];
        int self = 0;     /* t's own position in its list */
        while (s->ki[s->kp[s->var[t]] + 6 * self] != s->var[t])
            self++;
        for (int k = 0; k < 3; k++)
            *k_at(s, t, self, k, k) = m[0];
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++)
                *k_at(s, t, self, 3 + i, 3 + k) = m[1 + 3 * i + k];
    }
    double ic = 1 / s->comp;
    for (int r = 0; r < s->n; r++) {
        const row *rw = &pb->rows[r];
        if (ef[r] == AS_FREE) {
            k_add(s, r, rw, rw, ic);
        } else if (friction_row(s, r) && ef[pb->findex[r]] == AS_FREE) {
            const row *rn = &pb->rows[pb->findex[r]];
            k_add(s, r, rw, rn, held_sign(ef[r]) * pb->mu[r] * ic);
        }
    }
}

/* y = K x. */
static void k_mul(const as_ctx *s, const double *x, double *y)
{
    memset(y, 0, (size_t)s->nvar * sizeof *y);
    for (int j = 0; j < s->nvar; j++)
        for (int p = s->kp[j]; p < s->kp[j + 1]; p++)
            y[s->ki[p]] += s->kx[p] * x[j];
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

/* The right-hand side for the places ef: M u* + sum_r J_r^T a_r, where
 * row r's impulse is a_r - g_r u: a free row's a is -d / c, a held row's
 * its bound, a friction row's held at the bound of a free normal n
 * s mu (-d_n / c), of a held normal s mu z_n. */
static void as_rhs(const as_ctx *s, const unsigned char *ef, double *b)
{
    const gs_problem *pb = s->pb;
    memcpy(b, s->mu_star, (size_t)s->nvar * sizeof *b);
    for (int r = 0; r < s->n; r++) {
        const row *rw = &pb->rows[r];
        double a;
        if (ef[r] == AS_FREE) {
            a = -s->d[r] / s->comp;
        } else if (friction_row(s, r)) {
            int f = pb->findex[r];
            double zn = ef[f] == AS_FREE ? -s->d[f] / s->comp
                        : ef[f] == AS_HI ? pb->hi[f]
                                         : pb->lo[f];
            a = held_sign(ef[r]) * pb->mu[r] * zn;
        } else {
            a = ef[r] == AS_HI ? pb->hi[r] : pb->lo[r];
        }
        if (a != 0)
            jt_add(s, rw, a, b);
    }
}

/* u = K^-1 b, refined: AS_REFINE steps after one factor, AS_REFINE_SUB
 * after subdomains (their Schur complement is formed by cancelling terms
 * of 1/c, and a place decided on its rounding can send Newton's steps
 * elsewhere). */
static int as_solve(as_ctx *s, const double *b, double *u, double *tmp, double *dx)
{
    size_t nv = (size_t)s->nvar;
    memcpy(dx, b, nv * sizeof *dx);
    int steps = s->sch ? AS_REFINE_SUB : AS_REFINE;
    for (int it = 0;; it++) {
        if (s->sch ? sc_schur_solve(s->sch, dx, s->runner, s->arena) != SC_OK
                   : !klu_solve(s->sym, s->num, s->nvar, 1, dx, &s->kc))
            return SC_ENUMERIC;
        for (size_t i = 0; i < nv; i++)
            u[i] = it ? u[i] + dx[i] : dx[i];
        if (it == steps)
            break;
        k_mul(s, u, tmp);
        for (size_t i = 0; i < nv; i++)
            dx[i] = b[i] - tmp[i];
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

/* A row's place for an unclamped impulse v within [lo, hi]: held at the
 * bound it passed, else free (on a bound too: a resting contact whose
 * bodies do not approach yet, as in a stack whose lower contacts take the
 * load first, then carries its share in the same step instead of one level
 * a step). A friction row whose bounds are 0 is held at 0. */
static unsigned char place(double v, double lo, double hi)
{
    return lo == hi ? AS_LO : v < lo ? AS_LO : v > hi ? AS_HI : AS_FREE;
}

/* Each row's impulse at velocities u, z = clamp(-(J u + d) / c, lo, hi),
 * into z, and its place; the normals first, so that friction is bounded
 * by the normal impulses of the same u. */
static void as_places(const as_ctx *s, const double *u, double *z, unsigned char *ef)
{
    for (int pass = 0; pass < 2; pass++)
        for (int r = 0; r < s->n; r++) {
            if (friction_row(s, r) != pass)
                continue;
            double lo, hi;
            bounds(s, z, r, &lo, &hi);
            double v = -(j_u(s, &s->pb->rows[r], u) + s->d[r]) / s->comp;
            ef[r] = place(v, lo, hi);
            z[r] = ef[r] == AS_LO ? lo : ef[r] == AS_HI ? hi : v;
        }
}

/* The first places, from the warm start z and its w = J u + d + c z
 * (where u holds it): a row inside its bounds is free, and so is one on a
 * bound whose w does not push it there (w = 0: a resting contact, or a
 * stack's contact above one that takes the load first); friction whose
 * normal is held at 0 is held at 0, and friction of a free normal that
 * has no load yet sticks (free). Not the places at u: there the
 * velocities before this frame's impulses settle (gravity's h g) over the
 * tiny compliance put every friction row at a bound. */
static void as_guess(const as_ctx *s, const double *z, const double *u, unsigned char *ef)
{
    const gs_problem *pb = s->pb;
    for (int pass = 0; pass < 2; pass++)
        for (int r = 0; r < s->n; r++) {
            if (friction_row(s, r) != pass)
                continue;
            double lo, hi;
            bounds(s, z, r, &lo, &hi);
            double w = j_u(s, &pb->rows[r], u) + s->d[r] + s->comp * z[r];
            if (pass && ef[pb->findex[r]] != AS_FREE && lo == hi)
                ef[r] = AS_LO;
            else if (pass && lo == hi)
                ef[r] = AS_FREE;
            else
                ef[r] = lo == hi                 ? AS_LO
                        : z[r] <= lo && w > 0 ? AS_LO
                        : z[r] >= hi && w < 0 ? AS_HI
                                              : AS_FREE;
        }
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

/* The subdomains (see AS_PART_BODIES): the movable slots in breadth-first
 * order over the rows that join two of them, from the slots resting on an
 * immovable body (then from the first slot not reached), cut into runs at
 * the level boundaries nearest equal runs; a slot with a row to a slot of
 * an earlier part joins the interface, so no row joins the interiors of
 * two parts. SC_OK with no plan for a small island (or one level). */
static int as_parts(as_ctx *s)
{
    int ns = s->nslots, nmov = s->nvar / 6;
    int np = nmov / AS_PART_BODIES;
    if (np < 2)
        return SC_OK;
    np = np > AS_MAX_PARTS ? AS_MAX_PARTS : np;
    const row *rows = s->pb->rows;
    int *slot = malloc((size_t)nmov * sizeof *slot);     /* movable -> slot */
    int *order = malloc((size_t)nmov * sizeof *order);
    int *lev = malloc((size_t)nmov * sizeof *lev);     /* by order position */
    int *part = malloc((size_t)ns * sizeof *part);
    int *pv = malloc((size_t)s->nvar * sizeof *pv);
    int rc = SC_ENOMEM;
    if (!slot || !order || !lev || !part || !pv)
        goto out;
    for (int t = 0; t < ns; t++) {
        part[t] = -2;         /* not reached */
        if (s->var[t] >= 0)
            slot[s->var[t] / 6] = t;
    }
    int head = 0, tail = 0;
    for (int r = 0; r < s->n; r++) {
        int t = rows[r].ma && !rows[r].mb ? rows[r].la : !rows[r].ma && rows[r].mb ? rows[r].lb : -1;
        if (t >= 0 && part[t] == -2) {
            part[t] = -3;     /* queued */
            lev[tail] = 0;
            order[tail++] = t;
        }
    }
    for (int first = 0; head < nmov; head++) {
        if (head == tail) {
            while (part[slot[first]] != -2)
                first++;
            part[slot[first]] = -3;
            lev[tail] = tail > 0 ? lev[tail - 1] + 1 : 0;
            order[tail++] = slot[first];
        }
        int t = order[head], c = s->var[t];
        for (int j = 0; j < s->deg[t]; j++) {
            int u = slot[s->ki[s->kp[c] + 6 * j] / 6];
            if (part[u] == -2) {
                part[u] = -3;
                lev[tail] = lev[head] + 1;
                order[tail++] = u;
            }
        }
    }
    /* cuts at the level boundaries nearest the equal runs: the interface
     * is then one level (a row of a pyramid), not a level and a half */
    int cut[AS_MAX_PARTS + 1], nc = 0;
    cut[nc++] = 0;
    for (int k = 1; k < np; k++) {
        int want = (int)((long)k * nmov / np), best = -1;
        for (int d = 0; d < nmov && best < 0; d++)
            for (int sg = -1; sg <= 1 && best < 0; sg += 2) {
                int q = want + sg * d;
                if (q > cut[nc - 1] && q < nmov && lev[q] != lev[q - 1])
                    best = q;
            }
        if (best > cut[nc - 1])
            cut[nc++] = best;
    }
    np = nc;
    if (np < 2) {
        rc = SC_OK;
        goto out;
    }
    for (int k = 0, p = 0; k < nmov; k++) {
        while (p + 1 < np && k >= cut[p + 1])
            p++;
        part[order[k]] = p;
    }
    for (int k = 0; k < nmov; k++) {
        int t = slot[k], c = s->var[t], own = part[t];
        for (int j = 0; j < s->deg[t]; j++)
            own = part[slot[s->ki[s->kp[c] + 6 * j] / 6]] < part[t] ? -1 : own;
        for (int i = 0; i < 6; i++)
            pv[c + i] = own;
    }
    rc = sc_schur_plan(&s->sch, s->nvar, s->kp, s->ki, pv, np);
out:
    free(pv);
    free(part);
    free(lev);
    free(order);
    free(slot);
    return rc;
}

static void as_free(as_ctx *s)
{
    sc_schur_free(s->sch);
    if (s->num)
        klu_free_numeric(&s->num, &s->kc);
    if (s->sym)
        klu_free_symbolic(&s->sym, &s->kc);
    free(s->duabs);
    free(s->ustar);
    free(s->mu_star);
    free(s->d);
    free(s->kx);
    free(s->ki);
    free(s->kp);
    free(s->rpos);
    free(s->deg);
    free(s->mass);
    free(s->var);
}

/* K's factor for the places ef: the first one ordered (AMD) and pivoted
 * by KLU (no threads, the same bits on any machine load), later ones
 * refactored with its pivots, afresh when that fails. */
static int as_factor(as_ctx *s, const unsigned char *ef)
{
    as_matrix(s, ef);
    if (s->sch)
        return sc_schur_factor(s->sch, s->kx, s->runner, s->arena);
    if (!s->sym) {
        klu_defaults(&s->kc);
        s->sym = klu_analyze(s->nvar, s->kp, s->ki, &s->kc);
        if (!s->sym)
            return s->kc.status == KLU_OUT_OF_MEMORY ? SC_ENOMEM : SC_ENUMERIC;
    }
    if (s->num && klu_refactor(s->kp, s->ki, s->kx, s->sym, s->num, &s->kc) &&
        s->kc.status == KLU_OK)
        return SC_OK;
    if (s->num)
        klu_free_numeric(&s->num, &s->kc);
    s->num = klu_factor(s->kp, s->ki, s->kx, s->sym, &s->kc);
    if (!s->num)
        return s->kc.status == KLU_OUT_OF_MEMORY ? SC_ENOMEM : SC_ENUMERIC;
    return SC_OK;
}

int sc_island_active_set(const gs_problem *pb, const sc_body *bodies, const int *slot_body,
                         int nslots, int subdomains, const sc_task_runner *runner,
                         sc_arena *arena, double *z, double *u, sc_solve_info *info)
{
    int n = pb->nrows;
    as_ctx s = { .pb = pb, .n = n, .nslots = nslots, .runner = runner, .arena = arena };
    int rc = as_pattern(&s, bodies, slot_body);
    size_t nn = (size_t)n, nv = (size_t)(s.nvar > 0 ? s.nvar : 1);
    double *rbuf = rc == SC_OK ? malloc(4 * nn * sizeof *rbuf) : NULL;
    double *vbuf = rbuf ? malloc(4 * nv * sizeof *vbuf) : NULL;
    unsigned char *st = vbuf ? malloc(2 * nn) : NULL;
    s.d = st ? malloc(nn * sizeof *s.d) : NULL;
    s.mu_star = s.d ? malloc(nv * sizeof *s.mu_star) : NULL;
    s.ustar = s.mu_star ? malloc(nv * sizeof *s.ustar) : NULL;
    s.duabs = s.ustar ? malloc(nv * sizeof *s.duabs) : NULL;
    if (rc == SC_OK && !s.duabs)
        rc = SC_ENOMEM;
    if (rc == SC_OK && s.nvar == 0)
        rc = SC_ENUMERIC;     /* nothing movable: not an island to solve */
    if (rc == SC_OK && subdomains)
        rc = as_parts(&s);
    if (rc != SC_OK) {
        as_free(&s);
        free(st);
        free(vbuf);
        free(rbuf);
        return rc;
    }
    double *x = rbuf, *w = rbuf + nn, *sc = rbuf + 2 * nn, *xe = rbuf + 3 * nn;
    double *uv = vbuf, *b = vbuf + nv, *tmp = vbuf + 2 * nv, *dx = vbuf + 3 * nv;
    unsigned char *ef = st, *ef2 = st + nn;
    as_begin(&s, u, z, uv);
    s.comp = 0;
    for (int r = 0; r < n; r++)
        s.comp = max_d(s.comp, a_entry(&pb->rows[r], &pb->rows[r]));
    s.comp *= COMPLIANCE;
    /* Semismooth Newton on M (u - u*) = sum_r J_r^T z_r(u), z_r(u) the
     * row's impulse clamped into its bounds, friction's +-mu z_n(u): each
     * step fixes every row's place (as_places()) and solves the linear
     * equations they make; it ends when a step keeps every place. */
    as_guess(&s, z, uv, ef);
    int iter = 0, done = 0, stall = 0, last_changed = n + 1;
    double worst = INFINITY;
    while (iter < AS_MAX_ITER) {
        iter++;
        rc = as_factor(&s, ef);
        if (rc == SC_OK) {
            as_rhs(&s, ef, b);
            rc = as_solve(&s, b, uv, tmp, dx);
        }
        if (rc != SC_OK)
            break;
        memcpy(ef2, ef, nn);
        as_places(&s, uv, x, ef);
        int changed = 0;
        for (int r = 0; r < n; r++)
            changed += ef2[r] != ef[r];
        if (changed > 0) {
            /* places that change stop getting fewer: a cycle, which block
             * Gauss-Seidel takes over (docs/DESIGN.md 11) */
            if (AS_CHURN * changed > n || (changed >= last_changed && ++stall >= AS_STALL))
                break;
            last_changed = changed;
            continue;
        }
        /* the held rows at the bounds of the answer's own impulses, the
         * velocities and w of exactly these impulses */
        for (int r = 0; r < n; r++) {
            double lo, hi;
            bounds(&s, x, r, &lo, &hi);
            xe[r] = min_d(max_d(x[r], lo), hi);
        }
        as_velocities(&s, xe, tmp);
        for (int r = 0; r < n; r++)
            w[r] = j_u(&s, &pb->rows[r], tmp) + s.d[r] + s.comp * xe[r];
        as_scale(&s, xe, sc);
        if (as_check(&s, xe, w, sc, &worst)) {
            memcpy(x, xe, nn * sizeof *x);
            done = 1;
        }
        break;
    }
    info->as_iterations += iter;
    info->as_iterations_max = iter > info->as_iterations_max ? iter : info->as_iterations_max;
    long fnz = s.sch ? sc_schur_factor_nnz(s.sch)
               : s.num ? (long)s.num->lnz + s.num->unz + s.num->nzoff
                       : 0;
    info->factor_nnz_max = fnz > info->factor_nnz_max ? fnz : info->factor_nnz_max;
    int parts = 1;
    if (s.sch) {
        sc_schur_traffic tr = sc_schur_traffic_of(s.sch);
        int ni = sc_schur_interface(s.sch);
        parts = sc_schur_parts(s.sch);
        info->as_interface_max = ni > info->as_interface_max ? ni : info->as_interface_max;
        info->as_exchanges += tr.exchanges;
        info->as_exchange_bytes += tr.bytes;
    }
    info->as_parts_max = parts > info->as_parts_max ? parts : info->as_parts_max;
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
