/* group.c - motion groups (docs/DESIGN.md 3.9): the frame stepped apart
 * for bodies that cannot meet within it, so that an early time of impact
 * backs up only the bodies that can reach it. Bodies whose reach spheres
 * overlap and whose gap can close within the frame are joined; each group
 * runs its whole frame on a copy of its bodies, a work unit of its own.
 * Groups whose tracks came within touching distance are joined and stepped
 * again (check_groups()), so the groups that stand are a function of the
 * bodies alone, whoever ran what. */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

/* The paper backs the whole world up to the earliest time of impact; with
 * hundreds of bodies some pair almost always hits early, and every body
 * pays for it (200 bolts and nuts: about 10 back-ups per frame). Here each
 * dynamic body gets a sphere that holds everything it can reach in the
 * frame (its bound, the contact tolerance, twice its speed times dt, the
 * sweep of its shape origin about the centre of mass, half its
 * acceleration times dt^2, a margin); of the bodies whose spheres overlap,
 * those whose gap can close within the frame as they move at its start
 * (may_meet(): bodies falling side by side do not) are joined, as are
 * bodies touching at the end of the last frame, and bodies joined directly
 * or through others form a group. Each group runs the whole
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
 * A body turned by a collision within the frame can still reach a body of
 * another group. So every group's frame keeps where its bodies went (a
 * track: sc_track, frame.c), and after all groups ran, bodies of
 * different groups whose tracks came within touching distance
 * (check_groups()) are joined and the frame is stepped again from its
 * start for the groups that changed (sc_groups_step(); the others keep
 * their results: the same inputs give the same bits). The groups that
 * stand are a function of the bodies alone, whoever ran what.
 * docs/DESIGN.md 3.9. */

#define REACH_MARGIN 2e-3     /* m added to every body's reach */
#define BIG_GROUP 0.35        /* share of the awake bodies, or of the groups'
                                 work, that makes a pile */
#define BUNDLES_PER_NODE 8    /* group units a node, about */
#define BUNDLE_MAX_GROUPS 1024
#define BUNDLE_MAX_BODIES 4096
#define JOIN_MARGIN 1e-3      /* m: bodies whose gap can close within the
                                 frame, as they move at its start, to
                                 under this are joined (more than the
                                 parabola-to-chord distance of a falling
                                 body over a frame, |g| dt^2 / 8 = 0.34 mm at
                                 60 Hz, twice: check_groups() counts it) */
#define PILE_KEEP 0.5         /* moving average of the pile's frame time */
#define INSIDE_SLACK 1e-9     /* relative and absolute (m) room for rounding when
                                 a check sphere is taken as inside a reach sphere */
#define CHECK_FEW_OUTSIDE 16  /* the check takes the build's pairs while at most
                                 one body in this many is outside, */
#define CHECK_OUTSIDE_MAX 48  /* and at most this many (each is tested against every
                                 body; a sweep costs about as much a body) */

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
    int gpair_cap, ngpairs;         /* ngpairs: the last build's */
    double pile_s;                  /* the parent's: wall seconds of the last
                                       piles' frames (moving average) */
    sc_track track;                 /* the copy's */
    int track_cap;
    sc_broadphase *cbp;             /* the parent's: the tracks' check */
    sc_pair *cpairs;
    int cpair_cap;
    double *cc, *cr;                /* the check's spheres, n bodies */
    unsigned char *cact, *inside;   /* its activity; inside the reach sphere */
    int c_cap;
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
    sc_track_free(&gs->track);
    sc_bp_destroy(gs->cbp);
    free(gs->cpairs);
    free(gs->cc);
    free(gs->cr);
    free(gs->cact);
    free(gs->inside);
    free(gs);
}

static void group_scratch_free(void *p)
{
    group_scratch_destroy(p);
}

/* Whether bodies A and B (a and b, spheres overlapping) may come to touch
 * within dt as they move at its start (sc_body_drift(): the gap between
 * their bounds closes at most by their relative speed, half their relative
 * acceleration and their turns' second-order terms), to within
 * JOIN_MARGIN. Bodies falling side by side do not meet. A pair that meets
 * anyway, turned by a collision, is found by check_groups(). */
static int may_meet(const sc_frame_config *cfg, const sc_groups *g, const sc_body *A,
                    const sc_body *B, int a, int b, const double *drift, double dt)
{
    const double *da = &drift[9 * a], *db = &drift[9 * b];
    double dv[3], dacc[3];
    v3_sub(dv, da + 3, db + 3);
    v3_sub(dacc, da + 6, db + 6);
    double gap = v3_dist(&g->centre[3 * a], &g->centre[3 * b]) - A->shape->bound_r -
                 B->shape->bound_r - 2 * cfg->contact_tol_m;
    double wa = v3_len(A->w), wb = v3_len(B->w);
    double close = v3_len(dv) * dt +
                   0.5 * (v3_len(dacc) + wa * wa * v3_len(A->com) + wb * wb * v3_len(B->com)) *
                       dt * dt +
                   JOIN_MARGIN;
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
                        sc_group_scratch *gs, sc_groups *g, const double *drift, double dt,
                        const sc_task_runner *runner, int *forced)
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
    gs->ngpairs = np < 0 ? 0 : np;
    if (np < 0)
        return np;
    for (int k = 0; k < np; k++) {
        const sc_pair *pr = &gs->gpairs[k];
        if (st->bodies[pr->a].inv_mass > 0 && st->bodies[pr->b].inv_mass > 0 &&
            may_meet(cfg, g, &st->bodies[pr->a], &st->bodies[pr->b], pr->a, pr->b, drift, dt))
            sc_uf_unite(g->parent, pr->a, pr->b);
    }
    /* bodies touching at the end of the last frame stay together, asleep
     * ones too (an awake neighbour may wake them) */
    for (int k = 0; st->contacts_valid && k < st->ncontacts; k++) {
        const sc_contact *c = &st->contacts[k];
        if (st->bodies[c->body_a].inv_mass > 0 && st->bodies[c->body_b].inv_mass > 0)
            sc_uf_unite(g->parent, c->body_a, c->body_b);
    }
    /* bodies that met in an earlier try of this frame (sc_groups_step) */
    for (int i = 0; i < n; i++)
        if (sc_uf_find(forced, i) != i)
            sc_uf_unite(g->parent, i, sc_uf_find(forced, i));
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
    st->track = NULL;
    if (gj->track) {
        if (sc_track_reserve(&gs->track, &gs->track_cap, m) != SC_OK)
            return;
        st->track = &gs->track;
    }
    out->rc = group_copy_step(gj->cfg, st, gj->dt, &gs->scr, ex, &out->stats);
    for (int q = 0; q < m; q++)
        if (st->bodies[q].inv_mass > 0) {
            ps->bodies[ids[q]] = st->bodies[q];
            if (st->track)
                sc_track_copy(gj->track, ids[q], st->track, q);
        }
    st->track = NULL;
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
    int rc = SC_OK;
    for (int j = u->first; j < u->first + u->islands; j++) {
        int k = gj->list ? gj->list[j] : j;
        group_frame(gj, gs, k, &ex.base);
        if (rc == SC_OK)
            rc = gj->out[k].rc;
    }
    return rc;
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
                       sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats, sc_groups *g,
                       sc_group_out *out, sc_track *track, const unsigned char *todo)
{
    sc_arena *a = &scr->arena;
    int ng = g->ngroups;
    stats->frame.sched.groups = ng;
    sc_unit *units = sc_arena_calloc(a, (size_t)ng, sizeof *units);
    if (!units)
        return SC_ENOMEM;
    sc_group_job gj = { .cfg = cfg, .st = st, .g = g, .dt = dt, .out = out, .track = track };
    int awake = 0;
    for (int i = 0; i < st->nbodies; i++)
        awake += g->active[i] && todo[g->gid[i]];
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
        total += todo[k] ? group_cost(g, k) : 0;
    for (int k = 0; k < ng && ex->width(ex) > 1; k++)
        if (todo[k] && (g->start[k + 1] - g->start[k] > BIG_GROUP * awake ||
             group_cost(g, k) > BIG_GROUP * total) &&
            (big < 0 || group_cost(g, k) > group_cost(g, big)))
            big = k;
    int rc = SC_OK;
    /* the others: in units of several groups each (a bundle), about
     * BUNDLES_PER_NODE a node by their cost, so that a daemon gets a few
     * units of many groups rather than hundreds of one falling part (the
     * statics, the body constants and the headers travel once a unit:
     * docs/DESIGN.md 7.4) */
    int *list = sc_arena_calloc(a, (size_t)ng + 1, sizeof *list);
    if (!list) {
        sc_arena_free(a, units);
        return SC_ENOMEM;
    }
    int nl = 0;
    double small = 0;
    for (int k = 0; k < ng; k++)
        if (k != big && todo[k]) {
            list[nl++] = k;
            small += group_cost(g, k);
        }
    gj.list = list;
    gj.nlist = nl;
    int width = ex->width(ex);
    double target = small / (BUNDLES_PER_NODE * (width > 1 ? width : 1));
    int nu = 0;
    for (int j = 0; j < nl;) {
        sc_unit *u = &units[nu++];
        u->kind = SC_UNIT_GROUP;
        u->first = j;
        u->feat[0] = 1;
        int nm = 0, nc = 0;
        double cost = 0;
        do {
            int k = list[j++];
            nm += g->start[k + 1] - g->start[k];
            nc += g->cstart[k + 1] - g->cstart[k];
            cost += group_cost(g, k);
            u->islands++;
        } while (j < nl && cost < target && u->islands < BUNDLE_MAX_GROUPS &&
                 nm + g->start[list[j] + 1] - g->start[list[j]] <= BUNDLE_MAX_BODIES);
        u->count = nm;
        u->cost = cost;
        u->feat[1] = nm;
        u->feat[2] = nc;
        /* its wire size (the transfer estimate) */
        u->bytes = sc_unit_bytes_groups(g->nstatics, u->islands, nm, nc);
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
    for (int k = 0; k < ng; k++)
        if (todo[k] && out[k].rc != SC_OK && rc == SC_OK)
            rc = out[k].rc;
    sc_arena_free(a, list);
    sc_arena_free(a, units);
    return rc;
}

/* Body i's shape origin at time t of the frame: on its track (linear
 * between points) if it has one, else on its drift d (9 doubles). */
static void origin_at(const sc_track *tr, int i, const double *d, double t, double p[3])
{
    int n = tr ? tr->count[i] : 0;
    if (n == 0) {
        sc_drift_at(d, t, p);
        return;
    }
    enum { S = SC_TRACK_STRIDE };
    const double *q = &tr->pt[(size_t)i * SC_TRACK_MAX * S];
    int k = 0;
    while (k + 2 < n && q[S * (k + 1)] <= t)
        k++;
    if (n == 1) {
        v3_copy(p, q + 1);
        return;
    }
    const double *x = &q[S * k], *y = &q[S * (k + 1)];
    double s = y[0] > x[0] ? (t - x[0]) / (y[0] - x[0]) : 1;
    s = min_d(1, max_d(0, s));
    for (int c = 0; c < 3; c++)
        p[c] = x[1 + c] + s * (y[1 + c] - x[1 + c]);
}

/* The closest bodies a and b came in the frame of dt, less how far a
 * body without a track may have been from where its drift puts it (its
 * dev, and the parabola's distance from its chord over the intervals
 * here): at every point of either track, and between two along both
 * chords. */
/* 0, dt and the times of bodies a's and b's track points (none for a
 * body that did not run: ran_a, ran_b 0), sorted into ts (room for
 * TRACK_TIMES); returns how many. */
#define TRACK_TIMES (2 * SC_TRACK_MAX + 2)
static int track_times(const sc_track *tr, int a, int b, int ran_a, int ran_b, double dt,
                       double *ts)
{
    const int ab[2] = { a, b }, ran[2] = { ran_a, ran_b };
    int nt = 0;
    ts[nt++] = 0;
    ts[nt++] = dt;
    for (int s = 0; s < 2; s++) {
        int n = ran[s] ? tr->count[ab[s]] : 0;
        const double *q = &tr->pt[(size_t)ab[s] * SC_TRACK_MAX * SC_TRACK_STRIDE];
        for (int k = 0; k < n; k++)
            ts[nt++] = min_d(dt, max_d(0, q[SC_TRACK_STRIDE * k]));
    }
    /* sort the times (a few dozen) */
    for (int i = 1; i < nt; i++)
        for (int j = i; j > 0 && ts[j - 1] > ts[j]; j--) {
            double x = ts[j];
            ts[j] = ts[j - 1];
            ts[j - 1] = x;
        }
    return nt;
}

static double track_gap(const sc_track *tr, const double *drift, int a, int b, int ran_a,
                        int ran_b, double dt)
{
    const int ab[2] = { a, b }, ran[2] = { ran_a, ran_b };
    double ts[TRACK_TIMES];
    int nt = track_times(tr, a, b, ran_a, ran_b, dt, ts);
    double hmax = 0;
    for (int i = 1; i < nt; i++)
        hmax = max_d(hmax, ts[i] - ts[i - 1]);
    double pad = 0;
    for (int s = 0; s < 2; s++)
        if (!ran[s] || tr->count[ab[s]] == 0)
            pad += (ran[s] ? tr->dev[ab[s]] : 0) +
                   v3_len(&drift[9 * ab[s] + 6]) * hmax * hmax / 8;
    const sc_track *ta = ran_a ? tr : NULL, *tb = ran_b ? tr : NULL;
    double best = INFINITY, r0[3], pa[3], pb[3];
    origin_at(ta, a, &drift[9 * a], ts[0], pa);
    origin_at(tb, b, &drift[9 * b], ts[0], pb);
    v3_sub(r0, pa, pb);
    best = v3_len(r0);
    for (int i = 1; i < nt; i++) {
        double r1[3], dr[3];
        origin_at(ta, a, &drift[9 * a], ts[i], pa);
        origin_at(tb, b, &drift[9 * b], ts[i], pb);
        v3_sub(r1, pa, pb);
        v3_sub(dr, r1, r0);
        double dd = v3_dot(dr, dr);
        double s = dd > 0 ? min_d(1, max_d(0, -v3_dot(r0, dr) / dd)) : 0;
        double at[3];
        v3_madd(at, r0, dr, s);
        best = min_d(best, v3_len(at));
        v3_copy(r0, r1);
    }
    return best - pad;
}

/* The exact check (check_groups()): a pair whose bounding spheres came
 * within touching distance is still apart if its shapes never came within
 * it. A body's poses over the frame: at its start (a sleeping body in no
 * group), along its track's points (slerped between two, as the frame
 * moves it: the time of impact's poses), or, for a body that kept to its
 * drift, on the drift turning at its spin (sc_spin_at()), widened by its
 * track's dev and adev. */
#define APART_STEP 5e-4       /* m: the most any point moves between two of
                                 the check's samples, about */
#define APART_SAMPLES 128     /* samples a pair, at most (the step grows) */

enum { PATH_STILL, PATH_TRACK, PATH_SPIN };

typedef struct path {
    int kind;
    const sc_shape *shape;
    const double *pt;         /* PATH_TRACK: its points */
    int n;
    const double *d;          /* PATH_SPIN: drift, start orientation, spin */
    const double *q0, *w0;
    sc_pose still;            /* PATH_STILL */
    double pad;               /* m: how far the body may be from these poses */
} path;

/* Body i's path over the frame of dt, or 0 where the check has none (a
 * body with too many points for its track). Between its substep ends a
 * body that kept to its drift turns by a slerp, the spin at a steady rate:
 * two turns at rates w and w' part at first order as they did at the ends
 * (the larger, adev), and at second order by up to |w| h times that over a
 * substep of h <= dt, which the pad takes twice. */
static int path_of(const sc_body *start, const sc_track *tr, const double *drift, int i,
                   int ran, double dt, path *p)
{
    memset(p, 0, sizeof *p);
    p->shape = start[i].shape;
    if (!ran) {
        p->kind = PATH_STILL;
        sc_body_pose(&start[i], &p->still);
        return 1;
    }
    if (tr->count[i] > 0) {
        p->kind = PATH_TRACK;
        p->pt = &tr->pt[(size_t)i * SC_TRACK_MAX * SC_TRACK_STRIDE];
        p->n = tr->count[i];
        return 1;
    }
    if (tr->dev[i] > SC_TRACK_DEV)
        return 0;
    p->kind = PATH_SPIN;
    p->d = &drift[9 * i];
    p->q0 = start[i].q;
    p->w0 = start[i].w;
    p->pad = tr->dev[i] + (1 + 2 * v3_len(p->w0) * dt) * tr->adev[i] * p->shape->bound_r;
    return 1;
}

static void pose_on(const path *p, double t, sc_pose *out)
{
    enum { S = SC_TRACK_STRIDE };
    if (p->kind == PATH_STILL) {
        *out = p->still;
    } else if (p->kind == PATH_SPIN) {
        sc_drift_at(p->d, t, out->pos);
        sc_spin_at(p->q0, p->w0, t, out->quat);
    } else {
        int k = 0;
        while (k + 2 < p->n && p->pt[S * (k + 1)] <= t)
            k++;
        const double *x = &p->pt[S * k], *y = &p->pt[S * (k + 1 < p->n ? k + 1 : k)];
        sc_pose a, b;
        memcpy(a.pos, x + 1, 3 * sizeof *x);
        memcpy(a.quat, x + 4, 4 * sizeof *x);
        memcpy(b.pos, y + 1, 3 * sizeof *y);
        memcpy(b.quat, y + 4, 4 * sizeof *y);
        double s = y[0] > x[0] ? (t - x[0]) / (y[0] - x[0]) : 1;
        sc_pose_lerp(out, &a, &b, min_d(1, max_d(0, s)));
    }
}

/* 1 if bodies a and b, whose bounding spheres came within touching
 * distance in the frame of dt, were for sure never within touching distance
 * (twice the contact tolerance) of each other: sampled at every point of
 * either track and between, so that no point moves more than about
 * APART_STEP from one sample to the next, each sample's shapes more than
 * the touching distance apart, plus that half-step, the paths' widening
 * and a drift's parabola off its chord (sc_np_apart_by()). 0 when that
 * does not show it: they are then joined. */
static int exact_apart(const sc_frame_config *cfg, const sc_body *start, const sc_track *tr,
                       const double *drift, int a, int b, int ran_a, int ran_b, double dt)
{
    path pa, pb;
    if (!path_of(start, tr, drift, a, ran_a, dt, &pa) ||
        !path_of(start, tr, drift, b, ran_b, dt, &pb))
        return 0;
    const path *ps[2] = { &pa, &pb };
    double ts[TRACK_TIMES];
    int nt = track_times(tr, a, b, ran_a, ran_b, dt, ts);
    /* each interval's sweep: how far any point of either shape moves */
    double sweep[TRACK_TIMES], total = 0;
    for (int i = 1; i < nt; i++) {
        sweep[i] = 0;
        for (int s = 0; s < 2; s++) {
            sc_pose p0, p1;
            pose_on(ps[s], ts[i - 1], &p0);
            pose_on(ps[s], ts[i], &p1);
            sweep[i] += sc_toi_sweep(ps[s]->shape, &p0, &p1);
        }
        total += sweep[i];
    }
    double step = max_d(APART_STEP, total / APART_SAMPLES);
    double touch = 2 * cfg->contact_tol_m + pa.pad + pb.pad;
    for (int i = 1; i < nt; i++) {
        double h = ts[i] - ts[i - 1];
        if (!(h > 0) && i > 1)
            continue;
        int k = (int)ceil(sweep[i] / step);
        k = k < 1 ? 1 : k;
        double chord = 0;
        for (int s = 0; s < 2; s++)
            if (ps[s]->kind == PATH_SPIN)
                chord += v3_len(ps[s]->d + 6) * h * h / 8;
        double margin = touch + chord + sweep[i] / (2 * k);
        for (int j = i > 1; j <= k; j++) {
            double t = ts[i - 1] + h * j / k;
            sc_pose p0, p1;
            pose_on(&pa, t, &p0);
            pose_on(&pb, t, &p1);
            if (!sc_np_apart_by(pa.shape, &p0, pb.shape, &p1, margin))
                return 0;
        }
    }
    return 1;
}

/* Pairs of bodies of different groups (or of a group and a sleeping body
 * in none) that may have come close enough to touch in the frame: first
 * by their drifts (sc_body_drift(), from their states at the frame's
 * start, start[i]) and how far each went from it (tr->dev), then, where
 * that does not keep them apart and one has a track, by their tracks
 * (track_gap()). The frame is then stepped again with them in one group
 * (sc_groups_step). United in forced; returns how many pairs. */
static int check_groups(const sc_frame_config *cfg, const sc_body *start, const sc_body *now,
                        int n, sc_group_scratch *gs, sc_groups *g, const sc_track *tr,
                        const double *drift, double dt, const sc_task_runner *runner,
                        int *forced)
{
    if (!gs->cbp && !(gs->cbp = sc_bp_create()))
        return SC_ENOMEM;
    if (n > gs->c_cap) {
        free(gs->cc);
        free(gs->cr);
        free(gs->cact);
        free(gs->inside);
        gs->c_cap = 0;
        gs->cc = sc_alloc_array((size_t)n, 3 * sizeof *gs->cc);
        gs->cr = sc_alloc_array((size_t)n, sizeof *gs->cr);
        gs->cact = sc_alloc_array((size_t)n, 1);
        gs->inside = sc_alloc_array((size_t)n, 1);
        if (!gs->cc || !gs->cr || !gs->cact || !gs->inside)
            return SC_ENOMEM;
        gs->c_cap = n;
    }
    double *cc = gs->cc, *cr = gs->cr;
    unsigned char *act = gs->cact, *inside = gs->inside;
    /* the check's spheres; g keeps the build's reach spheres, which hold
     * most of them: a body whose check sphere lies inside its reach sphere
     * (with room for rounding) and that is active there when it is here
     * meets, in the check, only bodies the build's pairs name */
    int outside = 0;
    for (int i = 0; i < n; i++) {
        const sc_body *b = &start[i];
        act[i] = b->inv_mass > 0 && g->gid[i] >= 0;
        inside[i] = 0;
        if (b->inv_mass == 0) {
            v3_set(&cc[3 * i], 0, 0, 0);
            cr[i] = 0;
            outside++;
            continue;
        }
        const double *d = &drift[9 * i];
        double dev = act[i] ? tr->dev[i] : 0;
        v3_madd(&cc[3 * i], d, d + 3, 0.5 * dt);
        cr[i] = 0.5 * dt * v3_len(d + 3) + 0.5 * dt * dt * v3_len(d + 6) + dev +
                b->shape->bound_r + cfg->contact_tol_m;
        double off[3];
        v3_sub(off, &cc[3 * i], &g->centre[3 * i]);
        inside[i] = (!act[i] || g->active[i]) &&
                    v3_len(off) + cr[i] <= g->radius[i] * (1 - INSIDE_SLACK) - INSIDE_SLACK;
        outside += !inside[i];
    }
    int np = outside * CHECK_FEW_OUTSIDE <= n && outside <= CHECK_OUTSIDE_MAX
                 ? sc_bp_pairs_within(gs->cbp, gs->gpairs, gs->ngpairs, inside, cc, cr, act, n,
                                      &gs->cpairs, &gs->cpair_cap)
                 : sc_bp_find_pairs_on(gs->cbp, runner,
                                       n < 256 ? SC_BROADPHASE_SPHERES : SC_BROADPHASE_SAP, cc,
                                       cr, act, n, &gs->cpairs, &gs->cpair_cap);
    int met = 0;
    for (int k = 0; k < np; k++) {
        int a = gs->cpairs[k].a, b = gs->cpairs[k].b;
        if (start[a].inv_mass == 0 || start[b].inv_mass == 0 ||
            (g->gid[a] == g->gid[b] && g->gid[a] >= 0))
            continue;
        /* two bodies asleep from the frame's start to its end did not
         * move (a body woken in the frame has no rest time left to fall
         * asleep again by its end: state.c) */
        if (start[a].state == SC_ASLEEP && start[b].state == SC_ASLEEP &&
            now[a].state == SC_ASLEEP && now[b].state == SC_ASLEEP)
            continue;
        int ran_a = g->gid[a] >= 0, ran_b = g->gid[b] >= 0;
        const double *A = &drift[9 * a], *B = &drift[9 * b];
        double d0[3], dv[3], dacc[3];
        v3_sub(d0, A, B);
        v3_sub(dv, A + 3, B + 3);
        v3_sub(dacc, A + 6, B + 6);
        /* the nearest approach within the frame of the relative line, the
         * relative acceleration (the same gravity: mostly none) taken as a
         * bound */
        double vv = v3_dot(dv, dv);
        double t = vv > 0 ? min_d(dt, max_d(0, -v3_dot(d0, dv) / vv)) : 0;
        double at[3];
        v3_madd(at, d0, dv, t);
        double touch = start[a].shape->bound_r + start[b].shape->bound_r +
                       2 * cfg->contact_tol_m;
        double reach = touch + 0.5 * v3_len(dacc) * dt * dt + (ran_a ? tr->dev[a] : 0) +
                       (ran_b ? tr->dev[b] : 0);
        if (v3_len(at) >= reach)
            continue;
        if (((ran_a && tr->count[a] > 0) || (ran_b && tr->count[b] > 0)) &&
            track_gap(tr, drift, a, b, ran_a, ran_b, dt) >= touch)
            continue;
        if (exact_apart(cfg, start, tr, drift, a, b, ran_a, ran_b, dt))
            continue;
        sc_uf_unite(forced, a, b);
        met++;
    }
    return np < 0 ? np : met;
}

/* The arrays the tries of a frame share (sc_groups_step()): the bodies at
 * its start, where the groups' bodies went, the pairs that met, the last
 * try's groups, every body's drift. From arena a, freed in reverse. */
typedef struct tries {
    sc_body *start;
    sc_track track;
    int *forced, *prev_gid;
    double *drift;
} tries;

static void tries_free(sc_arena *a, tries *t)
{
    sc_arena_free(a, t->drift);
    sc_arena_free(a, t->prev_gid);
    sc_arena_free(a, t->forced);
    sc_arena_free(a, t->track.pt);
    sc_arena_free(a, t->track.count);
    sc_arena_free(a, t->track.adev);
    sc_arena_free(a, t->track.dev);
    sc_arena_free(a, t->start);
}

static int tries_alloc(sc_arena *a, tries *t, int n)
{
    size_t N = (size_t)n;
    memset(t, 0, sizeof *t);
    t->start = sc_arena_alloc(a, N * sizeof *t->start);
    t->track.dev = t->start ? sc_arena_alloc(a, N * sizeof *t->track.dev) : NULL;
    t->track.adev = t->track.dev ? sc_arena_alloc(a, N * sizeof *t->track.adev) : NULL;
    t->track.count = t->track.adev ? sc_arena_alloc(a, N * sizeof *t->track.count) : NULL;
    t->track.pt = t->track.count ? sc_arena_alloc(a, N * SC_TRACK_MAX * SC_TRACK_STRIDE *
                                                         sizeof *t->track.pt)
                                 : NULL;
    t->forced = t->track.pt ? sc_arena_alloc(a, N * sizeof *t->forced) : NULL;
    t->prev_gid = t->forced ? sc_arena_alloc(a, N * sizeof *t->prev_gid) : NULL;
    t->drift = t->prev_gid ? sc_arena_alloc(a, N * 9 * sizeof *t->drift) : NULL;
    if (t->drift)
        return SC_OK;
    tries_free(a, t);
    return SC_ENOMEM;
}

int sc_groups_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                   sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats)
{
    int n = st->nbodies;
    if (n == 0)
        return SC_OK;
    if (!scr->groups) {
        if (!(scr->groups = group_scratch_create()))
            return SC_ENOMEM;
        scr->groups_free = group_scratch_destroy;
    }
    sc_arena *a = &scr->arena;
    /* Groups are joined by how the bodies move at the frame's start; a
     * body turned by a collision in the frame may still reach another
     * group. So each group keeps where its bodies went (their tracks), and
     * bodies of different groups whose tracks came within touching
     * distance are joined and the frame is stepped again from its start
     * (the groups that did not change give the same bits again). The
     * groups are a function of the bodies alone, so the result does not
     * depend on who ran what. */
    tries t;
    if (tries_alloc(a, &t, n) != SC_OK)
        return SC_ENOMEM;
    sc_body *start = t.start;
    sc_track track = t.track;
    int *forced = t.forced, *prev_gid = t.prev_gid;
    double *drift = t.drift;
    memcpy(start, st->bodies, (size_t)n * sizeof *start);
    /* every body's drift from the frame's start: the joins and the check */
    for (int i = 0; i < n; i++) {
        forced[i] = i;
        if (start[i].inv_mass > 0)
            sc_body_drift(cfg, &start[i], &drift[9 * i]);
    }
    int rc = SC_OK;
    sc_group_out *prev = NULL;    /* the last try's outputs, by its groups */
    int prev_ng = 0;
    for (int round = 0; rc == SC_OK; round++) {
        double t0 = sc_cpu_now();
        sc_groups g;
        rc = groups_alloc(a, &g, n, st->contacts_valid ? st->ncontacts : 0);
        /* joined by the states at the frame's start (a try's groups
         * have moved st's bodies on) */
        sc_frame_state st0 = *st;
        st0.bodies = start;
        if (rc == SC_OK)
            rc = build_groups(cfg, &st0, scr->groups, &g, drift, dt, ex->runner, forced);
        int ng = rc == SC_OK ? g.ngroups : 0;
        sc_group_out *out = rc == SC_OK ? sc_alloc_array((size_t)ng + 1, sizeof *out) : NULL;
        unsigned char *todo = out ? malloc((size_t)ng + 1) : NULL;
        if (rc == SC_OK && !todo)
            rc = SC_ENOMEM;
        if (rc == SC_OK) {
            memset(out, 0, ((size_t)ng + 1) * sizeof *out);
            /* a group of the last try that is a group again keeps what it
             * did (the same inputs give the same bits); the others start
             * again from the frame's start */
            int *size = prev ? calloc((size_t)prev_ng + 1, sizeof *size) : NULL;
            unsigned char *kept = prev ? calloc((size_t)prev_ng + 1, 1) : NULL;
            if (prev && (!size || !kept))
                rc = SC_ENOMEM;
            for (int i = 0; size && i < n; i++)
                if (prev_gid[i] >= 0)
                    size[prev_gid[i]]++;
            for (int k = 0; rc == SC_OK && k < ng; k++) {
                int m0 = g.members[g.start[k]], nm = g.start[k + 1] - g.start[k];
                int q = prev ? prev_gid[m0] : -1;
                int same = q >= 0 && size[q] == nm;
                for (int j = g.start[k]; same && j < g.start[k + 1]; j++)
                    same = prev_gid[g.members[j]] == q;
                todo[k] = !same;
                if (same) {
                    out[k] = prev[q];
                    prev[q].contacts = NULL;
                    kept[q] = 1;
                } else if (prev) {
                    for (int j = g.start[k]; j < g.start[k + 1]; j++)
                        st->bodies[g.members[j]] = start[g.members[j]];
                    stats->frame.sched.group_retries++;
                }
            }
            /* the groups of the last try that are not groups again: their
             * work took its time (the scheduler's and Table 1's figures) */
            for (int q = 0; rc == SC_OK && kept && q < prev_ng; q++)
                if (!kept[q]) {
                    sc_stats_add_work(stats, &prev[q].stats);
                    for (int s = 0; s < SC_STAGE_COUNT; s++)
                        stats->frame.sched.retry_s += prev[q].stats.frame.stage_s[s];
                }
            free(kept);
            free(size);
        }
        for (int k = 0; prev && k < prev_ng; k++)
            free(prev[k].contacts);
        free(prev);
        prev = NULL;
        sc_stage_add(stats, SC_STAGE_BROADPHASE, t0);
        if (rc == SC_OK)
            rc = step_groups(cfg, st, dt, scr, ex, stats, &g, out, &track, todo);
        int met = 0;
        if (rc == SC_OK) {
            t0 = sc_cpu_now();
            met = check_groups(cfg, start, st->bodies, n, scr->groups, &g, &track, drift, dt,
                               ex->runner, forced);
            sc_stage_add(stats, SC_STAGE_BROADPHASE, t0);
            if (met < 0)
                rc = met;
        }
        if (rc == SC_OK && met == 0) {
            for (int k = 0; k < ng; k++)
                sc_stats_add_frame(stats, &out[k].stats);
            rc = merge_contacts(a, st, out, ng);
        }
        if (rc == SC_OK && met > 0) {
            /* again, with the pairs that met joined */
            prev = out;
            prev_ng = ng;
            memcpy(prev_gid, g.gid, (size_t)n * sizeof *prev_gid);
        } else {
            for (int k = 0; out && k < ng; k++)
                free(out[k].contacts);
            free(out);
        }
        free(todo);
        groups_free(a, &g);
        if (rc != SC_OK || met == 0)
            break;
    }
    for (int k = 0; prev && k < prev_ng; k++)
        free(prev[k].contacts);
    free(prev);
    tries_free(a, &t);
    if (a->high > stats->total.arena_bytes)
        stats->total.arena_bytes = a->high;
    if (rc != SC_OK)
        return rc;
    stats->frame.detect.contacts = st->ncontacts;
    for (int i = 0; i < n; i++) {
        v3_set(st->bodies[i].force, 0, 0, 0);
        v3_set(st->bodies[i].torque, 0, 0, 0);
    }
    st->contacts_valid = 1;
    return SC_OK;
}
