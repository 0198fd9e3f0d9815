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

void sc_spin_at(const double q0[4], const double w0[3], double t, double q[4])
{
    double wl = v3_len(w0);
    if (!(wl * t > 0)) {
        memcpy(q, q0, 4 * sizeof *q);
        return;
    }
    double axis[3], dq[4];
    v3_scale(axis, w0, 1 / wl);
    q_from_axis_angle(dq, axis, wl * t);
    q_mul(q, dq, q0);
    q_normalize(q);
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
    st->frame.stage_s[stage] += dt;
    st->total.stage_s[stage] += dt;
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
    st->frame.lcp.solves += info->solves;
    st->frame.lcp.pivots += info->pivots;
    st->frame.lcp.fallbacks += info->failures;
    st->frame.lcp.split += info->split;
    st->frame.lcp.blocks += info->blocks;
    st->frame.lcp.blocks_shared += info->blocks_shared;
    if (info->sweeps_max > st->frame.lcp.sweeps_max)
        st->frame.lcp.sweeps_max = info->sweeps_max;
    st->frame.lcp.sweeps += info->sweeps;
    st->frame.lcp.unconverged += info->unconverged;
    st->frame.lcp.diverged += info->diverged;
    st->frame.lcp.whole_tries += info->whole_tries;
    st->frame.lcp.whole_solved += info->whole_solved;
    st->frame.lcp.cold_starts += info->cold_starts;
    st->frame.lcp.regularised += info->regularised;
    st->frame.lcp.split_fallbacks += info->split_fallbacks;
    st->frame.lcp.block_fallbacks += info->block_fallbacks;
    st->frame.lcp.nan_islands += info->nan_islands;
    st->frame.lcp.inelastic += info->inelastic;
    st->frame.lcp.energy_refused += info->energy_refused;
    st->frame.lcp.restitution_scaled += info->restitution_scaled;
    st->frame.lcp.guessed += info->guessed;
    st->frame.lcp.residual = max_d(st->frame.lcp.residual, info->residual_exact);
    st->frame.lcp.outer_residual = max_d(st->frame.lcp.outer_residual, info->residual_split);
    st->frame.lcp.as_solves += info->as_solves;
    st->frame.lcp.as_fallbacks += info->as_fallbacks;
    st->frame.lcp.as_iterations += info->as_iterations;
    if (info->as_iterations_max > st->frame.lcp.as_iterations_max)
        st->frame.lcp.as_iterations_max = info->as_iterations_max;
    if (info->factor_nnz_max > st->frame.lcp.factor_nnz_max)
        st->frame.lcp.factor_nnz_max = info->factor_nnz_max;
    if (info->as_parts_max > st->frame.lcp.as_parts_max)
        st->frame.lcp.as_parts_max = info->as_parts_max;
    if (info->as_interface_max > st->frame.lcp.as_interface_max)
        st->frame.lcp.as_interface_max = info->as_interface_max;
    st->frame.lcp.as_exchanges += info->as_exchanges;
    st->frame.lcp.as_exchange_bytes += info->as_exchange_bytes;
}

static void add_lcp(sc_stats_lcp *s, const sc_stats_lcp *g)
{
    s->solves += g->solves;
    s->kept += g->kept;
    s->pivots += g->pivots;
    s->fallbacks += g->fallbacks;
    s->split += g->split;
    s->blocks += g->blocks;
    s->blocks_shared += g->blocks_shared;
    if (g->sweeps_max > s->sweeps_max)
        s->sweeps_max = g->sweeps_max;
    s->sweeps += g->sweeps;
    s->unconverged += g->unconverged;
    s->diverged += g->diverged;
    s->whole_tries += g->whole_tries;
    s->whole_solved += g->whole_solved;
    s->cold_starts += g->cold_starts;
    s->regularised += g->regularised;
    s->split_fallbacks += g->split_fallbacks;
    s->block_fallbacks += g->block_fallbacks;
    s->nan_islands += g->nan_islands;
    s->inelastic += g->inelastic;
    s->energy_refused += g->energy_refused;
    s->restitution_scaled += g->restitution_scaled;
    s->guessed += g->guessed;
    s->residual = max_d(s->residual, g->residual);
    s->outer_residual = max_d(s->outer_residual, g->outer_residual);
    s->as_solves += g->as_solves;
    s->as_fallbacks += g->as_fallbacks;
    s->as_iterations += g->as_iterations;
    if (g->as_iterations_max > s->as_iterations_max)
        s->as_iterations_max = g->as_iterations_max;
    if (g->factor_nnz_max > s->factor_nnz_max)
        s->factor_nnz_max = g->factor_nnz_max;
    if (g->as_parts_max > s->as_parts_max)
        s->as_parts_max = g->as_parts_max;
    if (g->as_interface_max > s->as_interface_max)
        s->as_interface_max = g->as_interface_max;
    s->as_exchanges += g->as_exchanges;
    s->as_exchange_bytes += g->as_exchange_bytes;
}

static void add_toi(sc_stats_toi *s, const sc_stats_toi *g)
{
    if (g->substeps > s->substeps)
        s->substeps = g->substeps;
    s->backups += g->backups;
    s->backup_regions += g->backup_regions;
    s->backup_bodies += g->backup_bodies;
    s->spec_contacts += g->spec_contacts;
    s->spec_rounds += g->spec_rounds;
}

void sc_stats_add_solver(sc_stats *s, const sc_stats *g)
{
    add_lcp(&s->frame.lcp, &g->frame.lcp);
    add_toi(&s->frame.toi, &g->frame.toi);
}

static void add_detect(sc_stats_detect *s, const sc_stats_detect *g)
{
    s->pairs += g->pairs;
    s->np_pairs += g->np_pairs;
    s->np_reused += g->np_reused;
    s->islands += g->islands;
    s->max_penetration = max_d(s->max_penetration, g->max_penetration);
    s->collider_warnings += g->collider_warnings;
}

static void add_sched(sc_stats_sched *s, const sc_stats_sched *g)
{
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
}

void sc_stats_add_work(sc_stats *s, const sc_stats *g)
{
    for (int k = 0; k < SC_STAGE_COUNT; k++) {
        s->frame.stage_s[k] += g->frame.stage_s[k];
        s->total.stage_s[k] += g->frame.stage_s[k];
    }
    add_sched(&s->frame.sched, &g->frame.sched);
}

void sc_stats_add_frame(sc_stats *s, const sc_stats *g)
{
    sc_stats_add_work(s, g);
    add_detect(&s->frame.detect, &g->frame.detect);
    sc_stats_add_solver(s, g);
    s->total.initial_overlaps += g->total.initial_overlaps;
    if (g->total.arena_bytes > s->total.unit_arena_bytes)
        s->total.unit_arena_bytes = g->total.arena_bytes;
    if (g->total.unit_arena_bytes > s->total.unit_arena_bytes)
        s->total.unit_arena_bytes = g->total.unit_arena_bytes;
}
