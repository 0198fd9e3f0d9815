/* spheres_box.c - the paper's Table 1 scene: 27 spheres (224 triangles,
 * r = 0.1 m, e = 1) in a 4 m box, 3 x 3 x 3 at 1 m spacing, dt = 0.01 s,
 * 5000 frames, gravity only. Prints the share of CPU time per stage next to
 * the paper's percentages, and the energy drift.
 *   usage: spheres_box [FRAMES]   (default 5000) */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "simcluster.h"

int main(int argc, char **argv)
{
    long frames = 5000;
    if (argc > 2 || (argc == 2 && ((frames = strtol(argv[1], NULL, 10)) <= 0 || frames > 10000000))) {
        fprintf(stderr, "usage: spheres_box [FRAMES (1..10000000)]\n");
        return 2;
    }
    sc_world *w = sc_world_create(NULL);
    int rc = w ? sc_scene_spheres_box(w) : sc_last_error();
    if (rc != SC_OK) {
        fprintf(stderr, "spheres_box: %s\n", sc_strerror(rc));
        sc_world_destroy(w);
        return 1;
    }
    double e0 = sc_world_energy(w), worst = 0;
    for (long f = 0; f < frames && rc == SC_OK; f++) {
        rc = sc_world_step(w, 0.01);
        worst = fmax(worst, fabs(sc_world_energy(w) / e0 - 1));
    }
    if (rc != SC_OK) {
        fprintf(stderr, "spheres_box: %s\n", sc_strerror(rc));
        sc_world_destroy(w);
        return 1;
    }
    sc_stats st;
    sc_world_stats(w, &st);
    /* the paper's rows (Table 1): detection, Dantzig, contact graph,
     * integration, bounding spheres; TOI is our extra row */
    static const struct { const char *name; int stage; double paper; } rows[] = {
        { "polygon-level detection", SC_STAGE_NARROWPHASE, 41.48 },
        { "Dantzig (LCP)", SC_STAGE_LCP, 37.35 },
        { "contact graph", SC_STAGE_ISLANDS, 16.27 },
        { "integration", SC_STAGE_INTEGRATE, 4.88 },
        { "bounding spheres", SC_STAGE_BROADPHASE, 0.02 },
        { "time of impact", SC_STAGE_TOI, NAN },
    };
    double total = 0;
    for (int k = 0; k < SC_STAGE_COUNT; k++)
        total += st.total.stage_s[k];
    printf("Table 1 scene, %ld frames: CPU time by stage\n", frames);
    printf("  %-26s %10s %8s %8s\n", "stage", "CPU s", "ours %", "paper %");
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        double s = st.total.stage_s[rows[i].stage];
        printf("  %-26s %10.4f %8.2f ", rows[i].name, s, total > 0 ? 100 * s / total : 0);
        if (isnan(rows[i].paper))
            printf("%8s\n", "-");
        else
            printf("%8.2f\n", rows[i].paper);
    }
    printf("  energy: worst |E/E0 - 1| = %.5f (%.3f %%)\n", worst, 100 * worst);
    sc_world_destroy(w);
    return 0;
}
