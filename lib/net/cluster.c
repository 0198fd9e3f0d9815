/* cluster.c - daemons as nodes of a world's scheduler (docs/DESIGN.md 7.4).
 *
 * One remote node per daemon slot, bound to one start (epoch) of a daemon
 * once it has answered a challenge. A node's submit() packs, seals and
 * publishes its units; wait() reads the bus until they are in or the
 * deadline passes and recomputes what is missing here. Results merge
 * through sc_wire_result_apply() as a local run writes them, so whoever
 * computes what, the bits are the same. */
#include <inttypes.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

#include "cluster.h"
#include "exec.h"
#include "simcluster_net.h"
#include "unit_wire.h"

#define CHANNEL_MAX 48
#define SILENT_S 1.0            /* no heartbeat this long: no work */
#define FORGET_S 10.0           /* no heartbeat this long: slot freed */
#define DEFAULT_DEADLINE_S 0.02
#define MIN_CAPACITY 0.05       /* a daemon that is not owner-busy gets some */
#define BATCH_BYTES (256u << 10) /* units sent together, at most */
#define BYTE_S_MIN 1e-11        /* the measured one's range */
#define BYTE_S_MAX 1e-5
#define LINK_KEEP 0.9           /* weight of the past jobs in the link fit */
#define LINK_JOBS 4             /* jobs (weighted) before the fit is used */
#define LINK_SPREAD 0.2         /* ... and their bytes' spread, of the mean */
#define HOME_BYTE_S 2e-9        /* the calling thread's shipping time per byte
                                   before any is measured; a prior above every
                                   unit's worth would keep all units home, so
                                   none would ever be measured (docs/DESIGN.md
                                   6.2) */
#define HOME_MEASURED 65536     /* bytes measured before the rate is used */
#define HOME_WINDOW 16777216    /* bytes: past this the sums are halved */
#define OVERHEAD_KEEP 0.8       /* EWMA of a job's communication overhead */
#define OVERHEAD_IDLE_DECAY 0.95 /* per job without work */
#define RT_WINDOW 16            /* round trips kept for the worth-it rule */
#define RT_KNOWN 4              /* ... before it applies */
#define RT_IDLE_DECAY 0.99      /* per job without work: a daemon kept out of
                                   every job is tried again in time */
#define WAIT_SPIN_S 3e-3        /* a wait for results polls this long before it
                                 * sleeps (docs/DESIGN.md 7.9) */
#define MAX_WAIT_DEADLINES 10   /* a long prediction stretches the deadline
                                   up to this many deadlines */

enum { OUT_NONE, OUT_SENT, OUT_DONE, OUT_LOCAL };

typedef struct daemon_slot {
    int used;
    int64_t id, epoch;          /* the daemon and the start of it this slot follows */
    int verified;               /* it answered our challenge for this epoch */
    uint8_t nonce[SC_MSG_NONCE_BYTES];  /* drawn once per (id, epoch) */
    int64_t rival;              /* an older live epoch of this id, counted once */
    char channel[CHANNEL_MAX], shape_channel[CHANNEL_MAX];
    sc_msg_announce a;
    double heard, missed_at;
    double overhead;            /* s per job beyond its threads' compute time */
    sc_link link;               /* its link, measured (sc_link_fit()) */
    double rt[RT_WINDOW];       /* its last jobs' round trips less their work,
                                   to the results' arrival in the kernel */
    int nrt, rt_next;
} daemon_slot;

/* A daemon's share of one job. */
typedef struct slot_job {
    int sent, done;
    int64_t submit_us, last_us;  /* real-time clock (the bus's receive stamps) */
    int64_t arrive_us;           /* the last result's arrival in the kernel */
    double t_submit;
    double compute_s;
    double bytes;                /* its units' and results' wire bytes */
} slot_job;

/* A job whose units are out: the current one (begun, not yet ended), and
 * a started one parked meanwhile (sc_exec.start: a frame's motion groups
 * while the pile runs); results of both are taken as they come. */
typedef struct cluster_job {
    const sc_job *job;
    int64_t serial;
    uint8_t *out;               /* per unit: OUT_* */
    int out_cap;
    int started;                /* parked once: its round trip held other jobs */
    double local_done;          /* when the first remote wait began */
    slot_job d[SC_MAX_DAEMONS];
} cluster_job;

typedef struct remote_node {
    sc_node base;
    sc_cluster *c;
    int slot;
} remote_node;

struct sc_cluster {
    sc_bus *bus;
    uint8_t key[SC_KEY_BYTES];
    int64_t id, epoch, seq;     /* this master: random id, epoch of this start */
    sc_msg_guard guard;
    long duplicates;            /* sc_stats.total.duplicate_nodes */
    int64_t duplicate;
    sc_sched *sched;            /* the executor's scheduler */
    sc_stats *stats;            /* the owner's figures */
    const sc_frame_state *st;   /* the owner's bodies (shapes asked for) */
    int first_node;             /* executor node index of slot 0 */
    int available;              /* daemons heard from and not owner-busy */
    daemon_slot d[SC_MAX_DAEMONS];
    remote_node node[SC_MAX_DAEMONS];
    double deadline_s;
    double wait_spin_s;         /* WAIT_SPIN_S, or 0 where the local threads
                                   do not poll (sc_local_pool_spins()) */
    cluster_job jobs[2];
    cluster_job *cur, *parked;  /* the current job, a started one parked */
    int64_t serial;             /* of the last job begun */
    sc_np_ctx *np;              /* recomputation on the calling thread */
    int force;                  /* benchmarks: idle fraction and owner-busy ignored */
    uint8_t *buf;
    size_t buf_cap;
    uint8_t *batch;             /* units for one daemon, encoded back to back */
    size_t batch_len, batch_cap;
    long late;
    int64_t recv_us;            /* the message being handled: when it came */
    double home_s, home_bytes;  /* shipping measured: the calling thread's
                                   seconds and the bytes they moved */
};

static int64_t realtime_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

/* ---- challenges (shared with sc_cluster_wait's listener) ---- */

/* Send daemon (id, epoch) the challenge nonce (drawn when it is all zero)
 * on its unit channel, addressed to that epoch. */
static void challenge(sc_bus *bus, const uint8_t *key, int64_t self, int64_t self_epoch,
                      int64_t *seq, int64_t id, int64_t epoch,
                      uint8_t nonce[SC_MSG_NONCE_BYTES])
{
    static const uint8_t zero[SC_MSG_NONCE_BYTES];
    if (!memcmp(nonce, zero, sizeof zero) &&
        getrandom(nonce, SC_MSG_NONCE_BYTES, 0) != SC_MSG_NONCE_BYTES)
        return;                 /* no randomness: ask again at the next announce */
    uint8_t *p, *env;
    size_t len, elen;
    if (sc_msg_challenge_encode(nonce, epoch, &p, &len) != SC_OK)
        return;
    char ch[CHANNEL_MAX];
    snprintf(ch, sizeof ch, "SC_UNIT_%016" PRIx64, (uint64_t)id);
    if (sc_msg_seal(key, self, self_epoch, (*seq)++, epoch, SC_MSG_CHALLENGE, p, len, &env,
                    &elen) == SC_OK) {
        sc_bus_publish(bus, ch, env, elen);
        free(env);
    }
    free(p);
}

/* An answer from (m->node, m->epoch) to the challenge whose nonce is
 * nonce: 1 if it is that answer. */
static int answers(const sc_msg *m, int64_t id, int64_t epoch,
                   const uint8_t nonce[SC_MSG_NONCE_BYTES])
{
    uint8_t got[SC_MSG_NONCE_BYTES];
    int64_t e;
    return m->node == id && m->epoch == epoch &&
           sc_msg_challenge_decode(m->payload, m->len, got, &e) == SC_OK && e == epoch &&
           !memcmp(got, nonce, sizeof got);
}

/* ---- receiving ---- */

static void on_announce(sc_cluster *c, const sc_msg *m)
{
    sc_msg_announce a;
    if (sc_msg_announce_decode(m->payload, m->len, &a) != SC_OK || a.node != m->node ||
        a.version != SC_MSG_VERSION) {
        c->guard.dropped_format++;
        return;
    }
    int free_slot = -1, k;
    for (k = 0; k < SC_MAX_DAEMONS; k++) {
        if (c->d[k].used && c->d[k].id == a.node)
            break;
        if (!c->d[k].used && free_slot < 0)
            free_slot = k;
    }
    if (k == SC_MAX_DAEMONS && free_slot < 0)
        return;                 /* more daemons than slots: the first ones serve */
    if (k == SC_MAX_DAEMONS || c->d[k].epoch < m->epoch) {
        /* a new daemon, or a new start of one (the guard refuses older
         * epochs): nothing learned about the last one holds */
        if (k == SC_MAX_DAEMONS)
            k = free_slot;
        daemon_slot *d = &c->d[k];
        int64_t rival = d->used ? d->rival : 0;
        memset(d, 0, sizeof *d);
        d->used = 1;
        d->id = a.node;
        d->epoch = m->epoch;
        d->rival = rival;
        snprintf(d->channel, sizeof d->channel, "SC_UNIT_%016" PRIx64, (uint64_t)a.node);
        snprintf(d->shape_channel, sizeof d->shape_channel, "SC_SHAPE_%016" PRIx64,
                 (uint64_t)a.node);
        /* what was learned goes; the current job's figures stay (a job may
         * be in flight to this slot) */
        sc_sched_node *nd = &c->sched->nodes[c->first_node + k];
        memset(nd->speed, 0, sizeof nd->speed);
        memset(nd->measured, 0, sizeof nd->measured);
        memset(nd->idle, 0, sizeof nd->idle);
        memset(nd->model, 0, sizeof nd->model);
    }
    daemon_slot *d = &c->d[k];
    d->a = a;
    d->heard = sc_wall_now();
    if (!d->verified)           /* again at each announce until it answers */
        challenge(c->bus, c->key, c->id, c->epoch, &c->seq, d->id, d->epoch, d->nonce);
}

static void on_answer(sc_cluster *c, const sc_msg *m)
{
    for (int k = 0; k < SC_MAX_DAEMONS; k++) {
        daemon_slot *d = &c->d[k];
        if (d->used && answers(m, d->id, d->epoch, d->nonce)) {
            d->verified = 1;
            d->heard = sc_wall_now();
            return;
        }
    }
    c->guard.dropped_format++;  /* not a challenge of ours that is open */
}

/* An announce the guard refused as stale (an older epoch of a node than
 * the newest heard): if it was sent after the newest epoch began (by the
 * sender's clock, which also made the epochs), it is not a replay of a
 * dead start but another daemon running with the same id: counted once
 * per pair of epochs. The newer keeps the slot and gets the work. */
static void stale_announce(sc_cluster *c, const void *buf, size_t len)
{
    sc_msg m;
    sc_msg_announce a;
    if (sc_msg_verify(c->key, buf, len, &m) != SC_OK)
        return;
    int live = m.kind == SC_MSG_ANNOUNCE &&
               sc_msg_announce_decode(m.payload, m.len, &a) == SC_OK && a.node == m.node;
    for (int k = 0; live && k < SC_MAX_DAEMONS; k++) {
        daemon_slot *d = &c->d[k];
        if (d->used && d->id == m.node && m.epoch < d->epoch && d->rival != m.epoch &&
            a.time_us / 1000 > SC_MSG_EPOCH_MS(d->epoch)) {
            d->rival = m.epoch;
            c->duplicates++;
            c->duplicate = m.node;
        }
    }
    sc_msg_free(&m);
}

static void take_result(sc_cluster *c, sc_msg_work *r)
{
    cluster_job *cj = NULL;
    for (int j = 0; j < 2; j++)
        if (c->jobs[j].job && c->jobs[j].serial == r->frame)
            cj = &c->jobs[j];
    const sc_job *job = cj ? cj->job : NULL;
    if (!job || r->unit >= job->nunits || cj->out[r->unit] != OUT_SENT) {
        c->late++;              /* an old job, taken already, or recomputed */
        c->stats->frame.remote.late_results++;
        return;
    }
    sc_unit *u = &job->units[r->unit];
    int k = u->node - c->first_node;
    daemon_slot *d = k >= 0 && k < SC_MAX_DAEMONS ? &c->d[k] : NULL;
    if (!d || sc_wire_result_apply(job, u, r->wire, r->len) != SC_OK) {
        c->guard.dropped_format++;    /* it will be recomputed */
        return;
    }
    slot_job *dj = &cj->d[k];
    cj->out[r->unit] = OUT_DONE;
    dj->bytes += (double)r->len;
    double sec = r->compute_us * 1e-6;
    int threads = d->a.cores < dj->sent ? d->a.cores : dj->sent;
    u->time_s = sec / (threads > 0 ? threads : 1);
    dj->done++;
    dj->compute_s += u->time_s;
    c->stats->frame.remote.bytes += (double)u->bytes;
    c->stats->frame.remote.work_s += u->time_s;
    /* when it was there for the master: read now for the current job
     * (after the calling thread's own units: the round trip the scheduler
     * must weigh), at the kernel's arrival stamp for a started one (read
     * only after the jobs run in between) */
    int64_t at = cj->started ? c->recv_us : realtime_us();
    if (at > dj->last_us)
        dj->last_us = at;
    if (c->recv_us > dj->arrive_us)
        dj->arrive_us = c->recv_us;
    c->stats->frame.remote.units++;
}

static void on_result(sc_cluster *c, const sc_msg *m)
{
    size_t off = 0;
    c->stats->frame.remote.result_messages++;
    c->home_bytes += (double)m->len;
    while (off < m->len) {
        sc_msg_work r;
        if (sc_msg_work_next(SC_MSG_RESULT, m->payload, m->len, &off, &r) != SC_OK) {
            c->guard.dropped_format++;
            return;
        }
        take_result(c, &r);
        sc_msg_work_free(&r);
    }
}

static void on_shape_request(sc_cluster *c, const sc_msg *m)
{
    uint64_t hash;
    if (sc_msg_shape_request_decode(m->payload, m->len, &hash) != SC_OK) {
        c->guard.dropped_format++;
        return;
    }
    int k;
    for (k = 0; k < SC_MAX_DAEMONS; k++)
        if (c->d[k].used && c->d[k].id == m->node && c->d[k].epoch == m->epoch)
            break;
    const sc_shape *s = NULL;
    for (int i = 0; i < c->st->nbodies && !s; i++)
        if (c->st->bodies[i].shape->hash == hash)
            s = c->st->bodies[i].shape;
    if (k == SC_MAX_DAEMONS || !s)
        return;                 /* not one of our daemons, or not our shape */
    uint8_t *p, *env;
    size_t len, elen;
    if (sc_msg_shape_encode(s, &p, &len) != SC_OK)
        return;
    if (sc_msg_seal(c->key, c->id, c->epoch, c->seq++, c->d[k].epoch, SC_MSG_SHAPE, p, len, &env,
                    &elen) == SC_OK) {
        sc_bus_publish(c->bus, c->d[k].shape_channel, env, elen);
        free(env);
    }
    free(p);
}

static void on_message(void *ctx, const char *channel, const uint8_t *data, size_t len,
                       int64_t recv_us)
{
    sc_cluster *c = ctx;
    sc_msg m;
    c->recv_us = recv_us;
    int announce = !strcmp(channel, "SC_ANNOUNCE");
    long stale = c->guard.dropped_stale;
    if (sc_msg_open(c->key, &c->guard, data, len, &m) != SC_OK) {
        if (announce && c->guard.dropped_stale > stale)
            stale_announce(c, data, len);
        return;
    }
    if (announce && m.kind == SC_MSG_ANNOUNCE)
        on_announce(c, &m);
    else if (!announce && m.kind == SC_MSG_RESULT)
        on_result(c, &m);
    else if (!announce && m.kind == SC_MSG_SHAPE_REQUEST)
        on_shape_request(c, &m);
    else if (!announce && m.kind == SC_MSG_ANSWER)
        on_answer(c, &m);
    else
        c->guard.dropped_format++;
    sc_msg_free(&m);
}

/* The calling thread's communication since t0, in the figures and in
 * the shipping rate (remote_home()). */
static void comm_since(sc_cluster *c, double t0)
{
    double t = sc_wall_now() - t0;
    c->stats->frame.remote.comm_s += t;
    c->home_s += t;
}

/* Handle what has come, waiting up to timeout_s for the first datagram:
 * polling without sleep until spin_until (wall clock; a wake-up from a
 * sleep costs tens of microseconds, more in a virtual machine), then
 * asleep in poll(). One pass over what is pending (the callers loop), so
 * that a flood of datagrams cannot hold a frame past its deadline. */
static void pump(sc_cluster *c, double timeout_s, double spin_until)
{
    struct pollfd pf = { sc_bus_fd(c->bus), POLLIN, 0 };
    double end = sc_wall_now() + (timeout_s > 0 ? timeout_s : 0), now;
    int ready = 0;
    while (!ready && (now = sc_wall_now()) < spin_until && now < end)
        ready = poll(&pf, 1, 0) > 0 && (pf.revents & POLLIN);
    if (!ready) {
        double left = end - sc_wall_now();
        int ms = left > 0 ? (int)(left * 1000) + 1 : 0;
        if (poll(&pf, 1, ms) <= 0 || !(pf.revents & POLLIN))
            return;
    }
    double t0 = sc_wall_now();
    sc_bus_handle(c->bus, 0);
    comm_since(c, t0);
}

/* ---- the remote node ---- */

static double capacity(const sc_node *n, int kind)
{
    const remote_node *r = (const remote_node *)n;
    const daemon_slot *d = &r->c->d[r->slot];
    (void)kind;                 /* every kind travels (a pile's group stays home: group.c) */
    if (!d->used || !d->verified || sc_wall_now() - d->heard > SILENT_S)
        return 0;
    if (r->c->force)
        return 1;
    if (d->a.owner_busy || d->missed_at > d->heard)
        return 0;
    return d->a.idle_fraction > MIN_CAPACITY ? d->a.idle_fraction : MIN_CAPACITY;
}

static int grow_buf(sc_cluster *c, size_t n)
{
    if (n <= c->buf_cap)
        return SC_OK;
    uint8_t *b = realloc(c->buf, n);
    if (!b)
        return SC_ENOMEM;
    c->buf = b;
    c->buf_cap = n;
    return SC_OK;
}

/* The units batched for one daemon go out as one sealed message. */
static int flush(sc_cluster *c, daemon_slot *d)
{
    if (!c->batch_len)
        return SC_OK;
    uint8_t *env;
    size_t elen;
    int rc = sc_msg_seal(c->key, c->id, c->epoch, c->seq++, d->epoch, SC_MSG_UNIT, c->batch,
                         c->batch_len, &env, &elen);
    c->batch_len = 0;
    if (rc != SC_OK)
        return rc;
    rc = sc_bus_publish(c->bus, d->channel, env, elen);
    free(env);
    if (rc == SC_OK)
        c->stats->frame.remote.unit_messages++;
    return rc;
}

static int add_unit(sc_cluster *c, daemon_slot *d, const sc_job *job, int idx)
{
    const sc_unit *u = &job->units[idx];
    size_t n = sc_wire_unit_pack(job, u, NULL, 0);
    int rc = n > 0 && n <= SC_MSG_MAX_WIRE ? grow_buf(c, n) : SC_ETOOBIG;
    if (rc != SC_OK)
        return rc;
    sc_wire_unit_pack(job, u, c->buf, n);
    c->home_bytes += (double)n;
    c->cur->d[d - c->d].bytes += (double)n;
    sc_msg_work w = { c->cur->serial, idx, c->buf, n, 0 };
    uint8_t *p;
    size_t len;
    rc = sc_msg_work_encode(SC_MSG_UNIT, &w, &p, &len);
    if (rc != SC_OK)
        return rc;
    if (c->batch_len + len > BATCH_BYTES)
        flush(c, d);
    if (c->batch_len + len > c->batch_cap) {
        size_t cap = 2 * (c->batch_len + len);
        uint8_t *b = realloc(c->batch, cap);
        if (!b) {
            free(p);
            return SC_ENOMEM;
        }
        c->batch = b;
        c->batch_cap = cap;
    }
    memcpy(c->batch + c->batch_len, p, len);
    c->batch_len += len;
    free(p);
    return SC_OK;
}

static int remote_submit(sc_node *n, const sc_job *job, const int *units, int count)
{
    remote_node *r = (remote_node *)n;
    sc_cluster *c = r->c;
    daemon_slot *d = &c->d[r->slot];
    slot_job *dj = &c->cur->d[r->slot];
    double t0 = sc_wall_now();
    dj->submit_us = dj->last_us = dj->arrive_us = realtime_us();
    dj->t_submit = t0;
    c->batch_len = 0;
    for (int i = 0; i < count; i++) {
        /* a unit that cannot be sent is computed here, in wait() */
        c->cur->out[units[i]] = OUT_SENT;
        dj->sent++;
        add_unit(c, d, job, units[i]);
    }
    flush(c, d);
    comm_since(c, t0);
    if (c->home_bytes > HOME_WINDOW) {     /* a window: the recent rate */
        c->home_s *= 0.5;
        c->home_bytes *= 0.5;
    }
    return SC_OK;
}

static void recompute(sc_cluster *c, daemon_slot *d, int k)
{
    cluster_job *cj = c->cur;
    const sc_job *job = cj->job;
    int missed = 0;
    for (int i = 0; i < job->nunits; i++) {
        sc_unit *u = &job->units[i];
        if (cj->out[i] != OUT_SENT || u->node != c->first_node + k)
            continue;
        if (!c->np)
            c->np = sc_np_create();
        double t0 = sc_wall_now();
        if (c->np) {
            sc_unit_run(c->np, job, u);
        } else {
            u->rc = SC_ENOMEM;
        }
        u->time_s = sc_wall_now() - t0;
        u->node = 0;            /* it taught us about this thread, not the daemon */
        cj->out[i] = OUT_LOCAL;
        c->stats->frame.remote.recomputed_units++;
        missed++;
    }
    if (missed)
        d->missed_at = sc_wall_now();
}

/* Units of the current job sent to slot k and neither back nor
 * recomputed. */
static int outstanding(const sc_cluster *c, int k)
{
    const cluster_job *cj = c->cur;
    int n = 0;
    for (int i = 0; i < cj->job->nunits; i++)
        n += cj->out[i] == OUT_SENT && cj->job->units[i].node == c->first_node + k;
    return n;
}

void sc_link_fit(sc_link *l, double x, double y)
{
    double *s = l->s;
    for (int i = 0; i < 5; i++)
        s[i] *= LINK_KEEP;
    s[0] += 1;
    s[1] += x;
    s[2] += x * x;
    s[3] += y;
    s[4] += x * y;
    double mx = s[1] / s[0], my = s[3] / s[0], var = s[2] / s[0] - mx * mx;
    double b = l->byte_s > 0 ? l->byte_s : SC_LINK_BYTE_S;
    if (s[0] >= LINK_JOBS && var > LINK_SPREAD * LINK_SPREAD * mx * mx && var > 0) {
        b = (s[4] / s[0] - mx * my) / var;
        b = b < BYTE_S_MIN ? BYTE_S_MIN : b > BYTE_S_MAX ? BYTE_S_MAX : b;
    }
    double a = my - b * mx;
    l->byte_s = b;
    l->latency = a > 0 ? a : 0;
}

static int remote_wait(sc_node *n, double *cpu_s)
{
    remote_node *r = (remote_node *)n;
    sc_cluster *c = r->c;
    daemon_slot *d = &c->d[r->slot];
    cluster_job *cj = c->cur;
    slot_job *dj = &cj->d[r->slot];
    double now = sc_wall_now();
    if (cj->local_done == 0)
        cj->local_done = now;
    /* the scheduler's own estimate of this daemon's work (behind what a
     * started job gave it), twice, or the configured deadline after the
     * local nodes finished */
    double predicted = d->overhead;
    for (int i = 0; i < cj->job->nunits; i++)
        if (cj->job->units[i].node == n->id)
            predicted += cj->job->units[i].predict_s;
    double busy = c->sched->nodes[n->id].busy_until - dj->t_submit;
    if (!cj->started && busy > 0)
        predicted += busy;
    double deadline = cj->local_done + c->deadline_s;
    double cap = MAX_WAIT_DEADLINES * c->deadline_s;
    if (dj->t_submit + fmin(2 * predicted, cap) > deadline)
        deadline = dj->t_submit + fmin(2 * predicted, cap);
    double t_wait = sc_wall_now();
    /* what is still out is read from the units, not from d's counts: a
     * restart of the daemon heard meanwhile resets its slot (a new epoch),
     * and units it was sent must still come back or be recomputed here */
    while (outstanding(c, r->slot) > 0 && (now = sc_wall_now()) < deadline)
        pump(c, deadline - now, t_wait + c->wait_spin_s);
    if (outstanding(c, r->slot) > 0)
        recompute(c, d, r->slot);
    else if (dj->sent > 0) {
        /* from the send to the last result's arrival (take_result), less
         * the work */
        double o = 1e-6 * (double)(dj->last_us - dj->submit_us) - dj->compute_s;
        if (o < 0)
            o = 0;
        d->overhead = d->overhead > 0 ? OVERHEAD_KEEP * d->overhead + (1 - OVERHEAD_KEEP) * o : o;
        /* the round trip itself, for the cluster model (bench_cluster -p
         * model): to the kernel's arrival, not to when this thread read it */
        double wire = 1e-6 * (double)(dj->arrive_us - dj->submit_us) - dj->compute_s;
        c->stats->frame.remote.overhead_s += wire > 0 ? wire : 0;
        sc_link_fit(&d->link, dj->bytes, wire > 0 ? wire : 0);
        if (wire > 0) {
            /* (not at or below 0: the clocks' noise on a reply faster than
             * it can measure) */
            d->rt[d->rt_next] = wire;
            d->rt_next = (d->rt_next + 1) % RT_WINDOW;
            d->nrt += d->nrt < RT_WINDOW;
        }
        c->stats->frame.remote.jobs++;
    }
    c->stats->frame.remote.wait_s += sc_wall_now() - t_wait;
    *cpu_s = dj->compute_s;
    return SC_OK;
}

/* The link's time for bytes (out and back) and its latency, as measured
 * (sc_link_fit()); before that, the prior and the mean round trip. */
static double remote_transfer(const sc_node *n, size_t bytes)
{
    const remote_node *r = (const remote_node *)n;
    double b = r->c->d[r->slot].link.byte_s;
    return (b > 0 ? b : SC_LINK_BYTE_S) * (double)bytes;
}

/* The calling thread's shipping time for a unit of bytes (out and back):
 * the rate measured over recent jobs (docs/DESIGN.md 6.2). */
static double remote_home(const sc_node *n, size_t bytes)
{
    const sc_cluster *c = ((const remote_node *)n)->c;
    double rate = c->home_bytes > HOME_MEASURED ? c->home_s / c->home_bytes : HOME_BYTE_S;
    return rate * (double)bytes;
}

static double remote_latency(const sc_node *n)
{
    const remote_node *r = (const remote_node *)n;
    const daemon_slot *d = &r->c->d[r->slot];
    return d->link.byte_s > 0 ? d->link.latency : d->overhead;
}

static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

/* The worth-it rule's round trip (sc_sched.min_gain): the median of the
 * last RT_WINDOW jobs' (one outlier, a page fault or a preempted daemon,
 * moves it little), 0 before RT_KNOWN. */
static double remote_round_trip(const sc_node *n)
{
    const remote_node *r = (const remote_node *)n;
    const daemon_slot *d = &r->c->d[r->slot];
    if (d->nrt < RT_KNOWN)
        return 0;
    double v[RT_WINDOW];
    memcpy(v, d->rt, (size_t)d->nrt * sizeof *v);
    qsort(v, (size_t)d->nrt, sizeof *v, cmp_double);
    return d->nrt % 2 ? v[d->nrt / 2] : 0.5 * (v[d->nrt / 2 - 1] + v[d->nrt / 2]);
}

static void remote_destroy(sc_node *n)
{
    (void)n;                    /* the cluster owns its nodes */
}

static const sc_node_ops remote_ops = {
    .submit = remote_submit,
    .wait = remote_wait,
    .transfer_s = remote_transfer,
    .latency_s = remote_latency,
    .capacity = capacity,
    .destroy = remote_destroy,
    .home_s = remote_home,
    .round_trip_s = remote_round_trip,
};

/* ---- the cluster ---- */

static int prov_begin(void *ctx, const sc_job *job);
static void prov_end(void *ctx);
static int prov_available(void *ctx);
static void prov_park(void *ctx);
static void prov_resume(void *ctx, const sc_job *job);

int sc_cluster_create(sc_exec_nodes *x, sc_stats *stats, const sc_frame_state *st,
                      const char *url, const char *key_file, double deadline_s,
                      sc_cluster **out)
{
    *out = NULL;
    sc_cluster *c = calloc(1, sizeof *c);
    if (!c)
        return SC_ENOMEM;
    int rc = key_file ? sc_key_load(key_file, c->key) : SC_OK;
    if (rc != SC_OK) {
        free(c);
        return rc;
    }
    c->sched = &x->sched;
    c->stats = stats;
    c->st = st;
    int first_node = x->nnodes;
    c->first_node = first_node;
    c->deadline_s = deadline_s > 0 ? deadline_s : DEFAULT_DEADLINE_S;
    c->wait_spin_s = sc_local_pool_spins(x->pool) ? WAIT_SPIN_S : 0;
    uint64_t id = 0;
    if (getrandom(&id, sizeof id, 0) != sizeof id)
        id = (uint64_t)getpid() * 0x9e3779b97f4a7c15ULL ^ (uint64_t)time(NULL);
    c->id = (int64_t)(id >> 1) | 1;
    c->epoch = sc_msg_epoch_new();
    c->guard.epoch = c->epoch;  /* results, requests and answers name this start */
    if (sc_bus_open(url, &c->bus, NULL, 0) != SC_OK) {
        free(c);
        return SC_EIO;
    }
    char ch[CHANNEL_MAX];
    int ok = sc_bus_subscribe(c->bus, "SC_ANNOUNCE", on_message, c) == SC_OK;
    snprintf(ch, sizeof ch, "SC_RESULT_%016" PRIx64, (uint64_t)c->id);
    ok = ok && sc_bus_subscribe(c->bus, ch, on_message, c) == SC_OK;
    snprintf(ch, sizeof ch, "SC_SHAPEREQ_%016" PRIx64, (uint64_t)c->id);
    ok = ok && sc_bus_subscribe(c->bus, ch, on_message, c) == SC_OK;
    if (!ok) {
        sc_cluster_destroy(c);
        return SC_EIO;
    }
    for (int k = 0; k < SC_MAX_DAEMONS; k++) {
        c->node[k] = (remote_node){ { &remote_ops, first_node + k }, c, k };
        sc_exec_nodes_add(x, &c->node[k].base);
    }
    x->prov = (sc_node_provider){ prov_begin, prov_end, prov_available, prov_park, prov_resume,
                                  c };
    *out = c;
    return SC_OK;
}

void sc_cluster_destroy(sc_cluster *c)
{
    if (!c)
        return;
    sc_bus_close(c->bus);
    sc_np_destroy(c->np);
    free(c->jobs[0].out);
    free(c->jobs[1].out);
    free(c->buf);
    free(c->batch);
    free(c);
}

void sc_cluster_frame(sc_cluster *c)
{
    pump(c, 0, 0);
    double now = sc_wall_now();
    c->stats->now.daemons = c->stats->now.daemons_busy = c->stats->now.daemons_unverified = 0;
    for (int k = 0; k < SC_MAX_DAEMONS; k++) {
        daemon_slot *d = &c->d[k];
        if (d->used && now - d->heard > FORGET_S) {
            /* gone: a later start of it is welcome even if its clock went
             * back (an older epoch than the one the guard remembers) */
            d->used = 0;
            sc_msg_guard_forget(&c->guard, d->id);
        }
        if (!d->used || now - d->heard > SILENT_S)
            continue;
        if (!d->verified)
            c->stats->now.daemons_unverified++;
        else if (d->a.owner_busy)
            c->stats->now.daemons_busy++;
        else
            c->stats->now.daemons++;
    }
    c->stats->now.nodes = c->first_node + c->stats->now.daemons;
    c->available = c->stats->now.daemons;
    /* what the bus dropped (datagrams, fragments, the kernel's overflows)
     * and the envelopes that did not open */
    sc_bus_counters bc;
    sc_bus_counters_get(c->bus, &bc);
    const sc_msg_guard *g = &c->guard;
    c->stats->total.dropped_messages = g->dropped_format + g->dropped_auth + g->dropped_replay +
                                 g->dropped_stale + g->dropped_misaddressed +
                                 (long)sc_bus_dropped(&bc);
    c->stats->total.dropped_auth = g->dropped_auth;
    c->stats->total.dropped_stale = g->dropped_stale;
    c->stats->total.dropped_misaddressed = g->dropped_misaddressed;
    c->stats->total.duplicate_nodes = c->duplicates;
    c->stats->now.duplicate_node = c->duplicate;
}

static int prov_available(void *ctx)
{
    return ((const sc_cluster *)ctx)->available;
}

static int prov_begin(void *ctx, const sc_job *job)
{
    sc_cluster *c = ctx;
    /* the slot the parked job (if any) does not hold */
    cluster_job *cj = c->parked == &c->jobs[0] ? &c->jobs[1] : &c->jobs[0];
    if (job->nunits > cj->out_cap) {
        uint8_t *o = realloc(cj->out, (size_t)job->nunits);
        if (!o)
            return SC_ENOMEM;
        cj->out = o;
        cj->out_cap = job->nunits;
    }
    memset(cj->out, OUT_NONE, (size_t)job->nunits);
    for (int k = 0; k < SC_MAX_DAEMONS; k++) {
        /* a daemon judged slow to answer gets no work and so no chance to
         * show otherwise (its first job waited for shapes, say): while it
         * idles its latency decays and it is tried again */
        if (cj->d[k].sent == 0) {
            c->d[k].overhead *= OVERHEAD_IDLE_DECAY;
            c->d[k].link.latency *= OVERHEAD_IDLE_DECAY;
            c->d[k].link.byte_s *= OVERHEAD_IDLE_DECAY;
            for (int i = 0; i < c->d[k].nrt; i++)
                c->d[k].rt[i] *= RT_IDLE_DECAY;
        }
    }
    memset(cj->d, 0, sizeof cj->d);
    cj->job = job;
    cj->serial = ++c->serial;
    cj->started = 0;
    cj->local_done = 0;
    c->cur = cj;
    return SC_OK;
}

static void prov_park(void *ctx)
{
    sc_cluster *c = ctx;
    SC_ASSERT(c->cur && !c->parked);
    c->parked = c->cur;
    c->parked->started = 1;
    c->cur = NULL;
}

static void prov_resume(void *ctx, const sc_job *job)
{
    sc_cluster *c = ctx;
    SC_ASSERT(c->parked && c->parked->job == job && !c->cur);
    c->cur = c->parked;
    c->parked = NULL;
    /* what came back while other jobs ran (nobody may have read the bus) */
    pump(c, 0, 0);
    for (int i = 0; i < job->nunits; i++)
        c->stats->frame.remote.pipelined_units += c->cur->out[i] == OUT_DONE;
}

void sc_cluster_force(sc_cluster *c)
{
    c->force = 1;
}

static void prov_end(void *ctx)
{
    sc_cluster *c = ctx;
    c->cur->job = NULL;
    c->cur = NULL;
}

/* ---- sc_cluster_wait: heartbeats and challenges ---- */

typedef struct listener {
    uint8_t key[SC_KEY_BYTES];
    sc_bus *bus;
    int64_t id, epoch, seq;     /* challenges come from this listener */
    sc_msg_guard guard;
    struct {
        int64_t id, epoch;
        int busy, verified;
        uint8_t nonce[SC_MSG_NONCE_BYTES];
        double heard;
    } d[SC_MAX_DAEMONS];
    int n;
} listener;

/* An authenticated heartbeat, checked as a world checks it (on_announce),
 * or an answer to this listener's challenge: a daemon counts once it has
 * answered, as in a world. */
static void on_heartbeat(void *ctx, const char *channel, const uint8_t *data, size_t len,
                         int64_t recv_us)
{
    (void)recv_us;
    listener *l = ctx;
    sc_msg m;
    if (sc_msg_open(l->key, &l->guard, data, len, &m) != SC_OK)
        return;
    int announce = !strcmp(channel, "SC_ANNOUNCE");
    sc_msg_announce a;
    if (announce && m.kind == SC_MSG_ANNOUNCE &&
        sc_msg_announce_decode(m.payload, m.len, &a) == SC_OK && a.node == m.node &&
        a.version == SC_MSG_VERSION) {
        int k = 0;
        while (k < l->n && l->d[k].id != a.node)
            k++;
        if (k == l->n && l->n < SC_MAX_DAEMONS)
            l->d[l->n++].id = a.node;
        if (k < l->n && l->d[k].epoch < m.epoch) {
            memset(&l->d[k], 0, sizeof l->d[k]);    /* a new start of it */
            l->d[k].id = a.node;
            l->d[k].epoch = m.epoch;
        }
        if (k < l->n) {
            l->d[k].busy = a.owner_busy;
            l->d[k].heard = sc_wall_now();
            if (!l->d[k].verified)
                challenge(l->bus, l->key, l->id, l->epoch, &l->seq, a.node, m.epoch,
                          l->d[k].nonce);
        }
    } else if (!announce && m.kind == SC_MSG_ANSWER) {
        for (int k = 0; k < l->n; k++)
            if (answers(&m, l->d[k].id, l->d[k].epoch, l->d[k].nonce))
                l->d[k].verified = 1;
    }
    sc_msg_free(&m);
}

/* Daemons heard within SILENT_S that answered and are not owner-busy
 * (sc_stats.now.daemons). */
static int available(const listener *l)
{
    double now = sc_wall_now();
    int n = 0;
    for (int k = 0; k < l->n; k++)
        n += l->d[k].verified && !l->d[k].busy && now - l->d[k].heard <= SILENT_S;
    return n;
}

SC_API int sc_cluster_listen(const sc_world_config *cfg, int k, double timeout_s,
                             sc_cluster_heard *out)
{
    if (out)
        memset(out, 0, sizeof *out);
    if (!cfg || !cfg->cluster || k < 0 || k > SC_MAX_DAEMONS || !(timeout_s >= 0) ||
        !isfinite(timeout_s))
        return sc_set_error(SC_EINVAL);
    if (cfg->internal_cookie != SC_CONFIG_COOKIE)
        return sc_set_error(SC_ENOINIT);
    listener *l = calloc(1, sizeof *l);
    if (!l)
        return sc_set_error(SC_ENOMEM);
    int rc = cfg->key_file ? sc_key_load(cfg->key_file, l->key) : SC_OK;
    uint64_t id = 0;
    if (getrandom(&id, sizeof id, 0) != sizeof id)
        id = (uint64_t)getpid() * 0x9e3779b97f4a7c15ULL ^ (uint64_t)time(NULL);
    l->id = (int64_t)(id >> 1) | 1;
    l->epoch = sc_msg_epoch_new();
    l->guard.epoch = l->epoch;
    sc_bus *bus = NULL;
    char ch[CHANNEL_MAX];
    snprintf(ch, sizeof ch, "SC_RESULT_%016" PRIx64, (uint64_t)l->id);
    if (rc == SC_OK && (sc_bus_open(cfg->cluster, &bus, NULL, 0) != SC_OK ||
                        sc_bus_subscribe(bus, "SC_ANNOUNCE", on_heartbeat, l) != SC_OK ||
                        sc_bus_subscribe(bus, ch, on_heartbeat, l) != SC_OK))
        rc = SC_EIO;
    l->bus = bus;               /* challenges go out on it */
    /* handle what comes until k are heard or the time is up (at least once) */
    double t0 = sc_wall_now(), left = timeout_s;
    int n = 0;
    while (rc == SC_OK) {
        if (sc_bus_handle(bus, k > 0 ? fmin(left, 0.05) : 0) < 0)
            rc = SC_EIO;
        n = available(l);
        left = timeout_s - (sc_wall_now() - t0);
        if (n >= k || left <= 0)
            break;
    }
    if (out && rc == SC_OK) {
        /* what was heard, and what did not open: another key shows here */
        double now = sc_wall_now();
        for (int j = 0; j < l->n; j++) {
            if (now - l->d[j].heard > SILENT_S)
                continue;
            if (!l->d[j].verified)
                out->unverified++;
            else if (l->d[j].busy)
                out->busy++;
        }
        out->daemons = n;
        out->auth_failed = l->guard.dropped_auth;
        sc_bus_counters bc;
        sc_bus_counters_get(bus, &bc);
        out->dropped = l->guard.dropped_format + l->guard.dropped_auth + l->guard.dropped_replay +
                       l->guard.dropped_stale + l->guard.dropped_misaddressed +
                       (long)sc_bus_dropped(&bc);
    }
    sc_bus_close(bus);
    free(l);
    return rc == SC_OK ? n : sc_set_error(rc);
}

SC_API int sc_cluster_wait(const sc_world_config *cfg, int k, double timeout_s)
{
    return sc_cluster_listen(cfg, k, timeout_s, NULL);
}
