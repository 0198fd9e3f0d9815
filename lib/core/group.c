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
 * frame (sc_frame_step(): substeps, back-ups, islands, states) on a copy
 * of its bodies and the static ones. Static bodies join no group:
 * they are only read. A group with no awake body is asleep and skipped.
 *
 * Groups are independent, so they are work units of their own: each runs
 * on one node (a thread here, or a daemon: unit_wire.c carries a group's
 * frame) from start to end of the frame, with no synchronisation per
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

#include "frame.h"
#include "vecmath.h"

#define REACH_MARGIN 2e-3     /* m added to every body's reach */
#define BIG_GROUP 0.35        /* share of the awake bodies, or of the groups'
                                 work, that makes a pile */
#define WIRE_GROUP_HEADER 400 /* bytes: unit and result headers, settings, figures */
#define WIRE_GROUP_BODY 496   /* per body out */
#define WIRE_GROUP_MEMBER 288 /* per member's state back */
#define WIRE_GROUP_CONTACT 88 /* per contact, with its impulse */
#define PILE_KEEP 0.5         /* moving average of the pile's frame time */

/* A group's frame runs on a copy of its bodies: this holds the copy and a
 * frame scratch of its own, kept between frames (one per thread that runs
 * groups, and one for a pile on the calling thread). The parent's also
 * keeps the broad phase that finds the groups. */
typedef struct sc_group_scratch {
    sc_frame_scratch scr;
    sc_frame_state st;
    int body_cap;
    int *ids;                       /* the copy's world ids, ascending */
    int ids_cap;
    sc_broadphase *gbp;             /* the parent's: reach spheres */
    sc_pair *gpairs;
    int gpair_cap;
    double pile_s;                  /* the parent's: wall seconds of the last
                                       piles' frames (moving average) */
} sc_group_scratch;

static sc_group_scratch *group_scratch_create(void)
{
    sc_group_scratch *gs = calloc(1, sizeof *gs);
    if (gs && sc_frame_scratch_init(&gs->scr) != SC_OK) {
        sc_frame_scratch_free(&gs->scr);
        free(gs);
        return NULL;
    }
    return gs;
}

static void group_scratch_destroy(sc_group_scratch *gs)
{
    if (!gs)
        return;
    sc_frame_scratch_free(&gs->scr);
    free(gs->st.bodies);
    free(gs->st.contacts);
    free(gs->ids);
    sc_bp_destroy(gs->gbp);
    free(gs->gpairs);
    free(gs);
}

static void group_scratch_free(void *p)
{
    group_scratch_destroy(p);
}

/* Whether bodies a and b (spheres overlapping) can touch within dt: the
 * gap between their bounds closes at most at twice their relative speed,
 * plus the sweep of their shape origins, their relative acceleration and a
 * margin. Bodies falling side by side do not meet. */
static int may_meet(const sc_frame_config *cfg, const sc_frame_state *st, const sc_groups *g,
                    int a, int b, double dt)
{
    const sc_body *A = &st->bodies[a], *B = &st->bodies[b];
    double dv[3], acc[3], aa[3], ab[3];
    v3_sub(dv, A->v, B->v);
    v3_madd(aa, cfg->gravity, A->force, A->inv_mass);
    v3_madd(ab, cfg->gravity, B->force, B->inv_mass);
    v3_sub(acc, aa, ab);
    double gap = v3_dist(&g->centre[3 * a], &g->centre[3 * b]) - A->shape->bound_r -
                 B->shape->bound_r - 2 * cfg->contact_tol_m;
    double close = (2 * v3_len(dv) + v3_len(A->w) * v3_len(A->com) +
                    v3_len(B->w) * v3_len(B->com)) * dt +
                   0.5 * v3_len(acc) * dt * dt + 2 * REACH_MARGIN;
    return gap < close;
}

/* The arrays of g for n bodies and nc contacts from arena a, freed by
 * groups_free() in reverse. */
static int groups_alloc(sc_arena *a, sc_groups *g, int n, int nc)
{
    memset(g, 0, sizeof *g);
    g->n = n;
    size_t N = (size_t)n;
    g->centre = sc_arena_alloc(a, N * 3 * sizeof *g->centre);
    g->radius = g->centre ? sc_arena_alloc(a, N * sizeof *g->radius) : NULL;
    g->active = g->radius ? sc_arena_alloc(a, N) : NULL;
    g->parent = g->active ? sc_arena_alloc(a, N * sizeof(int)) : NULL;
    g->start = g->parent ? sc_arena_alloc(a, (N + 1) * sizeof(int)) : NULL;
    g->members = g->start ? sc_arena_alloc(a, N * sizeof(int)) : NULL;
    g->gid = g->members ? sc_arena_alloc(a, N * sizeof(int)) : NULL;
    g->statics = g->gid ? sc_arena_alloc(a, N * sizeof(int)) : NULL;
    g->cstart = g->statics ? sc_arena_alloc(a, (N + 2) * sizeof(int)) : NULL;
    g->contacts = g->cstart ? sc_arena_alloc(a, (size_t)nc * sizeof(int)) : NULL;
    return g->contacts ? SC_OK : SC_ENOMEM;
}

static void groups_free(sc_arena *a, sc_groups *g)
{
    sc_arena_free(a, g->contacts);
    sc_arena_free(a, g->cstart);
    sc_arena_free(a, g->statics);
    sc_arena_free(a, g->gid);
    sc_arena_free(a, g->members);
    sc_arena_free(a, g->start);
    sc_arena_free(a, g->parent);
    sc_arena_free(a, g->active);
    sc_arena_free(a, g->radius);
    sc_arena_free(a, g->centre);
}

/* The groups of st: g->ngroups, members of group k in
 * members[start[k] .. start[k + 1]) (ascending), gid[i] (-1: none),
 * the static bodies, and the last frame's contacts of each group in
 * contacts[cstart[k] .. cstart[k + 1]). */
static int build_groups(const sc_frame_config *cfg, const sc_frame_state *st,
                        sc_group_scratch *gs, sc_groups *g, double dt,
                        const sc_task_runner *runner)
{
    int n = st->nbodies;
    if (!gs->gbp && !(gs->gbp = sc_bp_create()))
        return SC_ENOMEM;
    g->nstatics = 0;
    for (int i = 0; i < n; i++) {
        const sc_body *b = &st->bodies[i];
        g->parent[i] = i;
        g->gid[i] = -1;
        if (b->inv_mass == 0) {
            /* static: parked out of the sweep, joins no group */
            v3_set(&g->centre[3 * i], 0, 0, 0);
            g->radius[i] = 0;
            g->active[i] = 0;
            g->statics[g->nstatics++] = i;
            continue;
        }
        sc_pose p;
        sc_body_pose(b, &p);
        v3_copy(&g->centre[3 * i], p.pos);
        double reach = sc_body_reach(cfg, b, dt) + REACH_MARGIN;
        g->radius[i] = b->shape->bound_r + cfg->contact_tol_m + reach;
        g->active[i] = sc_body_movable(b);
    }
    int np = sc_bp_find_pairs_on(gs->gbp, runner,
                                 n < 256 ? SC_BROADPHASE_SPHERES : SC_BROADPHASE_SAP, g->centre,
                                 g->radius, g->active, n, &gs->gpairs, &gs->gpair_cap);
    if (np < 0)
        return np;
    for (int k = 0; k < np; k++) {
        const sc_pair *pr = &gs->gpairs[k];
        if (st->bodies[pr->a].inv_mass > 0 && st->bodies[pr->b].inv_mass > 0 &&
            may_meet(cfg, st, g, pr->a, pr->b, dt))
            sc_uf_unite(g->parent, pr->a, pr->b);
    }
    /* bodies touching at the end of the last frame stay together, asleep
     * ones too (an awake neighbour may wake them) */
    for (int k = 0; st->contacts_valid && k < st->ncontacts; k++) {
        const sc_contact *c = &st->contacts[k];
        if (st->bodies[c->body_a].inv_mass > 0 && st->bodies[c->body_b].inv_mass > 0)
            sc_uf_unite(g->parent, c->body_a, c->body_b);
    }
    /* a group needs an awake body; groups numbered by their first member */
    for (int i = 0; i < n; i++)
        if (g->active[i])
            g->gid[sc_uf_find(g->parent, i)] = 0;
    int ng = 0;
    for (int i = 0; i < n; i++) {
        if (st->bodies[i].inv_mass == 0)
            continue;
        int r = sc_uf_find(g->parent, i);
        if (r == i && g->gid[i] == 0)
            g->gid[i] = ++ng;    /* 1-based while numbering */
    }
    for (int i = 0; i < n; i++)
        if (st->bodies[i].inv_mass > 0 && sc_uf_find(g->parent, i) != i)
            g->gid[i] = g->gid[sc_uf_find(g->parent, i)];
    memset(g->start, 0, (size_t)(ng + 1) * sizeof *g->start);
    for (int i = 0; i < n; i++) {
        if (g->gid[i] > 0)
            g->start[g->gid[i]]++;
        g->gid[i] = g->gid[i] > 0 ? g->gid[i] - 1 : -1;
    }
    for (int k = 0; k < ng; k++)
        g->start[k + 1] += g->start[k];
    /* members, ascending within each group (counting sort) */
    for (int k = ng; k > 0; k--)
        g->start[k] = g->start[k - 1];
    g->start[0] = 0;
    for (int i = 0; i < n; i++)
        if (g->gid[i] >= 0)
            g->members[g->start[g->gid[i] + 1]++] = i;
    g->ngroups = ng;
    /* the last frame's contacts, by group, in their canonical order */
    int nc = st->contacts_valid ? st->ncontacts : 0;
    memset(g->cstart, 0, (size_t)(ng + 2) * sizeof *g->cstart);
    for (int k = 0; k < nc; k++) {
        int q = g->gid[st->contacts[k].body_a] >= 0 ? g->gid[st->contacts[k].body_a]
                                                    : g->gid[st->contacts[k].body_b];
        if (q >= 0)
            g->cstart[q + 2]++;
    }
    for (int k = 0; k < ng; k++)
        g->cstart[k + 2] += g->cstart[k + 1];
    for (int k = 0; k < nc; k++) {
        int q = g->gid[st->contacts[k].body_a] >= 0 ? g->gid[st->contacts[k].body_a]
                                                    : g->gid[st->contacts[k].body_b];
        if (q >= 0)
            g->contacts[g->cstart[q + 1]++] = k;
    }
    return SC_OK;
}

int sc_group_local_id(const int *ids, int m, int id)
{
    int lo = 0, hi = m - 1;
    while (lo <= hi) {
        int mid = lo + (hi - lo) / 2;
        if (ids[mid] == id)
            return mid;
        if (ids[mid] < id)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

int sc_group_ids(const sc_groups *g, int k, int *ids)
{
    const int *mem = &g->members[g->start[k]];
    int nm = g->start[k + 1] - g->start[k], ns = g->nstatics, m = nm + ns;
    for (int i = 0, j = 0, q = 0; q < m; q++)
        ids[q] = j >= ns || (i < nm && mem[i] < g->statics[j]) ? mem[i++] : g->statics[j++];
    return m;
}

/* A group's frame on its copy st: what every group runs, here or on a
 * daemon (sc_group_unit_run), so that both give the same bits. */
static int group_copy_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                           sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats)
{
    if (sc_arena_reset(&scr->arena) != SC_OK)
        return SC_ENOMEM;
    return sc_frame_step(cfg, st, dt, scr, ex, stats);
}

/* Group k's frame on the copy in gs: its members and the static bodies,
 * in world order (so contacts keep their canonical order), the last
 * frame's contacts, sc_frame_step() with executor ex, and back. */
static void group_frame(const sc_group_job *gj, sc_group_scratch *gs, int k, sc_exec *ex)
{
    const sc_groups *g = gj->g;
    sc_frame_state *ps = gj->st;
    sc_group_out *out = &gj->out[k];
    int m = g->start[k + 1] - g->start[k] + g->nstatics;
    memset(out, 0, sizeof *out);
    out->rc = SC_ENOMEM;
    sc_frame_state *st = &gs->st;
    if (sc_grow((void **)&gs->ids, &gs->ids_cap, m, sizeof *gs->ids, INT_MAX) ||
        sc_grow((void **)&st->bodies, &gs->body_cap, m, sizeof *st->bodies, INT_MAX))
        return;
    int *ids = gs->ids;
    sc_group_ids(g, k, ids);
    for (int q = 0; q < m; q++)
        st->bodies[q] = ps->bodies[ids[q]];
    st->nbodies = m;
    const int *ck = &g->contacts[g->cstart[k]];
    int nc = g->cstart[k + 1] - g->cstart[k];
    if (sc_grow((void **)&st->contacts, &st->contact_cap, nc, sizeof *st->contacts, INT_MAX))
        return;
    for (int q = 0; q < nc; q++) {
        sc_contact c = ps->contacts[ck[q]];
        c.body_a = sc_group_local_id(ids, m, c.body_a);
        c.body_b = sc_group_local_id(ids, m, c.body_b);
        st->contacts[q] = c;
    }
    st->ncontacts = nc;
    st->contacts_valid = ps->contacts_valid;
    out->rc = group_copy_step(gj->cfg, st, gj->dt, &gs->scr, ex, &out->stats);
    for (int q = 0; q < m; q++)
        if (st->bodies[q].inv_mass > 0)
            ps->bodies[ids[q]] = st->bodies[q];
    if (out->rc != SC_OK || st->ncontacts == 0)
        return;
    out->contacts = sc_alloc_array((size_t)st->ncontacts, sizeof *out->contacts);
    if (!out->contacts) {
        out->rc = SC_ENOMEM;
        return;
    }
    for (int q = 0; q < st->ncontacts; q++) {
        sc_contact c = st->contacts[q];
        c.body_a = ids[c.body_a];
        c.body_b = ids[c.body_b];
        out->contacts[q] = c;
    }
    out->ncontacts = st->ncontacts;
}

int sc_group_unit_run(sc_np_ctx *np, const sc_job *job, const sc_unit *u)
{
    void (*fn)(void *) = group_scratch_free;
    void **slot = sc_np_scratch(np, &fn);
    if (!*slot)
        *slot = group_scratch_create();
    sc_group_scratch *gs = *slot;
    if (!gs)
        return SC_ENOMEM;
    /* a group unit runs on this thread alone */
    sc_exec_serial ex;
    sc_exec_serial_init(&ex, np);
    const sc_group_job *gj = job->group;
    if (!gj->g) {
        /* received: the copy is the unit's own (the same step as below) */
        sc_group_out *out = &gj->out[0];
        memset(out, 0, sizeof *out);
        out->rc = group_copy_step(gj->cfg, gj->st, gj->dt, &gs->scr, &ex.base, &out->stats);
        return out->rc;
    }
    group_frame(gj, gs, u->first, &ex.base);
    return gj->out[u->first].rc;
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

/* The groups' contacts into st->contacts in canonical order (by pair,
 * then as found). A pair belongs to one group, where its contacts are
 * consecutive and in order: whole runs are sorted by their pair. */
static int merge_contacts(sc_arena *a, sc_frame_state *st, const sc_group_out *out, int ng)
{
    int total = 0;
    for (int k = 0; k < ng; k++)
        total += out[k].ncontacts;
    if (sc_grow((void **)&st->contacts, &st->contact_cap, total, sizeof *st->contacts, INT_MAX))
        return SC_ENOMEM;
    sc_contact *all = sc_arena_alloc(a, (size_t)total * sizeof *all);
    pair_run *run = all ? sc_arena_alloc(a, (size_t)total * sizeof *run) : NULL;
    if (!run) {
        sc_arena_free(a, all);
        return SC_ENOMEM;
    }
    int n = 0;
    for (int k = 0; k < ng; k++) {
        if (out[k].ncontacts)
            memcpy(&all[n], out[k].contacts, (size_t)out[k].ncontacts * sizeof *all);
        n += out[k].ncontacts;
    }
    int r = 0;
    for (int k = 0; k < n; k++) {
        if (k == 0 || all[k].body_a != all[k - 1].body_a || all[k].body_b != all[k - 1].body_b)
            run[r++] = (pair_run){ all[k].body_a, all[k].body_b, k, 0 };
        run[r - 1].len++;
    }
    qsort(run, (size_t)r, sizeof *run, cmp_run);    /* pairs are unique */
    st->ncontacts = 0;
    for (int i = 0; i < r; i++) {
        memcpy(&st->contacts[st->ncontacts], &all[run[i].start],
               (size_t)run[i].len * sizeof *all);
        st->ncontacts += run[i].len;
    }
    sc_arena_free(a, run);
    sc_arena_free(a, all);
    return SC_OK;
}

/* What group k's frame costs: its bodies, and its contacts of the last
 * frame (work per substep). */
static double group_cost(const sc_groups *g, int k)
{
    return (g->start[k + 1] - g->start[k]) + 4.0 * (g->cstart[k + 1] - g->cstart[k]);
}

/* The groups' frames, with the groups built in g. */
static int step_groups(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                       sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats, sc_groups *g)
{
    sc_arena *a = &scr->arena;
    int ng = g->ngroups;
    stats->groups = ng;
    sc_group_out *out = sc_arena_calloc(a, (size_t)ng, sizeof *out);
    sc_unit *units = out ? sc_arena_calloc(a, (size_t)ng, sizeof *units) : NULL;
    if (!units) {
        sc_arena_free(a, out);
        return SC_ENOMEM;
    }
    sc_group_job gj = { .cfg = cfg, .st = st, .g = g, .dt = dt, .out = out };
    int awake = 0;
    for (int i = 0; i < st->nbodies; i++)
        awake += g->active[i];
    /* a pile: on the calling thread, its jobs over every node. It holds
     * more than BIG_GROUP of the awake bodies, or of the work (as a unit
     * would cost: a group of a few hundred bodies in contact can outweigh
     * hundreds of lone falling bodies, and as one unit it would bound the
     * frame; the cost underestimates a large group, whose back-ups repeat
     * all of it, hence less than half: docs/DESIGN.md 3.9); a group is one
     * or the other on any executor, the same bits */
    int big = -1;
    double total = 0;
    for (int k = 0; k < ng; k++)
        total += group_cost(g, k);
    for (int k = 0; k < ng && ex->width(ex) > 1; k++)
        if ((g->start[k + 1] - g->start[k] > BIG_GROUP * awake ||
             group_cost(g, k) > BIG_GROUP * total) &&
            (big < 0 || group_cost(g, k) > group_cost(g, big)))
            big = k;
    int rc = SC_OK;
    /* the others: one unit each */
    int nu = 0;
    for (int k = 0; k < ng; k++) {
        if (k == big)
            continue;
        int nm = g->start[k + 1] - g->start[k];
        int nc = g->cstart[k + 1] - g->cstart[k];
        sc_unit *u = &units[nu++];
        u->kind = SC_UNIT_GROUP;
        u->first = k;
        u->count = nm;
        u->islands = 1;
        u->cost = group_cost(g, k);
        u->feat[0] = 1;
        u->feat[1] = nm;
        u->feat[2] = nc;
        /* its wire size (the transfer estimate; unit_wire.c): every body
         * out, the members' states back, contacts both ways */
        u->bytes = WIRE_GROUP_HEADER + WIRE_GROUP_BODY * (size_t)(nm + g->nstatics) +
                   WIRE_GROUP_MEMBER * (size_t)nm + 2 * WIRE_GROUP_CONTACT * (size_t)nc;
    }
    sc_job job = {
        .kind = SC_UNIT_GROUP,
        .units = units,
        .nunits = nu,
        .group = &gj,
        .run_group = sc_group_unit_run,
    };
    /* With a pile, the other groups' units go out to remote nodes before
     * it and are collected after it, so that daemons step them while this
     * thread steps the pile (the local nodes' share waits until then: the
     * scheduler counts them busy for the pile's predicted time). Units
     * read only the groups' own members and the static bodies, which the
     * pile does not write, and write only their own, so the order changes
     * nothing. */
    int started = 0, background = 0;
    /* Without remote nodes, idle local threads step the other groups in
     * the gaps of the pile's jobs, and the calling thread the rest after
     * it (the same bits: each unit writes only its own group). */
    if (nu > 0 && big >= 0 && ex->background)
        background = ex->background(ex, &job);
    if (nu > 0 && big >= 0 && !background && ex->start) {
        rc = ex->start(ex, &job, scr->groups->pile_s);
        started = rc == SC_OK;
    }
    if (big >= 0 && rc == SC_OK) {
        double t0 = sc_wall_now();
        group_frame(&gj, scr->groups, big, ex);
        double t = sc_wall_now() - t0;
        sc_group_scratch *ps = scr->groups;
        ps->pile_s = ps->pile_s > 0 ? PILE_KEEP * ps->pile_s + (1 - PILE_KEEP) * t : t;
    }
    if (background) {
        /* always: the units taken read this frame's arrays */
        int drc = ex->drain(ex, &job, stats);
        if (rc == SC_OK)
            rc = drc;
    } else if (nu > 0 && rc == SC_OK)
        rc = started ? ex->finish(ex, &job, -1, stats) : ex->run(ex, &job, -1, stats);
    for (int k = 0; k < ng; k++) {
        sc_stats_add_frame(stats, &out[k].stats);
        if (out[k].rc != SC_OK && rc == SC_OK)
            rc = out[k].rc;
    }
    if (rc == SC_OK)
        rc = merge_contacts(a, st, out, ng);
    for (int k = 0; k < ng; k++)
        free(out[k].contacts);
    sc_arena_free(a, units);
    sc_arena_free(a, out);
    return rc;
}

int sc_groups_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                   sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats)
{
    if (st->nbodies == 0)
        return SC_OK;
    if (!scr->groups) {
        if (!(scr->groups = group_scratch_create()))
            return SC_ENOMEM;
        scr->groups_free = group_scratch_destroy;
    }
    sc_arena *a = &scr->arena;
    double t0 = sc_cpu_now();
    sc_groups g;
    int rc = groups_alloc(a, &g, st->nbodies, st->contacts_valid ? st->ncontacts : 0);
    if (rc == SC_OK)
        rc = build_groups(cfg, st, scr->groups, &g, dt, ex->runner);
    sc_stage_add(stats, SC_STAGE_BROADPHASE, t0);
    if (rc == SC_OK)
        rc = step_groups(cfg, st, dt, scr, ex, stats, &g);
    groups_free(a, &g);
    if (a->high > stats->arena_bytes)
        stats->arena_bytes = a->high;
    if (rc != SC_OK)
        return rc;
    stats->contacts = st->ncontacts;
    for (int i = 0; i < st->nbodies; i++) {
        v3_set(st->bodies[i].force, 0, 0, 0);
        v3_set(st->bodies[i].torque, 0, 0, 0);
    }
    st->contacts_valid = 1;
    return SC_OK;
}
