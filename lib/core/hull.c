/* hull.c - 3D convex hull of a point set as a closed, outward triangle mesh
 * (docs/DESIGN.md 3.8): Quickhull with conflict lists (Barber, Dobkin and
 * Huhdanpaa, ACM TOMS 22(4), 1996). Whether a point sees a face is the
 * exact sign of an orientation determinant (Shewchuk's adaptive
 * predicates), so the topology is exact however degenerate the points;
 * whether it joins the hull needs it more than eps above a face, so near
 * duplicates never become vertices. The output holds the caller's
 * coordinates, bit for bit; ties are broken by index. */
#include <float.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "vecmath.h"

/* Quickhull (C. B. Barber, D. P. Dobkin, H. Huhdanpaa, "The Quickhull
 * Algorithm for Convex Hulls", ACM TOMS 22(4), 1996) with conflict lists:
 *   1. an initial tetrahedron from extreme points (degeneracy is found here);
 *   2. the main loop: take the farthest conflict point of a face (the eye),
 *      find the faces it sees and the horizon around them, replace the
 *      visible faces by a cone from the eye to the horizon and hand their
 *      conflict points to the new faces; at the end, points left within eps
 *      outside the hull are checked against every face they see;
 *   3. triangles whose vertices lie within eps of a common plane form a
 *      group (a flat face of the hull); vertices inside a group or on a
 *      straight edge between two groups are not corners: drop them and build
 *      the hull of the rest again (usually once), until none drops;
 *   4. output the vertices still used, in input order, and the triangles.
 *
 * Robustness keeps two kinds of decision apart:
 *   - Topology: whether the eye sees a face is the exact sign of an
 *     orientation determinant (a floating-point filter, else an exact sum
 *     in expansion arithmetic; J. R. Shewchuk, "Adaptive Precision
 *     Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997).
 *     So every step is exact Quickhull on the points: the visible faces
 *     form a disc, the horizon is one simple loop and the hull stays convex,
 *     however many points are coplanar, cocircular or repeated.
 *   - Tolerance: a point joins the hull only when it lies more than eps
 *     above a face ("thick" planes; the rounding of the distance is far
 *     below eps), and step 3 groups within eps. eps = 1e-9 * (max
 *     |coordinate| + bounding-box diagonal), in the caller's units. So
 *     duplicates, near-duplicates and points within eps of a face or an
 *     edge never become vertices; a point set no thicker than eps (all
 *     coincident, collinear or coplanar) has no volume: SC_EDEGENERATE.
 *     Every input point ends inside the hull or within a few eps of it
 *     (within eps of every face's plane unless step 3 dropped a vertex).
 *     Should the hull keep a triangle too small for sc_mesh_check (points
 *     a few eps apart, as float data make), eps grows tenfold, at most to
 *     1e-5 relative, and the rounds go on.
 *
 * The arithmetic runs on a copy of the points scaled by a power of two
 * (exact) to a largest |coordinate| in [0.5, 1) and moved to the centre of
 * their box, so nothing overflows and distances keep their precision far
 * from the origin. The output holds the caller's coordinates, bit for bit.
 * Deterministic: no hashing, no randomness, every tie broken by index.
 * Expected O(n log n) time. */

#ifdef __FAST_MATH__
#error "hull.c needs IEEE arithmetic for its exact predicate: build without -ffast-math"
#endif

#define HULL_EPS_REL 1e-9

/* Fault injection for tests: when >= 0, how many more allocations
 * sc_hull_build may make in this thread before they fail. Deliberately not in
 * a header: only tests/test_hull.c declares it. */
_Thread_local long sc_hull_alloc_budget = -1;

static int alloc_allowed(void)
{
    if (sc_hull_alloc_budget == 0)
        return 0;
    if (sc_hull_alloc_budget > 0)
        sc_hull_alloc_budget--;
    return 1;
}

static void *hull_alloc(size_t n, size_t size)
{
    return alloc_allowed() ? sc_alloc_array(n, size) : NULL;
}

/* p grown to hold at least need elements of size bytes (capacity in *cap);
 * the new block, or NULL with p untouched. */
static void *hull_grow(void *p, int *cap, int need, size_t size)
{
    long long c = *cap > 16 ? *cap : 16;
    while (c < need)
        c *= 2;
    if (c > INT_MAX)
        c = INT_MAX;
    if ((size_t)c > SIZE_MAX / size || !alloc_allowed())
        return NULL;
    void *q = realloc(p, (size_t)c * size);
    if (q)
        *cap = (int)c;
    return q;
}

/* ---- exact orientation ------------------------------------------------------ */

static void two_sum(double a, double b, double *s, double *e)
{
    double x = a + b, bv = x - a, av = x - bv;
    *s = x;
    *e = (a - av) + (b - bv);
}

/* e[0..n) + b into e, a nonoverlapping expansion in increasing magnitude
 * without zeros (Shewchuk's GROW-EXPANSION with zero elimination); returns
 * the new length. */
static int grow_expansion(double *e, int n, double b)
{
    double q = b;
    int m = 0;
    for (int i = 0; i < n; i++) {
        double s, t;
        two_sum(q, e[i], &s, &t);
        if (t != 0)
            e[m++] = t;
        q = s;
    }
    if (q != 0 || m == 0)
        e[m++] = q;
    return m;
}

/* The sign of det[b - a; c - a; d - a], exactly: the 4 x 4 determinant with
 * a column of ones, expanded into 24 triple products of coordinates, each
 * split exactly into 4 doubles (fma gives a product's rounding error) and
 * summed as an expansion. Exact while no product underflows, which the
 * flush in hull_setup guarantees. */
static int orient_exact(const double *a, const double *b, const double *c, const double *d)
{
    /* det3(p, q, r) = sum over permutations s of sign(s) p[s0] q[s1] r[s2] */
    static const int perm[6][4] = { { 0, 1, 2, 1 },  { 0, 2, 1, -1 }, { 1, 0, 2, -1 },
                                    { 1, 2, 0, 1 },  { 2, 0, 1, 1 },  { 2, 1, 0, -1 } };
    /* det[b - a; c - a; d - a] = det3(b,c,d) - det3(a,c,d) + det3(a,b,d) - det3(a,b,c) */
    const double *rows[4][3] = { { b, c, d }, { a, c, d }, { a, b, d }, { a, b, c } };
    double e[4 * 6 * 4 + 1];
    int n = 0;
    for (int r = 0; r < 4; r++)
        for (int s = 0; s < 6; s++) {
            double sg = (r & 1 ? -1 : 1) * perm[s][3];
            double x = rows[r][0][perm[s][0]], y = rows[r][1][perm[s][1]];
            double z = rows[r][2][perm[s][2]];
            double p = x * y, pe = fma(x, y, -p);
            double t[4] = { p * z, fma(p, z, -(p * z)), pe * z, fma(pe, z, -(pe * z)) };
            for (int k = 0; k < 4; k++)
                n = grow_expansion(e, n, sg * t[k]);
        }
    return (e[n - 1] > 0) - (e[n - 1] < 0);
}

/* +1 when d lies above the plane of the counter-clockwise triangle abc
 * (((b - a) x (c - a)) . (d - a) > 0), -1 below, 0 on it; exact. The filter
 * is Shewchuk's error bound for orient3d (the same determinant). */
static int orient(const double *a, const double *b, const double *c, const double *d)
{
    double bx = b[0] - a[0], by = b[1] - a[1], bz = b[2] - a[2];
    double cx = c[0] - a[0], cy = c[1] - a[1], cz = c[2] - a[2];
    double dx = d[0] - a[0], dy = d[1] - a[1], dz = d[2] - a[2];
    double m1 = by * cz, m2 = bz * cy, m3 = bz * cx, m4 = bx * cz, m5 = bx * cy, m6 = by * cx;
    double det = dx * (m1 - m2) + dy * (m3 - m4) + dz * (m5 - m6);
    double perm = fabs(dx) * (fabs(m1) + fabs(m2)) + fabs(dy) * (fabs(m3) + fabs(m4)) +
                  fabs(dz) * (fabs(m5) + fabs(m6));
    const double u = DBL_EPSILON / 2;
    double bound = (7 * u + 56 * u * u) * perm;
    if (det > bound)
        return 1;
    if (-det > bound)
        return -1;
    return orient_exact(a, b, c, d);
}

/* ---- Quickhull ------------------------------------------------------------ */

typedef struct hull_face {
    int v[3];            /* point indices, counter-clockwise seen from outside */
    int adj[3];          /* adj[i]: the face across the edge v[i] -> v[i+1] */
    double n[3], d;      /* unit outward normal; n.x = d on the plane */
    int head;            /* first conflict point (-1: none); free-list link when dead */
    int near;            /* first near point (-1: none) */
    int far;             /* the conflict point farthest above the plane */
    double far_d;
    int mark;            /* visibility pass that last looked at this face */
    signed char vis;     /* seen by the current eye (valid when mark == stamp) */
    signed char alive;
    signed char sliver;  /* n is too rough to bound distances: always ask orient */
} hull_face;

/* A horizon edge u -> w of a visible face; nb is the hidden face beyond it. */
typedef struct hull_edge {
    int u, w, nb;
} hull_edge;

typedef struct hull {
    const double *in;    /* the caller's points */
    double *p;           /* scaled and centred copy, 3 per point */
    int n;
    double eps;          /* in the units of p */
    int *link;           /* conflict and near list links, one per point */
    int *hstart;         /* horizon edge leaving each point, -1 */
    unsigned char *flag; /* per-point scratch bits, 0 between uses */
    int *pool;           /* points to hand to new faces */
    int npool;
    int *keep;           /* the vertices a next round starts from */
    hull_face *f;
    int nf, capf, free_face;
    int *work;           /* faces that may hold conflict points (a stack) */
    int nwork, capwork;
    int *vis;            /* faces the current eye sees */
    int nvis, capvis;
    hull_edge *hz;       /* horizon edges, in discovery order */
    int nhz, caphz;
    int *loop;           /* horizon edges in loop order, then the new faces */
    int caploop;
    double *planes;      /* the new faces' planes, 4 each, for distribute */
    int capplanes;
    int stamp;
} hull;

static void hull_free(hull *h)
{
    free(h->p);
    free(h->link);
    free(h->hstart);
    free(h->flag);
    free(h->pool);
    free(h->keep);
    free(h->f);
    free(h->work);
    free(h->vis);
    free(h->hz);
    free(h->loop);
    free(h->planes);
}

static const double *pt(const hull *h, int i)
{
    return &h->p[3 * (size_t)i];
}

static double face_dist(const hull *h, int f, int i)
{
    return v3_dot(h->f[f].n, pt(h, i)) - h->f[f].d;
}

/* Whether face f sees point i (i lies strictly above its plane), exactly,
 * given d = face_dist(h, f, i). Unless the face is a sliver, d is good to
 * far better than eps / 16 (face_plane), so a d beyond that settles it;
 * otherwise orient does. */
static int face_sees(const hull *h, int f, int i, double d)
{
    if (!h->f[f].sliver && fabs(d) > h->eps / 16)
        return d > 0;
    const int *v = h->f[f].v;
    return orient(pt(h, v[0]), pt(h, v[1]), pt(h, v[2]), pt(h, i)) > 0;
}

/* Plane of face f. The normal is the cross product of the two edges at the
 * vertex opposite the longest edge, the best conditioned of the three. */
static void face_plane(hull *h, int f)
{
    hull_face *F = &h->f[f];
    const double *a = pt(h, F->v[0]), *b = pt(h, F->v[1]), *c = pt(h, F->v[2]);
    double ab[3], bc[3], ca[3], t[3], n[3];
    v3_sub(ab, b, a);
    v3_sub(bc, c, b);
    v3_sub(ca, a, c);
    double lab = v3_dot(ab, ab), lbc = v3_dot(bc, bc), lca = v3_dot(ca, ca);
    double lmax = max_d(lab, max_d(lbc, lca));
    if (lab >= lbc && lab >= lca) {          /* at c: (a - c) x (b - c) */
        v3_scale(t, bc, -1);
        v3_cross(n, ca, t);
    } else if (lbc >= lca) {                 /* at a: (b - a) x (c - a) */
        v3_scale(t, ca, -1);
        v3_cross(n, ab, t);
    } else {                                 /* at b: (c - b) x (a - b) */
        v3_scale(t, ab, -1);
        v3_cross(n, bc, t);
    }
    /* The normal's relative rounding error is below 5 DBL_EPSILON lmax / |n|
     * (lmax: the longest edge squared; the two edges used are no longer).
     * Unless |n| > 1e-3 lmax, which bounds it by 1.1e-12 and a distance
     * error across the box (2 sqrt 3 wide at most) by 4e-12, under eps / 100
     * (eps >= 5e-10 here), the face is a sliver: face_sees asks orient. */
    F->sliver = !(v3_len(n) > 1e-3 * lmax);
    v3_normalize(n);
    v3_copy(F->n, n);
    F->d = (v3_dot(n, a) + v3_dot(n, b) + v3_dot(n, c)) / 3;
}

static int face_new(hull *h, int a, int b, int c)
{
    int f;
    if (h->free_face >= 0) {
        f = h->free_face;
        h->free_face = h->f[f].head;
    } else {
        if (h->nf == h->capf) {
            hull_face *q = hull_grow(h->f, &h->capf, h->nf + 1, sizeof *q);
            if (!q)
                return SC_ENOMEM;
            h->f = q;
        }
        f = h->nf++;
    }
    hull_face *F = &h->f[f];
    memset(F, 0, sizeof *F);
    F->v[0] = a;
    F->v[1] = b;
    F->v[2] = c;
    F->adj[0] = F->adj[1] = F->adj[2] = -1;
    F->head = F->near = F->far = -1;
    F->alive = 1;
    face_plane(h, f);
    return f;
}

static void face_kill(hull *h, int f)
{
    h->f[f].alive = 0;
    h->f[f].head = h->free_face;
    h->free_face = f;
}

static int push_work(hull *h, int f)
{
    if (h->nwork == h->capwork) {
        int *q = hull_grow(h->work, &h->capwork, h->nwork + 1, sizeof *q);
        if (!q)
            return SC_ENOMEM;
        h->work = q;
    }
    h->work[h->nwork++] = f;
    return SC_OK;
}

static void conflict_add(hull *h, int f, int i, double d)
{
    hull_face *F = &h->f[f];
    h->link[i] = F->head;
    F->head = i;
    if (F->far < 0 || d > F->far_d) {
        F->far = i;
        F->far_d = d;
    }
}

/* Each pooled point goes to the face among faces[0..nfaces) it lies farthest
 * above, if that is more than eps (and it truly is above: a sliver's
 * rounded normal may say otherwise): a conflict point. Else, if it lies
 * above one of them at all (exactly), it is outside the hull by at most
 * eps there: a near point of the face it is farthest above, checked again
 * when that face goes and once more at the end (hull_run), since "within
 * eps of one plane" says little near a thin hull's rim. The rest are inside
 * the hull for good (Quickhull's invariant: a point above a visible face and
 * above no new face is inside the new hull). Faces with conflict points
 * become work. */
static int distribute(hull *h, const int *faces, int nfaces)
{
    if (4 * nfaces > h->capplanes) {
        double *q = hull_grow(h->planes, &h->capplanes, 4 * nfaces, sizeof *q);
        if (!q)
            return SC_ENOMEM;
        h->planes = q;
    }
    for (int j = 0; j < nfaces; j++) {       /* contiguous, for the inner loop */
        v3_copy(&h->planes[4 * j], h->f[faces[j]].n);
        h->planes[4 * j + 3] = h->f[faces[j]].d;
    }
    for (int k = 0; k < h->npool; k++) {
        int i = h->pool[k], best = -1, near = -1;
        double bd = h->eps, nd = -INFINITY;
        const double *x = pt(h, i);
        for (int j = 0; j < nfaces; j++) {
            const hull_face *F = &h->f[faces[j]];
            double d = v3_dot(&h->planes[4 * j], x) - h->planes[4 * j + 3];
            if (d > bd) {
                if (face_sees(h, faces[j], i, d)) {
                    bd = d;
                    best = faces[j];
                }
            } else if (best < 0 && d > nd && (d > -h->eps || F->sliver) &&
                       face_sees(h, faces[j], i, d)) {
                nd = d;
                near = faces[j];
            }
        }
        if (best >= 0) {
            conflict_add(h, best, i, bd);
        } else if (near >= 0) {
            h->link[i] = h->f[near].near;
            h->f[near].near = i;
        }
    }
    h->npool = 0;
    for (int j = 0; j < nfaces; j++)
        if (h->f[faces[j]].head >= 0 && push_work(h, faces[j]) != SC_OK)
            return SC_ENOMEM;
    return SC_OK;
}

static int mark_visible(hull *h, int f)
{
    if (h->nvis == h->capvis) {
        int *q = hull_grow(h->vis, &h->capvis, h->nvis + 1, sizeof *q);
        if (!q)
            return SC_ENOMEM;
        h->vis = q;
    }
    h->f[f].vis = 1;
    h->vis[h->nvis++] = f;
    return SC_OK;
}

/* The faces the eye sees, breadth first from f0 across edges. */
static int find_visible(hull *h, int eye, int f0)
{
    h->stamp++;
    h->nvis = 0;
    h->f[f0].mark = h->stamp;
    int rc = mark_visible(h, f0);
    for (int k = 0; k < h->nvis && rc == SC_OK; k++) {
        int f = h->vis[k];
        for (int i = 0; i < 3 && rc == SC_OK; i++) {
            int nb = h->f[f].adj[i];
            if (h->f[nb].mark == h->stamp)
                continue;
            h->f[nb].mark = h->stamp;
            h->f[nb].vis = 0;
            if (face_sees(h, nb, eye, face_dist(h, nb, eye)))
                rc = mark_visible(h, nb);
        }
    }
    return rc;
}

/* The edges between visible and hidden faces, in loop order in h->loop.
 * Exact visibility makes them one simple loop; anything else is reported
 * as SC_ENUMERIC rather than trusted. */
static int find_horizon(hull *h)
{
    h->nhz = 0;
    int rc = SC_OK;
    for (int k = 0; k < h->nvis && rc == SC_OK; k++) {
        const hull_face *F = &h->f[h->vis[k]];
        for (int i = 0; i < 3; i++) {
            const hull_face *N = &h->f[F->adj[i]];
            if (N->mark == h->stamp && N->vis)
                continue;
            if (h->nhz == h->caphz) {
                hull_edge *q = hull_grow(h->hz, &h->caphz, h->nhz + 1, sizeof *q);
                if (!q)
                    return SC_ENOMEM;
                h->hz = q;
                F = &h->f[h->vis[k]];
            }
            hull_edge e = { F->v[i], F->v[(i + 1) % 3], F->adj[i] };
            if (h->hstart[e.u] >= 0)
                rc = SC_ENUMERIC;            /* pinched: impossible when exact */
            else
                h->hstart[e.u] = h->nhz;
            h->hz[h->nhz++] = e;
        }
    }
    if (rc == SC_OK && h->nhz < 3)
        rc = SC_ENUMERIC;
    if (rc == SC_OK && h->caploop < h->nhz) {
        int *q = hull_grow(h->loop, &h->caploop, h->nhz, sizeof *q);
        if (q)
            h->loop = q;
        else
            rc = SC_ENOMEM;
    }
    if (rc == SC_OK) {
        int k = 0, len = 0;
        do {
            h->loop[len++] = k;
            k = h->hstart[h->hz[k].w];
        } while (k > 0 && len < h->nhz);
        if (k != 0 || len != h->nhz)
            rc = SC_ENUMERIC;                /* several loops: impossible too */
    }
    SC_ASSERT(rc != SC_ENUMERIC);
    for (int k = 0; k < h->nhz; k++)
        h->hstart[h->hz[k].u] = -1;
    return rc;
}

/* One Quickhull iteration: the eye (farthest conflict point of f0) joins
 * the hull. */
static int add_point(hull *h, int eye, int f0)
{
    int rc = find_visible(h, eye, f0);
    if (rc == SC_OK)
        rc = find_horizon(h);
    if (rc != SC_OK)
        return rc;

    /* The conflict and near points of the visible faces go to the new ones.
     * (Their vertices off the horizon are inside the new hull: dropped.) */
    h->npool = 0;
    for (int k = 0; k < h->nvis; k++) {
        for (int i = h->f[h->vis[k]].head; i >= 0; i = h->link[i])
            if (i != eye)
                h->pool[h->npool++] = i;
        for (int i = h->f[h->vis[k]].near; i >= 0; i = h->link[i])
            h->pool[h->npool++] = i;
        face_kill(h, h->vis[k]);
    }

    /* The cone: new face k = (u_k, w_k, eye) over horizon edge k, in loop
     * order; h->loop is overwritten with the new faces' indices. */
    int L = h->nhz;
    for (int k = 0; k < L; k++) {
        hull_edge e = h->hz[h->loop[k]];
        int f = face_new(h, e.u, e.w, eye);
        if (f < 0)
            return f;
        hull_face *nb = &h->f[e.nb];
        int j = nb->v[0] == e.w ? 0 : nb->v[1] == e.w ? 1 : 2;
        SC_ASSERT(nb->v[(j + 1) % 3] == e.u);
        nb->adj[j] = f;
        h->f[f].adj[0] = e.nb;
        h->loop[k] = f;
    }
    for (int k = 0; k < L; k++) {
        hull_face *F = &h->f[h->loop[k]];
        F->adj[1] = h->loop[(k + 1) % L];
        F->adj[2] = h->loop[(k + L - 1) % L];
    }
    return distribute(h, h->loop, L);
}

/* Copy of the points scaled by 2^-e (exact) so the largest |coordinate| is
 * in [0.5, 1), moved to the centre of their box; eps in those units. */
static int hull_setup(hull *h, const double *pts, int n)
{
    double m = 0, lo[3] = { INFINITY, INFINITY, INFINITY };
    double hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    for (size_t i = 0; i < 3 * (size_t)n; i++)
        m = max_d(m, fabs(pts[i]));
    if (!(m > 0))
        return SC_EDEGENERATE;               /* all points at the origin */
    int e;
    (void)frexp(m, &e);
    h->in = pts;
    h->n = n;
    h->free_face = -1;
    h->p = hull_alloc(3 * (size_t)n, sizeof *h->p);
    h->link = hull_alloc((size_t)n, sizeof *h->link);
    h->hstart = hull_alloc((size_t)n, sizeof *h->hstart);
    h->pool = hull_alloc((size_t)n, sizeof *h->pool);
    h->flag = alloc_allowed() ? sc_calloc_array((size_t)n, 1) : NULL;
    if (!h->p || !h->link || !h->hstart || !h->pool || !h->flag)
        return SC_ENOMEM;
    for (size_t i = 0; i < 3 * (size_t)n; i++) {
        double q = ldexp(pts[i], -e);
        h->p[i] = q;
        lo[i % 3] = min_d(lo[i % 3], q);
        hi[i % 3] = max_d(hi[i % 3], q);
    }
    double c[3], ext[3];
    for (int k = 0; k < 3; k++) {
        c[k] = 0.5 * (lo[k] + hi[k]);
        ext[k] = hi[k] - lo[k];
    }
    /* Coordinates below 2^-300 (of a box at most 2 wide) become 0: moving a
     * point by that is nothing next to eps, and it keeps every product in
     * orient_exact clear of underflow. */
    for (size_t i = 0; i < 3 * (size_t)n; i++) {
        double q = h->p[i] - c[i % 3];
        h->p[i] = fabs(q) < 0x1p-300 ? 0 : q;
    }
    for (int i = 0; i < n; i++)
        h->hstart[i] = -1;
    h->eps = HULL_EPS_REL * (ldexp(m, -e) + v3_len(ext));
    return SC_OK;
}

/* Quickhull's first simplex from the points cand[0..m) (NULL: all points):
 * the two farthest apart of the six extreme points, the point farthest from
 * their line, the point farthest from the plane of those three. Each must be
 * more than eps off, or there is no volume. The other points are handed to
 * its faces. */
static int hull_simplex(hull *h, const int *cand, int m)
{
    int i0 = cand ? cand[0] : 0, ext[6] = { i0, i0, i0, i0, i0, i0 };
    for (int c = 1; c < m; c++)
        for (int k = 0, i = cand ? cand[c] : c; k < 3; k++) {
            if (pt(h, i)[k] < pt(h, ext[2 * k])[k])
                ext[2 * k] = i;
            if (pt(h, i)[k] > pt(h, ext[2 * k + 1])[k])
                ext[2 * k + 1] = i;
        }
    int s[4] = { 0, 0, 0, 0 };
    double best = 0, d[3];
    for (int a = 0; a < 6; a++)
        for (int b = a + 1; b < 6; b++) {
            v3_sub(d, pt(h, ext[a]), pt(h, ext[b]));
            if (v3_dot(d, d) > best) {
                best = v3_dot(d, d);
                s[0] = ext[a];
                s[1] = ext[b];
            }
        }
    if (!(sqrt(best) > h->eps))
        return SC_EDEGENERATE;               /* coincident */
    double dir[3], w[3], c[3], nrm[3];
    v3_sub(dir, pt(h, s[1]), pt(h, s[0]));
    v3_normalize(dir);
    best = 0;
    for (int k = 0; k < m; k++) {
        int i = cand ? cand[k] : k;
        v3_sub(w, pt(h, i), pt(h, s[0]));
        v3_cross(c, w, dir);
        if (v3_dot(c, c) > best) {
            best = v3_dot(c, c);
            s[2] = i;
        }
    }
    if (!(sqrt(best) > h->eps))
        return SC_EDEGENERATE;               /* collinear */
    v3_sub(w, pt(h, s[2]), pt(h, s[0]));
    v3_cross(nrm, dir, w);
    v3_normalize(nrm);
    best = 0;
    for (int k = 0; k < m; k++) {
        int i = cand ? cand[k] : k;
        v3_sub(w, pt(h, i), pt(h, s[0]));
        if (fabs(v3_dot(nrm, w)) > best) {
            best = fabs(v3_dot(nrm, w));
            s[3] = i;
        }
    }
    if (!(best > h->eps))
        return SC_EDEGENERATE;               /* coplanar */
    if (orient(pt(h, s[0]), pt(h, s[1]), pt(h, s[2]), pt(h, s[3])) > 0) {
        int t = s[1];                        /* s[3] below (s0, s1, s2) */
        s[1] = s[2];
        s[2] = t;
    }
    static const int fv[4][3] = { { 0, 1, 2 }, { 0, 3, 1 }, { 1, 3, 2 }, { 2, 3, 0 } };
    int f[4];
    for (int k = 0; k < 4; k++) {
        f[k] = face_new(h, s[fv[k][0]], s[fv[k][1]], s[fv[k][2]]);
        if (f[k] < 0)
            return f[k];
    }
    for (int a = 0; a < 4; a++)              /* adjacency: the reversed edge */
        for (int i = 0; i < 3; i++)
            for (int b = 0; b < 4; b++)
                for (int j = 0; j < 3; j++)
                    if (fv[b][j] == fv[a][(i + 1) % 3] && fv[b][(j + 1) % 3] == fv[a][i])
                        h->f[f[a]].adj[i] = f[b];
    h->npool = 0;
    for (int k = 0; k < m; k++) {
        int i = cand ? cand[k] : k;
        if (i != s[0] && i != s[1] && i != s[2] && i != s[3])
            h->pool[h->npool++] = i;
    }
    return distribute(h, f, 4);
}

/* The farthest of the faces that see near point i, found breadth first from
 * f0 (which does): the faces a point sees form a disc. Its distance in *d. */
static int near_check(hull *h, int i, int f0, double *d)
{
    int best = f0;
    h->stamp++;
    h->nvis = 0;
    h->f[f0].mark = h->stamp;
    *d = face_dist(h, f0, i);
    if (mark_visible(h, f0) != SC_OK)
        return SC_ENOMEM;
    for (int k = 0; k < h->nvis; k++)
        for (int j = 0; j < 3; j++) {
            int nb = h->f[h->vis[k]].adj[j];
            if (h->f[nb].mark == h->stamp)
                continue;
            h->f[nb].mark = h->stamp;
            double dn = face_dist(h, nb, i);
            if (!face_sees(h, nb, i, dn))
                continue;
            if (dn > *d) {
                *d = dn;
                best = nb;
            }
            if (mark_visible(h, nb) != SC_OK)
                return SC_ENOMEM;
        }
    return best;
}

/* Quickhull until no face has conflict points; then every near point more
 * than eps above some face it sees becomes a conflict point again, and so
 * on until none does. Each eye becomes a vertex, so this ends. */
static int hull_run(hull *h)
{
    for (;;) {
        while (h->nwork > 0) {
            int f = h->work[--h->nwork];
            if (!h->f[f].alive || h->f[f].head < 0)
                continue;
            int rc = add_point(h, h->f[f].far, f);
            if (rc != SC_OK)
                return rc;
        }
        for (int f = 0; f < h->nf; f++) {
            if (!h->f[f].alive)
                continue;
            int i = h->f[f].near, keep = -1;
            h->f[f].near = -1;
            while (i >= 0) {
                int next = h->link[i];
                double d;
                int g = near_check(h, i, f, &d);
                if (g < 0)
                    return g;
                if (d > h->eps) {
                    conflict_add(h, g, i, d);
                    if (push_work(h, g) != SC_OK)
                        return SC_ENOMEM;
                } else {
                    h->link[i] = keep;
                    keep = i;
                }
                i = next;
            }
            h->f[f].near = keep;
        }
        if (h->nwork == 0)
            return SC_OK;
    }
}

/* ---- coplanar merge ---------------------------------------------------------- */

/* Per-point bits of h->flag while a hull is analysed: how many groups meet
 * at the vertex (1, 2, 3 = more), whether one of them is kept as triangles,
 * whether it lies on a straight edge. */
enum { V_CNT = 3, V_FALLBACK = 4, V_DROP = 8 };

typedef struct hull_key {
    double a;
    int i;
} hull_key;

/* Larger area first, then lower index: a total order, so qsort is
 * deterministic. */
static int key_cmp(const void *x, const void *y)
{
    const hull_key *a = x, *b = y;
    if (a->a != b->a)
        return a->a > b->a ? -1 : 1;
    return (a->i > b->i) - (a->i < b->i);
}

static double seg_dist2(const double *p, const double *a, const double *b)
{
    double ab[3], ap[3], q[3];
    v3_sub(ab, b, a);
    v3_sub(ap, p, a);
    double l = v3_dot(ab, ab), t = l > 0 ? v3_dot(ap, ab) / l : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    v3_madd(q, a, ab, t);
    v3_sub(q, p, q);
    return v3_dot(q, q);
}

typedef struct hull_groups {
    int *fl;             /* alive faces, ascending: triangle t is face fl[t] */
    int *loc;            /* face index -> triangle */
    int *tadj;           /* 3 neighbour triangles per triangle */
    hull_key *key;
    int *grp;            /* group of each triangle */
    int *queue;
    int *gstart;         /* triangles of group g: gtri[gstart[g] .. gstart[g + 1]) */
    int *gtri;
    int *pstart, *plen;  /* boundary loop of group g in poly; plen -1: not one loop */
    int *poly;
} hull_groups;

static void groups_free(hull_groups *o)
{
    free(o->fl);
    free(o->loc);
    free(o->tadj);
    free(o->key);
    free(o->grp);
    free(o->queue);
    free(o->gstart);
    free(o->gtri);
    free(o->pstart);
    free(o->plen);
    free(o->poly);
}

/* Whether triangle u may join a group whose plane is n.x = d: its three
 * vertices lie within eps of the plane, and it faces the same side, decided
 * exactly (a sliver's rounded normal is noise). Facing the same side keeps a
 * group a flat, unfolded patch: seen along n it covers its inside, so a
 * vertex inside a group is inside the hull's face there, not on a rim that
 * a thin hull folds around. */
static int fits_plane(const hull *h, const hull_face *u, const double n[3], double d)
{
    for (int k = 0; k < 3; k++)
        if (!(fabs(v3_dot(n, pt(h, u->v[k])) - d) <= h->eps))
            return 0;
    const double *a = pt(h, u->v[0]);
    double an[3];
    v3_add(an, a, n);
    return orient(a, pt(h, u->v[1]), pt(h, u->v[2]), an) > 0;
}

/* Groups of coplanar triangles. Only a triangle that fits a neighbour's
 * plane, or whose plane a neighbour fits, can share a group; the others
 * (all of them for points in general position) are groups of one, so only
 * the candidates are sorted. A group floods from the largest candidate not
 * yet grouped (the seed, whose plane is the best estimate) across edges to
 * the triangles that fit the seed's plane. */
static int make_groups(const hull *h, hull_groups *o, int nt)
{
    int ng = 0, nk = 0;
    for (int t = 0; t < nt; t++) {
        const hull_face *F = &h->f[o->fl[t]];
        int cand = 0;
        for (int i = 0; i < 3 && !cand; i++) {
            const hull_face *U = &h->f[o->fl[o->tadj[3 * t + i]]];
            cand = fits_plane(h, U, F->n, F->d) || fits_plane(h, F, U->n, U->d);
        }
        o->grp[t] = -1;
        if (cand) {
            double ab[3], ac[3], cr[3];
            v3_sub(ab, pt(h, F->v[1]), pt(h, F->v[0]));
            v3_sub(ac, pt(h, F->v[2]), pt(h, F->v[0]));
            v3_cross(cr, ab, ac);
            o->key[nk++] = (hull_key){ v3_len(cr), t };
        }
    }
    qsort(o->key, (size_t)nk, sizeof *o->key, key_cmp);
    for (int s = 0; s < nk; s++) {
        int t0 = o->key[s].i;
        if (o->grp[t0] >= 0)
            continue;
        const hull_face *sf = &h->f[o->fl[t0]];
        int qh = 0, qt = 0;
        o->grp[t0] = ng;
        o->queue[qt++] = t0;
        while (qh < qt) {
            int t = o->queue[qh++];
            for (int i = 0; i < 3; i++) {
                int u = o->tadj[3 * t + i];
                if (o->grp[u] < 0 && fits_plane(h, &h->f[o->fl[u]], sf->n, sf->d)) {
                    o->grp[u] = ng;
                    o->queue[qt++] = u;
                }
            }
        }
        ng++;
    }
    for (int t = 0; t < nt; t++)
        if (o->grp[t] < 0)
            o->grp[t] = ng++;
    return ng;
}

/* The boundary of each group as one loop of vertices (counter-clockwise from
 * outside, like the triangles). A group whose boundary is not one simple
 * loop gets plen -1: its vertices all count as corners. */
static void group_loops(hull *h, hull_groups *o, int ng)
{
    int *bnext = h->hstart, np = 0;
    for (int g = 0; g < ng; g++) {
        int nbe = 0, first = -1, bad = 0, len = 0;
        for (int s = o->gstart[g]; s < o->gstart[g + 1]; s++) {
            int t = o->gtri[s];
            const int *v = h->f[o->fl[t]].v;
            for (int i = 0; i < 3; i++) {
                if (o->grp[o->tadj[3 * t + i]] == g)
                    continue;
                if (bnext[v[i]] >= 0)
                    bad = 1;                 /* pinched at v[i] */
                else
                    bnext[v[i]] = v[(i + 1) % 3];
                if (first < 0)
                    first = v[i];
                nbe++;
            }
        }
        if (!bad && nbe >= 3) {
            int v = first;
            do {
                o->poly[np + len++] = v;
                v = bnext[v];
            } while (v >= 0 && v != first && len < nbe);
            bad = !(v == first && len == nbe);
        }
        for (int s = o->gstart[g]; s < o->gstart[g + 1]; s++) {
            int t = o->gtri[s];
            for (int i = 0; i < 3; i++)
                bnext[h->f[o->fl[t]].v[i]] = -1;
        }
        o->pstart[g] = np;
        o->plen[g] = bad || nbe < 3 ? -1 : len;
        if (o->plen[g] > 0)
            np += len;
    }
}

static int is_anchor(const hull *h, int v)
{
    return (h->flag[v] & V_CNT) >= 3 || (h->flag[v] & V_FALLBACK);
}

/* Vertices that are not corners: a vertex all of whose triangles lie in one
 * group is inside that polygon and is simply not on its loop. A vertex on
 * the border of exactly two polygons lies on their common edge; a run of
 * such vertices between two corners (anchors) is dropped when all of it is
 * within eps of the straight segment between the corners. Decided once per
 * pair of groups, by the lower group. */
static void drop_edge_vertices(hull *h, const hull_groups *o, int ng, const int *ga,
                               const int *gb)
{
    for (int g = 0; g < ng; g++) {
        const int *c = o->poly + o->pstart[g];
        int m = o->plen[g], i0 = -1;
        for (int i = 0; i < m && i0 < 0; i++)
            if (is_anchor(h, c[i]))
                i0 = i;
        if (i0 < 0)
            continue;                        /* two polygons sharing a loop: keep */
        int i = i0;
        do {
            int j = (i + 1) % m;
            while (!is_anchor(h, c[j]))
                j = (j + 1) % m;
            int v = c[(i + 1) % m];
            if (j != (i + 1) % m && j != i && g < (ga[v] == g ? gb[v] : ga[v])) {
                const double *a = pt(h, c[i]), *b = pt(h, c[j]);
                int ok = 1;
                for (int k = (i + 1) % m; k != j && ok; k = (k + 1) % m)
                    ok = seg_dist2(pt(h, c[k]), a, b) <= h->eps * h->eps;
                for (int k = (i + 1) % m; k != j && ok; k = (k + 1) % m)
                    h->flag[c[k]] |= V_DROP;
            }
            i = j;
        } while (i != i0);
    }
}

/* Finds the hull vertices that are not corners: inside a group of coplanar
 * triangles (all their triangles in one group) or on a straight edge
 * between two groups. Lists the others in h->keep[0..*nkeep) and returns
 * how many were found, or a negative code. */
static int hull_simplify(hull *h, int *nkeep)
{
    hull_groups o = { 0 };
    int nt = 0, ng, rc = SC_ENOMEM;
    for (int f = 0; f < h->nf; f++)
        nt += h->f[f].alive;
    if (!h->keep)
        h->keep = hull_alloc((size_t)h->n, sizeof *h->keep);
    o.fl = hull_alloc((size_t)nt, sizeof *o.fl);
    o.loc = hull_alloc((size_t)h->nf, sizeof *o.loc);
    o.tadj = hull_alloc(3 * (size_t)nt, sizeof *o.tadj);
    o.key = hull_alloc((size_t)nt, sizeof *o.key);
    o.grp = hull_alloc((size_t)nt, sizeof *o.grp);
    o.queue = hull_alloc((size_t)nt, sizeof *o.queue);
    o.gstart = hull_alloc((size_t)nt + 1, sizeof *o.gstart);
    o.gtri = hull_alloc((size_t)nt, sizeof *o.gtri);
    o.pstart = hull_alloc((size_t)nt, sizeof *o.pstart);
    o.plen = hull_alloc((size_t)nt, sizeof *o.plen);
    o.poly = hull_alloc(3 * (size_t)nt, sizeof *o.poly);
    if (!h->keep || !o.fl || !o.loc || !o.tadj || !o.key || !o.grp || !o.queue ||
        !o.gstart || !o.gtri || !o.pstart || !o.plen || !o.poly)
        goto done;
    nt = 0;
    for (int f = 0; f < h->nf; f++)
        if (h->f[f].alive) {
            o.loc[f] = nt;
            o.fl[nt++] = f;
        }
    for (int t = 0; t < nt; t++)
        for (int i = 0; i < 3; i++)
            o.tadj[3 * t + i] = o.loc[h->f[o.fl[t]].adj[i]];
    ng = make_groups(h, &o, nt);

    /* Triangles by group (a counting sort keeps them ascending in a group). */
    memset(o.gstart, 0, ((size_t)ng + 1) * sizeof *o.gstart);
    for (int t = 0; t < nt; t++)
        o.gstart[o.grp[t] + 1]++;
    for (int g = 0; g < ng; g++)
        o.gstart[g + 1] += o.gstart[g];
    for (int t = 0; t < nt; t++)
        o.gtri[o.gstart[o.grp[t]]++] = t;
    for (int g = ng; g > 0; g--)
        o.gstart[g] = o.gstart[g - 1];
    o.gstart[0] = 0;
    group_loops(h, &o, ng);

    /* How many groups meet at each vertex; link and pool are free now and
     * hold the first two. */
    int *ga = h->link, *gb = h->pool;
    for (int t = 0; t < nt; t++) {
        int g = o.grp[t];
        for (int i = 0; i < 3; i++) {
            int v = h->f[o.fl[t]].v[i], c = h->flag[v] & V_CNT;
            if (o.plen[g] < 0)
                h->flag[v] |= V_FALLBACK;
            if (c == 0)
                ga[v] = g;
            else if (c == 1 && ga[v] != g)
                gb[v] = g;
            else if (!(c == 2 && ga[v] != g && gb[v] != g))
                continue;
            h->flag[v] = (unsigned char)((h->flag[v] & ~V_CNT) | (c + 1));
        }
    }
    drop_edge_vertices(h, &o, ng, ga, gb);

    rc = 0;
    *nkeep = 0;
    for (int v = 0; v < h->n; v++) {
        int b = h->flag[v];
        h->flag[v] = 0;
        if (!(b & V_CNT))
            continue;                        /* not a hull vertex */
        if (((b & V_CNT) == 1 && !(b & V_FALLBACK)) || (b & V_DROP))
            rc++;
        else
            h->keep[(*nkeep)++] = v;
    }
done:
    groups_free(&o);
    return rc;
}

/* The current hull as the caller's arrays: vertices in input order. */
static int hull_output(hull *h, double **xyz, int *nverts, int **tri, int *ntris)
{
    int nt = 0, nv = 0;
    for (int f = 0; f < h->nf; f++)
        if (h->f[f].alive) {
            nt++;
            for (int i = 0; i < 3; i++)
                h->flag[h->f[f].v[i]] = 1;
        }
    for (int v = 0; v < h->n; v++) {
        if (h->flag[v])
            h->link[v] = nv++;
        h->flag[v] = 0;
    }
    if (nt != 2 * nv - 4)                    /* Euler, for a closed hull */
        return SC_ENUMERIC;
    double *x = hull_alloc(3 * (size_t)nv, sizeof *x);
    int *t = hull_alloc(3 * (size_t)nt, sizeof *t);
    if (!x || !t) {
        free(x);
        free(t);
        return SC_ENOMEM;
    }
    nt = 0;
    for (int f = 0; f < h->nf; f++)
        if (h->f[f].alive)
            for (int i = 0; i < 3; i++) {
                int v = h->f[f].v[i];
                t[nt++] = h->link[v];
                memcpy(&x[3 * (size_t)h->link[v]], &h->in[3 * (size_t)v], 3 * sizeof *x);
            }
    *xyz = x;
    *tri = t;
    *nverts = nv;
    *ntris = nt / 3;
    return SC_OK;
}

/* Whether a triangle is too small for sc_mesh_check: |cross|^2 at most
 * 1e-24 diag^4 (diag: the vertices' box), with a margin. The ratio does not
 * change with scale, so it is computed on the scaled points, where neither
 * side can overflow or underflow. */
static int has_tiny_triangle(const hull *h)
{
    double lo[3] = { INFINITY, INFINITY, INFINITY }, hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    for (int f = 0; f < h->nf; f++)
        for (int i = 0; i < 3 && h->f[f].alive; i++)
            for (int k = 0; k < 3; k++) {
                lo[k] = min_d(lo[k], pt(h, h->f[f].v[i])[k]);
                hi[k] = max_d(hi[k], pt(h, h->f[f].v[i])[k]);
            }
    double ext[3];
    v3_sub(ext, hi, lo);
    double s2 = v3_dot(ext, ext), min2 = 4e-24 * s2 * s2;
    for (int f = 0; f < h->nf; f++) {
        if (!h->f[f].alive)
            continue;
        const int *v = h->f[f].v;
        double e1[3], e2[3], c[3];
        v3_sub(e1, pt(h, v[1]), pt(h, v[0]));
        v3_sub(e2, pt(h, v[2]), pt(h, v[0]));
        v3_cross(c, e1, e2);
        if (!(v3_dot(c, c) > min2))
            return 1;
    }
    return 0;
}

/* Rounds of "hull, then drop the vertices that are not corners" at most;
 * one or two are the rule. eps grows tenfold, HULL_EPS_RAISES times at
 * most (to 1e-5 relative), while the hull keeps a triangle too small for
 * sc_mesh_check (a cluster of points a few eps across, say from float data:
 * at 1e-9 they are distinct vertices, but their triangles have next to no
 * area). */
#define HULL_MAX_ROUNDS 16
#define HULL_EPS_RAISES 4

int sc_hull_build(const double *pts, int n, double **xyz, int *nverts, int **tri, int *ntris)
{
    if (xyz)
        *xyz = NULL;
    if (tri)
        *tri = NULL;
    if (nverts)
        *nverts = 0;
    if (ntris)
        *ntris = 0;
    if (!pts || !xyz || !nverts || !tri || !ntris || n < 0)
        return SC_EINVAL;
    if (n > SC_MESH_MAX_VERTS)
        return SC_ETOOBIG;
    for (int i = 0; i < n; i++)
        if (!sc_finite3(&pts[3 * (size_t)i]))
            return SC_EINVAL;
    if (n < 4)
        return SC_EDEGENERATE;

    /* Each round builds the exact hull of the points left, then drops the
     * vertices inside coplanar groups or on straight edges (within eps) and
     * goes again with the rest, until nothing drops (or eps must grow). So
     * the result is the exact convex hull of its own vertices, with clean
     * coplanar faces. Every round's hull is valid: if a later one fails (it
     * should not, short of eps growing past the hull's thickness), the
     * previous one stands. */
    hull h = { 0 };
    double *v = NULL;
    int *t = NULL, nv = 0, nt = 0, m = n, raises = 0;
    const int *cand = NULL;
    int rc = hull_setup(&h, pts, n);
    for (int round = 0; rc == SC_OK; round++) {
        rc = hull_simplex(&h, cand, m);
        if (rc == SC_OK)
            rc = hull_run(&h);
        if (rc != SC_OK) {
            if (v && rc != SC_ENOMEM)
                rc = SC_OK;
            break;
        }
        free(v);
        free(t);
        v = NULL;
        t = NULL;
        rc = hull_output(&h, &v, &nv, &t, &nt);
        int dropped = 0;
        if (rc == SC_OK && round + 1 < HULL_MAX_ROUNDS)
            dropped = hull_simplify(&h, &m);
        if (dropped < 0)
            rc = dropped;
        if (rc != SC_OK || round + 1 == HULL_MAX_ROUNDS)
            break;
        if (dropped == 0) {                  /* h.keep lists every vertex */
            if (raises == HULL_EPS_RAISES || !has_tiny_triangle(&h))
                break;
            raises++;
            h.eps *= 10;
        }
        cand = h.keep;
        h.nf = h.nwork = h.npool = 0;
        h.free_face = -1;
    }
    if (rc == SC_OK) {
        *xyz = v;
        *tri = t;
        *nverts = nv;
        *ntris = nt;
    } else {
        free(v);
        free(t);
    }
    hull_free(&h);
    return rc;
}
