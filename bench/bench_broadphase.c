/* bench_broadphase.c - time per frame of the broad phase on a moving pile:
 * bodies of radius 0.045-0.055 m spread over a 2 x 2 x 1 m region (at 5000
 * bodies they fill 65 % of it, a dense pile, ~2.5 contacts per body), each
 * jittering at a few cm/s (a damped random walk) and bouncing off the
 * region's walls, so that the scene stays as dense as it starts (bodies
 * pulled down without physics would all end in one interpenetrating layer,
 * which no pile does), for the paper's
 * all-pairs spheres and for sweep and prune. Prints median and 90th
 * percentile over the frames (CLOCK_MONOTONIC around sc_bp_find_pairs only;
 * the first call, which sizes the buffers, is shown apart) and the pairs per
 * frame (mean over the frames both methods ran); checks that both methods
 * find the same number of pairs on every frame both ran (the test checks the
 * pairs themselves).
 *
 * usage: bench_broadphase [frames]      (default 200; all pairs caps its
 * frame count at large n, where one frame takes tens of milliseconds) */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "core.h"

#include "bench_util.h"

typedef struct pile {
    int n;
    double *c, *v, *r;
    uint64_t seed;
} pile;

static double rnd(pile *p)   /* splitmix64: the same scene on every run */
{
    uint64_t z = (p->seed += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
}

static const double region[3] = { 2, 2, 1 };

static int pile_init(pile *p, int n)
{
    p->n = n;
    p->seed = 42;
    p->c = malloc((size_t)n * 3 * sizeof *p->c);
    p->v = malloc((size_t)n * 3 * sizeof *p->v);
    p->r = malloc((size_t)n * sizeof *p->r);
    if (!p->c || !p->v || !p->r)
        return -1;
    for (int i = 0; i < n; i++) {
        p->r[i] = 0.045 + 0.01 * rnd(p);
        for (int k = 0; k < 3; k++) {
            p->c[3 * i + k] = region[k] * rnd(p);
            p->v[3 * i + k] = 0.2 * (rnd(p) - 0.5);
        }
    }
    return 0;
}

static void pile_free(pile *p)
{
    free(p->c);
    free(p->v);
    free(p->r);
}

/* One 10 ms frame: a damped random walk (a few mm per frame), walls that
 * bounce with loss. */
static void pile_step(pile *p)
{
    const double dt = 0.01;
    for (int i = 0; i < p->n; i++) {
        double *c = &p->c[3 * i], *v = &p->v[3 * i];
        for (int k = 0; k < 3; k++) {
            v[k] = 0.95 * v[k] + 0.04 * (rnd(p) - 0.5);
            c[k] += v[k] * dt;
            if (c[k] < 0) {
                c[k] = 0;
                v[k] = 0.5 * -v[k];
            } else if (c[k] > region[k]) {
                c[k] = region[k];
                v[k] = 0.5 * -v[k];
            }
        }
    }
}

typedef struct result {
    double first_ms, median_ms, p90_ms;
    int frames;
    int *pairs;               /* per call, frames + 1 of them */
} result;

/* Runs a first call and then frames frames of a fresh pile of n bodies
 * through one method (every method sees the same sequence of piles). */
static int run(int method, int n, int frames, result *res)
{
    pile p;
    sc_broadphase *bp = sc_bp_create();
    double *t = malloc((size_t)frames * sizeof *t);
    sc_pair *pairs = NULL;
    int cap = 0, rc = 0;
    res->pairs = malloc(((size_t)frames + 1) * sizeof *res->pairs);
    if (!bp || !t || !res->pairs || pile_init(&p, n)) {
        fprintf(stderr, "bench_broadphase: out of memory\n");
        return -1;              /* and exit: nothing to clean up for */
    }
    for (int f = 0; f <= frames && rc >= 0; f++) {
        double t0 = now_s();
        rc = sc_bp_find_pairs(bp, method, p.c, p.r, NULL, n, &pairs, &cap);
        double ms = 1e3 * (now_s() - t0);
        if (f == 0)
            res->first_ms = ms;
        else
            t[f - 1] = ms;
        res->pairs[f] = rc;
        pile_step(&p);
    }
    if (rc < 0) {
        fprintf(stderr, "bench_broadphase: %s\n", sc_strerror(rc));
    } else {
        qsort(t, (size_t)frames, sizeof *t, cmp_double);
        res->frames = frames;
        res->median_ms = t[frames / 2];
        res->p90_ms = t[frames * 9 / 10];
    }
    free(pairs);
    free(t);
    sc_bp_destroy(bp);
    pile_free(&p);
    return rc < 0 ? -1 : 0;
}

static double mean_pairs(const result *r, int frames)
{
    double sum = 0;
    for (int f = 1; f <= frames; f++)
        sum += r->pairs[f];
    return sum / frames;
}

int main(int argc, char **argv)
{
    static const int sizes[] = { 500, 1000, 2000, 5000, 10000 };
    int frames = argc > 1 ? atoi(argv[1]) : 200;
    if (frames < 1) {
        fprintf(stderr, "usage: bench_broadphase [frames >= 1]\n");
        return 2;
    }
    double sap_5000 = -1;
    printf("broad phase, moving pile: radius 0.045-0.055 m in 2 x 2 x 1 m, random walk\n");
    printf("%6s  %-8s %6s %10s %10s %10s %10s\n", "n", "method", "frames", "first ms",
           "median ms", "p90 ms", "pairs");
    for (size_t s = 0; s < sizeof sizes / sizeof *sizes; s++) {
        int n = sizes[s];
        result all, sap;
        /* all pairs costs n^2/2 tests: cap it near 2 s per size */
        int fa = frames;
        long budget = 4000000000L / ((long)n * n);
        if (fa > budget)
            fa = budget < 10 ? 10 : (int)budget;
        if (fa > frames)
            fa = frames;
        if (run(SC_BROADPHASE_SPHERES, n, fa, &all) || run(SC_BROADPHASE_SAP, n, frames, &sap))
            return 1;
        for (int f = 0; f <= fa; f++)
            if (all.pairs[f] != sap.pairs[f]) {
                fprintf(stderr, "bench_broadphase: n %d frame %d: spheres %d pairs, SAP %d\n",
                        n, f, all.pairs[f], sap.pairs[f]);
                return 1;
            }
        printf("%6d  %-8s %6d %10.3f %10.3f %10.3f %10.0f\n", n, "spheres", all.frames,
               all.first_ms, all.median_ms, all.p90_ms, mean_pairs(&all, fa));
        printf("%6d  %-8s %6d %10.3f %10.3f %10.3f %10.0f\n", n, "sap", sap.frames,
               sap.first_ms, sap.median_ms, sap.p90_ms, mean_pairs(&sap, fa));
        free(all.pairs);
        free(sap.pairs);
        if (n == 5000)
            sap_5000 = sap.median_ms;
    }
    printf("5000 bodies with SAP: median %.3f ms per frame: %s the 1 ms budget\n", sap_5000,
           sap_5000 < 1 ? "within" : "OVER");
    return 0;
}
