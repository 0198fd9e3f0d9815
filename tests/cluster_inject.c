/* cluster_inject.c - hostile traffic for the cluster tests (tests/cluster.sh):
 * publishes raw bytes with plain LCM on one channel, as an attacker on the
 * network could, so that a test can check that simclusterd (or a master)
 * drops and counts them and carries on.
 *   usage: cluster_inject --url URL --key FILE --channel CH
 *                         --mode garbage|wrongkey|truncated|replay|oversize
 *                         [--count N (20)] [--node ID] [--to-epoch E]
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
 * Every packet of a run comes from one sender id (--node, else random),
 * addressed to the receiver's epoch --to-epoch (a daemon's counters line
 * says it; else 0: every message but an announce is then misaddressed).
 * Prints one line "sent N packets (MODE) to CH as node ID".
 *   capture    records what is published on CH (at most N messages or S
 *              seconds) to F, as an eavesdropper could; prints "captured N"
 *   resend     publishes the messages in F on CH again, paced, as they
 *              were: a replay of captured traffic; prints "resent N"
 * Exit 0, 1 on an error, 2 on a usage error. */
#include <errno.h>
#include <getopt.h>
#include <poll.h>
#include <lcm/lcm.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "simcluster_net.h"
#include "simcluster.h"

#define ENV_LEN_AT (8 + 2 + 8 + 8 + 8 + 8 + 2)  /* fingerprint, version, node, epoch, seq,
                                                   to_epoch, kind */
#define GARBAGE_MAX 4000
#define PACE_NS 2000000L                /* between packets: never overrun a receiver */

enum { GARBAGE, WRONGKEY, TRUNCATED, REPLAY, OVERSIZE, CAPTURE, RESEND, NMODES };
static const char *const mode_names[NMODES] = { "garbage", "wrongkey", "truncated", "replay",
                                                "oversize", "capture", "resend" };
static long long to_epoch;          /* the receiver's epoch the envelopes name */

static int usage(FILE *f, int status)
{
    fprintf(f, "usage: cluster_inject --url URL --key FILE --channel CH\n"
               "                      --mode garbage|wrongkey|truncated|replay|oversize\n"
               "                      [--count N (20)] [--node ID] [--to-epoch E]\n"
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

static void put_be32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

/* capture: each message on the channel as a 4-byte big-endian length and
 * its bytes. */
typedef struct recorder {
    FILE *f;
    long n, max;
} recorder;

static void on_capture(const lcm_recv_buf_t *rb, const char *channel, void *ctx)
{
    (void)channel;
    recorder *r = ctx;
    uint8_t head[4];
    if (r->n >= r->max)
        return;
    put_be32(head, (uint32_t)rb->data_size);
    if (fwrite(head, 1, 4, r->f) == 4 &&
        fwrite(rb->data, 1, (size_t)rb->data_size, r->f) == (size_t)rb->data_size)
        r->n++;
}

static int capture(lcm_t *lcm, const char *channel, const char *path, long max, double secs)
{
    recorder r = { fopen(path, "wb"), 0, max };
    if (!r.f || !lcm_subscribe(lcm, channel, on_capture, &r)) {
        fprintf(stderr, "cluster_inject: capture: %s: %s\n", path, strerror(errno));
        if (r.f)
            fclose(r.f);
        return 1;
    }
    struct timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    do {
        struct pollfd pf = { lcm_get_fileno(lcm), POLLIN, 0 };
        if (poll(&pf, 1, 20) > 0)
            lcm_handle(lcm);
        clock_gettime(CLOCK_MONOTONIC, &t);
    } while (r.n < r.max &&
             (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec) < secs);
    int bad = fclose(r.f) != 0;
    printf("captured %ld on %s\n", r.n, channel);
    return bad;
}

static int resend(lcm_t *lcm, const char *channel, const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cluster_inject: resend: %s: %s\n", path, strerror(errno));
        return 1;
    }
    uint8_t head[4], *buf = NULL;
    long n = 0;
    int bad = 0;
    const struct timespec pace = { 0, PACE_NS };
    while (!bad && fread(head, 1, 4, f) == 4) {
        size_t len = (size_t)head[0] << 24 | (size_t)head[1] << 16 | (size_t)head[2] << 8 | head[3];
        bad = len > SC_MSG_MAX_BYTES || !(buf = malloc(len ? len : 1)) ||
              fread(buf, 1, len, f) != len || lcm_publish(lcm, channel, buf, (unsigned)len) != 0;
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
        { "to-epoch", required_argument, NULL, 'e' }, { "file", required_argument, NULL, 'f' },
        { "seconds", required_argument, NULL, 's' }, { "help", no_argument, NULL, 'h' },
        { NULL, 0, NULL, 0 }
    };
    const char *url = NULL, *keyfile = NULL, *channel = NULL, *file = NULL;
    double seconds = 5;
    int mode = -1, c;
    long count = 20;
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
        lcm_t *l = lcm_create(url);
        if (!l) {
            fprintf(stderr, "cluster_inject: cannot open LCM URL %s\n", url);
            return 1;
        }
        int bad = mode == CAPTURE ? capture(l, channel, file, count_set ? count : 1000000, seconds)
                                  : resend(l, channel, file);
        lcm_destroy(l);
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
    lcm_t *lcm = lcm_create(url);
    if (!lcm) {
        fprintf(stderr, "cluster_inject: cannot open LCM URL %s\n", url);
        return 1;
    }

    /* One envelope serves replay; the other modes make one per packet. */
    uint8_t *env = NULL, *buf = NULL;
    size_t n = 0;
    if (mode == REPLAY && (rc = unit_envelope(key, node, 1, &env, &n)) != SC_OK)
        goto fail;
    const struct timespec pace = { 0, PACE_NS };
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
        default:                        /* REPLAY; CAPTURE and RESEND returned */
            break;
        }
        int pub = mode == REPLAY ? lcm_publish(lcm, channel, env, (unsigned)n)
                                 : lcm_publish(lcm, channel, buf, (unsigned)len);
        free(buf);
        buf = NULL;
        if (pub != 0) {
            fprintf(stderr, "cluster_inject: lcm_publish on %s failed\n", channel);
            free(env);
            lcm_destroy(lcm);
            return 1;
        }
        nanosleep(&pace, NULL);
    }
    printf("sent %ld packets (%s) to %s as node %016llx\n", count, mode_names[mode], channel,
           (unsigned long long)node);
    free(env);
    lcm_destroy(lcm);
    return 0;
fail:
    fprintf(stderr, "cluster_inject: %s\n", sc_strerror(rc));
    free(buf);
    free(env);
    lcm_destroy(lcm);
    return 1;
}
