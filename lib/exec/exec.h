/* exec.h - execution (docs/DESIGN.md section 5): nodes that run work
 * units (local worker threads here, daemons from the network layer), the
 * scheduler, and the executor that runs a frame's jobs on a set of nodes.
 * Depends on the core only. */
#ifndef SC_EXEC_H
#define SC_EXEC_H

#include "frame.h"

/* ODE copies (ode_copy.c): a private copy of libode for the calling
 * thread, or the shared one when none can be loaded (limit reached,
 * dlmopen unsupported). Never NULL. */
const sc_ode *sc_ode_acquire(void);
/* Give a copy from sc_ode_acquire() back for other threads; NULL is a no-op. */
void sc_ode_release(const sc_ode *o);

/* A node: something that runs units: a local worker thread, or a daemon
 * (lib/net/cluster.c) behind the same interface. submit() starts the units (indices into
 * job->units) and returns at once; wait() returns when they are done, with
 * each unit's rc and time_s set and *cpu_s the CPU seconds the node used. */
typedef struct sc_node sc_node;
typedef struct sc_node_ops {
    int (*submit)(sc_node *n, const sc_job *job, const int *units, int count);
    int (*wait)(sc_node *n, double *cpu_s);
    double (*transfer_s)(const sc_node *n, size_t bytes);   /* to and back,
                                       affine in bytes */
    double (*latency_s)(const sc_node *n);   /* per job: wake-up and reply */
    /* NULL = 1. What share of its measured speed the node offers now for
     * units of kind (a daemon: its idle fraction); 0 = give it none (gone,
     * owner-busy, or a kind it cannot run). Asked once per job. */
    double (*capacity)(const sc_node *n, int kind);
    void (*destroy)(sc_node *n);
    /* NULL = 0. The calling thread's own time to ship a unit of this wire
     * size to n and take its result in (packing, sealing, sending,
     * receiving, merging): time it does not compute (the worth-it rule,
     * docs/DESIGN.md 6.2). */
    double (*home_s)(const sc_node *n, size_t bytes);
    /* NULL = 0. The node's round trip per job less its work, as measured
     * over its recent jobs (a daemon: the median of the last 16); 0 = not
     * known yet. Asked once per job (the job-level worth-it rule). */
    double (*round_trip_s)(const sc_node *n);
} sc_node_ops;
struct sc_node {
    const sc_node_ops *ops;
    int id;
};
/* sc_cpu_budget() (simcluster.h) is in cpu_budget.c. The smallest quota
 * in CPUs that proc_cgroup (the text of /proc/self/cgroup) puts on the
 * process under the cgroup mount root; 0 for none (or nothing readable). */
double sc_cpu_quota_at(const char *root, const char *proc_cgroup);

/* A local node. inline_node = 1: the calling thread itself (runs its
 * units inside wait(), on the shared ODE); 0: a worker thread of its own
 * (with a private ODE copy when one can be had). Nodes of one pool take
 * not-yet-started units from each other's lists when they run out; pool
 * may be NULL. NULL on error. */
typedef struct sc_local_pool sc_local_pool;
sc_local_pool *sc_local_pool_create(void);
/* Whether the pool's idle threads poll for work a few milliseconds before
 * they sleep (the default), or sleep at once (docs/DESIGN.md 5.3). */
void sc_local_pool_set_spin(sc_local_pool *p, int spin);
int sc_local_pool_spins(const sc_local_pool *p);   /* 0 for NULL */
/* Stop every worker thread of the pool (before destroying its nodes). */
void sc_local_pool_stop(sc_local_pool *p);
void sc_local_pool_destroy(sc_local_pool *p);   /* after its nodes */
sc_node *sc_node_local_create(sc_local_pool *pool, int id, int inline_node);
/* Background units (docs/DESIGN.md section 5): the units of job (each
 * writing only its own outputs) published for idle worker threads, which
 * take them one at a time between their own batches while the caller goes
 * on with other jobs; drain() has the calling thread run what is left and
 * waits for those taken. One background job at a time; the pool needs its
 * home node (the calling thread). */
void sc_local_pool_background(sc_local_pool *p, const sc_job *job);
void sc_local_pool_drain(sc_local_pool *p);
/* The calling thread's task runner (its home node's): tasks handed to it
 * are shared with the pool's idle worker threads. NULL without a home
 * node or workers. */
const sc_task_runner *sc_local_pool_runner(sc_local_pool *p);
/* 1 when a local node runs on a private copy of ODE. */
int sc_node_local_private_ode(const sc_node *n);

/* The scheduler. Per node and unit kind: the paper's speed (cost per
 * second, from recent response times) and a least-squares cost model
 * (time = c . feat, fitted with GSL over the last measurements). */
#define SC_MODEL_WINDOW 128
#define SC_SHIP_SHARE_DEFAULT 0.5       /* sc_world_config.cluster_ship_share */
#define SC_MIN_GAIN_DEFAULT 2.0         /* sc_world_config.cluster_min_gain */
typedef struct sc_cost_model {
    double x[SC_MODEL_WINDOW][3], y[SC_MODEL_WINDOW];
    int n, pos, fresh;              /* samples held, next slot, since last fit */
    int jobs;                       /* jobs since the last fit */
    double c[3];
    int ok;                         /* c is a usable fit */
} sc_cost_model;
typedef struct sc_sched_node {
    double speed[SC_UNIT_KINDS];    /* cost units per second at full capacity (EWMA) */
    int measured[SC_UNIT_KINDS];
    int idle[SC_UNIT_KINDS];        /* jobs since it last got work */
    sc_cost_model model[SC_UNIT_KINDS];
    double ready;                   /* predicted finish in the current job */
    double busy;                    /* measured busy time in the current job */
    double done;                    /* cost done in the current job */
    double job_speed, job_latency;  /* for the current job's assignment */
    double job_tr0, job_tr1;        /* transfer: seconds fixed, per byte */
    double job_home0, job_home1;    /* the calling thread's shipping time
                                       (home_s): fixed, per byte */
    double job_cap;                 /* capacity offered in the current job */
    double job_rt;                  /* round trip less work (round_trip_s), for
                                       the current job; 0 = not known, or no
                                       job-level rule */
    int job_refused;                /* kept out of the current job by it */
    double busy_until;              /* wall clock (sc_wall_now) until which it is
                                       predicted busy with a started job's units
                                       (0: free); its ready time in a job begins
                                       there */
} sc_sched_node;
typedef struct sc_sched {
    int nnodes;
    sc_sched_node *nodes;
    void *keys;                     /* scratch: the LPT order */
    int *assigned, *start, *cursor; /* per-node unit lists */
    int order_cap;
    int use_models;                 /* 0: the paper's cost / speed only */
    double ship_share;              /* the worth-it rule: a unit goes to a node
                                       with a shipping cost (home_s) only when
                                       that is at most this share of computing
                                       it at home; negative: no rule */
    double min_gain;                /* the job-level worth-it rule: a node with a
                                       round trip gets a job's units only when
                                       their predicted work there is at least
                                       this many round trips; <= 0: no rule */
    int refused;                    /* nodes the last assignment kept its units
                                       from by that rule */
    uint64_t shuffle;               /* tests: != 0 seeds a random assignment */
    int learn_alone;                /* tests: learn with a single node too */
    double home_capacity;           /* node 0's capacity (1; benchmarks: 0 sends
                                       everything to the other nodes) */
} sc_sched;
int sc_sched_init(sc_sched *s, int nnodes);
void sc_sched_free(sc_sched *s);
/* Predicted time of u on node k (cost model, or cost / speed). */
double sc_sched_predict(const sc_sched *s, int k, const sc_unit *u);
/* Greedy longest-first: units sorted by cost, each to the node with the
 * earliest predicted finish (ready + transfer + predicted time). A node
 * whose share of the job is predicted to take less than min_gain of its
 * round trips gets none, and the job is assigned again without it. Sets
 * u->node and the per-node lists s->assigned[s->start[k] .. start[k+1]). */
int sc_sched_assign(sc_sched *s, sc_node *const *nodes, sc_unit *units, int n);
/* After a job: learn from the measured times; *bound_s the lower bound on
 * its makespan (max of total work / total speed and the largest unit). */
void sc_sched_observe(sc_sched *s, const sc_unit *units, int n, double *bound_s);


/* Something that adds nodes of its own to an executor (the cluster): told
 * around every job run on the nodes (after assignment, before the first
 * submit; after the last wait), and asked how many of its nodes can take
 * work now (for cutting pair jobs). A started job (sc_exec.start) is
 * parked after its remote submits, so that other jobs can begin and end
 * meanwhile (its results are still taken as they come), and resumed
 * before its waits. */
typedef struct sc_node_provider {
    int (*job_begin)(void *ctx, const sc_job *job);
    void (*job_end)(void *ctx);
    int (*available)(void *ctx);
    void (*job_park)(void *ctx);
    void (*job_resume)(void *ctx, const sc_job *job);
    void *ctx;
} sc_node_provider;

/* The executor over nodes (dispatch.c): node 0 is the calling thread,
 * nodes 1 .. nlocal - 1 worker threads, then a provider's nodes. */
typedef struct sc_exec_nodes {
    sc_exec base;
    sc_node **nodes;
    int nnodes, nlocal, cap;
    sc_local_pool *pool;
    sc_sched sched;
    sc_node_provider prov;          /* .ctx NULL: none */
    sc_unit *units;                 /* jobs' units, grown and kept */
    int unit_cap;
    int private_ode;                /* local nodes on a private ODE copy */
    double cpu_budget;              /* the CPUs it may use (init's budget) */
    double span_s;                  /* wall seconds from submit to the last result, summed
                                       over jobs (the frame's time less it is its serial
                                       part, sc_stats_sched.serial_s) */
    struct {                        /* a job between start() and finish() */
        sc_job *job;
        int whole;                  /* nothing sent: run() it at finish() */
        int *assigned, assigned_cap, *start;   /* its per-node lists */
        double *cap;                /* per node: the capacity it offered */
        double submit_s, sched_s;
        int refused;                /* sc_sched.refused of its assignment */
    } pend;
} sc_exec_nodes;
/* nlocal local nodes and room for extra more (a provider's), on a
 * process that may use budget CPUs (sc_cpu_budget(): its idle threads
 * poll only with a CPU each, 5.3): SC_OK or SC_ENOMEM (then
 * sc_exec_nodes_free() still applies). */
int sc_exec_nodes_init(sc_exec_nodes *x, int nlocal, int extra, double budget);
/* Add a provider's node (after init, at most extra of them). */
void sc_exec_nodes_add(sc_exec_nodes *x, sc_node *n);
void sc_exec_nodes_free(sc_exec_nodes *x);

#endif /* SC_EXEC_H */
