/* simclusterd - the worker daemon (simclusterd(8), docs/DESIGN.md section 7.3): the
 * process around the engine of daemon/engine.h. It reads its options
 * (command line over simcluster.conf(5)) and the cluster key, gives up root,
 * joins the LCM group and serves until SIGTERM or SIGINT; SIGHUP re-reads
 * the configuration file, SIGUSR1 logs the counters. It runs in the
 * foreground (systemd and the tests start it) and never executes anything
 * it receives. Signals are blocked in every thread and taken by one thread
 * in sigwait(), so no code runs in a signal handler. */
#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <grp.h>
#include <math.h>
#include <pthread.h>
#include <pwd.h>
#include <sched.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <syslog.h>
#include <unistd.h>

#include "simcluster_net.h"
#include "engine.h"
#include "simcluster.h"

#define DEFAULT_CONFIG "/etc/simcluster/simclusterd.conf"
#define LINE_BYTES 1024            /* a config line, without its newline */
#define CONFIG_BYTES (1L << 20)    /* a whole config file */
#define ERR_BYTES 2048

/* Everything the options set; strings fit one config line. */
typedef struct settings {
    char url[LINE_BYTES + 1], key_file[LINE_BYTES + 1], user[LINE_BYTES + 1];
    int insecure, threads, idle_priority, syslog, verbose;  /* threads 0: the CPUs we may use */
    int dedicated;                 /* no owner: always idle, never busy */
    double busy_threshold, heartbeat, spin;
    long long node_id;             /* 0: random */
} settings;

enum kind { STR, BOOL, INT, I64, DBL };
enum { ROW_URL, ROW_KEY, ROW_INSECURE, ROW_THREADS, ROW_BUSY, ROW_HEARTBEAT, ROW_NODE, ROW_USER,
       ROW_IDLE, ROW_SYSLOG, ROW_VERBOSE, ROW_DEDICATED, ROW_SPIN, NROWS };

/* The options, one row each: config key, long option, type, field, bounds
 * (lo excluded when lo_open), the value a BOOL flag sets, and whether SIGHUP
 * applies a change (live) or it needs a restart. Defaults: settings_default. */
static const struct row {
    const char *key, *flag;
    enum kind kind;
    size_t off;
    double lo, hi;
    int lo_open;
    const char *flag_value;
    int live;
} rows[] = {
#define ROW(k, f, t, name) .key = k, .flag = f, .kind = t, .off = offsetof(settings, name)
    [ROW_URL] = { ROW("url", "url", STR, url) },
    [ROW_KEY] = { ROW("key_file", "key", STR, key_file) },
    [ROW_INSECURE] = { ROW("insecure", "insecure", BOOL, insecure), .flag_value = "yes" },
    [ROW_THREADS] = { ROW("threads", "threads", INT, threads), .lo = 1,
                      .hi = SC_SERVE_MAX_THREADS },
    [ROW_BUSY] = { ROW("busy_threshold", "busy-threshold", DBL, busy_threshold), .lo = 0, .hi = 1,
                   .lo_open = 1, .live = 1 },
    [ROW_HEARTBEAT] = { ROW("heartbeat", "heartbeat", DBL, heartbeat), .lo = 0.01, .hi = 10,
                        .live = 1 },
    [ROW_NODE] = { ROW("node_id", "node-id", I64, node_id), .lo = 1 },
    [ROW_USER] = { ROW("user", "user", STR, user) },
    [ROW_IDLE] = { ROW("idle_priority", "no-idle-priority", BOOL, idle_priority),
                   .flag_value = "no" },
    [ROW_SYSLOG] = { ROW("syslog", "syslog", BOOL, syslog), .flag_value = "yes" },
    [ROW_VERBOSE] = { ROW("verbose", "verbose", BOOL, verbose), .flag_value = "yes", .live = 1 },
    [ROW_DEDICATED] = { ROW("dedicated", "dedicated", BOOL, dedicated), .flag_value = "yes" },
    [ROW_SPIN] = { ROW("spin", "spin", DBL, spin), .lo = 0, .hi = SC_SERVE_SPIN_MAX },
#undef ROW
};

static void settings_default(settings *s)
{
    memset(s, 0, sizeof *s);
    snprintf(s->url, sizeof s->url, "%s", SC_CLUSTER_URL);
    snprintf(s->user, sizeof s->user, "nobody");
    s->busy_threshold = 0.5;
    s->heartbeat = 0.2;
    s->spin = SC_SERVE_SPIN_S;
    s->idle_priority = 1;
}

/* Row r's field in settings s, and the bytes each kind of field takes. */
#define FIELD(s, r) ((void *)((char *)(s) + (r)->off))
static const size_t kind_size[] = { [STR] = LINE_BYTES + 1, [BOOL] = sizeof(int),
                                    [INT] = sizeof(int), [I64] = sizeof(long long),
                                    [DBL] = sizeof(double) };

/* Parse text as row r's value into s: 0, or -1 with why filled. */
static int set_value(settings *s, const struct row *r, const char *text, char *why, size_t n)
{
    char *end = NULL;
    errno = 0;
    switch (r->kind) {
    case STR:
        if (!*text || strlen(text) > LINE_BYTES) {
            snprintf(why, n, "the value must be 1 to %d bytes", LINE_BYTES);
            return -1;
        }
        snprintf(FIELD(s, r), LINE_BYTES + 1, "%s", text);
        return 0;
    case BOOL:
        if (strcmp(text, "yes") && strcmp(text, "no")) {
            snprintf(why, n, "'%.64s' is not yes or no", text);
            return -1;
        }
        *(int *)FIELD(s, r) = !strcmp(text, "yes");
        return 0;
    case INT: {
        long v = strtol(text, &end, 10);
        if (end == text || *end || errno || v < r->lo || v > r->hi) {
            snprintf(why, n, "'%.64s' is not an integer from %g to %g", text, r->lo, r->hi);
            return -1;
        }
        *(int *)FIELD(s, r) = (int)v;
        return 0;
    }
    case I64: {
        int hex = text[0] == '0' && (text[1] == 'x' || text[1] == 'X');
        long long v = strtoll(text, &end, hex ? 16 : 10);
        if (end == text || *end || errno || v < r->lo) {
            snprintf(why, n, "'%.64s' is not a positive 64-bit integer (decimal or 0x hex)", text);
            return -1;
        }
        *(long long *)FIELD(s, r) = v;
        return 0;
    }
    case DBL: {
        double v = strtod(text, &end);
        if (end == text || *end || errno || !isfinite(v) || v < r->lo || v > r->hi ||
            (r->lo_open && v == r->lo)) {
            snprintf(why, n, "'%.64s' is not a number in %c%g, %g]", text, r->lo_open ? '(' : '[',
                     r->lo, r->hi);
            return -1;
        }
        *(double *)FIELD(s, r) = v;
        return 0;
    }
    }
    return -1;
}

/* Row r's value in s as text, for the reload log. */
static const char *value_text(settings *s, const struct row *r, char *buf, size_t n)
{
    void *f = FIELD(s, r);
    switch (r->kind) {
    case STR: snprintf(buf, n, "%s", *(char *)f ? (char *)f : "(none)"); break;
    case BOOL: snprintf(buf, n, "%s", *(int *)f ? "yes" : "no"); break;
    case INT: snprintf(buf, n, *(int *)f ? "%d" : "auto", *(int *)f); break;
    case I64: snprintf(buf, n, *(long long *)f ? "%lld" : "random", *(long long *)f); break;
    case DBL: snprintf(buf, n, "%g", *(double *)f); break;
    }
    return buf;
}

/* t without its leading and trailing white space (t is changed). */
static char *trim(char *t)
{
    while (isspace((unsigned char)*t))
        t++;
    size_t n = strlen(t);
    while (n > 0 && isspace((unsigned char)t[n - 1]))
        t[--n] = '\0';
    return t;
}

/* Read a config file over s: 0, or -1 with err = "FILE:LINE: message" (or
 * "FILE: message"). Lines are "key = value", blank, or '#' comments. */
static int config_read(const char *path, settings *s, char *err, size_t errlen)
{
    FILE *f = fopen(path, "re");
    struct stat st;
    if (!f || fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        snprintf(err, errlen, "%s: %s", path, !f ? strerror(errno) : "not a regular file");
        if (f)
            fclose(f);
        return -1;
    }
    char line[LINE_BYTES + 1], why[512] = "", bad[256];
    long no = 0, total = 0, seen[NROWS] = { 0 };    /* seen: the line that set each key */
    int c = 0;
    while (!*why && c != EOF) {
        size_t n = 0;
        int too_long = 0, nul = 0;
        while ((c = getc(f)) != EOF && c != '\n' && ++total <= CONFIG_BYTES) {
            nul |= c == '\0';
            if (n < LINE_BYTES)
                line[n++] = (char)c;
            else
                too_long = 1;
        }
        if (c == EOF && n == 0 && !too_long)
            break;
        line[n] = '\0';
        no++;
        if (total > CONFIG_BYTES) {
            snprintf(why, sizeof why, "the file is longer than %ld bytes", CONFIG_BYTES);
            break;
        }
        char *k = trim(line), *v;
        if (too_long || nul) {
            snprintf(why, sizeof why, too_long ? "line longer than %d bytes" : "NUL byte in line",
                     LINE_BYTES);
            break;
        }
        if (!*k || *k == '#')
            continue;
        if (!(v = strchr(k, '='))) {
            snprintf(why, sizeof why, "missing '=' (lines are: key = value)");
            break;
        }
        *v = '\0';
        k = trim(k);
        v = trim(v + 1);
        int i = 0;
        while (i < NROWS && strcmp(rows[i].key, k))
            i++;
        if (i == NROWS)
            snprintf(why, sizeof why, "unknown key '%.64s'", k);
        else if (seen[i])
            snprintf(why, sizeof why, "%s is set twice (first on line %ld)", rows[i].key, seen[i]);
        else if (set_value(s, &rows[i], v, bad, sizeof bad) == 0)
            seen[i] = no;
        else
            snprintf(why, sizeof why, "%s: %s", rows[i].key, bad);
        if (!*why && seen[ROW_KEY] && seen[ROW_INSECURE] && s->insecure)
            snprintf(why, sizeof why, "key_file (line %ld) and insecure = yes exclude each other",
                     seen[ROW_KEY]);
    }
    if (!*why && ferror(f))
        snprintf(why, sizeof why, "read error");
    fclose(f);
    if (*why)
        snprintf(err, errlen, "%s:%ld: %s", path, no, why);
    return *why ? -1 : 0;
}

/* The command line wins: copy the options it set (mask: 1 << row) over s.
 * A key on the command line cancels insecure from the file, and back. */
static void settings_merge(settings *s, settings *cli, unsigned mask)
{
    for (int i = 0; i < NROWS; i++)
        if (mask & 1u << i)
            memcpy(FIELD(s, &rows[i]), FIELD(cli, &rows[i]), kind_size[rows[i].kind]);
    if (mask & 1u << ROW_KEY && !(mask & 1u << ROW_INSECURE))
        s->insecure = 0;
    if (mask & 1u << ROW_INSECURE && !(mask & 1u << ROW_KEY))
        s->key_file[0] = '\0';
}

/* ---- logging: stderr "simclusterd[PID]: message" or syslog(3) ---------- */
static atomic_int log_verbose;
static int log_syslog;            /* set before any thread starts */

/* One line, one write(2): lines from several threads never interleave.
 * Control characters (a peer's host name, say) are shown as '?'. This is
 * also the engine's sc_serve_config.log. */
static void log_line(void *ctx, int prio, const char *msg)
{
    (void)ctx;
    if (prio >= LOG_DEBUG && !atomic_load(&log_verbose))
        return;
    char line[ERR_BYTES];
    int head = log_syslog ? 0 : snprintf(line, sizeof line, "simclusterd[%ld]: ", (long)getpid());
    size_t n = (size_t)head;
    for (const char *p = msg; *p && n < sizeof line - 2; p++)
        line[n++] = iscntrl((unsigned char)*p) ? '?' : *p;
    line[n] = '\0';
    if (log_syslog) {
        syslog(prio, "%s", line);
        return;
    }
    line[n++] = '\n';
    if (write(STDERR_FILENO, line, n) < 0)
        return;    /* nowhere left to say it */
}

__attribute__((format(printf, 2, 3))) static void logf_(int prio, const char *fmt, ...)
{
    if (prio >= LOG_DEBUG && !atomic_load(&log_verbose))
        return;
    char msg[ERR_BYTES];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    log_line(NULL, prio, msg);
}

/* A start-up error after the options are read: logged (and on the
 * terminal too when logging goes to syslog), then exit 1. */
__attribute__((format(printf, 1, 2), noreturn)) static void fatal(const char *fmt, ...)
{
    char msg[ERR_BYTES];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    log_line(NULL, LOG_ERR, msg);
    if (log_syslog && isatty(STDERR_FILENO))
        fprintf(stderr, "simclusterd: %s\n", msg);
    exit(1);
}

static void log_counters(sc_serve *s)
{
    sc_serve_counters c;
    sc_serve_counters_get(s, &c);
    logf_(LOG_INFO,
          "counters: node=%016llx epoch=%016llx units=%ld results=%ld unit_errors=%ld "
          "shapes=%ld shape_requests=%ld dropped_format=%ld dropped_auth=%ld "
          "dropped_replay=%ld dropped_stale=%ld dropped_misaddressed=%ld dropped_net=%ld "
          "dropped_kernel=%ld challenges=%ld duplicates=%ld heartbeats=%ld spin_hits=%ld "
          "idle=%.3f owner_busy=%d",
          (unsigned long long)c.node, (unsigned long long)c.epoch, c.units, c.results,
          c.unit_errors, c.shapes, c.shape_requests, c.dropped_format, c.dropped_auth,
          c.dropped_replay, c.dropped_stale, c.dropped_misaddressed, c.dropped_net,
          c.dropped_kernel, c.challenges, c.duplicates, c.heartbeats, c.spin_hits,
          c.idle_fraction, c.owner_busy);
}

/* ---- the signal thread ------------------------------------------------- */
typedef struct daemon_state {
    sc_serve *serve;
    sc_serve_config cfg;          /* as running (the key zeroed after create) */
    settings running, cli;        /* running: what is in effect now */
    unsigned cli_mask;
    const char *config;           /* NULL: started without a file */
    sigset_t signals;
} daemon_state;
static atomic_int quitting;

/* SIGHUP: re-read the same file, command-line options still winning; apply
 * the live options, say which others changed and need a restart. A bad
 * file changes nothing. */
static void reload(daemon_state *d)
{
    if (!d->config) {
        logf_(LOG_INFO, "SIGHUP: started without a configuration file, nothing to re-read");
        return;
    }
    settings n;
    char err[ERR_BYTES], a[LINE_BYTES + 1], b[LINE_BYTES + 1];
    settings_default(&n);
    if (config_read(d->config, &n, err, sizeof err) != 0) {
        logf_(LOG_ERR, "reload: %s; keeping the old configuration", err);
        return;
    }
    settings_merge(&n, &d->cli, d->cli_mask);
    sc_serve_config c = d->cfg;
    c.busy_threshold = n.busy_threshold;
    c.heartbeat_s = n.heartbeat;
    if ((c.busy_threshold != d->cfg.busy_threshold || c.heartbeat_s != d->cfg.heartbeat_s) &&
        sc_serve_reload(d->serve, &c) != SC_OK) {
        logf_(LOG_ERR, "reload: the engine refused the new values; keeping the old configuration");
        return;
    }
    d->cfg = c;
    int changes = 0;
    for (int i = 0; i < NROWS; i++) {
        const struct row *r = &rows[i];
        size_t len = r->kind == STR ? strlen(FIELD(&n, r)) + 1 : kind_size[r->kind];
        if (!memcmp(FIELD(&d->running, r), FIELD(&n, r), len))
            continue;
        changes++;
        value_text(&d->running, r, a, sizeof a);
        value_text(&n, r, b, sizeof b);
        if (r->live) {
            logf_(LOG_INFO, "reload: %s %s -> %s", r->key, a, b);
            memcpy(FIELD(&d->running, r), FIELD(&n, r), kind_size[r->kind]);
        } else {
            logf_(LOG_WARNING, "reload: %s %s -> %s needs a restart; still %s", r->key, a, b, a);
        }
    }
    atomic_store(&log_verbose, d->running.verbose);
    logf_(LOG_INFO, "reloaded %s: %d change%s", d->config, changes, changes == 1 ? "" : "s");
}

static void *signal_thread(void *arg)
{
    daemon_state *d = arg;
    for (;;) {
        int sig = 0;
        if (sigwait(&d->signals, &sig) != 0)
            continue;
        if (atomic_load(&quitting))
            return NULL;
        if (sig == SIGTERM || sig == SIGINT) {
            logf_(LOG_INFO, "stopping (%s)", sig == SIGTERM ? "SIGTERM" : "SIGINT");
            sc_serve_stop(d->serve);
        } else if (sig == SIGHUP) {
            reload(d);
        } else if (sig == SIGUSR1) {
            log_counters(d->serve);
        }
    }
}

/* ---- start-up ---------------------------------------------------------- */
/* Become user (not root) for good, then check that root cannot come back. */
static void drop_root(const char *user)
{
    struct passwd *pw = getpwnam(user);
    if (!pw)
        fatal("refusing to run as root: no user '%s' to switch to (give --user)", user);
    uid_t uid = pw->pw_uid;
    gid_t gid = pw->pw_gid;
    if (uid == 0 || gid == 0)
        fatal("refusing to run as root: user '%s' has user or group id 0 (give --user)", user);
    if (setgroups(0, NULL) != 0 || setresgid(gid, gid, gid) != 0 || setresuid(uid, uid, uid) != 0)
        fatal("refusing to run as root: cannot switch to user '%s': %s", user, strerror(errno));
    if (getuid() == 0 || geteuid() == 0 || getgid() == 0 || getegid() == 0 || setuid(0) != -1 ||
        setgid(0) != -1)
        fatal("refusing to run as root: root privileges are still there after switching to '%s'",
              user);
    if (prctl(PR_SET_NO_NEW_PRIVS, 1L, 0L, 0L, 0L) != 0)
        logf_(LOG_WARNING, "cannot set no_new_privs: %s", strerror(errno));
    logf_(LOG_DEBUG, "running as user %s (uid %ld, gid %ld)", user, (long)uid, (long)gid);
}

static int usage(FILE *f, int status)
{
    fprintf(f,
            "usage: simclusterd [options]   the simcluster worker daemon (simclusterd(8))\n"
            "  -c, --config FILE      configuration file (default " DEFAULT_CONFIG " if any)\n"
            "      --url URL          LCM URL of the cluster (default " SC_CLUSTER_URL ")\n"
            "      --key FILE         cluster key file (simcluster keygen FILE)\n"
            "      --insecure         run without a key (the all-zero key)\n"
            "      --threads N        compute threads, 1..%d (default: the CPUs it may use)\n"
            "      --busy-threshold F owner busy above this CPU fraction, 0 < F <= 1 (0.5)\n"
            "      --heartbeat S      announce period in seconds, 0.01..10 (0.2)\n"
            "      --node-id N        this daemon's id, a positive integer (default random)\n"
            "      --user NAME        account to switch to when started as root (nobody)\n"
            "      --no-idle-priority compute threads at normal priority (not nice 19, idle)\n"
            "      --dedicated        a compute node with no owner: report all CPUs idle, never busy\n"
            "      --spin S           an idle compute thread polls S seconds for the next unit\n"
            "                         before it sleeps, 0..0.1 (0.002; 0: sleep at once)\n"
            "      --syslog           log to syslog (daemon facility), not standard error\n"
            "  -v, --verbose          log debug messages too\n"
            "  -h, --help             this text\n"
            "      --version          print the version\n",
            SC_SERVE_MAX_THREADS);
    return status;
}

/* Read the command line into cli/mask: -1 to go on, else the exit status. */
static int parse_args(int argc, char **argv, settings *cli, unsigned *mask, const char **config)
{
    struct option lo[NROWS + 4];
    for (int i = 0; i < NROWS; i++)
        lo[i] = (struct option){ rows[i].flag, rows[i].kind == BOOL ? no_argument
                                                                     : required_argument,
                                 NULL, 256 + i };
    lo[NROWS] = (struct option){ "config", required_argument, NULL, 'c' };
    lo[NROWS + 1] = (struct option){ "help", no_argument, NULL, 'h' };
    lo[NROWS + 2] = (struct option){ "version", no_argument, NULL, 'V' };
    lo[NROWS + 3] = (struct option){ NULL, 0, NULL, 0 };
    char why[512];
    int o;
    opterr = 0;
    while ((o = getopt_long(argc, argv, ":c:hv", lo, NULL)) != -1) {
        const char *opt = argv[optind - 1];
        if (o == 'v')
            o = 256 + ROW_VERBOSE;
        if (o == 'h')
            return usage(stdout, 0);
        if (o == 'V') {
            printf("simclusterd %d.%d.%d\n", SC_VERSION_MAJOR, SC_VERSION_MINOR, SC_VERSION_PATCH);
            return 0;
        }
        if (o == 'c') {
            *config = optarg;
        } else if (o == ':') {
            fprintf(stderr, "simclusterd: option %.64s needs a value (try --help)\n", opt);
            return 2;
        } else if (o == '?') {
            if (optopt)
                fprintf(stderr, "simclusterd: unknown option '-%c' (try --help)\n", optopt);
            else
                fprintf(stderr, "simclusterd: unknown option '%.64s' (try --help)\n", opt);
            return 2;
        } else {
            const struct row *r = &rows[o - 256];
            if (set_value(cli, r, r->kind == BOOL ? r->flag_value : optarg, why, sizeof why)) {
                fprintf(stderr, "simclusterd: --%s: %s (try --help)\n", r->flag, why);
                return 2;
            }
            *mask |= 1u << (o - 256);
        }
    }
    if (optind < argc) {
        fprintf(stderr, "simclusterd: unexpected argument '%.64s' (try --help)\n", argv[optind]);
        return 2;
    }
    if ((*mask & 1u << ROW_KEY) && (*mask & 1u << ROW_INSECURE)) {
        fprintf(stderr, "simclusterd: --key and --insecure exclude each other (try --help)\n");
        return 2;
    }
    return -1;
}

/* The default thread count: the CPUs this process may run on. */
static int cpus_usable(void)
{
    cpu_set_t set;
    long n = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set)
                                                         : sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > SC_SERVE_MAX_THREADS ? SC_SERVE_MAX_THREADS : (int)n;
}

int main(int argc, char **argv)
{
    static daemon_state d;
    settings_default(&d.cli);
    int rc = parse_args(argc, argv, &d.cli, &d.cli_mask, &d.config);
    if (rc >= 0)
        return rc;
    /* Signals blocked before any thread exists (LCM may start one in
     * sc_serve_create), so all inherit the mask and only sigwait sees them. */
    sigemptyset(&d.signals);
    for (const int *sig = (const int[]){ SIGTERM, SIGINT, SIGHUP, SIGUSR1, 0 }; *sig; sig++)
        sigaddset(&d.signals, *sig);
    pthread_sigmask(SIG_BLOCK, &d.signals, NULL);
    signal(SIGPIPE, SIG_IGN);

    char err[ERR_BYTES];
    if (!d.config && access(DEFAULT_CONFIG, F_OK) == 0)
        d.config = DEFAULT_CONFIG;
    settings_default(&d.running);
    if (d.config && config_read(d.config, &d.running, err, sizeof err) != 0) {
        fprintf(stderr, "simclusterd: %s\n", err);
        return 1;
    }
    settings *s = &d.running;
    settings_merge(s, &d.cli, d.cli_mask);
    atomic_store(&log_verbose, s->verbose);
    if (s->syslog) {
        openlog("simclusterd", LOG_PID | LOG_NDELAY, LOG_DAEMON);
        log_syslog = 1;
    }
    logf_(LOG_DEBUG, "configuration file: %s", d.config ? d.config : "(none)");

    d.cfg = sc_serve_config_default();
    d.cfg.url = s->url;
    d.cfg.threads = s->threads ? s->threads : cpus_usable();
    d.cfg.busy_threshold = s->busy_threshold;
    d.cfg.heartbeat_s = s->heartbeat;
    d.cfg.node_id = s->node_id;
    d.cfg.idle_priority = s->idle_priority;
    d.cfg.dedicated = s->dedicated;
    d.cfg.spin_s = s->spin;
    d.cfg.log = log_line;
    if (s->insecure) {
        memset(d.cfg.key, 0, sizeof d.cfg.key);
    } else if (!s->key_file[0]) {
        fatal("a cluster key is required: --key FILE or key_file (make one with "
              "'simcluster keygen FILE'), or --insecure to run without one");
    } else {
        errno = 0;
        rc = sc_key_load(s->key_file, d.cfg.key);
        if (rc != SC_OK)
            fatal("key file %s: %s%s%s", s->key_file, sc_strerror(rc),
                  rc == SC_EIO && errno ? ": " : "", rc == SC_EIO && errno ? strerror(errno) : "");
    }

    /* The engine opens its socket before root is given up (it starts no
     * thread until sc_serve_run), so that the kernel gives it the receive
     * buffer it asks for whatever net.core.rmem_max says (SO_RCVBUFFORCE). */
    rc = sc_serve_create(&d.cfg, &d.serve);
    explicit_bzero(d.cfg.key, sizeof d.cfg.key);    /* the engine holds its copy */
    if (rc == SC_EIO) {
        char why[ERR_BYTES] = "cannot open this URL";
        sc_bus *b = NULL;
        if (sc_bus_open(s->url, &b, why, sizeof why) == SC_OK)
            sc_bus_close(b);
        fatal("cannot start serving on %s: %s", s->url, why);
    }
    if (rc != SC_OK)
        fatal("cannot start serving on %s: %s", s->url, sc_strerror(rc));
    if (getuid() == 0 || geteuid() == 0)
        drop_root(s->user);
    else if (d.cli_mask & 1u << ROW_USER)
        logf_(LOG_DEBUG, "not started as root: --user %s not needed", s->user);
    if (s->insecure)
        logf_(LOG_WARNING, "insecure: running with the all-zero key, anyone who can reach %s "
              "can send this daemon work and forge its results", s->url);

    pthread_t sig_thread;
    if ((rc = pthread_create(&sig_thread, NULL, signal_thread, &d)) != 0)
        fatal("cannot start the signal thread: %s", strerror(rc));
    rc = sc_serve_run(d.serve);    /* logs "serving on URL as node ID with N threads" */
    if (rc != SC_OK)
        logf_(LOG_ERR, "serving stopped: %s", sc_strerror(rc));
    log_counters(d.serve);

    /* Wake the signal thread with a signal it waits for; it sees quitting. */
    atomic_store(&quitting, 1);
    pthread_kill(sig_thread, SIGUSR1);
    pthread_join(sig_thread, NULL);
    sc_serve_destroy(d.serve);
    logf_(LOG_INFO, "stopped");
    closelog();
    return rc == SC_OK ? 0 : 1;
}
