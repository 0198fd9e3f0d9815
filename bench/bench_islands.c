/* bench_islands.c - island size against contact solve time on the dense
 * pile (the solver: lib/core/contact.c): cold Dantzig, warm Dantzig and split.
 *
 * The islands are those of a real pile: sc_scene_bin(N, seed) (default
 * 200 parts) on a default world with one worker is stepped at 100 Hz for
 * T simulated seconds (-t, default 1.0) until the pile has formed, and
 * snapshots are taken then and every G seconds after (-k K snapshots,
 * default 3, -g G, default 0.25: at 1.0, 1.25 and 1.5 s), so that the
 * larger buckets hold more than one or two islands. At each snapshot
 * the next frame's first substep is set up as lib/core/frame.c's
 * substep() sets it up, on a copy of the world's state: the bodies get
 * u* = u + h g (sc_apply_forces, h = the whole frame, 0.01 s), the
 * contacts are the world's last detection with their impulses as matched
 * from the last solve (the warm start the frame would use), and the
 * islands are built over the movable bodies (sc_islands_build; asleep and
 * static bodies join none, as in the frame). Each island is solved by
 * sc_island_solve, the function the frame's island units call, always on
 * a fresh copy of the bodies and contacts, in three modes:
 *   cold   one exact LCP (split_contacts = 0), cold = 1 and every impulse
 *          zeroed: the paper's method, from z = 0
 *   warm   one exact LCP (split_contacts = 0), cold = 0: warm-started from
 *          the matched impulses (the engine warm-starts exact islands of
 *          more than 4 contacts only: for 1-4 contacts warm is cold)
 *   split  split_contacts = the world's island_split (default 16), cold =
 *          0: what the engine does now (islands up to 16 contacts are
 *          exact and warm, so there split is warm)
 * An "exact" island of more than SC_MAX_ISLAND_ROWS rows is split by
 * sc_island_solve whatever the mode: the "rows>max" column counts them.
 * The other contact settings are the frame's (sc_frame_contact_params()).
 *
 * A solve's time is CLOCK_MONOTONIC around sc_island_solve alone (copying
 * the state back is outside it); it includes building the rows and
 * matrices, the solve, its fallbacks and the push-out of deep contacts.
 * The arena is the engine's (grown once to the largest island, reset
 * before each solve): a solve during which it had to grow is a warm-up
 * and is repeated, as the engine's arenas stop growing after a few frames.
 * Each island is solved R times per mode (-r, default 5; caches warm, as
 * for a unit that solves its islands in a row) and its median taken; a
 * bucket's "median us" is the median of its islands' medians, "mean us"
 * their mean. Pivots (mean a solve), fallbacks (coupled friction LCP
 * failed: staggered; staggered failed: blocks; block Dantzig failed:
 * projected Gauss-Seidel; summed over the bucket's islands, one solve
 * each), regularised solves, split solves that did not converge within
 * the sweep limit, and the largest residual (exact solves: the LCP's
 * complementarity error; split ones: the outer residual; m/s) come from
 * one solve of each island (the solves are deterministic).
 *
 * Buckets by contacts: 1-4, 5-8, 9-16, 17-32, 33-64, 65-128, 129+. Exact
 * cold solves of big islands take seconds, so each bucket has a wall
 * budget (-b, default 20 s): islands are taken in island order, all three
 * modes each, until the bucket has used its budget (every island taken
 * gets at least one timed solve a mode, fewer than R repeats once the
 * budget is gone); "timed" says how many of the bucket's islands were,
 * and a capped bucket says "capped".
 *
 * Buckets pool the islands of every snapshot, in snapshot order.
 *
 * -m: the big-island methods instead (docs/DESIGN.md 11): every island of
 * more than 64 contacts (the size the engine tries the active set from) of
 * every snapshot, solved as the engine solves it (split) from the matched
 * impulses (warm) and from 0 (cold), with island_method
 * SC_ISLAND_ACTIVE_SET, SC_ISLAND_SUBDOMAINS (here on this one thread) and
 * SC_ISLAND_BLOCK_GS, one line each:
 * median time of R solves, factorisations (active set, summed over the
 * solve's velocity and push-out passes) or sweeps (the most of one pass),
 * whether the active set settled (else the blocks took it: "fallback"),
 * unconverged block passes and the largest residual; for subdomains the
 * parts, the interface unknowns, and the rounds and bytes they would
 * exchange with a master (island_schur.c). -S picks the scene:
 * bin (-n parts, the default), stack (-n cubes), pyramid (-n rows) or wall
 * (-n rows of 10), the structures of sc_scene_stack/pyramid/wall.
 *
 * usage: bench_islands [-n parts] [-t settle_s] [-k snapshots] [-g gap_s]
 *                      [-s seed] [-r reps] [-b bucket_budget_s]
 *                      [-m] [-S bin|stack|pyramid|wall] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "world.h"

#include "bench_util.h"

#define DT 0.01
#define MAX_REPS 101
#define NBUCKET 7
#define MAX_SNAPS 100

/* The frame's contact model and solver settings (sc_frame_contact_params),
 * with the mode's split and warm starts. */
static sc_contact_params frame_params(int split_contacts, int cold)
{
    sc_frame_config cfg = { .island_split = split_contacts };
    sc_contact_params p = sc_frame_contact_params(&cfg);
    p.cold = cold;
    return p;
}

enum { MODE_COLD, MODE_WARM, MODE_SPLIT, NMODE };
static const char *mode_name[NMODE] = { "cold", "warm", "split" };

static const int bucket_hi[NBUCKET] = { 4, 8, 16, 32, 64, 128, 1 << 30 };
static const char *bucket_name[NBUCKET] = { "1-4", "5-8", "9-16", "17-32",
                                            "33-64", "65-128", "129+" };

static int bucket_of(int nc)
{
    int b = 0;
    while (nc > bucket_hi[b])
        b++;
    return b;
}

/* What one mode gave over a bucket's timed islands. */
typedef struct mode_sum {
    double *med_s;            /* per timed island: median of its repeats */
    int timed;
    long solves;              /* timed solves in all */
    long pivots;              /* of one solve per island */
    long fallbacks, regularised, unconverged, split;
    double residual;
    int errors;               /* sc_island_solve returned an error */
    int last_rc;
} mode_sum;

/* One snapshot: the state the next substep's island solves start from. */
typedef struct snap {
    sc_body *bodies;          /* u* applied */
    sc_contact *contacts;     /* impulses as matched from the last solve */
    int nbodies, ncontacts;
    sc_islands is;
} snap;

typedef struct bench {
    sc_body *wb;              /* working copies, room for any snapshot */
    sc_contact *wc;
    sc_arena arena;
    int island_split;
    int island_method;        /* SC_ISLAND_* of the split solves */
    int always_split;         /* -m: cold solves split too */
} bench;

/* Solves island (ci, nc) of snapshot sn once in mode m; returns the wall
 * seconds of sc_island_solve, its code in *rc, its figures in *info, and
 * in *grew whether the arena had to grow during it. */
static double solve_once(bench *b, const snap *sn, int m, const int *ci, int nc,
                         sc_solve_info *info, int *rc, int *grew)
{
    memcpy(b->wb, sn->bodies, (size_t)sn->nbodies * sizeof *b->wb);
    memcpy(b->wc, sn->contacts, (size_t)sn->ncontacts * sizeof *b->wc);
    if (m == MODE_COLD)
        for (int k = 0; k < nc; k++)
            memset(b->wc[ci[k]].impulse, 0, sizeof b->wc[ci[k]].impulse);
    sc_contact_params p =
        frame_params(m == MODE_SPLIT || b->always_split ? b->island_split : 0, m == MODE_COLD);
    p.island_method = b->island_method;
    sc_arena_reset(&b->arena);
    long over = b->arena.overflows;
    memset(info, 0, sizeof *info);
    double t0 = now_s();
    *rc = sc_island_solve(&b->arena, b->wb, b->wc, ci, nc, DT, &p, info);
    double t = now_s() - t0;
    *grew = b->arena.overflows != over;
    return t;
}

/* Up to reps timed solves of island (ci, nc) of sn in mode m into t: a
 * solve during which the arena grew is a warm-up and is repeated (3 at
 * most); at least one, none more once now_s() passes until. The first
 * solve's figures in *first. Returns how many were timed, or a failed
 * solve's code (negative). */
static int timed_solves(bench *b, const snap *sn, int m, const int *ci, int nc, int reps,
                        double until, double *t, sc_solve_info *first)
{
    int got = 0, warmups = 0, have_first = 0;
    while (got < reps) {
        sc_solve_info info;
        int rc, grew;
        double s = solve_once(b, sn, m, ci, nc, &info, &rc, &grew);
        if (rc != SC_OK)
            return rc;
        if (!have_first) {
            *first = info;
            have_first = 1;
        }
        if (grew && warmups++ < 3)
            continue;
        t[got++] = s;
        if (now_s() > until)
            break;
    }
    return got;
}

/* The world's current state as the next substep's start (see the top). */
static int snap_take(snap *sn, const sc_world *w)
{
    memset(sn, 0, sizeof *sn);
    if (!w->st.contacts_valid) {
        fprintf(stderr, "the world's contacts are not of its current state\n");
        return -1;
    }
    sn->nbodies = w->st.nbodies;
    sn->ncontacts = w->st.ncontacts;
    sn->bodies = malloc((size_t)sn->nbodies * sizeof *sn->bodies);
    sn->contacts = malloc(((size_t)sn->ncontacts + 1) * sizeof *sn->contacts);
    unsigned char *active = malloc((size_t)sn->nbodies);
    if (!sn->bodies || !sn->contacts || !active) {
        free(active);
        return -1;
    }
    memcpy(sn->bodies, w->st.bodies, (size_t)sn->nbodies * sizeof *sn->bodies);
    memcpy(sn->contacts, w->st.contacts, (size_t)sn->ncontacts * sizeof *sn->contacts);
    sc_frame_state fs = { .bodies = sn->bodies, .nbodies = sn->nbodies };
    sc_frame fr = { .cfg = &w->fcfg, .st = &fs };
    sc_apply_forces(&fr, DT, NULL);
    for (int i = 0; i < sn->nbodies; i++)
        active[i] = sc_body_movable(&sn->bodies[i]);
    int rc = sc_islands_build(NULL, sn->nbodies, active, sn->contacts, sn->ncontacts, &sn->is);
    free(active);
    if (rc != SC_OK) {
        fprintf(stderr, "sc_islands_build: %s\n", sc_strerror(rc));
        return -1;
    }
    return 0;
}

static void snap_free(snap *sn)
{
    sc_islands_free(&sn->is);
    free(sn->contacts);
    free(sn->bodies);
}

/* Frees the bench, the snapshots and the world. */
static void bench_end(bench *b, snap *sn, int nsnap, sc_world *w)
{
    sc_arena_destroy(&b->arena);
    for (int k = 0; k < nsnap; k++)
        snap_free(&sn[k]);
    free(b->wc);
    free(b->wb);
    sc_world_destroy(w);
}

static double median(double *x, int n)
{
    qsort(x, (size_t)n, sizeof *x, cmp_double);
    return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

static void usage(void)
{
    fprintf(stderr, "usage: bench_islands [-n parts] [-t settle_s] [-k snapshots] [-g gap_s] "
                    "[-s seed] [-r reps] [-b bucket_budget_s] [-m] "
                    "[-S bin|stack|pyramid|wall]\n");
    exit(2);
}

/* Rows of island (ci, nc): three a contact with friction, else one. */
static int island_rows(const snap *S, const int *ci, int nc)
{
    int rows = 0;
    for (int c = 0; c < nc; c++)
        rows += sqrt(S->bodies[S->contacts[ci[c]].body_a].friction *
                     S->bodies[S->contacts[ci[c]].body_b].friction) > 0 ? 3 : 1;
    return rows;
}

#define METHOD_MIN_CONTACTS 64

/* -m: each island of more than METHOD_MIN_CONTACTS contacts by both
 * island methods (see the top). Returns nonzero if a solve failed. */
static int methods_table(bench *b, const snap *sn, int nsnap, int reps)
{
    static const int method[3] = { SC_ISLAND_ACTIVE_SET, SC_ISLAND_SUBDOMAINS,
                                   SC_ISLAND_BLOCK_GS };
    static const char *method_name[3] = { "active-set", "subdomains", "block-gs" };
    printf("%4s %6s %8s %6s  %-10s %-5s %11s %7s %7s %-9s %5s %10s %5s %6s %5s %9s\n", "snap",
           "island", "contacts", "rows", "method", "start", "median_us", "factors", "sweeps",
           "result", "uncv", "residual", "parts", "iface", "exch", "bytes");
    b->always_split = 1;
    int failed = 0, shown = 0;
    for (int k = 0; k < nsnap; k++)
        for (int i = 0; i < sn[k].is.count; i++) {
            const int *ci = &sn[k].is.contacts[sn[k].is.contact_start[i]];
            int nc = sn[k].is.contact_start[i + 1] - sn[k].is.contact_start[i];
            if (nc <= METHOD_MIN_CONTACTS)
                continue;
            shown++;
            for (int mm = 0; mm < 6; mm++) {
                int m = mm / 2, start = mm % 2 ? MODE_COLD : MODE_SPLIT;
                const char *start_name = start == MODE_COLD ? "cold" : "warm";
                b->island_method = method[m];
                double t[MAX_REPS];
                sc_solve_info first = { 0 };
                int got = timed_solves(b, &sn[k], start, ci, nc, reps, INFINITY, t, &first);
                int rc = got < 0 ? got : SC_OK;
                if (rc != SC_OK) {
                    printf("%4d %6d %8d %6d  %-10s %-5s error: %s\n", k, i, nc,
                           island_rows(&sn[k], ci, nc), method_name[m], start_name,
                           sc_strerror(rc));
                    failed = 1;
                    continue;
                }
                const char *result = m == 2 ? "blocks"
                                     : first.as_fallbacks ? "fallback"
                                                          : "exact";
                char factors[16];
                snprintf(factors, sizeof factors, m < 2 ? "%ld" : "-", first.as_iterations);
                printf("%4d %6d %8d %6d  %-10s %-5s %11.1f %7s %7d %-9s %5d %10.2e %5d %6d %5ld "
                       "%9ld\n",
                       k, i, nc, island_rows(&sn[k], ci, nc), method_name[m], start_name,
                       1e6 * median(t, got), factors, first.sweeps_max, result, first.unconverged,
                       fmax(first.residual_exact, first.residual_split), first.as_parts_max,
                       first.as_interface_max, first.as_exchanges, first.as_exchange_bytes);
            }
            fflush(stdout);
        }
    if (!shown)
        printf("no island of more than %d contacts\n", METHOD_MIN_CONTACTS);
    return failed;
}

int main(int argc, char **argv)
{
    int parts = 200, reps = 5, nsnap = 3;
    double settle_s = 1.0, gap_s = 0.25, budget_s = 20;
    uint64_t seed = 1;
    int opt, methods = 0;
    const char *scene = "bin";
    while ((opt = getopt(argc, argv, "n:t:k:g:s:r:b:mS:h")) != -1) {
        switch (opt) {
        case 'n': parts = atoi(optarg); break;
        case 't': settle_s = atof(optarg); break;
        case 'k': nsnap = atoi(optarg); break;
        case 'g': gap_s = atof(optarg); break;
        case 's': seed = strtoull(optarg, NULL, 0); break;
        case 'r': reps = atoi(optarg); break;
        case 'b': budget_s = atof(optarg); break;
        case 'm': methods = 1; break;
        case 'S': scene = optarg; break;
        default: usage();
        }
    }
    if (optind != argc || parts < 1 || parts > 100000 || !(settle_s >= 0) || settle_s > 1e4 ||
        nsnap < 1 || nsnap > MAX_SNAPS || !(gap_s >= DT) || gap_s > 1e4 || reps < 1 ||
        reps > MAX_REPS || !(budget_s > 0) || budget_s > 1e6 ||
        (strcmp(scene, "bin") && strcmp(scene, "stack") && strcmp(scene, "pyramid") &&
         strcmp(scene, "wall")))
        usage();

    /* ---- the pile, and its snapshots ---- */
    sc_world_config cfg = sc_world_config_default();
    cfg.workers = 1;
    sc_world *w = sc_world_create(&cfg);
    int rc = !w                        ? sc_last_error()
             : !strcmp(scene, "stack")   ? sc_scene_stack(w, parts, 0)
             : !strcmp(scene, "pyramid") ? sc_scene_pyramid(w, parts)
             : !strcmp(scene, "wall")    ? sc_scene_wall(w, 10, parts)
                                         : sc_scene_bin(w, parts, seed);
    if (rc != SC_OK) {
        fprintf(stderr, "scene %s (%d): %s\n", scene, parts, sc_strerror(rc));
        return 1;
    }
    printf("islands of the %s of %d (seed %llu), frames of %.2f s on one worker; %d "
           "snapshot%s from t = %.2f s, %.2f s apart\n",
           scene, parts, (unsigned long long)seed, DT, nsnap, nsnap == 1 ? "" : "s", settle_s,
           gap_s);
    static snap sn[MAX_SNAPS];
    bench b = { .island_split = w->fcfg.island_split, .island_method = w->fcfg.island_method };
    long frame = 0;
    int max_bodies = 0, max_contacts = 0, total_islands = 0, with_contacts = 0;
    for (int k = 0; k < nsnap; k++) {
        long until = (long)ceil((settle_s + k * gap_s) / DT - 1e-9);
        double t0 = now_s();
        for (; frame < until && rc == SC_OK; frame++)
            rc = sc_world_step(w, DT);
        double wall = now_s() - t0;
        if (rc != SC_OK) {
            fprintf(stderr, "sc_world_step at t = %.2f s: %s\n", frame * DT, sc_strerror(rc));
            return 1;
        }
        if (snap_take(&sn[k], w) != 0)
            return 1;
        sc_stats st;
        sc_world_stats(w, &st);
        int asleep = 0, big = 0, warm = 0, with = 0;
        for (int i = 0; i < sc_world_body_count(w); i++)
            asleep += sc_body_state(w, i) == SC_ASLEEP;
        for (int i = 0; i < sn[k].is.count; i++) {
            int nc = sn[k].is.contact_start[i + 1] - sn[k].is.contact_start[i];
            big = nc > big ? nc : big;
            with += nc > 0;
        }
        for (int c = 0; c < sn[k].ncontacts; c++)
            warm += sn[k].contacts[c].impulse[0] != 0 || sn[k].contacts[c].impulse[1] != 0 ||
                    sn[k].contacts[c].impulse[2] != 0;
        printf("  t = %.2f s (%.1f s wall to get there): last frame %d solves (%d split), %d "
               "substeps, max penetration %.3g m, %d parts asleep; next substep %d islands "
               "with contacts (largest %d) over %d contacts, %d with a matched impulse\n",
               frame * DT, wall, st.frame.lcp.solves, st.frame.lcp.split, st.frame.toi.substeps,
               st.frame.detect.max_penetration, asleep, with, big, sn[k].ncontacts, warm);
        max_bodies = sn[k].nbodies > max_bodies ? sn[k].nbodies : max_bodies;
        max_contacts = sn[k].ncontacts > max_contacts ? sn[k].ncontacts : max_contacts;
        total_islands += sn[k].is.count;
        with_contacts += with;
    }
    b.wb = malloc((size_t)max_bodies * sizeof *b.wb);
    b.wc = malloc(((size_t)max_contacts + 1) * sizeof *b.wc);
    if (!b.wb || !b.wc)
        return 1;
    sc_arena_init(&b.arena);
    if (methods) {
        printf("%d islands with contacts in all; h = %.2f s; split at island_split = %d; %d "
               "repeats an island, median\n\n",
               with_contacts, DT, b.island_split, reps);
        int failed = methods_table(&b, sn, nsnap, reps);
        bench_end(&b, sn, nsnap, w);
        return failed;
    }
    printf("%d islands with contacts in all; h = %.2f s; split mode at island_split = %d; %d "
           "repeats an island, median; budget %.0f s a bucket\n\n",
           with_contacts, DT, b.island_split, reps, budget_s);

    /* ---- the buckets ---- */
    printf("%-8s %7s %5s %7s %7s %8s  %-5s %11s %11s %8s %8s %9s %5s %5s %10s  %s\n", "contacts",
           "islands", "timed", "mean_c", "mean_c*", "rows>max", "mode", "median_us", "mean_us",
           "vs_cold", "pivots", "fallbacks", "reg", "uncv", "residual", "note");
    int failed = 0;
    for (int bk = 0; bk < NBUCKET; bk++) {
        int n_in = 0;
        long c_all = 0;
        for (int k = 0; k < nsnap; k++)
            for (int i = 0; i < sn[k].is.count; i++) {
                int nc = sn[k].is.contact_start[i + 1] - sn[k].is.contact_start[i];
                if (nc > 0 && bucket_of(nc) == bk) {
                    n_in++;
                    c_all += nc;
                }
            }
        if (n_in == 0) {
            printf("%-8s %7d %5s %7s %7s %8s  %-5s %11s\n", bucket_name[bk], 0, "-", "-", "-",
                   "-", "-", "no islands");
            continue;
        }
        mode_sum ms[NMODE];
        memset(ms, 0, sizeof ms);
        for (int m = 0; m < NMODE; m++) {
            ms[m].med_s = malloc((size_t)n_in * sizeof *ms[m].med_s);
            if (!ms[m].med_s)
                return 1;
        }
        int timed = 0, over_rows = 0, capped = 0;
        long c_timed = 0;
        double bt0 = now_s();
        for (int it = 0; it < total_islands && !capped; it++) {
            /* island it of all the snapshots' islands, in snapshot order */
            int k = 0, i = it;
            while (i >= sn[k].is.count)
                i -= sn[k++].is.count;
            const snap *S = &sn[k];
            const int *ci = &S->is.contacts[S->is.contact_start[i]];
            int nc = S->is.contact_start[i + 1] - S->is.contact_start[i];
            if (nc == 0 || bucket_of(nc) != bk)
                continue;
            if (now_s() - bt0 > budget_s) {
                capped = 1;
                break;
            }
            int rows = island_rows(S, ci, nc);
            over_rows += rows > SC_MAX_ISLAND_ROWS;
            for (int m = 0; m < NMODE; m++) {
                double t[MAX_REPS];
                sc_solve_info first = { 0 };
                /* at least one solve, fewer once the budget is gone */
                int got = timed_solves(&b, S, m, ci, nc, reps, bt0 + budget_s, t, &first);
                int src = got < 0 ? got : SC_OK;
                if (src == SC_OK)
                    ms[m].solves += got;
                if (src != SC_OK) {
                    ms[m].errors++;
                    ms[m].last_rc = src;
                    continue;
                }
                ms[m].med_s[ms[m].timed++] = median(t, got);
                ms[m].pivots += first.pivots;
                ms[m].fallbacks += first.failures + first.split_fallbacks + first.block_fallbacks;
                ms[m].regularised += first.regularised;
                ms[m].unconverged += first.unconverged;
                ms[m].split += first.split;
                ms[m].residual = fmax(ms[m].residual,
                                      fmax(first.residual_exact, first.residual_split));
            }
            timed++;
            c_timed += nc;
        }
        double cold_med = NAN;
        for (int m = 0; m < NMODE; m++) {
            mode_sum *s = &ms[m];
            char note[160] = "";
            if (capped)
                snprintf(note, sizeof note, "capped: %d of %d islands in %.0f s", timed, n_in,
                         budget_s);
            if (s->errors)
                snprintf(note + strlen(note), sizeof note - strlen(note), "%s%d errors (%s)",
                         *note ? "; " : "", s->errors, sc_strerror(s->last_rc));
            if (s->split && m != MODE_SPLIT)
                snprintf(note + strlen(note), sizeof note - strlen(note), "%s%ld solved split",
                         *note ? "; " : "", s->split);
            failed |= s->errors != 0;
            if (s->timed == 0) {
                printf("%-8s %7d %5d %7.1f %7s %8d  %-5s %11s %11s %8s %8s %9s %5s %5s %10s  %s\n",
                       bucket_name[bk], n_in, timed, (double)c_all / n_in, "-", over_rows,
                       mode_name[m], "-", "-", "-", "-", "-", "-", "-", "-", note);
                continue;
            }
            double sum = 0;
            for (int k = 0; k < s->timed; k++)
                sum += s->med_s[k];
            double mean = sum / s->timed, med = median(s->med_s, s->timed);
            if (m == MODE_COLD)
                cold_med = med;
            char vs[16];
            snprintf(vs, sizeof vs, "%.3g", cold_med / med);
            if (!isfinite(cold_med / med))
                snprintf(vs, sizeof vs, "-");
            printf("%-8s %7d %5d %7.1f %7.1f %8d  %-5s %11.1f %11.1f %8s %8.1f %9ld %5ld %5ld "
                   "%10.2e  %s\n",
                   bucket_name[bk], n_in, timed, (double)c_all / n_in,
                   timed ? (double)c_timed / timed : 0.0, over_rows, mode_name[m], 1e6 * med,
                   1e6 * mean, vs, (double)s->pivots / s->timed, s->fallbacks, s->regularised,
                   s->unconverged, s->residual, note);
        }
        for (int m = 0; m < NMODE; m++)
            free(ms[m].med_s);
        fflush(stdout);
    }
    printf("\nmean_c: mean contacts of the bucket's islands; mean_c*: of those timed; "
           "vs_cold: cold median / this median (> 1: faster than cold)\n");
    bench_end(&b, sn, nsnap, w);
    return failed;
}
