/* island_schur.c - K u = b by subdomains (docs/DESIGN.md 11). The unknowns
 * are split into parts and an interface such that no entry of K joins the
 * interiors of two parts; then with each part's interior block K_II, its
 * coupling to the interface K_IG, K_GI and the interface's own K_GG,
 *   S = K_GG - sum_p K_GI K_II^-1 K_IG             (the Schur complement)
 *   S u_G = b_G - sum_p K_GI K_II^-1 b_I,   u_I = K_II^-1 (b_I - K_IG u_G).
 * A part needs only its own rows and the interface unknowns next to it:
 * on a node of its own it would factor K_II, send its block of S (the
 * interface unknowns it touches, squared) once a factorisation and its
 * K_GI K_II^-1 b_I once a solve, and get u_G back. The parts run in part
 * order, each summed into S in that order, so the bits are the same
 * whoever runs them. The interface system is dense, LU with partial
 * pivoting: it is small (the bodies where the parts meet). */
#include <klu.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "island_schur.h"
#include "lcp.h"

typedef struct part {
    int n;                    /* interior unknowns */
    int *gl;                  /* local -> global */
    int na;                   /* interface unknowns next to it */
    int *adj;                 /* its interface unknowns (interface index) */
    int *kp, *ki;             /* K_II, compressed columns */
    double *kx;
    double *kig;              /* K_IG: n x na, column-major */
    double *kgi;              /* K_GI: na x n, column-major */
    double *x;                /* K_II^-1 K_IG, n x na */
    double *y;                /* n */
    double *t;                /* K_GI X, na x na column-major */
    double *gp;               /* K_GI y, na */
    int rc;                   /* of its last task */
    klu_common kc;            /* its own: parts run on several threads */
    klu_symbolic *sym;
    klu_numeric *num;
} part;

enum { TO_II, TO_IG, TO_GI, TO_GG };

struct sc_schur {
    int n, ng, nparts, nnz;
    const int *kp, *ki;       /* the caller's pattern (outlives the plan) */
    int *cls;                 /* per unknown: part, or -1 interface */
    int *loc;                 /* per unknown: index in its part or the interface */
    int *gi;                  /* interface index -> global */
    unsigned char *kind;      /* per entry of K: TO_* */
    int *dpart, *dst;         /* per entry: part, index in the target */
    part *pt;
    double *S;                /* ng x ng row-major, then its LU */
    int *piv;
    double *g;
    double *x;                /* the vector being solved */
    sc_schur_traffic tr;
};

void sc_schur_free(sc_schur *s)
{
    if (!s)
        return;
    for (int p = 0; s->pt && p < s->nparts; p++) {
        part *q = &s->pt[p];
        if (q->num)
            klu_free_numeric(&q->num, &q->kc);
        if (q->sym)
            klu_free_symbolic(&q->sym, &q->kc);
        free(q->gl);
        free(q->adj);
        free(q->kp);
        free(q->ki);
        free(q->kx);
        free(q->kig);
        free(q->kgi);
        free(q->x);
        free(q->y);
        free(q->t);
        free(q->gp);
    }
    free(s->pt);
    free(s->S);
    free(s->piv);
    free(s->g);
    free(s->kind);
    free(s->dpart);
    free(s->dst);
    free(s->gi);
    free(s->loc);
    free(s->cls);
    free(s);
}

/* Part p's interior pattern, its interface neighbours and the entries'
 * targets. mark: ng ints, all -1 on entry and on return. */
static int plan_part(sc_schur *s, int p, int *mark)
{
    part *q = &s->pt[p];
    const int *kp = s->kp, *ki = s->ki;
    /* interface neighbours: rows of its columns, and columns whose rows
     * are its, in interface order */
    int na = 0;
    for (int g = 0; g < s->ng; g++) {
        int j = s->gi[g], near = 0;
        for (int e = kp[j]; e < kp[j + 1] && !near; e++)
            near = s->cls[ki[e]] == p;
        if (near)
            mark[g] = na++;
    }
    q->na = na;
    size_t nn = (size_t)q->n, nad = (size_t)na;
    q->adj = malloc((nad ? nad : 1) * sizeof *q->adj);
    q->kp = malloc((nn + 1) * sizeof *q->kp);
    q->kig = calloc(nn * nad + 1, sizeof *q->kig);
    q->kgi = calloc(nn * nad + 1, sizeof *q->kgi);
    q->x = calloc(nn * nad + 1, sizeof *q->x);
    q->y = malloc((nn ? nn : 1) * sizeof *q->y);
    q->t = malloc((nad > 0 ? nad * nad : 1) * sizeof *q->t);
    q->gp = malloc((nad ? nad : 1) * sizeof *q->gp);
    if (!q->adj || !q->kp || !q->kig || !q->kgi || !q->x || !q->y || !q->t || !q->gp)
        return SC_ENOMEM;
    for (int g = 0; g < s->ng; g++)
        if (mark[g] >= 0)
            q->adj[mark[g]] = g;
    int cnt = 0;
    for (int k = 0; k < q->n; k++) {
        int j = q->gl[k];
        for (int e = kp[j]; e < kp[j + 1]; e++)
            cnt += s->cls[ki[e]] == p;
    }
    q->ki = malloc((size_t)(cnt ? cnt : 1) * sizeof *q->ki);
    q->kx = malloc((size_t)(cnt ? cnt : 1) * sizeof *q->kx);
    if (!q->ki || !q->kx)
        return SC_ENOMEM;
    cnt = 0;
    for (int k = 0; k < q->n; k++) {
        int j = q->gl[k];
        q->kp[k] = cnt;
        for (int e = kp[j]; e < kp[j + 1]; e++) {
            int i = ki[e];
            s->dpart[e] = p;
            if (s->cls[i] == p) {
                s->kind[e] = TO_II;
                s->dst[e] = cnt;
                q->ki[cnt++] = s->loc[i];
            } else {          /* the interface (plan() refused the rest) */
                s->kind[e] = TO_GI;
                s->dst[e] = k * na + mark[s->loc[i]];
            }
        }
    }
    q->kp[q->n] = cnt;
    for (int g = 0; g < s->ng; g++) {
        int j = s->gi[g];
        for (int e = kp[j]; e < kp[j + 1]; e++)
            if (s->cls[ki[e]] == p) {
                s->kind[e] = TO_IG;
                s->dpart[e] = p;
                s->dst[e] = mark[g] * q->n + s->loc[ki[e]];
            }
    }
    for (int g = 0; g < s->ng; g++)
        mark[g] = -1;
    klu_defaults(&q->kc);
    if (q->n > 0) {
        q->sym = klu_analyze(q->n, q->kp, q->ki, &q->kc);
        if (!q->sym)
            return q->kc.status == KLU_OUT_OF_MEMORY ? SC_ENOMEM : SC_ENUMERIC;
    }
    return SC_OK;
}

int sc_schur_plan(sc_schur **out, int n, const int *kp, const int *ki, const int *where,
                  int nparts)
{
    *out = NULL;
    if (n < 1 || nparts < 1)
        return SC_EINVAL;
    sc_schur *s = calloc(1, sizeof *s);
    if (!s)
        return SC_ENOMEM;
    s->n = n;
    s->nparts = nparts;
    s->kp = kp;
    s->ki = ki;
    s->nnz = kp[n];
    size_t nd = (size_t)n, nz = (size_t)(s->nnz ? s->nnz : 1);
    s->cls = malloc(nd * sizeof *s->cls);
    s->loc = malloc(nd * sizeof *s->loc);
    s->gi = malloc(nd * sizeof *s->gi);
    s->kind = malloc(nz);
    s->dpart = malloc(nz * sizeof *s->dpart);
    s->dst = malloc(nz * sizeof *s->dst);
    s->pt = calloc((size_t)nparts, sizeof *s->pt);
    int *mark = malloc(nd * sizeof *mark);
    int rc = SC_ENOMEM;
    if (!s->cls || !s->loc || !s->gi || !s->kind || !s->dpart || !s->dst || !s->pt || !mark)
        goto out;
    rc = SC_EINVAL;
    for (int i = 0; i < n; i++) {
        if (where[i] < -1 || where[i] >= nparts)
            goto out;
        s->cls[i] = where[i];
        s->loc[i] = where[i] < 0 ? s->ng++ : s->pt[where[i]].n++;
        if (where[i] < 0)
            s->gi[s->loc[i]] = i;
    }
    for (int j = 0; j < n; j++)
        for (int e = kp[j]; e < kp[j + 1]; e++) {
            int a = s->cls[ki[e]], b = s->cls[j];
            if (a >= 0 && b >= 0 && a != b)
                goto out;     /* two interiors joined */
            if (a < 0 && b < 0) {
                s->kind[e] = TO_GG;
                s->dpart[e] = 0;
                s->dst[e] = s->loc[ki[e]] * s->ng + s->loc[j];
            }
        }
    rc = SC_ENOMEM;
    size_t ng = (size_t)s->ng;
    s->S = malloc((ng > 0 ? ng * ng : 1) * sizeof *s->S);
    s->piv = malloc((ng ? ng : 1) * sizeof *s->piv);
    s->g = malloc((ng ? ng : 1) * sizeof *s->g);
    if (!s->S || !s->piv || !s->g)
        goto out;
    for (int p = 0; p < nparts; p++) {
        part *q = &s->pt[p];
        q->gl = malloc((size_t)(q->n ? q->n : 1) * sizeof *q->gl);
        if (!q->gl)
            goto out;
        q->n = 0;
    }
    for (int i = 0; i < n; i++)
        if (s->cls[i] >= 0)
            s->pt[s->cls[i]].gl[s->pt[s->cls[i]].n++] = i;
    for (int g = 0; g < s->ng; g++)
        mark[g] = -1;
    for (int p = 0; p < nparts; p++)
        if ((rc = plan_part(s, p, mark)) != SC_OK)
            goto out;
    rc = SC_OK;
out:
    free(mark);
    if (rc != SC_OK)
        sc_schur_free(s);
    else
        *out = s;
    return rc;
}

/* out = K_GI v (na entries) for v of the part's n interior unknowns. */
static void kgi_times(const part *q, const double *v, double *out)
{
    memset(out, 0, (size_t)q->na * sizeof *out);
    for (int k = 0; k < q->n; k++) {
        double vk = v[k];
        if (vk == 0)
            continue;
        const double *gk = q->kgi + (size_t)k * q->na;
        for (int r = 0; r < q->na; r++)
            out[r] += gk[r] * vk;
    }
}

/* Part i's share of a factorisation: its interior factor, X = K_II^-1
 * K_IG and T = K_GI X (a task: only the part's own arrays). */
static void factor_part(void *arg, int i, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    sc_schur *s = arg;
    part *q = &s->pt[i];
    q->rc = SC_OK;
    if (q->n == 0)
        return;
    if (!(q->num && klu_refactor(q->kp, q->ki, q->kx, q->sym, q->num, &q->kc) &&
          q->kc.status == KLU_OK)) {
        if (q->num)
            klu_free_numeric(&q->num, &q->kc);
        q->num = klu_factor(q->kp, q->ki, q->kx, q->sym, &q->kc);
        if (!q->num) {
            q->rc = q->kc.status == KLU_OUT_OF_MEMORY ? SC_ENOMEM : SC_ENUMERIC;
            return;
        }
    }
    if (q->na == 0)
        return;
    memcpy(q->x, q->kig, (size_t)q->n * (size_t)q->na * sizeof *q->x);
    if (!klu_solve(q->sym, q->num, q->n, q->na, q->x, &q->kc)) {
        q->rc = SC_ENUMERIC;
        return;
    }
    for (int c = 0; c < q->na; c++)
        kgi_times(q, q->x + (size_t)c * q->n, q->t + (size_t)c * q->na);
}

int sc_schur_factor(sc_schur *s, const double *kx, const sc_task_runner *runner, sc_arena *a)
{
    size_t ng = (size_t)s->ng;
    memset(s->S, 0, ng * ng * sizeof *s->S);
    for (int p = 0; p < s->nparts; p++) {
        part *q = &s->pt[p];
        size_t m = (size_t)q->n * (size_t)q->na;
        memset(q->kig, 0, m * sizeof *q->kig);
        memset(q->kgi, 0, m * sizeof *q->kgi);
    }
    for (int e = 0; e < s->nnz; e++) {
        part *q = &s->pt[s->dpart[e]];
        switch (s->kind[e]) {
        case TO_II: q->kx[s->dst[e]] = kx[e]; break;
        case TO_IG: q->kig[s->dst[e]] = kx[e]; break;
        case TO_GI: q->kgi[s->dst[e]] = kx[e]; break;
        default: s->S[s->dst[e]] = kx[e]; break;
        }
    }
    sc_tasks_run(runner, factor_part, s, s->nparts, a);
    /* S -= each part's T, in part order */
    long bytes = 0;
    for (int p = 0; p < s->nparts; p++) {
        const part *q = &s->pt[p];
        if (q->rc != SC_OK)
            return q->rc;
        if (q->n == 0)
            continue;
        for (int c = 0; c < q->na; c++)
            for (int r = 0; r < q->na; r++)
                s->S[(size_t)q->adj[r] * ng + q->adj[c]] -= q->t[(size_t)c * q->na + r];
        bytes += 8L * q->na * q->na;
    }
    s->tr.exchanges++;
    s->tr.bytes += bytes;
    return sc_lu_factor(s->ng, s->S, s->piv);
}

/* Part i's solve before the interface: y = K_II^-1 b_I, gp = K_GI y. */
static void solve_part(void *arg, int i, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    sc_schur *s = arg;
    part *q = &s->pt[i];
    q->rc = SC_OK;
    if (q->n == 0)
        return;
    for (int k = 0; k < q->n; k++)
        q->y[k] = s->x[q->gl[k]];
    if (!klu_solve(q->sym, q->num, q->n, 1, q->y, &q->kc)) {
        q->rc = SC_ENUMERIC;
        return;
    }
    kgi_times(q, q->y, q->gp);
}

/* Part i's solve after the interface: u_I = y - X u_G. */
static void finish_part(void *arg, int i, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    sc_schur *s = arg;
    const part *q = &s->pt[i];
    for (int k = 0; k < q->n; k++) {
        double v = q->y[k];
        for (int c = 0; c < q->na; c++)
            v -= q->x[(size_t)c * q->n + k] * s->g[q->adj[c]];
        s->x[q->gl[k]] = v;
    }
}

int sc_schur_solve(sc_schur *s, double *x, const sc_task_runner *runner, sc_arena *a)
{
    for (int g = 0; g < s->ng; g++)
        s->g[g] = x[s->gi[g]];
    s->x = x;
    sc_tasks_run(runner, solve_part, s, s->nparts, a);
    long bytes = 0;
    for (int p = 0; p < s->nparts; p++) {
        const part *q = &s->pt[p];
        if (q->rc != SC_OK)
            return q->rc;
        for (int r = 0; r < q->na; r++)
            s->g[q->adj[r]] -= q->gp[r];
        bytes += 16L * q->na;
    }
    sc_lu_solve_factored(s->ng, s->S, s->piv, s->g);
    for (int g = 0; g < s->ng; g++)
        x[s->gi[g]] = s->g[g];
    sc_tasks_run(runner, finish_part, s, s->nparts, a);
    s->tr.exchanges++;
    s->tr.bytes += bytes;
    for (int i = 0; i < s->n; i++)
        if (!isfinite(x[i]))
            return SC_ENUMERIC;
    return SC_OK;
}

int sc_schur_interface(const sc_schur *s)
{
    return s->ng;
}

int sc_schur_parts(const sc_schur *s)
{
    return s->nparts;
}

long sc_schur_factor_nnz(const sc_schur *s)
{
    long nnz = (long)s->ng * s->ng;
    for (int p = 0; p < s->nparts; p++)
        if (s->pt[p].num)
            nnz += (long)s->pt[p].num->lnz + s->pt[p].num->unz + s->pt[p].num->nzoff;
    return nnz;
}

sc_schur_traffic sc_schur_traffic_of(const sc_schur *s)
{
    return s->tr;
}
