/* bus.c - the cluster's multicast transport (docs/DESIGN.md 7.1). It
 * speaks LCM 1.3.1's UDP multicast wire format (LC02 datagrams and LC03
 * fragments, as lcm_udpm.c writes them), so LCM's tools still read the
 * traffic, but since LCM trusts the fragment headers it reads and drops
 * messages silently, it reads on the caller's thread, checks every header
 * field in 64 bits before use, keeps reassembly within a fixed budget and
 * counts every datagram it or the kernel drops. */
#include <arpa/inet.h>
#include <errno.h>
#include <limits.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

#include "bus.h"

/* LCM 1.3.1's UDP multicast code trusts the fragment headers it reads (a
 * 32-bit offset check that wraps, a malloc of whatever size a header
 * claims) and drops messages silently from a bounded per-subscription
 * queue. This file speaks the same wire format (so lcm-spy and lcm-logger
 * still read the cluster's traffic, and lcm-logplayer can still feed
 * simcluster-view) but reads it on the caller's thread, checks every
 * header field in 64 bits before it is used, keeps reassembly within a
 * fixed budget, and counts every datagram it or the kernel drops.
 *
 * Wire format (all fields big-endian), as LCM's lcm_udpm.c writes it:
 *   LC02  magic 0x4c433032, seqno (u32), channel, NUL, data
 *   LC03  magic 0x4c433033, seqno (u32), message size (u32), fragment
 *         offset (u32), fragment number (u16), fragments (u16), data; the
 *         data of fragment 0 begins with the channel and its NUL, and
 *         offsets count message bytes only.
 * A sender uses LC02 while channel, NUL and data fit in 65499 bytes, else
 * fragments of 65487 bytes after the header; one seqno per message.
 * Fragments are matched by sender address, port and seqno. */

#define DEFAULT_ADDR "239.255.76.67"    /* LCM's defaults */
#define DEFAULT_PORT 7667
#define HANDLE_MAX 4096                 /* datagrams read per sc_bus_handle call */
#define IGNORED_KEYS 32                 /* fragmented messages for others, remembered */

typedef struct frag {
    uint32_t off, len;                  /* len 0: not received */
} frag;

/* A message being reassembled. */
typedef struct partial {
    int used;
    uint32_t addr, seqno;
    uint16_t port, nfrag, got;
    uint32_t size;
    int sub;                            /* its subscription */
    uint8_t *data;
    frag *frags;
    size_t cost;                        /* bytes charged to the budgets */
    double last_s;
    uint64_t born;                      /* order of arrival: the oldest goes first */
} partial;

typedef struct msg_key {
    uint32_t addr, seqno;
    uint16_t port;
    uint8_t used;
} msg_key;

typedef struct sub {
    char channel[SC_BUS_CHANNEL_MAX + 1];
    sc_bus_handler fn;
    void *ctx;
} sub;

struct sc_bus {
    int rfd, sfd;                       /* receiving (bound to the group), sending */
    struct sockaddr_in group;
    sub subs[SC_BUS_SUBS_MAX];
    int nsubs;
    partial part[SC_BUS_INFLIGHT];
    uint64_t born;
    size_t reasm_bytes;
    msg_key ignored[IGNORED_KEYS];      /* fragment 0 was for a channel not ours */
    int ignored_next;
    uint32_t kernel_seen;               /* the kernel's drop counter, last read */
    sc_bus_counters n;
    pthread_mutex_t send_lock;          /* seqno and a message's fragments together */
    uint32_t seqno;
    uint8_t dgram[SC_BUS_DGRAM_MAX + 1];
};

/* What every bus of the process holds for reassembly. */
static _Atomic size_t process_bytes;

static double mono_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int64_t real_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static uint16_t get16(const uint8_t *p)
{
    return (uint16_t)(p[0] << 8 | p[1]);
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)v;
}

static void why_set(char *why, size_t n, const char *fmt, const char *a, const char *b)
{
    if (why && n)
        snprintf(why, n, fmt, a, b);
}

/* ---- opening ---- */

typedef struct url_parts {
    struct in_addr addr;
    int port, ttl, rcvbuf;
} url_parts;

/* A decimal in lo..hi, the whole of [s, end). */
static int parse_int(const char *s, const char *end, long lo, long hi, int *out)
{
    long v = 0;
    if (s == end || end - s > 10)
        return 0;
    for (const char *p = s; p < end; p++) {
        if (*p < '0' || *p > '9')
            return 0;
        v = 10 * v + (*p - '0');
    }
    if (v < lo || v > hi)
        return 0;
    *out = (int)v;
    return 1;
}

static int parse_url(const char *url, url_parts *u, char *why, size_t why_len)
{
    static const char scheme[] = "udpm://";
    *u = (url_parts){ .port = DEFAULT_PORT, .ttl = 0, .rcvbuf = 0 };
    inet_pton(AF_INET, DEFAULT_ADDR, &u->addr);
    if (!url || strncmp(url, scheme, sizeof scheme - 1) != 0) {
        why_set(why, why_len,
                "only LCM's udpm://ADDR:PORT?ttl=N&recv_buf_size=B URLs are supported%s%s",
                url && strstr(url, "://") ? " (not " : "",
                url && strstr(url, "://") ? "this provider)" : "");
        return SC_EINVAL;
    }
    const char *net = url + sizeof scheme - 1;
    const char *q = strchr(net, '?');
    const char *net_end = q ? q : net + strlen(net);
    if (net_end > net) {
        const char *colon = memchr(net, ':', (size_t)(net_end - net));
        const char *addr_end = colon ? colon : net_end;
        char a[INET_ADDRSTRLEN];
        size_t alen = (size_t)(addr_end - net);
        if (alen == 0 || alen >= sizeof a) {
            why_set(why, why_len, "bad multicast address%s%s", "", "");
            return SC_EINVAL;
        }
        memcpy(a, net, alen);
        a[alen] = 0;
        if (inet_pton(AF_INET, a, &u->addr) != 1 || !IN_MULTICAST(ntohl(u->addr.s_addr))) {
            why_set(why, why_len, "%s is not an IPv4 multicast address%s", a, "");
            return SC_EINVAL;
        }
        if (colon && !parse_int(colon + 1, net_end, 1, 65535, &u->port)) {
            why_set(why, why_len, "bad port%s%s", "", "");
            return SC_EINVAL;
        }
    }
    for (const char *o = q ? q + 1 : NULL; o && *o;) {
        const char *amp = strchr(o, '&');
        const char *end = amp ? amp : o + strlen(o);
        const char *eq = memchr(o, '=', (size_t)(end - o));
        int ok = 0;
        if (eq && eq - o == 3 && !strncmp(o, "ttl", 3))
            ok = parse_int(eq + 1, end, 0, 255, &u->ttl);
        else if (eq && eq - o == 13 && !strncmp(o, "recv_buf_size", 13))
            ok = parse_int(eq + 1, end, 0, INT_MAX / 2, &u->rcvbuf);
        if (!ok) {
            if (why && why_len)
                snprintf(why, why_len, "bad option '%.*s' (ttl=0..255, recv_buf_size=BYTES)",
                         (int)(end - o), o);
            return SC_EINVAL;
        }
        o = amp ? amp + 1 : NULL;
    }
    return SC_OK;
}

/* The receive buffer: as asked, at least SC_BUS_RCVBUF_MIN, so that a
 * burst of a thousand datagrams waits in the kernel; past net.core.rmem_max
 * only with CAP_NET_ADMIN (SO_RCVBUFFORCE). */
static int set_rcvbuf(int fd, int want)
{
    if (want < SC_BUS_RCVBUF_MIN)
        want = SC_BUS_RCVBUF_MIN;
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &want, sizeof want) != 0)
        setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &want, sizeof want);
    int got = 0;
    socklen_t len = sizeof got;
    getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &got, &len);
    return got;
}

static void bus_init(sc_bus *b)
{
    b->rfd = b->sfd = -1;
    pthread_mutex_init(&b->send_lock, NULL);
}

sc_bus *sc_bus_detached(void)
{
    sc_bus *b = calloc(1, sizeof *b);
    if (b)
        bus_init(b);
    return b;
}

SC_API int sc_bus_open(const char *url, sc_bus **out, char *why, size_t why_len)
{
    if (!out) {
        why_set(why, why_len, "no place for the bus%s%s", "", "");
        return SC_EINVAL;
    }
    *out = NULL;
    url_parts u;
    int rc = parse_url(url, &u, why, why_len);
    if (rc != SC_OK)
        return rc;
    sc_bus *b = calloc(1, sizeof *b);
    if (!b) {
        why_set(why, why_len, "out of memory%s%s", "", "");
        return SC_ENOMEM;
    }
    bus_init(b);
    b->group = (struct sockaddr_in){ .sin_family = AF_INET, .sin_port = htons((uint16_t)u.port),
                                     .sin_addr = u.addr };
    int one = 1;
    unsigned char ttl = (unsigned char)u.ttl, loop = 1;
    struct ip_mreq mreq = { .imr_multiaddr = u.addr, .imr_interface = { htonl(INADDR_ANY) } };
    const char *step = "socket";
    /* receiving: bound to the group and port, shared with other processes
     * on this host as LCM shares it (SO_REUSEADDR and SO_REUSEPORT) */
    if ((b->rfd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0)) < 0)
        goto fail;
    step = "SO_REUSEADDR";
    if (setsockopt(b->rfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0)
        goto fail;
    step = "SO_REUSEPORT";
    if (setsockopt(b->rfd, SOL_SOCKET, SO_REUSEPORT, &one, sizeof one) != 0)
        goto fail;
    step = "SO_RXQ_OVFL";
    if (setsockopt(b->rfd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one) != 0)
        goto fail;
    /* the kernel's arrival stamp of each datagram (best effort): a message
     * read late, after other work, still tells when it came */
    (void)setsockopt(b->rfd, SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one);
    b->n.rcvbuf_bytes = set_rcvbuf(b->rfd, u.rcvbuf);
    step = "bind";
    if (bind(b->rfd, (const struct sockaddr *)&b->group, sizeof b->group) != 0)
        goto fail;
    step = "IP_ADD_MEMBERSHIP";
    if (setsockopt(b->rfd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof mreq) != 0)
        goto fail;
    /* sending: from a port of its own, so that fragments of processes on
     * one host never share a sender address and port */
    step = "socket";
    if ((b->sfd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0)) < 0)
        goto fail;
    step = "IP_MULTICAST_TTL";
    if (setsockopt(b->sfd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl) != 0)
        goto fail;
    step = "IP_MULTICAST_LOOP";
    if (setsockopt(b->sfd, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop) != 0)
        goto fail;
    /* a route to the group, checked now rather than at the first send */
    int t = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (t < 0 || connect(t, (const struct sockaddr *)&b->group, sizeof b->group) != 0) {
        if (why && why_len) {
            char a[INET_ADDRSTRLEN] = "";
            inet_ntop(AF_INET, &u.addr, a, sizeof a);
            snprintf(why, why_len, "no route to %s: %s (add a multicast route)", a,
                     strerror(errno));
        }
        if (t >= 0)
            close(t);
        sc_bus_close(b);
        return SC_EIO;
    }
    close(t);
    *out = b;
    return SC_OK;
fail:
    if (why && why_len)
        snprintf(why, why_len, "%s: %s", step, strerror(errno));
    sc_bus_close(b);
    return SC_EIO;
}

static void drop_partial(sc_bus *b, partial *p)
{
    if (!p->used)
        return;
    free(p->data);
    free(p->frags);
    b->reasm_bytes -= p->cost;
    atomic_fetch_sub(&process_bytes, p->cost);
    memset(p, 0, sizeof *p);
}

SC_API void sc_bus_close(sc_bus *b)
{
    if (!b)
        return;
    for (int i = 0; i < SC_BUS_INFLIGHT; i++)
        drop_partial(b, &b->part[i]);
    if (b->rfd >= 0)
        close(b->rfd);
    if (b->sfd >= 0)
        close(b->sfd);
    pthread_mutex_destroy(&b->send_lock);
    free(b);
}

SC_API int sc_bus_subscribe(sc_bus *b, const char *channel, sc_bus_handler fn, void *ctx)
{
    if (!b || !channel || !fn || !*channel || strlen(channel) > SC_BUS_CHANNEL_MAX ||
        b->nsubs == SC_BUS_SUBS_MAX)
        return SC_EINVAL;
    for (int i = 0; i < b->nsubs; i++)
        if (!strcmp(b->subs[i].channel, channel))
            return SC_EINVAL;
    sub *s = &b->subs[b->nsubs++];
    strcpy(s->channel, channel);
    s->fn = fn;
    s->ctx = ctx;
    return SC_OK;
}

SC_API int sc_bus_fd(const sc_bus *b)
{
    return b ? b->rfd : -1;
}

SC_API void sc_bus_counters_get(const sc_bus *b, sc_bus_counters *out)
{
    *out = b->n;
    out->reasm_bytes = b->reasm_bytes;
}

SC_API uint64_t sc_bus_dropped(const sc_bus_counters *c)
{
    return c->malformed + c->refused + c->evicted + c->nomem + c->kernel;
}

size_t sc_bus_reasm_process_bytes(void)
{
    return atomic_load(&process_bytes);
}

/* ---- receiving ---- */

static int find_sub(const sc_bus *b, const char *channel)
{
    for (int i = 0; i < b->nsubs; i++)
        if (!strcmp(b->subs[i].channel, channel))
            return i;
    return -1;
}

/* The channel at p (at most avail bytes): its length, or -1 when no NUL
 * ends it within SC_BUS_CHANNEL_MAX + 1 bytes. */
static int channel_len(const uint8_t *p, size_t avail)
{
    size_t lim = avail < SC_BUS_CHANNEL_MAX + 1 ? avail : SC_BUS_CHANNEL_MAX + 1;
    const uint8_t *nul = memchr(p, 0, lim);
    return nul ? (int)(nul - p) : -1;
}

static int deliver(sc_bus *b, int s, const uint8_t *data, size_t len, int64_t recv_us)
{
    b->n.messages++;
    b->subs[s].fn(b->subs[s].ctx, b->subs[s].channel, data, len, recv_us);
    return 1;
}

static void remember_ignored(sc_bus *b, uint32_t addr, uint16_t port, uint32_t seqno)
{
    b->ignored[b->ignored_next] = (msg_key){ addr, seqno, port, 1 };
    b->ignored_next = (b->ignored_next + 1) % IGNORED_KEYS;
}

static int was_ignored(const sc_bus *b, uint32_t addr, uint16_t port, uint32_t seqno)
{
    for (int i = 0; i < IGNORED_KEYS; i++) {
        const msg_key *k = &b->ignored[i];
        if (k->used && k->addr == addr && k->port == port && k->seqno == seqno)
            return 1;
    }
    return 0;
}

/* Partial messages silent for SC_BUS_PARTIAL_S are given up. */
static void expire(sc_bus *b, double now_s)
{
    for (int i = 0; i < SC_BUS_INFLIGHT; i++) {
        partial *p = &b->part[i];
        if (p->used && now_s - p->last_s > SC_BUS_PARTIAL_S) {
            drop_partial(b, p);
            b->n.evicted++;
        }
    }
}

/* Room for a message costing cost bytes: a free slot within both budgets,
 * the oldest partial messages of this bus given up for it. NULL if even
 * an empty bus could not hold it (other buses of the process hold it). */
static partial *make_room(sc_bus *b, size_t cost)
{
    for (;;) {
        partial *free_slot = NULL, *oldest = NULL;
        for (int i = 0; i < SC_BUS_INFLIGHT; i++) {
            partial *p = &b->part[i];
            if (!p->used && !free_slot)
                free_slot = p;
            if (p->used && (!oldest || p->born < oldest->born))
                oldest = p;
        }
        size_t held = atomic_load(&process_bytes);
        if (free_slot && b->reasm_bytes + cost <= SC_BUS_REASM_BYTES &&
            held + cost <= SC_BUS_REASM_PROCESS_BYTES) {
            /* reserve; another bus may have taken the room meanwhile */
            if (atomic_compare_exchange_strong(&process_bytes, &held, held + cost))
                return free_slot;
            continue;
        }
        if (!oldest)
            return NULL;
        drop_partial(b, oldest);
        b->n.evicted++;
    }
}

static int frag_cmp(const void *a, const void *b)
{
    uint32_t x = ((const frag *)a)->off, y = ((const frag *)b)->off;
    return (x > y) - (x < y);
}

/* Every fragment in: the fragments must tile the message exactly. */
static int complete(sc_bus *b, partial *p, int64_t recv_us)
{
    qsort(p->frags, p->nfrag, sizeof *p->frags, frag_cmp);
    uint64_t at = 0;
    int i;
    for (i = 0; i < p->nfrag; i++) {
        if (p->frags[i].off != at)
            break;
        at += p->frags[i].len;
    }
    int s = p->sub, handed = 0;
    if (i == p->nfrag && at == p->size) {
        uint8_t *data = p->data;
        p->data = NULL;         /* the handler may see it; freed after */
        size_t size = p->size;
        drop_partial(b, p);
        handed = deliver(b, s, data, size, recv_us);
        free(data);
    } else {
        drop_partial(b, p);     /* overlapping or leaving a gap */
        b->n.refused++;
    }
    return handed;
}

static int fragment(sc_bus *b, const uint8_t *d, size_t len, uint32_t addr, uint16_t port,
                    double now_s, int64_t recv_us)
{
    if (len < SC_BUS_LONG_HDR) {
        b->n.malformed++;
        return 0;
    }
    uint32_t seqno = get32(d + 4), size = get32(d + 8), off = get32(d + 12);
    uint16_t no = get16(d + 16), nfrag = get16(d + 18);
    const uint8_t *data = d + SC_BUS_LONG_HDR;
    size_t dlen = len - SC_BUS_LONG_HDR;
    partial *p = NULL;
    for (int i = 0; i < SC_BUS_INFLIGHT && !p; i++)
        if (b->part[i].used && b->part[i].addr == addr && b->part[i].port == port &&
            b->part[i].seqno == seqno)
            p = &b->part[i];
    if (no == 0) {
        int cl = channel_len(data, dlen);
        if (cl < 0) {
            b->n.malformed++;
            return 0;
        }
        int s = find_sub(b, (const char *)data);
        if (s < 0) {
            remember_ignored(b, addr, port, seqno);
            b->n.ignored++;
            return 0;
        }
        data += cl + 1;
        dlen -= (size_t)cl + 1;
        /* a second fragment 0 for one message, or a claim we will not hold */
        if (p || off != 0 || nfrag < 2 || size == 0 || size > SC_MSG_MAX_BYTES ||
            dlen == 0 || dlen > size ||
            nfrag > size || (uint64_t)nfrag * SC_BUS_FRAG_MAX < size) {
            b->n.refused++;
            return 0;
        }
        size_t cost = size + (size_t)nfrag * sizeof(frag);
        p = make_room(b, cost);
        if (!p) {
            b->n.refused++;
            return 0;
        }
        p->data = malloc(size);
        p->frags = calloc(nfrag, sizeof *p->frags);
        if (!p->data || !p->frags) {
            free(p->data);
            free(p->frags);
            p->data = NULL;
            p->frags = NULL;
            atomic_fetch_sub(&process_bytes, cost);
            b->n.nomem++;
            return 0;
        }
        p->used = 1;
        p->addr = addr;
        p->port = port;
        p->seqno = seqno;
        p->size = size;
        p->nfrag = nfrag;
        p->sub = s;
        p->cost = cost;
        p->born = ++b->born;
        b->reasm_bytes += cost;
    } else if (!p) {
        if (was_ignored(b, addr, port, seqno))
            b->n.ignored++;
        else
            b->n.refused++;     /* a message not begun (its fragment 0 lost or forged) */
        return 0;
    }
    /* every bound in 64 bits: offset + length cannot wrap */
    if (size != p->size || nfrag != p->nfrag || no >= nfrag || dlen == 0 ||
        (uint64_t)off + dlen > p->size || p->frags[no].len != 0) {
        b->n.refused++;
        return 0;
    }
    memcpy(p->data + off, data, dlen);
    p->frags[no] = (frag){ off, (uint32_t)dlen };
    p->got++;
    p->last_s = now_s;
    return p->got == p->nfrag ? complete(b, p, recv_us) : 0;
}

int sc_bus_feed(sc_bus *b, const uint8_t *d, size_t len, uint32_t addr, uint16_t port,
                double now_s, int64_t recv_us)
{
    b->n.datagrams++;
    expire(b, now_s);
    if (len < SC_BUS_SHORT_HDR) {
        b->n.malformed++;
        return 0;
    }
    uint32_t magic = get32(d);
    if (magic == SC_BUS_MAGIC_LONG)
        return fragment(b, d, len, addr, port, now_s, recv_us);
    if (magic != SC_BUS_MAGIC_SHORT) {
        b->n.malformed++;
        return 0;
    }
    int cl = channel_len(d + SC_BUS_SHORT_HDR, len - SC_BUS_SHORT_HDR);
    if (cl < 0) {
        b->n.malformed++;
        return 0;
    }
    int s = find_sub(b, (const char *)d + SC_BUS_SHORT_HDR);
    if (s < 0) {
        b->n.ignored++;
        return 0;
    }
    size_t at = SC_BUS_SHORT_HDR + (size_t)cl + 1;
    return deliver(b, s, d + at, len - at, recv_us);
}

/* The kernel's count of datagrams it dropped for this socket, and the
 * datagram's arrival stamp (*recv_us, real-time microseconds; left as it
 * is without one), from a received message's control data. */
static void note_kernel_drops(sc_bus *b, struct msghdr *mh, int64_t *recv_us)
{
    for (struct cmsghdr *c = CMSG_FIRSTHDR(mh); c; c = CMSG_NXTHDR(mh, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMP &&
            c->cmsg_len >= CMSG_LEN(sizeof(struct timeval))) {
            struct timeval tv;
            memcpy(&tv, CMSG_DATA(c), sizeof tv);
            *recv_us = (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
        }
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL &&
            c->cmsg_len >= CMSG_LEN(sizeof(uint32_t))) {
            uint32_t v;
            memcpy(&v, CMSG_DATA(c), sizeof v);
            b->n.kernel += (uint32_t)(v - b->kernel_seen);   /* modulo 2^32 */
            b->kernel_seen = v;
        }
    }
}

SC_API int sc_bus_handle(sc_bus *b, double timeout_s)
{
    if (!b || b->rfd < 0)
        return SC_EIO;
    if (timeout_s > 0) {
        double ms = timeout_s * 1000;
        struct pollfd pf = { b->rfd, POLLIN, 0 };
        int n = poll(&pf, 1, ms > INT_MAX ? INT_MAX : (int)ms + (ms > (int)ms));
        if (n < 0 && errno != EINTR)
            return SC_EIO;
        if (n <= 0) {
            expire(b, mono_now());
            return 0;
        }
    }
    int handed = 0;
    for (int i = 0; i < HANDLE_MAX; i++) {
        struct sockaddr_in from;
        struct iovec iov = { b->dgram, sizeof b->dgram };
        union {
            struct cmsghdr align;
            char buf[CMSG_SPACE(sizeof(uint32_t)) + CMSG_SPACE(sizeof(struct timeval)) + 64];
        } ctl;
        struct msghdr mh = { .msg_name = &from, .msg_namelen = sizeof from, .msg_iov = &iov,
                             .msg_iovlen = 1, .msg_control = ctl.buf,
                             .msg_controllen = sizeof ctl.buf };
        ssize_t r = recvmsg(b->rfd, &mh, MSG_DONTWAIT);
        if (r < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                break;
            return SC_EIO;
        }
        int64_t recv_us = real_us();
        note_kernel_drops(b, &mh, &recv_us);
        if ((mh.msg_flags & MSG_TRUNC) || (size_t)r > SC_BUS_DGRAM_MAX) {
            b->n.datagrams++;
            b->n.malformed++;   /* longer than any LCM datagram */
            continue;
        }
        handed += sc_bus_feed(b, b->dgram, (size_t)r, ntohl(from.sin_addr.s_addr),
                              ntohs(from.sin_port), mono_now(), recv_us);
    }
    if (!handed)
        expire(b, mono_now());
    return handed;
}

/* ---- sending ---- */

static int send_iov(sc_bus *b, struct iovec *iov, int n, size_t total)
{
    struct msghdr mh = { .msg_name = &b->group, .msg_namelen = sizeof b->group,
                         .msg_iov = iov, .msg_iovlen = (size_t)n };
    ssize_t r;
    do
        r = sendmsg(b->sfd, &mh, MSG_NOSIGNAL);
    while (r < 0 && errno == EINTR);
    return r == (ssize_t)total ? SC_OK : SC_EIO;
}

SC_API int sc_bus_publish(sc_bus *b, const char *channel, const void *data, size_t len)
{
    if (!b || !channel || (!data && len) || !*channel)
        return SC_EINVAL;
    size_t cl = strlen(channel);
    if (cl > SC_BUS_CHANNEL_MAX)
        return SC_EINVAL;
    if (b->sfd < 0)
        return SC_EIO;
    size_t whole = cl + 1 + len;
    uint64_t nfrag = (whole + SC_BUS_FRAG_MAX - 1) / SC_BUS_FRAG_MAX;
    if (whole > SC_BUS_SHORT_MAX && (nfrag > 65535 || len > UINT32_MAX))
        return SC_ETOOBIG;
    pthread_mutex_lock(&b->send_lock);
    uint32_t seqno = b->seqno++;
    int rc;
    if (whole <= SC_BUS_SHORT_MAX) {
        uint8_t hdr[SC_BUS_SHORT_HDR];
        put32(hdr, SC_BUS_MAGIC_SHORT);
        put32(hdr + 4, seqno);
        struct iovec iov[3] = { { hdr, sizeof hdr }, { (void *)channel, cl + 1 },
                                { (void *)data, len } };
        rc = send_iov(b, iov, 3, sizeof hdr + whole);
    } else {
        /* fragment 0: the channel and as much data as fits after it */
        uint8_t hdr[SC_BUS_LONG_HDR];
        put32(hdr, SC_BUS_MAGIC_LONG);
        put32(hdr + 4, seqno);
        put32(hdr + 8, (uint32_t)len);
        put32(hdr + 12, 0);
        put16(hdr + 16, 0);
        put16(hdr + 18, (uint16_t)nfrag);
        size_t first = SC_BUS_FRAG_MAX - (cl + 1), off = first;
        struct iovec iov0[3] = { { hdr, sizeof hdr }, { (void *)channel, cl + 1 },
                                 { (void *)data, first } };
        rc = send_iov(b, iov0, 3, sizeof hdr + SC_BUS_FRAG_MAX);
        for (uint32_t no = 1; rc == SC_OK && no < nfrag; no++) {
            size_t n = len - off < SC_BUS_FRAG_MAX ? len - off : SC_BUS_FRAG_MAX;
            put32(hdr + 12, (uint32_t)off);
            put16(hdr + 16, (uint16_t)no);
            struct iovec iov[2] = { { hdr, sizeof hdr },
                                    { (uint8_t *)data + off, n } };
            rc = send_iov(b, iov, 2, sizeof hdr + n);
            off += n;
        }
    }
    pthread_mutex_unlock(&b->send_lock);
    return rc;
}

int sc_bus_send_raw(sc_bus *b, const void *dgram, size_t len)
{
    if (!b || b->sfd < 0 || !dgram)
        return SC_EIO;
    struct iovec iov = { (void *)dgram, len };
    pthread_mutex_lock(&b->send_lock);
    int rc = send_iov(b, &iov, 1, len);
    pthread_mutex_unlock(&b->send_lock);
    return rc;
}
