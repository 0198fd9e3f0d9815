/*
 * broadphase.c - step 4 (coarse): which pairs of bounding spheres overlap
 * (docs/DESIGN.md 3.2). Two methods give the same set, sorted by (a, b),
 * bit for bit: the paper's all-pairs test (SC_BROADPHASE_SPHERES) and a
 * sweep and prune over rows of power-of-two levels that keeps its order
 * between frames (SC_BROADPHASE_SAP). Both call one inline predicate,
 * |c_a - c_b| <= r_a + r_b on the same bits, and the pruning's slack keeps
 * every pair it accepts; with a task runner the sweeps are shared tasks
 * whose output does not depend on who ran them.
 */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"

/* The predicate must round the same way in both methods: IEEE arithmetic
 * and no contraction into FMA (GCC has it off in ISO mode, -std=c11; other
 * modes and clang get it switched off here). */
#ifdef __FAST_MATH__
#error "broadphase.c needs IEEE arithmetic: build it without -ffast-math"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__) && !defined(__STRICT_ANSI__)
#pragma GCC optimize("fp-contract=off")
#endif

/* Largest |coordinate| or radius accepted: no square or sum in the
 * predicate overflows below it. */
#define SC_BP_LIMIT 1e150
/* AUTO: all pairs below this many bodies, sweep and prune from it on. */
#define SC_BP_AUTO_SAP_MIN 256

/* Shared sweeps: from this many bodies on, a sweep with a runner is cut
 * into BP_CHUNKS tasks per kind (the frame's shared work's, core.h). */
#define BP_SHARE_MIN SC_SHARE_MIN
#define BP_CHUNKS SC_SHARE_CHUNKS

/* Slack of the pruning tests, so that they never drop a pair the predicate
 * accepts. The sweep interval is [x - r - m, x + r + m], m = BP_MARGIN_REL
 * (|x| + r) + BP_SLACK_ABS: two computed intervals that are disjoint are
 * apart by more than any rounding of the predicate. The level's diameter
 * is 2r (1 + BP_DIAM_REL) + BP_SLACK_ABS and the cell index an exact
 * scaling, so an accepted pair's cells differ by at most 1. */
#define BP_MARGIN_REL 1e-14
#define BP_SLACK_ABS 1e-140
#define BP_DIAM_REL 1e-12

/* Cell indices are clamped to +-BP_CELL_MAX so that index +- 1 plus
 * BP_CELL_OFF fits 27 bits; the level (L + BP_LEVEL_OFF) takes the top 10. */
#define BP_CELL_BITS 27
#define BP_CELL_OFF (1 << 26)
#define BP_CELL_MAX ((1 << 26) - 2)
#define BP_LEVEL_OFF 512
#define BP_LEVEL_SHIFT 54

typedef struct bp_entry {
    uint64_t row;             /* level, then row cell: see row_key() */
    double lo;                /* sweep interval start */
    int id;                   /* body */
} bp_entry;

/* A body in sweep order, with what the candidate test reads in one line. */
typedef struct bp_slot {
    double lo;                /* sweep interval start (= the entry's) */
    double c[3], r;           /* copies of the caller's centre and radius */
    int id;                   /* body */
    int act;                  /* 0 or 1 */
} bp_slot;

/* The pairs one sweep task found (in sweep order). */
typedef struct bp_out {
    sc_pair *p;
    int n, cap;
    int rc;                   /* SC_OK or SC_ENOMEM */
} bp_out;

/* The candidate loop is inlined into its three callers: it is the sweeps'
 * innermost loop. */
#if defined(__GNUC__)
#define BP_INLINE static inline __attribute__((always_inline))
#else
#define BP_INLINE static inline
#endif

struct sc_broadphase {
    int n;                    /* bodies in ent[] (0: no order kept yet) */
    int cap;                  /* capacity of the per-body arrays */
    int axis;                 /* sweep axis; rows over the other two */
    bp_entry *ent, *ent_tmp;  /* sorted order, merge-sort scratch */
    bp_slot *slot;            /* the bodies in sorted order */
    double *hi;               /* per slot: sweep interval end */
    /* rows: key and first slot (row R: sentinels) */
    uint64_t *rkey;
    int *rstart, nrows;
    /* levels: first row, exponent, widest sweep interval */
    int *lrow, *lexp, nlevels;
    double *lwidth;
    int *count;               /* radix sort of the output, n + 1 */
    sc_pair *tmp;             /* radix sort scratch */
    int tmp_cap;
    /* the sweep in tasks (sweep_task()): nchunk tasks over the
     * same-level rows, then nchunk over each pair of levels, each with
     * its own output */
    int nchunk;
    bp_out *chunk;
    int chunk_cap;
    /* output while a call runs */
    sc_pair **out;
    int *out_cap, nout;
    /* the last sweep's input and output, for a call that moves few
     * bodies (find_moved_pairs()) */
    int last_n;                    /* 0: none (per-body arrays: cap) */
    double *last_c, *last_r;
    unsigned char *last_act, *moved;
    sc_pair *last, *fresh;
    int nlast, last_pair_cap, fresh_cap;
    /* the candidate list ("Candidates within a skin" below): the pairs of
     * spheres grown by their skins, and each body's centre, radius, skin
     * and activity when it was made */
    int list_n;                    /* 0: none (per-body arrays: cap) */
    int list_calls;                /* calls since sc_bp_list_drop() */
    long list_reused;              /* calls answered from a list kept */
    double *list_c, *list_r, *list_skin, *list_grown;
    unsigned char *list_act;
    sc_pair *list;
    int nlist, list_cap;
};

/* The predicate of the contract; every method goes through it. */
static inline int spheres_overlap(double xa, double ya, double za, double ra, double xb,
                                  double yb, double zb, double rb)
{
    double dx = xb - xa, dy = yb - ya, dz = zb - za;
    double s = ra + rb;
    return dx * dx + dy * dy + dz * dz <= s * s;
}

/* Makes room for one more pair in the caller's array. */
static int grow_pairs(sc_broadphase *bp)
{
    return sc_grow((void **)bp->out, bp->out_cap, bp->nout + 1, sizeof **bp->out, INT_MAX)
               ? SC_ENOMEM
               : SC_OK;
}

/* ---- input ---- */

static int valid_body(const double *c, double r)
{
    for (int k = 0; k < 3; k++)
        if (!(fabs(c[k]) <= SC_BP_LIMIT))     /* also NaN */
            return 0;
    return r >= 0 && r <= SC_BP_LIMIT;
}

/* Checks every body; var gets each axis' variance (for the sweep axis). */
static int check_bodies(const double *c, const double *r, int n, double var[3])
{
    double s[3] = { 0, 0, 0 }, s2[3] = { 0, 0, 0 };
    for (int i = 0; i < n; i++) {
        if (!valid_body(&c[3 * i], r[i]))
            return SC_EINVAL;
        for (int k = 0; k < 3; k++) {
            double d = c[3 * i + k] - c[k];   /* shifted: less cancellation */
            s[k] += d;
            s2[k] += d * d;
        }
    }
    for (int k = 0; k < 3; k++)
        var[k] = n ? s2[k] / n - (s[k] / n) * (s[k] / n) : 0;
    return SC_OK;
}

/* ---- the paper's all pairs ---- */

static int find_all_pairs(sc_broadphase *bp, const double *c, const double *r,
                          const unsigned char *active, int n)
{
    for (int a = 0; a < n; a++) {
        const double *ca = &c[3 * a];
        int act_a = !active || active[a];
        for (int b = a + 1; b < n; b++) {
            if (!act_a && !active[b])
                continue;
            const double *cb = &c[3 * b];
            if (!spheres_overlap(ca[0], ca[1], ca[2], r[a], cb[0], cb[1], cb[2], r[b]))
                continue;
            if (grow_pairs(bp))
                return SC_ENOMEM;
            (*bp->out)[bp->nout++] = (sc_pair){ a, b };   /* already in order */
        }
    }
    return SC_OK;
}

/* ---- sweep and prune: keys and order ---- */

static int reserve_bodies(sc_broadphase *bp, int n)
{
    if (n <= bp->cap)
        return SC_OK;
    size_t cap = (size_t)n > (size_t)bp->cap * 2 ? (size_t)n : (size_t)bp->cap * 2;
    if (cap > (size_t)INT_MAX - 1)
        cap = (size_t)INT_MAX - 1;
    /* each array keeps its contents; cap is raised only once all grew */
#define BP_GROW(f, k, m) do {                                           \
        void *p_ = realloc(bp->f, ((k) * cap + (m)) * sizeof *bp->f);  \
        if (!p_)                                                        \
            return SC_ENOMEM;                                           \
        bp->f = p_;                                                     \
    } while (0)
    BP_GROW(ent, 1, 0);
    BP_GROW(ent_tmp, 1, 0);
    BP_GROW(slot, 1, 0);
    BP_GROW(hi, 1, 0);
    BP_GROW(rkey, 1, 1);
    BP_GROW(rstart, 1, 1);
    BP_GROW(lrow, 1, 1);
    BP_GROW(lexp, 1, 1);
    BP_GROW(lwidth, 1, 1);
    BP_GROW(count, 1, 1);
    BP_GROW(last_c, 3, 0);
    BP_GROW(last_r, 1, 0);
    BP_GROW(last_act, 1, 0);
    BP_GROW(moved, 1, 0);
    BP_GROW(list_c, 3, 0);
    BP_GROW(list_r, 1, 0);
    BP_GROW(list_skin, 1, 0);
    BP_GROW(list_grown, 1, 0);
    BP_GROW(list_act, 1, 0);
#undef BP_GROW
    bp->cap = (int)cap;
    return SC_OK;
}

/* The padded diameter of a body of radius r, and its level: the smallest L
 * with 2^L >= it. */
static inline double level_diameter(double r)
{
    return 2 * r * (1 + BP_DIAM_REL) + BP_SLACK_ABS;
}

static int level_of(double d)
{
    int e;
    double m = frexp(d, &e);
    return m == 0.5 ? e - 1 : e;
}

/* floor(u * scale) clamped; scale = 2^-L makes the product exact. Clamping
 * first (the same result: the bounds are integers) lets a truncating
 * conversion do the floor without a libm call. */
static inline int64_t cell_of(double u, double scale)
{
    double q = u * scale;
    if (q < -BP_CELL_MAX)
        q = -BP_CELL_MAX;
    if (q > BP_CELL_MAX)
        q = BP_CELL_MAX;
    int64_t t = (int64_t)q;
    return t - ((double)t > q);
}

static inline uint64_t row_key(int level, int64_t iu, int64_t iv)
{
    return (uint64_t)(level + BP_LEVEL_OFF) << BP_LEVEL_SHIFT |
           (uint64_t)(iu + BP_CELL_OFF) << BP_CELL_BITS | (uint64_t)(iv + BP_CELL_OFF);
}

static inline int ent_less(const bp_entry *a, const bp_entry *b)
{
    return a->row < b->row || (a->row == b->row && a->lo < b->lo);
}

/* Sweep interval start along the axis, with the pruning margin. */
static inline double sweep_margin(double x, double r)
{
    return BP_MARGIN_REL * (fabs(x) + r) + BP_SLACK_ABS;
}

/* Recomputes every entry's key from the current positions, order kept. */
static void update_keys(sc_broadphase *bp, const double *c, const double *r)
{
    int ax = bp->axis, ua = (ax + 1) % 3, va = (ax + 2) % 3;
    double d_lo = 0, d_hi = -1, scale = 0;    /* level holds (d_lo, d_hi] */
    int level = 0;
    for (int k = 0; k < bp->n; k++) {
        bp_entry *e = &bp->ent[k];
        const double *ci = &c[3 * e->id];
        double ri = r[e->id], d = level_diameter(ri);
        if (!(d > d_lo && d <= d_hi)) {     /* neighbours mostly share it */
            level = level_of(d);
            d_hi = ldexp(1.0, level);
            d_lo = 0.5 * d_hi;
            scale = ldexp(1.0, -level);
        }
        e->row = row_key(level, cell_of(ci[ua], scale), cell_of(ci[va], scale));
        e->lo = (ci[ax] - ri) - sweep_margin(ci[ax], ri);
    }
}

/* Insertion sort that gives up after budget moves (order then still a
 * permutation); 1 if sorted. */
static int insertion_sort(bp_entry *e, int n, long budget)
{
    long moves = 0;
    for (int i = 1; i < n; i++) {
        if (!ent_less(&e[i], &e[i - 1]))
            continue;
        bp_entry t = e[i];
        int j = i;
        do {
            e[j] = e[j - 1];
            j--;
        } while (j > 0 && ent_less(&t, &e[j - 1]));
        e[j] = t;
        moves += i - j;
        if (moves > budget)
            return 0;
    }
    return 1;
}

/* Bottom-up stable merge sort into e, tmp as scratch (no allocation). */
static void merge_sort(bp_entry *e, bp_entry *tmp, int n)
{
    bp_entry *src = e, *dst = tmp;
    for (int w = 1; w < n; w *= 2) {
        for (int lo = 0; lo < n; lo += 2 * w) {
            int mid = lo + w < n ? lo + w : n;
            int hi = mid + w < n ? mid + w : n;
            int i = lo, j = mid, k = lo;
            while (i < mid && j < hi)
                dst[k++] = ent_less(&src[j], &src[i]) ? src[j++] : src[i++];
            while (i < mid)
                dst[k++] = src[i++];
            while (j < hi)
                dst[k++] = src[j++];
        }
        bp_entry *t = src;
        src = dst;
        dst = t;
    }
    if (src != e)
        memcpy(e, src, (size_t)n * sizeof *e);
}

/* Keeps the previous order for the ids that still exist, appends new ones,
 * picks the sweep axis, recomputes the keys and repairs the order. */
static void update_order(sc_broadphase *bp, const double *c, const double *r, int n,
                         const double var[3])
{
    int best = var[1] > var[0] ? 1 : 0;
    best = var[2] > var[best] ? 2 : best;
    int full = bp->n == 0 || var[best] > 2 * var[bp->axis];
    if (full)
        bp->axis = best;
    if (n < bp->n) {
        int k = 0;
        for (int i = 0; i < bp->n; i++)
            if (bp->ent[i].id < n)
                bp->ent[k++] = bp->ent[i];
    } else {
        if (n - bp->n > n / 4)
            full = 1;
        for (int i = bp->n; i < n; i++)
            bp->ent[i].id = i;
    }
    bp->n = n;
    update_keys(bp, c, r);
    if (full || !insertion_sort(bp->ent, n, 2L * n + 64))
        merge_sort(bp->ent, bp->ent_tmp, n);
}

/* Lays the sorted bodies out by slot and builds the row and level tables. */
static void build_tables(sc_broadphase *bp, const double *c, const double *r,
                         const unsigned char *active)
{
    int n = bp->n, ax = bp->axis, nr = 0, nl = 0;
    for (int k = 0; k < n; k++) {
        const bp_entry *e = &bp->ent[k];
        int i = e->id;
        double x = c[3 * i + ax];
        bp_slot *sl = &bp->slot[k];
        sl->lo = e->lo;
        sl->c[0] = c[3 * i];
        sl->c[1] = c[3 * i + 1];
        sl->c[2] = c[3 * i + 2];
        sl->r = r[i];
        sl->id = i;
        sl->act = !active || active[i];
        bp->hi[k] = (x + r[i]) + sweep_margin(x, r[i]);
        if (k == 0 || e->row != bp->ent[k - 1].row) {
            if (k == 0 || e->row >> BP_LEVEL_SHIFT != bp->ent[k - 1].row >> BP_LEVEL_SHIFT) {
                bp->lrow[nl] = nr;
                bp->lexp[nl] = (int)(e->row >> BP_LEVEL_SHIFT) - BP_LEVEL_OFF;
                bp->lwidth[nl] = 0;
                nl++;
            }
            bp->rkey[nr] = e->row;
            bp->rstart[nr] = k;
            nr++;
        }
        double w = bp->hi[k] - e->lo;
        if (w > bp->lwidth[nl - 1])
            bp->lwidth[nl - 1] = w;
    }
    bp->rkey[nr] = UINT64_MAX;
    bp->rstart[nr] = n;
    bp->lrow[nl] = nr;
    bp->nrows = nr;
    bp->nlevels = nl;
}

/* ---- sweep and prune: the sweeps ---- */

/* Slot i against slots k0, k0 + 1, ... < k1 as long as their intervals start
 * by the end of i's: the activity and exact tests. The hot loop of the broad
 * phase, so without branches on the outcome (a mispredicted branch costs
 * more than a test): every candidate is written, only hits are kept. */
BP_INLINE int scan(const sc_broadphase *bp, bp_out *o, int i, int k0, int k1)
{
    const bp_slot *restrict sl = bp->slot;
    double h = bp->hi[i], xi = sl[i].c[0], yi = sl[i].c[1], zi = sl[i].c[2], ri = sl[i].r;
    int idi = sl[i].id, ai = sl[i].act;
    sc_pair *out = o->p;
    int nout = o->n, cap = o->cap;
    for (int k = k0; k < k1 && sl[k].lo <= h; k++) {
        if (nout == cap) {
            if (sc_grow((void **)&o->p, &o->cap, nout + 1, sizeof *o->p, INT_MAX))
                return SC_ENOMEM;
            out = o->p;
            cap = o->cap;
        }
        const bp_slot *o = &sl[k];
        int hit = (ai | o->act) &
                  spheres_overlap(xi, yi, zi, ri, o->c[0], o->c[1], o->c[2], o->r);
        int b = o->id;
        out[nout].a = idi < b ? idi : b;
        out[nout].b = idi < b ? b : idi;
        nout += hit;
    }
    o->n = nout;
    return SC_OK;
}

/* Pairs within one row whose sweep intervals overlap. */
static int sweep_self(const sc_broadphase *bp, bp_out *o, int i0, int i1)
{
    for (int i = i0; i < i1; i++)
        if (scan(bp, o, i, i + 1, i1))
            return SC_ENOMEM;
    return SC_OK;
}

/* Where a scan for an interval starting at lo may start: intervals that
 * start before lo - ((1 + 1e-9) width + 1e-15 |lo|), width the widest of
 * them, end before lo (the two slack terms cover the rounding of the
 * widths and of the subtraction). */
static inline double window_start(double lo, double width)
{
    return lo - ((1 + 1e-9) * width + 1e-15 * fabs(lo));
}

/* Pairs across two rows whose sweep intervals overlap: each body of the
 * first row scans the second from where an interval could still reach it.
 * Cheaper than merging the two lists, where both sides scan: half the scans,
 * and a scan's end is a mispredicted branch. The cursor only moves forward:
 * what ends before lo_i ends before every later lo. */
static int sweep_two(const sc_broadphase *bp, bp_out *o, int i0, int i1, int j0, int j1,
                     double width)
{
    const bp_slot *sl = bp->slot;
    int c = j0;
    for (int i = i0; i < i1; i++) {
        double from = window_start(sl[i].lo, width);
        while (c < j1 && sl[c].lo < from)
            c++;
        if (c == j1)
            break;
        if (scan(bp, o, i, c, j1))
            return SC_ENOMEM;
    }
    return SC_OK;
}

/* First row in [r0, r1) with key >= key. */
static int find_row(const uint64_t *rkey, int r0, int r1, uint64_t key)
{
    while (r0 < r1) {
        int m = r0 + (r1 - r0) / 2;
        if (rkey[m] < key)
            r0 = m + 1;
        else
            r1 = m;
    }
    return r0;
}

/* Same-level pairs of rows [a0, a1): each row with itself and its forward
 * neighbours (iu, iv+1), (iu+1, iv-1), (iu+1, iv), (iu+1, iv+1); the
 * other four neighbours see this row as theirs. Neighbour keys grow with
 * the row key, so four cursors, found for the first row, walk the row
 * table once. */
static int sweep_levels(const sc_broadphase *bp, bp_out *o, int a0, int a1)
{
    if (a0 >= a1)
        return SC_OK;
    const uint64_t du = (uint64_t)1 << BP_CELL_BITS;
    const uint64_t step[4] = { 1, du - 1, du, du + 1 };
    const uint64_t *rkey = bp->rkey;
    const int *rs = bp->rstart;
    int cur[4], li = 0;
    while (bp->lrow[li + 1] <= a0)
        li++;
    for (int t = 0; t < 4; t++)
        cur[t] = find_row(rkey, a0, bp->nrows, rkey[a0] + step[t]);
    for (int a = a0; a < a1; a++) {
        if (a == bp->lrow[li + 1])
            li++;
        int rc = sweep_self(bp, o, rs[a], rs[a + 1]);
        for (int t = 0; t < 4 && !rc; t++) {
            uint64_t want = rkey[a] + step[t];
            while (rkey[cur[t]] < want)
                cur[t]++;
            if (rkey[cur[t]] == want)
                rc = sweep_two(bp, o, rs[a], rs[a + 1], rs[cur[t]], rs[cur[t] + 1],
                               bp->lwidth[li]);
        }
        if (rc)
            return rc;
    }
    return SC_OK;
}

/* First slot in [s0, s1) with lo >= x. */
static int find_slot(const bp_slot *sl, int s0, int s1, double x)
{
    while (s0 < s1) {
        int m = s0 + (s1 - s0) / 2;
        if (sl[m].lo < x)
            s0 = m + 1;
        else
            s1 = m;
    }
    return s0;
}

/* The same slot as find_slot(), walked from c, the answer for the last
 * body of the same row: the bodies of a row come in order of lo, so it
 * is a step or two away (a step back too, should rounding ever make
 * window_start() fall). */
static inline int walk_slot(const bp_slot *sl, int s0, int s1, int c, double x)
{
    while (c > s0 && !(sl[c - 1].lo < x))
        c--;
    while (c < s1 && sl[c].lo < x)
        c++;
    return c;
}

/* Pairs between the bodies in slots [k0, k1) (of a finer level) and the
 * coarser level lj: each scans the 3 x 3 rows of lj around its cell (lj's
 * cells are at least twice the finer level's diameters, so that holds
 * every partner). */
static int sweep_cross(const sc_broadphase *bp, bp_out *o, int lj, int k0, int k1)
{
    int ua = (bp->axis + 1) % 3, va = (bp->axis + 2) % 3;
    int level = bp->lexp[lj], r0 = bp->lrow[lj], r1 = bp->lrow[lj + 1];
    double scale = ldexp(1.0, -level), width = bp->lwidth[lj];
    const bp_slot *sl = bp->slot;
    int row_lo[9], row_hi[9], cur[9], nr = 0;
    int64_t last_u = INT64_MIN, last_v = INT64_MIN;
    for (int k = k0; k < k1; k++) {
        int64_t iu = cell_of(sl[k].c[ua], scale), iv = cell_of(sl[k].c[va], scale);
        int fresh = iu != last_u || iv != last_v;
        if (fresh) {                             /* bodies of a row share it */
            last_u = iu;
            last_v = iv;
            nr = 0;
            for (int du = -1; du <= 1; du++) {
                uint64_t key = row_key(level, iu + du, iv - 1);
                int a = find_row(bp->rkey, r0, r1, key);
                for (; a < r1 && bp->rkey[a] <= key + 2; a++) {
                    row_lo[nr] = bp->rstart[a];
                    row_hi[nr++] = bp->rstart[a + 1];
                }
            }
        }
        double from = window_start(sl[k].lo, width);
        for (int t = 0; t < nr; t++) {
            if (fresh)
                cur[t] = find_slot(sl, row_lo[t], row_hi[t], from);
            else
                cur[t] = walk_slot(sl, row_lo[t], row_hi[t], cur[t], from);
            if (scan(bp, o, k, cur[t], row_hi[t]))
                return SC_ENOMEM;
        }
    }
    return SC_OK;
}

/* The tasks' pairs into the caller's array, sorted by (a, b): counting
 * sort by b from the tasks' outputs, then stable by a. */
static int sort_pairs(sc_broadphase *bp, int n, int ntasks)
{
    int np = 0;
    for (int t = 0; t < ntasks; t++) {
        if (bp->chunk[t].n > INT_MAX - np)
            return SC_ENOMEM;
        np += bp->chunk[t].n;
    }
    if (sc_grow((void **)bp->out, bp->out_cap, np, sizeof **bp->out, INT_MAX) ||
        sc_grow((void **)&bp->tmp, &bp->tmp_cap, np, sizeof *bp->tmp, INT_MAX))
        return SC_ENOMEM;
    sc_pair *p = *bp->out, *t = bp->tmp;
    int *cnt = bp->count;
    memset(cnt, 0, ((size_t)n + 1) * sizeof *cnt);
    for (int k = 0; k < ntasks; k++)
        for (int i = 0; i < bp->chunk[k].n; i++)
            cnt[bp->chunk[k].p[i].b + 1]++;
    for (int i = 0; i < n; i++)
        cnt[i + 1] += cnt[i];
    for (int k = 0; k < ntasks; k++)
        for (int i = 0; i < bp->chunk[k].n; i++)
            t[cnt[bp->chunk[k].p[i].b]++] = bp->chunk[k].p[i];
    memset(cnt, 0, ((size_t)n + 1) * sizeof *cnt);
    for (int i = 0; i < np; i++)
        cnt[t[i].a + 1]++;
    for (int i = 0; i < n; i++)
        cnt[i + 1] += cnt[i];
    for (int i = 0; i < np; i++)
        p[cnt[t[i].a]++] = t[i];
    bp->nout = np;
    return SC_OK;
}

/* The first row of same-level task c of K: the rows are cut where the
 * slots are (slot n K / c on), so that tasks get about as many bodies. */
static int row_at(const sc_broadphase *bp, int c, int K)
{
    int target = (int)((long long)bp->n * c / K);
    int lo = 0, hi = bp->nrows;     /* rstart[nrows] = n */
    while (lo < hi) {
        int m = lo + (hi - lo) / 2;
        if (bp->rstart[m] < target)
            lo = m + 1;
        else
            hi = m;
    }
    return lo;
}

/* Sweep task t (an sc_task_fn over bp): same-level rows for t < nchunk,
 * else a share of one pair of levels' cross sweep. */
static void sweep_task(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    sc_broadphase *bp = arg;
    /* on a copy: tasks' outputs lie side by side, and writing them back
     * after every scan would pass their cache lines between threads */
    bp_out out = bp->chunk[t], *o = &out;
    int K = bp->nchunk, kind = t / K, c = t % K;
    o->n = 0;
    if (kind == 0) {
        o->rc = sweep_levels(bp, o, row_at(bp, c, K), row_at(bp, c + 1, K));
    } else {
        int li = 0, lj = 1;
        for (int x = kind - 1; x > 0; x--)
            if (++lj == bp->nlevels) {
                li++;
                lj = li + 1;
            }
        int s0 = bp->rstart[bp->lrow[li]], m = bp->rstart[bp->lrow[li + 1]] - s0;
        o->rc = sweep_cross(bp, o, lj, s0 + (int)((long long)m * c / K),
                            s0 + (int)((long long)m * (c + 1) / K));
    }
    bp->chunk[t] = out;
}

static int find_swept_pairs(sc_broadphase *bp, const sc_task_runner *runner, const double *c,
                            const double *r, const unsigned char *active, int n,
                            const double var[3])
{
    if (n < 2) {
        bp->n = 0;              /* nothing to sweep; start afresh next time */
        return SC_OK;
    }
    int rc = reserve_bodies(bp, n);
    if (rc)
        return rc;
    update_order(bp, c, r, n, var);
    build_tables(bp, c, r, active);
    bp->nchunk = runner && n >= BP_SHARE_MIN ? BP_CHUNKS : 1;
    int ntasks = bp->nchunk * (1 + bp->nlevels * (bp->nlevels - 1) / 2);
    int had = bp->chunk_cap;
    if (sc_grow((void **)&bp->chunk, &bp->chunk_cap, ntasks, sizeof *bp->chunk, INT_MAX))
        return SC_ENOMEM;
    if (bp->chunk_cap > had)
        memset(&bp->chunk[had], 0, (size_t)(bp->chunk_cap - had) * sizeof *bp->chunk);
    sc_tasks_run(bp->nchunk > 1 ? runner : NULL, sweep_task, bp, ntasks, NULL);
    for (int t = 0; t < ntasks; t++)
        if (bp->chunk[t].rc)
            return bp->chunk[t].rc;
    return sort_pairs(bp, n, ntasks);
}

/* Into bp->fresh, sorted: the pairs of each body i with flag[i] == want
 * against every body (two such once) that pass the predicate, one of
 * them active. The count, or SC_ENOMEM. */
static int flagged_pairs(sc_broadphase *bp, const double *c, const double *r,
                         const unsigned char *active, int n, const unsigned char *flag,
                         unsigned char want)
{
    int nf = 0;
    for (int i = 0; i < n; i++) {
        if (flag[i] != want)
            continue;
        int ai = !active || active[i];
        const double *ci = &c[3 * i];
        for (int j = 0; j < n; j++) {
            if (j == i || (j < i && flag[j] == want) || !(ai || active[j]))
                continue;
            const double *cj = &c[3 * j];
            if (!spheres_overlap(ci[0], ci[1], ci[2], r[i], cj[0], cj[1], cj[2], r[j]))
                continue;
            if (sc_grow((void **)&bp->fresh, &bp->fresh_cap, nf + 1, sizeof *bp->fresh, INT_MAX))
                return SC_ENOMEM;
            bp->fresh[nf++] = (sc_pair){ i < j ? i : j, i < j ? j : i };
        }
    }
    if (nf > 1)
        qsort(bp->fresh, (size_t)nf, sizeof *bp->fresh, sc_pair_cmp);
    return nf;
}

/* ---- sweep and prune: few moved ---- */

#define BP_FEW_MOVED 16        /* at most one body in this many moved */

/* The pairs when few bodies moved since the last sweep (a pile detected
 * again within its frame; docs/DESIGN.md 3.2): those of two unmoved bodies
 * are the last ones, each moved body is tested against every body, both
 * merged in order. 1 if done so (into the output), 0 if too many moved,
 * or a code. */
static int find_moved_pairs(sc_broadphase *bp, const double *c, const double *r,
                            const unsigned char *active, int n)
{
    if (bp->last_n != n || n < 2 * BP_FEW_MOVED)
        return 0;
    int k = 0;
    for (int i = 0; i < n; i++) {
        unsigned char act = !active || active[i];
        bp->moved[i] = memcmp(&c[3 * i], &bp->last_c[3 * i], 3 * sizeof *c) != 0 ||
                       memcmp(&r[i], &bp->last_r[i], sizeof *r) != 0 || act != bp->last_act[i];
        k += bp->moved[i];
        if (k * BP_FEW_MOVED > n)
            return 0;
    }
    /* the moved bodies' pairs, merged with the last pairs of two unmoved
     * bodies */
    int nf = flagged_pairs(bp, c, r, active, n, bp->moved, 1);
    if (nf < 0)
        return nf;
    int i = 0, j = 0;
    for (;;) {
        while (i < bp->nlast && (bp->moved[bp->last[i].a] || bp->moved[bp->last[i].b]))
            i++;
        if (i == bp->nlast && j == nf)
            break;
        int take_last = j == nf || (i < bp->nlast && sc_pair_cmp(&bp->last[i], &bp->fresh[j]) < 0);
        if (grow_pairs(bp))
            return SC_ENOMEM;
        (*bp->out)[bp->nout++] = take_last ? bp->last[i++] : bp->fresh[j++];
    }
    return 1;
}

/* This call's input and output, for the next. */
static int keep_last(sc_broadphase *bp, const double *c, const double *r,
                     const unsigned char *active, int n)
{
    bp->last_n = 0;
    if (n < 2 * BP_FEW_MOVED)
        return SC_OK;           /* find_moved_pairs() does not look */
    if (reserve_bodies(bp, n) ||
        sc_grow((void **)&bp->last, &bp->last_pair_cap, bp->nout, sizeof *bp->last, INT_MAX))
        return SC_ENOMEM;
    memcpy(bp->last_c, c, 3 * (size_t)n * sizeof *c);
    memcpy(bp->last_r, r, (size_t)n * sizeof *r);
    for (int i = 0; i < n; i++)
        bp->last_act[i] = !active || active[i];
    if (bp->nout > 0)
        memcpy(bp->last, *bp->out, (size_t)bp->nout * sizeof *bp->last);
    bp->nlast = bp->nout;
    bp->last_n = n;
    return SC_OK;
}

/* ---- within a superset ---- */

int sc_bp_pairs_within(sc_broadphase *bp, const sc_pair *cand, int ncand,
                       const unsigned char *inside, const double *c, const double *r,
                       const unsigned char *active, int n, sc_pair **pairs, int *cap)
{
    if (!bp || !pairs || !cap || !inside || n < 0 || ncand < 0 || (ncand > 0 && !cand) ||
        *cap < 0 || (*cap > 0 && !*pairs) || (n > 0 && (!c || !r)))
        return SC_EINVAL;
    double var[3];
    if (check_bodies(c, r, n, var))
        return SC_EINVAL;
    bp->out = pairs;
    bp->out_cap = cap;
    bp->nout = 0;
    /* the pairs of a body not inside, merged with the candidates of two
     * bodies inside that pass */
    int nf = flagged_pairs(bp, c, r, active, n, inside, 0);
    if (nf < 0)
        return nf;
    int i = 0, j = 0;
    for (;;) {
        while (i < ncand) {
            int a = cand[i].a, b = cand[i].b;
            if (a >= 0 && b > a && b < n && inside[a] && inside[b] &&
                (!active || active[a] || active[b]) &&
                spheres_overlap(c[3 * a], c[3 * a + 1], c[3 * a + 2], r[a], c[3 * b],
                                c[3 * b + 1], c[3 * b + 2], r[b]))
                break;
            i++;
        }
        if (i == ncand && j == nf)
            break;
        int take_cand = j == nf || (i < ncand && sc_pair_cmp(&cand[i], &bp->fresh[j]) < 0);
        if (grow_pairs(bp))
            return SC_ENOMEM;
        (*bp->out)[bp->nout++] = take_cand ? cand[i++] : bp->fresh[j++];
    }
    return bp->nout;
}

/* ---- API ---- */

int sc_pair_cmp(const void *x, const void *y)
{
    const sc_pair *a = x, *b = y;
    if (a->a != b->a)
        return (a->a > b->a) - (a->a < b->a);
    return (a->b > b->b) - (a->b < b->b);
}

sc_broadphase *sc_bp_create(void)
{
    sc_broadphase *bp = calloc(1, sizeof *bp);
    if (!bp)
        sc_set_error(SC_ENOMEM);
    return bp;
}

void sc_bp_destroy(sc_broadphase *bp)
{
    if (!bp)
        return;
    free(bp->list_c);
    free(bp->list_r);
    free(bp->list_skin);
    free(bp->list_grown);
    free(bp->list_act);
    free(bp->list);
    free(bp->ent);
    free(bp->ent_tmp);
    free(bp->slot);
    free(bp->hi);
    free(bp->rkey);
    free(bp->rstart);
    free(bp->lrow);
    free(bp->lexp);
    free(bp->lwidth);
    free(bp->count);
    free(bp->tmp);
    free(bp->last_c);
    free(bp->last_r);
    free(bp->last_act);
    free(bp->moved);
    free(bp->last);
    free(bp->fresh);
    for (int t = 0; t < bp->chunk_cap; t++)
        free(bp->chunk[t].p);
    free(bp->chunk);
    free(bp);
}

int sc_bp_find_pairs(sc_broadphase *bp, int method, const double *c, const double *r,
                     const unsigned char *active, int n, sc_pair **pairs, int *cap)
{
    return sc_bp_find_pairs_on(bp, NULL, method, c, r, active, n, pairs, cap);
}

int sc_bp_find_pairs_on(sc_broadphase *bp, const sc_task_runner *runner, int method,
                        const double *c, const double *r, const unsigned char *active, int n,
                        sc_pair **pairs, int *cap)
{
    if (!bp || !pairs || !cap || n < 0 || *cap < 0 || (*cap > 0 && !*pairs) ||
        (n > 0 && (!c || !r)))
        return SC_EINVAL;
    if (method == SC_BROADPHASE_AUTO)
        method = n < SC_BP_AUTO_SAP_MIN ? SC_BROADPHASE_SPHERES : SC_BROADPHASE_SAP;
    if (method != SC_BROADPHASE_SPHERES && method != SC_BROADPHASE_SAP)
        return SC_EINVAL;
    double var[3];
    if (check_bodies(c, r, n, var))
        return SC_EINVAL;
    bp->out = pairs;
    bp->out_cap = cap;
    bp->nout = 0;
    int rc;
    if (method == SC_BROADPHASE_SPHERES) {
        rc = find_all_pairs(bp, c, r, active, n);
    } else {
        rc = find_moved_pairs(bp, c, r, active, n);
        if (rc == 0) {
            bp->nout = 0;
            rc = find_swept_pairs(bp, runner, c, r, active, n, var);
        }
        if (rc >= 0 && keep_last(bp, c, r, active, n) != SC_OK)
            bp->last_n = 0;     /* only costs the next call a sweep */
        rc = rc < 0 ? rc : SC_OK;
    }
    if (rc < 0) {
        bp->n = 0;              /* a failed call may leave the order half done */
        bp->last_n = 0;
        return rc;
    }
    return bp->nout;
}

/* ---- candidates within a skin ----
 *
 * Within a frame the same bodies are detected again after every substep,
 * back-up and speculative round, and most have moved little. So a call
 * with skins keeps the pairs of the spheres grown by them (radius r + skin,
 * the same sweep) with the centres it made them at; a later call whose
 * bodies all moved less than their skins (less a relative 1e-9, more
 * than any rounding), with the same radii and activity, takes those
 * candidates that pass the contract's predicate on this call's spheres:
 * a pair that overlaps now was within r_a + r_b + |moved_a| + |moved_b|
 * then, so it is a candidate, and the output is the same set in the same
 * order as sc_bp_find_pairs_on() gives. Else the list is made again.
 * (docs/DESIGN.md 3.2) */

static int list_holds(const sc_broadphase *bp, const double *c, const double *r,
                      const unsigned char *active, int n)
{
    if (bp->list_n != n || n == 0)
        return 0;
    for (int i = 0; i < n; i++) {
        unsigned char act = !active || active[i];
        if (act != bp->list_act[i] || memcmp(&r[i], &bp->list_r[i], sizeof *r) != 0)
            return 0;
        const double *ci = &c[3 * i], *li = &bp->list_c[3 * i];
        double dx = ci[0] - li[0], dy = ci[1] - li[1], dz = ci[2] - li[2];
        double size = fabs(ci[0]) + fabs(ci[1]) + fabs(ci[2]) + r[i] + bp->list_skin[i];
        double room = bp->list_skin[i] - 1e-9 * (1 + size);
        double moved = dx * dx + dy * dy + dz * dz;
        if (moved != 0 && !(room > 0 && moved <= room * room))
            return 0;
    }
    return 1;
}

/* The kept list's candidates that pass this call's test, in chunks. */
typedef struct skin_filter {
    const sc_broadphase *bp;
    const double *c, *r;
    sc_pair *out;                   /* room for the whole list */
    int chunks;
    int count[BP_CHUNKS];           /* pairs each chunk wrote, from its start */
} skin_filter;

/* The first index of chunk t of n items cut into k. */
static int chunk_at(int n, int t, int k)
{
    return (int)((long long)n * t / k);
}

static void filter_task(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    skin_filter *f = arg;
    const sc_broadphase *bp = f->bp;
    const double *c = f->c, *r = f->r;
    int i0 = chunk_at(bp->nlist, t, f->chunks), i1 = chunk_at(bp->nlist, t + 1, f->chunks);
    int k = i0;
    for (int i = i0; i < i1; i++) {
        int p = bp->list[i].a, q = bp->list[i].b;
        if (!bp->list_act[p] && !bp->list_act[q])
            continue;
        const double *cp = &c[3 * p], *cq = &c[3 * q];
        if (spheres_overlap(cp[0], cp[1], cp[2], r[p], cq[0], cq[1], cq[2], r[q]))
            f->out[k++] = bp->list[i];
    }
    f->count[t] = k - i0;
}

static int list_make(sc_broadphase *bp, const sc_task_runner *runner, int method,
                     const double *c, const double *r, const double *skin,
                     const unsigned char *active, int n)
{
    bp->list_n = 0;
    if (reserve_bodies(bp, n) != SC_OK)
        return SC_ENOMEM;
    for (int i = 0; i < n; i++) {
        double sk = skin[i] >= 0 && skin[i] <= SC_BP_LIMIT ? skin[i] : 0;
        bp->list_grown[i] = min_d(r[i] + sk, SC_BP_LIMIT);
        bp->list_skin[i] = bp->list_grown[i] - r[i];
        bp->list_act[i] = !active || active[i];
    }
    int np = sc_bp_find_pairs_on(bp, runner, method, c, bp->list_grown, active, n, &bp->list,
                                 &bp->list_cap);
    if (np < 0)
        return np;
    bp->nlist = np;
    memcpy(bp->list_c, c, 3 * (size_t)n * sizeof *c);
    memcpy(bp->list_r, r, (size_t)n * sizeof *r);
    bp->list_n = n;
    return SC_OK;
}

long sc_bp_list_reused(const sc_broadphase *bp)
{
    return bp ? bp->list_reused : 0;
}

void sc_bp_list_drop(sc_broadphase *bp)
{
    if (bp) {
        bp->list_n = 0;
        bp->list_calls = 0;
    }
}

int sc_bp_find_pairs_skin(sc_broadphase *bp, const sc_task_runner *runner, int method,
                          const double *c, const double *r, const double *skin,
                          const unsigned char *active, int n, sc_pair **pairs, int *cap)
{
    if (!bp || !pairs || !cap || !skin || n < 0 || *cap < 0 || (*cap > 0 && !*pairs) ||
        (n > 0 && (!c || !r)))
        return SC_EINVAL;
    /* the first call after a drop makes no list: a motion group of a few
     * bodies in free flight is detected once a frame */
    if (bp->list_calls++ == 0)
        return sc_bp_find_pairs_on(bp, runner, method, c, r, active, n, pairs, cap);
    double var[3];
    if (check_bodies(c, r, n, var))
        return SC_EINVAL;
    if (!list_holds(bp, c, r, active, n)) {
        int rc = list_make(bp, runner, method, c, r, skin, active, n);
        if (rc != SC_OK) {
            /* without a list (list_make() left none): the plain call,
             * the same set */
            return rc == SC_ENOMEM ? sc_bp_find_pairs_on(bp, runner, method, c, r, active, n,
                                                         pairs, cap)
                                   : rc;
        }
    } else {
        bp->list_reused++;
    }
    if (bp->nlist > 0 && sc_grow((void **)pairs, cap, bp->nlist, sizeof **pairs, INT_MAX))
        return SC_ENOMEM;
    /* the candidates that pass, in chunks (tasks of the runner for a long
     * list), each written from its own start in the output, then closed up
     * in order: the same array either way */
    skin_filter sf = { bp, c, r, *pairs,
                       runner && bp->nlist >= BP_SHARE_MIN * BP_CHUNKS ? BP_CHUNKS : 1, { 0 } };
    sc_tasks_run(sf.chunks > 1 ? runner : NULL, filter_task, &sf, sf.chunks, NULL);
    int k = sf.count[0];
    for (int t = 1; t < sf.chunks; t++) {
        int i0 = chunk_at(bp->nlist, t, sf.chunks);
        if (sf.count[t] > 0 && k != i0)
            memmove(&(*pairs)[k], &(*pairs)[i0], (size_t)sf.count[t] * sizeof **pairs);
        k += sf.count[t];
    }
    return k;
}
