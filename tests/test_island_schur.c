/* test_island_schur.c - a big island's Newton system by subdomains
 * (lib/core/island_schur.c; docs/DESIGN.md 11): the same answer as one
 * dense solve on a chain of 6 x 6 blocks cut into parts, also when the
 * parts run on two threads (the same bits), unsymmetric blocks included;
 * a plan that joins two interiors is refused; traffic is counted; an
 * island that rests on nothing static is cut into parts too. */
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "island_schur.h"
#include "simcluster.h"

/* A chain of nb bodies, 6 unknowns each, body k coupled to k + 1: K =
 * diag(mass) + stiff (k, k + 1) blocks, unsymmetric by a skew part. */
#define NB 12
#define NV (6 * NB)

typedef struct sys {
    int kp[NV + 1], ki[NV * 18];
    double kx[NV * 18];
    double dense[NV * NV];    /* row-major */
} sys;

static double rnd(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0 - 0.5;
}

static void build(sys *y, uint64_t seed)
{
    memset(y, 0, sizeof *y);
    for (int k = 0; k < NB; k++) {
        for (int i = 0; i < 6; i++)
            y->dense[(6 * k + i) * NV + 6 * k + i] += 1.0 + 0.1 * i;
        if (k + 1 < NB) {
            /* a stiff row joining k and k + 1: J^T J / c plus a skew part */
            double j[12];
            for (int i = 0; i < 12; i++)
                j[i] = rnd(&seed);
            for (int a = 0; a < 12; a++)
                for (int b = 0; b < 12; b++) {
                    int r = 6 * k + a, c = 6 * k + b;
                    y->dense[r * NV + c] += 1e4 * j[a] * j[b] + 0.3 * rnd(&seed);
                }
        }
    }
    int p = 0;
    for (int c = 0; c < NV; c++) {
        y->kp[c] = p;
        for (int r = 0; r < NV; r++)
            if (abs(r / 6 - c / 6) <= 1) {
                y->ki[p] = r;
                y->kx[p++] = y->dense[r * NV + c];
            }
    }
    y->kp[NV] = p;
}

/* x = K^-1 b by dense Gaussian elimination with partial pivoting. */
static void dense_solve(const sys *y, const double *b, double *x)
{
    static double a[NV * NV];
    memcpy(a, y->dense, sizeof a);
    memcpy(x, b, NV * sizeof *x);
    for (int k = 0; k < NV; k++) {
        int r = k;
        for (int i = k + 1; i < NV; i++)
            if (fabs(a[i * NV + k]) > fabs(a[r * NV + k]))
                r = i;
        for (int j = 0; j < NV; j++) {
            double t = a[k * NV + j];
            a[k * NV + j] = a[r * NV + j];
            a[r * NV + j] = t;
        }
        double t = x[k];
        x[k] = x[r];
        x[r] = t;
        for (int i = k + 1; i < NV; i++) {
            double f = a[i * NV + k] / a[k * NV + k];
            for (int j = k; j < NV; j++)
                a[i * NV + j] -= f * a[k * NV + j];
            x[i] -= f * x[k];
        }
    }
    for (int k = NV - 1; k >= 0; k--) {
        double v = x[k];
        for (int j = k + 1; j < NV; j++)
            v -= a[k * NV + j] * x[j];
        x[k] = v / a[k * NV + k];
    }
}

/* Bodies 0-3 part 0, 5-7 part 1, 9-11 part 2; bodies 4 and 8 interface. */
static void where3(int *w)
{
    for (int i = 0; i < NV; i++) {
        int k = i / 6;
        w[i] = k == 4 || k == 8 ? -1 : k < 4 ? 0 : k < 8 ? 1 : 2;
    }
}

static void b_of(double *b)
{
    for (int i = 0; i < NV; i++)
        b[i] = sin(1.0 + i);
}

static void solves_as_one_dense_factor(void **state)
{
    (void)state;
    static sys y;
    build(&y, 7);
    int w[NV];
    where3(w);
    sc_schur *s;
    assert_int_equal(sc_schur_plan(&s, NV, y.kp, y.ki, w, 3), SC_OK);
    assert_int_equal(sc_schur_interface(s), 12);
    assert_int_equal(sc_schur_parts(s), 3);
    assert_int_equal(sc_schur_factor(s, y.kx, NULL, NULL), SC_OK);
    double b[NV], x[NV], ref[NV];
    b_of(b);
    memcpy(x, b, sizeof x);
    assert_int_equal(sc_schur_solve(s, x, NULL, NULL), SC_OK);
    dense_solve(&y, b, ref);
    double err = 0, scale = 0;
    for (int i = 0; i < NV; i++) {
        err = fmax(err, fabs(x[i] - ref[i]));
        scale = fmax(scale, fabs(ref[i]));
    }
    assert_true(scale > 0);
    assert_true(err <= 1e-9 * scale);
    /* one round a factorisation (each part's Schur block: parts 0 and 2
     * touch one interface body, part 1 two), one a solve (16 bytes an
     * interface unknown next to a part) */
    sc_schur_traffic tr = sc_schur_traffic_of(s);
    assert_int_equal(tr.exchanges, 2);
    assert_int_equal(tr.bytes, 8L * (36 + 144 + 36) + 16L * (6 + 12 + 6));
    /* a second factorisation of other values refactors */
    for (int e = 0; e < y.kp[NV]; e++)
        y.kx[e] *= 2;
    assert_int_equal(sc_schur_factor(s, y.kx, NULL, NULL), SC_OK);
    memcpy(x, b, sizeof x);
    assert_int_equal(sc_schur_solve(s, x, NULL, NULL), SC_OK);
    for (int i = 0; i < NV; i++)
        assert_true(fabs(2 * x[i] - ref[i]) <= 1e-9 * scale);
    sc_schur_free(s);
}

/* A runner that runs the tasks on two threads: odd ones on a second. */
typedef struct two {
    sc_task_fn fn;
    void *arg;
    int count;
} two;

static void *odd_tasks(void *p)
{
    const two *t = p;
    for (int i = 1; i < t->count; i += 2)
        t->fn(t->arg, i, NULL, 1);
    return NULL;
}

static void run_two(void *ctx, sc_task_fn fn, void *arg, int count, sc_arena *a)
{
    (void)ctx;
    two t = { fn, arg, count };
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, odd_tasks, &t), 0);
    for (int i = 0; i < count; i += 2)
        fn(arg, i, a, 0);
    pthread_join(th, NULL);
}

static void parts_on_two_threads_give_the_same_bits(void **state)
{
    (void)state;
    static sys y;
    build(&y, 11);
    int w[NV];
    where3(w);
    double b[NV], x1[NV], x2[NV];
    b_of(b);
    sc_task_runner r = { run_two, NULL };
    for (int k = 0; k < 2; k++) {
        sc_schur *s;
        assert_int_equal(sc_schur_plan(&s, NV, y.kp, y.ki, w, 3), SC_OK);
        assert_int_equal(sc_schur_factor(s, y.kx, k ? &r : NULL, NULL), SC_OK);
        double *x = k ? x2 : x1;
        memcpy(x, b, NV * sizeof *x);
        assert_int_equal(sc_schur_solve(s, x, k ? &r : NULL, NULL), SC_OK);
        sc_schur_free(s);
    }
    assert_memory_equal(x1, x2, sizeof x1);
}

static void joined_interiors_are_refused(void **state)
{
    (void)state;
    static sys y;
    build(&y, 3);
    int w[NV];
    where3(w);
    for (int i = 24; i < 30; i++)
        w[i] = 0;             /* body 4 in part 0: it touches part 1's body 5 */
    sc_schur *s = NULL;
    assert_int_equal(sc_schur_plan(&s, NV, y.kp, y.ki, w, 3), SC_EINVAL);
    assert_null(s);
    w[0] = 3;                 /* no such part */
    assert_int_equal(sc_schur_plan(&s, NV, y.kp, y.ki, w, 3), SC_EINVAL);
}

static void a_singular_interior_is_reported(void **state)
{
    (void)state;
    static sys y;
    build(&y, 5);
    int w[NV];
    where3(w);
    for (int e = 0; e < y.kp[NV]; e++)
        if (y.ki[e] / 6 == 1 && y.kp[6] <= e && e < y.kp[12])
            y.kx[e] = 0;      /* body 1's own block and couplings: a zero column */
    for (int c = 6; c < 12; c++)
        for (int e = y.kp[c]; e < y.kp[c + 1]; e++)
            y.kx[e] = 0;
    sc_schur *s;
    assert_int_equal(sc_schur_plan(&s, NV, y.kp, y.ki, w, 3), SC_OK);
    assert_int_equal(sc_schur_factor(s, y.kx, NULL, NULL), SC_ENUMERIC);
    sc_schur_free(s);
}

/* A column of 70 cubes, each sunk 0.2 mm into the next, floating without
 * gravity or floor: no body rests on a static one, so the parts' breadth-
 * first order starts from the first body (island_sparse.c as_parts()). */
static void an_island_on_nothing_static_is_cut_too(void **state)
{
    (void)state;
    sc_world_config cfg = sc_world_config_default();
    cfg.gravity[2] = 0;
    cfg.workers = 1;
    cfg.island_method = SC_ISLAND_SUBDOMAINS;
    sc_world *w = sc_world_create(&cfg);
    assert_non_null(w);
    sc_shape *cube = sc_shape_box(0.1, 0.1, 0.1);
    assert_non_null(cube);
    for (int k = 0; k < 70; k++) {
        sc_body_desc d = sc_body_desc_default();
        d.shape = cube;
        d.mass = 1;
        d.pos[2] = k * 0.1998;
        assert_true(sc_body_add(w, &d) >= 0);
    }
    sc_shape_release(cube);
    int parts = 0;
    for (int f = 0; f < 3; f++) {
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
        sc_stats st;
        sc_world_stats(w, &st);
        parts = st.frame.lcp.as_parts_max > parts ? st.frame.lcp.as_parts_max : parts;
    }
    assert_true(parts >= 2);
    sc_world_destroy(w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(solves_as_one_dense_factor),
        cmocka_unit_test(parts_on_two_threads_give_the_same_bits),
        cmocka_unit_test(joined_interiors_are_refused),
        cmocka_unit_test(a_singular_interior_is_reported),
        cmocka_unit_test(an_island_on_nothing_static_is_cut_too),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
