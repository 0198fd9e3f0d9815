/* test_toi.c - time of impact: first touch found within tolerance, no
 * tunnelling through thin walls, no false hits. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "core.h"
#include "simcluster.h"

#define TOL 1e-3

static sc_pose at(double x, double y, double z)
{
    sc_pose p = { { x, y, z }, { 1, 0, 0, 0 } };
    return p;
}

static double depth_at(const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                       const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double t)
{
    /* positions only (these tests rotate with the same quaternion at both ends
     * or check through sc_toi's own contract) */
    sc_pose pa = *a0, pb = *b0;
    for (int k = 0; k < 3; k++) {
        pa.pos[k] += t * (a1->pos[k] - a0->pos[k]);
        pb.pos[k] += t * (b1->pos[k] - b0->pos[k]);
    }
    sc_contact c[4];
    int n = sc_collide(a, &pa, b, &pb, c, 4);
    double d = -1;
    for (int i = 0; i < n; i++)
        d = fmax(d, c[i].depth);
    return d;
}

static void test_falling_sphere_touches_plane_at_the_analytic_time(void **state)
{
    (void)state;
    sc_shape *plane = sc_shape_plane(0, 0, 1, 0), *ball = sc_shape_sphere(0.1);
    sc_pose o = at(0, 0, 0), b0 = at(0, 0, 1), b1 = at(0, 0, -1);
    double t = -1;
    assert_int_equal(sc_toi(plane, &o, &o, ball, &b0, &b1, TOL, &t), 1);
    /* touches at z = 0.1, i.e. t = 0.45; within tol the depth 2 m * dt */
    assert_true(t >= 0.45 && t <= 0.45 + TOL / 2.0);
    double d = depth_at(plane, &o, &o, ball, &b0, &b1, t);
    assert_true(d >= 0 && d <= TOL);
    sc_shape_release(plane);
    sc_shape_release(ball);
}

static void test_fast_sphere_does_not_tunnel_through_thin_wall(void **state)
{
    (void)state;
    sc_shape *wall = sc_shape_box(0.005, 1, 1), *ball = sc_shape_sphere(0.02);
    sc_pose w = at(0, 0, 0), b0 = at(-5, 0.3, 0.2), b1 = at(5, 0.3, 0.2);
    /* at both ends the ball is far from the wall: only sampling finds it */
    double t = -1;
    assert_int_equal(sc_toi(wall, &w, &w, ball, &b0, &b1, TOL, &t), 1);
    double expect = (5 - 0.025) / 10;
    assert_true(t >= expect - 1e-9 && t <= expect + TOL / 10 + 1e-9);
    sc_shape_release(wall);
    sc_shape_release(ball);
}

static void test_missing_each_other_returns_zero(void **state)
{
    (void)state;
    sc_shape *a = sc_shape_sphere(0.1), *b = sc_shape_box(0.1, 0.1, 0.1);
    sc_pose a0 = at(0, 0, 0), a1 = at(1, 0, 0), b0 = at(0, 1, 0), b1 = at(1, 1, 0);
    double t = -1;
    assert_int_equal(sc_toi(a, &a0, &a1, b, &b0, &b1, TOL, &t), 0);
    sc_shape_release(a);
    sc_shape_release(b);
}

static void test_already_touching_is_time_zero(void **state)
{
    (void)state;
    sc_shape *a = sc_shape_sphere(0.1);
    sc_pose a0 = at(0, 0, 0), b0 = at(0.15, 0, 0), b1 = at(1, 0, 0);
    double t = -1;
    assert_int_equal(sc_toi(a, &a0, &a0, a, &b0, &b1, TOL, &t), 1);
    assert_true(t == 0);
    sc_shape_release(a);
}

/* A lying bolt spinning about its own axis while dropping onto the floor:
 * rotation and translation together; the answer is checked by sampling. */
static void test_tumbling_bolt_hits_floor_within_tolerance(void **state)
{
    (void)state;
    sc_shape *plane = sc_shape_plane(0, 0, 1, 0), *bolt = sc_shape_bolt();
    const double s = 0.70710678118654752;
    sc_pose o = at(0, 0, 0);
    sc_pose b0 = { { 0, 0, 0.2 }, { s, 0, s, 0 } };            /* axis along x */
    sc_pose b1 = { { 0.05, 0, -0.05 }, { 0.5, 0.5, 0.5, 0.5 } }; /* turned further */
    double t = -1;
    assert_int_equal(sc_toi(plane, &o, &o, bolt, &b0, &b1, TOL, &t), 1);
    assert_true(t > 0 && t < 1);
    /* at t the bolt touches within tol; 0.01 earlier (it is 2.5 mm higher,
     * more than twice the tolerance) it is free */
    sc_contact c[4];
    double ts[2] = { t, t - 0.01 };
    for (int k = 0; k < 2; k++) {
        sc_pose p;
        for (int i = 0; i < 3; i++)
            p.pos[i] = b0.pos[i] + ts[k] * (b1.pos[i] - b0.pos[i]);
        /* slerp, as sc_toi does */
        double dot = 0;
        for (int i = 0; i < 4; i++)
            dot += b0.quat[i] * b1.quat[i];
        double th = acos(dot), w0 = sin((1 - ts[k]) * th) / sin(th), w1 = sin(ts[k] * th) / sin(th);
        for (int i = 0; i < 4; i++)
            p.quat[i] = w0 * b0.quat[i] + w1 * b1.quat[i];
        double l = sqrt(p.quat[0] * p.quat[0] + p.quat[1] * p.quat[1] + p.quat[2] * p.quat[2] +
                        p.quat[3] * p.quat[3]);
        for (int i = 0; i < 4; i++)
            p.quat[i] /= l;
        int n = sc_collide(plane, &o, bolt, &p, c, 4);
        if (k == 0) {
            assert_true(n > 0);
            for (int i = 0; i < n; i++)
                assert_true(c[i].depth <= TOL + 1e-9);
        } else {
            assert_int_equal(n, 0);
        }
    }
    sc_shape_release(plane);
    sc_shape_release(bolt);
}

/* The search before tmax (what a TOI unit uses once it has an earlier
 * pair): when the full search's answer is earlier than tmax it gives the
 * same bits; otherwise it gives 0 (no hit looked at) or a time >= tmax,
 * so the minimum over pairs does not change. Bolt on nut, both moving and
 * turning, new and deepening pairs. */
static void test_search_before_tmax_keeps_the_earliest_exact(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    sc_np_ctx *np = sc_np_create();
    assert_non_null(np);
    const double s = 0.70710678118654752;
    int hits = 0, pruned = 0;
    for (int k = 0; k < 24; k++) {
        double x = 0.004 * k;
        sc_pose a0 = { { -0.12 + x, 0, 0.01 }, { s, 0, s, 0 } };
        sc_pose a1 = { { 0.03, 0.002 * k, 0.0 }, { 0.5, 0.5, 0.5, 0.5 } };
        sc_pose b0 = at(0.02, 0, 0), b1 = at(0.02 - 0.001 * k, 0, 0.001);
        for (int deepen = 0; deepen < 2; deepen++) {
            double t = -1;
            int hit = deepen ? sc_toi_deepen_ctx(np, bolt, &a0, &a1, nut, &b0, &b1, TOL, &t)
                             : sc_toi_ctx(np, bolt, &a0, &a1, nut, &b0, &b1, TOL, &t);
            assert_true(hit >= 0);
            if (hit != 1)
                continue;
            hits++;
            double tmaxes[3] = { fmin(1, t + 1e-3), 0.5 * t, 0 };
            for (int j = 0; j < 3; j++) {
                double u = -1;
                int h2 = deepen ? sc_toi_deepen_before_ctx(np, bolt, &a0, &a1, nut, &b0, &b1,
                                                           TOL, tmaxes[j], &u)
                                : sc_toi_before_ctx(np, bolt, &a0, &a1, nut, &b0, &b1, TOL,
                                                    tmaxes[j], &u);
                assert_true(h2 >= 0);
                if (tmaxes[j] > t) {
                    assert_int_equal(h2, 1);
                    assert_true(u == t);    /* the same bits */
                } else {
                    assert_true(h2 == 0 || u >= tmaxes[j] || u == t);
                    pruned += h2 == 0;
                }
            }
        }
    }
    print_message("bolt-nut searches: %d hits, %d searches stopped at tmax\n", hits, pruned);
    assert_true(hits >= 10);
    assert_true(pruned >= 1);
    sc_np_destroy(np);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

static void test_toi_rejects_bad_arguments(void **state)
{
    (void)state;
    sc_shape *a = sc_shape_sphere(0.1);
    sc_pose p = at(0, 0, 0), q = at(NAN, 0, 0);
    double t;
    assert_int_equal(sc_toi(a, &p, &p, a, &p, &p, 0, &t), SC_EINVAL);
    assert_int_equal(sc_toi(a, &p, &p, a, &p, &p, NAN, &t), SC_EINVAL);
    assert_int_equal(sc_toi(a, &p, &p, a, &p, &p, TOL, NULL), SC_EINVAL);
    assert_int_equal(sc_toi(a, &p, &q, a, &p, &p, TOL, &t), SC_EINVAL);
    sc_shape_release(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_falling_sphere_touches_plane_at_the_analytic_time),
        cmocka_unit_test(test_fast_sphere_does_not_tunnel_through_thin_wall),
        cmocka_unit_test(test_missing_each_other_returns_zero),
        cmocka_unit_test(test_already_touching_is_time_zero),
        cmocka_unit_test(test_tumbling_bolt_hits_floor_within_tolerance),
        cmocka_unit_test(test_search_before_tmax_keeps_the_earliest_exact),
        cmocka_unit_test(test_toi_rejects_bad_arguments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
