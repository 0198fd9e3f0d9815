/* compute.c - the compute node a daemon runs received units on
 * (simcluster_net.h): a per-thread narrow-phase context on a private ODE
 * copy, received units decoded against the caller's shape cache, and
 * their results packed for the reply. The daemon around it (queues,
 * shape requests, heartbeats) is not part of the library. */
#include <stdlib.h>

#include "exec.h"
#include "unit_wire.h"
#include "simcluster_net.h"

/* Shapes one decode stands in for while it lists the missing ones. */
#define STAND_INS 64

struct sc_compute {
    const sc_ode *ode;
    sc_np_ctx *np;
};

struct sc_remote_unit {
    sc_wire_unit wu;            /* its job points into it: never moved */
    int ran;
    int nshapes;
    sc_shape **shapes;          /* one reference per pair end (released on free) */
};

sc_compute *sc_compute_create(void)
{
    sc_compute *c = calloc(1, sizeof *c);
    if (!c) {
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    c->ode = sc_ode_acquire();
    c->np = sc_np_create_on(c->ode);
    if (!c->np) {
        sc_ode_release(c->ode);
        free(c);
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    return c;
}

void sc_compute_destroy(sc_compute *c)
{
    if (!c)
        return;
    sc_np_destroy(c->np);
    sc_ode_release(c->ode);
    free(c);
}

/* The caller's find, and for a shape it lacks a stand-in with the right
 * hash, so that decoding goes on and finds every missing one (a unit that
 * needed one is never run). */
typedef struct finder {
    sc_shape_find_fn find;
    void *ctx;
    uint64_t missing[STAND_INS];
    sc_shape stand_in[STAND_INS];
    int nmissing;
} finder;

static const sc_shape *find_or_stand_in(void *ctx, uint64_t hash)
{
    finder *f = ctx;
    const sc_shape *s = f->find(f->ctx, hash);
    if (s)
        return s;
    for (int i = 0; i < f->nmissing; i++)
        if (f->missing[i] == hash)
            return &f->stand_in[i];
    if (f->nmissing == STAND_INS)
        return NULL;            /* the rest are asked for next time */
    int i = f->nmissing++;
    f->missing[i] = hash;
    memset(&f->stand_in[i], 0, sizeof f->stand_in[i]);
    f->stand_in[i].hash = hash;
    return &f->stand_in[i];
}

void sc_remote_unit_free(sc_remote_unit *u)
{
    if (!u)
        return;
    for (int i = 0; i < u->nshapes; i++)
        sc_shape_release(u->shapes[i]);
    free(u->shapes);
    sc_wire_unit_free(&u->wu);
    free(u);
}

int sc_remote_unit_decode(const void *wire, size_t len, sc_shape_find_fn find, void *find_ctx,
                          sc_remote_unit **out)
{
    if (!out)
        return SC_EINVAL;
    *out = NULL;
    if (!find || (!wire && len))
        return SC_EINVAL;
    finder *f = malloc(sizeof *f);
    sc_remote_unit *u = calloc(1, sizeof *u);
    if (!f || !u) {
        free(f);
        free(u);
        return SC_ENOMEM;
    }
    f->find = find;
    f->ctx = find_ctx;
    f->nmissing = 0;
    int rc = sc_wire_unit_decode(wire, len, find_or_stand_in, f, &u->wu);
    int missing = f->nmissing;
    free(f);
    if (missing > 0 || rc != SC_OK) {
        /* the pairs may point at the stand-ins just freed: nothing reads them */
        if (rc == SC_OK)
            sc_wire_unit_free(&u->wu);
        free(u);
        return missing > 0 ? missing : rc;
    }
    /* the caller's cache may drop a shape while the unit waits for a thread:
     * a reference per pair end, and per body of a group (island bodies
     * travel without shapes) */
    int np = u->wu.job.npairs;
    int nb = u->wu.job.kind == SC_UNIT_GROUP ? u->wu.nbodies : 0;
    if (np > 0 || nb > 0) {
        u->shapes = sc_alloc_array(2 * (size_t)np + (size_t)nb, sizeof *u->shapes);
        if (!u->shapes) {
            sc_remote_unit_free(u);
            return SC_ENOMEM;
        }
        for (int i = 0; i < np; i++) {
            u->shapes[u->nshapes++] = sc_shape_retain((sc_shape *)u->wu.pairs[i].sa);
            u->shapes[u->nshapes++] = sc_shape_retain((sc_shape *)u->wu.pairs[i].sb);
        }
        for (int i = 0; i < nb; i++)
            u->shapes[u->nshapes++] = sc_shape_retain(u->wu.bodies[i].shape);
    }
    *out = u;
    return SC_OK;
}

int sc_compute_run(sc_compute *c, sc_remote_unit *u)
{
    if (!c || !u)
        return SC_EINVAL;
    sc_unit_run(c->np, &u->wu.job, &u->wu.unit);
    u->ran = 1;
    return SC_OK;
}

int sc_remote_unit_result(const sc_remote_unit *u, uint8_t **out, size_t *len)
{
    if (!out || !len)
        return SC_EINVAL;
    *out = NULL;
    *len = 0;
    if (!u || !u->ran)
        return SC_EINVAL;
    size_t n = sc_wire_result_pack(&u->wu, NULL, 0);
    uint8_t *buf = n ? malloc(n) : NULL;
    if (!buf || sc_wire_result_pack(&u->wu, buf, n) != n) {
        free(buf);
        return SC_ENOMEM;
    }
    *out = buf;
    *len = n;
    return SC_OK;
}
