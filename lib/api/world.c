/* world.c - the world owns bodies, shape references and per-frame state;
 * this file holds its public API (create, add, query, energy, hash,
 * stats). The frame itself runs in step.c over detect.c, integrate.c,
 * contact.c and state.c. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cluster.h"
#include "sc_internal.h"
#include "vecmath.h"

#define CONFIG_COOKIE 0x5c0f1a
#define BODY_COOKIE 0x5cb0d1

SC_API sc_world_config sc_world_config_default(void)
{
    sc_world_config c;
    memset(&c, 0, sizeof c);
    v3_set(c.gravity, 0, 0, -9.81);
    c.broadphase = SC_BROADPHASE_AUTO;
    c.contact_tol_m = 1e-3;
    c.internal_cookie = CONFIG_COOKIE;
    return c;
}

SC_API sc_body_desc sc_body_desc_default(void)
{
    sc_body_desc d;
    memset(&d, 0, sizeof d);
    d.mass = 1;
    d.quat[0] = 1;
    d.restitution = 0.5;
    d.friction = 0.5;
    d.density = 1000;
    d.internal_cookie = BODY_COOKIE;
    return d;
}

SC_API sc_world *sc_world_create(const sc_world_config *cfg)
{
    sc_world_config c = cfg ? *cfg : sc_world_config_default();
    if (c.internal_cookie != CONFIG_COOKIE) {
        sc_set_error(SC_ENOINIT);
        return NULL;
    }
    if (!sc_finite3(c.gravity) || c.workers < 0 || c.workers > SC_MAX_WORKERS || !(c.contact_tol_m > 0) ||
        !isfinite(c.contact_tol_m) || !(c.cluster_deadline_s >= 0) ||
        !isfinite(c.cluster_deadline_s) || (c.key_file && !c.cluster) || c.broadphase < SC_BROADPHASE_AUTO ||
        c.broadphase > SC_BROADPHASE_SAP || (c.motion_groups != 0 && c.motion_groups != 1)) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    sc_world *w = calloc(1, sizeof *w);
    if (!w) {
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    w->cfg = c;
    w->cfg.cluster = NULL;   /* not kept: the caller's strings may go away */
    w->cfg.key_file = NULL;
    w->bp = sc_bp_create();
    if (!w->bp) {
        sc_world_destroy(w);
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    /* nodes: this thread (node 0) and workers - 1 worker threads */
    int nodes = c.workers;
    if (nodes == 0) {
        long cpus = sysconf(_SC_NPROCESSORS_ONLN);
        nodes = cpus < 1 ? 1 : cpus > SC_MAX_WORKERS ? SC_MAX_WORKERS : (int)cpus;
    }
    w->cfg.workers = nodes;
    w->nlocal = nodes;
    int all = nodes + (c.cluster ? SC_MAX_DAEMONS : 0);
    w->nodes = sc_calloc_array((size_t)all, sizeof *w->nodes);
    w->pool = sc_local_pool_create();
    int rc = w->nodes && w->pool ? sc_sched_init(&w->sched, all) : SC_ENOMEM;
    for (int k = 0; k < nodes && rc == SC_OK; k++) {
        w->nodes[k] = sc_node_local_create(w->pool, k, k == 0);
        if (!w->nodes[k])
            rc = SC_ENOMEM;
        else
            w->nnodes++;
        if (w->nodes[k] && sc_node_local_private_ode(w->nodes[k]))
            w->stats.private_ode++;
    }
    if (rc == SC_OK && c.cluster)
        rc = sc_cluster_create(w, c.cluster, c.key_file, c.cluster_deadline_s, nodes,
                               &w->cluster);
    for (int k = 0; rc == SC_OK && k < SC_MAX_DAEMONS && w->cluster; k++)
        w->nodes[w->nnodes++] = sc_cluster_node(w->cluster, k);
    if (rc != SC_OK) {
        sc_world_destroy(w);
        sc_set_error(rc);
        return NULL;
    }
    w->stats.nodes = w->nlocal;
    return w;
}

SC_API void sc_world_destroy(sc_world *w)
{
    if (!w)
        return;
    for (int i = 0; i < w->nbodies; i++)
        sc_shape_release(w->bodies[i].shape);
    sc_local_pool_stop(w->pool);
    for (int k = 0; k < w->nnodes; k++)
        w->nodes[k]->ops->destroy(w->nodes[k]);
    free(w->nodes);
    sc_cluster_destroy(w->cluster);
    sc_local_pool_destroy(w->pool);
    sc_world_scratch_free(w->bigsub);
    sc_world_scratch_free(w);
}

/* Everything a world owns but its bodies' shapes and its nodes
 * (also a group's scratch sub-world, whose bodies are copies). */
void sc_world_scratch_free(void *world)
{
    sc_world *w = world;
    if (!w)
        return;
    sc_bp_destroy(w->gbp);
    sc_group_scratch_free(w);
    free(w->gcontacts);
    free(w->gpairs);
    free(w->gout);
    free(w->sub_ids);
    sc_sched_free(&w->sched);
    free(w->units);
    free(w->upairs);
    free(w->ucontacts);
    free(w->uncontact);
    free(w->utoi);
    free(w->centre);
    free(w->poses);
    free(w->radius);
    free(w->active);
    free(w->pairs);
    free(w->contacts);
    free(w->saved);
    free(w->touched);
    free(w->c0);
    sc_islands_free(&w->islands);
    free(w->bodies);
    sc_bp_destroy(w->bp);
    free(w);
}

static int quat_ok(const double q[4])
{
    double n = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    return isfinite(n) && n > 1e-12;
}

SC_API int sc_body_add(sc_world *w, const sc_body_desc *d)
{
    if (!w || !d || !d->shape)
        return SC_EINVAL;
    if (d->internal_cookie != BODY_COOKIE)
        return SC_ENOINIT;
    if (!sc_finite3(d->pos) || !quat_ok(d->quat) || !sc_finite3(d->vel) ||
        !sc_finite3(d->omega) || !(d->restitution >= 0 && d->restitution <= 1) ||
        !(d->friction >= 0) || !isfinite(d->friction))
        return SC_EINVAL;
    double mass = d->mass;
    if (mass == SC_MASS_FROM_DENSITY) {
        if (!(d->density > 0) || !isfinite(d->density))
            return SC_EINVAL;
        mass = d->density * d->shape->mp.volume;
    }
    if (!(mass >= 0) || !isfinite(mass))
        return SC_EINVAL;
    if (d->shape->kind == SC_SHAPE_PLANE && mass != 0)
        return SC_ENOTSUP;              /* an infinite half space cannot move */
    int err = sc_grow((void **)&w->bodies, &w->cap, w->nbodies + 1, sizeof *w->bodies, INT_MAX);
    if (err != SC_OK)
        return err;
    sc_body *b = &w->bodies[w->nbodies];
    memset(b, 0, sizeof *b);
    b->shape = sc_shape_retain(d->shape);
    b->mass = mass;
    v3_copy(b->com, d->shape->mp.com);
    memcpy(b->q, d->quat, sizeof b->q);
    q_normalize(b->q);
    double rc[3];
    q_rotate(rc, b->q, b->com);
    v3_add(b->x, d->pos, rc);
    if (mass > 0) {
        double k = mass / d->shape->mp.volume;
        for (int i = 0; i < 9; i++)
            b->inertia[i] = k * d->shape->mp.inertia[i];
        if (!m3_inverse(b->inv_inertia, b->inertia)) {
            sc_shape_release(b->shape);
            return SC_EINVAL;
        }
        b->inv_mass = 1.0 / mass;
        v3_copy(b->w, d->omega);
        /* the desc gives the velocity of the shape origin */
        double r[3], wxr[3];
        v3_scale(r, rc, 1.0);
        v3_cross(wxr, b->w, r);
        v3_add(b->v, d->vel, wxr);
        b->state = SC_FREE;
    } else {
        b->state = SC_STATIC;
    }
    b->restitution = d->restitution;
    b->friction = d->friction;
    w->contacts_valid = 0;
    return w->nbodies++;
}

SC_API int sc_world_body_count(const sc_world *w)
{
    return w ? w->nbodies : 0;
}

void sc_body_pose(const sc_body *b, sc_pose *p)
{
    double rc[3];
    q_rotate(rc, b->q, b->com);
    v3_sub(p->pos, b->x, rc);
    memcpy(p->quat, b->q, sizeof p->quat);
}

double sc_cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double sc_wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void sc_stage_add(sc_world *w, int stage, double t0)
{
    double dt = sc_cpu_now() - t0;
    w->stats.stage_s[stage] += dt;
    w->stats.stage_total_s[stage] += dt;
}

static const sc_body *body_get(const sc_world *w, int id)
{
    return (w && id >= 0 && id < w->nbodies) ? &w->bodies[id] : NULL;
}

SC_API void sc_body_get_pose(const sc_world *w, int id, double pos[3], double quat[4])
{
    const sc_body *b = body_get(w, id);
    sc_pose p = { { 0, 0, 0 }, { 0, 0, 0, 0 } };
    if (b)
        sc_body_pose(b, &p);
    if (pos) memcpy(pos, p.pos, sizeof p.pos);
    if (quat) memcpy(quat, p.quat, sizeof p.quat);
}

SC_API void sc_body_get_velocity(const sc_world *w, int id, double v[3], double omega[3])
{
    const sc_body *b = body_get(w, id);
    double lin[3] = { 0, 0, 0 }, ang[3] = { 0, 0, 0 };
    if (b) {
        double rc[3], wxr[3];
        q_rotate(rc, b->q, b->com);
        v3_cross(wxr, b->w, rc);
        v3_sub(lin, b->v, wxr);        /* origin = com - R com_local */
        v3_copy(ang, b->w);
    }
    if (v) memcpy(v, lin, sizeof lin);
    if (omega) memcpy(omega, ang, sizeof ang);
}

SC_API const sc_shape *sc_body_shape(const sc_world *w, int id)
{
    const sc_body *b = body_get(w, id);
    return b ? b->shape : NULL;
}

SC_API int sc_body_state(const sc_world *w, int id)
{
    const sc_body *b = body_get(w, id);
    return b ? b->state : SC_ERANGE;
}

SC_API int sc_body_apply_force(sc_world *w, int id, const double f[3], const double at[3])
{
    if (!w || !f || !sc_finite3(f) || (at && !sc_finite3(at)))
        return SC_EINVAL;
    if (id < 0 || id >= w->nbodies)
        return SC_ERANGE;
    sc_body *b = &w->bodies[id];
    if (b->inv_mass == 0)
        return SC_ENOTSUP;
    if (b->state == SC_ASLEEP) {       /* a push wakes it */
        b->state = SC_FREE;
        b->rest_s = 0;
    }
    v3_add(b->force, b->force, f);
    if (at) {
        double r[3], t[3];
        v3_sub(r, at, b->x);
        v3_cross(t, r, f);
        v3_add(b->torque, b->torque, t);
    }
    return SC_OK;
}

SC_API int sc_world_at_rest(const sc_world *w)
{
    if (!w)
        return 0;
    for (int i = 0; i < w->nbodies; i++) {
        const sc_body *b = &w->bodies[i];
        if (b->inv_mass > 0 && b->state != SC_ASLEEP)
            return 0;
    }
    return 1;
}

SC_API double sc_world_energy(const sc_world *w)
{
    if (!w)
        return NAN;
    double e = 0;
    for (int i = 0; i < w->nbodies; i++) {
        const sc_body *b = &w->bodies[i];
        if (b->inv_mass == 0)
            continue;
        /* rotational: 0.5 w^T (R I R^T) w = 0.5 wb^T I wb, wb in body frame */
        double R[9], wb[3], Iw[3];
        q_to_m3(R, b->q);
        m3_tmulv(wb, R, b->w);
        m3_mulv(Iw, b->inertia, wb);
        e += 0.5 * b->mass * v3_dot(b->v, b->v) + 0.5 * v3_dot(wb, Iw) -
             b->mass * v3_dot(w->cfg.gravity, b->x);
    }
    return e;
}

SC_API uint64_t sc_world_hash(const sc_world *w)
{
    uint64_t h = 0xcbf29ce484222325ULL;
    if (!w)
        return h;
    for (int i = 0; i < w->nbodies; i++) {
        const sc_body *b = &w->bodies[i];
        const double *parts[4] = { b->x, b->q, b->v, b->w };
        const int len[4] = { 3, 4, 3, 3 };
        for (int p = 0; p < 4; p++)
            for (int k = 0; k < len[p]; k++) {
                double d = parts[p][k] + 0.0;   /* -0 and 0 hash alike */
                unsigned char bytes[sizeof d];
                memcpy(bytes, &d, sizeof d);
                for (size_t j = 0; j < sizeof d; j++) {
                    h ^= bytes[j];
                    h *= 0x100000001b3ULL;
                }
            }
    }
    return h;
}

SC_API void sc_world_stats(const sc_world *w, sc_stats *s)
{
    if (!s)
        return;
    if (!w) {
        memset(s, 0, sizeof *s);
        return;
    }
    *s = w->stats;
    s->bodies = w->nbodies;
}

SC_API int sc_world_contacts(const sc_world *w, sc_contact *out, int max)
{
    if (!w)
        return SC_EINVAL;
    int n = w->ncontacts < max ? w->ncontacts : max;
    if (out && n > 0)
        memcpy(out, w->contacts, (size_t)n * sizeof *out);
    return w->ncontacts;
}
