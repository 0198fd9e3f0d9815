/* bench_pieces.c - the narrow phase of the paper's parts as triangle meshes
 * against the same meshes as convex pieces (sc_shape_mesh_pieces(); the
 * bolt is 2 pieces, the nut 16): time per pair query, how many queries
 * find contacts, and how the two agree.
 *
 * Queries (seeded, the same on every run): a at the origin and b on a
 * random side, both turned at random, b's centre 0.65 to 1.0 summed
 * bounding radii from a's, so that the bounding spheres overlap (what the
 * broad phase passes on) and about half the pairs touch, many deeply; then
 * shallow ones, b moved along the same kind of line until the solids (the
 * pieces) just touch and then 0.5 mm in, the depths a frame works at. Each query is
 * sc_np_collide() on one thread's context, as a COLLIDE unit runs it; the
 * trimesh pairs take ODE's trimesh lock, uncontended here. Per query: the
 * median (and minimum) over the runs of one run's time over all queries,
 * CLOCK_MONOTONIC.
 *
 * Agreement: queries where one finds contacts and the other none, and for
 * queries where both do, the median and largest difference of their
 * deepest depths and the smallest cosine between their deepest contacts'
 * normals (the
 * representations differ: a trimesh pair reports where triangles cross,
 * pieces where solids overlap; the nut's hole is the same 16-gon).
 *
 * usage: bench_pieces [-r runs] [-n queries] [-s seed] */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "vecmath.h"

#include "bench_util.h"

#define MAXQ 20000
#define MAXR 51

static unsigned long long seed = 1;

static double rnd(void)
{
    return bench_rnd(&seed);
}

static void rnd_quat(double q[4])
{
    for (int i = 0; i < 4; i++)
        q[i] = rnd();
    q_normalize(q);
}

typedef struct shapes {
    const char *name;
    sc_shape *pieces, *mesh;  /* the same mesh, with and without pieces */
} shapes;

typedef struct query {
    sc_pose a, b;
} query;

/* The same mesh without its pieces. */
static sc_shape *plain(const sc_shape *s)
{
    const double *xyz;
    const int *tri;
    int nv, nt;
    if (sc_shape_mesh_data(s, &xyz, &nv, &tri, &nt) != SC_OK)
        return NULL;
    return sc_shape_mesh(xyz, nv, tri, nt);
}

/* a and b turned at random, both at the origin; u: a random direction. */
static void random_query(query *q, double u[3])
{
    do {
        v3_set(u, rnd(), rnd(), rnd());
    } while (v3_len(u) < 0.1 || v3_len(u) > 1);
    v3_normalize(u);
    memset(q, 0, sizeof *q);
    rnd_quat(q->a.quat);
    rnd_quat(q->b.quat);
}

/* The deepest contact's depth of a and b at q (0 when apart). */
static double depth_at(sc_np_ctx *ctx, const sc_shape *a, const sc_shape *b, const query *q)
{
    sc_contact c[SC_MAX_PAIR_CONTACTS];
    int k = sc_np_collide(ctx, a, &q->a, b, &q->b, c, SC_MAX_PAIR_CONTACTS);
    double d = 0;
    for (int i = 0; i < k; i++)
        d = fmax(d, c[i].depth);
    return d;
}

/* Shallow queries: as make_queries(), then b moved along its direction
 * until the solids (the pieces) just touch, and 0.5 mm further in: the
 * depths a frame's contacts have. */
static void make_shallow(sc_np_ctx *ctx, const sc_shape *a, const sc_shape *b, query *q, int n)
{
    for (int i = 0; i < n; i++) {
        double u[3];
        random_query(&q[i], u);
        double lo = 0, hi = a->bound_r + b->bound_r;   /* touching at lo, apart at hi */
        for (int it = 0; it < 40; it++) {
            double mid = 0.5 * (lo + hi);
            v3_scale(q[i].b.pos, u, mid);
            if (depth_at(ctx, a, b, &q[i]) > 0)
                lo = mid;
            else
                hi = mid;
        }
        v3_scale(q[i].b.pos, u, hi - 0.5e-3);
    }
}

static void make_queries(const sc_shape *a, const sc_shape *b, query *q, int n)
{
    for (int i = 0; i < n; i++) {
        double u[3];
        random_query(&q[i], u);
        v3_scale(q[i].b.pos, u, (a->bound_r + b->bound_r) * (0.65 + 0.35 * rnd()));
    }
}

typedef struct figures {
    double us_med, us_min;
    int hits;
} figures;

/* Times n queries of (a, b), runs times; contacts of the last run to c
 * (SC_MAX_PAIR_CONTACTS a query), counts to k. */
static figures run(sc_np_ctx *ctx, const sc_shape *a, const sc_shape *b, const query *q, int n,
                   int runs, sc_contact *c, int *k)
{
    double t[MAXR];
    figures f = { 0 };
    for (int r = 0; r < runs; r++) {
        double t0 = now_s();
        for (int i = 0; i < n; i++)
            k[i] = sc_np_collide(ctx, a, &q[i].a, b, &q[i].b, &c[i * SC_MAX_PAIR_CONTACTS],
                                 SC_MAX_PAIR_CONTACTS);
        t[r] = (now_s() - t0) / n * 1e6;
    }
    qsort(t, (size_t)runs, sizeof *t, cmp_double);
    f.us_med = t[runs / 2];
    f.us_min = t[0];
    for (int i = 0; i < n; i++) {
        if (k[i] < 0) {
            fprintf(stderr, "bench_pieces: query %d: %s\n", i, sc_strerror(k[i]));
            exit(1);
        }
        f.hits += k[i] > 0;
    }
    return f;
}

static int deepest(const sc_contact *c, int k)
{
    int d = 0;
    for (int i = 1; i < k; i++)
        if (c[i].depth > c[d].depth)
            d = i;
    return d;
}

int main(int argc, char **argv)
{
    int runs = 7, n = 2000, opt;
    while ((opt = getopt(argc, argv, "r:n:s:")) != -1) {
        if (opt == 'r')
            runs = atoi(optarg);
        else if (opt == 'n')
            n = atoi(optarg);
        else if (opt == 's')
            seed = strtoull(optarg, NULL, 10);
        else {
            fprintf(stderr, "usage: bench_pieces [-r runs] [-n queries] [-s seed]\n");
            return 2;
        }
    }
    if (runs < 1 || runs > MAXR || n < 1 || n > MAXQ) {
        fprintf(stderr, "bench_pieces: runs 1..%d, queries 1..%d\n", MAXR, MAXQ);
        return 2;
    }
    shapes bolt = { "bolt", sc_shape_bolt(), NULL }, nut = { "nut", sc_shape_nut(), NULL };
    bolt.mesh = plain(bolt.pieces);
    nut.mesh = plain(nut.pieces);
    sc_shape *box = sc_shape_box(0.02, 0.02, 0.02);
    sc_np_ctx *ctx = sc_np_create();
    query *q = malloc((size_t)n * sizeof *q);
    sc_contact *cm = malloc((size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *cm);
    sc_contact *cp = malloc((size_t)n * SC_MAX_PAIR_CONTACTS * sizeof *cp);
    int *km = malloc((size_t)n * sizeof *km), *kp = malloc((size_t)n * sizeof *kp);
    if (!bolt.mesh || !nut.mesh || !box || !ctx || !q || !cm || !cp || !km || !kp) {
        fprintf(stderr, "bench_pieces: out of memory\n");
        return 1;
    }
    struct {
        const char *name;
        const shapes *a, *b;
        sc_shape *other;          /* b when not a part */
    } pairs[] = {
        { "bolt-nut", &bolt, &nut, NULL }, { "nut-nut", &nut, &nut, NULL },
        { "bolt-bolt", &bolt, &bolt, NULL }, { "nut-box", &nut, NULL, box },
        { "bolt-box", &bolt, NULL, box },
    };
    printf("narrow phase of the paper's parts: triangle meshes against convex pieces "
           "(bolt 2, nut 16)\n%d queries a pair, seed %llu, median (min) of %d runs, one "
           "thread\n",
           n, (unsigned long long)seed, runs);
    for (int shallow = 0; shallow < 2; shallow++) {
        printf("%s\n", shallow ? "shallow: b moved until the solids touch, then 0.5 mm in"
                               : "overlapping bounding spheres (what the broad phase passes)");
        printf("  %-10s %16s %16s %8s %7s %7s %9s %17s %9s\n", "pair", "trimesh us/query",
               "pieces us/query", "speedup", "hits tm", "hits pc", "one only",
               "depth diff med/max", "min cos");
        for (size_t p = 0; p < sizeof pairs / sizeof *pairs; p++) {
            const sc_shape *am = pairs[p].a->mesh, *ap = pairs[p].a->pieces;
            const sc_shape *bm = pairs[p].b ? pairs[p].b->mesh : pairs[p].other;
            const sc_shape *bp = pairs[p].b ? pairs[p].b->pieces : pairs[p].other;
            if (shallow)
                make_shallow(ctx, ap, bp, q, n);
            else
                make_queries(ap, bp, q, n);
            figures fm = run(ctx, am, bm, q, n, runs, cm, km);
            figures fp = run(ctx, ap, bp, q, n, runs, cp, kp);
            int one = 0, nd = 0;
            double ddiff = 0, mincos = 1, *dd = malloc((size_t)n * sizeof *dd);
            if (!dd) {
                fprintf(stderr, "bench_pieces: out of memory\n");
                return 1;
            }
            for (int i = 0; i < n; i++) {
                if ((km[i] > 0) != (kp[i] > 0)) {
                    one++;
                    continue;
                }
                if (km[i] == 0)
                    continue;
                const sc_contact *x = &cm[i * SC_MAX_PAIR_CONTACTS], *y = &cp[i * SC_MAX_PAIR_CONTACTS];
                const sc_contact *a = &x[deepest(x, km[i])], *b = &y[deepest(y, kp[i])];
                ddiff = fmax(ddiff, fabs(a->depth - b->depth));
                dd[nd++] = fabs(a->depth - b->depth);
                mincos = fmin(mincos, v3_dot(a->normal, b->normal));
            }
            qsort(dd, (size_t)nd, sizeof *dd, cmp_double);
            double dmed = nd ? dd[nd / 2] : 0;
            free(dd);
            printf("  %-10s %9.2f (%5.2f) %9.2f (%5.2f) %7.2fx %7d %7d %9d %6.2f/%6.2f mm %9.3f\n",
                   pairs[p].name, fm.us_med, fm.us_min, fp.us_med, fp.us_min,
                   fp.us_med > 0 ? fm.us_med / fp.us_med : 0, fm.hits, fp.hits, one,
                   1e3 * dmed, 1e3 * ddiff, mincos);
        }
    }
    free(kp);
    free(km);
    free(cp);
    free(cm);
    free(q);
    sc_np_destroy(ctx);
    sc_shape_release(box);
    sc_shape_release(bolt.pieces);
    sc_shape_release(bolt.mesh);
    sc_shape_release(nut.pieces);
    sc_shape_release(nut.mesh);
    return 0;
}
