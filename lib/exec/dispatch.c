/* dispatch.c - a job through the world's nodes: units cut and costed,
 * assigned by the scheduler, submitted, waited for, learned from, and
 * accounted in the frame's statistics. Outputs are merged by the stages in
 * unit order, so the result does not depend on who ran what. */
#include <limits.h>
#include <stdlib.h>

#include "cluster.h"
#include "sc_internal.h"

#define UNITS_PER_NODE 8      /* pair units per node and job (balance) */
#define MAX_UNIT_PAIRS 256    /* pairs per unit at most */
#define GROUP_CONTACTS 24     /* small islands share a unit up to this */

/* Wire sizes (the transfer estimate): header, per pair, per island part. */
#define WIRE_HEADER 32
#define WIRE_PAIR 128
#define WIRE_TOI_PAIR 240
#define WIRE_BODY 400
#define WIRE_CONTACT 64

static int grow_units(sc_world *w, int n)
{
    return sc_grow((void **)&w->units, &w->unit_cap, n, sizeof *w->units, INT_MAX);
}

static void unit_init(sc_unit *u, int kind, int first, int count, double cost, double f1,
                      double f2, size_t bytes)
{
    memset(u, 0, sizeof *u);
    u->kind = kind;
    u->first = first;
    u->count = count;
    u->cost = cost;
    u->feat[0] = 1;
    u->feat[1] = f1;
    u->feat[2] = f2;
    u->bytes = bytes;
}

/* Pairs cut into contiguous units of about equal estimated cost: a few per
 * node, so the scheduler has something to balance. */
static int pair_units(sc_world *w, sc_job *job, int nnodes)
{
    double total = 0;
    for (int i = 0; i < job->npairs; i++)
        total += sc_pair_cost(job->pairs[i].sa, job->pairs[i].sb);
    int want = nnodes > 1 ? UNITS_PER_NODE * nnodes : 1;
    double target = total / want;
    int rc = grow_units(w, want + job->npairs / MAX_UNIT_PAIRS + 2);
    if (rc != SC_OK)
        return rc;
    size_t per = job->kind == SC_UNIT_TOI ? WIRE_TOI_PAIR : WIRE_PAIR;
    int n = 0, first = 0;
    double cost = 0, touching = 0;
    for (int i = 0; i < job->npairs; i++) {
        const sc_unit_pair *p = &job->pairs[i];
        double c = sc_pair_cost(p->sa, p->sb);
        cost += c;
        /* pairs in contact cost far more than pairs that only came near
         * (TOI pairs all touch): a model feature of their own */
        touching += (job->kind == SC_UNIT_TOI || p->touching) ? c : 0;
        int count = i + 1 - first;
        if (cost >= target || count == MAX_UNIT_PAIRS || i + 1 == job->npairs) {
            if (n == w->unit_cap && (rc = grow_units(w, n + 1)) != SC_OK)
                return rc;
            unit_init(&w->units[n++], job->kind, first, count, cost, touching,
                      cost - touching, WIRE_HEADER + per * (size_t)count);
            first = i + 1;
            cost = touching = 0;
        }
    }
    job->units = w->units;
    job->nunits = n;
    return SC_OK;
}

/* Islands cost contacts^3 (the paper). One unit per island of at least
 * GROUP_CONTACTS contacts; smaller neighbours (most are one body on the
 * floor) share a unit up to that many contacts, each still solved on its
 * own, so that a thousand tiny islands are not a thousand units to cost,
 * sort, time and learn from. Grouping does not depend on the nodes. */
static int island_units(sc_world *w, sc_job *job)
{
    const sc_islands *is = job->islands;
    int rc = grow_units(w, is->count);
    if (rc != SC_OK)
        return rc;
    int n = 0;
    for (int i = 0; i < is->count;) {
        int first = i, nc = 0, nb = 0;
        double cost = 0;
        do {
            double c = is->contact_start[i + 1] - is->contact_start[i];
            nc += (int)c;
            nb += is->body_start[i + 1] - is->body_start[i] + 1;
            cost += c * c * c;
            i++;
        } while (i < is->count && nc < GROUP_CONTACTS &&
                 nc + is->contact_start[i + 1] - is->contact_start[i] <= GROUP_CONTACTS);
        sc_unit *u = &w->units[n++];
        unit_init(u, SC_UNIT_ISLAND, first, nc, cost, nc, cost,
                  WIRE_HEADER + WIRE_BODY * (size_t)nb + WIRE_CONTACT * (size_t)nc);
        u->islands = i - first;
    }
    job->units = w->units;
    job->nunits = n;
    return SC_OK;
}

/* A group's sub-world running as one unit: everything on this thread. */
static int run_inline(sc_world *w, sc_job *job)
{
    int rc = SC_OK;
    for (int i = 0; i < job->nunits; i++) {
        sc_unit *u = &job->units[i];
        sc_unit_run(w->inline_np, job, u);
        w->stats.collider_warnings += u->messages;
        if (u->rc != SC_OK && rc == SC_OK)
            rc = u->rc;
    }
    w->stats.units += job->nunits;
    return rc;
}

int sc_job_run(sc_world *w, sc_job *job, int stage)
{
    double t0 = sc_wall_now();
    /* a sub-world (group.c) uses its parent's nodes and scheduler */
    sc_world *top = w->parent ? w->parent : w;
    int nnodes = w->inline_np ? 1 : top->nnodes;
    int rc = SC_OK;
    if (job->kind == SC_UNIT_ISLAND)
        rc = island_units(w, job);
    else if (job->kind != SC_UNIT_GROUP)    /* group units come made */
        rc = pair_units(w, job, w->inline_np ? 1 : top->nlocal + top->stats.daemons);
    if (rc != SC_OK)
        return rc;
    if (job->nunits == 0)
        return SC_OK;
    if (w->inline_np)
        return run_inline(w, job);
    sc_sched *s = &top->sched;
    sc_node **nodes = top->nodes;
    rc = sc_sched_assign(s, nodes, job->units, job->nunits);
    if (rc != SC_OK)
        return rc;
    if (top->cluster && (rc = sc_cluster_begin(top->cluster, job)) != SC_OK)
        return rc;
    double t1 = sc_wall_now();
    /* every list is in place before any node can look for more */
    for (int k = 0; k < nnodes; k++) {
        int cnt = s->start[k + 1] - s->start[k];
        if (cnt > 0)
            rc = nodes[k]->ops->submit(nodes[k], job, &s->assigned[s->start[k]], cnt);
        SC_ASSERT(rc == SC_OK);
    }
    double cpu_others = 0;
    for (int k = 0; k < nnodes; k++) {
        if (s->start[k + 1] == s->start[k])
            continue;
        double cpu = 0;
        nodes[k]->ops->wait(nodes[k], &cpu);
        if (k > 0)
            cpu_others += cpu;
    }
    if (top->cluster)
        sc_cluster_end(top->cluster);
    double t2 = sc_wall_now();
    double bound = 0;
    sc_sched_observe(s, job->units, job->nunits, &bound);
    /* CPU of the other nodes is CPU of this stage too (Table 1); group
     * units count their own */
    if (stage >= 0) {
        w->stats.stage_s[stage] += cpu_others;
        w->stats.stage_total_s[stage] += cpu_others;
    }
    w->stats.units += job->nunits;
    w->stats.makespan_s += t2 - t1;
    w->stats.makespan_bound_s += bound;
    for (int i = 0; i < job->nunits; i++) {
        const sc_unit *u = &job->units[i];
        w->stats.collider_warnings += u->messages;
        if (u->rc != SC_OK && rc == SC_OK)
            rc = u->rc;    /* the first in unit order: the same for any assignment */
    }
    w->stats.sched_s += (t1 - t0) + (sc_wall_now() - t2);
    return rc;
}
