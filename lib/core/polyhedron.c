/* polyhedron.c - polygon faces of convex shapes and a face-clipping
 * contact manifold for convex pairs (docs/DESIGN.md 3.3). ODE's convex
 * colliders return one contact per pair, so a body resting face on face
 * rocks from corner to corner and digs in; as Bullet and Box2D do, the
 * incident face is clipped by the reference face's side planes and the
 * points below it kept, each with its depth. A pure function of the two
 * poses; coplanar mesh triangles are merged into faces when the shape is
 * built. */
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "vecmath.h"

/* Triangles whose normals differ by less than about 1e-5 rad and whose
 * planes are closer than this share of the bounding radius are one face. */
#define FACE_COS_TOL (1 - 5e-11)
#define FACE_DIST_TOL 1e-7
/* Merging costs ntris * nfaces; beyond this the shape gets no faces and
 * keeps ODE's single contact (safe, only less stable at rest). */
#define FACE_BUDGET 5e7
/* A face axis is taken when it is at most this much deeper than the
 * collider's contact (its axis may be an edge-edge one): faces resting on
 * faces are what needs the manifold. */
#define FACE_PREFER 1.05
/* The face axis test costs faces * corners both ways; beyond this, keep
 * the collider's contact. */
#define SAT_BUDGET 1e6
#define CLIP_MAX 128        /* points of a clipped polygon */

void sc_poly_free(sc_shape *s)
{
    free(s->face_xyz);
    free(s->face_soa);
    free(s->face_plane_soa);
    s->face_soa = s->face_plane_soa = NULL;
    free(s->face_plane);
    free(s->face_start);
    free(s->face_vert);
    free(s->face_inner);
    s->face_xyz = s->face_plane = NULL;
    s->face_start = s->face_vert = NULL;
    s->nfaces = s->nface_xyz = 0;
}

/* A box's 8 corners and 6 square faces, counter-clockwise seen from out. */
static int build_box(sc_shape *s)
{
    static const int quad[6][4] = {
        { 1, 3, 7, 5 }, { 0, 4, 6, 2 },     /* +x, -x */
        { 2, 6, 7, 3 }, { 0, 1, 5, 4 },     /* +y, -y */
        { 4, 5, 7, 6 }, { 0, 2, 3, 1 },     /* +z, -z */
    };
    s->face_xyz = sc_alloc_array(24, sizeof *s->face_xyz);
    s->face_plane = sc_alloc_array(24, sizeof *s->face_plane);
    s->face_start = sc_alloc_array(7, sizeof *s->face_start);
    s->face_vert = sc_alloc_array(24, sizeof *s->face_vert);
    if (!s->face_xyz || !s->face_plane || !s->face_start || !s->face_vert) {
        sc_poly_free(s);
        return SC_ENOMEM;
    }
    for (int i = 0; i < 8; i++)          /* corner i: bit k set = +half[k] */
        for (int k = 0; k < 3; k++)
            s->face_xyz[3 * i + k] = (i >> k & 1) ? s->half[k] : -s->half[k];
    for (int f = 0; f < 6; f++) {
        int axis = f / 2;
        double sign = (f % 2) ? -1 : 1;
        double *pl = &s->face_plane[4 * f];
        v3_set(pl, 0, 0, 0);
        pl[axis] = sign;
        pl[3] = s->half[axis];
        s->face_start[f] = 4 * f;
        memcpy(&s->face_vert[4 * f], quad[f], sizeof quad[f]);
    }
    s->face_start[6] = 24;
    s->nfaces = 6;
    s->nface_xyz = 8;
    return SC_OK;
}

/* Indices idx[0..n) of points p (face plane with normal nrm) reordered in
 * place as their 2D convex hull, counter-clockwise about nrm (Andrew's
 * monotone chain; collinear and inner points dropped). Returns the count. */
static int face_hull(const double *p, const double nrm[3], int *idx, int n, double *u2)
{
    double u[3], v[3], t[3] = { 1, 0, 0 };
    if (fabs(nrm[0]) > 0.6)
        v3_set(t, 0, 1, 0);
    v3_cross(u, nrm, t);
    v3_normalize(u);
    v3_cross(v, nrm, u);       /* (u, v, nrm) right-handed: CCW about nrm */
    for (int i = 0; i < n; i++) {
        u2[2 * i] = v3_dot(&p[3 * idx[i]], u);
        u2[2 * i + 1] = v3_dot(&p[3 * idx[i]], v);
    }
    /* sort by (u, v), carrying the index (insertion sort: faces are small) */
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && (u2[2 * j] < u2[2 * j - 2] ||
                                  (u2[2 * j] == u2[2 * j - 2] && u2[2 * j + 1] < u2[2 * j - 1]));
             j--) {
            double a = u2[2 * j], b = u2[2 * j + 1];
            u2[2 * j] = u2[2 * j - 2]; u2[2 * j + 1] = u2[2 * j - 1];
            u2[2 * j - 2] = a; u2[2 * j - 1] = b;
            int k = idx[j]; idx[j] = idx[j - 1]; idx[j - 1] = k;
        }
    int *h = sc_alloc_array((size_t)2 * n + 1, sizeof *h);   /* positions into idx */
    if (!h)
        return -1;
    int m = 0;
#define CROSS(o, a, b) ((u2[2 * (a)] - u2[2 * (o)]) * (u2[2 * (b) + 1] - u2[2 * (o) + 1]) - \
                        (u2[2 * (a) + 1] - u2[2 * (o) + 1]) * (u2[2 * (b)] - u2[2 * (o)]))
    for (int i = 0; i < n; i++) {                       /* lower chain */
        while (m >= 2 && CROSS(h[m - 2], h[m - 1], i) <= 0)
            m--;
        h[m++] = i;
    }
    for (int i = n - 2, lo = m + 1; i >= 0; i--) {      /* upper chain */
        while (m >= lo && CROSS(h[m - 2], h[m - 1], i) <= 0)
            m--;
        h[m++] = i;
    }
#undef CROSS
    m = n > 1 ? m - 1 : n;     /* the last point repeats the first */
    int *out = sc_alloc_array((size_t)(m > 0 ? m : 1), sizeof *out);
    if (!out) {
        free(h);
        return -1;
    }
    for (int i = 0; i < m; i++)
        out[i] = idx[h[i]];
    memcpy(idx, out, (size_t)m * sizeof *idx);
    free(out);
    free(h);
    return m;
}

/* A convex mesh's faces: coplanar triangles merged, each face the convex
 * polygon of its triangles' corners. */
static int build_mesh(sc_shape *s)
{
    int nt = s->ntris, rc = SC_ENOMEM;
    double *plane = sc_alloc_array((size_t)nt * 4, sizeof *plane);
    int *tface = sc_alloc_array((size_t)nt, sizeof *tface);
    int *start = sc_calloc_array((size_t)nt + 1, sizeof *start);
    int *vert = sc_alloc_array((size_t)nt * 3, sizeof *vert);
    int *seen = sc_alloc_array((size_t)s->nverts, sizeof *seen);
    double *u2 = sc_alloc_array((size_t)nt * 6, sizeof *u2);
    double *xyz = sc_alloc_array((size_t)s->nverts * 3, sizeof *xyz);
    if (!plane || !tface || !start || !vert || !seen || !u2 || !xyz)
        goto out;
    int nf = 0;
    double work = 0, dtol = FACE_DIST_TOL * s->bound_r;
    for (int t = 0; t < nt; t++) {
        const int *f = &s->tri[3 * t];
        double n[3];
        tri_normal(n, &s->xyz[3 * f[0]], &s->xyz[3 * f[1]], &s->xyz[3 * f[2]]);
        double d = v3_dot(n, &s->xyz[3 * f[0]]);
        /* latest faces first: neighbouring triangles tend to be listed
         * together */
        int hit = -1;
        for (int k = nf - 1; k >= 0 && hit < 0; k--)
            if (v3_dot(n, &plane[4 * k]) > FACE_COS_TOL && fabs(d - plane[4 * k + 3]) <= dtol)
                hit = k;
        work += nf;
        if (work > FACE_BUDGET) {
            rc = SC_OK;        /* too big to merge: no faces, ODE's contact */
            goto out;
        }
        if (hit < 0) {
            hit = nf++;
            v3_copy(&plane[4 * hit], n);
            plane[4 * hit + 3] = d;
        }
        tface[t] = hit;
    }
    /* each face's distinct corners, in triangle order, then as a polygon */
    for (int i = 0; i < s->nverts; i++)
        seen[i] = -1;
    int nv = 0;
    for (int fi = 0; fi < nf; fi++) {
        int first = nv;
        for (int t = 0; t < nt; t++) {
            if (tface[t] != fi)
                continue;
            for (int k = 0; k < 3; k++) {
                int v = s->tri[3 * t + k];
                if (seen[v] != fi) {
                    seen[v] = fi;
                    vert[nv++] = v;
                }
            }
        }
        int m = face_hull(s->xyz, &plane[4 * fi], &vert[first], nv - first, u2);
        if (m < 0)
            goto out;
        nv = first + m;
        start[fi] = first;
        work += nt;
        if (work > FACE_BUDGET) {
            rc = SC_OK;
            goto out;
        }
    }
    start[nf] = nv;
    memcpy(xyz, s->xyz, (size_t)s->nverts * 3 * sizeof *xyz);
    s->face_xyz = xyz;
    s->face_plane = plane;
    s->face_start = start;
    s->face_vert = vert;
    s->nfaces = nf;
    s->nface_xyz = s->nverts;
    xyz = NULL;
    plane = NULL;
    start = vert = NULL;
    rc = SC_OK;
out:
    free(plane);
    free(tface);
    free(start);
    free(vert);
    free(seen);
    free(u2);
    free(xyz);
    return rc;
}

double *sc_soa_pairs(const double *src, int n, int width)
{
    int pairs = (n + 1) / 2;
    double *out = n > 0 ? sc_alloc_array((size_t)pairs * 2 * width, sizeof *out) : NULL;
    for (int p = 0; out && p < pairs; p++)
        for (int j = 0; j < 2; j++) {
            int v = 2 * p + j < n ? 2 * p + j : n - 1;
            for (int k = 0; k < width; k++)
                out[2 * width * p + 2 * k + j] = src[width * v + k];
        }
    return out;
}

/* face_soa and face_plane_soa from face_xyz and face_plane: corners and
 * face planes by pairs for corners_min() and ball_beyond_face(). */
static int build_soa(sc_shape *s)
{
    if (s->nface_xyz == 0 || s->nfaces == 0)
        return SC_OK;
    s->face_soa = sc_soa_pairs(s->face_xyz, s->nface_xyz, 3);
    s->face_plane_soa = sc_soa_pairs(s->face_plane, s->nfaces, 4);
    if (!s->face_soa || !s->face_plane_soa) {
        sc_poly_free(s);
        return SC_ENOMEM;
    }
    return SC_OK;
}

int sc_poly_build(sc_shape *s)
{
    int rc = SC_OK;
    if (s->kind == SC_SHAPE_BOX)
        rc = build_box(s);
    else if ((s->kind == SC_SHAPE_MESH || s->kind == SC_SHAPE_CONVEX) && s->convex)
        rc = build_mesh(s);
    return rc == SC_OK ? build_soa(s) : rc;
}

/* The face of s (rotation R) whose outward normal is closest to dir (world). */
static int best_face(const sc_shape *s, const double R[9], const double dir[3])
{
    double local[3];
    m3_tmulv(local, R, dir);
    int best = 0;
    double bc = -2;
    for (int f = 0; f < s->nfaces; f++) {
        if (s->face_inner && s->face_inner[f])
            continue;
        double c = v3_dot(local, &s->face_plane[4 * f]);
        if (c > bc) {
            bc = c;
            best = f;
        }
    }
    return best;
}

/* The least projection of o's corners (rotation Ro) on world direction
 * nw, in o's frame; it stops at the first pair of corners that brings it
 * to stop or below (callers compare the answer with stop only). With
 * SSE2, two corners at a time from face_soa: each projection is the same
 * products summed in the same order as v3_dot(), and MINPD with the new
 * value first is min_d() (ties and NaN keep the old), so the answer is the
 * same value, bit for bit; this loop is a large share of a pile's narrow
 * phase. */
static double corners_min(const sc_shape *o, const double Ro[9], const double nw[3], double stop)
{
    double nl[3], lo = INFINITY;
    m3_tmulv(nl, Ro, nw);               /* the direction in o's frame */
#ifdef __SSE2__
    if (o->face_soa) {
        const double *c = o->face_soa;
        int pairs = (o->nface_xyz + 1) / 2;
        __m128d ax = _mm_set1_pd(nl[0]), ay = _mm_set1_pd(nl[1]), az = _mm_set1_pd(nl[2]);
        __m128d m = _mm_set1_pd(INFINITY), st = _mm_set1_pd(stop);
        int check = stop > -INFINITY;
        for (int p = 0; p < pairs; p++, c += 6) {
            __m128d d = v3_dot2(ax, ay, az, c);
            m = _mm_min_pd(d, m);       /* d < m ? d : m: min_d(m, d) */
            if (check && _mm_movemask_pd(_mm_cmple_pd(m, st)))
                break;
        }
        double two[2];
        _mm_storeu_pd(two, m);
        return min_d(two[0], two[1]);
    }
#endif
    for (int v = 0; v < o->nface_xyz && !(lo <= stop); v++)
        lo = min_d(lo, v3_dot(nl, &o->face_xyz[3 * v]));
    return lo;
}

/* Separating-axis test over the face normals of s (pose Rs, ps) against
 * the corners of o (Ro, po): the least penetration along one of them (< 0:
 * apart), that face in *face. A mesh piece's inner faces are left out. */
static double least_face_depth(const sc_shape *s, const double Rs[9], const double ps[3],
                               const sc_shape *o, const double Ro[9], const double po[3],
                               int *face)
{
    double best = INFINITY;
    *face = 0;
    for (int f = 0; f < s->nfaces; f++) {
        if (s->face_inner && s->face_inner[f])
            continue;                    /* not a surface: nothing is pushed out there */
        const double *pl = &s->face_plane[4 * f];
        double nw[3];
        m3_mulv(nw, Rs, pl);
        double lo = corners_min(o, Ro, nw, -INFINITY);
        double depth = pl[3] + v3_dot(nw, ps) - (lo + v3_dot(nw, po));
        if (depth < best) {
            best = depth;
            *face = f;
        }
    }
    return best;
}

/* 1 if a face plane of s (pose Rs, ps), inner ones included, has every
 * corner of o more than margin beyond it. */
static int face_separates(const sc_shape *s, const double Rs[9], const double ps[3],
                          const sc_shape *o, const double Ro[9], const double po[3],
                          double margin)
{
    for (int f = 0; f < s->nfaces; f++) {
        const double *pl = &s->face_plane[4 * f];
        double nw[3];
        m3_mulv(nw, Rs, pl);
        double lim = pl[3] + v3_dot(nw, ps) - v3_dot(nw, po) + margin;
        if (corners_min(o, Ro, nw, lim) > lim)
            return 1;
    }
    return 0;
}

/* 1 if a face plane of s (pose Rs, ps) has o's bounding ball (about its
 * origin po) wholly beyond it: three multiplications a face, where the
 * corners take a pass over o's corners per face. The same answer as the
 * corners when it says apart, and most tests of a pile end here. */
static int ball_beyond_face(const sc_shape *s, const double Rs[9], const double ps[3],
                            const sc_shape *o, const double po[3], double margin)
{
    double d[3], dl[3];
    v3_sub(d, po, ps);
    m3_tmulv(dl, Rs, d);                /* o's origin in s's frame */
#ifdef __SSE2__
    if (s->face_plane_soa) {
        /* two faces at a time, the same products and sums as v3_dot() */
        const double *q = s->face_plane_soa;
        __m128d x = _mm_set1_pd(dl[0]), y = _mm_set1_pd(dl[1]), z = _mm_set1_pd(dl[2]);
        __m128d r = _mm_set1_pd(o->bound_r + margin);
        for (int p = 0; 2 * p < s->nfaces; p++, q += 8) {
            __m128d dot = v3_dot2(x, y, z, q);    /* v3_dot(pl, dl) */
            if (_mm_movemask_pd(_mm_cmpgt_pd(_mm_sub_pd(dot, _mm_loadu_pd(q + 6)), r)))
                return 1;
        }
        return 0;
    }
#endif
    for (int f = 0; f < s->nfaces; f++) {
        const double *pl = &s->face_plane[4 * f];
        if (v3_dot(pl, dl) - pl[3] > o->bound_r + margin)
            return 1;
    }
    return 0;
}

int sc_poly_apart_by(const sc_shape *a, const double Ra[9], const double pa[3],
                     const sc_shape *b, const double Rb[9], const double pb[3], double margin)
{
    if (a->nfaces == 0 || b->nfaces == 0)
        return 0;
    return ball_beyond_face(a, Ra, pa, b, pb, margin) ||
           ball_beyond_face(b, Rb, pb, a, pa, margin) ||
           face_separates(a, Ra, pa, b, Rb, pb, margin) ||
           face_separates(b, Rb, pb, a, Ra, pa, margin);
}

int sc_poly_apart(const sc_shape *a, const double Ra[9], const double pa[3], const sc_shape *b,
                  const double Rb[9], const double pb[3])
{
    return sc_poly_apart_by(a, Ra, pa, b, Rb, pb, 0);
}

/* Face f of s in world coordinates into p (3 per point); returns the count. */
static int face_world(const sc_shape *s, const double R[9], const double pos[3], int f,
                      double *p)
{
    int n = s->face_start[f + 1] - s->face_start[f];
    for (int i = 0; i < n; i++) {
        double *q = &p[3 * i];
        m3_mulv(q, R, &s->face_xyz[3 * s->face_vert[s->face_start[f] + i]]);
        v3_add(q, q, pos);
    }
    return n;
}

/* Sutherland-Hodgman: the part of polygon in (n points) with
 * dot(side, p) <= lim, into out; returns its count. */
static int clip_side(const double *in, int n, const double side[3], double lim, double *out)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        const double *p = &in[3 * i], *q = &in[3 * ((i + 1) % n)];
        double dp = v3_dot(side, p) - lim, dq = v3_dot(side, q) - lim;
        if (dp <= 0)
            v3_copy(&out[3 * m++], p);
        if ((dp < 0 && dq > 0) || (dp > 0 && dq < 0)) {
            double t = dp / (dp - dq);
            double *r = &out[3 * m++];
            for (int k = 0; k < 3; k++)
                r[k] = p[k] + t * (q[k] - p[k]);
        }
    }
    return m;
}

int sc_poly_clip(const sc_shape *a, const sc_pose *pa, const sc_shape *b, const sc_pose *pb,
                 double depth, sc_contact *out, int max)
{
    if (a->nfaces == 0 || b->nfaces == 0 || max <= 0)
        return 0;
    if ((double)a->nfaces * b->nface_xyz + (double)b->nfaces * a->nface_xyz > SAT_BUDGET)
        return 0;
    double Ra[9], Rb[9];
    q_to_m3(Ra, pa->quat);
    q_to_m3(Rb, pb->quat);
    /* The reference face: the face axis of least penetration (not the
     * collider's normal: ODE's convex-box one can be 15 degrees off a
     * resting face). When an edge-edge axis is clearly shallower (the
     * collider's depth), one point is right: keep the collider's. */
    int fa, fb;
    double da = least_face_depth(a, Ra, pa->pos, b, Rb, pb->pos, &fa);
    double db = least_face_depth(b, Rb, pb->pos, a, Ra, pa->pos, &fb);
    int ref_is_a = da <= db;
    double dref = min_d(da, db);
    if (!(dref <= FACE_PREFER * depth + 1e-9 * min_d(a->bound_r, b->bound_r)))
        return 0;
    const sc_shape *rs = ref_is_a ? a : b, *is = ref_is_a ? b : a;
    const double *rR = ref_is_a ? Ra : Rb, *iR = ref_is_a ? Rb : Ra;
    const sc_pose *rp = ref_is_a ? pa : pb, *ip = ref_is_a ? pb : pa;
    int rf = ref_is_a ? fa : fb;
    double rn[3], back[3];
    m3_mulv(rn, rR, &rs->face_plane[4 * rf]);
    v3_scale(back, rn, -1);
    int inf = best_face(is, iR, back);
    int nr = rs->face_start[rf + 1] - rs->face_start[rf];
    int ni = is->face_start[inf + 1] - is->face_start[inf];
    if (nr + ni > CLIP_MAX / 2)
        return 0;                        /* huge faces: keep ODE's contact */
    double ref[3 * CLIP_MAX], buf[2][3 * CLIP_MAX];
    face_world(rs, rR, rp->pos, rf, ref);
    int n = face_world(is, iR, ip->pos, inf, buf[0]);
    double rd = rs->face_plane[4 * rf + 3] + v3_dot(rn, rp->pos);
    int cur = 0;
    for (int e = 0; e < nr && n > 0; e++) {
        const double *p = &ref[3 * e], *q = &ref[3 * ((e + 1) % nr)];
        double edge[3], side[3];
        v3_sub(edge, q, p);
        v3_cross(side, edge, rn);        /* outward: the polygon is CCW about rn */
        if (v3_normalize(side) == 0)
            continue;
        n = clip_side(buf[cur], n, side, v3_dot(side, p), buf[1 - cur]);
        cur = 1 - cur;
    }
    sc_contact c[CLIP_MAX];
    int m = 0;
    for (int i = 0; i < n; i++) {
        const double *p = &buf[cur][3 * i];
        double d = rd - v3_dot(rn, p);
        if (!(d >= 0))
            continue;
        sc_contact *k = &c[m++];
        k->body_a = k->body_b = -1;
        v3_madd(k->pos, p, rn, 0.5 * d);       /* midway between the surfaces */
        v3_scale(k->normal, rn, ref_is_a ? 1 : -1);
        k->depth = d;
    }
    if (m > max)
        m = sc_manifold_reduce(c, m, 0);
    if (m > max)
        m = max;
    memcpy(out, c, (size_t)m * sizeof *out);
    return m;
}
