/*
 * core.h - what the physics core's files share and do not export
 * (docs/DESIGN.md section 2). The core knows nothing of threads or
 * networks. Every symbol here is hidden (-fvisibility=hidden); only SC_API
 * ones leave the shared object.
 */
#ifndef SC_CORE_H
#define SC_CORE_H
#include <assert.h>
#include <math.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "simcluster.h"
#include "arena.h"

/* fmax() and fmin() with the same result for every input (NaN and signed
 * zeros included: the first operand on a tie, the other one where one is
 * NaN), inline: they sit in the inner loops, where libm's calls cost. */
static inline double max_d(double a, double b) { return a >= b || (b != b && a == a) ? a : b; }
static inline double min_d(double a, double b) { return a <= b || (b != b && a == a) ? a : b; }

/* FNV-1a over n bytes at p, continuing from h (SC_FNV_OFFSET to start):
 * shapes' content hashes, the world's state hash, the friction fixed
 * point's cycle test. */
#define SC_FNV_OFFSET 0xcbf29ce484222325ULL
static inline uint64_t sc_fnv1a(uint64_t h, const void *p, size_t n)
{
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++) {
        h ^= c[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

/* Internal invariants only, never bad input (that gets an SC_E* code). */
#define SC_ASSERT(c) assert(c)

/* The cookies of sc_world_config_default() and sc_body_desc_default(). */
#define SC_CONFIG_COOKIE 0x5c0f1a
#define SC_BODY_COOKIE 0x5cb0d1

/* Record err as this thread's last error (see sc_last_error()); returns err. */
int sc_set_error(int err);

/* Checked allocation helpers: NULL on overflow or failure. */
void *sc_alloc_array(size_t n, size_t size);
void *sc_calloc_array(size_t n, size_t size);
/* Grow the array *p (capacity *cap items of size bytes) to hold need items,
 * doubling, never past max items: SC_OK, SC_ETOOBIG or SC_ENOMEM (then *p
 * and *cap are unchanged). */
int sc_grow(void **p, int *cap, int need, size_t size, int max);

static inline int sc_finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* ---- shapes ---- */
struct sc_shape {
    atomic_int refs;
    int kind;                 /* SC_SHAPE_* */
    double radius;            /* sphere */
    double half[3];           /* box */
    double plane[4];          /* plane: n (unit), d */
    /* SC_SHAPE_MESH and SC_SHAPE_CONVEX: outward triangles */
    int nverts, ntris;
    double *xyz;
    double *xyz_soa;          /* meshes: the vertices by pairs, x0 x1 y0 y1 z0 z1
                                 ..., the last pair padded with the last vertex
                                 (sc_soa_pairs(); the mesh-plane loops) */
    int *tri;
    int convex;               /* 1 if the mesh is convex (hulls always) */
    sc_mass_props mp;         /* per unit density */
    double bound_r;           /* about the shape origin */
    uint64_t hash;            /* content hash (cluster shape cache) */
    /* ODE data built once at creation, read-only afterwards */
    void *ode_tridata;        /* dTriMeshDataID for meshes and hulls */
    unsigned *ode_index;      /* dTriIndex copy of tri */
    double *ode_planes;       /* dConvex: 4 per triangle */
    unsigned *ode_polys;      /* dConvex: 3, i, j, k per triangle */
    /* boxes and convex meshes: polygon faces (coplanar triangles merged)
     * for the face-clipping manifold (polyhedron.c); nfaces 0 if none */
    int nfaces;
    int nface_xyz;
    double *face_xyz;         /* corners, 3 per point, shape frame */
    double *face_soa;         /* the same corners by pairs, x0 x1 y0 y1 z0 z1
                                 ..., the last pair padded with the last
                                 corner (polyhedron.c corners_min()) */
    double *face_plane;       /* 4 per face: outward unit normal, offset */
    double *face_plane_soa;   /* the same by pairs of faces, nx0 nx1 ny0 ny1 nz0
                                 nz1 d0 d1 ..., the last pair padded with the
                                 last face (ball_beyond_face()) */
    int *face_start;          /* face f: face_vert[face_start[f] .. face_start[f + 1]) */
    int *face_vert;           /* corner indices, counter-clockwise seen from out */
    unsigned char *face_inner; /* a mesh's convex piece: 1 for each face inside
                                  the mesh (on another piece); NULL if none */
    /* meshes: convex pieces the colliders use instead of the triangles
     * (docs/DESIGN.md 3.3); npieces 0 if none. Piece k is the hull of
     * piece_count[k] points of piece_pts (shape frame), which the hash and
     * the wire cover. pieces[k] is built about its points' mean (ODE's
     * dConvex needs its origin inside), which piece_ball[4k..] holds
     * (shape frame), then the piece's bounding radius about it. */
    int npieces;
    struct sc_shape **pieces;
    double *piece_ball;
    double *piece_pts;
    int *piece_count;
    int npiece_pts;
};

/* The points a mesh's convex pieces are built from: piece k is the hull
 * of count[k] points, 3 doubles each, taken in order from pts. */
typedef struct sc_piece_set {
    const double *pts;
    const int *count;
    int n;
} sc_piece_set;

/* A builder's mesh moved so its centre of mass is the origin; takes
 * ownership of xyz and tri. NULL on error (sc_last_error()). */
sc_shape *sc_shape_mesh_centered(double *xyz, int nverts, int *tri, int ntris,
                                 const sc_piece_set *pieces);
/* A shape from the content its hash covers (received by a daemon); the
 * arrays are copied. NULL on error (sc_last_error()). */
sc_shape *sc_shape_rebuild(int kind, double radius, const double half[3], const double plane[4],
                           const double *xyz, int nverts, const int *tri, int ntris,
                           const sc_piece_set *pieces);

/* ODE: process-wide initialisation (once) and the calling thread's ODE data
 * (idempotent, cheap); both needed before any ODE collision call. */
void sc_ode_init(void);
void sc_ode_thread_init(void);
/* ODE messages (warnings) raised in the calling thread so far. */
long sc_ode_message_count(void);

/* ---- bodies (world.c owns them; the stages read and update them) ---- */
typedef struct sc_body {
    /* dynamics are kept at the centre of mass; the shape frame is derived */
    sc_shape *shape;
    double mass, inv_mass;          /* 0 inverse mass = static */
    double inertia[9];              /* about the centre of mass, body frame */
    double inv_inertia[9];
    double com[3];                  /* centre of mass in the shape frame */
    double x[3], q[4];              /* centre of mass position, orientation */
    double v[3], w[3];              /* of the centre of mass, world frame */
    double force[3], torque[3];     /* user forces for the next frame */
    double restitution, friction;
    int state;
    /* per substep, set by the world before the contact solve */
    double v0[3], w0[3];            /* velocity before gravity (restitution) */
    double iw[9];                   /* world-frame inverse inertia */
    double rest_s;                  /* how long it has been slow (sleep) */
    int collided;                   /* 2: collision in this substep, 1: earlier
                                       in this frame, 0: none this frame */
} sc_body;

/* Shared tasks (docs/DESIGN.md 5.3): tasks 0 .. count - 1 of a batch,
 * each run once as fn(arg, i, a, helper) by the thread that takes it,
 * with scratch from that thread's arena a (helper: 1 when it is not the
 * thread that handed the batch out). A task writes only its own outputs,
 * so the result does not depend on who ran which. */
typedef void (*sc_task_fn)(void *arg, int i, sc_arena *a, int helper);
/* Runs tasks [0, count) of a batch (the calling thread with arena a, and
 * idle threads of its pool) and returns when all are done. */
typedef struct sc_task_runner {
    void (*run)(void *ctx, sc_task_fn fn, void *arg, int count, sc_arena *a);
    void *ctx;
} sc_task_runner;
/* Work over a frame's bodies is shared with a runner from this many
 * bodies on, in this many tasks (integrate.c, detect.c, broadphase.c) */
#define SC_SHARE_MIN 256
#define SC_SHARE_CHUNKS 8
/* Tasks [0, count) of a batch: handed to r when there is one and more
 * than one task, else run here one after another (helper 0). */
static inline void sc_tasks_run(const sc_task_runner *r, sc_task_fn fn, void *arg, int count,
                                sc_arena *a)
{
    if (r && count > 1)
        r->run(r->ctx, fn, arg, count, a);
    else
        for (int i = 0; i < count; i++)
            fn(arg, i, a, 0);
}

/* A split island's blocks of one colour (contact.c; no two share a
 * movable body), to be solved anywhere, in any order: each is run by
 * sc_block_run() with scratch from the arena of whoever runs it, reads and
 * writes only its own rows and its bodies' local velocities, so the result
 * is the same bits whoever ran which (docs/DESIGN.md 11, shared blocks). */
typedef struct sc_block_batch sc_block_batch;
/* Block i of the batch (an sc_block_batch; 0 <= i < its count): passed
 * over when it is close enough to its answer, else solved with scratch
 * from a; helper: 1 when a thread other than the island's runs it
 * (counted). An sc_task_fn. */
void sc_block_run(void *batch, int i, sc_arena *a, int helper);

/* The most sweeps block Gauss-Seidel's Anderson acceleration remembers. */
#define SC_ANDERSON_MAX 8

/* Contact model constants (Baraff's velocity-level LCP, the paper's states)
 * and the solver's settings (docs/DESIGN.md section 11). */
typedef struct sc_contact_params {
    double bounce_speed;            /* m/s: approach faster = collision (restitution),
                                       slower = resting contact (e = 0) */
    double slop;                    /* m of penetration left alone */
    double baumgarte;               /* fraction of the rest removed per substep */
    double push_tol;                /* m: depth past which the push-out takes
                                       out all of the excess in one substep
                                       (0: none, baumgarte throughout) */
    int split_contacts;             /* islands with more contacts are split into
                                       blocks (block Gauss-Seidel); 0: never */
    int block_contacts;             /* contacts per block (whole pairs) */
    double tol;                     /* outer residual to reach, m/s */
    int max_sweeps;                 /* outer sweeps at most */
    int anderson;                   /* block Gauss-Seidel's Anderson
                                       acceleration: sweeps remembered, 0
                                       (plain) to SC_ANDERSON_MAX */
    int island_method;              /* SC_ISLAND_*: how a split island is solved */
    int cold;                       /* benchmarks: no warm starts (every solve
                                       from z = 0) */
    double gravity[3];              /* m/s^2: the push-out's lift (its potential
                                       energy) is paid from the island's
                                       kinetic energy (contact.c) */
    int impact_first;               /* 1: an island's collisions are solved
                                       first, at the substep's start, then its
                                       resting contacts under the forces (the
                                       local mode, docs/DESIGN.md 3.4); 0: one
                                       LCP of both (the paper's, world mode) */
    int inject;                     /* tests only: SC_INJECT_* faults */
    const sc_task_runner *runner;   /* NULL: a split island's blocks are
                                       solved one after another; else each
                                       colour's go to the runner (not sent:
                                       a daemon sets its own) */
} sc_contact_params;

/* Faults a test can inject (sc_contact_params.inject), one per fallback. */
enum {
    SC_INJECT_COUPLED = 1,          /* the coupled friction LCP fails */
    SC_INJECT_STAGGERED = 2,        /* the staggered solve fails too */
    SC_INJECT_BLOCK = 4,            /* every block's Dantzig solve fails */
    SC_INJECT_NAN = 8,              /* a NaN appears in the island's data */
    SC_INJECT_ROUNDS = 16,          /* a whole solve's fixed-point rounds fail */
    SC_INJECT_ACTIVE_SET = 32,      /* the active set does not settle */
};

/* A contact's warm start (its impulse and the substep that impulse acted
 * over) taken from another. */
static inline void sc_impulse_copy(sc_contact *to, const sc_contact *from)
{
    memcpy(to->impulse, from->impulse, sizeof to->impulse);
    to->impulse_dt = from->impulse_dt;
}

typedef struct sc_solve_info {
    int solves;                     /* islands solved */
    long pivots;
    int failures;                   /* coupled friction LCPs that failed even
                                       regularised (solved staggered) */
    int regularised;                /* LCPs solved only after regularisation */
    int lemke;                      /* solved by the Lemke fallback */
    int guessed;                    /* friction solved from projected
                                       Gauss-Seidel's iterate after the fixed
                                       point and Lemke failed (lcp.c) */
    int collisions;                 /* contacts resolved with restitution */
    int split;                      /* islands solved by blocks */
    int split_fallbacks;            /* of them, exact islands whose staggered
                                       solve failed too */
    int blocks;                     /* block solves (blocks x sweeps) */
    long blocks_shared;             /* of blocks, solved by a helping thread
                                       (depends on timing, the result not) */
    int block_fallbacks;            /* block solves that failed: projected
                                       Gauss-Seidel on the block instead */
    int nan_islands;                /* islands with non-finite data: no impulse */
    int inelastic;                  /* islands whose elastic answer added energy:
                                       solved again with e = 0 */
    int energy_refused;             /* of failures, coupled friction answers the
                                       solver found but that added kinetic
                                       energy of their own (refused, solved
                                       staggered) */
    int restitution_scaled;         /* coupled friction answers whose
                                       restitution targets added energy,
                                       solved again with them scaled down */
    int sweeps_max;                 /* most outer sweeps of one split island */
    int sweeps;                     /* outer sweeps of the split islands, summed */
    int unconverged;                /* split islands still short of tol after
                                       their sweeps, whole tries and sweeps on */
    int diverged;                   /* split islands that ended short of tol on a
                                       diverging sweep (on the best iterate) */
    int whole_tries;                /* tries of small split islands that block
                                       Gauss-Seidel left short of tol, solved
                                       whole, and of split islands still short
                                       at the cap (contact.c LAST_MAX_ROWS) */
    int whole_solved;               /* of them, those the whole solve settled */
    int cold_starts;                /* split solves that started from 0: the
                                       warm start was further from the answer */
    int as_solves;                  /* split islands solved whole by the active
                                       set (island_sparse.c) */
    int as_fallbacks;               /* of them, those it did not settle: block
                                       Gauss-Seidel instead */
    long as_iterations;             /* guesses factored, summed */
    int as_iterations_max;          /* most of one solve */
    long factor_nnz_max;            /* entries of the largest factor */
    int as_parts_max;               /* most subdomains of one solve
                                       (SC_ISLAND_SUBDOMAINS; 1: one factor) */
    int as_interface_max;           /* largest interface, unknowns */
    long as_exchanges;              /* rounds the subdomains would exchange
                                       with a master, summed over solves */
    long as_exchange_bytes;         /* the bytes of those rounds, both ways */
    double residual_exact;          /* largest LCP residual of an exact island, m/s */
    double residual_split;          /* largest outer residual of a split island, m/s */
} sc_solve_info;

/* Contact impulses for one island (the paper's step 7): the velocity LCP
 * with restitution and Coulomb friction (boxed), then a split-impulse
 * position correction that moves bodies out of deep penetration without
 * touching velocities. bodies[*].v/w hold u* (gravity applied), v0/w0 the
 * velocities before it, iw the world inverse inertia. ci lists the
 * island's contact indices into c; their impulse fields hold the warm
 * start (last solve's impulses, matched) and get this solve's. Updates v,
 * w (and x, q by h * pseudo velocity). Fails only for bad arguments or
 * memory: numerical trouble takes a counted fallback (info). */
int sc_island_solve(sc_arena *a, sc_body *bodies, sc_contact *c, const int *ci, int nc,
                    double h, const sc_contact_params *p, sc_solve_info *info);

/* ---- narrow phase (narrowphase.c, manifold.c) ---- */

/* A copy of libode (ode_copy.c). The process's linked copy is shared by
 * every thread and serialises trimesh pairs (Debian's ODE keeps its
 * trimesh collider cache in a global); worker threads take a private copy
 * loaded with dlmopen() into its own link namespace when one can be had, so
 * their trimesh pairs run concurrently. Copies are process-wide and kept
 * (glibc cannot reliably unload a namespace, and allows only a few). */
typedef struct sc_ode sc_ode;
const sc_ode *sc_ode_shared(void);
/* 1 when o is a private copy (no lock needed). */
int sc_ode_is_private(const sc_ode *o);

typedef struct sc_np_ctx sc_np_ctx;     /* one per thread: owns ODE geoms */
/* The thread's scratch arena (island solves), reset by sc_unit_run(). */
sc_arena *sc_np_arena(sc_np_ctx *ctx);
/* The runner that shares the thread's split-island blocks with idle
 * threads (node_local.c), NULL: none (blocks solved one after another). */
const sc_task_runner *sc_np_runner(const sc_np_ctx *ctx);
void sc_np_set_runner(sc_np_ctx *ctx, const sc_task_runner *r);
/* A slot for the thread's motion-group scratch (group.c), freed with the
 * context by free_fn. */
void **sc_np_scratch(sc_np_ctx *ctx, void (**free_fn)(void *));
sc_np_ctx *sc_np_create(void);          /* on the shared copy of ODE */
sc_np_ctx *sc_np_create_on(const sc_ode *ode);
void sc_np_destroy(sc_np_ctx *ctx);
/* Contacts of a at pa with b at pb, normals from a to b, reduced to at most
 * SC_MAX_PAIR_CONTACTS; returns how many were written (<= max) or a code. */
int sc_np_collide(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                  const sc_shape *b, const sc_pose *pb, sc_contact *out, int max);
/* The same, for a caller that only asks whether the deepest contact is
 * deeper than stop: a shape with convex pieces stops at the first pair of
 * pieces with a contact deeper than stop, and returns what it has (its
 * deepest is then deeper than stop, not the deepest of all). Otherwise
 * the same contacts as sc_np_collide(). */
int sc_np_collide_until(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                        const sc_shape *b, const sc_pose *pb, sc_contact *out, int max,
                        double stop);
/* The deepest of sc_np_collide_until()'s contacts into *depth (-1: none),
 * the same value; a mesh on a plane without making the contacts (its
 * deepest vertex, the first deeper than stop). */
int sc_np_deepest_until(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                        const sc_shape *b, const sc_pose *pb, double stop, double *depth);
/* The raw contact of two convex shapes (each a convex mesh, hull or mesh
 * piece) before clipping and reduction, normal as ODE gives it (from b to
 * a): by this library's MPR (via_ode 0, what the narrow phase uses) or by
 * ODE's dCollide() (1); 1 if they touch, 0 if not, or a code. Tests compare
 * the two to the bit. */
int sc_np_convex_raw(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                     const sc_pose *pb, int via_ode, sc_contact *c);
/* Reduce n raw contacts in place to at most SC_MAX_PAIR_CONTACTS well-spread
 * ones (points closer than merge_dist merged); returns the new count. */
int sc_manifold_reduce(sc_contact *c, int n, double merge_dist);

/* Polygon faces of a box or convex mesh s (others: none), built once with
 * the shape: SC_OK (also when s is too big to merge faces: then none) or
 * SC_ENOMEM. sc_poly_free() frees them. */
int sc_poly_build(sc_shape *s);
void sc_poly_free(sc_shape *s);
/* n records of width doubles (points: 3, planes: 4) by pairs for two-wide
 * loops: x0 x1 y0 y1 z0 z1 ..., the last pair padded with the last
 * record; malloc'd, NULL when n is 0 or out of memory. */
double *sc_soa_pairs(const double *src, int n, int width);
/* 1 if a face plane of a or b (inner faces of a mesh's pieces included)
 * has all the other's corners beyond it: apart for sure; 0 when none does
 * (touching, or parted only along an edge-edge axis), or either lacks faces.
 * Ra, Rb: the rotations of the shapes at positions pa, pb (q_to_m3() of
 * their quaternions: a mesh's pieces share their body's). */
int sc_poly_apart(const sc_shape *a, const double Ra[9], const double pa[3], const sc_shape *b,
                  const double Rb[9], const double pb[3]);
/* The same, each corner more than margin (m) beyond the plane or the
 * ball more than margin beyond it: the shapes are then more than margin
 * apart. */
int sc_poly_apart_by(const sc_shape *a, const double Ra[9], const double pa[3],
                     const sc_shape *b, const double Rb[9], const double pb[3], double margin);
/* 1 if a at pa and b at pb are for sure more than margin (m) apart: every
 * pair of their convex pieces (a shape without pieces is one) has its
 * bounding balls, or a face plane of one (sc_poly_apart_by()), that far
 * apart; 0 when that does not show it (closer, or a shape without faces
 * whose ball is not that far, or a plane). The motion groups' check. */
int sc_np_apart_by(const sc_shape *a, const sc_pose *pa, const sc_shape *b, const sc_pose *pb,
                   double margin);
/* The contacts of an overlapping convex pair (the collider's deepest
 * point depth deep) by clipping: the face of least penetration of either
 * shape is the reference, the other shape's face most opposed to it is
 * clipped by its sides; up to max points, each with its own depth, normals
 * from a to b. Returns 0 (keep the collider's contacts) when a shape has
 * no faces, is too big, or an edge-edge axis is clearly shallower. */
int sc_poly_clip(const sc_shape *a, const sc_pose *pa, const sc_shape *b, const sc_pose *pb,
                 double depth, sc_contact *out, int max);

/* The whole file at path in a malloc'd buffer (*out, *len bytes; pipes are
 * read to their end too): SC_OK, SC_ETOOBIG past max bytes, SC_ENOMEM, or
 * SC_EIO with errno saying why (EISDIR for a folder). */
int sc_read_file(const char *path, size_t max, unsigned char **out, size_t *len);

/* How far any point of s can move between poses p0 and p1 (translation
 * plus rotation angle times the bounding radius; 0 for planes), and the
 * smallest feature of s a motion must not skip in one step (toi.c). */
double sc_toi_sweep(const sc_shape *s, const sc_pose *p0, const sc_pose *p1);
/* The pose at t in [0, 1] between p0 and p1: position lerped, rotation
 * slerped (the motion time of impact assumes). */
void sc_pose_lerp(sc_pose *r, const sc_pose *p0, const sc_pose *p1, double t);
double sc_toi_feature(const sc_shape *s);

/* sc_toi() with the caller's (per-thread) narrow-phase context. */
int sc_toi_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
               const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
               double *t);

/* Back-ups aim at this share of the contact tolerance: the backed-up
 * substep's impulses and push-out differ a little from the path the
 * search interpolated. */
#define SC_TOI_AIM 0.9

/* For a pair already in contact: the last time in [0, 1] at which its
 * penetration is still <= limit_m, when it exceeds limit_m later (1 and
 * *t), 0 when it never does. limit_m is the aim, SC_TOI_AIM of the
 * tolerance: a pair deeper than it at t = 0 is held to the tolerance, or
 * past the tolerance to its depth there plus a hundredth of it (the
 * sort-out's limits, impact.c), unless it is deeper than twice limit_m
 * (0: left to the push-out). */
int sc_toi_deepen_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double limit_m,
                      double *t);

/* The same, looking only at samples that start before tmax (a time in
 * [0, 1]): a pair whose answer would be earlier than tmax gets exactly the
 * answer of the full search; one that would not gets one >= tmax or 0.
 * The minimum over pairs, searched with tmax = the minimum so far, is the
 * same whatever the order and grouping of the pairs (unit.c). */
int sc_toi_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
                      double tmax, double *t);
int sc_toi_deepen_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                             const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                             const sc_pose *b1, double limit_m, double tmax, double *t);

/* The searches behind those, sampling over ODE's narrow phase, for any
 * pair (tests and benchmarks compare them with conservative advancement,
 * extra/ca/): */
int sc_toi_sample_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                             const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                             const sc_pose *b1, double tol_m, double tmax, double *t);
int sc_toi_sample_deepen_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                                    const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                                    const sc_pose *b1, double limit_m, double tmax, double *t);
/* The same searches over [t0, 1] only, the pair taken to be apart (within
 * limit_m) at t0; conservative advancement (extra/ca/) hands them the rest
 * of a motion. */
int sc_toi_sample_from_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                           const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                           const sc_pose *b1, double tol_m, double t0, double tmax, double *t);
int sc_toi_sample_deepen_from_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                                  const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                                  const sc_pose *b1, double limit_m, double t0, double tmax,
                                  double *t);
/* The narrow phase's deepest penetration at time t of the motion (-1 when
 * apart; past stop, any depth past it) and its normal into n (or NULL). */
int sc_toi_deepest_at(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double t,
                      double stop, double *depth, double n[3]);
/* The deepening searches' limit for a pair d deep at the start: 1 with
 * *limit (the aim) raised as toi.c says, or 0 when the pair is not held. */
int sc_toi_held_limit(double d, double *limit);

/* Validate a triangle mesh and compute its mass properties:
 * SC_EINVAL (NaN, bad index), SC_ETOOBIG, SC_EDEGENERATE (zero-area
 * triangles, no volume), SC_ENOTCLOSED (an edge not shared by exactly two
 * triangles of opposite orientation, or inward orientation). */
int sc_mesh_check(const double *xyz, int nverts, const int *tri, int ntris,
                  sc_mass_props *mp);

/* Convex hull (hull.c): the hull of n points as a closed, outward triangle
 * mesh whose vertices are hull vertices only. Caller frees *xyz and *tri. */
int sc_hull_build(const double *pts, int n, double **xyz, int *nverts,
                  int **tri, int *ntris);

/* Mesh file parsing (shape_load.c): OBJ, ASCII STL or binary STL from memory,
 * STL vertices welded, OBJ vertices no face uses dropped. Returns SC_OK with arrays the caller frees, or
 * SC_EFORMAT / SC_ETOOBIG / SC_ENOMEM. Does not check closedness. */
int sc_mesh_parse(const void *buf, size_t len, double **xyz, int *nverts,
                  int **tri, int *ntris);

/* ---- broad phase (broadphase.c) ---- */
typedef struct sc_pair { int a, b; } sc_pair;   /* a < b */
/* qsort() order of pairs: by a, then b. */
int sc_pair_cmp(const void *x, const void *y);
typedef struct sc_broadphase sc_broadphase;

sc_broadphase *sc_bp_create(void);
void sc_bp_destroy(sc_broadphase *bp);
/* All pairs (a < b) whose spheres (centre c[3i..], radius r[i]) overlap and
 * of which at least one is active (active[i] != 0), sorted by (a, b).
 * method: SC_BROADPHASE_SPHERES (all pairs, the paper) or SC_BROADPHASE_SAP
 * (sweep and prune, keeps its sort order between calls). Returns the number
 * of pairs (written to the growing array *pairs of capacity *cap) or a
 * negative code. */
int sc_bp_find_pairs(sc_broadphase *bp, int method, const double *c, const double *r,
                     const unsigned char *active, int n, sc_pair **pairs, int *cap);
/* The same, with the sweeps of a large SAP call handed to runner as tasks
 * (NULL: run here); the same array either way. */
int sc_bp_find_pairs_on(sc_broadphase *bp, const sc_task_runner *runner, int method,
                        const double *c, const double *r, const unsigned char *active, int n,
                        sc_pair **pairs, int *cap);
/* The same set again, from a list of candidates kept between calls: the
 * pairs of the spheres grown by skin[i] (>= 0), made again when a body
 * moved farther than its skin since, or its radius or activity changed.
 * A skin only changes the speed: how often the list is made, how long it
 * is. sc_bp_list_drop() forgets the list (other bodies come next). */
int sc_bp_find_pairs_skin(sc_broadphase *bp, const sc_task_runner *runner, int method,
                          const double *c, const double *r, const double *skin,
                          const unsigned char *active, int n, sc_pair **pairs, int *cap);
void sc_bp_list_drop(sc_broadphase *bp);
/* The same set as sc_bp_find_pairs_on() from candidates cand[0 .. ncand)
 * (sorted by (a, b)) that hold every pair of two bodies with inside[i] set
 * whose spheres overlap and of which one is active: those that pass, and
 * each body not inside tested against every body (its cost: n a body not
 * inside). The pair count or a negative code. */
int sc_bp_pairs_within(sc_broadphase *bp, const sc_pair *cand, int ncand,
                       const unsigned char *inside, const double *c, const double *r,
                       const unsigned char *active, int n, sc_pair **pairs, int *cap);
/* Calls of sc_bp_find_pairs_skin() answered from a list kept (tests). */
long sc_bp_list_reused(const sc_broadphase *bp);

/* ---- islands (island.c) ---- */
typedef struct sc_islands {
    int count;
    int *body_start, *bodies;        /* island i: bodies[body_start[i] .. body_start[i+1]) */
    int *contact_start, *contacts;   /* and contact indices, same layout */
    int body_cap, contact_cap;       /* arrays kept and grown between builds */
} sc_islands;
/* Union-find over contacts between bodies with joins[i] != 0 (awake,
 * dynamic); a contact with one joining body belongs to that body's island,
 * one with none to no island. Canonical order throughout. The arrays of is
 * are reused and grown; temporaries come from a (NULL: malloc). */
int sc_islands_build(sc_arena *a, int nbodies, const unsigned char *joins, const sc_contact *c,
                     int ncontacts, sc_islands *is);
/* Union-find with path halving; the smaller id becomes the root. */
int sc_uf_find(int *parent, int i);
void sc_uf_unite(int *parent, int a, int b);
void sc_islands_free(sc_islands *is);


static inline int sc_body_movable(const sc_body *b)
{
    return b->inv_mass > 0 && b->state != SC_ASLEEP;
}
/* Pose of a body's shape frame (the centre of mass is what is stored). */
void sc_body_pose(const sc_body *b, sc_pose *p);
/* Thread CPU seconds and monotonic wall seconds. */
double sc_cpu_now(void);
double sc_wall_now(void);
/* In the contact list c (sorted by pair): the index of pair (a, b)'s first
 * contact (where it would be: n or a later pair's when it has none), and
 * whether it has one. */
int sc_contacts_pair_start(const sc_contact *c, int n, int a, int b);
/* The same from a cursor: *at is where the last pair asked starts (-1: none
 * yet) and becomes this one's; pairs asked in order walk c once, any other
 * is searched for. */
int sc_contacts_pair_walk(const sc_contact *c, int n, int a, int b, int *at);
int sc_contacts_have_pair(const sc_contact *c, int n, int a, int b);

#endif /* SC_CORE_H */
