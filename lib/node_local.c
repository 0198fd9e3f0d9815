/* node_local.c - local nodes: the calling thread itself (node 0, runs its
 * units inside wait()) and worker threads, each with its own narrow-phase
 * context on a private copy of ODE when one can be had (ode_copy.c).
 * The embedded default: no network, no daemons.
 *
 * Waking a sleeping thread costs 0.1-3 ms on a virtual machine (measured
 * on the 2-core CI machine), longer than many jobs. So a worker spins for
 * a while after each batch before it sleeps, and the caller spins before
 * it sleeps waiting for results: jobs of one frame come back to back.
 * Handing work over is an atomic generation count; the mutex and condition
 * variables are only for sleeping. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>

#include "sc_internal.h"

#define WORKER_SPIN_S 3e-3    /* a worker stays awake this long for more */
#define WAITER_SPIN_S 2e-3    /* the caller spins this long for results */

typedef struct local_node {
    sc_node base;
    int inline_node;
    sc_np_ctx *np;
    const sc_ode *ode;
    pthread_t thread;
    int thread_ok;
    pthread_mutex_t lock;
    pthread_cond_t go, done;
    /* the current batch: written by submit() before gen is raised */
    const sc_job *job;
    const int *units;
    int count;
    atomic_uint gen;          /* batches submitted */
    atomic_uint done_gen;     /* batches finished */
    atomic_int quit;
    double cpu_s;             /* CPU seconds of the last batch */
    double t_submit, t_start; /* wall clock: submitted, picked up */
    double latency;           /* EWMA of the wake-up time, 0 = none yet */
    int init_rc;              /* worker thread start-up */
    int started;
} local_node;

static inline void cpu_relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

/* Spin until *v != old or spin_s passed; 1 if it changed. */
static int spin_until_changed(const atomic_uint *v, unsigned old, double spin_s)
{
    double end = sc_wall_now() + spin_s;
    for (int i = 1;; i++) {
        if (atomic_load_explicit(v, memory_order_acquire) != old)
            return 1;
        cpu_relax();
        if ((i & 63) == 0 && sc_wall_now() > end)
            return 0;
    }
}

/* Run the batch on the calling thread, timing every unit. */
static double run_batch(sc_np_ctx *np, const sc_job *job, const int *units, int count)
{
    double c0 = sc_cpu_now();
    double t = sc_wall_now();
    for (int i = 0; i < count; i++) {
        sc_unit *u = &job->units[units[i]];
        sc_unit_run(np, job, u);
        double t1 = sc_wall_now();
        u->time_s = t1 - t;
        t = t1;
    }
    return sc_cpu_now() - c0;
}

static void *worker(void *arg)
{
    local_node *n = arg;
    /* the copy of ODE and the context belong to this thread */
    n->ode = sc_ode_acquire();
    n->np = sc_np_create_on(n->ode);
    pthread_mutex_lock(&n->lock);
    n->init_rc = n->np ? SC_OK : SC_ENOMEM;
    n->started = 1;
    pthread_cond_broadcast(&n->done);
    pthread_mutex_unlock(&n->lock);
    unsigned seen = 0;
    while (n->np) {
        if (!spin_until_changed(&n->gen, seen, WORKER_SPIN_S)) {
            pthread_mutex_lock(&n->lock);
            while (atomic_load(&n->gen) == seen && !atomic_load(&n->quit))
                pthread_cond_wait(&n->go, &n->lock);
            pthread_mutex_unlock(&n->lock);
        }
        if (atomic_load(&n->quit))
            break;
        seen = atomic_load_explicit(&n->gen, memory_order_acquire);
        n->t_start = sc_wall_now();
        n->cpu_s = run_batch(n->np, n->job, n->units, n->count);
        atomic_store_explicit(&n->done_gen, seen, memory_order_release);
        pthread_mutex_lock(&n->lock);
        pthread_cond_signal(&n->done);
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
    n->count = count;
    n->cpu_s = 0;
    n->t_submit = sc_wall_now();
    atomic_fetch_add_explicit(&n->gen, 1, memory_order_release);
    if (!n->inline_node) {
        pthread_mutex_lock(&n->lock);
        pthread_cond_signal(&n->go);
        pthread_mutex_unlock(&n->lock);
    }
    return SC_OK;
}

static int local_wait(sc_node *base, double *cpu_s)
{
    local_node *n = (local_node *)base;
    unsigned gen = atomic_load(&n->gen);
    if (n->inline_node) {
        if (atomic_load(&n->done_gen) != gen) {
            n->cpu_s = run_batch(n->np, n->job, n->units, n->count);
            atomic_store(&n->done_gen, gen);
        }
        *cpu_s = n->cpu_s;
        return SC_OK;
    }
    if (atomic_load_explicit(&n->done_gen, memory_order_acquire) != gen &&
        !spin_until_changed(&n->done_gen, gen - 1, WAITER_SPIN_S)) {
        pthread_mutex_lock(&n->lock);
        while (atomic_load(&n->done_gen) != gen)
            pthread_cond_wait(&n->done, &n->lock);
        pthread_mutex_unlock(&n->lock);
    }
    atomic_thread_fence(memory_order_acquire);
    *cpu_s = n->cpu_s;
    /* there and back: twice the wake-up the worker saw */
    double l = 2 * (n->t_start - n->t_submit);
    n->latency = n->latency > 0 ? 0.8 * n->latency + 0.2 * l : l;
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
    if (n->thread_ok) {
        atomic_store(&n->quit, 1);
        pthread_mutex_lock(&n->lock);
        pthread_cond_signal(&n->go);
        pthread_mutex_unlock(&n->lock);
        pthread_join(n->thread, NULL);
    }
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

sc_node *sc_node_local_create(int id, int inline_node)
{
    local_node *n = calloc(1, sizeof *n);
    if (!n)
        return NULL;
    n->base.ops = &local_ops;
    n->base.id = id;
    n->inline_node = inline_node;
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
        return &n->base;
    }
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
    return &n->base;
}

int sc_node_local_private_ode(const sc_node *base)
{
    const local_node *n = (const local_node *)base;
    return sc_ode_is_private(n->ode);
}
