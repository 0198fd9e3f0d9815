/* test_cluster_msg.c - sealed cluster messages (lib/net/cluster_msg.c): what is
 * sealed opens to the same node, seq, kind and payload; a changed bit, a
 * wrong key, a truncation, a lying length field, a replay, an older epoch
 * of a sender or a message addressed to another epoch is refused with the
 * documented code and counted; a newer epoch starts afresh; payloads and key files round-trip and
 * bad ones are refused. (simcluster_net.h.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "simcluster_net.h"
#include "unit_wire.h"

static const uint8_t key[SC_KEY_BYTES] = "0123456789abcdef0123456789abcde";

static sc_msg_announce sample_announce(void)
{
    sc_msg_announce a = { .node = 42, .cores = 16, .speed = 1234.5, .idle_fraction = 0.75,
                          .owner_busy = 1, .version = SC_MSG_VERSION, .time_us = 1700000000000000,
                          .units = 123456789 };
    strcpy(a.host, "ws-17.lab");
    return a;
}

/* An announce sealed by node 42 as message seq. */
static uint8_t *sealed_announce(int64_t seq, size_t *n)
{
    sc_msg_announce a = sample_announce();
    uint8_t *pl, *env;
    size_t pn;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_OK);
    assert_int_equal(sc_msg_seal(key, 42, 1, seq, 0, SC_MSG_ANNOUNCE, pl, pn, &env, n), SC_OK);
    free(pl);
    return env;
}

static int open_once(const uint8_t *buf, size_t n, const uint8_t *k)
{
    sc_msg_guard g = { 0 };
    sc_msg m;
    int rc = sc_msg_open(k, &g, buf, n, &m);
    sc_msg_free(&m);
    return rc;
}

static void test_announce_round_trips_through_a_sealed_envelope(void **state)
{
    (void)state;
    size_t n;
    uint8_t *env = sealed_announce(7, &n);
    sc_msg_guard g = { 0 };
    sc_msg m;
    assert_int_equal(sc_msg_open(key, &g, env, n, &m), SC_OK);
    assert_int_equal(m.node, 42);
    assert_int_equal(m.seq, 7);
    assert_int_equal(m.kind, SC_MSG_ANNOUNCE);
    assert_int_equal(n, SC_MSG_OVERHEAD + m.len);
    sc_msg_announce a = sample_announce(), b;
    assert_int_equal(sc_msg_announce_decode(m.payload, m.len, &b), SC_OK);
    assert_int_equal(b.node, a.node);
    assert_string_equal(b.host, a.host);
    assert_int_equal(b.cores, a.cores);
    assert_true(b.speed == a.speed && b.idle_fraction == a.idle_fraction);
    assert_int_equal(b.owner_busy, 1);
    assert_int_equal(b.version, SC_MSG_VERSION);
    assert_int_equal(b.time_us, a.time_us);
    assert_int_equal(b.units, a.units);
    assert_int_equal(g.accepted, 1);
    assert_int_equal(g.dropped_format + g.dropped_auth + g.dropped_replay, 0);
    sc_msg_free(&m);
    sc_msg_free(&m);                    /* twice is harmless */
    free(env);
}

static void test_unit_and_result_round_trip_and_are_told_apart(void **state)
{
    (void)state;
    uint8_t wire[1000];
    for (size_t i = 0; i < sizeof wire; i++)
        wire[i] = (uint8_t)(i * 37 + 11);
    sc_msg_work w = { .frame = 123456789012, .unit = 17, .wire = wire, .len = sizeof wire,
                      .compute_us = 4321 };
    for (int kind = SC_MSG_UNIT; kind <= SC_MSG_RESULT; kind++) {
        uint8_t *pl, *env;
        size_t pn, n;
        assert_int_equal(sc_msg_work_encode(kind, &w, &pl, &pn), SC_OK);
        assert_int_equal(sc_msg_seal(key, 3, 1, 1, 0, kind, pl, pn, &env, &n), SC_OK);
        sc_msg_guard g = { 0 };
        sc_msg m;
        assert_int_equal(sc_msg_open(key, &g, env, n, &m), SC_OK);
        assert_int_equal(m.kind, kind);
        sc_msg_work r;
        assert_int_equal(sc_msg_work_decode(kind, m.payload, m.len, &r), SC_OK);
        assert_int_equal(r.frame, w.frame);
        assert_int_equal(r.unit, 17);
        assert_int_equal(r.len, sizeof wire);
        assert_memory_equal(r.wire, wire, sizeof wire);
        assert_int_equal(r.compute_us, kind == SC_MSG_RESULT ? 4321 : 0);
        sc_msg_work_free(&r);
        /* the LCM fingerprint: a unit_t is not a result_t, nor an announce_t */
        int other = kind == SC_MSG_UNIT ? SC_MSG_RESULT : SC_MSG_UNIT;
        assert_int_equal(sc_msg_work_decode(other, m.payload, m.len, &r), SC_EFORMAT);
        assert_null(r.wire);
        sc_msg_announce a;
        assert_int_equal(sc_msg_announce_decode(m.payload, m.len, &a), SC_EFORMAT);
        sc_msg_free(&m);
        free(env);
        free(pl);
    }
}

static void test_every_flipped_bit_is_refused(void **state)
{
    (void)state;
    size_t n;
    uint8_t *env = sealed_announce(1, &n);
    assert_int_equal(open_once(env, n, key), SC_OK);
    for (size_t bit = 0; bit < 8 * n; bit++) {
        env[bit / 8] ^= (uint8_t)(1u << bit % 8);
        int rc = open_once(env, n, key);
        assert_true(rc == SC_EFORMAT || rc == SC_EAUTH);
        env[bit / 8] ^= (uint8_t)(1u << bit % 8);
    }
    free(env);
}

static void test_a_wrong_key_is_an_auth_failure(void **state)
{
    (void)state;
    size_t n;
    uint8_t *env = sealed_announce(1, &n);
    uint8_t other[SC_KEY_BYTES];
    memcpy(other, key, sizeof other);
    other[31] ^= 1;
    sc_msg_guard g = { 0 };
    sc_msg m;
    assert_int_equal(sc_msg_open(other, &g, env, n, &m), SC_EAUTH);
    assert_null(m.payload);
    assert_int_equal(g.dropped_auth, 1);
    assert_int_equal(g.accepted, 0);
    free(env);
}

/* Seal an announce as seq and open it with g. */
static int open_seq(sc_msg_guard *g, int64_t node, int64_t seq)
{
    sc_msg_announce a = sample_announce();
    uint8_t *pl, *env;
    size_t pn, n;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_OK);
    assert_int_equal(sc_msg_seal(key, node, 1, seq, 0, SC_MSG_ANNOUNCE, pl, pn, &env, &n), SC_OK);
    sc_msg m;
    int rc = sc_msg_open(key, g, env, n, &m);
    sc_msg_free(&m);
    free(env);
    free(pl);
    return rc;
}

static void test_replays_are_refused_within_and_behind_the_window(void **state)
{
    (void)state;
    sc_msg_guard g = { 0 };
    assert_int_equal(open_seq(&g, 5, 100), SC_OK);
    assert_int_equal(open_seq(&g, 5, 100), SC_EAUTH);     /* the same message again */
    assert_int_equal(open_seq(&g, 5, 90), SC_OK);         /* late, inside the window: once */
    assert_int_equal(open_seq(&g, 5, 90), SC_EAUTH);
    assert_int_equal(open_seq(&g, 5, 100 - (SC_MSG_WINDOW - 1)), SC_OK);
    assert_int_equal(open_seq(&g, 5, 100 - SC_MSG_WINDOW), SC_EAUTH);   /* too old */
    assert_int_equal(open_seq(&g, 6, 100), SC_OK);        /* another sender has its own */
    assert_int_equal(open_seq(&g, 5, 101), SC_OK);
    assert_int_equal(open_seq(&g, 5, 90), SC_EAUTH);      /* still remembered after a shift */
    assert_int_equal(open_seq(&g, 5, 1000), SC_OK);       /* a jump clears the window */
    assert_int_equal(open_seq(&g, 5, 999), SC_OK);
    assert_int_equal(open_seq(&g, 5, 101), SC_EAUTH);
    assert_int_equal(g.accepted, 7);
    assert_int_equal(g.dropped_replay, 5);
    assert_int_equal(g.dropped_auth + g.dropped_format, 0);
}

static void test_the_stalest_sender_is_forgotten_when_the_table_is_full(void **state)
{
    (void)state;
    sc_msg_guard g = { 0 };
    for (int node = 0; node < SC_MSG_SENDERS; node++)
        assert_int_equal(open_seq(&g, node, 10), SC_OK);
    assert_int_equal(open_seq(&g, 0, 11), SC_OK);         /* node 0 is now the freshest */
    assert_int_equal(open_seq(&g, 1000, 1), SC_OK);       /* evicts node 1 */
    assert_int_equal(open_seq(&g, 0, 10), SC_EAUTH);
    assert_int_equal(open_seq(&g, 2, 10), SC_EAUTH);
    /* the documented limit: a forgotten sender starts afresh */
    assert_int_equal(open_seq(&g, 1, 10), SC_OK);
}

static void test_every_truncation_and_extension_is_a_format_error(void **state)
{
    (void)state;
    size_t n;
    uint8_t *env = sealed_announce(1, &n);
    sc_msg_guard g = { 0 };
    sc_msg m;
    for (size_t k = 0; k < n; k++) {
        uint8_t *cut = malloc(k ? k : 1);       /* exact size, for ASan */
        memcpy(cut, env, k);
        assert_int_equal(sc_msg_open(key, &g, cut, k, &m), SC_EFORMAT);
        assert_null(m.payload);
        free(cut);
    }
    uint8_t *longer = calloc(n + 1, 1);
    memcpy(longer, env, n);
    assert_int_equal(sc_msg_open(key, &g, longer, n + 1, &m), SC_EFORMAT);
    assert_int_equal(sc_msg_open(key, &g, NULL, 100, &m), SC_EFORMAT);
    assert_int_equal(g.dropped_format, (long)n + 2);
    assert_int_equal(g.accepted + g.dropped_auth + g.dropped_replay, 0);
    free(longer);
    free(env);
}

static void put_be32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (24 - 8 * i));
}

static void test_lying_length_fields_are_format_errors(void **state)
{
    (void)state;
    size_t n;
    uint8_t *env = sealed_announce(1, &n);
    static const uint32_t lies[] = { 0x7fffffffu, 0xffffffffu, 0x80000000u, 0, 1, 8 };
    sc_msg_guard g = { 0 };
    sc_msg m;
    for (size_t i = 0; i < sizeof lies / sizeof lies[0]; i++) {
        uint8_t *bad = malloc(n);
        memcpy(bad, env, n);
        put_be32(bad + 44, lies[i]);            /* envelope_t.len */
        assert_int_equal(sc_msg_open(key, &g, bad, n, &m), SC_EFORMAT);
        free(bad);
    }
    assert_int_equal(g.dropped_format, 6);
    /* more than SC_MSG_MAX_BYTES, whatever it says */
    size_t big = SC_MSG_MAX_BYTES + 1;
    uint8_t *huge = calloc(big, 1);
    put_be32(huge + 44, (uint32_t)(big - SC_MSG_OVERHEAD));
    assert_int_equal(sc_msg_open(key, &g, huge, big, &m), SC_EFORMAT);
    free(huge);
    /* payload lengths: the announce's host string, the unit's wire bytes */
    sc_msg_announce a = sample_announce(), b;
    uint8_t *pl;
    size_t pn;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_OK);
    for (size_t i = 0; i < sizeof lies / sizeof lies[0]; i++) {
        put_be32(pl + 16, lies[i]);
        assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_EFORMAT);
    }
    put_be32(pl + 16, (uint32_t)strlen(a.host) + 1);
    assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_OK);
    pl[20 + strlen(a.host)] = 'x';              /* no NUL */
    assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_EFORMAT);
    pl[20 + strlen(a.host)] = 0;
    pl[22] = 0;                                 /* a NUL inside */
    assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_EFORMAT);
    free(pl);
    uint8_t wire[16] = { 1 };
    sc_msg_work w = { .frame = 1, .unit = 2, .wire = wire, .len = sizeof wire }, r;
    assert_int_equal(sc_msg_work_encode(SC_MSG_UNIT, &w, &pl, &pn), SC_OK);
    for (size_t i = 0; i < sizeof lies / sizeof lies[0]; i++) {
        put_be32(pl + 20, lies[i]);
        assert_int_equal(sc_msg_work_decode(SC_MSG_UNIT, pl, pn, &r), SC_EFORMAT);
        assert_null(r.wire);
    }
    put_be32(pl + 20, sizeof wire);
    assert_int_equal(sc_msg_work_decode(SC_MSG_UNIT, pl, pn, &r), SC_OK);
    sc_msg_work_free(&r);
    for (size_t k = 0; k < pn; k++)
        assert_int_equal(sc_msg_work_decode(SC_MSG_UNIT, pl, k, &r), SC_EFORMAT);
    free(pl);
    free(env);
}

/* Write d big-endian at p (an LCM double). */
static void put_bed(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(u >> (56 - 8 * i));
}

static void test_announce_values_are_validated_both_ways(void **state)
{
    (void)state;
    uint8_t *pl;
    size_t pn;
    sc_msg_announce a = sample_announce(), b;
    a.idle_fraction = 1.5;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_EINVAL);
    a = sample_announce();
    a.speed = NAN;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_EINVAL);
    a = sample_announce();
    a.cores = 0;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_EINVAL);
    a.cores = 4097;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_EINVAL);
    a = sample_announce();
    memset(a.host, 'h', sizeof a.host);          /* no room for the NUL */
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_EINVAL);
    /* a well-formed encoding with values out of range */
    a = sample_announce();
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_OK);
    size_t idle = 20 + strlen(a.host) + 1 + 2 + 8;
    static const double bad[] = { 2.0, -0.5, NAN, INFINITY };
    for (size_t i = 0; i < 4; i++) {
        put_bed(pl + idle, bad[i]);
        assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_EFORMAT);
    }
    put_bed(pl + idle, 0.25);
    assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_OK);
    assert_true(b.idle_fraction == 0.25);
    pl[idle + 8] = 2;                           /* owner_busy neither 0 nor 1 */
    assert_int_equal(sc_msg_announce_decode(pl, pn, &b), SC_EFORMAT);
    free(pl);
}

static void test_seal_refuses_bad_arguments(void **state)
{
    (void)state;
    uint8_t pl[16] = { 0 }, *env;
    size_t n;
    assert_int_equal(sc_msg_seal(key, 1, 1, 1, 0, 0, pl, sizeof pl, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, 1, 1, 0, 99, pl, sizeof pl, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, 1, -1, 0, SC_MSG_UNIT, pl, sizeof pl, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, 1, 1, 0, SC_MSG_UNIT, pl, 4, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, 1, 1, 0, SC_MSG_UNIT, pl, SC_MSG_MAX_PAYLOAD + 1, &env, &n),
                     SC_EINVAL);
    assert_int_equal(sc_msg_seal(NULL, 1, 1, 1, 0, SC_MSG_UNIT, pl, sizeof pl, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, 0, 1, 0, SC_MSG_UNIT, pl, sizeof pl, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, -5, 1, 0, SC_MSG_UNIT, pl, sizeof pl, &env, &n), SC_EINVAL);
    assert_int_equal(sc_msg_seal(key, 1, 1, 1, -1, SC_MSG_UNIT, pl, sizeof pl, &env, &n), SC_EINVAL);
}

/* Seal kind (an announce's or a 24-byte payload) from node in epoch as
 * seq, addressed to to_epoch, and open it with g. */
static int open_at(sc_msg_guard *g, int64_t node, int64_t epoch, int64_t seq, int64_t to_epoch,
                   int kind)
{
    sc_msg_announce a = sample_announce();
    uint8_t *pl, *env, raw[24] = "a challenge-sized thing";
    size_t pn, n;
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_OK);
    int ann = kind == SC_MSG_ANNOUNCE;
    assert_int_equal(sc_msg_seal(key, node, epoch, seq, to_epoch, kind, ann ? pl : raw,
                                 ann ? pn : sizeof raw, &env, &n), SC_OK);
    sc_msg m;
    int rc = sc_msg_open(key, g, env, n, &m);
    if (rc == SC_OK) {
        assert_int_equal(m.epoch, epoch);
        assert_int_equal(m.to_epoch, to_epoch);
    } else {
        assert_null(m.payload);
    }
    sc_msg_free(&m);
    free(env);
    free(pl);
    return rc;
}

/* A restart: the new epoch is taken at seq 0 and clears the window; the
 * old epoch is refused from then on, whatever its seq. */
static void test_an_older_epoch_is_refused_and_a_newer_one_starts_afresh(void **state)
{
    (void)state;
    sc_msg_guard g = { 0 };
    const int A = SC_MSG_ANNOUNCE;
    assert_int_equal(open_at(&g, 5, 100, 500, 0, A), SC_OK);
    assert_int_equal(open_at(&g, 5, 100, 500, 0, A), SC_EAUTH);     /* a replay */
    assert_int_equal(open_at(&g, 5, 99, 1000, 0, A), SC_EAUTH);     /* an older start */
    assert_int_equal(g.dropped_stale, 1);
    assert_int_equal(g.dropped_replay, 1);
    assert_int_equal(open_at(&g, 5, 101, 0, 0, A), SC_OK);          /* restarted: seq 0 */
    assert_int_equal(g.new_epochs, 1);
    assert_int_equal(open_at(&g, 5, 101, 0, 0, A), SC_EAUTH);       /* replays in it too */
    assert_int_equal(open_at(&g, 5, 100, 501, 0, A), SC_EAUTH);     /* the old start, later */
    assert_int_equal(open_at(&g, 5, 100, 500, 0, A), SC_EAUTH);
    assert_int_equal(open_at(&g, 5, 101, 1, 0, A), SC_OK);
    assert_int_equal(open_at(&g, 6, 1, 0, 0, A), SC_OK);            /* others: their own */
    assert_int_equal(open_at(&g, 5, 101, 2, 0, A), SC_OK);
    assert_int_equal(g.accepted, 5);
    assert_int_equal(g.dropped_stale, 3);
    assert_int_equal(g.dropped_replay, 2);
    assert_int_equal(g.dropped_format + g.dropped_auth + g.dropped_misaddressed, 0);
    /* a sender forgotten on purpose (gone long enough) may come back with
     * a smaller epoch (its clock was set back) */
    sc_msg_guard_forget(&g, 5);
    assert_int_equal(open_at(&g, 5, 50, 0, 0, A), SC_OK);
    assert_int_equal(open_at(&g, 6, 1, 1, 0, A), SC_OK);            /* the others kept */
    assert_int_equal(open_at(&g, 6, 1, 0, 0, A), SC_EAUTH);
}

/* A receiver with an epoch takes only what is addressed to it (announces:
 * to nobody), and a refused message teaches its guard nothing. */
static void test_messages_for_another_epoch_are_refused(void **state)
{
    (void)state;
    sc_msg_guard g = { .epoch = 777 };
    assert_int_equal(open_at(&g, 9, 10, 1, 776, SC_MSG_UNIT), SC_EAUTH);   /* the last start */
    assert_int_equal(open_at(&g, 9, 10, 2, 0, SC_MSG_UNIT), SC_EAUTH);
    assert_int_equal(open_at(&g, 9, 10, 3, 777, SC_MSG_ANNOUNCE), SC_EAUTH);
    assert_int_equal(g.dropped_misaddressed, 3);
    assert_int_equal(g.accepted, 0);
    assert_int_equal(open_at(&g, 9, 10, 1, 777, SC_MSG_UNIT), SC_OK);      /* seq 1 unseen */
    assert_int_equal(open_at(&g, 9, 10, 2, 777, SC_MSG_CHALLENGE), SC_OK);
    assert_int_equal(open_at(&g, 9, 10, 3, 0, SC_MSG_ANNOUNCE), SC_OK);
    assert_int_equal(open_at(&g, 9, 10, 1, 777, SC_MSG_UNIT), SC_EAUTH);   /* now a replay */
    assert_int_equal(g.dropped_replay, 1);
    assert_int_equal(g.dropped_misaddressed, 3);
    assert_int_equal(g.accepted, 3);
    sc_msg_guard any = { 0 };       /* no epoch: addresses are not checked */
    assert_int_equal(open_at(&any, 9, 10, 1, 776, SC_MSG_UNIT), SC_OK);
}

/* Epochs grow with the clock; sc_msg_verify opens without counting. */
static void test_epochs_are_ordered_by_start_time(void **state)
{
    (void)state;
    int64_t e1 = sc_msg_epoch_new();
    usleep(3000);
    int64_t e2 = sc_msg_epoch_new();
    assert_true(e1 > 0 && e2 > e1);
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    int64_t ms = (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
    assert_true(SC_MSG_EPOCH_MS(e2) <= ms && SC_MSG_EPOCH_MS(e2) > ms - 1000);
    uint8_t *pl, *env;
    size_t pn, n;
    sc_msg_announce a = sample_announce();
    assert_int_equal(sc_msg_announce_encode(&a, &pl, &pn), SC_OK);
    assert_int_equal(sc_msg_seal(key, 4, e2, 0, 0, SC_MSG_ANNOUNCE, pl, pn, &env, &n), SC_OK);
    sc_msg m;
    for (int i = 0; i < 2; i++) {       /* no guard: twice is fine */
        assert_int_equal(sc_msg_verify(key, env, n, &m), SC_OK);
        assert_int_equal(m.epoch, e2);
        assert_int_equal(m.node, 4);
        sc_msg_free(&m);
    }
    env[n - 1] ^= 1;
    assert_int_equal(sc_msg_verify(key, env, n, &m), SC_EAUTH);
    assert_int_equal(sc_msg_verify(key, env, n - 1, &m), SC_EFORMAT);
    free(env);
    free(pl);
}

static void test_challenges_round_trip_and_bad_ones_are_refused(void **state)
{
    (void)state;
    uint8_t nonce[SC_MSG_NONCE_BYTES], got[SC_MSG_NONCE_BYTES], *p;
    for (int i = 0; i < SC_MSG_NONCE_BYTES; i++)
        nonce[i] = (uint8_t)(i * 29 + 3);
    size_t n;
    int64_t e = 0;
    assert_int_equal(sc_msg_challenge_encode(nonce, 0x123456789, &p, &n), SC_OK);
    assert_int_equal(sc_msg_challenge_decode(p, n, got, &e), SC_OK);
    assert_memory_equal(got, nonce, sizeof nonce);
    assert_true(e == 0x123456789);
    assert_int_equal(sc_msg_challenge_decode(p, n - 1, got, &e), SC_EFORMAT);
    p[n - 1] = 0;
    p[n - 2] = 0;
    p[n - 3] = 0;
    p[n - 4] = 0;
    p[n - 5] = 0;                       /* epoch 0 */
    assert_int_equal(sc_msg_challenge_decode(p, n, got, &e), SC_EFORMAT);
    assert_int_equal(sc_msg_challenge_encode(nonce, 0, &p, &n), SC_EINVAL);
    free(p);
    /* a challenge is not a shape request, an announce or a unit */
    assert_int_equal(sc_msg_challenge_encode(nonce, 5, &p, &n), SC_OK);
    uint64_t h;
    sc_msg_announce a;
    sc_msg_work w;
    assert_int_equal(sc_msg_shape_request_decode(p, n, &h), SC_EFORMAT);
    assert_int_equal(sc_msg_announce_decode(p, n, &a), SC_EFORMAT);
    assert_int_equal(sc_msg_work_decode(SC_MSG_UNIT, p, n, &w), SC_EFORMAT);
    free(p);
}

static void write_file(const char *path, const char *text, mode_t mode)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    assert_int_equal(chmod(path, mode), 0);
}

static void test_key_files_round_trip_and_bad_ones_are_refused(void **state)
{
    (void)state;
    char dir[] = "/tmp/sc_key_XXXXXX", path[64], other[64];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/key", dir);
    snprintf(other, sizeof other, "%s/other", dir);
    uint8_t k1[SC_KEY_BYTES], k2[SC_KEY_BYTES];
    assert_int_equal(sc_key_load(path, k1), SC_EIO);            /* missing */
    assert_int_equal(sc_key_generate(path), SC_OK);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_int_equal(st.st_mode & 0777, 0600);
    assert_int_equal(st.st_size, 2 * SC_KEY_BYTES + 1);
    assert_int_equal(sc_key_load(path, k1), SC_OK);
    assert_int_equal(sc_key_generate(path), SC_EIO);            /* never overwritten */
    assert_int_equal(sc_key_load(path, k2), SC_OK);
    assert_memory_equal(k1, k2, sizeof k1);
    assert_int_equal(sc_key_generate(other), SC_OK);            /* random: another key */
    assert_int_equal(sc_key_load(other, k2), SC_OK);
    assert_memory_not_equal(k1, k2, sizeof k1);
    assert_int_equal(chmod(path, 0644), 0);
    assert_int_equal(sc_key_load(path, k2), SC_EPERM);
    assert_int_equal(chmod(path, 0620), 0);
    assert_int_equal(sc_key_load(path, k2), SC_EPERM);
    assert_int_equal(chmod(path, 0400), 0);
    assert_int_equal(sc_key_load(path, k2), SC_OK);             /* read-only is fine */
    assert_memory_equal(k1, k2, sizeof k1);
    static const char *garbage[] = {
        "",
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeef\n",      /* 63 */
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeffa\n",    /* 65 */
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeefg\n",
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n\n",
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff ",
    };
    for (size_t i = 0; i < sizeof garbage / sizeof garbage[0]; i++) {
        unlink(other);
        write_file(other, garbage[i], 0600);
        assert_int_equal(sc_key_load(other, k2), SC_EFORMAT);
    }
    unlink(other);
    write_file(other, "00112233445566778899AABBCCDDEEFF00112233445566778899aabbccddeeff", 0600);
    assert_int_equal(sc_key_load(other, k2), SC_OK);            /* no newline, upper case */
    assert_int_equal(k2[10], 0xaa);
    assert_int_equal(sc_key_load(dir, k2), SC_EIO);             /* not a file */
    assert_int_equal(sc_key_load(NULL, k2), SC_EINVAL);
    assert_int_equal(sc_key_generate(NULL), SC_EINVAL);
    unlink(other);
    unlink(path);
    assert_int_equal(rmdir(dir), 0);
}

/* Shapes travel as their hashed content and come back with the same hash;
 * a changed byte anywhere is refused (bad lengths, or the hash no longer
 * matches the rebuilt shape). */
static void test_shapes_round_trip_and_tampered_ones_are_refused(void **state)
{
    (void)state;
    double pts[] = { 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.3, 0.3, 0.3 };
    sc_shape *shapes[] = { sc_shape_sphere(0.05), sc_shape_box(0.1, 0.2, 0.3),
                           sc_shape_plane(0, 0.6, 0.8, -1), sc_shape_convex(pts, 5),
                           sc_shape_bolt(), sc_shape_nut() };
    for (size_t k = 0; k < sizeof shapes / sizeof *shapes; k++) {
        sc_shape *s = shapes[k], *back = NULL;
        assert_non_null(s);
        uint8_t *p;
        size_t n;
        assert_int_equal(sc_msg_shape_encode(s, &p, &n), SC_OK);
        assert_int_equal(sc_msg_shape_decode(p, n, &back), SC_OK);
        assert_true(back->hash == s->hash);
        assert_int_equal(back->kind, s->kind);
        assert_int_equal(back->ntris, s->ntris);
        assert_int_equal(back->npieces, s->npieces);
        sc_shape_release(back);
        /* flip one byte at a few places: header, arrays, tail */
        size_t at[] = { 9, 17, n / 2, n - 30, n - 1 };
        for (size_t j = 0; j < sizeof at / sizeof *at; j++) {
            p[at[j]] ^= 0x40;
            int rc = sc_msg_shape_decode(p, n, &back);
            assert_int_equal(rc, SC_EFORMAT);
            assert_null(back);
            p[at[j]] ^= 0x40;
        }
        assert_int_equal(sc_msg_shape_decode(p, n - 1, &back), SC_EFORMAT);
        free(p);
        sc_shape_release(s);
    }
    uint8_t *p;
    size_t n;
    uint64_t h = 0;
    assert_int_equal(sc_msg_shape_request_encode(0xfedcba9876543210ULL, &p, &n), SC_OK);
    assert_int_equal(sc_msg_shape_request_decode(p, n, &h), SC_OK);
    assert_true(h == 0xfedcba9876543210ULL);
    assert_int_equal(sc_msg_shape_request_decode(p, n - 1, &h), SC_EFORMAT);
    free(p);
}

/* A mesh's convex pieces travel with it (the nut's 16); piece counts that
 * are zero, huge, do not add up to the points sent, or move points from
 * one piece to another are refused, and nothing is built from them. */
static void test_shape_pieces_travel_and_bad_counts_are_refused(void **state)
{
    (void)state;
    sc_shape *nut = sc_shape_nut();
    assert_non_null(nut);
    assert_int_equal(nut->npieces, 16);
    uint8_t *p;
    size_t n;
    assert_int_equal(sc_msg_shape_encode(nut, &p, &n), SC_OK);
    /* the tail: npieces (big-endian i32) and the counts */
    size_t np_at = n - 4 * 17, c0 = n - 4 * 16;
    struct { size_t at; uint32_t v; } bad[] = {
        { c0, 0 },                                      /* an empty piece */
        { c0, 0x7fffffff },                             /* more points than sent */
        { c0, (uint32_t)-3 },
        { c0, (uint32_t)nut->piece_count[0] + 1 },      /* the sum is off */
        { np_at, 17 },                                  /* one count too many */
        { np_at, (uint32_t)-1 },
    };
    sc_shape *back = NULL;
    for (size_t k = 0; k < sizeof bad / sizeof *bad; k++) {
        uint8_t keep[4];
        memcpy(keep, p + bad[k].at, 4);
        put_be32(p + bad[k].at, bad[k].v);
        assert_int_equal(sc_msg_shape_decode(p, n, &back), SC_EFORMAT);
        assert_null(back);
        memcpy(p + bad[k].at, keep, 4);
    }
    /* a point moved from piece 0 to piece 1: the same sum, other hulls */
    put_be32(p + c0, (uint32_t)nut->piece_count[0] - 1);
    put_be32(p + c0 + 4, (uint32_t)nut->piece_count[1] + 1);
    assert_int_equal(sc_msg_shape_decode(p, n, &back), SC_EFORMAT);
    assert_null(back);
    put_be32(p + c0, (uint32_t)nut->piece_count[0]);
    put_be32(p + c0 + 4, (uint32_t)nut->piece_count[1]);
    assert_int_equal(sc_msg_shape_decode(p, n, &back), SC_OK);
    assert_true(back->hash == nut->hash);
    sc_shape_release(back);
    free(p);
    sc_shape_release(nut);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_announce_round_trips_through_a_sealed_envelope),
        cmocka_unit_test(test_unit_and_result_round_trip_and_are_told_apart),
        cmocka_unit_test(test_every_flipped_bit_is_refused),
        cmocka_unit_test(test_a_wrong_key_is_an_auth_failure),
        cmocka_unit_test(test_replays_are_refused_within_and_behind_the_window),
        cmocka_unit_test(test_the_stalest_sender_is_forgotten_when_the_table_is_full),
        cmocka_unit_test(test_an_older_epoch_is_refused_and_a_newer_one_starts_afresh),
        cmocka_unit_test(test_messages_for_another_epoch_are_refused),
        cmocka_unit_test(test_epochs_are_ordered_by_start_time),
        cmocka_unit_test(test_challenges_round_trip_and_bad_ones_are_refused),
        cmocka_unit_test(test_every_truncation_and_extension_is_a_format_error),
        cmocka_unit_test(test_lying_length_fields_are_format_errors),
        cmocka_unit_test(test_announce_values_are_validated_both_ways),
        cmocka_unit_test(test_seal_refuses_bad_arguments),
        cmocka_unit_test(test_key_files_round_trip_and_bad_ones_are_refused),
        cmocka_unit_test(test_shapes_round_trip_and_tampered_ones_are_refused),
        cmocka_unit_test(test_shape_pieces_travel_and_bad_counts_are_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
