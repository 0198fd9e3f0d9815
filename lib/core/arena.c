/* arena.c - the per-frame stack arena (arena.h; docs/DESIGN.md section 4).
 * Like Box2D's arena allocator: a bump pointer over one block, entries on
 * a stack so that use out of order is caught, and a malloc fallback so
 * that a frame never fails for want of arena, only grows it afterwards. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "arena.h"
#include "core.h"

#define ALIGN 16

void sc_arena_init(sc_arena *a)
{
    memset(a, 0, sizeof *a);
}

void sc_arena_destroy(sc_arena *a)
{
    if (!a)
        return;
    SC_ASSERT(a->depth == 0);
    free(a->mem);
    memset(a, 0, sizeof *a);
}

void *sc_arena_alloc(sc_arena *a, size_t bytes)
{
    if (!a)
        return malloc(bytes ? bytes : 1);
    if (bytes > SIZE_MAX - ALIGN || a->depth == SC_ARENA_MAX_ENTRIES) {
        SC_ASSERT(a->depth < SC_ARENA_MAX_ENTRIES);
        return NULL;
    }
    size_t size = (bytes + ALIGN - 1) / ALIGN * ALIGN;
    if (size == 0)
        size = ALIGN;
    sc_arena_entry *e = &a->entry[a->depth];
    if (size <= a->cap - a->used) {
        e->data = a->mem + a->used;
        e->malloced = 0;
        a->used += size;
    } else {
        e->data = malloc(size);
        if (!e->data)
            return NULL;
        e->malloced = 1;
        a->overflows++;
    }
    e->size = size;
    a->depth++;
    a->live += size;
    if (a->live > a->high)
        a->high = a->live;
    return e->data;
}

void *sc_arena_calloc(sc_arena *a, size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size)
        return NULL;
    void *p = sc_arena_alloc(a, n * size);
    if (p)
        memset(p, 0, n * size);
    return p;
}

void sc_arena_free(sc_arena *a, void *p)
{
    if (!p)
        return;
    if (!a) {
        free(p);
        return;
    }
    SC_ASSERT(a->depth > 0);
    sc_arena_entry *e = &a->entry[a->depth - 1];
    SC_ASSERT(e->data == p);    /* last in, first out */
    if (e->malloced)
        free(p);
    else
        a->used -= e->size;
    a->live -= e->size;
    a->depth--;
}

int sc_arena_reset(sc_arena *a)
{
    SC_ASSERT(a->depth == 0 && a->used == 0);
    if (a->high <= a->cap)
        return SC_OK;
    size_t cap = a->high + a->high / 2;
    char *m = malloc(cap);
    if (!m)
        return SC_ENOMEM;
    free(a->mem);
    a->mem = m;
    a->cap = cap;
    return SC_OK;
}
