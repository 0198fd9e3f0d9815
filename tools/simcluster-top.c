/* simcluster-top - the cluster at a glance (simcluster-top(1)): listens to
 * the daemons' heartbeats (announce_t on SC_ANNOUNCE, daemon/engine.h)
 * and shows one row per daemon: its cores, speed, idle fraction, owner-busy
 * flag and the rate at which it computes units, refreshed every interval
 * (live) or once after a wait (--once, for scripts). It only listens: it
 * sends nothing, so it cannot disturb a running simulation. Every heartbeat
 * is opened and checked as the masters check it; what fails is counted. */
#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "simcluster_net.h"
#include "simcluster.h"

#define MAX_NODES 1024             /* rows the table holds */
#define SILENT_S 10.0              /* a node not heard from this long is marked silent */
#define FORGET_S 60.0              /* and dropped after this long */
#define HOST_COLS 24               /* the host column at most (longer names are cut) */
#define MIN_S 0.1                  /* bounds of --wait and --interval */
#define MAX_S 3600.0


static const char *prog = "simcluster-top";

/* One daemon, as its last heartbeat showed it. */
typedef struct node {
    int64_t id;
    char host[SC_MSG_HOST_MAX];
    int cores, busy;
    double speed, idle;
    double seen_s;                 /* our monotonic clock when it was last heard */
    int64_t time_us, units;        /* its clock and unit counter then */
    double rate;                   /* units/s between its last two heartbeats; < 0: unknown */
} node;

typedef struct top {
    uint8_t key[SC_KEY_BYTES];
    sc_msg_guard guard;            /* counts the dropped messages */
    sc_bus *bus;                   /* counts the dropped datagrams */
    node nodes[MAX_NODES];
    int n;
    long ignored;                  /* heartbeats of new nodes while the table was full */
} top;

typedef struct options {
    const char *url, *key;
    int insecure, once, json, have_wait, have_interval;
    double wait_s, interval_s;
} options;

static volatile sig_atomic_t stop_flag;

static void on_signal(int sig)
{
    (void)sig;
    stop_flag = 1;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Bad usage: one line, exit status 2. */
__attribute__((format(printf, 1, 2))) static int bad(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", prog);
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, " (try --help)\n");
    va_end(ap);
    return 2;
}

static int usage(FILE *f, int status)
{
    fprintf(f,
            "usage: simcluster-top [options]   the cluster's daemons, from their heartbeats\n"
            "      --url URL       udpm:// URL of the cluster (default " SC_CLUSTER_URL ")\n"
            "      --key FILE      cluster key file (simcluster keygen FILE)\n"
            "      --insecure      use the all-zero key (daemons started with --insecure)\n"
            "      --once          listen for --wait seconds, print one table and exit\n"
            "      --wait S        seconds --once listens, %g..%g (1.5)\n"
            "      --interval S    seconds between tables, %g..%g (1)\n"
            "      --json          each table as one JSON object on one line\n"
            "  -h, --help          this text\n"
            "      --version       print the version\n",
            MIN_S, MAX_S, MIN_S, MAX_S);
    return status;
}

static int parse_seconds(const char *text, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    if (errno || end == text || *end || !isfinite(v) || v < MIN_S || v > MAX_S)
        return 0;
    *out = v;
    return 1;
}

/* Read the command line into o: -1 to go on, else the exit status. */
static int parse_args(int argc, char **argv, options *o)
{
    static const struct option longs[] = {
        { "url", required_argument, 0, 'u' },  { "key", required_argument, 0, 'k' },
        { "insecure", no_argument, 0, 'i' },   { "once", no_argument, 0, 'o' },
        { "wait", required_argument, 0, 'w' }, { "interval", required_argument, 0, 't' },
        { "help", no_argument, 0, 'h' },       { "version", no_argument, 0, 'V' },
        { "json", no_argument, 0, 'j' },
        { 0, 0, 0, 0 }
    };
    *o = (options){ .url = SC_CLUSTER_URL, .wait_s = 1.5, .interval_s = 1 };
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":h", longs, NULL)) != -1) {
        const char *opt = argv[optind - 1];
        switch (c) {
        case 'h': return usage(stdout, 0);
        case 'V':
            printf("%s %s\n", prog, SC_VERSION_STRING);
            return 0;
        case 'u':
            if (!*optarg)
                return bad("--url: the URL is empty");
            o->url = optarg;
            break;
        case 'k': o->key = optarg; break;
        case 'i': o->insecure = 1; break;
        case 'o': o->once = 1; break;
        case 'j': o->json = 1; break;
        case 'w':
        case 't':
            if (!parse_seconds(optarg, c == 'w' ? &o->wait_s : &o->interval_s))
                return bad("--%s: '%.64s' is not a number of seconds from 0.1 to 3600",
                           c == 'w' ? "wait" : "interval", optarg);
            *(c == 'w' ? &o->have_wait : &o->have_interval) = 1;
            break;
        case ':': return bad("option %.64s needs a value", opt);
        default:
            if (optopt)
                return bad("unknown option '-%c'", optopt);
            return bad("unknown option '%.64s'", opt);
        }
    }
    if (optind < argc)
        return bad("unexpected argument '%.64s'", argv[optind]);
    if (o->key && o->insecure)
        return bad("--key and --insecure exclude each other");
    if (o->have_wait && !o->once)
        return bad("--wait goes with --once");
    if (o->have_interval && o->once)
        return bad("--interval and --once exclude each other");
    return -1;
}

/* ---- the table ---------------------------------------------------------- */

/* Drop the nodes not heard from for FORGET_S (the order does not matter:
 * rows are sorted when printed). */
static void forget(top *t, double now)
{
    for (int i = 0; i < t->n;)
        if (now - t->nodes[i].seen_s > FORGET_S)
            t->nodes[i] = t->nodes[--t->n];
        else
            i++;
}

/* A valid heartbeat: update its node's row (a new row for a new node). The
 * rate needs two heartbeats; a counter that went back (the daemon
 * restarted) or a clock that did not advance makes it unknown again. */
static void heard(top *t, const sc_msg_announce *a, double now)
{
    node *d = NULL;
    for (int i = 0; i < t->n && !d; i++)
        if (t->nodes[i].id == a->node)
            d = &t->nodes[i];
    if (!d) {
        if (t->n == MAX_NODES)
            forget(t, now);
        if (t->n == MAX_NODES) {
            t->ignored++;
            return;
        }
        d = &t->nodes[t->n++];
        d->id = a->node;
        d->rate = -1;
    } else if (a->time_us > d->time_us && a->units >= d->units) {
        d->rate = (double)(a->units - d->units) * 1e6 / (double)(a->time_us - d->time_us);
    } else {
        d->rate = -1;
    }
    snprintf(d->host, sizeof d->host, "%s", a->host);
    d->cores = a->cores;
    d->busy = a->owner_busy;
    d->speed = a->speed;
    d->idle = a->idle_fraction;
    d->time_us = a->time_us;
    d->units = a->units;
    d->seen_s = now;
}

/* The bus's callback: open the envelope with the guard (which counts what
 * it drops), then take what is on SC_ANNOUNCE as masters do
 * (lib/net/cluster.c): an announce_t of this protocol version from the
 * node that sealed it. */
static void on_message(void *ctx, const char *channel, const uint8_t *data, size_t len,
                       int64_t recv_us)
{
    (void)channel;
    (void)recv_us;
    top *t = ctx;
    sc_msg m;
    if (sc_msg_open(t->key, &t->guard, data, len, &m) != SC_OK)
        return;
    sc_msg_announce a;
    if (m.kind != SC_MSG_ANNOUNCE || sc_msg_announce_decode(m.payload, m.len, &a) != SC_OK ||
        a.node != m.node || a.version != SC_MSG_VERSION)
        t->guard.dropped_format++;
    else
        heard(t, &a, now_s());
    sc_msg_free(&m);
}

/* Rows by host, then by node id. */
static int by_host(const void *pa, const void *pb)
{
    const node *a = *(const node *const *)pa, *b = *(const node *const *)pb;
    int c = strcmp(a->host, b->host);
    if (c)
        return c;
    return (uint64_t)a->id < (uint64_t)b->id ? -1 : (uint64_t)a->id > (uint64_t)b->id;
}

/* A host name as it may be shown: a peer chose these bytes, so anything
 * but printable ASCII becomes '?' (no escape codes reach the terminal),
 * cut to cols. */
static void host_text(const char *host, char *out, int cols)
{
    int i = 0;
    for (; i < cols && host[i]; i++)
        out[i] = host[i] > 0x20 && host[i] < 0x7f ? host[i] : '?';
    out[i] = '\0';
}

/* A rate in at most 9 columns: tenths while they fit in view. */
static const char *rate_text(double v, char *buf, size_t n)
{
    snprintf(buf, n, v < 0 ? "-" : v < 1000 ? "%.1f" : "%.0f", v);
    return buf;
}

static const char *plural(long n, const char *one, const char *many)
{
    return n == 1 ? one : many;
}

/* The footer's totals over the rows heard within SILENT_S. */
typedef struct totals {
    long silent, busy, cores;
    double rate;
} totals;

static totals sum_rows(const node *const *rows, int n, double now)
{
    totals s = { 0, 0, 0, 0 };
    for (int i = 0; i < n; i++) {
        const node *d = rows[i];
        if (now - d->seen_s > SILENT_S) {
            s.silent++;
            continue;
        }
        s.busy += d->busy;
        s.cores += d->cores;
        s.rate += d->rate > 0 ? d->rate : 0;
    }
    return s;
}

/* The table at time now: a header, a row per node, a footer of totals. */
static void print_table(FILE *f, const top *t, double now)
{
    static const node *rows[MAX_NODES];
    int hw = 4;
    for (int i = 0; i < t->n; i++) {
        rows[i] = &t->nodes[i];
        int len = (int)strlen(t->nodes[i].host);
        hw = len > hw ? (len < HOST_COLS ? len : HOST_COLS) : hw;
    }
    qsort(rows, (size_t)t->n, sizeof rows[0], by_host);
    fprintf(f, "%-16s  %-*s  %5s  %12s  %5s  %4s  %9s  %10s\n", "node", hw, "host", "cores",
            "units/s/core", "idle%", "busy", "units/s", "seen-s-ago");
    for (int i = 0; i < t->n; i++) {
        const node *d = rows[i];
        double age = now - d->seen_s;
        int quiet = age > SILENT_S;
        char host[HOST_COLS + 1], sp[32], r[32];
        host_text(d->host, host, hw);
        fprintf(f, "%016" PRIx64 "  %-*s  %5d  %12s  %5.1f  %4s  %9s  %10.1f%s\n",
                (uint64_t)d->id, hw, host, d->cores, rate_text(d->speed, sp, sizeof sp),
                100 * d->idle, d->busy ? "yes" : "no",
                rate_text(quiet ? -1 : d->rate, r, sizeof r), age, quiet ? " silent" : "");
    }
    totals sum = sum_rows(rows, t->n, now);
    fprintf(f, "%d %s", t->n, plural(t->n, "daemon", "daemons"));
    if (sum.silent)
        fprintf(f, " (%ld silent)", sum.silent);
    char r[32];
    sc_bus_counters bc;
    sc_bus_counters_get(t->bus, &bc);
    fprintf(f, ", %ld busy, %ld %s, %s units/s; dropped %ld format, %ld auth, %ld replay, "
            "%ld stale, %llu net, %llu kernel",
            sum.busy, sum.cores, plural(sum.cores, "core", "cores"),
            rate_text(sum.rate, r, sizeof r), t->guard.dropped_format, t->guard.dropped_auth,
            t->guard.dropped_replay, t->guard.dropped_stale,
            (unsigned long long)(sc_bus_dropped(&bc) - bc.kernel),
            (unsigned long long)bc.kernel);
    if (t->ignored)
        fprintf(f, "; %ld %s of new nodes ignored (table full: %d)", t->ignored,
                plural(t->ignored, "heartbeat", "heartbeats"), MAX_NODES);
    fputc('\n', f);
}

/* s as a JSON string. */
static void json_text(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

/* The table as one JSON object on one line (--json): the rows in the same
 * order, with the same numbers, units in the key names; null for a rate
 * not known yet; a silent daemon's rate is null and it is not in the totals. */
static void print_json(FILE *f, const top *t, double now, const char *url)
{
    static const node *rows[MAX_NODES];
    for (int i = 0; i < t->n; i++)
        rows[i] = &t->nodes[i];
    qsort(rows, (size_t)t->n, sizeof rows[0], by_host);
    fputs("{\"url\": ", f);
    json_text(f, url);
    fputs(", \"daemons\": [", f);
    for (int i = 0; i < t->n; i++) {
        const node *d = rows[i];
        double age = now - d->seen_s;
        int quiet = age > SILENT_S;
        char host[SC_MSG_HOST_MAX + 1];
        host_text(d->host, host, SC_MSG_HOST_MAX);     /* printable ASCII only */
        fprintf(f, "%s{\"node\": \"%016" PRIx64 "\", \"host\": ", i ? ", " : "",
                (uint64_t)d->id);
        json_text(f, host);
        fprintf(f, ", \"cores\": %d, \"units_per_s_per_core\": %.6g, \"idle_percent\": %.1f, "
                "\"busy\": %s, \"units_per_s\": ",
                d->cores, d->speed, 100 * d->idle, d->busy ? "true" : "false");
        if (quiet || d->rate < 0)
            fputs("null", f);
        else
            fprintf(f, "%.6g", d->rate);
        fprintf(f, ", \"seen_s_ago\": %.3f, \"silent\": %s}", age, quiet ? "true" : "false");
    }
    totals sum = sum_rows(rows, t->n, now);
    sc_bus_counters bc;
    sc_bus_counters_get(t->bus, &bc);
    fprintf(f, "], \"daemons_total\": %d, \"silent\": %ld, \"busy\": %ld, \"cores\": %ld, "
            "\"units_per_s\": %.6g, \"dropped\": {\"format\": %ld, \"auth\": %ld, "
            "\"replay\": %ld, \"stale\": %ld, \"net\": %llu, \"kernel\": %llu}, "
            "\"ignored_heartbeats\": %ld}\n",
            t->n, sum.silent, sum.busy, sum.cores, sum.rate, t->guard.dropped_format,
            t->guard.dropped_auth, t->guard.dropped_replay, t->guard.dropped_stale,
            (unsigned long long)(sc_bus_dropped(&bc) - bc.kernel), (unsigned long long)bc.kernel,
            t->ignored);
}

/* ---- listening ---------------------------------------------------------- */

/* Open url and subscribe to the heartbeats: the bus, or NULL with why
 * filled (one line). */
static sc_bus *listen_on(const char *url, top *t, char *why, size_t n)
{
    sc_bus *b = NULL;
    if (sc_bus_open(url, &b, why, n) != SC_OK)
        return NULL;
    if (sc_bus_subscribe(b, "SC_ANNOUNCE", on_message, t) != SC_OK) {
        snprintf(why, n, "cannot subscribe to SC_ANNOUNCE");
        sc_bus_close(b);
        return NULL;
    }
    return b;
}

int main(int argc, char **argv)
{
    options o;
    int rc = parse_args(argc, argv, &o);
    if (rc >= 0)
        return rc;
    static top t;
    if (!o.key && !o.insecure) {
        fprintf(stderr, "%s: a cluster key is required: --key FILE (make one with "
                "'simcluster keygen FILE'), or --insecure to use the all-zero key\n", prog);
        return 1;
    }
    if (o.key) {
        errno = 0;
        rc = sc_key_load(o.key, t.key);
        if (rc != SC_OK) {
            int e = rc == SC_EIO ? errno : 0;
            fprintf(stderr, "%s: key file %s: %s%s%s\n", prog, o.key, sc_strerror(rc),
                    e ? ": " : "", e ? strerror(e) : "");
            return 1;
        }
    }

    /* SIGINT and SIGTERM only set stop_flag. They are blocked, and let
     * through only inside ppoll(), so a signal always wakes the loop at
     * once. */
    sigset_t block, open_mask;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    sigprocmask(SIG_BLOCK, &block, &open_mask);
    sigdelset(&open_mask, SIGINT);
    sigdelset(&open_mask, SIGTERM);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    char why[512];
    sc_bus *l = t.bus = listen_on(o.url, &t, why, sizeof why);
    if (!l) {
        fprintf(stderr, "%s: cannot listen on %s: %s\n", prog, o.url, why);
        return 1;
    }
    int fd = sc_bus_fd(l), tty = !o.once && !o.json && isatty(STDOUT_FILENO), shown = 0;
    double period = o.once ? o.wait_s : o.interval_s, next = now_s() + period;
    rc = 0;
    while (!stop_flag) {
        double now = now_s(), left = next - now;
        if (left <= 0) {
            forget(&t, now);
            if (tty)
                printf("\033[H\033[2J%s %s on %s\n\n", prog, SC_VERSION_STRING, o.url);
            else if (shown && !o.json)
                putchar('\n');
            if (o.json)
                print_json(stdout, &t, now, o.url);
            else
                print_table(stdout, &t, now);
            fflush(stdout);
            shown = 1;
            if (o.once)
                break;
            next += period;
            if (next <= now)
                next = now + period;    /* fell behind (suspended): start again */
            continue;
        }
        struct timespec ts = { (time_t)left, (long)((left - floor(left)) * 1e9) };
        struct pollfd pf = { fd, POLLIN, 0 };
        int r = ppoll(&pf, 1, &ts, &open_mask);
        if (r < 0 && errno != EINTR) {
            fprintf(stderr, "%s: poll: %s\n", prog, strerror(errno));
            rc = 1;
            break;
        }
        if (r > 0 && (pf.revents & (POLLERR | POLLHUP | POLLNVAL) ||
                      ((pf.revents & POLLIN) && sc_bus_handle(l, 0) < 0))) {
            fprintf(stderr, "%s: receiving from %s failed\n", prog, o.url);
            rc = 1;
            break;
        }
    }
    sc_bus_close(l);
    explicit_bzero(t.key, sizeof t.key);
    return rc;
}
