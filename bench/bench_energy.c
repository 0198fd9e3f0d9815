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
 * -j lists each box's jumps: the frame, its change, the spheres whose
 * translational and potential energy it moved by more than 0.01 J/kg, and
 * those spheres replayed alone (the same walls, their poses and velocities
 * at the frame's start, one frame) in both modes, as a share of their own
 * energy. A jump that the replay repeats is a defect of that contact
 * event alone, and the replay is its test case (docs/DESIGN.md 3.4).
 *
 * usage: bench_energy [-f frames] [-n 8,27,64] [-r 0.1,0.2] [-v 1,3] [-j] */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "simcluster.h"

#define MAXL 8
#define MAX_JUMPS 32             /* listed a box (-j) */
#define MAX_JUMP_BODIES 16
#define STEEL 7800.0             /* kg/m^3, as sc_scene_elastic_box() */

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

/* A sphere's pose and velocity: pos, quat, v, omega. */
typedef struct sphere_state {
    double x[13];
} sphere_state;

typedef struct jump {
    int frame, nbodies;
    int ids[MAX_JUMP_BODIES];
    double de;                   /* the box's change over its start energy */
    double alone[2];             /* replayed alone: local, world */
} jump;

typedef struct box_run {
    double peak, drift;
    long inelastic, jumps;
    int rc;
    int nlisted;
    jump listed[MAX_JUMPS];
} box_run;

static void get_state(const sc_world *w, int id, sphere_state *s)
{
    sc_body_get_pose(w, id, s->x, s->x + 3);
    sc_body_get_velocity(w, id, s->x + 7, s->x + 10);
}

/* Translational kinetic plus potential energy per kg (gravity -9.81 z). */
static double energy_per_kg(const double *x)
{
    return 0.5 * (x[7] * x[7] + x[8] * x[8] + x[9] * x[9]) + 9.81 * x[2];
}

/* The spheres alone in the box's walls, one frame from states s: the
 * change of their energy over its start (NAN when it cannot be built). */
static double replay_alone(const sphere_state *s, int n, double r, int mode)
{
    static const double planes[6][4] = { { 0, 0, 1, 0 },  { 0, 0, -1, -4 }, { 1, 0, 0, -2 },
                                         { -1, 0, 0, -2 }, { 0, 1, 0, -2 },  { 0, -1, 0, -2 } };
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    c.workers = 1;
    sc_world *w = sc_world_create(&c);
    int ok = w != NULL;
    for (int i = 0; i < 6 && ok; i++) {
        sc_body_desc d = sc_body_desc_default();
        d.shape = sc_shape_plane(planes[i][0], planes[i][1], planes[i][2], planes[i][3]);
        d.mass = 0;
        d.restitution = 1;
        d.friction = 0;
        ok = d.shape && sc_body_add(w, &d) >= 0;
        sc_shape_release(d.shape);
    }
    sc_shape *ball = ok ? sc_shape_uv_sphere(r, 16, 8) : NULL;
    for (int k = 0; k < n && ball; k++) {
        sc_body_desc d = sc_body_desc_default();
        d.shape = ball;
        d.mass = SC_MASS_FROM_DENSITY;
        d.density = STEEL;
        d.restitution = 1;
        d.friction = 0;
        memcpy(d.pos, s[k].x, sizeof d.pos);
        memcpy(d.quat, s[k].x + 3, sizeof d.quat);
        memcpy(d.vel, s[k].x + 7, sizeof d.vel);
        memcpy(d.omega, s[k].x + 10, sizeof d.omega);
        ok = ok && sc_body_add(w, &d) >= 0;
    }
    sc_shape_release(ball);
    double de = NAN;
    if (ok && ball) {
        double e0 = sc_world_energy(w);
        if (sc_world_step(w, 0.01) == SC_OK)
            de = sc_world_energy(w) / e0 - 1;
    }
    sc_world_destroy(w);
    return de;
}

/* The spheres whose energy frame f moved (before: their states at its
 * start), replayed alone in both modes. */
static void list_jump(box_run *b, const sc_world *w, const sphere_state *before, int nb, double r,
                      int f, double de)
{
    if (b->nlisted == MAX_JUMPS)
        return;
    jump *j = &b->listed[b->nlisted++];
    sphere_state alone[MAX_JUMP_BODIES];
    j->frame = f;
    j->de = de;
    j->nbodies = 0;
    for (int i = 0; i < nb && j->nbodies < MAX_JUMP_BODIES; i++) {
        if (sc_body_state(w, i) == SC_STATIC)
            continue;
        sphere_state now;
        get_state(w, i, &now);
        if (!(fabs(energy_per_kg(now.x) - energy_per_kg(before[i].x)) > 0.01))
            continue;
        alone[j->nbodies] = before[i];
        j->ids[j->nbodies++] = i;
    }
    for (int mode = 0; mode < 2; mode++)
        j->alone[mode] = j->nbodies ? replay_alone(alone, j->nbodies, r,
                                                   mode ? SC_TOI_WORLD : SC_TOI_LOCAL)
                                    : NAN;
}

static box_run run_box(int n, double r, double v, int mode, int frames, int list)
{
    box_run b = { 1, 0, 0, 0, SC_OK, 0, { { 0 } } };
    sc_world_config c = sc_world_config_default();
    c.toi_mode = mode;
    c.workers = 1;
    sc_world *w = sc_world_create(&c);
    b.rc = w ? sc_scene_elastic_box(w, n, r, v) : sc_last_error();
    int nb = b.rc == SC_OK ? sc_world_body_count(w) : 0;
    sphere_state *before = list && nb > 0 ? calloc((size_t)nb, sizeof *before) : NULL;
    if (list && nb > 0 && !before)
        b.rc = SC_ENOMEM;
    double e0 = b.rc == SC_OK ? sc_world_energy(w) : 0, e = e0;
    for (int f = 1; f <= frames && b.rc == SC_OK; f++) {
        double start = e;
        for (int i = 0; before && i < nb; i++)
            get_state(w, i, &before[i]);
        b.rc = sc_world_step(w, 0.01);
        e = sc_world_energy(w);
        sc_stats st;
        sc_world_stats(w, &st);
        b.inelastic += st.frame.lcp.inelastic;
        int jumped = fabs(e - start) > 0.002 * e0;
        b.jumps += jumped;
        if (jumped && before)
            list_jump(&b, w, before, nb, r, f, (e - start) / e0);
        b.peak = fmax(b.peak, e / e0);
        b.drift = fmax(b.drift, fabs(e / e0 - 1));
    }
    free(before);
    sc_world_destroy(w);
    return b;
}

int main(int argc, char **argv)
{
    double ns[MAXL] = { 8, 27, 64 }, rs[MAXL] = { 0.1, 0.2 }, vs[MAXL] = { 1, 3 };
    int nn = 3, nr = 2, nv = 2, frames = 5000, list = 0, opt;
    while ((opt = getopt(argc, argv, "f:n:r:v:j")) != -1) {
        int bad = 0;
        if (opt == 'j')
            list = 1;
        else if (opt == 'f')
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
                            "[-v 1,3] [-j] (up to %d values a list)\n", MAXL);
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
                    box_run x = run_box(n, rs[b], vs[k], mode, frames, list);
                    if (x.rc != SC_OK) {
                        printf("  %4d %5.2f %4.1f  %-6s error: %s\n", n, rs[b], vs[k],
                               mode == SC_TOI_LOCAL ? "local" : "world", sc_strerror(x.rc));
                        fail = 1;
                        continue;
                    }
                    printf("  %4d %5.2f %4.1f  %-6s %9.5f %9.3f %10ld %12ld\n", n, rs[b], vs[k],
                           mode == SC_TOI_LOCAL ? "local" : "world", x.peak, 100 * x.drift,
                           x.inelastic, x.jumps);
                    for (int i = 0; i < x.nlisted; i++) {
                        const jump *j = &x.listed[i];
                        printf("      frame %d: %+.5f of the box; spheres", j->frame, j->de);
                        for (int q = 0; q < j->nbodies; q++)
                            printf(" %d", j->ids[q]);
                        printf("; alone %+.5f (local), %+.5f (world) of theirs\n", j->alone[0],
                               j->alone[1]);
                    }
                }
    return fail;
}
