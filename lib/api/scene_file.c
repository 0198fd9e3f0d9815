/* scene_file.c - scene files (simcluster.conf(5), section SCENE FILES): a
 * plain-text world description read into an sc_scene, then built into any
 * number of worlds. The text is hostile input: every read is bounded,
 * every count capped before it sizes an allocation, numbers must be finite
 * whole words, read in the C locale. Errors stop the read and say
 * FILE:LINE:COLUMN: what. Only the public API builds, so a scene file
 * builds exactly what a program could build by hand. */
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "world.h"

#define SCENE_MAX_BYTES ((size_t)16 << 20)  /* largest scene file read */
#define SCENE_MAX_SHAPES 256
#define SCENE_MAX_MATERIALS 64
#define SCENE_MAX_BODIES 100000             /* after grids are expanded */
#define SCENE_MAX_GRID 1000                 /* per grid axis */
#define NAME_MAX_CHARS 63
#define TOK_MAX 32                          /* words on one line */
#define WORD_MAX_CHARS 4095                 /* longest word (a path) */

typedef struct named_shape {
    char name[NAME_MAX_CHARS + 1];
    sc_shape *shape;
} named_shape;

typedef struct material {
    char name[NAME_MAX_CHARS + 1];
    double density, restitution, friction;  /* < 0: not given */
} material;

typedef struct scene_body {
    sc_body_desc d;
    int grid[3];
    double step[3];
} scene_body;

struct sc_scene {
    double gravity[3];
    int has_gravity;
    double tolerance;                       /* 0: not given */
    named_shape shapes[SCENE_MAX_SHAPES];
    int nshapes;
    material mats[SCENE_MAX_MATERIALS];
    int nmats;
    scene_body *bodies;
    int nbodies, cap;
    long total;                             /* bodies after grids */
};

/* ---- words ------------------------------------------------------------- */

typedef struct word {
    const char *s;          /* not NUL-terminated */
    size_t n;
    int col;                /* 1-based */
} word;

typedef struct reader {
    const char *name, *dir;
    int line;
    char *err;
    size_t errlen;
    locale_t c_loc;
    word w[TOK_MAX];
    int nw;
} reader;

/* Write "NAME:LINE:COL: what" into the caller's buffer; returns code. */
static int fail(reader *r, int col, int code, const char *fmt, ...)
{
    if (r->err && r->errlen) {
        int k = snprintf(r->err, r->errlen, "%s:%d:%d: ", r->name, r->line, col);
        if (k >= 0 && (size_t)k < r->errlen) {
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(r->err + k, r->errlen - (size_t)k, fmt, ap);
            va_end(ap);
        }
    }
    return code;
}

static int is_blank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
}

/* Split line [s, s + n) into r->w; SC_OK or an error (written). */
static int split(reader *r, const char *s, size_t n)
{
    r->nw = 0;
    size_t i = 0;
    while (i < n) {
        if (is_blank(s[i])) {
            i++;
            continue;
        }
        if (s[i] == '#')
            break;
        int col = (int)i + 1;
        if (s[i] == '\0')
            return fail(r, col, SC_EFORMAT, "a NUL byte (is this a text file?)");
        if (r->nw == TOK_MAX)
            return fail(r, col, SC_EFORMAT, "more than %d words on one line", TOK_MAX);
        word *w = &r->w[r->nw++];
        w->col = col;
        if (s[i] == '"') {
            size_t j = i + 1;
            while (j < n && s[j] != '"' && s[j] != '\0')
                j++;
            if (j == n || s[j] != '"')
                return fail(r, col, SC_EFORMAT, "unterminated quote");
            w->s = s + i + 1;
            w->n = j - i - 1;
            i = j + 1;
            if (i < n && !is_blank(s[i]) && s[i] != '#')
                return fail(r, (int)i + 1, SC_EFORMAT, "a blank must follow a closing quote");
        } else {
            size_t j = i;
            while (j < n && !is_blank(s[j]) && s[j] != '#' && s[j] != '"' && s[j] != '\0')
                j++;
            if (j < n && s[j] == '"')
                return fail(r, (int)j + 1, SC_EFORMAT, "a quote inside a word");
            w->s = s + i;
            w->n = j - i;
            i = j;
        }
        if (w->n > WORD_MAX_CHARS)
            return fail(r, col, SC_ETOOBIG, "a word longer than %d characters", WORD_MAX_CHARS);
    }
    return SC_OK;
}

static int is(const word *w, const char *s)
{
    return w->n == strlen(s) && !memcmp(w->s, s, w->n);
}

/* The word as a C string in buf (size > WORD_MAX_CHARS). */
static const char *cstr(const word *w, char *buf)
{
    memcpy(buf, w->s, w->n);
    buf[w->n] = 0;
    return buf;
}

/* Word k of the line, or an error naming what was expected there. */
static int need(reader *r, int k, const char *what)
{
    if (k < r->nw)
        return SC_OK;
    int col = r->nw ? r->w[r->nw - 1].col + (int)r->w[r->nw - 1].n : 1;
    return fail(r, col, SC_EFORMAT, "missing %s", what);
}

/* Word k as a finite number in [lo, hi]. */
static int number(reader *r, int k, const char *what, double lo, double hi, double *out)
{
    int rc = need(r, k, what);
    if (rc != SC_OK)
        return rc;
    const word *w = &r->w[k];
    char buf[64];
    if (w->n == 0 || w->n >= sizeof buf)
        return fail(r, w->col, SC_EFORMAT, "%s: not a number", what);
    cstr(w, buf);
    char *end;
    errno = 0;
    double v = strtod_l(buf, &end, r->c_loc);
    if (end != buf + w->n || !isfinite(v) || errno == ERANGE)
        return fail(r, w->col, SC_EFORMAT, "%s: '%s' is not a finite number", what, buf);
    if (v < lo || v > hi)
        return fail(r, w->col, SC_EINVAL, "%s: %s is out of range [%g, %g]", what, buf, lo, hi);
    *out = v;
    return SC_OK;
}

/* Words k.. as n numbers. */
static int numbers(reader *r, int k, int n, const char *what, double lo, double hi, double *out)
{
    for (int i = 0; i < n; i++) {
        int rc = number(r, k + i, what, lo, hi, &out[i]);
        if (rc != SC_OK)
            return rc;
    }
    return SC_OK;
}

static int integer(reader *r, int k, const char *what, int lo, int hi, int *out)
{
    double v = 0;
    int rc = number(r, k, what, lo, hi, &v);
    if (rc != SC_OK)
        return rc;
    if (v != floor(v))
        return fail(r, r->w[k].col, SC_EINVAL, "%s: a whole number is needed", what);
    *out = (int)v;
    return SC_OK;
}

/* Word k as a new name (letters, digits, _ . -) not in use by another of
 * its kind. */
static int new_name(reader *r, int k, const char *kind, const char *names, size_t stride,
                    int count, char *out)
{
    int rc = need(r, k, "a name");
    if (rc != SC_OK)
        return rc;
    const word *w = &r->w[k];
    if (w->n == 0 || w->n > NAME_MAX_CHARS)
        return fail(r, w->col, SC_EINVAL, "a %s name has 1 to %d characters", kind,
                    NAME_MAX_CHARS);
    for (size_t i = 0; i < w->n; i++) {
        char c = w->s[i];
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '_' || c == '.' || c == '-'))
            return fail(r, w->col, SC_EINVAL, "a %s name has only letters, digits, _ . -",
                        kind);
    }
    for (int i = 0; i < count; i++)
        if (is(w, names + (size_t)i * stride))
            return fail(r, w->col, SC_EINVAL, "%s '%.*s' is already defined", kind, (int)w->n,
                        w->s);
    memcpy(out, w->s, w->n);
    out[w->n] = 0;
    return SC_OK;
}

/* ---- directives ---------------------------------------------------------- */

static int no_more(reader *r, int k)
{
    if (k < r->nw)
        return fail(r, r->w[k].col, SC_EFORMAT, "unexpected '%.*s'", (int)r->w[k].n, r->w[k].s);
    return SC_OK;
}

static int do_gravity(reader *r, sc_scene *sc)
{
    int rc = numbers(r, 1, 3, "gravity", -1e6, 1e6, sc->gravity);
    if (rc == SC_OK)
        rc = no_more(r, 4);
    sc->has_gravity = 1;
    return rc;
}

static int do_tolerance(reader *r, sc_scene *sc)
{
    int rc = number(r, 1, "tolerance (m)", 1e-9, 1, &sc->tolerance);
    if (rc == SC_OK && !(sc->tolerance > 0))
        rc = fail(r, r->w[1].col, SC_EINVAL, "tolerance must be above 0");
    return rc == SC_OK ? no_more(r, 2) : rc;
}

static int do_material(reader *r, sc_scene *sc)
{
    if (sc->nmats == SCENE_MAX_MATERIALS)
        return fail(r, r->w[0].col, SC_ETOOBIG, "more than %d materials", SCENE_MAX_MATERIALS);
    material m = { .density = -1, .restitution = -1, .friction = -1 };
    int rc = new_name(r, 1, "material", sc->mats[0].name, sizeof sc->mats[0], sc->nmats, m.name);
    for (int k = 2; rc == SC_OK && k < r->nw; k += 2) {
        const word *w = &r->w[k];
        double *dst = is(w, "density") ? &m.density : is(w, "restitution") ? &m.restitution
                      : is(w, "friction")                               ? &m.friction
                                                                        : NULL;
        if (!dst)
            return fail(r, w->col, SC_EFORMAT,
                        "unknown material property '%.*s' (density, restitution, friction)",
                        (int)w->n, w->s);
        if (*dst >= 0)
            return fail(r, w->col, SC_EINVAL, "'%.*s' given twice", (int)w->n, w->s);
        if (dst == &m.density)
            rc = number(r, k + 1, "density (kg/m^3)", 1e-9, 1e9, dst);
        else if (dst == &m.restitution)
            rc = number(r, k + 1, "restitution", 0, 1, dst);
        else
            rc = number(r, k + 1, "friction", 0, 1e3, dst);
    }
    if (rc == SC_OK)
        sc->mats[sc->nmats++] = m;
    return rc;
}

/* A copy of mesh shape s with every vertex times k (NULL: sc_last_error). */
static sc_shape *scaled(const sc_shape *s, double k, int hull)
{
    const double *xyz;
    const int *tri;
    int nv, nt;
    if (sc_shape_mesh_data(s, &xyz, &nv, &tri, &nt) != SC_OK)
        return NULL;
    double *p = malloc((size_t)nv * 3 * sizeof *p);
    if (!p) {
        sc_set_error(SC_ENOMEM);
        return NULL;
    }
    for (int i = 0; i < 3 * nv; i++)
        p[i] = k * xyz[i];
    sc_shape *out = hull ? sc_shape_convex(p, nv) : sc_shape_mesh(p, nv, tri, nt);
    free(p);
    return out;
}

/* Load a mesh file named by word k, relative to the scene's folder. */
static sc_shape *load_mesh(reader *r, int k, int *rc)
{
    char rel[WORD_MAX_CHARS + 1], path[2 * WORD_MAX_CHARS + 2];
    cstr(&r->w[k], rel);
    if (rel[0] == '\0') {
        *rc = fail(r, r->w[k].col, SC_EINVAL, "an empty file name");
        return NULL;
    }
    if (rel[0] == '/' || !r->dir || !r->dir[0])
        snprintf(path, sizeof path, "%s", rel);
    else
        snprintf(path, sizeof path, "%.*s/%s", WORD_MAX_CHARS, r->dir, rel);
    /* the loader's message names the mesh file and, when it is malformed,
     * its line (or a binary STL's byte offset) */
    char why[256];
    sc_shape *s = sc_shape_load_err(path, why, sizeof why);
    if (!s)
        *rc = fail(r, r->w[k].col, sc_last_error(), "%s", why);
    return s;
}

static int do_shape(reader *r, sc_scene *sc)
{
    if (sc->nshapes == SCENE_MAX_SHAPES)
        return fail(r, r->w[0].col, SC_ETOOBIG, "more than %d shapes", SCENE_MAX_SHAPES);
    named_shape ns = { .shape = NULL };
    int rc = new_name(r, 1, "shape", sc->shapes[0].name, sizeof sc->shapes[0], sc->nshapes,
                      ns.name);
    if (rc == SC_OK)
        rc = need(r, 2, "a shape kind (sphere, box, plane, uvsphere, bolt, nut, mesh, hull)");
    if (rc != SC_OK)
        return rc;
    const word *kind = &r->w[2];
    double a[4];
    int next = 3, meshy = 0, hull = 0;
    if (is(kind, "sphere")) {
        rc = number(r, 3, "radius (m)", 1e-6, 1e6, a);
        if (rc == SC_OK)
            ns.shape = sc_shape_sphere(a[0]);
        next = 4;
    } else if (is(kind, "box")) {
        rc = numbers(r, 3, 3, "half extent (m)", 1e-6, 1e6, a);
        if (rc == SC_OK)
            ns.shape = sc_shape_box(a[0], a[1], a[2]);
        next = 6;
    } else if (is(kind, "plane")) {
        rc = numbers(r, 3, 4, "plane (nx ny nz d)", -1e6, 1e6, a);
        if (rc == SC_OK && a[0] * a[0] + a[1] * a[1] + a[2] * a[2] < 1e-24)
            return fail(r, r->w[3].col, SC_EINVAL, "the plane's normal is zero");
        if (rc == SC_OK)
            ns.shape = sc_shape_plane(a[0], a[1], a[2], a[3]);
        next = 7;
    } else if (is(kind, "uvsphere")) {
        int sl = 0, st = 0;
        rc = number(r, 3, "radius (m)", 1e-6, 1e6, a);
        if (rc == SC_OK)
            rc = integer(r, 4, "slices", 3, 1000, &sl);
        if (rc == SC_OK)
            rc = integer(r, 5, "stacks", 2, 1000, &st);
        if (rc == SC_OK)
            ns.shape = sc_shape_uv_sphere(a[0], sl, st);
        next = 6;
        meshy = 1;
    } else if (is(kind, "bolt") || is(kind, "nut")) {
        ns.shape = is(kind, "bolt") ? sc_shape_bolt() : sc_shape_nut();
        meshy = 1;
    } else if (is(kind, "mesh") || is(kind, "hull")) {
        hull = is(kind, "hull");
        rc = need(r, 3, "a mesh file (OBJ or STL)");
        if (rc == SC_OK) {
            ns.shape = load_mesh(r, 3, &rc);
            if (!ns.shape)
                return rc;
        }
        next = 4;
        meshy = 1;
    } else {
        return fail(r, kind->col, SC_EFORMAT,
                    "unknown shape kind '%.*s' (sphere, box, plane, uvsphere, bolt, nut, mesh, "
                    "hull)",
                    (int)kind->n, kind->s);
    }
    if (rc == SC_OK && !ns.shape)
        rc = fail(r, kind->col, sc_last_error(), "%s", sc_strerror(sc_last_error()));
    double scale = 1;
    int scale_col = 0;
    if (rc == SC_OK && next < r->nw && is(&r->w[next], "scale")) {
        scale_col = r->w[next].col;
        if (!meshy)
            rc = fail(r, scale_col, SC_EINVAL,
                      "scale is for meshes (uvsphere, bolt, nut, mesh, hull); give the size "
                      "instead");
        else
            rc = number(r, next + 1, "scale", 1e-9, 1e9, &scale);
        next += 2;
    }
    if (rc == SC_OK)
        rc = no_more(r, next);
    if (rc == SC_OK && (scale != 1 || hull)) {
        sc_shape *t = scaled(ns.shape, scale, hull);
        sc_shape_release(ns.shape);
        ns.shape = t;
        if (!t)
            rc = fail(r, scale_col ? scale_col : kind->col, sc_last_error(), "%s",
                      sc_strerror(sc_last_error()));
    }
    if (rc != SC_OK) {
        sc_shape_release(ns.shape);
        return rc;
    }
    sc->shapes[sc->nshapes++] = ns;
    return SC_OK;
}

/* Body option flags: each at most once. */
enum { B_MAT, B_STATIC, B_MASS, B_DENSITY, B_POS, B_QUAT, B_ROT, B_VEL, B_OMEGA, B_REST,
       B_FRIC, B_GRID, B_COUNT };
static const char *const body_keys[B_COUNT] = {
    "material", "static", "mass", "density", "pos", "quat", "rot", "vel", "omega",
    "restitution", "friction", "grid"
};

static int do_body(reader *r, sc_scene *sc)
{
    int rc = need(r, 1, "a shape name");
    if (rc != SC_OK)
        return rc;
    const word *sw = &r->w[1];
    const named_shape *ns = NULL;
    for (int i = 0; i < sc->nshapes && !ns; i++)
        if (is(sw, sc->shapes[i].name))
            ns = &sc->shapes[i];
    if (!ns)
        return fail(r, sw->col, SC_EINVAL, "no shape named '%.*s' (define it above with shape)",
                    (int)sw->n, sw->s);
    scene_body b = { .d = sc_body_desc_default(), .grid = { 1, 1, 1 } };
    b.d.shape = ns->shape;
    int plane = sc_shape_kind(ns->shape) == SC_SHAPE_PLANE;
    int seen[B_COUNT] = { 0 };
    const material *mat = NULL;
    double mass = -1, density = -1, e = -1, mu = -1, rot[4];
    for (int k = 2; k < r->nw;) {
        const word *w = &r->w[k];
        int key = 0;
        while (key < B_COUNT && !is(w, body_keys[key]))
            key++;
        if (key == B_COUNT)
            return fail(r, w->col, SC_EFORMAT,
                        "unknown body option '%.*s' (material, static, mass, density, pos, "
                        "quat, rot, vel, omega, restitution, friction, grid)",
                        (int)w->n, w->s);
        if (seen[key]++)
            return fail(r, w->col, SC_EINVAL, "'%s' given twice", body_keys[key]);
        k++;
        switch (key) {
        case B_MAT:
            rc = need(r, k, "a material name");
            for (int i = 0; rc == SC_OK && i < sc->nmats && !mat; i++)
                if (is(&r->w[k], sc->mats[i].name))
                    mat = &sc->mats[i];
            if (rc == SC_OK && !mat)
                rc = fail(r, r->w[k].col, SC_EINVAL, "no material named '%.*s'",
                          (int)r->w[k].n, r->w[k].s);
            k++;
            break;
        case B_STATIC: break;
        case B_MASS: rc = number(r, k++, "mass (kg)", 1e-12, 1e12, &mass); break;
        case B_DENSITY: rc = number(r, k++, "density (kg/m^3)", 1e-9, 1e9, &density); break;
        case B_POS: rc = numbers(r, k, 3, "position (m)", -1e6, 1e6, b.d.pos); k += 3; break;
        case B_QUAT:
            rc = numbers(r, k, 4, "quaternion (w x y z)", -1e6, 1e6, b.d.quat);
            if (rc == SC_OK && sqrt(b.d.quat[0] * b.d.quat[0] + b.d.quat[1] * b.d.quat[1] +
                                    b.d.quat[2] * b.d.quat[2] + b.d.quat[3] * b.d.quat[3]) < 1e-9)
                rc = fail(r, r->w[k].col, SC_EINVAL, "the quaternion is zero");
            k += 4;
            break;
        case B_ROT:
            rc = numbers(r, k, 4, "rotation (axis x y z, degrees)", -1e6, 1e6, rot);
            if (rc == SC_OK) {
                double n = sqrt(rot[0] * rot[0] + rot[1] * rot[1] + rot[2] * rot[2]);
                if (n < 1e-12)
                    rc = fail(r, r->w[k].col, SC_EINVAL, "the rotation axis is zero");
                double h = rot[3] * M_PI / 360, s = n > 0 ? sin(h) / n : 0;
                b.d.quat[0] = cos(h);
                for (int i = 0; i < 3; i++)
                    b.d.quat[1 + i] = s * rot[i];
            }
            k += 4;
            break;
        case B_VEL: rc = numbers(r, k, 3, "velocity (m/s)", -1e6, 1e6, b.d.vel); k += 3; break;
        case B_OMEGA:
            rc = numbers(r, k, 3, "angular velocity (rad/s)", -1e6, 1e6, b.d.omega);
            k += 3;
            break;
        case B_REST: rc = number(r, k++, "restitution", 0, 1, &e); break;
        case B_FRIC: rc = number(r, k++, "friction", 0, 1e3, &mu); break;
        case B_GRID:
            for (int i = 0; rc == SC_OK && i < 3; i++)
                rc = integer(r, k + i, "grid count", 1, SCENE_MAX_GRID, &b.grid[i]);
            if (rc == SC_OK)
                rc = numbers(r, k + 3, 3, "grid spacing (m)", -1e6, 1e6, b.step);
            k += 6;
            break;
        }
        if (rc != SC_OK)
            return rc;
    }
    if (seen[B_QUAT] && seen[B_ROT])
        return fail(r, r->w[1].col, SC_EINVAL, "give quat or rot, not both");
    if (seen[B_STATIC] + seen[B_MASS] + seen[B_DENSITY] > 1)
        return fail(r, r->w[1].col, SC_EINVAL, "give one of static, mass and density");
    if (plane && (seen[B_MASS] || seen[B_DENSITY] || seen[B_VEL] || seen[B_OMEGA]))
        return fail(r, r->w[1].col, SC_EINVAL, "a plane cannot move: it takes no mass, "
                                               "density or velocity");
    if (seen[B_STATIC] || plane)
        b.d.mass = 0;
    else if (mass > 0)
        b.d.mass = mass;
    else if (density > 0 || (mat && mat->density > 0)) {
        b.d.mass = SC_MASS_FROM_DENSITY;
        b.d.density = density > 0 ? density : mat->density;
    }
    b.d.restitution = e >= 0 ? e : mat && mat->restitution >= 0 ? mat->restitution
                                                                : b.d.restitution;
    b.d.friction = mu >= 0 ? mu : mat && mat->friction >= 0 ? mat->friction : b.d.friction;
    long n = (long)b.grid[0] * b.grid[1] * b.grid[2];
    if (n > SCENE_MAX_BODIES - sc->total)
        return fail(r, r->w[0].col, SC_ETOOBIG, "more than %d bodies", SCENE_MAX_BODIES);
    if (sc->nbodies == sc->cap) {
        int cap = sc->cap ? 2 * sc->cap : 16;
        scene_body *nb = realloc(sc->bodies, (size_t)cap * sizeof *nb);
        if (!nb)
            return fail(r, r->w[0].col, SC_ENOMEM, "out of memory");
        sc->bodies = nb;
        sc->cap = cap;
    }
    sc->bodies[sc->nbodies++] = b;
    sc->total += n;
    return SC_OK;
}

/* ---- the public calls ------------------------------------------------------ */

SC_API void sc_scene_free(sc_scene *sc)
{
    if (!sc)
        return;
    for (int i = 0; i < sc->nshapes; i++)
        sc_shape_release(sc->shapes[i].shape);
    free(sc->bodies);
    free(sc);
}

SC_API sc_scene *sc_scene_parse(const char *text, size_t len, const char *name, const char *dir,
                                char *err, size_t errlen)
{
    if (err && errlen)
        err[0] = 0;
    reader r = { .name = name ? name : "(scene)", .dir = dir, .err = err, .errlen = errlen };
    if (!text && len) {
        sc_set_error(fail(&r, 1, SC_EINVAL, "no text"));
        return NULL;
    }
    if (len > SCENE_MAX_BYTES) {
        sc_set_error(fail(&r, 1, SC_ETOOBIG, "larger than %zu bytes", SCENE_MAX_BYTES));
        return NULL;
    }
    r.c_loc = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    sc_scene *sc = calloc(1, sizeof *sc);
    if (!sc || !r.c_loc) {
        if (r.c_loc)
            freelocale(r.c_loc);
        free(sc);
        sc_set_error(fail(&r, 1, SC_ENOMEM, "out of memory"));
        return NULL;
    }
    int rc = SC_OK;
    size_t pos = 0;
    while (rc == SC_OK && pos < len) {
        const char *nl = memchr(text + pos, '\n', len - pos);
        size_t n = nl ? (size_t)(nl - (text + pos)) : len - pos;
        r.line++;
        rc = split(&r, text + pos, n);
        pos += n + (nl != NULL);
        if (rc != SC_OK || r.nw == 0)
            continue;
        const word *k = &r.w[0];
        if (is(k, "gravity"))
            rc = do_gravity(&r, sc);
        else if (is(k, "tolerance"))
            rc = do_tolerance(&r, sc);
        else if (is(k, "material"))
            rc = do_material(&r, sc);
        else if (is(k, "shape"))
            rc = do_shape(&r, sc);
        else if (is(k, "body"))
            rc = do_body(&r, sc);
        else
            rc = fail(&r, k->col, SC_EFORMAT,
                      "unknown keyword '%.*s' (gravity, tolerance, material, shape, body)",
                      (int)k->n, k->s);
    }
    if (rc == SC_OK && sc->total == 0) {
        r.line = r.line ? r.line : 1;
        rc = fail(&r, 1, SC_EFORMAT, "no bodies (add a body line)");
    }
    freelocale(r.c_loc);
    if (rc != SC_OK) {
        sc_scene_free(sc);
        sc_set_error(rc);
        return NULL;
    }
    return sc;
}

SC_API sc_scene *sc_scene_load(const char *path, char *err, size_t errlen)
{
    if (err && errlen)
        err[0] = 0;
    if (!path) {
        if (err && errlen)
            snprintf(err, errlen, "(scene): no file name");
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    unsigned char *buf;
    size_t len;
    errno = 0;
    int rc = sc_read_file(path, SCENE_MAX_BYTES, &buf, &len);
    if (rc != SC_OK) {
        int e = errno;
        if (err && errlen && rc == SC_ETOOBIG)
            snprintf(err, errlen, "%s: larger than %zu bytes", path, SCENE_MAX_BYTES);
        else if (err && errlen)
            snprintf(err, errlen, "%s: %s", path,
                     rc == SC_ENOMEM            ? "out of memory"
                     : e == EISDIR || e == 0    ? "not a regular file"
                                                : strerror(e));
        sc_set_error(rc);
        return NULL;
    }
    /* mesh files are named relative to the scene file's folder */
    char dir[WORD_MAX_CHARS + 1];
    const char *slash = strrchr(path, '/');
    if (slash)
        snprintf(dir, sizeof dir, "%.*s", slash == path ? 1 : (int)(slash - path), path);
    else
        dir[0] = 0;
    sc_scene *sc = sc_scene_parse((const char *)buf, len, path, dir, err, errlen);
    free(buf);
    return sc;
}

SC_API int sc_scene_body_count(const sc_scene *sc)
{
    return sc ? (int)sc->total : 0;
}

SC_API void sc_scene_config(const sc_scene *sc, sc_world_config *cfg)
{
    if (!sc || !cfg)
        return;
    if (sc->has_gravity)
        memcpy(cfg->gravity, sc->gravity, sizeof cfg->gravity);
    if (sc->tolerance > 0)
        cfg->contact_tol_m = sc->tolerance;
}

SC_API int sc_scene_build(const sc_scene *sc, sc_world *w)
{
    if (!sc || !w)
        return sc_set_error(SC_EINVAL);
    for (int i = 0; i < sc->nbodies; i++) {
        const scene_body *b = &sc->bodies[i];
        sc_body_desc d = b->d;
        for (int z = 0; z < b->grid[2]; z++)
            for (int y = 0; y < b->grid[1]; y++)
                for (int x = 0; x < b->grid[0]; x++) {
                    d.pos[0] = b->d.pos[0] + x * b->step[0];
                    d.pos[1] = b->d.pos[1] + y * b->step[1];
                    d.pos[2] = b->d.pos[2] + z * b->step[2];
                    int rc = sc_body_add(w, &d);
                    if (rc < 0)
                        return sc_set_error(rc);
                }
    }
    return SC_OK;
}
