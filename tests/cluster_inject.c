/* cluster_inject.c - hostile traffic for the cluster tests (tests/cluster.sh,
 * daemon.sh, top.sh): publishes raw bytes on one channel, as an attacker on
 * the network could, so that a test can check that simclusterd (or a
 * master, or simcluster-top) drops and counts them and carries on.
 *   usage: cluster_inject --url URL --key FILE --channel CH
 *                         --mode garbage|wrongkey|truncated|replay|oversize|
 *                                frag-wrap|frag-huge|frag-4g
 *                         [--count N (20)] [--node ID] [--pace-us US (2000)]
 *                         [--to-epoch E]
 *          cluster_inject --url URL --channel CH --mode capture --file F
 *                         [--count N] [--seconds S (5)]
 *          cluster_inject --url URL --channel CH --mode resend --file F
 * Modes, and the receiver's counter each packet should raise:
 *   garbage    random bytes, 1..4000 of them              dropped_format
 *   wrongkey   a well-formed SC_MSG_UNIT envelope sealed
 *              under a random key                          dropped_auth
 *   truncated  a correctly sealed envelope cut short       dropped_format
 *   replay     one correctly sealed SC_MSG_UNIT envelope
 *              (a unit_t whose wire bytes are garbage) N
 *              times with the same seq: the first is
 *              accepted (the unit fails: unit_errors), the
 *              rest are replays                            dropped_replay
 *   oversize   a sealed envelope whose len field claims
 *              more bytes than the packet holds            dropped_format
 * and, as raw LC03 datagrams (LCM's fragments) that no envelope check
 * sees, the transport's counter (dropped_net; sc_bus_counters.refused):
 *   frag-wrap  two datagrams: a first fragment of a 100000-byte message
 *              on CH, then its second at offset 0xFFFFFFF0 (LCM 1.3.1
 *              checks offset + size in 32 bits, wraps and writes far
 *              past its buffer)                            refused, and the
 *              half message evicted later
 *   frag-huge  a first fragment on CH claiming a 256 MB message (LCM
 *              mallocs what it is told)                    refused
 *   frag-4g    the same claiming 0xFFFFFFFF bytes           refused
 * Every packet of a run comes from one sender id (--node, else random),
 * addressed to the receiver's epoch --to-epoch (a daemon's counters line
 * says it; else 0: every message but an announce is then misaddressed);
 * --pace-us 0 sends the packets in one burst.
 * Prints one line "sent N packets (MODE) to CH as node ID".
 *   capture    records what is published on CH (at most N messages or S
 *              seconds) to F, as an eavesdropper could; prints "captured N"
 *   resend     publishes the messages in F on CH again, paced, as they
 *              were: a replay of captured traffic; prints "resent N"
 * Exit 0, 1 on an error, 2 on a usage error. */
#include <errno.h>
#include <getopt.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bus.h"
#include "lc03.h"
#include "simcluster_net.h"
#include "simcluster.h"

#define ENV_LEN_AT (8 + 2 + 8 + 8 + 8 + 8 + 2)  /* fingerprint, version, node, epoch, seq,
                                                   to_epoch, kind */
#define GARBAGE_MAX 4000
#define PACE_US 2000L                   /* between packets, by default */
#define WRAP_SIZE 100000u               /* frag-wrap's message */

enum { GARBAGE, WRONGKEY, TRUNCATED, REPLAY, OVERSIZE, FRAG_WRAP, FRAG_HUGE, FRAG_4G, CAPTURE,
       RESEND, NMODES };
static const char *const mode_names[NMODES] = { "garbage",   "wrongkey",  "truncated", "replay",
                                                "oversize",  "frag-wrap", "frag-huge", "frag-4g",
                                                "capture",   "resend" };
static long long to_epoch;          /* the receiver's epoch the envelopes name */

static int usage(FILE *f, int status)
{
    fprintf(f, "usage: cluster_inject --url URL --key FILE --channel CH\n"
               "                      --mode garbage|wrongkey|truncated|replay|oversize|\n"
               "                             frag-wrap|frag-huge|frag-4g\n"
               "                      [--count N (20)] [--node ID] [--pace-us US (2000)]\n"
               "                      [--to-epoch E]\n"
               "       cluster_inject --url URL --channel CH --mode capture --file F\n"
               "                      [--count N] [--seconds S (5)]\n"
               "       cluster_inject --url URL --channel CH --mode resend --file F\n");
    return status;
}

/* A sealed SC_MSG_UNIT envelope under key: a valid unit_t encoding whose
 * wire bytes are random (no unit decodes from them). */
static int unit_envelope(const uint8_t *key, int64_t node, int64_t seq, uint8_t **env,
                         size_t *n)
{
    uint8_t wire[64];
    randombytes_buf(wire, sizeof wire);
    sc_msg_work u = { .frame = 1, .unit = 0, .wire = wire, .len = sizeof wire };
    uint8_t *pl;
    size_t pn;
    int rc = sc_msg_work_encode(SC_MSG_UNIT, &u, &pl, &pn);
    if (rc != SC_OK)
        return rc;
    rc = sc_msg_seal(key, node, 1, seq, to_epoch, SC_MSG_UNIT, pl, pn, env, n);
    free(pl);
    return rc;
}

/* An LC03 datagram: header, then (fragment 0) the channel and its NUL,
 * then fill bytes of data; its length. */
static size_t lc03(uint8_t *p, uint32_t seqno, uint32_t size, uint32_t off, uint16_t no,
                   uint16_t nfrag, const char *channel, size_t fill)
{
    size_t at = lc03_head(p, seqno, size, off, no, nfrag, channel);
    memset(p + at, 0xA5, fill);
    return at + fill;
}

/* One attack of a frag-* mode, as message seqno (distinct per attack). */
static int send_fragments(sc_bus *bus, int mode, const char *channel, uint32_t seqno)
{
    static uint8_t d[2048];
    seqno += 0x5C000000u;               /* far from what real senders use */
    size_t n;
    int rc;
    if (mode == FRAG_WRAP) {
        n = lc03(d, seqno, WRAP_SIZE, 0, 0, 2, channel, 1000);
        if ((rc = sc_bus_send_raw(bus, d, n)) != SC_OK)
            return rc;
        n = lc03(d, seqno, WRAP_SIZE, 0xFFFFFFF0u, 1, 2, NULL, 1000);
        return sc_bus_send_raw(bus, d, n);
    }
    uint32_t claim = mode == FRAG_HUGE ? 256u << 20 : 0xFFFFFFFFu;
    n = lc03(d, seqno, claim, 0, 0, 65535, channel, 1000);
    return sc_bus_send_raw(bus, d, n);
}

/* capture: each message on the channel as a 4-byte big-endian length and
 * its bytes. */
typedef struct recorder {
    FILE *f;
    long n, max;
} recorder;

static void on_capture(void *ctx, const char *channel, const uint8_t *data, size_t len,
                       int64_t recv_us)
{
    (void)channel;
    (void)recv_us;
    recorder *r = ctx;
    uint8_t head[4];
    if (r->n >= r->max)
        return;
    put_be32(head, (uint32_t)len);
    if (fwrite(head, 1, 4, r->f) == 4 && fwrite(data, 1, len, r->f) == len)
        r->n++;
}

static int capture(sc_bus *bus, const char *channel, const char *path, long max, double secs)
{
    recorder r = { fopen(path, "wb"), 0, max };
    if (!r.f || sc_bus_subscribe(bus, channel, on_capture, &r) != SC_OK) {
        fprintf(stderr, "cluster_inject: capture: %s: %s\n", path, strerror(errno));
        if (r.f)
            fclose(r.f);
        return 1;
    }
    struct timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    do {
        sc_bus_handle(bus, 0.02);
        clock_gettime(CLOCK_MONOTONIC, &t);
    } while (r.n < r.max &&
             (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec) < secs);
    int bad = fclose(r.f) != 0;
    printf("captured %ld on %s\n", r.n, channel);
    return bad;
}

static int resend(sc_bus *bus, const char *channel, const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cluster_inject: resend: %s: %s\n", path, strerror(errno));
        return 1;
    }
    uint8_t head[4], *buf = NULL;
    long n = 0;
    int bad = 0;
    const struct timespec pace = { 0, PACE_US * 1000 };
    while (!bad && fread(head, 1, 4, f) == 4) {
        size_t len = (size_t)head[0] << 24 | (size_t)head[1] << 16 | (size_t)head[2] << 8 | head[3];
        bad = len > SC_MSG_MAX_BYTES || !(buf = malloc(len ? len : 1)) ||
              fread(buf, 1, len, f) != len || sc_bus_publish(bus, channel, buf, len) != SC_OK;
        free(buf);
        buf = NULL;
        n += !bad;
        nanosleep(&pace, NULL);
    }
    fclose(f);
    printf("resent %ld on %s\n", n, channel);
    return bad;
}

int main(int argc, char **argv)
{
    static const struct option opts[] = {
        { "url", required_argument, NULL, 'u' },   { "key", required_argument, NULL, 'k' },
        { "channel", required_argument, NULL, 'c' }, { "mode", required_argument, NULL, 'm' },
        { "count", required_argument, NULL, 'n' }, { "node", required_argument, NULL, 'N' },
        { "pace-us", required_argument, NULL, 'p' },
        { "to-epoch", required_argument, NULL, 'e' }, { "file", required_argument, NULL, 'f' },
        { "seconds", required_argument, NULL, 's' }, { "help", no_argument, NULL, 'h' },
        { NULL, 0, NULL, 0 }
    };
    const char *url = NULL, *keyfile = NULL, *channel = NULL, *file = NULL;
    double seconds = 5;
    int mode = -1, c;
    long count = 20, pace_us = PACE_US;
    int count_set = 0;
    long long node = 0;
    char *end;
    while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (c) {
        case 'u': url = optarg; break;
        case 'k': keyfile = optarg; break;
        case 'c': channel = optarg; break;
        case 'm':
            for (int i = 0; i < NMODES; i++)
                if (!strcmp(optarg, mode_names[i]))
                    mode = i;
            if (mode < 0)
                return usage(stderr, 2);
            break;
        case 'n':
            errno = 0;
            count = strtol(optarg, &end, 10);
            count_set = 1;
            if (errno || *end || end == optarg || count < 1 || count > 1000000)
                return usage(stderr, 2);
            break;
        case 'N':
            errno = 0;
            node = strtoll(optarg, &end, 0);
            if (errno || *end || end == optarg || node <= 0)
                return usage(stderr, 2);
            break;
        case 'p':
            errno = 0;
            pace_us = strtol(optarg, &end, 10);
            if (errno || *end || end == optarg || pace_us < 0 || pace_us > 1000000)
                return usage(stderr, 2);
            break;
        case 'e':
            errno = 0;
            to_epoch = strtoll(optarg, &end, 0);
            if (errno || *end || end == optarg || to_epoch < 0)
                return usage(stderr, 2);
            break;
        case 'f': file = optarg; break;
        case 's':
            seconds = strtod(optarg, &end);
            if (*end || end == optarg || !(seconds > 0 && seconds <= 3600))
                return usage(stderr, 2);
            break;
        case 'h': return usage(stdout, 0);
        default: return usage(stderr, 2);
        }
    }
    int raw = mode == CAPTURE || mode == RESEND;
    if (optind != argc || !url || (!keyfile && !raw) || !channel || mode < 0 || (raw && !file))
        return usage(stderr, 2);
    if (raw) {
        char why[256];
        sc_bus *b = NULL;
        if (sc_bus_open(url, &b, why, sizeof why) != SC_OK) {
            fprintf(stderr, "cluster_inject: cannot open %s: %s\n", url, why);
            return 1;
        }
        int bad = mode == CAPTURE ? capture(b, channel, file, count_set ? count : 1000000, seconds)
                                  : resend(b, channel, file);
        sc_bus_close(b);
        return bad;
    }
    if (sodium_init() < 0) {
        fprintf(stderr, "cluster_inject: libsodium does not start\n");
        return 1;
    }
    uint8_t key[SC_KEY_BYTES];
    int rc = sc_key_load(keyfile, key);
    if (rc != SC_OK) {
        fprintf(stderr, "cluster_inject: %s: %s\n", keyfile, sc_strerror(rc));
        return 1;
    }
    if (node == 0)
        node = 1 + (long long)(randombytes_random() & 0x7fffffff) * 0x10000 +
               randombytes_uniform(0x10000);
    char why[256];
    sc_bus *bus = NULL;
    if (sc_bus_open(url, &bus, why, sizeof why) != SC_OK) {
        fprintf(stderr, "cluster_inject: cannot open %s: %s\n", url, why);
        return 1;
    }

    /* One envelope serves replay; the other modes make one per packet. */
    uint8_t *env = NULL, *buf = NULL;
    size_t n = 0;
    if (mode == REPLAY && (rc = unit_envelope(key, node, 1, &env, &n)) != SC_OK)
        goto fail;
    const struct timespec pace = { pace_us / 1000000, pace_us % 1000000 * 1000 };
    for (long i = 0; i < count; i++) {
        size_t len = 0;
        switch (mode) {
        case GARBAGE:
            len = 1 + randombytes_uniform(GARBAGE_MAX);
            buf = malloc(len);
            if (!buf) {
                rc = SC_ENOMEM;
                goto fail;
            }
            randombytes_buf(buf, len);
            break;
        case WRONGKEY: {
            uint8_t other[SC_KEY_BYTES];
            randombytes_buf(other, sizeof other);
            if ((rc = unit_envelope(other, node, i + 1, &buf, &len)) != SC_OK)
                goto fail;
            break;
        }
        case TRUNCATED:
            if ((rc = unit_envelope(key, node, i + 1, &buf, &len)) != SC_OK)
                goto fail;
            len = 1 + randombytes_uniform((uint32_t)len - 1);   /* 1..len-1 bytes */
            break;
        case OVERSIZE: {
            if ((rc = unit_envelope(key, node, i + 1, &buf, &len)) != SC_OK)
                goto fail;
            /* claim 1 .. 2^30 more payload bytes than there are */
            uint32_t claim = (uint32_t)(len - SC_MSG_OVERHEAD) + 1 +
                             (i % 2 ? randombytes_uniform(1u << 30) : randombytes_uniform(64));
            put_be32(buf + ENV_LEN_AT, claim);
            break;
        }
        default:                        /* REPLAY, FRAG_*; CAPTURE and RESEND returned */
            break;
        }
        int pub;
        if (mode >= FRAG_WRAP && mode <= FRAG_4G)
            pub = send_fragments(bus, mode, channel, (uint32_t)i);
        else
            pub = mode == REPLAY ? sc_bus_publish(bus, channel, env, n)
                                 : sc_bus_publish(bus, channel, buf, len);
        free(buf);
        buf = NULL;
        if (pub != SC_OK) {
            fprintf(stderr, "cluster_inject: sending on %s failed\n", channel);
            free(env);
            sc_bus_close(bus);
            return 1;
        }
        if (pace_us)
            nanosleep(&pace, NULL);
    }
    printf("sent %ld packets (%s) to %s as node %016llx\n", count, mode_names[mode], channel,
           (unsigned long long)node);
    free(env);
    sc_bus_close(bus);
    return 0;
fail:
    fprintf(stderr, "cluster_inject: %s\n", sc_strerror(rc));
    free(buf);
    free(env);
    sc_bus_close(bus);
    return 1;
}
