/* fuzz_frame_record.c - libFuzzer target for the frame record decoders
 * (lib/net/frame_record.c, public header only). Any bytes go to
 * sc_frame_record_decode and sc_frame_shape_decode: they must refuse them
 * with SC_EFORMAT (or SC_ENOMEM) leaving nothing allocated, or accept
 * them, and then a state encodes back to exactly the same bytes and a
 * shape carries the hash its record claims, with indices inside its
 * vertices. Seeds in tests/fuzz/corpus/frame_record/ are records written
 * by simcluster run --record. Built like fuzz_load.c; make check replays
 * the corpus. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "simcluster_net.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_state(const uint8_t *data, size_t size)
{
    sc_frame_record r;
    int rc = sc_frame_record_decode(data, size, &r);
    if (rc != SC_OK) {
        if ((rc != SC_EFORMAT && rc != SC_ENOMEM) || r.shape || r.pos || r.quat || r.state ||
            r.n)
            abort();
        return;
    }
    if (r.n < 0 || r.n > SC_FRAME_MAX_BODIES || r.frame < 0 || !isfinite(r.time_s))
        abort();
    for (int i = 0; i < r.n; i++) {
        if (r.state[i] < SC_FREE || r.state[i] > SC_STATIC)
            abort();
        for (int a = 0; a < 7; a++)
            if (!isfinite(a < 3 ? r.pos[3 * i + a] : r.quat[4 * i + a - 3]))
                abort();
    }
    uint8_t *again;
    size_t len;
    if (sc_frame_record_encode(&r, &again, &len) != SC_OK || len != size ||
        memcmp(again, data, size) != 0)
        abort();
    free(again);
    sc_frame_record_free(&r);
}

static void check_shape(const uint8_t *data, size_t size)
{
    uint64_t claimed;
    int peek = sc_frame_shape_hash(data, size, &claimed);
    sc_frame_shape s;
    int rc = sc_frame_shape_decode(data, size, &s);
    if (rc != SC_OK) {
        if ((rc != SC_EFORMAT && rc != SC_ENOMEM) || s.xyz || s.tri || s.nverts)
            abort();
        return;
    }
    if (peek != SC_OK || s.hash != claimed || s.kind < SC_SHAPE_SPHERE ||
        s.kind > SC_SHAPE_MESH || s.nverts < 0 || s.ntris < 0 ||
        (s.nverts > 0) != (s.kind == SC_SHAPE_MESH || s.kind == SC_SHAPE_CONVEX))
        abort();
    for (int i = 0; i < 3 * s.ntris; i++)
        if (s.tri[i] < 0 || s.tri[i] >= s.nverts)
            abort();
    sc_frame_shape_free(&s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    check_state(data, size);
    check_shape(data, size);
    return 0;
}
