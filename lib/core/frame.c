/* frame.c - one frame as a value (the paper's steps 3-7; docs/DESIGN.md
 * section 3): substeps of force, contact impulses and integration, each
 * checked for contacts that got deeper than the tolerance and backed up to
 * their time of impact (steps 5-6). It reads and writes only the state it
 * is given; its jobs go to the executor it is given. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

#define MAX_SUBSTEPS 16       /* time-of-impact back-ups per frame */
#define TOI_AIM 0.9           /* back up to this share of the tolerance */
/* split islands: contacts per block (whole pairs: a pair has at most 4) */
#define SPLIT_BLOCK_CONTACTS 4

sc_contact_params sc_frame_contact_params(const sc_frame_config *cfg)
{
    return (sc_contact_params){
        .bounce_speed = 0.1,      /* the paper's threshold speed */
        .slop = 0.5e-3,
        .baumgarte = 0.2,
        .split_contacts = cfg->island_split,
        .block_contacts = SPLIT_BLOCK_CONTACTS,
        .tol = SC_SPLIT_TOL,
        .max_sweeps = SC_SPLIT_MAX_SWEEPS,
    };
}

/* ---- scratch ---------------------------------------------------------- */

int sc_frame_scratch_init(sc_frame_scratch *s)
{
    memset(s, 0, sizeof *s);
    sc_arena_init(&s->arena);
    s->bp = sc_bp_create();
    return s->bp ? SC_OK : SC_ENOMEM;
}

void sc_frame_scratch_free(sc_frame_scratch *s)
{
    if (!s)
        return;
    if (s->groups_free)
        s->groups_free(s->groups);
    sc_bp_destroy(s->bp);
    free(s->pairs);
    sc_islands_free(&s->islands);
    sc_arena_destroy(&s->arena);
    memset(s, 0, sizeof *s);
}

/* ---- the frame: the paper's steps (3)-(7) ---------------------------- */

/* Steps (4)-(7) once over h: islands, contact impulses, positions. */
static int substep(sc_frame *f, double h, sc_islands *is, unsigned char *touched)
{
    sc_frame_state *st = f->st;
    int n = st->nbodies;
    sc_apply_forces(f, h);
    double t0 = sc_cpu_now();
    for (int i = 0; i < n; i++)
        f->active[i] = sc_body_movable(&st->bodies[i]);
    int rc = sc_islands_build(&f->scr->arena, n, f->active, st->contacts, st->ncontacts, is);
    sc_stage_add(f->stats, SC_STAGE_ISLANDS, t0);
    if (rc != SC_OK)
        return rc;
    memset(touched, 0, (size_t)n);
    for (int k = 0; k < st->ncontacts; k++) {
        touched[st->contacts[k].body_a] = 1;
        touched[st->contacts[k].body_b] = 1;
    }
    /* step 7: one work unit per island (islands share no movable body) */
    t0 = sc_cpu_now();
    sc_contact_params params = sc_frame_contact_params(f->cfg);
    sc_job job = {
        .kind = SC_UNIT_ISLAND,
        .bodies = st->bodies,
        .c = st->contacts,
        .islands = is,
        .h = h,
        .params = &params,
    };
    rc = f->ex->run(f->ex, &job, SC_STAGE_LCP, f->stats);
    sc_stage_add(f->stats, SC_STAGE_LCP, t0);
    f->stats->islands = is->count;
    if (rc != SC_OK)
        return rc;
    t0 = sc_cpu_now();
    sc_integrate_positions(f, h);
    sc_stage_add(f->stats, SC_STAGE_INTEGRATE, t0);
    for (int i = 0; i < n; i++) {
        sc_body *b = &st->bodies[i];
        if (sc_body_movable(b) && (!sc_finite3(b->x) || !sc_finite3(b->v) || !sc_finite3(b->w)))
            return SC_ENUMERIC;
    }
    return SC_OK;
}

/* Step 5: the earliest time of impact (fraction of the substep) among new
 * contacts deeper than the tolerance; 1 when there is none. One query per
 * pair, as work units; the minimum does not depend on who ran what. */
static int earliest_impact(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                           double *frac)
{
    const sc_frame_state *st = f->st;
    double t0 = sc_cpu_now();
    *frac = 1;
    int np = 0;
    for (int k = 0; k < st->ncontacts; k++)
        np += st->contacts[k].depth > f->cfg->contact_tol_m;
    if (np == 0) {
        sc_stage_add(f->stats, SC_STAGE_TOI, t0);
        return SC_OK;
    }
    sc_arena *a = &f->scr->arena;
    sc_unit_pair *pairs = sc_arena_alloc(a, (size_t)np * sizeof *pairs);
    double *toi = pairs ? sc_arena_alloc(a, (size_t)np * sizeof *toi) : NULL;
    if (!toi) {
        sc_arena_free(a, pairs);
        return SC_ENOMEM;
    }
    np = 0;
    for (int k = 0; k < st->ncontacts; k++) {
        const sc_contact *c = &st->contacts[k];
        if (c->depth <= f->cfg->contact_tol_m)
            continue;
        if (np > 0 && pairs[np - 1].body_a == c->body_a && pairs[np - 1].body_b == c->body_b)
            continue;    /* one query per pair */
        sc_unit_pair *p = &pairs[np++];
        memset(p, 0, sizeof *p);
        p->sa = st->bodies[c->body_a].shape;
        p->sb = st->bodies[c->body_b].shape;
        p->body_a = c->body_a;
        p->body_b = c->body_b;
        /* a new pair backs up to first touch; a pair already touching that
         * digs in past the tolerance (a bolt rocking onto its other end)
         * backs up to where it reaches the tolerance */
        p->deepen = sc_contacts_have_pair(c0, n0, c->body_a, c->body_b);
        sc_body_pose(&saved[c->body_a], &p->a0);
        sc_body_pose(&saved[c->body_b], &p->b0);
        p->a1 = f->poses[c->body_a];    /* the detection just before */
        p->b1 = f->poses[c->body_b];
    }
    sc_job job = {
        .kind = SC_UNIT_TOI,
        .pairs = pairs,
        .npairs = np,
        /* aim below the tolerance: the backed-up substep's impulses
         * and push-out differ a little from the path the search
         * interpolated */
        .tol_m = TOI_AIM * f->cfg->contact_tol_m,
        .toi = toi,
    };
    for (int i = 0; i < np; i++)
        toi[i] = 1;
    int rc = f->ex->run(f->ex, &job, SC_STAGE_TOI, f->stats);
    for (int i = 0; rc == SC_OK && i < np; i++)
        *frac = fmin(*frac, toi[i]);
    sc_arena_free(a, toi);
    sc_arena_free(a, pairs);
    sc_stage_add(f->stats, SC_STAGE_TOI, t0);
    return rc;
}

/* The substeps of a frame, with the frame's arrays in place. */
static int substeps(sc_frame *f, double dt, sc_body *saved, unsigned char *touched)
{
    sc_frame_state *st = f->st;
    sc_arena *a = &f->scr->arena;
    sc_islands *is = &f->scr->islands;
    int n = st->nbodies;
    int rc = SC_OK;
    if (!st->contacts_valid) {
        /* bodies were added: pairs already deep in each other are counted
         * (the push-out separates them, but not as physics would) */
        rc = sc_detect(f);
        int la = -1, lb = -1;    /* the last pair counted (contacts sorted by pair) */
        for (int k = 0; rc == SC_OK && k < st->ncontacts; k++) {
            const sc_contact *c = &st->contacts[k];
            if (c->depth > 2 * f->cfg->contact_tol_m && (c->body_a != la || c->body_b != lb)) {
                f->stats->initial_overlaps++;
                la = c->body_a;
                lb = c->body_b;
            }
        }
    }
    double left = dt;
    for (int sub = 0; rc == SC_OK && left > 0; sub++) {
        /* keep the start of the substep: contacts and state */
        memcpy(saved, st->bodies, (size_t)n * sizeof *saved);
        int n0 = st->ncontacts;
        sc_contact *c0 = sc_arena_alloc(a, (size_t)n0 * sizeof *c0);
        if (!c0)
            return SC_ENOMEM;
        if (n0 > 0)
            memcpy(c0, st->contacts, (size_t)n0 * sizeof *c0);
        double h = left;
        rc = substep(f, h, is, touched);
        if (rc == SC_OK)
            rc = sc_detect(f);
        double frac = 1;
        if (rc == SC_OK && sub + 1 < MAX_SUBSTEPS)
            rc = earliest_impact(f, saved, c0, n0, &frac);
        if (rc == SC_OK && frac < 1) {
            /* steps 5-6: back up and advance only until they touch */
            memcpy(st->bodies, saved, (size_t)n * sizeof *saved);
            if (n0 > 0)
                memcpy(st->contacts, c0, (size_t)n0 * sizeof *c0);
            st->ncontacts = n0;
            h = fmax(frac * h, 1e-6 * dt);
            rc = substep(f, h, is, touched);
            if (rc == SC_OK)
                rc = sc_detect(f);
        }
        sc_arena_free(a, c0);
        f->stats->substeps++;
        left -= h;
        if (left < 1e-9 * dt)
            left = 0;
    }
    if (rc == SC_OK)
        sc_update_states(f, is, touched, dt);
    return rc;
}

int sc_frame_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                  sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats)
{
    int n = st->nbodies;
    if (n == 0)
        return SC_OK;
    sc_arena *a = &scr->arena;
    sc_frame f = { .cfg = cfg, .st = st, .scr = scr, .ex = ex, .stats = stats };
    /* the frame's arrays, last in first out */
    sc_body *saved = sc_arena_alloc(a, (size_t)n * sizeof *saved);
    unsigned char *touched = sc_arena_alloc(a, (size_t)n);
    f.centre = sc_arena_alloc(a, (size_t)n * 3 * sizeof *f.centre);
    f.radius = sc_arena_alloc(a, (size_t)n * sizeof *f.radius);
    f.active = sc_arena_alloc(a, (size_t)n);
    f.poses = sc_arena_alloc(a, (size_t)n * sizeof *f.poses);
    int rc = saved && touched && f.centre && f.radius && f.active && f.poses
                 ? substeps(&f, dt, saved, touched)
                 : SC_ENOMEM;
    sc_arena_free(a, f.poses);
    sc_arena_free(a, f.active);
    sc_arena_free(a, f.radius);
    sc_arena_free(a, f.centre);
    sc_arena_free(a, touched);
    sc_arena_free(a, saved);
    if (a->high > stats->arena_bytes)
        stats->arena_bytes = a->high;
    if (rc != SC_OK)
        return rc;
    for (int i = 0; i < n; i++) {
        v3_set(st->bodies[i].force, 0, 0, 0);
        v3_set(st->bodies[i].torque, 0, 0, 0);
    }
    st->contacts_valid = 1;
    return SC_OK;
}
