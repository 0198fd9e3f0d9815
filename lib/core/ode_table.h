/* ode_table.h - the ODE functions the narrow phase calls, through one copy
 * of libode: the shared one the library links (ode.c) or a private copy
 * (lib/exec/ode_copy.c). Only narrowphase.c, ode.c and ode_copy.c see
 * ODE's headers. */
#ifndef SC_ODE_COPY_H
#define SC_ODE_COPY_H

#include <ode/ode.h>

#define SC_ODE_FUNCS(X) \
    X(dInitODE2) X(dSetMessageHandler) X(dAllocateODEDataForThread) \
    X(dCreateSphere) X(dCreateBox) X(dCreatePlane) X(dCreateConvex) X(dCreateTriMesh) \
    X(dGeomDestroy) X(dGeomPlaneSetParams) X(dGeomSetPosition) X(dGeomSetQuaternion) \
    X(dGeomGetClass) X(dGeomGetRotation) X(dGeomTriMeshSetLastTransform) X(dCollide) \
    X(dGeomGetPosition) X(dGeomGetQuaternion) \
    X(dGeomTriMeshDataCreate) X(dGeomTriMeshDataBuildDouble) \
    X(dGeomTriMeshDataPreprocess2) X(dGeomTriMeshDataDestroy)

struct sc_ode {
    void *handle;             /* dlmopen() handle; NULL: the linked copy */
    int trimesh_class;        /* dTriMeshClass */
#define SC_ODE_MEMBER(f) __typeof__(&f) f;
    SC_ODE_FUNCS(SC_ODE_MEMBER)
#undef SC_ODE_MEMBER
};

/* The handler every copy reports its messages to (counts them). */
void sc_ode_message(int num, const char *msg, va_list ap);

#endif
