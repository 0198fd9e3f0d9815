/* scene.c - the paper's two scenes, built into a caller's world.
 *
 * sc_scene_spheres_box: Table 1 (27 UV spheres, e = 1, in a closed 4 m box).
 * sc_scene_bolts_nuts: Table 2 and Figs 3-4 (n bolts and nuts dropped on a
 * floor from random, non-overlapping poses).
 * sc_scene_stack, sc_scene_pyramid, sc_scene_wall: structures of boxes that
 * must stand (big islands, docs/DESIGN.md 11).
 *
 * Both use the public API only, so they build exactly what a program could
 * build by hand. They are deterministic: the random poses come from our own
 * splitmix64 stream, never rand(), so a seed gives the same bits everywhere.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "simcluster.h"

#define STEEL_DENSITY 7800.0     /* kg/m^3 */

/* Table 1 */
#define SB_HALF 2.0              /* the box spans [-2, 2]^2 x [0, 4] m */
#define SB_HEIGHT 4.0
#define SB_RADIUS 0.1
#define SB_SPACING 1.0
#define SB_SPEED 1.0             /* m/s, every sphere */

/* Figs 3-4 */
#define BN_MAX 100000
#define BN_RESTITUTION 0.8
#define BN_FRICTION 0.5
#define BN_MAX_TRIES 10000       /* per body; unreachable at BN_ROOM (see below) */

/* ---- a small deterministic PRNG (splitmix64, Steele et al. 2014) ---- */
static uint64_t splitmix64(uint64_t *s)
{
    uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* Uniform in [0, 1), 53 bits. */
static double uniform01(uint64_t *s)
{
    return (double)(splitmix64(s) >> 11) * 0x1.0p-53;
}

/* Uniformly random unit quaternion (Shoemake, Graphics Gems III). */
static void random_quat(uint64_t *s, double q[4])
{
    double u1 = uniform01(s), u2 = 2 * M_PI * uniform01(s), u3 = 2 * M_PI * uniform01(s);
    double a = sqrt(1 - u1), b = sqrt(u1);
    q[0] = a * sin(u2);
    q[1] = a * cos(u2);
    q[2] = b * sin(u3);
    q[3] = b * cos(u3);
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; k++)
        q[k] /= n;
}

/* A static body of shape s at the origin; releases s (NULL s: the shape
 * constructor failed). */
static int add_static(sc_world *w, sc_shape *s, double restitution, double friction)
{
    if (!s)
        return sc_last_error();
    sc_body_desc d = sc_body_desc_default();
    d.shape = s;
    d.mass = 0;
    d.restitution = restitution;
    d.friction = friction;
    int id = sc_body_add(w, &d);
    sc_shape_release(s);
    return id < 0 ? id : SC_OK;
}

/* The walls of the Table 1 box: six static half spaces n.x <= d, each
 * solid outside the box so that its surface faces inward. */
static int add_box_walls(sc_world *w)
{
    static const double planes[6][4] = {
        { 0, 0, 1, 0 },                  /* floor, z <= 0 */
        { 0, 0, -1, -SB_HEIGHT },        /* ceiling, z >= 4 */
        { 1, 0, 0, -SB_HALF },           /* x <= -2 */
        { -1, 0, 0, -SB_HALF },          /* x >= 2 */
        { 0, 1, 0, -SB_HALF },           /* y <= -2 */
        { 0, -1, 0, -SB_HALF },          /* y >= 2 */
    };
    for (int i = 0; i < 6; i++) {
        const double *p = planes[i];
        int rc = add_static(w, sc_shape_plane(p[0], p[1], p[2], p[3]), 1.0, 0.0);
        if (rc != SC_OK)
            return rc;
    }
    return SC_OK;
}

/* n steel UV spheres of radius r (e = 1, no friction) on a cube grid of
 * the given side and spacing around the box centre, x fastest, sphere i
 * moving at speed along the i-th of n directions spread evenly over the
 * unit sphere (Fibonacci spiral: z from +1 towards -1, azimuth in
 * golden-angle steps), so that neighbours head off at different angles
 * and meet each other and the walls within a few seconds. */
static int add_sphere_grid(sc_world *w, int n, int side, double spacing, double r,
                           double speed)
{
    sc_shape *ball = sc_shape_uv_sphere(r, 16, 8);
    if (!ball)
        return sc_last_error();
    sc_body_desc d = sc_body_desc_default();
    d.shape = ball;
    d.mass = SC_MASS_FROM_DENSITY;
    d.density = STEEL_DENSITY;
    d.restitution = 1.0;
    d.friction = 0.0;
    const double golden = M_PI * (3 - sqrt(5.0));
    int rc = SC_OK;
    for (int i = 0; i < n && rc == SC_OK; i++) {
        int ix = i % side, iy = (i / side) % side, iz = i / (side * side);
        d.pos[0] = (ix - (side - 1) / 2.0) * spacing;
        d.pos[1] = (iy - (side - 1) / 2.0) * spacing;
        d.pos[2] = 0.5 * SB_HEIGHT + (iz - (side - 1) / 2.0) * spacing;
        double z = 1 - (2 * i + 1) / (double)n, rr = sqrt(1 - z * z), phi = golden * i;
        d.vel[0] = speed * rr * cos(phi);
        d.vel[1] = speed * rr * sin(phi);
        d.vel[2] = speed * z;
        int id = sc_body_add(w, &d);
        if (id < 0)
            rc = id;
    }
    sc_shape_release(ball);
    return rc;
}

SC_API int sc_scene_spheres_box(sc_world *w)
{
    if (!w)
        return SC_EINVAL;
    int rc = add_box_walls(w);
    /* 3 x 3 x 3 at 1 m spacing around the box centre (0, 0, 2), 224
     * triangles each, 1 m/s */
    return rc == SC_OK ? add_sphere_grid(w, 27, 3, SB_SPACING, SB_RADIUS, SB_SPEED) : rc;
}

SC_API int sc_scene_elastic_box(sc_world *w, int n, double radius, double speed)
{
    if (!w || n < 1 || n > SC_ELASTIC_BOX_MAX || !(radius > 0) || !(radius < 0.25) ||
        !(speed >= 0) || !isfinite(speed))
        return SC_EINVAL;
    int rc = add_box_walls(w);
    /* a cube grid of side ceil(cbrt(n)) filling the middle 3.2 m */
    int side = (int)ceil(cbrt((double)n));
    return rc == SC_OK ? add_sphere_grid(w, n, side, 3.2 / side, radius, speed) : rc;
}

/* ---- random non-overlapping poses for the bolt/nut drop ---- */

/* Each body gets ROOM^3 of the column, ROOM = 4 bounding radii of the larger
 * piece: its bounding sphere then fills at most ~6.5 % of the column, so a
 * random candidate is rarely rejected and placement is O(n). */
#define BN_ROOM 4.0

typedef struct placed {
    sc_shape *shape;
    sc_pose pose;
    double r;                    /* bounding radius */
} placed;

/* A uniform grid of cells 2 * rmax wide over the column: two bounding
 * spheres that overlap lie in the same or adjacent cells, so looking at the
 * 3 x 3 x 3 cells around a candidate finds every placed body whose bounding
 * sphere it touches, as a test against all of them would. */
typedef struct grid {
    double lo[3], cell;
    int dim[3];
    int *head;                   /* first body of each cell, -1 = empty */
    int *next;                   /* next body of the same cell */
} grid;

static int grid_cell_axis(const grid *g, const double p[3], int k)
{
    int c = (int)floor((p[k] - g->lo[k]) / g->cell);
    return c < 0 ? 0 : c >= g->dim[k] ? g->dim[k] - 1 : c;
}

/* 1 if shape s at pose p overlaps none of the bodies placed so far (bounding
 * spheres first, then the exact sc_collide), 0 if it overlaps one, or a
 * negative code from sc_collide. */
static int pose_is_free(const grid *g, const placed *pl, const sc_shape *s,
                        const sc_pose *p, double r)
{
    int c[3];
    for (int k = 0; k < 3; k++)
        c[k] = grid_cell_axis(g, p->pos, k);
    for (int i = c[0] - 1; i <= c[0] + 1; i++)
        for (int j = c[1] - 1; j <= c[1] + 1; j++)
            for (int k = c[2] - 1; k <= c[2] + 1; k++) {
                if (i < 0 || j < 0 || k < 0 || i >= g->dim[0] || j >= g->dim[1] ||
                    k >= g->dim[2])
                    continue;
                for (int b = g->head[(k * g->dim[1] + j) * g->dim[0] + i]; b >= 0;
                     b = g->next[b]) {
                    double d[3], rr = r + pl[b].r;
                    for (int m = 0; m < 3; m++)
                        d[m] = p->pos[m] - pl[b].pose.pos[m];
                    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > rr * rr)
                        continue;
                    sc_contact ct[SC_MAX_PAIR_CONTACTS];
                    int n = sc_collide(pl[b].shape, &pl[b].pose, s, p, ct,
                                       SC_MAX_PAIR_CONTACTS);
                    if (n != 0)
                        return n < 0 ? n : 0;
                }
            }
    return 1;
}

/* Draw the n poses (body i: bolt if i is even, nut if odd) into pl. */
static int place_bodies(placed *pl, int n, sc_shape *bolt, sc_shape *nut, uint64_t seed)
{
    double rb = sc_shape_bounding_radius(bolt), rn = sc_shape_bounding_radius(nut);
    double rmax = fmax(rb, rn), room = BN_ROOM * rmax;
    /* The column: a square footprint of k x k rooms, k = ceil(cbrt(n)), and
     * a height that gives every body one room; it starts 2 rmax above the
     * floor so that no body touches the floor. */
    int k = (int)ceil(cbrt((double)n) - 1e-9);
    double side = k * room, height = (double)n * room * room * room / (side * side);
    grid g = { .lo = { -0.5 * side, -0.5 * side, 2 * rmax }, .cell = 2 * rmax };
    double extent[3] = { side, side, height };
    size_t cells = 1;
    for (int m = 0; m < 3; m++) {
        g.dim[m] = (int)ceil(extent[m] / g.cell) + 1;
        cells *= (size_t)g.dim[m];
    }
    g.head = malloc(cells * sizeof *g.head);
    g.next = malloc((size_t)n * sizeof *g.next);
    if (!g.head || !g.next) {
        free(g.head);
        free(g.next);
        return SC_ENOMEM;
    }
    for (size_t c = 0; c < cells; c++)
        g.head[c] = -1;
    uint64_t rng = seed;
    int rc = SC_OK;
    for (int i = 0; i < n && rc == SC_OK; i++) {
        placed cand = { .shape = i % 2 == 0 ? bolt : nut, .r = i % 2 == 0 ? rb : rn };
        int found = 0;
        for (int t = 0; t < BN_MAX_TRIES && !found && rc == SC_OK; t++) {
            for (int m = 0; m < 3; m++)
                cand.pose.pos[m] = g.lo[m] + extent[m] * uniform01(&rng);
            random_quat(&rng, cand.pose.quat);
            int ok = pose_is_free(&g, pl, cand.shape, &cand.pose, cand.r);
            if (ok < 0)
                rc = ok;
            found = ok == 1;
        }
        if (rc == SC_OK && !found)
            rc = SC_ENOSOLUTION;     /* no free pose; cannot happen at this density */
        if (rc != SC_OK)
            break;
        pl[i] = cand;
        int c = (grid_cell_axis(&g, cand.pose.pos, 2) * g.dim[1] +
                 grid_cell_axis(&g, cand.pose.pos, 1)) * g.dim[0] +
                grid_cell_axis(&g, cand.pose.pos, 0);
        g.next[i] = g.head[c];
        g.head[c] = i;
    }
    free(g.head);
    free(g.next);
    return rc;
}

SC_API int sc_scene_bolts_nuts(sc_world *w, int n, uint64_t seed)
{
    if (!w || n < 1 || n > BN_MAX)
        return SC_EINVAL;
    sc_shape *bolt = sc_shape_bolt();
    sc_shape *nut = bolt ? sc_shape_nut() : NULL;
    if (!bolt || !nut) {
        int err = sc_last_error();
        sc_shape_release(bolt);
        return err;
    }
    /* All poses are drawn before any body is added: a failure to place
     * them (or bad arguments) adds nothing to the world. */
    placed *pl = malloc((size_t)n * sizeof *pl);
    int rc = pl ? place_bodies(pl, n, bolt, nut, seed) : SC_ENOMEM;
    if (rc == SC_OK)
        rc = add_static(w, sc_shape_plane(0, 0, 1, 0), BN_RESTITUTION, BN_FRICTION);
    sc_body_desc d = sc_body_desc_default();
    d.mass = SC_MASS_FROM_DENSITY;
    d.density = STEEL_DENSITY;
    d.restitution = BN_RESTITUTION;
    d.friction = BN_FRICTION;
    for (int i = 0; i < n && rc == SC_OK; i++) {
        d.shape = pl[i].shape;
        for (int m = 0; m < 3; m++)
            d.pos[m] = pl[i].pose.pos[m];
        for (int m = 0; m < 4; m++)
            d.quat[m] = pl[i].pose.quat[m];
        int id = sc_body_add(w, &d);
        if (id < 0)
            rc = id;
    }
    free(pl);
    sc_shape_release(bolt);
    sc_shape_release(nut);
    return rc;
}

/* ---- the parts bin: the dense pile (docs/DESIGN.md section 11) ---- */

#define BIN_LAYERS 4
#define BIN_GAP 1.02              /* grid pitch, in bounding diameters */

/* n bolts and nuts (body i: bolt if i is even) on a square grid one part
 * length apart, BIN_LAYERS layers deep, random orientations, inside four
 * walls that fit the grid: they fall a few centimetres onto each other and
 * the floor and pile up, every part touching several others. The pitch is
 * a little over one bounding diameter, so no two start in contact. */
SC_API int sc_scene_bin(sc_world *w, int n, uint64_t seed)
{
    if (!w || n < 1 || n > BN_MAX)
        return SC_EINVAL;
    sc_shape *bolt = sc_shape_bolt();
    sc_shape *nut = bolt ? sc_shape_nut() : NULL;
    if (!bolt || !nut) {
        int err = sc_last_error();
        sc_shape_release(bolt);
        return err;
    }
    double rmax = fmax(sc_shape_bounding_radius(bolt), sc_shape_bounding_radius(nut));
    double pitch = BIN_GAP * 2 * rmax;
    int per_layer = (n + BIN_LAYERS - 1) / BIN_LAYERS;
    int k = (int)ceil(sqrt((double)per_layer) - 1e-9);
    double half = 0.5 * k * pitch;
    /* floor, then the walls x = +-half, y = +-half (solid outside) */
    const double planes[5][4] = {
        { 0, 0, 1, 0 }, { 1, 0, 0, -half }, { -1, 0, 0, -half },
        { 0, 1, 0, -half }, { 0, -1, 0, -half },
    };
    int rc = SC_OK;
    for (int i = 0; i < 5 && rc == SC_OK; i++)
        rc = add_static(w, sc_shape_plane(planes[i][0], planes[i][1], planes[i][2], planes[i][3]),
                        BN_RESTITUTION, BN_FRICTION);
    sc_body_desc d = sc_body_desc_default();
    d.mass = SC_MASS_FROM_DENSITY;
    d.density = STEEL_DENSITY;
    d.restitution = BN_RESTITUTION;
    d.friction = BN_FRICTION;
    uint64_t rng = seed;
    for (int i = 0; i < n && rc == SC_OK; i++) {
        int layer = i / per_layer, j = i % per_layer;
        d.shape = i % 2 == 0 ? bolt : nut;
        d.pos[0] = -half + (j % k + 0.5) * pitch;
        d.pos[1] = -half + (j / k + 0.5) * pitch;
        d.pos[2] = rmax * BIN_GAP + layer * pitch;
        random_quat(&rng, d.quat);
        int id = sc_body_add(w, &d);
        if (id < 0)
            rc = id;
    }
    sc_shape_release(bolt);
    sc_shape_release(nut);
    return rc;
}

/* ---- structures ---- */

#define ST_HALF 0.1              /* m, the cubes' half extent */
#define ST_SINK 2e-4             /* m, each layer into the one below */
#define ST_PITCH 0.201           /* m, a wall's cubes: 1 mm apart */
#define ST_DENSITY 600.0         /* kg/m^3, wood */
#define ST_RESTITUTION 0.2
#define ST_FRICTION 0.6

/* A floor and a cube shape; *cube NULL on error (the code returned). */
static int structure_begin(sc_world *w, sc_shape **cube)
{
    *cube = NULL;
    int rc = add_static(w, sc_shape_plane(0, 0, 1, 0), ST_RESTITUTION, ST_FRICTION);
    if (rc != SC_OK)
        return rc;
    *cube = sc_shape_box(ST_HALF, ST_HALF, ST_HALF);
    return *cube ? SC_OK : sc_last_error();
}

/* A cube of layer k (0: on the floor) at x. */
static int add_cube(sc_world *w, sc_shape *cube, double x, int k)
{
    sc_body_desc d = sc_body_desc_default();
    d.shape = cube;
    d.mass = SC_MASS_FROM_DENSITY;
    d.density = ST_DENSITY;
    d.restitution = ST_RESTITUTION;
    d.friction = ST_FRICTION;
    d.pos[0] = x;
    d.pos[2] = ST_HALF - ST_SINK + k * (2 * ST_HALF - ST_SINK);
    int id = sc_body_add(w, &d);
    return id < 0 ? id : SC_OK;
}

SC_API int sc_scene_stack(sc_world *w, int n, double offset)
{
    if (!w || n < 1 || n > SC_STRUCTURE_MAX || !(fabs(offset) <= 0.05))
        return SC_EINVAL;
    sc_shape *cube;
    int rc = structure_begin(w, &cube);
    for (int k = 0; k < n && rc == SC_OK; k++)
        rc = add_cube(w, cube, k % 2 ? offset : 0, k);
    sc_shape_release(cube);
    return rc;
}

SC_API int sc_scene_pyramid(sc_world *w, int rows)
{
    if (!w || rows < 1 || (long)rows * (rows + 1) / 2 > SC_STRUCTURE_MAX)
        return SC_EINVAL;
    sc_shape *cube;
    int rc = structure_begin(w, &cube);
    for (int r = 0; r < rows && rc == SC_OK; r++)
        for (int i = 0; i < rows - r && rc == SC_OK; i++)
            rc = add_cube(w, cube, 2 * ST_HALF * i + ST_HALF * r - ST_HALF * (rows - 1), r);
    sc_shape_release(cube);
    return rc;
}

SC_API int sc_scene_wall(sc_world *w, int cols, int rows)
{
    if (!w || cols < 2 || rows < 1 || (long)cols * rows > SC_STRUCTURE_MAX)
        return SC_EINVAL;
    sc_shape *cube;
    int rc = structure_begin(w, &cube);
    for (int r = 0; r < rows && rc == SC_OK; r++)
        for (int i = 0; i < cols && rc == SC_OK; i++)
            rc = add_cube(w, cube, ST_PITCH * i + 0.5 * ST_HALF * (r % 2) - ST_PITCH * (cols - 1) / 2,
                          r);
    sc_shape_release(cube);
    return rc;
}
