/*
 * cluster_msg.h - the cluster's message layer (docs/DESIGN.md section 7.2): sealed
 * envelopes (HMAC-SHA-512/256 under a shared key, per-sender sequence numbers
 * checked against replay), the payloads they carry, and the key file.
 * The wire format is proto/simcluster.lcm, encoded by the C that lcm-gen
 * generates from it; nothing here depends on a transport.
 */
#ifndef SC_CLUSTER_MSG_H
#define SC_CLUSTER_MSG_H

#include <stddef.h>
#include <stdint.h>

#define SC_MSG_VERSION 3        /* 2: HMAC-SHA-512/256, batches; 3: announce units */
#define SC_MSG_MAX_BYTES (8u << 20)        /* a whole envelope, at most */
#define SC_MSG_OVERHEAD 64u                 /* envelope bytes besides the payload */
#define SC_MSG_MAX_PAYLOAD (SC_MSG_MAX_BYTES - SC_MSG_OVERHEAD)
#define SC_MSG_MAX_WIRE (SC_MSG_MAX_PAYLOAD - 28u)  /* unit_t / result_t bytes */
#define SC_MSG_HOST_MAX 256                 /* host name bytes, with the NUL */
#define SC_MSG_SENDERS 64                   /* senders a replay guard follows */
#define SC_MSG_WINDOW 64                    /* seqs behind the highest still accepted */
#define SC_KEY_BYTES 32

/* What an envelope's payload is (envelope_t.kind). */
enum {
    SC_MSG_ANNOUNCE = 1,        /* announce_t */
    SC_MSG_SHAPE_REQUEST = 2,   /* shape_request_t */
    SC_MSG_SHAPE = 3,           /* shape_t */
    SC_MSG_UNIT = 4,            /* unit_t */
    SC_MSG_RESULT = 5           /* result_t */
};

/* An opened message; payload is a malloc'd copy (sc_msg_free). */
typedef struct sc_msg {
    int64_t node, seq;
    int kind;
    uint8_t *payload;
    size_t len;
} sc_msg;

/* Per sender: the highest seq accepted and which of the SC_MSG_WINDOW
 * before it were (bit i: top - i). When all slots are taken the sender
 * heard from least recently is forgotten. Zero-initialise; one thread. */
typedef struct sc_msg_guard {
    struct {
        int64_t node;
        uint64_t top, seen, used;   /* used: 0 free, else last-accept stamp */
    } slot[SC_MSG_SENDERS];
    uint64_t clock;
    long dropped_format, dropped_auth, dropped_replay, accepted;
} sc_msg_guard;

/* Seal payload (len bytes, kind SC_MSG_*) from node as its message seq:
 * *out (malloc'd, *outlen bytes) is the LCM encoding of an envelope_t.
 * SC_OK, SC_EINVAL (bad kind, seq < 0, len too big) or SC_ENOMEM. */
int sc_msg_seal(const uint8_t key[SC_KEY_BYTES], int64_t node, int64_t seq, int kind,
                const void *payload, size_t len, uint8_t **out, size_t *outlen);
/* Check and open a received envelope: SC_OK with *out filled, SC_EFORMAT
 * (malformed, truncated, oversized, unknown version or kind) or SC_EAUTH
 * (bad MAC, replayed or older than the window), counted in g; SC_ENOMEM. */
int sc_msg_open(const uint8_t key[SC_KEY_BYTES], sc_msg_guard *g, const void *buf, size_t len,
                sc_msg *out);
/* Free an opened message's payload (m may be NULL). */
void sc_msg_free(sc_msg *m);

/* announce_t: a daemon's heartbeat. */
typedef struct sc_msg_announce {
    int64_t node;
    char host[SC_MSG_HOST_MAX];
    int cores;                  /* 1..4096 */
    double speed;               /* finite, > 0 */
    double idle_fraction;       /* 0..1 */
    int owner_busy;             /* 0 or 1 */
    int version;
    int64_t time_us;
    int64_t units;              /* units computed since the daemon started, >= 0 */
} sc_msg_announce;

/* unit_t or result_t: frame, unit index and the wire bytes of
 * sc_wire_unit_pack / sc_wire_result_pack. */
typedef struct sc_msg_work {
    int64_t frame;
    int unit;
    uint8_t *wire;              /* decoded: malloc'd (sc_msg_work_free) */
    size_t len;                 /* at most SC_MSG_MAX_WIRE */
    int compute_us;             /* result_t: the daemon's thread time, >= 0 */
} sc_msg_work;

/* Encode a (validated) to *out, malloc'd, *len bytes: SC_OK, SC_EINVAL, SC_ENOMEM. */
int sc_msg_announce_encode(const sc_msg_announce *a, uint8_t **out, size_t *len);
/* Decode and validate: SC_OK, SC_EFORMAT or SC_ENOMEM. */
int sc_msg_announce_decode(const void *buf, size_t len, sc_msg_announce *a);
/* The same for kind SC_MSG_UNIT (unit_t) or SC_MSG_RESULT (result_t). */
int sc_msg_work_encode(int kind, const sc_msg_work *w, uint8_t **out, size_t *len);
int sc_msg_work_decode(int kind, const void *buf, size_t len, sc_msg_work *w);
void sc_msg_work_free(sc_msg_work *w);
/* A batch: the payload of a SC_MSG_UNIT or SC_MSG_RESULT envelope is one
 * or more unit_t (result_t) encodings back to back. Decode the one at
 * *off and move *off past it: SC_OK, SC_EFORMAT (then stop), SC_ENOMEM. */
int sc_msg_work_next(int kind, const void *buf, size_t len, size_t *off, sc_msg_work *w);

/* shape_request_t: the content hash asked for (16 bytes of payload). */
int sc_msg_shape_request_encode(uint64_t hash, uint8_t **out, size_t *len);
int sc_msg_shape_request_decode(const void *buf, size_t len, uint64_t *hash);
/* shape_t: a shape's hashed content. Decoding rebuilds the shape (meshes
 * are checked as sc_shape_mesh checks them) and checks that its content
 * hash is the one the message carries: SC_OK with *out (one reference),
 * SC_EFORMAT or SC_ENOMEM. */
struct sc_shape;
int sc_msg_shape_encode(const struct sc_shape *s, uint8_t **out, size_t *len);
int sc_msg_shape_decode(const void *buf, size_t len, struct sc_shape **out);

/* Write a new random key to path as 64 hex digits and a newline, mode 0600;
 * an existing file is never overwritten: SC_OK or SC_EIO. */
int sc_key_generate(const char *path);
/* Read a key file: SC_OK, SC_EIO (cannot be opened or read, not a regular
 * file), SC_EPERM (group or others may read or write it) or SC_EFORMAT. */
int sc_key_load(const char *path, uint8_t key[SC_KEY_BYTES]);

#endif
