/* test_ccd.c - distances between convex shapes (lib/core/ccd.c) against
 * closed forms and a brute-force polytope distance, libccd's "closer than
 * d" test on inflated shapes, and the conservative-advancement time of
 * impact (lib/core/toi.c) against the sampling search. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "core.h"
#include "ca.h"
#include "vecmath.h"

#define TOL 0.9e-3    /* the frame's aim at the default 1 mm contact tolerance */

static uint64_t seed;

static double rnd(void)   /* splitmix64, [-1, 1) */
{
    uint64_t z = (seed += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return 2.0 * (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53 - 1.0;
}

static void rnd_dir(double u[3])
{
    do {
        v3_set(u, rnd(), rnd(), rnd());
    } while (v3_len(u) < 0.1 || v3_len(u) > 1);
    v3_normalize(u);
}

static sc_pose rnd_pose(double spread)
{
    sc_pose p;
    for (int i = 0; i < 4; i++)
        p.quat[i] = rnd();
    q_normalize(p.quat);
    v3_set(p.pos, spread * rnd(), spread * rnd(), spread * rnd());
    return p;
}

static sc_pose at(double x, double y, double z)
{
    sc_pose p = { { x, y, z }, { 1, 0, 0, 0 } };
    return p;
}

static sc_shape *rnd_hull(int n, double r)
{
    double p[3 * 64];
    for (int i = 0; i < n; i++) {
        double u[3];
        rnd_dir(u);
        v3_scale(&p[3 * i], u, r * (0.5 + 0.5 * fabs(rnd())));
    }
    return sc_shape_convex(p, n);
}

static double sep_dist(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                       const sc_pose *pb, sc_ccd_sep *s)
{
    assert_int_equal(sc_ccd_separation(a, pa, b, pb, 1, NULL, s), SC_OK);
    return s->dist;
}

/* ---- distances against closed forms ---- */

static void test_sphere_sphere_distance_is_centres_less_radii(void **state)
{
    (void)state;
    seed = 1;
    sc_shape *a = sc_shape_sphere(0.03), *b = sc_shape_sphere(0.05);
    for (int i = 0; i < 200; i++) {
        sc_pose pa = rnd_pose(0.1), pb = rnd_pose(0.1);
        sc_ccd_sep s;
        double expect = v3_dist(pa.pos, pb.pos) - 0.08;
        double d = sep_dist(a, &pa, b, &pb, &s);
        assert_true(fabs(d - expect) < 1e-12);
        assert_int_equal(s.overlap, expect <= 0);
        /* the direction: from a's centre towards b's */
        double u[3];
        v3_sub(u, pb.pos, pa.pos);
        v3_normalize(u);
        assert_true(v3_dot(u, s.n) > 1 - 1e-9);
    }
    sc_shape_release(a);
    sc_shape_release(b);
}

/* The distance from a sphere's centre to a box, in the box's frame: the
 * centre clamped to the box. */
static void test_sphere_box_distance_matches_closed_form(void **state)
{
    (void)state;
    seed = 2;
    const double h[3] = { 0.05, 0.03, 0.02 }, r = 0.01;
    sc_shape *box = sc_shape_box(h[0], h[1], h[2]), *ball = sc_shape_sphere(r);
    int faces = 0, edges = 0;
    for (int i = 0; i < 400; i++) {
        sc_pose pb = rnd_pose(0.2), pc = pb;
        double local[3], R[9];
        for (int k = 0; k < 3; k++)
            local[k] = h[k] * 2.5 * rnd();
        q_to_m3(R, pb.quat);
        m3_mulv(pc.pos, R, local);
        v3_add(pc.pos, pc.pos, pb.pos);
        double cl[3], out = 0;
        int outside = 0;
        for (int k = 0; k < 3; k++) {
            cl[k] = fmax(-h[k], fmin(h[k], local[k]));
            out += (local[k] - cl[k]) * (local[k] - cl[k]);
            outside += local[k] != cl[k];
        }
        if (outside == 0)
            continue;       /* centre inside: no closed form here */
        faces += outside == 1;
        edges += outside >= 2;
        double expect = sqrt(out) - r;
        sc_ccd_sep s;
        assert_true(fabs(sep_dist(box, &pb, ball, &pc, &s) - expect) < 1e-10);
        assert_true(fabs(sep_dist(ball, &pc, box, &pb, &s) - expect) < 1e-10);
    }
    assert_true(faces > 20 && edges > 20);
    sc_shape_release(box);
    sc_shape_release(ball);
}

/* Box b above box a, turned about z, its footprint over a's top face: the
 * distance is the gap and the direction is up. */
static void test_box_box_face_to_face_distance_is_the_gap(void **state)
{
    (void)state;
    seed = 3;
    sc_shape *a = sc_shape_box(0.2, 0.2, 0.05), *b = sc_shape_box(0.03, 0.02, 0.01);
    for (int i = 0; i < 200; i++) {
        double gap = 1e-4 + 0.05 * fabs(rnd());
        sc_pose pa = at(0, 0, 0), pb = at(0.1 * rnd(), 0.1 * rnd(), 0.05 + 0.01 + gap);
        double z[3] = { 0, 0, 1 };
        q_from_axis_angle(pb.quat, z, 3.1 * rnd());
        sc_ccd_sep s;
        assert_true(fabs(sep_dist(a, &pa, b, &pb, &s) - gap) < 1e-9);
        assert_true(s.n[2] > 1 - 1e-9);
        assert_false(s.overlap);
        /* and sunk into it (less than its own half height): overlapping,
         * the depth along z */
        double sink = fmin(gap, 0.008);
        pb.pos[2] -= gap + sink;
        sep_dist(a, &pa, b, &pb, &s);
        assert_true(s.overlap);
        assert_true(fabs(s.dist + sink) < 1e-12);
        assert_true(s.n[2] > 1 - 1e-12);
    }
    sc_shape_release(a);
    sc_shape_release(b);
}

/* A hull against a plane: the height of its lowest vertex, for the plane
 * as either shape of the pair. */
static void test_hull_plane_distance_is_the_lowest_vertex(void **state)
{
    (void)state;
    seed = 4;
    sc_shape *hull = rnd_hull(30, 0.05);
    assert_non_null(hull);
    double nrm[3] = { 0.2, -0.1, 1 };
    v3_normalize(nrm);
    sc_shape *plane = sc_shape_plane(nrm[0], nrm[1], nrm[2], 0.02);
    sc_pose o = at(0, 0, 0);
    const double *xyz;
    int nv;
    assert_int_equal(sc_shape_mesh_data(hull, &xyz, &nv, NULL, NULL), SC_OK);
    for (int i = 0; i < 100; i++) {
        sc_pose p = rnd_pose(0.1);
        double R[9], low = INFINITY;
        q_to_m3(R, p.quat);
        for (int v = 0; v < nv; v++) {
            double w[3];
            m3_mulv(w, R, &xyz[3 * v]);
            v3_add(w, w, p.pos);
            low = fmin(low, v3_dot(nrm, w) - 0.02);
        }
        sc_ccd_sep s;
        assert_true(fabs(sep_dist(plane, &o, hull, &p, &s) - low) < 1e-12);
        assert_true(v3_dot(s.n, nrm) > 1 - 1e-12);     /* plane (a) to hull */
        assert_int_equal(s.overlap, low <= 0);
        assert_true(fabs(sep_dist(hull, &p, plane, &o, &s) - low) < 1e-12);
        assert_true(v3_dot(s.n, nrm) < -1 + 1e-12);    /* hull (a) to plane */
    }
    sc_shape_release(hull);
    sc_shape_release(plane);
}

/* ---- against a brute-force polytope distance ---- */

/* The point of triangle abc nearest p (Ericson, Real-Time Collision
 * Detection 5.1.5). */
static void closest_on_tri(const double p[3], const double *a, const double *b,
                           const double *c, double out[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    v3_sub(ab, b, a);
    v3_sub(ac, c, a);
    v3_sub(ap, p, a);
    double d1 = v3_dot(ab, ap), d2 = v3_dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        v3_copy(out, a);
        return;
    }
    v3_sub(bp, p, b);
    double d3 = v3_dot(ab, bp), d4 = v3_dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        v3_copy(out, b);
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        v3_madd(out, a, ab, d1 / (d1 - d3));
        return;
    }
    v3_sub(cp, p, c);
    double d5 = v3_dot(ab, cp), d6 = v3_dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        v3_copy(out, c);
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        v3_madd(out, a, ac, d2 / (d2 - d6));
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double bc[3];
        v3_sub(bc, c, b);
        v3_madd(out, b, bc, (d4 - d3) / ((d4 - d3) + (d5 - d6)));
        return;
    }
    double den = 1 / (va + vb + vc);
    for (int k = 0; k < 3; k++)
        out[k] = a[k] + ab[k] * vb * den + ac[k] * vc * den;
}

static double seg_seg(const double *p1, const double *q1, const double *p2, const double *q2)
{
    double d1[3], d2[3], r[3];
    v3_sub(d1, q1, p1);
    v3_sub(d2, q2, p2);
    v3_sub(r, p1, p2);
    double a = v3_dot(d1, d1), e = v3_dot(d2, d2), f = v3_dot(d2, r);
    double c = v3_dot(d1, r), b = v3_dot(d1, d2), den = a * e - b * b;
    double s = den > 1e-300 ? fmin(fmax((b * f - c * e) / den, 0), 1) : 0;
    double t = (b * s + f) / e;
    if (t < 0) {
        t = 0;
        s = fmin(fmax(-c / a, 0), 1);
    } else if (t > 1) {
        t = 1;
        s = fmin(fmax((b - c) / a, 0), 1);
    }
    double x[3], y[3];
    v3_madd(x, p1, d1, s);
    v3_madd(y, p2, d2, t);
    return v3_dist(x, y);
}

/* The distance between two disjoint convex polytopes is between a vertex
 * and a face or between two edges: the smallest over all of them (every
 * vertex against every triangle, every edge against every edge). */
static double brute_dist(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                         const sc_pose *pb)
{
    const sc_shape *s[2] = { a, b };
    const sc_pose *p[2] = { pa, pb };
    double v[2][64][3];
    for (int m = 0; m < 2; m++) {
        double R[9];
        q_to_m3(R, p[m]->quat);
        for (int i = 0; i < s[m]->nverts; i++) {
            m3_mulv(v[m][i], R, &s[m]->xyz[3 * i]);
            v3_add(v[m][i], v[m][i], p[m]->pos);
        }
    }
    double best = INFINITY;
    for (int m = 0; m < 2; m++) {
        const sc_shape *f = s[m], *o = s[1 - m];
        for (int t = 0; t < f->ntris; t++) {
            const int *ft = &f->tri[3 * t];
            for (int i = 0; i < o->nverts; i++) {
                double q[3];
                closest_on_tri(v[1 - m][i], v[m][ft[0]], v[m][ft[1]], v[m][ft[2]], q);
                best = fmin(best, v3_dist(q, v[1 - m][i]));
            }
            for (int e = 0; e < 3; e++)
                for (int u = 0; u < o->ntris; u++)
                    for (int g = 0; g < 3; g++)
                        best = fmin(best, seg_seg(v[m][ft[e]], v[m][ft[(e + 1) % 3]],
                                                  v[1 - m][o->tri[3 * u + g]],
                                                  v[1 - m][o->tri[3 * u + (g + 1) % 3]]));
        }
    }
    return best;
}

static void test_hull_hull_distance_matches_brute_force(void **state)
{
    (void)state;
    seed = 5;
    sc_shape *a = rnd_hull(12, 0.05), *b = rnd_hull(10, 0.04);
    assert_true(a->nverts <= 64 && b->nverts <= 64);
    int checked = 0;
    for (int i = 0; i < 60; i++) {
        sc_pose pa = rnd_pose(0), pb = rnd_pose(0);
        double u[3];
        rnd_dir(u);
        v3_scale(pb.pos, u, 0.1);
        sc_ccd_sep s;
        if (sep_dist(a, &pa, b, &pb, &s) <= 0)
            continue;
        /* a few mm apart, along the closest direction */
        v3_madd(pb.pos, pb.pos, s.n, 2e-3 + 8e-3 * fabs(rnd()) - s.dist);
        double d = sep_dist(a, &pa, b, &pb, &s);
        assert_true(fabs(d - brute_dist(a, &pa, b, &pb)) < 1e-12);
        checked++;
        /* any other direction's gap is a lower bound, this one's is it */
        for (int k = 0; k < 20; k++) {
            double n[3];
            rnd_dir(n);
            assert_true(sc_ccd_gap(a, &pa, b, &pb, n) <= d + 1e-12);
        }
        assert_true(fabs(sc_ccd_gap(a, &pa, b, &pb, s.n) - d) < 1e-9);
    }
    assert_true(checked > 30);
    sc_shape_release(a);
    sc_shape_release(b);
}

/* ---- libccd on inflated shapes ---- */

/* Inflating both shapes by d / 2 makes the intersection test "closer than
 * d": at the face-to-face gap g, d just above g says yes and just below no,
 * for MPR and GJK; the inflated penetration gives g back. */
static void test_inflation_tells_closer_than_d(void **state)
{
    (void)state;
    seed = 6;
    sc_shape *a = sc_shape_box(0.2, 0.2, 0.05), *b = sc_shape_box(0.03, 0.02, 0.01);
    sc_shape *ball = sc_shape_sphere(0.02), *hull = rnd_hull(20, 0.04);
    const sc_shape *others[3] = { b, ball, hull };
    for (int i = 0; i < 90; i++) {
        const sc_shape *o = others[i % 3];
        sc_pose pa = at(0, 0, 0), pb = rnd_pose(0);
        pb.pos[0] = 0.1 * rnd();
        pb.pos[1] = 0.1 * rnd();
        pb.pos[2] = 0.3;
        sc_ccd_sep s;
        sep_dist(a, &pa, o, &pb, &s);
        double g = 1e-3 + 9e-3 * fabs(rnd());
        pb.pos[2] -= s.dist - g;      /* straight down to the gap g */
        assert_true(fabs(sep_dist(a, &pa, o, &pb, &s) - g) < 1e-9);
        for (int m = SC_CCD_MPR; m <= SC_CCD_GJK; m++) {
            assert_int_equal(sc_ccd_intersect(m, a, &pa, o, &pb, g * 1.001), 1);
            assert_int_equal(sc_ccd_intersect(m, a, &pa, o, &pb, g * 0.999), 0);
            assert_int_equal(sc_ccd_intersect(m, o, &pb, a, &pa, g * 1.001), 1);
        }
        double d;
        assert_int_equal(sc_ccd_distance_inflated(SC_CCD_GJK, a, &pa, o, &pb, 0.02, &d), 1);
        assert_true(fabs(d - g) < 1e-5);
        assert_int_equal(sc_ccd_distance_inflated(SC_CCD_GJK, a, &pa, o, &pb, g * 0.99, &d), 0);
    }
    sc_shape_release(a);
    sc_shape_release(b);
    sc_shape_release(ball);
    sc_shape_release(hull);
}

/* libccd #25: cubes of side 2 stacked 1.9 apart. With libccd's first
 * direction (1, 0, 0) its GJK reported them apart; ours starts along the
 * centres' line. */
static void test_stacked_cubes_overlap_by_a_tenth(void **state)
{
    (void)state;
    sc_shape *c = sc_shape_box(1, 1, 1);
    sc_pose p0 = at(0, 0, 0), p1 = at(0, 0, 1.9);
    for (int m = SC_CCD_MPR; m <= SC_CCD_GJK; m++) {
        double depth = -1, n[3];
        assert_int_equal(sc_ccd_intersect(m, c, &p0, c, &p1, 0), 1);
        assert_int_equal(sc_ccd_penetration(m, c, &p0, c, &p1, 0, &depth, n), 1);
        assert_true(fabs(depth - 0.1) < 1e-6);
        assert_true(n[2] > 1 - 1e-6);
    }
    sc_ccd_sep s;
    sep_dist(c, &p0, c, &p1, &s);
    assert_true(s.overlap && fabs(s.dist + 0.1) < 1e-9);
    sc_shape_release(c);
}

static void test_bad_input_is_refused(void **state)
{
    (void)state;
    sc_shape *box = sc_shape_box(0.1, 0.1, 0.1), *plane = sc_shape_plane(0, 0, 1, 0);
    sc_shape *bolt = sc_shape_bolt();
    sc_pose p = at(0, 0, 0), q = at(1, 0, 0), bad = at(NAN, 0, 0), skew = at(0, 0, 0);
    skew.quat[0] = 2;
    sc_ccd_sep s;
    double d, n[3];
    assert_int_equal(sc_ccd_separation(box, &p, box, &bad, 1, NULL, &s), SC_EINVAL);
    assert_int_equal(sc_ccd_separation(box, &p, box, &skew, 1, NULL, &s), SC_EINVAL);
    assert_int_equal(sc_ccd_separation(box, &p, NULL, &q, 1, NULL, &s), SC_EINVAL);
    assert_int_equal(sc_ccd_separation(plane, &p, plane, &q, 1, NULL, &s), SC_ENOTSUP);
    assert_int_equal(sc_ccd_separation(bolt, &p, box, &q, 1, NULL, &s), SC_ENOTSUP);
    assert_int_equal(sc_ccd_intersect(SC_CCD_MPR, box, &p, bolt, &q, 0), SC_ENOTSUP);
    assert_int_equal(sc_ccd_intersect(SC_CCD_MPR, box, &p, box, &q, -1), SC_EINVAL);
    assert_int_equal(sc_ccd_penetration(SC_CCD_GJK, box, &p, box, &q, 0, NULL, n), SC_EINVAL);
    assert_int_equal(sc_ccd_distance_inflated(SC_CCD_GJK, box, &p, plane, &q, 0, &d),
                     SC_ENOTSUP);
    sc_np_ctx *np = sc_np_create();
    double t;
    assert_int_equal(sc_toi_ca_before_ctx(np, bolt, &p, &p, box, &q, &q, TOL, 1, &t),
                     SC_ENOTSUP);
    assert_int_equal(sc_toi_ca_before_ctx(np, box, &p, &p, box, &q, &q, 0, 1, &t), SC_EINVAL);
    /* a moving plane is not taken (planes are static) */
    assert_int_equal(sc_toi_ca_pair(plane, &p, &q, box, &q, &q), 0);
    assert_int_equal(sc_toi_ca_pair(plane, &p, &p, box, &q, &q), 1);
    assert_int_equal(sc_toi_ca_pair(box, &q, &q, bolt, &p, &p), 0);
    sc_np_destroy(np);
    sc_shape_release(box);
    sc_shape_release(plane);
    sc_shape_release(bolt);
}

/* sc_np_deepest_until() is the deepest of sc_np_collide()'s contacts, to
 * the bit, for a bolt, a nut and a UV sphere on a tilted plane in many
 * poses (a mesh on a plane takes its own path, without contacts), and for
 * a bolt on a nut (through the pieces); with a stop it says at least
 * whether the deepest is deeper than the stop. */
static void test_deepest_until_is_the_deepest_contact(void **state)
{
    (void)state;
    sc_shape *shapes[3] = { sc_shape_bolt(), sc_shape_nut(), sc_shape_uv_sphere(0.02, 16, 8) };
    sc_shape *plane = sc_shape_plane(0.1, 0.05, 1, 0.001);
    sc_np_ctx *np = sc_np_create();
    assert_non_null(np);
    uint64_t r = 0x0ddba11u;
    int deep = 0, apart = 0;
    for (int k = 0; k < 600; k++) {
        const sc_shape *m = shapes[k % 3];
        double u[7];
        for (int j = 0; j < 7; j++) {
            r = r * 6364136223846793005ull + 1442695040888963407ull;
            u[j] = (double)(r >> 11) / 9007199254740992.0;
        }
        sc_pose pm = { { 0.1 * u[0] - 0.05, 0.1 * u[1] - 0.05, 0.04 * u[2] - 0.01 },
                       { u[3] - 0.5, u[4] - 0.5, u[5] - 0.5, u[6] - 0.5 } };
        double ql = sqrt(pm.quat[0] * pm.quat[0] + pm.quat[1] * pm.quat[1] +
                         pm.quat[2] * pm.quat[2] + pm.quat[3] * pm.quat[3]);
        for (int j = 0; j < 4; j++)
            pm.quat[j] /= ql;
        sc_pose pp = { { 0, 0, 0 }, { 1, 0, 0, 0 } };
        sc_contact c[SC_MAX_PAIR_CONTACTS];
        for (int order = 0; order < 2; order++) {
            const sc_shape *a = order ? plane : m, *b = order ? m : plane;
            const sc_pose *pa = order ? &pp : &pm, *pb = order ? &pm : &pp;
            int n = sc_np_collide(np, a, pa, b, pb, c, SC_MAX_PAIR_CONTACTS);
            assert_true(n >= 0);
            double want = -1, got, some;
            for (int i = 0; i < n; i++)
                want = fmax(want, c[i].depth);
            assert_int_equal(sc_np_deepest_until(np, a, pa, b, pb, INFINITY, &got), SC_OK);
            assert_true(got == want);
            assert_int_equal(sc_np_deepest_until(np, a, pa, b, pb, 1e-3, &some), SC_OK);
            assert_true((some > 1e-3) == (want > 1e-3));
            assert_true(some <= want);
            deep += want > 1e-3;
            apart += want < 0;
        }
    }
    assert_true(deep > 50 && apart > 50);
    /* a pair through the pieces: the same value as the contacts' */
    sc_pose pb = { { 0, 0, 0 }, { 1, 0, 0, 0 } }, pn = { { 0.004, 0, 0.01 }, { 1, 0, 0, 0 } };
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    int n = sc_np_collide(np, shapes[0], &pb, shapes[1], &pn, c, SC_MAX_PAIR_CONTACTS);
    assert_true(n > 0);
    double want = -1, got;
    for (int i = 0; i < n; i++)
        want = fmax(want, c[i].depth);
    assert_int_equal(sc_np_deepest_until(np, shapes[0], &pb, shapes[1], &pn, INFINITY, &got),
                     SC_OK);
    assert_true(got == want);
    assert_int_equal(sc_np_deepest_until(np, shapes[0], &pb, NULL, &pn, INFINITY, &got),
                     SC_EINVAL);
    print_message("deepest: %d mesh-plane poses deeper than 1 mm, %d apart\n", deep, apart);
    sc_np_destroy(np);
    for (int i = 0; i < 3; i++)
        sc_shape_release(shapes[i]);
    sc_shape_release(plane);
}

/* ---- time of impact ---- */

static double np_depth(sc_np_ctx *np, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                       const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double t)
{
    sc_pose pa, pb;
    sc_pose_lerp(&pa, a0, a1, t);
    sc_pose_lerp(&pb, b0, b1, t);
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    int n = sc_np_collide(np, a, &pa, b, &pb, c, SC_MAX_PAIR_CONTACTS);
    assert_true(n >= 0);
    double d = -1;
    for (int i = 0; i < n; i++)
        d = fmax(d, c[i].depth);
    return d;
}

/* Random convex pairs (boxes, hulls, spheres, a UV sphere mesh, a plane),
 * turning and moving at each other: both searches find the same touch,
 * that is, the earlier of their times already touches and no time between
 * them is deeper than the tolerance; CA's touch is at most 3/4 of it deep
 * (half, unless a shallow landing moved on). Where only one search finds a touch, it is a graze shallower than
 * the tolerance (the sampling search skips some, CA those below half of
 * it), checked by a fine scan. */
static void test_ca_agrees_with_sampling_on_random_convex_pairs(void **state)
{
    (void)state;
    seed = 7;
    sc_np_ctx *np = sc_np_create();
    sc_shape *s[6] = { sc_shape_box(0.05, 0.03, 0.02), rnd_hull(20, 0.05), sc_shape_sphere(0.03),
                       sc_shape_uv_sphere(0.04, 12, 6), sc_shape_box(0.1, 0.1, 0.004),
                       sc_shape_plane(0, 0, 1, -0.1) };
    int both = 0, grazes = 0;
    for (int i = 0; i < 300; i++) {
        const sc_shape *a = s[i % 6], *b = s[(i / 6) % 5];
        sc_pose a0 = rnd_pose(0.01), a1 = a0, b0 = rnd_pose(0), b1;
        if (a->kind == SC_SHAPE_PLANE)
            a0 = a1 = at(0, 0, 0);
        else
            for (int k = 0; k < 3; k++)
                a1.pos[k] += 0.02 * rnd();
        double u[3], ax[3], dq[4];
        rnd_dir(u);
        if (a->kind == SC_SHAPE_PLANE)
            v3_set(u, 0.3 * rnd(), 0.3 * rnd(), 1);
        v3_normalize(u);
        v3_scale(b0.pos, u, 0.25);
        rnd_dir(ax);
        q_from_axis_angle(dq, ax, 0.6 * rnd());
        q_mul(b1.quat, dq, b0.quat);
        for (int k = 0; k < 3; k++)
            b1.pos[k] = 0.06 * rnd() + (a->kind == SC_SHAPE_PLANE ? 0 : a1.pos[k]);
        double ts = -1, tc = -1;
        int hs = sc_toi_sample_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &ts);
        int hc = sc_toi_ca_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &tc);
        assert_true(hs >= 0 && hc >= 0);
        if (hs == 1 && hc == 1) {
            both++;
            double lo = fmin(ts, tc), hi = fmax(ts, tc);
            assert_true(np_depth(np, a, &a0, &a1, b, &b0, &b1, lo) >= 0);
            for (int k = 0; k <= 10; k++)
                assert_true(np_depth(np, a, &a0, &a1, b, &b0, &b1, lo + (hi - lo) * k / 10) <=
                            TOL);
            double dc = np_depth(np, a, &a0, &a1, b, &b0, &b1, tc);
            assert_true(dc >= 0 && dc <= 0.75 * TOL + 1e-9);
        } else if (hs != hc) {
            grazes++;
            double deepest = -1;
            for (int k = 0; k <= 4000; k++)
                deepest = fmax(deepest, np_depth(np, a, &a0, &a1, b, &b0, &b1, k / 4000.0));
            assert_true(deepest < TOL);
        }
    }
    assert_true(both > 100);
    assert_true(grazes <= 3);
    for (int i = 0; i < 6; i++)
        sc_shape_release(s[i]);
    sc_np_destroy(np);
}

/* A plate 1 mm thick crossing a box at 10 m per step, turning: each
 * sampling step moves it 40 mm, more than the plate's thickness, yet its
 * 2 cm sides make the overlap 21 mm long, so the sampling search
 * (256 samples) catches it; so must CA, at the analytic time. */
static void test_ca_catches_a_thin_fast_plate(void **state)
{
    (void)state;
    sc_np_ctx *np = sc_np_create();
    sc_shape *box = sc_shape_box(0.01, 0.05, 0.05), *plate = sc_shape_box(0.0005, 0.04, 0.04);
    sc_pose o = at(0, 0, 0), p0 = at(-5, 0.01, 0), p1 = at(5, 0.01, 0);
    double ts = -1, tc = -1;
    assert_int_equal(sc_toi_sample_before_ctx(np, box, &o, &o, plate, &p0, &p1, TOL, 1, &ts), 1);
    assert_int_equal(sc_toi_ca_before_ctx(np, box, &o, &o, plate, &p0, &p1, TOL, 1, &tc), 1);
    /* touches when its face reaches x = -0.01: t = (5 - 0.0105) / 10 */
    double touch = (5 - 0.0105) / 10;
    assert_true(tc >= touch && tc <= touch + 0.75 * TOL / 10 + 1e-12);
    assert_true(ts >= touch && ts <= touch + TOL / 10 + 1e-12);
    /* turning a quarter turn about y on the way: still caught, by both */
    double y[3] = { 0, 1, 0 };
    q_from_axis_angle(p1.quat, y, 1.5);
    assert_int_equal(sc_toi_sample_before_ctx(np, box, &o, &o, plate, &p0, &p1, TOL, 1, &ts), 1);
    assert_int_equal(sc_toi_ca_before_ctx(np, box, &o, &o, plate, &p0, &p1, TOL, 1, &tc), 1);
    double dc = np_depth(np, box, &o, &o, plate, &p0, &p1, tc);
    assert_true(dc >= 0 && dc <= 0.75 * TOL + 1e-9);
    assert_true(fabs(tc - ts) * 10 < 0.02);      /* the same crossing */
    sc_shape_release(box);
    sc_shape_release(plate);
    sc_np_destroy(np);
}

/* A sphere sliding onto a UV sphere mesh: the rotation bound of the mesh
 * is loose against the slow approach, so CA's step lands 0.43 um deep,
 * where ODE's sphere-convex collider sees nothing (it reads depths short,
 * by up to 4e-7 m in other poses) and the frame would find no contact at
 * the back-up. A
 * landing shallower than an eighth of the tolerance moves on (found in a
 * scan of 20000 random pairs, the only such case of two). */
static void test_ca_touch_is_one_the_narrow_phase_sees(void **state)
{
    (void)state;
    sc_np_ctx *np = sc_np_create();
    sc_shape *a = sc_shape_sphere(0.03), *b = sc_shape_uv_sphere(0.04, 12, 6);
    sc_pose a0 = { { 0, 0, 0 }, { 0x1.bf9d0bd179e2bp-2, -0x1.94f9647fce955p-1,
                                  -0x1.7da14cb21d97dp-2, -0x1.af8e83de0a6ebp-3 } };
    sc_pose a1 = { { 0, 0, 0 }, { 0x1.8c204891e120dp-2, -0x1.a0a2c5c0acb3cp-1,
                                  -0x1.712e89c943d27p-2, -0x1.ee0ec5b70c1fcp-3 } };
    sc_pose b0 = { { -0x1.3bcaf28157a53p-3, 0x1.2edadc0c96892p-6, 0x1.e3d12a40fddcdp-7 },
                   { 0x1.ecfe78e175875p-2, 0x1.b69a6ef6b8579p-2, 0x1.06914a48121d9p-2,
                     -0x1.70db149e0abdfp-1 } };
    sc_pose b1 = { { -0x1.67d03341f0ed5p-5, 0x1.428366a90bbbbp-6, -0x1.9c8442c953aecp-7 },
                   { 0x1.e2105ecd83b53p-2, 0x1.ccaf9f9d00387p-2, 0x1.664a81e1defccp-3,
                     -0x1.7a1be6638bd7dp-1 } };
    double t = -1;
    assert_int_equal(sc_toi_ca_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &t), 1);
    double d = np_depth(np, a, &a0, &a1, b, &b0, &b1, t);
    assert_true(d > 0 && d <= TOL);
    sc_shape_release(a);
    sc_shape_release(b);
    sc_np_destroy(np);
}

/* A sphere 1 nm into a hull at the start, moving in: the narrow phase
 * (ODE's sphere-convex collider reads depths short, here by 2.4e-8 m, and
 * misses shallower overlaps) takes them as apart, and the frame asked
 * because it did; CA answers as the sampling search does, not with time 0
 * (a back-up to the substep's start). */
static void test_ca_start_is_judged_by_the_narrow_phase(void **state)
{
    (void)state;
    double p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = i & 1 ? 0.05 : -0.05;
        p[3 * i + 1] = i & 2 ? 0.05 : -0.05;
        p[3 * i + 2] = i & 4 ? 0.05 : -0.05;
    }
    sc_np_ctx *np = sc_np_create();
    sc_shape *cube = sc_shape_convex(p, 8), *ball = sc_shape_sphere(0.02);
    sc_pose o = at(0, 0, 0), b0 = at(0.01, 0, 0.07 - 1e-9), b1 = at(0.01, 0, 0.065);
    assert_true(np_depth(np, cube, &o, &o, ball, &b0, &b1, 0) < 0);
    sc_ccd_sep s;
    assert_true(sep_dist(cube, &o, ball, &b0, &s) < 0);
    double ts = -1, tc = -1;
    assert_int_equal(sc_toi_sample_before_ctx(np, cube, &o, &o, ball, &b0, &b1, TOL, 1, &ts), 1);
    assert_int_equal(sc_toi_ca_before_ctx(np, cube, &o, &o, ball, &b0, &b1, TOL, 1, &tc), 1);
    assert_true(tc > 0);
    assert_memory_equal(&tc, &ts, sizeof tc);
    sc_shape_release(cube);
    sc_shape_release(ball);
    sc_np_destroy(np);
}

/* The search before tmax gives the full search's bits when its answer is
 * earlier, else 0 or a time >= tmax (what a TOI unit relies on to keep the
 * minimum over pairs the same for any cut of the pairs into units). For
 * the touch and the deepening search. */
static void test_ca_before_tmax_keeps_the_full_answer(void **state)
{
    (void)state;
    seed = 8;
    sc_np_ctx *np = sc_np_create();
    sc_shape *a = rnd_hull(16, 0.05), *b = sc_shape_box(0.04, 0.03, 0.02);
    int hits = 0, pruned = 0;
    for (int i = 0; i < 60; i++) {
        int deepen = i & 1;
        sc_pose a0 = rnd_pose(0), a1 = a0, b0 = rnd_pose(0), b1;
        double u[3], ax[3], dq[4];
        rnd_dir(u);
        v3_scale(b0.pos, u, 0.15);
        if (deepen) {
            sc_ccd_sep s;
            sep_dist(a, &a0, b, &b0, &s);
            v3_madd(b0.pos, b0.pos, s.n, -s.dist - 0.2e-3);   /* 0.2 mm in */
            v3_copy(u, s.n);
        }
        rnd_dir(ax);
        q_from_axis_angle(dq, ax, 0.4 * rnd());
        q_mul(b1.quat, dq, b0.quat);
        v3_madd(b1.pos, b0.pos, u, deepen ? -0.006 : -0.2);
        double full = -1;
        int hf = deepen ? sc_toi_ca_deepen_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &full)
                        : sc_toi_ca_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &full);
        assert_true(hf >= 0);
        if (hf == 1)
            hits++;
        for (int k = 0; k < 8; k++) {
            double tmax = 0.125 * (k + 1), t = -1;
            int h = deepen ? sc_toi_ca_deepen_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, tmax, &t)
                           : sc_toi_ca_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, tmax, &t);
            if (hf == 1 && full < tmax) {
                assert_int_equal(h, 1);
                assert_memory_equal(&t, &full, sizeof t);
            } else {
                assert_true(h == 0 || t >= tmax);
                pruned += h == 0;
            }
        }
    }
    assert_true(hits > 40 && pruned > 40);
    sc_shape_release(a);
    sc_shape_release(b);
    sc_np_destroy(np);
}

/* Pairs touching 0.3, 1.3 or 2.5 mm deep that dig in 5 mm while turning:
 * both deepening searches agree on which pairs pass the limit (one deeper
 * than twice the limit (the aim) at the start is left alone; one past the
 * aim is held to the tolerance, aim / SC_TOI_AIM, and one past that a
 * hundredth of the tolerance deeper); CA's answer is within the limit by the
 * shapes' penetration depth (EPA, exact for polytopes) and no earlier than
 * where the sampling search's narrow phase reads 0.7 of it. */
static void test_ca_deepening_agrees_with_sampling(void **state)
{
    (void)state;
    seed = 9;
    sc_np_ctx *np = sc_np_create();
    sc_shape *s[4] = { sc_shape_box(0.05, 0.03, 0.02), rnd_hull(20, 0.05), sc_shape_sphere(0.03),
                       sc_shape_uv_sphere(0.04, 12, 6) };
    const double start[3] = { 0.3e-3, 1.3e-3, 2.5e-3 };
    int hits[3] = { 0, 0, 0 }, early = 0;
    for (int i = 0; i < 240; i++) {
        const sc_shape *a = s[i % 4], *b = s[(i / 4) % 4];
        sc_pose a0 = rnd_pose(0), a1 = a0, b0 = rnd_pose(0), b1;
        double u[3], ax[3], dq[4];
        rnd_dir(u);
        v3_scale(b0.pos, u, 0.15);
        sc_ccd_sep sp;
        sep_dist(a, &a0, b, &b0, &sp);
        v3_madd(b0.pos, b0.pos, sp.n, -sp.dist - start[i % 3]);
        rnd_dir(ax);
        q_from_axis_angle(dq, ax, 0.1 * rnd());
        q_mul(b1.quat, dq, b0.quat);
        v3_madd(b1.pos, b0.pos, sp.n, -5e-3);
        double ts = -1, tc = -1;
        int hs = sc_toi_sample_deepen_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &ts);
        int hc = sc_toi_ca_deepen_before_ctx(np, a, &a0, &a1, b, &b0, &b1, TOL, 1, &tc);
        assert_int_equal(hs, hc);
        if (hc != 1)
            continue;
        hits[i % 3]++;
        double d0 = np_depth(np, a, &a0, &a1, b, &b0, &b1, 0);
        double tol = TOL / SC_TOI_AIM;
        double limit = d0 > tol ? d0 + 0.01 * tol : d0 > TOL ? tol : TOL;
        sc_pose pa, pb;
        sc_pose_lerp(&pa, &a0, &a1, tc);
        sc_pose_lerp(&pb, &b0, &b1, tc);
        double depth = 0, n[3];
        sc_ccd_penetration(SC_CCD_GJK, a, &pa, b, &pb, 0, &depth, n);
        assert_true(depth <= limit + 1e-6);
        assert_true(np_depth(np, a, &a0, &a1, b, &b0, &b1, fmax(tc, ts)) >= 0.7 * limit);
        early += limit - depth > 0.1 * TOL;
    }
    /* a step is at least 5 % of the limit: most answers are that close to
     * it (measured: 90 % within 6 %, the worst 25 %) */
    assert_true(early * 10 < hits[0] + hits[1] + hits[2]);
    /* nearly all of the first two kinds pass the limit, few of the last
     * (2.5 mm along the closest direction is less deep for some corners) */
    assert_true(hits[0] > 70 && hits[1] > 70 && hits[2] < 20);
    for (int i = 0; i < 4; i++)
        sc_shape_release(s[i]);
    sc_np_destroy(np);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sphere_sphere_distance_is_centres_less_radii),
        cmocka_unit_test(test_sphere_box_distance_matches_closed_form),
        cmocka_unit_test(test_box_box_face_to_face_distance_is_the_gap),
        cmocka_unit_test(test_hull_plane_distance_is_the_lowest_vertex),
        cmocka_unit_test(test_hull_hull_distance_matches_brute_force),
        cmocka_unit_test(test_inflation_tells_closer_than_d),
        cmocka_unit_test(test_stacked_cubes_overlap_by_a_tenth),
        cmocka_unit_test(test_bad_input_is_refused),
        cmocka_unit_test(test_ca_agrees_with_sampling_on_random_convex_pairs),
        cmocka_unit_test(test_ca_catches_a_thin_fast_plate),
        cmocka_unit_test(test_ca_touch_is_one_the_narrow_phase_sees),
        cmocka_unit_test(test_ca_start_is_judged_by_the_narrow_phase),
        cmocka_unit_test(test_ca_before_tmax_keeps_the_full_answer),
        cmocka_unit_test(test_ca_deepening_agrees_with_sampling),
        cmocka_unit_test(test_deepest_until_is_the_deepest_contact),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
