/* frame.c - one frame as a value (the paper's steps 3-7; docs/DESIGN.md
 * section 3): substeps of force, contact impulses and integration, each
 * checked for contacts that got deeper than the tolerance and backed up to
 * their time of impact (steps 5-6). It reads and writes only the state it
 * is given; its jobs go to the executor it is given. */
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

#define MAX_SUBSTEPS 16       /* time-of-impact back-ups per frame */
#define SPEC_ROUNDS 4         /* speculative re-solves of a substep at most */
/* Local mode: back-ups of one substep at most, and of a frame (a region's:
 * a motion group steps its own frame). With 15 a frame, as the world-wide
 * mode has, the 1000-part bin's landing spent them all and let a part in
 * 4.6 mm (31: 1.07 mm), and the 200-part bin's seed 10 1.39 mm (31: 1.00
 * mm), at the same cost. 6 a substep would keep seeds 7, 9 and 15 at 1.00
 * mm too (3: 1.01-1.09 mm) but drifts the elastic boxes of bench_energy
 * more (docs/DESIGN.md 3.4). */
#define SPEC_BACKUPS 3
#define MAX_BACKUPS_LOCAL 31
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
        .impact_first = cfg->toi_mode == SC_TOI_LOCAL,
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
    double t0 = sc_stage_now(f);
    for (int i = 0; i < n; i++)
        f->active[i] = sc_body_movable(&st->bodies[i]);
    int rc = sc_islands_build(&f->scr->arena, n, f->active, st->contacts, st->ncontacts, is);
    sc_stage_since(f, SC_STAGE_ISLANDS, t0);
    if (rc != SC_OK)
        return rc;
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
        .islands = is,
        .h = h,
        .params = &params,
    };
    rc = f->ex->run(f->ex, &job, SC_STAGE_LCP, f->stats);
    sc_stage_since(f, SC_STAGE_LCP, t0);
    f->stats->islands = is->count;
    if (rc != SC_OK)
        return rc;
    t0 = sc_stage_now(f);
    sc_integrate_positions(f, h);
    sc_stage_since(f, SC_STAGE_INTEGRATE, t0);
    for (int i = 0; i < n; i++) {
        sc_body *b = &st->bodies[i];
        if (sc_body_movable(b) && (!sc_finite3(b->x) || !sc_finite3(b->v) || !sc_finite3(b->w)))
            return SC_ENUMERIC;
    }
    return SC_OK;
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
    sc_spec_list spec = { 0 };    /* speculative contacts of this substep */
    int backups = 0, movable = 0;
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
        spec.n = 0;
        int rounds = 0, sub_backups = 0;
        while (rc == SC_OK && local) {
            /* local mode: pairs past the tolerance enter the substep again
             * as speculative contacts (slow ones from where they ended,
             * fast ones from where they first touched); what is left backs
             * up */
            unsigned char *fast = sc_arena_alloc(a, (size_t)st->ncontacts + 1);
            if (!fast) {
                rc = SC_ENOMEM;
                break;
            }
            /* a substep backed up may back up again (its speculative
             * contacts change the motion), SPEC_BACKUPS times at most:
             * every back-up counts against the frame's MAX_SUBSTEPS, and
             * a pair pushed in by another's push-out is as deep after any
             * substep, however short (a bin backed up 15 times to 1e-8 s
             * and let a part in 12 mm); once backed up, pairs too far to
             * hold at their touch are held where they ended (waiting for
             * the last back-up instead gained the Table 1 box 0.1 %) */
            int nfast = 0, nslow = 0;
            int can_back = backups < MAX_BACKUPS_LOCAL && sub_backups < SPEC_BACKUPS;
            if (rounds < SPEC_ROUNDS || can_back)
                nslow = sc_spec_sort_out(f, saved, c0, n0, h, &spec, fast, &nfast);
            if (nslow >= 0 && nfast > 0 && rounds < SPEC_ROUNDS) {
                int nt = sc_spec_touch(f, saved, c0, n0, h, &spec, fast, &nfast, sub_backups > 0);
                nslow = nt < 0 ? nt : nslow + nt;
            }
            if (nslow < 0) {
                sc_arena_free(a, fast);
                rc = nslow;
                break;
            }
            double frac = 1;
            if (nfast > 0 && can_back)
                rc = sc_frame_earliest_impact(f, saved, c0, n0, fast, &frac);
            sc_arena_free(a, fast);
            if (rc != SC_OK)
                break;
            int back = frac < 1;
            if (!back && (nslow == 0 || rounds >= SPEC_ROUNDS))
                break;
            /* a sleeper that a speculative contact holds against an awake
             * body wakes for the re-solve, as detection wakes one touched
             * (else it would stay immovable, and the other body might
             * come to rest on it at a gap, never touching it) */
            sc_wake_touched(saved, spec.c, spec.n);
            memcpy(st->bodies, saved, (size_t)n * sizeof *saved);
            if (back) {
                /* back up to the first impact of the pairs nothing holds;
                 * the speculative contacts stay (their gaps are at the
                 * substep's start, which does not move) */
                backups++;
                sub_backups++;
                h = max_d(frac * h, 1e-6 * dt);
            }
            rc = sc_spec_merge(st, c0, n0, &spec);
            f->stats->spec_contacts += spec.n;
            f->stats->spec_rounds += !back;
            rounds += !back;
            if (rc == SC_OK)
                rc = substep(f, h, is, touched);
            if (rc == SC_OK)
                rc = sc_detect(f);
        }
        double frac = 1;
        if (!local && rc == SC_OK && sub + 1 < MAX_SUBSTEPS)
            rc = sc_frame_earliest_impact(f, saved, c0, n0, NULL, &frac);
        if (rc == SC_OK && frac < 1) {
            /* steps 5-6: back up and advance only until they touch */
            memcpy(st->bodies, saved, (size_t)n * sizeof *saved);
            if (n0 > 0)
                memcpy(st->contacts, c0, (size_t)n0 * sizeof *c0);
            st->ncontacts = n0;
            backups++;
            h = max_d(frac * h, 1e-6 * dt);
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
    free(spec.c);
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
    scr->memo.valid = 0;    /* the last frame's (or another group's) bodies */
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
