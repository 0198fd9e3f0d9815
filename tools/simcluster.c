/* simcluster - the command-line tool (simcluster(1)): run the paper's
 * scenes (run), print their Table 1 breakdown (profile), solve an LCP given
 * as text (lcp), and write a cluster key (keygen); run --record writes
 * an LCM log that simcluster-view(1) renders (run --render runs it), and
 * run --publish sends the same messages live. A scene is bolts, bin,
 * spheres, stack, pyramid, wall or a scene file (simcluster.conf(5), lib/api/scene_file.c). */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <lcm/eventlog.h>

#include "simcluster.h"
#include "simcluster_net.h"

#define DT 0.01
#define MAX_LCP 2000               /* lcp: variables at most */
#define MAX_SHAPE_MSGS 256         /* run --publish: shapes sent again each second */
#define WAIT_DAEMONS_S 10.0        /* --wait-daemons: at most this long */


static const char run_help[] =
    "run and profile options: --bodies N --seed S --frames F --until-rest\n"
    "  --workers W --groups --cluster URL --key FILE --deadline S --json\n"
    "  --min-gain G (a daemon gets a job's units only for G of its round\n"
    "    trips of work, default 2; negative: always)\n"
    "  --wait-daemons K (before the first frame, at most 10 s)\n"
    "  --island-split N (islands of more contacts solved as blocks; 0: exact)\n"
    "  --island-method active-set|block-gs|subdomains (how a split island is\n"
    "    solved: whole and exact by an active set, the default; by block\n"
    "    Gauss-Seidel; or by the active set on subdomains of 32 bodies)\n"
    "  --toi local|world (time of impact: motion groups with speculative\n"
    "    contacts, run's default; or the paper's world-wide back-up, profile's)\n"
    "profile only: --chart PNG (CPU by stage beside the paper's, by gnuplot)\n";
static const char run_only_help[] =
    "run only: --record LOG (an LCM log of every frame, for simcluster-view)\n"
    "  --render DIR (every frame as DIR/frame_NNNNN.png, by simcluster-view)\n"
    "  --publish URL (frames live on a udpm:// URL, for simcluster-view --live)\n"
    "  --realtime (no faster than simulated time)\n";

static int usage(FILE *f, int status)
{
    fprintf(f,
            "usage: simcluster run SCENE [options]     simulate bolts, bin, spheres or a scene file\n"
            "       simcluster profile SCENE [options] CPU time per stage (Table 1)\n"
            "       simcluster lcp FILE                solve an LCP given as text\n"
            "       simcluster keygen FILE             write a new cluster key (mode 0600)\n"
            "       simcluster --help | --version      (COMMAND --help: that command)\n"
            "%s%sscene files: simcluster.conf(5)\n", run_help, run_only_help);
    return status;
}

/* COMMAND --help: that command's part of usage() */
static int usage_cmd(const char *cmd)
{
    if (!strcmp(cmd, "run") || !strcmp(cmd, "profile")) {
        printf("usage: simcluster %s SCENE [options]   %s\n%s%s", cmd,
               !strcmp(cmd, "run") ? "simulate bolts, bin, spheres or a scene file"
                                   : "CPU time per stage (the paper's Table 1)",
               run_help, !strcmp(cmd, "run") ? run_only_help : "");
        printf("scenes: bolts (a sparse drop), bin (a dense pile), spheres or a scene file (simcluster.conf(5))\n");
    } else if (!strcmp(cmd, "lcp")) {
        printf("usage: simcluster lcp FILE   solve the LCP w = Mz + q, z >= 0, w >= 0, z.w = 0\n"
               "  FILE (- for standard input): n, then M row by row, then q; # comments\n");
    } else {
        printf("usage: simcluster keygen FILE   write a new cluster key (mode 0600)\n"
               "  an existing FILE is never overwritten; a FILE starting with -: -- FILE\n");
    }
    return 0;
}

static int version(void)
{
    printf("simcluster %s\n", SC_VERSION_STRING);
    return 0;
}

static int bad(const char *cmd, const char *what)
{
    fprintf(stderr, "simcluster: %s: %s (try simcluster --help)\n", cmd, what);
    return 2;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int keygen(int argc, char **argv)
{
    /* an argument starting with - is an option, never a file name (-- ends
     * the options), so that keygen --help writes no file "--help" */
    int i = 2;
    if (i < argc && (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")))
        return usage_cmd("keygen");
    if (i < argc && !strcmp(argv[i], "--version"))
        return version();
    if (i < argc && !strcmp(argv[i], "--"))
        i++;
    else if (i < argc && argv[i][0] == '-' && argv[i][1] != '\0')
        return bad("keygen", "unknown option (a file name starting with -: keygen -- FILE)");
    if (argc != i + 1 || argv[i][0] == '\0')
        return bad("keygen", "give one file name");
    const char *path = argv[i];
    int rc = sc_key_generate(path);
    if (rc != SC_OK) {
        /* sc_key_generate never overwrites: say which case it was */
        const char *why = rc == SC_EIO && errno == EEXIST ? "the file exists (never overwritten)"
                          : rc == SC_EIO                  ? strerror(errno)
                                                          : sc_strerror(rc);
        fprintf(stderr, "simcluster: keygen: %s: %s\n", path, why);
        return 1;
    }
    return 0;
}

/* ---- run and profile ---- */

typedef struct options {
    const char *scene;
    sc_scene *file;         /* a scene file, else NULL: the built-in scene */
    long bodies, seed, frames, workers, wait_daemons, island_split;
    int until_rest, groups, json, realtime, bodies_set, seed_set, toi_mode, island_method;
    const char *cluster, *key, *record, *render, *publish, *chart;
    double deadline;
    double min_gain;        /* 0: the library's default */
} options;

static int parse_long(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi)
        return 0;
    *out = v;
    return 1;
}

/* Read the options of run or profile into o: -1 to go on, else the exit
 * status (0 after --help or --version). */
/* The scene parse_options() was given, against the options that need one
 * kind of scene; a scene file read and checked now, so that a bad one
 * stops before any work. -1 to go on, else the exit status. */
static int check_scene(const char *cmd, options *o)
{
    if (o->key && !o->cluster)
        return bad(cmd, "--key needs --cluster");
    if (o->wait_daemons && !o->cluster)
        return bad(cmd, "--wait-daemons needs --cluster");
    int seeded = !strcmp(o->scene, "bolts") || !strcmp(o->scene, "bin");
    int structure = !strcmp(o->scene, "stack") || !strcmp(o->scene, "pyramid") ||
                    !strcmp(o->scene, "wall");
    int builtin = seeded || structure || !strcmp(o->scene, "spheres");
    if (structure && o->seed_set)
        return bad(cmd, "--seed is for the bolts and bin scenes; a structure has no randomness");
    if (!seeded && !structure && (o->bodies_set || o->seed_set))
        return bad(cmd, builtin ? "--bodies and --seed are for the bolts, bin and structure "
                                  "scenes; spheres is the paper's fixed 27"
                                : "--bodies and --seed are for the built-in scenes; a "
                                  "scene file places its own bodies");
    if (structure && !o->bodies_set)
        o->bodies = !strcmp(o->scene, "stack") ? 20 : !strcmp(o->scene, "pyramid") ? 15 : 12;
    if (builtin)
        return -1;
    /* a bare word (no folder, no extension) that names no file is a
     * mistyped scene, not a missing file */
    if (!strpbrk(o->scene, "/.") && access(o->scene, F_OK) != 0) {
        char what[256];
        snprintf(what, sizeof what,
                 "no scene '%.100s': the built-in scenes are bolts, bin, spheres, stack, "
                 "pyramid and wall; else give a scene file's path",
                 o->scene);
        return bad(cmd, what);
    }
    /* a scene file: read and checked now, so a bad one stops before any work */
    char err[512];
    o->file = sc_scene_load(o->scene, err, sizeof err);
    if (!o->file) {
        fprintf(stderr, "simcluster: %s: %s\n", cmd, err);
        return 1;
    }
    return -1;
}

static int parse_options(const char *cmd, int argc, char **argv, options *o)
{
    static const struct option longs[] = {
        { "bodies", required_argument, 0, 'n' },   { "seed", required_argument, 0, 's' },
        { "frames", required_argument, 0, 'f' },   { "until-rest", no_argument, 0, 'r' },
        { "workers", required_argument, 0, 'w' },  { "groups", no_argument, 0, 'g' },
        { "cluster", required_argument, 0, 'c' },  { "key", required_argument, 0, 'k' },
        { "deadline", required_argument, 0, 'd' }, { "json", no_argument, 0, 'j' },
        { "record", required_argument, 0, 'o' },   { "render", required_argument, 0, 'p' },
        { "publish", required_argument, 0, 'P' },  { "realtime", no_argument, 0, 'R' },
        { "wait-daemons", required_argument, 0, 'W' },
        { "chart", required_argument, 0, 'C' },
        { "island-split", required_argument, 0, 'I' },
        { "island-method", required_argument, 0, 'M' },
        { "toi", required_argument, 0, 'T' },
        { "min-gain", required_argument, 0, 'G' },
        { "help", no_argument, 0, 'h' },           { "version", no_argument, 0, 'V' },
        { 0, 0, 0, 0 }
    };
    memset(o, 0, sizeof *o);
    o->bodies = 50;
    o->seed = 1;
    o->frames = -1;
    o->island_split = -1;
    /* run: the library's default; profile: the paper's mode, for its
     * Table 1, whatever the default */
    o->toi_mode = strcmp(cmd, "profile") ? sc_world_config_default().toi_mode : SC_TOI_WORLD;
    opterr = 0;
    optind = 2;
    int c, li;
    char *end, what[160];
    while ((c = getopt_long(argc, argv, "h", longs, &li)) != -1) {
        /* --record, --render, --publish, --realtime: run only */
        if (c != '?' && strchr("opPR", c) && strcmp(cmd, "run")) {
            snprintf(what, sizeof what, "--%s is an option of run", longs[li].name);
            return bad(cmd, what);
        }
        if (c == 'C' && strcmp(cmd, "profile"))
            return bad(cmd, "--chart is an option of profile");
        switch (c) {
        case 'h':
            return usage_cmd(cmd);
        case 'V':
            return version();
        case 'n':
            if (!parse_long(optarg, 1, 100000, &o->bodies))
                return bad(cmd, "--bodies takes 1..100000");
            o->bodies_set = 1;
            break;
        case 's':
            if (!parse_long(optarg, 0, 0x7fffffffL, &o->seed))
                return bad(cmd, "--seed takes 0..2147483647");
            o->seed_set = 1;
            break;
        case 'f':
            if (!parse_long(optarg, 1, 100000000L, &o->frames))
                return bad(cmd, "--frames takes 1..100000000");
            break;
        case 'r':
            o->until_rest = 1;
            break;
        case 'w':
            if (!parse_long(optarg, 0, SC_MAX_WORKERS, &o->workers))
                return bad(cmd, "--workers takes 0..64 (0: one per CPU)");
            break;
        case 'g':
            o->groups = 1;
            break;
        case 'c':
            o->cluster = optarg;
            break;
        case 'k':
            o->key = optarg;
            break;
        case 'd':
            errno = 0;
            o->deadline = strtod(optarg, &end);
            if (errno || end == optarg || *end || !(o->deadline > 0 && o->deadline <= 10))
                return bad(cmd, "--deadline takes seconds in (0, 10]");
            break;
        case 'j':
            o->json = 1;
            break;
        case 'W':
            if (!parse_long(optarg, 0, SC_MAX_DAEMONS, &o->wait_daemons))
                return bad(cmd, "--wait-daemons takes 0..64");
            break;
        case 'o':
            if (optarg[0] == '\0')
                return bad(cmd, "--record takes a file name");
            o->record = optarg;
            break;
        case 'p':
            if (optarg[0] == '\0')
                return bad(cmd, "--render takes a directory");
            o->render = optarg;
            break;
        case 'P':
            if (optarg[0] == '\0')
                return bad(cmd, "--publish takes a udpm:// URL");
            o->publish = optarg;
            break;
        case 'R':
            o->realtime = 1;
            break;
        case 'G':
            errno = 0;
            o->min_gain = strtod(optarg, &end);
            if (errno || end == optarg || *end || !isfinite(o->min_gain) || o->min_gain == 0 ||
                o->min_gain > 1000)
                return bad(cmd, "--min-gain takes round trips in (0, 1000], or a negative number "
                                "(no such rule)");
            break;
        case 'I':
            if (!parse_long(optarg, 0, 1000000, &o->island_split))
                return bad(cmd, "--island-split takes 0..1000000 contacts (0: one exact LCP "
                                "an island)");
            break;
        case 'M':
            if (!strcmp(optarg, "active-set"))
                o->island_method = SC_ISLAND_ACTIVE_SET;
            else if (!strcmp(optarg, "block-gs"))
                o->island_method = SC_ISLAND_BLOCK_GS;
            else if (!strcmp(optarg, "subdomains"))
                o->island_method = SC_ISLAND_SUBDOMAINS;
            else
                return bad(cmd, "--island-method takes active-set, block-gs or subdomains");
            break;
        case 'T':
            if (!strcmp(optarg, "world"))
                o->toi_mode = SC_TOI_WORLD;
            else if (!strcmp(optarg, "local"))
                o->toi_mode = SC_TOI_LOCAL;
            else
                return bad(cmd, "--toi takes world or local");
            break;
        case 'C':
            if (optarg[0] == '\0')
                return bad(cmd, "--chart takes a PNG file name");
            o->chart = optarg;
            break;
        default: {
            snprintf(what, sizeof what, "unknown option or missing value: %s", argv[optind - 1]);
            return bad(cmd, what);
        }
        }
    }
    if (optind != argc - 1)
        return bad(cmd, "give one scene: bolts, bin, spheres or a scene file");
    o->scene = argv[optind];
    return check_scene(cmd, o);
}

/* s as a JSON string (a scene file's name can hold anything). */
static void json_string(const char *s)
{
    putchar('"');
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            printf("\\%c", c);
        else if (c < 0x20)
            printf("\\u%04x", c);
        else
            putchar(c);
    }
    putchar('"');
}

/* --wait-daemons: wait (at most WAIT_DAEMONS_S) until k daemons that are
 * not owner-busy are heard, so that the first frames of a short run have
 * them too. 1 when they came, else 0 with the reason printed. */
static int wait_daemons(const sc_world_config *cfg, int k, const char *cmd)
{
    sc_cluster_heard h;
    int n = sc_cluster_listen(cfg, k, WAIT_DAEMONS_S, &h);
    if (n < 0) {
        fprintf(stderr, "simcluster: %s: --wait-daemons: %s\n", cmd, sc_strerror(n));
    } else if (n < k) {
        /* say why, when it can be seen: another key, busy owners, no answer */
        char why[200] = "";
        if (h.auth_failed > 0)
            snprintf(why, sizeof why, "; %ld messages failed authentication: do the daemons "
                     "use this key (--key)?", h.auth_failed);
        else if (h.busy > 0)
            snprintf(why, sizeof why, "; %d more heard whose owner is busy", h.busy);
        else if (h.unverified > 0)
            snprintf(why, sizeof why, "; %d more heard that did not answer the challenge",
                     h.unverified);
        else
            snprintf(why, sizeof why, "; none heard on %s", cfg->cluster);
        fprintf(stderr, "simcluster: %s: %d daemon%s after %.0f s, %d wanted%s\n", cmd, n,
                n == 1 ? "" : "s", WAIT_DAEMONS_S, k, why);
    }
    return n >= k;
}

/* sc_world_create failed with err on a cluster: say whether the key file
 * or the URL was at fault, and name it (the library's code alone cannot:
 * SC_EIO is "file or cluster URL"). The key is loaded again to learn it. */
static void cluster_error(const char *cmd, const options *o, int err)
{
    if (o->key) {
        uint8_t key[SC_KEY_BYTES];
        errno = 0;
        int rc = sc_key_load(o->key, key);
        int e = rc == SC_EIO ? errno : 0;
        explicit_bzero(key, sizeof key);
        if (rc != SC_OK) {
            fprintf(stderr, "simcluster: %s: --key %s: %s\n", cmd, o->key,
                    e                      ? strerror(e)
                    : rc == SC_EFORMAT     ? "not a cluster key (64 hexadecimal digits, as "
                                             "simcluster keygen writes)"
                                           : sc_strerror(rc));
            return;
        }
    }
    char why[256] = "cannot open this URL";
    sc_bus *b = NULL;
    if (err == SC_EIO && sc_bus_open(o->cluster, &b, why, sizeof why) == SC_OK)
        sc_bus_close(b);
    if (err == SC_EIO)
        fprintf(stderr, "simcluster: %s: --cluster %s: %s\n", cmd, o->cluster, why);
    else
        fprintf(stderr, "simcluster: %s: %s (cluster %s%s%s)\n", cmd, sc_strerror(err),
                o->cluster, o->key ? ", key " : "", o->key ? o->key : "");
}

static sc_world *make_world(const options *o, const char *cmd)
{
    sc_world_config c = sc_world_config_default();
    c.workers = (int)o->workers;
    c.motion_groups = o->groups;
    c.cluster = o->cluster;
    c.key_file = o->key;
    c.cluster_deadline_s = o->deadline;
    c.cluster_min_gain = o->min_gain;
    if (o->file)
        sc_scene_config(o->file, &c);
    if (o->island_split >= 0)
        c.island_split = (int)o->island_split;
    c.toi_mode = o->toi_mode;
    c.island_method = o->island_method;
    sc_world *w = sc_world_create(&c);
    if (!w) {
        int err = sc_last_error();
        if (o->cluster)
            cluster_error(cmd, o, err);
        else
            fprintf(stderr, "simcluster: %s: %s\n", cmd, sc_strerror(err));
        return NULL;
    }
    /* the library takes the all-zero key then: said, not silent */
    if (o->cluster && !o->key)
        fprintf(stderr, "simcluster: %s: no --key: the cluster's messages are sealed with the "
                        "all-zero key, which anyone on the network can use (simcluster keygen)\n",
                cmd);
    int rc = o->file                     ? sc_scene_build(o->file, w)
             : !strcmp(o->scene, "bolts") ? sc_scene_bolts_nuts(w, (int)o->bodies, (uint64_t)o->seed)
             : !strcmp(o->scene, "bin")   ? sc_scene_bin(w, (int)o->bodies, (uint64_t)o->seed)
             : !strcmp(o->scene, "stack") ? sc_scene_stack(w, (int)o->bodies, 0)
             : !strcmp(o->scene, "pyramid") ? sc_scene_pyramid(w, (int)o->bodies)
             : !strcmp(o->scene, "wall")  ? sc_scene_wall(w, 10, (int)o->bodies)
                                          : sc_scene_spheres_box(w);
    if (rc < 0) {
        fprintf(stderr, "simcluster: %s: scene: %s\n", cmd, sc_strerror(rc));
        sc_world_destroy(w);
        return NULL;
    }
    if (o->wait_daemons > 0 && !wait_daemons(&c, (int)o->wait_daemons, cmd)) {
        sc_world_destroy(w);
        return NULL;
    }
    return w;
}

static int awake(const sc_world *w)
{
    int n = 0;
    for (int i = 0; i < sc_world_body_count(w); i++) {
        int s = sc_body_state(w, i);
        n += s != SC_ASLEEP && s != SC_STATIC;
    }
    return n;
}

/* ---- run --record: an LCM event log (simcluster-view(1) reads it) ---- */

/* One shape record per distinct shape (unsealed: a log is local), then one
 * state record per frame, the initial state as frame 0 (frame records,
 * simcluster_net.h). Event timestamps are simulated microseconds, so
 * lcm-logplayer replays a run in simulated time. */
typedef struct recorder {
    lcm_eventlog_t *log;    /* --record, else NULL */
    const char *path;
    sc_bus *bus;            /* --publish, else NULL */
    uint8_t *shape_msg[MAX_SHAPE_MSGS];   /* for publishing again each second */
    size_t shape_len[MAX_SHAPE_MSGS];
    int nshape_msgs;
    double shapes_sent;     /* when they were last published */
    long publish_failed;
    int64_t events;
    sc_frame_record m;
} recorder;

static int record_event(recorder *r, const char *channel, int64_t t_us, const void *data,
                        size_t len)
{
    if (r->bus && sc_bus_publish(r->bus, channel, data, len) != SC_OK)
        r->publish_failed++;        /* a live view loses a frame; not an error */
    if (!r->log)
        return 0;
    lcm_eventlog_event_t ev = { .eventnum = r->events++, .timestamp = t_us,
                                .channellen = (int32_t)strlen(channel),
                                .datalen = (int32_t)len,
                                .channel = (char *)channel, .data = (void *)data };
    if (lcm_eventlog_write_event(r->log, &ev) != 0) {
        fprintf(stderr, "simcluster: run: %s: cannot write\n", r->path);
        return 1;
    }
    return 0;
}

static void record_close(recorder *r)
{
    if (r->log)
        lcm_eventlog_destroy(r->log);
    sc_bus_close(r->bus);
    for (int i = 0; i < r->nshape_msgs; i++)
        free(r->shape_msg[i]);
    sc_frame_record_free(&r->m);
    memset(r, 0, sizeof *r);
}

/* Create the log (path) and/or the LCM publisher (url), and write the
 * shapes; 0, or 1 with the error printed. */
static int record_open(recorder *r, const char *path, const char *url, const sc_world *w)
{
    memset(r, 0, sizeof *r);
    r->path = path;
    if (path && !(r->log = lcm_eventlog_create(path, "w"))) {
        fprintf(stderr, "simcluster: run: %s: %s\n", path, strerror(errno));
        return 1;
    }
    char why[256];
    if (url && sc_bus_open(url, &r->bus, why, sizeof why) != SC_OK) {
        fprintf(stderr, "simcluster: run: --publish %s: %s\n", url, why);
        return 1;
    }
    r->shapes_sent = now_s();
    /* distinct shapes, each written once; a scene has few, so a linear
     * search over the ones seen is enough */
    const sc_shape *seen[64];
    int nseen = 0;
    for (int i = 0; i < sc_world_body_count(w); i++) {
        const sc_shape *s = sc_body_shape(w, i);
        int k = 0;
        while (k < nseen && seen[k] != s)
            k++;
        if (k < nseen)
            continue;
        uint8_t *bytes;
        size_t len;
        int rc = sc_frame_shape_encode(s, &bytes, &len);
        if (rc != SC_OK) {
            fprintf(stderr, "simcluster: run: %s: shape of body %d: %s\n", path, i,
                    sc_strerror(rc));
            return 1;
        }
        rc = record_event(r, SC_FRAME_SHAPE_CHANNEL, 0, bytes, len);
        if (r->bus && r->nshape_msgs < MAX_SHAPE_MSGS) {
            r->shape_msg[r->nshape_msgs] = bytes;
            r->shape_len[r->nshape_msgs++] = len;
        } else {
            free(bytes);
        }
        if (rc)
            return 1;
        if (nseen < 64)
            seen[nseen++] = s;
    }
    return 0;
}

/* Write the world's state as frame f; 0, or 1 with the error printed. */
static int record_frame(recorder *r, const sc_world *w, long f)
{
    /* a viewer that starts late learns the shapes within a second */
    if (r->bus && now_s() - r->shapes_sent >= 1.0) {
        r->shapes_sent = now_s();
        for (int i = 0; i < r->nshape_msgs; i++)
            if (sc_bus_publish(r->bus, SC_FRAME_SHAPE_CHANNEL, r->shape_msg[i],
                               r->shape_len[i]) != SC_OK)
                r->publish_failed++;
    }
    uint8_t *buf = NULL;
    size_t len = 0;
    int rc = sc_frame_record_capture(&r->m, w, f, f * DT);
    if (rc == SC_OK)
        rc = sc_frame_record_encode(&r->m, &buf, &len);
    if (rc != SC_OK) {
        fprintf(stderr, "simcluster: run: %s: frame %ld: %s\n", r->path ? r->path : "--publish",
                f, rc == SC_ETOOBIG ? "too many bodies to record" : sc_strerror(rc));
        return 1;
    }
    rc = record_event(r, SC_FRAME_STATE_CHANNEL, (int64_t)llround(r->m.time_s * 1e6), buf, len);
    free(buf);
    return rc;
}

/* Flush and close: 0, or 1 when the data did not all reach the file. */
static int record_finish(recorder *r)
{
    int bad_write = r->log && (fflush(r->log->f) != 0 || ferror(r->log->f));
    if (bad_write)
        fprintf(stderr, "simcluster: run: %s: %s\n", r->path, strerror(errno));
    if (r->publish_failed)
        fprintf(stderr, "simcluster: run: --publish: %ld messages could not be sent\n",
                r->publish_failed);
    record_close(r);
    return bad_write;
}

typedef struct totals {
    long frames, units, remote, recomputed, late;
    long msgs_out, msgs_in;     /* sealed messages of units sent, results received */
    long piped;                 /* group units back while the pile ran */
    long kept_out;              /* daemons kept out of jobs (worth-it rule) */
    long beside;                /* group units idle threads ran beside the pile */
    long np_pairs, np_reused;   /* narrow-phase pair tests, of them from the memo */
    long overlaps;              /* body pairs overlapping where they were placed */
    int auth_warned;            /* the warning about another key was given */
    long over_budget;           /* frames whose step took more than DT of wall time */
    double wall, peak_energy, max_pen, comm, max_frame;
    int at_rest;
    double rest_s;
    int interrupted;            /* the signal that stopped the run, else 0 */
    long duplicates;            /* duplicate daemon ids reported so far */
    /* the contact solver, summed (or the largest) over the frames */
    long solves, split, blocks, shared, pivots, staggered, refused, split_fb, block_fb, nan;
    long inelastic, rscaled, unconverged, diverged, kept, guessed, regularised, whole_tries;
    long whole_solved, sweeps;
    long substeps, max_pivots, backups, spec, groups, retried;
    int max_sweeps, max_substeps, max_backups;
    double residual, outer_residual;
    long as_solves, as_fallbacks, as_iterations, factor_nnz_max, as_exchanges, as_exchange_bytes;
    int as_iterations_max, as_parts_max, as_interface_max;
    /* the scheduler's figures, summed (a model's inputs: bench/pcs.sh) */
    long jobs, remote_jobs;
    double unit_work, unit_bytes, ideal[SC_STATS_IDEAL_NODES];
    double remote_overhead, remote_bytes, remote_work, remote_wait;
} totals;

/* SIGINT and SIGTERM during run and profile: the handler only notes the
 * signal; the loop stops after the frame it is in (a --record log then
 * ends on that frame's whole event) and the report so far is printed. A
 * second one acts as it would have by default (SA_RESETHAND). */
static volatile sig_atomic_t stop_signal;

static void on_stop(int sig)
{
    stop_signal = sig;
}

static void catch_stop_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop;
    sa.sa_flags = SA_RESTART | SA_RESETHAND;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

static const char *signal_name(int sig)
{
    return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal";
}

/* Step w for the options' frames; with rec, every frame goes to the log
 * (a write error stops the run: *rec_failed). */
static int simulate(const options *o, sc_world *w, totals *t, int progress, recorder *rec,
                    int *rec_failed)
{
    long frames = o->frames > 0 ? o->frames : o->until_rest ? 6000 : 500;
    double e0 = sc_world_energy(w), t0 = now_s(), shown = 0;
    memset(t, 0, sizeof *t);
    t->peak_energy = 1;
    int rc = SC_OK;
    if (rec && (*rec_failed = record_frame(rec, w, 0)))
        frames = 0;
    for (long f = 0; f < frames; f++) {
        if (stop_signal) {
            t->interrupted = stop_signal;
            break;
        }
        double tf = now_s();
        rc = sc_world_step(w, DT);
        if (rc != SC_OK)
            break;
        /* the paper's "every frame in real time": this step's wall time
         * against the frame it simulates */
        tf = now_s() - tf;
        t->over_budget += tf > DT;
        t->max_frame = fmax(t->max_frame, tf);
        if (rec && (*rec_failed = record_frame(rec, w, f + 1)))
            break;
        sc_stats st;
        sc_world_stats(w, &st);
        t->frames++;
        t->units += st.frame.sched.units;
        t->remote += st.frame.remote.units;
        t->recomputed += st.frame.remote.recomputed_units;
        t->late += st.frame.remote.late_results;
        t->comm += st.frame.remote.comm_s;
        t->msgs_out += st.frame.remote.unit_messages;
        t->msgs_in += st.frame.remote.result_messages;
        t->piped += st.frame.remote.pipelined_units;
        t->kept_out += st.frame.remote.refused;
        t->beside += st.frame.sched.units_background;
        t->np_pairs += st.frame.detect.np_pairs;
        t->np_reused += st.frame.detect.np_reused;
        t->jobs += st.frame.sched.jobs;
        t->unit_work += st.frame.sched.unit_work_s;
        t->unit_bytes += st.frame.sched.unit_bytes;
        for (int k = 0; k < SC_STATS_IDEAL_NODES; k++)
            t->ideal[k] += st.frame.sched.ideal_makespan_s[k];
        t->remote_jobs += st.frame.remote.jobs;
        t->remote_overhead += st.frame.remote.overhead_s;
        t->remote_bytes += st.frame.remote.bytes;
        t->remote_work += st.frame.remote.work_s;
        t->remote_wait += st.frame.remote.wait_s;
        if (st.total.duplicate_nodes > t->duplicates) {
            /* two running daemons with one id: said once per pair */
            t->duplicates = st.total.duplicate_nodes;
            fprintf(stderr, "%ssimcluster: run: daemon node id %016llx is used by two running "
                    "daemons; only the one started last gets work\n", progress ? "\n" : "",
                    (unsigned long long)st.now.duplicate_node);
        }
        t->max_pen = fmax(t->max_pen, st.frame.detect.max_penetration);
        t->solves += st.frame.lcp.solves;
        t->kept += st.frame.lcp.kept;
        t->split += st.frame.lcp.split;
        t->blocks += st.frame.lcp.blocks;
        t->shared += st.frame.lcp.blocks_shared;
        t->pivots += st.frame.lcp.pivots;
        t->max_pivots = st.frame.lcp.pivots > t->max_pivots ? st.frame.lcp.pivots : t->max_pivots;
        t->staggered += st.frame.lcp.fallbacks;
        t->refused += st.frame.lcp.energy_refused;
        t->rscaled += st.frame.lcp.restitution_scaled;
        t->guessed += st.frame.lcp.guessed;
        t->regularised += st.frame.lcp.regularised;
        t->split_fb += st.frame.lcp.split_fallbacks;
        t->block_fb += st.frame.lcp.block_fallbacks;
        t->nan += st.frame.lcp.nan_islands;
        t->inelastic += st.frame.lcp.inelastic;
        t->unconverged += st.frame.lcp.unconverged;
        t->diverged += st.frame.lcp.diverged;
        t->whole_tries += st.frame.lcp.whole_tries;
        t->whole_solved += st.frame.lcp.whole_solved;
        t->as_solves += st.frame.lcp.as_solves;
        t->as_fallbacks += st.frame.lcp.as_fallbacks;
        t->as_iterations += st.frame.lcp.as_iterations;
        if (st.frame.lcp.as_iterations_max > t->as_iterations_max)
            t->as_iterations_max = st.frame.lcp.as_iterations_max;
        if (st.frame.lcp.factor_nnz_max > t->factor_nnz_max)
            t->factor_nnz_max = st.frame.lcp.factor_nnz_max;
        if (st.frame.lcp.as_parts_max > t->as_parts_max)
            t->as_parts_max = st.frame.lcp.as_parts_max;
        if (st.frame.lcp.as_interface_max > t->as_interface_max)
            t->as_interface_max = st.frame.lcp.as_interface_max;
        t->as_exchanges += st.frame.lcp.as_exchanges;
        t->as_exchange_bytes += st.frame.lcp.as_exchange_bytes;
        t->max_sweeps =
            st.frame.lcp.sweeps_max > t->max_sweeps ? st.frame.lcp.sweeps_max : t->max_sweeps;
        t->sweeps += st.frame.lcp.sweeps;
        t->residual = fmax(t->residual, st.frame.lcp.residual);
        t->outer_residual = fmax(t->outer_residual, st.frame.lcp.outer_residual);
        t->substeps += st.frame.toi.substeps;
        t->max_substeps =
            st.frame.toi.substeps > t->max_substeps ? st.frame.toi.substeps : t->max_substeps;
        t->backups += st.frame.toi.backups;
        t->groups += st.frame.sched.groups;
        t->retried += st.frame.sched.group_retries;
        t->max_backups =
            st.frame.toi.backups > t->max_backups ? st.frame.toi.backups : t->max_backups;
        t->spec += st.frame.toi.spec_contacts;
        if (st.total.initial_overlaps > t->overlaps)
            fprintf(stderr, "%s: warning: %ld body pairs overlap by more than twice the "
                    "contact tolerance where they were placed; they are pushed apart, not "
                    "simulated as physics would\n", "simcluster",
                    st.total.initial_overlaps - t->overlaps);
        t->overlaps = st.total.initial_overlaps;
        if (st.total.dropped_auth > 0 && !t->auth_warned) {
            /* another key on the group: say it, once (daemons with it get no work) */
            fprintf(stderr, "simcluster: warning: cluster messages fail authentication (%ld so "
                    "far): daemons with another key are not used; do they use this key "
                    "(--key)?\n", st.total.dropped_auth);
            t->auth_warned = 1;
        }
        if (e0 > 0)
            t->peak_energy = fmax(t->peak_energy, sc_world_energy(w) / e0);
        double now = now_s();
        if (progress && now - shown > 0.2) {
            shown = now;
            fprintf(stderr, "\r  frame %ld  t %.2f s  RT %.2fx  awake %d  nodes %d  ", t->frames,
                    t->frames * DT, t->frames * DT / (now - t0), awake(w), st.now.nodes);
        }
        if (o->realtime) {             /* no faster than simulated time */
            double ahead = t0 + t->frames * DT - now_s();
            if (ahead > 0)
                nanosleep(&(struct timespec){ .tv_sec = (time_t)ahead,
                                              .tv_nsec = (long)(1e9 * (ahead - floor(ahead))) },
                          NULL);
        }
        if (o->until_rest && sc_world_at_rest(w)) {
            t->at_rest = 1;
            t->rest_s = t->frames * DT;
            break;
        }
    }
    t->wall = now_s() - t0;
    if (progress)
        fprintf(stderr, "\r%70s\r", "");
    if (!t->at_rest && sc_world_at_rest(w)) {
        t->at_rest = 1;
        t->rest_s = -1;
    }
    return rc;
}

/* run --render DIR: created if it is not there (its parent must be) and
 * checked before the run, so that a bad folder does not cost a simulation.
 * 0, or 1 with the error printed. */
static int render_dir(const char *dir)
{
    struct stat st;
    const char *why = NULL;
    if (mkdir(dir, 0777) != 0 && errno != EEXIST)
        why = strerror(errno);
    else if (stat(dir, &st) != 0)
        why = strerror(errno);
    else if (!S_ISDIR(st.st_mode))
        why = "not a directory";
    else if (access(dir, W_OK | X_OK) != 0)
        why = strerror(errno);
    if (why)
        fprintf(stderr, "simcluster: run: --render %s: %s\n", dir, why);
    return why != NULL;
}

/* run --render: simcluster-view (next to this program, else on PATH)
 * draws the log into dir; its output goes to standard error so that a
 * --json report stays alone on standard output. 0, or 1 with the error
 * printed. */
static int render(const char *self, const char *log, const char *dir)
{
    char view[PATH_MAX];
    const char *slash = strrchr(self, '/');
    int n = slash ? snprintf(view, sizeof view, "%.*s/simcluster-view", (int)(slash - self), self)
                  : -1;
    if (n < 0 || (size_t)n >= sizeof view || access(view, X_OK) != 0)
        snprintf(view, sizeof view, "simcluster-view");
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        dup2(2, 1);
        execvp(view, (char *[]){ view, "--out", (char *)dir, (char *)log, NULL });
        fprintf(stderr, "simcluster: run: --render: cannot run %s: %s\n", view, strerror(errno));
        _exit(127);
    }
    int st = 0;
    if (pid < 0 || waitpid(pid, &st, 0) < 0) {
        fprintf(stderr, "simcluster: run: --render: %s\n", strerror(errno));
        return 1;
    }
    return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : 1;    /* the viewer said why */
}

/* An SC_ISLAND_* method by its --island-method name. */
static const char *island_method_name(int method)
{
    return method == SC_ISLAND_BLOCK_GS     ? "block-gs"
           : method == SC_ISLAND_SUBDOMAINS ? "subdomains"
                                            : "active-set";
}

/* run's report as one JSON object (--json). */
static void report_json(const options *o, const sc_world *w, const sc_stats *stp,
                        const totals *tp, int rc, const char *seed, unsigned long long hash)
{
    const sc_stats st = *stp;
    const totals t = *tp;
    double sim = t.frames * DT;
    int island_split = o->island_split >= 0 ? (int)o->island_split : SC_ISLAND_SPLIT_DEFAULT;
    printf("{\"scene\": ");
    json_string(o->scene);
    printf(", \"bodies\": %d, \"seed\": %s, \"workers\": %d, \"cpu_budget\": %.2f, "
           "\"spin\": %s, \"frames\": %ld, \"simulated_s\": %.2f, \"wall_s\": %.4f, "
           "\"realtime_factor\": %.4f, \"at_rest\": %s, \"rest_s\": %.2f, "
           "\"peak_energy_ratio\": %.6f, \"max_penetration_m\": %.6g, \"units\": %ld, "
           "\"daemons\": %d, \"remote_units\": %ld, \"recomputed_units\": %ld, "
           "\"late_results\": %ld, \"dropped_messages\": %ld, \"dropped_auth\": %ld, "
           "\"dropped_stale\": %ld, "
           "\"dropped_misaddressed\": %ld, \"duplicate_nodes\": %ld, \"comm_s\": %.4f, "
           "\"unit_messages\": %ld, \"result_messages\": %ld, \"pipelined_units\": %ld, "
           "\"kept_out\": %ld, "
           "\"background_units\": %ld, \"narrow_phase_pairs\": %ld, "
           "\"narrow_phase_reused\": %ld, "
           "\"frames_over_budget\": %ld, \"max_frame_s\": %.4f, \"initial_overlaps\": %ld, "
           "\"serial_s\": %.4f, \"serial_share\": %.4f, "
           "\"solver\": {\"island_split\": %d, \"solves\": %ld, \"kept\": %ld, \"split\": %ld, "
           "\"blocks\": %ld, \"blocks_shared\": %ld, \"pivots\": %ld, \"max_frame_pivots\": %ld, "
           "\"staggered_fallbacks\": %ld, \"energy_refused\": %ld, \"split_fallbacks\": %ld, "
           "\"block_fallbacks\": %ld, \"nan_islands\": %ld, \"inelastic_islands\": %ld, "
           "\"restitution_scaled\": %ld, \"guessed\": %ld, \"regularised\": %ld, "
           "\"unconverged\": %ld, \"diverged\": %ld, \"whole_tries\": %ld, "
           "\"whole_solved\": %ld, "
           "\"max_sweeps\": %d, \"sweeps_mean\": %.2f, \"max_residual\": %.3g, "
           "\"max_outer_residual\": %.3g, "
           "\"substeps\": %ld, \"max_substeps\": %d, \"island_method\": \"%s\", "
           "\"active_set\": {\"solves\": %ld, \"fallbacks\": %ld, \"iterations_mean\": %.2f, "
           "\"iterations_max\": %d, \"factor_nnz_max\": %ld, \"parts_max\": %d, "
           "\"interface_max\": %d, \"exchanges\": %ld, \"exchange_bytes\": %ld}}, "
           "\"toi\": {\"mode\": \"%s\", \"backups\": %ld, \"max_frame_backups\": %d, "
           "\"speculative_contacts\": %ld, \"groups\": %ld, \"groups_retried\": %ld, "
           "\"groups_retry_s\": %.4f}, "
           "\"hash\": \"%016llx\", \"interrupted\": %s%s%s, \"error\": %s%s%s, \"sched\": ",
           sc_world_body_count(w), seed, (int)(st.now.nodes - st.now.daemons), st.now.cpu_budget,
           st.now.spin ? "true" : "false", t.frames,
           sim, t.wall, t.wall > 0 ? sim / t.wall : 0, t.at_rest ? "true" : "false",
           t.rest_s, t.peak_energy, t.max_pen, t.units, st.now.daemons, t.remote, t.recomputed,
           t.late, st.total.dropped_messages, st.total.dropped_auth, st.total.dropped_stale,
           st.total.dropped_misaddressed,
           st.total.duplicate_nodes, t.comm, t.msgs_out, t.msgs_in, t.piped, t.kept_out, t.beside,
           t.np_pairs,
           t.np_reused, t.over_budget, t.max_frame,
           t.overlaps, st.total.serial_s,
           st.total.frame_s > 0 ? st.total.serial_s / st.total.frame_s : 0.0,
           island_split, t.solves, t.kept, t.split, t.blocks, t.shared, t.pivots, t.max_pivots, t.staggered,
           t.refused, t.split_fb, t.block_fb, t.nan, t.inelastic, t.rscaled, t.guessed,
           t.regularised, t.unconverged, t.diverged, t.whole_tries, t.whole_solved,
           t.max_sweeps, t.split ? (double)t.sweeps / (double)t.split : 0.0, t.residual,
           t.outer_residual, t.substeps, t.max_substeps,
           island_method_name(o->island_method), t.as_solves,
           t.as_fallbacks, t.as_solves ? (double)t.as_iterations / (double)t.as_solves : 0.0,
           t.as_iterations_max, t.factor_nnz_max, t.as_parts_max, t.as_interface_max,
           t.as_exchanges, t.as_exchange_bytes,
           o->toi_mode == SC_TOI_LOCAL ? "local" : "world", t.backups, t.max_backups, t.spec,
           t.groups, t.retried, st.total.retry_s, hash,
           t.interrupted ? "\"" : "null", t.interrupted ? signal_name(t.interrupted) : "",
           t.interrupted ? "\"" : "", rc ? "\"" : "null",
           rc ? sc_strerror(rc) : "", rc ? "\"" : "");
    printf("{\"jobs\": %ld, \"unit_work_s\": %.6f, \"unit_bytes\": %.0f, "
           "\"remote_jobs\": %ld, \"remote_overhead_s\": %.6f, \"remote_bytes\": %.0f, "
           "\"remote_work_s\": %.6f, \"remote_wait_s\": %.6f, \"ideal_makespan_s\": [",
           t.jobs, t.unit_work, t.unit_bytes, t.remote_jobs, t.remote_overhead, t.remote_bytes,
           t.remote_work, t.remote_wait);
    for (int k = 0; k < SC_STATS_IDEAL_NODES; k++)
        printf("%s%.6f", k ? ", " : "", t.ideal[k]);
    printf("]}}\n");
}

/* run's report as lines of text. */
static void report_text(const options *o, const sc_world *w, const sc_stats *stp,
                        const totals *tp, const char *seed, unsigned long long hash)
{
    const sc_stats st = *stp;
    const totals t = *tp;
    double sim = t.frames * DT;
    printf("%s: %d bodies%s%s, %ld frames of %.2f s\n", o->scene, sc_world_body_count(w),
           strcmp(seed, "null") ? ", seed " : "", strcmp(seed, "null") ? seed : "", t.frames,
           DT);
    printf("  simulated %8.2f s in %.3f s wall (real-time factor %.2f)\n", sim, t.wall,
           t.wall > 0 ? sim / t.wall : 0);
    printf("  %d local threads on %.2f CPUs (affinity mask, cgroup quota): idle threads %s\n",
           (int)(st.now.nodes - st.now.daemons), st.now.cpu_budget,
           st.now.spin ? "poll a few ms before they sleep"
                       : "sleep at once (fewer CPUs than threads)");
    if (o->until_rest)
        printf("  %s\n", t.at_rest ? "all at rest" : "not at rest at the frame limit");
    printf("  frames over their %.0f ms: %ld, longest %.1f ms\n", 1e3 * DT, t.over_budget,
           1e3 * t.max_frame);
    printf("  peak energy / initial %.5f, max penetration %.3f mm\n", t.peak_energy,
           1e3 * t.max_pen);
    if (t.overlaps)
        printf("  body pairs overlapping where placed: %ld (pushed apart)\n", t.overlaps);
    printf("  contact solves %ld (split into blocks %ld, block solves %ld, %ld of them by "
           "helping threads; islands kept by speculative rounds %ld), pivots %ld (most in a "
           "frame %ld), substeps %.2f a frame (most %d)\n",
           t.solves, t.split, t.blocks, t.shared, t.kept, t.pivots, t.max_pivots,
           t.frames ? (double)t.substeps / (double)t.frames : 0.0, t.max_substeps);
    printf("  LCP residual at most %.3g m/s (exact), %.3g m/s (split, tolerance %.0e; "
           "%ld stopped at the sweep limit, %ld on a diverging sweep)\n",
           t.residual, t.outer_residual, SC_SPLIT_TOL, t.unconverged, t.diverged);
    if (t.split)
        printf("  block Gauss-Seidel: %.2f sweeps a split solve (most %d)\n",
               (double)t.sweeps / (double)t.split, t.max_sweeps);
    if (t.whole_tries)
        printf("  split solves short of the tolerance solved whole: %ld of %ld tried\n",
               t.whole_solved, t.whole_tries);
    if (t.as_solves)
        printf("  active set: %ld split solves, %.2f guesses a solve (most %d), factor of "
               "%ld entries at most, %ld left to block Gauss-Seidel\n",
               t.as_solves, (double)t.as_iterations / (double)t.as_solves, t.as_iterations_max,
               t.factor_nnz_max, t.as_fallbacks);
    if (t.as_solves && t.as_parts_max > 1)
        printf("  subdomains: %d parts at most, interface of %d unknowns at most, %.2f "
               "exchanges a solve (%.0f bytes a solve)\n",
               t.as_parts_max, t.as_interface_max, (double)t.as_exchanges / (double)t.as_solves,
               (double)t.as_exchange_bytes / (double)t.as_solves);
    printf("  time of impact (%s): back-ups %.2f a frame (most %d), speculative "
           "contacts %ld\n",
           o->toi_mode == SC_TOI_LOCAL ? "local" : "world",
           t.frames ? (double)t.backups / (double)t.frames : 0.0, t.max_backups, t.spec);
    if (t.groups) {
        double cpu = 0;
        for (int k = 0; k < SC_STAGE_COUNT; k++)
            cpu += st.total.stage_s[k];
        printf("  motion groups %.1f a frame, %ld of them stepped again (bodies of two "
               "groups came close; the tries thrown away took %.3f s of CPU, %.1f %% of "
               "all stages')\n",
               t.frames ? (double)t.groups / (double)t.frames : 0.0, t.retried,
               st.total.retry_s, cpu > 0 ? 100 * st.total.retry_s / cpu : 0.0);
    }
    printf("  fallbacks: staggered friction %ld (%ld of them answers refused for adding "
           "energy), blocks after staggered %ld, projected Gauss-Seidel blocks %ld, "
           "non-finite islands %ld, inelastic re-solves %ld, restitution scaled down %ld\n",
           t.staggered, t.refused, t.split_fb, t.block_fb, t.nan, t.inelastic, t.rscaled);
    printf("  friction solved from a projected Gauss-Seidel guess (fixed point and Lemke "
           "failed; exact, no fallback): %ld\n",
           t.guessed);
    printf("  LCPs solved with the diagonal raised (singular or near-redundant contacts; "
           "exact for a compliance of at most 1e-4 of the diagonal, no fallback): %ld\n",
           t.regularised);
    printf("  narrow phase: %ld pair tests, %ld of them (%.1f %%) answered by the frame's "
           "last detection\n",
           t.np_pairs, t.np_reused,
           t.np_pairs ? 100.0 * (double)t.np_reused / (double)t.np_pairs : 0.0);
    printf("  master's serial part (outside the nodes' jobs): %.2f ms a frame, %.1f %% of "
           "the frames' wall time\n",
           t.frames ? 1e3 * st.total.serial_s / (double)t.frames : 0.0,
           st.total.frame_s > 0 ? 100 * st.total.serial_s / st.total.frame_s : 0.0);
    printf("  work units %ld", t.units);
    if (t.beside)
        printf(", motion groups stepped by idle threads beside the pile %ld", t.beside);
    if (o->cluster)
        printf(", from daemons %ld, recomputed %ld, late %ld, dropped messages %ld",
               t.remote, t.recomputed, t.late, st.total.dropped_messages);
    if (o->cluster && (st.total.dropped_auth || st.total.dropped_stale ||
                       st.total.dropped_misaddressed || st.total.duplicate_nodes))
        printf("\n  of them failed authentication %ld, stale %ld, misaddressed %ld; "
               "duplicate daemon ids %ld",
               st.total.dropped_auth, st.total.dropped_stale, st.total.dropped_misaddressed,
               st.total.duplicate_nodes);
    if (o->cluster && t.frames) {
        /* per daemon: over those in use now (at least one) */
        double nd = st.now.daemons > 1 ? st.now.daemons : 1, fr = (double)t.frames;
        printf("\n  cluster messages a frame: %.2f of units out, %.2f of results in "
               "(a daemon: %.2f, %.2f); communication %.2f ms a frame; group units "
               "back while the pile ran %.2f a frame; a daemon kept out of %.2f jobs a "
               "frame (its share worth too few round trips)",
               (double)t.msgs_out / fr, (double)t.msgs_in / fr, (double)t.msgs_out / fr / nd,
               (double)t.msgs_in / fr / nd, 1e3 * t.comm / fr, (double)t.piped / fr,
               (double)t.kept_out / fr / nd);
    }
    printf("\n  state hash %016llx\n", hash);
    if (t.interrupted)
        printf("  interrupted by %s after frame %ld\n", signal_name(t.interrupted),
               t.frames);
}

static int run_cmd(int argc, char **argv)
{
    options o;
    int u = parse_options("run", argc, argv, &o);
    if (u >= 0)
        return u;
    if (o.render && render_dir(o.render)) {
        sc_scene_free(o.file);
        return 1;
    }
    catch_stop_signals();
    sc_world *w = make_world(&o, "run");
    sc_scene_free(o.file);          /* built; not needed any more */
    o.file = NULL;
    if (!w)
        return 1;
    recorder rec;
    int rec_failed = 0;
    char tmp_log[] = "/tmp/simcluster-render-XXXXXX";
    if (o.render && !o.record) {
        int fd = mkstemp(tmp_log);
        if (fd < 0) {
            fprintf(stderr, "simcluster: run: --render: %s: %s\n", tmp_log, strerror(errno));
            sc_world_destroy(w);
            return 1;
        }
        close(fd);
        o.record = tmp_log;
    }
    if ((o.record || o.publish) && record_open(&rec, o.record, o.publish, w)) {
        record_close(&rec);
        sc_world_destroy(w);
        return 1;
    }
    totals t;
    int rc = simulate(&o, w, &t, isatty(2) && !o.json, o.record || o.publish ? &rec : NULL,
                      &rec_failed);
    if (o.record || o.publish)
        rec_failed |= record_finish(&rec);
    sc_stats st;
    sc_world_stats(w, &st);
    unsigned long long hash = (unsigned long long)sc_world_hash(w);
    char seed[24] = "null";         /* scene files have no seed */
    if (!strcmp(o.scene, "bolts") || !strcmp(o.scene, "bin"))
        snprintf(seed, sizeof seed, "%ld", o.seed);
    if (o.json)
        report_json(&o, w, &st, &t, rc, seed, hash);
    else
        report_text(&o, w, &st, &t, seed, hash);
    sc_world_destroy(w);
    if (rc == SC_OK && !rec_failed && o.render && !t.interrupted)
        rec_failed = render(argv[0], o.record, o.render);
    if (o.record == tmp_log)
        unlink(tmp_log);
    if (rc != SC_OK) {
        fprintf(stderr, "simcluster: run: step %ld: %s\n", t.frames + 1, sc_strerror(rc));
        return 1;
    }
    if (rec_failed)
        return 1;
    return t.interrupted ? 128 + t.interrupted : 0;    /* as a shell reports it */
}

/* Where the time goes, as a PNG (profile --chart): our share of CPU per
 * stage beside the paper's Table 1, drawn by gnuplot. 0, or 1 after an
 * error message. */
typedef struct stage_row {
    const char *name, *key;
    int stage;
    double paper;   /* %, -1: the paper has no row */
} stage_row;

static int chart(const char *path, const char *scene, long frames, const stage_row *rows,
                 int nrows, const sc_stats *st, double total)
{
    if (system("command -v gnuplot >/dev/null 2>&1") != 0) {
        fprintf(stderr, "simcluster: profile: --chart needs gnuplot "
                        "(sh scripts/deps.sh bench installs it)\n");
        return 1;
    }
    /* the file is made here first: a bad path is our error, not gnuplot's */
    FILE *out = fopen(path, "wb");
    if (!out) {
        fprintf(stderr, "simcluster: profile: --chart %s: %s\n", path, strerror(errno));
        return 1;
    }
    fclose(out);
    FILE *g = popen("gnuplot", "w");
    if (!g) {
        fprintf(stderr, "simcluster: profile: --chart: cannot run gnuplot: %s\n",
                strerror(errno));
        return 1;
    }
    fprintf(g, "set terminal pngcairo size 900,480 font ',10' noenhanced\nset output '");
    for (const char *c = path; *c; c++)      /* gnuplot's single quotes: '' */
        fputs(*c == '\'' ? "''" : (char[]){ *c, 0 }, g);
    fprintf(g, "'\n$d << EOD\n");
    for (int i = 0; i < nrows; i++) {
        double s = st->total.stage_s[rows[i].stage];
        fprintf(g, "\"%s\" %.4f %.4f\n", rows[i].name, total > 0 ? 100 * s / total : 0,
                rows[i].paper < 0 ? 0 : rows[i].paper);
    }
    fprintf(g, "EOD\nset title \"CPU by stage: ");
    for (const char *c = scene; *c; c++)
        if (*c != '"' && *c != '\\' && (unsigned char)*c >= 0x20)
            fputc(*c, g);
    fprintf(g, ", %ld frames (%.3f s CPU) beside the paper's Table 1\"\n"
               "set style data histograms\nset style histogram clustered gap 1\n"
               "set style fill solid 0.8 border -1\nset ylabel \"share of CPU (%%)\"\n"
               "set yrange [0:*]\nset grid ytics\nset xtics nomirror rotate by -15\n"
               "plot $d using 2:xtic(1) title \"simcluster\", '' using 3 title \"paper (Table 1)\"\n",
            frames, total);
    int rc = pclose(g);
    if (rc != 0) {
        fprintf(stderr, "simcluster: profile: --chart: gnuplot failed (status %d)\n", rc);
        return 1;
    }
    return 0;
}

static int profile_cmd(int argc, char **argv)
{
    options o;
    int u = parse_options("profile", argc, argv, &o);
    if (u >= 0)
        return u;
    catch_stop_signals();
    if (o.frames < 0 && !strcmp(o.scene, "spheres"))
        o.frames = 5000;    /* the paper's 50 s */
    sc_world *w = make_world(&o, "profile");
    sc_scene_free(o.file);
    o.file = NULL;
    if (!w)
        return 1;
    totals t;
    int rc = simulate(&o, w, &t, isatty(2) && !o.json, NULL, NULL);
    sc_stats st;
    sc_world_stats(w, &st);
    /* the paper's Table 1 rows (27 spheres); time of impact is ours */
    static const stage_row rows[] = {
        { "polygon-level detection", "narrowphase", SC_STAGE_NARROWPHASE, 41.48 },
        { "Dantzig (LCP)", "lcp", SC_STAGE_LCP, 37.35 },
        { "contact graph", "islands", SC_STAGE_ISLANDS, 16.27 },
        { "integration", "integrate", SC_STAGE_INTEGRATE, 4.88 },
        { "bounding spheres", "broadphase", SC_STAGE_BROADPHASE, 0.02 },
        { "time of impact", "toi", SC_STAGE_TOI, -1 },
    };
    double total = 0;
    for (int k = 0; k < SC_STAGE_COUNT; k++)
        total += st.total.stage_s[k];
    if (o.json) {
        printf("{\"scene\": ");
        json_string(o.scene);
        printf(", \"frames\": %ld, \"toi_mode\": \"%s\", \"cpu_s\": {", t.frames,
               o.toi_mode == SC_TOI_LOCAL ? "local" : "world");
        for (size_t i = 0; i < sizeof rows / sizeof *rows; i++)
            printf("%s\"%s\": %.6f", i ? ", " : "", rows[i].key, st.total.stage_s[rows[i].stage]);
        printf("}, \"interrupted\": %s%s%s}\n", t.interrupted ? "\"" : "null",
               t.interrupted ? signal_name(t.interrupted) : "", t.interrupted ? "\"" : "");
    } else {
        printf("%s, %ld frames, time of impact %s: CPU time by stage (paper: Table 1, 27 "
               "spheres)\n",
               o.scene, t.frames, o.toi_mode == SC_TOI_LOCAL ? "local" : "world-wide");
        printf("  %-26s %10s %8s %8s\n", "stage", "CPU s", "ours %", "paper %");
        for (size_t i = 0; i < sizeof rows / sizeof *rows; i++) {
            double s = st.total.stage_s[rows[i].stage];
            printf("  %-26s %10.4f %8.2f ", rows[i].name, s, total > 0 ? 100 * s / total : 0);
            if (rows[i].paper < 0)
                printf("%8s\n", "-");
            else
                printf("%8.2f\n", rows[i].paper);
        }
        if (t.interrupted)
            printf("  interrupted by %s after frame %ld\n", signal_name(t.interrupted),
                   t.frames);
    }
    sc_world_destroy(w);
    if (rc != SC_OK) {
        fprintf(stderr, "simcluster: profile: step %ld: %s\n", t.frames + 1, sc_strerror(rc));
        return 1;
    }
    if (o.chart && chart(o.chart, o.scene, t.frames, rows, (int)(sizeof rows / sizeof *rows),
                         &st, total))
        return 1;
    return t.interrupted ? 128 + t.interrupted : 0;
}

/* ---- lcp ---- */

/* Read the next number of f into *v; line and column of where it starts
 * for errors. 1 on success, 0 at the end, -1 on a bad token. */
static int next_number(FILE *f, double *v, long *line, long *col, long *at_line, long *at_col)
{
    int c;
    for (;;) {
        c = getc(f);
        if (c == '#') {
            while ((c = getc(f)) != EOF && c != '\n')
                ;
        }
        if (c == EOF)
            return 0;
        if (c == '\n') {
            (*line)++;
            *col = 0;
            continue;
        }
        (*col)++;
        if (c != ' ' && c != '\t' && c != '\r')
            break;
    }
    char tok[64];
    size_t n = 0;
    *at_line = *line;
    *at_col = *col;
    while (c != EOF && c != ' ' && c != '\t' && c != '\r' && c != '\n' && c != '#') {
        if (n + 1 >= sizeof tok)
            return -1;
        tok[n++] = (char)c;
        c = getc(f);
        (*col)++;
    }
    if (c != EOF) {
        ungetc(c, f);
        (*col)--;
    }
    tok[n] = 0;
    char *end;
    errno = 0;
    *v = strtod(tok, &end);
    return !errno && *end == 0 && isfinite(*v) ? 1 : -1;
}

static int lcp_cmd(int argc, char **argv)
{
    if (argc == 3 && (!strcmp(argv[2], "--help") || !strcmp(argv[2], "-h")))
        return usage_cmd("lcp");
    if (argc == 3 && !strcmp(argv[2], "--version"))
        return version();
    if (argc == 3 && argv[2][0] == '-' && argv[2][1] != '\0')
        return bad("lcp", "unknown option (a file name starting with -: ./-FILE)");
    if (argc != 3)
        return bad("lcp", "give one file (n, then M row by row, then q)");
    const char *path = argv[2];
    FILE *f = strcmp(path, "-") ? fopen(path, "r") : stdin;
    if (!f) {
        fprintf(stderr, "simcluster: lcp: %s: %s\n", path, strerror(errno));
        return 1;
    }
    long line = 1, col = 0, l0 = 1, c0 = 0;
    double v;
    int r = next_number(f, &v, &line, &col, &l0, &c0);
    int n = r == 1 && v == floor(v) && v >= 1 && v <= MAX_LCP ? (int)v : 0;
    double *M = NULL, *q = NULL, *z = NULL, *w = NULL;
    int status = 1;
    if (!n) {
        fprintf(stderr, "simcluster: lcp: %s:%ld:%ld: expected the size n (1..%d)\n", path, l0,
                c0, MAX_LCP);
        goto out;
    }
    M = malloc((size_t)n * (size_t)n * sizeof *M);
    q = malloc((size_t)n * sizeof *q);
    z = malloc((size_t)n * sizeof *z);
    w = malloc((size_t)n * sizeof *w);
    if (!M || !q || !z || !w) {
        fprintf(stderr, "simcluster: lcp: out of memory\n");
        goto out;
    }
    long want = (long)n * n + n;
    for (long i = 0; i < want; i++) {
        r = next_number(f, &v, &line, &col, &l0, &c0);
        if (r != 1) {
            fprintf(stderr, "simcluster: lcp: %s:%ld:%ld: %s\n", path, r ? l0 : line,
                    r ? c0 : col,
                    r ? "not a finite number"
                      : i < (long)n * n ? "the file ends inside M" : "the file ends inside q");
            goto out;
        }
        if (i < (long)n * n)
            M[i] = v;
        else
            q[i - (long)n * n] = v;
    }
    r = next_number(f, &v, &line, &col, &l0, &c0);
    if (r != 0) {
        fprintf(stderr, "simcluster: lcp: %s:%ld:%ld: more numbers than n^2 + n\n", path, l0, c0);
        goto out;
    }
    int rc = sc_lcp_solve(n, M, q, z, w);
    if (rc != SC_OK) {
        fprintf(stderr, "simcluster: lcp: %s\n", sc_strerror(rc));
        goto out;
    }
    printf("# i z w\n");
    for (int i = 0; i < n; i++)
        printf("%d %.17g %.17g\n", i, z[i], w[i]);
    status = 0;
out:
    free(M);
    free(q);
    free(z);
    free(w);
    if (f != stdin)
        fclose(f);
    return status;
}

int main(int argc, char **argv)
{
    if (argc < 2)
        return usage(stderr, 2);
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))
        return usage(stdout, 0);
    if (!strcmp(argv[1], "--version"))
        return version();
    if (!strcmp(argv[1], "keygen"))
        return keygen(argc, argv);
    if (!strcmp(argv[1], "run"))
        return run_cmd(argc, argv);
    if (!strcmp(argv[1], "profile"))
        return profile_cmd(argc, argv);
    if (!strcmp(argv[1], "lcp"))
        return lcp_cmd(argc, argv);
    fprintf(stderr, "simcluster: unknown command '%s' (try simcluster --help)\n", argv[1]);
    return 2;
}
