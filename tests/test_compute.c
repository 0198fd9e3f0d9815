/* The compute node of simcluster_net.h (lib/net/compute.c), as a daemon
 * uses it: a unit packed by the master decodes against a shape cache
 * (missing shapes are counted and named, not guessed), runs on its own
 * context, and its result merged on the master gives the bits a local run
 * gives. The unit keeps its shapes alive when the cache lets them go.
 * Packing and merging are the master's internals (lib/net/unit_wire.h). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "unit_wire.h"
#include "simcluster_net.h"

#define NPAIRS 3

/* A shape cache of up to two shapes; finds are counted. */
typedef struct cache {
    const sc_shape *s[2];
    int n;
    uint64_t asked[8];
    int nasked;
} cache;

static const sc_shape *find(void *ctx, uint64_t hash)
{
    cache *c = ctx;
    for (int i = 0; i < c->n; i++)
        if (sc_shape_hash(c->s[i]) == hash)
            return c->s[i];
    if (c->nasked < 8)
        c->asked[c->nasked++] = hash;
    return NULL;
}

typedef struct job_mem {
    sc_job job;
    sc_unit unit;
    sc_unit_pair pairs[NPAIRS];
    sc_contact contacts[NPAIRS * SC_MAX_PAIR_CONTACTS];
    int ncontact[NPAIRS];
} job_mem;

/* Bolt-nut pairs, the nut a little lower each time: apart, then touching,
 * then deep in the head. */
static void make_job(job_mem *m, const sc_shape *bolt, const sc_shape *nut)
{
    memset(m, 0, sizeof *m);
    for (int i = 0; i < NPAIRS; i++) {
        sc_unit_pair *p = &m->pairs[i];
        p->sa = bolt;
        p->sb = nut;
        p->body_a = 2 * i;
        p->body_b = 2 * i + 1;
        p->a0 = (sc_pose){ { 0, 0, 0 }, { 1, 0, 0, 0 } };
        p->b0 = (sc_pose){ { 0.002, 0.001, 0.06 - 0.02 * i },
                           { 0.9950041652780258, 0.0998334166468282, 0, 0 } }; /* 0.2 rad, x */
    }
    m->unit = (sc_unit){ .kind = SC_UNIT_COLLIDE, .first = 0, .count = NPAIRS };
    m->job = (sc_job){ .kind = SC_UNIT_COLLIDE, .units = &m->unit, .nunits = 1,
                       .pairs = m->pairs, .npairs = NPAIRS, .contacts = m->contacts,
                       .ncontact = m->ncontact };
}

static uint8_t *pack(const job_mem *m, size_t *len)
{
    size_t n = sc_wire_unit_pack(&m->job, &m->unit, NULL, 0);
    uint8_t *buf = malloc(n);
    assert_non_null(buf);
    assert_int_equal(sc_wire_unit_pack(&m->job, &m->unit, buf, n), n);
    *len = n;
    return buf;
}

static void test_remote_unit_gives_the_local_bits(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    assert_non_null(bolt);
    assert_non_null(nut);
    static job_mem local, remote;
    make_job(&local, bolt, nut);
    make_job(&remote, bolt, nut);
    /* a pattern in the contact slots: every field of a merged contact is
     * written as a local run writes it (the impulse 0, which the wire does
     * not carry for detection) */
    memset(local.contacts, 0xA5, sizeof local.contacts);
    memset(remote.contacts, 0x5A, sizeof remote.contacts);
    sc_np_ctx *np = sc_np_create();
    assert_non_null(np);
    sc_unit_run(np, &local.job, &local.unit);
    assert_int_equal(local.unit.rc, SC_OK);
    int touching = 0;
    for (int i = 0; i < NPAIRS; i++)
        touching += local.ncontact[i] > 0;
    assert_true(touching >= 1);     /* the test is about contacts */
    size_t len;
    uint8_t *wire = pack(&remote, &len);

    /* the cache has the bolt only: the nut is named, once, and no unit comes */
    cache c = { { bolt }, 1, { 0 }, 0 };
    sc_remote_unit *u = (sc_remote_unit *)1;
    assert_int_equal(sc_remote_unit_decode(wire, len, find, &c, &u), 1);
    assert_null(u);
    assert_true(c.nasked >= 1);
    for (int i = 0; i < c.nasked; i++)
        assert_true(c.asked[i] == sc_shape_hash(nut));

    /* with both: a unit, which holds the shapes when the cache drops them */
    sc_shape *cached_bolt = sc_shape_retain(bolt), *cached_nut = sc_shape_retain(nut);
    c = (cache){ { cached_bolt, cached_nut }, 2, { 0 }, 0 };
    assert_int_equal(sc_remote_unit_decode(wire, len, find, &c, &u), SC_OK);
    assert_non_null(u);
    assert_int_equal(c.nasked, 0);
    uint8_t *res;
    size_t rlen;
    assert_int_equal(sc_remote_unit_result(u, &res, &rlen), SC_EINVAL);   /* not run */
    sc_shape_release(cached_bolt);
    sc_shape_release(cached_nut);
    sc_compute *cc = sc_compute_create();
    assert_non_null(cc);
    assert_int_equal(sc_compute_run(cc, u), SC_OK);
    assert_int_equal(sc_remote_unit_result(u, &res, &rlen), SC_OK);
    sc_remote_unit_free(u);

    /* merged on the master: the local bits */
    remote.unit.rc = 99;
    assert_int_equal(sc_wire_result_apply(&remote.job, &remote.unit, res, rlen), SC_OK);
    assert_int_equal(remote.unit.rc, local.unit.rc);
    assert_memory_equal(remote.ncontact, local.ncontact, sizeof local.ncontact);
    for (int i = 0; i < NPAIRS; i++)
        assert_memory_equal(&remote.contacts[i * SC_MAX_PAIR_CONTACTS],
                            &local.contacts[i * SC_MAX_PAIR_CONTACTS],
                            (size_t)local.ncontact[i] * sizeof(sc_contact));
    for (int i = 0; i < NPAIRS * SC_MAX_PAIR_CONTACTS; i++)
        if (i % SC_MAX_PAIR_CONTACTS < local.ncontact[i / SC_MAX_PAIR_CONTACTS])
            for (int k = 0; k < 3; k++)
                assert_true(remote.contacts[i].impulse[k] == 0);
    free(res);
    free(wire);
    sc_compute_destroy(cc);
    sc_np_destroy(np);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

/* Truncated, padded or corrupt bytes are refused before anything runs;
 * NULL arguments are SC_EINVAL. */
static void test_bad_units_are_refused(void **state)
{
    (void)state;
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    static job_mem m;
    make_job(&m, bolt, nut);
    size_t len;
    uint8_t *wire = pack(&m, &len);
    cache c = { { bolt, nut }, 2, { 0 }, 0 };
    sc_remote_unit *u;
    for (size_t k = 0; k < len; k++) {
        int rc = sc_remote_unit_decode(wire, k, find, &c, &u);
        assert_true(rc == SC_EFORMAT || rc > 0);   /* a cut hash is a missing shape */
        assert_null(u);
    }
    uint8_t *more = calloc(1, len + 1);
    assert_non_null(more);
    memcpy(more, wire, len);
    assert_int_equal(sc_remote_unit_decode(more, len + 1, find, &c, &u), SC_EFORMAT);
    more[0] ^= 0xff;                /* the magic */
    assert_int_equal(sc_remote_unit_decode(more, len, find, &c, &u), SC_EFORMAT);
    assert_int_equal(sc_remote_unit_decode(wire, len, NULL, &c, &u), SC_EINVAL);
    assert_int_equal(sc_remote_unit_decode(wire, len, find, &c, NULL), SC_EINVAL);
    assert_int_equal(sc_compute_run(NULL, NULL), SC_EINVAL);
    sc_remote_unit_free(NULL);
    sc_compute_destroy(NULL);
    free(more);
    free(wire);
    sc_shape_release(bolt);
    sc_shape_release(nut);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_remote_unit_gives_the_local_bits),
        cmocka_unit_test(test_bad_units_are_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
