/* cluster_run.c - a master for the cluster tests (tests/cluster.sh) and for
 * people trying a cluster by hand: builds the bolts/nuts drop scene of
 * examples/bolts_nuts.c (N bodies from a seed), steps it a fixed number of
 * frames, locally or with the simclusterd daemons on an LCM URL, and prints
 * a hash of the final state (the same bits, the same hash) and the cluster
 * counters summed over the frames.
 *   usage: cluster_run [--url URL] [--key FILE] [--bodies N] [--seed S]
 *                      [--frames F] [--workers W] [--deadline S] [--trace]
 *                      [--wait-daemons K] [--realtime] [--toi world|local]
 *                      [--scene drop|pile]
 * --toi local steps by motion groups (sc_world_config.toi_mode); --scene
 * pile is a bin of N parts (sc_scene_bin) with 24 lone spheres falling
 * high above it: a pile and small groups beside it, whose units go out
 * while the pile steps here (sc_stats.frame.remote.pipelined_units, "piped").
 * --realtime paces the frames at DT = 10 ms of wall time each, as an
 * interactive program would (a frame that takes longer is not made up).
 * Output (stdout): with --trace one line per frame
 *   frame F wall S daemons D busy B remote R recomputed C late L
 * then
 *   hash HHHHHHHHHHHHHHHH
 *   remote R recomputed C late L dropped D stale S misaddressed M duplicates U piped P
 *   duplicate node id ID        (only when two running daemons share one)
 *   wall S frames F
 * Exit status: 0, 1 when the world cannot be made or a step fails (or the
 * daemons asked for by --wait-daemons do not show up), 2 on a usage error. */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "simcluster.h"

#define DT 0.01
#define WAIT_DAEMONS_S 10.0

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void sleep_s(double s)
{
    struct timespec ts = { (time_t)s, (long)((s - (double)(time_t)s) * 1e9) };
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

static int parse_long(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || end == s || v < lo || v > hi)
        return 0;
    *out = v;
    return 1;
}

static int parse_double(const char *s, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || end == s || !(v >= lo && v <= hi))
        return 0;
    *out = v;
    return 1;
}

/* Wait (at most WAIT_DAEMONS_S) until k daemons that are not owner-busy
 * are heard (sc_cluster_wait). */
static int wait_daemons(const sc_world_config *cfg, int k)
{
    int n = sc_cluster_wait(cfg, k, WAIT_DAEMONS_S);
    if (n < 0)
        fprintf(stderr, "cluster_run: probe world: %s\n", sc_strerror(n));
    else if (n < k)
        fprintf(stderr, "cluster_run: %d daemon%s after %.0f s, %d wanted\n", n,
                n == 1 ? "" : "s", WAIT_DAEMONS_S, k);
    return n >= k;
}

static int usage(FILE *f, int status)
{
    fprintf(f, "usage: cluster_run [--url URL] [--key FILE] [--bodies N (30)] [--seed S (1)]\n"
               "                   [--frames F (150)] [--workers W (1)] [--deadline S]\n"
               "                   [--trace] [--wait-daemons K] [--realtime]\n"
               "                   [--toi world|local] [--scene drop|pile]\n");
    return status;
}

int main(int argc, char **argv)
{
    static const struct option opts[] = {
        { "url", required_argument, NULL, 'u' },      { "key", required_argument, NULL, 'k' },
        { "bodies", required_argument, NULL, 'n' },   { "seed", required_argument, NULL, 's' },
        { "frames", required_argument, NULL, 'f' },   { "workers", required_argument, NULL, 'w' },
        { "deadline", required_argument, NULL, 'd' }, { "trace", no_argument, NULL, 't' },
        { "wait-daemons", required_argument, NULL, 'W' }, { "realtime", no_argument, NULL, 'r' },
        { "toi", required_argument, NULL, 'T' },      { "scene", required_argument, NULL, 'S' },
        { "help", no_argument, NULL, 'h' },           { NULL, 0, NULL, 0 }
    };
    const char *url = NULL, *key = NULL;
    long bodies = 30, seed = 1, frames = 150, workers = 1, wait = 0;
    double deadline = 0;
    int trace = 0, realtime = 0, c, li = 0, toi = SC_TOI_WORLD, pile = 0;
    while ((c = getopt_long(argc, argv, "", opts, &li)) != -1) {
        int ok = 1;
        switch (c) {
        case 'u': url = optarg; break;
        case 'k': key = optarg; break;
        case 'n': ok = parse_long(optarg, 1, 100000, &bodies); break;
        case 's': ok = parse_long(optarg, 0, 0x7fffffffL, &seed); break;
        case 'f': ok = parse_long(optarg, 0, 100000000L, &frames); break;
        case 'w': ok = parse_long(optarg, 0, SC_MAX_WORKERS, &workers); break;
        case 'd': ok = parse_double(optarg, 0, 60, &deadline); break;
        case 't': trace = 1; break;
        case 'r': realtime = 1; break;
        case 'W': ok = parse_long(optarg, 0, SC_MAX_DAEMONS, &wait); break;
        case 'T':
            ok = !strcmp(optarg, "world") || !strcmp(optarg, "local");
            toi = !strcmp(optarg, "local") ? SC_TOI_LOCAL : SC_TOI_WORLD;
            break;
        case 'S':
            ok = !strcmp(optarg, "drop") || !strcmp(optarg, "pile");
            pile = !strcmp(optarg, "pile");
            break;
        case 'h': return usage(stdout, 0);
        default: return usage(stderr, 2);
        }
        if (!ok) {
            fprintf(stderr, "cluster_run: bad value '%s' for --%s\n", optarg, opts[li].name);
            return usage(stderr, 2);
        }
    }
    if (optind != argc || (wait > 0 && !url))
        return usage(stderr, 2);

    sc_world_config cfg = sc_world_config_default();
    cfg.workers = (int)workers;
    cfg.cluster = url;
    cfg.key_file = key;
    cfg.cluster_deadline_s = deadline;
    /* what is tested is what happens to units out on daemons: they go out
     * whatever shipping them costs (the worth-it rules would keep most of
     * these small scenes' units here) */
    cfg.cluster_ship_share = -1;
    cfg.cluster_min_gain = -1;
    cfg.toi_mode = toi;
    sc_world *w = sc_world_create(&cfg);
    if (!w) {
        fprintf(stderr, "cluster_run: world: %s\n", sc_strerror(sc_last_error()));
        return 1;
    }
    int rc = pile ? sc_scene_bin(w, (int)bodies, (uint64_t)seed)
                  : sc_scene_bolts_nuts(w, (int)bodies, (uint64_t)seed);
    sc_body_desc d = sc_body_desc_default();
    d.shape = rc == SC_OK && pile ? sc_shape_sphere(0.01) : NULL;
    d.mass = 0.03;
    for (int i = 0; d.shape && i < 24 && rc == SC_OK; i++) {
        d.pos[0] = -0.1 + 0.04 * (i % 6);
        d.pos[1] = -0.1 + 0.04 * (i / 6);
        d.pos[2] = 10 + 0.05 * i;
        int id = sc_body_add(w, &d);
        rc = id < 0 ? id : SC_OK;
    }
    sc_shape_release(d.shape);
    if (rc != SC_OK) {
        fprintf(stderr, "cluster_run: scene: %s\n", sc_strerror(rc));
        sc_world_destroy(w);
        return 1;
    }
    if (wait > 0 && !wait_daemons(&cfg, (int)wait)) {
        sc_world_destroy(w);
        return 1;
    }

    long remote = 0, recomputed = 0, late = 0, piped = 0;
    sc_stats st;
    memset(&st, 0, sizeof st);
    double t0 = now_s();
    long f;
    for (f = 0; f < frames; f++) {
        rc = sc_world_step(w, DT);
        if (rc != SC_OK) {
            fprintf(stderr, "cluster_run: frame %ld: %s\n", f, sc_strerror(rc));
            break;
        }
        sc_world_stats(w, &st);
        remote += st.frame.remote.units;
        recomputed += st.frame.remote.recomputed_units;
        late += st.frame.remote.late_results;
        piped += st.frame.remote.pipelined_units;
        if (trace) {
            printf("frame %ld wall %.3f daemons %d busy %d remote %ld recomputed %ld late %ld\n",
                   f, now_s() - t0, st.now.daemons, st.now.daemons_busy, st.frame.remote.units,
                   st.frame.remote.recomputed_units, st.frame.remote.late_results);
            fflush(stdout);
        }
        double ahead = t0 + (double)(f + 1) * DT - now_s();
        if (realtime && ahead > 0)
            sleep_s(ahead);
    }
    double wall = now_s() - t0;
    sc_world_stats(w, &st);
    printf("hash %016llx\n", (unsigned long long)sc_world_hash(w));
    printf("remote %ld recomputed %ld late %ld dropped %ld stale %ld misaddressed %ld "
           "duplicates %ld piped %ld\n", remote, recomputed, late, st.total.dropped_messages,
           st.total.dropped_stale, st.total.dropped_misaddressed, st.total.duplicate_nodes, piped);
    if (st.total.duplicate_nodes)
        printf("duplicate node id %016llx\n", (unsigned long long)st.now.duplicate_node);
    printf("wall %.3f frames %ld\n", wall, f);
    sc_world_destroy(w);
    return rc == SC_OK ? 0 : 1;
}
