/* test_physics.c - physics validation: the numbers of the dynamics issue,
 * with tolerances from the physics, through the public API only. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "simcluster.h"

#define G 9.81
#define DT 0.01

static sc_world *world_with_plane_mode(double nx, double nz, double e, double mu, int mode)
{
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    sc_shape *p = sc_shape_plane(nx, 0, nz, 0);
    sc_body_desc d = sc_body_desc_default();
    d.shape = p;
    d.mass = 0;
    d.restitution = e;
    d.friction = mu;
    assert_int_equal(sc_body_add(w, &d), 0);
    sc_shape_release(p);
    return w;
}

static sc_world *world_with_plane(double nx, double nz, double e, double mu)
{
    return world_with_plane_mode(nx, nz, e, mu, sc_world_config_default().toi_mode);
}

static void test_ball_rebounds_to_e_squared_height(void **state)
{
    (void)state;
    sc_world *w = world_with_plane(0, 1, 0.8, 0.5);
    sc_shape *s = sc_shape_sphere(0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.restitution = 0.8;
    d.pos[2] = 1.1;                       /* dropped from 1 m above contact */
    int id = sc_body_add(w, &d);
    double peak = 0, vz_prev = 0;
    int bounces = 0;
    for (int n = 0; n < 200 && bounces < 2; n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        double p[3], v[3];
        sc_body_get_pose(w, id, p, NULL);
        sc_body_get_velocity(w, id, v, NULL);
        if (vz_prev < 0 && v[2] > 0)
            bounces++;
        if (bounces == 1)
            peak = fmax(peak, p[2] - 0.1);
        vz_prev = v[2];
    }
    /* the peak is sampled every frame: allow the sampling error too */
    assert_true(fabs(peak - 0.64) <= 0.02 * 0.64);
    sc_shape_release(s);
    sc_world_destroy(w);
}

/* examples/hello.c's ball (radius 0.1 m, dropped from 1 m: 0.9 m onto the
 * floor) rises to e^2 of its fall after the first bounce, within 1 % (the
 * peak is sampled every 10 ms frame: g (5 ms)^2 / 2 = 0.12 mm), in both
 * modes. In the local mode the landing is held by a speculative contact
 * (counted: the test sees one), which bounced a gap early, at the speed
 * the ball had there: 251.1 mm instead of 225 for e = 0.5. */
static void held_ball(int mode, double e)
{
    sc_world *w = world_with_plane_mode(0, 1, e, 0.5, mode);
    sc_shape *s = sc_shape_sphere(0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.restitution = e;
    d.pos[2] = 1.0;
    int id = sc_body_add(w, &d);
    double peak = 0, vz_prev = 0;
    int bounced = 0, held = 0;
    for (int n = 0; n < 200; n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        double p[3], v[3];
        sc_body_get_pose(w, id, p, NULL);
        sc_body_get_velocity(w, id, v, NULL);
        sc_stats st;
        sc_world_stats(w, &st);
        held += st.frame.toi.spec_contacts > 0;
        if (vz_prev < 0 && v[2] > 0)
            bounced = 1;
        if (bounced && v[2] < 0)
            break;
        if (bounced)
            peak = fmax(peak, p[2] - 0.1);
        vz_prev = v[2];
    }
    print_message("%s mode, e = %.1f: first bounce %.1f mm (e^2 of 0.9 m: %.1f mm), %d frames "
                  "with speculative contacts\n", mode == SC_TOI_LOCAL ? "local" : "world", e,
                  1e3 * peak, 1e3 * e * e * 0.9, held);
    assert_true(fabs(peak - e * e * 0.9) <= 0.01 * e * e * 0.9);
    if (mode == SC_TOI_LOCAL)
        assert_true(held > 0);
    sc_shape_release(s);
    sc_world_destroy(w);
}

static void test_held_ball_rebounds_to_e_squared_height(void **state)
{
    (void)state;
    for (int mode = 0; mode < 2; mode++) {
        held_ball(mode ? SC_TOI_WORLD : SC_TOI_LOCAL, 0.5);
        held_ball(mode ? SC_TOI_WORLD : SC_TOI_LOCAL, 0.8);
    }
}

static void test_sliding_box_stops_after_v2_over_2_mu_g(void **state)
{
    (void)state;
    const double mu = 0.5, v0 = 2.0;
    sc_world *w = world_with_plane(0, 1, 0, mu);
    sc_shape *s = sc_shape_box(0.1, 0.1, 0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.restitution = 0;
    d.friction = mu;
    d.pos[2] = 0.1;
    d.vel[0] = v0;
    int id = sc_body_add(w, &d);
    double p[3], v[3];
    for (int n = 0; n < 100; n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        sc_body_get_velocity(w, id, v, NULL);
    }
    sc_body_get_pose(w, id, p, NULL);
    assert_true(fabs(v[0]) < 1e-9);
    double expect = v0 * v0 / (2 * mu * G);
    assert_true(fabs(p[0] - expect) <= 0.02 * expect);
    assert_true(fabs(p[1]) < 1e-6 && fabs(p[2] - 0.1) < 1e-3);
    sc_shape_release(s);
    sc_world_destroy(w);
}

/* A box on a slope of angle th with mu = 0.5 (friction angle 26.6 deg):
 * below it the box stays, above it slides with a = g (sin th - mu cos th). */
static double slide(double th_deg, double *accel)
{
    const double mu = 0.5, th = th_deg * M_PI / 180;
    sc_world *w = world_with_plane(-sin(th), cos(th), 0, mu);
    sc_shape *s = sc_shape_box(0.1, 0.1, 0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.restitution = 0;
    d.friction = mu;
    /* resting on the slope: rotated by th about y, centre 0.1 above it */
    d.quat[0] = cos(th / 2);
    d.quat[2] = -sin(th / 2);
    d.pos[0] = -0.1 * sin(th);
    d.pos[2] = 0.1 * cos(th) - 0.0002;
    int id = sc_body_add(w, &d);
    double p0[3], p[3], v[3];
    sc_body_get_pose(w, id, p0, NULL);
    double t = 1.0, vt = 0;
    for (int n = 0; n < (int)(t / DT); n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        if (n == (int)(0.5 / DT) - 1) {
            sc_body_get_velocity(w, id, v, NULL);
            vt = -(v[0] * cos(th) + v[2] * sin(th));    /* downhill speed */
        }
    }
    sc_body_get_pose(w, id, p, NULL);
    sc_body_get_velocity(w, id, v, NULL);
    double v1 = -(v[0] * cos(th) + v[2] * sin(th));
    *accel = (v1 - vt) / 0.5;
    sc_shape_release(s);
    sc_world_destroy(w);
    double dx = p[0] - p0[0], dz = p[2] - p0[2];
    return sqrt(dx * dx + dz * dz);
}

static void test_box_on_slope_below_friction_angle_stays(void **state)
{
    (void)state;
    double a;
    double moved = slide(20, &a);
    assert_true(moved < 1e-3);
}

static void test_box_on_slope_above_friction_angle_slides(void **state)
{
    (void)state;
    double a;
    double th = 35 * M_PI / 180;
    slide(35, &a);
    double expect = G * (sin(th) - 0.5 * cos(th));
    assert_true(fabs(a - expect) <= 0.02 * expect);
}

/* Five 0.2 m boxes stacked, started resting (each interface at the 0.5 mm
 * slop the contact model keeps): after 10 s the top moved < 1 mm. */
static void test_stack_of_five_boxes_stands_ten_seconds(void **state)
{
    (void)state;
    sc_world *w = world_with_plane(0, 1, 0, 0.5);
    sc_shape *s = sc_shape_box(0.1, 0.1, 0.1);
    int top = -1;
    for (int i = 0; i < 5; i++) {
        sc_body_desc d = sc_body_desc_default();
        d.shape = s;
        d.restitution = 0;
        d.pos[2] = 0.1 + 0.2 * i - 0.0005 * (i + 1);
        top = sc_body_add(w, &d);
    }
    double p0[3], p1[3];
    sc_body_get_pose(w, top, p0, NULL);
    for (int n = 0; n < 1000; n++)
        assert_int_equal(sc_world_step(w, DT), SC_OK);
    sc_body_get_pose(w, top, p1, NULL);
    double drift = sqrt((p1[0] - p0[0]) * (p1[0] - p0[0]) + (p1[1] - p0[1]) * (p1[1] - p0[1]) +
                        (p1[2] - p0[2]) * (p1[2] - p0[2]));
    print_message("stack: top drift %.3f mm after 10 s\n", 1000 * drift);
    assert_true(drift < 1e-3);
    sc_shape_release(s);
    sc_world_destroy(w);
}

/* A 0.2 m cube as a triangle mesh with its corner at the origin (as
 * examples/scenes/cube.obj scaled by 0.2): convex, two triangles a face. */
static sc_shape *corner_cube(int hull)
{
    static const int tri[36] = { 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                 3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5 };
    double xyz[24];
    for (int i = 0; i < 8; i++) {
        xyz[3 * i] = (i == 1 || i == 2 || i == 5 || i == 6) ? 0.2 : 0;
        xyz[3 * i + 1] = (i == 2 || i == 3 || i == 6 || i == 7) ? 0.2 : 0;
        xyz[3 * i + 2] = i >= 4 ? 0.2 : 0;
    }
    sc_shape *s = hull ? sc_shape_convex(xyz, 8) : sc_shape_mesh(xyz, 8, tri, 12);
    assert_non_null(s);
    return s;
}

/* n corner cubes dropped 0.2 mm apart onto the floor for 4 s: no interface
 * ever gets deeper than the contact tolerance (ODE's convex-convex collider
 * gives one point; on it the upper cube rocked and sank 10 mm into the
 * lower one), and, from 1 s on, the top cube stays within 0.5 mm. */
static void cube_stack(int hull, int n, int still, int mode)
{
    sc_world *w = world_with_plane_mode(0, 1, 0.5, 0.5, mode);
    sc_shape *s = corner_cube(hull);
    double tol = sc_world_config_default().contact_tol_m;
    int id[3];
    for (int i = 0; i < n; i++) {
        sc_body_desc d = sc_body_desc_default();
        d.shape = s;
        d.pos[2] = 0.0005 + 0.2002 * i;
        id[i] = sc_body_add(w, &d);
    }
    double pen = 0, gap = INFINITY, lo = INFINITY, hi = -INFINITY;
    for (int f = 0; f < 400; f++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        sc_stats st;
        sc_world_stats(w, &st);
        pen = fmax(pen, st.frame.detect.max_penetration);
        double z[3];
        for (int i = 0; i < n; i++) {
            double p[3];
            sc_body_get_pose(w, id[i], p, NULL);
            z[i] = p[2];
        }
        for (int i = 1; i < n; i++)
            gap = fmin(gap, z[i] - z[i - 1] - 0.2);    /* < 0: overlap */
        if (f >= 100) {
            lo = fmin(lo, z[n - 1]);
            hi = fmax(hi, z[n - 1]);
        }
    }
    print_message("%d %s cubes (%s): max penetration %.3f mm, least gap %.3f mm, top moved "
                  "%.3f mm after 1 s\n", n, hull ? "hull" : "mesh",
                  mode == SC_TOI_LOCAL ? "local" : "world", 1000 * pen, 1000 * gap,
                  1000 * (hi - lo));
    assert_true(pen <= tol);
    assert_true(gap >= -tol);
    if (still)
        assert_true(hi - lo <= 0.5e-3);
    sc_shape_release(s);
    sc_world_destroy(w);
}

/* Three stack and stand; two (primitive boxes too) keep hopping a little
 * after they settle, so only their depth is checked. */
static void test_mesh_and_hull_cube_stacks_do_not_sink(void **state)
{
    (void)state;
    for (int hull = 0; hull < 2; hull++) {
        cube_stack(hull, 2, 0, SC_TOI_WORLD);
        cube_stack(hull, 3, 1, SC_TOI_WORLD);
        /* the local mode: a slow pair that got deeper on the rows it had
         * (nothing new to hold it) is searched and backed up as a fast
         * one (held as slow, a mesh stack sank 3.1 mm); and the top cube
         * rests: its collisions with the resting cube below are solved
         * before the resting contacts (contact.c, impacts(); as one LCP
         * it gained g h a bounce and hopped 2.3 mm for ever) */
        cube_stack(hull, 3, 1, SC_TOI_LOCAL);
    }
}

/* The Table 1 box (27 spheres, e = 1) over 5000 frames in toi mode:
 * energy within 0.5 % of the start, never above 1.001 of it. In the local
 * mode a sphere bounced off one neighbour into the next within one
 * substep must back up, not be held there too: held, the two collisions
 * were simultaneous and Newton's restitution on both gained 1.26 %. */
static void table1_energy(int mode)
{
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    assert_int_equal(sc_scene_spheres_box(w), SC_OK);
    double e0 = sc_world_energy(w), worst = 0, peak = 1;
    long collisions = 0;
    for (int n = 0; n < 5000; n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        worst = fmax(worst, fabs(sc_world_energy(w) / e0 - 1));
        peak = fmax(peak, sc_world_energy(w) / e0);
        sc_stats st;
        sc_world_stats(w, &st);
        collisions += st.frame.detect.contacts;
    }
    print_message("Table 1 scene, %s mode: worst |E/E0 - 1| = %.5f, peak %.5f over 5000 frames, "
                  "%ld contact points\n", mode == SC_TOI_LOCAL ? "local" : "world", worst, peak,
                  collisions);
    assert_true(collisions > 0);
    assert_true(worst <= 0.005);
    assert_true(peak <= 1.001);
    sc_world_destroy(w);
}

static void test_table1_spheres_conserve_energy(void **state)
{
    (void)state;
    table1_energy(SC_TOI_WORLD);
}

static void test_table1_spheres_conserve_energy_in_local_mode(void **state)
{
    (void)state;
    table1_energy(SC_TOI_LOCAL);
}

/* bench_energy's elastic box of n UV spheres of radius r at v m/s (e = 1,
 * no friction) over 5000 frames on one worker: its worst drift and peak. */
static void elastic_box(int n, double r, double v, int mode, double *worst, double *peak)
{
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    c.workers = 1;
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    assert_int_equal(sc_scene_elastic_box(w, n, r, v), SC_OK);
    double e0 = sc_world_energy(w);
    *worst = 0;
    *peak = 1;
    for (int f = 0; f < 5000; f++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        double e = sc_world_energy(w) / e0;
        *worst = fmax(*worst, fabs(e - 1));
        *peak = fmax(*peak, e);
    }
    print_message("%d spheres of %.1f m at %.0f m/s, %s: worst |E/E0 - 1| = %.5f, peak %.5f\n", n,
                  r, v, mode == SC_TOI_WORLD ? "world-wide" : "local", *worst, *peak);
    sc_world_destroy(w);
}

/* A crowded elastic box (64 spheres of 0.2 m at 3 m/s) in the world-wide
 * mode: within 0.1 % of its energy over 5000 frames. A perfectly elastic
 * island's answer is checked for energy its restitution adds with each
 * collision at its impact, not at the speed the whole substep's gravity
 * gives (contact.c solve_rows()): checked there, this box drifted
 * 0.21 %. */
static void test_crowded_elastic_box_keeps_its_energy(void **state)
{
    (void)state;
    double worst, peak;
    elastic_box(64, 0.2, 3, SC_TOI_WORLD, &worst, &peak);
    assert_true(worst <= 0.001);
    assert_true(peak <= 1.001);
}

/* The same in the local mode, on the two boxes that lost most there while
 * perfectly elastic collisions were held by speculative contacts (27 and
 * 64 spheres of 0.2 m at 1 m/s: 3.3 % and 1.7 %; impact.c
 * elastic_collision() backs them up to their touch instead): within
 * 0.1 %, never above 1.001. */
static void test_elastic_boxes_keep_their_energy_in_local_mode(void **state)
{
    (void)state;
    const int n[2] = { 27, 64 };
    for (int i = 0; i < 2; i++) {
        double worst, peak;
        elastic_box(n[i], 0.2, 1, SC_TOI_LOCAL, &worst, &peak);
        assert_true(worst <= 0.001);
        assert_true(peak <= 1.001);
    }
}

/* A nut thrown at 1.5 m/s onto a box resting on the floor, tilted so that
 * it lands on an edge: it moves 15 mm in the frame, more than half its
 * feature, so it is a fast pair, and it first touches within the frame.
 * The world-wide mode backs up to the touch; the local mode finds where
 * it touches, holds it there by speculative contacts in the same substep
 * (docs/DESIGN.md 3.4) and does not back up. Both bounce it, neither digs
 * it in past the tolerance, neither gains energy. */
static void nut_on_box(int mode, int *backups, int *spec, double *pen, double *vz, double *gain)
{
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    sc_shape *floor = sc_shape_plane(0, 0, 1, 0), *box = sc_shape_box(0.05, 0.05, 0.01),
             *nut = sc_shape_nut();
    sc_body_desc d = sc_body_desc_default();
    d.shape = floor;
    d.mass = 0;
    assert_int_equal(sc_body_add(w, &d), 0);
    d = sc_body_desc_default();
    d.shape = box;
    d.pos[2] = 0.0101;
    assert_int_equal(sc_body_add(w, &d), 1);
    d = sc_body_desc_default();
    d.shape = nut;
    d.mass = 0.05;
    d.pos[2] = 0.035;
    d.vel[2] = -1.5;
    d.quat[0] = cos(0.2);
    d.quat[1] = sin(0.2);
    int id = sc_body_add(w, &d);
    assert_int_equal(id, 2);
    sc_shape_release(floor);
    sc_shape_release(box);
    sc_shape_release(nut);
    double e0 = sc_world_energy(w);
    *backups = *spec = 0;
    *pen = *gain = 0;
    for (int n = 0; n < 3; n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        sc_stats st;
        sc_world_stats(w, &st);
        if (n == 0) {
            *backups = st.frame.toi.backups;
            *spec = st.frame.toi.spec_contacts;
        }
        *pen = fmax(*pen, st.frame.detect.max_penetration);
        *gain = fmax(*gain, sc_world_energy(w) / e0 - 1);
    }
    double v[3];
    sc_body_get_velocity(w, id, v, NULL);
    *vz = v[2];
    sc_world_destroy(w);
}

static void test_local_mode_holds_a_fast_landing_without_backing_up(void **state)
{
    (void)state;
    int bw, sw, bl, sl;
    double pw, pl, vw, vl, gw, gl;
    nut_on_box(SC_TOI_WORLD, &bw, &sw, &pw, &vw, &gw);
    nut_on_box(SC_TOI_LOCAL, &bl, &sl, &pl, &vl, &gl);
    print_message("nut on a box: world %d back-ups, pen %.3f mm, vz %.3f m/s; local %d back-ups, "
                  "%d speculative contacts, pen %.3f mm, vz %.3f m/s\n",
                  bw, 1e3 * pw, vw, bl, sl, 1e3 * pl, vl);
    assert_true(bw >= 1);              /* the scene does need a time of impact */
    assert_int_equal(bl, 0);           /* held, not backed up */
    assert_true(sl > 0);
    assert_true(pw <= 1e-3 && pl <= 1e-3);
    assert_true(vw > 0.1 && vl > 0.1); /* it bounced */
    assert_true(gw <= 1e-9 && gl <= 1e-9);
}

/* The state machine: free -> colliding -> contact -> asleep; a sleeping
 * body is woken by a body hitting it and by a push. */
/* A box settled asleep on the floor (returned in *a), a second box
 * dropped on its edge, off centre, and 100 frames stepped: returns how
 * far the first moved along x. keep_awake: the first gets a zero force
 * every frame (awake all along); *woke: whether it ever woke. */
static sc_world *knock(int mode, int keep_awake, int *a, double *moved, int *woke)
{
    /* boxes: a ball knocked sideways would roll forever (no rolling
     * resistance), a box stops by friction */
    sc_world *w = world_with_plane_mode(0, 1, 0.5, 0.5, mode);
    sc_shape *s = sc_shape_box(0.1, 0.1, 0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.pos[2] = 0.5;
    *a = sc_body_add(w, &d);
    assert_int_equal(sc_body_state(w, *a), SC_FREE);
    int seen[4] = { 0 };
    for (int n = 0; n < 300; n++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        int st = sc_body_state(w, *a);
        assert_true(st >= SC_FREE && st <= SC_ASLEEP);
        seen[st] = 1;
    }
    assert_true(seen[SC_FREE] && seen[SC_COLLIDING] && seen[SC_CONTACT] && seen[SC_ASLEEP]);
    assert_int_equal(sc_body_state(w, *a), SC_ASLEEP);
    assert_true(sc_world_at_rest(w));
    d.pos[2] = 0.6;
    d.pos[0] = 0.12;
    d.quat[0] = cos(0.3);
    d.quat[2] = sin(0.3);
    sc_body_add(w, &d);
    assert_false(sc_world_at_rest(w));
    double p0[3], p1[3], zero[3] = { 0, 0, 0 };
    sc_body_get_pose(w, *a, p0, NULL);
    *woke = 0;
    for (int n = 0; n < 100; n++) {
        if (keep_awake)
            assert_int_equal(sc_body_apply_force(w, *a, zero, NULL), SC_OK);
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        *woke |= sc_body_state(w, *a) != SC_ASLEEP;
    }
    sc_body_get_pose(w, *a, p1, NULL);
    *moved = p1[0] - p0[0];
    sc_shape_release(s);
    return w;
}

/* A body falls, collides, rests and sleeps; a box falling on it wakes it,
 * and moves it as it moves an awake one: sleep changes nothing (the
 * world-wide mode once solved the woken sleeper without its floor and
 * shoved it 48 mm where an awake one stays put); then both settle and
 * sleep, and a push wakes a sleeper. */
static void sleep_and_wake(int mode)
{
    int a, woke, woke_awake;
    double moved, moved_awake;
    sc_world *w = knock(mode, 0, &a, &moved, &woke);
    sc_world_destroy(knock(mode, 1, &a, &moved_awake, &woke_awake));
    print_message("%s: a sleeper hit moved %.3f mm, an awake box %.3f mm\n",
                  mode == SC_TOI_LOCAL ? "local" : "world", 1e3 * moved, 1e3 * moved_awake);
    assert_true(woke);
    assert_true(fabs(moved - moved_awake) < 1e-3);
    for (int n = 0; n < 1000 && !sc_world_at_rest(w); n++)
        assert_int_equal(sc_world_step(w, DT), SC_OK);
    assert_true(sc_world_at_rest(w));
    /* a push wakes a sleeper */
    int b = a + 1;
    double f[3] = { 5, 0, 0 };
    assert_int_equal(sc_body_apply_force(w, b, f, NULL), SC_OK);
    assert_int_not_equal(sc_body_state(w, b), SC_ASLEEP);
    assert_int_equal(sc_world_step(w, DT), SC_OK);
    double v[3];
    sc_body_get_velocity(w, b, v, NULL);
    assert_true(v[0] > 0);
    sc_world_destroy(w);
}

static void test_states_sleep_and_wake(void **state)
{
    (void)state;
    sleep_and_wake(SC_TOI_WORLD);
    sleep_and_wake(SC_TOI_LOCAL);
}

/* The paper's experiment at N = 50: energy never grows by more than 1 %,
 * penetration stays within 1 mm, everything rests within 10 s simulated. */
static void fifty_bolts_and_nuts(int motion_groups)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.motion_groups = motion_groups;
    sc_world *w = sc_world_create(&cfg);
    assert_int_equal(sc_scene_bolts_nuts(w, 50, 1), SC_OK);
    double e0 = sc_world_energy(w), peak = e0, pen = 0;
    int frames = 0, fallbacks = 0;
    while (!sc_world_at_rest(w) && frames < 1000) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        frames++;
        sc_stats st;
        sc_world_stats(w, &st);
        pen = fmax(pen, st.frame.detect.max_penetration);
        peak = fmax(peak, sc_world_energy(w));
        fallbacks += st.frame.lcp.fallbacks;
    }
    /* islands whose friction LCP failed and were solved frictionless are
     * reported, not hidden (an open item of the solver) */
    print_message("50 bodies%s: at rest after %.2f s, peak energy / initial %.6f, "
                  "max penetration %.3f mm, friction fallbacks %d\n",
                  motion_groups ? " (motion groups)" : "", frames * DT, peak / e0, 1000 * pen,
                  fallbacks);
    assert_true(sc_world_at_rest(w));
    assert_true(frames * DT <= 10.0);
    assert_true(peak <= 1.01 * e0);
    assert_true(pen <= 1e-3);
    sc_world_destroy(w);
}

static void test_fifty_bolts_and_nuts_drop_stably_and_come_to_rest(void **state)
{
    (void)state;
    fifty_bolts_and_nuts(0);
}

/* The same with motion groups: every group backs up on its own. */
static void test_fifty_bolts_and_nuts_in_motion_groups(void **state)
{
    (void)state;
    fifty_bolts_and_nuts(1);
}

/* A bolt thrown tumbling (31 rad/s about an axis far from its principal
 * ones) in zero gravity: a torque-free body keeps its kinetic energy and
 * its angular momentum in the world, and over 1000 frames it does to
 * rounding. (The explicit gyroscopic step kept 27 % of the energy after
 * 1 s and lost 55 % of |L|; docs/DESIGN.md 3.6.) */
static void test_tumbling_bolt_keeps_energy_and_angular_momentum(void **state)
{
    (void)state;
    sc_world_config c = sc_world_config_default();
    c.gravity[2] = 0;
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    sc_body_desc d = sc_body_desc_default();
    d.shape = sc_shape_bolt();
    d.mass = SC_MASS_FROM_DENSITY;
    d.density = 7800;
    d.omega[0] = 30;
    d.omega[1] = 7;
    d.omega[2] = 3;
    int id = sc_body_add(w, &d);
    assert_true(id >= 0);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(d.shape, &mp), SC_OK);
    sc_shape_release(d.shape);
    double e0 = sc_world_energy(w), L0[3] = { 0, 0, 0 }, emax = 0, lmax = 0;
    for (int f = 0; f <= 1000; f++) {
        /* L = R I R^T w, I per unit density times the density */
        double pos[3], q[4], v[3], om[3], R[9], wb[3], L[3] = { 0, 0, 0 };
        sc_body_get_pose(w, id, pos, q);
        sc_body_get_velocity(w, id, v, om);
        double ww = q[0], x = q[1], y = q[2], z = q[3];
        double Rm[9] = { 1 - 2 * (y * y + z * z), 2 * (x * y - ww * z), 2 * (x * z + ww * y),
                         2 * (x * y + ww * z), 1 - 2 * (x * x + z * z), 2 * (y * z - ww * x),
                         2 * (x * z - ww * y), 2 * (y * z + ww * x), 1 - 2 * (x * x + y * y) };
        for (int i = 0; i < 9; i++)
            R[i] = Rm[i];
        for (int i = 0; i < 3; i++)
            wb[i] = R[i] * om[0] + R[3 + i] * om[1] + R[6 + i] * om[2];
        double Ib[3];
        for (int i = 0; i < 3; i++)
            Ib[i] = 7800 * (mp.inertia[3 * i] * wb[0] + mp.inertia[3 * i + 1] * wb[1] +
                            mp.inertia[3 * i + 2] * wb[2]);
        for (int i = 0; i < 3; i++)
            L[i] = R[3 * i] * Ib[0] + R[3 * i + 1] * Ib[1] + R[3 * i + 2] * Ib[2];
        if (f == 0)
            for (int i = 0; i < 3; i++)
                L0[i] = L[i];
        double dl = sqrt((L[0] - L0[0]) * (L[0] - L0[0]) + (L[1] - L0[1]) * (L[1] - L0[1]) +
                         (L[2] - L0[2]) * (L[2] - L0[2])) /
                    sqrt(L0[0] * L0[0] + L0[1] * L0[1] + L0[2] * L0[2]);
        emax = fmax(emax, fabs(sc_world_energy(w) / e0 - 1));
        lmax = fmax(lmax, dl);
        if (f < 1000)
            assert_int_equal(sc_world_step(w, DT), SC_OK);
    }
    print_message("tumbling bolt, 1000 frames: energy within %.1e, angular momentum within %.1e\n",
                  emax, lmax);
    assert_true(emax < 1e-9);
    assert_true(lmax < 1e-9);
    sc_world_destroy(w);
}

/* One frame of a 0.2 m box placed depth below the surface of a
 * frictionless floor, sliding at 0.5 m/s along x and spinning at spin
 * rad/s about the vertical: how far it was lifted, its energy's change,
 * its speed along x and its spin after the frame. */
static void push_out_frame(double depth, double spin, double *lift, double *de, double *vx,
                           double *wz)
{
    sc_world *w = world_with_plane(0, 1, 0, 0);
    sc_shape *s = sc_shape_box(0.1, 0.1, 0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.restitution = 0;
    d.friction = 0;
    d.pos[2] = 0.1 - depth;
    d.vel[0] = 0.5;
    d.omega[2] = spin;
    int id = sc_body_add(w, &d);
    assert_true(id > 0);
    sc_shape_release(s);
    double e0 = sc_world_energy(w), p0[3], p1[3], v[3], om[3];
    sc_body_get_pose(w, id, p0, NULL);
    assert_int_equal(sc_world_step(w, DT), SC_OK);
    sc_body_get_pose(w, id, p1, NULL);
    sc_body_get_velocity(w, id, v, om);
    *lift = p1[2] - p0[2];
    *de = sc_world_energy(w) - e0;
    *vx = v[0];
    *wz = om[2];
    sc_world_destroy(w);
}

/* The push-out never adds energy (docs/DESIGN.md 3.5). A box 0.9 mm in
 * the floor (past the 0.5 mm slop) that spins is lifted, and the lift's
 * potential energy comes out of its spin, not out of its slide: the
 * world's energy does not rise and the box slides on at 0.5 m/s (pushed
 * out by the positions alone, the energy rose by m g dz; paid from every
 * velocity, a push on a resting part was eaten). Without a spin the same
 * box is not lifted at all: a resting part lifted for free at every
 * substep is what kept a nut rocking in a bin of 200. A box 1.5 mm deep
 * (past twice the slop: placed overlapping) is pushed out whatever it
 * costs, to within the contact tolerance in one frame (all of the depth
 * past it at once, a fifth of the rest). */
static void test_push_out_adds_no_energy(void **state)
{
    (void)state;
    double lift, de, vx, wz;
    push_out_frame(0.9e-3, 5, &lift, &de, &vx, &wz);
    print_message("box 0.9 mm in the floor, spinning: lifted %.4f mm, energy %+.3e J, "
                  "slide %.9f m/s, spin 5 -> %.6f rad/s\n",
                  1e3 * lift, de, vx, wz);
    assert_true(lift > 1e-5);                 /* pushed out: the lift happened */
    assert_true(de <= 1e-12);
    assert_true(fabs(vx - 0.5) < 1e-12);      /* the slide paid nothing */
    assert_true(wz < 5 && wz > 4);            /* the spin paid */
    push_out_frame(0.9e-3, 0, &lift, &de, &vx, &wz);
    print_message("box 0.9 mm in the floor, sliding only: lifted %.4f mm, energy %+.3e J\n",
                  1e3 * lift, de);
    assert_true(fabs(lift) < 1e-12);
    assert_true(de <= 1e-12);
    assert_true(fabs(vx - 0.5) < 1e-12);
    push_out_frame(1.5e-3, 0, &lift, &de, &vx, &wz);
    print_message("box 1.5 mm in the floor: lifted %.4f mm\n", 1e3 * lift);
    assert_true(lift >= 1.5e-3 - sc_world_config_default().contact_tol_m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tumbling_bolt_keeps_energy_and_angular_momentum),
        cmocka_unit_test(test_push_out_adds_no_energy),
        cmocka_unit_test(test_ball_rebounds_to_e_squared_height),
        cmocka_unit_test(test_held_ball_rebounds_to_e_squared_height),
        cmocka_unit_test(test_sliding_box_stops_after_v2_over_2_mu_g),
        cmocka_unit_test(test_box_on_slope_below_friction_angle_stays),
        cmocka_unit_test(test_box_on_slope_above_friction_angle_slides),
        cmocka_unit_test(test_states_sleep_and_wake),
        cmocka_unit_test(test_stack_of_five_boxes_stands_ten_seconds),
        cmocka_unit_test(test_mesh_and_hull_cube_stacks_do_not_sink),
        cmocka_unit_test(test_table1_spheres_conserve_energy),
        cmocka_unit_test(test_table1_spheres_conserve_energy_in_local_mode),
        cmocka_unit_test(test_crowded_elastic_box_keeps_its_energy),
        cmocka_unit_test(test_elastic_boxes_keep_their_energy_in_local_mode),
        cmocka_unit_test(test_local_mode_holds_a_fast_landing_without_backing_up),
        cmocka_unit_test(test_fifty_bolts_and_nuts_drop_stably_and_come_to_rest),
        cmocka_unit_test(test_fifty_bolts_and_nuts_in_motion_groups),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
