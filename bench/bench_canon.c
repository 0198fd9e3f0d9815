/* bench_canon.c - the canonical scenes with known answers (tests/canon.h)
 * in both time-of-impact modes and in ODE's dWorldStep and dWorldQuickStep
 * (20 iterations), side by side: each figure against its analytic value,
 * a star where an engine misses its tolerance, and each engine's wall
 * time for the scene. ODE gets the same boxes, spheres and planes, masses
 * and inertia; contacts from dCollide (at most 4 a pair), mode
 * dContactBounce | dContactApprox1, mu the geometric mean of the bodies',
 * bounce the larger restitution, bounce_vel 0.1 m/s (simcluster's bounce
 * speed), default ERP and CFM.
 * With -s, the structures (stacks, pyramid, wall: big islands) standing for
 * T s instead, and each engine's wall time per scene.
 * Usage: bench_canon [-w workers] [-m] [-s] [-T seconds]
 *   -m a markdown table; -s the structures; -T their time (default 10);
 *   -B the wall seconds an ODE run may take (default 120): dWorldStep's
 *   dense LCP on a pyramid of 15 rows takes far longer, and its figures
 *   then cover the simulated time it reached (printed) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <ode/ode.h>

#include "../tests/canon.h"
#include "bench_util.h"

#define QUICK_ITERS 20
#define ODE_MAX_CONTACTS 4

typedef struct ode_run {
    dWorldID world;
    dSpaceID space;
    dJointGroupID group;
} ode_run;

static void near_cb(void *ctx, dGeomID o1, dGeomID o2)
{
    ode_run *r = ctx;
    dBodyID b1 = dGeomGetBody(o1), b2 = dGeomGetBody(o2);
    if (!b1 && !b2)
        return;
    const canon_body *x = dGeomGetData(o1), *y = dGeomGetData(o2);
    dContact c[ODE_MAX_CONTACTS];
    memset(c, 0, sizeof c);
    int n = dCollide(o1, o2, ODE_MAX_CONTACTS, &c[0].geom, sizeof c[0]);
    for (int i = 0; i < n; i++) {
        c[i].surface.mode = dContactBounce | dContactApprox1;
        c[i].surface.mu = sqrt(x->mu * y->mu);
        c[i].surface.bounce = fmax(x->e, y->e);
        c[i].surface.bounce_vel = 0.1;
        dJointAttach(dJointCreateContact(r->world, r->group, &c[i]), b1, b2);
    }
}

/* The scene in ODE, stepped by dWorldQuickStep (quick) or dWorldStep,
 * for at most budget_s of wall time: past it the record ends at the frame
 * reached (t->frames), judged as far as it goes. */
static int run_ode(const canon_scene *sc, int quick, double budget_s, canon_traj *t)
{
    double t0 = now_s();
    ode_run r;
    r.world = dWorldCreate();
    r.space = dSimpleSpaceCreate(0);
    r.group = dJointGroupCreate(0);
    dWorldSetGravity(r.world, 0, 0, -sc->gravity);
    dWorldSetQuickStepNumIterations(r.world, QUICK_ITERS);
    dBodyID body[CANON_MAX_BODIES];
    int nd = 0;
    for (int i = 0; i < sc->nb; i++) {
        const canon_body *b = &sc->b[i];
        dGeomID g;
        if (b->kind == CANON_PLANE)
            g = dCreatePlane(r.space, b->size[0], b->size[1], b->size[2], b->size[3]);
        else if (b->kind == CANON_BOX)
            g = dCreateBox(r.space, 2 * b->size[0], 2 * b->size[1], 2 * b->size[2]);
        else
            g = dCreateSphere(r.space, b->size[0]);
        dGeomSetData(g, (void *)b);
        if (!(b->mass > 0))
            continue;
        dBodyID d = dBodyCreate(r.world);
        dMass m;
        if (b->kind == CANON_BOX)
            dMassSetBoxTotal(&m, b->mass, 2 * b->size[0], 2 * b->size[1], 2 * b->size[2]);
        else
            dMassSetSphereTotal(&m, b->mass, b->size[0]);
        dBodySetMass(d, &m);
        dGeomSetBody(g, d);
        dBodySetPosition(d, b->pos[0], b->pos[1], b->pos[2]);
        dQuaternion q = { b->quat[0], b->quat[1], b->quat[2], b->quat[3] };
        dBodySetQuaternion(d, q);
        dBodySetLinearVel(d, b->vel[0], b->vel[1], b->vel[2]);
        dBodySetAngularVel(d, b->omega[0], b->omega[1], b->omega[2]);
        body[nd++] = d;
    }
    for (int f = 0; f <= t->frames; f++) {
        if (f > 0) {
            dSpaceCollide(r.space, &r, near_cb);
            if (quick)
                dWorldQuickStep(r.world, sc->dt);
            else
                dWorldStep(r.world, sc->dt);
            dJointGroupEmpty(r.group);
        }
        for (int i = 0; i < nd; i++) {
            double *s = canon_at(t, f, i);
            const dReal *p = dBodyGetPosition(body[i]), *q = dBodyGetQuaternion(body[i]);
            const dReal *v = dBodyGetLinearVel(body[i]), *w = dBodyGetAngularVel(body[i]);
            for (int j = 0; j < 3; j++) {
                s[j] = p[j];
                s[7 + j] = v[j];
                s[10 + j] = w[j];
            }
            for (int j = 0; j < 4; j++)
                s[3 + j] = q[j];
        }
        if (f > 0 && f < t->frames && now_s() - t0 > budget_s) {
            t->frames = f;
            break;
        }
    }
    dJointGroupDestroy(r.group);
    dSpaceDestroy(r.space);
    dWorldDestroy(r.world);
    return 0;
}

enum { E_LOCAL, E_WORLD, E_STEP, E_QUICK, E_COUNT };
static const char *engine_name[E_COUNT] = { "local", "world", "ODE step", "ODE quick" };

int main(int argc, char **argv)
{
    int workers = 1, md = 0, structures = 0, opt;
    double T = 10, budget = 120;
    while ((opt = getopt(argc, argv, "w:msT:B:")) != -1) {
        if (opt == 'w')
            workers = atoi(optarg);
        else if (opt == 'm')
            md = 1;
        else if (opt == 's')
            structures = 1;
        else if (opt == 'T' && atof(optarg) > 0)
            T = atof(optarg);
        else if (opt == 'B' && atof(optarg) > 0)
            budget = atof(optarg);
        else {
            fprintf(stderr, "usage: bench_canon [-w workers] [-m] [-s] [-T seconds] [-B seconds]\n");
            return 2;
        }
    }
    dInitODE2(0);
    canon_scene *scenes = malloc(64 * sizeof *scenes);
    if (!scenes)
        return 1;
    int ns = structures ? canon_structures(scenes, 64, T) : canon_suite(scenes, 64);
    int missed[E_COUNT] = { 0 }, figs = 0;
    printf("%s (tests/canon.h): simcluster local and world time of impact "
           "(workers = %d), ODE %s dWorldStep and dWorldQuickStep (%d iterations); "
           "* = outside the tolerance\n",
           structures ? "structures standing" : "canonical scenes", workers, dGetConfiguration(),
           QUICK_ITERS);
    if (md)
        printf("\n| scene | figure | analytic | tolerance | local | world | ODE step | "
               "ODE quick |\n|---|---|---|---|---|---|---|---|\n");
    else
        printf("%-28s %-28s %10s %8s %11s %11s %11s %11s\n", "scene", "figure", "analytic",
               "tol", "local", "world", "ODE step", "ODE quick");
    double wall[E_COUNT] = { 0 }, swall[64][E_COUNT], reached[64][E_COUNT];
    for (int i = 0; i < ns; i++) {
        const canon_scene *sc = &scenes[i];
        canon_fig f[E_COUNT][CANON_MAX_FIGS];
        int nf = 0, err[E_COUNT];
        for (int e = 0; e < E_COUNT; e++) {
            canon_traj t;
            if (canon_traj_init(&t, sc))
                return 1;
            double t0 = now_s();
            err[e] = e == E_LOCAL   ? canon_run_sc(sc, SC_TOI_LOCAL, workers, &t)
                   : e == E_WORLD   ? canon_run_sc(sc, SC_TOI_WORLD, workers, &t)
                                    : run_ode(sc, e == E_QUICK, budget, &t);
            reached[i][e] = t.frames * sc->dt;
            swall[i][e] = now_s() - t0;
            wall[e] += swall[i][e];
            nf = canon_judge(sc, &t, f[e]);
            canon_traj_free(&t);
        }
        for (int k = 0; k < nf; k++) {
            figs++;
            if (md)
                printf("| %s | %s | %.4g | %s%.3g |", k ? "" : sc->name, f[0][k].name,
                       f[0][k].expect, f[0][k].how == CANON_AT_MOST ? "<= +" : "+-",
                       f[0][k].tol);
            else
                printf("%-28s %-28s %10.4g %8.3g", k ? "" : sc->name, f[0][k].name,
                       f[0][k].expect, f[0][k].tol);
            for (int e = 0; e < E_COUNT; e++) {
                int ok = !err[e] && canon_pass(&f[e][k]);
                missed[e] += !ok;
                if (err[e] && md)
                    printf(" error %d |", err[e]);
                else if (err[e])
                    printf(" %11s", "error");
                else if (md)
                    printf(" %.5g%s |", f[e][k].value, ok ? "" : " *");
                else
                    printf(" %10.5g%s", f[e][k].value, ok ? " " : "*");
            }
            printf("\n");
        }
    }
    printf("%s%d figures; missed:", md ? "\n" : "", figs);
    for (int e = 0; e < E_COUNT; e++)
        printf(" %s %d%s", engine_name[e], missed[e], e + 1 < E_COUNT ? "," : "\n");
    if (structures) {
        printf("%swall s per scene (%.0f s simulated):\n", md ? "\n" : "", T);
        for (int i = 0; i < ns; i++) {
            printf("%s%-28s", md ? "    " : "  ", scenes[i].name);
            for (int e = 0; e < E_COUNT; e++) {
                printf(" %s %.3f", engine_name[e], swall[i][e]);
                if (reached[i][e] < T - 1e-9)
                    printf(" (stopped at %.2f s)", reached[i][e]);
            }
            printf("\n");
        }
    }
    printf("wall s for the suite:");
    for (int e = 0; e < E_COUNT; e++)
        printf(" %s %.3f%s", engine_name[e], wall[e], e + 1 < E_COUNT ? "," : "\n");
    free(scenes);
    dCloseODE();
    return 0;
}
