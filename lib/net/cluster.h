/* cluster.h - simclusterd daemons as nodes of an executor (cluster.c;
 * the daemon's side is daemon/engine.h); docs/DESIGN.md section 7. */
#ifndef SC_CLUSTER_H
#define SC_CLUSTER_H

#include "exec.h"

typedef struct sc_cluster sc_cluster;

/* A daemon's link as the scheduler sees it: a job's round trip less its
 * work (to the kernel's arrival stamp of its last result) taken as
 * latency + byte_s * the job's wire bytes both ways, fitted by
 * sc_link_fit() through the recent jobs. Zero-initialise; byte_s 0: not
 * measured yet (the scheduler then takes SC_LINK_BYTE_S). */
#define SC_LINK_BYTE_S 1e-8     /* s a byte before a link is measured (100 MB/s) */
typedef struct sc_link {
    double s[5];                /* decaying sums of 1, x, x^2, y, x y */
    double latency, byte_s;
} sc_link;
/* One more job: x wire bytes, y seconds. Least squares over the recent
 * jobs (weights decaying by 0.9 a job) once four (weighted) are in and
 * their sizes spread by a fifth of their mean; until then byte_s stays
 * what it was (the prior) and latency is what is left of the mean. byte_s
 * is kept within 1e-11 .. 1e-5 s a byte, latency >= 0. It is fitted
 * because no constant suits every link: loopback and a 100 Mbit/s hop
 * differ more than a hundredfold a byte. */
void sc_link_fit(sc_link *l, double x, double y);

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
