/* toi_ca.c - conservative advancement (docs/DESIGN.md 3.4): the time of
 * impact of convex pairs on ccd.c's distances, time advancing by gap /
 * motion bound. The library's sampling search (lib/core/toi.c) takes a
 * long graze's rest and a start the narrow phase sees apart. */
#include "ca.h"
#include "vecmath.h"

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
        /* overlapping at the start: the sampling search gives time 0
         * where the narrow phase sees the touch too (the frame's view), and
         * searches on where it does not (ODE's sphere-convex collider reads
         * depths up to 4e-7 m short), as for any pair it takes as apart */
        return sc_toi_sample_before_ctx(ctx, a, a0, a1, b, b0, b1, tol_m, tmax, t);
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
    return sc_toi_sample_from_ctx(ctx, a, a0, a1, b, b0, b1, tol_m, now, tmax, t);
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
    int rc = sc_toi_deepest_at(ctx, a, a0, a1, b, b0, b1, 0, INFINITY, &d0, n0);
    if (rc < 0)
        return rc;
    /* as the sampling search */
    if (!sc_toi_held_limit(d0, &limit_m))
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
    return sc_toi_sample_deepen_from_ctx(ctx, a, a0, a1, b, b0, b1, limit_m, now, tmax, t);
}
