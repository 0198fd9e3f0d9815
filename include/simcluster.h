/*
 * simcluster.h - public API of libsimcluster, a real-time rigid body engine
 * that spreads its expensive stages over idle workstation CPUs. Every public
 * name starts with sc_; functions return SC_OK (0) or a negative SC_E* code,
 * constructors return NULL and leave the code in sc_last_error(). Units are
 * SI; quaternions are (w, x, y, z). Definition structs are filled by their
 * *_default() function first, else the create call fails with SC_ENOINIT.
 * man simcluster(3) documents every function below.
 */
#ifndef SIMCLUSTER_H
#define SIMCLUSTER_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define SC_API __attribute__((visibility("default")))
#else
#define SC_API
#endif

#define SC_VERSION_MAJOR 0
#define SC_VERSION_MINOR 1
#define SC_VERSION_PATCH 0
/* The version as text, "0.1.0" (the tools' --version; tests/tools.sh
 * checks that it is the Makefile's VERSION). */
#ifndef SC_VERSION_STRING
#define SC_STR_(x) #x
#define SC_STR(x) SC_STR_(x)
#define SC_VERSION_STRING \
    SC_STR(SC_VERSION_MAJOR) "." SC_STR(SC_VERSION_MINOR) "." SC_STR(SC_VERSION_PATCH)
#endif

/* ---- errors ------------------------------------------------------------ */
enum {
    SC_OK = 0,
    SC_EINVAL = -1,        /* an argument is NULL, NaN, infinite or out of range */
    SC_ENOMEM = -2,        /* out of memory */
    SC_EIO = -3,           /* a file or LCM URL could not be opened or read */
    SC_EFORMAT = -4,       /* a file or message is malformed or truncated (OBJ/STL, key, cluster) */
    SC_ETOOBIG = -5,       /* a file or mesh exceeds the size limits */
    SC_ENOTCLOSED = -6,    /* a mesh is not a closed, consistently oriented surface */
    SC_EDEGENERATE = -7,   /* a mesh or hull has no volume (flat, collinear, zero area) */
    SC_ERANGE = -8,        /* a body id or index is out of range */
    SC_ENOTSUP = -9,       /* the operation is not supported for this shape or body */
    SC_ENOINIT = -10,      /* a desc/config struct was not made by its *_default() */
    SC_ENOSOLUTION = -11,  /* the LCP has no solution the solver can find */
    SC_EMAXITER = -12,     /* the solver hit its pivot limit (cycling) */
    SC_ENUMERIC = -13,     /* numerical breakdown (singular pivot, NaN in state) */
    SC_EAUTH = -14,        /* a message failed authentication or was replayed */
    SC_EPERM = -15,        /* a key file is accessible by others: its mode must be 0600 */
    SC_ELIMIT = -16,       /* finite, but outside what the engine simulates (SC_MIN_ and
                              SC_MAX_ limits below) */
    SC_ETOOMANY = -17      /* an island has more contact rows than the exact solver takes
                              (SC_MAX_ISLAND_ROWS), as when bodies overlap heavily */
};

/* What the engine simulates: sizes, places, speeds and frames outside
 * these are refused (SC_ELIMIT) by the call that brings them, not met
 * later as overflow in a step. */
#define SC_MIN_LENGTH 1e-6     /* m: the smallest shape (sphere radius, box half extent, mesh bound) */
#define SC_MAX_LENGTH 1e6      /* m: the largest */
#define SC_MAX_COORD 1e7       /* m: a body's distance from the origin when added */
#define SC_MAX_SPEED 1e5       /* m/s: a body's speed when added */
#define SC_MAX_SPIN 1e5        /* rad/s: a body's angular speed when added */
#define SC_MAX_DT 1.0          /* s: one sc_world_step() */
/* Most rows of one exact island LCP (3 a contact with friction), whose dense
 * matrix is rows^2 doubles (512 MiB at this limit); a larger island is split
 * into blocks whatever sc_world_config.island_split says. */
#define SC_MAX_ISLAND_ROWS 8192
/* The default sc_world_config.island_split. */
#define SC_ISLAND_SPLIT_DEFAULT 16
/* A split island's outer iteration stops when no contact row is further than
 * SC_SPLIT_TOL (m/s) from its own answer given the others, or after
 * SC_SPLIT_MAX_SWEEPS sweeps; one the island's whole solves leave short there
 * sweeps on as many again (SC_ISLAND_BLOCK_GS: not), and one still short
 * then is counted in sc_stats_lcp.unconverged. */
#define SC_SPLIT_TOL 1e-3
#define SC_SPLIT_MAX_SWEEPS 500

/* A sentence describing the error code err (never NULL). */
SC_API const char *sc_strerror(int err);
/* The code of the last failed constructor call in this thread (like errno). */
SC_API int sc_last_error(void);

/* ---- shapes -------------------------------------------------------------- */
/* Shapes are immutable once built and reference counted: a shape may be
 * shared by many bodies and the world keeps its own reference. */
typedef struct sc_shape sc_shape;

enum { SC_SHAPE_SPHERE, SC_SHAPE_BOX, SC_SHAPE_PLANE, SC_SHAPE_CONVEX, SC_SHAPE_MESH };

/* Limits on what a mesh may hold (loaders and sc_shape_mesh enforce them). */
#define SC_MESH_MAX_VERTS 1000000
#define SC_MESH_MAX_TRIS  2000000
#define SC_MESH_MAX_PIECES 4096

/* Mass properties for unit density, in the shape's own frame. */
typedef struct sc_mass_props {
    double volume;         /* m^3 */
    double com[3];         /* centre of mass, m */
    double inertia[9];     /* row-major inertia tensor about com, per kg/m^3 */
} sc_mass_props;

/* A solid sphere of radius r centred on the origin. */
SC_API sc_shape *sc_shape_sphere(double r);
/* A solid box with half extents hx, hy, hz centred on the origin. */
SC_API sc_shape *sc_shape_box(double hx, double hy, double hz);
/* The static half space n.x <= d (normal need not be unit); static bodies only. */
SC_API sc_shape *sc_shape_plane(double nx, double ny, double nz, double d);
/* A closed, outward-oriented triangle mesh, convex or not, copied from xyz
 * (3*nverts) and tri (3*ntris) with the vertices no triangle uses dropped. */
SC_API sc_shape *sc_shape_mesh(const double *xyz, int nverts, const int *tri, int ntris);
/* A mesh as sc_shape_mesh() that other bodies collide with through convex
 * pieces (a convex decomposition such as V-HACD makes; mass, rendering and
 * planes use the mesh): piece k is the solid hull of the next counts[k] >= 4
 * points of pts (mesh frame, within its bounding box and sphere, else
 * SC_EINVAL), at most SC_MESH_MAX_PIECES pieces. */
SC_API sc_shape *sc_shape_mesh_pieces(const double *xyz, int nverts, const int *tri, int ntris,
                                      const double *pts, const int *counts, int npieces);
/* The convex hull of npoints points (xyz: 3*npoints). */
SC_API sc_shape *sc_shape_convex(const double *xyz, int npoints);
/* A mesh from a Wavefront .obj or STL (binary or ASCII) file; NULL on error,
 * with the code (SC_EIO, SC_EFORMAT, SC_ETOOBIG, SC_ENOTCLOSED, ...) in
 * sc_last_error(). */
SC_API sc_shape *sc_shape_load(const char *path);
/* sc_shape_load(), and on failure one line in err (errlen bytes; err may be
 * NULL): "path:LINE: what" for a malformed OBJ or ASCII STL, "path: byte N:
 * what" for a malformed binary STL, else "path: " and the reason. */
SC_API sc_shape *sc_shape_load_err(const char *path, char *err, size_t errlen);
/* A convex UV sphere mesh, slices around and stacks pole to pole, of
 * 2*slices*(stacks-1) triangles (224 for the paper's (r, 16, 8)). */
SC_API sc_shape *sc_shape_uv_sphere(double r, int slices, int stacks);
/* The paper's bolt, a hex head and a round shaft along +z: 180 triangles in
 * two convex pieces (head, shaft). */
SC_API sc_shape *sc_shape_bolt(void);
/* The paper's nut, a hexagonal prism with a round hole along z: 396
 * triangles in 16 convex pieces (one per edge of the hole). */
SC_API sc_shape *sc_shape_nut(void);

/* The SC_SHAPE_* kind of s. */
SC_API int sc_shape_kind(const sc_shape *s);
/* Number of convex pieces of a mesh (sc_shape_mesh_pieces()); 0 if none. */
SC_API int sc_shape_pieces(const sc_shape *s);
/* Number of triangles of a mesh or hull; 0 for analytic shapes. */
SC_API int sc_shape_triangles(const sc_shape *s);
/* Mass properties per unit density; SC_ENOTSUP for planes. */
SC_API int sc_shape_mass_props(const sc_shape *s, sc_mass_props *out);
/* Radius of the smallest origin-centred sphere holding s (INFINITY for planes). */
SC_API double sc_shape_bounding_radius(const sc_shape *s);
/* Borrow a mesh or hull's vertices and triangles, valid while s lives (any
 * out pointer may be NULL); SC_ENOTSUP for analytic shapes. */
SC_API int sc_shape_mesh_data(const sc_shape *s, const double **xyz, int *nverts,
                              const int **tri, int *ntris);
/* Take one more reference to s; returns s. */
SC_API sc_shape *sc_shape_retain(sc_shape *s);
/* Drop one reference to s, freeing it with the last one (NULL is a no-op). */
SC_API void sc_shape_release(sc_shape *s);

/* ---- poses and contacts ---------------------------------------------------- */
typedef struct sc_pose {
    double pos[3];         /* m */
    double quat[4];        /* unit quaternion w, x, y, z */
} sc_pose;

/* One contact point between bodies (or shapes) a and b, its normal pointing
 * from a to b so that moving b by depth along it separates them. */
typedef struct sc_contact {
    int body_a, body_b;    /* body ids, body_a < body_b (-1 in sc_collide) */
    double pos[3];         /* world point, m */
    double normal[3];      /* unit, from a to b */
    double depth;          /* penetration, m (>= 0) */
    double impulse[3];     /* impulse on b here in the last contact solve, N s,
                              world frame (0 from sc_collide) */
    double impulse_dt;     /* the length of the substep whose solve gave impulse, s
                              (0: none); impulse / impulse_dt is its mean force */
} sc_contact;

/* Most contact points kept per pair after reduction. */
#define SC_MAX_PAIR_CONTACTS 4

/* Exact narrow phase between shapes a and b at the given poses, thread-safe:
 * writes at most max well-spread contacts (SC_MAX_PAIR_CONTACTS kept) to out
 * and returns their number (0 = apart) or a negative code. */
SC_API int sc_collide(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                      const sc_pose *pb, sc_contact *out, int max);

/* Time of impact of a moving from a0 to a1 and b from b0 to b1 over t in
 * [0, 1] (linear in position, slerp in rotation): 1 with *t the first t at
 * which they touch with penetration <= tol_m (0 if touching at the start), 0
 * if they never touch, or a negative code. */
SC_API int sc_toi(const sc_shape *a, const sc_pose *a0, const sc_pose *a1,
                  const sc_shape *b, const sc_pose *b0, const sc_pose *b1,
                  double tol_m, double *t);

/* ---- world ----------------------------------------------------------------- */
typedef struct sc_world sc_world;

/* Broad-phase methods (sc_world_config.broadphase). */
enum { SC_BROADPHASE_AUTO, SC_BROADPHASE_SPHERES, SC_BROADPHASE_SAP };
/* Time-of-impact modes (sc_world_config.toi_mode). */
enum {
    SC_TOI_LOCAL,             /* motion groups back up alone, and pairs near
                                 touching are held in the substep's LCP as
                                 speculative contacts (the default) */
    SC_TOI_WORLD              /* the paper's: the earliest impact anywhere
                                 backs the whole world up (Table 1) */
};

/* How an island split into blocks is solved (sc_world_config.island_method). */
enum {
    SC_ISLAND_ACTIVE_SET,     /* an island of more than 64 contacts solved whole and
                                 exactly first: an active set on a sparse LU
                                 factor, iterations nearly independent of its height
                                 (the default); blocks where it does not settle */
    SC_ISLAND_BLOCK_GS,       /* block Gauss-Seidel over blocks of whole pairs,
                                 to SC_SPLIT_TOL or SC_SPLIT_MAX_SWEEPS sweeps */
    SC_ISLAND_SUBDOMAINS      /* the active set with each factorisation by
                                 subdomains of 32 bodies (an island of at least
                                 64), their interiors on the world's threads, coupled
                                 by a Schur complement on the interface */
};

/* Local threads a world uses at most (sc_world_config.workers). */
#define SC_MAX_WORKERS 64
/* Daemons a world uses at most, and the default cluster URL: LCM UDP
 * multicast (udpm; why not mpudpm: README, simclusterd(8)), ttl=0 keeping it
 * on this host and ttl=1 reaching the local network. */
#define SC_MAX_DAEMONS 64
#define SC_CLUSTER_URL "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"
typedef struct sc_world_config {
    double gravity[3];        /* m/s^2; default {0, 0, -9.81} */
    int workers;              /* local threads, the caller's included, at most
                                 SC_MAX_WORKERS; default 0: sc_cpu_budget() rounded up, at
                                 least 1 */
    const char *cluster;      /* LCM URL of the daemons (simclusterd(8)), e.g.
                                 SC_CLUSTER_URL; default NULL: local threads only */
    const char *key_file;     /* shared cluster key file (simcluster keygen); default
                                 NULL: the all-zero insecure key */
    double cluster_deadline_s; /* per job, how long after the local nodes finish a daemon's
                                 missing results are awaited before they are recomputed
                                 locally, s; default 0: 0.02 s */
    double cluster_ship_share; /* a unit goes to a daemon only when shipping it costs this
                                 thread at most this share of computing it here; default
                                 0: 0.5, negative: whatever it costs */
    double cluster_min_gain;  /* a daemon gets a job's units only when their predicted
                                 work is at least this many times its measured round trip;
                                 default 0: 2, negative: no such rule */
    int broadphase;           /* SC_BROADPHASE_*; default AUTO: all pairs below 256
                                 bodies, sweep and prune from there */
    double contact_tol_m;     /* allowed penetration, m; default 1e-3 */
    int motion_groups;        /* 1: bodies that cannot meet within a frame are stepped
                                 apart in motion groups also in SC_TOI_WORLD mode
                                 (SC_TOI_LOCAL always does so); default 0 */
    int island_split;         /* islands of more contacts than this are split into blocks
                                 solved by block Gauss-Seidel, 0: every island is one
                                 exact LCP (the paper's method); default
                                 SC_ISLAND_SPLIT_DEFAULT */
    int toi_mode;             /* SC_TOI_*, how a frame handles a pair that got too deep
                                 (simcluster(3)); default SC_TOI_LOCAL */
    int island_method;        /* SC_ISLAND_*, how a split island is solved; default
                                 SC_ISLAND_ACTIVE_SET */
    int internal_cookie;      /* set by sc_world_config_default(); do not touch */
} sc_world_config;
/* The default world configuration. */
SC_API sc_world_config sc_world_config_default(void);
/* The CPUs this process may use, possibly fractional: its affinity mask's
 * count, or less where a cgroup CPU quota (v2 cpu.max, v1 cpu.cfs_quota_us
 * over cpu.cfs_period_us, of its cgroup or an ancestor) allows less. */
SC_API double sc_cpu_budget(void);

/* Pass as sc_body_desc.mass to take the mass from density * volume. */
#define SC_MASS_FROM_DENSITY (-1.0)

typedef struct sc_body_desc {
    sc_shape *shape;          /* the body's shape, of which the world keeps a reference;
                                 default NULL, must be set */
    double mass;              /* kg, 0 for a static (immovable) body or
                                 SC_MASS_FROM_DENSITY; default 1 */
    double pos[3], quat[4];   /* m, and the quaternion w, x, y, z; default the origin,
                                 unturned */
    double vel[3], omega[3];  /* m/s and rad/s, world frame; default 0 */
    double restitution, friction;
                              /* coefficient of restitution e and Coulomb friction mu;
                                 default 0.5 each */
    double density;           /* kg/m^3, used when mass is SC_MASS_FROM_DENSITY; default
                                 1000 */
    int internal_cookie;      /* set by sc_body_desc_default(); do not touch */
} sc_body_desc;
/* The default body description: no shape, 1 kg, at rest at the origin, e = mu = 0.5. */
SC_API sc_body_desc sc_body_desc_default(void);

/* Body states (the paper's state machine). */
enum { SC_FREE, SC_COLLIDING, SC_CONTACT, SC_ASLEEP, SC_STATIC };

/* Rows of the paper's Table 1 (per-stage CPU time). */
enum {
    SC_STAGE_BROADPHASE,      /* bounding spheres / sweep and prune */
    SC_STAGE_NARROWPHASE,     /* polygon-level detection */
    SC_STAGE_TOI,             /* time of impact */
    SC_STAGE_ISLANDS,         /* extracting the contact graph */
    SC_STAGE_LCP,             /* building and solving the contact LCPs */
    SC_STAGE_INTEGRATE,       /* integration and state update */
    SC_STAGE_COUNT
};

/* sc_stats.frame.sched.ideal_makespan_s: node counts 1 .. SC_STATS_IDEAL_NODES */
#define SC_STATS_IDEAL_NODES 16
/* sc_stats.frame.sched.unit_work_by_density_s: bins of wire bytes per second
 * of work */
#define SC_STATS_DENSITY_BINS 16

/* Detection: pairs, contacts and islands of the last frame. */
typedef struct sc_stats_detect {
    int pairs;                /* broad-phase pairs */
    long np_pairs;            /* narrow-phase pair tests over the frame's detections
                                 (every substep, back-up and speculative round) */
    long np_reused;           /* of them, answered from the frame's last detection because
                                 both poses kept their bits (docs/DESIGN.md 3.3) */
    int contacts;             /* contact points */
    int islands;              /* islands */
    double max_penetration;   /* deepest contact, m */
    long collider_warnings;   /* ODE collider messages such as a contact buffer overflow
                                 (never printed) */
} sc_stats_detect;

/* The contact solver of the last frame (docs/DESIGN.md 11): every fallback is
 * counted, none is an error. */
typedef struct sc_stats_lcp {
    int solves;               /* island solves (islands x substeps) */
    int kept;                 /* islands a speculative round left as they were, their last
                                 result kept (docs/DESIGN.md 3.4) */
    long pivots;              /* LCP pivots */
    int fallbacks;            /* islands whose coupled friction LCP failed and were solved
                                 staggered: normals, then friction with fixed bounds */
    int split;                /* of the solves, those made as blocks by block Gauss-Seidel */
    long blocks;              /* block solves (blocks x sweeps) */
    long blocks_shared;       /* of them, those a helping thread solved (docs/DESIGN.md
                                 11; timing decides it, not the result) */
    int sweeps_max;           /* most outer sweeps of one split solve */
    long sweeps;              /* outer sweeps of the split solves, summed (sweeps / split
                                 is the mean; a solve the active set settles has none) */
    int unconverged;          /* split solves that stopped at the sweep limit */
    int diverged;             /* split solves that ended short of the tolerance on a
                                 diverging sweep (on their best iterate) */
    int whole_tries;          /* tries of split solves of at most 192 rows that block
                                 Gauss-Seidel left short of SC_SPLIT_TOL after 30 or 60
                                 sweeps as one exact LCP (friction by fixed-point rounds),
                                 and of split solves of at most 600 rows still short at
                                 the limit or diverged (with Lemke's method too up to 192
                                 rows; an island can count twice) */
    int whole_solved;         /* of them, those it settled (exact); after the first
                                 try's failure the sweeps go on to the limit */
    int cold_starts;          /* split solves started from 0 because last frame's impulses
                                 were a worse start */
    int regularised;          /* solves that needed a diagonal raised by 1e-9 to 1e-4 of
                                 its largest entry (singular or near-redundant contacts),
                                 exact for that compliance */
    int split_fallbacks;      /* exact islands whose staggered solve failed too, solved as
                                 blocks instead */
    long block_fallbacks;     /* block solves that failed, given projected Gauss-Seidel
                                 instead */
    int nan_islands;          /* islands with non-finite data, given no impulse */
    int inelastic;            /* islands whose elastic answer added kinetic energy, solved
                                 again with e = 0 */
    int energy_refused;       /* of fallbacks, coupled friction answers refused because
                                 they added kinetic energy of their own */
    int restitution_scaled;   /* answers whose restitution at several contacts at once
                                 added energy, solved again with the bounce scaled down */
    int guessed;              /* LCPs whose friction neither the fixed point nor Lemke's
                                 method settled, solved exactly from a projected
                                 Gauss-Seidel guess */
    int as_solves;            /* split solves made whole by the active set
                                 (SC_ISLAND_ACTIVE_SET) */
    int as_fallbacks;         /* of them, those whose guesses did not settle, solved by
                                 block Gauss-Seidel instead */
    long as_iterations;       /* guesses factored by those solves, summed (the mean is
                                 as_iterations / as_solves) */
    int as_iterations_max;    /* most guesses of one solve */
    long factor_nnz_max;      /* entries of the largest sparse factor */
    int as_parts_max;         /* most subdomains of one solve (SC_ISLAND_SUBDOMAINS; 1:
                                 one factor) */
    int as_interface_max;     /* unknowns of the largest interface between subdomains */
    long as_exchanges;        /* rounds the subdomains would exchange with a master,
                                 summed over solves */
    long as_exchange_bytes;   /* bytes of those rounds, both ways, summed */
    double residual;          /* largest complementarity error of an exact solve, m/s */
    double outer_residual;    /* largest outer residual of a split solve, m/s */
} sc_stats_lcp;

/* Time of impact of the last frame. */
typedef struct sc_stats_toi {
    int substeps;             /* substeps of the frame (1 + back-ups), the most of one
                                 region */
    int backups;              /* back-ups, summed over regions */
    int backup_regions;       /* regions (motion groups, or the world) that backed up at
                                 least once */
    int backup_bodies;        /* dynamic bodies in those regions */
    int spec_contacts;        /* speculative contacts entered in LCPs (approaches held
                                 without a back-up) */
    int spec_rounds;          /* substeps solved again with them */
} sc_stats_toi;

/* Work units and the scheduler in the last frame (docs/DESIGN.md 5 and 6). */
typedef struct sc_stats_sched {
    int groups;               /* motion groups stepped apart (bodies that cannot meet
                                 within the frame) */
    int group_retries;        /* times the groups were stepped again because bodies of two
                                 groups came close (docs/DESIGN.md 3.9) */
    double retry_s;           /* CPU seconds of the groups' tries thrown away then (their
                                 stage times, in stage_s too) */
    long units;               /* work units run */
    long units_background;    /* of them, motion groups stepped by idle local threads
                                 beside a pile (docs/DESIGN.md 5) */
    double sched_s;           /* wall seconds spent scheduling: cost estimates,
                                 assignment, model fits */
    double makespan_s;        /* wall seconds from dispatch to the last unit's result,
                                 summed over jobs */
    double makespan_bound_s;  /* lower bound of makespan_s: per job, the larger of total
                                 work / total speed and the largest unit */
    double makespan_ratio;    /* makespan_s / makespan_bound_s (>= 1, 1 ideal), 0 without
                                 work */
    long jobs;                /* jobs handed to the nodes, each a barrier for every node
                                 with units */
    double unit_work_s;       /* wall seconds of every unit where it ran, summed over jobs */
    double unit_bytes;        /* the units' estimated wire sizes out and back, summed */
    double unit_work_by_density_s[SC_STATS_DENSITY_BINS];
                              /* unit_work_s by wire bytes per second of work, bin i from
                                 2^i MB/s (bin 0 also below, the last also above) */
    double ideal_makespan_s[SC_STATS_IDEAL_NODES];
                              /* makespan_s as it would be on i + 1 nodes of the measured
                                 speed with free communication (the cluster model's input:
                                 bench_cluster -p model) */
    double frame_s;           /* wall seconds of the frame (sc_world_step()) */
    double serial_s;          /* of them, the master's serial part: the calling thread's
                                 time outside the jobs' submit-to-last-result spans (its
                                 own stages, scheduling, merging), which no node takes
                                 (docs/DESIGN.md 5.6) */
} sc_stats_sched;

/* Daemons' share of the last frame (sc_world_config.cluster). */
typedef struct sc_stats_remote {
    long units;               /* units whose result came from a daemon */
    long recomputed_units;    /* units sent but recomputed locally at the deadline */
    long late_results;        /* results that came after the deadline or twice, ignored */
    double comm_s;            /* wall seconds packing, sealing, sending and receiving */
    double wait_s;            /* wall seconds waiting for daemons' results after the local
                                 nodes were done, recomputation included */
    long unit_messages;       /* sealed messages of units sent to daemons, a daemon's
                                 units of a job together up to 256 KiB a message */
    long result_messages;     /* sealed messages of results received */
    double overhead_s;        /* daemons' round trips (send to the last result's arrival
                                 in the kernel) less their compute time, summed over jobs */
    long jobs;                /* jobs a daemon answered in full, one per daemon and job */
    long refused;             /* daemons kept out of a job by
                                 sc_world_config.cluster_min_gain, one per daemon and job */
    double bytes;             /* unit_bytes of the units whose result came from a daemon */
    double work_s;            /* the daemons' compute seconds (per thread) of those units */
    long pipelined_units;     /* motion groups' units sent to daemons before the pile's
                                 frame whose results were in when it ended */
} sc_stats_remote;

/* The last frame's figures: sc_world_step() zeroes them before it steps. */
typedef struct sc_stats_frame {
    double stage_s[SC_STAGE_COUNT]; /* seconds by stage: the thread's CPU time in world
                                       mode, the stage's monotonic time in local mode
                                       (docs/DESIGN.md 3.1) */
    sc_stats_detect detect;
    sc_stats_lcp lcp;
    sc_stats_toi toi;
    sc_stats_sched sched;
    sc_stats_remote remote;
} sc_stats_frame;

/* Figures summed or maximised over every frame since the world was created. */
typedef struct sc_stats_total {
    long frames;              /* frames stepped */
    double stage_s[SC_STAGE_COUNT]; /* seconds by stage */
    long backups;             /* time-of-impact back-ups */
    int backups_max;          /* most back-ups of one frame */
    long group_retries;       /* sc_stats_sched.group_retries summed */
    double retry_s;           /* sc_stats_sched.retry_s summed */
    double frame_s;           /* sc_stats_sched.frame_s summed */
    double serial_s;          /* sc_stats_sched.serial_s summed */
    long initial_overlaps;    /* body pairs found overlapping deeper than twice the
                                 contact tolerance when added */
    size_t arena_bytes;       /* high-water mark of the frame's arena (a stack arena that
                                 grows to its high-water mark), bytes */
    size_t unit_arena_bytes;  /* the same of the local threads' arenas, the largest seen */
    long dropped_messages;    /* messages dropped as malformed, unauthentic, replayed,
                                 stale or misaddressed, and datagrams the transport or the
                                 kernel dropped */
    long dropped_auth;        /* of them, those that failed the MAC (another cluster key,
                                 or forged) */
    long dropped_stale;       /* of them, those from an older start (epoch) of a daemon
                                 than its newest heard */
    long dropped_misaddressed; /* of them, those addressed to another start of this master */
    long duplicate_nodes;     /* daemon ids heard from two live epochs, each pair once */
} sc_stats_total;

/* The world and its nodes as they are now. */
typedef struct sc_stats_now {
    int bodies;               /* bodies in the world */
    int nodes;                /* nodes the scheduler uses (local threads) */
    int private_ode;          /* of them, those with their own copy of ODE, the only ones
                                 that run trimesh pairs concurrently */
    double cpu_budget;        /* CPUs this process may use (sc_cpu_budget()) */
    int spin;                 /* 1 when idle local threads poll for work a few ms before
                                 they sleep, 0 when fewer CPUs than nodes make them sleep
                                 at once */
    int daemons;              /* daemons heard from and not owner-busy */
    int daemons_busy;         /* daemons whose owner is busy */
    int daemons_unverified;   /* daemons heard that have not answered this master's
                                 challenge (not in daemons) */
    int64_t duplicate_node;   /* the last id counted in sc_stats_total.duplicate_nodes,
                                 0 if none */
} sc_stats_now;

/* A world's figures (sc_world_stats()). */
typedef struct sc_stats {
    sc_stats_frame frame;     /* the last frame */
    sc_stats_total total;     /* every frame so far */
    sc_stats_now now;         /* now */
} sc_stats;

/* A new empty world (cfg NULL: the defaults); NULL on error (sc_last_error()). */
SC_API sc_world *sc_world_create(const sc_world_config *cfg);
/* Free w and drop its shape references (NULL is a no-op). */
SC_API void sc_world_destroy(sc_world *w);
/* Add a body; returns its id (>= 0, ids count up from 0) or a negative code. */
SC_API int sc_body_add(sc_world *w, const sc_body_desc *d);
/* Number of bodies in w. */
SC_API int sc_world_body_count(const sc_world *w);
/* Advance w by one frame of dt seconds (detection, islands, contact LCP,
 * integration, time-of-impact back-ups); SC_OK or a negative code. */
SC_API int sc_world_step(sc_world *w, double dt);
/* Pose of body id (origin of its shape frame); zeros for a bad id. */
SC_API void sc_body_get_pose(const sc_world *w, int id, double pos[3], double quat[4]);
/* Linear velocity of body id's shape origin and its angular velocity, world
 * frame; zeros for a bad id. */
SC_API void sc_body_get_velocity(const sc_world *w, int id, double v[3], double omega[3]);
/* The shape of body id (borrowed: valid while w lives); NULL for a bad id. */
SC_API const sc_shape *sc_body_shape(const sc_world *w, int id);
/* SC_FREE, SC_COLLIDING, SC_CONTACT, SC_ASLEEP or SC_STATIC; negative for a bad id. */
SC_API int sc_body_state(const sc_world *w, int id);
/* Push body id with force f (N) at world point at (NULL = centre of mass)
 * during the next frame (the paper's 3D mouse); SC_OK or a negative code. */
SC_API int sc_body_apply_force(sc_world *w, int id, const double f[3], const double at[3]);
/* 1 when every dynamic body is asleep or at rest, else 0. */
SC_API int sc_world_at_rest(const sc_world *w);
/* Kinetic + gravitational potential energy, J. */
SC_API double sc_world_energy(const sc_world *w);
/* FNV-1a hash of every body's pose and velocity bits (determinism checks). */
SC_API uint64_t sc_world_hash(const sc_world *w);
/* Counters and timings of the last frame and of the run so far. */
SC_API void sc_world_stats(const sc_world *w, sc_stats *s);
/* Contacts found in the last frame, in canonical order (by body pair, then
 * point); copies at most max and returns how many there are in all. */
SC_API int sc_world_contacts(const sc_world *w, sc_contact *out, int max);
/* Wait at most timeout_s seconds until k daemons that are not owner-busy
 * answer a challenge on cfg's cluster (cfg->cluster, cfg->key_file), as a
 * world would, and return how many answered (fewer than k when the time ran
 * out) or a negative code. */
SC_API int sc_cluster_wait(const sc_world_config *cfg, int k, double timeout_s);

/* ---- the paper's scenes ---- */
/* Add Table 1's 27 steel spheres (e = 1) moving in a closed 4 m box to w; SC_OK or a code. */
SC_API int sc_scene_spheres_box(sc_world *w);
/* Add the Table 1 box's walls and n (1..SC_ELASTIC_BOX_MAX) frictionless
 * steel UV spheres (e = 1) of radius (0, 0.25) m on a grid filling the box's
 * middle 3.2 m, moving at speed m/s in spread directions, to w; SC_OK or a
 * code. */
#define SC_ELASTIC_BOX_MAX 1000
SC_API int sc_scene_elastic_box(sc_world *w, int n, double radius, double speed);
/* Add a floor and n (1..100000) bolts and nuts at random free poses from seed
 * to w; SC_OK or a code. */
SC_API int sc_scene_bolts_nuts(sc_world *w, int n, uint64_t seed);
/* Add the parts bin, a dense pile of n bolts and nuts on a grid one part
 * length apart, four layers deep, turned at random from seed, inside four
 * walls on a floor, to w; SC_OK or a code. */
SC_API int sc_scene_bin(sc_world *w, int n, uint64_t seed);

/* ---- structures: stacks, pyramids and walls of boxes (big islands) ---- */
/* The structures' boxes: wooden cubes of 0.2 m (600 kg/m^3, restitution
 * 0.2, friction 0.6) on a floor, each layer resting 0.2 mm into the one
 * below (faces touching at exactly 0 give no contact). Most boxes of one. */
#define SC_STRUCTURE_MAX 10000
/* Add a floor and a stack of n boxes to w, every other one offset sideways
 * by offset m (0: aligned; at most 0.05); SC_OK or a code. */
SC_API int sc_scene_stack(sc_world *w, int n, double offset);
/* Add a floor and a pyramid of rows rows to w: rows boxes at the bottom,
 * one fewer each row up, each box on two below; SC_OK or a code. */
SC_API int sc_scene_pyramid(sc_world *w, int rows);
/* Add a floor and a wall of rows rows to w: cols boxes a row 1 mm apart,
 * every other row shifted by a quarter of a box, each box on two below;
 * SC_OK or a code. */
SC_API int sc_scene_wall(sc_world *w, int cols, int rows);

/* ---- scene files (format: simcluster.conf(5), SCENE FILES) ---- */
typedef struct sc_scene sc_scene;
/* Read a scene file, whose mesh paths are relative to its folder; NULL on
 * error, with the code in sc_last_error() and, when err is not NULL, a line
 * "FILE:LINE:COLUMN: what" in err (errlen bytes, truncated). */
SC_API sc_scene *sc_scene_load(const char *path, char *err, size_t errlen);
/* sc_scene_load() from len bytes of text (no NUL needed), name naming it in
 * messages and dir resolving relative mesh paths (NULL: the current folder). */
SC_API sc_scene *sc_scene_parse(const char *text, size_t len, const char *name,
                                const char *dir, char *err, size_t errlen);
/* Copy the scene's world settings (gravity, tolerance) that it gives into cfg. */
SC_API void sc_scene_config(const sc_scene *s, sc_world_config *cfg);
/* Add the scene's bodies to w in file order (grids x fastest, then y, z),
 * as often as wanted; SC_OK, or a code with the bodies added so far in w. */
SC_API int sc_scene_build(const sc_scene *s, sc_world *w);
/* Bodies the scene adds (grids expanded); 0 for NULL. */
SC_API int sc_scene_body_count(const sc_scene *s);
/* Free s (NULL is a no-op). */
SC_API void sc_scene_free(sc_scene *s);

/* ---- LCP ------------------------------------------------------------------ */
/* Solve the standard LCP w = M z + q, z >= 0, w >= 0, z.w = 0 (M row-major
 * n x n): SC_OK with z and w written, or a negative code, never a wrong answer. */
SC_API int sc_lcp_solve(int n, const double *M, const double *q, double *z, double *w);

#ifdef __cplusplus
}
#endif
#endif /* SIMCLUSTER_H */
