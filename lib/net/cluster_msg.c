/* cluster_msg.c - sealed cluster messages, their payloads and the key file
 * (docs/DESIGN.md 7.2; formats in proto/simcluster.lcm).
 *
 * A message is an LCM envelope_t with a XChaCha20-Poly1305 tag under the
 * cluster key over every byte before it (nonce: node, epoch, seq, never
 * repeated), checked on the bytes as received before anything is decoded.
 * lcm-gen's decoders trust the lengths they read, so every length is
 * checked here on the raw bytes first and decoding starts from zero. */
#include <errno.h>
#include <fcntl.h>
#include <sodium.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "simcluster_net.h"
#include "unit_wire.h"
#include "sclcm_announce_t.h"
#include "sclcm_challenge_t.h"
#include "sclcm_envelope_t.h"
#include "sclcm_result_t.h"
#include "sclcm_shape_request_t.h"
#include "sclcm_shape_t.h"
#include "sclcm_unit_t.h"

#define FP_BYTES 8                      /* LCM type fingerprint */
#define MAC_BYTES crypto_aead_xchacha20poly1305_ietf_ABYTES
#define NONCE_AT (FP_BYTES + 2)           /* node, epoch, seq: 24 bytes */
#define ENV_LEN_AT (FP_BYTES + 2 + 8 + 8 + 8 + 8 + 2)
#define ENV_HEAD (ENV_LEN_AT + 4)
#define WORK_HEAD (FP_BYTES + 8 + 4 + 4)
#define RESULT_TAIL 4                   /* result_t: compute_us after the bytes */
#define SREQ_BYTES (FP_BYTES + 8)
#define CHAL_BYTES (FP_BYTES + SC_MSG_NONCE_BYTES + 8)
#define SHAPE_NC_AT (FP_BYTES + 8)
#define SHAPE_TAIL (1 + 8 + 3 * 8 + 4 * 8)  /* kind, radius, half, plane */
#define ANN_HOSTLEN_AT (FP_BYTES + 8)     /* then the bytes, NUL included */
#define ANN_FIXED (FP_BYTES + 8 + 4 + 2 + 8 + 8 + 1 + 2 + 8 + 8)
#define MAX_CORES 4096

_Static_assert(SC_MSG_OVERHEAD == ENV_HEAD + MAC_BYTES, "envelope overhead");
_Static_assert(SC_MSG_MAX_WIRE == SC_MSG_MAX_PAYLOAD - WORK_HEAD - RESULT_TAIL, "result_t overhead");
_Static_assert(SC_KEY_BYTES == crypto_aead_xchacha20poly1305_ietf_KEYBYTES, "key size");
_Static_assert(crypto_aead_xchacha20poly1305_ietf_NPUBBYTES == 24, "nonce: node, epoch, seq");

/* A big-endian i32 of the raw bytes, without overflow. */
static int64_t be32(const uint8_t *p)
{
    uint32_t u = (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
    return u < 0x80000000u ? (int64_t)u : (int64_t)u - 0x100000000;
}

static int known_kind(int64_t kind)
{
    return kind >= SC_MSG_ANNOUNCE && kind <= SC_MSG_ANSWER;
}

/* ---- envelopes ---- */

/* The epoch of a start: its CLOCK_REALTIME milliseconds above random low
 * bits, so that a later start of a node is a larger number and "older"
 * means something to a receiver. Time is what orders them: a clock set
 * back across a restart gives a smaller epoch, which receivers that still
 * remember the node refuse until they forget it (docs/DESIGN.md 7.2). */
int64_t sc_msg_epoch_new(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    int64_t ms = (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
    if (ms < 1)
        ms = 1;                         /* a clock before 1970: still > 0 */
    uint32_t r = sodium_init() >= 0 ? randombytes_random() : (uint32_t)ts.tv_nsec;
    ms &= ((int64_t)1 << (63 - SC_MSG_EPOCH_RANDOM_BITS)) - 1;
    return ms << SC_MSG_EPOCH_RANDOM_BITS | (int64_t)(r & ((1u << SC_MSG_EPOCH_RANDOM_BITS) - 1));
}

int sc_msg_seal(const uint8_t key[SC_KEY_BYTES], int64_t node, int64_t epoch, int64_t seq,
                int64_t to_epoch, int kind, const void *payload, size_t len, uint8_t **out,
                size_t *outlen)
{
    if (!key || !payload || !out || !outlen || !known_kind(kind) || epoch <= 0 || seq < 0 ||
        to_epoch < 0 || len < FP_BYTES || len > SC_MSG_MAX_PAYLOAD)
        return SC_EINVAL;               /* a payload is an LCM encoding: >= 8 bytes */
    *out = NULL;
    *outlen = 0;
    if (sodium_init() < 0)
        return SC_ENOMEM;
    size_t n = SC_MSG_OVERHEAD + len;
    uint8_t *buf = malloc(n);
    if (!buf)
        return SC_ENOMEM;
    sclcm_envelope_t e = { .version = SC_MSG_VERSION, .node = node, .epoch = epoch,
                           .seq = seq, .to_epoch = to_epoch, .kind = (int16_t)kind,
                           .len = (int32_t)len,
                           .payload = (uint8_t *)payload };
    int w = sclcm_envelope_t_encode(buf, 0, (int)n, &e);
    SC_ASSERT(w == (int)n);
    (void)w;
    /* nothing to encrypt: an empty message (libsodium wants its pointers) */
    unsigned char none[1] = { 0 };
    crypto_aead_xchacha20poly1305_ietf_encrypt_detached(none, buf + n - MAC_BYTES, NULL, none, 0,
                                                        buf, n - MAC_BYTES, NULL,
                                                        buf + NONCE_AT, key);
    *out = buf;
    *outlen = n;
    return SC_OK;
}

enum { GUARD_OK, GUARD_REPLAY, GUARD_STALE };

/* Record (epoch, seq) from node unless its epoch is older than the newest
 * seen, or the seq was seen or is older than the window. */
static int guard_accept(sc_msg_guard *g, int64_t node, int64_t epoch, uint64_t seq)
{
    int found = -1, victim = 0;
    for (int i = 0; i < SC_MSG_SENDERS && found < 0; i++) {
        if (g->slot[i].used && g->slot[i].node == node)
            found = i;
        else if (g->slot[i].used < g->slot[victim].used)
            victim = i;                 /* a free slot (0) or the stalest */
    }
    if (found >= 0 && epoch < g->slot[found].epoch)
        return GUARD_STALE;
    g->clock++;
    if (found < 0 || epoch > g->slot[found].epoch) {
        /* a new (or forgotten) sender, or a new start of one: its first seq */
        int i = found < 0 ? victim : found;
        if (found >= 0)
            g->new_epochs++;
        g->slot[i].node = node;
        g->slot[i].epoch = epoch;
        g->slot[i].top = seq;
        g->slot[i].seen = 1;
        g->slot[i].used = g->clock;
        return GUARD_OK;
    }
    uint64_t top = g->slot[found].top, seen = g->slot[found].seen;
    if (seq > top) {
        uint64_t d = seq - top;
        seen = d >= SC_MSG_WINDOW ? 1 : seen << d | 1;
        top = seq;
    } else {
        uint64_t d = top - seq;
        if (d >= SC_MSG_WINDOW || (seen >> d & 1))
            return GUARD_REPLAY;
        seen |= (uint64_t)1 << d;
    }
    g->slot[found].top = top;
    g->slot[found].seen = seen;
    g->slot[found].used = g->clock;
    return GUARD_OK;
}

void sc_msg_guard_forget(sc_msg_guard *g, int64_t node)
{
    for (int i = 0; g && i < SC_MSG_SENDERS; i++)
        if (g->slot[i].used && g->slot[i].node == node)
            memset(&g->slot[i], 0, sizeof g->slot[i]);
}

int sc_msg_verify(const uint8_t key[SC_KEY_BYTES], const void *buf, size_t len, sc_msg *out)
{
    if (!key || !out)
        return SC_EINVAL;
    memset(out, 0, sizeof *out);
    const uint8_t *p = buf;
    if (!p || len < SC_MSG_OVERHEAD + FP_BYTES || len > SC_MSG_MAX_BYTES ||
        be32(p + ENV_LEN_AT) != (int64_t)(len - SC_MSG_OVERHEAD))
        return SC_EFORMAT;
    if (sodium_init() < 0)
        return SC_ENOMEM;
    unsigned char none[1] = { 0 };
    if (crypto_aead_xchacha20poly1305_ietf_decrypt_detached(none, NULL, none, 0,
                                                            p + len - MAC_BYTES, p,
                                                            len - MAC_BYTES, p + NONCE_AT,
                                                            key) != 0)
        return SC_EAUTH;
    sclcm_envelope_t e;
    memset(&e, 0, sizeof e);
    int rc = SC_EFORMAT;
    if (sclcm_envelope_t_decode(p, 0, (int)len, &e) == (int)len && e.version == SC_MSG_VERSION &&
        known_kind(e.kind) && e.epoch > 0 && e.seq >= 0 && e.to_epoch >= 0 && e.payload) {
        rc = SC_ENOMEM;
        out->payload = malloc((size_t)e.len);
        if (out->payload) {
            memcpy(out->payload, e.payload, (size_t)e.len);
            out->node = e.node;
            out->epoch = e.epoch;
            out->seq = e.seq;
            out->to_epoch = e.to_epoch;
            out->kind = e.kind;
            out->len = (size_t)e.len;
            rc = SC_OK;
        }
    }
    sclcm_envelope_t_decode_cleanup(&e);
    return rc;
}

int sc_msg_open(const uint8_t key[SC_KEY_BYTES], sc_msg_guard *g, const void *buf, size_t len,
                sc_msg *out)
{
    if (!key || !g || !out)
        return SC_EINVAL;
    int rc = sc_msg_verify(key, buf, len, out);
    if (rc == SC_EFORMAT)
        g->dropped_format++;
    else if (rc == SC_EAUTH)
        g->dropped_auth++;
    if (rc != SC_OK)
        return rc;
    /* addressed to this start of the receiver (captured traffic replayed
     * to a later start is not), before the guard learns anything from it */
    if (g->epoch && (out->kind == SC_MSG_ANNOUNCE ? out->to_epoch != 0
                                                  : out->to_epoch != g->epoch)) {
        g->dropped_misaddressed++;
        sc_msg_free(out);
        memset(out, 0, sizeof *out);
        return SC_EAUTH;
    }
    int r = guard_accept(g, out->node, out->epoch, (uint64_t)out->seq);
    if (r != GUARD_OK) {
        if (r == GUARD_STALE)
            g->dropped_stale++;
        else
            g->dropped_replay++;
        sc_msg_free(out);
        memset(out, 0, sizeof *out);
        return SC_EAUTH;
    }
    g->accepted++;
    return SC_OK;
}

void sc_msg_free(sc_msg *m)
{
    if (m) {
        free(m->payload);
        m->payload = NULL;
        m->len = 0;
    }
}

/* ---- payloads ---- */

static int announce_ok(const sc_msg_announce *a)
{
    size_t n = strnlen(a->host, SC_MSG_HOST_MAX);
    return n < SC_MSG_HOST_MAX && a->cores >= 1 && a->cores <= MAX_CORES &&
           isfinite(a->speed) && a->speed > 0 && isfinite(a->idle_fraction) &&
           a->idle_fraction >= 0 && a->idle_fraction <= 1 &&
           (a->owner_busy == 0 || a->owner_busy == 1) && a->units >= 0 && a->version >= 0 &&
           a->version <= INT16_MAX;
}

int sc_msg_announce_encode(const sc_msg_announce *a, uint8_t **out, size_t *len)
{
    if (!a || !out || !len || !announce_ok(a))
        return SC_EINVAL;
    sclcm_announce_t m = { .node = a->node, .host = (char *)a->host, .cores = (int16_t)a->cores,
                           .speed = a->speed, .idle_fraction = a->idle_fraction,
                           .owner_busy = (int8_t)a->owner_busy, .version = (int16_t)a->version,
                           .time_us = a->time_us, .units = a->units };
    int n = sclcm_announce_t_encoded_size(&m);
    *out = malloc((size_t)n);
    if (!*out)
        return SC_ENOMEM;
    int w = sclcm_announce_t_encode(*out, 0, n, &m);
    SC_ASSERT(w == n);
    (void)w;
    *len = (size_t)n;
    return SC_OK;
}

int sc_msg_announce_decode(const void *buf, size_t len, sc_msg_announce *a)
{
    if (!a)
        return SC_EINVAL;
    memset(a, 0, sizeof *a);
    const uint8_t *p = buf;
    /* the host string: 1..SC_MSG_HOST_MAX bytes, its NUL last and only there */
    if (!p || len <= ANN_FIXED || len > ANN_FIXED + SC_MSG_HOST_MAX)
        return SC_EFORMAT;
    int64_t hl = be32(p + ANN_HOSTLEN_AT);
    const uint8_t *host = p + ANN_HOSTLEN_AT + 4;
    if (hl < 1 || (size_t)hl != len - ANN_FIXED || memchr(host, 0, (size_t)hl) != host + hl - 1)
        return SC_EFORMAT;
    sclcm_announce_t m;
    memset(&m, 0, sizeof m);
    int rc = SC_EFORMAT;
    if (sclcm_announce_t_decode(p, 0, (int)len, &m) == (int)len && m.host) {
        memcpy(a->host, m.host, (size_t)hl);
        a->node = m.node;
        a->cores = m.cores;
        a->speed = m.speed;
        a->idle_fraction = m.idle_fraction;
        a->owner_busy = m.owner_busy;
        a->version = m.version;
        a->time_us = m.time_us;
        a->units = m.units;
        rc = announce_ok(a) ? SC_OK : SC_EFORMAT;
    }
    sclcm_announce_t_decode_cleanup(&m);
    if (rc != SC_OK)
        memset(a, 0, sizeof *a);
    return rc;
}

int sc_msg_work_encode(int kind, const sc_msg_work *w, uint8_t **out, size_t *len)
{
    if (!w || !out || !len || (kind != SC_MSG_UNIT && kind != SC_MSG_RESULT) || !w->wire ||
        w->len < 1 || w->len > SC_MSG_MAX_WIRE || w->unit < 0 || w->compute_us < 0)
        return SC_EINVAL;
    size_t n = WORK_HEAD + w->len + (kind == SC_MSG_RESULT ? RESULT_TAIL : 0);
    *out = malloc(n);
    if (!*out)
        return SC_ENOMEM;
    int wrote;
    if (kind == SC_MSG_UNIT) {
        sclcm_unit_t m = { w->frame, w->unit, (int32_t)w->len, w->wire };
        wrote = sclcm_unit_t_encode(*out, 0, (int)n, &m);
    } else {
        sclcm_result_t m = { w->frame, w->unit, (int32_t)w->len, w->wire, w->compute_us };
        wrote = sclcm_result_t_encode(*out, 0, (int)n, &m);
    }
    SC_ASSERT(wrote == (int)n);
    (void)wrote;
    *len = n;
    return SC_OK;
}

int sc_msg_work_decode(int kind, const void *buf, size_t len, sc_msg_work *w)
{
    if (!w || (kind != SC_MSG_UNIT && kind != SC_MSG_RESULT))
        return SC_EINVAL;
    memset(w, 0, sizeof *w);
    const uint8_t *p = buf;
    size_t tail = kind == SC_MSG_RESULT ? RESULT_TAIL : 0;
    if (!p || len <= WORK_HEAD + tail || len > WORK_HEAD + SC_MSG_MAX_WIRE + tail ||
        be32(p + WORK_HEAD - 4) != (int64_t)(len - WORK_HEAD - tail))
        return SC_EFORMAT;
    int n;
    if (kind == SC_MSG_UNIT) {
        sclcm_unit_t m;
        memset(&m, 0, sizeof m);
        n = sclcm_unit_t_decode(p, 0, (int)len, &m);
        *w = (sc_msg_work){ m.frame, m.unit, m.wire, (size_t)len - WORK_HEAD, 0 };
    } else {
        sclcm_result_t m;
        memset(&m, 0, sizeof m);
        n = sclcm_result_t_decode(p, 0, (int)len, &m);
        *w = (sc_msg_work){ m.frame, m.unit, m.result, (size_t)len - WORK_HEAD - tail,
                            m.compute_us };
    }
    if (n != (int)len || !w->wire || w->unit < 0 || w->compute_us < 0) {
        sc_msg_work_free(w);
        return SC_EFORMAT;
    }
    return SC_OK;
}

int sc_msg_work_next(int kind, const void *buf, size_t len, size_t *off, sc_msg_work *w)
{
    if (!w || !off || (kind != SC_MSG_UNIT && kind != SC_MSG_RESULT))
        return SC_EINVAL;
    memset(w, 0, sizeof *w);
    const uint8_t *p = buf;
    size_t tail = kind == SC_MSG_RESULT ? RESULT_TAIL : 0;
    if (!p || *off > len || len - *off <= WORK_HEAD + tail)
        return SC_EFORMAT;
    int64_t n = be32(p + *off + WORK_HEAD - 4);
    if (n < 1 || (uint64_t)n > len - *off - WORK_HEAD - tail)
        return SC_EFORMAT;
    size_t rec = WORK_HEAD + (size_t)n + tail;
    int rc = sc_msg_work_decode(kind, p + *off, rec, w);
    if (rc == SC_OK)
        *off += rec;
    return rc;
}

void sc_msg_work_free(sc_msg_work *w)
{
    if (w) {
        free(w->wire);
        memset(w, 0, sizeof *w);
    }
}

/* ---- shapes ---- */

int sc_msg_shape_request_encode(uint64_t hash, uint8_t **out, size_t *len)
{
    if (!out || !len)
        return SC_EINVAL;
    *out = malloc(SREQ_BYTES);
    if (!*out)
        return SC_ENOMEM;
    sclcm_shape_request_t m = { (int64_t)hash };
    int n = sclcm_shape_request_t_encode(*out, 0, SREQ_BYTES, &m);
    SC_ASSERT(n == SREQ_BYTES);
    (void)n;
    *len = SREQ_BYTES;
    return SC_OK;
}

int sc_msg_shape_request_decode(const void *buf, size_t len, uint64_t *hash)
{
    sclcm_shape_request_t m;
    if (!buf || !hash || len != SREQ_BYTES ||
        sclcm_shape_request_t_decode(buf, 0, (int)len, &m) != (int)len)
        return SC_EFORMAT;
    *hash = (uint64_t)m.hash;
    return SC_OK;
}

/* ---- challenges ---- */

int sc_msg_challenge_encode(const uint8_t nonce[SC_MSG_NONCE_BYTES], int64_t epoch,
                            uint8_t **out, size_t *len)
{
    if (!nonce || !out || !len || epoch <= 0)
        return SC_EINVAL;
    *out = malloc(CHAL_BYTES);
    if (!*out)
        return SC_ENOMEM;
    sclcm_challenge_t m = { .epoch = epoch };
    memcpy(m.nonce, nonce, SC_MSG_NONCE_BYTES);
    int n = sclcm_challenge_t_encode(*out, 0, CHAL_BYTES, &m);
    SC_ASSERT(n == CHAL_BYTES);
    (void)n;
    *len = CHAL_BYTES;
    return SC_OK;
}

int sc_msg_challenge_decode(const void *buf, size_t len, uint8_t nonce[SC_MSG_NONCE_BYTES],
                            int64_t *epoch)
{
    sclcm_challenge_t m;
    if (!buf || !nonce || !epoch || len != CHAL_BYTES ||
        sclcm_challenge_t_decode(buf, 0, (int)len, &m) != (int)len || m.epoch <= 0)
        return SC_EFORMAT;
    memcpy(nonce, m.nonce, SC_MSG_NONCE_BYTES);
    *epoch = m.epoch;
    return SC_OK;
}

int sc_msg_shape_encode(const sc_shape *s, uint8_t **out, size_t *len)
{
    if (!s || !out || !len)
        return SC_EINVAL;
    int mesh = s->xyz != NULL;
    sclcm_shape_t m = { .hash = (int64_t)s->hash,
                        .ncoords = mesh ? 3 * s->nverts : 0,
                        .xyz = mesh ? s->xyz : NULL,
                        .nidx = mesh ? 3 * s->ntris : 0,
                        .tri = mesh ? (int32_t *)s->tri : NULL,
                        .kind = (int8_t)s->kind,
                        .radius = s->radius,
                        .npcoords = 3 * s->npiece_pts,
                        .pxyz = s->piece_pts,
                        .npieces = s->npieces,
                        .pcount = (int32_t *)s->piece_count };
    memcpy(m.half, s->half, sizeof m.half);
    memcpy(m.plane, s->plane, sizeof m.plane);
    int n = sclcm_shape_t_encoded_size(&m);
    if (n <= 0 || (size_t)n > SC_MSG_MAX_PAYLOAD)
        return SC_ETOOBIG;
    *out = malloc((size_t)n);
    if (!*out)
        return SC_ENOMEM;
    int w = sclcm_shape_t_encode(*out, 0, n, &m);
    SC_ASSERT(w == n);
    (void)w;
    *len = (size_t)n;
    return SC_OK;
}

int sc_msg_shape_decode(const void *buf, size_t len, sc_shape **out)
{
    if (!out)
        return SC_EINVAL;
    *out = NULL;
    const uint8_t *p = buf;
    /* the four array lengths on the raw bytes: coordinates and indices
     * each a multiple of 3 within the mesh limits, pieces within theirs,
     * and together exactly the message */
    if (!p || len < SHAPE_NC_AT + 4 + 4 + SHAPE_TAIL + 4 + 4 || len > SC_MSG_MAX_PAYLOAD)
        return SC_EFORMAT;
    int64_t nc = be32(p + SHAPE_NC_AT);
    if (nc < 0 || nc % 3 || nc > 3 * (int64_t)SC_MESH_MAX_VERTS ||
        (size_t)nc * 8 > len - (SHAPE_NC_AT + 4 + 4 + SHAPE_TAIL + 4 + 4))
        return SC_EFORMAT;
    size_t ni_at = SHAPE_NC_AT + 4 + (size_t)nc * 8;
    int64_t ni = be32(p + ni_at);
    if (ni < 0 || ni % 3 || ni > 3 * (int64_t)SC_MESH_MAX_TRIS ||
        (size_t)ni * 4 > len - (ni_at + 4 + SHAPE_TAIL + 4 + 4))
        return SC_EFORMAT;
    size_t npc_at = ni_at + 4 + (size_t)ni * 4 + SHAPE_TAIL;
    int64_t npc = be32(p + npc_at);
    if (npc < 0 || npc % 3 || npc > 3 * (int64_t)SC_MESH_MAX_VERTS ||
        (size_t)npc * 8 > len - (npc_at + 4 + 4))
        return SC_EFORMAT;
    size_t np_at = npc_at + 4 + (size_t)npc * 8;
    int64_t np = be32(p + np_at);
    if (np < 0 || np > SC_MESH_MAX_PIECES || (size_t)np * 4 != len - (np_at + 4))
        return SC_EFORMAT;
    sclcm_shape_t m;
    memset(&m, 0, sizeof m);
    int rc = SC_EFORMAT;
    if (sclcm_shape_t_decode(p, 0, (int)len, &m) == (int)len) {
        int mesh = m.kind == SC_SHAPE_MESH || m.kind == SC_SHAPE_CONVEX;
        int ok = mesh ? (nc > 0 && ni > 0) : (nc == 0 && ni == 0);
        ok = ok && isfinite(m.radius);
        for (int i = 0; i < 3; i++)
            ok = ok && isfinite(m.half[i]);
        for (int i = 0; i < 4; i++)
            ok = ok && isfinite(m.plane[i]);
        for (int64_t i = 0; ok && i < nc; i++)
            ok = isfinite(m.xyz[i]);
        /* pieces: none, or counts that add up to the points sent (each
         * count's own bounds are sc_shape_rebuild()'s) */
        int64_t sum = 0;
        for (int64_t k = 0; ok && k < np; k++) {
            ok = m.pcount[k] > 0 && m.pcount[k] <= npc / 3;
            sum += ok ? m.pcount[k] : 0;
        }
        ok = ok && (np > 0 ? sum == npc / 3 : npc == 0);
        sc_piece_set ps = { m.pxyz, m.pcount, (int)np };
        sc_shape *s = ok ? sc_shape_rebuild(m.kind, m.radius, m.half, m.plane, m.xyz,
                                            (int)(nc / 3), m.tri, (int)(ni / 3),
                                            np > 0 ? &ps : NULL)
                         : NULL;
        /* every field as sent: none the kind ignores may differ */
        if (s && s->hash == (uint64_t)m.hash && !memcmp(&s->radius, &m.radius, sizeof m.radius) &&
            !memcmp(s->half, m.half, sizeof m.half) && !memcmp(s->plane, m.plane, sizeof m.plane)) {
            *out = s;
            rc = SC_OK;
        } else {
            rc = !s && ok && sc_last_error() == SC_ENOMEM ? SC_ENOMEM : SC_EFORMAT;
            sc_shape_release(s);
        }
    }
    sclcm_shape_t_decode_cleanup(&m);
    return rc;
}

uint64_t sc_shape_hash(const sc_shape *s)
{
    return s ? s->hash : 0;
}

/* ---- key files ---- */

int sc_key_generate(const char *path)
{
    if (!path)
        return SC_EINVAL;
    if (sodium_init() < 0)
        return SC_EIO;
    uint8_t key[SC_KEY_BYTES];
    char hex[2 * SC_KEY_BYTES + 1];
    randombytes_buf(key, sizeof key);
    sodium_bin2hex(hex, sizeof hex, key, sizeof key);
    hex[2 * SC_KEY_BYTES] = '\n';
    sodium_memzero(key, sizeof key);
    /* O_EXCL: never replaces a key (or follows a link planted in its place) */
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    int rc = fd < 0 ? SC_EIO : SC_OK;
    if (fd >= 0) {
        size_t done = 0;
        while (rc == SC_OK && done < sizeof hex) {
            ssize_t w = write(fd, hex + done, sizeof hex - done);
            if (w > 0)
                done += (size_t)w;
            else if (w < 0 && errno != EINTR)
                rc = SC_EIO;
        }
        if (rc == SC_OK && fsync(fd) != 0)
            rc = SC_EIO;
        if (close(fd) != 0)
            rc = SC_EIO;
        if (rc != SC_OK)
            unlink(path);
    }
    sodium_memzero(hex, sizeof hex);
    return rc;
}

static int hexval(char c)
{
    return c >= '0' && c <= '9' ? c - '0'
         : c >= 'a' && c <= 'f' ? c - 'a' + 10
         : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

int sc_key_load(const char *path, uint8_t key[SC_KEY_BYTES])
{
    if (!path || !key)
        return SC_EINVAL;
    int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0)
        return SC_EIO;
    struct stat st;
    char text[2 * SC_KEY_BYTES + 2];    /* the digits, a newline, and one more to see excess */
    size_t n = 0;
    int rc = fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) ? SC_EIO
           : st.st_mode & (S_IRWXG | S_IRWXO) ? SC_EPERM : SC_OK;
    while (rc == SC_OK && n < sizeof text) {
        ssize_t r = read(fd, text + n, sizeof text - n);
        if (r > 0)
            n += (size_t)r;
        else if (r == 0)
            break;
        else if (errno != EINTR)
            rc = SC_EIO;
    }
    close(fd);
    uint8_t k[SC_KEY_BYTES];
    if (rc == SC_OK && !(n == 2 * SC_KEY_BYTES ||
                         (n == 2 * SC_KEY_BYTES + 1 && text[2 * SC_KEY_BYTES] == '\n')))
        rc = SC_EFORMAT;
    for (int i = 0; rc == SC_OK && i < SC_KEY_BYTES; i++) {
        int hi = hexval(text[2 * i]), lo = hexval(text[2 * i + 1]);
        if (hi < 0 || lo < 0)
            rc = SC_EFORMAT;
        else
            k[i] = (uint8_t)(hi << 4 | lo);
    }
    if (rc == SC_OK)
        memcpy(key, k, sizeof k);
    sodium_memzero(k, sizeof k);
    sodium_memzero(text, sizeof text);
    return rc;
}
