/* manifold.c - reduce a pair's raw contacts to at most four well-spread
 * points (deepest first, then the point farthest from it, then the one that
 * spans the largest triangle, then the one that adds the most area), the
 * same selection Bullet and Box2D use: a resting face keeps its footprint
 * while the LCP stays small. Deterministic: ties keep the lower index. */
#include <string.h>

#include "core.h"
#include "vecmath.h"

static double tri_area2(const double a[3], const double b[3], const double c[3])
{
    double n[3];
    return tri_normal(n, a, b, c);
}

int sc_manifold_reduce(sc_contact *c, int n, double merge_dist)
{
    /* Drop unusable points, clamp depth, merge near duplicates (keep deeper). */
    int m = 0;
    for (int i = 0; i < n; i++) {
        if (!sc_finite3(c[i].pos) || !sc_finite3(c[i].normal) || !isfinite(c[i].depth))
            continue;
        if (v3_normalize(c[i].normal) == 0)
            continue;
        c[i].depth = max_d(c[i].depth, 0.0) + 0.0;   /* + 0.0: no -0 */
        int dup = -1;
        for (int j = 0; j < m && dup < 0; j++)
            if (v3_dist(c[j].pos, c[i].pos) <= merge_dist && v3_dot(c[j].normal, c[i].normal) > 0.99)
                dup = j;
        if (dup >= 0) {
            if (c[i].depth > c[dup].depth)
                c[dup] = c[i];
        } else {
            c[m++] = c[i];
        }
    }
    if (m <= SC_MAX_PAIR_CONTACTS) {
        /* still deepest first, for a canonical order */
        for (int i = 1; i < m; i++)
            for (int j = i; j > 0 && c[j].depth > c[j - 1].depth; j--) {
                sc_contact t = c[j]; c[j] = c[j - 1]; c[j - 1] = t;
            }
        return m;
    }
    int pick[SC_MAX_PAIR_CONTACTS];
    int p0 = 0;
    for (int i = 1; i < m; i++)
        if (c[i].depth > c[p0].depth)
            p0 = i;
    int p1 = -1;
    double best = -1;
    for (int i = 0; i < m; i++) {
        double d = v3_dist(c[i].pos, c[p0].pos);
        if (i != p0 && d > best) { best = d; p1 = i; }
    }
    int p2 = -1;
    best = -1;
    for (int i = 0; i < m; i++) {
        double a = tri_area2(c[p0].pos, c[p1].pos, c[i].pos);
        if (i != p0 && i != p1 && a > best) { best = a; p2 = i; }
    }
    /* Fourth: the point whose triangles with the three edges add the most
     * area outside the triangle p0 p1 p2 (zero if it lies inside). */
    int p3 = -1;
    best = -1;
    double base = tri_area2(c[p0].pos, c[p1].pos, c[p2].pos);
    for (int i = 0; i < m; i++) {
        if (i == p0 || i == p1 || i == p2)
            continue;
        double a = tri_area2(c[p0].pos, c[p1].pos, c[i].pos) +
                   tri_area2(c[p1].pos, c[p2].pos, c[i].pos) +
                   tri_area2(c[p2].pos, c[p0].pos, c[i].pos) - base;
        if (a > best) { best = a; p3 = i; }
    }
    pick[0] = p0; pick[1] = p1; pick[2] = p2; pick[3] = p3;
    sc_contact out[SC_MAX_PAIR_CONTACTS];
    for (int k = 0; k < SC_MAX_PAIR_CONTACTS; k++)
        out[k] = c[pick[k]];
    memcpy(c, out, sizeof out);
    return SC_MAX_PAIR_CONTACTS;
}
