/* cluster_inject.c - hostile traffic for the cluster tests (tests/cluster.sh):
 * publishes raw bytes with plain LCM on one channel, as an attacker on the
 * network could, so that a test can check that simclusterd (or a master)
 * drops and counts them and carries on.
 *   usage: cluster_inject --url URL --key FILE --channel CH
 *                         --mode garbage|wrongkey|truncated|replay|oversize
 *                         [--count N (20)] [--node ID]
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
 * Every packet of a run comes from one sender id (--node, else random).
 * Prints one line "sent N packets (MODE) to CH as node ID"; exit 0, 1 on
 * an error, 2 on a usage error. */
#include <errno.h>
#include <getopt.h>
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

enum { GARBAGE, WRONGKEY, TRUNCATED, REPLAY, OVERSIZE, NMODES };
static const char *const mode_names[NMODES] = { "garbage", "wrongkey", "truncated", "replay",
                                                "oversize" };

static int usage(FILE *f, int status)
{
    fprintf(f, "usage: cluster_inject --url URL --key FILE --channel CH\n"
               "                      --mode garbage|wrongkey|truncated|replay|oversize\n"
               "                      [--count N (20)] [--node ID]\n");
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
    rc = sc_msg_seal(key, node, 1, seq, 0, SC_MSG_UNIT, pl, pn, env, n);
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

int main(int argc, char **argv)
{
    static const struct option opts[] = {
        { "url", required_argument, NULL, 'u' },   { "key", required_argument, NULL, 'k' },
        { "channel", required_argument, NULL, 'c' }, { "mode", required_argument, NULL, 'm' },
        { "count", required_argument, NULL, 'n' }, { "node", required_argument, NULL, 'N' },
        { "help", no_argument, NULL, 'h' },        { NULL, 0, NULL, 0 }
    };
    const char *url = NULL, *keyfile = NULL, *channel = NULL;
    int mode = -1, c;
    long count = 20;
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
            if (errno || *end || end == optarg || count < 1 || count > 1000000)
                return usage(stderr, 2);
            break;
        case 'N':
            errno = 0;
            node = strtoll(optarg, &end, 0);
            if (errno || *end || end == optarg || node <= 0)
                return usage(stderr, 2);
            break;
        case 'h': return usage(stdout, 0);
        default: return usage(stderr, 2);
        }
    }
    if (optind != argc || !url || !keyfile || !channel || mode < 0)
        return usage(stderr, 2);
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
        case REPLAY:
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
