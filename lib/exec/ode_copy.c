/* ode_copy.c - copies of libode for the worker threads (docs/DESIGN.md
 * 5.4). Debian's ODE shares one trimesh collider cache per process, so
 * trimesh pairs on the linked copy are serialised by a lock; a copy loaded
 * with dlmopen(LM_ID_NEWLM) has globals of its own, so threads on
 * different copies collide trimeshes concurrently. Copies are process-wide
 * and never unloaded (glibc's namespaces and static TLS are few); with none
 * to be had, or in sanitizer builds, the caller gets the shared, locked
 * copy: slower, never wrong. */
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>

#include "ode_table.h"
#include "exec.h"

#define MAX_COPIES 15

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define PRIVATE_COPIES 0
#else
#define PRIVATE_COPIES 1
#endif

static pthread_mutex_t copies_lock = PTHREAD_MUTEX_INITIALIZER;
static struct sc_ode *copies[MAX_COPIES];
static int ncopies;
static unsigned char in_use[MAX_COPIES];
static int load_failed;

/* A new copy of the libode this library is linked with; NULL if it cannot
 * be had. Called with copies_lock held. */
static struct sc_ode *load_copy(void)
{
    Dl_info di;
    if (!dladdr((void *)dCollide, &di) || !di.dli_fname)
        return NULL;
    void *h = dlmopen(LM_ID_NEWLM, di.dli_fname, RTLD_NOW | RTLD_LOCAL);
    if (!h)
        return NULL;
    struct sc_ode *o = calloc(1, sizeof *o);
    if (!o) {
        dlclose(h);
        return NULL;
    }
    o->handle = h;
    int ok = 1;
#define SC_ODE_LOOKUP(f) \
    *(void **)&o->f = dlsym(h, #f); \
    ok &= o->f != NULL;
    SC_ODE_FUNCS(SC_ODE_LOOKUP)
#undef SC_ODE_LOOKUP
    if (!ok) {
        free(o);
        dlclose(h);
        return NULL;
    }
    o->trimesh_class = dTriMeshClass;   /* class numbers are ODE's constants */
    o->dInitODE2(0);
    o->dSetMessageHandler(sc_ode_message);
    return o;
}

const sc_ode *sc_ode_acquire(void)
{
    sc_ode_init();
    if (!PRIVATE_COPIES)
        return sc_ode_shared();
    struct sc_ode *o = NULL;
    pthread_mutex_lock(&copies_lock);
    for (int i = 0; i < ncopies && !o; i++)
        if (!in_use[i]) {
            in_use[i] = 1;
            o = copies[i];
        }
    if (!o && !load_failed && ncopies < MAX_COPIES) {
        o = load_copy();
        if (o) {
            in_use[ncopies] = 1;
            copies[ncopies++] = o;
        } else {
            load_failed = 1;    /* the limit of this process: stop trying */
        }
    }
    pthread_mutex_unlock(&copies_lock);
    if (!o)
        return sc_ode_shared();
    o->dAllocateODEDataForThread(dAllocateMaskAll);
    return o;
}

void sc_ode_release(const sc_ode *o)
{
    if (!sc_ode_is_private(o))
        return;
    pthread_mutex_lock(&copies_lock);
    for (int i = 0; i < ncopies; i++)
        if (copies[i] == o)
            in_use[i] = 0;
    pthread_mutex_unlock(&copies_lock);
}
