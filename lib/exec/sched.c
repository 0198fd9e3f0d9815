/* sched.c - the scheduler of the paper (docs/DESIGN.md 6): each unit's
 * cost estimated, the units sorted longest first, each given to the node
 * predicted to finish it soonest. Beyond the paper, a least-squares model
 * per node and unit kind predicts unit times better than cost / speed, the
 * finish estimate counts a node's transfer time and latency (so a job too
 * small to share stays on the calling thread), and each job's makespan is
 * compared with a lower bound. */
#include <stdlib.h>

#include <gsl/gsl_matrix.h>
#include <gsl/gsl_multifit.h>
#include <gsl/gsl_vector.h>

#include "exec.h"

/* The paper: estimate each unit's cost (pairs: product of polygon counts;
 * islands: contacts^3), sort the units longest first, and give each to the
 * node predicted to finish it soonest, a node's speed being measured from
 * its recent responses (cost per second, averaged over recent jobs).
 *
 * Beyond it: per node and unit kind, a least-squares model of the measured
 * unit time on its features (1 and two costs: for pairs, of those touching
 * at the last detection and of the rest; for islands, contacts and
 * contacts^3), refitted with GSL over the
 * last SC_MODEL_WINDOW units, predicts better than cost / speed (a unit's
 * fixed overhead, pairs that miss early); the finish estimate includes the
 * node's transfer time and its measured latency (waking a thread, a round
 * trip to a daemon), so a job too small to be worth sharing stays on the
 * calling thread; and each job's makespan is compared with a lower
 * bound (total work over total speed, and the largest unit). */

#define SPEED_KEEP 0.7        /* EWMA weight of the old speed per job */
#define MIN_FIT 8             /* samples before a model is used */
#define REFIT 64              /* new samples between fits */
#define REFIT_JOBS 8          /* jobs between fits of a fitted model */
#define IDLE_DRIFT 0.2        /* per idle job, towards the mean speed */
#define IDLE_FORGET 4         /* idle jobs before a node's model is set aside */

typedef struct sort_key {
    double cost;
    int idx;
} sort_key;

int sc_sched_init(sc_sched *s, int nnodes)
{
    memset(s, 0, sizeof *s);
    s->nodes = sc_calloc_array((size_t)nnodes, sizeof *s->nodes);
    s->start = sc_calloc_array((size_t)nnodes + 1, sizeof *s->start);
    s->cursor = sc_calloc_array((size_t)nnodes, sizeof *s->cursor);
    if (!s->nodes || !s->start || !s->cursor) {
        sc_sched_free(s);
        return SC_ENOMEM;
    }
    s->nnodes = nnodes;
    s->use_models = 1;
    s->ship_share = SC_SHIP_SHARE_DEFAULT;
    s->min_gain = SC_MIN_GAIN_DEFAULT;
    s->home_capacity = 1;
    return SC_OK;
}

void sc_sched_free(sc_sched *s)
{
    free(s->nodes);
    free(s->start);
    free(s->keys);
    free(s->assigned);
    free(s->cursor);
    memset(s, 0, sizeof *s);
}

/* A node's speed for a kind; before it has answered, the mean of those
 * measured (or 1: all alike). */
static double speed_of(const sc_sched *s, int k, int kind)
{
    if (s->nodes[k].measured[kind])
        return s->nodes[k].speed[kind];
    double sum = 0;
    int n = 0;
    for (int i = 0; i < s->nnodes; i++)
        if (s->nodes[i].measured[kind]) {
            sum += s->nodes[i].speed[kind];
            n++;
        }
    return n ? sum / n : 1.0;
}

/* Predicted time from a node's model, or cost / speed. */
static inline double predict(const sc_sched *s, const sc_sched_node *nd, double speed,
                             const sc_unit *u)
{
    const sc_cost_model *m = &nd->model[u->kind];
    if (s->use_models && m->ok) {
        double t = m->c[0] * u->feat[0] + m->c[1] * u->feat[1] + m->c[2] * u->feat[2];
        if (t > 0 && isfinite(t))
            return t;
    }
    return u->cost / speed;
}

double sc_sched_predict(const sc_sched *s, int k, const sc_unit *u)
{
    return predict(s, &s->nodes[k], speed_of(s, k, u->kind), u);
}

static int cmp_key(const void *x, const void *y)
{
    const sort_key *a = x, *b = y;
    if (a->cost != b->cost)
        return a->cost < b->cost ? 1 : -1;    /* longest first */
    return (a->idx > b->idx) - (a->idx < b->idx);
}

/* What shipping unit u to node nd costs the calling thread (home_s). */
static double ship_s(const sc_sched_node *nd, const sc_unit *u)
{
    return nd->job_home0 + nd->job_home1 * (double)u->bytes;
}

/* One greedy assignment; nodes refused by the job-level rule
 * (sc_sched_node.job_refused) get nothing. */
static int assign(sc_sched *s, sc_node *const *nodes, sc_unit *units, int n)
{
    if (n > s->order_cap) {
        int cap = n > 2 * s->order_cap ? n : 2 * s->order_cap;
        void *o = realloc(s->keys, (size_t)cap * sizeof(sort_key));
        if (!o)
            return SC_ENOMEM;
        s->keys = o;
        int *a = realloc(s->assigned, (size_t)cap * sizeof *a);
        if (!a)
            return SC_ENOMEM;
        s->assigned = a;
        s->order_cap = cap;
    }
    sort_key *key = s->keys;
    int kind = n > 0 ? units[0].kind : 0;
    /* before a node has answered: the mean of those measured (speed_of) */
    double sum = 0;
    int nmeasured = 0;
    for (int k = 0; k < s->nnodes; k++)
        if (s->nodes[k].measured[kind]) {
            sum += s->nodes[k].speed[kind];
            nmeasured++;
        }
    double fallback = nmeasured ? sum / nmeasured : 1.0;
    double now = sc_wall_now();
    for (int k = 0; k < s->nnodes; k++) {
        sc_sched_node *nd = &s->nodes[k];
        /* a node still busy with a started job's units is ready later */
        nd->ready = nd->busy_until > now ? nd->busy_until - now : 0;
        nd->job_cap = k == 0                     ? s->home_capacity
                      : nd->job_refused          ? 0
                      : !nodes[k]->ops->capacity ? 1.0
                                                 : nodes[k]->ops->capacity(nodes[k], kind);
        nd->job_speed = (nd->measured[kind] ? nd->speed[kind] : fallback) *
                        (nd->job_cap > 0 ? nd->job_cap : 1.0);
        nd->job_latency = s->nnodes > 1 ? nodes[k]->ops->latency_s(nodes[k]) : 0;
        /* transfer time as fixed + per byte, asked once per job */
        nd->job_tr0 = s->nnodes > 1 ? nodes[k]->ops->transfer_s(nodes[k], 0) : 0;
        nd->job_tr1 = s->nnodes > 1
                          ? (nodes[k]->ops->transfer_s(nodes[k], 1 << 20) - nd->job_tr0) / (1 << 20)
                          : 0;
        const sc_node_ops *ops = nodes[k]->ops;
        nd->job_home0 = s->nnodes > 1 && k > 0 && ops->home_s ? ops->home_s(nodes[k], 0) : 0;
        nd->job_home1 = s->nnodes > 1 && k > 0 && ops->home_s
                            ? (ops->home_s(nodes[k], 1 << 20) - nd->job_home0) / (1 << 20)
                            : 0;
    }
    /* the estimate to sort by: the calling thread's fitted model once it
     * has one (it always has measurements), else the paper's cost. Units
     * below 1/64 of a node's fair share are not worth sorting: they keep
     * their order after the sorted ones (and idle nodes take them anyway) */
    double total = 0;
    for (int i = 0; i < n; i++) {
        key[i].cost = s->nnodes > 1 ? predict(s, &s->nodes[0], s->nodes[0].job_speed, &units[i])
                                    : 0;
        key[i].idx = i;
        total += key[i].cost;
    }
    double small = total / (64.0 * s->nnodes);
    int nbig = 0, nsmall = 0;
    for (int i = 0; i < n && s->nnodes > 1; i++) {
        if (key[i].cost >= small)
            key[nbig++] = key[i];    /* nbig <= i: not yet read ones stay */
        else
            s->assigned[nsmall++] = key[i].idx;    /* scratch until below */
    }
    for (int j = 0; j < nsmall; j++) {
        key[nbig + j].cost = 0;
        key[nbig + j].idx = s->assigned[j];
    }
    if (nbig > 1)
        qsort(key, (size_t)nbig, sizeof *key, cmp_key);
    memset(s->start, 0, (size_t)(s->nnodes + 1) * sizeof *s->start);
    for (int i = 0; i < n; i++) {
        sc_unit *u = &units[key[i].idx];
        int best = 0;
        double best_t = INFINITY;
        double at_home = s->nnodes > 1 ? predict(s, &s->nodes[0], s->nodes[0].job_speed, u) : 0;
        for (int k = 0; k < s->nnodes && s->nnodes > 1; k++) {
            const sc_sched_node *nd = &s->nodes[k];
            if (!(nd->job_cap > 0))
                continue;    /* gone, owner-busy, or not for this kind */
            /* worth it only when shipping it costs the calling thread at
             * most ship_share of computing it there (docs/DESIGN.md 6.2) */
            if (k > 0 && s->ship_share >= 0 && ship_s(nd, u) > s->ship_share * at_home)
                continue;
            /* the first unit a node gets in a job pays its latency */
            double t = nd->ready + nd->job_tr0 + nd->job_tr1 * (double)u->bytes +
                       predict(s, nd, nd->job_speed, u) + (s->start[k + 1] ? 0 : nd->job_latency);
            if (t < best_t) {
                best_t = t;
                best = k;
            }
        }
        if (best_t == INFINITY)    /* no node would take it: home */
            best_t = s->nodes[0].ready + predict(s, &s->nodes[0], s->nodes[0].job_speed, u);
        if (s->shuffle) {
            /* tests: any assignment must give the same result */
            s->shuffle ^= s->shuffle << 13;
            s->shuffle ^= s->shuffle >> 7;
            s->shuffle ^= s->shuffle << 17;
            best = (int)(s->shuffle % (uint64_t)s->nnodes);
            if (!(s->nodes[best].job_cap > 0))
                best = 0;
        }
        u->predict_s = s->nnodes > 1 ? predict(s, &s->nodes[best], s->nodes[best].job_speed, u) : 0;
        if (s->nnodes > 1)
            s->nodes[best].ready = best_t;
        if (best > 0)                   /* the calling thread ships it */
            s->nodes[0].ready += ship_s(&s->nodes[best], u);
        u->node = best;
        s->start[best + 1]++;
    }
    /* per-node lists, each in longest-first order */
    s->start[0] = 0;
    for (int k = 0; k < s->nnodes; k++)
        s->start[k + 1] += s->start[k];
    memcpy(s->cursor, s->start, (size_t)s->nnodes * sizeof *s->cursor);
    for (int i = 0; i < n; i++) {
        int idx = key[i].idx;
        s->assigned[s->cursor[units[idx].node]++] = idx;
    }
    return SC_OK;
}

/* The job-level worth-it rule (docs/DESIGN.md 6.2): a node whose share of
 * the job is predicted to take less than min_gain of its measured round
 * trips would save less than its messages cost (packing, sealing, the
 * barrier's wait, the prediction's error over a share that small), so it
 * gets none and the job is assigned again without it; a node whose round
 * trip is not known yet is exempt (how else would it be measured). */
int sc_sched_assign(sc_sched *s, sc_node *const *nodes, sc_unit *units, int n)
{
    s->refused = 0;
    int rule = 0;
    for (int k = 0; k < s->nnodes; k++) {
        sc_sched_node *nd = &s->nodes[k];
        nd->job_refused = 0;
        /* asked only where the rule applies: a daemon's is a median */
        nd->job_rt = k > 0 && s->min_gain > 0 && !s->shuffle && nodes[k]->ops->round_trip_s
                         ? nodes[k]->ops->round_trip_s(nodes[k])
                         : 0;
        rule |= nd->job_rt > 0;
    }
    for (;;) {
        int rc = assign(s, nodes, units, n);
        if (rc != SC_OK || !rule)
            return rc;
        int more = 0;
        for (int k = 1; k < s->nnodes; k++) {
            sc_sched_node *nd = &s->nodes[k];
            if (nd->job_refused || !(nd->job_rt > 0) || s->start[k + 1] == s->start[k])
                continue;
            double work = 0;
            for (int j = s->start[k]; j < s->start[k + 1]; j++)
                work += units[s->assigned[j]].predict_s;
            if (work < s->min_gain * nd->job_rt) {
                nd->job_refused = 1;
                s->refused++;
                more = 1;
            }
        }
        if (!more)
            return SC_OK;
    }
}

/* Least squares time = c . (1, count, cost) over the window (GSL, SVD:
 * rank-deficient windows, e.g. all units alike, still give a fit). */
static void fit(sc_cost_model *m)
{
    m->fresh = 0;
    m->jobs = 0;
    if (m->n < MIN_FIT)
        return;
    gsl_matrix_view X = gsl_matrix_view_array(&m->x[0][0], (size_t)m->n, 3);
    gsl_vector_view y = gsl_vector_view_array(m->y, (size_t)m->n);
    gsl_vector *c = gsl_vector_alloc(3);
    gsl_matrix *cov = gsl_matrix_alloc(3, 3);
    gsl_multifit_linear_workspace *ws = gsl_multifit_linear_alloc((size_t)m->n, 3);
    double chisq;
    m->ok = 0;
    if (c && cov && ws && gsl_multifit_linear(&X.matrix, &y.vector, c, cov, &chisq, ws) == 0) {
        for (int i = 0; i < 3; i++)
            m->c[i] = gsl_vector_get(c, (size_t)i);
        m->ok = isfinite(m->c[0]) && isfinite(m->c[1]) && isfinite(m->c[2]);
    }
    if (ws)
        gsl_multifit_linear_free(ws);
    if (cov)
        gsl_matrix_free(cov);
    if (c)
        gsl_vector_free(c);
}

void sc_sched_observe(sc_sched *s, const sc_unit *units, int n, double *bound_s)
{
    *bound_s = 0;
    if (n == 0)
        return;
    if (s->nnodes == 1 && !s->learn_alone) {
        /* nothing to choose between: no speeds or models to learn, and
         * the bound is all the work */
        for (int i = 0; i < n; i++)
            *bound_s += units[i].time_s;
        return;
    }
    int kind = units[0].kind;
    for (int k = 0; k < s->nnodes; k++) {
        s->nodes[k].busy = 0;
        s->nodes[k].done = 0;
    }
    for (int i = 0; i < n; i++) {
        const sc_unit *u = &units[i];
        sc_sched_node *nd = &s->nodes[u->node];
        nd->busy += u->time_s;
        nd->done += u->cost;
        sc_cost_model *m = &nd->model[kind];
        memcpy(m->x[m->pos], u->feat, sizeof u->feat);
        m->y[m->pos] = u->time_s;
        m->pos = (m->pos + 1) % SC_MODEL_WINDOW;
        if (m->n < SC_MODEL_WINDOW)
            m->n++;
        m->fresh++;
    }
    /* the paper's speed: cost per second of each node's recent responses */
    double mean_speed = 0;
    int nmeasured = 0;
    for (int k = 0; k < s->nnodes; k++) {
        sc_sched_node *nd = &s->nodes[k];
        if (nd->busy > 0 && nd->done > 0) {
            /* per unit of the capacity it offered */
            double v = nd->done / nd->busy / (nd->job_cap > 0 ? nd->job_cap : 1.0);
            nd->speed[kind] = nd->measured[kind] ? SPEED_KEEP * nd->speed[kind] +
                                                       (1 - SPEED_KEEP) * v
                                                 : v;
            nd->measured[kind] = 1;
            nd->idle[kind] = 0;
        } else {
            nd->idle[kind]++;
        }
        /* refit after REFIT new samples, but not more often than every
         * REFIT_JOBS jobs once fitted: a fit costs tens of microseconds */
        sc_cost_model *m = &nd->model[kind];
        m->jobs++;
        if (m->fresh >= REFIT && (!m->ok || m->jobs >= REFIT_JOBS))
            fit(m);
        if (nd->measured[kind]) {
            mean_speed += nd->speed[kind];
            nmeasured++;
        }
    }
    /* A node judged slow gets no work and so no chance to show otherwise
     * (a slow first unit, a busy moment): while it idles, its speed drifts
     * back to the mean and, after a while, its model is set aside. */
    for (int k = 0; k < s->nnodes && nmeasured > 0; k++) {
        sc_sched_node *nd = &s->nodes[k];
        if (nd->idle[kind] == 0 || !nd->measured[kind])
            continue;
        nd->speed[kind] += IDLE_DRIFT * (mean_speed / nmeasured - nd->speed[kind]);
        if (nd->idle[kind] >= IDLE_FORGET)
            nd->model[kind].ok = 0;
    }
    /* lower bound: a unit's work is its time scaled to the mean speed of
     * the nodes that could take work in this job */
    double fallback = nmeasured > 0 ? mean_speed / nmeasured : 1.0;
    double rsum = 0, rmax = 0, mean = 0;
    int navail = 0;
    for (int k = 0; k < s->nnodes; k++) {
        const sc_sched_node *nd = &s->nodes[k];
        if (nd->job_cap > 0) {
            mean += (nd->measured[kind] ? nd->speed[kind] : fallback) * nd->job_cap;
            navail++;
        }
    }
    mean = navail > 0 && mean > 0 ? mean / navail : 1.0;
    for (int k = 0; k < s->nnodes; k++) {
        const sc_sched_node *nd = &s->nodes[k];
        if (!(nd->job_cap > 0))
            continue;
        double r = (nd->measured[kind] ? nd->speed[kind] : fallback) * nd->job_cap / mean;
        rsum += r;
        rmax = fmax(rmax, r);
    }
    double total = 0, largest = 0;
    for (int i = 0; i < n; i++) {
        const sc_sched_node *nd = &s->nodes[units[i].node];
        double v = (nd->measured[kind] ? nd->speed[kind] : fallback) *
                   (nd->job_cap > 0 ? nd->job_cap : 1.0);
        double work = units[i].time_s * v / mean;
        total += work;
        largest = fmax(largest, work);
    }
    if (!(rsum > 0)) {
        rsum = rmax = 1;
    }
    *bound_s = fmax(total / rsum, largest / rmax);
}
