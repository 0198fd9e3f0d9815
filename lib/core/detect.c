/* detect.c - contact detection for the frame (the paper's step 4): bounding
 * spheres or sweep and prune, planes by signed distance, then the exact
 * narrow phase pair by pair in canonical order. Wakes sleepers that are
 * touched by awake bodies. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "sc_internal.h"
#include "vecmath.h"

static int cmp_pair(const void *x, const void *y)
{
    const sc_pair *a = x, *b = y;
    if (a->a != b->a)
        return (a->a > b->a) - (a->a < b->a);
    return (a->b > b->b) - (a->b < b->b);
}

int sc_body_scratch(sc_world *w)
{
    if (w->nbodies <= w->scratch_cap)
        return SC_OK;
    /* grows with the body count only, not every frame */
    free(w->centre);
    free(w->radius);
    free(w->active);
    free(w->poses);
    w->centre = sc_alloc_array((size_t)w->cap * 3, sizeof *w->centre);
    w->radius = sc_alloc_array((size_t)w->cap, sizeof *w->radius);
    w->active = sc_alloc_array((size_t)w->cap, sizeof *w->active);
    w->poses = sc_alloc_array((size_t)w->cap, sizeof *w->poses);
    w->scratch_cap = w->centre && w->radius && w->active && w->poses ? w->cap : 0;
    return w->scratch_cap ? SC_OK : SC_ENOMEM;
}

/* Step 4, coarse: bounding spheres (or sweep and prune), plus every active
 * body against every static plane (planes have no bounding sphere). */
static int broadphase(sc_world *w, int *npairs)
{
    int n = w->nbodies, np = 0;
    if (sc_body_scratch(w) != SC_OK)
        return SC_ENOMEM;
    int nplanes = 0;
    double margin = w->cfg.contact_tol_m;
    for (int i = 0; i < n; i++) {
        const sc_body *b = &w->bodies[i];
        sc_pose *p = &w->poses[i];    /* kept for the narrow phase */
        sc_body_pose(b, p);
        v3_copy(&w->centre[3 * i], p->pos);
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
        sc_body_pose(pb, &pp);
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

int sc_contacts_have_pair(const sc_contact *c, int n, int a, int b)
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

/* Step 4, exact: every pair through the narrow phase as work units on the
 * world's nodes, merged in pair order, so the contact list is canonical. */
static int narrowphase(sc_world *w, int npairs)
{
    if (sc_grow((void **)&w->upairs, &w->upair_cap, npairs, sizeof *w->upairs, INT_MAX) ||
        sc_grow((void **)&w->uncontact, &w->uncontact_cap, npairs, sizeof *w->uncontact,
                INT_MAX) ||
        sc_grow((void **)&w->ucontacts, &w->ucontact_cap, npairs * SC_MAX_PAIR_CONTACTS,
                sizeof *w->ucontacts, INT_MAX / SC_MAX_PAIR_CONTACTS))
        return SC_ENOMEM;
    for (int i = 0; i < npairs; i++) {
        sc_unit_pair *p = &w->upairs[i];
        const sc_body *a = &w->bodies[w->pairs[i].a], *b = &w->bodies[w->pairs[i].b];
        p->sa = a->shape;    /* a1, b1 are the TOI's only */
        p->deepen = 0;
        p->sb = b->shape;
        p->body_a = w->pairs[i].a;
        p->body_b = w->pairs[i].b;
        p->a0 = w->poses[w->pairs[i].a];
        p->b0 = w->poses[w->pairs[i].b];
        /* the contacts still held are those of the last detection */
        p->touching = sc_contacts_have_pair(w->contacts, w->ncontacts, p->body_a, p->body_b);
        w->uncontact[i] = 0;
    }
    sc_job job = {
        .kind = SC_UNIT_COLLIDE,
        .pairs = w->upairs,
        .npairs = npairs,
        .contacts = w->ucontacts,
        .ncontact = w->uncontact,
    };
    w->ncontacts = 0;
    int rc = sc_job_run(w, &job, SC_STAGE_NARROWPHASE);
    if (rc != SC_OK)
        return rc;
    int total = 0;
    for (int i = 0; i < npairs; i++)
        total += w->uncontact[i];
    if (sc_grow((void **)&w->contacts, &w->contact_cap, total, sizeof *w->contacts, INT_MAX))
        return SC_ENOMEM;
    double maxpen = 0;
    for (int i = 0; i < npairs; i++) {
        const sc_contact *c = &w->ucontacts[(size_t)i * SC_MAX_PAIR_CONTACTS];
        for (int k = 0; k < w->uncontact[i]; k++) {
            w->contacts[w->ncontacts++] = c[k];
            maxpen = fmax(maxpen, c[k].depth);
        }
    }
    w->stats.contacts = w->ncontacts;
    w->stats.max_penetration = maxpen;
    return SC_OK;
}

int sc_detect(sc_world *w)
{
    double t0 = sc_cpu_now();
    int npairs = 0;
    int rc = broadphase(w, &npairs);
    sc_stage_add(w, SC_STAGE_BROADPHASE, t0);
    if (rc != SC_OK)
        return rc;
    w->stats.pairs = npairs;
    t0 = sc_cpu_now();
    rc = narrowphase(w, npairs);
    sc_stage_add(w, SC_STAGE_NARROWPHASE, t0);
    /* a sleeping body touched by an awake one wakes up */
    for (int k = 0; rc == SC_OK && k < w->ncontacts; k++) {
        sc_body *a = &w->bodies[w->contacts[k].body_a], *b = &w->bodies[w->contacts[k].body_b];
        if (a->state == SC_ASLEEP && sc_body_movable(b)) { a->state = SC_CONTACT; a->rest_s = 0; }
        if (b->state == SC_ASLEEP && sc_body_movable(a)) { b->state = SC_CONTACT; b->rest_s = 0; }
    }
    return rc;
}

