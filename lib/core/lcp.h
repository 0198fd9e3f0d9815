/* lcp.h - our LCP solvers (lcp.c, lcp_factor.c, lcp_lemke.c): Dantzig's
 * principal pivoting for the standard and the boxed LCP, with Lemke's
 * method as the fallback on singular blocks (docs/DESIGN.md section 3). */
#ifndef SC_LCP_H
#define SC_LCP_H

#include <stddef.h>

#include "arena.h"

typedef struct sc_lcp_info {
    long pivots;              /* principal pivots made */
    double residual;          /* max complementarity / feasibility violation */
    int lemke;                /* 1: principal pivoting stalled on a singular
                                 block and Lemke's method (also exact, also
                                 verified) gave the answer */
    int covers;               /* friction: Lemke paths tried after the
                                 one of covering vector e (lcp.c, cover()) */
    int guessed;              /* 1: neither the friction fixed point nor
                                 Lemke's method settled, and a fixed point
                                 started from projected Gauss-Seidel's
                                 iterate did (exact, verified) */
} sc_lcp_info;

/* The standard LCP by Cottle-Dantzig principal pivoting; info may be NULL. */
int sc_lcp_dantzig(int n, const double *M, const double *q, double *z, double *w,
                   sc_lcp_info *info);
/* Boxed LCP (mixed complementarity): lo <= z <= hi, w = M z + q with
 * w >= 0 where z = lo, w <= 0 where z = hi, w = 0 in between. If findex is
 * not NULL and findex[i] >= 0, the bounds of row i are -mu[i] * z[findex[i]]
 * and +mu[i] * z[findex[i]] (friction), lo/hi ignored for that row. */
int sc_lcp_boxed(int n, const double *M, const double *q, const double *lo,
                 const double *hi, const int *findex, const double *mu,
                 double *z, double *w, sc_lcp_info *info);

/* The same two with their workspace (one block a call) from arena a
 * (NULL: malloc): the contact solves use their thread's arena. */
int sc_lcp_dantzig_in(sc_arena *a, int n, const double *M, const double *q, double *z,
                      double *w, sc_lcp_info *info);
int sc_lcp_boxed_in(sc_arena *a, int n, const double *M, const double *q, const double *lo,
                    const double *hi, const int *findex, const double *mu, double *z,
                    double *w, sc_lcp_info *info);

/* After a failed solve of M z + q (boxed when lo is not NULL, else the
 * standard LCP; M is changed): the retries with M's diagonal raised in
 * place, in turn by shares of its largest entry (RAISE in lcp.c; the
 * first, 1e-9, makes a singular M of redundant contacts regular, the
 * larger ones settle near-redundant, ill-conditioned ones), cold, each
 * but the last without the dearest friction try (the fixed point from
 * projected Gauss-Seidel's iterate), until one solves. A raised diagonal
 * is a compliance: the answer is exact for M + s dmax I (*share: s, 0 if
 * none solved), and off the given M's by s dmax |z| at most. info sums
 * the tries' pivots, Lemke and guessed counts; its residual is the last
 * try's. docs/DESIGN.md 11. */
int sc_lcp_raised_in(sc_arena *a, int n, double *M, const double *q, const double *lo,
                     const double *hi, const int *findex, const double *mu, double *z,
                     double *w, sc_lcp_info *info, double *share);

/* The same, started from z as a guess (warm start: last frame's impulses
 * or a block's last iterate): z in [lo, hi] strictly inside joins the
 * clamped set, at a bound starts there, 0 is driven as in a cold pass.
 * The answer is verified as a cold one; a start that fails is retried
 * cold. With friction, the first round's bounds come from the guess. */
int sc_lcp_dantzig_warm_in(sc_arena *a, int n, const double *M, const double *q, double *z,
                           double *w, sc_lcp_info *info);
int sc_lcp_boxed_warm_in(sc_arena *a, int n, const double *M, const double *q,
                         const double *lo, const double *hi, const int *findex,
                         const double *mu, double *z, double *w, sc_lcp_info *info);
/* The same with friction's fixed-point rounds only, damped (their bounds
 * from a mean of answers after the first rounds, more rounds: lcp.c):
 * where they do not settle, SC_EMAXITER (or the rounds' error) without
 * Lemke's method or the guess after them (a caller that has an answer to
 * keep). */
int sc_lcp_boxed_rounds_in(sc_arena *a, int n, const double *M, const double *q,
                           const double *lo, const double *hi, const int *findex,
                           const double *mu, double *z, double *w, sc_lcp_info *info);

/* L D U factorisation of the clamped block M_CC of an n x n row-major M,
 * updated as indices enter (sc_ldu_border + sc_ldu_commit) and leave
 * (sc_ldu_remove), O(m^2) each (lcp_factor.c). U = L^T when sym. */
typedef struct sc_ldu {
    int n;                    /* capacity (M is n x n) */
    int m;                    /* indices in the factorisation */
    int sym;                  /* M symmetric: ut aliases l */
    int bordered;             /* M index prepared at position m, or -1 */
    double *l;                /* row r: L[r][0..r-1], stride n */
    double *ut;               /* row r: U[0..r-1][r], stride n */
    double *d;                /* pivots */
    double *x, *y;            /* scratch */
    int *idx;                 /* M index of each factor position */
} sc_ldu;
/* Bytes of the memory sc_ldu_init() needs (aligned for double). */
size_t sc_ldu_size(int n, int sym);
void sc_ldu_init(sc_ldu *f, int n, int sym, void *mem);
/* Prepare M index j as position m; returns its pivot, *scale (may be NULL)
 * the magnitude of the terms it cancelled from. */
double sc_ldu_border(sc_ldu *f, const double *M, int j, double *scale);
/* Make the prepared border part of the factorisation. */
void sc_ldu_commit(sc_ldu *f);
/* x = -M_CC^-1 M_{C,j} for the prepared index j (factor order). */
void sc_ldu_border_direction(const sc_ldu *f, double *x);
/* v = M_CC^-1 v in place (factor order). */
void sc_ldu_solve(const sc_ldu *f, double *v);
/* Remove position k; SC_OK or SC_ENUMERIC (an updated pivot cancelled). */
int sc_ldu_remove(sc_ldu *f, int k);
/* Dense m x m solve a v = b in place, partial pivoting; SC_OK or SC_ENUMERIC. */
int sc_lu_solve(int m, double *a, double *b);
/* The same elimination kept for many right-hand sides: a (row-major) into
 * its LU factors in place, piv[m] its row swaps; SC_OK or SC_ENUMERIC. */
int sc_lu_factor(int m, double *a, int *piv);
/* b = a^-1 b in place, from sc_lu_factor()'s a and piv. */
void sc_lu_solve_factored(int m, const double *a, const int *piv, double *b);
/* Lemke's method (lcp_lemke.c), the fallback of sc_lcp_dantzig when a
 * principal block is singular: z of the final basis (not yet verified),
 * SC_OK, SC_ENOSOLUTION (secondary ray), SC_EMAXITER (*pivots reached
 * max_pivots) or SC_ENOMEM; *pivots is increased by the pivots made.
 * d: the covering vector, n entries > 0 (NULL: all 1). */
int sc_lcp_lemke(int n, const double *M, const double *q, const double *d, double *z,
                 long max_pivots, long *pivots);

#endif /* SC_LCP_H */
