/* test_narrowphase.c - contacts for every shape pair on hand-placed
 * configurations whose answer is known: normal, depth, where, how many. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <pthread.h>

#include "simcluster.h"
#include "core.h"

#define TOL 1e-9
static const double S2 = 0.70710678118654752;   /* sin 45 degrees */

static sc_pose at(double x, double y, double z)
{
    sc_pose p = { { x, y, z }, { 1, 0, 0, 0 } };
    return p;
}

/* Rotation by 90 degrees about y: the body's +x axis points down (-z). */
static sc_pose lying(double x, double y, double z)
{
    sc_pose p = { { x, y, z }, { S2, 0, S2, 0 } };
    return p;
}

static double max_depth(const sc_contact *c, int n)
{
    double d = -1;
    for (int i = 0; i < n; i++)
        d = fmax(d, c[i].depth);
    return d;
}

static void assert_normals(const sc_contact *c, int n, double nx, double ny, double nz, double tol)
{
    for (int i = 0; i < n; i++) {
        assert_true(fabs(c[i].normal[0] - nx) < tol);
        assert_true(fabs(c[i].normal[1] - ny) < tol);
        assert_true(fabs(c[i].normal[2] - nz) < tol);
    }
}

/* Lowest and highest z of a mesh shape in its own frame. */
static void z_range(const sc_shape *s, double *lo, double *hi)
{
    const double *xyz;
    int nv;
    assert_int_equal(sc_shape_mesh_data(s, &xyz, &nv, NULL, NULL), SC_OK);
    *lo = INFINITY;
    *hi = -INFINITY;
    for (int i = 0; i < nv; i++) {
        *lo = fmin(*lo, xyz[3 * i + 2]);
        *hi = fmax(*hi, xyz[3 * i + 2]);
    }
}

static void test_spheres_overlap_depth_and_normal_from_a_to_b(void **state)
{
    (void)state;
    sc_shape *s = sc_shape_sphere(0.1);
    sc_contact c[4];
    sc_pose a = at(0, 0, 0), b = at(0.15, 0, 0);
    assert_int_equal(sc_collide(s, &a, s, &b, c, 4), 1);
    assert_true(fabs(c[0].depth - 0.05) < TOL);
    assert_normals(c, 1, 1, 0, 0, TOL);
    /* swapped: the normal flips */
    assert_int_equal(sc_collide(s, &b, s, &a, c, 4), 1);
    assert_normals(c, 1, -1, 0, 0, TOL);
    /* apart */
    b = at(0.2001, 0, 0);
    assert_int_equal(sc_collide(s, &a, s, &b, c, 4), 0);
    sc_shape_release(s);
}

static void test_box_on_plane_gives_four_corner_contacts(void **state)
{
    (void)state;
    sc_shape *plane = sc_shape_plane(0, 0, 1, 0), *box = sc_shape_box(0.5, 0.3, 0.2);
    sc_contact c[4];
    sc_pose o = at(0, 0, 0), b = at(1, 2, 0.199);
    int n = sc_collide(plane, &o, box, &b, c, 4);
    assert_int_equal(n, 4);
    assert_normals(c, n, 0, 0, 1, TOL);
    for (int i = 0; i < n; i++) {
        assert_true(fabs(c[i].depth - 0.001) < 1e-9);
        assert_true(fabs(fabs(c[i].pos[0] - 1) - 0.5) < 1e-9);
        assert_true(fabs(fabs(c[i].pos[1] - 2) - 0.3) < 1e-9);
    }
    /* the plane's pose moves it: a plane body lifted by 1 m */
    sc_pose up = at(0, 0, 1);
    b.pos[2] = 1.2001;
    assert_int_equal(sc_collide(plane, &up, box, &b, c, 4), 0);
    b.pos[2] = 1.199;
    assert_int_equal(sc_collide(plane, &up, box, &b, c, 4), 4);
    sc_shape_release(plane);
    sc_shape_release(box);
}

static void test_max_limits_the_contacts_written(void **state)
{
    (void)state;
    sc_shape *plane = sc_shape_plane(0, 0, 1, 0), *box = sc_shape_box(0.5, 0.3, 0.2);
    sc_contact c[4];
    sc_pose o = at(0, 0, 0), b = at(0, 0, 0.19);
    memset(c, 0xff, sizeof c);
    assert_int_equal(sc_collide(plane, &o, box, &b, c, 2), 2);
    assert_int_equal(c[2].body_a, -1);    /* 0xff bytes untouched */
    assert_int_equal(sc_collide(plane, &o, box, &b, NULL, 0), 0);
    assert_int_equal(sc_collide(plane, &o, box, &b, c, -1), SC_EINVAL);
    sc_shape_release(plane);
    sc_shape_release(box);
}

static void test_bad_poses_are_rejected(void **state)
{
    (void)state;
    sc_shape *s = sc_shape_sphere(1);
    sc_contact c[4];
    sc_pose a = at(0, 0, 0), b = at(NAN, 0, 0);
    assert_int_equal(sc_collide(s, &a, s, &b, c, 4), SC_EINVAL);
    b = at(0, 0, 0);
    b.quat[0] = 2;                            /* not a unit quaternion */
    assert_int_equal(sc_collide(s, &a, s, &b, c, 4), SC_EINVAL);
    assert_int_equal(sc_collide(NULL, &a, s, &a, c, 4), SC_EINVAL);
    sc_shape_release(s);
}

static void test_bolt_lying_on_plane_touches_on_its_head(void **state)
{
    (void)state;
    sc_shape *plane = sc_shape_plane(0, 0, 1, 0), *bolt = sc_shape_bolt();
    double lo, hi;
    z_range(bolt, &lo, &hi);               /* head at lo .. lo + 0.0125 */
    /* lying: body z becomes world x; a head vertex (0.02 from the axis)
     * points down, the shaft (0.01) does not reach the floor */
    sc_pose p = lying(0, 0, 0.02 - 0.001);
    sc_pose o = at(0, 0, 0);
    sc_contact c[4];
    int n = sc_collide(plane, &o, bolt, &p, c, 4);
    assert_true(n >= 2);
    assert_true(fabs(max_depth(c, n) - 0.001) < 1e-6);
    assert_normals(c, n, 0, 0, 1, 1e-9);
    for (int i = 0; i < n; i++) {
        assert_true(c[i].pos[0] >= lo - 1e-9 && c[i].pos[0] <= lo + 0.0125 + 1e-9);
        assert_true(fabs(c[i].pos[1]) < 1e-6);   /* along the vertex edge */
    }
    /* raised by 2 mm it is free */
    p.pos[2] += 0.002;
    assert_int_equal(sc_collide(plane, &o, bolt, &p, c, 4), 0);
    sc_shape_release(plane);
    sc_shape_release(bolt);
}

static void test_bolt_standing_on_head_gets_a_spread_manifold(void **state)
{
    (void)state;
    sc_shape *plane = sc_shape_plane(0, 0, 1, 0), *bolt = sc_shape_bolt();
    double lo, hi;
    z_range(bolt, &lo, &hi);
    sc_pose o = at(0, 0, 0), p = at(0, 0, -lo - 0.0005);
    sc_contact c[4];
    int n = sc_collide(plane, &o, bolt, &p, c, 4);
    assert_int_equal(n, 4);
    assert_normals(c, n, 0, 0, 1, 1e-9);
    double xmin = 1, xmax = -1, ymin = 1, ymax = -1;
    for (int i = 0; i < n; i++) {
        assert_true(fabs(c[i].depth - 0.0005) < 1e-9);
        assert_true(hypot(c[i].pos[0], c[i].pos[1]) <= 0.02 + 1e-9);
        xmin = fmin(xmin, c[i].pos[0]); xmax = fmax(xmax, c[i].pos[0]);
        ymin = fmin(ymin, c[i].pos[1]); ymax = fmax(ymax, c[i].pos[1]);
    }
    /* well spread: the points span most of the hexagon (0.04 x 0.035) */
    assert_true(xmax - xmin > 0.025 && ymax - ymin > 0.02);
    sc_shape_release(plane);
    sc_shape_release(bolt);
}

static void test_bolt_passes_through_nut_hole_without_contact(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    double blo, bhi, nlo, nhi;
    z_range(bolt, &blo, &bhi);
    z_range(nut, &nlo, &nhi);
    sc_contact c[4];
    sc_pose b = at(0, 0, 0);
    /* nut threaded halfway up the shaft (0.5 mm radial clearance) */
    sc_pose n = at(0, 0, blo + 0.0125 + 0.02 - nlo);
    assert_int_equal(sc_collide(bolt, &b, nut, &n, c, 4), 0);
    /* moved sideways by 1 mm the hole wall (at -x) cuts 0.5 mm into the
     * shaft: the nut must go back towards -x */
    n.pos[0] = 0.001;
    int k = sc_collide(bolt, &b, nut, &n, c, 4);
    assert_true(k >= 1);
    assert_true(max_depth(c, k) > 0 && max_depth(c, k) < 0.002);
    for (int i = 0; i < k; i++)
        assert_true(c[i].normal[0] < -0.5);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

static void test_nut_resting_on_bolt_head_is_pushed_up_the_axis(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    double blo, bhi, nlo, nhi;
    z_range(bolt, &blo, &bhi);
    z_range(nut, &nlo, &nhi);
    sc_contact c[4];
    sc_pose b = at(0, 0, 0);
    sc_pose n = at(0, 0, blo + 0.0125 - 0.0005 - nlo);   /* 0.5 mm into the head */
    int k = sc_collide(bolt, &b, nut, &n, c, 4);
    assert_true(k >= 3);
    for (int i = 0; i < k; i++) {
        assert_true(c[i].normal[2] > 0.9);
        assert_true(c[i].depth <= 0.0005 + 1e-6);
        assert_true(fabs(c[i].pos[2] - (blo + 0.0125)) < 0.001);
    }
    assert_true(fabs(max_depth(c, k) - 0.0005) < 1e-4);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

/* Two lying bolts crossed like a plus sign, B's shaft resting across A's:
 * the two shafts' vertex lines cross 0.5 mm deep. */
static void test_crossed_bolts_touch_shaft_on_shaft(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt();
    double lo, hi;
    z_range(bolt, &lo, &hi);
    double x = 0.5 * (lo + 0.0125 + hi);     /* middle of A's shaft */
    sc_pose a = lying(0, 0, 0);               /* along +x, top vertex line at z = 0.01 */
    sc_pose b = { { x, 0, 0.02 - 0.0005 }, { S2, -S2, 0, 0 } };   /* along +y */
    sc_contact c[4];
    int k = sc_collide(bolt, &a, bolt, &b, c, 4);
    assert_true(k >= 1);
    assert_true(fabs(max_depth(c, k) - 0.0005) < 2e-4);
    for (int i = 0; i < k; i++) {
        assert_true(c[i].normal[2] > 0.7);
        assert_true(fabs(c[i].pos[0] - x) < 0.005 && fabs(c[i].pos[1]) < 0.005);
        assert_true(fabs(c[i].pos[2] - 0.01) < 0.001);
    }
    b.pos[2] += 0.001;                        /* lifted: 0.5 mm apart */
    assert_int_equal(sc_collide(bolt, &a, bolt, &b, c, 4), 0);
    sc_shape_release(bolt);
}

static void test_nuts_stacked_flat_touch_on_their_faces(void **state)
{
    (void)state;
    sc_shape *nut = sc_shape_nut();
    sc_contact c[4];
    sc_pose a = at(0, 0, 0), b = at(0, 0, 0.016 - 0.0002);
    int k = sc_collide(nut, &a, nut, &b, c, 4);
    assert_int_equal(k, 4);
    for (int i = 0; i < k; i++) {
        assert_true(c[i].normal[2] > 0.99);
        assert_true(fabs(c[i].depth - 0.0002) < 1e-6);
    }
    sc_shape_release(nut);
}

/* sc_np_apart_by(), the motion groups' exact check: more than margin
 * apart only where a face plane or the balls show it, never closer. */
static void test_apart_by_proves_gaps_and_never_more(void **state)
{
    (void)state;
    sc_shape *nut = sc_shape_nut(), *bolt = sc_shape_bolt(), *ball = sc_shape_sphere(0.1);
    sc_shape *floor = sc_shape_plane(0, 0, 1, 0);
    /* nuts stacked flat 3 mm apart: a face plane parts them by 3 mm */
    sc_pose a = at(0, 0, 0), b = at(0, 0, 0.016 + 0.003);
    assert_int_equal(sc_np_apart_by(nut, &a, nut, &b, 0.002), 1);
    assert_int_equal(sc_np_apart_by(nut, &a, nut, &b, 0.004), 0);
    b.pos[2] = 0.016 - 0.0002;               /* touching */
    assert_int_equal(sc_np_apart_by(nut, &a, nut, &b, 0), 0);
    /* balls: their bounding balls are the shapes, 50 mm apart */
    sc_pose p = at(0, 0, 0), q = at(0.25, 0, 0);
    assert_int_equal(sc_np_apart_by(ball, &p, ball, &q, 0.049), 1);
    assert_int_equal(sc_np_apart_by(ball, &p, ball, &q, 0.051), 0);
    /* a plane is never shown apart; shapes far apart always are */
    assert_int_equal(sc_np_apart_by(ball, &q, floor, &p, 0.001), 0);
    sc_pose far = at(1, 0, 0);
    assert_int_equal(sc_np_apart_by(bolt, &p, nut, &far, 0.01), 1);
    /* a bolt through a nut's hole: pieces interleaved, not shown apart */
    double blo, bhi, nlo, nhi;
    z_range(bolt, &blo, &bhi);
    z_range(nut, &nlo, &nhi);
    sc_pose n = at(0, 0, blo + 0.0125 + 0.02 - nlo);
    assert_int_equal(sc_np_apart_by(bolt, &p, nut, &n, 0.001), 0);
    sc_shape_release(nut);
    sc_shape_release(bolt);
    sc_shape_release(ball);
    sc_shape_release(floor);
}

static void test_meshes_against_box_and_sphere(void **state)
{
    (void)state;
    sc_shape *box = sc_shape_box(0.5, 0.5, 0.5), *sph = sc_shape_sphere(0.05);
    sc_shape *nut = sc_shape_nut(), *uv = sc_shape_uv_sphere(0.05, 16, 8);
    double nlo, nhi;
    z_range(nut, &nlo, &nhi);
    sc_contact c[4];
    /* nut flat on a box top (z = 0.5), 0.3 mm deep */
    sc_pose bx = at(0, 0, 0), n = at(0.1, 0, 0.5 - nlo - 0.0003);
    int k = sc_collide(box, &bx, nut, &n, c, 4);
    assert_true(k >= 3);
    assert_normals(c, k, 0, 0, 1, 1e-6);
    assert_true(fabs(max_depth(c, k) - 0.0003) < 1e-6);
    /* analytic sphere on the nut's top face, off the hole: 0.2 mm deep */
    sc_pose na = at(0, 0, 0), s = at(0.0155, 0, nhi + 0.05 - 0.0002);
    k = sc_collide(nut, &na, sph, &s, c, 4);
    assert_true(k >= 1);
    assert_true(fabs(max_depth(c, k) - 0.0002) < 1e-5);
    assert_true(c[0].normal[2] > 0.99);
    /* convex UV sphere on the box: one point straight below the centre
     * (a pole vertex), depth 1 mm */
    sc_pose u = at(0.2, 0.1, 0.5 + 0.05 - 0.001);
    k = sc_collide(box, &bx, uv, &u, c, 4);
    assert_true(k >= 1);
    assert_true(fabs(max_depth(c, k) - 0.001) < 1e-6);
    assert_true(fabs(c[0].pos[0] - 0.2) < 1e-6 && fabs(c[0].pos[1] - 0.1) < 1e-6);
    assert_normals(c, k, 0, 0, 1, 1e-6);
    /* convex mesh against a non-convex one: UV sphere on a lying bolt's shaft */
    sc_shape *bolt = sc_shape_bolt();
    double blo, bhi;
    z_range(bolt, &blo, &bhi);
    sc_pose bl = lying(0, 0, 0), us = at(bhi - 0.01, 0, 0.01 + 0.05 - 0.0005);
    k = sc_collide(bolt, &bl, uv, &us, c, 4);
    assert_true(k >= 1);
    assert_true(max_depth(c, k) > 0 && max_depth(c, k) < 0.001);
    for (int i = 0; i < k; i++)
        assert_true(c[i].normal[2] > 0.9);
    sc_shape_release(bolt);
    sc_shape_release(box);
    sc_shape_release(sph);
    sc_shape_release(nut);
    sc_shape_release(uv);
}

static void test_convex_hull_box_on_plane(void **state)
{
    (void)state;
    double pts[24];
    for (int i = 0; i < 8; i++) {
        pts[3 * i] = (i & 1) ? 0.1 : -0.1;
        pts[3 * i + 1] = (i & 2) ? 0.2 : -0.2;
        pts[3 * i + 2] = (i & 4) ? 0.05 : -0.05;
    }
    sc_shape *hull = sc_shape_convex(pts, 8), *plane = sc_shape_plane(0, 0, 1, 0);
    assert_non_null(hull);
    sc_contact c[4];
    sc_pose o = at(0, 0, 0), h = at(0, 0, 0.0498);
    int k = sc_collide(plane, &o, hull, &h, c, 4);
    assert_int_equal(k, 4);
    assert_normals(c, k, 0, 0, 1, 1e-9);
    for (int i = 0; i < k; i++)
        assert_true(fabs(c[i].depth - 0.0002) < 1e-9);
    /* hull on hull (two convex shapes, ODE's convex-convex) */
    sc_pose h2 = at(0.05, 0, 0.0998 - 0.0001);
    k = sc_collide(hull, &o, hull, &h2, c, 4);
    assert_true(k >= 1);
    assert_true(fabs(max_depth(c, k) - 0.0003) < 1e-6);
    for (int i = 0; i < k; i++)
        assert_true(c[i].normal[2] > 0.99);
    sc_shape_release(hull);
    sc_shape_release(plane);
}

/* Corner-at-origin 0.2 m cubes (a convex mesh, its hull, a box) face on
 * face, 1 mm deep: ODE's convex-convex and convex-box colliders give one
 * point; the pair must touch on the four corners of the overlap. */
static void test_convex_cubes_face_on_face_touch_on_the_overlap_corners(void **state)
{
    (void)state;
    static const int tri[36] = { 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                 3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5 };
    double xyz[24];
    for (int i = 0; i < 8; i++) {
        xyz[3 * i] = (i == 1 || i == 2 || i == 5 || i == 6) ? 0.2 : 0;
        xyz[3 * i + 1] = (i == 2 || i == 3 || i == 6 || i == 7) ? 0.2 : 0;
        xyz[3 * i + 2] = i >= 4 ? 0.2 : 0;
    }
    sc_shape *cube[3] = { sc_shape_mesh(xyz, 8, tri, 12), sc_shape_convex(xyz, 8),
                          sc_shape_box(0.1, 0.1, 0.1) };
    double off[3][3] = { { 0, 0, 0 }, { 0, 0, 0 }, { 0.1, 0.1, 0.1 } };  /* box: centred */
    sc_contact c[4];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            if (i == 2 && j == 2)
                continue;               /* box-box is ODE's own, tested above */
            /* upper cube shifted 50 mm in x: the overlap is x 0.05..0.2 */
            sc_pose a = at(off[i][0], off[i][1], off[i][2]);
            sc_pose b = at(0.05 + off[j][0], off[j][1], 0.2 - 0.001 + off[j][2]);
            int k = sc_collide(cube[i], &a, cube[j], &b, c, 4);
            assert_int_equal(k, 4);
            assert_normals(c, k, 0, 0, 1, 1e-9);
            int corners = 0;
            for (int m = 0; m < k; m++) {
                assert_true(fabs(c[m].depth - 0.001) < 1e-9);
                int cx = fabs(c[m].pos[0] - 0.05) < 1e-9 || fabs(c[m].pos[0] - 0.2) < 1e-9;
                int cy = fabs(c[m].pos[1]) < 1e-9 || fabs(c[m].pos[1] - 0.2) < 1e-9;
                corners += cx && cy;
            }
            assert_int_equal(corners, 4);
            /* upper cube tilted 3 degrees about y (about its corner), one
             * bottom edge 1 mm deep: two points, on that edge */
            double t = 3 * M_PI / 180;
            sc_pose tilt = { { 0, 0, 0.2 + 0.2 * sin(t) - 0.001 },
                             { cos(t / 2), 0, sin(t / 2), 0 } };
            double r[3];    /* the box's centre sits at R (0.1, 0.1, 0.1) */
            r[0] = 0.1 * cos(t) + 0.1 * sin(t);
            r[1] = 0.1;
            r[2] = -0.1 * sin(t) + 0.1 * cos(t);
            if (j == 2)
                for (int q = 0; q < 3; q++)
                    tilt.pos[q] += r[q];
            k = sc_collide(cube[i], &a, cube[j], &tilt, c, 4);
            assert_int_equal(k, 2);
            for (int m = 0; m < k; m++) {
                assert_true(c[m].normal[2] > 0.99);
                assert_true(fabs(c[m].depth - 0.001) < 1e-6);
                assert_true(fabs(c[m].pos[0] - 0.2 * cos(t)) < 1e-3);
            }
            assert_true(fabs(fabs(c[0].pos[1] - c[1].pos[1]) - 0.2) < 1e-6);
        }
    for (int i = 0; i < 3; i++)
        sc_shape_release(cube[i]);
}

static void test_contacts_are_bit_identical_on_repeat(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    sc_pose a = { { 0, 0, 0 }, { 0.9, 0.3, 0.2, 0.1 } }, b = { { 0.01, 0.005, 0.02 }, { 1, 0, 0, 0 } };
    double l = sqrt(0.81 + 0.09 + 0.04 + 0.01);
    for (int k = 0; k < 4; k++)
        a.quat[k] /= l;
    sc_contact c1[4], c2[4];
    memset(c1, 0, sizeof c1);
    memset(c2, 0, sizeof c2);
    int n1 = sc_collide(bolt, &a, nut, &b, c1, 4);
    int n2 = sc_collide(bolt, &a, nut, &b, c2, 4);
    assert_true(n1 > 0);
    assert_int_equal(n1, n2);
    assert_memory_equal(c1, c2, sizeof c1);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

/* Several threads colliding the same shared shapes at once must get the
 * same contacts as one thread (per-thread ODE data and geoms). */
#define MT_THREADS 4
#define MT_CASES 64

typedef struct mt_job {
    sc_shape *a, *b;
    sc_pose pa[MT_CASES], pb[MT_CASES];
    sc_contact c[MT_CASES][4];
    int n[MT_CASES];
} mt_job;

static void *mt_run(void *arg)
{
    mt_job *j = arg;
    for (int rep = 0; rep < 5; rep++)
        for (int i = 0; i < MT_CASES; i++)
            j->n[i] = sc_collide(j->a, &j->pa[i], j->b, &j->pb[i], j->c[i], 4);
    return NULL;
}

/* Two convex shapes meet by this library's MPR (libccd's, as ODE runs it,
 * with a two-wide support function): the same contact to the bit as ODE's
 * own dCollide() on the same geoms, over the bolt's and the nut's pieces
 * and a hull of an odd number of points, at random poses around contact. */
static void test_convex_pairs_match_ode_to_the_bit(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    double pts[7 * 3];
    srand(11);
    for (int i = 0; i < 21; i++)
        pts[i] = 0.01 * ((double)rand() / RAND_MAX - 0.5);
    sc_shape *odd = sc_shape_convex(pts, 7);
    assert_non_null(bolt);
    assert_non_null(nut);
    assert_non_null(odd);
    const sc_shape *s[] = { bolt->pieces[0], bolt->pieces[1], nut->pieces[0], nut->pieces[5],
                            odd };
    int ns = (int)(sizeof s / sizeof s[0]);
    sc_np_ctx *ctx = sc_np_create();
    assert_non_null(ctx);
    int touching = 0, apart = 0;
    for (int t = 0; t < 3000; t++) {
        const sc_shape *a = s[t % ns], *b = s[(t / ns) % ns];
        sc_pose pa = at(0, 0, 0), pb;
        double q[2][4];
        for (int j = 0; j < 2; j++) {
            double len = 0;
            for (int k = 0; k < 4; k++) {
                q[j][k] = (double)rand() / RAND_MAX - 0.5;
                len += q[j][k] * q[j][k];
            }
            for (int k = 0; k < 4; k++)
                q[j][k] /= sqrt(len);
        }
        memcpy(pa.quat, q[0], sizeof q[0]);
        double reach = a->bound_r + b->bound_r;
        for (int k = 0; k < 3; k++)
            pb.pos[k] = reach * 1.2 * ((double)rand() / RAND_MAX - 0.5);
        memcpy(pb.quat, q[1], sizeof q[1]);
        sc_contact ours, ode;
        memset(&ours, 0, sizeof ours);
        memset(&ode, 0, sizeof ode);
        int r0 = sc_np_convex_raw(ctx, a, &pa, b, &pb, 0, &ours);
        int r1 = sc_np_convex_raw(ctx, a, &pa, b, &pb, 1, &ode);
        assert_true(r0 >= 0 && r0 == r1);
        if (!r0) {
            apart++;
            continue;
        }
        touching++;
        assert_memory_equal(ours.pos, ode.pos, sizeof ours.pos);
        assert_memory_equal(ours.normal, ode.normal, sizeof ours.normal);
        assert_memory_equal(&ours.depth, &ode.depth, sizeof ours.depth);
    }
    printf("  %d touching, %d apart: the same bits\n", touching, apart);
    assert_true(touching > 300 && apart > 300);
    /* a shape that is not convex is refused */
    sc_pose p0 = at(0, 0, 0);
    sc_contact c;
    assert_int_equal(sc_np_convex_raw(ctx, bolt, &p0, nut, &p0, 0, &c), SC_EINVAL);
    sc_np_destroy(ctx);
    sc_shape_release(odd);
    sc_shape_release(nut);
    sc_shape_release(bolt);
}

/* The mesh-plane loops take the vertices two at a time (SSE2, from a copy
 * by pairs whose last pair is padded): with an odd count the last vertex
 * is seen, and no two contacts stand at one point. A cube with its
 * top face dented (9 vertices, not convex: a trimesh), the dent first and
 * a corner last, turned at random against a plane: the deepest contact is
 * the deepest vertex by brute force, the corner last among them included. */
static void test_mesh_on_plane_odd_vertex_count(void **state)
{
    (void)state;
    const double xyz[] = { 0, 0, 0.2,                                      /* the dent */
                           -0.5, -0.5, -0.5, 0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5, 0.5, -0.5,
                           -0.5, -0.5, 0.5,  0.5, -0.5, 0.5,  0.5, 0.5, 0.5,  -0.5, 0.5, 0.5 };
    const int tri[] = { 1, 3, 2, 1, 4, 3,                          /* bottom, outward -z */
                        1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6,        /* sides */
                        3, 4, 8, 3, 8, 7, 4, 1, 5, 4, 5, 8,
                        5, 6, 0, 6, 7, 0, 7, 8, 0, 8, 5, 0 };      /* the dented top */
    sc_shape *m = sc_shape_mesh(xyz, 9, tri, 14), *floor = sc_shape_plane(0, 0, 1, 0);
    assert_non_null(m);
    const double *v;
    int nv;
    assert_int_equal(sc_shape_mesh_data(m, &v, &nv, NULL, NULL), SC_OK);
    assert_int_equal(nv, 9);
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    int last_deepest = 0;
    srand(7);
    for (int t = 0; t < 400; t++) {
        double q[4], len = 0;
        for (int k = 0; k < 4; k++) {
            q[k] = (double)rand() / RAND_MAX - 0.5;
            len += q[k] * q[k];
        }
        len = sqrt(len);
        sc_pose pm = { { 0, 0, 0.3 + 0.4 * rand() / RAND_MAX }, { q[0] / len, q[1] / len,
                                                                   q[2] / len, q[3] / len } };
        double w = pm.quat[0], x = pm.quat[1], y = pm.quat[2], z = pm.quat[3];
        /* each vertex's world z: the third row of the rotation */
        double best = 0;
        int bi = -1;
        for (int i = 0; i < nv; i++) {
            const double *p = &v[3 * i];
            double wz = 2 * (x * z - w * y) * p[0] + 2 * (y * z + w * x) * p[1] +
                        (1 - 2 * (x * x + y * y)) * p[2] + pm.pos[2];
            if (-wz > best) {
                best = -wz;
                bi = i;
            }
        }
        sc_pose pp = at(0, 0, 0);
        int n = sc_collide(m, &pm, floor, &pp, c, SC_MAX_PAIR_CONTACTS);
        assert_true(n >= 0);
        if (bi < 0) {
            assert_int_equal(n, 0);
            continue;
        }
        assert_true(n > 0);
        assert_true(fabs(max_depth(c, n) - best) < 1e-9);
        /* no two contacts at one point (the padding repeats the last vertex) */
        for (int i = 0; i < n; i++)
            for (int j = 0; j < i; j++)
                assert_true(fabs(c[i].pos[0] - c[j].pos[0]) + fabs(c[i].pos[1] - c[j].pos[1]) +
                                fabs(c[i].pos[2] - c[j].pos[2]) > 1e-12);
        last_deepest += bi == nv - 1;
    }
    assert_true(last_deepest > 0);
    sc_shape_release(m);
    sc_shape_release(floor);
}

/* Mesh against plane (lib/core/narrowphase.c: mesh_plane, our own vertex test
 * instead of ODE's trimesh-plane collider): the deepest vertex is always a
 * contact, with its exact depth, the normal is the plane's (flipped with
 * the order), a mesh clear of the plane gets none, and a mesh with more
 * vertices inside than the buffer holds still gets a spread manifold. */
static void test_mesh_on_plane_every_vertex_counts(void **state)
{
    (void)state;
    /* a UV sphere of 2016 vertices with its north pole pushed in to half the
     * radius: non-convex, so a trimesh */
    sc_shape *u = sc_shape_uv_sphere(0.1, 64, 32);
    const double *xyz0;
    const int *tri0;
    int nv, nt;
    assert_int_equal(sc_shape_mesh_data(u, &xyz0, &nv, &tri0, &nt), SC_OK);
    double *xyz = malloc((size_t)nv * 3 * sizeof *xyz);
    assert_non_null(xyz);
    memcpy(xyz, xyz0, (size_t)nv * 3 * sizeof *xyz);
    int top = 0;
    for (int i = 1; i < nv; i++)
        if (xyz[3 * i + 2] > xyz[3 * top + 2])
            top = i;
    xyz[3 * top + 2] = 0.05;
    sc_shape *dent = sc_shape_mesh(xyz, nv, tri0, nt);
    free(xyz);
    assert_non_null(dent);
    sc_shape *floor = sc_shape_plane(0, 0, 1, 0);
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    /* centre on the plane: about 1000 vertices inside */
    sc_pose pm = at(0.3, -0.2, 0.0), pp = at(0, 0, 0);
    int n = sc_collide(dent, &pm, floor, &pp, c, SC_MAX_PAIR_CONTACTS);
    assert_int_equal(n, SC_MAX_PAIR_CONTACTS);
    double spread = 0;
    for (int i = 0; i < n; i++) {
        assert_true(c[i].pos[2] < 0 && fabs(c[i].depth + c[i].pos[2]) < TOL);
        assert_true(fabs(c[i].normal[2] + 1) < TOL);        /* from the mesh to the floor */
        for (int j = 0; j < i; j++)
            spread = fmax(spread, hypot(c[i].pos[0] - c[j].pos[0], c[i].pos[1] - c[j].pos[1]));
    }
    assert_true(fabs(max_depth(c, n) - 0.1) < TOL);        /* the south pole */
    assert_true(spread > 0.15);                             /* across the 0.2 m disc */
    n = sc_collide(floor, &pp, dent, &pm, c, SC_MAX_PAIR_CONTACTS);
    assert_int_equal(n, SC_MAX_PAIR_CONTACTS);
    for (int i = 0; i < n; i++)
        assert_true(fabs(c[i].normal[2] - 1) < TOL);
    /* just clear, and far */
    pm = at(0, 0, 0.1 + 1e-9);
    assert_int_equal(sc_collide(dent, &pm, floor, &pp, c, SC_MAX_PAIR_CONTACTS), 0);
    pm = at(0, 0, 5);
    assert_int_equal(sc_collide(dent, &pm, floor, &pp, c, SC_MAX_PAIR_CONTACTS), 0);
    /* a tilted nut against a tilted, shifted plane: the deepest contact is
     * the deepest vertex, by brute force */
    sc_shape *nut = sc_shape_nut(), *tilted = sc_shape_plane(0.1, 0.2, 1, 0.01);
    sc_pose pn = { { 0.01, 0.02, 0.005 }, { 0.9, 0.3, -0.2, 0.1 } };
    sc_pose pt = { { 0, 0, 0.002 }, { 0.99, 0.05, 0.1, 0 } };
    double qn = sqrt(0.81 + 0.09 + 0.04 + 0.01), qt = sqrt(0.9801 + 0.0025 + 0.01);
    for (int k = 0; k < 4; k++) {
        pn.quat[k] /= qn;
        pt.quat[k] /= qt;
    }
    n = sc_collide(nut, &pn, tilted, &pt, c, SC_MAX_PAIR_CONTACTS);
    assert_true(n >= 3);
    const double *nx;
    assert_int_equal(sc_shape_mesh_data(nut, &nx, &nv, &tri0, &nt), SC_OK);
    double w = pt.quat[0], x = pt.quat[1], y = pt.quat[2], z = pt.quat[3];
    double pl[3] = { 0.1, 0.2, 1 }, len = sqrt(1.05), nrm[3];
    for (int a = 0; a < 3; a++)
        pl[a] /= len;
    /* the plane's normal in the world: rotate by the plane's pose */
    const double Rt[9] = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                           2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                           2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) };
    for (int a = 0; a < 3; a++)
        nrm[a] = Rt[3 * a] * pl[0] + Rt[3 * a + 1] * pl[1] + Rt[3 * a + 2] * pl[2];
    double d = 0.01 / len + nrm[0] * pt.pos[0] + nrm[1] * pt.pos[1] + nrm[2] * pt.pos[2];
    w = pn.quat[0], x = pn.quat[1], y = pn.quat[2], z = pn.quat[3];
    const double Rn[9] = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                           2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                           2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) };
    double deepest = 0;
    for (int i = 0; i < nv; i++) {
        double v[3];
        for (int a = 0; a < 3; a++)
            v[a] = Rn[3 * a] * nx[3 * i] + Rn[3 * a + 1] * nx[3 * i + 1] + Rn[3 * a + 2] * nx[3 * i + 2] +
                   pn.pos[a];
        deepest = fmax(deepest, d - (nrm[0] * v[0] + nrm[1] * v[1] + nrm[2] * v[2]));
    }
    assert_true(deepest > 0.001);
    assert_true(fabs(max_depth(c, n) - deepest) < 1e-12);
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            assert_true(fabs(c[i].normal[a] + nrm[a]) < TOL);
    sc_shape_release(nut);
    sc_shape_release(tilted);
    sc_shape_release(dent);
    sc_shape_release(u);
    sc_shape_release(floor);
}

static void test_threads_collide_shared_shapes_concurrently(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    static mt_job ref, jobs[MT_THREADS];
    ref.a = bolt;
    ref.b = nut;
    for (int i = 0; i < MT_CASES; i++) {
        double ang = 0.1 * i;
        ref.pa[i] = (sc_pose){ { 0, 0, 0 }, { cos(ang), sin(ang), 0, 0 } };
        ref.pb[i] = (sc_pose){ { 0.002 * (i % 8), 0.001 * (i % 5), 0.03 - 0.001 * i }, { 1, 0, 0, 0 } };
    }
    mt_run(&ref);
    int hits = 0;
    for (int i = 0; i < MT_CASES; i++)
        hits += ref.n[i] > 0;
    assert_true(hits > 10);
    pthread_t th[MT_THREADS];
    for (int t = 0; t < MT_THREADS; t++) {
        jobs[t] = ref;
        memset(jobs[t].c, 0, sizeof jobs[t].c);
        assert_int_equal(pthread_create(&th[t], NULL, mt_run, &jobs[t]), 0);
    }
    for (int t = 0; t < MT_THREADS; t++) {
        assert_int_equal(pthread_join(th[t], NULL), 0);
        for (int i = 0; i < MT_CASES; i++) {
            assert_int_equal(jobs[t].n[i], ref.n[i]);
            if (ref.n[i] > 0)
                assert_memory_equal(jobs[t].c[i], ref.c[i], (size_t)ref.n[i] * sizeof(sc_contact));
        }
    }
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

/* A box pressed 2 mm into the nut's top face astride the cut between two
 * of its convex pieces (1.5 mm of it on one side): the cut is inside the
 * nut, so it is pushed up (+z), not out sideways through the cut, which is
 * the shallower way out of that piece. */
static void test_a_box_astride_a_nut_piece_cut_is_pushed_up(void **state)
{
    (void)state;
    sc_shape *nut = sc_shape_nut(), *box = sc_shape_box(0.002, 0.002, 0.002);
    double lo, hi;
    z_range(nut, &lo, &hi);
    sc_pose n = at(0, 0, 0);
    /* the cut at angle 0 is the plane y = 0, from the hole out to x = 20 mm */
    sc_pose b = at(0.015, 0.0005, hi);     /* its bottom 2 mm below the top */
    sc_contact c[4];
    int k = sc_collide(nut, &n, box, &b, c, 4);
    assert_true(k >= 3);
    assert_normals(c, k, 0, 0, 1, 1e-6);
    assert_true(fabs(max_depth(c, k) - 0.002) < 1e-6);
    sc_shape_release(nut);
    sc_shape_release(box);
}

/* A mesh cut into two convex halves collides as the whole mesh does: the
 * same deepest point, normal and manifold size for a box resting on it. */
static void test_mesh_pieces_collide_as_the_whole(void **state)
{
    (void)state;
    /* a 2 x 3 x 4 block as a triangle mesh (its hull's triangles), and
     * the same cut at z = 2 into two boxes of corners */
    double pts[48];
    for (int h = 0; h < 2; h++)
        for (int i = 0; i < 8; i++) {
            pts[24 * h + 3 * i] = i & 1 ? 2 : 0;
            pts[24 * h + 3 * i + 1] = i & 2 ? 3 : 0;
            pts[24 * h + 3 * i + 2] = 2 * h + (i & 4 ? 2 : 0);
        }
    double corners[24];
    memcpy(corners, pts, 12 * sizeof *corners);          /* z = 0 */
    memcpy(corners + 12, pts + 36, 12 * sizeof *corners); /* z = 4 */
    sc_shape *hull = sc_shape_convex(corners, 8);
    const double *xyz;
    const int *tri;
    int nv, nt;
    assert_non_null(hull);
    assert_int_equal(sc_shape_mesh_data(hull, &xyz, &nv, &tri, &nt), SC_OK);
    int counts[2] = { 8, 8 };
    sc_shape *whole = sc_shape_mesh(xyz, nv, tri, nt),
             *cut = sc_shape_mesh_pieces(xyz, nv, tri, nt, pts, counts, 2),
             *box = sc_shape_box(0.3, 0.3, 0.3);
    assert_true(whole && cut && box);
    sc_pose m = at(0, 0, 0), b = at(1, 1.5, 4 + 0.3 - 0.001);
    sc_contact cw[4], cc[4];
    int kw = sc_collide(whole, &m, box, &b, cw, 4), kc = sc_collide(cut, &m, box, &b, cc, 4);
    assert_int_equal(kw, 4);
    assert_int_equal(kc, kw);
    assert_normals(cc, kc, 0, 0, 1, 1e-9);
    assert_true(fabs(max_depth(cc, kc) - max_depth(cw, kw)) < 1e-12);
    sc_shape_release(hull);
    sc_shape_release(whole);
    sc_shape_release(cut);
    sc_shape_release(box);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spheres_overlap_depth_and_normal_from_a_to_b),
        cmocka_unit_test(test_box_on_plane_gives_four_corner_contacts),
        cmocka_unit_test(test_max_limits_the_contacts_written),
        cmocka_unit_test(test_bad_poses_are_rejected),
        cmocka_unit_test(test_bolt_lying_on_plane_touches_on_its_head),
        cmocka_unit_test(test_bolt_standing_on_head_gets_a_spread_manifold),
        cmocka_unit_test(test_bolt_passes_through_nut_hole_without_contact),
        cmocka_unit_test(test_apart_by_proves_gaps_and_never_more),
        cmocka_unit_test(test_a_box_astride_a_nut_piece_cut_is_pushed_up),
        cmocka_unit_test(test_mesh_pieces_collide_as_the_whole),
        cmocka_unit_test(test_nut_resting_on_bolt_head_is_pushed_up_the_axis),
        cmocka_unit_test(test_crossed_bolts_touch_shaft_on_shaft),
        cmocka_unit_test(test_nuts_stacked_flat_touch_on_their_faces),
        cmocka_unit_test(test_meshes_against_box_and_sphere),
        cmocka_unit_test(test_convex_hull_box_on_plane),
        cmocka_unit_test(test_convex_cubes_face_on_face_touch_on_the_overlap_corners),
        cmocka_unit_test(test_contacts_are_bit_identical_on_repeat),
        cmocka_unit_test(test_mesh_on_plane_every_vertex_counts),
        cmocka_unit_test(test_mesh_on_plane_odd_vertex_count),
        cmocka_unit_test(test_convex_pairs_match_ode_to_the_bit),
        cmocka_unit_test(test_threads_collide_shared_shapes_concurrently),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
