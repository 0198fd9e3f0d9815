/* test_island.c - contact-graph islands: static and sleeping bodies split
 * islands, order is canonical. (Internal API: lib/core/core.h.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "core.h"

static sc_contact ct(int a, int b)
{
    sc_contact c;
    memset(&c, 0, sizeof c);
    c.body_a = a;
    c.body_b = b;
    return c;
}

static void test_floor_does_not_merge_piles(void **state)
{
    (void)state;
    /* body 0 = floor (static); piles {1,2,3} and {4,5}; 6 alone on the floor;
     * 7 asleep touches 5 but does not join */
    unsigned char joins[8] = { 0, 1, 1, 1, 1, 1, 1, 0 };
    sc_contact c[] = { ct(0, 1), ct(0, 4), ct(1, 2), ct(2, 3), ct(0, 6), ct(4, 5), ct(5, 7) };
    sc_islands is = { 0 };
    assert_int_equal(sc_islands_build(NULL, 8, joins, c, 7, &is), SC_OK);
    assert_int_equal(is.count, 3);
    int b0[] = { 1, 2, 3 }, b1[] = { 4, 5 }, b2[] = { 6 };
    int *bs[] = { b0, b1, b2 }, nb[] = { 3, 2, 1 };
    int c0[] = { 0, 2, 3 }, c1[] = { 1, 5, 6 }, c2[] = { 4 };
    int *cs[] = { c0, c1, c2 }, nc[] = { 3, 3, 1 };
    for (int i = 0; i < 3; i++) {
        assert_int_equal(is.body_start[i + 1] - is.body_start[i], nb[i]);
        assert_memory_equal(&is.bodies[is.body_start[i]], bs[i], sizeof(int) * nb[i]);
        assert_int_equal(is.contact_start[i + 1] - is.contact_start[i], nc[i]);
        assert_memory_equal(&is.contacts[is.contact_start[i]], cs[i], sizeof(int) * nc[i]);
    }
    sc_islands_free(&is);
}

static void test_chain_in_reverse_order_is_one_island(void **state)
{
    (void)state;
    enum { N = 1000 };
    static unsigned char joins[N];
    static sc_contact c[N - 1];
    for (int i = 0; i < N; i++)
        joins[i] = 1;
    for (int i = 0; i < N - 1; i++)
        c[i] = ct(N - 2 - i, N - 1 - i);
    sc_islands is = { 0 };
    assert_int_equal(sc_islands_build(NULL, N, joins, c, N - 1, &is), SC_OK);
    assert_int_equal(is.count, 1);
    for (int i = 0; i < N; i++)
        assert_int_equal(is.bodies[i], i);
    for (int k = 0; k < N - 1; k++)
        assert_int_equal(is.contacts[k], k);
    sc_islands_free(&is);
}

static void test_bad_contacts_are_rejected(void **state)
{
    (void)state;
    unsigned char joins[2] = { 1, 1 };
    sc_contact c[] = { ct(0, 2) };
    sc_islands is = { 0 };
    assert_int_equal(sc_islands_build(NULL, 2, joins, c, 1, &is), SC_EINVAL);
    assert_int_equal(sc_islands_build(NULL, 2, joins, NULL, 0, &is), SC_OK);
    assert_int_equal(is.count, 2);
    sc_islands_free(&is);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_floor_does_not_merge_piles),
        cmocka_unit_test(test_chain_in_reverse_order_is_one_island),
        cmocka_unit_test(test_bad_contacts_are_rejected),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
