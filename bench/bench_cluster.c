/* bench_cluster.c - simclusterd daemons on this host (LCM, ttl=0), three
 * measurements (issue "simclusterd", docs/DESIGN.md section 10):
 *   scaling   the bolts/nuts drop with one local worker and 0, 1, 2, ...
 *             one-thread daemons: wall time, speedup over no daemons, the
 *             share of units daemons computed, recomputed units, and the
 *             communication time per frame (packing, sealing, sending,
 *             receiving and merging on the master), the time jobs took
 *             from dispatch to their last result and, of it, the time spent
 *             waiting for daemons after the local work was done; the final
 *             state's hash is compared with the local run's ("-" unless
 *             the first daemon count is 0). The rows take turns, one run
 *             each per round, and the speedup is the median of each round's
 *             ratio to that round's 0-daemon run: on a shared machine a
 *             slow minute falls on every row alike (it would fall on one
 *             row alone if each row ran its runs in a block).
 *   model     a prediction of k one-thread daemons (up to 15) from
 *             measured costs: the frame's work outside units, its jobs'
 *             least makespan on n nodes (sc_stats.frame.sched.ideal_makespan_s), the
 *             work by wire bytes per second of it, the daemon's round trip
 *             and the master's time per byte shipped (see model() below);
 *             checked against one daemon measured.
 *   fg        a CPU-bound program pinned to one CPU, alone and next to a
 *             one-thread daemon pinned to the same CPU that is kept full of
 *             units (the master sends it everything), with the daemon at
 *             nice 19 + SCHED_IDLE and at plain priority: the slowdown.
 *   busy      a daemon (busy threshold 0.5) whose CPU an owner's program
 *             takes over while the master runs: the time until it reports
 *             owner-busy and the time until the master stops sending it
 *             work.
 *   With -t local the frames run by motion groups in the local time-of-
 *             impact mode (-g: motion groups in the world mode), so that most
 *             units are groups' whole frames; the messages per frame and daemon (units
 *             out, results in) are counted, and the groups' units whose
 *             results were in when the pile's frame ended (piped/fr).
 *   -S bin    the dense bin (sc_scene_bin) instead of the drop.
 *   -D        scaling's daemons run --dedicated --no-idle-priority (a CPU
 *             set aside for the cluster: on a shared machine the others'
 *             load would otherwise make them offer little and run last).
 *   -G LIST   scaling: each row's sc_world_config.cluster_min_gain, in the
 *             order of -d (0: the default; negative: no job-level
 *             worth-it rule), e.g. -d 0,1,1 -G 0,0,-1 for one daemon with
 *             and without it, side by side.
 * usage: bench_cluster [-r RUNS] [-s SECONDS] [-n BODIES] [-d 0,1,2,...]
 *                      [-x DAEMON] [-u LCM-URL] [-p scaling,model,fg,busy]
 *                      [-t world|local] [-g] [-S drop|bin] [-D] [-G LIST]
 * The daemon binary defaults to daemon/simclusterd next to this bench's
 * build directory (build/bench/../daemon/simclusterd). */
#include <errno.h>
#include <stddef.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench_util.h"
#include "cluster.h"
#include "simcluster_net.h"
#include "world.h"
#include "simcluster.h"

#define DT 0.01
#define MAX_RUNS 15
#define MAX_D 64

static char url[160], key_path[64], daemon_bin[512];
static int ncpu;
static int toi_mode = SC_TOI_WORLD, groups;     /* the worlds' (-t, -g) */
static int bin_scene;                           /* -S bin: sc_scene_bin */
static double min_gain;                         /* the worlds' cluster_min_gain */
static int dedicated;                           /* -D: scaling's daemons --dedicated */

static double median(double *x, int n)
{
    qsort(x, (size_t)n, sizeof *x, cmp_double);
    return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

static void pin(pid_t pid, int cpu)
{
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu % ncpu, &set);
    sched_setaffinity(pid, sizeof set, &set);
}

static void unpin(void)
{
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int i = 0; i < ncpu; i++)
        CPU_SET(i, &set);
    sched_setaffinity(0, sizeof set, &set);
}

/* A daemon: one compute thread, pinned to cpu (< 0: not pinned). */
static pid_t start_daemon(int id, int cpu, double threshold, int idle_priority)
{
    pid_t pid = fork();
    if (pid == 0) {
        if (cpu >= 0)
            pin(0, cpu);
        char idbuf[32], thr[32];
        snprintf(idbuf, sizeof idbuf, "%d", id);
        snprintf(thr, sizeof thr, "%g", threshold);
        int fd = open("/dev/null", 1);
        if (fd >= 0) {
            dup2(fd, 2);
            dup2(fd, 1);
        }
        const char *argv[20] = { daemon_bin, "--url", url, "--key", key_path, "--threads", "1",
                                 "--node-id", idbuf, "--busy-threshold", thr, "--heartbeat",
                                 "0.1", NULL };
        int a = 13;
        if (!idle_priority)
            argv[a++] = "--no-idle-priority";
        if (dedicated && idle_priority) {
            /* a CPU set aside for the cluster: all idle, normal priority */
            argv[a++] = "--dedicated";
            argv[a++] = "--no-idle-priority";
        }
        argv[a] = NULL;
        execv(daemon_bin, (char **)argv);
        _exit(127);
    }
    return pid;
}

static void stop_daemon(pid_t pid)
{
    if (pid <= 0)
        return;
    kill(pid, SIGTERM);
    int st;
    waitpid(pid, &st, 0);
}

static sc_world *make_world_on(int n, int cluster, int workers)
{
    sc_world_config c = sc_world_config_default();
    c.workers = workers;
    c.toi_mode = toi_mode;
    c.motion_groups = groups;
    c.cluster_min_gain = min_gain;
    if (cluster) {
        c.cluster = url;
        c.key_file = key_path;
    }
    sc_world *w = sc_world_create(&c);
    if (!w || (bin_scene ? sc_scene_bin(w, n, 1) : sc_scene_bolts_nuts(w, n, 1)) < 0) {
        fprintf(stderr, "bench_cluster: %s\n", sc_strerror(sc_last_error()));
        exit(1);
    }
    return w;
}

static sc_world *make_world(int n, int cluster)
{
    return make_world_on(n, cluster, 1);
}

/* Heartbeats until the world knows k daemons (at most 5 s). */
static int wait_daemons(sc_world *w, int k)
{
    for (int i = 0; i < 500; i++) {
        sc_cluster_frame(w->cluster);
        if (w->stats.now.daemons >= k)
            return 0;
        usleep(10000);
    }
    return -1;
}

typedef struct result {
    double wall, remote, recomputed, comm_ms, late, wait_ms, local_ms, msgs_out, msgs_in, piped;
    uint64_t hash;
} result;

/* A world of n bodies on workers local threads that has heard k daemons
 * (none: no cluster); NULL, said, if they did not answer. */
static sc_world *start_world(int n, int k, int workers)
{
    sc_world *w = make_world_on(n, k > 0, workers);
    if (k > 0 && wait_daemons(w, k) != 0) {
        fprintf(stderr, "bench_cluster: only %d of %d daemons answered\n", w->stats.now.daemons, k);
        sc_world_destroy(w);
        return NULL;
    }
    return w;
}

/* One frame and its figures; on an error it says so and ends the world. */
static int step_frame(sc_world *w, sc_stats *st)
{
    int rc = sc_world_step(w, DT);
    if (rc != SC_OK) {
        fprintf(stderr, "bench_cluster: step: %s\n", sc_strerror(rc));
        sc_world_destroy(w);
        return -1;
    }
    sc_world_stats(w, st);
    return 0;
}

static int run(int n, int k, double seconds, result *r)
{
    sc_world *w = start_world(n, k, 1);
    if (!w)
        return -1;
    int frames = (int)(seconds / DT + 0.5);
    long units = 0, remote = 0, recomputed = 0, late = 0, msgs_out = 0, msgs_in = 0, piped = 0;
    double comm = 0, wait = 0, local = 0;
    double t0 = now_s();
    for (int f = 0; f < frames; f++) {
        sc_stats st;
        if (step_frame(w, &st) != 0)
            return -1;
        units += st.frame.sched.units;
        remote += st.frame.remote.units;
        recomputed += st.frame.remote.recomputed_units;
        late += st.frame.remote.late_results;
        comm += st.frame.remote.comm_s;
        wait += st.frame.remote.wait_s;
        local += st.frame.sched.makespan_s;
        msgs_out += st.frame.remote.unit_messages;
        msgs_in += st.frame.remote.result_messages;
        piped += st.frame.remote.pipelined_units;
    }
    r->wall = now_s() - t0;
    r->remote = units ? (double)remote / (double)units : 0;
    r->recomputed = (double)recomputed / frames;
    r->late = (double)late / frames;
    r->comm_ms = 1e3 * comm / frames;
    r->wait_ms = 1e3 * wait / frames;
    r->local_ms = 1e3 * local / frames;
    /* messages a frame and daemon */
    r->msgs_out = (double)msgs_out / frames / (k > 0 ? k : 1);
    r->msgs_in = (double)msgs_in / frames / (k > 0 ? k : 1);
    r->piped = (double)piped / frames;
    r->hash = sc_world_hash(w);
    sc_world_destroy(w);
    return 0;
}

/* One row's runs (scaling()). */
typedef struct scale_row {
    double wall[MAX_RUNS], rem[MAX_RUNS], rc[MAX_RUNS], comm[MAX_RUNS], late[MAX_RUNS],
        wait[MAX_RUNS], jobs[MAX_RUNS], mout[MAX_RUNS], min[MAX_RUNS], piped[MAX_RUNS],
        ratio[MAX_RUNS];
    int done, same;
} scale_row;

/* The rows take turns, one run each per round (daemons started and
 * stopped around each run), so that a shared machine's slow minutes fall
 * on every row alike; the speedup is the median of each round's ratio to
 * the 0-daemon run of the same round (the first row must be 0). */
static void scaling(int n, const int *ks, int nk, const double *gains, int ng, int runs,
                    double seconds)
{
    printf("\nscaling: %d bolts/nuts %s, %.2f s simulated, 1 local worker + k one-thread "
           "daemons, medians of %d runs, the rows in turn%s%s\n",
           n, bin_scene ? "in the bin" : "dropped", seconds, runs,
           toi_mode == SC_TOI_LOCAL ? ", local time of impact (motion groups)"
           : groups                 ? ", motion groups"
                                    : "",
           dedicated ? ", daemons --dedicated --no-idle-priority" : "");
    printf("%8s %9s %9s %8s %9s %12s %10s %10s %10s %10s %9s %9s %9s %6s\n", "daemons",
           "wall s", "RT factor", "speedup", "remote %", "recomp/frame", "late/frame",
           "jobs ms/fr", "wait ms/fr", "comm ms/fr", "out/fr/dmn", "in/fr/dmn", "piped/fr",
           "bits");
    scale_row *row = calloc((size_t)nk, sizeof *row);
    if (!row)
        return;
    uint64_t h0 = 0;
    int have0 = 0;
    for (int i = 0; i < nk; i++)
        row[i].same = 1;
    for (int r = 0; r < runs; r++)
        for (int i = 0; i < nk; i++) {
            int k = ks[i];
            pid_t pid[MAX_D] = { 0 };
            min_gain = i < ng ? gains[i] : 0;
            /* the master on CPU 0, daemon j on CPU j + 1 (wrapping) */
            pin(0, 0);
            for (int j = 0; j < k; j++)
                pid[j] = start_daemon(100 + j, ncpu > 1 ? 1 + j % (ncpu - 1) : 0, 1.0, 1);
            result res;
            int ok = run(n, k, seconds, &res) == 0;
            for (int j = 0; j < k; j++)
                stop_daemon(pid[j]);
            unpin();
            if (!ok || row[i].done != r)
                continue;       /* a row that failed once stays short */
            scale_row *w = &row[i];
            w->wall[r] = res.wall;
            w->rem[r] = 100 * res.remote;
            w->rc[r] = res.recomputed;
            w->comm[r] = res.comm_ms;
            w->late[r] = res.late;
            w->wait[r] = res.wait_ms;
            w->jobs[r] = res.local_ms;
            w->mout[r] = res.msgs_out;
            w->min[r] = res.msgs_in;
            w->piped[r] = res.piped;
            /* this round's 0-daemon run (row 0 runs first in a round) */
            w->ratio[r] = i == 0 ? 1 : row[0].done > r && ks[0] == 0 ? row[0].wall[r] / res.wall : 0;
            if (k == 0 && !have0) {
                h0 = res.hash;
                have0 = 1;
            }
            w->same = w->same && have0 && res.hash == h0;
            w->done++;
        }
    for (int i = 0; i < nk; i++) {
        scale_row *w = &row[i];
        int m = w->done;
        if (m == 0)
            continue;
        char sp[16] = "-", bits[8] = "-";
        if (ks[0] == 0 && row[0].done > 0) {
            double rat[MAX_RUNS];
            int nr = 0;
            for (int r = 0; r < m; r++)
                if (w->ratio[r] > 0)
                    rat[nr++] = w->ratio[r];
            if (nr > 0)
                snprintf(sp, sizeof sp, "%.2f", median(rat, nr));
            snprintf(bits, sizeof bits, "%s", w->same ? "same" : "DIFF");
        }
        double wall = median(w->wall, m);
        printf("%8d %9.3f %9.3f %8s %9.1f %12.2f %10.2f %10.1f %10.1f %10.1f %10.1f %9.1f %9.1f "
               "%6s\n",
               ks[i], wall, seconds / wall, sp, median(w->rem, m), median(w->rc, m),
               median(w->late, m), median(w->jobs, m), median(w->wait, m), median(w->comm, m),
               median(w->mout, m), median(w->min, m), median(w->piped, m), bits);
    }
    min_gain = 0;
    for (int i = 0; i < ng && i < nk; i++)
        printf("row %d (%d daemon%s): cluster_min_gain %g%s\n", i + 1, ks[i], ks[i] == 1 ? "" : "s",
               gains[i], gains[i] == 0 ? " (the default)" : gains[i] < 0 ? " (no job-level rule)" : "");
    fflush(stdout);
    free(row);
}

/* ---- model: a prediction of k daemons from measured costs ----
 *
 * Three runs of the same scene (each -r times, medians):
 *   A  one local worker, no daemons: T1, the wall time of a frame;
 *   B  every CPU as local workers: per frame the unit work W, the jobs J,
 *      the units' estimated wire bytes and ideal_makespan_s (sc_stats):
 *      I(n), the least time the frame's jobs could take on n nodes of
 *      this speed with free messages;
 *   C  one local worker and one one-thread daemon on the other CPU: the
 *      master's shipping time per wire byte (comm_s over the shipped
 *      units' bytes; packing, sealing, sending, receiving, merging) and
 *      the round trip less the work, L (remote_overhead_s / remote_jobs).
 * The frame's work outside units (serial stages, and the sweeps and
 * passes a master with daemons runs alone) is S = T1 - W. A unit of
 * density b (wire bytes per second of its work; B's bins of
 * unit_work_by_density_s) costs the master rho = (time per byte) b per
 * second of work to ship. With k daemons of the master's speed the master
 * ships the cheapest bins first, only where rho <= SHIP_SHARE (the
 * scheduler's rule), until its own time M = S + (W - shipped) + rho
 * shipped meets the daemons' D = shipped / k (model_frame()), and a
 * frame takes
 *   T(k) = max(M, D, S + I(k + 1)) + Jr L
 * when anything ships, Jr the jobs a frame that shipped with one daemon
 * (each waits a round trip beyond the work: the protocol today), or with
 * one exchange a frame (the coarse units of the plan) + min(Jr, 1) L;
 * S + I(k + 1) alone is the ceiling of free messages. rho over all
 * units as if they shipped alike is printed for comparison. It is a
 * model: the greedy's own imbalance, the barriers' waits and the
 * daemons' speed are left out (an upper bound); run C checks it at
 * k = 1. */
typedef struct profile {
    double wall, work, jobs, bytes, ideal[SC_STATS_IDEAL_NODES];
    double density[SC_STATS_DENSITY_BINS];
    double comm, overhead, remote_jobs, remote_bytes, remote_work, remote_units, units;
    double serial;              /* sc_stats_sched.serial_s */
    uint64_t hash;
} profile;

static int profile_run(int n, int workers, int k, double seconds, profile *p)
{
    sc_world *w = start_world(n, k, workers);
    if (!w)
        return -1;
    memset(p, 0, sizeof *p);
    int frames = (int)(seconds / DT + 0.5);
    double t0 = now_s();
    for (int f = 0; f < frames; f++) {
        sc_stats st;
        if (step_frame(w, &st) != 0)
            return -1;
        p->work += st.frame.sched.unit_work_s;
        p->jobs += (double)st.frame.sched.jobs;
        p->bytes += st.frame.sched.unit_bytes;
        for (int i = 0; i < SC_STATS_IDEAL_NODES; i++)
            p->ideal[i] += st.frame.sched.ideal_makespan_s[i];
        for (int i = 0; i < SC_STATS_DENSITY_BINS; i++)
            p->density[i] += st.frame.sched.unit_work_by_density_s[i];
        p->comm += st.frame.remote.comm_s;
        p->overhead += st.frame.remote.overhead_s;
        p->remote_jobs += (double)st.frame.remote.jobs;
        p->remote_bytes += st.frame.remote.bytes;
        p->remote_work += st.frame.remote.work_s;
        p->remote_units += (double)st.frame.remote.units;
        p->units += (double)st.frame.sched.units;
        p->serial += st.frame.sched.serial_s;
    }
    p->wall = (now_s() - t0) / frames;
    /* every figure a frame */
    double *per[] = { &p->work,        &p->jobs,         &p->bytes,        &p->comm,
                      &p->overhead,    &p->remote_jobs,  &p->remote_bytes, &p->remote_work,
                      &p->remote_units, &p->units,      &p->serial };
    for (size_t i = 0; i < sizeof per / sizeof per[0]; i++)
        *per[i] /= frames;
    for (int i = 0; i < SC_STATS_IDEAL_NODES; i++)
        p->ideal[i] /= frames;
    for (int i = 0; i < SC_STATS_DENSITY_BINS; i++)
        p->density[i] /= frames;
    p->hash = sc_world_hash(w);
    sc_world_destroy(w);
    return 0;
}

/* The median over runs of a profile's double at byte offset off. */
static double med_field(const profile *p, int runs, size_t off)
{
    double x[MAX_RUNS];
    for (int r = 0; r < runs; r++)
        memcpy(&x[r], (const char *)&p[r] + off, sizeof x[r]);
    return median(x, runs);
}

#define MED(p, field) med_field(p, runs, offsetof(profile, field))

/* The model's frame time with k daemons (see above): the master ships
 * the units cheapest to ship first (density bins ascending), only those
 * that cost it at most SHIP_SHARE of computing them (the scheduler's
 * rule), until its own time meets the daemons'; *f the shipped share. */
#define SHIP_SHARE 0.5
static double model_frame(double s, double w, const double *density, double per_byte,
                          double ideal, double waits, int k, double *f)
{
    double shipped = 0, m = s + w, d = 0;
    for (int i = 0; i < SC_STATS_DENSITY_BINS && m > d; i++) {
        double rho = per_byte * M_SQRT2 * 1e6 * ldexp(1, i);
        if (rho > SHIP_SHARE)
            break;
        double x = fmin(density[i], (m - d) / (1 - rho + 1.0 / k));
        shipped += x;
        m -= x * (1 - rho);
        d += x / k;
    }
    *f = w > 0 ? shipped / w : 0;
    return fmax(fmax(m, d), s + ideal) + (shipped > 0 ? waits : 0);
}

static void model(int n, int runs, double seconds)
{
    if (ncpu < 2) {
        printf("\nmodel: needs 2 CPUs, skipped\n");
        return;
    }
    int workers = ncpu < SC_STATS_IDEAL_NODES ? ncpu : SC_STATS_IDEAL_NODES;
    printf("\nmodel: %d bolts/nuts %s, %.2f s simulated%s, medians of %d runs: "
           "A one worker, B %d workers, C one worker + one one-thread daemon\n",
           n, bin_scene ? "in the bin" : "dropped", seconds,
           toi_mode == SC_TOI_LOCAL ? ", local time of impact (motion groups)"
           : groups                 ? ", motion groups"
                                    : ", time of impact world-wide",
           runs, workers);
    profile a[MAX_RUNS], b[MAX_RUNS], c[MAX_RUNS];
    pin(0, 0);
    int ok = 1;
    for (int r = 0; r < runs && ok; r++)
        ok = profile_run(n, 1, 0, seconds, &a[r]) == 0;
    unpin();
    for (int r = 0; r < runs && ok; r++)
        ok = profile_run(n, workers, 0, seconds, &b[r]) == 0;
    pin(0, 0);
    pid_t pid = start_daemon(150, 1, 1.0, 1);
    for (int r = 0; r < runs && ok; r++)
        ok = profile_run(n, 1, 1, seconds, &c[r]) == 0;
    stop_daemon(pid);
    unpin();
    if (!ok)
        return;
    int same = 1;
    for (int r = 0; r < runs; r++)
        same = same && b[r].hash == a[0].hash && c[r].hash == a[0].hash && a[r].hash == a[0].hash;
    double t1 = MED(a, wall), w = MED(b, work), jobs = MED(b, jobs), bytes = MED(b, bytes);
    double ideal[SC_STATS_IDEAL_NODES];
    for (int i = 0; i < SC_STATS_IDEAL_NODES; i++)
        ideal[i] = med_field(b, runs, offsetof(profile, ideal) + (size_t)i * sizeof(double));
    double tc = MED(c, wall), x[MAX_RUNS];
    for (int r = 0; r < runs; r++)
        x[r] = c[r].remote_bytes > 0 ? c[r].comm / c[r].remote_bytes : 0;
    double per_byte = median(x, runs);
    for (int r = 0; r < runs; r++)
        x[r] = c[r].remote_jobs > 0 ? c[r].overhead / c[r].remote_jobs : 0;
    double lat = median(x, runs);
    double jr = MED(c, remote_jobs);
    for (int r = 0; r < runs; r++)
        x[r] = c[r].remote_work > 0 ? c[r].comm / c[r].remote_work : 0;
    double rho_sent = median(x, runs);
    for (int r = 0; r < runs; r++)
        x[r] = c[r].work > 0 ? 100 * c[r].remote_work / c[r].work : 0;
    double sent = median(x, runs);
    double s = t1 - w, rho = w > 0 ? per_byte * bytes / w : 0;
    printf("measured, a frame: A T1 %.2f ms; B unit work W %.2f ms in %.1f jobs, %.0f kB of "
           "units; S = T1 - W %.2f ms; C %.2f ms (%.2f x), %.1f %% of the work shipped in %.1f "
           "jobs, the master %.1f ns a byte (rho %.2f for what it shipped, %.2f for all "
           "units), round trip less work L %.3f ms; bits %s\n",
           1e3 * t1, 1e3 * w, jobs, bytes / 1e3, 1e3 * s, 1e3 * tc, t1 / tc, sent, jr,
           1e9 * per_byte, rho_sent, rho, 1e3 * lat, same ? "same" : "DIFF");
    /* sc_stats' own measure beside S: with one local node the pile is a
     * unit (A); with more, or with a daemon, its stages outside jobs are
     * the master's (docs/DESIGN.md 5.6) */
    printf("master's serial part measured (sc_stats serial_s), a frame: A %.2f ms, B %.2f ms, "
           "C %.2f ms (%.1f %% of T1)\n",
           1e3 * MED(a, serial), 1e3 * MED(b, serial), 1e3 * MED(c, serial),
           t1 > 0 ? 100 * MED(c, serial) / t1 : 0.0);
    if (s < 0) {
        /* B's units took longer than A's whole frames: its threads slowed
         * each other (two vCPUs of one core), and W is not the work a
         * node of A's speed does; the model would count negative serial
         * work and predict far too much (docs/DESIGN.md 7.8; a measured
         * case, the world-wide drop, is in docs/HISTORY.md 7.8) */
        printf("no prediction: S < 0, B's units ran slower than A's frames (its CPUs "
               "contend; A's units took %.2f ms a frame)\n",
               1e3 * MED(a, work));
        fflush(stdout);
        return;
    }
    printf("%8s %10s %10s %10s %10s %10s %12s %12s\n", "daemons", "ceiling x", "shipped %",
           "T(k) ms", "today x", "waits ms", "1 exch. ms", "1 exch. x");
    static const int ks[] = { 1, 3, 7, 15 };
    for (size_t i = 0; i < sizeof ks / sizeof ks[0]; i++) {
        int k = ks[i];
        if (k + 1 > SC_STATS_IDEAL_NODES)
            break;
        double f, t = model_frame(s, w, b[0].density, per_byte, ideal[k], jr * lat, k, &f);
        double t_one =
            model_frame(s, w, b[0].density, per_byte, ideal[k], fmin(jr, 1) * lat, k, &f);
        printf("%8d %10.2f %10.1f %10.2f %10.2f %10.2f %12.2f %12.2f\n", k,
               t1 / (s + ideal[k]), 100 * f, 1e3 * t, t1 / t, 1e3 * jr * lat, 1e3 * t_one,
               t1 / t_one);
    }
    double f1;
    double t_1 = model_frame(s, w, b[0].density, per_byte, ideal[1], jr * lat, 1, &f1);
    printf("check at k = 1: measured %.2f x with %.1f %% shipped; the model %.2f x with "
           "%.1f %%\n", t1 / tc, sent, t1 / t_1, 100 * f1);
    fflush(stdout);
}

/* A CPU-bound program: a fixed amount of arithmetic; its wall time. */
static double foreground(int cpu)
{
    int fds[2];
    if (pipe(fds) != 0)
        return -1;
    pid_t pid = fork();
    if (pid == 0) {
        pin(0, cpu);
        double t0 = now_s();
        volatile double x = 1;
        for (long i = 0; i < 300000000L; i++)
            x = x * 1.0000001 + 1e-9;
        double t = now_s() - t0;
        ssize_t wr = write(fds[1], &t, sizeof t);
        _exit(wr == sizeof t ? 0 : 1);
    }
    close(fds[1]);
    double t = -1;
    if (read(fds[0], &t, sizeof t) != sizeof t)
        t = -1;
    close(fds[0]);
    int st;
    waitpid(pid, &st, 0);
    return t;
}

static volatile sig_atomic_t stop_master;
static void on_alarm(int sig)
{
    (void)sig;
    stop_master = 1;
}

/* The master, in a child: keeps the daemons full of units until killed. */
static pid_t busy_master(int n, int cpu, int k, int force)
{
    pid_t pid = fork();
    if (pid == 0) {
        pin(0, cpu);
        sc_world *w = make_world(n, 1);
        if (wait_daemons(w, k) != 0)
            _exit(2);
        if (force) {
            sc_cluster_force(w->cluster);
            w->ex.sched.home_capacity = 0;
            w->ex.sched.min_gain = -1;
        }
        for (int f = 1;; f++) {
            if (sc_world_step(w, DT) != SC_OK)
                break;
            if (f % 300 == 0) {     /* near rest: drop them again */
                sc_world_destroy(w);
                w = make_world(n, 1);
                wait_daemons(w, k);
                if (force) {
                    sc_cluster_force(w->cluster);
                    w->ex.sched.home_capacity = 0;
                    w->ex.sched.min_gain = -1;
                }
            }
        }
        _exit(0);
    }
    return pid;
}

static void fg(int runs)
{
    if (ncpu < 2) {
        printf("\nfg: needs 2 CPUs, skipped\n");
        return;
    }
    printf("\nforeground slowdown: a CPU-bound program on CPU 1, next to a one-thread daemon "
           "on CPU 1 kept full of units (master on CPU 0), medians of %d runs\n",
           runs);
    printf("%28s %10s %10s\n", "daemon", "fg wall s", "slowdown %");
    double alone[MAX_RUNS];
    for (int r = 0; r < runs; r++)
        alone[r] = foreground(1);
    double a = median(alone, runs);
    printf("%28s %10.3f %10s\n", "none", a, "-");
    for (int mode = 0; mode < 2; mode++) {
        pid_t d = start_daemon(200 + mode, 1, 1.0, mode == 0);
        pid_t m = busy_master(200, 0, 1, 1);
        usleep(1500000);    /* the daemon's queue fills */
        double t[MAX_RUNS];
        for (int r = 0; r < runs; r++)
            t[r] = foreground(1);
        kill(m, SIGKILL);
        waitpid(m, NULL, 0);
        stop_daemon(d);
        double v = median(t, runs);
        printf("%28s %10.3f %10.1f\n", mode == 0 ? "nice 19 + SCHED_IDLE" : "plain (nice 0, normal)",
               v, 100 * (v / a - 1));
        fflush(stdout);
    }
}

static void busy(int n, int runs)
{
    if (ncpu < 2) {
        printf("\nbusy: needs 2 CPUs, skipped\n");
        return;
    }
    printf("\nwork leaving a busy node: a daemon on CPU 1 (threshold 0.5, heartbeat 0.1 s), "
           "the master on CPU 0; an owner's program starts on CPU 1 at t = 0\n");
    printf("%4s %14s %16s\n", "run", "busy seen s", "last remote s");
    double seen[MAX_RUNS], last[MAX_RUNS];
    int ok = 0;
    for (int r = 0; r < runs; r++) {
        pin(0, 0);
        pid_t d = start_daemon(300 + r, 1, 0.5, 1);
        sc_world *w = make_world(n, 1);
        if (wait_daemons(w, 1) != 0) {
            stop_daemon(d);
            sc_world_destroy(w);
            unpin();
            continue;
        }
        for (int f = 0; f < 20; f++)
            sc_world_step(w, DT);
        pid_t hog = fork();
        if (hog == 0) {
            pin(0, 1);
            signal(SIGALRM, on_alarm);
            alarm(10);
            volatile double x = 0;
            while (!stop_master)
                x += 1;
            _exit(0);
        }
        double t0 = now_s(), t_seen = -1, t_last = 0;
        while (now_s() - t0 < 2.5) {
            if (sc_world_step(w, DT) != SC_OK)
                break;
            sc_stats st;
            sc_world_stats(w, &st);
            if (st.now.daemons_busy > 0 && t_seen < 0)
                t_seen = now_s() - t0;
            if (st.frame.remote.units > 0)
                t_last = now_s() - t0;
        }
        kill(hog, SIGKILL);
        waitpid(hog, NULL, 0);
        stop_daemon(d);
        sc_world_destroy(w);
        unpin();
        printf("%4d %14.3f %16.3f\n", r + 1, t_seen, t_last);
        seen[ok] = t_seen;
        last[ok] = t_last;
        ok++;
    }
    if (ok)
        printf("median %9.3f %16.3f\n", median(seen, ok), median(last, ok));
}

int main(int argc, char **argv)
{
    int runs = 3, n = 1000, ks[MAX_D] = { 0, 1 }, nk = 2, ngain = 0;
    double gains[MAX_D] = { 0 };
    double seconds = 1.0;
    const char *parts = "scaling,fg,busy";
    snprintf(daemon_bin, sizeof daemon_bin, "%s", argv[0]);
    char *slash = strrchr(daemon_bin, '/');
    snprintf(slash ? slash + 1 : daemon_bin,
             sizeof daemon_bin - (size_t)(slash ? slash + 1 - daemon_bin : 0),
             "../daemon/simclusterd");
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-r") && i + 1 < argc) {
            runs = atoi(argv[++i]);
        } else if (!strcmp(argv[i], "-s") && i + 1 < argc) {
            seconds = atof(argv[++i]);
        } else if (!strcmp(argv[i], "-n") && i + 1 < argc) {
            n = atoi(argv[++i]);
        } else if (!strcmp(argv[i], "-x") && i + 1 < argc) {
            snprintf(daemon_bin, sizeof daemon_bin, "%s", argv[++i]);
        } else if (!strcmp(argv[i], "-u") && i + 1 < argc) {
            snprintf(url, sizeof url, "%s", argv[++i]);
        } else if (!strcmp(argv[i], "-p") && i + 1 < argc) {
            parts = argv[++i];
        } else if (!strcmp(argv[i], "-t") && i + 1 < argc &&
                   (!strcmp(argv[i + 1], "world") || !strcmp(argv[i + 1], "local"))) {
            toi_mode = !strcmp(argv[++i], "local") ? SC_TOI_LOCAL : SC_TOI_WORLD;
        } else if (!strcmp(argv[i], "-S") && i + 1 < argc &&
                   (!strcmp(argv[i + 1], "drop") || !strcmp(argv[i + 1], "bin"))) {
            bin_scene = !strcmp(argv[++i], "bin");
        } else if (!strcmp(argv[i], "-D")) {
            dedicated = 1;
        } else if (!strcmp(argv[i], "-g")) {
            groups = 1;
        } else if (!strcmp(argv[i], "-G") && i + 1 < argc) {
            ngain = 0;
            for (char *t = strtok(argv[++i], ","); t && ngain < MAX_D; t = strtok(NULL, ","))
                gains[ngain++] = atof(t);
        } else if (!strcmp(argv[i], "-d") && i + 1 < argc) {
            nk = 0;
            for (char *t = strtok(argv[++i], ","); t && nk < MAX_D; t = strtok(NULL, ","))
                ks[nk++] = atoi(t);
        } else {
            fprintf(stderr, "usage: bench_cluster [-r RUNS] [-s SECONDS] [-n BODIES] "
                            "[-d 0,1,2,...] [-x DAEMON] [-u LCM-URL] [-p scaling,model,fg,busy] "
                            "[-t world|local] [-g] [-S drop|bin] [-D] [-G LIST]\n");
            return 2;
        }
    }
    if (runs < 1 || runs > MAX_RUNS || !(seconds > 0) || n < 1 || access(daemon_bin, X_OK)) {
        fprintf(stderr, "bench_cluster: bad arguments or no daemon at %s\n", daemon_bin);
        return 2;
    }
    ncpu = (int)sysconf(_SC_NPROCESSORS_ONLN);
    srand((unsigned)getpid());
    if (!url[0])
        snprintf(url, sizeof url, "udpm://239.255.76.67:%d?ttl=0&recv_buf_size=4194304",
                 20000 + rand() % 10000);
    /* in a folder of its own: a key file left by a run that was killed
     * (named by its pid) once made a later run with that pid fail, as
     * sc_key_generate() never overwrites a file */
    char key_dir[] = "/tmp/bench_cluster.XXXXXX";
    if (!mkdtemp(key_dir)) {
        fprintf(stderr, "bench_cluster: cannot make a folder for the key in /tmp\n");
        return 1;
    }
    snprintf(key_path, sizeof key_path, "%s/key", key_dir);
    if (sc_key_generate(key_path) != SC_OK) {
        fprintf(stderr, "bench_cluster: cannot write %s\n", key_path);
        rmdir(key_dir);
        return 1;
    }
    printf("bench_cluster: %d CPUs, LCM %s\n", ncpu, url);
    if (strstr(parts, "scaling"))
        scaling(n, ks, nk, gains, ngain, runs, seconds);
    if (strstr(parts, "model"))
        model(n, runs, seconds);
    if (strstr(parts, "fg"))
        fg(runs);
    if (strstr(parts, "busy"))
        busy(200, runs);
    unlink(key_path);
    rmdir(key_dir);
    return 0;
}
