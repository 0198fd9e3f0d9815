/* detect.c - contact detection for the frame (the paper's step 4): bounding
 * spheres or sweep and prune, planes by signed distance, then the exact
 * narrow phase pair by pair in canonical order. Wakes sleepers that are
 * touched by awake bodies. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

/* Bodies [i0, i1)'s poses (kept for the narrow phase), spheres, activity
 * and skins for the broad phase. */
static void spheres(sc_frame *f, int i0, int i1)
{
    const sc_frame_state *st = f->st;
    double margin = f->cfg->contact_tol_m;
    for (int i = i0; i < i1; i++) {
        const sc_body *b = &st->bodies[i];
        sc_pose *p = &f->poses[i];
        sc_body_pose(b, p);
        v3_copy(&f->centre[3 * i], p->pos);
        int plane = b->shape->kind == SC_SHAPE_PLANE;
        /* planes join the sweep as far-away points and pair below */
        f->radius[i] = plane ? 0 : b->shape->bound_r + margin;
        if (plane)
            v3_set(&f->centre[3 * i], 0, 0, 0);
        f->active[i] = b->inv_mass > 0 && b->state != SC_ASLEEP;
        /* the skin: how far the centre (the pose's origin) can go in the
         * frame, as the motion groups reckon it */
        f->skin[i] = f->active[i] ? sc_body_reach(f->cfg, b, f->dt) + margin : 0;
    }
}

/* spheres() in tasks of the frame's runner from SC_SHARE_MIN bodies on (a
 * pile is detected some twenty times a frame, and the idle worker waited
 * through it), else here: each body's are its own, the same bits. */
static void spheres_task(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    sc_frame *f = arg;
    long long n = f->st->nbodies;
    spheres(f, (int)(n * t / SC_SHARE_CHUNKS), (int)(n * (t + 1) / SC_SHARE_CHUNKS));
}

/* Step 4, coarse: bounding spheres (or sweep and prune), plus every active
 * body against every static plane (planes have no bounding sphere). */
static int broadphase(sc_frame *f, int *npairs)
{
    const sc_frame_state *st = f->st;
    sc_frame_scratch *scr = f->scr;
    int n = st->nbodies, np = 0;
    int nplanes = 0;
    const sc_task_runner *r = f->ex ? f->ex->runner : NULL;
    if (r && n >= SC_SHARE_MIN)
        sc_tasks_run(r, spheres_task, f, SC_SHARE_CHUNKS, NULL);
    else
        spheres(f, 0, n);
    for (int i = 0; i < n; i++)
        nplanes += st->bodies[i].shape->kind == SC_SHAPE_PLANE;
    int method = f->cfg->broadphase;
    if (nplanes == 0) {
        np = sc_bp_find_pairs_skin(scr->bp, f->ex->runner, method, f->centre, f->radius,
                                   f->skin, f->active, n, &scr->pairs, &scr->pair_cap);
        if (np < 0)
            return np;
        *npairs = np;
        return SC_OK;
    }
    /* Bodies other than planes go through the broad phase with planes
     * parked (inactive, zero radius, at the origin) and their pairs dropped;
     * then plane pairs are added by signed distance and all re-sorted. */
    for (int i = 0; i < n; i++)
        if (st->bodies[i].shape->kind == SC_SHAPE_PLANE)
            f->active[i] = 0;
    np = sc_bp_find_pairs_skin(scr->bp, f->ex->runner, method, f->centre, f->radius, f->skin,
                               f->active, n, &scr->pairs, &scr->pair_cap);
    if (np < 0)
        return np;
    int k = 0;
    for (int i = 0; i < np; i++) {
        const sc_pair *pr = &scr->pairs[i];
        if (st->bodies[pr->a].shape->kind != SC_SHAPE_PLANE &&
            st->bodies[pr->b].shape->kind != SC_SHAPE_PLANE)
            scr->pairs[k++] = *pr;
    }
    np = k;
    /* the plane pairs apart, sorted (one per body and plane: few), then
     * merged with the sweep's, which are sorted already */
    int npl = 0;
    for (int pi = 0; pi < n; pi++) {
        const sc_body *pb = &st->bodies[pi];
        if (pb->shape->kind != SC_SHAPE_PLANE)
            continue;
        sc_pose pp;
        sc_body_pose(pb, &pp);
        double nrm[3];
        q_rotate(nrm, pp.quat, pb->shape->plane);
        double d = pb->shape->plane[3] + v3_dot(nrm, pp.pos);
        for (int i = 0; i < n; i++) {
            const sc_body *b = &st->bodies[i];
            if (i == pi || !f->active[i] || b->shape->kind == SC_SHAPE_PLANE)
                continue;
            if (v3_dot(nrm, &f->centre[3 * i]) - d > f->radius[i])
                continue;
            if (sc_grow((void **)&scr->plane_pairs, &scr->plane_pair_cap, npl + 1,
                        sizeof *scr->plane_pairs, INT_MAX) != SC_OK)
                return SC_ENOMEM;
            scr->plane_pairs[npl].a = i < pi ? i : pi;
            scr->plane_pairs[npl].b = i < pi ? pi : i;
            npl++;
        }
    }
    if (npl > 1)
        qsort(scr->plane_pairs, (size_t)npl, sizeof *scr->plane_pairs, sc_pair_cmp);
    if (npl > 0) {
        if (sc_grow((void **)&scr->pairs, &scr->pair_cap, np + npl, sizeof *scr->pairs,
                    INT_MAX) != SC_OK)
            return SC_ENOMEM;
        /* from the back, so that the sweep's pairs move at most once */
        int i = np - 1, j = npl - 1;
        for (int o = np + npl - 1; o >= 0; o--) {
            if (j < 0 || (i >= 0 && sc_pair_cmp(&scr->pairs[i], &scr->plane_pairs[j]) > 0))
                scr->pairs[o] = scr->pairs[i--];
            else
                scr->pairs[o] = scr->plane_pairs[j--];
        }
        np += npl;
    }
    *npairs = np;
    return SC_OK;
}

int sc_contacts_pair_start(const sc_contact *c, int n, int a, int b)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (c[mid].body_a < a || (c[mid].body_a == a && c[mid].body_b < b))
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

int sc_contacts_have_pair(const sc_contact *c, int n, int a, int b)
{
    int k = sc_contacts_pair_start(c, n, a, b);
    return k < n && c[k].body_a == a && c[k].body_b == b;
}

/* Whether c[0 .. n) (sorted by pair) holds pair p; the cursor *k walks c
 * for pairs asked in ascending order. */
static int held_pair(const sc_contact *c, int n, sc_pair p, int *k)
{
    while (*k < n && (c[*k].body_a < p.a || (c[*k].body_a == p.a && c[*k].body_b < p.b)))
        (*k)++;
    return *k < n && c[*k].body_a == p.a && c[*k].body_b == p.b;
}

static int carries_impulse(const sc_contact *c)
{
    return c->impulse[0] != 0 || c->impulse[1] != 0 || c->impulse[2] != 0;
}

/* Warm starts (docs/DESIGN.md section 11): each new contact takes the
 * impulse of the nearest old contact of the same pair not yet taken, when
 * it lies within a tenth of the smaller body's bounding radius (a resting
 * contact moves far less in a frame; a new one is farther). Both lists
 * are sorted by pair. */
static void match_impulses(const sc_frame_state *st, const sc_contact *old, int nold,
                           unsigned char *taken)
{
    int j0 = 0;
    for (int k = 0; k < st->ncontacts; k++) {
        sc_contact *c = &st->contacts[k];
        while (j0 < nold && (old[j0].body_a < c->body_a ||
                             (old[j0].body_a == c->body_a && old[j0].body_b < c->body_b)))
            j0++;
        double ra = st->bodies[c->body_a].shape->bound_r, rb = st->bodies[c->body_b].shape->bound_r;
        double r = 0.1 * min_d(ra, rb);
        int best = -1;
        double bd = r * r;
        for (int j = j0; j < nold && old[j].body_a == c->body_a && old[j].body_b == c->body_b; j++) {
            double d[3];
            v3_sub(d, old[j].pos, c->pos);
            double dd = v3_dot(d, d);
            if (!taken[j] && dd <= bd) {
                bd = dd;
                best = j;
            }
        }
        if (best >= 0) {
            taken[best] = 1;
            sc_impulse_copy(c, &old[best]);
        }
    }
}

static int pose_same(const sc_pose *a, const sc_pose *b)
{
    return memcmp(a, b, sizeof *a) == 0;
}

/* Pair i's contacts from the memo when its two poses are the same bits as
 * at the memo's detection (cursor *j walks the memo's pairs in order):
 * the memo's pair index, or -1. */
static int memo_find(const sc_np_memo *m, const sc_pose *poses, sc_pair p, int *j)
{
    while (*j < m->npairs && sc_pair_cmp(&m->pairs[*j], &p) < 0)
        (*j)++;
    if (*j == m->npairs || sc_pair_cmp(&m->pairs[*j], &p) != 0)
        return -1;
    return pose_same(&m->poses[p.a], &poses[p.a]) && pose_same(&m->poses[p.b], &poses[p.b])
               ? *j
               : -1;
}

/* This detection's results into the memo (raw contacts, pairs in order);
 * without memory the memo is dropped, which only costs time. */
static void memo_keep(sc_np_memo *m, const sc_frame *f, const sc_pair *pairs, int npairs,
                      const sc_contact *uc, const int *ncontact, int total)
{
    int n = f->st->nbodies;
    m->valid = 0;
    if (sc_grow((void **)&m->poses, &m->pose_cap, n, sizeof *m->poses, INT_MAX) ||
        sc_grow((void **)&m->pairs, &m->pair_cap, npairs, sizeof *m->pairs, INT_MAX) ||
        sc_grow((void **)&m->start, &m->start_cap, npairs + 1, sizeof *m->start, INT_MAX) ||
        sc_grow((void **)&m->c, &m->c_cap, total, sizeof *m->c, INT_MAX))
        return;
    if (n > 0)
        memcpy(m->poses, f->poses, (size_t)n * sizeof *m->poses);
    if (npairs > 0)
        memcpy(m->pairs, pairs, (size_t)npairs * sizeof *m->pairs);
    int k = 0;
    for (int i = 0; i < npairs; i++) {
        m->start[i] = k;
        if (ncontact[i] > 0)
            memcpy(&m->c[k], &uc[(size_t)i * SC_MAX_PAIR_CONTACTS],
                   (size_t)ncontact[i] * sizeof *m->c);
        k += ncontact[i];
    }
    m->start[npairs] = k;
    m->nbodies = n;
    m->npairs = npairs;
    m->valid = 1;
}

/* Step 4, exact: every pair through the narrow phase as work units on the
 * executor, merged in pair order, so the contact list is canonical. A pair
 * whose poses have not changed since the last detection of this frame (a
 * sleeper's, or an island a speculative re-solve left alone) takes its
 * contacts from the memo instead: the same bits, as the narrow phase reads
 * nothing else. */
static int narrowphase(sc_frame *f, int npairs)
{
    sc_frame_state *st = f->st;
    const sc_pair *pairs = f->scr->pairs;
    sc_arena *a = &f->scr->arena;
    sc_np_memo *m = &f->scr->memo;
    if (npairs > INT_MAX / SC_MAX_PAIR_CONTACTS)
        return SC_ETOOBIG;
    sc_unit_pair *up = sc_arena_alloc(a, (size_t)npairs * sizeof *up);
    int *ncontact = up ? sc_arena_alloc(a, (size_t)npairs * sizeof *ncontact) : NULL;
    int *run_of = ncontact ? sc_arena_alloc(a, (size_t)npairs * sizeof *run_of) : NULL;
    sc_contact *uc = run_of ? sc_arena_alloc(a, (size_t)npairs * SC_MAX_PAIR_CONTACTS *
                                                    sizeof *uc)
                            : NULL;
    int rc = uc ? SC_OK : SC_ENOMEM;
    int use_memo = m->valid && m->nbodies == st->nbodies;
    int nrun = 0, cursor = 0, held = 0;
    for (int i = 0; rc == SC_OK && i < npairs; i++) {
        int hit = use_memo ? memo_find(m, f->poses, pairs[i], &cursor) : -1;
        if (hit >= 0) {
            ncontact[i] = m->start[hit + 1] - m->start[hit];
            if (ncontact[i] > 0)
                memcpy(&uc[(size_t)i * SC_MAX_PAIR_CONTACTS], &m->c[m->start[hit]],
                       (size_t)ncontact[i] * sizeof *uc);
            continue;
        }
        sc_unit_pair *p = &up[nrun];
        const sc_body *A = &st->bodies[pairs[i].a], *B = &st->bodies[pairs[i].b];
        memset(p, 0, sizeof *p);    /* a1, b1 are the TOI's only */
        p->sa = A->shape;
        p->sb = B->shape;
        p->body_a = pairs[i].a;
        p->body_b = pairs[i].b;
        p->a0 = f->poses[pairs[i].a];
        p->b0 = f->poses[pairs[i].b];
        /* the contacts still held are those of the last detection; both
         * lists are in pair order, so one cursor walks them */
        p->touching = held_pair(st->contacts, st->ncontacts, pairs[i], &held);
        ncontact[i] = 0;
        run_of[nrun++] = i;
    }
    f->stats->frame.detect.np_pairs += npairs;
    f->stats->frame.detect.np_reused += npairs - nrun;
    /* the old contacts that carry an impulse, for the warm start */
    int nold = 0;
    for (int k = 0; k < st->ncontacts; k++)
        nold += carries_impulse(&st->contacts[k]);
    sc_contact *old = rc == SC_OK && nold ? sc_arena_alloc(a, (size_t)nold * sizeof *old) : NULL;
    unsigned char *taken = old ? sc_arena_alloc(a, (size_t)nold) : NULL;
    if (nold && rc == SC_OK && !taken)
        rc = SC_ENOMEM;
    if (taken) {
        memset(taken, 0, (size_t)nold);
        nold = 0;
        for (int k = 0; k < st->ncontacts; k++)
            if (carries_impulse(&st->contacts[k]))
                old[nold++] = st->contacts[k];
    }
    /* the pairs collided now: their contacts and counts in run order */
    int *rn = rc == SC_OK && nrun ? sc_arena_alloc(a, (size_t)nrun * sizeof *rn) : NULL;
    sc_contact *rcs = rn ? sc_arena_alloc(a, (size_t)nrun * SC_MAX_PAIR_CONTACTS * sizeof *rcs)
                         : NULL;
    if (nrun && rc == SC_OK && !rcs)
        rc = SC_ENOMEM;
    sc_job job = {
        .kind = SC_UNIT_COLLIDE,
        .pairs = up,
        .npairs = nrun,
        .contacts = rcs,
        .ncontact = rn,
    };
    st->ncontacts = 0;
    if (rc == SC_OK && nrun > 0)
        rc = f->ex->run(f->ex, &job, SC_STAGE_NARROWPHASE, f->stats);
    for (int r = 0; rc == SC_OK && r < nrun; r++) {
        int i = run_of[r];
        ncontact[i] = rn[r];
        if (rn[r] > 0)
            memcpy(&uc[(size_t)i * SC_MAX_PAIR_CONTACTS], &rcs[(size_t)r * SC_MAX_PAIR_CONTACTS],
                   (size_t)rn[r] * sizeof *uc);
    }
    int total = 0;
    for (int i = 0; rc == SC_OK && i < npairs; i++)
        total += ncontact[i];
    if (rc == SC_OK &&
        sc_grow((void **)&st->contacts, &st->contact_cap, total, sizeof *st->contacts, INT_MAX))
        rc = SC_ENOMEM;
    double maxpen = 0;
    for (int i = 0; rc == SC_OK && i < npairs; i++) {
        const sc_contact *c = &uc[(size_t)i * SC_MAX_PAIR_CONTACTS];
        for (int k = 0; k < ncontact[i]; k++) {
            st->contacts[st->ncontacts++] = c[k];
            maxpen = max_d(maxpen, c[k].depth);
        }
    }
    if (rc == SC_OK)
        memo_keep(m, f, pairs, npairs, uc, ncontact, total);
    else
        m->valid = 0;
    if (rc == SC_OK && taken)
        match_impulses(st, old, nold, taken);
    sc_arena_free(a, rcs);
    sc_arena_free(a, rn);
    sc_arena_free(a, taken);
    sc_arena_free(a, old);
    sc_arena_free(a, uc);
    sc_arena_free(a, run_of);
    sc_arena_free(a, ncontact);
    sc_arena_free(a, up);
    if (rc != SC_OK)
        return rc;
    f->stats->frame.detect.contacts = st->ncontacts;
    f->stats->frame.detect.max_penetration = maxpen;
    return SC_OK;
}

int sc_detect(sc_frame *f)
{
    sc_frame_state *st = f->st;
    double t0 = sc_stage_now(f);
    int npairs = 0;
    int rc = broadphase(f, &npairs);
    sc_stage_since(f, SC_STAGE_BROADPHASE, t0);
    if (rc != SC_OK)
        return rc;
    f->stats->frame.detect.pairs = npairs;
    t0 = sc_stage_now(f);
    rc = narrowphase(f, npairs);
    sc_stage_since(f, SC_STAGE_NARROWPHASE, t0);
    /* A sleeper woken here has pairs the broad phase left out (with the
     * floor, with other sleepers): detection runs again until nobody new
     * wakes, so that it is solved with them. Else a box that falls on a
     * sleeper meets a sleeper without its floor and shoves it through,
     * where an awake one does not move (test_physics). */
    while (rc == SC_OK && sc_wake_touched(st->bodies, st->contacts, st->ncontacts) > 0) {
        t0 = sc_stage_now(f);
        rc = broadphase(f, &npairs);
        sc_stage_since(f, SC_STAGE_BROADPHASE, t0);
        if (rc != SC_OK)
            break;
        f->stats->frame.detect.pairs = npairs;
        t0 = sc_stage_now(f);
        rc = narrowphase(f, npairs);
        sc_stage_since(f, SC_STAGE_NARROWPHASE, t0);
    }
    return rc;
}

int sc_wake_touched(sc_body *bodies, const sc_contact *c, int n)
{
    int woken = 0;
    for (int k = 0; k < n; k++) {
        sc_body *a = &bodies[c[k].body_a], *b = &bodies[c[k].body_b];
        if (a->state == SC_ASLEEP && sc_body_movable(b)) {
            a->state = SC_CONTACT;
            a->rest_s = 0;
            woken++;
        }
        if (b->state == SC_ASLEEP && sc_body_movable(a)) {
            b->state = SC_CONTACT;
            b->rest_s = 0;
            woken++;
        }
    }
    return woken;
}
