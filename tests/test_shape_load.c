/* test_shape_load.c - mesh files: OBJ, ASCII STL and binary STL parsed from
 * memory (sc_mesh_parse) and loaded from disk (sc_shape_load), and every
 * way a file can be refused. Files go to a mkdtemp directory removed at the
 * end. */
#include <fcntl.h>
#include <ftw.h>
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
#include "core.h"    /* sc_mesh_parse */

/* The unit cube [0,1]^3, outward counter-clockwise triangles. */
static const double cube_xyz[] = { 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,
                                   0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1 };
static const int cube_tri[] = { 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7 };

static const char cube_obj[] =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
    "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\n"
    "f 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

/* The same cube as quads (fanned to the triangles above), with every
 * corner form, negative indices, CRLF, comments and ignored statements. */
static const char cube_quads_obj[] =
    "# unit cube\r\nmtllib cube.mtl\r\no cube\r\n"
    "v 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0 1.0\r\n"
    "v 0 0 1\r\nv 1 0 1\r\nv 1 1 1\r\nv 0 1 1   # last vertex\r\n"
    "vt 0 0\r\nvt 1 0\r\nvn 0 0 -1\r\nvn 0 0 1\r\ng box\r\nusemtl steel\r\ns off\r\n"
    "f 1/1 4/2 3/1 2/2\r\n"
    "f -4//2 -3//2 -2//2 -1//2\r\n"
    "f 1/1/1 2/2/1 6/1/1 5/2/1\r\n"
    "\r\n\t   \r\n"
    "f 2 3 7 6\r\nf 3 4 8 7\r\nf -5 -8 -4 -1\r\n"
    "l 1 2\r\np 3\r\n";

typedef struct fixture {
    char dir[64];
} fixture;

static int group_setup(void **state)
{
    fixture *fx = calloc(1, sizeof *fx);
    if (!fx)
        return -1;
    snprintf(fx->dir, sizeof fx->dir, "/tmp/sc_test_load_XXXXXX");
    if (!mkdtemp(fx->dir)) {
        free(fx);
        return -1;
    }
    *state = fx;
    return 0;
}

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st;
    (void)flag;
    (void)ftw;
    return remove(path);
}

static int group_teardown(void **state)
{
    fixture *fx = *state;
    int rc = nftw(fx->dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
    free(fx);
    return rc;
}

/* Writes len bytes to dir/name; the path goes to out (PATH_MAX-free). */
static void write_file(void **state, const char *name, const void *data, size_t len,
                       char *out, size_t outlen)
{
    fixture *fx = *state;
    snprintf(out, outlen, "%s/%s", fx->dir, name);
    FILE *f = fopen(out, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, len, f), len);
    assert_int_equal(fclose(f), 0);
}

/* ---- STL writers --------------------------------------------------------- */

static size_t ascii_stl(char *out, size_t cap, const double *xyz, const int *tri, int ntris)
{
    size_t n = (size_t)snprintf(out, cap, "solid cube\n");
    for (int t = 0; t < ntris; t++) {
        n += (size_t)snprintf(out + n, cap - n, "  facet normal 0 0 0\n    outer loop\n");
        for (int k = 0; k < 3; k++) {
            const double *p = &xyz[3 * tri[3 * t + k]];
            n += (size_t)snprintf(out + n, cap - n, "      vertex %.17g %.17g %.17g\n", p[0],
                                  p[1], p[2]);
        }
        n += (size_t)snprintf(out + n, cap - n, "    endloop\n  endfacet\n");
    }
    n += (size_t)snprintf(out + n, cap - n, "endsolid cube\n");
    assert_true(n < cap);
    return n;
}

static void put_le32(unsigned char *b, uint32_t u)
{
    for (int i = 0; i < 4; i++)
        b[i] = (unsigned char)(u >> (8 * i));
}

static void put_float(unsigned char *b, float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    put_le32(b, u);
}

/* A binary STL (malloc'd, *len bytes); header "solid ..." when solid. */
static unsigned char *binary_stl(const double *xyz, const int *tri, int ntris, int solid,
                                 size_t *len)
{
    *len = 84 + 50 * (size_t)ntris;
    unsigned char *b = calloc(1, *len);
    assert_non_null(b);
    memcpy(b, solid ? "solid cube exported by a tool that lies" : "binary cube", 11);
    put_le32(b + 80, (uint32_t)ntris);
    for (int t = 0; t < ntris; t++) {
        unsigned char *f = b + 84 + 50 * (size_t)t;
        put_float(f, NAN);                     /* the normal is ignored */
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++)
                put_float(f + 12 + 12 * k + 4 * j, (float)xyz[3 * tri[3 * t + k] + j]);
    }
    return b;
}

/* ---- checks ---------------------------------------------------------------- */

static int parse_str(const char *s, double **xyz, int *nv, int **tri, int *nt)
{
    return sc_mesh_parse(s, strlen(s), xyz, nv, tri, nt);
}

static int parse_code(const void *buf, size_t len)
{
    double *xyz = (double *)&xyz;
    int *tri = (int *)&tri, nv = -1, nt = -1;
    int rc = sc_mesh_parse(buf, len, &xyz, &nv, &tri, &nt);
    if (rc != SC_OK) {
        /* a failed parse leaves nothing to free */
        assert_null(xyz);
        assert_null(tri);
        assert_int_equal(nv, 0);
        assert_int_equal(nt, 0);
    }
    free(xyz);
    free(tri);
    return rc;
}

static int parse_str_code(const char *s)
{
    return parse_code(s, strlen(s));
}

/* Welded STL output: the 8 corners once each, and every triangle's corners
 * are those of the source triangle (same order). */
static void assert_welded_cube(const double *xyz, int nv, const int *tri, int nt)
{
    assert_int_equal(nv, 8);
    assert_int_equal(nt, 12);
    for (int i = 0; i < nv; i++)
        for (int j = 0; j < i; j++)
            assert_false(memcmp(&xyz[3 * i], &xyz[3 * j], 3 * sizeof *xyz) == 0);
    for (int t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            int v = tri[3 * t + k];
            assert_true(v >= 0 && v < nv);
            for (int j = 0; j < 3; j++)
                assert_true(xyz[3 * v + j] == cube_xyz[3 * cube_tri[3 * t + k] + j]);
        }
}

static void assert_unit_cube_shape(sc_shape *s)
{
    assert_non_null(s);
    sc_mass_props mp;
    assert_int_equal(sc_shape_mass_props(s, &mp), SC_OK);
    assert_true(fabs(mp.volume - 1) < 1e-12);
    for (int k = 0; k < 3; k++)
        assert_true(fabs(mp.com[k] - 0.5) < 1e-12);
    assert_int_equal(sc_shape_triangles(s), 12);
    sc_shape_release(s);
}

/* ---- valid files ----------------------------------------------------------- */

static void test_obj_unit_cube_gives_8_vertices_and_its_12_triangles(void **state)
{
    (void)state;
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(parse_str(cube_obj, &xyz, &nv, &tri, &nt), SC_OK);
    assert_int_equal(nv, 8);
    assert_int_equal(nt, 12);
    assert_memory_equal(xyz, cube_xyz, sizeof cube_xyz);
    assert_memory_equal(tri, cube_tri, sizeof cube_tri);
    free(xyz);
    free(tri);
}

static void test_ascii_stl_unit_cube_welds_to_8_vertices_12_triangles(void **state)
{
    (void)state;
    char text[4096];
    size_t n = ascii_stl(text, sizeof text, cube_xyz, cube_tri, 12);
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(sc_mesh_parse(text, n, &xyz, &nv, &tri, &nt), SC_OK);
    assert_welded_cube(xyz, nv, tri, nt);
    free(xyz);
    free(tri);
}

static void test_binary_stl_unit_cube_welds_to_8_vertices_12_triangles(void **state)
{
    (void)state;
    for (int solid = 0; solid <= 1; solid++) {
        /* a header starting with "solid" does not make it ASCII */
        size_t len;
        unsigned char *b = binary_stl(cube_xyz, cube_tri, 12, solid, &len);
        double *xyz;
        int *tri, nv, nt;
        assert_int_equal(sc_mesh_parse(b, len, &xyz, &nv, &tri, &nt), SC_OK);
        assert_welded_cube(xyz, nv, tri, nt);
        free(xyz);
        free(tri);
        free(b);
    }
}

static void test_loaded_cube_has_unit_volume_in_every_format(void **state)
{
    char path[256], text[4096];
    write_file(state, "cube.obj", cube_obj, strlen(cube_obj), path, sizeof path);
    assert_unit_cube_shape(sc_shape_load(path));

    size_t n = ascii_stl(text, sizeof text, cube_xyz, cube_tri, 12);
    write_file(state, "cube_ascii.stl", text, n, path, sizeof path);
    assert_unit_cube_shape(sc_shape_load(path));

    unsigned char *b = binary_stl(cube_xyz, cube_tri, 12, 1, &n);
    write_file(state, "cube_binary.stl", b, n, path, sizeof path);
    free(b);
    assert_unit_cube_shape(sc_shape_load(path));
}

static void test_obj_quads_negative_indices_and_slashes_give_the_cube(void **state)
{
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(parse_str(cube_quads_obj, &xyz, &nv, &tri, &nt), SC_OK);
    assert_int_equal(nv, 8);
    assert_int_equal(nt, 12);
    assert_memory_equal(xyz, cube_xyz, sizeof cube_xyz);
    /* a quad a b c d fans to (a b c) (a c d): the first quad's two
     * triangles come out in the other order, the rest as in cube_tri */
    static const int bottom[] = { 0, 3, 2, 0, 2, 1 };
    assert_memory_equal(tri, bottom, sizeof bottom);
    assert_memory_equal(tri + 6, cube_tri + 6, 30 * sizeof *tri);
    free(xyz);
    free(tri);

    char path[256];
    write_file(state, "quads.obj", cube_quads_obj, strlen(cube_quads_obj), path, sizeof path);
    assert_unit_cube_shape(sc_shape_load(path));
}

static void test_obj_polygon_is_fan_triangulated_from_its_first_corner(void **state)
{
    (void)state;
    double *xyz;
    int *tri, nv, nt;
    const char *s = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5";
    assert_int_equal(parse_str(s, &xyz, &nv, &tri, &nt), SC_OK);
    static const int want[] = { 0, 1, 2, 0, 2, 3, 0, 3, 4 };
    assert_int_equal(nv, 5);
    assert_int_equal(nt, 3);
    assert_memory_equal(tri, want, sizeof want);
    free(xyz);
    free(tri);
}

static void test_obj_faces_may_name_vertices_defined_later(void **state)
{
    (void)state;
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(parse_str("f 3 2 1\nv 0 0 0\nv 1 0 0\nv 0 1 0\n", &xyz, &nv, &tri, &nt),
                     SC_OK);
    assert_int_equal(nt, 1);
    assert_int_equal(tri[0], 2);
    free(xyz);
    free(tri);
}

/* Found by fuzzing: ODE aborted on a closed cube that came with more
 * unused vertices than the cube has edges. */
static void test_obj_unused_vertices_are_dropped_and_the_cube_still_loads(void **state)
{
    char s[2048], path[256];
    size_t n = (size_t)snprintf(s, sizeof s, "v 9 9 9\nv 8 8 8\n");
    for (int i = 0; i < 8; i++)
        n += (size_t)snprintf(s + n, sizeof s - n, "v %g %g %g\n", cube_xyz[3 * i],
                              cube_xyz[3 * i + 1], cube_xyz[3 * i + 2]);
    for (int i = 0; i < 30; i++)
        n += (size_t)snprintf(s + n, sizeof s - n, "v 7 7 %d\n", i);
    for (int t = 0; t < 12; t++)
        n += (size_t)snprintf(s + n, sizeof s - n, "f %d %d %d\n", cube_tri[3 * t] + 3,
                              cube_tri[3 * t + 1] + 3, cube_tri[3 * t + 2] + 3);
    assert_true(n < sizeof s);
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(sc_mesh_parse(s, n, &xyz, &nv, &tri, &nt), SC_OK);
    assert_int_equal(nv, 8);
    assert_int_equal(nt, 12);
    assert_memory_equal(xyz, cube_xyz, sizeof cube_xyz);
    assert_memory_equal(tri, cube_tri, sizeof cube_tri);
    free(xyz);
    free(tri);
    write_file(state, "unused.obj", s, n, path, sizeof path);
    assert_unit_cube_shape(sc_shape_load(path));
}

static void test_obj_numbers_in_every_decimal_form_are_exact(void **state)
{
    (void)state;
    double *xyz;
    int *tri, nv, nt;
    /* BOM, tabs, lone CR line ends, exponents, leading dot, trailing dot */
    const char *s = "\xef\xbb\xbfv\t+1.\t.5  -.25E+1\rv 1e-3 -0 1E2\rv 3 2 1\rf 1 2 3";
    assert_int_equal(parse_str(s, &xyz, &nv, &tri, &nt), SC_OK);
    static const double want[] = { 1, 0.5, -2.5, 0.001, 0, 100, 3, 2, 1 };
    assert_int_equal(nv, 3);
    for (int i = 0; i < 9; i++)
        assert_true(xyz[i] == want[i]);
    free(xyz);
    free(tri);
}

static void test_stl_welds_negative_zero_with_zero_but_nothing_merely_close(void **state)
{
    (void)state;
    double *xyz;
    int *tri, nv, nt;
    const char *s =
        "solid z\nfacet normal 0 0 1 outer loop\n"
        "vertex -0 0 -0.0\nvertex 1 0 0\nvertex 0 1 0\nendloop endfacet\n"
        "facet normal 0 0 1 outer loop\n"
        "vertex 0 -0.0 0\nvertex 1.0000000000000002 0 0\nvertex 0 1 0\n"
        "endloop endfacet\nendsolid z\n";
    assert_int_equal(parse_str(s, &xyz, &nv, &tri, &nt), SC_OK);
    assert_int_equal(nv, 4);    /* (0,0,0) shared, 1 and 1+2^-52 distinct */
    assert_int_equal(nt, 2);
    assert_int_equal(tri[3], 0);
    assert_int_equal(tri[4], 3);
    assert_int_equal(tri[5], 2);
    assert_false(signbit(xyz[0]) || signbit(xyz[2]));     /* folded to +0 */
    free(xyz);
    free(tri);
}

static void test_ascii_stl_with_two_solids_keeps_both(void **state)
{
    (void)state;
    char text[8192];
    size_t n = ascii_stl(text, sizeof text, cube_xyz, cube_tri, 6);
    n += ascii_stl(text + n, sizeof text - n, cube_xyz, cube_tri + 18, 6);
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(sc_mesh_parse(text, n, &xyz, &nv, &tri, &nt), SC_OK);
    assert_welded_cube(xyz, nv, tri, nt);
    free(xyz);
    free(tri);
}

static void test_parse_reads_nothing_past_len(void **state)
{
    (void)state;
    /* "f 1 2 3" followed by a "4" just past len: reading it would make the
     * index 34 (out of range) */
    const char s[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 34";
    size_t len = sizeof s - 2;
    char *exact = malloc(len);      /* ASan flags any read past it */
    assert_non_null(exact);
    memcpy(exact, s, len);
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(sc_mesh_parse(exact, len, &xyz, &nv, &tri, &nt), SC_OK);
    assert_int_equal(tri[2], 2);
    free(xyz);
    free(tri);
    free(exact);
}

/* ---- refused files --------------------------------------------------------- */

static void test_missing_file_is_eio(void **state)
{
    fixture *fx = *state;
    char path[256];
    snprintf(path, sizeof path, "%s/no_such_file.obj", fx->dir);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_EIO);
}

static void test_directory_is_eio(void **state)
{
    fixture *fx = *state;
    char path[256];
    snprintf(path, sizeof path, "%s/a_directory.obj", fx->dir);
    assert_int_equal(mkdir(path, 0700), 0);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_EIO);
}

static void test_null_arguments_are_einval(void **state)
{
    (void)state;
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(sc_mesh_parse(NULL, 4, &xyz, &nv, &tri, &nt), SC_EINVAL);
    assert_int_equal(sc_mesh_parse("v", 1, NULL, &nv, &tri, &nt), SC_EINVAL);
    assert_null(sc_shape_load(NULL));
    assert_int_equal(sc_last_error(), SC_EINVAL);
}

static void test_garbage_empty_and_faceless_files_are_eformat(void **state)
{
    unsigned char junk[1000];
    uint32_t x = 12345;
    for (size_t i = 0; i < sizeof junk; i++) {
        x = x * 1664525u + 1013904223u;
        junk[i] = (unsigned char)(x >> 24);
    }
    assert_int_equal(parse_code(junk, sizeof junk), SC_EFORMAT);
    assert_int_equal(parse_code("", 0), SC_EFORMAT);
    assert_int_equal(parse_code(NULL, 0), SC_EFORMAT);
    assert_int_equal(parse_str_code("hello, world\n"), SC_EFORMAT);
    assert_int_equal(parse_str_code("# only a comment\n\n"), SC_EFORMAT);
    assert_int_equal(parse_str_code("v 0 0 0\nv 1 0 0\nv 0 1 0\n"), SC_EFORMAT);
    assert_int_equal(parse_str_code("solid\nendsolid\n"), SC_EFORMAT);
    static const char nul[] = "v 0 0 0\0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    assert_int_equal(parse_code(nul, sizeof nul - 1), SC_EFORMAT);

    char path[256];
    write_file(state, "garbage.obj", junk, sizeof junk, path, sizeof path);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_EFORMAT);
    write_file(state, "empty.stl", "", 0, path, sizeof path);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_EFORMAT);
}

static void test_obj_syntax_errors_are_eformat(void **state)
{
    (void)state;
    static const char *const bad[] = {
        "v 1 2\n",          "v 1 2 3 4 5\n",   "v 1 2 3 4 5 6 7 8\n", "v 1 2 x\n",
        "v 1 2 3x\n",       "v 1.2.3 0 0\n",   "v 1e 0 0\n",          "v . 0 0\n",
        "v 0x1p3 0 0\n",    "v 1,5 0 0\n",     "f 1/ 2 3\n",          "f 1// 2 3\n",
        "f 1/2/3/4 2 3\n",  "f a b c\n",       "f 1/0 2 3\n",         "f 1//0 2 3\n",
        "f /1 2 3\n",       "f 1 2 3x\n",      "cube 1 2 3\n",        "vv 1 2 3\n",
    };
    char s[128];
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(s, sizeof s, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n%s", bad[i]);
        if (parse_str_code(s) != SC_EFORMAT)
            fail_msg("accepted: %s", bad[i]);
    }
    /* a 256-digit number is refused rather than copied unbounded */
    char longnum[300] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 0 0 ";
    size_t n = strlen(longnum);
    memset(longnum + n, '1', 256);
    longnum[n + 256] = '\0';
    assert_int_equal(parse_str_code(longnum), SC_EFORMAT);
}

static void test_face_with_fewer_than_3_vertices_is_eformat(void **state)
{
    (void)state;
    assert_int_equal(parse_str_code("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n"),
                     SC_EFORMAT);
    assert_int_equal(parse_str_code("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1\n"), SC_EFORMAT);
    assert_int_equal(parse_str_code("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf # none\n"),
                     SC_EFORMAT);
    assert_int_equal(parse_str_code("solid s\nfacet normal 0 0 0 outer loop\nvertex 0 0 0\n"
                                    "vertex 1 0 0\nendloop endfacet\nendsolid s\n"),
                     SC_EFORMAT);
}

static void test_index_out_of_range_or_zero_is_eformat(void **state)
{
    static const char *const bad[] = { "f 1 2 9", "f 0 1 2", "f -9 1 2", "f 1 2 -2147483648",
                                       "f 1 2 2147483648", "f 1 2 -2147483649",
                                       "f 1 2 99999999999999999999999" };
    char s[512];
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(s, sizeof s, "%s\n%s\n", cube_obj, bad[i]);
        if (parse_str_code(s) != SC_EFORMAT)
            fail_msg("accepted: %s", bad[i]);
    }
    /* -3 counts back from the vertices read so far, not from the file's end */
    assert_int_equal(parse_str_code("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n"), SC_EFORMAT);

    char path[256];
    snprintf(s, sizeof s, "%sf 1 2 9\n", cube_obj);
    write_file(state, "range.obj", s, strlen(s), path, sizeof path);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_EFORMAT);
}

static void test_nan_and_infinite_coordinates_are_eformat(void **state)
{
    static const char *const bad[] = { "v nan 0 0", "v 0 NaN 0", "v 0 0 inf", "v -inf 0 0",
                                       "v 1e999 0 0", "v 0 -1e400 0" };
    char s[512];
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(s, sizeof s, "%s\n%s\n", cube_obj, bad[i]);
        if (parse_str_code(s) != SC_EFORMAT)
            fail_msg("accepted: %s", bad[i]);
    }
    assert_int_equal(parse_str_code("solid s\nfacet normal 0 0 0 outer loop\nvertex 0 0 0\n"
                                    "vertex 1 0 0\nvertex 0 nan 0\nendloop endfacet\n"
                                    "endsolid s\n"),
                     SC_EFORMAT);
    /* the binary cube with one corner coordinate NaN, then +inf */
    size_t len;
    unsigned char *b = binary_stl(cube_xyz, cube_tri, 12, 0, &len);
    put_float(b + 84 + 50 * 5 + 12 + 12 + 8, NAN);
    assert_int_equal(parse_code(b, len), SC_EFORMAT);
    put_float(b + 84 + 50 * 5 + 12 + 12 + 8, INFINITY);
    assert_int_equal(parse_code(b, len), SC_EFORMAT);

    char path[256];
    write_file(state, "nan.stl", b, len, path, sizeof path);
    free(b);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_EFORMAT);
}

static void test_truncated_files_are_eformat(void **state)
{
    for (int solid = 0; solid <= 1; solid++) {
        size_t len;
        unsigned char *b = binary_stl(cube_xyz, cube_tri, 12, solid, &len);
        static const size_t cut[] = { 1, 2, 25, 49, 50, 51, 50 * 12 };
        for (size_t i = 0; i < sizeof cut / sizeof cut[0]; i++)
            assert_int_equal(parse_code(b, len - cut[i]), SC_EFORMAT);
        assert_int_equal(parse_code(b, 83), SC_EFORMAT);
        if (solid) {
            char path[256];
            write_file(state, "truncated.stl", b, len - 7, path, sizeof path);
            assert_null(sc_shape_load(path));
            assert_int_equal(sc_last_error(), SC_EFORMAT);
        }
        free(b);
    }
    char text[4096];
    size_t n = ascii_stl(text, sizeof text, cube_xyz, cube_tri, 12);
    assert_int_equal(parse_code(text, n - strlen("endsolid cube\n")), SC_EFORMAT);
    assert_int_equal(parse_code(text, n / 2), SC_EFORMAT);
}

static void test_binary_header_claiming_2_31_triangles_is_refused_unallocated(void **state)
{
    (void)state;
    /* 2^31 facets would be 100 GiB; the file holds 84 + 12 * 50 bytes, so
     * the length does not match and it is not read as binary at all */
    for (int solid = 0; solid <= 1; solid++) {
        size_t len;
        unsigned char *b = binary_stl(cube_xyz, cube_tri, 12, solid, &len);
        put_le32(b + 80, 0x80000000u);
        int rc = parse_code(b, len);
        assert_true(rc == SC_EFORMAT || rc == SC_ETOOBIG);
        assert_int_equal(parse_code(b, 84), rc);
        free(b);
    }
}

static void test_binary_stl_over_the_triangle_limit_is_etoobig(void **state)
{
    (void)state;
    /* a well-formed length for SC_MESH_MAX_TRIS + 1 facets (calloc's pages
     * stay untouched: the count is refused before any facet is read) */
    uint32_t count = SC_MESH_MAX_TRIS + 1;
    size_t len = 84 + 50 * (size_t)count;
    unsigned char *b = calloc(1, len);
    assert_non_null(b);
    put_le32(b + 80, count);
    assert_int_equal(parse_code(b, len), SC_ETOOBIG);
    free(b);
}

static void test_file_over_256_mib_is_etoobig(void **state)
{
    fixture *fx = *state;
    char path[256];
    snprintf(path, sizeof path, "%s/huge.stl", fx->dir);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(fd >= 0);
    /* sparse: no disk space used, and the size alone refuses it */
    assert_int_equal(ftruncate(fd, ((off_t)256 << 20) + 1), 0);
    assert_int_equal(close(fd), 0);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_ETOOBIG);
    unlink(path);
}

static void test_obj_over_the_vertex_and_triangle_limits_is_etoobig(void **state)
{
    (void)state;
    size_t nv = SC_MESH_MAX_VERTS + 1, len = 8 * nv;
    char *s = malloc(len + 16);
    assert_non_null(s);
    for (size_t i = 0; i < nv; i++)
        memcpy(s + 8 * i, "v 0 0 0\n", 8);
    assert_int_equal(parse_code(s, len), SC_ETOOBIG);
    free(s);

    /* one face with SC_MESH_MAX_TRIS + 3 corners fans into one too many */
    size_t corners = SC_MESH_MAX_TRIS + 3;
    len = 24 + 1 + 2 * corners;
    s = malloc(len);
    assert_non_null(s);
    memcpy(s, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf", 25);
    for (size_t i = 0; i < corners; i++)
        memcpy(s + 25 + 2 * i, " 1", 2);
    assert_int_equal(parse_code(s, len), SC_ETOOBIG);
    free(s);
}

/* sc_shape_load_err: the message for text "name" (contents s) is
 * "DIR/name" + want. */
static void assert_load_message(void **state, const char *name, const void *data, size_t len,
                                int code, const char *want)
{
    char path[256], err[256], full[512];
    write_file(state, name, data, len, path, sizeof path);
    assert_null(sc_shape_load_err(path, err, sizeof err));
    assert_int_equal(sc_last_error(), code);
    snprintf(full, sizeof full, "%s%s", path, want);
    assert_string_equal(err, full);
}

static void assert_obj_message(void **state, const char *s, const char *want)
{
    assert_load_message(state, "bad.obj", s, strlen(s), SC_EFORMAT, want);
}

static void test_load_err_names_the_obj_line_and_what_is_wrong(void **state)
{
    assert_obj_message(state, "v 0 1 abc\n", ":1: bad vertex coordinate");
    assert_obj_message(state, "# a cube\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1\r\n",
                       ":4: a vertex has 2 numbers (x y z, then w, or r g b [a])");
    assert_obj_message(state, "v 0 0 0\rv 1 0 0\rv 0 1 0 1 2 3 4 5\r",
                       ":3: a vertex has more than 7 numbers");
    assert_obj_message(state, "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n",
                       ":5: a face needs 3 corners or more, not 2");
    assert_obj_message(state, "v 0 0 0\nv 1 0 0\nf 1 2/x 3\n", ":3: bad face corner '2/x'");
    assert_obj_message(state, "v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n",
                       ":3: face index -3: only 2 vertices before it");
    assert_obj_message(state, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\nf 1 2 3\n",
                       ":5: face index 9: the file has 3 vertices");
    assert_obj_message(state, "v 0 0 0\ncube\x1b[2J 1\n", ":2: unknown statement 'cube?[2J'");
    assert_obj_message(state, "# nothing\n", ": no faces (is this an OBJ or STL file?)");
    assert_obj_message(state, "", ": an empty file");
    /* the code stays SC_EFORMAT, and sc_shape_load() says the same with no text */
    assert_null(sc_shape_load_err(NULL, NULL, 0));
    assert_int_equal(sc_last_error(), SC_EINVAL);
}

static void test_load_err_names_the_stl_line_or_byte(void **state)
{
    static const char *const stl[][2] = {
        { "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 x\n",
          ":4: bad vertex coordinate" },
        { "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n",
          ":4: the file ends where 'vertex' or 'endloop' should be (truncated?)" },
        { "solid s\nfacet normal 0 0 1\n  outer lop\n", ":3: 'loop' expected, not 'lop'" },
        { "solid s\n  facets\nendsolid\n", ":2: 'facet' or 'endsolid' expected, not 'facets'" },
        { "solid s\nfacet normal 0 0 1 outer loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n",
          ":5: a facet needs 3 vertices or more, not 2" },
    };
    for (size_t i = 0; i < sizeof stl / sizeof stl[0]; i++)
        assert_load_message(state, "bad.stl", stl[i][0], strlen(stl[i][0]), SC_EFORMAT,
                            stl[i][1]);
    /* binary: the byte offset of the first coordinate of the vertex at fault */
    size_t len;
    unsigned char *b = binary_stl(cube_xyz, cube_tri, 12, 0, &len);
    put_float(b + 84 + 50 * 2 + 12 + 12 * 1 + 4, INFINITY);   /* facet 2, vertex 1, y */
    assert_load_message(state, "bad_binary.stl", b, len, SC_EFORMAT,
                        ": byte 208: facet 2: a vertex coordinate is not finite");
    put_le32(b + 80, 0);
    assert_load_message(state, "zero.stl", b, 84, SC_EFORMAT,
                        ": byte 80: binary STL with no facets (a count of 0)");
    free(b);
    /* other failures: the system's reason, or the library's sentence */
    char err[256];
    assert_null(sc_shape_load_err("/nonexistent/x.obj", err, sizeof err));
    assert_string_equal(err, "/nonexistent/x.obj: No such file or directory");
    static const char open_obj[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    assert_load_message(state, "open.obj", open_obj, strlen(open_obj), SC_ENOTCLOSED,
                        ": mesh is not a closed, consistently outward-oriented surface");
    /* a short buffer is cut, never overrun */
    char tiny[8];
    assert_null(sc_shape_load_err("/nonexistent/x.obj", tiny, sizeof tiny));
    assert_string_equal(tiny, "/nonexi");
}

static void test_open_mesh_is_enotclosed_from_shape_load(void **state)
{
    /* the cube without its last triangle */
    char s[512], path[256];
    size_t n = strlen(cube_obj) - strlen("f 4 5 8\n");
    memcpy(s, cube_obj, n);
    write_file(state, "open.obj", s, n, path, sizeof path);
    double *xyz;
    int *tri, nv, nt;
    assert_int_equal(sc_mesh_parse(s, n, &xyz, &nv, &tri, &nt), SC_OK);
    assert_int_equal(nt, 11);
    free(xyz);
    free(tri);
    assert_null(sc_shape_load(path));
    assert_int_equal(sc_last_error(), SC_ENOTCLOSED);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_obj_unit_cube_gives_8_vertices_and_its_12_triangles),
        cmocka_unit_test(test_ascii_stl_unit_cube_welds_to_8_vertices_12_triangles),
        cmocka_unit_test(test_binary_stl_unit_cube_welds_to_8_vertices_12_triangles),
        cmocka_unit_test(test_loaded_cube_has_unit_volume_in_every_format),
        cmocka_unit_test(test_obj_quads_negative_indices_and_slashes_give_the_cube),
        cmocka_unit_test(test_obj_polygon_is_fan_triangulated_from_its_first_corner),
        cmocka_unit_test(test_obj_faces_may_name_vertices_defined_later),
        cmocka_unit_test(test_obj_unused_vertices_are_dropped_and_the_cube_still_loads),
        cmocka_unit_test(test_obj_numbers_in_every_decimal_form_are_exact),
        cmocka_unit_test(test_stl_welds_negative_zero_with_zero_but_nothing_merely_close),
        cmocka_unit_test(test_ascii_stl_with_two_solids_keeps_both),
        cmocka_unit_test(test_parse_reads_nothing_past_len),
        cmocka_unit_test(test_missing_file_is_eio),
        cmocka_unit_test(test_directory_is_eio),
        cmocka_unit_test(test_null_arguments_are_einval),
        cmocka_unit_test(test_garbage_empty_and_faceless_files_are_eformat),
        cmocka_unit_test(test_obj_syntax_errors_are_eformat),
        cmocka_unit_test(test_load_err_names_the_obj_line_and_what_is_wrong),
        cmocka_unit_test(test_load_err_names_the_stl_line_or_byte),
        cmocka_unit_test(test_face_with_fewer_than_3_vertices_is_eformat),
        cmocka_unit_test(test_index_out_of_range_or_zero_is_eformat),
        cmocka_unit_test(test_nan_and_infinite_coordinates_are_eformat),
        cmocka_unit_test(test_truncated_files_are_eformat),
        cmocka_unit_test(test_binary_header_claiming_2_31_triangles_is_refused_unallocated),
        cmocka_unit_test(test_binary_stl_over_the_triangle_limit_is_etoobig),
        cmocka_unit_test(test_file_over_256_mib_is_etoobig),
        cmocka_unit_test(test_obj_over_the_vertex_and_triangle_limits_is_etoobig),
        cmocka_unit_test(test_open_mesh_is_enotclosed_from_shape_load),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
