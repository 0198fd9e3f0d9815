/* test_bus.c - the cluster transport (lib/net/bus.c): LCM's framing byte
 * for byte, round trips over loopback multicast (with our own code and with
 * liblcm on the other end), and every hostile case of reassembly fed
 * straight to a detached bus: each dropped and counted, memory bounded. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <lcm/lcm.h>

#include "bus.h"
#include "lc03.h"

#define CH "SC_UNIT_0000000000004001"
#define ADDR 0x7f000001u

static char url[128];
static int port;

/* What the handler saw. */
typedef struct got {
    int n;
    char channel[SC_BUS_CHANNEL_MAX + 1];
    uint8_t *data;
    size_t len;
} got;

static void on_msg(void *ctx, const char *channel, const uint8_t *data, size_t len,
                   int64_t recv_us)
{
    got *g = ctx;
    assert_true(recv_us > 0);
    g->n++;
    snprintf(g->channel, sizeof g->channel, "%s", channel);
    free(g->data);
    g->data = malloc(len ? len : 1);
    assert_non_null(g->data);
    memcpy(g->data, data, len);
    g->len = len;
}

/* An LC03 datagram into p: its length. */
static size_t lc03(uint8_t *p, uint32_t seqno, uint32_t size, uint32_t off, uint16_t no,
                   uint16_t nfrag, const char *channel, const uint8_t *data, size_t n)
{
    size_t at = lc03_head(p, seqno, size, off, no, nfrag, channel);
    if (n)
        memcpy(p + at, data, n);
    return at + n;
}

static int feed(sc_bus *b, const uint8_t *d, size_t n)
{
    return sc_bus_feed(b, d, n, ADDR, 5555, 100.0, 1);
}

static sc_bus *detached(got *g)
{
    sc_bus *b = sc_bus_detached();
    assert_non_null(b);
    assert_int_equal(sc_bus_subscribe(b, CH, on_msg, g), SC_OK);
    return b;
}

static sc_bus_counters counters(const sc_bus *b)
{
    sc_bus_counters c;
    sc_bus_counters_get(b, &c);
    return c;
}

/* ---- framing, against bytes written by hand ---- */

static void test_short_message_as_lcm_frames_it_is_taken(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    static const uint8_t d[] = { 'L', 'C', '0', '2', 0, 0, 0, 7, 'S', 'C', '_', 'U', 'N',
                                 'I', 'T', '_', '0', '0', '0', '0', '0', '0', '0', '0',
                                 '0', '0', '0', '0', '4', '0', '0', '1', 0, 1, 2, 3 };
    assert_int_equal(feed(b, d, sizeof d), 1);
    assert_int_equal(g.n, 1);
    assert_string_equal(g.channel, CH);
    assert_int_equal(g.len, 3);
    assert_memory_equal(g.data, "\1\2\3", 3);
    /* an empty payload is a message too */
    assert_int_equal(feed(b, d, sizeof d - 3), 1);
    assert_int_equal(g.len, 0);
    /* another channel: ignored, not dropped */
    uint8_t o[sizeof d];
    memcpy(o, d, sizeof d);
    o[sizeof d - 5] = '2';
    assert_int_equal(feed(b, o, sizeof o), 0);
    sc_bus_counters c = counters(b);
    assert_int_equal(c.messages, 2);
    assert_int_equal(c.ignored, 1);
    assert_int_equal(sc_bus_dropped(&c), 0);
    sc_bus_close(b);
    free(g.data);
}

static void test_fragments_as_lcm_frames_them_are_reassembled(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    size_t size = 150000, cl = strlen(CH) + 1;
    uint8_t *msg = malloc(size), *d = malloc(SC_BUS_DGRAM_MAX);
    for (size_t i = 0; i < size; i++)
        msg[i] = (uint8_t)(i * 131 + 7);
    /* as LCM cuts it: 65487 bytes after each header, the channel first */
    size_t first = SC_BUS_FRAG_MAX - cl, second = SC_BUS_FRAG_MAX;
    uint16_t nfrag = (uint16_t)((cl + size + SC_BUS_FRAG_MAX - 1) / SC_BUS_FRAG_MAX);
    assert_int_equal(nfrag, 3);
    size_t n = lc03(d, 9, (uint32_t)size, 0, 0, nfrag, CH, msg, first);
    assert_int_equal(n, SC_BUS_DGRAM_MAX);
    assert_int_equal(feed(b, d, n), 0);
    /* out of order after the first */
    n = lc03(d, 9, (uint32_t)size, (uint32_t)(first + second), 2, nfrag, NULL,
             msg + first + second, size - first - second);
    assert_int_equal(feed(b, d, n), 0);
    assert_int_equal(counters(b).reasm_bytes, size + 3 * 8);
    n = lc03(d, 9, (uint32_t)size, (uint32_t)first, 1, nfrag, NULL, msg + first, second);
    assert_int_equal(feed(b, d, n), 1);
    assert_int_equal(g.len, size);
    assert_memory_equal(g.data, msg, size);
    sc_bus_counters c = counters(b);
    assert_int_equal(c.reasm_bytes, 0);
    assert_int_equal(sc_bus_dropped(&c), 0);
    assert_int_equal(sc_bus_reasm_process_bytes(), 0);
    sc_bus_close(b);
    free(g.data);
    free(msg);
    free(d);
}

/* ---- hostile fragments: dropped, counted, nothing written out of bounds ---- */

/* A fragment 0 of a 100000-byte message in 2 fragments, seqno s. */
static size_t first_of_two(uint8_t *d, uint32_t s)
{
    static uint8_t fill[1000];
    return lc03(d, s, 100000, 0, 0, 2, CH, fill, sizeof fill);
}

static void test_wrapping_offset_is_refused(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    uint8_t d[2048], fill[1000] = { 0 };
    assert_int_equal(feed(b, d, first_of_two(d, 1)), 0);
    /* 0xFFFFFFF0 + 1000 wraps to 984 in 32 bits: LCM 1.3.1 then writes 4 GB
     * past its buffer */
    size_t n = lc03(d, 1, 100000, 0xFFFFFFF0u, 1, 2, NULL, fill, sizeof fill);
    assert_int_equal(feed(b, d, n), 0);
    /* an offset just past the end, and one that ends one byte past it */
    n = lc03(d, 1, 100000, 100000, 1, 2, NULL, fill, sizeof fill);
    assert_int_equal(feed(b, d, n), 0);
    n = lc03(d, 1, 100000, 100000 - 999, 1, 2, NULL, fill, sizeof fill);
    assert_int_equal(feed(b, d, n), 0);
    sc_bus_counters c = counters(b);
    assert_int_equal(c.refused, 3);
    assert_int_equal(g.n, 0);
    /* the half message is given up once silent for SC_BUS_PARTIAL_S */
    assert_int_equal(sc_bus_feed(b, d, 3, ADDR, 5555, 100.0 + SC_BUS_PARTIAL_S + 0.1, 1), 0);
    c = counters(b);
    assert_int_equal(c.evicted, 1);
    assert_int_equal(c.malformed, 1);
    assert_int_equal(c.reasm_bytes, 0);
    sc_bus_close(b);
}

static void test_huge_claims_are_refused_before_any_allocation(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    uint8_t d[2048], fill[1000] = { 0 };
    const uint32_t claims[] = { 256u << 20, 0xFFFFFFFFu, SC_MSG_MAX_BYTES + 1, 0 };
    for (int i = 0; i < 4; i++) {
        size_t n = lc03(d, (uint32_t)i, claims[i], 0, 0, 65535, CH, fill, sizeof fill);
        assert_int_equal(feed(b, d, n), 0);
        assert_int_equal(counters(b).reasm_bytes, 0);
    }
    /* the largest message we take is held */
    size_t n = lc03(d, 9, SC_MSG_MAX_BYTES, 0, 0, 129, CH, fill, sizeof fill);
    assert_int_equal(feed(b, d, n), 0);
    sc_bus_counters c = counters(b);
    assert_int_equal(c.refused, 4);
    assert_int_equal(c.reasm_bytes, SC_MSG_MAX_BYTES + 129 * 8);
    assert_int_equal(c.nomem, 0);
    sc_bus_close(b);
    assert_int_equal(sc_bus_reasm_process_bytes(), 0);
}

static void test_counts_and_numbers_that_do_not_match_are_refused(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    uint8_t d[2048], fill[1000] = { 0 };
    long refused = 0;
    assert_int_equal(feed(b, d, first_of_two(d, 1)), 0);
    size_t n = lc03(d, 1, 100000, 1000, 1, 3, NULL, fill, sizeof fill);     /* count */
    feed(b, d, n), refused++;
    n = lc03(d, 1, 100001, 1000, 1, 2, NULL, fill, sizeof fill);            /* size */
    feed(b, d, n), refused++;
    n = lc03(d, 1, 100000, 1000, 2, 2, NULL, fill, sizeof fill);            /* number */
    feed(b, d, n), refused++;
    n = lc03(d, 1, 100000, 1000, 1, 2, NULL, fill, 0);                      /* empty */
    feed(b, d, n), refused++;
    n = lc03(d, 2, 100000, 1000, 1, 2, NULL, fill, sizeof fill);            /* not begun */
    feed(b, d, n), refused++;
    n = lc03(d, 3, 100000, 0, 0, 1, CH, fill, sizeof fill);                 /* 1 fragment */
    feed(b, d, n), refused++;
    n = lc03(d, 4, 100000, 0, 0, 1000, CH, fill, 0);                        /* no data */
    feed(b, d, n), refused++;
    n = lc03(d, 5, 100000, 7, 0, 2, CH, fill, sizeof fill);                 /* fragment 0 off 7 */
    feed(b, d, n), refused++;
    n = lc03(d, 6, 10, 0, 0, 11, CH, fill, 5);                              /* more fragments than bytes */
    feed(b, d, n), refused++;
    n = lc03(d, 7, 100, 0, 0, 2, CH, fill, 101);                            /* more data than size */
    feed(b, d, n), refused++;
    sc_bus_counters c = counters(b);
    assert_int_equal(c.refused, refused);
    assert_int_equal(c.messages, 0);
    assert_int_equal(g.n, 0);
    sc_bus_close(b);
}

static void test_duplicate_and_overlapping_fragments_are_refused(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    uint8_t d[2048], fill[1000] = { 0 };
    /* a message of 2500 bytes in 3 fragments of 1000 (1000 + 500 + 1000) */
    size_t n = lc03(d, 1, 2500, 0, 0, 3, CH, fill, 1000);
    assert_int_equal(feed(b, d, n), 0);
    assert_int_equal(feed(b, d, n), 0);          /* fragment 0 again */
    n = lc03(d, 1, 2500, 1000, 1, 3, NULL, fill, 1000);
    assert_int_equal(feed(b, d, n), 0);
    assert_int_equal(feed(b, d, n), 0);          /* fragment 1 again */
    /* fragment 2 overlaps fragment 1 and leaves a gap at the end */
    n = lc03(d, 1, 2500, 1500, 2, 3, NULL, fill, 500);
    assert_int_equal(feed(b, d, n), 0);
    sc_bus_counters c = counters(b);
    assert_int_equal(c.refused, 3);
    assert_int_equal(c.messages, 0);
    assert_int_equal(c.reasm_bytes, 0);
    /* all in, tiling with an overlap at the end: also refused */
    n = lc03(d, 2, 2000, 0, 0, 3, CH, fill, 1000);
    feed(b, d, n);
    n = lc03(d, 2, 2000, 1000, 1, 3, NULL, fill, 1000);
    feed(b, d, n);
    n = lc03(d, 2, 2000, 1500, 2, 3, NULL, fill, 500);
    assert_int_equal(feed(b, d, n), 0);
    assert_int_equal(counters(b).refused, 4);
    assert_int_equal(g.n, 0);
    sc_bus_close(b);
}

static void test_truncated_and_malformed_datagrams_are_counted(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g);
    uint8_t d[2048];
    size_t n = first_of_two(d, 1);
    long bad = 0;
    for (size_t len = 0; len < SC_BUS_LONG_HDR; len++, bad++)
        assert_int_equal(feed(b, d, len), 0);   /* LC03 header cut short */
    static const uint8_t s[] = { 'L', 'C', '0', '2', 0, 0, 0, 1, 'A', 'B' };
    for (size_t len = 0; len <= sizeof s; len++, bad++)
        assert_int_equal(feed(b, s, len), 0);   /* LC02 without its NUL */
    /* a channel of 64 bytes, and magic not LCM's */
    uint8_t l[SC_BUS_SHORT_HDR + 70];
    memcpy(l, s, SC_BUS_SHORT_HDR);
    memset(l + SC_BUS_SHORT_HDR, 'A', 64);
    l[SC_BUS_SHORT_HDR + 64] = 0;
    assert_int_equal(feed(b, l, SC_BUS_SHORT_HDR + 65), 0), bad++;
    memcpy(l, "LC04", 4);
    assert_int_equal(feed(b, l, sizeof l), 0), bad++;
    /* a first fragment whose channel has no NUL */
    memset(d + SC_BUS_LONG_HDR, 'A', n - SC_BUS_LONG_HDR);
    assert_int_equal(feed(b, d, n), 0), bad++;
    sc_bus_counters c = counters(b);
    assert_int_equal(c.malformed, bad);
    assert_int_equal(c.datagrams, bad);
    assert_int_equal(sc_bus_dropped(&c), bad);
    sc_bus_close(b);
}

static void test_reassembly_memory_stays_bounded(void **state)
{
    (void)state;
    got g = { 0 };
    sc_bus *b = detached(&g), *b2 = detached(&g);
    uint8_t d[2048], fill[1000] = { 0 };
    /* a hundred messages of the largest size begun, none finished */
    for (uint32_t i = 0; i < 100; i++) {
        size_t n = lc03(d, i, SC_MSG_MAX_BYTES, 0, 0, 200, CH, fill, sizeof fill);
        feed(b, d, n);
        sc_bus_counters c = counters(b);
        assert_true(c.reasm_bytes <= SC_BUS_REASM_BYTES);
        n = lc03(d, i, 1000000, 0, 0, 20, CH, fill, sizeof fill);
        feed(b2, d, n);
        assert_true(sc_bus_reasm_process_bytes() <= SC_BUS_REASM_PROCESS_BYTES);
    }
    sc_bus_counters c = counters(b), c2 = counters(b2);
    assert_int_equal(c.evicted, 100 - 2);       /* two fit, the oldest go */
    assert_int_equal(c2.evicted, 100 - SC_BUS_INFLIGHT);
    assert_int_equal(c.refused + c.nomem, 0);
    assert_int_equal(g.n, 0);
    sc_bus_close(b);
    sc_bus_close(b2);
    assert_int_equal(sc_bus_reasm_process_bytes(), 0);
}

/* ---- over loopback multicast ---- */

/* A plain socket on the group, to see the datagrams as sent. */
static int raw_listener(void)
{
    int fd = socket(AF_INET, SOCK_DGRAM, 0), one = 1;
    assert_true(fd >= 0);
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    setsockopt(fd, SOL_SOCKET, SO_REUSEPORT, &one, sizeof one);
    struct sockaddr_in a = { .sin_family = AF_INET, .sin_port = htons((uint16_t)port) };
    inet_pton(AF_INET, "239.255.76.67", &a.sin_addr);
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    struct ip_mreq m = { .imr_multiaddr = a.sin_addr, .imr_interface = { htonl(INADDR_ANY) } };
    assert_int_equal(setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &m, sizeof m), 0);
    return fd;
}

static ssize_t raw_recv(int fd, uint8_t *buf, size_t cap)
{
    struct pollfd pf = { fd, POLLIN, 0 };
    assert_int_equal(poll(&pf, 1, 2000), 1);
    return recv(fd, buf, cap, 0);
}

/* Handle b until g has n messages or 2 s pass. */
static void wait_for(sc_bus *b, got *g, int n)
{
    for (int i = 0; i < 200 && g->n < n; i++)
        assert_true(sc_bus_handle(b, 0.01) >= 0);
    assert_int_equal(g->n, n);
}

static void test_sent_datagrams_are_lcm_frames(void **state)
{
    (void)state;
    int fd = raw_listener();
    sc_bus *b = NULL;
    assert_int_equal(sc_bus_open(url, &b, NULL, 0), SC_OK);
    uint8_t *buf = malloc(70000), *msg = malloc(100000);
    for (int i = 0; i < 100000; i++)
        msg[i] = (uint8_t)(i ^ (i >> 8));
    assert_int_equal(sc_bus_publish(b, "AB", "xyz", 3), SC_OK);
    static const uint8_t short0[] = { 'L', 'C', '0', '2', 0, 0, 0, 0, 'A', 'B', 0, 'x', 'y', 'z' };
    assert_int_equal(raw_recv(fd, buf, 70000), sizeof short0);
    assert_memory_equal(buf, short0, sizeof short0);
    /* 100000 bytes: two fragments, seqno 1 */
    assert_int_equal(sc_bus_publish(b, "AB", msg, 100000), SC_OK);
    uint8_t hdr[SC_BUS_LONG_HDR];
    size_t first = SC_BUS_FRAG_MAX - 3;
    lc03(hdr, 1, 100000, 0, 0, 2, NULL, NULL, 0);
    assert_int_equal(raw_recv(fd, buf, 70000), SC_BUS_DGRAM_MAX);
    assert_memory_equal(buf, hdr, sizeof hdr);
    assert_memory_equal(buf + SC_BUS_LONG_HDR, "AB", 3);
    assert_memory_equal(buf + SC_BUS_LONG_HDR + 3, msg, first);
    lc03(hdr, 1, 100000, (uint32_t)first, 1, 2, NULL, NULL, 0);
    assert_int_equal(raw_recv(fd, buf, 70000), SC_BUS_LONG_HDR + 100000 - first);
    assert_memory_equal(buf, hdr, sizeof hdr);
    assert_memory_equal(buf + SC_BUS_LONG_HDR, msg + first, 100000 - first);
    /* the largest short message, and one byte more */
    assert_int_equal(sc_bus_publish(b, "AB", msg, SC_BUS_SHORT_MAX - 3), SC_OK);
    assert_int_equal(raw_recv(fd, buf, 70000), SC_BUS_DGRAM_MAX);
    assert_memory_equal(buf, "LC02", 4);
    assert_int_equal(sc_bus_publish(b, "AB", msg, SC_BUS_SHORT_MAX - 2), SC_OK);
    assert_int_equal(raw_recv(fd, buf, 70000), SC_BUS_DGRAM_MAX);
    assert_memory_equal(buf, "LC03", 4);
    assert_int_equal(raw_recv(fd, buf, 70000), SC_BUS_LONG_HDR + 13);   /* 65497 - 65484 */
    close(fd);
    sc_bus_close(b);
    free(buf);
    free(msg);
}

static void test_messages_round_trip_over_multicast(void **state)
{
    (void)state;
    sc_bus *tx = NULL, *rx = NULL;
    got g = { 0 };
    assert_int_equal(sc_bus_open(url, &tx, NULL, 0), SC_OK);
    assert_int_equal(sc_bus_open(url, &rx, NULL, 0), SC_OK);
    assert_int_equal(sc_bus_subscribe(rx, CH, on_msg, &g), SC_OK);
    sc_bus_counters c = counters(rx);
    /* root gets it whatever net.core.rmem_max says (SO_RCVBUFFORCE) */
    int big = c.rcvbuf_bytes >= SC_BUS_RCVBUF_MIN;
    if (geteuid() == 0)
        assert_true(big);
    /* sent whole before any is read: the largest must fit in the socket's
     * buffer at once (64 datagrams of 64 KiB) */
    const size_t sizes[] = { 0, 1, 1000, SC_BUS_SHORT_MAX - sizeof CH, 65500, 200000,
                             SC_MSG_MAX_BYTES / 2 };
    uint8_t *msg = malloc(SC_MSG_MAX_BYTES);
    for (size_t i = 0; i < SC_MSG_MAX_BYTES; i++)
        msg[i] = (uint8_t)(i * 2654435761u >> 24);
    for (int k = 0; k < 7; k++) {
        assert_int_equal(sc_bus_publish(tx, CH, msg, sizes[k]), SC_OK);
        wait_for(rx, &g, k + 1);
        assert_int_equal(g.len, sizes[k]);
        assert_memory_equal(g.data, msg, sizes[k]);
    }
    /* a burst of 1000 short messages: each taken or counted as dropped by
     * the kernel, and none dropped with the full buffer. The kernel's count
     * comes with the next datagram queued: one is sent whenever the queue
     * is found empty. */
    for (int k = 0; k < 1000; k++)
        assert_int_equal(sc_bus_publish(tx, CH, msg, 200), SC_OK);
    for (int i = 0; i < 200; i++) {
        c = counters(rx);
        if ((uint64_t)g.n - 7 + c.kernel >= 1000)
            break;
        if (sc_bus_handle(rx, 0.01) == 0)
            assert_int_equal(sc_bus_publish(tx, "SC_SENTINEL", msg, 1), SC_OK);
    }
    c = counters(rx);
    assert_int_equal((uint64_t)g.n - 7 + c.kernel, 1000);
    assert_int_equal(c.malformed + c.refused + c.evicted + c.nomem, 0);
    if (big)
        assert_int_equal(c.kernel, 0);
    assert_int_equal(sc_bus_publish(tx, "", msg, 1), SC_EINVAL);
    char longch[SC_BUS_CHANNEL_MAX + 2];
    memset(longch, 'A', sizeof longch - 1);
    longch[sizeof longch - 1] = 0;
    assert_int_equal(sc_bus_publish(tx, longch, msg, 1), SC_EINVAL);
    assert_int_equal(sc_bus_subscribe(rx, longch, on_msg, &g), SC_EINVAL);
    assert_int_equal(sc_bus_subscribe(rx, CH, on_msg, &g), SC_EINVAL);
    sc_bus_close(tx);
    sc_bus_close(rx);
    free(msg);
    free(g.data);
}

/* liblcm on the other end: what it sends we take, what we send it takes. */
typedef struct lgot {
    int n;
    size_t len;
    int same;
    const uint8_t *want;
} lgot;

static void on_lcm(const lcm_recv_buf_t *rb, const char *channel, void *ctx)
{
    (void)channel;
    lgot *g = ctx;
    g->n++;
    g->len = rb->data_size;
    g->same = !memcmp(rb->data, g->want, rb->data_size);
}

static void test_liblcm_reads_us_and_we_read_it(void **state)
{
    (void)state;
    char lurl[160];
    snprintf(lurl, sizeof lurl, "%s&recv_buf_size=4194304", url);
    lcm_t *l = lcm_create(lurl);
    assert_non_null(l);
    sc_bus *b = NULL;
    got g = { 0 };
    assert_int_equal(sc_bus_open(url, &b, NULL, 0), SC_OK);
    assert_int_equal(sc_bus_subscribe(b, CH, on_msg, &g), SC_OK);
    uint8_t *msg = malloc(300000);
    for (int i = 0; i < 300000; i++)
        msg[i] = (uint8_t)(i * 7 + (i >> 11));
    lgot lg = { .want = msg };
    assert_non_null(lcm_subscribe(l, "SC_FROM_US", on_lcm, &lg));
    const unsigned sizes[] = { 10, 300000 };
    for (int k = 0; k < 2; k++) {
        assert_int_equal(lcm_publish(l, CH, msg, sizes[k]), 0);
        wait_for(b, &g, k + 1);
        assert_int_equal(g.len, sizes[k]);
        assert_memory_equal(g.data, msg, sizes[k]);
        assert_int_equal(sc_bus_publish(b, "SC_FROM_US", msg, sizes[k]), SC_OK);
        for (int i = 0; i < 200 && lg.n < k + 1; i++)
            lcm_handle_timeout(l, 10);
        assert_int_equal(lg.n, k + 1);
        assert_int_equal(lg.len, sizes[k]);
        assert_true(lg.same);
    }
    lcm_destroy(l);
    sc_bus_close(b);
    free(msg);
    free(g.data);
}

static void test_urls_other_than_udpm_are_refused(void **state)
{
    (void)state;
    sc_bus *b = (sc_bus *)1;
    char why[200];
    const char *bad[] = { "mpudpm://239.255.76.67:7667", "file:///tmp/x", "memq://",
                          "udpm://10.0.0.1:7667", "udpm://999.1.1.1:7667",
                          "udpm://239.255.76.67:0", "udpm://239.255.76.67:x",
                          "udpm://239.255.76.67:7667?ttl=300",
                          "udpm://239.255.76.67:7667?frob=1", NULL };
    for (int i = 0; bad[i]; i++) {
        why[0] = 0;
        assert_int_equal(sc_bus_open(bad[i], &b, why, sizeof why), SC_EINVAL);
        assert_null(b);
        assert_true(strlen(why) > 5);
    }
    assert_int_equal(sc_bus_open("mpudpm://239.255.76.67:7667", &b, why, sizeof why),
                     SC_EINVAL);
    assert_non_null(strstr(why, "udpm://"));
    assert_int_equal(sc_bus_open(NULL, &b, NULL, 0), SC_EINVAL);
    assert_int_equal(sc_bus_handle(NULL, 0), SC_EIO);
    assert_int_equal(sc_bus_fd(NULL), -1);
    sc_bus_close(NULL);
}

int main(void)
{
    srand((unsigned)time(NULL) ^ (unsigned)getpid());
    port = 20000 + rand() % 10000;
    snprintf(url, sizeof url, "udpm://239.255.76.67:%d?ttl=0", port);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_short_message_as_lcm_frames_it_is_taken),
        cmocka_unit_test(test_fragments_as_lcm_frames_them_are_reassembled),
        cmocka_unit_test(test_wrapping_offset_is_refused),
        cmocka_unit_test(test_huge_claims_are_refused_before_any_allocation),
        cmocka_unit_test(test_counts_and_numbers_that_do_not_match_are_refused),
        cmocka_unit_test(test_duplicate_and_overlapping_fragments_are_refused),
        cmocka_unit_test(test_truncated_and_malformed_datagrams_are_counted),
        cmocka_unit_test(test_reassembly_memory_stays_bounded),
        cmocka_unit_test(test_sent_datagrams_are_lcm_frames),
        cmocka_unit_test(test_messages_round_trip_over_multicast),
        cmocka_unit_test(test_liblcm_reads_us_and_we_read_it),
        cmocka_unit_test(test_urls_other_than_udpm_are_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
