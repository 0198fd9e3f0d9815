/* test_shape.c - shapes: mass properties against analytic values, the
 * paper's builders, bad input. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "simcluster.h"

static const double cube_xyz[] = { 0, 0, 0, 2, 0, 0, 2, 3, 0, 0, 3, 0,
                                   0, 0, 4, 2, 0, 4, 2, 3, 4, 0, 3, 4 };
static const int cube_tri[] = { 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7 };

static void test_box_mesh_mass_props_match_analytic_box(void **state)
{
    (void)state;
    /* a 2 x 3 x 4 box with a corner at the origin */
    sc_shape *s = sc_shape_mesh(cube_xyz, 8, cube_tri, 12);
    assert_non_null(s);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
    assert_true(fabs(mp.volume - 24) < 1e-12);
    assert_true(fabs(mp.com[0] - 1) < 1e-12 && fabs(mp.com[1] - 1.5) < 1e-12 &&
                fabs(mp.com[2] - 2) < 1e-12);
    /* I = V/12 (b^2 + c^2) etc. about the centre, no products */
    assert_true(fabs(mp.inertia[0] - 24.0 / 12 * (9 + 16)) < 1e-9);
    assert_true(fabs(mp.inertia[4] - 24.0 / 12 * (4 + 16)) < 1e-9);
    assert_true(fabs(mp.inertia[8] - 24.0 / 12 * (4 + 9)) < 1e-9);
    for (int k = 0; k < 9; k++)
        if (k % 4)
            assert_true(fabs(mp.inertia[k]) < 1e-9);
    assert_int_equal(sc_shape_kind(s), SC_SHAPE_MESH);
    assert_int_equal(sc_shape_triangles(s), 12);
    sc_shape_release(s);
}

/* Validation ratios must not overflow or underflow at extreme scales (up
 * to where the inertia, ~L^5, is still a double); beyond, a clear code. */
static void test_mesh_checks_work_at_extreme_scales(void **state)
{
    (void)state;
    double huge[24];
    for (int i = 0; i < 24; i++)
        huge[i] = cube_xyz[i] * 1e100;
    assert_null(sc_shape_mesh(huge, 8, cube_tri, 12));
    assert_int_equal(sc_last_error(), SC_ETOOBIG);
    const double scales[] = { 1e-60, 1e-30, 1e30, 1e60 };
    for (int k = 0; k < 4; k++) {
        double xyz[24];
        for (int i = 0; i < 24; i++)
            xyz[i] = cube_xyz[i] * scales[k];
        sc_shape *s = sc_shape_mesh(xyz, 8, cube_tri, 12);
        assert_non_null(s);
        sc_mass_props mp;
        assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
        double v = 24 * scales[k] * scales[k] * scales[k];
        if (isfinite(v) && v > 0)
            assert_true(fabs(mp.volume - v) < 1e-9 * v);
        sc_shape_release(s);
    }
}

static void test_analytic_box_matches_its_mesh(void **state)
{
    (void)state;
    sc_shape *b = sc_shape_box(1, 1.5, 2);
    assert_non_null(b);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(b, &mp), SC_OK);
    assert_true(fabs(mp.volume - 24) < 1e-12);
    assert_true(fabs(mp.inertia[0] - 50) < 1e-9 && fabs(mp.inertia[4] - 40) < 1e-9 &&
                fabs(mp.inertia[8] - 26) < 1e-9);
    assert_true(fabs(sc_shape_bounding_radius(b) - sqrt(1 + 2.25 + 4)) < 1e-12);
    sc_shape_release(b);
}

/* Exact volume of the UV-sphere polyhedron: the caps and bands are sums of
 * tetrahedra from the centre; compare with the sphere as resolution grows. */
static void test_uv_sphere_converges_to_analytic_sphere(void **state)
{
    (void)state;
    const double r = 0.1, v = 4.0 / 3.0 * M_PI * r * r * r, I = 0.4 * v * r * r;
    double prev_err = INFINITY;
    const int res[][2] = { { 16, 8 }, { 64, 32 }, { 256, 128 } };
    for (int k = 0; k < 3; k++) {
        sc_shape *s = sc_shape_uv_sphere(r, res[k][0], res[k][1]);
        assert_non_null(s);
        assert_int_equal(sc_shape_triangles(s), 2 * res[k][0] * (res[k][1] - 1));
        sc_mass_props mp;
        assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
        double err = fabs(mp.volume - v) / v;
        assert_true(err < prev_err);
        prev_err = err;
        assert_true(fabs(mp.com[0]) < 1e-12 && fabs(mp.com[1]) < 1e-12 && fabs(mp.com[2]) < 1e-12);
        if (k == 2) {
            assert_true(err < 1e-3);
            assert_true(fabs(mp.inertia[0] - I) / I < 2e-3);
            assert_true(fabs(mp.inertia[8] - I) / I < 2e-3);
        }
        sc_shape_release(s);
    }
    /* analytic sphere */
    sc_shape *s = sc_shape_sphere(r);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
    assert_true(fabs(mp.volume - v) < 1e-15 && fabs(mp.inertia[0] - I) < 1e-18);
    sc_shape_release(s);
}

static void test_paper_shapes_have_the_papers_triangle_counts(void **state)
{
    (void)state;
    sc_shape *uv = sc_shape_uv_sphere(0.1, 16, 8), *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    assert_non_null(uv);
    assert_non_null(bolt);
    assert_non_null(nut);
    assert_int_equal(sc_shape_triangles(uv), 224);
    assert_int_equal(sc_shape_triangles(bolt), 180);   /* paper: 178 */
    assert_int_equal(sc_shape_triangles(nut), 396);
    sc_shape_release(uv);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

/* The bolt is a hex prism plus a 16-gon prism; the nut a hex prism minus a
 * 16-gon prism: their volumes in closed form. Centres of mass at the origin. */
static void test_bolt_and_nut_volumes_match_closed_form(void **state)
{
    (void)state;
    double hex = 1.5 * sqrt(3.0);                /* area of unit-circumradius hexagon */
    double gon16 = 0.5 * 16 * sin(2 * M_PI / 16); /* area of unit 16-gon */
    double vbolt = hex * 0.02 * 0.02 * 0.0125 + gon16 * 0.01 * 0.01 * 0.06;
    double vnut = (hex * 0.02 * 0.02 - gon16 * 0.0105 * 0.0105) * 0.016;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    sc_mass_props mb, mn;
    assert_int_equal(sc_shape_mass_props(bolt, &mb), SC_OK);
    assert_int_equal(sc_shape_mass_props(nut, &mn), SC_OK);
    assert_true(fabs(mb.volume - vbolt) / vbolt < 1e-12);
    assert_true(fabs(mn.volume - vnut) / vnut < 1e-12);
    for (int k = 0; k < 3; k++) {
        assert_true(fabs(mb.com[k]) < 1e-12);
        assert_true(fabs(mn.com[k]) < 1e-12);
    }
    /* symmetric about z: Ixx == Iyy, no products; positive definite */
    assert_true(fabs(mb.inertia[0] - mb.inertia[4]) < 1e-6 * mb.inertia[0]);
    assert_true(fabs(mn.inertia[0] - mn.inertia[4]) < 1e-6 * mn.inertia[0]);
    assert_true(mb.inertia[8] > 0 && mn.inertia[8] > 0);
    assert_true(fabs(mb.inertia[1]) < 1e-9 * mb.inertia[0]);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

static void test_open_and_inverted_meshes_are_rejected(void **state)
{
    (void)state;
    /* one face missing */
    assert_null(sc_shape_mesh(cube_xyz, 8, cube_tri, 11));
    assert_int_equal(sc_last_error(), SC_ENOTCLOSED);
    /* every face flipped: closed but inside out */
    int flipped[36];
    for (int t = 0; t < 12; t++) {
        flipped[3 * t] = cube_tri[3 * t];
        flipped[3 * t + 1] = cube_tri[3 * t + 2];
        flipped[3 * t + 2] = cube_tri[3 * t + 1];
    }
    assert_null(sc_shape_mesh(cube_xyz, 8, flipped, 12));
    assert_int_equal(sc_last_error(), SC_ENOTCLOSED);
    /* one face flipped: inconsistent */
    flipped[0] = cube_tri[0];
    for (int i = 3; i < 36; i++)
        flipped[i] = cube_tri[i];
    flipped[1] = cube_tri[2];
    flipped[2] = cube_tri[1];
    assert_null(sc_shape_mesh(cube_xyz, 8, flipped, 12));
    assert_int_equal(sc_last_error(), SC_ENOTCLOSED);
}

static void test_bad_mesh_input_gets_clear_codes(void **state)
{
    (void)state;
    int bad[36];
    for (int i = 0; i < 36; i++)
        bad[i] = cube_tri[i];
    bad[5] = 8;                                   /* index out of range */
    assert_null(sc_shape_mesh(cube_xyz, 8, bad, 12));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    bad[5] = -1;
    assert_null(sc_shape_mesh(cube_xyz, 8, bad, 12));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    double nanv[24];
    for (int i = 0; i < 24; i++)
        nanv[i] = cube_xyz[i];
    nanv[7] = NAN;
    assert_null(sc_shape_mesh(nanv, 8, cube_tri, 12));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    /* all vertices in one plane: no volume */
    double flat[24];
    for (int i = 0; i < 24; i++)
        flat[i] = (i % 3 == 2) ? 0 : cube_xyz[i];
    assert_null(sc_shape_mesh(flat, 8, cube_tri, 12));
    assert_int_equal(sc_last_error(), SC_EDEGENERATE);
    assert_null(sc_shape_mesh(NULL, 8, cube_tri, 12));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    assert_null(sc_shape_mesh(cube_xyz, SC_MESH_MAX_VERTS + 1, cube_tri, 12));
    assert_int_equal(sc_last_error(), SC_ETOOBIG);
}

/* ODE's trimesh preprocessing aborts on vertices no triangle uses: they
 * must be dropped, not passed on (found by fuzzing the loader). */
static void test_unused_vertices_are_dropped_not_fatal(void **state)
{
    (void)state;
    double xyz[3 * 40];
    for (int i = 0; i < 3 * 40; i++)
        xyz[i] = 0.25 * (i % 7);               /* 32 junk vertices ... */
    for (int i = 0; i < 24; i++)
        xyz[3 * 32 + i] = cube_xyz[i];         /* ... then the cube's 8 */
    int tri[36];
    for (int i = 0; i < 36; i++)
        tri[i] = cube_tri[i] + 32;
    sc_shape *s = sc_shape_mesh(xyz, 40, tri, 12);
    assert_non_null(s);
    int nv = 0;
    const int *t = NULL;
    assert_int_equal(sc_shape_mesh_data(s, NULL, &nv, &t, NULL), SC_OK);
    assert_int_equal(nv, 8);
    assert_int_equal(t[0], cube_tri[0]);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
    assert_true(fabs(mp.volume - 24) < 1e-12);
    sc_shape_release(s);
}

static void test_bad_analytic_parameters_are_rejected(void **state)
{
    (void)state;
    assert_null(sc_shape_sphere(0));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    assert_null(sc_shape_sphere(NAN));
    assert_null(sc_shape_box(1, -1, 1));
    assert_null(sc_shape_box(1, INFINITY, 1));
    assert_null(sc_shape_plane(0, 0, 0, 1));
    assert_null(sc_shape_uv_sphere(1, 2, 8));
    assert_null(sc_shape_uv_sphere(1, 16, 1));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    sc_shape *p = sc_shape_plane(0, 0, 2, 4);      /* normalised: z <= 2 */
    assert_non_null(p);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(p, &mp), SC_ENOTSUP);
    assert_true(isinf(sc_shape_bounding_radius(p)));
    assert_int_equal(sc_shape_mesh_data(p, NULL, NULL, NULL, NULL), SC_ENOTSUP);
    sc_shape_release(p);
}

static void test_convex_hull_shape_of_cube_points(void **state)
{
    (void)state;
    double pts[3 * 9];
    for (int i = 0; i < 24; i++)
        pts[i] = cube_xyz[i];
    pts[24] = 1; pts[25] = 1; pts[26] = 1;         /* interior point */
    sc_shape *s = sc_shape_convex(pts, 9);
    assert_non_null(s);
    assert_int_equal(sc_shape_kind(s), SC_SHAPE_CONVEX);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
    assert_true(fabs(mp.volume - 24) < 1e-9);
    int nv = 0;
    assert_int_equal(sc_shape_mesh_data(s, NULL, &nv, NULL, NULL), SC_OK);
    assert_int_equal(nv, 8);
    sc_shape_release(s);
    assert_null(sc_shape_convex(pts, 3));
    assert_int_equal(sc_last_error(), SC_EDEGENERATE);
}

static void test_shapes_are_reference_counted(void **state)
{
    (void)state;
    sc_shape *s = sc_shape_sphere(1);
    assert_ptr_equal(sc_shape_retain(s), s);
    sc_shape_release(s);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);  /* still alive */
    sc_shape_release(s);
    sc_shape_release(NULL);
}

static void test_every_error_code_has_a_sentence(void **state)
{
    (void)state;
    for (int e = SC_OK; e >= SC_EPERM; e--) {
        const char *m = sc_strerror(e);
        assert_non_null(m);
        assert_string_not_equal(m, "unknown error code");
    }
    assert_string_equal(sc_strerror(-999), "unknown error code");
}

/* The 8 corners of [x0,x1] x [y0,y1] x [z0,z1] into p (24 doubles). */
static void box_points(double *p, double x0, double x1, double y0, double y1, double z0,
                       double z1)
{
    for (int i = 0; i < 8; i++) {
        p[3 * i] = i & 1 ? x1 : x0;
        p[3 * i + 1] = i & 2 ? y1 : y0;
        p[3 * i + 2] = i & 4 ? z1 : z0;
    }
}

/* A mesh's convex pieces: counted, the mesh's mass kept, and bad pieces
 * (too few points, outside the mesh, flat, not finite, none, too many)
 * refused with a code. The paper's bolt has 2, its nut 16. */
static void test_mesh_pieces_are_checked(void **state)
{
    (void)state;
    double pts[48];
    int counts[2] = { 8, 8 };
    box_points(pts, 0, 2, 0, 3, 0, 2);
    box_points(pts + 24, 0, 2, 0, 3, 2, 4);
    sc_shape *s = sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, pts, counts, 2);
    assert_non_null(s);
    assert_int_equal(sc_shape_pieces(s), 2);
    assert_int_equal(sc_shape_kind(s), SC_SHAPE_MESH);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
    assert_true(fabs(mp.volume - 24) < 1e-12);
    sc_shape_release(s);
    sc_shape *plain = sc_shape_mesh(cube_xyz, 8, cube_tri, 12), *bolt = sc_shape_bolt(),
             *nut = sc_shape_nut();
    assert_int_equal(sc_shape_pieces(plain), 0);
    assert_int_equal(sc_shape_pieces(bolt), 2);
    assert_int_equal(sc_shape_pieces(nut), 16);
    sc_shape_release(plain);
    sc_shape_release(bolt);
    sc_shape_release(nut);

    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, pts, counts, 0));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, NULL, counts, 2));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    int few[2] = { 3, 13 };
    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, pts, few, 2));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, pts, counts,
                                     SC_MESH_MAX_PIECES + 1));
    assert_int_equal(sc_last_error(), SC_ETOOBIG);
    double bad[48];
    memcpy(bad, pts, sizeof bad);
    bad[3 * 9] = 2.5;                             /* outside the mesh */
    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, bad, counts, 2));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    bad[3 * 9] = NAN;
    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, bad, counts, 2));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    box_points(bad, 0, 2, 0, 3, 1, 1);            /* a flat piece */
    assert_null(sc_shape_mesh_pieces(cube_xyz, 8, cube_tri, 12, bad, counts, 2));
    assert_int_equal(sc_last_error(), SC_EINVAL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_box_mesh_mass_props_match_analytic_box),
        cmocka_unit_test(test_mesh_checks_work_at_extreme_scales),
        cmocka_unit_test(test_analytic_box_matches_its_mesh),
        cmocka_unit_test(test_uv_sphere_converges_to_analytic_sphere),
        cmocka_unit_test(test_paper_shapes_have_the_papers_triangle_counts),
        cmocka_unit_test(test_bolt_and_nut_volumes_match_closed_form),
        cmocka_unit_test(test_open_and_inverted_meshes_are_rejected),
        cmocka_unit_test(test_bad_mesh_input_gets_clear_codes),
        cmocka_unit_test(test_unused_vertices_are_dropped_not_fatal),
        cmocka_unit_test(test_bad_analytic_parameters_are_rejected),
        cmocka_unit_test(test_convex_hull_shape_of_cube_points),
        cmocka_unit_test(test_mesh_pieces_are_checked),
        cmocka_unit_test(test_shapes_are_reference_counted),
        cmocka_unit_test(test_every_error_code_has_a_sentence),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
