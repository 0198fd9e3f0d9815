/* engine.c - the daemon's engine (engine.h): the bus loop on the thread
 * that calls sc_serve_run() and compute threads that run units (pairs,
 * islands, or a motion group's frame, through the code a master's own
 * threads use, so the bits are theirs) and send their results. Received
 * bytes are never trusted: envelopes, units and shapes are checked
 * (sc_msg_open, sc_remote_unit_decode, sc_msg_shape_decode) before use.
 * Only the public API is used (simcluster_net.h). */
#include <errno.h>
#include <inttypes.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <syslog.h>
#include <time.h>
#include <unistd.h>

#include "engine.h"
#include "idle.h"
#include "simcluster_net.h"

#define QUEUE_MAX 4096            /* decoded units waiting for a thread */
#define PARKED_MAX 1024           /* units waiting for shapes */
#define MISSING_MAX 16            /* shapes one unit may wait for */
#define REQUEST_AGAIN_S 0.5       /* ask again for a shape not yet received */
#define BUSY_HYSTERESIS 0.1
#define CHANNEL_MAX 48
#define BATCH_BYTES (256u << 10)  /* results sent together, at most */
#define SHAPE_FIXED_BYTES 256     /* a cached shape's size besides its mesh */
#define RIVALS_MAX 8              /* other daemons' epochs with our id, logged once */
#define BUS_BUSY_MS 1             /* the main thread looks again this soon when a
                                     compute thread is reading the bus */

typedef struct task {
    sc_serve_job job;
    int unit;
    sc_remote_unit *ru;
    double decode_s;              /* thread seconds its decoding took */
} task;

typedef struct parked {           /* a unit whose shapes are on their way */
    int64_t master, master_epoch, frame;
    int unit;
    uint8_t *wire;
    size_t len;
    double since;
} parked;

typedef struct cached {
    uint64_t hash;
    sc_shape *shape;
    size_t bytes;
} cached;

typedef struct asked {
    uint64_t hash;
    double when;
} asked;

struct sc_serve {
    sc_serve_config cfg;
    sc_bus *bus;
    int64_t id, epoch;            /* this daemon and this start of it */
    int64_t rivals[RIVALS_MAX];   /* epochs of other daemons with our id (bus thread) */
    int nrivals, rival_next;
    char ch_unit[CHANNEL_MAX], ch_shape[CHANNEL_MAX];
    _Atomic int64_t seq;
    sc_msg_guard guard;           /* the bus's thread only (sc_serve_run) */
    int stop_pipe[2];
    /* shape cache (the bus's thread writes; compute threads read shapes that
     * decoded units hold references to) */
    cached *cache;
    int ncache, cache_cap;
    size_t cache_bytes;
    asked *asked;
    int nasked, asked_cap;
    parked *parked;
    int nparked;
    /* the compute queue */
    pthread_mutex_t lock;
    pthread_cond_t cond;
    pthread_mutex_t bus_lock;     /* receiving: the main thread, or a spinning compute thread */
    int spinning;                 /* (lock) a compute thread spins for the next unit */
    atomic_int pending;           /* qlen + quit, written under lock: what the
                                     spinning thread watches without taking it
                                     (an owner's program may hold a SCHED_IDLE
                                     thread off the CPU inside the lock, and
                                     the heartbeat needs the lock) */
    double budget;                /* sc_cpu_budget() at the start */
    struct {                      /* the main thread's: the last beat's figures */
        double idle, speed;
        long results;
    } hb;
    atomic_long heartbeats;       /* announcements sent (sc_serve_counters) */
    task **queue;
    int qhead, qlen;
    sc_serve_job *pick;         /* take_task()'s scratch, QUEUE_MAX */
    int quit;
    pthread_t *threads;
    int nthreads;
    /* heartbeat */
    cpu_set_t cpus;
    sc_cpu_times last_cpu;
    uint64_t last_self;
    int have_cpu;
    sc_busy busy;
    double speed;                 /* units per second per thread (EWMA) */
    double unit_s;                /* thread seconds in units since the last beat */
    long units_since;
    /* counters (lock) */
    sc_serve_counters n;
    pthread_mutex_t cfg_lock;     /* busy_threshold, heartbeat_s, log */
};

/* Monotonic wall seconds. */
static double wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Grow *p (capacity *cap items of size bytes) to hold need items, doubling,
 * never past max: 0, or -1 (then nothing changed). */
static int grow(void **p, int *cap, int need, size_t size, int max)
{
    if (need <= *cap)
        return 0;
    if (need > max)
        return -1;
    int c = *cap > 0 ? *cap : 64;
    while (c < need)
        c = c > max / 2 ? max : 2 * c;
    void *q = realloc(*p, (size_t)c * size);
    if (!q)
        return -1;
    *p = q;
    *cap = c;
    return 0;
}

static void logf_(sc_serve *s, int prio, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void logf_(sc_serve *s, int prio, const char *fmt, ...)
{
    pthread_mutex_lock(&s->cfg_lock);
    void (*fn)(void *, int, const char *) = s->cfg.log;
    void *ctx = s->cfg.log_ctx;
    pthread_mutex_unlock(&s->cfg_lock);
    if (!fn)
        return;
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    fn(ctx, prio, msg);
}

sc_serve_config sc_serve_config_default(void)
{
    sc_serve_config c;
    memset(&c, 0, sizeof c);
    c.url = SC_CLUSTER_URL;
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    c.threads = cpus < 1 ? 1 : cpus > SC_SERVE_MAX_THREADS ? SC_SERVE_MAX_THREADS : (int)cpus;
    c.busy_threshold = 0.5;
    c.heartbeat_s = 0.2;
    c.idle_priority = 1;
    c.cache_bytes = (size_t)256 << 20;
    c.spin_s = SC_SERVE_SPIN_S;
    return c;
}

static int config_ok(const sc_serve_config *c)
{
    return c->url && c->threads >= 1 && c->threads <= SC_SERVE_MAX_THREADS &&
           c->busy_threshold > 0 && c->busy_threshold <= 1 && c->heartbeat_s >= 0.01 &&
           c->heartbeat_s <= 10 && c->node_id >= 0 && c->cache_bytes > 0 && c->spin_s >= 0 &&
           c->spin_s <= SC_SERVE_SPIN_MAX;
}

/* Seal and publish, addressed to the receiver's epoch to_epoch (0: to
 * anyone). Any thread: sc_bus_publish is thread-safe. */
static int send_msg(sc_serve *s, const char *channel, int64_t to_epoch, int kind,
                    const uint8_t *payload, size_t len)
{
    uint8_t *env;
    size_t elen;
    int64_t seq = atomic_fetch_add(&s->seq, 1);
    int rc = sc_msg_seal(s->cfg.key, s->id, s->epoch, seq, to_epoch, kind, payload, len, &env,
                         &elen);
    if (rc != SC_OK)
        return rc;
    rc = sc_bus_publish(s->bus, channel, env, elen);
    free(env);
    return rc;
}

/* ---- compute threads ---- */

static void set_idle_priority(sc_serve *s)
{
    pid_t tid = (pid_t)syscall(SYS_gettid);
    if (setpriority(PRIO_PROCESS, (id_t)tid, 19) != 0)
        logf_(s, LOG_WARNING, "nice 19: %s", strerror(errno));
    struct sched_param sp = { 0 };
    if (sched_setscheduler(0, SCHED_IDLE, &sp) != 0)
        logf_(s, LOG_WARNING, "SCHED_IDLE: %s", strerror(errno));
}

/* Results of one job of one master waiting to go as one message (per
 * thread). */
typedef struct outbox {
    sc_serve_job job;
    uint8_t *buf;
    size_t len, cap;
    int count;
} outbox;

static void flush(sc_serve *s, outbox *o)
{
    if (!o->count)
        return;
    char ch[CHANNEL_MAX];
    snprintf(ch, sizeof ch, "SC_RESULT_%016" PRIx64, (uint64_t)o->job.master);
    int rc = send_msg(s, ch, o->job.master_epoch, SC_MSG_RESULT, o->buf, o->len);
    pthread_mutex_lock(&s->lock);
    if (rc == SC_OK)
        s->n.results += o->count;
    else
        s->n.unit_errors += o->count;
    pthread_mutex_unlock(&s->lock);
    if (rc != SC_OK)
        logf_(s, LOG_WARNING, "results not sent: %s", sc_strerror(rc));
    o->len = 0;
    o->count = 0;
}

static int outbox_add(outbox *o, const uint8_t *p, size_t n)
{
    if (o->len + n > o->cap) {
        size_t cap = 2 * (o->len + n);
        uint8_t *b = realloc(o->buf, cap);
        if (!b)
            return SC_ENOMEM;
        o->buf = b;
        o->cap = cap;
    }
    memcpy(o->buf + o->len, p, n);
    o->len += n;
    o->count++;
    return SC_OK;
}

static double thread_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A unit's time, as the master's scheduler learns this daemon's speed
 * from it: its decoding, its run and its result's encoding, the thread
 * seconds all of them take here (the sealing and sending of a batch of
 * results are the link's, which the master fits from round trips). */
static void run_task(sc_serve *s, sc_compute *cc, task *t, outbox *o)
{
    double c0 = thread_s();
    sc_compute_run(cc, t->ru);
    uint8_t *buf;
    size_t n;
    int rc = sc_remote_unit_result(t->ru, &buf, &n);
    double sec = t->decode_s + thread_s() - c0;
    uint8_t *payload = NULL;
    size_t plen = 0;
    if (rc == SC_OK) {
        sc_msg_work w = { t->job.frame, t->unit, buf, n,
                          sec > 2000 ? INT32_MAX : (int)(sec * 1e6) };
        rc = sc_msg_work_encode(SC_MSG_RESULT, &w, &payload, &plen);
    }
    /* compute() sent the results of any other job before this unit ran */
    if (rc == SC_OK && o->len + plen > BATCH_BYTES)
        flush(s, o);
    o->job = t->job;
    if (rc == SC_OK)
        rc = outbox_add(o, payload, plen);
    free(payload);
    free(buf);
    pthread_mutex_lock(&s->lock);
    if (rc != SC_OK)
        s->n.unit_errors++;
    s->unit_s += sec;
    s->units_since++;
    pthread_mutex_unlock(&s->lock);
    if (rc != SC_OK)
        logf_(s, LOG_WARNING, "result of unit %d: %s", t->unit, sc_strerror(rc));
}

int sc_serve_pick(const sc_serve_job *q, int n)
{
    int best = 0;
    for (int i = 1; i < n; i++)
        if (q[i].master == q[0].master && q[i].master_epoch == q[0].master_epoch &&
            q[i].frame > q[best].frame)
            best = i;
    return best;
}

/* The next task (under the lock), as sc_serve_pick() chooses; the ones
 * queued before it move up one. */
static task *take_task(sc_serve *s)
{
    sc_serve_job *q = s->pick;
    for (int i = 0; i < s->qlen; i++)
        q[i] = s->queue[(s->qhead + i) % QUEUE_MAX]->job;
    int best = sc_serve_pick(q, s->qlen);
    task *t = s->queue[(s->qhead + best) % QUEUE_MAX];
    for (int i = best; i > 0; i--)
        s->queue[(s->qhead + i) % QUEUE_MAX] = s->queue[(s->qhead + i - 1) % QUEUE_MAX];
    s->qhead = (s->qhead + 1) % QUEUE_MAX;
    s->qlen--;
    atomic_fetch_sub_explicit(&s->pending, 1, memory_order_release);
    return t;
}

/* Poll up to spin_s for a unit, receiving on the bus whenever the main
 * thread is not: a unit that comes meanwhile costs no wake-up of either
 * thread (tens of microseconds each, more in a virtual machine). The
 * thread is at the compute threads' priority (SCHED_IDLE by default): an
 * owner's program takes the CPU from it at once, and the idle fraction
 * the heartbeat reports leaves this process's own use out. */
static void spin_for_units(sc_serve *s, double spin_s)
{
    double end = wall_now() + spin_s;
    while (wall_now() < end) {
        if (pthread_mutex_trylock(&s->bus_lock) == 0) {
            sc_bus_handle(s->bus, 0);
            pthread_mutex_unlock(&s->bus_lock);
        }
        if (atomic_load_explicit(&s->pending, memory_order_acquire) > 0)
            return;
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#endif
    }
}

static void *compute(void *arg)
{
    sc_serve *s = arg;
    if (s->cfg.idle_priority)
        set_idle_priority(s);
    sc_compute *cc = sc_compute_create();     /* a private ODE copy if one can be had */
    outbox o = { { 0, 0, 0 }, NULL, 0, 0, 0 };
    int may_spin = 0;           /* a unit ran since this thread last polled */
    for (;;) {
        pthread_mutex_lock(&s->lock);
        if (!s->qlen && o.count) {
            /* nothing more to do now: what is done goes out together */
            pthread_mutex_unlock(&s->lock);
            flush(s, &o);
            continue;
        }
        while (!s->qlen && !s->quit) {
            /* after a unit, one idle thread at a time polls for the next
             * a while before it sleeps (docs/DESIGN.md 7.9); once, then
             * it sleeps until a unit comes */
            if (may_spin && !s->spinning && s->cfg.spin_s > 0) {
                may_spin = 0;
                s->spinning = 1;
                pthread_mutex_unlock(&s->lock);
                spin_for_units(s, s->cfg.spin_s);
                pthread_mutex_lock(&s->lock);
                s->spinning = 0;
                s->n.spin_hits += s->qlen > 0;
                continue;
            }
            pthread_cond_wait(&s->cond, &s->lock);
        }
        if (s->quit) {
            pthread_mutex_unlock(&s->lock);
            break;
        }
        task *t = take_task(s);
        pthread_mutex_unlock(&s->lock);
        may_spin = 1;
        /* a job's results do not wait for another job's units: the
         * master is waiting for this one */
        if (o.count && (o.job.master != t->job.master ||
                        o.job.master_epoch != t->job.master_epoch || o.job.frame != t->job.frame))
            flush(s, &o);
        if (cc)
            run_task(s, cc, t, &o);
        sc_remote_unit_free(t->ru);
        free(t);
    }
    free(o.buf);
    sc_compute_destroy(cc);
    return NULL;
}

/* ---- shapes ---- */

static const sc_shape *cache_find(const sc_serve *s, uint64_t hash)
{
    for (int i = 0; i < s->ncache; i++)
        if (s->cache[i].hash == hash)
            return s->cache[i].shape;
    return NULL;
}

/* The find of sc_remote_unit_decode: cached shapes; the missing ones
 * (the first MISSING_MAX) are noted to be asked for. */
typedef struct lookup_ctx {
    sc_serve *s;
    uint64_t missing[MISSING_MAX];
    int nmissing;
} lookup_ctx;

static const sc_shape *lookup(void *ctx, uint64_t hash)
{
    lookup_ctx *l = ctx;
    const sc_shape *sh = cache_find(l->s, hash);
    if (sh)
        return sh;
    for (int i = 0; i < l->nmissing; i++)
        if (l->missing[i] == hash)
            return NULL;
    if (l->nmissing < MISSING_MAX)
        l->missing[l->nmissing++] = hash;
    return NULL;
}

static void request_shape(sc_serve *s, int64_t master, int64_t master_epoch, uint64_t hash)
{
    double now = wall_now();
    int i;
    for (i = 0; i < s->nasked; i++)
        if (s->asked[i].hash == hash)
            break;
    if (i < s->nasked && now - s->asked[i].when < REQUEST_AGAIN_S)
        return;
    if (i == s->nasked) {
        if (grow((void **)&s->asked, &s->asked_cap, s->nasked + 1, sizeof *s->asked, 4096) != 0)
            return;
        s->nasked++;
    }
    s->asked[i] = (asked){ hash, now };
    uint8_t *p;
    size_t len;
    if (sc_msg_shape_request_encode(hash, &p, &len) != SC_OK)
        return;
    char ch[CHANNEL_MAX];
    snprintf(ch, sizeof ch, "SC_SHAPEREQ_%016" PRIx64, (uint64_t)master);
    if (send_msg(s, ch, master_epoch, SC_MSG_SHAPE_REQUEST, p, len) == SC_OK) {
        pthread_mutex_lock(&s->lock);
        s->n.shape_requests++;
        pthread_mutex_unlock(&s->lock);
    }
    free(p);
}

/* Decode a unit and queue it, or park it until its shapes come. Takes wire. */
static void take_unit(sc_serve *s, int64_t master, int64_t master_epoch, int64_t frame,
                      int unit, uint8_t *wire, size_t len, double since)
{
    lookup_ctx *l = calloc(1, sizeof *l);
    task *tp = calloc(1, sizeof *tp);
    if (!tp) {
        free(l);
        l = NULL;
    }
    int rc = l ? SC_OK : SC_ENOMEM;
    if (l) {
        tp->job.master = master;
        tp->job.master_epoch = master_epoch;
        tp->job.frame = frame;
        tp->unit = unit;
        l->s = s;
        double c0 = thread_s();
        rc = sc_remote_unit_decode(wire, len, lookup, l, &tp->ru);
        tp->decode_s = thread_s() - c0;
    }
    if (l && l->nmissing > 0) {
        sc_remote_unit_free(tp->ru);
        free(tp);
        for (int i = 0; i < l->nmissing; i++)
            request_shape(s, master, master_epoch, l->missing[i]);
        free(l);
        if (s->nparked == PARKED_MAX) {
            free(wire);
            return;
        }
        s->parked[s->nparked++] = (parked){ master, master_epoch, frame, unit, wire, len,
                                           since > 0 ? since : wall_now() };
        return;
    }
    free(l);
    free(wire);
    pthread_mutex_lock(&s->lock);
    if (rc == SC_OK && s->qlen == QUEUE_MAX)
        rc = SC_ETOOBIG;
    if (rc == SC_OK) {
        s->queue[(s->qhead + s->qlen) % QUEUE_MAX] = tp;
        s->qlen++;
        atomic_fetch_add_explicit(&s->pending, 1, memory_order_release);
        pthread_cond_signal(&s->cond);
    } else {
        s->n.unit_errors++;
    }
    pthread_mutex_unlock(&s->lock);
    if (rc != SC_OK) {
        if (tp)
            sc_remote_unit_free(tp->ru);
        free(tp);
        logf_(s, LOG_DEBUG, "unit %d of job %" PRId64 " dropped: %s", unit, frame,
              sc_strerror(rc));
    }
}

static void retry_parked(sc_serve *s)
{
    int n = s->nparked;
    parked *old = malloc((size_t)n * sizeof *old);
    if (!old)
        return;
    memcpy(old, s->parked, (size_t)n * sizeof *old);
    s->nparked = 0;
    double now = wall_now();
    for (int i = 0; i < n; i++) {
        if (now - old[i].since > 10) {      /* the master has long moved on */
            free(old[i].wire);
            continue;
        }
        take_unit(s, old[i].master, old[i].master_epoch, old[i].frame, old[i].unit, old[i].wire,
                  old[i].len, old[i].since);
    }
    free(old);
}

/* A message that opened but whose payload is not what its channel takes. */
static void count_format(sc_serve *s)
{
    pthread_mutex_lock(&s->lock);
    s->guard.dropped_format++;
    s->n.dropped_format = s->guard.dropped_format;
    pthread_mutex_unlock(&s->lock);
}

static size_t shape_bytes(const sc_shape *sh)
{
    int nverts = 0, ntris = 0;
    sc_shape_mesh_data(sh, NULL, &nverts, NULL, &ntris);    /* analytic: none */
    return SHAPE_FIXED_BYTES + (size_t)nverts * 24 + (size_t)ntris * 12 * 3;
}

static void take_shape(sc_serve *s, const uint8_t *p, size_t len)
{
    sc_shape *sh;
    int rc = sc_msg_shape_decode(p, len, &sh);
    if (rc != SC_OK) {
        count_format(s);
        logf_(s, LOG_WARNING, "shape dropped: %s", sc_strerror(rc));
        return;
    }
    uint64_t hash = sc_shape_hash(sh);
    if (cache_find(s, hash)) {
        sc_shape_release(sh);
        return;
    }
    size_t b = shape_bytes(sh);
    /* over the bound: forget every shape no queued unit holds (decoded
     * units keep their shapes alive by reference) */
    if (s->cache_bytes + b > s->cfg.cache_bytes) {
        for (int i = 0; i < s->ncache; i++)
            sc_shape_release(s->cache[i].shape);
        s->ncache = 0;
        s->cache_bytes = 0;
        logf_(s, LOG_INFO, "shape cache full: emptied");
    }
    if (grow((void **)&s->cache, &s->cache_cap, s->ncache + 1, sizeof *s->cache, 1 << 20) != 0) {
        sc_shape_release(sh);
        return;
    }
    s->cache[s->ncache++] = (cached){ hash, sh, b };
    s->cache_bytes += b;
    pthread_mutex_lock(&s->lock);
    s->n.shapes = s->ncache;
    pthread_mutex_unlock(&s->lock);
    logf_(s, LOG_DEBUG, "shape %016" PRIx64 " cached (%d triangles)", hash,
          sc_shape_triangles(sh));
    retry_parked(s);
}

/* ---- the bus's thread (sc_serve_run) ---- */

/* A master's challenge (addressed to this epoch: the guard checked): the
 * answer carries its nonce and this epoch, addressed to the master's. */
static void answer(sc_serve *s, const sc_msg *m)
{
    uint8_t nonce[SC_MSG_NONCE_BYTES];
    int64_t epoch;
    if (sc_msg_challenge_decode(m->payload, m->len, nonce, &epoch) != SC_OK ||
        epoch != s->epoch) {
        count_format(s);
        return;
    }
    uint8_t *p;
    size_t len;
    if (sc_msg_challenge_encode(nonce, s->epoch, &p, &len) != SC_OK)
        return;
    char ch[CHANNEL_MAX];
    snprintf(ch, sizeof ch, "SC_RESULT_%016" PRIx64, (uint64_t)m->node);
    if (send_msg(s, ch, m->epoch, SC_MSG_ANSWER, p, len) == SC_OK) {
        pthread_mutex_lock(&s->lock);
        s->n.challenges++;
        pthread_mutex_unlock(&s->lock);
    }
    free(p);
}

/* Heartbeats: only looked at (no guard: they are not acted on), for
 * another daemon with this id. One with a newer epoch started after this
 * one; one with an older epoch is running still if its heartbeat was sent
 * after this start began (its clock stamp): a replay of a dead start's
 * heartbeats is neither. Each such epoch is logged once. */
static void on_announce(void *ctx, const char *channel, const uint8_t *data, size_t len,
                        int64_t recv_us)
{
    (void)channel;
    (void)recv_us;
    sc_serve *s = ctx;
    sc_msg m;
    sc_msg_announce a;
    if (sc_msg_verify(s->cfg.key, data, len, &m) != SC_OK)
        return;
    if (m.kind == SC_MSG_ANNOUNCE && m.node == s->id && m.epoch != s->epoch &&
        sc_msg_announce_decode(m.payload, m.len, &a) == SC_OK && a.node == m.node &&
        (m.epoch > s->epoch || a.time_us / 1000 > SC_MSG_EPOCH_MS(s->epoch))) {
        int i = 0;
        while (i < s->nrivals && s->rivals[i] != m.epoch)
            i++;
        if (i == s->nrivals) {
            s->rivals[s->rival_next] = m.epoch;     /* over the oldest when full */
            s->rival_next = (s->rival_next + 1) % RIVALS_MAX;
            if (s->nrivals < RIVALS_MAX)
                s->nrivals++;
            pthread_mutex_lock(&s->lock);
            s->n.duplicates++;
            pthread_mutex_unlock(&s->lock);
            logf_(s, LOG_WARNING,
                  "node id %016" PRIx64 " is also used by a daemon on %s (epoch %016" PRIx64
                  ", ours %016" PRIx64 "): masters give work to the newer start only",
                  (uint64_t)s->id, a.host, (uint64_t)m.epoch, (uint64_t)s->epoch);
        }
    }
    sc_msg_free(&m);
}

static void on_message(void *ctx, const char *channel, const uint8_t *data, size_t len,
                       int64_t recv_us)
{
    (void)recv_us;
    sc_serve *s = ctx;
    sc_msg m;
    pthread_mutex_lock(&s->lock);
    int rc = sc_msg_open(s->cfg.key, &s->guard, data, len, &m);
    s->n.dropped_format = s->guard.dropped_format;
    s->n.dropped_auth = s->guard.dropped_auth;
    s->n.dropped_replay = s->guard.dropped_replay;
    s->n.dropped_stale = s->guard.dropped_stale;
    s->n.dropped_misaddressed = s->guard.dropped_misaddressed;
    pthread_mutex_unlock(&s->lock);
    if (rc != SC_OK) {
        logf_(s, LOG_DEBUG, "message on %s dropped: %s", channel, sc_strerror(rc));
        return;
    }
    int is_unit = !strcmp(channel, s->ch_unit);
    if (is_unit && m.kind == SC_MSG_UNIT) {
        size_t off = 0;
        while (off < m.len) {
            sc_msg_work w;
            if (sc_msg_work_next(SC_MSG_UNIT, m.payload, m.len, &off, &w) != SC_OK) {
                count_format(s);
                break;
            }
            pthread_mutex_lock(&s->lock);
            s->n.units++;
            pthread_mutex_unlock(&s->lock);
            take_unit(s, m.node, m.epoch, w.frame, w.unit, w.wire, w.len, 0); /* takes w.wire */
        }
    } else if (is_unit && m.kind == SC_MSG_CHALLENGE) {
        answer(s, &m);
    } else if (!is_unit && m.kind == SC_MSG_SHAPE) {
        take_shape(s, m.payload, m.len);
    } else {
        count_format(s);
    }
    sc_msg_free(&m);
}

static int read_file(const char *path, char *buf, size_t cap, size_t *len)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return SC_EIO;
    *len = fread(buf, 1, cap - 1, f);
    buf[*len] = 0;
    fclose(f);
    return SC_OK;
}

/* The idle fraction of our CPUs since the last beat, own use excluded. */
static double measure_idle(sc_serve *s)
{
    static const size_t cap = 1 << 16;
    char *buf = malloc(cap);
    if (!buf)
        return -1;
    size_t len;
    sc_cpu_times t;
    uint64_t self;
    double idle = -1;
    if (read_file("/proc/stat", buf, cap, &len) == SC_OK &&
        sc_cpu_parse_stat_cpus(buf, len, &s->cpus, &t) == SC_OK &&
        read_file("/proc/self/stat", buf, cap, &len) == SC_OK &&
        sc_cpu_parse_self(buf, len, &self) == SC_OK) {
        if (s->have_cpu && self >= s->last_self)
            idle = sc_idle_fraction(&s->last_cpu, &t, self - s->last_self);
        s->last_cpu = t;
        s->last_self = self;
        s->have_cpu = 1;
    }
    free(buf);
    return idle;
}

static void heartbeat(sc_serve *s)
{
    pthread_mutex_lock(&s->cfg_lock);
    double threshold = s->cfg.busy_threshold;
    pthread_mutex_unlock(&s->cfg_lock);
    double idle = measure_idle(s);
    if (s->cfg.dedicated)
        idle = 1;                  /* nobody to step aside for */
    int was = s->busy.busy;
    int busy = sc_busy_update(&s->busy, idle, threshold, BUSY_HYSTERESIS);
    if (busy != was)
        logf_(s, LOG_INFO, busy ? "owner busy (idle %.2f): no more work" : "owner idle again (idle %.2f)",
              idle);
    /* The announcement never waits for the compute threads' lock: one
     * that an owner's program keeps off the CPU (SCHED_IDLE) may hold it
     * for long, and the owner-busy flag must go out now. Without the lock
     * it carries the figures of the last beat that had it. */
    sc_msg_announce a;
    memset(&a, 0, sizeof a);
    if (idle >= 0)
        s->hb.idle = idle;
    if (pthread_mutex_trylock(&s->lock) == 0) {
        if (s->units_since > 0 && s->unit_s > 0) {
            double v = (double)s->units_since / s->unit_s;
            s->speed = s->speed > 0 ? 0.7 * s->speed + 0.3 * v : v;
        }
        s->units_since = 0;
        s->unit_s = 0;
        s->n.idle_fraction = s->hb.idle;
        s->n.owner_busy = busy;
        s->hb.speed = s->speed;
        s->hb.results = s->n.results;
        pthread_mutex_unlock(&s->lock);
    }
    a.node = s->id;
    gethostname(a.host, sizeof a.host - 1);
    a.cores = s->nthreads;
    a.speed = s->hb.speed > 0 ? s->hb.speed : 1;
    a.idle_fraction = s->hb.idle;
    a.owner_busy = busy;
    a.version = SC_MSG_VERSION;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    a.time_us = (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
    a.units = s->hb.results;
    uint8_t *p;
    size_t len;
    if (sc_msg_announce_encode(&a, &p, &len) == SC_OK) {
        if (send_msg(s, "SC_ANNOUNCE", 0, SC_MSG_ANNOUNCE, p, len) == SC_OK)
            atomic_fetch_add(&s->heartbeats, 1);
        free(p);
    }
}

int sc_serve_create(const sc_serve_config *c, sc_serve **out)
{
    if (!c || !out || !config_ok(c))
        return SC_EINVAL;
    *out = NULL;
    sc_serve *s = calloc(1, sizeof *s);
    if (!s)
        return SC_ENOMEM;
    s->cfg = *c;
    /* idle threads poll only where each has a CPU: under a smaller quota
     * polling would take the working threads' share */
    s->budget = sc_cpu_budget();
    if (s->cfg.spin_s > 0 && s->budget < s->cfg.threads)
        s->cfg.spin_s = 0;
    /* polling costs nobody only at idle priority or on a node with no
     * owner: at normal priority it would take an owner's CPU time */
    if (!s->cfg.idle_priority && !s->cfg.dedicated)
        s->cfg.spin_s = 0;
    s->stop_pipe[0] = s->stop_pipe[1] = -1;
    pthread_mutex_init(&s->lock, NULL);
    pthread_mutex_init(&s->bus_lock, NULL);
    pthread_mutex_init(&s->cfg_lock, NULL);
    pthread_cond_init(&s->cond, NULL);
    s->id = c->node_id;
    while (s->id <= 0) {
        uint64_t r = 0;
        if (getrandom(&r, sizeof r, 0) != sizeof r)
            r = (uint64_t)getpid() * 0x9e3779b97f4a7c15ULL ^ (uint64_t)time(NULL);
        s->id = (int64_t)(r >> 1);
    }
    s->n.node = s->id;
    s->epoch = sc_msg_epoch_new();
    s->n.epoch = s->epoch;
    s->guard.epoch = s->epoch;    /* units, shapes and challenges name this start */
    snprintf(s->ch_unit, sizeof s->ch_unit, "SC_UNIT_%016" PRIx64, (uint64_t)s->id);
    snprintf(s->ch_shape, sizeof s->ch_shape, "SC_SHAPE_%016" PRIx64, (uint64_t)s->id);
    if (sched_getaffinity(0, sizeof s->cpus, &s->cpus) != 0) {
        CPU_ZERO(&s->cpus);
        for (int i = 0; i < CPU_SETSIZE; i++)
            CPU_SET(i, &s->cpus);
    }
    s->queue = calloc(QUEUE_MAX, sizeof *s->queue);
    s->pick = calloc(QUEUE_MAX, sizeof *s->pick);
    s->parked = calloc(PARKED_MAX, sizeof *s->parked);
    s->threads = calloc((size_t)c->threads, sizeof *s->threads);
    if (!s->queue || !s->pick || !s->parked || !s->threads || pipe(s->stop_pipe) != 0) {
        sc_serve_destroy(s);
        return SC_ENOMEM;
    }
    if (sc_bus_open(c->url, &s->bus, NULL, 0) != SC_OK) {
        sc_serve_destroy(s);
        return SC_EIO;
    }
    if (sc_bus_subscribe(s->bus, s->ch_unit, on_message, s) != SC_OK ||
        sc_bus_subscribe(s->bus, s->ch_shape, on_message, s) != SC_OK ||
        sc_bus_subscribe(s->bus, "SC_ANNOUNCE", on_announce, s) != SC_OK) {
        sc_serve_destroy(s);
        return SC_EIO;
    }
    measure_idle(s);
    *out = s;
    return SC_OK;
}

/* The bus's counters into ours (the bus is read on this thread only). */
static void note_bus(sc_serve *s)
{
    sc_bus_counters b;
    sc_bus_counters_get(s->bus, &b);
    pthread_mutex_lock(&s->lock);
    s->n.dropped_net = (long)(b.malformed + b.refused + b.evicted + b.nomem);
    s->n.dropped_kernel = (long)b.kernel;
    s->n.rcvbuf_bytes = b.rcvbuf_bytes;
    pthread_mutex_unlock(&s->lock);
}

int sc_serve_run(sc_serve *s)
{
    if (!s)
        return SC_EINVAL;
    for (int i = 0; i < s->cfg.threads; i++) {
        if (pthread_create(&s->threads[i], NULL, compute, s) != 0)
            break;
        s->nthreads++;
    }
    if (s->nthreads == 0)
        return SC_ENOMEM;
    logf_(s, LOG_INFO, "serving on %s as node %016" PRIx64 " (epoch %016" PRIx64
          ") with %d threads%s", s->cfg.url, (uint64_t)s->id, (uint64_t)s->epoch, s->nthreads,
          s->cfg.idle_priority ? " (nice 19, SCHED_IDLE)" : "");
    if (s->cfg.spin_s == 0 && s->budget < s->cfg.threads)
        logf_(s, LOG_INFO, "%.2f CPUs for %d threads (affinity or cgroup quota): idle threads "
              "sleep at once (no --spin)", s->budget, s->cfg.threads);
    else if (s->cfg.spin_s == 0 && !s->cfg.idle_priority && !s->cfg.dedicated)
        logf_(s, LOG_INFO, "normal priority: idle threads sleep at once (no --spin)");
    note_bus(s);
    if (s->n.rcvbuf_bytes < SC_BUS_RCVBUF_MIN)
        logf_(s, LOG_WARNING, "receive buffer only %d KiB: a burst of datagrams may be lost "
              "(counted as dropped_kernel); raise net.core.rmem_max or start as root",
              s->n.rcvbuf_bytes >> 10);
    int rc = SC_OK;
    double next = wall_now();
    int fd = sc_bus_fd(s->bus);
    for (;;) {
        double now = wall_now();
        if (now >= next) {
            /* never behind bus_lock: a compute thread polling for units
             * holds it for a moment, but one that an owner's program keeps
             * off the CPU (SCHED_IDLE) may hold it for long, and the
             * heartbeat is what says the owner is busy */
            heartbeat(s);
            pthread_mutex_lock(&s->cfg_lock);
            next = now + s->cfg.heartbeat_s;
            pthread_mutex_unlock(&s->cfg_lock);
            if (pthread_mutex_trylock(&s->bus_lock) == 0) {
                if (s->nparked)
                    retry_parked(s);    /* re-asks for shapes lost on the way */
                note_bus(s);            /* what a polling thread read counts too */
                pthread_mutex_unlock(&s->bus_lock);
            }
        }
        struct pollfd pf[2] = { { fd, POLLIN, 0 }, { s->stop_pipe[0], POLLIN, 0 } };
        int ms = (int)((next - now) * 1000) + 1;
        int n = poll(pf, 2, ms);
        if (n < 0 && errno != EINTR) {
            rc = SC_EIO;
            break;
        }
        if (n > 0 && pf[1].revents)
            break;
        if (n > 0 && (pf[0].revents & POLLIN)) {
            if (pthread_mutex_trylock(&s->bus_lock) != 0) {
                /* a compute thread is reading the bus: what came is its;
                 * look again in a moment rather than wait for the lock */
                poll(&pf[1], 1, BUS_BUSY_MS);
                continue;
            }
            int hr = sc_bus_handle(s->bus, 0);
            note_bus(s);
            pthread_mutex_unlock(&s->bus_lock);
            if (hr < 0) {
                rc = SC_EIO;
                break;
            }
        }
    }
    pthread_mutex_lock(&s->lock);
    s->quit = 1;
    atomic_fetch_add_explicit(&s->pending, 1, memory_order_release);
    pthread_cond_broadcast(&s->cond);
    pthread_mutex_unlock(&s->lock);
    for (int i = 0; i < s->nthreads; i++)
        pthread_join(s->threads[i], NULL);
    s->nthreads = 0;
    return rc;
}

void sc_serve_stop(sc_serve *s)
{
    if (s) {
        char c = 1;
        ssize_t r = write(s->stop_pipe[1], &c, 1);
        (void)r;
    }
}

int sc_serve_reload(sc_serve *s, const sc_serve_config *c)
{
    if (!s || !c || !(c->busy_threshold > 0 && c->busy_threshold <= 1) ||
        !(c->heartbeat_s >= 0.01 && c->heartbeat_s <= 10))
        return SC_EINVAL;
    pthread_mutex_lock(&s->cfg_lock);
    s->cfg.busy_threshold = c->busy_threshold;
    s->cfg.heartbeat_s = c->heartbeat_s;
    s->cfg.log = c->log;
    s->cfg.log_ctx = c->log_ctx;
    pthread_mutex_unlock(&s->cfg_lock);
    return SC_OK;
}

void sc_serve_counters_get(sc_serve *s, sc_serve_counters *out)
{
    pthread_mutex_lock(&s->lock);
    *out = s->n;
    pthread_mutex_unlock(&s->lock);
    out->heartbeats = atomic_load(&s->heartbeats);
}

void sc_serve_destroy(sc_serve *s)
{
    if (!s)
        return;
    sc_bus_close(s->bus);
    for (int i = 0; s->queue && i < s->qlen; i++) {
        task *t = s->queue[(s->qhead + i) % QUEUE_MAX];
        sc_remote_unit_free(t->ru);
        free(t);
    }
    for (int i = 0; i < s->nparked; i++)
        free(s->parked[i].wire);
    for (int i = 0; i < s->ncache; i++)
        sc_shape_release(s->cache[i].shape);
    free(s->cache);
    free(s->asked);
    free(s->parked);
    free(s->queue);
    free(s->pick);
    free(s->threads);
    if (s->stop_pipe[0] >= 0) {
        close(s->stop_pipe[0]);
        close(s->stop_pipe[1]);
    }
    pthread_mutex_destroy(&s->lock);
    pthread_mutex_destroy(&s->bus_lock);
    pthread_mutex_destroy(&s->cfg_lock);
    pthread_cond_destroy(&s->cond);
    free(s);
}
