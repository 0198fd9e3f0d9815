/* ccd.c - distances between convex shapes (docs/DESIGN.md 3.4), for
 * conservative advancement (toi_ca.c). Shapes go to libccd 2.1 as support
 * functions inflated by a margin (FCL's trick); as libccd has no distance
 * query, a GJK distance of our own runs on the shapes' cores. libccd's
 * known defects (danfis/libccd #7, #25, #44, #71) are worked around where
 * its calls are set up. Every function here is pure, so a query gives the
 * same bits on any thread. */
#include <ccd/ccd.h>

#include "ca.h"
#include "vecmath.h"

#define CCD_MAX_ITER 128     /* libccd GJK and MPR iterations */
#define CCD_MPR_TOL 1e-9     /* m: MPR's portal tolerance */
#define CCD_EPA_TOL 1e-12    /* EPA's stop test mixes a length and its square
                                (libccd #44): it stops at about 1e-12 / depth m */
#define GJK_MAX_ITER 64
#define GJK_EPS 1e-10        /* m: the distance's upper and lower bound this close */
#define GJK_TOUCH 1e-12      /* m: cores closer than this overlap */

int sc_ccd_convex(const sc_shape *s)
{
    if (!s)
        return 0;
    switch (s->kind) {
    case SC_SHAPE_SPHERE:
    case SC_SHAPE_BOX:
    case SC_SHAPE_CONVEX: return 1;
    case SC_SHAPE_MESH: return s->convex;
    default: return 0;
    }
}

void sc_ccd_obj_init(sc_ccd_obj *o, const sc_shape *s, const sc_pose *p, double margin_m)
{
    o->s = s;
    v3_copy(o->pos, p->pos);
    q_to_m3(o->R, p->quat);
    o->round = margin_m + (s->kind == SC_SHAPE_SPHERE ? s->radius : 0);
}

/* The point of o's core farthest along d (world frame, any length): a
 * sphere's centre, a box's corner, a hull's vertex. Ties go to the first
 * vertex (or the + corner), so the answer is a function of d alone. */
static void core_support(const sc_ccd_obj *o, const double d[3], double out[3])
{
    const sc_shape *s = o->s;
    double l[3], p[3] = { 0, 0, 0 };
    m3_tmulv(l, o->R, d);
    if (s->kind == SC_SHAPE_BOX) {
        for (int k = 0; k < 3; k++)
            p[k] = l[k] < 0 ? -s->half[k] : s->half[k];
    } else if (s->kind != SC_SHAPE_SPHERE) {
        /* a scan of the vertices: the project's hulls have tens of them,
         * too few for hill climbing to pay */
        const double *v = s->xyz;
        int best = 0;
        double bd = v3_dot(v, l);
        for (int i = 1; i < s->nverts; i++) {
            double dd = v3_dot(&v[3 * i], l);
            if (dd > bd) {
                bd = dd;
                best = i;
            }
        }
        v3_copy(p, &v[3 * best]);
    }
    m3_mulv(out, o->R, p);
    v3_add(out, out, o->pos);
}

void sc_ccd_support(const sc_ccd_obj *o, const double d[3], double out[3])
{
    core_support(o, d, out);
    double l = v3_len(d);
    if (o->round > 0 && l > 0)
        v3_madd(out, out, d, o->round / l);
}

/* ---- libccd ---- */

static void ccd_support_cb(const void *obj, const ccd_vec3_t *dir, ccd_vec3_t *out)
{
    sc_ccd_support(obj, dir->v, out->v);
}

/* A point inside the shape for MPR: the centre of mass (inside any convex
 * solid; a hull's shape origin need not be). */
static void ccd_center_cb(const void *obj, ccd_vec3_t *c)
{
    const sc_ccd_obj *o = obj;
    m3_mulv(c->v, o->R, o->s->mp.com);
    v3_add(c->v, c->v, o->pos);
}

/* GJK's first direction: the line between the centres (libccd's default
 * (1, 0, 0) fails on stacked boxes, #25). */
static void ccd_first_dir_cb(const void *o1, const void *o2, ccd_vec3_t *dir)
{
    ccd_vec3_t c1, c2;
    ccd_center_cb(o1, &c1);
    ccd_center_cb(o2, &c2);
    v3_sub(dir->v, c2.v, c1.v);
    if (!(v3_dot(dir->v, dir->v) > 1e-24))
        v3_set(dir->v, 1, 0, 0);
}

static void ccd_setup(ccd_t *c)
{
    CCD_INIT(c);
    c->first_dir = ccd_first_dir_cb;
    c->support1 = c->support2 = ccd_support_cb;
    c->center1 = c->center2 = ccd_center_cb;
    c->max_iterations = CCD_MAX_ITER;
    c->mpr_tolerance = CCD_MPR_TOL;
    c->epa_tolerance = CCD_EPA_TOL;
}

static int pose_ok(const sc_pose *p)
{
    if (!p || !sc_finite3(p->pos))
        return 0;
    double n = p->quat[0] * p->quat[0] + p->quat[1] * p->quat[1] + p->quat[2] * p->quat[2] +
               p->quat[3] * p->quat[3];
    return isfinite(n) && fabs(n - 1) < 1e-6;
}

static int pair_check(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                      const sc_pose *pb, double margin_m)
{
    if (!a || !b || !pose_ok(pa) || !pose_ok(pb) || !(margin_m >= 0) || !isfinite(margin_m))
        return SC_EINVAL;
    return sc_ccd_convex(a) && sc_ccd_convex(b) ? SC_OK : SC_ENOTSUP;
}

int sc_ccd_intersect(int method, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                     const sc_pose *pb, double margin_m)
{
    int rc = pair_check(a, pa, b, pb, margin_m);
    if (rc < 0)
        return rc;
    sc_ccd_obj oa, ob;
    sc_ccd_obj_init(&oa, a, pa, 0.5 * margin_m);
    sc_ccd_obj_init(&ob, b, pb, 0.5 * margin_m);
    ccd_t c;
    ccd_setup(&c);
    return method == SC_CCD_GJK ? ccdGJKIntersect(&oa, &ob, &c) != 0
                                : ccdMPRIntersect(&oa, &ob, &c) != 0;
}

int sc_ccd_penetration(int method, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                       const sc_pose *pb, double margin_m, double *depth, double n[3])
{
    int rc = pair_check(a, pa, b, pb, margin_m);
    if (rc < 0)
        return rc;
    if (!depth || !n)
        return SC_EINVAL;
    sc_ccd_obj oa, ob;
    sc_ccd_obj_init(&oa, a, pa, 0.5 * margin_m);
    sc_ccd_obj_init(&ob, b, pb, 0.5 * margin_m);
    ccd_t c;
    ccd_setup(&c);
    /* a touching pair is "intersecting" without depth or direction */
    ccd_real_t d = 0;
    ccd_vec3_t dir = { { 0, 0, 0 } }, pos = { { 0, 0, 0 } };
    int r = method == SC_CCD_GJK ? ccdGJKPenetration(&oa, &ob, &c, &d, &dir, &pos)
                                 : ccdMPRPenetration(&oa, &ob, &c, &d, &dir, &pos);
    if (r == -2)
        return SC_ENOMEM;
    if (r != 0)
        return 0;
    /* libccd: moving obj2 (b) by depth along dir separates them; a
     * touching contact has no direction: the centres' line then */
    if (!isfinite(d) || !sc_finite3(dir.v) || v3_normalize(dir.v) == 0) {
        ccd_first_dir_cb(&oa, &ob, &dir);
        v3_normalize(dir.v);
        if (!isfinite(d))
            d = 0;
    }
    *depth = d;
    v3_copy(n, dir.v);
    return 1;
}

int sc_ccd_distance_inflated(int method, const sc_shape *a, const sc_pose *pa,
                             const sc_shape *b, const sc_pose *pb, double margin_m, double *dist)
{
    if (!dist)
        return SC_EINVAL;
    double depth, n[3];
    int rc = sc_ccd_penetration(method, a, pa, b, pb, margin_m, &depth, n);
    if (rc == 1)
        *dist = margin_m - depth;
    return rc;
}

/* ---- GJK distance between the cores ---- */

/* The support of the cores' Minkowski difference A - B along d. */
static void diff_support(const sc_ccd_obj *a, const sc_ccd_obj *b, const double d[3], double w[3])
{
    double sa[3], sb[3], md[3];
    v3_scale(md, d, -1.0);
    core_support(a, d, sa);
    core_support(b, md, sb);
    v3_sub(w, sa, sb);
}

typedef struct simplex {
    double w[4][3];
    int n;
} simplex;

static void keep1(simplex *s, int i)
{
    v3_copy(s->w[0], s->w[i]);
    s->n = 1;
}

static void keep2(simplex *s, int i, int j)
{
    double wi[3], wj[3];
    v3_copy(wi, s->w[i]);
    v3_copy(wj, s->w[j]);
    v3_copy(s->w[0], wi);
    v3_copy(s->w[1], wj);
    s->n = 2;
}

/* The point of segment w0 w1 nearest the origin; the simplex reduced to
 * the feature holding it. */
static void closest_segment(simplex *s, double v[3])
{
    const double *a = s->w[0], *b = s->w[1];
    double ab[3];
    v3_sub(ab, b, a);
    double t = -v3_dot(a, ab), l = v3_dot(ab, ab);
    if (t <= 0 || !(l > 0)) {
        keep1(s, 0);
    } else if (t >= l) {
        keep1(s, 1);
    } else {
        v3_madd(v, a, ab, t / l);
        return;
    }
    v3_copy(v, s->w[0]);
}

/* The same for triangle w0 w1 w2 (Ericson, Real-Time Collision Detection
 * 5.1.5, with the query point at the origin). */
static void closest_triangle(simplex *s, double v[3])
{
    const double *a = s->w[0], *b = s->w[1], *c = s->w[2];
    double ab[3], ac[3];
    v3_sub(ab, b, a);
    v3_sub(ac, c, a);
    double d1 = -v3_dot(ab, a), d2 = -v3_dot(ac, a);
    if (d1 <= 0 && d2 <= 0) {
        keep1(s, 0);
        v3_copy(v, s->w[0]);
        return;
    }
    double d3 = -v3_dot(ab, b), d4 = -v3_dot(ac, b);
    if (d3 >= 0 && d4 <= d3) {
        keep1(s, 1);
        v3_copy(v, s->w[0]);
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double t = d1 / (d1 - d3);
        v3_madd(v, a, ab, t);
        keep2(s, 0, 1);
        return;
    }
    double d5 = -v3_dot(ab, c), d6 = -v3_dot(ac, c);
    if (d6 >= 0 && d5 <= d6) {
        keep1(s, 2);
        v3_copy(v, s->w[0]);
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double t = d2 / (d2 - d6);
        v3_madd(v, a, ac, t);
        keep2(s, 0, 2);
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        double bc[3];
        v3_sub(bc, c, b);
        v3_madd(v, b, bc, t);
        keep2(s, 1, 2);
        return;
    }
    double sum = va + vb + vc;
    if (!(sum > 0) || !isfinite(sum)) {
        /* degenerate (collinear) triangle: its longest edge holds it */
        keep2(s, 0, 1);
        closest_segment(s, v);
        return;
    }
    double dv = vb / sum, dw = vc / sum;
    for (int k = 0; k < 3; k++)
        v[k] = a[k] + ab[k] * dv + ac[k] * dw;
}

/* The same for the tetrahedron w0..w3; returns 1 when it holds the origin. */
static int closest_tetra(simplex *s, double v[3])
{
    static const int face[4][4] = { { 0, 1, 2, 3 }, { 0, 1, 3, 2 }, { 0, 2, 3, 1 },
                                    { 1, 2, 3, 0 } };
    double best = INFINITY;
    simplex keep = *s;
    int outside = 0;
    for (int f = 0; f < 4; f++) {
        const double *a = s->w[face[f][0]], *b = s->w[face[f][1]], *c = s->w[face[f][2]];
        const double *d = s->w[face[f][3]];
        double ab[3], ac[3], nrm[3], ad[3];
        v3_sub(ab, b, a);
        v3_sub(ac, c, a);
        v3_cross(nrm, ab, ac);
        v3_sub(ad, d, a);
        double so = -v3_dot(nrm, a), sd = v3_dot(nrm, ad);
        /* the origin beyond this face (a flat tetrahedron: every face) */
        if (so * sd > 0 && fabs(sd) > 1e-30)
            continue;
        outside = 1;
        simplex t = { .n = 3 };
        v3_copy(t.w[0], a);
        v3_copy(t.w[1], b);
        v3_copy(t.w[2], c);
        double p[3];
        closest_triangle(&t, p);
        double pp = v3_dot(p, p);
        if (pp < best) {
            best = pp;
            keep = t;
            v3_copy(v, p);
        }
    }
    if (!outside)
        return 1;
    *s = keep;
    return 0;
}

/* GJK between the cores of a and b: 1 when they overlap (closer than
 * GJK_TOUCH); else 0 with v the point of A - B nearest the origin, to
 * GJK_EPS (b - a's closest points are -v apart). The search starts along
 * hint (from a towards b; NULL: the line between the origins): the last
 * direction, in a time-of-impact search, saves a third of the steps. */
static int gjk(const sc_ccd_obj *a, const sc_ccd_obj *b, const double *hint, double v[3])
{
    simplex s = { .n = 1 };
    double d[3];
    if (hint)
        v3_copy(d, hint);
    else
        v3_sub(d, b->pos, a->pos);
    if (!(v3_dot(d, d) > 0) || !sc_finite3(d))
        v3_set(d, 1, 0, 0);
    diff_support(a, b, d, s.w[0]);
    v3_copy(v, s.w[0]);
    for (int it = 0; it < GJK_MAX_ITER; it++) {
        double vv = v3_dot(v, v);
        if (vv <= GJK_TOUCH * GJK_TOUCH)
            return 1;
        double w[3], mv[3];
        v3_scale(mv, v, -1.0);
        diff_support(a, b, mv, w);
        /* |v| - v.w / |v| bounds the error of |v| as the distance */
        if (vv - v3_dot(v, w) <= GJK_EPS * sqrt(vv))
            return 0;
        for (int i = 0; i < s.n; i++)
            if (s.w[i][0] == w[0] && s.w[i][1] == w[1] && s.w[i][2] == w[2])
                return 0;   /* no new point: as close as it gets */
        simplex t = s;
        v3_copy(t.w[t.n++], w);
        double nv[3];
        if (t.n == 2) {
            closest_segment(&t, nv);
        } else if (t.n == 3) {
            closest_triangle(&t, nv);
        } else if (closest_tetra(&t, nv)) {
            return 1;
        }
        if (!(v3_dot(nv, nv) < vv))
            return 0;       /* no progress (rounding): keep the last */
        s = t;
        v3_copy(v, nv);
    }
    return 0;
}

/* ---- separation ---- */

/* The largest of n.x over o (core and rounding). */
static double extent(const sc_ccd_obj *o, const double n[3])
{
    double p[3];
    core_support(o, n, p);
    return v3_dot(p, n) + o->round * v3_len(n);
}

/* A plane shape at pose p in the world: unit normal and offset (n.x <= d). */
static void plane_world(const sc_shape *s, const sc_pose *p, double n[3], double *d)
{
    q_rotate(n, p->quat, s->plane);
    *d = s->plane[3] + v3_dot(n, p->pos);
}

/* The largest of u.x over the half space: finite only along its normal
 * (a direction within 1e-12 of it counts as it). */
static double plane_extent(const double pn[3], double pd, const double u[3])
{
    double l = v3_len(u), c = v3_dot(u, pn);
    return c >= l * (1 - 1e-12) ? c * pd : INFINITY;
}

double sc_ccd_gap(const sc_shape *a, const sc_pose *pa, const sc_shape *b, const sc_pose *pb,
                  const double n[3])
{
    double m[3], ea, eb;
    v3_scale(m, n, -1.0);
    if (a->kind == SC_SHAPE_PLANE) {
        double pn[3], pd;
        plane_world(a, pa, pn, &pd);
        ea = plane_extent(pn, pd, n);
    } else {
        sc_ccd_obj o;
        sc_ccd_obj_init(&o, a, pa, 0);
        ea = extent(&o, n);
    }
    if (b->kind == SC_SHAPE_PLANE) {
        double pn[3], pd;
        plane_world(b, pb, pn, &pd);
        eb = plane_extent(pn, pd, m);
    } else {
        sc_ccd_obj o;
        sc_ccd_obj_init(&o, b, pb, 0);
        eb = extent(&o, m);
    }
    return -(ea + eb);
}

/* The outward face normal of s at pose p most along u (world frame): 1,
 * or 0 when s has no faces (spheres; meshes too big to merge faces). */
static int best_face(const sc_shape *s, const sc_pose *p, const double u[3], double out[3])
{
    if (s->nfaces <= 0)
        return 0;
    double R[9], l[3];
    q_to_m3(R, p->quat);
    m3_tmulv(l, R, u);
    int best = 0;
    double bd = v3_dot(&s->face_plane[0], l);
    for (int f = 1; f < s->nfaces; f++) {
        double d = v3_dot(&s->face_plane[4 * f], l);
        if (d > bd) {
            bd = d;
            best = f;
        }
    }
    m3_mulv(out, R, &s->face_plane[4 * best]);
    return 1;
}

/* A convex shape s against a plane: the signed distance is exact. */
static int plane_separation(const sc_shape *pl, const sc_pose *pp, const sc_shape *s,
                            const sc_pose *ps, int plane_is_a, sc_ccd_sep *out)
{
    double pn[3], pd, m[3];
    plane_world(pl, pp, pn, &pd);
    sc_ccd_obj o;
    sc_ccd_obj_init(&o, s, ps, 0);
    v3_scale(m, pn, -1.0);
    /* min of pn.x over s, less the plane's offset */
    out->dist = out->gap = -extent(&o, m) - pd;
    out->overlap = out->dist <= 0;
    v3_scale(out->n, pn, plane_is_a ? 1.0 : -1.0);
    return SC_OK;
}

int sc_ccd_separation(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                      const sc_pose *pb, int want_depth, const double *hint, sc_ccd_sep *out)
{
    if (!a || !b || !out || !pose_ok(pa) || !pose_ok(pb))
        return SC_EINVAL;
    int pla = a->kind == SC_SHAPE_PLANE, plb = b->kind == SC_SHAPE_PLANE;
    if (pla && plb)
        return SC_ENOTSUP;
    if (pla || plb) {
        const sc_shape *s = pla ? b : a;
        if (!sc_ccd_convex(s))
            return SC_ENOTSUP;
        return pla ? plane_separation(a, pa, b, pb, 1, out)
                   : plane_separation(b, pb, a, pa, 0, out);
    }
    if (!sc_ccd_convex(a) || !sc_ccd_convex(b))
        return SC_ENOTSUP;
    sc_ccd_obj oa, ob;
    sc_ccd_obj_init(&oa, a, pa, 0);
    sc_ccd_obj_init(&ob, b, pb, 0);
    double v[3];
    if (!gjk(&oa, &ob, hint, v)) {
        double dc = v3_len(v), m[3];
        v3_scale(out->n, v, -1.0 / dc);     /* from a's closest point to b's */
        v3_scale(m, out->n, -1.0);
        out->dist = dc - oa.round - ob.round;
        out->gap = -(extent(&oa, out->n) + extent(&ob, m));
        out->overlap = out->dist <= 0;
        return SC_OK;
    }
    /* the cores overlap: libccd's MPR for a direction, and the exact depth
     * along it (it separates the shapes, whatever the direction's error) */
    out->overlap = 1;
    out->dist = out->gap = 0;
    v3_sub(out->n, pb->pos, pa->pos);
    if (!(v3_normalize(out->n) > 0))
        v3_set(out->n, 1, 0, 0);
    if (!want_depth)
        return SC_OK;
    double depth;
    int rc = sc_ccd_penetration(SC_CCD_MPR, a, pa, b, pb, 0, &depth, out->n);
    if (rc < 0)
        return rc;
    out->gap = sc_ccd_gap(a, pa, b, pb, out->n);
    if (hint && sc_finite3(hint) && v3_len(hint) > 0) {
        double h[3], g;
        v3_scale(h, hint, 1.0 / v3_len(hint));
        if ((g = sc_ccd_gap(a, pa, b, pb, h)) > out->gap) {
            out->gap = g;
            v3_copy(out->n, h);
        }
    }
    /* libccd 2.1's MPR points at the nearest point of its last portal
     * triangle, not along the triangle's normal (#71): a box sunk into a
     * face gets a tilted direction. The faces of either shape nearest that
     * direction are tried too, and the tightest bound kept: exact for a
     * face on a face or a corner in a face. */
    double f[3], m[3];
    for (int k = 0; k < 2; k++) {
        v3_scale(m, out->n, k ? -1.0 : 1.0);
        if (!best_face(k ? b : a, k ? pb : pa, m, f))
            continue;
        if (k)
            v3_scale(f, f, -1.0);
        double g = sc_ccd_gap(a, pa, b, pb, f);
        if (g > out->gap) {
            out->gap = g;
            v3_copy(out->n, f);
        }
    }
    out->dist = out->gap = min_d(out->gap, 0);
    return SC_OK;
}
