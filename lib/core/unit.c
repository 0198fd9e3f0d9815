/* unit.c - running one work unit (docs/DESIGN.md section 5): a batch of
 * body pairs through the narrow phase or the time-of-impact search, or one
 * island through the contact LCP. A unit reads its job's inputs and writes
 * only its own outputs (its pairs' slots, its island's bodies). */
#include "frame.h"

/* The wire form's parts (lib/net/unit_wire.c), in bytes: a header; a
 * COLLIDE pair (hashes, ids, two poses) and its contacts back; a TOI pair
 * (four poses) and its time back; an island's body (state, mass
 * properties) both ways; a contact (88 out with its warm start, 24 back);
 * a group unit's settings and headers, a static body or body constants,
 * a group's counts and figures, a member's state both ways with its
 * track, a contact each way. */
#define WIRE_HEADER 32
#define WIRE_PAIR 128
#define WIRE_TOI_PAIR 240
#define WIRE_BODY 400
#define WIRE_CONTACT 112
#define WIRE_GROUP_HEADER 300
#define WIRE_GROUP_BODY 496
#define WIRE_GROUP_PROFILES 4   /* body constants a group unit is taken to carry */
#define WIRE_GROUP_EACH 100
#define WIRE_GROUP_MEMBER 250
#define WIRE_GROUP_CONTACT 88

size_t sc_unit_bytes_pairs(int kind, int count)
{
    return WIRE_HEADER + (kind == SC_UNIT_TOI ? WIRE_TOI_PAIR : WIRE_PAIR) * (size_t)count;
}

size_t sc_unit_bytes_islands(int bodies, int contacts)
{
    return WIRE_HEADER + WIRE_BODY * (size_t)bodies + WIRE_CONTACT * (size_t)contacts;
}

size_t sc_unit_bytes_groups(int statics, int groups, int members, int contacts)
{
    int profiles = members < WIRE_GROUP_PROFILES ? members : WIRE_GROUP_PROFILES;
    return WIRE_GROUP_HEADER + WIRE_GROUP_BODY * (size_t)(statics + profiles) +
           WIRE_GROUP_EACH * (size_t)groups + WIRE_GROUP_MEMBER * (size_t)members +
           2 * WIRE_GROUP_CONTACT * (size_t)contacts;
}

/* Polygons the paper counts for a shape: primitives count as one. */
static double polygons(const sc_shape *s)
{
    return (s->kind == SC_SHAPE_MESH || s->kind == SC_SHAPE_CONVEX) ? (double)s->ntris : 1.0;
}

double sc_pair_cost(const sc_shape *a, const sc_shape *b)
{
    return polygons(a) * polygons(b);
}

static int run_collide(sc_np_ctx *np, const sc_job *job, const sc_unit *u)
{
    for (int i = u->first; i < u->first + u->count; i++) {
        const sc_unit_pair *p = &job->pairs[i];
        sc_contact *c = &job->contacts[(size_t)i * SC_MAX_PAIR_CONTACTS];
        int n = sc_np_collide(np, p->sa, &p->a0, p->sb, &p->b0, c, SC_MAX_PAIR_CONTACTS);
        if (n < 0)
            return n;
        for (int k = 0; k < n; k++) {
            c[k].body_a = p->body_a;
            c[k].body_b = p->body_b;
        }
        job->ncontact[i] = n;
    }
    return SC_OK;
}

/* The frame takes the minimum of a TOI job's times, so each pair is only
 * searched before the unit's earliest so far: a pair's time is exact when
 * it is the earliest, and the minimum is the same bits whoever ran which
 * pairs in which units (docs/DESIGN.md 3.4). */
static int run_toi(sc_np_ctx *np, const sc_job *job, const sc_unit *u)
{
    double best = 1;
    for (int i = u->first; i < u->first + u->count; i++) {
        const sc_unit_pair *p = &job->pairs[i];
        double t = 1, tmax = p->exact ? 1 : best;
        /* a new pair: back up to first touch; a pair already touching that
         * digs in past the tolerance: back up to where it reaches it */
        int hit = p->deepen ? sc_toi_deepen_before_ctx(np, p->sa, &p->a0, &p->a1, p->sb,
                                                       &p->b0, &p->b1, job->tol_m, tmax, &t)
                            : sc_toi_before_ctx(np, p->sa, &p->a0, &p->a1, p->sb, &p->b0,
                                                &p->b1, job->tol_m, tmax, &t);
        if (hit < 0)
            return hit;
        job->toi[i] = hit == 1 ? t : 1;
        if (!p->exact)
            best = min_d(best, job->toi[i]);
    }
    return SC_OK;
}

void sc_unit_run(sc_np_ctx *np, const sc_job *job, sc_unit *u)
{
    long msgs = sc_ode_message_count();
    sc_arena *arena = sc_np_arena(np);
    sc_arena_reset(arena);    /* grows it, when the last unit overflowed */
    memset(&u->info, 0, sizeof u->info);
    switch (job->kind) {
    case SC_UNIT_COLLIDE:
        u->rc = run_collide(np, job, u);
        break;
    case SC_UNIT_TOI:
        u->rc = run_toi(np, job, u);
        break;
    case SC_UNIT_ISLAND: {
        /* small islands travel together, each solved on its own; a split
         * island shares its blocks with idle threads (the thread's runner,
         * when it has one): the same bits either way */
        const sc_islands *is = job->islands;
        sc_contact_params p = *job->params;
        p.runner = sc_np_runner(np);
        u->rc = SC_OK;
        for (int i = u->first; i < u->first + u->islands && u->rc == SC_OK; i++)
            u->rc = sc_island_solve(arena, job->bodies, job->c, &is->contacts[is->contact_start[i]],
                                    is->contact_start[i + 1] - is->contact_start[i], job->h, &p,
                                    &u->info);
        break;
    }
    case SC_UNIT_GROUP:
        u->rc = job->run_group(np, job, u);
        break;
    default:
        u->rc = SC_EINVAL;
    }
    u->messages = sc_ode_message_count() - msgs;
    u->arena_high = arena->high;
}
