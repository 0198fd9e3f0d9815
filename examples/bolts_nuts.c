/* bolts_nuts.c - the paper's experiment (Figs 3-4): N bolts and nuts
 * (alternating, e = 0.8, mu = 0.5) dropped from random non-overlapping poses
 * onto a floor, simulated at 100 Hz until all are at rest. `make demo` runs
 * it with N = 50.
 *   usage: bolts_nuts [N [SEED [WORKERS]]]   (defaults 50, 1, online CPUs) */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "simcluster.h"

#define DT 0.01
#define MAX_SIM_S 60.0

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int parse_int(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || end == s || v < lo || v > hi)
        return 0;
    *out = v;
    return 1;
}

int main(int argc, char **argv)
{
    long n = 50, seed = 1;
    long workers = 0;
    if (argc > 4 || (argc > 1 && !parse_int(argv[1], 1, 100000, &n)) ||
        (argc > 2 && !parse_int(argv[2], 0, 0x7fffffffL, &seed)) ||
        (argc > 3 && !parse_int(argv[3], 0, SC_MAX_WORKERS, &workers))) {
        fprintf(stderr, "usage: bolts_nuts [N (1..100000) [SEED [WORKERS (0 = CPUs)]]]\n");
        return 2;
    }
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = (int)workers;
    sc_world *w = sc_world_create(&cfg);
    if (!w) {
        fprintf(stderr, "bolts_nuts: %s\n", sc_strerror(sc_last_error()));
        return 1;
    }
    int rc = sc_scene_bolts_nuts(w, (int)n, (uint64_t)seed);
    if (rc != SC_OK) {
        fprintf(stderr, "bolts_nuts: scene: %s\n", sc_strerror(rc));
        sc_world_destroy(w);
        return 1;
    }
    double e0 = sc_world_energy(w), peak = e0, pen = 0;
    long frames = 0, fallbacks = 0, refused = 0;
    double t0 = now_s();
    while (!sc_world_at_rest(w) && frames * DT < MAX_SIM_S) {
        rc = sc_world_step(w, DT);
        if (rc != SC_OK) {
            fprintf(stderr, "bolts_nuts: frame %ld: %s\n", frames, sc_strerror(rc));
            break;
        }
        frames++;
        sc_stats st;
        sc_world_stats(w, &st);
        pen = pen > st.frame.detect.max_penetration ? pen : st.frame.detect.max_penetration;
        fallbacks += st.frame.lcp.fallbacks;
        refused += st.frame.lcp.energy_refused;
        double e = sc_world_energy(w);
        peak = peak > e ? peak : e;
    }
    double wall = now_s() - t0, sim = frames * DT;
    sc_stats st;
    sc_world_stats(w, &st);
    printf("bolts and nuts: %ld bodies, seed %ld, %d worker thread%s (%d on a private ODE), "
           "frame %.2f s\n",
           n, seed, st.now.nodes, st.now.nodes == 1 ? "" : "s", st.now.private_ode, DT);
    if (sc_world_at_rest(w))
        printf("  all at rest after      %8.2f s simulated\n", sim);
    else
        printf("  NOT at rest after      %8.2f s simulated\n", sim);
    printf("  wall time              %8.3f s\n", wall);
    printf("  real-time factor       %8.2f x (simulated / wall)\n", wall > 0 ? sim / wall : 0);
    printf("  peak energy / initial  %8.5f\n", peak / e0);
    printf("  max penetration        %8.3f mm\n", 1000 * pen);
    printf("  friction fallbacks     %8ld islands (%ld answers refused for adding energy)\n",
           fallbacks, refused);
    static const char *names[SC_STAGE_COUNT] = { "broad phase", "narrow phase", "time of impact",
                                                 "contact graph", "LCP (Dantzig)", "integration" };
    double total = 0;
    for (int k = 0; k < SC_STAGE_COUNT; k++)
        total += st.total.stage_s[k];
    printf("  CPU by stage:\n");
    for (int k = 0; k < SC_STAGE_COUNT; k++)
        printf("    %-16s %8.3f s %6.2f %%\n", names[k], st.total.stage_s[k],
               total > 0 ? 100 * st.total.stage_s[k] / total : 0);
    sc_world_destroy(w);
    return rc == SC_OK && sim < MAX_SIM_S ? 0 : 1;
}
