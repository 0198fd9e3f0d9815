/* bus.h - the cluster transport's insides, for its tests, its fuzz target
 * and tests/cluster_inject.c (bus.c; the public calls are in
 * simcluster_net.h). */
#ifndef SC_BUS_H
#define SC_BUS_H

#include <stddef.h>
#include <stdint.h>

#include "simcluster_net.h"

/* LCM's UDP multicast framing (big-endian fields). */
#define SC_BUS_MAGIC_SHORT 0x4c433032u      /* "LC02": magic, seqno, channel, NUL, data */
#define SC_BUS_MAGIC_LONG 0x4c433033u       /* "LC03": magic, seqno, size, offset,
                                               fragment number, fragments; the first
                                               fragment's data begins with the channel */
#define SC_BUS_SHORT_HDR 8
#define SC_BUS_LONG_HDR 20
#define SC_BUS_SHORT_MAX 65499              /* channel, NUL and data in one LC02 */
#define SC_BUS_FRAG_MAX 65487               /* bytes after an LC03 header */
#define SC_BUS_DGRAM_MAX (SC_BUS_SHORT_HDR + SC_BUS_SHORT_MAX)
#define SC_BUS_PARTIAL_S 2.0                /* a message not complete this long after
                                               its last fragment is given up */

/* A bus with no sockets: datagrams come only through sc_bus_feed, and
 * sc_bus_publish fails with SC_EIO. NULL when out of memory. */
sc_bus *sc_bus_detached(void);
/* Hand b one datagram as if read from sender addr:port (host order) at
 * now_s (monotonic seconds; a partial message older than
 * SC_BUS_PARTIAL_S is given up) and recv_us: the number of messages
 * handed to handlers (0 or 1). */
int sc_bus_feed(sc_bus *b, const uint8_t *dgram, size_t len, uint32_t addr, uint16_t port,
                double now_s, int64_t recv_us);
/* Send one datagram as it is (hostile-traffic tests): SC_OK or SC_EIO. */
int sc_bus_send_raw(sc_bus *b, const void *dgram, size_t len);
/* The bytes every bus of this process holds for reassembly now. */
size_t sc_bus_reasm_process_bytes(void);

#endif
