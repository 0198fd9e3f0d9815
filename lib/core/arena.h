/* arena.h - per-frame scratch memory: a stack arena (docs/DESIGN.md
 * section 4). Allocations are freed in reverse order (asserted); one that
 * does not fit falls back to malloc and the arena grows to its high-water
 * mark at the next reset, so a frame of a given size stops allocating
 * after the first. A NULL arena means plain malloc/free (decoders, tests). */
#ifndef SC_ARENA_H
#define SC_ARENA_H

#include <stddef.h>

#define SC_ARENA_MAX_ENTRIES 64   /* nested allocations at most */

typedef struct sc_arena_entry {
    char *data;
    size_t size;                  /* bytes, rounded to the alignment */
    int malloced;                 /* did not fit: from malloc */
} sc_arena_entry;

typedef struct sc_arena {
    char *mem;
    size_t cap;                   /* bytes of mem */
    size_t used;                  /* bytes of mem in use */
    size_t live;                  /* bytes in use, malloc'd ones included */
    size_t high;                  /* high-water mark of live since creation */
    long overflows;               /* allocations that did not fit */
    int depth;
    sc_arena_entry entry[SC_ARENA_MAX_ENTRIES];
} sc_arena;

void sc_arena_init(sc_arena *a);
void sc_arena_destroy(sc_arena *a);
/* bytes (aligned for any type) or NULL on overflow or out of memory; a = NULL:
 * malloc. Zeroed by sc_arena_calloc. */
void *sc_arena_alloc(sc_arena *a, size_t bytes);
void *sc_arena_calloc(sc_arena *a, size_t n, size_t size);
/* Free p, the newest live allocation of a (asserted); NULL is a no-op. */
void sc_arena_free(sc_arena *a, void *p);
/* With nothing live (asserted): grow to the high-water mark when an
 * allocation had to fall back to malloc. SC_OK or SC_ENOMEM (the arena
 * stays as it was and keeps working). */
int sc_arena_reset(sc_arena *a);

#endif
