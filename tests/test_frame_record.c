/* Frame records (lib/net/frame_record.c) through the public header only:
 * states and shapes come back bit for bit, a captured frame is the world's
 * state, and every truncated, oversized or corrupt record is refused with
 * SC_EFORMAT, leaving nothing allocated. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "simcluster.h"
#include "simcluster_net.h"

/* state_t's layout (proto/simcluster.lcm): fingerprint, frame, time, n,
 * then the arrays one after another */
#define HEAD 28
#define AT_N 24
#define PER_BODY 65

static uint64_t next_bits(uint64_t *x)
{
    *x ^= *x << 13;
    *x ^= *x >> 7;
    *x ^= *x << 17;
    return *x;
}

/* A record of n bodies whose doubles use every kind of finite bit pattern
 * (negative zero, subnormals, the largest): record_free() frees it. */
static sc_frame_record make_record(int n, uint64_t seed)
{
    sc_frame_record r = { .frame = 12345678901LL, .time_s = 123.456789, .n = n };
    size_t un = n > 0 ? (size_t)n : 1;
    r.shape = calloc(un, sizeof *r.shape);
    r.pos = calloc(3 * un, sizeof *r.pos);
    r.quat = calloc(4 * un, sizeof *r.quat);
    r.state = calloc(un, sizeof *r.state);
    assert_non_null(r.shape);
    assert_non_null(r.pos);
    assert_non_null(r.quat);
    assert_non_null(r.state);
    static const double special[] = { -0.0, 4.9406564584124654e-324, 1.7976931348623157e308,
                                      -2.2250738585072014e-308, 1.0 / 3.0 };
    for (int i = 0; i < n; i++) {
        r.shape[i] = next_bits(&seed);
        for (int a = 0; a < 7; a++) {
            double v = (double)(int64_t)next_bits(&seed) * 1e-12;
            if ((i + a) % 4 == 0)
                v = special[(i + a) % 5];
            (a < 3 ? r.pos : r.quat)[a < 3 ? 3 * i + a : 4 * i + a - 3] = v;
        }
        r.state[i] = (int8_t)(i % (SC_STATIC + 1));
    }
    return r;
}

static void record_free(sc_frame_record *r)
{
    free(r->shape);
    free(r->pos);
    free(r->quat);
    free(r->state);
}

static void assert_same_record(const sc_frame_record *a, const sc_frame_record *b)
{
    assert_int_equal(a->frame, b->frame);
    assert_memory_equal(&a->time_s, &b->time_s, sizeof a->time_s);
    assert_int_equal(a->n, b->n);
    if (a->n == 0)
        return;
    assert_memory_equal(a->shape, b->shape, (size_t)a->n * sizeof *a->shape);
    assert_memory_equal(a->pos, b->pos, 3 * (size_t)a->n * sizeof *a->pos);
    assert_memory_equal(a->quat, b->quat, 4 * (size_t)a->n * sizeof *a->quat);
    assert_memory_equal(a->state, b->state, (size_t)a->n * sizeof *a->state);
}

/* A refused decode leaves a zeroed record: nothing to free. */
static void assert_refused(const uint8_t *buf, size_t len)
{
    sc_frame_record r;
    assert_int_equal(sc_frame_record_decode(buf, len, &r), SC_EFORMAT);
    assert_null(r.shape);
    assert_null(r.pos);
    assert_int_equal(r.n, 0);
}

static void test_state_round_trip_is_bit_exact(void **state)
{
    (void)state;
    for (int n = 0; n <= 40; n += 8) {
        sc_frame_record r = make_record(n, 0x9e3779b97f4a7c15ULL + (uint64_t)n);
        uint8_t *buf;
        size_t len;
        assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_OK);
        assert_int_equal(len, HEAD + (size_t)n * PER_BODY);
        sc_frame_record d;
        assert_int_equal(sc_frame_record_decode(buf, len, &d), SC_OK);
        assert_same_record(&r, &d);
        /* and encoding what was decoded gives the same bytes */
        uint8_t *again;
        size_t len2;
        assert_int_equal(sc_frame_record_encode(&d, &again, &len2), SC_OK);
        assert_int_equal(len2, len);
        assert_memory_equal(again, buf, len);
        free(again);
        free(buf);
        sc_frame_record_free(&d);
        assert_null(d.shape);
        record_free(&r);
    }
}

/* The layout is state_t's, big-endian: n and the first body's shape hash
 * are where lcm-spy and old logs expect them. */
static void test_state_bytes_are_state_t(void **state)
{
    (void)state;
    sc_frame_record r = make_record(2, 7);
    r.shape[0] = 0x0102030405060708ULL;
    uint8_t *buf;
    size_t len;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_OK);
    static const uint8_t n2[4] = { 0, 0, 0, 2 };
    static const uint8_t h[8] = { 1, 2, 3, 4, 5, 6, 7, 8 };
    assert_memory_equal(buf + AT_N, n2, 4);
    assert_memory_equal(buf + HEAD, h, 8);
    assert_int_equal(buf[len - 2], (uint8_t)r.state[0]);
    assert_int_equal(buf[len - 1], (uint8_t)r.state[1]);
    free(buf);
    record_free(&r);
}

static void test_capture_is_the_worlds_state(void **state)
{
    (void)state;
    sc_world_config c = sc_world_config_default();
    c.workers = 1;
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    assert_int_equal(sc_scene_bolts_nuts(w, 6, 3), SC_OK);
    for (int f = 0; f < 20; f++)
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
    sc_frame_record r = { 0 };
    assert_int_equal(sc_frame_record_capture(&r, w, 20, 0.2), SC_OK);
    assert_int_equal(r.n, sc_world_body_count(w));
    for (int i = 0; i < r.n; i++) {
        double p[3], q[4];
        sc_body_get_pose(w, i, p, q);
        assert_memory_equal(&r.pos[3 * i], p, sizeof p);
        assert_memory_equal(&r.quat[4 * i], q, sizeof q);
        assert_int_equal(r.state[i], sc_body_state(w, i));
        assert_true(r.shape[i] == sc_shape_hash(sc_body_shape(w, i)));
        assert_true(r.shape[i] != 0);
    }
    /* a second capture reuses the arrays */
    double *pos = r.pos;
    assert_int_equal(sc_world_step(w, 0.01), SC_OK);
    assert_int_equal(sc_frame_record_capture(&r, w, 21, 0.21), SC_OK);
    assert_ptr_equal(r.pos, pos);
    assert_int_equal(r.frame, 21);
    sc_frame_record_free(&r);
    sc_world_destroy(w);
}

static void test_encode_refuses_what_decode_would(void **state)
{
    (void)state;
    uint8_t *buf = (uint8_t *)1;
    size_t len = 1;
    sc_frame_record r = make_record(3, 11);
    assert_int_equal(sc_frame_record_encode(NULL, &buf, &len), SC_EINVAL);
    assert_null(buf);
    assert_int_equal(sc_frame_record_encode(&r, NULL, &len), SC_EINVAL);
    r.pos[4] = NAN;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_EINVAL);
    r.pos[4] = 0;
    r.quat[11] = INFINITY;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_EINVAL);
    r.quat[11] = 0;
    r.state[2] = SC_STATIC + 1;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_EINVAL);
    r.state[2] = -1;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_EINVAL);
    r.state[2] = SC_FREE;
    r.time_s = NAN;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_EINVAL);
    r.time_s = 0;
    r.frame = -1;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_EINVAL);
    r.frame = 0;
    r.n = SC_FRAME_MAX_BODIES + 1;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_ETOOBIG);
    r.n = 3;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_OK);
    free(buf);
    record_free(&r);
    sc_frame_record z = { .n = 1 };    /* arrays missing */
    assert_int_equal(sc_frame_record_encode(&z, &buf, &len), SC_EINVAL);
    assert_int_equal(sc_frame_record_decode(NULL, 0, NULL), SC_EINVAL);
    sc_frame_record_free(NULL);
}

static void test_truncated_or_padded_state_is_refused(void **state)
{
    (void)state;
    sc_frame_record r = make_record(5, 5);
    uint8_t *buf;
    size_t len;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_OK);
    for (size_t k = 0; k < len; k++)
        assert_refused(buf, k);
    uint8_t *more = malloc(len + 1);
    assert_non_null(more);
    memcpy(more, buf, len);
    more[len] = 0;
    assert_refused(more, len + 1);
    assert_refused(NULL, len);
    free(more);
    free(buf);
    record_free(&r);
}

static void put_be32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (24 - 8 * i));
}

static void test_corrupt_state_is_refused(void **state)
{
    (void)state;
    sc_frame_record r = make_record(4, 99);
    uint8_t *buf;
    size_t len;
    assert_int_equal(sc_frame_record_encode(&r, &buf, &len), SC_OK);
    uint8_t *b = malloc(len);
    assert_non_null(b);
    /* body counts that do not match the size */
    static const uint32_t counts[] = { 3, 5, 0xffffffffu, 0x80000000u, 0x7fffffffu, 1u << 30 };
    for (size_t i = 0; i < sizeof counts / sizeof *counts; i++) {
        memcpy(b, buf, len);
        put_be32(b + AT_N, counts[i]);
        assert_refused(b, len);
    }
    /* another type's fingerprint */
    memcpy(b, buf, len);
    b[3] ^= 0x40;
    assert_refused(b, len);
    /* a NaN or infinite coordinate, a state out of range, a negative frame */
    size_t pos0 = HEAD + 4 * 8, quat0 = pos0 + 4 * 24, state0 = quat0 + 4 * 32;
    const size_t at[] = { pos0 + 8, quat0 + 3 * 8, 16 };
    for (size_t i = 0; i < sizeof at / sizeof *at; i++) {
        memcpy(b, buf, len);
        memset(b + at[i], 0xff, 8);   /* a NaN */
        assert_refused(b, len);
        memcpy(b, buf, len);
        static const uint8_t inf[8] = { 0x7f, 0xf0, 0, 0, 0, 0, 0, 0 };
        memcpy(b + at[i], inf, 8);
        assert_refused(b, len);
    }
    memcpy(b, buf, len);
    b[state0 + 1] = SC_STATIC + 1;
    assert_refused(b, len);
    memcpy(b, buf, len);
    b[state0 + 3] = 0x80;
    assert_refused(b, len);
    memcpy(b, buf, len);
    b[8] = 0x80;                        /* frame < 0 */
    assert_refused(b, len);
    /* any one bit flipped: refused or decoded, never anything else */
    for (size_t k = 0; k < len * 8; k++) {
        memcpy(b, buf, len);
        b[k / 8] ^= (uint8_t)(1u << (k % 8));
        sc_frame_record d;
        int rc = sc_frame_record_decode(b, len, &d);
        assert_true(rc == SC_OK || rc == SC_EFORMAT);
        if (rc == SC_OK)
            assert_int_equal(d.n, 4);
        sc_frame_record_free(&d);
    }
    free(b);
    free(buf);
    record_free(&r);
}

/* More bodies than SC_FRAME_MAX_BODIES, with the size that many would
 * have, and a record past the message size: refused before allocating. */
static void test_oversized_state_is_refused(void **state)
{
    (void)state;
    size_t len = HEAD + (size_t)(SC_FRAME_MAX_BODIES + 1) * PER_BODY;
    uint8_t *b = calloc(1, SC_MSG_MAX_PAYLOAD + 1);
    assert_non_null(b);
    sc_frame_record r = make_record(1, 1);
    uint8_t *one;
    size_t n1;
    assert_int_equal(sc_frame_record_encode(&r, &one, &n1), SC_OK);
    memcpy(b, one, HEAD);                /* fingerprint, frame, time */
    put_be32(b + AT_N, SC_FRAME_MAX_BODIES + 1);
    assert_refused(b, len);
    assert_refused(b, SC_MSG_MAX_PAYLOAD + 1);
    free(one);
    free(b);
    record_free(&r);
}

static sc_shape *shape_n(int i)
{
    static const double pts[] = { 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.2, 0.2, 0.2 };
    switch (i) {
    case 0: return sc_shape_sphere(0.3);
    case 1: return sc_shape_box(0.1, 0.2, 0.3);
    case 2: return sc_shape_plane(0, 0, 1, -0.25);
    case 3: return sc_shape_bolt();
    default: return sc_shape_convex(pts, 5);
    }
}

static void test_shape_round_trip(void **state)
{
    (void)state;
    for (int i = 0; i < 5; i++) {
        sc_shape *s = shape_n(i);
        assert_non_null(s);
        uint8_t *buf;
        size_t len;
        assert_int_equal(sc_frame_shape_encode(s, &buf, &len), SC_OK);
        uint64_t h = 0;
        assert_int_equal(sc_frame_shape_hash(buf, len, &h), SC_OK);
        assert_true(h == sc_shape_hash(s));
        sc_frame_shape d;
        assert_int_equal(sc_frame_shape_decode(buf, len, &d), SC_OK);
        assert_true(d.hash == sc_shape_hash(s));
        assert_int_equal(d.kind, sc_shape_kind(s));
        const double *xyz;
        const int *tri;
        int nv, nt;
        if (sc_shape_mesh_data(s, &xyz, &nv, &tri, &nt) == SC_OK) {
            assert_int_equal(d.nverts, nv);
            assert_int_equal(d.ntris, nt);
            assert_memory_equal(d.xyz, xyz, 3 * (size_t)nv * sizeof *xyz);
            assert_memory_equal(d.tri, tri, 3 * (size_t)nt * sizeof *tri);
        } else {
            assert_int_equal(d.nverts, 0);
            assert_null(d.xyz);
        }
        if (i == 0)
            assert_true(d.radius == 0.3);
        if (i == 1)
            assert_true(d.half[0] == 0.1 && d.half[1] == 0.2 && d.half[2] == 0.3);
        if (i == 2)
            assert_true(d.plane[2] == 1 && d.plane[3] == -0.25);
        sc_frame_shape_free(&d);
        assert_null(d.xyz);
        /* truncated: refused, the hash too when it is cut */
        for (size_t k = 0; k < len; k += (len > 400 ? 37 : 1)) {
            assert_int_equal(sc_frame_shape_decode(buf, k, &d), SC_EFORMAT);
            assert_null(d.xyz);
            if (k < 16)
                assert_int_equal(sc_frame_shape_hash(buf, k, &h), SC_EFORMAT);
        }
        /* a hash that is not the content's */
        buf[15] ^= 1;
        assert_int_equal(sc_frame_shape_decode(buf, len, &d), SC_EFORMAT);
        free(buf);
        sc_shape_release(s);
    }
}

/* A state record is not a shape record and the other way round. */
static void test_records_are_not_taken_for_each_other(void **state)
{
    (void)state;
    sc_frame_record r = make_record(2, 2);
    uint8_t *st, *sh;
    size_t nst, nsh;
    assert_int_equal(sc_frame_record_encode(&r, &st, &nst), SC_OK);
    sc_shape *s = sc_shape_sphere(1);
    assert_int_equal(sc_frame_shape_encode(s, &sh, &nsh), SC_OK);
    sc_frame_shape d;
    uint64_t h;
    assert_int_equal(sc_frame_shape_decode(st, nst, &d), SC_EFORMAT);
    assert_int_equal(sc_frame_shape_hash(st, nst, &h), SC_EFORMAT);
    assert_refused(sh, nsh);
    assert_int_equal(sc_frame_shape_decode(NULL, 0, &d), SC_EFORMAT);
    assert_int_equal(sc_frame_shape_decode(sh, nsh, NULL), SC_EINVAL);
    sc_frame_shape_free(NULL);
    free(st);
    free(sh);
    sc_shape_release(s);
    record_free(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_state_round_trip_is_bit_exact),
        cmocka_unit_test(test_state_bytes_are_state_t),
        cmocka_unit_test(test_capture_is_the_worlds_state),
        cmocka_unit_test(test_encode_refuses_what_decode_would),
        cmocka_unit_test(test_truncated_or_padded_state_is_refused),
        cmocka_unit_test(test_corrupt_state_is_refused),
        cmocka_unit_test(test_oversized_state_is_refused),
        cmocka_unit_test(test_shape_round_trip),
        cmocka_unit_test(test_records_are_not_taken_for_each_other),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
