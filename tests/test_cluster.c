/* test_cluster.c - daemons (the serve engine, on threads of this process)
 * as nodes of a world over LCM on this host only (ttl=0): the same bits as
 * a local run when daemons work, stop mid-run or never answer; results
 * really come from them; hostile messages are dropped and counted; a
 * daemon restarted with its id is used again at once, a dead one's
 * replayed heartbeats never count, and units captured before a restart
 * are refused after it. The
 * multi-host version with real simclusterd processes in network
 * namespaces is tests/cluster.sh. (Internal API: lib/net/unit_wire.h, lib/api/world.h.) */
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>


#include "cluster.h"
#include "engine.h"
#include "world.h"

#define BODIES 30
#define FRAMES 120

static char url[128];
static int groups;              /* motion groups for the worlds made */
static int toi_mode = SC_TOI_WORLD;                  /* their time of impact */
static int island_split = SC_ISLAND_SPLIT_DEFAULT;   /* theirs */
static int pile_scene;          /* a pile in a bin, lone spheres above it */
static double min_gain = -1;    /* their cluster_min_gain (-1: no job-level rule) */
static uint8_t key[SC_KEY_BYTES];
static char key_path[64];

typedef struct daemon_thread {
    sc_serve *s;
    pthread_t t;
    int rc;
} daemon_thread;

static void *serve_main(void *arg)
{
    daemon_thread *d = arg;
    d->rc = sc_serve_run(d->s);
    return NULL;
}

static void log_to_stderr(void *ctx, int prio, const char *msg)
{
    (void)ctx;
    if (getenv("SC_DEBUG"))
        fprintf(stderr, "  daemon [%d]: %s\n", prio, msg);
}

static double spin_s = -1;    /* the next daemon's spin_s; < 0: the default */

static void start_daemon(daemon_thread *d, int64_t id, int threads)
{
    sc_serve_config c = sc_serve_config_default();
    if (spin_s >= 0)
        c.spin_s = spin_s;
    /* a daemon at normal priority polls only on a node with no owner */
    c.dedicated = spin_s > 0;
    c.url = url;
    memcpy(c.key, key, sizeof key);
    c.threads = threads;
    c.node_id = id;
    c.busy_threshold = 1;           /* this test's own load is not an owner's */
    c.heartbeat_s = 0.05;
    c.idle_priority = 0;
    c.log = log_to_stderr;
    assert_int_equal(sc_serve_create(&c, &d->s), SC_OK);
    assert_int_equal(pthread_create(&d->t, NULL, serve_main, d), 0);
}

static void stop_daemon(daemon_thread *d, sc_serve_counters *n)
{
    sc_serve_stop(d->s);
    pthread_join(d->t, NULL);
    assert_int_equal(d->rc, SC_OK);
    if (n)
        sc_serve_counters_get(d->s, n);
    sc_serve_destroy(d->s);
    d->s = NULL;
}

static sc_world *make_world(int cluster, const char *keyfile)
{
    sc_world_config c = sc_world_config_default();
    c.workers = 1;
    c.motion_groups = groups;
    c.toi_mode = toi_mode;
    c.island_split = island_split;
    if (cluster) {
        c.cluster = url;
        c.key_file = keyfile;
        c.cluster_deadline_s = 0.05;
        /* these tests are about what happens to units out on daemons:
         * they go out whatever shipping them costs (a lone sphere's frame
         * costs less than that, and the worth-it rule would keep it here) */
        c.cluster_ship_share = -1;
        c.cluster_min_gain = min_gain;
    }
    sc_world *w = sc_world_create(&c);
    assert_non_null(w);
    if (!pile_scene) {
        assert_int_equal(sc_scene_bolts_nuts(w, BODIES, 11), SC_OK);
        return w;
    }
    /* a pile (one group with most of the work) and lone spheres high
     * above it, falling side by side (a group each) */
    assert_int_equal(sc_scene_bin(w, 40, 11), SC_OK);
    sc_body_desc d = sc_body_desc_default();
    d.shape = sc_shape_sphere(0.01);
    assert_non_null(d.shape);
    d.mass = 0.03;
    for (int i = 0; i < 24; i++) {
        d.pos[0] = -0.1 + 0.04 * (i % 6);
        d.pos[1] = -0.1 + 0.04 * (i / 6);
        d.pos[2] = 10 + 0.05 * i;
        assert_true(sc_body_add(w, &d) >= 0);
    }
    sc_shape_release(d.shape);
    return w;
}

/* Until the world has heard from n daemons (stepping a throwaway world on
 * the same key: heartbeats are taken in at each frame). */
static void wait_daemons(sc_world *w, int n)
{
    sc_stats st;
    for (int i = 0; i < 200; i++) {
        sc_cluster_frame(w->cluster);
        sc_world_stats(w, &st);
        if (st.now.daemons >= n)
            return;
        usleep(10000);
    }
    fail_msg("only %d of %d daemons heard from", st.now.daemons, n);
}

static uint64_t local_hash_n(int frames)
{
    sc_world *w = make_world(0, NULL);
    for (int f = 0; f < frames; f++)
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
    uint64_t h = sc_world_hash(w);
    sc_world_destroy(w);
    return h;
}

static uint64_t local_hash(void)
{
    return local_hash_n(FRAMES);
}

/* Steps the world; stop_at >= 0 stops daemon d there. Totals in *sum. */
static uint64_t run(sc_world *w, daemon_thread *d, int stop_at, sc_stats *sum)
{
    memset(sum, 0, sizeof *sum);
    for (int f = 0; f < FRAMES; f++) {
        if (f == stop_at)
            stop_daemon(d, NULL);
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
        sc_stats st;
        sc_world_stats(w, &st);
        sum->frame.remote.units += st.frame.remote.units;
        sum->frame.remote.recomputed_units += st.frame.remote.recomputed_units;
        sum->frame.remote.late_results += st.frame.remote.late_results;
        sum->frame.remote.unit_messages += st.frame.remote.unit_messages;
        sum->frame.remote.result_messages += st.frame.remote.result_messages;
        /* the model's figures of the daemons (bench_cluster -p model) */
        assert_true(st.frame.remote.overhead_s >= 0 && st.frame.remote.work_s >= 0 &&
                    st.frame.remote.bytes >= 0);
        assert_true(st.frame.remote.units > 0 ||
                    (st.frame.remote.work_s == 0 && st.frame.remote.bytes == 0));
        assert_true(st.frame.remote.jobs <= st.frame.sched.jobs * 64);
        sum->frame.remote.jobs += st.frame.remote.jobs;
        sum->frame.remote.overhead_s += st.frame.remote.overhead_s;
        sum->frame.remote.bytes += st.frame.remote.bytes;
        sum->frame.remote.work_s += st.frame.remote.work_s;
        /* the solver's counters (remote units' come with their results) */
        sum->frame.lcp.pivots += st.frame.lcp.pivots;
        sum->frame.lcp.split += st.frame.lcp.split;
        sum->frame.lcp.blocks += st.frame.lcp.blocks;
        sum->frame.lcp.unconverged += st.frame.lcp.unconverged;
        sum->frame.lcp.fallbacks += st.frame.lcp.fallbacks;
        sum->frame.lcp.energy_refused += st.frame.lcp.energy_refused;
        sum->frame.lcp.restitution_scaled += st.frame.lcp.restitution_scaled;
        sum->frame.lcp.regularised += st.frame.lcp.regularised;
        if (st.frame.lcp.sweeps_max > sum->frame.lcp.sweeps_max)
            sum->frame.lcp.sweeps_max = st.frame.lcp.sweeps_max;
        sum->frame.lcp.sweeps += st.frame.lcp.sweeps;
        if (st.frame.lcp.residual > sum->frame.lcp.residual)
            sum->frame.lcp.residual = st.frame.lcp.residual;
        if (st.frame.lcp.outer_residual > sum->frame.lcp.outer_residual)
            sum->frame.lcp.outer_residual = st.frame.lcp.outer_residual;
        sum->total.dropped_messages = st.total.dropped_messages;
        sum->now.daemons = st.now.daemons;
    }
    return sc_world_hash(w);
}

/* Units of motion groups (a group's whole frame each) whose results came
 * from daemons: the scheduler learns from them on the daemons' nodes only
 * (a recomputed unit counts as the calling thread's). */
static int remote_group_units(const sc_world *w)
{
    int n = 0;
    for (int k = w->ex.nlocal; k < w->ex.nnodes; k++)
        n += w->ex.sched.nodes[k].model[SC_UNIT_GROUP].n;
    return n;
}

static void test_daemons_give_the_same_bits(void **state)
{
    (void)state;
    uint64_t h0 = local_hash();
    daemon_thread d[2];
    /* one daemon polls for units long enough to catch every next one of
     * a run, the other sleeps at once: the same bits either way */
    spin_s = SC_SERVE_SPIN_MAX;
    start_daemon(&d[0], 0x1001, 1);
    spin_s = 0;
    start_daemon(&d[1], 0x1002, 2);
    spin_s = -1;
    sc_world *w = make_world(1, key_path);
    wait_daemons(w, 2);
    sc_stats sum;
    uint64_t h = run(w, NULL, -1, &sum);
    sc_serve_counters n0, n1;
    stop_daemon(&d[0], &n0);
    stop_daemon(&d[1], &n1);
    int gu = remote_group_units(w);
    printf("  remote %ld (group units at least %d) recomputed %ld late %ld; daemon results %ld "
           "and %ld, shapes %ld; messages a frame %.2f out, %.2f in\n",
           sum.frame.remote.units, gu, sum.frame.remote.recomputed_units,
           sum.frame.remote.late_results, n0.results, n1.results, n0.shapes,
           (double)sum.frame.remote.unit_messages / FRAMES,
           (double)sum.frame.remote.result_messages / FRAMES);
    assert_true(h == h0);
    assert_true(sum.frame.remote.units > 0);
    /* every answered job's round trip is counted, with the work and the
     * wire bytes of what came back */
    printf("  remote jobs %ld, round trip less work %.3f ms a job, %.0f bytes, %.4f s work\n",
           sum.frame.remote.jobs,
           1e3 * sum.frame.remote.overhead_s / (sum.frame.remote.jobs ? sum.frame.remote.jobs : 1),
           sum.frame.remote.bytes, sum.frame.remote.work_s);
    assert_true(sum.frame.remote.jobs > 0 && sum.frame.remote.bytes > 0 &&
                sum.frame.remote.work_s > 0);
    /* results came in messages of one or more, units went out in some */
    assert_true(sum.frame.remote.result_messages > 0 &&
                sum.frame.remote.result_messages <= n0.results + n1.results);
    assert_true(sum.frame.remote.unit_messages > 0);
    assert_true(n0.results > 0 && n1.results > 0);
    printf("  units found while polling: %ld of %ld (spin 0.1 s), %ld of %ld (spin 0)\n",
           n0.spin_hits, n0.units, n1.spin_hits, n1.units);
    assert_true(n0.spin_hits <= n0.units);
    assert_int_equal(n1.spin_hits, 0);
    /* the paper's frame sends a daemon units many times a frame: some
     * come while it polls (motion groups' runs send far fewer) */
    if (!groups && toi_mode != SC_TOI_LOCAL)
        assert_true(n0.spin_hits > 0);
    assert_true(n0.shapes + n1.shapes >= 2);    /* bolt, nut, floor: on request */
    /* by motion groups, whole frames of groups travel */
    if (groups || toi_mode == SC_TOI_LOCAL)
        assert_true(gu > 0);
    else
        assert_int_equal(gu, 0);
    assert_int_equal(sum.total.dropped_messages, 0);
    sc_world_destroy(w);
}

/* The job-level worth-it rule (cluster_min_gain) decides who computes,
 * never what: a daemon asked for 1000 round trips of work a job is kept
 * out of the jobs it would have had once 4 of its round trips are
 * measured (counted in remote_refused; it is tried again as they decay),
 * and both runs end in the local bits. */
static void test_the_job_level_rule_keeps_daemons_out_not_the_bits(void **state)
{
    (void)state;
    uint64_t h0 = local_hash();
    long remote[2], refused[2];
    const double gain[2] = { -1, 1000 };
    for (int c = 0; c < 2; c++) {
        daemon_thread d;
        start_daemon(&d, 0x1201 + c, 1);
        min_gain = gain[c];
        sc_world *w = make_world(1, key_path);
        wait_daemons(w, 1);
        remote[c] = refused[c] = 0;
        uint64_t h = 0;
        for (int f = 0; f < FRAMES; f++) {
            assert_int_equal(sc_world_step(w, 0.01), SC_OK);
            sc_stats st;
            sc_world_stats(w, &st);
            remote[c] += st.frame.remote.units;
            refused[c] += st.frame.remote.refused;
        }
        h = sc_world_hash(w);
        printf("  min_gain %g: %ld units from the daemon, kept out of %ld jobs\n", gain[c],
               remote[c], refused[c]);
        sc_world_destroy(w);
        stop_daemon(&d, NULL);
        min_gain = -1;
        assert_true(h == h0);
    }
    assert_int_equal(refused[0], 0);
    assert_true(remote[0] > 0 && remote[1] > 0);    /* used, so measured */
    assert_true(refused[1] > 0);
}

/* Motion groups: each group's frame is a unit, sent to daemons like any
 * (a pile's stays here, its inner jobs may travel). */
static void test_daemons_with_motion_groups(void **state)
{
    groups = 1;
    test_daemons_give_the_same_bits(state);
    groups = 0;
}

/* The local time-of-impact mode runs every frame by motion groups: the
 * group units go to the daemons, and the bits are the local run's. */
static void test_daemons_in_local_toi_mode(void **state)
{
    toi_mode = SC_TOI_LOCAL;
    test_daemons_give_the_same_bits(state);
    toi_mode = SC_TOI_WORLD;
}

/* Islands past 2 contacts solved by blocks, warm-started from the last
 * frame's impulses, and units assigned at random (island units reach the
 * daemons too, not only where they would pay): the impulses go out with a
 * unit and come back with its result, so the bits are the local ones, and
 * so are the solver's counters (with theirs). */
static void test_split_islands_on_daemons_give_the_same_bits(void **state)
{
    (void)state;
    island_split = 2;
    sc_world *lw = make_world(0, NULL);
    sc_stats ls;
    uint64_t h0 = run(lw, NULL, -1, &ls);
    sc_world_destroy(lw);
    daemon_thread d[2];
    start_daemon(&d[0], 0x1501, 1);
    start_daemon(&d[1], 0x1502, 2);
    sc_world *w = make_world(1, key_path);
    wait_daemons(w, 2);
    w->ex.sched.shuffle = 0x9e3779b97f4a7c15ULL;
    sc_stats sum;
    uint64_t h = run(w, NULL, -1, &sum);
    sc_serve_counters n0, n1;
    stop_daemon(&d[0], &n0);
    stop_daemon(&d[1], &n1);
    printf("  remote %ld recomputed %ld late %ld; split %d (local %d), blocks %ld (%ld), "
           "pivots %ld (%ld), sweeps at most %d (%d); daemon results %ld and %ld\n",
           sum.frame.remote.units, sum.frame.remote.recomputed_units, sum.frame.remote.late_results,
           sum.frame.lcp.split, ls.frame.lcp.split, sum.frame.lcp.blocks, ls.frame.lcp.blocks,
           sum.frame.lcp.pivots, ls.frame.lcp.pivots, sum.frame.lcp.sweeps_max,
           ls.frame.lcp.sweeps_max, n0.results, n1.results);
    island_split = SC_ISLAND_SPLIT_DEFAULT;
    assert_true(h == h0);
    assert_true(sum.frame.lcp.split > 0 && sum.frame.lcp.blocks > 0);
    assert_int_equal(sum.frame.lcp.split, ls.frame.lcp.split);
    assert_int_equal(sum.frame.lcp.blocks, ls.frame.lcp.blocks);
    assert_int_equal(sum.frame.lcp.pivots, ls.frame.lcp.pivots);
    assert_int_equal(sum.frame.lcp.unconverged, ls.frame.lcp.unconverged);
    assert_int_equal(sum.frame.lcp.fallbacks, ls.frame.lcp.fallbacks);
    assert_int_equal(sum.frame.lcp.energy_refused, ls.frame.lcp.energy_refused);
    assert_int_equal(sum.frame.lcp.restitution_scaled, ls.frame.lcp.restitution_scaled);
    assert_int_equal(sum.frame.lcp.regularised, ls.frame.lcp.regularised);
    assert_int_equal(sum.frame.lcp.sweeps_max, ls.frame.lcp.sweeps_max);
    assert_int_equal(sum.frame.lcp.sweeps, ls.frame.lcp.sweeps);
    assert_true(sum.frame.lcp.sweeps >= sum.frame.lcp.sweeps_max);
    assert_memory_equal(&sum.frame.lcp.residual, &ls.frame.lcp.residual,
                        sizeof ls.frame.lcp.residual);
    assert_memory_equal(&sum.frame.lcp.outer_residual, &ls.frame.lcp.outer_residual,
                        sizeof ls.frame.lcp.outer_residual);
    assert_true(sum.frame.remote.units > 0);
    assert_true(n0.results > 0 && n1.results > 0);
    assert_int_equal(sum.total.dropped_messages, 0);
    /* the setting took effect */
    assert_true(h0 != local_hash());
    sc_world_destroy(w);
}

static void test_a_daemon_that_stops_changes_nothing(void **state)
{
    (void)state;
    uint64_t h0 = local_hash();
    daemon_thread d[2];
    start_daemon(&d[0], 0x2001, 1);
    start_daemon(&d[1], 0x2002, 1);
    sc_world *w = make_world(1, key_path);
    wait_daemons(w, 2);
    sc_stats sum;
    uint64_t h = run(w, &d[0], FRAMES / 3, &sum);
    stop_daemon(&d[1], NULL);
    int gu = remote_group_units(w);
    printf("  remote %ld (group units at least %d) recomputed %ld late %ld\n",
           sum.frame.remote.units, gu, sum.frame.remote.recomputed_units,
           sum.frame.remote.late_results);
    assert_true(h == h0);
    assert_true(sum.frame.remote.units > 0);
    if (toi_mode == SC_TOI_LOCAL)
        assert_true(gu > 0);
    sc_world_destroy(w);
}

/* The same with group units in flight when the daemon stops: those it
 * held are recomputed here after the deadline. */
static void test_a_daemon_that_stops_in_local_toi_mode_changes_nothing(void **state)
{
    toi_mode = SC_TOI_LOCAL;
    test_a_daemon_that_stops_changes_nothing(state);
    toi_mode = SC_TOI_WORLD;
}

/* With a pile, the other groups' units go to the daemons before the pile
 * steps here and come back while it runs (sc_stats.frame.remote.pipelined_units), and
 * the bits are the local run's; a daemon stopped part-way, with group
 * units out to it while a pile runs, changes nothing either (its units
 * are recomputed here after the deadline). */
static void groups_while_the_pile_runs(int stop)
{
    toi_mode = SC_TOI_LOCAL;
    pile_scene = 1;
    uint64_t h0 = local_hash();
    daemon_thread d;
    start_daemon(&d, stop ? 0x2201 : 0x2101, 1);
    sc_world *w = make_world(1, key_path);
    sc_cluster_force(w->cluster);   /* this test's own load is not an owner's */
    wait_daemons(w, 1);
    long piped = 0, piped_before = 0, recomputed = 0;
    for (int f = 0; f < FRAMES; f++) {
        if (stop && f == FRAMES / 2)
            stop_daemon(&d, NULL);
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
        sc_stats st;
        sc_world_stats(w, &st);
        piped += st.frame.remote.pipelined_units;
        recomputed += st.frame.remote.recomputed_units;
        if (f < FRAMES / 2)
            piped_before = piped;
    }
    uint64_t h = sc_world_hash(w);
    if (!stop)
        stop_daemon(&d, NULL);
    printf("  group units back while the pile ran %ld (%ld before the stop), recomputed %ld\n",
           piped, piped_before, recomputed);
    toi_mode = SC_TOI_WORLD;
    pile_scene = 0;
    assert_true(h == h0);
    assert_true(piped_before > 0);
    if (stop)
        assert_true(recomputed > 0);
    sc_world_destroy(w);
}

static void test_daemons_step_groups_while_the_pile_runs(void **state)
{
    (void)state;
    groups_while_the_pile_runs(0);
}

static void test_a_daemon_stopped_while_the_pile_runs_changes_nothing(void **state)
{
    (void)state;
    groups_while_the_pile_runs(1);
}

static void test_wrong_key_daemon_is_never_used(void **state)
{
    (void)state;
    uint64_t h0 = local_hash();
    daemon_thread d;
    start_daemon(&d, 0x3001, 1);
    /* the world runs with the insecure all-zero key: the daemon's
     * heartbeats fail its check, so it never becomes a node */
    sc_world *w = make_world(1, NULL);
    usleep(200000);
    sc_stats sum;
    uint64_t h = run(w, NULL, -1, &sum);
    stop_daemon(&d, NULL);
    assert_true(h == h0);
    assert_int_equal(sum.frame.remote.units, 0);
    assert_int_equal(sum.now.daemons, 0);
    assert_true(sum.total.dropped_messages > 0);
    sc_world_destroy(w);
}

/* sc_cluster_wait: returns once two daemons answer (within a few of their
 * 0.05 s heartbeats); with a third wanted it waits out its timeout and
 * says two; under another key it hears none; a config without a cluster,
 * or a bad count or timeout, is SC_EINVAL, one not made by
 * sc_world_config_default() SC_ENOINIT, a URL LCM cannot open or a missing
 * key file SC_EIO. */
static void test_cluster_wait_counts_daemons(void **state)
{
    (void)state;
    daemon_thread d[2];
    start_daemon(&d[0], 0x5001, 1);
    start_daemon(&d[1], 0x5002, 1);
    sc_world_config c = sc_world_config_default();
    c.cluster = url;
    c.key_file = key_path;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    assert_true(sc_cluster_wait(&c, 2, 5) >= 2);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    assert_true(s < 2);
    assert_int_equal(sc_cluster_wait(&c, 3, 0.3), 2);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    assert_true(s >= 0.3 && s < 4);
    assert_true(sc_cluster_wait(&c, 0, 0) >= 0);      /* at once: one look */
    c.key_file = NULL;              /* the all-zero key: their MACs fail */
    assert_int_equal(sc_cluster_wait(&c, 1, 0.3), 0);
    c.key_file = "/nonexistent/simcluster.key";
    assert_int_equal(sc_cluster_wait(&c, 1, 1), SC_EIO);
    c.key_file = key_path;
    c.cluster = "udpm://999.1.1.1:7667";
    assert_int_equal(sc_cluster_wait(&c, 1, 1), SC_EIO);
    c.cluster = url;
    sc_world_config raw = c;
    raw.internal_cookie = 0;
    assert_int_equal(sc_cluster_wait(&raw, 1, 1), SC_ENOINIT);
    assert_int_equal(sc_cluster_wait(&c, -1, 1), SC_EINVAL);
    assert_int_equal(sc_cluster_wait(&c, SC_MAX_DAEMONS + 1, 1), SC_EINVAL);
    assert_int_equal(sc_cluster_wait(&c, 1, -1), SC_EINVAL);
    assert_int_equal(sc_cluster_wait(NULL, 1, 1), SC_EINVAL);
    c.cluster = NULL;
    c.key_file = NULL;
    assert_int_equal(sc_cluster_wait(&c, 1, 1), SC_EINVAL);
    stop_daemon(&d[0], NULL);
    stop_daemon(&d[1], NULL);
}

static void test_hostile_messages_are_dropped(void **state)
{
    (void)state;
    daemon_thread d;
    start_daemon(&d, 0x4001, 1);
    sc_bus *l = NULL;
    assert_int_equal(sc_bus_open(url, &l, NULL, 0), SC_OK);
    const char *ch = "SC_UNIT_0000000000004001";
    uint8_t junk[300];
    for (size_t i = 0; i < sizeof junk; i++)
        junk[i] = (uint8_t)(i * 37 + 11);
    /* one burst: the daemon's socket holds it all (no queue that drops) */
    for (int i = 1; i < 40; i++)
        sc_bus_publish(l, ch, junk, (size_t)(i * 7));   /* garbage */
    uint8_t other[SC_KEY_BYTES] = { 1 }, *env;
    size_t elen;
    assert_int_equal(sc_msg_seal(other, 77, 1, 1, 0, SC_MSG_UNIT, junk, 40, &env, &elen), SC_OK);
    sc_bus_publish(l, ch, env, elen);                   /* wrong key */
    free(env);
    uint8_t *p;
    size_t plen;
    sc_msg_work wk = { 1, 0, junk, 100, 0 };
    assert_int_equal(sc_msg_work_encode(SC_MSG_UNIT, &wk, &p, &plen), SC_OK);
    sc_serve_counters n;
    sc_serve_counters_get(d.s, &n);     /* units name the daemon's epoch */
    assert_int_equal(sc_msg_seal(key, 77, 1, 5, n.epoch, SC_MSG_UNIT, p, plen, &env, &elen),
                     SC_OK);
    for (int i = 0; i < 3; i++) {
        sc_bus_publish(l, ch, env, elen);               /* once, then replays */
        usleep(2000);
    }
    sc_bus_publish(l, ch, env, elen / 2);               /* truncated */
    free(env);
    free(p);
    for (int i = 0; i < 500; i++) {
        usleep(10000);
        sc_serve_counters_get(d.s, &n);
        if (getenv("SC_DEBUG") && i % 50 == 0)
            printf("  t=%d format %ld auth %ld replay %ld\n", i, n.dropped_format, n.dropped_auth, n.dropped_replay);
        if (n.dropped_replay >= 2 && n.dropped_auth >= 1 && n.unit_errors >= 1 &&
            n.dropped_format >= 40)
            break;
    }
    sc_bus_close(l);
    printf("  format %ld auth %ld replay %ld unit errors %ld\n", n.dropped_format,
           n.dropped_auth, n.dropped_replay, n.unit_errors);
    /* all of the burst arrived and is counted: 39 garbage and 1 truncated */
    assert_int_equal(n.dropped_kernel, 0);
    assert_int_equal(n.dropped_format, 40);
    assert_int_equal(n.dropped_auth, 1);
    assert_int_equal(n.unit_errors, 1);     /* the one accepted: its wire is junk */
    assert_int_equal(n.dropped_replay, 2);
    assert_int_equal(n.results, 0);
    stop_daemon(&d, NULL);
}

static double mono_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Sealed messages seen on one channel (a passive listener's copy). */
typedef struct capture {
    uint8_t *msg[32];
    size_t len[32];
    int n;
} capture;

static void on_capture(void *ctx, const char *channel, const uint8_t *data, size_t len,
                       int64_t recv_us)
{
    (void)channel;
    (void)recv_us;
    capture *c = ctx;
    if (c->n < 32 && (c->msg[c->n] = malloc(len ? len : 1)) != NULL) {
        if (len)
            memcpy(c->msg[c->n], data, len);
        c->len[c->n++] = len;
    }
}

/* Handle l's messages for s seconds. */
static void pump_for(sc_bus *l, double s)
{
    double end = mono_s() + s;
    while (mono_s() < end)
        sc_bus_handle(l, 0.01);
}

/* Publish what c holds on channel, paced, and free it. */
static void replay(sc_bus *l, const char *channel, capture *c)
{
    for (int i = 0; i < c->n; i++) {
        sc_bus_publish(l, channel, c->msg[i], c->len[i]);
        free(c->msg[i]);
        usleep(3000);
    }
}

/* A daemon killed and started again with the same id (a new epoch) is
 * challenged on its first announce and used again at once, not when its
 * new sequence numbers pass the old ones; the bits stay those of a local
 * run. */
static void test_a_daemon_restarted_with_its_id_is_used_again_at_once(void **state)
{
    (void)state;
    daemon_thread d;
    start_daemon(&d, 0x6001, 1);
    sc_world *w = make_world(1, key_path);
    wait_daemons(w, 1);
    sc_stats st;
    long before = 0, after = 0;
    for (int f = 0; f < FRAMES / 3; f++) {
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
        sc_world_stats(w, &st);
        before += st.frame.remote.units;
    }
    stop_daemon(&d, NULL);
    start_daemon(&d, 0x6001, 1);
    /* until the new start's first result has been merged: units sent to
     * the old epoch meanwhile are refused by the new one and recomputed */
    double t0 = mono_s(), used = -1;
    sc_serve_counters n;
    /* FRAMES at least; more while the new start has not been used and
     * less than 1.5 s have passed (on a loaded machine the frames can run
     * out before its first announce); the local run takes as many */
    int frames = FRAMES;
    for (int f = FRAMES / 3; f < frames; f++) {
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
        sc_world_stats(w, &st);
        after += st.frame.remote.units;
        sc_serve_counters_get(d.s, &n);
        if (used < 0 && st.frame.remote.units > 0 && n.results > 0)
            used = mono_s() - t0;
        if (f + 1 == frames && used < 0 && mono_s() - t0 < 1.5 && frames < 8 * FRAMES)
            frames++;
    }
    stop_daemon(&d, &n);
    printf("  used again %.3f s after the restart (%d frames); remote units %ld before, %ld "
           "after (results %ld), challenges answered %ld, misaddressed %ld\n", used, frames,
           before, after,
           n.results, n.challenges, n.dropped_misaddressed);
    assert_true(used >= 0 && used < 1);
    assert_true(before > 0 && after > 0 && n.results > 0);
    assert_int_equal(n.challenges >= 1, 1);
    assert_true(sc_world_hash(w) == local_hash_n(frames));
    sc_world_destroy(w);
}

/* A dead daemon's heartbeats, captured and replayed to a new master, are
 * challenged; nobody answers, so it never counts and gets no work. */
static void test_a_dead_daemons_replayed_announces_never_count(void **state)
{
    (void)state;
    uint64_t h0 = local_hash();
    sc_bus *l = NULL;
    assert_int_equal(sc_bus_open(url, &l, NULL, 0), SC_OK);
    capture cap = { .n = 0 };
    assert_int_equal(sc_bus_subscribe(l, "SC_ANNOUNCE", on_capture, &cap), SC_OK);
    daemon_thread d;
    start_daemon(&d, 0x7001, 1);
    pump_for(l, 0.4);
    stop_daemon(&d, NULL);
    pump_for(l, 0.05);
    assert_true(cap.n >= 3);
    int n = cap.n;
    sc_world *w = make_world(1, key_path);
    sc_stats st;
    int unverified = 0;
    for (int i = 0; i < n; i++) {
        sc_bus_publish(l, "SC_ANNOUNCE", cap.msg[i], cap.len[i]);
        free(cap.msg[i]);
        usleep(20000);
        sc_cluster_frame(w->cluster);
        sc_world_stats(w, &st);
        assert_int_equal(st.now.daemons, 0);
        unverified |= st.now.daemons_unverified == 1;
    }
    cap.n = 0;
    sc_stats sum;
    uint64_t h = run(w, NULL, -1, &sum);
    printf("  %d announces replayed: heard unverified %d, daemons %d, remote units %ld\n", n,
           unverified, sum.now.daemons, sum.frame.remote.units);
    assert_true(unverified);
    assert_int_equal(sum.frame.remote.units, 0);
    assert_true(h == h0);
    sc_world_destroy(w);
    sc_bus_close(l);
}

/* Units (and challenges) a master sent one start of a daemon, captured
 * and replayed to the next start with the same id: addressed to the old
 * epoch, refused and counted, nothing computed. */
static void test_units_captured_before_a_restart_are_refused_after_it(void **state)
{
    (void)state;
    const char *ch = "SC_UNIT_0000000000008001";
    sc_bus *l = NULL;
    assert_int_equal(sc_bus_open(url, &l, NULL, 0), SC_OK);
    capture cap = { .n = 0 };
    assert_int_equal(sc_bus_subscribe(l, ch, on_capture, &cap), SC_OK);
    daemon_thread d;
    start_daemon(&d, 0x8001, 1);
    sc_world *w = make_world(1, key_path);
    wait_daemons(w, 1);
    for (int f = 0; f < 30; f++)
        assert_int_equal(sc_world_step(w, 0.01), SC_OK);
    sc_world_destroy(w);
    pump_for(l, 0.1);
    sc_serve_counters n;
    stop_daemon(&d, &n);
    assert_true(n.units > 0);
    assert_true(cap.n >= 3);
    int sent = cap.n;
    start_daemon(&d, 0x8001, 1);
    usleep(50000);
    replay(l, ch, &cap);
    for (int i = 0; i < 100; i++) {
        usleep(10000);
        sc_serve_counters_get(d.s, &n);
        if (n.dropped_misaddressed >= sent)
            break;
    }
    stop_daemon(&d, &n);
    printf("  %d captured messages replayed: misaddressed %ld, units %ld, results %ld\n", sent,
           n.dropped_misaddressed, n.units, n.results);
    assert_true(n.dropped_misaddressed >= sent - 2);  /* UDP may lose one or two */
    assert_int_equal(n.units, 0);
    assert_int_equal(n.results, 0);
    assert_int_equal(n.dropped_replay + n.dropped_stale, 0);
    sc_bus_close(l);
}

/* Jobs of a link of latency a and b s a byte, sizes spread over 2-200 kB,
 * with +-20 us of noise, into l. */
static void link_jobs(sc_link *l, double a, double b, int n)
{
    uint64_t r = 1;
    for (int j = 0; j < n; j++) {
        double x = 2000 + 198000.0 * (j * 37 % 40) / 40;
        r = r * 6364136223846793005ull + 1442695040888963407ull;
        double noise = 40e-6 * ((double)(r >> 11) / 9007199254740992.0 - 0.5);
        sc_link_fit(l, x, a + b * x + noise);
    }
}

/* The scheduler's view of a daemon's link (cluster.c): recovered from its
 * jobs' round trips at loopback's, 100 and 10 Mbit/s's rates; the prior
 * kept while the jobs are all of one size; in range when round trips
 * fall with size (noise). */
static void test_link_fit(void **state)
{
    (void)state;
    const double a[3] = { 50e-6, 300e-6, 1.2e-3 }, b[3] = { 2e-9, 80e-9, 800e-9 };
    for (int k = 0; k < 3; k++) {
        sc_link l = { 0 };
        link_jobs(&l, a[k], b[k], 40);
        print_message("link %d: latency %.1f us (%.1f), %.3g s a byte (%.3g)\n", k,
                      1e6 * l.latency, 1e6 * a[k], l.byte_s, b[k]);
        assert_true(fabs(l.byte_s - b[k]) < 0.05 * b[k] + 2e-10);
        assert_true(fabs(l.latency - a[k]) < 30e-6);
    }
    sc_link l = { 0 };
    for (int j = 0; j < 20; j++)
        sc_link_fit(&l, 50e3, 1e-3);
    assert_true(l.byte_s == SC_LINK_BYTE_S);
    assert_true(fabs(l.latency - (1e-3 - 50e3 * SC_LINK_BYTE_S)) < 1e-9);
    sc_link f = { 0 };
    for (int j = 0; j < 20; j++)
        sc_link_fit(&f, 1000.0 * (j % 5 + 1), 1e-3 / (j % 5 + 1));
    assert_true(f.byte_s >= 1e-11 && f.byte_s <= 1e-5 && f.latency >= 0);
}

/* A daemon's compute threads take the first unit of the newest job of
 * the first unit's master: a pile's substep (sent after the frame's
 * groups) before the groups, a job's units in their order, another
 * master's (or another start's) units in arrival order. */
static void test_daemon_runs_the_newest_job_first(void **state)
{
    (void)state;
    const sc_serve_job q[] = {
        { 7, 1, 10 }, { 7, 1, 10 }, { 9, 1, 30 }, { 7, 1, 11 }, { 7, 1, 11 }, { 7, 2, 12 },
    };
    assert_int_equal(sc_serve_pick(q, 1), 0);
    assert_int_equal(sc_serve_pick(q, 2), 0);   /* one job: in order */
    assert_int_equal(sc_serve_pick(q, 3), 0);   /* another master's newer job: not this one's */
    assert_int_equal(sc_serve_pick(q, 5), 3);   /* the newer job, its first unit */
    assert_int_equal(sc_serve_pick(q, 6), 3);   /* another start of the master: not its */
    assert_int_equal(sc_serve_pick(&q[2], 4), 0);
    assert_int_equal(sc_serve_pick(&q[3], 3), 0);
}

int main(void)
{
    srand((unsigned)time(NULL) ^ (unsigned)getpid());
    snprintf(url, sizeof url, "udpm://239.255.76.67:%d?ttl=0&recv_buf_size=4194304",
             20000 + rand() % 10000);
    snprintf(key_path, sizeof key_path, "/tmp/sc_test_key_%d", (int)getpid());
    unlink(key_path);
    if (sc_key_generate(key_path) != SC_OK || sc_key_load(key_path, key) != SC_OK) {
        fprintf(stderr, "cannot make a key in /tmp\n");
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_link_fit),
        cmocka_unit_test(test_daemon_runs_the_newest_job_first),
        cmocka_unit_test(test_daemons_give_the_same_bits),
        cmocka_unit_test(test_daemons_with_motion_groups),
        cmocka_unit_test(test_daemons_in_local_toi_mode),
        cmocka_unit_test(test_the_job_level_rule_keeps_daemons_out_not_the_bits),
        cmocka_unit_test(test_split_islands_on_daemons_give_the_same_bits),
        cmocka_unit_test(test_a_daemon_that_stops_changes_nothing),
        cmocka_unit_test(test_a_daemon_that_stops_in_local_toi_mode_changes_nothing),
        cmocka_unit_test(test_daemons_step_groups_while_the_pile_runs),
        cmocka_unit_test(test_a_daemon_stopped_while_the_pile_runs_changes_nothing),
        cmocka_unit_test(test_wrong_key_daemon_is_never_used),
        cmocka_unit_test(test_cluster_wait_counts_daemons),
        cmocka_unit_test(test_hostile_messages_are_dropped),
        cmocka_unit_test(test_a_daemon_restarted_with_its_id_is_used_again_at_once),
        cmocka_unit_test(test_a_dead_daemons_replayed_announces_never_count),
        cmocka_unit_test(test_units_captured_before_a_restart_are_refused_after_it),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    unlink(key_path);
    return rc;
}
