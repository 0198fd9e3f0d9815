/* node_local.c - local nodes (docs/DESIGN.md 5.3): the calling thread
 * (node 0, running its units inside wait()) and worker threads, each with
 * a narrow-phase context on a private copy of ODE when one can be had.
 * The nodes form a pool: one that runs out of work steals the smallest
 * unstarted unit of another, and records who ran it for the scheduler.
 * Waking a sleeping thread can take longer than a job, so workers and the
 * caller spin a while before they sleep; idle members also take shared
 * tasks (sc_task_runner) below the units. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>

#include "exec.h"

/* The scheduler's assignment is a prediction; the local nodes of a world
 * form a pool in which a node that runs out of work takes the smallest
 * not-yet-started unit from the tail of another's list (each list is a
 * deque: its owner takes from the head, the largest first). A unit's
 * result does not depend on who runs it, and whoever runs it is recorded
 * in u->node, so the scheduler learns from what really happened.
 *
 * Waking a sleeping thread costs 0.1-3 ms on a virtual machine (measured
 * on the 2-core CI machine), longer than many jobs. So a worker spins for
 * a while after each batch before it sleeps, and the caller spins before
 * it sleeps waiting for results: jobs of one frame come back to back.
 * Handing work over is atomic; the mutex and condition variables are only
 * for sleeping.
 *
 * Tasks are shared below the units: a node publishes a batch of tasks
 * (sc_task_runner: a split island's blocks of one colour, docs/DESIGN.md
 * 11, or the calling thread's sweep and prune, 5.3), and members of the
 * pool that are idle or waiting take tasks from it until none is left.
 * The publisher takes tasks too, so nothing waits for a helper that
 * never comes. */

#define WORKER_SPIN_S 3e-3    /* a worker stays awake this long for more */
#define WAITER_SPIN_S 2e-3    /* the caller spins this long for results */

typedef struct local_node local_node;

/* Units run in the background (sc_local_pool_background): idle workers
 * take them one at a time, the caller the rest when it drains them. */
typedef struct bg_batch {
    const sc_job *job;
    int count;
    atomic_int next;          /* the next unit to take */
} bg_batch;

/* Members are only added (never moved: idle workers look at them any
 * time, for blocks), each before n counts it. */
struct sc_local_pool {
    local_node *members[SC_MAX_WORKERS];
    atomic_int n;
    local_node *home;         /* the calling thread's node, or NULL */
    bg_batch bg_store;
    _Atomic(bg_batch *) bg;   /* published background units, or NULL */
    atomic_int bg_helpers;    /* workers looking at bg */
    atomic_int nospin;        /* 1: idle threads sleep at once */
};

/* A batch of tasks, published by the node that runs it. */
typedef struct help_batch {
    sc_task_fn fn;
    void *arg;
    int count;
    atomic_int next;          /* the next task to take */
} help_batch;

struct local_node {
    sc_node base;
    sc_local_pool *pool;
    int inline_node;
    sc_np_ctx *np;
    const sc_ode *ode;
    pthread_t thread;
    int thread_ok;
    pthread_mutex_t lock;
    pthread_cond_t go, done;
    /* the current batch: written by submit() before range and gen */
    const sc_job *job;
    const int *units;
    _Atomic uint64_t range;   /* list positions not started: head | tail << 32 */
    atomic_int left;          /* units of the list not finished (by anyone) */
    atomic_uint gen;          /* batches submitted */
    atomic_uint started_gen;  /* batches this node has started working on */
    atomic_uint done_gen;     /* batches this node has finished working on */
    atomic_int quit;
    _Atomic double cpu_s;     /* CPU seconds of the last batch (atomic: a
                                 worker that starts after the others took
                                 all its units still writes it, maybe as
                                 the next batch is submitted) */
    double t_submit, t_start; /* wall clock: submitted, picked up */
    double latency;           /* EWMA of the wake-up time, 0 = none yet */
    int init_rc;              /* worker thread start-up */
    int started;
    sc_task_runner runner;    /* its np's: shares its tasks with the pool */
    _Atomic(help_batch *) help;   /* its published tasks, or NULL */
    atomic_int helpers;       /* threads looking at help */
};

sc_local_pool *sc_local_pool_create(void)
{
    return calloc(1, sizeof(sc_local_pool));
}

void sc_local_pool_set_spin(sc_local_pool *p, int spin)
{
    if (p)
        atomic_store(&p->nospin, !spin);
}

int sc_local_pool_spins(const sc_local_pool *p)
{
    return p && !atomic_load_explicit(&p->nospin, memory_order_relaxed);
}

/* How long an idle thread of n's pool polls before it sleeps. */
static double spin_for(const local_node *n, double spin_s)
{
    return !n->pool || sc_local_pool_spins(n->pool) ? spin_s : 0;
}

static void stop_thread(local_node *n)
{
    if (!n->thread_ok)
        return;
    atomic_store(&n->quit, 1);
    pthread_mutex_lock(&n->lock);
    pthread_cond_signal(&n->go);
    pthread_mutex_unlock(&n->lock);
    pthread_join(n->thread, NULL);
    n->thread_ok = 0;
}

void sc_local_pool_stop(sc_local_pool *p)
{
    /* all threads first: a late worker may still be looking at the others */
    for (int k = 0; p && k < atomic_load(&p->n); k++)
        stop_thread(p->members[k]);
}

void sc_local_pool_destroy(sc_local_pool *p)
{
    if (!p)
        return;
    free(p);
}

static inline void cpu_relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

/* Run tasks that other members of n's pool published, with n's arena
 * (n is between units: its arena is free); 1 if it ran any. A helper
 * counts itself in m->helpers before it reads m->help, and the publisher
 * takes the batch back before it waits for helpers to reach 0 (both
 * sequentially consistent), so no helper is left holding a batch that
 * is gone. */
static int help_others(local_node *n)
{
    sc_local_pool *p = n->pool;
    int ran = 0, members = p ? atomic_load_explicit(&p->n, memory_order_acquire) : 0;
    for (int k = 0; k < members; k++) {
        local_node *m = p->members[k];
        if (m == n || !atomic_load_explicit(&m->help, memory_order_relaxed))
            continue;
        atomic_fetch_add(&m->helpers, 1);
        help_batch *h = atomic_load(&m->help);
        int i;
        while (h && (i = atomic_fetch_add_explicit(&h->next, 1, memory_order_relaxed)) < h->count) {
            h->fn(h->arg, i, sc_np_arena(n->np), 1);
            ran = 1;
        }
        atomic_fetch_sub(&m->helpers, 1);
    }
    return ran;
}

/* The runner of node ctx: publish the tasks, take them with the others
 * until none is left, withdraw them and wait for the helpers still
 * running one. */
static void run_tasks(void *ctx, sc_task_fn fn, void *arg, int count, sc_arena *a)
{
    local_node *n = ctx;
    help_batch h = { .fn = fn, .arg = arg, .count = count };
    atomic_init(&h.next, 0);
    atomic_store(&n->help, &h);
    int i;
    while ((i = atomic_fetch_add_explicit(&h.next, 1, memory_order_relaxed)) < count)
        fn(arg, i, a, 0);
    atomic_store(&n->help, NULL);
    while (atomic_load(&n->helpers) > 0)
        cpu_relax();
}

/* Unit u of job on n, timed from *t (then the time it ended) and recorded
 * as run by n. */
static void run_timed(local_node *n, const sc_job *job, sc_unit *u, double *t)
{
    sc_unit_run(n->np, job, u);
    /* Under a CPU quota (no polling: 5.3) a thread that used its share is
     * throttled at its next entry into the kernel, not where it ran out;
     * reading its CPU clock enters it here, so that the stall counts in
     * this unit's time rather than in whatever the thread does next. */
    if (n->pool && !sc_local_pool_spins(n->pool))
        (void)sc_cpu_now();
    double t1 = sc_wall_now();
    u->time_s = t1 - *t;
    u->node = n->base.id;
    *t = t1;
}

/* Background unit i of b on n. */
static void run_bg_unit(local_node *n, bg_batch *b, int i)
{
    double t = sc_wall_now();
    run_timed(n, b->job, &b->job->units[i], &t);
}

/* An idle worker takes one background unit (then looks for a batch of
 * its own again); 1 if it ran one. Counted in bg_helpers as help_others()
 * counts its helpers, so that drain() waits for it. */
static int help_background(local_node *n)
{
    sc_local_pool *p = n->pool;
    if (!p || n->inline_node || !atomic_load_explicit(&p->bg, memory_order_relaxed))
        return 0;
    atomic_fetch_add(&p->bg_helpers, 1);
    bg_batch *b = atomic_load(&p->bg);
    int i, ran = 0;
    if (b && (i = atomic_fetch_add_explicit(&b->next, 1, memory_order_relaxed)) < b->count) {
        run_bg_unit(n, b, i);
        ran = 1;
    }
    atomic_fetch_sub(&p->bg_helpers, 1);
    return ran;
}

void sc_local_pool_background(sc_local_pool *p, const sc_job *job)
{
    bg_batch *b = &p->bg_store;
    b->job = job;
    b->count = job->nunits;
    atomic_store_explicit(&b->next, 0, memory_order_relaxed);
    atomic_store(&p->bg, b);
}

void sc_local_pool_drain(sc_local_pool *p)
{
    bg_batch *b = atomic_load(&p->bg);
    if (!b)
        return;
    int i;
    while ((i = atomic_fetch_add_explicit(&b->next, 1, memory_order_relaxed)) < b->count)
        run_bg_unit(p->home, b, i);
    atomic_store(&p->bg, NULL);
    while (atomic_load(&p->bg_helpers) > 0)
        cpu_relax();
}

/* Spin until *v != old or spin_s passed (since the last block n helped
 * with); 1 if it changed. */
static int spin_until_changed(local_node *n, const atomic_uint *v, unsigned old, double spin_s)
{
    if (!(spin_s > 0))          /* sleeping at once: no helping either */
        return atomic_load_explicit(v, memory_order_acquire) != old;
    double end = sc_wall_now() + spin_s;
    for (int i = 1;; i++) {
        if (atomic_load_explicit(v, memory_order_acquire) != old)
            return 1;
        if (help_others(n) || help_background(n))
            end = sc_wall_now() + spin_s;
        cpu_relax();
        if ((i & 63) == 0 && sc_wall_now() > end)
            return 0;
    }
}

/* Take the next unit of m's list: from the head (m's own) or the tail (a
 * thief's); -1 when none is left. */
static int take(local_node *m, int from_tail)
{
    uint64_t r = atomic_load_explicit(&m->range, memory_order_acquire);
    for (;;) {
        uint32_t h = (uint32_t)r, t = (uint32_t)(r >> 32);
        if (h >= t)
            return -1;
        uint64_t next = from_tail ? ((uint64_t)(t - 1) << 32 | h) : ((uint64_t)t << 32 | (h + 1));
        if (atomic_compare_exchange_weak_explicit(&m->range, &r, next, memory_order_acq_rel,
                                                  memory_order_acquire))
            return (int)(from_tail ? t - 1 : h);
    }
}

/* Run position pos of m's list on n, timed; tell m's waiter when its list
 * is finished. */
static void run_one(local_node *n, local_node *m, int pos, double *t)
{
    run_timed(n, m->job, &m->job->units[m->units[pos]], t);
    if (atomic_fetch_sub_explicit(&m->left, 1, memory_order_acq_rel) == 1 && m != n) {
        pthread_mutex_lock(&m->lock);
        pthread_cond_broadcast(&m->done);
        pthread_mutex_unlock(&m->lock);
    }
}

/* A node's batch: its own list from the head, then the other nodes' from
 * their tails. Returns the CPU seconds it took. */
static double run_batch(local_node *n)
{
    /* the wall clock first: a quota's stall at the CPU clock's read (see
     * run_timed()) belongs to the first unit's time */
    double t = sc_wall_now();
    double c0 = sc_cpu_now();
    int pos;
    while ((pos = take(n, 0)) >= 0)
        run_one(n, n, pos, &t);
    sc_local_pool *p = n->pool;
    int members = p ? atomic_load_explicit(&p->n, memory_order_acquire) : 0;
    for (int k = 0; k < members; k++) {
        local_node *m = p->members[(n->base.id + 1 + k) % members];
        if (m == n)
            continue;
        while ((pos = take(m, 1)) >= 0)
            run_one(n, m, pos, &t);
    }
    return sc_cpu_now() - c0;
}

static void *worker(void *arg)
{
    local_node *n = arg;
    /* the copy of ODE and the context belong to this thread */
    n->ode = sc_ode_acquire();
    n->np = sc_np_create_on(n->ode);
    if (n->np)
        sc_np_set_runner(n->np, &n->runner);
    pthread_mutex_lock(&n->lock);
    n->init_rc = n->np ? SC_OK : SC_ENOMEM;
    n->started = 1;
    pthread_cond_broadcast(&n->done);
    pthread_mutex_unlock(&n->lock);
    unsigned seen = 0;
    while (n->np) {
        if (!spin_until_changed(n, &n->gen, seen, spin_for(n, WORKER_SPIN_S))) {
            pthread_mutex_lock(&n->lock);
            while (atomic_load(&n->gen) == seen && !atomic_load(&n->quit))
                pthread_cond_wait(&n->go, &n->lock);
            pthread_mutex_unlock(&n->lock);
        }
        if (atomic_load(&n->quit))
            break;
        seen = atomic_load_explicit(&n->gen, memory_order_acquire);
        n->t_start = sc_wall_now();
        atomic_store_explicit(&n->started_gen, seen, memory_order_release);
        atomic_store_explicit(&n->cpu_s, run_batch(n), memory_order_relaxed);
        atomic_store_explicit(&n->done_gen, seen, memory_order_release);
        pthread_mutex_lock(&n->lock);
        pthread_cond_broadcast(&n->done);
        pthread_mutex_unlock(&n->lock);
    }
    sc_np_destroy(n->np);
    n->np = NULL;
    sc_ode_release(n->ode);
    return NULL;
}

static int local_submit(sc_node *base, const sc_job *job, const int *units, int count)
{
    local_node *n = (local_node *)base;
    n->job = job;
    n->units = units;
    atomic_store_explicit(&n->cpu_s, 0.0, memory_order_relaxed);
    n->t_submit = sc_wall_now();
    atomic_store_explicit(&n->left, count, memory_order_relaxed);
    atomic_store_explicit(&n->range, (uint64_t)(uint32_t)count << 32, memory_order_release);
    atomic_fetch_add_explicit(&n->gen, 1, memory_order_release);
    if (!n->inline_node) {
        pthread_mutex_lock(&n->lock);
        pthread_cond_signal(&n->go);
        pthread_mutex_unlock(&n->lock);
    }
    return SC_OK;
}

/* Done: every unit of n's list finished (by n or by others) and n not in
 * the middle of this batch. A worker still asleep when the others have
 * taken all its units is not waited for. */
static int finished(local_node *n, unsigned gen)
{
    return atomic_load_explicit(&n->left, memory_order_acquire) == 0 &&
           (atomic_load_explicit(&n->started_gen, memory_order_acquire) != gen ||
            atomic_load_explicit(&n->done_gen, memory_order_acquire) == gen);
}

static int local_wait(sc_node *base, double *cpu_s)
{
    local_node *n = (local_node *)base;
    unsigned gen = atomic_load(&n->gen);
    if (n->inline_node && atomic_load(&n->done_gen) != gen) {
        atomic_store(&n->started_gen, gen);
        atomic_store_explicit(&n->cpu_s, run_batch(n), memory_order_relaxed);
        atomic_store(&n->done_gen, gen);
    }
    if (!finished(n, gen)) {
        /* the caller, waiting, helps with blocks */
        local_node *home = n->pool ? n->pool->home : NULL;
        double spin_s = spin_for(n, WAITER_SPIN_S);
        double end = sc_wall_now() + spin_s;
        for (int i = 1; spin_s > 0 && !finished(n, gen) && ((i & 63) || sc_wall_now() < end);
             i++) {
            if (home && help_others(home))
                end = sc_wall_now() + spin_s;
            cpu_relax();
        }
        if (!finished(n, gen)) {
            pthread_mutex_lock(&n->lock);
            while (!finished(n, gen))
                pthread_cond_wait(&n->done, &n->lock);
            pthread_mutex_unlock(&n->lock);
        }
    }
    int ran = atomic_load(&n->done_gen) == gen;
    *cpu_s = ran ? atomic_load_explicit(&n->cpu_s, memory_order_relaxed) : 0;
    if (!n->inline_node && ran) {
        /* there and back: twice the wake-up the worker saw */
        double l = 2 * (n->t_start - n->t_submit);
        n->latency = n->latency > 0 ? 0.8 * n->latency + 0.2 * l : l;
    }
    return SC_OK;
}

static double local_latency(const sc_node *base)
{
    const local_node *n = (const local_node *)base;
    if (n->inline_node)
        return 0;
    return n->latency > 0 ? n->latency : 50e-6;   /* a guess until measured */
}

static double local_transfer(const sc_node *base, size_t bytes)
{
    (void)base;
    (void)bytes;
    return 0;    /* shared memory: nothing travels */
}

static void local_destroy(sc_node *base)
{
    local_node *n = (local_node *)base;
    if (!n)
        return;
    /* the pool's owner stopped every thread first (sc_local_pool_stop) */
    stop_thread(n);
    if (n->inline_node)
        sc_np_destroy(n->np);
    pthread_cond_destroy(&n->go);
    pthread_cond_destroy(&n->done);
    pthread_mutex_destroy(&n->lock);
    free(n);
}

static const sc_node_ops local_ops = {
    .submit = local_submit,
    .wait = local_wait,
    .transfer_s = local_transfer,
    .latency_s = local_latency,
    .destroy = local_destroy,
};

sc_node *sc_node_local_create(sc_local_pool *pool, int id, int inline_node)
{
    if (pool && atomic_load(&pool->n) >= SC_MAX_WORKERS)
        return NULL;
    local_node *n = calloc(1, sizeof *n);
    if (!n)
        return NULL;
    n->base.ops = &local_ops;
    n->base.id = id;
    n->inline_node = inline_node;
    n->runner = (sc_task_runner){ .run = run_tasks, .ctx = n };
    n->pool = pool;           /* before its thread starts: read there */
    pthread_mutex_init(&n->lock, NULL);
    pthread_cond_init(&n->go, NULL);
    pthread_cond_init(&n->done, NULL);
    if (inline_node) {
        n->ode = sc_ode_shared();
        n->np = sc_np_create_on(n->ode);
        if (!n->np) {
            local_destroy(&n->base);
            return NULL;
        }
        sc_np_set_runner(n->np, &n->runner);
    } else {
        if (pthread_create(&n->thread, NULL, worker, n) != 0) {
            local_destroy(&n->base);
            return NULL;
        }
        n->thread_ok = 1;
        pthread_mutex_lock(&n->lock);
        while (!n->started)
            pthread_cond_wait(&n->done, &n->lock);
        int rc = n->init_rc;
        pthread_mutex_unlock(&n->lock);
        if (rc != SC_OK) {
            local_destroy(&n->base);
            return NULL;
        }
    }
    /* joins the pool only once it can run units (members look at each
     * other's lists only while a job runs, at each other's blocks any
     * time: members are appended, never moved) */
    if (pool && inline_node)
        pool->home = n;
    if (pool) {
        int k = atomic_load(&pool->n);
        pool->members[k] = n;
        atomic_store_explicit(&pool->n, k + 1, memory_order_release);
    }
    return &n->base;
}

const sc_task_runner *sc_local_pool_runner(sc_local_pool *p)
{
    if (!p || !p->home || atomic_load(&p->n) < 2)
        return NULL;
    return &p->home->runner;
}

int sc_node_local_private_ode(const sc_node *base)
{
    const local_node *n = (const local_node *)base;
    return sc_ode_is_private(n->ode);
}
