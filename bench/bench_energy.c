/* bench_energy.c - elastic boxes beyond the Table 1 scene: n UV spheres
 * (16 x 8, steel) of radius r at speed v in the Table 1 box (4 x 4 x 4 m,
 * six half spaces, e = 1, no friction, gravity on), both time-of-impact
 * modes, frames of 10 ms; per box the peak of the total energy over its
 * start and the worst drift |E/E0 - 1|, with the elastic re-solves and the
 * single frames that lost or gained more than 0.2 % of the start.
 *
 * The scene is sc_scene_elastic_box(): spheres on a cubic grid filling
 * 3.2 m around the box's centre, heading off along n directions spread
 * over the unit sphere (Fibonacci spiral, as sc_scene_spheres_box()),
 * which test_physics runs too. The target for every such
 * box: peak <= 1.001, drift <= 0.5 % over 5000 frames.
 *
 * usage: bench_energy [-f frames] [-n 8,27,64] [-r 0.1,0.2] [-v 1,3] */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "simcluster.h"

#define MAXL 8

static int parse_list(const char *s, double *out)
{
    int n = 0;
    char *end;
    while (n < MAXL) {
        out[n++] = strtod(s, &end);
        if (end == s)
            return -1;
        if (*end != ',')
            break;
        s = end + 1;
    }
    return *end ? -1 : n;
}

typedef struct box_run {
    double peak, drift;
    long inelastic, jumps;
    int rc;
} box_run;

static box_run run_box(int n, double r, double v, int mode, int frames)
{
    box_run b = { 1, 0, 0, 0, SC_OK };
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    c.workers = 1;
    sc_world *w = sc_world_create(&c);
    b.rc = w ? sc_scene_elastic_box(w, n, r, v) : sc_last_error();
    double e0 = b.rc == SC_OK ? sc_world_energy(w) : 0, e = e0;
    for (int f = 0; f < frames && b.rc == SC_OK; f++) {
        double before = e;
        b.rc = sc_world_step(w, 0.01);
        e = sc_world_energy(w);
        sc_stats st;
        sc_world_stats(w, &st);
        b.inelastic += st.lcp_inelastic;
        b.jumps += fabs(e - before) > 0.002 * e0;
        b.peak = fmax(b.peak, e / e0);
        b.drift = fmax(b.drift, fabs(e / e0 - 1));
    }
    sc_world_destroy(w);
    return b;
}

int main(int argc, char **argv)
{
    double ns[MAXL] = { 8, 27, 64 }, rs[MAXL] = { 0.1, 0.2 }, vs[MAXL] = { 1, 3 };
    int nn = 3, nr = 2, nv = 2, frames = 5000, opt;
    while ((opt = getopt(argc, argv, "f:n:r:v:")) != -1) {
        int bad = 0;
        if (opt == 'f')
            bad = (frames = atoi(optarg)) < 1;
        else if (opt == 'n')
            bad = (nn = parse_list(optarg, ns)) < 1;
        else if (opt == 'r')
            bad = (nr = parse_list(optarg, rs)) < 1;
        else if (opt == 'v')
            bad = (nv = parse_list(optarg, vs)) < 1;
        else
            bad = 1;
        if (bad) {
            fprintf(stderr, "usage: bench_energy [-f frames] [-n 8,27,64] [-r 0.1,0.2] "
                            "[-v 1,3] (up to %d values a list)\n", MAXL);
            return 2;
        }
    }
    printf("elastic boxes: n UV spheres of radius r at v m/s in the Table 1 box, e = 1, %d "
           "frames of 10 ms, one worker\n", frames);
    printf("  %4s %5s %4s  %-6s %9s %9s %10s %12s\n", "n", "r m", "v", "mode", "peak", "drift %",
           "inelastic", "jumps >0.2%");
    int fail = 0;
    for (int a = 0; a < nn; a++)
        for (int b = 0; b < nr; b++)
            for (int k = 0; k < nv; k++)
                for (int mode = SC_TOI_LOCAL; mode <= SC_TOI_WORLD; mode++) {
                    int n = (int)ns[a];
                    if (n < 1 || n > 1000 || !(rs[b] > 0) || !(rs[b] < 0.25)) {
                        fprintf(stderr, "bench_energy: n 1..1000, r in (0, 0.25) m\n");
                        return 2;
                    }
                    box_run x = run_box(n, rs[b], vs[k], mode, frames);
                    if (x.rc != SC_OK) {
                        printf("  %4d %5.2f %4.1f  %-6s error: %s\n", n, rs[b], vs[k],
                               mode == SC_TOI_LOCAL ? "local" : "world", sc_strerror(x.rc));
                        fail = 1;
                        continue;
                    }
                    printf("  %4d %5.2f %4.1f  %-6s %9.5f %9.3f %10ld %12ld\n", n, rs[b], vs[k],
                           mode == SC_TOI_LOCAL ? "local" : "world", x.peak, 100 * x.drift,
                           x.inelastic, x.jumps);
                }
    return fail;
}
