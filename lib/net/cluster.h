/* cluster.h - simclusterd daemons as nodes of a world's scheduler
 * (cluster.c; the daemon's side is daemon/engine.h). */
#ifndef SC_CLUSTER_H
#define SC_CLUSTER_H

typedef struct sc_cluster sc_cluster;
struct sc_world;
struct sc_node;
struct sc_job;

/* Join url (LCM) with the key in key_file (NULL: the all-zero insecure
 * key); its SC_MAX_DAEMONS nodes are the world's nodes first_node ...
 * SC_OK, SC_EIO (url cannot be opened; key file unreadable), SC_EPERM,
 * SC_EFORMAT (key file), SC_ENOMEM. */
int sc_cluster_create(struct sc_world *w, const char *url, const char *key_file,
                      double deadline_s, int first_node, sc_cluster **out);
void sc_cluster_destroy(sc_cluster *c);
/* Remote node k (0 .. SC_MAX_DAEMONS - 1). */
struct sc_node *sc_cluster_node(sc_cluster *c, int k);
/* At the start of a frame: heartbeats in, the daemon counts in w->stats. */
void sc_cluster_frame(sc_cluster *c);
/* Around each job run on the world's nodes (after assignment, before the
 * first submit; after the last wait). */
int sc_cluster_begin(sc_cluster *c, const struct sc_job *job);
void sc_cluster_end(sc_cluster *c);
/* Benchmarks only: every daemon heard from gets work, whatever its idle
 * fraction, owner-busy flag or missed deadlines (bench_cluster's
 * foreground test keeps a daemon full this way). */
void sc_cluster_force(sc_cluster *c);

#endif
