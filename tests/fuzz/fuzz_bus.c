/* fuzz_bus.c - libFuzzer target for the cluster transport's datagram parser
 * and reassembly (lib/net/bus.c). The input is a run of datagrams, each
 * as one byte (its sender port, and whether time jumps past
 * SC_BUS_PARTIAL_S before it), a 16-bit big-endian length and its bytes,
 * fed to one detached bus subscribed to two channels. Whatever comes, the
 * bytes held for reassembly stay within their budgets, a message handed
 * on is no longer than SC_MSG_MAX_BYTES, every datagram is counted, and
 * nothing is held once the bus is closed. Built like fuzz_envelope.c;
 * make check replays the corpus (tests/fuzz/corpus/bus/: LC02 and LC03
 * messages, the wrapping offset, the 256 MB claim, overlaps). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "bus.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void on_msg(void *ctx, const char *channel, const uint8_t *d, size_t len,
                   int64_t recv_us)
{
    (void)recv_us;
    long *n = ctx;
    if (len > SC_MSG_MAX_BYTES || strlen(channel) > SC_BUS_CHANNEL_MAX || (len && !d))
        abort();
    volatile uint8_t touch = 0;
    for (size_t i = 0; i < len; i += 4096)   /* the bytes are readable */
        touch ^= d[i];
    if (len)
        touch ^= d[len - 1];
    (*n)++;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sc_bus *b = sc_bus_detached();
    if (!b)
        return 0;
    long handed = 0;
    sc_bus_subscribe(b, "SC_X", on_msg, &handed);
    sc_bus_subscribe(b, "SC_UNIT_0000000000004001", on_msg, &handed);
    double now = 1;
    uint64_t fed = 0;
    size_t at = 0;
    while (at + 3 <= size) {
        uint8_t how = data[at];
        size_t len = (size_t)data[at + 1] << 8 | data[at + 2];
        at += 3;
        if (len > size - at)
            len = size - at;
        if (how & 0x80)
            now += SC_BUS_PARTIAL_S + 1;
        sc_bus_feed(b, data + at, len, 0x0a000001u, (uint16_t)(40000 + (how & 3)), now, 1);
        fed++;
        at += len;
        sc_bus_counters c;
        sc_bus_counters_get(b, &c);
        if (c.reasm_bytes > SC_BUS_REASM_BYTES ||
            sc_bus_reasm_process_bytes() > SC_BUS_REASM_PROCESS_BYTES || c.datagrams != fed ||
            c.malformed + c.refused + c.nomem + c.messages + c.ignored > fed + c.messages)
            abort();
    }
    sc_bus_counters c;
    sc_bus_counters_get(b, &c);
    if ((long)c.messages != handed)
        abort();
    sc_bus_close(b);
    if (sc_bus_reasm_process_bytes() != 0)
        abort();
    return 0;
}
