/* frame_record.h - what the library's own files share of the frame
 * records (frame_record.c; the public calls are in simcluster_net.h,
 * docs/DESIGN.md section 7.7). */
#ifndef SC_FRAME_RECORD_H
#define SC_FRAME_RECORD_H

#include "simcluster_net.h"

/* r's arrays for n bodies (n >= 1 allocated even for n = 0), r->n = n:
 * SC_OK or SC_ENOMEM (then r is freed). */
int sc_frame_record_alloc(sc_frame_record *r, int n);

#endif
