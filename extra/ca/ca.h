/*
 * ca.h - conservative advancement (time of impact by gap / motion bound)
 * and the convex distances it runs on (docs/DESIGN.md 3.4). Not part of
 * the library: tests/test_ccd.c and bench/bench_toi.c link it to compare it
 * with the library's sampling search (lib/core/toi.c).
 */
#ifndef SC_CA_H
#define SC_CA_H
#include "core.h"

/* ---- convex distances (ccd.c: libccd 2.1 and a GJK distance) ---- */

/* 1 when ccd.c takes s: spheres, boxes, hulls and convex meshes (planes
 * only against those, in sc_ccd_separation() and sc_ccd_gap()). */
int sc_ccd_convex(const sc_shape *s);
/* A shape at a pose, inflated by a margin: what libccd's support calls get.
 * A sphere is its centre (the core) rounded by its radius. */
typedef struct sc_ccd_obj {
    const sc_shape *s;
    double pos[3], R[9];      /* shape frame to world */
    double round;             /* m added in every direction (radius + margin) */
} sc_ccd_obj;
void sc_ccd_obj_init(sc_ccd_obj *o, const sc_shape *s, const sc_pose *p, double margin_m);
/* The point of o farthest along d (world frame, any nonzero length). */
void sc_ccd_support(const sc_ccd_obj *o, const double d[3], double out[3]);
enum { SC_CCD_MPR, SC_CCD_GJK };      /* libccd's two algorithms */
/* 1 when a at pa and b at pb are closer than margin_m (>= 0; 0: overlap
 * test), by libccd's MPR or GJK on the shapes inflated by margin_m / 2 each;
 * 0 when not; SC_EINVAL, SC_ENOTSUP (not sc_ccd_convex()). */
int sc_ccd_intersect(int method, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                     const sc_pose *pb, double margin_m);
/* libccd's penetration (MPR, or GJK + EPA) of the shapes inflated by
 * margin_m / 2 each: 1 with its depth and unit n from a towards b (moving b
 * by depth along n separates them, to libccd's accuracy), 0 when apart. */
int sc_ccd_penetration(int method, const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                       const sc_pose *pb, double margin_m, double *depth, double n[3]);
/* The distance as margin_m less that depth: 1 with *dist (< margin_m) when
 * they are closer than margin_m, 0 when not. */
int sc_ccd_distance_inflated(int method, const sc_shape *a, const sc_pose *pa,
                             const sc_shape *b, const sc_pose *pb, double margin_m, double *dist);
/* How far apart a and b are along unit n (from a towards b): the smallest
 * n.x over b less the largest over a. For any n a lower bound of their
 * signed distance (below), equal to it along the closest direction; exact
 * up to rounding. Planes too (-INFINITY unless n is along the normal). */
double sc_ccd_gap(const sc_shape *a, const sc_pose *pa, const sc_shape *b, const sc_pose *pb,
                  const double n[3]);
/* Where b stands from a. */
typedef struct sc_ccd_sep {
    int overlap;              /* 1: they touch or overlap */
    double dist;              /* signed distance: apart, to 1e-10 m (GJK);
                                 overlapping, -depth: exact where a sphere's
                                 centre or the margin makes it, else the
                                 extent along MPR's direction (an upper bound
                                 of the depth) */
    double gap;               /* sc_ccd_gap() along n: <= dist */
    double n[3];              /* unit, from a towards b */
} sc_ccd_sep;
/* The signed distance of a and b (sc_ccd_convex() shapes, or one of them a
 * plane): GJK on the cores when apart, starting along hint (a direction
 * from a towards b, NULL: between the origins; the answer does not depend
 * on it beyond GJK's accuracy); when the cores overlap, the least extent
 * along MPR's direction, hint and the faces nearest MPR's, or with
 * want_depth 0 only overlap (dist, gap 0). Shallow overlaps get their
 * depth; one deeper than a shape's thickness may get a far larger bound
 * (MPR looks along the line between the centres). SC_OK, SC_EINVAL,
 * SC_ENOTSUP, SC_ENOMEM. */
int sc_ccd_separation(const sc_shape *a, const sc_pose *pa, const sc_shape *b,
                      const sc_pose *pb, int want_depth, const double *hint, sc_ccd_sep *out);

/* ---- conservative advancement (toi_ca.c) ---- */

/* 1 when conservative advancement takes the pair: both sc_ccd_convex(), or
 * one of them and a plane that does not move (the same pose bits). */
int sc_toi_ca_pair(const sc_shape *a, const sc_pose *a0, const sc_pose *a1, const sc_shape *b,
                   const sc_pose *b0, const sc_pose *b1);
/* Conservative advancement on ccd.c's distances, with the contracts of
 * sc_toi_before_ctx() and sc_toi_deepen_before_ctx() (core.h; the touch
 * found is at most tol_m / 2 deep, 3/4 tol_m where a shallower one than
 * tol_m / 8 moved on, and the pair was never deeper before it); SC_ENOTSUP
 * for other pairs. After 64 steps (a long graze) the sampling search takes
 * the rest of the motion (ctx is for that), as it does a start that
 * overlaps less than the narrow phase sees. */
int sc_toi_ca_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                         const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                         const sc_pose *b1, double tol_m, double tmax, double *t);
int sc_toi_ca_deepen_before_ctx(sc_np_ctx *ctx, const sc_shape *a, const sc_pose *a0,
                                const sc_pose *a1, const sc_shape *b, const sc_pose *b0,
                                const sc_pose *b1, double limit_m, double tmax, double *t);

#endif /* SC_CA_H */
