/* clock.c - the clocks the stages time themselves with, and a body's
 * shape pose and the frame's figures (the stages' shared helpers, below
 * every stage). */
#include <math.h>
#include <string.h>
#include <time.h>

#include "frame.h"
#include "vecmath.h"

void sc_body_pose(const sc_body *b, sc_pose *p)
{
    double rc[3];
    q_rotate(rc, b->q, b->com);
    v3_sub(p->pos, b->x, rc);
    memcpy(p->quat, b->q, sizeof p->quat);
}

double sc_body_reach(const sc_frame_config *cfg, const sc_body *b, double dt)
{
    double a[3];
    v3_madd(a, cfg->gravity, b->force, b->inv_mass);
    return (2 * v3_len(b->v) + v3_len(b->w) * v3_len(b->com)) * dt +
           0.5 * v3_len(a) * dt * dt;
}

void sc_body_drift(const sc_frame_config *cfg, const sc_body *b, double d[9])
{
    sc_pose p;
    sc_body_pose(b, &p);
    v3_copy(d, p.pos);
    v3_set(d + 3, 0, 0, 0);
    v3_set(d + 6, 0, 0, 0);
    if (sc_body_movable(b)) {
        double r[3], wr[3];
        v3_sub(r, p.pos, b->x);
        v3_cross(wr, b->w, r);
        v3_add(d + 3, b->v, wr);
        v3_madd(d + 6, cfg->gravity, b->force, b->inv_mass);
    }
}

void sc_drift_at(const double d[9], double t, double p[3])
{
    v3_madd(p, d, d + 3, t);
    v3_madd(p, p, d + 6, 0.5 * t * t);
}

double sc_cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double sc_wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of the calling thread since t0 into row stage of the frame's
 * figures (Table 1). */
/* dt seconds into row stage of the frame's figures and of the run's. */
static void stage_credit(sc_stats *st, int stage, double dt)
{
    st->stage_s[stage] += dt;
    st->stage_total_s[stage] += dt;
}

void sc_stage_add(sc_stats *st, int stage, double t0)
{
    stage_credit(st, stage, sc_cpu_now() - t0);
}

double sc_stage_now(const sc_frame *f)
{
    return f->cfg->toi_mode == SC_TOI_LOCAL ? sc_wall_now() : sc_cpu_now();
}

void sc_stage_since(sc_frame *f, int stage, double t0)
{
    stage_credit(f->stats, stage, sc_stage_now(f) - t0);
}

void sc_stats_add_solve(sc_stats *st, const sc_solve_info *info)
{
    st->lcp_solves += info->solves;
    st->lcp_pivots += info->pivots;
    st->lcp_fallbacks += info->failures;
    st->lcp_split += info->split;
    st->lcp_blocks += info->blocks;
    st->lcp_blocks_shared += info->blocks_shared;
    if (info->sweeps_max > st->lcp_sweeps_max)
        st->lcp_sweeps_max = info->sweeps_max;
    st->lcp_unconverged += info->unconverged;
    st->lcp_diverged += info->diverged;
    st->lcp_cold_starts += info->cold_starts;
    st->lcp_regularised += info->regularised;
    st->lcp_split_fallbacks += info->split_fallbacks;
    st->lcp_block_fallbacks += info->block_fallbacks;
    st->lcp_nan_islands += info->nan_islands;
    st->lcp_inelastic += info->inelastic;
    st->lcp_energy_refused += info->energy_refused;
    st->lcp_restitution_scaled += info->restitution_scaled;
    st->lcp_guessed += info->guessed;
    st->lcp_residual = max_d(st->lcp_residual, info->residual_exact);
    st->lcp_outer_residual = max_d(st->lcp_outer_residual, info->residual_split);
}

void sc_stats_add_solver(sc_stats *s, const sc_stats *g)
{
    s->lcp_solves += g->lcp_solves;
    s->lcp_kept += g->lcp_kept;
    s->lcp_pivots += g->lcp_pivots;
    s->lcp_fallbacks += g->lcp_fallbacks;
    s->lcp_split += g->lcp_split;
    s->lcp_blocks += g->lcp_blocks;
    s->lcp_blocks_shared += g->lcp_blocks_shared;
    if (g->lcp_sweeps_max > s->lcp_sweeps_max)
        s->lcp_sweeps_max = g->lcp_sweeps_max;
    s->lcp_unconverged += g->lcp_unconverged;
    s->lcp_diverged += g->lcp_diverged;
    s->lcp_cold_starts += g->lcp_cold_starts;
    s->lcp_regularised += g->lcp_regularised;
    s->lcp_split_fallbacks += g->lcp_split_fallbacks;
    s->lcp_block_fallbacks += g->lcp_block_fallbacks;
    s->lcp_nan_islands += g->lcp_nan_islands;
    s->lcp_inelastic += g->lcp_inelastic;
    s->lcp_energy_refused += g->lcp_energy_refused;
    s->lcp_restitution_scaled += g->lcp_restitution_scaled;
    s->lcp_guessed += g->lcp_guessed;
    s->lcp_residual = max_d(s->lcp_residual, g->lcp_residual);
    s->lcp_outer_residual = max_d(s->lcp_outer_residual, g->lcp_outer_residual);
    if (g->substeps > s->substeps)
        s->substeps = g->substeps;
    s->backups += g->backups;
    s->backup_regions += g->backup_regions;
    s->backup_bodies += g->backup_bodies;
    s->spec_contacts += g->spec_contacts;
    s->spec_rounds += g->spec_rounds;
}

void sc_stats_clear_solver(sc_stats *st)
{
    st->lcp_solves = 0;
    st->lcp_kept = 0;
    st->lcp_pivots = 0;
    st->lcp_fallbacks = 0;
    st->lcp_split = 0;
    st->lcp_blocks = 0;
    st->lcp_blocks_shared = 0;
    st->lcp_sweeps_max = 0;
    st->lcp_unconverged = 0;
    st->lcp_diverged = 0;
    st->lcp_cold_starts = 0;
    st->lcp_regularised = 0;
    st->lcp_split_fallbacks = 0;
    st->lcp_block_fallbacks = 0;
    st->lcp_nan_islands = 0;
    st->lcp_inelastic = 0;
    st->lcp_energy_refused = 0;
    st->lcp_restitution_scaled = 0;
    st->lcp_guessed = 0;
    st->lcp_residual = 0;
    st->lcp_outer_residual = 0;
    st->substeps = 0;
    st->backups = 0;
    st->backup_regions = 0;
    st->backup_bodies = 0;
    st->spec_contacts = 0;
    st->spec_rounds = 0;
}

void sc_stats_add_frame(sc_stats *s, const sc_stats *g)
{
    for (int k = 0; k < SC_STAGE_COUNT; k++) {
        s->stage_s[k] += g->stage_s[k];
        s->stage_total_s[k] += g->stage_s[k];
    }
    s->pairs += g->pairs;
    s->np_pairs += g->np_pairs;
    s->np_reused += g->np_reused;
    s->islands += g->islands;
    sc_stats_add_solver(s, g);
    s->max_penetration = max_d(s->max_penetration, g->max_penetration);
    s->collider_warnings += g->collider_warnings;
    s->units += g->units;
    s->sched_s += g->sched_s;
    s->makespan_s += g->makespan_s;
    s->makespan_bound_s += g->makespan_bound_s;
    s->jobs += g->jobs;
    s->unit_work_s += g->unit_work_s;
    s->unit_bytes += g->unit_bytes;
    for (int k = 0; k < SC_STATS_IDEAL_NODES; k++)
        s->ideal_makespan_s[k] += g->ideal_makespan_s[k];
    for (int k = 0; k < SC_STATS_DENSITY_BINS; k++)
        s->unit_work_by_density_s[k] += g->unit_work_by_density_s[k];
    s->initial_overlaps += g->initial_overlaps;
    if (g->arena_bytes > s->unit_arena_bytes)
        s->unit_arena_bytes = g->arena_bytes;
    if (g->unit_arena_bytes > s->unit_arena_bytes)
        s->unit_arena_bytes = g->unit_arena_bytes;
}
