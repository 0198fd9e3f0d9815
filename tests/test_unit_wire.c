/* test_unit_wire.c - the wire form of work units (lib/net/unit_wire.c): a unit
 * packed, decoded, run elsewhere and its result applied gives the bits a
 * local run gives, for narrow-phase, time-of-impact, island and motion-group
 * units of a real bolts-and-nuts scene; malformed buffers are refused,
 * never crash.
 * (Internal API: lib/net/unit_wire.h, lib/api/world.h.) */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "unit_wire.h"
#include "world.h"

/* the kinds that travel: all */
#define WIRE_KINDS (SC_UNIT_GROUP + 1)

#define NBODIES 30
#define DT (1.0 / 60.0)
#define FRAMES 100            /* the bolts land from frame 60 on (seed 7) */
#define TOI_BACK 5            /* TOI units span frames FRAMES - TOI_BACK .. FRAMES */

/* The contact parameters of lib/core/frame.c (the default island split). */
static const sc_contact_params params = { .bounce_speed = 0.1, .slop = 0.5e-3, .baumgarte = 0.2,
                                          .split_contacts = SC_ISLAND_SPLIT_DEFAULT,
                                          .block_contacts = 4, .tol = 1e-3, .max_sweeps = 50 };

static uint64_t rng = 0x853c49e6748fea9bULL;
static uint64_t next_rand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

static sc_world *make_world(void)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = 1;
    sc_world *w = sc_world_create(&cfg);
    assert_non_null(w);
    assert_int_equal(sc_scene_bolts_nuts(w, NBODIES, 7), SC_OK);
    return w;
}

/* A world of NBODIES bolts and nuts whose frames run by motion groups:
 * the local time-of-impact mode, or motion groups in the world mode. */
static sc_world *make_group_world(int toi_local)
{
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = 1;
    if (toi_local)
        cfg.toi_mode = SC_TOI_LOCAL;
    else
        cfg.motion_groups = 1;
    sc_world *w = sc_world_create(&cfg);
    assert_non_null(w);
    assert_int_equal(sc_scene_bolts_nuts(w, NBODIES, 7), SC_OK);
    return w;
}

/* The receiver's shape cache: the world's shapes by content hash; skip
 * (when not 0) is a hash the cache does not hold. */
typedef struct cache {
    const sc_world *w;
    uint64_t skip;
} cache;

static const sc_shape *lookup(void *ctx, uint64_t hash)
{
    const cache *c = ctx;
    for (int i = 0; i < c->w->st.nbodies; i++) {
        const sc_shape *s = c->w->st.bodies[i].shape;
        if (s->hash == hash && hash != c->skip)
            return s;
    }
    return NULL;
}

static unsigned char *pack_unit(const sc_job *job, const sc_unit *u, size_t *len)
{
    size_t n = sc_wire_unit_pack(job, u, NULL, 0);
    assert_true(n > 0);
    unsigned char *buf = malloc(n);
    assert_non_null(buf);
    /* too small a buffer is left alone */
    memset(buf, 0xEE, n);
    assert_int_equal(sc_wire_unit_pack(job, u, buf, n - 1), n);
    for (size_t i = 0; i < n; i++)
        assert_int_equal(buf[i], 0xEE);
    assert_int_equal(sc_wire_unit_pack(job, u, buf, n), n);
    *len = n;
    return buf;
}

/* What a remote node does with a unit: decode, run, pack the result. */
static unsigned char *remote_run(sc_np_ctx *np, const unsigned char *unit, size_t len,
                                 cache *cc, size_t *rlen)
{
    sc_wire_unit wu;
    assert_int_equal(sc_wire_unit_decode(unit, len, lookup, cc, &wu), SC_OK);
    sc_unit_run(np, &wu.job, &wu.unit);
    size_t n = sc_wire_result_pack(&wu, NULL, 0);
    assert_true(n > 0);
    unsigned char *buf = malloc(n);
    assert_non_null(buf);
    assert_int_equal(sc_wire_result_pack(&wu, buf, n), n);
    sc_wire_unit_free(&wu);
    *rlen = n;
    return buf;
}

/* Unit u of job_l run here, and the same unit of job_r (same inputs, its
 * own outputs) run through the wire: rc, messages and info must agree. */
static sc_unit run_both(sc_np_ctx *local, sc_np_ctx *remote, cache *cc, const sc_job *job_l,
                        const sc_job *job_r, const sc_unit *u)
{
    sc_unit ul = *u, ur = *u;
    sc_unit_run(local, job_l, &ul);
    size_t len, rlen;
    unsigned char *buf = pack_unit(job_r, &ur, &len);
    unsigned char *res = remote_run(remote, buf, len, cc, &rlen);
    ur.rc = 99;
    ur.messages = -1;
    assert_int_equal(sc_wire_result_apply(job_r, &ur, res, rlen), SC_OK);
    assert_int_equal(ul.rc, SC_OK);
    assert_int_equal(ur.rc, ul.rc);
    assert_int_equal(ur.messages, ul.messages);
    assert_memory_equal(&ur.info, &ul.info, sizeof ul.info);
    free(buf);
    free(res);
    return ul;
}

/* ---- pair units (narrow phase, time of impact) ---- */

typedef struct pairs {
    sc_unit_pair *p;
    int n;
    int hits;                 /* pairs touching at the end */
} pairs;

static int touching(const sc_contact *c, int n, int a, int b)
{
    for (int k = 0; k < n; k++)
        if (c[k].body_a == a && c[k].body_b == b)
            return 1;
    return 0;
}

/* Every pair in contact at the end plus every neighbour pair (i, i + 1)
 * (mostly apart, the floor with body 1), moving from the poses of `from`
 * to those of w (COLLIDE units read the first only). */
static pairs make_pairs(const sc_world *w, const sc_body *from, const sc_contact *c0, int n0)
{
    pairs ps = { 0 };
    ps.p = calloc((size_t)w->st.ncontacts + (size_t)w->st.nbodies, sizeof *ps.p);
    assert_non_null(ps.p);
    for (int k = 0; k < w->st.ncontacts + w->st.nbodies - 1; k++) {
        int a, b;
        if (k < w->st.ncontacts) {
            const sc_contact *c = &w->st.contacts[k];
            if (k > 0 && c[-1].body_a == c->body_a && c[-1].body_b == c->body_b)
                continue;
            a = c->body_a;
            b = c->body_b;
            ps.hits++;
        } else {
            a = k - w->st.ncontacts;
            b = a + 1;
        }
        sc_unit_pair *p = &ps.p[ps.n++];
        p->sa = w->st.bodies[a].shape;
        p->sb = w->st.bodies[b].shape;
        p->body_a = a;
        p->body_b = b;
        p->deepen = touching(c0, n0, a, b);
        sc_body_pose(&from[a], &p->a0);
        sc_body_pose(&from[b], &p->b0);
        sc_body_pose(&w->st.bodies[a], &p->a1);
        sc_body_pose(&w->st.bodies[b], &p->b1);
    }
    return ps;
}

typedef struct scene {
    sc_world *w;
    sc_world *gw;             /* the same by motion groups (local mode) */
    sc_body *from;            /* bodies TOI_BACK frames before the end */
    sc_contact *c0;           /* and their contacts */
    int n0;
    pairs pc, pt;             /* COLLIDE: at the end; TOI: from `from` to the end */
} scene;

static int group_sample_ok(const scene *s);

static int scene_setup(void **state)
{
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    s->w = make_world();
    for (int f = 0; f < FRAMES; f++) {
        if (f == FRAMES - TOI_BACK) {
            size_t nb = (size_t)s->w->st.nbodies, nc = (size_t)s->w->st.ncontacts;
            s->from = malloc(nb * sizeof *s->from);
            s->c0 = malloc((nc ? nc : 1) * sizeof *s->c0);
            assert_true(s->from && s->c0);
            memcpy(s->from, s->w->st.bodies, nb * sizeof *s->from);
            memcpy(s->c0, s->w->st.contacts, nc * sizeof *s->c0);
            s->n0 = (int)nc;
        }
        assert_int_equal(sc_world_step(s->w, DT), SC_OK);
    }
    s->gw = make_group_world(1);
    for (int f = 0; f < FRAMES; f++)
        assert_int_equal(sc_world_step(s->gw, DT), SC_OK);
    /* on until the group sample (samples_init()) has two members and two
     * contacts: since held collisions bounce where they touch, each part
     * lies alone at frame FRAMES */
    for (int f = 0; f < 3 * FRAMES && !group_sample_ok(s); f++)
        assert_int_equal(sc_world_step(s->gw, DT), SC_OK);
    assert_true(group_sample_ok(s));
    s->pc = make_pairs(s->w, s->w->st.bodies, s->c0, s->n0);
    s->pt = make_pairs(s->w, s->from, s->c0, s->n0);
    assert_true(s->pc.hits > 0);
    *state = s;
    return 0;
}

static int scene_teardown(void **state)
{
    scene *s = *state;
    if (!s)
        return 0;
    sc_world_destroy(s->w);
    sc_world_destroy(s->gw);
    free(s->from);
    free(s->c0);
    free(s->pc.p);
    free(s->pt.p);
    free(s);
    return 0;
}

/* Outputs of a pair job, pre-filled with a pattern so that any slot
 * written in one copy and not the other shows. */
typedef struct outputs {
    sc_contact *contacts;
    int *ncontact;
    double *toi;
} outputs;

static void outputs_init(outputs *o, int n)
{
    o->contacts = malloc((size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *o->contacts);
    o->ncontact = malloc((size_t)n * sizeof *o->ncontact);
    o->toi = malloc((size_t)n * sizeof *o->toi);
    assert_true(o->contacts && o->ncontact && o->toi);
    memset(o->contacts, 0xA5, (size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *o->contacts);
    memset(o->ncontact, 0x5A, (size_t)n * sizeof *o->ncontact);
    for (int i = 0; i < n; i++)
        o->toi[i] = -7;
}

static void outputs_free(outputs *o)
{
    free(o->contacts);
    free(o->ncontact);
    free(o->toi);
}

static sc_job pair_job(int kind, const scene *s, outputs *o)
{
    sc_job job;
    memset(&job, 0, sizeof job);
    job.kind = kind;
    const pairs *ps = kind == SC_UNIT_TOI ? &s->pt : &s->pc;
    job.pairs = ps->p;
    job.npairs = ps->n;
    job.contacts = o->contacts;
    job.ncontact = o->ncontact;
    job.toi = o->toi;
    job.tol_m = s->w->cfg.contact_tol_m;
    return job;
}

/* Units [0, n/3), [n/3, 2n/3), [2n/3, n) and an empty one. */
static void check_pair_kind(const scene *s, int kind)
{
    int n = s->pc.n;
    outputs ol, or_;
    outputs_init(&ol, n);
    outputs_init(&or_, n);
    sc_job jl = pair_job(kind, s, &ol), jr = pair_job(kind, s, &or_);
    sc_np_ctx *local = sc_np_create(), *remote = sc_np_create();
    assert_true(local && remote);
    cache cc = { s->w, 0 };
    int cut[] = { 0, n / 3, 2 * n / 3, n, n };
    for (int k = 0; k < 4; k++) {
        sc_unit u = { .kind = kind, .first = cut[k], .count = cut[k + 1] - cut[k] };
        run_both(local, remote, &cc, &jl, &jr, &u);
    }
    if (kind == SC_UNIT_COLLIDE) {
        assert_memory_equal(ol.ncontact, or_.ncontact, (size_t)n * sizeof *ol.ncontact);
        assert_memory_equal(ol.contacts, or_.contacts,
                            (size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *ol.contacts);
        int with = 0;
        for (int i = 0; i < n; i++)
            with += ol.ncontact[i] > 0;
        /* the pairs in contact at the end of the frame still are */
        assert_true(with >= s->pc.hits);
        print_message("collide: %d pairs, %d with contacts\n", n, with);
    } else {
        assert_memory_equal(ol.toi, or_.toi, (size_t)n * sizeof *ol.toi);
        int hits = 0;
        for (int i = 0; i < n; i++) {
            assert_true(ol.toi[i] >= 0 && ol.toi[i] <= 1);
            hits += ol.toi[i] < 1;
        }
        print_message("toi: %d pairs, %d impacts\n", n, hits);
    }
    sc_np_destroy(local);
    sc_np_destroy(remote);
    outputs_free(&ol);
    outputs_free(&or_);
}

static void test_collide_unit_through_wire_is_bit_identical(void **state)
{
    check_pair_kind(*state, SC_UNIT_COLLIDE);
}

static void test_toi_unit_through_wire_is_bit_identical(void **state)
{
    check_pair_kind(*state, SC_UNIT_TOI);
}

/* ---- island units ---- */

typedef struct islands_job {
    sc_islands is;
    unsigned char *joins;
    sc_body *b0, *bl, *br;    /* the bodies before, and local and remote copies */
    sc_contact *c0, *cl, *cr; /* the contacts (their impulses: the warm start), the same */
    int nc;
    sc_job jl, jr;
} islands_job;

/* With the solver settings p (the world's own solve used frame.c's). */
static void islands_job_init_p(islands_job *ij, const sc_world *w, const sc_contact_params *p)
{
    size_t n = (size_t)w->st.nbodies, nc = (size_t)w->st.ncontacts;
    memset(ij, 0, sizeof *ij);
    ij->joins = malloc(n);
    ij->b0 = malloc(n * sizeof *ij->b0);
    ij->bl = malloc(n * sizeof *ij->bl);
    ij->br = malloc(n * sizeof *ij->br);
    assert_true(ij->joins && ij->b0 && ij->bl && ij->br);
    /* the solve writes each contact's impulse: each copy has its own */
    ij->nc = (int)nc;
    ij->c0 = malloc((nc ? nc : 1) * sizeof *ij->c0);
    ij->cl = malloc((nc ? nc : 1) * sizeof *ij->cl);
    ij->cr = malloc((nc ? nc : 1) * sizeof *ij->cr);
    assert_true(ij->c0 && ij->cl && ij->cr);
    memcpy(ij->c0, w->st.contacts, nc * sizeof *ij->c0);
    memcpy(ij->cl, ij->c0, nc * sizeof *ij->cl);
    memcpy(ij->cr, ij->c0, nc * sizeof *ij->cr);
    for (size_t i = 0; i < n; i++)
        ij->joins[i] = (unsigned char)sc_body_movable(&w->st.bodies[i]);
    assert_int_equal(sc_islands_build(NULL, w->st.nbodies, ij->joins, w->st.contacts, w->st.ncontacts, &ij->is),
                     SC_OK);
    memcpy(ij->b0, w->st.bodies, n * sizeof *ij->b0);
    /* non-members' collided cleared, so that a solve marking them shows */
    for (size_t i = 0; i < n; i++)
        if (!ij->joins[i])
            ij->b0[i].collided = 0;
    memcpy(ij->bl, ij->b0, n * sizeof *ij->bl);
    memcpy(ij->br, ij->b0, n * sizeof *ij->br);
    sc_job job;
    memset(&job, 0, sizeof job);
    job.kind = SC_UNIT_ISLAND;
    job.islands = &ij->is;
    job.h = DT;
    job.params = p;
    ij->jl = ij->jr = job;
    ij->jl.bodies = ij->bl;
    ij->jr.bodies = ij->br;
    ij->jl.c = ij->cl;
    ij->jr.c = ij->cr;
}

static void islands_job_init(islands_job *ij, const sc_world *w)
{
    islands_job_init_p(ij, w, &params);
}

static void islands_job_free(islands_job *ij)
{
    sc_islands_free(&ij->is);
    free(ij->joins);
    free(ij->b0);
    free(ij->bl);
    free(ij->br);
    free(ij->c0);
    free(ij->cl);
    free(ij->cr);
}

static int has_impulse(const sc_contact *c)
{
    return c->impulse[0] != 0 || c->impulse[1] != 0 || c->impulse[2] != 0;
}

/* A unit of islands [i, i + n), each solved on its own. */
static sc_unit island_unit(const sc_islands *is, int i, int n)
{
    sc_unit u = { .kind = SC_UNIT_ISLAND, .first = i, .islands = n,
                  .count = is->contact_start[i + n] - is->contact_start[i] };
    return u;
}

/* The solver settings the island units are solved with: frame.c's; every
 * island of more than two contacts split into blocks (sweeps from the warm
 * start); the same without warm starts; one sweep at most (unconverged);
 * the local mode's impacts first (which writes v0, w0: they come back). */
#define NSETTINGS 5
static sc_contact_params setting(int k)
{
    sc_contact_params p = params;
    if (k == 1)
        p.split_contacts = 2;
    if (k == 2) {
        p.split_contacts = 2;
        p.cold = 1;
    }
    if (k == 3) {
        p.split_contacts = 2;
        p.block_contacts = 1;
        p.max_sweeps = 1;
        p.tol = 0;
    }
    if (k == 4)
        p.impact_first = 1;
    return p;
}

typedef struct island_counts {
    int islands, collisions, deep, warm, changed, split, blocks, unconverged;
} island_counts;

/* Every island of the world's islands solved here and through the wire
 * under p: every body and every contact (its new impulse) matches bit for
 * bit, info too (run_both), and the static and sleeping bodies (shared by
 * islands, not carried back) are only read, collided included. */
static void check_islands(const sc_world *w, sc_np_ctx *local, sc_np_ctx *remote, cache *cc,
                          const sc_contact_params *p, island_counts *n)
{
    islands_job ij;
    islands_job_init_p(&ij, w, p);
    /* units of 1, 2 and 3 islands in turn */
    for (int i = 0, g = 1; i < ij.is.count; i += g, g = g % 3 + 1) {
        if (g > ij.is.count - i)
            g = ij.is.count - i;
        sc_unit u = island_unit(&ij.is, i, g);
        sc_unit ul = run_both(local, remote, cc, &ij.jl, &ij.jr, &u);
        n->collisions += ul.info.collisions;
        n->split += ul.info.split;
        n->blocks += ul.info.blocks;
        n->unconverged += ul.info.unconverged;
        n->islands += g;
    }
    for (int k = 0; k < ij.nc; k++) {
        n->deep += ij.c0[k].depth > p->slop;
        n->warm += has_impulse(&ij.c0[k]);
        n->changed += memcmp(ij.c0[k].impulse, ij.cl[k].impulse, sizeof ij.c0[k].impulse) != 0;
    }
    assert_memory_equal(ij.br, ij.bl, (size_t)w->st.nbodies * sizeof *ij.bl);
    assert_memory_equal(ij.cr, ij.cl, (size_t)ij.nc * sizeof *ij.cl);
    for (int j = 0; j < w->st.nbodies; j++)
        if (!ij.joins[j])
            assert_memory_equal(&ij.bl[j], &ij.b0[j], sizeof ij.b0[j]);
    islands_job_free(&ij);
}

/* Every island of several frames of the scene, its contacts carrying the
 * world's last impulses as warm starts, under each setting. */
static void test_island_units_through_wire_are_bit_identical(void **state)
{
    (void)state;
    sc_world *w = make_world();
    sc_np_ctx *local = sc_np_create(), *remote = sc_np_create();
    assert_true(local && remote);
    cache cc = { w, 0 };
    island_counts n[NSETTINGS] = { { 0 } };
    for (int f = 1; f <= 120; f++) {
        assert_int_equal(sc_world_step(w, DT), SC_OK);
        if (f < 60 || f % 5)
            continue;
        for (int k = 0; k < NSETTINGS; k++) {
            sc_contact_params p = setting(k);
            check_islands(w, local, remote, &cc, &p, &n[k]);
        }
    }
    for (int k = 0; k < NSETTINGS; k++) {
        print_message("island setting %d: %d islands, %d collisions, %d deep contacts, "
                      "%d with a warm start, %d impulses changed, %d split, %d block solves, "
                      "%d unconverged\n",
                      k, n[k].islands, n[k].collisions, n[k].deep, n[k].warm, n[k].changed,
                      n[k].split, n[k].blocks, n[k].unconverged);
        assert_true(n[k].islands > 0);
        assert_true(n[k].collisions > 0);
        assert_true(n[k].deep > 0);
        assert_true(n[k].warm > 0);
        assert_true(n[k].changed > 0);
    }
    /* the settings took effect, and travelled */
    assert_true(n[1].split > n[0].split && n[1].blocks > 0);
    assert_int_equal(n[2].split, n[1].split);
    assert_true(n[3].unconverged > 0);
    sc_np_destroy(local);
    sc_np_destroy(remote);
    sc_world_destroy(w);
}

/* ---- group units (a motion group's whole frame) ---- */

/* An executor that hands GROUP jobs to a test's hook (which must leave
 * every unit's outputs written) and runs any other job serially. Width 1:
 * no pile stays home, every group is a unit. */
typedef struct group_exec group_exec;
struct group_exec {
    sc_exec base;
    sc_exec_serial serial;
    void (*on_job)(group_exec *gx, sc_job *job);
    sc_np_ctx *local, *remote;
    cache cc;
    /* what the units held */
    int units, warm, found, backups, spec, asleep, nodes;
    /* capture: the unit with the most bodies and contacts */
    unsigned char *sample;
    size_t sample_len;
    int sample_size, sample_nm, sample_m, sample_nc;
};

static int gx_run(sc_exec *ex, sc_job *job, int stage, sc_stats *st)
{
    group_exec *gx = (group_exec *)ex;
    if (job->kind != SC_UNIT_GROUP)
        return gx->serial.base.run(&gx->serial.base, job, stage, st);
    gx->on_job(gx, job);
    int rc = SC_OK;
    for (int i = 0; i < job->nunits; i++)
        if (job->units[i].rc != SC_OK && rc == SC_OK)
            rc = job->units[i].rc;
    st->units += job->nunits;
    return rc;
}

static int gx_width(const sc_exec *ex)
{
    (void)ex;
    return 1;
}

static void gx_init(group_exec *gx, const sc_world *shapes, void (*on_job)(group_exec *, sc_job *))
{
    memset(gx, 0, sizeof *gx);
    gx->base.run = gx_run;
    gx->base.width = gx_width;
    gx->on_job = on_job;
    gx->local = sc_np_create();
    gx->remote = sc_np_create();
    assert_true(gx->local && gx->remote);
    sc_exec_serial_init(&gx->serial, gx->local);
    gx->cc = (cache){ shapes, 0 };
}

static void gx_free(group_exec *gx)
{
    sc_np_destroy(gx->local);
    sc_np_destroy(gx->remote);
    free(gx->sample);
}

/* One frame of w by motion groups on gx (as sc_world_step() runs it). */
static void group_step(sc_world *w, group_exec *gx)
{
    sc_stats fs;
    memset(&fs, 0, sizeof fs);
    assert_int_equal(sc_arena_reset(&w->scr.arena), SC_OK);
    assert_int_equal(sc_groups_step(&w->fcfg, &w->st, DT, &w->scr, &gx->base, &fs), SC_OK);
}

/* The figures of a group's frame as the world merges them
 * (sc_stats_add_frame), timings aside (CPU seconds differ run to run). */
static void assert_same_figures(const sc_stats *a, const sc_stats *b)
{
    sc_stats x, y;
    memset(&x, 0, sizeof x);
    memset(&y, 0, sizeof y);
    sc_stats_add_frame(&x, a);
    sc_stats_add_frame(&y, b);
    sc_stats *s[2] = { &x, &y };
    for (int i = 0; i < 2; i++) {
        memset(s[i]->stage_s, 0, sizeof s[i]->stage_s);
        memset(s[i]->stage_total_s, 0, sizeof s[i]->stage_total_s);
        s[i]->sched_s = s[i]->makespan_s = s[i]->makespan_bound_s = 0;
    }
    assert_memory_equal(&x, &y, sizeof x);
}

/* Each unit of a GROUP job run here on a copy of the state and through
 * the wire on the job itself: the members, the unit's rc, messages and
 * info, and the group's contacts (impulses included) and figures agree
 * bit for bit; the static bodies are not written. */
static void group_both_ways(group_exec *gx, sc_job *job)
{
    const sc_group_job *gj = job->group;
    const sc_groups *g = gj->g;
    size_t nb = (size_t)gj->st->nbodies, nc = (size_t)gj->st->ncontacts;
    sc_frame_state cp = *gj->st;
    cp.bodies = malloc(nb * sizeof *cp.bodies);
    cp.contacts = malloc((nc ? nc : 1) * sizeof *cp.contacts);
    sc_body *before = malloc(nb * sizeof *before);
    sc_group_out *out_l = calloc((size_t)g->ngroups, sizeof *out_l);
    assert_true(cp.bodies && cp.contacts && before && out_l);
    memcpy(cp.bodies, gj->st->bodies, nb * sizeof *cp.bodies);
    if (nc)    /* none yet in the first frame (and no array) */
        memcpy(cp.contacts, gj->st->contacts, nc * sizeof *cp.contacts);
    memcpy(before, gj->st->bodies, nb * sizeof *before);
    sc_group_job gl = *gj;
    gl.st = &cp;
    gl.out = out_l;
    sc_job jl = *job;
    jl.group = &gl;
    gx->nodes = job->nunits > gx->nodes ? job->nunits : gx->nodes;
    for (int i = 0; i < job->nunits; i++) {
        sc_unit *u = &job->units[i];
        int k = u->first;
        sc_unit ul = *u;
        sc_unit_run(gx->local, &jl, &ul);
        size_t len, rlen;
        unsigned char *buf = pack_unit(job, u, &len);
        unsigned char *res = remote_run(gx->remote, buf, len, &gx->cc, &rlen);
        u->rc = 99;
        u->messages = -1;
        assert_int_equal(sc_wire_result_apply(job, u, res, rlen), SC_OK);
        assert_int_equal(ul.rc, SC_OK);
        assert_int_equal(u->rc, ul.rc);
        assert_int_equal(u->messages, ul.messages);
        assert_memory_equal(&u->info, &ul.info, sizeof ul.info);
        const sc_group_out *a = &out_l[k], *b = &gj->out[k];
        assert_int_equal(b->rc, a->rc);
        assert_int_equal(b->ncontacts, a->ncontacts);
        if (a->ncontacts)
            assert_memory_equal(b->contacts, a->contacts, (size_t)a->ncontacts * sizeof *a->contacts);
        assert_same_figures(&a->stats, &b->stats);
        /* the daemon's CPU time came with them */
        double cpu = 0;
        for (int s = 0; s < SC_STAGE_COUNT; s++)
            cpu += b->stats.stage_s[s];
        assert_true(cpu > 0);
        gx->units++;
        gx->warm += g->cstart[k + 1] > g->cstart[k];
        gx->found += b->ncontacts > 0;
        gx->backups += b->stats.backups;
        gx->spec += b->stats.spec_contacts;
        for (int j = g->start[k]; j < g->start[k + 1]; j++)
            gx->asleep += gj->st->bodies[g->members[j]].state == SC_ASLEEP;
        free(buf);
        free(res);
    }
    assert_memory_equal(cp.bodies, gj->st->bodies, nb * sizeof *cp.bodies);
    for (int j = 0; j < g->nstatics; j++)
        assert_memory_equal(&gj->st->bodies[g->statics[j]], &before[g->statics[j]],
                            sizeof *before);
    for (int k = 0; k < g->ngroups; k++)
        free(out_l[k].contacts);
    free(out_l);
    free(before);
    free(cp.bodies);
    free(cp.contacts);
}

/* A body's bytes but its shape pointer (each world has its own shapes). */
static void assert_same_body(const sc_body *a, const sc_body *b)
{
    size_t at = offsetof(sc_body, mass);
    assert_memory_equal((const char *)a + at, (const char *)b + at, sizeof *a - at);
}

/* Every group unit of 150 frames of falling, landing and settling bolts
 * and nuts through the wire: each gives the bits of a local run (units
 * and results in group_both_ways), and the world stepped so ends on the
 * bits of the same world stepped by sc_world_step(), frame by frame. In
 * the local time-of-impact mode and with motion groups in the world mode
 * (the mode travels with the unit). */
static void test_group_units_through_wire_are_bit_identical(void **state)
{
    (void)state;
    for (int mode = 0; mode < 2; mode++) {
        sc_world *w = make_group_world(mode == 0), *ref = make_group_world(mode == 0);
        group_exec gx;
        gx_init(&gx, ref, group_both_ways);
        for (int f = 0; f < 150; f++) {
            group_step(w, &gx);
            assert_int_equal(sc_world_step(ref, DT), SC_OK);
            assert_true(sc_world_hash(w) == sc_world_hash(ref));
            assert_int_equal(w->st.nbodies, ref->st.nbodies);
            for (int i = 0; i < w->st.nbodies; i++)
                assert_same_body(&w->st.bodies[i], &ref->st.bodies[i]);
            assert_int_equal(w->st.ncontacts, ref->st.ncontacts);
            if (w->st.ncontacts)
                assert_memory_equal(w->st.contacts, ref->st.contacts,
                                    (size_t)w->st.ncontacts * sizeof *w->st.contacts);
        }
        print_message("group units (%s): %d, at most %d a frame; %d with last frame's contacts, "
                      "%d with new ones; %d back-ups, %d speculative contacts, %d asleep "
                      "members\n",
                      mode == 0 ? "local mode" : "motion groups", gx.units, gx.nodes, gx.warm,
                      gx.found, gx.backups, gx.spec, gx.asleep);
        assert_true(gx.units > 150);
        assert_true(gx.warm > 0 && gx.found > 0);
        assert_true(gx.backups > 0);
        gx_free(&gx);
        sc_world_destroy(w);
        sc_world_destroy(ref);
    }
}

/* One frame of a copy of w's state by motion groups on gx (w unchanged). */
static void group_frame_of_copy(const sc_world *w, group_exec *gx)
{
    sc_frame_state st = w->st;
    size_t nb = (size_t)st.nbodies, nc = (size_t)st.ncontacts;
    st.bodies = malloc(nb * sizeof *st.bodies);
    st.contacts = malloc((nc ? nc : 1) * sizeof *st.contacts);
    assert_true(st.bodies && st.contacts);
    memcpy(st.bodies, w->st.bodies, nb * sizeof *st.bodies);
    if (nc)
        memcpy(st.contacts, w->st.contacts, nc * sizeof *st.contacts);
    st.contact_cap = nc ? (int)nc : 1;
    sc_frame_scratch scr;
    assert_int_equal(sc_frame_scratch_init(&scr), SC_OK);
    sc_stats fs;
    memset(&fs, 0, sizeof fs);
    assert_int_equal(sc_groups_step(&w->fcfg, &st, DT, &scr, &gx->base, &fs), SC_OK);
    sc_frame_scratch_free(&scr);
    free(st.bodies);
    free(st.contacts);
}

/* The hook that keeps the packed unit with the most bodies and contacts
 * (a sample for the malformed-input tests), then runs every unit here. */
static void group_capture(group_exec *gx, sc_job *job)
{
    const sc_groups *g = job->group->g;
    for (int i = 0; i < job->nunits; i++) {
        sc_unit *u = &job->units[i];
        int k = u->first, nm = g->start[k + 1] - g->start[k], nc = g->cstart[k + 1] - g->cstart[k];
        if (nm + 4 * nc > gx->sample_size) {
            free(gx->sample);
            gx->sample = pack_unit(job, u, &gx->sample_len);
            gx->sample_size = nm + 4 * nc;
            gx->sample_nm = nm;
            gx->sample_m = nm + g->nstatics;
            gx->sample_nc = nc;
        }
        sc_unit_run(gx->local, job, u);
    }
}

/* Whether the group sample of a frame of s->gw (samples_init()) has two
 * members and two contacts. */
static int group_sample_ok(const scene *s)
{
    group_exec gx;
    gx_init(&gx, s->w, group_capture);
    group_frame_of_copy(s->gw, &gx);
    int ok = gx.sample && gx.sample_nm >= 2 && gx.sample_nc >= 2;
    gx_free(&gx);
    return ok;
}

/* ---- malformed input ---- */

/* One packed unit of each kind from the scene (caller frees). */
typedef struct samples {
    unsigned char *buf[WIRE_KINDS];
    size_t len[WIRE_KINDS];
    islands_job ij;
    outputs o;
} samples;

static void samples_init(samples *sm, const scene *s)
{
    outputs_init(&sm->o, s->pc.n);
    for (int kind = SC_UNIT_COLLIDE; kind <= SC_UNIT_TOI; kind++) {
        sc_job job = pair_job(kind, s, &sm->o);
        sc_unit u = { .kind = kind, .first = 1, .count = s->pc.n - 2 };
        sm->buf[kind] = pack_unit(&job, &u, &sm->len[kind]);
    }
    islands_job_init(&sm->ij, s->w);
    /* the island with the most contacts */
    int best = 0;
    for (int i = 1; i < sm->ij.is.count; i++)
        if (island_unit(&sm->ij.is, i, 1).count > island_unit(&sm->ij.is, best, 1).count)
            best = i;
    /* with its neighbour when it has one: the per-island counts travel too */
    sc_unit u = island_unit(&sm->ij.is, best, best + 1 < sm->ij.is.count ? 2 : 1);
    assert_true(u.count > 0);
    sm->buf[SC_UNIT_ISLAND] = pack_unit(&sm->ij.jl, &u, &sm->len[SC_UNIT_ISLAND]);
    /* the group with the most bodies and contacts of a frame of the pile */
    group_exec gx;
    gx_init(&gx, s->w, group_capture);
    group_frame_of_copy(s->gw, &gx);
    assert_non_null(gx.sample);
    sm->buf[SC_UNIT_GROUP] = gx.sample;
    sm->len[SC_UNIT_GROUP] = gx.sample_len;
    gx.sample = NULL;
    gx_free(&gx);
}

static void samples_free(samples *sm)
{
    for (int k = 0; k < WIRE_KINDS; k++)
        free(sm->buf[k]);
    islands_job_free(&sm->ij);
    outputs_free(&sm->o);
}

static void test_every_truncation_is_a_format_error(void **state)
{
    const scene *s = *state;
    samples sm;
    samples_init(&sm, s);
    cache cc = { s->w, 0 };
    for (int kind = 0; kind < WIRE_KINDS; kind++) {
        sc_wire_unit wu;
        for (size_t n = 0; n < sm.len[kind]; n++)
            assert_int_equal(sc_wire_unit_decode(sm.buf[kind], n, lookup, &cc, &wu), SC_EFORMAT);
        /* one byte too many as well */
        unsigned char *more = malloc(sm.len[kind] + 1);
        assert_non_null(more);
        memcpy(more, sm.buf[kind], sm.len[kind]);
        more[sm.len[kind]] = 0;
        assert_int_equal(sc_wire_unit_decode(more, sm.len[kind] + 1, lookup, &cc, &wu),
                         SC_EFORMAT);
        free(more);
        assert_int_equal(sc_wire_unit_decode(sm.buf[kind], sm.len[kind], lookup, &cc, &wu),
                         SC_OK);
        assert_int_equal(wu.job.kind, kind);
        sc_wire_unit_free(&wu);
    }
    samples_free(&sm);
}

static void test_corrupted_units_are_refused_or_run_safely(void **state)
{
    const scene *s = *state;
    samples sm;
    samples_init(&sm, s);
    cache cc = { s->w, 0 };
    sc_np_ctx *np = sc_np_create();
    assert_non_null(np);
    int ok = 0, bad = 0, runs_failed = 0;
    for (int t = 0; t < 2000; t++) {
        int kind = t % WIRE_KINDS;
        size_t len = sm.len[kind];
        unsigned char *b = malloc(len);
        assert_non_null(b);
        memcpy(b, sm.buf[kind], len);
        size_t at = (size_t)(next_rand() % len);
        b[at] ^= (unsigned char)(1 + next_rand() % 255);
        sc_wire_unit wu;
        int rc = sc_wire_unit_decode(b, len, lookup, &cc, &wu);
        assert_true(rc == SC_OK || rc == SC_EFORMAT);
        if (rc == SC_OK) {
            ok++;
            assert_int_equal(wu.job.kind, kind);
            /* what decodes may run: a daemon would */
            sc_unit_run(np, &wu.job, &wu.unit);
            assert_true(wu.unit.rc <= 0);
            runs_failed += wu.unit.rc != SC_OK;
            sc_wire_unit_free(&wu);
        } else {
            bad++;
        }
        free(b);
    }
    print_message("corruptions: %d decoded (%d of them failed to run), %d refused\n", ok,
                  runs_failed, bad);
    assert_true(ok > 0 && bad > 0);
    sc_np_destroy(np);
    samples_free(&sm);
}

static void put_u64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

/* n little-endian bytes of v at b + at make buf a format error; then put back. */
static void bad_at(unsigned char *buf, size_t len, size_t at, uint64_t v, int n)
{
    unsigned char keep[8];
    memcpy(keep, buf + at, (size_t)n);
    for (int i = 0; i < n; i++)
        buf[at + (size_t)i] = (unsigned char)(v >> (8 * i));
    sc_wire_unit wu;
    assert_int_equal(sc_wire_unit_decode(buf, len, NULL, NULL, &wu), SC_EFORMAT);
    memcpy(buf + at, keep, (size_t)n);
}

static uint64_t bits(double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    return u;
}

static void test_bad_fields_are_format_errors(void **state)
{
    const scene *s = *state;
    samples sm;
    samples_init(&sm, s);
    cache cc = { s->w, 0 };
    sc_wire_unit wu;
    unsigned char *b = sm.buf[SC_UNIT_COLLIDE];
    size_t len = sm.len[SC_UNIT_COLLIDE];
    /* layout: magic 4, version 2, kind 2, count 4, then pair 0: hashes */
    const size_t ver = 4, kind = 6, count = 8, hash0 = 12;
    unsigned char keep[8];
    memcpy(keep, b, sizeof keep);
    b[ver] = 0x7f;    /* a version nobody speaks */
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    memcpy(b, keep, sizeof keep);
    b[kind] = WIRE_KINDS;
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    memcpy(b, keep, sizeof keep);
    b[0] ^= 1;
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    memcpy(b, keep, sizeof keep);
    /* a count out of range (the length cannot match either) */
    memcpy(keep, b + count, 4);
    b[count + 2] = 2;   /* 1 << 17 pairs */
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    memcpy(b + count, keep, 4);
    /* an unknown shape: not in the cache, or a hash nobody has */
    uint64_t h = s->pc.p[1].sa->hash;
    cache miss = { s->w, h };
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &miss, &wu), SC_EFORMAT);
    memcpy(keep, b + hash0, 8);
    put_u64(b + hash0, h ^ 0x1234);
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    memcpy(b + hash0, keep, 8);
    /* pair 0's flags byte (after hashes and ids): bit 0 deepen, bit 1
     * exact (a search of the pair's own time) travel; other bits are
     * refused */
    const size_t flags0 = hash0 + 8 + 8 + 4 + 4;
    unsigned char kf = b[flags0];
    b[flags0] = 3;
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_OK);
    assert_true(wu.pairs[0].deepen == 1 && wu.pairs[0].exact == 1);
    sc_wire_unit_free(&wu);
    b[flags0] = 2;
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_OK);
    assert_true(wu.pairs[0].deepen == 0 && wu.pairs[0].exact == 1);
    sc_wire_unit_free(&wu);
    b[flags0] = 4;
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    b[flags0] = kf;
    /* NaN and infinity in a pose (pair 0's a0.pos[0], after hashes, ids, flags) */
    const size_t pos0 = flags0 + 1;
    memcpy(keep, b + pos0, 8);
    double bad[2] = { NAN, INFINITY };
    for (int k = 0; k < 2; k++) {
        uint64_t u;
        memcpy(&u, &bad[k], sizeof u);
        put_u64(b + pos0, u);
        assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
    }
    memcpy(b + pos0, keep, 8);
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_OK);
    sc_wire_unit_free(&wu);
    /* an island whose non-member body is awake and dynamic: the result
     * would not carry what the solve changed */
    unsigned char *ib = sm.buf[SC_UNIT_ISLAND];
    assert_int_equal(sc_wire_unit_decode(ib, sm.len[SC_UNIT_ISLAND], NULL, NULL, &wu), SC_OK);
    int nisl = wu.islands.count, m = wu.nbodies, nm = wu.islands.body_start[nisl];
    sc_wire_unit_free(&wu);
    /* island header: magic, version, kind 8; bodies, members, contacts,
     * islands 16; h, bounce_speed, slop, baumgarte, tol 40; gravity 24;
     * split_contacts, block_contacts, max_sweeps, cold, impact_first 20;
     * per island 8 */
    const size_t tol = 8 + 16 + 32, grav = tol + 8, ints = grav + 24, isl0 = ints + 20;
    size_t ilen = sm.len[SC_UNIT_ISLAND];
    print_message("island sample: %d islands, %d members, %d bodies\n", nisl, nm, m);
    /* the offsets are right: other valid values there decode as such */
    struct { size_t at; uint64_t v; int n; } good[] = {
        { tol, bits(0.25), 8 }, { ints, 5, 4 }, { ints + 4, 1u << 16, 4 },
        { ints + 8, 10000, 4 }, { ints + 12, 1, 4 }, { ints + 16, 1, 4 },
        { grav + 16, bits(-1.62), 8 },
    };
    for (int k = 0; k < 7; k++) {
        unsigned char keep8[8];
        memcpy(keep8, ib + good[k].at, (size_t)good[k].n);
        for (int i = 0; i < good[k].n; i++)
            ib[good[k].at + (size_t)i] = (unsigned char)(good[k].v >> (8 * i));
        assert_int_equal(sc_wire_unit_decode(ib, ilen, NULL, NULL, &wu), SC_OK);
        const sc_contact_params *q = &wu.params;
        int ok = k == 0 ? q->tol == 0.25
               : k == 1 ? q->split_contacts == 5
               : k == 2 ? q->block_contacts == 1 << 16
               : k == 3 ? q->max_sweeps == 10000
               : k == 4 ? q->cold == 1
               : k == 5 ? q->impact_first == 1
                        : q->gravity[2] == -1.62;
        assert_true(ok);
        assert_int_equal(q->inject, 0);
        sc_wire_unit_free(&wu);
        memcpy(ib + good[k].at, keep8, (size_t)good[k].n);
    }
    /* solver settings out of range */
    const double bad_tol[] = { NAN, INFINITY, -1e-3 };
    for (int k = 0; k < 3; k++)
        bad_at(ib, ilen, tol, bits(bad_tol[k]), 8);
    for (int k = 0; k < 3; k++)                              /* gravity */
        bad_at(ib, ilen, grav + 8 * (size_t)k, bits(k == 1 ? -INFINITY : NAN), 8);
    bad_at(ib, ilen, ints, (uint32_t)-1, 4);                 /* split_contacts */
    bad_at(ib, ilen, ints + 4, 0, 4);                        /* block_contacts */
    bad_at(ib, ilen, ints + 4, (uint32_t)-4, 4);
    bad_at(ib, ilen, ints + 4, (1u << 16) + 1, 4);
    bad_at(ib, ilen, ints + 8, 0, 4);                        /* max_sweeps */
    bad_at(ib, ilen, ints + 8, 10001, 4);
    bad_at(ib, ilen, ints + 8, (uint32_t)-50, 4);
    bad_at(ib, ilen, ints + 12, 2, 4);                       /* cold */
    bad_at(ib, ilen, ints + 12, (uint32_t)-1, 4);
    bad_at(ib, ilen, ints + 16, 2, 4);                       /* impact_first */
    bad_at(ib, ilen, ints + 16, (uint32_t)-1, 4);
    /* a NaN or infinite warm-start impulse (contact 0's, after its ids,
     * pos, normal and depth) */
    size_t imp0 = isl0 + 8 * (size_t)nisl + (size_t)m * (31 * 8 + 8) + 8 + 7 * 8;
    assert_int_equal(sc_wire_unit_decode(ib, ilen, NULL, NULL, &wu), SC_OK);
    double want[3];
    memcpy(want, wu.c[0].impulse, sizeof want);
    sc_wire_unit_free(&wu);
    for (int k = 0; k < 3; k++) {
        uint64_t keep64;
        memcpy(&keep64, ib + imp0 + 8 * (size_t)k, 8);
        put_u64(ib + imp0 + 8 * (size_t)k, bits(-0.5 - k));
        assert_int_equal(sc_wire_unit_decode(ib, ilen, NULL, NULL, &wu), SC_OK);
        assert_true(wu.c[0].impulse[k] == -0.5 - k);
        assert_memory_equal(&wu.c[0].impulse[(k + 1) % 3], &want[(k + 1) % 3], sizeof(double));
        sc_wire_unit_free(&wu);
        memcpy(ib + imp0 + 8 * (size_t)k, &keep64, 8);
    }
    for (int k = 0; k < 3; k++) {
        bad_at(ib, ilen, imp0 + 8 * (size_t)k, bits(NAN), 8);
        bad_at(ib, ilen, imp0 + 8 * (size_t)k, bits(-INFINITY), 8);
    }
    /* the last contact's impulse ends the unit */
    bad_at(ib, ilen, ilen - 8, bits(INFINITY), 8);
    assert_int_equal(sc_wire_unit_decode(ib, ilen, NULL, NULL, &wu), SC_OK);
    sc_wire_unit_free(&wu);
    if (nisl > 1) {
        /* per-island member counts that do not add up to the members */
        memcpy(keep, ib + isl0, 4);
        ib[isl0] ^= 1;
        assert_int_equal(sc_wire_unit_decode(ib, sm.len[SC_UNIT_ISLAND], NULL, NULL, &wu),
                         SC_EFORMAT);
        memcpy(ib + isl0, keep, 4);
        /* an island count beyond the members */
        memcpy(keep, ib + 20, 4);
        ib[22] = 1;
        assert_int_equal(sc_wire_unit_decode(ib, sm.len[SC_UNIT_ISLAND], NULL, NULL, &wu),
                         SC_EFORMAT);
        memcpy(ib + 20, keep, 4);
    }
    if (m > nm) {
        /* body nm's inv_mass, after the header and the per-island counts */
        size_t at = isl0 + 8 * (size_t)nisl + (size_t)nm * (31 * 8 + 8);
        memcpy(keep, ib + at, 8);
        double one = 1;
        uint64_t u;
        memcpy(&u, &one, sizeof u);
        put_u64(ib + at, u);
        /* and its state, after the 31 doubles */
        unsigned char st = ib[at + 31 * 8];
        ib[at + 31 * 8] = SC_FREE;
        assert_int_equal(sc_wire_unit_decode(ib, sm.len[SC_UNIT_ISLAND], NULL, NULL, &wu),
                         SC_EFORMAT);
        memcpy(ib + at, keep, 8);
        ib[at + 31 * 8] = st;
        assert_int_equal(sc_wire_unit_decode(ib, sm.len[SC_UNIT_ISLAND], NULL, NULL, &wu), SC_OK);
        sc_wire_unit_free(&wu);
    }
    samples_free(&sm);
}

/* An island unit's settings and its contacts (warm-start impulses
 * included) decode as they were; inject (tests only) and settings a
 * receiver would refuse are not packed, so such a unit runs locally. */
static void test_island_settings_and_impulses_travel(void **state)
{
    const scene *s = *state;
    sc_contact_params p = { .bounce_speed = 0.25, .slop = 1e-4, .baumgarte = 0.3,
                            .split_contacts = 3, .block_contacts = 2, .tol = 0.125,
                            .max_sweeps = 7, .cold = 1, .impact_first = 1 };
    islands_job ij;
    islands_job_init_p(&ij, s->w, &p);
    /* warm starts of every sign and size, on every contact */
    for (int k = 0; k < ij.nc; k++)
        for (int j = 0; j < 3; j++)
            ij.cl[k].impulse[j] = (double)(int64_t)next_rand() * 0x1p-70;
    int with = 0;
    for (int i = 0; i < ij.is.count; i++) {
        sc_unit u = island_unit(&ij.is, i, 1);
        size_t len;
        unsigned char *buf = pack_unit(&ij.jl, &u, &len);
        sc_wire_unit wu;
        assert_int_equal(sc_wire_unit_decode(buf, len, NULL, NULL, &wu), SC_OK);
        assert_true(wu.params.bounce_speed == p.bounce_speed && wu.params.slop == p.slop &&
                    wu.params.baumgarte == p.baumgarte && wu.params.tol == p.tol &&
                    wu.params.split_contacts == p.split_contacts &&
                    wu.params.block_contacts == p.block_contacts &&
                    wu.params.max_sweeps == p.max_sweeps && wu.params.cold == p.cold &&
                    wu.params.impact_first == p.impact_first && wu.params.inject == 0);
        assert_int_equal(wu.unit.count, u.count);
        const int *ci = &ij.is.contacts[ij.is.contact_start[i]];
        for (int k = 0; k < u.count; k++) {
            const sc_contact *a = &ij.cl[ci[k]], *b = &wu.c[k];
            assert_memory_equal(a->impulse, b->impulse, sizeof a->impulse);
            assert_memory_equal(a->pos, b->pos, sizeof a->pos);
            assert_memory_equal(a->normal, b->normal, sizeof a->normal);
            assert_memory_equal(&a->depth, &b->depth, sizeof a->depth);
        }
        with += u.count > 0;
        sc_wire_unit_free(&wu);
        free(buf);
    }
    assert_true(with > 0);
    /* what cannot travel is not packed */
    sc_unit u = island_unit(&ij.is, 0, 1);
    const sc_contact_params keep = p;
    sc_contact_params *q = &p;
    for (int k = 0; k < 9; k++) {
        *q = keep;
        switch (k) {
        case 7: q->impact_first = 2; break;
        case 0: q->inject = SC_INJECT_NAN; break;
        case 1: q->tol = NAN; break;
        case 2: q->tol = -1; break;
        case 3: q->max_sweeps = 0; break;
        case 4: q->max_sweeps = 10001; break;
        case 5: q->block_contacts = 0; break;
        case 6: q->split_contacts = -1; break;
        default: q->cold = 2; break;
        }
        assert_int_equal(sc_wire_unit_pack(&ij.jl, &u, NULL, 0), 0);
    }
    *q = keep;
    assert_true(sc_wire_unit_pack(&ij.jl, &u, NULL, 0) > 0);
    islands_job_free(&ij);
}

/* A result must match the unit it is applied to; a mismatched or
 * malformed one changes nothing. */
static void test_result_for_another_unit_is_a_format_error(void **state)
{
    const scene *s = *state;
    int n = s->pc.n;
    outputs o;
    outputs_init(&o, n);
    sc_job job = pair_job(SC_UNIT_COLLIDE, s, &o);
    sc_unit u = { .kind = SC_UNIT_COLLIDE, .first = 0, .count = n / 2 };
    sc_np_ctx *np = sc_np_create();
    assert_non_null(np);
    cache cc = { s->w, 0 };
    size_t len, rlen;
    unsigned char *buf = pack_unit(&job, &u, &len);
    unsigned char *res = remote_run(np, buf, len, &cc, &rlen);
    unsigned char *before = malloc((size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *o.contacts);
    assert_non_null(before);
    memcpy(before, o.contacts, (size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *o.contacts);
    /* another count; the same count over other pairs (their body ids) */
    sc_unit other = { .kind = SC_UNIT_COLLIDE, .first = 0, .count = n / 2 - 1 };
    assert_int_equal(sc_wire_result_apply(&job, &other, res, rlen), SC_EFORMAT);
    other.first = n - n / 2;
    other.count = n / 2;
    assert_int_equal(sc_wire_result_apply(&job, &other, res, rlen), SC_EFORMAT);
    /* another kind */
    sc_job tjob = pair_job(SC_UNIT_TOI, s, &o);
    sc_unit tu = u;
    tu.kind = SC_UNIT_TOI;
    assert_int_equal(sc_wire_result_apply(&tjob, &tu, res, rlen), SC_EFORMAT);
    /* every truncation */
    for (size_t k = 0; k < rlen; k++)
        assert_int_equal(sc_wire_result_apply(&job, &u, res, k), SC_EFORMAT);
    /* a unit buffer is not a result */
    assert_int_equal(sc_wire_result_apply(&job, &u, buf, len), SC_EFORMAT);
    assert_memory_equal(before, o.contacts, (size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *o.contacts);
    assert_int_equal(sc_wire_result_apply(&job, &u, res, rlen), SC_OK);
    /* an island's result against another island (other member count) */
    islands_job ij;
    islands_job_init(&ij, s->w);
    int a = -1, b = -1;
    for (int i = 0; i < ij.is.count && b < 0; i++) {
        int nb = ij.is.body_start[i + 1] - ij.is.body_start[i];
        if (a < 0)
            a = i;
        else if (nb != ij.is.body_start[a + 1] - ij.is.body_start[a])
            b = i;
    }
    if (b >= 0) {
        sc_unit ua = island_unit(&ij.is, a, 1), ub = island_unit(&ij.is, b, 1);
        free(buf);
        free(res);
        buf = pack_unit(&ij.jr, &ua, &len);
        res = remote_run(np, buf, len, &cc, &rlen);
        assert_int_equal(sc_wire_result_apply(&ij.jr, &ub, res, rlen), SC_EFORMAT);
        assert_memory_equal(ij.br, ij.bl, (size_t)s->w->st.nbodies * sizeof *ij.bl);
        assert_int_equal(sc_wire_result_apply(&ij.jr, &ua, res, rlen), SC_OK);
    }
    /* an island result whose contact count or counters are wrong changes
     * nothing (layout: header 8, members 4, rc 4, messages 8, pivots 8,
     * failures ... guessed 18 x 4, residuals 16, contacts 4) */
    int big = 0;
    for (int i = 1; i < ij.is.count; i++)
        if (island_unit(&ij.is, i, 1).count > island_unit(&ij.is, big, 1).count)
            big = i;
    sc_unit ui = island_unit(&ij.is, big, 1);
    assert_true(ui.count > 0);
    free(buf);
    free(res);
    buf = pack_unit(&ij.jr, &ui, &len);
    res = remote_run(np, buf, len, &cc, &rlen);
    const size_t pivots = 24, counters = pivots + 8, ncont = counters + 72 + 16;
    assert_int_equal(rlen, ncont + 4 +
                               (size_t)(ij.is.body_start[big + 1] - ij.is.body_start[big]) *
                                   (19 * 8 + 4) +
                               (size_t)ui.count * 24);
    size_t nb = (size_t)s->w->st.nbodies, ncb = (size_t)ij.nc * sizeof *ij.cr;
    sc_body *bodies_before = malloc(nb * sizeof *bodies_before);
    sc_contact *contacts_before = malloc(ncb ? ncb : 1);
    assert_true(bodies_before && contacts_before);
    memcpy(bodies_before, ij.br, nb * sizeof *bodies_before);
    memcpy(contacts_before, ij.cr, ncb);
    struct { size_t at; int n; uint64_t v; } wrong[] = {
        { ncont, 4, (uint64_t)ui.count + 1 }, { ncont, 4, (uint64_t)ui.count - 1 },
        { pivots, 8, (uint64_t)-1 },
    };
    for (int k = 0; k < 3 + 18; k++) {
        size_t at = k < 3 ? wrong[k].at : counters + 4 * (size_t)(k - 3);
        int nbytes = k < 3 ? wrong[k].n : 4;
        uint64_t v = k < 3 ? wrong[k].v : (uint32_t)-1;   /* a negative counter */
        unsigned char keep[8];
        memcpy(keep, res + at, (size_t)nbytes);
        for (int i = 0; i < nbytes; i++)
            res[at + (size_t)i] = (unsigned char)(v >> (8 * i));
        assert_int_equal(sc_wire_result_apply(&ij.jr, &ui, res, rlen), SC_EFORMAT);
        memcpy(res + at, keep, (size_t)nbytes);
    }
    for (size_t k = 0; k < rlen; k++)
        assert_int_equal(sc_wire_result_apply(&ij.jr, &ui, res, k), SC_EFORMAT);
    assert_memory_equal(bodies_before, ij.br, nb * sizeof *bodies_before);
    assert_memory_equal(contacts_before, ij.cr, ncb);
    /* the residuals are carried as they are */
    double odd = NAN;
    memcpy(res + counters + 72, &odd, sizeof odd);
    ui.info.residual_exact = 0;
    assert_int_equal(sc_wire_result_apply(&ij.jr, &ui, res, rlen), SC_OK);
    assert_true(isnan(ui.info.residual_exact));
    free(bodies_before);
    free(contacts_before);
    islands_job_free(&ij);
    free(before);
    free(buf);
    free(res);
    sc_np_destroy(np);
    outputs_free(&o);
}

/* A GROUP unit's layout (see unit_wire.c's header): the header; bodies,
 * members, contacts, contacts_valid at 8; dt, gravity, tol at 24;
 * broadphase, island_split, toi_mode at 64; bodies from 76, 496 bytes
 * each (hash, 60 doubles, state, collided); then contacts, 88 each. */
#define G_DT 24
#define G_GRAVITY 32
#define G_TOL 56
#define G_INTS 64
#define G_BODY(q) (76 + 496 * (size_t)(q))
#define GB_MASS 8
#define GB_INV_MASS 16
#define GB_INERTIA 24
#define GB_INV_INERTIA 96
#define GB_X 208
#define GB_REST 480
#define GB_STATE 488
#define GB_COLLIDED 492
#define G_CONTACT(m, k) (G_BODY(m) + 88 * (size_t)(k))

/* n little-endian bytes of v at at, with the world's shapes to look up:
 * the decode's answer, then put back. */
static int group_decode_with(unsigned char *buf, size_t len, const cache *cc, size_t at,
                             uint64_t v, int n)
{
    unsigned char keep[8];
    memcpy(keep, buf + at, (size_t)n);
    for (int i = 0; i < n; i++)
        buf[at + (size_t)i] = (unsigned char)(v >> (8 * i));
    sc_wire_unit wu;
    int rc = sc_wire_unit_decode(buf, len, lookup, (void *)cc, &wu);
    if (rc == SC_OK)
        sc_wire_unit_free(&wu);
    memcpy(buf + at, keep, (size_t)n);
    return rc;
}

#define GROUP_BAD(at, v, n) \
    assert_int_equal(group_decode_with(b, len, &cc, (at), (v), (n)), SC_EFORMAT)
#define GROUP_GOOD(at, v, n) \
    assert_int_equal(group_decode_with(b, len, &cc, (at), (v), (n)), SC_OK)

/* A group unit's counts, frame settings, bodies and contacts out of range
 * are format errors; other valid values at the same places decode. */
static void test_bad_group_fields_are_format_errors(void **state)
{
    const scene *s = *state;
    samples sm;
    samples_init(&sm, s);
    cache cc = { s->w, 0 };
    unsigned char *b = sm.buf[SC_UNIT_GROUP];
    size_t len = sm.len[SC_UNIT_GROUP];
    sc_wire_unit wu;
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_OK);
    int m = wu.nbodies, nm = wu.unit.count, nc = wu.gst.ncontacts, member = -1, fixed = -1;
    for (int q = 0; q < m; q++) {
        if (wu.bodies[q].inv_mass > 0 && member < 0)
            member = q;
        if (wu.bodies[q].inv_mass == 0 && fixed < 0)
            fixed = q;
    }
    assert_true(wu.gst.contacts_valid == 1 && wu.group.dt == DT && !wu.group.g);
    assert_true(wu.cfg.toi_mode == SC_TOI_LOCAL && wu.cfg.contact_tol_m == s->w->cfg.contact_tol_m);
    sc_wire_unit_free(&wu);
    print_message("group sample: %d bodies, %d members, %d contacts\n", m, nm, nc);
    assert_true(member >= 0 && fixed >= 0 && nc >= 2);
    /* without a lookup the shapes cannot be had */
    assert_int_equal(sc_wire_unit_decode(b, len, NULL, NULL, &wu), SC_EINVAL);
    /* counts: members beyond the bodies, none, or not the bodies with mass */
    GROUP_BAD(8, (uint64_t)nm - 1, 4);
    GROUP_BAD(12, 0, 4);
    GROUP_BAD(12, (uint64_t)nm + 1, 4);
    GROUP_BAD(12, (uint64_t)nm - 1, 4);
    GROUP_BAD(16, (uint64_t)nc + 1, 4);
    GROUP_BAD(20, 2, 4);                          /* contacts_valid */
    GROUP_BAD(20, 0, 4);                          /* ... 0 with contacts */
    /* frame settings */
    const double bad_dt[] = { NAN, INFINITY, 0, -DT };
    for (int k = 0; k < 4; k++)
        GROUP_BAD(G_DT, bits(bad_dt[k]), 8);
    GROUP_BAD(G_GRAVITY + 8, bits(-INFINITY), 8);
    GROUP_BAD(G_GRAVITY, bits(NAN), 8);
    const double bad_tol[] = { NAN, 0, -1e-3, INFINITY };
    for (int k = 0; k < 4; k++)
        GROUP_BAD(G_TOL, bits(bad_tol[k]), 8);
    GROUP_BAD(G_INTS, (uint32_t)-1, 4);           /* broadphase */
    GROUP_BAD(G_INTS, SC_BROADPHASE_SAP + 1, 4);
    GROUP_BAD(G_INTS + 4, (uint32_t)-1, 4);       /* island_split */
    GROUP_BAD(G_INTS + 8, 2, 4);                  /* toi_mode */
    GROUP_BAD(G_INTS + 8, (uint32_t)-1, 4);
    /* the offsets are right: other valid settings decode as such */
    GROUP_GOOD(G_DT, bits(0.5), 8);
    GROUP_GOOD(G_TOL, bits(0.25), 8);
    GROUP_GOOD(G_INTS, SC_BROADPHASE_SAP, 4);
    GROUP_GOOD(G_INTS + 4, 0, 4);
    GROUP_GOOD(G_INTS + 8, SC_TOI_WORLD, 4);
    GROUP_GOOD(G_BODY(member) + GB_REST, bits(2.5), 8);
    /* bodies: a shape nobody has, negative or NaN masses, a position at
     * infinity, a member marked static, a static given mass (or a member
     * made static: the member count no longer holds), states and
     * collided out of range */
    GROUP_BAD(G_BODY(member), s->w->st.bodies[1].shape->hash ^ 0x1234, 8);
    GROUP_BAD(G_BODY(member) + GB_INV_MASS, bits(-1), 8);
    GROUP_BAD(G_BODY(member) + GB_INV_MASS, bits(NAN), 8);
    GROUP_BAD(G_BODY(member) + GB_MASS, bits(-1), 8);
    /* a member's inverses not its mass's and inertia's (a corrupted
     * off-diagonal entry of the inverse inertia ran a frame for 16 s) */
    GROUP_BAD(G_BODY(member) + GB_INV_INERTIA + 6 * 8, bits(-1.8769e69), 8);
    GROUP_BAD(G_BODY(member) + GB_INV_INERTIA, bits(0), 8);
    GROUP_BAD(G_BODY(member) + GB_INERTIA + 4 * 8, bits(1e3), 8);
    GROUP_BAD(G_BODY(member) + GB_MASS, bits(1e3), 8);
    GROUP_BAD(G_BODY(member) + GB_INV_MASS, bits(1e-3), 8);
    GROUP_BAD(G_BODY(member) + GB_X + 8, bits(INFINITY), 8);
    GROUP_BAD(G_BODY(member) + GB_REST, bits(NAN), 8);
    GROUP_BAD(G_BODY(member) + GB_STATE, SC_STATIC, 4);
    GROUP_BAD(G_BODY(member) + GB_STATE, SC_STATIC + 1, 4);
    GROUP_BAD(G_BODY(member) + GB_STATE, (uint32_t)-1, 4);
    GROUP_BAD(G_BODY(fixed) + GB_INV_MASS, bits(1), 8);
    GROUP_BAD(G_BODY(fixed) + GB_STATE, SC_FREE, 4);
    GROUP_BAD(G_BODY(member) + GB_COLLIDED, 3, 4);
    GROUP_BAD(G_BODY(member) + GB_COLLIDED, (uint32_t)-1, 4);
    GROUP_GOOD(G_BODY(member) + GB_STATE, SC_ASLEEP, 4);
    GROUP_GOOD(G_BODY(member) + GB_COLLIDED, 2, 4);
    {
        /* a member turned static whole: the counts no longer match */
        unsigned char keep[8];
        size_t at = G_BODY(member) + GB_INV_MASS;
        memcpy(keep, b + at, 8);
        put_u64(b + at, bits(0));
        GROUP_BAD(G_BODY(member) + GB_STATE, SC_STATIC, 4);
        memcpy(b + at, keep, 8);
    }
    /* contacts: ends out of range, reversed, on one body, between two
     * static bodies, out of pair order, not finite */
    size_t c0 = G_CONTACT(m, 0), cl = G_CONTACT(m, nc - 1);
    GROUP_BAD(c0, (uint32_t)-1, 4);
    GROUP_BAD(c0 + 4, (uint64_t)m, 4);
    GROUP_BAD(c0 + 4, b[c0], 4);                  /* body_b = body_a */
    GROUP_BAD(c0, (uint64_t)m - 1, 4);            /* body_a > body_b */
    GROUP_BAD(c0 + 4, (uint64_t)fixed, 4);        /* fixed: then both static, or a > b */
    GROUP_BAD(c0 + 56, bits(NAN), 8);             /* depth */
    GROUP_BAD(c0 + 64 + 16, bits(INFINITY), 8);   /* impulse */
    GROUP_BAD(cl + 64, bits(-INFINITY), 8);
    if (memcmp(b + c0, b + cl, 8) != 0) {
        /* the first and last contacts swapped (other pairs: out of order) */
        unsigned char *t = malloc(88);
        assert_non_null(t);
        memcpy(t, b + c0, 88);
        memcpy(b + c0, b + cl, 88);
        memcpy(b + cl, t, 88);
        assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_EFORMAT);
        memcpy(b + cl, b + c0, 88);
        memcpy(b + c0, t, 88);
        free(t);
    } else {
        /* all of one pair (a, b), a a member: the first one made (a, b +
         * 1), or the last (a - 1, b), is a valid pair out of order */
        uint32_t a0 = (uint32_t)b[c0] | (uint32_t)b[c0 + 1] << 8 | (uint32_t)b[c0 + 2] << 16 |
                      (uint32_t)b[c0 + 3] << 24;
        uint32_t b0 = (uint32_t)b[c0 + 4] | (uint32_t)b[c0 + 5] << 8 |
                      (uint32_t)b[c0 + 6] << 16 | (uint32_t)b[c0 + 7] << 24;
        assert_true((int)a0 < nm && ((int)b0 + 1 < m || a0 > 0));
        if ((int)b0 + 1 < m)
            GROUP_BAD(c0 + 4, (uint64_t)b0 + 1, 4);
        else
            GROUP_BAD(cl, (uint64_t)a0 - 1, 4);
    }
    assert_int_equal(sc_wire_unit_decode(b, len, lookup, &cc, &wu), SC_OK);
    sc_wire_unit_free(&wu);
    samples_free(&sm);
}

/* A group result at its layout (header 8, members 4, rc 4, messages 8,
 * info 96; figures 268; per member 288: 35 doubles, state, collided; then
 * contacts 4 and 88 each). */
#define GR_RC 12
#define GR_STATS 120
#define GR_STAT_INTS (GR_STATS + 8 * 22)
/* Member i of a group result: 288 bytes of state, then its track: dev
 * f64, points u32 and 32 bytes a point. */
static size_t gr_member(const unsigned char *res, int i)
{
    size_t at = GR_STATS + 268;
    for (int j = 0; j < i; j++) {
        uint32_t n;
        memcpy(&n, res + at + 296, 4);
        at += 300 + 32 * (size_t)n;
    }
    return at;
}
#define GR_MEMBER(i) gr_member(res, (int)(i))
#define GR_CONTACTS(nm) GR_MEMBER(nm)

/* The hook that sends results at units they do not fit, and malformed
 * ones: refused, nothing written; then the right ones, and the rest here. */
static void group_hostile_results(group_exec *gx, sc_job *job)
{
    const sc_group_job *gj = job->group;
    const sc_groups *g = gj->g;
    size_t nb = (size_t)gj->st->nbodies;
    /* the unit with the most contacts of the last frame whose result
     * has contacts too (the checks below change them; a group whose
     * bodies bounce apart ends with none), and one with another member
     * count */
    int a = -1, o = -1, nm = 0;
    size_t len, rlen;
    unsigned char *buf = NULL, *res = NULL;
    char *tried = calloc((size_t)job->nunits, 1);
    assert_non_null(tried);
    for (;;) {
        a = -1;
        for (int i = 0; i < job->nunits; i++) {
            int k = job->units[i].first, ka = a >= 0 ? job->units[a].first : 0;
            if (!tried[i] && (a < 0 || g->cstart[k + 1] - g->cstart[k] >
                                           g->cstart[ka + 1] - g->cstart[ka]))
                a = i;
        }
        assert_true(a >= 0);
        tried[a] = 1;
        buf = pack_unit(job, &job->units[a], &len);
        res = remote_run(gx->remote, buf, len, &gx->cc, &rlen);
        int k = job->units[a].first;
        nm = g->start[k + 1] - g->start[k];
        uint32_t n;
        memcpy(&n, res + GR_CONTACTS(nm), 4);
        if (n >= 1)
            break;
        free(buf);
        free(res);
    }
    free(tried);
    sc_unit *ua = &job->units[a];
    int ka = ua->first;
    for (int i = 0; i < job->nunits && o < 0; i++) {
        int k = job->units[i].first;
        if (g->start[k + 1] - g->start[k] != nm)
            o = i;
    }
    sc_body *before = malloc(nb * sizeof *before);
    assert_non_null(before);
    memcpy(before, gj->st->bodies, nb * sizeof *before);
    sc_group_out out0[2] = { gj->out[ka], { 0 } };
    if (o >= 0) {
        out0[1] = gj->out[job->units[o].first];
        assert_int_equal(sc_wire_result_apply(job, &job->units[o], res, rlen), SC_EFORMAT);
    }
    /* a result for a unit of another kind, or beyond the groups */
    sc_unit bad = *ua;
    bad.first = g->ngroups;
    assert_int_equal(sc_wire_result_apply(job, &bad, res, rlen), SC_EINVAL);
    for (size_t k = 0; k < rlen; k++)
        assert_int_equal(sc_wire_result_apply(job, ua, res, k), SC_EFORMAT);
    /* a unit buffer is not a result */
    assert_int_equal(sc_wire_result_apply(job, ua, buf, len), SC_EFORMAT);
    /* counts and states out of range */
    uint32_t nc;
    memcpy(&nc, res + GR_CONTACTS(nm), 4);
    int m = nm + g->nstatics;
    /* a member with a track of two points at least */
    int tracked = -1;
    for (int i = 0; i < nm && tracked < 0; i++) {
        uint32_t n;
        memcpy(&n, res + GR_MEMBER(i) + 296, 4);
        if (n >= 2)
            tracked = i;
    }
    assert_true(tracked >= 0);
    struct { size_t at; int n; uint64_t v; } wrong[] = {
        { 8, 4, (uint64_t)nm + 1 },                       /* members */
        { GR_STATS + 8 * 12, 8, (uint64_t)-1 },           /* lcp_pivots < 0 */
        { GR_STAT_INTS, 4, (uint32_t)-1 },                /* pairs < 0 */
        { GR_STAT_INTS + 4 * 17, 4, (uint32_t)-1 },       /* spec_rounds < 0 */
        { GR_MEMBER(0) + 280, 4, SC_STATIC },             /* a member made static */
        { GR_MEMBER(nm - 1) + 280, 4, (uint32_t)-1 },
        { GR_MEMBER(0) + 284, 4, 3 },                     /* collided */
        { GR_CONTACTS(nm), 4, (uint64_t)nc + 1 },         /* contacts */
        { GR_CONTACTS(nm), 4, (uint64_t)nc - 1 },
        { GR_CONTACTS(nm) + 4, 4, (uint32_t)-1 },         /* contact 0's body_a */
        { GR_CONTACTS(nm) + 8, 4, (uint64_t)m },          /* ... its body_b */
        { GR_RC, 4, (uint32_t)SC_ENUMERIC },              /* failed, with contacts */
        { GR_RC, 4, 1 },                                  /* rc > 0 */
        { GR_MEMBER(0) + 288, 8, bits(-1e-3) },           /* track: dev < 0 */
        { GR_MEMBER(0) + 288, 8, bits(NAN) },
        { GR_MEMBER(0) + 296, 4, SC_TRACK_MAX + 1 },      /* points */
        { GR_MEMBER(tracked) + 300 + 32, 8, bits(-1e-3) },/* its second point's t < 0 */
        { GR_MEMBER(tracked) + 300 + 32, 8, bits(1.0) },  /* ... past the frame */
        { GR_MEMBER(tracked) + 300, 8, bits(0.5) },       /* ... before its first */
    };
    assert_true(nc >= 1);
    for (size_t k = 0; k < sizeof wrong / sizeof wrong[0]; k++) {
        unsigned char keep[8];
        memcpy(keep, res + wrong[k].at, (size_t)wrong[k].n);
        for (int i = 0; i < wrong[k].n; i++)
            res[wrong[k].at + (size_t)i] = (unsigned char)(wrong[k].v >> (8 * i));
        assert_int_equal(sc_wire_result_apply(job, ua, res, rlen), SC_EFORMAT);
        memcpy(res + wrong[k].at, keep, (size_t)wrong[k].n);
    }
    /* nothing was written */
    assert_memory_equal(before, gj->st->bodies, nb * sizeof *before);
    assert_memory_equal(&gj->out[ka], &out0[0], sizeof out0[0]);
    if (o >= 0)
        assert_memory_equal(&gj->out[job->units[o].first], &out0[1], sizeof out0[1]);
    /* the doubles are carried as they come (the master's frame checks
     * them, as after a local run): a NaN position is merged */
    unsigned char keep[8];
    memcpy(keep, res + GR_MEMBER(0), 8);
    put_u64(res + GR_MEMBER(0), bits(NAN));
    unsigned char *odd = malloc(rlen);
    assert_non_null(odd);
    memcpy(odd, res, rlen);
    memcpy(res + GR_MEMBER(0), keep, 8);
    sc_unit copy = *ua;
    sc_body b0 = gj->st->bodies[g->members[g->start[ka]]];
    assert_int_equal(sc_wire_result_apply(job, &copy, odd, rlen), SC_OK);
    assert_true(isnan(gj->st->bodies[g->members[g->start[ka]]].x[0]));
    free(gj->out[ka].contacts);
    gj->st->bodies[g->members[g->start[ka]]] = b0;
    free(odd);
    /* the right one */
    assert_int_equal(sc_wire_result_apply(job, ua, res, rlen), SC_OK);
    assert_int_equal(gj->out[ka].ncontacts, (int)nc);
    gx->units++;
    gx->found += o >= 0;
    for (int i = 0; i < job->nunits; i++)
        if (i != a)
            sc_unit_run(gx->local, job, &job->units[i]);
    free(before);
    free(buf);
    free(res);
}

/* A group result must match its unit; a mismatched or malformed one
 * writes nothing. Over several frames of the scene's settling pile. */
static void test_group_result_for_another_unit_is_a_format_error(void **state)
{
    const scene *s = *state;
    group_exec gx;
    gx_init(&gx, s->w, group_hostile_results);
    group_frame_of_copy(s->gw, &gx);
    print_message("hostile group results: %d jobs, %d with a unit of another size\n", gx.units,
                  gx.found);
    assert_int_equal(gx.units, 1);
    assert_int_equal(gx.found, 1);
    gx_free(&gx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_collide_unit_through_wire_is_bit_identical),
        cmocka_unit_test(test_toi_unit_through_wire_is_bit_identical),
        cmocka_unit_test(test_island_units_through_wire_are_bit_identical),
        cmocka_unit_test(test_every_truncation_is_a_format_error),
        cmocka_unit_test(test_corrupted_units_are_refused_or_run_safely),
        cmocka_unit_test(test_bad_fields_are_format_errors),
        cmocka_unit_test(test_island_settings_and_impulses_travel),
        cmocka_unit_test(test_result_for_another_unit_is_a_format_error),
        cmocka_unit_test(test_group_units_through_wire_are_bit_identical),
        cmocka_unit_test(test_bad_group_fields_are_format_errors),
        cmocka_unit_test(test_group_result_for_another_unit_is_a_format_error),
    };
    return cmocka_run_group_tests(tests, scene_setup, scene_teardown);
}
