/* unit_wire.h - the wire form of work units and of their results
 * (unit_wire.c; docs/DESIGN.md section 7). */
#ifndef SC_UNIT_WIRE_H
#define SC_UNIT_WIRE_H

#include "frame.h"

/* Wire form of units and results (unit_wire.c): self-contained,
 * little-endian, versioned, every size bounded; shapes travel as content
 * hashes (sc_shape.hash) resolved by the receiver's lookup. */
typedef const sc_shape *(*sc_shape_lookup_fn)(void *ctx, uint64_t hash);
/* Bytes unit u of job needs; written to buf when cap is enough. 0 for a
 * unit the wire cannot carry (an island with settings a receiver refuses,
 * or sc_contact_params.inject set): compute it locally. */
size_t sc_wire_unit_pack(const sc_job *job, const sc_unit *u, unsigned char *buf, size_t cap);
/* A received unit: a job of its own holding that one unit. */
typedef struct sc_wire_unit {
    sc_job job;
    sc_unit unit;
    sc_unit_pair *pairs;      /* owned arrays */
    sc_contact *contacts;
    int *ncontact;
    double *toi;
    sc_body *bodies;
    int nbodies;
    sc_contact *c;
    sc_islands islands;
    sc_contact_params params;
    /* GROUP: its groups' frames over its bodies (above: the static ones
     * and the members in world order), as the master runs them (group.c) */
    sc_frame_config cfg;
    sc_frame_state gst;
    sc_groups g;
    int *gints;               /* g's arrays */
    sc_group_job group;
    sc_group_out *gouts;      /* per group */
    sc_track track;           /* where its bodies went (owned arrays) */
} sc_wire_unit;
/* Decode; SC_EFORMAT for anything malformed (truncated, bad version/kind,
 * counts or solver or frame settings out of range, NaN, unknown shape
 * hash), SC_ENOMEM. A decoded island's params have inject 0. */
int sc_wire_unit_decode(const unsigned char *buf, size_t len, sc_shape_lookup_fn lookup,
                        void *lookup_ctx, sc_wire_unit *out);
void sc_wire_unit_free(sc_wire_unit *wu);
/* Results of a decoded unit after sc_unit_run(&np, &wu->job, &wu->unit). */
size_t sc_wire_result_pack(const sc_wire_unit *wu, unsigned char *buf, size_t cap);
/* Merge received results into the master's job exactly as if u had run
 * locally (u->rc, u->messages, the whole u->info and the job's outputs for
 * u: an island's members and its contacts' impulses; a group's members,
 * and its new contacts and figures in its sc_group_out). SC_EFORMAT when
 * buf does not match u (kind, counts of pairs, members or contacts) or is
 * malformed, SC_ENOMEM; nothing is written then. */
int sc_wire_result_apply(const sc_job *job, sc_unit *u, const unsigned char *buf, size_t len);

#endif /* SC_UNIT_WIRE_H */
