/* contact_rows.h - an island's contact rows as the contact solvers see
 * them (contact.c, island_sparse.c): each row's Jacobian and W J^T per
 * body, its local velocity slots, and the problem w = J u + off with
 * bounds or friction bounds +-mu z_normal (docs/DESIGN.md 3.5 and 11). */
#ifndef SC_CONTACT_ROWS_H
#define SC_CONTACT_ROWS_H
#include "core.h"

typedef struct row {
    int a, b;                 /* body indices (static or asleep: W = 0) */
    int la, lb;               /* their slots in the island's local velocities */
    unsigned char ma, mb;     /* movable (W != 0): only their slots are
                                 written, so blocks of one colour that share
                                 a static body can run at once */
    double ja[6], jb[6];      /* Jacobian: linear, angular */
    double wa[6], wb[6];      /* W J^T per body */
} row;

/* A body the contact solves move (W != 0); static and sleeping ones are
 * only read. */
static inline int movable(const sc_body *b)
{
    return b->inv_mass > 0 && b->state != SC_ASLEEP;
}

static inline double dot6(const double *x, const double *y)
{
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2] + x[3] * y[3] + x[4] * y[4] + x[5] * y[5];
}

/* J u for a row on the island's local velocities (6 per slot). */
static inline double local_speed(const row *rw, const double *u)
{
    return dot6(rw->ja, &u[6 * rw->la]) + dot6(rw->jb, &u[6 * rw->lb]);
}

static inline void local_apply(const row *rw, double dz, double *u)
{
    double *ua = &u[6 * rw->la], *ub = &u[6 * rw->lb];
    if (rw->ma)
        for (int k = 0; k < 6; k++)
            ua[k] += rw->wa[k] * dz;
    if (rw->mb)
        for (int k = 0; k < 6; k++)
            ub[k] += rw->wb[k] * dz;
}

/* A_rs = J_r W J_s^T */
static inline double a_entry(const row *r, const row *s)
{
    double v = 0;
    if (r->a == s->a) v += dot6(r->ja, s->wa);
    if (r->a == s->b) v += dot6(r->ja, s->wb);
    if (r->b == s->a) v += dot6(r->jb, s->wa);
    if (r->b == s->b) v += dot6(r->jb, s->wb);
    return v;
}

/* The problem the blocks iterate on: w = J u + off, bounds lo/hi or, for
 * friction rows (findex >= 0), +-mu z[findex]; u the local velocities. */
typedef struct gs_problem {
    const row *rows;
    int nrows;
    const double *off, *lo, *hi, *mu;
    const int *findex;        /* island row indices, -1 none; NULL: none */
    int cold;                 /* no warm starts (sc_contact_params.cold) */
    int pseudo;               /* the push-out: pseudo velocities, its own
                                 relative tolerance, not in the residual and
                                 sweep figures (its unit scales with 1/h) */
} gs_problem;

static inline void row_bounds(const gs_problem *pb, const double *z, int r, double *lo, double *hi)
{
    if (pb->findex && pb->findex[r] >= 0) {
        *hi = pb->mu[r] * z[pb->findex[r]];
        *lo = -*hi;
    } else {
        *lo = pb->lo[r];
        *hi = pb->hi[r];
    }
}

/* The whole problem pb exactly by an active set (island_sparse.c), from z
 * (warm start, already in the local velocities u, 6 a slot; slot t is body
 * slot_body[t]): the answer in z and u, verified as a Dantzig answer;
 * SC_ENUMERIC when the guesses did not settle (z and u unchanged),
 * SC_ENOMEM. subdomains: each factorisation by subdomains (island_schur.c),
 * their parts as tasks of runner (NULL: here) with this thread's arena. */
int sc_island_active_set(const gs_problem *pb, const sc_body *bodies, const int *slot_body,
                         int nslots, int subdomains, const sc_task_runner *runner,
                         sc_arena *arena, double *z, double *u, sc_solve_info *info);

/* A = J W J^T gets a compliance of COMPLIANCE times its largest diagonal
 * entry on the diagonal (contact.c build_a() says why). */
#define COMPLIANCE 1e-6

#endif
