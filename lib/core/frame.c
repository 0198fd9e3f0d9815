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

/* World-wide mode: substeps of a frame (the world's or a motion group's);
 * all but the last may back up. A landing pile backs the whole world up
 * once for every impact, dozens of times a frame for a thousand parts;
 * fewer substeps let the last one's parts in well past the tolerance
 * (docs/DESIGN.md 3.1). */
#define MAX_SUBSTEPS 128
#define SPEC_ROUNDS 4         /* speculative re-solves of a substep at most */
/* Local mode: back-ups of one substep at most, and of a frame (a region's:
 * a motion group steps its own frame). A region's landing can spend 15,
 * and then lets parts in past the tolerance; 31 keeps them near it at the
 * same cost. More a substep would keep piles closer still but drift
 * elastic bodies' energy more (docs/DESIGN.md 3.4). */
#define SPEC_BACKUPS 3
#define MAX_BACKUPS_LOCAL 31
/* split islands: contacts per block (whole pairs: a pair has at most 4) */
#define SPLIT_BLOCK_CONTACTS 4
/* split islands: the symmetric sweeps Anderson's acceleration remembers
 * (docs/DESIGN.md 11) */
#define SPLIT_ANDERSON 3

sc_contact_params sc_frame_contact_params(const sc_frame_config *cfg)
{
    return (sc_contact_params){
        .bounce_speed = SC_BOUNCE_SPEED,
        .slop = 0.5e-3,
        .baumgarte = 0.2,
        .push_tol = cfg->contact_tol_m,
        .split_contacts = cfg->island_split,
        .block_contacts = SPLIT_BLOCK_CONTACTS,
        .tol = SC_SPLIT_TOL,
        .max_sweeps = SC_SPLIT_MAX_SWEEPS,
        .anderson = SPLIT_ANDERSON,
        .island_method = cfg->island_method,
        .impact_first = cfg->toi_mode == SC_TOI_LOCAL,
        .gravity = { cfg->gravity[0], cfg->gravity[1], cfg->gravity[2] },
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
    free(s->plane_pairs);
    free(s->memo.poses);
    free(s->memo.pairs);
    free(s->memo.start);
    free(s->memo.c);
    free(s->memo.start_next);
    free(s->memo.c_next);
    free(s->memo.spare);
    sc_islands_free(&s->islands);
    sc_arena_destroy(&s->arena);
    memset(s, 0, sizeof *s);
}

/* ---- the frame: the paper's steps (3)-(7) ---------------------------- */

/* The islands of is that hold a body marked in mask, into sub (arrays
 * from the arena, freed by sub_islands_free()); returns how many of those
 * left out have contacts (islands kept), or SC_ENOMEM. */
static int sub_islands(sc_arena *a, const sc_islands *is, const unsigned char *mask,
                       sc_islands *sub)
{
    memset(sub, 0, sizeof *sub);
    size_t nb = (size_t)is->body_start[is->count], nc = (size_t)is->contact_start[is->count];
    sub->body_start = sc_arena_alloc(a, ((size_t)is->count + 1) * sizeof(int));
    sub->contact_start = sub->body_start ? sc_arena_alloc(a, ((size_t)is->count + 1) * sizeof(int))
                                         : NULL;
    sub->bodies = sub->contact_start ? sc_arena_alloc(a, (nb + 1) * sizeof(int)) : NULL;
    sub->contacts = sub->bodies ? sc_arena_alloc(a, (nc + 1) * sizeof(int)) : NULL;
    if (!sub->contacts)
        return SC_ENOMEM;
    int m = 0, kb = 0, kc = 0, kept = 0;
    for (int i = 0; i < is->count; i++) {
        if (!mask[is->bodies[is->body_start[i]]]) {
            /* an island is marked whole or not at all */
            kept += is->contact_start[i + 1] > is->contact_start[i];
            continue;
        }
        sub->body_start[m] = kb;
        sub->contact_start[m] = kc;
        for (int j = is->body_start[i]; j < is->body_start[i + 1]; j++)
            sub->bodies[kb++] = is->bodies[j];
        for (int j = is->contact_start[i]; j < is->contact_start[i + 1]; j++)
            sub->contacts[kc++] = is->contacts[j];
        m++;
    }
    sub->body_start[m] = kb;
    sub->contact_start[m] = kc;
    sub->count = m;
    return kept;
}

static void sub_islands_free(sc_arena *a, sc_islands *sub)
{
    sc_arena_free(a, sub->contacts);
    sc_arena_free(a, sub->bodies);
    sc_arena_free(a, sub->contact_start);
    sc_arena_free(a, sub->body_start);
}

/* What a speculative round solves again (frame.c's loop): the bodies at
 * the substep's start, and those the round's new speculative contacts
 * hold. Islands without one of them have the contacts and start they had
 * in the last solve of this substep, over the same h: their bodies keep
 * its result, the same bits a solve again would give. */
typedef struct redo {
    const sc_body *saved;
    const unsigned char *dirty;
    const sc_contact *old;          /* the last solve's contacts, impulses */
    int nold;
} redo;

static int same_contact(const sc_contact *x, const sc_contact *y)
{
    return x->body_a == y->body_a && x->body_b == y->body_b &&
           !memcmp(x->pos, y->pos, sizeof x->pos) &&
           !memcmp(x->normal, y->normal, sizeof x->normal) &&
           !memcmp(&x->depth, &y->depth, sizeof x->depth);
}

/* The place of contact c in old[0 .. nold) (sorted by pair): the same
 * contact, whose impulse that solve found; -1 if none. *at: where c's
 * pair starts in old, or -1 to search for it; contacts asked in pair
 * order walk old once. */
static int find_same(const sc_contact *old, int nold, const sc_contact *c, int *at)
{
    int o = sc_contacts_pair_walk(old, nold, c->body_a, c->body_b, at);
    while (o < nold && old[o].body_a == c->body_a && old[o].body_b == c->body_b &&
           !same_contact(&old[o], c))
        o++;
    return o < nold && same_contact(&old[o], c) ? o : -1;
}

/* For each contact of an island kept (not in mask), its place in the last
 * solve's contacts (from[k]; -1 for the others): the same contact, whose
 * impulse that solve found. 0 if one is missing (then all are solved).
 * The kept contacts are marked first, then found in pair order. */
static int kept_impulses(const sc_frame_state *st, const sc_islands *is,
                         const unsigned char *mask, const redo *rd, int *from)
{
    for (int k = 0; k < st->ncontacts; k++)
        from[k] = -1;
    for (int i = 0; i < is->count; i++) {
        if (mask[is->bodies[is->body_start[i]]])
            continue;
        for (int j = is->contact_start[i]; j < is->contact_start[i + 1]; j++)
            from[is->contacts[j]] = -2;
    }
    int at = -1;
    for (int k = 0; k < st->ncontacts; k++) {
        if (from[k] != -2)
            continue;
        from[k] = find_same(rd->old, rd->nold, &st->contacts[k], &at);
        if (from[k] < 0)
            return 0;
    }
    return 1;
}

void sc_track_copy(sc_track *to, int i, const sc_track *from, int j)
{
    to->dev[i] = from->dev[j];
    to->adev[i] = from->adev[j];
    to->count[i] = from->count[j];
    if (from->count[j] > 0)
        memcpy(&to->pt[(size_t)i * SC_TRACK_MAX * SC_TRACK_STRIDE],
               &from->pt[(size_t)j * SC_TRACK_MAX * SC_TRACK_STRIDE],
               (size_t)from->count[j] * SC_TRACK_STRIDE * sizeof *to->pt);
}

int sc_track_reserve(sc_track *t, int *cap, int n)
{
    if (n <= *cap)
        return SC_OK;
    sc_track_free(t);
    *cap = 0;
    size_t N = (size_t)n;
    t->dev = sc_calloc_array(N, sizeof *t->dev);
    t->adev = sc_calloc_array(N, sizeof *t->adev);
    t->count = sc_calloc_array(N, sizeof *t->count);
    t->pt = sc_alloc_array(N, SC_TRACK_MAX * SC_TRACK_STRIDE * sizeof *t->pt);
    if (!t->dev || !t->adev || !t->count || !t->pt) {
        sc_track_free(t);
        return SC_ENOMEM;
    }
    *cap = n;
    return SC_OK;
}

void sc_track_free(sc_track *t)
{
    free(t->dev);
    free(t->adev);
    free(t->count);
    free(t->pt);
    memset(t, 0, sizeof *t);
}

/* Body i's track (st->track) gets its shape's pose at time t of the frame
 * as a point; past SC_TRACK_MAX points it keeps none (count beyond). */
static void track_point(const sc_frame *f, int i, double t)
{
    sc_track *tr = f->st->track;
    int k = tr->count[i];
    if (k < SC_TRACK_MAX) {
        sc_pose p;
        sc_body_pose(&f->st->bodies[i], &p);
        double *q = &tr->pt[((size_t)i * SC_TRACK_MAX + (size_t)k) * SC_TRACK_STRIDE];
        q[0] = t;
        v3_copy(q + 1, p.pos);
        memcpy(q + 4, p.quat, 4 * sizeof *q);
    }
    tr->count[i] = k + (k <= SC_TRACK_MAX);
}

/* Body i's track distance (st->track->dev) grown to its shape origin's
 * distance at the end t of a substep of h from its drift
 * (sc_body_drift()), plus how far the drift's parabola leaves its chord
 * over h (|a| h^2 / 8): between substep ends the frame moves a shape origin
 * along the chord (the time of impact's poses, toi.c), so the whole path
 * stays within that distance of the drift. Its angle (adev) grown to the
 * turn between its orientation and its spin's (sc_spin_at()) there. Every
 * substep counts, those a back-up undoes too (a bound only). */
static void track_dev(const sc_frame *f, int i, double t, double h)
{
    const sc_body *b = &f->st->bodies[i];
    const double *d = &f->drift[9 * i], *sp = &f->spin[7 * i];
    sc_pose p;
    sc_body_pose(b, &p);
    double at[3], q[4];
    sc_drift_at(d, t, at);
    double dev = v3_dist(p.pos, at) + v3_len(d + 6) * h * h / 8;
    f->st->track->dev[i] = max_d(f->st->track->dev[i], dev);
    sc_spin_at(sp, sp + 4, t, q);
    f->st->track->adev[i] = max_d(f->st->track->adev[i], q_angle_between(q, b->q));
}

/* The per-body work at a substep's end, in SC_SHARE_CHUNKS tasks of the
 * frame's runner from SC_SHARE_MIN bodies on (each body's outputs are its
 * own, so the same bits whoever runs which): after the solve, every
 * movable body checked finite and its track distance grown (end 0); after
 * the substep, its track point (end 1). */
typedef struct end_pass {
    const sc_frame *f;
    int end;
    double t, h;
    int chunks;
    unsigned char bad[SC_SHARE_CHUNKS];
} end_pass;

static void end_task(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    end_pass *p = arg;
    const sc_frame_state *st = p->f->st;
    long long n = st->nbodies;
    int i1 = (int)(n * (t + 1) / p->chunks);
    p->bad[t] = 0;
    for (int i = (int)(n * t / p->chunks); i < i1; i++) {
        const sc_body *b = &st->bodies[i];
        if (p->end == 1) {
            if (b->inv_mass > 0)
                track_point(p->f, i, p->t);
            continue;
        }
        if (sc_body_movable(b) && (!sc_finite3(b->x) || !sc_finite3(b->v) || !sc_finite3(b->w)))
            p->bad[t] = 1;
        else if (st->track && b->inv_mass > 0)
            track_dev(p->f, i, p->t, p->h);
    }
}

/* end_task() over the bodies; SC_ENUMERIC if a body is not finite. */
static int bodies_end(const sc_frame *f, int end, double t, double h)
{
    const sc_task_runner *r = f->ex ? f->ex->runner : NULL;
    end_pass p = { .f = f, .end = end, .t = t, .h = h,
                   .chunks = r && f->st->nbodies >= SC_SHARE_MIN ? SC_SHARE_CHUNKS : 1 };
    sc_tasks_run(r, end_task, &p, p.chunks, NULL);
    for (int k = 0; k < p.chunks; k++)
        if (p.bad[k])
            return SC_ENUMERIC;
    return SC_OK;
}

/* Steps (4)-(7) once over h: islands, contact impulses, positions; with
 * rd, only the islands that hold a dirty body, the others' bodies kept. */
static int substep(sc_frame *f, double h, sc_islands *is, unsigned char *touched,
                   const redo *rd)
{
    sc_frame_state *st = f->st;
    sc_arena *a = &f->scr->arena;
    int n = st->nbodies;
    if (!rd)
        sc_apply_forces(f, h, NULL);
    double t0 = sc_stage_now(f);
    for (int i = 0; i < n; i++)
        f->active[i] = sc_body_movable(rd ? &rd->saved[i] : &st->bodies[i]);
    int rc = sc_islands_build(a, n, f->active, st->contacts, st->ncontacts, is);
    sc_stage_since(f, SC_STAGE_ISLANDS, t0);
    if (rc != SC_OK)
        return rc;
    unsigned char *mask = NULL;
    sc_islands sub;
    const sc_islands *solve = is;
    if (rd) {
        /* the islands of the dirty bodies are solved again from the start;
         * the other bodies keep the last solve's result (a body that was
         * not movable then is as it started: detection may have woken it
         * since) */
        mask = sc_arena_alloc(a, (size_t)n);
        if (!mask)
            return SC_ENOMEM;
        memcpy(mask, rd->dirty, (size_t)n);
        for (int i = 0; i < is->count; i++) {
            int any = 0;
            for (int j = is->body_start[i]; j < is->body_start[i + 1] && !any; j++)
                any = mask[is->bodies[j]];
            for (int j = is->body_start[i]; any && j < is->body_start[i + 1]; j++)
                mask[is->bodies[j]] = 1;
        }
        /* the kept islands' contacts take the impulses that solve found
         * (the next detection's warm starts) */
        int *from = sc_arena_alloc(a, ((size_t)st->ncontacts + 1) * sizeof *from);
        if (!from) {
            sc_arena_free(a, mask);
            return SC_ENOMEM;
        }
        if (kept_impulses(st, is, mask, rd, from)) {
            for (int k = 0; k < st->ncontacts; k++)
                if (from[k] >= 0)
                    sc_impulse_copy(&st->contacts[k], &rd->old[from[k]]);
        } else {
            memset(mask, 1, (size_t)n);
        }
        sc_arena_free(a, from);
        for (int i = 0; i < n; i++)
            if (mask[i] || !sc_body_movable(&rd->saved[i]))
                st->bodies[i] = rd->saved[i];
        sc_apply_forces(f, h, mask);
        int kept = sub_islands(a, is, mask, &sub);
        if (kept < 0) {
            sub_islands_free(a, &sub);
            sc_arena_free(a, mask);
            return kept;
        }
        solve = &sub;
        f->stats->frame.lcp.kept += kept;
    }
    memset(touched, 0, (size_t)n);
    for (int k = 0; k < st->ncontacts; k++) {
        touched[st->contacts[k].body_a] = 1;
        touched[st->contacts[k].body_b] = 1;
    }
    /* step 7: one work unit per island (islands share no movable body) */
    t0 = sc_stage_now(f);
    sc_contact_params params = sc_frame_contact_params(f->cfg);
    sc_job job = {
        .kind = SC_UNIT_ISLAND,
        .bodies = st->bodies,
        .c = st->contacts,
        .islands = solve,
        .h = h,
        .params = &params,
    };
    rc = solve->count > 0 ? f->ex->run(f->ex, &job, SC_STAGE_LCP, f->stats) : SC_OK;
    sc_stage_since(f, SC_STAGE_LCP, t0);
    f->stats->frame.detect.islands = is->count;
    if (rc == SC_OK) {
        t0 = sc_stage_now(f);
        sc_integrate_positions(f, h, mask);
        sc_stage_since(f, SC_STAGE_INTEGRATE, t0);
    }
    if (rd) {
        sub_islands_free(a, &sub);
        sc_arena_free(a, mask);
    }
    if (rc != SC_OK)
        return rc;
    return bodies_end(f, 0, f->t + h, h);
}

/* The contacts a solve ended with, impulses included, into keep. */
static int keep_solved(const sc_frame_state *st, sc_spec_list *keep)
{
    if (sc_grow((void **)&keep->c, &keep->cap, st->ncontacts, sizeof *keep->c, INT_MAX))
        return SC_ENOMEM;
    if (st->ncontacts > 0)
        memcpy(keep->c, st->contacts, (size_t)st->ncontacts * sizeof *keep->c);
    keep->n = st->ncontacts;
    return SC_OK;
}

/* A substep backed up is solved again, shorter, on the contacts it
 * started with and its speculative ones (c[0 .. n)): each takes the
 * impulse the last solve found for it (old) as its warm start, where it
 * had only its detection's match. A back-up for one part's impact leaves
 * the rest of a pile's impulses nearly as they were, so its islands start
 * near their answers (fewer pivots and sweeps); the answers are verified
 * as any other (docs/DESIGN.md 11, warm starts). Every later solve of the
 * substep starts from them, kept islands or not (the same bits). */
static void warm_from_solved(sc_contact *c, int n, const sc_spec_list *old)
{
    int at = -1;
    for (int k = 0; k < n; k++) {
        int o = find_same(old->c, old->n, &c[k], &at);
        if (o >= 0)
            sc_impulse_copy(&c[k], &old->c[o]);
    }
}

/* The substeps of a frame, with the frame's arrays in place. */
/* A frame's first detection after bodies were added: pairs already deep in
 * each other are counted (the push-out separates them, but not as physics
 * would). */
static int detect_initial(sc_frame *f)
{
    const sc_frame_state *st = f->st;
    int rc = sc_detect(f);
    int la = -1, lb = -1;    /* the last pair counted (contacts sorted by pair) */
    for (int k = 0; rc == SC_OK && k < st->ncontacts; k++) {
        const sc_contact *c = &st->contacts[k];
        if (c->depth > 2 * f->cfg->contact_tol_m && (c->body_a != la || c->body_b != lb)) {
            f->stats->total.initial_overlaps++;
            la = c->body_a;
            lb = c->body_b;
        }
    }
    return rc;
}

/* What one substep's time-of-impact handling works on: its start (the
 * bodies and contacts, kept before it was solved) and its length. */
typedef struct sub_state {
    sc_body *saved;           /* the bodies at the substep's start */
    sc_contact *c0;           /* its contacts (their impulses: warm starts) */
    int n0;
    double h;                 /* its length, shortened by back-ups */
    double dt;                /* the frame's */
    int backups;              /* the frame's back-ups so far */
    unsigned char *touched;
    sc_spec_list *spec;       /* speculative contacts of this substep */
    sc_spec_list *solved;     /* the contacts of its last solve */
} sub_state;

/* The local mode (docs/DESIGN.md 3.4), after a substep's solve and
 * detection: pairs past the tolerance enter the substep again as
 * speculative contacts (slow ones from where they ended, fast ones from
 * where they first touched), up to SPEC_ROUNDS rounds; what nothing holds
 * backs the region up, SPEC_BACKUPS times a substep at most. */
static int local_rounds(sc_frame *f, sub_state *u)
{
    sc_frame_state *st = f->st;
    sc_arena *a = &f->scr->arena;
    int n = st->nbodies, rc = SC_OK;
    int rounds = 0, sub_backups = 0;
    int solved_spec = 0;    /* speculative contacts the last solve had */
    u->spec->n = 0;
    for (;;) {
        unsigned char *fast = sc_arena_alloc(a, (size_t)st->ncontacts + 1);
        if (!fast)
            return SC_ENOMEM;
        /* a substep backed up may back up again (its speculative
         * contacts change the motion), SPEC_BACKUPS times at most:
         * every back-up counts against MAX_BACKUPS_LOCAL, and
         * a pair pushed in by another's push-out is as deep after any
         * substep, however short, so backing up again only spends the
         * frame's back-ups; once backed up, pairs too far to hold at
         * their touch are held where they ended (waiting for the last
         * back-up instead gains elastic bodies energy); perfectly
         * elastic collisions back up past SPEC_BACKUPS, while the frame
         * has back-ups left (held, one is solved with the others of the
         * substep at once, and the box of elastic balls loses energy) */
        int nfast = 0, nslow = 0;
        f->backups = u->backups;
        int can_back = u->backups < MAX_BACKUPS_LOCAL && sub_backups < SPEC_BACKUPS;
        int el_back = u->backups < MAX_BACKUPS_LOCAL;
        if (rounds < SPEC_ROUNDS || can_back)
            nslow = sc_spec_sort_out(f, u->saved, u->c0, u->n0, u->h, u->spec, fast, &nfast);
        if (nslow >= 0 && nfast > 0 && rounds < SPEC_ROUNDS) {
            int hold = sub_backups > 0 ? SC_HOLD_FAR | (el_back ? 0 : SC_HOLD_ELASTIC) : 0;
            int nt = sc_spec_touch(f, u->saved, u->c0, u->n0, u->h, u->spec, fast, &nfast, hold);
            nslow = nt < 0 ? nt : nslow + nt;
        }
        if (nslow < 0) {
            sc_arena_free(a, fast);
            return nslow;
        }
        double frac = 1;
        if (nfast > 0 && (can_back || (el_back && sc_spec_fast_elastic(f, u->saved, fast))))
            rc = sc_frame_earliest_impact(f, u->saved, u->c0, u->n0, fast, &frac);
        sc_arena_free(a, fast);
        if (rc != SC_OK)
            return rc;
        int back = frac < 1;
        if (!back && (nslow == 0 || rounds >= SPEC_ROUNDS))
            return SC_OK;
        /* a sleeper that a speculative contact holds against an awake
         * body wakes for the re-solve, as detection wakes one touched
         * (else it would stay immovable, and the other body might
         * come to rest on it at a gap, never touching it) */
        sc_wake_touched(u->saved, u->spec->c, u->spec->n);
        /* a round at the same h: only the islands the new speculative
         * contacts reach are solved again (substep(), redo) */
        int part = !back && !f->cfg->redo_all;
        unsigned char *dirty = part ? sc_arena_alloc(a, (size_t)n) : NULL;
        if (part && !dirty)
            return SC_ENOMEM;
        if (dirty) {
            memset(dirty, 0, (size_t)n);
            for (int k = solved_spec; k < u->spec->n; k++) {
                dirty[u->spec->c[k].body_a] = 1;
                dirty[u->spec->c[k].body_b] = 1;
            }
        } else {
            memcpy(st->bodies, u->saved, (size_t)n * sizeof *u->saved);
        }
        if (back) {
            /* back up to the first impact of the pairs nothing holds;
             * the speculative contacts stay (their gaps are at the
             * substep's start, which does not move) */
            u->backups++;
            sub_backups++;
            u->h = max_d(frac * u->h, 1e-6 * u->dt);
        }
        if (back) {
            warm_from_solved(u->c0, u->n0, u->solved);
            warm_from_solved(u->spec->c, u->spec->n, u->solved);
        }
        rc = sc_spec_merge(st, u->c0, u->n0, u->spec);
        solved_spec = u->spec->n;
        f->stats->frame.toi.spec_contacts += u->spec->n;
        f->stats->frame.toi.spec_rounds += !back;
        rounds += !back;
        redo rd = { .saved = u->saved, .dirty = dirty, .old = u->solved->c,
                    .nold = u->solved->n };
        if (rc == SC_OK)
            rc = substep(f, u->h, &f->scr->islands, u->touched, dirty ? &rd : NULL);
        sc_arena_free(a, dirty);
        if (rc == SC_OK)
            rc = keep_solved(st, u->solved);
        if (rc == SC_OK)
            rc = sc_detect(f);
        if (rc != SC_OK)
            return rc;
    }
}

/* The world-wide mode (the paper's steps 5-6), after a substep's solve
 * and detection: the earliest impact of any pair past the tolerance backs
 * the whole world (or motion group) up, and it advances only until they
 * touch; the last substep of a frame takes the rest whole. */
static int world_backup(sc_frame *f, sub_state *u, int sub)
{
    sc_frame_state *st = f->st;
    double frac = 1;
    int rc = SC_OK;
    if (sub + 1 < MAX_SUBSTEPS)
        rc = sc_frame_earliest_impact(f, u->saved, u->c0, u->n0, NULL, &frac);
    if (rc != SC_OK || !(frac < 1))
        return rc;
    memcpy(st->bodies, u->saved, (size_t)st->nbodies * sizeof *u->saved);
    if (u->n0 > 0)
        memcpy(st->contacts, u->c0, (size_t)u->n0 * sizeof *u->c0);
    st->ncontacts = u->n0;
    u->backups++;
    u->h = max_d(frac * u->h, 1e-6 * u->dt);
    rc = substep(f, u->h, &f->scr->islands, u->touched, NULL);
    return rc == SC_OK ? sc_detect(f) : rc;
}

/* The substeps of a frame, with the frame's arrays in place. */
static int substeps(sc_frame *f, double dt, sc_body *saved, unsigned char *touched)
{
    sc_frame_state *st = f->st;
    sc_arena *a = &f->scr->arena;
    int n = st->nbodies;
    int local = f->cfg->toi_mode == SC_TOI_LOCAL;
    int rc = st->contacts_valid ? SC_OK : detect_initial(f);
    sc_spec_list spec = { 0 }, solved = { 0 };
    sub_state u = { .saved = saved, .dt = dt, .touched = touched, .spec = &spec,
                    .solved = &solved };
    int movable = 0;
    for (int i = 0; i < n; i++)
        movable += st->bodies[i].inv_mass > 0;
    double left = dt;
    for (int sub = 0; rc == SC_OK && left > 0; sub++) {
        f->t = dt - left;
        /* keep the start of the substep: contacts and state */
        memcpy(saved, st->bodies, (size_t)n * sizeof *saved);
        u.n0 = st->ncontacts;
        sc_contact *c0 = sc_arena_alloc(a, (size_t)u.n0 * sizeof *c0);
        if (!c0) {
            rc = SC_ENOMEM;
            break;
        }
        if (u.n0 > 0)
            memcpy(c0, st->contacts, (size_t)u.n0 * sizeof *c0);
        u.c0 = c0;
        u.h = left;
        rc = substep(f, u.h, &f->scr->islands, touched, NULL);
        if (rc == SC_OK && local)
            rc = keep_solved(st, &solved);
        if (rc == SC_OK)
            rc = sc_detect(f);
        if (rc == SC_OK)
            rc = local ? local_rounds(f, &u) : world_backup(f, &u, sub);
        sc_arena_free(a, c0);
        f->stats->frame.toi.substeps++;
        left -= u.h;
        if (left < 1e-9 * dt)
            left = 0;
        if (st->track && rc == SC_OK)
            bodies_end(f, 1, dt - left, 0);
    }
    free(spec.c);
    free(solved.c);
    f->stats->frame.toi.backups += u.backups;
    if (u.backups > 0) {
        f->stats->frame.toi.backup_regions++;
        f->stats->frame.toi.backup_bodies += movable;
    }
    if (rc == SC_OK)
        sc_update_states(f, &f->scr->islands, touched, dt);
    return rc;
}

int sc_frame_step(const sc_frame_config *cfg, sc_frame_state *st, double dt,
                  sc_frame_scratch *scr, sc_exec *ex, sc_stats *stats)
{
    int n = st->nbodies;
    if (n == 0)
        return SC_OK;
    sc_arena *a = &scr->arena;
    sc_frame f = { .cfg = cfg, .st = st, .scr = scr, .ex = ex, .stats = stats, .dt = dt };
    scr->memo.valid = 0;    /* the last frame's (or another group's) bodies */
    sc_bp_list_drop(scr->bp);
    /* the frame's arrays, last in first out */
    sc_track *tr = st->track;
    if (tr) {
        /* empty first: a frame that fails leaves no stale points */
        memset(tr->dev, 0, (size_t)n * sizeof *tr->dev);
        memset(tr->adev, 0, (size_t)n * sizeof *tr->adev);
        memset(tr->count, 0, (size_t)n * sizeof *tr->count);
        if (!(f.drift = sc_arena_alloc(a, (size_t)n * 9 * sizeof *f.drift)))
            return SC_ENOMEM;
        if (!(f.spin = sc_arena_alloc(a, (size_t)n * 7 * sizeof *f.spin))) {
            sc_arena_free(a, f.drift);
            return SC_ENOMEM;
        }
        for (int i = 0; i < n; i++) {
            if (st->bodies[i].inv_mass > 0) {
                sc_body_drift(cfg, &st->bodies[i], &f.drift[9 * i]);
                double *sp = f.spin + 7 * (size_t)i;
                memcpy(sp, st->bodies[i].q, 4 * sizeof *sp);
                memcpy(sp + 4, st->bodies[i].w, 3 * sizeof *sp);
                track_point(&f, i, 0);
            }
        }
    }
    sc_body *saved = sc_arena_alloc(a, (size_t)n * sizeof *saved);
    unsigned char *touched = sc_arena_alloc(a, (size_t)n);
    f.centre = sc_arena_alloc(a, (size_t)n * 3 * sizeof *f.centre);
    f.radius = sc_arena_alloc(a, (size_t)n * sizeof *f.radius);
    f.skin = sc_arena_alloc(a, (size_t)n * sizeof *f.skin);
    f.active = sc_arena_alloc(a, (size_t)n);
    f.poses = sc_arena_alloc(a, (size_t)n * sizeof *f.poses);
    int rc = saved && touched && f.centre && f.radius && f.skin && f.active && f.poses
                 ? substeps(&f, dt, saved, touched)
                 : SC_ENOMEM;
    sc_arena_free(a, f.poses);
    sc_arena_free(a, f.active);
    sc_arena_free(a, f.skin);
    sc_arena_free(a, f.radius);
    sc_arena_free(a, f.centre);
    sc_arena_free(a, touched);
    sc_arena_free(a, saved);
    sc_arena_free(a, f.spin);
    sc_arena_free(a, f.drift);
    if (a->high > stats->total.arena_bytes)
        stats->total.arena_bytes = a->high;
    if (rc != SC_OK)
        return rc;
    /* a body near its drift is checked by it; one with too many points
     * by its distance from it */
    for (int i = 0; tr && i < n; i++)
        if (tr->dev[i] <= SC_TRACK_DEV || tr->count[i] > SC_TRACK_MAX)
            tr->count[i] = 0;
    for (int i = 0; i < n; i++) {
        v3_set(st->bodies[i].force, 0, 0, 0);
        v3_set(st->bodies[i].torque, 0, 0, 0);
    }
    st->contacts_valid = 1;
    return SC_OK;
}
