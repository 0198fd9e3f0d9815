/* serial.c - the serial executor (docs/DESIGN.md section 5.5): every job
 * as one unit on the calling thread, with its narrow-phase context. A
 * motion group running as a unit of its own steps its frame with it. */
#include <string.h>

#include "frame.h"

/* Every job as one unit: its pairs or islands are computed one by one
 * either way, so the outputs are those of any cut. */
static int serial_run(sc_exec *ex, sc_job *job, int stage, sc_stats *st)
{
    (void)stage;
    sc_exec_serial *s = (sc_exec_serial *)ex;
    sc_unit one;
    memset(&one, 0, sizeof one);
    one.kind = job->kind;
    if (job->kind == SC_UNIT_ISLAND) {
        one.islands = job->islands->count;
        one.count = job->islands->contact_start[job->islands->count];
        if (one.islands == 0)
            return SC_OK;
    } else if (job->kind != SC_UNIT_GROUP) {
        one.count = job->npairs;
        if (one.count == 0)
            return SC_OK;
    }
    if (job->kind == SC_UNIT_GROUP) {
        /* group units come made: run them in order */
        int rc = SC_OK;
        for (int i = 0; i < job->nunits; i++) {
            sc_unit_run(s->np, job, &job->units[i]);
            st->frame.detect.collider_warnings += job->units[i].messages;
            if (job->units[i].rc != SC_OK && rc == SC_OK)
                rc = job->units[i].rc;
        }
        st->frame.sched.units += job->nunits;
        return rc;
    }
    job->units = &one;
    job->nunits = 1;
    sc_unit_run(s->np, job, &one);
    job->units = NULL;
    job->nunits = 0;
    st->frame.detect.collider_warnings += one.messages;
    st->frame.sched.units++;
    if (job->kind == SC_UNIT_ISLAND)
        sc_stats_add_solve(st, &one.info);
    if (one.arena_high > st->total.unit_arena_bytes)
        st->total.unit_arena_bytes = one.arena_high;
    return one.rc;
}

static int serial_width(const sc_exec *ex)
{
    (void)ex;
    return 1;
}

void sc_exec_serial_init(sc_exec_serial *s, sc_np_ctx *np)
{
    memset(s, 0, sizeof *s);
    s->base.run = serial_run;
    s->base.width = serial_width;
    s->np = np;
}
