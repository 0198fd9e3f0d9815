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

/* Whether c's pair comes before pair (a, b). */
static int pair_before(const sc_contact *c, int a, int b)
{
    return c->body_a < a || (c->body_a == a && c->body_b < b);
}

int sc_contacts_pair_start(const sc_contact *c, int n, int a, int b)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (pair_before(&c[mid], a, b))
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

int sc_contacts_pair_walk(const sc_contact *c, int n, int a, int b, int *at)
{
    int k = *at;
    if (k < 0 || (k > 0 && !pair_before(&c[k - 1], a, b)))
        k = sc_contacts_pair_start(c, n, a, b);
    while (k < n && pair_before(&c[k], a, b))
        k++;
    return *at = k;
}

int sc_contacts_have_pair(const sc_contact *c, int n, int a, int b)
{
    int k = sc_contacts_pair_start(c, n, a, b);
    return k < n && c[k].body_a == a && c[k].body_b == b;
}

/* Whether c[0 .. n) (sorted by pair) holds pair p; the cursor *k walks c
 * (sc_contacts_pair_walk()). */
static int held_pair(const sc_contact *c, int n, sc_pair p, int *k)
{
    int i = sc_contacts_pair_walk(c, n, p.a, p.b, k);
    return i < n && c[i].body_a == p.a && c[i].body_b == p.b;
}

static int carries_impulse(const sc_contact *c)
{
    return c->impulse[0] != 0 || c->impulse[1] != 0 || c->impulse[2] != 0;
}

/* Warm starts (docs/DESIGN.md section 11): each new contact takes the
 * impulse of the nearest old contact of the same pair that carries one and
 * is not yet taken, when it lies within a tenth of the smaller body's
 * bounding radius (a resting contact moves far less in a frame; a new one
 * is farther). Both lists are sorted by pair; c[0 .. n) are the new
 * contacts of whole pairs, so that runs over disjoint pairs share nothing
 * (taken: one flag per old contact). */
static void match_impulses(const sc_frame_state *st, sc_contact *c, int n, const sc_contact *old,
                           int nold, unsigned char *taken)
{
    int at = -1;
    for (int k = 0; k < n; k++) {
        sc_contact *ck = &c[k];
        int j0 = sc_contacts_pair_walk(old, nold, ck->body_a, ck->body_b, &at);
        double ra = st->bodies[ck->body_a].shape->bound_r;
        double rb = st->bodies[ck->body_b].shape->bound_r;
        double r = 0.1 * min_d(ra, rb);
        int best = -1;
        double bd = r * r;
        for (int j = j0; j < nold && old[j].body_a == ck->body_a && old[j].body_b == ck->body_b;
             j++) {
            if (!carries_impulse(&old[j]) || taken[j])
                continue;
            double d[3];
            v3_sub(d, old[j].pos, ck->pos);
            double dd = v3_dot(d, d);
            if (dd <= bd) {
                bd = dd;
                best = j;
            }
        }
        if (best >= 0) {
            taken[best] = 1;
            sc_impulse_copy(ck, &old[best]);
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

/* The first of the memo's pairs not before p. */
static int memo_lower(const sc_np_memo *m, sc_pair p)
{
    int lo = 0, hi = m->npairs;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (sc_pair_cmp(&m->pairs[mid], &p) < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The narrow phase's passes over the pairs (narrowphase()), in chunks of
 * whole pairs that are tasks of the frame's runner from NP_SHARE_MIN pairs
 * on: a pile is detected some twenty times a frame, and each pass only
 * reads shared data and writes its own pairs' outputs, so the result is the
 * same bits whoever runs which. */
#define NP_SHARE_MIN 512

typedef struct np_pass {
    const sc_frame *f;
    const sc_pair *pairs;
    int npairs, chunks;
    const sc_np_memo *m;
    int use_memo;
    int *hit;               /* per pair: its memo index, or -1 to collide it */
    int *ncontact;          /* per pair: its contacts */
    int *runs;              /* per chunk: pairs to collide (pass 1), then the
                               first run index (pass 2) */
    sc_unit_pair *up;       /* per run: the unit's pair */
    const int *rn;          /* per run: contacts found */
    const sc_contact *rcs;  /* per run: SC_MAX_PAIR_CONTACTS of room */
    const int *start;       /* per pair: its first contact in out (npairs + 1) */
    int *run_at;            /* per pair collided: its run index */
    sc_contact *out;        /* the new contacts */
    sc_contact *memo_c;     /* the memo's next copy of them (raw) */
    const sc_contact *old;  /* the last detection's contacts (warm starts) */
    int nold;
    unsigned char *taken;   /* per old contact */
    double *maxpen;         /* per chunk */
} np_pass;

static int chunk_lo(const np_pass *p, int t)
{
    return (int)((long long)p->npairs * t / p->chunks);
}

/* Pass 1, chunk t: each pair found in the memo or marked to collide. */
static void np_find(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    np_pass *p = arg;
    int lo = chunk_lo(p, t), hi = chunk_lo(p, t + 1), runs = 0;
    if (lo >= hi) {
        p->runs[t] = 0;
        return;
    }
    int cursor = p->use_memo ? memo_lower(p->m, p->pairs[lo]) : 0;
    for (int i = lo; i < hi; i++) {
        int h = p->use_memo ? memo_find(p->m, p->f->poses, p->pairs[i], &cursor) : -1;
        p->hit[i] = h;
        if (h >= 0)
            p->ncontact[i] = p->m->start[h + 1] - p->m->start[h];
        else
            runs++;
    }
    p->runs[t] = runs;
}

/* Pass 2, chunk t: the pairs to collide as the job's unit pairs. */
static void np_units(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    np_pass *p = arg;
    const sc_frame_state *st = p->f->st;
    int r = p->runs[t], held = -1;
    for (int i = chunk_lo(p, t); i < chunk_lo(p, t + 1); i++) {
        if (p->hit[i] >= 0)
            continue;
        sc_unit_pair *u = &p->up[r];
        sc_pair pr = p->pairs[i];
        memset(u, 0, sizeof *u);    /* a1, b1 are the TOI's only */
        u->sa = st->bodies[pr.a].shape;
        u->sb = st->bodies[pr.b].shape;
        u->body_a = pr.a;
        u->body_b = pr.b;
        u->a0 = p->f->poses[pr.a];
        u->b0 = p->f->poses[pr.b];
        /* the contacts still held are those of the last detection; both
         * lists are in pair order, so one cursor walks them */
        u->touching = held_pair(st->contacts, st->ncontacts, pr, &held);
        p->run_at[i] = r++;
    }
}

/* Pass 3, chunk t: the contacts in pair order into out (and, raw, into
 * the memo's next copy), then their warm starts; the deepest. */
static void np_gather(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    np_pass *p = arg;
    int lo = chunk_lo(p, t), hi = chunk_lo(p, t + 1);
    double maxpen = 0;
    for (int i = lo; i < hi; i++) {
        int n = p->ncontact[i];
        if (n == 0)
            continue;
        const sc_contact *from = p->hit[i] >= 0
                                     ? &p->m->c[p->m->start[p->hit[i]]]
                                     : &p->rcs[(size_t)p->run_at[i] * SC_MAX_PAIR_CONTACTS];
        sc_contact *to = &p->out[p->start[i]];
        memcpy(to, from, (size_t)n * sizeof *to);
        for (int k = 0; k < n; k++)
            maxpen = max_d(maxpen, to[k].depth);
    }
    if (lo < hi) {
        int c0 = p->start[lo], n = p->start[hi] - c0;
        if (p->memo_c && n > 0)
            memcpy(&p->memo_c[c0], &p->out[c0], (size_t)n * sizeof *p->out);
        if (p->nold > 0)
            match_impulses(p->f->st, &p->out[c0], n, p->old, p->nold, p->taken);
    }
    p->maxpen[t] = maxpen;
}

/* Two buffers (pointer and capacity) trade places. */
static void trade(void **a, int *acap, void **b, int *bcap)
{
    void *p = *a;
    int cap = *acap;
    *a = *b;
    *acap = *bcap;
    *b = p;
    *bcap = cap;
}

/* Step 4, exact: every pair through the narrow phase as work units on the
 * executor, merged in pair order, so the contact list is canonical. A pair
 * whose poses have not changed since the last detection of this frame (a
 * sleeper's, or an island a speculative re-solve left alone) takes its
 * contacts from the memo instead: the same bits, as the narrow phase reads
 * nothing else. The new list is built in the memo's spare buffer and takes
 * the old list's place, which the warm starts read where it lies. */
static int narrowphase(sc_frame *f, int npairs)
{
    sc_frame_state *st = f->st;
    sc_arena *a = &f->scr->arena;
    sc_np_memo *m = &f->scr->memo;
    const sc_task_runner *runner = f->ex ? f->ex->runner : NULL;
    if (npairs > INT_MAX / SC_MAX_PAIR_CONTACTS - 1)
        return SC_ETOOBIG;
    np_pass p = {
        .f = f,
        .pairs = f->scr->pairs,
        .npairs = npairs,
        .chunks = runner && npairs >= NP_SHARE_MIN ? SC_SHARE_CHUNKS : 1,
        .m = m,
        .use_memo = m->valid && m->nbodies == st->nbodies,
    };
    size_t np = (size_t)npairs, nch = (size_t)p.chunks;
    p.hit = sc_arena_alloc(a, np * sizeof *p.hit);
    p.ncontact = p.hit ? sc_arena_alloc(a, np * sizeof *p.ncontact) : NULL;
    p.run_at = p.ncontact ? sc_arena_alloc(a, np * sizeof *p.run_at) : NULL;
    p.runs = p.run_at ? sc_arena_alloc(a, nch * sizeof *p.runs) : NULL;
    p.maxpen = p.runs ? sc_arena_alloc(a, nch * sizeof *p.maxpen) : NULL;
    /* each pair's first contact, written where the memo takes it next */
    int rc = p.maxpen && !sc_grow((void **)&m->start_next, &m->start_next_cap, npairs + 1,
                                  sizeof *m->start_next, INT_MAX)
                 ? SC_OK
                 : SC_ENOMEM;
    int *start = m->start_next;
    if (rc == SC_OK)
        sc_tasks_run(runner, np_find, &p, p.chunks, NULL);
    int nrun = 0;
    for (int t = 0; rc == SC_OK && t < p.chunks; t++) {
        int r = p.runs[t];
        p.runs[t] = nrun;
        nrun += r;
    }
    size_t nr = (size_t)nrun;
    p.up = rc == SC_OK && nrun ? sc_arena_alloc(a, nr * sizeof *p.up) : NULL;
    int *rn = p.up ? sc_arena_alloc(a, nr * sizeof *rn) : NULL;
    sc_contact *rcs = rn ? sc_arena_alloc(a, nr * SC_MAX_PAIR_CONTACTS * sizeof *rcs) : NULL;
    if (nrun && rc == SC_OK && !rcs)
        rc = SC_ENOMEM;
    if (rc == SC_OK && nrun)
        sc_tasks_run(runner, np_units, &p, p.chunks, NULL);
    if (rc == SC_OK) {
        f->stats->frame.detect.np_pairs += npairs;
        f->stats->frame.detect.np_reused += npairs - nrun;
    }
    sc_job job = {
        .kind = SC_UNIT_COLLIDE,
        .pairs = p.up,
        .npairs = nrun,
        .contacts = rcs,
        .ncontact = rn,
    };
    if (rc == SC_OK && nrun > 0)
        rc = f->ex->run(f->ex, &job, SC_STAGE_NARROWPHASE, f->stats);
    int total = 0;
    for (int i = 0; rc == SC_OK && i < npairs; i++) {
        if (p.hit[i] < 0)
            p.ncontact[i] = rn[p.run_at[i]];
        start[i] = total;
        total += p.ncontact[i];
    }
    if (rc == SC_OK)
        start[npairs] = total;
    /* the new list in the spare buffer; the memo's next copy beside it
     * (without memory the memo is dropped, which only costs time) */
    if (rc == SC_OK && sc_grow((void **)&m->spare, &m->spare_cap, total, sizeof *m->spare,
                               INT_MAX))
        rc = SC_ENOMEM;
    int keep = rc == SC_OK &&
               !sc_grow((void **)&m->c_next, &m->c_next_cap, total, sizeof *m->c_next, INT_MAX);
    unsigned char *taken = NULL;
    if (rc == SC_OK && st->ncontacts > 0) {
        taken = sc_arena_alloc(a, (size_t)st->ncontacts);
        if (taken)
            memset(taken, 0, (size_t)st->ncontacts);
        else
            rc = SC_ENOMEM;
    }
    double maxpen = 0;
    if (rc == SC_OK) {
        p.rn = rn;
        p.rcs = rcs;
        p.start = start;
        p.out = m->spare;
        p.memo_c = keep ? m->c_next : NULL;
        p.old = st->contacts;
        p.nold = st->ncontacts;
        p.taken = taken;
        sc_tasks_run(runner, np_gather, &p, p.chunks, NULL);
        for (int t = 0; t < p.chunks; t++)
            maxpen = max_d(maxpen, p.maxpen[t]);
        /* the new list takes the old one's place, whose buffer is spare */
        trade((void **)&st->contacts, &st->contact_cap, (void **)&m->spare, &m->spare_cap);
        st->ncontacts = total;
    } else {
        st->ncontacts = 0;
    }
    m->valid = 0;
    if (rc == SC_OK && keep &&
        !sc_grow((void **)&m->poses, &m->pose_cap, st->nbodies, sizeof *m->poses, INT_MAX) &&
        !sc_grow((void **)&m->pairs, &m->pair_cap, npairs, sizeof *m->pairs, INT_MAX)) {
        if (st->nbodies > 0)
            memcpy(m->poses, f->poses, (size_t)st->nbodies * sizeof *m->poses);
        if (npairs > 0)
            memcpy(m->pairs, p.pairs, np * sizeof *m->pairs);
        trade((void **)&m->c, &m->c_cap, (void **)&m->c_next, &m->c_next_cap);
        trade((void **)&m->start, &m->start_cap, (void **)&m->start_next, &m->start_next_cap);
        m->nbodies = st->nbodies;
        m->npairs = npairs;
        m->valid = 1;
    }
    sc_arena_free(a, taken);
    sc_arena_free(a, rcs);
    sc_arena_free(a, rn);
    sc_arena_free(a, p.up);
    sc_arena_free(a, p.maxpen);
    sc_arena_free(a, p.runs);
    sc_arena_free(a, p.run_at);
    sc_arena_free(a, p.ncontact);
    sc_arena_free(a, p.hit);
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
