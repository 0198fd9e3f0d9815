/* shape.c - immutable, reference-counted collision shapes.
 *
 * A shape is built once and shared (read-only) by bodies, worker threads
 * and work units. Everything a collider needs, ODE's trimesh data included,
 * is built here at creation so the narrow phase never mutates a shape.
 */
#include <stdlib.h>
#include <string.h>

#include <ode/ode.h>

#include "core.h"
#include "vecmath.h"

static sc_shape *shape_new(int kind)
{
    sc_shape *s = calloc(1, sizeof *s);
    if (!s) {
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    atomic_init(&s->refs, 1);
    s->kind = kind;
    return s;
}

static void shape_free(sc_shape *s)
{
    if (s->ode_tridata)
        dGeomTriMeshDataDestroy((dTriMeshDataID)s->ode_tridata);
    free(s->xyz);
    free(s->xyz_soa);
    free(s->tri);
    free(s->ode_index);
    free(s->ode_planes);
    free(s->ode_polys);
    sc_poly_free(s);
    for (int k = 0; s->pieces && k < s->npieces; k++)
        sc_shape_release(s->pieces[k]);
    free(s->pieces);
    free(s->piece_ball);
    free(s->piece_pts);
    free(s->piece_count);
    free(s);
}

/* Content hash: equal shapes hash equal on every machine (cluster cache). */
static void shape_hash(sc_shape *s)
{
    uint64_t h = SC_FNV_OFFSET;
    h = sc_fnv1a(h, &s->kind, sizeof s->kind);
    h = sc_fnv1a(h, &s->radius, sizeof s->radius);
    h = sc_fnv1a(h, s->half, sizeof s->half);
    h = sc_fnv1a(h, s->plane, sizeof s->plane);
    if (s->xyz) {
        h = sc_fnv1a(h, s->xyz, (size_t)s->nverts * 3 * sizeof *s->xyz);
        h = sc_fnv1a(h, s->tri, (size_t)s->ntris * 3 * sizeof *s->tri);
    }
    if (s->npieces > 0) {     /* shapes without pieces keep their hashes */
        h = sc_fnv1a(h, &s->npieces, sizeof s->npieces);
        h = sc_fnv1a(h, s->piece_count, (size_t)s->npieces * sizeof *s->piece_count);
        h = sc_fnv1a(h, s->piece_pts, (size_t)s->npiece_pts * 3 * sizeof *s->piece_pts);
    }
    s->hash = h;
}

SC_API sc_shape *sc_shape_sphere(double r)
{
    if (!(r > 0) || !isfinite(r)) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    if (r < SC_MIN_LENGTH || r > SC_MAX_LENGTH) {
        sc_set_error(SC_ELIMIT);
        return NULL;
    }
    sc_shape *s = shape_new(SC_SHAPE_SPHERE);
    if (!s)
        return NULL;
    s->radius = r;
    s->bound_r = r;
    s->mp.volume = 4.0 / 3.0 * M_PI * r * r * r;
    double i = 0.4 * s->mp.volume * r * r;
    s->mp.inertia[0] = s->mp.inertia[4] = s->mp.inertia[8] = i;
    shape_hash(s);
    return s;
}

SC_API sc_shape *sc_shape_box(double hx, double hy, double hz)
{
    if (!(hx > 0 && hy > 0 && hz > 0) || !isfinite(hx + hy + hz)) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    if (min_d(hx, min_d(hy, hz)) < SC_MIN_LENGTH || max_d(hx, max_d(hy, hz)) > SC_MAX_LENGTH) {
        sc_set_error(SC_ELIMIT);
        return NULL;
    }
    sc_shape *s = shape_new(SC_SHAPE_BOX);
    if (!s)
        return NULL;
    v3_set(s->half, hx, hy, hz);
    s->bound_r = v3_len(s->half);
    double v = 8 * hx * hy * hz;
    s->mp.volume = v;
    s->mp.inertia[0] = v / 3 * (hy * hy + hz * hz);
    s->mp.inertia[4] = v / 3 * (hx * hx + hz * hz);
    s->mp.inertia[8] = v / 3 * (hx * hx + hy * hy);
    if (sc_poly_build(s) != SC_OK) {
        shape_free(s);
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    shape_hash(s);
    return s;
}

SC_API sc_shape *sc_shape_plane(double nx, double ny, double nz, double d)
{
    double n[3] = { nx, ny, nz };
    double l = v3_len(n);
    if (!(l > 0) || !isfinite(l) || !isfinite(d)) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    sc_shape *s = shape_new(SC_SHAPE_PLANE);
    if (!s)
        return NULL;
    s->plane[0] = nx / l;
    s->plane[1] = ny / l;
    s->plane[2] = nz / l;
    s->plane[3] = d / l;
    s->bound_r = INFINITY;
    shape_hash(s);
    return s;
}

/* Every vertex behind (or on) every face plane, within a relative tolerance.
 * Costs ntris * nverts; beyond a budget the mesh is treated as non-convex,
 * which is always safe (the trimesh collider handles any closed mesh). */
static int mesh_is_convex(const sc_shape *s)
{
    if ((double)s->ntris * s->nverts > 5e7)
        return 0;
    double tol = 1e-9 * s->bound_r;
    for (int t = 0; t < s->ntris; t++) {
        const double *a = &s->xyz[3 * s->tri[3 * t]], *b = &s->xyz[3 * s->tri[3 * t + 1]],
                     *c = &s->xyz[3 * s->tri[3 * t + 2]];
        double n[3];
        tri_normal(n, a, b, c);
        double d = v3_dot(n, a);
        for (int i = 0; i < s->nverts; i++)
            if (v3_dot(n, &s->xyz[3 * i]) - d > tol)
                return 0;
    }
    return 1;
}

/* ODE's trimesh data (and, for convex shapes, dConvex planes/polygons). */
static int build_ode_data(sc_shape *s)
{
    sc_ode_init();
    s->ode_index = sc_alloc_array((size_t)s->ntris * 3, sizeof *s->ode_index);
    if (!s->ode_index)
        return SC_ENOMEM;
    for (int i = 0; i < 3 * s->ntris; i++)
        s->ode_index[i] = (unsigned)s->tri[i];
    dTriMeshDataID td = dGeomTriMeshDataCreate();
    if (!td)
        return SC_ENOMEM;
    dGeomTriMeshDataBuildDouble(td, s->xyz, 3 * sizeof(double), s->nverts, s->ode_index,
                                3 * s->ntris, 3 * sizeof(dTriIndex));
    dGeomTriMeshDataPreprocess2(td, 1U << dTRIDATAPREPROCESS_BUILD_CONCAVE_EDGES, NULL);
    s->ode_tridata = td;
    if (!s->convex)
        return SC_OK;
    s->ode_planes = sc_alloc_array((size_t)s->ntris * 4, sizeof *s->ode_planes);
    s->ode_polys = sc_alloc_array((size_t)s->ntris * 4, sizeof *s->ode_polys);
    if (!s->ode_planes || !s->ode_polys)
        return SC_ENOMEM;
    for (int t = 0; t < s->ntris; t++) {
        const int *f = &s->tri[3 * t];
        double n[3];
        tri_normal(n, &s->xyz[3 * f[0]], &s->xyz[3 * f[1]], &s->xyz[3 * f[2]]);
        double *pl = &s->ode_planes[4 * t];
        v3_copy(pl, n);
        pl[3] = v3_dot(n, &s->xyz[3 * f[0]]);
        unsigned *po = &s->ode_polys[4 * t];
        po[0] = 3;
        po[1] = (unsigned)f[0];
        po[2] = (unsigned)f[1];
        po[3] = (unsigned)f[2];
    }
    return SC_OK;
}

/* Drop vertices no triangle uses, keeping order: ODE's trimesh
 * preprocessing asserts (aborts the process) on a mesh with more vertices
 * than triangle corners. Indices must be in range (checked before). */
static int compact_vertices(double *xyz, int *nverts, int *tri, int ntris)
{
    int *map = sc_alloc_array((size_t)*nverts, sizeof *map);
    if (!map)
        return SC_ENOMEM;
    for (int i = 0; i < *nverts; i++)
        map[i] = -1;
    for (int i = 0; i < 3 * ntris; i++)
        map[tri[i]] = 0;
    int n = 0;
    for (int i = 0; i < *nverts; i++)
        if (map[i] == 0) {
            memmove(&xyz[3 * n], &xyz[3 * i], 3 * sizeof *xyz);
            map[i] = n++;
        }
    for (int i = 0; i < 3 * ntris; i++)
        tri[i] = map[tri[i]];
    *nverts = n;
    free(map);
    return SC_OK;
}

static int indices_ok(int nverts, const int *tri, int ntris)
{
    for (int i = 0; i < 3 * ntris; i++)
        if (tri[i] < 0 || tri[i] >= nverts)
            return 0;
    return 1;
}

/* 1 if point x (mesh frame) is strictly inside piece j of s. */
static int in_piece(const sc_shape *s, int j, const double x[3])
{
    const sc_shape *c = s->pieces[j];
    double p[3];
    v3_sub(p, x, &s->piece_ball[4 * j]);
    for (int g = 0; g < c->nfaces; g++)
        if (!(v3_dot(&c->face_plane[4 * g], p) - c->face_plane[4 * g + 3] < 0))
            return 0;
    return 1;
}

/* Marks the faces of each piece that lie inside the mesh's solid: where a
 * point just outside the face (its centre and its corners drawn a tenth
 * towards the centre, moved out by a millionth of the bounding radius) is
 * inside another piece, all of them. Nothing is pushed out through such a
 * face (polyhedron.c, narrowphase.c): the shaft's face inside a bolt's
 * head, or the cuts between a nut's pieces, would otherwise be the
 * shallowest way out of a piece for a body that dug in next to them. */
static int mark_inner_faces(sc_shape *s)
{
    double off = 1e-6 * s->bound_r;
    for (int k = 0; k < s->npieces; k++) {
        sc_shape *c = s->pieces[k];
        const double *ball = &s->piece_ball[4 * k];
        if (c->nfaces == 0)
            continue;
        c->face_inner = calloc((size_t)c->nfaces, 1);
        if (!c->face_inner)
            return SC_ENOMEM;
        int any = 0;
        for (int f = 0; f < c->nfaces; f++) {
            const double *pl = &c->face_plane[4 * f];
            int n = c->face_start[f + 1] - c->face_start[f];
            double mid[3] = { 0, 0, 0 };
            for (int i = 0; i < n; i++)
                v3_add(mid, mid, &c->face_xyz[3 * c->face_vert[c->face_start[f] + i]]);
            v3_scale(mid, mid, 1.0 / n);
            int inner = 1;
            for (int i = -1; i < n && inner; i++) {
                double x[3];
                if (i < 0) {
                    v3_copy(x, mid);
                } else {
                    const double *v = &c->face_xyz[3 * c->face_vert[c->face_start[f] + i]];
                    for (int d = 0; d < 3; d++)
                        x[d] = v[d] + 0.1 * (mid[d] - v[d]);
                }
                v3_madd(x, x, pl, off);
                v3_add(x, x, ball);
                int in = 0;
                for (int j = 0; j < s->npieces && !in; j++)
                    in = j != k && in_piece(s, j, x);
                inner = in;
            }
            c->face_inner[f] = (unsigned char)inner;
            any |= inner;
        }
        if (!any) {
            free(c->face_inner);
            c->face_inner = NULL;
        }
    }
    return SC_OK;
}

/* The most points one piece of ps has. */
static int piece_max_pts(const sc_piece_set *ps)
{
    int m = 0;
    for (int k = 0; k < ps->n; k++)
        m = ps->count[k] > m ? ps->count[k] : m;
    return m;
}

/* The convex pieces of mesh s from ps, each point moved by -shift (NULL:
 * not moved). Every point must be finite and inside the mesh's bounding
 * box and sphere (a piece outside them would be missed by the broad phase
 * or be a mistake); every piece must have a solid hull. On error the
 * shape keeps what was built, for shape_free(). */
static int attach_pieces(sc_shape *s, const sc_piece_set *ps, const double *shift)
{
    if (!ps)
        return SC_OK;
    if (ps->n < 1 || !ps->pts || !ps->count || s->kind != SC_SHAPE_MESH)
        return SC_EINVAL;
    if (ps->n > SC_MESH_MAX_PIECES)
        return SC_ETOOBIG;
    long total = 0;
    for (int k = 0; k < ps->n; k++) {
        if (ps->count[k] < 4)
            return SC_EINVAL;
        total += ps->count[k];
        if (total > SC_MESH_MAX_VERTS)
            return SC_ETOOBIG;
    }
    s->piece_pts = sc_alloc_array((size_t)total * 3, sizeof *s->piece_pts);
    s->piece_count = sc_alloc_array((size_t)ps->n, sizeof *s->piece_count);
    s->piece_ball = sc_alloc_array((size_t)ps->n * 4, sizeof *s->piece_ball);
    s->pieces = calloc((size_t)ps->n, sizeof *s->pieces);
    if (!s->piece_pts || !s->piece_count || !s->piece_ball || !s->pieces)
        return SC_ENOMEM;
    s->npieces = ps->n;
    s->npiece_pts = (int)total;
    memcpy(s->piece_count, ps->count, (size_t)ps->n * sizeof *ps->count);
    double lo[3] = { INFINITY, INFINITY, INFINITY }, hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    for (int i = 0; i < s->nverts; i++)
        for (int d = 0; d < 3; d++) {
            lo[d] = min_d(lo[d], s->xyz[3 * i + d]);
            hi[d] = max_d(hi[d], s->xyz[3 * i + d]);
        }
    double tol = 1e-9 * s->bound_r;
    for (long i = 0; i < total; i++) {
        double *p = &s->piece_pts[3 * i];
        for (int d = 0; d < 3; d++) {
            p[d] = ps->pts[3 * i + d] - (shift ? shift[d] : 0);
            if (!isfinite(p[d]) || p[d] < lo[d] - tol || p[d] > hi[d] + tol)
                return SC_EINVAL;
        }
        if (v3_len(p) > s->bound_r + tol)
            return SC_EINVAL;
    }
    /* ODE's dConvex wants its origin inside: each piece is built about
     * the mean of its points (inside its hull), which piece_ball keeps */
    double *q = sc_alloc_array((size_t)piece_max_pts(ps) * 3, sizeof *q);
    if (!q)
        return SC_ENOMEM;
    const double *p = s->piece_pts;
    int rc = SC_OK;
    for (int k = 0; k < ps->n && rc == SC_OK; p += 3 * ps->count[k], k++) {
        double *ball = &s->piece_ball[4 * k];
        v3_set(ball, 0, 0, 0);
        for (int i = 0; i < ps->count[k]; i++)
            v3_add(ball, ball, &p[3 * i]);
        v3_scale(ball, ball, 1.0 / ps->count[k]);
        for (int i = 0; i < ps->count[k]; i++)
            v3_sub(&q[3 * i], &p[3 * i], ball);
        sc_shape *c = s->pieces[k] = sc_shape_convex(q, ps->count[k]);
        if (!c) {
            rc = sc_last_error() == SC_ENOMEM ? SC_ENOMEM : SC_EINVAL;
            break;
        }
        ball[3] = c->bound_r;
    }
    free(q);
    if (rc == SC_OK)
        rc = mark_inner_faces(s);
    return rc;
}

/* Takes ownership of xyz and tri (freed on failure); ps: convex pieces
 * (NULL: none), moved by -shift like the vertices were. */
static sc_shape *mesh_shape_take(int kind, double *xyz, int nverts, int *tri, int ntris,
                                 const sc_piece_set *ps, const double *shift)
{
    sc_mass_props mp;
    int rc = indices_ok(nverts, tri, ntris) ? compact_vertices(xyz, &nverts, tri, ntris)
                                            : SC_EINVAL;
    if (rc == SC_OK)
        rc = sc_mesh_check(xyz, nverts, tri, ntris, &mp);
    sc_shape *s = rc == SC_OK ? shape_new(kind) : NULL;
    if (!s) {
        free(xyz);
        free(tri);
        sc_set_error(rc == SC_OK ? SC_ENOMEM : rc);
        return NULL;
    }
    s->xyz = xyz;
    s->tri = tri;
    s->nverts = nverts;
    s->ntris = ntris;
    s->mp = mp;
    for (int i = 0; i < nverts; i++)
        s->bound_r = max_d(s->bound_r, v3_len(&xyz[3 * i]));
    s->convex = kind == SC_SHAPE_CONVEX || mesh_is_convex(s);
    rc = build_ode_data(s);
    if (rc == SC_OK && !(s->xyz_soa = sc_soa_pairs(xyz, nverts, 3)))
        rc = SC_ENOMEM;
    if (rc == SC_OK)
        rc = sc_poly_build(s);
    if (rc == SC_OK)
        rc = attach_pieces(s, ps, shift);
    if (rc != SC_OK) {
        shape_free(s);
        sc_set_error(rc);
        return NULL;
    }
    shape_hash(s);
    return s;
}

/* A mesh shape of kind from copies of the caller's arrays. */
static sc_shape *mesh_shape_copy(int kind, const double *xyz, int nverts, const int *tri,
                                 int ntris, const sc_piece_set *ps)
{
    if (!xyz || !tri || nverts <= 0 || ntris <= 0) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    if (nverts > SC_MESH_MAX_VERTS || ntris > SC_MESH_MAX_TRIS) {
        sc_set_error(SC_ETOOBIG);
        return NULL;
    }
    double *v = sc_alloc_array((size_t)nverts * 3, sizeof *v);
    int *t = sc_alloc_array((size_t)ntris * 3, sizeof *t);
    if (!v || !t) {
        free(v);
        free(t);
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    memcpy(v, xyz, (size_t)nverts * 3 * sizeof *v);
    memcpy(t, tri, (size_t)ntris * 3 * sizeof *t);
    return mesh_shape_take(kind, v, nverts, t, ntris, ps, NULL);
}

SC_API sc_shape *sc_shape_mesh(const double *xyz, int nverts, const int *tri, int ntris)
{
    return mesh_shape_copy(SC_SHAPE_MESH, xyz, nverts, tri, ntris, NULL);
}

SC_API sc_shape *sc_shape_mesh_pieces(const double *xyz, int nverts, const int *tri, int ntris,
                                      const double *pts, const int *counts, int npieces)
{
    if (!pts || !counts || npieces < 1) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    sc_piece_set ps = { pts, counts, npieces };
    return mesh_shape_copy(SC_SHAPE_MESH, xyz, nverts, tri, ntris, &ps);
}

SC_API sc_shape *sc_shape_convex(const double *xyz, int npoints)
{
    double *v = NULL;
    int *t = NULL, nv = 0, nt = 0;
    int rc = sc_hull_build(xyz, npoints, &v, &nv, &t, &nt);
    if (rc != SC_OK) {
        sc_set_error(rc);
        return NULL;
    }
    return mesh_shape_take(SC_SHAPE_CONVEX, v, nv, t, nt, NULL, NULL);
}

/* Internal: a mesh made by a builder, moved so that its centre of mass is
 * the origin (then a body's pose is the pose of its centre of mass). */
sc_shape *sc_shape_mesh_centered(double *xyz, int nverts, int *tri, int ntris,
                                 const sc_piece_set *pieces)
{
    sc_mass_props mp;
    int rc = indices_ok(nverts, tri, ntris) ? sc_mesh_check(xyz, nverts, tri, ntris, &mp)
                                            : SC_EINVAL;
    if (rc == SC_OK)
        for (int i = 0; i < nverts; i++)
            v3_sub(&xyz[3 * i], &xyz[3 * i], mp.com);
    return mesh_shape_take(SC_SHAPE_MESH, xyz, nverts, tri, ntris, pieces,
                           rc == SC_OK ? mp.com : NULL);
}

SC_API int sc_shape_kind(const sc_shape *s)
{
    return s ? s->kind : SC_EINVAL;
}

SC_API int sc_shape_triangles(const sc_shape *s)
{
    return s ? s->ntris : 0;
}

SC_API int sc_shape_mass_props(const sc_shape *s, sc_mass_props *out)
{
    if (!s || !out)
        return SC_EINVAL;
    if (s->kind == SC_SHAPE_PLANE)
        return SC_ENOTSUP;
    *out = s->mp;
    return SC_OK;
}

SC_API int sc_shape_pieces(const sc_shape *s)
{
    return s ? s->npieces : 0;
}

SC_API double sc_shape_bounding_radius(const sc_shape *s)
{
    return s ? s->bound_r : NAN;
}

SC_API int sc_shape_mesh_data(const sc_shape *s, const double **xyz, int *nverts,
                              const int **tri, int *ntris)
{
    if (!s)
        return SC_EINVAL;
    if (!s->xyz)
        return SC_ENOTSUP;
    if (xyz) *xyz = s->xyz;
    if (nverts) *nverts = s->nverts;
    if (tri) *tri = s->tri;
    if (ntris) *ntris = s->ntris;
    return SC_OK;
}

SC_API sc_shape *sc_shape_retain(sc_shape *s)
{
    if (s)
        atomic_fetch_add(&s->refs, 1);
    return s;
}

SC_API void sc_shape_release(sc_shape *s)
{
    if (s && atomic_fetch_sub(&s->refs, 1) == 1)
        shape_free(s);
}

/* Internal: a shape from the content its hash covers (a shape received by
 * a daemon, cluster_msg.c); xyz and tri are copied. NULL on error. */
sc_shape *sc_shape_rebuild(int kind, double radius, const double half[3], const double plane[4],
                           const double *xyz, int nverts, const int *tri, int ntris,
                           const sc_piece_set *pieces)
{
    if (pieces && kind != SC_SHAPE_MESH) {
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    switch (kind) {
    case SC_SHAPE_SPHERE:
        return sc_shape_sphere(radius);
    case SC_SHAPE_BOX:
        return sc_shape_box(half[0], half[1], half[2]);
    case SC_SHAPE_PLANE: {
        /* as sent: normalising again could change the last bit */
        double l = v3_len(plane);
        if (!(fabs(l - 1) < 1e-12) || !isfinite(plane[3])) {
            sc_set_error(SC_EINVAL);
            return NULL;
        }
        sc_shape *s = shape_new(SC_SHAPE_PLANE);
        if (!s)
            return NULL;
        memcpy(s->plane, plane, sizeof s->plane);
        s->bound_r = INFINITY;
        shape_hash(s);
        return s;
    }
    case SC_SHAPE_CONVEX:
    case SC_SHAPE_MESH:
        return mesh_shape_copy(kind, xyz, nverts, tri, ntris, pieces);
    default:
        sc_set_error(SC_EINVAL);
        return NULL;
    }
}
