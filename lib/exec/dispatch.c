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
                      cost - touching, sc_unit_bytes_pairs(job->kind, count));
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
                  sc_unit_bytes_islands(nb, nc));
        u->islands = i - first;
    }
    job->units = w->units;
    job->nunits = n;
    return SC_OK;
}

/* The nodes that can take units now: the local ones and the daemons
 * heard (not the free slots). */
static int nodes_width(const sc_exec *ex)
{
    const sc_exec_nodes *x = (const sc_exec_nodes *)ex;
    return x->nlocal + (x->prov.ctx ? x->prov.available(x->prov.ctx) : 0);
}

/* Cut a job into units (GROUP jobs come cut). */
static int cut(sc_exec_nodes *x, sc_job *job)
{
    if (job->kind == SC_UNIT_ISLAND)
        return island_units(x, job);
    if (job->kind != SC_UNIT_GROUP)
        return pair_units(x, job, nodes_width(&x->base));
    return SC_OK;
}

/* Submit nodes [k0, k1) their lists (assigned[start[k] .. start[k + 1])). */
static void submit_nodes(sc_exec_nodes *x, const sc_job *job, const int *assigned,
                         const int *start, int k0, int k1)
{
    for (int k = k0; k < k1; k++) {
        int cnt = start[k + 1] - start[k];
        int rc = cnt > 0 ? x->nodes[k]->ops->submit(x->nodes[k], job, &assigned[start[k]], cnt)
                         : SC_OK;
        SC_ASSERT(rc == SC_OK);
        (void)rc;
    }
}

/* Wait for every node with a list; the CPU seconds of the nodes but the
 * calling thread. */
static double wait_nodes(sc_exec_nodes *x, const int *start)
{
    double cpu_others = 0;
    for (int k = 0; k < x->nnodes; k++) {
        if (start[k + 1] == start[k])
            continue;
        double cpu = 0;
        x->nodes[k]->ops->wait(x->nodes[k], &cpu);
        if (k > 0)
            cpu_others += cpu;
    }
    return cpu_others;
}

/* sc_stats.frame.sched.unit_work_by_density_s's bin of bytes_per_s: from 2^i MB/s. */
static int density_bin(double bytes_per_s)
{
    int bin = 0;
    for (double at = 2e6; bin < SC_STATS_DENSITY_BINS - 1 && bytes_per_s >= at; at *= 2)
        bin++;
    return bin;
}

/* After a job: learn from it (learn 0: its units' times are no one's
 * speed) and account it in st (stage CPU of the other nodes, makespan,
 * scheduling time, the first unit error). */
static int account(sc_exec_nodes *x, sc_job *job, int stage, sc_stats *st, double cpu_others,
                   double makespan_s, double sched_s, int learn)
{
    double t2 = sc_wall_now();
    double bound = 0;
    int rc = SC_OK;
    if (learn)
        sc_sched_observe(&x->sched, job->units, job->nunits, &bound);
    /* CPU of the other nodes is CPU of this stage too (Table 1); group
     * units count their own */
    if (stage >= 0) {
        st->frame.stage_s[stage] += cpu_others;
        st->total.stage_s[stage] += cpu_others;
    }
    st->frame.sched.units += job->nunits;
    st->frame.sched.makespan_s += makespan_s;
    st->frame.sched.makespan_bound_s += bound;
    st->frame.sched.jobs++;
    double work = 0, largest = 0;
    for (int i = 0; i < job->nunits; i++) {
        const sc_unit *u = &job->units[i];
        work += u->time_s;
        if (u->time_s > largest)
            largest = u->time_s;
        st->frame.sched.unit_bytes += (double)u->bytes;
        if (u->time_s > 0)
            st->frame.sched.unit_work_by_density_s[density_bin((double)u->bytes / u->time_s)] +=
                u->time_s;
        st->frame.detect.collider_warnings += u->messages;
        if (job->kind == SC_UNIT_ISLAND)
            sc_stats_add_solve(st, &u->info);
        if (u->arena_high > st->total.unit_arena_bytes)
            st->total.unit_arena_bytes = u->arena_high;
        if (u->rc != SC_OK && rc == SC_OK)
            rc = u->rc;    /* the first in unit order: the same for any assignment */
    }
    st->frame.sched.unit_work_s += work;
    /* the least makespan on n equal nodes with free communication (the
     * cluster model's input, bench_cluster -p model) */
    int divisible = job->kind == SC_UNIT_COLLIDE || job->kind == SC_UNIT_TOI;
    for (int k = 0; k < SC_STATS_IDEAL_NODES; k++) {
        double share = work / (k + 1);
        st->frame.sched.ideal_makespan_s[k] += divisible || share > largest ? share : largest;
    }
    st->frame.sched.sched_s += sched_s + (sc_wall_now() - t2);
    return rc;
}

/* A job on the nodes: cut, cost, assign, submit, wait, learn, and account
 * it in st (stage CPU of the other nodes, makespan). */
static int nodes_run(sc_exec *ex, sc_job *job, int stage, sc_stats *st)
{
    sc_exec_nodes *x = (sc_exec_nodes *)ex;
    double t0 = sc_wall_now();
    int rc = cut(x, job);
    if (rc != SC_OK || job->nunits == 0)
        return rc;
    sc_sched *s = &x->sched;
    rc = sc_sched_assign(s, x->nodes, job->units, job->nunits);
    if (rc != SC_OK)
        return rc;
    st->frame.remote.refused += s->refused;
    if (x->prov.ctx && (rc = x->prov.job_begin(x->prov.ctx, job)) != SC_OK)
        return rc;
    double t1 = sc_wall_now();
    /* every list is in place before any node can look for more */
    submit_nodes(x, job, s->assigned, s->start, 0, x->nnodes);
    double cpu_others = wait_nodes(x, s->start);
    if (x->prov.ctx)
        x->prov.job_end(x->prov.ctx);
    double span = sc_wall_now() - t1;
    x->span_s += span;
    return account(x, job, stage, st, cpu_others, span, t1 - t0, 1);
}

/* start(): assign with the local nodes busy for home_busy_s, send the
 * remote nodes their units now and park the job with the provider; the
 * local lists wait for finish(). The assignment is kept here (the
 * scheduler's lists serve the jobs run in between), and the remote nodes
 * are marked busy until their predicted finish, so that those jobs send
 * them only what still finishes sooner there. When no remote node gets a
 * unit, finish() runs the job as run() would. */
static int nodes_start(sc_exec *ex, sc_job *job, double home_busy_s)
{
    sc_exec_nodes *x = (sc_exec_nodes *)ex;
    SC_ASSERT(!x->pend.job);
    double t0 = sc_wall_now();
    int rc = cut(x, job);
    x->pend.job = rc == SC_OK ? job : NULL;
    x->pend.whole = 1;
    if (rc != SC_OK || job->nunits == 0 || !x->prov.ctx || x->nnodes == x->nlocal)
        return rc;
    sc_sched *s = &x->sched;
    for (int k = 0; k < x->nlocal; k++)
        s->nodes[k].busy_until = home_busy_s > 0 ? t0 + home_busy_s : 0;
    rc = sc_sched_assign(s, x->nodes, job->units, job->nunits);
    for (int k = 0; k < x->nlocal; k++)
        s->nodes[k].busy_until = 0;
    x->pend.refused = s->refused;
    int n = x->nnodes;
    if (rc == SC_OK && s->start[n] == s->start[x->nlocal])
        return SC_OK;           /* nothing goes out: all at finish() */
    if (rc == SC_OK && sc_grow((void **)&x->pend.assigned, &x->pend.assigned_cap, job->nunits,
                               sizeof *x->pend.assigned, INT_MAX) != SC_OK)
        rc = SC_ENOMEM;
    if (rc == SC_OK && (rc = x->prov.job_begin(x->prov.ctx, job)) == SC_OK)
        x->pend.whole = 0;
    if (rc != SC_OK) {
        x->pend.job = NULL;
        return rc;
    }
    memcpy(x->pend.assigned, s->assigned, (size_t)job->nunits * sizeof *x->pend.assigned);
    memcpy(x->pend.start, s->start, (size_t)(n + 1) * sizeof *x->pend.start);
    for (int k = 0; k < n; k++)
        x->pend.cap[k] = s->nodes[k].job_cap;
    double t1 = sc_wall_now();
    submit_nodes(x, job, x->pend.assigned, x->pend.start, x->nlocal, n);
    x->prov.job_park(x->prov.ctx);
    double t2 = sc_wall_now();
    for (int k = x->nlocal; k < n; k++)
        if (x->pend.start[k + 1] > x->pend.start[k])
            s->nodes[k].busy_until = t1 + s->nodes[k].ready;
    x->pend.submit_s = t2 - t1;
    x->pend.sched_s = t1 - t0;
    x->span_s += t2 - t1;
    return SC_OK;
}

static int nodes_finish(sc_exec *ex, sc_job *job, int stage, sc_stats *st)
{
    sc_exec_nodes *x = (sc_exec_nodes *)ex;
    SC_ASSERT(x->pend.job == job);
    x->pend.job = NULL;
    if (x->pend.whole)
        return nodes_run(ex, job, stage, st);
    sc_sched *s = &x->sched;
    int n = x->nnodes;
    x->prov.job_resume(x->prov.ctx, job);
    st->frame.remote.refused += x->pend.refused;
    double t1 = sc_wall_now();
    submit_nodes(x, job, x->pend.assigned, x->pend.start, 0, x->nlocal);
    double cpu_others = wait_nodes(x, x->pend.start);
    x->prov.job_end(x->prov.ctx);
    for (int k = 0; k < n; k++) {
        s->nodes[k].busy_until = 0;
        s->nodes[k].job_cap = x->pend.cap[k];   /* what it offered for this job */
    }
    double span = sc_wall_now() - t1;
    x->span_s += span;
    return account(x, job, stage, st, cpu_others, x->pend.submit_s + span, x->pend.sched_s, 1);
}

/* background(): only with worker threads and no remote nodes (those get
 * theirs by start()), and no job started. */
static int nodes_background(sc_exec *ex, sc_job *job)
{
    sc_exec_nodes *x = (sc_exec_nodes *)ex;
    /* background units are for idle threads that poll (5.3) */
    if (x->prov.ctx || x->nlocal < 2 || !sc_local_pool_spins(x->pool) || x->pend.job ||
        job->nunits == 0 || cut(x, job) != SC_OK)
        return 0;
    sc_local_pool_background(x->pool, job);
    return 1;
}

static int nodes_drain(sc_exec *ex, sc_job *job, sc_stats *st)
{
    sc_exec_nodes *x = (sc_exec_nodes *)ex;
    double t0 = sc_wall_now();
    sc_local_pool_drain(x->pool);
    x->span_s += sc_wall_now() - t0;
    for (int i = 0; i < job->nunits; i++)
        st->frame.sched.units_background += job->units[i].node != 0;
    /* the units' times are not the scheduler's to learn from: they ran
     * in gaps, not as assigned */
    return account(x, job, -1, st, 0, 0, 0, 0);
}

int sc_exec_nodes_init(sc_exec_nodes *x, int nlocal, int extra, double budget)
{
    memset(x, 0, sizeof *x);
    x->base.run = nodes_run;
    x->base.width = nodes_width;
    x->base.start = nodes_start;
    x->base.finish = nodes_finish;
    x->base.background = nodes_background;
    x->base.drain = nodes_drain;
    x->cap = nlocal + extra;
    x->nodes = sc_calloc_array((size_t)x->cap, sizeof *x->nodes);
    x->pend.start = sc_calloc_array((size_t)x->cap + 1, sizeof *x->pend.start);
    x->pend.cap = sc_calloc_array((size_t)x->cap, sizeof *x->pend.cap);
    if (!x->pend.start || !x->pend.cap)
        return SC_ENOMEM;
    x->pool = sc_local_pool_create();
    /* idle threads poll for work only where each of them has a CPU: under
     * a smaller quota (or affinity mask) polling takes the working ones'
     * share (docs/DESIGN.md 5.3) */
    x->cpu_budget = budget;
    sc_local_pool_set_spin(x->pool, budget >= nlocal);
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
    x->base.runner = rc == SC_OK ? sc_local_pool_runner(x->pool) : NULL;
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
    free(x->pend.assigned);
    free(x->pend.start);
    free(x->pend.cap);
    memset(x, 0, sizeof *x);
}
