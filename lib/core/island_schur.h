/* island_schur.h - a big island's Newton system K u = b solved by
 * subdomains: each part's interior factored on its own, coupled through a
 * dense Schur complement on the interface unknowns (island_schur.c,
 * docs/DESIGN.md 11). */
#ifndef SC_ISLAND_SCHUR_H
#define SC_ISLAND_SCHUR_H
#include "core.h"

typedef struct sc_schur sc_schur;

/* What the subdomains would exchange with a master that holds the
 * interface, were each part on its own node. */
typedef struct sc_schur_traffic {
    long exchanges;           /* rounds: one a factorisation (each part's Schur
                                 block), one a solve (its interface terms out,
                                 the interface unknowns back) */
    long bytes;               /* in all, both ways */
} sc_schur_traffic;

/* The plan for the CSC pattern (kp, ki) of n unknowns, both triangles:
 * where[i] is unknown i's subdomain (0 .. nparts - 1) or -1 for the
 * interface. No
 * entry may join the interiors of two parts (SC_EINVAL). SC_ENOMEM. */
int sc_schur_plan(sc_schur **out, int n, const int *kp, const int *ki, const int *where,
                  int nparts);

/* Factors K (values kx in the plan's pattern): each part's interior by KLU
 * (the parts as tasks of runner, NULL: here; a: this thread's arena),
 * then the interface's Schur complement, dense, by LU with partial
 * pivoting. SC_ENUMERIC if a factor is singular, SC_ENOMEM. */
int sc_schur_factor(sc_schur *s, const double *kx, const sc_task_runner *runner, sc_arena *a);

/* x = K^-1 x with the last factors (the parts as tasks of runner). */
int sc_schur_solve(sc_schur *s, double *x, const sc_task_runner *runner, sc_arena *a);

/* Interface unknowns, parts, the factors' entries (the parts' LU and the
 * dense interface's); traffic so far. */
int sc_schur_interface(const sc_schur *s);
int sc_schur_parts(const sc_schur *s);
long sc_schur_factor_nnz(const sc_schur *s);
sc_schur_traffic sc_schur_traffic_of(const sc_schur *s);

void sc_schur_free(sc_schur *s);

#endif
