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
#define SPEC_ROUNDS 2         /* speculative re-solves of a substep at most */
#define SPEC_DEPTH 0.25       /* deepest share of the smaller feature a
                                 speculative contact may come from */
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

/* Step 5: the earliest time of impact (fraction of the substep) among the
 * pairs whose contacts are marked 1 in fast (sort_out()), or, fast NULL,
 * among all new contacts deeper than the tolerance; 1 when there is none.
 * One query per pair, as work units; the minimum does not depend on who
 * ran what. */
static int earliest_impact(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                           const unsigned char *fast, double *frac)
{
    const sc_frame_state *st = f->st;
    double t0 = sc_cpu_now();
    *frac = 1;
    int np = 0;
    for (int k = 0; k < st->ncontacts; k++)
        np += fast ? fast[k] == 1 : st->contacts[k].depth > f->cfg->contact_tol_m;
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
        if (fast ? fast[k] != 1 : c->depth <= f->cfg->contact_tol_m)
            continue;
        if (np > 0 && pairs[np - 1].body_a == c->body_a && pairs[np - 1].body_b == c->body_b)
            continue;    /* one query per pair */
        toi_pair(f, saved, c0, n0, c->body_a, c->body_b, &pairs[np++]);
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

/* ---- speculative contacts (local mode; docs/DESIGN.md section 3.4) --- */

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

/* The detection's pairs past the tolerance, sorted out: a pair that got
 * deeper than allowed (a new pair past the tolerance, a touching one past
 * its start depth plus a tenth of it) is slow when its sweep over the
 * substep stays below half its smaller feature (no feature can have been
 * skipped) and its depth below SPEC_DEPTH of it (the contact is where
 * the bodies meet), else fast. Slow pairs' new contacts are appended to
 * spec (transported back to the substep's start, depth = estimated
 * depth there, negative = gap); fast[k] is 1 for a fast pair's contacts,
 * 2 for a slow one's.
 * Returns the number of slow pairs (spec grows) and sets *nfast. */
static int sort_out(sc_frame *f, const sc_body *saved, const sc_contact *c0, int n0,
                    sc_contact **spec, int *nspec, int *spec_cap, unsigned char *fast,
                    int *nfast)
{
    const sc_frame_state *st = f->st;
    double tol = f->cfg->contact_tol_m;
    int nslow = 0;
    *nfast = 0;
    memset(fast, 0, (size_t)st->ncontacts);
    for (int k0 = 0, k1; k0 < st->ncontacts; k0 = k1) {
        const sc_contact *c = &st->contacts[k0];
        int a = c->body_a, b = c->body_b;
        double d1 = 0;
        for (k1 = k0; k1 < st->ncontacts && st->contacts[k1].body_a == a &&
                      st->contacts[k1].body_b == b; k1++)
            d1 = fmax(d1, st->contacts[k1].depth);
        /* the pair at the start: its contacts c0[j0 .. j1), deepest d0 */
        int j0 = sc_contacts_pair_start(c0, n0, a, b), j1 = j0;
        double d0 = -1;
        for (; j1 < n0 && c0[j1].body_a == a && c0[j1].body_b == b; j1++)
            d0 = fmax(d0, c0[j1].depth);
        double limit = d0 < 0 ? tol : fmax(tol, d0 + 0.1 * tol);
        if (!(d1 > limit))
            continue;
        const sc_shape *sa = st->bodies[a].shape, *sb = st->bodies[b].shape;
        sc_pose a0, b0;
        sc_body_pose(&saved[a], &a0);
        sc_body_pose(&saved[b], &b0);
        double feature = fmin(sc_toi_feature(sa), sc_toi_feature(sb));
        double sweep = sc_toi_sweep(sa, &a0, &f->poses[a]) + sc_toi_sweep(sb, &b0, &f->poses[b]);
        if (sweep > 0.5 * feature || d1 > SPEC_DEPTH * feature) {
            for (int k = k0; k < k1; k++)
                fast[k] = 1;
            (*nfast)++;
            continue;
        }
        for (int k = k0; k < k1; k++)
            fast[k] = 2;
        /* slow: its contacts deeper than the slop that no contact of the
         * pair at the start (or already speculative) lies near */
        double ra = sa->bound_r, rb = sb->bound_r;
        double near = 0.1 * fmin(ra, rb);
        int added = 0;
        for (int k = k0; k < k1; k++) {
            const sc_contact *ck = &st->contacts[k];
            if (ck->depth <= limit && d0 >= 0)
                continue;    /* a touching pair: only its new deep points */
            double pa[3], pb[3];
            transport(pa, ck->pos, &f->poses[a], &a0);
            transport(pb, ck->pos, &f->poses[b], &b0);
            sc_contact s = *ck;
            for (int j = 0; j < 3; j++)
                s.pos[j] = 0.5 * (pa[j] + pb[j]);
            /* depth_end = depth_start + (da - db).n, d = displacement */
            double da[3], db[3], dd[3];
            v3_sub(da, ck->pos, pa);
            v3_sub(db, ck->pos, pb);
            v3_sub(dd, da, db);
            s.depth = ck->depth - v3_dot(dd, ck->normal);
            v3_set(s.impulse, 0, 0, 0);
            int dup = 0;
            for (int j = j0; j < j1 && !dup; j++)
                dup = v3_dist(c0[j].pos, s.pos) < near;
            for (int j = 0; j < *nspec && !dup; j++)
                if ((*spec)[j].body_a == a && (*spec)[j].body_b == b &&
                    v3_dist((*spec)[j].pos, s.pos) < near)
                    dup = 1;
            if (dup)
                continue;
            if (sc_grow((void **)spec, spec_cap, *nspec + 1, sizeof **spec, INT_MAX))
                return SC_ENOMEM;
            (*spec)[(*nspec)++] = s;
            added = 1;
        }
        nslow += added;
    }
    return nslow;
}

/* c0 and spec (both sorted by pair) merged into st->contacts, by pair,
 * a pair's start contacts first. */
static int merge_spec(sc_frame_state *st, const sc_contact *c0, int n0, const sc_contact *spec,
                      int ns)
{
    if (sc_grow((void **)&st->contacts, &st->contact_cap, n0 + ns, sizeof *st->contacts,
                INT_MAX))
        return SC_ENOMEM;
    int i = 0, j = 0, k = 0;
    while (i < n0 || j < ns) {
        int take0 = j >= ns || (i < n0 && (c0[i].body_a < spec[j].body_a ||
                                           (c0[i].body_a == spec[j].body_a &&
                                            c0[i].body_b <= spec[j].body_b)));
        st->contacts[k++] = take0 ? c0[i++] : spec[j++];
    }
    st->ncontacts = k;
    return SC_OK;
}

static int cmp_contact_pair(const void *x, const void *y)
{
    const sc_contact *a = x, *b = y;
    if (a->body_a != b->body_a)
        return (a->body_a > b->body_a) - (a->body_a < b->body_a);
    return (a->body_b > b->body_b) - (a->body_b < b->body_b);
}

/* The substeps of a frame, with the frame's arrays in place. */
static int substeps(sc_frame *f, double dt, sc_body *saved, unsigned char *touched)
{
    sc_frame_state *st = f->st;
    sc_arena *a = &f->scr->arena;
    sc_islands *is = &f->scr->islands;
    int n = st->nbodies;
    int local = f->cfg->toi_mode == SC_TOI_LOCAL;
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
    sc_contact *spec = NULL;    /* speculative contacts of this substep */
    int nspec = 0, spec_cap = 0, backups = 0, movable = 0;
    for (int i = 0; i < n; i++)
        movable += st->bodies[i].inv_mass > 0;
    double left = dt;
    for (int sub = 0; rc == SC_OK && left > 0; sub++) {
        /* keep the start of the substep: contacts and state */
        memcpy(saved, st->bodies, (size_t)n * sizeof *saved);
        int n0 = st->ncontacts;
        sc_contact *c0 = sc_arena_alloc(a, (size_t)n0 * sizeof *c0);
        if (!c0) {
            rc = SC_ENOMEM;
            break;
        }
        if (n0 > 0)
            memcpy(c0, st->contacts, (size_t)n0 * sizeof *c0);
        double h = left;
        rc = substep(f, h, is, touched);
        if (rc == SC_OK)
            rc = sc_detect(f);
        nspec = 0;
        int backed = 0, rounds = 0;
        while (rc == SC_OK && local) {
            /* local mode: slow pairs past the tolerance enter the substep
             * again as speculative contacts; fast ones back up */
            unsigned char *fast = sc_arena_alloc(a, (size_t)st->ncontacts + 1);
            if (!fast) {
                rc = SC_ENOMEM;
                break;
            }
            int nfast = 0, nslow = 0;
            if (rounds < SPEC_ROUNDS || (!backed && sub + 1 < MAX_SUBSTEPS))
                nslow = sort_out(f, saved, c0, n0, &spec, &nspec, &spec_cap, fast, &nfast);
            if (nslow < 0) {
                sc_arena_free(a, fast);
                rc = nslow;
                break;
            }
            double frac = 1;
            if (nfast > 0 && !backed && sub + 1 < MAX_SUBSTEPS)
                rc = earliest_impact(f, saved, c0, n0, fast, &frac);
            sc_arena_free(a, fast);
            if (rc != SC_OK)
                break;
            int back = frac < 1;
            if (!back && (nslow == 0 || rounds >= SPEC_ROUNDS))
                break;
            memcpy(st->bodies, saved, (size_t)n * sizeof *saved);
            if (back) {
                /* back up to the fast pairs' first impact; the slow ones
                 * there are found again */
                backed = 1;
                backups++;
                nspec = 0;
                h = fmax(frac * h, 1e-6 * dt);
            }
            if (nspec > 1)
                qsort(spec, (size_t)nspec, sizeof *spec, cmp_contact_pair);
            rc = merge_spec(st, c0, n0, spec, nspec);
            f->stats->spec_contacts += nspec;
            f->stats->spec_rounds += !back;
            rounds += !back;
            if (rc == SC_OK)
                rc = substep(f, h, is, touched);
            if (rc == SC_OK)
                rc = sc_detect(f);
        }
        double frac = 1;
        if (!local && rc == SC_OK && sub + 1 < MAX_SUBSTEPS)
            rc = earliest_impact(f, saved, c0, n0, NULL, &frac);
        if (rc == SC_OK && frac < 1) {
            /* steps 5-6: back up and advance only until they touch */
            memcpy(st->bodies, saved, (size_t)n * sizeof *saved);
            if (n0 > 0)
                memcpy(st->contacts, c0, (size_t)n0 * sizeof *c0);
            st->ncontacts = n0;
            backups++;
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
    free(spec);
    f->stats->backups += backups;
    if (backups > 0) {
        f->stats->backup_regions++;
        f->stats->backup_bodies += movable;
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
