/* shape_builders.c - the paper's shapes: UV sphere, bolt and nut meshes.
 *
 * All are built from rings of vertices around the z axis, stitched with
 * quad strips (sides), fans (caps) and an angle-ordered zipper (the annulus
 * between a hexagon and a circle). Triangles are counter-clockwise seen from
 * outside. Builders move the mesh so its centre of mass is the origin.
 */
#include <stdlib.h>

#include "core.h"

/* Bolt: hex head (circumradius, height) and shaft (radius, length). */
#define BOLT_HEAD_R 0.020
#define BOLT_HEAD_H 0.0125
#define BOLT_SHAFT_R 0.010
#define BOLT_SHAFT_L 0.060
#define BOLT_SEGS 16
#define BOLT_ROWS 4          /* shaft split along z: 4 + 4*16 + 2*16*(4-1)... = 180 tris */
/* Nut: hexagonal prism (circumradius, height) with a round hole. */
#define NUT_R 0.020
#define NUT_H 0.016
#define NUT_HOLE_R 0.0105
#define NUT_SEGS 16
#define NUT_ROWS 8           /* 2*(6+16) + 8*6*2 + 8*16*2 = 396 tris */

typedef struct mesh_builder {
    double *xyz;
    int *tri;
    int nv, nt, vcap, tcap;
    int failed;              /* first error code, SC_OK while fine */
} mesh_builder;

static int mb_vertex(mesh_builder *mb, double x, double y, double z)
{
    int rc = mb->failed ? mb->failed
                        : sc_grow((void **)&mb->xyz, &mb->vcap, mb->nv + 1, 3 * sizeof *mb->xyz,
                                  SC_MESH_MAX_VERTS);
    if (rc != SC_OK) {
        mb->failed = rc;
        return 0;
    }
    double *v = &mb->xyz[3 * mb->nv];
    v[0] = x; v[1] = y; v[2] = z;
    return mb->nv++;
}

static void mb_tri(mesh_builder *mb, int a, int b, int c)
{
    int rc = mb->failed ? mb->failed
                        : sc_grow((void **)&mb->tri, &mb->tcap, mb->nt + 1, 3 * sizeof *mb->tri,
                                  SC_MESH_MAX_TRIS);
    if (rc != SC_OK) {
        mb->failed = rc;
        return;
    }
    int *t = &mb->tri[3 * mb->nt++];
    t[0] = a; t[1] = b; t[2] = c;
}

/* A ring of n vertices at height z, counter-clockwise seen from +z, the
 * first at angle phase. Returns the index of the first vertex. */
static int mb_ring(mesh_builder *mb, int n, double r, double z, double phase)
{
    int first = mb->nv;
    for (int i = 0; i < n; i++) {
        double a = phase + 2 * M_PI * i / n;
        mb_vertex(mb, r * cos(a), r * sin(a), z);
    }
    return first;
}

/* Side strip between ring a (lower) and ring b (upper) of n vertices each;
 * outward = 1 faces away from the axis, 0 towards it (a hole). */
static void mb_strip(mesh_builder *mb, int a, int b, int n, int outward)
{
    for (int j = 0; j < n; j++) {
        int a0 = a + j, a1 = a + (j + 1) % n, b0 = b + j, b1 = b + (j + 1) % n;
        if (outward) {
            mb_tri(mb, a0, a1, b1);
            mb_tri(mb, a0, b1, b0);
        } else {
            mb_tri(mb, a0, b1, a1);
            mb_tri(mb, a0, b0, b1);
        }
    }
}

/* Fan over a convex ring; up = 1 faces +z. */
static void mb_cap(mesh_builder *mb, int ring, int n, int up)
{
    for (int j = 1; j + 1 < n; j++) {
        if (up)
            mb_tri(mb, ring, ring + j, ring + j + 1);
        else
            mb_tri(mb, ring, ring + j + 1, ring + j);
    }
}

/* Flat annulus between an outer ring (no vertices) and an inner ring (ni),
 * both starting at angle 0: walk both by angle, always advancing the ring
 * whose next vertex comes first, so every triangle is well formed. */
static void mb_annulus(mesh_builder *mb, int outer, int no, int inner, int ni, int up)
{
    int i = 0, j = 0;
    while (i < no || j < ni) {
        double ao = 2 * M_PI * (i + 1) / no, ai = 2 * M_PI * (j + 1) / ni;
        int o0 = outer + i % no, in0 = inner + j % ni;
        if (j == ni || (i < no && ao <= ai)) {
            int o1 = outer + (i + 1) % no;
            if (up) mb_tri(mb, o0, o1, in0); else mb_tri(mb, o0, in0, o1);
            i++;
        } else {
            int in1 = inner + (j + 1) % ni;
            if (up) mb_tri(mb, o0, in1, in0); else mb_tri(mb, o0, in0, in1);
            j++;
        }
    }
}

static sc_shape *mb_finish(mesh_builder *mb, const sc_piece_set *pieces)
{
    if (mb->failed) {
        free(mb->xyz);
        free(mb->tri);
        sc_set_error(mb->failed);
        return NULL;
    }
    return sc_shape_mesh_centered(mb->xyz, mb->nv, mb->tri, mb->nt, pieces);
}

/* Convex pieces as prisms along z: each a polygon (x, y pairs) extruded
 * from z0 to z1; the points go to pts, 2 * n a piece. */
#define PIECE_MAX_PTS 512
typedef struct piece_builder {
    double pts[3 * PIECE_MAX_PTS];
    int count[32];
    int n, np;
} piece_builder;

static void pb_prism(piece_builder *pb, const double *xy, int n, double z0, double z1)
{
    SC_ASSERT(pb->n < 32 && pb->np + 2 * n <= PIECE_MAX_PTS);
    for (int h = 0; h < 2; h++)
        for (int i = 0; i < n; i++) {
            double *p = &pb->pts[3 * pb->np++];
            p[0] = xy[2 * i];
            p[1] = xy[2 * i + 1];
            p[2] = h ? z1 : z0;
        }
    pb->count[pb->n++] = 2 * n;
}

/* A ring's vertex i as mb_ring() places it (the same bits). */
static void ring_xy(double *xy, int n, double r, int i)
{
    double a = 0 + 2 * M_PI * i / n;
    xy[0] = r * cos(a);
    xy[1] = r * sin(a);
}

/* Where the ray from the axis at angle a leaves the hexagon of
 * circumradius r whose first corner is at angle 0. */
static void hexagon_at(double *xy, double r, double a)
{
    int k = (int)floor(a / (M_PI / 3));
    double mid = (k + 0.5) * (M_PI / 3);      /* the edge's normal */
    double d = r * cos(M_PI / 6) / cos(a - mid);
    xy[0] = d * cos(a);
    xy[1] = d * sin(a);
}

SC_API sc_shape *sc_shape_uv_sphere(double r, int slices, int stacks)
{
    if (!(r > 0) || !isfinite(r) || slices < 3 || stacks < 2 || slices > 4096 || stacks > 4096) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    mesh_builder mb = { 0 };
    int north = mb_vertex(&mb, 0, 0, r);
    int prev = -1;
    for (int i = 1; i < stacks; i++) {
        double th = M_PI * i / stacks;
        int ring = mb_ring(&mb, slices, r * sin(th), r * cos(th), 0);
        if (prev < 0) {
            for (int j = 0; j < slices; j++)
                mb_tri(&mb, north, ring + j, ring + (j + 1) % slices);
        } else {
            /* rings run top to bottom here, so "outward" is reversed */
            mb_strip(&mb, ring, prev, slices, 1);
        }
        prev = ring;
    }
    int south = mb_vertex(&mb, 0, 0, -r);
    for (int j = 0; j < slices; j++)
        mb_tri(&mb, south, prev + (j + 1) % slices, prev + j);
    return mb_finish(&mb, NULL);
}

SC_API sc_shape *sc_shape_bolt(void)
{
    mesh_builder mb = { 0 };
    double z0 = 0, z1 = BOLT_HEAD_H, z2 = BOLT_HEAD_H + BOLT_SHAFT_L;
    int hb = mb_ring(&mb, 6, BOLT_HEAD_R, z0, 0);      /* head bottom hexagon */
    int ht = mb_ring(&mb, 6, BOLT_HEAD_R, z1, 0);      /* head top hexagon */
    mb_cap(&mb, hb, 6, 0);
    mb_strip(&mb, hb, ht, 6, 1);
    int prev = mb_ring(&mb, BOLT_SEGS, BOLT_SHAFT_R, z1, 0);
    mb_annulus(&mb, ht, 6, prev, BOLT_SEGS, 1);        /* underside of the head */
    for (int k = 1; k <= BOLT_ROWS; k++) {
        int ring = mb_ring(&mb, BOLT_SEGS, BOLT_SHAFT_R, z1 + (z2 - z1) * k / BOLT_ROWS, 0);
        mb_strip(&mb, prev, ring, BOLT_SEGS, 1);
        prev = ring;
    }
    mb_cap(&mb, prev, BOLT_SEGS, 1);
    /* pieces: the head's prism and the shaft's */
    piece_builder pb = { .n = 0 };
    double xy[2 * BOLT_SEGS];
    for (int i = 0; i < 6; i++)
        ring_xy(&xy[2 * i], 6, BOLT_HEAD_R, i);
    pb_prism(&pb, xy, 6, z0, z1);
    for (int i = 0; i < BOLT_SEGS; i++)
        ring_xy(&xy[2 * i], BOLT_SEGS, BOLT_SHAFT_R, i);
    pb_prism(&pb, xy, BOLT_SEGS, z1, z2);
    sc_piece_set ps = { pb.pts, pb.count, pb.n };
    return mb_finish(&mb, &ps);
}

SC_API sc_shape *sc_shape_nut(void)
{
    mesh_builder mb = { 0 };
    int out_prev = -1, in_prev = -1, out0 = -1, in0 = -1;
    for (int k = 0; k <= NUT_ROWS; k++) {
        double z = NUT_H * k / NUT_ROWS;
        int o = mb_ring(&mb, 6, NUT_R, z, 0);
        int in = mb_ring(&mb, NUT_SEGS, NUT_HOLE_R, z, 0);
        if (k == 0) {
            out0 = o;
            in0 = in;
        } else {
            mb_strip(&mb, out_prev, o, 6, 1);
            mb_strip(&mb, in_prev, in, NUT_SEGS, 0);
        }
        out_prev = o;
        in_prev = in;
    }
    mb_annulus(&mb, out0, 6, in0, NUT_SEGS, 0);        /* bottom face */
    mb_annulus(&mb, out_prev, 6, in_prev, NUT_SEGS, 1); /* top face */
    /* pieces: one per edge of the hole, out to the hexagon along the rays
     * through the edge's ends (with the hexagon's corner between them, if
     * any); each is convex: its inner side is a single edge */
    piece_builder pb = { .n = 0 };
    for (int j = 0; j < NUT_SEGS; j++) {
        double a0 = 2 * M_PI * j / NUT_SEGS, a1 = 2 * M_PI * (j + 1) / NUT_SEGS;
        double xy[2 * 5];
        int n = 0;
        ring_xy(&xy[2 * n++], NUT_SEGS, NUT_HOLE_R, j);
        ring_xy(&xy[2 * n++], NUT_SEGS, NUT_HOLE_R, (j + 1) % NUT_SEGS);
        hexagon_at(&xy[2 * n++], NUT_R, a1 - 1e-12);
        for (int c = 5; c >= 0; c--) {
            double ac = 2 * M_PI * c / 6;
            if (ac > a0 + 1e-9 && ac < a1 - 1e-9)
                ring_xy(&xy[2 * n++], 6, NUT_R, c);
        }
        hexagon_at(&xy[2 * n++], NUT_R, a0 + 1e-12);
        pb_prism(&pb, xy, n, 0, NUT_H);
    }
    sc_piece_set ps = { pb.pts, pb.count, pb.n };
    return mb_finish(&mb, &ps);
}
