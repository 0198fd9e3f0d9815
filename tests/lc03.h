/* lc03.h - LCM's fragment datagram (LC03) made by hand, for the tests that
 * check the transport's reassembly (test_bus.c) and attack it with real
 * programs (cluster_inject.c). Needs bus.h before it. */
#ifndef SC_TEST_LC03_H
#define SC_TEST_LC03_H

#include <stdint.h>
#include <string.h>

static inline void put_be32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

/* The LC03 header into p and, for a first fragment (channel not NULL), the
 * channel and its NUL: the bytes written; the fragment's data follows. */
static inline size_t lc03_head(uint8_t *p, uint32_t seqno, uint32_t size, uint32_t off,
                               uint16_t no, uint16_t nfrag, const char *channel)
{
    put_be32(p, SC_BUS_MAGIC_LONG);
    put_be32(p + 4, seqno);
    put_be32(p + 8, size);
    put_be32(p + 12, off);
    p[16] = (uint8_t)(no >> 8);
    p[17] = (uint8_t)no;
    p[18] = (uint8_t)(nfrag >> 8);
    p[19] = (uint8_t)nfrag;
    size_t at = SC_BUS_LONG_HDR;
    if (channel) {
        size_t cl = strlen(channel) + 1;
        memcpy(p + at, channel, cl);
        at += cl;
    }
    return at;
}

#endif
