/* test_broadphase.c - both broad phases against a brute-force reference:
 * every method must return exactly the pairs (a < b, sorted) whose spheres
 * overlap by the documented closed test and of which one is active, on
 * seeded scenes chosen to break a sweep (planes, identical centres, exact
 * touching, far offsets, mixed radii) and over frames of moving bodies. */
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "core.h"

static const int methods[] = { SC_BROADPHASE_SPHERES, SC_BROADPHASE_SAP, SC_BROADPHASE_AUTO };
#define NMETHODS 3

/* ---- seeded random numbers (splitmix64: the same scenes on every run) ---- */
typedef struct rng { uint64_t s; } rng;

static uint64_t rng_next(rng *g)
{
    uint64_t z = (g->s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static double uni(rng *g, double lo, double hi)
{
    return lo + (hi - lo) * ((double)(rng_next(g) >> 11) * 0x1.0p-53);
}

static double gauss(rng *g)
{
    double u = uni(g, 1e-12, 1), v = uni(g, 0, 1);
    return sqrt(-2 * log(u)) * cos(6.283185307179586 * v);
}

/* ---- a scene and the reference ---- */
typedef struct scene {
    int n;
    double *c, *r;
    unsigned char *act;       /* NULL = all active */
} scene;

static scene scene_new(int n, int with_active)
{
    scene s = { n, calloc((size_t)n * 3 + 1, sizeof(double)),
                calloc((size_t)n + 1, sizeof(double)), NULL };
    assert_non_null(s.c);
    assert_non_null(s.r);
    if (with_active) {
        s.act = calloc((size_t)n + 1, 1);
        assert_non_null(s.act);
    }
    return s;
}

static double *centre(const scene *s, int i)
{
    return &s->c[3 * i];
}

static void scene_free(scene *s)
{
    free(s->c);
    free(s->r);
    free(s->act);
}

/* The contract written out independently: d = c_b - c_a, s = r_a + r_b,
 * overlap when d.d <= s*s, at least one active; a < b in order. */
static int reference(const scene *s, sc_pair **out)
{
    int np = 0, cap = 0;
    *out = NULL;
    for (int a = 0; a < s->n; a++)
        for (int b = a + 1; b < s->n; b++) {
            if (s->act && !s->act[a] && !s->act[b])
                continue;
            double dx = s->c[3 * b] - s->c[3 * a];
            double dy = s->c[3 * b + 1] - s->c[3 * a + 1];
            double dz = s->c[3 * b + 2] - s->c[3 * a + 2];
            double rs = s->r[a] + s->r[b];
            if (!(dx * dx + dy * dy + dz * dz <= rs * rs))
                continue;
            if (np == cap) {
                cap = cap ? 2 * cap : 256;
                *out = realloc(*out, (size_t)cap * sizeof **out);
                assert_non_null(*out);
            }
            (*out)[np++] = (sc_pair){ a, b };
        }
    return np;
}

static void assert_same_pairs(const sc_pair *want, int nwant, const sc_pair *got, int ngot,
                              const char *what)
{
    if (nwant != ngot)
        print_error("%s: %d pairs, reference %d\n", what, ngot, nwant);
    assert_int_equal(ngot, nwant);
    for (int i = 0; i < nwant; i++) {
        if (got[i].a != want[i].a || got[i].b != want[i].b)
            print_error("%s: pair %d is (%d, %d), reference (%d, %d)\n", what, i, got[i].a,
                        got[i].b, want[i].a, want[i].b);
        assert_int_equal(got[i].a, want[i].a);
        assert_int_equal(got[i].b, want[i].b);
    }
}

/* Runs one method through bp (kept by the caller for coherence) and checks
 * the result against want. */
static void check_method(sc_broadphase *bp, int method, const scene *s, const sc_pair *want,
                         int nwant, const char *what)
{
    sc_pair *got = NULL;
    int cap = 0;
    int np = sc_bp_find_pairs(bp, method, s->c, s->r, s->act, s->n, &got, &cap);
    assert_true(np >= 0);
    assert_true(cap >= np);
    assert_same_pairs(want, nwant, got, np, what);
    free(got);
}

/* Every method, each with a fresh broad phase, equals the reference;
 * returns the number of pairs. */
static int check_all_methods(const scene *s, const char *what)
{
    sc_pair *want;
    int nwant = reference(s, &want);
    for (int m = 0; m < NMETHODS; m++) {
        sc_broadphase *bp = sc_bp_create();
        assert_non_null(bp);
        check_method(bp, methods[m], s, want, nwant, what);
        sc_bp_destroy(bp);
    }
    free(want);
    return nwant;
}

/* ---- scenes ---- */

static void fill_uniform(scene *s, rng *g, const double lo[3], const double hi[3], double rmin,
                         double rmax)
{
    for (int i = 0; i < s->n; i++) {
        for (int k = 0; k < 3; k++)
            s->c[3 * i + k] = uni(g, lo[k], hi[k]);
        s->r[i] = uni(g, rmin, rmax);
    }
}

/* The typical pile: radius ~0.05 over 2 x 2 x 1 m. */
static void fill_pile(scene *s, rng *g)
{
    static const double lo[3] = { 0, 0, 0 }, hi[3] = { 2, 2, 1 };
    fill_uniform(s, g, lo, hi, 0.045, 0.055);
}

static void test_both_methods_match_reference_on_uniform_scenes(void **state)
{
    (void)state;
    static const int sizes[] = { 3, 17, 100, 255, 256, 700, 2000 };
    rng g = { 1 };
    int total = 0;
    for (size_t t = 0; t < sizeof sizes / sizeof *sizes; t++) {
        scene s = scene_new(sizes[t], 0);
        fill_pile(&s, &g);
        total += check_all_methods(&s, "uniform pile");
        /* a sparse scene too: most bodies alone */
        static const double lo[3] = { -50, -50, -50 }, hi[3] = { 50, 50, 50 };
        fill_uniform(&s, &g, lo, hi, 0.1, 2);
        total += check_all_methods(&s, "uniform sparse");
        scene_free(&s);
    }
    assert_true(total > 2000);     /* the scenes really have contacts */
}

static void test_both_methods_match_reference_on_clustered_scenes(void **state)
{
    (void)state;
    rng g = { 2 };
    for (int rep = 0; rep < 4; rep++) {
        scene s = scene_new(1500, 0);
        double centre[8][3];
        for (int k = 0; k < 8; k++)
            for (int d = 0; d < 3; d++)
                centre[k][d] = uni(&g, -3, 3);
        double spread = rep == 0 ? 0.02 : rep == 1 ? 0.1 : 0.4;
        for (int i = 0; i < s.n; i++) {
            int k = (int)(rng_next(&g) % 8);
            for (int d = 0; d < 3; d++)
                s.c[3 * i + d] = centre[k][d] + spread * gauss(&g);
            s.r[i] = rep == 3 ? uni(&g, 0.001, 0.3) : 0.05;
        }
        assert_true(check_all_methods(&s, "clustered") > s.n / 10);
        scene_free(&s);
    }
}

/* All centres on one plane, for each axis: the sweep or a row axis has no
 * extent at all. */
static void test_both_methods_match_reference_with_all_bodies_on_one_plane(void **state)
{
    (void)state;
    rng g = { 3 };
    for (int axis = 0; axis < 3; axis++) {
        scene s = scene_new(1200, 0);
        fill_pile(&s, &g);
        for (int i = 0; i < s.n; i++)
            s.c[3 * i + axis] = 0.25;
        assert_true(check_all_methods(&s, "plane") > 0);
        /* and on a line along the axis */
        for (int i = 0; i < s.n; i++) {
            s.c[3 * i + axis] = uni(&g, -1, 1);
            s.c[3 * i + (axis + 1) % 3] = 0.5;
            s.c[3 * i + (axis + 2) % 3] = -0.5;
        }
        assert_true(check_all_methods(&s, "line") > s.n);
        scene_free(&s);
    }
}

/* Groups of bodies at exactly the same centre, zero radii included: every
 * pair in a group touches (0 <= s*s). */
static void test_both_methods_match_reference_with_many_identical_centres(void **state)
{
    (void)state;
    rng g = { 4 };
    scene s = scene_new(900, 0);
    fill_pile(&s, &g);
    for (int i = 0; i < s.n; i++) {
        int grp = i % 30;
        if (grp < 20) {           /* 20 groups of 30, the rest scattered */
            s.c[3 * i] = 0.1 * grp;
            s.c[3 * i + 1] = 0.3;
            s.c[3 * i + 2] = 0.2;
        }
        if (i % 7 == 0)
            s.r[i] = 0;
    }
    /* 20 groups of 30 all pair among themselves at least */
    assert_true(check_all_methods(&s, "identical centres") >= 20 * 30 * 29 / 2);
    /* everything at one point */
    for (int i = 0; i < s.n; i++) {
        s.c[3 * i] = s.c[3 * i + 1] = s.c[3 * i + 2] = -1.5;
        s.r[i] = (i % 3) * 0.01;
    }
    assert_int_equal(check_all_methods(&s, "one point"), s.n * (s.n - 1) / 2);
    scene_free(&s);
}

/* A cubic lattice of spacing 0.5 and radius 0.25: neighbours are exactly at
 * distance r_a + r_b (all exact in binary) and must count; one ulp smaller
 * radii must count none. Also far from the origin, where the sweep margins
 * are widest relative to the gap. */
static void test_touching_exactly_counts_as_overlap(void **state)
{
    (void)state;
    const int m = 9;
    const double offsets[] = { 0, -7.5, 1e6, 0x1p40, -0x1p40 };
    for (size_t o = 0; o < sizeof offsets / sizeof *offsets; o++) {
        scene s = scene_new(m * m * m, 0);
        for (int i = 0; i < s.n; i++) {
            s.c[3 * i] = offsets[o] + 0.5 * (i % m);
            s.c[3 * i + 1] = offsets[o] + 0.5 * (i / m % m);
            s.c[3 * i + 2] = 0.5 * (i / (m * m));
            s.r[i] = 0.25;
        }
        assert_int_equal(check_all_methods(&s, "touching lattice"), 3 * m * m * (m - 1));
        for (int i = 0; i < s.n; i++)
            s.r[i] = nextafter(0.25, 0);
        assert_int_equal(check_all_methods(&s, "lattice one ulp apart"), 0);
        /* unequal radii that still sum exactly: 0.125 + 0.375 */
        for (int i = 0; i < s.n; i++)
            s.r[i] = (i % 2) ? 0.125 : 0.375;
        assert_true(check_all_methods(&s, "unequal touching") > 0);
        scene_free(&s);
    }
    /* a 3-4-5 triangle: distance 5/8 == 1/4 + 3/8, touching off the axes */
    scene s = scene_new(2, 0);
    s.c[3] = 0.375;
    s.c[4] = 0.5;
    s.r[0] = 0.25;
    s.r[1] = 0.375;
    assert_int_equal(check_all_methods(&s, "3-4-5"), 1);
    s.r[1] = 0.375 - 0x1p-53;      /* r_a + r_b one ulp below 5/8 */
    assert_int_equal(check_all_methods(&s, "3-4-5 apart"), 0);
    scene_free(&s);
}

/* Pairs placed at r_a + r_b times (1 + k ulp), k in -6..6, in random
 * directions and at random offsets up to 1e9: decided by the last bits of
 * the predicate, which the sweep must not pre-empt. */
static void test_both_methods_match_reference_on_pairs_at_the_rounding_edge(void **state)
{
    (void)state;
    rng g = { 5 };
    scene s = scene_new(1000, 0);
    for (int i = 0; i < s.n; i += 2) {
        double base = pow(10, uni(&g, -3, 9)) * (rng_next(&g) & 1 ? 1 : -1);
        double ra = pow(10, uni(&g, -7, 0));
        double rb = (rng_next(&g) & 1) ? ra : pow(10, uni(&g, -7, 0));
        double dir[3] = { gauss(&g), gauss(&g), gauss(&g) };
        if (rng_next(&g) % 3 == 0)      /* often straight along one axis */
            dir[0] = dir[1] = 0, dir[2] = 1;
        double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        double dist = (ra + rb) * (1 + (double)((int)(rng_next(&g) % 13) - 6) * 0x1p-52);
        for (int k = 0; k < 3; k++) {
            s.c[3 * i + k] = k == 1 ? 5.0 * i : base + 0.01 * k;
            s.c[3 * i + 3 + k] = s.c[3 * i + k] + dist * dir[k] / len;
        }
        s.r[i] = ra;
        s.r[i + 1] = rb;
    }
    /* pairs are 5 m apart in y: only the designed ones can touch, and
     * some fall on each side of the edge */
    int np = check_all_methods(&s, "rounding edge");
    assert_true(np > s.n / 20 && np < s.n / 2 - s.n / 20);
    scene_free(&s);
}

/* Pairs touching along one axis within a few ulps, spread along that axis
 * so that it is the sweep axis. For some of them the predicate holds although
 * the rounded intervals [x - r, x + r] are disjoint: a sweep without margins
 * loses those. The scene is checked to contain such pairs. */
static void test_sap_keeps_pairs_whose_rounded_intervals_are_disjoint(void **state)
{
    (void)state;
    rng g = { 14 };
    static const double scales[] = { 1, 1e3, 1e6 };
    for (int axis = 0; axis < 3; axis++) {
        scene s = scene_new(2000, 0);
        int naive_misses = 0;
        for (int i = 0; i < s.n; i += 2) {
            int p = i / 2;
            double ri = uni(&g, 0.01, 1), rj = rng_next(&g) & 1 ? ri : uni(&g, 0.01, 1);
            double xi = scales[p % 3] * uni(&g, -2, 2);
            double xj = xi + (ri + rj);
            for (int k = (int)(rng_next(&g) % 6); k > 0; k--)   /* a few ulps off */
                xj = nextafter(xj, rng_next(&g) & 1 ? INFINITY : -INFINITY);
            double *a = centre(&s, i), *b = centre(&s, i + 1);
            a[axis] = xi;
            b[axis] = xj;
            a[(axis + 1) % 3] = b[(axis + 1) % 3] = 5.0 * (p % 30);   /* pairs apart */
            a[(axis + 2) % 3] = b[(axis + 2) % 3] = 5.0 * (p / 30);
            s.r[i] = ri;
            s.r[i + 1] = rj;
            double dx = xj - xi, rs = ri + rj;
            if (dx * dx <= rs * rs && xj - rj > xi + ri)
                naive_misses++;
        }
        assert_true(naive_misses > 0);
        int np = check_all_methods(&s, "disjoint rounded intervals");
        assert_true(np > naive_misses);
        scene_free(&s);
    }
}

/* Two spheres of radius 2^e at -2^(e-60) and 2^(e+1) along one axis: the
 * difference rounds to exactly r_a + r_b, so they touch, while the exact
 * distance is a hair more than their diameter and their centres lie two
 * diameter-sized cells apart. A grid sized by the bare diameter misses them.
 * Tried along every axis, with the scene stretched along every axis (so the
 * pair is split along the sweep axis or along a row axis). */
static void test_touching_pairs_across_grid_cell_boundaries_are_found(void **state)
{
    (void)state;
    for (int sweep = 0; sweep < 3; sweep++)
        for (int axis = 0; axis < 3; axis++) {
            scene s = scene_new(2 * 14 + 40, 0);
            int i = 0;
            for (int e = -10; e <= 3; e++, i += 2) {
                double r = ldexp(1, e);
                double *a = centre(&s, i), *b = centre(&s, i + 1);
                for (int k = 0; k < 3; k++)
                    a[k] = b[k] = 100.0 * (e + 10);       /* pairs far apart */
                a[axis] = -ldexp(1, e - 60);              /* < half an ulp of b */
                b[axis] = 2 * r;
                s.r[i] = s.r[i + 1] = r;
            }
            for (int k = 0; i < s.n; i++, k++) {          /* stretch the scene */
                s.c[3 * i + sweep] = 1e4 * (k - 20);
                s.c[3 * i + (sweep + 1) % 3] = -500;
                s.r[i] = 1e-3;
            }
            assert_int_equal(check_all_methods(&s, "cell boundary"), 14);
            scene_free(&s);
        }
}

/* Radii from 0 and 1e-9 to 1e3 in one scene: several grid levels. */
static void test_both_methods_match_reference_with_huge_and_tiny_radii_mixed(void **state)
{
    (void)state;
    rng g = { 6 };
    for (int rep = 0; rep < 3; rep++) {
        scene s = scene_new(1500, 0);
        static const double lo[3] = { -2, -2, -1 }, hi[3] = { 2, 2, 1 };
        fill_uniform(&s, &g, lo, hi, 0, 0);
        for (int i = 0; i < s.n; i++) {
            int kind = (int)(rng_next(&g) % 20);
            s.r[i] = kind == 0   ? 0
                     : kind == 1 ? pow(10, uni(&g, 0, 3))      /* huge */
                     : kind < 6  ? pow(10, uni(&g, -9, -4))    /* tiny */
                     : rep == 0  ? 0.05
                                 : pow(10, uni(&g, -3, -0.5));
        }
        if (rep == 2)                   /* tiny bodies touching huge ones */
            for (int i = 0; i + 1 < s.n; i += 10) {
                s.r[i] = 1e3;
                memcpy(&s.c[3 * (i + 1)], &s.c[3 * i], 3 * sizeof(double));
                s.c[3 * (i + 1)] += 1e3;
                s.r[i + 1] = 1e-9;
            }
        assert_true(check_all_methods(&s, "mixed radii") > 0);
        scene_free(&s);
    }
}

/* Inactive (static or sleeping) bodies pair only with active ones. */
static void test_inactive_pairs_are_excluded(void **state)
{
    (void)state;
    rng g = { 7 };
    static const double fracs[] = { 0, 0.05, 0.3, 1 };
    for (size_t f = 0; f < sizeof fracs / sizeof *fracs; f++) {
        scene s = scene_new(1500, 1);
        fill_pile(&s, &g);
        for (int i = 0; i < s.n; i++)
            s.act[i] = (unsigned char)(uni(&g, 0, 1) < fracs[f] ? 1 + i % 200 : 0);
        int np = check_all_methods(&s, "active flags");
        if (fracs[f] == 0)
            assert_int_equal(np, 0);
        /* no reported pair has both inactive */
        sc_broadphase *bp = sc_bp_create();
        sc_pair *p = NULL;
        int cap = 0;
        int got = sc_bp_find_pairs(bp, SC_BROADPHASE_SAP, s.c, s.r, s.act, s.n, &p, &cap);
        assert_int_equal(got, np);
        for (int i = 0; i < got; i++)
            assert_true(s.act[p[i].a] || s.act[p[i].b]);
        /* all flags set is the same as NULL */
        if (fracs[f] == 1) {
            unsigned char *keep = s.act;
            s.act = NULL;
            assert_int_equal(check_all_methods(&s, "NULL active"), np);
            s.act = keep;
        }
        free(p);
        sc_bp_destroy(bp);
        scene_free(&s);
    }
}

static void test_zero_one_and_two_bodies(void **state)
{
    (void)state;
    scene s = scene_new(2, 1);
    for (int m = 0; m < NMETHODS; m++) {
        sc_broadphase *bp = sc_bp_create();
        sc_pair *p = NULL;
        int cap = 0;
        assert_int_equal(sc_bp_find_pairs(bp, methods[m], NULL, NULL, NULL, 0, &p, &cap), 0);
        assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, 1, &p, &cap), 0);
        s.c[3] = 1;
        s.r[0] = s.r[1] = 0.5;                          /* touching */
        s.act[0] = 1;
        s.act[1] = 0;
        assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, s.act, 2, &p, &cap), 1);
        assert_int_equal(p[0].a, 0);
        assert_int_equal(p[0].b, 1);
        s.act[0] = 0;                                   /* both inactive */
        assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, s.act, 2, &p, &cap), 0);
        s.c[3] = 1.5;                                   /* apart */
        assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, 2, &p, &cap), 0);
        s.c[3] = 1;
        assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, 1, &p, &cap), 0);
        free(p);
        sc_bp_destroy(bp);
    }
    scene_free(&s);
}

/* One broad phase kept over frames: bodies jitter, some jump across the
 * scene, radii change, the scene collapses onto a plane (the sweep axis
 * changes); SAP must stay exact every frame. */
static void test_sap_stays_exact_over_frames_of_moving_bodies(void **state)
{
    (void)state;
    rng g = { 8 };
    scene s = scene_new(1500, 1);
    fill_pile(&s, &g);
    for (int i = 0; i < s.n; i++)
        s.act[i] = i % 5 != 0;
    sc_broadphase *bp = sc_bp_create();
    sc_pair *p = NULL;
    int cap = 0;
    for (int frame = 0; frame < 60; frame++) {
        for (int i = 0; i < s.n; i++) {
            for (int k = 0; k < 3; k++)
                s.c[3 * i + k] += uni(&g, -0.01, 0.01);
            if (rng_next(&g) % 200 == 0)         /* a few teleport */
                s.c[3 * i] = uni(&g, 0, 2);
            if (rng_next(&g) % 500 == 0)
                s.r[i] = uni(&g, 0.01, 0.2);
        }
        if (frame == 30)                         /* everything on the plane x = 1 */
            for (int i = 0; i < s.n; i++)
                s.c[3 * i] = 1;
        if (frame == 45)                         /* and spread out again */
            for (int i = 0; i < s.n; i++)
                s.c[3 * i] = uni(&g, 0, 2);
        sc_pair *want;
        int nwant = reference(&s, &want);
        int np = sc_bp_find_pairs(bp, SC_BROADPHASE_SAP, s.c, s.r, s.act, s.n, &p, &cap);
        assert_same_pairs(want, nwant, p, np, "moving frame");
        free(want);
    }
    free(p);
    sc_bp_destroy(bp);
    scene_free(&s);
}

/* The candidate list (sc_bp_find_pairs_skin()): over calls in which the
 * bodies move within their skins, past them (a few teleport), exactly to
 * a touch, change radius or activity, with skins of zero, with the list
 * dropped between "frames" and the body count changed, both methods give
 * the reference's pairs every time, and the list is reused. */
static void test_skin_list_matches_reference_over_moving_calls(void **state)
{
    (void)state;
    static const int meth[] = { SC_BROADPHASE_SPHERES, SC_BROADPHASE_SAP };
    for (int m = 0; m < 2; m++) {
        rng g = { 31 + (uint64_t)m };
        scene s = scene_new(700, 1);
        fill_pile(&s, &g);
        double *skin = calloc((size_t)s.n, sizeof *skin);
        assert_non_null(skin);
        for (int i = 0; i < s.n; i++) {
            s.act[i] = i % 7 != 0;
            skin[i] = i % 11 == 0 ? 0 : uni(&g, 0.001, 0.03);
        }
        sc_broadphase *bp = sc_bp_create();
        assert_non_null(bp);
        sc_pair *p = NULL;
        int cap = 0, n_full = s.n;
        for (int call = 0; call < 120; call++) {
            if (call % 10 == 0) {
                sc_bp_list_drop(bp);     /* a new frame */
                s.n = call == 60 ? n_full - 37 : n_full;
            }
            for (int i = 0; i < s.n; i++) {
                double *c = centre(&s, i);
                if (skin[i] > 0)          /* within the skin over a frame */
                    for (int k = 0; k < 3; k++)
                        c[k] += uni(&g, -0.05, 0.05) * skin[i];
                if (call % 10 == 7 && rng_next(&g) % 300 == 0) /* past it */
                    c[0] = uni(&g, 0, 2);
                if (call % 10 == 3 && rng_next(&g) % 300 == 0)
                    s.r[i] = uni(&g, 0.02, 0.08);
                if (call % 10 == 8 && rng_next(&g) % 300 == 0)
                    s.act[i] = !s.act[i];
            }
            if (call % 10 == 5) {
                /* two bodies moved onto an exact touch along x */
                int a = (int)(rng_next(&g) % (uint64_t)s.n), b = (a + 1) % s.n;
                double *ca = centre(&s, a), *cb = centre(&s, b);
                cb[1] = ca[1];
                cb[2] = ca[2];
                cb[0] = ca[0] + (s.r[a] + s.r[b]);
            }
            sc_pair *want;
            int nwant = reference(&s, &want);
            int np = sc_bp_find_pairs_skin(bp, NULL, meth[m], s.c, s.r, skin, s.act, s.n, &p,
                                           &cap);
            assert_same_pairs(want, nwant, p, np, meth[m] ? "skin list, SAP" : "skin list");
            free(want);
        }
        assert_true(sc_bp_list_reused(bp) > 30);
        free(p);
        free(skin);
        sc_bp_destroy(bp);
        scene_free(&s);
    }
}

/* Pairs from a superset (the motion groups' check, group.c): candidates
 * from larger spheres around most bodies, the rest (not inside: moved out
 * of theirs, or given new radii, or at an exact touch) tested against
 * every body; the same set as the reference, inactive bodies included. */
static void test_pairs_within_a_superset_match_reference(void **state)
{
    (void)state;
    for (int round = 0; round < 6; round++) {
        rng g = { 71 + (uint64_t)round };
        scene big = scene_new(600, 1), s = scene_new(600, 1);
        static const double lo[3] = { 0, 0, 0 }, hi[3] = { 2, 2, 1 };
        fill_uniform(&big, &g, lo, hi, 0.1, 0.15);
        unsigned char *inside = calloc((size_t)s.n, 1);
        assert_non_null(inside);
        for (int i = 0; i < s.n; i++) {
            big.act[i] = s.act[i] = i % 5 != 0;
            double *cb = centre(&big, i), *c = centre(&s, i);
            double room = uni(&g, 0, 0.5) * big.r[i];
            for (int k = 0; k < 3; k++)
                c[k] = cb[k] + uni(&g, -0.5, 0.5) * room;
            s.r[i] = big.r[i] - room;
            inside[i] = 1;
            if (rng_next(&g) % (round < 3 ? 40 : 4) == 0) {  /* out of its sphere */
                c[0] += uni(&g, 0, 0.3);
                s.r[i] = uni(&g, 0.005, 0.06);
                inside[i] = 0;
            }
            if (round == 5 && i % 9 == 0) { /* inactive in the superset only */
                big.act[i] = 0;
                inside[i] = !s.act[i];
            }
        }
        if (round == 2) {
            /* two bodies not inside moved onto an exact touch */
            inside[3] = inside[4] = 0;
            double *a = centre(&s, 3), *b = centre(&s, 4);
            b[1] = a[1];
            b[2] = a[2];
            b[0] = a[0] + (s.r[3] + s.r[4]);
        }
        sc_pair *cand, *want, *p = NULL;
        int ncand = reference(&big, &cand), nwant = reference(&s, &want), cap = 0;
        sc_broadphase *bp = sc_bp_create();
        assert_non_null(bp);
        int np = sc_bp_pairs_within(bp, cand, ncand, inside, s.c, s.r, s.act, s.n, &p, &cap);
        assert_same_pairs(want, nwant, p, np, "within a superset");
        assert_true(nwant > 100);
        /* no candidates: every pair comes from the bodies not inside */
        memset(inside, 0, (size_t)s.n);
        np = sc_bp_pairs_within(bp, NULL, 0, inside, s.c, s.r, s.act, s.n, &p, &cap);
        assert_same_pairs(want, nwant, p, np, "none inside");
        s.c[0] = NAN;
        assert_int_equal(sc_bp_pairs_within(bp, cand, ncand, inside, s.c, s.r, s.act, s.n, &p,
                                            &cap),
                         SC_EINVAL);
        free(cand);
        free(want);
        free(p);
        free(inside);
        sc_bp_destroy(bp);
        scene_free(&big);
        scene_free(&s);
    }
}

/* Two spheres 2.5 skins apart (not candidates): one moving 0.9 of its
 * skin and the other 1.9 of its own bring them into overlap; the list
 * must be made again for the second, and the pair is found. Then from a
 * new list both move a quarter past their skins onto an exact touch
 * (r_a + r_b apart), found, and apart again. */
static void test_skin_list_is_made_again_past_a_skin(void **state)
{
    (void)state;
    for (int m = 0; m < 2; m++) {
        int meth = m ? SC_BROADPHASE_SAP : SC_BROADPHASE_SPHERES;
        double c[6] = { 0, 0, 0, 0, 0, 0 }, r[2] = { 0.5, 0.5 }, skin[2] = { 0.1, 0.1 };
        sc_broadphase *bp = sc_bp_create();
        assert_non_null(bp);
        sc_pair *p = NULL;
        int cap = 0;
        c[3] = 1.0 + 2.5 * 0.1;
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 0);
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 0);
        c[0] += 0.09;
        c[3] -= 0.19;
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 1);
        assert_int_equal(p[0].a, 0);
        assert_int_equal(p[0].b, 1);
        /* apart again, a new list; then 0 moves exactly its skin onto an
         * exact touch with 1 (1.0 apart: r_a + r_b) */
        sc_bp_list_drop(bp);
        c[0] = 0;
        c[3] = 1.1;
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 0);
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 0);
        c[0] = 0.125;
        c[3] = 1.125;
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 1);
        c[0] = 0.1;
        assert_int_equal(sc_bp_find_pairs_skin(bp, NULL, meth, c, r, skin, NULL, 2, &p, &cap), 0);
        free(p);
        sc_bp_destroy(bp);
    }
}

/* The body count changes between calls on one broad phase (bodies added,
 * removed, all removed, methods alternated). */
/* SAP after a call that moved few bodies tests only theirs again (its
 * last pairs for the others): after moving 1, 3 or 20 of 400 bodies (some
 * onto others, some apart), growing a radius, waking or sleeping one, or
 * moving them all, the reference's pairs every time. */
static void test_sap_exact_when_few_bodies_moved(void **state)
{
    (void)state;
    rng g = { 77 };
    scene s = scene_new(400, 1);
    for (int i = 0; i < s.n; i++) {
        for (int k = 0; k < 3; k++)
            centre(&s, i)[k] = uni(&g, 0, 1.5);
        s.r[i] = uni(&g, 0.02, 0.09);
        s.act[i] = rng_next(&g) % 5 != 0;
    }
    sc_broadphase *bp = sc_bp_create();
    assert_non_null(bp);
    for (int round = 0; round < 60; round++) {
        sc_pair *want;
        int nwant = reference(&s, &want);
        check_method(bp, SC_BROADPHASE_SAP, &s, want, nwant, "few moved");
        free(want);
        int kind = round % 6, moves = kind == 0 ? 1 : kind == 1 ? 3 : kind == 2 ? 20 : 1;
        if (kind == 5)
            moves = s.n;
        for (int m = 0; m < moves; m++) {
            int i = (int)(rng_next(&g) % (uint64_t)s.n);
            if (kind == 3) {
                s.r[i] *= 1.5;                  /* grown */
            } else if (kind == 4) {
                s.act[i] = !s.act[i];           /* woken or put to sleep */
            } else if (m % 2 && kind != 5) {
                int j = (int)(rng_next(&g) % (uint64_t)s.n);
                for (int k = 0; k < 3; k++)     /* onto another */
                    centre(&s, i)[k] = centre(&s, j)[k] + uni(&g, -0.05, 0.05);
            } else {
                for (int k = 0; k < 3; k++)
                    centre(&s, i)[k] += uni(&g, -0.02, 0.02);
            }
        }
    }
    sc_bp_destroy(bp);
    scene_free(&s);
}

static void test_sap_stays_exact_when_the_body_count_changes(void **state)
{
    (void)state;
    static const int counts[] = { 600, 610, 700, 590, 2, 0, 5, 1200, 1, 1200, 300, 1199 };
    rng g = { 9 };
    scene s = scene_new(1200, 0);
    fill_pile(&s, &g);
    sc_broadphase *bp = sc_bp_create();
    sc_pair *p = NULL;
    int cap = 0;
    for (size_t t = 0; t < sizeof counts / sizeof *counts; t++) {
        scene view = s;
        view.n = counts[t];
        for (int i = 0; i < s.n; i++)
            for (int k = 0; k < 3; k++)
                s.c[3 * i + k] += uni(&g, -0.005, 0.005);
        sc_pair *want;
        int nwant = reference(&view, &want);
        int method = t == 6 ? SC_BROADPHASE_SPHERES : SC_BROADPHASE_SAP;
        int np = sc_bp_find_pairs(bp, method, view.c, view.r, NULL, view.n, &p, &cap);
        assert_same_pairs(want, nwant, p, np, "changing count");
        free(want);
    }
    free(p);
    sc_bp_destroy(bp);
    scene_free(&s);
}

/* A 5000-body pile over a few frames, the size the benchmark targets. */
static void test_sap_matches_reference_on_a_5000_body_pile(void **state)
{
    (void)state;
    rng g = { 10 };
    scene s = scene_new(5000, 0);
    fill_pile(&s, &g);
    sc_broadphase *bp = sc_bp_create();
    sc_pair *p = NULL;
    int cap = 0;
    for (int frame = 0; frame < 3; frame++) {
        sc_pair *want;
        int nwant = reference(&s, &want);
        int np = sc_bp_find_pairs(bp, SC_BROADPHASE_SAP, s.c, s.r, NULL, s.n, &p, &cap);
        assert_same_pairs(want, nwant, p, np, "5000 pile");
        assert_true(np > 10000);
        free(want);
        for (int i = 0; i < 3 * s.n; i++)
            s.c[i] += uni(&g, -0.002, 0.002);
    }
    free(p);
    sc_bp_destroy(bp);
    scene_free(&s);
}

/* Once the output array is big enough it is reused, never reallocated. */
static void test_pairs_array_grows_from_null_then_is_reused(void **state)
{
    (void)state;
    rng g = { 11 };
    scene s = scene_new(800, 0);
    fill_pile(&s, &g);
    for (int m = 0; m < NMETHODS; m++) {
        sc_broadphase *bp = sc_bp_create();
        sc_pair *p = NULL;
        int cap = 0;
        int np = sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, s.n, &p, &cap);
        assert_true(np > 100);
        assert_non_null(p);
        sc_pair *first = p;
        int first_cap = cap;
        for (int rep = 0; rep < 5; rep++) {
            int again = sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, s.n, &p, &cap);
            assert_int_equal(again, np);
        }
        assert_ptr_equal(p, first);
        assert_int_equal(cap, first_cap);
        free(p);
        sc_bp_destroy(bp);
    }
    scene_free(&s);
}

/* NaN or infinite centres, bad radii, out-of-range values, bad arguments:
 * SC_EINVAL and the output untouched. */
static void test_invalid_input_returns_einval(void **state)
{
    (void)state;
    rng g = { 12 };
    scene s = scene_new(300, 0);
    sc_pair *p = NULL;
    int cap = 0;
    for (int m = 0; m < NMETHODS; m++) {
        sc_broadphase *bp = sc_bp_create();
        const double bad_c[] = { NAN, INFINITY, -INFINITY, 1.1e150 };
        const double bad_r[] = { NAN, -1e-300, -1, INFINITY, 1.1e150 };
        for (size_t b = 0; b < sizeof bad_c / sizeof *bad_c; b++) {
            fill_pile(&s, &g);
            s.c[3 * 137 + b % 3] = bad_c[b];
            assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, s.n, &p, &cap),
                             SC_EINVAL);
        }
        for (size_t b = 0; b < sizeof bad_r / sizeof *bad_r; b++) {
            fill_pile(&s, &g);
            s.r[299] = bad_r[b];
            assert_int_equal(sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, s.n, &p, &cap),
                             SC_EINVAL);
        }
        assert_null(p);
        assert_int_equal(cap, 0);
        fill_pile(&s, &g);
        int mt = methods[m];
        assert_int_equal(sc_bp_find_pairs(bp, mt, s.c, s.r, NULL, -1, &p, &cap), SC_EINVAL);
        assert_int_equal(sc_bp_find_pairs(bp, mt, NULL, s.r, NULL, 3, &p, &cap), SC_EINVAL);
        assert_int_equal(sc_bp_find_pairs(bp, mt, s.c, NULL, NULL, 3, &p, &cap), SC_EINVAL);
        assert_int_equal(sc_bp_find_pairs(bp, mt, s.c, s.r, NULL, 3, NULL, &cap), SC_EINVAL);
        assert_int_equal(sc_bp_find_pairs(bp, mt, s.c, s.r, NULL, 3, &p, NULL), SC_EINVAL);
        assert_int_equal(sc_bp_find_pairs(NULL, mt, s.c, s.r, NULL, 3, &p, &cap), SC_EINVAL);
        cap = 5;                                        /* capacity without an array */
        assert_int_equal(sc_bp_find_pairs(bp, mt, s.c, s.r, NULL, 3, &p, &cap), SC_EINVAL);
        cap = 0;
        /* the largest accepted values still work */
        s.c[0] = -1e150;
        s.r[1] = 1e150;
        assert_true(sc_bp_find_pairs(bp, methods[m], s.c, s.r, NULL, s.n, &p, &cap) >= s.n - 1);
        free(p);
        p = NULL;
        cap = 0;
        sc_bp_destroy(bp);
    }
    sc_broadphase *bp = sc_bp_create();
    assert_int_equal(sc_bp_find_pairs(bp, 42, s.c, s.r, NULL, 3, &p, &cap), SC_EINVAL);
    assert_int_equal(sc_bp_find_pairs(bp, -1, s.c, s.r, NULL, 3, &p, &cap), SC_EINVAL);
    sc_bp_destroy(bp);
    sc_bp_destroy(NULL);
    scene_free(&s);
}

/* A failed call (NaN) in the middle of a coherent run does not spoil the
 * kept order: the next good frame is exact. */
static void test_sap_recovers_after_an_invalid_frame(void **state)
{
    (void)state;
    rng g = { 13 };
    scene s = scene_new(900, 0);
    fill_pile(&s, &g);
    sc_broadphase *bp = sc_bp_create();
    sc_pair *p = NULL, *want;
    int cap = 0;
    assert_true(sc_bp_find_pairs(bp, SC_BROADPHASE_SAP, s.c, s.r, NULL, s.n, &p, &cap) > 0);
    double keep = s.c[3 * 400 + 1];
    s.c[3 * 400 + 1] = NAN;
    assert_int_equal(sc_bp_find_pairs(bp, SC_BROADPHASE_SAP, s.c, s.r, NULL, s.n, &p, &cap),
                     SC_EINVAL);
    s.c[3 * 400 + 1] = keep + 0.3;
    int nwant = reference(&s, &want);
    int np = sc_bp_find_pairs(bp, SC_BROADPHASE_SAP, s.c, s.r, NULL, s.n, &p, &cap);
    assert_same_pairs(want, nwant, p, np, "after NaN");
    free(want);
    free(p);
    sc_bp_destroy(bp);
    scene_free(&s);
}

/* ---- shared sweeps: the sweep's tasks handed to a runner ---- */

typedef struct task_runner {
    int threaded;             /* 0: every task here, last first; 1: odd
                                 tasks on a second thread at the same time */
    int calls, tasks, helped;
} task_runner;

typedef struct odd_tasks {
    sc_task_fn fn;
    void *arg;
    int count;
} odd_tasks;

static void *run_odd(void *p)
{
    odd_tasks *o = p;
    for (int i = 1; i < o->count; i += 2)
        o->fn(o->arg, i, NULL, 1);
    return NULL;
}

static void run_tasks(void *ctx, sc_task_fn fn, void *arg, int count, sc_arena *a)
{
    task_runner *r = ctx;
    r->calls++;
    r->tasks += count;
    if (!r->threaded) {
        for (int i = count - 1; i >= 0; i--)
            fn(arg, i, a, 0);
        return;
    }
    odd_tasks o = { fn, arg, count };
    pthread_t t;
    assert_int_equal(pthread_create(&t, NULL, run_odd, &o), 0);
    for (int i = 0; i < count; i += 2)
        fn(arg, i, a, 0);
    assert_int_equal(pthread_join(t, NULL), 0);
    r->helped += count / 2;
}

/* The sweeps cut into tasks (a runner, 256 bodies or more) find exactly
 * the reference's pairs whatever order the tasks run in and whichever
 * thread runs them: on the pile, on mixed radii (several levels, so cross
 * tasks too) with sleeping bodies, and over frames of moving bodies (the
 * kept order, the few-moved path between). Were a task's rows or slots
 * cut so that some were swept twice or not at all, pairs would be
 * missing or doubled. */
static void test_shared_sweeps_match_reference_in_any_order_and_thread(void **state)
{
    (void)state;
    rng g = { 21 };
    for (int threaded = 0; threaded < 2; threaded++)
        for (int kind = 0; kind < 2; kind++) {
            scene s = scene_new(kind ? 1500 : 3000, kind);
            if (kind) {
                static const double lo[3] = { -1, -1, -0.5 }, hi[3] = { 1, 1, 0.5 };
                fill_uniform(&s, &g, lo, hi, 0, 0);
                for (int i = 0; i < s.n; i++) {
                    s.r[i] = pow(10, uni(&g, -2.5, -0.8));
                    s.act[i] = rng_next(&g) % 4 != 0;
                }
            } else {
                fill_pile(&s, &g);
            }
            task_runner tr = { .threaded = threaded };
            sc_task_runner runner = { run_tasks, &tr };
            sc_broadphase *bp = sc_bp_create();
            sc_pair *p = NULL;
            int cap = 0;
            for (int frame = 0; frame < 4; frame++) {
                sc_pair *want;
                int nwant = reference(&s, &want);
                int np = sc_bp_find_pairs_on(bp, &runner, SC_BROADPHASE_SAP, s.c, s.r, s.act,
                                             s.n, &p, &cap);
                assert_same_pairs(want, nwant, p, np, kind ? "shared, mixed" : "shared, pile");
                assert_true(nwant > 1000);
                free(want);
                /* frame 2 moves one body in 40 (few moved: no sweep) */
                for (int i = 0; i < s.n; i++)
                    if (frame != 1 || i % 40 == 0)
                        for (int k = 0; k < 3; k++)
                            s.c[3 * i + k] += uni(&g, -0.003, 0.003);
            }
            print_message("%s, %s: %d sweeps handed out, %d tasks\n", kind ? "mixed" : "pile",
                          threaded ? "two threads" : "reverse order", tr.calls, tr.tasks);
            assert_int_equal(tr.calls, 3);
            assert_true(tr.tasks >= 3 * 8 * (kind ? 2 : 1));
            free(p);
            sc_bp_destroy(bp);
            scene_free(&s);
        }
}

/* A kept list's candidates filtered in tasks (a runner and a long list):
 * the same pairs in the same order as the reference, over calls within
 * the skins, in reverse order and on two threads. */
static void test_skin_list_filtered_in_tasks_matches_reference(void **state)
{
    (void)state;
    for (int threaded = 0; threaded < 2; threaded++) {
        rng g = { 41 + (uint64_t)threaded };
        scene s = scene_new(3000, 1);
        fill_pile(&s, &g);
        double *skin = calloc((size_t)s.n, sizeof *skin);
        assert_non_null(skin);
        for (int i = 0; i < s.n; i++) {
            s.act[i] = i % 9 != 0;
            skin[i] = 0.02;
        }
        task_runner tr = { .threaded = threaded };
        sc_task_runner runner = { run_tasks, &tr };
        sc_broadphase *bp = sc_bp_create();
        assert_non_null(bp);
        sc_pair *p = NULL;
        int cap = 0;
        for (int call = 0; call < 6; call++) {
            sc_pair *want;
            int nwant = reference(&s, &want);
            int np = sc_bp_find_pairs_skin(bp, &runner, SC_BROADPHASE_SAP, s.c, s.r, skin, s.act,
                                           s.n, &p, &cap);
            assert_same_pairs(want, nwant, p, np, "skin list in tasks");
            assert_true(nwant > 1000);
            free(want);
            for (int i = 0; i < s.n; i++)
                for (int k = 0; k < 3; k++)
                    s.c[3 * i + k] += uni(&g, -0.002, 0.002);
        }
        assert_true(sc_bp_list_reused(bp) >= 3);
        print_message("skin list, %s: %d batches handed out, %d tasks\n",
                      threaded ? "two threads" : "reverse order", tr.calls, tr.tasks);
        /* the list's sweep and at least three filters went out as tasks */
        assert_true(tr.calls >= 4);
        free(p);
        free(skin);
        sc_bp_destroy(bp);
        scene_free(&s);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_both_methods_match_reference_on_uniform_scenes),
        cmocka_unit_test(test_both_methods_match_reference_on_clustered_scenes),
        cmocka_unit_test(test_both_methods_match_reference_with_all_bodies_on_one_plane),
        cmocka_unit_test(test_both_methods_match_reference_with_many_identical_centres),
        cmocka_unit_test(test_touching_exactly_counts_as_overlap),
        cmocka_unit_test(test_both_methods_match_reference_on_pairs_at_the_rounding_edge),
        cmocka_unit_test(test_sap_keeps_pairs_whose_rounded_intervals_are_disjoint),
        cmocka_unit_test(test_touching_pairs_across_grid_cell_boundaries_are_found),
        cmocka_unit_test(test_both_methods_match_reference_with_huge_and_tiny_radii_mixed),
        cmocka_unit_test(test_inactive_pairs_are_excluded),
        cmocka_unit_test(test_zero_one_and_two_bodies),
        cmocka_unit_test(test_skin_list_matches_reference_over_moving_calls),
        cmocka_unit_test(test_skin_list_is_made_again_past_a_skin),
        cmocka_unit_test(test_pairs_within_a_superset_match_reference),
        cmocka_unit_test(test_skin_list_filtered_in_tasks_matches_reference),
        cmocka_unit_test(test_sap_stays_exact_over_frames_of_moving_bodies),
        cmocka_unit_test(test_sap_stays_exact_when_the_body_count_changes),
        cmocka_unit_test(test_sap_exact_when_few_bodies_moved),
        cmocka_unit_test(test_sap_matches_reference_on_a_5000_body_pile),
        cmocka_unit_test(test_pairs_array_grows_from_null_then_is_reused),
        cmocka_unit_test(test_invalid_input_returns_einval),
        cmocka_unit_test(test_sap_recovers_after_an_invalid_frame),
        cmocka_unit_test(test_shared_sweeps_match_reference_in_any_order_and_thread),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
