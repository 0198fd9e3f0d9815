/* test_arena.c - the per-frame stack arena (lib/core/arena.c): last in
 * first out, aligned, zeroed by calloc, a fallback to malloc when full that
 * the next reset turns into room, and the high-water mark. (Internal API:
 * lib/core/arena.h.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "core.h"

static void test_lifo_and_alignment(void **state)
{
    (void)state;
    sc_arena a;
    sc_arena_init(&a);
    char *p = sc_arena_alloc(&a, 3);
    double *q = sc_arena_alloc(&a, 5 * sizeof *q);
    assert_non_null(p);
    assert_non_null(q);
    assert_int_equal((uintptr_t)q % 16, 0);
    assert_int_equal(a.depth, 2);
    sc_arena_free(&a, q);
    sc_arena_free(&a, p);
    assert_int_equal(a.depth, 0);
    assert_int_equal(a.live, 0);
    sc_arena_destroy(&a);
}

static void test_overflow_falls_back_then_grows_at_reset(void **state)
{
    (void)state;
    sc_arena a;
    sc_arena_init(&a);
    /* an empty arena: everything overflows to malloc, nothing fails */
    void *p = sc_arena_alloc(&a, 1000);
    void *q = sc_arena_alloc(&a, 3000);
    assert_non_null(p);
    assert_non_null(q);
    assert_int_equal(a.overflows, 2);
    assert_true(a.high >= 4000);
    sc_arena_free(&a, q);
    sc_arena_free(&a, p);
    assert_int_equal(sc_arena_reset(&a), SC_OK);
    assert_true(a.cap >= a.high);
    /* the same frame again: no overflow, inside the block */
    p = sc_arena_alloc(&a, 1000);
    q = sc_arena_alloc(&a, 3000);
    assert_int_equal(a.overflows, 2);
    assert_true((char *)p >= a.mem && (char *)q + 3000 <= a.mem + a.cap);
    assert_int_equal(a.used, 1008 + 3008);
    sc_arena_free(&a, q);
    sc_arena_free(&a, p);
    assert_int_equal(a.used, 0);
    sc_arena_destroy(&a);
}

static void test_calloc_zeroes_reused_memory(void **state)
{
    (void)state;
    sc_arena a;
    sc_arena_init(&a);
    unsigned char *p = sc_arena_alloc(&a, 256);
    sc_arena_free(&a, p);
    assert_int_equal(sc_arena_reset(&a), SC_OK);
    p = sc_arena_alloc(&a, 256);
    memset(p, 0xab, 256);
    sc_arena_free(&a, p);
    int *z = sc_arena_calloc(&a, 64, sizeof *z);
    assert_non_null(z);
    for (int i = 0; i < 64; i++)
        assert_int_equal(z[i], 0);
    sc_arena_free(&a, z);
    /* overflowing sizes are refused, not wrapped */
    assert_null(sc_arena_calloc(&a, SIZE_MAX / 2, 4));
    assert_null(sc_arena_alloc(&a, SIZE_MAX - 4));
    assert_int_equal(a.depth, 0);
    sc_arena_destroy(&a);
}

static void test_null_arena_is_malloc(void **state)
{
    (void)state;
    int *p = sc_arena_calloc(NULL, 10, sizeof *p);
    assert_non_null(p);
    assert_int_equal(p[9], 0);
    sc_arena_free(NULL, p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lifo_and_alignment),
        cmocka_unit_test(test_overflow_falls_back_then_grows_at_reset),
        cmocka_unit_test(test_calloc_zeroes_reused_memory),
        cmocka_unit_test(test_null_arena_is_malloc),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
