/* test_scene_file.c - scene files (lib/api/scene_file.c, simcluster.conf(5)):
 * what each keyword builds, checked against the same world built by hand
 * with the public API (same hash), grids and rotations, world settings,
 * meshes named relative to the scene file, and every kind of bad input
 * with its FILE:LINE:COLUMN message and code. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "simcluster.h"

static sc_scene *parse(const char *text, char *err, size_t errlen)
{
    return sc_scene_parse(text, strlen(text), "t", NULL, err, errlen);
}

static sc_world *build(const sc_scene *s)
{
    sc_world_config c = sc_world_config_default();
    c.workers = 1;
    sc_scene_config(s, &c);
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    assert_int_equal(sc_scene_build(s, w), SC_OK);
    return w;
}

static void test_scene_builds_what_the_api_builds_by_hand(void **state)
{
    (void)state;
    char err[256];
    sc_scene *s = parse("# two kinds of body on a floor\n"
                        "material steel density 7800 restitution 0.3 friction 0.4\n"
                        "shape floor plane 0 0 1 0\n"
                        "shape ball sphere 0.05\n"
                        "shape crate box 0.1 0.2 0.05   # half extents\n"
                        "body floor\n"
                        "body ball material steel pos 0 0 1 vel 1 0 0 omega 0 0 2\n"
                        "body crate mass 3 pos 1 0 0.5 quat 0 0 0 1 friction 0.9\n",
                        err, sizeof err);
    assert_non_null(s);
    assert_string_equal(err, "");
    assert_int_equal(sc_scene_body_count(s), 3);
    sc_world *a = build(s);

    sc_world_config c = sc_world_config_default();
    c.workers = 1;
    sc_world *b = sc_world_create(&c);
    sc_shape *fl = sc_shape_plane(0, 0, 1, 0), *ball = sc_shape_sphere(0.05),
             *crate = sc_shape_box(0.1, 0.2, 0.05);
    sc_body_desc d = sc_body_desc_default();
    d.shape = fl;
    d.mass = 0;
    assert_true(sc_body_add(b, &d) >= 0);
    d = sc_body_desc_default();
    d.shape = ball;
    d.mass = SC_MASS_FROM_DENSITY;
    d.density = 7800;
    d.restitution = 0.3;
    d.friction = 0.4;
    d.pos[2] = 1;
    d.vel[0] = 1;
    d.omega[2] = 2;
    assert_true(sc_body_add(b, &d) >= 0);
    d = sc_body_desc_default();
    d.shape = crate;
    d.mass = 3;
    d.pos[0] = 1;
    d.pos[2] = 0.5;
    d.quat[0] = 0;
    d.quat[3] = 1;
    d.friction = 0.9;
    assert_true(sc_body_add(b, &d) >= 0);
    assert_int_equal(sc_body_state(a, 0), SC_STATIC);
    /* same bodies, and the same motion over 100 frames */
    for (int f = 0; f < 100; f++) {
        assert_int_equal(sc_world_hash(a), sc_world_hash(b));
        assert_int_equal(sc_world_step(a, 0.01), SC_OK);
        assert_int_equal(sc_world_step(b, 0.01), SC_OK);
    }
    assert_int_equal(sc_world_hash(a), sc_world_hash(b));
    sc_shape_release(fl);
    sc_shape_release(ball);
    sc_shape_release(crate);
    sc_world_destroy(a);
    sc_world_destroy(b);
    sc_scene_free(s);
}

static void test_grid_rot_and_world_settings(void **state)
{
    (void)state;
    sc_scene *s = parse("gravity 0 0 -1.62\ntolerance 0.002\n"
                        "shape c box 0.05 0.05 0.05\n"
                        "body c pos 1 2 3 rot 0 0 2 90 grid 3 2 2 0.5 0.25 1\n",
                        NULL, 0);
    assert_non_null(s);
    assert_int_equal(sc_scene_body_count(s), 12);
    sc_world_config c = sc_world_config_default();
    sc_scene_config(s, &c);
    assert_true(c.gravity[0] == 0 && c.gravity[1] == 0 && c.gravity[2] == -1.62);
    assert_true(c.contact_tol_m == 0.002);
    sc_world *w = build(s);
    assert_int_equal(sc_world_body_count(w), 12);
    for (int i = 0; i < 12; i++) {       /* x fastest, then y, then z */
        double p[3], q[4];
        sc_body_get_pose(w, i, p, q);
        assert_true(fabs(p[0] - (1 + 0.5 * (i % 3))) < 1e-12);
        assert_true(fabs(p[1] - (2 + 0.25 * (i / 3 % 2))) < 1e-12);
        assert_true(fabs(p[2] - (3 + (i / 6))) < 1e-12);
        /* 90 degrees about z, whatever the axis' length */
        assert_true(fabs(q[0] - sqrt(0.5)) < 1e-12 && fabs(q[3] - sqrt(0.5)) < 1e-12);
        assert_true(fabs(q[1]) < 1e-12 && fabs(q[2]) < 1e-12);
    }
    /* the scene's gravity: a free body falls at 1.62 m/s^2 */
    assert_int_equal(sc_world_step(w, 0.1), SC_OK);
    double v[3], om[3];
    sc_body_get_velocity(w, 0, v, om);
    assert_true(fabs(v[2] + 0.162) < 1e-9);
    sc_world_destroy(w);
    /* without the keywords, the caller's settings stay */
    sc_scene_free(s);
    s = parse("shape c sphere 1\nbody c\n", NULL, 0);
    c = sc_world_config_default();
    c.gravity[2] = -3;
    sc_scene_config(s, &c);
    assert_true(c.gravity[2] == -3 && c.contact_tol_m == sc_world_config_default().contact_tol_m);
    sc_scene_free(s);
}

static void test_mass_from_density_and_defaults(void **state)
{
    (void)state;
    /* a 0.1 m sphere of density 1000: 4.18879 kg. Push it up with 100 N for
     * a frame in zero gravity: dv = 100 / m * dt */
    sc_scene *s = parse("gravity 0 0 0\nmaterial water density 1000\nshape s sphere 0.1\n"
                        "body s material water\nbody s density 2000 pos 1 0 0\n"
                        "body s pos 2 0 0\nbody s mass 5 material water pos 3 0 0\n",
                        NULL, 0);
    assert_non_null(s);
    sc_world *w = build(s);
    const double up[3] = { 0, 0, 100 }, vol = 4.0 / 3 * M_PI * 1e-3;
    const double want[4] = { 1000 * vol, 2000 * vol, 1.0 /* the default body */, 5 };
    for (int i = 0; i < 4; i++)
        assert_int_equal(sc_body_apply_force(w, i, up, NULL), SC_OK);
    assert_int_equal(sc_world_step(w, 0.01), SC_OK);
    for (int i = 0; i < 4; i++) {
        double v[3], om[3];
        sc_body_get_velocity(w, i, v, om);
        assert_true(fabs(v[2] - 100 / want[i] * 0.01) < 1e-9 * (1 + v[2]));
    }
    sc_world_destroy(w);
    sc_scene_free(s);
}

/* A unit cube, outward faces. */
static void write_cube_obj(const char *path)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
          "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 8 7\nf 4 7 3\n"
          "f 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n",
          f);
    assert_int_equal(fclose(f), 0);
}

static void test_meshes_are_found_next_to_the_scene_file(void **state)
{
    (void)state;
    char dir[] = "/tmp/sc_scene_XXXXXX", path[256], scene[256];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/sub", dir);
    assert_int_equal(mkdir(path, 0700), 0);
    snprintf(path, sizeof path, "%s/sub/cube.obj", dir);
    write_cube_obj(path);
    snprintf(scene, sizeof scene, "%s/s.scene", dir);
    FILE *f = fopen(scene, "w");
    assert_non_null(f);
    fputs("shape c mesh sub/cube.obj\nshape big mesh \"sub/cube.obj\" scale 0.5\n"
          "shape h hull sub/cube.obj\n"
          "body c pos 0 0 0\nbody big pos 5 0 0\nbody h pos 9 0 0\n",
          f);
    assert_int_equal(fclose(f), 0);
    char err[256];
    sc_scene *s = sc_scene_load(scene, err, sizeof err);   /* cwd is elsewhere */
    assert_non_null(s);
    sc_world *w = build(s);
    assert_int_equal(sc_shape_kind(sc_body_shape(w, 0)), SC_SHAPE_MESH);
    assert_int_equal(sc_shape_triangles(sc_body_shape(w, 0)), 12);
    assert_true(fabs(sc_shape_bounding_radius(sc_body_shape(w, 1)) -
                     0.5 * sc_shape_bounding_radius(sc_body_shape(w, 0))) < 1e-12);
    assert_int_equal(sc_shape_kind(sc_body_shape(w, 2)), SC_SHAPE_CONVEX);
    sc_world_destroy(w);
    sc_scene_free(s);
    /* a missing mesh names the scene line and the path it tried */
    f = fopen(scene, "w");
    assert_non_null(f);
    fputs("\n  shape c mesh gone.obj\n", f);
    assert_int_equal(fclose(f), 0);
    assert_null(sc_scene_load(scene, err, sizeof err));
    assert_int_equal(sc_last_error(), SC_EIO);
    char want[512];
    snprintf(want, sizeof want, "%s:2:16: %s/gone.obj: No such file or directory", scene, dir);
    assert_string_equal(err, want);
    /* a malformed mesh: the scene's line and column, then the mesh's line */
    char bad[300];
    snprintf(bad, sizeof bad, "%s/badv.obj", dir);
    f = fopen(bad, "w");
    assert_non_null(f);
    fputs("v 0 0 0\nv 0 1 abc\n", f);
    assert_int_equal(fclose(f), 0);
    f = fopen(scene, "w");
    assert_non_null(f);
    fputs("shape m mesh badv.obj\n", f);
    assert_int_equal(fclose(f), 0);
    assert_null(sc_scene_load(scene, err, sizeof err));
    assert_int_equal(sc_last_error(), SC_EFORMAT);
    snprintf(want, sizeof want, "%s:1:14: %s/badv.obj:2: bad vertex coordinate", scene, dir);
    assert_string_equal(err, want);
    unlink(bad);
    unlink(scene);
    unlink(path);
    snprintf(path, sizeof path, "%s/sub", dir);
    rmdir(path);
    rmdir(dir);
    /* not a file at all */
    assert_null(sc_scene_load("/nonexistent/x.scene", err, sizeof err));
    assert_int_equal(sc_last_error(), SC_EIO);
    assert_string_equal(err, "/nonexistent/x.scene: No such file or directory");
    assert_null(sc_scene_load("/tmp", err, sizeof err));
    assert_string_equal(err, "/tmp: not a regular file");
}

static void test_errors_name_line_column_and_code(void **state)
{
    (void)state;
    static const struct { const char *text, *msg; int code; } cases[] = {
        { "body x\n", "t:1:6: no shape named 'x' (define it above with shape)", SC_EINVAL },
        { "shape a sphere 0.1\nbody a pos 1 2\n", "t:2:15: missing position (m)", SC_EFORMAT },
        { "shape a sphere 1.5x\n", "t:1:16: radius (m): '1.5x' is not a finite number",
          SC_EFORMAT },
        { "shape a sphere nan\n", "t:1:16: radius (m): 'nan' is not a finite number",
          SC_EFORMAT },
        { "shape a sphere 1e999\n", "t:1:16: radius (m): '1e999' is not a finite number",
          SC_EFORMAT },
        { "shape a sphere -1\n", "t:1:16: radius (m): -1 is out of range [1e-06, 1e+06]",
          SC_EINVAL },
        { "shape a sphere 0.1\n\tshape a box 1 1 1\n", "t:2:8: shape 'a' is already defined",
          SC_EINVAL },
        { "shape a sphere 0.1\nbody a mass 1 static\n",
          "t:2:6: give one of static, mass and density", SC_EINVAL },
        { "shape a sphere 0.1\nbody a pos 0 0 0 pos 1 1 1\n", "t:2:18: 'pos' given twice",
          SC_EINVAL },
        { "shape a sphere 0.1\nbody a quat 1 0 0 0 rot 1 0 0 5\n",
          "t:2:6: give quat or rot, not both", SC_EINVAL },
        { "shape a sphere 0.1\nbody a quat 0 0 0 0\n", "t:2:13: the quaternion is zero",
          SC_EINVAL },
        { "shape a sphere 0.1\nbody a grid 2 2 1.5 1 1 1\n",
          "t:2:17: grid count: a whole number is needed", SC_EINVAL },
        { "shape a sphere 0.1\nbody a spin 3\n",
          "t:2:8: unknown body option 'spin' (material, static, mass, density, pos, quat, rot, "
          "vel, omega, restitution, friction, grid)",
          SC_EFORMAT },
        { "shape p plane 0 0 0 1\n", "t:1:15: the plane's normal is zero", SC_EINVAL },
        { "shape p plane 0 0 1 0\nbody p vel 1 0 0\n",
          "t:2:6: a plane cannot move: it takes no mass, density or velocity", SC_EINVAL },
        { "shape a cone 1\n",
          "t:1:9: unknown shape kind 'cone' (sphere, box, plane, uvsphere, bolt, nut, mesh, "
          "hull)",
          SC_EFORMAT },
        { "shape a sphere 0.1 0.2\n", "t:1:20: unexpected '0.2'", SC_EFORMAT },
        { "shape a box 1 1 1 scale 2\n",
          "t:1:19: scale is for meshes (uvsphere, bolt, nut, mesh, hull); give the size instead",
          SC_EINVAL },
        { "shape a\"b sphere 1\n", "t:1:8: a quote inside a word", SC_EFORMAT },
        { "shape \"a sphere 1\n", "t:1:7: unterminated quote", SC_EFORMAT },
        { "shape \"a\"b sphere 1\n", "t:1:10: a blank must follow a closing quote", SC_EFORMAT },
        { "shape a/b sphere 1\n", "t:1:7: a shape name has only letters, digits, _ . -",
          SC_EINVAL },
        { "material m density 1 density 2\n", "t:1:22: 'density' given twice", SC_EINVAL },
        { "material m colour red\n",
          "t:1:12: unknown material property 'colour' (density, restitution, friction)",
          SC_EFORMAT },
        { "shape a sphere 1\nbody a material none\n", "t:2:17: no material named 'none'",
          SC_EINVAL },
        { "Body a\n",
          "t:1:1: unknown keyword 'Body' (gravity, tolerance, material, shape, body)",
          SC_EFORMAT },
        { "# nothing\n\n", "t:2:1: no bodies (add a body line)", SC_EFORMAT },
        { "", "t:1:1: no bodies (add a body line)", SC_EFORMAT },
        { "gravity 0 0\n", "t:1:12: missing gravity", SC_EFORMAT },
        { "tolerance 0\n", "t:1:11: tolerance (m): 0 is out of range [1e-09, 1]", SC_EINVAL },
        { "shape a sphere 1\nbody a grid 1000 1000 1 1 1 1\n", "t:2:1: more than 100000 bodies",
          SC_ETOOBIG },
        { "shape u uvsphere 1 2 4\n", "t:1:20: slices: 2 is out of range [3, 1000]", SC_EINVAL },
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char err[256];
        sc_scene *s = parse(cases[i].text, err, sizeof err);
        if (s || strcmp(err, cases[i].msg) || sc_last_error() != cases[i].code)
            fail_msg("case %zu: got '%s' code %d, want '%s' code %d", i, err, sc_last_error(),
                     cases[i].msg, cases[i].code);
    }
}

static void test_hostile_text(void **state)
{
    (void)state;
    char err[256];
    /* a NUL inside the text */
    static const char nul[] = "shape a sphere 1\nbody\0 a\n";
    assert_null(sc_scene_parse(nul, sizeof nul - 1, "t", NULL, err, sizeof err));
    assert_string_equal(err, "t:2:5: a NUL byte (is this a text file?)");
    /* no NUL terminator: the text ends at len, mid-word */
    static const char cut[] = "shape a sphere 1\nbody a pos 1 2 3X";
    sc_scene *s = sc_scene_parse(cut, sizeof cut - 2, "t", NULL, err, sizeof err);
    assert_non_null(s);
    sc_scene_free(s);
    /* 33 words on a line, a 5000-byte word */
    char line[6000] = "shape a sphere 1\nbody a";
    for (int i = 0; i < 31; i++)
        strcat(line, " x");
    assert_null(parse(line, err, sizeof err));
    assert_string_equal(err, "t:2:68: more than 32 words on one line");
    memset(line, 'a', sizeof line - 1);
    line[sizeof line - 1] = 0;
    assert_null(parse(line, err, sizeof err));
    assert_string_equal(err, "t:1:1: a word longer than 4095 characters");
    assert_int_equal(sc_last_error(), SC_ETOOBIG);
    /* a short buffer gets a truncated, terminated message; none at all is fine */
    char tiny[8];
    assert_null(parse("bogus\n", tiny, sizeof tiny));
    assert_string_equal(tiny, "t:1:1: ");
    assert_null(parse("bogus\n", NULL, 0));
    assert_null(sc_scene_parse(NULL, 5, "t", NULL, err, sizeof err));
    assert_int_equal(sc_last_error(), SC_EINVAL);
    /* NULLs elsewhere */
    assert_int_equal(sc_scene_build(NULL, NULL), SC_EINVAL);
    assert_int_equal(sc_scene_body_count(NULL), 0);
    sc_scene_config(NULL, NULL);
    sc_scene_free(NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scene_builds_what_the_api_builds_by_hand),
        cmocka_unit_test(test_grid_rot_and_world_settings),
        cmocka_unit_test(test_mass_from_density_and_defaults),
        cmocka_unit_test(test_meshes_are_found_next_to_the_scene_file),
        cmocka_unit_test(test_errors_name_line_column_and_code),
        cmocka_unit_test(test_hostile_text),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
