/* world.c - the world owns bodies, shape references and per-frame state,
 * and runs the frame pipeline: integrate -> broad phase -> narrow phase.
 *
 * Dynamics (contact LCP, time-of-impact back-up, the state machine) arrive
 * with the dynamics stage; until then a frame integrates free motion and
 * reports the contacts it finds (the paper's steps 3 and 4).
 */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sc_internal.h"
#include "vecmath.h"

#define CONFIG_COOKIE 0x5c0f1a
#define BODY_COOKIE 0x5cb0d1


struct sc_world {
    sc_world_config cfg;
    sc_body *bodies;
    int nbodies, cap;
    sc_broadphase *bp;
    sc_np_ctx *np;
    /* per-frame scratch, grown as needed and kept */
    double *centre, *radius;
    unsigned char *active;
    int scratch_cap;
    sc_pair *pairs;
    int pair_cap;
    sc_contact *contacts;
    int ncontacts, contact_cap;
    int contacts_valid;       /* contacts match the current state */
    sc_stats stats;
};

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
    if (!sc_finite3(c.gravity) || c.workers < 0 || !(c.contact_tol_m > 0) ||
        !isfinite(c.contact_tol_m) || c.broadphase < SC_BROADPHASE_AUTO ||
        c.broadphase > SC_BROADPHASE_SAP) {
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
    w->np = sc_np_create();
    if (!w->bp || !w->np) {
        sc_world_destroy(w);
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    return w;
}

SC_API void sc_world_destroy(sc_world *w)
{
    if (!w)
        return;
    for (int i = 0; i < w->nbodies; i++)
        sc_shape_release(w->bodies[i].shape);
    free(w->bodies);
    sc_bp_destroy(w->bp);
    sc_np_destroy(w->np);
    free(w->centre);
    free(w->radius);
    free(w->active);
    free(w->pairs);
    free(w->contacts);
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

static const sc_body *body_get(const sc_world *w, int id)
{
    return (w && id >= 0 && id < w->nbodies) ? &w->bodies[id] : NULL;
}

/* Pose of the shape frame (the centre of mass is stored). */
static void body_pose(const sc_body *b, sc_pose *p)
{
    double rc[3];
    q_rotate(rc, b->q, b->com);
    v3_sub(p->pos, b->x, rc);
    memcpy(p->quat, b->q, sizeof p->quat);
}

SC_API void sc_body_get_pose(const sc_world *w, int id, double pos[3], double quat[4])
{
    const sc_body *b = body_get(w, id);
    sc_pose p = { { 0, 0, 0 }, { 0, 0, 0, 0 } };
    if (b)
        body_pose(b, &p);
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

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void stage_add(sc_world *w, int stage, double t0)
{
    double dt = cpu_now() - t0;
    w->stats.stage_s[stage] += dt;
    w->stats.stage_total_s[stage] += dt;
}

static int cmp_pair(const void *x, const void *y)
{
    const sc_pair *a = x, *b = y;
    if (a->a != b->a)
        return (a->a > b->a) - (a->a < b->a);
    return (a->b > b->b) - (a->b < b->b);
}

/* Step 4, coarse: bounding spheres (or sweep and prune), plus every active
 * body against every static plane (planes have no bounding sphere). */
static int broadphase(sc_world *w, int *npairs)
{
    int n = w->nbodies, np = 0;
    if (n > w->scratch_cap) {
        /* grows with the body count only, not every frame */
        free(w->centre);
        free(w->radius);
        free(w->active);
        w->centre = sc_alloc_array((size_t)w->cap * 3, sizeof *w->centre);
        w->radius = sc_alloc_array((size_t)w->cap, sizeof *w->radius);
        w->active = sc_alloc_array((size_t)w->cap, sizeof *w->active);
        w->scratch_cap = w->centre && w->radius && w->active ? w->cap : 0;
        if (!w->scratch_cap)
            return SC_ENOMEM;
    }
    int nplanes = 0;
    double margin = w->cfg.contact_tol_m;
    for (int i = 0; i < n; i++) {
        const sc_body *b = &w->bodies[i];
        sc_pose p;
        body_pose(b, &p);
        v3_copy(&w->centre[3 * i], p.pos);
        int plane = b->shape->kind == SC_SHAPE_PLANE;
        nplanes += plane;
        /* planes join the sweep as far-away points and pair below */
        w->radius[i] = plane ? 0 : b->shape->bound_r + margin;
        if (plane)
            v3_set(&w->centre[3 * i], 0, 0, 0);
        w->active[i] = b->inv_mass > 0 && b->state != SC_ASLEEP;
    }
    int method = w->cfg.broadphase;
    if (nplanes == 0) {
        np = sc_bp_find_pairs(w->bp, method, w->centre, w->radius, w->active, n, &w->pairs,
                              &w->pair_cap);
        if (np < 0)
            return np;
        *npairs = np;
        return SC_OK;
    }
    /* Bodies other than planes go through the broad phase with planes
     * parked (inactive, zero radius, at the origin) and their pairs dropped;
     * then plane pairs are added by signed distance and all re-sorted. */
    for (int i = 0; i < n; i++)
        if (w->bodies[i].shape->kind == SC_SHAPE_PLANE)
            w->active[i] = 0;
    np = sc_bp_find_pairs(w->bp, method, w->centre, w->radius, w->active, n, &w->pairs,
                          &w->pair_cap);
    if (np < 0)
        return np;
    int k = 0;
    for (int i = 0; i < np; i++) {
        const sc_pair *pr = &w->pairs[i];
        if (w->bodies[pr->a].shape->kind != SC_SHAPE_PLANE &&
            w->bodies[pr->b].shape->kind != SC_SHAPE_PLANE)
            w->pairs[k++] = *pr;
    }
    np = k;
    for (int pi = 0; pi < n; pi++) {
        const sc_body *pb = &w->bodies[pi];
        if (pb->shape->kind != SC_SHAPE_PLANE)
            continue;
        sc_pose pp;
        body_pose(pb, &pp);
        double nrm[3];
        q_rotate(nrm, pp.quat, pb->shape->plane);
        double d = pb->shape->plane[3] + v3_dot(nrm, pp.pos);
        for (int i = 0; i < n; i++) {
            const sc_body *b = &w->bodies[i];
            if (i == pi || !w->active[i] || b->shape->kind == SC_SHAPE_PLANE)
                continue;
            if (v3_dot(nrm, &w->centre[3 * i]) - d > w->radius[i])
                continue;
            if (sc_grow((void **)&w->pairs, &w->pair_cap, np + 1, sizeof *w->pairs, INT_MAX) != SC_OK)
                return SC_ENOMEM;
            w->pairs[np].a = i < pi ? i : pi;
            w->pairs[np].b = i < pi ? pi : i;
            np++;
        }
    }
    if (np > 1)
        qsort(w->pairs, (size_t)np, sizeof *w->pairs, cmp_pair);
    *npairs = np;
    return SC_OK;
}

/* Step 4, exact: every pair through the narrow phase, in pair order, so the
 * contact list is canonical. */
static int narrowphase(sc_world *w, int npairs)
{
    w->ncontacts = 0;
    double maxpen = 0;
    for (int i = 0; i < npairs; i++) {
        const sc_body *a = &w->bodies[w->pairs[i].a], *b = &w->bodies[w->pairs[i].b];
        sc_pose pa, pb;
        body_pose(a, &pa);
        body_pose(b, &pb);
        if (sc_grow((void **)&w->contacts, &w->contact_cap,
                    w->ncontacts + SC_MAX_PAIR_CONTACTS, sizeof *w->contacts, INT_MAX) != SC_OK)
            return SC_ENOMEM;
        sc_contact *c = &w->contacts[w->ncontacts];
        int n = sc_np_collide(w->np, a->shape, &pa, b->shape, &pb, c, SC_MAX_PAIR_CONTACTS);
        if (n < 0)
            return n;
        for (int k = 0; k < n; k++) {
            c[k].body_a = w->pairs[i].a;
            c[k].body_b = w->pairs[i].b;
            maxpen = fmax(maxpen, c[k].depth);
        }
        w->ncontacts += n;
    }
    w->stats.contacts = w->ncontacts;
    w->stats.max_penetration = maxpen;
    return SC_OK;
}

/* ---- the frame: the paper's steps (3)-(7) ---------------------------- */

#define MAX_SUBSTEPS 16       /* time-of-impact back-ups per frame */
#define SLEEP_SPEED 0.02      /* m/s and rad/s below which a body is slow */
#define SLEEP_TIME 0.5        /* s an island stays slow before it sleeps */

static const sc_contact_params contact_params = {
    .bounce_speed = 0.1,      /* the paper's threshold speed */
    .slop = 0.5e-3,
    .baumgarte = 0.2,
};

static int movable(const sc_body *b)
{
    return b->inv_mass > 0 && b->state != SC_ASLEEP;
}

/* Rotate q by angle |w| h about w (exact for constant w). */
static void rotate_by(double q[4], const double w[3], double h)
{
    double ang = v3_len(w) * h;
    if (ang == 0)
        return;
    double axis[3], dq[4];
    v3_scale(axis, w, h / ang);
    q_from_axis_angle(dq, axis, ang);
    q_mul(q, dq, q);
    q_normalize(q);
}

/* Step 3, first half: u* = u + h (g + F/m), gyroscopic term, and the world
 * inverse inertia the contact solve needs. v0/w0 keep u for restitution. */
static void apply_forces(sc_world *w, double h)
{
    for (int i = 0; i < w->nbodies; i++) {
        sc_body *b = &w->bodies[i];
        if (!movable(b))
            continue;
        v3_copy(b->v0, b->v);
        v3_copy(b->w0, b->w);
        double a[3], R[9], Rt[9], t[9];
        v3_madd(a, w->cfg.gravity, b->force, b->inv_mass);
        v3_madd(b->v, b->v, a, h);
        q_to_m3(R, b->q);
        m3_transpose(Rt, R);
        m3_mul(t, R, b->inv_inertia);
        m3_mul(b->iw, t, Rt);
        double wb[3], Iw[3], gyro[3], tb[3], dw[3];
        m3_tmulv(wb, R, b->w);
        m3_mulv(Iw, b->inertia, wb);
        v3_cross(gyro, wb, Iw);
        m3_tmulv(tb, R, b->torque);
        v3_sub(tb, tb, gyro);
        m3_mulv(dw, b->inv_inertia, tb);
        v3_madd(wb, wb, dw, h);
        m3_mulv(b->w, R, wb);
    }
}

/* Step 3, second half: positions. The trapezoid rule x += h (u0 + u') / 2
 * is exact for free fall and for a constant friction deceleration; a body
 * that collided this substep took its impulse at the start and then flew
 * under the external forces: x += h (u' - a h / 2). */
static void integrate_positions(sc_world *w, double h)
{
    for (int i = 0; i < w->nbodies; i++) {
        sc_body *b = &w->bodies[i];
        if (!movable(b))
            continue;
        double step[3], avg_w[3];
        if (b->collided == 2) {
            double a[3];
            v3_madd(a, w->cfg.gravity, b->force, b->inv_mass);
            v3_madd(step, b->v, a, -0.5 * h);
            v3_copy(avg_w, b->w);
            b->collided = 1;
        } else {
            v3_add(step, b->v0, b->v);
            v3_scale(step, step, 0.5);
            v3_add(avg_w, b->w0, b->w);
            v3_scale(avg_w, avg_w, 0.5);
        }
        v3_madd(b->x, b->x, step, h);
        rotate_by(b->q, avg_w, h);
    }
}

static int detect(sc_world *w)
{
    double t0 = cpu_now();
    int npairs = 0;
    int rc = broadphase(w, &npairs);
    stage_add(w, SC_STAGE_BROADPHASE, t0);
    if (rc != SC_OK)
        return rc;
    w->stats.pairs = npairs;
    t0 = cpu_now();
    long msgs = sc_ode_message_count();
    rc = narrowphase(w, npairs);
    w->stats.collider_warnings += sc_ode_message_count() - msgs;
    stage_add(w, SC_STAGE_NARROWPHASE, t0);
    /* a sleeping body touched by an awake one wakes up */
    for (int k = 0; rc == SC_OK && k < w->ncontacts; k++) {
        sc_body *a = &w->bodies[w->contacts[k].body_a], *b = &w->bodies[w->contacts[k].body_b];
        if (a->state == SC_ASLEEP && movable(b)) { a->state = SC_CONTACT; a->rest_s = 0; }
        if (b->state == SC_ASLEEP && movable(a)) { b->state = SC_CONTACT; b->rest_s = 0; }
    }
    return rc;
}

/* Steps (4)-(7) once over h: islands, contact impulses, positions. */
static int substep(sc_world *w, double h, sc_islands *is, unsigned char *touched)

{
    int n = w->nbodies;
    apply_forces(w, h);
    double t0 = cpu_now();
    for (int i = 0; i < n; i++)
        w->active[i] = movable(&w->bodies[i]);
    int rc = sc_islands_build(n, w->active, w->contacts, w->ncontacts, is);
    stage_add(w, SC_STAGE_ISLANDS, t0);
    if (rc != SC_OK)
        return rc;
    memset(touched, 0, (size_t)n);
    for (int k = 0; k < w->ncontacts; k++) {
        touched[w->contacts[k].body_a] = 1;
        touched[w->contacts[k].body_b] = 1;
    }
    t0 = cpu_now();
    sc_solve_info info = { 0 };
    for (int i = 0; i < is->count && rc == SC_OK; i++)
        rc = sc_island_solve(w->bodies, w->contacts, &is->contacts[is->contact_start[i]],
                             is->contact_start[i + 1] - is->contact_start[i], h,
                             &contact_params, &info);
    stage_add(w, SC_STAGE_LCP, t0);
    w->stats.lcp_pivots += info.pivots;
    w->stats.lcp_fallbacks += info.failures;
    w->stats.islands = is->count;
    if (rc != SC_OK)
        return rc;
    t0 = cpu_now();
    integrate_positions(w, h);
    stage_add(w, SC_STAGE_INTEGRATE, t0);
    for (int i = 0; i < n; i++) {
        sc_body *b = &w->bodies[i];
        if (movable(b) && (!sc_finite3(b->x) || !sc_finite3(b->v) || !sc_finite3(b->w)))
            return SC_ENUMERIC;
    }
    return SC_OK;
}

static int has_pair(const sc_contact *c, int n, int a, int b)
{
    int lo = 0, hi = n - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        int d = c[mid].body_a != a ? (c[mid].body_a < a ? -1 : 1)
                                   : (c[mid].body_b != b ? (c[mid].body_b < b ? -1 : 1) : 0);
        if (d == 0)
            return 1;
        if (d < 0)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return 0;
}

/* Step 5: the earliest time of impact (fraction of the substep) among new
 * contacts deeper than the tolerance; 1 when there is none. */
static int earliest_impact(sc_world *w, const sc_body *saved, const sc_contact *c0, int n0,
                           double *frac)
{
    double t0 = cpu_now();
    *frac = 1;
    int rc = SC_OK;
    for (int k = 0; k < w->ncontacts && rc == SC_OK; k++) {
        const sc_contact *c = &w->contacts[k];
        if (c->depth <= w->cfg.contact_tol_m)
            continue;
        if (k > 0 && c[-1].body_a == c->body_a && c[-1].body_b == c->body_b)
            continue;    /* one query per pair */
        sc_pose a0, a1, b0, b1;
        body_pose(&saved[c->body_a], &a0);
        body_pose(&w->bodies[c->body_a], &a1);
        body_pose(&saved[c->body_b], &b0);
        body_pose(&w->bodies[c->body_b], &b1);
        const sc_shape *sa = w->bodies[c->body_a].shape, *sb = w->bodies[c->body_b].shape;
        double t;
        /* a new pair: back up to first touch; a pair already touching that
         * digs in past the tolerance (a bolt rocking onto its other end):
         * back up to where it reaches the tolerance */
        int hit = has_pair(c0, n0, c->body_a, c->body_b)
                      ? sc_toi_deepen_ctx(w->np, sa, &a0, &a1, sb, &b0, &b1,
                                          w->cfg.contact_tol_m, &t)
                      : sc_toi_ctx(w->np, sa, &a0, &a1, sb, &b0, &b1, w->cfg.contact_tol_m, &t);
        if (hit < 0)
            rc = hit;
        else if (hit == 1 && t < *frac)
            *frac = t;
    }
    stage_add(w, SC_STAGE_TOI, t0);
    return rc;
}

/* The paper's states: free fall, collision, contact; islands that stay slow
 * go to sleep and cost nothing until touched. */
static void update_states(sc_world *w, const sc_islands *is, const unsigned char *touched,
                          double dt)
{
    for (int i = 0; i < w->nbodies; i++) {
        sc_body *b = &w->bodies[i];
        if (!movable(b))
            continue;
        int slow = v3_len(b->v) < SLEEP_SPEED && v3_len(b->w) < SLEEP_SPEED;
        b->rest_s = slow && touched[i] ? b->rest_s + dt : 0;
        b->state = b->collided ? SC_COLLIDING : (touched[i] ? SC_CONTACT : SC_FREE);
        b->collided = 0;
    }
    for (int k = 0; k < is->count; k++) {
        double rest = INFINITY;
        for (int j = is->body_start[k]; j < is->body_start[k + 1]; j++)
            rest = fmin(rest, w->bodies[is->bodies[j]].rest_s);
        if (rest < SLEEP_TIME)
            continue;
        for (int j = is->body_start[k]; j < is->body_start[k + 1]; j++) {
            sc_body *b = &w->bodies[is->bodies[j]];
            b->state = SC_ASLEEP;
            v3_set(b->v, 0, 0, 0);
            v3_set(b->w, 0, 0, 0);
        }
    }
}

SC_API int sc_world_step(sc_world *w, double dt)
{
    if (!w || !(dt > 0) || !isfinite(dt))
        return SC_EINVAL;
    int n = w->nbodies;
    memset(w->stats.stage_s, 0, sizeof w->stats.stage_s);
    w->stats.lcp_pivots = 0;
    w->stats.lcp_fallbacks = 0;
    w->stats.collider_warnings = 0;
    sc_islands is = { 0 };
    sc_body *saved = sc_alloc_array((size_t)n, sizeof *saved);
    unsigned char *touched = sc_calloc_array((size_t)n, 1);
    sc_contact *c0 = NULL;
    int c0_cap = 0, rc = saved && touched ? SC_OK : SC_ENOMEM;
    if (rc == SC_OK && !w->contacts_valid)
        rc = detect(w);
    double left = dt;
    for (int sub = 0; rc == SC_OK && left > 0; sub++) {
        /* keep the start of the substep: contacts and state */
        memcpy(saved, w->bodies, (size_t)n * sizeof *saved);
        int n0 = w->ncontacts;
        rc = sc_grow((void **)&c0, &c0_cap, n0, sizeof *c0, INT_MAX);
        if (rc != SC_OK)
            break;
        if (n0 > 0)
            memcpy(c0, w->contacts, (size_t)n0 * sizeof *c0);
        double h = left;
        rc = substep(w, h, &is, touched);
        if (rc == SC_OK)
            rc = detect(w);
        double frac = 1;
        if (rc == SC_OK && sub + 1 < MAX_SUBSTEPS)
            rc = earliest_impact(w, saved, c0, n0, &frac);
        if (rc == SC_OK && frac < 1) {
            /* steps 5-6: back up and advance only until they touch */
            memcpy(w->bodies, saved, (size_t)n * sizeof *saved);
            if (n0 > 0)
                memcpy(w->contacts, c0, (size_t)n0 * sizeof *c0);
            w->ncontacts = n0;
            h = fmax(frac * h, 1e-6 * dt);
            rc = substep(w, h, &is, touched);
            if (rc == SC_OK)
                rc = detect(w);
        }
        left -= h;
        if (left < 1e-9 * dt)
            left = 0;
    }
    if (rc == SC_OK) {
        update_states(w, &is, touched, dt);
        for (int i = 0; i < n; i++) {
            v3_set(w->bodies[i].force, 0, 0, 0);
            v3_set(w->bodies[i].torque, 0, 0, 0);
        }
        w->contacts_valid = 1;
        w->stats.frames++;
    }
    sc_islands_free(&is);
    free(saved);
    free(touched);
    free(c0);
    return rc;
}
