/* fuzz_envelope.c - libFuzzer target for the cluster message decoders
 * (lib/cluster_msg.c). Any bytes go to sc_msg_open under a fixed key (the
 * seeds in tests/fuzz/corpus/envelope/ are sealed with it, so mutations get
 * past the MAC only there) and, as a payload, to the announce, unit,
 * result, challenge, shape request and shape decoders (a shape is rebuilt and its
 * hash checked); what opens or decodes must be consistent. The bytes are
 * also sealed and opened again, which must give them back. Built like
 * fuzz_load.c; make check replays the corpus. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "simcluster_net.h"
#include "unit_wire.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const uint8_t key[SC_KEY_BYTES] = "simcluster fuzz key, not secret";

static void check_payload(const uint8_t *data, size_t size)
{
    sc_msg_announce a;
    int rc = sc_msg_announce_decode(data, size, &a);
    if (rc == SC_OK) {
        if (a.cores < 1 || a.cores > 4096 || !(a.idle_fraction >= 0 && a.idle_fraction <= 1) ||
            !(a.speed > 0) || !isfinite(a.speed) ||
            strnlen(a.host, SC_MSG_HOST_MAX) >= SC_MSG_HOST_MAX)
            abort();
    } else if (rc != SC_EFORMAT) {
        abort();
    }
    for (int kind = SC_MSG_UNIT; kind <= SC_MSG_RESULT; kind++) {
        sc_msg_work w;
        rc = sc_msg_work_decode(kind, data, size, &w);
        if (rc == SC_OK ? !w.wire || w.len < 1 || w.len > SC_MSG_MAX_WIRE || w.unit < 0
                        : rc != SC_EFORMAT || w.wire)
            abort();
        sc_msg_work_free(&w);
    }
    for (int kind = SC_MSG_UNIT; kind <= SC_MSG_RESULT; kind++) {
        size_t off = 0, last = 0;
        sc_msg_work w;
        while (sc_msg_work_next(kind, data, size, &off, &w) == SC_OK) {
            if (off <= last || off > size || !w.wire || w.len < 1)
                abort();    /* every record moves on, within the bytes */
            last = off;
            sc_msg_work_free(&w);
        }
    }
    uint8_t nonce[SC_MSG_NONCE_BYTES];
    int64_t epoch;
    rc = sc_msg_challenge_decode(data, size, nonce, &epoch);
    if (rc == SC_OK ? epoch <= 0 : rc != SC_EFORMAT)
        abort();
    uint64_t hash;
    rc = sc_msg_shape_request_decode(data, size, &hash);
    if (rc != SC_OK && rc != SC_EFORMAT)
        abort();
    sc_shape *s;
    rc = sc_msg_shape_decode(data, size, &s);
    if (rc == SC_OK ? !s || s->kind < SC_SHAPE_SPHERE || s->kind > SC_SHAPE_MESH
                    : (rc != SC_EFORMAT && rc != SC_ENOMEM) || s)
        abort();
    sc_shape_release(s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sc_msg_guard g = { 0 };
    sc_msg m;
    int rc = sc_msg_open(key, &g, data, size, &m);
    if (rc == SC_OK) {
        if (m.kind < SC_MSG_ANNOUNCE || m.kind > SC_MSG_ANSWER || m.epoch <= 0 || m.seq < 0 ||
            m.to_epoch < 0 || !m.payload ||
            m.len + SC_MSG_OVERHEAD != size || g.accepted != 1)
            abort();
        check_payload(m.payload, m.len);
        /* the same bytes again are a replay */
        sc_msg again;
        if (sc_msg_open(key, &g, data, size, &again) != SC_EAUTH || again.payload ||
            g.dropped_replay != 1)
            abort();
    } else if ((rc != SC_EFORMAT && rc != SC_EAUTH) || m.payload ||
               g.dropped_format + g.dropped_auth + g.dropped_replay + g.dropped_stale +
                       g.dropped_misaddressed != 1) {
        abort();
    }
    sc_msg_free(&m);
    check_payload(data, size);
    /* sealing any payload of a valid size and opening it gives it back */
    uint8_t *env;
    size_t n;
    if (size >= 8 && sc_msg_seal(key, 9, 1, 1, 0, SC_MSG_SHAPE, data, size, &env, &n) == SC_OK) {
        sc_msg_guard h = { 0 };
        if (sc_msg_open(key, &h, env, n, &m) != SC_OK || m.len != size ||
            memcmp(m.payload, data, size) != 0)
            abort();
        sc_msg_free(&m);
        free(env);
    }
    return 0;
}
