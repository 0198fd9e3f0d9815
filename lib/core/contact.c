/* contact.c - contact impulses for one island (the paper's step 7).
 *
 * Baraff's velocity-level formulation: for contact i with pre-impact normal
 * speed v_i (negative when approaching) the impulses p solve
 *     w = A p + J u* + e_i min(v_i, 0) >= 0,  p >= 0,  p.w = 0
 * where u* is the velocity after external forces, A = J W J^T (W the
 * inverse mass matrix) and e_i the restitution for a collision (approach
 * faster than bounce_speed) or 0 for a resting contact (the paper's contact
 * state). Coulomb friction adds two tangent rows per contact bounded by
 * +-mu p_n (a boxed LCP, findex as in ODE). Both go to our Dantzig solver.
 *
 * Resting contacts keep a small penetration; deeper ones are pushed out by
 * a second, normal-only LCP on pseudo velocities (split impulse): positions
 * move, velocities do not, so the correction adds no kinetic energy.
 */
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "lcp.h"
#include "vecmath.h"

typedef struct row {
    int a, b;                 /* body indices (static or asleep: W = 0) */
    double ja[6], jb[6];      /* Jacobian: linear, angular */
    double wa[6], wb[6];      /* W J^T per body */
} row;

static int movable(const sc_body *b)
{
    return b->inv_mass > 0 && b->state != SC_ASLEEP;
}

static void row_body(const sc_body *b, const double r[3], const double d[3], double sign,
                     double j[6], double wj[6])
{
    double rxd[3];
    v3_cross(rxd, r, d);
    v3_scale(j, d, sign);
    v3_scale(j + 3, rxd, sign);
    if (movable(b)) {
        v3_scale(wj, j, b->inv_mass);
        m3_mulv(wj + 3, b->iw, j + 3);
    } else {
        memset(wj, 0, 6 * sizeof *wj);
    }
}

static void make_row(row *rw, const sc_body *bodies, const sc_contact *c, const double d[3])
{
    const sc_body *A = &bodies[c->body_a], *B = &bodies[c->body_b];
    double ra[3], rb[3];
    v3_sub(ra, c->pos, A->x);
    v3_sub(rb, c->pos, B->x);
    rw->a = c->body_a;
    rw->b = c->body_b;
    row_body(A, ra, d, -1.0, rw->ja, rw->wa);
    row_body(B, rb, d, +1.0, rw->jb, rw->wb);
}

static double dot6(const double *x, const double *y)
{
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2] + x[3] * y[3] + x[4] * y[4] + x[5] * y[5];
}

/* J u for a row, u being each body's current (v, w) or (v0, w0). */
static double row_speed(const row *rw, const sc_body *bodies, int pre)
{
    const sc_body *A = &bodies[rw->a], *B = &bodies[rw->b];
    double ua[6], ub[6];
    memcpy(ua, pre ? A->v0 : A->v, 3 * sizeof(double));
    memcpy(ua + 3, pre ? A->w0 : A->w, 3 * sizeof(double));
    memcpy(ub, pre ? B->v0 : B->v, 3 * sizeof(double));
    memcpy(ub + 3, pre ? B->w0 : B->w, 3 * sizeof(double));
    return dot6(rw->ja, ua) + dot6(rw->jb, ub);
}

/* A = J W J^T over the given rows (dense, symmetric), plus a compliance
 * of 1e-6 of its largest diagonal entry on the diagonal: several contacts
 * on one face make A singular and the split of the load among them
 * arbitrary (a basic solution loads three corners of a box, not four, and
 * friction then twists it); the tiny compliance makes the solution unique
 * and symmetric, at the cost of 1e-6 relative softness. */
#define COMPLIANCE 1e-6

static void build_a(const row *rows, const int *sel, int n, double *A)
{
    for (int i = 0; i < n; i++) {
        const row *r = &rows[sel ? sel[i] : i];
        for (int k = i; k < n; k++) {
            const row *s = &rows[sel ? sel[k] : k];
            double v = 0;
            if (r->a == s->a) v += dot6(r->ja, s->wa);
            if (r->a == s->b) v += dot6(r->ja, s->wb);
            if (r->b == s->a) v += dot6(r->jb, s->wa);
            if (r->b == s->b) v += dot6(r->jb, s->wb);
            A[i * n + k] = A[k * n + i] = v;
        }
    }
    double dmax = 0;
    for (int i = 0; i < n; i++)
        dmax = fmax(dmax, A[i * n + i]);
    for (int i = 0; i < n; i++)
        A[i * n + i] += COMPLIANCE * dmax;
}

/* Solve, and on failure retry once with the diagonal raised by 1e-9 of its
 * largest entry (redundant contacts make A singular); counted, never hidden. */
static int solve(sc_arena *a, int n, double *A, const double *q, const double *lo,
                 const double *hi, const int *findex, const double *mu, double *z, double *w,
                 sc_solve_info *info)
{
    sc_lcp_info li = { 0 };
    int rc = lo ? sc_lcp_boxed_in(a, n, A, q, lo, hi, findex, mu, z, w, &li)
                : sc_lcp_dantzig_in(a, n, A, q, z, w, &li);
    info->pivots += li.pivots;
    info->lemke += li.lemke;
    if (rc == SC_OK || rc == SC_EINVAL || rc == SC_ENOMEM)
        return rc;
    double dmax = 0;
    for (int i = 0; i < n; i++)
        dmax = fmax(dmax, A[i * n + i]);
    for (int i = 0; i < n; i++)
        A[i * n + i] += 1e-9 * dmax + 1e-300;
    rc = lo ? sc_lcp_boxed_in(a, n, A, q, lo, hi, findex, mu, z, w, &li)
            : sc_lcp_dantzig_in(a, n, A, q, z, w, &li);
    info->pivots += li.pivots;
    if (rc == SC_OK)
        info->regularised++;
    return rc;
}

static void apply(const row *rw, double z, sc_body *bodies, int pseudo, double h)
{
    sc_body *body[2] = { &bodies[rw->a], &bodies[rw->b] };
    const double *wj[2] = { rw->wa, rw->wb };
    for (int k = 0; k < 2; k++) {
        sc_body *b = body[k];
        if (!movable(b) || z == 0)
            continue;
        if (!pseudo) {
            v3_madd(b->v, b->v, wj[k], z);
            v3_madd(b->w, b->w, wj[k] + 3, z);
        } else {
            /* move by h times the pseudo velocity */
            v3_madd(b->x, b->x, wj[k], z * h);
            double dw[3];
            v3_scale(dw, wj[k] + 3, z * h);
            double wq[4] = { 0, dw[0], dw[1], dw[2] }, dq[4];
            q_mul(dq, wq, b->q);
            for (int i = 0; i < 4; i++)
                b->q[i] += 0.5 * dq[i];
            q_normalize(b->q);
        }
    }
}

/* Tangent directions: t1 along the sliding velocity when the contact
 * slides, so that the friction pyramid's edge opposes the motion exactly
 * (as ODE's fdir1); otherwise a fixed rule, the axis least aligned with n. */
/* The staggered fallback (see sc_island_solve): rows[nsel[k]] are the
 * normals; scratch holds 6 n doubles, the first n the rows' q; sel room
 * for n ints. */
static int staggered(sc_arena *arena, const row *rows, int nrows, const int *nsel, int nn,
                     const int *findex, const double *mu, sc_body *bodies, double *A,
                     double *scratch, int *sel, sc_solve_info *info)
{
    size_t n = (size_t)nrows;
    double *q = scratch, *lo = scratch + n, *hi = scratch + 2 * n, *z = scratch + 3 * n,
           *w = scratch + 4 * n, *zrow = scratch + 5 * n;
    build_a(rows, nsel, nn, A);
    for (int k = 0; k < nn; k++)
        q[k] = q[nsel[k]];       /* the normals' q, restitution included; nsel[k] >= k */
    int rc = solve(arena, nn, A, q, NULL, NULL, NULL, NULL, z, w, info);
    if (rc != SC_OK)
        return rc;
    for (int i = 0; i < nrows; i++)
        zrow[i] = 0;
    for (int k = 0; k < nn; k++) {
        zrow[nsel[k]] = z[k];
        apply(&rows[nsel[k]], z[k], bodies, 0, 0);
    }
    /* tangents, bounds fixed by the normal impulses just applied */
    int nt = nrows - nn;
    if (nt == 0)
        return SC_OK;
    nt = 0;
    for (int i = 0; i < nrows; i++)
        if (findex[i] >= 0)
            sel[nt++] = i;
    build_a(rows, sel, nt, A);
    for (int k = 0; k < nt; k++) {
        int r = sel[k];
        q[k] = row_speed(&rows[r], bodies, 0);
        hi[k] = mu[r] * zrow[findex[r]];
        lo[k] = -hi[k];
    }
    rc = solve(arena, nt, A, q, lo, hi, NULL, NULL, z, w, info);
    if (rc == SC_OK)
        for (int k = 0; k < nt; k++)
            apply(&rows[sel[k]], z[k], bodies, 0, 0);
    return rc;
}

static void tangents(const sc_body *bodies, const sc_contact *c, double t1[3], double t2[3])
{
    const double *n = c->normal;
    const sc_body *A = &bodies[c->body_a], *B = &bodies[c->body_b];
    double ra[3], rb[3], va[3], vb[3], vr[3];
    v3_sub(ra, c->pos, A->x);
    v3_sub(rb, c->pos, B->x);
    v3_cross(va, A->w, ra);
    v3_add(va, va, A->v);
    v3_cross(vb, B->w, rb);
    v3_add(vb, vb, B->v);
    v3_sub(vr, vb, va);
    v3_madd(vr, vr, n, -v3_dot(vr, n));
    if (v3_len(vr) > 1e-6) {
        v3_scale(t1, vr, 1.0 / v3_len(vr));
        v3_cross(t2, n, t1);
        return;
    }
    double e[3] = { 0, 0, 0 };
    int k = fabs(n[0]) < fabs(n[1]) ? (fabs(n[0]) < fabs(n[2]) ? 0 : 2)
                                    : (fabs(n[1]) < fabs(n[2]) ? 1 : 2);
    e[k] = 1;
    v3_cross(t1, n, e);
    v3_normalize(t1);
    v3_cross(t2, n, t1);
}

int sc_island_solve(sc_arena *arena, sc_body *bodies, const sc_contact *c, const int *ci, int nc,
                    double h, const sc_contact_params *p, sc_solve_info *info)
{
    if (nc == 0)
        return SC_OK;
    /* rows: normal, then two tangents where there is friction */
    int nrows = 0;
    for (int k = 0; k < nc; k++) {
        const sc_contact *ck = &c[ci[k]];
        double mu = sqrt(bodies[ck->body_a].friction * bodies[ck->body_b].friction);
        nrows += mu > 0 ? 3 : 1;
        if (nrows > SC_MAX_ISLAND_ROWS)
            return SC_ETOOMANY;    /* not a misleading out-of-memory later */
    }
    size_t n = (size_t)nrows;
    /* per island, from the thread's arena: no allocation once it has
     * grown to the largest island */
    if (n > SIZE_MAX / sizeof(double) / n)
        return SC_ETOOBIG;
    row *rows = sc_arena_alloc(arena, n * sizeof *rows);
    double *A = rows ? sc_arena_alloc(arena, n * n * sizeof *A) : NULL;
    double *buf = A ? sc_arena_alloc(arena, n * 6 * sizeof *buf) : NULL;
    int *findex = buf ? sc_arena_alloc(arena, n * sizeof *findex) : NULL;
    int *nsel = findex ? sc_arena_alloc(arena, n * sizeof *nsel) : NULL;
    int *sel = nsel ? sc_arena_alloc(arena, n * sizeof *sel) : NULL;
    int rc = SC_ENOMEM;
    if (!sel)
        goto out;
    double *q = buf, *lo = buf + n, *hi = buf + 2 * n, *mu = buf + 3 * n, *z = buf + 4 * n,
           *w = buf + 5 * n;
    int r = 0, nn = 0, friction = 0;
    for (int k = 0; k < nc; k++) {
        const sc_contact *ck = &c[ci[k]];
        const sc_body *A_ = &bodies[ck->body_a], *B_ = &bodies[ck->body_b];
        double e = fmax(A_->restitution, B_->restitution);
        double m = sqrt(A_->friction * B_->friction);
        int rn = r;
        make_row(&rows[r], bodies, ck, ck->normal);
        double vpre = row_speed(&rows[r], bodies, 1);
        int collide = vpre < -p->bounce_speed;
        info->collisions += collide;
        /* only movable bodies are written: static and sleeping ones are
         * shared by islands solved concurrently */
        if (collide && movable(A_))
            bodies[ck->body_a].collided = 2;
        if (collide && movable(B_))
            bodies[ck->body_b].collided = 2;
        /* a collision is an impulse at the start of the substep, before the
         * external forces act: target J u' = -e v_pre + (J u* - J u0), so
         * w = A p + (1 + e) v_pre. A resting contact absorbs the forces. */
        q[r] = collide ? (1 + e) * vpre : row_speed(&rows[r], bodies, 0);
        lo[r] = 0;
        hi[r] = INFINITY;
        findex[r] = -1;
        mu[r] = 0;
        nsel[nn++] = r;
        r++;
        if (m > 0) {
            double t[2][3];
            tangents(bodies, ck, t[0], t[1]);
            for (int j = 0; j < 2; j++, r++) {
                make_row(&rows[r], bodies, ck, t[j]);
                q[r] = row_speed(&rows[r], bodies, 0);
                lo[r] = -INFINITY;
                hi[r] = INFINITY;
                findex[r] = rn;
                mu[r] = m;
            }
            friction = 1;
        }
    }
    build_a(rows, NULL, nrows, A);
    rc = solve(arena, nrows, A, q, lo, hi, friction ? findex : NULL, mu, z, w, info);
    if (rc != SC_OK && friction && rc != SC_ENOMEM && rc != SC_EINVAL) {
        /* The friction fixed point can fail (pivot limit, ill-conditioned
         * near-duplicate rows). Then stagger: normals alone (a PSD LCP the
         * pivoting solves), then the tangents as a boxed LCP with the bounds
         * fixed at +-mu p_n. Exact for each half, the coupling of friction
         * back into the normals is lost for this substep: counted in
         * sc_stats.lcp_fallbacks, never silent. */
        info->failures++;
        rc = staggered(arena, rows, nrows, nsel, nn, findex, mu, bodies, A, buf, sel, info);
    } else if (rc == SC_OK) {
        for (int i = 0; i < nrows; i++)
            apply(&rows[i], z[i], bodies, 0, h);
    }
    if (rc != SC_OK)
        goto out;

    /* split impulse: push deep contacts out by pseudo velocities */
    int deep = 0;
    for (int k = 0; k < nc; k++)
        deep |= c[ci[k]].depth > p->slop;
    if (!deep)
        goto out;
    build_a(rows, nsel, nn, A);
    for (int k = 0; k < nn; k++)
        q[k] = -p->baumgarte * fmax(c[ci[k]].depth - p->slop, 0.0) / h;
    rc = solve(arena, nn, A, q, NULL, NULL, NULL, NULL, z, w, info);
    if (rc != SC_OK)
        goto out;
    for (int k = 0; k < nn; k++)
        apply(&rows[nsel[k]], z[k], bodies, 1, h);
out:
    sc_arena_free(arena, sel);
    sc_arena_free(arena, nsel);
    sc_arena_free(arena, findex);
    sc_arena_free(arena, buf);
    sc_arena_free(arena, A);
    sc_arena_free(arena, rows);
    return rc;
}
