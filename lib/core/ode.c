/* ode.c - the copy of libode the library links: its one-time
 * initialisation and its function table (ode_table.h). Worker threads may
 * use private copies instead (lib/exec/ode_copy.c). ODE's own global
 * initialisation is process-wide by ODE's design; it holds no simulation
 * state. */
#include <pthread.h>
#include <stdarg.h>

#include "core.h"
#include "ode_table.h"

/* ODE messages (e.g. "contact hash table bucket overflow") of this thread. */
static _Thread_local long ode_messages;

void sc_ode_message(int num, const char *msg, va_list ap)
{
    /* a library must not print on its users' stderr: count instead */
    (void)num;
    (void)msg;
    (void)ap;
    ode_messages++;
}

long sc_ode_message_count(void)
{
    return ode_messages;
}

void sc_ode_thread_init(void)
{
    sc_ode_init();
    dAllocateODEDataForThread(dAllocateMaskAll);
}

static pthread_once_t shared_once = PTHREAD_ONCE_INIT;
static struct sc_ode shared;

static void shared_init(void)
{
#define SC_ODE_LINKED(f) shared.f = f;
    SC_ODE_FUNCS(SC_ODE_LINKED)
#undef SC_ODE_LINKED
    shared.trimesh_class = dTriMeshClass;
    /* ODE's global init (its own tables, no simulation state); never closed
     * so that worlds in any thread can come and go. */
    dInitODE2(0);
    dSetMessageHandler(sc_ode_message);
}

void sc_ode_init(void)
{
    pthread_once(&shared_once, shared_init);
}

const sc_ode *sc_ode_shared(void)
{
    sc_ode_init();
    return &shared;
}

int sc_ode_is_private(const sc_ode *o)
{
    return o && o->handle != NULL;
}
