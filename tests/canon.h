/* canon.h - the canonical scenes: single bodies and small structures whose
 * motion has an answer on paper (docs/DESIGN.md 10). Each scene is a list
 * of boxes, spheres and planes that any engine can build; an engine steps
 * it and records every dynamic body's state each frame (canon_traj), and
 * canon_judge() turns the record into figures, each with the analytic
 * value it must reach and a tolerance derived from the physics.
 * tests/test_canon.c runs every scene in both time-of-impact modes on 1
 * and 2 workers and asserts each figure; bench/bench_canon.c prints them
 * beside ODE's dWorldStep and dWorldQuickStep on the same scenes. */
#ifndef SC_CANON_H
#define SC_CANON_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <simcluster.h>

#define CANON_G 9.81
#define CANON_MAX_BODIES 256
#define CANON_MAX_FIGS 5

enum { CANON_PLANE, CANON_BOX, CANON_SPHERE };

typedef struct canon_body {
    int kind;
    double size[4];           /* box: half extents; sphere: radius; plane: n, d */
    double mass;              /* 0: static */
    double pos[3], quat[4], vel[3], omega[3];
    double e, mu;
} canon_body;

/* How a figure is judged: |value - expect| <= tol, or value <= expect + tol. */
enum { CANON_NEAR, CANON_AT_MOST };

typedef struct canon_fig {
    const char *name;         /* what is measured, with its unit */
    double value, expect, tol;
    int how;
} canon_fig;

typedef struct canon_scene {
    const char *name;
    const char *what;         /* the known answer, in words */
    double dt, T;             /* frame and simulated time, s */
    double gravity;           /* m/s^2 down -z (0: none) */
    int nb;
    canon_body b[CANON_MAX_BODIES];
    int family;               /* CANON_F_*: which judge */
    double p[4];              /* the judge's parameters (per family) */
} canon_scene;

enum {
    CANON_F_DROP,             /* p: h (fall of the lowest point), e */
    CANON_F_SLIDE,            /* p: v0, mu */
    CANON_F_SLOPE,            /* p: theta, mu */
    CANON_F_ROLL,             /* p: v0 (rolling from the start) */
    CANON_F_SLIDE_ROLL,       /* p: v0, mu (sliding into rolling) */
    CANON_F_SPIN,             /* p: w0, mu, corner distance */
    CANON_F_HEADON,           /* p: v0, e */
    CANON_F_STAND,            /* p: none: every body stays put */
};

/* What an engine records: per frame, per dynamic body (in scene order),
 * x[3] q[4] v[3] w[3]. */
typedef struct canon_traj {
    int frames, nd;
    double *s;                /* frames * nd * 13 */
    int error;                /* a step failed (the engine's code), 0 if none */
} canon_traj;

static inline double *canon_at(const canon_traj *t, int f, int i)
{
    return &t->s[((size_t)f * (size_t)t->nd + (size_t)i) * 13];
}

static inline int canon_dynamic(const canon_scene *sc)
{
    int n = 0;
    for (int i = 0; i < sc->nb; i++)
        n += sc->b[i].mass > 0;
    return n;
}

static inline int canon_traj_init(canon_traj *t, const canon_scene *sc)
{
    t->frames = (int)lround(sc->T / sc->dt);
    t->nd = canon_dynamic(sc);
    t->error = 0;
    t->s = calloc((size_t)(t->frames + 1) * (size_t)t->nd * 13, sizeof *t->s);
    return t->s ? 0 : -1;
}

static inline void canon_traj_free(canon_traj *t)
{
    free(t->s);
    t->s = NULL;
}

/* ---- the scenes ---------------------------------------------------------- */

static inline canon_body canon_floor(double e, double mu)
{
    canon_body b = { .kind = CANON_PLANE, .size = { 0, 0, 1, 0 }, .quat = { 1, 0, 0, 0 },
                     .e = e, .mu = mu };
    return b;
}

static inline canon_body canon_box(double half, double mass, double e, double mu)
{
    canon_body b = { .kind = CANON_BOX, .size = { half, half, half }, .mass = mass,
                     .quat = { 1, 0, 0, 0 }, .e = e, .mu = mu };
    return b;
}

static inline canon_body canon_sphere(double r, double mass, double e, double mu)
{
    canon_body b = { .kind = CANON_SPHERE, .size = { r }, .mass = mass, .quat = { 1, 0, 0, 0 },
                     .e = e, .mu = mu };
    return b;
}

/* A unit quaternion turning by angle a about the unit axis (x, y, z). */
static inline void canon_quat(double q[4], double a, double x, double y, double z)
{
    q[0] = cos(a / 2);
    q[1] = x * sin(a / 2);
    q[2] = y * sin(a / 2);
    q[3] = z * sin(a / 2);
}

/* A 0.2 m cube (1 kg, e, mu 0.5) dropped from h onto a floor: flat, on an
 * edge (turned 45 degrees about x) or on a corner (its long diagonal
 * vertical). The lowest point falls h. The impulse passes through the
 * centre of mass in all three, so it bounces straight up to e^2 h, with
 * no turn and no drift. */
static inline canon_scene canon_drop_box(const char *name, int how, double h, double e)
{
    canon_scene sc = { .name = name, .dt = 0.01, .T = 3.0, .gravity = CANON_G, .nb = 2,
                       .family = CANON_F_DROP, .p = { h, e } };
    sc.what = how == 0 ? "cube dropped flat: apex e^2 h, no tilt, no drift"
            : how == 1 ? "cube dropped on an edge: apex e^2 h, no tilt, no drift"
                       : "cube dropped on a corner: apex e^2 h, no tilt, no drift";
    sc.b[0] = canon_floor(e, 0.5);
    sc.b[1] = canon_box(0.1, 1.0, e, 0.5);
    double low = 0.1;
    if (how == 1) {
        canon_quat(sc.b[1].quat, M_PI / 4, 1, 0, 0);
        low = 0.1 * sqrt(2.0);
    } else if (how == 2) {
        /* the diagonal (1, 1, 1) turned onto z: about (1, -1, 0) by acos(1/sqrt 3) */
        canon_quat(sc.b[1].quat, acos(1 / sqrt(3.0)), 1 / sqrt(2.0), -1 / sqrt(2.0), 0);
        low = 0.1 * sqrt(3.0);
    }
    sc.b[1].pos[2] = h + low;
    return sc;
}

/* A sphere of 0.1 m dropped from h (its lowest point) onto a floor. */
static inline canon_scene canon_drop_sphere(double h, double e)
{
    canon_scene sc = { .name = "sphere bounce", .dt = 0.01, .T = 3.0, .gravity = CANON_G,
                       .nb = 2, .family = CANON_F_DROP, .p = { h, e },
                       .what = "sphere dropped: apex e^2 h, no drift" };
    sc.b[0] = canon_floor(e, 0.5);
    sc.b[1] = canon_sphere(0.1, 1.0, e, 0.5);
    sc.b[1].pos[2] = h + 0.1;
    return sc;
}

/* Bodies 0 and 1 of sc: a floor and a 0.2 m cube (1 kg) resting on it,
 * no restitution, friction mu on both. */
static inline void canon_box_on_floor(canon_scene *sc, double mu)
{
    sc->b[0] = canon_floor(0, mu);
    sc->b[1] = canon_box(0.1, 1.0, 0, mu);
    sc->b[1].pos[2] = 0.1;
}

/* A cube resting on the floor, pushed along x at v0: it slides
 * v0^2 / (2 mu g) and stops, without tipping (mu h_com < half width). */
static inline canon_scene canon_slide(double v0, double mu)
{
    canon_scene sc = { .name = "box slides to rest", .dt = 0.01, .T = 1.5, .gravity = CANON_G,
                       .nb = 2, .family = CANON_F_SLIDE, .p = { v0, mu },
                       .what = "sliding box stops after v0^2 / (2 mu g)" };
    canon_box_on_floor(&sc, mu);
    sc.b[1].vel[0] = v0;
    return sc;
}

/* A cube at rest on a plane tilted by theta about y (mu on both): below
 * the friction angle atan(mu) it holds; above it slides down at
 * g (sin theta - mu cos theta). tan theta < 1: it never tips. */
static inline canon_scene canon_slope(const char *name, double theta, double mu)
{
    canon_scene sc = { .name = name, .dt = 0.01, .T = 1.0, .gravity = CANON_G, .nb = 2,
                       .family = CANON_F_SLOPE, .p = { theta, mu } };
    sc.what = theta < atan(mu) ? "box on a slope below the friction angle: holds"
                               : "box on a slope above the friction angle: a = g (sin - mu cos)";
    double n[3] = { -sin(theta), 0, cos(theta) };    /* the plane's normal, tilted about y */
    sc.b[0] = canon_floor(0, mu);
    memcpy(sc.b[0].size, n, sizeof n);
    sc.b[0].size[3] = 0;
    sc.b[1] = canon_box(0.1, 1.0, 0, mu);
    canon_quat(sc.b[1].quat, -theta, 0, 1, 0);
    /* resting: 0.2 mm into the plane (under the slop), so that the first
     * frame finds the contact instead of a fall of g dt^2 / 2, whose part
     * along the slope would count as sliding */
    for (int j = 0; j < 3; j++)
        sc.b[1].pos[j] = (0.1 - 2e-4) * n[j];
    return sc;
}

/* A sphere rolling on the floor without slipping at v0 (w = v0 / r):
 * nothing acts along the floor, so it rolls on at v0. */
static inline canon_scene canon_roll(double v0)
{
    canon_scene sc = { .name = "sphere rolls", .dt = 0.01, .T = 2.0, .gravity = CANON_G,
                       .nb = 2, .family = CANON_F_ROLL, .p = { v0 },
                       .what = "rolling sphere keeps v0 and w = v0 / r" };
    sc.b[0] = canon_floor(0, 0.5);
    sc.b[1] = canon_sphere(0.1, 1.0, 0, 0.5);
    sc.b[1].pos[2] = 0.1;
    sc.b[1].vel[0] = v0;
    sc.b[1].omega[1] = v0 / 0.1;
    return sc;
}

/* A sphere thrown along the floor at v0 without spin: friction turns it
 * until it rolls, at 5/7 v0 (a solid sphere), after 2 v0 / (7 mu g). */
static inline canon_scene canon_slide_roll(double v0, double mu)
{
    canon_scene sc = { .name = "sphere slides into rolling", .dt = 0.01, .T = 1.0,
                       .gravity = CANON_G, .nb = 2, .family = CANON_F_SLIDE_ROLL,
                       .p = { v0, mu }, .what = "sliding sphere rolls on at 5/7 v0" };
    sc.b[0] = canon_floor(0, mu);
    sc.b[1] = canon_sphere(0.1, 1.0, 0, mu);
    sc.b[1].pos[2] = 0.1;
    sc.b[1].vel[0] = v0;
    return sc;
}

/* A cube spinning at w0 about z on the floor. Its face rests on the four
 * corners the box-plane contact gives, each with a quarter of the weight
 * at a sqrt 2 from the axis: a friction torque of mu m g a sqrt 2 against
 * I_z = m (2a)^2 / 6, so it turns w0^2 / (2 alpha) before it stops, in
 * place. (A uniformly pressed face would give 0.541 of that torque; the
 * engine's face contact is its corners.) */
static inline canon_scene canon_spin(double w0, double mu)
{
    canon_scene sc = { .name = "box spins down", .dt = 0.01, .T = 1.0, .gravity = CANON_G,
                       .nb = 2, .family = CANON_F_SPIN, .p = { w0, mu, 0.1 * sqrt(2.0) },
                       .what = "spinning box turns w0^2 / (2 alpha) in place" };
    canon_box_on_floor(&sc, mu);
    sc.b[1].omega[2] = w0;
    return sc;
}

/* Two equal bodies (1 kg; spheres of 0.1 m or cubes of 0.2 m meeting face
 * to face) without gravity, one at rest, the other coming at v0 along x:
 * after the impact (1 - e) v0 / 2 and (1 + e) v0 / 2, no spin. */
static inline canon_scene canon_headon(const char *name, int boxes, double v0, double e)
{
    canon_scene sc = { .name = name, .dt = 0.01, .T = 1.0, .gravity = 0, .nb = 2,
                       .family = CANON_F_HEADON, .p = { v0, e },
                       .what = "head-on: (1 -+ e) v0 / 2, no spin" };
    for (int i = 0; i < 2; i++) {
        sc.b[i] = boxes ? canon_box(0.1, 1.0, e, 0.5) : canon_sphere(0.1, 1.0, e, 0.5);
        sc.b[i].pos[0] = i ? 0.3 : -0.3;
    }
    sc.b[0].vel[0] = v0;
    return sc;
}

/* The centre of a cube of 0.2 m resting on layer-many others on the floor,
 * each 0.2 mm into the one below (under the slop): a contact from the
 * first frame on. Placed exactly touching, the structure fell for a frame
 * or two before its contacts showed (box faces touching at depth 0 give
 * none), and landed on itself at 0.2 m/s. */
#define CANON_REST_Z(layer) ((0.1 - 2e-4) + (layer) * (0.2 - 2e-4))

/* n cubes of 0.2 m stacked on the floor, each resting on the one below,
 * aligned: nothing moves. */
static inline canon_scene canon_stack(int n)
{
    canon_scene sc = { .name = "stack of boxes", .dt = 0.01, .T = 3.0, .gravity = CANON_G,
                       .nb = n + 1, .family = CANON_F_STAND,
                       .what = "stack stands: no drift, at rest" };
    sc.b[0] = canon_floor(0, 0.5);
    for (int i = 0; i < n; i++) {
        sc.b[i + 1] = canon_box(0.1, 1.0, 0, 0.5);
        sc.b[i + 1].pos[2] = CANON_REST_Z(i);
    }
    return sc;
}

/* A stack of n cubes of 0.2 m whose every other cube is offset by dx (m)
 * sideways, well inside static balance: nothing moves. */
static inline canon_scene canon_stack_offset(const char *name, int n, double dx, double T)
{
    canon_scene sc = canon_stack(n);
    sc.name = name;
    sc.T = T;
    for (int i = 0; i < n; i++)
        sc.b[i + 1].pos[0] = i % 2 ? dx : 0;
    return sc;
}

/* A wall of cubes of 0.2 m: rows of cols cubes 1 mm apart (faces that
 * touch at exactly 0 make contacts come and go), every other row shifted
 * by a quarter of a cube, so that each cube rests on two below (the end
 * cubes on three quarters of one): nothing moves. */
static inline canon_scene canon_wall(const char *name, int cols, int rows, double T)
{
    canon_scene sc = { .name = name, .dt = 0.01, .T = T, .gravity = CANON_G, .nb = 1,
                       .family = CANON_F_STAND, .what = "wall stands: no drift, at rest" };
    sc.b[0] = canon_floor(0, 0.5);
    for (int r = 0; r < rows; r++)
        for (int i = 0; i < cols && sc.nb < CANON_MAX_BODIES; i++) {
            canon_body *b = &sc.b[sc.nb++];
            *b = canon_box(0.1, 1.0, 0, 0.5);
            b->pos[0] = 0.201 * i + 0.05 * (r % 2) - 0.1005 * (cols - 1);
            b->pos[2] = CANON_REST_Z(r);
        }
    return sc;
}

/* A pyramid of cubes of 0.2 m: rows of rows, rows - 1, ... 1, each cube on
 * two of the row below (half a cube apart): nothing moves. */
static inline canon_scene canon_pyramid(int rows)
{
    canon_scene sc = { .name = "pyramid of boxes", .dt = 0.01, .T = 3.0, .gravity = CANON_G,
                       .nb = 1, .family = CANON_F_STAND,
                       .what = "pyramid stands: no drift, at rest" };
    sc.b[0] = canon_floor(0, 0.5);
    for (int r = 0; r < rows; r++)
        for (int i = 0; i < rows - r && sc.nb < CANON_MAX_BODIES; i++) {
            canon_body *b = &sc.b[sc.nb++];
            *b = canon_box(0.1, 1.0, 0, 0.5);
            b->pos[0] = 0.2 * i + 0.1 * r - 0.1 * (rows - 1);
            b->pos[2] = CANON_REST_Z(r);
        }
    return sc;
}

/* The structures suite (big islands: docs/DESIGN.md 11): stacks of 10, 20
 * and 40 cubes, two of them offset, a pyramid of 15 rows and a wall, each
 * standing for T s; *n its size. */
static inline canon_scene canon_named(canon_scene sc, const char *name, double T)
{
    sc.name = name;
    sc.T = T;
    return sc;
}

static inline int canon_structures(canon_scene *out, int max, double T)
{
    canon_scene all[] = {
        canon_named(canon_stack(10), "stack of 10", T),
        canon_named(canon_stack(20), "stack of 20", T),
        canon_named(canon_stack(40), "stack of 40", T),
        canon_stack_offset("stack of 20, offset 1 cm", 20, 0.01, T),
        canon_stack_offset("stack of 40, offset 1 cm", 40, 0.01, T),
        canon_named(canon_pyramid(15), "pyramid of 15 rows", T),
        canon_wall("wall of 10 x 12", 10, 12, T),
    };
    int n = (int)(sizeof all / sizeof all[0]);
    for (int i = 0; i < n && i < max; i++)
        out[i] = all[i];
    return n < max ? n : max;
}

/* A ball resting on the floor stepped at a large frame dt: it stays on it. */
static inline canon_scene canon_big_frame(const char *name, double dt)
{
    canon_scene sc = { .name = name, .dt = dt, .T = 5.0,
                       .gravity = CANON_G, .nb = 2, .family = CANON_F_STAND,
                       .what = "resting ball stays on the floor at a large frame" };
    sc.b[0] = canon_floor(0.5, 0.5);
    sc.b[1] = canon_sphere(0.1, 1.0, 0.5, 0.5);
    sc.b[1].pos[2] = 0.1;
    return sc;
}

/* The suite; *n its size. */
static inline int canon_suite(canon_scene *out, int max)
{
    canon_scene all[] = {
        canon_drop_box("box drop flat 0.5 m", 0, 0.5, 0.5),
        canon_drop_box("box drop flat 1 m", 0, 1.0, 0.5),
        canon_drop_box("box drop flat 2 m", 0, 2.0, 0.5),
        canon_drop_box("box drop edge 0.5 m", 1, 0.5, 0.5),
        canon_drop_box("box drop edge 1 m", 1, 1.0, 0.5),
        canon_drop_box("box drop edge 2 m", 1, 2.0, 0.5),
        canon_drop_box("box drop corner 0.5 m", 2, 0.5, 0.5),
        canon_drop_box("box drop corner 1 m", 2, 1.0, 0.5),
        canon_drop_box("box drop corner 2 m", 2, 2.0, 0.5),
        canon_drop_sphere(1.0, 0.5),
        canon_slide(2.0, 0.5),
        canon_slope("slope 20 deg, mu 0.5", 20 * M_PI / 180, 0.5),
        canon_slope("slope 35 deg, mu 0.5", 35 * M_PI / 180, 0.5),
        canon_roll(2.0),
        canon_slide_roll(2.0, 0.5),
        canon_spin(20.0, 0.5),
        canon_headon("head-on spheres", 0, 2.0, 0.5),
        canon_headon("head-on boxes", 1, 2.0, 0.5),
        canon_stack(8),
        canon_pyramid(4),
        canon_big_frame("ball at rest, frame 0.05 s", 0.05),
        canon_big_frame("ball at rest, frame 0.1 s", 0.1),
    };
    int n = (int)(sizeof all / sizeof all[0]);
    for (int i = 0; i < n && i < max; i++)
        out[i] = all[i];
    return n < max ? n : max;
}

/* ---- the judges ---------------------------------------------------------- */

/* The angle between two unit quaternions, degrees. */
static inline double canon_turn_deg(const double *q, const double *q0)
{
    double d = fabs(q[0] * q0[0] + q[1] * q0[1] + q[2] * q0[2] + q[3] * q0[3]);
    return 2 * acos(d < 1 ? d : 1) * 180 / M_PI;
}

/* Kinetic plus potential energy of the dynamic bodies at frame f (z = 0
 * at the floor), from the record: the same sum for every engine. */
static inline double canon_energy(const canon_scene *sc, const canon_traj *t, int f)
{
    double E = 0;
    int d = 0;
    for (int i = 0; i < sc->nb; i++) {
        const canon_body *b = &sc->b[i];
        if (!(b->mass > 0))
            continue;
        const double *s = canon_at(t, f, d++);
        double I = b->kind == CANON_SPHERE ? 0.4 * b->mass * b->size[0] * b->size[0]
                                           : b->mass * 4 * b->size[0] * b->size[0] / 6;
        double v2 = s[7] * s[7] + s[8] * s[8] + s[9] * s[9];
        double w2 = s[10] * s[10] + s[11] * s[11] + s[12] * s[12];
        E += 0.5 * b->mass * v2 + 0.5 * I * w2 + b->mass * sc->gravity * s[2];
    }
    return E;
}

static inline void canon_add(canon_fig *f, int *n, const char *name, double value,
                             double expect, double tol, int how)
{
    f[*n] = (canon_fig){ name, value, expect, tol, how };
    (*n)++;
}

static inline int canon_pass(const canon_fig *f)
{
    if (f->how == CANON_AT_MOST)
        return f->value <= f->expect + f->tol;
    return fabs(f->value - f->expect) <= f->tol;
}

/* The figures of a scene's record; returns their number. */
static inline int canon_judge(const canon_scene *sc, const canon_traj *t, canon_fig *f)
{
    int n = 0, F = t->frames;
    const canon_body *b = &sc->b[1];    /* the moving body of one-body scenes */
    const double *s0 = canon_at(t, 0, 0);
    double E0 = canon_energy(sc, t, 0), Epeak = E0, tilt = 0, drift = 0;
    for (int k = 0; k <= F; k++) {
        Epeak = fmax(Epeak, canon_energy(sc, t, k));
        for (int i = 0; i < t->nd; i++) {
            const double *s = canon_at(t, k, i), *a = canon_at(t, 0, i);
            tilt = fmax(tilt, canon_turn_deg(s + 3, a + 3));
            drift = fmax(drift, hypot(s[0] - a[0], s[1] - a[1]));
        }
    }
    switch (sc->family) {
    case CANON_F_DROP: {
        /* the first apex: the highest point after the first bounce, above
         * the start's resting height of the lowest point */
        double h = sc->p[0], e = sc->p[1], low = s0[2] - h, apex = -INFINITY;
        int bounced = 0;
        for (int k = 1; k <= F; k++) {
            const double *s = canon_at(t, k, 0), *p = canon_at(t, k - 1, 0);
            if (!bounced && p[9] < 0 && s[9] > 0)
                bounced = 1;
            if (bounced && s[9] < 0) {
                apex = fmax(apex, p[2] - low);
                break;
            }
            if (bounced)
                apex = fmax(apex, s[2] - low);
        }
        /* sampled at frames: the apex is missed by at most g dt^2 / 8 */
        canon_add(f, &n, "first apex / (e^2 h)", apex / (e * e * h), 1, 0.01, CANON_NEAR);
        if (b->kind == CANON_BOX)
            canon_add(f, &n, "largest turn, deg", tilt, 0, 0.01, CANON_AT_MOST);
        canon_add(f, &n, "largest drift, mm", 1e3 * drift, 0, 0.1, CANON_AT_MOST);
        canon_add(f, &n, "peak energy / start", Epeak / E0, 1, 1e-9, CANON_AT_MOST);
        break;
    }
    case CANON_F_SLIDE: {
        double v0 = sc->p[0], mu = sc->p[1];
        const double *e = canon_at(t, F, 0);
        /* a frame's trapezoid step overshoots the stop by under mu g dt^2 */
        canon_add(f, &n, "slide, m", e[0] - s0[0], v0 * v0 / (2 * mu * CANON_G),
                  0.01 * v0 * v0 / (2 * mu * CANON_G), CANON_NEAR);
        canon_add(f, &n, "speed at the end, m/s", hypot(e[7], e[8]), 0, 1e-3, CANON_AT_MOST);
        canon_add(f, &n, "largest turn, deg", tilt, 0, 0.01, CANON_AT_MOST);
        canon_add(f, &n, "sideways, mm", 1e3 * fabs(e[1] - s0[1]), 0, 0.1, CANON_AT_MOST);
        break;
    }
    case CANON_F_SLOPE: {
        double th = sc->p[0], mu = sc->p[1], T = F * sc->dt;
        const double *e = canon_at(t, F, 0);
        double along = -((e[0] - s0[0]) * cos(th) + (e[2] - s0[2]) * sin(th));  /* downhill */
        double a = CANON_G * (sin(th) - mu * cos(th));
        if (a <= 0)
            canon_add(f, &n, "slid downhill, mm", 1e3 * fabs(along), 0, 0.1, CANON_AT_MOST);
        else
            canon_add(f, &n, "slid downhill / (a T^2 / 2)", along / (0.5 * a * T * T), 1, 0.01,
                      CANON_NEAR);
        canon_add(f, &n, "largest turn, deg", tilt, 0, 0.01, CANON_AT_MOST);
        canon_add(f, &n, "sideways, mm", 1e3 * fabs(e[1] - s0[1]), 0, 0.1, CANON_AT_MOST);
        break;
    }
    case CANON_F_ROLL: {
        double v0 = sc->p[0];
        const double *e = canon_at(t, F, 0);
        canon_add(f, &n, "speed / v0 at the end", e[7] / v0, 1, 1e-3, CANON_NEAR);
        canon_add(f, &n, "spin r / v0 at the end", e[11] * b->size[0] / v0, 1, 1e-3, CANON_NEAR);
        double lift = 0;
        for (int k = 0; k <= F; k++)
            lift = fmax(lift, fabs(canon_at(t, k, 0)[2] - s0[2]));
        canon_add(f, &n, "off the floor, mm", 1e3 * lift, 0, 1.0, CANON_AT_MOST);
        break;
    }
    case CANON_F_SLIDE_ROLL: {
        double v0 = sc->p[0];
        const double *e = canon_at(t, F, 0);
        canon_add(f, &n, "speed / (5/7 v0) at the end", e[7] / (5.0 / 7 * v0), 1, 0.01,
                  CANON_NEAR);
        canon_add(f, &n, "slip at the end, m/s", fabs(e[7] - e[11] * b->size[0]), 0, 1e-3,
                  CANON_AT_MOST);
        break;
    }
    case CANON_F_SPIN: {
        double w0 = sc->p[0], mu = sc->p[1], rc = sc->p[2], a = b->size[0];
        double alpha = mu * CANON_G * rc / (4 * a * a / 6);
        const double *e = canon_at(t, F, 0);
        /* the turn from the start, about z (quaternion w, 0, 0, z) */
        double turn = 2 * atan2(e[6], e[3]);
        canon_add(f, &n, "turned / (w0^2 / 2 alpha)", turn / (w0 * w0 / (2 * alpha)), 1, 0.02,
                  CANON_NEAR);
        canon_add(f, &n, "spin at the end, rad/s", fabs(e[12]), 0, 1e-3, CANON_AT_MOST);
        canon_add(f, &n, "largest drift, mm", 1e3 * drift, 0, 0.1, CANON_AT_MOST);
        break;
    }
    case CANON_F_HEADON: {
        double v0 = sc->p[0], e = sc->p[1], spin = 0;
        const double *x = canon_at(t, F, 0), *y = canon_at(t, F, 1);
        for (int i = 0; i < 2; i++) {
            const double *s = canon_at(t, F, i);
            spin = fmax(spin, sqrt(s[10] * s[10] + s[11] * s[11] + s[12] * s[12]));
        }
        canon_add(f, &n, "first body after, m/s", x[7], (1 - e) * v0 / 2, 0.005 * v0, CANON_NEAR);
        canon_add(f, &n, "second body after, m/s", y[7], (1 + e) * v0 / 2, 0.005 * v0,
                  CANON_NEAR);
        canon_add(f, &n, "spin after, rad/s", spin, 0, 1e-6, CANON_AT_MOST);
        canon_add(f, &n, "peak energy / start", Epeak / E0, 1, 1e-9, CANON_AT_MOST);
        break;
    }
    case CANON_F_STAND: {
        double sink = 0, speed = 0, layers = 1;
        for (int i = 0, d = 0; i < sc->nb; i++) {
            if (!(sc->b[i].mass > 0))
                continue;
            const double *s = canon_at(t, F, d), *a = canon_at(t, 0, d++);
            sink = fmax(sink, fabs(s[2] - a[2]));
            speed = fmax(speed, sqrt(s[7] * s[7] + s[8] * s[8] + s[9] * s[9]));
            layers = fmax(layers, ceil(a[2] / (2 * sc->b[i].size[0])));
        }
        /* resting contacts sit up to the contact tolerance (1 mm) deep:
         * a layer each. A structure of many bodies stands when its drift
         * stays within that tolerance too (docs/DESIGN.md 10; its islands
         * are solved as blocks to a velocity tolerance, section 11), a
         * turn of 1 mm over a 0.2 m face; a single body within 0.1 mm */
        int many = t->nd > 1;
        canon_add(f, &n, "largest sink, mm", 1e3 * sink, 0, layers, CANON_AT_MOST);
        canon_add(f, &n, "largest drift, mm", 1e3 * drift, 0, many ? 1.0 : 0.1, CANON_AT_MOST);
        canon_add(f, &n, "largest turn, deg", tilt, 0, many ? atan(1e-3 / 0.2) * 180 / M_PI : 0.01,
                  CANON_AT_MOST);
        canon_add(f, &n, "speed at the end, m/s", speed, 0, 1e-3, CANON_AT_MOST);
        break;
    }
    }
    return n;
}

/* ---- simcluster ------------------------------------------------------------ */

static inline sc_shape *canon_sc_shape(const canon_body *b)
{
    switch (b->kind) {
    case CANON_PLANE: return sc_shape_plane(b->size[0], b->size[1], b->size[2], b->size[3]);
    case CANON_BOX: return sc_shape_box(b->size[0], b->size[1], b->size[2]);
    default: return sc_shape_sphere(b->size[0]);
    }
}

static inline void canon_sc_record(sc_world *w, const int *id, canon_traj *t, int f)
{
    for (int i = 0; i < t->nd; i++) {
        double *s = canon_at(t, f, i);
        sc_body_get_pose(w, id[i], s, s + 3);
        sc_body_get_velocity(w, id[i], s + 7, s + 10);
    }
}

/* The scene in a simcluster world (toi_mode, workers, island_method),
 * recorded into t (canon_traj_init first). 0, or the failed call's code
 * (also t->error). */
static inline int canon_run_sc_method(const canon_scene *sc, int toi_mode, int workers,
                                      int island_method, canon_traj *t)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.gravity[2] = -sc->gravity;
    cfg.toi_mode = toi_mode;
    cfg.workers = workers;
    cfg.island_method = island_method;
    sc_world *w = sc_world_create(&cfg);
    if (!w)
        return t->error = sc_last_error();
    int id[CANON_MAX_BODIES], nd = 0, rc = SC_OK;
    for (int i = 0; i < sc->nb && rc == SC_OK; i++) {
        const canon_body *b = &sc->b[i];
        sc_body_desc d = sc_body_desc_default();
        d.shape = canon_sc_shape(b);
        d.mass = b->mass;
        memcpy(d.pos, b->pos, sizeof d.pos);
        memcpy(d.quat, b->quat, sizeof d.quat);
        memcpy(d.vel, b->vel, sizeof d.vel);
        memcpy(d.omega, b->omega, sizeof d.omega);
        d.restitution = b->e;
        d.friction = b->mu;
        int r = d.shape ? sc_body_add(w, &d) : sc_last_error();
        sc_shape_release(d.shape);
        if (r < 0)
            rc = r;
        else if (b->mass > 0)
            id[nd++] = r;
    }
    if (rc == SC_OK)
        canon_sc_record(w, id, t, 0);
    for (int f = 1; rc == SC_OK && f <= t->frames; f++) {
        rc = sc_world_step(w, sc->dt);
        if (rc == SC_OK)
            canon_sc_record(w, id, t, f);
    }
    sc_world_destroy(w);
    return t->error = rc;
}

/* The same with the default island method. */
static inline int canon_run_sc(const canon_scene *sc, int toi_mode, int workers, canon_traj *t)
{
    return canon_run_sc_method(sc, toi_mode, workers, sc_world_config_default().island_method, t);
}

#endif /* SC_CANON_H */
