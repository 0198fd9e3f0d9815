/* frame_record.c - the records of a recorded or published run
 * (simcluster_net.h): state_t per frame and shape_t per distinct shape
 * (proto/simcluster.lcm), encoded by the C lcm-gen generates, so logs
 * written before this file existed, and lcm-spy, read them as ever.
 *
 * As in cluster_msg.c, lcm-gen's decoders trust the lengths they read: the
 * body count of a state is checked against the exact size on the raw
 * bytes before the generated decoder allocates anything, and a shape goes
 * through sc_msg_shape_decode's checks (its array lengths, the rebuilt
 * shape and its content hash) first. */
#include <stdlib.h>

#include "frame.h"
#include "frame_record.h"
#include "sclcm_shape_t.h"
#include "sclcm_state_t.h"
#include "simcluster_net.h"

#define FP_BYTES 8
#define STATE_HEAD (FP_BYTES + 8 + 8 + 4)       /* fingerprint, frame, time, n */
#define STATE_PER_BODY (8 + 3 * 8 + 4 * 8 + 1)  /* shape, pos, quat, state */

_Static_assert((size_t)STATE_HEAD + (size_t)SC_FRAME_MAX_BODIES * STATE_PER_BODY <=
               SC_MSG_MAX_PAYLOAD, "a state record fits a message");

static uint64_t be64(const uint8_t *p)
{
    uint64_t x = 0;
    for (int i = 0; i < 8; i++)
        x = x << 8 | p[i];
    return x;
}

/* A body's pose is finite and its state one of SC_FREE .. SC_STATIC. */
static int body_ok(const double *pos, const double *quat, int state)
{
    return sc_finite3(pos) && sc_finite3(quat + 1) && isfinite(quat[0]) && state >= SC_FREE &&
           state <= SC_STATIC;
}

void sc_frame_record_free(sc_frame_record *r)
{
    if (!r)
        return;
    free(r->shape);
    free(r->pos);
    free(r->quat);
    free(r->state);
    memset(r, 0, sizeof *r);
}

/* r's arrays for n bodies (n >= 1 is allocated even for n = 0). */
int sc_frame_record_alloc(sc_frame_record *r, int n)
{
    size_t un = n > 0 ? (size_t)n : 1;
    r->shape = sc_alloc_array(un, sizeof *r->shape);
    r->pos = sc_alloc_array(3 * un, sizeof *r->pos);
    r->quat = sc_alloc_array(4 * un, sizeof *r->quat);
    r->state = sc_alloc_array(un, sizeof *r->state);
    if (!r->shape || !r->pos || !r->quat || !r->state) {
        sc_frame_record_free(r);
        return SC_ENOMEM;
    }
    r->n = n;
    return SC_OK;
}

int sc_frame_record_encode(const sc_frame_record *r, uint8_t **out, size_t *len)
{
    if (!out || !len)
        return SC_EINVAL;
    *out = NULL;
    *len = 0;
    if (!r || r->n < 0 || !isfinite(r->time_s) || r->frame < 0)
        return SC_EINVAL;
    if (r->n > SC_FRAME_MAX_BODIES)
        return SC_ETOOBIG;
    int n = r->n;
    if (n > 0 && (!r->shape || !r->pos || !r->quat || !r->state))
        return SC_EINVAL;
    for (int i = 0; i < n; i++)
        if (!body_ok(&r->pos[3 * i], &r->quat[4 * i], r->state[i]))
            return SC_EINVAL;
    /* state_t's pos and quat are arrays of rows */
    double **rows = sc_alloc_array(2 * (size_t)(n > 0 ? n : 1), sizeof *rows);
    size_t size = STATE_HEAD + (size_t)n * STATE_PER_BODY;
    uint8_t *buf = malloc(size);
    if (!rows || !buf) {
        free(rows);
        free(buf);
        return SC_ENOMEM;
    }
    for (int i = 0; i < n; i++) {
        rows[i] = &r->pos[3 * i];
        rows[n + i] = &r->quat[4 * i];
    }
    /* lcm's int8 array codec memcpy()s even 0 bytes: never from NULL */
    static int8_t no_state[1];
    sclcm_state_t m = { .frame = r->frame, .time = r->time_s, .n = n,
                        .shape = (int64_t *)r->shape, .pos = rows, .quat = rows + n,
                        .state = n > 0 ? r->state : no_state };
    int wrote = sclcm_state_t_encode(buf, 0, (int)size, &m);
    SC_ASSERT(wrote == (int)size);
    (void)wrote;
    free(rows);
    *out = buf;
    *len = size;
    return SC_OK;
}

/* A state of no bodies, read here: lcm's decoder would memcpy() its empty
 * state array to NULL. p holds STATE_HEAD bytes. */
static int decode_empty(const uint8_t *p, sc_frame_record *r)
{
    uint64_t t = be64(p + FP_BYTES + 8);
    double time_s;
    memcpy(&time_s, &t, sizeof time_s);
    int64_t frame = (int64_t)be64(p + FP_BYTES);
    if (be64(p) != (uint64_t)__sclcm_state_t_get_hash() || frame < 0 || !isfinite(time_s))
        return SC_EFORMAT;
    int rc = sc_frame_record_alloc(r, 0);
    if (rc == SC_OK) {
        r->frame = frame;
        r->time_s = time_s;
    }
    return rc;
}

int sc_frame_record_decode(const void *buf, size_t len, sc_frame_record *r)
{
    if (!r)
        return SC_EINVAL;
    memset(r, 0, sizeof *r);
    const uint8_t *p = buf;
    if (!p || len < STATE_HEAD || len > SC_MSG_MAX_PAYLOAD)
        return SC_EFORMAT;
    const uint8_t *q = p + STATE_HEAD - 4;        /* n: a big-endian i32 */
    int64_t n = (int32_t)((uint32_t)q[0] << 24 | (uint32_t)q[1] << 16 | (uint32_t)q[2] << 8 | q[3]);
    if (n < 0 || n > SC_FRAME_MAX_BODIES || len != STATE_HEAD + (size_t)n * STATE_PER_BODY)
        return SC_EFORMAT;
    if (n == 0)
        return decode_empty(p, r);
    sclcm_state_t m;
    memset(&m, 0, sizeof m);
    int rc = SC_EFORMAT;
    if (sclcm_state_t_decode(p, 0, (int)len, &m) == (int)len && m.n == n && m.frame >= 0 &&
        isfinite(m.time)) {
        rc = sc_frame_record_alloc(r, (int)n);
        for (int i = 0; rc == SC_OK && i < (int)n; i++) {
            if (!body_ok(m.pos[i], m.quat[i], m.state[i])) {
                rc = SC_EFORMAT;
                break;
            }
            r->shape[i] = (uint64_t)m.shape[i];
            memcpy(&r->pos[3 * i], m.pos[i], 3 * sizeof *r->pos);
            memcpy(&r->quat[4 * i], m.quat[i], 4 * sizeof *r->quat);
            r->state[i] = m.state[i];
        }
        r->frame = m.frame;
        r->time_s = m.time;
    }
    sclcm_state_t_decode_cleanup(&m);
    if (rc != SC_OK)
        sc_frame_record_free(r);
    return rc;
}

/* ---- shapes ---- */

int sc_frame_shape_encode(const sc_shape *s, uint8_t **out, size_t *len)
{
    return sc_msg_shape_encode(s, out, len);
}

int sc_frame_shape_hash(const void *buf, size_t len, uint64_t *hash)
{
    const uint8_t *p = buf;
    if (!hash)
        return SC_EINVAL;
    if (!p || len < FP_BYTES + 8 || be64(p) != (uint64_t)__sclcm_shape_t_get_hash())
        return SC_EFORMAT;
    *hash = be64(p + FP_BYTES);
    return SC_OK;
}

void sc_frame_shape_free(sc_frame_shape *s)
{
    if (!s)
        return;
    free(s->xyz);
    free(s->tri);
    memset(s, 0, sizeof *s);
}

int sc_frame_shape_decode(const void *buf, size_t len, sc_frame_shape *out)
{
    if (!out)
        return SC_EINVAL;
    memset(out, 0, sizeof *out);
    sc_shape *s;
    int rc = sc_msg_shape_decode(buf, len, &s);
    if (rc != SC_OK)
        return rc;
    sc_shape_release(s);
    /* the content as sent (the rebuilt shape's hash matched it) */
    sclcm_shape_t m;
    memset(&m, 0, sizeof m);
    rc = SC_EFORMAT;
    if (sclcm_shape_t_decode(buf, 0, (int)len, &m) == (int)len) {
        out->hash = (uint64_t)m.hash;
        out->kind = m.kind;
        out->radius = m.radius;
        memcpy(out->half, m.half, sizeof out->half);
        memcpy(out->plane, m.plane, sizeof out->plane);
        out->nverts = m.ncoords / 3;
        out->ntris = m.nidx / 3;
        rc = SC_OK;
        if (m.ncoords > 0) {
            out->xyz = sc_alloc_array((size_t)m.ncoords, sizeof *out->xyz);
            out->tri = sc_alloc_array((size_t)m.nidx, sizeof *out->tri);
            if (!out->xyz || !out->tri) {
                rc = SC_ENOMEM;
            } else {
                memcpy(out->xyz, m.xyz, (size_t)m.ncoords * sizeof *out->xyz);
                for (int i = 0; i < m.nidx; i++)
                    out->tri[i] = m.tri[i];
            }
        }
    }
    sclcm_shape_t_decode_cleanup(&m);
    if (rc != SC_OK)
        sc_frame_shape_free(out);
    return rc;
}
