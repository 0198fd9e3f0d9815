/* world.c - the world owns bodies, shape references, the frame's state and
 * scratch, its executor and cluster (docs/DESIGN.md section 4); this file
 * holds its public API (create, add, step, query, energy, hash, stats). The
 * frame itself is lib/core/frame.c's sc_frame_step(). */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cluster.h"
#include "world.h"
#include "vecmath.h"

SC_API sc_world *sc_world_create(const sc_world_config *cfg)
{
    sc_world_config c = cfg ? *cfg : sc_world_config_default();
    if (c.internal_cookie != SC_CONFIG_COOKIE) {
        sc_set_error(SC_ENOINIT);
        return NULL;
    }
    if (!sc_finite3(c.gravity) || c.workers < 0 || c.workers > SC_MAX_WORKERS || !(c.contact_tol_m > 0) ||
        !isfinite(c.contact_tol_m) || !(c.cluster_deadline_s >= 0) ||
        !isfinite(c.cluster_ship_share) || !isfinite(c.cluster_min_gain) ||
        !isfinite(c.cluster_deadline_s) || (c.key_file && !c.cluster) || c.broadphase < SC_BROADPHASE_AUTO ||
        c.broadphase > SC_BROADPHASE_SAP || (c.motion_groups != 0 && c.motion_groups != 1) ||
        c.island_split < 0 ||
        (c.island_method != SC_ISLAND_ACTIVE_SET && c.island_method != SC_ISLAND_BLOCK_GS &&
         c.island_method != SC_ISLAND_SUBDOMAINS) || (c.toi_mode != SC_TOI_LOCAL && c.toi_mode != SC_TOI_WORLD)) {
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
    memcpy(w->fcfg.gravity, c.gravity, sizeof w->fcfg.gravity);
    w->fcfg.contact_tol_m = c.contact_tol_m;
    w->fcfg.broadphase = c.broadphase;
    w->fcfg.island_split = c.island_split;
    w->fcfg.island_method = c.island_method;
    w->fcfg.toi_mode = c.toi_mode;
    /* nodes: this thread (node 0) and workers - 1 worker threads */
    int nodes = c.workers;
    double budget = sc_cpu_budget();
    if (nodes == 0) {
        double cpus = ceil(budget);
        nodes = !(cpus >= 1) ? 1 : cpus > SC_MAX_WORKERS ? SC_MAX_WORKERS : (int)cpus;
    }
    w->cfg.workers = nodes;
    int rc = sc_frame_scratch_init(&w->scr);
    if (rc == SC_OK)
        rc = sc_exec_nodes_init(&w->ex, nodes, c.cluster ? SC_MAX_DAEMONS : 0, budget);
    w->ex.sched.ship_share = c.cluster_ship_share == 0 ? SC_SHIP_SHARE_DEFAULT
                                                        : c.cluster_ship_share;
    w->ex.sched.min_gain = c.cluster_min_gain == 0 ? SC_MIN_GAIN_DEFAULT : c.cluster_min_gain;
    w->stats.now.private_ode = w->ex.private_ode;
    w->stats.now.cpu_budget = w->ex.cpu_budget;
    w->stats.now.spin = sc_local_pool_spins(w->ex.pool);
    if (rc == SC_OK && c.cluster)
        rc = sc_cluster_create(&w->ex, &w->stats, &w->st, c.cluster, c.key_file,
                               c.cluster_deadline_s, &w->cluster);
    if (rc != SC_OK) {
        sc_world_destroy(w);
        sc_set_error(rc);
        return NULL;
    }
    w->stats.now.nodes = w->ex.nlocal;
    return w;
}

SC_API void sc_world_destroy(sc_world *w)
{
    if (!w)
        return;
    for (int i = 0; i < w->st.nbodies; i++)
        sc_shape_release(w->st.bodies[i].shape);
    sc_exec_nodes_free(&w->ex);     /* the cluster's nodes too */
    sc_cluster_destroy(w->cluster);
    sc_frame_scratch_free(&w->scr);
    free(w->st.bodies);
    free(w->st.contacts);
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
    if (d->internal_cookie != SC_BODY_COOKIE)
        return SC_ENOINIT;
    if (!sc_finite3(d->pos) || !quat_ok(d->quat) || !sc_finite3(d->vel) ||
        !sc_finite3(d->omega) || !(d->restitution >= 0 && d->restitution <= 1) ||
        !(d->friction >= 0) || !isfinite(d->friction))
        return SC_EINVAL;
    /* finite, but beyond what a step can carry without overflow */
    if (v3_len(d->pos) > SC_MAX_COORD || v3_len(d->vel) > SC_MAX_SPEED ||
        v3_len(d->omega) > SC_MAX_SPIN)
        return SC_ELIMIT;
    if (d->shape->kind != SC_SHAPE_PLANE &&
        (d->shape->bound_r < SC_MIN_LENGTH || d->shape->bound_r > SC_MAX_LENGTH))
        return SC_ELIMIT;
    double mass = d->mass;
    if (mass == SC_MASS_FROM_DENSITY) {
        if (!(d->density > 0) || !isfinite(d->density))
            return SC_EINVAL;
        mass = d->density * d->shape->mp.volume;
    }
    if (!(mass >= 0) || !isfinite(mass))
        return SC_EINVAL;
    /* a mass that underflowed (a tiny shape or density) would make the body
     * static without a word; one whose inertia cannot be inverted is
     * caught below */
    if (mass != 0 && !isnormal(mass))
        return SC_ELIMIT;
    if (d->shape->kind == SC_SHAPE_PLANE && mass != 0)
        return SC_ENOTSUP;              /* an infinite half space cannot move */
    int err = sc_grow((void **)&w->st.bodies, &w->cap, w->st.nbodies + 1, sizeof *w->st.bodies,
                      INT_MAX);
    if (err != SC_OK)
        return err;
    sc_body *b = &w->st.bodies[w->st.nbodies];
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
        int inv_ok = m3_inverse(b->inv_inertia, b->inertia);
        for (int i = 0; i < 9; i++)
            inv_ok = inv_ok && isfinite(b->inv_inertia[i]);
        if (!inv_ok) {              /* finite mass, inertia under- or overflowed */
            sc_shape_release(b->shape);
            return SC_ELIMIT;
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
    w->st.contacts_valid = 0;
    return w->st.nbodies++;
}

SC_API int sc_world_body_count(const sc_world *w)
{
    return w ? w->st.nbodies : 0;
}

static const sc_body *body_get(const sc_world *w, int id)
{
    return (w && id >= 0 && id < w->st.nbodies) ? &w->st.bodies[id] : NULL;
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
    if (id < 0 || id >= w->st.nbodies)
        return SC_ERANGE;
    sc_body *b = &w->st.bodies[id];
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
    for (int i = 0; i < w->st.nbodies; i++) {
        const sc_body *b = &w->st.bodies[i];
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
    for (int i = 0; i < w->st.nbodies; i++) {
        const sc_body *b = &w->st.bodies[i];
        if (b->inv_mass == 0)
            continue;
        /* rotational: 0.5 w^T (R I R^T) w = 0.5 wb^T I wb, wb in body frame */
        double R[9], wb[3], Iw[3];
        q_to_m3(R, b->q);
        m3_tmulv(wb, R, b->w);
        m3_mulv(Iw, b->inertia, wb);
        e += 0.5 * b->mass * v3_dot(b->v, b->v) + 0.5 * v3_dot(wb, Iw) -
             b->mass * v3_dot(w->fcfg.gravity, b->x);
    }
    return e;
}

SC_API uint64_t sc_world_hash(const sc_world *w)
{
    uint64_t h = SC_FNV_OFFSET;
    if (!w)
        return h;
    for (int i = 0; i < w->st.nbodies; i++) {
        const sc_body *b = &w->st.bodies[i];
        const double *parts[4] = { b->x, b->q, b->v, b->w };
        const int len[4] = { 3, 4, 3, 3 };
        for (int p = 0; p < 4; p++)
            for (int k = 0; k < len[p]; k++) {
                double d = parts[p][k] + 0.0;   /* -0 and 0 hash alike */
                h = sc_fnv1a(h, &d, sizeof d);
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
    s->now.bodies = w->st.nbodies;
}

SC_API int sc_world_contacts(const sc_world *w, sc_contact *out, int max)
{
    if (!w)
        return SC_EINVAL;
    int n = w->st.ncontacts < max ? w->st.ncontacts : max;
    if (out && n > 0)
        memcpy(out, w->st.contacts, (size_t)n * sizeof *out);
    return w->st.ncontacts;
}

SC_API int sc_world_step(sc_world *w, double dt)
{
    if (!w || !(dt > 0) || !isfinite(dt))
        return SC_EINVAL;
    if (dt > SC_MAX_DT)
        return SC_ELIMIT;
    /* the last frame's figures start again; totals and the state now stay */
    sc_stats *st = &w->stats;
    memset(&st->frame, 0, sizeof st->frame);
    double t0 = sc_wall_now(), span0 = w->ex.span_s;
    if (w->cluster)
        sc_cluster_frame(w->cluster);
    int rc = sc_arena_reset(&w->scr.arena);
    if (rc != SC_OK)
        return rc;
    rc = w->cfg.motion_groups || w->cfg.toi_mode == SC_TOI_LOCAL
             ? sc_groups_step(&w->fcfg, &w->st, dt, &w->scr, &w->ex.base, st)
             : sc_frame_step(&w->fcfg, &w->st, dt, &w->scr, &w->ex.base, st);
    if (rc == SC_OK) {
        st->total.frames++;
        st->total.backups += st->frame.toi.backups;
        st->total.group_retries += st->frame.sched.group_retries;
        st->total.retry_s += st->frame.sched.retry_s;
        if (st->frame.toi.backups > st->total.backups_max)
            st->total.backups_max = st->frame.toi.backups;
        sc_stats_sched *sd = &st->frame.sched;
        sd->makespan_ratio = sd->makespan_bound_s > 0 ? sd->makespan_s / sd->makespan_bound_s : 0;
        sd->frame_s = sc_wall_now() - t0;
        sd->serial_s = fmax(sd->frame_s - (w->ex.span_s - span0), 0);
        st->total.frame_s += sd->frame_s;
        st->total.serial_s += sd->serial_s;
    }
    return rc;
}
