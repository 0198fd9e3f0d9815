/* test_hull.c - convex hull (lib/core/hull.c): exact answers for cubes, a
 * tetrahedron, UV spheres and cylinders fed with points on their faces and
 * edges, duplicated and near-duplicated points; the hull invariants (closed,
 * manifold, outward, convex, every input point inside within eps) for random
 * points and for points placed at the tolerance (near faces, beside a thin
 * plate's rim, in clusters a few eps wide); degenerate and bad input;
 * determinism; allocation failure; timing of 100 000 points.
 *
 * Internal test: sc_hull_build is declared in lib/core/core.h.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "core.h"

/* Fault injection hook in lib/core/hull.c (allocations left before failure). */
extern _Thread_local long sc_hull_alloc_budget;

/* ---- helpers --------------------------------------------------------------- */

/* splitmix64: the same numbers on every platform. */
typedef struct rng {
    uint64_t s;
} rng;

static double rng_uniform(rng *r)
{
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

static void rng_ball(rng *r, double *p)
{
    do {
        for (int k = 0; k < 3; k++)
            p[k] = 2 * rng_uniform(r) - 1;
    } while (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] > 1);
}

static void rng_sphere(rng *r, double *p)
{
    double l;
    do {
        rng_ball(r, p);
        l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    } while (l < 0.1);
    for (int k = 0; k < 3; k++)
        p[k] /= l;
}

/* Fisher-Yates on points, so corners do not come first. */
static void shuffle(rng *r, double *p, int n)
{
    for (int i = n - 1; i > 0; i--) {
        int j = (int)(rng_uniform(r) * (i + 1));
        for (int k = 0; k < 3; k++) {
            double t = p[3 * i + k];
            p[3 * i + k] = p[3 * j + k];
            p[3 * j + k] = t;
        }
    }
}

/* The tolerance lib/core/hull.c documents. */
static double hull_eps(const double *p, int n)
{
    double m = 0, lo[3] = { INFINITY, INFINITY, INFINITY };
    double hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            m = fmax(m, fabs(p[3 * i + k]));
            lo[k] = fmin(lo[k], p[3 * i + k]);
            hi[k] = fmax(hi[k], p[3 * i + k]);
        }
    double d = 0;
    for (int k = 0; k < 3; k++)
        d += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return 1e-9 * (m + sqrt(d));
}

typedef struct mesh {
    double *xyz;
    int *tri;
    int nv, nt;
} mesh;

static int build(const double *p, int n, mesh *m)
{
    return sc_hull_build(p, n, &m->xyz, &m->nv, &m->tri, &m->nt);
}

static void mesh_free(mesh *m)
{
    free(m->xyz);
    free(m->tri);
    m->xyz = NULL;
    m->tri = NULL;
}

static const double *vtx(const mesh *m, int t, int k)
{
    return &m->xyz[3 * m->tri[3 * t + k]];
}

/* Unit normal of triangle t and its plane through the first vertex. */
static void tri_normal(const mesh *m, int t, double n[3])
{
    const double *a = vtx(m, t, 0), *b = vtx(m, t, 1), *c = vtx(m, t, 2);
    double u[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
    double v[3] = { c[0] - a[0], c[1] - a[1], c[2] - a[2] };
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

/* Volume by the divergence theorem: tetrahedra from the first vertex. */
static double mesh_volume(const mesh *m, double scale)
{
    const double *o = m->xyz;
    double vol = 0;
    for (int t = 0; t < m->nt; t++) {
        double p[3][3];
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++)
                p[k][j] = (vtx(m, t, k)[j] - o[j]) / scale;
        vol += p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) -
               p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
               p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
    }
    return vol / 6;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* The hull invariants. Topology: F = 2V - 4, every directed edge once and
 * its reverse once (closed, manifold, consistently oriented), V - E + F = 2,
 * every vertex used, distinct, and one of the input points bit for bit.
 * Geometry: no triangle smaller than sc_mesh_check accepts, every normal
 * outward (the vertex centroid strictly inside every face plane), and every
 * input point (every stride-th) at most tol above every face plane. */
static void check_hull(const double *p, int n, const mesh *m, double tol, int stride)
{
    assert_true(m->nv >= 4);
    assert_int_equal(m->nt, 2 * m->nv - 4);
    int *used = calloc((size_t)m->nv, sizeof *used);
    uint64_t *e = malloc(3 * (size_t)m->nt * sizeof *e);
    assert_non_null(used);
    assert_non_null(e);
    for (int t = 0; t < m->nt; t++)
        for (int k = 0; k < 3; k++) {
            int a = m->tri[3 * t + k], b = m->tri[3 * t + (k + 1) % 3];
            assert_true(a >= 0 && a < m->nv && b >= 0 && b < m->nv && a != b);
            used[a] = 1;
            e[3 * t + k] = (uint64_t)a << 32 | (uint32_t)b;
        }
    for (int v = 0; v < m->nv; v++)
        assert_true(used[v]);
    qsort(e, 3 * (size_t)m->nt, sizeof *e, cmp_u64);
    for (size_t i = 0; i < 3 * (size_t)m->nt; i++) {
        if (i > 0)
            assert_true(e[i] != e[i - 1]);
        uint64_t r = e[i] << 32 | e[i] >> 32;
        assert_non_null(bsearch(&r, e, 3 * (size_t)m->nt, sizeof *e, cmp_u64));
    }
    int edges = 3 * m->nt / 2;
    assert_int_equal(m->nv - edges + m->nt, 2);

    /* Vertices: distinct input points. */
    if (n <= 20000) {
        for (int v = 0; v < m->nv; v++) {
            int found = 0;
            for (int i = 0; i < n && !found; i++)
                found = !memcmp(&m->xyz[3 * v], &p[3 * i], 3 * sizeof *p);
            assert_true(found);
            for (int w = 0; w < v; w++)
                assert_true(memcmp(&m->xyz[3 * v], &m->xyz[3 * w], 3 * sizeof *p) != 0);
        }
    }

    double lo[3] = { INFINITY, INFINITY, INFINITY }, hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    double c[3] = { 0, 0, 0 };
    for (int v = 0; v < m->nv; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], m->xyz[3 * v + k]);
            hi[k] = fmax(hi[k], m->xyz[3 * v + k]);
            c[k] += m->xyz[3 * v + k] / m->nv;
        }
    double diag2 = 0;
    for (int k = 0; k < 3; k++)
        diag2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    for (int t = 0; t < m->nt; t++) {
        double nr[3];
        tri_normal(m, t, nr);
        double l = sqrt(nr[0] * nr[0] + nr[1] * nr[1] + nr[2] * nr[2]);
        assert_true(l * l > 1e-24 * diag2 * diag2);
        for (int k = 0; k < 3; k++)
            nr[k] /= l;
        const double *a = vtx(m, t, 0);
        double dc = nr[0] * (c[0] - a[0]) + nr[1] * (c[1] - a[1]) + nr[2] * (c[2] - a[2]);
        assert_true(dc < 0);
        for (int i = 0; i < n; i += stride) {
            const double *q = &p[3 * i];
            double d = nr[0] * (q[0] - a[0]) + nr[1] * (q[1] - a[1]) + nr[2] * (q[2] - a[2]);
            if (d > tol)
                fail_msg("point %d is %g above triangle %d (tolerance %g)", i, d, t, tol);
        }
    }
    assert_true(mesh_volume(m, 1) > 0);
    free(used);
    free(e);
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Unit cube corners, interior points, points on faces and edges (random and
 * at centres and midpoints) and repeated corners, shuffled; returns n. */
static int cube_cloud(rng *r, double *p, double lo, double size)
{
    for (int c = 0; c < 16; c++)             /* corners, twice */
        for (int k = 0; k < 3; k++)
            p[3 * c + k] = (c >> k) & 1;
    int n = 16;
    for (int i = 0; i < 300; i++, n++)       /* interior */
        for (int k = 0; k < 3; k++)
            p[3 * n + k] = rng_uniform(r);
    for (int i = 0; i < 300; i++, n++) {     /* on faces */
        int axis = i % 3;
        for (int k = 0; k < 3; k++)
            p[3 * n + k] = k == axis ? (double)((i / 3) & 1) : rng_uniform(r);
    }
    for (int i = 0; i < 120; i++, n++) {     /* on edges */
        int axis = i % 3;
        for (int k = 0; k < 3; k++)
            p[3 * n + k] = k == axis ? rng_uniform(r) : (double)(((i / 3) >> k) & 1);
    }
    for (int i = 0; i < 18; i++, n++) {      /* face centres, edge midpoints */
        int axis = i % 3;
        for (int k = 0; k < 3; k++)
            p[3 * n + k] = i < 6 ? (k == axis ? (double)(i / 3) : 0.5)
                                 : (k == axis ? 0.5 : (double)((((i - 6) / 3) >> k) & 1));
    }
    for (int i = 0; i < 3 * n; i++)
        p[i] = lo + size * p[i];
    shuffle(r, p, n);
    return n;
}

/* ---- exact answers ----------------------------------------------------------- */

static void test_cube_with_inner_face_and_edge_points_keeps_8_corners_12_triangles(void **state)
{
    (void)state;
    rng r = { 1 };
    double p[3 * 800];
    int n = cube_cloud(&r, p, 0, 1);
    mesh m;
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, 8);
    assert_int_equal(m.nt, 12);
    for (int i = 0; i < 3 * m.nv; i++)
        assert_true(m.xyz[i] == 0 || m.xyz[i] == 1);
    assert_true(fabs(mesh_volume(&m, 1) - 1) < 1e-12);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);
}

/* Every point of an 11 x 11 x 11 lattice on the cube's surface: rows of
 * collinear and sheets of coplanar points, nothing in general position. */
static void test_cube_surface_lattice_reduces_to_corners(void **state)
{
    (void)state;
    double *p = malloc(3 * 1331 * sizeof *p);
    assert_non_null(p);
    int n = 0;
    for (int i = 0; i <= 10; i++)
        for (int j = 0; j <= 10; j++)
            for (int k = 0; k <= 10; k++) {
                if (i % 10 && j % 10 && k % 10)
                    continue;
                p[3 * n] = i / 10.0 * 2;
                p[3 * n + 1] = j / 10.0 * 3;
                p[3 * n + 2] = k / 10.0 * 4;
                n++;
            }
    mesh m;
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, 8);
    assert_int_equal(m.nt, 12);
    assert_true(fabs(mesh_volume(&m, 1) - 24) < 1e-12);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);
    free(p);
}

/* Regular tetrahedron with edge 2 sqrt 2 (volume 8/3), alone and with its
 * edge midpoints, face centroids and interior points. */
static void test_regular_tetrahedron_keeps_its_4_corners(void **state)
{
    (void)state;
    static const double c[4][3] = { { 1, 1, 1 }, { 1, -1, -1 }, { -1, 1, -1 }, { -1, -1, 1 } };
    double p[3 * 64];
    int n = 0;
    for (int i = 0; i < 4; i++, n++)
        memcpy(&p[3 * n], c[i], sizeof c[i]);
    mesh m;
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, 4);
    assert_int_equal(m.nt, 4);
    assert_true(fabs(mesh_volume(&m, 1) - 8.0 / 3) < 1e-14);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);

    rng r = { 2 };
    for (int i = 0; i < 4; i++)
        for (int j = i + 1; j < 4; j++, n++)     /* edge midpoints */
            for (int k = 0; k < 3; k++)
                p[3 * n + k] = 0.5 * (c[i][k] + c[j][k]);
    for (int i = 0; i < 4; i++, n++)             /* face centroids */
        for (int k = 0; k < 3; k++)
            p[3 * n + k] = (c[(i + 1) % 4][k] + c[(i + 2) % 4][k] + c[(i + 3) % 4][k]) / 3;
    for (; n < 60; n++) {                        /* interior */
        double w[4], s = 0;
        for (int i = 0; i < 4; i++)
            s += w[i] = rng_uniform(&r);
        for (int k = 0; k < 3; k++)
            p[3 * n + k] = (w[0] * c[0][k] + w[1] * c[1][k] + w[2] * c[2][k] + w[3] * c[3][k]) / s;
    }
    shuffle(&r, p, n);
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, 4);
    assert_int_equal(m.nt, 4);
    assert_true(fabs(mesh_volume(&m, 1) - 8.0 / 3) < 1e-14);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);
}

/* A UV sphere's vertex grid as a mesher writes it: (stacks + 1) rings of
 * (slices + 1) points, so each pole repeats slices + 1 times (exactly at the
 * north pole, within 1e-16 at the south) and the seam is doubled. The hull
 * is the UV polyhedron: every distinct grid point, each quad in two
 * triangles, the same volume as the UV mesh. */
static void uv_sphere_case(int slices, int stacks)
{
    int n = (stacks + 1) * (slices + 1);
    double *p = malloc(3 * (size_t)n * sizeof *p);
    assert_non_null(p);
    for (int i = 0; i <= stacks; i++)
        for (int j = 0; j <= slices; j++) {
            double th = M_PI * i / stacks, ph = 2 * M_PI * j / slices;
            double *q = &p[3 * (i * (slices + 1) + j)];
            q[0] = 0.5 * sin(th) * cos(ph);
            q[1] = 0.5 * sin(th) * sin(ph);
            q[2] = 0.5 * cos(th);
        }
    /* Volume of the UV mesh itself: tetrahedra from the centre. */
    double vol = 0;
    for (int i = 0; i < stacks; i++)
        for (int j = 0; j < slices; j++) {
            int w = slices + 1;
            const double *a = &p[3 * (i * w + j)], *b = &p[3 * ((i + 1) * w + j)];
            const double *c = &p[3 * ((i + 1) * w + j + 1)], *d = &p[3 * (i * w + j + 1)];
            const double *t[2][3] = { { a, b, c }, { a, c, d } };
            for (int k = 0; k < 2; k++) {
                if ((i == 0 && k == 1) || (i == stacks - 1 && k == 0))
                    continue;                    /* pole caps are single triangles */
                const double *x = t[k][0], *y = t[k][1], *z = t[k][2];
                vol += (x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0]) +
                        x[2] * (y[0] * z[1] - y[1] * z[0])) / 6;
            }
        }
    mesh m;
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, slices * (stacks - 1) + 2);
    assert_int_equal(m.nt, 2 * slices * (stacks - 1));
    assert_true(fabs(mesh_volume(&m, 1) - vol) < 1e-14);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);
    free(p);
}

static void test_uv_sphere_with_duplicated_poles_gives_uv_polyhedron(void **state)
{
    (void)state;
    uv_sphere_case(16, 8);                       /* sc_shape_uv_sphere(r, 16, 8) */
    uv_sphere_case(32, 17);
    uv_sphere_case(64, 32);
}

/* Two rings of K points (a prism on a regular K-gon) with points at the cap
 * centres, inside the caps, on the side edges and inside the side faces:
 * only the ring points are vertices; 2K vertices, 4K - 4 triangles. */
static void test_cylinder_rings_with_cap_and_side_points_keep_ring_points(void **state)
{
    (void)state;
    enum { K = 48 };
    const double r0 = 0.3, h = 1.7;
    rng r = { 3 };
    double p[3 * 1200];
    int n = 0;
    for (int i = 0; i < K; i++)
        for (int s = 0; s < 2; s++, n++) {
            p[3 * n] = r0 * cos(2 * M_PI * i / K);
            p[3 * n + 1] = r0 * sin(2 * M_PI * i / K);
            p[3 * n + 2] = s * h;
        }
    for (int s = 0; s < 2; s++, n++) {           /* cap centres */
        p[3 * n] = p[3 * n + 1] = 0;
        p[3 * n + 2] = s * h;
    }
    for (int i = 0; i < 200; i++, n++) {         /* inside the caps */
        double a = 2 * M_PI * rng_uniform(&r), rr = 0.9 * r0 * sqrt(rng_uniform(&r));
        p[3 * n] = rr * cos(a);
        p[3 * n + 1] = rr * sin(a);
        p[3 * n + 2] = (i & 1) * h;
    }
    for (int i = 0; i < 2 * K; i++, n++) {       /* on the vertical side edges */
        memcpy(&p[3 * n], &p[3 * (2 * (i % K))], 2 * sizeof *p);
        p[3 * n + 2] = h * rng_uniform(&r);
    }
    for (int i = 0; i < 300; i++, n++) {         /* inside the side rectangles */
        int j = i % K;
        double t = rng_uniform(&r);
        for (int k = 0; k < 2; k++)
            p[3 * n + k] = (1 - t) * p[3 * (2 * j) + k] + t * p[3 * (2 * ((j + 1) % K)) + k];
        p[3 * n + 2] = h * rng_uniform(&r);
    }
    shuffle(&r, p, n);
    mesh m;
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, 2 * K);
    assert_int_equal(m.nt, 4 * K - 4);
    for (int v = 0; v < m.nv; v++) {
        double rr = hypot(m.xyz[3 * v], m.xyz[3 * v + 1]);
        assert_true(fabs(rr - r0) < 1e-15 && (m.xyz[3 * v + 2] == 0 || m.xyz[3 * v + 2] == h));
    }
    double vol = K / 2.0 * r0 * r0 * sin(2 * M_PI / K) * h;
    assert_true(fabs(mesh_volume(&m, 1) - vol) < 1e-13);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);
}

/* Each corner of a cube repeated 20 times, moved by up to 1e-13 (far below
 * eps ~ 3e-9): one vertex per corner. */
static void test_near_duplicate_points_collapse_to_one_vertex(void **state)
{
    (void)state;
    rng r = { 4 };
    double p[3 * 160];
    int n = 0;
    for (int c = 0; c < 8; c++)
        for (int i = 0; i < 20; i++, n++)
            for (int k = 0; k < 3; k++)
                p[3 * n + k] = ((c >> k) & 1) + (i ? 1e-13 * (2 * rng_uniform(&r) - 1) : 0);
    shuffle(&r, p, n);
    mesh m;
    assert_int_equal(build(p, n, &m), SC_OK);
    assert_int_equal(m.nv, 8);
    assert_int_equal(m.nt, 12);
    int seen[8] = { 0 };
    for (int v = 0; v < 8; v++) {
        int c = 0;
        for (int k = 0; k < 3; k++)
            c |= (m.xyz[3 * v + k] > 0.5) << k;
        seen[c]++;
    }
    for (int c = 0; c < 8; c++)
        assert_int_equal(seen[c], 1);
    assert_true(fabs(mesh_volume(&m, 1) - 1) < 1e-11);
    check_hull(p, n, &m, hull_eps(p, n), 1);
    mesh_free(&m);
}

/* The same cube cloud far from the origin (eps grows with |coordinate|) and
 * scaled by 1e200 and 1e-200 (no overflow or underflow inside); then with a
 * point 100 eps above the middle of the top face, which must stay: a
 * pyramid on the cube, 9 vertices and 14 triangles. */
static void test_cube_far_from_origin_and_at_extreme_scales(void **state)
{
    (void)state;
    static const double lo[] = { 1e6, -3e7, 0, 0 }, size[] = { 1, 1, 1e200, 1e-200 };
    for (int c = 0; c < 4; c++)
        for (int apex = 0; apex < 2; apex++) {
            rng r = { 5 }, r2 = r;
            double p[3 * 801];
            int n = cube_cloud(&r, p, lo[c] / size[c], 1);     /* in unit size */
            double h = 100 * hull_eps(p, n);
            cube_cloud(&r2, p, lo[c], size[c]);
            if (apex) {
                p[3 * n] = p[3 * n + 1] = lo[c] + 0.5 * size[c];
                p[3 * n + 2] = lo[c] + (1 + h) * size[c];
                h = (p[3 * n + 2] - lo[c]) / size[c] - 1;   /* as rounded */
                n++;
            }
            mesh m;
            assert_int_equal(build(p, n, &m), SC_OK);
            assert_int_equal(m.nv, 8 + apex);
            assert_int_equal(m.nt, 12 + 2 * apex);
            assert_true(fabs(mesh_volume(&m, size[c]) - (1 + apex * h / 3)) < 1e-9);
            /* Checked in unit size: the same division maps equal bits to
             * equal bits, and squares of 1e200 would overflow. */
            for (int i = 0; i < 3 * n; i++)
                p[i] /= size[c];
            for (int i = 0; i < 3 * m.nv; i++)
                m.xyz[i] /= size[c];
            check_hull(p, n, &m, hull_eps(p, n), 1);
            mesh_free(&m);
        }
}

/* ---- invariants on random input -------------------------------------------- */

static void test_random_ball_points_lie_inside_a_closed_outward_hull(void **state)
{
    (void)state;
    static const int sizes[] = { 10, 100, 10000 };
    for (int s = 0; s < 3; s++) {
        int n = sizes[s];
        rng r = { 100 + (uint64_t)s };
        double *p = malloc(3 * (size_t)n * sizeof *p);
        assert_non_null(p);
        for (int i = 0; i < n; i++)
            rng_ball(&r, &p[3 * i]);
        mesh m;
        assert_int_equal(build(p, n, &m), SC_OK);
        assert_true(m.nv <= n);
        check_hull(p, n, &m, hull_eps(p, n), 1);
        double vol = mesh_volume(&m, 1);
        assert_true(vol > 0 && vol < 4.0 / 3.0 * M_PI);
        mesh_free(&m);
        free(p);
    }
}

/* Points on a sphere are all extreme: each is a vertex. Random points, and
 * a Fibonacci lattice (many near-cocircular quadruples). */
static void test_points_on_a_sphere_are_all_vertices(void **state)
{
    (void)state;
    enum { N = 2000 };
    double *p = malloc(3 * N * sizeof *p);
    assert_non_null(p);
    rng r = { 6 };
    for (int i = 0; i < N; i++)
        rng_sphere(&r, &p[3 * i]);
    mesh m;
    assert_int_equal(build(p, N, &m), SC_OK);
    assert_int_equal(m.nv, N);
    check_hull(p, N, &m, hull_eps(p, N), 1);
    mesh_free(&m);

    for (int i = 0; i < N; i++) {
        double z = 1 - (2 * i + 1.0) / N, rr = sqrt(1 - z * z), a = i * M_PI * (3 - sqrt(5.0));
        p[3 * i] = rr * cos(a);
        p[3 * i + 1] = rr * sin(a);
        p[3 * i + 2] = z;
    }
    assert_int_equal(build(p, N, &m), SC_OK);
    assert_int_equal(m.nv, N);
    check_hull(p, N, &m, hull_eps(p, N), 1);
    mesh_free(&m);
    free(p);
}

/* Points thrown at the tolerance: cube faces carrying points pushed out by
 * 0 to 3 eps, so coplanar and "just outside" mix. The hull must stay closed,
 * outward and convex and hold every point within a few eps. */
static void test_points_within_a_few_eps_of_faces_keep_the_hull_valid(void **state)
{
    (void)state;
    enum { N = 3000 };
    double *p = malloc(3 * N * sizeof *p);
    assert_non_null(p);
    for (int trial = 0; trial < 20; trial++) {
        rng r = { 1000 + (uint64_t)trial };
        int n = cube_cloud(&r, p, 0, 1);
        double eps = hull_eps(p, n);
        for (; n < N; n++) {
            int axis = n % 3, side = (n / 3) & 1;
            for (int k = 0; k < 3; k++)
                p[3 * n + k] = rng_uniform(&r);
            p[3 * n + axis] = side ? 1 + 3 * eps * rng_uniform(&r) : -3 * eps * rng_uniform(&r);
        }
        mesh m;
        assert_int_equal(build(p, n, &m), SC_OK);
        check_hull(p, n, &m, 4 * hull_eps(p, n), 1);
        assert_true(fabs(mesh_volume(&m, 1) - 1) < 1e-7);
        mesh_free(&m);
    }
    free(p);
}

/* A plate only 3 to 50 eps thick: a point beside the rim is within eps of
 * the top and bottom planes yet may be far outside a rim face, so "within
 * eps of the face it was tested against" is not enough; such points must
 * be checked again against every face they see. */
static void test_points_beside_a_thin_plates_rim_stay_inside(void **state)
{
    (void)state;
    enum { N = 500 };
    double p[3 * N];
    for (int trial = 0; trial < 48; trial++) {
        rng r = { 2000 + (uint64_t)trial };
        double th = 2.7e-9 * (3 + trial);
        for (int i = 0; i < N; i++) {
            p[3 * i] = 2 * rng_uniform(&r) - 1;
            p[3 * i + 1] = 2 * rng_uniform(&r) - 1;
            p[3 * i + 2] = th * rng_uniform(&r);
        }
        mesh m;
        int rc = build(p, N, &m);
        if (rc == SC_EDEGENERATE)
            continue;                            /* thinner than eps where measured */
        assert_int_equal(rc, SC_OK);
        check_hull(p, N, &m, 2 * hull_eps(p, N), 1);
        mesh_free(&m);
    }
}

/* Twelve clusters of 40 points, each 1e-8 to 3e-8 across (a few eps, as
 * float data make): at eps they are distinct vertices whose triangles have
 * next to no area, which sc_mesh_check rejects. eps grows until each
 * cluster is one vertex. */
static void test_clusters_a_few_eps_across_weld_into_single_vertices(void **state)
{
    (void)state;
    enum { C = 12, K = 40 };
    double p[3 * C * K];
    for (int trial = 0; trial < 12; trial++) {
        rng r = { 3000 + (uint64_t)trial };
        int n = 0;
        for (int c = 0; c < C; c++) {
            double ctr[3];
            for (int k = 0; k < 3; k++)
                ctr[k] = 2 * rng_uniform(&r) - 1;
            for (int i = 0; i < K; i++, n++)
                for (int k = 0; k < 3; k++)
                    p[3 * n + k] = ctr[k] + (rng_uniform(&r) - 0.5) * 1e-8 * (1 + trial % 3);
        }
        mesh m;
        assert_int_equal(build(p, n, &m), SC_OK);
        assert_true(m.nv <= C);
        check_hull(p, n, &m, 30 * hull_eps(p, n), 1);
        mesh_free(&m);
    }
}

/* ---- errors ------------------------------------------------------------------- */

static void test_point_sets_without_volume_return_edegenerate(void **state)
{
    (void)state;
    double p[3 * 200];
    mesh m;
    rng r = { 7 };
    for (int i = 0; i < 3 * 200; i++)
        p[i] = rng_uniform(&r);
    for (int n = 0; n < 4; n++)                  /* too few points */
        assert_int_equal(build(p, n, &m), SC_EDEGENERATE);
    for (int i = 0; i < 200; i++) {              /* coincident */
        p[3 * i] = 0.25;
        p[3 * i + 1] = -3;
        p[3 * i + 2] = 7;
    }
    assert_int_equal(build(p, 200, &m), SC_EDEGENERATE);
    memset(p, 0, sizeof p);                      /* all at the origin */
    assert_int_equal(build(p, 200, &m), SC_EDEGENERATE);
    for (int i = 0; i < 200; i++) {              /* collinear */
        double t = rng_uniform(&r) * 10 - 5;
        p[3 * i] = 1 + t;
        p[3 * i + 1] = 2 - 2 * t;
        p[3 * i + 2] = 3 + 0.5 * t;
    }
    assert_int_equal(build(p, 200, &m), SC_EDEGENERATE);
    for (int i = 0; i < 200; i++) {              /* coplanar: x + 2y - z = 1 */
        double u = rng_uniform(&r) * 4 - 2, v = rng_uniform(&r) * 4 - 2;
        p[3 * i] = u;
        p[3 * i + 1] = v;
        p[3 * i + 2] = u + 2 * v - 1;
    }
    assert_int_equal(build(p, 200, &m), SC_EDEGENERATE);
    for (int i = 0; i < 200; i++)                /* flat within 1e-12 << eps */
        p[3 * i + 2] = 1e-12 * (rng_uniform(&r) - 0.5);
    assert_int_equal(build(p, 200, &m), SC_EDEGENERATE);
    assert_null(m.xyz);
    assert_null(m.tri);
    assert_int_equal(m.nv, 0);
    assert_int_equal(m.nt, 0);
    for (int i = 0; i < 200; i++)                /* 1e-6 thick: has volume */
        p[3 * i + 2] = 1e-6 * rng_uniform(&r);
    assert_int_equal(build(p, 200, &m), SC_OK);
    check_hull(p, 200, &m, hull_eps(p, 200), 1);
    mesh_free(&m);
}

static void test_bad_arguments_return_einval(void **state)
{
    (void)state;
    double p[3 * 8], *xyz = (double *)p;
    int *tri = (int *)p, nv = 7, nt = 7;
    for (int c = 0; c < 8; c++)
        for (int k = 0; k < 3; k++)
            p[3 * c + k] = (c >> k) & 1;
    assert_int_equal(sc_hull_build(NULL, 8, &xyz, &nv, &tri, &nt), SC_EINVAL);
    assert_null(xyz);                            /* outputs cleared on error */
    assert_null(tri);
    assert_int_equal(nv, 0);
    assert_int_equal(nt, 0);
    assert_int_equal(sc_hull_build(NULL, 0, &xyz, &nv, &tri, &nt), SC_EINVAL);
    assert_int_equal(sc_hull_build(p, -1, &xyz, &nv, &tri, &nt), SC_EINVAL);
    assert_int_equal(sc_hull_build(p, 8, NULL, &nv, &tri, &nt), SC_EINVAL);
    assert_int_equal(sc_hull_build(p, 8, &xyz, NULL, &tri, &nt), SC_EINVAL);
    assert_int_equal(sc_hull_build(p, 8, &xyz, &nv, NULL, &nt), SC_EINVAL);
    assert_int_equal(sc_hull_build(p, 8, &xyz, &nv, &tri, NULL), SC_EINVAL);
    static const double bad[] = { NAN, INFINITY, -INFINITY };
    for (int b = 0; b < 3; b++)
        for (int i = 0; i < 3 * 8; i += 7) {
            double q[3 * 8];
            memcpy(q, p, sizeof q);
            q[i] = bad[b];
            assert_int_equal(sc_hull_build(q, 8, &xyz, &nv, &tri, &nt), SC_EINVAL);
            assert_int_equal(sc_hull_build(q, 3, &xyz, &nv, &tri, &nt),
                             i < 9 ? SC_EINVAL : SC_EDEGENERATE);
        }
}

static void test_more_than_max_points_returns_etoobig(void **state)
{
    (void)state;
    double *p = calloc(3 * ((size_t)SC_MESH_MAX_VERTS + 1), sizeof *p);
    assert_non_null(p);
    mesh m;
    assert_int_equal(build(p, SC_MESH_MAX_VERTS + 1, &m), SC_ETOOBIG);
    assert_int_equal(build(p, INT32_MAX, &m), SC_ETOOBIG);
    free(p);
}

/* Every allocation in turn fails: SC_ENOMEM with the outputs cleared, until
 * the build gets all it needs. The sanitizer and valgrind runs catch leaks. */
static void test_allocation_failure_returns_enomem_and_leaks_nothing(void **state)
{
    (void)state;
    rng r = { 8 };
    double p[3 * 1400];
    int n = cube_cloud(&r, p, 0, 1);
    for (; n < 1400; n++)                        /* and a cap of random points */
        rng_sphere(&r, &p[3 * n]);
    mesh ref, m;
    assert_int_equal(build(p, n, &ref), SC_OK);
    long k;
    int rc = SC_ENOMEM;
    for (k = 0; k < 100000 && rc != SC_OK; k++) {
        sc_hull_alloc_budget = k;
        rc = build(p, n, &m);
        sc_hull_alloc_budget = -1;
        if (rc != SC_OK) {
            assert_int_equal(rc, SC_ENOMEM);
            assert_null(m.xyz);
            assert_null(m.tri);
            assert_int_equal(m.nv, 0);
            assert_int_equal(m.nt, 0);
        }
    }
    assert_int_equal(rc, SC_OK);
    assert_true(k > 10);                         /* it did fail along the way */
    assert_int_equal(m.nv, ref.nv);
    assert_int_equal(m.nt, ref.nt);
    assert_memory_equal(m.tri, ref.tri, 3 * (size_t)m.nt * sizeof *m.tri);
    mesh_free(&m);
    mesh_free(&ref);
}

/* ---- determinism and time ------------------------------------------------------ */

static void test_same_input_gives_bitwise_identical_hull(void **state)
{
    (void)state;
    enum { N = 20000 };
    double *p = malloc(3 * N * sizeof *p);
    assert_non_null(p);
    rng r = { 9 };
    int n = cube_cloud(&r, p, -0.5, 1.9);
    for (; n < N; n++)
        rng_ball(&r, &p[3 * n]);
    mesh a, b;
    assert_int_equal(build(p, N, &a), SC_OK);
    assert_int_equal(build(p, N, &b), SC_OK);
    assert_int_equal(a.nv, b.nv);
    assert_int_equal(a.nt, b.nt);
    assert_memory_equal(a.xyz, b.xyz, 3 * (size_t)a.nv * sizeof *a.xyz);
    assert_memory_equal(a.tri, b.tri, 3 * (size_t)a.nt * sizeof *a.tri);
    mesh_free(&a);
    mesh_free(&b);
    free(p);
}

/* Timing only (printed, not asserted): 100 000 points in a ball, and on a
 * sphere (every point a vertex, the worst case for output size). The hulls
 * are checked, with every 97th (997th on the sphere) point for containment. */
static void test_hull_of_100k_points_is_valid_and_timed(void **state)
{
    (void)state;
    enum { N = 100000 };
    double *p = malloc(3 * N * sizeof *p);
    assert_non_null(p);
    for (int s = 0; s < 2; s++) {
        rng r = { 10 };
        for (int i = 0; i < N; i++)
            (s ? rng_sphere : rng_ball)(&r, &p[3 * i]);
        mesh m;
        double t0 = now_ms();
        assert_int_equal(build(p, N, &m), SC_OK);
        double t1 = now_ms();
        print_message("hull of %d points %s: %.1f ms, %d vertices, %d triangles\n", N,
                      s ? "on a sphere" : "in a ball", t1 - t0, m.nv, m.nt);
        if (s)
            assert_int_equal(m.nv, N);
        check_hull(p, N, &m, hull_eps(p, N), s ? 997 : 97);
        mesh_free(&m);
    }
    free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube_with_inner_face_and_edge_points_keeps_8_corners_12_triangles),
        cmocka_unit_test(test_cube_surface_lattice_reduces_to_corners),
        cmocka_unit_test(test_regular_tetrahedron_keeps_its_4_corners),
        cmocka_unit_test(test_uv_sphere_with_duplicated_poles_gives_uv_polyhedron),
        cmocka_unit_test(test_cylinder_rings_with_cap_and_side_points_keep_ring_points),
        cmocka_unit_test(test_near_duplicate_points_collapse_to_one_vertex),
        cmocka_unit_test(test_cube_far_from_origin_and_at_extreme_scales),
        cmocka_unit_test(test_random_ball_points_lie_inside_a_closed_outward_hull),
        cmocka_unit_test(test_points_on_a_sphere_are_all_vertices),
        cmocka_unit_test(test_points_within_a_few_eps_of_faces_keep_the_hull_valid),
        cmocka_unit_test(test_points_beside_a_thin_plates_rim_stay_inside),
        cmocka_unit_test(test_clusters_a_few_eps_across_weld_into_single_vertices),
        cmocka_unit_test(test_point_sets_without_volume_return_edegenerate),
        cmocka_unit_test(test_bad_arguments_return_einval),
        cmocka_unit_test(test_more_than_max_points_returns_etoobig),
        cmocka_unit_test(test_allocation_failure_returns_enomem_and_leaks_nothing),
        cmocka_unit_test(test_same_input_gives_bitwise_identical_hull),
        cmocka_unit_test(test_hull_of_100k_points_is_valid_and_timed),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
