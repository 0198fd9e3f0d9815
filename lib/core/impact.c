/* impact.c - what a substep does about contacts that got too deep (the
 * paper's steps 5-6; docs/DESIGN.md section 3.4): the earliest time of
 * impact to back up to, and in the local mode the speculative contacts
 * that let a substep be solved again with the pair in its LCP instead.
 * frame.c runs the loop; this file decides per pair. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

#define SAME_NORMAL 0.95      /* cos of ~18 degrees */
/* A pair held at its touch bounces at the substep's start, early by its
 * gap: gaps beyond this many contact tolerances back up instead (a fast
 * elastic sphere bouncing that early can meet another body in the same
 * substep, a collision the LCP cannot order) */
#define SPEC_MARGIN 10.0
#define CREEP_BACKUPS 4       /* back-ups of a frame before a creeping pair
                                 is held instead (sc_spec_sort_out()) */
#define SPEC_DEPTH 0.25       /* deepest share of the smaller feature a
                                 speculative contact may come from */

/* One query pair of a TOI job from the substep's start (saved) and end
 * (the detection just before) poses. */
static void toi_pair(const sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                     int a, int b, sc_unit_pair *p)
{
    const sc_frame_state *st = f->st;
    memset(p, 0, sizeof *p);
    p->sa = st->bodies[a].shape;
    p->sb = st->bodies[b].shape;
    p->body_a = a;
    p->body_b = b;
    /* a new pair backs up to first touch; a pair already touching that
     * digs in past the tolerance (a bolt rocking onto its other end)
     * backs up to where it reaches the tolerance */
    p->deepen = sc_contacts_have_pair(c0, n0, a, b);
    sc_body_pose(&saved[a], &p->a0);
    sc_body_pose(&saved[b], &p->b0);
    p->a1 = f->poses[a];
    p->b1 = f->poses[b];
}

/* The pairs whose contacts are marked 1 in fast (or, fast NULL, have a
 * contact deeper than the tolerance), one query each, into a TOI job
 * (pairs and toi from the arena, toi[i] = 1). */
static int toi_job(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                   const unsigned char *fast, int exact, sc_job *job)
{
    const sc_frame_state *st = f->st;
    int np = 0;
    for (int k = 0; k < st->ncontacts; k++)
        np += fast ? fast[k] == 1 : st->contacts[k].depth > f->cfg->contact_tol_m;
    memset(job, 0, sizeof *job);
    job->kind = SC_UNIT_TOI;
    if (np == 0)
        return SC_OK;
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
        if (fast ? fast[k] != 1 : c->depth <= f->cfg->contact_tol_m)
            continue;
        if (np > 0 && pairs[np - 1].body_a == c->body_a && pairs[np - 1].body_b == c->body_b)
            continue;    /* one query per pair */
        toi_pair(f, saved, c0, n0, c->body_a, c->body_b, &pairs[np]);
        pairs[np].exact = exact;
        toi[np++] = 1;
    }
    job->pairs = pairs;
    job->npairs = np;
    /* aim below the tolerance: the backed-up substep's impulses and
     * push-out differ a little from the path the search interpolated */
    job->tol_m = SC_TOI_AIM * f->cfg->contact_tol_m;
    job->toi = toi;
    return SC_OK;
}

static void toi_job_free(sc_frame *f, sc_job *job)
{
    sc_arena_free(&f->scr->arena, job->toi);
    sc_arena_free(&f->scr->arena, (void *)job->pairs);
}

int sc_frame_earliest_impact(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                             const unsigned char *fast, double *frac)
{
    double t0 = sc_stage_now(f);
    *frac = 1;
    sc_job job;
    int rc = toi_job(f, saved, c0, n0, fast, 0, &job);
    if (rc == SC_OK && job.npairs > 0) {
        rc = f->ex->run(f->ex, &job, SC_STAGE_TOI, f->stats);
        for (int i = 0; rc == SC_OK && i < job.npairs; i++)
            *frac = min_d(*frac, job.toi[i]);
        toi_job_free(f, &job);
    }
    sc_stage_since(f, SC_STAGE_TOI, t0);
    return rc;
}

/* ---- speculative contacts (local mode) -------------------------------- */

/* Where the material point of body at pose p1 that lies at x ends up at
 * pose p0 (a rigid transport back to the substep's start). */
static void transport(double out[3], const double x[3], const sc_pose *p1, const sc_pose *p0)
{
    double R1[9], R0[9], l[3], d[3];
    q_to_m3(R1, p1->quat);
    q_to_m3(R0, p0->quat);
    v3_sub(d, x, p1->pos);
    m3_tmulv(l, R1, d);
    m3_mulv(out, R0, l);
    v3_add(out, out, p0->pos);
}

/* Contact ck, found with the bodies at poses a1 and b1, moved back to
 * poses a0 and b0: the midpoint of the two bodies' material points, and
 * depth there = depth - (da - db).n (d: the points' displacements from 0
 * to 1); negative is a gap. */
static sc_contact to_start(const sc_contact *ck, const sc_pose *a1, const sc_pose *b1,
                           const sc_pose *a0, const sc_pose *b0)
{
    double pa[3], pb[3], da[3], db[3], dd[3];
    transport(pa, ck->pos, a1, a0);
    transport(pb, ck->pos, b1, b0);
    sc_contact s = *ck;
    for (int j = 0; j < 3; j++)
        s.pos[j] = 0.5 * (pa[j] + pb[j]);
    v3_sub(da, ck->pos, pa);
    v3_sub(db, ck->pos, pb);
    v3_sub(dd, da, db);
    s.depth = ck->depth - v3_dot(dd, ck->normal);
    v3_set(s.impulse, 0, 0, 0);
    s.impulse_dt = 0;
    return s;
}

/* Two contacts of a pair hold the same thing: close, and pushing the same
 * way (the same place of a mesh touched along another face is not). */
static int same_point(const sc_contact *x, const sc_contact *y, double near)
{
    return v3_dist(x->pos, y->pos) < near && v3_dot(x->normal, y->normal) > SAME_NORMAL;
}

/* s appended to spec unless a start contact of its pair (c0[j0 .. j1))
 * or a speculative one lies within near of it: 1 added, 0 not, or
 * SC_ENOMEM. */
static int spec_add(sc_spec_list *spec, const sc_contact *c0, int j0, int j1,
                    const sc_contact *s, double near)
{
    for (int j = j0; j < j1; j++)
        if (same_point(&c0[j], s, near))
            return 0;
    for (int j = 0; j < spec->n; j++)
        if (spec->c[j].body_a == s->body_a && spec->c[j].body_b == s->body_b &&
            same_point(&spec->c[j], s, near))
            return 0;
    if (sc_grow((void **)&spec->c, &spec->cap, spec->n + 1, sizeof *spec->c, INT_MAX))
        return SC_ENOMEM;
    spec->c[spec->n++] = *s;
    return 1;
}

/* Two contacts of one pair count as the same point within this (and
 * normals within acos(SAME_NORMAL)). */
static double near_of(const sc_frame *f, int a, int b)
{
    return 0.1 * min_d(f->st->bodies[a].shape->bound_r, f->st->bodies[b].shape->bound_r);
}

/* The run of pair (a, b) in the pair-sorted c[0 .. n): its first index,
 * *end one past its last (both the pair's place when it has none); *at
 * as sc_contacts_pair_walk()'s. */
static int pair_run_at(const sc_contact *c, int n, int a, int b, int *at, int *end)
{
    int k = sc_contacts_pair_walk(c, n, a, b, at), e = k;
    while (e < n && c[e].body_a == a && c[e].body_b == b)
        e++;
    *end = e;
    return k;
}

static int pair_run(const sc_contact *c, int n, int a, int b, int *end)
{
    int at = -1;
    return pair_run_at(c, n, a, b, &at, end);
}

/* Pair (a, b) held: its detected contacts marked 2 in fast, one fast pair
 * fewer. */
static void mark_held(const sc_frame_state *st, int a, int b, unsigned char *fast, int *nfast)
{
    int k1, k0 = pair_run(st->contacts, st->ncontacts, a, b, &k1);
    memset(fast + k0, 2, (size_t)(k1 - k0));
    (*nfast)--;
}

/* How deep pair (a, b) may get in this substep: the tolerance for a new
 * pair, and for one touching at the start (contacts in c0, *touching = 1)
 * within it; one already past it, its deepest start depth plus a
 * hundredth of the tolerance. (The margin is what a pair just inside the
 * tolerance may end past it by, so it is kept small.)
 * *at walks c0 as pair_run_at()'s does. */
static double pair_limit_at(const sc_contact *c0, int n0, int a, int b, double tol,
                            int *touching, int *at)
{
    double d0 = -1;
    int j1;
    for (int j = pair_run_at(c0, n0, a, b, at, &j1); j < j1; j++)
        d0 = max_d(d0, c0[j].depth);
    *touching = d0 >= 0;
    return d0 <= tol ? tol : d0 + 0.01 * tol;
}

/* pair_limit_at() on its own. */
static double pair_limit(const sc_contact *c0, int n0, int a, int b, double tol, int *touching)
{
    int at = -1;
    return pair_limit_at(c0, n0, a, b, tol, touching, &at);
}

/* The deepest of contacts s[0 .. n) if it is a gap, else -1. */
static int deepest_gap(const sc_contact *s, int n)
{
    int k = -1;
    for (int i = 0; i < n; i++)
        if (k < 0 || s[i].depth > s[k].depth)
            k = i;
    return k >= 0 && s[k].depth < 0 ? k : -1;
}

/* The bodies' relative speed along contact c's normal at its point from
 * their velocities at the substep's start (after h of the external forces
 * when f is given); negative closes. */
static double normal_speed(const sc_frame *f, const sc_body *saved, const sc_contact *c, double h)
{
    double vrel = 0;
    for (int side = 0; side < 2; side++) {
        const sc_body *b = &saved[side ? c->body_b : c->body_a];
        if (!sc_body_movable(b))
            continue;
        double v[3], r[3], wr[3];
        v3_copy(v, b->v);
        if (f) {
            v3_madd(v, v, f->cfg->gravity, h);
            v3_madd(v, v, b->force, h * b->inv_mass);
        }
        v3_sub(r, c->pos, b->x);
        v3_cross(wr, b->w, r);
        v3_add(v, v, wr);
        vrel += (side ? 1 : -1) * v3_dot(v, c->normal);
    }
    return vrel;
}

/* Whether a pair whose deepest contact at the substep's start is c, a
 * gap, is only brought together by impulses of this substep: its own
 * approach (each movable body's velocity at the start, and after the
 * external forces of h, at the contact point along the normal) cannot
 * close that gap within h. Such a pair meets after another collision of
 * the substep (a sphere bounced off one neighbour into the next): held
 * in the same LCP, both collisions would be simultaneous, and Newton's
 * restitution on simultaneous contacts can add energy. A perfectly
 * elastic one is backed up to instead, which orders them; an inelastic
 * one is held (its row rests in the LCP and bounces at the substep's end,
 * contact.c rebound()): in a pile nearly every part is pushed in by its
 * neighbours, and backing the whole pile up for each made piles slow. */
static int pushed_in(const sc_frame *f, const sc_body *saved, const sc_contact *c, double h)
{
    double reach = 0;
    for (int pass = 0; pass < 2; pass++)
        reach = max_d(reach, -normal_speed(pass ? f : NULL, saved, c, h) * h);
    /* the same test as contact.c's for a colliding speculative row: what
     * is held here bounces there */
    return -c->depth >= reach;
}

/* Whether a pair with contact c has restitution 1 (a pair's is the
 * larger of its bodies', as contact.c takes it). */
static int perfectly_elastic(const sc_body *saved, const sc_contact *c)
{
    return max_d(saved[c->body_a].restitution, saved[c->body_b].restitution) >= 1;
}

/* Whether a pair whose deepest contact at the substep's start is c, a
 * gap, is a perfectly elastic collision: restitution 1
 * (perfectly_elastic()) and c closing faster than the bounce speed. Such
 * a pair is not held: it backs up to its touch, as in the world-wide
 * mode, so that its collisions come one at a time in their order. Held,
 * several touches of one substep would be solved at once (a faceted
 * sphere's vertices, or a floor touch that a hit on the same sphere
 * earlier in the substep would have prevented), and restitution on
 * simultaneous contacts loses or gains energy, so elastic bodies drift
 * (docs/DESIGN.md 3.4). Inelastic pairs are still held: they
 * lose energy anyway, and piles need it. */
static int elastic_collision(const sc_body *saved, const sc_contact *c)
{
    return perfectly_elastic(saved, c) && normal_speed(NULL, saved, c, 0) < -SC_BOUNCE_SPEED;
}

int sc_spec_fast_elastic(const sc_frame *f, const sc_body *saved, const unsigned char *fast)
{
    for (int k = 0; k < f->st->ncontacts; k++)
        if (fast[k] == 1 && perfectly_elastic(saved, &f->st->contacts[k]))
            return 1;
    return 0;
}

/* Whether a pair with contacts s[0 .. n) at the substep's start backs up
 * instead of being held: a perfectly elastic pair whose deepest contact is
 * a gap that it is only pushed into, or a perfectly elastic collision. */
static int backs_up(const sc_frame *f, const sc_body *saved, const sc_contact *s, int n, double h)
{
    int k = deepest_gap(s, n);
    return k >= 0 && ((perfectly_elastic(saved, &s[k]) && pushed_in(f, saved, &s[k], h)) ||
                      elastic_collision(saved, &s[k]));
}

/* The contacts of the detection's pair run st->contacts[k0 .. k1) moved
 * back to the substep's start into spec (of a pair touching at the start,
 * only those deeper than limit: its new points), unless a start or
 * speculative contact holds the same point, or the pair backs up
 * (backs_up()) and hold (SC_HOLD_*) lacks SC_HOLD_ELASTIC. 1 if one was
 * added, 0 if not, or SC_ENOMEM. */
static int end_contacts(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0, int k0,
                        int k1, double limit, int touching, double h, int hold,
                        sc_spec_list *spec)
{
    const sc_frame_state *st = f->st;
    int a = st->contacts[k0].body_a, b = st->contacts[k0].body_b;
    int j1, j0 = pair_run(c0, n0, a, b, &j1);
    sc_pose a0, b0;
    sc_body_pose(&saved[a], &a0);
    sc_body_pose(&saved[b], &b0);
    sc_contact s[SC_MAX_PAIR_CONTACTS];
    int n = 0;
    for (int k = k0; k < k1 && n < SC_MAX_PAIR_CONTACTS; k++)
        if (!touching || st->contacts[k].depth > limit)
            s[n++] = to_start(&st->contacts[k], &f->poses[a], &f->poses[b], &a0, &b0);
    if (!(hold & SC_HOLD_ELASTIC) && backs_up(f, saved, s, n, h))
        return 0;
    int added = 0;
    for (int k = 0; k < n; k++) {
        int rc = spec_add(spec, c0, j0, j1, &s[k], near_of(f, a, b));
        if (rc < 0)
            return rc;
        added |= rc;
    }
    return added;
}

int sc_spec_sort_out(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0, double h,
                     sc_spec_list *spec, unsigned char *fast, int *nfast)
{
    const sc_frame_state *st = f->st;
    double tol = f->cfg->contact_tol_m;
    int nslow = 0, at = -1;
    *nfast = 0;
    memset(fast, 0, (size_t)st->ncontacts);
    for (int k0 = 0, k1; k0 < st->ncontacts; k0 = k1) {
        const sc_contact *c = &st->contacts[k0];
        int a = c->body_a, b = c->body_b;
        double d1 = 0;
        for (k1 = k0; k1 < st->ncontacts && st->contacts[k1].body_a == a &&
                      st->contacts[k1].body_b == b; k1++)
            d1 = max_d(d1, st->contacts[k1].depth);
        int touching;
        double limit = pair_limit_at(c0, n0, a, b, tol, &touching, &at);
        if (!(d1 > limit))
            continue;
        const sc_shape *sa = st->bodies[a].shape, *sb = st->bodies[b].shape;
        sc_pose a0, b0;
        sc_body_pose(&saved[a], &a0);
        sc_body_pose(&saved[b], &b0);
        double feature = min_d(sc_toi_feature(sa), sc_toi_feature(sb));
        double sweep = sc_toi_sweep(sa, &a0, &f->poses[a]) + sc_toi_sweep(sb, &b0, &f->poses[b]);
        if (sweep > 0.5 * feature || d1 > SPEC_DEPTH * feature) {
            for (int k = k0; k < k1; k++)
                fast[k] = 1;
            (*nfast)++;
            continue;
        }
        int added = end_contacts(f, saved, c0, n0, k0, k1, limit, touching, h, 0, spec);
        if (added < 0)
            return added;
        /* a slow pair with nothing new to hold it got deeper on the rows
         * it had (a stack of mesh cubes sinks so), or was pushed in:
         * it goes as a fast one, searched for where it passed the limit,
         * else backed up; but once the frame has backed up CREEP_BACKUPS
         * times, a touching pair past its limit by a hundredth of the
         * tolerance at most is left where it ended: pressed in at its
         * limit, it passes it again early in every substep, and each
         * back-up advances the pile only a little of the time left, so
         * such frames spend every back-up they may (docs/DESIGN.md 3.4) */
        if (!added && touching && f->backups >= CREEP_BACKUPS && d1 <= limit + 0.01 * tol)
            continue;
        memset(fast + k0, added ? 2 : 1, (size_t)(k1 - k0));
        *nfast += !added;
        nslow += added;
    }
    return nslow;
}

/* Fast pair (a, b) held by its contacts where the substep ended (as a
 * slow pair is): 1 when one was added (its contacts then marked 2 in fast
 * and the pair taken off *nfast), 0 when none was, or SC_ENOMEM. */
static int hold_at_end(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0, int a,
                       int b, double h, int hold, sc_spec_list *spec, unsigned char *fast,
                       int *nfast)
{
    const sc_frame_state *st = f->st;
    int k1, k0 = pair_run(st->contacts, st->ncontacts, a, b, &k1);
    int touching;
    double limit = pair_limit(c0, n0, a, b, f->cfg->contact_tol_m, &touching);
    int added = end_contacts(f, saved, c0, n0, k0, k1, limit, touching, h, hold, spec);
    if (added > 0)
        mark_held(st, a, b, fast, nfast);
    return added;
}

int sc_spec_touch(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0, double h,
                  sc_spec_list *spec, unsigned char *fast, int *nfast, int hold)
{
    double t0 = sc_stage_now(f);
    sc_arena *ar = &f->scr->arena;
    const sc_frame_state *st = f->st;
    sc_job tj;
    int rc = toi_job(f, saved, c0, n0, fast, 1, &tj);
    int np = tj.npairs, ntouch = 0;
    if (rc != SC_OK || np == 0) {
        sc_stage_since(f, SC_STAGE_TOI, t0);
        return rc;
    }
    /* a pair already held by speculative contacts that still got too
     * deep touches elsewhere too (a bolt landing on one end and rocking
     * onto the other within the substep): search where its depth passes
     * the tolerance, not its first touch again */
    for (int i = 0; i < np; i++) {
        sc_unit_pair *p = (sc_unit_pair *)&tj.pairs[i];
        for (int j = 0; j < spec->n && !p->deepen; j++)
            p->deepen = spec->c[j].body_a == p->body_a && spec->c[j].body_b == p->body_b;
    }
    /* each pair's own time of impact (exact: every pair, not only the
     * earliest), then its contacts there */
    rc = f->ex->run(f->ex, &tj, SC_STAGE_TOI, f->stats);
    sc_unit_pair *cp = NULL;
    sc_contact *uc = NULL;
    int *ncontact = NULL;
    if (rc == SC_OK) {
        cp = sc_arena_alloc(ar, (size_t)np * sizeof *cp);
        uc = cp ? sc_arena_alloc(ar, (size_t)np * SC_MAX_PAIR_CONTACTS * sizeof *uc) : NULL;
        ncontact = uc ? sc_arena_alloc(ar, (size_t)np * sizeof *ncontact) : NULL;
        rc = ncontact ? SC_OK : SC_ENOMEM;
    }
    int nc = 0;
    for (int i = 0; rc == SC_OK && i < np; i++) {
        const sc_unit_pair *p = &tj.pairs[i];
        if (!(tj.toi[i] < 1)) {
            /* no time found (a pair already deep at the start is not
             * searched): held where it ended, as a slow pair */
            int r = hold_at_end(f, saved, c0, n0, p->body_a, p->body_b, h, hold, spec, fast, nfast);
            if (r < 0)
                rc = r;
            ntouch += r > 0;
            continue;
        }
        sc_unit_pair *q = &cp[nc++];
        *q = *p;
        sc_pose_lerp(&q->a0, &p->a0, &p->a1, tj.toi[i]);
        sc_pose_lerp(&q->b0, &p->b0, &p->b1, tj.toi[i]);
        q->a1 = p->a0;    /* the start, for the transport below */
        q->b1 = p->b0;
    }
    sc_job cj = { .kind = SC_UNIT_COLLIDE, .pairs = cp, .npairs = nc, .contacts = uc,
                  .ncontact = ncontact };
    if (rc == SC_OK && nc > 0)
        rc = f->ex->run(f->ex, &cj, SC_STAGE_TOI, f->stats);
    /* the contacts at the touch, moved back to the substep's start */
    double margin = SPEC_MARGIN * f->cfg->contact_tol_m;
    for (int i = 0; rc == SC_OK && i < nc; i++) {
        const sc_unit_pair *q = &cp[i];
        int a = q->body_a, b = q->body_b;
        int j1, j0 = pair_run(c0, n0, a, b, &j1);
        sc_contact s[SC_MAX_PAIR_CONTACTS];
        double gap = INFINITY;
        for (int k = 0; k < ncontact[i]; k++) {
            s[k] = to_start(&uc[(size_t)i * SC_MAX_PAIR_CONTACTS + k], &q->a0, &q->b0, &q->a1,
                            &q->b1);
            gap = min_d(gap, -s[k].depth);
        }
        /* too far to bounce early: it backs up, unless the substep
         * already backed up (then it is held where it ended); pushed in,
         * or perfectly elastic: it backs up while the substep may */
        int far = gap > margin;
        if ((!(hold & SC_HOLD_FAR) && far) ||
            (!(hold & SC_HOLD_ELASTIC) && backs_up(f, saved, s, ncontact[i], h)))
            continue;
        int added = 0;
        for (int k = 0; !far && k < ncontact[i] && rc == SC_OK; k++) {
            int r = spec_add(spec, c0, j0, j1, &s[k], near_of(f, a, b));
            if (r < 0)
                rc = r;
            added |= r > 0;
        }
        if (added) {
            mark_held(st, a, b, fast, nfast);
            ntouch++;
        } else if (rc == SC_OK) {
            /* nothing new at the touch: where it ended, then (else it
             * backs up) */
            int r = hold_at_end(f, saved, c0, n0, a, b, h, hold, spec, fast, nfast);
            if (r < 0)
                rc = r;
            ntouch += r > 0;
        }
    }
    sc_arena_free(ar, ncontact);
    sc_arena_free(ar, uc);
    sc_arena_free(ar, cp);
    toi_job_free(f, &tj);
    sc_stage_since(f, SC_STAGE_TOI, t0);
    return rc == SC_OK ? ntouch : rc;
}

static int cmp_contact_pair(const void *x, const void *y)
{
    const sc_contact *a = x, *b = y;
    if (a->body_a != b->body_a)
        return (a->body_a > b->body_a) - (a->body_a < b->body_a);
    return (a->body_b > b->body_b) - (a->body_b < b->body_b);
}

int sc_spec_merge(sc_frame_state *st, const sc_contact *c0, int n0, sc_spec_list *spec)
{
    const sc_contact *sp = spec->c;
    int ns = spec->n;
    if (ns > 1)
        qsort(spec->c, (size_t)ns, sizeof *spec->c, cmp_contact_pair);
    if (sc_grow((void **)&st->contacts, &st->contact_cap, n0 + ns, sizeof *st->contacts,
                INT_MAX))
        return SC_ENOMEM;
    /* by pair, a pair's start contacts first */
    int i = 0, j = 0, k = 0;
    while (i < n0 || j < ns) {
        int take0 = j >= ns || (i < n0 && (c0[i].body_a < sp[j].body_a ||
                                           (c0[i].body_a == sp[j].body_a &&
                                            c0[i].body_b <= sp[j].body_b)));
        st->contacts[k++] = take0 ? c0[i++] : sp[j++];
    }
    st->ncontacts = k;
    return SC_OK;
}
