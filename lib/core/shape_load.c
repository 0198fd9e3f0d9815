/* shape_load.c - triangle meshes from Wavefront OBJ, ASCII STL and binary
 * STL files, with the line or byte offset of what is malformed
 * (docs/DESIGN.md 3.8). Files are hostile input: every read is bounded,
 * every count checked before it sizes an allocation, time and memory
 * linear in the file size. STL corners are welded through a hash table
 * under a random SipHash key per call (against hash flooding); vertices
 * are numbered by first appearance, so the result never depends on it. */
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <limits.h>
#include <locale.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "core.h"

#define LOAD_MAX_BYTES ((size_t)256 << 20)  /* largest file sc_shape_load reads */
#define NUM_MAX_CHARS 255                   /* longest number token accepted */
#define STL_HEADER_BYTES 84                 /* 80-byte comment + uint32 count */
#define STL_FACET_BYTES 50                  /* normal, 3 corners, attribute */

_Static_assert(sizeof(float) == 4, "binary STL stores IEEE-754 binary32");

/* ---- growing output arrays ---------------------------------------------- */

typedef struct mesh_buf {
    double *xyz;
    int *tri;
    int nverts, ntris;      /* <= SC_MESH_MAX_*, so no int ever overflows */
    int vcap, tcap;         /* capacities in vertices and triangles */
} mesh_buf;

/* Room for need vertices / triangles: SC_ETOOBIG past the limits, or SC_ENOMEM. */
static int reserve_verts(mesh_buf *m, int need)
{
    return sc_grow((void **)&m->xyz, &m->vcap, need, 3 * sizeof *m->xyz, SC_MESH_MAX_VERTS);
}

static int reserve_tris(mesh_buf *m, int need)
{
    return sc_grow((void **)&m->tri, &m->tcap, need, 3 * sizeof *m->tri, SC_MESH_MAX_TRIS);
}

static int push_vertex(mesh_buf *m, const double v[3])
{
    int rc = reserve_verts(m, m->nverts + 1);
    if (rc != SC_OK)
        return rc;
    memcpy(&m->xyz[3 * (size_t)m->nverts], v, 3 * sizeof *v);
    m->nverts++;
    return SC_OK;
}

static int push_tri(mesh_buf *m, int a, int b, int c)
{
    int rc = reserve_tris(m, m->ntris + 1);
    if (rc != SC_OK)
        return rc;
    int *t = &m->tri[3 * (size_t)m->ntris];
    t[0] = a;
    t[1] = b;
    t[2] = c;
    m->ntris++;
    return SC_OK;
}

/* ---- tokens and numbers ------------------------------------------------- */

/* Where and why a file is malformed: the first error found is kept. */
typedef struct mesh_err {
    int set, binary;
    long long at;                   /* line (text, from 1) or byte offset (binary) */
    char what[128];
} mesh_err;

typedef struct cursor {
    const unsigned char *p, *end;
    const unsigned char *start;     /* the buffer, for line numbers */
    mesh_err *err;                  /* NULL: no detail wanted */
    long long fwd;                  /* OBJ: the largest forward vertex index seen, */
    const unsigned char *fwd_at;    /* and where (checked at the end of the file) */
} cursor;

/* Record the first error of a text file, at byte at (its line: LF, CRLF and
 * a lone CR each end one); SC_EFORMAT. */
__attribute__((format(printf, 3, 4))) static int text_error(cursor *c, const unsigned char *at,
                                                            const char *fmt, ...)
{
    if (!c->err || c->err->set)
        return SC_EFORMAT;
    long long line = 1;
    for (const unsigned char *q = c->start; q < at && q < c->end; q++)
        line += *q == '\n' || (*q == '\r' && (q + 1 == c->end || q[1] != '\n'));
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->err->what, sizeof c->err->what, fmt, ap);
    va_end(ap);
    c->err->set = 1;
    c->err->at = line;
    return SC_EFORMAT;
}

/* A token as it may be quoted in a message: at most 24 bytes, anything but
 * printable ASCII as '?' (the file's bytes reach a terminal). */
static const char *quoted(const unsigned char *t, size_t n, char out[25])
{
    size_t i = 0;
    for (; i < n && i < 24; i++)
        out[i] = t[i] > 0x20 && t[i] < 0x7f ? (char)t[i] : '?';
    out[i] = '\0';
    return out;
}

static int is_blank(int c)
{
    return c == ' ' || c == '\t' || c == '\v' || c == '\f';
}

/* A lone CR ends a line too (CRLF then yields an empty line, which is fine). */
static int is_eol(int c)
{
    return c == '\n' || c == '\r';
}

static int tok_is(const unsigned char *t, size_t n, const char *s)
{
    return n == strlen(s) && memcmp(t, s, n) == 0;
}

/* Past the end of the current line (and its terminator). */
static void skip_line(cursor *c)
{
    while (c->p < c->end && !is_eol(*c->p))
        c->p++;
    if (c->p < c->end)
        c->p++;
}

static int is_digit(int c)
{
    return c >= '0' && c <= '9';
}

/* A decimal number [+-] digits [. digits] [(e|E) [+-] digits] that is finite
 * as a double. The grammar is checked here, so strtod never sees "nan",
 * "inf" or hex; the conversion (correct rounding) is left to strtod_l on a
 * bounded NUL-terminated copy, with the "C" locale passed in: plain strtod
 * follows the caller's LC_NUMERIC and stops at the '.' of "0.5" under e.g.
 * de_DE, so files would load or not depending on the application. */
static int parse_num(const unsigned char *s, size_t n, locale_t c_loc, double *out)
{
    if (n == 0 || n > NUM_MAX_CHARS)
        return SC_EFORMAT;
    size_t i = 0, digits = 0;
    if (s[i] == '+' || s[i] == '-')
        i++;
    for (; i < n && is_digit(s[i]); i++)
        digits++;
    if (i < n && s[i] == '.')
        for (i++; i < n && is_digit(s[i]); i++)
            digits++;
    if (digits == 0)
        return SC_EFORMAT;
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        size_t exp_digits = 0;
        i++;
        if (i < n && (s[i] == '+' || s[i] == '-'))
            i++;
        for (; i < n && is_digit(s[i]); i++)
            exp_digits++;
        if (exp_digits == 0)
            return SC_EFORMAT;
    }
    if (i != n)
        return SC_EFORMAT;
    char tmp[NUM_MAX_CHARS + 1];
    memcpy(tmp, s, n);
    tmp[n] = '\0';
    char *endp;
    double v = strtod_l(tmp, &endp, c_loc);
    if (endp != tmp + n || !isfinite(v))
        return SC_EFORMAT;
    *out = v;
    return SC_OK;
}

/* [+-] digits; magnitudes past INT_MAX saturate (callers range-check). */
static int parse_int(const unsigned char *s, size_t n, long long *out)
{
    size_t i = 0;
    int neg = 0;
    if (i < n && (s[i] == '+' || s[i] == '-'))
        neg = s[i++] == '-';
    if (i == n)
        return SC_EFORMAT;
    long long v = 0;
    for (; i < n; i++) {
        if (!is_digit(s[i]))
            return SC_EFORMAT;
        if (v <= INT_MAX)
            v = 10 * v + (s[i] - '0');
    }
    *out = neg ? -v : v;
    return SC_OK;
}

/* ---- vertex welding (STL) ----------------------------------------------- */

typedef struct weld {
    uint32_t *slot;         /* vertex index + 1; 0 = empty */
    size_t mask;            /* slots - 1 (a power of two) */
    uint64_t key[2];        /* SipHash key, random per call */
} weld;

#define ROTL64(x, b) (((x) << (b)) | ((x) >> (64 - (b))))

static void sip_round(uint64_t v[4])
{
    v[0] += v[1]; v[1] = ROTL64(v[1], 13); v[1] ^= v[0]; v[0] = ROTL64(v[0], 32);
    v[2] += v[3]; v[3] = ROTL64(v[3], 16); v[3] ^= v[2];
    v[0] += v[3]; v[3] = ROTL64(v[3], 21); v[3] ^= v[0];
    v[2] += v[1]; v[1] = ROTL64(v[1], 17); v[1] ^= v[2]; v[2] = ROTL64(v[2], 32);
}

/* SipHash-1-3 (Aumasson & Bernstein) of the 24 bytes of a vertex's bits. */
static uint64_t weld_hash(const weld *w, const double p[3])
{
    uint64_t v[4] = { w->key[0] ^ 0x736f6d6570736575ULL, w->key[1] ^ 0x646f72616e646f6dULL,
                      w->key[0] ^ 0x6c7967656e657261ULL, w->key[1] ^ 0x7465646279746573ULL };
    for (int k = 0; k < 3; k++) {
        uint64_t m;
        memcpy(&m, &p[k], sizeof m);
        v[3] ^= m;
        sip_round(v);
        v[0] ^= m;
    }
    uint64_t b = (uint64_t)24 << 56;
    v[3] ^= b;
    sip_round(v);
    v[0] ^= b;
    v[2] ^= 0xff;
    sip_round(v);
    sip_round(v);
    sip_round(v);
    return v[0] ^ v[1] ^ v[2] ^ v[3];
}

/* Draws the key; called before the first vertex, so OBJ files never pay
 * for the system call. */
static void weld_seed(weld *w)
{
    if (getrandom(w->key, sizeof w->key, GRND_NONBLOCK) == (ssize_t)sizeof w->key)
        return;
    /* No entropy yet (early boot) or no getrandom: a weaker key still beats
     * a fixed one, and correctness never depends on it. */
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    w->key[0] = (uint64_t)ts.tv_nsec * 0x9e3779b97f4a7c15ULL ^ (uint64_t)(uintptr_t)w;
    w->key[1] = (uint64_t)ts.tv_sec * 0xbf58476d1ce4e5b9ULL ^ (uint64_t)(uintptr_t)&ts;
}

/* Keep the load factor <= 1/2 for the vertices already in m plus one. */
static int weld_reserve(weld *w, const mesh_buf *m)
{
    size_t need = 2 * ((size_t)m->nverts + 1);
    if (w->slot && need <= w->mask + 1)
        return SC_OK;
    if (!w->slot)
        weld_seed(w);
    size_t n = w->slot ? 2 * (w->mask + 1) : 1024;
    while (n < need)
        n *= 2;
    uint32_t *s = calloc(n, sizeof *s);
    if (!s)
        return SC_ENOMEM;
    for (int v = 0; v < m->nverts; v++) {
        size_t i = weld_hash(w, &m->xyz[3 * (size_t)v]) & (n - 1);
        while (s[i])
            i = (i + 1) & (n - 1);
        s[i] = (uint32_t)v + 1;
    }
    free(w->slot);
    w->slot = s;
    w->mask = n - 1;
    return SC_OK;
}

/* The index of the vertex equal to p, added if new. p must be finite. */
static int weld_vertex(weld *w, mesh_buf *m, const double p[3], int *idx)
{
    double q[3];
    for (int k = 0; k < 3; k++)
        q[k] = p[k] == 0 ? 0.0 : p[k];  /* -0.0 and 0.0 are one point */
    int rc = weld_reserve(w, m);
    if (rc != SC_OK)
        return rc;
    size_t i = weld_hash(w, q) & w->mask;
    for (; w->slot[i]; i = (i + 1) & w->mask) {
        int v = (int)w->slot[i] - 1;
        /* bitwise equality is == here: no NaNs, and -0.0 was folded */
        if (memcmp(&m->xyz[3 * (size_t)v], q, sizeof q) == 0) {
            *idx = v;
            return SC_OK;
        }
    }
    rc = push_vertex(m, q);
    if (rc != SC_OK)
        return rc;
    w->slot[i] = (uint32_t)m->nverts;
    *idx = m->nverts - 1;
    return SC_OK;
}

/* ---- Wavefront OBJ ------------------------------------------------------ */

/* The next token on the current line; 0 at its end or at a '#' comment. */
static int obj_token(cursor *c, const unsigned char **tok, size_t *n)
{
    while (c->p < c->end && is_blank(*c->p))
        c->p++;
    if (c->p == c->end || is_eol(*c->p) || *c->p == '#')
        return 0;
    *tok = c->p;
    while (c->p < c->end && !is_blank(*c->p) && !is_eol(*c->p) && *c->p != '#')
        c->p++;
    *n = (size_t)(c->p - *tok);
    return 1;
}

/* Statements that carry nothing a collision mesh needs: normals, texture
 * coordinates, grouping, materials, lines, points and free-form geometry. */
static int obj_ignored(const unsigned char *t, size_t n)
{
    static const char *const kw[] = {
        "vn", "vt", "vp", "o", "g", "s", "mg", "usemtl", "mtllib", "l", "p",
        "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim",
        "hole", "scrv", "sp", "end", "con", "bevel", "c_interp", "d_interp", "lod",
        "maplib", "usemap", "shadow_obj", "trace_obj", "ctech", "stech",
    };
    for (size_t i = 0; i < sizeof kw / sizeof kw[0]; i++)
        if (tok_is(t, n, kw[i]))
            return 1;
    return 0;
}

/* v x y z [w], or MeshLab's v x y z r g b [a]; only x y z are kept. */
static int obj_vertex(cursor *c, mesh_buf *m, locale_t c_loc)
{
    double v[3];
    const unsigned char *t;
    size_t n;
    int k = 0;
    const unsigned char *line = c->p;
    while (obj_token(c, &t, &n)) {
        double x;
        if (k == 7)
            return text_error(c, t, "a vertex has more than 7 numbers");
        if (parse_num(t, n, c_loc, &x) != SC_OK)
            return text_error(c, t, "bad vertex coordinate");
        if (k < 3)
            v[k] = x;
        k++;
    }
    if (k != 3 && k != 4 && k != 6 && k != 7)
        return text_error(c, line, "a vertex has %d numbers (x y z, then w, or r g b [a])", k);
    return push_vertex(m, v);
}

/* Keep only the vertices some triangle uses, in their file order. OBJ files
 * often carry others (helper points, other objects' leftovers); they are no
 * part of the surface, and ODE's trimesh preprocessing asserts (aborts) when
 * a mesh has more vertices than edges. */
static int drop_unused_vertices(mesh_buf *m)
{
    int *map = malloc((size_t)(m->nverts ? m->nverts : 1) * sizeof *map);
    if (!map)
        return SC_ENOMEM;
    for (int v = 0; v < m->nverts; v++)
        map[v] = -1;
    for (size_t i = 0; i < 3 * (size_t)m->ntris; i++)
        map[m->tri[i]] = 0;
    int n = 0;
    for (int v = 0; v < m->nverts; v++)
        if (map[v] == 0) {
            memmove(&m->xyz[3 * (size_t)n], &m->xyz[3 * (size_t)v], 3 * sizeof *m->xyz);
            map[v] = n++;
        }
    for (size_t i = 0; i < 3 * (size_t)m->ntris; i++)
        m->tri[i] = map[m->tri[i]];
    m->nverts = n;
    free(map);
    return SC_OK;
}

/* One corner of a face, "a", "a/b", "a//c" or "a/b/c", to a 0-based vertex
 * index (*vout: a, when a relative a reaches before the first vertex). a < 0 counts back from the last vertex read so far; a > 0 may
 * point forward and is range-checked once the whole file is read. The
 * texture and normal indices are only checked for syntax. */
static int obj_corner(const unsigned char *s, size_t n, int nverts, int *idx, long long *vout)
{
    size_t a = 0;
    long long v, t;
    while (a < n && s[a] != '/')
        a++;
    if (parse_int(s, a, &v) != SC_OK || v == 0)
        return SC_EFORMAT;
    if (a < n) {
        const unsigned char *r = s + a + 1;
        size_t rn = n - a - 1, b = 0;
        while (b < rn && r[b] != '/')
            b++;
        if (b == rn) {                                  /* a/b */
            if (parse_int(r, b, &t) != SC_OK || t == 0)
                return SC_EFORMAT;
        } else {                                        /* a/b/c or a//c */
            if (b > 0 && (parse_int(r, b, &t) != SC_OK || t == 0))
                return SC_EFORMAT;
            if (parse_int(r + b + 1, rn - b - 1, &t) != SC_OK || t == 0)
                return SC_EFORMAT;
        }
    }
    if (v > 0) {
        if (v > SC_MESH_MAX_VERTS)
            return SC_EFORMAT;
        *idx = (int)(v - 1);
    } else {
        if (-v > nverts) {
            *vout = v;                  /* before the first vertex */
            return SC_EFORMAT;
        }
        *idx = nverts + (int)v;
    }
    return SC_OK;
}

/* f c1 c2 c3 ...: polygons are fanned from the first corner. */
static int obj_face(cursor *c, mesh_buf *m)
{
    const unsigned char *t;
    size_t n;
    int k = 0, first = 0, prev = 0;
    while (obj_token(c, &t, &n)) {
        int idx;
        long long v = 0;
        char q[25];
        if (obj_corner(t, n, m->nverts, &idx, &v) != SC_OK)
            return v < 0 ? text_error(c, t, "face index %lld: only %d vertices before it", v,
                                      m->nverts)
                         : text_error(c, t, "bad face corner '%s'", quoted(t, n, q));
        if (idx >= m->nverts && idx > c->fwd) {     /* checked at the end */
            c->fwd = idx;
            c->fwd_at = t;
        }
        int rc = k >= 2 ? push_tri(m, first, prev, idx) : SC_OK;
        if (rc != SC_OK)
            return rc;
        if (k == 0)
            first = idx;
        prev = idx;
        k++;
    }
    return k >= 3 ? SC_OK : text_error(c, c->p, "a face needs 3 corners or more, not %d", k);
}

static int obj_parse(cursor c, mesh_buf *m, locale_t c_loc)
{
    while (c.p < c.end) {
        const unsigned char *kw;
        size_t n;
        int rc = SC_OK;
        if (obj_token(&c, &kw, &n)) {           /* else blank or a comment */
            if (tok_is(kw, n, "v"))
                rc = obj_vertex(&c, m, c_loc);
            else if (tok_is(kw, n, "f"))
                rc = obj_face(&c, m);
            else if (!obj_ignored(kw, n)) {
                char q[25];
                rc = text_error(&c, kw, "unknown statement '%s'", quoted(kw, n, q));
            }
        }
        if (rc != SC_OK)
            return rc;
        skip_line(&c);
    }
    /* forward references are legal; check every index against the total */
    if (c.fwd >= m->nverts)
        return text_error(&c, c.fwd_at, "face index %lld: the file has %d vertices", c.fwd + 1,
                          m->nverts);
    return drop_unused_vertices(m);
}

/* ---- STL ------------------------------------------------------------------ */

/* The next whitespace-separated token (lines do not matter); 0 at the end. */
static int stl_token(cursor *c, const unsigned char **tok, size_t *n)
{
    while (c->p < c->end && (is_blank(*c->p) || is_eol(*c->p)))
        c->p++;
    if (c->p == c->end)
        return 0;
    *tok = c->p;
    while (c->p < c->end && !is_blank(*c->p) && !is_eol(*c->p))
        c->p++;
    *n = (size_t)(c->p - *tok);
    return 1;
}

/* The token where an ASCII STL parse went wrong: the file ended, or t is
 * not what was expected (one word or a description). */
static int stl_error(cursor *c, int have, const unsigned char *t, size_t n, const char *want)
{
    char q[25];
    if (!have) {                    /* the line of the file's last word */
        const unsigned char *at = c->end;
        while (at > c->start && (is_blank(at[-1]) || is_eol(at[-1])))
            at--;
        return text_error(c, at, "the file ends where %s should be (truncated?)", want);
    }
    return text_error(c, t, "%s expected, not '%s'", want, quoted(t, n, q));
}

static int stl_expect(cursor *c, const char *word)
{
    const unsigned char *t = NULL;
    size_t n = 0;
    char want[32];
    int have = stl_token(c, &t, &n);
    if (have && tok_is(t, n, word))
        return SC_OK;
    snprintf(want, sizeof want, "'%s'", word);
    return stl_error(c, have, t, n, want);
}

/* The rest of "facet normal nx ny nz outer loop (vertex x y z){3,} endloop
 * endfacet". The normal is ignored (exporters write garbage there); loops
 * of more than three vertices are fanned. */
static int stl_facet(cursor *c, mesh_buf *m, weld *w, locale_t c_loc)
{
    const unsigned char *t;
    size_t n;
    if (stl_expect(c, "normal") != SC_OK)
        return SC_EFORMAT;
    for (int k = 0; k < 3; k++)
        if (!stl_token(c, &t, &n))
            return stl_error(c, 0, t, n, "the normal");
    if (stl_expect(c, "outer") != SC_OK || stl_expect(c, "loop") != SC_OK)
        return SC_EFORMAT;
    int k = 0, first = 0, prev = 0;
    for (;;) {
        int have = stl_token(c, &t, &n);
        if (have && tok_is(t, n, "endloop"))
            break;
        if (!have || !tok_is(t, n, "vertex"))
            return stl_error(c, have, t, n, "'vertex' or 'endloop'");
        double p[3];
        for (int j = 0; j < 3; j++) {
            if (!stl_token(c, &t, &n))
                return stl_error(c, 0, t, n, "a vertex coordinate");
            if (parse_num(t, n, c_loc, &p[j]) != SC_OK)
                return text_error(c, t, "bad vertex coordinate");
        }
        int idx, rc = weld_vertex(w, m, p, &idx);
        if (rc == SC_OK && k >= 2)
            rc = push_tri(m, first, prev, idx);
        if (rc != SC_OK)
            return rc;
        if (k == 0)
            first = idx;
        prev = idx;
        k++;
    }
    if (k < 3)
        return text_error(c, t, "a facet needs 3 vertices or more, not %d", k);
    return stl_expect(c, "endfacet");
}

/* solid [name] facet... endsolid [name], possibly several solids in a row;
 * a file that ends before "endsolid" is truncated. */
static int stl_ascii_parse(cursor c, mesh_buf *m, weld *w, locale_t c_loc)
{
    if (stl_expect(&c, "solid") != SC_OK)
        return SC_EFORMAT;
    for (;;) {
        skip_line(&c);                          /* the solid's name */
        for (;;) {
            const unsigned char *t = NULL;
            size_t n = 0;
            int have = stl_token(&c, &t, &n);
            if (have && tok_is(t, n, "endsolid"))
                break;
            if (!have || !tok_is(t, n, "facet"))
                return stl_error(&c, have, t, n, "'facet' or 'endsolid'");
            int rc = stl_facet(&c, m, w, c_loc);
            if (rc != SC_OK)
                return rc;
        }
        skip_line(&c);                          /* the name after endsolid */
        const unsigned char *t;
        size_t n;
        if (!stl_token(&c, &t, &n))
            return SC_OK;
        if (!tok_is(t, n, "solid"))
            return stl_error(&c, 1, t, n, "'solid' (or the end of the file) after 'endsolid'");
    }
}

static uint32_t le32(const unsigned char *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

/* count facets of 50 bytes after the 84-byte header; len was checked to
 * hold exactly that many, and count against the limit before any
 * allocation is sized from it. */
static int binary_error(mesh_err *e, size_t offset, const char *what, uint32_t facet)
{
    if (e && !e->set) {
        e->set = e->binary = 1;
        e->at = (long long)offset;
        snprintf(e->what, sizeof e->what, what, facet);
    }
    return SC_EFORMAT;
}

static int stl_binary_parse(const unsigned char *b, uint32_t count, mesh_buf *m, weld *w,
                            mesh_err *e)
{
    if (count == 0)
        return binary_error(e, 80, "binary STL with no facets (a count of %u)", count);
    if (count > SC_MESH_MAX_TRIS)
        return SC_ETOOBIG;
    int rc = reserve_tris(m, (int)count);
    if (rc != SC_OK)
        return rc;
    for (uint32_t f = 0; f < count; f++) {
        const unsigned char *p = b + STL_HEADER_BYTES + (size_t)f * STL_FACET_BYTES + 12;
        int idx[3];
        for (int k = 0; k < 3; k++) {
            double v[3];
            for (int j = 0; j < 3; j++) {
                uint32_t u = le32(p + 12 * k + 4 * j);
                float x;
                memcpy(&x, &u, sizeof x);
                v[j] = x;
            }
            if (!sc_finite3(v))
                return binary_error(e, (size_t)(p - b) + 12 * (size_t)k,
                                    "facet %u: a vertex coordinate is not finite", f);
            rc = weld_vertex(w, m, v, &idx[k]);
            if (rc != SC_OK)
                return rc;
        }
        rc = push_tri(m, idx[0], idx[1], idx[2]);
        if (rc != SC_OK)
            return rc;
    }
    return SC_OK;
}

/* ---- entry points --------------------------------------------------------- */

/* "solid" as the first token (after whitespace) of a text file. */
static int starts_with_solid(cursor c)
{
    const unsigned char *t;
    size_t n;
    return stl_token(&c, &t, &n) && tok_is(t, n, "solid");
}

static int mesh_parse(const void *buf, size_t len, double **xyz, int *nverts, int **tri,
                      int *ntris, mesh_err *e)
{
    if ((!buf && len) || !xyz || !nverts || !tri || !ntris)
        return SC_EINVAL;
    *xyz = NULL;
    *tri = NULL;
    *nverts = *ntris = 0;
    if (len == 0) {                             /* (and buf may be NULL) */
        if (e && !e->set)
            snprintf(e->what, sizeof e->what, "an empty file");
        return SC_EFORMAT;
    }
    const unsigned char *b = buf;
    cursor c = { .p = b, .end = b + len, .start = b, .err = e, .fwd = -1 };
    mesh_buf m = { 0 };
    weld w = { 0 };
    int rc;
    /* Binary STL is recognised by its exact length alone: many exporters
     * start the binary header with "solid" too. */
    uint32_t count = len >= STL_HEADER_BYTES ? le32(b + 80) : 0;
    if (len >= STL_HEADER_BYTES &&
        (uint64_t)count * STL_FACET_BYTES + STL_HEADER_BYTES == (uint64_t)len) {
        rc = stl_binary_parse(b, count, &m, &w, e);
    } else {
        /* Text: numbers go through strtod_l with the "C" locale (see
         * parse_num); glibc hands out its static C locale object here. */
        locale_t c_loc = newlocale(LC_ALL_MASK, "C", (locale_t)0);
        if (!c_loc) {
            rc = SC_ENOMEM;
        } else {
            if (len >= 3 && memcmp(b, "\xef\xbb\xbf", 3) == 0)
                c.p += 3;                       /* UTF-8 byte order mark */
            if (starts_with_solid(c))
                rc = stl_ascii_parse(c, &m, &w, c_loc);
            else
                rc = obj_parse(c, &m, c_loc);
            freelocale(c_loc);
        }
    }
    free(w.slot);
    if (rc == SC_OK && (m.nverts == 0 || m.ntris == 0)) {
        rc = SC_EFORMAT;                        /* nothing to collide with */
        if (e && !e->set)
            snprintf(e->what, sizeof e->what, "no faces (is this an OBJ or STL file?)");
    }
    if (rc != SC_OK) {
        free(m.xyz);
        free(m.tri);
        return rc;
    }
    *xyz = m.xyz;
    *nverts = m.nverts;
    *tri = m.tri;
    *ntris = m.ntris;
    return SC_OK;
}

int sc_mesh_parse(const void *buf, size_t len, double **xyz, int *nverts, int **tri,
                  int *ntris)
{
    return mesh_parse(buf, len, xyz, nverts, tri, ntris, NULL);
}

int sc_read_file(const char *path, size_t max, unsigned char **out, size_t *len)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return SC_EIO;
    struct stat st;
    if (fstat(fd, &st) != 0 || S_ISDIR(st.st_mode)) {
        int e = S_ISDIR(st.st_mode) ? EISDIR : errno;
        close(fd);
        errno = e;
        return SC_EIO;
    }
    if (S_ISREG(st.st_mode) && (uintmax_t)st.st_size > max) {
        close(fd);
        return SC_ETOOBIG;
    }
    /* one byte of slack, so a file that grew past its size is noticed */
    size_t cap = S_ISREG(st.st_mode) ? (size_t)st.st_size + 1 : 65536, n = 0;
    unsigned char *buf = malloc(cap);
    int rc = buf ? SC_OK : SC_ENOMEM;
    while (rc == SC_OK) {
        if (n == cap) {
            if (cap > max) {
                rc = SC_ETOOBIG;
                break;
            }
            size_t nc = cap > max / 2 ? max + 1 : 2 * cap;
            unsigned char *nb = realloc(buf, nc);
            if (!nb) {
                rc = SC_ENOMEM;
                break;
            }
            buf = nb;
            cap = nc;
        }
        ssize_t r = read(fd, buf + n, cap - n);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            rc = SC_EIO;
        else if (r == 0)
            break;
        else
            n += (size_t)r;
    }
    int e = errno;
    close(fd);
    errno = e;
    if (rc == SC_OK && n > max)
        rc = SC_ETOOBIG;
    if (rc != SC_OK) {
        free(buf);
        return rc;
    }
    *out = buf;
    *len = n;
    return SC_OK;
}

/* "path: why" into err (errlen bytes; none when err is NULL or errlen 0):
 * "path:LINE: what" for a malformed text file, "path: byte N: what" for a
 * malformed binary STL, else the system's or sc_strerror()'s sentence. */
static void load_error(const char *path, int rc, int sys, const mesh_err *e, char *err,
                       size_t errlen)
{
    if (!err || errlen == 0)
        return;
    if (rc == SC_EFORMAT && e->set && e->binary)
        snprintf(err, errlen, "%s: byte %lld: %s", path, e->at, e->what);
    else if (rc == SC_EFORMAT && e->set)
        snprintf(err, errlen, "%s:%lld: %s", path, e->at, e->what);
    else if (rc == SC_EFORMAT && e->what[0])
        snprintf(err, errlen, "%s: %s", path, e->what);
    else if (rc == SC_EIO && sys)
        snprintf(err, errlen, "%s: %s", path, strerror(sys));
    else
        snprintf(err, errlen, "%s: %s", path, sc_strerror(rc));
}

SC_API sc_shape *sc_shape_load_err(const char *path, char *err, size_t errlen)
{
    if (err && errlen)
        err[0] = '\0';
    if (!path) {
        load_error("(null)", SC_EINVAL, 0, &(mesh_err){ 0 }, err, errlen);
        sc_set_error(SC_EINVAL);
        return NULL;
    }
    unsigned char *buf;
    size_t len;
    mesh_err e = { 0 };
    errno = 0;
    int rc = sc_read_file(path, LOAD_MAX_BYTES, &buf, &len);
    if (rc != SC_OK) {
        load_error(path, rc, errno, &e, err, errlen);
        sc_set_error(rc);
        return NULL;
    }
    double *xyz;
    int *tri, nverts, ntris;
    rc = mesh_parse(buf, len, &xyz, &nverts, &tri, &ntris, &e);
    free(buf);
    if (rc != SC_OK) {
        load_error(path, rc, 0, &e, err, errlen);
        sc_set_error(rc);
        return NULL;
    }
    /* validates closedness and orientation; sets the error itself */
    sc_shape *s = sc_shape_mesh(xyz, nverts, tri, ntris);
    free(xyz);
    free(tri);
    if (!s)
        load_error(path, sc_last_error(), 0, &e, err, errlen);
    return s;
}

SC_API sc_shape *sc_shape_load(const char *path)
{
    return sc_shape_load_err(path, NULL, 0);
}
