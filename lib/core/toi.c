/* toi.c - time of impact (the paper's step 5; docs/DESIGN.md 3.4): the
 * time at which two moving shapes first touch, so the frame can back up to
 * it. Every pair the frame asks about is sampled finely enough that no
 * feature is skipped, and the first overlapping sample is bisected, on
 * ODE's narrow phase. Conservative advancement on ccd.c's distances
 * (sc_toi_ca_*: time advances by gap / motion bound) is here for the tests
 * and benchmarks that compare it; the frame does not use it. */
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
static int deepest_at(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double t,
                      double stop, double *depth, double *n)
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
    return deepest_at(ctx, a, a0, a1, b, b0, b1, t, stop, depth, NULL);
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
static int sample_touch(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                        const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
                        double t0, double tmax, double *t)
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
static int sample_deepen(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                         const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                         const sc_pose *b1, double limit_m, double t0, double tmax, double *t)
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

/* ---- conservative advancement (convex pairs) ---- */

#define CA_MAX_STEPS 64      /* then the sampling search takes the rest */
#define CA_LAND 0.5          /* a step may end this share of tol deep */
#define CA_SHALLOW 0.125     /* a landing shallower than this share of tol */
#define CA_REFINE 0.75       /* moves on to at most this share deep, so that
                                the narrow phase surely sees the touch (ODE's
                                sphere-convex collider reads depths up to
                                4e-7 m short and misses shallower ones) */
#define CA_DEEP_STEP 0.05    /* shortest deepening step, share of the limit */
/* q_slerp() interpolates linearly (nlerp) between rotations closer than
 * 2 acos(0.9995) = 0.063 rad, turning up to 2 tan(phi/2) / phi < 1.0001
 * times faster than uniformly in the middle: the rotation bound allows it */
#define CA_NLERP_SLACK 1.001

/* The pair's motion: b's translation relative to a's per unit t, and the
 * most any point can move by rotation per unit t (angle times the radius
 * about the shape origin; spheres turn in place, planes are static). */
typedef struct ca_motion {
    double dx[3];
    double rot;
} ca_motion;

static double rot_bound(const sc_shape *s, const sc_pose *p0, const sc_pose *p1)
{
    if (s->kind == SC_SHAPE_SPHERE || s->kind == SC_SHAPE_PLANE)
        return 0;
    return q_angle_between(p0->quat, p1->quat) * s->bound_r * CA_NLERP_SLACK;
}

static void ca_motion_of(ca_motion *m, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                         const sc_shape *b, const sc_pose *b0, const sc_pose *b1)
{
    for (int k = 0; k < 3; k++)
        m->dx[k] = (b1->pos[k] - b0->pos[k]) - (a1->pos[k] - a0->pos[k]);
    m->rot = rot_bound(a, a0, a1) + rot_bound(b, b0, b1);
}

/* How fast the gap along n can close (or a depth along n grow), per unit t. */
static double ca_rate(const ca_motion *m, const double n[3])
{
    return fabs(v3_dot(m->dx, n)) + m->rot;
}

/* The pair at time t (poses to pa, pb): apart (distance, direction) or
 * overlapping; no depth (it would cost an MPR penetration query), GJK
 * starting along hint. */
static int ca_at(const sc_shape *a, const sc_pose *a0, const sc_pose *a1, const sc_shape *b,
                 const sc_pose *b0, const sc_pose *b1, double t, const double *hint,
                 sc_pose *pa, sc_pose *pb, sc_ccd_sep *s)
{
    sc_pose_lerp(pa, a0, a1, t);
    sc_pose_lerp(pb, b0, b1, t);
    return sc_ccd_separation(a, pa, b, pb, 0, hint, s);
}

int sc_toi_ca_pair(const sc_shape *a, const sc_pose *a0, const sc_pose *a1, const sc_shape *b,
                   const sc_pose *b0, const sc_pose *b1)
{
    int pa = a->kind == SC_SHAPE_PLANE, pb = b->kind == SC_SHAPE_PLANE;
    if (pa && pb)
        return 0;
    if (pa)
        return sc_ccd_convex(b) && memcmp(a0, a1, sizeof *a0) == 0;
    if (pb)
        return sc_ccd_convex(a) && memcmp(b0, b1, sizeof *b0) == 0;
    return sc_ccd_convex(a) && sc_ccd_convex(b);
}

/* Step k goes from t to t + (gap + CA_LAND tol) / rate, gap the pair's
 * exact separation along the closest direction n at t: over the step the
 * gap along n falls by at most rate per unit t, so the shapes are never
 * more than CA_LAND tol deep (a deeper overlap would need more), and a
 * step that ends overlapping has found the touch. The times depend on
 * nothing but the inputs, and a search stops only at its answer or at a
 * time >= tmax, so an answer before tmax is the full search's. */
int sc_toi_ca_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                         const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                         const sc_pose *b1, double tol_m, double tmax, double *t)
{
    if (!ctx || !a || !b || !a0 || !a1 || !b0 || !b1 || !t || !(tol_m > 0) || !isfinite(tol_m))
        return SC_EINVAL;
    if (!sc_toi_ca_pair(a, a0, a1, b, b0, b1))
        return SC_ENOTSUP;
    ca_motion m;
    ca_motion_of(&m, a, a0, a1, b, b0, b1);
    sc_ccd_sep s, sn;
    sc_pose pa, pb;
    int rc = ca_at(a, a0, a1, b, b0, b1, 0, NULL, &pa, &pb, &s);
    if (rc < 0)
        return rc;
    if (s.overlap) {
        /* touching at the start as the narrow phase sees it (the frame's
         * view): time 0; overlapping by less than it sees (ODE's
         * sphere-convex collider reads depths up to 4e-7 m short): the
         * sampling search, as for any pair it takes as apart */
        double d;
        rc = depth_at(ctx, a, a0, a1, b, b0, b1, 0, -1, &d);
        if (rc < 0)
            return rc;
        if (d >= 0) {
            *t = 0;
            return 1;
        }
        return sample_touch(ctx, a, a0, a1, b, b0, b1, tol_m, 0, tmax, t);
    }
    double now = 0;
    for (int k = 0; k < CA_MAX_STEPS; k++) {
        if (!(now < tmax) || !(now < 1))
            return 0;
        double rate = ca_rate(&m, s.n);
        if (!(rate > 0))
            return 0;     /* nothing closes the gap along n */
        double next = min_d(now + (s.gap + CA_LAND * tol_m) / rate, 1);
        rc = ca_at(a, a0, a1, b, b0, b1, next, s.n, &pa, &pb, &sn);
        if (rc < 0)
            return rc;
        if (!sn.overlap) {
            now = next;
            s = sn;
            continue;
        }
        /* a touch within CA_LAND tol; a grazing one may be too shallow for
         * the narrow phase: on to at most CA_REFINE tol, if it still
         * overlaps there. The depth is exact where a sphere's radius holds
         * it, else bounded by the extent along the last direction (no
         * penetration query: in a head-on approach it is the depth) */
        double depth = sn.dist < 0 ? -sn.dist : -sc_ccd_gap(a, &pa, b, &pb, s.n);
        if (depth < CA_SHALLOW * tol_m && next < 1) {
            double deeper = min_d(now + (s.gap + CA_REFINE * tol_m) / rate, 1);
            sc_ccd_sep sd;
            rc = ca_at(a, a0, a1, b, b0, b1, deeper, s.n, &pa, &pb, &sd);
            if (rc < 0)
                return rc;
            if (sd.overlap)
                next = deeper;
        }
        *t = next;
        return 1;
    }
    /* a long graze (a pair sliding close by while turning): the sampling
     * search from here on */
    return sample_touch(ctx, a, a0, a1, b, b0, b1, tol_m, now, tmax, t);
}

/* The pair at pa, pb for the deepening search, from the direction n it
 * carries (starting from the narrow phase's normal: depths change little
 * from step to step). The gap along n bounds the signed distance from
 * below, so it alone keeps a step safe and needs no GJK or MPR: they are
 * asked only where it says the pair is apart (GJK's closest direction
 * then) or past the limit (MPR's direction may bound the depth tighter:
 * it is off now and then, by more than 2x on some polytope overlaps,
 * libccd #71, so it only confirms). */
static int ca_deep_at(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                      const sc_pose *pb, const double n[3], double limit_m, sc_ccd_sep *s)
{
    double g = sc_ccd_gap(a, pa, b, pb, n);
    if (g <= 0 && -g <= limit_m) {
        s->overlap = 1;       /* or nearly: only the step uses it here */
        s->gap = s->dist = g;
        v3_copy(s->n, n);
        return SC_OK;
    }
    /* n is one of the directions it tries where they overlap */
    return sc_ccd_separation(a, pa, b, pb, 1, n, s);
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
static int held_limit(double d, double *limit)
{
    if (d > 2 * *limit)
        return 0;
    double tol = *limit / SC_TOI_AIM;
    if (d > *limit)
        *limit = d <= tol ? tol : d + 0.01 * tol;
    return 1;
}

/* The deepening search: steps of (gap + limit) / rate keep the depth
 * within the limit (the gap is -depth along n where they overlap), at
 * least CA_DEEP_STEP of the limit, so that one that passes it ends a
 * step: the time before that step is the answer. The depth at the start
 * is the narrow phase's, as in the sampling search, so both searches
 * apply the same rules to the same pairs. The depth here is the shapes'
 * penetration depth; the narrow phase's contacts at an edge may read
 * deeper (a clipped point's depth along a face normal). */
int sc_toi_ca_deepen_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                                const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                                const sc_pose *b1, double limit_m, double tmax, double *t)
{
    if (!ctx || !a || !b || !a0 || !a1 || !b0 || !b1 || !t || !(limit_m > 0) ||
        !isfinite(limit_m))
        return SC_EINVAL;
    if (!sc_toi_ca_pair(a, a0, a1, b, b0, b1))
        return SC_ENOTSUP;
    ca_motion m;
    ca_motion_of(&m, a, a0, a1, b, b0, b1);
    sc_ccd_sep s, sn;
    sc_pose pa, pb;
    double d0, n0[3];
    int rc = deepest_at(ctx, a, a0, a1, b, b0, b1, 0, INFINITY, &d0, n0);
    if (rc < 0)
        return rc;
    /* as the sampling search */
    if (!held_limit(d0, &limit_m))
        return 0;
    sc_pose_lerp(&pa, a0, a1, 0);
    sc_pose_lerp(&pb, b0, b1, 0);
    if (d0 >= 0)
        rc = ca_deep_at(a, &pa, b, &pb, n0, limit_m, &s);
    else
        rc = sc_ccd_separation(a, &pa, b, &pb, 1, NULL, &s);
    if (rc < 0)
        return rc;
    double now = 0;
    for (int k = 0; k < CA_MAX_STEPS; k++) {
        if (!(now < tmax) || !(now < 1))
            return 0;
        double rate = ca_rate(&m, s.n);
        if (!(rate > 0))
            return 0;
        double room = max_d(s.gap + limit_m, CA_DEEP_STEP * limit_m);
        double next = min_d(now + room / rate, 1);
        sc_pose_lerp(&pa, a0, a1, next);
        sc_pose_lerp(&pb, b0, b1, next);
        if ((rc = ca_deep_at(a, &pa, b, &pb, s.n, limit_m, &sn)) < 0)
            return rc;
        if (sn.overlap && -sn.gap > limit_m) {
            *t = now;
            return 1;
        }
        now = next;
        s = sn;
    }
    return sample_deepen(ctx, a, a0, a1, b, b0, b1, limit_m, now, tmax, t);
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
    return sample_touch(ctx, a, a0, a1, b, b0, b1, tol_m, 0, tmax, t);
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
    if (!held_limit(d, &limit_m))
        return 0;
    return sample_deepen(ctx, a, a0, a1, b, b0, b1, limit_m, 0, tmax, t);
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
    /* not routed to conservative advancement for convex pairs, though it
     * is faster a query: its touches are shallower (at most tol/2, where
     * the sampling aims at 0.9 tol), and shallower touches gain elastic
     * bodies more energy, in both time-of-impact modes; docs/DESIGN.md
     * 3.4 */
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
