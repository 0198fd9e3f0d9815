/*
 * sc_internal.h - what the library's files share and do not export.
 * Every symbol here is hidden (-fvisibility=hidden); only SC_API ones leave
 * the shared object.
 */
#ifndef SC_INTERNAL_H
#define SC_INTERNAL_H

#include <assert.h>
#include <math.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "simcluster.h"

/* Internal invariants only, never bad input (that gets an SC_E* code). */
#define SC_ASSERT(c) assert(c)

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
    double *face_plane;       /* 4 per face: outward unit normal, offset */
    int *face_start;          /* face f: face_vert[face_start[f] .. face_start[f + 1]) */
    int *face_vert;           /* corner indices, counter-clockwise seen from out */
};

/* A builder's mesh moved so its centre of mass is the origin; takes
 * ownership of xyz and tri. NULL on error (sc_last_error()). */
sc_shape *sc_shape_mesh_centered(double *xyz, int nverts, int *tri, int ntris);
/* A shape from the content its hash covers (received by a daemon); the
 * arrays are copied. NULL on error (sc_last_error()). */
sc_shape *sc_shape_rebuild(int kind, double radius, const double half[3], const double plane[4],
                           const double *xyz, int nverts, const int *tri, int ntris);

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

/* Contact model constants (Baraff's velocity-level LCP, the paper's states). */
typedef struct sc_contact_params {
    double bounce_speed;            /* m/s: approach faster = collision (restitution),
                                       slower = resting contact (e = 0) */
    double slop;                    /* m of penetration left alone */
    double baumgarte;               /* fraction of the rest removed per substep */
} sc_contact_params;

typedef struct sc_solve_info {
    long pivots;
    int failures;                   /* friction LCPs that failed even regularised
                                       (the island was solved without friction) */
    int regularised;                /* LCPs solved only after regularisation */
    int lemke;                      /* solved by the Lemke fallback */
    int collisions;                 /* contacts resolved with restitution */
} sc_solve_info;

/* Contact impulses for one island (the paper's step 7): the velocity LCP
 * with restitution and Coulomb friction (boxed), then a split-impulse
 * position correction that moves bodies out of deep penetration without
 * touching velocities. bodies[*].v/w hold u* (gravity applied), v0/w0 the
 * velocities before it, iw the world inverse inertia. ci lists the
 * island's contact indices into c. Updates v, w (and x, q by h * pseudo
 * velocity). */
int sc_island_solve(sc_body *bodies, const sc_contact *c, const int *ci, int nc, double h,
                    const sc_contact_params *p, sc_solve_info *info);

/* ---- narrow phase (narrowphase.c, manifold.c) ---- */

/* A copy of libode (ode_copy.c). The process's linked copy is shared by
 * every thread and serialises trimesh pairs (Debian's ODE keeps its
 * trimesh collider cache in a global); worker threads take a private copy
 * loaded with dlmopen() into its own link namespace when one can be had, so
 * their trimesh pairs run concurrently. Copies are process-wide and kept
 * (glibc cannot reliably unload a namespace, and allows only a few). */
typedef struct sc_ode sc_ode;
const sc_ode *sc_ode_shared(void);
/* A private copy for the calling thread, or the shared one when none can be
 * loaded (limit reached, dlmopen unsupported). Never NULL. */
const sc_ode *sc_ode_acquire(void);
/* Give a copy from sc_ode_acquire() back for other threads; NULL is a no-op. */
void sc_ode_release(const sc_ode *o);
/* 1 when o is a private copy (no lock needed). */
int sc_ode_is_private(const sc_ode *o);

typedef struct sc_np_ctx sc_np_ctx;     /* one per thread: owns ODE geoms */
/* A slot for the thread's scratch world (group.c), freed with the context
 * by free_fn. */
void **sc_np_scratch(sc_np_ctx *ctx, void (**free_fn)(void *));
sc_np_ctx *sc_np_create(void);          /* on the shared copy of ODE */
sc_np_ctx *sc_np_create_on(const sc_ode *ode);
void sc_np_destroy(sc_np_ctx *ctx);
/* Contacts of a at pa with b at pb, normals from a to b, reduced to at most
 * SC_MAX_PAIR_CONTACTS; returns how many were written (<= max) or a code. */
int sc_np_collide(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *pa,
                  const sc_shape *b, const sc_pose *pb, sc_contact *out, int max);
/* Reduce n raw contacts in place to at most SC_MAX_PAIR_CONTACTS well-spread
 * ones (points closer than merge_dist merged); returns the new count. */
int sc_manifold_reduce(sc_contact *c, int n, double merge_dist);

/* Polygon faces of a box or convex mesh s (others: none), built once with
 * the shape: SC_OK (also when s is too big to merge faces: then none) or
 * SC_ENOMEM. sc_poly_free() frees them. */
int sc_poly_build(sc_shape *s);
void sc_poly_free(sc_shape *s);
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

/* sc_toi() with the caller's (per-thread) narrow-phase context. */
int sc_toi_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
               const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double tol_m,
               double *t);

/* For a pair already in contact: the last time in [0, 1] at which its
 * penetration is still <= limit_m, when it exceeds limit_m later (1 and
 * *t), 0 when it never does. A pair deeper than limit_m at t = 0 is held
 * to its depth there plus a tenth of limit_m, unless it is deeper than
 * twice limit_m (0: left to the push-out). */
int sc_toi_deepen_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                      const sc_shape *b, const sc_pose *b0, const sc_pose *b1, double limit_m,
                      double *t);

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

/* ---- islands (island.c) ---- */
typedef struct sc_islands {
    int count;
    int *body_start, *bodies;        /* island i: bodies[body_start[i] .. body_start[i+1]) */
    int *contact_start, *contacts;   /* and contact indices, same layout */
} sc_islands;
/* Union-find over contacts between bodies with joins[i] != 0 (awake,
 * dynamic); a contact with one joining body belongs to that body's island,
 * one with none to no island. Canonical order throughout. */
int sc_islands_build(int nbodies, const unsigned char *joins, const sc_contact *c,
                     int ncontacts, sc_islands *is);
/* Union-find with path halving; the smaller id becomes the root. */
int sc_uf_find(int *parent, int i);
void sc_uf_unite(int *parent, int a, int b);
void sc_islands_free(sc_islands *is);

/* ---- LCP (lcp.c) ---- */
typedef struct sc_lcp_info {
    long pivots;              /* principal pivots made */
    double residual;          /* max complementarity / feasibility violation */
    int lemke;                /* 1: principal pivoting stalled on a singular
                                 block and Lemke's method (also exact, also
                                 verified) gave the answer */
} sc_lcp_info;

/* The standard LCP by Cottle-Dantzig principal pivoting; info may be NULL. */
int sc_lcp_dantzig(int n, const double *M, const double *q, double *z, double *w,
                   sc_lcp_info *info);
/* Boxed LCP (mixed complementarity): lo <= z <= hi, w = M z + q with
 * w >= 0 where z = lo, w <= 0 where z = hi, w = 0 in between. If findex is
 * not NULL and findex[i] >= 0, the bounds of row i are -mu[i] * z[findex[i]]
 * and +mu[i] * z[findex[i]] (friction), lo/hi ignored for that row. */
int sc_lcp_boxed(int n, const double *M, const double *q, const double *lo,
                 const double *hi, const int *findex, const double *mu,
                 double *z, double *w, sc_lcp_info *info);

/* L D U factorisation of the clamped block M_CC of an n x n row-major M,
 * updated as indices enter (sc_ldu_border + sc_ldu_commit) and leave
 * (sc_ldu_remove), O(m^2) each (lcp_factor.c). U = L^T when sym. */
typedef struct sc_ldu {
    int n;                    /* capacity (M is n x n) */
    int m;                    /* indices in the factorisation */
    int sym;                  /* M symmetric: ut aliases l */
    int bordered;             /* M index prepared at position m, or -1 */
    double *l;                /* row r: L[r][0..r-1], stride n */
    double *ut;               /* row r: U[0..r-1][r], stride n */
    double *d;                /* pivots */
    double *x, *y;            /* scratch */
    int *idx;                 /* M index of each factor position */
} sc_ldu;
/* Bytes of the memory sc_ldu_init() needs (aligned for double). */
size_t sc_ldu_size(int n, int sym);
void sc_ldu_init(sc_ldu *f, int n, int sym, void *mem);
/* Prepare M index j as position m; returns its pivot, *scale (may be NULL)
 * the magnitude of the terms it cancelled from. */
double sc_ldu_border(sc_ldu *f, const double *M, int j, double *scale);
/* Make the prepared border part of the factorisation. */
void sc_ldu_commit(sc_ldu *f);
/* x = -M_CC^-1 M_{C,j} for the prepared index j (factor order). */
void sc_ldu_border_direction(const sc_ldu *f, double *x);
/* v = M_CC^-1 v in place (factor order). */
void sc_ldu_solve(const sc_ldu *f, double *v);
/* Remove position k; SC_OK or SC_ENUMERIC (an updated pivot cancelled). */
int sc_ldu_remove(sc_ldu *f, int k);
/* Dense m x m solve a v = b in place, partial pivoting; SC_OK or SC_ENUMERIC. */
int sc_lu_solve(int m, double *a, double *b);
/* Lemke's method (lcp_lemke.c), the fallback of sc_lcp_dantzig when a
 * principal block is singular: z of the final basis (not yet verified),
 * SC_OK, SC_ENOSOLUTION (secondary ray), SC_EMAXITER (*pivots reached
 * max_pivots) or SC_ENOMEM; *pivots is increased by the pivots made. */
int sc_lcp_lemke(int n, const double *M, const double *q, double *z, long max_pivots,
                 long *pivots);

/* ---- work units (unit.c, unit_wire.c), nodes (node_local.c) and the
 * scheduler (sched.c): DESIGN.md sections 1, 3 and 6 ---- */

/* The expensive stages of a substep are batches ("jobs") of work units of
 * one kind. A unit reads only its job's inputs and writes only its own
 * outputs, so units run on any node in any order and the merge, in unit
 * order, gives the same bits whoever computed what. */
enum { SC_UNIT_COLLIDE, SC_UNIT_TOI, SC_UNIT_ISLAND, SC_UNIT_GROUP, SC_UNIT_KINDS };

/* One body pair of a COLLIDE or TOI unit. */
typedef struct sc_unit_pair {
    const sc_shape *sa, *sb;        /* serialised as content hashes */
    int body_a, body_b;             /* world ids (a < b), carried through */
    int deepen;                     /* TOI: the pair touched at the start */
    int touching;                   /* COLLIDE: in contact at the last detection
                                       (only a cost feature, not sent) */
    sc_pose a0, b0;                 /* COLLIDE: the poses; TOI: start ... */
    sc_pose a1, b1;                 /* ... and end of the substep */
} sc_unit_pair;

typedef struct sc_unit {
    int kind;                       /* SC_UNIT_* (the job's kind) */
    int first, count;               /* pairs [first, first + count) of the job,
                                       or islands [first, first + islands),
                                       each solved on its own (count = their
                                       contacts) */
    int islands;
    double cost;                    /* the paper's estimate: sum of polygon count
                                       products, or of contacts^3 */
    double feat[3];                 /* cost model features: 1, then for pairs
                                       the cost of those touching at the last
                                       detection and of the others, for islands
                                       contacts and contacts^3 */
    size_t bytes;                   /* wire size of the unit (transfer time) */
    int node;                       /* assigned node */
    double predict_s;               /* the scheduler's estimate on that node */
    int rc;                         /* SC_OK or the unit's error */
    double time_s;                  /* measured wall time on its node */
    long messages;                  /* ODE messages raised while running it */
    sc_solve_info info;             /* ISLAND: the solve's counters */
} sc_unit;

typedef struct sc_job {
    int kind;
    sc_unit *units;
    int nunits;
    /* COLLIDE and TOI */
    const sc_unit_pair *pairs;
    int npairs;
    sc_contact *contacts;           /* COLLIDE: SC_MAX_PAIR_CONTACTS per pair */
    int *ncontact;                  /* COLLIDE: contacts of each pair */
    double tol_m;                   /* TOI: contact tolerance */
    double *toi;                    /* TOI: per pair, 1 = no impact */
    /* ISLAND: bodies are updated in place (islands share no movable body;
     * static and sleeping ones are only read) */
    sc_body *bodies;
    const sc_contact *c;
    const sc_islands *islands;
    double h;
    const sc_contact_params *params;
    /* GROUP: a motion group's whole frame (group.c) */
    struct sc_world *world;
    double dt;
    struct sc_group_out *gout;      /* per group */
} sc_job;

/* Run unit u of job on the calling thread with its narrow-phase context;
 * sets u->rc, u->messages, u->info (not u->time_s). */
void sc_unit_run(sc_np_ctx *np, const sc_job *job, sc_unit *u);
/* The paper's cost estimate of a pair (product of polygon counts). */
double sc_pair_cost(const sc_shape *a, const sc_shape *b);

/* Wire form of units and results (unit_wire.c): self-contained,
 * little-endian, versioned, every size bounded; shapes travel as content
 * hashes (sc_shape.hash) resolved by the receiver's lookup. */
typedef const sc_shape *(*sc_shape_lookup_fn)(void *ctx, uint64_t hash);
/* Bytes unit u of job needs; written to buf when cap is enough. */
size_t sc_wire_unit_pack(const sc_job *job, const sc_unit *u, unsigned char *buf, size_t cap);
/* A received unit: a job of its own holding that one unit. */
typedef struct sc_wire_unit {
    sc_job job;
    sc_unit unit;
    sc_unit_pair *pairs;      /* owned arrays */
    sc_contact *contacts;
    int *ncontact;
    double *toi;
    sc_body *bodies;
    int nbodies;
    sc_contact *c;
    sc_islands islands;
    sc_contact_params params;
} sc_wire_unit;
/* Decode; SC_EFORMAT for anything malformed (truncated, bad version/kind,
 * counts out of range, NaN, unknown shape hash), SC_ENOMEM. */
int sc_wire_unit_decode(const unsigned char *buf, size_t len, sc_shape_lookup_fn lookup,
                        void *lookup_ctx, sc_wire_unit *out);
void sc_wire_unit_free(sc_wire_unit *wu);
/* Results of a decoded unit after sc_unit_run(&np, &wu->job, &wu->unit). */
size_t sc_wire_result_pack(const sc_wire_unit *wu, unsigned char *buf, size_t cap);
/* Merge received results into the master's job exactly as if u had run
 * locally (u->rc, u->messages, u->info and the job's outputs for u).
 * SC_EFORMAT when buf does not match u (kind, counts) or is malformed. */
int sc_wire_result_apply(const sc_job *job, sc_unit *u, const unsigned char *buf, size_t len);

/* A node: something that runs units. Local worker threads now; daemons
 * behind the same interface later. submit() starts the units (indices into
 * job->units) and returns at once; wait() returns when they are done, with
 * each unit's rc and time_s set and *cpu_s the CPU seconds the node used. */
typedef struct sc_node sc_node;
typedef struct sc_node_ops {
    int (*submit)(sc_node *n, const sc_job *job, const int *units, int count);
    int (*wait)(sc_node *n, double *cpu_s);
    double (*transfer_s)(const sc_node *n, size_t bytes);   /* to and back,
                                       affine in bytes */
    double (*latency_s)(const sc_node *n);   /* per job: wake-up and reply */
    /* NULL = 1. What share of its measured speed the node offers now for
     * units of kind (a daemon: its idle fraction); 0 = give it none (gone,
     * owner-busy, or a kind it cannot run). Asked once per job. */
    double (*capacity)(const sc_node *n, int kind);
    void (*destroy)(sc_node *n);
} sc_node_ops;
struct sc_node {
    const sc_node_ops *ops;
    int id;
};
/* A local node. inline_node = 1: the calling thread itself (runs its
 * units inside wait(), on the shared ODE); 0: a worker thread of its own
 * (with a private ODE copy when one can be had). Nodes of one pool take
 * not-yet-started units from each other's lists when they run out; pool
 * may be NULL. NULL on error. */
typedef struct sc_local_pool sc_local_pool;
sc_local_pool *sc_local_pool_create(void);
/* Stop every worker thread of the pool (before destroying its nodes). */
void sc_local_pool_stop(sc_local_pool *p);
void sc_local_pool_destroy(sc_local_pool *p);   /* after its nodes */
sc_node *sc_node_local_create(sc_local_pool *pool, int id, int inline_node);
/* 1 when a local node runs on a private copy of ODE. */
int sc_node_local_private_ode(const sc_node *n);

/* The scheduler. Per node and unit kind: the paper's speed (cost per
 * second, from recent response times) and a least-squares cost model
 * (time = c . feat, fitted with GSL over the last measurements). */
#define SC_MODEL_WINDOW 128
typedef struct sc_cost_model {
    double x[SC_MODEL_WINDOW][3], y[SC_MODEL_WINDOW];
    int n, pos, fresh;              /* samples held, next slot, since last fit */
    int jobs;                       /* jobs since the last fit */
    double c[3];
    int ok;                         /* c is a usable fit */
} sc_cost_model;
typedef struct sc_sched_node {
    double speed[SC_UNIT_KINDS];    /* cost units per second at full capacity (EWMA) */
    int measured[SC_UNIT_KINDS];
    int idle[SC_UNIT_KINDS];        /* jobs since it last got work */
    sc_cost_model model[SC_UNIT_KINDS];
    double ready;                   /* predicted finish in the current job */
    double busy;                    /* measured busy time in the current job */
    double done;                    /* cost done in the current job */
    double job_speed, job_latency;  /* for the current job's assignment */
    double job_tr0, job_tr1;        /* transfer: seconds fixed, per byte */
    double job_cap;                 /* capacity offered in the current job */
} sc_sched_node;
typedef struct sc_sched {
    int nnodes;
    sc_sched_node *nodes;
    void *keys;                     /* scratch: the LPT order */
    int *assigned, *start, *cursor; /* per-node unit lists */
    int order_cap;
    int use_models;                 /* 0: the paper's cost / speed only */
    uint64_t shuffle;               /* tests: != 0 seeds a random assignment */
    int learn_alone;                /* tests: learn with a single node too */
    double home_capacity;           /* node 0's capacity (1; benchmarks: 0 sends
                                       everything to the other nodes) */
} sc_sched;
int sc_sched_init(sc_sched *s, int nnodes);
void sc_sched_free(sc_sched *s);
/* Predicted time of u on node k (cost model, or cost / speed). */
double sc_sched_predict(const sc_sched *s, int k, const sc_unit *u);
/* Greedy longest-first: units sorted by cost, each to the node with the
 * earliest predicted finish (ready + transfer + predicted time). Sets
 * u->node and the per-node lists s->assigned[s->start[k] .. start[k+1]). */
int sc_sched_assign(sc_sched *s, sc_node *const *nodes, sc_unit *units, int n);
/* After a job: learn from the measured times; *bound_s the lower bound on
 * its makespan (max of total work / total speed and the largest unit). */
void sc_sched_observe(sc_sched *s, const sc_unit *units, int n, double *bound_s);

/* Run a job on the world's nodes: cost, assign, submit, wait, learn, and
 * account it in w->stats (stage CPU of the other nodes, makespan). */
int sc_job_run(sc_world *w, sc_job *job, int stage);

/* ---- motion groups (group.c): bodies that cannot meet within a frame
 * step apart, each with its own substeps and back-ups ---- */
typedef struct sc_group_out {
    int rc;
    sc_contact *contacts;           /* world ids, canonical order; malloc'd */
    int ncontacts;
    sc_stats stats;                 /* of the group's frame */
} sc_group_out;
/* The frame of w by motion groups: sc_frame() on each group's sub-world,
 * the groups as work units. */
int sc_groups_step(sc_world *w, double dt);
/* Run GROUP unit u (group.c; called by sc_unit_run). */
int sc_group_unit_run(sc_np_ctx *np, const sc_job *job, const sc_unit *u);
void sc_world_scratch_free(void *sub);
/* Free the per-body group arrays (gcentre .. gcstart) of w. */
void sc_group_scratch_free(struct sc_world *w);

/* ---- the world (world.c) and its frame (detect.c, integrate.c, step.c,
 * state.c) ---- */
struct sc_world {
    sc_world_config cfg;
    sc_body *bodies;
    int nbodies, cap;
    sc_broadphase *bp;
    /* per-frame scratch, grown as needed and kept */
    double *centre, *radius;
    unsigned char *active;
    sc_pose *poses;           /* of the last broad phase (detect.c) */
    int scratch_cap;
    sc_pair *pairs;
    int pair_cap;
    sc_contact *contacts;
    int ncontacts, contact_cap;
    int contacts_valid;       /* contacts match the current state */
    /* step.c's scratch: the substep's starting state, kept between frames */
    sc_body *saved;
    int saved_cap;
    unsigned char *touched;
    int touched_cap;
    sc_contact *c0;
    int c0_cap;
    sc_islands islands;
    /* work units: nodes (node 0 = the calling thread), scheduler, and the
     * jobs' scratch (grown, kept) */
    sc_node **nodes;
    int nnodes;
    struct sc_cluster *cluster;     /* daemons: nodes nlocal .. nnodes - 1 */
    int nlocal;
    sc_local_pool *pool;
    /* a group's sub-world runs its jobs either on this context alone (a
     * group unit on some node) or on its parent's nodes (a big group) */
    sc_np_ctx *inline_np;
    struct sc_world *parent;
    /* motion groups (group.c) */
    sc_broadphase *gbp;
    double *gcentre, *gradius;
    unsigned char *gactive;
    int *gparent, *gstart, *gmembers, *gid, *gcstart, *gcontacts, *statics;
    int gcap, ngroups, nstatics;
    sc_pair *gpairs;
    int gpair_cap;
    sc_group_out *gout;
    int gout_cap, gcontact_cap;
    struct sc_world *bigsub;        /* scratch for a group on all nodes */
    int *sub_ids;                   /* a sub-world's world ids */
    int sub_ids_cap;
    sc_sched sched;
    sc_unit *units;
    int unit_cap;
    sc_unit_pair *upairs;
    int upair_cap;
    sc_contact *ucontacts;
    int ucontact_cap;
    int *uncontact;
    int uncontact_cap;
    double *utoi;
    int utoi_cap;
    sc_stats stats;
};

static inline int sc_body_movable(const sc_body *b)
{
    return b->inv_mass > 0 && b->state != SC_ASLEEP;
}
/* Pose of a body's shape frame (the centre of mass is what is stored). */
void sc_body_pose(const sc_body *b, sc_pose *p);
/* Thread CPU seconds, monotonic wall seconds, and adding the CPU time
 * since t0 to a Table 1 row. */
double sc_cpu_now(void);
double sc_wall_now(void);
void sc_stage_add(sc_world *w, int stage, double t0);
/* 1 if the contact list c (sorted by pair) has a contact of pair (a, b). */
int sc_contacts_have_pair(const sc_contact *c, int n, int a, int b);
/* The per-body scratch (centre, radius, active) for w->nbodies. */
int sc_body_scratch(sc_world *w);
/* One frame of w as a whole (step.c): substeps, back-ups, states. */
int sc_frame(sc_world *w, double dt);
/* Step 4: pairs and contacts of the current state into w->contacts. */
int sc_detect(sc_world *w);
/* Step 3: u* = u + h (g + F/m) (keeping u in v0/w0); positions after the
 * contact solve. */
void sc_apply_forces(sc_world *w, double h);
void sc_integrate_positions(sc_world *w, double h);
/* States after a frame: free / colliding / contact, islands asleep. */
void sc_update_states(sc_world *w, const sc_islands *is, const unsigned char *touched, double dt);

#endif /* SC_INTERNAL_H */
