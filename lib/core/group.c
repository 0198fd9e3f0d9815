/* group.c - motion groups: the frame stepped apart for bodies that cannot
 * meet within it.
 *
 * The paper backs the whole world up to the earliest time of impact; with
 * hundreds of bodies some pair almost always hits early, and every body
 * pays for it (200 bolts and nuts: about 10 back-ups per frame). Here each
 * dynamic body gets a sphere that holds everything it can reach in the
 * frame (its bound, the contact tolerance, twice its speed times dt, the
 * sweep of its shape origin about the centre of mass, half its
 * acceleration times dt^2, a margin); of the bodies whose spheres overlap,
 * those whose gap can close within the frame at twice their relative speed
 * (may_meet(): bodies falling side by side do not) are joined, and bodies
 * joined directly or through others form a group. Each group runs the whole
 * frame (sc_frame(): substeps, back-ups, islands, states) on a sub-world
 * holding its bodies and the static ones. Static bodies join no group:
 * they are only read. A group with no awake body is asleep and skipped.
 *
 * Groups are independent, so they are work units of their own: each runs
 * on one node from start to end of the frame, with no synchronisation per
 * substep, and the result does not depend on who ran what. A group holding
 * most of the awake bodies (a pile) instead runs on the calling thread
 * with its jobs spread over every node as before.
 *
 * A body set moving faster within the frame by a collision than its sphere
 * allowed for can reach a body of another group before the frame ends;
 * the contact is then found at the start of the next frame (the doubled
 * speed and the margin make that rare; the split impulse handles it).
 */
#include <limits.h>
#include <stdlib.h>

#include "sc_internal.h"
#include "vecmath.h"

#define REACH_MARGIN 2e-3     /* m added to every body's reach */
#define BIG_GROUP 0.5         /* share of the awake bodies that makes a pile */

/* Whether bodies a and b (spheres overlapping) can touch within dt: the
 * gap between their bounds closes at most at twice their relative speed,
 * plus the sweep of their shape origins, their relative acceleration and a
 * margin. Bodies falling side by side do not meet. */
static int may_meet(const sc_world *w, int a, int b, double dt)
{
    const sc_body *A = &w->bodies[a], *B = &w->bodies[b];
    double dv[3], acc[3], aa[3], ab[3];
    v3_sub(dv, A->v, B->v);
    v3_madd(aa, w->cfg.gravity, A->force, A->inv_mass);
    v3_madd(ab, w->cfg.gravity, B->force, B->inv_mass);
    v3_sub(acc, aa, ab);
    double gap = v3_dist(&w->gcentre[3 * a], &w->gcentre[3 * b]) - A->shape->bound_r -
                 B->shape->bound_r - 2 * w->cfg.contact_tol_m;
    double close = (2 * v3_len(dv) + v3_len(A->w) * v3_len(A->com) +
                    v3_len(B->w) * v3_len(B->com)) * dt +
                   0.5 * v3_len(acc) * dt * dt + 2 * REACH_MARGIN;
    return gap < close;
}

void sc_group_scratch_free(sc_world *w)
{
    free(w->gcentre);
    free(w->gradius);
    free(w->gactive);
    free(w->gparent);
    free(w->gstart);
    free(w->gmembers);
    free(w->gid);
    free(w->statics);
    free(w->gcstart);
    w->gcap = 0;
}

static int grow_scratch(sc_world *w, int n)
{
    if (n <= w->gcap)
        return SC_OK;
    int cap = n > 2 * w->gcap ? n : 2 * w->gcap;
    sc_group_scratch_free(w);
    w->gcentre = sc_alloc_array((size_t)cap * 3, sizeof *w->gcentre);
    w->gradius = sc_alloc_array((size_t)cap, sizeof *w->gradius);
    w->gactive = sc_alloc_array((size_t)cap, sizeof *w->gactive);
    w->gparent = sc_alloc_array((size_t)cap, sizeof *w->gparent);
    w->gstart = sc_alloc_array((size_t)cap + 1, sizeof *w->gstart);
    w->gmembers = sc_alloc_array((size_t)cap, sizeof *w->gmembers);
    w->gid = sc_alloc_array((size_t)cap, sizeof *w->gid);
    w->statics = sc_alloc_array((size_t)cap, sizeof *w->statics);
    w->gcstart = sc_alloc_array((size_t)cap + 2, sizeof *w->gcstart);
    w->gcap = w->gcentre && w->gradius && w->gactive && w->gparent && w->gstart &&
                      w->gmembers && w->gid && w->statics && w->gcstart
                  ? cap
                  : 0;
    return w->gcap ? SC_OK : SC_ENOMEM;
}

/* The groups of w: w->ngroups, members of group g in
 * gmembers[gstart[g] .. gstart[g + 1]) (ascending), gid[i] (-1: none),
 * the static bodies, and the last frame's contacts of each group in
 * gcontacts[gcstart[g] .. gcstart[g + 1]). */
static int build_groups(sc_world *w, double dt)
{
    int n = w->nbodies, rc = grow_scratch(w, n);
    if (rc != SC_OK)
        return rc;
    if (!w->gbp && !(w->gbp = sc_bp_create()))
        return SC_ENOMEM;
    w->nstatics = 0;
    for (int i = 0; i < n; i++) {
        const sc_body *b = &w->bodies[i];
        w->gparent[i] = i;
        w->gid[i] = -1;
        if (b->inv_mass == 0) {
            /* static: parked out of the sweep, joins no group */
            v3_set(&w->gcentre[3 * i], 0, 0, 0);
            w->gradius[i] = 0;
            w->gactive[i] = 0;
            w->statics[w->nstatics++] = i;
            continue;
        }
        sc_pose p;
        sc_body_pose(b, &p);
        v3_copy(&w->gcentre[3 * i], p.pos);
        double a[3];
        v3_madd(a, w->cfg.gravity, b->force, b->inv_mass);
        double reach = (2 * v3_len(b->v) + v3_len(b->w) * v3_len(b->com)) * dt +
                       0.5 * v3_len(a) * dt * dt + REACH_MARGIN;
        w->gradius[i] = b->shape->bound_r + w->cfg.contact_tol_m + reach;
        w->gactive[i] = sc_body_movable(b);
    }
    int np = sc_bp_find_pairs(w->gbp, n < 256 ? SC_BROADPHASE_SPHERES : SC_BROADPHASE_SAP,
                              w->gcentre, w->gradius, w->gactive, n, &w->gpairs,
                              &w->gpair_cap);
    if (np < 0)
        return np;
    for (int k = 0; k < np; k++) {
        const sc_pair *pr = &w->gpairs[k];
        if (w->bodies[pr->a].inv_mass > 0 && w->bodies[pr->b].inv_mass > 0 &&
            may_meet(w, pr->a, pr->b, dt))
            sc_uf_unite(w->gparent, pr->a, pr->b);
    }
    /* bodies touching at the end of the last frame stay together, asleep
     * ones too (an awake neighbour may wake them) */
    for (int k = 0; w->contacts_valid && k < w->ncontacts; k++) {
        const sc_contact *c = &w->contacts[k];
        if (w->bodies[c->body_a].inv_mass > 0 && w->bodies[c->body_b].inv_mass > 0)
            sc_uf_unite(w->gparent, c->body_a, c->body_b);
    }
    /* a group needs an awake body; groups numbered by their first member */
    for (int i = 0; i < n; i++)
        if (w->gactive[i])
            w->gid[sc_uf_find(w->gparent, i)] = 0;
    int ng = 0;
    for (int i = 0; i < n; i++) {
        if (w->bodies[i].inv_mass == 0)
            continue;
        int r = sc_uf_find(w->gparent, i);
        if (r == i && w->gid[i] == 0)
            w->gid[i] = ++ng;    /* 1-based while numbering */
    }
    for (int i = 0; i < n; i++)
        if (w->bodies[i].inv_mass > 0 && sc_uf_find(w->gparent, i) != i)
            w->gid[i] = w->gid[sc_uf_find(w->gparent, i)];
    memset(w->gstart, 0, (size_t)(ng + 1) * sizeof *w->gstart);
    for (int i = 0; i < n; i++) {
        if (w->gid[i] > 0)
            w->gstart[w->gid[i]]++;
        w->gid[i] = w->gid[i] > 0 ? w->gid[i] - 1 : -1;
    }
    for (int g = 0; g < ng; g++)
        w->gstart[g + 1] += w->gstart[g];
    /* members, ascending within each group (counting sort) */
    for (int g = ng; g > 0; g--)
        w->gstart[g] = w->gstart[g - 1];
    w->gstart[0] = 0;
    for (int i = 0; i < n; i++)
        if (w->gid[i] >= 0)
            w->gmembers[w->gstart[w->gid[i] + 1]++] = i;
    w->ngroups = ng;
    /* the last frame's contacts, by group, in their canonical order */
    int nc = w->contacts_valid ? w->ncontacts : 0;
    if (sc_grow((void **)&w->gcontacts, &w->gcontact_cap, nc, sizeof *w->gcontacts, INT_MAX))
        return SC_ENOMEM;
    memset(w->gcstart, 0, (size_t)(ng + 2) * sizeof *w->gcstart);
    for (int k = 0; k < nc; k++) {
        int g = w->gid[w->contacts[k].body_a] >= 0 ? w->gid[w->contacts[k].body_a]
                                                   : w->gid[w->contacts[k].body_b];
        if (g >= 0)
            w->gcstart[g + 2]++;
    }
    for (int g = 0; g < ng; g++)
        w->gcstart[g + 2] += w->gcstart[g + 1];
    for (int k = 0; k < nc; k++) {
        int g = w->gid[w->contacts[k].body_a] >= 0 ? w->gid[w->contacts[k].body_a]
                                                   : w->gid[w->contacts[k].body_b];
        if (g >= 0)
            w->gcontacts[w->gcstart[g + 1]++] = k;
    }
    return SC_OK;
}

static int local_id(const int *ids, int m, int id)
{
    int lo = 0, hi = m - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        if (ids[mid] == id)
            return mid;
        if (ids[mid] < id)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

static sc_world *sub_create(const sc_world *w)
{
    sc_world *sub = calloc(1, sizeof *sub);
    if (!sub)
        return NULL;
    sub->cfg = w->cfg;    /* a sub-world runs sc_frame() only */
    sub->bp = sc_bp_create();
    if (!sub->bp) {
        free(sub);
        return NULL;
    }
    return sub;
}

/* Group g's frame on the scratch world sub: its members and the static
 * bodies, in world order (so contacts keep their canonical order), the
 * last frame's contacts, sc_frame(), and back. */
static void group_frame(sc_world *w, sc_world *sub, int g, double dt, sc_group_out *out)
{
    const int *mem = &w->gmembers[w->gstart[g]];
    int nm = w->gstart[g + 1] - w->gstart[g], ns = w->nstatics, m = nm + ns;
    memset(out, 0, sizeof *out);
    out->rc = SC_ENOMEM;
    if (sc_grow((void **)&sub->sub_ids, &sub->sub_ids_cap, m, sizeof *sub->sub_ids, INT_MAX) ||
        sc_grow((void **)&sub->bodies, &sub->cap, m, sizeof *sub->bodies, INT_MAX))
        return;
    int *ids = sub->sub_ids;
    for (int i = 0, j = 0, k = 0; k < m; k++)
        ids[k] = j >= ns || (i < nm && mem[i] < w->statics[j]) ? mem[i++] : w->statics[j++];
    for (int k = 0; k < m; k++)
        sub->bodies[k] = w->bodies[ids[k]];
    sub->nbodies = m;
    const int *ck = &w->gcontacts[w->gcstart[g]];
    int nc = w->gcstart[g + 1] - w->gcstart[g];
    if (sc_grow((void **)&sub->contacts, &sub->contact_cap, nc, sizeof *sub->contacts,
                INT_MAX))
        return;
    for (int k = 0; k < nc; k++) {
        sc_contact c = w->contacts[ck[k]];
        c.body_a = local_id(ids, m, c.body_a);
        c.body_b = local_id(ids, m, c.body_b);
        sub->contacts[k] = c;
    }
    sub->ncontacts = nc;
    sub->contacts_valid = w->contacts_valid;
    memset(&sub->stats, 0, sizeof sub->stats);
    out->rc = sc_frame(sub, dt);
    out->stats = sub->stats;
    for (int k = 0; k < m; k++)
        if (sub->bodies[k].inv_mass > 0)
            w->bodies[ids[k]] = sub->bodies[k];
    if (out->rc != SC_OK || sub->ncontacts == 0)
        return;
    out->contacts = sc_alloc_array((size_t)sub->ncontacts, sizeof *out->contacts);
    if (!out->contacts) {
        out->rc = SC_ENOMEM;
        return;
    }
    for (int k = 0; k < sub->ncontacts; k++) {
        sc_contact c = sub->contacts[k];
        c.body_a = ids[c.body_a];
        c.body_b = ids[c.body_b];
        out->contacts[k] = c;
    }
    out->ncontacts = sub->ncontacts;
}

int sc_group_unit_run(sc_np_ctx *np, const sc_job *job, const sc_unit *u)
{
    void (*fn)(void *) = sc_world_scratch_free;
    void **slot = sc_np_scratch(np, &fn);
    if (!*slot)
        *slot = sub_create(job->world);
    sc_world *sub = *slot;
    if (!sub)
        return SC_ENOMEM;
    sub->cfg = job->world->cfg;
    sub->inline_np = np;
    sub->parent = NULL;
    group_frame(job->world, sub, u->first, job->dt, &job->gout[u->first]);
    return job->gout[u->first].rc;
}

static void add_stats(sc_stats *s, const sc_stats *g)
{
    for (int k = 0; k < SC_STAGE_COUNT; k++) {
        s->stage_s[k] += g->stage_s[k];
        s->stage_total_s[k] += g->stage_s[k];
    }
    s->pairs += g->pairs;
    s->islands += g->islands;
    s->lcp_pivots += g->lcp_pivots;
    s->lcp_fallbacks += g->lcp_fallbacks;
    s->max_penetration = fmax(s->max_penetration, g->max_penetration);
    s->collider_warnings += g->collider_warnings;
    s->units += g->units;
    s->sched_s += g->sched_s;
    s->makespan_s += g->makespan_s;
    s->makespan_bound_s += g->makespan_bound_s;
}

typedef struct pair_run {
    int a, b;                 /* the pair */
    int start, len;           /* its contacts in the concatenation */
} pair_run;

static int cmp_run(const void *x, const void *y)
{
    const pair_run *p = x, *q = y;
    if (p->a != q->a)
        return (p->a > q->a) - (p->a < q->a);
    return (p->b > q->b) - (p->b < q->b);
}

/* The groups' contacts into w->contacts in canonical order (by pair, then
 * as found). A pair belongs to one group, where its contacts are
 * consecutive and in order: whole runs are sorted by their pair. */
static int merge_contacts(sc_world *w)
{
    int total = 0;
    for (int g = 0; g < w->ngroups; g++)
        total += w->gout[g].ncontacts;
    if (sc_grow((void **)&w->c0, &w->c0_cap, total, sizeof *w->c0, INT_MAX) ||
        sc_grow((void **)&w->contacts, &w->contact_cap, total, sizeof *w->contacts, INT_MAX))
        return SC_ENOMEM;
    sc_contact *all = w->c0;
    int n = 0;
    for (int g = 0; g < w->ngroups; g++) {
        if (w->gout[g].ncontacts)
            memcpy(&all[n], w->gout[g].contacts,
                   (size_t)w->gout[g].ncontacts * sizeof *all);
        n += w->gout[g].ncontacts;
    }
    pair_run *run = sc_alloc_array((size_t)(n > 0 ? n : 1), sizeof *run);
    if (!run)
        return SC_ENOMEM;
    int r = 0;
    for (int k = 0; k < n; k++) {
        if (k == 0 || all[k].body_a != all[k - 1].body_a || all[k].body_b != all[k - 1].body_b)
            run[r++] = (pair_run){ all[k].body_a, all[k].body_b, k, 0 };
        run[r - 1].len++;
    }
    qsort(run, (size_t)r, sizeof *run, cmp_run);    /* pairs are unique */
    w->ncontacts = 0;
    for (int i = 0; i < r; i++) {
        memcpy(&w->contacts[w->ncontacts], &all[run[i].start],
               (size_t)run[i].len * sizeof *all);
        w->ncontacts += run[i].len;
    }
    free(run);
    return SC_OK;
}

int sc_groups_step(sc_world *w, double dt)
{
    double t0 = sc_cpu_now();
    int rc = build_groups(w, dt);
    sc_stage_add(w, SC_STAGE_BROADPHASE, t0);
    if (rc != SC_OK)
        return rc;
    int ng = w->ngroups;
    w->stats.groups = ng;
    if (sc_grow((void **)&w->gout, &w->gout_cap, ng, sizeof *w->gout, INT_MAX) ||
        sc_grow((void **)&w->units, &w->unit_cap, ng, sizeof *w->units, INT_MAX))
        return SC_ENOMEM;
    memset(w->gout, 0, (size_t)ng * sizeof *w->gout);
    int awake = 0;
    for (int i = 0; i < w->nbodies; i++)
        awake += w->gactive[i];
    /* a pile: on the calling thread, its jobs over every node */
    int big = -1;
    for (int g = 0; g < ng && w->nnodes > 1; g++)
        if (w->gstart[g + 1] - w->gstart[g] > BIG_GROUP * awake)
            big = g;
    if (big >= 0) {
        if (!w->bigsub && !(w->bigsub = sub_create(w)))
            return SC_ENOMEM;
        w->bigsub->cfg = w->cfg;
        w->bigsub->parent = w;
        w->bigsub->inline_np = NULL;
        group_frame(w, w->bigsub, big, dt, &w->gout[big]);
    }
    /* the others: one unit each */
    int nu = 0;
    for (int g = 0; g < ng; g++) {
        if (g == big)
            continue;
        int nm = w->gstart[g + 1] - w->gstart[g];
        int nc = w->gcstart[g + 1] - w->gcstart[g];
        sc_unit *u = &w->units[nu++];
        memset(u, 0, sizeof *u);
        u->kind = SC_UNIT_GROUP;
        u->first = g;
        u->count = nm;
        u->islands = 1;
        /* bodies, and their contacts of the last frame (work per substep) */
        u->cost = nm + 4.0 * nc;
        u->feat[0] = 1;
        u->feat[1] = nm;
        u->feat[2] = nc;
    }
    if (nu > 0) {
        sc_job job = {
            .kind = SC_UNIT_GROUP,
            .units = w->units,
            .nunits = nu,
            .world = w,
            .dt = dt,
            .gout = w->gout,
        };
        rc = sc_job_run(w, &job, -1);
    }
    for (int g = 0; g < ng; g++) {
        add_stats(&w->stats, &w->gout[g].stats);
        if (w->gout[g].rc != SC_OK && rc == SC_OK)
            rc = w->gout[g].rc;
    }
    if (rc == SC_OK)
        rc = merge_contacts(w);
    for (int g = 0; g < ng; g++)
        free(w->gout[g].contacts);
    if (rc != SC_OK)
        return rc;
    w->stats.contacts = w->ncontacts;
    for (int i = 0; i < w->nbodies; i++) {
        v3_set(w->bodies[i].force, 0, 0, 0);
        v3_set(w->bodies[i].torque, 0, 0, 0);
    }
    w->contacts_valid = 1;
    return SC_OK;
}
