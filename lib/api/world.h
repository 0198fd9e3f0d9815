/* world.h - the world behind the public API (world.c; docs/DESIGN.md
 * section 4): the bodies' state, the frame's scratch, the executor over
 * local threads and, when configured, the cluster's daemons. */
#ifndef SC_WORLD_H
#define SC_WORLD_H

#include "exec.h"

struct sc_cluster;

struct sc_world {
    sc_world_config cfg;
    sc_frame_config fcfg;           /* what a frame needs of cfg */
    sc_frame_state st;              /* bodies and last contacts */
    int cap;                        /* bodies allocated */
    sc_frame_scratch scr;
    sc_exec_nodes ex;
    struct sc_cluster *cluster;     /* daemons: nodes ex.nlocal .. */
    sc_stats stats;
};

#endif /* SC_WORLD_H */
