/* bench_workers.c - the bolts/nuts drop on 1 and 2 (or more) local worker
 * threads: wall time, real-time factor, speedup, the scheduler's makespan
 * over its lower bound and its own overhead (issue 4).
 *
 * Usage: bench_workers [-r RUNS] [-s SECONDS] [-w W1,W2,...] [-m MODES] [N ...]
 *   defaults: 3 runs (medians), 1 s simulated, workers 1,2, modes "wg"
 *   (w: the paper's world-wide back-up, g: motion groups), N = 50 200 1000
 * Every run checks that the final state hash is the same for every worker
 * count (the result must not depend on the threads). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_util.h"
#include "simcluster.h"

#define DT 0.01
#define MAX_RUNS 15
#define MAX_W 8

typedef struct result {
    double wall, ratio, sched, units;
    int nodes, private_ode;
    unsigned long long hash;
} result;

static int run(int n, int workers, int groups, double seconds, result *r)
{
    sc_world_config c = sc_world_config_default();
    c.workers = workers;
    c.motion_groups = groups;
    sc_world *w = sc_world_create(&c);
    if (!w || sc_scene_bolts_nuts(w, n, 1) < 0) {
        fprintf(stderr, "bench_workers: %s\n", sc_strerror(sc_last_error()));
        sc_world_destroy(w);
        return -1;
    }
    int frames = (int)(seconds / DT + 0.5);
    double mk = 0, bound = 0, sched = 0;
    long units = 0;
    double t0 = now_s();
    for (int f = 0; f < frames; f++) {
        int rc = sc_world_step(w, DT);
        if (rc != SC_OK) {
            fprintf(stderr, "bench_workers: step: %s\n", sc_strerror(rc));
            sc_world_destroy(w);
            return -1;
        }
        sc_stats st;
        sc_world_stats(w, &st);
        mk += st.frame.sched.makespan_s;
        bound += st.frame.sched.makespan_bound_s;
        sched += st.frame.sched.sched_s;
        units += st.frame.sched.units;
    }
    r->wall = now_s() - t0;
    sc_stats st;
    sc_world_stats(w, &st);
    r->nodes = st.now.nodes;
    r->private_ode = st.now.private_ode;
    r->ratio = bound > 0 ? mk / bound : 0;
    r->sched = sched / r->wall;
    r->units = (double)units / frames;
    r->hash = (unsigned long long)sc_world_hash(w);
    sc_world_destroy(w);
    return 0;
}

static double median(double *x, int n)
{
    qsort(x, (size_t)n, sizeof *x, cmp_double);
    return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

int main(int argc, char **argv)
{
    int runs = 3, nw = 2, ws[MAX_W] = { 1, 2 };
    double seconds = 1.0;
    const char *modes = "wg";
    int ns[16], nn = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-r") && i + 1 < argc) {
            runs = atoi(argv[++i]);
        } else if (!strcmp(argv[i], "-s") && i + 1 < argc) {
            seconds = atof(argv[++i]);
        } else if (!strcmp(argv[i], "-w") && i + 1 < argc) {
            nw = 0;
            for (char *t = strtok(argv[++i], ","); t && nw < MAX_W; t = strtok(NULL, ","))
                ws[nw++] = atoi(t);
        } else if (!strcmp(argv[i], "-m") && i + 1 < argc) {
            modes = argv[++i];
        } else if (argv[i][0] != '-' && nn < 16) {
            ns[nn++] = atoi(argv[i]);
        } else {
            fprintf(stderr, "usage: bench_workers [-r RUNS] [-s SECONDS] [-w W1,W2,...] "
                            "[-m MODES (w, g)] [N ...]\n");
            return 2;
        }
    }
    if (runs < 1 || runs > MAX_RUNS || !(seconds > 0) || nw < 1 || !*modes ||
        strspn(modes, "wg") != strlen(modes)) {
        fprintf(stderr, "bench_workers: runs 1..%d, seconds > 0, at least one worker count, "
                        "modes of w and g\n", MAX_RUNS);
        return 2;
    }
    for (int k = 0; k < nw; k++)
        if (ws[k] < 1 || ws[k] > SC_MAX_WORKERS) {
            fprintf(stderr, "bench_workers: workers 1..%d\n", SC_MAX_WORKERS);
            return 2;
        }
    if (nn == 0) {
        ns[0] = 50;
        ns[1] = 200;
        ns[2] = 1000;
        nn = 3;
    }
    printf("bolts/nuts drop, %.2f s simulated (frames of %.2f s), medians of %d runs\n", seconds,
           DT, runs);
    printf("%6s %7s %8s %6s %10s %9s %8s %10s %9s %10s\n", "N", "mode", "workers", "priv",
           "wall s", "RT factor", "speedup", "makespan/", "sched %", "units/fr");
    printf("%6s %7s %8s %6s %10s %9s %8s %10s %9s %10s\n", "", "", "", "ODE", "", "", "", "bound",
           "", "");
    int bad = 0;
    for (int i = 0; i < nn; i++)
    for (const char *m = modes; *m; m++) {
        int groups = *m == 'g';
        double base = 0;
        unsigned long long h0 = 0;
        for (int k = 0; k < nw; k++) {
            double wall[MAX_RUNS], ratio[MAX_RUNS], sched[MAX_RUNS];
            result r = { 0 };
            for (int j = 0; j < runs; j++) {
                if (run(ns[i], ws[k], groups, seconds, &r) != 0)
                    return 1;
                if (k == 0 && j == 0)
                    h0 = r.hash;
                if (r.hash != h0) {
                    fprintf(stderr, "bench_workers: N=%d %s workers=%d: state hash %016llx != "
                            "%016llx of %d workers\n", ns[i], groups ? "groups" : "world",
                            ws[k], r.hash, h0, ws[0]);
                    bad = 1;
                }
                wall[j] = r.wall;
                ratio[j] = r.ratio;
                sched[j] = r.sched;
            }
            double mw = median(wall, runs);
            if (k == 0)
                base = mw;
            printf("%6d %7s %8d %6d %10.3f %9.3f %8.2f %10.2f %9.2f %10.0f\n", ns[i],
                   groups ? "groups" : "world", ws[k], r.private_ode, mw, seconds / mw, base / mw, median(ratio, runs),
                   100 * median(sched, runs), r.units);
            fflush(stdout);
        }
    }
    printf("mode: world = the paper's world-wide time-of-impact back-up, groups = motion "
           "groups (sc_world_config.motion_groups). RT factor: simulated / wall (>= 1 is real "
           "time). speedup: wall of %d worker(s) / wall, same mode. makespan/bound: measured job "
           "makespans over max(total work / total speed, largest unit), summed over all jobs. "
           "sched %%: scheduling time / wall.\n", ws[0]);
    if (bad)
        printf("FAILED: the final state depends on the worker count\n");
    return bad;
}
