/* mesh.c - triangle mesh validation and mass properties.
 *
 * A mesh is accepted when it is a closed 2-manifold with consistent outward
 * orientation: every directed edge appears exactly once and its reverse
 * exactly once. Mass properties follow D. Eberly, "Polyhedral Mass
 * Properties (Revisited)" (divergence theorem over the surface), computed
 * about the vertex mean to keep the sums well conditioned.
 */
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "vecmath.h"

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Each directed edge once, and its reverse once. */
static int check_closed(const int *tri, int ntris)
{
    size_t ne = (size_t)ntris * 3;
    uint64_t *e = sc_alloc_array(ne, sizeof *e);
    if (!e)
        return SC_ENOMEM;
    for (int t = 0; t < ntris; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t u = (uint32_t)tri[3 * t + k], v = (uint32_t)tri[3 * t + (k + 1) % 3];
            e[3 * (size_t)t + k] = (uint64_t)u << 32 | v;
        }
    qsort(e, ne, sizeof *e, cmp_u64);
    int rc = SC_OK;
    for (size_t i = 0; i < ne && rc == SC_OK; i++) {
        if (i + 1 < ne && e[i + 1] == e[i]) {
            rc = SC_ENOTCLOSED;     /* an edge used twice the same way */
            break;
        }
        uint64_t rev = (e[i] << 32) | (e[i] >> 32);
        if (!bsearch(&rev, e, ne, sizeof *e, cmp_u64))
            rc = SC_ENOTCLOSED;     /* a border edge, or flipped neighbour */
    }
    free(e);
    return rc;
}

static void subexpr(double w0, double w1, double w2, double *f1, double *f2, double *f3,
                    double *g0, double *g1, double *g2)
{
    double t0 = w0 + w1, t1 = w0 * w0, t2 = t1 + w1 * t0;
    *f1 = t0 + w2;
    *f2 = t2 + w2 * *f1;
    *f3 = w0 * t1 + w1 * t2 + w2 * *f2;
    *g0 = *f2 + w0 * (*f1 + w0);
    *g1 = *f2 + w1 * (*f1 + w1);
    *g2 = *f2 + w2 * (*f1 + w2);
}

static void mass_props(const double *xyz, int nverts, const int *tri, int ntris,
                       const double ref[3], sc_mass_props *mp)
{
    double in[10] = { 0 };
    (void)nverts;
    for (int t = 0; t < ntris; t++) {
        double p[3][3];
        for (int k = 0; k < 3; k++)
            v3_sub(p[k], &xyz[3 * tri[3 * t + k]], ref);
        double a1 = p[1][0] - p[0][0], b1 = p[1][1] - p[0][1], c1 = p[1][2] - p[0][2];
        double a2 = p[2][0] - p[0][0], b2 = p[2][1] - p[0][1], c2 = p[2][2] - p[0][2];
        double d0 = b1 * c2 - b2 * c1, d1 = a2 * c1 - a1 * c2, d2 = a1 * b2 - a2 * b1;
        double f1x, f2x, f3x, g0x, g1x, g2x, f1y, f2y, f3y, g0y, g1y, g2y;
        double f1z, f2z, f3z, g0z, g1z, g2z;
        subexpr(p[0][0], p[1][0], p[2][0], &f1x, &f2x, &f3x, &g0x, &g1x, &g2x);
        subexpr(p[0][1], p[1][1], p[2][1], &f1y, &f2y, &f3y, &g0y, &g1y, &g2y);
        subexpr(p[0][2], p[1][2], p[2][2], &f1z, &f2z, &f3z, &g0z, &g1z, &g2z);
        in[0] += d0 * f1x;
        in[1] += d0 * f2x; in[2] += d1 * f2y; in[3] += d2 * f2z;
        in[4] += d0 * f3x; in[5] += d1 * f3y; in[6] += d2 * f3z;
        in[7] += d0 * (p[0][1] * g0x + p[1][1] * g1x + p[2][1] * g2x);
        in[8] += d1 * (p[0][2] * g0y + p[1][2] * g1y + p[2][2] * g2y);
        in[9] += d2 * (p[0][0] * g0z + p[1][0] * g1z + p[2][0] * g2z);
    }
    static const double mult[10] = { 1.0 / 6, 1.0 / 24, 1.0 / 24, 1.0 / 24, 1.0 / 60,
                                     1.0 / 60, 1.0 / 60, 1.0 / 120, 1.0 / 120, 1.0 / 120 };
    for (int i = 0; i < 10; i++)
        in[i] *= mult[i];
    double m = in[0];
    double c[3] = { in[1] / m, in[2] / m, in[3] / m };
    double *I = mp->inertia;
    I[0] = in[5] + in[6] - m * (c[1] * c[1] + c[2] * c[2]);
    I[4] = in[4] + in[6] - m * (c[2] * c[2] + c[0] * c[0]);
    I[8] = in[4] + in[5] - m * (c[0] * c[0] + c[1] * c[1]);
    I[1] = I[3] = -(in[7] - m * c[0] * c[1]);
    I[5] = I[7] = -(in[8] - m * c[1] * c[2]);
    I[2] = I[6] = -(in[9] - m * c[2] * c[0]);
    mp->volume = m;
    v3_add(mp->com, c, ref);
}

int sc_mesh_check(const double *xyz, int nverts, const int *tri, int ntris, sc_mass_props *mp)
{
    if (!xyz || !tri || nverts < 4 || ntris < 4)
        return (nverts < 0 || ntris < 0 || !xyz || !tri) ? SC_EINVAL : SC_ENOTCLOSED;
    if (nverts > SC_MESH_MAX_VERTS || ntris > SC_MESH_MAX_TRIS)
        return SC_ETOOBIG;
    double lo[3] = { INFINITY, INFINITY, INFINITY }, hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    double ref[3] = { 0, 0, 0 };
    for (int i = 0; i < nverts; i++) {
        const double *p = &xyz[3 * i];
        if (!sc_finite3(p))
            return SC_EINVAL;
        for (int k = 0; k < 3; k++) {
            lo[k] = min_d(lo[k], p[k]);
            hi[k] = max_d(hi[k], p[k]);
            ref[k] += p[k] / nverts;
        }
    }
    double ext[3];
    v3_sub(ext, hi, lo);
    double scale = v3_len(ext);
    if (!(scale > 0) || !isfinite(scale))
        return SC_EDEGENERATE;
    /* Triangles whose area is below 1e-12 scale^2 are slivers no collider
     * can use; ratios divide by scale one factor at a time so that meshes
     * at 1e+-150 neither overflow nor underflow. */
    for (int t = 0; t < ntris; t++) {
        const int *f = &tri[3 * t];
        for (int k = 0; k < 3; k++)
            if (f[k] < 0 || f[k] >= nverts)
                return SC_EINVAL;
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2])
            return SC_EDEGENERATE;
        double n[3], area2 = tri_normal(n, &xyz[3 * f[0]], &xyz[3 * f[1]], &xyz[3 * f[2]]);
        if (!(area2 / scale / scale > 1e-12))
            return SC_EDEGENERATE;
    }
    int rc = check_closed(tri, ntris);
    if (rc != SC_OK)
        return rc;
    sc_mass_props p = { 0 };
    mass_props(xyz, nverts, tri, ntris, ref, &p);
    /* Mass properties beyond double range (inertia grows as size^5) */
    int finite = isfinite(p.volume) && sc_finite3(p.com);
    for (int k = 0; k < 9; k++)
        finite = finite && isfinite(p.inertia[k]);
    if (!finite)
        return SC_ETOOBIG;
    /* Closed and consistent but inside out: the volume comes out negative. */
    if (p.volume < 0)
        return SC_ENOTCLOSED;
    if (!(p.volume / scale / scale / scale > 1e-15))
        return SC_EDEGENERATE;
    if (mp)
        *mp = p;
    return SC_OK;
}
