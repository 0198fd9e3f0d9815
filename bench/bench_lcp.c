/* bench_lcp.c - time per solve of the contact LCP (lib/lcp.c) on the kind of
 * problem the engine builds: a stack of boxes, each face resting on the one
 * below with 6 contact points (4 corners and 2 edge midpoints: 6 rows of
 * rank 3, so A = J W J^T is only positive semidefinite), the boxes moving
 * a little (random velocities of a few cm/s and tenths of rad/s, seeded) on
 * top of one step of gravity, so that some contacts separate.
 *
 * Table 1: the standard LCP (sc_lcp_dantzig), n = 12 ... 384 contacts.
 * Table 2: the same stacks with Coulomb friction (sc_lcp_boxed, mu = 0.5,
 * two tangent rows per contact with findex), n = 3 x contacts.
 * Prints the median and the minimum over the runs (CLOCK_MONOTONIC around
 * the solve only), the pivots, the nonzero z and the residual. Exits
 * non-zero if any solve fails.
 *
 * usage: bench_lcp [runs]        (default 15) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core.h"
#include "lcp.h"

#include "bench_util.h"

#define G 9.81
#define DT 0.01
#define HX 0.3
#define HY 0.2
#define HZ 0.1
#define MASS 2.0

static uint64_t seed = 7;

static double rnd(void)   /* splitmix64, [-1, 1): the same scenes on every run */
{
    uint64_t z = (seed += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return 2.0 * (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53 - 1.0;
}

typedef struct scene {
    int boxes, rows;
    double yaw, iinv[9];   /* all boxes alike, same yaw */
    double *J;             /* rows x 6 boxes */
    double *u;             /* 6 boxes: velocities after gravity */
} scene;

static void cross(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

/* Row of J: velocity of box b minus box a (a = -1: the floor) along d at p. */
static void add_row(scene *s, int a, int b, const double p[3], const double d[3])
{
    double *row = s->J + (size_t)s->rows * 6 * s->boxes;
    int who[2] = { a, b };
    for (int k = 0; k < 2; k++) {
        if (who[k] < 0)
            continue;
        double c[3] = { 0, 0, HZ * (2 * who[k] + 1) }, r[3], rxd[3];
        double sign = k == 0 ? -1.0 : 1.0;
        for (int i = 0; i < 3; i++)
            r[i] = p[i] - c[i];
        cross(r, d, rxd);
        for (int i = 0; i < 3; i++) {
            row[6 * who[k] + i] += sign * d[i];
            row[6 * who[k] + 3 + i] += sign * rxd[i];
        }
    }
    s->rows++;
}

/* A stack of `boxes` boxes, npts contacts per face, friction: also two
 * tangent rows per contact (after all the normal rows). */
static int scene_build(scene *s, int boxes, int npts, int friction)
{
    static const double pat[6][2] = { { 1, 1 }, { -1, 1 }, { -1, -1 },
                                      { 1, -1 }, { 0, 1 }, { 0, -1 } };
    int contacts = boxes * npts, rows = contacts * (friction ? 3 : 1);
    s->boxes = boxes;
    s->rows = 0;
    s->yaw = 0.5 * rnd();
    s->J = calloc((size_t)rows * 6 * boxes, sizeof(double));
    s->u = calloc((size_t)6 * boxes, sizeof(double));
    if (!s->J || !s->u)
        return -1;
    double I[3] = { MASS * (HY * HY + HZ * HZ) / 3, MASS * (HX * HX + HZ * HZ) / 3,
                    MASS * (HX * HX + HY * HY) / 3 };
    double cy = cos(s->yaw), sy = sin(s->yaw);
    double R[9] = { cy, -sy, 0, sy, cy, 0, 0, 0, 1 };
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double a = 0;
            for (int k = 0; k < 3; k++)
                a += R[i * 3 + k] * R[j * 3 + k] / I[k];
            s->iinv[i * 3 + j] = a;
        }
    double dirs[3][3] = { { 0, 0, 1 }, { cy, sy, 0 }, { -sy, cy, 0 } };
    for (int d = 0; d < (friction ? 3 : 1); d++)
        for (int b = 0; b < boxes; b++)
            for (int k = 0; k < npts; k++) {
                double x = pat[k][0] * HX, y = pat[k][1] * HY;
                double p[3] = { cy * x - sy * y, sy * x + cy * y, 2 * HZ * b };
                add_row(s, b - 1, b, p, dirs[d]);
            }
    for (int b = 0; b < boxes; b++) {
        for (int i = 0; i < 3; i++) {
            s->u[6 * b + i] = 0.03 * rnd();
            s->u[6 * b + 3 + i] = 0.2 * rnd();
        }
        s->u[6 * b + 2] -= G * DT;
    }
    return 0;
}

/* A = J W J^T, q = J u. */
static void scene_lcp(const scene *s, double *A, double *q)
{
    int n = s->rows, k = 6 * s->boxes;
    double *wj = malloc((size_t)k * sizeof(double));
    for (int j = 0; j < n; j++) {
        const double *r = s->J + (size_t)j * k;
        for (int b = 0; b < s->boxes; b++)
            for (int i = 0; i < 3; i++) {
                wj[6 * b + i] = r[6 * b + i] / MASS;
                double a = 0;
                for (int c = 0; c < 3; c++)
                    a += s->iinv[i * 3 + c] * r[6 * b + 3 + c];
                wj[6 * b + 3 + i] = a;
            }
        for (int i = 0; i < n; i++) {
            double a = 0;
            for (int c = 0; c < k; c++)
                a += s->J[(size_t)i * k + c] * wj[c];
            A[(size_t)i * n + j] = a;
        }
    }
    for (int i = 0; i < n; i++) {
        double a = 0;
        for (int c = 0; c < k; c++)
            a += s->J[(size_t)i * k + c] * s->u[c];
        q[i] = a;
    }
    free(wj);
}

/* Solve one scene `runs` times; print a row. Returns 0 or 1 (failure). */
static int bench_one(int boxes, int npts, int friction, int runs)
{
    scene s;
    if (scene_build(&s, boxes, npts, friction) != 0)
        return 1;
    int n = s.rows, contacts = boxes * npts;
    double *A = malloc((size_t)n * n * sizeof(double)), *q = malloc((size_t)n * sizeof(double));
    double *z = malloc((size_t)n * sizeof(double)), *w = malloc((size_t)n * sizeof(double));
    double *lo = malloc((size_t)n * sizeof(double)), *hi = malloc((size_t)n * sizeof(double));
    double *mu = malloc((size_t)n * sizeof(double)), *t = malloc((size_t)runs * sizeof(double));
    int *findex = malloc((size_t)n * sizeof(int));
    if (!A || !q || !z || !w || !lo || !hi || !mu || !t || !findex)
        return 1;
    scene_lcp(&s, A, q);
    for (int i = 0; i < n; i++) {
        findex[i] = i < contacts ? -1 : i % contacts;
        mu[i] = 0.5;
        lo[i] = 0;
        hi[i] = INFINITY;
    }
    sc_lcp_info info = { 0 };
    int rc = SC_OK;
    for (int r = 0; r < runs && rc == SC_OK; r++) {
        double t0 = now_s();
        rc = friction ? sc_lcp_boxed(n, A, q, lo, hi, findex, mu, z, w, &info)
                      : sc_lcp_dantzig(n, A, q, z, w, &info);
        t[r] = now_s() - t0;
    }
    int nonzero = 0;
    for (int i = 0; i < n; i++)
        nonzero += z[i] != 0;
    if (rc == SC_OK) {
        qsort(t, (size_t)runs, sizeof(double), cmp_double);
        printf("%5d %6d %11.3f %9.3f %7ld %8d %10.2e\n", n, boxes, 1e3 * t[runs / 2],
               1e3 * t[0], info.pivots, nonzero, info.residual);
    } else {
        printf("%5d %6d   failed: %s\n", n, boxes, sc_strerror(rc));
    }
    free(A);
    free(q);
    free(z);
    free(w);
    free(lo);
    free(hi);
    free(mu);
    free(t);
    free(findex);
    free(s.J);
    free(s.u);
    return rc != SC_OK;
}

int main(int argc, char **argv)
{
    int runs = argc > 1 ? atoi(argv[1]) : 15;
    if (runs < 1 || runs > 100000) {
        fprintf(stderr, "usage: bench_lcp [runs]\n");
        return 2;
    }
    static const int boxes6[] = { 2, 8, 16, 32, 64 };   /* 6 contacts per box */
    static const int boxes4[] = { 1, 4, 8, 16, 32 };    /* 4 contacts, x3 rows */
    int bad = 0;
    printf("standard LCP (sc_lcp_dantzig): stack of boxes, 6 contacts per face, "
           "median of %d runs\n", runs);
    printf("%5s %6s %11s %9s %7s %8s %10s\n", "n", "boxes", "median_ms", "min_ms", "pivots",
           "z!=0", "residual");
    for (int k = 0; k < 5; k++)
        bad |= bench_one(boxes6[k], 6, 0, runs);
    printf("\nboxed LCP with friction (sc_lcp_boxed, mu 0.5): 4 contacts per face, "
           "n = 3 x contacts\n");
    printf("%5s %6s %11s %9s %7s %8s %10s\n", "n", "boxes", "median_ms", "min_ms", "pivots",
           "z!=0", "residual");
    for (int k = 0; k < 5; k++)
        bad |= bench_one(boxes4[k], 4, 1, runs);
    return bad;
}
