/* bench_ode_threads.c - can trimesh collisions run on several threads?
 *
 * Debian's libode keeps its trimesh collider cache in a process global, so
 * the library serialises trimesh pairs behind one lock (narrowphase.c).
 * This measures bolt-nut trimesh collision throughput for 1..T threads:
 *   shared  - every thread calls sc_collide (one libode, the lock);
 *   dlmopen - every thread loads its own copy of libode with
 *             dlmopen(LM_ID_NEWLM) and collides through it (no lock).
 * Usage: bench_ode_threads [MAX_THREADS]  (default: online CPUs, max 15;
 * above ~11 copies glibc needs GLIBC_TUNABLES=glibc.rtld.optional_static_tls=16384). */
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include <ode/ode.h>

#include "bench_util.h"
#include "simcluster.h"

#define QUERIES 4000
#define RUNS 3

static const double *xyz;
static const int *tri;
static int nv, nt;
static unsigned *idx;
static sc_shape *bolt;

static void pose_of(int i, sc_pose *a, sc_pose *b)
{
    double ang = 0.001 * i;
    *a = (sc_pose){ { 0, 0, 0 }, { cos(ang), sin(ang), 0, 0 } };
    *b = (sc_pose){ { 0.001 * (i % 7), 0.0005 * (i % 5), 0.03 - 0.0005 * (i % 60) }, { 1, 0, 0, 0 } };
}

typedef struct job {
    int mode;          /* 0 shared, 1 dlmopen */
    long contacts;
    int failed;
} job;

static void quiet(int num, const char *msg, va_list ap)
{
    (void)num;
    (void)msg;
    (void)ap;
}

static void *run(void *arg)
{
    job *j = arg;
    if (j->mode == 0) {
        for (int i = 0; i < QUERIES; i++) {
            sc_pose a, b;
            pose_of(i, &a, &b);
            sc_contact c[4];
            int n = sc_collide(bolt, &a, bolt, &b, c, 4);
            j->contacts += n > 0 ? n : 0;
        }
        return NULL;
    }
    void *h = dlmopen(LM_ID_NEWLM, "libode.so.8", RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        j->failed = 1;
        return NULL;
    }
    int (*init2)(unsigned) = (int (*)(unsigned))dlsym(h, "dInitODE2");
    int (*alloc)(unsigned) = (int (*)(unsigned))dlsym(h, "dAllocateODEDataForThread");
    void (*msgh)(dMessageFunction *) = (void (*)(dMessageFunction *))dlsym(h, "dSetMessageHandler");
    dTriMeshDataID (*tdc)(void) = (dTriMeshDataID (*)(void))dlsym(h, "dGeomTriMeshDataCreate");
    void (*tdb)(dTriMeshDataID, const void *, int, int, const void *, int, int) =
        (void (*)(dTriMeshDataID, const void *, int, int, const void *, int, int))dlsym(
            h, "dGeomTriMeshDataBuildDouble");
    dGeomID (*mk)(dSpaceID, dTriMeshDataID, void *, void *, void *) =
        (dGeomID (*)(dSpaceID, dTriMeshDataID, void *, void *, void *))dlsym(h, "dCreateTriMesh");
    void (*setp)(dGeomID, dReal, dReal, dReal) =
        (void (*)(dGeomID, dReal, dReal, dReal))dlsym(h, "dGeomSetPosition");
    void (*setq)(dGeomID, const dQuaternion) =
        (void (*)(dGeomID, const dQuaternion))dlsym(h, "dGeomSetQuaternion");
    int (*coll)(dGeomID, dGeomID, int, dContactGeom *, int) =
        (int (*)(dGeomID, dGeomID, int, dContactGeom *, int))dlsym(h, "dCollide");
    if (!init2 || !alloc || !msgh || !tdc || !tdb || !mk || !setp || !setq || !coll) {
        j->failed = 1;
        return NULL;
    }
    init2(0);
    alloc(0xffffffffu);
    msgh(quiet);
    dTriMeshDataID td = tdc();
    tdb(td, xyz, 3 * sizeof(double), nv, idx, 3 * nt, 3 * sizeof(unsigned));
    dGeomID g1 = mk(0, td, 0, 0, 0), g2 = mk(0, td, 0, 0, 0);
    for (int i = 0; i < QUERIES; i++) {
        sc_pose a, b;
        pose_of(i, &a, &b);
        setp(g1, a.pos[0], a.pos[1], a.pos[2]);
        setq(g1, a.quat);
        setp(g2, b.pos[0], b.pos[1], b.pos[2]);
        setq(g2, b.quat);
        dContactGeom c[64];
        j->contacts += coll(g1, g2, 64, c, sizeof c[0]) > 0;
    }
    return NULL;
}

/* Collisions per second with t threads each doing QUERIES; median of RUNS. */
static double measure(int mode, int t, int *failed)
{
    double r[RUNS];
    for (int k = 0; k < RUNS; k++) {
        pthread_t th[64];
        job jobs[64] = { { 0 } };
        double t0 = now_s();
        for (int i = 0; i < t; i++) {
            jobs[i].mode = mode;
            pthread_create(&th[i], NULL, run, &jobs[i]);
        }
        for (int i = 0; i < t; i++) {
            pthread_join(th[i], NULL);
            *failed += jobs[i].failed;
        }
        r[k] = t * QUERIES / (now_s() - t0);
    }
    qsort(r, RUNS, sizeof r[0], cmp_double);
    return r[RUNS / 2];
}

int main(int argc, char **argv)
{
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    int maxt = argc > 1 ? atoi(argv[1]) : (int)(cpus < 15 ? cpus : 15);
    if (maxt < 1 || maxt > 64) {
        fprintf(stderr, "usage: bench_ode_threads [MAX_THREADS 1..64]\n");
        return 2;
    }
    bolt = sc_shape_bolt();
    sc_shape_mesh_data(bolt, &xyz, &nv, &tri, &nt);
    idx = malloc((size_t)nt * 3 * sizeof *idx);
    for (int i = 0; i < 3 * nt; i++)
        idx[i] = (unsigned)tri[i];
    printf("bolt-bolt trimesh collisions per second, %d queries per thread, median of %d\n",
           QUERIES, RUNS);
    printf("%8s %16s %16s %12s\n", "threads", "shared (lock)", "dlmopen copies", "dlmopen x1");
    double base = 0;
    for (int t = 1; t <= maxt; t++) {
        int failed = 0;
        double s = measure(0, t, &failed);
        double d = measure(1, t, &failed);
        if (t == 1)
            base = d;
        printf("%8d %16.0f %16.0f %12.2f%s\n", t, s, d, d / base,
               failed ? "  (some dlmopen failed: see usage)" : "");
    }
    free(idx);
    sc_shape_release(bolt);
    return 0;
}
