/* narrowphase.c - exact contact detection on ODE's collision primitives
 * (the paper's step 4, polygon level; docs/DESIGN.md 3.3). ODE geoms carry
 * a pose, so each thread owns an sc_np_ctx with geoms of its own over the
 * shapes' immutable, shared data. Debian's ODE is built without libccd
 * (a convex shape meets a trimesh through its own trimesh) and without
 * thread-local storage, so on the shared libode trimesh pairs are
 * serialised by one lock; a private copy (ode_copy.c) needs none. */
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include <ccd/ccd.h>
#include <ccd/quat.h>

#include "ode_table.h"
#include "core.h"
#include "vecmath.h"

#define RAW_CONTACTS 64

/* Guards the shared copy's global trimesh collider cache (Debian's ODE has
 * no thread-local storage, so it is one for the process). */
static pthread_mutex_t ode_trimesh_lock = PTHREAD_MUTEX_INITIALIZER;

enum { REP_NATIVE, REP_CONVEX, REP_TRIMESH, REP_COUNT };

typedef struct geom_slot {
    const sc_shape *shape;
    dGeomID g[2][REP_COUNT];   /* [slot][representation] */
    dTriMeshDataID tridata;    /* a private copy's own trimesh data */
} geom_slot;

struct sc_np_ctx {
    const sc_ode *ode;
    geom_slot *slots;
    int n, cap;
    void *scratch;                 /* the thread's motion-group scratch (group.c) */
    void (*scratch_free)(void *);
    sc_arena arena;                /* the thread's arena (island solves) */
    const sc_task_runner *runner; /* the thread's node's, or NULL */
};

sc_arena *sc_np_arena(sc_np_ctx *ctx)
{
    return &ctx->arena;
}

const sc_task_runner *sc_np_runner(const sc_np_ctx *ctx)
{
    return ctx->runner;
}

void sc_np_set_runner(sc_np_ctx *ctx, const sc_task_runner *r)
{
    ctx->runner = r;
}

void **sc_np_scratch(sc_np_ctx *ctx, void (**free_fn)(void *))
{
    if (free_fn)
        ctx->scratch_free = *free_fn;
    return &ctx->scratch;
}

sc_np_ctx *sc_np_create_on(const sc_ode *ode)
{
    sc_np_ctx *ctx = calloc(1, sizeof(sc_np_ctx));
    if (ctx) {
        ctx->ode = ode;
        sc_arena_init(&ctx->arena);
    }
    return ctx;
}

sc_np_ctx *sc_np_create(void)
{
    return sc_np_create_on(sc_ode_shared());
}

void sc_np_destroy(sc_np_ctx *ctx)
{
    if (!ctx)
        return;
    if (ctx->scratch && ctx->scratch_free)
        ctx->scratch_free(ctx->scratch);
    for (int i = 0; i < ctx->n; i++)
        for (int s = 0; s < 2; s++)
            for (int r = 0; r < REP_COUNT; r++)
                if (ctx->slots[i].g[s][r])
                    ctx->ode->dGeomDestroy(ctx->slots[i].g[s][r]);
    for (int i = 0; i < ctx->n; i++)
        if (ctx->slots[i].tridata)
            ctx->ode->dGeomTriMeshDataDestroy(ctx->slots[i].tridata);
    free(ctx->slots);
    sc_arena_destroy(&ctx->arena);
    free(ctx);
}

/* The trimesh data of s for this context's copy of ODE: the shape's own
 * (built on the shared copy) or, on a private copy, one built there: ODE's
 * objects must not cross copies. */
static dTriMeshDataID tridata(const sc_ode *o, geom_slot *gs)
{
    const sc_shape *s = gs->shape;
    if (!sc_ode_is_private(o))
        return (dTriMeshDataID)s->ode_tridata;
    if (!gs->tridata) {
        dTriMeshDataID td = o->dGeomTriMeshDataCreate();
        if (!td)
            return NULL;
        o->dGeomTriMeshDataBuildDouble(td, s->xyz, 3 * sizeof(double), s->nverts,
                                       s->ode_index, 3 * s->ntris, 3 * sizeof(dTriIndex));
        o->dGeomTriMeshDataPreprocess2(td, 1U << dTRIDATAPREPROCESS_BUILD_CONCAVE_EDGES, NULL);
        gs->tridata = td;
    }
    return gs->tridata;
}

static dGeomID make_geom(const sc_ode *o, geom_slot *gs, int rep)
{
    const sc_shape *s = gs->shape;
    switch (rep) {
    case REP_NATIVE:
        switch (s->kind) {
        case SC_SHAPE_SPHERE: return o->dCreateSphere(0, s->radius);
        case SC_SHAPE_BOX:
            return o->dCreateBox(0, 2 * s->half[0], 2 * s->half[1], 2 * s->half[2]);
        case SC_SHAPE_PLANE: return o->dCreatePlane(0, 0, 0, 1, 0);
        default: return NULL;
        }
    case REP_CONVEX:
        return o->dCreateConvex(0, s->ode_planes, (unsigned)s->ntris, s->xyz,
                                (unsigned)s->nverts, s->ode_polys);
    case REP_TRIMESH: {
        dTriMeshDataID td = tridata(o, gs);
        return td ? o->dCreateTriMesh(0, td, NULL, NULL, NULL) : NULL;
    }
    }
    return NULL;
}

/* The cached geom for (shape, slot, representation); linear search is fine:
 * a world has few distinct shapes. */
static dGeomID get_geom(sc_np_ctx *ctx, const sc_shape *s, int slot, int rep)
{
    geom_slot *gs = NULL;
    for (int i = 0; i < ctx->n && !gs; i++)
        if (ctx->slots[i].shape == s)
            gs = &ctx->slots[i];
    if (!gs) {
        if (sc_grow((void **)&ctx->slots, &ctx->cap, ctx->n + 1, sizeof *ctx->slots, INT_MAX))
            return NULL;
        gs = &ctx->slots[ctx->n++];
        memset(gs, 0, sizeof *gs);
        gs->shape = s;
    }
    if (!gs->g[slot][rep])
        gs->g[slot][rep] = make_geom(ctx->ode, gs, rep);
    return gs->g[slot][rep];
}

/* Which representation each shape of a pair uses. */
static void choose_reps(const sc_shape *a, const sc_shape *b, int *ra, int *rb)
{
    int ka = a->kind, kb = b->kind;
    int mesh_a = ka == SC_SHAPE_MESH && !a->convex, mesh_b = kb == SC_SHAPE_MESH && !b->convex;
    int poly_a = ka == SC_SHAPE_MESH || ka == SC_SHAPE_CONVEX;
    int poly_b = kb == SC_SHAPE_MESH || kb == SC_SHAPE_CONVEX;
    *ra = poly_a ? REP_CONVEX : REP_NATIVE;
    *rb = poly_b ? REP_CONVEX : REP_NATIVE;
    if (mesh_a) *ra = REP_TRIMESH;
    if (mesh_b) *rb = REP_TRIMESH;
    /* no convex-trimesh collider without libccd: both go trimesh */
    if (poly_a && poly_b && (mesh_a || mesh_b))
        *ra = *rb = REP_TRIMESH;
}

static void place(const sc_ode *o, dGeomID g, const sc_shape *s, const sc_pose *p)
{
    if (s->kind == SC_SHAPE_PLANE) {
        /* the plane is given in the body frame: move it to the world */
        double n[3];
        q_rotate(n, p->quat, s->plane);
        o->dGeomPlaneSetParams(g, n[0], n[1], n[2], s->plane[3] + v3_dot(n, p->pos));
        return;
    }
    o->dGeomSetPosition(g, p->pos[0], p->pos[1], p->pos[2]);
    dQuaternion q = { p->quat[0], p->quat[1], p->quat[2], p->quat[3] };
    o->dGeomSetQuaternion(g, q);
    if (o->dGeomGetClass(g) == o->trimesh_class) {
        /* no previous pose is tracked: the trimesh colliders must not
         * extrapolate from a stale one */
        const dReal *R = o->dGeomGetRotation(g);
        dMatrix4 m = { R[0], R[4], R[8], 0, R[1], R[5], R[9], 0,
                       R[2], R[6], R[10], 0, p->pos[0], p->pos[1], p->pos[2], 1 };
        o->dGeomTriMeshSetLastTransform(g, m);
    }
}

static int pose_ok(const sc_pose *p)
{
    if (!sc_finite3(p->pos))
        return 0;
    double n = p->quat[0] * p->quat[0] + p->quat[1] * p->quat[1] +
               p->quat[2] * p->quat[2] + p->quat[3] * p->quat[3];
    return isfinite(n) && fabs(n - 1) < 1e-6;
}

/* A non-convex mesh against a plane: each vertex inside the half space is a
 * contact, as in ODE's trimesh-plane collider, which reaches the vertices
 * through the triangles (each one fetched, converted and transformed about
 * six times), takes the trimesh lock and stops at the contact buffer's
 * size; here each vertex is looked at once, none is left out, and a full
 * buffer is reduced (deepest and widest kept) before it takes more. The
 * normal points from a to b (the mesh is pushed out along the plane's). */
#define MESH_PLANE_BUF 256

/* The plane pl at pp in the frame of the mesh m at pm: a vertex vl is
 * dl - nl . vl deep. n: the plane's world normal, R: the mesh's rotation.
 * 0 when the mesh's bounding sphere is clear of it. */
static int plane_in_mesh(const sc_shape *m, const sc_pose *pm, const sc_shape *pl,
                         const sc_pose *pp, double n[3], double R[9], double nl[3], double *dl)
{
    q_rotate(n, pp->quat, pl->plane);
    *dl = pl->plane[3] + v3_dot(n, pp->pos) - v3_dot(n, pm->pos);
    if (*dl + m->bound_r < 0)
        return 0;
    q_to_m3(R, pm->quat);
    m3_tmulv(nl, R, n);
    return 1;
}

/* mesh_plane()'s contact at vertex vl (mesh frame), depth deep, as c[k]
 * (c reduced first when full); the new count. */
static int vertex_contact(sc_contact *c, int k, const double R[9], const sc_pose *pm,
                          const double *vl, const double n[3], int plane_is_a, double depth,
                          double merge)
{
    double v[3];
    m3_mulv(v, R, vl);
    v3_add(v, v, pm->pos);
    if (k == MESH_PLANE_BUF)
        k = sc_manifold_reduce(c, k, merge);
    sc_contact *ci = &c[k++];
    ci->body_a = ci->body_b = -1;
    v3_copy(ci->pos, v);
    v3_scale(ci->normal, n, plane_is_a ? 1.0 : -1.0);
    ci->depth = depth;
    return k;
}

static int mesh_plane(const sc_shape *m, const sc_pose *pm, const sc_shape *pl,
                      const sc_pose *pp, int plane_is_a, sc_contact *c, double merge)
{
    /* the plane in the mesh's frame: one dot product a vertex; only the
     * vertices inside are carried to the world */
    double n[3], R[9], nl[3], dl;
    if (!plane_in_mesh(m, pm, pl, pp, n, R, nl, &dl))
        return 0;                  /* the mesh's bounding sphere is clear */
    int k = 0;
#ifdef __SSE2__
    /* two vertices at a time (the same products and sums as v3_dot(), so
     * the same depths), in order; most are above the plane */
    const __m128d ax = _mm_set1_pd(nl[0]), ay = _mm_set1_pd(nl[1]), az = _mm_set1_pd(nl[2]);
    const __m128d dv = _mm_set1_pd(dl), zero = _mm_setzero_pd();
    for (int p = 0; 2 * p < m->nverts; p++) {
        __m128d d2 = _mm_sub_pd(dv, v3_dot2(ax, ay, az, &m->xyz_soa[6 * p]));
        int in = _mm_movemask_pd(_mm_cmpgt_pd(d2, zero));
        if (!in)
            continue;
        double two[2];
        _mm_storeu_pd(two, d2);
        for (int j = 0; j < 2 && 2 * p + j < m->nverts; j++)
            if (in >> j & 1)
                k = vertex_contact(c, k, R, pm, &m->xyz[3 * (2 * p + j)], n, plane_is_a, two[j],
                                   merge);
    }
#else
    for (int i = 0; i < m->nverts; i++) {
        double depth = dl - v3_dot(nl, &m->xyz[3 * i]);
        if (depth > 0)
            k = vertex_contact(c, k, R, pm, &m->xyz[3 * i], n, plane_is_a, depth, merge);
    }
#endif
    return k;
}

/* 1 if dir (world) is the outward normal of an inner face of s (a mesh
 * piece's face inside the mesh, shape.c), within about 2.5 degrees. */
static int inner_normal(const sc_shape *s, const sc_pose *p, const double dir[3])
{
    if (!s->face_inner)
        return 0;
    double R[9], local[3];
    q_to_m3(R, p->quat);
    m3_tmulv(local, R, dir);
    for (int f = 0; f < s->nfaces; f++)
        if (s->face_inner[f] && v3_dot(local, &s->face_plane[4 * f]) > 0.999)
            return 1;
    return 0;
}

/* The n contacts in c reduced to a well-spread few, at most max of them
 * copied to out; returns how many. */
static int emit(sc_contact *c, int n, double merge, sc_contact *out, int max)
{
    n = sc_manifold_reduce(c, n, merge);
    if (n > max)
        n = max;
    for (int i = 0; i < n; i++) {
        v3_set(c[i].impulse, 0, 0, 0);
        c[i].impulse_dt = 0;
    }
    if (n > 0)
        memcpy(out, c, (size_t)n * sizeof *out);
    return n;
}

/* Shape k of s's collision pieces (s itself if it has none), its pose q
 * in the world (a piece's frame is offset in s's) and its bounding radius
 * about q's origin. */
static const sc_shape *piece_at(const sc_shape *s, const sc_pose *p, const double R[9], int k,
                                sc_pose *q, double *r)
{
    *q = *p;
    if (s->npieces == 0) {
        *r = s->bound_r;
        return s;
    }
    const double *ball = &s->piece_ball[4 * k];
    m3_mulv(q->pos, R, ball);        /* q_rotate(), its matrix made once */
    v3_add(q->pos, q->pos, p->pos);
    *r = ball[3];
    return s->pieces[k];
}

/* A piece placed in the world: its shape, pose and bounding radius. */
#define PIECES_APART 128      /* sc_np_apart_by(): pieces of both, at most */
typedef struct placed_piece {
    const sc_shape *s;
    sc_pose q;
    double r;
} placed_piece;

/* The pieces of s (s itself if it has none) that can reach a ball at c of
 * radius r, placed, into out; returns how many. R: s's rotation matrix
 * (q_to_m3() of p's quaternion), made here. */
static int pieces_near(const sc_shape *s, const sc_pose *p, const double c[3], double r,
                       placed_piece *out, double R[9])
{
    q_to_m3(R, p->quat);
    if (s->npieces == 0) {
        out[0].s = piece_at(s, p, R, 0, &out[0].q, &out[0].r);
        return 1;
    }
    /* the ball in s's frame: a piece is placed only if it reaches it */
    double d[3], cl[3];
    v3_sub(d, c, p->pos);
    m3_tmulv(cl, R, d);
    int m = 0;
    for (int k = 0; k < s->npieces; k++) {
        const double *ball = &s->piece_ball[4 * k];
        double e[3], reach = ball[3] + r;
        v3_sub(e, ball, cl);
        if (v3_dot(e, e) > reach * reach)
            continue;
        placed_piece *pp = &out[m++];
        pp->s = piece_at(s, p, R, k, &pp->q, &pp->r);
    }
    return m;
}

int sc_np_apart_by(const sc_shape *a, const sc_pose *pa, const sc_shape *b, const sc_pose *pb,
                   double margin)
{
    if (a->kind == SC_SHAPE_PLANE || b->kind == SC_SHAPE_PLANE)
        return 0;
    if (v3_dist(pa->pos, pb->pos) > a->bound_r + b->bound_r + margin)
        return 1;
    placed_piece stack[PIECES_APART], *qa = stack, *qb = stack + PIECES_APART / 2;
    int na = a->npieces ? a->npieces : 1, nb = b->npieces ? b->npieces : 1;
    if (na > PIECES_APART / 2 || nb > PIECES_APART / 2)
        return 0;
    double Ra[9], Rb[9];
    int ma = pieces_near(a, pa, pb->pos, b->bound_r + margin, qa, Ra);
    int mb = pieces_near(b, pb, pa->pos, a->bound_r + margin, qb, Rb);
    for (int i = 0; i < ma; i++)
        for (int j = 0; j < mb; j++) {
            if (v3_dist(qa[i].q.pos, qb[j].q.pos) > qa[i].r + qb[j].r + margin)
                continue;
            if (!sc_poly_apart_by(qa[i].s, Ra, qa[i].q.pos, qb[j].s, Rb, qb[j].q.pos, margin))
                return 0;
        }
    return 1;
}

/* A pair where one shape or both have convex pieces: every pair of pieces
 * whose balls overlap, collided as convex shapes (concurrently: no
 * trimesh lock unless the other is a mesh without pieces), the contacts
 * together reduced to the pair's manifold. Each side's pieces are placed
 * once and first culled against the other's bounding sphere. */
#define PIECE_BUF 64
#define PIECE_STACK 64
static int collide_pieces(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                          const sc_shape *b, const sc_pose *pb, double merge, sc_contact *out,
                          int max, double stop)
{
    sc_contact c[PIECE_BUF + SC_MAX_PAIR_CONTACTS];
    placed_piece stack[PIECE_STACK], *pp = stack;
    int na = a->npieces ? a->npieces : 1, nb = b->npieces ? b->npieces : 1;
    if (na + nb > PIECE_STACK &&
        !(pp = sc_arena_alloc(&ctx->arena, (size_t)(na + nb) * sizeof *pp)))
        return SC_ENOMEM;
    placed_piece *qa = pp, *qb = pp + na;
    double Ra[9], Rb[9];             /* every piece turns as its body */
    int ma = pieces_near(a, pa, pb->pos, b->bound_r, qa, Ra);
    int mb = pieces_near(b, pb, pa->pos, a->bound_r, qb, Rb);
    int n = 0, rc = SC_OK, deep = 0;
    for (int i = 0; i < ma && rc == SC_OK && !deep; i++)
        for (int j = 0; j < mb && rc == SC_OK && !deep; j++) {
            double d[3], r = qa[i].r + qb[j].r;
            v3_sub(d, qa[i].q.pos, qb[j].q.pos);
            if (v3_dot(d, d) > r * r)
                continue;
            /* most pieces whose balls overlap are apart: a face plane
             * that parts them says so faster than ODE's collider finds no
             * contact */
            if (sc_poly_apart(qa[i].s, Ra, qa[i].q.pos, qb[j].s, Rb, qb[j].q.pos))
                continue;
            int k = sc_np_collide(ctx, qa[i].s, &qa[i].q, qb[j].s, &qb[j].q, &c[n],
                                  SC_MAX_PAIR_CONTACTS);
            if (k < 0) {
                rc = k;
                break;
            }
            /* deeper than stop: the caller asks no more than this */
            for (int q = n; q < n + k; q++)
                deep |= c[q].depth > stop;
            n += k;
            if (n > PIECE_BUF)
                n = sc_manifold_reduce(c, n, merge);
        }
    if (pp != stack)
        sc_arena_free(&ctx->arena, pp);
    return rc == SC_OK ? emit(c, n, merge, out, max) : rc;
}

/* Whether a and b (their representations ra, rb: choose_reps()) are a
 * triangle mesh and a plane, which meet by their vertices alone. */
static int mesh_on_plane(const sc_shape *a, int ra, const sc_shape *b, int rb)
{
    return (ra == REP_TRIMESH && b->kind == SC_SHAPE_PLANE) ||
           (rb == REP_TRIMESH && a->kind == SC_SHAPE_PLANE);
}

/* The deepest vertex of a mesh inside a plane, as the deepest of
 * mesh_plane()'s contacts (the manifold keeps the deepest point and its
 * depth as it is), without making them; it stops at the first vertex
 * deeper than stop. */
static double mesh_plane_deepest(const sc_shape *m, const sc_pose *pm, const sc_shape *pl,
                                 const sc_pose *pp, double stop)
{
    double n[3], R[9], nl[3], dl, deepest = -1;
    if (!plane_in_mesh(m, pm, pl, pp, n, R, nl, &dl))
        return -1;
#ifdef __SSE2__
    /* as mesh_plane(): two at a time, then in order */
    const __m128d ax = _mm_set1_pd(nl[0]), ay = _mm_set1_pd(nl[1]), az = _mm_set1_pd(nl[2]);
    const __m128d dv = _mm_set1_pd(dl), zero = _mm_setzero_pd();
    for (int p = 0; 2 * p < m->nverts && !(deepest > stop); p++) {
        __m128d d2 = _mm_sub_pd(dv, v3_dot2(ax, ay, az, &m->xyz_soa[6 * p]));
        if (!_mm_movemask_pd(_mm_cmpgt_pd(d2, zero)))
            continue;
        double two[2];
        _mm_storeu_pd(two, d2);
        for (int j = 0; j < 2 && 2 * p + j < m->nverts && !(deepest > stop); j++)
            if (two[j] > 0 && two[j] > deepest)
                deepest = two[j];
    }
#else
    for (int i = 0; i < m->nverts && !(deepest > stop); i++) {
        double depth = dl - v3_dot(nl, &m->xyz[3 * i]);
        if (depth > 0 && depth > deepest)
            deepest = depth;
    }
#endif
    return deepest;
}

int sc_np_deepest_until(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                        const sc_shape *b, const sc_pose *pb, double stop, double *depth)
{
    if (!ctx || !a || !b || !pa || !pb || !depth)
        return SC_EINVAL;
    if (!pose_ok(pa) || !pose_ok(pb))
        return SC_EINVAL;
    int ra, rb;
    choose_reps(a, b, &ra, &rb);
    if (mesh_on_plane(a, ra, b, rb)) {
        *depth = a->kind == SC_SHAPE_PLANE ? mesh_plane_deepest(b, pb, a, pa, stop)
                                           : mesh_plane_deepest(a, pa, b, pb, stop);
        return SC_OK;
    }
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    int k = sc_np_collide_until(ctx, a, pa, b, pb, c, SC_MAX_PAIR_CONTACTS, stop);
    if (k < 0)
        return k;
    *depth = -1;
    for (int i = 0; i < k; i++)
        if (c[i].depth > *depth)
            *depth = c[i].depth;
    return SC_OK;
}

/* ---- two convex shapes: ODE's collider, with a faster support ----
 *
 * Debian's ODE meets two dConvex geoms in dCollideConvexConvexCCD: libccd's
 * MPR penetration (500 iterations, tolerance 1e-6) over a support function
 * that turns the direction into the shape's frame by the geom's quaternion,
 * takes the first vertex of largest projection and turns it back; that
 * support function is a large share of a pile's narrow phase. The same
 * query is made here with the same libccd, the same settings, the geom's
 * own position and quaternion (read back from ODE, which keeps a matrix)
 * and the same arithmetic, the vertices taken two at a time from the
 * shape's copy by pairs: the same contact to the bit, only faster. */
typedef struct mpr_shape {
    ccd_vec3_t pos;
    ccd_quat_t rot, rot_inv;
    const sc_shape *s;
} mpr_shape;

static void mpr_support(const void *obj, const ccd_vec3_t *dir_, ccd_vec3_t *v)
{
    const mpr_shape *c = obj;
    const sc_shape *s = c->s;
    ccd_vec3_t dir;
    ccdVec3Copy(&dir, dir_);
    ccdQuatRotVec(&dir, &c->rot_inv);
    /* the first vertex whose projection is the largest (dot > max, as
     * ODE's loop: NaN never wins) */
    int best = -1;
#ifdef __SSE2__
    const __m128d dx = _mm_set1_pd(dir.v[0]), dy = _mm_set1_pd(dir.v[1]),
                  dz = _mm_set1_pd(dir.v[2]);
    __m128d m = _mm_set1_pd(-CCD_REAL_MAX), idx = _mm_set1_pd(-1), at = _mm_set_pd(1, 0);
    const __m128d two = _mm_set1_pd(2);
    for (int p = 0; 2 * p < s->nverts; p++, at = _mm_add_pd(at, two)) {
        /* ccdVec3Dot(dir, p): dir first, summed x, y, z, as v3_dot() */
        __m128d d = v3_dot2(dx, dy, dz, &s->xyz_soa[6 * p]);
        __m128d up = _mm_cmpgt_pd(d, m);
        m = _mm_or_pd(_mm_and_pd(up, d), _mm_andnot_pd(up, m));
        idx = _mm_or_pd(_mm_and_pd(up, at), _mm_andnot_pd(up, idx));
    }
    double mv[2], iv[2];
    _mm_storeu_pd(mv, m);
    _mm_storeu_pd(iv, idx);
    /* the lanes hold the even and the odd vertices: the larger, and on a
     * tie the first (the padding repeats the last vertex, never first) */
    int i0 = (int)iv[0], i1 = (int)iv[1];
    if (i0 >= 0 && (i1 < 0 || mv[0] > mv[1] || (mv[0] == mv[1] && i0 < i1)))
        best = i0;
    else if (i1 >= 0)
        best = i1;
    if (best >= s->nverts)
        best = s->nverts - 1;
#else
    double maxdot = -CCD_REAL_MAX;
    for (int i = 0; i < s->nverts; i++) {
        ccd_vec3_t p;
        ccdVec3Set(&p, s->xyz[3 * i], s->xyz[3 * i + 1], s->xyz[3 * i + 2]);
        double dot = ccdVec3Dot(&dir, &p);
        if (dot > maxdot) {
            best = i;
            maxdot = dot;
        }
    }
#endif
    if (best >= 0)
        ccdVec3Set(v, s->xyz[3 * best], s->xyz[3 * best + 1], s->xyz[3 * best + 2]);
    ccdQuatRotVec(v, &c->rot);
    ccdVec3Add(v, &c->pos);
}

static void mpr_centre(const void *obj, ccd_vec3_t *c)
{
    ccdVec3Copy(c, &((const mpr_shape *)obj)->pos);
}

/* As ODE's ccdGeomToObj(): the geom's position and quaternion. */
static void mpr_shape_of(const sc_ode *o, dGeomID g, const sc_shape *s, mpr_shape *m)
{
    const dReal *pos = o->dGeomGetPosition(g);
    dQuaternion q;
    o->dGeomGetQuaternion(g, q);
    ccdVec3Set(&m->pos, pos[0], pos[1], pos[2]);
    ccdQuatSet(&m->rot, q[1], q[2], q[3], q[0]);
    ccdQuatInvert2(&m->rot_inv, &m->rot);
    m->s = s;
}

/* dCollide() of two placed dConvex geoms, as dCollideConvexConvexCCD()
 * answers it: 0 or 1 contact. */
static int convex_convex(const sc_ode *o, dGeomID ga, const sc_shape *a, dGeomID gb,
                         const sc_shape *b, dContactGeom *c)
{
    mpr_shape sa, sb;
    mpr_shape_of(o, ga, a, &sa);
    mpr_shape_of(o, gb, b, &sb);
    ccd_t ccd;
    CCD_INIT(&ccd);
    ccd.support1 = mpr_support;
    ccd.support2 = mpr_support;
    ccd.center1 = mpr_centre;
    ccd.center2 = mpr_centre;
    ccd.max_iterations = 500;
    ccd.mpr_tolerance = (ccd_real_t)1E-6;
    ccd_real_t depth;
    ccd_vec3_t dir, pos;
    if (ccdMPRPenetration(&sa, &sb, &ccd, &depth, &dir, &pos) != 0)
        return 0;
    memset(c, 0, sizeof *c);
    c->g1 = ga;
    c->g2 = gb;
    c->side1 = c->side2 = -1;
    c->depth = depth;
    for (int k = 0; k < 3; k++)
        c->pos[k] = pos.v[k];
    ccdVec3Scale(&dir, -1.);
    for (int k = 0; k < 3; k++)
        c->normal[k] = dir.v[k];
    return 1;
}

/* The thread's ODE set up and the pair's geoms (representations ra, rb)
 * placed at pa and pb. */
static int placed_geoms(sc_np_ctx *ctx, const sc_shape *a, int ra, const sc_pose *pa,
                        const sc_shape *b, int rb, const sc_pose *pb, dGeomID *ga, dGeomID *gb)
{
    const sc_ode *o = ctx->ode;
    if (sc_ode_is_private(o))
        o->dAllocateODEDataForThread(dAllocateMaskAll);
    else
        sc_ode_thread_init();
    *ga = get_geom(ctx, a, 0, ra);
    *gb = get_geom(ctx, b, 1, rb);
    if (!*ga || !*gb)
        return SC_ENOMEM;
    place(o, *ga, a, pa);
    place(o, *gb, b, pb);
    return SC_OK;
}

int sc_np_convex_raw(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                     const sc_pose *pb, int via_ode, sc_contact *c)
{
    if (!ctx || !a || !b || !pa || !pb || !c || !pose_ok(pa) || !pose_ok(pb))
        return SC_EINVAL;
    int ra, rb;
    choose_reps(a, b, &ra, &rb);
    if (ra != REP_CONVEX || rb != REP_CONVEX || !a->xyz_soa || !b->xyz_soa)
        return SC_EINVAL;
    const sc_ode *o = ctx->ode;
    dGeomID ga, gb;
    if (placed_geoms(ctx, a, ra, pa, b, rb, pb, &ga, &gb) != SC_OK)
        return SC_ENOMEM;
    dContactGeom raw[RAW_CONTACTS];
    int n = via_ode ? o->dCollide(ga, gb, RAW_CONTACTS, raw, sizeof raw[0])
                    : convex_convex(o, ga, a, gb, b, raw);
    if (n > 0) {
        c->body_a = c->body_b = -1;
        v3_copy(c->pos, raw[0].pos);
        v3_copy(c->normal, raw[0].normal);
        c->depth = raw[0].depth;
    }
    return n > 0;
}

int sc_np_collide(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                  const sc_pose *pb, sc_contact *out, int max)
{
    return sc_np_collide_until(ctx, a, pa, b, pb, out, max, INFINITY);
}

int sc_np_collide_until(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                        const sc_shape *b, const sc_pose *pb, sc_contact *out, int max,
                        double stop)
{
    if (!ctx || !a || !b || !pa || !pb || (!out && max > 0) || max < 0)
        return SC_EINVAL;
    if (!pose_ok(pa) || !pose_ok(pb))
        return SC_EINVAL;
    if (a->kind == SC_SHAPE_PLANE && b->kind == SC_SHAPE_PLANE)
        return 0;
    int ra, rb;
    choose_reps(a, b, &ra, &rb);
    double size = min_d(a->bound_r, b->bound_r);
    double merge = 1e-3 * (isfinite(size) ? size : 1);
    if (mesh_on_plane(a, ra, b, rb)) {   /* no ODE needed */
        sc_contact c[MESH_PLANE_BUF];
        int n = a->kind == SC_SHAPE_PLANE ? mesh_plane(b, pb, a, pa, 1, c, merge)
                                          : mesh_plane(a, pa, b, pb, 0, c, merge);
        return emit(c, n, merge, out, max);
    }
    if (a->npieces || b->npieces)
        return collide_pieces(ctx, a, pa, b, pb, merge, out, max, stop);
    const sc_ode *o = ctx->ode;
    dGeomID ga, gb;
    if (placed_geoms(ctx, a, ra, pa, b, rb, pb, &ga, &gb) != SC_OK)
        return SC_ENOMEM;
    dContactGeom raw[RAW_CONTACTS];
    int lock = (ra == REP_TRIMESH || rb == REP_TRIMESH) && !sc_ode_is_private(o);
    int n;
    if (ra == REP_CONVEX && rb == REP_CONVEX && a->xyz_soa && b->xyz_soa) {
        n = convex_convex(o, ga, a, gb, b, raw);
    } else {
        if (lock)
            pthread_mutex_lock(&ode_trimesh_lock);
        n = o->dCollide(ga, gb, RAW_CONTACTS, raw, sizeof raw[0]);
        if (lock)
            pthread_mutex_unlock(&ode_trimesh_lock);
    }
    if (n <= 0)
        return 0;
    sc_contact c[RAW_CONTACTS];
    for (int i = 0; i < n; i++) {
        c[i].body_a = c[i].body_b = -1;
        v3_copy(c[i].pos, raw[i].pos);
        v3_scale(c[i].normal, raw[i].normal, -1.0);
        c[i].depth = raw[i].depth;
    }
    /* ODE's convex-convex and convex-box colliders give one point (docs/DESIGN.md
     * section 3.3): a face resting on a face gets its whole footprint by
     * clipping (polyhedron.c). Box-box is native and gives several. */
    if (ra == REP_CONVEX || rb == REP_CONVEX) {
        double deepest = 0;
        for (int i = 0; i < n; i++)
            deepest = max_d(deepest, c[i].depth);
        sc_contact clip[RAW_CONTACTS];
        int k = sc_poly_clip(a, pa, b, pb, deepest, clip, RAW_CONTACTS);
        if (k > 0)
            return emit(clip, k, merge, out, max);
        /* a mesh piece's inner face is no way out: push out through the
         * shallowest outer face instead, or not at all */
        double back[3];
        v3_scale(back, c[0].normal, -1);
        if (inner_normal(a, pa, c[0].normal) || inner_normal(b, pb, back)) {
            k = sc_poly_clip(a, pa, b, pb, INFINITY, clip, RAW_CONTACTS);
            return k > 0 ? emit(clip, k, merge, out, max) : 0;
        }
    }
    return emit(c, n, merge, out, max);
}

SC_API int sc_collide(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                      const sc_pose *pb, sc_contact *out, int max)
{
    sc_np_ctx *ctx = sc_np_create();
    if (!ctx)
        return SC_ENOMEM;
    int n = sc_np_collide(ctx, a, pa, b, pb, out, max);
    sc_np_destroy(ctx);
    return n;
}
