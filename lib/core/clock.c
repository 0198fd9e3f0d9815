/* clock.c - the clocks the stages time themselves with, and a body's
 * shape pose (the stages' shared helpers, below every stage). */
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
void sc_stage_add(sc_stats *st, int stage, double t0)
{
    double dt = sc_cpu_now() - t0;
    st->stage_s[stage] += dt;
    st->stage_total_s[stage] += dt;
}
