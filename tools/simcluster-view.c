/* simcluster-view - the paper's drawing node (simcluster-view(1)): reads
 * the LCM log of simcluster run --record, or subscribes live to the state
 * channel of simcluster run --publish, and renders the frames with OSMesa
 * (no display needed) into numbered PNG files, or pipes them to ffmpeg.
 * Fixed-function OpenGL: one directional light and ambient, flat shaded
 * triangles, bodies coloured by state, the floor a checkered quad. */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>


#include <GL/osmesa.h>
#include <GL/gl.h>
#include <png.h>

#include "simcluster.h"
#include "simcluster_net.h"

#define MAX_SHAPES 4096            /* distinct shapes a log may hold */
#define MAX_CHANNEL 256
#define LOG_SYNC 0xEDA1DA01u       /* LCM event log: every event starts with it */
#define PLANE_HALF 40              /* the floor quad: 80 m, 1 m checkers */


static const char *prog = "simcluster-view";
static const GLfloat sky[3] = { 0.60f, 0.75f, 0.92f };
/* by sc_body_state: free fall, colliding, contact, asleep, static */
static const GLfloat state_rgb[5][3] = {
    { 0.20f, 0.45f, 0.95f }, { 0.95f, 0.20f, 0.15f }, { 0.95f, 0.70f, 0.10f },
    { 0.55f, 0.25f, 0.75f }, { 0.85f, 0.30f, 0.60f },
};

typedef struct view_opts {
    const char *out, *mp4, *log, *live;   /* log: a file, or the URL with --live */
    int w, h, every, have_eye, have_look, dump;
    long first, last;
    double eye[3], look[3], fov, timeout;
} view_opts;

typedef struct viewer {
    view_opts o;
    FILE *log, *pipe;
    long event;                    /* events read so far (1-based in errors) */
    struct {
        uint64_t hash;
        GLuint list;               /* drawn in the shape's frame */
        int kind;                  /* SC_SHAPE_*: a static box may hide the view */
        double half[3];
    } shapes[MAX_SHAPES];
    int nshapes, frames_out, camera_set;
    int quiet;                     /* live: malformed messages are counted, not printed */
    uint8_t *rgba;
} viewer;

static int bad(const char *what)
{
    fprintf(stderr, "%s: %s (try --help)\n", prog, what);
    return 2;
}

static int usage(FILE *f, int status)
{
    fprintf(f, "usage: %s [options] LOG     render a simcluster run --record log\n"
               "       %s [options] --live URL   render frames as simcluster run --publish\n"
               "                   sends them (until --frames' end, --timeout or a signal)\n"
               "  --timeout S      with --live: stop after S seconds without a frame\n"
               "  --out DIR        PNG files DIR/frame_NNNNN.png (default .)\n"
               "  --size WxH       image size, 16..4096 each (default 640x480)\n"
               "  --eye X,Y,Z --look X,Y,Z   camera and the point it looks at (default:\n"
               "                   the bodies' first centroid, from up and to the side)\n"
               "  --fov DEG        vertical field of view (default 45)\n"
               "  --every N --frames A:B   every Nth frame; frames A to B (A: or :B too)\n"
               "  --mp4 FILE       pipe the frames to ffmpeg instead of PNG files\n"
               "  --dump           print the bodies' states and positions, no images\n"
               "  -h, --help       this text;  --version  the version\n", prog, prog);
    return status;
}

static int parse_vec(const char *s, double v[3])
{
    char *end;
    for (int i = 0; i < 3; i++) {
        errno = 0;
        v[i] = strtod(s, &end);
        if (errno || end == s || !isfinite(v[i]) || *end != (i < 2 ? ',' : '\0'))
            return 0;
        s = end + 1;
    }
    return 1;
}

static int parse_int(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi)
        return 0;
    *out = v;
    return 1;
}

static int parse_args(int argc, char **argv, view_opts *o)
{
    static const struct option longs[] = {
        { "out", required_argument, 0, 'o' },   { "size", required_argument, 0, 's' },
        { "eye", required_argument, 0, 'e' },   { "look", required_argument, 0, 'l' },
        { "fov", required_argument, 0, 'f' },   { "every", required_argument, 0, 'n' },
        { "frames", required_argument, 0, 'r' }, { "mp4", required_argument, 0, 'm' },
        { "help", no_argument, 0, 'h' },        { "version", no_argument, 0, 'V' },
        { "dump", no_argument, 0, 'd' },        { "live", required_argument, 0, 'L' },
        { "timeout", required_argument, 0, 't' }, { 0, 0, 0, 0 }
    };
    *o = (view_opts){ .out = ".", .w = 640, .h = 480, .fov = 45, .every = 1, .last = LONG_MAX };
    opterr = 0;
    int c;
    long a, b;
    char *end, what[160];
    while ((c = getopt_long(argc, argv, "h", longs, NULL)) != -1) {
        switch (c) {
        case 'o':
            o->out = optarg;
            break;
        case 's':
            errno = 0;
            a = strtol(optarg, &end, 10);
            if (errno || end == optarg || *end != 'x' || !parse_int(end + 1, 16, 4096, &b) ||
                a < 16 || a > 4096)
                return bad("--size takes WxH, each 16..4096");
            o->w = (int)a;
            o->h = (int)b;
            break;
        case 'e':
        case 'l':
            if (!parse_vec(optarg, c == 'e' ? o->eye : o->look))
                return bad(c == 'e' ? "--eye takes X,Y,Z" : "--look takes X,Y,Z");
            *(c == 'e' ? &o->have_eye : &o->have_look) = 1;
            break;
        case 'f':
            errno = 0;
            o->fov = strtod(optarg, &end);
            if (errno || end == optarg || *end || !(o->fov >= 1 && o->fov <= 170))
                return bad("--fov takes degrees in 1..170");
            break;
        case 'n':
            if (!parse_int(optarg, 1, 1000000, &a))
                return bad("--every takes 1..1000000");
            o->every = (int)a;
            break;
        case 'r':                  /* A:B, A: or :B */
            errno = 0;
            o->first = strtol(optarg, &end, 10);
            if (errno || *end != ':' || (end[1] && !parse_int(end + 1, 0, 100000000L, &o->last)) ||
                o->first < 0 || o->first > 100000000L || o->first > o->last)
                return bad("--frames takes A:B, 0 <= A <= B <= 100000000");
            break;
        case 'm':
            o->mp4 = optarg;
            break;
        case 'd':
            o->dump = 1;
            break;
        case 'L':
            if (optarg[0] == '\0')
                return bad("--live takes a udpm:// URL");
            o->live = optarg;
            break;
        case 't':
            errno = 0;
            o->timeout = strtod(optarg, &end);
            if (errno || end == optarg || *end || !(o->timeout > 0 && o->timeout <= 1e6))
                return bad("--timeout takes seconds in (0, 1e6]");
            break;
        case 'h':
            exit(usage(stdout, 0));
        case 'V':
            printf("%s %s\n", prog, SC_VERSION_STRING);
            exit(0);
        default:
            snprintf(what, sizeof what, "unknown option or missing value: %s", argv[optind - 1]);
            return bad(what);
        }
    }
    if (o->live) {
        if (optind != argc)
            return bad("give a log file or --live URL, not both");
        o->log = o->live;
        return 0;
    }
    if (o->timeout > 0)
        return bad("--timeout is for --live");
    if (optind != argc - 1)
        return bad("give one log file (or --live URL)");
    o->log = argv[optind];
    return 0;
}

/* ---- reading the log: every length is checked before anything is kept ---- */

static int fail(viewer *v, const char *what)
{
    if (!v->quiet)
        fprintf(stderr, "%s: %s: event %ld: %s\n", prog, v->o.log, v->event, what);
    return -1;
}

static uint64_t be(const uint8_t *p, int n)
{
    uint64_t x = 0;
    for (int i = 0; i < n; i++)
        x = x << 8 | p[i];
    return x;
}

/* The next event: 1 with *chan and *data (malloc'd, *len bytes), 0 at the
 * clean end of the file, -1 on a truncated or malformed event (printed). */
static int next_event(viewer *v, char chan[MAX_CHANNEL + 1], uint8_t **data, size_t *len)
{
    uint8_t h[28];
    size_t got = fread(h, 1, sizeof h, v->log);
    v->event++;
    if (got == 0 && feof(v->log))
        return 0;
    if (got != sizeof h)
        return fail(v, ferror(v->log) ? strerror(errno) : "truncated event header");
    uint64_t clen = be(h + 20, 4), dlen = be(h + 24, 4);
    if (be(h, 4) != LOG_SYNC && v->event == 1) {
        /* the first bytes say what the file is not: a recording */
        if (!v->quiet)
            fprintf(stderr,
                    "%s: %s: not a recording (an LCM log as simcluster run --record writes); "
                    "a scene file is viewed by recording it first: simcluster run FILE "
                    "--record LOG, then %s LOG\n",
                    prog, v->o.log, prog);
        return -1;
    }
    if (be(h, 4) != LOG_SYNC)
        return fail(v, "not an LCM event (bad sync word)");
    if (clen == 0 || clen > MAX_CHANNEL || dlen > SC_MSG_MAX_PAYLOAD)
        return fail(v, "channel or data length out of range");
    *data = malloc(dlen ? dlen : 1);
    if (!*data)
        return fail(v, "out of memory");
    if (fread(chan, 1, clen, v->log) != clen || fread(*data, 1, dlen, v->log) != dlen) {
        free(*data);
        return fail(v, "truncated event");
    }
    chan[clen] = '\0';
    *len = dlen;
    return 1;
}

/* o = a x b, scaled to unit length (left as is when it is zero) */
static void cross_unit(double o[3], const double a[3], const double b[3])
{
    double c[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0] };
    double l = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    for (int k = 0; k < 3; k++)
        o[k] = l > 0 ? c[k] / l : c[k];
}

/* One flat-shaded triangle: its face normal, then its corners. */
static void face(const double *a, const double *b, const double *c)
{
    double u[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
    double w[3] = { c[0] - a[0], c[1] - a[1], c[2] - a[2] }, n[3];
    cross_unit(n, u, w);
    glNormal3dv(n);
    glVertex3dv(a);
    glVertex3dv(b);
    glVertex3dv(c);
}

static void draw_sphere(double r)
{
    enum { SL = 24, ST = 12 };
    for (int j = 0; j < ST; j++)
        for (int i = 0; i < SL; i++) {
            double p[4][3];
            for (int k = 0; k < 4; k++) {
                double th = M_PI * (j + (k >> 1)) / ST, ph = 2 * M_PI * (i + (k & 1)) / SL;
                double q[3] = { r * sin(th) * cos(ph), r * sin(th) * sin(ph), r * cos(th) };
                memcpy(p[k], q, sizeof q);
            }
            if (j > 0)
                face(p[0], p[2], p[1]);
            if (j < ST - 1)
                face(p[1], p[2], p[3]);
        }
}

static void draw_box(const double *hf)
{
    static const int quads[6][4] = { { 0, 2, 3, 1 }, { 4, 5, 7, 6 }, { 0, 1, 5, 4 },
                                     { 2, 6, 7, 3 }, { 0, 4, 6, 2 }, { 1, 3, 7, 5 } };
    double c[8][3];
    for (int k = 0; k < 8; k++)
        for (int a = 0; a < 3; a++)
            c[k][a] = (k >> a & 1 ? 1 : -1) * hf[a];
    for (int f = 0; f < 6; f++) {
        face(c[quads[f][0]], c[quads[f][1]], c[quads[f][2]]);
        face(c[quads[f][0]], c[quads[f][2]], c[quads[f][3]]);
    }
}

/* The plane n.x <= d as a checkered square around the foot point n d; its
 * front faces the free side, and back faces are culled, so a wall seen from
 * inside the solid (a box viewed from outside) hides nothing. */
static void draw_plane(const double *pl)
{
    double n[3] = { pl[0], pl[1], pl[2] }, u[3], w[3], foot[3];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int a = 0; a < 3; a++) {
        n[a] /= l;
        foot[a] = n[a] * pl[3] / l;
    }
    int m = fabs(n[0]) < 0.6 ? 0 : fabs(n[1]) < 0.6 ? 1 : 2;
    double e[3] = { m == 0, m == 1, m == 2 };
    cross_unit(u, e, n);           /* u x w = n: counter-clockwise from the free side */
    cross_unit(w, n, u);
    glNormal3dv(n);
    glBegin(GL_QUADS);
    for (int i = -PLANE_HALF; i < PLANE_HALF; i++)
        for (int j = -PLANE_HALF; j < PLANE_HALF; j++) {
            GLfloat g = (i + j) & 1 ? 0.50f : 0.68f;
            glColor3f(g, g, g);
            static const int c4[4][2] = { { 0, 0 }, { 1, 0 }, { 1, 1 }, { 0, 1 } };
            for (int k = 0; k < 4; k++) {
                double s = i + c4[k][0], t = j + c4[k][1], p[3];
                for (int a = 0; a < 3; a++)
                    p[a] = foot[a] + s * u[a] + t * w[a];
                glVertex3dv(p);
            }
        }
    glEnd();
}

/* A display list drawing shape m in its own frame. */
static GLuint compile_shape(const sc_frame_shape *m)
{
    GLuint list = glGenLists(1);
    glNewList(list, GL_COMPILE);
    if (m->kind == SC_SHAPE_PLANE) {
        draw_plane(m->plane);
    } else {
        glBegin(GL_TRIANGLES);
        if (m->kind == SC_SHAPE_SPHERE)
            draw_sphere(m->radius);
        else if (m->kind == SC_SHAPE_BOX)
            draw_box(m->half);
        else    /* indices were checked against the vertices by the decode */
            for (int t = 0; t < 3 * m->ntris; t += 3)
                face(m->xyz + 3 * m->tri[t], m->xyz + 3 * m->tri[t + 1], m->xyz + 3 * m->tri[t + 2]);
        glEnd();
    }
    glEndList();
    return list;
}

/* The shape with content hash h among those read, or -1. */
static int shape_index(const viewer *v, uint64_t h)
{
    for (int k = 0; k < v->nshapes; k++)
        if (v->shapes[k].hash == h)
            return k;
    return -1;
}

/* A shape record: checked as a daemon checks a shape (rebuilt, its content
 * hash compared), then compiled to a display list. A shape already known
 * (a live run sends them again every second) is not checked again. */
static int add_shape(viewer *v, const uint8_t *data, size_t len)
{
    uint64_t h;
    if (sc_frame_shape_hash(data, len, &h) == SC_OK && shape_index(v, h) >= 0)
        return 0;
    sc_frame_shape m;
    int rc = sc_frame_shape_decode(data, len, &m);
    if (rc != SC_OK)
        return fail(v, rc == SC_ENOMEM ? "out of memory" : "malformed shape");
    int full = v->nshapes == MAX_SHAPES;
    if (!full) {    /* with --dump, no GL: the shape is only checked */
        v->shapes[v->nshapes].hash = m.hash;
        v->shapes[v->nshapes].kind = m.kind;
        memcpy(v->shapes[v->nshapes].half, m.half, sizeof m.half);
        v->shapes[v->nshapes++].list = v->o.dump ? 0 : compile_shape(&m);
    }
    sc_frame_shape_free(&m);
    return full ? fail(v, "too many shapes") : 0;
}

/* A state record (sc_frame_record_decode checks sizes, poses and states). */
static int decode_state(viewer *v, const uint8_t *data, size_t len, sc_frame_record *m)
{
    int rc = sc_frame_record_decode(data, len, m);
    return rc == SC_OK ? 0 : fail(v, rc == SC_ENOMEM ? "out of memory" : "malformed state");
}

/* The rotation matrix (R[row][col]) of unit quaternion q (w, x, y, z). */
static void quat_rot(const double *q, double R[3][3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    R[0][0] = 1 - 2 * (y * y + z * z);
    R[0][1] = 2 * (x * y - w * z);
    R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z);
    R[1][1] = 1 - 2 * (x * x + z * z);
    R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y);
    R[2][1] = 2 * (y * z + w * x);
    R[2][2] = 1 - 2 * (x * x + y * y);
}

/* Whether static body i of m, a box, stands between eye and look (a plane
 * seen from its solid side is culled: it hides nothing). */
static int hides(const viewer *v, const sc_frame_record *m, int i, const double eye[3],
                 const double look[3])
{
    int k = shape_index(v, m->shape[i]);
    if (k < 0 || v->shapes[k].kind != SC_SHAPE_BOX)
        return 0;
    /* the segment in the box's frame (the pose's rotation transposed),
     * clipped by its three slabs */
    const double *c = &m->pos[3 * i], *h = v->shapes[k].half;
    double R[3][3], p0[3], p1[3], t0 = 0, t1 = 1;
    quat_rot(&m->quat[4 * i], R);
    for (int a = 0; a < 3; a++) {
        p0[a] = p1[a] = 0;
        for (int b = 0; b < 3; b++) {
            p0[a] += R[b][a] * (eye[b] - c[b]);
            p1[a] += R[b][a] * (look[b] - c[b]);
        }
    }
    for (int a = 0; a < 3; a++) {
        double d = p1[a] - p0[a];
        if (fabs(d) < 1e-12) {
            if (fabs(p0[a]) > h[a])
                return 0;
            continue;
        }
        double ta = (-h[a] - p0[a]) / d, tb = (h[a] - p0[a]) / d;
        t0 = fmax(t0, fmin(ta, tb));
        t1 = fmin(t1, fmax(ta, tb));
        if (t0 > t1)
            return 0;
    }
    return 1;
}

/* The first frame: unless given, look at the centroid of the moving bodies
 * from up and to the side, far enough that all of them fit, and from
 * higher up where a static box stands in the way (a parts bin's walls),
 * up to nearly straight down. */
static void default_camera(viewer *v, const sc_frame_record *m)
{
    double c[3] = { 0, 0, 0 }, r = 0.25;
    int k = 0;
    for (int i = 0; i < m->n; i++)
        if (m->state[i] != SC_STATIC) {
            for (int a = 0; a < 3; a++)
                c[a] += m->pos[3 * i + a];
            k++;
        }
    for (int a = 0; a < 3 && k; a++)
        c[a] /= k;
    for (int i = 0; i < m->n; i++)
        if (m->state[i] != SC_STATIC) {
            const double *p = &m->pos[3 * i];
            double d[3] = { p[0] - c[0], p[1] - c[1], p[2] - c[2] };
            r = fmax(r, sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 0.15);
        }
    if (!v->o.have_look)
        memcpy(v->o.look, c, sizeof c);
    double dist = 1.1 * r / sin(v->o.fov * M_PI / 360);
    for (int step = 0; step <= 9 && !v->o.have_eye; step++) {
        double s = 0.1 * step, dir[3] = { 0.55 * (1 - s), -0.7 * (1 - s), 0.45 * (1 - s) + s };
        double l = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        for (int a = 0; a < 3; a++)
            v->o.eye[a] = v->o.look[a] + dist * dir[a] / l;
        int clear = 1;
        for (int i = 0; i < m->n && clear; i++)
            clear = m->state[i] != SC_STATIC || !hides(v, m, i, v->o.eye, v->o.look);
        if (clear)
            break;
    }
    v->camera_set = 1;
}

static void set_camera(const view_opts *o)
{
    double f[3], up[3] = { 0, 0, 1 }, s[3], u[3];
    double l = hypot(hypot(o->look[0] - o->eye[0], o->look[1] - o->eye[1]), o->look[2] - o->eye[2]);
    for (int a = 0; a < 3; a++)    /* eye == look: look along +x */
        f[a] = l > 0 ? (o->look[a] - o->eye[a]) / l : (a == 0);
    if (fabs(f[2]) > 0.999) {      /* looking straight up or down: y is up */
        up[1] = 1;
        up[2] = 0;
    }
    cross_unit(s, f, up);
    cross_unit(u, s, f);
    glMatrixMode(GL_PROJECTION);
    glLoadIdentity();
    double near = 0.05, top = near * tan(o->fov * M_PI / 360), right = top * o->w / o->h;
    glFrustum(-right, right, -top, top, near, 1000);
    glMatrixMode(GL_MODELVIEW);
    const GLdouble view[16] = { s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0,
                                s[2], u[2], -f[2], 0, 0,    0,    0,     1 };
    glLoadMatrixd(view);
    glTranslated(-o->eye[0], -o->eye[1], -o->eye[2]);
}

/* frame_NNNNN.png in --out; v->rgba holds GL's rows, bottom-up. */
static int write_png(viewer *v, long frame)
{
    char path[4096];
    if (snprintf(path, sizeof path, "%s/frame_%05ld.png", v->o.out, frame) >= (int)sizeof path) {
        fprintf(stderr, "%s: %s: path too long\n", prog, v->o.out);
        return -1;
    }
    png_image im = { .version = PNG_IMAGE_VERSION, .width = (png_uint_32)v->o.w,
                     .height = (png_uint_32)v->o.h, .format = PNG_FORMAT_RGB };
    if (!png_image_write_to_file(&im, path, 0, v->rgba, -3 * v->o.w, NULL)) {
        fprintf(stderr, "%s: %s\n", prog, im.message);
        png_image_free(&im);
        return -1;
    }
    return 0;
}

static int render(viewer *v, const sc_frame_record *m)
{
    if (v->o.dump) {               /* text, for scripts: no GL at all */
        for (int i = 0; i < m->n; i++)
            printf("frame %ld body %d state %d pos %.9g %.9g %.9g\n", (long)m->frame, i,
                   m->state[i], m->pos[3 * i], m->pos[3 * i + 1], m->pos[3 * i + 2]);
        v->frames_out++;
        return 0;
    }
    if (!v->camera_set)
        default_camera(v, m);
    glClearColor(sky[0], sky[1], sky[2], 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    set_camera(&v->o);
    const GLfloat light[4] = { 0.35f, 0.25f, 1.0f, 0 };   /* from above, world-fixed */
    glLightfv(GL_LIGHT0, GL_POSITION, light);
    for (int i = 0; i < m->n; i++) {
        int k = shape_index(v, m->shape[i]);
        if (k < 0)
            return fail(v, "a body's shape is not in the log");
        glColor3fv(state_rgb[m->state[i]]);
        const double *p = &m->pos[3 * i];
        double R[3][3];
        quat_rot(&m->quat[4 * i], R);
        /* the rotation column-major, then the translation */
        const GLdouble M[16] = { R[0][0], R[1][0], R[2][0], 0, R[0][1], R[1][1], R[2][1], 0,
                                 R[0][2], R[1][2], R[2][2], 0, p[0], p[1], p[2], 1 };
        glPushMatrix();
        glMultMatrixd(M);
        glCallList(v->shapes[k].list);
        glPopMatrix();
    }
    glFinish();
    glReadPixels(0, 0, v->o.w, v->o.h, GL_RGB, GL_UNSIGNED_BYTE, v->rgba);
    v->frames_out++;
    if (v->pipe)
        return fwrite(v->rgba, 3 * (size_t)v->o.w, (size_t)v->o.h, v->pipe) == (size_t)v->o.h
                   ? 0 : (fprintf(stderr, "%s: %s: ffmpeg stopped\n", prog, v->o.mp4), -1);
    return write_png(v, (long)m->frame);
}

/* ffmpeg, if PATH has it, reading raw RGB frames (bottom-up: vflip). */
static int open_mp4(viewer *v)
{
    char cmd[8192], *q = cmd;
    if (system("command -v ffmpeg >/dev/null 2>&1") != 0) {
        fprintf(stderr, "%s: --mp4: ffmpeg is not on PATH\n", prog);
        return -1;
    }
    q += snprintf(cmd, sizeof cmd, "ffmpeg -loglevel error -y -f rawvideo -pix_fmt rgb24 "
                  "-s %dx%d -r %g -i - -vf vflip -pix_fmt yuv420p '", v->o.w, v->o.h,
                  100.0 / v->o.every);
    for (const char *s = v->o.mp4; *s && q < cmd + sizeof cmd - 8; s++)
        q += *s == '\'' ? sprintf(q, "'\\''") : sprintf(q, "%c", *s);
    strcpy(q, "'");
    v->pipe = popen(cmd, "w");
    if (!v->pipe)
        fprintf(stderr, "%s: --mp4: cannot start ffmpeg: %s\n", prog, strerror(errno));
    return v->pipe ? 0 : -1;
}

/* The PNG folder is created if it is not there (its parent must be, as
 * for mkdir(1)) and must be a writable directory; --mp4 starts ffmpeg.
 * 0, or -1 (printed). */
static int open_output(viewer *v)
{
    if (v->o.dump)
        return 0;
    if (v->o.mp4)
        return open_mp4(v);
    struct stat st;
    const char *why = NULL;
    if (mkdir(v->o.out, 0777) != 0 && errno != EEXIST)
        why = strerror(errno);
    else if (stat(v->o.out, &st) != 0)
        why = strerror(errno);
    else if (!S_ISDIR(st.st_mode))
        why = "not a directory";
    else if (access(v->o.out, W_OK | X_OK) != 0)
        why = strerror(errno);
    if (why)
        fprintf(stderr, "%s: --out %s: %s\n", prog, v->o.out, why);
    return why ? -1 : 0;
}

/* ---- live: the channels of simcluster run --publish ---- */

typedef struct live {
    viewer *v;
    uint8_t *state;                /* the newest SC_STATE not drawn yet */
    size_t len, cap;
    int fresh;
    long states, bad;              /* received; malformed, dropped */
    long superseded;               /* replaced by a newer one before drawn */
} live;

static volatile sig_atomic_t stop_live;
static void on_stop(int sig)
{
    (void)sig;
    stop_live = 1;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Shapes are checked and compiled as they come (each once); of the states
 * only the newest is kept: a viewer slower than the run skips frames. */
static void on_live(void *user, const char *chan, const uint8_t *data, size_t n,
                    int64_t recv_us)
{
    (void)recv_us;
    live *L = user;
    L->v->event++;
    if (!strcmp(chan, SC_FRAME_SHAPE_CHANNEL)) {
        L->bad += add_shape(L->v, data, n) != 0;
        return;
    }
    if (n > SC_MSG_MAX_PAYLOAD) {
        L->bad++;
        return;
    }
    if (n > L->cap) {
        uint8_t *p = realloc(L->state, n);
        if (!p) {
            L->bad++;
            return;
        }
        L->state = p;
        L->cap = n;
    }
    memcpy(L->state, data, n);
    L->len = n;
    L->superseded += L->fresh;
    L->fresh = 1;
    L->states++;
}

static int shapes_known(const viewer *v, const sc_frame_record *m)
{
    for (int i = 0; i < m->n; i++)
        if (shape_index(v, m->shape[i]) < 0)
            return 0;
    return 1;
}

static int run_live(viewer *v)
{
    if (open_output(v))
        return -1;
    sc_bus *l = NULL;
    char why[256];
    if (sc_bus_open(v->o.live, &l, why, sizeof why) != SC_OK) {
        fprintf(stderr, "%s: --live: cannot open %s: %s\n", prog, v->o.live, why);
        return -1;
    }
    live L = { .v = v };
    if (sc_bus_subscribe(l, SC_FRAME_SHAPE_CHANNEL, on_live, &L) != SC_OK ||
        sc_bus_subscribe(l, SC_FRAME_STATE_CHANNEL, on_live, &L) != SC_OK) {
        fprintf(stderr, "%s: --live: cannot subscribe on %s\n", prog, v->o.live);
        sc_bus_close(l);
        return -1;
    }
    struct sigaction sa = { .sa_handler = on_stop };
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    v->quiet = 1;
    long last = -1, waiting = 0;
    double heard = now_s();
    int rc = 0, done = 0;
    while (!stop_live && !done && rc == 0) {
        /* all that is pending is taken: the newest state is drawn */
        if (sc_bus_handle(l, 0.1) < 0) {
            fprintf(stderr, "%s: --live: %s: receive failed\n", prog, v->o.live);
            rc = -1;
            break;
        }
        if (!L.fresh) {
            if (v->o.timeout > 0 && now_s() - heard > v->o.timeout)
                break;
            continue;
        }
        L.fresh = 0;
        heard = now_s();
        sc_frame_record m;
        if (decode_state(v, L.state, L.len, &m)) {
            L.bad++;
            continue;
        }
        if (m.frame < last)
            last = -1;             /* a new run: start again */
        if (!shapes_known(v, &m))
            waiting++;             /* they come within a second */
        else if (m.frame >= v->o.first && m.frame <= v->o.last &&
                 (last < 0 || m.frame - last >= v->o.every)) {
            rc = render(v, &m);
            last = m.frame;
        }
        done = m.frame >= v->o.last;
        sc_frame_record_free(&m);
    }
    sc_bus_counters bc;
    sc_bus_counters_get(l, &bc);
    sc_bus_close(l);
    free(L.state);
    fprintf(stderr, "%s: %s: %d frames drawn of %ld received", prog, v->o.live,
            v->frames_out, L.states);
    if (waiting)
        fprintf(stderr, ", %ld before their shapes came", waiting);
    if (L.bad)
        fprintf(stderr, ", %ld malformed messages dropped", L.bad);
    if (sc_bus_dropped(&bc))
        fprintf(stderr, ", %llu datagrams dropped",
                (unsigned long long)sc_bus_dropped(&bc));
    if (L.superseded)
        fprintf(stderr, ", %ld replaced by a newer frame before they were drawn (the viewer "
                        "draws the newest; a slower viewer skips frames)",
                L.superseded);
    fprintf(stderr, "\n");
    return rc == 0 && v->frames_out ? 0 : -1;
}

static int run(viewer *v)
{
    if (v->o.live)
        return run_live(v);
    if (open_output(v))
        return -1;
    v->log = fopen(v->o.log, "rb");
    if (!v->log) {
        fprintf(stderr, "%s: %s: %s\n", prog, v->o.log, strerror(errno));
        return -1;
    }
    char chan[MAX_CHANNEL + 1];
    uint8_t *data;
    size_t len;
    int r, states = 0;
    while ((r = next_event(v, chan, &data, &len)) == 1) {
        if (!strcmp(chan, SC_FRAME_SHAPE_CHANNEL)) {
            r = add_shape(v, data, len);
        } else if (!strcmp(chan, SC_FRAME_STATE_CHANNEL)) {
            sc_frame_record m;
            r = decode_state(v, data, len, &m);
            if (r == 0) {
                states++;
                if (m.frame >= v->o.first && m.frame <= v->o.last &&
                    (m.frame - v->o.first) % v->o.every == 0)
                    r = render(v, &m);
                sc_frame_record_free(&m);
            }
        }   /* other channels: not ours, skipped */
        free(data);
        if (r)
            return -1;
    }
    if (r < 0)
        return -1;
    if (!v->frames_out)
        fprintf(stderr, "%s: %s: no frame%s\n", prog, v->o.log,
                states ? " in the range of --frames" : " (not a simcluster run --record log)");
    return v->frames_out ? 0 : -1;
}

/* The GL state every frame shares: depth, culling, one light, colour by
 * glColor. The context draws into fb (RGBA); frames are read into v->rgba. */
static uint8_t *gl_open(viewer *v, OSMesaContext *ctx)
{
    uint8_t *fb = malloc(4 * (size_t)v->o.w * (size_t)v->o.h);
    *ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, NULL);
    if (!fb || !*ctx || !OSMesaMakeCurrent(*ctx, fb, GL_UNSIGNED_BYTE, v->o.w, v->o.h)) {
        fprintf(stderr, "%s: cannot create an OSMesa %dx%d context\n", prog, v->o.w, v->o.h);
        free(fb);
        return NULL;
    }
    glViewport(0, 0, v->o.w, v->o.h);
    static const GLenum caps[] = { GL_DEPTH_TEST, GL_CULL_FACE, GL_LIGHTING, GL_LIGHT0,
                                   GL_COLOR_MATERIAL };
    for (size_t k = 0; k < sizeof caps / sizeof *caps; k++)
        glEnable(caps[k]);
    glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
    const GLfloat amb[4] = { 0.35f, 0.35f, 0.35f, 1 }, dif[4] = { 0.75f, 0.75f, 0.75f, 1 };
    glLightModelfv(GL_LIGHT_MODEL_AMBIENT, amb);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, dif);
    glShadeModel(GL_FLAT);
    return fb;
}

int main(int argc, char **argv)
{
    static viewer v;               /* static: the shape table is large */
    int rc = parse_args(argc, argv, &v.o);
    if (rc)
        return rc;
    /* --dump needs no GL. Mesa keeps each OSMesa framebuffer in a global
     * list that it never frees (LeakSanitizer reports it: tests/view.sh) */
    OSMesaContext ctx = NULL;
    uint8_t *fb = v.o.dump ? NULL : gl_open(&v, &ctx);
    v.rgba = malloc(3 * (size_t)v.o.w * (size_t)v.o.h);
    rc = 1;
    if (!v.rgba)
        fprintf(stderr, "%s: out of memory\n", prog);
    else if (fb || v.o.dump)
        rc = run(&v) == 0 ? 0 : 1;
    if (v.log)
        fclose(v.log);
    if (v.pipe && pclose(v.pipe) != 0 && rc == 0) {
        fprintf(stderr, "%s: %s: ffmpeg failed\n", prog, v.o.mp4);
        rc = 1;
    }
    if (ctx)
        OSMesaDestroyContext(ctx);
    free(fb);
    free(v.rgba);
    return rc;
}
