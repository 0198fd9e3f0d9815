/* frame.h - a frame as a value (frame.c, detect.c, integrate.c, state.c,
 * group.c) and the work units its expensive stages are cut into (unit.c);
 * docs/DESIGN.md sections 3 to 5. A frame reads and writes only what it is
 * given: the bodies' states and last contacts, the shapes they reference
 * (immutable), the configuration, its scratch and an executor that runs its
 * jobs. Nothing here knows of threads or networks: executors do. */
#ifndef SC_FRAME_H
#define SC_FRAME_H

#include "core.h"

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
    int exact;                      /* TOI: its own time, not only when before
                                       the unit's earliest (speculative
                                       contacts at the touch, impact.c) */
    int touching;                   /* COLLIDE: in contact at the last detection
                                       (only a cost feature, not sent) */
    sc_pose a0, b0;                 /* COLLIDE: the poses; TOI: start ... */
    sc_pose a1, b1;                 /* ... and end of the substep */
} sc_unit_pair;

/* A unit's size on the wire, out and back, as the scheduler estimates its
 * transfer: one model for every kind (unit.c), which tests/test_unit_wire.c
 * holds against lib/net/unit_wire.c's encoder. Pair units (COLLIDE, TOI)
 * of count pairs; island units of bodies and contacts; group units of
 * static bodies, groups, members and contacts. */
size_t sc_unit_bytes_pairs(int kind, int count);
size_t sc_unit_bytes_islands(int bodies, int contacts);
size_t sc_unit_bytes_groups(int statics, int groups, int members, int contacts);

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
    size_t arena_high;              /* high-water mark of the running thread's
                                       arena after it (0: not known) */
} sc_unit;

struct sc_group_job;         /* below */

typedef struct sc_job {
    int kind;
    sc_unit *units;                 /* set by the executor that runs the job */
    int nunits;
    /* COLLIDE and TOI */
    const sc_unit_pair *pairs;
    int npairs;
    sc_contact *contacts;           /* COLLIDE: SC_MAX_PAIR_CONTACTS per pair */
    int *ncontact;                  /* COLLIDE: contacts of each pair */
    double tol_m;                   /* TOI: contact tolerance */
    double *toi;                    /* TOI: per pair, 1 = no impact (before the
                                       unit's earliest: only the minimum counts) */
    /* ISLAND: bodies are updated in place (islands share no movable body;
     * static and sleeping ones are only read) */
    sc_body *bodies;
    sc_contact *c;
    const sc_islands *islands;
    double h;
    const sc_contact_params *params;
    /* GROUP: motion groups' whole frames (group.c); units come made, and
     * run_group runs one (so that unit.c need not know group.c) */
    const struct sc_group_job *group;
    int (*run_group)(sc_np_ctx *np, const struct sc_job *job, const sc_unit *u);
} sc_job;

/* Run unit u of job on the calling thread with its narrow-phase context;
 * sets u->rc, u->messages, u->info, u->arena_high (not u->time_s). */
void sc_unit_run(sc_np_ctx *np, const sc_job *job, sc_unit *u);
/* The paper's cost estimate of a pair (product of polygon counts). */
double sc_pair_cost(const sc_shape *a, const sc_shape *b);

/* An executor runs a job's units: it cuts the job into units (COLLIDE,
 * TOI and ISLAND jobs; GROUP jobs come cut), runs them wherever it likes
 * and returns the first unit error in unit order (the same whoever ran
 * what). It adds its own figures to st: units, scheduling and makespan
 * times, other nodes' CPU in stage_s[stage] (stage < 0: none). */
typedef struct sc_exec sc_exec;
struct sc_exec {
    int (*run)(sc_exec *ex, sc_job *job, int stage, sc_stats *st);
    int (*width)(const sc_exec *ex);   /* nodes it can run units on now */
    /* A job in two halves (NULL: only run()): start() assigns the units
     * and sends the remote nodes theirs at once, the local nodes' waiting
     * for finish(), which runs them, collects the rest and returns as
     * run() would. In between the caller may run() other jobs on ex (not
     * start another); local nodes are taken as busy for home_busy_s
     * first, so units go remote only where that still finishes sooner.
     * After a start() that failed, finish() is not called. */
    int (*start)(sc_exec *ex, sc_job *job, double home_busy_s);
    int (*finish)(sc_exec *ex, sc_job *job, int stage, sc_stats *st);
    /* A job run around the caller's (NULL: not offered): background()
     * returns 1 when it handed the job's units to idle local threads (0:
     * not now, run it otherwise), which take them while the caller runs
     * other jobs; drain() runs what is left on the calling thread, waits
     * for the rest and accounts the job as run() would. */
    int (*background)(sc_exec *ex, sc_job *job);
    int (*drain)(sc_exec *ex, sc_job *job, sc_stats *st);
    /* NULL, or the calling thread's task runner: the serial stages of a
     * frame on the calling thread (sweep and prune, integration's
     * per-body passes) hand it tasks that idle local threads share
     * (docs/DESIGN.md 5.3). */
    const sc_task_runner *runner;
};
/* The serial executor: every job as one unit on the calling thread, with
 * its narrow-phase context np. */
typedef struct sc_exec_serial {
    sc_exec base;
    sc_np_ctx *np;
} sc_exec_serial;
void sc_exec_serial_init(sc_exec_serial *s, sc_np_ctx *np);

/* ---- the frame ---- */
typedef struct sc_frame_config {
    double gravity[3];
    double contact_tol_m;
    int broadphase;                 /* SC_BROADPHASE_* */
    int island_split;               /* sc_world_config.island_split */
    int island_method;              /* sc_world_config.island_method */
    int toi_mode;                   /* sc_world_config.toi_mode */
    int redo_all;                   /* tests: a speculative round solves every
                                       island again (frame.c) */
} sc_frame_config;

/* What a frame reads and writes: the bodies (states in, new states out)
 * and the contacts of the last detection. The arrays belong to the
 * caller; contacts grow as needed (sc_grow). */
typedef struct sc_frame_state {
    sc_body *bodies;
    int nbodies;
    sc_contact *contacts;
    int ncontacts, contact_cap;
    int contacts_valid;             /* contacts match the current bodies */
    struct sc_track *track;         /* NULL, or where the bodies went in
                                       the frame (motion groups, group.c) */
} sc_frame_state;

/* Where the bodies of a frame went, for the motion groups' check
 * (group.c): how far each body's shape origin went from its drift
 * (sc_body_drift()) at any time of the frame, how far its orientation
 * turned from its spin's (sc_spin_at(): turning at its angular velocity
 * of the frame's start), and, for a body that went farther than
 * SC_TRACK_DEV, its pose at the frame's start and at the end of every
 * substep (t, x, y, z, then the quaternion; between two the frame moves it
 * along the chord and turns it by the slerp: the time of impact's poses,
 * toi.c). Arrays by body, written by sc_frame_step(). */
#define SC_TRACK_MAX 34       /* points: the start and 1 + 31 back-ups'
                                 substeps (frame.c MAX_BACKUPS_LOCAL), one
                                 spare; a body with more keeps none */
#define SC_TRACK_DEV 2e-4     /* m: a body that stayed this close to its
                                 drift keeps no points (the check takes
                                 its drift and distance) */
#define SC_TRACK_STRIDE 8     /* doubles a point: t, x, y, z, qw, qx, qy, qz */
typedef struct sc_track {
    double *dev;
    double *adev;                   /* rad from the spin's orientation */
    int *count;                     /* points kept (0: none) */
    double *pt;                     /* SC_TRACK_MAX * SC_TRACK_STRIDE a body */
} sc_track;

/* Body j of track from written as body i of to. */
void sc_track_copy(sc_track *to, int i, const sc_track *from, int j);
/* Room in t's malloc'd arrays for n bodies (*cap: the room it has; the
 * arrays are made again, zeroed, when it is less), or SC_ENOMEM with t
 * empty; sc_track_free() frees them. */
int sc_track_reserve(sc_track *t, int *cap, int n);
void sc_track_free(sc_track *t);

/* Scratch a frame needs, kept between frames: the arena (reset by the
 * caller between frames), the broad phase's sort order and pair list, the
 * islands' arrays, and (motion groups) the scratch of groups run on this
 * thread. */
/* The narrow phase's last results within one frame (detect.c): a pair
 * whose two poses are the same bits as at the last detection has the same
 * contacts (the narrow phase reads only shapes and poses), so it is not
 * collided again. Pair k's contacts are c[start[k] .. start[k + 1]),
 * before the warm start. Valid only within the frame that wrote it. */
typedef struct sc_np_memo {
    int valid;
    int nbodies;
    sc_pose *poses;                 /* every body's pose at that detection */
    int pose_cap;
    int npairs;
    sc_pair *pairs;                 /* in (a, b) order */
    int pair_cap;
    int *start;
    int start_cap;
    sc_contact *c;
    int c_cap;
    /* narrowphase()'s buffers: the next copy of start and c, written while
     * c is read, and the contact list's spare (the frame state's list and
     * this one trade places at each detection) */
    int *start_next;
    int start_next_cap;
    sc_contact *c_next;
    int c_next_cap;
    sc_contact *spare;
    int spare_cap;
} sc_np_memo;

typedef struct sc_frame_scratch {
    sc_arena arena;
    sc_np_memo memo;
    sc_broadphase *bp;
    sc_pair *pairs;
    int pair_cap;
    sc_pair *plane_pairs;           /* detect.c: pairs with a plane */
    int plane_pair_cap;
    sc_islands islands;
    struct sc_group_scratch *groups;   /* group.c, created when first used */
    void (*groups_free)(struct sc_group_scratch *);
} sc_frame_scratch;
/* SC_OK or SC_ENOMEM (sc_frame_scratch_free() still applies). */
int sc_frame_scratch_init(sc_frame_scratch *s);
void sc_frame_scratch_free(sc_frame_scratch *s);

/* One frame of dt seconds (the paper's steps 3-7: substeps, back-ups to
 * the time of impact, islands, states). Adds the frame's figures to
 * stats (the caller clears the per-frame ones). SC_OK or an error code;
 * st is then in a defined but unspecified state. */
int sc_frame_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                  sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats);
/* The same frame by motion groups (group.c): bodies that cannot meet
 * within it step apart, each group by sc_frame_step() as a unit of its own. */
int sc_groups_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                   sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats);

/* ---- motion groups (group.c): what a GROUP unit reads and writes ---- */
/* The groups of a frame: arrays from the parent frame's arena. Group k's
 * members (world ids, ascending) are members[start[k] .. start[k + 1]),
 * gid[i] is body i's group (-1: none); the static bodies statics[0 ..
 * nstatics) are read by every group; group k's contacts of the last frame
 * are contacts[cstart[k] .. cstart[k + 1]) (indices into the frame
 * state's contacts, in their order). */
typedef struct sc_groups {
    int n, ngroups, nstatics;
    double *centre, *radius;
    unsigned char *active;
    int *parent, *start, *members, *gid, *statics, *cstart, *contacts;
} sc_groups;

/* A group's frame's outputs besides its members' new states. */
typedef struct sc_group_out {
    int rc;
    sc_contact *contacts;           /* world ids, canonical order; malloc'd */
    int ncontacts;
    sc_stats stats;                 /* of the group's frame, from zero */
} sc_group_out;

/* What a GROUP job's units read and write. Unit u holds the u->islands
 * groups list[u->first ...] (list NULL: groups u->first ... themselves),
 * u->count members in all. Each group k runs on a copy of its members and
 * the static bodies, its members written back to st (and their tracks to
 * track), its outputs to out[k]. On the master g is the frame's groups; a
 * unit received over the wire (unit_wire.c) makes a g of its own over its
 * bodies (the static ones and the members of its groups, in world order)
 * and its groups' contacts, so that both run the same code. */
typedef struct sc_group_job {
    const sc_frame_config *cfg;
    sc_frame_state *st;
    const sc_groups *g;
    const int *list;
    int nlist;
    double dt;
    sc_group_out *out;
    sc_track *track;                /* by body of st, each member's from its
                                       group's frame */
} sc_group_job;

/* Group k's bodies in the order its copy has them: its members and the
 * static bodies merged by world id into ids (room for both); returns how
 * many. */
int sc_group_ids(const sc_groups *g, int k, int *ids);
/* Index of id in the ascending ids[0 .. m) (a group's copy), or -1. */
int sc_group_local_id(const int *ids, int m, int id);
/* Unit u of a GROUP job in either form above, on the calling thread's
 * group scratch and the serial executor (sc_job.run_group). */
int sc_group_unit_run(sc_np_ctx *np, const sc_job *job, const sc_unit *u);

/* ---- inside a frame: the stages' shared view ---- */
typedef struct sc_frame {
    const sc_frame_config *cfg;
    sc_frame_state *st;
    sc_frame_scratch *scr;
    sc_exec *ex;
    sc_stats *stats;
    /* per frame, from the arena: of the last broad phase (detect.c) */
    double *centre, *radius;
    double *skin;             /* how far each body may move before the
                                 broad phase's candidates are made again */
    unsigned char *active;
    sc_pose *poses;
    double dt;                /* the frame's length, s */
    double t;                 /* the substep's start in the frame, s */
    double *drift;            /* with st->track: 9 a body, sc_body_drift() */
    double *spin;             /* with st->track: 7 a body, q and w at the
                                 frame's start (sc_spin_at()) */
    int backups;              /* back-ups of this frame so far (local mode) */
} sc_frame;

/* How far body b's shape origin can go in dt at twice its speed, turning
 * and under gravity and its force (clock.c): the motion groups' reach
 * (group.c) and the broad phase's skin (detect.c), without their margins. */
double sc_body_reach(const sc_frame_config *cfg, const sc_body *b, double dt);
/* Where b's shape origin goes in a frame if nothing touches it, to first
 * order in its turn: o0 + v t + a t^2 / 2, from its pose o0, the
 * origin's velocity v (the centre's and the turn's) and a from gravity
 * and its force (integration is exact for that but for the turn: the
 * origin leaves the line by at most |com| (|w| t)^2 / 2). A body that
 * cannot move stays. d[0..8] = o0, v, a (clock.c). The motion groups'
 * joins and their check (group.c). */
void sc_body_drift(const sc_frame_config *cfg, const sc_body *b, double d[9]);
/* Where that is at time t of the frame. */
void sc_drift_at(const double d[9], double t, double p[3]);
/* The orientation at time t of a body that starts the frame at q0 and
 * turns at w0 (world, rad/s) about a fixed axis: the motion groups' check
 * takes it, widened by the track's adev, for a body that keeps no points
 * (clock.c). */
void sc_spin_at(const double q0[4], const double w0[3], double t, double q[4]);
/* The contact model and solver settings a frame of cfg uses (frame.c;
 * docs/DESIGN.md section 11). */
sc_contact_params sc_frame_contact_params(const sc_frame_config *cfg);
/* m/s: an approach faster than this collides (restitution), the paper's
 * threshold speed; sc_contact_params.bounce_speed of every frame */
#define SC_BOUNCE_SPEED 0.1
/* Adding the CPU time since t0 to a Table 1 row of f's figures. */
void sc_stage_add(sc_stats *st, int stage, double t0);
/* The clock a frame's stages time themselves with (sc_stats.frame.stage_s): the
 * thread's CPU time in world mode (Table 1 is CPU by stage; a few dozen
 * reads a frame), the monotonic clock in local mode, where every motion
 * group's frame times its stages: a thread CPU read is a system call, and
 * a large scene's many small groups would make thousands a frame
 * (docs/DESIGN.md 3.1). sc_stage_since() adds the time since t0 (of this
 * clock) to stage. */
double sc_stage_now(const sc_frame *f);
void sc_stage_since(sc_frame *f, int stage, double t0);
/* One island solve's figures into the frame's (sc_stats_lcp). */
void sc_stats_add_solve(sc_stats *st, const sc_solve_info *info);
/* The solver figures of s2 (a motion group's frame) into s. */
void sc_stats_add_solver(sc_stats *s, const sc_stats *s2);
/* The figures of g (a motion group's or a region's frame, its own stats
 * from zero) into s: stage times, counters, maxima. */
void sc_stats_add_frame(sc_stats *s, const sc_stats *g);
/* Only g's stage times and scheduler figures (sc_stats_sched) into s: the
 * work of a group's try that the check threw away (group.c), which took
 * its time though its results are not the frame's. */
void sc_stats_add_work(sc_stats *s, const sc_stats *g);
/* Step 5 (impact.c): the earliest time of impact (fraction of the
 * substep) among the pairs whose contacts are marked 1 in fast, or, fast
 * NULL, among all contacts deeper than the tolerance; 1 when there is
 * none. saved: the bodies at the substep's start, c0[0 .. n0) its
 * contacts. One query per pair, as a TOI job. */
int sc_frame_earliest_impact(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                             const unsigned char *fast, double *frac);
/* Speculative contacts of a substep (local mode), sorted by pair when
 * merged. */
typedef struct sc_spec_list {
    sc_contact *c;
    int n, cap;
} sc_spec_list;
/* The detection's pairs that got deeper than allowed (a new pair past the
 * tolerance, a touching one past its start depth plus a tenth of it),
 * sorted out: slow ones (sweep below half the smaller feature, depth
 * below a quarter of it) add their new contacts to spec, moved back to
 * the substep's start with their depth there (negative: a gap), and are
 * marked 2 in fast; fast ones are marked 1 and counted in *nfast.
 * Returns the number of slow pairs that added a contact, or a code. */
int sc_spec_sort_out(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0, double h,
                     sc_spec_list *spec, unsigned char *fast, int *nfast);
/* Fast pairs (marked 1) searched for their own time of impact, their
 * contacts there moved back to the start into spec (a pair with nothing
 * new there, or no time, held by its contacts where it ended, as a slow
 * one): a pair that added one is marked 2 and taken off *nfast. A pair
 * whose gap at the start passes SPEC_MARGIN contact tolerances is left
 * fast, unless hold has SC_HOLD_FAR (then it is held where it ended); a
 * perfectly elastic collision is left fast (to back up to its touch)
 * unless hold has SC_HOLD_ELASTIC. Returns the number of pairs held. */
#define SC_HOLD_FAR 1
#define SC_HOLD_ELASTIC 2
/* 1 if a pair left fast (marked 1) is perfectly elastic: restitution 1. */
int sc_spec_fast_elastic(const sc_frame *f, const sc_body *saved, const unsigned char *fast);
int sc_spec_touch(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0, double h,
                  sc_spec_list *spec, unsigned char *fast, int *nfast, int hold);
/* st->contacts = c0 and spec (sorted here) merged by pair, a pair's start
 * contacts first. */
int sc_spec_merge(sc_frame_state *st, const sc_contact *c0, int n0, sc_spec_list *spec);
/* Step 4: pairs and contacts of the current state into f->st->contacts
 * (sleepers they touch woken, and detected again with their pairs). */
int sc_detect(sc_frame *f);
/* A sleeping body in contact c[0 .. n) with a movable one wakes up;
 * returns how many woke. */
int sc_wake_touched(sc_body *bodies, const sc_contact *c, int n);
/* Step 3: u* = u + h (g + F/m) (keeping u in v0/w0); positions after the
 * contact solve. only (NULL: every body) marks the bodies to step. */
void sc_apply_forces(sc_frame *f, double h, const unsigned char *only);
void sc_integrate_positions(sc_frame *f, double h, const unsigned char *only);
/* States after a frame: free / colliding / contact, islands asleep. */
void sc_update_states(sc_frame *f, const sc_islands *is, const unsigned char *touched,
                      double dt);

#endif /* SC_FRAME_H */
