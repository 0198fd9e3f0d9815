/*
 * simcluster_net.h - the network side of libsimcluster, for programs that
 * talk to a cluster themselves (simclusterd, simcluster-top, recorders and
 * viewers): the cluster key, sealed messages and their payloads, frame
 * records (simcluster run --record/--publish), and the compute node a
 * daemon runs received work units on. A physics-only program needs only
 * simcluster.h. Message formats: proto/simcluster.lcm (LCM encodings; no
 * LCM or libsodium header is needed here). man simcluster(3) documents
 * every function below.
 */
#ifndef SIMCLUSTER_NET_H
#define SIMCLUSTER_NET_H

#include <stddef.h>
#include <stdint.h>

#include "simcluster.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- the cluster key ------------------------------------------------------ */
#define SC_KEY_BYTES 32

/* Write a new random key to path as 64 hex digits and a newline, mode 0600;
 * an existing file is never overwritten: SC_OK or SC_EIO. */
SC_API int sc_key_generate(const char *path);
/* Read a key file: SC_OK, SC_EIO (cannot be opened or read, not a regular
 * file), SC_EPERM (group or others may read or write it) or SC_EFORMAT. */
SC_API int sc_key_load(const char *path, uint8_t key[SC_KEY_BYTES]);

/* ---- sealed messages --------------------------------------------------------
 * Every message between masters and daemons is an envelope: a Poly1305 tag
 * (XChaCha20-Poly1305, nothing encrypted, nonce: the sender's id, epoch
 * and sequence number) under the shared key over all its bytes, the
 * sender's id and epoch (one
 * per process start), a sequence number per sender and epoch checked
 * against replay, and the epoch of the receiver it is addressed to.
 * Channels: SC_ANNOUNCE (heartbeats), SC_UNIT_<node> (units, challenges),
 * SC_RESULT_<node> (results, answers), SC_SHAPEREQ_<node>, SC_SHAPE_<node>,
 * <node> the receiver's id in 16 lower-case hex digits. */
#define SC_MSG_VERSION 5        /* 2: HMAC-SHA-512/256, batches; 3: announce units;
                                   4: epochs, addressed messages, challenges;
                                   5: XChaCha20-Poly1305's tag, nonce (node,
                                   epoch, seq) */
#define SC_MSG_MAX_BYTES (8u << 20)        /* a whole envelope, at most */
#define SC_MSG_OVERHEAD 64u                 /* envelope bytes besides the payload */
#define SC_MSG_MAX_PAYLOAD (SC_MSG_MAX_BYTES - SC_MSG_OVERHEAD)
#define SC_MSG_MAX_WIRE (SC_MSG_MAX_PAYLOAD - 28u)  /* unit_t / result_t bytes */
#define SC_MSG_HOST_MAX 256                 /* host name bytes, with the NUL */
#define SC_MSG_SENDERS 64                   /* senders a replay guard follows */
#define SC_MSG_WINDOW 64                    /* seqs behind the highest still accepted */
#define SC_MSG_NONCE_BYTES 16               /* a challenge's nonce */
/* An epoch is the start time (CLOCK_REALTIME, ms since 1970) shifted left
 * by SC_MSG_EPOCH_RANDOM_BITS, with random low bits: later starts have
 * larger epochs (while the clock is not set back). */
#define SC_MSG_EPOCH_RANDOM_BITS 20
#define SC_MSG_EPOCH_MS(e) ((int64_t)(e) >> SC_MSG_EPOCH_RANDOM_BITS)

/* What an envelope's payload is. */
enum {
    SC_MSG_ANNOUNCE = 1,        /* sc_msg_announce */
    SC_MSG_SHAPE_REQUEST = 2,   /* a shape's content hash */
    SC_MSG_SHAPE = 3,           /* a shape */
    SC_MSG_UNIT = 4,            /* sc_msg_work: units */
    SC_MSG_RESULT = 5,          /* sc_msg_work: results */
    SC_MSG_CHALLENGE = 6,       /* a master's nonce for a daemon (sc_msg_challenge_*) */
    SC_MSG_ANSWER = 7           /* the daemon's answer: the nonce and its epoch */
};

/* An opened message; payload is a malloc'd copy (sc_msg_free). */
typedef struct sc_msg {
    int64_t node, epoch, seq;
    int64_t to_epoch;           /* 0 for announces */
    int kind;
    uint8_t *payload;
    size_t len;
} sc_msg;

/* Per sender: its newest epoch, the highest seq accepted in it and which
 * of the SC_MSG_WINDOW before it were (bit i: top - i). A message of an
 * older epoch is refused (dropped_stale); one of a newer epoch replaces
 * the sender's state at once. When all slots are taken the sender heard
 * from least recently is forgotten. epoch: the receiver's own; when not 0,
 * every message but an announce must be addressed to it (to_epoch, else
 * dropped_misaddressed) and announces must not be addressed. Zero-
 * initialise (then set epoch); one thread. */
typedef struct sc_msg_guard {
    struct {
        int64_t node, epoch;
        uint64_t top, seen, used;   /* used: 0 free, else last-accept stamp */
    } slot[SC_MSG_SENDERS];
    uint64_t clock;
    int64_t epoch;
    long dropped_format, dropped_auth, dropped_replay, accepted;
    long dropped_stale;             /* from an older epoch of a sender than its newest */
    long dropped_misaddressed;      /* addressed to another epoch than g->epoch */
    long new_epochs;                /* senders seen again under a newer epoch */
} sc_msg_guard;

/* A new epoch for this process start (> 0; see SC_MSG_EPOCH_RANDOM_BITS). */
SC_API int64_t sc_msg_epoch_new(void);
/* Seal payload (len bytes, kind SC_MSG_*) from node in its epoch as its
 * message seq (node, epoch, seq are the tag's nonce: never repeat a seq
 * within an epoch), addressed to the receiver's epoch to_epoch (0: to anyone):
 * *out (malloc'd, *outlen bytes) is the envelope. SC_OK, SC_EINVAL (bad
 * kind, epoch <= 0, seq or to_epoch < 0, len too big) or SC_ENOMEM. */
SC_API int sc_msg_seal(const uint8_t key[SC_KEY_BYTES], int64_t node, int64_t epoch,
                       int64_t seq, int64_t to_epoch, int kind, const void *payload,
                       size_t len, uint8_t **out, size_t *outlen);
/* Check and open a received envelope: SC_OK with *out filled, SC_EFORMAT
 * (malformed, truncated, oversized, unknown version or kind) or SC_EAUTH
 * (bad tag, misaddressed, from an older epoch, replayed or older than the
 * window), counted in g; SC_ENOMEM. */
SC_API int sc_msg_open(const uint8_t key[SC_KEY_BYTES], sc_msg_guard *g, const void *buf,
                       size_t len, sc_msg *out);
/* Check an envelope's size, MAC, version and kind and open it without a
 * replay guard or counters (a message only looked at, such as another
 * daemon's heartbeat): SC_OK, SC_EFORMAT, SC_EAUTH or SC_ENOMEM. */
SC_API int sc_msg_verify(const uint8_t key[SC_KEY_BYTES], const void *buf, size_t len,
                         sc_msg *out);
/* Forget what g knows of node (its epoch and seqs): its next message is
 * taken as its first. For a sender long gone (a master frees its slot). */
SC_API void sc_msg_guard_forget(sc_msg_guard *g, int64_t node);
/* Free an opened message's payload (m may be NULL). */
SC_API void sc_msg_free(sc_msg *m);

/* A challenge's or answer's payload: nonce and the daemon's epoch (> 0).
 * SC_OK, SC_EINVAL, SC_ENOMEM; decode: SC_OK or SC_EFORMAT. */
SC_API int sc_msg_challenge_encode(const uint8_t nonce[SC_MSG_NONCE_BYTES], int64_t epoch,
                                   uint8_t **out, size_t *len);
SC_API int sc_msg_challenge_decode(const void *buf, size_t len,
                                   uint8_t nonce[SC_MSG_NONCE_BYTES], int64_t *epoch);

/* A daemon's heartbeat. */
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

/* Encode a (validated) to *out, malloc'd, *len bytes: SC_OK, SC_EINVAL, SC_ENOMEM. */
SC_API int sc_msg_announce_encode(const sc_msg_announce *a, uint8_t **out, size_t *len);
/* Decode and validate: SC_OK, SC_EFORMAT or SC_ENOMEM. */
SC_API int sc_msg_announce_decode(const void *buf, size_t len, sc_msg_announce *a);

/* Units (SC_MSG_UNIT) or results (SC_MSG_RESULT): frame (the master's job
 * serial), unit index and the unit's or result's wire bytes. */
typedef struct sc_msg_work {
    int64_t frame;
    int unit;
    uint8_t *wire;              /* decoded: malloc'd (sc_msg_work_free) */
    size_t len;                 /* at most SC_MSG_MAX_WIRE */
    int compute_us;             /* results: the daemon's thread time, >= 0 */
} sc_msg_work;

/* Encode w as kind SC_MSG_UNIT or SC_MSG_RESULT: SC_OK, SC_EINVAL, SC_ENOMEM. */
SC_API int sc_msg_work_encode(int kind, const sc_msg_work *w, uint8_t **out, size_t *len);
/* Decode exactly one: SC_OK, SC_EFORMAT or SC_ENOMEM. */
SC_API int sc_msg_work_decode(int kind, const void *buf, size_t len, sc_msg_work *w);
/* A batch (one or more encodings back to back, an envelope's payload):
 * decode the one at *off and move *off past it: SC_OK, SC_EFORMAT (then
 * stop), SC_ENOMEM. */
SC_API int sc_msg_work_next(int kind, const void *buf, size_t len, size_t *off,
                            sc_msg_work *w);
/* Free a decoded w's bytes (w may be NULL). */
SC_API void sc_msg_work_free(sc_msg_work *w);

/* A shape request: the content hash asked for. */
SC_API int sc_msg_shape_request_encode(uint64_t hash, uint8_t **out, size_t *len);
SC_API int sc_msg_shape_request_decode(const void *buf, size_t len, uint64_t *hash);
/* A shape's hashed content (SC_ETOOBIG past SC_MSG_MAX_PAYLOAD). */
SC_API int sc_msg_shape_encode(const sc_shape *s, uint8_t **out, size_t *len);
/* Rebuild a sent shape (meshes are checked as sc_shape_mesh checks them)
 * and check that its content hash is the one the message carries: SC_OK
 * with *out (one reference), SC_EFORMAT or SC_ENOMEM. */
SC_API int sc_msg_shape_decode(const void *buf, size_t len, sc_shape **out);
/* The content hash of s that shape messages and work units name it by
 * (equal content, equal hash); 0 for NULL. */
SC_API uint64_t sc_shape_hash(const sc_shape *s);

/* ---- the cluster transport ------------------------------------------------
 * The cluster's multicast traffic, read and written without LCM's network
 * code (docs/DESIGN.md section 7.1) but in LCM's UDP multicast wire format,
 * so lcm-spy and lcm-logger read it: short messages as one "LC02" datagram,
 * longer ones as "LC03" fragments. URLs as LCM's:
 * udpm://ADDR:PORT?ttl=N&recv_buf_size=B (ADDR a multicast address; ttl
 * 0..255, default 0; B the kernel receive buffer asked for, at least
 * SC_BUS_RCVBUF_MIN); other LCM providers (mpudpm://, file://, memq://,
 * tcpq://) are refused. No receive thread: sc_bus_handle() reads on the
 * caller's thread. Fragments are reassembled within a fixed budget of
 * memory whatever a header claims, and every datagram dropped, by this code
 * or by the kernel, is counted. */
#define SC_BUS_CHANNEL_MAX 63                /* channel name bytes, without the NUL */
#define SC_BUS_SUBS_MAX 16                   /* subscriptions per bus */
#define SC_BUS_RCVBUF_MIN (8 << 20)          /* receive buffer asked for, at least */
#define SC_BUS_INFLIGHT 8                    /* messages reassembled at once, per bus */
#define SC_BUS_REASM_BYTES (2 * SC_MSG_MAX_BYTES + (1u << 20))  /* their buffers, per bus */
#define SC_BUS_REASM_PROCESS_BYTES (4 * SC_BUS_REASM_BYTES)     /* all buses of a process */
typedef struct sc_bus sc_bus;
/* What a bus has received and dropped since it was opened. Every datagram
 * read is counted in datagrams and, if it is dropped, once in malformed,
 * refused or nomem; a message given up once its fragments were in (they
 * overlap) adds one to refused, one given up before (evicted) one to
 * evicted; kernel counts datagrams that never reached us. */
typedef struct sc_bus_counters {
    uint64_t datagrams;         /* datagrams read */
    uint64_t messages;          /* whole messages handed to a handler */
    uint64_t ignored;           /* messages (or their fragments) on channels
                                   this bus has no subscription for: not drops */
    uint64_t malformed;         /* too short or truncated, unknown magic, channel
                                   missing, unterminated or too long */
    uint64_t refused;           /* fragments refused: a size claim over
                                   SC_MSG_MAX_BYTES, offset, length, number or
                                   count out of range or not matching their
                                   message, duplicate, of a message not begun,
                                   no room left; messages whose fragments
                                   overlap or leave a gap */
    uint64_t evicted;           /* messages given up part-assembled (too old, or
                                   the room was needed): each counts once */
    uint64_t nomem;             /* datagrams dropped as a buffer could not be had */
    uint64_t kernel;            /* datagrams the kernel dropped, the socket's
                                   receive queue full (SO_RXQ_OVFL) */
    uint64_t reasm_bytes;       /* bytes held for reassembly now */
    int rcvbuf_bytes;           /* the kernel receive buffer obtained (0: none) */
} sc_bus_counters;
/* Called on the thread in sc_bus_handle() for each whole message on a
 * subscribed channel; data (len bytes) is valid during the call only;
 * recv_us: the real-time clock, microseconds, when its last datagram came. */
typedef void (*sc_bus_handler)(void *ctx, const char *channel, const uint8_t *data,
                               size_t len, int64_t recv_us);
/* Open url (see above): SC_OK with *out, SC_EINVAL (not a udpm:// URL, a
 * bad address, port or option), SC_EIO (a socket call failed; no route
 * to the group) or SC_ENOMEM. On error, why (may be NULL, why_len bytes)
 * gets a sentence saying what was wrong. */
SC_API int sc_bus_open(const char *url, sc_bus **out, char *why, size_t why_len);
/* Close b; NULL is a no-op. */
SC_API void sc_bus_close(sc_bus *b);
/* Call fn(ctx, ...) for each message on exactly this channel: SC_OK,
 * SC_EINVAL (name empty or over SC_BUS_CHANNEL_MAX bytes, subscribed
 * already, or SC_BUS_SUBS_MAX subscriptions made). */
SC_API int sc_bus_subscribe(sc_bus *b, const char *channel, sc_bus_handler fn, void *ctx);
/* The receiving socket, for poll() or select() (readable: call
 * sc_bus_handle); -1 for NULL. */
SC_API int sc_bus_fd(const sc_bus *b);
/* Wait up to timeout_s (0: not at all) for a datagram, then read every
 * datagram pending (at most a few thousand a call) and hand each whole
 * message to its handler: the number of messages handed, or SC_EIO. */
SC_API int sc_bus_handle(sc_bus *b, double timeout_s);
/* Send len bytes on channel, in one datagram or as fragments; any thread.
 * SC_OK, SC_EINVAL (bad channel name), SC_ETOOBIG (more than LCM's 65535
 * fragments), SC_EIO (the kernel refused a datagram). */
SC_API int sc_bus_publish(sc_bus *b, const char *channel, const void *data, size_t len);
/* The counters; call on the thread that handles b. */
SC_API void sc_bus_counters_get(const sc_bus *b, sc_bus_counters *out);
/* The datagrams dropped: malformed + refused + nomem + kernel, plus
 * evicted messages. */
SC_API uint64_t sc_bus_dropped(const sc_bus_counters *c);

/* ---- listening to the cluster ------------------------------------------- */
/* What sc_cluster_listen() heard. */
typedef struct sc_cluster_heard {
    int daemons;        /* answered the challenge, heard within 1 s, not owner-busy */
    int busy;           /* the same, owner-busy */
    int unverified;     /* heard within 1 s, not (yet) answered the challenge */
    long auth_failed;   /* messages that failed the MAC: another key, or forged */
    long dropped;       /* every message and datagram dropped, those included */
} sc_cluster_heard;
/* sc_cluster_wait() that also says what it heard (out may be NULL): with
 * too few daemons, auth_failed > 0 points at a key that differs from the
 * daemons'. The count of daemons, or a negative code. */
SC_API int sc_cluster_listen(const sc_world_config *cfg, int k, double timeout_s,
                             sc_cluster_heard *out);

/* ---- frame records -------------------------------------------------------
 * What simcluster run --record writes to an LCM event log and --publish
 * sends (unsealed): one SC_FRAME_SHAPE_CHANNEL record per distinct shape
 * (the bytes of sc_frame_shape_encode), then one SC_FRAME_STATE_CHANNEL
 * record per frame. Decoders refuse anything malformed, truncated or
 * oversized with SC_EFORMAT. */
#define SC_FRAME_SHAPE_CHANNEL "SC_SHAPE"
#define SC_FRAME_STATE_CHANNEL "SC_STATE"
#define SC_FRAME_MAX_BODIES 100001      /* the largest scene and its floor */

/* The bodies of one frame; arrays of n (pos: 3 per body, quat: 4). */
typedef struct sc_frame_record {
    int64_t frame;              /* frames stepped so far (0: the initial state) */
    double time_s;              /* simulated seconds */
    int n;                      /* bodies, 0..SC_FRAME_MAX_BODIES */
    uint64_t *shape;            /* each body's shape content hash (sc_shape_hash) */
    double *pos;                /* m */
    double *quat;               /* w, x, y, z */
    int8_t *state;              /* SC_FREE .. SC_STATIC */
} sc_frame_record;

/* Fill r with w's bodies as frame number frame at time_s, (re)allocating
 * r's arrays (r zeroed first, or from an earlier call; free with
 * sc_frame_record_free): SC_OK, SC_ETOOBIG, SC_ENOMEM. */
SC_API int sc_frame_record_capture(sc_frame_record *r, const sc_world *w, int64_t frame,
                                   double time_s);
/* Encode r to *out (malloc'd, *len bytes): SC_OK, SC_EINVAL (NULL array,
 * non-finite pose or time, state out of range), SC_ETOOBIG, SC_ENOMEM. */
SC_API int sc_frame_record_encode(const sc_frame_record *r, uint8_t **out, size_t *len);
/* Decode and check a state record into *r (arrays malloc'd, freed by
 * sc_frame_record_free; zeroed on error): SC_OK, SC_EFORMAT, SC_ENOMEM. */
SC_API int sc_frame_record_decode(const void *buf, size_t len, sc_frame_record *r);
/* Free r's arrays and zero it (r may be NULL). */
SC_API void sc_frame_record_free(sc_frame_record *r);

/* A recorded shape, as a renderer needs it. */
typedef struct sc_frame_shape {
    uint64_t hash;              /* content hash: sc_frame_record.shape */
    int kind;                   /* SC_SHAPE_* */
    double radius;              /* sphere */
    double half[3];             /* box */
    double plane[4];            /* plane: unit normal, d */
    int nverts, ntris;          /* mesh and convex: outward triangles */
    double *xyz;                /* 3 * nverts, malloc'd */
    int *tri;                   /* 3 * ntris, indices checked */
} sc_frame_shape;

/* The shape record of s (the bytes of sc_msg_shape_encode). */
SC_API int sc_frame_shape_encode(const sc_shape *s, uint8_t **out, size_t *len);
/* Decode a shape record, checked as a daemon checks a received shape
 * (rebuilt, its content hash compared): SC_OK, SC_EFORMAT, SC_ENOMEM. */
SC_API int sc_frame_shape_decode(const void *buf, size_t len, sc_frame_shape *out);
/* The hash a shape record claims, without checking the rest (to skip a
 * shape already known): SC_OK or SC_EFORMAT. */
SC_API int sc_frame_shape_hash(const void *buf, size_t len, uint64_t *hash);
/* Free out's arrays and zero it (out may be NULL). */
SC_API void sc_frame_shape_free(sc_frame_shape *out);

/* ---- the compute node ------------------------------------------------------
 * What a daemon does with a received unit (the wire bytes of an
 * SC_MSG_UNIT record): decode it against its shape cache, run it on a
 * compute thread, and send back the result's bytes. */
typedef struct sc_compute sc_compute;
typedef struct sc_remote_unit sc_remote_unit;
/* Finds a shape by content hash; NULL when the caller does not have it. */
typedef const sc_shape *(*sc_shape_find_fn)(void *ctx, uint64_t hash);

/* A compute context for the calling thread: its narrow phase runs on a
 * private copy of ODE when one can be had (else the shared one). One per
 * thread. NULL on error (sc_last_error()). */
SC_API sc_compute *sc_compute_create(void);
/* Free c (on the thread that created it); NULL is a no-op. */
SC_API void sc_compute_destroy(sc_compute *c);
/* Decode a received unit, finding its shapes through find. Returns SC_OK
 * with *out (holding a reference to each shape it uses), a count > 0 of
 * shapes find did not have (each passed to find; *out NULL: decode again
 * once they are in), or SC_EFORMAT (malformed, truncated, counts out of
 * range, NaN), SC_EINVAL, SC_ENOMEM. */
SC_API int sc_remote_unit_decode(const void *wire, size_t len, sc_shape_find_fn find,
                                 void *find_ctx, sc_remote_unit **out);
/* Run u on c (the calling thread); u's own error, if any, travels in its
 * result. SC_OK or SC_EINVAL. */
SC_API int sc_compute_run(sc_compute *c, sc_remote_unit *u);
/* The result bytes of a unit that ran, for an SC_MSG_RESULT record: *out
 * malloc'd, *len bytes. SC_OK, SC_EINVAL (not run yet) or SC_ENOMEM. */
SC_API int sc_remote_unit_result(const sc_remote_unit *u, uint8_t **out, size_t *len);
/* Free u and drop its shape references; NULL is a no-op. */
SC_API void sc_remote_unit_free(sc_remote_unit *u);

#ifdef __cplusplus
}
#endif
#endif /* SIMCLUSTER_NET_H */
