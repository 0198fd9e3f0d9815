/* unit_wire.c - the wire form of work units and of their results
 * (docs/DESIGN.md 5 and 7.1): what a remote node needs to run a unit and
 * what it sends back, so that the master's merge gives the bits a local
 * run gives. Little-endian whatever the host, doubles as their IEEE bits,
 * shapes as content hashes, an island's bodies re-indexed one to one (the
 * solve only looks bodies up and compares them). Received bytes are
 * hostile: counts are bounded and the length checked before anything is
 * allocated, settings must be in range, and a result is written only when
 * all of it matches the master's unit. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "unit_wire.h"
#include "vecmath.h"

/* Self-contained: shapes travel as content hashes resolved in the
 * receiver's cache; an island carries copies of its bodies and of every
 * static or sleeping body its contacts reach, re-indexed 0..m-1 (members
 * first, in island order, then the others by world id). The solve uses
 * body indices only to look bodies up and to compare them, so a one-to-one
 * re-indexing leaves its arithmetic, and its result, unchanged.
 *
 * Little-endian whatever the host, doubles as their IEEE bits:
 *   header    magic u32 ("SCWU" unit, "SCWR" result), version u16, kind u16
 *   pose      pos f64[3], quat f64[4]
 *   contact   body_a i32, body_b i32, pos f64[3], normal f64[3], depth f64
 *   COLLIDE / TOI unit: count u32, (TOI) tol_m f64, per pair: hash_a u64,
 *             hash_b u64, body_a i32, body_b i32, flags u8 (bit 0 deepen, bit 1
 *             exact), a0, b0, (TOI) a1, b1
 *   ISLAND unit (consecutive islands, each solved on its own): bodies u32,
 *             members u32, contacts u32, islands u32, h, bounce_speed, slop,
 *             baumgarte, tol f64, gravity f64[3], push_tol f64, split_contacts,
 *             block_contacts, max_sweeps,
 *             cold i32, impact_first i32, island_method i32, anderson i32, per island:
 *             members u32, contacts
 *             u32; per body: see
 *             put_body(), per contact: a contact (local body indices) and its
 *             impulse f64[3] and impulse_dt f64 (the warm start)
 *   GROUP unit (motion groups' whole frames, group.c): groups, statics,
 *             profiles, members, contacts u32, contacts_valid i32, dt,
 *             gravity f64[3], contact_tol_m f64, broadphase, island_split,
 *             toi_mode, island_method i32; per static body (world ids ascending): world id
 *             u32, shape hash u64, every double of sc_body (see
 *             gbody_fields()), state i32, collided i32; per profile (a
 *             member's constants, once a unit): shape hash u64 and the
 *             first GBODY_KEEP fields; per group: members u32, contacts
 *             u32; per member (group by group, each group's world ids
 *             ascending): world id u32, profile u32, flags u8 (state,
 *             collided << 2, force and torque follow << 4), x f64[3], q
 *             f64[4], v, w f64[3], rest_s f64, (then) force, torque f64[3];
 *             per contact of the last frame, group by group (ids of the
 *             group's copy: its members and the static bodies in world
 *             order, the master's order): a contact, its impulse f64[3] and
 *             impulse_dt f64.
 *             v0, w0 and iw are a substep's (set before they are read,
 *             integrate.c) and stay home both ways
 *   result:   count u32 (pairs, island members or group members), rc i32,
 *             messages i64, pivots, as_iterations, factor_nnz_max,
 *             as_exchanges, as_exchange_bytes i64,
 *             failures, regularised, lemke,
 *             collisions, split, split_fallbacks, blocks, block_fallbacks,
 *             nan_islands, sweeps_max, unconverged, solves, diverged,
 *             cold_starts, inelastic, energy_refused, restitution_scaled,
 *             guessed, as_solves, as_fallbacks, as_iterations_max,
 *             as_parts_max, as_interface_max, whole_tries, whole_solved, sweeps i32,
 *             residual_exact, residual_split f64,
 *             then per pair: n u8 and n contacts (COLLIDE), toi f64 (TOI);
 *             (ISLAND) contacts u32, per member: x f64[3], q f64[4], v, w,
 *             v0, w0 f64[3], collided i32, per contact in the unit's contact order:
 *             impulse f64[3], impulse_dt f64 (this solve's);
 *             (GROUP) per group in the unit's order: rc i32, the figures
 *             of its frame that sc_stats_add_frame() merges (a mask u64 of
 *             the fields of stat_fields() that are not 0, then those: f64s,
 *             i64s, u64s, i32s), per member: flags u8 (state, collided <<
 *             2), x, q, v, w, rest_s f64, its track (group.c's check:
 *             sc_track): dev, adev f64 (>= 0), points u8 (at most
 *             SC_TRACK_MAX) and per point t (within the frame, in order),
 *             x, y, z, qw, qx, qy, qz f64;
 *             contacts u32 (0 unless its rc is 0) and the frame's new
 *             contacts with their impulses (ids of the group's copy,
 *             canonical order)
 * A unit's counts are bounded and its length checked (a group unit's
 * within what its optional forces allow) before anything is allocated;
 * its doubles must be finite and its solver settings in range
 * (params_ok()); sc_contact_params.inject (tests only) never travels. A
 * unit with settings out of range or inject set is not packed (0: the
 * master computes it), and a decoded one has inject 0. A group unit's
 * frame settings must be the world's (world.c's ranges), its static bodies
 * static, its profiles a mass and inertia with their inverses, every group
 * a member, every world id once (a group's ascending), its contacts
 * between a member and a body of the group's copy, body_a < body_b, sorted
 * by pair as a frame leaves them. A result's doubles are carried verbatim (a solve
 * that blew up reaches the master as NaN, as it would locally, for
 * frame.c's check); its kind, counts (pairs, or members and contacts, which
 * must be the master's unit's) and body ids must match the master's unit
 * (a group's contacts: as a unit's, and none when it failed), and nothing
 * is written unless all of it is valid. A COLLIDE result's
 * contacts carry no impulse: the narrow phase emits every contact with
 * impulse 0 (narrowphase.c, emit()) and detect.c matches last frame's onto
 * them on the master afterwards, so the master writes 0 where the narrow
 * phase would have. Outputs of a unit that failed (rc < 0) are as undefined as after a
 * local failure. */

#define WIRE_VERSION 21      /* 6: island units carry impact_first, results inelastic, v0, w0;
                                7: results carry energy_refused, restitution_scaled;
                                8: and np_pairs, np_reused; 9: and lcp_kept;
                                10: island units carry gravity (the push-out's lift);
                                11: results carry guessed, stats lcp_guessed;
                                12: group results carry the members' tracks;
                                13: group units of several groups, members
                                by state and profile (docs/DESIGN.md 7.4);
                                14: island_method in island and group units,
                                active-set figures in results and stats;
                                15: island_method SC_ISLAND_SUBDOMAINS,
                                subdomain figures in results and stats;
                                16: island units carry anderson;
                                17: results and stats carry whole_tries,
                                whole_solved;
                                18: an impulse travels with its impulse_dt;
                                19: tracks carry adev and their points'
                                orientations; 20: results and stats carry
                                sweeps; 21: island units carry push_tol */
#define MAGIC_UNIT 0x55574353u        /* "SCWU" */
#define MAGIC_RESULT 0x52574353u      /* "SCWR" */
#define MAX_PAIRS (1 << 16)
#define MAX_CONTACTS (1 << 16)
#define MAX_BODIES (1 << 17)
#define MAX_SWEEPS 10000      /* sc_contact_params.max_sweeps (frame.c: 500) */

#define POSE_BYTES (7 * 8)
#define PAIR_BYTES(nposes) (8 + 8 + 4 + 4 + 1 + (size_t)(nposes) * POSE_BYTES)
#define BODY_BYTES (31 * 8 + 2 * 4)
#define CONTACT_BYTES (2 * 4 + 7 * 8)
#define IMPULSE_BYTES (4 * 8)
#define GBODY_BYTES (8 + 60 * 8 + 2 * 4)
#define STATIC_BYTES (4 + GBODY_BYTES)
#define PROFILE_BYTES (8 + 25 * 8)
#define MEMBER_BYTES (4 + 4 + 1 + 14 * 8)
#define MEMBER_FT_BYTES (6 * 8)
#define MAX_GROUPS MAX_BODIES

/* ---- little-endian writer and reader ---- */

typedef struct wbuf {
    unsigned char *p;       /* NULL: only count */
    size_t n;
} wbuf;

/* The wire is little-endian: on such a host a value's bytes are its
 * bytes (a memcpy the compiler turns into a store); elsewhere, shifts. */
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define WIRE_HOST_LE 1
#else
#define WIRE_HOST_LE 0
#endif

static void put(wbuf *w, uint64_t v, int bytes)
{
    if (w->p) {
        if (WIRE_HOST_LE)
            memcpy(w->p + w->n, &v, (size_t)bytes);
        else
            for (int i = 0; i < bytes; i++)
                w->p[w->n + (size_t)i] = (unsigned char)(v >> (8 * i));
    }
    w->n += (size_t)bytes;
}

static void put_i32(wbuf *w, int v)
{
    put(w, (uint32_t)v, 4);
}

static void put_f64s(wbuf *w, const double *d, int n)
{
    if (WIRE_HOST_LE) {
        if (w->p && n > 0)
            memcpy(w->p + w->n, d, (size_t)n * sizeof *d);
        w->n += (size_t)n * sizeof *d;
        return;
    }
    for (int i = 0; i < n; i++) {
        uint64_t u;
        memcpy(&u, &d[i], sizeof u);
        put(w, u, 8);
    }
}

static void put_header(wbuf *w, uint32_t magic, int kind)
{
    put(w, magic, 4);
    put(w, WIRE_VERSION, 2);
    put(w, (uint64_t)kind, 2);
}

/* A contact; with its impulse only where it is an input (island units). */
static void put_contact(wbuf *w, const sc_contact *c, int a, int b, int impulse)
{
    put_i32(w, a);
    put_i32(w, b);
    put_f64s(w, c->pos, 3);
    put_f64s(w, c->normal, 3);
    put_f64s(w, &c->depth, 1);
    if (impulse) {
        put_f64s(w, c->impulse, 3);
        put_f64s(w, &c->impulse_dt, 1);
    }
}

/* Bytes fn writes; written to buf too when cap is enough. */
static size_t emit(void (*fn)(wbuf *, const void *, const void *), const void *x,
                   const void *y, unsigned char *buf, size_t cap)
{
    wbuf w = { NULL, 0 };
    fn(&w, x, y);
    if (buf && cap >= w.n) {
        wbuf out = { buf, 0 };
        fn(&out, x, y);
    }
    return w.n;
}

typedef struct rbuf {
    const unsigned char *p;
    size_t n, len;
    int bad;                /* read past the end, or a value out of range */
} rbuf;

static uint64_t get(rbuf *r, int bytes)
{
    if (r->bad || r->len - r->n < (size_t)bytes) {
        r->bad = 1;
        return 0;
    }
    uint64_t v = 0;
    if (WIRE_HOST_LE)
        memcpy(&v, r->p + r->n, (size_t)bytes);
    else
        for (int i = 0; i < bytes; i++)
            v |= (uint64_t)r->p[r->n + (size_t)i] << (8 * i);
    r->n += (size_t)bytes;
    return v;
}

/* Two's complement of the given width, without overflow. */
static int64_t get_signed(rbuf *r, int bytes)
{
    uint64_t u = get(r, bytes), sign = (uint64_t)1 << (8 * bytes - 1);
    return u < sign ? (int64_t)u : (int64_t)(u - sign) - (int64_t)(sign - 1) - 1;
}

static int get_i32(rbuf *r)
{
    return (int)get_signed(r, 4);
}

/* Doubles as sent (results) or checked finite (units). */
static void get_f64s(rbuf *r, double *d, int n, int finite)
{
    for (int i = 0; i < n; i++) {
        uint64_t u = get(r, 8);
        memcpy(&d[i], &u, sizeof u);
        if (finite && !isfinite(d[i]))
            r->bad = 1;
    }
}

/* Without an impulse on the wire the contact gets 0, as the narrow phase
 * leaves it: every field is written. */
static void get_contact(rbuf *r, sc_contact *c, int finite, int impulse)
{
    c->body_a = get_i32(r);
    c->body_b = get_i32(r);
    get_f64s(r, c->pos, 3, finite);
    get_f64s(r, c->normal, 3, finite);
    get_f64s(r, &c->depth, 1, finite);
    c->impulse[0] = c->impulse[1] = c->impulse[2] = c->impulse_dt = 0;
    if (impulse) {
        get_f64s(r, c->impulse, 3, finite);
        get_f64s(r, &c->impulse_dt, 1, finite);
        if (finite && !(c->impulse_dt >= 0))
            r->bad = 1;
    }
}

/* The header's kind, or -1 when magic, version or kind are wrong. */
static int get_header(rbuf *r, uint32_t magic)
{
    uint32_t m = (uint32_t)get(r, 4);
    unsigned version = (unsigned)get(r, 2), kind = (unsigned)get(r, 2);
    if (r->bad || m != magic || version != WIRE_VERSION || kind > SC_UNIT_GROUP)
        return -1;
    return (int)kind;
}

/* ---- units ---- */

static void write_pairs(wbuf *w, const void *job_, const void *u_)
{
    const sc_job *job = job_;
    const sc_unit *u = u_;
    int toi = job->kind == SC_UNIT_TOI;
    put_header(w, MAGIC_UNIT, job->kind);
    put(w, (uint64_t)u->count, 4);
    if (toi)
        put_f64s(w, &job->tol_m, 1);
    for (int i = u->first; i < u->first + u->count; i++) {
        const sc_unit_pair *p = &job->pairs[i];
        put(w, p->sa->hash, 8);
        put(w, p->sb->hash, 8);
        put_i32(w, p->body_a);
        put_i32(w, p->body_b);
        put(w, (uint64_t)(p->deepen != 0) | (uint64_t)(p->exact != 0) << 1, 1);
        const sc_pose *pose[4] = { &p->a0, &p->b0, &p->a1, &p->b1 };
        for (int k = 0; k < (toi ? 4 : 2); k++) {
            put_f64s(w, pose[k]->pos, 3);
            put_f64s(w, pose[k]->quat, 4);
        }
    }
}

/* The doubles of a body sc_island_solve() reads or writes (contact.c:
 * movable() reads inv_mass and state; rows x and iw; mu and e friction and
 * restitution; speeds and tangents v, w, v0, w0; it writes v, w, x, q and
 * collided, and v0, w0 where it solves the impacts first: the integration
 * then starts from them), then state and collided. A result carries fields
 * 2-7 back (x, q, v, w, v0, w0). */
#define NBODY_F64 10
#define MEMBER_F64 2, 8
static const int body_n[NBODY_F64] = { 1, 9, 3, 4, 3, 3, 3, 3, 1, 1 };

static void body_fields(sc_body *b, double *f[NBODY_F64])
{
    double *p[NBODY_F64] = { &b->inv_mass, b->iw, b->x, b->q, b->v, b->w,
                             b->v0, b->w0, &b->restitution, &b->friction };
    memcpy(f, p, sizeof p);
}

/* Fields [from, to); of a copy, so that b stays const. */
static void put_body_f64(wbuf *w, sc_body b, int from, int to)
{
    double *f[NBODY_F64];
    body_fields(&b, f);
    for (int k = from; k < to; k++)
        put_f64s(w, f[k], body_n[k]);
}

static void get_body_f64(rbuf *r, sc_body *b, int from, int to, int finite)
{
    double *f[NBODY_F64];
    body_fields(b, f);
    for (int k = from; k < to; k++)
        get_f64s(r, f[k], body_n[k], finite);
}

static void put_body(wbuf *w, const sc_body *b)
{
    put_body_f64(w, *b, 0, NBODY_F64);
    put_i32(w, b->state);
    put_i32(w, b->collided);
}

static void get_body(rbuf *r, sc_body *b)
{
    get_body_f64(r, b, 0, NBODY_F64, 1);
    b->state = get_i32(r);
    b->collided = get_i32(r);
    if (!(b->inv_mass >= 0) || b->state < SC_FREE || b->state > SC_STATIC ||
        b->collided < 0 || b->collided > 2)
        r->bad = 1;
}

/* An island's bodies in local order (world ids) and its contacts' ends
 * (local indices). */
typedef struct island_map {
    int first, nisl;        /* the unit's islands */
    int nm, m, nc;
    const int *ci;          /* the island's contacts (indices into job->c) */
    int *world;             /* m world ids */
    int *ends;              /* 2 nc local indices */
} island_map;

typedef struct idmap {
    int id, local;
} idmap;

static int cmp_id(const void *x, const void *y)
{
    const idmap *a = x, *b = y;
    return (a->id > b->id) - (a->id < b->id);
}

static int find_local(const idmap *m, int n, int id)
{
    const idmap key = { id, 0 };
    const idmap *hit = n > 0 ? bsearch(&key, m, (size_t)n, sizeof *m, cmp_id) : NULL;
    return hit ? hit->local : -1;
}

static int contact_end(const sc_job *job, const island_map *im, int k)
{
    const sc_contact *c = &job->c[im->ci[k / 2]];
    return k % 2 ? c->body_b : c->body_a;
}

static int map_island(const sc_job *job, int i, int nisl, island_map *im)
{
    const sc_islands *is = job->islands;
    const int *mem = &is->bodies[is->body_start[i]];
    im->first = i;
    im->nisl = nisl;
    /* consecutive islands: their members and contacts are consecutive too */
    im->nm = is->body_start[i + nisl] - is->body_start[i];
    im->nc = is->contact_start[i + nisl] - is->contact_start[i];
    im->ci = &is->contacts[is->contact_start[i]];
    if (im->nm < 1 || im->nm > MAX_BODIES || im->nc > MAX_CONTACTS)
        return SC_ETOOBIG;
    size_t most = (size_t)im->nm + 2 * (size_t)im->nc;
    idmap *map = sc_alloc_array(most, sizeof *map);
    im->world = sc_alloc_array(most, sizeof *im->world);
    im->ends = sc_alloc_array(2 * (size_t)im->nc, sizeof *im->ends);
    int rc = SC_ENOMEM;
    if (!map || !im->world || !im->ends)
        goto out;
    for (int k = 0; k < im->nm; k++) {
        map[k].id = im->world[k] = mem[k];
        map[k].local = k;
    }
    qsort(map, (size_t)im->nm, sizeof *map, cmp_id);
    /* the others: contact ends that are not members, by world id, once */
    idmap *ext = map + im->nm;
    int ne = 0, nu = 0;
    for (int k = 0; k < 2 * im->nc; k++)
        if (find_local(map, im->nm, contact_end(job, im, k)) < 0)
            ext[ne++].id = contact_end(job, im, k);
    qsort(ext, (size_t)ne, sizeof *ext, cmp_id);
    rc = SC_OK;
    for (int k = 0; k < ne && rc == SC_OK; k++) {
        if (nu > 0 && ext[nu - 1].id == ext[k].id)
            continue;
        ext[nu] = (idmap){ ext[k].id, im->nm + nu };
        im->world[im->nm + nu++] = ext[k].id;
        /* the solve changes movable bodies; the result carries members only */
        if (sc_body_movable(&job->bodies[ext[k].id]))
            rc = SC_EINVAL;
    }
    im->m = im->nm + nu;
    if (rc == SC_OK && im->m > MAX_BODIES)
        rc = SC_ETOOBIG;
    for (int k = 0; k < 2 * im->nc && rc == SC_OK; k++) {
        int id = contact_end(job, im, k), l = find_local(map, im->nm, id);
        im->ends[k] = l >= 0 ? l : find_local(ext, nu, id);
    }
out:
    free(map);
    return rc;
}

/* Solver settings the wire carries and a receiver accepts; inject is not
 * carried (tests only). */
static int params_ok(const sc_contact_params *p)
{
    return isfinite(p->bounce_speed) && p->bounce_speed >= 0 && isfinite(p->slop) &&
           isfinite(p->gravity[0]) && isfinite(p->gravity[1]) && isfinite(p->gravity[2]) &&
           p->slop >= 0 && isfinite(p->baumgarte) && p->baumgarte >= 0 && isfinite(p->tol) &&
           p->tol >= 0 && isfinite(p->push_tol) && p->push_tol >= 0 &&
           p->split_contacts >= 0 && p->block_contacts >= 1 &&
           p->block_contacts <= MAX_CONTACTS && p->max_sweeps >= 1 &&
           p->max_sweeps <= MAX_SWEEPS && (p->cold == 0 || p->cold == 1) &&
           (p->impact_first == 0 || p->impact_first == 1) &&
           (p->island_method == SC_ISLAND_ACTIVE_SET || p->island_method == SC_ISLAND_BLOCK_GS ||
            p->island_method == SC_ISLAND_SUBDOMAINS) &&
           p->anderson >= 0 && p->anderson <= SC_ANDERSON_MAX && p->inject == 0;
}

static void write_island(wbuf *w, const void *job_, const void *im_)
{
    const sc_job *job = job_;
    const island_map *im = im_;
    put_header(w, MAGIC_UNIT, SC_UNIT_ISLAND);
    put(w, (uint64_t)im->m, 4);
    put(w, (uint64_t)im->nm, 4);
    put(w, (uint64_t)im->nc, 4);
    put(w, (uint64_t)im->nisl, 4);
    const sc_contact_params *p = job->params;
    double head[9] = { job->h,         p->bounce_speed, p->slop,       p->baumgarte,
                       p->tol,         p->gravity[0],   p->gravity[1], p->gravity[2],
                       p->push_tol };
    put_f64s(w, head, 9);
    put_i32(w, p->split_contacts);
    put_i32(w, p->block_contacts);
    put_i32(w, p->max_sweeps);
    put_i32(w, p->cold);
    put_i32(w, p->impact_first);
    put_i32(w, p->island_method);
    put_i32(w, p->anderson);
    const sc_islands *is = job->islands;
    for (int i = im->first; i < im->first + im->nisl; i++) {
        put(w, (uint64_t)(is->body_start[i + 1] - is->body_start[i]), 4);
        put(w, (uint64_t)(is->contact_start[i + 1] - is->contact_start[i]), 4);
    }
    for (int k = 0; k < im->m; k++)
        put_body(w, &job->bodies[im->world[k]]);
    for (int k = 0; k < im->nc; k++)
        put_contact(w, &job->c[im->ci[k]], im->ends[2 * k], im->ends[2 * k + 1], 1);
}

/* ---- group units: a motion group's whole frame ---- */

/* Every double of a body (a frame may read any), all but the shape, which
 * travels as its hash: the first GBODY_KEEP a frame only reads; the rest it
 * writes, and a result carries them back. A field added to sc_body must be
 * added here (test_unit_wire compares whole bodies of a local and a
 * remote run). */
#define GBODY_F64 17
#define GBODY_KEEP 7
enum { GF_X = 7, GF_FORCE = 11 };  /* x, q, v, w; force, torque */
static const int gbody_n[GBODY_F64] = { 1, 1, 9, 9, 3, 1, 1, 3, 4, 3, 3, 3, 3, 3, 3, 9, 1 };

static void gbody_fields(sc_body *b, double *f[GBODY_F64])
{
    double *p[GBODY_F64] = { &b->mass, &b->inv_mass, b->inertia, b->inv_inertia, b->com,
                             &b->restitution, &b->friction, b->x, b->q, b->v, b->w,
                             b->force, b->torque, b->v0, b->w0, b->iw, &b->rest_s };
    memcpy(f, p, sizeof p);
}

static void put_gbody_f64(wbuf *w, sc_body b, int from, int to)
{
    double *f[GBODY_F64];
    gbody_fields(&b, f);
    for (int k = from; k < to; k++)
        put_f64s(w, f[k], gbody_n[k]);
}

static void get_gbody_f64(rbuf *r, sc_body *b, int from, int to, int finite)
{
    double *f[GBODY_F64];
    gbody_fields(b, f);
    for (int k = from; k < to; k++)
        get_f64s(r, f[k], gbody_n[k], finite);
}

/* Whether a member's mass and inertia are the inverses of the inverse
 * mass and inverse inertia its frame uses, as sc_body_add() makes them
 * (to rounding: 1e-12 and 1e-6 of the identity). A decoded group unit
 * whose inverse inertia was corrupted (one off-diagonal entry 1e69 or
 * 1e180, finite and otherwise in range) ran its frame for 10-16 s
 * (test_unit_wire). */
static int inverses_ok(const sc_body *b)
{
    if (!(fabs(b->mass * b->inv_mass - 1) <= 1e-12))
        return 0;
    double p[9];
    m3_mul(p, b->inertia, b->inv_inertia);
    for (int i = 0; i < 9; i++)
        if (!(fabs(p[i] - (i % 4 == 0)) <= 1e-6))
            return 0;
    return 1;
}

/* b's shape: the one the receiver holds under hash (unless r is bad
 * already). A frame only reads shapes; sc_body holds them unqualified for
 * the world's references. */
static void set_shape(rbuf *r, sc_body *b, uint64_t hash, sc_shape_lookup_fn lookup, void *ctx)
{
    if (r->bad)
        return;
    const sc_shape *s = lookup(ctx, hash);
    if (!s || s->hash != hash)
        r->bad = 1;
    b->shape = (sc_shape *)s;
}

/* A unit's body: static exactly when its inverse mass is 0 (world.c), a
 * member's inverses its mass's and inertia's, its shape one the receiver
 * holds under that hash. */
static void get_gbody(rbuf *r, sc_body *b, sc_shape_lookup_fn lookup, void *ctx)
{
    uint64_t hash = get(r, 8);
    get_gbody_f64(r, b, 0, GBODY_F64, 1);
    b->state = get_i32(r);
    b->collided = get_i32(r);
    if (!(b->inv_mass >= 0) || !(b->mass >= 0) || b->state < SC_FREE ||
        b->state > SC_STATIC || (b->inv_mass > 0) != (b->state != SC_STATIC) ||
        b->collided < 0 || b->collided > 2 || (b->inv_mass > 0 && !inverses_ok(b)))
        r->bad = 1;
    set_shape(r, b, hash, lookup, ctx);
}

/* The frame settings a receiver accepts: those sc_world_create() does. */
static int frame_cfg_ok(const sc_frame_config *c, double dt)
{
    return sc_finite3(c->gravity) && isfinite(c->contact_tol_m) && c->contact_tol_m > 0 &&
           c->broadphase >= SC_BROADPHASE_AUTO && c->broadphase <= SC_BROADPHASE_SAP &&
           c->island_split >= 0 &&
           (c->island_method == SC_ISLAND_ACTIVE_SET || c->island_method == SC_ISLAND_BLOCK_GS ||
            c->island_method == SC_ISLAND_SUBDOMAINS) &&
           (c->toi_mode == SC_TOI_LOCAL || c->toi_mode == SC_TOI_WORLD) && isfinite(dt) &&
           dt > 0;
}

/* How many of the ascending a[0 .. n) are below r. */
static int count_below(const int *a, int n, int r)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (a[mid] < r)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* Index of body r (a world id on the master, a received unit's index on
 * a daemon: world order either way) in group k's copy: the members and
 * static bodies before it (each ascending). */
static int copy_index(const sc_groups *g, int k, int r)
{
    return count_below(&g->members[g->start[k]], g->start[k + 1] - g->start[k], r) +
           count_below(g->statics, g->nstatics, r);
}

/* Which profile (a member's constants: GBODY_KEEP fields and its shape)
 * p of a unit's holders body b has: one of the last PROFILE_SCAN made, or
 * a new one (the same bits: memcmp). */
#define PROFILE_SCAN 16

static int same_profile(const sc_body *a, const sc_body *b)
{
    if (a->shape->hash != b->shape->hash)
        return 0;
    double *fa[GBODY_F64], *fb[GBODY_F64];
    gbody_fields((sc_body *)a, fa);
    gbody_fields((sc_body *)b, fb);
    for (int k = 0; k < GBODY_KEEP; k++)
        if (memcmp(fa[k], fb[k], (size_t)gbody_n[k] * sizeof(double)) != 0)
            return 0;
    return 1;
}

/* The groups of a master's GROUP unit: list[first .. first + ng) of its
 * job, nm members and nc contacts in all; per member (in the unit's
 * order) its profile, each profile by a body holding it. */
typedef struct bundle_map {
    int first, ng, nm, nc, np;
    int *prof, *holder;
} bundle_map;

static void bundle_free(bundle_map *bm)
{
    free(bm->prof);
    free(bm->holder);
}

static int map_bundle(const sc_job *job, const sc_unit *u, bundle_map *bm)
{
    const sc_group_job *gj = job->group;
    const sc_groups *g = gj->g;
    const sc_body *bodies = gj->st->bodies;
    bm->first = u->first;
    bm->ng = u->islands;
    for (int j = 0; j < bm->ng; j++) {
        int k = gj->list[bm->first + j];
        int nm = g->start[k + 1] - g->start[k];
        if (nm < 1 || nm > MAX_BODIES)
            return SC_ETOOBIG;
        bm->nm += nm;
        bm->nc += g->cstart[k + 1] - g->cstart[k];
        if (bm->nm > MAX_BODIES - g->nstatics || bm->nc > MAX_CONTACTS)
            return SC_ETOOBIG;
    }
    if (bm->ng > MAX_GROUPS)
        return SC_ETOOBIG;
    bm->prof = sc_alloc_array((size_t)bm->nm, sizeof *bm->prof);
    bm->holder = sc_alloc_array((size_t)bm->nm, sizeof *bm->holder);
    if (!bm->prof || !bm->holder)
        return SC_ENOMEM;
    int q = 0;
    for (int j = 0; j < bm->ng; j++) {
        int k = gj->list[bm->first + j];
        for (int i = g->start[k]; i < g->start[k + 1]; i++, q++) {
            const sc_body *b = &bodies[g->members[i]];
            int p = bm->np - 1;
            while (p >= 0 && p >= bm->np - PROFILE_SCAN && !same_profile(&bodies[bm->holder[p]], b))
                p--;
            if (p < 0 || p < bm->np - PROFILE_SCAN) {
                p = bm->np++;
                bm->holder[p] = g->members[i];
            }
            bm->prof[q] = p;
        }
    }
    return SC_OK;
}

/* A static body: world id, then as a group body always was. */
static void put_static(wbuf *w, const sc_body *b, int id)
{
    put(w, (uint64_t)id, 4);
    put(w, b->shape->hash, 8);
    put_gbody_f64(w, *b, 0, GBODY_F64);
    put_i32(w, b->state);
    put_i32(w, b->collided);
}

/* Whether any bit of b's force or torque is set. */
static int has_ft(const sc_body *b)
{
    static const double zero[3];
    return memcmp(b->force, zero, sizeof zero) != 0 || memcmp(b->torque, zero, sizeof zero) != 0;
}

/* A member's state (in a unit, and in a result with ft 0): flags u8
 * (state, collided << 2, force and torque sent << 4), x, q, v, w, rest_s,
 * (then) force, torque. */
static void put_member_state(wbuf *w, const sc_body *b, int ft)
{
    put(w, (uint64_t)(b->state | b->collided << 2 | ft << 4), 1);
    put_gbody_f64(w, *b, GF_X, GF_X + 4);
    put_f64s(w, &b->rest_s, 1);
    if (ft)
        put_gbody_f64(w, *b, GF_FORCE, GF_FORCE + 2);
}

/* put_member_state()'s record into b: a dynamic state (SC_FREE ..
 * SC_ASLEEP), collided 0..2, force and torque only where ft_ok (a unit;
 * not a result); doubles finite or verbatim. */
static void get_member_state(rbuf *r, sc_body *b, int ft_ok, int finite)
{
    unsigned flags = (unsigned)get(r, 1);
    int ft = (int)(flags >> 4 & 1);
    if (r->bad || flags >> 5 || (ft && !ft_ok) || (flags >> 2 & 3) > 2) {
        r->bad = 1;
        return;
    }
    b->state = (int)(flags & 3);
    b->collided = (int)(flags >> 2 & 3);
    get_gbody_f64(r, b, GF_X, GF_X + 4, finite);
    get_f64s(r, &b->rest_s, 1, finite);
    if (ft)
        get_gbody_f64(r, b, GF_FORCE, GF_FORCE + 2, finite);
}

static void write_group(wbuf *w, const void *job_, const void *bm_)
{
    const sc_job *job = job_;
    const bundle_map *bm = bm_;
    const sc_group_job *gj = job->group;
    const sc_groups *g = gj->g;
    const sc_frame_state *st = gj->st;
    const sc_frame_config *cfg = gj->cfg;
    put_header(w, MAGIC_UNIT, SC_UNIT_GROUP);
    put(w, (uint64_t)bm->ng, 4);
    put(w, (uint64_t)g->nstatics, 4);
    put(w, (uint64_t)bm->np, 4);
    put(w, (uint64_t)bm->nm, 4);
    put(w, (uint64_t)bm->nc, 4);
    put_i32(w, st->contacts_valid != 0);
    double head[5] = { gj->dt, cfg->gravity[0], cfg->gravity[1], cfg->gravity[2],
                       cfg->contact_tol_m };
    put_f64s(w, head, 5);
    put_i32(w, cfg->broadphase);
    put_i32(w, cfg->island_split);
    put_i32(w, cfg->toi_mode);
    put_i32(w, cfg->island_method);
    for (int j = 0; j < g->nstatics; j++)
        put_static(w, &st->bodies[g->statics[j]], g->statics[j]);
    for (int p = 0; p < bm->np; p++) {
        const sc_body *b = &st->bodies[bm->holder[p]];
        put(w, b->shape->hash, 8);
        put_gbody_f64(w, *b, 0, GBODY_KEEP);
    }
    for (int j = 0; j < bm->ng; j++) {
        int k = gj->list[bm->first + j];
        put(w, (uint64_t)(g->start[k + 1] - g->start[k]), 4);
        put(w, (uint64_t)(g->cstart[k + 1] - g->cstart[k]), 4);
    }
    int q = 0;
    for (int j = 0; j < bm->ng; j++) {
        int k = gj->list[bm->first + j];
        for (int i = g->start[k]; i < g->start[k + 1]; i++, q++) {
            const sc_body *b = &st->bodies[g->members[i]];
            put(w, (uint64_t)g->members[i], 4);
            put(w, (uint64_t)bm->prof[q], 4);
            put_member_state(w, b, has_ft(b));
        }
    }
    for (int j = 0; j < bm->ng; j++) {
        int k = gj->list[bm->first + j];
        for (int i = g->cstart[k]; i < g->cstart[k + 1]; i++) {
            const sc_contact *c = &st->contacts[g->contacts[i]];
            put_contact(w, c, copy_index(g, k, c->body_a), copy_index(g, k, c->body_b), 1);
        }
    }
}

static size_t pack_group(const sc_job *job, const sc_unit *u, unsigned char *buf, size_t cap)
{
    const sc_group_job *gj = job->group;
    /* only a master's groups (a received unit is not sent on) with
     * settings a receiver takes */
    if (!gj || !gj->g || !gj->list || u->islands < 1 || u->first < 0 ||
        u->first > gj->nlist - u->islands || !frame_cfg_ok(gj->cfg, gj->dt))
        return 0;
    bundle_map bm = { 0 };
    size_t n = map_bundle(job, u, &bm) == SC_OK ? emit(write_group, job, &bm, buf, cap) : 0;
    bundle_free(&bm);
    return n;
}

size_t sc_wire_unit_pack(const sc_job *job, const sc_unit *u, unsigned char *buf, size_t cap)
{
    if (!job || !u || u->kind != job->kind)
        return 0;
    if (job->kind == SC_UNIT_GROUP)
        return pack_group(job, u, buf, cap);
    if (job->kind == SC_UNIT_COLLIDE || job->kind == SC_UNIT_TOI) {
        if (u->count < 0 || u->count > MAX_PAIRS || u->first < 0 ||
            u->first > job->npairs - u->count)
            return 0;
        return emit(write_pairs, job, u, buf, cap);
    }
    if (job->kind != SC_UNIT_ISLAND || !job->islands || u->first < 0 || u->islands < 1 ||
        u->first > job->islands->count - u->islands)
        return 0;
    /* settings a receiver would refuse, or inject (tests only), are not
     * sent: such a unit is computed locally */
    if (!job->params || !params_ok(job->params))
        return 0;
    /* 0 also for an island the wire cannot carry (see map_island()) */
    island_map im = { 0 };
    size_t n = map_island(job, u->first, u->islands, &im) == SC_OK
                   ? emit(write_island, job, &im, buf, cap)
                   : 0;
    free(im.world);
    free(im.ends);
    return n;
}

static int decode_pairs(rbuf *r, int kind, sc_shape_lookup_fn lookup, void *ctx,
                        sc_wire_unit *wu)
{
    int toi = kind == SC_UNIT_TOI;
    uint32_t n = (uint32_t)get(r, 4);
    double tol = 0;
    if (toi)
        get_f64s(r, &tol, 1, 1);
    if (r->bad || n > MAX_PAIRS || !(tol >= 0) ||
        r->len - r->n != (size_t)n * PAIR_BYTES(toi ? 4 : 2))
        return SC_EFORMAT;
    if (n > 0 && !lookup)
        return SC_EINVAL;
    wu->pairs = sc_calloc_array(n, sizeof *wu->pairs);
    if (toi) {
        wu->toi = sc_alloc_array(n, sizeof *wu->toi);
    } else {
        wu->contacts = sc_calloc_array((size_t)n * SC_MAX_PAIR_CONTACTS, sizeof *wu->contacts);
        wu->ncontact = sc_calloc_array(n, sizeof *wu->ncontact);
    }
    if (!wu->pairs || (toi ? !wu->toi : !wu->contacts || !wu->ncontact))
        return SC_ENOMEM;
    for (uint32_t i = 0; i < n; i++) {
        sc_unit_pair *p = &wu->pairs[i];
        uint64_t ha = get(r, 8), hb = get(r, 8);
        p->body_a = get_i32(r);
        p->body_b = get_i32(r);
        uint64_t deepen = get(r, 1);    /* bit 0 deepen, bit 1 exact */
        p->deepen = (deepen & 1) != 0;
        p->exact = (deepen & 2) != 0;
        sc_pose *pose[4] = { &p->a0, &p->b0, &p->a1, &p->b1 };
        for (int k = 0; k < (toi ? 4 : 2); k++) {
            get_f64s(r, pose[k]->pos, 3, 1);
            get_f64s(r, pose[k]->quat, 4, 1);
        }
        if (toi)
            wu->toi[i] = 1;
        if (r->bad || p->body_a < 0 || p->body_b <= p->body_a || deepen > 3)
            return SC_EFORMAT;
        p->sa = lookup(ctx, ha);
        p->sb = lookup(ctx, hb);
        if (!p->sa || !p->sb || p->sa->hash != ha || p->sb->hash != hb)
            return SC_EFORMAT;
    }
    sc_job *job = &wu->job;
    job->pairs = wu->pairs;
    job->npairs = (int)n;
    job->contacts = wu->contacts;
    job->ncontact = wu->ncontact;
    job->tol_m = tol;
    job->toi = wu->toi;
    wu->unit.count = (int)n;
    return SC_OK;
}

static int decode_island(rbuf *r, sc_wire_unit *wu)
{
    uint32_t m = (uint32_t)get(r, 4), nm = (uint32_t)get(r, 4), nc = (uint32_t)get(r, 4);
    uint32_t nisl = (uint32_t)get(r, 4);
    double head[9];
    get_f64s(r, head, 9, 1);
    sc_contact_params p = { .bounce_speed = head[1], .slop = head[2], .baumgarte = head[3],
                            .tol = head[4], .gravity = { head[5], head[6], head[7] },
                            .push_tol = head[8] };
    p.split_contacts = get_i32(r);
    p.block_contacts = get_i32(r);
    p.max_sweeps = get_i32(r);
    p.cold = get_i32(r);
    p.impact_first = get_i32(r);
    p.island_method = get_i32(r);
    p.anderson = get_i32(r);
    if (r->bad || nm < 1 || nm > m || m > MAX_BODIES || nc > MAX_CONTACTS || nisl < 1 ||
        nisl > nm || !(head[0] > 0) || !params_ok(&p) ||
        r->len - r->n != (size_t)nisl * 8 + (size_t)m * BODY_BYTES +
                             (size_t)nc * (CONTACT_BYTES + IMPULSE_BYTES))
        return SC_EFORMAT;
    sc_islands *is = &wu->islands;
    wu->bodies = sc_calloc_array(m, sizeof *wu->bodies);
    wu->c = sc_calloc_array(nc, sizeof *wu->c);
    is->body_start = sc_calloc_array((size_t)nisl + 1, sizeof *is->body_start);
    is->bodies = sc_alloc_array(nm, sizeof *is->bodies);
    is->contact_start = sc_calloc_array((size_t)nisl + 1, sizeof *is->contact_start);
    is->contacts = sc_alloc_array(nc, sizeof *is->contacts);
    if (!wu->bodies || !wu->c || !is->body_start || !is->bodies || !is->contact_start ||
        !is->contacts)
        return SC_ENOMEM;
    for (uint32_t i = 0; i < nisl; i++) {
        uint32_t bm = (uint32_t)get(r, 4), bc = (uint32_t)get(r, 4);
        /* every island has a member; the counts add up (checked below) */
        if (r->bad || bm < 1 || bm > nm || bc > nc)
            return SC_EFORMAT;
        is->body_start[i + 1] = is->body_start[i] + (int)bm;
        is->contact_start[i + 1] = is->contact_start[i] + (int)bc;
        if (is->body_start[i + 1] > (int)nm || is->contact_start[i + 1] > (int)nc)
            return SC_EFORMAT;
    }
    if (is->body_start[nisl] != (int)nm || is->contact_start[nisl] != (int)nc)
        return SC_EFORMAT;
    for (uint32_t k = 0; k < m; k++) {
        get_body(r, &wu->bodies[k]);
        /* only members may change: the others are static or asleep */
        if (r->bad || (k >= nm && sc_body_movable(&wu->bodies[k])))
            return SC_EFORMAT;
    }
    for (uint32_t k = 0; k < nc; k++) {
        sc_contact *c = &wu->c[k];
        get_contact(r, c, 1, 1);
        int a = c->body_a, b = c->body_b;
        if (r->bad || a < 0 || b < 0 || a >= (int)m || b >= (int)m || a == b ||
            (a >= (int)nm && b >= (int)nm))
            return SC_EFORMAT;
        is->contacts[k] = (int)k;
    }
    for (uint32_t k = 0; k < nm; k++)
        is->bodies[k] = (int)k;
    is->count = (int)nisl;
    wu->nbodies = (int)m;
    wu->params = p;      /* inject 0 */
    sc_job *job = &wu->job;
    job->bodies = wu->bodies;
    job->c = wu->c;
    job->islands = is;
    job->h = head[0];
    job->params = &wu->params;
    wu->unit.count = (int)nc;
    wu->unit.islands = (int)nisl;
    return SC_OK;
}

/* A group's contacts (a unit's, or a result's): between two bodies of
 * the unit, body_a < body_b, not both static (stat[i] set: body i is),
 * sorted by pair as a frame keeps them. */
static int group_contact_ok(const sc_contact *c, int m, const unsigned char *stat, int *pa,
                            int *pb)
{
    int a = c->body_a, b = c->body_b;
    if (a < 0 || a >= b || b >= m || (stat[a] && stat[b]) || a < *pa || (a == *pa && b < *pb))
        return 0;
    *pa = a;
    *pb = b;
    return 1;
}

/* A member's world id and decode index, to order a unit's bodies. */
typedef struct id_at {
    uint32_t id;
    int at;
} id_at;

static int cmp_id_at(const void *x, const void *y)
{
    const id_at *a = x, *b = y;
    return (a->id > b->id) - (a->id < b->id);
}

/* The received unit's own groups (sc_group_job: g over its bodies, in
 * world order) and their arrays (one allocation). */
static int group_arrays(sc_wire_unit *wu, int ng, int ns, int nm, int nc)
{
    int m = ns + nm;
    size_t n = 2 * ((size_t)ng + 1) + (size_t)nm + (size_t)m + (size_t)ns + (size_t)nc;
    int *p = sc_alloc_array(n, sizeof *p);
    if (!p)
        return SC_ENOMEM;
    wu->gints = p;
    sc_groups *g = &wu->g;
    g->n = m;
    g->ngroups = ng;
    g->nstatics = ns;
    g->start = p;
    p += ng + 1;
    g->cstart = p;
    p += ng + 1;
    g->members = p;
    p += nm;
    g->gid = p;
    p += m;
    g->statics = p;
    p += ns;
    g->contacts = p;
    return SC_OK;
}

/* A member's profile: shape hash and the constants, checked as a member's
 * (a mass, its inverses, a shape the receiver holds). */
static void get_profile(rbuf *r, sc_body *b, sc_shape_lookup_fn lookup, void *ctx)
{
    uint64_t hash = get(r, 8);
    get_gbody_f64(r, b, 0, GBODY_KEEP, 1);
    if (!(b->mass > 0) || !(b->inv_mass > 0) || !inverses_ok(b))
        r->bad = 1;
    set_shape(r, b, hash, lookup, ctx);
}

/* A member: world id, profile, state (put_member_state()); v0, w0 and iw
 * are a substep's (set before they are read: integrate.c) and left 0. */
static uint32_t get_member(rbuf *r, sc_body *b, const sc_body *prof, uint32_t np)
{
    uint32_t id = (uint32_t)get(r, 4), p = (uint32_t)get(r, 4);
    if (r->bad || id > INT_MAX || p >= np) {
        r->bad = 1;
        return 0;
    }
    *b = prof[p];
    get_member_state(r, b, 1, 1);
    return id;
}

static int decode_group(rbuf *r, sc_shape_lookup_fn lookup, void *ctx, sc_wire_unit *wu)
{
    uint32_t ng = (uint32_t)get(r, 4), ns = (uint32_t)get(r, 4), np = (uint32_t)get(r, 4);
    uint32_t nm = (uint32_t)get(r, 4), nc = (uint32_t)get(r, 4);
    int valid = get_i32(r);
    double head[5];
    get_f64s(r, head, 5, 1);
    sc_frame_config cfg = { .gravity = { head[1], head[2], head[3] }, .contact_tol_m = head[4] };
    cfg.broadphase = get_i32(r);
    cfg.island_split = get_i32(r);
    cfg.toi_mode = get_i32(r);
    cfg.island_method = get_i32(r);
    /* every group has a member, every profile a holder; the last frame's
     * contacts only when they are valid (group.c); the length within what
     * the counts allow (forces and torques are optional) */
    if (r->bad || ng < 1 || ng > nm || nm > MAX_BODIES || ns > MAX_BODIES - nm || np < 1 ||
        np > nm || nc > MAX_CONTACTS || valid < 0 || valid > 1 || (!valid && nc > 0) ||
        !frame_cfg_ok(&cfg, head[0]))
        return SC_EFORMAT;
    size_t least = (size_t)ns * STATIC_BYTES + (size_t)np * PROFILE_BYTES +
                   (size_t)ng * 8 + (size_t)nm * MEMBER_BYTES +
                   (size_t)nc * (CONTACT_BYTES + IMPULSE_BYTES);
    size_t left = r->len - r->n;
    if (left < least || left - least > (size_t)nm * MEMBER_FT_BYTES)
        return SC_EFORMAT;
    if (!lookup)
        return SC_EINVAL;
    uint32_t m = ns + nm;
    sc_frame_state *st = &wu->gst;
    wu->bodies = sc_calloc_array(m, sizeof *wu->bodies);
    st->contacts = sc_calloc_array(nc > 0 ? nc : 1, sizeof *st->contacts);
    wu->gouts = sc_calloc_array(ng, sizeof *wu->gouts);
    sc_body *dec = sc_calloc_array(m, sizeof *dec);
    sc_body *prof = sc_calloc_array(np, sizeof *prof);
    id_at *order = sc_alloc_array(m, sizeof *order);
    int *rank = sc_alloc_array(m, sizeof *rank);
    int *ids = sc_alloc_array(m, sizeof *ids);
    unsigned char *stat = sc_alloc_array(m, 1);
    int track_cap = 0;
    int rc = wu->bodies && st->contacts && wu->gouts && dec && prof && order && rank && ids &&
                     stat && sc_track_reserve(&wu->track, &track_cap, (int)m) == SC_OK &&
                     group_arrays(wu, (int)ng, (int)ns, (int)nm, (int)nc) == SC_OK
                 ? SC_OK
                 : SC_ENOMEM;
    sc_groups *g = &wu->g;
    /* the static bodies (world ids ascending), the profiles, the groups'
     * counts, the members (each group's ids ascending) */
    for (uint32_t j = 0; j < ns && rc == SC_OK; j++) {
        order[j].id = (uint32_t)get(r, 4);
        order[j].at = (int)j;
        get_gbody(r, &dec[j], lookup, ctx);
        if (r->bad || order[j].id > INT_MAX || dec[j].inv_mass > 0 ||
            (j > 0 && order[j].id <= order[j - 1].id))
            rc = SC_EFORMAT;
    }
    for (uint32_t p = 0; p < np && rc == SC_OK; p++) {
        get_profile(r, &prof[p], lookup, ctx);
        if (r->bad)
            rc = SC_EFORMAT;
    }
    uint32_t sum_m = 0, sum_c = 0;
    for (uint32_t k = 0; k < ng && rc == SC_OK; k++) {
        uint32_t a = (uint32_t)get(r, 4), c = (uint32_t)get(r, 4);
        if (r->bad || a < 1 || a > nm - sum_m || c > nc - sum_c)
            rc = SC_EFORMAT;
        g->start[k] = (int)sum_m;
        g->cstart[k] = (int)sum_c;
        sum_m += a;
        sum_c += c;
    }
    if (rc == SC_OK && (sum_m != nm || sum_c != nc))
        rc = SC_EFORMAT;
    if (rc == SC_OK) {
        g->start[ng] = (int)nm;
        g->cstart[ng] = (int)nc;
    }
    for (uint32_t k = 0; k < ng && rc == SC_OK; k++)
        for (int i = g->start[k]; i < g->start[k + 1] && rc == SC_OK; i++) {
            uint32_t q = ns + (uint32_t)i;
            order[q].id = get_member(r, &dec[q], prof, np);
            order[q].at = (int)q;
            if (r->bad || (i > g->start[k] && order[q].id <= order[q - 1].id))
                rc = SC_EFORMAT;
        }
    /* world order: every id once */
    if (rc == SC_OK) {
        qsort(order, m, sizeof *order, cmp_id_at);
        for (uint32_t q = 0; q < m && rc == SC_OK; q++) {
            if (q > 0 && order[q].id == order[q - 1].id)
                rc = SC_EFORMAT;
            rank[order[q].at] = (int)q;
            wu->bodies[q] = dec[order[q].at];
        }
    }
    for (uint32_t q = 0; q < m && rc == SC_OK; q++)
        g->gid[q] = -1;
    for (uint32_t j = 0; j < ns && rc == SC_OK; j++)
        g->statics[j] = rank[j];
    for (uint32_t k = 0; k < ng && rc == SC_OK; k++)
        for (int i = g->start[k]; i < g->start[k + 1]; i++) {
            g->members[i] = rank[ns + (uint32_t)i];
            g->gid[g->members[i]] = (int)k;
        }
    /* each group's contacts, by its copy's ids (as a frame keeps them),
     * into the unit's */
    for (uint32_t k = 0; k < ng && rc == SC_OK; k++) {
        int mk = sc_group_ids(g, (int)k, ids), pa = -1, pb = -1;
        for (int q = 0; q < mk; q++)
            stat[q] = g->gid[ids[q]] != (int)k;
        for (int i = g->cstart[k]; i < g->cstart[k + 1] && rc == SC_OK; i++) {
            sc_contact *c = &st->contacts[i];
            get_contact(r, c, 1, 1);
            if (r->bad || !group_contact_ok(c, mk, stat, &pa, &pb)) {
                rc = SC_EFORMAT;
                break;
            }
            c->body_a = ids[c->body_a];
            c->body_b = ids[c->body_b];
            g->contacts[i] = i;
        }
    }
    free(dec);
    free(prof);
    free(order);
    free(rank);
    free(ids);
    free(stat);
    if (rc != SC_OK)
        return rc;
    wu->nbodies = (int)m;
    wu->cfg = cfg;
    st->bodies = wu->bodies;
    st->nbodies = (int)m;
    st->ncontacts = (int)nc;
    st->contact_cap = nc > 0 ? (int)nc : 1;
    st->contacts_valid = valid;
    /* its groups, run as the master's are (group.c) */
    wu->group = (sc_group_job){ .cfg = &wu->cfg, .st = st, .g = g, .list = NULL,
                                .nlist = (int)ng, .dt = head[0], .out = wu->gouts,
                                .track = &wu->track };
    sc_job *job = &wu->job;
    job->group = &wu->group;
    job->run_group = sc_group_unit_run;
    wu->unit.first = 0;
    wu->unit.count = (int)nm;
    wu->unit.islands = (int)ng;
    return SC_OK;
}

int sc_wire_unit_decode(const unsigned char *buf, size_t len, sc_shape_lookup_fn lookup,
                        void *lookup_ctx, sc_wire_unit *out)
{
    if (!out)
        return SC_EINVAL;
    memset(out, 0, sizeof *out);
    if (!buf && len)
        return SC_EINVAL;
    rbuf r = { buf, 0, len, 0 };
    int kind = get_header(&r, MAGIC_UNIT);
    int rc = kind < 0                 ? SC_EFORMAT
           : kind == SC_UNIT_ISLAND   ? decode_island(&r, out)
           : kind == SC_UNIT_GROUP    ? decode_group(&r, lookup, lookup_ctx, out)
                                      : decode_pairs(&r, kind, lookup, lookup_ctx, out);
    if (rc == SC_OK && r.n != len)
        rc = SC_EFORMAT;
    if (rc != SC_OK) {
        sc_wire_unit_free(out);
        return rc;
    }
    /* the job points into out: out must not be moved or copied */
    out->job.kind = out->unit.kind = kind;
    out->job.units = &out->unit;
    out->job.nunits = 1;
    out->unit.bytes = len;
    return SC_OK;
}

void sc_wire_unit_free(sc_wire_unit *wu)
{
    if (!wu)
        return;
    free(wu->pairs);
    free(wu->contacts);
    free(wu->ncontact);
    free(wu->toi);
    free(wu->bodies);
    free(wu->c);
    free(wu->gst.contacts);
    for (int k = 0; wu->gouts && k < wu->g.ngroups; k++)
        free(wu->gouts[k].contacts);
    free(wu->gouts);
    free(wu->gints);
    sc_track_free(&wu->track);
    sc_islands_free(&wu->islands);
    memset(wu, 0, sizeof *wu);
}

/* ---- results ---- */

/* The solve's counters (sc_solve_info), field by field: every int of it (a
 * field added there must be added here; test_unit_wire compares whole
 * infos of a local and a remote run), and pivots. blocks_shared stays
 * home: a daemon's island shares no blocks. */
#define INFO_INTS 26

static void info_ints(sc_solve_info *info, int *f[INFO_INTS])
{
    int *p[INFO_INTS] = { &info->failures,        &info->regularised, &info->lemke,
                          &info->collisions,      &info->split,       &info->split_fallbacks,
                          &info->blocks,          &info->block_fallbacks,
                          &info->nan_islands,     &info->sweeps_max,  &info->unconverged,
                          &info->solves,          &info->diverged,    &info->cold_starts,
                          &info->inelastic,       &info->energy_refused,
                          &info->restitution_scaled, &info->guessed,
                          &info->as_solves,       &info->as_fallbacks,
                          &info->as_iterations_max, &info->as_parts_max,
                          &info->as_interface_max, &info->whole_tries,
                          &info->whole_solved,    &info->sweeps };
    memcpy(f, p, sizeof p);
}

static void put_info(wbuf *w, sc_solve_info info)
{
    int *f[INFO_INTS];
    info_ints(&info, f);
    put(w, (uint64_t)info.pivots, 8);
    put(w, (uint64_t)info.as_iterations, 8);
    put(w, (uint64_t)info.factor_nnz_max, 8);
    put(w, (uint64_t)info.as_exchanges, 8);
    put(w, (uint64_t)info.as_exchange_bytes, 8);
    for (int k = 0; k < INFO_INTS; k++)
        put_i32(w, *f[k]);
    put_f64s(w, &info.residual_exact, 1);
    put_f64s(w, &info.residual_split, 1);
}

/* Counts must not be negative; the residuals are carried verbatim. */
static void get_info(rbuf *r, sc_solve_info *info)
{
    int *f[INFO_INTS];
    memset(info, 0, sizeof *info);
    info_ints(info, f);
    int64_t pivots = get_signed(r, 8);
    if (pivots < 0 || pivots > LONG_MAX)
        r->bad = 1;
    info->pivots = (long)pivots;
    long *l[] = { &info->as_iterations, &info->factor_nnz_max, &info->as_exchanges,
                  &info->as_exchange_bytes };
    for (size_t k = 0; k < sizeof l / sizeof l[0]; k++) {
        int64_t v = get_signed(r, 8);
        if (v < 0 || v > LONG_MAX)
            r->bad = 1;
        *l[k] = (long)v;
    }
    for (int k = 0; k < INFO_INTS; k++)
        if ((*f[k] = get_i32(r)) < 0)
            r->bad = 1;
    get_f64s(r, &info->residual_exact, 1, 0);
    get_f64s(r, &info->residual_split, 1, 0);
}

/* The figures of a group's frame that sc_stats_add_frame() and
 * sc_stats_add_solver() (clock.c) read, field by field: a field they
 * start to read must be added here (test_unit_wire compares them). */
#define STAT_F64 (SC_STAGE_COUNT + 6)
#define STAT_LONGS 13
#define STAT_SIZES 2
#define STAT_INTS 30

typedef struct stat_ptrs {
    double *d[STAT_F64];
    long *l[STAT_LONGS];
    size_t *z[STAT_SIZES];
    int *i[STAT_INTS];
} stat_ptrs;

static void stat_fields(sc_stats *s, stat_ptrs *p)
{
    for (int k = 0; k < SC_STAGE_COUNT; k++)
        p->d[k] = &s->frame.stage_s[k];
    double *d[] = {&s->frame.lcp.residual,           &s->frame.lcp.outer_residual,
                   &s->frame.detect.max_penetration, &s->frame.sched.sched_s,
                   &s->frame.sched.makespan_s,       &s->frame.sched.makespan_bound_s};
    long *l[STAT_LONGS] = {&s->frame.lcp.pivots,          &s->frame.lcp.blocks,
                           &s->frame.lcp.block_fallbacks, &s->frame.detect.collider_warnings,
                           &s->frame.sched.units,         &s->total.initial_overlaps,
                           &s->frame.detect.np_pairs,     &s->frame.detect.np_reused,
                           &s->frame.lcp.as_iterations,   &s->frame.lcp.factor_nnz_max,
                           &s->frame.lcp.as_exchanges,    &s->frame.lcp.as_exchange_bytes,
                           &s->frame.lcp.sweeps};
    size_t *z[STAT_SIZES] = { &s->total.arena_bytes, &s->total.unit_arena_bytes };
    int *i[STAT_INTS] = {
        &s->frame.detect.pairs,       &s->frame.detect.islands,     &s->frame.lcp.solves,
        &s->frame.lcp.fallbacks,      &s->frame.lcp.split,          &s->frame.lcp.sweeps_max,
        &s->frame.lcp.unconverged,    &s->frame.lcp.diverged,       &s->frame.lcp.cold_starts,
        &s->frame.lcp.regularised,    &s->frame.lcp.split_fallbacks, &s->frame.lcp.nan_islands,
        &s->frame.toi.substeps,       &s->frame.toi.backups,        &s->frame.toi.backup_regions,
        &s->frame.toi.backup_bodies,  &s->frame.toi.spec_contacts,  &s->frame.toi.spec_rounds,
        &s->frame.lcp.inelastic,      &s->frame.lcp.energy_refused,
        &s->frame.lcp.restitution_scaled, &s->frame.lcp.kept,       &s->frame.lcp.guessed,
        &s->frame.lcp.as_solves,      &s->frame.lcp.as_fallbacks,   &s->frame.lcp.as_iterations_max,
        &s->frame.lcp.as_parts_max,   &s->frame.lcp.as_interface_max,
        &s->frame.lcp.whole_tries,    &s->frame.lcp.whole_solved };
    _Static_assert(sizeof d / sizeof d[0] == STAT_F64 - SC_STAGE_COUNT, "stat doubles");
    memcpy(&p->d[SC_STAGE_COUNT], d, sizeof d);
    memcpy(p->l, l, sizeof l);
    memcpy(p->z, z, sizeof z);
    memcpy(p->i, i, sizeof i);
}

/* The figures of a group's frame, compactly: a mask u64 of the fields of
 * stat_fields() whose bits are not all 0, then those (f64s, i64s, u64s,
 * i32s in that order); a group of a falling part or two sets a handful. */
#define STAT_FIELDS (STAT_F64 + STAT_LONGS + STAT_SIZES + STAT_INTS)
_Static_assert(STAT_FIELDS <= 64, "one mask bit a field");

static uint64_t stats_mask(sc_stats s)
{
    stat_ptrs p;
    stat_fields(&s, &p);
    uint64_t mask = 0;
    int f = 0;
    static const double zd = 0;
    for (int k = 0; k < STAT_F64; k++, f++)
        mask |= (uint64_t)(memcmp(p.d[k], &zd, sizeof zd) != 0) << f;
    for (int k = 0; k < STAT_LONGS; k++, f++)
        mask |= (uint64_t)(*p.l[k] != 0) << f;
    for (int k = 0; k < STAT_SIZES; k++, f++)
        mask |= (uint64_t)(*p.z[k] != 0) << f;
    for (int k = 0; k < STAT_INTS; k++, f++)
        mask |= (uint64_t)(*p.i[k] != 0) << f;
    return mask;
}

static void put_stats_compact(wbuf *w, sc_stats s)
{
    stat_ptrs p;
    stat_fields(&s, &p);
    uint64_t mask = stats_mask(s);
    put(w, mask, 8);
    int f = 0;
    for (int k = 0; k < STAT_F64; k++, f++)
        if (mask >> f & 1)
            put_f64s(w, p.d[k], 1);
    for (int k = 0; k < STAT_LONGS; k++, f++)
        if (mask >> f & 1)
            put(w, (uint64_t)*p.l[k], 8);
    for (int k = 0; k < STAT_SIZES; k++, f++)
        if (mask >> f & 1)
            put(w, (uint64_t)*p.z[k], 8);
    for (int k = 0; k < STAT_INTS; k++, f++)
        if (mask >> f & 1)
            put_i32(w, *p.i[k]);
}

/* As get_stats(): doubles verbatim, counts not negative, the rest 0. */
static void get_stats_compact(rbuf *r, sc_stats *s)
{
    stat_ptrs p;
    memset(s, 0, sizeof *s);
    stat_fields(s, &p);
    uint64_t mask = get(r, 8);
    if (STAT_FIELDS < 64 && mask >> STAT_FIELDS)
        r->bad = 1;
    int f = 0;
    for (int k = 0; k < STAT_F64; k++, f++)
        if (mask >> f & 1)
            get_f64s(r, p.d[k], 1, 0);
    for (int k = 0; k < STAT_LONGS; k++, f++) {
        if (!(mask >> f & 1))
            continue;
        int64_t v = get_signed(r, 8);
        if (v < 0 || v > LONG_MAX)
            r->bad = 1;
        *p.l[k] = (long)v;
    }
    for (int k = 0; k < STAT_SIZES; k++, f++) {
        if (!(mask >> f & 1))
            continue;
        uint64_t v = get(r, 8);
        if (v > SIZE_MAX)
            r->bad = 1;
        *p.z[k] = (size_t)v;
    }
    for (int k = 0; k < STAT_INTS; k++, f++)
        if ((mask >> f & 1) && (*p.i[k] = get_i32(r)) < 0)
            r->bad = 1;
}

/* A received unit's outputs, group by group: rc i32, its figures, per
 * member (the unit's order) flags u8 (state, collided << 2), x, q, v, w,
 * rest_s, its track (dev f64, points u8, the points), then its new
 * contacts (none when it failed: a failed frame makes none here either,
 * group.c) by its copy's ids. */
static void write_group_result(wbuf *w, const sc_wire_unit *wu)
{
    const sc_group_job *gj = &wu->group;
    const sc_groups *g = gj->g;
    const sc_frame_state *st = gj->st;
    for (int k = 0; k < g->ngroups; k++) {
        const sc_group_out *out = &gj->out[k];
        put_i32(w, out->rc);
        put_stats_compact(w, out->stats);
        for (int i = g->start[k]; i < g->start[k + 1]; i++) {
            int q = g->members[i];
            put_member_state(w, &st->bodies[q], 0);
            int n = gj->track->count[q];
            put_f64s(w, &gj->track->dev[q], 1);
            put_f64s(w, &gj->track->adev[q], 1);
            put(w, (uint64_t)n, 1);
            if (n > 0)
                put_f64s(w, &gj->track->pt[(size_t)q * SC_TRACK_MAX * SC_TRACK_STRIDE],
                         SC_TRACK_STRIDE * n);
        }
        int nc = out->rc == SC_OK ? out->ncontacts : 0;
        put(w, (uint64_t)nc, 4);
        for (int j = 0; j < nc; j++) {
            const sc_contact *c = &out->contacts[j];
            put_contact(w, c, copy_index(g, k, c->body_a), copy_index(g, k, c->body_b), 1);
        }
    }
}

static void write_result(wbuf *w, const void *wu_, const void *unused)
{
    (void)unused;
    const sc_wire_unit *wu = wu_;
    const sc_job *job = &wu->job;
    const sc_unit *u = &wu->unit;
    int island = job->kind == SC_UNIT_ISLAND;
    int nm = island ? job->islands->body_start[job->islands->count] : 0;
    put_header(w, MAGIC_RESULT, job->kind);
    put(w, (uint64_t)(island ? nm : u->count), 4);
    put_i32(w, u->rc);
    put(w, (uint64_t)u->messages, 8);
    put_info(w, u->info);
    if (job->kind == SC_UNIT_GROUP) {
        write_group_result(w, wu);
        return;
    }
    for (int i = 0; !island && i < u->count; i++) {
        if (job->kind == SC_UNIT_TOI) {
            put_f64s(w, &job->toi[i], 1);
            continue;
        }
        int n = job->ncontact[i];
        SC_ASSERT(n >= 0 && n <= SC_MAX_PAIR_CONTACTS);
        put(w, (uint64_t)n, 1);
        for (int k = 0; k < n; k++) {
            const sc_contact *c = &job->contacts[(size_t)i * SC_MAX_PAIR_CONTACTS + (size_t)k];
            put_contact(w, c, c->body_a, c->body_b, 0);
        }
    }
    if (!island)
        return;
    const sc_islands *is = job->islands;
    int nc = is->contact_start[is->count];
    put(w, (uint64_t)nc, 4);
    for (int k = 0; k < nm; k++) {
        const sc_body *b = &job->bodies[is->bodies[k]];
        put_body_f64(w, *b, MEMBER_F64);
        put_i32(w, b->collided);
    }
    for (int k = 0; k < nc; k++) {
        put_f64s(w, job->c[is->contacts[k]].impulse, 3);
        put_f64s(w, &job->c[is->contacts[k]].impulse_dt, 1);
    }
}

size_t sc_wire_result_pack(const sc_wire_unit *wu, unsigned char *buf, size_t cap)
{
    if (!wu || wu->job.units != &wu->unit ||
        (wu->job.kind == SC_UNIT_GROUP && wu->job.group != &wu->group))
        return 0;
    return emit(write_result, wu, NULL, buf, cap);
}

/* A group result's side of the master: room for the largest group's
 * copy (ids, static flags), each group's contact count (the check) and
 * where its contacts go (the write). */
typedef struct group_res {
    int *ids;
    unsigned char *stat;        /* per body of the copy: static */
    int *nc;                    /* per group of the unit */
    sc_contact **c;
} group_res;

/* The group part of a result for u (after the common part); rc is the
 * result's, the first of its groups'. Written to the master's bodies,
 * tracks and out[] only when write. */
static int read_group_result(rbuf *r, const sc_job *job, const sc_unit *u, int write, int rc,
                             group_res *gr)
{
    const sc_group_job *gj = job->group;
    const sc_groups *g = gj->g;
    int first_rc = SC_OK;
    for (int j = 0; j < u->islands; j++) {
        int k = gj->list[u->first + j];
        const int *mem = &g->members[g->start[k]];
        int nm = g->start[k + 1] - g->start[k];
        int grc = get_i32(r);
        sc_stats stats;
        get_stats_compact(r, &stats);
        if (r->bad || grc > 0)
            return SC_EFORMAT;
        if (first_rc == SC_OK)
            first_rc = grc;
        sc_body scratch = { 0 };
        for (int i = 0; i < nm; i++) {
            sc_body *b = write ? &gj->st->bodies[mem[i]] : &scratch;
            /* a member stays dynamic */
            get_member_state(r, b, 0, 0);
            /* its track: how far it went from its drift and turned from
             * its spin, and its points (times within the frame, in order,
             * unit quaternions) */
            double dev, adev;
            get_f64s(r, &dev, 1, 1);
            get_f64s(r, &adev, 1, 1);
            unsigned n = (unsigned)get(r, 1);
            if (r->bad || !(dev >= 0) || !(adev >= 0) || n > SC_TRACK_MAX)
                return SC_EFORMAT;
            enum { S = SC_TRACK_STRIDE };
            double pt[SC_TRACK_MAX * S];
            get_f64s(r, pt, S * (int)n, 1);
            for (unsigned p = 0; p < n && !r->bad; p++)
                if (pt[S * p] < 0 || pt[S * p] > gj->dt || (p > 0 && pt[S * p] < pt[S * (p - 1)]) ||
                    fabs(q_dot(&pt[S * p + 4], &pt[S * p + 4]) - 1) > 1e-6)
                    return SC_EFORMAT;
            if (r->bad)
                return SC_EFORMAT;
            if (write && gj->track) {
                gj->track->dev[mem[i]] = dev;
                gj->track->adev[mem[i]] = adev;
                gj->track->count[mem[i]] = (int)n;
                memcpy(&gj->track->pt[(size_t)mem[i] * SC_TRACK_MAX * S], pt,
                       (size_t)n * S * sizeof *pt);
            }
        }
        uint32_t nc = (uint32_t)get(r, 4);
        if (r->bad || nc > MAX_CONTACTS || (grc != SC_OK && nc > 0) ||
            r->len - r->n < (size_t)nc * (CONTACT_BYTES + IMPULSE_BYTES) ||
            (write && (int)nc != gr->nc[j]))
            return SC_EFORMAT;
        int m = sc_group_ids(g, k, gr->ids);
        for (int q = 0; q < m; q++)
            gr->stat[q] = g->gid[gr->ids[q]] != k;
        int pa = -1, pb = -1;
        for (uint32_t q = 0; q < nc; q++) {
            sc_contact c;
            get_contact(r, &c, 0, 1);
            if (r->bad || !group_contact_ok(&c, m, gr->stat, &pa, &pb))
                return SC_EFORMAT;
            if (write) {
                c.body_a = gr->ids[c.body_a];
                c.body_b = gr->ids[c.body_b];
                gr->c[j][q] = c;
            }
        }
        gr->nc[j] = (int)nc;
        if (write) {
            sc_group_out *out = &gj->out[k];
            memset(out, 0, sizeof *out);
            out->rc = grc;
            out->stats = stats;
            out->contacts = nc > 0 ? gr->c[j] : NULL;
            out->ncontacts = (int)nc;
            gr->c[j] = NULL;
        }
    }
    return first_rc == rc ? SC_OK : SC_EFORMAT;
}

/* Read a result for u; write it to the job and u only when write is set
 * (the caller validates the whole buffer first, then writes). */
static int read_result(rbuf *r, const sc_job *job, sc_unit *u, int write, group_res *gr)
{
    int island = job->kind == SC_UNIT_ISLAND, group = job->kind == SC_UNIT_GROUP;
    int pairs = !island && !group;
    const sc_islands *is = job->islands;
    int i0 = island ? is->body_start[u->first] : u->first;
    int count = island ? is->body_start[u->first + u->islands] - i0
                       : u->count;
    if (get_header(r, MAGIC_RESULT) != job->kind || get(r, 4) != (uint64_t)count)
        return SC_EFORMAT;
    int rc = get_i32(r);
    int64_t msgs = get_signed(r, 8);
    sc_solve_info info;
    get_info(r, &info);
    if (r->bad || rc > 0 || msgs < 0 || msgs > LONG_MAX)
        return SC_EFORMAT;
    if (group) {
        int grc = read_group_result(r, job, u, write, rc, gr);
        if (grc != SC_OK)
            return grc;
    }
    for (int i = i0; pairs && i < i0 + count; i++) {
        if (job->kind == SC_UNIT_TOI) {
            double t;
            get_f64s(r, &t, 1, 0);
            if (write)
                job->toi[i] = t;
            continue;
        }
        const sc_unit_pair *p = &job->pairs[i];
        int n = (int)get(r, 1);
        if (n > SC_MAX_PAIR_CONTACTS)
            return SC_EFORMAT;
        for (int k = 0; k < n; k++) {
            sc_contact c;
            get_contact(r, &c, 0, 0);
            if (c.body_a != p->body_a || c.body_b != p->body_b)
                return SC_EFORMAT;
            if (write)
                job->contacts[(size_t)i * SC_MAX_PAIR_CONTACTS + (size_t)k] = c;
        }
        if (write)
            job->ncontact[i] = n;
    }
    /* an island's contacts: the master's unit's, in its order (the
     * receiver numbered them so); the count must be theirs */
    int c0 = island ? is->contact_start[u->first] : 0;
    int nc = island ? is->contact_start[u->first + u->islands] - c0 : 0;
    if (island && get(r, 4) != (uint64_t)nc)
        return SC_EFORMAT;
    sc_body scratch = { 0 };
    for (int k = 0; island && k < count; k++) {
        sc_body *b = write ? &job->bodies[is->bodies[i0 + k]] : &scratch;
        int collided;
        get_body_f64(r, b, MEMBER_F64, 0);
        if ((collided = get_i32(r)) < 0 || collided > 2)
            return SC_EFORMAT;
        b->collided = collided;
    }
    for (int k = 0; k < nc; k++) {
        double imp[4];
        get_f64s(r, imp, 4, 0);
        if (write) {
            memcpy(job->c[is->contacts[c0 + k]].impulse, imp, 3 * sizeof *imp);
            job->c[is->contacts[c0 + k]].impulse_dt = imp[3];
        }
    }
    if (r->bad || r->n != r->len)
        return SC_EFORMAT;
    if (write) {
        u->rc = rc;
        u->messages = (long)msgs;
        u->info = info;
    }
    return SC_OK;
}

/* Room for the largest of u's groups' copies, for read_result(). */
static int group_res_init(const sc_job *job, const sc_unit *u, group_res *gr)
{
    const sc_group_job *gj = job->group;
    const sc_groups *g = gj->g;
    int big = 0;
    for (int j = 0; j < u->islands; j++) {
        int k = gj->list[u->first + j];
        big = g->start[k + 1] - g->start[k] > big ? g->start[k + 1] - g->start[k] : big;
    }
    size_t m = (size_t)big + (size_t)g->nstatics;
    gr->ids = sc_alloc_array(m > 0 ? m : 1, sizeof *gr->ids);
    gr->stat = sc_alloc_array(m > 0 ? m : 1, 1);
    gr->nc = sc_calloc_array((size_t)u->islands, sizeof *gr->nc);
    gr->c = sc_calloc_array((size_t)u->islands, sizeof *gr->c);
    if (!gr->ids || !gr->stat || !gr->nc || !gr->c)
        return SC_ENOMEM;
    return SC_OK;
}

static void group_res_free(group_res *gr, int n)
{
    for (int j = 0; gr->c && j < n; j++)
        free(gr->c[j]);
    free(gr->c);
    free(gr->nc);
    free(gr->ids);
    free(gr->stat);
}

int sc_wire_result_apply(const sc_job *job, sc_unit *u, const unsigned char *buf, size_t len)
{
    if (!job || !u || (!buf && len) || u->kind != job->kind || u->first < 0)
        return SC_EINVAL;
    int bad;
    switch (job->kind) {
    case SC_UNIT_COLLIDE:
    case SC_UNIT_TOI:
        bad = u->count < 0 || u->first > job->npairs - u->count;
        break;
    case SC_UNIT_ISLAND:
        bad = !job->islands || u->islands < 1 || u->first > job->islands->count - u->islands;
        break;
    case SC_UNIT_GROUP:
        /* a master's group job (a received one is not answered to) */
        bad = !job->group || !job->group->g || !job->group->list || u->islands < 1 ||
              u->first > job->group->nlist - u->islands;
        break;
    default:
        bad = 1;
    }
    if (bad)
        return SC_EINVAL;
    group_res gr = { 0 };
    int rc = job->kind == SC_UNIT_GROUP ? group_res_init(job, u, &gr) : SC_OK;
    rbuf r = { buf, 0, len, 0 };
    if (rc == SC_OK)
        rc = read_result(&r, job, u, 0, &gr);
    /* the contacts' room before anything is written: the write cannot fail */
    for (int j = 0; rc == SC_OK && job->kind == SC_UNIT_GROUP && j < u->islands; j++)
        if (gr.nc[j] > 0 && !(gr.c[j] = sc_alloc_array((size_t)gr.nc[j], sizeof *gr.c[j])))
            rc = SC_ENOMEM;
    if (rc == SC_OK) {
        r = (rbuf){ buf, 0, len, 0 };
        rc = read_result(&r, job, u, 1, &gr);
        SC_ASSERT(rc == SC_OK);
    }
    if (job->kind == SC_UNIT_GROUP)
        group_res_free(&gr, u->islands);
    return rc;
}
