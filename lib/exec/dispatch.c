/* dispatch.c - the executor over nodes (docs/DESIGN.md section 5): a
 * job's units cut and costed, assigned by the scheduler, submitted, waited
 * for, learned from, and accounted in the frame's statistics. Outputs are merged by the stages in
 * unit order, so the result does not depend on who ran what. */
#include <limits.h>
#include <stdlib.h>

#include "exec.h"

#define UNITS_PER_NODE 8      /* pair units per node and job (balance) */
#define MAX_UNIT_PAIRS 256    /* pairs per unit at most */
#define GROUP_CONTACTS 24     /* small islands share a unit up to this */

/* Wire sizes (the transfer estimate): header, per pair, per island part. */
#define WIRE_HEADER 32
#define WIRE_PAIR 128
#define WIRE_TOI_PAIR 240
#define WIRE_BODY 400
#define WIRE_CONTACT 112     /* 88 out (its warm-start impulse included), 24 back */

static int grow_units(sc_exec_nodes *x, int n)
{
    return sc_grow((void **)&x->units, &x->unit_cap, n, sizeof *x->units, INT_MAX);
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
static int pair_units(sc_exec_nodes *w, sc_job *job, int nnodes)
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
static int island_units(sc_exec_nodes *w, sc_job *job)
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

static int nodes_width(const sc_exec *ex)
{
    return ((const sc_exec_nodes *)ex)->nnodes;
}

/* A job on the nodes: cut, cost, assign, submit, wait, learn, and account
 * it in st (stage CPU of the other nodes, makespan). */
static int nodes_run(sc_exec *ex, sc_job *job, int stage, sc_stats *st)
{
    sc_exec_nodes *x = (sc_exec_nodes *)ex;
    double t0 = sc_wall_now();
    int nnodes = x->nnodes;
    int rc = SC_OK;
    if (job->kind == SC_UNIT_ISLAND)
        rc = island_units(x, job);
    else if (job->kind != SC_UNIT_GROUP)    /* group units come made */
        rc = pair_units(x, job, x->nlocal + (x->prov.ctx ? x->prov.available(x->prov.ctx) : 0));
    if (rc != SC_OK)
        return rc;
    if (job->nunits == 0)
        return SC_OK;
    sc_sched *s = &x->sched;
    sc_node **nodes = x->nodes;
    rc = sc_sched_assign(s, nodes, job->units, job->nunits);
    if (rc != SC_OK)
        return rc;
    if (x->prov.ctx && (rc = x->prov.job_begin(x->prov.ctx, job)) != SC_OK)
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
    if (x->prov.ctx)
        x->prov.job_end(x->prov.ctx);
    double t2 = sc_wall_now();
    double bound = 0;
    sc_sched_observe(s, job->units, job->nunits, &bound);
    /* CPU of the other nodes is CPU of this stage too (Table 1); group
     * units count their own */
    if (stage >= 0) {
        st->stage_s[stage] += cpu_others;
        st->stage_total_s[stage] += cpu_others;
    }
    st->units += job->nunits;
    st->makespan_s += t2 - t1;
    st->makespan_bound_s += bound;
    for (int i = 0; i < job->nunits; i++) {
        const sc_unit *u = &job->units[i];
        st->collider_warnings += u->messages;
        if (job->kind == SC_UNIT_ISLAND)
            sc_stats_add_solve(st, &u->info);
        if (u->arena_high > st->unit_arena_bytes)
            st->unit_arena_bytes = u->arena_high;
        if (u->rc != SC_OK && rc == SC_OK)
            rc = u->rc;    /* the first in unit order: the same for any assignment */
    }
    st->sched_s += (t1 - t0) + (sc_wall_now() - t2);
    return rc;
}

int sc_exec_nodes_init(sc_exec_nodes *x, int nlocal, int extra)
{
    memset(x, 0, sizeof *x);
    x->base.run = nodes_run;
    x->base.width = nodes_width;
    x->cap = nlocal + extra;
    x->nodes = sc_calloc_array((size_t)x->cap, sizeof *x->nodes);
    x->pool = sc_local_pool_create();
    int rc = x->nodes && x->pool ? sc_sched_init(&x->sched, x->cap) : SC_ENOMEM;
    for (int k = 0; k < nlocal && rc == SC_OK; k++) {
        /* node 0 is the calling thread, the others worker threads */
        x->nodes[k] = sc_node_local_create(x->pool, k, k == 0);
        if (!x->nodes[k])
            return SC_ENOMEM;
        x->nnodes++;
        x->private_ode += sc_node_local_private_ode(x->nodes[k]);
    }
    x->nlocal = x->nnodes;
    return rc;
}

void sc_exec_nodes_add(sc_exec_nodes *x, sc_node *n)
{
    SC_ASSERT(x->nnodes < x->cap);
    x->nodes[x->nnodes++] = n;
}

void sc_exec_nodes_free(sc_exec_nodes *x)
{
    sc_local_pool_stop(x->pool);
    for (int k = 0; k < x->nnodes; k++)
        x->nodes[k]->ops->destroy(x->nodes[k]);
    free(x->nodes);
    sc_local_pool_destroy(x->pool);
    sc_sched_free(&x->sched);
    free(x->units);
    memset(x, 0, sizeof *x);
}
