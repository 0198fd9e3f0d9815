/* toi.c - time of impact (the paper's step 5; docs/DESIGN.md 3.4): the
 * time at which two moving shapes first touch, or a touching pair gets too
 * deep, so the frame can back up to it. Every pair is sampled finely
 * enough that no feature is skipped, and the first sample past the mark is
 * bisected, on ODE's narrow phase. */
#include "core.h"
#include "vecmath.h"

#define TOI_MAX_SAMPLES 256
#define TOI_MAX_BISECT 64

void sc_pose_lerp(sc_pose *r, const sc_pose *a, const sc_pose *b, double t)
{
    for (int k = 0; k < 3; k++)
        r->pos[k] = a->pos[k] + t * (b->pos[k] - a->pos[k]);
    q_slerp(r->quat, a->quat, b->quat, t);
}

/* Deepest penetration at time t, or -1 when apart, and its normal (n may
 * be NULL); negative code on error. A caller that only compares it with
 * stop gets, when it is deeper, some depth deeper than stop (pieces:
 * sc_np_collide_until()); stop INFINITY: the deepest. */
int sc_toi_deepest_at(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double t,
                      double stop, double *depth, double n[3])
{
    sc_pose pa, pb;
    sc_pose_lerp(&pa, a0, a1, t);
    sc_pose_lerp(&pb, b0, b1, t);
    /* bounding spheres apart: the shapes are (no narrow phase needed) */
    if (v3_dist(pa.pos, pb.pos) > a->bound_r + b->bound_r + 1e-9) {
        *depth = -1;
        return SC_OK;
    }
    if (!n)
        return sc_np_deepest_until(ctx, a, &pa, b, &pb, stop, depth);
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    int k = sc_np_collide_until(ctx, a, &pa, b, &pb, c, SC_MAX_PAIR_CONTACTS, stop);
    if (k < 0)
        return k;
    *depth = -1;
    for (int i = 0; i < k; i++)
        if (c[i].depth > *depth) {
            *depth = c[i].depth;
            if (n)
                v3_copy(n, c[i].normal);
        }
    return SC_OK;
}

static int depth_at(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                    const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double t,
                    double stop, double *depth)
{
    return sc_toi_deepest_at(ctx, a, a0, a1, b, b0, b1, t, stop, depth, NULL);
}

/* How far any point of s can move between p0 and p1 (translation plus
 * rotation angle times the bounding radius). Planes are static. */
double sc_toi_sweep(const sc_shape *s, const sc_pose *p0, const sc_pose *p1)
{
    if (s->kind == SC_SHAPE_PLANE)
        return 0;
    return v3_dist(p0->pos, p1->pos) + q_angle_between(p0->quat, p1->quat) * s->bound_r;
}

/* Smallest feature a sample step must not skip: a fraction of the shape. */
double sc_toi_feature(const sc_shape *s)
{
    switch (s->kind) {
    case SC_SHAPE_SPHERE: return s->radius;
    case SC_SHAPE_BOX: return min_d(s->half[0], min_d(s->half[1], s->half[2]));
    case SC_SHAPE_PLANE: return INFINITY;
    default: return 0.25 * s->bound_r;
    }
}

/* Samples over [t0, 1] so that no sample step moves a surface point by
 * more than half the smaller feature (or the tolerance, if larger). */
static int sample_count(const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                        const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
                        double t0)
{
    double sweep = (sc_toi_sweep(a, a0, a1) + sc_toi_sweep(b, b0, b1)) * (1 - t0);
    double step = max_d(0.5 * min_d(sc_toi_feature(a), sc_toi_feature(b)), tol_m);
    return (int)min_d(max_d(ceil(sweep / step), 1), TOI_MAX_SAMPLES);
}

/* The sampling search for the first touch after t0 (apart at t0): samples
 * at t0 + (1 - t0) k / n, the first overlapping one bisected. t0 = 0 is
 * the whole search, bit for bit (the samples are then exactly k / n). */
int sc_toi_sample_from_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                           const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                           const sc_pose *b1, double tol_m, double t0, double tmax, double *t)
{
    double d;
    int rc;
    int samples = sample_count(a, a0, a1, b, b0, b1, tol_m, t0);
    for (int k = 1; k <= samples && t0 + (1 - t0) * ((double)(k - 1) / samples) < tmax; k++) {
        double hi = t0 + (1 - t0) * ((double)k / samples);
        double lo = t0 + (1 - t0) * ((double)(k - 1) / samples);
        rc = depth_at(ctx, a, a0, a1, b, b0, b1, hi, tol_m, &d);
        if (rc < 0)
            return rc;
        if (d < 0)
            continue;
        /* lo is apart, hi touches: bisect to the first touch within tol */
        double best = hi;
        for (int it = 0; it < TOI_MAX_BISECT && hi - lo > 1e-12; it++) {
            double mid = 0.5 * (lo + hi);
            rc = depth_at(ctx, a, a0, a1, b, b0, b1, mid, tol_m, &d);
            if (rc < 0)
                return rc;
            if (d < 0) {
                lo = mid;
            } else {
                hi = mid;
                best = mid;
                if (d <= tol_m)
                    break;
            }
        }
        *t = best;
        return 1;
    }
    return 0;
}

/* The same for a pair within limit_m at t0: the last time its depth is
 * within limit_m before a sample past it. */
int sc_toi_sample_deepen_from_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                                  const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                                  const sc_pose *b1, double limit_m, double t0, double tmax,
                                  double *t)
{
    double d;
    int rc;
    int samples = sample_count(a, a0, a1, b, b0, b1, limit_m, t0);
    for (int k = 1; k <= samples && t0 + (1 - t0) * ((double)(k - 1) / samples) < tmax; k++) {
        double hi = t0 + (1 - t0) * ((double)k / samples);
        double lo = t0 + (1 - t0) * ((double)(k - 1) / samples);
        rc = depth_at(ctx, a, a0, a1, b, b0, b1, hi, limit_m, &d);
        if (rc < 0)
            return rc;
        if (d <= limit_m)
            continue;
        /* lo within the limit, hi past it: keep the last time within */
        for (int it = 0; it < TOI_MAX_BISECT && hi - lo > 1e-9; it++) {
            double mid = 0.5 * (lo + hi);
            rc = depth_at(ctx, a, a0, a1, b, b0, b1, mid, limit_m, &d);
            if (rc < 0)
                return rc;
            if (d <= limit_m)
                lo = mid;
            else
                hi = mid;
        }
        *t = lo;
        return 1;
    }
    return 0;
}

/* The limit a deepening search holds a pair to that starts d deep: a
 * little past the aim *limit (a backed-up substep left it there), the
 * tolerance (*limit / SC_TOI_AIM), or past that its depth plus a
 * hundredth of the tolerance: the sort-out's limits (impact.c), so that a
 * pair sorted out for passing them has a time to back up to (a looser
 * limit lets a pair end past the limit it was sorted out for with no time
 * found, and no limit lets a part sink deep into the floor); far past it
 * (a pile at the substep cap), 0: not held, the push-out works on it
 * (holding those costs a pile much time and gains nothing;
 * docs/DESIGN.md 3.4). */
int sc_toi_held_limit(double d, double *limit)
{
    if (d > 2 * *limit)
        return 0;
    double tol = *limit / SC_TOI_AIM;
    if (d > *limit)
        *limit = d <= tol ? tol : d + 0.01 * tol;
    return 1;
}

/* ---- the searches the frame calls ---- */

int sc_toi_sample_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                             const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                             const sc_pose *b1, double tol_m, double tmax, double *t)
{
    if (!ctx || !a || !b || !a0 || !a1 || !b0 || !b1 || !t || !(tol_m > 0) || !isfinite(tol_m))
        return SC_EINVAL;
    double d;
    int rc = depth_at(ctx, a, a0, a1, b, b0, b1, 0.0, -1, &d);
    if (rc < 0)
        return rc;
    if (d >= 0) {
        *t = 0;
        return 1;
    }
    return sc_toi_sample_from_ctx(ctx, a, a0, a1, b, b0, b1, tol_m, 0, tmax, t);
}

int sc_toi_sample_deepen_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                                    const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                                    const sc_pose *b1, double limit_m, double tmax, double *t)
{
    if (!ctx || !a || !b || !a0 || !a1 || !b0 || !b1 || !t || !(limit_m > 0))
        return SC_EINVAL;
    double d;
    int rc = depth_at(ctx, a, a0, a1, b, b0, b1, 0.0, INFINITY, &d);
    if (rc < 0)
        return rc;
    if (!sc_toi_held_limit(d, &limit_m))
        return 0;
    return sc_toi_sample_deepen_from_ctx(ctx, a, a0, a1, b, b0, b1, limit_m, 0, tmax, t);
}

int sc_toi_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
               const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
               double *t)
{
    return sc_toi_before_ctx(ctx, a, a0, a1, b, b0, b1, tol_m, 1, t);
}

int sc_toi_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
                      double tmax, double *t)
{
    /* not routed to conservative advancement (extra/ca/) for convex
     * pairs, though it is faster a query: its touches are shallower (at
     * most tol/2, where the sampling aims at 0.9 tol), and shallower
     * touches gain elastic bodies more energy, in both time-of-impact
     * modes; docs/DESIGN.md 3.4 */
    return sc_toi_sample_before_ctx(ctx, a, a0, a1, b, b0, b1, tol_m, tmax, t);
}

int sc_toi_deepen_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double limit_m,
                      double *t)
{
    return sc_toi_deepen_before_ctx(ctx, a, a0, a1, b, b0, b1, limit_m, 1, t);
}

int sc_toi_deepen_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                             const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                             const sc_pose *b1, double limit_m, double tmax, double *t)
{
    /* sampled too (see above: by conservative advancement alone this
     * search, too, gains elastic bodies energy) */
    return sc_toi_sample_deepen_before_ctx(ctx, a, a0, a1, b, b0, b1, limit_m, tmax, t);
}

SC_API int sc_toi(const sc_shape *a, const sc_pose *a0, const sc_pose *a1, const sc_shape *b,
                  const sc_pose *b0, const sc_pose *b1, double tol_m, double *t)
{
    sc_np_ctx *ctx = sc_np_create();
    if (!ctx)
        return SC_ENOMEM;
    int rc = sc_toi_ctx(ctx, a, a0, a1, b, b0, b1, tol_m, t);
    sc_np_destroy(ctx);
    return rc;
}
