/*
 * engine.h - the daemon's engine (docs/DESIGN.md 7.3-7.5): it joins the
 * cluster's multicast group, announces itself, caches shapes by content
 * hash, computes the work units masters send it on its compute threads and
 * replies with their results, every message a sealed envelope on the
 * channels of simcluster_net.h. Each start has a new epoch. The process
 * around it (configuration, logging, signals) is daemon/simclusterd.c.
 */
#ifndef SCD_ENGINE_H
#define SCD_ENGINE_H

#include <stddef.h>
#include <stdint.h>

#include "simcluster_net.h"

#define SC_SERVE_MAX_THREADS 256
#define SC_SERVE_SPIN_S 2e-3     /* sc_serve_config.spin_s's default */
#define SC_SERVE_SPIN_MAX 0.1

typedef struct sc_serve_config {
    const char *url;            /* udpm:// URL (SC_CLUSTER_URL; sc_bus_open) */
    uint8_t key[SC_KEY_BYTES];  /* the cluster key; all zero = insecure */
    int threads;                /* compute threads, 1..SC_SERVE_MAX_THREADS */
    double busy_threshold;      /* owner-busy when the others' CPU use passes
                                  this fraction of the machine (0..1], with
                                  hysteresis (idle.h) */
    double heartbeat_s;         /* announce period, 0.01..10 (default 0.2) */
    int64_t node_id;            /* > 0; 0 = random */
    int idle_priority;          /* 1: compute threads at nice 19 and SCHED_IDLE */
    int dedicated;              /* 1: a compute node with no owner: the idle
                                   fraction is reported as 1 and the node is
                                   never owner-busy, whatever else runs */
    size_t cache_bytes;         /* shape cache bound (default 256 MiB) */
    double spin_s;              /* an idle compute thread polls this long for
                                   the next unit before it sleeps, 0 ..
                                   SC_SERVE_SPIN_MAX (default SC_SERVE_SPIN_S;
                                   0: sleep at once) */
    /* messages (syslog priorities: LOG_ERR, LOG_WARNING, LOG_INFO, LOG_DEBUG);
     * called from any thread, one line each, no newline; NULL = none */
    void (*log)(void *ctx, int prio, const char *msg);
    void *log_ctx;
} sc_serve_config;

typedef struct sc_serve_counters {
    int64_t node;               /* this daemon's id */
    int64_t epoch;              /* this start's epoch */
    long units;                 /* units received and decoded */
    long results;               /* results sent */
    long unit_errors;           /* units that failed to decode or run */
    long shapes;                /* shapes in the cache */
    long shape_requests;        /* requests sent */
    long dropped_format, dropped_auth, dropped_replay;  /* envelopes dropped */
    long dropped_net;           /* datagrams and fragments the bus dropped:
                                   malformed, refused, evicted, no memory */
    long dropped_kernel;        /* datagrams the kernel dropped (queue full) */
    int rcvbuf_bytes;           /* the socket's receive buffer */
    long dropped_stale;         /* from an older epoch of a master than its newest */
    long dropped_misaddressed;  /* addressed to another epoch (start) of this daemon */
    long challenges;            /* masters' challenges answered */
    long duplicates;            /* other daemons heard with this id (each epoch once) */
    long heartbeats;            /* announces sent */
    long spin_hits;             /* times an idle compute thread found units
                                   queued while it polled (spin_s): wake-ups
                                   saved */
    double idle_fraction;       /* last measured */
    int owner_busy;
} sc_serve_counters;

sc_serve_config sc_serve_config_default(void);
typedef struct sc_serve sc_serve;
/* Join the multicast group and prepare (no threads yet): SC_OK, SC_EINVAL
 * (bad config), SC_EIO (the URL cannot be opened), SC_ENOMEM. */
int sc_serve_create(const sc_serve_config *c, sc_serve **out);
/* Start the compute threads and serve until sc_serve_stop(): SC_OK, or
 * SC_EIO when the bus fails, SC_ENOMEM. */
int sc_serve_run(sc_serve *s);
/* Apply a new configuration's busy_threshold, heartbeat_s and log to a
 * running daemon (SIGHUP); the other fields need a restart and are
 * ignored. SC_OK or SC_EINVAL (nothing changed). Any thread. */
int sc_serve_reload(sc_serve *s, const sc_serve_config *c);
/* Ask sc_serve_run() to return (async-signal-safe). */
void sc_serve_stop(sc_serve *s);
/* A snapshot of the counters (any thread). */
void sc_serve_counters_get(sc_serve *s, sc_serve_counters *out);
void sc_serve_destroy(sc_serve *s);

/* A queued unit's job: its master (id, epoch) and the job's serial. */
typedef struct sc_serve_job {
    int64_t master, master_epoch, frame;
} sc_serve_job;
/* Which of the n >= 1 queued units (in arrival order) a compute thread
 * runs next: the first of the newest job of the first unit's master. A
 * master waits on its current job (a pile's substep) at once and on a
 * started one (the frame's motion groups, sent before it) only at the end
 * of its frame (docs/DESIGN.md 7.4). */
int sc_serve_pick(const sc_serve_job *q, int n);

#endif
