/* contact.c - contact impulses for one island (the paper's step 7;
 * docs/DESIGN.md 3.5 and 11).
 *
 * Baraff's velocity-level LCP with restitution and Coulomb friction (a
 * boxed LCP), one exact Dantzig solve for a small island and block
 * Gauss-Seidel for a pile (each block's normals exact, its friction by
 * passes over its rows); no island fails for numerical
 * reasons, and every fallback is counted (sc_solve_info). Deeper contacts
 * are pushed out by a normal-only LCP on pseudo velocities (split
 * impulse), which moves positions and adds no kinetic energy. */
#include <stdlib.h>
#include <string.h>

#include "contact_rows.h"
#include "lcp.h"
#include "vecmath.h"

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
    rw->la = rw->lb = -1;
    rw->ma = (unsigned char)movable(A);
    rw->mb = (unsigned char)movable(B);
    row_body(A, ra, d, -1.0, rw->ja, rw->wa);
    row_body(B, rb, d, +1.0, rw->jb, rw->wb);
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

static void build_a(const row *rows, const int *sel, int n, double *A)
{
    for (int i = 0; i < n; i++) {
        const row *r = &rows[sel ? sel[i] : i];
        for (int k = i; k < n; k++)
            A[i * n + k] = A[k * n + i] = a_entry(r, &rows[sel ? sel[k] : k]);
    }
    double dmax = 0;
    for (int i = 0; i < n; i++)
        dmax = max_d(dmax, A[i * n + i]);
    for (int i = 0; i < n; i++)
        A[i * n + i] += COMPLIANCE * dmax;
}

enum {
    SOLVE_WARM = 1,           /* z holds a guess to start from */
    SOLVE_FAIL = 2,           /* a test's injected fault: fail without a solve */
};

static int lcp_call(sc_arena *a, int n, double *A, const double *q, const double *lo,
                    const double *hi, const int *findex, const double *mu, double *z,
                    double *w, sc_lcp_info *li, int warm)
{
    if (warm)
        return lo ? sc_lcp_boxed_warm_in(a, n, A, q, lo, hi, findex, mu, z, w, li)
                  : sc_lcp_dantzig_warm_in(a, n, A, q, z, w, li);
    return lo ? sc_lcp_boxed_in(a, n, A, q, lo, hi, findex, mu, z, w, li)
              : sc_lcp_dantzig_in(a, n, A, q, z, w, li);
}

/* An LCP call's counters (and, solved, its residual) into info. */
static void lcp_info_add(sc_solve_info *info, const sc_lcp_info *li, int rc)
{
    info->pivots += li->pivots;
    info->lemke += li->lemke;
    info->guessed += li->guessed;
    if (rc == SC_OK)
        info->residual_exact = max_d(info->residual_exact, li->residual);
}

/* Solve, and on failure retry with the diagonal raised
 * (sc_lcp_raised_in(): redundant or near-redundant contacts make A
 * singular or ill-conditioned); counted, never hidden. flags: SOLVE_*. */
static int solve(sc_arena *a, int n, double *A, const double *q, const double *lo,
                 const double *hi, const int *findex, const double *mu, double *z, double *w,
                 sc_solve_info *info, int flags)
{
    if (flags & SOLVE_FAIL)
        return SC_EMAXITER;
    int warm = (flags & SOLVE_WARM) != 0;
    sc_lcp_info li = { 0 };
    int rc = lcp_call(a, n, A, q, lo, hi, findex, mu, z, w, &li, warm);
    lcp_info_add(info, &li, rc);
    if (rc == SC_OK || rc == SC_EINVAL || rc == SC_ENOMEM)
        return rc;
    double share;
    rc = sc_lcp_raised_in(a, n, A, q, lo, hi, findex, mu, z, w, &li, &share);
    lcp_info_add(info, &li, rc);
    info->regularised += rc == SC_OK;
    return rc;
}

/* Whether a coupled friction answer z adds kinetic energy, and whose. With
 * row speeds s = q - off (J u*) and w = A z + q, applying z changes the
 * kinetic energy by z.s + z.A z / 2 = (z.w - z.A z / 2) - z.off. ds (NULL:
 * none) moves a row's speed to where its impulse acts: a collision's is
 * taken at its impact (J u0 at the substep's start, the approach at the
 * touch for a held one), not at J u* = s, which already holds the
 * forces' pull of the whole substep (sc_island_solve() gives it for a
 * perfectly elastic island only; docs/DESIGN.md 9, elastic boxes). The
 * first part is the answer's own and is never positive for an exact one:
 * z.w = 0 on normals and free friction rows, and a friction row at its
 * bound opposes its sliding (z_t w_t <= 0); a positive one is rounding
 * grown large (a bolt wedged in a nut: 550 N s of squeeze and 16 m/s out),
 * not physics: ENERGY_OWN. The second is the targets': Newton's
 * restitution at several contacts at once can add energy (ENERGY_TARGETS).
 * A normal-only or a boxed LCP answer adds none of its own. */
enum { ENERGY_NONE, ENERGY_TARGETS, ENERGY_OWN };
static int adds_energy(const double *A, int n, const double *q, const double *off,
                       const double *ds, const double *z)
{
    double zw = 0, quad = 0, zoff = 0;
    for (int i = 0; i < n; i++) {
        if (z[i] == 0)
            continue;
        double az = 0;
        for (int j = 0; j < n; j++)
            az += A[i * n + j] * z[j];
        zw += z[i] * (az + q[i]);
        quad += 0.5 * z[i] * az;
        zoff += z[i] * (ds ? off[i] + ds[i] : off[i]);
    }
    if (zw - quad > 1e-6 * (fabs(zw) + quad) + 1e-12)
        return ENERGY_OWN;
    double lin = zw - 2 * quad - zoff;    /* z.s */
    return lin + quad > 1e-6 * (fabs(lin) + quad) + 1e-12 ? ENERGY_TARGETS : ENERGY_NONE;
}

/* An answer whose restitution targets add energy: solved again with the
 * targets (the negative offsets, -e times an approach) scaled down until
 * it adds none. Keeps the coupling of friction and normals that the
 * staggered fallback loses. With e < 1 (keep 0) the shares 1/2, 1/4 and
 * 0 are tried in turn: the collision loses energy, as such a collision
 * does. A perfectly elastic island (keep 1: every collision's e is 1)
 * takes the largest share that adds none, by bisection
 * (RESTITUTION_HALVINGS) between none (the velocity LCP is then a
 * projection and never adds) and all, so that it keeps its energy as
 * nearly as it can (the fixed shares alone lose much of it;
 * docs/DESIGN.md 3.4). q, off, z, w: the island's (z and w get the new
 * answer); ENERGY_NONE when one was found. */
#define RESTITUTION_HALVINGS 8
typedef struct bounce_try {
    sc_arena *arena;
    int n;
    double *A;
    const double *q, *off, *lo, *hi, *mu;
    const int *findex;
    double *q2, *off2;
    const double *ds;
    sc_solve_info *info;
} bounce_try;

/* The answer with the restitution targets scaled by s, into z and w: its
 * energy kind (ENERGY_OWN when the solve failed). */
static int bounce_share(const bounce_try *b, double s, double *z, double *w)
{
    for (int i = 0; i < b->n; i++) {
        b->off2[i] = b->off[i] < 0 ? s * b->off[i] : b->off[i];
        b->q2[i] = b->q[i] - b->off[i] + b->off2[i];
    }
    int rc = solve(b->arena, b->n, b->A, b->q2, b->lo, b->hi, b->findex, b->mu, z, w, b->info, 0);
    return rc == SC_OK ? adds_energy(b->A, b->n, b->q2, b->off2, b->ds, z) : ENERGY_OWN;
}

static int scale_restitution(sc_arena *arena, int n, double *A, const double *q,
                             const double *off, const double *ds, const double *lo,
                             const double *hi, const int *findex, const double *mu, double *z,
                             double *w, int keep, sc_solve_info *info)
{
    static const double ladder[] = { 0.5, 0.25, 0 };
    double *q2 = sc_arena_alloc(arena, 4 * (size_t)n * sizeof *q2);
    if (!q2)
        return ENERGY_TARGETS;
    bounce_try b = { .arena = arena, .n = n, .A = A, .q = q, .off = off, .lo = lo, .hi = hi,
                     .mu = mu, .findex = findex, .q2 = q2, .off2 = q2 + n, .ds = ds,
                     .info = info };
    double *zb = q2 + 2 * n, *wb = q2 + 3 * n;
    int kind = ENERGY_TARGETS;
    if (!keep) {
        for (size_t t = 0; t < sizeof ladder / sizeof *ladder && kind == ENERGY_TARGETS; t++)
            kind = bounce_share(&b, ladder[t], z, w);
    } else {
        double ok = 0, bad = 1;
        int found = 0;
        for (int t = 0; t < RESTITUTION_HALVINGS; t++) {
            double s = 0.5 * (ok + bad);
            if (bounce_share(&b, s, z, w) == ENERGY_NONE) {
                ok = s;
                found = 1;
                memcpy(zb, z, (size_t)n * sizeof *z);
                memcpy(wb, w, (size_t)n * sizeof *w);
            } else {
                bad = s;
            }
        }
        if (found) {
            memcpy(z, zb, (size_t)n * sizeof *z);
            memcpy(w, wb, (size_t)n * sizeof *w);
            kind = ENERGY_NONE;
        } else {
            kind = bounce_share(&b, 0, z, w);
        }
    }
    sc_arena_free(arena, q2);
    return kind;
}

/* Move a movable body by h times a pseudo velocity (6: linear, angular). */
static void move_body(sc_body *b, const double u[6], double h)
{
    v3_madd(b->x, b->x, u, h);
    double dw[3];
    v3_scale(dw, u + 3, h);
    double wq[4] = { 0, dw[0], dw[1], dw[2] }, dq[4];
    q_mul(dq, wq, b->q);
    for (int i = 0; i < 4; i++)
        b->q[i] += 0.5 * dq[i];
    q_normalize(b->q);
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
            double u[6];
            for (int i = 0; i < 6; i++)
                u[i] = wj[k][i] * z;
            move_body(b, u, h);
        }
    }
}

/* The staggered fallback (see sc_island_solve): rows[nsel[k]] are the
 * normals; scratch holds 6 n doubles, the first n the rows' q; sel room
 * for n ints. The impulses applied are left in zrow (scratch + 5 n). */
static int staggered(sc_arena *arena, const row *rows, int nrows, const int *nsel, int nn,
                     const int *findex, const double *mu, sc_body *bodies, double *A,
                     double *scratch, int *sel, sc_solve_info *info, int fail)
{
    size_t n = (size_t)nrows;
    double *q = scratch, *lo = scratch + n, *hi = scratch + 2 * n, *z = scratch + 3 * n,
           *w = scratch + 4 * n, *zrow = scratch + 5 * n;
    build_a(rows, nsel, nn, A);
    for (int k = 0; k < nn; k++)
        q[k] = q[nsel[k]];       /* the normals' q, restitution included; nsel[k] >= k */
    int rc = solve(arena, nn, A, q, NULL, NULL, NULL, NULL, z, w, info, fail ? SOLVE_FAIL : 0);
    if (rc != SC_OK)
        return rc;
    for (int i = 0; i < nrows; i++)
        zrow[i] = 0;
    for (int k = 0; k < nn; k++) {
        zrow[nsel[k]] = z[k];
        apply(&rows[nsel[k]], z[k], bodies, 0, 0);
    }
    /* tangents, bounds fixed by the normal impulses just applied */
    int nt = 0;
    for (int i = 0; i < nrows; i++)
        if (findex[i] >= 0)
            sel[nt++] = i;
    if (nt == 0)
        return SC_OK;
    build_a(rows, sel, nt, A);
    for (int k = 0; k < nt; k++) {
        int r = sel[k];
        q[k] = row_speed(&rows[r], bodies, 0);
        hi[k] = mu[r] * zrow[findex[r]];
        lo[k] = -hi[k];
    }
    rc = solve(arena, nt, A, q, lo, hi, NULL, NULL, z, w, info, 0);
    if (rc == SC_OK)
        for (int k = 0; k < nt; k++) {
            zrow[sel[k]] = z[k];
            apply(&rows[sel[k]], z[k], bodies, 0, 0);
        }
    return rc;
}

/* Tangent directions: t1 along the sliding velocity when the contact
 * slides, so that the friction pyramid's edge opposes the motion exactly
 * (as ODE's fdir1); otherwise a fixed rule, the axis least aligned with n. */
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

/* ---- block Gauss-Seidel (split islands) ------------------------------ */

/* An island's rows as blocks: block k is rows [bstart[k], bstart[k + 1]),
 * whole contacts of whole pairs, its matrix (compliance included) at
 * amat + aoff[k]. */
typedef struct blocks {
    int count;
    int *bstart;
    size_t *aoff;
    double *amat;
    double *diag;             /* A_rr of every row */
    /* colours: no two blocks of one colour share a movable body; a sweep
     * takes colour after colour, block order[cstart[c]] .. order[cstart[c +
     * 1] - 1] of colour c, so that a colour's blocks can be solved at once
     * (docs/DESIGN.md 11, shared blocks); the order is the same for any
     * runner */
    int ncolours;
    int *cstart;              /* count + 1 entries */
    int *order;               /* count entries */
} blocks;

/* Greedy colouring in block order: colour c takes every block not yet
 * coloured whose movable bodies no block of colour c has taken (mark[] is
 * the last colour that took a slot). Static and sleeping bodies are only
 * read, so they do not part blocks. */
static void blocks_colour(const row *rows, blocks *bl, int *colour, int *mark, int nslots)
{
    int nb = bl->count, left = nb, c = 0;
    for (int k = 0; k < nb; k++)
        colour[k] = -1;
    for (int i = 0; i < nslots; i++)
        mark[i] = -1;
    bl->cstart[0] = 0;
    while (left > 0) {
        for (int k = 0; k < nb; k++) {
            if (colour[k] >= 0)
                continue;
            int ok = 1;
            for (int r = bl->bstart[k]; r < bl->bstart[k + 1] && ok; r++)
                ok = !(rows[r].ma && mark[rows[r].la] == c) &&
                     !(rows[r].mb && mark[rows[r].lb] == c);
            if (!ok)
                continue;
            colour[k] = c;
            for (int r = bl->bstart[k]; r < bl->bstart[k + 1]; r++) {
                if (rows[r].ma)
                    mark[rows[r].la] = c;
                if (rows[r].mb)
                    mark[rows[r].lb] = c;
            }
            bl->order[nb - left] = k;
            left--;
        }
        bl->cstart[++c] = nb - left;
    }
    bl->ncolours = c;
}

/* Split rows at pair boundaries into blocks of about per contacts, and
 * colour them; rows of one contact are consecutive, cstart[k] the first
 * row of contact k, nslots the island's local velocity slots. */
static int blocks_build(sc_arena *a, const row *rows, int nrows, const int *cstart, int nc,
                        int per, int nslots, blocks *bl)
{
    memset(bl, 0, sizeof *bl);
    bl->bstart = sc_arena_alloc(a, (size_t)(nc + 1) * sizeof *bl->bstart);
    bl->aoff = bl->bstart ? sc_arena_alloc(a, (size_t)(nc + 1) * sizeof *bl->aoff) : NULL;
    bl->diag = bl->aoff ? sc_arena_alloc(a, (size_t)nrows * sizeof *bl->diag) : NULL;
    bl->cstart = bl->diag ? sc_arena_alloc(a, (size_t)(nc + 1) * sizeof *bl->cstart) : NULL;
    bl->order = bl->cstart ? sc_arena_alloc(a, (size_t)nc * sizeof *bl->order) : NULL;
    if (!bl->order)
        return SC_ENOMEM;
    int nb = 0, inblock = 0;
    size_t total = 0;
    bl->bstart[0] = 0;
    for (int k = 0; k < nc; k++) {
        int r = cstart[k];
        int new_pair = k == 0 || rows[r].a != rows[cstart[k - 1]].a ||
                       rows[r].b != rows[cstart[k - 1]].b;
        if (k > 0 && new_pair && inblock >= per) {
            int len = r - bl->bstart[nb];
            bl->aoff[nb] = total;
            total += (size_t)len * (size_t)len;
            bl->bstart[++nb] = r;
            inblock = 0;
        }
        inblock++;
    }
    int len = nrows - bl->bstart[nb];
    bl->aoff[nb] = total;
    total += (size_t)len * (size_t)len;
    bl->bstart[++nb] = nrows;
    bl->count = nb;
    int *colour = sc_arena_alloc(a, (size_t)nb * sizeof *colour);
    int *mark = colour ? sc_arena_alloc(a, (size_t)(nslots > 0 ? nslots : 1) * sizeof *mark) : NULL;
    if (mark)
        blocks_colour(rows, bl, colour, mark, nslots);
    sc_arena_free(a, mark);
    sc_arena_free(a, colour);
    if (!mark)
        return SC_ENOMEM;
    bl->amat = sc_arena_alloc(a, total * sizeof *bl->amat);
    if (!bl->amat)
        return SC_ENOMEM;
    for (int k = 0; k < nb; k++) {
        int r0 = bl->bstart[k], m = bl->bstart[k + 1] - r0;
        double *A = bl->amat + bl->aoff[k];
        build_a(rows + r0, NULL, m, A);
        for (int i = 0; i < m; i++)
            bl->diag[r0 + i] = A[i * m + i];
    }
    return SC_OK;
}

static void blocks_free(sc_arena *a, blocks *bl)
{
    sc_arena_free(a, bl->amat);
    sc_arena_free(a, bl->order);
    sc_arena_free(a, bl->cstart);
    sc_arena_free(a, bl->diag);
    sc_arena_free(a, bl->aoff);
    sc_arena_free(a, bl->bstart);
}

/* Projected Gauss-Seidel on one block (the fallback when its Dantzig solve
 * fails): z clamped row by row into its bounds, always finite. */
#define PGS_ITER 30

/* Row r's own answer given the others, clamp(z - w / A_rr, lo, hi), in
 * *zn; 0 for a row without a pivot (A_rr = 0: it moves nothing). */
static int row_project(const gs_problem *pb, const blocks *bl, const double *z,
                       const double *u, int r, double *zn)
{
    double d = bl->diag[r];
    if (!(d > 0))
        return 0;
    double lo, hi;
    row_bounds(pb, z, r, &lo, &hi);
    double w = local_speed(&pb->rows[r], u) + pb->off[r];
    *zn = min_d(max_d(z[r] - w / d, lo), hi);
    return 1;
}

/* Row r moved to its own answer given the others (row_project()). */
static void row_step(const gs_problem *pb, const blocks *bl, double *z, double *u, int r)
{
    double zn;
    if (!row_project(pb, bl, z, u, r, &zn))
        return;
    local_apply(&pb->rows[r], zn - z[r], u);
    z[r] = zn;
}

static void block_pgs(const gs_problem *pb, const blocks *bl, int k, double *z, double *u)
{
    int r0 = bl->bstart[k], r1 = bl->bstart[k + 1];
    for (int it = 0; it < PGS_ITER; it++)
        for (int r = r0; r < r1; r++)
            row_step(pb, bl, z, u, r);
}

/* Rows [r0, r0 + m) of pb as an LCP of their own, the other rows held at
 * z: w = A (zs - z_r) + J_r u + off_r, started from zs = z_r. sub_alloc()
 * takes its data from the arena, the caller fills A (the rows' matrix,
 * compliance included), sub_fill() the rest. */
typedef struct sub_lcp {
    double *A, *buf, *q, *lo, *hi, *mu, *z, *w;
    int *fx;
    int friction, finite;
} sub_lcp;

static int sub_alloc(sc_arena *a, int m, sub_lcp *s)
{
    size_t mm = (size_t)m;
    memset(s, 0, sizeof *s);
    s->A = sc_arena_alloc(a, mm * mm * sizeof *s->A);
    s->buf = s->A ? sc_arena_alloc(a, 6 * mm * sizeof *s->buf) : NULL;
    s->fx = s->buf ? sc_arena_alloc(a, mm * sizeof *s->fx) : NULL;
    if (!s->fx) {
        sc_arena_free(a, s->buf);
        sc_arena_free(a, s->A);
        return SC_ENOMEM;
    }
    s->q = s->buf;
    s->lo = s->buf + m;
    s->hi = s->buf + 2 * m;
    s->mu = s->buf + 3 * m;
    s->z = s->buf + 4 * m;
    s->w = s->buf + 5 * m;
    return SC_OK;
}

static void sub_free(sc_arena *a, sub_lcp *s)
{
    sc_arena_free(a, s->fx);
    sc_arena_free(a, s->buf);
    sc_arena_free(a, s->A);
}

/* nr: the sub-LCP's rows of pb, NULL for r0 .. r0 + m - 1 (a friction
 * row's normal is then findex - r0; a list holds no friction rows). */
static void sub_fill(const gs_problem *pb, int r0, const int *nr, int m, const double *z,
                     const double *u, sub_lcp *s)
{
    s->friction = 0;
    s->finite = 1;
    for (int i = 0; i < m; i++) {
        int r = nr ? nr[i] : r0 + i;
        double v = local_speed(&pb->rows[r], u) + pb->off[r];
        const double *Ai = s->A + (size_t)i * (size_t)m;
        for (int j = 0; j < m; j++)
            v -= Ai[j] * z[nr ? nr[j] : r0 + j];
        s->q[i] = v;
        s->finite &= isfinite(v);
        s->fx[i] = pb->findex && pb->findex[r] >= 0 ? pb->findex[r] - r0 : -1;
        s->friction |= s->fx[i] >= 0;
        s->mu[i] = s->fx[i] >= 0 ? pb->mu[r] : 0;
        s->lo[i] = s->fx[i] >= 0 ? -INFINITY : pb->lo[r];
        s->hi[i] = s->fx[i] >= 0 ? INFINITY : pb->hi[r];
        s->z[i] = z[r];
    }
}

/* The sub-LCP's answer into z and u (nr as sub_fill()'s). */
static void sub_take(const gs_problem *pb, int r0, const int *nr, int m, const sub_lcp *s,
                     double *z, double *u)
{
    for (int i = 0; i < m; i++) {
        int r = nr ? nr[i] : r0 + i;
        local_apply(&pb->rows[r], s->z[i] - z[r], u);
        z[r] = s->z[i];
    }
}

/* Passes of projected Gauss-Seidel over a block's friction rows after its
 * normals' exact solve: a pair's friction converges with the sweeps that
 * carry its neighbours' loads, and three passes a block take a pile to the
 * tolerance in about as many sweeps as the coupled exact solve, at a
 * fraction of its cost (docs/DESIGN.md 11). */
#define FRICTION_PASSES 3

/* One block with the others held, from its last iterate (a warm start):
 * its rows' LCP w_b = A_bb (z_b - z_b_old) + J_b u + off_b. coupled: all
 * its rows, friction coupled to the normals (solve()). Otherwise its
 * normal rows alone, the block's friction held, then FRICTION_PASSES
 * passes of projected Gauss-Seidel over its friction rows, bounds +-mu
 * z_n of the new normals, alternately forwards and backwards, the first
 * backwards in a backward sweep (back). The normals solved together
 * carry a pair's load on its near-redundant face contacts symmetrically,
 * which rows solved one by one do not within the tolerance (a stack
 * rocks); a block without friction rows is exact either way. */
static int block_solve(sc_arena *a, const gs_problem *pb, const blocks *bl, int k, double *z,
                       double *u, sc_solve_info *info, int fail, int back, int coupled)
{
    int r0 = bl->bstart[k], m = bl->bstart[k + 1] - r0, nn = m;
    int *nr = NULL;           /* the normal rows, where the friction is apart */
    if (!coupled && pb->findex) {
        nr = sc_arena_alloc(a, (size_t)m * sizeof *nr);
        if (!nr)
            return SC_ENOMEM;
        nn = 0;
        for (int i = 0; i < m; i++)
            if (pb->findex[r0 + i] < 0)
                nr[nn++] = r0 + i;
    }
    sub_lcp s;
    if (sub_alloc(a, nn, &s) != SC_OK) {
        sc_arena_free(a, nr);
        return SC_ENOMEM;
    }
    const double *Ab = bl->amat + bl->aoff[k];
    if (!nr)
        memcpy(s.A, Ab, (size_t)m * (size_t)m * sizeof *s.A);
    else
        for (int i = 0; i < nn; i++)
            for (int j = 0; j < nn; j++)
                s.A[(size_t)i * (size_t)nn + (size_t)j] =
                    Ab[(size_t)(nr[i] - r0) * (size_t)m + (size_t)(nr[j] - r0)];
    sub_fill(pb, r0, nr, nn, z, u, &s);
    int rc = SC_OK;
    if (!s.finite) {
        info->nan_islands++;      /* leave the block as it was */
    } else {
        info->blocks++;
        sc_solve_info bi = { 0 };
        rc = solve(a, nn, s.A, s.q, s.lo, s.hi, s.friction ? s.fx : NULL, s.mu, s.z, s.w, &bi,
                   (pb->cold ? 0 : SOLVE_WARM) | (fail ? SOLVE_FAIL : 0));
        info->pivots += bi.pivots;
        info->lemke += bi.lemke;
        info->guessed += bi.guessed;
        info->regularised += bi.regularised;
        if (rc == SC_OK) {
            sub_take(pb, r0, nr, nn, &s, z, u);
            for (int it = 0; nn < m && it < FRICTION_PASSES; it++)
                for (int i = 0; i < m; i++) {
                    int r = (it & 1) != back ? r0 + m - 1 - i : r0 + i;
                    if (pb->findex[r] >= 0)
                        row_step(pb, bl, z, u, r);
                }
        } else if (rc != SC_ENOMEM && rc != SC_EINVAL) {
            info->block_fallbacks++;
            block_pgs(pb, bl, k, z, u);
            rc = SC_OK;
        }
    }
    sub_free(a, &s);
    sc_arena_free(a, nr);
    return rc;
}

/* The outer residual in m/s: for every row, how far z is from the answer
 * of that row alone given the others (the natural residual
 * |z - clamp(z - w / A_rr, lo, hi)|, times A_rr). */
static double rows_residual(const gs_problem *pb, const blocks *bl, const double *z,
                            const double *u, int r0, int r1)
{
    double res = 0;
    for (int r = r0; r < r1; r++) {
        double zn;
        if (row_project(pb, bl, z, u, r, &zn))
            res = max_d(res, fabs(z[r] - zn) * bl->diag[r]);
    }
    return res;
}

static double residual(const gs_problem *pb, const blocks *bl, const double *z, const double *u)
{
    return rows_residual(pb, bl, z, u, 0, pb->nrows);
}

/* A block whose own rows are this close to their answers is passed over
 * in a sweep (its solve would move nothing that matters); the sweep's end
 * still checks every row against tol. */
#define SKIP_SHARE 0.1

/* What block_solve() adds to an island's figures. */
static void block_info_add(sc_solve_info *to, const sc_solve_info *from)
{
    to->nan_islands += from->nan_islands;
    to->blocks += from->blocks;
    to->blocks_shared += from->blocks_shared;
    to->pivots += from->pivots;
    to->lemke += from->lemke;
    to->guessed += from->guessed;
    to->regularised += from->regularised;
    to->block_fallbacks += from->block_fallbacks;
}

struct sc_block_batch {
    const gs_problem *pb;
    const blocks *bl;
    double *z, *u;
    int fail;
    const int *list;          /* the colour's blocks */
    double skip;              /* a block this close to its answer is passed over */
    int back;                 /* a backward sweep (block_solve()) */
    int coupled;              /* block_solve()'s coupled exact solve */
    sc_solve_info *info;      /* per listed block */
    int *rc;                  /* per listed block */
};

/* Whether block k is close enough to its answer to be passed over in a
 * sweep (its solve would move nothing that matters): it reads only its
 * rows and its bodies, which no other block of its colour writes. */
static int block_settled(const gs_problem *pb, const blocks *bl, const double *z,
                         const double *u, int k, double skip)
{
    return rows_residual(pb, bl, z, u, bl->bstart[k], bl->bstart[k + 1]) <= skip;
}

void sc_block_run(void *batch, int i, sc_arena *a, int helper)
{
    sc_block_batch *b = batch;
    memset(&b->info[i], 0, sizeof b->info[i]);
    b->rc[i] = SC_OK;
    if (block_settled(b->pb, b->bl, b->z, b->u, b->list[i], b->skip))
        return;
    b->rc[i] = block_solve(a, b->pb, b->bl, b->list[i], b->z, b->u, &b->info[i], b->fail,
                           b->back, b->coupled);
    b->info[i].blocks_shared = helper;
}

/* One colour of a sweep: its blocks that are not close enough already
 * (binfo, brc: room for every block), solved here one after another or,
 * with a runner, wherever it runs them (the closeness test too). Either way
 * each block's solve sees the same numbers, and the first error in block
 * order is returned. */
static int colour_solve(sc_arena *a, const gs_problem *pb, const blocks *bl, int c, int back,
                        int coupled, double *z, double *u, int fail, double skip,
                        const sc_task_runner *runner, sc_solve_info *binfo, int *brc,
                        sc_solve_info *info)
{
    int n = bl->cstart[c + 1] - bl->cstart[c];
    sc_block_batch b = { .pb = pb, .bl = bl, .z = z, .u = u, .fail = fail,
                         .list = &bl->order[bl->cstart[c]], .skip = skip, .back = back,
                         .coupled = coupled, .info = binfo, .rc = brc };
    sc_tasks_run(runner, sc_block_run, &b, n, a);
    int rc = SC_OK;
    for (int i = 0; i < n; i++) {
        block_info_add(info, &binfo[i]);
        rc = rc == SC_OK ? brc[i] : rc;
    }
    return rc;
}

/* Block Gauss-Seidel, sweeps alternating forwards and backwards over the
 * colours (the symmetric order converges faster on chains and stacks),
 * from z (warm start, already in u) until the residual is at most tol or
 * max_sweeps; coupled: each block's friction coupled to its normals
 * (block_solve()).
 * Gauss-Seidel over frictional blocks is not bound to converge: the best
 * iterate is kept (z and u, nu doubles), and a sweep that leaves the
 * residual DIVERGE times above the best stops the iteration, which then
 * ends on the best (counted: sc_solve_info.diverged). */
#define DIVERGE 100.0

/* Anderson acceleration (sc_contact_params.anderson, at most AA_DEPTH): the
 * map is a symmetric sweep, g = G(x) on x = (z, u), a forward and a backward
 * sweep; with the differences of the last sweeps' moves f = (g_z - x_z)
 * A_rr (m/s) and of their results, the next x is g - dG gamma, gamma the
 * least squares of f - dF gamma. u is affine in z, so the combination keeps
 * them consistent; a sweep takes any x, and its blocks' exact answers put z
 * back in its bounds. A sweep whose residual does not fall starts the
 * history again (docs/DESIGN.md 11). */
#define AA_DEPTH SC_ANDERSON_MAX

/* The least squares gamma (k unknowns) of f - dF gamma over n rows, by the
 * normal equations with a little Tikhonov; 0 if they are singular. */
static int aa_gamma(const double *dF, int k, int n, const double *f, double *gamma)
{
    double H[AA_DEPTH * AA_DEPTH], b[AA_DEPTH];
    double tr = 0;
    for (int i = 0; i < k; i++) {
        for (int j = 0; j <= i; j++) {
            double s = 0;
            for (int r = 0; r < n; r++)
                s += dF[(size_t)i * n + r] * dF[(size_t)j * n + r];
            H[i * k + j] = H[j * k + i] = s;
        }
        double s = 0;
        for (int r = 0; r < n; r++)
            s += dF[(size_t)i * n + r] * f[r];
        b[i] = s;
        tr += H[i * k + i];
    }
    if (!(tr > 0))
        return 0;
    for (int i = 0; i < k; i++)
        H[i * k + i] += 1e-10 * tr;
    if (sc_lu_solve(k, H, b) != SC_OK)
        return 0;
    memcpy(gamma, b, (size_t)k * sizeof *gamma);
    for (int i = 0; i < k; i++)
        if (!isfinite(gamma[i]))
            return 0;
    return 1;
}

/* How block_gs() ended: the residual of its iterate, its sweeps (added
 * to), whether it stopped on a diverging sweep. */
typedef struct gs_end {
    double res;
    int sweeps;
    int diverged;
} gs_end;

static int block_gs(sc_arena *a, const gs_problem *pb, const blocks *bl, double *z, double *u,
                    int nu, const sc_contact_params *p, int max_sweeps, double tol,
                    int coupled, sc_solve_info *info, gs_end *end)
{
    int nr = pb->nrows;
    size_t nz = (size_t)nr * sizeof *z, nub = (size_t)nu * sizeof *u;
    size_t nx = (size_t)nr + (size_t)nu;
    size_t nbl = (size_t)bl->count;
    const sc_task_runner *runner = p->runner;
    int aa = p->anderson <= 0 ? 0 : p->anderson < AA_DEPTH ? p->anderson : AA_DEPTH;
    double *zb = sc_arena_alloc(a, nz), *ub = zb ? sc_arena_alloc(a, nub) : NULL;
    sc_solve_info *binfo = ub ? sc_arena_alloc(a, nbl * sizeof *binfo) : NULL;
    int *brc = binfo ? sc_arena_alloc(a, nbl * sizeof *brc) : NULL;
    /* Anderson: z before the symmetric sweep, the last sweep's result
     * (z, u) and move f, the histories of their differences */
    double *xz = NULL, *gp = NULL, *fp = NULL, *f = NULL, *dG = NULL, *dF = NULL;
    if (brc && aa > 0) {
        xz = sc_arena_alloc(a, nz);
        gp = xz ? sc_arena_alloc(a, nx * sizeof *gp) : NULL;
        fp = gp ? sc_arena_alloc(a, nz) : NULL;
        f = fp ? sc_arena_alloc(a, nz) : NULL;
        dG = f ? sc_arena_alloc(a, (size_t)aa * nx * sizeof *dG) : NULL;
        dF = dG ? sc_arena_alloc(a, (size_t)aa * nz) : NULL;
    }
    int rc = brc && (aa == 0 || dF) ? SC_OK : SC_ENOMEM;
    int sweeps = 0, diverged = 0;
    double res = rc == SC_OK ? residual(pb, bl, z, u) : INFINITY, best = res;
    if (rc == SC_OK) {
        memcpy(zb, z, nz);
        memcpy(ub, u, nub);
    }
    int fail = (p->inject & SC_INJECT_BLOCK) != 0;
    int nh = 0, next = 0, have_prev = 0;
    double res_prev = INFINITY;
    while (rc == SC_OK && res > tol && sweeps < max_sweeps) {
        if (aa > 0 && sweeps % 2 == 0)
            memcpy(xz, z, nz);
        for (int i = 0; i < bl->ncolours && rc == SC_OK; i++) {
            int c = sweeps % 2 == 0 ? i : bl->ncolours - 1 - i;
            rc = colour_solve(a, pb, bl, c, sweeps % 2, coupled, z, u, fail, SKIP_SHARE * tol,
                              runner, binfo, brc, info);
        }
        sweeps++;
        res = residual(pb, bl, z, u);
        if (res < best) {
            best = res;
            memcpy(zb, z, nz);
            memcpy(ub, u, nub);
        } else if (!(res <= DIVERGE * best)) {
            diverged = 1;
            break;
        }
        if (aa == 0 || sweeps % 2 != 0 || res <= tol || rc != SC_OK)
            continue;
        for (int r = 0; r < nr; r++)
            f[r] = (z[r] - xz[r]) * bl->diag[r];
        if (!(res < res_prev)) {
            nh = 0;
            next = 0;
        }
        if (have_prev) {
            double *cg = dG + (size_t)next * nx, *cf = dF + (size_t)next * nr;
            for (int r = 0; r < nr; r++) {
                cf[r] = f[r] - fp[r];
                cg[r] = z[r] - gp[r];
            }
            for (int j = 0; j < nu; j++)
                cg[nr + j] = u[j] - gp[nr + j];
            next = (next + 1) % aa;
            nh += nh < aa;
        }
        memcpy(fp, f, nz);
        memcpy(gp, z, nz);
        memcpy(gp + nr, u, nub);
        have_prev = 1;
        res_prev = res;
        /* the columns are slots [0, nh): their order does not matter */
        double gamma[AA_DEPTH];
        if (nh == 0)
            continue;
        if (!aa_gamma(dF, nh, nr, f, gamma)) {
            nh = 0;
            next = 0;
            continue;
        }
        for (int i = 0; i < nh; i++) {
            const double *col = dG + (size_t)i * nx;
            for (int r = 0; r < nr; r++)
                z[r] -= gamma[i] * col[r];
            for (int j = 0; j < nu; j++)
                u[j] -= gamma[i] * col[nr + j];
        }
    }
    if (rc == SC_OK && !(res <= best)) {
        memcpy(z, zb, nz);
        memcpy(u, ub, nub);
        res = best;
    }
    sc_arena_free(a, dF);
    sc_arena_free(a, dG);
    sc_arena_free(a, f);
    sc_arena_free(a, fp);
    sc_arena_free(a, gp);
    sc_arena_free(a, xz);
    sc_arena_free(a, brc);
    sc_arena_free(a, binfo);
    sc_arena_free(a, ub);
    sc_arena_free(a, zb);
    if (rc != SC_OK)
        return rc;
    if (!isfinite(res))
        res = INFINITY;
    end->res = res;
    end->sweeps += sweeps;
    end->diverged |= diverged;
    return SC_OK;
}

/* Split islands of at most this many rows whose block Gauss-Seidel stops
 * short of tol are solved whole: one dense exact LCP from the iterate,
 * friction by the fixed point's rounds alone (sc_lcp_boxed_rounds_in()),
 * after WHOLE_SWEEPS sweeps up to WHOLE_SMALL rows and WHOLE_SWEEPS_BIG
 * past them. Its matrix grows as the rows squared and its pivots' work
 * as their cube, so a larger island sweeps on longer first; where the
 * rounds do not settle, the sweeps go on from the iterate to max_sweeps
 * (Lemke's method on the whole friction LCP costs more than all the
 * sweeps). Bigger islands are the active set's first. Any split island
 * still short of tol at max_sweeps, or ended on a diverging sweep, sweeps
 * on from its best iterate for max_sweeps more with each block's friction
 * coupled (block_solve()); most settle within them. One of up to
 * LAST_MAX_ROWS rows still short then is solved whole once more: by the
 * full exact solve (Lemke's method included) up to WHOLE_MAX_ROWS rows;
 * past them by the rounds alone first, and by the full solve only where
 * they do not settle, up to LAST_FULL_ROWS, since Lemke's tableau (the
 * rows and twice the friction rows, square) makes one solve cost as much
 * as many frames (docs/DESIGN.md 11). SC_ISLAND_BLOCK_GS is block
 * Gauss-Seidel alone. */
#define WHOLE_MAX_ROWS 192
#define WHOLE_SMALL 96
#define WHOLE_SWEEPS 30
#define WHOLE_SWEEPS_BIG 60
#define LAST_MAX_ROWS 800
#define LAST_FULL_ROWS 600

/* The whole problem pb as one exact LCP from the iterate (z, u), whose
 * answer replaces it if solved and adding no kinetic energy of its own
 * (adds_energy()): SC_OK, SC_ENUMERIC where it is not taken (z, u as
 * they were: the sweeps' answer stands), SC_ENOMEM. Friction by the
 * fixed point's rounds alone, or with full set every way solve() has
 * (Lemke's method, the guess, the raised diagonal). inject: SC_INJECT_*
 * (tests). */
static int whole_solve(sc_arena *a, const gs_problem *pb, double *z, double *u,
                       sc_solve_info *info, int full, int inject)
{
    int m = pb->nrows;
    sub_lcp s;
    if (sub_alloc(a, m, &s) != SC_OK)
        return SC_ENOMEM;
    build_a(pb->rows, NULL, m, s.A);
    /* w = A (zw - z) + J u + off, as a block's (block_solve()): at zw = z
     * it is the speed the iterate leaves, so the compliance c that
     * build_a() added pulls the answer towards the iterate instead of
     * softening it: w = (A - cI) zw + J u0 + off + c (zw - z), the
     * stiff LCP that block Gauss-Seidel converges to, off by c |zw - z|
     * (far below tol). The fixed point's rounds settle more often so
     * than on the exact island's softened LCP (a proximal step). */
    sub_fill(pb, 0, NULL, m, z, u, &s);
    int rc = SC_ENUMERIC;
    if (s.finite) {
        sc_lcp_info li = { 0 };
        if (full) {
            rc = solve(a, m, s.A, s.q, s.lo, s.hi, s.friction ? s.fx : NULL, s.mu, s.z, s.w,
                       info, SOLVE_WARM);
        } else if (!(inject & SC_INJECT_ROUNDS)) {
            rc = sc_lcp_boxed_rounds_in(a, m, s.A, s.q, s.lo, s.hi, s.friction ? s.fx : NULL,
                                        s.mu, s.z, s.w, &li);
            lcp_info_add(info, &li, rc);
        }
        if (rc == SC_OK && adds_energy(s.A, m, s.q, pb->off, NULL, s.z) == ENERGY_OWN)
            rc = SC_ENUMERIC;
    }
    if (rc == SC_OK)
        sub_take(pb, 0, NULL, m, &s, z, u);
    sub_free(a, &s);
    return rc == SC_OK || rc == SC_ENOMEM ? rc : SC_ENUMERIC;
}

/* whole_solve() counted as a try, its success ending the sweeps' run
 * (end) at the answer. */
static int whole_try(sc_arena *a, const gs_problem *pb, double *z, double *u,
                     sc_solve_info *info, int full, int inject, gs_end *end)
{
    info->whole_tries++;
    int rc = whole_solve(a, pb, z, u, info, full, inject);
    if (rc == SC_OK) {
        info->whole_solved++;
        end->res = 0;
        end->diverged = 0;
    }
    return rc;
}

static int cmp_int(const void *x, const void *y)
{
    int a = *(const int *)x, b = *(const int *)y;
    return (a > b) - (a < b);
}

/* Local velocity slots: every body of the rows gets one (immovable ones
 * too: with W = 0 they keep their velocity). *body_out lists the slots'
 * bodies (sorted); returns the slot count or SC_ENOMEM. */
static int slots_build(sc_arena *a, row *rows, int nrows, int **body_out)
{
    int *body = sc_arena_alloc(a, (size_t)(2 * nrows) * sizeof *body);
    if (!body)
        return SC_ENOMEM;
    int m = 0;
    for (int r = 0; r < nrows; r++) {
        body[m++] = rows[r].a;
        body[m++] = rows[r].b;
    }
    qsort(body, (size_t)m, sizeof *body, cmp_int);
    int u = 0;
    for (int i = 0; i < m; i++)
        if (u == 0 || body[u - 1] != body[i])
            body[u++] = body[i];
    for (int r = 0; r < nrows; r++) {
        rows[r].la = (int)((int *)bsearch(&rows[r].a, body, (size_t)u, sizeof *body, cmp_int) - body);
        rows[r].lb = (int)((int *)bsearch(&rows[r].b, body, (size_t)u, sizeof *body, cmp_int) - body);
    }
    *body_out = body;
    return u;
}

/* Split islands of more contacts than this are solved whole by the active
 * set first: block Gauss-Seidel settles smaller ones (a stack of up to 16
 * boxes) within its sweeps, and on a bolt pile's small islands, whose
 * friction the active set rarely settles, its tries would only add cost
 * (docs/DESIGN.md 11). */
#define AS_MIN_CONTACTS 64

/* Rows solved by blocks: local velocities from the bodies (pseudo: from
 * 0), warm start z applied, block Gauss-Seidel, then velocities written
 * back (pseudo: bodies moved by h times them). cstart[k] is the first row
 * of contact k. */
static int solve_split(sc_arena *a, row *rows, int nrows, const int *cstart, int nc,
                       const gs_problem *pb_in, double *z, sc_body *bodies, int pseudo, double h,
                       const sc_contact_params *p, double tol, sc_solve_info *info)
{
    int *body = NULL;
    int m = slots_build(a, rows, nrows, &body);
    if (m < 0)
        return m;
    double *u = sc_arena_alloc(a, (size_t)m * 6 * sizeof *u);
    blocks bl = { 0 };
    int per = p->block_contacts > 0 ? p->block_contacts : 1;
    int rc = u ? blocks_build(a, rows, nrows, cstart, nc, per, m, &bl) : SC_ENOMEM;
    if (rc == SC_OK) {
        for (int i = 0; i < m; i++) {
            const sc_body *b = &bodies[body[i]];
            if (pseudo) {
                memset(&u[6 * i], 0, 6 * sizeof *u);
            } else {
                memcpy(&u[6 * i], b->v, 3 * sizeof *u);
                memcpy(&u[6 * i + 3], b->w, 3 * sizeof *u);
            }
        }
        gs_problem pb = *pb_in;
        pb.rows = rows;
        pb.nrows = nrows;
        /* the warm start only where it is the better start: a matched
         * impulse can come from another kind of contact (last frame's
         * collision), and an iteration stopped early keeps what it
         * started from */
        int warm = 0;
        for (int r = 0; r < nrows && !warm; r++)
            warm = z[r] != 0;
        double *ucold = warm ? sc_arena_alloc(a, (size_t)m * 6 * sizeof *u) : NULL;
        double *zcold = ucold ? sc_arena_alloc(a, (size_t)nrows * sizeof *z) : NULL;
        if (warm && !zcold)
            rc = SC_ENOMEM;
        if (zcold) {
            memcpy(ucold, u, (size_t)m * 6 * sizeof *u);
            memset(zcold, 0, (size_t)nrows * sizeof *z);
            for (int r = 0; r < nrows; r++)
                if (z[r] != 0)
                    local_apply(&rows[r], z[r], u);
            if (residual(&pb, &bl, zcold, ucold) < residual(&pb, &bl, z, u)) {
                memcpy(u, ucold, (size_t)m * 6 * sizeof *u);
                memset(z, 0, (size_t)nrows * sizeof *z);
                info->cold_starts++;
            }
        }
        sc_arena_free(a, zcold);
        sc_arena_free(a, ucold);
        int as = rc == SC_OK && p->island_method != SC_ISLAND_BLOCK_GS && nc > AS_MIN_CONTACTS;
        if (as) {
            /* the whole island exactly; where its guesses do not settle,
             * block Gauss-Seidel (counted; an active set started from its
             * iterate settled no more of a bin's islands) */
            info->as_solves++;
            rc = p->inject & SC_INJECT_ACTIVE_SET
                     ? SC_ENUMERIC
                     : sc_island_active_set(&pb, bodies, body, m,
                                            p->island_method == SC_ISLAND_SUBDOMAINS, p->runner,
                                            a, z, u, info);
            if (rc == SC_OK)
                goto done;
            rc = rc == SC_ENUMERIC ? SC_OK : rc;
        }
        /* an unconverged iterate of a small island: solved whole (counted) */
        gs_end end = { 0 };
        int rescue = !pseudo && p->island_method != SC_ISLAND_BLOCK_GS;
        int last = rescue && nrows <= LAST_MAX_ROWS;
        int whole = last && nrows <= WHOLE_MAX_ROWS;
        int first = whole ? (nrows <= WHOLE_SMALL ? WHOLE_SWEEPS : WHOLE_SWEEPS_BIG) : 0;
        first = whole && first < p->max_sweeps ? first : p->max_sweeps;
        if (rc == SC_OK)
            rc = block_gs(a, &pb, &bl, z, u, 6 * m, p, first, tol, 0, info, &end);
        if (rc == SC_OK && whole && end.res > tol) {
            rc = whole_try(a, &pb, z, u, info, 0, p->inject, &end);
            if (rc == SC_ENUMERIC)
                rc = block_gs(a, &pb, &bl, z, u, 6 * m, p, p->max_sweeps - end.sweeps, tol, 0,
                              info, &end);
        }
        /* what the sweeps leave short sweeps on from its best iterate, as
         * many sweeps again (a fresh Anderson history), each block's
         * friction coupled to its normals: the friction passes leave some
         * islands short that the coupled blocks settle */
        if (rc == SC_OK && rescue && end.res > tol)
            rc = block_gs(a, &pb, &bl, z, u, 6 * m, p, p->max_sweeps, tol, 1, info, &end);
        /* the last resort: the full solve (Lemke's method too) where it
         * is cheap, else the rounds first and it where they fail */
        if (rc == SC_OK && last && end.res > tol) {
            rc = whole_try(a, &pb, z, u, info, whole, p->inject, &end);
            if (rc == SC_ENUMERIC && !whole && nrows <= LAST_FULL_ROWS)
                rc = whole_try(a, &pb, z, u, info, 1, p->inject, &end);
            rc = rc == SC_ENUMERIC ? SC_OK : rc;
        }
        if (rc == SC_OK && !pseudo) {
            info->sweeps_max = end.sweeps > info->sweeps_max ? end.sweeps : info->sweeps_max;
            info->sweeps += end.sweeps;
            info->unconverged += end.res > tol && !end.diverged;
            info->diverged += end.res > tol && end.diverged;
            info->residual_split = max_d(info->residual_split, end.res);
        }
        info->as_fallbacks += as;
    }
done:
    if (rc == SC_OK)
        for (int i = 0; i < m; i++) {
            sc_body *b = &bodies[body[i]];
            if (!movable(b))
                continue;
            if (pseudo) {
                move_body(b, &u[6 * i], h);
            } else {
                memcpy(b->v, &u[6 * i], 3 * sizeof *u);
                memcpy(b->w, &u[6 * i + 3], 3 * sizeof *u);
            }
        }
    if (bl.bstart)
        blocks_free(a, &bl);
    sc_arena_free(a, u);
    sc_arena_free(a, body);
    return rc;
}

/* Islands past this many rows are refused (SC_ETOOMANY): split or not,
 * their rows alone take more memory than a frame should. */
#define SPLIT_MAX_ROWS (1 << 20)

/* An exact normal-only LCP over rows nr[0 .. m) (its matrix from the
 * arena), its impulses z applied to the bodies' velocities (pseudo: to
 * their pseudo velocities, over h). */
static int exact_normals(sc_arena *a, const row *nr, int m, const double *q, double *z,
                         double *w, sc_body *bodies, int pseudo, double h, sc_solve_info *info)
{
    size_t mm = (size_t)m;
    double *A = sc_arena_alloc(a, mm * mm * sizeof *A);
    if (!A)
        return SC_ENOMEM;
    build_a(nr, NULL, m, A);
    int rc = solve(a, m, A, q, NULL, NULL, NULL, NULL, z, w, info, 0);
    sc_arena_free(a, A);
    if (rc == SC_OK)
        for (int k = 0; k < m; k++)
            apply(&nr[k], z[k], bodies, pseudo, h);
    return rc;
}

/* The push-out of deep contacts: a normal-only LCP on pseudo velocities
 * (target: remove baumgarte of the depth past slop in h), exact for small
 * islands, by blocks for split ones or when the exact solve fails. */
static int push_out(sc_arena *a, const row *rows, const int *nsel, int nn, const sc_contact *c,
                    const int *ci, sc_body *bodies, double h, const sc_contact_params *p,
                    int split, sc_solve_info *info)
{
    size_t n = (size_t)nn;
    double *buf = sc_arena_alloc(a, 5 * n * sizeof *buf);
    int *cs = buf ? sc_arena_alloc(a, n * sizeof *cs) : NULL;
    row *nr = cs ? sc_arena_alloc(a, n * sizeof *nr) : NULL;
    if (!nr) {
        sc_arena_free(a, cs);
        sc_arena_free(a, buf);
        return SC_ENOMEM;
    }
    double *q = buf, *z = buf + n, *w = buf + 2 * n, *lo = buf + 3 * n, *hi = buf + 4 * n;
    double qmax = 0;
    for (int k = 0; k < nn; k++) {
        /* what the velocities just solved do not already take out: a
         * sphere leaving the floor after a bounce is not lifted as well
         * (that lift, against gravity, would add energy) */
        double d = c[ci[k]].depth, tol = p->push_tol > 0 ? p->push_tol : INFINITY;
        double target = (p->baumgarte * max_d(min_d(d, tol) - p->slop, 0.0) +
                         max_d(d - tol, 0.0)) / h;
        q[k] = -max_d(target - max_d(row_speed(&rows[nsel[k]], bodies, 0), 0.0), 0.0);
        qmax = max_d(qmax, -q[k]);
        nr[k] = rows[nsel[k]];
        cs[k] = k;
        lo[k] = 0;
        hi[k] = INFINITY;
        z[k] = 0;
    }
    int rc = SC_ETOOMANY;
    if (!split) {
        rc = exact_normals(a, nr, nn, q, z, w, bodies, 1, h, info);
        if (rc != SC_OK && rc != SC_ENOMEM)
            for (int k = 0; k < nn; k++)
                z[k] = 0;
    }
    if (rc != SC_OK && rc != SC_ENOMEM) {
        gs_problem pb = { .off = q, .lo = lo, .hi = hi, .cold = p->cold, .pseudo = 1 };
        rc = solve_split(a, nr, nn, cs, nn, &pb, z, bodies, 1, h, p, max_d(p->tol, 1e-3 * qmax),
                         info);
    }
    sc_arena_free(a, nr);
    sc_arena_free(a, cs);
    sc_arena_free(a, buf);
    return rc;
}

/* One LCP over an island's rows, its impulses applied to the bodies'
 * velocities: exact (with the staggered and block fallbacks) or, split,
 * by blocks. buf holds q, lo, hi, mu, z, w and off (n = nrows doubles
 * each); z is the warm start (used when warm) and returns the impulses. */
static int solve_rows(sc_arena *arena, sc_body *bodies, row *rows, int nrows,
                      const int *nsel, int nn, const int *cstart, int nc, double *A, double *buf,
                      const int *findex, int *sel, int friction, int split, int warm, int keep,
                      const double *ds, double h, const sc_contact_params *p,
                      sc_solve_info *info)
{
    size_t n = (size_t)nrows;
    double *q = buf, *lo = buf + n, *hi = buf + 2 * n, *mu = buf + 3 * n, *z = buf + 4 * n,
           *w = buf + 5 * n, *off = buf + 6 * n;
    int rc = SC_OK;
    if (!split) {
        build_a(rows, NULL, nrows, A);
        /* from the matched impulses, scaled to this substep (build_rows()) */
        rc = solve(arena, nrows, A, q, lo, hi, friction ? findex : NULL, mu, z, w, info,
                   (warm && !p->cold ? SOLVE_WARM : 0) |
                       (p->inject & SC_INJECT_COUPLED ? SOLVE_FAIL : 0));
        int gain = rc == SC_OK ? adds_energy(A, nrows, q, off, ds, z) : ENERGY_NONE;
        if (gain == ENERGY_TARGETS) {
            gain = scale_restitution(arena, nrows, A, q, off, ds, lo, hi, findex, mu, z, w, keep,
                                     info);
            info->restitution_scaled += gain == ENERGY_NONE;
        }
        if (gain != ENERGY_NONE) {
            /* a coupled friction answer that adds kinetic energy of its
             * own (seen on a bolt wedged in a nut's hole: near-opposed
             * normals squeezing with hundreds of N s, friction bounded by
             * them): an LCP answer, but not physics; the staggered solve
             * cannot do it */
            info->energy_refused++;
            rc = SC_ENUMERIC;
        }
        if (rc == SC_OK) {
            for (int i = 0; i < nrows; i++)
                apply(&rows[i], z[i], bodies, 0, h);
        } else if (rc != SC_ENOMEM && rc != SC_EINVAL) {
            int fail_st = (p->inject & SC_INJECT_STAGGERED) != 0;
            for (int i = 0; i < nrows; i++)
                z[i] = 0;
            if (friction) {
                /* The friction fixed point can fail (pivot limit,
                 * ill-conditioned near-duplicate rows). Then stagger:
                 * normals alone (a PSD LCP the pivoting solves), then the
                 * tangents as a boxed LCP with the bounds fixed at +-mu p_n.
                 * Exact for each half, the coupling of friction back into
                 * the normals is lost for this substep: counted in
                 * sc_stats.frame.lcp.fallbacks, never silent. */
                info->failures++;
                double *sbuf = sc_arena_alloc(arena, 6 * n * sizeof *sbuf);
                rc = SC_ENOMEM;
                if (sbuf) {
                    memcpy(sbuf, q, n * sizeof *q);
                    memset(sbuf + 5 * n, 0, n * sizeof *sbuf);
                    rc = staggered(arena, rows, nrows, nsel, nn, findex, mu, bodies, A, sbuf,
                                   sel, info, fail_st);
                    memcpy(z, sbuf + 5 * n, n * sizeof *z);   /* what it applied */
                    sc_arena_free(arena, sbuf);
                }
            }
            if (rc != SC_OK && rc != SC_ENOMEM) {
                /* last resort: blocks, from what the staggered solve
                 * applied (in z), taken back off the bodies first: the
                 * block solve applies its start itself */
                info->split_fallbacks++;
                split = 1;
                for (int i = 0; i < nrows; i++)
                    if (z[i] != 0)
                        apply(&rows[i], -z[i], bodies, 0, 0);
            }
        }
        if (rc != SC_OK && !split)
            return rc;
    }
    if (split) {
        info->split++;
        gs_problem pb = { .off = off, .lo = lo, .hi = hi, .mu = mu,
                          .findex = friction ? findex : NULL, .cold = p->cold };
        if (p->cold || !warm)
            memset(z, 0, n * sizeof *z);
        rc = solve_split(arena, rows, nrows, cstart, nc, &pb, z, bodies, 0, h, p, p->tol, info);
    }
    return rc;

}

/* The island's movable bodies, each once (sorted), into *out from the
 * arena: their count, or SC_ENOMEM. */
static int island_movable(sc_arena *a, const sc_body *bodies, const sc_contact *c, const int *ci,
                          int nc, int **out)
{
    int *ids = sc_arena_alloc(a, (size_t)(2 * nc) * sizeof *ids);
    if (!ids)
        return SC_ENOMEM;
    int m = 0;
    for (int k = 0; k < nc; k++) {
        if (movable(&bodies[c[ci[k]].body_a]))
            ids[m++] = c[ci[k]].body_a;
        if (movable(&bodies[c[ci[k]].body_b]))
            ids[m++] = c[ci[k]].body_b;
    }
    qsort(ids, (size_t)m, sizeof *ids, cmp_int);
    int u = 0;
    for (int i = 0; i < m; i++)
        if (u == 0 || ids[u - 1] != ids[i])
            ids[u++] = ids[i];
    *out = ids;
    return u;
}

static double kinetic(const sc_body *b, const double v[3], const double w[3]);

/* The push-out without the energy it would give: lifting bodies against
 * gravity raises their potential energy, which nothing paid for, so the
 * island's kinetic energy of turning and of moving along gravity pays it
 * (those velocities scaled down, every contact row's sign kept; a part
 * pushed or sliding across the floor keeps its speed). Where the lift
 * would cost more than that, the push-out goes only as far as it pays
 * (every body's move and turn scaled by the same share) and those
 * velocities stop: a resting part is not lifted for free. A part whose
 * contacts hover just past the slop is pushed out in every substep, and
 * lifted so a little at a time while still it tips and rocks
 * (docs/DESIGN.md 3.5). An island whose deepest contact (deep) is deeper
 * than PUSH_PAID_DEPTH times the slop (bodies placed overlapping, a pair
 * at the time of impact's tolerance) is pushed out whatever it costs: a
 * little inside the tolerance, so that a creeping pile is pushed back
 * before it passes it (at twice the slop, piles pass it). */
#define PUSH_PAID_DEPTH 1.9

/* Every body of ids moved from x0 (position, then orientation: 7 doubles
 * a body) by the share f of the move it made. */
static void scale_moves(sc_body *bodies, const int *ids, int nb, const double *x0, double f)
{
    for (int i = 0; i < nb; i++) {
        sc_body *b = &bodies[ids[i]];
        const double *q0 = &x0[7 * i + 3];
        double sg = q_dot(q0, b->q) < 0 ? -1 : 1;
        for (int j = 0; j < 3; j++)
            b->x[j] = x0[7 * i + j] + f * (b->x[j] - x0[7 * i + j]);
        for (int j = 0; j < 4; j++)
            b->q[j] = q0[j] + f * (sg * b->q[j] - q0[j]);
        q_normalize(b->q);
    }
}

/* Body b's size for limit_moves(): sqrt(trace(I) / m), from its world
 * inverse inertia and inverse mass (what an island unit carries to a
 * daemon: no shape), 0.7-1.1 times the bounding radius about the centre
 * of mass of a cube, a sphere or a rod. 0 if iw is not invertible. */
static double gyration_reach(const sc_body *b)
{
    double I[9];
    if (!m3_inverse(I, b->iw))
        return 0;
    double tr = I[0] + I[4] + I[8];     /* trace of the world inertia */
    return tr > 0 && isfinite(tr) ? sqrt(tr * b->inv_mass) : 0;
}

/* A push-out moves no body by more than PUSH_MAX_MOVE times the island's
 * deepest contact (or the slop, if more), a body's move being |dx| plus
 * its turn times gyration_reach(): it removes a share of a depth, and a
 * move far past that comes from near-opposed normals, whose pseudo
 * impulses grow without bound while their forces cancel and their
 * torques do not: a part squeezed between two such contacts is turned by
 * a large angle in each substep's push-out and driven deep into its
 * neighbour. Where a body's move is larger, every body of the island
 * moves by the same smaller share (docs/DESIGN.md 3.5). */
#define PUSH_MAX_MOVE 2.0
static void limit_moves(sc_body *bodies, const int *ids, int nb, const double *x0, double deep,
                        double slop)
{
    double cap = PUSH_MAX_MOVE * max_d(deep, slop), worst = 0;
    for (int i = 0; i < nb; i++) {
        const sc_body *b = &bodies[ids[i]];
        double d[3];
        v3_sub(d, b->x, &x0[7 * i]);
        worst = max_d(worst, sqrt(v3_dot(d, d)) +
                                 q_angle_between(&x0[7 * i + 3], b->q) * gyration_reach(b));
    }
    if (worst > cap)
        scale_moves(bodies, ids, nb, x0, cap / worst);
}
static int neutral_push_out(sc_arena *a, const row *rows, const int *nsel, int nn,
                            const sc_contact *c, const int *ci, int nc, double deep,
                            sc_body *bodies, double h, const sc_contact_params *p, int split,
                            sc_solve_info *info)
{
    int *ids = NULL;
    int nb = island_movable(a, bodies, c, ci, nc, &ids);
    if (nb < 0)
        return nb;
    double *x0 = nb > 0 ? sc_arena_alloc(a, (size_t)nb * 7 * sizeof *x0) : NULL;
    if (nb > 0 && !x0) {
        sc_arena_free(a, ids);
        return SC_ENOMEM;
    }
    for (int i = 0; i < nb; i++) {
        v3_copy(&x0[7 * i], bodies[ids[i]].x);
        memcpy(&x0[7 * i + 3], bodies[ids[i]].q, 4 * sizeof *x0);
    }
    int rc = push_out(a, rows, nsel, nn, c, ci, bodies, h, p, split, info);
    if (rc == SC_OK)
        limit_moves(bodies, ids, nb, x0, deep, p->slop);
    /* g: gravity's direction (none: all of v may pay) */
    double g[3], lift = 0, ke = 0;
    v3_copy(g, p->gravity);
    int along = v3_normalize(g) > 0;
    for (int i = 0; rc == SC_OK && i < nb; i++) {
        const sc_body *b = &bodies[ids[i]];
        double d[3], vg[3];
        v3_sub(d, b->x, &x0[7 * i]);
        lift -= v3_dot(p->gravity, d) / b->inv_mass;
        v3_scale(vg, g, v3_dot(b->v, g));
        ke += kinetic(b, along ? vg : b->v, b->w);
    }
    if (rc == SC_OK && lift > ke && deep <= PUSH_PAID_DEPTH * p->slop) {
        scale_moves(bodies, ids, nb, x0, ke / lift);
        lift = ke;
    }
    if (rc == SC_OK && lift > 0 && ke > 0) {
        double s = sqrt(max_d(ke - lift, 0.0) / ke);
        for (int i = 0; i < nb; i++) {
            sc_body *b = &bodies[ids[i]];
            if (along)
                v3_madd(b->v, b->v, g, (s - 1) * v3_dot(b->v, g));
            else
                v3_scale(b->v, b->v, s);
            v3_scale(b->w, b->w, s);
        }
    }
    sc_arena_free(a, x0);
    sc_arena_free(a, ids);
    return rc;
}

/* The share s of a velocity change that brings the bodies' kinetic energy
 * to cap: k0 before the change, k1 after it, kd the change's own, so that
 * the energy with a share s is k0 + s l + s^2 kd (l = k1 - k0 - kd); 1
 * when k1 is within cap, 0 when no share is. */
static double energy_share(double k0, double k1, double kd, double cap)
{
    if (!(k1 > cap) || !(kd > 0))
        return 1;
    double l = k1 - k0 - kd, d = l * l - 4 * kd * (k0 - cap);
    return k0 < cap && d > 0 ? min_d(max_d((-l + sqrt(d)) / (2 * kd), 0.0), 1.0) : 0;
}

/* The kinetic energy a movable body may have at the substep's end: what
 * it had at the start (its rotation after the forces: the gyroscopic turn
 * does no work) plus the forces' work over the displacement it will have
 * made (what the solve moved it, and the step integrate.c will take from
 * its velocities now). k: what bodies_keep() kept of it. */
static double work_budget(const sc_body *b, const double *k, double h)
{
    double acc[3], dx[3], step[3];
    v3_sub(acc, k, k + 6);
    v3_scale(acc, acc, 1 / h);
    if (b->collided == 2) {
        v3_madd(step, b->v, acc, -0.5 * h);
    } else {
        v3_add(step, b->v0, b->v);
        v3_scale(step, step, 0.5);
    }
    v3_sub(dx, b->x, k + 13);
    v3_madd(dx, dx, step, h);
    return kinetic(b, k + 6, k + 3) + v3_dot(acc, dx) / b->inv_mass;
}

/* The target of a row that does not touch at the impacts: no impulse. */
#define NOT_TOUCHING 1e12

/* The collisions of an island of touching bodies (coll[k]: contact k
 * collides; e = 0 when inelastic) as impulses at the substep's start, on
 * the velocities before the external forces (v0, w0): colliding rows to
 * -e times their approach, resting ones to no approach, speculative ones
 * (a gap: not touching) no impulse. Each body's v0, w0 then become its velocities
 * after the impacts, its v, w those plus what the external forces add
 * over h, and buf is set up for the substep's resting solve over every
 * row (the last solve's impulses its warm start): the resting contacts
 * take the forces after the impacts, and the positions integrate by the
 * trapezoid rule from the velocities after them.
 *
 * Why: as one LCP of collisions and resting contacts, a colliding row's
 * target J u' = -e v_pre + (J u* - J u0) counts the other body's gravity
 * as if it fell freely, and the body flies from the substep's start at
 * u' - g h / 2. A cube bouncing off a resting stack so gained g h each
 * bounce and hopped for ever at g h / (1 - e) = 0.196 m/s (e = 0.5, 100
 * Hz), above the bounce speed; and a body that a collision hit while it
 * rested on another rose by g h^2 / 2 (0.49 mm) in that substep. */
static int impacts(sc_arena *arena, sc_body *bodies, const sc_contact *c, const int *ci, int nc,
                   row *rows, int nrows, int *nsel, const int *cstart, const int *coll, double *A,
                   double *buf, const int *findex, int *sel, int friction, int split,
                   int inelastic, int keep, double h, const sc_contact_params *p,
                   sc_solve_info *info)
{
    size_t n = (size_t)nrows;
    double *q = buf, *z = buf + 4 * n, *off = buf + 6 * n;
    int *mb = NULL;
    int nb = island_movable(arena, bodies, c, ci, nc, &mb);
    if (nb < 0)
        return nb;
    double *du = sc_arena_alloc(arena, (size_t)nb * 6 * sizeof *du);
    double *zw = du ? sc_arena_alloc(arena, n * sizeof *zw) : NULL;
    if (!zw) {
        sc_arena_free(arena, du);
        sc_arena_free(arena, mb);
        return SC_ENOMEM;
    }
    memcpy(zw, z, n * sizeof *z);
    /* the velocities before the forces, what the forces add kept in du */
    for (int i = 0; i < nb; i++) {
        sc_body *b = &bodies[mb[i]];
        v3_sub(&du[6 * i], b->v, b->v0);
        v3_sub(&du[6 * i + 3], b->w, b->w0);
        v3_copy(b->v, b->v0);
        v3_copy(b->w, b->w0);
    }
    for (int k = 0; k < nc; k++) {
        const sc_contact *ck = &c[ci[k]];
        double e = inelastic ? 0
                             : max_d(bodies[ck->body_a].restitution, bodies[ck->body_b].restitution);
        for (int r = cstart[k]; r < (k + 1 < nc ? cstart[k + 1] : nrows); r++) {
            double s = row_speed(&rows[r], bodies, 0);
            if (r > cstart[k])
                off[r] = 0;                 /* friction */
            else if (coll[k])
                off[r] = e * s;
            else
                off[r] = ck->depth < 0 ? NOT_TOUCHING : 0;
            q[r] = s + off[r];
            z[r] = 0;
        }
    }
    int rc = solve_rows(arena, bodies, rows, nrows, nsel, nc, cstart, nc, A, buf, findex, sel,
                        friction, split, 0, keep, NULL, h, p, info);
    for (int i = 0; i < nb; i++) {
        sc_body *b = &bodies[mb[i]];
        v3_copy(b->v0, b->v);
        v3_copy(b->w0, b->w);
        v3_add(b->v, b->v, &du[6 * i]);
        v3_add(b->w, b->w, &du[6 * i + 3]);
        if (b->collided == 2)
            b->collided = 1;        /* no flight from the start: v0 is after the impacts */
    }
    for (int k = 0; k < nc; k++) {
        double gap = max_d(-c[ci[k]].depth, 0.0);
        for (int r = cstart[k]; r < (k + 1 < nc ? cstart[k + 1] : nrows); r++) {
            double s = row_speed(&rows[r], bodies, 0);
            off[r] = r > cstart[k] ? 0 : gap / h;
            q[r] = s + off[r];
        }
    }
    memcpy(z, zw, n * sizeof *z);
    sc_arena_free(arena, zw);
    sc_arena_free(arena, du);
    sc_arena_free(arena, mb);
    return rc;
}

/* An elastic answer may add kinetic energy beyond this share of the
 * island's (before or after the substep's forces, whichever is more):
 * Newton's restitution applied at several contacts at once can, and on
 * near-opposed contacts (a part pinched inside another) it turned a
 * 4 m/s approach into 27 m/s (docs/DESIGN.md 3.5). Single collisions
 * under gravity gain at most about g h / v, far below this. */
#define ELASTIC_GAIN_MAX 0.05

/* Kinetic energy of movable body b at velocities v, w (world frame), from
 * what an island solve reads (inv_mass, iw: a remote node's bodies carry
 * no more, docs/DESIGN.md 7.1). */
static double kinetic(const sc_body *b, const double v[3], const double w[3])
{
    double I[9], iw[3];
    double rot = 0;
    if (m3_inverse(I, b->iw)) {
        m3_mulv(iw, I, w);
        rot = 0.5 * v3_dot(w, iw);
    }
    return 0.5 * v3_dot(v, v) / b->inv_mass + rot;
}

/* What an island's solve changes on its movable bodies (velocities before
 * and after the forces, the collision mark), kept so that it can be solved
 * again, and the position before it: KEEP doubles a body. */
#define KEEP 16
static void bodies_keep(const sc_body *bodies, const int *ids, int nb, double *keep)
{
    for (int i = 0; i < nb; i++) {
        const sc_body *b = &bodies[ids[i]];
        double *k = &keep[KEEP * i];
        v3_copy(k, b->v);
        v3_copy(k + 3, b->w);
        v3_copy(k + 6, b->v0);
        v3_copy(k + 9, b->w0);
        k[12] = b->collided;
        v3_copy(k + 13, b->x);
    }
}

static void bodies_restore(sc_body *bodies, const int *ids, int nb, const double *keep)
{
    for (int i = 0; i < nb; i++) {
        sc_body *b = &bodies[ids[i]];
        const double *k = &keep[KEEP * i];
        v3_copy(b->v, k);
        v3_copy(b->w, k + 3);
        v3_copy(b->v0, k + 6);
        v3_copy(b->w0, k + 9);
        b->collided = (int)k[12];
    }
}

/* A held collision (a speculative row that collides, docs/DESIGN.md 3.4)
 * bounces where it touches. The bodies approach at -v_pre (J u0) with a
 * gap g, the forces adding a = (J u* - J u0) / h along the row: they touch
 * at t, where g + v_pre t + a t^2 / 2 = 0, approaching at v_t, v_t^2 =
 * v_pre^2 - 2 a g; they leave at e v_t and end the substep (T = h - t
 * later) at e v_t + a T. The LCP gives them that speed from the substep's
 * start (the impulse z), and they fly from there (integrate.c), so their
 * configuration is off by t times the impulse's velocity change: the row's
 * separation by *pull = t (v_end - J u*) (>= 0), which pull_in() takes
 * back once the collision is solved; *t the touch. Where they would meet
 * again within the substep (e v_t T + a T^2 / 2 <= 0) they end at the touch
 * at rest instead: *pull what the flight from the start overshoots it by.
 *
 * a_lin is the part of a that comes from the bodies' linear velocities:
 * the rest is the gyroscopic turn of w, which does no work, and counted in
 * the bounce it would gain a spinning body z (a - a_lin) T a bounce;
 * v_end takes it out for e = 1 (the energy after is then the energy
 * before plus the linear forces' work, as the flight and the pull give
 * it), (1 + e) / 2 of that for e < 1.
 *
 * (Bouncing at the start from the start's speed keeps the energy with
 * e = 1 but puts the bounce a gap early, at the speed of the gap's top, so
 * a ball with e < 1 rebounds too high.) */
static double touch(double vpre, double speed, double a_lin, double gap, double e, double h,
                    double *pull, double *t)
{
    double a = (speed - vpre) / h;
    double vt = sqrt(max_d(vpre * vpre - 2 * a * gap, 0.0));
    *t = vt - vpre > 0 ? min_d(2 * gap / (vt - vpre), h) : h;
    double T = h - *t;
    double v = e * vt + a * T - 0.5 * (1 + e) * 2 * (a - a_lin) * T;
    if (!(e * vt * T + 0.5 * a * T * T > 0)) {
        v = 0;
        *pull = max_d(gap - 0.5 * a * h * h, 0.0);
    } else {
        *pull = max_d(*t * (v - speed), 0.0);
    }
    return v;
}

/* J (u* - u0) / h of a row's linear parts: what the forces, not the
 * turning of w, add along it. */
static double row_lin_accel(const row *rw, const sc_body *bodies, double h)
{
    const sc_body *A = &bodies[rw->a], *B = &bodies[rw->b];
    double da[3], db[3];
    v3_sub(da, A->v, A->v0);
    v3_sub(db, B->v, B->v0);
    return (v3_dot(rw->ja, da) + v3_dot(rw->jb, db)) / h;
}

/* Held collisions that were solved (z > 0) brought back from where the
 * bounce at the substep's start puts them to where bouncing at the touch
 * does (touch()), by positions alone (as the push-out moves them). A
 * pair's held rows act as one: the row of their resultant (the rows'
 * Jacobians weighted by their impulses, so that it moves the bodies the
 * way the collision's impulse does), its separation taken back by the
 * rows' pull weighted the same way, the least move in the mass metric
 * that does it. A face or an edge that touches on several points so moves
 * as one (pulling along one of its rows turned a box dropped flat onto
 * its corner); a single point is pulled along its own row. No further
 * than takes another contact of the island (of this pair or of its
 * bodies' others) deeper than it is, than the velocities solved take it
 * over h, or than the slop, to first order: the pull knows nothing else of
 * them. */
/* Whether contact k (of the island's ci) is a held collision that was
 * solved: a speculative row that collides, with an impulse and a pull. */
static int held_row(const sc_contact *c, const int *ci, const int *coll, const int *cstart,
                    const double *z, const double *pull, int k)
{
    return coll[k] && c[ci[k]].depth < 0 && z[cstart[k]] > 0 && pull[k] > 0;
}

static void pull_in(const row *rows, const int *cstart, const sc_contact *c, const int *ci,
                    int nc, const int *coll, const double *z, const double *pull, double slop,
                    double h, sc_body *bodies)
{
    for (int k0 = 0, k1; k0 < nc; k0 = k1) {
        row rw = rows[cstart[k0]];
        double zsum = 0, want = 0;
        memset(rw.ja, 0, sizeof rw.ja);
        memset(rw.jb, 0, sizeof rw.jb);
        memset(rw.wa, 0, sizeof rw.wa);
        memset(rw.wb, 0, sizeof rw.wb);
        for (k1 = k0; k1 < nc && c[ci[k1]].body_a == c[ci[k0]].body_a &&
                      c[ci[k1]].body_b == c[ci[k0]].body_b; k1++) {
            if (!held_row(c, ci, coll, cstart, z, pull, k1))
                continue;
            double zk = z[cstart[k1]];
            const row *rk = &rows[cstart[k1]];
            for (int j = 0; j < 6; j++) {
                rw.ja[j] += zk * rk->ja[j];
                rw.jb[j] += zk * rk->jb[j];
                rw.wa[j] += zk * rk->wa[j];
                rw.wb[j] += zk * rk->wb[j];
            }
            zsum += zk;
            want += zk * pull[k1];
        }
        if (!(zsum > 0))
            continue;
        for (int j = 0; j < 6; j++) {
            rw.ja[j] /= zsum;
            rw.jb[j] /= zsum;
            rw.wa[j] /= zsum;
            rw.wb[j] /= zsum;
        }
        double arr = a_entry(&rw, &rw);
        if (!(arr > 0))
            continue;
        double lam = -(want / zsum) / arr, s = 1;
        for (int k = 0; k < nc; k++) {
            if (k >= k0 && k < k1 && held_row(c, ci, coll, cstart, z, pull, k))
                continue;
            /* depth it adds, against the depth the contact has or, if
             * deeper, the velocities just solved take it to over h (a
             * speculative row may close its gap with them: the pull may
             * not close it again) */
            double close = -a_entry(&rows[cstart[k]], &rw) * lam;
            double d0 = c[ci[k]].depth, d1 = d0 - h * row_speed(&rows[cstart[k]], bodies, 0);
            double room = max_d(d0, slop) - max_d(d0, d1);
            if (close > 0 && close * s > room)
                s = max_d(0.0, room / close);
        }
        apply(&rw, s * lam, bodies, 1, 1.0);
    }
}

/* A speculative row that its own approach does not close within h (no
 * collision: a resting row with its gap) is loaded only when another
 * collision of the substep drives the bodies into it (a sphere bounced off
 * one neighbour into a wall), and then it would stop them at the surface
 * without a bounce, losing their energy. Such a row touches at the
 * substep's end, so it bounces there: a normal-only LCP over the island
 * gives it v_n >= e times the approach it took out (its speed without its
 * own impulse, s - A_rr z), the island's other touching or loaded rows no
 * faster approach than they have. The
 * bounce acts after the positions moved: they are moved back by what the
 * integration will add for it (integrate.c: h du for a body that flies
 * from a collision at the start, h du / 2 by the trapezoid rule). */
static int rebound(sc_arena *a, sc_body *bodies, const sc_contact *c, const int *ci, int nc,
                   const row *rows, const int *cstart, const int *coll, const double *z,
                   double cap, int split, double h, const sc_contact_params *p,
                   sc_solve_info *info)
{
    int nb_rows = 0;
    for (int k = 0; k < nc; k++)
        nb_rows += c[ci[k]].depth < 0 && !coll[k] && z[cstart[k]] > 0;
    if (nb_rows == 0)
        return SC_OK;
    size_t n = (size_t)nc;
    int *ids = NULL;
    int nb = island_movable(a, bodies, c, ci, nc, &ids);
    if (nb < 0)
        return nb;
    double *keep = sc_arena_alloc(a, KEEP * (size_t)(nb > 0 ? nb : 1) * sizeof *keep);
    double *buf = keep ? sc_arena_alloc(a, 5 * n * sizeof *buf) : NULL;
    int *cs = buf ? sc_arena_alloc(a, n * sizeof *cs) : NULL;
    row *nr = cs ? sc_arena_alloc(a, n * sizeof *nr) : NULL;
    int rc = SC_ENOMEM;
    if (!nr)
        goto out;
    double *q = buf, *zr = buf + n, *w = buf + 2 * n, *lo = buf + 3 * n, *hi = buf + 4 * n;
    int m = 0, nbounce = 0;
    for (int k = 0; k < nc; k++) {
        const sc_contact *ck = &c[ci[k]];
        const row *rw = &rows[cstart[k]];
        double s = row_speed(rw, bodies, 0), zk = z[cstart[k]];
        double e = max_d(bodies[ck->body_a].restitution, bodies[ck->body_b].restitution);
        double took = -(s - a_entry(rw, rw) * zk);
        if (ck->depth < 0 && !coll[k] && zk > 0 && e > 0 && took > p->bounce_speed) {
            q[m] = s - e * took;
            nbounce++;
        } else if ((ck->depth >= 0 || zk > 0) && s >= -p->bounce_speed) {
            q[m] = max_d(s, 0.0);
        } else {
            continue;
        }
        nr[m] = *rw;
        cs[m] = m;
        lo[m] = 0;
        hi[m] = INFINITY;
        zr[m] = 0;
        m++;
    }
    rc = SC_OK;
    if (nbounce == 0)
        goto out;
    bodies_keep(bodies, ids, nb, keep);
    rc = SC_ETOOMANY;
    if (!split)
        rc = exact_normals(a, nr, m, q, zr, w, bodies, 0, 0, info);
    if (rc != SC_OK && rc != SC_ENOMEM) {
        gs_problem pb = { .off = q, .lo = lo, .hi = hi, .cold = 1 };
        for (int k = 0; k < m; k++) {
            q[k] -= row_speed(&nr[k], bodies, 0);   /* off: J u is added per sweep */
            zr[k] = 0;
        }
        rc = solve_split(a, nr, m, cs, m, &pb, zr, bodies, 0, h, p, p->tol, info);
    }
    /* no more kinetic energy than the bodies had before the solve */
    double k0 = 0, k1 = 0, kd = 0;
    for (int i = 0; i < nb; i++) {
        const sc_body *b = &bodies[ids[i]];
        double d[6];
        v3_sub(d, b->v, &keep[KEEP * i]);
        v3_sub(d + 3, b->w, &keep[KEEP * i + 3]);
        k0 += kinetic(b, &keep[KEEP * i], &keep[KEEP * i + 3]);
        k1 += kinetic(b, b->v, b->w);
        kd += kinetic(b, d, d + 3);
    }
    double share = energy_share(k0, k1, kd, cap);
    /* the positions as the velocities before the bounce integrate them */
    for (int i = 0; i < nb && rc == SC_OK; i++) {
        sc_body *b = &bodies[ids[i]];
        double u[6];
        v3_sub(u, &keep[KEEP * i], b->v);
        v3_sub(u + 3, &keep[KEEP * i + 3], b->w);
        for (int j = 0; j < 6; j++)
            u[j] *= share;
        v3_madd(b->v, &keep[KEEP * i], u, -1);
        v3_madd(b->w, &keep[KEEP * i + 3], u + 3, -1);
        if (u[0] != 0 || u[1] != 0 || u[2] != 0 || u[3] != 0 || u[4] != 0 || u[5] != 0)
            move_body(b, u, b->collided == 2 ? h : 0.5 * h);
    }
out:
    sc_arena_free(a, nr);
    sc_arena_free(a, cs);
    sc_arena_free(a, buf);
    sc_arena_free(a, keep);
    sc_arena_free(a, ids);
    return rc;
}

/* Held collisions of one pair that touch later than its first (by more
 * than the slop at their speed) are no collisions: the first's bounce may
 * take them apart, and else they hold as resting rows with their gaps
 * (the bodies flying from the start: J u' - (J u* - J u0) / 2 >= -g / h),
 * and rebound() bounces them where they touch. A spinning faceted body
 * can meet the floor on two vertices at different speeds within a
 * substep, and Newton's restitution on both at once gains it energy.
 * pull: touch()'s, then per contact its approach at the touch and its
 * resting row's q. */
static void first_touches(const sc_contact *c, const int *ci, int nc, const int *cstart,
                          int *coll, const double *pull, double *q, double *off, double slop)
{
    for (int k0 = 0, k1; k0 < nc; k0 = k1) {
        double tmin = INFINITY;
        for (k1 = k0; k1 < nc && c[ci[k1]].body_a == c[ci[k0]].body_a &&
                      c[ci[k1]].body_b == c[ci[k0]].body_b; k1++)
            if (coll[k1] && c[ci[k1]].depth < 0)
                tmin = min_d(tmin, pull[nc + k1]);
        for (int k = k0; k < k1; k++) {
            if (!(coll[k] && c[ci[k]].depth < 0) || (pull[nc + k] - tmin) * pull[2 * nc + k] <= slop)
                continue;
            int r = cstart[k];
            coll[k] = 0;
            off[r] += pull[3 * nc + k] - q[r];
            q[r] = pull[3 * nc + k];
        }
    }
}

/* An island's LCP rows and their data, as build_rows() makes them. */
typedef struct island_rows {
    row *rows;
    int *cstart;              /* contact k's first row */
    int *coll;                /* contact k collides */
    int *nsel, *findex;       /* the normal rows; a friction row's normal */
    double *q, *lo, *hi, *mu, *z, *off;
    double *pull;             /* a held collision's touch() figures, 4 nc */
    int inelastic;            /* in: solved again without restitution */
    int nn;                   /* out: normal rows */
    int friction;             /* out: any friction row */
    int ncollide, nspecc;     /* out: collisions, of them held (speculative) */
    int elastic;              /* out: a collision with restitution */
    int perfect;              /* out: every collision perfectly elastic */
} island_rows;

/* The rows of contacts c[ci[0 .. nc)]: a normal, then two tangents where
 * there is friction, each with its target, bounds and warm start; marks
 * the bodies of a collision (collided = 2) and counts the collisions. */
static void build_rows(island_rows *ir, sc_body *bodies, sc_contact *c, const int *ci, int nc,
                       double h, const sc_contact_params *p, sc_solve_info *info)
{
    row *rows = ir->rows;
    int *cstart = ir->cstart, *coll = ir->coll, *nsel = ir->nsel, *findex = ir->findex;
    double *q = ir->q, *lo = ir->lo, *hi = ir->hi, *mu = ir->mu, *z = ir->z, *off = ir->off,
           *pull = ir->pull;
    int inelastic = ir->inelastic;
    int r = 0, nn = 0, friction = 0, ncollide = 0, nspecc = 0, elastic = 0;
    int perfect = 1;          /* every collision perfectly elastic */
    for (int k = 0; k < nc; k++) {
        sc_contact *ck = &c[ci[k]];
        const sc_body *A_ = &bodies[ck->body_a], *B_ = &bodies[ck->body_b];
        /* solved again without restitution: see ELASTIC_GAIN_MAX */
        double e = inelastic ? 0 : max_d(A_->restitution, B_->restitution);
        double m = sqrt(A_->friction * B_->friction);
        int rn = r;
        cstart[k] = r;
        make_row(&rows[r], bodies, ck, ck->normal);
        double vpre = row_speed(&rows[r], bodies, 1);
        double speed = row_speed(&rows[r], bodies, 0);
        /* a speculative contact (depth < 0: a gap, docs/DESIGN.md 3.4)
         * collides only if its approach closes the gap within h */
        int collide = vpre < -p->bounce_speed && -ck->depth < -min_d(vpre, speed) * h;
        int held = collide && ck->depth < 0;
        info->collisions += collide && !inelastic;
        elastic |= collide && e > 0;
        perfect &= !collide || e >= 1;
        coll[k] = collide;
        ncollide += collide;
        nspecc += held;
        /* only movable bodies are written: static and sleeping ones are
         * shared by islands solved concurrently */
        if (collide && movable(A_))
            bodies[ck->body_a].collided = 2;
        if (collide && movable(B_))
            bodies[ck->body_b].collided = 2;
        /* a collision is an impulse at the start of the substep, before the
         * external forces act: target J u' = -e v_pre + (J u* - J u0), so
         * w = A p + (1 + e) v_pre. A resting contact absorbs the forces. */
        /* a speculative resting contact lets the bodies close its gap
         * within h but no more */
        q[r] = collide ? (1 + e) * vpre : speed + max_d(-ck->depth, 0.0) / h;
        if (held) {
            q[r] = speed - touch(vpre, speed, row_lin_accel(&rows[r], bodies, h), -ck->depth, e, h,
                                 &pull[k], &pull[nc + k]);
            pull[2 * nc + k] = sqrt(max_d(vpre * vpre - 2 * (speed - vpre) / h * -ck->depth, 0.0));
            pull[3 * nc + k] = 0.5 * (vpre + speed) - ck->depth / h;
        }
        off[r] = q[r] - speed;
        lo[r] = 0;
        hi[r] = INFINITY;
        findex[r] = -1;
        mu[r] = 0;
        /* warm start: last solve's impulse on this contact, projected;
         * a resting contact's scaled to this substep (its force kept: a
         * back-up's substep is shorter, the one after it and the next
         * frame's longer), a collision's as it was */
        double ws = !collide && ck->impulse_dt > 0 ? h / ck->impulse_dt : 1;
        z[r] = ws * max_d(v3_dot(ck->impulse, ck->normal), 0.0);
        nsel[nn++] = r;
        r++;
        if (m > 0) {
            double t[2][3];
            tangents(bodies, ck, t[0], t[1]);
            for (int j = 0; j < 2; j++, r++) {
                make_row(&rows[r], bodies, ck, t[j]);
                speed = row_speed(&rows[r], bodies, 0);
                q[r] = speed;
                off[r] = 0;
                lo[r] = -INFINITY;
                hi[r] = INFINITY;
                findex[r] = rn;
                mu[r] = m;
                double b = m * z[rn];
                z[r] = min_d(max_d(ws * v3_dot(ck->impulse, t[j]), -b), b);
            }
            friction = 1;
        }
    }
    ir->nn = nn;
    ir->friction = friction;
    ir->ncollide = ncollide;
    ir->nspecc = nspecc;
    ir->elastic = elastic;
    ir->perfect = perfect;
}

/* The kinetic energy of bodies ids[0 .. nb) at their velocities (pre: at
 * the substep's start, v0 and w0). */
static double bodies_kinetic(const sc_body *bodies, const int *ids, int nb, int pre)
{
    double ke = 0;
    for (int i = 0; i < nb; i++) {
        const sc_body *b = &bodies[ids[i]];
        ke += pre ? kinetic(b, b->v0, b->w0) : kinetic(b, b->v, b->w);
    }
    return ke;
}

/* For a perfectly elastic island (solve_rows()' energy check): each
 * colliding row's speed moved to its impact, the approach at the touch for
 * a held one (touch()'s figures in pull), J u0 for the others; 0 on every
 * other row. Returns ds. */
static double *impact_speeds(const row *rows, int nrows, const int *cstart, const int *coll,
                             const double *pull, const sc_body *bodies, const sc_contact *c,
                             const int *ci, int nc, double *ds)
{
    for (int k = 0; k < nc; k++) {
        int r0 = cstart[k], r1 = k + 1 < nc ? cstart[k + 1] : nrows;
        for (int rr = r0; rr < r1; rr++)
            ds[rr] = 0;
        if (!coll[k])
            continue;
        double vpre = row_speed(&rows[r0], bodies, 1), speed = row_speed(&rows[r0], bodies, 0);
        double at = c[ci[k]].depth < 0 ? -pull[2 * nc + k] : vpre;
        ds[r0] = speed - at;
    }
    return ds;
}

/* Each contact's impulse from its rows' z (normal, then friction), and the
 * substep h it acted over, for the next solve's warm start and the
 * caller. */
static void store_impulses(const row *rows, int nrows, const int *cstart, const double *z,
                           sc_contact *c, const int *ci, int nc, double h)
{
    for (int k = 0; k < nc; k++) {
        sc_contact *ck = &c[ci[k]];
        int r0 = cstart[k], r1 = k + 1 < nc ? cstart[k + 1] : nrows;
        v3_scale(ck->impulse, ck->normal, z[r0]);
        ck->impulse_dt = h;
        for (int j = r0 + 1; j < r1; j++)
            v3_madd(ck->impulse, ck->impulse, rows[j].jb, z[j]);
    }
}

int sc_island_solve(sc_arena *arena, sc_body *bodies, sc_contact *c, const int *ci, int nc,
                    double h, const sc_contact_params *p, sc_solve_info *info)
{
    if (nc == 0)
        return SC_OK;
    info->solves++;
    /* rows: normal, then two tangents where there is friction */
    int nrows = 0;
    for (int k = 0; k < nc; k++) {
        const sc_contact *ck = &c[ci[k]];
        double mu = sqrt(bodies[ck->body_a].friction * bodies[ck->body_b].friction);
        nrows += mu > 0 ? 3 : 1;
        if (nrows > SPLIT_MAX_ROWS)
            return SC_ETOOMANY;    /* not a misleading out-of-memory later */
    }
    /* one exact LCP up to split_contacts (and SC_MAX_ISLAND_ROWS), else blocks */
    int split = (p->split_contacts > 0 && nc > p->split_contacts) || nrows > SC_MAX_ISLAND_ROWS;
    size_t n = (size_t)nrows;
    /* per island, from the thread's arena: no allocation once it has
     * grown to the largest island */
    row *rows = sc_arena_alloc(arena, n * sizeof *rows);
    double *A = rows && !split ? sc_arena_alloc(arena, n * n * sizeof *A) : NULL;
    double *buf = rows && (A || split) ? sc_arena_alloc(arena, n * 7 * sizeof *buf) : NULL;
    int *findex = buf ? sc_arena_alloc(arena, n * sizeof *findex) : NULL;
    int *nsel = findex ? sc_arena_alloc(arena, n * sizeof *nsel) : NULL;
    int *sel = nsel ? sc_arena_alloc(arena, n * sizeof *sel) : NULL;
    int *cstart = sel ? sc_arena_alloc(arena, (size_t)nc * sizeof *cstart) : NULL;
    int *coll = cstart ? sc_arena_alloc(arena, (size_t)nc * sizeof *coll) : NULL;
    double *pull = coll ? sc_arena_alloc(arena, 4 * (size_t)nc * sizeof *pull) : NULL;
    /* a perfect island's impact speeds (solve_rows()) */
    double *dsbuf = pull ? sc_arena_alloc(arena, n * sizeof *dsbuf) : NULL, *ds = NULL;
    int *bid = NULL;                /* an elastic island's bodies, */
    double *keep = NULL;            /* what its solve changes on them */
    int rc = SC_ENOMEM;
    if (!dsbuf)
        goto out;
    double *q = buf, *lo = buf + n, *hi = buf + 2 * n, *mu = buf + 3 * n, *z = buf + 4 * n,
           *off = buf + 6 * n;
    int finite, nb = 0;
    double ke_ref = 0;
    island_rows ir = { .rows = rows, .cstart = cstart, .coll = coll, .nsel = nsel,
                       .findex = findex, .q = q, .lo = lo, .hi = hi, .mu = mu, .z = z,
                       .off = off, .pull = pull };
rows_again:
    build_rows(&ir, bodies, c, ci, nc, h, p, info);
    finite = 1;
    if (ir.nspecc > 0)
        first_touches(c, ci, nc, cstart, coll, pull, q, off, p->slop);
    if (p->inject & SC_INJECT_NAN)
        q[0] = NAN;
    for (int i = 0; i < nrows; i++)
        finite &= isfinite(q[i]) && isfinite(z[i]);
    if (!finite) {
        /* bodies with non-finite speeds or poses: no impulse rather than a
         * NaN spread over the island; counted */
        info->nan_islands++;
        for (int i = 0; i < nrows; i++)
            z[i] = 0;
        rc = SC_OK;
        goto impulses;
    }
    /* the local mode: an island's collisions first, then its resting
     * contacts (impacts()); not where a speculative row collides (a held
     * collision): one LCP with the resting rows, its impulse at the
     * substep's start aiming at the speed bouncing at the touch ends with
     * (touch()), the bodies then pulled back to where that bounce puts
     * them (pull_in()) (solved with the impacts first, a held collision
     * bounces a gap early and gains energy) */
    /* an elastic answer is checked for energy it adds: the island's
     * bodies and their energy before the solve */
    if (ir.elastic) {
        nb = island_movable(arena, bodies, c, ci, nc, &bid);
        keep = nb >= 0 ? sc_arena_alloc(arena, KEEP * (size_t)(nb > 0 ? nb : 1) * sizeof *keep)
                       : NULL;
        if (!keep) {
            rc = SC_ENOMEM;
            goto out;
        }
        bodies_keep(bodies, bid, nb, keep);
        ke_ref = max_d(bodies_kinetic(bodies, bid, nb, 0), bodies_kinetic(bodies, bid, nb, 1));
    }
    if (p->impact_first && ir.ncollide > 0 && ir.nspecc == 0) {
        rc = impacts(arena, bodies, c, ci, nc, rows, nrows, nsel, cstart, coll, A, buf, findex, sel,
                     ir.friction, split, ir.inelastic, ir.perfect, h, p, info);
        if (rc != SC_OK)
            goto out;
    }
    /* a perfectly elastic island's collisions checked at their impacts */
    ds = ir.perfect && ir.ncollide > 0 && !ir.inelastic && !split
             ? impact_speeds(rows, nrows, cstart, coll, pull, bodies, c, ci, nc, dsbuf)
             : NULL;
    rc = solve_rows(arena, bodies, rows, nrows, nsel, ir.nn, cstart, nc, A, buf, findex, sel,
                    ir.friction, split, 1, ir.perfect, ds, h, p, info);
    if (rc != SC_OK)
        goto out;
    if (ir.elastic) {
        double ke = bodies_kinetic(bodies, bid, nb, 0);
        if (ke > (1 + ELASTIC_GAIN_MAX) * ke_ref + 1e-12) {
            /* solved again without restitution (counted): the velocity
             * LCP is then a projection and takes energy out */
            info->inelastic++;
            ir.inelastic = 1;
            bodies_restore(bodies, bid, nb, keep);
            sc_arena_free(arena, keep);
            sc_arena_free(arena, bid);
            keep = NULL;
            bid = NULL;
            goto rows_again;
        }
    }
    /* split impulse: push deep contacts out by pseudo velocities */
    double deep = 0;
    for (int k = 0; k < nc; k++)
        deep = max_d(deep, c[ci[k]].depth);
    if (deep > p->slop)
        rc = neutral_push_out(arena, rows, nsel, ir.nn, c, ci, nc, deep, bodies, h, p, split, info);
    if (ir.nspecc > 0)
        pull_in(rows, cstart, c, ci, nc, coll, z, pull, p->slop, h, bodies);
    if (rc == SC_OK && p->impact_first && !ir.inelastic && keep) {
        double cap = 0;
        for (int i = 0; i < nb; i++)
            cap += work_budget(&bodies[bid[i]], &keep[KEEP * i], h);
        rc = rebound(arena, bodies, c, ci, nc, rows, cstart, coll, z, cap, split, h, p, info);
    }
impulses:
    store_impulses(rows, nrows, cstart, z, c, ci, nc, h);
out:
    sc_arena_free(arena, keep);
    sc_arena_free(arena, bid);
    sc_arena_free(arena, dsbuf);
    sc_arena_free(arena, pull);
    sc_arena_free(arena, coll);
    sc_arena_free(arena, cstart);
    sc_arena_free(arena, sel);
    sc_arena_free(arena, nsel);
    sc_arena_free(arena, findex);
    sc_arena_free(arena, buf);
    sc_arena_free(arena, A);
    sc_arena_free(arena, rows);
    return rc;
}
