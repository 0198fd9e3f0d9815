/* test_scene.c - the paper's scenes: what sc_scene_spheres_box and
 * sc_scene_bolts_nuts put in a world (bodies, shapes, masses, materials'
 * placement), that nothing overlaps at t = 0, determinism, bad input. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <cmocka.h>

#include "simcluster.h"

#define G 9.81
#define STEEL 7800.0

static sc_pose body_pose(const sc_world *w, int id)
{
    sc_pose p = { { 0, 0, 0 }, { 0, 0, 0, 0 } };
    sc_body_get_pose(w, id, p.pos, p.quat);
    return p;
}

/* The mass of each dynamic body, measured through the public API: push it
 * with f newtons upwards for one short frame and read the change of
 * velocity, dv = (f / m - g) dt (exact for any integrator: the force is
 * constant and the bodies touch nothing). Steps w. */
static void measure_masses(sc_world *w, int first, int n, double f, double *mass)
{
    const double dt = 1e-3;
    double v0[3 * 200], v[3], om[3];
    assert_true(n <= 200);
    const double up[3] = { 0, 0, f };
    for (int i = 0; i < n; i++) {
        sc_body_get_velocity(w, first + i, &v0[3 * i], om);
        assert_int_equal(sc_body_apply_force(w, first + i, up, NULL), SC_OK);
    }
    assert_int_equal(sc_world_step(w, dt), SC_OK);
    for (int i = 0; i < n; i++) {
        sc_body_get_velocity(w, first + i, v, om);
        double dvz = v[2] - v0[3 * i + 2];
        mass[i] = f / (dvz / dt + G);
    }
}

static double rel_err(double x, double ref)
{
    return fabs(x - ref) / fabs(ref);
}

/* ---- Table 1: spheres in a box ---- */

static const double wall_planes[6][4] = {
    { 0, 0, 1, 0 }, { 0, 0, -1, -4 }, { 1, 0, 0, -2 },
    { -1, 0, 0, -2 }, { 0, 1, 0, -2 }, { 0, -1, 0, -2 },
};

static void test_spheres_box_has_six_walls_and_27_moving_spheres_on_a_lattice(void **state)
{
    (void)state;
    sc_world *w = sc_world_create(NULL);
    assert_non_null(w);
    assert_int_equal(sc_scene_spheres_box(w), SC_OK);
    assert_int_equal(sc_world_body_count(w), 6 + 27);
    for (int i = 0; i < 6; i++)
        assert_int_equal(sc_body_state(w, i), SC_STATIC);
    int seen[27] = { 0 };
    for (int i = 6; i < 33; i++) {
        assert_int_not_equal(sc_body_state(w, i), SC_STATIC);
        sc_pose p = body_pose(w, i);
        /* a lattice point (x, y in {-1, 0, 1}, z in {1, 2, 3}), each once */
        int cell[3];
        for (int k = 0; k < 3; k++) {
            double c = p.pos[k] - (k == 2 ? 2 : 0);
            cell[k] = (int)lround(c) + 1;
            assert_true(fabs(c - lround(c)) < 1e-12);
            assert_true(cell[k] >= 0 && cell[k] <= 2);
        }
        seen[cell[0] + 3 * cell[1] + 9 * cell[2]]++;
        double v[3], om[3];
        sc_body_get_velocity(w, i, v, om);
        assert_true(fabs(sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) - 1.0) < 1e-12);
        assert_true(om[0] == 0 && om[1] == 0 && om[2] == 0);
    }
    for (int c = 0; c < 27; c++)
        assert_int_equal(seen[c], 1);
    sc_world_destroy(w);
}

static void test_spheres_box_spheres_are_224_triangle_steel_uv_spheres(void **state)
{
    (void)state;
    sc_shape *uv = sc_shape_uv_sphere(0.1, 16, 8);
    sc_shape *coarser = sc_shape_uv_sphere(0.1, 16, 7);
    assert_non_null(uv);
    assert_non_null(coarser);
    assert_int_equal(sc_shape_triangles(uv), 224);
    sc_mass_props mp, mp_coarser;
    assert_int_equal(sc_shape_mass_props(uv, &mp), SC_OK);
    assert_int_equal(sc_shape_mass_props(coarser, &mp_coarser), SC_OK);
    double expect = STEEL * mp.volume;
    /* the mass identifies the mesh: an analytic sphere and other
     * tessellations differ from it by far more than the tolerance */
    double analytic = STEEL * 4.0 / 3.0 * M_PI * 1e-3;
    assert_true(rel_err(analytic, expect) > 1e-3);
    assert_true(rel_err(STEEL * mp_coarser.volume, expect) > 1e-3);

    sc_world *w = sc_world_create(NULL);
    assert_int_equal(sc_scene_spheres_box(w), SC_OK);
    double mass[27];
    measure_masses(w, 6, 27, 100.0, mass);
    for (int i = 0; i < 27; i++)
        assert_true(rel_err(mass[i], expect) < 1e-6);
    sc_world_destroy(w);
    sc_shape_release(uv);
    sc_shape_release(coarser);
}

static void test_spheres_box_nothing_overlaps_at_start(void **state)
{
    (void)state;
    sc_world *w = sc_world_create(NULL);
    assert_int_equal(sc_scene_spheres_box(w), SC_OK);
    /* the documented shapes at the world's poses, every pair */
    sc_shape *shapes[33];
    for (int i = 0; i < 6; i++) {
        const double *p = wall_planes[i];
        shapes[i] = sc_shape_plane(p[0], p[1], p[2], p[3]);
    }
    sc_shape *ball = sc_shape_uv_sphere(0.1, 16, 8);
    for (int i = 6; i < 33; i++)
        shapes[i] = ball;
    sc_pose pose[33];
    for (int i = 0; i < 33; i++)
        pose[i] = body_pose(w, i);
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    for (int i = 0; i < 33; i++)
        for (int j = i + 1; j < 33; j++)
            assert_int_equal(sc_collide(shapes[i], &pose[i], shapes[j], &pose[j], c,
                                        SC_MAX_PAIR_CONTACTS), 0);
    /* and the world's own narrow phase, on its own shapes, agrees */
    assert_int_equal(sc_world_step(w, 1e-6), SC_OK);
    assert_int_equal(sc_world_contacts(w, NULL, 0), 0);
    for (int i = 0; i < 6; i++)
        sc_shape_release(shapes[i]);
    sc_shape_release(ball);
    sc_world_destroy(w);
}

/* Each wall is where the man page says and faces inward: a probe ball put
 * 0.5 mm into wall i (inside the allowed penetration, so no contact model
 * pushes it out) touches wall i only, with the normal pointing into the box
 * and a 0.5 mm depth. */
static void test_spheres_box_walls_close_the_4m_box_and_face_inward(void **state)
{
    (void)state;
    sc_world *w = sc_world_create(NULL);
    assert_int_equal(sc_scene_spheres_box(w), SC_OK);
    sc_shape *probe = sc_shape_sphere(0.05);
    const double in = 0.05 - 0.0005;   /* centre to wall */
    const double at[6][3] = { { 0.5, 0.5, in }, { 0.5, 0.5, 4 - in }, { -2 + in, 0.5, 1.5 },
                              { 2 - in, 0.5, 1.5 }, { 0.5, -2 + in, 2.5 }, { 0.5, 2 - in, 2.5 } };
    for (int i = 0; i < 6; i++) {
        sc_body_desc d = sc_body_desc_default();
        d.shape = probe;
        for (int k = 0; k < 3; k++)
            d.pos[k] = at[i][k];
        assert_int_equal(sc_body_add(w, &d), 33 + i);
    }
    sc_shape_release(probe);
    assert_int_equal(sc_world_step(w, 1e-6), SC_OK);
    sc_contact c[32];
    int n = sc_world_contacts(w, c, 32);
    assert_int_equal(n, 6);
    for (int k = 0; k < n; k++) {
        int wall = c[k].body_a;
        assert_true(wall >= 0 && wall < 6);
        assert_int_equal(c[k].body_b, 33 + wall);
        const double *inward = wall_planes[wall];
        double dot = c[k].normal[0] * inward[0] + c[k].normal[1] * inward[1] +
                     c[k].normal[2] * inward[2];
        assert_true(dot > 1 - 1e-9);
        assert_true(fabs(c[k].depth - 0.0005) < 1e-6);
    }
    sc_world_destroy(w);
}

/* ---- Figs 3-4: bolts and nuts ---- */

typedef struct bn_shapes {
    sc_shape *bolt, *nut, *floor;
    double r;                     /* the larger bounding radius */
    double m_bolt, m_nut;         /* steel */
} bn_shapes;

static bn_shapes bn_shapes_make(void)
{
    bn_shapes s = { sc_shape_bolt(), sc_shape_nut(), sc_shape_plane(0, 0, 1, 0), 0, 0, 0 };
    assert_non_null(s.bolt);
    assert_non_null(s.nut);
    assert_non_null(s.floor);
    s.r = fmax(sc_shape_bounding_radius(s.bolt), sc_shape_bounding_radius(s.nut));
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s.bolt, &mp), SC_OK);
    s.m_bolt = STEEL * mp.volume;
    assert_int_equal(sc_shape_mass_props(s.nut, &mp), SC_OK);
    s.m_nut = STEEL * mp.volume;
    return s;
}

static void bn_shapes_free(bn_shapes *s)
{
    sc_shape_release(s->bolt);
    sc_shape_release(s->nut);
    sc_shape_release(s->floor);
}

static sc_world *bolts_nuts_world(int n, uint64_t seed)
{
    sc_world *w = sc_world_create(NULL);
    assert_non_null(w);
    assert_int_equal(sc_scene_bolts_nuts(w, n, seed), SC_OK);
    return w;
}

static const int bn_sizes[] = { 1, 10, 50, 200 };

static void test_bolts_nuts_adds_a_floor_and_n_alternating_steel_bolts_and_nuts(void **state)
{
    (void)state;
    bn_shapes s = bn_shapes_make();
    /* the two pieces' masses differ by far more than the tolerance */
    assert_true(rel_err(s.m_nut, s.m_bolt) > 0.5);
    for (size_t t = 0; t < sizeof bn_sizes / sizeof *bn_sizes; t++) {
        int n = bn_sizes[t];
        sc_world *w = bolts_nuts_world(n, 42);
        assert_int_equal(sc_world_body_count(w), n + 1);
        assert_int_equal(sc_body_state(w, 0), SC_STATIC);
        for (int i = 1; i <= n; i++) {
            assert_int_equal(sc_body_state(w, i), SC_FREE);
            double v[3], om[3];
            sc_body_get_velocity(w, i, v, om);
            for (int k = 0; k < 3; k++)
                assert_true(v[k] == 0 && om[k] == 0);
        }
        double *mass = malloc((size_t)n * sizeof *mass);
        assert_non_null(mass);
        measure_masses(w, 1, n, 1.0, mass);
        for (int i = 0; i < n; i++)
            assert_true(rel_err(mass[i], i % 2 == 0 ? s.m_bolt : s.m_nut) < 1e-6);
        free(mass);
        sc_world_destroy(w);
    }
    bn_shapes_free(&s);
}

static void test_bolts_nuts_start_apart_above_the_floor_inside_the_column(void **state)
{
    (void)state;
    bn_shapes s = bn_shapes_make();
    sc_pose *pose = malloc(200 * sizeof *pose);
    assert_non_null(pose);
    for (size_t t = 0; t < sizeof bn_sizes / sizeof *bn_sizes; t++) {
        int n = bn_sizes[t];
        sc_world *w = bolts_nuts_world(n, 7 + t);
        /* the documented column: k x k cubes of side 4R, n cubes high in
         * all, from 2R above the floor */
        int k = (int)ceil(cbrt((double)n) - 1e-9);
        double side = 4 * s.r * k, height = n * pow(4 * s.r, 3) / (side * side);
        sc_contact c[SC_MAX_PAIR_CONTACTS];
        sc_pose floor_pose = body_pose(w, 0);
        for (int i = 0; i < n; i++) {
            pose[i] = body_pose(w, i + 1);
            const double *q = pose[i].quat;
            assert_true(fabs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1) < 1e-12);
            sc_shape *sh = i % 2 == 0 ? s.bolt : s.nut;
            assert_true(fabs(pose[i].pos[0]) <= 0.5 * side + 1e-12);
            assert_true(fabs(pose[i].pos[1]) <= 0.5 * side + 1e-12);
            assert_true(pose[i].pos[2] >= 2 * s.r - 1e-12);
            assert_true(pose[i].pos[2] <= 2 * s.r + height + 1e-12);
            /* above the floor with room to spare, and not touching it */
            assert_true(pose[i].pos[2] - sc_shape_bounding_radius(sh) >= s.r - 1e-12);
            assert_int_equal(sc_collide(s.floor, &floor_pose, sh, &pose[i], c,
                                        SC_MAX_PAIR_CONTACTS), 0);
        }
        /* every pair apart, by the exact narrow phase */
        for (int i = 0; i < n; i++)
            for (int j = i + 1; j < n; j++)
                assert_int_equal(sc_collide(i % 2 == 0 ? s.bolt : s.nut, &pose[i],
                                            j % 2 == 0 ? s.bolt : s.nut, &pose[j], c,
                                            SC_MAX_PAIR_CONTACTS), 0);
        /* the world's narrow phase, on its own shapes, agrees */
        assert_int_equal(sc_world_step(w, 1e-6), SC_OK);
        assert_int_equal(sc_world_contacts(w, NULL, 0), 0);
        sc_world_destroy(w);
    }
    free(pose);
    bn_shapes_free(&s);
}

static void test_bolts_nuts_same_seed_same_hash_other_seed_other_hash(void **state)
{
    (void)state;
    for (size_t t = 0; t < sizeof bn_sizes / sizeof *bn_sizes; t++) {
        int n = bn_sizes[t];
        sc_world *a = bolts_nuts_world(n, 1234), *b = bolts_nuts_world(n, 1234);
        sc_world *c = bolts_nuts_world(n, 1235);
        assert_true(sc_world_hash(a) == sc_world_hash(b));
        assert_true(sc_world_hash(a) != sc_world_hash(c));
        sc_world_destroy(a);
        sc_world_destroy(b);
        sc_world_destroy(c);
    }
}

static void test_bolts_nuts_go_after_bodies_already_in_the_world(void **state)
{
    (void)state;
    sc_world *w = sc_world_create(NULL);
    sc_shape *ball = sc_shape_sphere(0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = ball;
    d.pos[0] = 50;                   /* far from the column */
    assert_int_equal(sc_body_add(w, &d), 0);
    sc_shape_release(ball);
    assert_int_equal(sc_scene_bolts_nuts(w, 3, 9), SC_OK);
    assert_int_equal(sc_world_body_count(w), 1 + 1 + 3);
    assert_int_equal(sc_body_state(w, 1), SC_STATIC);   /* the floor */
    /* the same poses as in an empty world with the same seed */
    sc_world *e = bolts_nuts_world(3, 9);
    for (int i = 0; i < 4; i++) {
        sc_pose p = body_pose(w, i + 1), q = body_pose(e, i);
        for (int k = 0; k < 3; k++)
            assert_true(p.pos[k] == q.pos[k]);
        for (int k = 0; k < 4; k++)
            assert_true(p.quat[k] == q.quat[k]);
    }
    sc_world_destroy(e);
    sc_world_destroy(w);
}

static void test_scenes_reject_bad_n_and_null_world(void **state)
{
    (void)state;
    assert_int_equal(sc_scene_spheres_box(NULL), SC_EINVAL);
    assert_int_equal(sc_scene_bolts_nuts(NULL, 10, 1), SC_EINVAL);
    sc_world *w = sc_world_create(NULL);
    const int bad[] = { 0, -1, -100, 100001, 2147483647, -2147483647 - 1 };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++)
        assert_int_equal(sc_scene_bolts_nuts(w, bad[i], 1), SC_EINVAL);
    assert_int_equal(sc_world_body_count(w), 0);    /* nothing added */
    sc_world_destroy(w);
}

/* The elastic boxes (bench_energy's): six walls, then n spheres of the
 * radius, steel, e = 1, no friction, all at the given speed, none
 * overlapping another or a wall; bad arguments add nothing. */
static void test_elastic_box_has_n_spheres_at_speed_and_rejects_bad_input(void **state)
{
    (void)state;
    sc_world *w = sc_world_create(NULL);
    assert_non_null(w);
    const int bad_n[] = { 0, -1, SC_ELASTIC_BOX_MAX + 1 };
    for (size_t i = 0; i < sizeof bad_n / sizeof *bad_n; i++)
        assert_int_equal(sc_scene_elastic_box(w, bad_n[i], 0.1, 1), SC_EINVAL);
    const double bad_r[] = { 0, -0.1, 0.25, NAN, INFINITY };
    for (size_t i = 0; i < sizeof bad_r / sizeof *bad_r; i++)
        assert_int_equal(sc_scene_elastic_box(w, 8, bad_r[i], 1), SC_EINVAL);
    assert_int_equal(sc_scene_elastic_box(w, 8, 0.1, NAN), SC_EINVAL);
    assert_int_equal(sc_scene_elastic_box(w, 8, 0.1, -1), SC_EINVAL);
    assert_int_equal(sc_scene_elastic_box(NULL, 8, 0.1, 1), SC_EINVAL);
    assert_int_equal(sc_world_body_count(w), 0);
    assert_int_equal(sc_scene_elastic_box(w, 27, 0.2, 3), SC_OK);
    assert_int_equal(sc_world_body_count(w), 6 + 27);
    double pos[27][3];
    for (int i = 0; i < 27; i++) {
        double q[4], v[3], om[3];
        sc_body_get_pose(w, 6 + i, pos[i], q);
        sc_body_get_velocity(w, 6 + i, v, om);
        assert_true(fabs(sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) - 3) < 1e-12);
        for (int k = 0; k < 2; k++)
            assert_true(fabs(pos[i][k]) + 0.2 < 2);
        assert_true(pos[i][2] > 0.2 && pos[i][2] < 3.8);
        for (int j = 0; j < i; j++) {
            double dx = pos[i][0] - pos[j][0], dy = pos[i][1] - pos[j][1],
                   dz = pos[i][2] - pos[j][2];
            assert_true(sqrt(dx * dx + dy * dy + dz * dz) > 0.4);
        }
    }
    sc_world_destroy(w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spheres_box_has_six_walls_and_27_moving_spheres_on_a_lattice),
        cmocka_unit_test(test_spheres_box_spheres_are_224_triangle_steel_uv_spheres),
        cmocka_unit_test(test_spheres_box_nothing_overlaps_at_start),
        cmocka_unit_test(test_spheres_box_walls_close_the_4m_box_and_face_inward),
        cmocka_unit_test(test_bolts_nuts_adds_a_floor_and_n_alternating_steel_bolts_and_nuts),
        cmocka_unit_test(test_bolts_nuts_start_apart_above_the_floor_inside_the_column),
        cmocka_unit_test(test_bolts_nuts_same_seed_same_hash_other_seed_other_hash),
        cmocka_unit_test(test_bolts_nuts_go_after_bodies_already_in_the_world),
        cmocka_unit_test(test_scenes_reject_bad_n_and_null_world),
        cmocka_unit_test(test_elastic_box_has_n_spheres_at_speed_and_rejects_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
