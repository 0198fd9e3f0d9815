/* record.c - a frame record captured from a world (docs/DESIGN.md section
 * 7.7): the world's side of what simcluster run --record and --publish
 * write; the record's wire form is lib/net/frame_record.c. */
#include "frame_record.h"
#include "world.h"

int sc_frame_record_capture(sc_frame_record *r, const sc_world *w, int64_t frame, double time_s)
{
    if (!r || !w)
        return SC_EINVAL;
    int n = sc_world_body_count(w);
    if (n > SC_FRAME_MAX_BODIES)
        return SC_ETOOBIG;
    if (!r->shape || r->n != n) {
        sc_frame_record_free(r);
        int rc = sc_frame_record_alloc(r, n);
        if (rc != SC_OK)
            return rc;
    }
    r->frame = frame;
    r->time_s = time_s;
    for (int i = 0; i < n; i++) {
        r->shape[i] = sc_shape_hash(sc_body_shape(w, i));
        sc_body_get_pose(w, i, &r->pos[3 * i], &r->quat[4 * i]);
        r->state[i] = (int8_t)sc_body_state(w, i);
    }
    return SC_OK;
}

