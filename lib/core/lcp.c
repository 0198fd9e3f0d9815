/* lcp.c - the contact LCP solver (the paper's step (7); docs/DESIGN.md 3.5
 * and 11): Cottle-Dantzig principal pivoting as Baraff describes it
 * (SIGGRAPH 1994, section 4), extended to bounds lo <= z <= hi (the boxed
 * LCP of ODE's dSolveLCP) and to Coulomb friction bounds +-mu z_normal.
 * A pivot costs O(n^2): the factorisation of M_CC (lcp_factor.c) is
 * bordered and downdated, never refactorised, and nothing is allocated in
 * the pivot loop. Failure is reported, never hidden (SC_ENOSOLUTION,
 * SC_EMAXITER, SC_ENUMERIC); SC_OK answers are checked against the
 * original data, and Lemke's method (lcp_lemke.c) takes what pivoting
 * cannot. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "lcp.h"

/* Problem: w = M z + q with, for every i, one of
 *   z_i = lo_i and w_i >= 0,   z_i = hi_i and w_i <= 0,   lo_i <= z_i <= hi_i and w_i = 0.
 * The standard LCP (z >= 0, w >= 0, z.w = 0) is lo = 0, hi = +inf; for
 * contacts (the paper's V' = A P + V) M = A = J W J^T, z = P, w = V'.
 *
 * Method. Indices are taken in order 0..n-1. Each one, d, is driven (Baraff's
 * drive-to-zero): z_d moves towards making (z_d, w_d) valid while every
 * index already settled stays valid: clamped ones (set C: w = 0) move z_C
 * so that w_C stays 0 (fdirection: M_CC dz_C = -M_Cd), free ones (at a
 * bound) keep z and let w move. The step stops at the first event (maxstep):
 * d becomes valid (w_d = 0: d joins C; or z_d reaches its bound), a clamped
 * z reaches a bound (it leaves C), or a free w reaches 0 (it joins C). The
 * direction solve uses an L D U factorisation of M_CC (lcp_factor.c) that
 * is bordered when an index joins C and downdated when one leaves. Boxes
 * that exclude 0 are shifted first (z = c + z', c = clamp(0, lo, hi)), so
 * z' = 0 is a valid start. After the pass z_C is recomputed from scratch
 * with one refinement step and any index the drift left invalid is driven
 * again (finish()).
 *
 * Cost per pivot: the direction solve is a bordering (one or two triangular
 * solves of size m = |C|) plus one back substitution, O(m^2); dw for the
 * free indices is O(n m); moving an index in or out of the factorisation is
 * O(m^2). So a pivot is O(n^2), never the O(m^3) of refactorising M_CC.
 * Memory: two allocations per call (the caller's arena), nothing
 * allocated in the pivot loop.
 *
 * Cost per call, besides the pivots (on the small blocks of contact.c,
 * n <= 18 with a few pivots each, these O(n^2) passes are most of it):
 * one pass over M for its row sums, symmetry and finiteness
 * (work_init()); per refresh in finish() O(m n + m^2) for z_C and, when
 * nothing leaves C, O(n^2) for every w (refresh_z(), refresh_w()). The
 * final check reuses the last refresh's w when the answer is its z, and
 * the friction check reuses that when its clamps move nothing, so
 * verify()'s own O(n^2) pass runs only on answers that changed after it
 * (shifted boxes, polished or Lemke answers). A warm pass whose unseen
 * indices all settle where they stand skips its second finish(). Each of
 * these reuses values computed from the same numbers, so the answer is
 * the same to the bit as with the passes done again.
 *
 * Singular M_CC (positive semidefinite M: 8 contact points on one box face
 * give 8 rows of rank 3, and any number of contacts on one body rank <= 6).
 * For symmetric PSD M the method keeps M_CC nonsingular by itself: an
 * index j joins C only when its w is pushed through 0 (dw_j < 0), and with
 * Schur complements s_j, s_d of j and d over C and coupling t = dw_j, the
 * 2x2 block [s_j t; t s_d] is PSD, so s_j >= t^2 / s_d > 0. Only d's own
 * pivot s_d = dw_d can vanish: then column d is a combination of the
 * clamped columns and the whole direction changes no w (dw = 0). We do not
 * add d then (M_CC would be singular); d's direction moves load from
 * clamped indices to d at constant w until a clamped z reaches its bound
 * and leaves C, after which s_d > 0. If no clamped z decreases, dz >= 0
 * with M dz = 0 and dz.w = w_d < 0 prove that no z >= 0 has M z + q >= 0:
 * SC_ENOSOLUTION. Numerically "vanish" means |pivot| <= LCP_TAU_PIV times
 * the terms it cancelled from; any index (also for non-symmetric or
 * indefinite M) joins C only with a pivot above that, otherwise it is
 * passed over for that step. A non-symmetric PSD M (e.g. skew-symmetric)
 * can need a 2x2 block pivot that this form cannot make; when it fails,
 * sc_lcp_dantzig() runs Lemke's method (lcp_lemke.c), which processes
 * every PSD problem.
 *
 * Friction (findex): the bounds +-mu_i |z_normal| depend on the answer.
 * Rounds of a fixed point: round 0 with the normals at 0 (frictionless),
 * each later round with the bounds of the previous answer, warm-started
 * from its sets so that the load split between redundant contacts stays
 * put; after each round the same sets are also solved with the coupling
 * exact (friction_polish()). SC_OK as soon as an answer satisfies the
 * bounds it implies itself. When the rounds do not settle, Lemke's method
 * on the friction LCP (friction_lemke(), from up to six covering vectors),
 * and when that fails too, the rounds again from projected Gauss-Seidel's
 * iterate (friction_guess()).
 *
 * Tolerances (eps = DBL_EPSILON, S_i = |q_i| + sum_j |M_ij z_j|, the size
 * of the terms that make w_i, so (n+1) eps S_i bounds the rounding of
 * w_i): an index is driven when its w is wrong by more than
 * LCP_DRIVE (n+1) eps S_i; SC_OK requires every violation (see verify())
 * to be at most LCP_VERIFY (n+1) eps S_i.
 *
 * Failure is reported, never hidden: no blocking event (unbounded ray) is
 * SC_ENOSOLUTION, more than LCP_MAX_PIVOTS(n) pivots in one pass (cycling
 * on degenerate ties, or an exponential path such as Murty's) or friction
 * rounds that do not settle is SC_EMAXITER, a cancelling downdate or a
 * final check that fails is SC_ENUMERIC. Before SC_OK the answer is
 * checked against the original data. On error z and w hold the last
 * iterate, for diagnostics only. */

/* A pivot is singular when |pivot| <= LCP_TAU_PIV * (the magnitude of the
 * terms it was computed from): exact redundancy leaves ~1e-16 there, a
 * genuine pivot of a well-posed contact problem is far above 1e-10. */
#define LCP_TAU_PIV 1e-10
/* Rounding noise of dw_i and dz_i: LCP_NOISE (n+1) eps times their scale. */
#define LCP_NOISE 8.0
/* An index is driven when its w is wrong by more than LCP_DRIVE (n+1) eps
 * times the scale S_i = |q_i| + sum_j |M_ij z_j| of the terms of w_i. */
#define LCP_DRIVE 100.0
/* SC_OK requires every violation <= LCP_VERIFY (n+1) eps S_i (10x the
 * drive threshold, so that rounding in the final solve never fails it). */
#define LCP_VERIFY 1000.0
/* Pivot limit per pass: Cottle-Dantzig needs one to five pivots per index
 * on contact problems (bench/bench_lcp.c); 2^n - 1 paths exist (Murty's
 * example) but not on those. */
#define LCP_MAX_PIVOTS(n) (10L * (n) + 100L)
/* Refresh-and-redrive rounds after the main pass (see finish()). */
#define LCP_SWEEPS 4
/* Friction: fixed-point rounds on the bounds +-mu z_normal. Nearly every
 * fixed point that settles does so within these rounds, and most that fail
 * would run any number of rounds more, so further rounds are mostly time
 * spent on failures: Lemke's method (friction_lemke()) is the cheaper way
 * on from here (docs/DESIGN.md 11). */
#define LCP_FRICTION_ROUNDS 10
/* The rounds alone (sc_lcp_boxed_rounds_in(), with no Lemke after them)
 * damp the fixed point: from round LCP_DAMP_FROM on, the normals a
 * round's bounds come from are the mean of the previous round's and its
 * answer, which ends most of the two-set cycles the plain rounds fall
 * into near stick-slip, up to LCP_DAMPED_ROUNDS rounds. Where Lemke's method follows, the plain
 * rounds and their stop on a cycle are cheaper: damped, a small island
 * that cycles runs every round before Lemke (docs/DESIGN.md 11). */
#define LCP_DAMP_FROM 3
#define LCP_DAMPED_ROUNDS 20

enum { ST_UNSEEN, ST_DRIVE, ST_C, ST_LO, ST_HI, ST_FREE };

/* Events that end a step (Baraff's maxstep). */
enum { EV_NONE, EV_D_TO_C, EV_D_TO_BOUND, EV_LEAVE_C, EV_ENTER_C };

typedef struct lcp {
    int n;
    const double *M;
    const double *q, *lo, *hi;   /* shifted so that lo <= 0 <= hi */
    double *z, *w;
    double *dzc;                 /* dz of C, factor order */
    double *dw;                  /* dw by index (free indices only) */
    double *rowabs;              /* sum_j |M_ij| */
    double *wtol;                /* drive tolerance of each settled index */
    double *wv, *wsc, *zref;     /* the last refresh_w(): w = M z + q and S_i
                                    of every index, at z = zref */
    int wv_ok;                   /* wv, wsc, zref hold one of this pass */
    double *tmp;                 /* n scratch */
    signed char *st;             /* ST_* by index */
    long *mark;                  /* pivot stamp: index passed over */
    long *left_run;              /* run stamp: index left C at a zero step */
    long run;                    /* counts steps of nonzero length */
    sc_ldu f;
    double eps_n;                /* (n + 1) DBL_EPSILON */
    long pivots, max_pivots;
    int clamped;                 /* drop_out_of_bounds() moved a z of C */
    int settled;                 /* the last finish() left every index valid
                                    and every z as its last refresh_w() had it */
} lcp;

typedef struct step {
    int ev;                      /* EV_* */
    int who;                     /* index (EV_LEAVE_C: factor position) */
    double t;                    /* step length along dz */
    int to_hi;                   /* bound reached is hi */
} step;

/* ---- small helpers -------------------------------------------------- */

/* Whether a pivot is clearly nonzero. For symmetric M (PSD when it comes
 * from contacts) it must also be positive: every Schur complement of a PSD
 * matrix is >= 0, so a negative one is rounding on a near-singular block. */
static int significant(const lcp *s, double pivot, double scale)
{
    return (s->f.sym ? pivot : fabs(pivot)) > LCP_TAU_PIV * scale;
}

/* S_i = |q_i| + sum_j |M_ij z_j|: the size of the terms that make w_i,
 * hence of its rounding error. */
static double w_scale(const double *M, const double *q, const double *z, int n, int i)
{
    const double *row = M + (size_t)i * n;
    double s = fabs(q[i]);
    for (int j = 0; j < n; j++)
        s += fabs(row[j] * z[j]);
    return s;
}

static double row_dot(const double *M, const double *z, int n, int i)
{
    const double *row = M + (size_t)i * n;
    double s = 0;
    for (int j = 0; j < n; j++)
        s += row[j] * z[j];
    return s;
}

/* row_dot() and w_scale() in one pass over the row (the same sums in the
 * same order, so the same bits): w_i - q_i, and S_i into *scale. */
static double row_dot_scale(const double *M, const double *q, const double *z, int n, int i,
                            double *scale)
{
    const double *row = M + (size_t)i * n;
    double d = 0, sc = fabs(q[i]);
    for (int j = 0; j < n; j++) {
        double t = row[j] * z[j];
        d += t;
        sc += fabs(t);
    }
    *scale = sc;
    return d;
}

static int all_finite(const double *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return 0;
    return 1;
}

/* ---- index sets ------------------------------------------------------ */

/* Put index d, whose border is prepared, into C. */
static void join_c(lcp *s, int d)
{
    SC_ASSERT(s->f.bordered == d);
    sc_ldu_commit(&s->f);
    s->st[d] = ST_C;
    s->w[d] = 0;
}

/* If (z_d, w_d) is valid (within tol), file d under its set and return 1.
 * An interior z_d with w_d = 0 joins C when its pivot allows, otherwise it
 * is ST_FREE: w_d must stay 0 although d is not in the factorisation. */
static int try_settle(lcp *s, int d, double tol)
{
    double z = s->z[d], w = s->w[d];
    s->wtol[d] = tol;
    if (z <= s->lo[d] && w >= -tol) {
        s->z[d] = s->lo[d];
        s->st[d] = ST_LO;
        return 1;
    }
    if (z >= s->hi[d] && w <= tol) {
        s->z[d] = s->hi[d];
        s->st[d] = ST_HI;
        return 1;
    }
    if (fabs(w) <= tol) {
        double scale, piv = sc_ldu_border(&s->f, s->M, d, &scale);
        if (significant(s, piv, scale))
            join_c(s, d);
        else
            s->st[d] = ST_FREE;
        return 1;
    }
    return 0;
}

/* ---- one pivot ------------------------------------------------------- */

/* Baraff's fdirection for driving d by dir = +-1: dz_d = dir,
 * dz_C = -dir M_CC^-1 M_Cd, and dw = M dz on the free indices. Returns
 * d's own dw_d = dir * (its Schur complement), 0 when that pivot is
 * singular (*null_dir set: then dw = 0 in exact arithmetic for PSD M). */
static double direction(lcp *s, int d, int dir, int *null_dir, double *dzmax)
{
    const int n = s->n, m = s->f.m;
    double scale, piv = sc_ldu_border(&s->f, s->M, d, &scale);
    sc_ldu_border_direction(&s->f, s->dzc);
    double big = 1.0;
    for (int k = 0; k < m; k++) {
        s->dzc[k] *= dir;
        big = max_d(big, fabs(s->dzc[k]));
    }
    *dzmax = big;
    for (int i = 0; i < n; i++) {
        if (s->st[i] != ST_LO && s->st[i] != ST_HI && s->st[i] != ST_FREE)
            continue;
        const double *row = s->M + (size_t)i * n;
        double acc = dir * row[d];
        for (int k = 0; k < m; k++)
            acc += row[s->f.idx[k]] * s->dzc[k];
        s->dw[i] = acc;
    }
    *null_dir = !significant(s, piv, scale);
    return *null_dir ? 0.0 : dir * piv;
}

static void consider(step *best, int ev, int who, double t, int to_hi)
{
    t = max_d(t, 0.0);   /* rounding can put a value a hair past its bound */
    if (t < best->t) {
        best->ev = ev;
        best->who = who;
        best->t = t;
        best->to_hi = to_hi;
    }
}

/* maxstep, part 1: events of d itself and of the clamped indices. */
static step steps_d_and_c(const lcp *s, int d, int dir, double dwd, double dzmax)
{
    step best = { EV_NONE, -1, INFINITY, 0 };
    if (dwd * s->w[d] < 0)
        consider(&best, EV_D_TO_C, d, -s->w[d] / dwd, 0);
    if (dir > 0 && isfinite(s->hi[d]))
        consider(&best, EV_D_TO_BOUND, d, s->hi[d] - s->z[d], 1);
    if (dir < 0 && isfinite(s->lo[d]))
        consider(&best, EV_D_TO_BOUND, d, s->z[d] - s->lo[d], 0);
    double ztol = LCP_NOISE * s->eps_n * dzmax;
    for (int k = 0; k < s->f.m; k++) {
        int i = s->f.idx[k];
        double dz = s->dzc[k];
        if (dz < -ztol && isfinite(s->lo[i]))
            consider(&best, EV_LEAVE_C, k, (s->lo[i] - s->z[i]) / dz, 0);
        else if (dz > ztol && isfinite(s->hi[i]))
            consider(&best, EV_LEAVE_C, k, (s->hi[i] - s->z[i]) / dz, 1);
    }
    return best;
}

/* A free index whose w is on the wrong side by more than its tolerance:
 * only after a refresh (finish()), until it is driven. Such an index does
 * not block others: only valid indices do. */
static inline int invalid(const lcp *s, int i)
{
    double w = s->w[i], tol = s->wtol[i];
    switch (s->st[i]) {
    case ST_LO: return w < -tol;
    case ST_HI: return w > tol;
    case ST_FREE: return fabs(w) > tol;
    default: return 0;
    }
}

/* maxstep, part 2: the free index whose w first reaches 0 (skipping those
 * passed over in this pivot). dw below its noise level counts as 0; in a
 * null direction the noise level is the singular-pivot one. */
static void steps_free(const lcp *s, step *best, double dzmax, int null_dir)
{
    double rel = null_dir ? LCP_TAU_PIV : LCP_NOISE * s->eps_n;
    for (int i = 0; i < s->n; i++) {
        int st = s->st[i];
        if ((st != ST_LO && st != ST_HI && st != ST_FREE) || s->mark[i] == s->pivots)
            continue;
        double dw = s->dw[i], wt = rel * s->rowabs[i] * dzmax, w = s->w[i];
        if (invalid(s, i))
            continue;   /* waiting to be driven itself (finish()) */
        double t;
        if ((st == ST_LO && dw < -wt) || (st == ST_HI && dw > wt))
            t = -w / dw;
        else if (st == ST_FREE && fabs(dw) > wt)
            t = w * dw < 0 ? -w / dw : 0.0;
        else
            continue;
        /* anti-cycling: an index that left C in this run of zero-length
         * steps may not come straight back (on a near-singular block,
         * rounding can make it look blocking both ways) */
        if (t <= 0 && s->left_run[i] == s->run)
            continue;
        consider(best, EV_ENTER_C, i, t, 0);
    }
}

/* The full maxstep: a free index may only win if it can join C with a
 * nonsingular pivot; one that cannot is passed over (marked) and the
 * choice is made again. */
static step maxstep(lcp *s, int d, int dir, double dwd, double dzmax, int null_dir)
{
    step base = steps_d_and_c(s, d, dir, dwd, dzmax);
    for (;;) {
        step best = base;
        steps_free(s, &best, dzmax, null_dir);
        if (best.ev != EV_ENTER_C)
            return best;
        double scale, piv = sc_ldu_border(&s->f, s->M, best.who, &scale);
        if (significant(s, piv, scale))
            return best;
        s->mark[best.who] = s->pivots;
    }
}

/* Move along the direction by t: z on C and d, w on the free indices and d. */
static void advance(lcp *s, int d, int dir, double dwd, double t)
{
    if (t > 0)
        s->run++;
    for (int k = 0; k < s->f.m; k++)
        s->z[s->f.idx[k]] += t * s->dzc[k];
    s->z[d] += t * dir;
    s->w[d] += t * dwd;
    for (int i = 0; i < s->n; i++)
        if (s->st[i] == ST_LO || s->st[i] == ST_HI || s->st[i] == ST_FREE)
            s->w[i] += t * s->dw[i];
}

/* Apply the event that ended the step. Returns 1 to keep driving d, 0 when
 * d is settled, or a negative code. */
static int transfer(lcp *s, int d, const step *e)
{
    switch (e->ev) {
    case EV_D_TO_C:
        if (s->f.bordered != d) {
            double scale, piv = sc_ldu_border(&s->f, s->M, d, &scale);
            if (!significant(s, piv, scale))
                return SC_ENUMERIC;
        }
        join_c(s, d);
        return 0;
    case EV_D_TO_BOUND:
        s->z[d] = e->to_hi ? s->hi[d] : s->lo[d];
        s->st[d] = e->to_hi ? ST_HI : ST_LO;
        return 0;
    case EV_LEAVE_C: {
        int i = s->f.idx[e->who];
        s->z[i] = e->to_hi ? s->hi[i] : s->lo[i];
        s->w[i] = 0;
        s->st[i] = e->to_hi ? ST_HI : ST_LO;
        if (e->t <= 0)
            s->left_run[i] = s->run;
        return sc_ldu_remove(&s->f, e->who) == SC_OK ? 1 : SC_ENUMERIC;
    }
    case EV_ENTER_C:
        SC_ASSERT(s->f.bordered == e->who);
        join_c(s, e->who);
        return 1;
    default:
        return SC_ENOSOLUTION;
    }
}

/* Baraff's drive-to-zero for index d. */
static int drive(lcp *s, int d)
{
    s->st[d] = ST_DRIVE;
    s->run++;
    for (;;) {
        double tol = LCP_DRIVE * s->eps_n * w_scale(s->M, s->q, s->z, s->n, d);
        if (try_settle(s, d, tol))
            return SC_OK;
        if (++s->pivots > s->max_pivots)
            return SC_EMAXITER;
        int dir = s->w[d] < 0 ? 1 : -1, null_dir;
        double dzmax, dwd = direction(s, d, dir, &null_dir, &dzmax);
        step e = maxstep(s, d, dir, dwd, dzmax, null_dir);
        if (e.ev == EV_NONE)
            return SC_ENOSOLUTION;   /* an unbounded ray: see the header */
        advance(s, d, dir, dwd, e.t);
        int rc = transfer(s, d, &e);
        if (rc <= 0)
            return rc;
    }
}

/* ---- end game ---------------------------------------------------------- */

/* Recompute z_C from scratch, M_CC z_C = -(q_C + M_{C,N} z_N), with one
 * step of iterative refinement: this removes the drift of the incremental
 * updates. O(m n + m^2). */
static void refresh_z(lcp *s)
{
    const int n = s->n, m = s->f.m;
    const int *idx = s->f.idx;
    double *zc = s->dzc, *r = s->dw;
    for (int k = 0; k < m; k++)
        s->z[idx[k]] = 0;
    for (int k = 0; k < m; k++)
        r[k] = -s->q[idx[k]] - row_dot(s->M, s->z, n, idx[k]);
    memcpy(zc, r, (size_t)m * sizeof(double));
    sc_ldu_solve(&s->f, zc);
    double *res = s->tmp;
    for (int k = 0; k < m; k++) {
        const double *row = s->M + (size_t)idx[k] * n;
        double a = r[k];
        for (int l = 0; l < m; l++)
            a -= row[idx[l]] * zc[l];
        res[k] = a;
    }
    sc_ldu_solve(&s->f, res);
    for (int k = 0; k < m; k++)
        s->z[idx[k]] = zc[k] + res[k];
}

/* Every w = M z + q from scratch, and every drive tolerance. Keeps w and
 * S_i with the z they belong to: when the answer is that z, verify() needs
 * no second O(n^2) pass (solve_fixed()). O(n^2). */
static void refresh_w(lcp *s)
{
    const int n = s->n;
    for (int i = 0; i < n; i++) {
        double scale;
        s->w[i] = s->wv[i] = s->q[i] + row_dot_scale(s->M, s->q, s->z, n, i, &scale);
        s->wsc[i] = scale;
        s->wtol[i] = LCP_DRIVE * s->eps_n * scale;
    }
    memcpy(s->zref, s->z, (size_t)n * sizeof(double));
    s->wv_ok = 1;
}

/* How far a refreshed z of C may lie beyond its bound and stay in C. */
static double c_slack(const lcp *s)
{
    double zmax = 0;
    for (int i = 0; i < s->n; i++)
        zmax = max_d(zmax, fabs(s->z[i]));
    return LCP_DRIVE * s->eps_n * zmax;
}

static int beyond(const lcp *s, int i, double tz)
{
    return s->z[i] < s->lo[i] - tz || s->z[i] > s->hi[i] + tz;
}

/* Take out of C every index whose refreshed z is beyond a bound (at that
 * bound now), clamp the others into theirs; returns how many left, or
 * SC_ENUMERIC. */
static int drop_out_of_bounds(lcp *s, double tz)
{
    int dropped = 0;
    s->clamped = 0;
    for (int k = s->f.m - 1; k >= 0; k--) {
        int i = s->f.idx[k];
        if (beyond(s, i, tz)) {
            int hi = s->z[i] > s->hi[i];
            s->z[i] = hi ? s->hi[i] : s->lo[i];
            s->st[i] = hi ? ST_HI : ST_LO;
            if (sc_ldu_remove(&s->f, k) != SC_OK)
                return SC_ENUMERIC;
            dropped++;
        } else {
            double c = min_d(max_d(s->z[i], s->lo[i]), s->hi[i]);
            s->clamped |= c != s->z[i];
            s->z[i] = c;
            s->w[i] = 0;
        }
    }
    return dropped;
}

/* After a pass: refresh, then repair - clamped z beyond a bound leave C,
 * free indices whose refreshed w is off by more than the drive tolerance
 * are driven again (Baraff's "while some a_i < 0" loop, on exact values).
 * Dropping rounds are bounded by |C|; driving rounds by LCP_SWEEPS. A
 * round that drops refreshes z again at once, so its w (O(n^2)) are only
 * computed when nothing is dropped: before the clamp into the bounds, as
 * one refresh of z and w would. */
static int finish(lcp *s)
{
    for (int sweeps = 0; sweeps < LCP_SWEEPS;) {
        refresh_z(s);
        double tz = c_slack(s);
        int drop = 0;
        for (int k = 0; k < s->f.m && !drop; k++)
            drop = beyond(s, s->f.idx[k], tz);
        if (!drop)
            refresh_w(s);
        int dropped = drop_out_of_bounds(s, tz);
        if (dropped < 0)
            return dropped;
        if (dropped > 0)
            continue;
        int driven = 0;
        for (int i = 0; i < s->n; i++) {
            if (!invalid(s, i))
                continue;
            driven = 1;
            int rc = drive(s, i);
            if (rc != SC_OK)
                return rc;
        }
        if (!driven) {
            s->settled = !s->clamped;
            return SC_OK;
        }
        sweeps++;
    }
    refresh_z(s);
    refresh_w(s);
    s->settled = 0;
    return SC_OK;   /* verify() has the last word */
}

/* The whole pass for fixed bounds (already shifted: lo <= 0 <= hi). */
static int pivot_all(lcp *s)
{
    const int n = s->n;
    memset(s->z, 0, (size_t)n * sizeof(double));
    for (int i = 0; i < n; i++) {
        s->st[i] = ST_UNSEEN;
        s->mark[i] = -1;
    }
    s->f.m = 0;
    s->f.bordered = -1;
    s->max_pivots = s->pivots + LCP_MAX_PIVOTS(n);   /* per pass */
    for (int d = 0; d < n; d++) {
        s->w[d] = s->q[d] + row_dot(s->M, s->z, n, d);
        int rc = drive(s, d);
        if (rc != SC_OK)
            return rc;
    }
    return finish(s);
}

/* The end of a warm pass: repair what the start broke, then drive the
 * unseen indices as in a first pass. An unseen index that settles where
 * it stands without a pivot and without joining C (a separating contact
 * at its bound 0, say) changes no z and no factor. So when the first
 * finish() ended with every index valid and z as its refresh computed it
 * (no clamp of a z of C), a second one would refresh to the same values
 * and find nothing to do: it is only run when some drive moved something
 * or the first did not end so (same answer, one O(n^2) refresh less). */
static int warm_finish(lcp *s)
{
    const int n = s->n;
    int rc = finish(s), moved = 0;
    for (int d = 0; d < n && rc == SC_OK; d++) {
        if (s->st[d] != ST_UNSEEN)
            continue;
        long pivots = s->pivots;
        int m = s->f.m;
        s->w[d] = s->q[d] + row_dot(s->M, s->z, n, d);
        rc = drive(s, d);
        moved |= s->pivots != pivots || s->f.m != m;
    }
    return rc == SC_OK && (moved || !s->settled) ? finish(s) : rc;
}

/* A pass that starts from the sets of the previous one (friction rounds,
 * where only some bounds moved, prevlo/prevhi being the old ones): C is
 * rebuilt by bordering in its old order (O(m^2) each, O(m^3) once per
 * pass), indices at a bound that did not move stay there, those at a bound
 * that moved start again from 0 (unseen), finish() repairs what the new
 * bounds broke and the unseen ones are driven as in a first pass. Keeps
 * the previous answer's split of load between redundant contacts, which a
 * fresh pass would choose anew (and so throw the rounds off). */
static int pivot_warm(lcp *s, const double *prevlo, const double *prevhi)
{
    const int n = s->n, m = s->f.m;
    int *order = (int *)(void *)s->tmp;   /* n ints fit in n doubles */
    memcpy(order, s->f.idx, (size_t)m * sizeof(int));
    s->f.m = 0;
    s->f.bordered = -1;
    s->max_pivots = s->pivots + LCP_MAX_PIVOTS(n);
    for (int i = 0; i < n; i++) {
        s->mark[i] = -1;
        int st = s->st[i];
        if ((st == ST_LO || st == ST_HI) && prevlo[i] == prevhi[i] &&
            (s->lo[i] != prevlo[i] || s->hi[i] != prevhi[i]))
            s->st[i] = ST_UNSEEN;
        if (s->st[i] == ST_UNSEEN)
            s->z[i] = 0;
        else if (s->st[i] == ST_LO)
            s->z[i] = s->lo[i];
        else if (s->st[i] == ST_HI)
            s->z[i] = s->hi[i];
        else
            s->z[i] = min_d(max_d(s->z[i], s->lo[i]), s->hi[i]);
    }
    for (int k = 0; k < m; k++) {
        int i = order[k];
        double scale, piv = sc_ldu_border(&s->f, s->M, i, &scale);
        if (significant(s, piv, scale)) {
            sc_ldu_commit(&s->f);
        } else {
            int hi = s->z[i] - s->lo[i] > s->hi[i] - s->z[i];
            s->z[i] = hi ? s->hi[i] : s->lo[i];
            s->st[i] = hi ? ST_HI : ST_LO;
        }
    }
    return warm_finish(s);
}

/* A pass that starts from a guess (s->z, shifted; the last frame's
 * impulses, or a block's last iterate): indices strictly inside their
 * box join C (bordered in index order, when the pivot allows), those at a
 * bound start there, those at 0 are unseen; then as pivot_warm(). A
 * guess is only a start: finish() repairs it and verify() checks the
 * answer as after a cold pass. */
static int pivot_guess(lcp *s)
{
    const int n = s->n;
    s->f.m = 0;
    s->f.bordered = -1;
    s->max_pivots = s->pivots + LCP_MAX_PIVOTS(n);
    for (int i = 0; i < n; i++) {
        double z = s->z[i];
        s->mark[i] = -1;
        if (!(z != 0) || !isfinite(z)) {
            s->z[i] = 0;
            s->st[i] = ST_UNSEEN;
        } else if (z <= s->lo[i]) {
            s->z[i] = s->lo[i];
            s->st[i] = ST_LO;
        } else if (z >= s->hi[i]) {
            s->z[i] = s->hi[i];
            s->st[i] = ST_HI;
        } else {
            double scale, piv = sc_ldu_border(&s->f, s->M, i, &scale);
            if (significant(s, piv, scale)) {
                sc_ldu_commit(&s->f);
                s->st[i] = ST_C;
            } else {
                s->z[i] = 0;
                s->st[i] = ST_UNSEEN;
            }
        }
    }
    return warm_finish(s);
}

/* ---- verification -------------------------------------------------------- */

/* w = M z + q and S_i = |q_i| + sum_j |M_ij z_j| of every index. */
static void w_all(int n, const double *M, const double *q, const double *z, double *w,
                  double *sc)
{
    for (int i = 0; i < n; i++)
        w[i] = q[i] + row_dot_scale(M, q, z, n, i, &sc[i]);
}

/* Largest violation (in units of w) of the boxed conditions by (z, w) and
 * whether each index is within its tolerance tol_i = LCP_VERIFY (n+1) eps
 * S_i, S_i = sc[i] = |q_i| + sum_j |M_ij z_j| (the rounding bound of w_i
 * scaled up); w and sc must be those of z (w_all()). For index i with
 * zs = max_j |z_j|:
 *   w_i > 0 is allowed only at z_i = lo_i: violation min(w_i, (z_i-lo_i) w_i / zs);
 *   w_i < 0 only at z_i = hi_i:          min(-w_i, (hi_i-z_i)(-w_i) / zs);
 * for the standard LCP this is exactly w_i >= -tol_i and z_i w_i <= tol_i zs.
 * z outside [lo, hi] or anything not finite fails. O(n). */
static int check(int n, const double *lo, const double *hi, const double *z, const double *w,
                 const double *sc, double eps_n, double *residual)
{
    double zs = DBL_MIN, worst = 0;
    int ok = 1;
    for (int i = 0; i < n; i++)
        zs = max_d(zs, fabs(z[i]));
    for (int i = 0; i < n; i++) {
        double tol = LCP_VERIFY * eps_n * sc[i];
        double wp = max_d(w[i], 0), wm = max_d(-w[i], 0), v = 0;
        if (!isfinite(z[i]) || !isfinite(w[i]) || z[i] < lo[i] || z[i] > hi[i])
            v = INFINITY;
        if (wp > 0)
            v = max_d(v, isinf(lo[i]) ? wp : min_d(wp, (z[i] - lo[i]) * wp / zs));
        if (wm > 0)
            v = max_d(v, isinf(hi[i]) ? wm : min_d(wm, (hi[i] - z[i]) * wm / zs));
        if (!(v <= tol))
            ok = 0;
        worst = max_d(worst, v);
    }
    *residual = worst;
    return ok;
}

/* The final check of an answer against the original data: w = M z + q
 * (into w, S_i into sc) recomputed from z, then check(). */
static int verify(int n, const double *M, const double *q, const double *lo,
                  const double *hi, const double *z, double *w, double *sc, double eps_n,
                  double *residual)
{
    w_all(n, M, q, z, w, sc);
    return check(n, lo, hi, z, w, sc, eps_n, residual);
}

/* ---- workspace ----------------------------------------------------------- */

typedef struct work {
    void *mem, *fmem;
    lcp s;
    double *lo, *hi, *shift, *qs, *blo, *bhi, *plo, *phi, *zfix, *zprev, *zbound, *kmat;
    double *vsc;                 /* S_i of the w of the last verify() */
    double *zpgs, *zsor;         /* the projected Gauss-Seidel iterates,
                                    plain and over-relaxed (friction_guess()) */
    int covers;                  /* sc_lcp_info.covers */
} work;

/* Everything a call needs in two allocations (nothing is allocated in the
 * pivot loop): 24 vectors, kmat (n x n, friction only), two stamp arrays
 * and the set of each index in mem, the factorisation (whose size depends
 * on whether M is symmetric) in fmem. One pass over M finds its row sums
 * |M_i.|, whether it is symmetric and whether it is finite (SC_EINVAL if
 * not): the O(n^2) each call pays once. */
static int work_init(sc_arena *arena, work *wk, int n, const double *M, int friction)
{
    enum { VECS = 24 };
    size_t nd = (size_t)n, nn = nd * nd;
    if (nd > SIZE_MAX / sizeof(double) / (nd + VECS) / 4)
        return SC_ENOMEM;
    size_t bytes = (VECS * nd + (friction ? nn : 0)) * sizeof(double) +
                   2 * nd * sizeof(long) + nd;
    wk->fmem = NULL;
    wk->covers = 0;
    wk->mem = sc_arena_alloc(arena, bytes);
    if (!wk->mem)
        return SC_ENOMEM;
    double *p = wk->mem;
    lcp *s = &wk->s;
    double **vec[VECS] = { &s->z, &s->w, &s->dzc, &s->dw, &s->rowabs, &s->wtol, &s->tmp,
                           &s->wv, &s->wsc, &s->zref, &wk->lo, &wk->hi, &wk->shift,
                           &wk->qs, &wk->blo, &wk->bhi, &wk->plo, &wk->phi, &wk->zfix,
                           &wk->zprev, &wk->zbound, &wk->vsc, &wk->zpgs, &wk->zsor };
    for (int v = 0; v < VECS; v++, p += nd)
        *vec[v] = p;
    wk->kmat = friction ? p : NULL;
    p += friction ? nn : 0;
    _Static_assert(_Alignof(long) <= _Alignof(double), "stamps follow doubles");
    s->mark = (long *)(void *)p;
    s->left_run = s->mark + nd;
    s->st = (signed char *)(s->left_run + nd);
    int sym = 1, finite = 1;
    for (int i = 0; i < n; i++) {
        const double *row = M + (size_t)i * n;
        double a = 0;
        for (int j = 0; j < i; j++) {
            a += fabs(row[j]);
            sym &= row[j] == M[(size_t)j * n + i];
        }
        for (int j = i; j < n; j++)
            a += fabs(row[j]);
        s->rowabs[i] = a;
        finite &= isfinite(a);   /* a NaN or inf entry makes the sum one */
    }
    if (!finite && !all_finite(M, nn)) {   /* else finite entries overflowed the sum */
        sc_arena_free(arena, wk->mem);
        return SC_EINVAL;
    }
    wk->fmem = sc_arena_alloc(arena, sc_ldu_size(n, sym));
    if (!wk->fmem) {
        sc_arena_free(arena, wk->mem);
        return SC_ENOMEM;
    }
    sc_ldu_init(&s->f, n, sym, wk->fmem);
    s->n = n;
    s->M = M;
    s->eps_n = (n + 1.0) * DBL_EPSILON;
    s->pivots = 0;
    s->run = 0;
    s->wv_ok = 0;
    for (int i = 0; i < n; i++)
        s->left_run[i] = -1;
    return SC_OK;
}

static void work_free(sc_arena *arena, work *wk)
{
    sc_arena_free(arena, wk->fmem);
    sc_arena_free(arena, wk->mem);
}

/* verify() of an answer z of solve_fixed(). When z is the z of the last
 * refresh_w() of the pass and nothing was shifted (so that its q was
 * the original q), that refresh's w and S_i are the ones verify() would
 * compute: the same sums of the same numbers, so the same bits (a zero's
 * sign in z changes no sum: it starts at +0 and x + -0 = x). Only the O(n)
 * check() is left then; w and wk->vsc are set either way. */
static int verify_answer(work *wk, int shifted, const double *q, const double *lo,
                         const double *hi, const double *z, double *w, double *residual)
{
    const lcp *s = &wk->s;
    const int n = s->n;
    int same = s->wv_ok && !shifted;
    for (int i = 0; i < n && same; i++)
        same = z[i] == s->zref[i];
    if (!same)
        return verify(n, s->M, q, lo, hi, z, w, wk->vsc, s->eps_n, residual);
    memcpy(w, s->wv, (size_t)n * sizeof(double));
    memcpy(wk->vsc, s->wsc, (size_t)n * sizeof(double));
    return check(n, lo, hi, z, w, wk->vsc, s->eps_n, residual);
}

/* Solve for fixed bounds lo <= hi: shift z by c = clamp(0, lo, hi) so that
 * z = 0 is inside every box (the start point of the method), pivot, shift
 * back into z, check against the original data. */
enum { START_COLD, START_SETS, START_GUESS };

static int solve_fixed(work *wk, const double *q, const double *lo, const double *hi,
                       int start, double *z, double *w, double *residual)
{
    lcp *s = &wk->s;
    const int n = s->n;
    int shifted = 0, warm = start == START_SETS;
    if (warm) {
        memcpy(wk->plo, wk->blo, (size_t)n * sizeof(double));
        memcpy(wk->phi, wk->bhi, (size_t)n * sizeof(double));
    }
    for (int i = 0; i < n; i++) {
        wk->shift[i] = min_d(max_d(0.0, lo[i]), hi[i]);
        wk->blo[i] = lo[i] - wk->shift[i];
        wk->bhi[i] = hi[i] - wk->shift[i];
        shifted |= wk->shift[i] != 0;
    }
    for (int i = 0; i < n; i++)
        wk->qs[i] = q[i] + (shifted ? row_dot(s->M, wk->shift, n, i) : 0.0);
    s->q = wk->qs;
    s->lo = wk->blo;
    s->hi = wk->bhi;
    s->wv_ok = 0;
    int guess = 0;
    if (start == START_GUESS)
        for (int i = 0; i < n; i++) {
            s->z[i] = z[i] - wk->shift[i];
            guess |= s->z[i] != 0;
        }
    int rc = warm ? pivot_warm(s, wk->plo, wk->phi) : guess ? pivot_guess(s) : pivot_all(s);
    if ((warm || guess) && rc != SC_OK && rc != SC_ENOMEM)
        rc = pivot_all(s);   /* the warm start lost its way: start afresh */
    for (int i = 0; i < n; i++)
        z[i] = min_d(max_d(s->z[i] + wk->shift[i], lo[i]), hi[i]);
    int ok = verify_answer(wk, shifted, q, lo, hi, z, w, residual);
    if (guess && rc == SC_OK && !ok) {
        /* a guessed start that ends just outside the tolerance: afresh */
        rc = pivot_all(s);
        for (int i = 0; i < n; i++)
            z[i] = min_d(max_d(s->z[i] + wk->shift[i], lo[i]), hi[i]);
        ok = verify_answer(wk, shifted, q, lo, hi, z, w, residual);
    }
    if (rc == SC_OK && !ok)
        rc = SC_ENUMERIC;
    return rc;
}

static void report(sc_lcp_info *info, const work *wk, double residual)
{
    if (info) {
        info->pivots = wk->s.pivots;
        info->residual = residual;
        info->lemke = 0;
        info->covers = wk->covers;
        info->guessed = 0;
    }
}

/* ---- standard LCP -------------------------------------------------------- */

static int dantzig(sc_arena *arena, int n, const double *M, const double *q, int start,
                   double *z, double *w, sc_lcp_info *info)
{
    if (info) {
        info->pivots = 0;
        info->residual = 0;
        info->lemke = 0;
        info->guessed = 0;
    }
    if (n < 0 || (n > 0 && (!M || !q || !z || !w)))
        return SC_EINVAL;
    if (n == 0)
        return SC_OK;
    if (!all_finite(q, (size_t)n))   /* M: work_init() */
        return SC_EINVAL;
    int lemke = 0;
    work wk;
    int rc = work_init(arena, &wk, n, M, 0);
    if (rc != SC_OK)
        return rc;
    for (int i = 0; i < n; i++) {
        wk.lo[i] = 0;
        wk.hi[i] = INFINITY;
    }
    double residual;
    rc = solve_fixed(&wk, q, wk.lo, wk.hi, start, z, w, &residual);
    if (rc == SC_ENOSOLUTION || rc == SC_ENUMERIC || rc == SC_EMAXITER) {
        /* a singular principal block the principal form cannot pass:
         * Lemke's method can (see lcp_lemke.c) */
        rc = sc_lcp_lemke(n, M, q, NULL, z, wk.s.pivots + LCP_MAX_PIVOTS(n), &wk.s.pivots);
        int ok = verify(n, M, q, wk.lo, wk.hi, z, w, wk.vsc, wk.s.eps_n, &residual);
        if (rc == SC_OK && !ok)
            rc = SC_ENUMERIC;
        lemke = 1;
    }
    report(info, &wk, residual);
    if (info)
        info->lemke = lemke;    /* never silent: callers can count it */
    work_free(arena, &wk);
    return rc;
}

int sc_lcp_dantzig_in(sc_arena *arena, int n, const double *M, const double *q, double *z,
                      double *w, sc_lcp_info *info)
{
    return dantzig(arena, n, M, q, START_COLD, z, w, info);
}

int sc_lcp_dantzig_warm_in(sc_arena *arena, int n, const double *M, const double *q,
                           double *z, double *w, sc_lcp_info *info)
{
    return dantzig(arena, n, M, q, START_GUESS, z, w, info);
}

int sc_lcp_dantzig(int n, const double *M, const double *q, double *z, double *w,
                   sc_lcp_info *info)
{
    return sc_lcp_dantzig_in(NULL, n, M, q, z, w, info);
}

SC_API int sc_lcp_solve(int n, const double *M, const double *q, double *z, double *w)
{
    return sc_lcp_dantzig(n, M, q, z, w, NULL);
}

/* ---- boxed LCP and friction ---------------------------------------------- */

static int boxed_args_ok(int n, const double *lo, const double *hi, const int *findex,
                         const double *mu)
{
    for (int i = 0; i < n; i++) {
        int fi = findex ? findex[i] : -1;
        if (fi >= 0) {
            /* a friction row's normal must be an ordinary row */
            if (fi >= n || fi == i || findex[fi] >= 0 || !isfinite(mu[i]) || mu[i] < 0)
                return 0;
            continue;
        }
        if (isnan(lo[i]) || isnan(hi[i]) || lo[i] > hi[i] || lo[i] == INFINITY ||
            hi[i] == -INFINITY)
            return 0;
    }
    return 1;
}

/* Bounds of every row: the given ones, friction rows +-mu |z_normal|
 * (0 * inf does not arise: normals are finite). */
static void friction_bounds(int n, const double *lo, const double *hi, const int *findex,
                            const double *mu, const double *z, double *blo, double *bhi)
{
    for (int i = 0; i < n; i++) {
        if (findex[i] >= 0) {
            double b = mu[i] * fabs(z[findex[i]]);
            blo[i] = -b;
            bhi[i] = b;
        } else {
            blo[i] = lo[i];
            bhi[i] = hi[i];
        }
    }
}

/* Check a candidate against the friction bounds it implies itself. z is
 * clamped into them first (friction rows after their normals); a clamp by
 * more than rounding fails. have_w: w and wk->vsc are those of z (the
 * last verify() was of this z); if the clamps move nothing they still
 * are, and only the bounds changed: check() alone, O(n), the same result
 * as a full verify(). */
static int verify_coupled(work *wk, const double *q, const double *lo, const double *hi,
                          const int *findex, const double *mu, double *z, double *w,
                          double *residual, int have_w)
{
    const int n = wk->s.n;
    int moved = 0;
    for (int i = 0; i < n; i++)
        if (findex[i] < 0) {
            double c = min_d(max_d(z[i], lo[i]), hi[i]);
            moved |= c != z[i];
            z[i] = c;
        }
    friction_bounds(n, lo, hi, findex, mu, z, wk->lo, wk->hi);
    double zs = 0;
    for (int i = 0; i < n; i++)
        zs = max_d(zs, fabs(z[i]));
    int ok = 1;
    for (int i = 0; i < n; i++) {
        double c = min_d(max_d(z[i], wk->lo[i]), wk->hi[i]);
        if (fabs(c - z[i]) > LCP_VERIFY * wk->s.eps_n * zs)
            ok = 0;
        moved |= c != z[i];
        z[i] = c;
    }
    if (have_w && !moved)
        return check(n, wk->lo, wk->hi, z, w, wk->vsc, wk->s.eps_n, residual) && ok;
    return verify(n, wk->s.M, q, wk->lo, wk->hi, z, w, wk->vsc, wk->s.eps_n, residual) && ok;
}

/* Friction polish: with the sets of the last pass (C, at lower / upper
 * bound), solve the coupled equations exactly, friction rows at a bound
 * being z_i = sigma mu_i |z_normal| also where the normal is in C:
 *   w_C = 0,  z = z_fixed + E z_C   ->   (M_{C,:} E) z_C = -q_C - M_{C,:} z_fixed.
 * A dense O(m^3) solve, once per round, not per pivot. Writes z. */
static int friction_polish(work *wk, const double *q, const int *findex,
                           const double *mu, double *z)
{
    const lcp *s = &wk->s;
    const int n = s->n, m = s->f.m;
    const int *idx = s->f.idx;
    double *K = wk->kmat, *rhs = wk->qs, *zf = wk->zfix;
    int *pos = (int *)(void *)s->tmp;   /* n ints fit in n doubles */
    for (int i = 0; i < n; i++)
        pos[i] = -1;
    for (int k = 0; k < m; k++)
        pos[idx[k]] = k;
    /* the fixed part, and where each coupled friction row is tied */
    for (int i = 0; i < n; i++) {
        int f = findex[i];
        zf[i] = pos[i] >= 0 ? 0.0 : z[i];
        if (f >= 0 && pos[i] < 0 && (s->st[i] == ST_LO || s->st[i] == ST_HI)) {
            double sg = s->st[i] == ST_HI ? 1.0 : -1.0;
            zf[i] = pos[f] >= 0 ? 0.0 : sg * mu[i] * fabs(z[f]);
        }
    }
    for (int r = 0; r < m; r++) {
        const double *row = s->M + (size_t)idx[r] * n;
        rhs[r] = -q[idx[r]] - row_dot(s->M, zf, n, idx[r]);
        for (int k = 0; k < m; k++)
            K[(size_t)r * m + k] = row[idx[k]];
        for (int i = 0; i < n; i++) {
            int f = findex[i];
            if (f < 0 || pos[i] >= 0 || pos[f] < 0 ||
                (s->st[i] != ST_LO && s->st[i] != ST_HI))
                continue;
            double sg = (s->st[i] == ST_HI ? 1.0 : -1.0) * (z[f] < 0 ? -1.0 : 1.0);
            K[(size_t)r * m + pos[f]] += row[i] * sg * mu[i];
        }
    }
    if (sc_lu_solve(m, K, rhs) != SC_OK || !all_finite(rhs, (size_t)m))
        return SC_ENUMERIC;
    for (int i = 0; i < n; i++)
        z[i] = pos[i] >= 0 ? rhs[pos[i]] : zf[i];
    for (int i = 0; i < n; i++) {
        int f = findex[i];
        if (f >= 0 && pos[i] < 0 && pos[f] >= 0 && (s->st[i] == ST_LO || s->st[i] == ST_HI))
            z[i] = (s->st[i] == ST_HI ? 1.0 : -1.0) * mu[i] * fabs(z[f]);
    }
    return SC_OK;
}

/* Coulomb friction: the bounds of a friction row depend on the answer.
 * Fixed point on them (round 0 with the normals at 0, i.e. frictionless),
 * each round a full pivoting pass with fixed bounds, then an exact polish
 * with that round's sets; SC_OK as soon as one satisfies the bounds it
 * implies, SC_EMAXITER after LCP_FRICTION_ROUNDS (damped:
 * LCP_DAMPED_ROUNDS) or once the rounds repeat (a cycle). */
static int solve_friction(work *wk, const double *q, const double *lo, const double *hi,
                          const int *findex, const double *mu, int start, int damped,
                          double *z, double *w, double *residual)
{
    const int n = wk->s.n;
    const size_t nb = (size_t)n * sizeof(double);
    double *zprev = wk->zprev, *zb = wk->zbound;
    const int rounds = damped ? LCP_DAMPED_ROUNDS : LCP_FRICTION_ROUNDS;
    /* a round that repeats an earlier round's answer bit for bit has
     * entered a cycle (the bin: a third of the fixed points that failed,
     * most with period 2, found by round 3-8; none settled after a
     * repeat): Lemke at once instead of the remaining rounds; damped,
     * the bounds' answer is what repeats */
    _Static_assert(LCP_DAMPED_ROUNDS >= LCP_FRICTION_ROUNDS, "seen holds every round");
    uint64_t seen[LCP_DAMPED_ROUNDS];
    /* round 0: the bounds of the guess (a warm start), else frictionless */
    if (start == START_GUESS)
        memcpy(zb, z, nb);
    else
        memset(zb, 0, nb);
    for (int round = 0; round < rounds; round++) {
        friction_bounds(n, lo, hi, findex, mu, zb, wk->lo, wk->hi);
        int rc = solve_fixed(wk, q, wk->lo, wk->hi, round > 0 ? START_SETS : start, z, w,
                             residual);
        if (rc != SC_OK)
            return rc;
        memcpy(zprev, z, nb);
        if (verify_coupled(wk, q, lo, hi, findex, mu, z, w, residual, 1))
            return SC_OK;
        memcpy(z, zprev, nb);
        if (friction_polish(wk, q, findex, mu, z) == SC_OK &&
            verify_coupled(wk, q, lo, hi, findex, mu, z, w, residual, 0))
            return SC_OK;
        memcpy(z, zprev, nb);
        if (damped && round + 1 >= LCP_DAMP_FROM)
            for (int i = 0; i < n; i++)
                zb[i] = 0.5 * (zb[i] + z[i]);
        else
            memcpy(zb, z, nb);
        seen[round] = sc_fnv1a(SC_FNV_OFFSET, zb, nb);
        int cycle = 0;
        for (int r = 0; r < round && !cycle; r++)
            cycle = seen[r] == seen[round];
        if (cycle)
            break;
    }
    for (int i = 0; i < n; i++)   /* the w of the z handed back */
        w[i] = q[i] + row_dot(wk->s.M, z, n, i);
    return SC_EMAXITER;
}

/* Covering vector v of friction_lemke(), entry k of N = nn normals, then
 * nf rows b+, nf rows b-, nf rows lambda: 0 is e; 1, 4 and 5 are e
 * perturbed by up to 50 or 90 % (fractional parts of multiples of
 * irrational numbers: deterministic, no two entries alike); 2 and 3 weigh
 * the b rows against the lambda rows (1/2 and 2, 2 and 1/2). Lemke's path
 * depends on its covering vector and from e can end on a secondary ray;
 * the others, tried in turn, solve most of what e leaves, so that far
 * fewer problems are left to the guess or to a raised diagonal
 * (docs/DESIGN.md 11). */
#define LEMKE_COVERS 6
static double frac_part(double x)
{
    return x - floor(x);
}

static double cover(int v, int k, int nn, int nf)
{
    int b_row = k >= nn && k < nn + 2 * nf, lambda_row = k >= nn + 2 * nf;
    switch (v) {
    case 0:
        return 1;
    case 1:
        return 1 + 0.5 * frac_part((k + 1) * 0.6180339887498949);
    case 2:
        return b_row ? 0.5 : lambda_row ? 2 : 1;
    case 3:
        return b_row ? 2 : lambda_row ? 0.5 : 1;
    default:
        return 1 + 0.9 * frac_part((k + 1) * v * 0.7548776662466927);
    }
}

/* Friction by Lemke's method when the fixed point does not settle (it can
 * cycle between sets near stick-slip). The box friction problem is an LCP
 * of its own (Stewart and Trinkle's form, one multiplier per friction
 * row): with z_t = b+ - b-, variables (z_normals, b+, b-, lambda) >= 0 and
 *   w_n   = (M z + q)_n                  >= 0  _|_  z_n
 *   w_b+  =  (M z + q)_t + lambda_t      >= 0  _|_  b+
 *   w_b-  = -(M z + q)_t + lambda_t      >= 0  _|_  b-
 *   w_lam =  mu_t z_f(t) - b+ - b-       >= 0  _|_  lambda_t
 * so |z_t| <= mu z_n, and at the bound the sliding velocity opposes z_t.
 * Lemke's method processes it (Anitescu and Potra, 1997); the answer is
 * mapped back and verified against the coupled bounds like any other.
 * Its matrix is not copositive-plus, so a path can end on a secondary ray
 * (or on an answer that fails the check) where an answer exists: then
 * the paths of the other covering vectors of cover() are tried, up to
 * LEMKE_COVERS in all (docs/DESIGN.md 11). Only for rows that are contact
 * normals (lo 0, hi inf) and their friction rows; SC_EINVAL otherwise. */
static int friction_lemke(work *wk, const double *q, const double *lo, const double *hi,
                          const int *findex, const double *mu, double *z, double *w,
                          double *residual)
{
    const int n = wk->s.n;
    const double *M = wk->s.M;
    int nf = 0;
    for (int i = 0; i < n; i++) {
        if (findex[i] >= 0)
            nf++;
        else if (lo[i] != 0 || hi[i] != INFINITY)
            return SC_EINVAL;
    }
    /* column of each row's variable: normals keep their order, then b+ */
    int nn = n - nf, N = n + 2 * nf;
    size_t Nd = (size_t)N;
    double *mem = malloc((Nd * Nd + 3 * Nd) * sizeof *mem + 2 * (size_t)n * sizeof(int));
    if (!mem)
        return SC_ENOMEM;
    double *B = mem, *qb = B + Nd * Nd, *x = qb + Nd, *d = x + Nd;
    int *col = (int *)(void *)(d + Nd), *fr = col + n;
    int kn = 0, kf = 0;
    for (int i = 0; i < n; i++) {
        if (findex[i] >= 0) {
            fr[kf] = i;
            col[i] = nn + kf++;
        } else {
            col[i] = kn++;
        }
    }
    memset(B, 0, Nd * Nd * sizeof *B);
    /* rows: w of normal i at col[i]; of b+_k at nn+k, b-_k at nn+nf+k,
     * lambda_k at nn+2nf+k. Columns likewise. */
    for (int i = 0; i < n; i++) {
        const double *Mi = M + (size_t)i * n;
        int ri = col[i];
        int rows[2] = { ri, findex[i] >= 0 ? ri + nf : -1 };
        for (int s2 = 0; s2 < 2 && rows[s2] >= 0; s2++) {
            double sg = s2 == 0 ? 1.0 : -1.0;
            double *Br = B + (size_t)rows[s2] * Nd;
            for (int j = 0; j < n; j++) {
                if (findex[j] >= 0) {
                    Br[col[j]] += sg * Mi[j];
                    Br[col[j] + nf] -= sg * Mi[j];
                } else {
                    Br[col[j]] += sg * Mi[j];
                }
            }
            qb[rows[s2]] = sg * q[i];
            if (findex[i] >= 0)
                Br[col[i] + 2 * nf] = 1;   /* + lambda */
        }
    }
    for (int k = 0; k < nf; k++) {
        int i = fr[k];
        double *Br = B + (size_t)(nn + 2 * nf + k) * Nd;
        Br[col[findex[i]]] = mu[i];
        Br[nn + k] = -1;
        Br[nn + nf + k] = -1;
        qb[nn + 2 * nf + k] = 0;
    }
    int rc = SC_ENOSOLUTION;
    for (int v = 0; v < LEMKE_COVERS && rc != SC_OK; v++) {
        wk->covers += v > 0;
        for (int k = 0; k < N; k++)
            d[k] = cover(v, k, nn, nf);
        rc = sc_lcp_lemke(N, B, qb, d, x, wk->s.pivots + LCP_MAX_PIVOTS(N), &wk->s.pivots);
        if (rc == SC_ENOMEM)
            break;
        if (rc == SC_OK) {
            for (int i = 0; i < n; i++)
                z[i] = findex[i] >= 0 ? x[col[i]] - x[col[i] + nf] : x[col[i]];
            if (!verify_coupled(wk, q, lo, hi, findex, mu, z, w, residual, 0))
                rc = SC_ENUMERIC;
        }
    }
    free(mem);
    return rc;
}

/* Friction from a guess when the fixed point and Lemke's method both
 * failed (the bin: stick-slip on islands of 4-8 contacts, the fixed point
 * cycling and Lemke ending on a secondary ray or failing verification).
 * Projected Gauss-Seidel on the coupled problem (row by row z_i =
 * clamp(z_i - omega w_i / M_ii) into its bounds, friction rows' from the
 * current normals) moves towards the answer, if slowly on the
 * ill-conditioned ones; the fixed point started from its iterate
 * (pivot_guess() takes the active set it points at) then finds the exact
 * answer, which is verified like any other. Two iterates go side by side,
 * plain (omega 1) and over-relaxed (LCP_GUESS_SOR): each solves LCPs the
 * other does not (docs/DESIGN.md 11). Tried after 10, 100, 1000 and 10000
 * sweeps, plain first; each try is a whole fixed point, so a start that
 * points at the wrong sets costs rounds, never the answer. A row with
 * M_ii <= 0 moves nothing and is left at 0. */
#define LCP_GUESS_TRIES 4
#define LCP_GUESS_SOR 1.6
static void pgs_sweep(int n, const double *M, const double *q, const double *lo,
                      const double *hi, const int *findex, const double *mu, double omega,
                      double *z)
{
    for (int i = 0; i < n; i++) {
        double d = M[(size_t)i * n + i];
        if (!(d > 0))
            continue;
        double b = findex[i] >= 0 ? mu[i] * fabs(z[findex[i]]) : 0;
        double l = findex[i] >= 0 ? -b : lo[i], h = findex[i] >= 0 ? b : hi[i];
        double wi = q[i] + row_dot(M, z, n, i);
        z[i] = min_d(max_d(z[i] - omega * wi / d, l), h);
    }
}

static int friction_guess(work *wk, const double *q, const double *lo, const double *hi,
                          const int *findex, const double *mu, double *z, double *w,
                          double *residual)
{
    const int n = wk->s.n;
    const double *M = wk->s.M;
    double *zg[2] = { wk->zpgs, wk->zsor };
    const double omega[2] = { 1.0, LCP_GUESS_SOR };
    memset(zg[0], 0, (size_t)n * sizeof *zg[0]);
    memset(zg[1], 0, (size_t)n * sizeof *zg[1]);
    long sweeps = 0, until = 10;
    int rc = SC_EMAXITER;
    for (int t = 0; t < LCP_GUESS_TRIES; t++, until *= 10) {
        for (; sweeps < until; sweeps++)
            for (int k = 0; k < 2; k++)
                pgs_sweep(n, M, q, lo, hi, findex, mu, omega[k], zg[k]);
        for (int k = 0; k < 2; k++) {
            if (!all_finite(zg[k], (size_t)n))
                continue;
            memcpy(z, zg[k], (size_t)n * sizeof *z);
            rc = solve_friction(wk, q, lo, hi, findex, mu, START_GUESS, 0, z, w, residual);
            if (rc == SC_OK || rc == SC_ENOMEM)
                return rc;
        }
    }
    return rc;
}

/* What boxed() tries where friction's fixed point does not settle. */
enum {
    MORE_LEMKE = 1,           /* Lemke's method (friction_lemke()) */
    MORE_GUESS = 2            /* then the rounds from a guess (friction_guess()) */
};

static int boxed(sc_arena *arena, int n, const double *M, const double *q, const double *lo,
                 const double *hi, const int *findex, const double *mu, int start, int more,
                 double *z, double *w, sc_lcp_info *info)
{
    if (info) {
        info->pivots = 0;
        info->residual = 0;
    }
    if (n < 0 || (n > 0 && (!M || !q || !lo || !hi || !z || !w)))
        return SC_EINVAL;
    if (n == 0)
        return SC_OK;
    int friction = 0;
    for (int i = 0; findex && i < n; i++)
        friction |= findex[i] >= 0;
    if ((friction && !mu) || !all_finite(q, (size_t)n) ||   /* M: work_init() */
        !boxed_args_ok(n, lo, hi, friction ? findex : NULL, mu))
        return SC_EINVAL;
    work wk;
    int rc = work_init(arena, &wk, n, M, friction);
    if (rc != SC_OK)
        return rc;
    double residual;
    int lemke = 0, guessed = 0;
    if (friction) {
        /* the rounds alone (nothing after them) are damped */
        rc = solve_friction(&wk, q, lo, hi, findex, mu, start, more == 0, z, w, &residual);
        int failed = rc == SC_EMAXITER || rc == SC_ENUMERIC || rc == SC_ENOSOLUTION;
        if ((more & MORE_LEMKE) && failed) {
            int lr = friction_lemke(&wk, q, lo, hi, findex, mu, z, w, &residual);
            if (lr != SC_EINVAL) {
                rc = lr;
                lemke = 1;
            }
            failed = rc == SC_EMAXITER || rc == SC_ENUMERIC || rc == SC_ENOSOLUTION;
            if ((more & MORE_GUESS) && failed) {
                int gr = friction_guess(&wk, q, lo, hi, findex, mu, z, w, &residual);
                guessed = gr == SC_OK;
                if (guessed || gr == SC_ENOMEM)
                    rc = gr;
            }
        }
    } else {
        rc = solve_fixed(&wk, q, lo, hi, start, z, w, &residual);
    }
    report(info, &wk, residual);
    if (info) {
        info->lemke = lemke;    /* counted by the callers */
        info->guessed = guessed;
    }
    work_free(arena, &wk);
    return rc;
}

int sc_lcp_boxed_in(sc_arena *arena, int n, const double *M, const double *q,
                    const double *lo, const double *hi, const int *findex, const double *mu,
                    double *z, double *w, sc_lcp_info *info)
{
    return boxed(arena, n, M, q, lo, hi, findex, mu, START_COLD, MORE_LEMKE | MORE_GUESS, z, w,
                 info);
}

int sc_lcp_boxed_warm_in(sc_arena *arena, int n, const double *M, const double *q,
                         const double *lo, const double *hi, const int *findex,
                         const double *mu, double *z, double *w, sc_lcp_info *info)
{
    return boxed(arena, n, M, q, lo, hi, findex, mu, START_GUESS, MORE_LEMKE | MORE_GUESS, z, w,
                 info);
}

int sc_lcp_boxed_rounds_in(sc_arena *arena, int n, const double *M, const double *q,
                           const double *lo, const double *hi, const int *findex,
                           const double *mu, double *z, double *w, sc_lcp_info *info)
{
    return boxed(arena, n, M, q, lo, hi, findex, mu, START_GUESS, 0, z, w, info);
}

/* The retries of sc_lcp_raised_in(): shares of the largest diagonal
 * entry, from the least (which changes the problem least) up, since the
 * least share that solves differs from problem to problem. The first tries
 * are quick, without friction_guess() (up to 2 x 10^4 sweeps), which is
 * run only at the last share: on every try it would cost more than it
 * saves (docs/DESIGN.md 11). */
static const struct {
    double share;
    int quick;
} RAISE[] = { { 1e-9, 1 }, { 1e-8, 1 }, { 1e-6, 1 }, { 1e-4, 1 }, { 1e-4, 0 } };

int sc_lcp_raised_in(sc_arena *arena, int n, double *M, const double *q, const double *lo,
                     const double *hi, const int *findex, const double *mu, double *z,
                     double *w, sc_lcp_info *info, double *share)
{
    sc_lcp_info sum = { 0 }, li = { 0 };
    *share = 0;
    double dmax = 0;
    for (int i = 0; M && i < n; i++)
        dmax = max_d(dmax, M[(size_t)i * n + i]);
    int rc = SC_EMAXITER;
    double raised = 0;
    for (size_t k = 0; k < sizeof RAISE / sizeof *RAISE; k++) {
        int quick = RAISE[k].quick && lo;
        if (RAISE[k].share == raised && (!findex || quick))
            continue;     /* the same problem and the same tries */
        double add = k == 0 ? RAISE[0].share * dmax + 1e-300 : (RAISE[k].share - raised) * dmax;
        for (int i = 0; M && add > 0 && i < n; i++)
            M[(size_t)i * n + i] += add;
        raised = RAISE[k].share;
        rc = lo ? boxed(arena, n, M, q, lo, hi, findex, mu, START_COLD,
                          MORE_LEMKE | (quick ? 0 : MORE_GUESS), z, w, &li)
                : dantzig(arena, n, M, q, START_COLD, z, w, &li);
        sum.pivots += li.pivots;
        sum.lemke += li.lemke;
        sum.covers += li.covers;
        sum.guessed += li.guessed;
        sum.residual = li.residual;
        if (rc == SC_OK)
            *share = raised;
        if (rc == SC_OK || rc == SC_EINVAL || rc == SC_ENOMEM)
            break;
    }
    if (info)
        *info = sum;
    return rc;
}

int sc_lcp_boxed(int n, const double *M, const double *q, const double *lo,
                 const double *hi, const int *findex, const double *mu,
                 double *z, double *w, sc_lcp_info *info)
{
    return sc_lcp_boxed_in(NULL, n, M, q, lo, hi, findex, mu, z, w, info);
}
