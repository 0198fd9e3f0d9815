/* step.c - one frame (the paper's steps 3-7): substeps of force, contact
 * impulses and integration, each checked for contacts that got deeper than
 * the tolerance and backed up to their time of impact (steps 5-6). */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "cluster.h"
#include "sc_internal.h"
#include "vecmath.h"

/* ---- the frame: the paper's steps (3)-(7) ---------------------------- */

#define MAX_SUBSTEPS 16       /* time-of-impact back-ups per frame */
#define TOI_AIM 0.9           /* back up to this share of the tolerance */

static const sc_contact_params contact_params = {
    .bounce_speed = 0.1,      /* the paper's threshold speed */
    .slop = 0.5e-3,
    .baumgarte = 0.2,
};

/* Steps (4)-(7) once over h: islands, contact impulses, positions. */
static int substep(sc_world *w, double h, sc_islands *is, unsigned char *touched)

{
    int n = w->nbodies;
    sc_apply_forces(w, h);
    double t0 = sc_cpu_now();
    for (int i = 0; i < n; i++)
        w->active[i] = sc_body_movable(&w->bodies[i]);
    int rc = sc_islands_build(n, w->active, w->contacts, w->ncontacts, is);
    sc_stage_add(w, SC_STAGE_ISLANDS, t0);
    if (rc != SC_OK)
        return rc;
    memset(touched, 0, (size_t)n);
    for (int k = 0; k < w->ncontacts; k++) {
        touched[w->contacts[k].body_a] = 1;
        touched[w->contacts[k].body_b] = 1;
    }
    /* step 7: one work unit per island (islands share no movable body) */
    t0 = sc_cpu_now();
    sc_job job = {
        .kind = SC_UNIT_ISLAND,
        .bodies = w->bodies,
        .c = w->contacts,
        .islands = is,
        .h = h,
        .params = &contact_params,
    };
    rc = sc_job_run(w, &job, SC_STAGE_LCP);
    sc_stage_add(w, SC_STAGE_LCP, t0);
    for (int i = 0; i < job.nunits; i++) {
        w->stats.lcp_pivots += job.units[i].info.pivots;
        w->stats.lcp_fallbacks += job.units[i].info.failures;
    }
    w->stats.islands = is->count;
    if (rc != SC_OK)
        return rc;
    t0 = sc_cpu_now();
    sc_integrate_positions(w, h);
    sc_stage_add(w, SC_STAGE_INTEGRATE, t0);
    for (int i = 0; i < n; i++) {
        sc_body *b = &w->bodies[i];
        if (sc_body_movable(b) && (!sc_finite3(b->x) || !sc_finite3(b->v) || !sc_finite3(b->w)))
            return SC_ENUMERIC;
    }
    return SC_OK;
}

/* Step 5: the earliest time of impact (fraction of the substep) among new
 * contacts deeper than the tolerance; 1 when there is none. One query per
 * pair, as work units; the minimum does not depend on who ran what. */
static int earliest_impact(sc_world *w, const sc_body *saved, const sc_contact *c0, int n0,
                           double *frac)
{
    double t0 = sc_cpu_now();
    *frac = 1;
    int np = 0;
    for (int k = 0; k < w->ncontacts; k++) {
        const sc_contact *c = &w->contacts[k];
        if (c->depth <= w->cfg.contact_tol_m)
            continue;
        if (np > 0 && w->upairs[np - 1].body_a == c->body_a &&
            w->upairs[np - 1].body_b == c->body_b)
            continue;    /* one query per pair */
        if (sc_grow((void **)&w->upairs, &w->upair_cap, np + 1, sizeof *w->upairs, INT_MAX))
            return SC_ENOMEM;
        sc_unit_pair *p = &w->upairs[np++];
        p->sa = w->bodies[c->body_a].shape;
        p->sb = w->bodies[c->body_b].shape;
        p->body_a = c->body_a;
        p->body_b = c->body_b;
        /* a new pair backs up to first touch; a pair already touching that
         * digs in past the tolerance (a bolt rocking onto its other end)
         * backs up to where it reaches the tolerance */
        p->deepen = sc_contacts_have_pair(c0, n0, c->body_a, c->body_b);
        sc_body_pose(&saved[c->body_a], &p->a0);
        sc_body_pose(&saved[c->body_b], &p->b0);
        p->a1 = w->poses[c->body_a];    /* the detection just before */
        p->b1 = w->poses[c->body_b];
    }
    int rc = SC_OK;
    if (np > 0) {
        rc = sc_grow((void **)&w->utoi, &w->utoi_cap, np, sizeof *w->utoi, INT_MAX);
        if (rc != SC_OK)
            return rc;
        sc_job job = {
            .kind = SC_UNIT_TOI,
            .pairs = w->upairs,
            .npairs = np,
            /* aim below the tolerance: the backed-up substep's impulses
             * and push-out differ a little from the path the search
             * interpolated */
            .tol_m = TOI_AIM * w->cfg.contact_tol_m,
            .toi = w->utoi,
        };
        for (int i = 0; i < np; i++)
            w->utoi[i] = 1;
        rc = sc_job_run(w, &job, SC_STAGE_TOI);
        for (int i = 0; rc == SC_OK && i < np; i++)
            *frac = fmin(*frac, w->utoi[i]);
    }
    sc_stage_add(w, SC_STAGE_TOI, t0);
    return rc;
}

int sc_frame(sc_world *w, double dt)
{
    int n = w->nbodies;
    /* scratch owned by the world: grows with the body count, no malloc
     * per frame once it has */
    int rc = sc_grow((void **)&w->saved, &w->saved_cap, n, sizeof *w->saved, INT_MAX);
    if (rc == SC_OK)
        rc = sc_body_scratch(w);
    if (rc == SC_OK)
        rc = sc_grow((void **)&w->touched, &w->touched_cap, n, 1, INT_MAX);
    if (rc != SC_OK)
        return rc;
    sc_body *saved = w->saved;
    unsigned char *touched = w->touched;
    sc_islands *is = &w->islands;
    if (!w->contacts_valid)
        rc = sc_detect(w);
    double left = dt;
    for (int sub = 0; rc == SC_OK && left > 0; sub++) {
        /* keep the start of the substep: contacts and state */
        memcpy(saved, w->bodies, (size_t)n * sizeof *saved);
        int n0 = w->ncontacts;
        rc = sc_grow((void **)&w->c0, &w->c0_cap, n0, sizeof *w->c0, INT_MAX);
        if (rc != SC_OK)
            break;
        sc_contact *c0 = w->c0;
        if (n0 > 0)
            memcpy(c0, w->contacts, (size_t)n0 * sizeof *c0);
        double h = left;
        rc = substep(w, h, is, touched);
        if (rc == SC_OK)
            rc = sc_detect(w);
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
            rc = substep(w, h, is, touched);
            if (rc == SC_OK)
                rc = sc_detect(w);
        }
        left -= h;
        if (left < 1e-9 * dt)
            left = 0;
    }
    if (rc == SC_OK) {
        sc_update_states(w, is, touched, dt);
        for (int i = 0; i < n; i++) {
            v3_set(w->bodies[i].force, 0, 0, 0);
            v3_set(w->bodies[i].torque, 0, 0, 0);
        }
        w->contacts_valid = 1;
    }
    return rc;
}

SC_API int sc_world_step(sc_world *w, double dt)
{
    if (!w || !(dt > 0) || !isfinite(dt))
        return SC_EINVAL;
    memset(w->stats.stage_s, 0, sizeof w->stats.stage_s);
    w->stats.lcp_pivots = 0;
    w->stats.lcp_fallbacks = 0;
    w->stats.collider_warnings = 0;
    w->stats.units = 0;
    w->stats.sched_s = 0;
    w->stats.makespan_s = 0;
    w->stats.makespan_bound_s = 0;
    w->stats.groups = 0;
    w->stats.pairs = 0;
    w->stats.contacts = 0;
    w->stats.islands = 0;
    w->stats.max_penetration = 0;
    w->stats.remote_units = 0;
    w->stats.recomputed_units = 0;
    w->stats.late_results = 0;
    w->stats.comm_s = 0;
    w->stats.remote_wait_s = 0;
    if (w->cluster)
        sc_cluster_frame(w->cluster);
    if (w->nbodies == 0) {
        w->stats.frames++;      /* nothing to move */
        return SC_OK;
    }
    int rc = w->cfg.motion_groups ? sc_groups_step(w, dt) : sc_frame(w, dt);
    if (rc == SC_OK) {
        w->stats.frames++;
        w->stats.makespan_ratio = w->stats.makespan_bound_s > 0
                                      ? w->stats.makespan_s / w->stats.makespan_bound_s
                                      : 0;
    }
    return rc;
}
