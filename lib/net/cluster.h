/* cluster.h - simclusterd daemons as nodes of an executor (cluster.c;
 * the daemon's side is daemon/engine.h); docs/DESIGN.md section 7. */
#ifndef SC_CLUSTER_H
#define SC_CLUSTER_H

#include "exec.h"

typedef struct sc_cluster sc_cluster;

/* Join url (a udpm:// URL, bus.c) with the key in key_file (NULL: the all-zero insecure
 * key) as a provider of SC_MAX_DAEMONS remote nodes, added to the
 * executor x (which has room for them). stats gets the cluster's figures;
 * st is read to answer daemons' requests for shapes. SC_OK, SC_EIO (url
 * cannot be opened; key file unreadable), SC_EPERM, SC_EFORMAT (key file),
 * SC_ENOMEM. */
int sc_cluster_create(sc_exec_nodes *x, sc_stats *stats, const sc_frame_state *st,
                      const char *url, const char *key_file, double deadline_s,
                      sc_cluster **out);
/* After the executor's nodes are destroyed. */
void sc_cluster_destroy(sc_cluster *c);
/* At the start of a frame: heartbeats in, the daemon counts in stats. */
void sc_cluster_frame(sc_cluster *c);
/* Benchmarks only: every daemon heard from gets work, whatever its idle
 * fraction, owner-busy flag or missed deadlines (bench_cluster's
 * foreground test keeps a daemon full this way). */
void sc_cluster_force(sc_cluster *c);

#endif
