/* test_contact.c - the contact solver for piles (lib/core/contact.c;
 * docs/DESIGN.md section 11): every fallback forced and counted with a
 * finite, physical answer; split islands agree with exact ones, and their
 * blocks give the same bits in any order and on any thread; warm starts
 * carry the weight from frame to frame.
 *
 * The island is a stack of three boxes on the floor, resting (12 contacts,
 * 36 rows with friction), taken from a world after a few frames and solved
 * with sc_island_solve() on copies of its bodies and contacts. */
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "vecmath.h"
#include "world.h"

#define H 0.01
#define HALF 0.1
#define LAYERS 3

typedef struct stack {
    sc_world *w;
    int nb, nc;
    sc_body *bodies;          /* u* (gravity applied), as a substep has them */
    sc_contact *c;
    int *ci;
    sc_body *out[2];          /* room for two solves' bodies and contacts */
    sc_contact *cout[2];
} stack;

static sc_world *stack_world(void)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = 1;
    sc_world *w = sc_world_create(&cfg);
    assert_non_null(w);
    sc_shape *floor = sc_shape_plane(0, 0, 1, 0), *box = sc_shape_box(HALF, HALF, HALF);
    sc_body_desc d = sc_body_desc_default();
    d.shape = floor;
    d.mass = 0;
    assert_int_equal(sc_body_add(w, &d), 0);
    for (int k = 0; k < LAYERS; k++) {
        d = sc_body_desc_default();
        d.shape = box;
        d.mass = 1;
        d.friction = 0.5;
        d.pos[2] = HALF + 2 * HALF * k - 1e-4;    /* a hair of penetration */
        assert_int_equal(sc_body_add(w, &d), k + 1);
    }
    sc_shape_release(floor);
    sc_shape_release(box);
    return w;
}

/* World w after frames, every contact as one island, its bodies at u*
 * for one substep of H. */
static void capture(stack *s, sc_world *w, int frames)
{
    s->w = w;
    for (int f = 0; f < frames; f++)
        assert_int_equal(sc_world_step(s->w, H), SC_OK);
    sc_frame_state *st = &s->w->st;
    s->nb = st->nbodies;
    s->nc = st->ncontacts;
    s->bodies = malloc((size_t)s->nb * sizeof *s->bodies);
    s->c = malloc((size_t)s->nc * sizeof *s->c);
    s->ci = malloc((size_t)s->nc * sizeof *s->ci);
    assert_true(s->bodies && s->c && s->ci);
    for (int k = 0; k < 2; k++) {
        s->out[k] = malloc((size_t)s->nb * sizeof *s->out[k]);
        s->cout[k] = malloc((size_t)s->nc * sizeof *s->cout[k]);
        assert_true(s->out[k] && s->cout[k]);
    }
    memcpy(s->c, st->contacts, (size_t)s->nc * sizeof *s->c);
    for (int k = 0; k < s->nc; k++)
        s->ci[k] = k;
    /* u* as the frame makes it: sc_apply_forces on a copy of the state */
    sc_body *keep = malloc((size_t)s->nb * sizeof *keep);
    assert_non_null(keep);
    memcpy(keep, st->bodies, (size_t)s->nb * sizeof *keep);
    sc_frame f = { .cfg = &s->w->fcfg, .st = st };
    sc_apply_forces(&f, H, NULL);
    memcpy(s->bodies, st->bodies, (size_t)s->nb * sizeof *s->bodies);
    memcpy(st->bodies, keep, (size_t)s->nb * sizeof *keep);
    free(keep);
}

/* The stack after a few frames. */
static void stack_make(stack *s)
{
    capture(s, stack_world(), 5);
    assert_int_equal(s->nc, 4 * LAYERS);
}

/* A bin of 60 bolts and nuts, piled after 1.2 s. */
static void pile_make(stack *s)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = 1;
    sc_world *w = sc_world_create(&cfg);
    assert_non_null(w);
    assert_int_equal(sc_scene_bin(w, 60, 1), SC_OK);
    capture(s, w, 120);
    assert_true(s->nc > 100);
}

static void stack_free(stack *s)
{
    for (int k = 0; k < 2; k++) {
        free(s->cout[k]);
        free(s->out[k]);
    }
    free(s->ci);
    free(s->c);
    free(s->bodies);
    sc_world_destroy(s->w);
}

/* Solve a copy; returns the largest speed of a box afterwards (m/s) and
 * checks every number is finite. */
static double solve_copy(const stack *s, const sc_contact_params *p, sc_solve_info *info,
                         sc_body *out, sc_contact *cout)
{
    memcpy(out, s->bodies, (size_t)s->nb * sizeof *out);
    memcpy(cout, s->c, (size_t)s->nc * sizeof *cout);
    sc_arena a;
    sc_arena_init(&a);
    memset(info, 0, sizeof *info);
    assert_int_equal(sc_island_solve(&a, out, cout, s->ci, s->nc, H, p, info), SC_OK);
    sc_arena_destroy(&a);
    double vmax = 0;
    for (int i = 1; i < s->nb; i++) {
        for (int k = 0; k < 3; k++)
            assert_true(isfinite(out[i].x[k]) && isfinite(out[i].v[k]) && isfinite(out[i].w[k]));
        vmax = fmax(vmax, sqrt(out[i].v[0] * out[i].v[0] + out[i].v[1] * out[i].v[1] +
                               out[i].v[2] * out[i].v[2]));
    }
    for (int k = 0; k < s->nc; k++)
        for (int j = 0; j < 3; j++)
            assert_true(isfinite(cout[k].impulse[j]));
    return vmax;
}

/* The floor carries the stack's weight over the substep: the normal
 * impulses of the floor contacts add up to m g h (3 kg). */
static double floor_impulse(const sc_contact *c, int nc)
{
    double sum = 0;
    for (int k = 0; k < nc; k++)
        if (c[k].body_a == 0)
            sum += c[k].impulse[2];
    return sum;
}

static void test_each_fallback_is_taken_counted_and_physical(void **state)
{
    (void)state;
    stack s;
    stack_make(&s);
    sc_body *out = s.out[0];
    sc_contact *cout = s.cout[0];
    const double weight = LAYERS * 1.0 * 9.81 * H;
    sc_contact_params base = sc_frame_contact_params(&s.w->fcfg);
    sc_solve_info info;

    /* no fault: one exact LCP, no fallback, the stack stays put */
    double v = solve_copy(&s, &base, &info, out, cout);
    assert_int_equal(info.solves, 1);
    assert_int_equal(info.failures + info.split + info.split_fallbacks + info.nan_islands, 0);
    assert_true(v < 1e-3);
    assert_true(fabs(floor_impulse(cout, s.nc) - weight) < 0.02 * weight);
    assert_true(info.residual_exact < 1e-9);

    /* the coupled friction LCP fails: staggered (normals, then friction) */
    sc_contact_params p = base;
    p.inject = SC_INJECT_COUPLED;
    v = solve_copy(&s, &p, &info, out, cout);
    assert_int_equal(info.failures, 1);
    assert_int_equal(info.split_fallbacks, 0);
    assert_true(v < 1e-3);
    assert_true(fabs(floor_impulse(cout, s.nc) - weight) < 0.02 * weight);

    /* and the staggered one fails too: blocks */
    p.inject = SC_INJECT_COUPLED | SC_INJECT_STAGGERED;
    v = solve_copy(&s, &p, &info, out, cout);
    assert_int_equal(info.failures, 1);
    assert_int_equal(info.split_fallbacks, 1);
    assert_int_equal(info.split, 1);
    assert_true(info.blocks > 0);
    assert_true(v < 5 * base.tol);
    assert_true(fabs(floor_impulse(cout, s.nc) - weight) < 0.02 * weight);

    /* a split island whose every block solve fails: projected Gauss-Seidel
     * on each block, to the outer tolerance or counted unconverged */
    p = base;
    p.split_contacts = 2;
    p.inject = SC_INJECT_BLOCK;
    v = solve_copy(&s, &p, &info, out, cout);
    assert_int_equal(info.split, 1);
    assert_true(info.block_fallbacks > 0);
    assert_int_equal(info.block_fallbacks, info.blocks);
    assert_true(info.unconverged || info.residual_split <= base.tol);
    assert_true(v < 0.05);
    assert_true(fabs(floor_impulse(cout, s.nc) - weight) < 0.1 * weight);

    /* a NaN in the island's data: no impulse, counted, nothing spread */
    p = base;
    p.inject = SC_INJECT_NAN;
    solve_copy(&s, &p, &info, out, cout);
    assert_int_equal(info.nan_islands, 1);
    for (int i = 0; i < s.nb; i++)
        assert_memory_equal(out[i].v, s.bodies[i].v, sizeof out[i].v);
    for (int k = 0; k < s.nc; k++)
        assert_true(cout[k].impulse[0] == 0 && cout[k].impulse[1] == 0 && cout[k].impulse[2] == 0);
    stack_free(&s);
}

/* Blocks of one pair each (split past 2 contacts), iterated from 0, reach
 * the exact answer within the outer tolerance. */
static void test_split_island_agrees_with_the_exact_one(void **state)
{
    (void)state;
    stack s;
    stack_make(&s);
    sc_body *ex = s.out[0], *sp = s.out[1];
    sc_contact *cex = s.cout[0], *csp = s.cout[1];
    sc_contact_params p = sc_frame_contact_params(&s.w->fcfg);
    sc_solve_info ie, is;
    p.split_contacts = 0;
    solve_copy(&s, &p, &ie, ex, cex);
    p.split_contacts = 2;
    p.block_contacts = 4;
    p.cold = 1;               /* from 0: the blocks must iterate */
    solve_copy(&s, &p, &is, sp, csp);
    assert_int_equal(ie.split, 0);
    assert_int_equal(is.split, 1);
    assert_int_equal(is.unconverged, 0);
    assert_true(is.residual_split <= p.tol);
    assert_true(is.sweeps_max >= 2);
    assert_int_equal(is.sweeps, is.sweeps_max);     /* one split solve */
    print_message("split from 0: %d sweeps, outer residual %.2g m/s, floor %.6f vs %.6f N s\n",
                  is.sweeps_max, is.residual_split, floor_impulse(csp, s.nc),
                  floor_impulse(cex, s.nc));
    for (int i = 1; i < s.nb; i++)
        for (int k = 0; k < 3; k++) {
            assert_true(fabs(ex[i].v[k] - sp[i].v[k]) < 5 * p.tol);
            assert_true(fabs(ex[i].w[k] - sp[i].w[k]) < 5 * p.tol / HALF);
        }
    /* momentum: the floor's impulse differs by at most the stack's mass
     * times the velocity error allowed above */
    assert_true(fabs(floor_impulse(cex, s.nc) - floor_impulse(csp, s.nc)) <
                LAYERS * 1.0 * 5 * p.tol);
    stack_free(&s);
}

/* Runners that take a colour's blocks in another order or on another
 * thread, each with an arena of its own (docs/DESIGN.md 11, shared
 * blocks). */
typedef struct test_runner {
    int calls, blocks, threaded;
    sc_arena arena[2];
} test_runner;

typedef struct half {
    sc_task_fn fn;
    void *b;
    int count;
    sc_arena *a;
} half;

static void *odd_blocks(void *arg)
{
    half *h = arg;
    for (int i = 1; i < h->count; i += 2)
        h->fn(h->b, i, h->a, 1);
    return NULL;
}

static void test_run(void *ctx, sc_task_fn fn, void *b, int count, sc_arena *a)
{
    (void)a;
    test_runner *r = ctx;
    r->calls++;
    r->blocks += count;
    if (!r->threaded) {
        for (int i = count - 1; i >= 0; i--)
            fn(b, i, &r->arena[0], 1);
        return;
    }
    /* odd blocks on a thread, even ones here, at the same time */
    half h = { fn, b, count, &r->arena[1] };
    pthread_t t;
    assert_int_equal(pthread_create(&t, NULL, odd_blocks, &h), 0);
    for (int i = 0; i < count; i += 2)
        fn(b, i, &r->arena[0], 0);
    assert_int_equal(pthread_join(t, NULL), 0);
}

/* A split island's colours hold blocks that share no movable body: solved
 * in reverse order, or half on another thread at the same time, the
 * answer is the same bits as one after another (were two blocks of a
 * colour to share a part, the order would show in the bits). The island
 * is every contact of a 60-part bin. */
static void test_blocks_of_a_colour_give_the_same_bits_in_any_order_or_thread(void **state)
{
    (void)state;
    stack s;
    pile_make(&s);
    sc_body *b0 = s.out[0], *b1 = s.out[1];
    sc_contact *c0 = s.cout[0], *c1 = s.cout[1];
    sc_contact_params p = sc_frame_contact_params(&s.w->fcfg);
    sc_solve_info i0, i1;
    solve_copy(&s, &p, &i0, b0, c0);
    assert_true(i0.split >= 1);
    for (int threaded = 0; threaded < 2; threaded++) {
        test_runner r = { .threaded = threaded };
        sc_arena_init(&r.arena[0]);
        sc_arena_init(&r.arena[1]);
        sc_contact_params pr = p;
        pr.runner = (sc_task_runner[]){ { test_run, &r } };
        solve_copy(&s, &pr, &i1, b1, c1);
        print_message("%d contacts, %s: %d colours handed out, %d blocks; %d block solves\n",
                      s.nc, threaded ? "two threads" : "reverse order", r.calls, r.blocks,
                      i1.blocks);
        assert_true(r.calls > 10);
        assert_int_equal(i1.blocks, i0.blocks);
        assert_int_equal(i1.pivots, i0.pivots);
        assert_true(i1.blocks_shared > 0 && i1.blocks_shared <= r.blocks);
        assert_int_equal(i0.blocks_shared, 0);
        assert_memory_equal(b0, b1, (size_t)s.nb * sizeof *b0);
        assert_memory_equal(c0, c1, (size_t)s.nc * sizeof *c0);
        sc_arena_destroy(&r.arena[1]);
        sc_arena_destroy(&r.arena[0]);
    }
    stack_free(&s);
}

/* A stack of n boxes (the library's scene) a few frames after it is
 * placed: every contact one island. */
static void tall_make(stack *s, int n)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = 1;
    sc_world *w = sc_world_create(&cfg);
    assert_non_null(w);
    assert_int_equal(sc_scene_stack(w, n, 0), SC_OK);
    capture(s, w, 5);
    assert_true(s->nc >= 4 * n);
}

/* The same with the frame's contact parameters, every solve from 0. */
static sc_contact_params tall_cold(stack *s, int n)
{
    tall_make(s, n);
    sc_contact_params p = sc_frame_contact_params(&s->w->fcfg);
    p.cold = 1;
    return p;
}

/* The largest speed (linear velocity, m/s) by which each of the n answers
 * b[k] of the stack differs from the island solved whole from the start,
 * one exact LCP, under p otherwise, into d[k]. */
static void off_whole(stack *s, sc_contact_params p, sc_body *const *b, int n, double *d)
{
    sc_body *ex = malloc((size_t)s->nb * sizeof *ex);
    sc_contact *cex = malloc((size_t)s->nc * sizeof *cex);
    assert_true(ex && cex);
    sc_solve_info ie;
    p.split_contacts = 0;
    solve_copy(s, &p, &ie, ex, cex);
    assert_int_equal(ie.split, 0);
    for (int k = 0; k < n; k++) {
        d[k] = 0;
        for (int i = 0; i < s->nb; i++)
            for (int j = 0; j < 3; j++)
                d[k] = fmax(d[k], fabs(b[k][i].v[j] - ex[i].v[j]));
    }
    free(cex);
    free(ex);
}

/* Anderson's acceleration of block Gauss-Seidel (docs/DESIGN.md 11). Plain
 * sweeps carry a load one block a sweep: on a stack of 16 boxes solved from
 * 0, a box's weight reaches the floor only after many sweeps, and the
 * residual falls by a near constant factor a sweep, which is what the
 * acceleration removes. Both reach the tolerance; the accelerated one in
 * under half the sweeps, and their answers agree within what the tolerance
 * allows. */
static void test_anderson_reaches_the_tolerance_in_fewer_sweeps(void **state)
{
    (void)state;
    stack s;
    sc_contact_params p = tall_cold(&s, 16);
    sc_body *b0 = s.out[0], *b1 = s.out[1];
    sc_contact *c0 = s.cout[0], *c1 = s.cout[1];
    p.island_method = SC_ISLAND_BLOCK_GS;
    p.max_sweeps = 2000;
    sc_solve_info plain, aa;
    p.anderson = 0;
    solve_copy(&s, &p, &plain, b0, c0);
    p.anderson = 3;
    solve_copy(&s, &p, &aa, b1, c1);
    print_message("stack of 16, %d contacts from 0: plain %d sweeps, %d block solves, residual "
                  "%.2g m/s; Anderson (3) %d sweeps, %d block solves, residual %.2g m/s\n",
                  s.nc, plain.sweeps_max, plain.blocks, plain.residual_split, aa.sweeps_max,
                  aa.blocks, aa.residual_split);
    assert_int_equal(plain.split, 1);
    assert_int_equal(plain.unconverged + plain.diverged, 0);
    assert_int_equal(aa.unconverged + aa.diverged, 0);
    assert_true(plain.residual_split <= p.tol && aa.residual_split <= p.tol);
    assert_true(2 * aa.sweeps_max < plain.sweeps_max);
    /* against the exact answer (the island as one LCP): a row within tol
     * of its own answer leaves a chain of n boxes within n tol */
    double d[2];
    off_whole(&s, p, (sc_body *const[]){ b0, b1 }, 2, d);
    print_message("largest velocity off the exact answer: plain %.2g m/s, Anderson %.2g m/s\n",
                  d[0], d[1]);
    assert_true(d[0] < 16 * p.tol && d[1] < 16 * p.tol);
    stack_free(&s);
}

/* A block's normals are one exact LCP (docs/DESIGN.md 11): on a stack of 16
 * boxes solved from 0 by blocks, each face's four contacts carry equal
 * loads and no box turns. Rows solved one by one reach the same tolerance
 * with unequal loads and turning boxes, which a stack multiplies with its
 * height (a stack of 8 rocks and ends millimetres off). */
static void test_a_block_carries_a_face_load_evenly(void **state)
{
    (void)state;
    stack s;
    sc_contact_params p = tall_cold(&s, 16);
    sc_body *b = s.out[0];
    sc_contact *c = s.cout[0];
    p.island_method = SC_ISLAND_BLOCK_GS;
    sc_solve_info in;
    solve_copy(&s, &p, &in, b, c);
    assert_int_equal(in.split, 1);
    assert_int_equal(in.unconverged + in.diverged, 0);
    assert_true(in.residual_split <= p.tol);
    /* contacts of one pair are consecutive */
    double spread = 0, turn = 0;
    int pairs = 0;
    for (int k = 0; k < s.nc;) {
        int e = k;
        double lo = INFINITY, hi = 0;
        while (e < s.nc && c[e].body_a == c[k].body_a && c[e].body_b == c[k].body_b) {
            lo = fmin(lo, c[e].impulse[2]);
            hi = fmax(hi, c[e].impulse[2]);
            e++;
        }
        assert_true(lo > 0);
        spread = fmax(spread, (hi - lo) / hi);
        pairs++;
        k = e;
    }
    for (int i = 1; i < s.nb; i++)
        for (int j = 0; j < 3; j++)
            turn = fmax(turn, fabs(b[i].w[j]));
    print_message("stack of 16, %d pairs from 0: %d sweeps; a face's loads within %.2g of "
                  "each other, boxes turning at most %.2g rad/s\n",
                  pairs, in.sweeps_max, spread, turn);
    assert_int_equal(pairs, 16);
    assert_true(spread < 1e-6);
    assert_true(turn < 1e-9);
    stack_free(&s);
}

/* A small island that block Gauss-Seidel leaves short of the tolerance is
 * solved whole (docs/DESIGN.md 11): the stack of 16 from 0 without the
 * acceleration (hundreds of sweeps to the tolerance) stops sweeping at 60
 * (its 192 rows), and the one exact LCP from there gives the answer of
 * the island solved whole from the start. Block Gauss-Seidel alone
 * (SC_ISLAND_BLOCK_GS) does not. */
static void test_a_small_island_short_of_the_tolerance_is_solved_whole(void **state)
{
    (void)state;
    stack s;
    sc_contact_params p = tall_cold(&s, 16);
    sc_body *b0 = s.out[0];
    p.anderson = 0;
    sc_solve_info wi, gi;
    solve_copy(&s, &p, &wi, b0, s.cout[0]);
    p.island_method = SC_ISLAND_BLOCK_GS;
    solve_copy(&s, &p, &gi, s.out[1], s.cout[1]);
    print_message("stack of 16, %d contacts from 0: %d sweeps then whole (%d of %d settled), "
                  "residual %.2g m/s; block Gauss-Seidel alone %d sweeps, %d unconverged, "
                  "residual %.2g m/s\n",
                  s.nc, wi.sweeps_max, wi.whole_solved, wi.whole_tries, wi.residual_split,
                  gi.sweeps_max, gi.unconverged, gi.residual_split);
    assert_int_equal(wi.split, 1);
    assert_int_equal(wi.whole_tries, 1);
    assert_int_equal(wi.whole_solved, 1);
    assert_int_equal(wi.unconverged, 0);
    assert_int_equal(wi.sweeps_max, 60);
    assert_int_equal(gi.whole_tries, 0);
    assert_true(gi.sweeps_max > 60);
    double d;
    off_whole(&s, p, &b0, 1, &d);
    print_message("largest velocity off the island solved whole from the start: %.2g m/s\n", d);
    /* the compliance (1e-6 of A's largest diagonal entry) softens the
     * island's exact LCP and pulls the whole solve towards its iterate:
     * both far below the tolerance, which the sweeps alone miss by 15 */
    assert_true(d < 1e-4 && d < 0.1 * p.tol);
    stack_free(&s);
}

/* The stack of n from 0 without the acceleration, at most 100 sweeps, a
 * fault injected (inject): solved into wi, and by block Gauss-Seidel
 * alone. Either way the sweeps stop at the cap short of the tolerance,
 * and so do the 100 with coupled blocks after it; the solve ends on the
 * island solved whole from the start (within a tenth of the tolerance)
 * after tries whole tries, the last of them settling it; block
 * Gauss-Seidel alone unconverged. */
static void left_at_the_cap(int n, int inject, int tries, int *nc, sc_solve_info *wi)
{
    stack s;
    sc_solve_info gi;
    sc_contact_params p = tall_cold(&s, n);
    sc_body *b0 = s.out[0];
    p.anderson = 0;
    p.max_sweeps = 100;
    p.inject = inject;
    solve_copy(&s, &p, wi, b0, s.cout[0]);
    p.island_method = SC_ISLAND_BLOCK_GS;
    solve_copy(&s, &p, &gi, s.out[1], s.cout[1]);
    double d;
    off_whole(&s, p, &b0, 1, &d);
    print_message("stack of %d, %d contacts: %d sweeps, then %d of %d whole tries settled, %d "
                  "unconverged, %.2g m/s off the island solved whole from the start; block "
                  "Gauss-Seidel alone %d unconverged, residual %.2g m/s\n",
                  n, s.nc, wi->sweeps_max, wi->whole_solved, wi->whole_tries, wi->unconverged, d,
                  gi.unconverged, gi.residual_split);
    assert_int_equal(wi->split, 1);
    assert_int_equal(wi->sweeps_max, 2 * 100);
    assert_int_equal(wi->unconverged + wi->diverged, 0);
    assert_true(d < 0.1 * p.tol);
    assert_int_equal(gi.whole_tries, 0);
    assert_int_equal(gi.unconverged, 1);
    assert_true(gi.residual_split > p.tol);
    assert_int_equal(wi->whole_tries, tries);
    assert_int_equal(wi->whole_solved, 1);
    *nc = s.nc;
    stack_free(&s);
}

/* Where the whole solve's rounds do not settle, the sweeps go on to the
 * cap, and a small island still short of the tolerance there is solved
 * whole once more with Lemke's method too (docs/DESIGN.md 11): the stack
 * of 16, its rounds made to fail. */
static void test_a_small_island_left_at_the_cap_is_solved_with_lemke(void **state)
{
    (void)state;
    sc_solve_info wi;
    int nc;
    left_at_the_cap(16, SC_INJECT_ROUNDS, 2, &nc, &wi);
}

/* A bigger island (over 192 rows) that neither the active set nor the
 * sweeps settle is solved whole once more at the cap, friction by the
 * fixed point's rounds (docs/DESIGN.md 11): the stack of 24, its active
 * set made to fail. */
static void test_a_big_island_left_at_the_cap_is_solved_whole(void **state)
{
    (void)state;
    sc_solve_info wi;
    int nc;
    left_at_the_cap(24, SC_INJECT_ACTIVE_SET, 1, &nc, &wi);
    assert_true(3 * nc > 192);
    assert_int_equal(wi.as_solves, 1);
    assert_int_equal(wi.as_fallbacks, 1);
}

/* The same island, its rounds made to fail too: the last whole try's
 * rounds alone fail, and the full solve after them (its own rounds, then
 * Lemke's method where they do not settle) settles it (docs/DESIGN.md
 * 11). */
static void test_a_big_island_the_rounds_leave_is_solved_by_the_full_solve(void **state)
{
    (void)state;
    sc_solve_info wi;
    int nc;
    left_at_the_cap(24, SC_INJECT_ACTIVE_SET | SC_INJECT_ROUNDS, 2, &nc, &wi);
    assert_true(3 * nc > 192);
}

/* An island past the full solve's 600 rows gets the last whole try by
 * the rounds alone (docs/DESIGN.md 11): the stack of 64 (768 rows), its
 * active set made to fail. */
static void test_an_island_past_600_rows_gets_the_rounds(void **state)
{
    (void)state;
    sc_solve_info wi;
    int nc;
    left_at_the_cap(64, SC_INJECT_ACTIVE_SET, 1, &nc, &wi);
    assert_true(3 * nc > 600 && 3 * nc <= 800);
}

/* What the sweeps leave short at the cap sweeps on from its best iterate,
 * as many sweeps again with each block's friction coupled, before the
 * last whole try (docs/DESIGN.md 11): the stack of 24, its active set and
 * its rounds made to fail, at most 40 sweeps a run, settles within the
 * second run without a whole try. Block Gauss-Seidel alone stops short at
 * the 40. */
static void test_an_island_short_at_the_cap_sweeps_on_coupled(void **state)
{
    (void)state;
    stack s;
    sc_contact_params p = tall_cold(&s, 24);
    p.max_sweeps = 40;
    p.inject = SC_INJECT_ACTIVE_SET | SC_INJECT_ROUNDS;
    sc_solve_info wi, gi;
    solve_copy(&s, &p, &wi, s.out[0], s.cout[0]);
    p.island_method = SC_ISLAND_BLOCK_GS;
    solve_copy(&s, &p, &gi, s.out[1], s.cout[1]);
    double d;
    off_whole(&s, p, &s.out[0], 1, &d);
    print_message("stack of 24, %d contacts: %d sweeps, %d whole tries, %d unconverged, "
                  "residual %.2g m/s, %.2g m/s off the island solved whole from the start; "
                  "block Gauss-Seidel alone %d sweeps, %d unconverged, residual %.2g m/s\n",
                  s.nc, wi.sweeps_max, wi.whole_tries, wi.unconverged, wi.residual_split, d,
                  gi.sweeps_max, gi.unconverged, gi.residual_split);
    assert_true(3 * s.nc > 192);
    assert_int_equal(wi.split, 1);
    assert_int_equal(wi.whole_tries, 0);
    assert_true(wi.sweeps_max > 40 && wi.sweeps_max <= 80);
    assert_int_equal(wi.unconverged + wi.diverged, 0);
    assert_true(wi.residual_split <= p.tol);
    assert_true(d < 24 * p.tol);
    assert_int_equal(gi.sweeps_max, 40);
    assert_int_equal(gi.unconverged, 1);
    assert_true(gi.residual_split > p.tol);
    stack_free(&s);
}

/* The stack's island solved over h from contacts c0 (each copied), u*
 * made for h from the world's bodies as a substep makes it; into b, c. */
static void solve_over(const stack *s, const sc_contact_params *p, double h,
                       const sc_contact *c0, sc_solve_info *info, sc_body *b, sc_contact *c)
{
    sc_frame_state *st = &s->w->st;
    sc_body *keep = malloc((size_t)s->nb * sizeof *keep);
    assert_non_null(keep);
    memcpy(keep, st->bodies, (size_t)s->nb * sizeof *keep);
    sc_frame f = { .cfg = &s->w->fcfg, .st = st };
    sc_apply_forces(&f, h, NULL);
    memcpy(b, st->bodies, (size_t)s->nb * sizeof *b);
    memcpy(st->bodies, keep, (size_t)s->nb * sizeof *keep);
    free(keep);
    memcpy(c, c0, (size_t)s->nc * sizeof *c);
    sc_arena a;
    sc_arena_init(&a);
    memset(info, 0, sizeof *info);
    assert_int_equal(sc_island_solve(&a, b, c, s->ci, s->nc, h, p, info), SC_OK);
    sc_arena_destroy(&a);
}

/* A resting contact carries a force, and its impulse the substep it acted
 * over (impulse_dt): the next solve's warm start is scaled to its own
 * substep (docs/DESIGN.md 11). The stack of 16 solved over H, then over
 * H/4 (a back-up's) from those impulses: the floor carries a quarter of
 * the impulse, and the sweeps are fewer than from the same impulses taken
 * as they were (impulse_dt 0: four times too heavy a start). */
static void test_warm_starts_keep_the_force_over_a_shorter_substep(void **state)
{
    (void)state;
    stack s;
    tall_make(&s, 16);
    sc_contact_params p = sc_frame_contact_params(&s.w->fcfg);
    p.island_method = SC_ISLAND_BLOCK_GS;
    sc_body *b = s.out[0];
    sc_contact *c = s.cout[0], *c1 = malloc((size_t)s.nc * sizeof *c1),
               *c2 = malloc((size_t)s.nc * sizeof *c2);
    assert_true(c1 && c2);
    sc_solve_info full, scaled, plain;
    solve_over(&s, &p, H, s.c, &full, b, c);
    for (int k = 0; k < s.nc; k++)
        assert_true(c[k].impulse_dt == H);
    double w_full = floor_impulse(c, s.nc);
    solve_over(&s, &p, H / 4, c, &scaled, b, c1);
    for (int k = 0; k < s.nc; k++)
        assert_true(c1[k].impulse_dt == H / 4);
    double w_scaled = floor_impulse(c1, s.nc);
    for (int k = 0; k < s.nc; k++)
        c[k].impulse_dt = 0;
    solve_over(&s, &p, H / 4, c, &plain, b, c2);
    print_message("stack of 16 over H/4 from the impulses over H: scaled %d sweeps, %d block "
                  "solves; as they were %d sweeps, %d block solves; floor impulse %.4g of %.4g "
                  "N s\n",
                  scaled.sweeps_max, scaled.blocks, plain.sweeps_max, plain.blocks, w_scaled,
                  w_full);
    assert_int_equal(scaled.split + plain.split, 2);
    assert_int_equal(scaled.unconverged + plain.unconverged, 0);
    assert_true(fabs(w_scaled - w_full / 4) < 0.01 * w_full / 4);
    assert_true(scaled.sweeps_max < plain.sweeps_max);
    assert_true(scaled.blocks < plain.blocks);
    free(c2);
    free(c1);
    stack_free(&s);
}

/* Contacts persist from frame to frame with their impulses (the warm
 * start): a resting stack's floor contacts carry its weight, and a warm
 * exact solve takes fewer pivots than a cold one on the same island. */
static void test_resting_contacts_keep_their_impulses(void **state)
{
    (void)state;
    stack s;
    stack_make(&s);
    const double weight = LAYERS * 1.0 * 9.81 * H;
    sc_contact got[4 * LAYERS];
    int n = sc_world_contacts(s.w, got, 4 * LAYERS);
    assert_int_equal(n, 4 * LAYERS);
    assert_true(fabs(floor_impulse(got, n) - weight) < 0.02 * weight);
    /* matched, not recomputed: the contacts the solve starts from carry it */
    assert_true(fabs(floor_impulse(s.c, s.nc) - weight) < 0.02 * weight);
    sc_contact_params p = sc_frame_contact_params(&s.w->fcfg);
    sc_solve_info warm, cold;
    solve_copy(&s, &p, &warm, s.out[0], s.cout[0]);
    p.cold = 1;
    solve_copy(&s, &p, &cold, s.out[0], s.cout[0]);
    assert_true(warm.pivots < cold.pivots);
    stack_free(&s);
}

/* Kinetic energy of box body b (inertia from iw, as the solve sees it). */
static double box_energy(const sc_body *b)
{
    double ke = 0.5 * b->mass * (b->v[0] * b->v[0] + b->v[1] * b->v[1] + b->v[2] * b->v[2]);
    for (int k = 0; k < 3; k++)
        ke += 0.5 * b->w[k] * b->w[k] / b->iw[4 * k];     /* iw is diagonal here */
    return ke;
}

/* Two opposed contacts of the floor (body 0) on box b's -x face, on
 * either side of its centre line by off, normals +x and -x, depth deep. */
static void pinch(sc_contact c[2], const sc_body *b, double off, double deep)
{
    memset(c, 0, 2 * sizeof *c);
    for (int k = 0; k < 2; k++) {
        c[k].body_a = 0;
        c[k].body_b = 1;
        c[k].pos[0] = b->x[0] - HALF;
        c[k].pos[1] = b->x[1] + (k ? -off : off);
        c[k].pos[2] = b->x[2];
        c[k].normal[0] = k ? -1 : 1;
        c[k].depth = deep;
    }
}

/* A box pinched between two opposed contacts 2 cm apart (as a part caught
 * in another's hole), e = 1, moving into one of them at 1 m/s and away from
 * the other: Newton's restitution at both at once asks for a spin of about
 * 50 rad/s (8.5 J from 0.5 J). The answer is solved again with the bounce
 * scaled to the largest share that adds no energy (counted): none gained,
 * nearly all kept; one contact alone still bounces elastically, with
 * nothing counted. */
static void test_a_pinched_elastic_body_is_not_thrown(void **state)
{
    (void)state;
    stack s;
    stack_make(&s);
    sc_body *b = &s.bodies[1];
    for (int i = 0; i < s.nb; i++) {
        s.bodies[i].restitution = 1;
        s.bodies[i].friction = 0;
    }
    double v[3] = { -1, 0, 0 }, zero[3] = { 0, 0, 0 };
    memcpy(b->v, v, sizeof v);
    memcpy(b->v0, v, sizeof v);
    memcpy(b->w, zero, sizeof zero);
    memcpy(b->w0, zero, sizeof zero);
    sc_contact c[2];
    pinch(c, b, 0.01, 0);
    int ci[2] = { 0, 1 };
    sc_contact_params p = sc_frame_contact_params(&s.w->fcfg);
    sc_solve_info info;
    sc_arena a;
    sc_arena_init(&a);
    sc_body *out = s.out[0];
    double ke0 = box_energy(b);
    /* one contact: an elastic bounce */
    memcpy(out, s.bodies, (size_t)s.nb * sizeof *out);
    memset(&info, 0, sizeof info);
    assert_int_equal(sc_island_solve(&a, out, c, ci, 1, H, &p, &info), SC_OK);
    assert_int_equal(info.collisions, 1);
    assert_int_equal(info.inelastic, 0);
    assert_int_equal(info.restitution_scaled, 0);
    /* the contact point leaves at 1 m/s; no energy gained or lost */
    assert_true(fabs(out[1].v[0] - 0.01 * out[1].w[2] - 1) < 1e-5);
    assert_true(fabs(box_energy(&out[1]) - ke0) < 1e-5 * ke0);
    /* both: the bounce scaled down until it adds no energy */
    memcpy(out, s.bodies, (size_t)s.nb * sizeof *out);
    memset(&info, 0, sizeof info);
    assert_int_equal(sc_island_solve(&a, out, c, ci, 2, H, &p, &info), SC_OK);
    double ke = box_energy(&out[1]);
    print_message("pinched box: %.3f J before, %.3f J after, spin %.2f rad/s\n", ke0, ke,
                  out[1].w[2]);
    assert_int_equal(info.restitution_scaled, 1);
    assert_int_equal(info.inelastic, 0);
    assert_true(ke <= ke0 * (1 + 1e-6));
    assert_true(ke >= 0.9 * ke0);
    assert_true(fabs(out[1].w[2]) < 20);
    for (int k = 0; k < 3; k++)
        assert_true(isfinite(out[1].v[k]) && isfinite(out[1].w[k]));
    sc_arena_destroy(&a);
    stack_free(&s);
}

/* A box pinched between two opposed contacts 0.78 mm deep whose lines
 * pass 1 mm from its centre (as a bolt squeezed in a nut's hole): the
 * push-out's pseudo impulses cancel as forces and add as torques, and
 * the move that takes the depth past the slop out is a turn of 0.056 rad,
 * 7.9 mm at the box's radius of gyration sqrt(trace(I) / m). It moves by
 * no more than twice the deepest contact (1.56 mm) there; it still moves.
 * Without the limit a bolt in a bin of 200 so turned by up to 0.73 rad a
 * substep and went 4.8 mm into a nut. */
static void test_a_pinched_body_is_not_turned_by_the_push_out(void **state)
{
    (void)state;
    stack s;
    stack_make(&s);
    sc_body *b = &s.bodies[1];
    double zero[3] = { 0, 0, 0 };
    memcpy(b->v, zero, sizeof zero);
    memcpy(b->v0, zero, sizeof zero);
    memcpy(b->w, zero, sizeof zero);
    memcpy(b->w0, zero, sizeof zero);
    const double deep = 0.78e-3;
    sc_contact c[2];
    pinch(c, b, 0.001, deep);
    int ci[2] = { 0, 1 };
    sc_contact_params p = sc_frame_contact_params(&s.w->fcfg);
    sc_solve_info info;
    memset(&info, 0, sizeof info);
    sc_arena a;
    sc_arena_init(&a);
    sc_body *out = s.out[0];
    memcpy(out, s.bodies, (size_t)s.nb * sizeof *out);
    assert_int_equal(sc_island_solve(&a, out, c, ci, 2, H, &p, &info), SC_OK);
    /* the body's size as the limit counts it: sqrt(trace(I) / m) */
    double reach = sqrt((b->inertia[0] + b->inertia[4] + b->inertia[8]) / b->mass), d[3];
    v3_sub(d, out[1].x, b->x);
    double turn = q_angle_between(b->q, out[1].q);
    double move = sqrt(v3_dot(d, d)) + turn * reach;
    print_message("pinched box: turned %.4f rad, points moved up to %.3f mm\n", turn,
                  1e3 * move);
    assert_true(move <= 2 * deep * (1 + 1e-9));
    assert_true(turn > 1e-3);
    sc_arena_destroy(&a);
    stack_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_each_fallback_is_taken_counted_and_physical),
        cmocka_unit_test(test_split_island_agrees_with_the_exact_one),
        cmocka_unit_test(test_blocks_of_a_colour_give_the_same_bits_in_any_order_or_thread),
        cmocka_unit_test(test_anderson_reaches_the_tolerance_in_fewer_sweeps),
        cmocka_unit_test(test_a_block_carries_a_face_load_evenly),
        cmocka_unit_test(test_a_small_island_short_of_the_tolerance_is_solved_whole),
        cmocka_unit_test(test_a_small_island_left_at_the_cap_is_solved_with_lemke),
        cmocka_unit_test(test_a_big_island_left_at_the_cap_is_solved_whole),
        cmocka_unit_test(test_a_big_island_the_rounds_leave_is_solved_by_the_full_solve),
        cmocka_unit_test(test_an_island_past_600_rows_gets_the_rounds),
        cmocka_unit_test(test_an_island_short_at_the_cap_sweeps_on_coupled),
        cmocka_unit_test(test_warm_starts_keep_the_force_over_a_shorter_substep),
        cmocka_unit_test(test_resting_contacts_keep_their_impulses),
        cmocka_unit_test(test_a_pinched_elastic_body_is_not_thrown),
        cmocka_unit_test(test_a_pinched_body_is_not_turned_by_the_push_out),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
