/* bench_drop.c - the bolt/nut drop of the paper's Figs 3-4, and the dense
 * parts bin, side by side with ODE (docs/DESIGN.md section 10): the same
 * scene simulated by
 *   quick  ODE dWorldQuickStep, 20 iterations
 *   step   ODE dWorldStep (its Dantzig-type LCP)
 *   sc1    simcluster, sc_world_step with toi_mode = SC_TOI_WORLD (the paper's
 *          world-wide back-up), workers = 1
 *   scN    the same with workers = every online CPU (the embedded default)
 *   sl1    simcluster with toi_mode = SC_TOI_LOCAL (speculative contacts,
 *          local back-ups; docs/DESIGN.md 3.4), workers = 1
 *   slN    the same with workers = every online CPU: the library's default
 *          world (local mode, embedded workers)
 *   quickAD ODE dWorldQuickStep with ODE's auto-disable on (its default
 *          thresholds: a body still for 10 steps under 0.01 linear and
 *          angular is disabled; pairs whose bodies are all disabled or
 *          static are not collided, as ODE's demos do): ODE's own sleep,
 *          the peer to compare with ours, which sleeps too
 * at 100 Hz for up to 10 s of simulated time (-T), stopping early when
 * every body is at rest (unless -F: a full run to -T, the rest time still
 * recorded as the start of the last rest that held to the end), or when a
 * run's wall time passes the budget (-b,
 * default 30 s). The budget bounds the default run: a 1000-body drop
 * takes minutes of wall per run, so it is cut short and says "not at rest
 * within the cap".
 *
 * The scenes (-S):
 *   drop  (default) sc_scene_bolts_nuts(N, seed): N bolts and nuts at
 *         random free poses in a column above a floor (the static half
 *         space z <= 0), falling onto it: sparse, most islands small.
 *   bin   sc_scene_bin(N, seed), the dense pile: N parts (body i a bolt
 *         if i is even, a nut if odd) in BIN_LAYERS = 4 layers of
 *         ceil(N / 4) on a k x k grid, k = ceil(sqrt(ceil(N / 4))), at a
 *         pitch of 1.02 bounding diameters of the larger part (the nut or
 *         the bolt, whichever bound is larger), centred on the z axis;
 *         layer L at height (1.02 + 2.04 L) bounding radii; uniformly
 *         random orientations from the seed, at rest. Five static half
 *         spaces: the floor z <= 0 and the walls x <= -h, x >= h,
 *         y <= -h, y >= h with h = k pitch / 2 (the grid fits them
 *         exactly). The parts fall a few cm onto the floor and each other
 *         and pile up, every part touching several others.
 *   Both: steel (7800 kg/m^3), e = 0.8, mu = 0.5 for every body, static
 *   ones included. The header prints the walls as read from the world.
 *
 * Same scene for all engines: the poses and velocities are read back from a
 * world filled by the scene's function (sc_body_get_pose/velocity), and so
 * are its static bodies: each is given to ODE as what it is in the world,
 * a half space n.x <= d as dCreatePlane(n, d) (the same convention: the
 * solid is n.x < d) and a box as a dCreateBox at its pose (the shape's
 * own fields, read through lib/core/core.h: this bench is at the core
 * layer for that only; other static shapes are refused). ODE gets the same
 * meshes (sc_shape_mesh_data of sc_shape_bolt/nut, each body's checked to
 * be the same bits as one of them, as trimesh geoms in a dHashSpace with
 * its default levels) and the same masses and inertia
 * (sc_shape_mass_props times the steel density 7800).
 * ODE contacts: at most 4 per pair (dCollide's limit), a contact joint each
 * with mode dContactBounce | dContactApprox1, mu 0.5, bounce 0.8, bounce_vel
 * 0.1 m/s (below it a contact does not bounce; ODE demos use this value),
 * no soft ERP/CFM (the world defaults: ERP 0.2, CFM 1e-10 in double),
 * no auto-disable, gravity -9.81.
 * dGeomTriMeshSetLastTransform is set to each geom's pose after every
 * collision pass (the trimesh-trimesh collider's temporal coherence).
 *
 * Measured per run: wall time of the stepping loop (collision + step for
 * ODE, sc_world_step for simcluster; setup excluded), the simulated time
 * reached, real-time factor = simulated / wall, peak total energy over
 * initial (kinetic + gravitational potential with z = 0 at the floor; our
 * own sum for ODE, sc_world_energy for simcluster), the deepest penetration
 * seen (ODE: deepest contact depth of any frame; simcluster: the largest
 * sc_stats.frame.detect.max_penetration of any frame) and the time at which all bodies
 * came to rest (every body below 1 cm/s and 0.1 rad/s, and staying so for
 * REST_HOLD_S; the run stops then). A run stops as "exploded" when the
 * state has a NaN or the energy passes 100 x the initial; as "budget" when
 * its wall time passes the budget (-b); a step that returns an error stops
 * it too, reported as "step error" with the code and the simulated time at
 * the end of the failed frame. Each run happens in a forked child, so that
 * an abort or crash inside a peer is reported (as its signal) instead of
 * ending the benchmark. Nothing is special-cased: each engine is measured
 * as it is.
 *
 * For simcluster a second line under its row gives the contact solver's
 * figures over the run (sc_stats, per frame, summed or maxed over every
 * frame stepped without error): island solves, of them split (block
 * Gauss-Seidel), those of them short of the tolerance tried as one exact
 * LCP and solved so, unconverged (stopped at the sweep limit) and diverged
 * (stopped on a sweep that left the residual far above its best), the most
 * sweeps, the largest outer residual of a split solve and of an exact one,
 * the fallbacks (coupled friction LCP failed: staggered; staggered failed:
 * blocks; block failed: projected Gauss-Seidel; non-finite islands;
 * regularised solves), the mean substeps and back-ups a frame and the
 * speculative contacts entered.
 *
 * Each cell is the median of R runs (-r) by real-time factor; the run with
 * the median is reported whole. The physics of a run does not depend on
 * timing, so only the times differ between runs. Without -r a cell gets 3
 * runs, or 1 when its first run is cut by the wall budget (repeating it
 * would triple the cost of the largest cells; the "runs" column says how
 * many were made); with -r R every cell gets exactly R. The runs go round
 * the engines in turn (quick, sl1, slN, quick, ...), so that a slow spell
 * of the shared machine falls on every engine of a ratio alike: made a
 * cell after another (all runs of QuickStep, then all of ours), a ratio
 * such as the drop's slN over quick swings with the machine's load.
 *
 * Ratios, ours (sc1, scN) over each peer (quick, step) and scN over sc1,
 * follow each body count. Runs cut by the wall budget reach different
 * simulated times, and free fall is cheaper than landing, so the ratio of
 * real-time factors is taken over the span both runs simulated (the wall
 * time of each at that frame; each run keeps its cumulative wall time at
 * up to NMARK evenly spaced frames). Where a peer exploded, crashed or
 * failed, the line says so instead of giving ratios.
 *
 * usage: bench_drop [-S drop|bin] [-r runs] [-T sim_seconds] [-F]
 *                   [-b wall_budget_s] [-s seed] [-e engines] [N ...]
 *   engines: any of q (quick), a (quickAD), s (step), 1 (sc1), n (scN),
 *   l (sl1), L (slN), c (= 1n);
 *   default qsc.  N: body counts (1..100000), default 10 50 200 1000
 *   (drop) or 50 200 (bin) */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <ode/ode.h>

#include "simcluster.h"
/* struct sc_shape: the static bodies' planes and boxes (see the top) */
#include "core.h"

#include "bench_util.h"

#define DT 0.01
#define G 9.81
#define STEEL 7800.0
#define MAX_PAIR_CONTACTS 4
#define QUICK_ITERS 20
#define MU 0.5
#define BOUNCE 0.8
#define BOUNCE_VEL 0.1
#define REST_V 0.01              /* m/s */
#define REST_W 0.1               /* rad/s */
#define REST_HOLD_S 0.5          /* at rest this long before we believe it */
#define EXPLODE_FACTOR 100.0
#define MAX_RUNS 15
#define NMARK 500                /* wall-time marks kept per run */
#define MAX_STATIC 64            /* static bodies a scene may have */

enum { SCENE_DROP, SCENE_BIN };
static int scene_kind = SCENE_DROP;

enum { ENG_QUICK, ENG_QAD, ENG_STEP, ENG_SC1, ENG_SCN, ENG_SL1, ENG_SLN, ENG_COUNT };
static const char *eng_name[ENG_COUNT] = { "quick", "quickAD", "step", "sc1", "scN", "sl1", "slN" };
static const char eng_key[ENG_COUNT] = { 'q', 'a', 's', '1', 'n', 'l', 'L' };
static int eng_threads[ENG_COUNT] = { 1, 1, 1, 1, 1, 1, 1 };   /* scN's, slN's set in main */
/* ours: sc1, scN (world mode), sl1 and slN (the local time-of-impact mode) */
static int is_ours(int eng)
{
    return eng == ENG_SC1 || eng == ENG_SCN || eng == ENG_SL1 || eng == ENG_SLN;
}

enum { END_TIME, END_REST, END_EXPLODED, END_BUDGET, END_ERROR, END_CRASH };

typedef struct result {
    int end;                     /* END_* */
    int code;                    /* sc error code, or signal / exit status */
    double wall_s, sim_s;
    double e0, epeak;
    double max_pen;
    double rest_s;               /* -1: not at rest */
    double vmax, wmax;           /* fastest body at the last frame, m/s and rad/s */
    /* simcluster's contact solver over the run (sc_stats, every frame) */
    long frames;                 /* frames stepped without error */
    long solves, split, blocks, shared, unconverged, substeps, backups, spec, refused, rscaled;
    long whole_tries, whole_solved, diverged, sweeps;
    long fallbacks, split_fallbacks, block_fallbacks, nan_islands, regularised;
    int sweeps_max;
    double outer_res, exact_res; /* largest of any frame, m/s */
    int nmark;                   /* marks kept: frames stride, 2 stride, ... */
    double mark_wall[NMARK];     /* cumulative wall time at frame (k + 1) * stride */
} result;

/* What both ODE and simcluster start from. */
typedef struct piece {
    const double *xyz;
    const int *tri;
    int nverts, ntris;
    double mass, inertia[9], com[3];
} piece;

/* A static body of the scene, as the world has it. */
typedef struct wall {
    int kind;                    /* SC_SHAPE_PLANE or SC_SHAPE_BOX */
    double plane[4];             /* plane: the half space n.x <= d, n unit */
    double half[3];              /* box: half extents */
    double pos[3], quat[4];      /* box: pose */
} wall;

typedef struct scene {
    int n;
    uint64_t seed;
    piece kind[2];               /* bolt, nut */
    int *body_kind;              /* 0 bolt, 1 nut, per dynamic body */
    double *pos, *quat, *vel, *omega;   /* of the shape origins, from the world */
    int nwalls;
    wall walls[MAX_STATIC];
} scene;

static double sim_limit_s = 10.0;
static double budget_s = 30.0;
static long mark_stride = 1;     /* frames between marks, set in main */
static int full_run = 0;         /* -F: run to sim_limit_s whatever rests */

/* ---- the scene, read back from simcluster ---- */

static int piece_init(piece *p, const sc_shape *s)
{
    sc_mass_props mp;
    if (sc_shape_mesh_data(s, &p->xyz, &p->nverts, &p->tri, &p->ntris) != SC_OK ||
        sc_shape_mass_props(s, &mp) != SC_OK)
        return -1;
    p->mass = STEEL * mp.volume;
    for (int k = 0; k < 9; k++)
        p->inertia[k] = STEEL * mp.inertia[k];
    memcpy(p->com, mp.com, sizeof p->com);
    return 0;
}

/* The scene's function (-S) into w. */
static int scene_add(sc_world *w, int n, uint64_t seed)
{
    return scene_kind == SCENE_BIN ? sc_scene_bin(w, n, seed) : sc_scene_bolts_nuts(w, n, seed);
}

/* 1 when mesh s has exactly the vertices and triangles of p. */
static int same_mesh(const sc_shape *s, const piece *p)
{
    const double *xyz;
    const int *tri;
    int nv, nt;
    if (sc_shape_mesh_data(s, &xyz, &nv, &tri, &nt) != SC_OK || nv != p->nverts ||
        nt != p->ntris)
        return 0;
    return memcmp(xyz, p->xyz, (size_t)nv * 3 * sizeof *xyz) == 0 &&
           memcmp(tri, p->tri, (size_t)nt * 3 * sizeof *tri) == 0;
}

/* A static body of the world as a wall; -1 for a shape ODE is not given. */
static int wall_init(wall *wl, const sc_world *w, int id)
{
    const sc_shape *s = sc_body_shape(w, id);
    memset(wl, 0, sizeof *wl);
    wl->kind = sc_shape_kind(s);
    if (wl->kind == SC_SHAPE_PLANE) {
        memcpy(wl->plane, s->plane, sizeof wl->plane);
    } else if (wl->kind == SC_SHAPE_BOX) {
        memcpy(wl->half, s->half, sizeof wl->half);
        sc_body_get_pose(w, id, wl->pos, wl->quat);
    } else {
        fprintf(stderr, "static body %d: shape kind %d is not given to ODE here\n", id,
                wl->kind);
        return -1;
    }
    return 0;
}

static int scene_init(scene *sc, int n, uint64_t seed, sc_shape *bolt, sc_shape *nut)
{
    sc->n = n;
    sc->seed = seed;
    if (piece_init(&sc->kind[0], bolt) || piece_init(&sc->kind[1], nut))
        return -1;
    sc_world *w = sc_world_create(NULL);
    if (!w)
        return -1;
    int rc = scene_add(w, n, seed);
    if (rc != SC_OK) {
        fprintf(stderr, "sc_scene_%s(%d): %s\n", scene_kind == SCENE_BIN ? "bin" : "bolts_nuts",
                n, sc_strerror(rc));
        sc_world_destroy(w);
        return -1;
    }
    sc->pos = malloc((size_t)n * 3 * sizeof *sc->pos);
    sc->quat = malloc((size_t)n * 4 * sizeof *sc->quat);
    sc->vel = malloc((size_t)n * 3 * sizeof *sc->vel);
    sc->omega = malloc((size_t)n * 3 * sizeof *sc->omega);
    sc->body_kind = malloc((size_t)n * sizeof *sc->body_kind);
    if (!sc->pos || !sc->quat || !sc->vel || !sc->omega || !sc->body_kind) {
        sc_world_destroy(w);
        return -1;
    }
    /* every body in id order: static ones are walls, the others parts */
    int nb = sc_world_body_count(w), i = 0;
    rc = 0;
    for (int id = 0; id < nb && rc == 0; id++) {
        if (sc_body_state(w, id) == SC_STATIC) {
            if (sc->nwalls == MAX_STATIC) {
                fprintf(stderr, "more than %d static bodies\n", MAX_STATIC);
                rc = -1;
            } else {
                rc = wall_init(&sc->walls[sc->nwalls++], w, id);
            }
            continue;
        }
        const sc_shape *s = sc_body_shape(w, id);
        int k = same_mesh(s, &sc->kind[0]) ? 0 : same_mesh(s, &sc->kind[1]) ? 1 : -1;
        if (k < 0 || i == n) {
            fprintf(stderr, "body %d: not one of the %d bolts and nuts\n", id, n);
            rc = -1;
            break;
        }
        sc->body_kind[i] = k;
        sc_body_get_pose(w, id, &sc->pos[3 * i], &sc->quat[4 * i]);
        sc_body_get_velocity(w, id, &sc->vel[3 * i], &sc->omega[3 * i]);
        i++;
    }
    if (rc == 0 && i != n) {
        fprintf(stderr, "the scene has %d parts, not %d\n", i, n);
        rc = -1;
    }
    sc_world_destroy(w);
    return rc;
}

static void scene_free(scene *sc)
{
    free(sc->body_kind);
    free(sc->pos);
    free(sc->quat);
    free(sc->vel);
    free(sc->omega);
}

/* ---- rest detection and the stopping rules, common to all engines ---- */

typedef struct watch {
    double e0, epeak, max_pen;
    double rest_since;           /* -1 while some body moves */
} watch;

/* Folds body velocity v, omega w into the frame's fastest speeds r->vmax,
 * r->wmax; returns 1 if this body is at rest. */
static int body_at_rest(const double v[3], const double w[3], result *r)
{
    double v2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    double w2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    r->vmax = fmax(r->vmax, sqrt(v2));
    r->wmax = fmax(r->wmax, sqrt(w2));
    return v2 < REST_V * REST_V && w2 < REST_W * REST_W;
}

/* After the frame ending at t: fold in energy e and penetration pen and
 * the rest flag; returns END_* if the run should stop, -1 to go on. */
static int watch_frame(watch *wt, double t, double e, double pen, int all_rest, result *r)
{
    wt->max_pen = fmax(wt->max_pen, pen);
    if (!isfinite(e) || e > EXPLODE_FACTOR * fabs(wt->e0)) {
        wt->epeak = isfinite(e) ? fmax(wt->epeak, e) : e;
        return END_EXPLODED;
    }
    wt->epeak = fmax(wt->epeak, e);
    if (!all_rest) {
        wt->rest_since = -1;
        r->rest_s = -1;           /* a full run: that rest did not last */
    } else {
        if (wt->rest_since < 0)
            wt->rest_since = t;
        if (t - wt->rest_since >= REST_HOLD_S - 1e-9) {
            r->rest_s = wt->rest_since;
            if (!full_run)
                return END_REST;
        }
    }
    return t >= sim_limit_s - 1e-9 ? END_TIME : -1;
}

/* Keeps the cumulative wall time at every mark_stride-th frame. */
static void mark_frame(result *r, long frame, double wall)
{
    if (frame % mark_stride == 0 && r->nmark < NMARK)
        r->mark_wall[r->nmark++] = wall;
}

/* ---- ODE ---- */

typedef struct ode_sim {
    dWorldID world;
    dSpaceID space;
    dJointGroupID contacts;
    dTriMeshDataID data[2];
    dTriIndex *index[2];
    double *verts[2];
    dBodyID *body;
    dGeomID *geom;
    int *kind;
    double max_depth;            /* this frame */
} ode_sim;

static void near_callback(void *ctx, dGeomID o1, dGeomID o2)
{
    ode_sim *s = ctx;
    dBodyID b1 = dGeomGetBody(o1), b2 = dGeomGetBody(o2);
    if (!b1 && !b2)
        return;
    /* auto-disable (quickAD): nothing to do between sleepers and walls */
    if ((!b1 || !dBodyIsEnabled(b1)) && (!b2 || !dBodyIsEnabled(b2)))
        return;
    dContact c[MAX_PAIR_CONTACTS];
    memset(c, 0, sizeof c);
    int n = dCollide(o1, o2, MAX_PAIR_CONTACTS, &c[0].geom, sizeof c[0]);
    for (int i = 0; i < n; i++) {
        c[i].surface.mode = dContactBounce | dContactApprox1;
        c[i].surface.mu = MU;
        c[i].surface.bounce = BOUNCE;
        c[i].surface.bounce_vel = BOUNCE_VEL;
        s->max_depth = fmax(s->max_depth, c[i].geom.depth);
        dJointID j = dJointCreateContact(s->world, s->contacts, &c[i]);
        dJointAttach(j, b1, b2);
    }
}

static void set_last_transform(dGeomID g)
{
    const dReal *R = dGeomGetRotation(g), *p = dGeomGetPosition(g);
    dMatrix4 m = { R[0], R[4], R[8], 0, R[1], R[5], R[9], 0,
                   R[2], R[6], R[10], 0, p[0], p[1], p[2], 1 };
    dGeomTriMeshSetLastTransform(g, m);
}

static int ode_build(ode_sim *s, const scene *sc, int auto_disable)
{
    memset(s, 0, sizeof *s);
    s->world = dWorldCreate();
    dWorldSetAutoDisableFlag(s->world, auto_disable);   /* ODE's default thresholds */
    dWorldSetGravity(s->world, 0, 0, -G);
    dWorldSetQuickStepNumIterations(s->world, QUICK_ITERS);
    s->space = dHashSpaceCreate(0);
    s->contacts = dJointGroupCreate(0);
    /* the world's static bodies: geoms without a body */
    for (int i = 0; i < sc->nwalls; i++) {
        const wall *wl = &sc->walls[i];
        if (wl->kind == SC_SHAPE_PLANE) {
            dCreatePlane(s->space, wl->plane[0], wl->plane[1], wl->plane[2], wl->plane[3]);
        } else {
            dGeomID g = dCreateBox(s->space, 2 * wl->half[0], 2 * wl->half[1], 2 * wl->half[2]);
            dQuaternion dq = { wl->quat[0], wl->quat[1], wl->quat[2], wl->quat[3] };
            dGeomSetPosition(g, wl->pos[0], wl->pos[1], wl->pos[2]);
            dGeomSetQuaternion(g, dq);
        }
    }
    for (int k = 0; k < 2; k++) {
        const piece *p = &sc->kind[k];
        /* ODE wants the centre of mass at the body origin */
        s->verts[k] = malloc((size_t)p->nverts * 3 * sizeof *s->verts[k]);
        s->index[k] = malloc((size_t)p->ntris * 3 * sizeof *s->index[k]);
        if (!s->verts[k] || !s->index[k])
            return -1;
        for (int i = 0; i < 3 * p->nverts; i++)
            s->verts[k][i] = p->xyz[i] - p->com[i % 3];
        for (int i = 0; i < 3 * p->ntris; i++)
            s->index[k][i] = (dTriIndex)p->tri[i];
        s->data[k] = dGeomTriMeshDataCreate();
        dGeomTriMeshDataBuildDouble(s->data[k], s->verts[k], 3 * sizeof(double), p->nverts,
                                    s->index[k], 3 * p->ntris, 3 * sizeof(dTriIndex));
    }
    int n = sc->n;
    s->body = calloc((size_t)n, sizeof *s->body);
    s->geom = calloc((size_t)n, sizeof *s->geom);
    s->kind = calloc((size_t)n, sizeof *s->kind);
    if (!s->body || !s->geom || !s->kind)
        return -1;
    for (int i = 0; i < n; i++) {
        const piece *p = &sc->kind[sc->body_kind[i]];
        const double *q = &sc->quat[4 * i], *I = p->inertia;
        s->kind[i] = sc->body_kind[i];
        dBodyID b = dBodyCreate(s->world);
        dMass m;
        dMassSetParameters(&m, p->mass, 0, 0, 0, I[0], I[4], I[8], I[1], I[2], I[5]);
        dBodySetMass(b, &m);
        dQuaternion dq = { q[0], q[1], q[2], q[3] };
        dBodySetQuaternion(b, dq);
        /* the body origin is the centre of mass: shape origin + R com */
        const dReal *R = dBodyGetRotation(b);
        double rc[3], wxr[3];
        for (int k = 0; k < 3; k++)
            rc[k] = R[4 * k] * p->com[0] + R[4 * k + 1] * p->com[1] + R[4 * k + 2] * p->com[2];
        const double *x = &sc->pos[3 * i], *v = &sc->vel[3 * i], *w = &sc->omega[3 * i];
        wxr[0] = w[1] * rc[2] - w[2] * rc[1];
        wxr[1] = w[2] * rc[0] - w[0] * rc[2];
        wxr[2] = w[0] * rc[1] - w[1] * rc[0];
        dBodySetPosition(b, x[0] + rc[0], x[1] + rc[1], x[2] + rc[2]);
        dBodySetLinearVel(b, v[0] + wxr[0], v[1] + wxr[1], v[2] + wxr[2]);
        dBodySetAngularVel(b, w[0], w[1], w[2]);
        dGeomID g = dCreateTriMesh(s->space, s->data[s->kind[i]], NULL, NULL, NULL);
        dGeomSetBody(g, b);
        set_last_transform(g);
        s->body[i] = b;
        s->geom[i] = g;
    }
    return 0;
}

/* Kinetic + potential energy (z = 0 at the floor); NaN if any state is. */
static double ode_energy(const ode_sim *s, const scene *sc, int *all_rest, result *r)
{
    double e = 0;
    int rest = 1;
    r->vmax = r->wmax = 0;
    for (int i = 0; i < sc->n; i++) {
        const piece *p = &sc->kind[s->kind[i]];
        const dReal *x = dBodyGetPosition(s->body[i]), *v = dBodyGetLinearVel(s->body[i]);
        const dReal *w = dBodyGetAngularVel(s->body[i]), *R = dBodyGetRotation(s->body[i]);
        double wb[3], Iw[3];
        for (int k = 0; k < 3; k++)       /* body frame: R^T w (R is 3x4 row-major) */
            wb[k] = R[k] * w[0] + R[4 + k] * w[1] + R[8 + k] * w[2];
        for (int k = 0; k < 3; k++)
            Iw[k] = p->inertia[3 * k] * wb[0] + p->inertia[3 * k + 1] * wb[1] +
                    p->inertia[3 * k + 2] * wb[2];
        e += 0.5 * p->mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) +
             0.5 * (wb[0] * Iw[0] + wb[1] * Iw[1] + wb[2] * Iw[2]) + p->mass * G * x[2];
        double vv[3] = { v[0], v[1], v[2] }, ww[3] = { w[0], w[1], w[2] };
        rest &= body_at_rest(vv, ww, r);
    }
    *all_rest = rest;
    return e;
}

static void ode_free(ode_sim *s)
{
    if (s->contacts)
        dJointGroupDestroy(s->contacts);
    if (s->space)
        dSpaceDestroy(s->space);          /* destroys its geoms */
    if (s->world)
        dWorldDestroy(s->world);
    for (int k = 0; k < 2; k++) {
        if (s->data[k])
            dGeomTriMeshDataDestroy(s->data[k]);
        free(s->verts[k]);
        free(s->index[k]);
    }
    free(s->body);
    free(s->geom);
    free(s->kind);
}

static void run_ode(const scene *sc, int quick, int auto_disable, result *r)
{
    ode_sim s;
    dRandSetSeed(0);                      /* QuickStep's row shuffling */
    if (ode_build(&s, sc, auto_disable) != 0) {
        r->end = END_ERROR;
        r->code = -1;
        ode_free(&s);
        return;
    }
    int rest;
    watch wt = { .e0 = ode_energy(&s, sc, &rest, r), .rest_since = -1 };
    wt.epeak = wt.e0;
    r->e0 = wt.e0;
    double wall = 0;
    long frame = 0;
    int end = -1;
    while (end < 0) {
        double t0 = now_s();
        s.max_depth = 0;
        dSpaceCollide(s.space, &s, near_callback);
        int ok = quick ? dWorldQuickStep(s.world, DT) : dWorldStep(s.world, DT);
        dJointGroupEmpty(s.contacts);
        for (int i = 0; i < sc->n; i++)
            set_last_transform(s.geom[i]);
        wall += now_s() - t0;
        frame++;
        mark_frame(r, frame, wall);
        double e = ode_energy(&s, sc, &rest, r);
        end = watch_frame(&wt, frame * DT, e, s.max_depth, rest, r);
        if (end < 0 && !ok) {
            end = END_ERROR;              /* ODE ran out of memory */
            r->code = 0;
        }
        if (end < 0 && wall > budget_s)
            end = END_BUDGET;
    }
    r->end = end;
    r->wall_s = wall;
    r->sim_s = frame * DT;
    r->epeak = wt.epeak;
    r->max_pen = wt.max_pen;
    ode_free(&s);
}

/* ---- simcluster ---- */

/* One frame's contact solver figures into the run's. */
static void solver_add(result *r, const sc_stats *st)
{
    r->frames++;
    r->solves += st->frame.lcp.solves;
    r->split += st->frame.lcp.split;
    r->blocks += st->frame.lcp.blocks;
    r->shared += st->frame.lcp.blocks_shared;
    r->unconverged += st->frame.lcp.unconverged;
    r->whole_tries += st->frame.lcp.whole_tries;
    r->whole_solved += st->frame.lcp.whole_solved;
    r->diverged += st->frame.lcp.diverged;
    r->substeps += st->frame.toi.substeps;
    r->backups += st->frame.toi.backups;
    r->spec += st->frame.toi.spec_contacts;
    r->fallbacks += st->frame.lcp.fallbacks;
    r->refused += st->frame.lcp.energy_refused;
    r->rscaled += st->frame.lcp.restitution_scaled;
    r->split_fallbacks += st->frame.lcp.split_fallbacks;
    r->block_fallbacks += st->frame.lcp.block_fallbacks;
    r->nan_islands += st->frame.lcp.nan_islands;
    r->regularised += st->frame.lcp.regularised;
    if (st->frame.lcp.sweeps_max > r->sweeps_max)
        r->sweeps_max = st->frame.lcp.sweeps_max;
    r->sweeps += st->frame.lcp.sweeps;
    r->outer_res = fmax(r->outer_res, st->frame.lcp.outer_residual);
    r->exact_res = fmax(r->exact_res, st->frame.lcp.residual);
}

static void run_sc(const scene *sc, int workers, int toi_mode, result *r)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = workers;
    cfg.toi_mode = toi_mode;
    sc_world *w = sc_world_create(&cfg);
    int rc = w ? scene_add(w, sc->n, sc->seed) : sc_last_error();
    if (rc != SC_OK) {
        r->end = END_ERROR;
        r->code = rc;
        sc_world_destroy(w);
        return;
    }
    watch wt = { .e0 = sc_world_energy(w), .rest_since = -1 };
    wt.epeak = wt.e0;
    r->e0 = wt.e0;
    double wall = 0;
    long frame = 0;
    int end = -1;
    while (end < 0) {
        double t0 = now_s();
        rc = sc_world_step(w, DT);
        wall += now_s() - t0;
        frame++;
        mark_frame(r, frame, wall);
        if (rc != SC_OK) {
            end = END_ERROR;
            r->code = rc;
            break;
        }
        sc_stats st;
        sc_world_stats(w, &st);
        solver_add(r, &st);
        int rest = 1;
        r->vmax = r->wmax = 0;
        for (int i = 1; i <= sc->n; i++) {
            double v[3], om[3];
            sc_body_get_velocity(w, i, v, om);
            rest &= body_at_rest(v, om, r);
        }
        end = watch_frame(&wt, frame * DT, sc_world_energy(w), st.frame.detect.max_penetration,
                          rest, r);
        if (end < 0 && wall > budget_s)
            end = END_BUDGET;
    }
    r->end = end;
    r->wall_s = wall;
    r->sim_s = frame * DT;
    r->epeak = wt.epeak;
    r->max_pen = wt.max_pen;
    sc_world_destroy(w);
}

/* ---- one run in a child process ---- */

static void run_child(const scene *sc, int eng, result *r)
{
    memset(r, 0, sizeof *r);
    r->rest_s = -1;
    int fd[2];
    if (pipe(fd) != 0) {
        perror("pipe");
        exit(1);
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        perror("fork");
        exit(1);
    }
    if (pid == 0) {
        close(fd[0]);
        /* a single step far beyond the budget is killed */
        alarm((unsigned)(budget_s + 300));
        if (is_ours(eng))
            run_sc(sc, eng_threads[eng],
                   eng == ENG_SL1 || eng == ENG_SLN ? SC_TOI_LOCAL : SC_TOI_WORLD, r);
        else
            run_ode(sc, eng != ENG_STEP, eng == ENG_QAD, r);
        ssize_t k = write(fd[1], r, sizeof *r);
        _exit(k == (ssize_t)sizeof *r ? 0 : 1);
    }
    close(fd[1]);
    result got;
    size_t have = 0;
    while (have < sizeof got) {
        ssize_t k = read(fd[0], (char *)&got + have, sizeof got - have);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            break;
        have += (size_t)k;
    }
    close(fd[0]);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    if (have == sizeof got && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
        *r = got;
    } else {
        r->end = END_CRASH;
        r->code = WIFSIGNALED(status) ? WTERMSIG(status) : -WEXITSTATUS(status);
    }
}

/* ---- the table ---- */

static double rtf(const result *r)
{
    return r->wall_s > 0 ? r->sim_s / r->wall_s : 0;
}

static int cmp_rtf(const void *a, const void *b)
{
    double x = rtf(a), y = rtf(b);
    return (x > y) - (x < y);
}

static void describe_end(const result *r, char *buf, size_t len)
{
    switch (r->end) {
    case END_TIME:
        if (r->rest_s >= 0)
            snprintf(buf, len, "ran %.1f s (-F), at rest from %.2f s", r->sim_s, r->rest_s);
        else
            snprintf(buf, len, "ran %.1f s: not at rest within the cap", r->sim_s);
        break;
    case END_REST: snprintf(buf, len, "at rest"); break;
    case END_EXPLODED: snprintf(buf, len, "exploded at t = %.2f s", r->sim_s); break;
    case END_BUDGET:
        snprintf(buf, len, "wall budget hit at t = %.2f s: not at rest within the cap", r->sim_s);
        break;
    case END_ERROR: snprintf(buf, len, "step error %d (%s) at t = %.2f s", r->code,
                             r->code < 0 ? sc_strerror(r->code) : "ODE", r->sim_s); break;
    default:
        if (r->code > 0)
            snprintf(buf, len, "child died: signal %d (%s)", r->code, strsignal(r->code));
        else
            snprintf(buf, len, "child exited %d", -r->code);
    }
}

static void print_row(int n, int eng, int runs, const result *r)
{
    char end[128], rest[32];
    describe_end(r, end, sizeof end);
    if (r->end == END_CRASH) {
        printf("%6d  %-7s %3d %4d  %9s %8s %9s %9s %10s %9s %10s  %s\n", n, eng_name[eng],
               eng_threads[eng], runs, "-", "-", "-", "-", "-", "-", "-", end);
        return;
    }
    if (r->rest_s >= 0)
        snprintf(rest, sizeof rest, "%.2f", r->rest_s);
    else
        snprintf(rest, sizeof rest, "none");
    printf("%6d  %-7s %3d %4d  %9.3f %8.2f %9.3f %9.4f %10.4g %9s %10.3g  %s\n", n,
           eng_name[eng], eng_threads[eng], runs, r->wall_s, r->sim_s, rtf(r), r->epeak / r->e0,
           r->max_pen, rest, r->vmax, end);
}

/* simcluster's solver line under its row (see the top); $2 is never an
 * engine name, so scripts that read the rows by engine skip it. */
static void print_solver(int eng, const result *r)
{
    if (!is_ours(eng))
        return;
    if (r->frames == 0) {
        printf("        %s solver: no frame stepped\n", eng_name[eng]);
        return;
    }
    printf("        %s solver: %ld frames, %ld island solves, %ld split (%.1f %%), "
           "%ld block solves (%ld by helping threads), solved whole %ld of %ld tried, "
           "%ld unconverged, %ld diverged, sweeps %.2f a split solve (most %d), "
           "outer residual max %.3g m/s, exact residual max %.3g m/s; fallbacks: staggered "
           "%ld (%ld refused for adding energy), blocks %ld, block PGS %ld, NaN islands %ld, "
           "regularised %ld, restitution scaled down %ld; substeps %.3f a frame, back-ups "
           "%.3f a frame (summed over motion groups), speculative contacts %ld\n",
           eng_name[eng], r->frames, r->solves, r->split,
           r->solves ? 100.0 * (double)r->split / (double)r->solves : 0.0, r->blocks, r->shared,
           r->whole_solved, r->whole_tries, r->unconverged, r->diverged,
           r->split ? (double)r->sweeps / (double)r->split : 0.0, r->sweeps_max, r->outer_res,
           r->exact_res, r->fallbacks, r->refused, r->split_fallbacks,
           r->block_fallbacks, r->nan_islands, r->regularised, r->rscaled,
           (double)r->substeps / (double)r->frames, (double)r->backups / (double)r->frames,
           r->spec);
}

/* Real-time factors of a and b over the frames both simulated (a multiple
 * of mark_stride): 0 and *span_s = 0 when they share no mark. */
static int common_rtf(const result *a, const result *b, double *span_s, double *ra, double *rb)
{
    int k = a->nmark < b->nmark ? a->nmark : b->nmark;
    *span_s = 0;
    if (k < 1 || !(a->mark_wall[k - 1] > 0) || !(b->mark_wall[k - 1] > 0))
        return 0;
    *span_s = (double)k * (double)mark_stride * DT;
    *ra = *span_s / a->mark_wall[k - 1];
    *rb = *span_s / b->mark_wall[k - 1];
    return 1;
}

/* Why a run gives no ratios (exploded, crashed, failed), or NULL. */
static const char *broken(const result *r)
{
    switch (r->end) {
    case END_EXPLODED: return "exploded";
    case END_ERROR: return "failed";
    case END_CRASH: return "died";
    default: return NULL;
    }
}

static void ratio_cell(double ours, double peer)
{
    if (isfinite(ours) && isfinite(peer) && peer > 0)
        printf(" %10.4g", ours / peer);
    else
        printf(" %10s", "n/a");
}

/* One line of ratios, ours over peer; o and p are engine indices. */
static void print_ratios(int o, int p, const result *ours, const result *peer)
{
    char pair[24], end[128];
    snprintf(pair, sizeof pair, "%s / %s", eng_name[o], eng_name[p]);
    const result *bad = broken(peer) ? peer : broken(ours) ? ours : NULL;
    if (bad) {
        int who = bad == peer ? p : o;
        describe_end(bad, end, sizeof end);
        printf("    %-15s %s %s", pair, eng_name[who], end);
        if (bad->end == END_EXPLODED)
            printf(" (energy %.3gx the initial)", bad->epeak / bad->e0);
        printf(": no ratios\n");
        return;
    }
    double span, ra = NAN, rb = NAN;
    common_rtf(ours, peer, &span, &ra, &rb);
    printf("    %-15s %8.2f", pair, span);
    ratio_cell(ra, rb);
    ratio_cell(ours->epeak / ours->e0, peer->epeak / peer->e0);
    ratio_cell(ours->max_pen, peer->max_pen);
    ratio_cell(ours->rest_s >= 0 ? ours->rest_s : NAN, peer->rest_s >= 0 ? peer->rest_s : NAN);
    if (ours->rest_s < 0 || peer->rest_s < 0)
        printf("  (rest: %s%s%s not at rest within the cap)", ours->rest_s < 0 ? eng_name[o] : "",
               ours->rest_s < 0 && peer->rest_s < 0 ? ", " : "",
               peer->rest_s < 0 ? eng_name[p] : "");
    printf("\n");
}

/* The static bodies ODE was given, as read from the world. */
static void print_walls(int n, const scene *sc)
{
    printf("  N = %d: %d static bod%s:", n, sc->nwalls, sc->nwalls == 1 ? "y" : "ies");
    for (int i = 0; i < sc->nwalls; i++) {
        const wall *wl = &sc->walls[i];
        if (wl->kind == SC_SHAPE_PLANE)
            printf("%s plane %+.3g x %+.3g y %+.3g z <= %.4g", i ? "," : "", wl->plane[0] + 0.0,
                   wl->plane[1] + 0.0, wl->plane[2] + 0.0, wl->plane[3] + 0.0);
        else
            printf("%s box %.3g x %.3g x %.3g m at (%.3g, %.3g, %.3g)", i ? "," : "",
                   2 * wl->half[0], 2 * wl->half[1], 2 * wl->half[2], wl->pos[0], wl->pos[1],
                   wl->pos[2]);
    }
    printf("\n");
}

static void usage(void)
{
    fprintf(stderr, "usage: bench_drop [-S drop|bin] [-r runs] [-T sim_seconds] "
                    "[-F] [-b wall_budget_s] [-s seed] [-e qas1nlLc] [N ...]\n");
    exit(2);
}

int main(int argc, char **argv)
{
    int runs_opt = 0;
    uint64_t seed = 1;
    const char *engines = "qsc";
    int opt;
    while ((opt = getopt(argc, argv, "S:r:T:Fb:s:e:h")) != -1) {
        switch (opt) {
        case 'S':
            if (strcmp(optarg, "drop") == 0)
                scene_kind = SCENE_DROP;
            else if (strcmp(optarg, "bin") == 0)
                scene_kind = SCENE_BIN;
            else
                usage();
            break;
        case 'r': runs_opt = atoi(optarg); break;
        case 'T': sim_limit_s = atof(optarg); break;
        case 'F': full_run = 1; break;
        case 'b': budget_s = atof(optarg); break;
        case 's': seed = strtoull(optarg, NULL, 0); break;
        case 'e': engines = optarg; break;
        default: usage();
        }
    }
    if (runs_opt < 0 || runs_opt > MAX_RUNS || !(sim_limit_s > 0) || !(budget_s > 0) ||
        sim_limit_s > 1e6 || budget_s > 1e6 || strspn(engines, "qas1nlLc") != strlen(engines))
        usage();
    int ns[64], nn = 0;
    for (int i = optind; i < argc && nn < 64; i++) {
        ns[nn] = atoi(argv[i]);
        if (ns[nn] < 1 || ns[nn] > 100000)
            usage();
        nn++;
    }
    if (nn == 0 && scene_kind == SCENE_BIN) {
        ns[0] = 50;
        ns[1] = 200;
        nn = 2;
    } else if (nn == 0) {
        ns[0] = 10;
        ns[1] = 50;
        ns[2] = 200;
        ns[3] = 1000;
        nn = 4;
    }
    int use[ENG_COUNT];
    for (int e = 0; e < ENG_COUNT; e++)
        use[e] = strchr(engines, eng_key[e]) != NULL ||
                 ((e == ENG_SC1 || e == ENG_SCN) && strchr(engines, 'c') != NULL);
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    eng_threads[ENG_SCN] = cpus < 1 ? 1 : cpus > SC_MAX_WORKERS ? SC_MAX_WORKERS : (int)cpus;
    eng_threads[ENG_SLN] = eng_threads[ENG_SCN];
    long frames_max = (long)ceil(sim_limit_s / DT - 1e-9);
    mark_stride = (frames_max + NMARK - 1) / NMARK;
    if (mark_stride < 1)
        mark_stride = 1;
    dInitODE2(0);
    dAllocateODEDataForThread(dAllocateMaskAll);
    sc_shape *bolt = sc_shape_bolt(), *nut = sc_shape_nut();
    if (!bolt || !nut) {
        fprintf(stderr, "building the meshes: %s\n", sc_strerror(sc_last_error()));
        return 1;
    }
    printf("%s, %d + %d triangles, steel, e = %.1f, mu = %.1f, dt = %.2f s, "
           "up to %.1f s simulated, wall budget %.0f s a run, seed %llu\n",
           scene_kind == SCENE_BIN ? "parts bin (-S bin, sc_scene_bin: the dense pile)"
                                   : "bolt/nut drop (-S drop, sc_scene_bolts_nuts)",
           sc_shape_triangles(bolt), sc_shape_triangles(nut), BOUNCE, MU, DT, sim_limit_s,
           budget_s, (unsigned long long)seed);
    printf("quick: ODE dWorldQuickStep (%d iterations); quickAD: the same with ODE's "
           "auto-disable; step: ODE dWorldStep; ODE (%s): trimesh "
           "in dHashSpace, <= %d contacts a pair, Bounce|Approx1, bounce_vel %.1f m/s, "
           "default ERP/CFM\n",
           QUICK_ITERS, dGetConfiguration(), MAX_PAIR_CONTACTS, BOUNCE_VEL);
    printf("sc1: simcluster, toi_mode world, workers = 1; scN: workers = %d (every online CPU); "
           "sl1: toi_mode local (the default), workers = 1; slN: local, workers = %d%s\n",
           eng_threads[ENG_SCN], eng_threads[ENG_SLN],
           full_run ? "; -F: every run goes to -T" : "");
    printf("rest: all bodies < %.0f cm/s and < %.1f rad/s for %.1f s; "
           "explosion: NaN or energy > %.0fx initial\n\n",
           REST_V * 100, REST_W, REST_HOLD_S, EXPLODE_FACTOR);
    printf("%6s  %-7s %3s %4s  %9s %8s %9s %9s %10s %9s %10s  %s\n", "N", "engine", "thr", "runs",
           "wall s", "sim s", "RT factor", "Epeak/E0", "max pen m", "rest at s", "vmax end",
           "end");
    for (int t = 0; t < nn; t++) {
        int n = ns[t], runs = runs_opt ? runs_opt : 3;
        scene sc;
        memset(&sc, 0, sizeof sc);
        if (scene_init(&sc, n, seed, bolt, nut) != 0) {
            fprintf(stderr, "scene of %d bodies failed\n", n);
            scene_free(&sc);
            return 1;
        }
        print_walls(n, &sc);
        static result med[ENG_COUNT], rs[ENG_COUNT][MAX_RUNS];
        int have[ENG_COUNT] = { 0 }, made[ENG_COUNT] = { 0 }, cut[ENG_COUNT] = { 0 };
        memset(rs, 0, sizeof rs);
        for (int k = 0; k < runs; k++)
            for (int e = 0; e < ENG_COUNT; e++) {
                if (!use[e] || cut[e])
                    continue;
                run_child(&sc, e, &rs[e][made[e]++]);
                /* a cut cell is not repeated (see the top) */
                cut[e] = !runs_opt && rs[e][0].end == END_BUDGET;
            }
        for (int e = 0; e < ENG_COUNT; e++) {
            if (!use[e])
                continue;
            qsort(rs[e], (size_t)made[e], sizeof rs[e][0], cmp_rtf);
            med[e] = rs[e][made[e] / 2];
            have[e] = 1;
            print_row(n, e, made[e], &med[e]);
            print_solver(e, &med[e]);
            fflush(stdout);
        }
        /* ours over each peer, and scN over sc1 */
        static const int pairs[][2] = {
            { ENG_SC1, ENG_QUICK }, { ENG_SCN, ENG_QUICK }, { ENG_SL1, ENG_QUICK },
            { ENG_SLN, ENG_QUICK }, { ENG_SL1, ENG_QAD },   { ENG_SLN, ENG_QAD },
            { ENG_SC1, ENG_STEP },  { ENG_SCN, ENG_STEP },  { ENG_SL1, ENG_STEP },
            { ENG_SLN, ENG_STEP },  { ENG_SCN, ENG_SC1 },   { ENG_SL1, ENG_SC1 },
            { ENG_SLN, ENG_SL1 } };
        int header = 0;
        for (size_t i = 0; i < sizeof pairs / sizeof pairs[0]; i++) {
            int o = pairs[i][0], p = pairs[i][1];
            if (!have[o] || !have[p])
                continue;
            if (!header) {
                printf("  ratios at N = %d (RT factor over the simulated span both runs reached):\n"
                       "    %-15s %8s %10s %10s %10s %10s\n",
                       n, "pair", "span s", "RT factor", "Epeak/E0", "max pen", "rest time");
                header = 1;
            }
            print_ratios(o, p, &med[o], &med[p]);
        }
        fflush(stdout);
        scene_free(&sc);
    }
    sc_shape_release(bolt);
    sc_shape_release(nut);
    dCloseODE();
    return 0;
}
